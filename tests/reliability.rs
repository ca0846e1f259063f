// SPDX-License-Identifier: MIT OR Apache-2.0
//! Reliability: a device destroyed from another thread in the middle of a bake gives
//! `Error::DeviceLost` (never a panic, never a wrong texture), a fresh engine bakes the same bytes
//! again; allocations beyond the adapter's limits are typed errors; one process baking many jobs
//! keeps its resident memory flat.

mod common;
use common::*;
use decalbake::{Error, Job};
use std::path::Path;
use std::time::{Duration, Instant};

/// Spot with 24 exponential-map decals at 512²: long enough on lavapipe (a few hundred ms warm)
/// for a destroy to land inside it.
fn heavy_job(dir: &Path) -> Job {
    let spot = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/spot.glb");
    std::fs::write(
        dir.join("img.png"),
        test_image(32, 32, 5, true).encode_png(8),
    )
    .unwrap();
    let layers: Vec<serde_json::Value> = (0..24)
        .map(|i| {
            let t = i as f32 * 0.26;
            let y = 0.1 + 0.15 * (2.0 * t).sin();
            let origin = [2.0 * t.cos(), y, 0.2 + 2.0 * t.sin()];
            let dir = [-origin[0], 0.0, 0.2 - origin[2]];
            serde_json::json!({ "image": "img.png", "method": "expmap", "size": [0.25, 0.25],
                "at": { "ray": { "origin": origin, "dir": dir } } })
        })
        .collect();
    let text = serde_json::json!({ "mesh": spot, "texture": { "width": 512, "height": 512 },
        "layers": layers, "output": { "texture": "out.png" } });
    Job::parse(&text.to_string(), &dir.join("job.json"), dir, dir).unwrap()
}

/// Bakes `job` on a fresh engine while another thread destroys its device `after` the bake
/// started. Returns the result and whether the destroy came before the bake returned.
fn bake_and_destroy(job: &Job, after: Duration) -> (decalbake::Result<decalbake::Baked>, bool) {
    let engine = engine();
    let mesh = engine.load_mesh(&job.mesh).unwrap();
    // Warm the pipelines and the mesh's caches, so the destroy lands in the bake's own work.
    engine.bake(&mesh, job).unwrap();
    let (out, destroyed_at) = std::thread::scope(|s| {
        let killer = s.spawn(|| {
            std::thread::sleep(after);
            engine.ctx.device.destroy();
            Instant::now()
        });
        let out = engine.bake(&mesh, job);
        let returned = Instant::now();
        (out, killer.join().unwrap() < returned)
    });
    // Once lost, every later bake on the engine says so at once.
    assert!(engine.ctx.is_lost());
    assert!(matches!(
        engine.bake(&mesh, job),
        Err(Error::DeviceLost { .. })
    ));
    (out, destroyed_at)
}

#[test]
fn a_device_destroyed_mid_bake_gives_device_lost_and_a_fresh_engine_bakes_the_same_bytes() {
    let dir = scratch("device_loss");
    let job = heavy_job(&dir);
    let reference = {
        let engine = engine();
        let mesh = engine.load_mesh(&job.mesh).unwrap();
        engine.bake(&mesh, &job).unwrap();
        let t = Instant::now();
        let baked = engine.bake(&mesh, &job).unwrap();
        (baked, t.elapsed())
    };
    let (reference, warm) = reference;
    println!("warm bake: {warm:?}");
    for frac in [0.0, 0.1, 0.5] {
        let (out, destroyed_first) = bake_and_destroy(&job, warm.mul_f64(frac));
        match out {
            Err(Error::DeviceLost { stage, detail }) => {
                println!("destroyed at {frac} of a bake: lost during {stage}: {detail}")
            }
            Err(e) => panic!("a destroyed device must give DeviceLost, got: {e}"),
            // Only a bake that had read its texture back before the destroy may succeed, and then
            // with the right bytes.
            Ok(b) => {
                assert!(
                    !destroyed_first || frac > 0.0,
                    "destroy before the bake, yet Ok"
                );
                assert_eq!(b.texels, reference.texels, "a bake that survived differs");
                assert!(
                    frac > 0.1,
                    "destroyed at {frac} of the bake, yet it succeeded"
                );
            }
        }
    }
    // A fresh engine after a loss bakes the very same bytes.
    let engine = engine();
    let mesh = engine.load_mesh(&job.mesh).unwrap();
    assert_eq!(engine.bake(&mesh, &job).unwrap().texels, reference.texels);
}
