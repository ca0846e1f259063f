// SPDX-License-Identifier: MIT OR Apache-2.0
//! `--refine conformal`: the pelt as the starting point of a least-squares conformal map (Lévy et al.
//! 2002) of the same piece (Piponi & Borshukov §4: "further modifications may be carried out using
//! algorithms more suited to local refinement").
//!
//! Each piece's LSCM system is assembled on its own vertices (a cut vertex once per side,
//! `maps::chart::lscm::assemble_local`), with the two boundary vertices farthest apart in the pelt
//! pinned where the pelt put them, and solved from the pelt by the batched conjugate gradient on the
//! GPU (`solve::gpu::cg_batched`, all pieces in one batch) or by its f64 twin (`solve::cg::pcg`).
//! A refined layout that folds (flipped or overlapping triangles: LSCM does not promise it will not)
//! is dropped and the pelt kept.

use super::cut::Piece;
use super::Device;
use crate::error::Result;
use crate::maps::chart::lscm;
use crate::mesh::Topology;
use crate::solve::cg::pcg;
use crate::solve::gpu::{cg_batched, SystemDesc};
use crate::solve::sparse::{CgReport, Csr, PreconditionerKind};
use glam::DVec2;
use rayon::prelude::*;

/// Relative residual the solves aim for.
pub const RTOL: f32 = 1e-6;

/// What the refinement did to one piece.
#[derive(Debug, Clone, Copy, Default, serde::Serialize)]
pub struct Refinement {
    /// Whether the refined layout was kept (false: it folded, the pelt stays).
    pub kept: bool,
    /// Conjugate-gradient iterations.
    pub iterations: u32,
    /// Final relative residual.
    pub residual: f64,
    /// Jacobi, or a multigrid V-cycle (pieces of 1,536 vertices or more: `solve::amg`).
    pub preconditioner: PreconditionerKind,
}

/// A system: matrix, right-hand side, warm start.
pub type System = (Csr, Vec<f64>, Vec<f64>);

/// A piece's LSCM system warm-started at its pelt `flat`.
fn system(topo: &Topology, piece: &Piece, flat: &[DVec2]) -> System {
    let b = &piece.boundary;
    // The boundary pair farthest apart in the pelt (a few sweeps from the first vertex).
    let far = |from: u32| {
        *b.iter()
            .max_by(|x, y| {
                (flat[**x as usize] - flat[from as usize])
                    .length_squared()
                    .total_cmp(&(flat[**y as usize] - flat[from as usize]).length_squared())
            })
            .expect("a piece has a boundary")
    };
    let p = far(b[0]);
    let q = far(p);
    let mut value = vec![None; piece.welded.len()];
    for v in [p, q] {
        value[v as usize] = Some(flat[v as usize].to_array());
    }
    let (matrix, rhs) = lscm::assemble_local(
        &piece.triangles,
        &|k| {
            lscm::triangle_edges_at(
                piece.triangles[k]
                    .map(|v| topo.positions[piece.welded[v as usize] as usize].as_dvec3()),
            )
        },
        &value,
        &|i| flat[i].to_array(),
    );
    let x0 = flat.iter().flat_map(|p| [p.x, p.y]).collect();
    (matrix, rhs, x0)
}

/// Refines every piece's pelt; returns the refined coordinates (`None` where the system could not
/// be built: fewer than two boundary vertices) and what the solver did.
pub fn refine(
    device: Device,
    topo: &Topology,
    pieces: &[Piece],
    flats: &[Vec<DVec2>],
) -> Result<Vec<(Option<Vec<DVec2>>, Refinement)>> {
    let systems: Vec<Option<System>> = pieces
        .iter()
        .zip(flats)
        .map(|(p, f)| (p.boundary.len() >= 2).then(|| system(topo, p, f)))
        .collect();
    let solved = solve_systems(device, &systems)?;
    Ok(solved
        .into_iter()
        .map(|s| match s {
            None => (None, Refinement::default()),
            Some((x, rep)) => (
                Some(x.chunks(2).map(|c| DVec2::new(c[0], c[1])).collect()),
                Refinement {
                    kept: false,
                    iterations: rep.iterations,
                    residual: rep.residual,
                    preconditioner: rep.preconditioner,
                },
            ),
        })
        .collect())
}

/// Solves each present system (matrix, right-hand side, start) to [`RTOL`]: on the GPU all in one
/// batch (`cg_batched`), on the CPU by the f64 twin (`pcg`), a system per core at a time (each
/// solve is the same sequential twin, so the results do not depend on the cores).
#[allow(
    clippy::type_complexity,
    reason = "a solution and its report per system, if present"
)]
pub fn solve_systems(
    device: Device,
    systems: &[Option<System>],
) -> Result<Vec<Option<(Vec<f64>, CgReport)>>> {
    Ok(match device {
        Device::Cpu => systems
            .par_iter()
            .map(|s| {
                s.as_ref().map(|(a, b, x0)| {
                    let mut x = x0.clone();
                    let rep = pcg(a, b, &mut x, RTOL as f64, budget(a.rows));
                    (x, rep)
                })
            })
            .collect(),
        Device::Gpu(ctx, pipes) => {
            let present: Vec<&System> = systems.iter().flatten().collect();
            let mats: Vec<&Csr> = present.iter().map(|s| &s.0).collect();
            let (a, starts) = Csr::block_diagonal(&mats);
            let b: Vec<f64> = present.iter().flat_map(|s| s.1.iter().copied()).collect();
            let x0: Vec<f64> = present.iter().flat_map(|s| s.2.iter().copied()).collect();
            let descs: Vec<SystemDesc> = present
                .iter()
                .zip(&starts)
                .map(|(s, &r0)| SystemDesc::new(r0, s.0.rows, RTOL, budget(s.0.rows)))
                .collect();
            let out = cg_batched(ctx, pipes, &a, &b, &x0, &descs)?;
            let mut it = present.iter().zip(&starts).zip(&out.reports);
            systems
                .iter()
                .map(|s| {
                    s.as_ref().map(|_| {
                        let ((sys, &r0), rep) = it.next().expect("one report per system");
                        let x = out.x[r0..r0 + sys.0.rows]
                            .iter()
                            .map(|&v| v as f64)
                            .collect();
                        (x, *rep)
                    })
                })
                .collect()
        }
    })
}

/// Iteration budget of a system of `rows` unknowns (the chart solves' rule of thumb: enough for a
/// Jacobi-preconditioned CG on a mesh Laplacian of that size).
fn budget(rows: usize) -> u32 {
    crate::maps::chart::default_budget(rows)
}
