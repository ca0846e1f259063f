// SPDX-License-Identifier: MIT OR Apache-2.0
//! `decalbake bench --vector`: what vector images cost against bitmaps, in one run, at each of
//! `--sizes` (default 4096):
//!
//! - **decals**: `--decals` (the first value, default 64) planar decals of the demo's SVG logo on
//!   `--mesh` (default the bundled bob), at [`random_job`]'s places and sizes, against the same
//!   decals as PNGs, each rendered beforehand by resvg at the pixel size the SVG bake chose for its
//!   layer (the report's `raster_px`: the texel density it covers), so both bakes sample images
//!   of the same size;
//! - **glyphs**: 1,000 glyphs of text along 20 curves (straight lines of 50 glyphs) on a plane of
//!   64 × 64 cells, against the same ribbons with each line as a PNG strip of its raster size.
//!
//! Each variant is baked once cold, then `--reps` times, the variants in turn, with the engine's
//! image cache emptied before every bake: each vector bake renders its SVGs and text, as a
//! one-off `decalbake bake` does, and each bitmap bake decodes its PNGs. JSON lines through
//! `emit`: one per size and variant, and one per size and workload with the ratio vector /
//! bitmap (the target: at most 2).

use super::common::{median, random_job};
use decalbake::bake::vector_gpu::bin;
use decalbake::io::job::Layer;
use decalbake::io::vector::Svg;
use decalbake::{Engine, Job, LoadedMesh};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Options of `decalbake bench --vector`.
pub struct VectorBenchOptions {
    /// The mesh of the decal workload.
    pub mesh: PathBuf,
    /// Texture sides.
    pub sizes: Vec<u32>,
    /// Decals in the decal workload.
    pub decals: usize,
    /// Timed repetitions per variant (median reported).
    pub reps: usize,
    /// The decals' method (`--method`: `planar` by default).
    pub method: String,
}

/// Lines of text in the glyph workload, and glyphs a line (1,000 in all).
const LINES: usize = 20;
/// Glyphs a line.
const GLYPHS_PER_LINE: usize = 50;
/// The length of a line's path, model units.
const LINE_LENGTH: f32 = 0.96;

/// Runs the benchmark: JSON lines through `emit`.
pub fn run(
    engine: &Engine,
    opts: &VectorBenchOptions,
    mut emit: impl FnMut(serde_json::Value),
) -> anyhow::Result<()> {
    super::common::in_scratch("vector", |dir| run_in(engine, opts, dir, &mut emit))
}

/// [`run`] in the scratch folder `dir`.
fn run_in(
    engine: &Engine,
    opts: &VectorBenchOptions,
    dir: &Path,
    emit: &mut dyn FnMut(serde_json::Value),
) -> anyhow::Result<()> {
    let mesh = engine.load_mesh(&opts.mesh)?;
    let logo = dir.join("logo.svg");
    decalbake::io::image::write_atomic(&logo, crate::demo::LOGO_SVG.as_bytes())?;
    let plane_path = dir.join("plane.glb");
    write_plane(&plane_path)?;
    let plane = engine.load_mesh(&plane_path)?;
    for &side in &opts.sizes {
        let mut svg = random_job(&mesh, opts.decals, side, dir, 11, &opts.method)?;
        for l in &mut svg.layers {
            l.image = logo.clone();
        }
        let (png, sized) = bitmap_twin(engine, &mesh, &svg, dir, "decal")?;
        compare(engine, (&mesh, &svg, &png), opts, "decals", side, emit)?;
        coverage(engine, &sized, opts.reps, ("decals", side), emit)?;
        let text = text_job(dir, &plane_path, side)?;
        let (strips, sized) = bitmap_twin(engine, &plane, &text, dir, "line")?;
        compare(engine, (&plane, &text, &strips), opts, "glyphs", side, emit)?;
        coverage(engine, &sized, opts.reps, ("glyphs", side), emit)?;
    }
    Ok(())
}

/// Bakes the vector job and its bitmap twin once cold and `reps` times in turn; emits a line per
/// variant and the ratio.
fn compare(
    engine: &Engine,
    (mesh, vector, bitmap): (&LoadedMesh, &Job, &Job),
    opts: &VectorBenchOptions,
    workload: &str,
    side: u32,
    emit: &mut dyn FnMut(serde_json::Value),
) -> anyhow::Result<()> {
    let cold = [timed(engine, mesh, vector)?, timed(engine, mesh, bitmap)?];
    let mut samples = [Vec::new(), Vec::new()];
    for _ in 0..opts.reps.max(1) {
        for (k, job) in [vector, bitmap].into_iter().enumerate() {
            samples[k].push(timed(engine, mesh, job)?);
        }
    }
    let med = |k: usize, f: fn(&(f64, f64, f64)) -> f64| median(samples[k].iter().map(f).collect());
    for (k, name) in ["vector", "bitmap"].into_iter().enumerate() {
        emit(serde_json::json!({
            "bench": "vector", "workload": workload, "variant": name, "side": side,
            "layers": vector.layers.len(), "cold_ms": cold[k].0,
            "median_ms": med(k, |s| s.0), "median_images_ms": med(k, |s| s.1),
            "median_vector_maps_ms": med(k, |s| s.2),
            "all_ms": samples[k].iter().map(|s| s.0).collect::<Vec<_>>(),
            "adapter": engine.ctx.adapter,
        }));
    }
    let ratio = med(0, |s| s.0) / med(1, |s| s.0).max(1e-9);
    emit(serde_json::json!({
        "bench": "vector", "workload": workload, "side": side,
        "ratio_vector_over_bitmap": ratio,
        "ratio_images_stage": med(0, |s| s.1) / med(1, |s| s.1).max(1e-9),
        "target_at_most_2x": ratio <= 2.0,
        "adapter": engine.ctx.adapter,
    }));
    Ok(())
}

/// One bake with the image cache and the mesh's vector needs emptied first, as a one-off bake
/// runs: (wall ms, the images stage's ms, its mapping of the vector layers' ms).
fn timed(engine: &Engine, mesh: &LoadedMesh, job: &Job) -> anyhow::Result<(f64, f64, f64)> {
    engine.clear_image_cache();
    mesh.forget_vector_needs();
    let t = Instant::now();
    let baked = engine.bake(mesh, job)?;
    let timings = &baked.report.timings;
    Ok((
        t.elapsed().as_secs_f64() * 1000.0,
        timings.images_ms,
        timings.vector_maps_ms,
    ))
}

/// resvg against the GPU alternative (`bake::vector_gpu`) over the images of `layers` at their
/// raster sizes, as the images stage would run each: resvg's renders on every core (with the
/// conversion to straight linear colour the stage uploads), against flattening and binning on
/// every core then one GPU draw a document (one point sample a pixel, read back; the kernel's own
/// time, submission to end, reported apart). Neither uploads or builds mipmaps. Once untimed (the kernel's compile), then `reps` times in turn;
/// one JSON line with the medians.
fn coverage(
    engine: &Engine,
    layers: &[Layer],
    reps: usize,
    (workload, side): (&str, u32),
    emit: &mut dyn FnMut(serde_json::Value),
) -> anyhow::Result<()> {
    use rayon::prelude::*;
    let docs: Vec<(Svg, [u32; 2])> = layers
        .iter()
        .map(|l| {
            let svg = l
                .colour_svg()?
                .ok_or_else(|| anyhow::anyhow!("a layer is no SVG"))?;
            let px = l.raster.unwrap_or_else(|| svg.default_px());
            Ok((svg, px))
        })
        .collect::<anyhow::Result<_>>()?;
    let cpu = || -> f64 {
        let t = Instant::now();
        let n: usize = docs
            .par_iter()
            .map(|(svg, px)| svg.render(*px, false).pixels.len())
            .sum();
        std::hint::black_box(n);
        t.elapsed().as_secs_f64() * 1000.0
    };
    let gpu = || -> anyhow::Result<[f64; 4]> {
        let t = Instant::now();
        let binned: Vec<_> = docs
            .par_iter()
            .map(|(svg, px)| svg.flatten(*px).map(|scene| bin(&scene, 1)))
            .collect::<Result<_, String>>()
            .map_err(|e| anyhow::anyhow!("flattening: {e}"))?;
        let prepare = t.elapsed().as_secs_f64() * 1000.0;
        let mut kernels = 0.0;
        for b in &binned {
            let (pixels, ms) = engine.draw_flat_timed(b)?;
            std::hint::black_box(pixels);
            kernels += ms;
        }
        let all = t.elapsed().as_secs_f64() * 1000.0;
        Ok([all, prepare, all - prepare, kernels])
    };
    let (_, first) = (cpu(), gpu()?);
    let (mut cpus, mut gpus) = (Vec::new(), Vec::new());
    for _ in 0..reps.max(1) {
        cpus.push(cpu());
        gpus.push(gpu()?);
    }
    let scene_sizes: Vec<(usize, usize)> = docs
        .iter()
        .map(|(svg, px)| {
            let scene = svg
                .flatten(*px)
                .unwrap_or(decalbake::io::vector_paths::FlatScene {
                    size: *px,
                    paths: Vec::new(),
                });
            (scene.segment_count(), bin(&scene, 1).refs())
        })
        .collect();
    let med = |k: usize| median(gpus.iter().map(|g| g[k]).collect());
    let resvg_ms = median(cpus.clone());
    emit(serde_json::json!({
        "bench": "vector", "workload": workload, "side": side, "variant": "coverage",
        "images": docs.len(),
        "pixels": docs.iter().map(|(_, p)| p[0] as u64 * p[1] as u64).sum::<u64>(),
        "segments": scene_sizes.iter().map(|s| s.0).sum::<usize>(),
        "tile_refs": scene_sizes.iter().map(|s| s.1).sum::<usize>(),
        "resvg_ms": resvg_ms, "resvg_all_ms": cpus,
        "gpu_ms": med(0), "gpu_prepare_ms": med(1), "gpu_draw_ms": med(2),
        "gpu_kernel_ms": med(3), "ratio_kernel_over_resvg": med(3) / resvg_ms.max(1e-9),
        "gpu_first_ms": first[0],
        "ratio_gpu_over_resvg": med(0) / resvg_ms.max(1e-9),
        "adapter": engine.ctx.adapter,
    }));
    Ok(())
}

/// The vector job with each layer's image a PNG of its rendering at the raster size its vector
/// bake chose (a text layer's line too), written into `dir` as `{stem}{index}.png`; and the
/// vector job's layers with that size set (`Layer::raster`).
fn bitmap_twin(
    engine: &Engine,
    mesh: &LoadedMesh,
    job: &Job,
    dir: &Path,
    stem: &str,
) -> anyhow::Result<(Job, Vec<Layer>)> {
    let baked = engine.bake(mesh, job)?;
    let mut out = job.clone();
    let mut sized_layers = Vec::new();
    for (i, (l, r)) in out.layers.iter_mut().zip(&baked.report.layers).enumerate() {
        let px = r
            .raster_px
            .ok_or_else(|| anyhow::anyhow!("layer {i} has no raster size"))?;
        let mut sized = l.clone();
        sized.raster = Some(px);
        if sized.ribbon.is_some() {
            // A text line's strip spans its curve: the straight path's length.
            sized.size[0] = LINE_LENGTH;
        }
        let img = sized.colour_image()?;
        sized_layers.push(sized.clone());
        let path = dir.join(format!("{stem}{i}.png"));
        decalbake::io::image::write_atomic(&path, &img.encode_png(8))?;
        // The same layer with the PNG (a text line keeps its ribbon and strip width).
        l.image = path;
        l.text = None;
    }
    Ok((out, sized_layers))
}

/// The glyph workload: `LINES` lines of `GLYPHS_PER_LINE` glyphs along straight paths across the
/// plane, em 0.03.
fn text_job(dir: &Path, plane: &Path, side: u32) -> anyhow::Result<Job> {
    let words = "vector glyphs on the surface ";
    let line: String = words.chars().cycle().take(GLYPHS_PER_LINE).collect();
    let layers: Vec<serde_json::Value> = (0..LINES)
        .map(|k| {
            let y = 0.04 + 0.92 * k as f32 / (LINES - 1) as f32;
            // Points 0.12 apart: one chart joins two of them.
            let path: Vec<[f32; 3]> = (0..=8)
                .map(|i| [0.02 + LINE_LENGTH * i as f32 / 8.0, y, 0.0])
                .collect();
            serde_json::json!({ "kind": "text", "text": line, "size": 0.03,
                "path": path, "interpolate": "linear", "align": "start",
                "fit": "shrink" })
        })
        .collect();
    let text = serde_json::json!({ "mesh": plane, "texture": { "width": side, "height": side },
        "layers": layers, "output": { "texture": null, "report": null } })
    .to_string();
    Ok(Job::parse(&text, &dir.join("text.json"), dir, dir)?)
}

/// The unit square at z = 0 in 64 × 64 cells, UV (x, 1 − y), written as a GLB.
fn write_plane(path: &Path) -> anyhow::Result<()> {
    let n = 64u32;
    let mut mesh = decalbake::mesh::Mesh {
        source: path.to_path_buf(),
        ..Default::default()
    };
    let mut uv = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (x, y) = (i as f32 / n as f32, j as f32 / n as f32);
            mesh.positions.push(glam::Vec3::new(x, y, 0.0));
            mesh.normals.push(glam::Vec3::Z);
            uv.push(glam::Vec2::new(x, 1.0 - y));
        }
    }
    mesh.uv_sets = vec![uv];
    for j in 0..n {
        for i in 0..n {
            let a = j * (n + 1) + i;
            mesh.triangles.push([a, a + 1, a + n + 2]);
            mesh.triangles.push([a, a + n + 2, a + n + 1]);
        }
    }
    let written = decalbake::output::gltf::write_model(&mesh, &[], path)?;
    decalbake::io::image::write_atomic(path, &written.files[0].1)?;
    Ok(())
}
