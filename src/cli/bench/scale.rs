// SPDX-License-Identifier: MIT OR Apache-2.0
//! `decalbake bench --scale`: does a decal keep the size it was asked for? One decal at each mesh's
//! highest vertex, 0.12 × the bounding-box diagonal wide, per method (expmap, lscm, hybrid), through
//! `decalbake param`'s coordinates: the scale at the placed point (median of |(u, v)| / |x − p| over
//! the reached vertices within half the decal's size, and within 0.2 × the size), the triangles
//! folded into the decal's footprint, and the surface area painted. One JSON line per mesh and
//! method.

use decalbake::bake::ParamRow;
use decalbake::error::Result;
use decalbake::io::job::Job;
use decalbake::mesh::Topology;
use decalbake::{Engine, LoadedMesh};
use glam::{DVec2, DVec3};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// The meshes of the table: the four from the shared folder, else the bundled Spot.
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
                "footprint_collapsed": m.collapsed, "painted_area": m.painted_area,
                "rectangle_area": size * size,
            }));
        }
    }
    Ok(())
}

/// What [`measure`] finds for one decal.
pub struct Measured {
    /// Scale at the point, over the vertices within half the size.
    pub scale_half: f64,
    /// Scale at the point, over the vertices within 0.2 × the size.
    pub scale_fifth: f64,
    /// Triangles whose (u, v) meet the decal rectangle.
    pub footprint: usize,
    /// Of those, flipped.
    pub flipped: usize,
    /// Of those, collapsed (area ratio below 1e-3 of the median).
    pub collapsed: usize,
    /// Surface area whose (u, v) falls inside the rectangle (model units²).
    pub painted_area: f64,
}

/// One square decal of side `size` at `at` with `method`, measured from its `param` coordinates.
pub fn measure(
    engine: &Engine,
    mesh: &LoadedMesh,
    at: [f32; 3],
    size: f32,
    method: &str,
) -> Result<Measured> {
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
    let rows = engine.layer_param(mesh, &job, 0)?;
    let p = DVec3::from(at.map(f64::from));
    Ok(measure_rows(&mesh.topo, &rows, p, size as f64))
}

/// The figures of [`Measured`] from a layer's coordinates.
pub fn measure_rows(topo: &Topology, rows: &[ParamRow], p: DVec3, size: f64) -> Measured {
    let uv: HashMap<u32, DVec2> = rows
        .iter()
        .map(|r| (r.vertex, DVec2::new(r.uv[0] as f64, r.uv[1] as f64)))
        .collect();
    let scale = |radius: f64| {
        let mut s: Vec<f64> = rows
            .iter()
            .filter_map(|r| {
                let d = (DVec3::from(r.position.map(f64::from)) - p).length();
                (d > 1e-9 * size && d <= radius).then(|| uv[&r.vertex].length() / d)
            })
            .collect();
        s.sort_by(f64::total_cmp);
        s.get(s.len() / 2).copied().unwrap_or(f64::NAN)
    };
    let h = 0.5 * size;
    let mut ratios = Vec::new();
    let mut foot = Vec::new();
    let mut painted = 0.0;
    for tri in &topo.triangles {
        let Some(z) = tri
            .iter()
            .map(|v| uv.get(v).copied())
            .collect::<Option<Vec<_>>>()
        else {
            continue;
        };
        let x = tri.map(|v| topo.positions[v as usize].as_dvec3());
        let area3 = 0.5 * (x[1] - x[0]).cross(x[2] - x[0]).length();
        if area3 <= 0.0 {
            continue;
        }
        let area2 = 0.5 * (z[1] - z[0]).perp_dot(z[2] - z[0]);
        ratios.push(area2.abs() / area3);
        let lo = z[0].min(z[1]).min(z[2]);
        let hi = z[0].max(z[1]).max(z[2]);
        if hi.x < -h || lo.x > h || hi.y < -h || lo.y > h {
            continue;
        }
        foot.push((area2, area3));
        // Painted area: the fraction of 15 × 15 barycentric samples inside the rectangle.
        let n = 15;
        let mut inside = 0;
        let mut total = 0;
        for i in 0..n {
            for j in 0..n - i {
                let (a, b) = (
                    (i as f64 + 1.0 / 3.0) / n as f64,
                    (j as f64 + 1.0 / 3.0) / n as f64,
                );
                let q = z[0] + a * (z[1] - z[0]) + b * (z[2] - z[0]);
                total += 1;
                inside += usize::from(q.x.abs() <= h && q.y.abs() <= h);
            }
        }
        painted += area3 * inside as f64 / total as f64;
    }
    ratios.sort_by(f64::total_cmp);
    let median = ratios.get(ratios.len() / 2).copied().unwrap_or(0.0);
    Measured {
        scale_half: scale(0.5 * size),
        scale_fifth: scale(0.2 * size),
        footprint: foot.len(),
        flipped: foot.iter().filter(|(a2, _)| *a2 < 0.0).count(),
        collapsed: foot
            .iter()
            .filter(|(a2, a3)| a2.abs() / a3 < 1e-3 * median)
            .count(),
        painted_area: painted,
    }
}
