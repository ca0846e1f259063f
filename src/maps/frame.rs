// SPDX-License-Identifier: MIT OR Apache-2.0
//! The decal frame at the placed point: image centre, axes and normal on the surface, from the
//! layer's `up` and `angle`. Every map method expresses its local coordinates in this frame.

use crate::io::job::Layer;
use crate::place::Placement;
use glam::Vec3;

/// The decal's frame on the surface.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct Frame {
    /// Image centre on the surface.
    pub center: Vec3,
    /// Surface direction of the image's +x.
    pub axis_u: Vec3,
    /// Surface direction of the image's +y (up).
    pub axis_v: Vec3,
    /// Out of the surface.
    pub normal: Vec3,
    /// Width, height.
    pub size: [f32; 2],
    /// Planar depth limit.
    pub depth: f32,
    /// True when `up` was (nearly) parallel to the normal and a fallback direction was used.
    pub up_fallback: bool,
}

impl Frame {
    /// The frame at a placement: `up` projected into the tangent plane, then turned by `angle`
    /// degrees counter-clockwise seen from outside.
    pub fn new(p: &Placement, layer: &Layer) -> Self {
        let n = Vec3::from(p.normal).normalize();
        let up = Vec3::from(layer.up).normalize();
        let mut t_up = up - up.dot(n) * n;
        let mut up_fallback = false;
        if t_up.length() < 1e-3 {
            up_fallback = true;
            // The world axis least aligned with the normal.
            let a = n.abs();
            let axis = if a.x <= a.y && a.x <= a.z {
                Vec3::X
            } else if a.y <= a.z {
                Vec3::Y
            } else {
                Vec3::Z
            };
            t_up = axis - axis.dot(n) * n;
        }
        let up0 = t_up.normalize();
        let right0 = up0.cross(n).normalize();
        let (s, c) = layer.angle.to_radians().sin_cos();
        Self {
            center: Vec3::from(p.point),
            axis_u: c * right0 + s * up0,
            axis_v: -s * right0 + c * up0,
            normal: n,
            size: layer.size,
            depth: layer.depth,
            up_fallback,
        }
    }

    /// The exponential-map seed of this frame at `placement` (image axes as the tangent frame).
    pub fn seed(&self, placement: &Placement) -> crate::maps::expmap::cpu::Seed {
        crate::maps::expmap::cpu::Seed {
            triangle: placement.triangle,
            point: self.center,
            normal: self.normal,
            e1: self.axis_u,
            e2: self.axis_v,
        }
    }

    /// The geodesic radius an exponential-map decal needs: its rectangle's half-diagonal, with 20 %
    /// added because the propagation limit is a graph distance, which overestimates geodesics.
    pub fn expmap_radius(&self) -> f32 {
        1.2 * 0.5 * (self.size[0] * self.size[0] + self.size[1] * self.size[1]).sqrt()
    }

    /// The options of this layer's exponential map (expmap, and the start of lscm / hybrid).
    pub fn expmap_options(
        &self,
        layer: &crate::io::job::Layer,
    ) -> crate::maps::expmap::cpu::Options {
        crate::maps::expmap::cpu::Options {
            radius: self.expmap_radius(),
            curvature_stop: layer.curvature_stop,
            accuracy: layer.accuracy,
        }
    }
}
