// SPDX-License-Identifier: MIT OR Apache-2.0
//! Conformal decals keep the size they were asked for: the LSCM and hybrid charts are scaled at the
//! placed point (not by a global area fit), flattened only from disc-shaped regions, and never fold
//! into the decal's footprint. Measured the way a user would, through `decalbake param`'s
//! coordinates (`Engine::layer_param`), with this file's own measuring code (not the engine's report).
//!
//! Decals: one square decal at a model's highest vertex, 0.12 × the bounding-box diagonal wide.
//! Models: Spot's horn tip and Bob's top (bundled, CC0), and a cube standing on a corner (made here:
//! the highest vertex is a sharp corner, the CAD case the shared fandisk stands for; fandisk itself
//! has no licence that lets it be bundled, so `decalbake bench --scale` measures it).

mod common;
use common::*;
use decalbake::bake::{size_figures, ParamRow, SizeFigures};
use decalbake::mesh::{Mesh, Topology};
use decalbake::{Engine, Job, LoadedMesh};
use glam::{Vec2, Vec3};
use std::path::Path;

/// Scale bound at the placed point (the issue's): 10 %.
const SCALE_TOL: f64 = 0.10;
/// Painted-area bound against the exponential map's (the issue's): 15 %.
const AREA_TOL: f64 = 0.15;

/// The size figures of a decal's `param` rows (`bake::size_figures`: the measure of the issue and of
/// `decalbake bench --scale`, computed from the exported coordinates, not from the chart report).
fn measure(topo: &Topology, rows: &[ParamRow], p: Vec3, size: f64) -> SizeFigures {
    size_figures(topo, rows, p.as_dvec3(), size)
}

/// The job of one square decal of side `size` at `at` with `method` (its image is never read).
fn decal_job(at: Vec3, size: f64, method: &str) -> Job {
    let text = serde_json::json!({
        "mesh": "unused.glb",
        "layers": [{ "image": "unused.png", "at": at.to_array(), "size": [size, size],
                     "up": [0, 0, 1], "method": method }]
    })
    .to_string();
    Job::parse(
        &text,
        Path::new("decal.json"),
        Path::new("."),
        Path::new("."),
    )
    .unwrap()
}

/// The highest welded vertex and 0.12 × the bounding-box diagonal.
fn top_and_size(mesh: &LoadedMesh) -> (Vec3, f64) {
    let topo = &mesh.topo;
    let top = topo
        .positions
        .iter()
        .copied()
        .max_by(|a, b| a.y.total_cmp(&b.y))
        .unwrap();
    let (lo, hi) = mesh.mesh.bounds();
    (top, 0.12 * (hi - lo).length() as f64)
}

fn measure_method(engine: &Engine, mesh: &LoadedMesh, method: &str) -> SizeFigures {
    let (top, size) = top_and_size(mesh);
    let rows = engine
        .layer_param(mesh, &decal_job(top, size, method), 0)
        .unwrap();
    measure(&mesh.topo, &rows, top, size)
}

/// A cube of side 1, each face an `n` × `n` grid, turned so that a corner is the highest point.
fn cube_on_corner(n: u32) -> Mesh {
    let rot = glam::Quat::from_rotation_arc(Vec3::ONE.normalize(), Vec3::Y);
    let (mut positions, mut triangles) = (Vec::new(), Vec::new());
    for axis in 0..3 {
        for side in [-0.5f32, 0.5] {
            let base = positions.len() as u32;
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            for j in 0..=n {
                for i in 0..=n {
                    let mut p = [0.0f32; 3];
                    p[axis] = side;
                    p[u] = i as f32 / n as f32 - 0.5;
                    p[v] = j as f32 / n as f32 - 0.5;
                    positions.push(rot * Vec3::from(p));
                }
            }
            for j in 0..n {
                for i in 0..n {
                    let a = base + j * (n + 1) + i;
                    let (b, c, d) = (a + 1, a + n + 2, a + n + 1);
                    // Outward winding: (u, v, axis) is right-handed; flip on the negative side.
                    if side > 0.0 {
                        triangles.push([a, b, c]);
                        triangles.push([a, c, d]);
                    } else {
                        triangles.push([a, c, b]);
                        triangles.push([a, d, c]);
                    }
                }
            }
        }
    }
    Mesh {
        source: "cube on a corner".into(),
        normals: vec![Vec3::ZERO; positions.len()],
        uv_sets: vec![vec![Vec2::ZERO; positions.len()]],
        positions,
        triangles,
        primitives: vec![],
        material: None,
    }
}

/// A torus around the y axis (ring radius `big`, tube radius `small`), `m` × `n` quads.
fn torus(big: f32, small: f32, m: u32, n: u32) -> Mesh {
    let mut positions = Vec::new();
    for i in 0..m {
        let a = i as f32 / m as f32 * std::f32::consts::TAU;
        for j in 0..n {
            let b = j as f32 / n as f32 * std::f32::consts::TAU;
            let r = big + small * b.cos();
            positions.push(Vec3::new(r * a.cos(), small * b.sin(), r * a.sin()));
        }
    }
    let id = |i: u32, j: u32| (i % m) * n + (j % n);
    let mut triangles = Vec::new();
    for i in 0..m {
        for j in 0..n {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            triangles.push([a, c, b]);
            triangles.push([a, d, c]);
        }
    }
    Mesh {
        source: "torus".into(),
        normals: vec![Vec3::ZERO; positions.len()],
        uv_sets: vec![vec![Vec2::ZERO; positions.len()]],
        positions,
        triangles,
        primitives: vec![],
        material: None,
    }
}

fn bundled(engine: &Engine, name: &str) -> LoadedMesh {
    engine
        .load_mesh(
            &Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("assets")
                .join(name),
        )
        .unwrap()
}

/// At Spot's horn tip, Bob's top and a cube's corner, lscm and hybrid decals have scale 1 (within
/// 10 %) at the placed point, like the exponential map, and no flipped or collapsed triangle in
/// their footprint. Before the fix the horn tip's scale was 0.13 (lscm and hybrid: the chart was
/// scaled to match its total area, and a horn's conformal factor varies eightfold).
#[test]
fn conformal_decals_keep_their_size_at_the_placed_point() {
    let engine = engine();
    let meshes = [
        ("spot horn tip", bundled(&engine, "spot.glb")),
        ("bob top", bundled(&engine, "bob.glb")),
        ("cube corner", engine.prepare(cube_on_corner(24)).unwrap()),
    ];
    let mut bad = Vec::new();
    for (name, mesh) in &meshes {
        for method in ["expmap", "lscm", "hybrid"] {
            let m = measure_method(&engine, mesh, method);
            eprintln!("{name:14} {method:7} {m:?}");
            if method == "expmap" {
                continue;
            }
            if (m.scale_fifth - 1.0).abs() > SCALE_TOL {
                bad.push(format!("{name} {method}: scale {:.3}", m.scale_fifth));
            }
            if m.flipped + m.collapsed + m.torn > 0 || m.footprint < 20 {
                bad.push(format!("{name} {method}: footprint {m:?}"));
            }
        }
    }
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}

/// Away from a cone-like tip the painted surface area matches the exponential map's within 15 %
/// (Bob's top: about 6 % apart). At a sharp tip it cannot: a conformal flattening of a cone of
/// total angle 2πk has |z| ∝ r^(1/k) around the apex, so with the scale fixed at the point the
/// image grows faster than the surface and the square covers less of it (Spot's horn tip, k ≈ 0.55:
/// about half the exponential map's area; the exponential map instead leaves a wedge of the image
/// unused). Printed, not asserted, there.
#[test]
fn painted_area_matches_the_exponential_map_away_from_tips() {
    let engine = engine();
    let bob = bundled(&engine, "bob.glb");
    let expmap = measure_method(&engine, &bob, "expmap").painted_area;
    for method in ["lscm", "hybrid"] {
        let m = measure_method(&engine, &bob, method).painted_area;
        eprintln!("bob top {method}: painted {m:.5} vs expmap {expmap:.5}");
        assert!(
            (m / expmap - 1.0).abs() <= AREA_TOL,
            "bob top {method}: painted area {m} vs the exponential map's {expmap}"
        );
    }
    let spot = bundled(&engine, "spot.glb");
    let e = measure_method(&engine, &spot, "expmap").painted_area;
    let l = measure_method(&engine, &spot, "lscm").painted_area;
    eprintln!("spot horn tip: lscm painted {l:.5} vs expmap {e:.5} (a cone tip: see the doc)");
}

/// A decal wider than a torus's tube: the chart's selection wraps around the tube (an annulus,
/// Euler characteristic 0, two boundary loops). The region is shrunk to a disc (the tube cut open
/// where the growing front meets itself), the report says so, and the chart has no fold in its
/// footprint. Without the disc check the annulus's conformal map crushes one side of the tube.
#[test]
fn a_region_with_a_handle_is_cut_to_a_disc_without_folds() {
    let engine = engine();
    let mesh = engine.prepare(torus(1.0, 0.25, 96, 32)).unwrap();
    let top = Vec3::new(1.0, 0.25, 0.0);
    let size = 0.9;
    for method in ["lscm", "hybrid"] {
        let rows = engine
            .layer_param(&mesh, &decal_job(top, size, method), 0)
            .unwrap();
        let m = measure(&mesh.topo, &rows, top, size);
        eprintln!("torus {method}: {m:?}");
        assert!(
            m.flipped + m.collapsed + m.torn == 0,
            "torus {method}: folds in the footprint: {m:?}"
        );
        assert!(
            (m.scale_fifth - 1.0).abs() <= SCALE_TOL,
            "torus {method}: scale {}",
            m.scale_fifth
        );
    }
    // The report of an lscm bake says the region was not a disc and what was done.
    let dir = scratch("torus");
    let img = dir.join("d.png");
    decalbake::io::image::write_atomic(
        &img,
        &decalbake::io::image::LinearImage::solid(8, 8, [1.0, 0.0, 0.0, 1.0]).encode_png(8),
    )
    .unwrap();
    let mut job = decal_job(top, size, "lscm");
    job.layers[0].image = img;
    job.width = 64;
    job.height = 64;
    let baked = engine.bake(&mesh, &job).unwrap();
    let chart = baked.report.layers[0]
        .chart
        .expect("an lscm layer has a chart");
    eprintln!("torus lscm report: {chart:?}");
    assert!(!chart.region.disc, "the torus selection is not a disc");
    assert_eq!(chart.region.euler_characteristic, 0);
    assert_eq!(
        chart.region.fix,
        decalbake::maps::chart::region::RegionFix::ShrunkToDisc
    );
    assert_eq!(
        chart.footprint_flipped + chart.footprint_collapsed + chart.footprint_torn,
        0
    );
    assert!(
        baked
            .report
            .warnings
            .iter()
            .any(|w| w.contains("not a disc")),
        "{:?}",
        baked.report.warnings
    );
}

/// A decal wider than the tube's circumference: any disc of the tube under it is cut open inside
/// the decal, where the cut's triangles (their corners on opposite sides of the chart) would be drawn
/// flipped or stretched across it. The fold check finds them (before it looked only at the chart's
/// own triangles and let them through), the re-solves on smaller regions cannot avoid them, and
/// `decalbake param` (like the bake) refuses the layer with a message that names it and says what to
/// do.
#[test]
fn a_decal_wrapping_a_handle_is_refused() {
    let engine = engine();
    let mesh = engine.prepare(torus(1.0, 0.25, 96, 32)).unwrap();
    let top = Vec3::new(1.0, 0.25, 0.0);
    for method in ["lscm", "hybrid"] {
        let job = decal_job(top, 2.0, method);
        let err = engine.layer_param(&mesh, &job, 0).unwrap_err().to_string();
        eprintln!("{method}: {err}");
        assert!(
            err.contains("layer 0")
                && err.contains("folds inside the decal")
                && err.contains("torn"),
            "{method}: {err}"
        );
    }
}

/// The region checks on known shapes: a disc, an annulus (a tube), a closed sphere; and growing a
/// disc out of the annulus gives a disc.
#[test]
fn region_topology_and_disc_growing() {
    use decalbake::maps::chart::region::{grow_disc, topology};
    let torus_mesh = torus(1.0, 0.25, 48, 16);
    let topo = Topology::build(&torus_mesh, decalbake::mesh::DEFAULT_WELD_TOLERANCE);
    let all: Vec<u32> = (0..topo.triangles.len() as u32).collect();
    let t = topology(&topo, &all);
    assert_eq!(
        (t.euler_characteristic, t.boundary_loops, t.disc),
        (0, 0, false)
    );
    // A ring of the tube (quads i in 0..6, all j): an annulus.
    let tube: Vec<u32> = (0..6 * 16 * 2).collect();
    let a = topology(&topo, &tube);
    assert_eq!(
        (a.euler_characteristic, a.boundary_loops, a.components),
        (0, 2, 1)
    );
    // Part of it (j in 0..8): a disc.
    let half: Vec<u32> = tube.iter().copied().filter(|t| (t / 2) % 16 < 8).collect();
    assert!(topology(&topo, &half).disc);
    let grown = grow_disc(&topo, &tube, 0, topo.positions[0].as_dvec3());
    let g = topology(&topo, &grown);
    assert!(g.disc, "{g:?}");
    assert!(
        grown.len() * 10 >= tube.len() * 9,
        "the disc keeps most of the tube"
    );
}
