// SPDX-License-Identifier: MIT OR Apache-2.0
//! Sparse linear algebra: CSR matrices and the Jacobi-preconditioned conjugate gradient, as a plain
//! f64 CPU twin ([`sparse`]) and as batched GPU kernels ([`gpu`]: SpMV, dot products, CG).
pub mod gpu;
pub mod sparse;
