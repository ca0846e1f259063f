// SPDX-License-Identifier: MIT OR Apache-2.0
//! `decalbake bench --scale`: does a decal keep the size it was asked for? One decal at each mesh's
//! highest vertex, 0.12 × the bounding-box diagonal wide, per method (expmap, lscm, hybrid), through
//! `decalbake param`'s coordinates: the scale at the placed point (median of |(u, v)| / |x − p| over
//! the reached vertices within half the decal's size, and within 0.2 × the size), the triangles
//! folded into the decal's footprint, and the surface area painted. One JSON line per mesh and
//! method.

use decalbake::bake::{size_figures, SizeFigures};
use decalbake::error::Result;
use decalbake::io::job::Job;
use decalbake::{Engine, LoadedMesh};
use glam::DVec3;
use std::path::{Path, PathBuf};

/// The meshes of the table: spot, fandisk, bob and Duck from the shared folder, else the bundled Spot.
pub fn default_meshes(shared: &Path) -> Vec<PathBuf> {
    let named: Vec<PathBuf> = ["spot.glb", "fandisk.glb", "bob.glb", "Duck.glb"]
        .iter()
        .map(|n| shared.join(n))
        .filter(|p| p.exists())
        .collect();
    if named.is_empty() {
        vec![Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/spot.glb")]
    } else {
        named
    }
}

/// Runs the table, calling `emit` with one JSON object per mesh and method.
pub fn run(
    engine: &Engine,
    meshes: &[PathBuf],
    mut emit: impl FnMut(serde_json::Value),
) -> Result<()> {
    for path in meshes {
        let loaded = engine.load_mesh(path)?;
        let topo = &loaded.topo;
        let top = (0..topo.positions.len())
            .max_by(|&a, &b| topo.positions[a].y.total_cmp(&topo.positions[b].y))
            .expect("a mesh has vertices");
        let p = topo.positions[top];
        let (lo, hi) = loaded.mesh.bounds();
        let size = 0.12 * (hi - lo).length();
        for method in ["expmap", "lscm", "hybrid"] {
            let m = measure(engine, &loaded, p.to_array(), size, method)?;
            emit(serde_json::json!({
                "bench": "decal_scale", "mesh": path.display().to_string(), "method": method,
                "size": size, "scale_half_size": m.scale_half, "scale_fifth_size": m.scale_fifth,
                "footprint_triangles": m.footprint, "footprint_flipped": m.flipped,
                "footprint_collapsed": m.collapsed, "footprint_torn": m.torn, "painted_area": m.painted_area,
                "rectangle_area": size * size,
            }));
        }
    }
    Ok(())
}

/// One square decal of side `size` at `at` with `method`, measured from its `param` coordinates.
pub fn measure(
    engine: &Engine,
    mesh: &LoadedMesh,
    at: [f32; 3],
    size: f32,
    method: &str,
) -> Result<SizeFigures> {
    let text = serde_json::json!({
        "mesh": "unused.glb",
        "layers": [{ "image": "unused.png", "at": at, "size": [size, size], "up": [0, 0, 1], "method": method }]
    })
    .to_string();
    let job = Job::parse(
        &text,
        Path::new("scale-bench.json"),
        Path::new("."),
        Path::new("."),
    )?;
    let map = engine.layer_param_map(mesh, &job, 0)?;
    let p = DVec3::from(at.map(f64::from));
    Ok(size_figures(&mesh.topo, &map, p, size as f64))
}
