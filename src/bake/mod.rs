// SPDX-License-Identifier: MIT OR Apache-2.0
//! The bake.
pub mod blend;
pub mod cpu;
mod engine;
pub mod params;
pub mod report;
pub mod select;

pub use engine::*;
