// SPDX-License-Identifier: MIT OR Apache-2.0
//! Meshes: loading ([`Mesh`]), welded surface topology ([`Topology`]), intrinsic surface data
//! ([`surface::SurfaceData`]), tangent frames for normal maps ([`tangents::tangents`]) and the GPU
//! upload ([`upload::GpuMesh`]).
pub mod bvh;
mod checks;
mod decode;
pub mod document;
pub mod lbvh;
mod load;
pub mod material;
mod sets;
pub mod surface;
pub mod tangents;
mod topology;
pub mod upload;

pub use checks::MAX_ELEMENTS;
pub use document::SourceDocument;
pub use load::{MaterialInfo, Mesh, PrimitiveInfo};
pub use sets::TextureSet;
pub use surface::SurfaceData;
pub use topology::{Topology, DEFAULT_WELD_TOLERANCE, NO_NEIGHBOR};
pub use upload::GpuMesh;

/// The welded surface as the map kernels read it: topology, intrinsic data and the GPU buffers
/// (borrowed from the engine's loaded mesh).
#[derive(Clone, Copy)]
pub struct SurfaceRef<'a> {
    /// Welded topology.
    pub topo: &'a Topology,
    /// Curvature and edge angles.
    pub surface: &'a SurfaceData,
    /// GPU buffers.
    pub gpu: &'a GpuMesh,
}
