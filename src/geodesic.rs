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
    /// Second tangent axis (the decal's image +y): normal × e1 (right-handed; the smooth mode turns
    /// its frame by angles measured about the normal, and a mirrored frame would turn it backwards).
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
    /// - **Frame**: each vertex carries the angle α between the parallel-transported seed frame and
    ///   the minimal-rotation frame `transfer` reads edges in. A step y→x adds the area of the
    ///   spherical triangle of normals (seed, y, x) (the minimal rotations seed→y→x→seed compose to
    ///   a rotation by it: edge-by-edge transport, exact on developable meshes) and subtracts the
    ///   holonomy of the wedge (seed, y, x), ∫K dA = dθ (1 - G') (Gauss-Bonnet; dθ the step's turn
    ///   around the seed in the chart), which turns transport along the path back into transport
    ///   along the radial geodesic.
    /// - **Trapezoidal rule**: the edge is mapped with the differential at both ends (x's end from
    ///   a predictor step) and the two images are averaged.
    ///
    /// Second order: on the unit sphere (within radius 1) the max 2D error is 4.7e-3, 1.3e-3,
    /// 4.7e-4, 1.2e-4 at 642, 2.6k, 10k, 41k vertices (potpourri3d's AffineLocal: 1.0e-2 to 1.7e-3;
    /// 2.8e-3 at 10k); on a cone (developable) it falls by 3.5-3.8× per halving of the edge length. The fixed point is still set by
    /// the upwind tree, so the GPU relaxation reaches the twin's values (up to f32 rounding).
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

/// Signed area of the spherical triangle of unit normals (a, b, c) (Van Oosterom & Strackee's
/// formula, accurate for tiny triangles in f32). The minimal rotations a → b → c → a compose to a
/// rotation about a by this angle: how far the minimal-rotation frames of `transfer` turn against
/// a frame carried edge by edge. Twin of `normal_loop_angle` in `wgsl/shared/expmap.wgsl`.
pub fn normal_loop_angle(a: Vec3, b: Vec3, c: Vec3) -> f32 {
    let det = a.dot(b.cross(c));
    let den = 1.0 + a.dot(b) + b.dot(c) + c.dot(a);
    if det == 0.0 && den <= 0.0 {
        // Two opposite normals: no minimal rotation, no loop (`rotate_min` flips instead).
        return 0.0;
    }
    2.0 * det.atan2(den)
}

/// `v` turned by `angle` (counter-clockwise in the seed frame).
fn turn(v: [f32; 2], angle: f32) -> [f32; 2] {
    let (s, c) = angle.sin_cos();
    [v[0] * c - v[1] * s, v[0] * s + v[1] * c]
}

/// Per-vertex state of the smooth mode: the Jacobi field (G, G') of geodesic polar coordinates and
/// the frame angle α (see [`Accuracy::Smooth`]); the fourth float is padding (a `vec4` on the GPU).
pub type SmoothState = [f32; 4];

/// The state of a seed-triangle vertex at distance `d`: G = d, G' = 1, α = 0.
pub fn smooth_seed_state(d: f32) -> SmoothState {
    [d, 1.0, 0.0, 0.0]
}

/// One step of the smooth mode from upwind vertex y (coordinates `cy`, state `sy`, curvature `ky`) to
/// x (curvature `kx`): `ty` and `tx` are the edge y→x laid into y's and x's tangent planes and read
/// through the minimal-rotation frames (`transfer` with y's and x's normal), `loop_angle` is
/// [`normal_loop_angle`]`(seed normal, n_y, n_x)`. Trapezoidal rule: the edge is mapped by the
/// differential of the log map at both ends and the two images are averaged (a predictor gives x's
/// end). Returns x's coordinates and state. Twin of `smooth_step` in `wgsl/shared/expmap.wgsl`.
pub fn smooth_step(
    cy: [f32; 2],
    sy: SmoothState,
    ky: f32,
    kx: f32,
    ty: [f32; 2],
    tx: [f32; 2],
    loop_angle: f32,
) -> ([f32; 2], SmoothState) {
    let ry = (cy[0] * cy[0] + cy[1] * cy[1]).sqrt();
    let km = 0.5 * (ky + kx);
    let state = |c: [f32; 2]| -> SmoothState {
        let r = (c[0] * c[0] + c[1] * c[1]).sqrt();
        let g = jacobi_step([sy[0], sy[1]], km, r - ry);
        let dtheta = if ry > 1.0e-12 && r > 1.0e-12 {
            (cy[0] * c[1] - cy[1] * c[0]).atan2(cy[0] * c[0] + cy[1] * c[1])
        } else {
            0.0
        };
        // Holonomy of the wedge (seed, y, x): ∫K dA = dθ (1 - G'), G' averaged over the step.
        let alpha = sy[2] + loop_angle - dtheta * (1.0 - 0.5 * (sy[1] + g[1]));
        [g[0], g[1], alpha, 0.0]
    };
    let iy = smooth_increment(cy, sy[0], turn(ty, -sy[2]));
    let pred = [cy[0] + iy[0], cy[1] + iy[1]];
    let sp = state(pred);
    let ix = smooth_increment(pred, sp[0], turn(tx, -sp[2]));
    let c = [cy[0] + 0.5 * (iy[0] + ix[0]), cy[1] + 0.5 * (iy[1] + ix[1])];
    (c, state(c))
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
    // Per-vertex state of the smooth mode.
    let mut state = vec![smooth_seed_state(0.0); n];
    let mut heap = BinaryHeap::new();
    let flat = Seed {
        normal: seed.normal,
        ..*seed
    };
    for &v in &topo.triangles[seed.triangle as usize] {
        let p = topo.positions[v as usize];
        map.dist[v as usize] = (p - seed.point).length();
        map.uv[v as usize] = transfer(seed.point, seed.normal, p, &flat);
        state[v as usize] = smooth_seed_state(map.dist[v as usize]);
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
                let tx = transfer(pr, topo.normals[q], pq, seed);
                let loop_angle = normal_loop_angle(seed.normal, topo.normals[rr], topo.normals[q]);
                (map.uv[q], state[q]) = smooth_step(c, state[rr], k(rr), k(q), t, tx, loop_angle);
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
