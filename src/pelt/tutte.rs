// SPDX-License-Identifier: MIT OR Apache-2.0
//! The last rung of the pelting ladder, solved directly: a net whose springs have no rest length.
//!
//! With rest length 0 every spring of eq. 1 (Piponi & Borshukov §3) pulls with k (xⱼ − xᵢ) and
//! every frame spring with a (pᵢ − xᵢ), so the net's steady state is linear: for each vertex,
//! (Σⱼ kᵢⱼ + aᵢ) xᵢ − Σⱼ kᵢⱼ xⱼ = aᵢ pᵢ in x and y, and z = 0 (the plane pull is the only force on
//! z). It is the Tutte embedding of the piece with weights k = 2 / L on the convex frame, which
//! does not fold (Tutte 1963, Floater 2003). The damped dynamics of `relax` reaches the same state
//! step by step; this solves it by the preconditioned conjugate gradient (the multigrid V-cycle
//! above 3,072 unknowns) on the GPU or by its f64 twin, with x and y interleaved as the LSCM
//! systems are, so the GPU solves it on complex blocks ((k + 0i) entries).
//!
//! Why: on bob subdivided twice (86,628 vertices in its first piece) the dynamics took 1,408 steps
//! and 2.7 s of the CPU twin to settle this net (a one-off timing at commit 97235a5; its report's
//! `relax.steps` gives the steps); the solves of all three split levels now take about 0.5 s
//! (`stages_ms.relax` of `decalbake bench --unwrap --mesh assets/bob.glb --subdivide 2`), and it
//! is the refinement's starting point on every piece (`pelt::one_level`).

use super::refine::{solve_systems, System};
use super::relax::{energy, Net, Relaxed};
use super::Device;
use crate::error::Result;
use crate::solve::sparse::{CgStatus, Csr};

/// The linear system of `net`'s steady state with its rest lengths ignored (taken as 0), x and y
/// interleaved (unknown 2i + c is coordinate c of vertex i), started from the origin.
pub fn system(net: &Net) -> System {
    let n = net.len();
    let mut t = Vec::with_capacity(2 * (net.other.len() + n));
    let mut b = vec![0.0; 2 * n];
    for i in 0..n {
        let a = net.anchor[i];
        let mut diag = a[3] as f64;
        for s in net.offsets[i] as usize..net.offsets[i + 1] as usize {
            let k = net.spring[s][1] as f64;
            diag += k;
            let j = net.other[s];
            for c in 0..2 {
                t.push((2 * i as u32 + c, 2 * j + c, -k));
            }
        }
        for c in 0..2 {
            t.push((2 * i as u32 + c, 2 * i as u32 + c, diag));
            b[2 * i + c as usize] = a[3] as f64 * a[c as usize] as f64;
        }
    }
    (Csr::from_triplets(2 * n, t), b, vec![0.0; 2 * n])
}

/// Each net's steady state at rest length 0 (the nets' own rest lengths are ignored), solved on
/// `device`; the result reads like the dynamics' (positions with z = 0, energy at the start and the
/// end with the rest lengths taken as 0, `rest_scale` 0), with `steps` 0 and `iterations` the
/// conjugate gradient's, `steady` whether it converged.
pub fn settle(device: Device, nets: &[Net]) -> Result<Vec<Relaxed>> {
    let systems: Vec<Option<System>> = nets.iter().map(|n| Some(system(n))).collect();
    let solved = solve_systems(device, &systems)?;
    Ok(nets
        .iter()
        .zip(solved)
        .map(|(net, s)| {
            let (x, rep) = s.expect("every system is present");
            // The energy without rest lengths: the net itself when it has none (the ladder's
            // last rung passes it so), else a copy without them.
            let copy;
            let zero = if net.spring.iter().all(|s| s[0] == 0.0) {
                net
            } else {
                copy = net.with_rest_scale(0.0);
                &copy
            };
            let start: Vec<[f64; 3]> = net
                .start
                .iter()
                .map(|p| [p[0], p[1], p[2]].map(f64::from))
                .collect();
            let x: Vec<[f64; 3]> = x.chunks(2).map(|c| [c[0], c[1], 0.0]).collect();
            Relaxed {
                energy: [energy(zero, &start[..]), energy(zero, &x)],
                x,
                steps: 0,
                iterations: rep.iterations,
                steady: rep.status == CgStatus::Converged,
                rest_scale: 0.0,
            }
        })
        .collect())
}
