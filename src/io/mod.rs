// SPDX-License-Identifier: MIT OR Apache-2.0
//! Inputs: the job file ([`job`], whose types are the schema the rest of the engine reads), the
//! batch manifest ([`manifest`]) and image decoding and encoding ([`image`], also the atomic file
//! writer every output goes through).
pub mod at;
pub mod channels;
pub mod image;
pub mod job;
pub mod manifest;
pub mod ribbon;
pub mod stroke;
pub mod warp;
