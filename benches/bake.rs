// SPDX-License-Identifier: MIT OR Apache-2.0
//! Criterion benchmarks of the bake on the bundled Spot (or the mesh in `DECALBAKE_BENCH_MESH`):
//! whole bakes of 1, 16 and 256 planar decals at 1024² with the mesh's islands cached (the steady
//! state of "load once, bake many"), batched GPU placement, and the demo's stroke per stamp method. The `decalbake bench` subcommand
//! gives the per-stage split and the larger sizes.
//!
//! Run: `cargo bench --bench bake` (set `WGPU_BACKEND=vulkan` for lavapipe).

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use decalbake::place::Query;
use decalbake::{Engine, LoadedMesh};
use std::path::PathBuf;

// The workloads are the `decalbake bench` ones (the binary's `src/cli/bench/common.rs`, which uses the
// demo's images), compiled into this bench so that the library exports no benchmark code.
#[path = "../src/cli/bench/common.rs"]
mod common;
#[path = "../src/cli/demo.rs"]
#[allow(dead_code)]
mod demo;

fn setup() -> (Engine, LoadedMesh) {
    let engine = Engine::new(None).expect("a GPU adapter (mesa-vulkan-drivers for lavapipe)");
    let mesh = match std::env::var("DECALBAKE_BENCH_MESH") {
        Ok(p) => engine.load_mesh(&PathBuf::from(p)).expect("mesh loads"),
        Err(_) => engine
            .load_mesh_bytes(demo::SPOT_GLB, std::path::Path::new("spot.glb"))
            .expect("bundled mesh loads"),
    };
    (engine, mesh)
}

fn bake(c: &mut Criterion) {
    let (engine, mesh) = setup();
    let dir = std::env::temp_dir().join(format!("decalbake-criterion-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut group = c.benchmark_group("bake_1024");
    group.sample_size(10);
    for n in [1usize, 16, 256] {
        let job = common::random_job(&mesh, n, 1024, &dir, 11, "planar").unwrap();
        engine.bake(&mesh, &job).unwrap(); // warm-up: shaders, island cache
        group.throughput(Throughput::Elements(n as u64));
        group.bench_with_input(BenchmarkId::new("decals", n), &job, |b, job| {
            b.iter(|| engine.bake(&mesh, job).unwrap())
        });
    }
    group.finish();
    let _ = std::fs::remove_dir_all(&dir);
}

fn placement(c: &mut Criterion) {
    let (engine, mesh) = setup();
    let queries: Vec<Query> = (0..256)
        .map(|i| {
            let a = i as f32 * 0.1;
            Query::Point(glam::Vec3::new(
                a.sin() * 0.5,
                (a * 0.7).cos() * 0.8,
                a.cos() * 0.8,
            ))
        })
        .collect();
    let mut group = c.benchmark_group("placement");
    group.sample_size(20);
    group.throughput(Throughput::Elements(queries.len() as u64));
    group.bench_function("256_points", |b| {
        b.iter(|| engine.place(&mesh, &queries).expect("placement on the GPU"))
    });
    group.finish();
}

/// The demo's stroke (a wave of about a hundred stamps over Spot's back) alone at 1024², per stamp
/// method; `decalbake bench --strokes` gives the large case and its baselines.
fn stroke(c: &mut Criterion) {
    let (engine, mesh) = setup();
    let dir =
        std::env::temp_dir().join(format!("decalbake-criterion-stroke-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("brush.png"), demo::brush(64).encode_png(8)).unwrap();
    let demo: serde_json::Value = serde_json::from_str(&demo::job_json()).unwrap();
    let mut group = c.benchmark_group("stroke_1024");
    group.sample_size(10);
    for method in ["lscm", "expmap"] {
        let mut layer = demo["layers"][4].clone();
        layer["image"] = "brush.png".into();
        layer["method"] = method.into();
        let job = serde_json::json!({ "mesh": "spot.glb", "texture": { "width": 1024, "height": 1024 },
            "layers": [layer], "output": { "texture": null, "report": null } });
        let job =
            decalbake::Job::parse(&job.to_string(), &dir.join("job.json"), &dir, &dir).unwrap();
        let stamps = engine.bake(&mesh, &job).unwrap().report.layers[0]
            .stroke
            .as_ref()
            .unwrap()
            .stamps;
        group.throughput(Throughput::Elements(stamps as u64));
        group.bench_with_input(BenchmarkId::new("stamps", method), &job, |b, job| {
            b.iter(|| engine.bake(&mesh, job).unwrap())
        });
    }
    group.finish();
    let _ = std::fs::remove_dir_all(&dir);
}

criterion_group!(benches, bake, placement, stroke);
criterion_main!(benches);
