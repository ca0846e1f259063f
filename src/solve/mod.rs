// SPDX-License-Identifier: MIT OR Apache-2.0
//! Sparse linear algebra: CSR matrices and the preconditioned conjugate gradient (Jacobi, or a
//! smoothed-aggregation multigrid V-cycle: [`amg`]), as a plain f64 CPU twin ([`sparse`], [`cg`]) and as
//! batched GPU kernels ([`gpu`]: SpMV, dot products, CG; [`gpu_wide`]: one large system over many
//! workgroups).
pub mod amg;
pub mod cg;
pub mod gpu;
mod gpu_amg;
pub mod gpu_wide;
pub mod sparse;
