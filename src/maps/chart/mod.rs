// SPDX-License-Identifier: MIT OR Apache-2.0
//! Local conformal charts for decals: `"method": "lscm"` (Maillot, "Continuous Local Parameterization
//! of Polygons", sections 4, 6 and 9) and `"method": "hybrid"` (Schmidt, Grimm & Wyvill 2006,
//! section 5.1).
//!
//! LSCM chart, per decal:
//! 1. **Selection** (Maillot §4, §9): breadth-first over triangle adjacency from the placed triangle,
//!    keeping the connected triangles whose projection along the placed normal meets the stamp's disc
//!    (the decal rectangle's circumscribed circle); cost proportional to the triangles kept.
//! 2. **Solve**: the LSCM system ([`crate::maps::chart::lscm`]) with two pins (the chart's extreme vertices along
//!    the decal's x axis, held where the warm start puts them), by the batched GPU CG, all charts of
//!    a bake in one batch. Warm start: the planar projection for the first solve, the previous
//!    solution afterwards.
//! 3. **Normalisation**: the similarity that puts the placed point on the image centre, turns the
//!    frame's axes onto the image axes and makes the chart's scale at the placed point 1
//!    ([`crate::maps::chart::lscm::normalising_similarity`], [`FIT_RADIUS`]). Pins therefore only
//!    fix the null space; their positions do not matter (LSCM with two pins is unique up to a
//!    similarity).
//! 4. **Disc regions** ([`region`]): a selection that is not a topological disc is shrunk to one,
//!    after the first selection and after every refinement round.
//! 5. **Refinement** (Maillot §6): the first adjustment drops triangles whose image lies wholly
//!    outside the decal rectangle (keeping the placed triangle's connected part); every adjustment
//!    adds the neighbour across each border edge whose image crosses the rectangle's interior (when
//!    that edge is not a mesh boundary). Re-solve until the set no longer changes, at most
//!    [`MAX_ROUNDS`] times; a set seen before stops the loop (no cycling). Intermediate solves use the
//!    coarse tolerance [`COARSE_RTOL`], the final one [`FINAL_RTOL`] (Maillot §9).
//!
//! Hybrid decal: the exponential map (already computed on the GPU) is the start; triangles whose
//! angle distortion s1 / s2 exceeds the layer's threshold mark their vertices free; every other
//! vertex of the triangles touching a free vertex is held at its exponential-map position, and the
//! conformal energy of those triangles is minimised over the free vertices. The map keeps the
//! exponential map's frame and geodesic radius where it was good and becomes conformal where it was
//! not.
//!
//! After the solves, every chart is checked where the decal lands ([`ChartReport::folded`]: flipped,
//! collapsed or torn triangles among those the map covers under the decal) and re-solved on smaller
//! regions ([`FALLBACK_REACH`]; a hybrid as a free LSCM chart) or refused.
//!
//! The CPU here does set logic and assembly (proportional to the chart); the solves run on the GPU
//! ([`Solver::Gpu`]) or, for the CPU twin of a bake, in f64 on the CPU ([`Solver::Cpu`]).

use crate::error::Result;
use crate::maps::Frame;
use crate::mesh::{Topology, NO_NEIGHBOR};
use crate::solve::sparse::{CgReport, CgStatus, Csr, PreconditionerKind};
use lscm::System;
use rayon::prelude::*;
use region::{RegionFix, RegionReport};
pub mod cone;
pub mod lscm;
pub mod region;
use glam::{DVec2, DVec3};
use rustc_hash::{FxHashMap as HashMap, FxHashSet as HashSet};

/// Relative residual of the solves while the triangle set is still changing.
pub const COARSE_RTOL: f32 = 1e-3;
/// Relative residual (normwise backward error, see [`crate::solve::sparse::residual_scale`]) of the final
/// solve: about 4 f32 ulps, twice the rounding floor of a row of about 14 terms. Measured on Spot,
/// 1e-5 left the chart's conformal energy 3 % above the optimum; 1e-6 within 3e-4 for one chart but
/// 1.3e-3 for another (`tests/lscm.rs`, a chart of 392 unknowns, stopped one iteration early); 5e-7
/// within 4e-4 for both, for one more iteration.
pub const FINAL_RTOL: f32 = 5e-7;
/// Rings of vertices around the distorted triangles that a hybrid decal frees as well.
pub const HYBRID_RINGS: u32 = 2;
/// Most refinement rounds per chart.
pub const MAX_ROUNDS: u32 = 8;

/// Which chart to build.
#[derive(Debug, Clone, Copy)]
pub enum ChartKind<'a> {
    /// A free-boundary LSCM chart.
    Lscm,
    /// Exponential map (per welded vertex `(u, v, _, valid)`) with its distorted part re-solved.
    Hybrid {
        /// The exponential map.
        expmap: &'a [[f32; 4]],
        /// s1 / s2 above which a triangle is re-solved.
        threshold: f32,
    },
}

/// One decal's chart request.
#[derive(Debug, Clone, Copy)]
pub struct ChartRequest<'a> {
    /// The decal frame at the placed point.
    pub frame: Frame,
    /// Placed triangle (welded).
    pub triangle: u32,
    /// Kind.
    pub kind: ChartKind<'a>,
    /// Final-solve CG budget (`None` = 50 sqrt(unknowns) + 500).
    pub max_iter: Option<u32>,
    /// LSCM: an exponential map at the same placement (per welded vertex `(u, v, _, valid)`), the
    /// warm start where it reaches; elsewhere the planar projection is used.
    pub warm: Option<&'a [[f32; 4]]>,
    /// Whether the chart may be opened at a cone-like tip ([`cone`]); false for charts whose
    /// coordinates are used vertex by vertex (a continuous stroke's corner charts, which stamps
    /// blend; the stamps of blur, smear and clone strokes, which inverse rendering draws).
    pub cone: bool,
}

impl<'a> ChartRequest<'a> {
    /// The request of an `lscm` or `hybrid` layer (see [`crate::maps::MapMethod::chart`]) placed at `frame` / `triangle`, starting from the
    /// layer's exponential map `expmap` (hybrid: re-solved in part; LSCM: the warm start).
    pub fn for_layer(
        frame: Frame,
        triangle: u32,
        layer: &crate::io::job::Layer,
        expmap: &'a [[f32; 4]],
    ) -> Self {
        crate::maps::method(layer.method)
            .chart(layer, frame, triangle, expmap)
            .expect("for_layer takes an lscm or hybrid layer")
    }
}

/// What a chart reports (bake report, per layer).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ChartReport {
    /// Triangles in the final chart (hybrid: in the re-solved region).
    pub triangles: u32,
    /// Vertices in the final chart (hybrid: vertices moved).
    pub vertices: u32,
    /// Hybrid: vertices held at their exponential-map position (LSCM: the 2 pins).
    pub fixed_vertices: u32,
    /// Solves run (refinement rounds plus the final solve).
    pub rounds: u32,
    /// CG iterations of the final solve.
    pub cg_iterations: u32,
    /// CG iterations over all solves.
    pub cg_iterations_total: u32,
    /// Final relative residual.
    pub residual: f64,
    /// Final status.
    pub status: CgStatus,
    /// The final solve's preconditioner: Jacobi, or a multigrid V-cycle (charts of 1,536 vertices
    /// or more, `solve::amg`).
    pub preconditioner: PreconditionerKind,
    /// Whether the triangle set stopped changing within [`MAX_ROUNDS`] (always true for hybrid).
    pub settled: bool,
    /// The chart's scale at the placed point after normalisation: the median of |z − z_p| / |x − p|
    /// over its vertices within [`CHECK_RADIUS`] × the decal's larger side (1 = the size asked for).
    pub scale_at_point: f64,
    /// The topology of the selected region and what was done when it was not a disc (hybrid: the
    /// exponential map's region).
    pub region: RegionReport,
    /// Triangles whose image meets the decal's rectangle (hybrid: of the whole map).
    pub footprint_triangles: u32,
    /// Of those, flipped.
    pub footprint_flipped: u32,
    /// Of those, collapsed: image area below [`COLLAPSED`] of the chart's median area ratio.
    pub footprint_collapsed: u32,
    /// Of those, torn: image area above 1 / [`COLLAPSED`] times the median ratio (a triangle whose
    /// corners lie on opposite sides of a cut, stretched across the chart).
    pub footprint_torn: u32,
    /// What was done when the chart folded into the footprint.
    pub fallback: Fallback,
    /// The cone transform that opens the chart at a tip, when it has one ([`cone`]).
    pub cone: Option<cone::Cone>,
}

/// A footprint triangle whose image-to-surface area ratio is below this fraction of the chart's
/// median ratio counts as collapsed.
pub const COLLAPSED: f64 = 1e-3;

/// Reach of the re-solves when a chart folds into its footprint, as multiples of [`REACH`]: 1.2 and
/// then 1.0 half-diagonals, so the region still reaches the decal's corners (a surface point within
/// geodesic distance r of the placed point is within 3D distance r).
pub const FALLBACK_REACH: [f64; 2] = [0.8, 2.0 / 3.0];

/// What was done when a chart folded into its footprint.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Fallback {
    /// Nothing was needed.
    None,
    /// LSCM: re-solved on a smaller region (the report's figures are the final chart's).
    SmallerRegion,
    /// Hybrid: re-solved as a free LSCM chart from its exponential map (on a smaller region too
    /// where that still folded).
    Lscm,
    /// Hybrid: every conformal re-solve still folded; the layer keeps its exponential map (the
    /// report's footprint figures are the exponential map's).
    Expmap,
    /// LSCM: still folded on the smallest region; the bake refuses the layer.
    Refused,
}

/// A chart: coordinates per welded vertex, model units in the decal frame (image centre at 0).
#[derive(Debug, Clone)]
pub struct Chart {
    /// (welded vertex, (x, y)) for every vertex the chart sets.
    pub coords: Vec<(u32, [f32; 2])>,
    /// Chart triangles (LSCM: the final set; hybrid: the re-solved region).
    pub triangles: Vec<u32>,
    /// Report.
    pub report: ChartReport,
    /// True when the chart replaces the layer's map (LSCM); false when it only moves its own
    /// vertices and the others keep their exponential-map coordinates (hybrid).
    pub replaces_map: bool,
}

impl Chart {
    /// The cone transform the chart's coordinates go through where they are used (`None`: none).
    pub fn cone(&self) -> Option<cone::Cone> {
        self.report.cone
    }
}

/// Where the solves run.
pub enum Solver<'a> {
    /// Batched GPU CG (f32).
    Gpu(
        &'a crate::gpu::GpuContext,
        &'a crate::gpu::pipelines::Pipelines,
    ),
    /// f64 CG on the CPU (the twin), the systems of a batch on every core.
    Cpu,
}

/// Totals of the GPU work issued.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct SolveStats {
    /// Batched solves.
    pub batches: u32,
    /// Compute dispatches.
    pub dispatches: u32,
    /// Submissions (each with one status read-back).
    pub submits: u32,
    /// Wall time spent in the solves, seconds (GPU: upload, submissions, read-backs; CPU: the
    /// twin's CG), without the set-up and refinement around them.
    pub solve_seconds: f64,
}

impl Solver<'_> {
    /// Solves `systems` (with warm starts) to `rtol`, each within its budget.
    fn solve(
        &self,
        systems: &[(&System, Vec<f64>, u32)],
        rtol: f32,
        stats: &mut SolveStats,
    ) -> Result<Vec<(Vec<f64>, CgReport)>> {
        if systems.is_empty() {
            return Ok(Vec::new());
        }
        let t = std::time::Instant::now();
        let out = self.solve_timed(systems, rtol, stats);
        stats.solve_seconds += t.elapsed().as_secs_f64();
        out
    }

    fn solve_timed(
        &self,
        systems: &[(&System, Vec<f64>, u32)],
        rtol: f32,
        stats: &mut SolveStats,
    ) -> Result<Vec<(Vec<f64>, CgReport)>> {
        match self {
            Solver::Cpu => Ok(systems
                .par_iter()
                .map(|(s, x0, budget)| {
                    let mut x = x0.clone();
                    let rep =
                        crate::solve::cg::pcg(&s.matrix, &s.rhs, &mut x, rtol as f64, *budget);
                    (x, rep)
                })
                .collect()),
            Solver::Gpu(ctx, pipes) => {
                let blocks: Vec<&Csr> = systems.iter().map(|(s, _, _)| &s.matrix).collect();
                let (a, starts) = Csr::block_diagonal(&blocks);
                let b: Vec<f64> = systems.iter().flat_map(|(s, _, _)| s.rhs.clone()).collect();
                let x0: Vec<f64> = systems.iter().flat_map(|(_, x, _)| x.clone()).collect();
                let descs: Vec<crate::solve::gpu::SystemDesc> = systems
                    .iter()
                    .zip(&starts)
                    .map(|((s, _, budget), &r0)| {
                        crate::solve::gpu::SystemDesc::new(r0, s.matrix.rows, rtol, *budget)
                    })
                    .collect();
                let out = crate::solve::gpu::cg_batched(ctx, pipes, &a, &b, &x0, &descs)?;
                stats.batches += 1;
                stats.dispatches += out.dispatches;
                stats.submits += out.submits;
                Ok(systems
                    .iter()
                    .zip(&starts)
                    .zip(out.reports)
                    .map(|(((s, _, _), &r0), rep)| {
                        let x = out.x[r0..r0 + s.matrix.rows]
                            .iter()
                            .map(|&v| v as f64)
                            .collect();
                        (x, rep)
                    })
                    .collect())
            }
        }
    }
}

/// Automatic final-solve budget for `unknowns`.
pub fn default_budget(unknowns: usize) -> u32 {
    (50.0 * (unknowns as f64).sqrt() + 500.0) as u32
}

/// Positions in the frame's plane, relative to the centre (model units).
fn project(frame: &Frame, p: glam::Vec3) -> DVec2 {
    let d = (p - frame.center).as_dvec3();
    DVec2::new(
        d.dot(frame.axis_u.as_dvec3()),
        d.dot(frame.axis_v.as_dvec3()),
    )
}

fn half_extent(frame: &Frame) -> DVec2 {
    DVec2::new(0.5 * frame.size[0] as f64, 0.5 * frame.size[1] as f64)
}

/// Distance from `c` to segment `a`-`b`.
fn segment_distance(a: DVec2, b: DVec2, c: DVec2) -> f64 {
    let ab = b - a;
    let t = if ab.length_squared() > 0.0 {
        ((c - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (a + t * ab - c).length()
}

fn point_in_triangle(q: [DVec2; 3], c: DVec2) -> bool {
    let s = |a: DVec2, b: DVec2| (b - a).perp_dot(c - a);
    let (d0, d1, d2) = (s(q[0], q[1]), s(q[1], q[2]), s(q[2], q[0]));
    (d0 >= 0.0 && d1 >= 0.0 && d2 >= 0.0) || (d0 <= 0.0 && d1 <= 0.0 && d2 <= 0.0)
}

/// Maillot §4 selection: the connected triangles, from `start`, whose projection along the frame
/// normal meets the disc of radius `radius` around the centre.
pub fn select(topo: &Topology, frame: &Frame, start: u32, radius: f64) -> Vec<u32> {
    select_within(topo, frame, start, radius, REACH)
}

/// [`select`] with the reach limit `reach` (multiples of the decal's half-diagonal).
fn select_within(topo: &Topology, frame: &Frame, start: u32, radius: f64, reach: f64) -> Vec<u32> {
    let hits = |t: u32| -> bool {
        if topo.degenerate[t as usize] {
            return false;
        }
        if !within_reach(topo, frame, t, reach) {
            return false;
        }
        let q = topo.triangles[t as usize].map(|v| project(frame, topo.positions[v as usize]));
        point_in_triangle(q, DVec2::ZERO)
            || (0..3).any(|k| segment_distance(q[k], q[(k + 1) % 3], DVec2::ZERO) <= radius)
    };
    let mut seen = HashSet::from_iter([start]);
    let mut out = vec![start];
    let mut queue = std::collections::VecDeque::from([start]);
    while let Some(t) = queue.pop_front() {
        for nb in topo.triangle_neighbors[t as usize] {
            if nb != NO_NEIGHBOR && seen.insert(nb) && hits(nb) {
                out.push(nb);
                queue.push_back(nb);
            }
        }
    }
    out
}

/// Charts never reach farther than this multiple of the decal's half-diagonal from the placed point
/// (3D distance). Without it a decal larger than a rounded feature (a head, a knob) keeps adding
/// triangles all around it, and the conformal chart of a nearly closed surface crushes its far side.
pub const REACH: f64 = 1.5;

fn within_reach(topo: &Topology, frame: &Frame, t: u32, reach: f64) -> bool {
    let r = reach * half_extent(frame).length();
    topo.triangles[t as usize].iter().any(|&v| {
        (topo.positions[v as usize] - frame.center)
            .as_dvec3()
            .length()
            <= r
    })
}

/// Does segment `a`-`b` meet the open rectangle |x| < h.x, |y| < h.y? (Liang-Barsky clipping.)
fn segment_meets_rect(a: DVec2, b: DVec2, h: DVec2) -> bool {
    let d = b - a;
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for (p, q) in [
        (-d.x, a.x + h.x),
        (d.x, h.x - a.x),
        (-d.y, a.y + h.y),
        (d.y, h.y - a.y),
    ] {
        if p == 0.0 {
            if q <= 0.0 {
                return false;
            }
        } else {
            let r = q / p;
            if p < 0.0 {
                t0 = t0.max(r);
            } else {
                t1 = t1.min(r);
            }
        }
    }
    t0 < t1
}

fn box_meets_rect(q: [DVec2; 3], h: DVec2) -> bool {
    let lo = q[0].min(q[1]).min(q[2]);
    let hi = q[0].max(q[1]).max(q[2]);
    !(hi.x < -h.x || lo.x > h.x || hi.y < -h.y || lo.y > h.y)
}

/// Position of `c` unfolded across the edge `a`-`b` whose images are `za`, `zb` (a similarity of
/// the triangle `t`'s own plane, orientation kept).
fn unfold(topo: &Topology, t: u32, a: u32, b: u32, c: u32, za: DVec2, zb: DVec2) -> DVec2 {
    let tri = topo.triangles[t as usize];
    let p = |v: u32| topo.positions[v as usize].as_dvec3();
    let n = (p(tri[1]) - p(tri[0])).cross(p(tri[2]) - p(tri[0]));
    let n = if n.length() > 0.0 {
        n.normalize()
    } else {
        DVec3::Z
    };
    let (ab, ac) = (p(b) - p(a), p(c) - p(a));
    let l2 = ab.length_squared().max(f64::MIN_POSITIVE);
    let w = DVec2::new(ac.dot(ab) / l2, ab.cross(ac).dot(n) / l2);
    za + lscm::cmul(zb - za, w)
}

/// Per-chart state during refinement.
struct Work {
    triangles: Vec<u32>,
    /// Reach limit (multiples of the half-diagonal).
    reach: f64,
    /// The first selection's topology, and whether any round had to shrink the region to a disc.
    region: RegionReport,
    /// Current coordinates (model units, frame-aligned) per welded vertex.
    warm: HashMap<u32, DVec2>,
    /// The cone fitted to the current coordinates (refinement tests the opened chart's image).
    cone: Option<cone::Cone>,
    seen: HashSet<Vec<u32>>,
    rounds: u32,
    iterations: u32,
    done: bool,
}

impl Work {
    /// Vertex `v`'s image in the opened chart (its coordinate through the cone, if any).
    fn image(&self, v: u32) -> DVec2 {
        let w = self.warm[&v];
        self.cone.map_or(w, |c| c.apply(w))
    }
}

/// The cone a chart needs ([`cone::fit`]), when the request allows one.
fn fit_cone(
    topo: &Topology,
    req: &ChartRequest,
    triangles: &[u32],
    coord: &dyn Fn(u32) -> DVec2,
) -> Option<cone::Cone> {
    if !req.cone {
        return None;
    }
    cone::fit(
        topo,
        &cone::ChartView {
            triangles,
            coord,
            frame: &req.frame,
            seed_triangle: req.triangle,
        },
    )
}

/// A solved system's unknowns (scaled back by `scale`) as a per-vertex chart coordinate.
fn solved_coord<'a>(
    sys: &'a lscm::System,
    x: &'a [f64],
    scale: f64,
) -> impl Fn(u32) -> [f64; 2] + 'a {
    move |v| {
        let i = sys.local[&v] as usize;
        [x[2 * i] * scale, x[2 * i + 1] * scale]
    }
}

/// [`lscm::normalising_similarity`] for the request's frame.
fn frame_similarity(
    topo: &Topology,
    triangles: &[u32],
    coord: &dyn Fn(u32) -> [f64; 2],
    req: &ChartRequest,
) -> Option<(DVec2, DVec2)> {
    lscm::normalising_similarity(
        topo,
        triangles,
        coord,
        req.triangle,
        req.frame.center.as_dvec3(),
        req.frame.axis_u.as_dvec3(),
        req.frame.axis_v.as_dvec3(),
        FIT_RADIUS * max_side(&req.frame),
    )
}

/// The scale at the placed point is fitted over the vertices within this fraction of the decal's
/// larger side (see [`lscm::scale_at`]); the report measures it out to [`CHECK_RADIUS`].
pub const FIT_RADIUS: f64 = 0.1;
/// The report's `scale_at_point` is measured over the vertices within this fraction of the decal's
/// larger side.
pub const CHECK_RADIUS: f64 = 0.2;

fn max_side(frame: &Frame) -> f64 {
    frame.size[0].max(frame.size[1]) as f64
}

/// Builds the charts of `requests` (LSCM and hybrid), solving all charts of a round in one batch.
pub fn build(
    topo: &Topology,
    requests: &[ChartRequest],
    solver: &Solver,
    stats: &mut SolveStats,
) -> Result<Vec<Chart>> {
    let mut out: Vec<Option<Chart>> = vec![None; requests.len()];
    let lscm_ids: Vec<usize> = (0..requests.len())
        .filter(|&i| matches!(requests[i].kind, ChartKind::Lscm))
        .collect();
    build_lscm(topo, requests, &lscm_ids, REACH, solver, stats, &mut out)?;
    build_hybrid(topo, requests, solver, stats, &mut out)?;
    let mut out: Vec<Chart> = out
        .into_iter()
        .map(|c| c.expect("every request answered"))
        .collect();
    for (req, chart) in requests.iter().zip(&mut out) {
        assess(topo, req, chart);
    }
    // Folds in the footprint: an LSCM chart is re-solved on smaller regions; a hybrid decal is
    // re-solved as a free LSCM chart from its exponential map (then on smaller regions too).
    let as_lscm: Vec<ChartRequest> = requests
        .iter()
        .map(|r| ChartRequest {
            kind: ChartKind::Lscm,
            warm: match r.kind {
                ChartKind::Hybrid { expmap, .. } => Some(expmap),
                ChartKind::Lscm => r.warm,
            },
            ..*r
        })
        .collect();
    let hybrid = |i: usize| matches!(requests[i].kind, ChartKind::Hybrid { .. });
    for factor in [1.0].into_iter().chain(FALLBACK_REACH) {
        let folded: Vec<usize> = (0..requests.len())
            .filter(|&i| out[i].report.folded() && (factor < 1.0 || hybrid(i)))
            .collect();
        if folded.is_empty() {
            continue;
        }
        let mut again: Vec<Option<Chart>> = vec![None; requests.len()];
        build_lscm(
            topo,
            &as_lscm,
            &folded,
            factor * REACH,
            solver,
            stats,
            &mut again,
        )?;
        for i in folded {
            let mut c = again[i].take().expect("re-solved");
            assess(topo, &as_lscm[i], &mut c);
            c.report.fallback = if hybrid(i) {
                Fallback::Lscm
            } else {
                Fallback::SmallerRegion
            };
            out[i] = c;
        }
    }
    for (i, chart) in out.iter_mut().enumerate() {
        if !chart.report.folded() {
            continue;
        }
        if hybrid(i) {
            *chart = expmap_fallback(topo, &requests[i], &chart.report);
        } else {
            chart.report.fallback = Fallback::Refused;
        }
    }
    Ok(out)
}

/// A hybrid whose conformal re-solves all fold keeps its exponential map (which bakes wherever
/// the hybrid was asked for): a chart that moves no vertex, its footprint figures the
/// exponential map's own.
fn expmap_fallback(topo: &Topology, req: &ChartRequest, folded: &ChartReport) -> Chart {
    let mut keep = Chart {
        coords: Vec::new(),
        triangles: Vec::new(),
        report: ChartReport {
            cone: None,
            ..*folded
        },
        replaces_map: false,
    };
    assess(topo, req, &mut keep);
    keep.report.fallback = Fallback::Expmap;
    keep
}

impl ChartReport {
    /// A converged, settled report with no solve and no assessment yet (filled by [`assess`]).
    fn unassessed(region: RegionReport) -> Self {
        Self {
            triangles: 0,
            vertices: 0,
            fixed_vertices: 0,
            rounds: 0,
            cg_iterations: 0,
            cg_iterations_total: 0,
            residual: 0.0,
            status: CgStatus::Converged,
            preconditioner: PreconditionerKind::Jacobi,
            settled: true,
            scale_at_point: f64::NAN,
            region,
            footprint_triangles: 0,
            footprint_flipped: 0,
            footprint_collapsed: 0,
            footprint_torn: 0,
            fallback: Fallback::None,
            cone: None,
        }
    }

    /// Some triangle of the footprint is flipped, collapsed or torn.
    pub fn folded(&self) -> bool {
        self.footprint_flipped + self.footprint_collapsed + self.footprint_torn > 0
    }
}

/// Fills `chart`'s scale at the placed point and footprint figures, from the map the layer ends up
/// with (hybrid: the exponential map with the chart's vertices moved).
fn assess(topo: &Topology, req: &ChartRequest, chart: &mut Chart) {
    let mut z: HashMap<u32, DVec2> = HashMap::default();
    if let (ChartKind::Hybrid { expmap, .. }, false) = (req.kind, chart.replaces_map) {
        for (v, c) in expmap.iter().enumerate() {
            if c[3] > 0.5 {
                z.insert(v as u32, DVec2::new(c[0] as f64, c[1] as f64));
            }
        }
    }
    for &(v, c) in &chart.coords {
        z.insert(v, DVec2::new(c[0] as f64, c[1] as f64));
    }
    // Every triangle whose three vertices the final map covers: what the selection stage can draw,
    // including triangles left out of the chart (a handle cut open) whose corners it still covers.
    let mut tris: Vec<u32> = z
        .keys()
        .flat_map(|&v| topo.triangles_around(v).iter().copied())
        .filter(|&t| {
            !topo.degenerate[t as usize]
                && topo.triangles[t as usize].iter().all(|v| z.contains_key(v))
        })
        .collect();
    tris.sort_unstable();
    tris.dedup();
    // The placed point's image, interpolated in the uncut chart (the placed triangle is the one a
    // cut from a tip under the decal crosses), then opened.
    let st = topo.triangles[req.triangle as usize];
    let p = req.frame.center.as_dvec3();
    let bary = lscm::barycentric(st.map(|v| topo.positions[v as usize].as_dvec3()), p);
    let mut zs = st.iter().zip(bary).fold(DVec2::ZERO, |a, (&v, w)| {
        a + w * z.get(&v).copied().unwrap_or(DVec2::NAN)
    });
    if let Some(c) = chart.report.cone {
        // The cut's triangles are drawn per fragment, their per-vertex images straddle the wedge.
        tris.retain(|&t| !c.cut_crosses(topo.triangles[t as usize].map(|v| z[&v])));
        for q in z.values_mut() {
            *q = c.apply(*q);
        }
        zs = c.apply(zs);
    }
    let coord = |v: u32| z.get(&v).map_or([f64::NAN; 2], |c| [c.x, c.y]);
    let radius = CHECK_RADIUS * max_side(&req.frame);
    let r = &mut chart.report;
    r.scale_at_point =
        lscm::scale_at(topo, &tris, &coord, req.triangle, p, zs, radius).unwrap_or(f64::NAN);
    let (ratios, foot) = footprint(topo, &tris, &z, half_extent(&req.frame));
    let median = {
        let mut v = ratios;
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(0.0)
    };
    r.footprint_triangles = foot.len() as u32;
    r.footprint_flipped = foot.iter().filter(|&&f| f < 0.0).count() as u32;
    r.footprint_collapsed = foot
        .iter()
        .filter(|&&f| f >= 0.0 && f < COLLAPSED * median)
        .count() as u32;
    r.footprint_torn = foot.iter().filter(|&&f| f > median / COLLAPSED).count() as u32;
}

/// Every triangle's image-to-surface area ratio (unsigned), and the signed ratios of the triangles
/// whose image meets the rectangle of half-extent `h` (positive: orientation kept).
fn footprint(
    topo: &Topology,
    tris: &[u32],
    z: &HashMap<u32, DVec2>,
    h: DVec2,
) -> (Vec<f64>, Vec<f64>) {
    let mut ratios = Vec::with_capacity(tris.len());
    let mut foot = Vec::new();
    for &t in tris {
        let tri = topo.triangles[t as usize];
        let Some((_, area3)) = lscm::triangle_edges(topo, tri) else {
            continue;
        };
        let q = tri.map(|v| z[&v]);
        let ratio = 0.5 * (q[1] - q[0]).perp_dot(q[2] - q[0]) / area3;
        ratios.push(ratio.abs());
        if box_meets_rect(q, h) {
            foot.push(ratio);
        }
    }
    (ratios, foot)
}

/// The triangles whose three vertices an exponential map (`(u, v, _, valid)` per welded vertex)
/// reaches, found from its vertices (cost proportional to the map, not the mesh), ascending.
fn map_triangles(topo: &Topology, expmap: &[[f32; 4]]) -> Vec<u32> {
    let valid = |v: u32| expmap[v as usize][3] > 0.5;
    let mut tris: Vec<u32> = (0..expmap.len() as u32)
        .filter(|&v| valid(v))
        .flat_map(|v| topo.triangles_around(v).iter().copied())
        .filter(|&t| {
            !topo.degenerate[t as usize] && topo.triangles[t as usize].iter().all(|&v| valid(v))
        })
        .collect();
    tris.sort_unstable();
    tris.dedup();
    tris
}

/// A hybrid decal's region: the exponential map's triangles; when the whole disc is re-solved and
/// it is not a disc, it is shrunk to one.
fn hybrid_region(topo: &Topology, expmap: &[[f32; 4]], whole: bool) -> RegionReport {
    let mut r = region::topology(topo, &map_triangles(topo, expmap));
    if whole && !r.disc {
        r.fix = RegionFix::ShrunkToDisc;
    }
    r
}

/// The LSCM charts `lscm_ids` of `requests` (within `reach` half-diagonals): selection, then rounds of solve and refinement (all charts of a
/// round in one batch) until every chart settles or [`MAX_ROUNDS`], then a final solve to
/// [`FINAL_RTOL`].
#[allow(clippy::too_many_arguments)]
fn build_lscm(
    topo: &Topology,
    requests: &[ChartRequest],
    lscm_ids: &[usize],
    reach: f64,
    solver: &Solver,
    stats: &mut SolveStats,
    out: &mut [Option<Chart>],
) -> Result<()> {
    let mut work: Vec<Work> = lscm_ids
        .iter()
        .map(|&i| start_work(topo, &requests[i], reach))
        .collect();
    let mut finals: Vec<Option<(Vec<f64>, CgReport, System)>> = vec![None; lscm_ids.len()];
    for round in 0..=MAX_ROUNDS {
        let last = round == MAX_ROUNDS || work.iter().all(|w| w.done);
        let active: Vec<usize> = (0..work.len()).filter(|&k| last || !work[k].done).collect();
        if active.is_empty() {
            break;
        }
        let systems: Vec<(System, Vec<f64>)> = active
            .iter()
            .map(|&k| pinned_system(topo, &requests[lscm_ids[k]], &work[k]))
            .collect();
        let (rtol, budgets): (f32, Vec<u32>) = if last {
            (
                FINAL_RTOL,
                active
                    .iter()
                    .zip(&systems)
                    .map(|(&k, (s, _))| {
                        requests[lscm_ids[k]]
                            .max_iter
                            .unwrap_or_else(|| default_budget(s.matrix.rows))
                    })
                    .collect(),
            )
        } else {
            (
                COARSE_RTOL,
                systems
                    .iter()
                    .map(|(s, _)| default_budget(s.matrix.rows))
                    .collect(),
            )
        };
        let input: Vec<(&System, Vec<f64>, u32)> = systems
            .iter()
            .zip(&budgets)
            .map(|((s, x0), &b)| (s, x0.clone(), b))
            .collect();
        let solved = solver.solve(&input, rtol, stats)?;
        for ((&k, (sys, _)), (x, rep)) in active.iter().zip(systems).zip(solved) {
            let req = &requests[lscm_ids[k]];
            let w = &mut work[k];
            w.rounds += 1;
            w.iterations += rep.iterations;
            let scale = half_extent(&req.frame).length();
            if rep.status != CgStatus::Breakdown {
                let coord = solved_coord(&sys, &x, scale);
                if let Some((alpha, beta)) = frame_similarity(topo, &w.triangles, &coord, req) {
                    for &v in &sys.vertices {
                        let z = DVec2::from(coord(v));
                        w.warm.insert(v, lscm::cmul(alpha, z) + beta);
                    }
                }
                w.cone = fit_cone(topo, req, &w.triangles, &|v| w.warm[&v]);
            }
            if last {
                finals[k] = Some((x, rep, sys));
                continue;
            }
            if rep.status == CgStatus::Breakdown {
                w.done = true;
                continue;
            }
            w.seen.insert(sorted(&w.triangles));
            let changed = refine(topo, req, w, round == 0);
            if !changed || w.seen.contains(&sorted(&w.triangles)) {
                w.done = true;
            }
        }
        if last {
            break;
        }
    }
    for (k, f) in finals.into_iter().enumerate() {
        let (_, rep, sys) = f.expect("every chart gets a final solve");
        out[lscm_ids[k]] = Some(finished_chart(&work[k], rep, sys));
    }
    Ok(())
}

/// A chart's first selection, with its warm start: the request's map where it reaches, else the
/// planar projection.
fn start_work(topo: &Topology, r: &ChartRequest, reach: f64) -> Work {
    let radius = half_extent(&r.frame).length();
    let mut triangles = select_within(topo, &r.frame, r.triangle, radius, reach);
    let mut region = region::topology(topo, &triangles);
    if !region.disc {
        triangles = region::grow_disc(topo, &triangles, r.triangle, r.frame.center.as_dvec3());
        region.fix = RegionFix::ShrunkToDisc;
    }
    let mut warm = HashMap::default();
    for &t in &triangles {
        for v in topo.triangles[t as usize] {
            warm.entry(v).or_insert_with(|| match r.warm {
                Some(m) if m[v as usize][3] > 0.5 => {
                    DVec2::new(m[v as usize][0] as f64, m[v as usize][1] as f64)
                }
                _ => project(&r.frame, topo.positions[v as usize]),
            });
        }
    }
    Work {
        triangles,
        reach,
        region,
        warm,
        cone: None,
        seen: HashSet::default(),
        rounds: 0,
        iterations: 0,
        done: false,
    }
}

/// The chart of a finished LSCM solve.
fn finished_chart(w: &Work, rep: CgReport, sys: System) -> Chart {
    let coords = sys
        .vertices
        .iter()
        .map(|&v| {
            let z = w.warm[&v];
            (v, [z.x as f32, z.y as f32])
        })
        .collect();
    Chart {
        replaces_map: true,
        coords,
        triangles: w.triangles.clone(),
        report: ChartReport {
            triangles: w.triangles.len() as u32,
            vertices: sys.vertices.len() as u32,
            fixed_vertices: sys.fixed.len() as u32,
            rounds: w.rounds,
            cg_iterations: rep.iterations,
            cg_iterations_total: w.iterations,
            residual: rep.residual,
            status: rep.status,
            preconditioner: rep.preconditioner,
            settled: w.done,
            cone: w.cone,
            ..ChartReport::unassessed(w.region)
        },
    }
}

/// The hybrid charts of `requests`: one constrained solve each, all in one batch.
fn build_hybrid(
    topo: &Topology,
    requests: &[ChartRequest],
    solver: &Solver,
    stats: &mut SolveStats,
    out: &mut [Option<Chart>],
) -> Result<()> {
    let hybrid: Vec<(usize, System, Vec<f64>, u32, bool)> = (0..requests.len())
        .filter_map(|i| match requests[i].kind {
            ChartKind::Hybrid { expmap, threshold } => {
                let (sys, x0, whole) = hybrid_system(topo, &requests[i], expmap, threshold);
                let budget = requests[i]
                    .max_iter
                    .unwrap_or_else(|| default_budget(sys.matrix.rows));
                Some((i, sys, x0, budget, whole))
            }
            ChartKind::Lscm => None,
        })
        .collect();
    let input: Vec<(&System, Vec<f64>, u32)> = hybrid
        .iter()
        .filter(|(_, s, _, _, _)| s.matrix.rows > 0)
        .map(|(_, s, x0, b, _)| (s, x0.clone(), *b))
        .collect();
    let mut solved = solver.solve(&input, FINAL_RTOL, stats)?.into_iter();
    for (i, sys, _, _, whole) in hybrid {
        let req = &requests[i];
        let region_report = match req.kind {
            ChartKind::Hybrid { expmap, .. } => hybrid_region(topo, expmap, whole),
            ChartKind::Lscm => unreachable!("hybrid requests only"),
        };
        let scale = half_extent(&req.frame).length();
        let (coords, report) = if sys.matrix.rows == 0 {
            (Vec::new(), ChartReport::unassessed(region_report))
        } else {
            let (x, rep) = solved.next().expect("one solution per hybrid system");
            let coord = solved_coord(&sys, &x, scale);
            // Whole disc re-solved: normalise like an LSCM chart, every vertex moves.
            let similarity = if whole {
                frame_similarity(topo, &sys.triangles, &coord, req)
            } else {
                None
            };
            let fixed: HashSet<u32> = sys.fixed.iter().map(|f| f.0).collect();
            let coords = (0..sys.vertices.len())
                .filter(|i| whole || !fixed.contains(&(*i as u32)))
                .map(|i| {
                    let v = sys.vertices[i];
                    let mut z = DVec2::from(coord(v));
                    if let Some((alpha, beta)) = similarity {
                        z = lscm::cmul(alpha, z) + beta;
                    }
                    (v, [z.x as f32, z.y as f32])
                })
                .collect::<Vec<_>>();
            let report = ChartReport {
                triangles: sys.triangles.len() as u32,
                vertices: coords.len() as u32,
                fixed_vertices: sys.fixed.len() as u32,
                rounds: 1,
                cg_iterations: rep.iterations,
                cg_iterations_total: rep.iterations,
                residual: rep.residual,
                status: rep.status,
                preconditioner: rep.preconditioner,
                cone: if whole {
                    let at: HashMap<u32, DVec2> = coords
                        .iter()
                        .map(|&(v, c)| (v, DVec2::new(c[0] as f64, c[1] as f64)))
                        .collect();
                    fit_cone(topo, req, &sys.triangles, &|v| at[&v])
                } else {
                    None
                },
                ..ChartReport::unassessed(region_report)
            };
            (coords, report)
        };
        out[i] = Some(Chart {
            // A whole-disc re-solve replaces the map (its disc may have been shrunk); otherwise the
            // vertices the solve did not free keep their exponential-map coordinates.
            replaces_map: whole,
            coords,
            triangles: sys.triangles.clone(),
            report,
        });
    }
    Ok(())
}

/// The first LSCM system of a chart (Maillot §4 selection, two pins, planar warm start, unknowns in
/// units of the decal's half-diagonal), for benchmarks and peer comparisons: returns the selected
/// triangles, the system and the warm start.
pub fn initial_system(
    topo: &Topology,
    frame: &Frame,
    triangle: u32,
) -> (Vec<u32>, System, Vec<f64>) {
    let radius = half_extent(frame).length();
    let triangles = select(topo, frame, triangle, radius);
    let mut warm = HashMap::default();
    for &t in &triangles {
        for v in topo.triangles[t as usize] {
            warm.entry(v)
                .or_insert_with(|| project(frame, topo.positions[v as usize]));
        }
    }
    let w = Work {
        region: region::topology(topo, &triangles),
        triangles: triangles.clone(),
        reach: REACH,
        warm,
        cone: None,
        seen: HashSet::default(),
        rounds: 0,
        iterations: 0,
        done: false,
    };
    let req = ChartRequest {
        frame: *frame,
        triangle,
        kind: ChartKind::Lscm,
        max_iter: None,
        warm: None,
        cone: false,
    };
    let (sys, x0) = pinned_system(topo, &req, &w);
    (triangles, sys, x0)
}

fn sorted(v: &[u32]) -> Vec<u32> {
    let mut s = v.to_vec();
    s.sort_unstable();
    s
}

/// The LSCM system of a chart with two pins at its extreme vertices along x, unknowns in units of
/// the decal's half-diagonal, and the warm start.
fn pinned_system(topo: &Topology, req: &ChartRequest, w: &Work) -> (System, Vec<f64>) {
    let scale = half_extent(&req.frame).length();
    let warm = |v: u32| -> [f64; 2] {
        let z = w.warm[&v] / scale;
        [z.x, z.y]
    };
    pinned_lscm(topo, &w.triangles, &|v| w.warm[&v].x, &warm)
}

/// The LSCM system of `triangles` with two pins, the vertices of least and greatest `x`, held at
/// `warm`, and the warm start.
fn pinned_lscm(
    topo: &Topology,
    triangles: &[u32],
    x: &dyn Fn(u32) -> f64,
    warm: &dyn Fn(u32) -> [f64; 2],
) -> (System, Vec<f64>) {
    let mut verts: Vec<u32> = triangles
        .iter()
        .flat_map(|&t| topo.triangles[t as usize])
        .collect();
    verts.sort_unstable();
    verts.dedup();
    let lo = *verts
        .iter()
        .min_by(|a, b| x(**a).total_cmp(&x(**b)))
        .expect("a chart has vertices");
    let hi = *verts
        .iter()
        .max_by(|a, b| x(**a).total_cmp(&x(**b)))
        .expect("a chart has vertices");
    let fixed = if lo == hi {
        vec![(lo, warm(lo))]
    } else {
        vec![(lo, warm(lo)), (hi, warm(hi))]
    };
    let sys = lscm::assemble(topo, triangles, &fixed, warm);
    let x0 = sys.vertices.iter().flat_map(|&v| warm(v)).collect();
    (sys, x0)
}

/// Maillot §6 adjustment of one chart from its normalised coordinates; returns whether the triangle
/// set changed.
fn refine(topo: &Topology, req: &ChartRequest, w: &mut Work, remove: bool) -> bool {
    let h = half_extent(&req.frame);
    let before = w.triangles.len();
    let img = |w: &Work, t: u32| topo.triangles[t as usize].map(|v| w.image(v));
    let mut changed = false;
    if remove {
        let keep: HashSet<u32> = w
            .triangles
            .iter()
            .copied()
            .filter(|&t| t == req.triangle || box_meets_rect(img(w, t), h))
            .collect();
        // The placed triangle's connected part of what is kept.
        let mut comp = vec![req.triangle];
        let mut seen = HashSet::from_iter([req.triangle]);
        let mut i = 0;
        while i < comp.len() {
            for nb in topo.triangle_neighbors[comp[i] as usize] {
                if nb != NO_NEIGHBOR && keep.contains(&nb) && seen.insert(nb) {
                    comp.push(nb);
                }
            }
            i += 1;
        }
        changed |= comp.len() != before;
        w.triangles = comp;
    }
    let set: HashSet<u32> = w.triangles.iter().copied().collect();
    let mut add = Vec::new();
    let mut added = HashSet::default();
    for &t in &w.triangles {
        let tri = topo.triangles[t as usize];
        for k in 0..3 {
            let nb = topo.triangle_neighbors[t as usize][k];
            if nb == NO_NEIGHBOR
                || set.contains(&nb)
                || topo.degenerate[nb as usize]
                || !within_reach(topo, &req.frame, nb, w.reach)
            {
                continue;
            }
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            if segment_meets_rect(w.image(a), w.image(b), h) && added.insert(nb) {
                add.push((nb, a, b));
            }
        }
    }
    for (nb, a, b) in add {
        let c = topo.triangles[nb as usize]
            .into_iter()
            .find(|&v| v != a && v != b)
            .expect("a triangle has a third vertex");
        if !w.warm.contains_key(&c) {
            let z = unfold(topo, nb, a, b, c, w.warm[&a], w.warm[&b]);
            w.warm.insert(c, z);
        }
        w.triangles.push(nb);
        changed = true;
    }
    if changed {
        let found = region::topology(topo, &w.triangles);
        if !found.disc {
            let center = req.frame.center.as_dvec3();
            w.triangles = region::grow_disc(topo, &w.triangles, req.triangle, center);
            w.region = RegionReport {
                fix: RegionFix::ShrunkToDisc,
                ..found
            };
        }
    }
    changed
}

/// Angle distortion s1 / s2 of a triangle's map `z` (per vertex) from its own plane.
pub fn angle_distortion(topo: &Topology, tri: [u32; 3], z: [DVec2; 3]) -> f64 {
    let Some((e, _)) = lscm::triangle_edges(topo, tri) else {
        return 1.0;
    };
    // Writing the affine map as z = α w + β conj(w) + c on the triangle's plane, Σ conj(e_k) z_k =
    // 4A|α| in modulus and Σ e_k z_k is 4A|β| in modulus; the singular values are
    // |α| + |β| and ||α| - |β||.
    let (mut h, mut a) = (DVec2::ZERO, DVec2::ZERO);
    for k in 0..3 {
        h += lscm::cmul(DVec2::new(e[k].x, -e[k].y), z[k]);
        a += lscm::cmul(e[k], z[k]);
    }
    let (p, q) = (h.length(), a.length());
    if (p - q).abs() == 0.0 {
        f64::INFINITY
    } else {
        (p + q) / (p - q).abs()
    }
}

/// The hybrid system of one request: free vertices are those of triangles whose angle distortion
/// exceeds the threshold; the energy covers every map triangle touching a free vertex; their other
/// vertices are held at the exponential map. Unknowns in units of the decal's half-diagonal. The flag
/// says the whole disc was freed (then the result needs normalising).
fn hybrid_system(
    topo: &Topology,
    req: &ChartRequest,
    expmap: &[[f32; 4]],
    threshold: f32,
) -> (System, Vec<f64>, bool) {
    let scale = half_extent(&req.frame).length();
    let h = half_extent(&req.frame);
    let valid = |v: u32| expmap[v as usize][3] > 0.5;
    let z = |v: u32| DVec2::new(expmap[v as usize][0] as f64, expmap[v as usize][1] as f64);
    let mut free: HashSet<u32> = HashSet::default();
    // The map's triangles, found from its vertices (cost proportional to the map, not the mesh).
    let mut map_tris = map_triangles(topo, expmap);
    for &t in &map_tris {
        let tri = &topo.triangles[t as usize];
        let img = tri.map(z);
        // Only triangles under the decal matter.
        if box_meets_rect(img, h) && angle_distortion(topo, *tri, img) > threshold as f64 {
            free.extend(tri.iter().copied());
        }
    }
    // Grow the free region by HYBRID_RINGS rings inside the map, so the held vertices sit away from
    // the distortion they would otherwise pin in place.
    for _ in 0..HYBRID_RINGS {
        let ring: Vec<u32> = free
            .iter()
            .flat_map(|&v| {
                let (a, b) = (
                    topo.adjacency_offsets[v as usize] as usize,
                    topo.adjacency_offsets[v as usize + 1] as usize,
                );
                topo.adjacency[a..b].iter().copied()
            })
            .filter(|&q| valid(q))
            .collect();
        free.extend(ring);
    }
    let energy: Vec<u32> = map_tris
        .iter()
        .copied()
        .filter(|&t| topo.triangles[t as usize].iter().any(|v| free.contains(v)))
        .collect();
    let warm = |v: u32| -> [f64; 2] {
        let q = z(v) / scale;
        [q.x, q.y]
    };
    let mut fixed: Vec<(u32, [f64; 2])> = Vec::new();
    let mut fixed_seen = HashSet::default();
    for &t in &energy {
        for v in topo.triangles[t as usize] {
            if !free.contains(&v) && fixed_seen.insert(v) {
                fixed.push((v, warm(v)));
            }
        }
    }
    // When the distorted part dominates the decal there is nothing good to keep, and the few held
    // vertices (themselves in distorted surroundings) would dictate the result: solve the whole
    // geodesic disc conformally instead, with two pins, and normalise it like an LSCM chart.
    let under: HashSet<u32> = map_tris
        .iter()
        .filter(|&&t| box_meets_rect(topo.triangles[t as usize].map(z), h))
        .flat_map(|&t| topo.triangles[t as usize])
        .collect();
    let free_under = under.iter().filter(|v| free.contains(v)).count();
    if !energy.is_empty() && (fixed.len() < 2 || 2 * free_under > under.len()) {
        if !region::topology(topo, &map_tris).disc {
            map_tris =
                region::grow_disc(topo, &map_tris, req.triangle, req.frame.center.as_dvec3());
        }
        let (sys, x0) = pinned_lscm(topo, &map_tris, &|v| z(v).x, &warm);
        return (sys, x0, true);
    }
    let sys = lscm::assemble(topo, &energy, &fixed, &warm);
    let x0 = sys.vertices.iter().flat_map(|&v| warm(v)).collect();
    (sys, x0, false)
}
