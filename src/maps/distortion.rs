// SPDX-License-Identifier: MIT OR Apache-2.0
//! Distortion of a layer's map over the triangles it covers: kernel `wgsl/maps/distortion.wgsl`
//! (dispatched by the compose stage, which has the triangle lists), CPU twin [`distortion`].

use crate::mesh::Topology;
use glam::Vec2;

/// Workgroups per layer in `distortion.wgsl`. Keep in sync with the WGSL constant.
pub const DIST_GROUPS: u32 = 16;

/// vec4s a workgroup of `distortion.wgsl` writes.
pub const PARTIAL_VEC4S: usize = 3;

/// A triangle drawn by a layer whose map's area ratio (model units in, model units out: 1 is an
/// isometry) lies in [0, this) is collapsed; one whose |ratio| exceeds its inverse is torn
/// (stretched across a cut or a fold of the map). Keep in sync with `COLLAPSED` in the kernel.
pub const COLLAPSED_RATIO: f32 = 1e-3;

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
    /// Triangles not flipped whose area ratio is below [`COLLAPSED_RATIO`].
    pub collapsed: u32,
    /// Triangles whose |area ratio| exceeds 1 / [`COLLAPSED_RATIO`].
    pub torn: u32,
}

impl Distortion {
    /// Adds up the GPU partials of one layer (`PARTIAL_VEC4S × DIST_GROUPS` vec4s), in order.
    pub fn from_partials(p: &[[f32; 4]]) -> Self {
        let (mut a, mut ratio_max, mut ratio_min, mut angle_max) =
            ([0.0f64; 4], f32::MIN, f32::MAX, 0.0f32);
        let mut counts = [0.0f64; 2];
        for group in p.chunks_exact(PARTIAL_VEC4S) {
            for k in 0..4 {
                a[k] += group[0][k] as f64;
            }
            angle_max = angle_max.max(group[1][0]);
            ratio_max = ratio_max.max(group[1][1]);
            ratio_min = ratio_min.min(group[1][2]);
            counts[0] += group[2][0] as f64;
            counts[1] += group[2][1] as f64;
        }
        let w = a[0].max(f64::MIN_POSITIVE);
        Self {
            area_ratio_mean: (a[1] / w) as f32,
            area_ratio_min: ratio_min,
            area_ratio_max: ratio_max,
            angle_distortion_mean: (a[2] / w) as f32,
            angle_distortion_max: angle_max,
            flipped: a[3].round() as u32,
            collapsed: counts[0].round() as u32,
            torn: counts[1].round() as u32,
        }
    }

    /// Triangles flipped, collapsed or torn.
    pub fn folds(&self) -> u32 {
        self.flipped + self.collapsed + self.torn
    }
}

impl Distortion {
    /// Several maps' distortion as one: means weighted by the triangle counts given, extremes and
    /// flips over all (a stroke's stamps).
    pub fn combine(parts: impl Iterator<Item = (Distortion, u32)>) -> Self {
        let mut out = Distortion {
            area_ratio_min: f32::MAX,
            area_ratio_max: f32::MIN,
            ..Default::default()
        };
        let mut w = 0.0f64;
        let (mut area, mut angle) = (0.0f64, 0.0f64);
        for (d, n) in parts.filter(|(_, n)| *n > 0) {
            w += n as f64;
            area += d.area_ratio_mean as f64 * n as f64;
            angle += d.angle_distortion_mean as f64 * n as f64;
            out.area_ratio_min = out.area_ratio_min.min(d.area_ratio_min);
            out.area_ratio_max = out.area_ratio_max.max(d.area_ratio_max);
            out.angle_distortion_max = out.angle_distortion_max.max(d.angle_distortion_max);
            out.flipped += d.flipped;
            out.collapsed += d.collapsed;
            out.torn += d.torn;
        }
        if w == 0.0 {
            return Distortion::default();
        }
        out.area_ratio_mean = (area / w) as f32;
        out.angle_distortion_mean = (angle / w) as f32;
        out
    }
}

/// CPU twin of `distortion.wgsl` for one layer: its coordinates, through its chart's cone where it
/// has one (the triangles the cut crosses left out, as the kernel does).
pub fn distortion(
    topo: &Topology,
    (coords, cone): (&[[f32; 4]], Option<&crate::maps::chart::cone::Cone>),
    triangles: &[u32],
) -> Distortion {
    let mut partial = [[0.0f32; 4], [0.0, f32::MIN, f32::MAX, 0.0], [0.0; 4]];
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
        let w = tri
            .map(|v| glam::DVec2::new(coords[v as usize][0] as f64, coords[v as usize][1] as f64));
        if cone.is_some_and(|k| k.cut_crosses(w)) {
            continue;
        }
        let c = |i: usize| match cone {
            Some(k) => k.apply(w[i]).as_vec2(),
            None => Vec2::new(coords[tri[i] as usize][0], coords[tri[i] as usize][1]),
        };
        let (d1, d2) = (c(1) - c(0), c(2) - c(0));
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
        partial[2][0] += f32::from((0.0..COLLAPSED_RATIO).contains(&det));
        partial[2][1] += f32::from(det.abs() > 1.0 / COLLAPSED_RATIO);
    }
    Distortion::from_partials(&partial)
}
