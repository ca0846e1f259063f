// SPDX-License-Identifier: MIT OR Apache-2.0
//! decalbake: bakes decals onto 3D meshes, straight into the mesh's texture, on the GPU.
//!
//! The modules read as the pipeline (see `ARCHITECTURE.md`); each folder imports only from the
//! ones listed before it:
//! - [`error`], [`gpu`]: typed errors; the device, the WGSL sources and every pipeline;
//! - [`io`]: the job file (the schema every other module reads) and image decoding/encoding;
//! - [`mesh`]: glTF loading, welding and topology, intrinsic surface data, the GPU upload;
//! - [`solve`]: sparse matrices and the conjugate gradient (CPU twin and GPU);
//! - [`place`]: where a layer lands on the surface (GPU and CPU twin);
//! - [`maps`]: a layer's local coordinates, one module per method (planar, expmap, lscm, hybrid);
//! - [`pelt`]: new UV sets by pelting (cut, spring dynamics on the GPU, packing);
//! - [`bake`]: the engine and the bake's stages, from images to the encoded texture;
//! - [`output`]: the files a bake writes (PNG, GLB, preview, report).
#![warn(missing_docs)]
pub mod bake;
pub mod error;
pub mod gpu;
pub mod io;
pub mod maps;
pub mod mesh;
pub mod output;
pub mod pelt;
pub mod place;
pub mod solve;

pub use bake::{
    Baked, BakedTextures, BvhBuild, Edit, EditReport, Engine, LiveBake, LoadedMesh, StagePath,
    StagePaths,
};
pub use error::{Error, Result};
pub use io::job::Job;
