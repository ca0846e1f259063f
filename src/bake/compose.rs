// SPDX-License-Identifier: MIT OR Apache-2.0
//! Stage 5, raster and compose: each layer's selected triangles are drawn at their global UVs into
//! supersampled atlas targets, carrying the layer's local coordinates, sampling its image (trilinear,
//! premultiplied) and mask (`wgsl/bake/layer_raster.wgsl`); `wgsl/bake/compose.wgsl` then blends the
//! covered texels into the canvas with the layer's blend mode, in job order. The same submission
//! measures each layer's distortion over its triangles (`wgsl/maps/distortion.wgsl`). CPU twin of
//! the whole stage: [`crate::bake::cpu::bake_cpu`].

use super::canvas::Canvas;
use super::channels::{ChannelDraw, Draw, Pass};
use super::engine::{Engine, LoadedMesh};
use super::images::Images;
use super::maps::{LayerMaps, Slots};
use super::params::{
    params_buffer, pbind, Params, FLAG_DIRTY, FLAG_TOOL, FLAG_WARP, PARAMS_STRIDE,
};
use super::place::Placed;
use super::plan::{meets, pack_atlas, plan_cells, Batch, BLOCK, BLOCKS_ROW, TILE_TARGET};
use super::stage::{Cx, Log};
use crate::error::Result;
use crate::gpu::pipelines::make_bind_group;
use crate::gpu::shaders::GENERAL_LAYER_FLAGS;
use crate::io::job::Job;
use crate::maps::distortion::{Distortion, DIST_GROUPS, PARTIAL_VEC4S};
use std::collections::HashMap;
use std::ops::Range;

/// One raster rectangle: the units drawn into it (one decal, or the run of a stroke's stamps in
/// this chunk, blended per sample so that a stroke's edges are its stamps' union, not their
/// texel-level compound) and the rectangle's `Params` (texel rectangle and UV tile, with the first
/// unit's fields).
pub struct RasterJob {
    /// The units drawn, in order.
    pub units: Range<usize>,
    /// The rectangle.
    pub params: Params,
    /// Index of the first unit's entry in the chunk's uniform buffer (one entry per unit follows).
    pub entry: usize,
}

/// The chunk's units in drawing groups: a decal alone, a stroke's consecutive stamps together when
/// the raster targets blend (`blending`: the adapter blends f32 targets, or the f16 fallback is in
/// use); without blending each stamp is its own group and stamps build up per texel.
fn groups(placed: &Placed, range: Range<usize>, blending: bool) -> Vec<Range<usize>> {
    let mut out: Vec<Range<usize>> = Vec::new();
    for i in range {
        let stroke = placed.stroke_of(i).map(|s| s.layer).filter(|_| blending);
        match out.last_mut() {
            Some(g) if stroke.is_some() && placed.stroke_of(g.start).map(|s| s.layer) == stroke => {
                g.end = i + 1
            }
            _ => out.push(i..i + 1),
        }
    }
    out
}

/// The raster jobs of the chunk, in unit order: one per run of marked cells (of the group's units
/// together) per UV tile the group's texel box touches.
pub fn raster_jobs(
    job: &Job,
    canvas: &Canvas,
    maps: &LayerMaps,
    stats: &[i32],
    placed: &Placed,
    blending: bool,
) -> Vec<RasterJob> {
    let (w, h, ss) = (job.width, job.height, job.ss);
    let mut jobs = Vec::new();
    let mut entry = 0;
    for g in groups(placed, maps.range.clone(), blending) {
        let mut mask = vec![0i32; canvas.row(stats, g.start).len() - 8];
        let mut bx = [i32::MAX, i32::MAX, i32::MIN, i32::MIN];
        for i in g.clone().filter(|&i| !placed.sources[i]) {
            let row = canvas.row(stats, i);
            for (m, r) in mask.iter_mut().zip(&row[8..]) {
                *m |= *r;
            }
            bx = [
                bx[0].min(row[1]),
                bx[1].min(row[2]),
                bx[2].max(row[3]),
                bx[3].max(row[4]),
            ];
        }
        if bx[0] > bx[2] {
            continue;
        }
        // The group's compose reads its first drawn unit's fields (a stroke's stamps: Normal).
        let shown = g.clone().find(|&u| !placed.hidden[u]).unwrap_or(g.start);
        let base = maps.params[shown - maps.range.start];
        let rects = plan_cells(
            &mask,
            canvas.grid,
            super::plan::CELL,
            [w, h],
            TILE_TARGET / ss,
        );
        for tj in bx[1].div_euclid(h as i32)..=(bx[3] - 1).max(bx[1]).div_euclid(h as i32) {
            for ti in bx[0].div_euclid(w as i32)..=(bx[2] - 1).max(bx[0]).div_euclid(w as i32) {
                for r in &rects {
                    jobs.push(RasterJob {
                        units: g.clone(),
                        params: Params {
                            rect_origin: [r[0], r[1]],
                            rect_size: [r[2] as u32, r[3] as u32],
                            tile: [ti, tj],
                            ..base
                        },
                        entry,
                    });
                    entry += g.len();
                }
            }
        }
    }
    jobs
}

/// Where a finished stroke is applied: before raster job `at` of the chunk (`jobs.len()`: after
/// the last), with `Params` entry `params` of the chunk's uniform buffer.
#[derive(Debug, Clone, Copy)]
struct Flush {
    at: usize,
    params: usize,
}

/// The strokes whose last unit is in this chunk, applied once their units' raster jobs are composed:
/// their flush points and `Params` (the whole texture, the stroke's blend and opacity, the row of its
/// last unit for the texel count).
fn flushes(
    placed: &Placed,
    maps: &LayerMaps,
    jobs: &[RasterJob],
    global: &Params,
    pass: Option<&Pass>,
) -> (Vec<Flush>, Vec<Params>) {
    let entries = jobs.last().map_or(0, |j| j.entry + j.units.len());
    let mut out = Vec::new();
    let mut params = Vec::new();
    for s in &placed.strokes {
        let last = s.units.end - 1;
        if s.units.is_empty() || !maps.range.contains(&last) {
            continue;
        }
        out.push(Flush {
            at: jobs.iter().filter(|j| j.units.start <= last).count(),
            params: entries + params.len(),
        });
        let [x, y, w, h] = global.window();
        // A channel pass applies the stroke with its channel's blend and opacity.
        let (blend, opacity, chan) = match pass.map(|p| &p.draws[s.layer]) {
            Some(Draw::Channel {
                opacity,
                blend,
                chan,
                ..
            }) => (*blend, *opacity, *chan),
            _ => (s.blend as u32, s.opacity, [0.0; 4]),
        };
        params.push(Params {
            rect_origin: [x as i32, y as i32],
            rect_size: [w, h],
            blend,
            opacity,
            chan,
            aux: last as u32,
            ..*global
        });
    }
    (out, params)
}

/// The cells a live bake's edit re-composes ([`crate::bake::LiveBake`]): a cell mask laid out as
/// a stats row's (one bit per [`super::plan::CELL`]-texel cell, `grid` cells a row, row-major).
pub(crate) struct Dirty<'a> {
    /// The mask's words.
    pub mask: &'a [u32],
    /// Cells per row and column.
    pub grid: [u32; 2],
}

impl Dirty<'_> {
    /// Whether texel rectangle (x, y, w, h) meets a marked cell.
    fn meets(&self, r: [i32; 4]) -> bool {
        let cell = super::plan::CELL as i32;
        let (x0, y0) = ((r[0] / cell).max(0), (r[1] / cell).max(0));
        let x1 = ((r[0] + r[2] - 1) / cell).min(self.grid[0] as i32 - 1);
        let y1 = ((r[1] + r[3] - 1) / cell).min(self.grid[1] as i32 - 1);
        (y0..=y1).any(|cy| {
            (x0..=x1).any(|cx| {
                let b = (cy as u32 * self.grid[0] + cx as u32) as usize;
                self.mask[b / 32] >> (b % 32) & 1 == 1
            })
        })
    }
}

/// What a [`compose`] call draws and composes.
#[derive(Clone, Copy)]
pub(crate) enum Passes<'a> {
    /// The colour, into the canvas the call is given.
    Colour,
    /// A channel group's separate pass ([`super::channels`]), into the canvas the call is given.
    Channel(&'a Pass),
    /// The colour into the canvas the call is given and, in the same raster and compose, every
    /// channel group of the list into its canvas ([`Engine::fuses_channels`]).
    Fused(&'a [(Pass, Canvas)]),
}

/// Rasterizes and composes the chunk's layers into the canvas (a stroke's stamps into the stroke
/// buffer, applied to the canvas after its last stamp); returns each layer's distortion.
/// `passes` ([`Passes`]): the colour's; a channel's pass ([`super::channels`]) into its own
/// canvas, each unit drawn as its job layer's [`Draw`] says (no distortion measured: the colour's
/// pass did); or the colour's with the channel groups fused beside it. `dirty`: a live bake's edit,
/// which draws only the raster rectangles that meet its cells, at the places the whole chunk's
/// plan gives them (the same samples, bit for bit), and composes only its cells' texels (no
/// distortion measured).
#[allow(clippy::too_many_arguments)]
pub(crate) fn compose(
    cx: Cx<'_>,
    images: &Images,
    canvas: &Canvas,
    slots: &Slots,
    maps: &LayerMaps,
    (stats, dirty): (&[i32], Option<&Dirty<'_>>),
    placed: &Placed,
    passes: Passes<'_>,
    log: &mut Log,
) -> Result<Vec<Distortion>> {
    let Cx { engine, mesh, job } = cx;
    let (pass, fused) = match passes {
        Passes::Colour => (None, &[][..]),
        Passes::Channel(p) => (Some(p), &[][..]),
        Passes::Fused(f) => (None, f),
    };
    let dev = &engine.ctx.device;
    let blending = engine.pipes.layer_blending;
    let mut jobs = raster_jobs(job, canvas, maps, stats, placed, blending);
    let sizes: Vec<[u32; 2]> = jobs.iter().map(|j| j.params.rect_size).collect();
    // Each job layer starts its own targets (a stroke's stamps share theirs).
    let layer = |k: usize| placed.origin[jobs[k].units.start].0;
    let starts: Vec<bool> = (0..jobs.len())
        .map(|k| k == 0 || layer(k) != layer(k - 1))
        .collect();
    // Packed in grid samples; the adaptive raster's targets hold a texel's samples in one
    // pixel, so its origins are the grid's over ss (every rectangle's samples are whole texels).
    let msaa = engine.adaptive_sampling(job);
    let (origins, mut batches) = pack_atlas(&sizes, &starts, job.ss);
    for (j, o) in jobs.iter_mut().zip(&origins) {
        j.params.atlas_origin = match msaa {
            true => o.map(|v| v / job.ss),
            false => *o,
        };
    }
    keep_drawn(&mut batches, &jobs, canvas.global.window(), dirty);
    if std::env::var("DECALBAKE_DEBUG").is_ok() {
        let covered: u64 = sizes.iter().map(|s| s[0] as u64 * s[1] as u64).sum();
        eprintln!(
            "raster jobs {} in {} batches, rect texels {covered}",
            jobs.len(),
            batches.len()
        );
    }
    let (flush, flush_params) = flushes(placed, maps, &jobs, &canvas.global, pass);
    super::tools::check_window(canvas, maps, stats, placed, &job.source)?;
    let mut jp = entry_params(&jobs, maps, placed, (images, canvas, pass), flush_params);
    if dirty.is_some() {
        for p in &mut jp {
            p.flags |= FLAG_DIRTY;
        }
    }
    let (draws, attached) = upload_draws(engine, &mut jp, &jobs, placed, (pass, fused));
    let job_params = params_buffer(dev, "bake.raster_params", &jp);
    let flags: Vec<u32> = jp.iter().map(|p| p.flags).collect();
    // The fused compose binds a canvas's two planes per channel group: 16-byte placeholders where
    // the pass has no such group.
    let spare_planes: Vec<wgpu::Buffer> = match fused.is_empty() {
        true => Vec::new(),
        false => (0..6)
            .map(|_| {
                engine
                    .ctx
                    .storage_init("bake.no_channel", &[], wgpu::BufferUsages::empty())
            })
            .collect(),
    };
    let n_chunk = maps.range.len() as u64;
    let partials_size = n_chunk * DIST_GROUPS as u64 * PARTIAL_VEC4S as u64 * 16;
    let partials = dev.create_buffer(&wgpu::BufferDescriptor {
        label: Some("bake.distortion"),
        size: partials_size,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let blocks = block_mask(engine);
    let no_flats = dev.create_buffer(&wgpu::BufferDescriptor {
        label: Some("bake.no_flats"),
        size: 16,
        usage: wgpu::BufferUsages::STORAGE,
        mapped_at_creation: false,
    });
    engine.ctx.scoped("raster and compose", || {
        let mut enc = dev.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("bake.compose"),
        });
        let flats = super::tools::record(
            Cx { engine, mesh, job },
            canvas,
            (&slots.coords, &slots.lists),
            maps,
            (stats, placed),
            &mut enc,
        );
        let cx = Recording {
            engine,
            mesh,
            job,
            images,
            canvas,
            slots,
            stats,
            jobs: &jobs,
            job_params: &job_params,
            placed,
            flush: &flush,
            flats: flats.as_ref().map_or(&no_flats, |f| &f.buffer),
            pass,
            fused,
            attached,
            draws: &draws,
            placeholder: &no_flats,
            spare_planes: &spare_planes,
            msaa,
            blocks: &blocks,
            flags: &flags,
        };
        if pass.is_none() && dirty.is_none() {
            log.commands +=
                record_distortion(engine, mesh, canvas, slots, maps, &partials, &mut enc);
        }
        let mut layer_bgs = HashMap::new();
        let mut flushed = 0;
        for batch in &batches {
            log.commands += cx.record_batch(batch, &mut layer_bgs, &mut flushed, &mut enc);
        }
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("bake.stroke_apply"),
            timestamp_writes: None,
        });
        log.commands += cx.record_flushes(usize::MAX, &mut flushed, &mut pass);
        drop(pass);
        engine.ctx.queue.submit([enc.finish()]);
    })?;
    if pass.is_some() || dirty.is_some() {
        return Ok(Vec::new());
    }
    let pb = engine
        .ctx
        .read_buffer(&partials, partials_size, "distortion read-back")?;
    let pf: &[[f32; 4]] = bytemuck::cast_slice(&pb);
    let per = PARTIAL_VEC4S * DIST_GROUPS as usize;
    Ok(pf
        .chunks_exact(per)
        .map(Distortion::from_partials)
        .collect())
}

/// The compose's block mask (`wgsl/shared/blocks.wgsl`): one word per [`BLOCK`]² texels of the
/// widest atlas target. Zeros, cleared before each batch, where the engine skips empty blocks
/// ([`Engine::skip_empty_blocks`]); otherwise ones, never cleared: every block is composed.
fn block_mask(engine: &Engine) -> wgpu::Buffer {
    let words = (BLOCKS_ROW * (TILE_TARGET / BLOCK)) as usize;
    match engine.skip_empty_blocks {
        // Made zeroed by wgpu, nothing uploaded: each batch clears what it uses.
        true => engine.ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("bake.blocks"),
            size: words as u64 * 4,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        }),
        false => engine.ctx.storage_init(
            "bake.blocks",
            bytemuck::cast_slice(&vec![1u32; words]),
            wgpu::BufferUsages::COPY_DST,
        ),
    }
}

/// Keeps in `batches` the raster jobs this canvas draws, and the batches left with any. A tile's
/// canvas (`bake/tiles.rs`) draws the rectangles that meet its window `win`, where the whole
/// texture's bake draws them (same rectangle, same atlas place: the same samples, bit for bit),
/// and composes their texels inside the window; a live bake's edit (`dirty`) those that meet its
/// cells.
fn keep_drawn(
    batches: &mut Vec<Batch>,
    jobs: &[RasterJob],
    win: [u32; 4],
    dirty: Option<&Dirty<'_>>,
) {
    let rect = |k: usize| {
        let p = &jobs[k].params;
        let [w, h] = p.rect_size.map(|v| v as i32);
        [p.rect_origin[0], p.rect_origin[1], w, h]
    };
    for (entries, _) in batches.iter_mut() {
        entries.retain(|&(k, _)| meets(rect(k), win) && dirty.is_none_or(|d| d.meets(rect(k))));
    }
    batches.retain(|(entries, _)| !entries.is_empty());
}

/// The chunk's uniform entries: one per (raster job, unit), the rectangle's fields with the
/// unit's own (tool stamps read their cell of the chunk's flat images, `bake/tools.rs`; a
/// channel pass draws each unit as its layer's [`Draw`] says), then the strokes' flushes.
fn entry_params(
    jobs: &[RasterJob],
    maps: &LayerMaps,
    placed: &Placed,
    (images, canvas, pass): (&Images, &Canvas, Option<&Pass>),
    flush_params: Vec<Params>,
) -> Vec<Params> {
    let start = maps.range.start;
    let cells: HashMap<usize, u32> = super::tools::cells(maps, placed).1;
    let cells = &cells;
    jobs.iter()
        .flat_map(|j| {
            j.units.clone().map(move |u| {
                let p = maps.params[u - start];
                let (mut flags, pad) = match cells.get(&u) {
                    Some(&c) => (p.flags | FLAG_TOOL, [c, 0]),
                    None => (p.flags, p.pad),
                };
                let warp = images.warp_at[u].map_or([0; 4], |w| {
                    flags |= FLAG_WARP;
                    [w, 0, 0, 0]
                });
                let (opacity, blend, chan) = unit_draw(pass, placed, u, &p, &mut flags);
                Params {
                    opacity,
                    blend,
                    chan,
                    rect_origin: j.params.rect_origin,
                    rect_size: j.params.rect_size,
                    tile: j.params.tile,
                    atlas_origin: j.params.atlas_origin,
                    flags,
                    pad,
                    win: canvas.global.win,
                    warp,
                    ..p
                }
            })
        })
        .chain(flush_params)
        .collect()
}

/// The channel draws of a fused pass (`fused`: its channel groups) or of a separate channel
/// pass (`pass`; its constants): one per entry of `jp`, each entry's [`Params::draw`] pointing
/// at its own (and, for a separate pass, at its group). The colour's alone: one unread entry
/// (a binding holds at least one).
fn channel_draws(
    jp: &mut [Params],
    jobs: &[RasterJob],
    placed: &Placed,
    (pass, fused): (Option<&Pass>, &[(Pass, Canvas)]),
) -> Vec<ChannelDraw> {
    let passes: Vec<&Pass> = fused.iter().map(|(p, _)| p).chain(pass).collect();
    if passes.is_empty() {
        return vec![ChannelDraw::default()];
    }
    let group = pass.map_or(0, |p| p.kind.slot() as u32);
    let mut draws: Vec<ChannelDraw> = jobs
        .iter()
        .flat_map(|j| j.units.clone())
        .map(|u| ChannelDraw::of(&passes, placed.origin[u].0))
        .collect();
    draws.resize(jp.len(), ChannelDraw::default());
    for (i, (p, d)) in jp.iter_mut().zip(&mut draws).enumerate() {
        p.draw = [i as u32, group, 0, 0];
        if pass.is_none() {
            d.bits[3] = derived_groups(d, p.opacity);
        }
    }
    draws
}

/// [`channel_draws`] on the device, with the groups a fused pass draws attachments for
/// ([`attached_groups`]; 0 in a colour's or a separate channel's pass).
fn upload_draws(
    engine: &Engine,
    jp: &mut [Params],
    jobs: &[RasterJob],
    placed: &Placed,
    (pass, fused): (Option<&Pass>, &[(Pass, Canvas)]),
) -> (wgpu::Buffer, u32) {
    let draws = channel_draws(jp, jobs, placed, (pass, fused));
    let attached = match fused.is_empty() {
        true => 0,
        false => attached_groups(&draws),
    };
    if std::env::var("DECALBAKE_DEBUG").is_ok() && !fused.is_empty() {
        eprintln!(
            "channel groups fused {}, drawn {attached:#05b}",
            fused.len()
        );
    }
    let buffer = engine.ctx.storage_init(
        "bake.channel_draws",
        bytemuck::cast_slice(&draws),
        wgpu::BufferUsages::empty(),
    );
    (buffer, attached)
}

/// Of a fused entry's channel groups `d`, those whose samples are the colour's alphas times a
/// constant: drawn from a constant (occlusion-roughness-metallic numbers, an emissive triple) at
/// exactly the colour's `opacity`, so every sample's alpha is the colour sample's (the raster
/// writes both as the image's alpha, masked, times the opacity and the sample's share).
fn derived_groups(d: &ChannelDraw, opacity: f32) -> u32 {
    (0..3)
        .filter(|&k| d.bits[2] >> k & 1 == 1 && d.opacity[k].to_bits() == opacity.to_bits())
        .fold(0, |b, k| b | 1 << k)
}

/// The channel groups a fused pass draws attachments for: those some entry paints and does not
/// derive from the colour ([`derived_groups`]; 0: the colour's raster alone).
fn attached_groups(draws: &[ChannelDraw]) -> u32 {
    draws.iter().fold(0, |b, d| b | (d.bits[0] & !d.bits[3]))
}

/// Unit `u`'s opacity, blend and data weights in `pass` (its `Params` `p` in the colour's), and
/// its raster flags added to `flags`. A stroke's stamps keep theirs (their stroke is applied with
/// the channel's, [`flushes`]); a unit whose layer does not paint the channel gets opacity 0 and is
/// not drawn ([`Recording::drawn`]).
fn unit_draw(
    pass: Option<&Pass>,
    placed: &Placed,
    u: usize,
    p: &Params,
    flags: &mut u32,
) -> (f32, u32, [f32; 4]) {
    match pass.map(|s| &s.draws[placed.origin[u].0]) {
        None | Some(Draw::Colour) => (p.opacity, p.blend, p.chan),
        Some(Draw::Skip) => (0.0, p.blend, p.chan),
        Some(Draw::Channel {
            opacity,
            blend,
            chan,
            flags: f,
            ..
        }) => {
            *flags |= f;
            match placed.stroke_of(u) {
                Some(_) => (p.opacity, p.blend, p.chan),
                None => (*opacity, *blend, *chan),
            }
        }
    }
}

/// `distortion`: each layer's map over its selected triangles, partial sums per workgroup.
fn record_distortion(
    engine: &Engine,
    mesh: &LoadedMesh,
    canvas: &Canvas,
    slots: &Slots,
    maps: &LayerMaps,
    partials: &wgpu::Buffer,
    enc: &mut wgpu::CommandEncoder,
) -> u32 {
    let (dev, pipes, g) = (&engine.ctx.device, &engine.pipes, &mesh.gpu);
    let bg = pipes.distortion.bind(
        dev,
        "bake.distortion",
        &[
            (0, pbind(&maps.buffer)),
            (1, g.positions.as_entire_binding()),
            (2, g.tris.as_entire_binding()),
            (3, slots.coords.as_entire_binding()),
            (4, slots.lists.as_entire_binding()),
            (5, canvas.stats.as_entire_binding()),
            (6, partials.as_entire_binding()),
        ],
    );
    let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
        label: Some("bake.distortion"),
        timestamp_writes: None,
    });
    pass.set_pipeline(&pipes.distortion.pipeline);
    for k in 0..maps.range.len() as u64 {
        pass.set_bind_group(0, &bg, &[(k * PARAMS_STRIDE) as u32]);
        pass.dispatch_workgroups(DIST_GROUPS, 1, 1);
    }
    maps.range.len() as u32
}

/// The part of raster rectangle `p` inside the canvas window `win` (x, y, w, h texels), in atlas
/// pixels (`ss` a texel: samples of the grid, or 1 for the adaptive raster's pixels of four
/// samples) relative to the rectangle's atlas origin: the scissor of its draws. A tile of a tiled
/// bake (`bake/tiles.rs`) rasterizes only its own part of a rectangle that straddles tile borders;
/// the viewport stays the whole rectangle's, so the samples drawn are exactly the whole bake's
/// (the scissor test discards fragments and changes no interpolation), and `compose.wgsl` reads
/// only the samples of texels inside the window. For a whole-texture canvas it is the rectangle.
fn scissor(p: &Params, win: [u32; 4], ss: u32) -> [u32; 4] {
    let (r0, rs) = (p.rect_origin, p.rect_size);
    let x0 = r0[0].max(win[0] as i32);
    let y0 = r0[1].max(win[1] as i32);
    let x1 = (r0[0] + rs[0] as i32).min((win[0] + win[2]) as i32);
    let y1 = (r0[1] + rs[1] as i32).min((win[1] + win[3]) as i32);
    let (w, h) = ((x1 - x0).max(0) as u32, (y1 - y0).max(0) as u32);
    [
        (x0 - r0[0]) as u32 * ss,
        (y0 - r0[1]) as u32 * ss,
        w * ss,
        h * ss,
    ]
}

/// What recording a batch reads.
struct Recording<'a> {
    engine: &'a Engine,
    mesh: &'a LoadedMesh,
    job: &'a Job,
    images: &'a Images,
    canvas: &'a Canvas,
    slots: &'a Slots,
    stats: &'a [i32],
    jobs: &'a [RasterJob],
    job_params: &'a wgpu::Buffer,
    placed: &'a Placed,
    flush: &'a [Flush],
    /// The chunk's filtered flat images (a 16-byte placeholder without tool stamps).
    flats: &'a wgpu::Buffer,
    /// A channel's pass, `None` for the colour's.
    pass: Option<&'a Pass>,
    /// The channel groups fused beside the colour, with their canvases (empty: none).
    fused: &'a [(Pass, Canvas)],
    /// Of those, the groups the raster draws attachments for ([`attached_groups`]; 0 where the
    /// compose derives every one from the colour, or none is fused).
    attached: u32,
    /// The fused pass's channel draws ([`channel_draws`]).
    draws: &'a wgpu::Buffer,
    /// A 16-byte storage buffer bound where a fused pass has no normal group (its tangents).
    placeholder: &'a wgpu::Buffer,
    /// Six 16-byte storage buffers bound where a fused pass has no group (its canvas's planes).
    spare_planes: &'a [wgpu::Buffer],
    /// Drawn at four samples a pixel ([`Engine::adaptive_sampling`]).
    msaa: bool,
    /// The block mask the raster marks and the compose reads ([`block_mask`]).
    blocks: &'a wgpu::Buffer,
    /// Each raster entry's flags (a unit whose entry has none of [`GENERAL_LAYER_FLAGS`] is
    /// drawn by the plain raster, [`crate::gpu::pipelines::Layers::raster_for`]).
    flags: &'a [u32],
}

impl Recording<'_> {
    /// One atlas batch: a render pass drawing each raster job into its region of the target, then
    /// one compose dispatch per job, in job order (so overlapping layers still apply in order; a
    /// stroke's stamps into the stroke buffer, the stroke applied where [`Flush`] says). `flushed`
    /// counts the flushes recorded so far. Returns the draws and dispatches recorded.
    fn record_batch(
        &self,
        (batch, used_h): &Batch,
        layer_bgs: &mut HashMap<(usize, bool), wgpu::BindGroup>,
        flushed: &mut usize,
        enc: &mut wgpu::CommandEncoder,
    ) -> u32 {
        let (engine, pipes) = (self.engine, self.engine.pipes.family(self.msaa));
        // Atlas pixels a texel a side: the grid's ss, the adaptive raster's one (of four samples).
        let (ss, samples) = match self.msaa {
            true => (1, 4),
            false => (self.job.ss, 1),
        };
        let size = match self.msaa {
            true => [TILE_TARGET, *used_h].map(|v| v / self.job.ss),
            false => [TILE_TARGET, *used_h],
        };
        let size = [size[0], size[1].next_power_of_two().max(64)];
        let tg = engine.targets(size, samples);
        let channel_views = self.channel_views(size);
        if engine.skip_empty_blocks {
            let rows = used_h.div_ceil(self.job.ss).div_ceil(BLOCK) as u64;
            enc.clear_buffer(self.blocks, 0, Some(rows * BLOCKS_ROW as u64 * 4));
        }
        {
            let views: Vec<Option<&wgpu::TextureView>> = [Some(&tg.color_view), Some(&tg.cov_view)]
                .into_iter()
                .chain(channel_views.iter().map(|v| v.as_deref()))
                .collect();
            // As many attachments as the pipelines have targets: none after the last group's.
            let used = views.iter().rposition(Option::is_some).map_or(0, |i| i + 1);
            let views = &views[..used];
            let win = self.canvas.global.window();
            // Each job's part of the target is cleared (a quad per scissor) instead of the whole
            // target: llvmpipe then loads and stores only the bins the jobs touch. Measured with a
            // temporary switch between the two, one pair of runs of `decalbake bench` on bob: 256
            // decals at 4096² (46 targets of 2048², about 60 % packed) compose 3.09 → 2.76 s; 16
            // decals 394 → 372 ms; one decal the same (a tiled 8192² bake: 1.80 → 1.62 s).
            let mut pass =
                crate::gpu::render_pass_to(enc, "bake.layer_raster", views, wgpu::LoadOp::Load);
            let clear = match self.attached {
                0 => &pipes.clear,
                b => &pipes.fused.clear[b as usize - 1],
            };
            pass.set_pipeline(&clear.pipeline);
            for &(k, _) in batch {
                let origin = self.jobs[k].params.atlas_origin;
                let [sx, sy, sw, sh] = scissor(&self.jobs[k].params, win, ss);
                pass.set_scissor_rect(origin[0] + sx, origin[1] + sy, sw, sh);
                pass.draw(0..3, 0..1);
            }
            let normal = self.pass.map(|p| p.kind) == Some(super::channels::ChannelKind::Normal);
            // The pipeline last set: each unit takes the plain variant where it can.
            let mut set: Option<bool> = None;
            for &(k, _) in batch {
                let rj = &self.jobs[k];
                let p = &rj.params;
                let origin = p.atlas_origin;
                let (jw, jh) = (p.rect_size[0] * ss, p.rect_size[1] * ss);
                pass.set_viewport(
                    origin[0] as f32,
                    origin[1] as f32,
                    jw as f32,
                    jh as f32,
                    0.0,
                    1.0,
                );
                // A tile's window clips the scissor, never the viewport: the samples inside
                // are the whole bake's, bit for bit (see `scissor`).
                let [sx, sy, sw, sh] = scissor(p, win, ss);
                pass.set_scissor_rect(origin[0] + sx, origin[1] + sy, sw, sh);
                for (e, i) in rj.units.clone().enumerate() {
                    if self.placed.sources[i] || !self.drawn(i) {
                        continue;
                    }
                    let plain = self.flags[rj.entry + e] & GENERAL_LAYER_FLAGS == 0;
                    let raster = pipes.raster_for(normal, self.attached, plain);
                    if set != Some(plain) {
                        pass.set_pipeline(&raster.pipeline);
                        set = Some(plain);
                    }
                    let bg = layer_bgs
                        .entry((i, plain))
                        .or_insert_with(|| self.layer_bind_group(i, &raster.layout));
                    let count = (self.canvas.row(self.stats, i)[0].max(0) as u32)
                        .min(self.mesh.gpu.triangle_count);
                    let offset = (rj.entry + e) as u64 * PARAMS_STRIDE;
                    pass.set_bind_group(0, &*bg, &[offset as u32]);
                    pass.draw(0..3 * count, 0..1);
                }
            }
        }
        let bind_compose = |planes: &[wgpu::Buffer; 2]| {
            pipes.compose.bind(
                &engine.ctx.device,
                "bake.compose",
                &[
                    (0, pbind(self.job_params)),
                    (1, wgpu::BindingResource::TextureView(&tg.color_view)),
                    (2, wgpu::BindingResource::TextureView(&tg.cov_view)),
                    (3, self.canvas.stats.as_entire_binding()),
                    (10, planes[0].as_entire_binding()),
                    (11, planes[1].as_entire_binding()),
                    (18, self.draws.as_entire_binding()),
                    (19, self.blocks.as_entire_binding()),
                ],
            )
        };
        let acc = [self.canvas.acc_rg.clone(), self.canvas.acc_ba.clone()];
        let (bg_canvas, compose) = match self.fused.is_empty() {
            true => (bind_compose(&acc), &pipes.compose),
            false => (
                self.bind_fused_compose(&tg, &channel_views),
                pipes.fused.compose_for(self.present(), self.attached),
            ),
        };
        let bg_stroke = self.canvas.stroke.as_ref().map(bind_compose);
        let mut n = 2 * batch.len() as u32;
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("bake.compose"),
            timestamp_writes: None,
        });
        for &(k, _) in batch {
            n += self.record_flushes(k, flushed, &mut pass);
            let rj = &self.jobs[k];
            let p = &rj.params;
            let bg = match (self.placed.stroke_of(rj.units.start), &bg_stroke) {
                (Some(_), Some(bg)) => bg,
                _ => &bg_canvas,
            };
            pass.set_pipeline(&compose.pipeline);
            pass.set_bind_group(0, bg, &[(rj.entry as u64 * PARAMS_STRIDE) as u32]);
            pass.dispatch_workgroups(p.rect_size[0].div_ceil(8), p.rect_size[1].div_ceil(8), 1);
        }
        n
    }

    /// `stroke_apply` for every stroke due before raster job `k` (`usize::MAX`: all that are left).
    /// Returns the dispatches recorded.
    fn record_flushes(&self, k: usize, flushed: &mut usize, pass: &mut wgpu::ComputePass) -> u32 {
        let (engine, pipes) = (self.engine, &self.engine.pipes);
        let mut n = 0;
        while let Some(f) = self.flush.get(*flushed).filter(|f| f.at <= k) {
            let planes = self
                .canvas
                .stroke
                .as_ref()
                .expect("a job with strokes has a stroke buffer");
            let bg = pipes.stroke_apply.bind(
                &engine.ctx.device,
                "bake.stroke_apply",
                &[
                    (0, pbind(self.job_params)),
                    (3, self.canvas.stats.as_entire_binding()),
                    (10, self.canvas.acc_rg.as_entire_binding()),
                    (11, self.canvas.acc_ba.as_entire_binding()),
                    (12, planes[0].as_entire_binding()),
                    (13, planes[1].as_entire_binding()),
                ],
            );
            let [_, _, w, h] = self.canvas.global.window();
            pass.set_pipeline(&pipes.stroke_apply.pipeline);
            pass.set_bind_group(0, &bg, &[(f.params as u64 * PARAMS_STRIDE) as u32]);
            pass.dispatch_workgroups(w.div_ceil(8), h.div_ceil(8), 1);
            *flushed += 1;
            n += 1;
        }
        n
    }

    /// The fused pass's channel attachments of `size`, by group (`None` where it draws none).
    fn channel_views(&self, size: [u32; 2]) -> [Option<std::sync::Arc<wgpu::TextureView>>; 3] {
        let bits = self.attached;
        let samples = if self.msaa { 4 } else { 1 };
        std::array::from_fn(|k| {
            (bits >> k & 1 == 1).then(|| self.engine.channel_target(size, k, samples))
        })
    }

    /// The fused compose's bindings: the colour's, each channel group's attachment and canvas
    /// planes (the colour's attachment and 16-byte placeholders where the pass has no such
    /// group), and the channel draws.
    fn bind_fused_compose(
        &self,
        tg: &super::engine::Targets,
        views: &[Option<std::sync::Arc<wgpu::TextureView>>; 3],
    ) -> wgpu::BindGroup {
        let mut planes: [Vec<&wgpu::Buffer>; 3] = Default::default();
        for (pass, canvas) in self.fused {
            planes[pass.kind.slot()] = vec![&canvas.acc_rg, &canvas.acc_ba];
        }
        let spare = self.spare_planes;
        let mut entries = vec![
            (0, pbind(self.job_params)),
            (1, wgpu::BindingResource::TextureView(&tg.color_view)),
            (2, wgpu::BindingResource::TextureView(&tg.cov_view)),
            (3, self.canvas.stats.as_entire_binding()),
            (10, self.canvas.acc_rg.as_entire_binding()),
            (11, self.canvas.acc_ba.as_entire_binding()),
            (18, self.draws.as_entire_binding()),
            (19, self.blocks.as_entire_binding()),
        ];
        for k in 0..3 {
            let view = views[k].as_deref().unwrap_or(&tg.color_view);
            entries.push((4 + k as u32, wgpu::BindingResource::TextureView(view)));
            for (j, spare) in spare[2 * k..2 * k + 2].iter().enumerate() {
                let plane = planes[k].get(j).copied().unwrap_or(spare);
                entries.push((12 + 2 * k as u32 + j as u32, plane.as_entire_binding()));
            }
        }
        let fused = &self.engine.pipes.family(self.msaa).fused;
        fused.compose_for(self.present(), self.attached).bind(
            &self.engine.ctx.device,
            "bake.compose_fused",
            &entries,
        )
    }

    /// The channel groups fused beside the colour, as bits (bit [`super::channels::ChannelKind::slot`]).
    fn present(&self) -> u32 {
        self.fused
            .iter()
            .fold(0, |b, (pass, _)| b | 1 << pass.kind.slot())
    }

    /// Whether unit `i` is drawn in this pass (always in the colour's).
    fn drawn(&self, i: usize) -> bool {
        self.pass
            .is_none_or(|p| !matches!(p.draws[self.placed.origin[i].0], Draw::Skip))
    }

    /// Layer `i`'s raster bind group: its triangle list, UVs, coords, image and mask (in a
    /// channel's pass, its channel image; for normals, the mesh's frames too).
    fn layer_bind_group(&self, i: usize, layout: &wgpu::BindGroupLayout) -> wgpu::BindGroup {
        if self.attached != 0 {
            return self.fused_bind_group(i, layout);
        }
        let engine = self.engine;
        let colour = &self.images.layers[i].0;
        // A constant channel is drawn from the colour image's coverage (`FLAG_CONSTANT`).
        let img = match self.pass.map(|p| &p.draws[self.placed.origin[i].0]) {
            Some(Draw::Channel {
                image: Some(image), ..
            }) => image,
            _ => colour,
        };
        let tangents = self.pass.and_then(|p| p.tangents.as_ref());
        let mut entries = self.unit_entries(i, &img.view);
        if let Some(t) = tangents {
            entries.extend(self.frames(t));
        }
        make_bind_group(&engine.ctx.device, layout, "bake.layer_raster", &entries)
    }

    /// The bindings every variant of the layer raster has, for unit `i` drawing `image`: its
    /// triangle list, UVs, coordinates, mask, the tool stamps' flats, the warps, the channel draws,
    /// the block mask.
    fn unit_entries<'b>(
        &'b self,
        i: usize,
        image: &'b wgpu::TextureView,
    ) -> Vec<(u32, wgpu::BindingResource<'b>)> {
        let g = &self.mesh.gpu;
        let mask = self.images.layers[i].1.as_ref();
        let mview = mask.map_or(&self.images.dummy.view, |m| &m.view);
        vec![
            (0, pbind(self.job_params)),
            (1, self.slots.lists.as_entire_binding()),
            (2, g.split_tris.as_entire_binding()),
            (3, g.uvs[self.job.uv_set as usize].as_entire_binding()),
            (4, g.welded_of.as_entire_binding()),
            (5, self.slots.coords.as_entire_binding()),
            (6, wgpu::BindingResource::TextureView(image)),
            (7, wgpu::BindingResource::TextureView(mview)),
            (
                8,
                wgpu::BindingResource::Sampler(&self.engine.linear_sampler),
            ),
            (9, self.flats.as_entire_binding()),
            (10, self.images.warps.as_entire_binding()),
            (17, self.draws.as_entire_binding()),
            (18, self.blocks.as_entire_binding()),
        ]
    }

    /// The normal and fused variants' mesh frames: split positions, normals and `tangents`.
    fn frames<'b>(&'b self, tangents: &'b wgpu::Buffer) -> [(u32, wgpu::BindingResource<'b>); 3] {
        let g = &self.mesh.gpu;
        [
            (11, g.split_positions.as_entire_binding()),
            (12, g.split_normals.as_entire_binding()),
            (13, tangents.as_entire_binding()),
        ]
    }

    /// Unit `i`'s raster bind group in a fused pass: the colour's bindings, the mesh's frames
    /// (the normal group's tangents, or a placeholder), each group's channel image (the dummy
    /// image where its layer or the pass has none) and the channel draws.
    fn fused_bind_group(&self, i: usize, layout: &wgpu::BindGroupLayout) -> wgpu::BindGroup {
        let engine = self.engine;
        let colour = &self.images.layers[i].0;
        let mut images = [&self.images.dummy.view; 3];
        let mut tangents = self.placeholder;
        for (pass, _) in self.fused {
            if let Draw::Channel {
                image: Some(image), ..
            } = &pass.draws[self.placed.origin[i].0]
            {
                images[pass.kind.slot()] = &image.view;
            }
            if let Some(t) = &pass.tangents {
                tangents = t;
            }
        }
        let mut entries = self.unit_entries(i, &colour.view);
        entries.extend(self.frames(tangents));
        for (k, view) in images.into_iter().enumerate() {
            entries.push((14 + k as u32, wgpu::BindingResource::TextureView(view)));
        }
        make_bind_group(
            &engine.ctx.device,
            layout,
            "bake.layer_raster_fused",
            &entries,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An entry painting `groups`, those in `constant` from numbers, each at `opacity`.
    fn draw(groups: u32, constant: u32, opacity: [f32; 3]) -> ChannelDraw {
        ChannelDraw {
            opacity: [opacity[0], opacity[1], opacity[2], 0.0],
            bits: [groups, 0, constant, 0],
            ..Default::default()
        }
    }

    /// Only the constant groups at exactly the colour's opacity are derived; a pass draws
    /// attachments for the groups some entry paints and does not derive.
    #[test]
    fn constant_groups_at_the_colours_opacity_are_derived() {
        let mut numbers = draw(0b101, 0b101, [0.8; 3]);
        assert_eq!(derived_groups(&numbers, 0.8), 0b101);
        numbers.bits[3] = derived_groups(&numbers, 0.8);
        // The roughness at its own opacity: drawn.
        let mut own = draw(0b001, 0b001, [0.5, 0.8, 0.8]);
        assert_eq!(derived_groups(&own, 0.8), 0);
        own.bits[3] = derived_groups(&own, 0.8);
        // A normal map and a metallic image: drawn.
        let images = draw(0b011, 0, [0.8; 3]);
        assert_eq!(derived_groups(&images, 0.8), 0);
        assert_eq!(attached_groups(&[numbers]), 0);
        assert_eq!(attached_groups(&[numbers, own]), 0b001);
        assert_eq!(attached_groups(&[numbers, images]), 0b011);
        assert_eq!(attached_groups(&[ChannelDraw::default()]), 0);
    }
}
