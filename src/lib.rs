// SPDX-License-Identifier: MIT OR Apache-2.0
//! decalbake: bakes decals onto 3D meshes, straight into the mesh's texture, on the GPU.
pub mod error;
pub mod gpu;
pub mod image_io;
pub mod mesh;
pub mod shaders;

pub use error::{Error, Result};
