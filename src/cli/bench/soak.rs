// SPDX-License-Identifier: MIT OR Apache-2.0
//! `decalbake bench --soak N`: N bakes in one process on one engine and mesh, cycling through four
//! jobs (1, 4, 16 and 64 random decals by every blend mode at 256² and 512²), with the resident
//! memory after each hundred bakes. After a warm-up of a tenth of the bakes (at least 50:
//! pipelines compiled, islands cached per size, the driver's pools grown) the resident memory must
//! stay within [`BOUND`]; the last line says whether it did. `tests/reliability.rs` runs a 300-bake
//! version with the same bound.

use super::common::random_job;
use anyhow::Result;
use decalbake::Engine;
use std::path::Path;
use std::time::Instant;

/// Growth of resident memory after warm-up that still counts as flat.
pub const BOUND: u64 = 24 << 20;

/// Resident memory of this process in bytes (`/proc/self/statm`; 0 where there is none).
fn rss() -> u64 {
    std::fs::read_to_string("/proc/self/statm")
        .ok()
        .and_then(|s| s.split_whitespace().nth(1)?.parse::<u64>().ok())
        .map_or(0, |pages| pages * 4096)
}

/// Runs `bakes` bakes on `mesh_path`; JSON lines through `emit`.
pub fn run(
    engine: &Engine,
    mesh_path: &Path,
    bakes: usize,
    mut emit: impl FnMut(serde_json::Value),
) -> Result<()> {
    let dir = std::env::temp_dir().join(format!("decalbake-bench-soak-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let mesh = engine.load_mesh(mesh_path)?;
    let jobs = [(1, 256), (4, 512), (16, 256), (64, 512)]
        .iter()
        .enumerate()
        .map(|(k, &(n, side))| random_job(&mesh, n, side, &dir, 7 + k as u32, "expmap"))
        .collect::<decalbake::Result<Vec<_>>>()?;
    let warm = (bakes / 10).max(50).min(bakes);
    let (t0, start) = (Instant::now(), rss());
    let mut after_warm = start;
    for i in 1..=bakes {
        engine.bake(&mesh, &jobs[i % jobs.len()])?;
        if i == warm {
            after_warm = rss();
        }
        if i % 100 == 0 || i == bakes {
            emit(
                serde_json::json!({ "bench": "soak", "bakes": i, "rss_mib": rss() as f64 / 1048576.0,
                "seconds": t0.elapsed().as_secs_f64() }),
            );
        }
    }
    let end = rss();
    let growth = end as i64 - after_warm as i64;
    emit(serde_json::json!({
        "bench": "soak_summary", "bakes": bakes, "warmup_bakes": warm, "mesh": mesh_path,
        "adapter": engine.ctx.adapter, "rss_start_mib": start as f64 / 1048576.0,
        "rss_after_warmup_mib": after_warm as f64 / 1048576.0, "rss_end_mib": end as f64 / 1048576.0,
        "growth_after_warmup_kib": growth / 1024, "bound_kib": BOUND / 1024,
        "flat": growth < BOUND as i64,
        "ms_per_bake": t0.elapsed().as_secs_f64() * 1000.0 / bakes.max(1) as f64,
    }));
    let _ = std::fs::remove_dir_all(&dir);
    Ok(())
}
