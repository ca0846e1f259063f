// SPDX-License-Identifier: MIT OR Apache-2.0
//! What the benchmarks share: the workloads (the largest shared mesh with UVs, a job of random
//! decals, a decal frame at a triangle), the median, OBJ export and the peers' runner. The criterion
//! benches (`benches/`) include this file too.

#![allow(dead_code)]
use decalbake::bake::LoadedMesh;
use decalbake::error::Result;
use decalbake::io::job::Job;
use decalbake::maps::Frame;
use decalbake::mesh::Mesh;
use decalbake::mesh::Topology;
use glam::Vec3;
use std::path::{Path, PathBuf};

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
    let modes = decalbake::io::job::BlendMode::ALL;
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
            decalbake::io::image::write_atomic(&p, &img.encode_png(8))?;
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

/// Runs `f` in a scratch folder of its own under the system's temporary folder (named after
/// `name` and the process), removed afterwards whatever `f` returns.
pub fn in_scratch<T>(name: &str, f: impl FnOnce(&Path) -> anyhow::Result<T>) -> anyhow::Result<T> {
    let dir = std::env::temp_dir().join(format!("decalbake-bench-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let result = f(&dir);
    let _ = std::fs::remove_dir_all(&dir);
    result
}

/// Median (upper middle for even counts).
pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

/// A decal frame of size `side` at the centroid of triangle `t` (image x along its first edge).
pub fn frame_at(topo: &Topology, t: usize, side: f32) -> Frame {
    let [a, b, c] = topo.triangles[t].map(|i| topo.positions[i as usize]);
    let n = (b - a).cross(c - a).normalize();
    let u = (b - a).normalize();
    Frame {
        center: (a + b + c) / 3.0,
        axis_u: u,
        axis_v: n.cross(u),
        normal: n,
        size: [side, side],
        depth: side,
        up_fallback: false,
    }
}

/// Writes `tris` of `topo` as an OBJ file (for the peers).
pub fn write_obj(path: &Path, topo: &Topology, tris: &[u32]) -> Result<()> {
    let mut local = std::collections::HashMap::new();
    let mut text = String::new();
    let mut faces = String::new();
    for &t in tris {
        let mut f = Vec::new();
        for v in topo.triangles[t as usize] {
            let n = local.len() + 1;
            let id = *local.entry(v).or_insert_with(|| {
                let p = topo.positions[v as usize];
                text.push_str(&format!("v {} {} {}\n", p.x, p.y, p.z));
                n
            });
            f.push(id);
        }
        faces.push_str(&format!("f {} {} {}\n", f[0], f[1], f[2]));
    }
    text.push_str(&faces);
    decalbake::io::image::write_atomic(path, text.as_bytes())
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
