// SPDX-License-Identifier: MIT OR Apache-2.0
//! `decalbake bench --geodesic`: exponential maps on the GPU against the serial CPU twin and the
//! peers (potpourri3d), and sphere accuracy side by side.

use super::bake::BenchOptions;
use super::common::{largest_uv_mesh, median, run_peers_py, write_obj, SHARED_MESHES};
use decalbake::bake::{Engine, LoadedMesh};
use decalbake::error::Result;
use decalbake::maps::expmap::GeoResult;
use decalbake::mesh::Mesh;
use std::path::Path;
use std::time::Instant;

/// `decalbake bench --geodesic`: exponential-map timings. For each mesh size and target disc size
/// (vertices reached), the GPU relaxation (`expmaps_gpu`: candidate disc on the CPU, one dispatch,
/// read-back) against the CPU twin (`dem_cpu`, serial Dijkstra) on the same seed; then `batch` maps
/// of about 1k vertices each in one dispatch.
pub fn run_geodesic(
    engine: &Engine,
    opts: &BenchOptions,
    batch: usize,
    mut emit: impl FnMut(serde_json::Value),
) -> Result<()> {
    use decalbake::maps::expmap::cpu::{dem_cpu, Options, Seed};
    use decalbake::mesh::SurfaceData;
    let path = opts
        .mesh
        .clone()
        .or_else(|| largest_uv_mesh(Path::new(SHARED_MESHES)));
    let base = match &path {
        Some(p) => Mesh::load(p)?,
        None => Mesh::from_bytes(crate::demo::SPOT_GLB, Path::new("spot.glb (bundled)"), None)?,
    };
    let mut levels = vec![opts.subdivide];
    if opts.subdivide == 0 {
        levels = vec![2, 3];
    }
    for level in levels {
        let mut mesh = base.clone();
        for _ in 0..level {
            mesh = mesh.subdivide();
        }
        let loaded = engine.prepare(mesh)?;
        let topo = &loaded.topo;
        let k = SurfaceData::new(topo);
        // The peers read the welded mesh as OBJ.
        let peer_mesh = match &opts.peers {
            Some(_) => {
                let p = std::env::temp_dir()
                    .join(format!("decalbake-geo-{}-{level}.obj", std::process::id()));
                let tris: Vec<u32> = (0..topo.triangles.len() as u32)
                    .filter(|&t| !topo.degenerate[t as usize])
                    .collect();
                write_obj(&p, topo, &tris)?;
                Some(p)
            }
            None => None,
        };
        let area: f32 = topo
            .triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| topo.positions[i as usize]);
                0.5 * (b - a).cross(c - a).length()
            })
            .sum();
        let nv = topo.positions.len() as f32;
        let seed_for = |t: usize| {
            let tri = topo.triangles[t];
            let [a, b, c] = tri.map(|i| topo.positions[i as usize]);
            let n = (b - a).cross(c - a).normalize();
            let e1 = (b - a).normalize();
            Seed {
                triangle: t as u32,
                point: (a + b + c) / 3.0,
                normal: n,
                e1,
                e2: n.cross(e1),
            }
        };
        for target in [1_000f32, 10_000.0, 100_000.0] {
            if target > 0.5 * nv {
                continue;
            }
            // A disc holding `target` of the mesh's vertices has about that share of its area.
            let radius = (target / nv * area / std::f32::consts::PI).sqrt();
            let seed = seed_for(topo.triangles.len() / 3);
            let o = Options {
                radius,
                curvature_stop: f32::INFINITY,
                accuracy: opts.accuracy,
            };
            // One workgroup a map (lavapipe's path; a GPU's below its spread threshold), then the
            // same map spread over many (`expmap_spread`), in the same run.
            let (gpu_ms, res, dispatches) = timed(engine, &loaded, (seed, o), opts.reps, u32::MAX)?;
            let (spread, ..) = timed(engine, &loaded, (seed, o), opts.reps, 1)?;
            let t = Instant::now();
            let cpu = dem_cpu(topo, &seed, o, &k);
            let cpu_ms = t.elapsed().as_secs_f64() * 1000.0;
            let peers = match (&opts.peers, &peer_mesh) {
                (Some(dir), Some(obj)) => {
                    let source = topo.triangles[seed.triangle as usize][0];
                    peer_logmap(dir, obj, source, radius)
                }
                _ => serde_json::Value::Null,
            };
            emit(serde_json::json!({
                "bench": "expmap", "mesh_triangles": topo.triangles.len(), "mesh_vertices": topo.positions.len(),
                "disc_vertices": res.reached, "cpu_reached": cpu.dist.iter().filter(|d| d.is_finite()).count(),
                "sweeps": res.sweeps, "converged": res.converged == 1, "dispatches": dispatches,
                "gpu_ms": gpu_ms, "gpu_spread_ms": spread, "cpu_twin_ms": cpu_ms, "cpu_over_gpu": cpu_ms / gpu_ms,
                "accuracy": opts.accuracy, "peers": peers,
            }));
        }
        // Many small maps in one dispatch.
        let radius = (1000.0 / nv * area / std::f32::consts::PI).sqrt();
        let maps: Vec<(Seed, Options)> = (0..batch)
            .map(|i| {
                (
                    seed_for((i * 7919) % topo.triangles.len()),
                    Options {
                        radius,
                        curvature_stop: f32::INFINITY,
                        accuracy: opts.accuracy,
                    },
                )
            })
            .collect();
        expmaps_warm(engine, &loaded, &maps)?;
        let t = Instant::now();
        let (r, dispatches) = engine.expmaps_status(&loaded, &maps)?;
        let gpu_ms = t.elapsed().as_secs_f64() * 1000.0;
        let t = Instant::now();
        for (s, o) in &maps {
            let _ = dem_cpu(topo, s, *o, &k);
        }
        let cpu_ms = t.elapsed().as_secs_f64() * 1000.0;
        let mean_reached = r.iter().map(|x| x.reached as f64).sum::<f64>() / r.len() as f64;
        emit(serde_json::json!({
            "bench": "expmap_batch", "mesh_triangles": topo.triangles.len(), "maps": batch, "mean_disc_vertices": mean_reached,
            "dispatches": dispatches, "gpu_ms": gpu_ms, "gpu_maps_per_s": batch as f64 / (gpu_ms / 1000.0),
            "cpu_twin_ms": cpu_ms, "cpu_maps_per_s": batch as f64 / (cpu_ms / 1000.0),
        }));
        if let Some(p) = &peer_mesh {
            let _ = std::fs::remove_file(p);
        }
    }
    Ok(())
}

/// `decalbake bench --geodesic --peers DIR`, first part: accuracy on the unit sphere, side by side in
/// the same run. Runs `accuracy.py --quick` from DIR (potpourri3d's log maps on the class-I
/// icospheres f8, f16, f32 from their seed vertex, error after fitting a rotation) and our GPU maps
/// (both modes) on the same icospheres from the same vertex, error in the seed's own frame (no
/// fit), within geodesic radius 1. One JSON line per sphere.
pub fn run_sphere_accuracy(
    engine: &Engine,
    peers: &Path,
    mut emit: impl FnMut(serde_json::Value),
) -> Result<()> {
    use decalbake::maps::expmap::cpu::{Accuracy, Options, Seed};
    let dir = std::fs::canonicalize(peers).unwrap_or_else(|_| peers.to_path_buf());
    let json = std::env::temp_dir().join(format!("decalbake-accuracy-{}.json", std::process::id()));
    let status = std::process::Command::new(dir.join(".venv/bin/python"))
        .current_dir(&dir)
        .args(["accuracy.py", "--quick", "--json"])
        .arg(&json)
        .output();
    let rows: Vec<serde_json::Value> = match status {
        Ok(out) if out.status.success() => std::fs::read_to_string(&json)
            .ok()
            .and_then(|t| serde_json::from_str(&t).ok())
            .unwrap_or_default(),
        _ => Vec::new(),
    };
    let _ = std::fs::remove_file(&json);
    let peer = |case: &str, method: &str| {
        rows.iter()
            .find(|r| r["case"] == case && r["method"] == method)
            .map(|r| serde_json::json!({ "max": r["pos_max"], "rms": r["pos_rms"] }))
            .unwrap_or(serde_json::Value::Null)
    };
    for f in [8u32, 16, 32] {
        let mesh = engine.prepare(decalbake::maps::expmap::sphere::icosphere(f))?;
        let topo = &mesh.topo;
        let seed = Seed::nearest(
            topo,
            decalbake::maps::expmap::sphere::peers_seed_vertex(topo),
            glam::Vec3::X,
        );
        let mut ours = serde_json::Map::new();
        for accuracy in [Accuracy::Smooth, Accuracy::Fast] {
            let opts = Options {
                radius: 1.3,
                curvature_stop: f32::INFINITY,
                accuracy,
            };
            let (coords, _) = &engine.expmaps(&mesh, &[(seed, opts)])?[0];
            let e =
                decalbake::maps::expmap::sphere::unit_sphere_log_errors(topo, &seed, 1.0, |v| {
                    (coords[v][3] > 0.5).then_some([coords[v][0], coords[v][1]])
                });
            let key = match accuracy {
                Accuracy::Smooth => "decalbake_smooth",
                Accuracy::Fast => "decalbake_fast",
            };
            ours.insert(
                key.into(),
                serde_json::json!({ "max": e.max, "rms": e.rms }),
            );
        }
        let case = format!("icosphere f{f}");
        emit(serde_json::json!({
            "bench": "sphere_accuracy", "icosphere": f, "vertices": topo.positions.len(), "radius": 1.0,
            "decalbake_smooth": ours["decalbake_smooth"], "decalbake_fast": ours["decalbake_fast"],
            "pp3d_affine_local": peer(&case, "affine"), "pp3d_vector_heat": peer(&case, "vhm"),
            "dem_py": peer(&case, "dem_py"),
        }));
    }
    Ok(())
}

/// Times potpourri3d's log maps (`peers.py logmap`, VectorHeat and AffineLocal; they compute the map
/// over the whole mesh, their cost model) from vertex `source` of `obj`.
fn peer_logmap(dir: &Path, obj: &Path, source: u32, radius: f32) -> serde_json::Value {
    let (source, radius) = (source.to_string(), radius.to_string());
    let args: Vec<&std::ffi::OsStr> = [
        "logmap".as_ref(),
        obj.as_os_str(),
        "--source".as_ref(),
        source.as_ref(),
        "--radius".as_ref(),
        radius.as_ref(),
    ]
    .into_iter()
    .chain(["--no-exact", "--no-dem", "--repeats", "3", "--budget", "10"].map(|s| s.as_ref()))
    .collect();
    match run_peers_py(dir, &args) {
        Ok(v) => {
            let p = &v["peers"];
            serde_json::json!({
                "vhm_setup_s": p["pp3d_vhm_setup"]["setup"]["median_s"],
                "vector_heat_s": p["pp3d_VectorHeat"]["total_s"],
                "vector_heat_cold_s": p["pp3d_VectorHeat"]["cold_total_s"],
                "affine_local_s": p["pp3d_AffineLocal"]["total_s"],
                "affine_local_cold_s": p["pp3d_AffineLocal"]["cold_total_s"],
            })
        }
        Err(e) => serde_json::json!({ "error": e }),
    }
}

/// `map` computed once to warm up, then `reps` times with
/// `maps::expmap::gpu::SPREAD_MIN_CANDIDATES_OVERRIDE` at `spread_min` (`u32::MAX`: one workgroup
/// a map; 1: spread over many, `expmap_spread`): the median ms, and the last run's result and
/// dispatches.
fn timed(
    engine: &Engine,
    mesh: &LoadedMesh,
    map: (
        decalbake::maps::expmap::cpu::Seed,
        decalbake::maps::expmap::cpu::Options,
    ),
    reps: usize,
    spread_min: u32,
) -> Result<(f64, GeoResult, u32)> {
    use decalbake::maps::expmap::gpu::SPREAD_MIN_CANDIDATES_OVERRIDE as SPREAD;
    SPREAD.store(spread_min, std::sync::atomic::Ordering::Relaxed);
    let mut g = Vec::new();
    let mut last = (GeoResult::default(), 0);
    let run = expmaps_warm(engine, mesh, &[map]).and_then(|_| {
        for _ in 0..reps.max(1) {
            let t = Instant::now();
            let (r, d) = engine.expmaps_status(mesh, &[map])?;
            g.push(t.elapsed().as_secs_f64() * 1000.0);
            last = (r[0], d);
        }
        Ok(())
    });
    SPREAD.store(0, std::sync::atomic::Ordering::Relaxed);
    run.map(|_| (median(g), last.0, last.1))
}

fn expmaps_warm(
    engine: &Engine,
    mesh: &LoadedMesh,
    maps: &[(
        decalbake::maps::expmap::cpu::Seed,
        decalbake::maps::expmap::cpu::Options,
    )],
) -> Result<()> {
    engine.expmaps_status(mesh, maps).map(|_| ())
}
