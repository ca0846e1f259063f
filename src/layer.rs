// SPDX-License-Identifier: MIT OR Apache-2.0
//! Layers: the decal frame at the placed point, the per-kernel `Params` block, and the CPU twins of
//! the layer kernels (`planar_coords`, `select_triangles`).
//!
//! The interface every placement method implements: for each welded vertex, local coordinates
//! `(x, y)` in model units in the decal's frame plus a validity flag (`vec4(x, y, extra, valid)` in
//! the coords buffer). `select_triangles` then keeps the triangles whose three vertices are valid and
//! whose coordinate box overlaps the decal rectangle. The planar method is the tangent-plane projection
//! of Schmidt, Grimm & Wyvill 2006 (section 3, the projection their exponential map improves upon).

use crate::job::Layer;
use crate::mesh::{Mesh, Topology};
use crate::place::Placement;
use glam::{Vec2, Vec3};

/// Per-dispatch parameters. Keep in sync with `Params` in wgsl/shared/params.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Params {
    /// Decal centre.
    pub center: [f32; 4],
    /// Image +x direction; w = width.
    pub axis_u: [f32; 4],
    /// Image +y direction; w = height.
    pub axis_v: [f32; 4],
    /// Projection normal; w = planar depth limit.
    pub normal: [f32; 4],
    /// Output texture size.
    pub tex_size: [u32; 2],
    /// Raster rectangle origin (texels).
    pub rect_origin: [i32; 2],
    /// Raster rectangle size (texels); the encode kernel reads `rect_size[0]` as its row stride.
    pub rect_size: [u32; 2],
    /// UV tile.
    pub tile: [i32; 2],
    /// Supersampling per axis.
    pub ss: u32,
    /// Blend mode id.
    pub blend: u32,
    /// Slot in the chunk.
    pub slot: u32,
    /// Flags (`FLAG_*`).
    pub flags: u32,
    /// Opacity.
    pub opacity: f32,
    /// Welded vertex count.
    pub vertex_count: u32,
    /// Triangle count.
    pub triangle_count: u32,
    /// Layer kernels: the layer's index in the job (stats row); `edt_rows_fill`: padding radius
    /// (`u32::MAX` = full).
    pub aux: u32,
    /// Words per row of the stats buffer (8 counters + the cell mask).
    pub stats_stride: u32,
    /// Side of a mask cell in texels.
    pub cell: u32,
    /// Cells per row and column.
    pub grid: [u32; 2],
    /// Raster job: origin of its samples in the batch's atlas target.
    pub atlas_origin: [u32; 2],
    /// Unused.
    pub pad: [u32; 2],
}

const _: () = assert!(std::mem::size_of::<Params>() == 160);

/// Require front-facing triangles.
pub const FLAG_FACING: u32 = 1;
/// A mask image is bound.
pub const FLAG_MASK: u32 = 2;
/// Encode at 16 bits.
pub const FLAG_16BIT: u32 = 4;

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
    pub fn seed(&self, placement: &Placement) -> crate::geodesic::Seed {
        crate::geodesic::Seed {
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
    pub fn expmap_options(&self, layer: &crate::job::Layer) -> crate::geodesic::Options {
        crate::geodesic::Options {
            radius: self.expmap_radius(),
            curvature_stop: layer.curvature_stop,
            accuracy: layer.accuracy,
        }
    }

    /// Fills the frame fields of a `Params` block.
    pub fn params(&self) -> Params {
        Params {
            center: self.center.extend(0.0).to_array(),
            axis_u: self.axis_u.extend(self.size[0]).to_array(),
            axis_v: self.axis_v.extend(self.size[1]).to_array(),
            normal: self.normal.extend(self.depth).to_array(),
            ..Default::default()
        }
    }
}

/// CPU twin of `planar_coords.wgsl`: `(x, y, depth, valid)` per welded vertex.
pub fn planar_coords(topo: &Topology, f: &Frame) -> Vec<[f32; 4]> {
    topo.positions
        .iter()
        .map(|p| {
            let d = *p - f.center;
            let z = d.dot(f.normal);
            [
                d.dot(f.axis_u),
                d.dot(f.axis_v),
                z,
                if z.abs() <= f.depth { 1.0 } else { 0.0 },
            ]
        })
        .collect()
}

/// What `select_triangles` produces for one layer.
#[derive(Debug, Clone, PartialEq)]
pub struct Selection {
    /// Covered triangles, ascending (the GPU appends in any order).
    pub triangles: Vec<u32>,
    /// Texel box (min x, min y, max x, max y), before UV wrapping.
    pub texel_box: [i32; 4],
}

/// CPU twin of `select_triangles.wgsl`.
pub fn select_triangles(
    mesh: &Mesh,
    topo: &Topology,
    uvs: &[Vec2],
    coords: &[[f32; 4]],
    f: &Frame,
    facing: bool,
    tex: [u32; 2],
) -> Selection {
    let mut out = Selection {
        triangles: Vec::new(),
        texel_box: [i32::MAX, i32::MAX, i32::MIN, i32::MIN],
    };
    let (hx, hy) = (0.5 * f.size[0], 0.5 * f.size[1]);
    for (t, tri) in topo.triangles.iter().enumerate() {
        if topo.degenerate[t] {
            continue;
        }
        let c = tri.map(|v| coords[v as usize]);
        if c.iter().any(|c| c[3] < 0.5) {
            continue;
        }
        let lo = Vec2::new(
            c[0][0].min(c[1][0]).min(c[2][0]),
            c[0][1].min(c[1][1]).min(c[2][1]),
        );
        let hi = Vec2::new(
            c[0][0].max(c[1][0]).max(c[2][0]),
            c[0][1].max(c[1][1]).max(c[2][1]),
        );
        if hi.x < -hx || lo.x > hx || hi.y < -hy || lo.y > hy {
            continue;
        }
        if facing {
            let [a, b, cc] = tri.map(|v| topo.positions[v as usize]);
            if (b - a).cross(cc - a).dot(f.normal) <= 0.0 {
                continue;
            }
        }
        out.triangles.push(t as u32);
        let size = Vec2::new(tex[0] as f32, tex[1] as f32);
        let u = mesh.triangles[t].map(|s| uvs[s as usize] * size);
        let tlo = u[0].min(u[1]).min(u[2]).floor();
        let thi = u[0].max(u[1]).max(u[2]).ceil();
        out.texel_box[0] = out.texel_box[0].min(tlo.x as i32);
        out.texel_box[1] = out.texel_box[1].min(tlo.y as i32);
        out.texel_box[2] = out.texel_box[2].max(thi.x as i32);
        out.texel_box[3] = out.texel_box[3].max(thi.y as i32);
    }
    out
}

/// Workgroups per layer in `distortion.wgsl`. Keep in sync with the WGSL constant.
pub const DIST_GROUPS: u32 = 16;

/// Distortion of a layer's map over the triangles it covers (whole triangles, area-weighted), from
/// the singular values s1 >= s2 of each triangle's Jacobian into the layer's (u, v).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct Distortion {
    /// Area-weighted mean of s1 s2 (1 = area kept).
    pub area_ratio_mean: f32,
    /// Smallest s1 s2 (negative for flipped triangles).
    pub area_ratio_min: f32,
    /// Largest s1 s2.
    pub area_ratio_max: f32,
    /// Area-weighted mean of s1 / s2 (1 = angles kept).
    pub angle_distortion_mean: f32,
    /// Largest s1 / s2.
    pub angle_distortion_max: f32,
    /// Triangles whose image is flipped.
    pub flipped: u32,
}

impl Distortion {
    /// Adds up the GPU partials of one layer (`2 × DIST_GROUPS` vec4s).
    pub fn from_partials(p: &[[f32; 4]]) -> Self {
        let (mut a, mut ratio_max, mut ratio_min, mut angle_max) =
            ([0.0f64; 4], f32::MIN, f32::MAX, 0.0f32);
        for pair in p.chunks_exact(2) {
            for k in 0..4 {
                a[k] += pair[0][k] as f64;
            }
            angle_max = angle_max.max(pair[1][0]);
            ratio_max = ratio_max.max(pair[1][1]);
            ratio_min = ratio_min.min(pair[1][2]);
        }
        let w = a[0].max(f64::MIN_POSITIVE);
        Self {
            area_ratio_mean: (a[1] / w) as f32,
            area_ratio_min: ratio_min,
            area_ratio_max: ratio_max,
            angle_distortion_mean: (a[2] / w) as f32,
            angle_distortion_max: angle_max,
            flipped: a[3].round() as u32,
        }
    }
}

/// CPU twin of `distortion.wgsl` for one layer.
pub fn distortion(topo: &Topology, coords: &[[f32; 4]], triangles: &[u32]) -> Distortion {
    let mut partial = [[0.0f32; 4], [0.0, f32::MIN, f32::MAX, 0.0]];
    partial[1][0] = 0.0;
    for &t in triangles {
        let tri = topo.triangles[t as usize];
        let p0 = topo.positions[tri[0] as usize];
        let e1 = topo.positions[tri[1] as usize] - p0;
        let e2 = topo.positions[tri[2] as usize] - p0;
        let n = e1.cross(e2);
        let area = 0.5 * n.length();
        let l1 = e1.length();
        if area <= 0.0 || l1 <= 0.0 {
            continue;
        }
        let x = e1 / l1;
        let y = n.cross(x).normalize();
        let q2 = Vec2::new(e2.dot(x), e2.dot(y));
        let c = |v: u32| Vec2::new(coords[v as usize][0], coords[v as usize][1]);
        let (d1, d2) = (c(tri[1]) - c(tri[0]), c(tri[2]) - c(tri[0]));
        let inv_det = 1.0 / (l1 * q2.y);
        let m00 = (d1.x * q2.y) * inv_det;
        let m10 = (d1.y * q2.y) * inv_det;
        let m01 = (d2.x * l1 - d1.x * q2.x) * inv_det;
        let m11 = (d2.y * l1 - d1.y * q2.x) * inv_det;
        let det = m00 * m11 - m01 * m10;
        // Singular values of a 2x2 matrix without cancellation: (sqrt(p) +- sqrt(q)) / 2.
        let p = ((m00 + m11) * (m00 + m11) + (m10 - m01) * (m10 - m01)).sqrt();
        let q = ((m00 - m11) * (m00 - m11) + (m10 + m01) * (m10 + m01)).sqrt();
        let s1 = 0.5 * (p + q);
        let s2 = 0.5 * (p - q).abs();
        let angle = if s2 > 0.0 { s1 / s2 } else { 3.0e38 };
        partial[0][0] += area;
        partial[0][1] += area * det;
        partial[0][2] += area * angle.min(1.0e6);
        partial[0][3] += if det < 0.0 { 1.0 } else { 0.0 };
        partial[1][0] = partial[1][0].max(angle);
        partial[1][1] = partial[1][1].max(det);
        partial[1][2] = partial[1][2].min(det);
    }
    Distortion::from_partials(&partial)
}
