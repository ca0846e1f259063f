// SPDX-License-Identifier: MIT OR Apache-2.0
//! `decalbake bench --edit`: what an edit of a live bake costs against a full bake, at each of
//! `--sizes` (default 4096): `--decals` (the largest value, default 256) planar decals on
//! `--mesh` (default the bundled bob) at [`random_job`]'s places, baked in full `--reps` times
//! (`full_ms`, the median: `Engine::bake`, read-back included, no PNG), then kept live
//! (`Engine::live`, `live_ms`) while one decal is moved 20 times to other random points:
//! `edit_ms` is the median of those edits (`LiveBake::apply`: the texture is current when it
//! returns), `edit_read_ms` the median with the changed rows read back (`LiveBake::read`),
//! `edit_steps_ms` the medians of the edit's steps (`EditReport`), and
//! `identical` whether the live bytes equal a full bake of the final job, byte for byte. One JSON
//! line per size through `emit`.

use super::common::{median, random_job};
use decalbake::{Edit, Engine};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Options of `decalbake bench --edit`.
pub struct EditBenchOptions {
    /// The mesh.
    pub mesh: PathBuf,
    /// Texture sides.
    pub sizes: Vec<u32>,
    /// Decals in the job.
    pub decals: usize,
    /// Full bakes timed (median reported).
    pub reps: usize,
}

/// Moves timed.
const MOVES: usize = 20;

/// Runs the benchmark: JSON lines through `emit`.
pub fn run(
    engine: &Engine,
    opts: &EditBenchOptions,
    mut emit: impl FnMut(serde_json::Value),
) -> anyhow::Result<()> {
    super::common::in_scratch("edit", |dir| run_in(engine, opts, dir, &mut emit))
}

/// [`run`] in the scratch folder `dir`.
fn run_in(
    engine: &Engine,
    opts: &EditBenchOptions,
    dir: &Path,
    emit: &mut dyn FnMut(serde_json::Value),
) -> anyhow::Result<()> {
    let mesh = engine.load_mesh(&opts.mesh)?;
    for &side in &opts.sizes {
        let job = random_job(&mesh, opts.decals, side, dir, 11, "planar")?;
        // The points the decal moves to: other random places on the surface.
        let targets = random_job(&mesh, MOVES, side, dir, 29, "planar")?;
        engine.bake(&mesh, &job)?;
        let mut full = Vec::with_capacity(opts.reps);
        for _ in 0..opts.reps.max(1) {
            let t = Instant::now();
            engine.bake(&mesh, &job)?;
            full.push(t.elapsed().as_secs_f64() * 1000.0);
        }
        let t = Instant::now();
        let mut live = engine.live(&mesh, &job)?;
        let live_ms = t.elapsed().as_secs_f64() * 1000.0;
        let layer = opts.decals / 2;
        let (mut edits, mut reads, mut cells, mut drawn) = (Vec::new(), Vec::new(), 0, 0);
        let mut steps: [Vec<f64>; 4] = Default::default();
        for target in &targets.layers {
            let mut l = live.job().layers[layer].clone();
            l.at = target.at.clone();
            let t = Instant::now();
            let r = live.apply(Edit::Set {
                layer,
                to: Box::new(l),
            })?;
            edits.push(t.elapsed().as_secs_f64() * 1000.0);
            live.read()?;
            reads.push(t.elapsed().as_secs_f64() * 1000.0);
            for (v, ms) in steps
                .iter_mut()
                .zip([r.place_ms, r.maps_ms, r.compose_ms, r.encode_ms])
            {
                v.push(ms);
            }
            cells += r.cells;
            drawn += r.layers_drawn;
        }
        let last = engine.bake(&mesh, live.job())?;
        let identical = live.read()? == &last.texels[..];
        let (full_ms, edit_ms) = (median(full), median(edits));
        let [place, maps, compose, encode] = steps.map(median);
        emit(serde_json::json!({
            "bench": "edit",
            "adapter": engine.ctx.adapter,
            "mesh": opts.mesh.display().to_string(),
            "texture": side,
            "decals": opts.decals,
            "full_ms": full_ms,
            "live_ms": live_ms,
            "edit_ms": edit_ms,
            "edit_read_ms": median(reads),
            "edit_steps_ms": { "place": place, "maps": maps, "compose": compose, "encode": encode },
            "edit_over_full": edit_ms / full_ms,
            "mean_cells": cells as f64 / MOVES as f64,
            "cells": (side / 64).pow(2),
            "mean_layers_drawn": drawn as f64 / MOVES as f64,
            "identical": identical,
        }));
    }
    Ok(())
}
