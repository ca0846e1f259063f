// SPDX-License-Identifier: MIT OR Apache-2.0
//! The multigrid hierarchies ([`crate::solve::amg`]) of a batch's large systems, laid out for
//! `wgsl/solve/cg_amg.wgsl`: one index space of `total` rows, the batch's own rows first and then
//! every coarse level of every such system; one CSR of every level's matrix in it (the batch's
//! matrix is its first rows, so the Jacobi kernels of the same batch read it unchanged), one CSR of
//! the prolongators (rows `0 .. total`) and restrictions (rows `total .. 2 total`), the smoother's
//! weights per row (1 / dᵢ on the rows of Jacobi systems), each level's (first row, rows), and the
//! coarsest levels' dense inverses.

use crate::solve::amg::{Hierarchy, AMG_MIN_ROWS, NU};
use crate::solve::sparse::{ComplexCsr, Csr};

/// Where one system's hierarchy lives, and what one iteration costs.
#[derive(Debug, Clone, Copy)]
pub(crate) struct AmgSystem {
    /// Its first entry in [`AmgBatch::levels`].
    pub lvl0: u32,
    /// Its levels, the finest (the system's own rows) and the coarsest included.
    pub nlev: u32,
    /// Offset of its coarsest level's inverse in [`AmgBatch::cinv`].
    pub cinv0: u32,
    /// Loop steps one invocation of a `wg`-wide workgroup runs per CG iteration (the lavapipe
    /// loop cut-off's measure, `solve::gpu`).
    pub steps: usize,
    /// The same on the real form (the batch's fallback when its complex form does not hold).
    pub steps_real: usize,
}

/// The batch's hierarchies, laid out.
pub(crate) struct AmgBatch {
    /// Every level's matrix, `total` rows.
    pub a: Csr,
    /// Prolongators then restrictions, `2 total` rows.
    pub pr: Csr,
    /// Smoother weight per row (Jacobi's 1 / dᵢ on other systems' rows; 0 on coarsest rows).
    pub weights: Vec<f32>,
    /// (first row, rows) per level.
    pub levels: Vec<[u32; 2]>,
    /// Dense inverses of the coarsest levels.
    pub cinv: Vec<f32>,
    /// Rows of the index space.
    pub total: usize,
    /// Per system of the batch, its hierarchy (`None`: solved with Jacobi).
    pub systems: Vec<Option<AmgSystem>>,
}

/// Loop steps per CG iteration of one invocation of a `wg`-wide workgroup on `h`: per level the
/// sweeps' and residual's products, the prolongation and restriction, the coarsest inverse, and
/// the CG's own passes (with a true residual) on the finest. `unit`: real rows per kernel row (2
/// on complex blocks, where rows and their entries both halve).
fn steps(h: &Hierarchy, wg: usize, unit: usize) -> usize {
    let per = |n: usize| (n / unit).div_ceil(wg).max(1);
    let len = |m: &Csr| m.max_row_len().div_ceil(unit);
    let mut s = 100;
    for lv in &h.levels {
        s += per(lv.a.rows) * ((2 * NU + 1) * (len(&lv.a) + 2) + len(&lv.p) + 2);
        s += per(lv.r.rows) * (len(&lv.r) + 2);
    }
    s += per(h.coarse_rows) * h.coarse_rows / unit;
    let fine = &h.levels[0].a;
    s + per(fine.rows) * (2 * len(fine) + 12)
}

/// The hierarchies of the systems (`(row0, n)` of the block-diagonal `a`) that `wants` picks and
/// that have at least [`AMG_MIN_ROWS`] rows and build one ([`Hierarchy::build`]).
pub(crate) fn hierarchies(
    a: &Csr,
    systems: &[(usize, usize)],
    wants: impl Fn(usize) -> bool,
) -> Vec<Option<Hierarchy>> {
    systems
        .iter()
        .enumerate()
        .map(|(k, &(row0, n))| {
            if n < AMG_MIN_ROWS || !wants(k) {
                return None;
            }
            Hierarchy::build(&a.sub_block(row0, n))
        })
        .collect()
}

/// Whether every system's hierarchy fits the loop limit on complex blocks (`unit` 2).
pub(crate) fn all_fit(hs: &[Option<Hierarchy>], wg: usize, max_steps: usize, unit: usize) -> bool {
    hs.iter()
        .all(|h| h.as_ref().is_some_and(|h| steps(h, wg, unit) <= max_steps))
}

/// The batch's layout on complex 2 × 2 blocks ([`ComplexCsr`]): rows, levels and offsets count
/// vertices.
pub(crate) struct ComplexLayout {
    /// Every level's matrix.
    pub a: ComplexCsr,
    /// Prolongators then restrictions.
    pub pr: ComplexCsr,
    /// Smoother weight per block row (the same for its two real rows: both have the diagonal a).
    pub weights: Vec<f32>,
    /// (first block row, block rows) per level.
    pub levels: Vec<[u32; 2]>,
    /// The coarsest inverses' (a, b) blocks, row-major per system.
    pub cinv: Vec<[f32; 2]>,
    /// Per system: (first level, levels, offset of its coarsest inverse in `cinv`).
    pub systems: Vec<[u32; 3]>,
}

/// One level's transfers placed in the index space: P's rows are the level's (from `fine`), its
/// columns the next level's (from `coarse`); R = Pᵀ the other way.
struct Transfer<'h> {
    fine: usize,
    coarse: usize,
    p: &'h Csr,
    r: &'h Csr,
}

/// The CSR of `2 total` rows: every level's prolongator rows at its own rows, its restriction's
/// at `total` + the next level's rows, columns shifted to where they live; empty rows elsewhere.
/// Rows are copied whole (each row of the index space has at most one source, its columns stay
/// sorted under the shift).
fn transfer_rows(total: usize, transfers: &[Transfer]) -> Csr {
    let mut source: Vec<Option<(&Csr, usize, usize)>> = vec![None; 2 * total];
    for t in transfers {
        for i in 0..t.p.rows {
            source[t.fine + i] = Some((t.p, i, t.coarse));
        }
        for j in 0..t.r.rows {
            source[total + t.coarse + j] = Some((t.r, j, t.fine));
        }
    }
    let nnz = transfers.iter().map(|t| t.p.nnz() + t.r.nnz()).sum();
    let mut out = Csr {
        rows: 2 * total,
        row_ptr: Vec::with_capacity(2 * total + 1),
        cols: Vec::with_capacity(nnz),
        vals: Vec::with_capacity(nnz),
    };
    out.row_ptr.push(0);
    for s in source {
        if let Some((m, i, shift)) = s {
            for (c, v) in m.row(i) {
                out.cols.push((shift + c) as u32);
                out.vals.push(v);
            }
        }
        out.row_ptr.push(out.cols.len() as u32);
    }
    out
}

impl AmgBatch {
    /// The layout of the hierarchies `hs` (one per system, `(row0, n)` of the block-diagonal
    /// `a`) whose iteration stays within `max_steps` loop steps per invocation of a `wg`-wide
    /// workgroup, counted in kernel rows of `unit` real rows; `None` when no system has one.
    /// `jacobi` is 1 / dᵢ per row of `a`.
    pub fn build(
        a: &Csr,
        systems: &[(usize, usize)],
        hs: Vec<Option<Hierarchy>>,
        (wg, max_steps, unit): (usize, usize, usize),
        jacobi: Vec<f32>,
    ) -> Option<Self> {
        let hierarchies: Vec<Option<(Hierarchy, [usize; 2])>> = hs
            .into_iter()
            .map(|h| {
                let h = h?;
                let st = [steps(&h, wg, unit), steps(&h, wg, 1)];
                (st[0] <= max_steps).then_some((h, st))
            })
            .collect();
        if hierarchies.iter().all(Option::is_none) {
            return None;
        }
        let mut out = Self {
            a: a.clone(),
            pr: Csr::default(),
            weights: jacobi,
            levels: Vec::new(),
            cinv: Vec::new(),
            total: a.rows,
            systems: Vec::new(),
        };
        // Per level of every hierarchy: (its first row, the next level's first row, P, R).
        let mut transfers = Vec::new();
        for (&(row0, n), h) in systems.iter().zip(&hierarchies) {
            let Some((h, steps)) = h else {
                out.systems.push(None);
                continue;
            };
            let placed = out.lay_out(h, row0, n, *steps, &mut transfers);
            out.systems.push(Some(placed));
        }
        out.pr = transfer_rows(out.total, &transfers);
        Some(out)
    }

    /// Appends one system's coarse levels to the index space; returns where they are.
    fn lay_out<'h>(
        &mut self,
        h: &'h Hierarchy,
        row0: usize,
        n: usize,
        [steps, steps_real]: [usize; 2],
        transfers: &mut Vec<Transfer<'h>>,
    ) -> AmgSystem {
        let lvl0 = self.levels.len() as u32;
        let mut bases = vec![row0];
        self.levels.push([row0 as u32, n as u32]);
        for (i, w) in h.levels[0].w.iter().enumerate() {
            self.weights[row0 + i] = *w as f32;
        }
        let rows = h.level_rows();
        for (l, &nl) in rows.iter().enumerate().skip(1) {
            let base = self.total;
            bases.push(base);
            self.levels.push([base as u32, nl as u32]);
            self.total += nl;
            match h.levels.get(l) {
                Some(lv) => {
                    for i in 0..nl {
                        for (c, v) in lv.a.row(i) {
                            self.a.cols.push((base + c) as u32);
                            self.a.vals.push(v);
                        }
                        self.a.row_ptr.push(self.a.cols.len() as u32);
                    }
                    self.weights.extend(lv.w.iter().map(|&w| w as f32));
                }
                None => {
                    let end = *self.a.row_ptr.last().expect("row offsets");
                    self.a.row_ptr.extend(std::iter::repeat_n(end, nl));
                    self.weights.extend(std::iter::repeat_n(0.0, nl));
                }
            }
            self.a.rows += nl;
        }
        for (l, lv) in h.levels.iter().enumerate() {
            transfers.push(Transfer {
                fine: bases[l],
                coarse: bases[l + 1],
                p: &lv.p,
                r: &lv.r,
            });
        }
        let cinv0 = self.cinv.len() as u32;
        self.cinv.extend(h.coarse_inverse.iter().map(|&v| v as f32));
        AmgSystem {
            lvl0,
            nlev: rows.len() as u32,
            cinv0,
            steps,
            steps_real,
        }
    }
}

impl AmgBatch {
    /// This layout on complex 2 × 2 blocks, or `None` when a matrix is not of that form.
    pub fn complex(&self) -> Option<ComplexLayout> {
        if !self.total.is_multiple_of(2) {
            return None;
        }
        let a = ComplexCsr::from_real(&self.a)?;
        let pr = ComplexCsr::from_real(&self.pr)?;
        let weights = self.weights.iter().step_by(2).copied().collect();
        let levels = self.levels.iter().map(|l| [l[0] / 2, l[1] / 2]).collect();
        let mut cinv = Vec::with_capacity(self.cinv.len() / 4);
        let mut systems = Vec::new();
        for s in self.systems.iter().flatten() {
            let n = self.levels[(s.lvl0 + s.nlev - 1) as usize][1] as usize;
            let real = &self.cinv[s.cinv0 as usize..s.cinv0 as usize + n * n];
            systems.push([s.lvl0, s.nlev, cinv.len() as u32]);
            for i in (0..n).step_by(2) {
                for j in (0..n).step_by(2) {
                    cinv.push([real[i * n + j], real[(i + 1) * n + j]]);
                }
            }
        }
        Some(ComplexLayout {
            a,
            pr,
            weights,
            levels,
            cinv,
            systems,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::amg::tests::grid;

    /// The transfers' rows copied in place equal the triplets of every P and R entry, shifted to
    /// their rows and columns in the index space and summed by `Csr::from_triplets`: a batch of
    /// three systems, the middle one too small for a hierarchy.
    #[test]
    fn transfer_rows_are_the_triplets_ones() {
        let (g1, g2, g3) = (grid(60), grid(5), grid(57));
        let (a, row0) = Csr::block_diagonal(&[&g1, &g2, &g3]);
        let systems: Vec<(usize, usize)> = row0
            .iter()
            .zip([g1.rows, g2.rows, g3.rows])
            .map(|(&r, n)| (r, n))
            .collect();
        let hs = hierarchies(&a, &systems, |_| true);
        assert!(hs[0].is_some() && hs[1].is_none() && hs[2].is_some());
        let jacobi = vec![1.0; a.rows];
        let batch = AmgBatch::build(&a, &systems, hs.clone(), (64, usize::MAX, 1), jacobi)
            .expect("a layout");
        let mut t = Vec::new();
        for (s, h) in batch.systems.iter().zip(&hs) {
            let (Some(s), Some(h)) = (s, h) else { continue };
            for (l, lv) in h.levels.iter().enumerate() {
                let lvl = s.lvl0 as usize + l;
                let (fine, coarse) = (batch.levels[lvl][0], batch.levels[lvl + 1][0]);
                for i in 0..lv.p.rows {
                    t.extend(
                        lv.p.row(i)
                            .map(|(c, v)| (fine + i as u32, coarse + c as u32, v)),
                    );
                }
                for j in 0..lv.r.rows {
                    let row = batch.total as u32 + coarse + j as u32;
                    t.extend(lv.r.row(j).map(|(c, v)| (row, fine + c as u32, v)));
                }
            }
        }
        assert_eq!(batch.pr, Csr::from_triplets(2 * batch.total, t));
    }
}
