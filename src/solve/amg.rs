// SPDX-License-Identifier: MIT OR Apache-2.0
//! Smoothed-aggregation algebraic multigrid (Vaněk, Mandel & Brezina 1996) as the conjugate
//! gradient's preconditioner: the set-up (aggregates, prolongators, coarse matrices, in f64 on the
//! CPU) and the V-cycle's CPU twin. The GPU kernel `wgsl/solve/cg_amg.wgsl` runs the same cycle on
//! the same hierarchy in f32 ([`crate::solve::gpu`] uploads it).
//!
//! Why: Jacobi-preconditioned CG needs iterations in proportion to the square root of the
//! condition number, which for a mesh Laplacian or an LSCM system grows with the number of vertices
//! (1,640 iterations on a 10k-vertex chart). A V-cycle removes the smooth error the Jacobi sweeps
//! cannot, so the iterations hardly grow with the mesh (docs/, "Linear algebra").
//!
//! The cycle: on each level `NU` damped-Jacobi sweeps (weights ω / dᵢ with ω = 4 / (3 ρ(D⁻¹A))), the
//! residual restricted by `R = Pᵀ`, the next level's cycle, the correction prolonged by `P`, and
//! `NU` sweeps again; the coarsest level is solved by its dense inverse. With the same sweeps
//! before and after and `R = Pᵀ`, the cycle is a symmetric positive-definite operator, which the
//! conjugate gradient requires (`tests/amg.rs` shows a cycle without its post-sweeps failing).
//!
//! Aggregation works on nodes of `block` rows: a vertex's (u, v) pair when the matrix has the
//! complex 2 × 2 structure of LSCM systems ([`ComplexCsr`]), so both coordinates of a vertex share
//! an aggregate and the coarse matrices keep that structure; single rows otherwise.
//!
//! The set-up's cost: on a GPU a large chart's solve waits for it (a 100k-vertex chart: 451 ms
//! of 1.0 s on an H200's host, docs/performance.md, "On a real GPU"). Its sparse products, the power
//! iteration's products and the strong-connection graph run on every core (rayon, rows or nodes
//! in tasks), the transpose is a counting
//! sort and the prolongator a merge of sorted rows, not triplets sorted again; each row's sums
//! keep their order, so the hierarchy is the same bit for bit as one thread's (the tests below
//! compare the parts with the triplet forms they replaced).

use super::sparse::{ComplexCsr, Csr};
use rayon::prelude::*;

/// Systems with at least this many rows get a V-cycle; smaller ones Jacobi. Below it the cycle
/// does not pay for its set-up and its dearer iterations (`bench --linalg`, one run: a chart of
/// 2,022 rows took the twin 12.0 ms with it, 51 iterations, against 8.5 ms, 272, with Jacobi, and
/// the GPU 294 against 336 ms; 256 charts of 640 rows ran at half the twin's charts/s; at 19,150
/// rows 164 against 359 ms and 5.0 against 19.9 s).
pub const AMG_MIN_ROWS: usize = 3072;
/// Coarsening stops at this many rows or fewer; that level is solved by its dense inverse.
pub const COARSE_ROWS: usize = 128;
/// The most rows a coarsest level may keep when coarsening stalls (its dense inverse is applied
/// every cycle).
const COARSE_MAX: usize = 512;
/// The most levels, the finest and the coarsest included.
pub const MAX_LEVELS: usize = 10;
/// Jacobi sweeps before and after each coarse correction (`NU` in `wgsl/solve/cg_amg.wgsl`). One:
/// two cut the iterations by a fifth to a half but cost two more products on every level, a wash
/// on lavapipe (bob's 5k-20k-row charts: 0.71-1.6 s against 0.87-1.4 s), and one lets a system
/// twice as large stay within the loop limit of one workgroup (`solve::gpu`).
pub const NU: usize = 1;
/// Strength of connection: nodes i and j are strongly connected when the sum of |a| over their
/// block is at least θ √(sᵢᵢ sⱼⱼ). Small, because mesh matrices are well graded: nearly every
/// neighbour counts, and only the weak links of thin triangles are ignored.
const THETA: f64 = 0.08;

/// One level that is not the coarsest.
#[derive(Debug, Clone)]
pub struct Level {
    /// This level's matrix.
    pub a: Csr,
    /// The smoother's weight ω / dᵢ per row.
    pub w: Vec<f64>,
    /// From the next level to this one (rows: this level; columns: the next).
    pub p: Csr,
    /// Pᵀ: from this level to the next.
    pub r: Csr,
}

/// A smoothed-aggregation hierarchy of one SPD matrix.
#[derive(Debug, Clone)]
pub struct Hierarchy {
    /// Every level but the coarsest, finest first.
    pub levels: Vec<Level>,
    /// Rows of the coarsest level.
    pub coarse_rows: usize,
    /// The coarsest matrix's inverse, row-major (symmetric).
    pub coarse_inverse: Vec<f64>,
    /// Rows per aggregation node (2: LSCM (u, v) pairs).
    pub block: usize,
    /// Jacobi sweeps after the coarse correction ([`NU`]; the tests set 0 to show that a cycle
    /// that is not symmetric breaks the CG).
    pub post_sweeps: usize,
}

impl Hierarchy {
    /// The hierarchy of the SPD matrix `a`, or `None` when it has a diagonal entry that is not
    /// positive, no coarse level, or a coarsest level that is not positive definite or stays above
    /// `COARSE_MAX` rows (the caller then uses Jacobi). The solvers ask for one only from
    /// [`AMG_MIN_ROWS`] rows on.
    pub fn build(a: &Csr) -> Option<Self> {
        let block = if a.rows.is_multiple_of(2) && ComplexCsr::from_real(a).is_some() {
            2
        } else {
            1
        };
        let mut levels = Vec::new();
        let mut cur = a.clone();
        while cur.rows > COARSE_ROWS && levels.len() + 1 < MAX_LEVELS {
            let d = cur.diagonal();
            if d.iter().any(|&v| !(v > 0.0 && v.is_finite())) {
                return None;
            }
            let (agg, count) = aggregate(&cur, block);
            if count * block * 10 > cur.rows * 9 {
                break; // coarsening stalled
            }
            let omega = 4.0 / (3.0 * spectral_radius(&cur, &d));
            let p = prolongator(&cur, &d, omega, &agg, count, block);
            let r = transpose(&p, count * block);
            let coarse = multiply(&r, &multiply(&cur, &p, count * block), count * block);
            let w = d.iter().map(|&v| omega / v).collect();
            levels.push(Level { a: cur, w, p, r });
            cur = coarse;
        }
        if levels.is_empty() || cur.rows > COARSE_MAX {
            return None;
        }
        let coarse_inverse = dense_inverse(&cur)?;
        Some(Self {
            levels,
            coarse_rows: cur.rows,
            coarse_inverse,
            block,
            post_sweeps: NU,
        })
    }

    /// Rows of every level, finest first (the coarsest last).
    pub fn level_rows(&self) -> Vec<usize> {
        let mut v: Vec<usize> = self.levels.iter().map(|l| l.a.rows).collect();
        v.push(self.coarse_rows);
        v
    }

    /// One V-cycle on the residual `r`: the preconditioned residual z ≈ A⁻¹ r.
    pub fn apply(&self, r: &[f64]) -> Vec<f64> {
        self.cycle(0, r)
    }

    fn cycle(&self, l: usize, b: &[f64]) -> Vec<f64> {
        let Some(lv) = self.levels.get(l) else {
            let n = self.coarse_rows;
            return (0..n)
                .map(|i| {
                    let row = &self.coarse_inverse[i * n..(i + 1) * n];
                    row.iter().zip(b).map(|(m, v)| m * v).sum()
                })
                .collect();
        };
        // The first sweep from x = 0 is x = W b.
        let mut x: Vec<f64> = b.iter().zip(&lv.w).map(|(v, w)| v * w).collect();
        for _ in 0..NU.saturating_sub(1) {
            sweep(lv, b, &mut x);
        }
        let ax = lv.a.mul(&x);
        let t: Vec<f64> = b.iter().zip(&ax).map(|(v, a)| v - a).collect();
        let xc = self.cycle(l + 1, &lv.r.mul(&t));
        for (xi, c) in x.iter_mut().zip(lv.p.mul(&xc)) {
            *xi += c;
        }
        for _ in 0..self.post_sweeps {
            sweep(lv, b, &mut x);
        }
        x
    }
}

/// One damped-Jacobi sweep: x += W (b - A x).
fn sweep(lv: &Level, b: &[f64], x: &mut [f64]) {
    let ax = lv.a.mul(x);
    for i in 0..x.len() {
        x[i] += lv.w[i] * (b[i] - ax[i]);
    }
}

/// The strongly connected neighbour nodes of each node (nodes of `block` rows). Nodes run in
/// tasks of [`ROWS_PER_TASK`] on every core; each node's sums keep their order.
fn strong_graph(a: &Csr, block: usize) -> Vec<Vec<u32>> {
    let nodes = a.rows / block;
    let tasks = nodes.div_ceil(ROWS_PER_TASK);
    // Per node: its block sums with its neighbour nodes, and with itself.
    let parts: Vec<Vec<NodeSums>> = (0..tasks)
        .into_par_iter()
        .map_init(
            || (vec![0.0f64; nodes], Vec::new()),
            |(acc, touched), t| {
                let range = t * ROWS_PER_TASK..((t + 1) * ROWS_PER_TASK).min(nodes);
                range
                    .map(|i| node_sums(a, block, i, acc, touched))
                    .collect()
            },
        )
        .collect();
    let (sums, diag): (Vec<Vec<(u32, f64)>>, Vec<f64>) = parts.into_iter().flatten().unzip();
    sums.par_iter()
        .enumerate()
        .map(|(i, row)| {
            row.iter()
                .filter(|&&(j, s)| s >= THETA * (diag[i] * diag[j as usize]).sqrt())
                .map(|&(j, _)| j)
                .collect()
        })
        .collect()
}

/// A node's block sums with its neighbour nodes (node, sum), and with itself.
type NodeSums = (Vec<(u32, f64)>, f64);

/// Node `i`'s sums of |a| over its block with each node its rows reach (each entry at least
/// the smallest positive f64), its own apart; `acc` (zero on entry and on return, one slot a
/// node) and `touched` (empty) are scratch.
fn node_sums(
    a: &Csr,
    block: usize,
    i: usize,
    acc: &mut [f64],
    touched: &mut Vec<usize>,
) -> NodeSums {
    for r in i * block..(i + 1) * block {
        for (c, v) in a.row(r) {
            let j = c / block;
            if acc[j] == 0.0 {
                touched.push(j);
            }
            acc[j] += v.abs().max(f64::MIN_POSITIVE);
        }
    }
    touched.sort_unstable();
    let mut row = Vec::with_capacity(touched.len());
    let mut diag = 0.0;
    for &j in touched.iter() {
        if j == i {
            diag = acc[j];
        } else {
            row.push((j as u32, acc[j]));
        }
        acc[j] = 0.0;
    }
    touched.clear();
    (row, diag)
}

/// Greedy aggregation (Vaněk et al.'s three passes): a node whose strong neighbours are all free
/// starts an aggregate with them; a node left over joins the aggregate of a neighbour from the
/// first pass; what is still left forms aggregates with its free neighbours. Returns each node's
/// aggregate and the number of aggregates. Deterministic (nodes in index order).
fn aggregate(a: &Csr, block: usize) -> (Vec<u32>, usize) {
    const FREE: u32 = u32::MAX;
    let g = strong_graph(a, block);
    let mut agg = vec![FREE; g.len()];
    let mut count = 0u32;
    for i in 0..g.len() {
        if agg[i] == FREE && g[i].iter().all(|&j| agg[j as usize] == FREE) {
            agg[i] = count;
            for &j in &g[i] {
                agg[j as usize] = count;
            }
            count += 1;
        }
    }
    let first = agg.clone();
    for i in 0..g.len() {
        if agg[i] == FREE {
            if let Some(&j) = g[i].iter().find(|&&j| first[j as usize] != FREE) {
                agg[i] = first[j as usize];
            }
        }
    }
    for i in 0..g.len() {
        if agg[i] == FREE {
            agg[i] = count;
            for &j in &g[i] {
                if agg[j as usize] == FREE {
                    agg[j as usize] = count;
                }
            }
            count += 1;
        }
    }
    (agg, count as usize)
}

/// The smoothed prolongator P = (I − ω D⁻¹ A) P₀, where P₀ is the tentative one: per node, its
/// aggregate's column for each of its rows, scaled by 1 / √(aggregate size) (orthonormal columns).
fn prolongator(a: &Csr, d: &[f64], omega: f64, agg: &[u32], count: usize, block: usize) -> Csr {
    let mut size = vec![0usize; count];
    for &k in agg {
        size[k as usize] += 1;
    }
    // One entry a row: (its aggregate's column for the row, 1 / √size).
    let entry = |r: usize| {
        let k = agg[r / block] as usize;
        (
            (k * block + r % block) as u32,
            1.0 / (size[k] as f64).sqrt(),
        )
    };
    let tentative = Csr {
        rows: a.rows,
        row_ptr: (0..=a.rows as u32).collect(),
        cols: (0..a.rows).map(|r| entry(r).0).collect(),
        vals: (0..a.rows).map(|r| entry(r).1).collect(),
    };
    let ap = multiply(a, &tentative, count * block);
    // Row r: the tentative entry merged into −(ω / dᵣ) (A P₀) row r by column, the tentative value
    // first where both have the column (the sum `Csr::from_triplets` would form).
    let mut out = Csr {
        rows: a.rows,
        row_ptr: Vec::with_capacity(a.rows + 1),
        cols: Vec::with_capacity(ap.nnz() + a.rows),
        vals: Vec::with_capacity(ap.nnz() + a.rows),
    };
    out.row_ptr.push(0);
    for (r, &dr) in d.iter().enumerate() {
        let s = omega / dr;
        let (tc, tv) = entry(r);
        let mut pending = Some((tc, tv));
        for (c, v) in ap.row(r) {
            let c = c as u32;
            match pending {
                Some((pc, pv)) if pc == c => {
                    out.cols.push(c);
                    out.vals.push(pv + -s * v);
                    pending = None;
                    continue;
                }
                Some((pc, pv)) if pc < c => {
                    out.cols.push(pc);
                    out.vals.push(pv);
                    pending = None;
                }
                _ => {}
            }
            out.cols.push(c);
            out.vals.push(-s * v);
        }
        if let Some((pc, pv)) = pending {
            out.cols.push(pc);
            out.vals.push(pv);
        }
        out.row_ptr.push(out.cols.len() as u32);
    }
    out
}

/// Rows one task of the set-up's parallel products takes at once: enough that a task's own
/// accumulator (one entry a column of the product) is worth its allocation.
const ROWS_PER_TASK: usize = 2048;

/// `a b`, where `b` has `cols` columns (a dense accumulator per row; columns sorted). Rows are
/// computed in tasks of `ROWS_PER_TASK` on every core (rayon); each row's sums run in the same
/// order whatever the split, so the product is the same bit for bit as one thread's.
pub fn multiply(a: &Csr, b: &Csr, cols: usize) -> Csr {
    multiply_in_tasks(a, b, cols, ROWS_PER_TASK)
}

/// [`multiply`] with `chunk` rows a task (the tests split small matrices finely).
fn multiply_in_tasks(a: &Csr, b: &Csr, cols: usize, chunk: usize) -> Csr {
    let chunk = chunk.max(1);
    let tasks = a.rows.div_ceil(chunk);
    let parts: Vec<(Vec<u32>, Vec<u32>, Vec<f64>)> = (0..tasks)
        .into_par_iter()
        .map_init(
            || (vec![0.0f64; cols], vec![usize::MAX; cols], Vec::new()),
            |(acc, mark, touched), t| {
                let rows = t * chunk..((t + 1) * chunk).min(a.rows);
                let mut lens = Vec::with_capacity(rows.len());
                let (mut oc, mut ov) = (Vec::new(), Vec::new());
                for i in rows {
                    for (k, av) in a.row(i) {
                        for (j, bv) in b.row(k) {
                            if mark[j] != i {
                                mark[j] = i;
                                acc[j] = 0.0;
                                touched.push(j);
                            }
                            acc[j] += av * bv;
                        }
                    }
                    touched.sort_unstable();
                    lens.push(touched.len() as u32);
                    for &j in touched.iter() {
                        oc.push(j as u32);
                        ov.push(acc[j]);
                    }
                    touched.clear();
                }
                (lens, oc, ov)
            },
        )
        .collect();
    let nnz = parts.iter().map(|p| p.1.len()).sum();
    let mut out = Csr {
        rows: a.rows,
        row_ptr: Vec::with_capacity(a.rows + 1),
        cols: Vec::with_capacity(nnz),
        vals: Vec::with_capacity(nnz),
    };
    out.row_ptr.push(0);
    for (lens, oc, ov) in parts {
        for len in lens {
            let last = *out.row_ptr.last().expect("row 0's start");
            out.row_ptr.push(last + len);
        }
        out.cols.extend(oc);
        out.vals.extend(ov);
    }
    out
}

/// The transpose of `a`, which has `cols` columns (a counting sort of the entries by column: each
/// transposed row comes out sorted, as [`Csr::from_triplets`] would sort it).
pub fn transpose(a: &Csr, cols: usize) -> Csr {
    let mut row_ptr = vec![0u32; cols + 1];
    for &c in &a.cols {
        row_ptr[c as usize + 1] += 1;
    }
    for i in 0..cols {
        row_ptr[i + 1] += row_ptr[i];
    }
    let mut fill: Vec<usize> = row_ptr[..cols].iter().map(|&v| v as usize).collect();
    let mut out_cols = vec![0u32; a.nnz()];
    let mut out_vals = vec![0.0f64; a.nnz()];
    for r in 0..a.rows {
        for (c, v) in a.row(r) {
            out_cols[fill[c]] = r as u32;
            out_vals[fill[c]] = v;
            fill[c] += 1;
        }
    }
    Csr {
        rows: cols,
        row_ptr,
        cols: out_cols,
        vals: out_vals,
    }
}

/// An upper estimate of ρ(D⁻¹ A): 20 power iterations on D^-½ A D^-½ (whose spectrum it shares),
/// times 1.1 for the iterations' shortfall, capped by Gershgorin's bound max Σⱼ |aᵢⱼ| / dᵢ.
fn spectral_radius(a: &Csr, d: &[f64]) -> f64 {
    let s: Vec<f64> = d.iter().map(|v| 1.0 / v.sqrt()).collect();
    let mut x: Vec<f64> = (0..a.rows).map(|i| 1.0 + (i % 7) as f64 / 7.0).collect();
    let mut est = 1.0;
    for _ in 0..20 {
        let sx: Vec<f64> = x.iter().zip(&s).map(|(v, s)| v * s).collect();
        let y: Vec<f64> = a.mul_par(&sx).iter().zip(&s).map(|(v, s)| v * s).collect();
        let (ny, nx) = (norm(&y), norm(&x));
        if ny == 0.0 || nx == 0.0 {
            break;
        }
        est = ny / nx;
        x = y.iter().map(|v| v / ny).collect();
    }
    let gershgorin = (0..a.rows)
        .map(|i| a.row(i).map(|(_, v)| v.abs()).sum::<f64>() / d[i])
        .fold(0.0, f64::max);
    (1.1 * est).min(gershgorin)
}

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// The Cholesky factor L of the SPD matrix `a` (dense row-major storage, lower triangle) and each
/// row's first stored column: L has no entry left of it (the envelope, or profile, method), so the
/// work is n × bandwidth², not n³. `None` when `a` is not positive definite.
fn cholesky(a: &Csr) -> Option<(Vec<f64>, Vec<usize>)> {
    let n = a.rows;
    let mut m = vec![0.0f64; n * n];
    let mut first: Vec<usize> = (0..n).collect();
    for i in 0..n {
        for (j, v) in a.row(i).filter(|&(j, _)| j <= i) {
            m[i * n + j] = v;
            first[i] = first[i].min(j);
        }
    }
    for i in 0..n {
        for j in first[i]..=i {
            let k0 = first[i].max(first[j]);
            let s: f64 = (k0..j).map(|k| m[i * n + k] * m[j * n + k]).sum();
            let v = m[i * n + j] - s;
            if j < i {
                m[i * n + j] = v / m[j * n + j];
            } else if v.is_nan() || v <= 0.0 {
                return None;
            } else {
                m[i * n + i] = v.sqrt();
            }
        }
    }
    Some((m, first))
}

/// Solves L Lᵀ x = b for the factor of [`cholesky`].
fn cholesky_solve((l, first): &(Vec<f64>, Vec<usize>), b: &[f64]) -> Vec<f64> {
    let n = b.len();
    let mut y = vec![0.0f64; n];
    for i in 0..n {
        let s: f64 = (first[i]..i).map(|j| l[i * n + j] * y[j]).sum();
        y[i] = (b[i] - s) / l[i * n + i];
    }
    // Backward: column i of L below the diagonal is row j's entry i for the rows that reach it.
    for i in (0..n).rev() {
        let s: f64 = (i + 1..n)
            .filter(|&j| first[j] <= i)
            .map(|j| l[j * n + i] * y[j])
            .sum();
        y[i] = (y[i] - s) / l[i * n + i];
    }
    y
}

/// The solution of the SPD system `a x = b` by a Cholesky factorisation in f64 (dense storage,
/// envelope work): the direct solve the tests compare the conjugate gradients with (mesh systems
/// of a few thousand rows whose vertex order keeps the bandwidth small).
pub fn direct_solve(a: &Csr, b: &[f64]) -> Option<Vec<f64>> {
    Some(cholesky_solve(&cholesky(a)?, b))
}

/// The inverse of the SPD matrix `a` (dense, row-major, symmetrised); `None` when `a` is not
/// positive definite.
fn dense_inverse(a: &Csr) -> Option<Vec<f64>> {
    let n = a.rows;
    let l = cholesky(a)?;
    let mut inv = vec![0.0f64; n * n];
    for k in 0..n {
        let e: Vec<f64> = (0..n).map(|i| f64::from(i == k)).collect();
        for (i, v) in cholesky_solve(&l, &e).into_iter().enumerate() {
            inv[i * n + k] = v;
        }
    }
    for i in 0..n {
        for j in 0..i {
            let v = 0.5 * (inv[i * n + j] + inv[j * n + i]);
            inv[i * n + j] = v;
            inv[j * n + i] = v;
        }
    }
    Some(inv)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// The 5-point Laplacian of a k × k grid plus a small shift (SPD); also the layout's tests'
    /// (`solve::gpu_amg`).
    pub(crate) fn grid(k: usize) -> Csr {
        let mut t = Vec::new();
        let id = |x: usize, y: usize| (y * k + x) as u32;
        for y in 0..k {
            for x in 0..k {
                t.push((id(x, y), id(x, y), 4.0 + 1e-3));
                for (dx, dy) in [(1i32, 0i32), (-1, 0), (0, 1), (0, -1)] {
                    let (nx, ny) = (x as i32 + dx, y as i32 + dy);
                    if nx >= 0 && ny >= 0 && (nx as usize) < k && (ny as usize) < k {
                        t.push((id(x, y), id(nx as usize, ny as usize), -1.0));
                    }
                }
            }
        }
        Csr::from_triplets(k * k, t)
    }

    #[test]
    fn galerkin_coarse_matrix_is_pt_a_p() {
        let a = grid(40);
        let h = Hierarchy::build(&a).expect("a hierarchy");
        let (p, c) = (&h.levels[0].p, &h.levels[1].a);
        // Check one coarse entry against Pᵀ A P computed column by column.
        let e0: Vec<f64> = (0..c.rows).map(|i| f64::from(i == 3)).collect();
        let pe = p.mul(&e0);
        let ape = a.mul(&pe);
        let pt_ape = h.levels[0].r.mul(&ape);
        let direct = c.mul(&e0);
        for i in 0..c.rows {
            assert!((pt_ape[i] - direct[i]).abs() < 1e-12, "row {i}");
        }
        assert!(h.level_rows().len() >= 3, "{:?}", h.level_rows());
    }

    /// The products run in tasks of rows; however the rows are split, the product is the same,
    /// and it is A B (checked column by column against the matrix-vector product).
    #[test]
    fn products_in_tasks_are_one_threads() {
        let a = grid(23);
        let h = Hierarchy::build(&a).expect("a hierarchy");
        let p = &h.levels[0].p;
        let cols = h.level_rows()[1];
        let whole = multiply_in_tasks(&a, p, cols, a.rows);
        for chunk in [1, 7, 64, 500] {
            assert_eq!(
                multiply_in_tasks(&a, p, cols, chunk),
                whole,
                "{chunk} rows a task"
            );
        }
        for k in [0, 5, cols - 1] {
            let e: Vec<f64> = (0..cols).map(|i| f64::from(i == k)).collect();
            let (direct, two) = (whole.mul(&e), a.mul(&p.mul(&e)));
            for (x, y) in direct.iter().zip(&two) {
                assert!((x - y).abs() < 1e-12, "column {k}: {x} against {y}");
            }
        }
    }

    /// The transpose by counting equals the one `Csr::from_triplets` forms, and transposing twice
    /// gives the matrix back.
    #[test]
    fn transpose_is_the_triplets_one() {
        let h = Hierarchy::build(&grid(23)).expect("a hierarchy");
        let p = &h.levels[0].p;
        let cols = h.level_rows()[1];
        let t = (0..p.rows)
            .flat_map(|r| p.row(r).map(move |(c, v)| (c as u32, r as u32, v)))
            .collect();
        let r = transpose(p, cols);
        assert_eq!(r, Csr::from_triplets(cols, t));
        assert_eq!(transpose(&r, p.rows), *p);
    }

    /// The prolongator's merge of P₀ into −ω D⁻¹ A P₀ forms what the triplets of both would sum
    /// to, entry for entry (the tentative value first where both have a column): on the grid's
    /// own aggregates, single rows and (u, v) pairs, and on a grid without its stored diagonal
    /// and with aggregates dealt out at random, where a row's tentative column may come before,
    /// between or after those of A P₀, or be alone.
    #[test]
    fn prolongator_is_the_triplets_sum() {
        let check = |a: &Csr, d: &[f64], agg: &[u32], count: usize, block: usize| {
            let omega = 0.7;
            let p = prolongator(a, d, omega, agg, count, block);
            let mut size = vec![0usize; count];
            for &k in agg {
                size[k as usize] += 1;
            }
            let tentative = Csr::from_triplets(
                a.rows,
                (0..a.rows)
                    .map(|r| {
                        let k = agg[r / block] as usize;
                        let col = (k * block + r % block) as u32;
                        (r as u32, col, 1.0 / (size[k] as f64).sqrt())
                    })
                    .collect(),
            );
            let ap = multiply(a, &tentative, count * block);
            let mut t = Vec::new();
            for (r, &dr) in d.iter().enumerate() {
                t.extend(tentative.row(r).map(|(c, v)| (r as u32, c as u32, v)));
                t.extend(
                    ap.row(r)
                        .map(|(c, v)| (r as u32, c as u32, -(omega / dr) * v)),
                );
            }
            assert_eq!(p, Csr::from_triplets(a.rows, t), "block {block}");
        };
        let a = grid(23);
        let (agg, count) = aggregate(&a, 1);
        check(&a, &a.diagonal(), &agg, count, 1);
        // Each entry v as the 2 × 2 block v I: a vertex's (u, v) rows.
        let pairs = Csr::from_triplets(
            2 * a.rows,
            (0..a.rows)
                .flat_map(|r| a.row(r).map(move |(c, v)| (r, c, v)))
                .flat_map(|(r, c, v)| {
                    let (r, c) = (2 * r as u32, 2 * c as u32);
                    [(r, c, v), (r + 1, c + 1, v)]
                })
                .collect(),
        );
        let (agg, count) = aggregate(&pairs, 2);
        check(&pairs, &pairs.diagonal(), &agg, count, 2);
        let g = grid(12);
        let off = Csr::from_triplets(
            g.rows,
            (0..g.rows)
                .flat_map(|r| g.row(r).map(move |(c, v)| (r as u32, c as u32, v)))
                .filter(|&(r, c, _)| r != c)
                .collect(),
        );
        let count = 17;
        let agg: Vec<u32> = (0..off.rows)
            .map(|r| ((r * 7 + r / 5) % count) as u32)
            .collect();
        let mut seen = [false; 3];
        for r in 0..off.rows {
            let cols: Vec<usize> = off.row(r).map(|(c, _)| agg[c] as usize).collect();
            let own = agg[r] as usize;
            let (lo, hi) = (cols.iter().min(), cols.iter().max());
            seen[0] |= lo.is_some_and(|&m| own < m);
            seen[1] |= lo.is_some_and(|&m| own > m) && hi.is_some_and(|&m| own < m);
            seen[2] |= hi.is_some_and(|&m| own > m);
        }
        assert_eq!(
            seen, [true; 3],
            "the random aggregates cover every place of the merge"
        );
        check(&off, &vec![4.0; off.rows], &agg, count, 1);
    }

    #[test]
    fn dense_inverse_inverts() {
        let a = grid(6);
        let inv = dense_inverse(&a).expect("SPD");
        let n = a.rows;
        for k in 0..n {
            let col: Vec<f64> = (0..n).map(|i| inv[i * n + k]).collect();
            let e = a.mul(&col);
            for (i, v) in e.iter().enumerate() {
                assert!((v - f64::from(i == k)).abs() < 1e-10);
            }
        }
    }
}
