// SPDX-License-Identifier: MIT OR Apache-2.0
//! Stage 2, placement: every layer's query placed on the mesh in one GPU submission
//! ([`crate::place::place_gpu`]: `wgsl/place/place_candidates.wgsl` + `place_reduce.wgsl`, CPU twin
//! [`crate::place::place_cpu`]), then each layer's kind turns its placement into a frame.

use super::kinds::kind;
use super::stage::{Cx, Log};
use crate::error::Result;
use crate::maps::Frame;
use crate::place::{place_gpu, Placement};

/// Where every layer landed, and its frame there.
pub struct Placed {
    /// Per layer.
    pub placements: Vec<Placement>,
    /// Per layer.
    pub frames: Vec<Frame>,
}

/// Places every layer of `job` on `mesh`.
pub(crate) fn place(cx: Cx<'_>, log: &mut Log) -> Result<Placed> {
    let Cx { engine, mesh, job } = cx;
    let queries: Vec<_> = job.layers.iter().map(|l| kind(l.kind).query(l)).collect();
    let placements = place_gpu(&engine.ctx, &engine.pipes, &mesh.gpu, &queries)?;
    log.commands += 2;
    let mut frames = Vec::with_capacity(placements.len());
    for (i, (l, p)) in job.layers.iter().zip(&placements).enumerate() {
        frames.push(kind(l.kind).frame(job, i, p, &mut log.warnings)?);
    }
    Ok(Placed { placements, frames })
}
