// SPDX-License-Identifier: MIT OR Apache-2.0
//! decalbake: bakes decals onto 3D meshes, straight into the mesh's texture, on the GPU.
pub mod error;
pub mod gpu;
pub mod image_io;
pub mod mesh;
pub mod shaders;

pub use error::{Error, Result};
pub mod bake;
pub mod blend;
pub mod gpu_mesh;
pub mod job;
pub mod layer;
pub mod pipelines;
pub mod place;
pub mod report;

pub use bake::{Baked, Engine, LoadedMesh};
pub use job::Job;
pub mod bench;
pub mod bench_linalg;
pub mod chart;
pub mod compose_cpu;
pub mod demo;
pub mod geodesic;
pub mod geodesic_gpu;
pub mod glb;
pub mod linalg_gpu;
pub mod lscm;
pub mod output;
pub mod preview;
pub mod shapes;
pub mod sparse;
