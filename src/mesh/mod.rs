// SPDX-License-Identifier: MIT OR Apache-2.0
//! Meshes: loading ([`Mesh`]) and welded surface topology ([`Topology`]).
mod load;
mod topology;

pub use load::{MaterialInfo, Mesh, PrimitiveInfo};
pub use topology::{Topology, DEFAULT_WELD_TOLERANCE, NO_NEIGHBOR};
