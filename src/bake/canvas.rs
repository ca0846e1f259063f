// SPDX-License-Identifier: MIT OR Apache-2.0
//! The canvas every layer composes into: a linear f32 accumulation image in two storage planes
//! (`wgsl/shared/acc.wgsl`), filled with the base by `wgsl/bake/base_init.wgsl` (or, for a
//! texture transfer, by [`super::transfer`]); the per-layer
//! statistics rows the selection stage fills; and the mesh's islands at this size
//! ([`super::islands`]). Created once per bake, owned by it, dropped with it.

use super::engine::Engine;
use super::engine::Islands;
use super::images::Images;
use super::islands::islands;
use super::params::{params_buffer, pbind, Params};
use super::plan::CELL;
use super::stage::{Cx, Log};
use crate::error::Result;
use crate::gpu::BufferInit;
use crate::io::job::Base;
use std::sync::Arc;

/// Counters at the start of a layer's stats row (`wgsl/bake/select_triangles.wgsl`): triangles,
/// texel box (4), texels covered, triangles reached, texels a stroke changed (counted on its last
/// unit's row by `stroke_apply`); the layer's cell mask follows.
pub const STATS_COUNTERS: u32 = 8;

/// The bake's accumulation image, statistics and islands.
pub struct Canvas {
    /// Accumulation plane: red and green (f32 each).
    pub acc_rg: wgpu::Buffer,
    /// Accumulation plane: blue and alpha.
    pub acc_ba: wgpu::Buffer,
    /// Where a stroke's stamps build up before the stroke is composed (same layout as the
    /// accumulation planes, transparent between strokes); only when the job has strokes.
    pub stroke: Option<[wgpu::Buffer; 2]>,
    /// The smear tool's carried colour (one flat cell, `bake/tools.rs`), kept across chunks; only
    /// when the job has strokes.
    pub carry: Option<wgpu::Buffer>,
    /// One row per layer: [`STATS_COUNTERS`] counters, then its cell mask.
    pub stats: wgpu::Buffer,
    /// Bytes of `stats`.
    pub stats_size: u64,
    /// Words per stats row.
    pub stats_stride: u32,
    /// Cells per row and column.
    pub grid: [u32; 2],
    /// The `Params` fields every kernel of this bake shares.
    pub global: Params,
    /// The mesh's islands at this size.
    pub islands: Arc<Islands>,
}

impl Canvas {
    /// Allocates the canvas, fetches (or computes) the islands and fills the base.
    /// `strokes`: whether to allocate the stroke buffer. `window`: the texel rectangle x, y, w, h
    /// the canvas holds, for one tile of a tiled bake ([`super::tiles`]; the islands are then the
    /// tiles' business and this canvas has none); `None`: the whole texture.
    pub(crate) fn new(
        cx: Cx<'_>,
        images: &Images,
        strokes: bool,
        window: Option<[u32; 4]>,
        log: &mut Log,
    ) -> Result<Self> {
        let Cx { engine, mesh, job } = cx;
        let dev = &engine.ctx.device;
        let g = &mesh.gpu;
        let (w, h, ss) = (job.width, job.height, job.ss);
        let win = window.unwrap_or([0, 0, w, h]);
        let texels = win[2] as u64 * win[3] as u64;
        let plane = |label| {
            dev.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: texels * 8,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            })
        };
        // The accumulation planes come from the engine's pool: the base fill below writes every
        // texel, and a transferred base clears them first.
        let usage = wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_SRC
            | wgpu::BufferUsages::COPY_DST;
        let (acc_rg, new_rg) = engine.pooled_buffer("bake.acc_rg", texels * 8, usage);
        let (acc_ba, new_ba) = engine.pooled_buffer("bake.acc_ba", texels * 8, usage);
        let reused = [acc_rg.clone(), acc_ba.clone()]
            .into_iter()
            .zip([new_rg, new_ba])
            .filter(|(_, new)| !new)
            .map(|(b, _)| b)
            .collect::<Vec<_>>();
        // wgpu zero-fills new buffers: the stroke buffer starts transparent.
        let stroke = strokes.then(|| [plane("bake.stroke_rg"), plane("bake.stroke_ba")]);
        let carry = strokes.then(|| {
            dev.create_buffer(&wgpu::BufferDescriptor {
                label: Some("bake.smear_carry"),
                size: (super::params::FLAT_RES * super::params::FLAT_RES) as u64 * 16,
                usage: wgpu::BufferUsages::STORAGE,
                mapped_at_creation: false,
            })
        });
        let nl = job.layers.len().max(1) as u64;
        let grid = [w.div_ceil(CELL), h.div_ceil(CELL)];
        let mask_words = (grid[0] * grid[1]).div_ceil(32);
        let stats_stride = STATS_COUNTERS + mask_words;
        let stats_init: Vec<i32> = (0..nl)
            .flat_map(|_| {
                [0, i32::MAX, i32::MAX, i32::MIN, i32::MIN, 0, 0, 0]
                    .into_iter()
                    .chain(std::iter::repeat_n(0, mask_words as usize))
            })
            .collect();
        let stats = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("bake.stats"),
            contents: bytemuck::cast_slice(&stats_init),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        });
        let global = Params {
            tex_size: [w, h],
            ss,
            vertex_count: g.vertex_count,
            triangle_count: g.triangle_count,
            stats_stride,
            cell: CELL,
            grid,
            win,
            ..Default::default()
        };
        let islands = match window {
            None => {
                let sampling = (ss, engine.adaptive_sampling(job));
                islands(
                    engine,
                    mesh,
                    job.uv_set,
                    [w, h],
                    sampling,
                    &mut log.commands,
                )?
            }
            Some(_) => Arc::new(Islands::none(dev)),
        };
        log.paths.islands = islands.path;
        let canvas = Self {
            acc_rg,
            acc_ba,
            stroke,
            carry,
            stats,
            stats_size: nl * stats_stride as u64 * 4,
            stats_stride,
            grid,
            global,
            islands,
        };
        // The material's texture belongs to its own set: baking into another, it is transferred.
        let sets = mesh.mesh.uv_sets.len() as u32;
        let from = match &job.base {
            Base::Transfer { from_uv_set, .. } => Some(*from_uv_set),
            Base::Material => mesh
                .mesh
                .material
                .as_ref()
                .filter(|m| m.base_color_texture.is_some())
                .map(|m| m.base_color_uv_set)
                .filter(|&s| s != job.uv_set && s < sets),
            _ => None,
        };
        if let Some(from_uv_set) = from {
            if !reused.is_empty() {
                engine.ctx.scoped("canvas clear", || {
                    let mut enc = dev.create_command_encoder(&Default::default());
                    for b in &reused {
                        enc.clear_buffer(b, 0, None);
                    }
                    engine.ctx.queue.submit([enc.finish()]);
                })?;
            }
            let acc = [&canvas.acc_rg, &canvas.acc_ba];
            let src = (&*images.base, from_uv_set);
            super::transfer::fill(engine, mesh, job, src, canvas.global, acc, log)?;
        } else {
            canvas.fill_base(engine, images, log)?;
        }
        Ok(canvas)
    }

    /// A channel pass's canvas ([`super::channels`]): new accumulation planes (and stroke
    /// buffers) filled with the pass's base, or transferred from it where it is laid out on
    /// another UV set; the islands and `Params` are this canvas's, and the stats buffer a new one
    /// of the same shape (the compose counts into it; the colour's counts are the report's).
    pub(crate) fn channel(
        &self,
        cx: Cx<'_>,
        base: (&Arc<super::engine::GpuImage>, u32),
        log: &mut Log,
    ) -> Result<Self> {
        let Cx { engine, mesh, job } = cx;
        let dev = &engine.ctx.device;
        let [_, _, w, h] = self.global.window();
        let bytes = w as u64 * h as u64 * 8;
        let usage = wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_SRC
            | wgpu::BufferUsages::COPY_DST;
        let plane = |label: &str| {
            dev.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes,
                usage,
                mapped_at_creation: false,
            })
        };
        let (acc_rg, _) = engine.pooled_buffer("bake.channel_rg", bytes, usage);
        let (acc_ba, _) = engine.pooled_buffer("bake.channel_ba", bytes, usage);
        let carry = self.carry.as_ref().map(|c| {
            dev.create_buffer(&wgpu::BufferDescriptor {
                label: Some("bake.smear_carry"),
                size: c.size(),
                usage: wgpu::BufferUsages::STORAGE,
                mapped_at_creation: false,
            })
        });
        let canvas = Self {
            acc_rg,
            acc_ba,
            stroke: self
                .stroke
                .as_ref()
                .map(|_| [plane("bake.stroke_rg"), plane("bake.stroke_ba")]),
            carry,
            stats: dev.create_buffer(&wgpu::BufferDescriptor {
                label: Some("bake.channel_stats"),
                size: self.stats_size,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
            stats_size: self.stats_size,
            stats_stride: self.stats_stride,
            grid: self.grid,
            global: self.global,
            islands: self.islands.clone(),
        };
        let (image, from) = base;
        if from != job.uv_set && (from as usize) < mesh.mesh.uv_sets.len() {
            engine.ctx.scoped("canvas clear", || {
                let mut enc = dev.create_command_encoder(&Default::default());
                enc.clear_buffer(&canvas.acc_rg, 0, None);
                enc.clear_buffer(&canvas.acc_ba, 0, None);
                engine.ctx.queue.submit([enc.finish()]);
            })?;
            let acc = [&canvas.acc_rg, &canvas.acc_ba];
            super::transfer::fill(engine, mesh, job, (image, from), canvas.global, acc, log)?;
        } else {
            canvas.fill_base_image(engine, image, log)?;
        }
        Ok(canvas)
    }

    /// `base_init`: the base image, sampled at every texel centre, into the accumulation planes.
    fn fill_base(&self, engine: &Engine, images: &Images, log: &mut Log) -> Result<()> {
        self.fill_base_image(engine, &images.base, log)
    }

    /// `base_init` of `base` over the whole window.
    fn fill_base_image(
        &self,
        engine: &Engine,
        base: &super::engine::GpuImage,
        log: &mut Log,
    ) -> Result<()> {
        self.fill_base_regions(engine, base, &[], log)
    }

    /// `base_init` of `base` over `regions` (x, y, w, h texel rectangles of the window: a live
    /// bake's edit resets its cells); none: the whole window.
    pub(crate) fn fill_base_regions(
        &self,
        engine: &Engine,
        base: &super::engine::GpuImage,
        regions: &[[u32; 4]],
        log: &mut Log,
    ) -> Result<()> {
        let (dev, pipes) = (&engine.ctx.device, &engine.pipes);
        let [_, _, w, h] = self.global.window();
        let whole = [[0, 0, w, h]];
        let entries: Vec<Params> = match regions {
            [] => vec![self.global],
            r => r
                .iter()
                .map(|r| Params {
                    rect_origin: [r[0] as i32, r[1] as i32],
                    atlas_origin: [r[2], r[3]],
                    ..self.global
                })
                .collect(),
        };
        let sizes = if regions.is_empty() {
            &whole[..]
        } else {
            regions
        };
        let base_params = params_buffer(dev, "bake.base_params", &entries);
        engine.ctx.scoped("base", || {
            let mut enc = dev.create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("bake.base"),
            });
            let bg_base = pipes.base_init.bind(
                dev,
                "bake.base_init",
                &[
                    (0, pbind(&base_params)),
                    (1, wgpu::BindingResource::TextureView(&base.view)),
                    (2, wgpu::BindingResource::Sampler(&engine.linear_sampler)),
                    (10, self.acc_rg.as_entire_binding()),
                    (11, self.acc_ba.as_entire_binding()),
                ],
            );
            {
                let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("bake.base_init"),
                    timestamp_writes: None,
                });
                pass.set_pipeline(&pipes.base_init.pipeline);
                for (k, r) in sizes.iter().enumerate() {
                    let offset = (k as u64 * super::params::PARAMS_STRIDE) as u32;
                    pass.set_bind_group(0, &bg_base, &[offset]);
                    pass.dispatch_workgroups(r[2].div_ceil(8), r[3].div_ceil(8), 1);
                    log.commands += 1;
                }
            }
            engine.ctx.queue.submit([enc.finish()]);
        })
    }

    /// This canvas's planes, islands and `Params` with a new stats buffer of `rows` rows (laid
    /// out as this one's, counters reset, masks clear), which the queue may write: a live bake
    /// keeps its edit's cells in the last row ([`crate::bake::LiveBake`]).
    pub(crate) fn with_rows(&self, dev: &wgpu::Device, rows: usize) -> Self {
        let init: Vec<i32> = (0..rows)
            .flat_map(|_| {
                [0, i32::MAX, i32::MAX, i32::MIN, i32::MIN, 0, 0, 0]
                    .into_iter()
                    .chain(std::iter::repeat_n(
                        0,
                        (self.stats_stride - STATS_COUNTERS) as usize,
                    ))
            })
            .collect();
        let stats = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("bake.stats"),
            contents: bytemuck::cast_slice(&init),
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC
                | wgpu::BufferUsages::COPY_DST,
        });
        Self {
            acc_rg: self.acc_rg.clone(),
            acc_ba: self.acc_ba.clone(),
            stroke: None,
            carry: None,
            stats,
            stats_size: rows as u64 * self.stats_stride as u64 * 4,
            stats_stride: self.stats_stride,
            grid: self.grid,
            global: self.global,
            islands: self.islands.clone(),
        }
    }

    /// The canvas window's texels, linear straight-alpha RGBA f32, read back (a float output).
    pub fn read_linear(&self, engine: &Engine) -> Result<Vec<f32>> {
        let [_, _, w, h] = self.global.window();
        let bytes = w as u64 * h as u64 * 8;
        let rg = engine
            .ctx
            .read_buffer(&self.acc_rg, bytes, "canvas read-back")?;
        let ba = engine
            .ctx
            .read_buffer(&self.acc_ba, bytes, "canvas read-back")?;
        let (rg, ba): (&[[f32; 2]], &[[f32; 2]]) =
            (bytemuck::cast_slice(&rg), bytemuck::cast_slice(&ba));
        Ok(rg
            .iter()
            .zip(ba)
            .flat_map(|(a, b)| [a[0], a[1], b[0], b[1]])
            .collect())
    }

    /// The stats rows, read back.
    pub fn read_stats(&self, engine: &Engine, stage: &str) -> Result<Vec<i32>> {
        let bytes = engine
            .ctx
            .read_buffer(&self.stats, self.stats_size, stage)?;
        Ok(bytemuck::cast_slice(&bytes).to_vec())
    }

    /// Layer `i`'s stats row in `stats` (as read by [`Canvas::read_stats`]).
    pub fn row<'a>(&self, stats: &'a [i32], i: usize) -> &'a [i32] {
        let n = self.stats_stride as usize;
        &stats[i * n..(i + 1) * n]
    }
}
