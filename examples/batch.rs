// SPDX-License-Identifier: MIT OR Apache-2.0
//! Many jobs on one engine from several threads: the mesh is loaded and uploaded once, every
//! thread bakes its own jobs against it, and the same job gives the same bytes on any thread.
//!
//! ```text
//! cargo run --example batch
//! ```

use decalbake::{Engine, Job};
use std::path::Path;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let engine = Engine::new(None)?;
    println!("adapter: {}", engine.ctx.adapter);
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mesh = engine.load_mesh(&root.join("assets/spot.glb"))?;
    let dir = std::env::temp_dir().join(format!("decalbake-batch-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    std::fs::write(dir.join("square.png"), square(32))?;

    // Eight jobs: a square decal turned a little further each time, seen from the right flank.
    let jobs: Vec<Job> = (0..8)
        .map(|i| {
            let text = format!(
                r#"{{ "mesh": "spot.glb", "texture": {{ "width": 256, "height": 256 }},
                     "layers": [ {{ "image": "square.png", "size": [0.3, 0.3], "angle": {},
                                   "at": {{ "ray": {{ "origin": [1.5, 0.0, 0.45], "dir": [-1, 0, 0] }} }} }} ] }}"#,
                i * 10
            );
            Job::parse(&text, &dir.join(format!("job{i}.json")), &dir, &dir)
        })
        .collect::<Result<_, _>>()?;

    // Two threads share the engine and the mesh; each takes every other job.
    let threads = 2;
    let start = Instant::now();
    let baked: Vec<Vec<(usize, Vec<u8>)>> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..threads)
            .map(|t| {
                let (engine, mesh, jobs) = (&engine, &mesh, &jobs);
                s.spawn(move || {
                    (t..jobs.len())
                        .step_by(threads)
                        .map(|i| engine.bake(mesh, &jobs[i]).map(|b| (i, b.rgba8())))
                        .collect::<Result<Vec<_>, _>>()
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().expect("a baking thread panicked"))
            .collect::<Result<_, _>>()
    })?;
    let mut textures: Vec<(usize, Vec<u8>)> = baked.into_iter().flatten().collect();
    textures.sort_by_key(|(i, _)| *i);
    println!(
        "{} jobs on {threads} threads in {:.0} ms",
        textures.len(),
        start.elapsed().as_secs_f64() * 1e3
    );

    // The same job again on this thread: the same bytes.
    let again = engine.bake(&mesh, &jobs[3])?.rgba8();
    assert_eq!(
        again, textures[3].1,
        "a job's bytes do not depend on its thread"
    );
    let distinct = textures.windows(2).filter(|w| w[0].1 != w[1].1).count();
    println!("job 3 baked again gives the same bytes; {distinct} of 7 neighbours differ");
    std::fs::remove_dir_all(&dir)?;
    Ok(())
}

/// A 16-bit RGBA PNG: a blue square with a yellow top half, so its turn shows.
fn square(n: u32) -> Vec<u8> {
    let mut samples = Vec::with_capacity((n * n * 4) as usize);
    for y in 0..n {
        for _ in 0..n {
            let top = y < n / 2;
            let rgb = if top {
                [u16::MAX, u16::MAX, 0]
            } else {
                [0, 0, u16::MAX]
            };
            samples.extend_from_slice(&[rgb[0], rgb[1], rgb[2], u16::MAX]);
        }
    }
    decalbake::io::image::png_bytes(n, n, 16, &samples)
}
