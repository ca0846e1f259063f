// SPDX-License-Identifier: MIT OR Apache-2.0
//! Continuous stamp charts (Maillot, "Continuous Local Parameterization of Polygons", section 7): a
//! stamp's coordinates interpolated from per-vertex charts instead of solved at its point, so they
//! vary continuously as the stamp moves, across triangle edges and vertices.
//!
//! The stamp lies in triangle (a, b, c) at barycentric coordinates β. Each corner v has a chart C_v
//! solved at v (any method), with the stamp's size grown by the longest edge at v so that it covers
//! the stamp wherever the stamp's point is in a triangle around v, and normalised at v to unit scale
//! and v's frame axes. Each chart is moved so that the stamp's point goes to the origin (its value
//! there is the β-interpolation of its values at a, b, c) and turned by θ_v, the angle of the stamp's
//! image x axis in v's frame; the results are interpolated with the weights w (β, and the two
//! neighbouring size levels of §7 where stamp sizes vary):
//!
//! `C(x) = Σ_k w_k R(−θ_k) (C_k(x) − Σ_j β_j C_k(corner_j))`
//!
//! Every term is continuous in the stamp's point: β is, the charts do not depend on the hit triangle,
//! θ_k turns with the stamp's axis, and a corner leaves the sum with weight 0. The paper fits each
//! chart to the hit triangle by least squares instead of using its frame at v; that fit changes when
//! the point crosses an edge, which the frame does not. A vertex is valid where every chart with a
//! non-zero weight is. GPU kernel `wgsl/maps/stamp_blend.wgsl`; [`blend_cpu`] is its CPU twin.

/// How a stamp's coordinates follow from the charts of its corners.
#[derive(Debug, Clone, PartialEq)]
pub struct StampBlend {
    /// (chart unit, weight, θ in radians) per chart with a non-zero weight; chart units are unit
    /// indices (within the layer in [`crate::bake::kinds::Unit`], of the whole bake afterwards).
    pub charts: Vec<(usize, f32, f32)>,
    /// The stamp's triangle (welded vertex ids).
    pub corners: [u32; 3],
    /// The stamp's barycentric coordinates there.
    pub bary: [f32; 3],
}

/// Most charts a stamp blends: three corners at two size levels.
pub const MAX_CHARTS: usize = 6;

/// The stamp's coordinates from its charts' (`charts[k]` is chart k's slot: x, y, _, valid per
/// welded vertex). Twin of `stamp_blend.wgsl`.
pub fn blend_cpu(blend: &StampBlend, charts: &[&[[f32; 4]]]) -> Vec<[f32; 4]> {
    let n = charts.first().map_or(0, |c| c.len());
    let centres: Vec<[f32; 2]> = charts
        .iter()
        .map(|c| {
            let mut p = [0.0f32; 2];
            for j in 0..3 {
                let v = c[blend.corners[j] as usize];
                p[0] += blend.bary[j] * v[0];
                p[1] += blend.bary[j] * v[1];
            }
            p
        })
        .collect();
    (0..n)
        .map(|x| {
            let mut acc = [0.0f32; 2];
            for (k, &(_, w, theta)) in blend.charts.iter().enumerate() {
                let c = charts[k][x];
                if c[3] < 0.5 {
                    return [0.0; 4];
                }
                let (s, co) = theta.sin_cos();
                let d = [c[0] - centres[k][0], c[1] - centres[k][1]];
                acc[0] += w * (co * d[0] + s * d[1]);
                acc[1] += w * (-s * d[0] + co * d[1]);
            }
            [acc[0], acc[1], 0.0, 1.0]
        })
        .collect()
}
