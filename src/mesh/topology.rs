// SPDX-License-Identifier: MIT OR Apache-2.0
//! Surface topology: welding glTF's split vertices by position, and the adjacency structures the GPU
//! kernels walk (CSR vertex adjacency, triangle adjacency, boundary and non-manifold edges).
//!
//! glTF splits a vertex wherever its UV (or normal) changes, which cuts the surface along every UV seam.
//! A decal must flow across seams, so the surface is rebuilt by welding vertices whose positions agree
//! within `weld_tolerance` (relative to the bounding-box diagonal); the split vertices stay in
//! [`crate::mesh::Mesh`] for rasterization in UV space.

use crate::mesh::Mesh;
use glam::Vec3;
use std::collections::HashMap;

/// Default welding tolerance as a fraction of the bounding-box diagonal.
pub const DEFAULT_WELD_TOLERANCE: f32 = 1e-6;

/// Marker for "no neighbour" in [`Topology::triangle_neighbors`].
pub const NO_NEIGHBOR: u32 = u32::MAX;

/// The welded surface.
#[derive(Debug, Clone)]
pub struct Topology {
    /// `welded_of[split_vertex]` = welded vertex id.
    pub welded_of: Vec<u32>,
    /// Position of each welded vertex.
    pub positions: Vec<Vec3>,
    /// Area-weighted unit normal of each welded vertex.
    pub normals: Vec<Vec3>,
    /// Triangles in welded ids, same order as [`Mesh::triangles`].
    pub triangles: Vec<[u32; 3]>,
    /// Triangles that are degenerate (repeated welded vertex or zero area); skipped everywhere.
    pub degenerate: Vec<bool>,
    /// CSR offsets of the vertex adjacency (length = vertices + 1).
    pub adjacency_offsets: Vec<u32>,
    /// CSR neighbour lists, sorted per vertex.
    pub adjacency: Vec<u32>,
    /// For each triangle, the triangle across edge (v0,v1), (v1,v2), (v2,v0), or [`NO_NEIGHBOR`] at
    /// boundary and non-manifold edges.
    pub triangle_neighbors: Vec<[u32; 3]>,
    /// Edges (welded ids, smaller first) used by exactly one triangle.
    pub boundary_edges: Vec<[u32; 2]>,
    /// Edges used by more than two triangles.
    pub non_manifold_edges: Vec<[u32; 2]>,
    /// Number of connected components (over non-degenerate triangles).
    pub components: u32,
    /// Component id of each triangle (`u32::MAX` for degenerate ones).
    pub triangle_component: Vec<u32>,
    /// CSR offsets of the (non-degenerate) triangles around each vertex (length = vertices + 1).
    pub vertex_triangle_offsets: Vec<u32>,
    /// Triangle ids around each vertex.
    pub vertex_triangles: Vec<u32>,
    /// The absolute welding distance used.
    pub weld_distance: f32,
}

impl Topology {
    /// Welds `mesh` with a tolerance relative to its bounding-box diagonal and builds adjacency.
    pub fn build(mesh: &Mesh, relative_tolerance: f32) -> Self {
        let (lo, hi) = mesh.bounds();
        let diag = (hi - lo).length().max(f32::MIN_POSITIVE);
        let eps = (relative_tolerance * diag).max(f32::MIN_POSITIVE);
        let (welded_of, positions) = weld(&mesh.positions, eps);
        let nv = positions.len();
        let triangles: Vec<[u32; 3]> = mesh
            .triangles
            .iter()
            .map(|t| {
                [
                    welded_of[t[0] as usize],
                    welded_of[t[1] as usize],
                    welded_of[t[2] as usize],
                ]
            })
            .collect();
        let area_eps = (eps * eps) as f64;
        let mut normals = vec![Vec3::ZERO; nv];
        let degenerate: Vec<bool> = triangles
            .iter()
            .map(|t| {
                if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
                    return true;
                }
                let [a, b, c] = t.map(|i| positions[i as usize]);
                let n = (b - a).cross(c - a);
                // NaN areas count as degenerate too.
                let bad = (n.length() as f64 * 0.5).partial_cmp(&area_eps)
                    != Some(std::cmp::Ordering::Greater);
                if !bad {
                    for &i in t {
                        normals[i as usize] += n;
                    }
                }
                bad
            })
            .collect();
        for n in &mut normals {
            *n = n.normalize_or_zero();
        }

        // Edge -> triangles.
        let mut edges: HashMap<(u32, u32), Vec<(u32, u8)>> =
            HashMap::with_capacity(triangles.len() * 2);
        for (ti, t) in triangles.iter().enumerate() {
            if degenerate[ti] {
                continue;
            }
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                edges
                    .entry((a.min(b), a.max(b)))
                    .or_default()
                    .push((ti as u32, k as u8));
            }
        }
        let mut triangle_neighbors = vec![[NO_NEIGHBOR; 3]; triangles.len()];
        let mut boundary_edges = Vec::new();
        let mut non_manifold_edges = Vec::new();
        let mut neighbor_sets: Vec<Vec<u32>> = vec![Vec::new(); nv];
        for (&(a, b), users) in &edges {
            neighbor_sets[a as usize].push(b);
            neighbor_sets[b as usize].push(a);
            match users.len() {
                1 => boundary_edges.push([a, b]),
                2 => {
                    let (t0, k0) = users[0];
                    let (t1, k1) = users[1];
                    triangle_neighbors[t0 as usize][k0 as usize] = t1;
                    triangle_neighbors[t1 as usize][k1 as usize] = t0;
                }
                _ => non_manifold_edges.push([a, b]),
            }
        }
        boundary_edges.sort_unstable();
        non_manifold_edges.sort_unstable();
        let mut adjacency_offsets = Vec::with_capacity(nv + 1);
        let mut adjacency = Vec::new();
        adjacency_offsets.push(0);
        for set in &mut neighbor_sets {
            set.sort_unstable();
            adjacency.extend_from_slice(set);
            adjacency_offsets.push(adjacency.len() as u32);
        }

        let (triangle_component, components) = components(&triangles, &degenerate, &edges);
        let (vertex_triangle_offsets, vertex_triangles) =
            vertex_triangles(&triangles, &degenerate, nv);

        Self {
            vertex_triangle_offsets,
            vertex_triangles,
            welded_of,
            positions,
            normals,
            triangles,
            degenerate,
            adjacency_offsets,
            adjacency,
            triangle_neighbors,
            boundary_edges,
            non_manifold_edges,
            components,
            triangle_component,
            weld_distance: eps,
        }
    }

    /// Gives every vertex of `mesh` without a normal (zero: the file had none) its welded vertex's
    /// area-weighted normal, or +Z where that is zero too (a vertex of degenerate triangles only),
    /// so written files carry unit normals.
    pub fn fill_normals(&self, mesh: &mut Mesh) {
        for (i, n) in mesh.normals.iter_mut().enumerate() {
            if *n == Vec3::ZERO {
                *n = self.normals[self.welded_of[i] as usize];
                if *n == Vec3::ZERO {
                    *n = Vec3::Z;
                }
            }
        }
    }

    /// The triangles around welded vertex `v`.
    pub fn triangles_around(&self, v: u32) -> &[u32] {
        let (a, b) = (
            self.vertex_triangle_offsets[v as usize] as usize,
            self.vertex_triangle_offsets[v as usize + 1] as usize,
        );
        &self.vertex_triangles[a..b]
    }

    /// Number of degenerate triangles.
    pub fn degenerate_count(&self) -> usize {
        self.degenerate.iter().filter(|d| **d).count()
    }
}

/// Welds points closer than `eps` (grid hashing, 27-cell neighbourhood; the first point of a cluster
/// is its representative). Returns the map and the representatives' positions.
fn weld(points: &[Vec3], eps: f32) -> (Vec<u32>, Vec<Vec3>) {
    let cell = |p: Vec3| -> (i64, i64, i64) {
        let q = p / eps;
        (q.x.floor() as i64, q.y.floor() as i64, q.z.floor() as i64)
    };
    let mut grid: HashMap<(i64, i64, i64), Vec<u32>> = HashMap::with_capacity(points.len());
    let mut reps: Vec<Vec3> = Vec::new();
    let mut map = Vec::with_capacity(points.len());
    let eps2 = eps * eps;
    for p in points {
        let (cx, cy, cz) = cell(*p);
        let mut found = None;
        'search: for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    // Saturating: a point far beyond the tolerance's scale sits in a cell at
                    // i64::MAX (the cast saturates), whose neighbours must not overflow.
                    let key = (
                        cx.saturating_add(dx),
                        cy.saturating_add(dy),
                        cz.saturating_add(dz),
                    );
                    if let Some(ids) = grid.get(&key) {
                        for &id in ids {
                            if reps[id as usize].distance_squared(*p) <= eps2 {
                                found = Some(id);
                                break 'search;
                            }
                        }
                    }
                }
            }
        }
        let id = match found {
            Some(id) => id,
            None => {
                let id = reps.len() as u32;
                reps.push(*p);
                grid.entry((cx, cy, cz)).or_default().push(id);
                id
            }
        };
        map.push(id);
    }
    (map, reps)
}

/// Edge-connected components over the non-degenerate triangles (non-manifold edges connect too):
/// each triangle's component (`u32::MAX` for degenerate ones) and the count.
fn components(
    triangles: &[[u32; 3]],
    degenerate: &[bool],
    edges: &HashMap<(u32, u32), Vec<(u32, u8)>>,
) -> (Vec<u32>, u32) {
    let mut triangle_component = vec![u32::MAX; triangles.len()];
    let mut components = 0;
    let mut stack = Vec::new();
    for seed in 0..triangles.len() {
        if degenerate[seed] || triangle_component[seed] != u32::MAX {
            continue;
        }
        triangle_component[seed] = components;
        stack.push(seed as u32);
        while let Some(t) = stack.pop() {
            let tri = triangles[t as usize];
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                for &(u, _) in &edges[&(a.min(b), a.max(b))] {
                    if triangle_component[u as usize] == u32::MAX {
                        triangle_component[u as usize] = components;
                        stack.push(u);
                    }
                }
            }
        }
        components += 1;
    }
    (triangle_component, components)
}

/// CSR of the non-degenerate triangles around each of `nv` vertices: (offsets, triangles).
fn vertex_triangles(
    triangles: &[[u32; 3]],
    degenerate: &[bool],
    nv: usize,
) -> (Vec<u32>, Vec<u32>) {
    let mut counts = vec![0u32; nv + 1];
    for (t, tri) in triangles.iter().enumerate() {
        if !degenerate[t] {
            for &v in tri {
                counts[v as usize + 1] += 1;
            }
        }
    }
    for i in 0..nv {
        counts[i + 1] += counts[i];
    }
    let offsets = counts.clone();
    let mut list = vec![0u32; counts[nv] as usize];
    for (t, tri) in triangles.iter().enumerate() {
        if !degenerate[t] {
            for &v in tri {
                list[counts[v as usize] as usize] = t as u32;
                counts[v as usize] += 1;
            }
        }
    }
    (offsets, list)
}
