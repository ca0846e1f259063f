// SPDX-License-Identifier: MIT OR Apache-2.0
//! `decalbake bench --batch-bake`: jobs per minute of `decalbake batch` (one process, meshes loaded
//! once) against one `decalbake bake` process per job, on the same generated jobs, in one run; and
//! `decalbake batch --jobs 2`. Jobs: `--decals` of them (the first value), one decal each (a ray at
//! the mesh from a seeded direction, 15 % of its diagonal, expmap / lscm / planar in turn), over the
//! bundled Spot and the shared `bob.glb`, `Duck.glb` and `WaterBottle` (a `.gltf` with external
//! files) where present, at `--sizes` in turn; and where `batch`'s time went (load, bake, write,
//! from its reports).

use super::common::SHARED_MESHES;
use crate::batch::{BatchOptions, ProgressMode};
use anyhow::{Context, Result};
use decalbake::mesh::Mesh;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Where `batch`'s time went, from its jobs' reports under `out` (seconds): `load` (load, weld and
/// upload, once per mesh: a cached mesh's reports repeat its first load's figures), `bake` (the
/// bake's stages), `write` (encoding and writing the files).
fn time_split(out: &Path) -> Result<serde_json::Value> {
    let (mut load, mut bake, mut write) = (0.0, 0.0, 0.0);
    let mut seen = std::collections::HashSet::new();
    for d in std::fs::read_dir(out)? {
        for f in std::fs::read_dir(d?.path()).into_iter().flatten() {
            let f = f?.path();
            if f.extension().is_none_or(|e| e != "json") {
                continue;
            }
            let r: serde_json::Value = serde_json::from_slice(&std::fs::read(&f)?)?;
            let t = &r["timings"];
            let ms = |k: &str| t[k].as_f64().unwrap_or(0.0);
            if seen.insert(r["mesh"]["source"].to_string()) {
                load += ms("load_ms") + ms("weld_ms") + ms("upload_ms");
            }
            bake += [
                "images_ms",
                "placement_ms",
                "compose_ms",
                "padding_ms",
                "encode_ms",
            ]
            .iter()
            .map(|k| ms(k))
            .sum::<f64>();
            write += ms("write_ms");
        }
    }
    Ok(serde_json::json!({ "load": load / 1e3, "bake": bake / 1e3, "write": write / 1e3 }))
}

/// The meshes the jobs use.
fn meshes_used(dir: &Path) -> usize {
    [
        "spot.glb",
        "bob.glb",
        "Duck.glb",
        "WaterBottle/WaterBottle.gltf",
    ]
    .iter()
    .filter(|m| dir.join(m).exists())
    .count()
}

/// Writes the meshes, image, job files and manifest into `dir`; returns the job files.
fn write_jobs(dir: &Path, count: usize, sizes: &[u32]) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir)?;
    std::fs::write(dir.join("spot.glb"), crate::demo::SPOT_GLB)?;
    let mut meshes = vec![dir.join("spot.glb")];
    for name in ["bob.glb", "Duck.glb"] {
        let p = Path::new(SHARED_MESHES).join(name);
        if p.exists() {
            std::fs::copy(&p, dir.join(name))?;
            meshes.push(dir.join(name));
        }
    }
    // A `.gltf` with external buffers and textures, copied with its folder.
    let bottle = Path::new(SHARED_MESHES).join("WaterBottle");
    if bottle.join("WaterBottle.gltf").exists() {
        std::fs::create_dir_all(dir.join("WaterBottle"))?;
        for f in std::fs::read_dir(&bottle)? {
            let f = f?.path();
            std::fs::copy(&f, dir.join("WaterBottle").join(f.file_name().unwrap()))?;
        }
        meshes.push(dir.join("WaterBottle/WaterBottle.gltf"));
    }
    std::fs::write(dir.join("badge.png"), crate::demo::badge(256).encode_png(8))?;
    let bounds: Vec<(glam::Vec3, f32)> = meshes
        .iter()
        .map(|m| {
            let (lo, hi) = Mesh::load(m)?.bounds();
            Ok(((lo + hi) / 2.0, (hi - lo).length()))
        })
        .collect::<Result<_>>()?;
    let mut files = Vec::new();
    for k in 0..count {
        let (mi, side) = (k % meshes.len(), sizes[k % sizes.len()]);
        let (c, diag) = bounds[mi];
        let (a, b) = (k as f32 * 2.399, (k as f32 * 0.7).sin() * 0.6);
        let d = glam::Vec3::new(a.cos() * b.cos(), b.sin(), a.sin() * b.cos());
        let o = c + d * 2.0 * diag;
        let method = ["expmap", "lscm", "planar"][k % 3];
        let job = serde_json::json!({
            "mesh": meshes[mi].strip_prefix(dir).unwrap_or(&meshes[mi]),
            "texture": { "width": side, "height": side, "padding": 8 },
            "layers": [{ "image": "badge.png", "at": { "ray": { "origin": o.to_array(), "dir": (-d).to_array() } },
                         "size": [0.15 * diag, 0.15 * diag], "method": method }],
            "output": { "texture": format!("t{k}.png"), "report": format!("r{k}.json") }
        });
        let f = dir.join(format!("job{k}.json"));
        std::fs::write(&f, job.to_string())?;
        files.push(f);
    }
    let manifest: Vec<String> = (0..count).map(|k| format!("\"job{k}.json\"")).collect();
    std::fs::write(dir.join("manifest.jsonl"), manifest.join("\n"))?;
    Ok(files)
}

/// Runs the benchmark; one JSON line.
pub fn run(
    devices: &crate::batch::Devices,
    count: usize,
    sizes: &[u32],
    mut emit: impl FnMut(serde_json::Value),
) -> Result<()> {
    let dir = std::env::temp_dir().join(format!("decalbake-bench-batch-{}", std::process::id()));
    let files = write_jobs(&dir, count, sizes)?;
    let batch = |jobs: usize, out: &str| -> Result<(f64, i32)> {
        let t = Instant::now();
        let code = crate::batch::run(
            devices,
            &BatchOptions {
                manifest: dir.join("manifest.jsonl"),
                out: Some(dir.join(out)),
                shard: None,
                resume: false,
                fail_fast: false,
                summary: None,
                progress: ProgressMode::None,
                jobs,
                max_memory: None,
            },
        )?;
        Ok((t.elapsed().as_secs_f64(), code))
    };
    let (one, code) = batch(1, "batch")?;
    let (two, _) = batch(2, "batch2")?;
    let exe = std::env::current_exe().context("finding the decalbake binary")?;
    let t = Instant::now();
    let mut failed = 0;
    for (k, f) in files.iter().enumerate() {
        let out = dir.join("separate").join(k.to_string());
        let status = std::process::Command::new(&exe)
            .arg("bake")
            .arg(f)
            .arg("--out")
            .arg(&out)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .status()
            .context("running decalbake bake")?;
        failed += usize::from(!status.success());
    }
    let separate = t.elapsed().as_secs_f64();
    let per_min = |s: f64| count as f64 * 60.0 / s;
    let split = time_split(&dir.join("batch"))?;
    emit(serde_json::json!({
        "bench": "batch", "jobs": count, "sizes": sizes, "adapter": devices.adapter(),
        "batch_exit": code, "separate_failed": failed,
        "batch_s": one, "batch_jobs_per_min": per_min(one),
        "batch_jobs2_s": two, "batch_jobs2_jobs_per_min": per_min(two),
        "separate_processes_s": separate, "separate_jobs_per_min": per_min(separate),
        "batch_over_separate": separate / one, "meshes": meshes_used(&dir),
        "batch_split_s": split,
    }));
    let _ = std::fs::remove_dir_all(&dir);
    Ok(())
}
