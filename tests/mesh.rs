// SPDX-License-Identifier: MIT OR Apache-2.0
//! Loading and topology on real models, checked against the facts measured independently in
//! `../shared/data/meshes/README.md` (trimesh), and midpoint subdivision invariants.

use decalbake::mesh::{Mesh, Topology, DEFAULT_WELD_TOLERANCE};
use std::path::Path;

fn spot() -> Mesh {
    Mesh::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/spot.glb")).unwrap()
}

#[test]
fn spot_topology_matches_the_data_sheet() {
    let m = spot();
    let t = Topology::build(&m, DEFAULT_WELD_TOLERANCE);
    assert_eq!(m.positions.len(), 3225);
    assert_eq!(m.triangles.len(), 5856);
    assert_eq!(t.positions.len(), 2930, "welded vertices");
    assert_eq!(t.adjacency.len() / 2, 8784, "edges");
    assert!(t.boundary_edges.is_empty() && t.non_manifold_edges.is_empty());
    assert_eq!(t.components, 1);
    assert_eq!(t.degenerate_count(), 0);
    assert_eq!(m.uv_sets.len(), 1);
    let tex = m
        .material
        .as_ref()
        .unwrap()
        .base_color_texture
        .as_ref()
        .unwrap();
    assert_eq!((tex.width, tex.height), (1024, 1024));
    // Every interior edge has a neighbour on both sides; CSR is symmetric.
    for (v, w) in t.adjacency_offsets.windows(2).enumerate() {
        for &n in &t.adjacency[w[0] as usize..w[1] as usize] {
            let o = &t.adjacency[t.adjacency_offsets[n as usize] as usize
                ..t.adjacency_offsets[n as usize + 1] as usize];
            assert!(
                o.contains(&(v as u32)),
                "adjacency is not symmetric at {v}-{n}"
            );
        }
    }
    assert!(t
        .triangle_neighbors
        .iter()
        .flatten()
        .all(|n| *n != decalbake::mesh::NO_NEIGHBOR));
    // Vertex -> triangle lists: every triangle listed under each of its corners.
    assert_eq!(t.vertex_triangles.len(), 3 * m.triangles.len());
    for v in 0..t.positions.len() {
        let (a, b) = (
            t.vertex_triangle_offsets[v] as usize,
            t.vertex_triangle_offsets[v + 1] as usize,
        );
        assert!(b > a, "vertex {v} has no triangle");
        for &tri in &t.vertex_triangles[a..b] {
            assert!(t.triangles[tri as usize].contains(&(v as u32)));
        }
    }
    // Euler characteristic of a closed genus-0 surface.
    let chi = t.positions.len() as i64 - (t.adjacency.len() / 2) as i64 + m.triangles.len() as i64;
    assert_eq!(chi, 2);
}

#[test]
fn subdivision_keeps_the_surface_and_its_topology() {
    let m = spot();
    let s = m.subdivide();
    let t0 = Topology::build(&m, DEFAULT_WELD_TOLERANCE);
    let t1 = Topology::build(&s, DEFAULT_WELD_TOLERANCE);
    assert_eq!(s.triangles.len(), 4 * m.triangles.len());
    // V' = V + E on a closed mesh; genus unchanged.
    assert_eq!(
        t1.positions.len(),
        t0.positions.len() + t0.adjacency.len() / 2
    );
    assert!(t1.boundary_edges.is_empty() && t1.components == 1);
    let area = |m: &Mesh| -> f64 {
        m.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| m.positions[i as usize]);
                0.5 * (b - a).cross(c - a).length() as f64
            })
            .sum()
    };
    assert!(
        (area(&s) - area(&m)).abs() < 1e-5 * area(&m),
        "midpoint subdivision keeps the area"
    );
    // UV area is kept too (every UV triangle splits into four of a quarter).
    let uv_area = |m: &Mesh| -> f64 {
        m.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| m.uv_sets[0][i as usize]);
                0.5 * ((b - a).perp_dot(c - a)).abs() as f64
            })
            .sum()
    };
    assert!((uv_area(&s) - uv_area(&m)).abs() < 1e-6);
}
