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
//! The default `"smooth"` accuracy ([`Accuracy::Smooth`]) keeps the paper's upwind tree but
//! replaces the update with a second-order integration of the log map's differential.
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
    /// Second tangent axis (the decal's image +y); normally normal × e1. The smooth mode only uses
    /// its side (which way the frame turns against the seed triangle's winding).
    pub e2: Vec3,
}

impl Seed {
    /// The seed at the surface point closest to `point` (CPU placement, [`crate::place::place_cpu`]),
    /// with `e1` projected into the tangent plane as the first axis and e2 = normal × e1. For tests
    /// and tools; bakes place on the GPU.
    pub fn nearest(topo: &Topology, point: Vec3, e1: Vec3) -> Seed {
        let q = crate::place::place_cpu(topo, crate::place::Query::Point(point));
        let n = Vec3::from(q.normal);
        let e1 = (e1 - n * e1.dot(n)).normalize();
        Seed {
            triangle: q.triangle,
            point: Vec3::from(q.point),
            normal: n,
            e1,
            e2: n.cross(e1),
        }
    }
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
    /// The differential of the log map, integrated edge by edge along the same upwind paths. At a
    /// point at geodesic distance r the log map keeps the radial component of a tangent vector
    /// and stretches the angular one by r / G(r), after parallel transport to the seed along the
    /// radial geodesic (geodesic polar coordinates have metric dr² + G² dθ²; G is the Jacobi field,
    /// G'' = -K G, G(0) = 0, G'(0) = 1). Three discrete pieces make that exact in the limit:
    /// - **Stretch**: G is integrated along the upwind path with the Gaussian curvature averaged over
    ///   each step (exact for constant curvature); the edge's angular component is scaled by r / G.
    /// - **Frame**: each vertex carries the angle α of the seed frame in its intrinsic tangent
    ///   coordinates ([`edge_angles`]: corner angles only, no normals). Crossing an edge adds
    ///   tx + π - ty (parallel transport, exact on any flat mesh, sharp creases included) and
    ///   subtracts the holonomy of the wedge (seed, y, x), ∫K dA = dθ (1 - G') (Gauss-Bonnet; dθ the
    ///   step's turn around the seed in the chart), which turns transport along the zigzag path
    ///   into transport along the radial geodesic.
    /// - **Trapezoidal rule**: the edge is mapped with the differential at both ends (x's end from
    ///   a predictor step) and the two images are averaged.
    ///
    /// Second order: on the unit sphere (within radius 1) the max 2D error is 8.3e-3, 2.1e-3,
    /// 6.8e-4, 2.3e-4 at 642, 2.6k, 10k, 41k vertices (potpourri3d's AffineLocal: 1.0e-2 to 1.7e-3;
    /// 2.8e-3 at 10k); on a cone (developable) it falls by about 4× per halving of the edge length;
    /// a crumpled developable sheet is unfolded to 1e-5 of the disc radius.
    /// The fixed point is still set by the upwind tree, so the GPU relaxation reaches the twin's
    /// values (up to f32 rounding).
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

/// Per-vertex state of the smooth mode: the Jacobi field (G, G') of geodesic polar coordinates and
/// the frame angle α (see [`Accuracy::Smooth`]); the fourth float is padding (a `vec4` on the GPU).
pub type SmoothState = [f32; 4];

/// The state of a seed-triangle vertex at distance `d`: G = d, G' = 1, α = 0.
pub fn smooth_seed_state(d: f32) -> SmoothState {
    [d, 1.0, 0.0, 0.0]
}

/// One step of the smooth mode from upwind vertex y (coordinates `cy`, state `sy`, curvature `ky`) to
/// x (curvature `kx`) along an edge of length `len`, whose intrinsic angle is `ty` at y and `tx` at x
/// ([`edge_angles`]); `orient` is +1 when the seed frame turns the same way as the mesh's winding, -1
/// when mirrored. A tangent vector of intrinsic angle t at a vertex with frame angle α has the chart
/// direction orient·(t - α); carrying the frame across the edge adds tx + π - ty (exact parallel
/// transport on a flat mesh, creases included), and the wedge's holonomy turns it back to the
/// radial geodesic's transport. Trapezoidal rule: the edge is mapped by the differential of the log
/// map at both ends and the two images are averaged (a predictor gives x's end). Returns x's
/// coordinates and state. Twin of `smooth_step` in `wgsl/shared/expmap.wgsl`.
#[allow(
    clippy::too_many_arguments,
    reason = "the step's inputs, as in the WGSL twin"
)]
pub fn smooth_step(
    cy: [f32; 2],
    sy: SmoothState,
    ky: f32,
    kx: f32,
    len: f32,
    ty: f32,
    tx: f32,
    orient: f32,
) -> ([f32; 2], SmoothState) {
    let ry = (cy[0] * cy[0] + cy[1] * cy[1]).sqrt();
    let km = 0.5 * (ky + kx);
    let carried = sy[2] + tx + std::f32::consts::PI - ty;
    let state = |c: [f32; 2]| -> SmoothState {
        let r = (c[0] * c[0] + c[1] * c[1]).sqrt();
        let g = jacobi_step([sy[0], sy[1]], km, r - ry);
        let dtheta = if ry > 1.0e-12 && r > 1.0e-12 {
            (cy[0] * c[1] - cy[1] * c[0]).atan2(cy[0] * c[0] + cy[1] * c[1])
        } else {
            0.0
        };
        // Holonomy of the wedge (seed, y, x): ∫K dA = dθ (1 - G'), G' averaged over the step.
        let alpha = carried - orient * dtheta * (1.0 - 0.5 * (sy[1] + g[1]));
        [g[0], g[1], alpha, 0.0]
    };
    let dir = |t: f32, alpha: f32| {
        let (sn, cs) = (orient * (t - alpha)).sin_cos();
        [len * cs, len * sn]
    };
    let iy = smooth_increment(cy, sy[0], dir(ty, sy[2]));
    let pred = [cy[0] + iy[0], cy[1] + iy[1]];
    let sp = state(pred);
    let ix = smooth_increment(pred, sp[0], dir(tx + std::f32::consts::PI, sp[2]));
    let c = [cy[0] + 0.5 * (iy[0] + ix[0]), cy[1] + 0.5 * (iy[1] + ix[1])];
    (c, state(c))
}

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
/// `wgsl/expmap_relax.wgsl`.
pub fn edge_angle(topo: &Topology, angles: &[f32], v: u32, q: u32) -> f32 {
    let (a, b) = (
        topo.adjacency_offsets[v as usize] as usize,
        topo.adjacency_offsets[v as usize + 1] as usize,
    );
    (a..b)
        .find(|&k| topo.adjacency[k] == q)
        .map_or(0.0, |k| angles[k])
}

/// The smooth mode's start at the seed triangle's vertices: their coordinates in the triangle's own
/// plane (exact: the seed point lies in it) and their frame angle, the intrinsic angle of the seed
/// frame's first axis at each vertex. Also returns `orient` for [`smooth_step`]. Twin of the seed
/// start in `wgsl/expmap_relax.wgsl`.
pub fn smooth_seed(
    topo: &Topology,
    angles: &[f32],
    seed: &Seed,
) -> ([[f32; 2]; 3], [SmoothState; 3], f32) {
    let tri = topo.triangles[seed.triangle as usize];
    let p = tri.map(|v| topo.positions[v as usize]);
    let nt = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
    let e1 = (seed.e1 - nt * seed.e1.dot(nt)).normalize_or_zero();
    // +1 when (e1, e2) turns like the triangle's winding, -1 when the frame is mirrored against it.
    let orient = if nt.cross(e1).dot(seed.e2) < 0.0 {
        -1.0
    } else {
        1.0
    };
    let e2 = nt.cross(e1) * orient;
    let mut uv = [[0.0; 2]; 3];
    let mut st = [smooth_seed_state(0.0); 3];
    for i in 0..3 {
        let d = p[i] - seed.point;
        uv[i] = [d.dot(e1), d.dot(e2)];
        let (next, prev) = (tri[(i + 1) % 3], tri[(i + 2) % 3]);
        let (en, ep) = (p[(i + 1) % 3] - p[i], p[(i + 2) % 3] - p[i]);
        // Angle from the edge to `next` to e1 within the triangle, and the vertex's angle scale
        // (the corner's intrinsic width over its true angle).
        let beta = nt.dot(en.cross(e1)).atan2(en.dot(e1));
        let corner = en.cross(ep).length().atan2(en.dot(ep));
        let (tn, tp) = (
            edge_angle(topo, angles, tri[i], next),
            edge_angle(topo, angles, tri[i], prev),
        );
        let mut width = tp - tn;
        if width < 0.0 {
            width += std::f32::consts::TAU;
        }
        let scale = if corner > 0.0 { width / corner } else { 1.0 };
        st[i] = [d.length(), 1.0, tn + beta * scale, 0.0];
    }
    (uv, st, orient)
}

/// The paper's Dijkstra-based discrete exponential map (f32, the CPU twin of the GPU relaxation).
/// `curvature` is the signed Gaussian curvature per welded vertex (see [`gaussian_curvature`]):
/// the stop compares |K|, the smooth mode integrates K.
pub fn dem_cpu(topo: &Topology, seed: &Seed, opts: Options, surface: &SurfaceData) -> ExpMap {
    let curvature = &surface.curvature[..];
    let n = topo.positions.len();
    let mut map = ExpMap {
        dist: vec![f32::INFINITY; n],
        uv: vec![[0.0; 2]; n],
        parent: vec![u32::MAX; n],
    };
    let mut done = vec![false; n];
    // Per-vertex state of the smooth mode.
    let mut state = vec![smooth_seed_state(0.0); n];
    let mut heap = BinaryHeap::new();
    let flat = Seed {
        normal: seed.normal,
        ..*seed
    };
    let (seed_uv, seed_state, orient) = smooth_seed(topo, &surface.edge_angles, seed);
    for (i, &v) in topo.triangles[seed.triangle as usize].iter().enumerate() {
        let p = topo.positions[v as usize];
        map.dist[v as usize] = (p - seed.point).length();
        match opts.accuracy {
            Accuracy::Fast => map.uv[v as usize] = transfer(seed.point, seed.normal, p, &flat),
            Accuracy::Smooth => {
                (map.uv[v as usize], state[v as usize]) = (seed_uv[i], seed_state[i])
            }
        }
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
        let (pr, pq) = (topo.positions[rr], topo.positions[q]);
        let t = transfer(pr, topo.normals[rr], pq, seed);
        map.dist[q] = d;
        let c = map.uv[rr];
        match opts.accuracy {
            Accuracy::Fast => map.uv[q] = [c[0] + t[0], c[1] + t[1]],
            Accuracy::Smooth => {
                let k = |v: usize| curvature.get(v).copied().unwrap_or(0.0);
                let angles = &surface.edge_angles;
                let (ty, tx) = (
                    edge_angle(topo, angles, r, q as u32),
                    edge_angle(topo, angles, q as u32, r),
                );
                let len = (pq - pr).length();
                (map.uv[q], state[q]) = smooth_step(c, state[rr], k(rr), k(q), len, ty, tx, orient);
            }
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
