// SPDX-License-Identifier: MIT OR Apache-2.0
//! A stroke's path on the surface: consecutive placed points joined by the straight segment in the
//! first point's exponential map, mapped back to the surface (the straightest path, never
//! the 3D chord). Radial lines of an exponential map are geodesics (Schmidt et al. 2006, section 3:
//! the map is normal coordinates), so the segment from the origin to the next point's coordinates
//! is the geodesic between the two points as far as the discrete map resolves it.
//!
//! The maps are computed on the GPU, one per segment, all in one batch
//! ([`crate::maps::expmap::gpu::expmaps_gpu`]); the walk back to the surface is CPU set-up: the
//! segment is sampled every quarter of the mean edge length and each sample located in the chart
//! ([`walk`]) and mapped back through its triangle (the chart is linear on each triangle).

use crate::error::{Error, Result};
use crate::maps::expmap::cpu::{Options, Seed};
use crate::maps::expmap::Accuracy;
use crate::mesh::{Topology, NO_NEIGHBOR};
use crate::place::Placement;
use glam::{Vec2, Vec3};

/// A path on the surface: a polyline whose pieces each lie in one triangle.
#[derive(Debug, Clone, Default)]
pub struct SurfacePath {
    /// Polyline points (model units): the path points and samples every quarter of the mean edge
    /// length between them.
    pub points: Vec<Vec3>,
    /// Per piece (`points[k]` to `points[k + 1]`): the welded triangle it crosses.
    pub triangles: Vec<u32>,
    /// Arc length at each point.
    pub arc: Vec<f32>,
    /// Arc length at each of the stroke's path points (for pressure).
    pub knots: Vec<f32>,
}

impl SurfacePath {
    /// Total length.
    pub fn length(&self) -> f32 {
        self.arc.last().copied().unwrap_or(0.0)
    }

    /// The piece containing arc length `s` and the point there.
    pub fn at(&self, s: f32) -> (usize, Vec3) {
        if self.triangles.is_empty() {
            return (usize::MAX, self.points[0]);
        }
        let k = self
            .arc
            .partition_point(|&a| a <= s)
            .clamp(1, self.arc.len() - 1)
            - 1;
        let len = self.arc[k + 1] - self.arc[k];
        let t = if len > 0.0 {
            ((s - self.arc[k]) / len).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (k, self.points[k].lerp(self.points[k + 1], t))
    }
}

/// How far apart consecutive path points may be, as a fraction of the model's bounding-box
/// diagonal: one exponential map joins them, and a map that spans much of a curved model stops being
/// one-to-one (its far side folds over itself), so the straight segment would no longer be a
/// geodesic.
pub const MAX_SEGMENT_FRACTION: f32 = 0.5;

/// The exponential map that joins path point `a` to the next point `b`: seeded at `a`, reaching a
/// little beyond `b` (graph distances overestimate geodesics; the path may bend over a bump).
pub fn segment_map(topo: &Topology, a: &Placement, b: &Placement, edge: f32) -> (Seed, Options) {
    let n = Vec3::from(a.normal).normalize();
    let helper = if n.x.abs() < 0.9 { Vec3::X } else { Vec3::Y };
    let e1 = (helper - n * helper.dot(n)).normalize();
    let chord = (Vec3::from(b.point) - Vec3::from(a.point)).length();
    let _ = topo;
    (
        Seed {
            triangle: a.triangle,
            point: Vec3::from(a.point),
            normal: n,
            e1,
            e2: n.cross(e1),
        },
        Options {
            radius: 2.0 * chord + 4.0 * edge,
            curvature_stop: f32::INFINITY,
            accuracy: Accuracy::Smooth,
        },
    )
}

/// Follows the straight chart segment from `a` to `b` over the triangles of `topo`, given the
/// chart `coords` (per welded vertex: x, y, distance, state; state 0 = not reached), sampling it
/// every `step` (chart units = model units) and locating each sample by a visibility walk from the
/// previous one (Devillers et al.: step into the neighbour across the edge whose barycentric
/// coordinate is most negative), which is indifferent to samples on edges and vertices. Appends the
/// samples, mapped back to the surface, to `path` (whose last point is `a`). `Err` says why the
/// chart could not be followed.
pub fn walk(
    topo: &Topology,
    coords: &[[f32; 4]],
    (a, b): (&Placement, &Placement),
    step: f32,
    path: &mut SurfacePath,
) -> std::result::Result<(), String> {
    let chart = |t: u32| -> Option<[Vec2; 3]> {
        let tri = topo.triangles[t as usize];
        let c = tri.map(|v| coords[v as usize]);
        c.iter()
            .all(|c| c[3] > 0.5)
            .then(|| c.map(|c| Vec2::new(c[0], c[1])))
    };
    let at = |p: &Placement| -> Option<Vec2> {
        let c = chart(p.triangle)?;
        Some(c[0] * p.bary[0] + c[1] * p.bary[1] + c[2] * p.bary[2])
    };
    let start = at(a).ok_or("the chart does not cover the first point")?;
    let end = at(b).ok_or("the next point lies beyond the chart's reach")?;
    let n = ((end - start).length() / step).ceil().max(1.0) as usize;
    let mut t = a.triangle;
    for j in 1..n {
        let p = start.lerp(end, j as f32 / n as f32);
        let (found, l) = locate(topo, &chart, t, p)?;
        t = found;
        let tri = topo.triangles[t as usize];
        let q: Vec3 = (0..3).map(|k| topo.positions[tri[k] as usize] * l[k]).sum();
        push(path, q, t);
    }
    push(path, Vec3::from(b.point), b.triangle);
    Ok(())
}

/// The triangle of the chart containing `p`, found by walking from `t`, and `p`'s barycentric
/// coordinates there (clamped to the triangle).
fn locate(
    topo: &Topology,
    chart: &dyn Fn(u32) -> Option<[Vec2; 3]>,
    mut t: u32,
    p: Vec2,
) -> std::result::Result<(u32, [f32; 3]), String> {
    for _ in 0..4096 {
        let c = chart(t).ok_or("the path leaves the chart's reach")?;
        let l = barycentric(p, c);
        let (k, worst) =
            (0..3)
                .map(|k| (k, l[k]))
                .fold((0, f32::MAX), |m, x| if x.1 < m.1 { x } else { m });
        if worst >= -1e-5 {
            let l = l.map(|x| x.max(0.0));
            let sum = l[0] + l[1] + l[2];
            return Ok((t, l.map(|x| x / sum)));
        }
        // The edge opposite corner k is edge (k + 1, k + 2), index (k + 1) % 3.
        let next = topo.triangle_neighbors[t as usize][(k + 1) % 3];
        if next == NO_NEIGHBOR {
            return Err("the path runs off the mesh's boundary".into());
        }
        t = next;
    }
    Err("the chart folds over itself between the points".into())
}

/// Barycentric coordinates of `p` in the 2D triangle `c` (not clamped).
fn barycentric(p: Vec2, c: [Vec2; 3]) -> [f32; 3] {
    let area = (c[1] - c[0]).perp_dot(c[2] - c[0]);
    if area.abs() < 1e-30 {
        // A collapsed triangle of the chart contains nothing: step on across its first edge.
        return [-1.0, 1.0, 1.0];
    }
    let l0 = (c[1] - p).perp_dot(c[2] - p) / area;
    let l1 = (c[2] - p).perp_dot(c[0] - p) / area;
    [l0, l1, 1.0 - l0 - l1]
}

/// Appends a point reached through triangle `t`.
fn push(path: &mut SurfacePath, p: Vec3, t: u32) {
    let last = *path
        .points
        .last()
        .expect("a path starts with its first point");
    let d = (p - last).length();
    if d <= 0.0 {
        return;
    }
    let s = path.arc.last().copied().unwrap_or(0.0) + d;
    path.points.push(p);
    path.triangles.push(t);
    path.arc.push(s);
}

impl SurfacePath {
    /// A path at its first point.
    pub fn start(first: &Placement) -> Self {
        Self {
            points: vec![Vec3::from(first.point)],
            triangles: Vec::new(),
            arc: vec![0.0],
            knots: vec![0.0],
        }
    }
}

/// Extends `path` (which ends at path point k, `a`) to path point k + 1 (`b`) through the chart of
/// segment k (`None` for a segment of zero length), sampling every `step`. `err` makes an error
/// naming the layer.
pub fn extend(
    topo: &Topology,
    (k, a, b): (usize, &Placement, &Placement),
    chart: Option<Vec<[f32; 4]>>,
    step: f32,
    path: &mut SurfacePath,
    err: &dyn Fn(String) -> Error,
) -> Result<()> {
    if let Some(coords) = chart {
        walk(topo, &coords, (a, b), step, path).map_err(|why| {
            err(format!(
                "path[{k}] to path[{}]: {why}; add points in between so that each step stays within one chart",
                k + 1
            ))
        })?;
    }
    path.knots.push(path.length());
    Ok(())
}

/// Mean edge length of the mesh (the map reach's margin).
pub fn mean_edge(topo: &Topology) -> f32 {
    let mut sum = 0.0f64;
    for tri in &topo.triangles {
        for k in 0..3 {
            let (a, b) = (tri[k] as usize, tri[(k + 1) % 3] as usize);
            sum += (topo.positions[a] - topo.positions[b]).length() as f64;
        }
    }
    (sum / (3 * topo.triangles.len().max(1)) as f64) as f32
}
