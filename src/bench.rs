// SPDX-License-Identifier: MIT OR Apache-2.0
//! `decalbake bench`: bake time per stage for N planar decals at several texture sizes, printed as one
//! JSON object per configuration, with the CPU twin (`compose_cpu`) timed in the same run as the
//! baseline where it finishes in reasonable time.
//!
//! Decals are placed at deterministic pseudo-random surface points (area-weighted), each 8 % of the
//! bounding-box diagonal wide, with random angles and the blend modes in turn.

use crate::bake::{Engine, LoadedMesh};
use crate::error::Result;
use crate::image_io::LinearImage;
use crate::job::Job;
use crate::mesh::Mesh;
use glam::Vec3;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Where the shared meshes live, relative to the repository.
pub const SHARED_MESHES: &str = "../shared/data/meshes";

/// The largest mesh with UVs in `dir` (by triangle count), if any loads.
pub fn largest_uv_mesh(dir: &Path) -> Option<PathBuf> {
    let mut best: Option<(usize, PathBuf)> = None;
    let mut candidates: Vec<PathBuf> = std::fs::read_dir(dir)
        .ok()?
        .filter_map(|e| e.ok())
        .map(|e| e.path())
        .collect();
    // Models kept as .gltf live in a folder of their own.
    let subdirs: Vec<PathBuf> = candidates.iter().filter(|p| p.is_dir()).cloned().collect();
    for d in subdirs {
        if let Ok(rd) = std::fs::read_dir(&d) {
            candidates.extend(rd.filter_map(|e| e.ok()).map(|e| e.path()));
        }
    }
    for p in candidates {
        let ext = p.extension().and_then(|e| e.to_str()).unwrap_or("");
        if ext != "glb" && ext != "gltf" {
            continue;
        }
        if let Ok(m) = Mesh::load(&p) {
            if !m.uv_sets.is_empty() && best.as_ref().is_none_or(|(n, _)| m.triangles.len() > *n) {
                best = Some((m.triangles.len(), p));
            }
        }
    }
    best.map(|(_, p)| p)
}

/// A job with `n` random planar decals on `mesh`, images in `dir`.
pub fn random_job(
    mesh: &LoadedMesh,
    n: usize,
    side: u32,
    dir: &Path,
    seed: u32,
    method: &str,
) -> Result<Job> {
    let topo = &mesh.topo;
    let mut s = seed.max(1);
    let mut rnd = move || {
        s ^= s << 13;
        s ^= s >> 17;
        s ^= s << 5;
        (s >> 8) as f32 / (1u32 << 24) as f32
    };
    let areas: Vec<f32> = topo
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| topo.positions[i as usize]);
            0.5 * (b - a).cross(c - a).length()
        })
        .collect();
    let total: f32 = areas.iter().sum();
    let (lo, hi) = mesh.mesh.bounds();
    let size = 0.08 * (hi - lo).length();
    let modes = crate::blend::BlendMode::ALL;
    let images = ["bench_a.png", "bench_b.png", "bench_c.png", "bench_d.png"];
    for (i, name) in images.iter().enumerate() {
        let p = dir.join(name);
        if !p.exists() {
            let img = match i {
                0 => crate::demo::badge(256),
                1 => crate::demo::stripes(256),
                2 => crate::demo::rings(256),
                _ => crate::demo::glow(256),
            };
            crate::image_io::write_atomic(&p, &img.encode_png(8))?;
        }
    }
    let mut layers = Vec::new();
    for i in 0..n {
        let mut r = rnd() * total;
        let mut t = 0;
        while t + 1 < areas.len() && r > areas[t] {
            r -= areas[t];
            t += 1;
        }
        let (mut u, mut v) = (rnd(), rnd());
        if u + v > 1.0 {
            (u, v) = (1.0 - u, 1.0 - v);
        }
        let [a, b, c] = topo.triangles[t].map(|k| topo.positions[k as usize]);
        let p: Vec3 = a + u * (b - a) + v * (c - a);
        layers.push(serde_json::json!({
            "image": images[i % images.len()], "at": p.to_array(), "size": [size, size],
            "angle": rnd() * 360.0, "blend": modes[i % modes.len()].name(), "opacity": 0.9,
            "method": method
        }));
    }
    let job = serde_json::json!({
        "mesh": mesh.mesh.source, "texture": { "width": side, "height": side, "padding": 16, "samples": 4 },
        "layers": layers, "output": { "texture": null, "report": null }
    });
    Job::parse(&job.to_string(), &dir.join("bench-job.json"), dir, dir)
}

/// Median (upper middle for even counts).
pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

/// Options of `decalbake bench`.
pub struct BenchOptions {
    /// Mesh file (default: the largest mesh with UVs in [`SHARED_MESHES`], else the bundled Spot).
    pub mesh: Option<PathBuf>,
    /// Midpoint subdivisions applied to the mesh first.
    pub subdivide: u32,
    /// Texture sides.
    pub sizes: Vec<u32>,
    /// Decal counts.
    pub decals: Vec<usize>,
    /// Repetitions (median reported).
    pub reps: usize,
    /// Largest `decals × side²` for which the CPU twin is timed too.
    pub cpu_budget: u64,
    /// Decal method of the bake benchmark's layers (`"planar"` by default; `"expmap"` measures the
    /// maps inside a bake).
    pub method: String,
    /// Exponential-map update rule (geodesic benchmark, and expmap layers of the bake benchmark).
    pub accuracy: crate::geodesic::Accuracy,
    /// Geodesic benchmark: `../shared/peers`, to time potpourri3d's log maps on the same meshes and
    /// seed vertices in the same run.
    pub peers: Option<PathBuf>,
}

/// Runs the benchmark, calling `emit` with one JSON object per configuration.
pub fn run(
    engine: &Engine,
    opts: &BenchOptions,
    mut emit: impl FnMut(serde_json::Value),
) -> Result<()> {
    let t = Instant::now();
    let path = opts
        .mesh
        .clone()
        .or_else(|| largest_uv_mesh(Path::new(SHARED_MESHES)));
    let mut mesh = match &path {
        Some(p) => Mesh::load(p)?,
        None => Mesh::from_bytes(crate::demo::SPOT_GLB, Path::new("spot.glb (bundled)"), None)?,
    };
    for _ in 0..opts.subdivide {
        mesh = mesh.subdivide();
    }
    let load_ms = t.elapsed().as_secs_f64() * 1000.0;
    let loaded = engine.prepare(mesh)?;
    let dir = std::env::temp_dir().join(format!("decalbake-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).map_err(|source| crate::Error::Io {
        path: dir.clone(),
        action: "creating",
        source,
    })?;
    for &side in &opts.sizes {
        for &n in &opts.decals {
            let job = random_job(&loaded, n, side, &dir, 7 + n as u32, &opts.method)?;
            // Cold run: the first bake at a size rasterizes the islands and their distance transform
            // (then cached on the mesh) and compiles pipelines in the driver.
            let t_cold = Instant::now();
            engine.bake(&loaded, &job)?;
            let cold_ms = t_cold.elapsed().as_secs_f64() * 1000.0;
            let mut totals = Vec::new();
            let mut stages: Vec<crate::report::Timings> = Vec::new();
            let mut last = None;
            for _ in 0..opts.reps.max(1) {
                let t = Instant::now();
                let baked = engine.bake(&loaded, &job)?;
                let te = Instant::now();
                let png = baked.to_png();
                let encode_png_ms = te.elapsed().as_secs_f64() * 1000.0;
                let total = t.elapsed().as_secs_f64() * 1000.0;
                totals.push(total);
                let mut tm = baked.report.timings.clone();
                tm.write_ms = encode_png_ms;
                stages.push(tm);
                let _ = png;
                last = Some(baked);
            }
            let baked = last.expect("at least one repetition");
            let texels: u64 = baked
                .report
                .layers
                .iter()
                .map(|l| l.texels_covered as u64)
                .sum();
            let med =
                |f: fn(&crate::report::Timings) -> f64| median(stages.iter().map(f).collect());
            let compose = med(|t| t.compose_ms);
            let gpu_total = median(totals.clone());
            let mut cpu_ms = None;
            if (n as u64) * (side as u64).pow(2) <= opts.cpu_budget {
                let topo = &loaded.topo;
                let images: Vec<(LinearImage, Option<LinearImage>)> = job
                    .layers
                    .iter()
                    .map(|l| LinearImage::load(&l.image).map(|i| (i, None)))
                    .collect::<Result<_>>()?;
                let placements: Vec<_> = baked.report.layers.iter().map(|l| l.placement).collect();
                let base = loaded
                    .mesh
                    .material
                    .as_ref()
                    .and_then(|m| m.base_color_texture.clone())
                    .unwrap_or_else(|| LinearImage::solid(1, 1, [0.5, 0.5, 0.5, 1.0]));
                let t = Instant::now();
                let _ = crate::compose_cpu::bake_cpu(
                    &loaded.mesh,
                    topo,
                    &job,
                    &placements,
                    &base,
                    &images,
                );
                cpu_ms = Some(t.elapsed().as_secs_f64() * 1000.0);
            }
            emit(serde_json::json!({
                "mesh": loaded.stats.source,
                "triangles": loaded.stats.triangles,
                "welded_vertices": loaded.stats.welded_vertices,
                "texture": side,
                "decals": n,
                "method": opts.method,
                "reps": opts.reps,
                "adapter": engine.ctx.adapter,
                "median_ms": {
                    "total": gpu_total,
                    "load": load_ms, "weld": loaded.timings.1, "upload": loaded.timings.2,
                    "images": med(|t| t.images_ms), "placement": med(|t| t.placement_ms),
                    "compose": compose, "padding": med(|t| t.padding_ms), "encode_readback": med(|t| t.encode_ms),
                    "png_encode": med(|t| t.write_ms),
                },
                "cold_total_ms": cold_ms,
                "texels_composed": texels,
                "composed_texels_per_s": texels as f64 / (compose / 1000.0),
                "gpu_commands": baked.report.gpu_commands,
                "cpu_twin_compose_ms": cpu_ms,
                "cpu_twin_over_gpu_compose": cpu_ms.map(|c| c / compose),
            }));
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    Ok(())
}

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
    use crate::geodesic::{dem_cpu, Options, Seed, SurfaceData};
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
                crate::bench_linalg::write_obj(&p, topo, &tris)?;
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
            expmaps_warm(engine, &loaded, &[(seed, o)])?;
            let mut g = Vec::new();
            let mut last = None;
            for _ in 0..opts.reps.max(1) {
                let t = Instant::now();
                let (r, d) =
                    crate::geodesic_gpu::expmaps_gpu_status(engine, &loaded, &[(seed, o)])?;
                g.push(t.elapsed().as_secs_f64() * 1000.0);
                last = Some((r[0], d));
            }
            let t = Instant::now();
            let cpu = dem_cpu(topo, &seed, o, &k);
            let cpu_ms = t.elapsed().as_secs_f64() * 1000.0;
            let (res, dispatches) = last.expect("one repetition");
            let gpu_ms = median(g);
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
                "gpu_ms": gpu_ms, "cpu_twin_ms": cpu_ms, "cpu_over_gpu": cpu_ms / gpu_ms,
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
        let (r, dispatches) = crate::geodesic_gpu::expmaps_gpu_status(engine, &loaded, &maps)?;
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
    use crate::geodesic::{Accuracy, Options, Seed};
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
        let mesh = engine.prepare(crate::shapes::icosphere(f))?;
        let topo = &mesh.topo;
        let seed = Seed::nearest(topo, crate::shapes::peers_seed_vertex(topo), glam::Vec3::X);
        let mut ours = serde_json::Map::new();
        for accuracy in [Accuracy::Smooth, Accuracy::Fast] {
            let opts = Options {
                radius: 1.3,
                curvature_stop: f32::INFINITY,
                accuracy,
            };
            let (coords, _) = &crate::geodesic_gpu::expmaps_gpu(engine, &mesh, &[(seed, opts)])?[0];
            let e = crate::shapes::unit_sphere_log_errors(topo, &seed, 1.0, |v| {
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

/// Runs `../shared/peers/peers.py ARGS` (its own venv, from its folder) and returns the JSON object
/// it prints last, or a one-line error text.
pub fn run_peers_py(
    dir: &Path,
    args: &[&std::ffi::OsStr],
) -> std::result::Result<serde_json::Value, String> {
    let dir = std::fs::canonicalize(dir).unwrap_or_else(|_| dir.to_path_buf());
    let out = std::process::Command::new(dir.join(".venv/bin/python"))
        .current_dir(&dir)
        .arg("peers.py")
        .args(args)
        .output()
        .map_err(|e| e.to_string())?;
    if !out.status.success() {
        return Err(String::from_utf8_lossy(&out.stderr)
            .lines()
            .last()
            .unwrap_or("failed")
            .to_string());
    }
    let text = String::from_utf8_lossy(&out.stdout);
    let line = text
        .lines()
        .rev()
        .find(|l| l.trim_start().starts_with('{'))
        .unwrap_or("{}");
    serde_json::from_str(line).map_err(|e| e.to_string())
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

fn expmaps_warm(
    engine: &Engine,
    mesh: &LoadedMesh,
    maps: &[(crate::geodesic::Seed, crate::geodesic::Options)],
) -> Result<()> {
    crate::geodesic_gpu::expmaps_gpu_status(engine, mesh, maps).map(|_| ())
}
