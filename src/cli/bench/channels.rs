// SPDX-License-Identifier: MIT OR Apache-2.0
//! `decalbake bench --channels`: what PBR channels add to a bake. The same planar decals (the
//! largest `--decals` value, default 256, [`random_job`]'s positions and colour images) on
//! `--mesh` (default the bundled bob) at each of `--sizes` (default 2048 and 4096), in two
//! variants: colour only, and colour + normal + roughness + metallic (a dome bump written here as
//! an 8-bit RGB normal map, `n * 0.5 + 0.5`; roughness 0.3; metallic 1.0), which bakes two more
//! textures (`orm`, `normal`): drawn and composed beside the colour in one pass where the device
//! holds the attachments (the report's `paths.channels`, printed in each line as `channels`),
//! else by a raster and compose pass each over the colour's maps. Both variants keep their
//! buffers between bakes ([`KEPT_BUFFERS`]).
//!
//! Each variant is baked once cold, then `--reps` times, the variants in turn; the wall time of
//! [`Engine::bake_with_progress`] (the bake, with a callback that notes when each stage starts)
//! and the process's CPU time over it (lavapipe's threads included: what a shared machine's load
//! inflates less than the wall time), the median of the report's stage timings, and the progress split of the compose stage: from
//! `"canvas"` to the first chunk (the canvases and, per channel pass, each layer's channel image
//! made on the CPU and uploaded) and from the first chunk to `"padding and encode"` (maps,
//! selection, raster and compose of every pass). One JSON line per size and variant through
//! `emit`, one per size with the ratio full / colour (the spec's target: at most 2), and a table
//! through `table`.

use super::common::{median, random_job};
use decalbake::bake::report::Timings;
use decalbake::io::channels::{Channel, Channels, DataBlend, Normal, NormalBlend, Value};
use decalbake::{Engine, Job, LoadedMesh};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::Instant;

/// Options of `decalbake bench --channels`.
pub struct ChannelBenchOptions {
    /// The mesh.
    pub mesh: PathBuf,
    /// Texture sides.
    pub sizes: Vec<u32>,
    /// Decals in each bake.
    pub decals: usize,
    /// Timed repetitions per variant (median reported).
    pub reps: usize,
    /// Both variants with `texture.sampling` adaptive (four samples a pixel, once a texel and
    /// triangle).
    pub adaptive: bool,
}

/// Side of the normal map the bench writes.
const NORMAL_SIDE: u32 = 256;
/// Roughness of the full variant's decals.
const ROUGHNESS: f32 = 0.3;
/// Metallic of the full variant's decals.
const METALLIC: f32 = 1.0;

/// One timed bake: wall time, the process's CPU time (user + system, all threads: lavapipe's
/// too; NaN off Linux), the report's timings, and the progress split (ms).
struct Sample {
    wall_ms: f64,
    cpu_ms: f64,
    timings: Timings,
    setup_ms: f64,
    chunks_ms: f64,
    textures: Vec<&'static str>,
    /// How the channels were drawn (the report's `paths.channels`).
    channels: &'static str,
    /// How the layers were sampled (the report's `paths.sampling`).
    sampling: &'static str,
}

/// One variant's figures at one size.
struct Row {
    name: &'static str,
    cold_ms: f64,
    samples: Vec<Sample>,
}

impl Row {
    fn med(&self, f: impl Fn(&Sample) -> f64) -> f64 {
        median(self.samples.iter().map(f).collect())
    }
}

/// Runs the benchmark: JSON lines through `emit`, the table's lines through `table`.
pub fn run(
    engine: &Engine,
    opts: &ChannelBenchOptions,
    mut emit: impl FnMut(serde_json::Value),
    mut table: impl FnMut(&str),
) -> anyhow::Result<()> {
    // Both variants keep their buffers between bakes: the full material's four canvases at
    // 4096² (1 GiB of planes and 256 MiB of encodes) do not fit the engine's default pool, and
    // the comparison would otherwise time fresh allocations (page faults) against reused ones.
    engine.keep_buffers(KEPT_BUFFERS);
    let out = super::common::in_scratch("channels", |dir| {
        run_in(engine, opts, dir, &mut emit, &mut table)
    });
    engine.keep_buffers(Engine::DEFAULT_KEPT_BUFFERS);
    out
}

/// The buffers the bench keeps between bakes: the full variant's at 4096², twice over.
const KEPT_BUFFERS: u64 = 3 << 30;

/// [`run`] with its scratch folder `dir`.
fn run_in(
    engine: &Engine,
    opts: &ChannelBenchOptions,
    dir: &Path,
    emit: &mut dyn FnMut(serde_json::Value),
    table: &mut dyn FnMut(&str),
) -> anyhow::Result<()> {
    let mesh = engine.load_mesh(&opts.mesh)?;
    let normal = dir.join("bench_dome_normal.png");
    decalbake::io::image::write_atomic(&normal, &dome_normal_png(NORMAL_SIDE))?;
    table(&format!(
        "decalbake bench --channels: {} decals on {} ({} triangles), {} reps, adapter {}",
        opts.decals,
        opts.mesh.display(),
        mesh.stats.triangles,
        opts.reps.max(1),
        engine.ctx.adapter
    ));
    table("| size | variant | textures | median s | CPU s | cold s | images ms | placement ms | compose ms | of which canvas + channel images ms | maps + raster + compose ms | padding + encode ms | read-back ms |");
    table("|---:|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for &side in &opts.sizes {
        let mut colour = random_job(
            &mesh,
            opts.decals,
            side,
            dir,
            7 + opts.decals as u32,
            "planar",
        )?;
        colour.adaptive = opts.adaptive;
        let full = with_channels(&colour, &normal);
        let mut rows = [
            Row {
                name: "colour",
                cold_ms: timed(engine, &mesh, &colour)?.wall_ms,
                samples: Vec::new(),
            },
            Row {
                name: "full",
                cold_ms: timed(engine, &mesh, &full)?.wall_ms,
                samples: Vec::new(),
            },
        ];
        for _ in 0..opts.reps.max(1) {
            for (row, job) in rows.iter_mut().zip([&colour, &full]) {
                row.samples.push(timed(engine, &mesh, job)?);
            }
        }
        if rows[1].samples[0].textures != ["orm", "normal"] {
            anyhow::bail!(
                "the full variant baked {:?} besides the colour, not orm and normal",
                rows[1].samples[0].textures
            );
        }
        for row in &rows {
            report_row(engine, opts, side, row, emit, table);
        }
        let (c, f) = (rows[0].med(|s| s.wall_ms), rows[1].med(|s| s.wall_ms));
        let stage_ratio = |g: fn(&Sample) -> f64| rows[1].med(g) / rows[0].med(g).max(1e-9);
        let cpu_ratio = stage_ratio(|s| s.cpu_ms);
        emit(serde_json::json!({
            "bench": "channels", "side": side, "decals": opts.decals,
            "ratio_full_over_colour": f / c,
            "ratio_cpu": cpu_ratio,
            "ratio_compose": stage_ratio(|s| s.timings.compose_ms),
            "ratio_padding": stage_ratio(|s| s.timings.padding_ms),
            "target_at_most_2x": f / c <= 2.0,
            "adapter": engine.ctx.adapter,
        }));
        table(&format!(
            "| {side}² | full / colour | | {:.2}× | {:.2}× | | | | {:.2}× | | | {:.2}× | |",
            f / c,
            cpu_ratio,
            stage_ratio(|s| s.timings.compose_ms),
            stage_ratio(|s| s.timings.padding_ms),
        ));
    }
    Ok(())
}

/// Emits one variant's JSON line and table row.
fn report_row(
    engine: &Engine,
    opts: &ChannelBenchOptions,
    side: u32,
    row: &Row,
    emit: &mut dyn FnMut(serde_json::Value),
    table: &mut dyn FnMut(&str),
) {
    let m = |f: fn(&Timings) -> f64| row.med(|s| f(&s.timings));
    let textures = std::iter::once("base_color")
        .chain(row.samples[0].textures.iter().copied())
        .collect::<Vec<_>>();
    emit(serde_json::json!({
        "bench": "channels", "side": side, "decals": opts.decals, "variant": row.name,
        "textures": textures, "channels": row.samples[0].channels,
        "sampling": row.samples[0].sampling,
        "mesh": opts.mesh, "reps": opts.reps.max(1),
        "cold_ms": row.cold_ms, "median_ms": row.med(|s| s.wall_ms),
        "all_ms": row.samples.iter().map(|s| s.wall_ms).collect::<Vec<_>>(),
        "median_cpu_ms": row.med(|s| s.cpu_ms),
        "median_stage_ms": {
            "images": m(|t| t.images_ms), "placement": m(|t| t.placement_ms),
            "compose": m(|t| t.compose_ms), "charts": m(|t| t.charts_ms),
            "padding": m(|t| t.padding_ms), "encode_readback": m(|t| t.encode_ms),
            "canvas_and_channel_images": row.med(|s| s.setup_ms),
            "maps_raster_compose": row.med(|s| s.chunks_ms),
        },
        "adapter": engine.ctx.adapter,
    }));
    table(&format!(
        "| {side}² | {} | {} | {:.2} | {:.2} | {:.2} | {:.0} | {:.0} | {:.0} | {:.0} | {:.0} | {:.0} | {:.0} |",
        row.name,
        textures.join(" + "),
        row.med(|s| s.wall_ms) / 1000.0,
        row.med(|s| s.cpu_ms) / 1000.0,
        row.cold_ms / 1000.0,
        m(|t| t.images_ms),
        m(|t| t.placement_ms),
        m(|t| t.compose_ms),
        row.med(|s| s.setup_ms),
        row.med(|s| s.chunks_ms),
        m(|t| t.padding_ms),
        m(|t| t.encode_ms),
    ));
}

/// Bakes `job` once, noting when the stages start.
fn timed(engine: &Engine, mesh: &LoadedMesh, job: &Job) -> anyhow::Result<Sample> {
    let marks: Mutex<Vec<(String, Instant)>> = Mutex::new(Vec::new());
    let note = |stage: &str| {
        if let Ok(mut m) = marks.lock() {
            m.push((stage.to_string(), Instant::now()));
        }
    };
    let (t, cpu) = (Instant::now(), cpu_ms());
    let baked = engine.bake_with_progress(mesh, job, &note)?;
    let wall_ms = t.elapsed().as_secs_f64() * 1000.0;
    let cpu_ms = cpu_ms() - cpu;
    let marks = marks.into_inner().unwrap_or_default();
    let at = |f: &dyn Fn(&str) -> bool| marks.iter().find(|(s, _)| f(s)).map(|(_, t)| *t);
    let between = |a: Option<Instant>, b: Option<Instant>| match (a, b) {
        (Some(a), Some(b)) => b.duration_since(a).as_secs_f64() * 1000.0,
        _ => f64::NAN,
    };
    let canvas = at(&|s| s == "canvas");
    let chunks = at(&|s| s.starts_with("maps"));
    let padding = at(&|s| s == "padding and encode");
    Ok(Sample {
        wall_ms,
        cpu_ms,
        setup_ms: between(canvas, chunks),
        chunks_ms: between(chunks, padding),
        textures: baked.channels.iter().map(|c| c.kind.name()).collect(),
        channels: baked.report.paths.channels,
        sampling: baked.report.paths.sampling,
        timings: baked.report.timings,
    })
}

/// The process's CPU time so far, user + system, in ms (from `/proc/self/stat`, at 100 ticks a
/// second), or NaN where that cannot be read. On a machine shared with other work the wall time
/// grows with the load; the CPU time much less.
fn cpu_ms() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return f64::NAN;
    };
    // Fields after the command name (which may hold spaces), from the state (field 3) on.
    let rest = stat.rsplit_once(')').map_or("", |(_, r)| r);
    let f: Vec<f64> = rest
        .split_whitespace()
        .skip(11)
        .take(2)
        .filter_map(|v| v.parse().ok())
        .collect();
    match f[..] {
        [user, system] => (user + system) * 10.0,
        _ => f64::NAN,
    }
}

/// `job` with every layer painting the normal map `normal`, roughness [`ROUGHNESS`] and metallic
/// [`METALLIC`] at the layer's opacity (what a job file's `"normal"`, `"roughness"` and
/// `"metallic"` give).
fn with_channels(job: &Job, normal: &Path) -> Job {
    let mut full = job.clone();
    for l in &mut full.layers {
        let constant = |v: f32| Channel {
            value: Value::Constant([v; 3]),
            opacity: l.opacity,
        };
        l.channels = Channels {
            normal: Some(Normal {
                image: normal.to_path_buf(),
                y_down: false,
                blend: NormalBlend::Rnm,
                opacity: l.opacity,
            }),
            roughness: Some(constant(ROUGHNESS)),
            metallic: Some(constant(METALLIC)),
            occlusion: None,
            emissive: None,
            data_blend: DataBlend::Normal,
        };
    }
    full
}

/// An 8-bit RGB PNG of a dome's tangent-space normals (glTF's convention: green up the image),
/// `n * 0.5 + 0.5`: a spherical cap over the inner 0.8 of the image, flat outside.
fn dome_normal_png(side: u32) -> Vec<u8> {
    use image::ImageEncoder;
    let mut raw = Vec::with_capacity((side * side * 3) as usize);
    for y in 0..side {
        for x in 0..side {
            let (s, t) = (
                (x as f32 + 0.5) / side as f32 - 0.5,
                0.5 - (y as f32 + 0.5) / side as f32,
            );
            // A cap of the sphere of radius 0.6 through the circle of radius 0.4.
            let n = match s * s + t * t < 0.16 {
                true => glam::Vec3::new(s, t, (0.36 - s * s - t * t).sqrt()).normalize(),
                false => glam::Vec3::Z,
            };
            raw.extend(
                (n * 0.5 + 0.5)
                    .to_array()
                    .map(|c| (c * 255.0).round() as u8),
            );
        }
    }
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new(&mut out)
        .write_image(&raw, side, side, image::ExtendedColorType::Rgb8)
        .expect("PNG encoding into memory cannot fail for a well-formed buffer");
    out
}
