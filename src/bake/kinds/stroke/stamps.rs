// SPDX-License-Identifier: MIT OR Apache-2.0
//! A stroke's stamps: placed every `spacing` × stamp width of arc length along its surface path
//! (the way Blender and Photoshop express spacing), pressure interpolated by arc length scaling the
//! size by `1 - pressure_size (1 - p)` and the flow by `1 - pressure_flow (1 - p)`, each stamp's
//! frame turned along the path (Maillot section 7) or fixed like a decal.

use super::path::SurfacePath;
use crate::bake::kinds::Unit;
use crate::bake::LoadedMesh;
use crate::error::{Error, Result};
use crate::io::job::{AtSpec, BlendMode, Layer, LayerKind, Orient, Stroke};
use crate::io::stroke::MAX_STAMPS;
use crate::maps::Frame;
use crate::mesh::Topology;
use crate::place::Placement;
use glam::Vec3;

/// A stamp's size factor never drops the step below this fraction of the full-size step, so a
/// stroke at zero pressure still advances.
pub const MIN_STEP_FACTOR: f32 = 0.05;

/// Stamps smaller than this fraction of the full size are not drawn (their step still counts).
pub const MIN_SIZE_FACTOR: f32 = 1e-3;

/// Pressure at arc length `s`: piecewise linear between the path points' arc lengths.
pub fn pressure_at(knots: &[f32], pressure: &[f32], s: f32) -> f32 {
    let k = knots.partition_point(|&a| a <= s);
    if k == 0 {
        return pressure[0];
    }
    if k >= knots.len() {
        return *pressure.last().expect("a path has points");
    }
    let (a, b) = (knots[k - 1], knots[k]);
    let t = if b > a { (s - a) / (b - a) } else { 1.0 };
    pressure[k - 1] + (pressure[k] - pressure[k - 1]) * t
}

/// The stamps of `layer` (a stroke) along `path`, as units; `err` makes an error naming the layer.
pub fn stamps(
    mesh: &LoadedMesh,
    layer: &Layer,
    stroke: &Stroke,
    path: &SurfacePath,
    first: &Placement,
    err: &dyn Fn(String) -> Error,
) -> Result<Vec<Unit>> {
    let width = layer.size[0];
    let size_factor = |p: f32| 1.0 - stroke.pressure_size * (1.0 - p);
    let flow_factor = |p: f32| 1.0 - stroke.pressure_flow * (1.0 - p);
    let min_factor = stroke
        .pressure
        .iter()
        .map(|&p| size_factor(p))
        .fold(1.0f32, f32::min)
        .max(MIN_STEP_FACTOR);
    let estimate = path.length() / (stroke.spacing * width * min_factor) + 1.0;
    if estimate > MAX_STAMPS as f32 {
        return Err(err(format!(
            "`spacing`: the stroke would need about {estimate:.0} stamps ({:.4} long, stamps {width:.4} wide every {} widths), more than the limit of {MAX_STAMPS}; raise `spacing`, enlarge `size` or split the stroke",
            path.length(),
            stroke.spacing
        )));
    }
    let mut units = Vec::new();
    let mut s = 0.0f32;
    let end = path.length();
    loop {
        let p = pressure_at(&path.knots, &stroke.pressure, s);
        let f = size_factor(p);
        if f >= MIN_SIZE_FACTOR {
            units.push(stamp(
                mesh,
                (layer, stroke),
                path,
                first,
                s,
                [f, flow_factor(p)],
            ));
        }
        s += stroke.spacing * width * f.max(MIN_STEP_FACTOR);
        if s > end + 1e-6 * end.max(1e-30) || path.triangles.is_empty() {
            break;
        }
    }
    if units.is_empty() {
        return Err(err(
            "`pressure`: every stamp has size 0 (pressure 0 with `pressure_size` 1); raise the pressure or lower `pressure_size`".into(),
        ));
    }
    Ok(units)
}

/// One stamp at arc length `s` with size and flow factors `[f, g]` (`first`: the placement of a
/// one-point path).
fn stamp(
    mesh: &LoadedMesh,
    (layer, stroke): (&Layer, &Stroke),
    path: &SurfacePath,
    first: &Placement,
    s: f32,
    [f, g]: [f32; 2],
) -> Unit {
    let (k, on_path) = path.at(s);
    let (placement, tangent) = if k == usize::MAX {
        let p = Placement {
            distance: 0.0,
            ..*first
        };
        (p, None)
    } else {
        let d = path.points[k + 1] - path.points[k];
        let p = placement_at(mesh, path.triangles[k], on_path);
        (p, Some(d.normalize_or_zero()))
    };
    let point = Vec3::from(placement.point);
    let unit_layer = Layer {
        kind: LayerKind::Decal,
        at: AtSpec::Point(point.to_array()),
        size: [layer.size[0] * f, layer.size[1] * f],
        depth: layer.depth * f,
        opacity: stroke.flow * g,
        blend: BlendMode::Normal,
        stroke: None,
        ..layer.clone()
    };
    let n = Vec3::from(placement.normal);
    let along = tangent
        .map(|t| t - n * t.dot(n))
        .filter(|t| t.length() > 1e-6 && stroke.orient == Orient::Path);
    let frame = match along {
        Some(t) => {
            let u0 = t.normalize();
            let v0 = n.cross(u0);
            let (sn, cs) = layer.angle.to_radians().sin_cos();
            Frame {
                center: point,
                axis_u: cs * u0 + sn * v0,
                axis_v: -sn * u0 + cs * v0,
                normal: n,
                size: unit_layer.size,
                depth: unit_layer.depth,
                up_fallback: false,
            }
        }
        None => Frame::new(&placement, &unit_layer),
    };
    Unit::drawn(unit_layer, placement, frame)
}

/// The placement of a point of the path near triangle `t` (the path's piece there; a point between
/// two samples can lie just across an edge, so the triangle containing it is found by a short walk
/// over neighbours): the point projected into that triangle, its barycentric coordinates there and
/// the model's shading normal there ([`crate::place::with_shading_normal`], as every placement of
/// a bake). The point returned is the one the barycentric coordinates give, so the stamp's point
/// and its triangle agree exactly.
pub fn placement_at(mesh: &LoadedMesh, mut t: u32, p: Vec3) -> Placement {
    let topo = &mesh.topo;
    let mut bary = barycentric(topo, t, p);
    for _ in 0..8 {
        let (k, worst) =
            (0..3)
                .map(|k| (k, bary[k]))
                .fold((0, f32::MAX), |m, x| if x.1 < m.1 { x } else { m });
        if worst >= -1e-5 {
            break;
        }
        let next = topo.triangle_neighbors[t as usize][(k + 1) % 3];
        if next == crate::mesh::NO_NEIGHBOR {
            break;
        }
        let b = barycentric(topo, next, p);
        if b.iter().fold(f32::MAX, |m, x| m.min(*x)) <= worst {
            break;
        }
        (t, bary) = (next, b);
    }
    let l = bary.map(|x| x.max(0.0));
    let sum = l[0] + l[1] + l[2];
    let bary = l.map(|x| x / sum);
    let tri = topo.triangles[t as usize];
    let q: Vec3 = (0..3)
        .map(|k| topo.positions[tri[k] as usize] * bary[k])
        .sum();
    let n: Vec3 = (0..3)
        .map(|k| topo.normals[tri[k] as usize] * bary[k])
        .sum();
    let [a, b, c] = tri.map(|v| topo.positions[v as usize]);
    let n = if n.length() > 1e-12 {
        n.normalize()
    } else {
        (b - a).cross(c - a).normalize_or_zero()
    };
    let placed = Placement {
        point: q.to_array(),
        triangle: t,
        bary,
        distance: 0.0,
        normal: n.to_array(),
        found: 1,
    };
    crate::place::with_shading_normal(&mesh.mesh, placed)
}

/// Barycentric coordinates of `p` projected into triangle `t`'s plane (not clamped).
fn barycentric(topo: &Topology, t: u32, p: Vec3) -> [f32; 3] {
    let [a, b, c] = topo.triangles[t as usize].map(|v| topo.positions[v as usize]);
    let (e0, e1, ep) = (b - a, c - a, p - a);
    let (d00, d01, d11) = (e0.dot(e0), e0.dot(e1), e1.dot(e1));
    let (d20, d21) = (ep.dot(e0), ep.dot(e1));
    let den = (d00 * d11 - d01 * d01).max(1e-30);
    let l1 = (d11 * d20 - d01 * d21) / den;
    let l2 = (d00 * d21 - d01 * d20) / den;
    [1.0 - l1 - l2, l1, l2]
}
