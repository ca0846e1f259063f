// SPDX-License-Identifier: MIT OR Apache-2.0
//! `decalbake bench --unwrap`: `decalbake unwrap`'s pipeline on the GPU and through its CPU twin in
//! the same run, per mesh (Spot, bob, the Stanford bunny from `../shared/data/meshes`, bob
//! subdivided twice: 171k triangles), time per stage and the layout's quality; with `--peers DIR`,
//! xatlas (whole-mesh atlas) and libigl's ARAP and harmonic maps (on a geodesic disc patch when
//! the mesh is not a disc: `peers.py` cuts one) on the same mesh, and, where `DIR/.venv-bpy` holds
//! Blender as a module (`setup.sh --bpy`), Blender's Smart UV Project and its angle-based unwrap
//! (`benches/peers/blender_unwrap.py`), whose layouts are scored by our own quality measure.

use super::common::{run_peers_py, SHARED_MESHES};
use anyhow::Result;
use decalbake::mesh::{Mesh, Topology, DEFAULT_WELD_TOLERANCE};
use decalbake::pelt::{self, Device, Options};
use decalbake::Engine;
use serde_json::json;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What to measure.
pub struct UnwrapBenchOptions {
    /// One mesh instead of the default set.
    pub mesh: Option<PathBuf>,
    /// `../shared/peers`, to run xatlas, ARAP and the harmonic map on the same meshes.
    pub peers: Option<PathBuf>,
    /// Leave out the GPU runs of meshes above this many triangles (the GPU's LSCM refinement of a
    /// 171k-triangle mesh takes many minutes on lavapipe).
    pub gpu_max_triangles: usize,
    /// Midpoint subdivisions of `mesh` (with `--mesh` only).
    pub subdivide: u32,
}

fn meshes(opts: &UnwrapBenchOptions) -> Result<Vec<(String, Mesh)>> {
    if let Some(p) = &opts.mesh {
        let mut m = Mesh::load(p)?;
        for _ in 0..opts.subdivide {
            m = m.subdivide();
        }
        let name = match opts.subdivide {
            0 => p.display().to_string(),
            n => format!("{} x{n}", p.display()),
        };
        return Ok(vec![(name, m)]);
    }
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let bob = Mesh::load(&root.join("assets/bob.glb"))?;
    let mut out = vec![
        (
            "spot".to_string(),
            Mesh::load(&root.join("assets/spot.glb"))?,
        ),
        ("bob".to_string(), bob.clone()),
    ];
    let bunny = Path::new(SHARED_MESHES).join("stanford_bunny.glb");
    if bunny.exists() {
        out.push(("bunny".to_string(), Mesh::load(&bunny)?));
    }
    out.push(("bob x2".to_string(), bob.subdivide().subdivide()));
    Ok(out)
}

/// Runs the benchmark, one JSON line per mesh and device (and per mesh for the peers).
pub fn run(engine: &Engine, opts: &UnwrapBenchOptions, emit: impl Fn(String)) -> Result<()> {
    for (name, mut mesh) in meshes(opts)? {
        let topo = Topology::build(&mesh, DEFAULT_WELD_TOLERANCE);
        topo.fill_normals(&mut mesh);
        let tris = mesh.triangles.len();
        let mut cpu_ms = None;
        for gpu in [false, true] {
            if gpu && tris > opts.gpu_max_triangles {
                emit(
                    json!({"bench": "unwrap", "mesh": name, "triangles": tris, "device": "gpu",
                    "skipped": format!("over --gpu-max-triangles {}", opts.gpu_max_triangles)})
                    .to_string(),
                );
                continue;
            }
            let device = if gpu {
                Device::Gpu(&engine.ctx, engine.pipelines())
            } else {
                Device::Cpu
            };
            let t = Instant::now();
            let un = pelt::unwrap(device, &mesh, &topo, &Options::default(), Path::new(&name))?;
            let ms = t.elapsed().as_secs_f64() * 1e3;
            if !gpu {
                cpu_ms = Some(ms);
            }
            let r = &un.report;
            emit(
                json!({"bench": "unwrap", "mesh": name, "triangles": tris,
                "vertices": topo.positions.len(), "device": r.device, "ms": ms,
                "gpu_over_cpu": cpu_ms.filter(|_| gpu).map(|c| ms / c),
                "stages_ms": r.ms, "pelts": r.pieces.len(), "splits": r.splits,
                "steps": r.steps, "seam_length": r.seam_length,
                "refined": r.pieces.iter().filter(|p| p.refine.is_some_and(|f| f.kept)).count(),
                "quality": r.quality})
                .to_string(),
            );
        }
        if let Some(dir) = &opts.peers {
            let file = std::env::temp_dir().join(format!(
                "decalbake-bench-unwrap-{}-{}.glb",
                name.replace(|c: char| !c.is_ascii_alphanumeric(), "_"),
                std::process::id()
            ));
            let written = decalbake::output::gltf::write_model(&mesh, &[], &file)?;
            decalbake::io::image::write_atomic(&file, &written.files[0].1)?;
            for cmd in ["atlas", "arap", "harmonic"] {
                let v = run_peers_py(dir, &[cmd.as_ref(), file.as_os_str()])
                    .unwrap_or_else(|e| json!({ "error": e }));
                emit(
                    json!({"bench": "unwrap", "mesh": name, "triangles": tris, "peer": cmd,
                    "patch": v.get("patch"), "result": v.get("peers").unwrap_or(&v)})
                    .to_string(),
                );
            }
            if dir.join(".venv-bpy/bin/python").exists() {
                for method in ["smart", "angle"] {
                    let v = blender(dir, &file, method).unwrap_or_else(|e| json!({ "error": e }));
                    emit(
                        json!({"bench": "unwrap", "mesh": name, "triangles": tris,
                        "peer": "blender", "method": method, "result": v})
                        .to_string(),
                    );
                }
            }
            let _ = std::fs::remove_file(&file);
        }
    }
    Ok(())
}

/// Runs `benches/peers/blender_unwrap.py` with `method` on `file` through `DIR/.venv-bpy` and scores
/// the layout it writes with `pelt::quality::measure` (as ours are).
fn blender(
    dir: &Path,
    file: &Path,
    method: &str,
) -> std::result::Result<serde_json::Value, String> {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("benches/peers/blender_unwrap.py");
    let out_glb = file.with_extension(format!("blender-{method}.glb"));
    let out = std::process::Command::new(dir.join(".venv-bpy/bin/python"))
        .arg(&script)
        .arg(file)
        .arg(&out_glb)
        .args(["--method", method])
        .output()
        .map_err(|e| e.to_string())?;
    let text = String::from_utf8_lossy(&out.stdout);
    let line = text.lines().rev().find(|l| l.starts_with('{'));
    let (true, Some(line)) = (out.status.success(), line) else {
        let err = String::from_utf8_lossy(&out.stderr);
        return Err(err.lines().last().unwrap_or("failed").to_string());
    };
    let mut v: serde_json::Value = serde_json::from_str(line).map_err(|e| e.to_string())?;
    let mesh = Mesh::load(&out_glb).map_err(|e| e.to_string());
    let _ = std::fs::remove_file(&out_glb);
    let mesh = mesh?;
    let uv = mesh.uv_sets.first().ok_or("Blender wrote no UVs")?;
    let pos: Vec<glam::DVec3> = mesh.positions.iter().map(|p| p.as_dvec3()).collect();
    let uv: Vec<glam::DVec2> = uv.iter().map(|p| p.as_dvec2()).collect();
    v["quality"] = json!(pelt::quality::measure(&pos, &uv, &mesh.triangles));
    Ok(v)
}
