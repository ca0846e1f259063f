// SPDX-License-Identifier: MIT OR Apache-2.0
//! Cone charts: a conformal chart opened along a cut at a cone-like tip, so a decal on a horn tip or
//! a box corner keeps its size out to its edges, not only at its centre.
//!
//! Around a point where the surface gathers Gaussian curvature Ω (the sum of the angle defects
//! 2π − Σ corner angles of the vertices there), the surface is locally a cone of total angle
//! θ = 2π − Ω: a cone singularity in the sense of Kharevych, Springborn & Schröder ("Discrete
//! conformal mappings via circle patterns", 2006, section 3). A flattening without a seam must spread
//! the missing angle over the whole chart: the conformal chart `w` grows like |w| ∝ r^(2π/θ) with the
//! geodesic distance r from the tip, so with its scale fixed at the placed point (chart step 3)
//! the image runs ahead of the surface (1.3× at half the decal's size on Spot's horn) and the decal
//! covers about half the surface the exponential map's does. No seamless map can keep both.
//!
//! The cone transform opens the chart instead. With q = (w − w₀) · conj(ρ) (w₀ the tip's image,
//! ρ = −e^{iφ_c} for a cut in direction φ_c; for the downward cut q = −i (w − w₀) and ρ = i),
//!
//! z = β + α · ρ · q^k,  k = θ / 2π,  principal branch (arg q in (−π, π]),
//!
//! maps the uncut chart onto a wedge of angle 2πk: on an exact cone of half-angle φ (k = sin φ) it is
//! the cone's isometric development, and on a rounded tip it undoes the growth outside the rounded
//! part. k is measured from the chart, as the k that makes the opened chart's scale at the decal's
//! outer half equal to its scale at the centre (`wedge`), not taken from Ω. The branch cut, where
//! the image is discontinuous, is the ray from the tip in direction φ_c ([`cut_angle`]): towards the
//! image's bottom edge for a decal on the tip, else away from the placed point, so it never runs
//! through the decal's centre. The wedge of the image that no surface receives ends up there, as
//! the exponential map leaves an unused wedge where its geodesics close. α (scale and turn) keeps
//! the chart's scale and orientation at the placed point; β keeps the placed point where it was.
//!
//! The coordinate slots keep `w`, which is continuous across the cut; every consumer applies the
//! transform: the raster per fragment (`wgsl/shared/cone.wgsl`), so the cut runs exactly through the
//! triangles it crosses; the selection per vertex, keeping the triangles the cut crosses and those
//! near the tip (whose opened edges bend most); the distortion measure, the fold check and
//! `decalbake param` per vertex, leaving out the triangles the cut crosses ([`Cone::cut_crosses`]),
//! whose per-vertex images would straddle the wedge.
//!
//! A chart gets a cone only where it needs one ([`fit`]): its scale over the vertices within half
//! the decal's size ([`CONE_CHECK`]) is more than [`CONE_TRIGGER`] times the size asked for, and
//! the surface there holds positive curvature. Charts everywhere else have no cut: a decal on a
//! smooth region, and the charts whose coordinates are used vertex by vertex
//! ([`super::ChartRequest::cone`] is false: a continuous stroke's corner charts, tool stamps).

use super::lscm::{self, cmul};
use crate::maps::Frame;
use crate::mesh::{Topology, NO_NEIGHBOR};
use glam::DVec2;
use rustc_hash::FxHashSet as HashSet;

/// A chart gets a cone when its scale over the vertices within [`CONE_CHECK`] × the decal's larger
/// side exceeds this (the size conformal decals hold within 10 %, `tests/conformal_size.rs`).
pub const CONE_TRIGGER: f64 = 1.1;
/// Radius (fraction of the decal's larger side) over which the scale is checked and the curvature
/// gathered: half the size, the decal's edge.
pub const CONE_CHECK: f64 = 0.5;
/// A tip closer than this fraction of the decal's side to the placed point counts as under it
/// ([`cut_angle`]).
pub const TIP_AT_POINT: f64 = 0.02;
/// Smallest wedge fraction k: a tip sharper than this (Ω > 1.75π) is treated as this one.
pub const MIN_WEDGE: f64 = 0.25;

/// The cone transform of a chart (see the module docs), in the chart's model units.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Cone {
    /// The tip's image w₀ in the uncut chart.
    pub tip: [f64; 2],
    /// Direction of the cut from the tip (radians from the image's +x axis): −π/2 (the image's
    /// bottom) when the tip is near the placed point, else away from the placed point
    /// ([`cut_angle`]).
    pub cut: f64,
    /// Wedge fraction k = θ / 2π (measured, `wedge`).
    pub k: f64,
    /// Complex scale and turn α.
    pub alpha: [f64; 2],
    /// Offset β.
    pub beta: [f64; 2],
    /// The Gaussian curvature Ω gathered at the tip (radians).
    pub curvature: f64,
}

impl Cone {
    /// ρ = −e^{iφ_c}, the unit complex number that turns the cut onto q's negative real axis.
    fn rho(&self) -> DVec2 {
        -DVec2::new(self.cut.cos(), self.cut.sin())
    }

    /// q = (w − w₀) · conj(ρ) (= −i (w − w₀) for the downward cut), with −0 as +0 in its imaginary
    /// part, so a point on the cut's line is on the same side in Rust and WGSL.
    fn q(&self, w: DVec2) -> DVec2 {
        let d = w - DVec2::from(self.tip);
        let r = self.rho();
        let q = cmul(d, DVec2::new(r.x, -r.y));
        DVec2::new(q.x, if q.y == 0.0 { 0.0 } else { q.y })
    }

    /// ρ q^k on the principal branch, before α and β.
    fn raw(&self, w: DVec2) -> DVec2 {
        let q = self.q(w);
        let r = q.length();
        if r == 0.0 {
            return DVec2::ZERO;
        }
        let a = self.k * q.y.atan2(q.x);
        let m = r.powf(self.k);
        cmul(self.rho(), DVec2::new(m * a.cos(), m * a.sin()))
    }

    /// The opened chart's coordinates of a point the uncut chart puts at `w`.
    pub fn apply(&self, w: DVec2) -> DVec2 {
        cmul(DVec2::from(self.alpha), self.raw(w)) + DVec2::from(self.beta)
    }

    /// Whether the cut crosses the triangle with uncut images `w`: some edge meets the ray from the
    /// tip in the cut's direction (q's negative real axis). A triangle around the tip always does.
    pub fn cut_crosses(&self, w: [DVec2; 3]) -> bool {
        let q = w.map(|w| self.q(w));
        (0..3).any(|i| {
            let (a, b) = (q[i], q[(i + 1) % 3]);
            if (a.y >= 0.0) == (b.y >= 0.0) {
                return false;
            }
            a.x + (b.x - a.x) * a.y / (a.y - b.y) < 0.0
        })
    }

    /// Whether the triangle with uncut images `w` lies near the tip: a corner closer to it than the
    /// triangle's own extent (its opened edges bend most; the selection keeps it).
    pub fn near_tip(&self, w: [DVec2; 3]) -> bool {
        let ext = w[0].max(w[1]).max(w[2]) - w[0].min(w[1]).min(w[2]);
        let tip = DVec2::from(self.tip);
        w.iter()
            .map(|p| (*p - tip).length())
            .fold(f64::INFINITY, f64::min)
            < ext.max_element()
    }

    /// The two `vec4`s of the WGSL `Params` (`cone_a`: tip, k, cut angle; `cone_b`: α, β).
    pub fn params(&self) -> ([f32; 4], [f32; 4]) {
        (
            [
                self.tip[0] as f32,
                self.tip[1] as f32,
                self.k as f32,
                self.cut as f32,
            ],
            [
                self.alpha[0] as f32,
                self.alpha[1] as f32,
                self.beta[0] as f32,
                self.beta[1] as f32,
            ],
        )
    }
}

/// What the chart builder knows of a chart when it decides on a cone.
pub struct ChartView<'a> {
    /// The chart's triangles.
    pub triangles: &'a [u32],
    /// The uncut, normalised chart coordinate of a chart vertex.
    pub coord: &'a dyn Fn(u32) -> DVec2,
    /// The decal frame.
    pub frame: &'a Frame,
    /// The placed triangle.
    pub seed_triangle: u32,
}

/// The cone a chart needs, or `None` (see the module docs): the scale over the vertices within
/// [`CONE_CHECK`] × the larger side must exceed [`CONE_TRIGGER`] and the curvature Ω gathered by
/// the chart's interior vertices within that radius must be positive (at least 0.05 · 2π). The tip
/// is the chart image of those vertices weighted by their positive angle defects; k is measured
/// from the chart (`wedge`); α and β keep the scale, turn and image of the placed point.
pub fn fit(topo: &Topology, c: &ChartView) -> Option<Cone> {
    let side = c.frame.size[0].max(c.frame.size[1]) as f64;
    let p = c.frame.center.as_dvec3();
    let st = topo.triangles[c.seed_triangle as usize];
    let bary = lscm::barycentric(st.map(|v| topo.positions[v as usize].as_dvec3()), p);
    let zs = st
        .iter()
        .zip(bary)
        .fold(DVec2::ZERO, |a, (&v, b)| a + b * (c.coord)(v));
    let coord = |v: u32| (c.coord)(v).to_array();
    let radius = CONE_CHECK * side;
    let scale = lscm::scale_at(topo, c.triangles, &coord, c.seed_triangle, p, zs, radius)?;
    if scale <= CONE_TRIGGER {
        return None;
    }
    let inside: HashSet<u32> = c.triangles.iter().copied().collect();
    let mut verts: Vec<u32> = c
        .triangles
        .iter()
        .flat_map(|&t| topo.triangles[t as usize])
        .collect();
    verts.sort_unstable();
    verts.dedup();
    verts.retain(|&v| (topo.positions[v as usize].as_dvec3() - p).length() <= radius);
    let (mut omega, mut weight, mut tip) = (0.0, 0.0, DVec2::ZERO);
    for &v in &verts {
        let Some(d) = angle_defect(topo, v, &inside) else {
            continue;
        };
        omega += d;
        if d > 0.0 {
            weight += d;
            tip += d * (c.coord)(v);
        }
    }
    if omega < 0.05 * std::f64::consts::TAU || weight <= 0.0 {
        return None;
    }
    let tip = tip / weight;
    let cut = cut_angle(tip, zs, side);
    let k = wedge(topo, c, (tip, cut), zs)?;
    let mut cone = Cone {
        tip: tip.to_array(),
        cut,
        k: k.clamp(MIN_WEDGE, 1.0),
        alpha: [1.0, 0.0],
        beta: [0.0, 0.0],
        curvature: omega,
    };
    let alpha = keep_at_point(topo, c, &cone, zs)?;
    cone.alpha = alpha.to_array();
    cone.beta = (zs - cmul(alpha, cone.raw(zs))).to_array();
    Some(cone)
}

/// The wedge fraction k the chart needs: the k for which the opened chart's scale (median of
/// |z_v − z_p| / |x_v − p|) over the decal's outer half (vertices at 0.25 to 0.5 × the side from the
/// placed point) equals its scale near the point (the ring of `keep_at_point`), found by
/// bisection in [[`MIN_WEDGE`], 1] (the ratio falls as k does). Measured, not derived from the
/// angle defects: on a rounded tip Ω counts curvature that lies beyond the vertices nearer the tip,
/// and k = 1 − Ω / 2π over-opens the chart (Spot's horn: 0.18 from Ω); a log-log fit of the
/// growth from the tip weighs the rounded cap, where the chart does not grow, and under-opens it.
/// `None` when the chart does not outgrow the surface at k = 1.
fn wedge(topo: &Topology, c: &ChartView, (tip, cut): (DVec2, f64), zs: DVec2) -> Option<f64> {
    let side = c.frame.size[0].max(c.frame.size[1]) as f64;
    let near = ring(topo, c, side);
    let outer: Vec<(f64, u32)> = vertices_by_distance(topo, c)
        .into_iter()
        .filter(|e| e.0 > 0.25 * side && e.0 <= CONE_CHECK * side)
        .collect();
    if outer.len() < RING_MIN {
        return None;
    }
    let ratio = |k: f64| -> Option<f64> {
        let cone = Cone {
            tip: tip.to_array(),
            cut,
            k,
            alpha: [1.0, 0.0],
            beta: [0.0, 0.0],
            curvature: 0.0,
        };
        let zr = cone.raw(zs);
        let median = |set: &[(f64, u32)]| -> Option<f64> {
            let mut r: Vec<f64> = set
                .iter()
                .filter(|e| e.0 > 1e-9 * side)
                .map(|&(d, v)| (cone.raw((c.coord)(v)) - zr).length() / d)
                .collect();
            r.sort_by(f64::total_cmp);
            r.get(r.len() / 2).copied()
        };
        Some(median(&outer)? / median(&near)?)
    };
    if ratio(1.0)? <= 1.0 {
        return None;
    }
    if ratio(MIN_WEDGE)? >= 1.0 {
        return Some(MIN_WEDGE);
    }
    let (mut lo, mut hi) = (MIN_WEDGE, 1.0);
    for _ in 0..40 {
        let mid = 0.5 * (lo + hi);
        if ratio(mid)? > 1.0 {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    Some(0.5 * (lo + hi))
}

/// The cut's direction from the tip for a decal placed at `zs` (images in the uncut chart): away
/// from the placed point, so the cut never crosses the decal's centre, unless the tip is within
/// [`TIP_AT_POINT`] × the decal's side of it (a decal on the tip itself, where that direction is
/// noise that would differ between the GPU's and the CPU's charts): then towards the image's bottom
/// edge (−π/2), the side a decal's `up` points away from.
pub fn cut_angle(tip: DVec2, zs: DVec2, side: f64) -> f64 {
    let d = tip - zs;
    if d.length() > TIP_AT_POINT * side {
        d.y.atan2(d.x)
    } else {
        -std::f64::consts::FRAC_PI_2
    }
}

/// The chart's vertices with their distance from the placed point, nearest first.
fn vertices_by_distance(topo: &Topology, c: &ChartView) -> Vec<(f64, u32)> {
    let p = c.frame.center.as_dvec3();
    let mut verts: Vec<(f64, u32)> = c
        .triangles
        .iter()
        .flat_map(|&t| topo.triangles[t as usize])
        .map(|v| ((topo.positions[v as usize].as_dvec3() - p).length(), v))
        .collect();
    verts.sort_by_key(|e| e.1);
    verts.dedup_by_key(|e| e.1);
    verts.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    verts
}

/// The vertices within [`super::CHECK_RADIUS`] × the side of the placed point, at least the
/// [`RING_MIN`] nearest (coarse meshes).
fn ring(topo: &Topology, c: &ChartView, side: f64) -> Vec<(f64, u32)> {
    let verts = vertices_by_distance(topo, c);
    let radius = (super::CHECK_RADIUS * side).max(verts.get(RING_MIN).map_or(0.0, |e| e.0));
    verts.into_iter().take_while(|e| e.0 <= radius).collect()
}

/// α for `cone`. Scale: over the chart's vertices within [`super::CHECK_RADIUS`] × the larger side
/// of the placed point (at least its [`RING_MIN`] nearest, for coarse meshes), the inverse of the
/// median of |raw(w) − raw(zs)| / |x − p| (`zs`: the placed point's image). The ring is wider than
/// the chart's own normalisation ring ([`super::FIT_RADIUS`]) because inside a rounded tip the
/// opened chart's scale varies (the curvature is not all at one point); this radius is where the
/// report and the tests hold the size. Turn: the circular mean of the angles by which the raw
/// transform turns [`TURN_SAMPLES`] evenly spaced directions from `zs` (at the ring's median
/// distance in the chart), so that on average the directions at the placed point keep the frame's
/// orientation. Directions, not the ring's vertices: a direction next to the cut turns by about
/// ±(1 − k)π depending on its side, and a vertex lying on the cut (a symmetric mesh has them) would
/// make the turn depend on the last bit of the chart, so the GPU and CPU charts would disagree by a
/// degree; evenly spaced directions, none on the cut when the tip is at `zs`, average both sides.
fn keep_at_point(topo: &Topology, c: &ChartView, cone: &Cone, zs: DVec2) -> Option<DVec2> {
    let side = c.frame.size[0].max(c.frame.size[1]) as f64;
    let verts = ring(topo, c, side);
    let zr = cone.raw(zs);
    let (mut ratios, mut reach) = (Vec::new(), Vec::new());
    for &(d, v) in &verts {
        let w = (c.coord)(v) - zs;
        let b = cone.raw((c.coord)(v)) - zr;
        if d <= 1e-9 * side || w.length() <= 0.0 || b.length() <= 0.0 {
            continue;
        }
        ratios.push(b.length() / d);
        reach.push(w.length());
    }
    ratios.sort_by(f64::total_cmp);
    reach.sort_by(f64::total_cmp);
    let scale = *ratios.get(ratios.len() / 2)?;
    let rho = *reach.get(reach.len() / 2)?;
    let mut turn = DVec2::ZERO;
    for j in 0..TURN_SAMPLES {
        let t = (j as f64 + 0.5) / TURN_SAMPLES as f64 * std::f64::consts::TAU;
        let a = DVec2::new(t.cos(), t.sin());
        let b = cone.raw(zs + rho * a) - zr;
        if b.length() > 0.0 {
            // a / b as a unit complex number.
            turn += cmul(a, DVec2::new(b.x, -b.y).normalize());
        }
    }
    let turn = if turn.length() > 0.0 {
        turn.normalize()
    } else {
        DVec2::X
    };
    Some(turn / scale)
}

/// Directions `keep_at_point` averages the turn over (a multiple of 4: with the half-step offset
/// none lies on a downward cut from a tip at the placed point).
pub const TURN_SAMPLES: usize = 64;

/// Fewest vertices `keep_at_point` measures over.
pub const RING_MIN: usize = 8;

/// The angle defect 2π − Σ corner angles of `v`, when its whole fan lies in `inside` and closes
/// (not on a mesh boundary); `None` otherwise.
pub fn angle_defect(topo: &Topology, v: u32, inside: &HashSet<u32>) -> Option<f64> {
    let mut sum = 0.0;
    for &t in topo.triangles_around(v) {
        if topo.degenerate[t as usize] || !inside.contains(&t) {
            return None;
        }
        let tri = topo.triangles[t as usize];
        let k = tri.iter().position(|&u| u == v)?;
        // The two edges at v, and whether the fan continues across both.
        for e in [k, (k + 2) % 3] {
            if topo.triangle_neighbors[t as usize][e] == NO_NEIGHBOR {
                return None;
            }
        }
        let x = topo.positions[v as usize].as_dvec3();
        let a = topo.positions[tri[(k + 1) % 3] as usize].as_dvec3() - x;
        let b = topo.positions[tri[(k + 2) % 3] as usize].as_dvec3() - x;
        sum += a.angle_between(b);
    }
    Some(std::f64::consts::TAU - sum)
}
