// SPDX-License-Identifier: MIT OR Apache-2.0
//! Intrinsic surface data of the welded mesh, computed once per mesh on the CPU and uploaded with it
//! ([`crate::mesh::upload`]): signed Gaussian curvature per vertex and the intrinsic angle of every
//! edge at its source vertex. The exponential maps ([`crate::maps::expmap`]) read both, on the GPU
//! through one record per adjacency entry ([`relax_edges`]).

use crate::mesh::Topology;

/// Per-vertex surface data the maps need, computed once per mesh: signed Gaussian curvature
/// ([`gaussian_curvature`]) and intrinsic edge angles ([`edge_angles`]).
#[derive(Debug, Clone)]
pub struct SurfaceData {
    /// Per welded vertex.
    pub curvature: Vec<f32>,
    /// Per CSR adjacency entry.
    pub edge_angles: Vec<f32>,
}

impl SurfaceData {
    /// Computes both.
    pub fn new(topo: &Topology) -> Self {
        Self {
            curvature: gaussian_curvature(topo),
            edge_angles: edge_angles(topo),
        }
    }
}

/// What the exponential maps' relaxation (`wgsl/shared/expmap_relax_common.wgsl`) reads of each CSR
/// adjacency entry v → r, in one 16-byte load: r, the edge's intrinsic angle at v, the reverse
/// edge's (r → v) at r (0 where r does not list v, as the kernel's scan gave) and r's signed
/// Gaussian curvature, as bits. On lavapipe every storage load is a loop over the SIMD lanes: this
/// replaces two of a neighbour scan's loads (adjacency, curvature) with one, and the two scans of
/// r's and v's lists the smooth step made for the two angles with none.
pub fn relax_edges(topo: &Topology, surface: &SurfaceData) -> Vec<[u32; 4]> {
    let offsets = &topo.adjacency_offsets;
    let mut out = Vec::with_capacity(topo.adjacency.len());
    for v in 0..topo.positions.len() {
        for k in offsets[v] as usize..offsets[v + 1] as usize {
            let r = topo.adjacency[k] as usize;
            let back = (offsets[r] as usize..offsets[r + 1] as usize)
                .find(|&j| topo.adjacency[j] as usize == v)
                .map_or(0.0, |j| surface.edge_angles[j]);
            out.push([
                r as u32,
                surface.edge_angles[k].to_bits(),
                back.to_bits(),
                surface.curvature[r].to_bits(),
            ]);
        }
    }
    out
}

/// The intrinsic angle of each edge at its source vertex, per CSR adjacency entry: going around the
/// vertex in the winding direction, the sum of the corner angles passed, scaled by 2π / (angle sum)
/// at interior vertices (the usual discrete tangent-space coordinates, e.g. Sharp, Soliman & Crane
/// 2019) and unscaled at boundary vertices. Only corner angles enter: vertex normals play no part,
/// so a vector carried across an edge by these angles is parallel-transported exactly on a flat
/// (developable) mesh, sharp creases included.
pub fn edge_angles(topo: &Topology) -> Vec<f32> {
    let mut out = vec![0f32; topo.adjacency.len()];
    let mut theta: std::collections::HashMap<u32, f64> = std::collections::HashMap::new();
    for v in 0..topo.positions.len() {
        let (a, b) = (
            topo.vertex_triangle_offsets[v] as usize,
            topo.vertex_triangle_offsets[v + 1] as usize,
        );
        let p = topo.positions[v].as_dvec3();
        // Corners (next, previous, angle) in winding order.
        let corners: Vec<(u32, u32, f64)> = topo.vertex_triangles[a..b]
            .iter()
            .filter(|&&t| !topo.degenerate[t as usize])
            .filter_map(|&t| {
                let tri = topo.triangles[t as usize];
                let i = tri.iter().position(|&x| x as usize == v)?;
                let (n, m) = (tri[(i + 1) % 3], tri[(i + 2) % 3]);
                let (e, f) = (
                    topo.positions[n as usize].as_dvec3() - p,
                    topo.positions[m as usize].as_dvec3() - p,
                );
                Some((n, m, e.cross(f).length().atan2(e.dot(f))))
            })
            .collect();
        let opens = |i: usize| !corners.iter().any(|c| c.1 == corners[i].0);
        let boundary = (0..corners.len()).any(opens);
        let total: f64 = corners.iter().map(|c| c.2).sum();
        let scale = if boundary || total <= 0.0 {
            1.0
        } else {
            std::f64::consts::TAU / total
        };
        // Walk the fan(s) from an open corner (or any), continuing across further fans of a
        // non-manifold vertex.
        theta.clear();
        let mut used = vec![false; corners.len()];
        let mut angle = 0.0f64;
        while let Some(start) = (0..corners.len())
            .find(|&i| !used[i] && opens(i))
            .or_else(|| (0..corners.len()).find(|&i| !used[i]))
        {
            let mut i = start;
            loop {
                used[i] = true;
                theta.entry(corners[i].0).or_insert(angle * scale);
                angle += corners[i].2;
                theta.entry(corners[i].1).or_insert(angle * scale);
                match (0..corners.len()).find(|&j| !used[j] && corners[j].0 == corners[i].1) {
                    Some(j) => i = j,
                    None => break,
                }
            }
        }
        let (a, b) = (
            topo.adjacency_offsets[v] as usize,
            topo.adjacency_offsets[v + 1] as usize,
        );
        for (o, q) in out[a..b].iter_mut().zip(&topo.adjacency[a..b]) {
            *o = theta.get(q).copied().unwrap_or(0.0) as f32;
        }
    }
    out
}

/// The intrinsic angle of edge v→q at v (0 when q is not a neighbour). Twin of `edge_angle` in
/// `wgsl/shared/expmap_relax_common.wgsl`.
pub fn edge_angle(topo: &Topology, angles: &[f32], v: u32, q: u32) -> f32 {
    let (a, b) = (
        topo.adjacency_offsets[v as usize] as usize,
        topo.adjacency_offsets[v as usize + 1] as usize,
    );
    (a..b)
        .find(|&k| topo.adjacency[k] == q)
        .map_or(0.0, |k| angles[k])
}

/// Angle defects (radians) at or below this count as flat. Rounding the positions to f32 leaves
/// defects of a few 1e-7 rad at the vertices of an exactly developable mesh; divided by a small vertex
/// area that is a curvature of order 1e-3 on a 25k-vertex cone, which the smooth mode integrates
/// along every path (measured: the cone error stopped converging at 192×64). A smooth surface only
/// has defects this small with more than about 1,000 vertices per radian of curvature.
pub const FLAT_DEFECT: f64 = 1.0e-6;

/// Gaussian curvature per welded vertex (signed): angle defect over a third of the incident area;
/// 0 at boundary vertices, whose defect (against π) is the boundary's turning, not the surface's.
/// Degenerate triangles are skipped.
pub fn gaussian_curvature(topo: &Topology) -> Vec<f32> {
    let n = topo.positions.len();
    let mut angle = vec![0f64; n];
    let mut area = vec![0f64; n];
    for (t, tri) in topo.triangles.iter().enumerate() {
        if topo.degenerate[t] {
            continue;
        }
        let p = tri.map(|i| topo.positions[i as usize].as_dvec3());
        let a = 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length();
        for k in 0..3 {
            let (u, v) = (p[(k + 1) % 3] - p[k], p[(k + 2) % 3] - p[k]);
            angle[tri[k] as usize] += u.cross(v).length().atan2(u.dot(v));
            area[tri[k] as usize] += a / 3.0;
        }
    }
    let mut boundary = vec![false; n];
    for e in &topo.boundary_edges {
        boundary[e[0] as usize] = true;
        boundary[e[1] as usize] = true;
    }
    (0..n)
        .map(|v| {
            let full = if boundary[v] {
                std::f64::consts::PI
            } else {
                2.0 * std::f64::consts::PI
            };
            // At a boundary vertex the defect against π measures the boundary's turning (geodesic
            // curvature), not the surface's: report 0 there (the smooth mode integrates K, and a
            // boundary is a stop for propagation anyway).
            let defect = full - angle[v];
            if area[v] > 0.0 && !boundary[v] && defect.abs() > FLAT_DEFECT {
                (defect / area[v]) as f32
            } else {
                0.0
            }
        })
        .collect()
}
