// SPDX-License-Identifier: MIT OR Apache-2.0
//! The preconditioned conjugate gradient in f64: the CPU twin of `wgsl/solve/cg_batched.wgsl`
//! (Jacobi) and `wgsl/solve/cg_amg.wgsl` (a multigrid V-cycle, [`crate::solve::amg`]), the
//! tests' oracle and the benchmarks' baseline.

use crate::solve::amg::{Hierarchy, AMG_MIN_ROWS};
use crate::solve::sparse::{dot, residual_scale, CgReport, CgStatus, Csr, PreconditionerKind};

/// The preconditioner of a CG solve: Jacobi, or a multigrid V-cycle for systems of at least
/// [`crate::solve::amg::AMG_MIN_ROWS`] rows whose hierarchy builds.
#[derive(Debug, Clone)]
pub enum Preconditioner {
    /// 1 / dᵢ per row (1 where dᵢ is 0).
    Jacobi(Vec<f64>),
    /// One V-cycle on the hierarchy.
    Amg(Box<Hierarchy>),
}

impl Preconditioner {
    /// Jacobi's.
    pub fn jacobi(a: &Csr) -> Self {
        Self::Jacobi(
            a.diagonal()
                .iter()
                .map(|&d| if d != 0.0 { 1.0 / d } else { 1.0 })
                .collect(),
        )
    }

    /// The one both solvers choose for `a`: a V-cycle from [`AMG_MIN_ROWS`] rows on when
    /// [`Hierarchy::build`] gives one, else Jacobi's.
    pub fn for_matrix(a: &Csr) -> Self {
        if a.rows < AMG_MIN_ROWS {
            return Self::jacobi(a);
        }
        match Hierarchy::build(a) {
            Some(h) => Self::Amg(Box::new(h)),
            None => Self::jacobi(a),
        }
    }

    /// z = M r.
    pub fn apply(&self, r: &[f64]) -> Vec<f64> {
        match self {
            Self::Jacobi(d) => r.iter().zip(d).map(|(r, d)| r * d).collect(),
            Self::Amg(h) => h.apply(r),
        }
    }

    /// Which one it is.
    pub fn kind(&self) -> PreconditionerKind {
        match self {
            Self::Jacobi(_) => PreconditionerKind::Jacobi,
            Self::Amg(_) => PreconditionerKind::Amg,
        }
    }
}

/// Preconditioned conjugate gradient for SPD `a` with the preconditioner the GPU solver would
/// choose ([`Preconditioner::for_matrix`]), from `x` (warm start) until |b - A x| <= `rtol` ×
/// [`residual_scale`] or `max_iter` iterations. The CPU twin of `cg_batched.wgsl` and
/// `cg_amg.wgsl` (same algorithm and stopping rule in f64, without the residual replacement f32
/// needs).
pub fn pcg(a: &Csr, b: &[f64], x: &mut [f64], rtol: f64, max_iter: u32) -> CgReport {
    pcg_with(a, b, x, rtol, max_iter, &Preconditioner::for_matrix(a))
}

/// [`pcg`] with the preconditioner `m`.
pub fn pcg_with(
    a: &Csr,
    b: &[f64],
    x: &mut [f64],
    rtol: f64,
    max_iter: u32,
    m: &Preconditioner,
) -> CgReport {
    let n = a.rows;
    let preconditioner = m.kind();
    let ax = a.mul(x);
    let mut r: Vec<f64> = (0..n).map(|i| b[i] - ax[i]).collect();
    if dot(b, b) == 0.0 {
        x.iter_mut().for_each(|v| *v = 0.0);
        return CgReport {
            preconditioner,
            status: CgStatus::Converged,
            iterations: 0,
            residual: 0.0,
        };
    }
    let mut scale = residual_scale(a, b, x);
    let mut z = m.apply(&r);
    let mut p = z.clone();
    let mut rz = dot(&r, &z);
    let mut res = dot(&r, &r).sqrt() / scale;
    let mut it = 0;
    loop {
        if res <= rtol {
            // Confirm against the scale of the current x.
            scale = residual_scale(a, b, x);
            res = dot(&r, &r).sqrt() / scale;
            if res <= rtol {
                break;
            }
        }
        if it >= max_iter {
            return CgReport {
                preconditioner,
                status: CgStatus::NotConverged,
                iterations: it,
                residual: res,
            };
        }
        let q = a.mul(&p);
        let pq = dot(&p, &q);
        if pq.is_nan() || pq <= 0.0 || !pq.is_finite() {
            return CgReport {
                preconditioner,
                status: CgStatus::Breakdown,
                iterations: it,
                residual: res,
            };
        }
        let alpha = rz / pq;
        for i in 0..n {
            x[i] += alpha * p[i];
            r[i] -= alpha * q[i];
        }
        z = m.apply(&r);
        let rz2 = dot(&r, &z);
        if (it + 1) % 50 == 0 {
            // The GPU kernel refreshes its reference with each residual replacement; so does the twin.
            scale = residual_scale(a, b, x);
        }
        res = dot(&r, &r).sqrt() / scale;
        if !res.is_finite() {
            return CgReport {
                preconditioner,
                status: CgStatus::Breakdown,
                iterations: it + 1,
                residual: res,
            };
        }
        let beta = rz2 / rz;
        rz = rz2;
        for i in 0..n {
            p[i] = z[i] + beta * p[i];
        }
        it += 1;
    }
    CgReport {
        preconditioner,
        status: CgStatus::Converged,
        iterations: it,
        residual: res,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::sparse::relative_residual;

    #[test]
    fn pcg_solves_a_small_spd_system() {
        // 1D Laplacian plus identity: SPD, known to converge in at most n steps in exact arithmetic.
        let n = 20;
        let mut t = Vec::new();
        for i in 0..n as u32 {
            t.push((i, i, 3.0));
            if i > 0 {
                t.push((i, i - 1, -1.0));
                t.push((i - 1, i, -1.0));
            }
        }
        let a = Csr::from_triplets(n, t);
        let xs: Vec<f64> = (0..n).map(|i| (i as f64 * 0.7).sin()).collect();
        let b = a.mul(&xs);
        let mut x = vec![0.0; n];
        let rep = pcg(&a, &b, &mut x, 1e-12, 100);
        assert_eq!(rep.status, CgStatus::Converged);
        for i in 0..n {
            assert!((x[i] - xs[i]).abs() < 1e-10);
        }
        assert!(relative_residual(&a, &b, &x) <= 1e-12);
    }
}
