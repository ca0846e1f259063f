// SPDX-License-Identifier: MIT OR Apache-2.0
//! Textures beyond one storage binding, baked by tiles. The canvas of a W × H texture is 8 bytes a
//! texel per plane, so lavapipe's 128 MiB storage binding holds at most 4096²; an 8192² or 16384²
//! bake (up to the adapter's 2D texture limit) runs stages 2 to 7 once per tile window (`run_in`:
//! the canvas holds the window's texels, every kernel indexes it through `wgsl/shared/window.wgsl`,
//! raster rectangles are clipped to the window, which is cell-aligned), reads each tile back
//! unpadded, and pads on the CPU: band by band (`bands.rs`) for a finite padding, the assembled
//! texture for `"padding": "full"` ([`bake_whole`]).
//!
//! Why the result is the untiled bake's, byte for byte: every stage is per texel (a texel's colour
//! depends on the layers drawn over it, not on its neighbours), except two:
//! - **padding** copies each background texel's nearest island texel, which may lie in another
//!   tile. The islands are rasterized per window on the GPU (the same kernels), and their exact
//!   distance transform computed by the CPU twin ([`crate::bake::cpu::nearest_island_map`], the
//!   same algorithm and tie order as the GPU's) over a band and the rows its padding reaches
//!   (`bands.rs` says why that is exact), or over the whole texture for a full padding (cached on
//!   the mesh per set, size and sampling); padding is a copy of an encoded texel, and encoding is
//!   per texel, so padding after encoding gives the bytes the GPU's pad-then-encode does.
//! - **blur, smear and clone stamps** read the canvas around them: a stamp that crosses a tile
//!   border is refused with a message (`tools::check_window`) rather than read across the border.
//!
//! A float (EXR) output takes the same path with one tile when the texture fits, so that its
//! linear canvas is padded by the same map. `tests/tiles.rs` compares tiled with untiled bakes.

use super::engine::{unpack_rows, Engine, IslandKey, LoadedMesh, TiledIslands};
use super::report::Report;
use crate::error::Result;
use crate::io::job::Job;
use std::sync::Arc;
use std::time::Instant;

/// The tile (width, height) a bake of `job` uses, if it is tiled: `texture.tile` squares; else,
/// for a texture whose canvas plane does not fit one storage buffer, bands the texture's width
/// across and as many rows (a multiple of 64) as fit one buffer, or where not even 64 rows fit,
/// the largest power-of-two square that does; else (a float output) the whole texture as one
/// tile; else `None` (the GPU pads, one pass). Bands keep what a streamed bake holds on the host
/// small (a few bands of rows, `bands.rs`) for as many tile runs as squares would take.
pub(crate) fn tile_shape(engine: &Engine, job: &Job) -> Option<[u32; 2]> {
    if let Some(t) = job.tile {
        return Some([t, t]);
    }
    let (limit, _) = engine.ctx.storage_limit();
    let (w, h) = (job.width as u64, job.height as u64);
    if w.saturating_mul(h).saturating_mul(8) > limit {
        let texels = (limit / 8).max(64 * 64);
        let rows = (texels / w) / 64 * 64;
        if rows >= 64 {
            return Some([job.width, rows.min(h) as u32]);
        }
        let side = 1 << (texels.ilog2() / 2);
        return Some([side, side]);
    }
    job.exr().then(|| {
        let side = job.width.max(job.height).next_multiple_of(64);
        [side, side]
    })
}

/// The tile windows (x, y, w, h) of a `w` × `h` texture in tiles of `shape`, row by row.
pub fn windows(w: u32, h: u32, shape: [u32; 2]) -> Vec<[u32; 4]> {
    let mut out = Vec::new();
    for y in (0..h).step_by(shape[1] as usize) {
        for x in (0..w).step_by(shape[0] as usize) {
            out.push([x, y, shape[0].min(w - x), shape[1].min(h - y)]);
        }
    }
    out
}

/// Where a tile's texels go: the colour's rows, each PBR channel's (in pass order,
/// `channels::passes`), and for a float output the linear colour and channels; all rows of the
/// texture's width, starting at one texture row.
pub(crate) struct Dest<'a> {
    pub texels: &'a mut [u16],
    pub channels: Vec<&'a mut [u16]>,
    pub linear: Option<&'a mut Vec<f32>>,
    /// Each channel's linear values for a float output (empty otherwise).
    pub channel_linear: Vec<&'a mut [f32]>,
}

impl Dest<'_> {
    /// The same rows, borrowed again.
    fn again(&mut self) -> Dest<'_> {
        Dest {
            texels: &mut *self.texels,
            channels: self.channels.iter_mut().map(|c| &mut **c).collect(),
            linear: self.linear.as_deref_mut(),
            channel_linear: self.channel_linear.iter_mut().map(|c| &mut **c).collect(),
        }
    }
}

/// Bakes tile `k` of `n`, window `win`, into `dest`'s rows of the texture's width starting at
/// texture row `y0` (the colour, each PBR channel, and the linear colour for a float output),
/// unpadded; returns the tile's report.
pub(crate) fn bake_window(
    cx: (&Engine, &LoadedMesh, &Job),
    (win, k, n): ([u32; 4], usize, usize),
    on_stage: &dyn Fn(&str),
    y0: u32,
    dest: Dest<'_>,
) -> Result<Report> {
    let (engine, mesh, job) = cx;
    let w = job.width;
    let stage = |s: &str| on_stage(&format!("tile {}/{n}: {s}", k + 1));
    let run = super::run_in(engine, mesh, job, Some(win), &stage)?;
    let t = Instant::now();
    let local = [win[0], win[1] - y0, win[2], win[3]];
    let encoded = std::iter::once(&run.encoded).chain(run.channels.iter().map(|(_, e)| e));
    let texels = std::iter::once(dest.texels).chain(dest.channels);
    for (e, texels) in encoded.zip(texels) {
        let e = match e {
            super::Finished::Gpu(e) => e,
            // Not taken today: a tile is never padded where it is baked (`finish::finish`).
            super::Finished::Host(tile) => {
                copy_rows(texels, w, local, tile, 4);
                continue;
            }
        };
        engine
            .ctx
            .read_buffer_with(&e.packed, e.packed_size, "encode read-back", |bytes| {
                let words = bytemuck::cast_slice(bytes);
                unpack_rows(texels, w, local, words, e.stride, job.bit_depth)
            })?;
        engine.return_buffers([e.packed.clone()]);
    }
    let linear = dest.linear.map(|l| &mut l[..]).into_iter();
    let linear = linear.chain(dest.channel_linear);
    let tiles = run.linear.iter().chain(&run.channel_linear);
    for (all, tile) in linear.zip(tiles) {
        copy_rows(all, w, local, tile, 4);
    }
    let mut r = run.report;
    r.timings.encode_ms += t.elapsed().as_secs_f64() * 1000.0;
    Ok(r)
}

/// Copies a window's rows (`n` values a texel, `tile`) into the texture's (`all`, `w` texels a
/// row) at `win` (x, y, w, h).
fn copy_rows<T: Copy>(all: &mut [T], w: u32, win: [u32; 4], tile: &[T], n: usize) {
    let row = win[2] as usize * n;
    for (r, src) in tile.chunks_exact(row).take(win[3] as usize).enumerate() {
        let at = ((win[1] as usize + r) * w as usize + win[0] as usize) * n;
        all[at..at + row].copy_from_slice(src);
    }
}

/// Every tile, then the padding over the whole texture (`"padding": "full"`: a background texel
/// may take an island texel anywhere).
pub(crate) fn bake_whole(
    engine: &Engine,
    mesh: &LoadedMesh,
    job: &Job,
    shape: [u32; 2],
    on_stage: &dyn Fn(&str),
    mut all: Dest<'_>,
) -> Result<Report> {
    let w = job.width;
    let wins = windows(w, job.height, shape);
    let islands = islands(engine, mesh, job, &wins)?;
    let mut report: Option<Report> = None;
    for (k, &win) in wins.iter().enumerate() {
        let cx = (engine, mesh, job);
        let dest = all.again();
        let r = bake_window(cx, (win, k, wins.len()), on_stage, 0, dest)?;
        report = Some(merge(report, r));
    }
    on_stage("padding");
    let radius = super::finish::padding_radius(job.padding);
    let t = Instant::now();
    super::finish::pad(&islands, w, radius, all.texels, 4);
    for c in all.channels {
        super::finish::pad(&islands, w, radius, c, 4);
    }
    for c in all.channel_linear {
        super::finish::pad(&islands, w, radius, c, 4);
    }
    if let Some(l) = all.linear {
        super::finish::pad(&islands, w, radius, l, 4);
    }
    let mut report = report.expect("a texture has at least one tile");
    report.timings.padding_ms += t.elapsed().as_secs_f64() * 1000.0;
    report.island_texels = islands.count;
    report.padding = Some(radius).filter(|&p| p != u32::MAX);
    report.tiles = Some([shape[0], wins.len() as u32]);
    report.tile_size = Some(shape);
    Ok(report)
}

/// Two tiles' reports as one: the first's (`b` alone when there is none yet), with the texels each
/// layer covered added up (the rest, placement, maps and triangles, is the same in every tile) and
/// the stage times summed.
pub(crate) fn merge(a: Option<Report>, b: Report) -> Report {
    let Some(mut a) = a else {
        return b;
    };
    for (la, lb) in a.layers.iter_mut().zip(&b.layers) {
        la.texels_covered += lb.texels_covered;
    }
    let (ta, tb) = (&mut a.timings, &b.timings);
    ta.images_ms += tb.images_ms;
    ta.vector_maps_ms += tb.vector_maps_ms;
    ta.placement_ms += tb.placement_ms;
    ta.compose_ms += tb.compose_ms;
    ta.padding_ms += tb.padding_ms;
    ta.encode_ms += tb.encode_ms;
    a.gpu_commands += b.gpu_commands;
    a
}

/// The texture's islands, assembled from every window's mask (cached on the mesh).
fn islands(
    engine: &Engine,
    mesh: &LoadedMesh,
    job: &Job,
    wins: &[[u32; 4]],
) -> Result<Arc<TiledIslands>> {
    let (w, h) = (job.width, job.height);
    let msaa = engine.adaptive_sampling(job);
    let key: IslandKey = (job.uv_set, w, h, job.ss, msaa);
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
            (job.uv_set, job.ss, msaa),
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
