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
use super::params::{
    params_buffer, pbind, Params, FLAG_CONE, FLAG_FACING, FLAG_MASK, FLAG_NO_CLIP, FLAG_REPEAT,
    PARAMS_STRIDE,
};
use super::place::Placed;
use super::stage::{ms, Cx, Log};
use crate::error::{Error, Result};
use crate::gpu::BufferInit;
use crate::io::job::Job;
use crate::maps::chart::{self, ChartReport};
use crate::maps::expmap::GeoResult;
use crate::maps::{method, Record};
use std::ops::Range;
use std::time::Instant;

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
    /// Slots for as many layers as fit the chunk budget ([`super::stage::unit_capacity`]).
    pub(crate) fn new(engine: &Engine, mesh: &LoadedMesh, job: &Job) -> Self {
        let chunk = super::stage::unit_capacity(mesh).min(job.layers.len().max(1));
        Self::with_units(engine, mesh, chunk)
    }

    /// Slots for `chunk` units (zeroed).
    pub(crate) fn with_units(engine: &Engine, mesh: &LoadedMesh, chunk: usize) -> Self {
        let (dev, g) = (&engine.ctx.device, &mesh.gpu);
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
            // Copied between slots by a live bake's edits (`bake/live.rs`).
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_DST
                | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        Self {
            coords,
            lists,
            chunk,
        }
    }

    /// The units in chunks of at most [`Slots::chunk`], never splitting a block (a continuous
    /// stroke's stamps with the charts they blend; every other unit is a block of its own).
    /// A chunk also starts at every unit in `starts` (a blur or smear stroke, whose stamps read the
    /// canvas as the chunks before left it).
    pub fn chunks(&self, blocks: &[Range<usize>], starts: &[usize]) -> Vec<Range<usize>> {
        let mut out: Vec<Range<usize>> = Vec::new();
        for b in blocks {
            match out.last_mut() {
                Some(c) if b.end - c.start <= self.chunk && !starts.contains(&b.start) => {
                    c.end = b.end
                }
                _ => out.push(b.clone()),
            }
        }
        out
    }
}

/// A chunk's layers with their coordinates computed (in [`Slots::coords`]).
pub struct LayerMaps {
    /// The chunk's layers (job indices); slot k holds layer `range.start + k`.
    pub range: Range<usize>,
    /// Per layer of the chunk: its `Params` (frame, slot, blend, flags).
    pub params: Vec<Params>,
    /// `params` as a uniform buffer, one entry per [`PARAMS_STRIDE`] (uploaded after the chart
    /// pass, which sets the cone fields; a one-entry placeholder before).
    pub buffer: wgpu::Buffer,
    /// Per layer of the chunk: the exponential-map report, for layers that have one.
    pub expmap: Vec<Option<GeoResult>>,
    /// Per layer of the chunk: the chart report, for layers that have one.
    pub chart: Vec<Option<ChartReport>>,
    /// Per layer of the chunk: a ribbon's harmonic repair.
    pub ribbon: Vec<Option<crate::maps::ribbon::repair::RepairReport>>,
    /// Per layer of the chunk: the vertices its map can make valid (an exponential map's
    /// candidate disc, a chart's vertices, a blended stamp's charts' union), or `None` where the
    /// method may cover any vertex (planar projections). See [`LayerMaps::candidate_triangles`].
    pub reach: Vec<Option<Vec<u32>>>,
}

impl LayerMaps {
    /// Per layer of the chunk, the triangles the selection stage must test (ascending): every
    /// triangle with a vertex in the layer's reach, a superset of those with all three vertices
    /// valid, so selecting from them finds what a pass over the whole mesh finds, with work in
    /// proportion to the decal. `None`: the whole mesh.
    pub fn candidate_triangles(&self, topo: &crate::mesh::Topology) -> Vec<Option<Vec<u32>>> {
        self.reach
            .iter()
            .map(|r| {
                r.as_ref().map(|verts| {
                    let mut t: Vec<u32> = verts
                        .iter()
                        .flat_map(|&v| topo.triangles_around(v).iter().copied())
                        .collect();
                    t.sort_unstable();
                    t.dedup();
                    t
                })
            })
            .collect()
    }

    /// The chunk's layers (job indices) that their method solves (not blended: `blend_pass`) and
    /// whose method satisfies `f`.
    fn layers_where(
        &self,
        (job, placed): (&Job, &Placed),
        f: impl Fn(&dyn crate::maps::MapMethod) -> bool,
    ) -> Vec<usize> {
        self.range
            .clone()
            .filter(|&i| placed.blends[i].is_none() && f(method(job.layers[i].method)))
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
    let Cx { engine, mesh, job } = cx;
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
    // Triangles clipped to the layer's image where the raster clips (`clip_planes` in
    // `layer_raster.wgsl`; the selection marks the clipped part's cells): not with
    // `Engine::unclipped_raster`, on a device without clip distances, where the mesh's triangles
    // are small at this size (`Engine::clip_min_texels`), or for a warped image.
    let clips = engine.pipes.layer_clipped
        && !engine.unclipped_raster
        && mean_triangle_texels(mesh, job) >= engine.clip_min_texels;
    let params: Vec<Params> = range
        .clone()
        .map(|i| {
            let mut p = layer_params(job, placed, i, range.start, global);
            if !clips || !job.layers[i].warp.is_empty() {
                p.flags |= FLAG_NO_CLIP;
            }
            p
        })
        .collect();
    // Uploaded once the chart pass has set the cones' fields (the passes before do not read it).
    let buffer = params_buffer(&engine.ctx.device, "bake.layer_params", &[]);
    let mut maps = LayerMaps {
        expmap: vec![None; range.len()],
        chart: vec![None; range.len()],
        ribbon: vec![None; range.len()],
        reach: vec![None; range.len()],
        range,
        params,
        buffer,
    };
    expmap_pass(cx, placed, slots, &mut maps, log)?;
    chart_pass(cx, placed, slots, &mut maps, log)?;
    maps.buffer = params_buffer(&engine.ctx.device, "bake.layer_params", &maps.params);
    direct_pass(cx, placed, slots, &maps, log)?;
    direct_reach(cx, placed, &mut maps);
    ribbon_pass(cx, placed, slots, &mut maps, log)?;
    blend_reach(placed, &mut maps);
    blend_pass(cx, placed, slots, &maps, log)?;
    Ok(maps)
}

/// The mesh's mean triangle area in texels of the bake's UV set at its size
/// ([`Engine::clip_min_texels`]).
fn mean_triangle_texels(mesh: &super::engine::LoadedMesh, job: &Job) -> f32 {
    let m = &mesh.mesh;
    let Some(uv) = m.uv_sets.get(job.uv_set as usize) else {
        return 0.0;
    };
    let area: f64 = m
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| uv[i as usize]);
            ((b - a).perp_dot(c - a) as f64).abs() / 2.0
        })
        .sum();
    let texels = area * job.width as f64 * job.height as f64;
    (texels / m.triangles.len().max(1) as f64) as f32
}

/// Layer `i`'s `Params`: the shared fields, its frame, slot, blend and flags.
fn layer_params(job: &Job, placed: &Placed, i: usize, start: usize, global: &Params) -> Params {
    let l = &job.layers[i];
    let f = Params::of_frame(&placed.frames[i]);
    // A tiled ribbon repeats its image along x (`FLAG_REPEAT`, the count in `cone_a[3]`).
    let repeats = placed.ribbons[i].as_ref().map_or(0.0, |r| r.repeats);
    Params {
        cone_a: [0.0, 0.0, 0.0, repeats],
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
        } | if l.mask.is_some() { FLAG_MASK } else { 0 }
            | if repeats > 0.0 { FLAG_REPEAT } else { 0 },
        ..*global
    }
}

/// The ribbon units' maps: each curve's extended exponential map on the GPU
/// ([`crate::maps::ribbon::gpu::run`]) straight into its slot as the unit's image coordinates;
/// their reach is the strip's candidates.
fn ribbon_pass(
    cx: Cx<'_>,
    placed: &Placed,
    slots: &Slots,
    maps: &mut LayerMaps,
    log: &mut Log,
) -> Result<()> {
    use crate::maps::ribbon::gpu::{run, Output};
    let Cx { engine, mesh, .. } = cx;
    let start = maps.range.start;
    let units: Vec<usize> = maps
        .range
        .clone()
        .filter(|&i| placed.ribbons[i].is_some())
        .collect();
    if units.is_empty() {
        return Ok(());
    }
    for i in units {
        let r = placed.ribbons[i].as_ref().expect("filtered");
        let out = Output {
            slot: (i - start) as u32,
            xform: r.xform,
        };
        let (status, cands) = run(
            &engine.ctx,
            &engine.pipes,
            mesh.surface_ref(),
            (&r.curve, r.reach),
            (&slots.coords, out),
        )?;
        log.commands += status.dispatches;
        // The surface must let the strip spread as wide as asked (a curve along a border, or a
        // strip wider than the part it lies on, would be cut off).
        for (side, (want, got)) in ["left", "right"]
            .iter()
            .zip(r.sides.iter().zip(status.extent))
        {
            if status.converged && *want > 0.0 && got < 0.95 * want {
                let l = placed.origin[i].0;
                return Err(crate::error::Error::job(
                    &cx.job.source,
                    format!("layers[{l}].width"),
                    format!("the strip spreads {want:.4} to the curve's {side}, but the surface reaches only {got:.4} there (a border or the end of the part the curve is on); narrow the ribbon, align it to the other side, or move the curve"),
                ));
            }
        }
        if !status.converged {
            log.warnings.push(format!(
                "layer {}: the ribbon's map did not converge in {} sweeps; the ribbon may be incomplete",
                placed.origin[i].0, status.sweeps
            ));
        }
        maps.ribbon[i - start] = Some(repair_pass(cx, slots, (i - start) as u32, r, log)?);
        maps.reach[i - start] = Some(cands);
    }
    Ok(())
}

/// A ribbon's harmonic repair ([`crate::maps::ribbon::repair`]): its curved parts found from the
/// curve; where there are any, the unit's slot is read back, the parts re-solved on the GPU
/// conjugate gradient and the slot written again.
fn repair_pass(
    cx: Cx<'_>,
    slots: &Slots,
    slot: u32,
    r: &crate::bake::kinds::ribbon::RibbonUnit,
    log: &mut Log,
) -> Result<crate::maps::ribbon::repair::RepairReport> {
    use crate::maps::ribbon::repair::{curved_parts, repair_coords, solve_gpu};
    let Cx { engine, mesh, .. } = cx;
    if curved_parts(&mesh.topo, &r.curve, r.sides, r.lambda).is_empty() {
        return Ok(Default::default());
    }
    let size = mesh.gpu.vertex_count as u64 * 16;
    let offset = slot as u64 * size;
    let bytes = engine
        .ctx
        .read_buffer_range(&slots.coords, offset, size, "ribbon repair")?;
    let mut coords: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(&bytes);
    let report = repair_coords(
        &mesh.topo,
        (&r.curve, r.sides, r.lambda),
        &mut coords,
        r.xform,
        solve_gpu(&engine.ctx, &engine.pipes),
    )?;
    let bytes = bytemuck::cast_slice(&coords);
    engine.ctx.queue.write_buffer(&slots.coords, offset, bytes);
    log.commands += 2;
    Ok(report)
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
    let layers = maps.layers_where((job, placed), |m| m.uses_expmap());
    let requests: Vec<_> = layers
        .iter()
        .map(|&i| {
            let f = &placed.frames[i];
            let opts = f.expmap_options(&job.layers[i]);
            (f.seed(&placed.placements[i]), opts, (i - start) as u32)
        })
        .collect();
    if requests.is_empty() {
        return Ok(());
    }
    let gl = engine.ctx.backend == Some(wgpu::Backend::Gl);
    let (results, dispatches) = if engine.stage_paths.expmap_on_cpu(engine) {
        log.paths.expmap = "cpu";
        crate::maps::expmap::gpu::run_cpu_twin(
            &engine.ctx,
            mesh.surface_ref(),
            &requests,
            &slots.coords,
        )?
    } else {
        log.paths.expmap = if gl { "cpu" } else { "gpu" };
        crate::maps::expmap::gpu::run(
            &engine.ctx,
            &engine.pipes,
            mesh.surface_ref(),
            &requests,
            &slots.coords,
        )?
    };
    log.commands += dispatches;
    for ((&i, r), (seed, opts, _)) in layers.iter().zip(results).zip(&requests) {
        maps.expmap[i - start] = Some(r);
        // The relaxation writes only its candidate disc (and marks the halo unreachable).
        maps.reach[i - start] = Some(crate::maps::expmap::gpu::candidates(
            &mesh.topo,
            seed,
            opts.radius,
        ));
    }
    Ok(())
}

/// The reach of the layers whose method's own pass wrote their coordinates (planar: the vertices
/// near the decal's box, from the mesh's BVH; [`crate::maps::MapMethod::reach`]).
fn direct_reach(cx: Cx<'_>, placed: &Placed, maps: &mut LayerMaps) {
    let Cx { mesh, job, .. } = cx;
    let start = maps.range.start;
    for i in maps.range.clone() {
        let m = method(job.layers[i].method);
        if placed.blends[i].is_none() && !m.uses_expmap() {
            maps.reach[i - start] = m.reach(&mesh.topo, &mesh.bvh, &placed.frames[i]);
        }
    }
}

/// A blended stamp's reach: the union of its charts' (its coordinates are valid where all of
/// theirs are).
fn blend_reach(placed: &Placed, maps: &mut LayerMaps) {
    let start = maps.range.start;
    for i in maps.range.clone() {
        let Some(b) = &placed.blends[i] else {
            continue;
        };
        // Without charts every vertex is valid (`maps::stamp::blend_cpu`): the whole mesh.
        let mut union: Option<Vec<u32>> = (!b.charts.is_empty()).then(Vec::new);
        for &(u, _, _) in &b.charts {
            union = match (union, &maps.reach[u - start]) {
                (Some(mut a), Some(r)) => {
                    a.extend_from_slice(r);
                    Some(a)
                }
                _ => None,
            };
        }
        if let Some(v) = &mut union {
            v.sort_unstable();
            v.dedup();
        }
        maps.reach[i - start] = union;
    }
}

/// The conformal charts of every layer whose method has one, solved in one batch from the layers'
/// exponential maps (read back once, over their candidate discs: [`read_discs`]), then written
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
    let layers = maps.layers_where((job, placed), |m| m.uses_expmap() && m.solves_chart());
    if layers.is_empty() {
        return Ok(());
    }
    let t = Instant::now();
    let all = read_discs(engine, slots, maps, &layers, nv)?;
    let requests: Vec<_> = layers
        .iter()
        .zip(&all)
        .map(|(&i, map)| {
            let l = &job.layers[i];
            let (f, tri) = (placed.frames[i], placed.placements[i].triangle);
            let req = method(l.method)
                .chart(l, f, tri, map)
                .expect("filtered above");
            // No cut where coordinates are used vertex by vertex: corner charts (stamps blend them)
            // and the stamps of blur, smear and clone strokes (inverse rendering draws their
            // triangles at their coordinates).
            let paint = placed
                .stroke_of(i)
                .is_none_or(|s| matches!(s.tool, crate::io::job::Tool::Paint));
            chart::ChartRequest {
                cone: !placed.hidden[i] && paint,
                ..req
            }
        })
        .collect();
    let mut stats = chart::SolveStats::default();
    let solver = if engine.stage_paths.charts_on_cpu(engine) {
        log.paths.charts = "cpu";
        chart::Solver::Cpu
    } else {
        log.paths.charts = "gpu";
        engine.solver()
    };
    let charts = chart::build(&mesh.topo, &requests, &solver, &mut stats)?;
    log.commands += stats.dispatches;
    let mut items: Vec<[u32; 8]> = Vec::new();
    let mut kept = vec![true; charts.len()];
    for (k, (&i, c)) in layers.iter().zip(&charts).enumerate() {
        if placed.hidden[i] && chart_error(job, i, &c.report).is_some() {
            // A continuous stroke's corner chart (larger than its stamps) that folds or does not
            // converge keeps its exponential map: the stamps blending it stay continuous.
            log.warnings.push(format!(
                "layer {}: a corner chart of the continuous stroke ({} triangles) folded or did not converge as a conformal chart; its exponential map is used instead",
                placed.origin[i].0, c.report.triangles
            ));
            kept[k] = false;
            maps.chart[i - start] = Some(c.report);
            continue;
        }
        check_chart(job, (i, placed.origin[i].0), &c.report, log)?;
        maps.chart[i - start] = Some(c.report);
        if let Some(cone) = c.cone() {
            let p = &mut maps.params[i - start];
            (p.cone_a, p.cone_b) = cone.params();
            p.flags |= FLAG_CONE;
        }
        // A chart may grow past its exponential map's disc (refinement unfolds across borders).
        if let Some(r) = &mut maps.reach[i - start] {
            r.extend(c.coords.iter().map(|&(v, _)| v));
        }
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
        .zip(&kept)
        .filter(|((_, c), keep)| c.replaces_map && **keep)
        .map(|((&i, _), _)| (i - start) as u64 * nv * 16)
        .collect();
    scatter(engine, slots, &items, &cleared, nv * 16)?;
    log.commands += 1;
    log.timings.charts_ms += ms(t);
    Ok(())
}

/// The exponential maps of `layers` (per welded vertex), read back only over their candidate
/// discs (`chart_gather`; every other vertex is unreached, as the relaxation leaves it), where
/// reading the slots whole would move the mesh's size per layer.
fn read_discs(
    engine: &Engine,
    slots: &Slots,
    maps: &LayerMaps,
    layers: &[usize],
    nv: u64,
) -> Result<Vec<Vec<[f32; 4]>>> {
    let start = maps.range.start;
    let discs: Vec<&[u32]> = layers
        .iter()
        .map(|&i| maps.reach[i - start].as_deref().unwrap_or(&[]))
        .collect();
    let indices: Vec<u32> = layers
        .iter()
        .zip(&discs)
        .flat_map(|(&i, d)| {
            d.iter()
                .map(move |&v| ((i - start) as u64 * nv + v as u64) as u32)
        })
        .collect();
    let (dev, pipes) = (&engine.ctx.device, &engine.pipes);
    let len = indices.len().max(1) as u64;
    let out = engine.ctx.scoped("chart exponential maps", || {
        let idx = engine.ctx.storage_init(
            "bake.chart_gather_indices",
            bytemuck::cast_slice(&indices),
            wgpu::BufferUsages::empty(),
        );
        let dims = engine.ctx.uniform_init(
            "bake.chart_gather_dims",
            bytemuck::cast_slice(&[indices.len() as u32, 0, 0, 0]),
        );
        let out = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("bake.chart_gather_out"),
            size: len * 16,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let bg = pipes.chart_gather.bind(
            dev,
            "bake.chart_gather",
            &[
                (0, dims.as_entire_binding()),
                (1, idx.as_entire_binding()),
                (2, slots.coords.as_entire_binding()),
                (3, out.as_entire_binding()),
            ],
        );
        let mut enc = dev.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(&pipes.chart_gather.pipeline);
            pass.set_bind_group(0, &bg, &[]);
            pass.dispatch_workgroups((len as u32).div_ceil(64), 1, 1);
        }
        engine.ctx.queue.submit([enc.finish()]);
        out
    })?;
    let bytes = engine
        .ctx
        .read_buffer(&out, len * 16, "chart exponential-map read-back")?;
    let values: &[[f32; 4]] = bytemuck::cast_slice(&bytes);
    let mut at = 0;
    Ok(discs
        .iter()
        .map(|d| {
            let mut map = vec![[0.0f32; 4]; nv as usize];
            for &v in *d {
                map[v as usize] = values[at];
                at += 1;
            }
            map
        })
        .collect())
}

/// A chart that did not converge stops the bake; one that kept growing is a warning.
/// `(i, layer)`: the unit and its job layer (warnings name the layer).
fn check_chart(
    job: &Job,
    (i, layer): (usize, usize),
    r: &ChartReport,
    log: &mut Log,
) -> Result<()> {
    if let Some(e) = chart_error(job, i, r) {
        return Err(e);
    }
    if r.region.fix == chart::region::RegionFix::ShrunkToDisc {
        log.warnings.push(format!(
            "layer {layer}: the conformal chart's region was not a disc (Euler characteristic {}, {} boundary loop(s)); it was shrunk to a disc grown from the placed point, leaving the handle open",
            r.region.euler_characteristic, r.region.boundary_loops
        ));
    }
    match r.fallback {
        chart::Fallback::SmallerRegion => log.warnings.push(format!(
            "layer {layer}: the conformal chart folded inside the decal; it was re-solved on a smaller region"
        )),
        chart::Fallback::Lscm => log.warnings.push(format!(
            "layer {layer}: the hybrid re-solve folded inside the decal; it was re-solved as a free conformal chart"
        )),
        chart::Fallback::Expmap => log.warnings.push(format!(
            "layer {layer}: every conformal re-solve of the hybrid folded inside the decal ({} flipped, {} collapsed and {} torn of {} triangles); the layer keeps its exponential map",
            r.footprint_flipped, r.footprint_collapsed, r.footprint_torn, r.footprint_triangles
        )),
        _ => {}
    }
    if !r.settled {
        log.warnings.push(format!(
            "layer {layer}: the conformal chart was still growing after {} refinement rounds (the decal wraps around a rounded feature); it is conformal but its size varies: make the decal smaller, or use \"expmap\" or \"hybrid\"",
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
fn direct_pass(
    cx: Cx<'_>,
    placed: &Placed,
    slots: &Slots,
    maps: &LayerMaps,
    log: &mut Log,
) -> Result<()> {
    let Cx { engine, mesh, job } = cx;
    // Group the chunk's layers by method (first appearance first): one bind group per method.
    let start = maps.range.start;
    let mut groups: Vec<(crate::io::job::Method, Vec<u32>)> = Vec::new();
    for i in maps.range.clone().filter(|&i| placed.blends[i].is_none()) {
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

/// `first` of a stamp record whose blend covers every vertex (`ALL_VERTICES` in the kernel).
const ALL_VERTICES: u32 = u32::MAX;

/// `stamp_blend`: the chunk's blended stamps' coordinates from their corners' charts (in the same
/// chunk: [`Slots::chunks`] keeps them together), one dispatch for all of them, each stamp over the
/// vertices its charts reach ([`LayerMaps::reach`]; the rest of its slot stays cleared).
fn blend_pass(
    cx: Cx<'_>,
    placed: &Placed,
    slots: &Slots,
    maps: &LayerMaps,
    log: &mut Log,
) -> Result<()> {
    let Cx { engine, mesh, .. } = cx;
    let start = maps.range.start;
    let slot = |u: usize| (u - start) as u32;
    let mut records: Vec<[u32; 4]> = Vec::new();
    // Each stamp writes the vertices its charts reach (`verts`), or all where that is unknown.
    let mut verts: Vec<u32> = Vec::new();
    let mut widest = 0u32;
    let nv = mesh.gpu.vertex_count;
    for i in maps.range.clone() {
        let Some(b) = &placed.blends[i] else {
            continue;
        };
        let c = b.corners;
        let (first, count) = match &maps.reach[i - start] {
            Some(r) => {
                verts.extend_from_slice(r);
                ((verts.len() - r.len()) as u32, r.len() as u32)
            }
            None => (ALL_VERTICES, nv),
        };
        widest = widest.max(count);
        records.push([slot(i), b.charts.len() as u32, first, count]);
        records.push([c[0], c[1], c[2], 0]);
        records.push([
            b.bary[0].to_bits(),
            b.bary[1].to_bits(),
            b.bary[2].to_bits(),
            0,
        ]);
        for k in 0..crate::maps::stamp::MAX_CHARTS {
            records.push(match b.charts.get(k) {
                Some(&(u, w, theta)) => {
                    let (s, co) = theta.sin_cos();
                    [slot(u), w.to_bits(), co.to_bits(), s.to_bits()]
                }
                None => [0; 4],
            });
        }
    }
    if records.is_empty() {
        return Ok(());
    }
    let stamps = (records.len() / 9) as u32;
    let (dev, pipes) = (&engine.ctx.device, &engine.pipes);
    engine.ctx.scoped("stamp charts", || {
        let recs = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("bake.stamp_records"),
            contents: bytemuck::cast_slice(&records),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let verts = engine.ctx.storage_init(
            "bake.stamp_vertices",
            bytemuck::cast_slice(&verts),
            wgpu::BufferUsages::empty(),
        );
        let mut enc = dev.create_command_encoder(&Default::default());
        for first in (0..stamps).step_by(65_535) {
            let dims = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("bake.stamp_dims"),
                contents: bytemuck::cast_slice(&[nv, stamps, first, 0]),
                usage: wgpu::BufferUsages::UNIFORM,
            });
            let bg = pipes.stamp_blend.bind(
                dev,
                "bake.stamp_blend",
                &[
                    (0, dims.as_entire_binding()),
                    (1, recs.as_entire_binding()),
                    (2, slots.coords.as_entire_binding()),
                    (3, verts.as_entire_binding()),
                ],
            );
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("bake.stamp_blend"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&pipes.stamp_blend.pipeline);
            pass.set_bind_group(0, &bg, &[]);
            pass.dispatch_workgroups(widest.div_ceil(64).max(1), (stamps - first).min(65_535), 1);
        }
        engine.ctx.queue.submit([enc.finish()]);
    })?;
    log.commands += 1;
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
