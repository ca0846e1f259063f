// SPDX-License-Identifier: MIT OR Apache-2.0
//! Discrete exponential maps (Schmidt, Grimm & Wyvill 2006, "Interactive Decal Compositing with
//! Discrete Exponential Maps", sections 4.2-4.3 and 5): geodesic distance and normal coordinates
//! around a seed point, for surface-following decals (`"method": "expmap"`).
//!
//! The update (their eq. 2-3): a vertex q reached through its upwind neighbour r gets
//! `u_q = u_r + T(r → p) · L_r(q)`, where `L_r(q)` is the edge r→q laid into r's tangent plane with
//! its length kept, and `T(r → p)` is the minimal rotation taking r's normal onto the seed's normal
//! (applied directly, not through every previous plane, as the paper prescribes), after which the
//! vector is read in the seed frame. Distances are Dijkstra's graph distances; the upwind neighbour
//! is the one that attains the minimum (ties go to the lower vertex id).
//!
//! [`dem_cpu`] is the paper's serial Dijkstra version, the CPU twin. The GPU (`wgsl/expmap_relax.wgsl`)
//! computes the same fixed point by parallel relaxation: every sweep each candidate vertex takes the
//! best of its neighbours, until a sweep changes nothing.

use crate::mesh::Topology;
use glam::Vec3;
use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// The seed of a map: a surface point in a triangle and the tangent frame there.
#[derive(Debug, Clone, Copy)]
pub struct Seed {
    /// Welded triangle containing the point.
    pub triangle: u32,
    /// The point.
    pub point: Vec3,
    /// Unit normal at the point.
    pub normal: Vec3,
    /// First tangent axis (the decal's image +x).
    pub e1: Vec3,
    /// Second tangent axis (the decal's image +y).
    pub e2: Vec3,
}

/// A discrete exponential map over the vertices it reached.
#[derive(Debug, Clone)]
pub struct ExpMap {
    /// Dijkstra graph distance per welded vertex (`f32::INFINITY` where not reached): the
    /// propagation order. The geodesic distance estimate is the length of `uv`.
    pub dist: Vec<f32>,
    /// Normal coordinates (model units) in the seed frame.
    pub uv: Vec<[f32; 2]>,
    /// Upwind neighbour (`u32::MAX` for seed-triangle vertices and unreached ones).
    pub parent: Vec<u32>,
}

/// `v` rotated by the minimal rotation taking unit `from` onto unit `to` (Rodrigues, in the form
/// `v c + a × v + a (a · v) / (1 + c)` with `a = from × to`, `c = from · to`). Twin of `rotate_min`
/// in `wgsl/shared/expmap.wgsl`.
pub fn rotate_min(from: Vec3, to: Vec3, v: Vec3) -> Vec3 {
    let a = from.cross(to);
    let c = from.dot(to);
    if c <= -0.999_999 {
        // Opposite normals: no unique minimal rotation; flip through the plane.
        return -v;
    }
    v * c + a.cross(v) + a * (a.dot(v) / (1.0 + c))
}

/// The edge r→q laid into r's tangent plane (length kept), turned into the seed's plane and read in
/// the seed frame. Twin of `transfer` in `wgsl/shared/expmap.wgsl`.
pub fn transfer(r: Vec3, nr: Vec3, q: Vec3, seed: &Seed) -> [f32; 2] {
    let d = q - r;
    let len = d.length();
    let t = d - nr * d.dot(nr);
    let tl = t.length();
    if tl <= 0.0 || len <= 0.0 {
        return [0.0, 0.0];
    }
    let v = rotate_min(nr, seed.normal, t * (len / tl));
    [v.dot(seed.e1), v.dot(seed.e2)]
}

#[derive(PartialEq)]
struct Item(f32, u32);
impl Eq for Item {}
impl Ord for Item {
    fn cmp(&self, o: &Self) -> Ordering {
        o.0.total_cmp(&self.0).then(o.1.cmp(&self.1))
    }
}
impl PartialOrd for Item {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}

/// Options of a map.
#[derive(Debug, Clone, Copy)]
pub struct Options {
    /// Vertices whose graph distance exceeds this are reached but not expanded. Graph distance
    /// overestimates geodesic distance (by up to about 15 % on typical meshes), so callers that need
    /// a geodesic disc of radius r pass a little more.
    pub radius: f32,
    /// Vertices whose |Gaussian curvature| exceeds this are reached but not expanded (partial
    /// decals, section 5.2). `f32::INFINITY` turns it off.
    pub curvature_stop: f32,
    /// The update rule.
    pub accuracy: Accuracy,
}

/// How a vertex's normal coordinates follow from its upwind neighbour's.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Accuracy {
    /// The paper's update (Schmidt et al. eq. 2-3): the edge, laid into the neighbour's tangent
    /// plane, turned into the seed's plane by the minimal rotation between the normals.
    Fast,
    /// The same, with the edge's angular component (perpendicular to the neighbour's radial
    /// direction) scaled by r / G(r), where G is the Jacobi field of the geodesic polar coordinates
    /// (G'' = -K G, G(0) = 0, G'(0) = 1) integrated along the upwind path with each vertex's Gaussian
    /// curvature. Geodesic polar coordinates have metric dr² + G(r)² dθ², so an angular step of
    /// length s turns θ by s / G, which the plain update takes as s / r: on a sphere it under-turns
    /// by sin r / r, and the error does not shrink under refinement. With the correction it does.
    #[default]
    Smooth,
}

/// Jacobi field (G, G') advanced by `dr` along a geodesic through curvature `k` (exact for
/// constant curvature). Twin of `jacobi_step` in `wgsl/shared/expmap.wgsl`: same operations.
pub fn jacobi_step(g: [f32; 2], k: f32, dr: f32) -> [f32; 2] {
    if k > 1.0e-12 {
        let w = k.sqrt();
        let (sn, cs) = ((w * dr).sin(), (w * dr).cos());
        [g[0] * cs + g[1] * sn / w, g[1] * cs - g[0] * w * sn]
    } else if k < -1.0e-12 {
        let w = (-k).sqrt();
        let (e, ei) = ((w * dr).exp(), (-w * dr).exp());
        let (sn, cs) = (0.5 * (e - ei), 0.5 * (e + ei));
        [g[0] * cs + g[1] * sn / w, g[1] * cs + g[0] * w * sn]
    } else {
        [g[0] + g[1] * dr, g[1]]
    }
}

/// The smooth mode's increment: `t` (the plain update) with its component perpendicular to the
/// neighbour's coordinates `c` scaled by |c| / G. Twin of `smooth_increment` in
/// `wgsl/shared/expmap.wgsl`.
pub fn smooth_increment(c: [f32; 2], g: f32, t: [f32; 2]) -> [f32; 2] {
    let r = (c[0] * c[0] + c[1] * c[1]).sqrt();
    if r <= 1.0e-12 || g <= 1.0e-12 {
        return t;
    }
    let u = [c[0] / r, c[1] / r];
    let w = [-u[1], u[0]];
    let k = r / g;
    let a = t[0] * u[0] + t[1] * u[1];
    let b = k * (t[0] * w[0] + t[1] * w[1]);
    [u[0] * a + w[0] * b, u[1] * a + w[1] * b]
}

/// The paper's Dijkstra-based discrete exponential map (f32, the CPU twin of the GPU relaxation).
/// `curvature` is the signed Gaussian curvature per welded vertex (see [`gaussian_curvature`]):
/// the stop compares |K|, the smooth mode integrates K.
pub fn dem_cpu(topo: &Topology, seed: &Seed, opts: Options, curvature: &[f32]) -> ExpMap {
    let n = topo.positions.len();
    let mut map = ExpMap {
        dist: vec![f32::INFINITY; n],
        uv: vec![[0.0; 2]; n],
        parent: vec![u32::MAX; n],
    };
    let mut done = vec![false; n];
    // Jacobi field (G, G') per vertex, for the smooth mode.
    let mut jac = vec![[0.0f32, 1.0f32]; n];
    let mut heap = BinaryHeap::new();
    let flat = Seed {
        normal: seed.normal,
        ..*seed
    };
    for &v in &topo.triangles[seed.triangle as usize] {
        let p = topo.positions[v as usize];
        map.dist[v as usize] = (p - seed.point).length();
        map.uv[v as usize] = transfer(seed.point, seed.normal, p, &flat);
        jac[v as usize] = [map.dist[v as usize], 1.0];
        done[v as usize] = true;
    }
    // Seed vertices are final; expand them first.
    let expandable = |v: usize, d: f32| {
        d <= opts.radius
            && curvature
                .get(v)
                .is_none_or(|k| k.abs() <= opts.curvature_stop)
    };
    for &v in &topo.triangles[seed.triangle as usize] {
        let v = v as usize;
        if expandable(v, map.dist[v]) {
            push_neighbors(topo, v, &map, &done, &mut heap);
        }
    }
    while let Some(Item(key, q)) = heap.pop() {
        let q = q as usize;
        if done[q]
            || key > best_key(topo, q, &map, &done, &expandable).map_or(f32::INFINITY, |b| b.0)
        {
            continue;
        }
        let Some((d, r)) = best_key(topo, q, &map, &done, &expandable) else {
            continue;
        };
        let rr = r as usize;
        let t = transfer(
            topo.positions[rr],
            topo.normals[rr],
            topo.positions[q],
            seed,
        );
        map.dist[q] = d;
        let c = map.uv[rr];
        let t = match opts.accuracy {
            Accuracy::Fast => t,
            Accuracy::Smooth => smooth_increment(c, jac[rr][0], t),
        };
        map.uv[q] = [c[0] + t[0], c[1] + t[1]];
        if opts.accuracy == Accuracy::Smooth {
            let rc = (c[0] * c[0] + c[1] * c[1]).sqrt();
            let rq = (map.uv[q][0] * map.uv[q][0] + map.uv[q][1] * map.uv[q][1]).sqrt();
            jac[q] = jacobi_step(jac[rr], curvature.get(rr).copied().unwrap_or(0.0), rq - rc);
        }
        map.parent[q] = r;
        done[q] = true;
        if expandable(q, d) {
            push_neighbors(topo, q, &map, &done, &mut heap);
        }
    }
    map
}

/// The best upwind neighbour of q among finished, expandable vertices: (distance, neighbour).
fn best_key(
    topo: &Topology,
    q: usize,
    map: &ExpMap,
    done: &[bool],
    expandable: &impl Fn(usize, f32) -> bool,
) -> Option<(f32, u32)> {
    let (a, b) = (
        topo.adjacency_offsets[q] as usize,
        topo.adjacency_offsets[q + 1] as usize,
    );
    let mut best: Option<(f32, u32)> = None;
    for &r in &topo.adjacency[a..b] {
        let ri = r as usize;
        if !done[ri] || !expandable(ri, map.dist[ri]) {
            continue;
        }
        let key = map.dist[ri] + (topo.positions[q] - topo.positions[ri]).length();
        if best.is_none_or(|(k, br)| key < k || (key == k && r < br)) {
            best = Some((key, r));
        }
    }
    best
}

fn push_neighbors(
    topo: &Topology,
    v: usize,
    map: &ExpMap,
    done: &[bool],
    heap: &mut BinaryHeap<Item>,
) {
    let (a, b) = (
        topo.adjacency_offsets[v] as usize,
        topo.adjacency_offsets[v + 1] as usize,
    );
    for &q in &topo.adjacency[a..b] {
        if !done[q as usize] {
            let key = map.dist[v] + (topo.positions[q as usize] - topo.positions[v]).length();
            heap.push(Item(key, q));
        }
    }
}

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
            angle[tri[k] as usize] += u.angle_between(v);
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
            if area[v] > 0.0 && !boundary[v] {
                ((full - angle[v]) / area[v]) as f32
            } else {
                0.0
            }
        })
        .collect()
}
