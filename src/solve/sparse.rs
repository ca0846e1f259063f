// SPDX-License-Identifier: MIT OR Apache-2.0
//! Sparse matrices on the CPU: compressed sparse rows (CSR) built from triplets, their complex
//! 2 × 2 block form, the CPU twin of `wgsl/solve/spmv.wgsl` (the product `A x`, in f64), and what a
//! conjugate-gradient solve reports (the solve itself, twin of the CG kernels, is
//! [`crate::solve::cg`]). They are the tests' oracles and the baseline of `decalbake bench
//! --linalg`.
//!
//! A batch of independent systems is one block-diagonal matrix: system `s` owns rows
//! `row0 .. row0 + n` and only references columns in that range ([`Csr::block_diagonal`]).

/// A sparse matrix in CSR form, f64 values. Rows are sorted by column and duplicates are summed.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Csr {
    /// Rows.
    pub rows: usize,
    /// Row start offsets into `cols`/`vals` (length `rows + 1`).
    pub row_ptr: Vec<u32>,
    /// Column of each stored entry.
    pub cols: Vec<u32>,
    /// Value of each stored entry.
    pub vals: Vec<f64>,
}

impl Csr {
    /// Builds a `rows × rows` matrix from `(row, col, value)` triplets; repeated positions are summed.
    ///
    /// The triplets are bucketed by row (a counting sort) and each row's few sorted by column:
    /// sorting all of them at once took 9 % of an unwrap of bob subdivided twice.
    pub fn from_triplets(rows: usize, t: Vec<(u32, u32, f64)>) -> Self {
        let mut start = vec![0usize; rows + 1];
        for &(r, _, _) in &t {
            start[r as usize + 1] += 1;
        }
        for i in 0..rows {
            start[i + 1] += start[i];
        }
        let mut fill = start.clone();
        let mut bucketed = vec![(0u32, 0.0f64); t.len()];
        for (r, c, v) in t {
            bucketed[fill[r as usize]] = (c, v);
            fill[r as usize] += 1;
        }
        let mut row_ptr = vec![0u32; rows + 1];
        let mut cols = Vec::with_capacity(bucketed.len());
        let mut vals: Vec<f64> = Vec::with_capacity(bucketed.len());
        for r in 0..rows {
            let row = &mut bucketed[start[r]..start[r + 1]];
            row.sort_by_key(|&(c, _)| c);
            let first = cols.len();
            for &(c, v) in row.iter() {
                if cols.len() > first && cols.last() == Some(&c) {
                    *vals.last_mut().expect("a previous entry") += v;
                } else {
                    cols.push(c);
                    vals.push(v);
                }
            }
            row_ptr[r + 1] = cols.len() as u32;
        }
        Self {
            rows,
            row_ptr,
            cols,
            vals,
        }
    }

    /// Stored entries.
    pub fn nnz(&self) -> usize {
        self.vals.len()
    }

    /// The entries of row `i`: (column, value).
    pub fn row(&self, i: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
        let (a, b) = (self.row_ptr[i] as usize, self.row_ptr[i + 1] as usize);
        self.cols[a..b]
            .iter()
            .zip(&self.vals[a..b])
            .map(|(&c, &v)| (c as usize, v))
    }

    /// `A x` (CPU twin of `spmv.wgsl`, in f64).
    pub fn mul(&self, x: &[f64]) -> Vec<f64> {
        (0..self.rows).map(|i| self.row_dot(i, x)).collect()
    }

    /// [`Csr::mul`] on every core (rayon): the same sums row by row, so the same bits.
    pub fn mul_par(&self, x: &[f64]) -> Vec<f64> {
        use rayon::prelude::*;
        (0..self.rows)
            .into_par_iter()
            .with_min_len(1024)
            .map(|i| self.row_dot(i, x))
            .collect()
    }

    /// Row `i` times `x`.
    fn row_dot(&self, i: usize, x: &[f64]) -> f64 {
        self.row(i).map(|(c, v)| v * x[c]).sum()
    }

    /// The diagonal.
    pub fn diagonal(&self) -> Vec<f64> {
        (0..self.rows)
            .map(|i| self.row(i).filter(|&(c, _)| c == i).map(|(_, v)| v).sum())
            .collect()
    }

    /// Longest row.
    pub fn max_row_len(&self) -> usize {
        longest_row(&self.row_ptr)
    }

    /// Rows `row0 .. row0 + n` of a block-diagonal matrix as a matrix of their own (columns
    /// shifted by `row0`; the block must not reference columns outside it).
    pub fn sub_block(&self, row0: usize, n: usize) -> Csr {
        let (s, e) = (self.row_ptr[row0] as usize, self.row_ptr[row0 + n] as usize);
        Csr {
            rows: n,
            row_ptr: self.row_ptr[row0..=row0 + n]
                .iter()
                .map(|p| p - s as u32)
                .collect(),
            cols: self.cols[s..e].iter().map(|c| c - row0 as u32).collect(),
            vals: self.vals[s..e].to_vec(),
        }
    }

    /// The block-diagonal matrix of `blocks`, and each block's first row.
    pub fn block_diagonal(blocks: &[&Csr]) -> (Csr, Vec<usize>) {
        let mut out = Csr {
            rows: 0,
            row_ptr: vec![0],
            cols: Vec::new(),
            vals: Vec::new(),
        };
        let mut starts = Vec::with_capacity(blocks.len());
        for b in blocks {
            let off = out.rows as u32;
            starts.push(out.rows);
            let base = out.cols.len() as u32;
            out.cols.extend(b.cols.iter().map(|c| c + off));
            out.vals.extend_from_slice(&b.vals);
            out.row_ptr.extend(b.row_ptr[1..].iter().map(|p| p + base));
            out.rows += b.rows;
        }
        (out, starts)
    }
}

/// A real matrix of even size whose 2 × 2 blocks all have the form [[a, -b], [b, a]], stored as one
/// complex entry (a, b) per block: rows and columns are block indices (a vertex's (u, v) pair in an
/// LSCM system). The real form of a Hermitian matrix has this structure, and the LSCM energy is a
/// Hermitian form in z = u + i v (Lévy et al. 2002), so the conjugate gradient can read one column and
/// one (a, b) where the real CSR reads four entries with their columns (`wgsl/shared/cg_complex.wgsl`).
#[derive(Debug, Clone, PartialEq)]
pub struct ComplexCsr {
    /// Block rows (half the real rows).
    pub rows: usize,
    /// Block-row start offsets into `cols`/`vals` (length `rows + 1`).
    pub row_ptr: Vec<u32>,
    /// Block column of each stored block.
    pub cols: Vec<u32>,
    /// (a, b) of each stored block.
    pub vals: Vec<[f64; 2]>,
}

/// Largest difference between a block's two copies of `a` (and of `b`) allowed by
/// [`ComplexCsr::from_real`], relative to the block's largest entry: the LSCM assembly computes the
/// two copies with the same products added in another order, which differ in the last bits only.
pub const COMPLEX_REL_TOL: f64 = 1e-9;

impl ComplexCsr {
    /// The blocks of `a`, or `None` when `a` has an odd size or a block that is not of the form
    /// [[a, -b], [b, a]] within [`COMPLEX_REL_TOL`] (a missing entry counts as 0). Each (a, b) is
    /// the mean of its two copies.
    pub fn from_real(a: &Csr) -> Option<Self> {
        if !a.rows.is_multiple_of(2) {
            return None;
        }
        let rows = a.rows / 2;
        let mut out = ComplexCsr {
            rows,
            row_ptr: vec![0],
            cols: Vec::new(),
            vals: Vec::new(),
        };
        // The two real rows of block row i, both sorted by column, walked side by side one block
        // column at a time.
        for i in 0..rows {
            let ends = |r: usize| (a.row_ptr[r] as usize, a.row_ptr[r + 1] as usize);
            let ((mut p0, e0), (mut p1, e1)) = (ends(2 * i), ends(2 * i + 1));
            while p0 < e0 || p1 < e1 {
                let next = |p: usize, e: usize| if p < e { a.cols[p] / 2 } else { u32::MAX };
                let j = next(p0, e0).min(next(p1, e1));
                let mut block = [0.0f64; 4];
                while p0 < e0 && a.cols[p0] / 2 == j {
                    block[(a.cols[p0] % 2) as usize] = a.vals[p0];
                    p0 += 1;
                }
                while p1 < e1 && a.cols[p1] / 2 == j {
                    block[2 + (a.cols[p1] % 2) as usize] = a.vals[p1];
                    p1 += 1;
                }
                let [uu, uv, vu, vv] = block;
                let scale = uu.abs().max(uv.abs()).max(vu.abs()).max(vv.abs());
                let tol = COMPLEX_REL_TOL * scale;
                if (uu - vv).abs() > tol || (uv + vu).abs() > tol {
                    return None;
                }
                out.cols.push(j);
                out.vals.push([0.5 * (uu + vv), 0.5 * (vu - uv)]);
            }
            out.row_ptr.push(out.cols.len() as u32);
        }
        Some(out)
    }

    /// The real matrix of these blocks.
    pub fn to_real(&self) -> Csr {
        let mut t = Vec::with_capacity(4 * self.vals.len());
        for i in 0..self.rows {
            let (s, e) = (self.row_ptr[i] as usize, self.row_ptr[i + 1] as usize);
            for (&j, &[a, b]) in self.cols[s..e].iter().zip(&self.vals[s..e]) {
                let (r, c) = (2 * i as u32, 2 * j);
                t.extend([(r, c, a), (r, c + 1, -b), (r + 1, c, b), (r + 1, c + 1, a)]);
            }
        }
        Csr::from_triplets(2 * self.rows, t)
    }

    /// Longest block row.
    pub fn max_row_len(&self) -> usize {
        longest_row(&self.row_ptr)
    }
}

/// The most entries of one row, from CSR row offsets.
fn longest_row(row_ptr: &[u32]) -> usize {
    row_ptr
        .windows(2)
        .map(|w| (w[1] - w[0]) as usize)
        .max()
        .unwrap_or(0)
}

/// Dot product in f64.
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Outcome of a conjugate-gradient solve.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum CgStatus {
    /// The relative residual reached the target.
    Converged,
    /// The iteration budget ran out first.
    NotConverged,
    /// NaN or infinity appeared, or the matrix showed it is not positive definite.
    Breakdown,
}

/// The preconditioner a solve used.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PreconditionerKind {
    /// 1 / dᵢ per row.
    #[default]
    Jacobi,
    /// One smoothed-aggregation V-cycle ([`crate::solve::amg`]).
    Amg,
}

/// What a solve reports.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct CgReport {
    /// Status.
    pub status: CgStatus,
    /// The preconditioner.
    pub preconditioner: PreconditionerKind,
    /// Iterations run.
    pub iterations: u32,
    /// Final relative residual |b - A x| / max(|b|, |(|A| |x|)|) (see [`residual_scale`]).
    pub residual: f64,
}

/// The reference a residual is measured against: max(|b|, |(|A| |x|)|). Relative to |b| alone a
/// well-solved system whose right-hand side is small next to the terms of `A x` (an LSCM chart's
/// only comes from two pinned vertices) could never reach a tight target in f32; this is the
/// normwise backward error, what f32 arithmetic can actually deliver.
pub fn residual_scale(a: &Csr, b: &[f64], x: &[f64]) -> f64 {
    let ax: f64 = (0..a.rows)
        .map(|i| {
            let s: f64 = a.row(i).map(|(c, v)| (v * x[c]).abs()).sum();
            s * s
        })
        .sum::<f64>()
        .sqrt();
    dot(b, b).sqrt().max(ax)
}

/// Relative residual |b - A x| / [`residual_scale`] in f64 (the measure both solvers stop on).
pub fn relative_residual(a: &Csr, b: &[f64], x: &[f64]) -> f64 {
    let ax = a.mul(x);
    let r: f64 = ax
        .iter()
        .zip(b)
        .map(|(p, q)| (q - p) * (q - p))
        .sum::<f64>()
        .sqrt();
    let s = residual_scale(a, b, x);
    if s == 0.0 {
        r
    } else {
        r / s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn triplets_sum_and_sort() {
        let a = Csr::from_triplets(2, vec![(1, 0, 1.0), (0, 1, 2.0), (0, 0, 3.0), (0, 1, 4.0)]);
        assert_eq!(a.row_ptr, vec![0, 2, 3]);
        assert_eq!(a.cols, vec![0, 1, 0]);
        assert_eq!(a.vals, vec![3.0, 6.0, 1.0]);
        assert_eq!(a.mul(&[1.0, 2.0]), vec![15.0, 1.0]);
    }
}
