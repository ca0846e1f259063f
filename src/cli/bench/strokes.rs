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
    engine: &mut Engine,
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
        // The baseline of the selection stage: every layer tested against the whole mesh.
        engine.whole_mesh_selection = true;
        let whole_ms = time_bakes(engine, &loaded, &sj, opts.reps)?.0;
        engine.whole_mesh_selection = false;
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
                (&units.strokes, &units.ribbons),
                &base,
                &images,
            );
            t.elapsed().as_secs_f64() * 1000.0
        });
        let charts = (method == "lscm")
            .then(|| chart_solves(engine, &loaded, &units))
            .transpose()?;
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
            "whole_mesh_selection_ms": whole_ms, "stroke_vs_whole_mesh_selection": whole_ms / stroke_ms,
            "cpu_twin_ms": cpu_ms, "gpu_vs_cpu_twin": cpu_ms.map(|c| c / stroke_ms),
            "commands": report.gpu_commands,
            "chart_solves": charts,
        }));
    }
    Ok(())
}

/// The stroke's LSCM charts (stamps and corner charts) built three ways from the same requests,
/// each from the planar projection (the bake warm-starts from the exponential maps, which these
/// figures leave out): all in one [`chart::build`] (every round's solves batched, as the bake does
/// per chunk), one `build` per chart, and on the CPU twin. Charts per second of the whole build
/// (selection, assembly, refinement and solves) and of the solves alone.
fn chart_solves(
    engine: &Engine,
    mesh: &LoadedMesh,
    units: &decalbake::bake::Units,
) -> Result<serde_json::Value> {
    use decalbake::maps::chart::{self, ChartKind, ChartRequest, SolveStats, Solver};
    let requests: Vec<ChartRequest> = (0..units.placements.len())
        .map(|i| ChartRequest {
            frame: units.frames[i],
            triangle: units.placements[i].triangle,
            kind: ChartKind::Lscm,
            max_iter: None,
            warm: None,
            cone: true,
        })
        .collect();
    let topo = &mesh.topo;
    let gpu = Solver::Gpu(&engine.ctx, engine.pipelines());
    let n = requests.len() as f64;
    let per_s = |secs: f64| n / secs.max(1e-9);
    let timed = |f: &mut dyn FnMut(&mut SolveStats) -> Result<u32>| -> Result<serde_json::Value> {
        let mut stats = SolveStats::default();
        let t = Instant::now();
        let iterations = f(&mut stats)?;
        let secs = t.elapsed().as_secs_f64();
        Ok(serde_json::json!({
            "ms": secs * 1e3, "charts_per_s": per_s(secs),
            "solve_ms": stats.solve_seconds * 1e3, "solve_charts_per_s": per_s(stats.solve_seconds),
            "solves": stats.batches, "submits": stats.submits, "cg_iterations": iterations,
        }))
    };
    let total = |c: &[chart::Chart]| c.iter().map(|c| c.report.cg_iterations_total).sum::<u32>();
    // Warm-up: pipelines compiled, buffers of this size seen once.
    chart::build(topo, &requests, &gpu, &mut SolveStats::default())?;
    let batched = timed(&mut |st| Ok(total(&chart::build(topo, &requests, &gpu, st)?)))?;
    let one_by_one = timed(&mut |st| {
        let mut it = 0;
        for r in &requests {
            it += total(&chart::build(topo, std::slice::from_ref(r), &gpu, st)?);
        }
        Ok(it)
    })?;
    let cpu = timed(&mut |st| Ok(total(&chart::build(topo, &requests, &Solver::Cpu, st)?)))?;
    let ratio = |a: &serde_json::Value, b: &serde_json::Value, k: &str| {
        b[k].as_f64().unwrap_or(0.0) / a[k].as_f64().unwrap_or(1.0)
    };
    Ok(serde_json::json!({
        "charts": requests.len(), "batched": batched, "one_by_one": one_by_one, "cpu_twin": cpu,
        "batched_over_one_by_one": ratio(&one_by_one, &batched, "charts_per_s"),
        "batched_over_one_by_one_solves": ratio(&one_by_one, &batched, "solve_charts_per_s"),
        "batched_over_cpu_twin": ratio(&cpu, &batched, "charts_per_s"),
    }))
}
