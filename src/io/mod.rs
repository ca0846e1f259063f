// SPDX-License-Identifier: MIT OR Apache-2.0
//! Inputs: the job file ([`job`], whose types are the schema the rest of the engine reads), the
//! batch manifest ([`manifest`]) and image decoding and encoding ([`image`], also the atomic file
//! writer every output goes through; [`png_bands`], a PNG's image data deflated a band of rows at
//! a time on every core), and the JSON Schemas of job files and manifests ([`schema`]).
pub mod at;
pub mod channels;
pub mod image;
pub mod job;
pub mod manifest;
pub mod png_bands;
pub mod ribbon;
pub mod schema;
pub mod stroke;
pub mod text;
pub mod vector;
pub mod vector_paths;
pub mod warp;
