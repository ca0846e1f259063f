// SPDX-License-Identifier: MIT OR Apache-2.0
//! A layer's local coordinates: for each welded vertex, `(x, y)` in model units in the layer's
//! [`Frame`] plus a validity flag.
pub mod chart;
pub mod distortion;
pub mod expmap;
mod frame;
pub mod planar;

pub use frame::Frame;
