// SPDX-License-Identifier: MIT OR Apache-2.0
//! Seam continuity on a real model with 13 UV islands (Spot, bundled in `assets/`): a decal straddling
//! UV seams gives the same colour on both sides. Each surface point on a seam edge has two UVs (one
//! per island); the baked texture, sampled bilinearly at both, must agree.
//!
//! Metric and tolerance: per channel, linear light, at 7 points along every seam edge under the decal.
//! The decal is a linear colour ramp (slope 0.8 / 0.3 per model unit). A texture can only agree
//! across a seam to within what one texel represents on the coarser side, so each point's tolerance is
//! 2 × slope × (surface length of one texel, in the worst direction, of the coarser of the two
//! triangles) + 0.01: bilinear reconstruction is exact for a ramp inside an island, and at the island
//! border padding repeats edge texels, so the 2×2 bilinear footprint can be off by up to about two
//! texels of ramp. Where a triangle's
//! UVs are so squashed that one texel spans more than 0.01 model units (Spot has sliver triangles in
//! UV, almost zero width), no bake can resolve the decal and the edge is skipped. The mean difference
//! must also stay under 0.01.

mod common;
use common::*;
use decalbake::bake::cpu::sample_bilinear;
use decalbake::io::image::LinearImage;
use decalbake::mesh::{Mesh, Topology, DEFAULT_WELD_TOLERANCE};
use decalbake::Job;
use glam::Vec2;
use std::collections::HashMap;
use std::path::Path;

/// One side of a seam edge: the UVs of its two endpoints and the triangle.
type Side = (Vec2, Vec2, usize);

#[test]
fn planar_decal_across_uv_seams_is_continuous_on_spot() {
    seam_check("planar");
}

#[test]
fn expmap_decal_across_uv_seams_is_continuous_on_spot() {
    seam_check("expmap");
}

#[test]
fn lscm_decal_across_uv_seams_is_continuous_on_spot() {
    seam_check("lscm");
}

#[test]
fn hybrid_decal_across_uv_seams_is_continuous_on_spot() {
    seam_check("hybrid");
}

/// A stroke over Spot's UV seams where they are densest (along the densest seam edge, so the band
/// straddles seams for its whole length) paints both sides of every seam under its middle: an
/// opaque one-colour brush, so both sides must match to 0.01 (a stroke that stopped at a seam, as a
/// UV-space brush does, leaves the base on one side). A ramped brush would not do here: where an
/// opaque stamp covers the one before, the step between their charts' values is a property of
/// stamping, not of seams (the decal tests above check charts across seams with a ramp).
#[test]
fn stroke_across_uv_seams_is_continuous_on_spot() {
    let dir = scratch("seam-stroke");
    let spot = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/spot.glb");
    let mesh = Mesh::load(&spot).unwrap();
    let topo = Topology::build(&mesh, DEFAULT_WELD_TOLERANCE);
    let seams = spot_seams(&mesh, &topo);
    let size = 0.3f32;
    let e = densest_seam(&topo, &seams, size);
    let center = 0.5 * (topo.positions[e.0 as usize] + topo.positions[e.1 as usize]);
    let d = (topo.positions[e.1 as usize] - topo.positions[e.0 as usize]).normalize();
    let pts = [center - 0.2 * d, center, center + 0.2 * d];
    let mut brush = LinearImage::solid(64, 64, [0.0; 4]);
    for y in 0..64 {
        for x in 0..64 {
            brush.pixels[y * 64 + x] = [0.2, 0.9, 0.3, 1.0];
        }
    }
    std::fs::write(dir.join("across.png"), brush.encode_png(16)).unwrap();
    let layer = serde_json::json!({ "kind": "stroke", "image": "across.png",
        "path": pts.map(|p| p.to_array()), "size": [size, size], "spacing": 0.2, "method": "lscm" });
    let text = serde_json::json!({ "mesh": spot, "texture": { "width": 512, "height": 512, "padding": 8, "samples": 4 },
        "layers": [layer], "output": { "texture": null, "bit_depth": 16, "report": null } });
    let job = Job::parse(&text.to_string(), &dir.join("job.json"), &dir, &dir).unwrap();
    let engine = engine();
    let loaded = engine.load_mesh(&spot).unwrap();
    let baked = engine.bake(&loaded, &job).unwrap();
    let l = &baked.report.layers[0];
    eprintln!("stroke: {:?}, distortion {:?}", l.stroke, l.distortion);
    let texture = read_texture(&baked, &dir);
    let base = mesh
        .material
        .as_ref()
        .unwrap()
        .base_color_texture
        .as_ref()
        .unwrap();
    // The middle of the band: within 0.3 of its half-width of the path's chords, between its ends.
    let near = |p: glam::Vec3| {
        pts.windows(2).any(|w| {
            let (a, b) = (w[0], w[1]);
            let t = (p - a).dot(b - a) / (b - a).length_squared();
            (0.0..=1.0).contains(&t) && (a + (b - a) * t).distance(p) < 0.3 * 0.5 * size
        })
    };
    let r = compare_seams(&mesh, &topo, &seams, (&texture, base), &near, &|_| 0.0);
    r.check("stroke");
}

/// A ribbon over Spot's UV seams where they are densest (its curve along the densest seam edge, so
/// the strip straddles seams for its length), with the decal tests' colour ramp stretched over
/// the strip: both sides of every seam within the middle of the strip (0.3 of its half-width from
/// the curve, away from its ends) agree within the decal tests' tolerance, the ramp's slope on the
/// surface being 0.8 over the strip's shorter side (the ribbon's map keeps lengths, up to the
/// surface's curvature under a strip this narrow).
#[test]
fn ribbon_across_uv_seams_is_continuous_on_spot() {
    let dir = scratch("seam-ribbon");
    let spot = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/spot.glb");
    let mesh = Mesh::load(&spot).unwrap();
    let topo = Topology::build(&mesh, DEFAULT_WELD_TOLERANCE);
    let seams = spot_seams(&mesh, &topo);
    let width = 0.3f32;
    let e = densest_seam(&topo, &seams, 0.3);
    let center = 0.5 * (topo.positions[e.0 as usize] + topo.positions[e.1 as usize]);
    let d = (topo.positions[e.1 as usize] - topo.positions[e.0 as usize]).normalize();
    let pts = [center - 0.2 * d, center, center + 0.2 * d];
    let mut ramp = LinearImage::solid(64, 16, [0.0; 4]);
    for y in 0..16 {
        for x in 0..64 {
            ramp.pixels[y * 64 + x] = [
                0.1 + 0.8 * x as f32 / 63.0,
                0.1 + 0.8 * y as f32 / 15.0,
                0.5,
                1.0,
            ];
        }
    }
    std::fs::write(dir.join("ramp.png"), ramp.encode_png(16)).unwrap();
    let layer = serde_json::json!({ "kind": "ribbon", "image": "ramp.png",
        "path": pts.map(|p| p.to_array()), "width": width });
    let text = serde_json::json!({ "mesh": spot, "texture": { "width": 512, "height": 512, "padding": 8, "samples": 4 },
        "layers": [layer], "output": { "texture": null, "bit_depth": 16, "report": null } });
    // Kept beside the texture, to look at (`decalbake bake` it with a preview).
    std::fs::write(dir.join("job.json"), text.to_string()).unwrap();
    let job = Job::parse(&text.to_string(), &dir.join("job.json"), &dir, &dir).unwrap();
    let engine = engine();
    let loaded = engine.load_mesh(&spot).unwrap();
    let baked = engine.bake(&loaded, &job).unwrap();
    let l = &baked.report.layers[0];
    eprintln!(
        "ribbon: {} triangles, distortion {:?}",
        l.triangles_covered, l.distortion
    );
    let texture = read_texture(&baked, &dir);
    let base = mesh
        .material
        .as_ref()
        .unwrap()
        .base_color_texture
        .as_ref()
        .unwrap();
    let near = |p: glam::Vec3| {
        pts.windows(2).any(|w| {
            let (a, b) = (w[0], w[1]);
            let t = (p - a).dot(b - a) / (b - a).length_squared();
            (0.05..=0.95).contains(&t) && (a + (b - a) * t).distance(p) < 0.3 * 0.5 * width
        })
    };
    let slope = 0.8 / width;
    let r = compare_seams(&mesh, &topo, &seams, (&texture, base), &near, &|_| slope);
    r.check("ribbon");
}

fn seam_check(method: &str) {
    let dir = scratch(&format!("seam-{method}"));
    let spot = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/spot.glb");
    let mesh = Mesh::load(&spot).unwrap();
    let topo = Topology::build(&mesh, DEFAULT_WELD_TOLERANCE);

    let seams = spot_seams(&mesh, &topo);

    // Centre the decal where seam edges are densest.
    let size = 0.3f32;
    let e = densest_seam(&topo, &seams, size);
    let center = 0.5 * (topo.positions[e.0 as usize] + topo.positions[e.1 as usize]);

    // A smooth decal: a colour ramp, opaque.
    let mut decal = LinearImage::solid(64, 64, [0.0; 4]);
    for y in 0..64 {
        for x in 0..64 {
            decal.pixels[y * 64 + x] = [
                0.1 + 0.8 * x as f32 / 63.0,
                0.1 + 0.8 * y as f32 / 63.0,
                0.5,
                1.0,
            ];
        }
    }
    std::fs::write(dir.join("ramp.png"), decal.encode_png(16)).unwrap();
    let job_text = format!(
        r#"{{ "mesh": "{}", "texture": {{ "width": 512, "height": 512, "padding": 8, "samples": 4 }},
            "layers": [ {{ "image": "ramp.png", "at": [{}, {}, {}], "size": [{size}, {size}], "depth": 0.3, "method": "{method}" }} ],
            "output": {{ "texture": null, "bit_depth": 16, "report": null }} }}"#,
        spot.display(),
        center.x,
        center.y,
        center.z
    );
    let job = Job::parse(&job_text, &dir.join("job.json"), &dir, &dir).unwrap();
    let engine = engine();
    let loaded = engine.load_mesh(&spot).unwrap();
    let baked = engine.bake(&loaded, &job).unwrap();
    let layer = &baked.report.layers[0];
    eprintln!(
        "{method}: distortion {:?}, chart {:?}",
        layer.distortion, layer.chart
    );
    let texture = read_texture(&baked, &dir);
    let base = mesh
        .material
        .as_ref()
        .unwrap()
        .base_color_texture
        .as_ref()
        .unwrap();

    let f = &layer.frame;
    let inside = |p: glam::Vec3| {
        let d = p - f.center;
        d.dot(f.axis_u).abs() < 0.4 * size
            && d.dot(f.axis_v).abs() < 0.4 * size
            && d.dot(f.normal).abs() < 0.25
    };
    // The ramp changes by 0.8 across the decal's size in its own coordinates; on the surface that
    // slope is multiplied by the map's largest stretch s1 (1 for a length-preserving map; a
    // conformal chart scales by its local conformal factor), read from the layer's coordinates.
    let rows = engine.layer_param(&loaded, &job, 0).unwrap();
    let mut coords = vec![[0.0f32; 4]; topo.positions.len()];
    for r in &rows {
        coords[r.vertex as usize] = [r.uv[0], r.uv[1], 0.0, 1.0];
    }
    let stretch = |t: usize| {
        let d = decalbake::maps::distortion::distortion(&topo, (&coords, None), &[t as u32]);
        (d.area_ratio_max.abs() * d.angle_distortion_max)
            .sqrt()
            .max(1.0)
    };
    let slope = 0.8 / size;
    let r = compare_seams(&mesh, &topo, &seams, (&texture, base), &inside, &|t| {
        slope * stretch(t)
    });
    r.check(method);
}

/// What [`compare_seams`] found.
struct Compared {
    /// Seam points compared.
    n: usize,
    /// Sub-texel edges skipped.
    skipped: usize,
    /// Points where the layer changed the base.
    visible: usize,
    /// Worst difference / tolerance.
    worst: f32,
    /// Mean difference.
    mean: f32,
}

impl Compared {
    fn check(&self, name: &str) {
        eprintln!(
            "{name}: seam points compared: {} ({} sub-texel edges skipped), layer visible at {}; worst difference / tolerance = {:.3}, mean difference = {:.5}",
            self.n, self.skipped, self.visible, self.worst, self.mean
        );
        assert!(
            self.n >= 40,
            "too few seam points under the layer: {}",
            self.n
        );
        assert!(
            self.visible * 10 >= self.n * 9,
            "the layer should cover the seam points: {} of {}",
            self.visible,
            self.n
        );
        assert!(self.mean <= 0.01, "seam discontinuity: mean {}", self.mean);
    }
}

/// Compares both sides of every seam edge whose endpoints are `inside`, at 7 points each, in the
/// red and green channels' ramp: each point's tolerance is 2 × `slope(t)` (the ramp's slope on the
/// surface, model units) × the coarser side's texel footprint + 0.01 (see the file's doc).
fn compare_seams(
    mesh: &Mesh,
    topo: &Topology,
    seams: &[Seam],
    (texture, base): (&LinearImage, &LinearImage),
    inside: &dyn Fn(glam::Vec3) -> bool,
    slope: &dyn Fn(usize) -> f32,
) -> Compared {
    let (mut n, mut sum, mut worst, mut visible, mut skipped) = (0, 0.0f32, 0.0f32, 0, 0);
    for ((a, b), (a0, b0, t0), (a1, b1, t1)) in seams {
        let (pa, pb) = (topo.positions[*a as usize], topo.positions[*b as usize]);
        if !inside(pa) || !inside(pb) {
            continue;
        }
        let texel = footprint(mesh, topo, *t0).max(footprint(mesh, topo, *t1));
        if texel > 0.01 {
            // Fewer than 3 texels across 0.03 model units there: no bake can resolve the layer.
            skipped += 1;
            continue;
        }
        let tol = 2.0 * slope(*t0).max(slope(*t1)) * texel + 0.01;
        for k in 1..8 {
            let t = k as f32 / 8.0;
            // UVs outside [0, 1] repeat (glTF's default wrap), as the bake draws them.
            let wrap = |u: Vec2| Vec2::new(u.x.rem_euclid(1.0), u.y.rem_euclid(1.0));
            let c0 = sample_bilinear(texture, wrap(a0.lerp(*b0, t)));
            let c1 = sample_bilinear(texture, wrap(a1.lerp(*b1, t)));
            let orig = sample_bilinear(base, wrap(a0.lerp(*b0, t)));
            if (c0[2] - orig[2]).abs() > 0.05 || (c0[0] - orig[0]).abs() > 0.05 {
                visible += 1;
            }
            for ch in 0..3 {
                let d = (c0[ch] - c1[ch]).abs();
                assert!(d <= tol, "seam edge {a}-{b} at t = {t}: sides differ by {d} in channel {ch} (tolerance {tol}): {c0:?} vs {c1:?} at uv {:?} / {:?}", a0.lerp(*b0, t) * 512.0, a1.lerp(*b1, t) * 512.0);
                worst = worst.max(d / tol);
                sum += d;
            }
            n += 1;
        }
    }
    Compared {
        n,
        skipped,
        visible,
        worst,
        mean: sum / (3 * n.max(1)) as f32,
    }
}

/// A seam edge (welded endpoints) and its two sides.
type Seam = ((u32, u32), Side, Side);

/// Spot's UV seam edges: welded edges whose two triangles use different UVs for the same endpoints.
fn spot_seams(mesh: &Mesh, topo: &Topology) -> Vec<Seam> {
    let uvs = &mesh.uv_sets[0];
    let mut sides: HashMap<(u32, u32), Vec<Side>> = HashMap::new();
    for (t, tri) in mesh.triangles.iter().enumerate() {
        for k in 0..3 {
            let (sa, sb) = (tri[k], tri[(k + 1) % 3]);
            let (wa, wb) = (topo.welded_of[sa as usize], topo.welded_of[sb as usize]);
            let (key, ua, ub) = if wa < wb {
                ((wa, wb), uvs[sa as usize], uvs[sb as usize])
            } else {
                ((wb, wa), uvs[sb as usize], uvs[sa as usize])
            };
            sides.entry(key).or_default().push((ua, ub, t));
        }
    }
    let seams: Vec<Seam> = sides
        .iter()
        .filter(|(_, s)| {
            s.len() == 2 && (s[0].0.distance(s[1].0) > 1e-4 || s[0].1.distance(s[1].1) > 1e-4)
        })
        .map(|(k, s)| (*k, s[0], s[1]))
        .collect();
    assert!(seams.len() > 50, "Spot has UV seams, found {}", seams.len());
    seams
}

/// Surface length of one texel (at 512²) in the worst direction of triangle t (largest singular
/// value of the texel -> surface Jacobian): how coarse the texture is there.
fn footprint(mesh: &Mesh, topo: &Topology, t: usize) -> f32 {
    let uvs = &mesh.uv_sets[0];
    let p = topo.triangles[t].map(|v| topo.positions[v as usize]);
    let q = mesh.triangles[t].map(|s| uvs[s as usize] * 512.0);
    let (e1, e2) = (q[1] - q[0], q[2] - q[0]);
    let det = e1.perp_dot(e2);
    if det.abs() < 1e-9 {
        return f32::INFINITY;
    }
    // J = [P1-P0, P2-P0] * inverse([e1 e2]).
    let inv = [[e2.y / det, -e2.x / det], [-e1.y / det, e1.x / det]];
    let (d1, d2) = (p[1] - p[0], p[2] - p[0]);
    let c0 = d1 * inv[0][0] + d2 * inv[1][0];
    let c1 = d1 * inv[0][1] + d2 * inv[1][1];
    let (a, b, c) = (c0.dot(c0), c0.dot(c1), c1.dot(c1));
    (0.5 * (a + c + ((a - c).powi(2) + 4.0 * b * b).sqrt())).sqrt()
}

/// The baked 512² texture in linear light, also written to `dir/baked.png` to look at.
fn read_texture(baked: &decalbake::Baked, dir: &Path) -> LinearImage {
    let texture = LinearImage {
        width: 512,
        height: 512,
        pixels: (0..512 * 512)
            .map(|i| baked.linear(i % 512, i / 512))
            .collect(),
    };
    std::fs::write(dir.join("baked.png"), texture.encode_png(8)).unwrap();
    texture
}

/// The seam edge with the most seam edges within 0.4 × `size` of its midpoint (a layer `size` wide
/// centred there straddles the most seams).
fn densest_seam(topo: &Topology, seams: &[Seam], size: f32) -> (u32, u32) {
    let mid = |e: &(u32, u32)| 0.5 * (topo.positions[e.0 as usize] + topo.positions[e.1 as usize]);
    seams
        .iter()
        .map(|(e, _, _)| *e)
        .max_by_key(|e| {
            seams
                .iter()
                .filter(|(f, _, _)| mid(f).distance(mid(e)) < 0.4 * size)
                .count()
        })
        .unwrap()
}
