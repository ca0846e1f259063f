// SPDX-License-Identifier: MIT OR Apache-2.0
//! The GPU bake equals the plain CPU twin (`decalbake::bake::cpu`) texel by texel, for every blend
//! mode, on a small two-island mesh with a UV seam; and the padding follows its rule exactly.
//!
//! Tolerance: 1e-4 in linear light per channel on island texels. The bake is read back at 16 bits
//! (sRGB quantization up to about 1.5e-5 in linear light) and both sides compute in f32, so what is
//! left is rounding in the blend formulas and in bilinear filtering; lavapipe filters f32 textures with
//! f32 weights (measured worst case 1.7e-5). A GPU with 8-bit sub-texel filtering precision would need
//! about 1/256 of the largest step between neighbouring decal texels (0.2 here), i.e. 1e-3.

mod common;
use common::*;
use decalbake::bake::cpu::{bake_cpu, nearest_island};
use decalbake::io::image::LinearImage;
use decalbake::io::job::BlendMode;
use decalbake::mesh::{Mesh, Topology, DEFAULT_WELD_TOLERANCE};
use decalbake::Job;

const TOL: f32 = 1e-4;

fn job_text(mode: &str, with_mask: bool, padding: u32) -> String {
    job_text_method(mode, with_mask, padding, "planar", "")
}

/// `extra`: more fields of the second layer (`, "name": value`).
fn job_text_method(mode: &str, with_mask: bool, padding: u32, method: &str, extra: &str) -> String {
    let mask = if with_mask { "\"mask.png\"" } else { "null" };
    format!(
        r#"{{
  "mesh": "book.glb",
  "texture": {{ "width": 64, "height": 64, "base": "base.png", "padding": {padding}, "samples": 4 }},
  "layers": [
    {{ "image": "decal_a.png", "at": [0.3, 0.45, 0.02], "size": [0.4, 0.5], "angle": -10, "blend": "normal", "opacity": 0.8 }},
    {{ "image": "decal_b.png", "mask": {mask}, "at": [0.52, 0.55, 0.01], "size": [0.6, 0.5], "angle": 25, "blend": "{mode}", "opacity": 1.0, "method": "{method}"{extra} }}
  ],
  "output": {{ "texture": "out.png", "bit_depth": 16, "report": null }}
}}"#
    )
}

/// The book mesh, a 64² base image and two decals, as 16-bit PNGs, into `dir`.
fn write_inputs(dir: &std::path::Path) {
    let (pos, uv, idx) = book_mesh();
    write_glb(&dir.join("book.glb"), &pos, Some(&uv), &idx);
    for (name, img) in [
        ("base.png", test_image(64, 64, 7, false)),
        ("decal_a.png", test_image(12, 16, 3, true)),
        ("decal_b.png", test_image(16, 12, 5, true)),
    ] {
        std::fs::write(dir.join(name), img.encode_png(16)).unwrap();
    }
}

#[test]
fn gpu_compose_matches_cpu_twin_for_every_blend_mode() {
    let dir = scratch("compose");
    write_inputs(&dir);
    // Mask: a radial ramp (raw values, no sRGB).
    let mut mask = LinearImage::solid(16, 16, [0.0; 4]);
    for y in 0..16 {
        for x in 0..16 {
            let d = (((x as f32 - 7.5).powi(2) + (y as f32 - 7.5).powi(2)).sqrt() / 8.0).min(1.0);
            let v = decalbake::io::image::srgb_to_linear(1.0 - d);
            mask.pixels[y * 16 + x] = [v, v, v, 1.0];
        }
    }
    std::fs::write(dir.join("mask.png"), mask.encode_png(16)).unwrap();

    let engine = engine();
    let loaded = engine.load_mesh(&dir.join("book.glb")).unwrap();
    let mesh = Mesh::load(&dir.join("book.glb")).unwrap();
    let topo = Topology::build(&mesh, DEFAULT_WELD_TOLERANCE);
    assert_eq!(
        topo.positions.len(),
        45,
        "the two panels share their seam column after welding"
    );
    let base = LinearImage::load(&dir.join("base.png")).unwrap();
    let decal_a = LinearImage::load(&dir.join("decal_a.png")).unwrap();
    let decal_b = LinearImage::load(&dir.join("decal_b.png")).unwrap();
    let raw = |img: LinearImage| LinearImage {
        pixels: img
            .pixels
            .iter()
            .map(|p| [decalbake::io::image::linear_to_srgb(p[0]), 0.0, 0.0, p[3]])
            .collect(),
        ..img
    };
    let mask_raw = raw(LinearImage::load(&dir.join("mask.png")).unwrap());

    let mut worst_all = 0.0f32;
    // The last case warps the second decal's image (a thin-plate spline, `FLAG_WARP`).
    let warp = r#", "warp": [[[0.5, 0.5], [0.65, 0.35]], [[0.2, 0.8], [0.2, 0.7]]]"#;
    let cases: Vec<(BlendMode, &str, &str)> = BlendMode::ALL
        .iter()
        .map(|m| (*m, "planar", ""))
        .chain([
            (BlendMode::Normal, "expmap", ""),
            (BlendMode::Overlay, "expmap", ""),
            (BlendMode::Normal, "lscm", ""),
            (BlendMode::Multiply, "hybrid", ""),
            (BlendMode::Normal, "expmap", warp),
        ])
        .collect();
    for (k, (mode, method, extra)) in cases.iter().enumerate() {
        let with_mask = k % 2 == 1;
        let job = Job::parse(
            &job_text_method(mode.name(), with_mask, 6, method, extra),
            &dir.join("job.json"),
            &dir,
            &dir,
        )
        .unwrap();
        let baked = engine.bake(&loaded, &job).unwrap();
        let placements: Vec<_> = baked.report.layers.iter().map(|l| l.placement).collect();
        let images = vec![
            (decal_a.clone(), None),
            (decal_b.clone(), with_mask.then(|| mask_raw.clone())),
        ];
        let cpu = bake_cpu(&mesh, &topo, &job, &placements, &base, &images);
        for (l, sel) in baked.report.layers.iter().zip(&cpu.selected) {
            assert_eq!(
                l.triangles_covered as usize,
                sel.len(),
                "{mode:?}: layer {} triangle selection differs",
                l.index
            );
        }
        let (w, h) = (64u32, 64u32);
        let mut worst = (0.0f32, 0u32, 0u32);
        let mut changed = 0;
        for y in 0..h {
            for x in 0..w {
                let i = (y * w + x) as usize;
                if !cpu.island[i] {
                    continue;
                }
                let g = baked.linear(x, y);
                let c = cpu.composed.pixels[i];
                if (c[0] - base.pixels[i][0]).abs() > 0.01 {
                    changed += 1;
                }
                for ch in 0..4 {
                    let d = (g[ch] - c[ch]).abs();
                    if d > worst.0 {
                        worst = (d, x, y);
                    }
                }
            }
        }
        if worst.0 > TOL {
            let gpu_img = LinearImage {
                width: w,
                height: h,
                pixels: (0..w * h).map(|i| baked.linear(i % w, i / w)).collect(),
            };
            std::fs::write(
                dir.join(format!("gpu_{}.png", mode.name())),
                gpu_img.encode_png(8),
            )
            .unwrap();
            std::fs::write(
                dir.join(format!("cpu_{}.png", mode.name())),
                cpu.composed.encode_png(8),
            )
            .unwrap();
            eprintln!("wrote {}/{{gpu,cpu}}_{}.png", dir.display(), mode.name());
        }
        eprintln!("{mode:?} {method}{extra} (mask {with_mask}): max |GPU - CPU| = {:.2e} at texel ({}, {}); {changed} texels changed", worst.0, worst.1, worst.2);
        assert!(
            changed > 200,
            "{mode:?}: the layers should change many texels, changed {changed}"
        );
        assert!(
            worst.0 <= TOL,
            "{mode:?}: GPU differs from the CPU twin by {} at texel ({}, {}): gpu {:?} cpu {:?}",
            worst.0,
            worst.1,
            worst.2,
            baked.linear(worst.1, worst.2),
            cpu.composed.pixels[(worst.2 * w + worst.1) as usize]
        );
        worst_all = worst_all.max(worst.0);

        // The island mask agrees with the CPU twin.
        let island_gpu = baked.report.island_texels as usize;
        let island_cpu = cpu.island.iter().filter(|b| **b).count();
        assert_eq!(island_gpu, island_cpu, "{mode:?}: island texel count");
    }
    eprintln!("worst over all modes: {worst_all:.2e} (tolerance {TOL:.0e})");
}

/// Padding: island texels are unchanged by padding; every background texel within `padding` takes the
/// colour of one of its nearest island texels; everything farther keeps the base.
fn texel(b: &decalbake::Baked, i: usize) -> &[u16] {
    &b.texels[i * 4..i * 4 + 4]
}

#[test]
fn padding_fills_exactly_the_band_from_the_nearest_island_texel() {
    let dir = scratch("padding");
    write_inputs(&dir);
    let engine = engine();
    let loaded = engine.load_mesh(&dir.join("book.glb")).unwrap();
    let bake = |pad: &str| {
        let text =
            job_text("normal", false, 0).replace("\"padding\": 0", &format!("\"padding\": {pad}"));
        engine
            .bake(
                &loaded,
                &Job::parse(&text, &dir.join("job.json"), &dir, &dir).unwrap(),
            )
            .unwrap()
    };
    let none = bake("0");
    let pad = bake("5");
    let full = bake("\"full\"");
    let mesh = Mesh::load(&dir.join("book.glb")).unwrap();
    let topo = Topology::build(&mesh, DEFAULT_WELD_TOLERANCE);
    let base = LinearImage::load(&dir.join("base.png")).unwrap();
    let job = Job::parse(
        &job_text("normal", false, 0),
        &dir.join("job.json"),
        &dir,
        &dir,
    )
    .unwrap();
    let cpu = bake_cpu(
        &mesh,
        &topo,
        &job,
        &[
            none.report.layers[0].placement,
            none.report.layers[1].placement,
        ],
        &base,
        &[(base.clone(), None), (base.clone(), None)],
    );
    let nearest = nearest_island(&cpu.island, 64, 64);
    let (mut filled, mut kept, mut full_filled) = (0, 0, 0);
    for (i, near) in nearest.iter().enumerate() {
        match near {
            None => {
                // Island texel: padding never touches it.
                assert_eq!(
                    texel(&pad, i),
                    texel(&none, i),
                    "island texel {i} changed by padding"
                );
                assert_eq!(
                    texel(&full, i),
                    texel(&none, i),
                    "island texel {i} changed by full padding"
                );
            }
            Some((d2, who)) => {
                let from_nearest =
                    |b: &decalbake::Baked| who.iter().any(|&j| texel(b, j as usize) == texel(b, i));
                if *d2 <= 25 {
                    assert!(from_nearest(&pad), "texel {i} at distance^2 {d2} is not a copy of its nearest island texel(s) {who:?}");
                    filled += 1;
                } else {
                    assert_eq!(
                        texel(&pad, i),
                        texel(&none, i),
                        "texel {i} beyond the padding radius was touched"
                    );
                    kept += 1;
                }
                assert!(
                    from_nearest(&full),
                    "full padding: texel {i} is not from its nearest island texel"
                );
                full_filled += 1;
            }
        }
    }
    eprintln!("padding 5: {filled} texels filled, {kept} kept; full: {full_filled} filled");
    assert!(
        filled > 300 && kept > 300,
        "the test image should have both a band and a far background"
    );
}

/// The report's distortion on the folded sheet: a planar projection along the flat panel's normal
/// keeps that panel's areas (ratio 1) and shrinks the tilted panel's by cos(tilt) = 1/sqrt(1.25)
/// (slope 0.25 over 0.5); the exponential map of this developable sheet keeps both up to the crease:
/// the vertices on the fold carry the average of the two panels' normals, so the edges leaving them
/// are laid into a plane halfway between (within 3 % here). The GPU figures also equal the CPU twin
/// `maps::distortion::distortion`.
#[test]
fn distortion_report_matches_analytic_values_on_the_folded_sheet() {
    let dir = scratch("distortion");
    write_inputs(&dir);
    let engine = engine();
    let loaded = engine.load_mesh(&dir.join("book.glb")).unwrap();
    let text = r#"{ "mesh": "book.glb", "texture": { "width": 64, "height": 64 },
        "layers": [
          { "image": "decal_a.png", "at": [0.25, 0.5, 0.0], "size": [0.65, 0.5], "method": "planar", "depth": 1.0 },
          { "image": "decal_a.png", "at": [0.45, 0.5, 0.0], "size": [0.5, 0.5], "method": "expmap" },
          { "image": "decal_a.png", "at": [0.45, 0.5, 0.0], "size": [0.5, 0.5], "method": "lscm" } ],
        "output": { "texture": null, "report": null } }"#;
    let job = Job::parse(text, &dir.join("job.json"), &dir, &dir).unwrap();
    let baked = engine.bake(&loaded, &job).unwrap();
    let planar = baked.report.layers[0].distortion;
    let expmap = baked.report.layers[1].distortion;
    eprintln!("planar {planar:?}\nexpmap {expmap:?}");
    let cos = 1.0 / 1.25f32.sqrt();
    assert!((planar.area_ratio_max - 1.0).abs() < 1e-5, "{planar:?}");
    assert!((planar.area_ratio_min - cos).abs() < 1e-5, "{planar:?}");
    assert!(planar.area_ratio_mean < 1.0 && planar.area_ratio_mean > cos);
    assert!(
        (planar.angle_distortion_max - 1.0 / cos).abs() < 1e-4,
        "{planar:?}"
    );
    assert_eq!(planar.flipped, 0);
    assert!(
        (expmap.area_ratio_min - 1.0).abs() < 0.03 && (expmap.area_ratio_max - 1.0).abs() < 0.03,
        "{expmap:?}"
    );
    assert!(
        expmap.angle_distortion_max < 1.03 && (expmap.area_ratio_mean - 1.0).abs() < 1e-3,
        "{expmap:?}"
    );
    // The folded sheet is developable: the conformal chart is its unfolding, an isometry after the
    // normalisation (f32 solve to 1e-6: bounds 1e-3).
    let lscm = baked.report.layers[2].distortion;
    eprintln!("lscm {lscm:?}");
    assert!(
        lscm.angle_distortion_max < 1.001
            && (lscm.area_ratio_min - 1.0).abs() < 1e-3
            && (lscm.area_ratio_max - 1.0).abs() < 1e-3,
        "{lscm:?}"
    );
    assert_eq!(lscm.flipped, 0);
    // CPU twin of the planar figures.
    let mesh = Mesh::load(&dir.join("book.glb")).unwrap();
    let topo = Topology::build(&mesh, DEFAULT_WELD_TOLERANCE);
    let frame = decalbake::maps::Frame::new(&baked.report.layers[0].placement, &job.layers[0]);
    let coords = decalbake::maps::planar::planar_coords(&topo, &frame);
    let sel = decalbake::bake::cpu::select_triangles(
        &mesh,
        &topo,
        &mesh.uv_sets[0],
        (&coords, None),
        &frame,
        true,
        [64, 64],
    );
    let cpu = decalbake::maps::distortion::distortion(&topo, (&coords, None), &sel.triangles);
    assert!(
        (cpu.area_ratio_mean - planar.area_ratio_mean).abs() < 1e-5,
        "CPU {cpu:?} GPU {planar:?}"
    );
    assert!(
        (cpu.angle_distortion_mean - planar.angle_distortion_mean).abs() < 1e-5,
        "CPU {cpu:?} GPU {planar:?}"
    );
    assert_eq!(cpu.flipped, planar.flipped);
}

/// A decal shrunk to a few texels must not alias: a one-pixel checkerboard (mean 0.5 in linear
/// light) baked at about 8 texels across must come out as its mean, which needs mipmapping
/// (point-sampling level 0 would give 0 or 1 per sample; a 2×2 supersampled average of those still
/// swings by ±0.5).
#[test]
fn minified_decals_are_filtered_not_aliased() {
    let dir = scratch("minify");
    write_inputs(&dir);
    let mut checker = LinearImage::solid(128, 128, [0.0; 4]);
    for (i, p) in checker.pixels.iter_mut().enumerate() {
        let v = ((i % 128) + (i / 128)) % 2;
        *p = [v as f32, v as f32, v as f32, 1.0];
    }
    std::fs::write(dir.join("checker.png"), checker.encode_png(16)).unwrap();
    let text = r#"{ "mesh": "book.glb", "texture": { "width": 64, "height": 64, "base": [0, 0, 1, 1] },
        "layers": [ { "image": "checker.png", "at": [0.25, 0.5, 0.0], "size": [0.3, 0.3] } ],
        "output": { "texture": null, "bit_depth": 16, "report": null } }"#;
    let engine = engine();
    let loaded = engine.load_mesh(&dir.join("book.glb")).unwrap();
    let baked = engine
        .bake(
            &loaded,
            &Job::parse(text, &dir.join("job.json"), &dir, &dir).unwrap(),
        )
        .unwrap();
    // Texels well inside the decal: the base is pure blue, the decal grey; its red channel is the
    // decal's value.
    let (mut n, mut worst) = (0, 0.0f32);
    for y in 0..64 {
        for x in 0..64 {
            let c = baked.linear(x, y);
            if c[2] < 0.9 && c[0] > 0.05 {
                // Inside or on the decal's edge; keep the texels whose blue was fully replaced.
                if c[2] < 0.6 {
                    n += 1;
                    worst = worst.max((c[0] - 0.5).abs());
                }
            }
        }
    }
    eprintln!("{n} texels inside the decal, worst |value - 0.5| = {worst:.3}");
    assert!(n >= 20, "the decal should cover some texels: {n}");
    assert!(
        worst < 0.08,
        "aliasing: a texel is {worst} away from the checker's mean"
    );
}

/// Adaptive supersampling (`"sampling": "adaptive"`): the raster runs once a texel and triangle at
/// four samples a pixel. Against its CPU twin (the same samples, the same evaluation at the
/// texel's centre clamped into the image, the same share of the covered samples in the image):
/// within `TOL`, as the full pattern is. Against the full pattern on the same GPU: a mean
/// difference within 2e-3 in linear light over the island texels (they differ where a texel's
/// four samples would not agree: edges of triangles and images, and the creases of the magnified
/// bilinear images; measured 5e-4, at most 0.11 at an edge). Skipped on a device without
/// four-sample targets (the GPU then draws the full pattern, which the twin does not follow).
#[test]
fn adaptive_sampling_matches_its_twin_and_the_full_pattern() {
    let dir = scratch("compose_adaptive");
    write_inputs(&dir);
    let engine = engine();
    let loaded = engine.load_mesh(&dir.join("book.glb")).unwrap();
    let mesh = Mesh::load(&dir.join("book.glb")).unwrap();
    let topo = Topology::build(&mesh, DEFAULT_WELD_TOLERANCE);
    let base = LinearImage::load(&dir.join("base.png")).unwrap();
    let images = vec![
        (LinearImage::load(&dir.join("decal_a.png")).unwrap(), None),
        (LinearImage::load(&dir.join("decal_b.png")).unwrap(), None),
    ];
    let warp = r#", "warp": [[[0.5, 0.5], [0.65, 0.35]], [[0.2, 0.8], [0.2, 0.7]]]"#;
    let adaptive =
        |text: String| text.replace(r#""samples": 4"#, r#""samples": 4, "sampling": "adaptive""#);
    let (w, h) = (64u32, 64u32);
    for (method, extra) in [
        ("planar", ""),
        ("expmap", ""),
        ("lscm", ""),
        ("expmap", warp),
    ] {
        let text = job_text_method("normal", false, 6, method, extra);
        let parse = |t: &str| Job::parse(t, &dir.join("job.json"), &dir, &dir).unwrap();
        let (job, full_job) = (parse(&adaptive(text.clone())), parse(&text));
        let baked = engine.bake(&loaded, &job).unwrap();
        let full = engine.bake(&loaded, &full_job).unwrap();
        if baked.report.paths.sampling != "adaptive" {
            eprintln!("the device holds no four-sample targets of the layer format: skipped");
            return;
        }
        assert_eq!(full.report.paths.sampling, "full");
        let placements: Vec<_> = baked.report.layers.iter().map(|l| l.placement).collect();
        let cpu = bake_cpu(&mesh, &topo, &job, &placements, &base, &images);
        let (mut twin, mut sum, mut n, mut worst_full) = (0.0f32, 0.0f64, 0u32, 0.0f32);
        for y in 0..h {
            for x in 0..w {
                let i = (y * w + x) as usize;
                if !cpu.island[i] {
                    continue;
                }
                let (g, f, c) = (
                    baked.linear(x, y),
                    full.linear(x, y),
                    cpu.composed.pixels[i],
                );
                for ch in 0..4 {
                    twin = twin.max((g[ch] - c[ch]).abs());
                    worst_full = worst_full.max((g[ch] - f[ch]).abs());
                    sum += (g[ch] - f[ch]).abs() as f64;
                }
                n += 1;
            }
        }
        let mean = sum / (4 * n) as f64;
        eprintln!("{method}{extra}: |GPU - twin| {twin:.2e}; |adaptive - full| mean {mean:.2e}, max {worst_full:.3}");
        assert!(
            twin <= TOL,
            "{method}: the adaptive raster differs from its twin by {twin}"
        );
        assert!(
            mean <= 2e-3,
            "{method}: adaptive differs from the full pattern by {mean} on average"
        );
        assert_eq!(
            baked.report.island_texels,
            cpu.island.iter().filter(|b| **b).count() as u64
        );
    }
}
