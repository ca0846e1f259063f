// SPDX-License-Identifier: MIT OR Apache-2.0
//! A path's smooth curve (`"interpolate": "catmull-rom"`, the default): the centripetal
//! Catmull-Rom spline through the path's points, laid on the surface.
//!
//! **The spline.** Segment k, from point P_k to P_k+1, is the Barry-Goldman pyramid over the four
//! points P_k-1 .. P_k+2 with knot intervals |P_j+1 − P_j|^½ (centripetal: Yuksel, Schaefer and
//! Keyser 2011; no cusps or self-intersections within a segment, and it stays close to the
//! polygon where the points are unevenly spaced). It passes through every point with a continuous
//! tangent. Points evenly spaced on a circle, 7.5° apart, give a curve within 7e-6 × the radius of
//! the circle (22.5° apart: 5.5e-4, 11.25° apart: 3.5e-5; the error falls as the fourth power of
//! the spacing); its tangent wavers more, so the nearest points of points beside it shift along it
//! (a ribbon's u, 0.1 from a quarter circle of radius 0.5 through 13 points: 4.8e-5 × the radius;
//! the error falls as the cube of the spacing). An open path's ends get the point one step further on the circle through the
//! first (last) three points: the mirror image of P_2 across the plane halfway between P_0 and
//! P_1 (a straight extension, 2 P_0 − P_1, would flatten the end segment: 1.3e-3 × the radius on
//! that circle). A closed path (its last point on its first) takes its neighbours around the loop.
//!
//! **On the surface.** The spline is a 3D curve, and the path's points may lie far apart on a
//! curved surface, where the 3D curve between them cuts through the model. So the curve is laid
//! on the surface as a correction of the geodesic join ([`super::path`]): at parameter t of
//! segment k, the point of the geodesic a fraction t of the way along it is moved by the spline's
//! offset from the chord, C(t) − ((1 − t) P_k + t P_k+1), and projected onto the surface (its
//! nearest point on the part of the mesh around the geodesic's point, [`project`]). On a plane
//! the geodesic is the chord and the curve is the spline itself; on a curved surface the offset
//! is small beside the segment and the projection stays local. A two-point path has no offset.
//!
//! **Sampling.** Each segment is sampled every quarter of the mean edge (as the geodesic walk
//! is), and so densely that each piece turns by at most [`MAX_TURN`]: a piece's chord then lies
//! within (turn)² / 8 ≈ 7.6e-6 × the radius of curvature of the curve.

use super::path::SurfacePath;
use crate::mesh::{Topology, NO_NEIGHBOR};
use crate::place::closest_barycentric;
use glam::Vec3;
use rustc_hash::FxHashSet;

/// The most a piece of the sampled curve turns by (radians).
pub const MAX_TURN: f32 = 1.0 / 128.0;

/// The most pieces one segment is sampled with.
const MAX_SAMPLES: usize = 1 << 16;

/// Samples of a segment's spline taken to measure how much it turns.
const PROBES: usize = 32;

/// One segment of a centripetal Catmull-Rom spline: its four control points and their knots.
#[derive(Debug, Clone, Copy)]
pub struct Segment {
    p: [Vec3; 4],
    t: [f32; 4],
}

impl Segment {
    /// The segment from `p[1]` to `p[2]`, `p[0]` and `p[3]` its outer neighbours (consecutive
    /// points distinct).
    pub fn new(p: [Vec3; 4]) -> Self {
        let mut t = [0.0f32; 4];
        for j in 1..4 {
            t[j] = t[j - 1] + (p[j] - p[j - 1]).length().sqrt().max(1e-12);
        }
        Self { p, t }
    }

    /// The point at fraction `f` of the segment's parameter (0 at `p[1]`, 1 at `p[2]`): the
    /// Barry-Goldman pyramid of linear interpolations.
    pub fn at(&self, f: f32) -> Vec3 {
        let (p, t) = (&self.p, &self.t);
        let x = t[1] + (t[2] - t[1]) * f;
        let mix = |a: Vec3, b: Vec3, ta: f32, tb: f32| a.lerp(b, (x - ta) / (tb - ta));
        let a1 = mix(p[0], p[1], t[0], t[1]);
        let a2 = mix(p[1], p[2], t[1], t[2]);
        let a3 = mix(p[2], p[3], t[2], t[3]);
        let b1 = mix(a1, a2, t[0], t[2]);
        let b2 = mix(a2, a3, t[1], t[3]);
        mix(b1, b2, t[1], t[2])
    }

    /// How far the segment turns (the angles between consecutive chords of [`PROBES`] samples).
    fn turning(&self) -> f32 {
        let pts: Vec<Vec3> = (0..=PROBES)
            .map(|j| self.at(j as f32 / PROBES as f32))
            .collect();
        pts.windows(3)
            .map(|w| (w[1] - w[0]).angle_between(w[2] - w[1]))
            .filter(|a| a.is_finite())
            .sum()
    }
}

/// The segments of the centripetal Catmull-Rom spline through `points` (consecutive points
/// distinct, at least two), one per consecutive pair; the outer neighbours of an open path's
/// ends are `beyond` them, a closed path's (last point equal to the first, at least three
/// segments) are its points around the loop.
pub fn segments(points: &[Vec3]) -> Vec<Segment> {
    let n = points.len();
    let closed = n >= 4 && points[0] == points[n - 1];
    let before = match (closed, n) {
        (true, _) => points[n - 2],
        (false, 2) => 2.0 * points[0] - points[1],
        (false, _) => beyond(points[0], points[1], points[2]),
    };
    let after = match (closed, n) {
        (true, _) => points[1],
        (false, 2) => 2.0 * points[1] - points[0],
        (false, _) => beyond(points[n - 1], points[n - 2], points[n - 3]),
    };
    (0..n - 1)
        .map(|k| {
            let prev = if k == 0 { before } else { points[k - 1] };
            let next = if k + 2 < n { points[k + 2] } else { after };
            Segment::new([prev, points[k], points[k + 1], next])
        })
        .collect()
}

/// The point one step beyond end point `a` of a path whose next points are `b` and `c`: `c`
/// mirrored across the plane halfway between `a` and `b` (on a circle through the three, evenly
/// spaced, the circle's next point; on a line, the line's).
fn beyond(a: Vec3, b: Vec3, c: Vec3) -> Vec3 {
    let n = (b - a).normalize_or_zero();
    let mid = 0.5 * (a + b);
    c - 2.0 * (c - mid).dot(n) * n
}

/// The path through the same points as `joined` (the geodesic join of `points`, whose knots are
/// at them) along their Catmull-Rom spline, laid on the surface of `topo` and sampled every `step`
/// at most (see the module's notes). Knots stay at the path's points; coincident consecutive
/// points share a knot. A path of fewer than three distinct points is `joined` itself.
pub fn smooth(topo: &Topology, joined: &SurfacePath, points: &[Vec3], step: f32) -> SurfacePath {
    // The distinct points and, per path point, the distinct point it is.
    let mut distinct: Vec<Vec3> = Vec::with_capacity(points.len());
    let mut which = Vec::with_capacity(points.len());
    for &p in points {
        if distinct.last() != Some(&p) {
            distinct.push(p);
        }
        which.push(distinct.len() - 1);
    }
    if distinct.len() < 3 {
        return joined.clone();
    }
    // The joined path's knot at each distinct point (the first of a run of coincident ones).
    let mut knot = vec![0.0; distinct.len()];
    for (k, &d) in which.iter().enumerate().rev() {
        knot[d] = joined.knots[k];
    }
    let mut out = SurfacePath {
        points: vec![joined.points[0]],
        triangles: Vec::new(),
        arc: vec![0.0],
        knots: Vec::with_capacity(points.len()),
    };
    let segs = segments(&distinct);
    let mut done = 0;
    for &d in &which {
        while done < d {
            let chord = (distinct[done], distinct[done + 1]);
            let span = (knot[done], knot[done + 1]);
            lay(topo, joined, (&segs[done], chord, span), step, &mut out);
            done += 1;
        }
        out.knots.push(out.length());
    }
    out
}

/// Appends to `out` segment `seg` of the spline, from `chord.0` to `chord.1`, laid on the surface
/// along the joined path's stretch `span` (the geodesic between the two points).
fn lay(
    topo: &Topology,
    joined: &SurfacePath,
    (seg, chord, span): (&Segment, (Vec3, Vec3), (f32, f32)),
    step: f32,
    out: &mut SurfacePath,
) {
    let length = (span.1 - span.0).max((chord.1 - chord.0).length());
    let by_length = (length / step).ceil();
    let by_turn = (seg.turning() / MAX_TURN).ceil();
    let n = (by_length.max(by_turn).max(1.0) as usize).min(MAX_SAMPLES);
    for j in 1..=n {
        let f = j as f32 / n as f32;
        let (piece, on) = joined.at(span.0 + f * (span.1 - span.0));
        let offset = seg.at(f) - chord.0.lerp(chord.1, f);
        let triangle = joined.triangles[piece.min(joined.triangles.len() - 1)];
        let (p, t) = if j == n {
            (chord.1, joined.triangles[end_piece(joined, span.1)])
        } else {
            project(topo, on + offset, (on, triangle))
        };
        push(out, p, t);
    }
}

/// The piece of `joined` that ends at arc length `s` (the one before a knot).
fn end_piece(joined: &SurfacePath, s: f32) -> usize {
    joined
        .arc
        .partition_point(|&a| a < s)
        .clamp(1, joined.arc.len() - 1)
        - 1
}

/// The nearest point to `x` of the part of the surface around `near` (a point of the surface in or
/// beside triangle `from`), and its triangle: the triangles reached from `from` across edges while
/// they come within |x − near| of `x` (a ball around `x` that holds `near`), so the point stays on
/// the sheet the path runs on where another part of the model passes close by.
pub fn project(topo: &Topology, x: Vec3, (near, from): (Vec3, u32)) -> (Vec3, u32) {
    let closest = |t: u32, x: Vec3| {
        let [a, b, c] = topo.triangles[t as usize].map(|v| topo.positions[v as usize]);
        let l = closest_barycentric(x, a, b, c);
        l.x * a + l.y * b + l.z * c
    };
    // `near` may lie beside `from` (on a piece's chord, in the next triangle): the ball reaches
    // the surface there too.
    let slack = (closest(from, near) - near).length();
    let reach = ((x - near).length() + slack) * (1.0 + 1e-4) + 1e-7 * near.length().max(1.0);
    let closest = |t: u32| closest(t, x);
    let mut best = (closest(from), from);
    let mut seen = FxHashSet::default();
    let mut queue = vec![from];
    seen.insert(from);
    while let Some(t) = queue.pop() {
        for &m in &topo.triangle_neighbors[t as usize] {
            if m == NO_NEIGHBOR || topo.degenerate[m as usize] || !seen.insert(m) {
                continue;
            }
            let q = closest(m);
            if (q - x).length() > reach {
                continue;
            }
            if (q - x).length() < (best.0 - x).length() {
                best = (q, m);
            }
            queue.push(m);
        }
    }
    best
}

/// Appends point `p`, reached through triangle `t`, unless it is where the path already is.
fn push(path: &mut SurfacePath, p: Vec3, t: u32) {
    let last = *path.points.last().expect("a path starts with a point");
    let d = (p - last).length();
    if d <= 0.0 {
        return;
    }
    let s = path.length() + d;
    path.points.push(p);
    path.triangles.push(t);
    path.arc.push(s);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Samples of every segment through `points`, `per` a segment.
    fn sampled(points: &[Vec3], per: usize) -> Vec<Vec3> {
        segments(points)
            .iter()
            .flat_map(|s| (0..=per).map(move |j| s.at(j as f32 / per as f32)))
            .collect()
    }

    /// Through 13 points 7.5° apart on a circle of radius 0.5 the spline stays within 1e-5 × r
    /// of the circle, end segments included (measured 6.9e-6 × r; with the straight extension
    /// 2 P_0 − P_1 beyond the ends instead, 1.3e-3 × r), and passes through the points.
    #[test]
    fn circle_points_give_the_circle() {
        let r = 0.5;
        let points: Vec<Vec3> = (0..13)
            .map(|k| {
                let t = std::f32::consts::FRAC_PI_2 * k as f32 / 12.0;
                Vec3::new(r * t.cos(), r * t.sin(), 0.0)
            })
            .collect();
        let off = sampled(&points, 64)
            .iter()
            .map(|p| (p.length() - r).abs())
            .fold(0.0f32, f32::max);
        assert!(off < 1e-5 * r, "{:.2e} × r off the circle", off / r);
        for (k, s) in segments(&points).iter().enumerate() {
            assert!((s.at(0.0) - points[k]).length() < 1e-6);
            assert!((s.at(1.0) - points[k + 1]).length() < 1e-6);
        }
    }

    /// Points on a line, unevenly spaced, give the line, travelled forwards.
    #[test]
    fn collinear_points_give_their_line() {
        let dir = Vec3::new(1.0, 2.0, -0.5).normalize();
        let points: Vec<Vec3> = [0.0, 0.1, 0.5, 0.55, 1.5].map(|s| s * dir).to_vec();
        let samples = sampled(&points, 32);
        for w in samples.windows(2) {
            assert!(w[0].cross(dir).length() < 1e-6, "{} off the line", w[0]);
            assert!((w[1] - w[0]).dot(dir) >= -1e-7, "backwards at {}", w[0]);
        }
    }

    /// A closed path (last point on the first) turns smoothly at its first point: the last
    /// segment arrives in the direction the first leaves.
    #[test]
    fn closed_paths_close_smoothly() {
        let points = [
            Vec3::ZERO,
            Vec3::X,
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::Y,
            Vec3::ZERO,
        ];
        let segs = segments(&points);
        let h = 1e-3;
        let leave = (segs[0].at(h) - segs[0].at(0.0)).normalize();
        let last = segs.last().unwrap();
        let arrive = (last.at(1.0) - last.at(1.0 - h)).normalize();
        assert!(leave.angle_between(arrive) < 1e-2, "{leave} vs {arrive}");
    }
}
