// SPDX-License-Identifier: MIT OR Apache-2.0
//! Criterion benchmarks of the GPU linear algebra on the bundled Spot: SpMV on its Laplacian (one
//! submission, 20 products), one LSCM chart of about 1k vertices solved by the GPU CG and by the f64
//! CPU twin, a larger chart with the multigrid V-cycle against Jacobi (GPU and twin; the twin's
//! V-cycle time includes its set-up; the set-up and the complex-block check also alone), and 64
//! small charts batched versus one solve each. `decalbake bench --linalg` gives the
//! larger sizes, bandwidth ratios and the libigl comparison.
//!
//! Run: `cargo bench --bench linalg` (set `WGPU_BACKEND=vulkan` for lavapipe).

use criterion::{criterion_group, criterion_main, Criterion};
use decalbake::maps::chart::{self, FINAL_RTOL};
use decalbake::mesh::{Mesh, Topology, DEFAULT_WELD_TOLERANCE};
use decalbake::solve::gpu::{cg_batched, spmv, GpuPairs, SystemDesc};
use decalbake::solve::sparse::Csr;
use decalbake::Engine;

// The workloads are the `decalbake bench` ones (the binary's `src/cli/bench/common.rs`, which uses the
// demo's images), compiled into this bench so that the library exports no benchmark code.
#[path = "../src/cli/bench/common.rs"]
mod common;
#[path = "../src/cli/demo.rs"]
#[allow(dead_code)]
mod demo;
use common::frame_at;

fn linalg(c: &mut Criterion) {
    let engine = Engine::new(None).expect("a GPU adapter (mesa-vulkan-drivers for lavapipe)");
    let mesh = Mesh::from_bytes(demo::SPOT_GLB, std::path::Path::new("spot.glb"), None)
        .expect("bundled mesh")
        .subdivide();
    let topo = Topology::build(&mesh, DEFAULT_WELD_TOLERANCE);
    let (ctx, pipes) = (&engine.ctx, engine.pipelines());
    let mut group = c.benchmark_group("linalg");
    group.sample_size(10);

    let lap = decalbake::maps::chart::lscm::shifted_laplacian(&topo, 1.0);
    let g = GpuPairs::upload(ctx, &lap).unwrap();
    let x: Vec<f32> = (0..lap.rows).map(|i| (i % 7) as f32).collect();
    group.bench_function("spmv_x20_spot_laplacian", |b| {
        b.iter(|| spmv(ctx, pipes, &g, &x, 20).unwrap())
    });

    let t = topo.triangles.len() / 3;
    let (_, sys, x0) = chart::initial_system(&topo, &frame_at(&topo, t, 0.35), t as u32);
    let desc = [SystemDesc::new(
        0,
        sys.matrix.rows,
        FINAL_RTOL,
        chart::default_budget(sys.matrix.rows),
    )];
    group.bench_function("lscm_chart_gpu", |b| {
        b.iter(|| cg_batched(ctx, pipes, &sys.matrix, &sys.rhs, &x0, &desc).unwrap())
    });
    group.bench_function("lscm_chart_cpu_twin", |b| {
        b.iter(|| {
            let mut x = x0.clone();
            decalbake::solve::cg::pcg(&sys.matrix, &sys.rhs, &mut x, FINAL_RTOL as f64, 100_000)
        })
    });

    // A chart large enough for the multigrid V-cycle, against Jacobi on the same system.
    let (_, big, big_x0) = chart::initial_system(&topo, &frame_at(&topo, t, 0.8), t as u32);
    assert!(big.matrix.rows >= decalbake::solve::amg::AMG_MIN_ROWS);
    let budget = 20 * chart::default_budget(big.matrix.rows);
    let d = SystemDesc::new(0, big.matrix.rows, FINAL_RTOL, budget);
    for (name, desc) in [("vcycle", d), ("jacobi", d.jacobi_only())] {
        group.bench_function(format!("lscm_chart_{}_gpu_{name}", big.matrix.rows), |b| {
            b.iter(|| cg_batched(ctx, pipes, &big.matrix, &big.rhs, &big_x0, &[desc]).unwrap())
        });
    }
    let (m, r, rows) = (&big.matrix, &big.rhs, big.matrix.rows);
    group.bench_function(format!("lscm_chart_{rows}_cpu_twin_vcycle"), |b| {
        b.iter(|| {
            let mut x = big_x0.clone();
            decalbake::solve::cg::pcg(m, r, &mut x, FINAL_RTOL as f64, budget)
        })
    });
    let jacobi = decalbake::solve::cg::Preconditioner::jacobi(m);
    group.bench_function(format!("lscm_chart_{rows}_cpu_twin_jacobi"), |b| {
        b.iter(|| {
            let mut x = big_x0.clone();
            decalbake::solve::cg::pcg_with(m, r, &mut x, FINAL_RTOL as f64, budget, &jacobi)
        })
    });

    // The V-cycle's hierarchy alone (part of both V-cycle solves above), and the complex-block
    // check the GPU path runs on the chart before it.
    group.bench_function(format!("lscm_chart_{rows}_amg_setup"), |b| {
        b.iter(|| decalbake::solve::amg::Hierarchy::build(m).expect("a hierarchy"))
    });
    group.bench_function(format!("lscm_chart_{rows}_complex_check"), |b| {
        b.iter(|| decalbake::solve::sparse::ComplexCsr::from_real(m).expect("complex blocks"))
    });

    let systems: Vec<_> = (0..64)
        .map(|i| {
            let t = (i * 131 + 17) % topo.triangles.len();
            let (_, s, x0) = chart::initial_system(&topo, &frame_at(&topo, t, 0.12), t as u32);
            (s, x0)
        })
        .collect();
    let blocks: Vec<&Csr> = systems.iter().map(|(s, _)| &s.matrix).collect();
    let (a, starts) = Csr::block_diagonal(&blocks);
    let rhs: Vec<f64> = systems.iter().flat_map(|(s, _)| s.rhs.clone()).collect();
    let x0: Vec<f64> = systems.iter().flat_map(|(_, x)| x.clone()).collect();
    let descs: Vec<SystemDesc> = systems
        .iter()
        .zip(&starts)
        .map(|((s, _), &r0)| SystemDesc::new(r0, s.matrix.rows, FINAL_RTOL, 20_000))
        .collect();
    group.bench_function("64_charts_batched", |b| {
        b.iter(|| cg_batched(ctx, pipes, &a, &rhs, &x0, &descs).unwrap())
    });
    group.bench_function("64_charts_one_by_one", |b| {
        b.iter(|| {
            for (s, x) in &systems {
                let d = [SystemDesc::new(0, s.matrix.rows, FINAL_RTOL, 20_000)];
                cg_batched(ctx, pipes, &s.matrix, &s.rhs, x, &d).unwrap();
            }
        })
    });
    group.finish();
}

criterion_group!(benches, linalg);
criterion_main!(benches);
