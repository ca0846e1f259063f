// SPDX-License-Identifier: MIT OR Apache-2.0
//! Live bakes: a bake kept on the GPU for a host that edits its layers and wants each edit seen
//! ([`Engine::live`], [`LiveBake::apply`]). The canvas, every unit's coordinates and triangle list
//! (one chunk's [`Slots`], a unit per slot) and their stats rows stay between edits. An edit:
//!
//! 1. places the edited job again (the placement of an unchanged layer is the same, bit for bit);
//! 2. computes the map and selection of the changed layer only, in a chunk of its own, and copies
//!    its coordinates and triangle list into its slot;
//! 3. resets the 64 × 64 cells its old and new footprints touch to the base (`base_init` over
//!    those cells) and composes every layer there in job order, drawing the raster rectangles of
//!    the whole job's plan that meet those cells at the places that plan gives them, so each
//!    sample is the full bake's, bit for bit (`compose::Dirty`, `FLAG_DIRTY` in `compose.wgsl`);
//! 4. pads and encodes those cells and the texels their padding reaches, into the kept encoded
//!    texture, and copies them into the host's `wgpu::Texture`.
//!
//! [`LiveBake::read`] reads back only what the edits since the last read changed. The bytes equal
//! a full bake of the edited job (`tests/live.rs`, after random sequences of edits).
//!
//! Where a batch's result depends on its company, the changed layer is solved in the company a
//! full bake gives it: a chart layer with every chart of the job where the adapter packs such a
//! batch ([`crate::solve::gpu::Packing`]), and an exponential map with another where the full
//! bake's batch has more than one (a map alone in its chunk may be spread over workgroups on a
//! GPU, `maps::expmap::gpu`).
//!
//! A live bake takes decal, text and ribbon layers (one unit each) into the colour texture; jobs
//! with strokes, PBR channels, tiles, float outputs or a base transferred from another UV set
//! are refused with an error that says so (bake them with [`Engine::bake`]).

use super::canvas::Canvas;
use super::compose::{self, Dirty};
use super::engine::{Engine, LoadedMesh};
use super::finish::{self, Encoded};
use super::images::{self, Images};
use super::maps::{self, LayerMaps, Slots};
use super::params::{params_buffer, Params};
use super::place::{self, Placed};
use super::plan::{plan_cells, CELL};
use super::stage::{Cx, Log};
use crate::error::{Error, Result};
use crate::io::job::{Base, Job, Layer, LayerKind};
use crate::maps::method;
use std::time::Instant;

/// One change to a live bake's layers ([`LiveBake::apply`]). Layer indices are the job's.
#[derive(Debug, Clone)]
pub enum Edit {
    /// Layer `layer` becomes `to`: moved (`at`), turned (`angle`), resized (`size`), re-weighted
    /// (`opacity`, `blend`), or any other field changed.
    Set {
        /// The layer.
        layer: usize,
        /// Its new fields.
        to: Box<Layer>,
    },
    /// `layer` inserted before layer `at` (`at` = the number of layers: on top).
    Add {
        /// Where.
        at: usize,
        /// The new layer.
        layer: Box<Layer>,
    },
    /// Layer `layer` removed.
    Remove {
        /// The layer.
        layer: usize,
    },
    /// Layer `from` moved to position `to` in the layer order (the layers between shift by one).
    Reorder {
        /// The layer.
        from: usize,
        /// Its new position.
        to: usize,
    },
}

/// What one edit re-did ([`LiveBake::apply`]).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct EditReport {
    /// Maps (and selections) computed: the changed layer's, and its company where a batch needs
    /// it (see the module's documentation).
    pub maps: usize,
    /// 64 × 64 cells reset and re-composed.
    pub cells: u32,
    /// Layers drawn into those cells.
    pub layers_drawn: usize,
    /// Milliseconds: placement and images, maps and selection, compose, padding and encode.
    pub place_ms: f64,
    /// See `place_ms`.
    pub maps_ms: f64,
    /// See `place_ms`.
    pub compose_ms: f64,
    /// See `place_ms`.
    pub encode_ms: f64,
}

/// A unit's map as the compose stage reads it: its `Params` (slot and stats row: its index) and
/// what the map stage reported.
#[derive(Clone)]
struct UnitMap {
    params: Params,
    expmap: Option<crate::maps::expmap::GeoResult>,
    chart: Option<crate::maps::chart::ChartReport>,
    ribbon: Option<crate::maps::ribbon::repair::RepairReport>,
    reach: Option<Vec<u32>>,
}

impl UnitMap {
    /// Unit k of a chunk's maps.
    fn of(maps: &LayerMaps, k: usize) -> Self {
        Self {
            params: maps.params[k],
            expmap: maps.expmap[k],
            chart: maps.chart[k],
            ribbon: maps.ribbon[k].clone(),
            reach: maps.reach[k].clone(),
        }
    }
}

/// A bake kept on the GPU and re-baked edit by edit ([`Engine::live`]).
pub struct LiveBake<'a> {
    engine: &'a Engine,
    mesh: &'a LoadedMesh,
    /// The job as edited so far.
    job: Job,
    /// Its units (one per layer) and their images.
    placed: Placed,
    images: Images,
    /// The canvas; its stats buffer has `capacity` rows and the edit's cell mask in one more.
    canvas: Canvas,
    /// A slot per unit: coordinates and triangle list at the unit's index.
    slots: Slots,
    capacity: usize,
    units: Vec<UnitMap>,
    /// Each unit's stats row (counters and cell mask) as its selection left it.
    rows: Vec<i32>,
    encoded: Encoded,
    texture: wgpu::Texture,
    texels: Vec<u16>,
    /// Regions encoded since the last [`LiveBake::read`].
    pending: Vec<[u32; 4]>,
    /// An edit failed after it began changing the kept GPU state (a lost device, say).
    failed: bool,
}

impl Engine {
    /// Bakes `job` onto `mesh` and keeps the bake on the GPU for edits ([`LiveBake::apply`]),
    /// each of which re-bakes only what it changed, to the bytes a full bake of the edited job
    /// gives. See [`LiveBake`] for the jobs it takes.
    pub fn live<'a>(&'a self, mesh: &'a LoadedMesh, job: &Job) -> Result<LiveBake<'a>> {
        LiveBake::new(self, mesh, job)
    }
}

/// A [`Log`] for work whose report is not kept.
fn scratch_log() -> Log {
    Log {
        timings: Default::default(),
        warnings: Vec::new(),
        commands: 0,
        paths: Default::default(),
    }
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1000.0
}

/// The error of every call on a live bake after an edit failed part-way on the GPU.
fn failed() -> Error {
    Error::Gpu {
        stage: "live bake".into(),
        detail: "an earlier edit failed after it began changing the bake on the GPU; make a new live bake (after a lost device, on a new engine)".into(),
    }
}

/// The job's refusal when a live bake cannot take it.
fn refuse(job: &Job, field: &str, what: &str) -> Error {
    Error::Job {
        path: job.source.clone(),
        field: field.into(),
        detail: format!("a live bake does not take {what}; bake this job with Engine::bake"),
    }
}

/// Whether a live bake takes `job` (its fields; its layers one by one: [`check_layer`]).
fn check_job(engine: &Engine, mesh: &LoadedMesh, job: &Job) -> Result<()> {
    if super::tiles::tile_shape(engine, job).is_some() {
        return Err(refuse(
            job,
            "texture",
            "tiled bakes (or a texture beyond one storage buffer)",
        ));
    }
    if job.exr() {
        return Err(refuse(job, "output.texture", "float (EXR) outputs"));
    }
    let sets = mesh.mesh.uv_sets.len() as u32;
    let transferred = match &job.base {
        Base::Transfer { .. } => true,
        Base::Material => mesh.mesh.material.as_ref().is_some_and(|m| {
            m.base_color_texture.is_some()
                && m.base_color_uv_set != job.uv_set
                && m.base_color_uv_set < sets
        }),
        _ => false,
    };
    if transferred {
        return Err(refuse(
            job,
            "texture.base",
            "a base transferred from another UV set",
        ));
    }
    for (i, l) in job.layers.iter().enumerate() {
        check_layer(job, i, l)?;
    }
    Ok(())
}

/// Whether a live bake takes layer `i`: one unit (not a stroke), colour only, sane numbers.
fn check_layer(job: &Job, i: usize, l: &Layer) -> Result<()> {
    let field = |f: &str| format!("layers[{i}].{f}");
    if l.kind == LayerKind::Stroke {
        return Err(refuse(job, &field("kind"), "strokes"));
    }
    if crate::io::channels::ChannelKind::ALL
        .into_iter()
        .any(|k| l.channels.paints(k))
    {
        return Err(refuse(job, &field("normal"), "PBR channels"));
    }
    let bad = |f: &str, detail: &str| Error::Job {
        path: job.source.clone(),
        field: field(f),
        detail: detail.into(),
    };
    if !l.size.iter().all(|s| s.is_finite() && *s > 0.0) {
        return Err(bad("size", "each side must be a positive number"));
    }
    if !(l.opacity.is_finite() && (0.0..=1.0).contains(&l.opacity)) {
        return Err(bad("opacity", "must be between 0 and 1"));
    }
    if !l.angle.is_finite() {
        return Err(bad("angle", "must be a number of degrees"));
    }
    Ok(())
}

/// The units `list` of `placed` as a job of their own (unit k of it is `list[k]`): a chunk for
/// their maps and selection. Live bakes hold no strokes, so every unit is its own layer.
fn subset(placed: &Placed, list: &[usize]) -> Placed {
    let mut job = placed.job.clone();
    job.layers = list.iter().map(|&u| placed.job.layers[u].clone()).collect();
    Placed {
        placements: list.iter().map(|&u| placed.placements[u]).collect(),
        frames: list.iter().map(|&u| placed.frames[u]).collect(),
        job,
        origin: (0..list.len()).map(|k| (k, 0)).collect(),
        units_of: (0..list.len()).map(|k| k..k + 1).collect(),
        hidden: vec![false; list.len()],
        blends: vec![None; list.len()],
        sources: vec![false; list.len()],
        clone_of: vec![None; list.len()],
        blocks: (0..list.len()).map(|k| k..k + 1).collect(),
        strokes: Vec::new(),
        ribbons: list.iter().map(|&u| placed.ribbons[u].clone()).collect(),
    }
}

impl<'a> LiveBake<'a> {
    fn new(engine: &'a Engine, mesh: &'a LoadedMesh, job: &Job) -> Result<Self> {
        check_job(engine, mesh, job)?;
        super::limits(engine, mesh, job)?;
        super::check::check_job(engine, mesh, job, None)?;
        let capacity = super::stage::unit_capacity(mesh);
        let mut log = scratch_log();
        let (placed, images) = place_and_load(engine, mesh, job, capacity, &mut log)?;
        let ucx = Cx {
            engine,
            mesh,
            job: &placed.job,
        };
        let canvas = Canvas::new(ucx, &images, false, None, &mut log)?;
        let canvas = canvas.with_rows(&engine.ctx.device, capacity + 1);
        let slots = Slots::with_units(engine, mesh, capacity);
        let n = placed.job.layers.len();
        let maps = maps::compute(ucx, &placed, &slots, 0..n, &canvas.global, &mut log)
            .map_err(|e| placed.rename(e))?;
        let stats = super::select::select(ucx, &canvas, (&slots, &maps), &placed, &mut log)?;
        let stride = canvas.stats_stride as usize;
        let rows = stats[..n * stride].to_vec();
        let at = (&rows[..], None);
        compose::compose(
            ucx,
            &images,
            &canvas,
            &slots,
            &maps,
            at,
            &placed,
            compose::Passes::Colour,
            &mut log,
        )?;
        let units = (0..n).map(|k| UnitMap::of(&maps, k)).collect();
        let encoded = finish::pad_and_encode(ucx, &canvas, (true, false), &mut log)?;
        let texture = output_texture(engine, job);
        let live = Self {
            engine,
            mesh,
            job: job.clone(),
            placed,
            images,
            canvas,
            slots,
            capacity,
            units,
            rows,
            encoded,
            texture,
            texels: vec![0; job.width as usize * job.height as usize * 4],
            pending: vec![[0, 0, job.width, job.height]],
            failed: false,
        };
        live.copy_to_texture(&[[0, 0, job.width, job.height]])?;
        Ok(live)
    }

    /// The job as edited so far.
    pub fn job(&self) -> &Job {
        &self.job
    }

    /// The baked texture, kept current by every edit: `Rgba8UnormSrgb` for an 8-bit job,
    /// `Rgba16Uint` holding the sRGB-encoded values for a 16-bit one (the PNG's values; a
    /// 16-bit normalized format is an optional feature of wgpu).
    pub fn texture(&self) -> &wgpu::Texture {
        &self.texture
    }

    /// The texels (4 values a texel, sRGB-encoded, at the job's bit depth, as
    /// [`crate::Baked::texels`]), reading back only the regions the edits since the last read
    /// changed.
    pub fn read(&mut self) -> Result<&[u16]> {
        if self.failed {
            return Err(failed());
        }
        let (w, stride) = (self.job.width, self.encoded.stride);
        for r in std::mem::take(&mut self.pending) {
            let (offset, size) = (
                r[1] as u64 * stride as u64 * 4,
                r[3] as u64 * stride as u64 * 4,
            );
            let bytes = self.engine.ctx.read_buffer_range(
                &self.encoded.packed,
                offset,
                size,
                "live read-back",
            )?;
            let words: &[u32] = bytemuck::cast_slice(&bytes);
            let depth = self.job.bit_depth;
            // Whole rows: the packed words of a row start at its first texel.
            let rows = [0, r[1], w, r[3]];
            super::engine::unpack_rows(&mut self.texels, w, rows, words, stride, depth);
        }
        Ok(&self.texels)
    }

    /// Applies `edit`: re-computes only the changed layer's map and re-composes only the cells
    /// its old and new footprints touch. On an error (a layer that misses the mesh, a field a
    /// live bake does not take) the bake is left as it was.
    pub fn apply(&mut self, edit: Edit) -> Result<EditReport> {
        if self.failed {
            return Err(failed());
        }
        let (engine, mesh) = (self.engine, self.mesh);
        let mut report = EditReport::default();
        let t = Instant::now();
        let (job, old_of, fresh, mut touched) = self.edited(edit)?;
        let mut log = scratch_log();
        let (placed, images) = place_and_load(engine, mesh, &job, self.capacity, &mut log)?;
        report.place_ms = ms(t);

        let t = Instant::now();
        let fresh = self.company(&placed, &old_of, fresh);
        let solved = self.fresh_maps(&placed, &fresh, &mut log)?;
        report.maps = fresh.len();
        // Re-solved units clear their old footprints too, and so does a kept layer whose vector
        // image changed size (the bake's vector images share one pixel budget).
        touched.extend(fresh.iter().filter_map(|&u| old_of[u]));
        for (j, o) in old_of.iter().enumerate() {
            if let Some(o) = *o {
                if self.placed.job.layers[o].raster != placed.job.layers[j].raster {
                    touched.push(o);
                }
            }
        }
        let dirty = self.dirty_cells(&touched, &solved.2);
        report.maps_ms = ms(t);
        // From here on the kept GPU state changes: a failure leaves the bake unusable.
        let out = self.commit(
            (job, placed, images),
            (&old_of, &fresh, &solved),
            &dirty,
            &mut log,
        );
        if out.is_err() {
            self.failed = true;
        }
        let (layout_ms, (cells, drawn), compose_ms, encode_ms) = out?;
        report.maps_ms += layout_ms;
        (report.cells, report.layers_drawn) = (cells, drawn);
        (report.compose_ms, report.encode_ms) = (compose_ms, encode_ms);
        Ok(report)
    }

    /// The GPU side of an edit: the new layout of the slots, the re-compose of the `dirty` cells
    /// and their encode; then the edited job, units and rows become the bake's. Returns the
    /// milliseconds of the layout, (cells, layers drawn), the compose's and the encode's.
    #[allow(clippy::type_complexity)]
    fn commit(
        &mut self,
        (job, placed, images): (Job, Placed, Images),
        (old_of, fresh, solved): (&[Option<usize>], &[usize], &(Slots, LayerMaps, Vec<i32>)),
        dirty: &[u32],
        log: &mut Log,
    ) -> Result<(f64, (u32, usize), f64, f64)> {
        let t = Instant::now();
        let (slots, units, rows) = self.relayout(old_of, fresh, solved)?;
        let layout_ms = ms(t);
        let t = Instant::now();
        let target = slots.as_ref().unwrap_or(&self.slots);
        let layout = (target, &units[..], &rows[..]);
        let (regions, drawn) = self.recompose((&placed, &images), layout, dirty, log)?;
        let cells = dirty.iter().map(|w| w.count_ones()).sum();
        let compose_ms = ms(t);
        let t = Instant::now();
        self.encode(&placed.job, &regions, log)?;
        let encode_ms = ms(t);
        if let Some(s) = slots {
            self.slots = s;
        }
        (self.job, self.placed, self.images, self.units, self.rows) =
            (job, placed, images, units, rows);
        Ok((layout_ms, (cells, drawn), compose_ms, encode_ms))
    }

    /// The cells to re-compose (a cell mask, as a stats row's): the footprints of the old units
    /// `touched` and of the fresh units (`fresh_rows`: their stats rows).
    fn dirty_cells(&self, touched: &[usize], fresh_rows: &[i32]) -> Vec<u32> {
        let stride = self.canvas.stats_stride as usize;
        let counters = super::canvas::STATS_COUNTERS as usize;
        let mut dirty = vec![0u32; stride - counters];
        let old = touched
            .iter()
            .map(|&u| &self.rows[u * stride..(u + 1) * stride]);
        for row in old.chain(fresh_rows.chunks_exact(stride)) {
            for (d, m) in dirty.iter_mut().zip(&row[counters..]) {
                *d |= *m as u32;
            }
        }
        dirty
    }

    /// The units' new layout: kept units from their old slot, fresh ones from the scratch chunk
    /// that `solved` holds (its slots, maps and stats rows), each copied to its new index. Returns
    /// new slots where units moved (`None`: the kept slots, fresh units copied into them), every
    /// unit's map and every unit's stats row.
    #[allow(clippy::type_complexity)]
    fn relayout(
        &self,
        old_of: &[Option<usize>],
        fresh: &[usize],
        (scratch, maps, stats): &(Slots, LayerMaps, Vec<i32>),
    ) -> Result<(Option<Slots>, Vec<UnitMap>, Vec<i32>)> {
        let stride = self.canvas.stats_stride as usize;
        let n = old_of.len();
        let moved = old_of
            .iter()
            .enumerate()
            .any(|(j, o)| o.is_some_and(|o| o != j));
        let slots = moved.then(|| Slots::with_units(self.engine, self.mesh, self.capacity));
        let target = slots.as_ref().unwrap_or(&self.slots);
        let (mut rows, mut units, mut copies) = (vec![0i32; n * stride], Vec::new(), Vec::new());
        for (j, old) in old_of.iter().enumerate() {
            let (from, src, mut unit, row) = match fresh.iter().position(|&u| u == j) {
                Some(k) => (
                    k,
                    scratch,
                    UnitMap::of(maps, k),
                    &stats[k * stride..][..stride],
                ),
                None => {
                    let o = old.expect("a unit is kept or fresh");
                    let row = &self.rows[o * stride..][..stride];
                    (o, &self.slots, self.units[o].clone(), row)
                }
            };
            if !std::ptr::eq(src, target) || from != j {
                copies.push((src, from, j));
            }
            rows[j * stride..][..stride].copy_from_slice(row);
            (unit.params.slot, unit.params.aux) = (j as u32, j as u32);
            units.push(unit);
        }
        self.copy_slots(target, &copies)?;
        Ok((slots, units, rows))
    }

    /// Resets the `dirty` cells to the base and composes every unit there, in job order, from
    /// the layout (slots, maps, stats rows) at the places the whole job's plan gives them.
    /// Returns the cells as texel regions and the units drawn.
    fn recompose(
        &self,
        (placed, images): (&Placed, &Images),
        (slots, units, rows): (&Slots, &[UnitMap], &[i32]),
        dirty: &[u32],
        log: &mut Log,
    ) -> Result<(Vec<[u32; 4]>, usize)> {
        let (engine, canvas) = (self.engine, &self.canvas);
        let (grid, stride) = (canvas.grid, canvas.stats_stride as usize);
        let counters = super::canvas::STATS_COUNTERS as usize;
        let mask: Vec<i32> = dirty.iter().map(|&w| w as i32).collect();
        let [w, h] = canvas.global.tex_size;
        let regions: Vec<[u32; 4]> = plan_cells(&mask, grid, CELL, [w, h], u32::MAX)
            .iter()
            .map(|r| r.map(|v| v as u32))
            .collect();
        if regions.is_empty() {
            return Ok((regions, 0));
        }
        canvas.fill_base_regions(engine, &images.base, &regions, log)?;
        let at = (self.capacity * stride + counters) * 4;
        let queue = &engine.ctx.queue;
        queue.write_buffer(&canvas.stats, at as u64, bytemuck::cast_slice(dirty));
        let params: Vec<Params> = units.iter().map(|u| u.params).collect();
        let all = LayerMaps {
            range: 0..units.len(),
            buffer: params_buffer(&engine.ctx.device, "bake.layer_params", &params),
            params,
            expmap: units.iter().map(|u| u.expmap).collect(),
            chart: units.iter().map(|u| u.chart).collect(),
            ribbon: units.iter().map(|u| u.ribbon.clone()).collect(),
            reach: units.iter().map(|u| u.reach.clone()).collect(),
        };
        let drawn = rows
            .chunks_exact(stride)
            .filter(|row| {
                row[counters..]
                    .iter()
                    .zip(dirty)
                    .any(|(a, b)| *a as u32 & b != 0)
            })
            .count();
        let cx = Cx {
            engine,
            mesh: self.mesh,
            job: &placed.job,
        };
        let d = Dirty { mask: dirty, grid };
        let at = (rows, Some(&d));
        let colour = compose::Passes::Colour;
        compose::compose(cx, images, canvas, slots, &all, at, placed, colour, log)?;
        Ok((regions, drawn))
    }

    /// Pads and encodes the re-composed `cells` and the texels their padding reaches into the
    /// kept encoded texture, copies them into the texture and notes them for [`LiveBake::read`].
    fn encode(&mut self, job: &Job, cells: &[[u32; 4]], log: &mut Log) -> Result<()> {
        let regions = padded_regions(job, cells);
        if regions.is_empty() {
            return Ok(());
        }
        let cx = Cx {
            engine: self.engine,
            mesh: self.mesh,
            job,
        };
        let e = (&self.encoded, &regions[..]);
        finish::encode_regions(cx, &self.canvas, (true, false), e, log)?;
        self.copy_to_texture(&regions)?;
        self.pending.extend(regions);
        if self.pending.len() > 64 {
            // A host that never reads: one band of rows covers them all.
            let y0 = self.pending.iter().map(|r| r[1]).min().unwrap_or(0);
            let y1 = self.pending.iter().map(|r| r[1] + r[3]).max().unwrap_or(0);
            self.pending = vec![[0, y0, job.width, y1 - y0]];
        }
        Ok(())
    }

    /// The edited job; per new unit, the old unit it keeps (`None`: fresh); the fresh units; the
    /// old units whose footprints the edit clears.
    #[allow(clippy::type_complexity)]
    fn edited(&self, edit: Edit) -> Result<(Job, Vec<Option<usize>>, Vec<usize>, Vec<usize>)> {
        let mut job = self.job.clone();
        let n = job.layers.len();
        let mut old_of: Vec<Option<usize>> = (0..n).map(Some).collect();
        let out_of_range = |field: &str, i: usize, n: usize| Error::Job {
            path: self.job.source.clone(),
            field: field.into(),
            detail: format!("layer {i} does not exist: the job has {n} layers"),
        };
        let (fresh, touched) = match edit {
            Edit::Set { layer, to } => {
                if layer >= n {
                    return Err(out_of_range("layers", layer, n));
                }
                check_layer(&job, layer, &to)?;
                job.layers[layer] = *to;
                old_of[layer] = None;
                (vec![layer], vec![layer])
            }
            Edit::Add { at, layer } => {
                if at > n {
                    return Err(out_of_range("layers", at, n));
                }
                if n + 1 > self.capacity {
                    return Err(Error::Job {
                        path: self.job.source.clone(),
                        field: "layers".into(),
                        detail: format!(
                            "a live bake on this mesh holds at most {} layers",
                            self.capacity
                        ),
                    });
                }
                check_layer(&job, at, &layer)?;
                job.layers.insert(at, *layer);
                old_of.insert(at, None);
                (vec![at], vec![])
            }
            Edit::Remove { layer } => {
                if layer >= n {
                    return Err(out_of_range("layers", layer, n));
                }
                job.layers.remove(layer);
                old_of.remove(layer);
                (vec![], vec![layer])
            }
            Edit::Reorder { from, to } => {
                if from >= n || to >= n {
                    return Err(out_of_range("layers", from.max(to), n));
                }
                let l = job.layers.remove(from);
                job.layers.insert(to, l);
                let o = old_of.remove(from);
                old_of.insert(to, o);
                (vec![], vec![from])
            }
        };
        Ok((job, old_of, fresh, touched))
    }

    /// The fresh units with the company their batch needs to solve as in a full bake (see the
    /// module's documentation), ascending. `old_of`: per unit of `placed`, the old unit it keeps.
    fn company(
        &self,
        placed: &Placed,
        old_of: &[Option<usize>],
        mut fresh: Vec<usize>,
    ) -> Vec<usize> {
        let (engine, layers) = (self.engine, &placed.job.layers);
        let old_layers = &self.placed.job.layers;
        let with = |ls: &[Layer], f: &dyn Fn(&dyn crate::maps::MapMethod) -> bool| -> Vec<usize> {
            (0..ls.len()).filter(|&u| f(method(ls[u].method))).collect()
        };
        // Whether a batch's members changed: the kept members' old indices against the old ones.
        let changed = |now: &[usize], before: &[usize]| {
            let kept: Vec<Option<usize>> = now.iter().map(|&u| old_of[u]).collect();
            kept.len() != before.len() || kept.iter().zip(before).any(|(k, b)| *k != Some(*b))
        };
        let is_chart = |m: &dyn crate::maps::MapMethod| m.uses_expmap() && m.solves_chart();
        let (charts, charts_before) = (with(layers, &is_chart), with(old_layers, &is_chart));
        let packs = |n: usize| {
            !engine.stage_paths.charts_on_cpu(engine)
                && crate::solve::gpu::Packing::Auto.packs(&engine.ctx, n)
        };
        if (packs(charts.len()) || packs(charts_before.len())) && changed(&charts, &charts_before) {
            fresh.extend(&charts);
        }
        let uses = |m: &dyn crate::maps::MapMethod| m.uses_expmap();
        let (maps, maps_before) = (with(layers, &uses), with(old_layers, &uses));
        let cpu_adapter = engine.ctx.device_type == Some(wgpu::DeviceType::Cpu)
            && crate::maps::expmap::gpu::SPREAD_MIN_CANDIDATES_OVERRIDE
                .load(std::sync::atomic::Ordering::Relaxed)
                == 0;
        // A map alone in its batch may be spread over workgroups (GPU path, GPU adapter).
        if !engine.stage_paths.expmap_on_cpu(engine) && !cpu_adapter {
            if (maps.len() == 1 || maps_before.len() == 1) && changed(&maps, &maps_before) {
                fresh.extend(&maps);
            }
            let alone = fresh.iter().filter(|u| maps.contains(u)).count() == 1;
            if alone && maps.len() > 1 {
                if let Some(&other) = maps.iter().find(|u| !fresh.contains(u)) {
                    fresh.push(other);
                }
            }
        }
        fresh.sort_unstable();
        fresh.dedup();
        fresh
    }

    /// The maps and selections of `fresh` (units of `placed`) in a chunk of their own: its slots,
    /// the maps and the stats rows (one per fresh unit).
    fn fresh_maps(
        &self,
        placed: &Placed,
        fresh: &[usize],
        log: &mut Log,
    ) -> Result<(Slots, LayerMaps, Vec<i32>)> {
        let (engine, mesh) = (self.engine, self.mesh);
        let sub = subset(placed, fresh);
        let cx = Cx {
            engine,
            mesh,
            job: &sub.job,
        };
        let slots = Slots::with_units(engine, mesh, fresh.len().max(1));
        // Errors name the unit's index in this chunk: renamed to name the job's layer.
        let rename = |e: Error| match e {
            Error::Placement {
                path,
                layer,
                detail,
            } if layer < fresh.len() => Error::Placement {
                path,
                layer: fresh[layer],
                detail,
            },
            Error::Job {
                path,
                field,
                detail,
            } => {
                let index = field
                    .strip_prefix("layers[")
                    .and_then(|r| r.split_once(']'))
                    .and_then(|(k, rest)| Some((k.parse::<usize>().ok()?, rest)));
                let field = match index {
                    Some((k, rest)) if k < fresh.len() => format!("layers[{}]{rest}", fresh[k]),
                    _ => field,
                };
                Error::Job {
                    path,
                    field,
                    detail,
                }
            }
            other => other,
        };
        if fresh.is_empty() {
            let maps = LayerMaps {
                range: 0..0,
                params: Vec::new(),
                buffer: params_buffer(&engine.ctx.device, "bake.layer_params", &[]),
                expmap: Vec::new(),
                chart: Vec::new(),
                ribbon: Vec::new(),
                reach: Vec::new(),
            };
            return Ok((slots, maps, Vec::new()));
        }
        let global = self.canvas.global;
        let maps = maps::compute(cx, &sub, &slots, 0..fresh.len(), &global, log).map_err(rename)?;
        let canvas = self.canvas.with_rows(&engine.ctx.device, fresh.len());
        let stats =
            super::select::select(cx, &canvas, (&slots, &maps), &sub, log).map_err(rename)?;
        Ok((slots, maps, stats))
    }

    /// Copies units' coordinates and triangle lists: (from slots, from unit, to unit) into
    /// `target`.
    fn copy_slots(&self, target: &Slots, copies: &[(&Slots, usize, usize)]) -> Result<()> {
        if copies.is_empty() {
            return Ok(());
        }
        let g = &self.mesh.gpu;
        let (cb, lb) = (g.vertex_count as u64 * 16, g.triangle_count as u64 * 4);
        let ctx = &self.engine.ctx;
        ctx.scoped("live slots", || {
            let mut enc = ctx.device.create_command_encoder(&Default::default());
            for &(src, from, to) in copies {
                let (from, to) = (from as u64, to as u64);
                enc.copy_buffer_to_buffer(&src.coords, from * cb, &target.coords, to * cb, cb);
                enc.copy_buffer_to_buffer(&src.lists, from * lb, &target.lists, to * lb, lb);
            }
            ctx.queue.submit([enc.finish()]);
        })
    }

    /// Copies `regions` of the encoded texture into [`LiveBake::texture`].
    fn copy_to_texture(&self, regions: &[[u32; 4]]) -> Result<()> {
        let ctx = &self.engine.ctx;
        let bpp = if self.job.bit_depth == 16 { 8 } else { 4 };
        let stride = self.encoded.stride as u64 * 4;
        ctx.scoped("live texture", || {
            let mut enc = ctx.device.create_command_encoder(&Default::default());
            for r in regions {
                enc.copy_buffer_to_texture(
                    wgpu::TexelCopyBufferInfo {
                        buffer: &self.encoded.packed,
                        layout: wgpu::TexelCopyBufferLayout {
                            offset: r[1] as u64 * stride + r[0] as u64 * bpp,
                            bytes_per_row: Some(stride as u32),
                            rows_per_image: Some(r[3]),
                        },
                    },
                    wgpu::TexelCopyTextureInfo {
                        texture: &self.texture,
                        mip_level: 0,
                        origin: wgpu::Origin3d {
                            x: r[0],
                            y: r[1],
                            z: 0,
                        },
                        aspect: wgpu::TextureAspect::All,
                    },
                    wgpu::Extent3d {
                        width: r[2],
                        height: r[3],
                        depth_or_array_layers: 1,
                    },
                );
            }
            ctx.queue.submit([enc.finish()]);
        })
    }
}

/// Places `job` and loads its images, as a bake does (vector images at the sizes their maps
/// need), refusing a layer of more than one unit and more units than the slots hold.
fn place_and_load(
    engine: &Engine,
    mesh: &LoadedMesh,
    job: &Job,
    capacity: usize,
    log: &mut Log,
) -> Result<(Placed, Images)> {
    let cx = Cx { engine, mesh, job };
    let mut placed = place::place(cx, log)?;
    if let Some(i) = placed.units_of.iter().position(|r| r.len() != 1) {
        return Err(refuse(
            job,
            &format!("layers[{i}]"),
            "a layer of several units (an animated ribbon)",
        ));
    }
    if placed.job.layers.len() > capacity {
        return Err(Error::Job {
            path: job.source.clone(),
            field: "layers".into(),
            detail: format!("a live bake on this mesh holds at most {capacity} layers"),
        });
    }
    let job = &*super::vector::set_rasters(engine, mesh, job, &mut placed, log);
    let images = images::load(engine, mesh, job)?.for_units(&placed.origin);
    Ok((placed, images))
}

/// The texel regions an edit of `cells` re-encodes: each grown by the padding radius (the
/// background texels whose nearest island texel may lie in it), clipped to the texture; the
/// whole texture for `"padding": "full"`.
fn padded_regions(job: &Job, cells: &[[u32; 4]]) -> Vec<[u32; 4]> {
    let r = finish::padding_radius(job.padding);
    let (w, h) = (job.width, job.height);
    if cells.is_empty() {
        return Vec::new();
    }
    if r == u32::MAX {
        return vec![[0, 0, w, h]];
    }
    cells
        .iter()
        .map(|c| {
            let (x0, y0) = (c[0].saturating_sub(r), c[1].saturating_sub(r));
            let x1 = (c[0] + c[2]).saturating_add(r).min(w);
            let y1 = (c[1] + c[3]).saturating_add(r).min(h);
            [x0, y0, x1 - x0, y1 - y0]
        })
        .collect()
}

/// The texture a live bake keeps current.
fn output_texture(engine: &Engine, job: &Job) -> wgpu::Texture {
    engine.ctx.device.create_texture(&wgpu::TextureDescriptor {
        label: Some("decalbake.live"),
        size: wgpu::Extent3d {
            width: job.width,
            height: job.height,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: if job.bit_depth == 16 {
            wgpu::TextureFormat::Rgba16Uint
        } else {
            wgpu::TextureFormat::Rgba8UnormSrgb
        },
        usage: wgpu::TextureUsages::TEXTURE_BINDING
            | wgpu::TextureUsages::COPY_SRC
            | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    })
}
