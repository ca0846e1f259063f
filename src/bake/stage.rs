// SPDX-License-Identifier: MIT OR Apache-2.0
//! What the bake's stages share: their inputs ([`Cx`]) and what they record for the report
//! ([`Log`]).

use super::engine::{Engine, LoadedMesh};
use super::report::Timings;
use crate::io::job::Job;
use std::time::Instant;

/// What every stage reads: the engine, the mesh and the job.
#[derive(Clone, Copy)]
pub(crate) struct Cx<'a> {
    pub engine: &'a Engine,
    pub mesh: &'a LoadedMesh,
    pub job: &'a Job,
}

/// What the stages record as they go, for the report.
pub(crate) struct Log {
    /// Milliseconds per stage.
    pub timings: Timings,
    /// Warnings, in the order they arose.
    pub warnings: Vec<String>,
    /// GPU dispatches and draws issued.
    pub commands: u32,
    /// Where the stages that have a CPU twin ran.
    pub paths: super::report::Paths,
}

/// Milliseconds since `t`.
pub(crate) fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1000.0
}

/// Memory budget for one chunk's per-unit coordinates and triangle lists.
pub(crate) const CHUNK_BUDGET: u64 = 64 << 20;

/// How many units' coordinate slots and triangle lists fit [`CHUNK_BUDGET`] on `mesh` (at least
/// one): the most units one chunk of the map stage holds. On a device whose storage buffers hold
/// less than the budget ([`crate::gpu::GpuContext::storage_limit`]), the chunks shrink to fit it
/// (a unit's slot alone past the limit is [`crate::Error::DeviceLimit`], from [`check_units`]).
pub(crate) fn unit_capacity(mesh: &LoadedMesh) -> usize {
    let g = &mesh.gpu;
    let per_unit = g.vertex_count as u64 * 16 + g.triangle_count as u64 * 4;
    let budget = CHUNK_BUDGET.min(mesh.storage_limit);
    (budget / per_unit.max(1)).max(1) as usize
}

/// [`crate::Error::DeviceLimit`] when one unit's coordinate slot (16 bytes a welded vertex) does
/// not fit a storage buffer of the engine's device.
pub(crate) fn check_units(cx: Cx<'_>) -> crate::error::Result<()> {
    let bytes = cx.mesh.gpu.vertex_count as u64 * 16;
    cx.engine.ctx.fits(
        || format!("a layer's coordinates on {}", cx.mesh.mesh.source.display()),
        bytes,
        "bake on a device with larger storage buffers, or on a mesh with fewer vertices",
    )
}
