// SPDX-License-Identifier: MIT OR Apache-2.0
//! The extended exponential map of a curve (Sun et al. 2013, "Texture Brush", section 3): every
//! surface point near a curve γ gets u, the arc length of its foot point on γ (plus the tangential
//! offset past γ's ends), and v, its signed geodesic distance to γ (positive on the left of γ seen
//! from outside the surface, that is along N × T). Strips along γ are then laid out like the plane
//! along a straight line: the coordinates of a ribbon layer.
//!
//! [`ribbon_cpu`] is the CPU twin; [`gpu`] computes the same fixed point by parallel relaxation
//! (`wgsl/maps/ribbon_relax.wgsl`), which ribbon layers bake with (`bake/maps.rs`, the ribbon
//! pass); [`repair`] re-solves the highly curved parts harmonically (section 3, steps 4-5).
//! The algorithm is the exponential map's
//! (Schmidt et al. 2006, section 4.2; [`crate::maps::expmap::cpu::dem_cpu`]) with the seed point
//! replaced by the curve:
//! 1. **Seeds**: the vertices of every triangle γ crosses get their exact foot on γ's polyline (the
//!    nearest point of the pieces in their triangles) and their offset from it, read in γ's frame
//!    there (T along γ, B = N × T).
//! 2. **Propagation**: Dijkstra on graph distance from the seeds (Bellman-Ford's fixed point, as the
//!    exponential map's relaxation); a vertex q reached from its upwind neighbour r takes r's foot
//!    and r's offset plus the edge r→q laid into r's tangent plane and turned into the foot's plane
//!    (the paper's update, [`crate::maps::expmap::cpu::transfer`]).
//! 3. **Sliding**: the foot then slides along γ by the offset's tangential part, the offset re-read
//!    in the new foot's frame (`slide`), so that the foot is the nearest point of γ and not the
//!    root of q's Dijkstra path (which wanders along γ by a few edges). On a plane this is exact for
//!    γ's polyline; on curved surfaces it treats the strip between the two feet as flat, an error of
//!    the order of the offset times the curvature that shrinks with the strip's width.
//! 4. **Reading**: the offset is read against the smooth curve the polyline samples, each piece as
//!    a circular arc with γ's mean curvature over the stretch the strip reaches (`Framed::fermi`,
//!    `Turning::curvature`), not against the polyline, whose corners would put an error of |v|
//!    times half the turning angle into u. Inside a turn no point is read at or beyond its arc's
//!    centre (`reading_curvature`).
//!
//! Tested against analytic Fermi coordinates (`tests/ribbon.rs`): a circular arc on a plane (1.6e-5
//! for chords of 0.01), path points on circles on a plane, both sides of the curve (4.8e-5 × the
//! radius along their spline, within the polyline's own error along the polyline), and a helix on
//! a cylinder (converging under refinement).
//!

use crate::maps::expmap::cpu::{transfer, Item, Seed};
use crate::mesh::Topology;
use glam::{Vec2, Vec3};
use std::collections::BinaryHeap;

/// A curve on the surface: a polyline whose pieces each lie in one triangle (a stroke's
/// `SurfacePath`, `bake/kinds/stroke/path.rs`, has this shape).
#[derive(Debug, Clone)]
pub struct Curve {
    /// Polyline points, model units.
    pub points: Vec<Vec3>,
    /// Per piece (`points[k]` to `points[k + 1]`): the welded triangle it lies in.
    pub triangles: Vec<u32>,
}

pub mod gpu;
pub mod repair;

/// `"kind": "ribbon"` as a map method: its coordinates come from the bake's ribbon pass
/// (`bake/maps.rs`, [`gpu::run`]), not from the exponential-map, chart or direct passes.
pub struct RibbonMethod;

impl super::MapMethod for RibbonMethod {
    /// The CPU twin of the whole bake (`bake::cpu::bake_cpu`) takes decals and strokes; a ribbon's
    /// map has its own twin, [`ribbon_cpu`].
    fn cpu_coords(
        &self,
        _topo: &Topology,
        _layer: &crate::io::job::Layer,
        _frame: &super::Frame,
        _at: (u32, bool),
        _expmap: Option<Vec<[f32; 4]>>,
    ) -> super::CpuCoords {
        panic!("bake::cpu::bake_cpu takes decal and stroke layers; for ribbons use bake::cpu::bake_units_cpu with Engine::units' ribbon units (bake::cpu::ribbon_coords_cpu)")
    }
}

/// One piece's frame: start point, unit tangent, unit normal (its triangle's), N × T, length, arc
/// length at its start and the curvature it is read with ([`Turning::curvature`]).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Piece {
    start: Vec3,
    t: Vec3,
    n: Vec3,
    b: Vec3,
    len: f32,
    arc: f32,
    kappa: f32,
}

/// A piece as the GPU reads it. Keep in sync with `Piece` in `wgsl/maps/ribbon_relax.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct GpuPiece {
    start: [f32; 4],
    t: [f32; 4],
    n: [f32; 4],
    b: [f32; 4],
}

impl From<&Piece> for GpuPiece {
    fn from(p: &Piece) -> Self {
        Self {
            start: p.start.extend(p.arc).to_array(),
            t: p.t.extend(p.len).to_array(),
            n: p.n.extend(p.kappa).to_array(),
            b: p.b.extend(0.0).to_array(),
        }
    }
}

/// The curve as framed pieces (zero-length pieces dropped).
pub(crate) struct Framed {
    pub(crate) pieces: Vec<Piece>,
    pub(crate) length: f32,
}

/// A seed vertex (a vertex of a triangle the curve crosses): its foot's piece and arc length, its
/// offset in that piece's frame and its distance (the offset's length).
#[derive(Debug, Clone, Copy)]
pub(crate) struct SeedFoot {
    pub vertex: u32,
    pub piece: u32,
    pub s: f32,
    pub off: Vec2,
    pub dist: f32,
}

impl Framed {
    /// The pieces of `c` with their frames, each with the curvature γ turns with over the stretch
    /// within `reach` of its middle ([`Turning::curvature`]): the strip reaches that far from γ.
    pub(crate) fn new(topo: &Topology, c: &Curve, reach: f32) -> Self {
        let mut pieces = Vec::new();
        let mut arc = 0.0;
        for (k, &tri) in c.triangles.iter().enumerate() {
            let (a, b) = (c.points[k], c.points[k + 1]);
            let len = (b - a).length();
            if len <= 0.0 {
                continue;
            }
            let [i, j, l] = topo.triangles[tri as usize].map(|v| topo.positions[v as usize]);
            let n = (j - i).cross(l - i).normalize_or_zero();
            let t = ((b - a) - n * (b - a).dot(n)).normalize_or(b - a);
            pieces.push(Piece {
                start: a,
                t,
                n,
                b: n.cross(t),
                len,
                arc,
                kappa: 0.0,
            });
            arc += len;
        }
        let turning = Turning::new(&pieces);
        for p in &mut pieces {
            p.kappa = turning.curvature(p.arc + 0.5 * p.len, reach);
        }
        Self {
            pieces,
            length: arc,
        }
    }

    /// The piece holding arc length `s` (the last one at the end).
    fn piece_at(&self, s: f32) -> usize {
        self.pieces
            .partition_point(|p| p.arc <= s)
            .clamp(1, self.pieces.len())
            - 1
    }

    /// The point at arc length `s` on the line of piece `k`.
    fn point_on(&self, k: usize, s: f32) -> Vec3 {
        let p = &self.pieces[k];
        p.start + p.t * (s - p.arc)
    }

    /// (u, v) of the point at offset `off` (piece `k`'s frame) from the foot at arc length `s`.
    /// The polyline samples a smooth curve; reading the offset against the polyline itself would
    /// leave an error of |v| times half the turning angle at each knot (beside a convex corner no
    /// perpendicular foot exists, beside a concave one two do: 2.5e-3 in the plane test's strip).
    /// So the piece is read as the circular arc through its two ends with the curvature γ turns
    /// with there ([`Turning::curvature`], limited by [`reading_curvature`]): v is the signed
    /// distance to that arc and u the arc length of the point's radial foot on it, scaled so that
    /// the piece keeps its length (u stays continuous from piece to piece). Past γ's ends the
    /// offset continues straight ([`Framed::past_end`]).
    fn fermi(&self, k: usize, s: f32, off: Vec2) -> [f32; 2] {
        if let Some(uv) = self.past_end(k, s, off) {
            return uv;
        }
        let p = &self.pieces[k];
        let kappa = reading_curvature(p.kappa, off.y);
        if kappa.abs() * p.len < 1e-5 {
            return [s + off.x, off.y];
        }
        // In the piece's frame from its start: the point, the arc's centre.
        let at = Vec2::new(s - p.arc + off.x, off.y);
        let r = 1.0 / kappa.abs();
        let h = (r * r - 0.25 * p.len * p.len).max(0.0).sqrt() * kappa.signum();
        let c = Vec2::new(0.5 * p.len, h);
        let angle = |q: Vec2| (-c).perp_dot(q - c).atan2((-c).dot(q - c));
        let end = angle(Vec2::new(p.len, 0.0));
        let u = p.arc + p.len * angle(at) / end;
        let v = (r - (at - c).length()) * kappa.signum();
        [u, v]
    }

    /// (u, v) of the offset `off` (piece `k`'s frame) from the foot at arc length `s` where that
    /// foot is one of γ's ends and the point lies beyond it: u = s + x, v = y, read along γ's
    /// tangent at the end, which is the end piece's arc's (its chord turned by half the piece's
    /// turning; read along the chord, points level with the end would have u off by |v| times
    /// that half-turn). `None` for a point within γ's span.
    fn past_end(&self, k: usize, s: f32, off: Vec2) -> Option<[f32; 2]> {
        let p = &self.pieces[k];
        let half = 0.5 * p.kappa * p.len;
        let (start, end) = (
            k == 0 && s <= 0.0,
            k == self.pieces.len() - 1 && s >= self.length,
        );
        let o = match (start, end) {
            (true, _) => Vec2::from_angle(half).rotate(off),
            (_, true) => Vec2::from_angle(-half).rotate(off),
            _ => return None,
        };
        let beyond = (start && o.x < 0.0) || (end && o.x > 0.0);
        beyond.then_some([s + o.x, o.y])
    }

    /// Foot of `x` on piece `k`: arc length and offset (along T, along B) in its frame.
    fn foot_on(&self, k: usize, x: Vec3) -> (f32, Vec2) {
        let p = &self.pieces[k];
        let along = (x - p.start).dot(p.t).clamp(0.0, p.len);
        let d = x - (p.start + p.t * along);
        (p.arc + along, Vec2::new(d.dot(p.t), d.dot(p.b)))
    }
}

/// The most a point's offset across γ, times the curvature its piece is read with, may be on the
/// inside of a turn ([`reading_curvature`]).
const MAX_BEND: f32 = 0.75;

/// The curvature a point at offset `y` across γ (towards B) reads its piece with: the piece's
/// `kappa`, limited on the inside of the turn (y κ > 0) so that y κ stays within [`MAX_BEND`].
/// A point at the arc's centre (y κ = 1) has every foot on the arc at once and a point beyond it
/// has its radial foot on the arc's far side, its u turned half way around the centre; near a
/// smooth curve the strip stays well clear of its centres of curvature, and where it does not (a
/// corner sharper than the strip is wide, a turn tighter than it) no nearest point of γ says what
/// u is and the harmonic repair takes the part over ([`repair`]).
fn reading_curvature(kappa: f32, y: f32) -> f32 {
    if y * kappa > 0.0 {
        kappa.clamp(-MAX_BEND / y.abs(), MAX_BEND / y.abs())
    } else {
        kappa
    }
}

/// γ's cumulative turning Φ(s) (towards B positive): the turning at each knot spread evenly
/// between the middles of the two pieces that meet there, so that Φ is linear in s along a
/// polyline that samples a circle evenly, and grows by a knot's turning angle across it.
struct Turning {
    /// Arc length at each piece's middle.
    mids: Vec<f32>,
    /// Φ at each piece's middle.
    phi: Vec<f32>,
}

impl Turning {
    fn new(pieces: &[Piece]) -> Self {
        let mids = pieces.iter().map(|p| p.arc + 0.5 * p.len).collect();
        let mut phi = Vec::with_capacity(pieces.len());
        let mut total = 0.0;
        phi.push(total);
        for w in pieces.windows(2) {
            total += w[1].t.dot(w[0].b).atan2(w[1].t.dot(w[0].t));
            phi.push(total);
        }
        Self { mids, phi }
    }

    /// Φ at arc length `s` (constant before the first piece's middle and past the last's).
    fn at(&self, s: f32) -> f32 {
        let i = self.mids.partition_point(|&m| m <= s);
        if i == 0 {
            return self.phi[0];
        }
        if i == self.mids.len() {
            return self.phi[i - 1];
        }
        let (m0, m1) = (self.mids[i - 1], self.mids[i]);
        let f = if m1 > m0 { (s - m0) / (m1 - m0) } else { 1.0 };
        self.phi[i - 1] + f * (self.phi[i] - self.phi[i - 1])
    }

    /// γ's mean curvature over the stretch within `half` of arc length `s` (cut to the span of
    /// the pieces' middles, where Φ is defined): a circle's curvature along any stretch of a
    /// polyline that samples it evenly. The pieces beside a corner (a `"linear"` path's point,
    /// where two joined geodesics meet at an angle) are a quarter of an edge long; divided by their
    /// lengths alone the corner's angle is the curvature of an arc whose centre lies inside the
    /// strip. Over the strip's reach it is the turning the strip beside the corner goes through.
    fn curvature(&self, s: f32, half: f32) -> f32 {
        let (first, last) = (self.mids[0], self.mids[self.mids.len() - 1]);
        let (a, b) = ((s - half).max(first), (s + half).min(last));
        if b - a <= 1e-6 * (last - first) || b <= a {
            return 0.0;
        }
        (self.at(b) - self.at(a)) / (b - a)
    }
}

/// The extended exponential map over the vertices it reached.
#[derive(Debug, Clone)]
pub struct RibbonMap {
    /// Graph distance from γ per welded vertex (`f32::INFINITY` where not reached): the
    /// propagation order.
    pub dist: Vec<f32>,
    /// (u, v) per welded vertex, model units: arc length of the foot plus the tangential offset,
    /// and the signed offset along N × T.
    pub uv: Vec<[f32; 2]>,
    /// Arc length of each vertex's foot on γ.
    pub foot: Vec<f32>,
    /// Upwind neighbour (`u32::MAX` for seed vertices and unreached ones).
    pub parent: Vec<u32>,
    /// γ's length (the polyline's).
    pub length: f32,
}

impl RibbonMap {
    /// Whether vertex `v` was reached.
    pub fn reached(&self, v: usize) -> bool {
        self.dist[v].is_finite()
    }
}

/// Slides the foot at arc length `s` on piece `k`, with offset `off` in piece `k`'s frame, along
/// γ until the offset has no tangential part, or γ ends: each step moves the foot by the
/// tangential part, subtracts the move (the chord between the feet, read in the old frame) and
/// turns the offset by the angle between the two pieces' tangents. Returns the new piece, arc
/// length and offset (in the new piece's frame). At most 8 steps (beside a convex corner of the
/// polyline no foot has a zero tangential part).
fn slide(c: &Framed, mut k: usize, mut s: f32, mut off: Vec2) -> (usize, f32, Vec2) {
    for _ in 0..8 {
        let s2 = (s + off.x).clamp(0.0, c.length);
        if (s2 - s).abs() <= 1e-7 * c.length {
            break;
        }
        let k2 = c.piece_at(s2);
        let (a, b) = (&c.pieces[k], &c.pieces[k2]);
        let chord = c.point_on(k2, s2) - c.point_on(k, s);
        let d = off - Vec2::new(chord.dot(a.t), chord.dot(a.b));
        let phi = b.t.dot(a.b).atan2(b.t.dot(a.t));
        off = Vec2::from_angle(-phi).rotate(d);
        (k, s) = (k2, s2);
    }
    (k, s, off)
}

/// The extended exponential map of `curve` on `topo`, over the vertices within graph distance
/// `reach` of it (and one ring more: the vertices a strip of half-width `reach` needs). A curve
/// with no piece of positive length reaches nothing.
pub fn ribbon_cpu(topo: &Topology, curve: &Curve, reach: f32) -> RibbonMap {
    let n = topo.positions.len();
    let framed = Framed::new(topo, curve, reach);
    let mut map = RibbonMap {
        dist: vec![f32::INFINITY; n],
        uv: vec![[0.0; 2]; n],
        foot: vec![0.0; n],
        parent: vec![u32::MAX; n],
        length: framed.length,
    };
    if framed.pieces.is_empty() {
        return map;
    }
    // Per vertex: the offset from its foot, in the frame of the foot's piece.
    let mut off = vec![Vec2::ZERO; n];
    let mut piece = vec![0u32; n];
    let mut is_seed = vec![false; n];
    for f in seeds(topo, curve, &framed) {
        let v = f.vertex as usize;
        (map.dist[v], map.foot[v], off[v], piece[v]) = (f.dist, f.s, f.off, f.piece);
        is_seed[v] = true;
    }
    let mut done = vec![false; n];
    let mut heap = BinaryHeap::new();
    for v in 0..n {
        if map.dist[v].is_finite() {
            heap.push(Item(map.dist[v], v as u32));
        }
    }
    while let Some(Item(d, q)) = heap.pop() {
        let q = q as usize;
        if done[q] || d > map.dist[q] {
            continue;
        }
        done[q] = true;
        if map.parent[q] != u32::MAX {
            let r = map.parent[q] as usize;
            let k = piece[r] as usize;
            let p = &framed.pieces[k];
            let frame = Seed {
                triangle: 0,
                point: p.start,
                normal: p.n,
                e1: p.t,
                e2: p.b,
            };
            let (pr, pq) = (topo.positions[r], topo.positions[q]);
            let t = Vec2::from(transfer(pr, topo.normals[r], pq, &frame));
            let (kq, s, o) = slide(&framed, k, map.foot[r], off[r] + t);
            (piece[q], map.foot[q], off[q]) = (kq as u32, s, o);
        }
        if map.dist[q] > reach {
            continue;
        }
        let (a, b) = (
            topo.adjacency_offsets[q] as usize,
            topo.adjacency_offsets[q + 1] as usize,
        );
        for &w in &topo.adjacency[a..b] {
            let wi = w as usize;
            let key = map.dist[q] + (topo.positions[wi] - topo.positions[q]).length();
            // Ties go to the lower neighbour id, as in the exponential map's twin.
            let better = key < map.dist[wi] || (key == map.dist[wi] && (q as u32) < map.parent[wi]);
            // Seeds are final (their feet are exact).
            if !done[wi] && !is_seed[wi] && better {
                map.dist[wi] = key;
                map.parent[wi] = q as u32;
                heap.push(Item(key, w));
            }
        }
    }
    for v in 0..n {
        if map.reached(v) {
            map.uv[v] = framed.fermi(piece[v] as usize, map.foot[v], off[v]);
        }
    }
    map
}

/// Step 1: the vertices of γ's triangles, each at its nearest foot among the pieces in its
/// triangles, slid to the nearest point of γ; each vertex once, in vertex order.
pub(crate) fn seeds(topo: &Topology, curve: &Curve, framed: &Framed) -> Vec<SeedFoot> {
    let mut best: std::collections::BTreeMap<u32, SeedFoot> = Default::default();
    // `k` counts framed pieces (zero-length pieces have none).
    let mut k = 0;
    for (i, &tri) in curve.triangles.iter().enumerate() {
        if (curve.points[i + 1] - curve.points[i]).length() <= 0.0 {
            continue;
        }
        for v in topo.triangles[tri as usize] {
            let (s, o) = framed.foot_on(k, topo.positions[v as usize]);
            let (kf, s, off) = slide(framed, k, s, o);
            let f = SeedFoot {
                vertex: v,
                piece: kf as u32,
                s,
                off,
                dist: off.length(),
            };
            if best.get(&v).is_none_or(|b| f.dist < b.dist) {
                best.insert(v, f);
            }
        }
        k += 1;
    }
    best.into_values().collect()
}
