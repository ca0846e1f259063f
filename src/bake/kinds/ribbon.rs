// SPDX-License-Identifier: MIT OR Apache-2.0
//! `"kind": "ribbon"`: an image laid along a surface curve (Sun et al. 2013, "Texture Brush",
//! section 3). The path's points are joined along the surface as a stroke's are
//! (`super::stroke::join_path`: by default the smooth curve through them), and the strip around the curve is mapped by the curve's
//! extended exponential map ([`crate::maps::ribbon`], computed in the map stage's ribbon pass,
//! `bake/maps.rs`): u along the curve, v across it. The layer is one unit whose image rectangle is
//! the curve's length × `width`; `"repeat": "tile"` repeats the image along the curve at its own
//! aspect (the raster wraps the image coordinate, `FLAG_REPEAT` in `wgsl/bake/layer_raster.wgsl`).

use super::{placement_problem, query_of, Expansion, Kind, Unit};
use crate::bake::stage::Cx;
use crate::error::{Error, Result};
use crate::io::job::Layer;
use crate::io::ribbon::{Align, Repeat};
use crate::maps::ribbon::Curve;
use crate::maps::Frame;
use crate::place::{Placement, Query};
use glam::Vec3;

/// `"kind": "ribbon"`.
pub struct RibbonKind;

/// What the map stage needs of a ribbon unit.
#[derive(Debug, Clone)]
pub struct RibbonUnit {
    /// The curve on the surface.
    pub curve: Curve,
    /// Graph distance the map spreads to from the curve: the strip's far edge, with a margin.
    pub reach: f32,
    /// The unit's coordinates from the map's (u, v): x = a u + b, y = c v + d, as (a, b, c, d).
    pub xform: [f32; 4],
    /// Copies of the image along the curve (`"repeat": "tile"`); 0 for one stretched copy.
    pub repeats: f32,
    /// How far the strip spreads on the curve's left and right (model units).
    pub sides: [f32; 2],
    /// λ of the curved parts' harmonic repair ([`crate::maps::ribbon::repair`]).
    pub lambda: f32,
}

impl Kind for RibbonKind {
    fn queries(&self, layer: &Layer) -> Vec<Query> {
        let r = layer
            .ribbon
            .as_ref()
            .expect("a ribbon layer has its ribbon");
        r.path.iter().map(query_of).collect()
    }

    fn expand(
        &self,
        cx: Cx<'_>,
        index: usize,
        placements: &[Placement],
        _warnings: &mut Vec<String>,
    ) -> Result<Expansion> {
        let Cx { mesh, job, .. } = cx;
        let layer = &job.layers[index];
        let r = layer
            .ribbon
            .as_ref()
            .expect("a ribbon layer has its ribbon");
        let err = |detail: String| Error::Placement {
            path: job.source.clone(),
            layer: index,
            detail,
        };
        let diag = (Vec3::from(mesh.stats.bbox_max) - Vec3::from(mesh.stats.bbox_min)).length();
        let near = r.width.unwrap_or(0.05 * diag);
        for (k, (at, p)) in r.path.iter().zip(placements).enumerate() {
            if let Some(why) = placement_problem(at, p, (near, "the ribbon's width")) {
                return Err(err(format!("path[{k}]: {why}")));
            }
        }
        let limit = super::stroke::path::MAX_SEGMENT_FRACTION * diag;
        for (k, w) in placements.windows(2).enumerate() {
            let chord = (Vec3::from(w[1].point) - Vec3::from(w[0].point)).length();
            if chord > limit {
                return Err(err(format!(
                    "path[{k}] and path[{}] are {chord:.4} apart, more than one chart can join ({limit:.4}, half the model's size); add points in between",
                    k + 1
                )));
            }
        }
        let edge = super::stroke::path::mean_edge(&mesh.topo);
        let path = super::stroke::join_path(cx, (placements, r.interpolate), edge, &err)?;
        if let Some(why) = crossing(&path, edge) {
            return Err(err(why));
        }
        if path.length() <= 0.0 {
            return Err(err(
                "the path's points are all at one place; a ribbon needs a curve".into(),
            ));
        }
        let curve = match &r.animate {
            None => Curve {
                points: path.points,
                triangles: path.triangles,
            },
            Some(a) => frame_piece(&path, a).map_err(|e| {
                Error::job(&job.source, format!("layers[{index}].animate.length"), e)
            })?,
        };
        let length = curve_length(&curve);
        let (iw, ih) = layer.image_dimensions(&job.source, index)?;
        let aspect = ih as f32 / iw.max(1) as f32;
        let width = r.width.unwrap_or(aspect * length);
        let ribbon = mapping(r, length, width, aspect, edge, curve);
        let mut unit_layer = layer.clone();
        unit_layer.size = [length, width];
        let frame = Frame::new(&placements[0], &unit_layer);
        Ok(Expansion {
            units: vec![Unit {
                ribbon: Some(ribbon),
                ..Unit::drawn(unit_layer, placements[0], frame)
            }],
            stroke: None,
            blocks: Vec::new(),
        })
    }
}

/// The curve's length.
fn curve_length(c: &Curve) -> f32 {
    c.points.windows(2).map(|w| (w[1] - w[0]).length()).sum()
}

/// The piece of the route an animated ribbon shows at its frame ([`Animate::start`]): `length`
/// along the route from the frame's start, wrapping past the route's start when it is closed
/// (the joined route then ends at its first point). An error says why the piece does not fit.
fn frame_piece(
    route: &super::stroke::path::SurfacePath,
    a: &crate::io::ribbon::Animate,
) -> std::result::Result<Curve, String> {
    let total = route.length();
    if a.length > total || (a.closed && a.length >= total) {
        return Err(format!(
            "{} does not fit the route, which is {total:.4} long{}",
            a.length,
            if a.closed { " around" } else { "" }
        ));
    }
    let s0 = a.start(total);
    let s1 = s0 + a.length;
    let mut curve = Curve {
        points: Vec::new(),
        triangles: Vec::new(),
    };
    let mut walk = |from: f32, to: f32| {
        let (k0, p0) = route.at(from);
        let (k1, p1) = route.at(to);
        let mut push = |p: Vec3, t: Option<u32>| match curve.points.last() {
            Some(&q) if (p - q).length() <= 1e-7 * total.max(1.0) => {}
            Some(_) => {
                curve.points.push(p);
                curve.triangles.push(t.unwrap_or(route.triangles[k0]));
            }
            None => curve.points.push(p),
        };
        push(p0, None);
        for k in k0..k1 {
            push(route.points[k + 1], Some(route.triangles[k]));
        }
        push(p1, Some(route.triangles[k1]));
    };
    // An open route's last piece can end an ulp past the route in f32: clamp, never wrap.
    if !a.closed || s1 <= total {
        walk(s0, s1.min(total));
    } else {
        walk(s0, total);
        walk(0.0, s1 - total);
    }
    Ok(curve)
}

/// How the map's (u, v) become the unit's coordinates, whose image rectangle is `length` ×
/// `width` centred at the origin: x = u − length / 2; y = ±(v − the strip's middle), the sign
/// negative when `flip`; the strip's middle is on the curve (`center`), `width` / 2 to its left
/// (`left`, along N × T) or right. `aspect`: the image's height / width (a tiled copy is `width` /
/// `aspect` long). The map reaches the strip's far edge plus two mean edges (its graph distances
/// run a little long, and the selection needs whole triangles).
fn mapping(
    r: &crate::io::ribbon::Ribbon,
    length: f32,
    width: f32,
    aspect: f32,
    edge: f32,
    curve: Curve,
) -> RibbonUnit {
    let middle = match r.align {
        Align::Center => 0.0,
        Align::Left => 0.5 * width,
        Align::Right => -0.5 * width,
    };
    let sign = if r.flip { -1.0 } else { 1.0 };
    let far = middle.abs() + 0.5 * width;
    RibbonUnit {
        curve,
        reach: 1.2 * far + 2.0 * edge,
        sides: [
            (middle + 0.5 * width).max(0.0),
            (0.5 * width - middle).max(0.0),
        ],
        xform: [1.0, -0.5 * length, sign, -sign * middle],
        lambda: r.curved_threshold,
        repeats: match r.repeat {
            Repeat::Stretch => 0.0,
            Repeat::Tile => length * aspect / width,
        },
    }
}

/// Why the curve is not simple, if it crosses or touches itself: the extended exponential map
/// needs a simple curve (Sun et al. 2013, section 7). Two pieces of the joined path that come
/// within a hundredth of a mean edge of each other in space, while more than twice that apart
/// along the curve (cyclically, for a closed curve), are a crossing; the pieces are bucketed in a
/// grid so the test costs what the path does. Robust where the crossing falls on a mesh vertex or
/// edge (the pieces there lie in different triangles).
fn crossing(path: &super::stroke::path::SurfacePath, edge: f32) -> Option<String> {
    let n = path.triangles.len();
    let delta = 0.01 * edge;
    let seg = |k: usize| (path.points[k], path.points[k + 1]);
    let longest = (0..n)
        .map(|k| (seg(k).1 - seg(k).0).length())
        .fold(delta, f32::max);
    let cell = |p: Vec3| (p / longest).floor().as_ivec3();
    let mut grid: std::collections::HashMap<glam::IVec3, Vec<usize>> = Default::default();
    for k in 0..n {
        let (a, b) = seg(k);
        let (lo, hi) = (cell(a.min(b) - delta), cell(a.max(b) + delta));
        for x in lo.x..=hi.x {
            for y in lo.y..=hi.y {
                for z in lo.z..=hi.z {
                    grid.entry(glam::IVec3::new(x, y, z)).or_default().push(k);
                }
            }
        }
    }
    let length = path.length();
    let closed = n > 2 && (path.points[n] - path.points[0]).length() <= delta;
    let apart = |i: usize, j: usize| {
        let d = path.arc[j] - path.arc[i + 1];
        let d = if closed {
            d.min(length - (path.arc[j + 1] - path.arc[i]))
        } else {
            d
        };
        d > 2.0 * delta
    };
    for pieces in grid.values() {
        for (x, &i) in pieces.iter().enumerate() {
            for &j in &pieces[x + 1..] {
                let (i, j) = (i.min(j), i.max(j));
                if j <= i + 1 || !apart(i, j) {
                    continue;
                }
                let (p, q) = closest(seg(i), seg(j));
                if (p - q).length() < delta {
                    let knot =
                        |k: usize| path.knots.partition_point(|&s| s <= path.arc[k]).max(1) - 1;
                    return Some(format!(
                        "the curve crosses or touches itself near ({:.4}, {:.4}, {:.4}), between path[{}]-path[{}] and path[{}]-path[{}]; a ribbon needs a simple curve: split it into two ribbons",
                        p.x, p.y, p.z, knot(i), knot(i) + 1, knot(j), knot(j) + 1
                    ));
                }
            }
        }
    }
    None
}

/// The closest points of segments `(p0, p1)` and `(q0, q1)` (the usual clamped solve).
fn closest((p0, p1): (Vec3, Vec3), (q0, q1): (Vec3, Vec3)) -> (Vec3, Vec3) {
    let (d1, d2, r) = (p1 - p0, q1 - q0, p0 - q0);
    let (a, e, f) = (d1.dot(d1), d2.dot(d2), d2.dot(r));
    let (c, b) = (d1.dot(r), d1.dot(d2));
    let den = a * e - b * b;
    let mut s = if den > 1e-20 * a * e && a > 0.0 {
        ((b * f - c * e) / den).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let mut t = if e > 0.0 { (b * s + f) / e } else { 0.0 };
    if !(0.0..=1.0).contains(&t) {
        t = t.clamp(0.0, 1.0);
        s = if a > 0.0 {
            ((b * t - c) / a).clamp(0.0, 1.0)
        } else {
            0.0
        };
    }
    (p0 + d1 * s, q0 + d2 * t)
}
