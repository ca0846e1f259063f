// SPDX-License-Identifier: MIT OR Apache-2.0
//! `decalbake bench`: the bake ([`bake`]), exponential maps ([`geodesic`]) and the linear algebra
//! ([`linalg`]), each printing JSON lines; [`common`] holds the workloads they share.
pub mod bake;
pub mod batch;
pub mod channels;
pub mod common;
pub mod corpus;
pub mod device;
pub mod edit;
pub mod geodesic;
pub mod linalg;
pub mod ribbons;
pub mod scale;
pub mod soak;
pub mod strokes;
pub mod tiles;
pub mod unwrap;
pub mod vector;
