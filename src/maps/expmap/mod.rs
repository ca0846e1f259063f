// SPDX-License-Identifier: MIT OR Apache-2.0
//! `"method": "expmap"`: the discrete exponential map around the placed point (Schmidt, Grimm &
//! Wyvill 2006), computed on the GPU by relaxation ([`gpu`], `wgsl/maps/expmap_relax.wgsl`) with a
//! serial Dijkstra CPU twin ([`cpu`]); [`sphere`] holds the sphere's exact answer for tests and
//! benches.
pub mod cpu;
pub mod gpu;
pub mod sphere;

pub use crate::io::job::Accuracy;
pub use cpu::{dem_cpu, ExpMap, Options, Seed};
pub use gpu::GeoResult;

use super::MapMethod;

/// `"method": "expmap"`: the coordinates are the exponential map itself.
pub struct Expmap;

impl MapMethod for Expmap {
    fn uses_expmap(&self) -> bool {
        true
    }
}
