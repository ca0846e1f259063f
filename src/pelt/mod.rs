// SPDX-License-Identifier: MIT OR Apache-2.0
//! Pelting (Piponi & Borshukov 2000, §3-5): new UV sets for meshes that have none or whose seams
//! show. The surface is cut into disks (`cut`, through its tips: `tips`), each disk is stretched on
//! a frame by damped spring dynamics in 3D on the GPU (`relax` holds the net and its CPU twin,
//! `gpu` the dispatch of `wgsl/pelt/pelt_step.wgsl` and `pelt_check.wgsl`; `tutte` solves the net
//! without rest lengths directly, the refinement's start) and projected, refined
//! by a conformal map (`refine`), split where it folds (`split`), packed into [0, 1]² (`pack`) and
//! measured (`quality`); `patch` adds the §5 patch and blend function, and `bridge` the third chart
//! that a patch needs round seams with cycles. `decalbake unwrap` writes
//! the result as new `TEXCOORD_n` sets (`apply`, `apply_all` build the mesh).

pub mod bridge;
pub mod cut;
pub mod gpu;
pub mod hidden;
pub mod pack;
pub mod patch;
pub mod quality;
pub mod refine;
pub mod relax;
pub mod repack;
pub mod split;
pub mod tips;
pub mod tutte;

use crate::error::Result;
use crate::gpu::pipelines::Pipelines;
use crate::gpu::GpuContext;
use crate::mesh::{Mesh, Topology};
use glam::{DVec2, Vec2};
use rayon::prelude::*;
use std::path::Path;
use std::time::Instant;

pub use cut::CutSpec;
pub use relax::{Frame, SystemCfg};

/// How to unwrap.
#[derive(Debug, Clone)]
pub struct Options {
    /// The cut.
    pub cut: CutSpec,
    /// The frame.
    pub frame: Frame,
    /// Texture size the packing margin is measured in.
    pub size: u32,
    /// Margin round each pelt, in texels of `size`.
    pub margin: u32,
    /// The dynamics' stopping rule.
    pub relax: SystemCfg,
    /// What follows the pelting.
    pub refine: Refine,
    /// Open non-manifold edges instead of refusing them (`cut::cut_with`).
    pub split_non_manifold: bool,
    /// How many times a piece may be split (one split after another); 0 keeps the cut's pieces.
    pub max_split_levels: usize,
    /// Split an elongated pelt where the packing would use too little of the texture (`repack`;
    /// only with `max_split_levels` above 0).
    pub pack_splits: bool,
}

/// What follows the pelting (`decalbake unwrap --refine`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Refine {
    /// The pelts as the dynamics left them.
    None,
    /// A least-squares conformal map from each pelt, kept where it does not fold (`refine`).
    Conformal,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            cut: CutSpec::Auto,
            frame: Frame::Circle,
            size: 1024,
            margin: 4,
            relax: SystemCfg::default(),
            refine: Refine::Conformal,
            split_non_manifold: false,
            max_split_levels: MAX_SPLIT_LEVELS,
            pack_splits: true,
        }
    }
}

/// Where the relaxation ran.
#[derive(Clone, Copy)]
pub enum Device<'a> {
    /// The GPU kernel.
    Gpu(&'a GpuContext, &'a Pipelines),
    /// The CPU twin.
    Cpu,
}

/// Per-piece figures of the report.
#[derive(Debug, Clone, serde::Serialize)]
pub struct PieceReport {
    /// Vertices (cut vertices counted per side).
    pub vertices: usize,
    /// Triangles.
    pub triangles: usize,
    /// Boundary vertices (on the frame).
    pub boundary: usize,
    /// The dynamics.
    pub relax: relax::Relaxed,
    /// The conformal refinement (`None` with `Refine::None`).
    pub refine: Option<refine::Refinement>,
    /// The piece's own layout (its flips and overlaps, distortion normalised by its own area).
    pub quality: quality::Quality,
}

/// What an unwrap reports (`decalbake unwrap --report`).
#[derive(Debug, Clone, serde::Serialize)]
pub struct UnwrapReport {
    /// `gpu` or `cpu`.
    pub device: &'static str,
    /// The frame.
    pub frame: Frame,
    /// Pieces (pelts).
    pub pieces: Vec<PieceReport>,
    /// Pieces split in two because their pelt folded or stretched too far ([`folds`]).
    pub splits: usize,
    /// Pieces the first automatic cut left that were not disks (a small closed part whose cut
    /// path is one edge, a part whose winding flips), each cut further into disks grown triangle
    /// by triangle ([`cut::disk_charts`]); the splits' own cuts are not counted.
    pub regrown: usize,
    /// Opened edges (the automatic cut's and the splits' seams).
    pub seam_edges: usize,
    /// Summed 3D length of the opened edges.
    pub seam_length: f64,
    /// Welded vertices the automatic cut runs through (boundary joints, tips).
    pub terminals: Vec<u32>,
    /// Energy (eq. 1 plus the frame springs, in mean-edge units) summed over pieces: start, end.
    pub energy: [f64; 2],
    /// Most steps any piece took.
    pub steps: u32,
    /// The packed layout's quality.
    pub quality: quality::Quality,
    /// Milliseconds per stage: cut (with splits), net, relax, refine, pack, measure.
    pub ms: Timings,
}

/// Milliseconds per stage.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct Timings {
    /// Cutting and splitting.
    pub cut: f64,
    /// Building the nets.
    pub net: f64,
    /// The dynamics.
    pub relax: f64,
    /// The conformal refinement.
    pub refine: f64,
    /// Packing.
    pub pack: f64,
    /// Measuring.
    pub measure: f64,
    /// The occlusion rays of the automatic cut (`hidden::exposure`): part of `cut`, not added
    /// again by [`Timings::total`].
    pub exposure: f64,
}

impl Timings {
    /// All stages together.
    pub fn total(&self) -> f64 {
        self.cut + self.net + self.relax + self.refine + self.pack + self.measure
    }
}

/// An unwrapped surface.
#[derive(Debug, Clone)]
pub struct Unwrapped {
    /// The cut.
    pub cut: cut::Cut,
    /// Per piece, per piece vertex: its UV in [0, 1]² (v down, as glTF has it).
    pub uv: Vec<Vec<Vec2>>,
    /// The report.
    pub report: UnwrapReport,
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// Unwraps the welded surface `topo` of `mesh` (`path` names it in errors).
pub fn unwrap(
    device: Device,
    mesh: &Mesh,
    topo: &Topology,
    opts: &Options,
    path: &Path,
) -> Result<Unwrapped> {
    let t = Instant::now();
    let first = cut::cut_with(mesh, topo, &opts.cut, opts.split_non_manifold, path)?;
    let prior = Prior {
        terminals: first.terminals,
        cut_ms: ms(t),
        exposure: first.exposure,
        exposure_ms: first.exposure_ms,
        regrown: first.regrown,
    };
    layout(device, topo, first.pieces, prior, opts, path)
}

/// `hidden::exposure`, its time added to `timings.exposure`.
fn measure_exposure(topo: &Topology, timings: &mut Timings) -> Vec<f32> {
    let t = Instant::now();
    let e = hidden::exposure(topo);
    timings.exposure += ms(t);
    e
}

/// What the first cut leaves to [`layout`].
#[derive(Debug, Clone, Default)]
pub struct Prior {
    /// The automatic cut's terminals (tips, boundary joints), for the report.
    pub terminals: Vec<u32>,
    /// The cut's time.
    pub cut_ms: f64,
    /// Each welded vertex's exposure, if the cut measured it (`hidden::exposure`; measured on the
    /// first split otherwise).
    pub exposure: Vec<f32>,
    /// Milliseconds the exposure took (part of `cut_ms`).
    pub exposure_ms: f64,
    /// Pieces the cut left that were not disks, cut further ([`cut::Cut::regrown`]).
    pub regrown: usize,
}

/// Pelts, refines, splits and packs `pieces` (disks, in `topo`'s welded ids) as
/// [`unwrap`] does after its cut (`prior`).
pub fn layout(
    device: Device,
    topo: &Topology,
    pieces: Vec<cut::Piece>,
    prior: Prior,
    opts: &Options,
    path: &Path,
) -> Result<Unwrapped> {
    let mut timings = Timings {
        cut: prior.cut_ms,
        exposure: prior.exposure_ms,
        ..Timings::default()
    };
    let (terminals, mut exposure, regrown) = (prior.terminals, prior.exposure, prior.regrown);
    let mut todo = pieces;
    let mut done: Vec<Done> = Vec::new();
    let mut splits = 0;
    for level in 0..=opts.max_split_levels {
        let split_here = level < opts.max_split_levels;
        let (kept, parts) = one_level(device, topo, todo, opts, split_here, &mut timings)?;
        done.extend(kept);
        let t = Instant::now();
        if !parts.is_empty() && exposure.is_empty() {
            exposure = measure_exposure(topo, &mut timings);
        }
        splits += parts.len();
        let halves: Vec<Vec<u32>> = parts.into_iter().flatten().collect();
        let nm = opts.split_non_manifold;
        // Each half is cut on its own (on every core; the order is kept).
        let cuts: Vec<Vec<cut::Piece>> = halves
            .par_iter()
            .map(|half| split::cut_region(topo, half, nm, &exposure, path))
            .collect::<Result<_>>()?;
        let next: Vec<cut::Piece> = cuts.into_iter().flatten().collect();
        timings.cut += ms(t);
        todo = next;
        if todo.is_empty() {
            break;
        }
    }
    let (done, repacked, packed) =
        repack::split_for_packing(device, topo, done, opts, &mut exposure, path, &mut timings)?;
    splits += repacked;
    let mut pieces = Vec::new();
    let (mut relaxed, mut flat, mut refined) = (Vec::new(), Vec::new(), Vec::new());
    for (p, r, f, rf) in done {
        pieces.push(p);
        relaxed.push(r);
        flat.push(f);
        refined.push(rf);
    }
    let mut cut = cut::Cut::assemble(topo, pieces, terminals);
    cut.regrown = regrown;
    let t = Instant::now();
    let uv = packed.unwrap_or_else(|| {
        let pieces: Vec<&cut::Piece> = cut.pieces.iter().collect();
        let flat: Vec<&[DVec2]> = flat.iter().map(|f| &f[..]).collect();
        place(topo, &pieces, &flat, opts)
    });
    timings.pack += ms(t);
    let t = Instant::now();
    let quality = measure(topo, &cut, &uv);
    timings.measure = ms(t);
    let report = UnwrapReport {
        device: match device {
            Device::Gpu(..) => "gpu",
            Device::Cpu => "cpu",
        },
        frame: opts.frame,
        pieces: cut
            .pieces
            .iter()
            .zip(relaxed.into_iter().zip(refined))
            .zip(&flat)
            .map(|((p, (r, rf)), f)| PieceReport {
                quality: piece_quality(topo, p, f),
                vertices: p.welded.len(),
                triangles: p.triangles.len(),
                boundary: p.boundary.len(),
                relax: r,
                refine: (opts.refine == Refine::Conformal).then_some(rf),
            })
            .collect(),
        splits,
        regrown,
        seam_edges: cut.edges.len(),
        seam_length: cut.seam_length(topo),
        terminals: cut.terminals.clone(),
        energy: [0.0, 0.0],
        steps: 0,
        quality,
        ms: timings,
    };
    let mut report = report;
    report.energy = report.pieces.iter().fold([0.0, 0.0], |a, p| {
        [a[0] + p.relax.energy[0], a[1] + p.relax.energy[1]]
    });
    report.steps = report
        .pieces
        .iter()
        .map(|p| p.relax.steps)
        .max()
        .unwrap_or(0);
    Ok(Unwrapped { cut, uv, report })
}

/// A laid-out piece: the piece, its dynamics, its layout, its refinement.
type Done = (cut::Piece, relax::Relaxed, Vec<DVec2>, refine::Refinement);

/// One split level of [`layout`]: pelts and refines `todo`; returns the pieces kept and, for each
/// piece split (only when `split_here`), its two halves (mesh triangle ids).
///
/// With `--refine conformal` each piece is refined from the ladder's last rung ([`START_SCALES`]);
/// a piece whose refinement is not kept and that is not split is pelted again on the whole
/// ladder ([`REST_SCALES`], eq. 1's rest lengths first), and that pelt is its layout.
#[allow(clippy::type_complexity, reason = "kept pieces and split halves")]
fn one_level(
    device: Device,
    topo: &Topology,
    todo: Vec<cut::Piece>,
    opts: &Options,
    split_here: bool,
    timings: &mut Timings,
) -> Result<(Vec<Done>, Vec<[Vec<u32>; 2]>)> {
    let conformal = opts.refine == Refine::Conformal;
    let t = Instant::now();
    let nets: Vec<relax::Net> = todo
        .par_iter()
        .map(|p| relax::net(topo, p, opts.frame))
        .collect();
    timings.net += ms(t);
    let first = if conformal {
        &START_SCALES[..]
    } else {
        &REST_SCALES[..]
    };
    let all: Vec<_> = todo.iter().zip(&nets).collect();
    let pelts = pelt_without_folds(device, topo, &all, first, &opts.relax, timings)?;
    let (mut relaxed, mut flats): (Vec<relax::Relaxed>, Vec<Vec<DVec2>>) =
        pelts.into_iter().unzip();
    let t = Instant::now();
    let (refinements, apart, measured) = if conformal {
        refine_pelts(device, topo, &todo, &mut flats)?
    } else {
        let n = todo.len();
        (
            vec![refine::Refinement::default(); n],
            vec![None; n],
            vec![None; n],
        )
    };
    timings.refine += ms(t);
    let t = Instant::now();
    let halves: Vec<Option<[Vec<u32>; 2]>> = (0..todo.len())
        .into_par_iter()
        .map(|k| {
            let rf = &refinements[k];
            let refine_failed = conformal && !rf.kept;
            let known = measured[k].as_ref();
            (split_here && stretched(topo, &todo[k], &flats[k], refine_failed, known))
                .then(|| split::halves(topo, &todo[k], apart[k].filter(|_| !rf.kept)))
                .flatten()
        })
        .collect();
    timings.cut += ms(t);
    let unrefined: Vec<usize> = (0..todo.len())
        .filter(|&k| conformal && !refinements[k].kept && halves[k].is_none())
        .collect();
    if !unrefined.is_empty() {
        let sel: Vec<_> = unrefined.iter().map(|&k| all[k]).collect();
        let again = pelt_without_folds(device, topo, &sel, &REST_SCALES, &opts.relax, timings)?;
        for (&k, (r, f)) in unrefined.iter().zip(again) {
            (relaxed[k], flats[k]) = (r, f);
        }
    }
    let mut kept = Vec::new();
    let mut parts = Vec::new();
    for ((((p, r), f), rf), h) in todo
        .into_iter()
        .zip(relaxed)
        .zip(flats)
        .zip(refinements)
        .zip(halves)
    {
        match h {
            Some(h) => parts.push(h),
            None => kept.push((p, r, f, rf)),
        }
    }
    Ok((kept, parts))
}

fn run(device: Device, nets: &[relax::Net], cfg: &SystemCfg) -> Result<Vec<relax::Relaxed>> {
    match device {
        Device::Gpu(ctx, pipes) => gpu::relax_gpu(ctx, pipes, nets, cfg),
        Device::Cpu => Ok(nets
            .iter()
            .map(|n| relax::relax_cpu(n, cfg, None))
            .collect()),
    }
}

/// Refines every pelt (`refine`), replacing `flats[k]` where the refinement does not fold; also
/// returns, per piece, a pair of overlapping triangles of its refinement (a split there lets the
/// halves refine) and the quality of the refinement where it was kept.
#[allow(clippy::type_complexity, reason = "three per-piece lists")]
fn refine_pelts(
    device: Device,
    topo: &Topology,
    pieces: &[cut::Piece],
    flats: &mut [Vec<DVec2>],
) -> Result<(
    Vec<refine::Refinement>,
    Vec<Option<(u32, u32)>>,
    Vec<Option<quality::Quality>>,
)> {
    let refined = refine::refine(device, topo, pieces, flats)?;
    // One measure per piece (on every core) gives both the fold test and, only where it overlaps,
    // the pair to split at.
    let measures: Vec<Option<(quality::Quality, Option<(u32, u32)>)>> = refined
        .par_iter()
        .zip(pieces)
        .map(|((x, _), p)| {
            x.as_ref().map(|x| {
                let q = piece_quality(topo, p, x);
                let pair = (q.overlaps > 0)
                    .then(|| quality::overlapping_pairs(x, &p.triangles).first().copied())
                    .flatten();
                (q, pair)
            })
        })
        .collect();
    let mut refinements = vec![refine::Refinement::default(); pieces.len()];
    let mut apart = vec![None; pieces.len()];
    let mut measured = vec![None; pieces.len()];
    for (k, ((x, mut rf), m)) in refined.into_iter().zip(measures).enumerate() {
        if let (Some(x), Some((q, pair))) = (x, m) {
            apart[k] = pair;
            if q.flipped == 0 && q.overlaps == 0 {
                flats[k] = x;
                rf.kept = true;
                measured[k] = Some(q);
            }
        }
        refinements[k] = rf;
    }
    Ok((refinements, apart, measured))
}

/// The rest-length scales tried in turn until a pelt does not fold; the last (no rest length)
/// cannot fold (`relax::Net::with_rest_scale`).
pub const REST_SCALES: [f32; 3] = [1.0, 0.5, 0.0];

/// The refinement's start: the ladder's last rung (the Tutte embedding on the frame, which cannot
/// fold), solved directly (`tutte`). The refinement's result does not depend on its start in
/// exact arithmetic (LSCM with two pins has one minimiser), but the f32 conjugate gradient stops
/// at a backward error, and from a folded start the error left over is large: on the crumpled
/// sheet the layout refined from its folded eq. 1 pelt had 2.5 % area distortion (the test
/// `developable_sheet_unwraps_to_its_flattening` allows 0.5 % and fails with it), against 0.1 %
/// from Tutte's. The start used to be eq. 1's pelt where it did not fold, Tutte's where
/// it did; eq. 1's pelt folded on every piece of bob subdivided twice, so most of the 12.2 s of
/// dynamics (of 20.7 s in all: `stages_ms.relax` of `decalbake bench --unwrap --mesh
/// assets/bob.glb --subdivide 2` at commit 97235a5; 7.4 s for eq. 1's rung in a one-off timing)
/// was thrown away, and the layouts from the two starts are the same to the last printed digit
/// of that command's quality, pelts and splits. The
/// pelt of eq. 1 (the paper's) is still the layout wherever the refinement is not kept
/// (`one_level`) and with `--refine none`.
pub const START_SCALES: [f32; 1] = [0.0];

/// Pelts the pieces of `sel` (each with its net): all at the first of `scales` at once, then the
/// ones that folded again at the next, and so on; the last scale's pelt is kept whatever it does.
/// Returns, in `sel`'s order, each one's dynamics (its report says the scale it kept) and
/// projection.
fn pelt_without_folds(
    device: Device,
    topo: &Topology,
    sel: &[(&cut::Piece, &relax::Net)],
    scales: &[f32],
    cfg: &SystemCfg,
    timings: &mut Timings,
) -> Result<Vec<(relax::Relaxed, Vec<DVec2>)>> {
    let mut out: Vec<Option<(relax::Relaxed, Vec<DVec2>)>> = vec![None; sel.len()];
    let mut todo: Vec<usize> = (0..sel.len()).collect();
    for (i, &scale) in scales.iter().enumerate() {
        if todo.is_empty() {
            break;
        }
        let t = Instant::now();
        let scaled: Vec<relax::Net> = todo
            .iter()
            .map(|&k| sel[k].1.with_rest_scale(scale))
            .collect();
        let relaxed = if scale == 0.0 {
            tutte::settle(device, &scaled)?
        } else {
            run(device, &scaled, cfg)?
        };
        timings.relax += ms(t);
        let mut again = Vec::new();
        for (&k, mut r) in todo.iter().zip(relaxed) {
            r.rest_scale = scale;
            let flat = oriented(sel[k].0, &r);
            if i + 1 < scales.len() && folds(topo, sel[k].0, &flat) {
                again.push(k);
            } else {
                out[k] = Some((r, flat));
            }
        }
        todo = again;
    }
    Ok(out
        .into_iter()
        .map(|o| o.expect("the last scale keeps every piece"))
        .collect())
}

/// How many times a piece may be split in two, one split after another.
pub const MAX_SPLIT_LEVELS: usize = 10;
/// A pelt whose area distortion's 95th percentile exceeds this is split.
pub const MAX_AREA_P95: f64 = 4.0;

fn piece_quality(topo: &Topology, p: &cut::Piece, flat: &[DVec2]) -> quality::Quality {
    let pos: Vec<glam::DVec3> = p
        .welded
        .iter()
        .map(|&w| topo.positions[w as usize].as_dvec3())
        .collect();
    quality::measure(&pos, flat, &p.triangles)
}

/// Whether a piece's pelt folds: flipped or overlapping triangles.
pub fn folds(topo: &Topology, p: &cut::Piece, flat: &[DVec2]) -> bool {
    let q = piece_quality(topo, p, flat);
    q.flipped > 0 || q.overlaps > 0
}

/// Whether a piece's layout stretches too far ([`MAX_AREA_P95`]), or its conformal refinement
/// folded (`refine_failed`; halves refine more readily than the whole). `known`: the layout's
/// quality, if measured already.
pub fn stretched(
    topo: &Topology,
    p: &cut::Piece,
    flat: &[DVec2],
    refine_failed: bool,
    known: Option<&quality::Quality>,
) -> bool {
    refine_failed
        || known
            .map_or_else(|| piece_quality(topo, p, flat), Clone::clone)
            .area_distortion
            .p95
            > MAX_AREA_P95
}

/// The projection (x, y) of a relaxed piece, mirrored if most of its area came out wound against
/// the mesh (the 3D dynamics may turn a closed piece over).
fn oriented(p: &cut::Piece, r: &relax::Relaxed) -> Vec<DVec2> {
    let mut q: Vec<DVec2> = r.x.iter().map(|x| DVec2::new(x[0], x[1])).collect();
    let signed: f64 = p
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| q[i as usize]);
            (b - a).perp_dot(c - a)
        })
        .sum();
    if signed < 0.0 {
        for v in &mut q {
            v.x = -v.x;
        }
    }
    q
}

/// Turns a flat piece so its bounding box is the smallest of 32 turns over a quarter circle (a
/// box's area repeats every quarter turn), refined by 32 more round the best, so the packing
/// wastes less.
fn upright(q: &[DVec2]) -> Vec<DVec2> {
    let area = |a: f64| {
        let r = DVec2::from_angle(a);
        let (lo, hi) = q.iter().fold((DVec2::MAX, DVec2::MIN), |(lo, hi), p| {
            let p = r.rotate(*p);
            (lo.min(p), hi.max(p))
        });
        (hi - lo).x * (hi - lo).y
    };
    let step = std::f64::consts::FRAC_PI_2 / 32.0;
    let coarse = (0..32)
        .map(|k| k as f64 * step)
        .min_by(|a, b| area(*a).total_cmp(&area(*b)))
        .unwrap_or(0.0);
    // Then 32 turns across the best one's neighbourhood (a box's area is smooth between corners).
    let best = (0..=32)
        .map(|k| coarse + (k as f64 / 16.0 - 1.0) * step)
        .min_by(|a, b| area(*a).total_cmp(&area(*b)))
        .unwrap_or(coarse);
    let r = DVec2::from_angle(best);
    q.iter().map(|p| r.rotate(*p)).collect()
}

/// Packs the flat pieces (every piece at the texel density of its 3D area, turned upright) and
/// flips v to glTF's.
fn place(
    topo: &Topology,
    pieces: &[&cut::Piece],
    flat: &[&[DVec2]],
    opts: &Options,
) -> Vec<Vec<Vec2>> {
    let flat: Vec<Vec<DVec2>> = flat.iter().map(|q| upright(q)).collect();
    let flat = &flat[..];
    let density: Vec<f64> = pieces
        .iter()
        .zip(flat)
        .map(|(p, q)| {
            let (mut a3, mut a2) = (0.0, 0.0);
            for t in &p.triangles {
                let x = t.map(|i| topo.positions[p.welded[i as usize] as usize].as_dvec3());
                a3 += 0.5 * (x[1] - x[0]).cross(x[2] - x[0]).length();
                let y = t.map(|i| q[i as usize]);
                a2 += 0.5 * (y[1] - y[0]).perp_dot(y[2] - y[0]).abs();
            }
            (a3 / a2.max(f64::MIN_POSITIVE)).sqrt()
        })
        .collect();
    let shapes: Vec<pack::Shape> = flat
        .iter()
        .zip(pieces)
        .map(|(q, &p)| pack::Shape {
            points: q,
            triangles: &p.triangles,
        })
        .collect();
    let placed = pack::pack_shapes(&shapes, &density, opts.size, opts.margin);
    flat.iter()
        .enumerate()
        .map(|(i, q)| {
            q.iter()
                .map(|p| {
                    let u = placed.uv(i, *p);
                    Vec2::new(u.x as f32, (1.0 - u.y) as f32)
                })
                .collect()
        })
        .collect()
}

/// The quality of the packed layout over all pieces.
fn measure(topo: &Topology, cut: &cut::Cut, uv: &[Vec<Vec2>]) -> quality::Quality {
    let (mut pos, mut q, mut tris) = (Vec::new(), Vec::new(), Vec::new());
    for (p, u) in cut.pieces.iter().zip(uv) {
        let base = pos.len() as u32;
        pos.extend(
            p.welded
                .iter()
                .map(|&w| topo.positions[w as usize].as_dvec3()),
        );
        // v back up, so the winding reads as the pieces were laid out.
        q.extend(u.iter().map(|v| DVec2::new(v.x as f64, 1.0 - v.y as f64)));
        tris.extend(p.triangles.iter().map(|t| t.map(|i| i + base)));
    }
    quality::measure(&pos, &q, &tris)
}

/// `mesh` with the unwrap's UVs as set `set` (replacing it if it exists, else appended): every
/// split vertex that lands on more than one side of the cut is split again.
pub fn apply(mesh: &Mesh, un: &Unwrapped, set: usize) -> Mesh {
    apply_all(mesh, &[(un, set)]).0
}

/// `mesh` with several layouts' UVs, each as its set (replaced or appended, in order): an output
/// vertex per split vertex and place in every layout. A layout that leaves a triangle out (the
/// patch of `patch`) gives its corners (0, 0). Also returns each output vertex's split vertex.
pub fn apply_all(mesh: &Mesh, layouts: &[(&Unwrapped, usize)]) -> (Mesh, Vec<u32>) {
    let mut out = mesh.clone();
    let mut seen: std::collections::HashMap<Vec<u32>, u32> = Default::default();
    let mut new_uv: Vec<Vec<Vec2>> = vec![Vec::new(); layouts.len()];
    let mut remap: Vec<u32> = Vec::new();
    for (t, tri) in mesh.triangles.iter().enumerate() {
        let places: Vec<Option<(u32, [u32; 3])>> = layouts
            .iter()
            .map(|(un, _)| {
                un.cut.triangle_piece[t]
                    .map(|(p, lt)| (p, un.cut.pieces[p as usize].triangles[lt as usize]))
            })
            .collect();
        // Degenerate triangles (in no layout) keep vertices of their own.
        let alone = places.iter().all(Option::is_none);
        for k in 0..3 {
            let mut key = vec![tri[k]];
            for p in &places {
                key.extend(p.map_or([u32::MAX; 2], |(p, l)| [p, l[k]]));
            }
            if alone {
                key.push(t as u32);
            }
            let id = *seen.entry(key).or_insert_with(|| {
                remap.push(tri[k]);
                for (i, p) in places.iter().enumerate() {
                    new_uv[i].push(p.map_or(Vec2::ZERO, |(p, l)| {
                        layouts[i].0.uv[p as usize][l[k] as usize]
                    }));
                }
                remap.len() as u32 - 1
            });
            out.triangles[t][k] = id;
        }
    }
    out.positions = remap.iter().map(|&o| mesh.positions[o as usize]).collect();
    out.normals = remap.iter().map(|&o| mesh.normals[o as usize]).collect();
    if mesh.tangents.len() == mesh.positions.len() {
        out.tangents = remap.iter().map(|&o| mesh.tangents[o as usize]).collect();
    }
    out.uv_sets = mesh
        .uv_sets
        .iter()
        .map(|s| remap.iter().map(|&o| s[o as usize]).collect())
        .collect();
    if mesh.blend.len() == mesh.positions.len() {
        out.blend = remap.iter().map(|&o| mesh.blend[o as usize]).collect();
    }
    if mesh.bridge.len() == mesh.positions.len() {
        out.bridge = remap.iter().map(|&o| mesh.bridge[o as usize]).collect();
    }
    for ((_, set), uv) in layouts.iter().zip(new_uv) {
        if *set < out.uv_sets.len() {
            out.uv_sets[*set] = uv;
        } else {
            out.uv_sets.push(uv);
        }
        if !out.new_uv_sets.contains(set) {
            out.new_uv_sets.push(*set);
        }
    }
    // Each output vertex's vertex as the document has it, for the writer (`Mesh::vertex_origin`).
    out.vertex_origin = remap
        .iter()
        .map(|&o| mesh.vertex_origin.get(o as usize).copied().unwrap_or(o))
        .collect();
    (out, remap)
}
