// SPDX-License-Identifier: MIT OR Apache-2.0
//! Limits before work: a bake's peak memory, estimated from its sizes before anything is
//! allocated, against the job's limit (`"max_memory"`, `--max-memory`) or the memory this machine
//! has available (`MemAvailable` in `/proc/meminfo`). A bake that would not fit is refused with
//! the estimate, the limit and what to change (exit 2), instead of dying in an allocation.
//!
//! The estimate is a model of the engine's own buffers, fitted to peak resident sizes measured on
//! lavapipe (2026-11-27, this 2-core machine: `decalbake bake` of one decal on Spot, 1024² to
//! 16384², 8 and 16 bits, PNG and EXR, whole and by tiles; 16384² by tiles peaked at 4.56 GiB
//! against an estimate of 4.75), where device memory is host memory; it errs on the large side,
//! by up to about a fifth (one-pass 2048², 2 % under):
//! - a fixed [`FIXED`] for the process, the driver and the compiled pipelines, plus the mesh;
//! - a one-pass bake: [`DEVICE_PER_TEXEL`] on the device (canvas planes, islands, distance
//!   transform, encoded texture, read-back) and [`HOST_PER_TEXEL`] on the host (texels, PNG),
//!   once for the colour and once per PBR channel group;
//! - a bake by tiles: [`TILE_DEVICE_PER_TEXEL`] for a tile on the device, [`TILED_HOST_PER_TEXEL`]
//!   for the whole texture on the host (the assembled texels, the islands and the nearest-island
//!   map for the padding, the PNG), and for each PBR channel group the tile's share again on the
//!   device, one attachment and [`HOST_PER_TEXEL`] a texel on the host;
//! - a bake by tiles streamed to its file (`output/stream.rs`, band by band, `bands.rs`): the
//!   tile on the device, and on the host [`BAND_HOST_PER_TEXEL`] for each texel of a band and its
//!   padding's halo (three bands queued, the halo's copy, its islands and distance transform),
//!   [`FLOAT_BAND_PER_TEXEL`] more for an EXR, plus [`STREAM_HOST`] for the preview's reduced
//!   copy and the encoder; each PBR channel group adds its tile's share on the device and
//!   [`BAND_CHANNEL_PER_TEXEL`] a band texel (and the EXR's floats) and [`STREAM_HOST`] on the host;
//! - 16-bit outputs add [`WIDE_PER_TEXEL`], float (EXR) outputs [`FLOAT_PER_TEXEL`] (the linear
//!   canvas and its encoding);
//! - the layers' bitmap images, read from their files' headers ([`image_pixels`]):
//!   [`IMAGE_HOST_PER_PIXEL`] on the host while decoded, [`IMAGE_DEVICE_PER_PIXEL`] on the device
//!   (not the vector images, whose sizes are decided after placement, within a budget).
//!
//! On a CPU adapter the device's memory is the host's, so the two add up against the limit; on a
//! GPU the host part is compared with the limit and the device part with the adapter's buffer
//! limits (`check.rs`; wgpu does not say how much memory a GPU has).

use super::engine::{Engine, LoadedMesh};
use crate::error::{bytes_text, Error, Result};
use crate::io::job::Job;

/// Process, driver and pipelines.
pub const FIXED: u64 = 256 << 20;
/// Device bytes a texel of a one-pass bake.
pub const DEVICE_PER_TEXEL: u64 = 24;
/// Host bytes a texel of a one-pass bake.
pub const HOST_PER_TEXEL: u64 = 8;
/// Device bytes a texel of one tile.
pub const TILE_DEVICE_PER_TEXEL: u64 = 16;
/// Host bytes a texel of a texture baked by tiles.
pub const TILED_HOST_PER_TEXEL: u64 = 17;
/// Host bytes a texel of a band (and its halo) of a streamed bake by tiles.
pub const BAND_HOST_PER_TEXEL: u64 = 48;
/// Host bytes a texel of a band more for a float (EXR) output: the linear rows of the three
/// queued bands and of the halo's copy.
pub const FLOAT_BAND_PER_TEXEL: u64 = 64;
/// Host bytes a texel of a band (and its halo) of a streamed bake by tiles for each PBR channel
/// group: its rows in the queued bands and in its writer's queue (measured 2026-11-29 on
/// lavapipe: the knight's badge at 8192², colour + ORM + normal, by bands of 2,048 rows, peaked
/// at 2.06 GiB against 1.01 GiB for the colour alone; estimates 2.7 and 1.4 GiB).
pub const BAND_CHANNEL_PER_TEXEL: u64 = 16;
/// Host bytes of a streamed bake besides its bands: the preview's reduced copy, the encoder.
pub const STREAM_HOST: u64 = 96 << 20;
/// Host bytes a texel more for a 16-bit output.
pub const WIDE_PER_TEXEL: u64 = 6;
/// Host bytes a texel more for a float (EXR) output.
pub const FLOAT_PER_TEXEL: u64 = 32;

/// Device bytes of a PBR channel group's attachment in the fused raster (`bake/compose.rs`): at
/// most a 2048² atlas target of f32 RGBA.
pub const CHANNEL_TARGET: u64 = 64 << 20;

/// Device bytes a pixel of a layer's bitmap image: f32 RGBA and its mipmaps (a third more).
pub const IMAGE_DEVICE_PER_PIXEL: u64 = 22;
/// Host bytes a pixel of a layer's bitmap image while it is decoded: the file's pixels and the
/// f32 image made from them (the images are decoded on every core at once).
pub const IMAGE_HOST_PER_PIXEL: u64 = 24;

/// Pixels of the distinct bitmap files the job's layers read (`image`, `mask`, channel images),
/// from their headers (no pixel is decoded). Vector images and text are not counted: their sizes
/// are decided after placement, all of them within a budget of 2²⁵ pixels. A file
/// whose header does not read counts nothing here; the images stage names it.
pub fn image_pixels(job: &Job) -> u64 {
    use crate::io::vector::{dimensions, is_svg};
    let mut paths: Vec<&std::path::Path> = job
        .layers
        .iter()
        .filter(|l| l.text.is_none())
        .flat_map(|l| {
            std::iter::once(l.image.as_path())
                .chain(l.mask.as_deref())
                .chain(l.channels.image_paths())
        })
        .filter(|p| !is_svg(p))
        .collect();
    paths.sort_unstable();
    paths.dedup();
    paths
        .into_iter()
        .filter_map(|p| dimensions(p).ok())
        .map(|(w, h)| w as u64 * h as u64)
        .fold(0u64, u64::saturating_add)
}

/// A bake's estimated peak memory.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Estimate {
    /// Host bytes (the fixed part and the mesh included).
    pub host: u64,
    /// Device bytes.
    pub device: u64,
    /// The tile (width, height), for a bake by tiles.
    pub tile: Option<[u32; 2]>,
    /// Whether the bake streams its texture to the file band by band.
    pub streamed: bool,
}

/// The estimate for `job` on `mesh`, baked whole or by tiles of `tile` (width, height), the
/// texture in memory or `streamed` band by band to its file (tiled bakes only).
pub fn estimate(job: &Job, mesh_bytes: u64, tile: Option<[u32; 2]>, streamed: bool) -> Estimate {
    let texels = job.width as u64 * job.height as u64;
    let mut extra = 0;
    if job.bit_depth == 16 {
        extra += WIDE_PER_TEXEL;
    }
    if job.exr() {
        extra += FLOAT_PER_TEXEL;
    }
    let textures = 1 + super::channels::passes(job).len() as u64;
    let streamed = streamed && tile.is_some();
    let band_extra = match job.exr() {
        true => FLOAT_BAND_PER_TEXEL,
        false => 0,
    };
    let (device, host) = match tile {
        Some([tw, th]) if streamed => {
            let (w, h) = (tw.min(job.width) as u64, th.min(job.height) as u64);
            let radius = super::finish::padding_radius(job.padding) as u64;
            let halo = h
                .saturating_add(radius.saturating_mul(2))
                .min(job.height as u64);
            let band = (job.width as u64).saturating_mul(halo);
            // Each PBR channel group: its tile canvas and fused attachment on the device; on the
            // host its rows in the queued bands and its writer's, and its own encoder and
            // reduced copy.
            let channels = textures - 1;
            let channel_band = BAND_CHANNEL_PER_TEXEL + band_extra;
            (
                (w * h * TILE_DEVICE_PER_TEXEL * textures)
                    .saturating_add(channels * CHANNEL_TARGET),
                band.saturating_mul(BAND_HOST_PER_TEXEL + band_extra + channels * channel_band)
                    .saturating_add(STREAM_HOST * textures),
            )
        }
        Some([tw, th]) => {
            // Each PBR channel group: its tile canvas and fused attachment on the device, its
            // whole texture (and its floats, for a float output) on the host.
            let (w, h) = (tw.min(job.width) as u64, th.min(job.height) as u64);
            let floats = if job.exr() { FLOAT_PER_TEXEL } else { 0 };
            let channel = (textures - 1) * (HOST_PER_TEXEL + floats);
            (
                (w * h * TILE_DEVICE_PER_TEXEL * textures)
                    .saturating_add((textures - 1) * CHANNEL_TARGET),
                texels.saturating_mul(TILED_HOST_PER_TEXEL + extra + channel),
            )
        }
        None => (
            texels
                .saturating_mul(DEVICE_PER_TEXEL * textures)
                .saturating_add((textures - 1) * CHANNEL_TARGET),
            texels.saturating_mul(HOST_PER_TEXEL * textures + extra),
        ),
    };
    Estimate {
        host: host.saturating_add(FIXED + mesh_bytes),
        device,
        tile,
        streamed,
    }
}

/// Bytes of a loaded mesh, host and device copies (positions, normals, UVs, topology, BVH).
pub fn mesh_bytes(mesh: &LoadedMesh) -> u64 {
    let (v, t) = (mesh.gpu.vertex_count as u64, mesh.gpu.triangle_count as u64);
    v * 160 + t * 96
}

/// The memory this machine has available now (`MemAvailable`), where the system says.
pub fn available() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// Refuses `job` before any work when its sides exceed the adapter's texture limit, or its
/// estimated memory exceeds its limit (`"max_memory"`, else the memory available).
/// `streamed`: the bake streams its texture to its file when it goes by tiles.
pub fn check(engine: &Engine, mesh: &LoadedMesh, job: &Job, streamed: bool) -> Result<()> {
    super::check::sides(engine, job)?;
    let tile = super::tiles::tile_shape(engine, job);
    let mut e = estimate(job, mesh_bytes(mesh), tile, streamed);
    let pixels = image_pixels(job);
    e.host = e
        .host
        .saturating_add(pixels.saturating_mul(IMAGE_HOST_PER_PIXEL));
    e.device = e
        .device
        .saturating_add(pixels.saturating_mul(IMAGE_DEVICE_PER_PIXEL));
    let cpu = engine.ctx.device_type == Some(wgpu::DeviceType::Cpu);
    let needed = if cpu { e.host + e.device } else { e.host };
    let (limit, source) = match (job.max_memory, available()) {
        (Some(m), _) => (m, "the job's `max_memory` (or `--max-memory`)"),
        (None, Some(a)) => (a, "the memory this machine has available"),
        (None, None) => return Ok(()),
    };
    if needed <= limit {
        return Ok(());
    }
    let how = match tile {
        Some([tw, th]) if e.streamed => format!("by tiles of {tw}x{th}, streamed to its file"),
        Some([tw, th]) => format!("by tiles of {tw}x{th}, the texture in memory"),
        None => "in one pass".to_string(),
    };
    let tiles = match job.channel_groups() {
        0 => "use smaller tiles (`texture.tile`; `decalbake bake` streams a tiled bake with a finite padding to its file band by band, the texture never whole in memory)",
        _ => "bake fewer PBR channels (each channel group adds a canvas and an attachment on the device and a texture on the host), use smaller tiles (`texture.tile`; `decalbake bake` streams a tiled bake with a finite padding to its files band by band, every channel's texture too, none whole in memory)",
    };
    Err(Error::job(
        &job.source,
        "texture",
        format!(
            "a {}x{} bake {how} needs about {} ({} on the host, {} on the device{}{}), above {source}: {}; bake a smaller texture or smaller layer images, {tiles}, or, where the machine has the room (swap, memory other processes will free), give a larger `max_memory` or `--max-memory`",
            job.width,
            job.height,
            bytes_text(needed),
            bytes_text(e.host),
            bytes_text(e.device),
            if cpu { ", which is host memory on this CPU adapter" } else { "" },
            match pixels {
                0 => String::new(),
                n => format!(
                    "; the layers' images, {n} pixels, take {} of it",
                    bytes_text(n.saturating_mul(IMAGE_HOST_PER_PIXEL + IMAGE_DEVICE_PER_PIXEL))
                ),
            },
            bytes_text(limit),
        ),
    ))
}
