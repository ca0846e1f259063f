// SPDX-License-Identifier: MIT OR Apache-2.0
//! Discrete exponential maps (Schmidt et al. 2006): the GPU relaxation reaches the same fixed point
//! as the serial Dijkstra twin (`maps::expmap::dem_cpu`); both are exact on a plane; the error against the
//! analytic exponential map of a sphere is measured and printed.

mod common;
use common::*;
use decalbake::maps::expmap::sphere::{icosphere, peers_seed_vertex, unit_sphere_log_errors};
use decalbake::maps::expmap::{dem_cpu, Accuracy, Options, Seed};
use decalbake::mesh::SurfaceData;
use decalbake::mesh::{Mesh, Topology, DEFAULT_WELD_TOLERANCE};
use glam::Vec3;
use std::path::Path;

/// A flat n×n grid on z = 0 over [0, 1]², with UVs.
fn plane(dir: &Path, n: u32) -> std::path::PathBuf {
    let mut pos = Vec::new();
    let mut uv = Vec::new();
    let mut idx = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (x, y) = (i as f32 / n as f32, j as f32 / n as f32);
            // A little deterministic jitter so the grid is irregular.
            let jx = if i > 0 && i < n {
                0.2 * ((i * 7 + j * 3) % 5) as f32 / 5.0 / n as f32
            } else {
                0.0
            };
            pos.push([x + jx, y, 0.0]);
            uv.push([x, 1.0 - y]);
        }
    }
    for j in 0..n {
        for i in 0..n {
            let a = j * (n + 1) + i;
            idx.extend_from_slice(&[a, a + 1, a + n + 2, a, a + n + 2, a + n + 1]);
        }
    }
    let p = dir.join("plane.glb");
    write_glb(&p, &pos, Some(&uv), &idx);
    p
}

fn seed_at(topo: &Topology, point: Vec3, e1: Vec3) -> Seed {
    Seed::nearest(topo, point, e1)
}

#[test]
fn plane_maps_are_exact_on_gpu_and_cpu() {
    let dir = scratch("expmap-plane");
    let path = plane(&dir, 24);
    let engine = engine();
    let mesh = engine.load_mesh(&path).unwrap();
    let topo = Topology::build(&Mesh::load(&path).unwrap(), DEFAULT_WELD_TOLERANCE);
    let seed = seed_at(&topo, Vec3::new(0.43, 0.51, 0.0), Vec3::new(1.0, 0.3, 0.0));
    let opts = Options {
        radius: 0.35,
        curvature_stop: f32::INFINITY,
        accuracy: Accuracy::Fast,
    };
    let cpu = dem_cpu(&topo, &seed, opts, &SurfaceData::new(&topo));
    let gpu = engine.expmaps(&mesh, &[(seed, opts)]).unwrap();
    let (coords, res) = &gpu[0];
    assert_eq!(res.converged, 1, "relaxation converged: {res:?}");
    let mut reached = 0;
    for (v, p) in topo.positions.iter().enumerate() {
        let exact = [
            (*p - seed.point).dot(seed.e1),
            (*p - seed.point).dot(seed.e2),
        ];
        if cpu.dist[v].is_finite() {
            reached += 1;
            for k in 0..2 {
                // Exact up to f32 rounding accumulated along the path (< 40 edges of length 0.04).
                assert!(
                    (cpu.uv[v][k] - exact[k]).abs() < 2e-6,
                    "CPU vertex {v}: {:?} vs {exact:?}",
                    cpu.uv[v]
                );
                assert!(
                    (coords[v][k] - exact[k]).abs() < 2e-6,
                    "GPU vertex {v}: {:?} vs {exact:?}",
                    coords[v]
                );
            }
        }
        assert_eq!(
            coords[v][3] > 0.5,
            cpu.dist[v].is_finite(),
            "vertex {v}: reached on one side only"
        );
    }
    // The disc of radius 0.35 holds about pi * 0.35^2 / (1/24)^2 = 220 vertices, plus one ring.
    assert!(reached > 200 && reached < 400, "reached {reached}");
    assert_eq!(res.reached as usize, reached);
}

#[test]
fn gpu_relaxation_reaches_the_dijkstra_fixed_point_on_spot() {
    let spot = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/spot.glb");
    let engine = engine();
    let mesh = engine.load_mesh(&spot).unwrap();
    let topo = Topology::build(&Mesh::load(&spot).unwrap(), DEFAULT_WELD_TOLERANCE);
    let k = SurfaceData::new(&topo);
    let points = [
        Vec3::new(0.33, 0.0, 0.45),
        Vec3::new(0.0, 0.3, 0.55),
        Vec3::new(0.0, 0.55, -0.55),
        Vec3::new(-0.2, -0.4, 0.2),
    ];
    // Both update rules, every seed: eight maps in one batch, then one by one.
    let maps: Vec<(Seed, Options)> = [Accuracy::Fast, Accuracy::Smooth]
        .iter()
        .flat_map(|&accuracy| points.iter().map(move |p| (p, accuracy)))
        .map(|(p, accuracy)| {
            (
                seed_at(&topo, *p, Vec3::Y),
                Options {
                    radius: 0.45,
                    curvature_stop: f32::INFINITY,
                    accuracy,
                },
            )
        })
        .collect();
    let gpu = engine.expmaps(&mesh, &maps).unwrap();
    // Then the maps one at a time, last first: each run reuses the scratch the batch left on the
    // mesh (`GpuMesh::expmap_scratch`, eight slots of stale marks and state, not cleared).
    let again = maps
        .iter()
        .rev()
        .map(|m| engine.expmaps(&mesh, &[*m]).unwrap().remove(0));
    let again: Vec<_> = again.collect::<Vec<_>>().into_iter().rev().collect();
    let runs = maps.iter().chain(&maps).zip(gpu.iter().chain(&again));
    for ((seed, opts), (coords, res)) in runs {
        let cpu = dem_cpu(&topo, seed, *opts, &k);
        assert_eq!(res.converged, 1, "{res:?}");
        let (mut n, mut worst, mut differ) = (0, 0.0f32, 0);
        for (v, c) in coords.iter().enumerate() {
            assert_eq!(
                c[3] > 0.5,
                cpu.dist[v].is_finite(),
                "vertex {v} reached on one side only"
            );
            if !cpu.dist[v].is_finite() {
                continue;
            }
            n += 1;
            assert!(
                c[0].is_finite() && c[1].is_finite(),
                "vertex {v}: {c:?} ({:?})",
                opts.accuracy
            );
            let d = (c[0] - cpu.uv[v][0]).abs().max((c[1] - cpu.uv[v][1]).abs());
            worst = worst.max(d);
            if d > 1e-5 {
                differ += 1;
            }
        }
        eprintln!("seed {:?} ({:?}): {n} vertices, {} sweeps, max |GPU - CPU| = {worst:.2e}, {differ} above 1e-5", seed.point, opts.accuracy, res.sweeps);
        // Same arithmetic in the same order: equal up to f32 rounding, except where rounding flips
        // a near-tie between two upwind neighbours (then the two paths differ by the map's own error).
        assert!(n > 250, "the disc should hold hundreds of vertices: {n}");
        assert!(
            differ * 100 <= n,
            "more than 1 % of vertices differ: {differ} of {n}"
        );
        assert!(worst < 0.02, "max difference {worst}");
    }
}

/// One map on the GPU, checked: converged, and within 1e-5 of its CPU twin (same upwind tree, same
/// arithmetic; only f32 sin/cos/atan2 rounding differs). Returns the coordinates.
fn gpu_map_checked(
    engine: &decalbake::Engine,
    mesh: &decalbake::LoadedMesh,
    seed: Seed,
    opts: Options,
    surface: &SurfaceData,
) -> Vec<[f32; 4]> {
    let (coords, res) = engine.expmaps(mesh, &[(seed, opts)]).unwrap().remove(0);
    assert_eq!(res.converged, 1, "{res:?}");
    let twin = twin_gap(&coords, &dem_cpu(&mesh.topo, &seed, opts, surface));
    assert!(twin < 1e-5, "{:?}: |GPU - twin| = {twin}", opts.accuracy);
    coords
}

/// Largest |GPU - CPU twin| coordinate difference over the vertices the GPU reached; the two must
/// reach the same vertices. NaN counts as infinitely far.
fn twin_gap(coords: &[[f32; 4]], cpu: &decalbake::maps::expmap::cpu::ExpMap) -> f32 {
    let mut gap = 0.0f32;
    for (v, (c, u)) in coords.iter().zip(&cpu.uv).enumerate() {
        assert_eq!(
            c[3] > 0.5,
            cpu.dist[v].is_finite(),
            "vertex {v} reached on one side only"
        );
        if c[3] > 0.5 {
            let d = (c[0] - u[0]).abs().max((c[1] - u[1]).abs());
            gap = if d.is_nan() {
                f32::INFINITY
            } else {
                gap.max(d)
            };
        }
    }
    gap
}

/// Both update rules against the analytic exponential map of a unit sphere at two resolutions,
/// GPU and CPU twin. The paper's update ("fast") does not converge: its angular error comes from
/// treating an angular step s as s / r instead of s / sin r, independent of h. The smooth mode
/// (Jacobi-field stretch, carried frame with holonomy, trapezoidal steps) converges at second order:
/// its error must fall by more than 2.5× when the edge length halves (f = 22 to f = 44).
#[test]
fn sphere_error_against_the_analytic_exponential_map() {
    let engine = engine();
    let mut smooth_max = Vec::new();
    for f in [22u32, 44] {
        let mesh = engine.prepare(icosphere(f)).unwrap();
        let topo = &mesh.topo;
        let curvature = SurfaceData::new(topo);
        let seed = seed_at(topo, Vec3::new(0.3, 0.2, 1.0).normalize() * 1.01, Vec3::X);
        for accuracy in [Accuracy::Fast, Accuracy::Smooth] {
            let opts = Options {
                radius: 1.0,
                curvature_stop: f32::INFINITY,
                accuracy,
            };
            let (coords, res) = &engine.expmaps(&mesh, &[(seed, opts)]).unwrap()[0];
            assert_eq!(res.converged, 1);
            let gpu = unit_sphere_log_errors(topo, &seed, 1.0, |v| {
                (coords[v][3] > 0.5).then_some([coords[v][0], coords[v][1]])
            });
            let cpu_map = dem_cpu(topo, &seed, opts, &curvature);
            let cpu = unit_sphere_log_errors(topo, &seed, 1.0, |v| {
                cpu_map.dist[v].is_finite().then_some(cpu_map.uv[v])
            });
            // GPU and twin follow the same upwind tree; only f32 sin/cos/exp rounding differs.
            let twin = twin_gap(coords, &cpu_map);
            eprintln!(
                "icosphere f={f} ({} vertices), {accuracy:?}: 2D error max {:.2e} RMS {:.2e}; distance error max {:.2e} RMS {:.2e} (CPU twin: 2D max {:.2e}); |GPU - twin| {twin:.1e}; {} sweeps",
                topo.positions.len(),
                gpu.max, gpu.rms, gpu.dist_max, gpu.dist_rms, cpu.max, res.sweeps
            );
            assert!(twin < 1e-4, "GPU and CPU twin differ by {twin}");
            match accuracy {
                // Regression guard only: this error does not shrink.
                Accuracy::Fast => assert!(gpu.max < 0.15 && gpu.rms < 0.06, "{gpu:?}"),
                Accuracy::Smooth => smooth_max.push(gpu.max),
            }
        }
    }
    assert!(
        smooth_max[0] < 2.5e-3,
        "smooth mode at f = 22: {}",
        smooth_max[0]
    );
    // Second order would divide the error by 4; asserted: by more than 2.5.
    assert!(
        smooth_max[1] < 0.4 * smooth_max[0],
        "smooth mode does not converge: {smooth_max:?}"
    );
}

/// The CPU twin of the smooth mode on the icosphere family of `../shared/peers/accuracy.py`
/// (frequencies 8, 16, 32, 64: 642 to 40,962 vertices), for the README's comparison with
/// potpourri3d: the RMS error must fall by at least half at each halving of the edge length (second
/// order would quarter it; measured 0.25, 0.26, 0.27 and 0.23, 0.30, 0.22 for the two seeds), the
/// max error must fall (measured by 0.26-0.34), and at f = 32 (10,242 vertices) the max must be
/// below potpourri3d's default log map (AffineLocal) on the same sphere, 2.7e-3
/// (`../shared/peers/README.md`; measured 6.8e-4 and 8.8e-4).
#[test]
fn smooth_twin_converges_on_the_icosphere_family() {
    // Two seeds: the vertex `accuracy.py` seeds from (the one furthest along (0.31, 0.47, 0.83)),
    // and a surface point inside a triangle (exercises the seed-triangle start).
    let mut errors = vec![(Vec::new(), Vec::new()); 2];
    for f in [8u32, 16, 32, 64] {
        let topo = Topology::build(&icosphere(f), DEFAULT_WELD_TOLERANCE);
        let points = [
            peers_seed_vertex(&topo),
            Vec3::new(0.3, 0.2, 1.0).normalize() * 1.01,
        ];
        for (point, (max, rms)) in points.into_iter().zip(&mut errors) {
            let seed = seed_at(&topo, point, Vec3::X);
            let opts = Options {
                radius: 1.3,
                curvature_stop: f32::INFINITY,
                accuracy: Accuracy::Smooth,
            };
            let map = dem_cpu(&topo, &seed, opts, &SurfaceData::new(&topo));
            let e = unit_sphere_log_errors(&topo, &seed, 1.0, |v| {
                map.dist[v].is_finite().then_some(map.uv[v])
            });
            eprintln!(
                "icosphere f{f} ({} vertices), seed {point:.3}, smooth CPU twin: 2D error max {:.2e} RMS {:.2e}",
                topo.positions.len(),
                e.max,
                e.rms
            );
            max.push(e.max);
            rms.push(e.rms);
        }
    }
    for (max, rms) in &errors {
        for (w, r) in max.windows(2).zip(rms.windows(2)) {
            assert!(w[1] < w[0], "max error grows: {max:?}");
            assert!(r[1] < 0.5 * r[0], "no convergence: RMS {rms:?}");
        }
        assert!(max[2] < 2.7e-3, "f = 32: {} (AffineLocal: 2.7e-3)", max[2]);
    }
}

/// The smooth mode is exact on a plane too (zero curvature: the correction factor is 1).
#[test]
fn smooth_mode_is_exact_on_a_plane() {
    let dir = scratch("expmap-plane-smooth");
    let path = plane(&dir, 24);
    let engine = engine();
    let mesh = engine.load_mesh(&path).unwrap();
    let topo = &mesh.topo;
    let seed = seed_at(topo, Vec3::new(0.43, 0.51, 0.0), Vec3::new(1.0, 0.3, 0.0));
    // Also a mirrored frame (e2 = e1 × normal): the map must follow the frame it is given.
    let mirrored = Seed {
        e2: -seed.e2,
        ..seed
    };
    let opts = Options {
        radius: 0.35,
        curvature_stop: f32::INFINITY,
        accuracy: Accuracy::Smooth,
    };
    let maps = engine
        .expmaps(&mesh, &[(seed, opts), (mirrored, opts)])
        .unwrap();
    for (seed, (coords, res)) in [seed, mirrored].iter().zip(&maps) {
        assert_eq!(res.converged, 1);
        let mut n = 0;
        for (v, p) in topo.positions.iter().enumerate() {
            if coords[v][3] < 0.5 {
                continue;
            }
            n += 1;
            let exact = [
                (*p - seed.point).dot(seed.e1),
                (*p - seed.point).dot(seed.e2),
            ];
            for k in 0..2 {
                assert!(
                    (coords[v][k] - exact[k]).abs() < 4e-6,
                    "vertex {v}: {:?} vs {exact:?}",
                    coords[v]
                );
            }
        }
        assert!(n > 200);
    }
}

#[test]
fn param_command_writes_the_layer_map_as_csv() {
    let dir = scratch("expmap-param");
    let path = plane(&dir, 16);
    std::fs::write(dir.join("d.png"), test_image(8, 8, 2, false).encode_png(8)).unwrap();
    let job = serde_json::json!({
        "mesh": path.file_name().unwrap().to_str().unwrap(),
        "layers": [
            { "image": "d.png", "at": [0.5, 0.5, 0.1], "size": [0.3, 0.2], "method": "expmap", "up": [0, 1, 0] },
            { "image": "d.png", "at": [0.5, 0.5, 0.1], "size": [0.3, 0.2], "method": "planar" }
        ]
    });
    std::fs::write(dir.join("job.json"), serde_json::to_vec(&job).unwrap()).unwrap();
    for (layer, has_distance) in [("0", true), ("1", false)] {
        let out = dir.join(format!("p{layer}.csv"));
        let (code, _, err) = param(&dir.join("job.json"), layer, &out);
        assert_eq!(code, 0, "{err}");
        let text = std::fs::read_to_string(&out).unwrap();
        let mut lines = text.lines();
        assert_eq!(lines.next(), Some("x,y,z,distance,u,v"));
        let mut n = 0;
        for line in lines {
            let f: Vec<&str> = line.split(',').collect();
            let num = |i: usize| f[i].parse::<f32>().unwrap();
            // On the plane with up = +y and the seed at (0.5, 0.5): u = x - 0.5, v = y - 0.5.
            assert!(
                (num(4) - (num(0) - 0.5)).abs() < 1e-5 && (num(5) - (num(1) - 0.5)).abs() < 1e-5,
                "{line}"
            );
            if has_distance {
                assert!((num(3) - num(4).hypot(num(5))).abs() < 1e-5, "{line}");
            } else {
                assert!(f[3].is_empty(), "planar rows have no distance: {line}");
            }
            n += 1;
        }
        assert!(n > 20, "layer {layer}: {n} rows");
    }
    // The bake report counts the same vertices, and the triangles whose three vertices they are.
    let rows: Vec<[usize; 2]> = std::fs::read_to_string(dir.join("p0.csv"))
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| {
            let f: Vec<f32> = l.split(',').map(|x| x.parse().unwrap()).collect();
            // Grid index: the jitter is below 0.2 of a cell.
            [
                (f[0] * 16.0).round() as usize,
                (f[1] * 16.0).round() as usize,
            ]
        })
        .collect();
    let reached: std::collections::HashSet<usize> = rows.iter().map(|[i, j]| j * 17 + i).collect();
    let mut triangles = 0;
    for j in 0..16 {
        for i in 0..16 {
            let a = j * 17 + i;
            for t in [[a, a + 1, a + 18], [a, a + 18, a + 17]] {
                triangles += usize::from(t.iter().all(|v| reached.contains(v)));
            }
        }
    }
    let engine = engine();
    let job = decalbake::io::job::Job::load(&dir.join("job.json"), None).unwrap();
    let mesh = engine.load_mesh(&path).unwrap();
    let report = engine.bake(&mesh, &job).unwrap().report;
    let ex = report.layers[0].expmap.expect("expmap stats");
    eprintln!(
        "report: {ex:?}; CSV: {} vertices, {triangles} triangles",
        reached.len()
    );
    assert_eq!(ex.reached as usize, reached.len());
    assert_eq!(ex.triangles_reached as usize, triangles);
    assert!(ex.triangles_reached >= report.layers[0].triangles_covered);

    let (code, _, err) = param(&dir.join("job.json"), "5", &dir.join("x.csv"));
    assert_eq!(code, 2);
    assert!(err.contains("--layer 5 does not exist"), "{err}");
    assert!(!dir.join("x.csv").exists());
}

/// A disc of about ten thousand vertices needs many sweeps: they run in several rounds (lavapipe
/// abandons shaders that loop too long), and the result must still equal the serial twin. A
/// dispatch runs as many sweeps as its loop budget fits (the fronts after the first are small, so
/// this disc fits one round at the default budget): the budget is lowered to 100 steps for this
/// test, which makes it cross several submissions of four rounds (other tests of this binary
/// running meanwhile only take more rounds; results do not depend on the budget).
#[test]
fn large_discs_converge_over_several_rounds() {
    let engine = engine();
    let Some(mesh) = spot_subdivided_twice(&engine) else {
        return;
    };
    let topo = &mesh.topo;
    let seed = seed_at(topo, Vec3::new(0.33, 0.0, 0.45), Vec3::Y);
    let opts = Options {
        radius: 0.8,
        curvature_stop: f32::INFINITY,
        accuracy: Accuracy::Fast,
    };
    use decalbake::maps::expmap::gpu::{
        LOOP_BUDGET_OVERRIDE, SPREAD_MIN_CANDIDATES_OVERRIDE, WIDE_MIN_CANDIDATES_OVERRIDE,
    };
    use std::sync::atomic::Ordering::Relaxed;
    let _overrides = OVERRIDES.lock().unwrap_or_else(|e| e.into_inner());
    // The defaults come back however this test ends.
    struct Restore;
    impl Drop for Restore {
        fn drop(&mut self) {
            LOOP_BUDGET_OVERRIDE.store(0, Relaxed);
            WIDE_MIN_CANDIDATES_OVERRIDE.store(0, Relaxed);
            SPREAD_MIN_CANDIDATES_OVERRIDE.store(0, Relaxed);
        }
    }
    let restore = Restore;
    LOOP_BUDGET_OVERRIDE.store(100, Relaxed);
    // One workgroup a map on any adapter (a GPU would spread a large lone map).
    SPREAD_MIN_CANDIDATES_OVERRIDE.store(u32::MAX, Relaxed);
    let (_, dispatches) = engine.expmaps_status(&mesh, &[(seed, opts)]).unwrap();
    let (coords, res) = &engine.expmaps(&mesh, &[(seed, opts)]).unwrap()[0];
    // The variant of 256 invocations a map, which the default runs only past 262,144
    // candidates: the same fixed point, so the same map; it runs more sweeps a dispatch (a
    // sweep's front split among four times the invocations), so fewer dispatches.
    WIDE_MIN_CANDIDATES_OVERRIDE.store(1, Relaxed);
    let (_, wide_dispatches) = engine.expmaps_status(&mesh, &[(seed, opts)]).unwrap();
    let (wide, wide_res) = &engine.expmaps(&mesh, &[(seed, opts)]).unwrap()[0];
    drop(restore);
    assert_eq!(wide, coords);
    assert_eq!((wide_res.reached, wide_res.converged), (res.reached, 1));
    assert!(
        wide_dispatches < dispatches,
        "{wide_dispatches} dispatches 256 wide, {dispatches} 64 wide"
    );
    assert!(
        dispatches > 8,
        "{dispatches} dispatches: the map should cross several rounds"
    );
    let cpu = dem_cpu(topo, &seed, opts, &SurfaceData::new(topo));
    eprintln!("{} vertices, {} sweeps", res.reached, res.sweeps);
    assert_eq!(res.converged, 1);
    assert!(res.reached > 8000, "reached {}", res.reached);
    let mut differ = 0;
    for (v, c) in coords.iter().enumerate() {
        assert_eq!(c[3] > 0.5, cpu.dist[v].is_finite(), "vertex {v}");
        if cpu.dist[v].is_finite()
            && ((c[0] - cpu.uv[v][0]).abs() > 1e-5 || (c[1] - cpu.uv[v][1]).abs() > 1e-5)
        {
            differ += 1;
        }
    }
    assert!(
        differ * 100 <= res.reached as usize,
        "{differ} vertices differ"
    );
}

/// Spot subdivided twice, or `None` on GL (see [`on_gl`]).
fn spot_subdivided_twice(engine: &decalbake::Engine) -> Option<decalbake::LoadedMesh> {
    if on_gl(engine) {
        return None;
    }
    let spot = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/spot.glb");
    let mesh = Mesh::load(&spot).unwrap().subdivide().subdivide();
    Some(engine.prepare(mesh).unwrap())
}

/// On wgpu's GL backend the maps come from the CPU twin (`maps::expmap::gpu::run`): the tests of
/// the GPU relaxation's paths (dispatch counts, variants) have nothing to compare there.
fn on_gl(engine: &decalbake::Engine) -> bool {
    let gl = engine.ctx.backend == Some(wgpu::Backend::Gl);
    if gl {
        eprintln!("GL: the maps come from the CPU twin; nothing to compare");
    }
    gl
}

/// The tests that set the relaxation's overrides (process-wide statics) take turns: one's
/// dispatch counts would otherwise see the other's settings.
static OVERRIDES: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// A lone large map spread over many workgroups, a dispatch a sweep (`expmap_spread`, off by
/// default: slower on lavapipe; forced here), reaches the one-workgroup
/// kernel's fixed point: the same map byte for byte, both update rules, also when the spread
/// run reuses the scratch (marks, smooth state) a one-workgroup run left on the mesh. Shown to
/// fail with a `sweep` that handles only the first 64 vertices of each front (the map stops
/// short: 5,880 of 15,307 vertices reached).
#[test]
fn spread_maps_equal_one_workgroup_maps() {
    use decalbake::maps::expmap::gpu::SPREAD_MIN_CANDIDATES_OVERRIDE as SPREAD;
    use std::sync::atomic::Ordering::Relaxed;
    let _overrides = OVERRIDES.lock().unwrap_or_else(|e| e.into_inner());
    struct Restore;
    impl Drop for Restore {
        fn drop(&mut self) {
            SPREAD.store(0, Relaxed);
        }
    }
    let _restore = Restore;
    let engine = engine();
    let Some(mesh) = spot_subdivided_twice(&engine) else {
        return;
    };
    let seed = seed_at(&mesh.topo, Vec3::new(0.33, 0.0, 0.45), Vec3::Y);
    for accuracy in [Accuracy::Fast, Accuracy::Smooth] {
        let m = (
            seed,
            Options {
                radius: 0.8,
                curvature_stop: f32::INFINITY,
                accuracy,
            },
        );
        SPREAD.store(u32::MAX, Relaxed);
        let (one, one_res) = engine.expmaps(&mesh, &[m]).unwrap().remove(0);
        let (_, one_dispatches) = engine.expmaps_status(&mesh, &[m]).unwrap();
        SPREAD.store(1, Relaxed);
        let (spread, spread_res) = engine.expmaps(&mesh, &[m]).unwrap().remove(0);
        let (_, spread_dispatches) = engine.expmaps_status(&mesh, &[m]).unwrap();
        eprintln!(
            "{accuracy:?}: {} vertices; one workgroup {} sweeps in {one_dispatches} dispatches, spread {} in {spread_dispatches}",
            one_res.reached, one_res.sweeps, spread_res.sweeps
        );
        assert_eq!(one_res.converged, 1, "{one_res:?}");
        assert!(one_res.reached > 8000, "{one_res:?}");
        // The spread path ran: at least a dispatch a sweep.
        assert!(
            spread_dispatches > one_res.sweeps,
            "{spread_dispatches} dispatches"
        );
        assert_eq!(
            (spread_res.reached, spread_res.converged),
            (one_res.reached, 1),
            "{spread_res:?}"
        );
        let differ = one.iter().zip(&spread).filter(|(a, b)| a != b).count();
        assert_eq!(differ, 0, "{accuracy:?}: {differ} vertices differ");
    }
}

/// A cylinder is developable: the map must approach its unrolling (u = arc length around, v = height)
/// as the mesh is refined. The remaining error comes from the polygonal cross-section (chords instead
/// of arcs) and from the averaged vertex normals, both O(h^2) per edge.
#[test]
fn cylinder_maps_converge_to_the_unrolling() {
    let engine = engine();
    let mut errors = Vec::new();
    for ((n, m), accuracy) in [(32u32, 16u32), (64, 32)]
        .into_iter()
        .flat_map(|nm| [(nm, Accuracy::Fast), (nm, Accuracy::Smooth)])
    {
        let mesh = engine.prepare(common::cylinder(n, m)).unwrap();
        let topo = &mesh.topo;
        let seed = seed_at(topo, Vec3::new(1.2, 0.05, 0.03), Vec3::Y);
        assert!(
            seed.e1.dot(Vec3::Y) > 0.99 && seed.e2.dot(Vec3::Z) > 0.99,
            "frame follows the tangent and the axis"
        );
        let opts = Options {
            radius: 1.2,
            curvature_stop: f32::INFINITY,
            accuracy,
        };
        let coords = gpu_map_checked(&engine, &mesh, seed, opts, &SurfaceData::new(topo));
        let ts = seed.point.y.atan2(seed.point.x);
        let (mut max_e, mut n_in) = (0.0f32, 0);
        for (v, c) in coords.iter().enumerate() {
            if c[3] < 0.5 {
                continue;
            }
            let p = topo.positions[v];
            let exact = [p.y.atan2(p.x) - ts, p.z - seed.point.z];
            if exact[0].hypot(exact[1]) > 1.0 {
                continue;
            }
            max_e = max_e.max((c[0] - exact[0]).hypot(c[1] - exact[1]));
            n_in += 1;
        }
        eprintln!("cylinder {n}x{m} ({accuracy:?}): {n_in} vertices within 1 of the seed, max error {max_e:.2e}");
        assert!(n_in > 50);
        errors.push(max_e);
    }
    // errors: [fast coarse, smooth coarse, fast fine, smooth fine]. Both update rules transport
    // exactly on a cylinder; what remains is O(h^2) per unit length.
    for mode in 0..2 {
        assert!(
            errors[2 + mode] < 0.6 * errors[mode],
            "refinement must shrink the error: {errors:?}"
        );
        assert!(errors[2 + mode] < 0.02, "{errors:?}");
    }
}

/// A cone (apex at the top) without its tip: developable away from the apex, where its unrolling is a
/// circular sector. The map is compared with the unrolled coordinates at three resolutions.
#[test]
fn cone_maps_converge_to_the_unrolling() {
    let (rb, h) = (1.0f32, 1.5f32);
    let l = (rb * rb + h * h).sqrt();
    let sin_a = rb / l;
    let engine = engine();
    let (mut fast, mut smooth) = (Vec::new(), Vec::new());
    for (n, m) in [(48u32, 16u32), (96, 32), (192, 64)] {
        // Rings from slant 0.3 l to l.
        let mut pos = Vec::new();
        let mut tris = Vec::new();
        for j in 0..=m {
            let s = l * (0.3 + 0.7 * j as f32 / m as f32);
            for i in 0..n {
                let phi = i as f32 / n as f32 * std::f32::consts::TAU;
                pos.push(Vec3::new(
                    s * sin_a * phi.cos(),
                    s * sin_a * phi.sin(),
                    h - s * h / l,
                ));
            }
        }
        for j in 0..m {
            for i in 0..n {
                let (a, b) = (j * n + i, j * n + (i + 1) % n);
                let (c, d) = (a + n, b + n);
                // Counter-clockwise seen from outside (rings go down the cone).
                tris.push([a, d, b]);
                tris.push([a, c, d]);
            }
        }
        let uv = vec![glam::Vec2::ZERO; pos.len()];
        let mesh = Mesh {
            source: "cone".into(),
            normals: vec![Vec3::ZERO; pos.len()],
            positions: pos,
            uv_sets: vec![uv],
            triangles: tris,
            primitives: vec![],
            material: None,
            blend: Vec::new(),
            bridge: Vec::new(),
            ..Default::default()
        };
        let mesh = engine.prepare(mesh).unwrap();
        let topo = &mesh.topo;
        // Seed at slant 0.7 l, phi = 0.
        let (s0, phi0) = (0.7 * l, 0.0f32);
        let target = Vec3::new(s0 * sin_a, 0.0, h - s0 * h / l) + Vec3::new(0.2, 0.0, 0.1);
        let seed = seed_at(topo, target, Vec3::Y);
        let outward = Vec3::new(h / l * phi0.cos(), h / l * phi0.sin(), sin_a);
        assert!(
            seed.normal.dot(outward) > 0.99,
            "outward normals: {:?}",
            seed.normal
        );
        let opts = |accuracy| Options {
            radius: 0.3 * l,
            curvature_stop: f32::INFINITY,
            accuracy,
        };
        let maps = engine
            .expmaps(
                &mesh,
                &[(seed, opts(Accuracy::Fast)), (seed, opts(Accuracy::Smooth))],
            )
            .unwrap();
        // Unrolled plane: apex at the origin, generator phi at angle phi * sin_a.
        let unroll = |p: Vec3| {
            let s = (p - Vec3::new(0.0, 0.0, h)).length();
            let psi = p.y.atan2(p.x) * sin_a;
            glam::Vec2::new(s * psi.cos(), s * psi.sin())
        };
        let s_2d = unroll(seed.point);
        let psi0 = seed.point.y.atan2(seed.point.x) * sin_a;
        let (t_phi, r_hat) = (
            glam::Vec2::new(-psi0.sin(), psi0.cos()),
            glam::Vec2::new(psi0.cos(), psi0.sin()),
        );
        let phi_s = seed.point.y.atan2(seed.point.x);
        let e_phi = Vec3::new(-phi_s.sin(), phi_s.cos(), 0.0);
        let e_s = Vec3::new(sin_a * phi_s.cos(), sin_a * phi_s.sin(), -h / l);
        let k = SurfaceData::new(topo);
        for (((coords, res), errors), accuracy) in maps
            .iter()
            .zip([&mut fast, &mut smooth])
            .zip([Accuracy::Fast, Accuracy::Smooth])
        {
            assert_eq!(res.converged, 1);
            let twin = twin_gap(coords, &dem_cpu(topo, &seed, opts(accuracy), &k));
            assert!(twin < 1e-5, "{accuracy:?}: |GPU - twin| = {twin}");
            let (mut max_e, mut n_in) = (0.0f32, 0);
            for (v, c) in coords.iter().enumerate() {
                if c[3] < 0.5 {
                    continue;
                }
                let d = unroll(topo.positions[v]) - s_2d;
                if d.length() > 0.25 * l {
                    continue;
                }
                let tangent = e_phi * d.dot(t_phi) + e_s * d.dot(r_hat);
                let exact = [tangent.dot(seed.e1), tangent.dot(seed.e2)];
                max_e = max_e.max((c[0] - exact[0]).hypot(c[1] - exact[1]));
                n_in += 1;
            }
            assert!(n_in > 30);
            errors.push(max_e);
        }
        eprintln!(
            "cone {n}x{m}: max error fast {:.2e}, smooth {:.2e}",
            fast.last().unwrap(),
            smooth.last().unwrap()
        );
    }
    // The fast mode's transfer turns each edge by the minimal rotation between vertex normals, which
    // on a cone is not the surface's parallel transport (it is on a cylinder): its error stays small
    // but does not shrink (6.4e-4, 9.6e-4, 1.0e-3 here): regression guard only. The smooth mode
    // carries its frame edge by edge with intrinsic angles (exact parallel transport on a
    // developable mesh) and integrates the edges with the trapezoidal rule: second order, the error
    // must fall by more than half at each refinement (measured 2.1e-4, 5.5e-5, 1.5e-5: by 3.7-3.9×).
    assert!(
        fast.iter().all(|e| *e < 2e-3),
        "fast mode regressed: {fast:?}"
    );
    for w in smooth.windows(2) {
        assert!(
            w[1] < 0.5 * w[0],
            "smooth mode does not converge: {smooth:?}"
        );
    }
}

/// Area of triangle `t` (2D) clipped to the square [-h, h]².
fn clipped_area(t: [[f32; 2]; 3], h: f32) -> f32 {
    let mut poly: Vec<[f32; 2]> = t.to_vec();
    // Sutherland-Hodgman against x <= h, x >= -h, y <= h, y >= -h.
    for (axis, sign) in [(0usize, 1.0f32), (0, -1.0), (1, 1.0), (1, -1.0)] {
        let inside = |p: &[f32; 2]| sign * p[axis] <= h;
        let mut out = Vec::new();
        for i in 0..poly.len() {
            let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
            if inside(&a) {
                out.push(a);
            }
            if inside(&a) != inside(&b) {
                let t = (sign * h - a[axis]) / (b[axis] - a[axis]);
                out.push([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]);
            }
        }
        poly = out;
        if poly.is_empty() {
            return 0.0;
        }
    }
    let mut area = 0.0;
    for i in 0..poly.len() {
        let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
        area += a[0] * b[1] - a[1] * b[0];
    }
    0.5 * area.abs()
}

/// A decal of size s × s on a nearly flat region (Spot's flank) covers s² of surface: each covered
/// triangle contributes the part of its (u, v) image inside the decal square, scaled back to surface
/// area by its own area ratio. Tolerance 2 %: the flank curves gently, and the map's area distortion
/// there is about 1 % (see the demo's report).
#[test]
fn expmap_decal_covers_its_area_on_a_nearly_flat_region() {
    let spot = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/spot.glb");
    let engine = engine();
    let mesh = engine
        .prepare(Mesh::load(&spot).unwrap().subdivide())
        .unwrap();
    let topo = &mesh.topo;
    let s = 0.2f32;
    let seed = seed_at(topo, Vec3::new(0.4, 0.0, 0.45), Vec3::Y);
    let opts = Options {
        radius: 1.2 * 0.5 * s * 2f32.sqrt(),
        curvature_stop: f32::INFINITY,
        accuracy: Accuracy::Fast,
    };
    let (coords, res) = &engine.expmaps(&mesh, &[(seed, opts)]).unwrap()[0];
    assert_eq!(res.converged, 1);
    let mut covered = 0.0f32;
    for tri in &topo.triangles {
        if tri.iter().any(|&v| coords[v as usize][3] < 0.5) {
            continue;
        }
        let uv = tri.map(|v| [coords[v as usize][0], coords[v as usize][1]]);
        let uv_area = 0.5
            * ((uv[1][0] - uv[0][0]) * (uv[2][1] - uv[0][1])
                - (uv[1][1] - uv[0][1]) * (uv[2][0] - uv[0][0]))
                .abs();
        if uv_area <= 0.0 {
            continue;
        }
        let [a, b, c] = tri.map(|v| topo.positions[v as usize]);
        let area3 = 0.5 * (b - a).cross(c - a).length();
        covered += clipped_area(uv, 0.5 * s) * area3 / uv_area;
    }
    eprintln!(
        "decal {s} x {s}: covers {covered:.5} of surface (s^2 = {:.5}, ratio {:.4})",
        s * s,
        covered / (s * s)
    );
    assert!(
        (covered / (s * s) - 1.0).abs() < 0.02,
        "covered {covered}, expected {}",
        s * s
    );
}

/// Topology: a map flows around a hole (a slot cut into a flat sheet: the vertex behind it is reached
/// along the way around, at a graph distance far above the straight line, and since the sheet is
/// flat its coordinates are still its plane offset from the seed) and never jumps to a disconnected
/// component lying 0.02 above (well inside the Euclidean reach of the disc), on the GPU and in the
/// CPU twin, in both modes.
#[test]
fn maps_go_around_holes_and_stay_on_their_component() {
    let n = 40u32;
    let mut pos = Vec::new();
    let mut tris = Vec::new();
    for sheet in 0..2u32 {
        let base = pos.len() as u32;
        for j in 0..=n {
            for i in 0..=n {
                pos.push(Vec3::new(
                    i as f32 / n as f32,
                    j as f32 / n as f32,
                    0.02 * sheet as f32,
                ));
            }
        }
        for j in 0..n {
            for i in 0..n {
                // The slot: x in [0.45, 0.55], y in [0.3, 0.7], cut from the lower sheet only.
                let (cx, cy) = ((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                if sheet == 0 && (0.45..=0.55).contains(&cx) && (0.3..=0.7).contains(&cy) {
                    continue;
                }
                let a = base + j * (n + 1) + i;
                tris.push([a, a + 1, a + n + 2]);
                tris.push([a, a + n + 2, a + n + 1]);
            }
        }
    }
    let np = pos.len();
    let mesh = Mesh {
        source: "slot".into(),
        normals: vec![Vec3::Z; np],
        positions: pos,
        uv_sets: vec![vec![glam::Vec2::ZERO; np]],
        triangles: tris,
        primitives: vec![],
        material: None,
        blend: Vec::new(),
        bridge: Vec::new(),
        ..Default::default()
    };
    let engine = engine();
    let mesh = engine.prepare(mesh).unwrap();
    let topo = &mesh.topo;
    assert_eq!(topo.components, 2);
    let seed = seed_at(topo, Vec3::new(0.3, 0.5, -0.001), Vec3::X);
    let behind = topo
        .positions
        .iter()
        .position(|p| (*p - Vec3::new(0.7, 0.5, 0.0)).length() < 1e-4)
        .unwrap();
    let upper = |v: usize| topo.positions[v].z > 0.01;
    let k = SurfaceData::new(topo);
    for accuracy in [Accuracy::Fast, Accuracy::Smooth] {
        let opts = Options {
            radius: 0.8,
            curvature_stop: f32::INFINITY,
            accuracy,
        };
        let coords = gpu_map_checked(&engine, &mesh, seed, opts, &k);
        for (v, c) in coords.iter().enumerate() {
            assert!(
                !(c[3] > 0.5 && upper(v)),
                "vertex {v} of the other sheet reached"
            );
        }
        // Around the slot: up to its corner, along its top edge and down again is 0.25 + 0.1 + 0.25
        // = 0.6, against 0.4 straight through.
        let c = coords[behind];
        eprintln!(
            "{accuracy:?}: vertex behind the slot at graph distance {:.4} (straight line 0.4), coordinates ({:.6}, {:.6})",
            c[2], c[0], c[1]
        );
        assert!(c[3] > 0.5, "vertex behind the slot not reached");
        assert!(c[2] > 0.55, "graph distance {} goes through the slot", c[2]);
        // Flat: exact up to f32 rounding along the ~25-edge path.
        assert!((c[0] - 0.4).abs() < 1e-5 && c[1].abs() < 1e-5, "{c:?}");
    }
}

/// A real developable model with sharp creases (Keenan Crane's crumpled sheet, whose UVs are its
/// exact isometric flattening): the exponential map of a flat surface is its unfolding, so the
/// smooth mode must reproduce the UV layout up to a rigid motion. Its frame transport uses only
/// intrinsic edge angles, which are exact across creases; the paper's update turns edges by the
/// minimal rotation between averaged vertex normals, which is not, and is only guarded (measured
/// about 20 % of the disc radius). GPU and CPU twin.
#[test]
fn smooth_maps_unfold_a_crumpled_developable_sheet() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/crumpled_developable.glb");
    let engine = engine();
    let mesh = engine.load_mesh(&path).unwrap();
    let topo = &mesh.topo;
    let mut flat = vec![glam::Vec2::ZERO; topo.positions.len()];
    for (i, w) in topo.welded_of.iter().enumerate() {
        flat[*w as usize] = mesh.mesh.uv_sets[0][i];
    }
    let centre = flat.iter().copied().sum::<glam::Vec2>() / flat.len() as f32;
    let v0 = (0..flat.len())
        .min_by(|&a, &b| {
            (flat[a] - centre)
                .length()
                .total_cmp(&(flat[b] - centre).length())
        })
        .unwrap();
    let seed = seed_at(
        topo,
        topo.positions[v0] + Vec3::new(1e-3, 0.0, 0.0),
        Vec3::X,
    );
    let surface = SurfaceData::new(topo);
    for accuracy in [Accuracy::Fast, Accuracy::Smooth] {
        let opts = Options {
            radius: 0.8,
            curvature_stop: f32::INFINITY,
            accuracy,
        };
        let coords = gpu_map_checked(&engine, &mesh, seed, opts, &surface);
        // The seed point in the flattening, then the best rigid motion (with reflection, as the
        // flattening's orientation is its own) from the flattening to the map.
        let t = topo.triangles[seed.triangle as usize];
        let [a, b, c] = t.map(|v| topo.positions[v as usize]);
        let n = (b - a).cross(c - a);
        let w =
            |p: Vec3, q: Vec3| (p - seed.point).cross(q - seed.point).dot(n) / n.length_squared();
        let (wa, wb) = (w(b, c), w(c, a));
        let s2 = flat[t[0] as usize] * wa
            + flat[t[1] as usize] * wb
            + flat[t[2] as usize] * (1.0 - wa - wb);
        let pairs: Vec<(glam::Vec2, glam::Vec2)> = coords
            .iter()
            .enumerate()
            .filter(|(_, c)| c[3] > 0.5)
            .map(|(v, c)| (flat[v] - s2, glam::Vec2::new(c[0], c[1])))
            .collect();
        let fit = |mirror: f32| {
            let m = |p: glam::Vec2| glam::Vec2::new(p.x, mirror * p.y);
            let (sx, sy) = pairs.iter().fold((0.0, 0.0), |(x, y), (p, q)| {
                (x + m(*p).dot(*q), y + m(*p).perp_dot(*q))
            });
            let r = glam::Vec2::from_angle(f32::atan2(sy, sx));
            pairs
                .iter()
                .map(|(p, q)| (r.rotate(m(*p)) - *q).length())
                .fold(0.0f32, f32::max)
        };
        let err = fit(1.0).min(fit(-1.0));
        let radius = pairs.iter().map(|(_, q)| q.length()).fold(0.0f32, f32::max);
        eprintln!(
            "crumpled sheet, {accuracy:?}: {} vertices, disc radius {radius:.3}, max error against the flattening {err:.2e} ({:.4} % of the radius)",
            pairs.len(),
            100.0 * err / radius
        );
        assert!(pairs.len() > 100 && radius > 0.5);
        match accuracy {
            Accuracy::Fast => assert!(err < 0.3 * radius, "fast mode regressed: {err}"),
            // Flat up to f32 rounding along ~15-edge paths.
            Accuracy::Smooth => assert!(err < 1e-4 * radius, "smooth mode: {err}"),
        }
    }
}

/// A bake's exponential maps come from the CPU twin on a CPU adapter and from the kernels on a
/// GPU (`StagePaths::expmap`, `Auto`); forcing either gives the same texture within one 8-bit
/// step on at most 0.1 % of the values (the maps agree within the twins' tolerance, not bit for
/// bit; on lavapipe all 262,144 values were equal), and the report names the path taken. With the
/// twin's u and v swapped, 16,597 values differed.
#[test]
fn a_bake_maps_on_the_faster_path_and_both_paths_agree() {
    let (job, mut engine, mesh, auto) = spot_paths_bake("expmap_paths", spot_ring("img.png", 0.2));
    let cpu_adapter = engine.ctx.device_type == Some(wgpu::DeviceType::Cpu);
    let gl = engine.ctx.backend == Some(wgpu::Backend::Gl);
    let expected = if cpu_adapter || gl { "cpu" } else { "gpu" };
    assert_eq!(auto.report.paths.expmap, expected);
    let mut baked = Vec::new();
    for path in [decalbake::StagePath::Cpu, decalbake::StagePath::Gpu] {
        engine.stage_paths.expmap = path;
        baked.push(engine.bake(&mesh, &job).unwrap());
    }
    let [cpu, gpu] = [&baked[0], &baked[1]];
    assert_eq!(cpu.report.paths.expmap, "cpu");
    assert_eq!(gpu.report.paths.expmap, if gl { "cpu" } else { "gpu" });
    let (differ, worst) = value_diffs(&cpu.texels, &gpu.texels);
    assert!(differ * 1000 <= cpu.texels.len(), "{differ} differ");
    assert!(worst <= 1, "worst difference {worst}");
    for (c, g) in cpu.report.layers.iter().zip(&gpu.report.layers) {
        assert_eq!(
            c.triangles_covered, g.triangles_covered,
            "layer {}",
            c.index
        );
    }
}
