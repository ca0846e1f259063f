// SPDX-License-Identifier: MIT OR Apache-2.0
//! The thin-plate-spline warp of a layer's image (Schmidt et al. 2006, section 6.1; Sun et al. 2013,
//! section 4.4 "texture deformation"): a smooth map T of image coordinates with T(to_k) = from_k
//! for each pair of the layer's `warp`, so the texel that showed image point p now shows T(p) and
//! the content at `from` appears at `to`.
//!
//! T(p) = a0 + a1 p.x + a2 p.y + Σ_k w_k φ(|p - c_k|), φ(r) = r² ln r, the centres c_k being the
//! `to` points and the image's four corners (pinned: T(corner) = corner) unless a pair's `to` lies
//! on one. The weights solve the usual bordered system [K P; Pᵀ 0] [w; a] = [from; 0] (in f64, on
//! the CPU: at most 36 centres); with four non-collinear corners among at most 36 distinct centres
//! it is never singular. The GPU evaluates T per fragment (`warp_apply` in
//! `wgsl/bake/layer_raster.wgsl`) from [`Tps::pack`]; the CPU twin is [`Tps::eval`] on the same f32
//! coefficients.

/// The image corners pinned by default.
const CORNERS: [[f64; 2]; 4] = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]];

/// A fitted warp, its coefficients rounded to f32 as the GPU reads them.
#[derive(Debug, Clone, PartialEq)]
pub struct Tps {
    /// a0, a1, a2 of the affine part.
    pub affine: [[f32; 2]; 3],
    /// Centres and their weights.
    pub centers: Vec<([f32; 2], [f32; 2])>,
}

/// The spline's kernel φ(r) = r² ln r, taken at r² (0 at 0).
fn kernel(r2: f64) -> f64 {
    if r2 <= 0.0 {
        0.0
    } else {
        0.5 * r2 * r2.ln()
    }
}

impl Tps {
    /// The spline through `pairs` ([from, to], validated by `io::warp`) and the pinned corners.
    /// `None` without pairs. Pairs that keep their points fit the identity exactly (the weights
    /// and the affine part's off-terms round to zero), so the layer draws bit for bit as without
    /// a warp (`tests/ribbon.rs` checks it through the GPU's warp branch).
    pub fn fit(pairs: &[[[f32; 2]; 2]]) -> Option<Tps> {
        if pairs.is_empty() {
            return None;
        }
        let near = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]) < 1e-3;
        let mut pts: Vec<([f64; 2], [f64; 2])> = pairs
            .iter()
            .map(|[f, t]| (t.map(f64::from), f.map(f64::from)))
            .collect();
        for c in CORNERS {
            if !pts.iter().any(|(t, _)| near(*t, c)) {
                pts.push((c, c));
            }
        }
        let n = pts.len();
        let m = n + 3;
        let mut a = vec![vec![0.0f64; m + 2]; m];
        for (i, (ci, fi)) in pts.iter().enumerate() {
            for (j, (cj, _)) in pts.iter().enumerate() {
                a[i][j] = kernel((ci[0] - cj[0]).powi(2) + (ci[1] - cj[1]).powi(2));
            }
            for (k, p) in [1.0, ci[0], ci[1]].into_iter().enumerate() {
                a[i][n + k] = p;
                a[n + k][i] = p;
            }
            a[i][m] = fi[0];
            a[i][m + 1] = fi[1];
        }
        let x = solve(a)?;
        // Coefficients below rounding noise are exactly zero, so a warp that moves nothing much
        // keeps the affine part exact.
        let clean = |v: f64| if v.abs() < 1e-12 { 0.0 } else { v as f32 };
        let affine = [0, 1, 2].map(|k| [clean(x[n + k][0]), clean(x[n + k][1])]);
        let centers = pts
            .iter()
            .zip(&x)
            .map(|((c, _), w)| (c.map(|v| v as f32), [clean(w[0]), clean(w[1])]))
            .collect();
        Some(Tps { affine, centers })
    }

    /// T(p), in f32 as the shader computes it.
    pub fn eval(&self, p: [f32; 2]) -> [f32; 2] {
        let [a0, a1, a2] = self.affine;
        let mut q = [
            a0[0] + a1[0] * p[0] + a2[0] * p[1],
            a0[1] + a1[1] * p[0] + a2[1] * p[1],
        ];
        for (c, w) in &self.centers {
            let (dx, dy) = (p[0] - c[0], p[1] - c[1]);
            let r2 = dx * dx + dy * dy;
            let phi = 0.5 * r2 * r2.max(1e-30).ln();
            q[0] += w[0] * phi;
            q[1] += w[1] * phi;
        }
        q
    }

    /// The GPU layout (`warp_apply`): vec4(a0, a1), vec4(a2, centres, 0), then one vec4(c, w) per
    /// centre.
    pub fn pack(&self) -> Vec<[f32; 4]> {
        let [a0, a1, a2] = self.affine;
        let mut out = vec![
            [a0[0], a0[1], a1[0], a1[1]],
            [a2[0], a2[1], self.centers.len() as f32, 0.0],
        ];
        out.extend(self.centers.iter().map(|(c, w)| [c[0], c[1], w[0], w[1]]));
        out
    }
}

/// Gaussian elimination with partial pivoting of `a` (rows: m coefficients then two right-hand
/// sides); `None` if singular.
fn solve(mut a: Vec<Vec<f64>>) -> Option<Vec<[f64; 2]>> {
    let m = a.len();
    for col in 0..m {
        let piv = (col..m).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[piv][col].abs() < 1e-14 {
            return None;
        }
        a.swap(col, piv);
        let (top, rest) = a.split_at_mut(col + 1);
        let pivot = &top[col];
        for row in rest {
            let f = row[col] / pivot[col];
            if f != 0.0 {
                for (x, p) in row[col..].iter_mut().zip(&pivot[col..]) {
                    *x -= f * p;
                }
            }
        }
    }
    let mut x = vec![[0.0; 2]; m];
    for r in (0..m).rev() {
        for k in 0..2 {
            let s: f64 = (r + 1..m).map(|c| a[r][c] * x[c][k]).sum();
            x[r][k] = (a[r][m + k] - s) / a[r][r];
        }
    }
    Some(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_spline_interpolates_its_pairs_and_pins_the_corners() {
        let t = Tps::fit(&[[[0.5, 0.5], [0.6, 0.4]], [[0.2, 0.8], [0.25, 0.8]]]).unwrap();
        for (p, want) in [
            ([0.6, 0.4], [0.5, 0.5]),
            ([0.25, 0.8], [0.2, 0.8]),
            ([0.0, 0.0], [0.0, 0.0]),
            ([1.0, 1.0], [1.0, 1.0]),
        ] {
            let q = t.eval(p);
            assert!(
                (q[0] - want[0]).abs() < 1e-5 && (q[1] - want[1]).abs() < 1e-5,
                "{p:?} -> {q:?}"
            );
        }
    }

    #[test]
    fn a_warp_that_moves_nothing_is_the_exact_identity() {
        let t = Tps::fit(&[[[0.3, 0.3], [0.3, 0.3]], [[0.7, 0.1], [0.7, 0.1]]]).unwrap();
        assert_eq!(t.affine, [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]);
        assert!(t.centers.iter().all(|(_, w)| *w == [0.0, 0.0]), "{t:?}");
        assert!(Tps::fit(&[]).is_none());
    }
}
