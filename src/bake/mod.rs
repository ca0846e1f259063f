// SPDX-License-Identifier: MIT OR Apache-2.0
//! The bake: layers placed, mapped, rasterized at their global UVs and composed into the texture,
//! then padding and encoding, all on the GPU. `run` names the stages in order; each is a module:
//!
//! 0. `check`: the job against the mesh and the device's limits;
//! 1. `images`: base, layer images and masks decoded and uploaded;
//! 2. [`place`]: every layer placed in one submission, its kind ([`kinds`]) makes its frame;
//! 3. `canvas`: the accumulation image filled with the base, the mesh's islands (`islands`);
//!
//! then, per chunk of layers that fits the memory budget (`maps::Slots`):
//!
//! 4. `maps`: each layer's local coordinates, by its method's plug-in;
//! 5. [`select`]: the triangles each layer covers and the texture cells they touch;
//! 6. `compose`: raster jobs planned ([`plan`]), drawn into atlas targets and composed in job
//!    order;
//!
//! and last:
//!
//! 7. `finish`: padding from the islands' distance transform and sRGB encoding, in one pass.
//!
//! A texture whose canvas does not fit one storage buffer (8192² and up on lavapipe), a job that
//! asks for tiles (`texture.tile`) and a float (EXR) output are baked by `tiles`: stages 2 to 7
//! per tile window, padding on the CPU over the assembled texture.
//!
//! The engine ([`Engine`]: device, pipelines, pooled targets) and the loaded mesh ([`LoadedMesh`]:
//! GPU buffers and per-mesh caches) are in `engine`; [`cpu`] is the CPU twin of the whole bake.
pub(crate) mod bands;
pub mod blend;
mod canvas;
pub mod channels;
mod check;
mod compose;
pub mod cpu;
pub mod cpu_tools;
mod engine;
mod finish;
mod images;
pub(crate) use images::checked_image;
mod islands;
pub mod kinds;
mod live;
mod maps;
pub mod memory;
mod param;
pub mod params;
pub mod place;
pub mod plan;
pub mod report;
pub mod select;
pub mod sets;
mod stage;
pub(crate) mod tiles;
pub mod tools;
mod transfer;
mod vector;
pub mod vector_gpu;
mod vector_maps;

pub use engine::{
    Baked, BakedChannel, BakedTextures, BvhBuild, Engine, LoadedMesh, StagePath, StagePaths,
};
pub(crate) use finish::Finished;
pub use images::{f32_to_f16, load_raw, upload_image};
pub use live::{Edit, EditReport, LiveBake};
pub use param::{size_figures, ParamMap, ParamRow, SizeFigures};
pub use place::Units;
pub(crate) use tiles::tile_shape;

use crate::error::Result;
use crate::io::job::Job;
use report::{LayerReport, Report, Timings};
use stage::{ms, Cx, Log};
use std::time::Instant;

/// A bake before read-back: the encoded texture (on the GPU, or on the CPU where padding ran
/// there) and the report.
pub(crate) struct Run {
    pub encoded: finish::Finished,
    /// Each channel pass's encoded texture ([`channels`]), in pass order.
    pub channels: Vec<(channels::ChannelKind, finish::Finished)>,
    /// Each channel pass's canvas, linear RGBA f32 (unpadded), in pass order, for a float (EXR)
    /// output; empty otherwise.
    pub channel_linear: Vec<Vec<f32>>,
    pub report: Report,
    /// The canvas, linear RGBA f32 (unpadded), for a float (EXR) output.
    pub linear: Option<Vec<f32>>,
}

/// The limits checked before any work ([`memory::check`]: sides, estimated memory).
pub(crate) fn limits(engine: &Engine, mesh: &LoadedMesh, job: &Job) -> Result<()> {
    memory::check(engine, mesh, job, false)
}

/// [`limits`] for a bake streamed band by band ([`bake_bands`]), before its file is begun.
pub(crate) fn streamed_limits(engine: &Engine, mesh: &LoadedMesh, job: &Job) -> Result<()> {
    memory::check(engine, mesh, job, true)
}

/// The tile (width, height) of `job` when its bake goes by tiles with a finite padding, so that
/// its bands can be streamed ([`bake_bands`]); `None`: one pass, or `"padding": "full"`.
pub(crate) fn streamed_shape(engine: &Engine, job: &Job) -> Option<[u32; 2]> {
    let shape = tiles::tile_shape(engine, job)?;
    (finish::padding_radius(job.padding) != u32::MAX).then_some(shape)
}

/// Bakes `job` by tiles of `shape`, handing `sink` each band of rows as soon as it is padded
/// ([`bands`]; each band carries every PBR channel's rows too); returns the whole bake's report.
/// The caller has checked [`streamed_limits`] before it began its files.
pub(crate) fn bake_bands(
    engine: &Engine,
    mesh: &LoadedMesh,
    job: &Job,
    shape: [u32; 2],
    on_stage: &dyn Fn(&str),
    sink: &mut dyn FnMut(&bands::Band) -> Result<()>,
) -> Result<Report> {
    bands::bake(engine, mesh, job, shape, on_stage, sink)
}

/// A bake by tiles ([`tiles`]) when `job` needs one (a canvas beyond one storage buffer,
/// `texture.tile`, a float output), else `None`: the engine's one-pass bake follows.
pub(crate) fn tiled(
    engine: &Engine,
    mesh: &LoadedMesh,
    job: &Job,
    on_stage: &dyn Fn(&str),
) -> Option<Result<Baked>> {
    let shape = tiles::tile_shape(engine, job)?;
    Some(tiled_in_memory(engine, mesh, job, shape, on_stage))
}

/// Bakes `job` tile by tile into one texture in memory ([`tiles`]): band by band ([`bands`]) for
/// a finite padding, whole ([`tiles::bake_whole`]) for `"padding": "full"`.
fn tiled_in_memory(
    engine: &Engine,
    mesh: &LoadedMesh,
    job: &Job,
    shape: [u32; 2],
    on_stage: &dyn Fn(&str),
) -> Result<Baked> {
    let (w, h) = (job.width as usize, job.height as usize);
    let mut texels = vec![0u16; w * h * 4];
    let kinds = channels::passes(job);
    let mut planes: Vec<Vec<u16>> = kinds.iter().map(|_| vec![0u16; texels.len()]).collect();
    let mut linear = job.exr().then(|| vec![0f32; texels.len()]);
    let mut floats: Vec<Vec<f32>> = match job.exr() {
        true => kinds.iter().map(|_| vec![0f32; texels.len()]).collect(),
        false => Vec::new(),
    };
    let report = if finish::padding_radius(job.padding) == u32::MAX {
        let dest = tiles::Dest {
            texels: &mut texels[..],
            channels: planes.iter_mut().map(|c| &mut c[..]).collect(),
            linear: linear.as_mut(),
            channel_linear: floats.iter_mut().map(|c| &mut c[..]).collect(),
        };
        tiles::bake_whole(engine, mesh, job, shape, on_stage, dest)?
    } else {
        bands::bake(engine, mesh, job, shape, on_stage, &mut |band| {
            let at = band.y as usize * w * 4;
            texels[at..at + band.texels.len()].copy_from_slice(&band.texels);
            for (all, rows) in planes.iter_mut().zip(&band.channels) {
                all[at..at + rows.len()].copy_from_slice(rows);
            }
            for (all, rows) in floats.iter_mut().zip(&band.channel_linear) {
                all[at..at + rows.len()].copy_from_slice(rows);
            }
            if let (Some(all), Some(rows)) = (linear.as_mut(), &band.linear) {
                all[at..at + rows.len()].copy_from_slice(rows);
            }
            Ok(())
        })?
    };
    let mut floats = floats.into_iter();
    let channels = kinds
        .into_iter()
        .zip(planes)
        .map(|(kind, texels)| BakedChannel {
            kind,
            texels,
            linear: floats.next(),
        })
        .collect();
    Ok(Baked {
        channels,
        width: job.width,
        height: job.height,
        bit_depth: job.bit_depth,
        texels,
        linear,
        report,
    })
}

/// Bakes `job` onto `mesh`, stage by stage, naming each stage to `on_stage` as it starts (a
/// progress display's spinner; chunks of the map stage say which layers they hold).
pub(crate) fn run(
    engine: &Engine,
    mesh: &LoadedMesh,
    job: &Job,
    on_stage: &dyn Fn(&str),
) -> Result<Run> {
    run_in(engine, mesh, job, None, on_stage)
}

/// [`run`] over one window (x, y, w, h) of the texture: the canvas holds only those texels, and
/// the encoded result is the window's, unpadded ([`tiles`] pads the assembled texture);
/// `None`: the whole texture, padded.
pub(crate) fn run_in(
    engine: &Engine,
    mesh: &LoadedMesh,
    job: &Job,
    window: Option<[u32; 4]>,
    on_stage: &dyn Fn(&str),
) -> Result<Run> {
    check::check_job(engine, mesh, job, window)?;
    let mut log = Log {
        timings: Timings {
            load_ms: mesh.timings.0,
            weld_ms: mesh.timings.1,
            upload_ms: mesh.timings.2,
            ..Default::default()
        },
        warnings: check::unpainted(mesh, job),
        commands: 0,
        paths: Default::default(),
    };
    let cx = Cx { engine, mesh, job };
    let t = Instant::now();
    on_stage("placement");
    let mut placed = place::place(cx, &mut log)?;
    log.timings.placement_ms = ms(t);
    // Images after placement: vector images are rendered at the sizes their maps need.
    let t = Instant::now();
    on_stage("images");
    let job = &*vector::set_rasters(engine, mesh, job, &mut placed, &mut log);
    let images = images::load(engine, mesh, job)?;
    log.timings.images_ms = ms(t);
    // From here on the stages work on units (a decal is one, a stroke one per stamp).
    let images = images.for_units(&placed.origin);
    let ucx = Cx {
        engine,
        mesh,
        job: &placed.job,
    };
    let t = Instant::now();
    on_stage("canvas");
    let canvas = canvas::Canvas::new(ucx, &images, !placed.strokes.is_empty(), window, &mut log)?;
    let mut passes = Vec::new();
    for kind in channels::passes(job) {
        let pass = channels::pass(engine, mesh, job, kind, &mut log.warnings)?;
        let c = canvas.channel(ucx, (&pass.base.0, pass.base.1), &mut log)?;
        passes.push((pass, c));
    }
    let units = compose_units(
        ucx,
        &placed,
        &images,
        (&canvas, &passes),
        &mut log,
        on_stage,
    )
    .map_err(|e| placed.rename(e))?;
    engine.ctx.wait("compose")?;
    log.timings.compose_ms = ms(t);

    let t = Instant::now();
    on_stage("padding and encode");
    let encoded = finish::finish(cx, &canvas, (window.is_none(), false), &mut log)?;
    let mut encoded_channels = Vec::with_capacity(passes.len());
    let mut channel_linear = Vec::new();
    for (pass, c) in &passes {
        let pad = (window.is_none(), pass.kind.linear());
        encoded_channels.push((pass.kind, finish::finish(cx, c, pad, &mut log)?));
        if job.exr() {
            channel_linear.push(c.read_linear(engine)?);
        }
        engine.return_buffers([c.acc_rg.clone(), c.acc_ba.clone()]);
    }
    let linear = match job.exr() {
        true => Some(canvas.read_linear(engine)?),
        false => None,
    };
    log.timings.padding_ms = ms(t);
    let stats = canvas.read_stats(engine, "stats read-back")?;
    // Submitted work that reads the planes is queued ahead of any later user's.
    engine.return_buffers([canvas.acc_rg.clone(), canvas.acc_ba.clone()]);
    let mut layers = fold_reports(&placed, units, |u| canvas.row(&stats, u));
    footprints(&mut layers, &mut log.warnings);
    // A stroke's stamps can raise the same warning many times: keep each once, in order.
    let mut seen = std::collections::HashSet::new();
    log.warnings.retain(|w| seen.insert(w.clone()));
    let report = Report {
        version: env!("CARGO_PKG_VERSION"),
        adapter: engine.ctx.adapter.clone(),
        job: job.source.display().to_string(),
        mesh: mesh.stats.clone(),
        uv_set: job.uv_set,
        texture: [job.width, job.height],
        samples: job.ss * job.ss,
        padding: Some(finish::padding_radius(job.padding)).filter(|&p| p != u32::MAX),
        layers,
        island_texels: canvas.islands.count,
        warnings: log.warnings,
        timings: log.timings,
        gpu_commands: log.commands,
        paths: log.paths,
        pipeline_cache: engine.ctx.pipeline_cache.1.name(),
        input_hash: None,
        unwrap: mesh.unwrap.clone(),
        tiles: None,
        tile_size: None,
        streamed: false,
        texture_sets: Vec::new(),
    };
    Ok(Run {
        encoded,
        channels: encoded_channels,
        channel_linear,
        report,
        linear,
    })
}

/// Stages 4 to 6 for every chunk of units: maps, selection, raster and compose, the colour's and
/// then each channel pass's (`passes`, with their canvases) over the same maps and selection.
/// Returns each unit's report (texels covered not yet read back).
fn compose_units(
    cx: Cx<'_>,
    placed: &place::Placed,
    images: &images::Images,
    (canvas, passes): (&canvas::Canvas, &[(channels::Pass, canvas::Canvas)]),
    log: &mut Log,
    on_stage: &dyn Fn(&str),
) -> Result<Vec<LayerReport>> {
    let job = cx.job;
    let slots = maps::Slots::new(cx.engine, cx.mesh, job);
    // `job` holds the units (a stroke's stamps among them): strokes are told by `placed`.
    let fused = !passes.is_empty() && placed.strokes.is_empty() && cx.engine.fuses_channels(job);
    log.paths.channels = match (passes.is_empty(), fused) {
        (true, _) => "none",
        (false, true) => "fused",
        (false, false) => "separate",
    };
    if cx.engine.adaptive_sampling(job) {
        log.paths.sampling = "adaptive";
    }
    let mut units: Vec<LayerReport> = Vec::with_capacity(job.layers.len());
    let starts = tools::chunk_starts(placed);
    for range in slots.chunks(&placed.blocks, &starts) {
        on_stage(&format!(
            "maps, selection and compose: units {}-{} of {}",
            range.start + 1,
            range.end,
            job.layers.len()
        ));
        let maps = maps::compute(cx, placed, &slots, range.clone(), &canvas.global, log)?;
        let stats = select::select(cx, canvas, (&slots, &maps), placed, log)?;
        let first = units.len();
        for i in range {
            let row = canvas.row(&stats, i);
            let r = layer_report(job, i, placed, &maps, row, &mut log.warnings);
            units.push(r);
        }
        let at = (&stats[..], None);
        let which = match fused {
            true => compose::Passes::Fused(passes),
            false => compose::Passes::Colour,
        };
        let d = compose::compose(cx, images, canvas, &slots, &maps, at, placed, which, log)?;
        for (l, d) in units[first..].iter_mut().zip(d) {
            l.distortion = d;
        }
        for (pass, c) in passes.iter().filter(|_| !fused) {
            let at = (&stats[..], None);
            let which = compose::Passes::Channel(pass);
            compose::compose(cx, images, c, &slots, &maps, at, placed, which, log)?;
        }
    }
    Ok(units)
}

/// The job layers' reports from their units' (`row(u)`: unit u's stats row after the bake): a
/// decal's is its unit's; a stroke's adds up its stamps (triangles, texel box, distortion weighted
/// by triangles) and reports the texels the stroke changed, counted when it was applied.
fn fold_reports<'a>(
    placed: &place::Placed,
    units: Vec<LayerReport>,
    row: impl Fn(usize) -> &'a [i32],
) -> Vec<LayerReport> {
    let mut out = Vec::with_capacity(placed.units_of.len());
    for (i, r) in placed.units_of.iter().enumerate() {
        let Some(stroke) = placed.strokes.iter().find(|s| s.layer == i) else {
            let mut l = units[r.start].clone();
            l.index = i;
            l.texels_covered = row(r.start)[5].max(0) as u32;
            out.push(l);
            continue;
        };
        let stamps = &units[r.clone()];
        let drawn = |u: &usize| !placed.hidden[*u] && !placed.sources[*u];
        let Some(first) = r.clone().find(drawn).map(|u| &units[u]) else {
            continue;
        };
        let mut l = first.clone();
        l.index = i;
        l.blend = stroke.blend;
        l.kind = crate::io::job::LayerKind::Stroke;
        l.triangles_covered = stamps.iter().map(|s| s.triangles_covered).sum();
        l.texels_covered = row(r.end - 1)[7].max(0) as u32;
        l.texel_box = stamps
            .iter()
            .fold([i32::MAX, i32::MAX, i32::MIN, i32::MIN], |b, s| {
                [
                    b[0].min(s.texel_box[0]),
                    b[1].min(s.texel_box[1]),
                    b[2].max(s.texel_box[2]),
                    b[3].max(s.texel_box[3]),
                ]
            });
        l.distortion = crate::maps::distortion::Distortion::combine(
            stamps.iter().map(|s| (s.distortion, s.triangles_covered)),
        );
        let mut report = stroke.report.clone();
        report.cg_iterations = stamps
            .iter()
            .filter_map(|s| s.chart.as_ref())
            .map(|c| c.cg_iterations_total as u64)
            .sum();
        l.chart = None;
        l.expmap = None;
        l.stroke = Some(report);
        out.push(l);
    }
    out
}

/// Each layer's footprint counts from its distortion, and a warning for a layer whose map folds
/// (flipped, collapsed or torn triangles where the bake draws it).
fn footprints(layers: &mut [LayerReport], warnings: &mut Vec<String>) {
    for l in layers {
        let d = l.distortion;
        (l.footprint_flipped, l.footprint_collapsed, l.footprint_torn) =
            (d.flipped, d.collapsed, d.torn);
        if d.folds() > 0 {
            warnings.push(format!(
                "layer {}: its map folds where it is drawn: {} flipped, {} collapsed and {} torn of {} triangles (the image is mirrored, squeezed or smeared there); make the decal smaller, move it off the tip or saddle, or try another `method`",
                l.index, d.flipped, d.collapsed, d.torn, l.triangles_covered
            ));
        }
    }
}

/// Layer `i`'s report from its placement, map and selection (stats row `row`); the distortion and
/// texels covered are filled in later. Warns when its exponential map did not converge.
fn layer_report(
    job: &crate::io::job::Job,
    i: usize,
    placed: &place::Placed,
    maps: &maps::LayerMaps,
    row: &[i32],
    warnings: &mut Vec<String>,
) -> LayerReport {
    let k = i - maps.range.start;
    let l = &job.layers[i];
    let expmap = maps.expmap[k].map(|g| crate::maps::expmap::GeoResult {
        triangles_reached: row[6].max(0) as u32,
        ..g
    });
    if let Some(g) = maps.expmap[k] {
        if g.converged == 0 {
            warnings.push(format!(
                "layer {}: the exponential map did not converge in {} sweeps; the decal may be incomplete",
                placed.origin[i].0,
                g.sweeps
            ));
        }
    }
    LayerReport {
        index: i,
        kind: l.kind,
        image: l.image.display().to_string(),
        method: l.method,
        blend: l.blend,
        placement: placed.placements[i],
        distance_moved: placed.placements[i].distance,
        frame: placed.frames[i],
        triangles_covered: row[0].max(0) as u32,
        texels_covered: 0,
        texel_box: [row[1], row[2], row[3], row[4]],
        distortion: Default::default(),
        footprint_flipped: 0,
        footprint_collapsed: 0,
        footprint_torn: 0,
        expmap,
        chart: maps.chart[k],
        ribbon: maps.ribbon[k].clone(),
        raster_px: l.raster,
        stroke: None,
    }
}
