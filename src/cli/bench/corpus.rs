// SPDX-License-Identifier: MIT OR Apache-2.0
//! `decalbake bench --corpus DIR`: one planar decal baked onto every glTF 2.0 model of a corpus of
//! real files (`benches/corpus/fetch.sh` fetches one), a JSON line per model: baked, refused (exit
//! 2's message) or failed, the seconds it took, its texture sets, and whether the document was
//! kept: the output's JSON equals the input's outside the parts a bake may change (buffers,
//! buffer views, images, textures, the base colour of materials, materials added for bare
//! primitives, and with a UV set made by pelting the primitives' attributes and accessors).

use anyhow::Result;
use decalbake::io::job::Job;
use decalbake::Engine;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The models of `dir`: its `models.txt` (a path a line), or every `.glb` and `.gltf` under it.
fn models(dir: &Path) -> Vec<PathBuf> {
    if let Ok(list) = std::fs::read_to_string(dir.join("models.txt")) {
        return list
            .lines()
            .filter(|l| !l.is_empty())
            .map(PathBuf::from)
            .collect();
    }
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).into_iter().flatten().flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if p
                .extension()
                .is_some_and(|x| x.eq_ignore_ascii_case("glb") || x.eq_ignore_ascii_case("gltf"))
            {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

/// Bakes a decal onto every model of `dir`, emitting a row per model and a summary.
pub fn run(engine: &Engine, dir: &Path, emit: impl Fn(String)) -> Result<()> {
    let scratch = std::env::temp_dir().join(format!("decalbake-corpus-{}", std::process::id()));
    std::fs::create_dir_all(&scratch)?;
    let img: Vec<u16> = (0..32 * 32)
        .flat_map(|i| {
            let on = (i % 32 / 8 + i / 32 / 8) % 2 == 0;
            if on {
                [230, 40, 40, 255]
            } else {
                [250, 250, 250, 255]
            }
        })
        .collect();
    std::fs::write(
        scratch.join("decal.png"),
        decalbake::io::image::png_bytes(32, 32, 8, &img),
    )?;
    let (mut baked, mut kept, mut total) = (0, 0, 0);
    for (k, model) in models(dir).iter().enumerate() {
        total += 1;
        let t = Instant::now();
        let out_dir = scratch.join(format!("m{k}"));
        std::fs::create_dir_all(&out_dir)?;
        let name = model
            .strip_prefix(dir)
            .unwrap_or(model)
            .display()
            .to_string();
        let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            bake_one(engine, model, &out_dir, &scratch.join("decal.png"))
        }));
        let mut row = json!({"bench": "corpus", "model": name});
        match result {
            Ok(Ok(r)) => {
                baked += 1;
                kept += usize::from(r["document_kept"] == true);
                row["status"] = json!("baked");
                for (key, v) in r.as_object().into_iter().flatten() {
                    row[key] = v.clone();
                }
            }
            Ok(Err(e)) => {
                let input = e
                    .downcast_ref::<decalbake::Error>()
                    .is_some_and(decalbake::Error::is_input_error);
                row["status"] = json!(if input { "refused" } else { "failed" });
                row["reason"] = json!(format!("{e:#}"));
            }
            Err(_) => row["status"] = json!("panicked"),
        }
        row["seconds"] = json!((t.elapsed().as_secs_f64() * 1000.0).round() / 1000.0);
        emit(row.to_string());
        let _ = std::fs::remove_dir_all(&out_dir);
    }
    emit(
        json!({"bench": "corpus", "models": total, "baked": baked, "document_kept": kept})
            .to_string(),
    );
    let _ = std::fs::remove_dir_all(&scratch);
    Ok(())
}

/// One model's bake: a planar decal a fifth of the model's size on its first triangle, into
/// `"uv_set": "auto"` at 256², the model written as it came in (`.glb` or `.gltf`).
fn bake_one(engine: &Engine, model: &Path, out: &Path, decal: &Path) -> Result<Value> {
    let mesh = decalbake::mesh::Mesh::load(model)?;
    let tri = mesh.triangles.first().copied().unwrap_or_default();
    let at = tri
        .iter()
        .map(|&v| mesh.positions[v as usize])
        .sum::<glam::Vec3>()
        / 3.0;
    let (lo, hi) = mesh.bounds();
    let size = 0.2 * (hi - lo).length().max(1e-6);
    let ext = model
        .extension()
        .map_or("glb".into(), |e| e.to_string_lossy().to_lowercase());
    let out_model = out.join(format!("out.{ext}"));
    let job = json!({
        "mesh": model, "uv_set": "auto",
        "texture": {"width": 256, "height": 256, "padding": 4},
        "layers": [{"image": decal, "at": at.to_array(), "size": [size, size], "method": "planar"}],
        "output": {"texture": "baked.png", "glb": out_model, "report": "report.json"}
    });
    let job_path = out.join("job.json");
    std::fs::write(&job_path, serde_json::to_vec(&job)?)?;
    let job = Job::load(&job_path, None)?;
    let (loaded, job) = engine.load_mesh_for(&job)?;
    let sets = loaded.mesh.texture_sets(job.uv_set);
    let n_sets = sets.len();
    let warnings = if sets.len() > 1 {
        let mut bakes = engine.bake_texture_sets(&loaded, &job, sets)?;
        decalbake::output::write_set_outputs(engine, &loaded, &job, &mut bakes)?;
        bakes[0].baked.report.warnings.len()
    } else {
        let job = job.for_single_set(sets.first().map_or("default", |s| s.name.as_str()));
        let mut b = engine.bake(&loaded, &job)?;
        decalbake::output::write_outputs(engine, &loaded, &job, &mut b)?;
        b.report.warnings.len()
    };
    let unwrapped = loaded.unwrap.is_some();
    let input = loaded
        .mesh
        .document
        .as_ref()
        .map(|d| d.json.clone())
        .unwrap_or_default();
    let output = read_json(&out_model)?;
    let mut changed = Vec::new();
    decalbake::output::gltf::json_diff(&input, &output, "", &mut changed);
    changed.retain(|p| !may_change(p, unwrapped));
    Ok(json!({
        "triangles": loaded.mesh.triangles.len(),
        "primitives": loaded.mesh.primitives.len(),
        "texture_sets": n_sets,
        "unwrapped": unwrapped,
        "warnings": warnings,
        "document_kept": changed.is_empty(),
        "changed": changed.iter().take(5).collect::<Vec<_>>(),
    }))
}

/// A model's JSON (a `.glb`'s JSON chunk).
fn read_json(path: &Path) -> Result<Value> {
    let bytes = std::fs::read(path)?;
    if bytes.starts_with(b"glTF") && bytes.len() >= 20 {
        let n = u32::from_le_bytes([bytes[12], bytes[13], bytes[14], bytes[15]]) as usize;
        return Ok(serde_json::from_slice(&bytes[20..20 + n])?);
    }
    Ok(serde_json::from_slice(&bytes)?)
}

/// Whether a bake may change the JSON at `path` (`unwrapped`: it made a UV set by pelting).
fn may_change(path: &str, unwrapped: bool) -> bool {
    let parts: Vec<&str> = path.split('/').collect();
    let top = parts.get(1).copied().unwrap_or("");
    match top {
        "buffers" | "bufferViews" | "images" | "textures" => true,
        "materials" => {
            parts.len() <= 3
                || (parts.get(3) == Some(&"pbrMetallicRoughness")
                    && parts.get(4).is_none_or(|k| k.starts_with("baseColor")))
        }
        "accessors" => unwrapped,
        "meshes" => {
            parts.get(3) == Some(&"primitives")
                && (parts.get(5) == Some(&"material")
                    || (unwrapped
                        && parts
                            .get(5)
                            .is_some_and(|k| ["attributes", "indices", "targets"].contains(k))))
        }
        _ => false,
    }
}
