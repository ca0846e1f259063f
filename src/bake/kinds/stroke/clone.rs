// SPDX-License-Identifier: MIT OR Apache-2.0
//! The clone tool's source stamps (Maillot section 10, "aligned" cloning): the source follows the
//! stroke from `source` with the same steps and turns as the stamps take from the path's first
//! point. Step k of the stroke, expressed in stamp k − 1's frame (along and across its image x
//! axis), is taken in source stamp k − 1's frame and projected back onto the surface in sub-steps of
//! half the mean edge length; the source frame turns by the angle the stamps' x axes turn. On a
//! plane this is the stroke translated (and turned) to the source; on a curved surface it is a
//! discrete parallel walk, accurate to the step's curvature. CPU set-up: a few projections a stamp.

use super::stamps::placement_at;
use crate::bake::kinds::Unit;
use crate::bake::LoadedMesh;
use crate::error::{Error, Result};
use crate::maps::Frame;
use crate::place::Placement;
use glam::Vec3;

/// The source unit of each stamp, in order (hidden from drawing, flattened for its stamp).
pub fn sources(
    mesh: &LoadedMesh,
    stamps: &[Unit],
    source: &Placement,
    edge: f32,
    err: &dyn Fn(String) -> Error,
) -> Result<Vec<Unit>> {
    let mut out: Vec<Unit> = Vec::with_capacity(stamps.len());
    let mut at = *source;
    let n0 = Vec3::from(at.normal);
    let first = &stamps[0].frame;
    let mut u = tangent(first.axis_u, n0).ok_or_else(|| {
        err(
            "`source`: the stroke's first stamp cannot be turned into the source's tangent plane"
                .into(),
        )
    })?;
    for (k, stamp) in stamps.iter().enumerate() {
        if k > 0 {
            let (prev, cur) = (&stamps[k - 1].frame, &stamp.frame);
            let d = cur.center - prev.center;
            let (along, across) = (d.dot(prev.axis_u), d.dot(prev.axis_v));
            let n = Vec3::from(at.normal);
            let v = n.cross(u);
            let step = along * u + across * v;
            let parts = (step.length() / (0.5 * edge)).ceil().max(1.0) as usize;
            for _ in 0..parts {
                let q = Vec3::from(at.point) + step / parts as f32;
                at = placement_at(mesh, at.triangle, q);
                if (Vec3::from(at.point) - q).length() > 0.5 * edge + 1e-6 {
                    return Err(err(format!(
                        "`source`: the clone's source runs off the mesh at stamp {k}; move `source` so that the whole stroke fits beside it"
                    )));
                }
            }
            let turn = cur
                .axis_u
                .dot(prev.axis_v)
                .atan2(cur.axis_u.dot(prev.axis_u));
            let n = Vec3::from(at.normal);
            let base = tangent(u, n).unwrap_or(u);
            let w = n.cross(base);
            u = (turn.cos() * base + turn.sin() * w).normalize();
        }
        let n = Vec3::from(at.normal);
        let frame = Frame {
            center: Vec3::from(at.point),
            axis_u: u,
            axis_v: n.cross(u),
            normal: n,
            ..stamp.frame
        };
        out.push(Unit {
            layer: stamp.layer.clone(),
            placement: at,
            frame,
            hidden: false,
            blend: None,
            source: true,
            clone_of: None,
            ribbon: None,
        });
    }
    Ok(out)
}

/// `v` projected into the plane normal to `n`, unit length, if it is not (nearly) along `n`.
fn tangent(v: Vec3, n: Vec3) -> Option<Vec3> {
    let t = v - n * v.dot(n);
    (t.length() > 1e-6).then(|| t.normalize())
}
