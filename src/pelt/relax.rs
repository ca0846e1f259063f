// SPDX-License-Identifier: MIT OR Apache-2.0
//! The pelting dynamics (Piponi & Borshukov §3-4) and its CPU twin.
//!
//! A piece (a disk) becomes a net of springs: one along every edge with rest length the 3D edge
//! length L and the stiffness of eq. 1 (E = Σ (L − l)² / L, so k = 2 / L in E = Σ ½ k (l − L)²),
//! and one from every boundary vertex to its point on a fixed frame (a circle or a square in the
//! plane z = 0), the points spaced along the frame in proportion to the boundary's spacing on the
//! model and each spring's stiffness in proportion to that spacing (§4). The net starts at the
//! model's own 3D shape and moves by damped dynamics in 3D until it is steady; the texture
//! coordinates are then its projection onto the frame's plane (§4: "planar projection").
//!
//! Choices the paper leaves open, and why:
//! - **Masses**: the paper uses equal masses; the steady state does not depend on them, so each
//!   vertex's mass is the sum of its springs' stiffnesses (the "dynamic relaxation" of cable-net
//!   form finding), which makes one time step (h = 1) stable for every vertex at once, however
//!   uneven the edge lengths.
//! - **Frame size**: the frame's perimeter is at least the boundary's length, its area at least
//!   the piece's, and its inradius at least the longest path from the boundary into the piece
//!   (radius max(√(A/π), P/2π, depth) for the circle), so the net is stretched, not compressed
//!   (with the area alone a hemisphere's radial edges were 10 % short and it buckled): a net in tension has positive spring weights, and with a convex frame such an
//!   equilibrium does not fold (Tutte, Floater), which is what keeps the pelt free of flips.
//! - **Frame springs**: zero rest length, stiffness [`ANCHOR_STIFFNESS`] × the spacing (in mean edge
//!   lengths): stiff enough that the boundary lies on the frame.
//! - **Plane pull**: every vertex is pulled towards the frame's plane by a weak spring
//!   ([`PLANE_PULL`] × its mass, ½ k z² in the energy). A planar equilibrium of eq. 1 is an
//!   equilibrium of the pulled net too (the pull vanishes at z = 0) and the pulled energy is never
//!   below eq. 1's, so the planar result is the same; without it the out-of-plane sag, held only by
//!   the springs' tension, took about 8,000 steps to relax on a 577-vertex hemisphere and was still
//!   2 edge lengths high. Early on the net still moves through 3D as the paper intends.
//! - **Damping**: the velocity is multiplied by `damping` every step, chosen from the piece's size
//!   in edges (its slowest mode) near critical damping: [`damping_for`].
//! - **Units**: lengths in the piece's mean edge length, so the same tolerances suit every model.
//!
//! Steps (symplectic Euler, all vertices from the same positions):
//! `v ← damping · v + F(x) / m`, `x ← x + v`. Every [`SystemCfg::check_every`] steps the
//! kinetic energy per vertex is compared with `tol²`: below it, the piece is steady and stops. The
//! GPU kernels (`wgsl/pelt/pelt_step.wgsl`, `pelt_check.wgsl`) run the same steps in f32, an
//! invocation per vertex and a dispatch per step (`pelt::gpu`).

use super::cut::Piece;
use crate::mesh::Topology;
use glam::DVec3;

/// Frame-spring stiffness per unit of boundary spacing (edge springs are about 2).
pub const ANCHOR_STIFFNESS: f64 = 10.0;
/// Stiffness of the pull towards the frame's plane, as a fraction of each vertex's mass (module
/// docs).
pub const PLANE_PULL: f64 = 0.02;

/// The frame the boundary is stretched on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Frame {
    /// A circle.
    Circle,
    /// A square (corners at the boundary's quarter points).
    Square,
}

/// When and how the dynamics stops.
#[derive(Debug, Clone, Copy)]
pub struct SystemCfg {
    /// Steps between steadiness checks (rounded down to an even number: [`SystemCfg::interval`]).
    pub check_every: u32,
    /// Most steps.
    pub max_steps: u32,
    /// Steady when the mean squared speed per vertex (edge lengths per step) falls below this.
    pub tol2: f64,
}

impl SystemCfg {
    /// Steps per check interval: `check_every` rounded down to an even number, at least 2 (the GPU
    /// ping-pongs positions between two buffers and reads the first back).
    pub fn interval(&self) -> u32 {
        self.check_every.max(2) & !1
    }
}

impl Default for SystemCfg {
    fn default() -> Self {
        Self {
            check_every: 64,
            max_steps: 20_000,
            tol2: 1e-10,
        }
    }
}

/// One piece's spring net, in mean-edge-length units, laid out as the GPU reads it.
#[derive(Debug, Clone)]
pub struct Net {
    /// Start of each vertex's springs (length n + 1).
    pub offsets: Vec<u32>,
    /// The other end of each spring (piece vertex ids).
    pub other: Vec<u32>,
    /// (rest length, stiffness) of each spring.
    pub spring: Vec<[f32; 2]>,
    /// Frame point (x, y), plane-pull stiffness, frame-spring stiffness (0 inside) of each vertex.
    pub anchor: Vec<[f32; 4]>,
    /// 1 / mass of each vertex.
    pub inv_mass: Vec<f32>,
    /// Start positions (the model, in the frame's axes), w = 0.
    pub start: Vec<[f32; 4]>,
    /// Velocity multiplier per step.
    pub damping: f32,
    /// Model units per net unit (the mean edge length).
    pub unit: f64,
}

impl Net {
    /// The same net with every spring's rest length times `scale` (the fallback ladder of
    /// `pelt::unwrap`: at 0 the springs have no rest length and the steady state is a convex
    /// combination of its neighbours for every vertex, which on a convex frame never folds: Tutte,
    /// Floater 2003).
    pub fn with_rest_scale(&self, scale: f32) -> Net {
        let mut n = self.clone();
        for s in &mut n.spring {
            s[0] *= scale;
        }
        n
    }

    /// Vertices.
    pub fn len(&self) -> usize {
        self.inv_mass.len()
    }

    /// Whether the net has no vertices.
    pub fn is_empty(&self) -> bool {
        self.inv_mass.is_empty()
    }
}

/// Velocity multiplier per step for a net whose farthest vertex is `hops` edges from the frame:
/// near critical damping of its slowest mode (frequency about 2.4 / hops per step for a disk held
/// at its rim, with masses equal to the summed stiffness).
pub fn damping_for(hops: u32) -> f32 {
    let omega = 2.4 / (hops.max(2) as f64 * 1.5);
    (1.0 - 2.0 * omega).clamp(0.5, 0.999) as f32
}

/// Builds the spring net of `piece` on `frame`.
pub fn net(topo: &Topology, piece: &Piece, frame: Frame) -> Net {
    let n = piece.welded.len();
    let pos: Vec<DVec3> = piece
        .welded
        .iter()
        .map(|&w| topo.positions[w as usize].as_dvec3())
        .collect();
    let mut nbrs: Vec<Vec<u32>> = vec![Vec::new(); n];
    let (mut area, mut normal) = (0.0, DVec3::ZERO);
    for t in &piece.triangles {
        let [a, b, c] = t.map(|i| pos[i as usize]);
        let cr = (b - a).cross(c - a);
        area += 0.5 * cr.length();
        normal += cr;
        for k in 0..3 {
            let (u, v) = (t[k], t[(k + 1) % 3]);
            if !nbrs[u as usize].contains(&v) {
                nbrs[u as usize].push(v);
                nbrs[v as usize].push(u);
            }
        }
    }
    let edges: usize = nbrs.iter().map(Vec::len).sum();
    let unit = nbrs
        .iter()
        .enumerate()
        .flat_map(|(i, l)| {
            let pos = &pos;
            l.iter().map(move |&j| (pos[i] - pos[j as usize]).length())
        })
        .sum::<f64>()
        / edges.max(1) as f64;
    let unit = if unit > 0.0 { unit } else { 1.0 };
    let centre = pos.iter().sum::<DVec3>() / n.max(1) as f64;
    let axis = if normal.length() > 0.2 * 2.0 * area {
        normal.normalize()
    } else {
        least_axis(&pos, centre)
    };
    let e1 = axis.any_orthonormal_vector();
    let e2 = axis.cross(e1);
    let start: Vec<[f32; 4]> = pos
        .iter()
        .map(|p| {
            let d = (*p - centre) / unit;
            [d.dot(e1) as f32, d.dot(e2) as f32, d.dot(axis) as f32, 0.0]
        })
        .collect();
    let (hops, depth) = depth_from_boundary(&nbrs, &pos, &piece.boundary, unit);
    let mut anchor = anchors(&pos, &start, &piece.boundary, frame, area, unit, depth);
    let mut offsets = vec![0u32];
    let (mut other, mut spring) = (Vec::new(), Vec::new());
    let mut inv_mass = Vec::with_capacity(n);
    for (i, list) in nbrs.iter().enumerate() {
        let mut mass = anchor[i][3] as f64;
        for &j in list {
            let rest = ((pos[i] - pos[j as usize]).length() / unit).max(1e-6);
            let k = 2.0 / rest;
            mass += k;
            other.push(j);
            spring.push([rest as f32, k as f32]);
        }
        offsets.push(other.len() as u32);
        anchor[i][2] = (PLANE_PULL * mass) as f32;
        mass += PLANE_PULL * mass;
        inv_mass.push(if mass > 0.0 { (1.0 / mass) as f32 } else { 0.0 });
    }
    Net {
        offsets,
        other,
        spring,
        anchor,
        inv_mass,
        start,
        damping: damping_for(hops),
        unit,
    }
}

/// The axis of least spread of `pos` about `centre` (power iteration on the deflated covariance).
fn least_axis(pos: &[DVec3], centre: DVec3) -> DVec3 {
    let mut c = glam::DMat3::ZERO;
    for p in pos {
        let d = *p - centre;
        c += glam::DMat3::from_cols(d * d.x, d * d.y, d * d.z);
    }
    let power = |m: glam::DMat3, mut v: DVec3| {
        for _ in 0..64 {
            let w = m * v;
            if w.length() == 0.0 {
                break;
            }
            v = w.normalize();
        }
        v
    };
    let a = power(c, DVec3::new(0.6, 0.7, 0.4).normalize());
    let la = a.dot(c * a);
    let deflated = c - glam::DMat3::from_cols(a * a.x, a * a.y, a * a.z) * la;
    let b = power(deflated, a.any_orthonormal_vector());
    let n = a.cross(b);
    if n.length() > 0.0 {
        n.normalize()
    } else {
        DVec3::Z
    }
}

/// Frame points and stiffnesses of the boundary vertices (module docs); zero elsewhere.
fn anchors(
    pos: &[DVec3],
    start: &[[f32; 4]],
    boundary: &[u32],
    frame: Frame,
    area: f64,
    unit: f64,
    depth: f64,
) -> Vec<[f32; 4]> {
    let mut out = vec![[0.0f32; 4]; pos.len()];
    let m = boundary.len();
    if m < 3 {
        return out;
    }
    let seg: Vec<f64> = (0..m)
        .map(|k| (pos[boundary[(k + 1) % m] as usize] - pos[boundary[k] as usize]).length() / unit)
        .collect();
    let perimeter: f64 = seg.iter().sum();
    let area = area / (unit * unit);
    let s0 = start[boundary[0] as usize];
    let theta0 = (s0[1] as f64).atan2(s0[0] as f64);
    let mut arc = 0.0;
    for k in 0..m {
        let t = arc / perimeter;
        let p = match frame {
            Frame::Circle => {
                let r = (area / std::f64::consts::PI)
                    .sqrt()
                    .max(perimeter / std::f64::consts::TAU)
                    .max(depth);
                let a = theta0 + t * std::f64::consts::TAU;
                [r * a.cos(), r * a.sin()]
            }
            Frame::Square => {
                let side = area.sqrt().max(perimeter / 4.0).max(2.0 * depth);
                square_point(
                    side,
                    t + theta0.rem_euclid(std::f64::consts::TAU) / std::f64::consts::TAU,
                )
            }
        };
        let spacing = 0.5 * (seg[k] + seg[(k + m - 1) % m]);
        out[boundary[k] as usize] = [
            p[0] as f32,
            p[1] as f32,
            0.0,
            (ANCHOR_STIFFNESS * spacing) as f32,
        ];
        arc += seg[k];
    }
    out
}

/// The point at fraction `t` (mod 1) of a square's perimeter, counter-clockwise from its
/// lower-left corner, centred on the origin.
fn square_point(side: f64, t: f64) -> [f64; 2] {
    let u = t.rem_euclid(1.0) * 4.0;
    let (e, f) = (u.floor(), u - u.floor());
    let h = side / 2.0;
    match e as u32 {
        0 => [-h + f * side, -h],
        1 => [h, -h + f * side],
        2 => [h - f * side, h],
        _ => [-h, h - f * side],
    }
}

/// The most edges any vertex is from the boundary, and the longest shortest path from the
/// boundary along the edges (net units).
fn depth_from_boundary(
    nbrs: &[Vec<u32>],
    pos: &[DVec3],
    boundary: &[u32],
    unit: f64,
) -> (u32, f64) {
    let mut hops = vec![u32::MAX; nbrs.len()];
    let mut dist = vec![f64::INFINITY; nbrs.len()];
    let mut heap = std::collections::BinaryHeap::new();
    for &b in boundary {
        hops[b as usize] = 0;
        dist[b as usize] = 0.0;
        heap.push(std::cmp::Reverse((0u64, b)));
    }
    // Distances as fixed-point keys (1e-9 net units) for the heap.
    while let Some(std::cmp::Reverse((key, v))) = heap.pop() {
        let d = key as f64 * 1e-9;
        if d > dist[v as usize] + 1e-9 {
            continue;
        }
        for &w in &nbrs[v as usize] {
            let nd = dist[v as usize] + (pos[v as usize] - pos[w as usize]).length() / unit;
            if nd < dist[w as usize] {
                dist[w as usize] = nd;
                hops[w as usize] = hops[v as usize] + 1;
                heap.push(std::cmp::Reverse(((nd * 1e9) as u64, w)));
            }
        }
    }
    let far = hops
        .iter()
        .filter(|&&h| h != u32::MAX)
        .max()
        .copied()
        .unwrap_or(0);
    let deep = dist
        .iter()
        .filter(|d| d.is_finite())
        .fold(0.0, |a: f64, &d| a.max(d));
    (far, deep)
}

/// The net's energy at `x`: eq. 1's springs plus the frame springs, ½ k (l − L)² each (every edge
/// once), plus the plane pull.
pub fn energy(net: &Net, x: &[[f64; 3]]) -> f64 {
    let mut e = 0.0;
    for i in 0..net.len() {
        let xi = DVec3::from(x[i]);
        for s in net.offsets[i] as usize..net.offsets[i + 1] as usize {
            let j = net.other[s] as usize;
            if j > i {
                let [rest, k] = net.spring[s].map(f64::from);
                let l = (DVec3::from(x[j]) - xi).length();
                e += 0.5 * k * (l - rest) * (l - rest);
            }
        }
        let a = net.anchor[i];
        let d = DVec3::new(a[0] as f64, a[1] as f64, 0.0) - xi;
        e += 0.5 * a[3] as f64 * d.length_squared() + 0.5 * a[2] as f64 * xi.z * xi.z;
    }
    e
}

/// What a relaxation did.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Relaxed {
    /// Final positions (net units, 3D).
    #[serde(skip)]
    pub x: Vec<[f64; 3]>,
    /// Steps taken (0 when the state was solved directly: `pelt::tutte`).
    pub steps: u32,
    /// Conjugate-gradient iterations of a direct solve (`pelt::tutte`; 0 for the dynamics).
    pub iterations: u32,
    /// Whether it became steady (a direct solve: converged) before `max_steps`.
    pub steady: bool,
    /// Energy at the start and the end.
    pub energy: [f64; 2],
    /// The rest lengths' scale the pelt was kept at (`pelt::REST_SCALES`, or `pelt::START_SCALES`
    /// when a conformal refinement follows).
    pub rest_scale: f32,
}

/// The CPU twin: the dynamics in f64, checking steadiness as the GPU kernel does. `trace` (if
/// given) receives the energy after every check.
pub fn relax_cpu(net: &Net, cfg: &SystemCfg, mut trace: Option<&mut Vec<f64>>) -> Relaxed {
    let n = net.len();
    let mut x: Vec<DVec3> = net
        .start
        .iter()
        .map(|p| DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64))
        .collect();
    let mut v = vec![DVec3::ZERO; n];
    let e0 = energy(net, &to_arrays(&x));
    let damping = net.damping as f64;
    let (mut steps, mut steady) = (0, false);
    // Whole check intervals only, as the GPU runs them.
    let every = cfg.interval();
    while steps + every <= cfg.max_steps && !steady {
        for _ in 0..every {
            let f: Vec<DVec3> = (0..n).map(|i| force(net, &x, i)).collect();
            for i in 0..n {
                v[i] = v[i] * damping + f[i] * net.inv_mass[i] as f64;
                x[i] += v[i];
            }
            steps += 1;
        }
        let ke = v.iter().map(|w| w.length_squared()).sum::<f64>() / n.max(1) as f64;
        steady = ke < cfg.tol2;
        if let Some(t) = trace.as_deref_mut() {
            t.push(energy(net, &to_arrays(&x)));
        }
    }
    let x = to_arrays(&x);
    Relaxed {
        energy: [e0, energy(net, &x)],
        x,
        steps,
        iterations: 0,
        steady,
        rest_scale: 1.0,
    }
}

fn to_arrays(x: &[DVec3]) -> Vec<[f64; 3]> {
    x.iter().map(|p| p.to_array()).collect()
}

/// The force on vertex `i`: its springs and its frame spring.
fn force(net: &Net, x: &[DVec3], i: usize) -> DVec3 {
    let xi = x[i];
    let a = net.anchor[i];
    let mut f = (DVec3::new(a[0] as f64, a[1] as f64, 0.0) - xi) * a[3] as f64
        - DVec3::new(0.0, 0.0, xi.z * a[2] as f64);
    for s in net.offsets[i] as usize..net.offsets[i + 1] as usize {
        let d = x[net.other[s] as usize] - xi;
        let l = d.length();
        if l > 1e-12 {
            let [rest, k] = net.spring[s].map(f64::from);
            f += d * (k * (l - rest) / l);
        }
    }
    f
}
