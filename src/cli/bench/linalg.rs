// SPDX-License-Identifier: MIT OR Apache-2.0
//! `decalbake bench --linalg`: the GPU linear-algebra core and LSCM charts, with their baselines
//! measured in the same run. One JSON object per line:
//!
//! - `copy`: streaming-copy bandwidth of the device (the reference for SpMV);
//! - `spmv`: CSR product on a real mesh Laplacian, GB/s and non-zeros per second, against the copy
//!   bandwidth and the f64 CPU twin;
//! - `lscm_chart`: one chart of about 1k, 10k and 100k vertices: GPU CG iterations, time per
//!   iteration, dispatches, against the CPU twin (f64 PCG, same tolerance) and, with `--peers`,
//!   libigl's LSCM (direct solve) and scipy's CG on the same patch (written as OBJ and run through
//!   `../shared/peers/peers.py lscm`);
//! - `lscm_batch`: many small charts solved in one batched solve versus one solve per chart, the
//!   batch packed as the engine chooses for this adapter and both ways (`packed_ms`, one chart per
//!   invocation; `per_workgroup_ms`, one per workgroup: `solve::gpu::Packing`).

use decalbake::error::Result;
use decalbake::maps::chart::{self, FINAL_RTOL};
use decalbake::maps::Frame;
use decalbake::mesh::{Mesh, Topology};
use decalbake::solve::gpu::{
    cg_batched, cg_batched_with, copy_bandwidth, spmv, GpuPairs, Packing, Solved, SystemDesc,
};
use decalbake::solve::sparse::Csr;
use decalbake::solve::sparse::PreconditionerKind;
use decalbake::Engine;
use glam::Vec3;
use std::path::{Path, PathBuf};
use std::time::Instant;

use super::common::{frame_at, median, run_peers_py, write_obj, SHARED_MESHES};

/// A chart at triangle `t` with about `target` vertices (bisection on the decal size): its frame,
/// triangles, LSCM system and warm start.
pub fn chart_of_size(
    topo: &Topology,
    t: usize,
    target: usize,
) -> (
    Frame,
    Vec<u32>,
    decalbake::maps::chart::lscm::System,
    Vec<f64>,
) {
    let (lo, hi) = topo
        .positions
        .iter()
        .fold((Vec3::MAX, Vec3::MIN), |(l, h), p| (l.min(*p), h.max(*p)));
    let (mut a, mut b) = (1e-4 * (hi - lo).length(), (hi - lo).length());
    let mut best = None;
    for _ in 0..24 {
        let side = 0.5 * (a + b);
        let f = frame_at(topo, t, side);
        let (tris, sys, x0) = chart::initial_system(topo, &f, t as u32);
        let n = sys.vertices.len();
        if n < target {
            a = side;
        } else {
            b = side;
        }
        let better = best.as_ref().is_none_or(
            |(_, _, s, _): &(
                Frame,
                Vec<u32>,
                decalbake::maps::chart::lscm::System,
                Vec<f64>,
            )| {
                (s.vertices.len() as f64 / target as f64).ln().abs()
                    > (n as f64 / target as f64).ln().abs()
            },
        );
        if better {
            best = Some((f, tris, sys, x0));
        }
        if (n as f64 / target as f64 - 1.0).abs() < 0.05 {
            break;
        }
    }
    best.expect("at least one bisection step")
}

/// Runs `peers.py lscm` on an OBJ patch (the whole chart, disc or not: without `--patch-radius`
/// the script cuts its own patch from non-discs); returns the peers' figures or an error text.
fn run_peer(peers_dir: &Path, obj: &Path, chart_vertices: usize) -> serde_json::Value {
    let args: [&std::ffi::OsStr; 4] = [
        "lscm".as_ref(),
        obj.as_os_str(),
        "--patch-radius".as_ref(),
        "1e30".as_ref(),
    ];
    match run_peers_py(peers_dir, &args) {
        Ok(v) => {
            let patch_nv = v["patch"]["patch_nv"].as_u64().or(v["nv"].as_u64());
            serde_json::json!({
                "igl_lscm_s": v["peers"]["igl_lscm"]["total_s"],
                "scipy_cg_lscm_s": v["peers"]["scipy_cg_lscm"]["total_s"],
                "scipy_cg_iterations": v["peers"]["scipy_cg_lscm"]["iterations"],
                "patch_is_disk": v["patch"]["is_disk"],
                // False if the peer cut its own smaller patch: then the times are not comparable.
                "peer_used_whole_chart": patch_nv == Some(chart_vertices as u64),
                "peer_patch_vertices": patch_nv,
            })
        }
        Err(e) => serde_json::json!({ "error": e }),
    }
}

/// Options of the linear-algebra benchmark.
pub struct LinalgOptions {
    /// Mesh (default: bob from [`SHARED_MESHES`], else the bundled Spot).
    pub mesh: Option<PathBuf>,
    /// Midpoint subdivisions (default 3).
    pub subdivide: u32,
    /// Charts in the batched benchmark.
    pub batch: usize,
    /// Repetitions (median reported).
    pub reps: usize,
    /// `../shared/peers` directory, to run libigl on the same patches.
    pub peers: Option<PathBuf>,
    /// Chart sizes (vertices) of the single-chart figures.
    pub charts: Vec<usize>,
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1000.0
}

/// Runs the benchmark, calling `emit` per figure.
pub fn run(
    engine: &Engine,
    opts: &LinalgOptions,
    mut emit: impl FnMut(serde_json::Value),
) -> Result<()> {
    let ctx = &engine.ctx;
    let pipes = engine.pipelines();
    // Device bandwidth reference.
    let copy_gbs = copy_bandwidth(ctx, pipes, 64 << 20, 20)?;
    emit(
        serde_json::json!({ "bench": "copy", "bytes": 64u64 << 20, "reps": 20, "gb_per_s": copy_gbs }),
    );

    let path = opts.mesh.clone().or_else(|| {
        let p = Path::new(SHARED_MESHES).join("bob.glb");
        p.exists().then_some(p)
    });
    let mut mesh = match &path {
        Some(p) => Mesh::load(p)?,
        None => Mesh::from_bytes(crate::demo::SPOT_GLB, Path::new("spot.glb (bundled)"), None)?,
    };
    for _ in 0..opts.subdivide {
        mesh = mesh.subdivide();
    }
    let topo = Topology::build(&mesh, decalbake::mesh::DEFAULT_WELD_TOLERANCE);
    let source = path
        .map(|p| p.display().to_string())
        .unwrap_or_else(|| "spot (bundled)".into());

    bench_spmv(engine, &topo, &source, opts, copy_gbs, &mut emit)?;
    bench_charts(engine, &topo, &source, (opts, copy_gbs), &mut emit)?;
    bench_batch(engine, &topo, &source, opts, &mut emit)
}

/// SpMV on the mesh Laplacian, GPU against the f64 twin, as a fraction of the copy bandwidth.
fn bench_spmv(
    engine: &Engine,
    topo: &Topology,
    source: &str,
    opts: &LinalgOptions,
    copy_gbs: f64,
    emit: &mut impl FnMut(serde_json::Value),
) -> Result<()> {
    let ctx = &engine.ctx;
    let pipes = engine.pipelines();
    let reps = opts.reps.max(1);
    // SpMV on the mesh Laplacian.
    let lap = decalbake::maps::chart::lscm::shifted_laplacian(topo, 1.0);
    let g = GpuPairs::upload(ctx, &lap)?;
    let x: Vec<f32> = (0..lap.rows)
        .map(|i| ((i * 37) % 101) as f32 / 101.0)
        .collect();
    let xd: Vec<f64> = x.iter().map(|&v| v as f64).collect();
    spmv(ctx, pipes, &g, &x, 1)?;
    let spmv_reps = 20;
    let mut gpu_s = Vec::new();
    for _ in 0..reps {
        gpu_s.push(spmv(ctx, pipes, &g, &x, spmv_reps)?.1 / spmv_reps as f64);
    }
    let gpu_s = median(gpu_s);
    let t = Instant::now();
    let _ = std::hint::black_box(lap.mul(&xd));
    let cpu_s = t.elapsed().as_secs_f64();
    let gbs = g.bytes_per_product() as f64 / gpu_s / 1e9;
    emit(serde_json::json!({
        "bench": "spmv", "mesh": source, "rows": lap.rows, "nnz": lap.nnz(),
        "gpu_ms": gpu_s * 1e3, "gb_per_s": gbs, "fraction_of_copy_bandwidth": gbs / copy_gbs,
        "nnz_per_s": lap.nnz() as f64 / gpu_s, "cpu_twin_ms": cpu_s * 1e3, "cpu_over_gpu": cpu_s / gpu_s,
    }));

    Ok(())
}

/// The spread solve's passes, each timed over 50 dispatches after `solve` (a solve spread
/// over workgroups) finishes (`solve::gpu_wide::TIME_PASSES_REPS`): microseconds a pass, the bytes
/// it moves and that rate against the copy kernel's (`copy_gbs`, the same run).
fn cg_pass_times(copy_gbs: f64, solve: impl FnOnce() -> Result<()>) -> Result<serde_json::Value> {
    use decalbake::solve::gpu_wide::{LAST_PASS_TIMES, TIME_PASSES_REPS};
    use std::sync::atomic::Ordering::Relaxed;
    TIME_PASSES_REPS.store(50, Relaxed);
    let run = solve();
    TIME_PASSES_REPS.store(0, Relaxed);
    run?;
    let times = std::mem::take(&mut *LAST_PASS_TIMES.lock().unwrap_or_else(|e| e.into_inner()));
    Ok(times
        .iter()
        .map(|p| {
            let gbs = (p.bytes > 0).then(|| p.bytes as f64 / (p.us * 1e3));
            serde_json::json!({
                "pass": p.pass, "level": p.level, "workgroups": p.workgroups, "us": p.us,
                "bytes": p.bytes, "gb_per_s": gbs,
                "fraction_of_copy_bandwidth": gbs.map(|g| g / copy_gbs),
            })
        })
        .collect())
}

/// One chart of each requested size: GPU CG, the CPU twin and (with `--peers`) libigl and scipy.
fn bench_charts(
    engine: &Engine,
    topo: &Topology,
    source: &str,
    (opts, copy_gbs): (&LinalgOptions, f64),
    emit: &mut impl FnMut(serde_json::Value),
) -> Result<()> {
    let ctx = &engine.ctx;
    let pipes = engine.pipelines();
    let reps = opts.reps.max(1);
    // One chart of each size.
    let dir = std::env::temp_dir().join(format!("decalbake-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).map_err(|e| decalbake::Error::Io {
        path: dir.clone(),
        action: "creating",
        source: e,
    })?;
    let seed_tri = topo.triangles.len() / 3;
    for &target in &opts.charts {
        if target * 2 > topo.positions.len() {
            continue;
        }
        let (frame, tris, sys, x0) = chart_of_size(topo, seed_tri, target);
        // Set-up on the CPU: selection, pins and assembly of this chart.
        let t = Instant::now();
        let _ = std::hint::black_box(chart::initial_system(topo, &frame, seed_tri as u32));
        let setup_ms = ms(t);
        let budget = 20 * chart::default_budget(sys.matrix.rows);
        let desc = [SystemDesc::new(0, sys.matrix.rows, FINAL_RTOL, budget)];
        let zero = vec![0.0; x0.len()];
        let solve = || cg_batched(ctx, pipes, &sys.matrix, &sys.rhs, &zero, &desc);
        // Large charts take minutes on a software driver: one cold run (pipelines are compiled at
        // engine creation, so "cold" only adds buffer allocation).
        let large = sys.matrix.rows > 50_000;
        if !large {
            solve()?;
        }
        let mut times = Vec::new();
        let mut last = None;
        for _ in 0..if large { 1 } else { reps } {
            let t = Instant::now();
            last = Some(solve()?);
            times.push(ms(t));
        }
        let gpu_ms = median(times);
        let out = last.expect("one repetition");
        let its = out.reports[0].iterations;
        // A baseline: the same solve with the system described by `d`, timed once.
        let baseline = |d: SystemDesc| -> Result<_> {
            let t = Instant::now();
            let o = cg_batched(ctx, pipes, &sys.matrix, &sys.rhs, &zero, &[d])?;
            Ok((o.reports[0], ms(t)))
        };
        // Preconditioned by Jacobi (the baseline of the multigrid row), below 50k unknowns (the
        // 100k chart's took 106 s: docs/performance.md).
        let jacobi = (!large)
            .then(|| baseline(desc[0].jacobi_only()))
            .transpose()?;
        // In one workgroup where the chart is spread over many (`cg_wide`), and spread where the
        // adapter keeps it in one (a multigrid chart of at least 1,024 vertices).
        let one_workgroup = (out.spread > 0)
            .then(|| baseline(desc[0].one_workgroup()))
            .transpose()?;
        let spread = (out.spread == 0 && sys.vertices.len() >= 1024 && !large)
            .then(|| {
                use decalbake::solve::gpu_wide::WIDE_MIN_ROWS_OVERRIDE as WIDE;
                WIDE.store(1, std::sync::atomic::Ordering::Relaxed);
                let r = baseline(desc[0]);
                WIDE.store(0, std::sync::atomic::Ordering::Relaxed);
                r
            })
            .transpose()?
            .filter(|r| r.0.preconditioner == PreconditionerKind::Amg);
        // The multigrid hierarchy's build on the CPU (f64), part of every multigrid solve's
        // `gpu_ms`: the same call `cg_batched` makes.
        let amg_setup_ms = (sys.matrix.rows >= decalbake::solve::amg::AMG_MIN_ROWS).then(|| {
            let t = Instant::now();
            let _ = std::hint::black_box(decalbake::solve::amg::Hierarchy::build(&sys.matrix));
            ms(t)
        });
        let passes = if out.spread > 0 {
            cg_pass_times(copy_gbs, || solve().map(|_| ()))?
        } else {
            serde_json::Value::Null
        };
        let mut xj = zero.clone();
        let t = Instant::now();
        let cpu_jacobi = decalbake::solve::cg::pcg_with(
            &sys.matrix,
            &sys.rhs,
            &mut xj,
            FINAL_RTOL as f64,
            budget,
            &decalbake::solve::cg::Preconditioner::jacobi(&sys.matrix),
        );
        let cpu_jacobi_ms = ms(t);
        let t = Instant::now();
        let mut xc = zero.clone();
        let cpu =
            decalbake::solve::cg::pcg(&sys.matrix, &sys.rhs, &mut xc, FINAL_RTOL as f64, budget);
        let cpu_ms = ms(t);
        let peer = match &opts.peers {
            Some(p) => {
                let obj = dir.join(format!("chart_{target}.obj"));
                write_obj(&obj, topo, &tris)?;
                run_peer(p, &obj, sys.vertices.len())
            }
            None => serde_json::Value::Null,
        };
        emit(serde_json::json!({
            "bench": "lscm_chart", "mesh": source, "mesh_vertices": topo.positions.len(),
            "chart_vertices": sys.vertices.len(), "chart_triangles": tris.len(), "unknowns": sys.matrix.rows, "nnz": sys.matrix.nnz(),
            "gpu_status": out.reports[0].status, "gpu_preconditioner": out.reports[0].preconditioner,
            "gpu_iterations": its, "gpu_residual": out.reports[0].residual,
            "gpu_jacobi_iterations": jacobi.map(|j| j.0.iterations), "gpu_jacobi_ms": jacobi.map(|j| j.1),
            "gpu_ms": gpu_ms, "gpu_ms_per_iteration": gpu_ms / its.max(1) as f64,
            "dispatches": out.dispatches, "submits": out.submits, "gpu_spread": out.spread,
            "gpu_one_workgroup_iterations": one_workgroup.map(|j| j.0.iterations), "gpu_one_workgroup_ms": one_workgroup.map(|j| j.1),
            "gpu_spread_forced_ms": spread.map(|j| j.1), "cg_passes": passes, "amg_setup_ms": amg_setup_ms,
            "cpu_twin_preconditioner": cpu.preconditioner, "cpu_twin_iterations": cpu.iterations,
            "cpu_twin_ms": cpu_ms, "cpu_over_gpu": cpu_ms / gpu_ms,
            "cpu_twin_jacobi_iterations": cpu_jacobi.iterations, "cpu_twin_jacobi_ms": cpu_jacobi_ms,
            "cpu_setup_ms": setup_ms, "start": "zero", "rtol": FINAL_RTOL, "peers": peer,
        }));
    }

    let _ = std::fs::remove_dir_all(&dir);
    Ok(())
}

/// Many small charts: one batched GPU solve against one solve each and the CPU twin.
fn bench_batch(
    engine: &Engine,
    topo: &Topology,
    source: &str,
    opts: &LinalgOptions,
    emit: &mut impl FnMut(serde_json::Value),
) -> Result<()> {
    let ctx = &engine.ctx;
    let pipes = engine.pipelines();
    let reps = opts.reps.max(1);
    let seed_tri = topo.triangles.len() / 3;
    // Batched small charts versus one solve per chart.
    let step = (topo.triangles.len() / opts.batch.max(1)).max(1);
    // The decal size that gives one chart of about 300 vertices, used at every position.
    let side = chart_of_size(topo, seed_tri, 300).0.size[0];
    let systems: Vec<(decalbake::maps::chart::lscm::System, Vec<f64>)> = (0..opts.batch)
        .map(|i| {
            let t = (i * step + step / 2) % topo.triangles.len();
            let (_, s, x0) = chart::initial_system(topo, &frame_at(topo, t, side), t as u32);
            (s, x0)
        })
        .collect();
    let blocks: Vec<&Csr> = systems.iter().map(|(s, _)| &s.matrix).collect();
    let (a, starts) = Csr::block_diagonal(&blocks);
    let b: Vec<f64> = systems.iter().flat_map(|(s, _)| s.rhs.clone()).collect();
    let x0: Vec<f64> = systems.iter().flat_map(|(_, x)| x.clone()).collect();
    let descs: Vec<SystemDesc> = systems
        .iter()
        .zip(&starts)
        .map(|((s, _), &r0)| {
            SystemDesc::new(
                r0,
                s.matrix.rows,
                FINAL_RTOL,
                chart::default_budget(s.matrix.rows),
            )
        })
        .collect();
    // The engine's choice (`Packing::Auto`), then both packings on the same adapter.
    let timed = |packing: Packing| -> decalbake::Result<(f64, Solved)> {
        cg_batched_with(ctx, pipes, (&a, &b, &x0), &descs, packing)?;
        let mut times = Vec::new();
        let mut last = None;
        for _ in 0..reps {
            let t = Instant::now();
            last = Some(cg_batched_with(ctx, pipes, (&a, &b, &x0), &descs, packing)?);
            times.push(ms(t));
        }
        Ok((median(times), last.expect("one repetition")))
    };
    let (batched_ms, out) = timed(Packing::Auto)?;
    let (packed_ms, packed) = timed(Packing::Packed)?;
    let (per_wg_ms, per_wg) = timed(Packing::PerWorkgroup)?;
    let converged = out
        .reports
        .iter()
        .filter(|r| r.status == decalbake::solve::sparse::CgStatus::Converged)
        .count();
    let t = Instant::now();
    let mut single_dispatches = 0;
    for (s, x) in &systems {
        let o = cg_batched(
            ctx,
            pipes,
            &s.matrix,
            &s.rhs,
            x,
            &[SystemDesc::new(
                0,
                s.matrix.rows,
                FINAL_RTOL,
                chart::default_budget(s.matrix.rows),
            )],
        )?;
        single_dispatches += o.dispatches;
    }
    let single_ms = ms(t);
    let t = Instant::now();
    for (s, x) in &systems {
        let mut xc = x.clone();
        decalbake::solve::cg::pcg(
            &s.matrix,
            &s.rhs,
            &mut xc,
            FINAL_RTOL as f64,
            chart::default_budget(s.matrix.rows),
        );
    }
    let cpu_ms = ms(t);
    let mean_v = systems.iter().map(|(s, _)| s.vertices.len()).sum::<usize>() as f64
        / systems.len().max(1) as f64;
    let n = systems.len() as f64;
    emit(serde_json::json!({
        "bench": "lscm_batch", "mesh": source, "charts": systems.len(), "mean_chart_vertices": mean_v, "converged": converged,
        "batched_ms": batched_ms, "batched_charts_per_s": n / (batched_ms / 1e3), "batched_dispatches": out.dispatches, "batched_submits": out.submits,
        "one_by_one_ms": single_ms, "one_by_one_charts_per_s": n / (single_ms / 1e3), "one_by_one_dispatches": single_dispatches,
        "batched_over_one_by_one": single_ms / batched_ms,
        "batched_packing": if out.packed > 0 { "packed" } else { "per_workgroup" },
        "packed_ms": packed_ms, "packed_charts_per_s": n / (packed_ms / 1e3), "packed_systems": packed.packed,
        "per_workgroup_ms": per_wg_ms, "per_workgroup_charts_per_s": n / (per_wg_ms / 1e3), "per_workgroup_dispatches": per_wg.dispatches,
        "cpu_twin_ms": cpu_ms, "cpu_twin_charts_per_s": n / (cpu_ms / 1e3),
    }));
    Ok(())
}
