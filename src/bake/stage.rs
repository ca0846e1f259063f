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
}

/// Milliseconds since `t`.
pub(crate) fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1000.0
}
