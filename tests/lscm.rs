// SPDX-License-Identifier: MIT OR Apache-2.0
//! Local conformal charts (Maillot; Levy et al. 2002) and hybrid decals (Schmidt et al. 2006 §5.1):
//! a plane is reproduced exactly (up to f32), the GPU solve reaches the f64 twin's optimum on a real
//! model, charts on disc-shaped patches have no flipped triangles, conformal decals keep angles better
//! than exponential maps on a curved model, and a solve that cannot converge fails the bake with a
//! message naming the layer.

mod common;
use common::*;
use decalbake::maps::chart::lscm;
use decalbake::maps::chart::{self, ChartKind, ChartRequest};
use decalbake::maps::Frame;
use decalbake::mesh::{Mesh, Topology};
use decalbake::place::{place_cpu, Query};
use decalbake::solve::gpu::{cg_batched, SystemDesc};
use glam::Vec3;
use std::path::Path;

fn spot() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/spot.glb")
}

/// The decal frame of a layer `size` at the surface point nearest `at`, image up along `up`.
fn frame_at(topo: &Topology, at: Vec3, up: [f32; 3], size: [f32; 2]) -> (Frame, u32) {
    let p = place_cpu(topo, Query::Point(at));
    let job_layer: decalbake::io::job::Layer = decalbake::io::job::Layer {
        kind: decalbake::io::job::LayerKind::Decal,
        image: "x.png".into(),
        mask: None,
        at: decalbake::io::job::AtSpec::Point(at.to_array()),
        size,
        angle: 0.0,
        up,
        method: decalbake::io::job::Method::Lscm,
        blend: decalbake::io::job::BlendMode::Normal,
        opacity: 1.0,
        depth: 1.0,
        curvature_stop: f32::INFINITY,
        accuracy: decalbake::maps::expmap::Accuracy::Smooth,
        hybrid_threshold: 1.1,
        cg_max_iterations: None,
        stroke: None,
        ribbon: None,
        warp: Vec::new(),
        channels: Default::default(),
        text: None,
        raster: None,
    };
    (Frame::new(&p, &job_layer), p.triangle)
}

/// A free LSCM chart (planar warm start) solved on the GPU.
fn lscm_chart(
    engine: &decalbake::Engine,
    topo: &Topology,
    frame: Frame,
    triangle: u32,
) -> (chart::Chart, chart::SolveStats) {
    let req = ChartRequest {
        frame,
        triangle,
        kind: ChartKind::Lscm,
        max_iter: None,
        warm: None,
        cone: true,
    };
    let mut stats = Default::default();
    let c = chart::build(topo, &[req], &engine.solver(), &mut stats)
        .unwrap()
        .remove(0);
    (c, stats)
}

/// A tilted, jittered planar grid: the chart must be the plane itself (the normalisation fixes
/// position, rotation and scale), up to f32 rounding and the CG tolerance (1e-5 relative residual):
/// bound 2e-4 of the decal size.
#[test]
fn planar_patch_is_reproduced() {
    let n = 30u32;
    let (ex, ey) = (Vec3::new(0.8, 0.0, 0.6), Vec3::new(0.0, 1.0, 0.0));
    let mut pos = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let jit = if i % n != 0 && j % n != 0 {
                0.3 * (((i * 13 + j * 7) % 11) as f32 / 11.0 - 0.5) / n as f32
            } else {
                0.0
            };
            let (x, y) = (i as f32 / n as f32 + jit, j as f32 / n as f32 - 0.5 * jit);
            pos.push(ex * x + ey * y + Vec3::new(1.0, -2.0, 3.0));
        }
    }
    let mut tris = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let a = j * (n + 1) + i;
            tris.push([a, a + 1, a + n + 2]);
            tris.push([a, a + n + 2, a + n + 1]);
        }
    }
    let normals = vec![ex.cross(ey); pos.len()];
    let mesh = Mesh {
        source: "plane".into(),
        uv_sets: vec![vec![glam::Vec2::ZERO; pos.len()]],
        positions: pos,
        normals,
        triangles: tris,
        primitives: vec![],
        material: None,
        blend: Vec::new(),
        bridge: Vec::new(),
        ..Default::default()
    };
    let engine = engine();
    let loaded = engine.prepare(mesh).unwrap();
    let topo = &loaded.topo;
    let at = ex * 0.47 + ey * 0.52 + Vec3::new(1.0, -2.0, 3.0);
    let size = [0.4, 0.3];
    let (frame, tri) = frame_at(topo, at, [0.3, 1.0, 0.0], size);
    let (c, stats) = &lscm_chart(&engine, topo, frame, tri);
    eprintln!("plane chart: {:?}, {stats:?}", c.report);
    assert_eq!(
        c.report.status,
        decalbake::solve::sparse::CgStatus::Converged
    );
    let mut worst = 0.0f32;
    for &(v, uv) in &c.coords {
        let d = topo.positions[v as usize] - frame.center;
        let want = [d.dot(frame.axis_u), d.dot(frame.axis_v)];
        worst = worst.max((uv[0] - want[0]).abs().max((uv[1] - want[1]).abs()));
    }
    eprintln!("max |chart - plane| = {worst:.2e} (decal 0.4 x 0.3)");
    assert!(worst <= 2e-4 * 0.5, "plane not reproduced: {worst}");
    // The chart is not trivially small (the decal spans about 12 x 9 grid cells).
    assert!(c.report.triangles > 50);
}

/// Spot, curved region: the GPU (f32) solve of the final chart's system reaches the f64 twin's
/// optimum. The energy excess E(x) - E(x*) equals (x - x*)ᵀ Q (x - x*), second order in the
/// error, so the final 1e-6 residual gives a relative excess far below 1e-3, the stated bound. The chart
/// has no flipped triangles.
#[test]
fn spot_chart_matches_cpu_optimum_without_flips() {
    let engine = engine();
    let loaded = engine
        .prepare(Mesh::load(&spot()).unwrap().subdivide())
        .unwrap();
    let topo = &loaded.topo;
    for (at, size) in [
        (Vec3::new(0.33, 0.0, 0.45), [0.3f32, 0.3f32]),
        (Vec3::new(0.0, 0.6, 0.0), [0.35, 0.25]),
    ] {
        let (frame, tri) = frame_at(topo, at, [0.0, 1.0, 0.0], size);
        let (c, _) = &lscm_chart(&engine, topo, frame, tri);
        eprintln!("{at}: {:?}", c.report);
        assert_eq!(
            c.report.status,
            decalbake::solve::sparse::CgStatus::Converged
        );
        let uv: std::collections::HashMap<u32, [f32; 2]> = c.coords.iter().copied().collect();
        let mut flipped = 0;
        for &t in &c.triangles {
            let z = topo.triangles[t as usize].map(|v| glam::Vec2::from(uv[&v]));
            if (z[1] - z[0]).perp_dot(z[2] - z[0]) <= 0.0 {
                flipped += 1;
            }
        }
        assert_eq!(flipped, 0, "flipped triangles in the chart at {at}");

        // Same system, two pins, solved by both.
        let verts: Vec<u32> = {
            let mut v: Vec<u32> = c
                .triangles
                .iter()
                .flat_map(|&t| topo.triangles[t as usize])
                .collect();
            v.sort_unstable();
            v.dedup();
            v
        };
        let lo = *verts
            .iter()
            .min_by(|a, b| uv[a][0].total_cmp(&uv[b][0]))
            .unwrap();
        let hi = *verts
            .iter()
            .max_by(|a, b| uv[a][0].total_cmp(&uv[b][0]))
            .unwrap();
        let pin = |v: u32| [uv[&v][0] as f64, uv[&v][1] as f64];
        let sys = lscm::assemble(topo, &c.triangles, &[(lo, pin(lo)), (hi, pin(hi))], &|v| {
            pin(v)
        });
        let x0: Vec<f64> = sys.vertices.iter().flat_map(|&v| pin(v)).collect();
        let zero = vec![0.0; x0.len()];
        let (xc, rep) = lscm::solve_cpu(&sys, &zero);
        assert_eq!(rep.status, decalbake::solve::sparse::CgStatus::Converged);
        let g = cg_batched(
            &engine.ctx,
            engine.pipelines(),
            &sys.matrix,
            &sys.rhs,
            &zero,
            &[SystemDesc::new(
                0,
                sys.matrix.rows,
                chart::FINAL_RTOL,
                20_000,
            )],
        )
        .unwrap();
        let energy = |x: &[f64]| {
            lscm::conformal_energy(topo, &sys.triangles, |v| {
                let i = sys.local[&v] as usize;
                [x[2 * i], x[2 * i + 1]]
            })
        };
        let xg: Vec<f64> = g.x.iter().map(|&v| v as f64).collect();
        let (eg, ec) = (energy(&xg), energy(&xc));
        let (img, surf) = lscm::areas(topo, &sys.triangles, |v| {
            let i = sys.local[&v] as usize;
            [xc[2 * i], xc[2 * i + 1]]
        });
        eprintln!(
            "{at}: {} unknowns, gpu {} its from zero (cpu f64 {}), energy gpu {eg:.6e} cpu {ec:.6e} (rel excess {:.2e}); chart area {img:.4} surface {surf:.4}",
            sys.matrix.rows, g.reports[0].iterations, rep.iterations, (eg - ec) / ec
        );
        assert_eq!(
            g.reports[0].status,
            decalbake::solve::sparse::CgStatus::Converged
        );
        assert!((eg - ec) / ec <= 1e-3, "gpu energy {eg} vs optimum {ec}");
        // Sanity: the optimum is no worse than the warm start (the chart the bake used).
        assert!(ec <= energy(&x0) * (1.0 + 1e-6));
    }
}

fn bake_report(dir: &Path, layers: serde_json::Value) -> Result<serde_json::Value, String> {
    std::fs::copy(spot(), dir.join("spot.glb")).unwrap();
    std::fs::write(
        dir.join("d.png"),
        test_image(32, 32, 3, false).encode_png(8),
    )
    .unwrap();
    let job = serde_json::json!({
        "mesh": "spot.glb",
        "texture": { "width": 256, "height": 256 },
        "layers": layers,
        "output": { "texture": "out.png", "report": "report.json" }
    });
    std::fs::write(dir.join("job.json"), serde_json::to_vec(&job).unwrap()).unwrap();
    let (code, _, err) = cli(&["bake", dir.join("job.json").to_str().unwrap()]);
    if code != 0 {
        return Err(err);
    }
    Ok(serde_json::from_slice(&std::fs::read(dir.join("report.json")).unwrap()).unwrap())
}

/// On Spot's curved back the conformal decals (LSCM, hybrid) have lower mean angle distortion than
/// the exponential map at the same placement, read from the bake report; LSCM reports its solve.
#[test]
fn conformal_decals_keep_angles_better_than_expmap() {
    let dir = scratch("lscm-distortion");
    let layer = |m: &str| serde_json::json!({ "image": "d.png", "at": [0.0, 0.6, 0.0], "size": [0.5, 0.4], "method": m, "up": [0, 0, 1] });
    let rep = bake_report(
        &dir,
        serde_json::json!([layer("expmap"), layer("lscm"), layer("hybrid")]),
    )
    .unwrap();
    let ls = rep["layers"].as_array().unwrap();
    let angle = |i: usize| {
        ls[i]["distortion"]["angle_distortion_mean"]
            .as_f64()
            .unwrap()
    };
    let flips = |i: usize| ls[i]["distortion"]["flipped"].as_u64().unwrap();
    eprintln!(
        "angle distortion mean: expmap {:.4}, lscm {:.4}, hybrid {:.4}; max: {} {} {}",
        angle(0),
        angle(1),
        angle(2),
        ls[0]["distortion"]["angle_distortion_max"],
        ls[1]["distortion"]["angle_distortion_max"],
        ls[2]["distortion"]["angle_distortion_max"]
    );
    eprintln!(
        "lscm chart: {}\nhybrid chart: {}",
        ls[1]["chart"], ls[2]["chart"]
    );
    assert!(
        angle(1) < angle(0),
        "lscm {} vs expmap {}",
        angle(1),
        angle(0)
    );
    assert!(
        angle(2) < angle(0),
        "hybrid {} vs expmap {}",
        angle(2),
        angle(0)
    );
    assert_eq!(flips(1), 0);
    assert_eq!(ls[1]["chart"]["status"], "converged");
    assert!(ls[1]["chart"]["cg_iterations"].as_u64().unwrap() > 0);
    assert!(ls[1]["chart"]["triangles"].as_u64().unwrap() > 20);
    assert!(
        ls[2]["chart"]["triangles"].as_u64().unwrap() > 0,
        "hybrid re-solved nothing"
    );
}

/// A budget too small to converge fails the bake with the layer, the residual and what to do; no
/// texture is written.
#[test]
fn unconverged_chart_fails_the_bake_clearly() {
    let dir = scratch("lscm-budget");
    let err = bake_report(
        &dir,
        serde_json::json!([
            { "image": "d.png", "at": [0.0, 0.6, 0.0], "size": [0.5, 0.4], "method": "expmap" },
            { "image": "d.png", "at": [0.0, 0.6, 0.0], "size": [0.5, 0.4], "method": "lscm", "cg_max_iterations": 2 }
        ]),
    )
    .unwrap_err();
    eprintln!("{err}");
    assert!(err.contains("layer 1"), "{err}");
    assert!(
        err.contains("did not converge") && err.contains("cg_max_iterations"),
        "{err}"
    );
    assert!(!dir.join("out.png").exists());
}

/// `decalbake param` exports LSCM charts (no distance) and hybrid maps (expmap distance).
#[test]
fn param_exports_conformal_layers() {
    let dir = scratch("lscm-param");
    std::fs::copy(spot(), dir.join("spot.glb")).unwrap();
    std::fs::write(dir.join("d.png"), test_image(8, 8, 2, false).encode_png(8)).unwrap();
    let job = serde_json::json!({
        "mesh": "spot.glb",
        "layers": [
            { "image": "d.png", "at": [0.0, 0.6, 0.0], "size": [0.3, 0.3], "method": "lscm" },
            { "image": "d.png", "at": [0.0, 0.6, 0.0], "size": [0.3, 0.3], "method": "hybrid" }
        ]
    });
    std::fs::write(dir.join("job.json"), serde_json::to_vec(&job).unwrap()).unwrap();
    for (layer, has_distance) in [("0", false), ("1", true)] {
        let out = dir.join(format!("p{layer}.csv"));
        let (code, _, err) = param(&dir.join("job.json"), layer, &out);
        assert_eq!(code, 0, "{err}");
        let text = std::fs::read_to_string(&out).unwrap();
        let rows: Vec<Vec<&str>> = text
            .lines()
            .skip(1)
            .map(|l| l.split(',').collect())
            .collect();
        assert!(rows.len() > 20, "{} rows", rows.len());
        // The row nearest the placed point has coordinates near (0, 0).
        let best = rows
            .iter()
            .map(|f| {
                let p = Vec3::new(
                    f[0].parse().unwrap(),
                    f[1].parse().unwrap(),
                    f[2].parse().unwrap(),
                );
                let uv = glam::Vec2::new(f[4].parse().unwrap(), f[5].parse().unwrap());
                (p, uv)
            })
            .min_by(|a, b| a.1.length().total_cmp(&b.1.length()))
            .unwrap();
        assert!(best.1.length() < 0.05, "closest chart point {:?}", best);
        for f in &rows {
            assert_eq!(!f[3].is_empty(), has_distance, "layer {layer}: {f:?}");
        }
    }
}

/// LSCM systems have the complex 2 × 2 block structure (the real form of a Hermitian matrix), so a
/// batch of them is solved on the blocks, one chart per invocation (`cg_packed` with `cg_complex`).
/// Twenty charts on Spot: the blocks reproduce the real matrix, each chart converges in the same
/// iterations as the same system solved alone on the real CSR (one workgroup; ±1 for f32 rounding),
/// and the two solutions and the f64 twin's agree to 1e-3 of the chart's extent: each is within
/// cond × 1e-6 (the tolerance) of the exact one, and an LSCM system's condition grows with the
/// chart (up to 7e-5 of the extent measured, on the 454-unknown chart).
#[test]
fn lscm_batches_solve_on_complex_blocks() {
    let e = engine();
    let topo = Topology::build(
        &Mesh::load(&spot()).unwrap(),
        decalbake::mesh::DEFAULT_WELD_TOLERANCE,
    );
    let systems: Vec<(lscm::System, Vec<f64>)> = (0..20)
        .map(|k| {
            let v = topo.positions[(k * 97) % topo.positions.len()];
            let (frame, tri) = frame_at(&topo, v, [0.0, 1.0, 0.0], [0.15, 0.15]);
            let (_, s, x0) = chart::initial_system(&topo, &frame, tri);
            (s, x0)
        })
        .collect();
    for (s, _) in &systems {
        let c = decalbake::solve::sparse::ComplexCsr::from_real(&s.matrix).expect("complex blocks");
        let (x, y) = (s.matrix.mul(&s.rhs), c.to_real().mul(&s.rhs));
        let err = x
            .iter()
            .zip(&y)
            .map(|(p, q)| (p - q).abs())
            .fold(0.0, f64::max);
        assert!(
            err <= 1e-12 * x.iter().map(|v| v.abs()).fold(1.0, f64::max),
            "blocks differ by {err}"
        );
    }
    let blocks: Vec<&decalbake::solve::sparse::Csr> =
        systems.iter().map(|(s, _)| &s.matrix).collect();
    let (a, starts) = decalbake::solve::sparse::Csr::block_diagonal(&blocks);
    let b: Vec<f64> = systems.iter().flat_map(|(s, _)| s.rhs.clone()).collect();
    let x0: Vec<f64> = systems.iter().flat_map(|(_, x)| x.clone()).collect();
    let rtol = 1e-6;
    let descs: Vec<SystemDesc> = systems
        .iter()
        .zip(&starts)
        .map(|((s, _), &r0)| SystemDesc::new(r0, s.matrix.rows, rtol, 4000))
        .collect();
    // Packed as on lavapipe (the engine's choice there; a GPU keeps a workgroup per chart).
    let batch = decalbake::solve::gpu::cg_batched_with(
        &e.ctx,
        e.pipelines(),
        (&a, &b, &x0),
        &descs,
        decalbake::solve::gpu::Packing::Packed,
    )
    .unwrap();
    assert!(
        batch.complex && batch.packed == 20,
        "packed {} complex {}",
        batch.packed,
        batch.complex
    );
    for (k, (s, x0k)) in systems.iter().enumerate() {
        let r = starts[k]..starts[k] + s.matrix.rows;
        let alone = cg_batched(
            &e.ctx,
            e.pipelines(),
            &s.matrix,
            &s.rhs,
            x0k,
            // Jacobi, as the packed kernel: the same algorithm on the other storage.
            &[SystemDesc::new(0, s.matrix.rows, rtol, 4000).jacobi_only()],
        )
        .unwrap();
        assert!(!alone.complex && alone.packed == 0);
        let mut xc = x0k.clone();
        decalbake::solve::cg::pcg(&s.matrix, &s.rhs, &mut xc, 1e-12, 20_000);
        let extent = xc.iter().map(|v| v.abs()).fold(1e-9, f64::max);
        let diff = |u: &[f32], v: &[f64]| {
            u.iter()
                .zip(v)
                .map(|(p, q)| (*p as f64 - q).abs())
                .fold(0.0, f64::max)
        };
        let xw: Vec<f64> = alone.x.iter().map(|&v| v as f64).collect();
        let (d_alone, d_twin) = (diff(&batch.x[r.clone()], &xw), diff(&batch.x[r], &xc));
        println!(
            "chart {k}: {} unknowns, complex {} its / real alone {} its; |complex - alone| {:.1e}, |complex - f64| {:.1e} of {extent:.2}",
            s.matrix.rows, batch.reports[k].iterations, alone.reports[0].iterations, d_alone, d_twin
        );
        assert_eq!(
            batch.reports[k].status,
            decalbake::solve::sparse::CgStatus::Converged
        );
        let (ic, ir) = (batch.reports[k].iterations, alone.reports[0].iterations);
        assert!(
            ic.abs_diff(ir) <= 1,
            "chart {k}: {ic} iterations, {ir} alone"
        );
        assert!(
            d_alone <= 1e-3 * extent,
            "chart {k}: {d_alone} from the real solve"
        );
        assert!(
            d_twin <= 1e-3 * extent,
            "chart {k}: {d_twin} from the f64 twin"
        );
    }
}

/// A bake's conformal charts are solved by the CPU twin on a CPU adapter and by the batched GPU
/// CG on a GPU (`StagePaths::charts`, `Auto`); forcing either gives the same texture within one
/// 8-bit step on at most 0.1 % of the values (both solve to the same relative tolerance, in f64
/// and in f32; on lavapipe one value of 262,144 differed, by one step), and the report names the
/// path taken. With the twin stopped at a relative residual of 0.3, 5,745 values differed, by up
/// to 68.
#[test]
fn a_bake_solves_charts_on_the_faster_path_and_both_paths_agree() {
    let mut layers = spot_ring("img.png", 0.2);
    for (i, l) in layers.iter_mut().enumerate() {
        l["method"] = serde_json::json!(if i % 2 == 0 { "lscm" } else { "hybrid" });
    }
    let (job, mut engine, mesh, auto) = spot_paths_bake("chart_paths", layers);
    let cpu_adapter = engine.ctx.device_type == Some(wgpu::DeviceType::Cpu);
    assert_eq!(
        auto.report.paths.charts,
        if cpu_adapter { "cpu" } else { "gpu" }
    );
    let mut baked = Vec::new();
    for path in [decalbake::StagePath::Cpu, decalbake::StagePath::Gpu] {
        engine.stage_paths.charts = path;
        baked.push(engine.bake(&mesh, &job).unwrap());
    }
    let [cpu, gpu] = [&baked[0], &baked[1]];
    assert_eq!(cpu.report.paths.charts, "cpu");
    assert_eq!(gpu.report.paths.charts, "gpu");
    let (differ, worst) = value_diffs(&cpu.texels, &gpu.texels);
    assert!(differ * 1000 <= cpu.texels.len(), "{differ} differ");
    assert!(worst <= 1, "worst difference {worst}");
    let charts = cpu
        .report
        .layers
        .iter()
        .filter(|l| l.chart.is_some())
        .count();
    assert!(charts >= 12, "{charts} layers solved a chart");
}
