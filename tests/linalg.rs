// SPDX-License-Identifier: MIT OR Apache-2.0
//! GPU sparse linear algebra against its f64 CPU twins (`decalbake::solve::sparse`): SpMV, batched dot
//! products, and the batched Jacobi-preconditioned CG on random SPD systems and on a real mesh's
//! Laplacian. Tolerances follow f32 rounding: a sum of m terms is off by at most about m·eps·Σ|terms|
//! (eps = 2^-24); CG is judged by its true residual, recomputed here in f64.

mod common;
use decalbake::mesh::{Mesh, Topology, DEFAULT_WELD_TOLERANCE};
use decalbake::solve::cg::pcg;
use decalbake::solve::gpu::{
    cg_batched, cg_batched_with, dots, spmv, GpuPairs, Packing, SystemDesc,
};
use decalbake::solve::sparse::{relative_residual, CgStatus, ComplexCsr, Csr};

const EPS: f64 = 5.96e-8;

/// Deterministic pseudo-random numbers in [0, 1).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// A random sparse SPD matrix: symmetric random off-diagonals in [-1, 1], diagonal = row |sum| + margin.
fn random_spd(n: usize, per_row: usize, margin: f64, rng: &mut Lcg) -> Csr {
    let mut t = Vec::new();
    let mut diag = vec![margin; n];
    for i in 0..n {
        for _ in 0..per_row / 2 {
            let j = (rng.next() * n as f64) as usize;
            if j == i {
                continue;
            }
            let v = 2.0 * rng.next() - 1.0;
            t.push((i as u32, j as u32, v));
            t.push((j as u32, i as u32, v));
            diag[i] += v.abs();
            diag[j] += v.abs();
        }
    }
    for (i, d) in diag.iter().enumerate() {
        t.push((i as u32, i as u32, *d));
    }
    Csr::from_triplets(n, t)
}

fn random_vec(n: usize, rng: &mut Lcg) -> Vec<f64> {
    (0..n).map(|_| 2.0 * rng.next() - 1.0).collect()
}

/// f32-rounded copy, so the CPU twin sees exactly the numbers the GPU sees.
fn round32(v: &[f64]) -> Vec<f64> {
    v.iter().map(|&x| x as f32 as f64).collect()
}

fn round_matrix(a: &Csr) -> Csr {
    Csr {
        vals: round32(&a.vals),
        ..a.clone()
    }
}

#[test]
fn spmv_matches_cpu_twin() {
    let e = common::engine();
    let mut rng = Lcg(7);
    // Rows of 0..40 entries, unsymmetric, including empty rows.
    let n = 3000;
    let mut t = Vec::new();
    for i in 0..n {
        let len = (rng.next() * 40.0) as usize;
        for _ in 0..len {
            let j = (rng.next() * n as f64) as u32;
            t.push((i as u32, j, 2.0 * rng.next() - 1.0));
        }
    }
    let a = round_matrix(&Csr::from_triplets(n, t));
    let x = round32(&random_vec(n, &mut rng));
    let xf: Vec<f32> = x.iter().map(|&v| v as f32).collect();
    let g = GpuPairs::upload(&e.ctx, &a).unwrap();
    let (y, _) = spmv(&e.ctx, e.pipelines(), &g, &xf, 1).unwrap();
    let want = a.mul(&x);
    for i in 0..n {
        let scale: f64 = a.row(i).map(|(c, v)| (v * x[c]).abs()).sum();
        let len = a.row(i).count().max(1) as f64;
        let tol = len * EPS * scale + 1e-30;
        assert!(
            (y[i] as f64 - want[i]).abs() <= tol,
            "row {i}: gpu {} cpu {} tol {tol}",
            y[i],
            want[i]
        );
    }
}

#[test]
fn batched_dots_match_cpu_twin() {
    let e = common::engine();
    let mut rng = Lcg(11);
    let sizes = [1usize, 7, 256, 1000, 40_000];
    let total: usize = sizes.iter().sum();
    let a = round32(&random_vec(total, &mut rng));
    let b = round32(&random_vec(total, &mut rng));
    let mut segs = Vec::new();
    let mut row = 0;
    for &n in &sizes {
        segs.push(SystemDesc::new(row, n, 0.0, 0));
        row += n;
    }
    let af: Vec<f32> = a.iter().map(|&v| v as f32).collect();
    let bf: Vec<f32> = b.iter().map(|&v| v as f32).collect();
    let got = dots(&e.ctx, e.pipelines(), &af, &bf, &segs).unwrap();
    for (s, g) in segs.iter().zip(&got) {
        let r = s.row0 as usize..(s.row0 + s.n) as usize;
        let ab: f64 = r.clone().map(|i| a[i] * b[i]).sum();
        let abs: f64 = r.clone().map(|i| (a[i] * b[i]).abs()).sum();
        let aa: f64 = r.clone().map(|i| a[i] * a[i]).sum();
        let bb: f64 = r.clone().map(|i| b[i] * b[i]).sum();
        let m = s.n as f64;
        assert!(
            (g[0] as f64 - ab).abs() <= m * EPS * abs,
            "<a,b> {} vs {ab}",
            g[0]
        );
        assert!(
            (g[1] as f64 - aa).abs() <= m * EPS * aa,
            "<a,a> {} vs {aa}",
            g[1]
        );
        assert!(
            (g[2] as f64 - bb).abs() <= m * EPS * bb,
            "<b,b> {} vs {bb}",
            g[2]
        );
    }
}

/// Systems of different sizes solved in one batch: every one converges, its true residual (f64)
/// meets the target within a factor 2 (the kernel checks it in f32), x agrees with the f64 twin, and
/// each system's iterations and solution are bitwise the same as when it is solved alone.
#[test]
fn batched_cg_converges_and_is_batch_independent() {
    let e = common::engine();
    let mut rng = Lcg(3);
    let sizes = [1usize, 10, 300, 2000, 6000];
    let blocks: Vec<Csr> = sizes
        .iter()
        .map(|&n| round_matrix(&random_spd(n, 8, 0.05, &mut rng)))
        .collect();
    let refs: Vec<&Csr> = blocks.iter().collect();
    let (a, starts) = Csr::block_diagonal(&refs);
    let b = round32(&random_vec(a.rows, &mut rng));
    let x0 = vec![0.0; a.rows];
    let rtol = 1e-5;
    let systems: Vec<SystemDesc> = sizes
        .iter()
        .zip(&starts)
        .map(|(&n, &s)| SystemDesc::new(s, n, rtol, 5000))
        .collect();
    let batch = cg_batched(&e.ctx, e.pipelines(), &a, &b, &x0, &systems).unwrap();
    println!(
        "batch: {} dispatches, {} submits",
        batch.dispatches, batch.submits
    );
    for (k, (s, rep)) in systems.iter().zip(&batch.reports).enumerate() {
        let r = s.row0 as usize..(s.row0 + s.n) as usize;
        let xg: Vec<f64> = batch.x[r.clone()].iter().map(|&v| v as f64).collect();
        let res = relative_residual(&blocks[k], &b[r.clone()], &xg);
        let mut xc = vec![0.0; s.n as usize];
        let cpu = pcg(&blocks[k], &b[r.clone()], &mut xc, 1e-12, 10_000);
        let err = xg
            .iter()
            .zip(&xc)
            .map(|(p, q)| (p - q).abs())
            .fold(0.0, f64::max);
        let xmax = xc.iter().map(|v| v.abs()).fold(0.0, f64::max);
        println!(
            "n {:5}: {:?} in {} its (cpu f64 {} its), reported residual {:.2e}, true {:.2e}, max |x - x*| {:.2e} of {:.2e}",
            s.n, rep.status, rep.iterations, cpu.iterations, rep.residual, res, err, xmax
        );
        assert_eq!(rep.status, CgStatus::Converged);
        assert!(res <= 2.0 * rtol as f64, "true residual {res}");
        assert!(rep.residual <= rtol as f64);
        // Diagonally dominant with margin 0.05: the condition number is below about 2 × 8 / 0.05,
        // so the forward error is at most cond × residual.
        assert!(
            err <= 320.0 * 2.0 * rtol as f64 * xmax.max(1e-3),
            "x error {err}"
        );

        let alone = cg_batched(
            &e.ctx,
            e.pipelines(),
            &blocks[k],
            &b[r.clone()],
            &vec![0.0; s.n as usize],
            &[SystemDesc::new(0, s.n as usize, rtol, 5000)],
        )
        .unwrap();
        assert_eq!(alone.reports[0].iterations, rep.iterations);
        assert_eq!(alone.x, batch.x[r].to_vec(), "system {k} differs alone");
    }
}

/// Many small systems in one batch are packed one per invocation (`cg_packed.wgsl`, `Packing::Packed`,
/// the engine's choice on lavapipe); each alone, or in a batch that is not packed
/// (`Packing::PerWorkgroup`, the engine's choice on a GPU), gets a workgroup (`cg_batched.wgsl`). Both sum in their own fixed order, so x differs in the last
/// bits; both must reach the tolerance, agree with each other to 1e-5 of |x| and with the f64
/// twin within the forward-error bound (cond × residual; cond < 2 × 8 / 0.05 as in the test
/// above), and take the same iterations within 10 % (f32 rounding moves the step where the
/// residual crosses).
#[test]
fn packed_systems_match_one_workgroup_each() {
    let e = common::engine();
    let mut rng = Lcg(11);
    let sizes: Vec<usize> = (0..24).map(|k| 5 + 9 * k).collect();
    let blocks: Vec<Csr> = sizes
        .iter()
        .map(|&n| round_matrix(&random_spd(n, 8, 0.05, &mut rng)))
        .collect();
    let refs: Vec<&Csr> = blocks.iter().collect();
    let (a, starts) = Csr::block_diagonal(&refs);
    let b = round32(&random_vec(a.rows, &mut rng));
    let rtol = 1e-5;
    let systems: Vec<SystemDesc> = sizes
        .iter()
        .zip(&starts)
        .map(|(&n, &s)| SystemDesc::new(s, n, rtol, 5000))
        .collect();
    let zero = vec![0.0; a.rows];
    let batch = cg_batched_with(
        &e.ctx,
        e.pipelines(),
        (&a, &b, &zero),
        &systems,
        Packing::Packed,
    )
    .unwrap();
    assert_eq!(batch.packed as usize, sizes.len(), "every system packed");
    // The engine's own choice: packed on a CPU adapter (lavapipe), a workgroup each on a GPU.
    let auto = cg_batched(&e.ctx, e.pipelines(), &a, &b, &zero, &systems).unwrap();
    let cpu = e.ctx.device_type == Some(wgpu::DeviceType::Cpu);
    assert_eq!(auto.packed as usize, if cpu { sizes.len() } else { 0 });
    // Not packed: each system in its own workgroup of the batch, which gives what it gives alone
    // bit for bit (checked below).
    let per_wg = cg_batched_with(
        &e.ctx,
        e.pipelines(),
        (&a, &b, &zero),
        &systems,
        Packing::PerWorkgroup,
    )
    .unwrap();
    assert_eq!(per_wg.packed, 0, "no system packed");
    assert!(
        !batch.complex,
        "a random SPD matrix has no complex block structure"
    );
    for (k, (s, rep)) in systems.iter().zip(&batch.reports).enumerate() {
        let r = s.row0 as usize..(s.row0 + s.n) as usize;
        let alone = cg_batched(
            &e.ctx,
            e.pipelines(),
            &blocks[k],
            &b[r.clone()],
            &vec![0.0; s.n as usize],
            &[SystemDesc::new(0, s.n as usize, rtol, 5000)],
        )
        .unwrap();
        assert_eq!(alone.packed, 0, "a lone system keeps its workgroup");
        assert_eq!(
            per_wg.x[r.clone()],
            alone.x[..],
            "system {k}: a workgroup in the batch gives what it gives alone"
        );
        assert_eq!(per_wg.reports[k].iterations, alone.reports[0].iterations);
        let xp: Vec<f64> = batch.x[r.clone()].iter().map(|&v| v as f64).collect();
        let xw: Vec<f64> = alone.x.iter().map(|&v| v as f64).collect();
        let mut xc = vec![0.0; s.n as usize];
        pcg(&blocks[k], &b[r.clone()], &mut xc, 1e-12, 10_000);
        let diff = |u: &[f64], v: &[f64]| {
            u.iter()
                .zip(v)
                .map(|(p, q)| (p - q).abs())
                .fold(0.0, f64::max)
        };
        let xmax = xc.iter().map(|v| v.abs()).fold(0.0, f64::max).max(1e-3);
        let (wi, pi) = (alone.reports[0].iterations, rep.iterations);
        println!(
            "n {:3}: packed {pi} its, workgroup {wi} its; |packed - workgroup| {:.1e}, |packed - f64| {:.1e} of {xmax:.1e}",
            s.n,
            diff(&xp, &xw),
            diff(&xp, &xc)
        );
        assert_eq!(rep.status, CgStatus::Converged);
        assert!(relative_residual(&blocks[k], &b[r.clone()], &xp) <= 2.0 * rtol as f64);
        // Same iterations, other summation order: the runs differ by accumulated rounding
        // (2e-7 of |x| measured); 1e-5 leaves room for that and still catches a wrong step.
        assert!(diff(&xp, &xw) <= 1e-5 * xmax);
        assert!(diff(&xp, &xc) <= 320.0 * 2.0 * rtol as f64 * xmax);
        assert!(
            pi.abs_diff(wi) <= 1 + wi / 10,
            "iterations {pi} packed, {wi} alone"
        );
    }
}

/// The complex block form of a matrix: found where every 2 × 2 block is [[a, -b], [b, a]], refused
/// otherwise, and equal to the real matrix it came from.
#[test]
fn complex_blocks_are_found_only_where_they_exist() {
    let mut t = Vec::new();
    for (i, j, a, b) in [
        (0u32, 0u32, 4.0, 0.0),
        (0, 1, -1.0, 0.5),
        (1, 0, -1.0, -0.5),
        (1, 1, 3.0, 0.0),
    ] {
        let (r, c) = (2 * i, 2 * j);
        t.extend([(r, c, a), (r, c + 1, -b), (r + 1, c, b), (r + 1, c + 1, a)]);
    }
    let m = Csr::from_triplets(4, t.clone());
    let c = ComplexCsr::from_real(&m).expect("complex blocks");
    assert_eq!(c.rows, 2);
    assert_eq!(
        c.vals,
        vec![[4.0, 0.0], [-1.0, 0.5], [-1.0, -0.5], [3.0, 0.0]]
    );
    assert_eq!(
        c.to_real().mul(&[1.0, 2.0, 3.0, 4.0]),
        m.mul(&[1.0, 2.0, 3.0, 4.0])
    );
    // One entry off by 1e-6 relative: not a complex block.
    let mut off = t.clone();
    off[0].2 *= 1.0 + 1e-6;
    assert!(ComplexCsr::from_real(&Csr::from_triplets(4, off)).is_none());
    // A missing mirror entry (b on one side only).
    let one_sided: Vec<_> = t
        .iter()
        .copied()
        .filter(|&(r, c, _)| (r, c) != (3, 0))
        .collect();
    assert!(ComplexCsr::from_real(&Csr::from_triplets(4, one_sided)).is_none());
    // Odd size, and a random SPD matrix.
    assert!(ComplexCsr::from_real(&Csr::from_triplets(
        3,
        vec![(0, 0, 1.0), (1, 1, 1.0), (2, 2, 1.0)]
    ))
    .is_none());
    assert!(ComplexCsr::from_real(&random_spd(40, 6, 0.1, &mut Lcg(5))).is_none());
}

/// Random block patterns (rows of 0-6 blocks at random block columns, some with b = 0 and both
/// of its entries left out, some rows empty, some block columns held by only one of the two
/// real rows, as an explicit zero) come back from their real form unchanged: the real rows of a
/// block row are walked side by side, whatever columns each holds.
#[test]
fn complex_blocks_round_trip_through_the_real_form() {
    let mut rng = Lcg(11);
    let n = 60;
    let mut t = Vec::new();
    let mut blocks = vec![Vec::new(); n];
    for (i, row) in blocks.iter_mut().enumerate() {
        for _ in 0..(rng.next() * 7.0) as usize {
            let j = (rng.next() * n as f64) as u32;
            let (a, b) = (
                rng.next() - 0.5,
                if rng.next() < 0.3 {
                    0.0
                } else {
                    rng.next() - 0.5
                },
            );
            let (r, c) = (2 * i as u32, 2 * j);
            t.extend([(r, c, a), (r + 1, c + 1, a)]);
            if b != 0.0 {
                t.extend([(r, c + 1, -b), (r + 1, c, b)]);
            }
            row.push((j, a, b));
        }
        // Now and then an explicit zero in one of the two real rows only: a block column that
        // the other row lacks (a zero block).
        if rng.next() < 0.4 {
            let k = (rng.next() * n as f64) as u32;
            let r = 2 * i as u32 + u32::from(rng.next() < 0.5);
            t.push((r, 2 * k + u32::from(rng.next() < 0.5), 0.0));
            row.push((k, 0.0, 0.0));
        }
    }
    let m = Csr::from_triplets(2 * n, t);
    let c = ComplexCsr::from_real(&m).expect("complex blocks");
    for (i, row) in blocks.iter_mut().enumerate() {
        // Repeated block columns were summed by the triplets; sum them here too.
        row.sort_by_key(|e| e.0);
        let mut want: Vec<(u32, [f64; 2])> = Vec::new();
        for &(j, a, b) in row.iter() {
            match want.last_mut() {
                Some((k, v)) if *k == j => *v = [v[0] + a, v[1] + b],
                _ => want.push((j, [a, b])),
            }
        }
        let (s, e) = (c.row_ptr[i] as usize, c.row_ptr[i + 1] as usize);
        let got: Vec<(u32, [f64; 2])> = c.cols[s..e]
            .iter()
            .copied()
            .zip(c.vals[s..e].iter().copied())
            .collect();
        assert_eq!(got.len(), want.len(), "block row {i}");
        for ((gj, gv), (wj, wv)) in got.iter().zip(&want) {
            assert_eq!(gj, wj, "block row {i}");
            for k in 0..2 {
                assert!(
                    (gv[k] - wv[k]).abs() <= 1e-15,
                    "block row {i}, column {gj}: {gv:?} against {wv:?}"
                );
            }
        }
    }
    let x: Vec<f64> = (0..2 * n).map(|i| i as f64 * 0.25 - 3.0).collect();
    let (y, z) = (m.mul(&x), c.to_real().mul(&x));
    for (a, b) in y.iter().zip(&z) {
        assert!((a - b).abs() < 1e-12);
    }
}

/// A real mesh system: Spot's (clamped-cotangent) Laplacian plus a mass shift, 2,930 unknowns.
#[test]
fn cg_solves_a_mesh_laplacian() {
    let e = common::engine();
    let mesh =
        Mesh::load(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/spot.glb"))
            .unwrap();
    let topo = Topology::build(&mesh, DEFAULT_WELD_TOLERANCE);
    let a = round_matrix(&decalbake::maps::chart::lscm::shifted_laplacian(
        &topo, 10.0,
    ));
    let mut rng = Lcg(5);
    let b = round32(&random_vec(a.rows, &mut rng));
    let rtol = 1e-5;
    let sol = cg_batched(
        &e.ctx,
        e.pipelines(),
        &a,
        &b,
        &vec![0.0; a.rows],
        &[SystemDesc::new(0, a.rows, rtol, 20_000)],
    )
    .unwrap();
    let x: Vec<f64> = sol.x.iter().map(|&v| v as f64).collect();
    let res = relative_residual(&a, &b, &x);
    let mut xc = vec![0.0; a.rows];
    let cpu = pcg(&a, &b, &mut xc, rtol as f64, 20_000);
    println!(
        "spot laplacian n={} nnz={}: gpu {:?} {} its residual {:.2e} (true {:.2e}); cpu f64 {} its; {} dispatches {} submits",
        a.rows,
        a.nnz(),
        sol.reports[0].status,
        sol.reports[0].iterations,
        sol.reports[0].residual,
        res,
        cpu.iterations,
        sol.dispatches,
        sol.submits
    );
    assert_eq!(sol.reports[0].status, CgStatus::Converged);
    assert!(res <= 2.0 * rtol as f64);
    // f32 CG may need more iterations than f64 but not wildly more.
    assert!(sol.reports[0].iterations <= 2 * cpu.iterations + 20);
}

/// Honest failure: a budget too small reports "not converged" with the residual reached; a matrix
/// with a NaN, or one that is not positive definite, reports a breakdown.
#[test]
fn cg_failures_are_reported() {
    let e = common::engine();
    let mut rng = Lcg(9);
    let a = round_matrix(&random_spd(2000, 8, 0.001, &mut rng));
    let b = round32(&random_vec(a.rows, &mut rng));
    // One system from zero to 1e-6 within `budget` iterations.
    let solve = |m: &Csr, budget: u32| {
        cg_batched(
            &e.ctx,
            e.pipelines(),
            m,
            &b,
            &vec![0.0; m.rows],
            &[SystemDesc::new(0, m.rows, 1e-6, budget)],
        )
        .unwrap()
    };
    let sol = solve(&a, 3);
    let x: Vec<f64> = sol.x.iter().map(|&v| v as f64).collect();
    let res = relative_residual(&a, &b, &x);
    assert_eq!(sol.reports[0].status, CgStatus::NotConverged);
    assert_eq!(sol.reports[0].iterations, 3);
    assert!(sol.reports[0].residual > 1e-6);
    // The reported residual is the true one of the returned x (recomputed when the budget ran out).
    assert!(
        (sol.reports[0].residual - res).abs() <= 1e-3 * res,
        "reported {} true {res}",
        sol.reports[0].residual
    );

    let mut nan = a.clone();
    nan.vals[5] = f64::NAN;
    let sol = solve(&nan, 100);
    assert_eq!(sol.reports[0].status, CgStatus::Breakdown);

    let mut neg = a.clone();
    for v in neg.vals.iter_mut() {
        *v = -*v;
    }
    let sol = solve(&neg, 100);
    assert_eq!(sol.reports[0].status, CgStatus::Breakdown);
}
