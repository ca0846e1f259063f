// SPDX-License-Identifier: MIT OR Apache-2.0
//! Textures beyond one storage binding, baked by tiles. The canvas of a W × H texture is 8 bytes a
//! texel per plane, so lavapipe's 128 MiB storage binding holds at most 4096²; an 8192² or 16384²
//! bake (up to the adapter's 2D texture limit) runs stages 2 to 7 once per tile window (`run_in`:
//! the canvas holds the window's texels, every kernel indexes it through `wgsl/shared/window.wgsl`,
//! raster rectangles are clipped to the window, which is cell-aligned), reads each tile back
//! unpadded, and pads the assembled texture on the CPU.
//!
//! Why the result is the untiled bake's, byte for byte: every stage is per texel (a texel's colour
//! depends on the layers drawn over it, not on its neighbours), except two:
//! - **padding** copies each background texel's nearest island texel, which may lie in another
//!   tile. The islands are rasterized per window on the GPU (the same kernels), assembled, and their
//!   exact distance transform computed over the whole texture by the CPU twin
//!   ([`crate::bake::cpu::nearest_island_map`], the same algorithm and tie order as the GPU's);
//!   padding is a copy of an encoded texel, and encoding is per texel, so padding after encoding
//!   gives the bytes the GPU's pad-then-encode does. Cached on the mesh per (set, size, sampling).
//! - **blur, smear and clone stamps** read the canvas around them: a stamp that crosses a tile
//!   border is refused with a message (`tools::check_window`) rather than read across the border.
//!
//! A float (EXR) output takes the same path with one tile when the texture fits, so that its
//! linear canvas is padded by the same map. `tests/tiles.rs` compares tiled with untiled bakes.

use super::engine::{unpack_rows, Baked, Engine, IslandKey, LoadedMesh, TiledIslands};
use super::report::Report;
use crate::error::Result;
use crate::io::job::Job;
use std::sync::Arc;
use std::time::Instant;

/// The tile side a bake of `job` uses, if it is tiled: `texture.tile`; else, for a texture whose
/// canvas plane does not fit one storage buffer, the largest power of two whose square does; else
/// (a float output) the whole texture as one tile; else `None` (the GPU pads, one pass).
pub(crate) fn tile_side(engine: &Engine, job: &Job) -> Option<u32> {
    if let Some(t) = job.tile {
        return Some(t);
    }
    let (limit, _) = engine.ctx.storage_limit();
    if job.width as u64 * job.height as u64 * 8 > limit {
        let texels = (limit / 8).max(64 * 64);
        return Some(1 << (texels.ilog2() / 2));
    }
    job.exr()
        .then(|| job.width.max(job.height).next_multiple_of(64))
}

/// The tile windows (x, y, w, h) of a `w` × `h` texture in tiles of `side`, row by row.
pub fn windows(w: u32, h: u32, side: u32) -> Vec<[u32; 4]> {
    let mut out = Vec::new();
    for y in (0..h).step_by(side as usize) {
        for x in (0..w).step_by(side as usize) {
            out.push([x, y, side.min(w - x), side.min(h - y)]);
        }
    }
    out
}

/// Bakes `job` tile by tile (see the module doc).
pub(crate) fn bake(
    engine: &Engine,
    mesh: &LoadedMesh,
    job: &Job,
    side: u32,
    on_stage: &dyn Fn(&str),
) -> Result<Baked> {
    if let Some(kind) = super::channels::passes(job).first() {
        return Err(crate::error::Error::job(
            &job.source,
            "texture",
            format!(
                "this bake goes by tiles (a texture beyond one storage buffer, `texture.tile` or an .exr output), which bake the colour only, and a layer paints the {} channel; bake PBR channels at a size that fits one pass ({side}² here) to a PNG, without `texture.tile`",
                kind.name()
            ),
        ));
    }
    let (w, h) = (job.width, job.height);
    let wins = windows(w, h, side);
    let islands = islands(engine, mesh, job, &wins)?;
    let mut texels = vec![0u16; w as usize * h as usize * 4];
    let mut linear = job.exr().then(|| vec![0f32; texels.len()]);
    let mut report: Option<Report> = None;
    for (k, &win) in wins.iter().enumerate() {
        let stage = |s: &str| on_stage(&format!("tile {}/{}: {s}", k + 1, wins.len()));
        let run = super::run_in(engine, mesh, job, Some(win), &stage)?;
        let t = Instant::now();
        let e = &run.encoded;
        engine
            .ctx
            .read_buffer_with(&e.packed, e.packed_size, "encode read-back", |bytes| {
                let words = bytemuck::cast_slice(bytes);
                unpack_rows(&mut texels, w, win, words, e.stride, job.bit_depth)
            })?;
        engine.return_buffers([run.encoded.packed.clone()]);
        if let (Some(all), Some(tile)) = (linear.as_mut(), &run.linear) {
            for row in 0..win[3] as usize {
                let src = &tile[row * win[2] as usize * 4..][..win[2] as usize * 4];
                let at = ((win[1] as usize + row) * w as usize + win[0] as usize) * 4;
                all[at..at + src.len()].copy_from_slice(src);
            }
        }
        let mut r = run.report;
        r.timings.encode_ms += t.elapsed().as_secs_f64() * 1000.0;
        report = Some(match report {
            None => r,
            Some(acc) => merge(acc, r),
        });
    }
    on_stage("padding");
    let radius = super::finish::padding_radius(job.padding);
    let t = Instant::now();
    pad(&islands, w, radius, &mut texels, 4);
    if let Some(l) = linear.as_mut() {
        pad(&islands, w, radius, l, 4);
    }
    let mut report = report.expect("a texture has at least one tile");
    report.timings.padding_ms += t.elapsed().as_secs_f64() * 1000.0;
    report.island_texels = islands.count;
    report.padding = Some(radius).filter(|&p| p != u32::MAX);
    report.tiles = Some([side, wins.len() as u32]);
    Ok(Baked {
        channels: Vec::new(),
        width: w,
        height: h,
        bit_depth: job.bit_depth,
        texels,
        linear,
        report,
    })
}

/// Two tiles' reports as one: the first's, with the texels each layer covered added up (the
/// rest, placement, maps and triangles, is the same in every tile) and the stage times summed.
fn merge(mut a: Report, b: Report) -> Report {
    for (la, lb) in a.layers.iter_mut().zip(&b.layers) {
        la.texels_covered += lb.texels_covered;
    }
    let (ta, tb) = (&mut a.timings, &b.timings);
    ta.images_ms += tb.images_ms;
    ta.placement_ms += tb.placement_ms;
    ta.compose_ms += tb.compose_ms;
    ta.padding_ms += tb.padding_ms;
    ta.encode_ms += tb.encode_ms;
    a.gpu_commands += b.gpu_commands;
    a
}

/// Pads `values` (`n` per texel) in place: each background texel whose nearest island texel lies
/// within `radius` (`u32::MAX`: any distance) takes that texel's values, as `encode.wgsl` does.
/// Rows are split between the cores (an 8192² texture has 64M texels).
fn pad<T: Copy + Send + Sync>(isl: &TiledIslands, w: u32, radius: u32, values: &mut [T], n: usize) {
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

/// The texture's islands, assembled from every window's mask (cached on the mesh).
fn islands(
    engine: &Engine,
    mesh: &LoadedMesh,
    job: &Job,
    wins: &[[u32; 4]],
) -> Result<Arc<TiledIslands>> {
    let (w, h) = (job.width, job.height);
    let key: IslandKey = (job.uv_set, w, h, job.ss);
    let cache = || mesh.tiled_islands.lock().expect("island cache poisoned");
    if let Some(c) = cache().get(&key) {
        return Ok(c.clone());
    }
    let mut mask = vec![false; w as usize * h as usize];
    let mut commands = 0;
    for &win in wins {
        let m = super::islands::window_mask(
            engine,
            mesh,
            (job.uv_set, job.ss),
            [w, h],
            win,
            &mut commands,
        )?;
        for row in 0..win[3] as usize {
            let at = (win[1] as usize + row) * w as usize + win[0] as usize;
            for (d, s) in mask[at..at + win[2] as usize]
                .iter_mut()
                .zip(&m[row * win[2] as usize..])
            {
                *d = *s != 0;
            }
        }
    }
    let nearest = super::cpu::nearest_island_map(&mask, w, h);
    let count = mask.iter().filter(|m| **m).count() as u64;
    let isl = Arc::new(TiledIslands {
        mask,
        nearest,
        count,
    });
    cache().insert(key, isl.clone());
    Ok(isl)
}
