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
//! [`dem_cpu`] is the paper's serial Dijkstra version, the CPU twin. The GPU (`wgsl/maps/expmap_relax.wgsl`)
//! computes the same fixed point by parallel relaxation: every sweep each candidate vertex takes the
//! best of its neighbours, until a sweep changes nothing.

pub use crate::io::job::Accuracy;
use crate::mesh::surface::edge_angle;
use crate::mesh::{SurfaceData, Topology};
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

/// A Dijkstra heap entry: (distance, vertex), smallest distance first, ties to the lower vertex.
#[derive(PartialEq)]
pub(crate) struct Item(pub f32, pub u32);
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
/// (`edge_angles`); `orient` is +1 when the seed frame turns the same way as the mesh's winding, -1
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

/// The smooth mode's start at the seed triangle's vertices: their coordinates in the triangle's own
/// plane (exact: the seed point lies in it) and their frame angle, the intrinsic angle of the seed
/// frame's first axis at each vertex. Also returns `orient` for [`smooth_step`]. Twin of the seed
/// start (`smooth_seed`, `set_seed`) in `wgsl/shared/expmap_relax_common.wgsl`.
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
/// `curvature` is the signed Gaussian curvature per welded vertex (see `gaussian_curvature`):
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
