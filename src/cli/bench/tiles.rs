// SPDX-License-Identifier: MIT OR Apache-2.0
//! `decalbake bench --tiles`: the same decals baked at each of `--sizes` (default 4096 and 8192;
//! above the device's storage binding, 8192² on lavapipe, the bake goes by tiles, `bake/tiles.rs`),
//! one JSON line per size: wall time of a warm bake (median of `--reps`; the first, cold bake also
//! rasterizes and distance-transforms the islands), its stages, and the cost per texel against the
//! first size's in the same run. The target: tiled 8K within 1.2× the per-texel cost of 4K.

use super::common::{median, random_job};
use decalbake::Engine;
use std::path::Path;
use std::time::Instant;

/// Runs the benchmark on `mesh_path` with `decals` planar decals; JSON lines through `emit`.
pub fn run(
    engine: &Engine,
    mesh_path: &Path,
    sizes: &[u32],
    decals: usize,
    reps: usize,
    mut emit: impl FnMut(serde_json::Value),
) -> anyhow::Result<()> {
    let dir = std::env::temp_dir().join(format!("decalbake-bench-tiles-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let mesh = engine.load_mesh(mesh_path)?;
    let mut first_ns_per_texel = None;
    for &side in sizes {
        let job = random_job(&mesh, decals, side, &dir, 11, "planar")?;
        let t = Instant::now();
        let cold = engine.bake(&mesh, &job)?;
        let cold_ms = t.elapsed().as_secs_f64() * 1000.0;
        let mut times = Vec::new();
        let mut last = cold;
        for _ in 0..reps.max(1) {
            let t = Instant::now();
            last = engine.bake(&mesh, &job)?;
            times.push(t.elapsed().as_secs_f64() * 1000.0);
        }
        let ms = median(times);
        let ns_per_texel = ms * 1e6 / (side as f64 * side as f64);
        let base = *first_ns_per_texel.get_or_insert(ns_per_texel);
        let tm = &last.report.timings;
        emit(serde_json::json!({
            "bench": "tiles", "side": side, "decals": decals, "mesh": mesh_path,
            "tiles": last.report.tiles, "cold_ms": cold_ms, "warm_ms": ms,
            "ns_per_texel": ns_per_texel, "per_texel_vs_first_size": ns_per_texel / base,
            "placement_ms": tm.placement_ms, "compose_ms": tm.compose_ms,
            "padding_ms": tm.padding_ms, "encode_ms": tm.encode_ms,
            "adapter": engine.ctx.adapter,
        }));
    }
    let _ = std::fs::remove_dir_all(&dir);
    Ok(())
}
