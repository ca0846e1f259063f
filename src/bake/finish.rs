// SPDX-License-Identifier: MIT OR Apache-2.0
//! Stages 6 and 7, padding and encoding, in one pass (`wgsl/bake/encode.wgsl`): background texels
//! within `padding` of an island (or all, for `"full"`) take the colour of their nearest island texel
//! (from the islands' distance transform), then every texel is encoded to sRGB 8 or 16 bits into a
//! packed buffer with 256-byte rows, ready for one read-back or a copy into a host texture. Or,
//! for an 8-bit texture baked whole where the islands are on the CPU and `StagePaths::padding`
//! says so (a CPU adapter), the same on the CPU: the canvas read back band by band, each texel
//! quantised, then the background padded from the quantised texels. Both quantise 8-bit values
//! by one table of exact thresholds ([`Quantiser`]), so both give the same bytes.

use super::canvas::Canvas;
use super::engine::TiledIslands;
use super::params::{params_buffer, pbind, Params, FLAG_16BIT, FLAG_LINEAR, FLAG_NO_PAD};
use super::stage::{Cx, Log};
use crate::error::Result;
use crate::io::job::Padding;
use rayon::prelude::*;

/// A padded, encoded texture: the kernel's packed words on the GPU, or texels on the CPU (4
/// values a texel, row by row, as [`super::Baked::texels`] holds them).
pub enum Finished {
    /// On the GPU.
    Gpu(Encoded),
    /// On the CPU.
    Host(Vec<u16>),
}

/// Pads and encodes the canvas on the CPU where [`host_path`] says, on the GPU otherwise; the
/// report's `paths.padding` says which.
pub(crate) fn finish(
    cx: Cx<'_>,
    canvas: &Canvas,
    (pad, linear): (bool, bool),
    log: &mut Log,
) -> Result<Finished> {
    match host_path(cx, canvas, pad) {
        Some(isl) => {
            log.paths.padding = "cpu";
            let radius = padding_radius(cx.job.padding);
            pad_and_encode_host(cx, canvas, (isl, radius), linear).map(Finished::Host)
        }
        None => pad_and_encode(cx, canvas, (pad, linear), log).map(Finished::Gpu),
    }
}

/// The islands the CPU path pads from, where it runs: an 8-bit texture baked whole (not a tile,
/// whose padding is the tiles' business) whose islands the twin computed, and
/// `StagePaths::padding` on the CPU.
fn host_path<'a>(cx: Cx<'_>, canvas: &'a Canvas, pad: bool) -> Option<&'a TiledIslands> {
    let Cx { engine, job, .. } = cx;
    let whole = canvas.global.window() == [0, 0, job.width, job.height];
    (pad && whole && engine.stage_paths.pads_on_cpu(engine, job.bit_depth))
        .then_some(canvas.islands.host.as_ref())
        .flatten()
}

/// Canvas bytes read back at a time by the CPU path (both planes together).
const BAND_BYTES: u64 = 8 << 20;

/// The CPU path: the two planes read back in bands of rows, each texel quantised as the kernel
/// does ([`Quantiser`]), then every background texel within `radius` of an island takes its
/// nearest island texel's bytes ([`pad`]: the kernel's rule, on every core). Padding after
/// quantising gives the kernel's bytes, which quantises the nearest island texel's value.
fn pad_and_encode_host(
    cx: Cx<'_>,
    canvas: &Canvas,
    (isl, radius): (&TiledIslands, u32),
    linear: bool,
) -> Result<Vec<u16>> {
    let ctx = &cx.engine.ctx;
    let [_, _, w, h] = canvas.global.window();
    let row = w as u64 * 8;
    // At least four bands: the copy of one and the quantising of another could overlap, and
    // every bake reads more than one.
    let rows = (BAND_BYTES / 2 / row).min((h as u64).div_ceil(4)).max(1);
    let staging = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("bake.padding.readback"),
        size: 2 * rows * row,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let q = Quantiser::get();
    let mut texels = vec![0u16; w as usize * h as usize * 4];
    for (band, out) in texels
        .chunks_mut((rows * w as u64 * 4) as usize)
        .enumerate()
    {
        let n = out.len() as u64 / (w as u64 * 4) * row;
        let at = band as u64 * rows * row;
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        enc.copy_buffer_to_buffer(&canvas.acc_rg, at, &staging, 0, n);
        enc.copy_buffer_to_buffer(&canvas.acc_ba, at, &staging, rows * row, n);
        ctx.queue.submit([enc.finish()]);
        ctx.map_with(&staging, "padding read-back", |bytes| {
            let (rg, ba) = bytes.split_at((rows * row) as usize);
            out.par_chunks_mut(w as usize * 4)
                .zip(rg.par_chunks(row as usize))
                .zip(ba.par_chunks(row as usize))
                .for_each(|((out, rg), ba)| q.encode_row(out, (rg, ba), linear));
        })?;
    }
    pad(isl, w, radius, &mut texels, 4);
    Ok(texels)
}

/// Pads `values` (`n` per texel) in place: each background texel whose nearest island texel lies
/// within `radius` (`u32::MAX`: any distance) takes that texel's values, as `encode.wgsl` does (a CPU-padded bake, and a tiled one over its assembled
/// texture: `bake/tiles.rs`, `bake/bands.rs`).
/// Rows are split between the cores (an 8192² texture has 64M texels).
pub(crate) fn pad<T: Copy + Send + Sync>(
    isl: &TiledIslands,
    w: u32,
    radius: u32,
    values: &mut [T],
    n: usize,
) {
    let r2 = radius as u64 * radius as u64;
    // |src − i| = |dy·w + dx| with |dx| < w: beyond (radius + 1)·w − 1, |dy| > radius.
    let far = (radius as u64 + 1)
        .saturating_mul(w as u64)
        .saturating_sub(1);
    let texels = isl.mask.len();
    let threads = std::thread::available_parallelism().map_or(1, |t| t.get());
    let band = texels.div_ceil(threads).max(1);
    let base = Shared(values.as_mut_ptr());
    std::thread::scope(|s| {
        for start in (0..texels).step_by(band) {
            let base = &base;
            s.spawn(move || {
                for i in start..(start + band).min(texels) {
                    let src = isl.nearest[i];
                    if isl.mask[i] || src == u32::MAX {
                        continue;
                    }
                    // Indices further apart than `far` are more than `radius` rows apart: no
                    // division needed to reject them (most background texels, for small radii).
                    if (src as i64 - i as i64).unsigned_abs() > far {
                        continue;
                    }
                    let (sy, y) = (src / w, i as u32 / w);
                    let (dx, dy) = (
                        (src - sy * w) as i64 - (i as u32 - y * w) as i64,
                        sy as i64 - y as i64,
                    );
                    if radius == u32::MAX || (dx * dx + dy * dy) as u64 <= r2 {
                        // SAFETY: `src` is an island texel (the distance transform points only at
                        // those) and `i` a background texel: no thread writes an island texel,
                        // each background texel is written by the one thread whose band holds
                        // it, and both lie inside `values` (texels × n).
                        unsafe {
                            std::ptr::copy_nonoverlapping(
                                base.0.add(src as usize * n),
                                base.0.add(i * n),
                                n,
                            )
                        };
                    }
                }
            });
        }
    });
}

/// A pointer the padding threads share (see the safety note in [`pad`]).
struct Shared<T>(*mut T);
// SAFETY: the threads read and write disjoint texels (see `pad`).
unsafe impl<T: Send> Sync for Shared<T> {}

/// The 8-bit quantisation both padding paths share: a value's byte is the number of thresholds
/// at or below it, each threshold the least f32 whose value times 255 rounds half up to that
/// byte (sRGB-encoded in f64; linear in f32 arithmetic, as `pack4x8unorm` is defined). Found in two loads: the byte at the start of
/// its 1/4096 cell, then one threshold's test (no two thresholds lie within a cell: the steepest
/// curve, sRGB's linear foot, moves 3,295 bytes a unit). The GPU reads the same words
/// (`encode.wgsl`'s `quantise`), so the bytes do not depend on a `pow` or a rounding mode.
pub struct Quantiser {
    /// Per curve (sRGB, then linear): byte 0's threshold (0), bytes 1 to 255's, and +∞.
    thresholds: [[f32; THRESHOLDS as usize]; 2],
    /// Per curve: the byte at the start of each cell, and at 1 (about 10 KB with the
    /// thresholds, within a core's first cache).
    cells: [[u8; CELLS as usize + 1]; 2],
}

/// Cells over [0, 1] of the quantiser's first load.
pub const CELLS: u32 = 4096;
/// Thresholds per curve: byte 0's (0.0), bytes 1 to 255's, and +∞ after.
pub const THRESHOLDS: u32 = 257;

impl Quantiser {
    /// The table, made once.
    pub fn get() -> &'static Quantiser {
        static Q: std::sync::OnceLock<Quantiser> = std::sync::OnceLock::new();
        Q.get_or_init(Quantiser::new)
    }

    fn new() -> Self {
        // sRGB in f64; linear as `pack4x8unorm` states it, in f32 (so 0.9 gives 230, the byte
        // of 0.9 × 255 = 229.5 rounded half up, though the f32 nearest 0.9 lies just below it).
        let reaches = |curve: usize, x: f32, k: usize| match curve {
            0 => srgb_f64(x as f64) * 255.0 + 0.5 >= k as f64,
            _ => (x * 255.0 + 0.5).floor() >= k as f32,
        };
        let thresholds: [[f32; THRESHOLDS as usize]; 2] = std::array::from_fn(|curve| {
            std::array::from_fn(|k| match k {
                0 => 0.0,
                256 => f32::INFINITY,
                k => least_reaching(|x| reaches(curve, x, k)),
            })
        });
        let cells: [[u8; CELLS as usize + 1]; 2] = std::array::from_fn(|curve| {
            std::array::from_fn(|c| {
                let x = c as f32 / CELLS as f32;
                thresholds[curve][1..256]
                    .iter()
                    .filter(|&&t| t <= x)
                    .count() as u8
            })
        });
        Self { thresholds, cells }
    }

    /// The table as `encode.wgsl` binds it: [`THRESHOLDS`] words per curve of f32 bits, then
    /// [`CELLS`] + 1 bytes per curve, a word each.
    pub fn words(&self) -> Vec<u32> {
        let thresholds = self.thresholds.iter().flatten().map(|t| t.to_bits());
        let cells = self.cells.iter().flatten().map(|&b| b as u32);
        thresholds.chain(cells).collect()
    }

    /// `x`'s byte: sRGB-encoded unless `linear`, clamped to [0, 1].
    #[inline]
    pub fn quantise(&self, x: f32, linear: bool) -> u8 {
        let v = x.clamp(0.0, 1.0);
        let curve = usize::from(linear);
        // NaN: cell 0, no threshold reached: byte 0. Byte 255's next threshold is +∞.
        let k = self.cells[curve][((v * CELLS as f32) as usize).min(CELLS as usize)];
        k + u8::from(v >= self.thresholds[curve][k as usize + 1])
    }

    /// One row of texels from the canvas planes' bytes (RG and BA, f32 pairs): colour sRGB unless
    /// `linear`, alpha linear.
    fn encode_row(&self, out: &mut [u16], (rg, ba): (&[u8], &[u8]), linear: bool) {
        let f = |b: &[u8]| f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
        for ((o, rg), ba) in out
            .chunks_exact_mut(4)
            .zip(rg.chunks_exact(8))
            .zip(ba.chunks_exact(8))
        {
            o[0] = self.quantise(f(&rg[..4]), linear) as u16;
            o[1] = self.quantise(f(&rg[4..]), linear) as u16;
            o[2] = self.quantise(f(&ba[..4]), linear) as u16;
            o[3] = self.quantise(f(&ba[4..]), true) as u16;
        }
    }
}

/// The sRGB curve in f64: what the quantiser's sRGB thresholds are exact to.
fn srgb_f64(x: f64) -> f64 {
    match x <= 0.003_130_8 {
        true => x * 12.92,
        false => 1.055 * x.powf(1.0 / 2.4) - 0.055,
    }
}

/// The least f32 in [0, 1] where `reaches` holds (it holds at 1 and, once it holds, for every
/// larger value): a bisection over the bit patterns, which order non-negative floats.
fn least_reaching(reaches: impl Fn(f32) -> bool) -> f32 {
    let (mut lo, mut hi) = (0u32, 1f32.to_bits());
    if reaches(0.0) {
        return 0.0;
    }
    // reaches(lo) is false, reaches(hi) true.
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        match reaches(f32::from_bits(mid)) {
            true => hi = mid,
            false => lo = mid,
        }
    }
    f32::from_bits(hi)
}

/// The encoded texture on the GPU.
pub struct Encoded {
    /// Packed texels: RGBA8 in one word, or RGBA16 in two, rows `stride` words apart.
    pub packed: wgpu::Buffer,
    /// Bytes of `packed`.
    pub packed_size: u64,
    /// Words per row.
    pub stride: u32,
}

/// Pads and encodes the canvas.
/// `pad`: pad here (false for a tile of a tiled bake, which is padded on the CPU); the encoded
/// texels are the canvas window's. `linear`: write the values as stored (a data or normal
/// channel), not sRGB-encoded.
pub(crate) fn pad_and_encode(
    cx: Cx<'_>,
    canvas: &Canvas,
    (pad, linear): (bool, bool),
    log: &mut Log,
) -> Result<Encoded> {
    let Cx { engine, job, .. } = cx;
    let [_, _, w, h] = canvas.global.window();
    let stride = if job.bit_depth == 16 {
        (2 * w).next_multiple_of(64)
    } else {
        w.next_multiple_of(64)
    };
    let packed_size = stride as u64 * h as u64 * 4;
    // Every word a reader reads (w texels a row, never the row padding) is written below, so a
    // buffer from the pool serves as well as a new one.
    let usage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC;
    let (packed, _) = engine.pooled_buffer("bake.packed", packed_size, usage);
    let encoded = Encoded {
        packed,
        packed_size,
        stride,
    };
    encode_regions(cx, canvas, (pad, linear), (&encoded, &[]), log)?;
    Ok(encoded)
}

/// Pads and encodes `regions` (x, y, w, h texel rectangles of the canvas window; none: the whole
/// window) into `encoded`, whose other texels keep their bytes: a live bake's edit
/// ([`crate::bake::LiveBake`]) encodes only its cells and the padding they reach.
pub(crate) fn encode_regions(
    cx: Cx<'_>,
    canvas: &Canvas,
    (pad, linear): (bool, bool),
    (encoded, regions): (&Encoded, &[[u32; 4]]),
    log: &mut Log,
) -> Result<()> {
    let Cx { engine, job, .. } = cx;
    let (dev, pipes) = (&engine.ctx.device, &engine.pipes);
    let [_, _, w, h] = canvas.global.window();
    let whole = [[0, 0, w, h]];
    let fin = Params {
        rect_size: [encoded.stride, 0],
        flags: if job.bit_depth == 16 { FLAG_16BIT } else { 0 }
            | if pad { 0 } else { FLAG_NO_PAD }
            | if linear { FLAG_LINEAR } else { 0 },
        aux: padding_radius(job.padding),
        ..canvas.global
    };
    let entries: Vec<Params> = match regions {
        [] => vec![fin],
        r => r
            .iter()
            .map(|r| Params {
                rect_origin: [r[0] as i32, r[1] as i32],
                atlas_origin: [r[2], r[3]],
                ..fin
            })
            .collect(),
    };
    let sizes = if regions.is_empty() {
        &whole[..]
    } else {
        regions
    };
    let fin_params = params_buffer(dev, "bake.final_params", &entries);
    let table = engine.quantiser.get_or_init(|| {
        let words = Quantiser::get().words();
        let none = wgpu::BufferUsages::empty();
        engine
            .ctx
            .storage_init("bake.quantiser", bytemuck::cast_slice(&words), none)
    });
    let encode = pipes.encode_for(linear, job.bit_depth == 16);
    let islands = canvas.islands.gpu(&engine.ctx);
    engine.ctx.scoped("padding and encode", || {
        let mut enc = dev.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("bake.finish"),
        });
        let bg_enc = encode.bind(
            dev,
            "bake.encode",
            &[
                (0, pbind(&fin_params)),
                (1, encoded.packed.as_entire_binding()),
                (2, islands[0].as_entire_binding()),
                (3, islands[1].as_entire_binding()),
                (4, table.as_entire_binding()),
                (10, canvas.acc_rg.as_entire_binding()),
                (11, canvas.acc_ba.as_entire_binding()),
            ],
        );
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("bake.finish"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&encode.pipeline);
            for (k, r) in sizes.iter().enumerate() {
                let offset = (k as u64 * super::params::PARAMS_STRIDE) as u32;
                pass.set_bind_group(0, &bg_enc, &[offset]);
                pass.dispatch_workgroups(r[2].div_ceil(8), r[3].div_ceil(8), 1);
                log.commands += 1;
            }
        }
        engine.ctx.queue.submit([enc.finish()]);
    })?;
    engine.ctx.wait("padding")
}

/// The encode kernel's padding radius in texels (`u32::MAX` = the whole background).
pub fn padding_radius(p: Padding) -> u32 {
    match p {
        Padding::Texels(n) => n,
        Padding::Full => u32::MAX,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The byte each value's curve rounds to (sRGB in f64, linear in f32): what the table must
    /// answer.
    fn exact(x: f32, linear: bool) -> u8 {
        let x = x.clamp(0.0, 1.0);
        if linear {
            return (x * 255.0 + 0.5).floor() as u8;
        }
        (srgb_f64(x as f64) * 255.0 + 0.5).floor() as u8
    }

    /// Every threshold, its neighbours a bit either side, cell edges and a sweep of values get
    /// the exact curve's byte (fails with the threshold's test left out, or with one cell's
    /// byte off).
    #[test]
    fn the_quantiser_gives_the_exact_curves_bytes() {
        let q = Quantiser::get();
        let mut values: Vec<f32> = vec![-1.0, 0.0, 1.0, 2.0, f32::MIN_POSITIVE, 0.5];
        for curve in 0..2 {
            for k in 1..256 {
                let t = q.thresholds[curve][k];
                values.extend([
                    t,
                    f32::from_bits(t.to_bits() - 1),
                    f32::from_bits(t.to_bits() + 1),
                ]);
            }
        }
        values.extend((0..=CELLS).map(|c| c as f32 / CELLS as f32));
        values.extend((0..200_000).map(|i| i as f32 / 200_000.0));
        for x in values {
            for linear in [false, true] {
                assert_eq!(
                    q.quantise(x, linear),
                    exact(x, linear),
                    "{x} linear {linear}"
                );
            }
        }
        assert_eq!(q.quantise(f32::NAN, false), 0);
        assert_eq!(q.quantise(0.9, true), 230, "0.9 × 255 = 229.5 in f32");
    }
}
