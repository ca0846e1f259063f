// SPDX-License-Identifier: MIT OR Apache-2.0
//! The automatic matte of `decalbake extract --matte` (Sun et al. 2013, section 4.2): which part of
//! an extracted strip is the feature to clone and which is the surface around it.
//!
//! Sun et al. take the initial alpha from GrabCut's colour models; here (the engine's choice: no
//! segmentation model to train) it comes from the colour distance to the strip's border: the
//! pixels within [`BORDER`] of the image's frame are background (alpha 0, fixed), and every other
//! covered pixel starts at α̂ = min(1, d / s), d its linear-RGB distance to the nearest border
//! colour (at most [`MAX_BORDER_COLORS`], evenly subsampled) and s half the 99th percentile of d
//! (a feature's colours count fully from half the distance of the most distinct ones present; a
//! percentile rather than the maximum, so a stray pixel does not set the scale). The paper's objective then smooths it:
//!
//! min Σ_i (α_i − α̂_i)² + λ Σ_{i~j} ω_ij (α_i − α_j)²,  ω_ij = exp(−|C_i − C_j|² / (2σ²)),
//!
//! over 4-neighbours (λ = [`LAMBDA`], σ = [`SIGMA`]: the paper gives no values), i.e. the sparse
//! SPD system (I + λ L_ω) α = α̂ over the free pixels, border neighbours entering at α = 0. It is
//! solved on the GPU conjugate gradient ([`crate::solve::gpu::cg_batched`]; twin
//! [`crate::solve::cg::pcg`] in f64, `solve_cpu`).

use crate::error::Result;
use crate::io::image::LinearImage;
use crate::solve::sparse::{CgReport, Csr};

/// Pixels within this distance of the image's frame are background.
pub const BORDER: u32 = 2;
/// The smoothing weight λ.
pub const LAMBDA: f64 = 2.0;
/// The colour scale σ of the neighbour weights (linear RGB).
pub const SIGMA: f64 = 0.1;
/// Border colours compared against.
pub const MAX_BORDER_COLORS: usize = 256;
/// The solve's relative residual target (alpha to well under an 8-bit step).
pub const RTOL: f32 = 1e-5;

/// The matte's linear system.
pub struct MatteSystem {
    /// I + λ L_ω over the free pixels.
    pub a: Csr,
    /// α̂ of the free pixels.
    pub b: Vec<f64>,
    /// Per pixel: its unknown, if free.
    pub index: Vec<Option<u32>>,
    /// Border colours compared against.
    pub border_colors: usize,
}

/// What the matte reports.
#[derive(Debug, Clone, serde::Serialize)]
pub struct MatteReport {
    /// Free pixels (unknowns).
    pub unknowns: usize,
    /// Border colours compared against.
    pub border_colors: usize,
    /// The solve.
    pub solve: CgReport,
}

/// Builds the system of `img` (covered pixels: alpha > 0, as `extract` leaves them).
pub fn system(img: &LinearImage) -> MatteSystem {
    let (w, h) = (img.width as usize, img.height as usize);
    let covered = |i: usize| img.pixels[i][3] > 0.0;
    let near_frame = |i: usize| {
        let (x, y) = ((i % w) as u32, (i / w) as u32);
        x < BORDER || y < BORDER || x + BORDER >= w as u32 || y + BORDER >= h as u32
    };
    let rgb = |i: usize| {
        glam::DVec3::new(
            img.pixels[i][0] as f64,
            img.pixels[i][1] as f64,
            img.pixels[i][2] as f64,
        )
    };
    let border: Vec<usize> = (0..w * h)
        .filter(|&i| covered(i) && near_frame(i))
        .collect();
    let step = border.len().div_ceil(MAX_BORDER_COLORS).max(1);
    let colors: Vec<glam::DVec3> = border.iter().step_by(step).map(|&i| rgb(i)).collect();
    let mut index = vec![None; w * h];
    let mut free = Vec::new();
    for i in (0..w * h).filter(|&i| covered(i) && !near_frame(i)) {
        index[i] = Some(free.len() as u32);
        free.push(i);
    }
    let dist: Vec<f64> = free
        .iter()
        .map(|&i| {
            colors
                .iter()
                .map(|c| (rgb(i) - *c).length())
                .fold(f64::INFINITY, f64::min)
        })
        .collect();
    let mut sorted: Vec<f64> = dist.iter().copied().filter(|d| d.is_finite()).collect();
    sorted.sort_by(f64::total_cmp);
    let p99 = sorted.get(sorted.len() * 99 / 100).copied().unwrap_or(1.0);
    let scale = (0.5 * p99).max(1e-3);
    let b: Vec<f64> = dist
        .iter()
        .map(|d| {
            if d.is_finite() {
                (d / scale).min(1.0)
            } else {
                1.0
            }
        })
        .collect();
    let mut t = Vec::with_capacity(free.len() * 5);
    for (r, &i) in free.iter().enumerate() {
        let (x, y) = (i % w, i / w);
        let mut diag = 1.0;
        let nbrs = [
            (x > 0, i.wrapping_sub(1)),
            (x + 1 < w, i + 1),
            (y > 0, i.wrapping_sub(w)),
            (y + 1 < h, i + w),
        ];
        for (ok, j) in nbrs {
            if !ok || !covered(j) {
                continue;
            }
            let wij = LAMBDA * (-(rgb(i) - rgb(j)).length_squared() / (2.0 * SIGMA * SIGMA)).exp();
            diag += wij;
            if let Some(c) = index[j] {
                t.push((r as u32, c, -wij));
            }
        }
        t.push((r as u32, r as u32, diag));
    }
    MatteSystem {
        a: Csr::from_triplets(free.len(), t),
        b,
        index,
        border_colors: colors.len(),
    }
}

/// The system solved on the GPU conjugate gradient (from α̂).
pub fn solve_gpu(engine: &crate::bake::Engine, sys: &MatteSystem) -> Result<(Vec<f64>, CgReport)> {
    use crate::solve::gpu::{cg_batched, SystemDesc};
    let n = sys.b.len();
    if n == 0 {
        return Ok((Vec::new(), empty_report()));
    }
    let desc = SystemDesc::new(0, n, RTOL, 2000);
    let out = cg_batched(&engine.ctx, &engine.pipes, &sys.a, &sys.b, &sys.b, &[desc])?;
    Ok((out.x.iter().map(|&v| v as f64).collect(), out.reports[0]))
}

/// CPU twin of [`solve_gpu`] (f64 PCG, the same preconditioner choice and stopping rule).
pub fn solve_cpu(sys: &MatteSystem) -> (Vec<f64>, CgReport) {
    let mut x = sys.b.clone();
    if x.is_empty() {
        return (x, empty_report());
    }
    let rep = crate::solve::cg::pcg(&sys.a, &sys.b, &mut x, RTOL as f64, 2000);
    (x, rep)
}

/// The report of a system with no unknowns (nothing to solve: converged).
fn empty_report() -> CgReport {
    CgReport {
        status: crate::solve::sparse::CgStatus::Converged,
        preconditioner: Default::default(),
        iterations: 0,
        residual: 0.0,
    }
}

/// `img`'s alpha set to the matte: the solution (clamped to [0, 1]) on free pixels, 0 on the
/// border and where nothing was covered.
pub fn apply(img: &mut LinearImage, sys: &MatteSystem, alpha: &[f64]) {
    for (p, ix) in img.pixels.iter_mut().zip(&sys.index) {
        p[3] = ix.map_or(0.0, |k| alpha[k as usize].clamp(0.0, 1.0) as f32);
    }
}
