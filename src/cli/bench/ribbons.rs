// SPDX-License-Identifier: MIT OR Apache-2.0
//! `decalbake bench --ribbons`: the extended exponential map of a curve (`maps::ribbon`, Sun et al.
//! 2013 §3) on the GPU against its CPU twin, one JSON line per mesh: a curve of `samples` pieces
//! along the mesh's edges, a strip 2 % of the mesh's bounding-box diagonal wide (1 % each side);
//! time of the GPU map (set-up, relaxation, status read-back; the coordinates stay on the GPU, as
//! in a bake) and of the twin, the strip's vertices,
//! sweeps and the cost per strip vertex. The target: the cost follows the strip, not the
//! mesh (per strip vertex within 1.2× between bob subdivided twice, 171k triangles, and the bunny
//! subdivided twice, 1.1M).
//!
//! Also per mesh: the harmonic repair of the curve's highly curved parts (`maps::ribbon::repair`,
//! as a bake runs it, λ = 0.2, on the GPU conjugate gradient) and its CG iterations (0 when the
//! curve has no curved part); and with `--peers DIR` (`../shared/peers`), potpourri3d's
//! multi-source heat-method distance from the curve's vertices on the same mesh, in the same run
//! (`benches/peers/ribbon_heat.py`): its set-up and solve times, ours as ratios against them, and
//! how far our map's |v| is from its distance on the strip; potpourri3d's fast marching from the
//! same vertices referees the heat method's own error.

use super::common::median;
use decalbake::maps::ribbon::gpu::{ribbon_gpu, run as ribbon_run, Output};
use decalbake::maps::ribbon::repair::{curved_parts, repair, solve_gpu, DEFAULT_LAMBDA};
use decalbake::maps::ribbon::{ribbon_cpu, Curve};
use decalbake::mesh::{Mesh, Topology};
use decalbake::Engine;
use glam::Vec3;
use serde_json::{json, Value};
use std::path::Path;
use std::time::Instant;

/// A curve of `pieces` mesh edges: from the vertex farthest along −x, each step to the unvisited
/// neighbour whose edge points most along +x (the greedy walk stops early only in a dead end).
pub fn edge_curve(topo: &Topology, pieces: usize) -> Curve {
    let n = topo.positions.len();
    let start = (0..n)
        .filter(|&v| topo.vertex_triangle_offsets[v] < topo.vertex_triangle_offsets[v + 1])
        .min_by(|&a, &b| topo.positions[a].x.total_cmp(&topo.positions[b].x))
        .expect("a mesh with triangles");
    let mut visited = vec![false; n];
    let (mut points, mut triangles) = (vec![topo.positions[start]], Vec::new());
    let mut v = start;
    visited[v] = true;
    for _ in 0..pieces {
        let (a, b) = (
            topo.adjacency_offsets[v] as usize,
            topo.adjacency_offsets[v + 1] as usize,
        );
        let along = |w: u32| {
            let d = topo.positions[w as usize] - topo.positions[v];
            d.dot(Vec3::X) / d.length().max(1e-30)
        };
        let Some(&w) = topo.adjacency[a..b]
            .iter()
            .filter(|&&w| !visited[w as usize])
            .max_by(|&&p, &&q| along(p).total_cmp(&along(q)))
        else {
            break;
        };
        let (s, e) = (
            topo.vertex_triangle_offsets[v] as usize,
            topo.vertex_triangle_offsets[v + 1] as usize,
        );
        let tri = topo.vertex_triangles[s..e]
            .iter()
            .copied()
            .find(|&t| topo.triangles[t as usize].contains(&w))
            .expect("an edge has a triangle");
        triangles.push(tri);
        points.push(topo.positions[w as usize]);
        visited[w as usize] = true;
        v = w as usize;
    }
    Curve { points, triangles }
}

/// The heat method's sources: per point of `curve`, the nearest vertex of the triangles of the
/// pieces beside it, each vertex once. [`edge_curve`]'s points are mesh vertices, so these lie on
/// the curve (distance 0), where the seed vertices of the map (every vertex of the triangles the
/// curve crosses) lie up to an edge beside it and would shorten the peer's distances by as much.
pub fn curve_vertices(topo: &Topology, curve: &Curve) -> Vec<u32> {
    let mut out: Vec<u32> = Vec::new();
    for (k, p) in curve.points.iter().enumerate() {
        let tris = [k.checked_sub(1), (k < curve.triangles.len()).then_some(k)];
        let nearest = tris
            .into_iter()
            .flatten()
            .flat_map(|i| topo.triangles[curve.triangles[i] as usize])
            .min_by(|&a, &b| {
                let d = |v: u32| topo.positions[v as usize].distance_squared(*p);
                d(a).total_cmp(&d(b))
            });
        if let Some(v) = nearest.filter(|v| !out.contains(v)) {
            out.push(v);
        }
    }
    out
}

/// Runs the benchmark on `meshes` (name, mesh, subdivisions); JSON lines through `emit`. With
/// `peers` (`../shared/peers`), potpourri3d's heat method runs beside it.
pub fn run(
    engine: &Engine,
    meshes: Vec<(String, Mesh, u32)>,
    samples: usize,
    reps: usize,
    peers: Option<&Path>,
    mut emit: impl FnMut(Value),
) -> anyhow::Result<()> {
    for (name, mut mesh, levels) in meshes {
        for _ in 0..levels {
            mesh = mesh.subdivide();
        }
        let loaded = engine.prepare(mesh)?;
        let topo = &loaded.topo;
        let (lo, hi) = topo.positions.iter().fold(
            (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
            |(lo, hi), p| (lo.min(*p), hi.max(*p)),
        );
        let reach = 0.01 * (hi - lo).length();
        let curve = edge_curve(topo, samples);
        let length: f32 = curve
            .points
            .windows(2)
            .map(|w| (w[1] - w[0]).length())
            .sum();
        // Warm: the pipelines compiled. The coordinates are made once per mesh,
        // as a bake's are; a map's time is its set-up, relaxation and status read-back. The warm
        // run's coordinates (read back) are the ones the accuracy and the repair use.
        let (ctx, pipes, surface) = (&engine.ctx, engine.pipelines(), loaded.surface_ref());
        let (map, _) = ribbon_gpu(ctx, pipes, surface, &curve, reach)?;
        let coords = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("bench.ribbon_coords"),
            size: loaded.gpu.vertex_count as u64 * 16,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        let (mut gpu_ms, mut cpu_ms) = (Vec::new(), Vec::new());
        let mut status = Default::default();
        let mut strip = 0;
        for _ in 0..reps.max(1) {
            let t = Instant::now();
            let out = (&coords, Output::PLAIN);
            let (s, _) = ribbon_run(ctx, pipes, surface, (&curve, reach), out)?;
            gpu_ms.push(t.elapsed().as_secs_f64() * 1e3);
            status = s;
            let t = Instant::now();
            let twin = ribbon_cpu(topo, &curve, reach);
            cpu_ms.push(t.elapsed().as_secs_f64() * 1e3);
            strip = (0..topo.positions.len())
                .filter(|&v| twin.reached(v))
                .count();
        }
        let (g, c) = (median(gpu_ms), median(cpu_ms));
        let repair = repair_run(engine, topo, &curve, reach, &map)?;
        let peer = match peers {
            Some(dir) => peer_json(dir, topo, &curve, reps, (&map, reach, length), [g, c]),
            None => Value::Null,
        };
        emit(json!({
            "bench": "ribbons", "mesh": name, "subdivisions": levels,
            "triangles": topo.triangles.len(), "vertices": topo.positions.len(),
            "curve_pieces": curve.triangles.len(), "curve_length": length, "reach": reach,
            "strip_vertices": strip, "gpu": status,
            "gpu_ms": g, "cpu_twin_ms": c, "gpu_vs_twin": g / c,
            "gpu_ns_per_strip_vertex": g * 1e6 / strip.max(1) as f64,
            "gpu_ns_per_candidate_sweep":
                g * 1e6 / (status.candidates.max(1) as f64 * status.sweeps.max(1) as f64),
            "cpu_ns_per_strip_vertex": c * 1e6 / strip.max(1) as f64,
            "repair": repair, "peer": peer,
            "adapter": engine.ctx.adapter,
        }));
    }
    Ok(())
}

/// The harmonic repair of `map` (the GPU map's read-back: u, v, graph distance, reached) as a bake
/// runs it: the curved parts of `curve` for a strip reaching `reach` on both sides at the default
/// λ, re-solved on the GPU conjugate gradient (`rectangle`: parts that needed the full map;
/// `cg_iterations` summed over parts and solves; `ms`: one run). Where the curve has no curved
/// part nothing is solved and the CG iterations are 0 (`"note"` says so).
fn repair_run(
    engine: &Engine,
    topo: &Topology,
    curve: &Curve,
    reach: f32,
    map: &[[f32; 4]],
) -> anyhow::Result<Value> {
    let parts = curved_parts(topo, curve, [reach, reach], DEFAULT_LAMBDA);
    if parts.is_empty() {
        return Ok(json!({
            "lambda": DEFAULT_LAMBDA, "parts": 0, "cg_iterations": 0,
            "note": "no curved parts at this lambda: nothing to repair, no CG run",
        }));
    }
    let mut uv: Vec<Option<[f32; 2]>> = map
        .iter()
        .map(|x| (x[3] > 0.5).then_some([x[0], x[1]]))
        .collect();
    let t = Instant::now();
    let solve = solve_gpu(&engine.ctx, engine.pipelines());
    let report = repair(topo, &mut uv, &parts, solve)?;
    Ok(json!({
        "lambda": DEFAULT_LAMBDA, "parts": parts.len(), "repaired": report.repaired.len(),
        "skipped": report.skipped.len(), "rectangle": report.rectangle.len(),
        "vertices": report.vertices,
        "cg_iterations": report.cg_iterations, "ms": t.elapsed().as_secs_f64() * 1e3,
    }))
}

/// The peer's entry of a mesh's JSON line: potpourri3d's heat method (and fast marching) from
/// [`curve_vertices`] ([`peer_heat`]), our GPU map's and CPU twin's median times `[gpu, twin]` as
/// ratios against its solve and against its set-up plus solve (below 1: ours is faster), and the
/// accuracy of our map (`map`, `reach`, the curve's `length`: [`accuracy`]). `{"error": ...}`
/// when the peer fails.
fn peer_json(
    dir: &Path,
    topo: &Topology,
    curve: &Curve,
    reps: usize,
    (map, reach, length): (&[[f32; 4]], f32, f32),
    [g, c]: [f64; 2],
) -> Value {
    let sources = curve_vertices(topo, curve);
    let (mut v, [heat, fmm]) = match peer_heat(dir, topo, &sources, reps) {
        Ok(x) => x,
        Err(e) => return json!({ "error": e }),
    };
    let ms = |v: &Value, part: &str| v[part]["median_ms"].as_f64().unwrap_or(f64::NAN);
    let (setup, solve) = (ms(&v, "setup"), ms(&v, "solve"));
    let total = setup + solve;
    v["setup_ms"] = json!(setup);
    v["solve_ms"] = json!(solve);
    v["gpu_vs_peer_solve"] = json!(g / solve);
    v["gpu_vs_peer_total"] = json!(g / total);
    v["twin_vs_peer_solve"] = json!(c / solve);
    v["twin_vs_peer_total"] = json!(c / total);
    let (fs, fv) = (ms(&v["fmm"], "setup"), ms(&v["fmm"], "solve"));
    v["fmm"]["setup_ms"] = json!(fs);
    v["fmm"]["solve_ms"] = json!(fv);
    v["fmm"]["gpu_vs_fmm_total"] = json!(g / (fs + fv));
    v["accuracy"] = accuracy(map, [&heat, &fmm], reach, length, &sources);
    v
}

/// How far our map's |v| is from the peers' distances (`[heat, fmm]` per welded vertex) over the
/// strip's vertices: those `map` reached with |v| ≤ `reach` (the strip's half-width) and u within
/// [0, `length`] (past γ's ends |v| is the offset beside the end's tangent, not the distance to
/// γ). Per pair: median, 95th percentile and max of the absolute difference and the median signed
/// difference (`bias`, first minus second), in model units and as a share of the strip's width
/// (2 × `reach`). The map is the relaxation's, before the repair (which re-solves the curved parts
/// harmonically and is no distance there).
///
/// The heat method's own error is not zero: its distance is smoothed over about an edge (t = h²)
/// and shifted so that its mean over the sources is 0, so it is not 0 on the curve itself
/// (`heat_at_sources_max`, where the true distance is 0), and the bench's strip is only a few edges
/// wide; `../shared/peers/README.md` finds 2–12 % of the largest distance on real meshes from one
/// source. `ours_vs_heat` therefore bounds the disagreement, not our error. Fast marching (first
/// order, exactly 0 on its sources) referees: `heat_vs_fmm` is the heat method's own share.
/// Both peers measure from the curve's vertices; our map reads |v| against the smooth curve they
/// sample, which differs from the polyline by its sag (well under an edge).
fn accuracy(
    map: &[[f32; 4]],
    [heat, fmm]: [&[f64]; 2],
    reach: f32,
    length: f32,
    sources: &[u32],
) -> Value {
    let width = 2.0 * reach as f64;
    let strip: Vec<usize> = (0..map.len())
        .filter(|&v| {
            let x = map[v];
            x[3] > 0.5 && x[1].abs() <= reach && (0.0..=length).contains(&x[0])
        })
        .filter(|&v| heat[v].is_finite() && fmm[v].is_finite())
        .collect();
    let ours = |v: usize| map[v][1].abs() as f64;
    let stats = |pairs: Vec<(f64, f64)>| {
        let signed: Vec<f64> = pairs.iter().map(|(a, b)| a - b).collect();
        let abs: Vec<f64> = signed.iter().map(|e| e.abs()).collect();
        let max = abs.iter().fold(0.0f64, |m, &e| m.max(e));
        let p95 = percentile(abs.clone(), 0.95);
        let (med, bias) = (median(abs), median(signed));
        json!({
            "median": med, "p95": p95, "max": max, "bias": bias,
            "median_of_width": med / width, "p95_of_width": p95 / width,
            "max_of_width": max / width, "bias_of_width": bias / width,
        })
    };
    if strip.is_empty() {
        return json!({ "compared": 0 });
    }
    let at_sources = sources
        .iter()
        .filter_map(|&s| heat.get(s as usize).filter(|d| d.is_finite()))
        .fold(0.0f64, |m, d| m.max(d.abs()));
    json!({
        "compared": strip.len(), "width": width,
        "ours_vs_heat": stats(strip.iter().map(|&v| (ours(v), heat[v])).collect()),
        "ours_vs_fmm": stats(strip.iter().map(|&v| (ours(v), fmm[v])).collect()),
        "heat_vs_fmm": stats(strip.iter().map(|&v| (heat[v], fmm[v])).collect()),
        "heat_at_sources_max": at_sources, "heat_at_sources_max_of_width": at_sources / width,
    })
}

/// The `q` quantile of `v` (nearest rank; `v` not empty).
fn percentile(mut v: Vec<f64>, q: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * q).round() as usize]
}

/// Runs `benches/peers/ribbon_heat.py` (with fast marching) through `DIR/.venv` on `topo` (every
/// welded vertex in order, the non-degenerate triangles) from `sources`: its JSON line and the
/// heat method's and fast marching's distances per welded vertex (NaN where no triangle uses
/// it), or a one-line error.
fn peer_heat(
    dir: &Path,
    topo: &Topology,
    sources: &[u32],
    reps: usize,
) -> Result<(Value, [Vec<f64>; 2]), String> {
    let dir = std::fs::canonicalize(dir).unwrap_or_else(|_| dir.to_path_buf());
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("benches/peers/ribbon_heat.py");
    let base = std::env::temp_dir().join(format!("decalbake-ribbon-heat-{}", std::process::id()));
    let [obj, src, heat, fmm] =
        ["obj", "src.txt", "heat.f64", "fmm.f64"].map(|e| base.with_extension(e));
    let ids: Vec<String> = sources.iter().map(u32::to_string).collect();
    let result = write_welded_obj(&obj, topo)
        .and_then(|_| std::fs::write(&src, ids.join("\n")))
        .map_err(|e| e.to_string())
        .and_then(|_| {
            std::process::Command::new(dir.join(".venv/bin/python"))
                .arg(&script)
                .args([&obj, &src])
                .arg("--out")
                .arg(&heat)
                .arg("--fmm-out")
                .arg(&fmm)
                .args(["--reps", &reps.max(1).to_string()])
                .output()
                .map_err(|e| e.to_string())
        });
    let read = |p: &Path| -> Result<Vec<f64>, String> {
        let d: Vec<f64> = std::fs::read(p)
            .map_err(|e| e.to_string())?
            .chunks_exact(8)
            .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")))
            .collect();
        match d.len() == topo.positions.len() {
            true => Ok(d),
            false => Err(format!(
                "{} distances for {} vertices",
                d.len(),
                topo.positions.len()
            )),
        }
    };
    let dists = result.as_ref().ok().map(|_| [read(&heat), read(&fmm)]);
    for p in [&obj, &src, &heat, &fmm] {
        let _ = std::fs::remove_file(p);
    }
    let result = result?;
    if !result.status.success() {
        let err = String::from_utf8_lossy(&result.stderr);
        return Err(err.lines().last().unwrap_or("failed").to_string());
    }
    let text = String::from_utf8_lossy(&result.stdout);
    let line = text.lines().rev().find(|l| l.starts_with('{'));
    let v: Value = serde_json::from_str(line.unwrap_or("")).map_err(|e| e.to_string())?;
    let [h, f] = dists.expect("the peer ran");
    Ok((v, [h?, f?]))
}

/// `topo` as OBJ: every welded vertex in order (so ids keep their meaning), then the
/// non-degenerate triangles.
fn write_welded_obj(path: &Path, topo: &Topology) -> std::io::Result<()> {
    use std::io::Write;
    let mut f = std::io::BufWriter::new(std::fs::File::create(path)?);
    for p in &topo.positions {
        writeln!(f, "v {} {} {}", p.x, p.y, p.z)?;
    }
    for (t, tri) in topo.triangles.iter().enumerate() {
        if !topo.degenerate[t] {
            writeln!(f, "f {} {} {}", tri[0] + 1, tri[1] + 1, tri[2] + 1)?;
        }
    }
    f.flush()
}
