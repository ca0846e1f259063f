// SPDX-License-Identifier: MIT OR Apache-2.0
//! A bake by tiles, one row of tiles (a band of texture rows) at a time, each band padded and
//! handed on as soon as the rows its padding can reach are baked: the texture is never whole in
//! memory, so a file writer can stream it (`output/stream.rs`) and a 16384² bake holds a few bands.
//!
//! Why a band's padding is the whole texture's, byte for byte: with a finite radius r, a
//! background texel takes its nearest island texel only when that texel lies within r, so within
//! r rows. The exact distance transform over the band and r rows each side (the halo) finds every
//! island texel at the winning distance, and only those can win: the candidates at that distance
//! are the same set as over the whole texture, and [`cpu::nearest_island_map`]'s tie order depends
//! on that set alone (the column pass prefers the upper of two equal rows, the row pass the
//! envelope's left parabola at an exact intersection). `tests/tiles.rs` compares band-padded bakes
//! with untiled ones, including a radius larger than a band.
//!
//! Padding reads island texels only, and never writes one, so a halo row may come from a band
//! already handed on (kept until no later band's halo reaches it) or from one not yet padded.
//! `"padding": "full"` reaches the whole texture: `tiles.rs` bakes that whole.

use super::cpu;
use super::engine::{Engine, LoadedMesh, TiledIslands};
use super::report::Report;
use super::tiles;
use crate::error::Result;
use crate::io::job::Job;
use std::collections::VecDeque;
use std::time::Instant;

/// A band of the texture's rows, baked and padded.
pub struct Band {
    /// The band's first row.
    pub y: u32,
    /// Rows.
    pub rows: u32,
    /// sRGB-encoded RGBA, 4 values a texel, `rows` × the texture's width (as `Baked::texels`).
    pub texels: Vec<u16>,
    /// Each PBR channel's texels (as `BakedChannel::texels`), in pass order
    /// (`channels::passes`).
    pub channels: Vec<Vec<u16>>,
    /// Linear RGBA f32 for a float output (as `Baked::linear`).
    pub linear: Option<Vec<f32>>,
    /// Each PBR channel's linear values for a float output (empty otherwise).
    pub channel_linear: Vec<Vec<f32>>,
    /// True per island texel.
    mask: Vec<bool>,
}

impl Band {
    /// The row after the band's last.
    fn end(&self) -> u64 {
        self.y as u64 + self.rows as u64
    }
}

/// Bakes `job` by tiles of `shape` (finite padding only), calling `sink` with each band in order,
/// padded; returns the report of the whole bake.
pub(crate) fn bake(
    engine: &Engine,
    mesh: &LoadedMesh,
    job: &Job,
    shape: [u32; 2],
    on_stage: &dyn Fn(&str),
    sink: &mut dyn FnMut(&Band) -> Result<()>,
) -> Result<Report> {
    let radius = super::finish::padding_radius(job.padding);
    debug_assert!(radius != u32::MAX, "full padding reaches the whole texture");
    let wins = tiles::windows(job.width, job.height, shape);
    let rows: Vec<&[[u32; 4]]> = wins.chunk_by(|a, b| a[1] == b[1]).collect();
    let mut queue: VecDeque<Band> = VecDeque::new();
    // Bands at the queue's front already handed on, kept as the next bands' halo.
    let mut handed = 0;
    let mut report: Option<Report> = None;
    let (mut islands, mut padding_ms) = (0u64, 0.0);
    let mut first = 0;
    for (i, row) in rows.iter().enumerate() {
        let (band, r) = bake_band(engine, mesh, job, (row, first, wins.len()), on_stage)?;
        first += row.len();
        report = Some(tiles::merge(report, r));
        queue.push_back(band);
        let baked = queue.back().map_or(0, Band::end);
        let last = i + 1 == rows.len();
        while handed < queue.len() && (last || queue[handed].end() + radius as u64 <= baked) {
            let t = Instant::now();
            pad_band(&mut queue, handed, job, radius);
            padding_ms += t.elapsed().as_secs_f64() * 1000.0;
            islands += queue[handed].mask.iter().filter(|m| **m).count() as u64;
            sink(&queue[handed])?;
            handed += 1;
            // Drop the bands no later band's halo reaches.
            let next = queue.get(handed).map_or(u64::MAX, |b| b.y as u64);
            while handed > 0 && queue[0].end() + radius as u64 <= next {
                queue.pop_front();
                handed -= 1;
            }
        }
    }
    let mut report = report.expect("a texture has at least one tile");
    report.timings.padding_ms += padding_ms;
    report.island_texels = islands;
    report.padding = Some(radius);
    report.tiles = Some([shape[0], wins.len() as u32]);
    report.tile_size = Some(shape);
    Ok(report)
}

/// One row of tiles (`row`, the first of them tile `first` of `n`), unpadded, with its islands.
fn bake_band(
    engine: &Engine,
    mesh: &LoadedMesh,
    job: &Job,
    (row, first, n): (&[[u32; 4]], usize, usize),
    on_stage: &dyn Fn(&str),
) -> Result<(Band, Report)> {
    let (w, y, rows) = (job.width as usize, row[0][1], row[0][3]);
    let texels_n = w * rows as usize;
    let mut band = Band {
        y,
        rows,
        texels: vec![0u16; texels_n * 4],
        channels: super::channels::passes(job)
            .iter()
            .map(|_| vec![0u16; texels_n * 4])
            .collect(),
        linear: job.exr().then(|| vec![0f32; texels_n * 4]),
        channel_linear: match job.exr() {
            true => (super::channels::passes(job).iter())
                .map(|_| vec![0f32; texels_n * 4])
                .collect(),
            false => Vec::new(),
        },
        mask: vec![false; texels_n],
    };
    let mut report: Option<Report> = None;
    let mut commands = 0;
    for (k, &win) in row.iter().enumerate() {
        let dest = tiles::Dest {
            texels: &mut band.texels[..],
            channels: band.channels.iter_mut().map(|c| &mut c[..]).collect(),
            linear: band.linear.as_mut(),
            channel_linear: band.channel_linear.iter_mut().map(|c| &mut c[..]).collect(),
        };
        let cx = (engine, mesh, job);
        let r = tiles::bake_window(cx, (win, first + k, n), on_stage, y, dest)?;
        report = Some(tiles::merge(report, r));
        let m = super::islands::window_mask(
            engine,
            mesh,
            (job.uv_set, job.ss, engine.adaptive_sampling(job)),
            [job.width, job.height],
            win,
            &mut commands,
        )?;
        let ww = win[2] as usize;
        for (r, src) in m.chunks_exact(ww).enumerate() {
            let at = r * w + win[0] as usize;
            for (d, s) in band.mask[at..at + ww].iter_mut().zip(src) {
                *d = *s != 0;
            }
        }
    }
    let mut report = report.expect("a row has at least one tile");
    report.gpu_commands += commands;
    Ok((band, report))
}

/// Pads band `k` of `queue` in place over its halo: the rows within `radius` above (earlier bands
/// still queued) and below (later bands, baked), clipped to the texture.
fn pad_band(queue: &mut VecDeque<Band>, k: usize, job: &Job, radius: u32) {
    if radius == 0 {
        return;
    }
    let w = job.width as usize;
    let (y0, y1) = (queue[k].y as u64, queue[k].end());
    let top = y0.saturating_sub(radius as u64);
    let bottom = (y1 + radius as u64).min(job.height as u64);
    // The halo window, assembled from the queued bands that overlap it.
    let mut mask = Vec::new();
    let mut texels = Vec::new();
    let mut channels = vec![Vec::new(); queue[k].channels.len()];
    let mut channel_linear = vec![Vec::new(); queue[k].channel_linear.len()];
    let mut linear = job.exr().then(Vec::new);
    let mut from = top;
    for b in queue.iter() {
        let (a, e) = (b.y as u64, b.end());
        if e <= from || a >= bottom {
            continue;
        }
        let (r0, r1) = ((from - a) as usize, (e.min(bottom) - a) as usize);
        mask.extend_from_slice(&b.mask[r0 * w..r1 * w]);
        texels.extend_from_slice(&b.texels[r0 * w * 4..r1 * w * 4]);
        for (c, src) in channels.iter_mut().zip(&b.channels) {
            c.extend_from_slice(&src[r0 * w * 4..r1 * w * 4]);
        }
        for (c, src) in channel_linear.iter_mut().zip(&b.channel_linear) {
            c.extend_from_slice(&src[r0 * w * 4..r1 * w * 4]);
        }
        if let (Some(l), Some(src)) = (linear.as_mut(), &b.linear) {
            l.extend_from_slice(&src[r0 * w * 4..r1 * w * 4]);
        }
        from = e.min(bottom);
    }
    debug_assert_eq!(from, bottom, "the halo's rows are all queued");
    let rows = (bottom - top) as u32;
    let nearest = cpu::nearest_island_map(&mask, job.width, rows);
    let isl = TiledIslands {
        mask,
        nearest,
        count: 0,
    };
    super::finish::pad(&isl, job.width, radius, &mut texels, 4);
    let at = (y0 - top) as usize * w * 4;
    let band = &mut queue[k];
    let len = band.texels.len();
    band.texels.copy_from_slice(&texels[at..at + len]);
    for (dst, mut c) in band.channels.iter_mut().zip(channels) {
        super::finish::pad(&isl, job.width, radius, &mut c, 4);
        dst.copy_from_slice(&c[at..at + len]);
    }
    for (dst, mut c) in band.channel_linear.iter_mut().zip(channel_linear) {
        super::finish::pad(&isl, job.width, radius, &mut c, 4);
        dst.copy_from_slice(&c[at..at + len]);
    }
    if let (Some(l), Some(dst)) = (linear.as_mut(), band.linear.as_mut()) {
        super::finish::pad(&isl, job.width, radius, l, 4);
        dst.copy_from_slice(&l[at..at + len]);
    }
}
