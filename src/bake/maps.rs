// SPDX-License-Identifier: MIT OR Apache-2.0
//! Stage 3, layer maps: each layer's local coordinates per welded vertex, written into its slot of
//! the coords buffer, by the method's plug-in ([`crate::maps::MapMethod`]) in three batched passes:
//! the exponential maps of the chunk in one dispatch ([`crate::maps::expmap::gpu::run`]), the
//! conformal charts in one batched GPU CG ([`crate::maps::chart::build`], scattered into the slots by
//! `wgsl/maps/chart_scatter.wgsl`), and the methods' own kernels (planar: `planar_coords`).
//!
//! Layers are processed in chunks whose coords slots and triangle lists fit a memory budget
//! ([`Slots`]); the selection and compose stages then run on the same chunk.

use super::engine::{Engine, LoadedMesh};
use super::params::{params_buffer, pbind, Params, FLAG_FACING, FLAG_MASK, PARAMS_STRIDE};
use super::place::Placed;
use super::stage::{ms, Cx, Log};
use crate::error::{Error, Result};
use crate::io::job::Job;
use crate::maps::chart::{self, ChartReport};
use crate::maps::expmap::GeoResult;
use crate::maps::{method, Record};
use std::ops::Range;
use std::time::Instant;
use wgpu::util::DeviceExt;

/// Memory budget for one chunk's per-layer coordinates and triangle lists.
const CHUNK_BUDGET: u64 = 64 << 20;

/// The per-chunk buffers: one coords slot (a vec4 per welded vertex) and one triangle list per
/// layer of a chunk. Owned by the bake, reused by every chunk.
pub struct Slots {
    /// Coordinates, `chunk` slots.
    pub coords: wgpu::Buffer,
    /// Selected triangles, `chunk` lists of `triangle_count` entries.
    pub lists: wgpu::Buffer,
    /// Layers per chunk.
    pub chunk: usize,
}

impl Slots {
    /// Slots for as many layers as fit [`CHUNK_BUDGET`] (at least one).
    pub(crate) fn new(engine: &Engine, mesh: &LoadedMesh, job: &Job) -> Self {
        let (dev, g) = (&engine.ctx.device, &mesh.gpu);
        let per_layer = g.vertex_count as u64 * 16 + g.triangle_count as u64 * 4;
        let chunk =
            ((CHUNK_BUDGET / per_layer.max(1)).max(1) as usize).min(job.layers.len().max(1));
        let coords = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("bake.coords"),
            size: (chunk as u64 * g.vertex_count as u64 * 16).max(16),
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_DST
                | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let lists = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("bake.lists"),
            size: (chunk as u64 * g.triangle_count as u64 * 4).max(16),
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        Self {
            coords,
            lists,
            chunk,
        }
    }

    /// The job's layers in chunks.
    pub fn chunks(&self, layers: usize) -> impl Iterator<Item = Range<usize>> {
        let chunk = self.chunk;
        (0..layers)
            .step_by(chunk)
            .map(move |s| s..(s + chunk).min(layers))
    }
}

/// A chunk's layers with their coordinates computed (in [`Slots::coords`]).
pub struct LayerMaps {
    /// The chunk's layers (job indices); slot k holds layer `range.start + k`.
    pub range: Range<usize>,
    /// Per layer of the chunk: its `Params` (frame, slot, blend, flags).
    pub params: Vec<Params>,
    /// `params` as a uniform buffer, one entry per [`PARAMS_STRIDE`].
    pub buffer: wgpu::Buffer,
    /// Per layer of the chunk: the exponential-map report, for layers that have one.
    pub expmap: Vec<Option<GeoResult>>,
    /// Per layer of the chunk: the chart report, for layers that have one.
    pub chart: Vec<Option<ChartReport>>,
}

impl LayerMaps {
    /// The chunk's layers (job indices) whose map method satisfies `f`.
    fn layers_where(
        &self,
        job: &Job,
        f: impl Fn(&dyn crate::maps::MapMethod) -> bool,
    ) -> Vec<usize> {
        self.range
            .clone()
            .filter(|&i| f(method(job.layers[i].method)))
            .collect()
    }
}

/// Computes the coordinates of the layers in `range` into their slots.
pub(crate) fn compute(
    cx: Cx<'_>,
    placed: &Placed,
    slots: &Slots,
    range: Range<usize>,
    global: &Params,
    log: &mut Log,
) -> Result<LayerMaps> {
    let Cx {
        engine,
        mesh: _,
        job,
    } = cx;
    if range.start > 0 {
        // The exponential maps only write the vertices of their disc (and mark its halo); a slot's
        // other vertices must not keep the previous chunk's layer as valid.
        engine.ctx.scoped("coords clear", || {
            let mut enc = engine
                .ctx
                .device
                .create_command_encoder(&Default::default());
            enc.clear_buffer(&slots.coords, 0, None);
            engine.ctx.queue.submit([enc.finish()]);
        })?;
        log.commands += 1;
    }
    let params: Vec<Params> = range
        .clone()
        .map(|i| layer_params(job, placed, i, range.start, global))
        .collect();
    let buffer = params_buffer(&engine.ctx.device, "bake.layer_params", &params);
    let mut maps = LayerMaps {
        expmap: vec![None; range.len()],
        chart: vec![None; range.len()],
        range,
        params,
        buffer,
    };
    expmap_pass(cx, placed, slots, &mut maps, log)?;
    chart_pass(cx, placed, slots, &mut maps, log)?;
    direct_pass(cx, slots, &maps, log)?;
    Ok(maps)
}

/// Layer `i`'s `Params`: the shared fields, its frame, slot, blend and flags.
fn layer_params(job: &Job, placed: &Placed, i: usize, start: usize, global: &Params) -> Params {
    let l = &job.layers[i];
    let f = Params::of_frame(&placed.frames[i]);
    Params {
        center: f.center,
        axis_u: f.axis_u,
        axis_v: f.axis_v,
        normal: f.normal,
        slot: (i - start) as u32,
        aux: i as u32,
        blend: l.blend as u32,
        opacity: l.opacity,
        flags: if method(l.method).front_facing() {
            FLAG_FACING
        } else {
            0
        } | if l.mask.is_some() { FLAG_MASK } else { 0 },
        ..*global
    }
}

/// The exponential maps of every layer whose method uses one: one dispatch, one workgroup per map.
fn expmap_pass(
    cx: Cx<'_>,
    placed: &Placed,
    slots: &Slots,
    maps: &mut LayerMaps,
    log: &mut Log,
) -> Result<()> {
    let Cx { engine, mesh, job } = cx;
    let start = maps.range.start;
    let layers = maps.layers_where(job, |m| m.uses_expmap());
    let requests: Vec<_> = layers
        .iter()
        .map(|&i| {
            let f = &placed.frames[i];
            let opts = f.expmap_options(&job.layers[i]);
            (f.seed(&placed.placements[i]), opts, (i - start) as u32)
        })
        .collect();
    let (results, dispatches) = crate::maps::expmap::gpu::run(
        &engine.ctx,
        &engine.pipes,
        mesh.surface_ref(),
        &requests,
        &slots.coords,
    )?;
    log.commands += dispatches;
    for (&i, r) in layers.iter().zip(results) {
        maps.expmap[i - start] = Some(r);
    }
    Ok(())
}

/// The conformal charts of every layer whose method has one, solved in one batch from the layers'
/// exponential maps (read back once, from the first to the last chart layer's slot), then written
/// into their slots on the GPU (`chart_scatter`).
fn chart_pass(
    cx: Cx<'_>,
    placed: &Placed,
    slots: &Slots,
    maps: &mut LayerMaps,
    log: &mut Log,
) -> Result<()> {
    let Cx { engine, mesh, job } = cx;
    let start = maps.range.start;
    let nv = mesh.gpu.vertex_count as u64;
    let layers = maps.layers_where(job, |m| m.uses_expmap() && m.solves_chart());
    let (Some(&first), Some(&last)) = (layers.first(), layers.last()) else {
        return Ok(());
    };
    let t = Instant::now();
    let bytes = engine.ctx.read_buffer_range(
        &slots.coords,
        (first - start) as u64 * nv * 16,
        (last - first + 1) as u64 * nv * 16,
        "chart exponential-map read-back",
    )?;
    let all: &[[f32; 4]] = bytemuck::cast_slice(&bytes);
    let n = nv as usize;
    let requests: Vec<_> = layers
        .iter()
        .map(|&i| {
            let l = &job.layers[i];
            let k = i - first;
            let (f, tri) = (placed.frames[i], placed.placements[i].triangle);
            method(l.method)
                .chart(l, f, tri, &all[k * n..(k + 1) * n])
                .expect("filtered above")
        })
        .collect();
    let mut stats = chart::SolveStats::default();
    let charts = chart::build(&mesh.topo, &requests, &engine.solver(), &mut stats)?;
    log.commands += stats.dispatches;
    let mut items: Vec<[u32; 8]> = Vec::new();
    for (&i, c) in layers.iter().zip(&charts) {
        check_chart(job, i, &c.report, log)?;
        maps.chart[i - start] = Some(c.report);
        let base = (i - start) as u64 * nv;
        for &(v, uv) in &c.coords {
            let value = [uv[0], uv[1], 0.0, 1.0];
            let mut item = [0u32; 8];
            item[0] = (base + v as u64) as u32;
            item[4..].copy_from_slice(bytemuck::cast_slice(&value));
            items.push(item);
        }
    }
    let cleared: Vec<u64> = layers
        .iter()
        .zip(&charts)
        .filter(|(_, c)| c.replaces_map)
        .map(|(&i, _)| (i - start) as u64 * nv * 16)
        .collect();
    scatter(engine, slots, &items, &cleared, nv * 16)?;
    log.commands += 1;
    log.timings.charts_ms += ms(t);
    Ok(())
}

/// A chart that did not converge stops the bake; one that kept growing is a warning.
fn check_chart(job: &Job, i: usize, r: &ChartReport, log: &mut Log) -> Result<()> {
    if let Some(e) = chart_error(job, i, r) {
        return Err(e);
    }
    if r.region.fix == chart::region::RegionFix::ShrunkToDisc {
        log.warnings.push(format!(
            "layer {i}: the conformal chart's region was not a disc (Euler characteristic {}, {} boundary loop(s)); it was shrunk to a disc grown from the placed point, leaving the handle open",
            r.region.euler_characteristic, r.region.boundary_loops
        ));
    }
    match r.fallback {
        chart::Fallback::SmallerRegion => log.warnings.push(format!(
            "layer {i}: the conformal chart folded inside the decal; it was re-solved on a smaller region"
        )),
        chart::Fallback::Lscm => log.warnings.push(format!(
            "layer {i}: the hybrid re-solve folded inside the decal; it was re-solved as a free conformal chart"
        )),
        _ => {}
    }
    if !r.settled {
        log.warnings.push(format!(
            "layer {i}: the conformal chart was still growing after {} refinement rounds (the decal wraps around a rounded feature); it is conformal but its size varies: make the decal smaller, or use \"expmap\" or \"hybrid\"",
            chart::MAX_ROUNDS
        ));
    }
    Ok(())
}

/// Clears the slots at byte offsets `cleared` (each `slot_bytes` long), then writes `items`
/// (coords index, pad, value) into the coords buffer with `chart_scatter`.
fn scatter(
    engine: &Engine,
    slots: &Slots,
    items: &[[u32; 8]],
    cleared: &[u64],
    slot_bytes: u64,
) -> Result<()> {
    let (dev, pipes) = (&engine.ctx.device, &engine.pipes);
    engine.ctx.scoped("chart coordinates", || {
        let items_buf = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("bake.chart_items"),
            contents: bytemuck::cast_slice(if items.is_empty() {
                &[[0u32; 8]][..]
            } else {
                items
            }),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let dims = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("bake.chart_dims"),
            contents: bytemuck::cast_slice(&[items.len() as u32, 0, 0, 0]),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let bg = pipes.chart_scatter.bind(
            dev,
            "bake.chart_scatter",
            &[
                (0, dims.as_entire_binding()),
                (1, items_buf.as_entire_binding()),
                (2, slots.coords.as_entire_binding()),
            ],
        );
        let mut enc = dev.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("bake.charts"),
        });
        for &offset in cleared {
            enc.clear_buffer(&slots.coords, offset, Some(slot_bytes));
        }
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("bake.chart_scatter"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&pipes.chart_scatter.pipeline);
            pass.set_bind_group(0, &bg, &[]);
            pass.dispatch_workgroups((items.len() as u32).div_ceil(64).max(1), 1, 1);
        }
        engine.ctx.queue.submit([enc.finish()]);
    })
}

/// The methods' own kernels (planar), one compute pass for the chunk.
fn direct_pass(cx: Cx<'_>, slots: &Slots, maps: &LayerMaps, log: &mut Log) -> Result<()> {
    let Cx { engine, mesh, job } = cx;
    // Group the chunk's layers by method (first appearance first): one bind group per method.
    let start = maps.range.start;
    let mut groups: Vec<(crate::io::job::Method, Vec<u32>)> = Vec::new();
    for i in maps.range.clone() {
        let m = job.layers[i].method;
        let off = ((i - start) as u64 * PARAMS_STRIDE) as u32;
        match groups.iter_mut().find(|(g, _)| *g == m) {
            Some((_, offs)) => offs.push(off),
            None => groups.push((m, vec![off])),
        }
    }
    let cx = Record {
        device: &engine.ctx.device,
        pipes: &engine.pipes,
        mesh: mesh.surface_ref(),
        params: pbind(&maps.buffer),
        coords: &slots.coords,
    };
    let mut recorded = 0;
    engine.ctx.scoped("layer coordinates", || {
        let mut enc = engine
            .ctx
            .device
            .create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("bake.layer_coords"),
                timestamp_writes: None,
            });
            for (m, offsets) in &groups {
                recorded += method(*m).record(&cx, &mut pass, offsets);
            }
        }
        // A chunk without direct methods records nothing: no submission.
        if recorded > 0 {
            engine.ctx.queue.submit([enc.finish()]);
        }
    })?;
    log.commands += recorded;
    Ok(())
}

/// The error that stops a bake (and `decalbake param`) for layer `i`'s chart: a solve that did not
/// converge, or a chart that still folds into the decal after the fallbacks.
pub(super) fn chart_error(job: &Job, i: usize, r: &ChartReport) -> Option<Error> {
    let detail = if r.status != crate::solve::sparse::CgStatus::Converged {
        format!(
            "the conformal chart ({} triangles) did not converge: {:?} after {} conjugate-gradient iterations, relative residual {:.2e} (target {:.0e}); raise `cg_max_iterations`, make the decal smaller, or use \"expmap\"",
            r.triangles, r.status, r.cg_iterations, r.residual, chart::FINAL_RTOL
        )
    } else if r.fallback == chart::Fallback::Refused {
        format!(
            "the conformal chart folds inside the decal ({} flipped, {} collapsed and {} torn of the {} triangles under it) even when solved on a smaller region; make the decal smaller, move it off the sharp feature or the handle, or use \"expmap\"",
            r.footprint_flipped, r.footprint_collapsed, r.footprint_torn, r.footprint_triangles
        )
    } else {
        return None;
    };
    Some(Error::Placement {
        path: job.source.clone(),
        layer: i,
        detail,
    })
}
