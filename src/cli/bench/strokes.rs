// SPDX-License-Identifier: MIT OR Apache-2.0
//! `decalbake bench --strokes`: a stroke of about `--stamps` stamps (spacing 0.1) along a wave over
//! the top of the mesh (rays from above), per stamp method, against the same number of separate
//! decals at the stroke's stamp points (the baseline measured in the same run) and, within
//! `--cpu-budget`, the CPU twin (`bake::cpu::bake_units_cpu`). One JSON line per configuration:
//! time per stage, stamps per second, charts solved and CG iterations.

use super::common::median;
use decalbake::bake::Engine;
use decalbake::error::Result;
use decalbake::io::image::LinearImage;
use decalbake::io::job::Job;
use decalbake::mesh::Mesh;
use decalbake::place::Query;
use decalbake::LoadedMesh;
use glam::Vec3;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Options of `decalbake bench --strokes`.
pub struct StrokeBenchOptions {
    /// Mesh file (default: the bundled bob).
    pub mesh: Option<PathBuf>,
    /// Midpoint subdivisions (bob twice: 171k triangles).
    pub subdivide: u32,
    /// Texture side.
    pub side: u32,
    /// Stamps wanted.
    pub stamps: usize,
    /// Repetitions (median reported).
    pub reps: usize,
    /// Largest `stamps × side²` for which the CPU twin is timed too.
    pub cpu_budget: u64,
}

/// The stroke's path: the longest run of consecutive hits of 48 rays from above along a wave across
/// the mesh's bounding box (rays through a hole miss), as surface points.
fn path(engine: &Engine, mesh: &LoadedMesh) -> Result<Vec<serde_json::Value>> {
    let (lo, hi) = mesh.mesh.bounds();
    let (c, e) = ((lo + hi) * 0.5, (hi - lo) * 0.5);
    let rays: Vec<Query> = (0..48)
        .map(|k| {
            let t = k as f32 / 47.0;
            let x = c.x + e.x * 0.8 * (2.0 * t - 1.0);
            let z = c.z + e.z * 0.3 * (t * 2.0 * std::f32::consts::PI).sin();
            Query::Ray(Vec3::new(x, hi.y + e.y, z), Vec3::NEG_Y)
        })
        .collect();
    let hits = engine.place(mesh, &rays)?;
    let mut best: Vec<[f32; 3]> = Vec::new();
    let mut run: Vec<[f32; 3]> = Vec::new();
    for h in &hits {
        if h.found == 0 {
            run.clear();
            continue;
        }
        run.push(h.point);
        if run.len() > best.len() {
            best = run.clone();
        }
    }
    Ok(best.into_iter().map(|p| serde_json::json!(p)).collect())
}

/// A job on `mesh` with `layers`, images in `dir`.
fn job(mesh: &LoadedMesh, side: u32, layers: serde_json::Value, dir: &Path) -> Result<Job> {
    let job = serde_json::json!({
        "mesh": mesh.mesh.source, "texture": { "width": side, "height": side, "padding": 16, "samples": 4 },
        "layers": layers, "output": { "texture": null, "report": null }
    });
    Job::parse(&job.to_string(), &dir.join("bench-stroke.json"), dir, dir)
}

/// Median wall time of `reps` bakes (after one cold bake) and the last report.
fn time_bakes(
    engine: &Engine,
    mesh: &LoadedMesh,
    job: &Job,
    reps: usize,
) -> Result<(f64, decalbake::bake::report::Report)> {
    engine.bake(mesh, job)?;
    let mut times = Vec::new();
    let mut last = None;
    for _ in 0..reps.max(1) {
        let t = Instant::now();
        let b = engine.bake(mesh, job)?;
        times.push(t.elapsed().as_secs_f64() * 1000.0);
        last = Some(b.report);
    }
    Ok((median(times), last.expect("one repetition")))
}

/// The stamps of the stroke in a report.
fn l_stamps(report: &decalbake::bake::report::Report) -> usize {
    report.layers[0].stroke.as_ref().map_or(0, |s| s.stamps)
}

/// Runs the benchmark, calling `emit` with one JSON object per configuration.
pub fn run(
    engine: &Engine,
    opts: &StrokeBenchOptions,
    mut emit: impl FnMut(serde_json::Value),
) -> Result<()> {
    let mut mesh = match &opts.mesh {
        Some(p) => Mesh::load(p)?,
        None => Mesh::from_bytes(
            include_bytes!("../../../assets/bob.glb"),
            Path::new("bob.glb (bundled)"),
            None,
        )?,
    };
    for _ in 0..opts.subdivide {
        mesh = mesh.subdivide();
    }
    let loaded = engine.prepare(mesh)?;
    let dir = std::env::temp_dir().join(format!("decalbake-bench-strokes-{}", std::process::id()));
    std::fs::create_dir_all(&dir).map_err(|source| decalbake::Error::Io {
        path: dir.clone(),
        action: "creating",
        source,
    })?;
    let brush = crate::demo::brush(64);
    decalbake::io::image::write_atomic(&dir.join("brush.png"), &brush.encode_png(8))?;
    let pts = path(engine, &loaded)?;
    // Size the stamps so that the stroke has about `stamps` of them at spacing 0.1: a probe stroke
    // measures the path's length on the surface.
    let probe = job(
        &loaded,
        64,
        serde_json::json!([{ "kind": "stroke", "image": "brush.png", "path": pts, "size": [1.0, 1.0], "spacing": 1.0, "method": "planar" }]),
        &dir,
    )?;
    let length = engine.bake(&loaded, &probe)?.report.layers[0]
        .stroke
        .as_ref()
        .map_or(1.0, |s| s.path_length);
    let size = length / (0.1 * opts.stamps as f32);
    let mut decal_times: Vec<(&str, f64)> = Vec::new();
    for (method, continuity) in [("lscm", true), ("lscm", false), ("expmap", false)] {
        let stroke = serde_json::json!([{ "kind": "stroke", "image": "brush.png", "path": pts,
            "size": [size, size], "spacing": 0.1, "flow": 0.6, "method": method, "continuity": continuity }]);
        let sj = job(&loaded, opts.side, stroke, &dir)?;
        let (stroke_ms, report) = time_bakes(engine, &loaded, &sj, opts.reps)?;
        let units = engine.units(&loaded, &sj)?;
        let stamps = l_stamps(&report);
        // The baseline: the same stamps as separate decals at the same points, same method.
        let decals_ms = match decal_times.iter().find(|(m, _)| *m == method) {
            Some(&(_, t)) => t,
            None => {
                let decals: Vec<serde_json::Value> = units
                    .placements
                    .iter()
                    .zip(&units.strokes[0].hidden)
                    .filter(|(_, hidden)| !**hidden)
                    .map(|(p, _)| serde_json::json!({ "image": "brush.png", "at": p.point, "size": [size, size], "method": method, "opacity": 0.6 }))
                    .collect();
                let dj = job(&loaded, opts.side, serde_json::Value::Array(decals), &dir)?;
                let t = time_bakes(engine, &loaded, &dj, opts.reps)?.0;
                decal_times.push((method, t));
                t
            }
        };
        let cpu_ms = (stamps as u64 * (opts.side as u64).pow(2) <= opts.cpu_budget).then(|| {
            let images: Vec<_> = units.origin.iter().map(|_| (brush.clone(), None)).collect();
            let base = LinearImage::solid(1, 1, [0.5, 0.5, 0.5, 1.0]);
            let t = Instant::now();
            let _ = decalbake::bake::cpu::bake_units_cpu(
                &loaded.mesh,
                &loaded.topo,
                (&units.job, &units.placements, &units.frames),
                &units.strokes,
                &base,
                &images,
            );
            t.elapsed().as_secs_f64() * 1000.0
        });
        let l = &report.layers[0];
        emit(serde_json::json!({
            "bench": "strokes", "adapter": engine.ctx.adapter, "mesh": loaded.stats.source,
            "triangles": loaded.stats.triangles, "texture": opts.side, "method": method,
            "continuity": continuity, "stamps": stamps, "stamp_size": size,
            "path_length": length, "stroke_ms": stroke_ms,
            "stamps_per_s": stamps as f64 / (stroke_ms / 1000.0),
            "charts": l.stroke.as_ref().map(|s| s.charts),
            "cg_iterations": l.stroke.as_ref().map(|s| s.cg_iterations),
            "timings": report.timings,
            "separate_decals_ms": decals_ms, "stroke_vs_decals": decals_ms / stroke_ms,
            "cpu_twin_ms": cpu_ms, "gpu_vs_cpu_twin": cpu_ms.map(|c| c / stroke_ms),
            "commands": report.gpu_commands,
        }));
    }
    Ok(())
}
