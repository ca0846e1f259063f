// SPDX-License-Identifier: MIT OR Apache-2.0
//! The harmonic repair of a ribbon's highly curved parts (Sun et al. 2013, section 3, steps 4-5).
//!
//! Where γ turns tighter than its strip is wide, the offsets on the turn's inside shrink to nothing
//! and the extended exponential map folds there (its u runs backwards). Step 4 finds such parts:
//! at each piece p of γ the ratio r = |u_s − u_t| / l(o_s, o_t) compares a stretch of γ
//! (s, t = p's arc length ∓ d) with the stretch of the strip's outer offset beside it. The paper
//! traces l on the mesh; here it is the offset's length on a developable surface,
//! l = ∫ (1 − κ_g h) du over the window (h the strip's reach on that side, κ_g γ's turning per
//! length, positive towards the left), so r = 1 / (1 ∓ κ̄ h) with κ̄ the window's mean turning
//! ([`curved_parts`]; d = the strip's wider side). Pieces with r outside [1 − λ, 1 + λ] on either
//! side are curved (λ = the layer's `curved_threshold`, 0.2 by default; an offset that collapses,
//! 1 − κ̄ h ≤ 0, is curved at any λ); each run of curved pieces, widened by d at both ends, is a part
//! to repair.
//!
//! Step 5 re-solves the part's (u, v) as a harmonic map onto a rectangle ([`repair`]): the region
//! M is the reached vertices whose u lies in the part's range, a disk whose boundary loop runs
//! along the map's lateral ends (where M meets the rest of the strip: those vertices keep their
//! values, so the repaired part joins the map without a seam) and its outer edges (where the map's
//! reach ends, beyond the strip itself: v keeps the geodesic distance, u keeps the map's value where
//! it runs monotonically along the edge and is spread by arc length across the stretches where it
//! does not, the paper's arc-length boundary condition; `outer_values`). Inside, u and v are harmonic with
//! cotangent weights clamped to at least [`MIN_WEIGHT`] (positive weights make the map onto a
//! convex domain one-to-one, Floater's form of the Radó theorem the paper cites; plain cotangent
//! weights can be negative on obtuse triangles). The two systems are one SPD matrix solved by the
//! GPU conjugate gradient (or its f64 twin, [`crate::solve::cg::pcg`]).

use super::{Curve, Framed};
use crate::mesh::Topology;
use crate::solve::sparse::Csr;
use std::collections::HashMap;

/// The smallest edge weight of the repair's Laplacian (cotangent weights are dimensionless).
pub const MIN_WEIGHT: f64 = 0.01;

/// The default `curved_threshold` (the paper's λ).
pub const DEFAULT_LAMBDA: f32 = 0.2;

/// The parts of `curve` (arc-length ranges) the repair re-solves, for a strip reaching
/// `sides` = [left, right] from γ and threshold `lambda`.
pub fn curved_parts(topo: &Topology, curve: &Curve, sides: [f32; 2], lambda: f32) -> Vec<[f32; 2]> {
    let d = sides[0].max(sides[1]).max(1e-12);
    let framed = Framed::new(topo, curve, d);
    let n = framed.pieces.len();
    if n < 2 {
        return Vec::new();
    }
    // Turning at each knot (towards B positive) and its arc length: the cumulative turning Φ(s).
    let knots: Vec<(f32, f32)> = framed
        .pieces
        .windows(2)
        .map(|w| (w[1].arc, w[1].t.dot(w[0].b).atan2(w[1].t.dot(w[0].t))))
        .collect();
    let turning = |a: f32, b: f32| -> f32 {
        knots
            .iter()
            .filter(|(s, _)| *s > a && *s <= b)
            .map(|k| k.1)
            .sum()
    };
    let curved: Vec<bool> = framed
        .pieces
        .iter()
        .map(|p| {
            let mid = p.arc + 0.5 * p.len;
            let (a, b) = ((mid - d).max(0.0), (mid + d).min(framed.length));
            let kappa = turning(a, b) / (b - a).max(1e-12);
            let ratio = |h: f32, sign: f32| {
                let den = 1.0 - sign * kappa * h;
                if den <= 0.0 {
                    f32::INFINITY
                } else {
                    1.0 / den
                }
            };
            [(sides[0], 1.0), (sides[1], -1.0)]
                .iter()
                .any(|&(h, sign)| h > 0.0 && (ratio(h, sign) - 1.0).abs() > lambda)
        })
        .collect();
    let mut parts: Vec<[f32; 2]> = Vec::new();
    for (k, p) in framed.pieces.iter().enumerate() {
        if !curved[k] {
            continue;
        }
        let range = [(p.arc - d).max(0.0), (p.arc + p.len + d).min(framed.length)];
        match parts.last_mut() {
            Some(last) if range[0] <= last[1] => last[1] = last[1].max(range[1]),
            _ => parts.push(range),
        }
    }
    parts
}

/// The repair's linear system for one part: unknown vertices and the two right-hand sides.
pub struct RepairSystem {
    /// The unknowns' welded ids.
    pub unknowns: Vec<u32>,
    /// The Laplacian over the unknowns (SPD).
    pub a: Csr,
    /// Right-hand sides for u and v.
    pub b: [Vec<f64>; 2],
    /// Boundary vertices and the (u, v) they are held at.
    pub fixed: Vec<(u32, [f64; 2])>,
}

/// The system of the part `range` of a map given as (u, v) per welded vertex (`None` where not
/// reached); `None` when the part's region is not a disk with lateral ends (nothing to repair
/// against).
pub fn system(
    topo: &Topology,
    uv: &[Option<[f32; 2]>],
    range: [f32; 2],
    full: bool,
) -> Option<RepairSystem> {
    let n = topo.positions.len();
    let inside: Vec<bool> = uv
        .iter()
        .map(|c| c.is_some_and(|c| c[0] >= range[0] && c[0] <= range[1]))
        .collect();
    let tris: Vec<[u32; 3]> = topo
        .triangles
        .iter()
        .copied()
        .filter(|t| t.iter().all(|&v| inside[v as usize]))
        .collect();
    let lp = boundary_loop(&tris)?;
    let mut border = vec![false; n];
    for e in &topo.boundary_edges {
        e.iter().for_each(|&v| border[v as usize] = true);
    }
    // Lateral: every neighbour reached (the map goes on past M); outer: the map's reach ends here.
    let lateral = |v: u32| {
        let (a, b) = (
            topo.adjacency_offsets[v as usize] as usize,
            topo.adjacency_offsets[v as usize + 1] as usize,
        );
        !border[v as usize]
            && topo.adjacency[a..b]
                .iter()
                .all(|&w| uv[w as usize].is_some())
    };
    let is_lat: Vec<bool> = lp.iter().map(|&v| lateral(v)).collect();
    let first = is_lat.iter().position(|&l| l)?;
    if is_lat.iter().all(|&l| l) {
        return None;
    }
    let mut fixed: HashMap<u32, [f64; 2]> = HashMap::new();
    let at = |v: u32| uv[v as usize].expect("M is reached").map(f64::from);
    // Walk the loop from a lateral vertex; each run of outer vertices gets u by arc length between
    // the lateral u at its two ends.
    let m = lp.len();
    let mut k = 0;
    while k < m {
        let i = (first + k) % m;
        if is_lat[i] {
            fixed.insert(lp[i], at(lp[i]));
            k += 1;
            continue;
        }
        let start = (i + m - 1) % m;
        let mut run = vec![start];
        while !is_lat[(first + k) % m] {
            run.push((first + k) % m);
            k += 1;
        }
        run.push((first + k) % m);
        let pos = |j: usize| topo.positions[lp[run[j]] as usize];
        let cum: Vec<f64> = std::iter::once(0.0)
            .chain((1..run.len()).scan(0.0, |s, j| {
                *s += (pos(j) - pos(j - 1)).length() as f64;
                Some(*s)
            }))
            .collect();
        let values: Vec<[f64; 2]> = run.iter().map(|&j| at(lp[j])).collect();
        let held = match full {
            false => outer_values(&values, &cum),
            true => rectangle_side(&values, &cum),
        };
        for (j, val) in held.into_iter().enumerate().skip(1) {
            if j + 1 < run.len() {
                fixed.insert(lp[run[j]], val);
            }
        }
    }
    let mut index = vec![u32::MAX; n];
    let mut unknowns = Vec::new();
    for t in &tris {
        for &v in t {
            if index[v as usize] == u32::MAX && !fixed.contains_key(&v) {
                index[v as usize] = unknowns.len() as u32;
                unknowns.push(v);
            }
        }
    }
    let weights = cot_weights(topo, &tris);
    let mut diag = vec![0.0f64; unknowns.len()];
    let mut b = [vec![0.0f64; unknowns.len()], vec![0.0f64; unknowns.len()]];
    let mut t = Vec::new();
    for (&(p, q), &w) in &weights {
        for (x, y) in [(p, q), (q, p)] {
            let r = index[x as usize];
            if r == u32::MAX {
                continue;
            }
            diag[r as usize] += w;
            match fixed.get(&y) {
                Some(f) => (0..2).for_each(|c| b[c][r as usize] += w * f[c]),
                None => t.push((r, index[y as usize], -w)),
            }
        }
    }
    t.extend(
        diag.iter()
            .enumerate()
            .map(|(r, &d)| (r as u32, r as u32, d)),
    );
    Some(RepairSystem {
        a: Csr::from_triplets(unknowns.len(), t),
        b,
        unknowns,
        fixed: fixed.into_iter().collect(),
    })
}

/// The values an outer run of the region's boundary is held at (`values`: the map's, from one
/// lateral end to the other; `cum`: arc length along the run). Where the map's u runs monotonically
/// from one end's u to the other's it is kept (the repair then leaves a good map as it is); across
/// each stretch where it does not (the fold: u runs backwards, or past an end's), u is spread by
/// arc length between the good values around it, the paper's arc-length boundary condition. v
/// keeps the map's geodesic distance.
fn outer_values(values: &[[f64; 2]], cum: &[f64]) -> Vec<[f64; 2]> {
    let n = values.len();
    let dir = if values[n - 1][0] >= values[0][0] {
        1.0
    } else {
        -1.0
    };
    let u: Vec<f64> = values.iter().map(|v| dir * v[0]).collect();
    let mut before = vec![f64::NEG_INFINITY; n];
    let mut after = vec![f64::INFINITY; n];
    for j in 1..n {
        before[j] = before[j - 1].max(u[j - 1]);
        after[n - 1 - j] = after[n - j].min(u[n - j]);
    }
    let good: Vec<bool> = (0..n)
        .map(|j| j == 0 || j == n - 1 || (u[j] > before[j] && u[j] < after[j]))
        .collect();
    let mut out = values.to_vec();
    let mut last = 0;
    for j in 1..n {
        if !good[j] {
            continue;
        }
        for k in last + 1..j {
            let t = (cum[k] - cum[last]) / (cum[j] - cum[last]).max(1e-30);
            out[k][0] = values[last][0] + (values[j][0] - values[last][0]) * t;
        }
        last = j;
    }
    out
}

/// The rectangle's side for the full harmonic map (the paper's boundary condition): u spread by
/// arc length between the lateral ends' u, v one value for the run (its median distance: the
/// vertices where the map's reach stops differ by up to an edge, and a jagged side would not be
/// convex).
fn rectangle_side(values: &[[f64; 2]], cum: &[f64]) -> Vec<[f64; 2]> {
    let n = values.len();
    let (u0, u1, total) = (values[0][0], values[n - 1][0], cum[n - 1].max(1e-30));
    let inner = &values[1..n - 1];
    let side = inner.iter().map(|v| v[1]).sum::<f64>().signum();
    let mut far: Vec<f64> = inner.iter().map(|v| v[1].abs()).collect();
    far.sort_by(f64::total_cmp);
    let v_side = side * far.get(far.len() / 2).copied().unwrap_or(0.0);
    (0..n)
        .map(|j| match j == 0 || j == n - 1 {
            true => values[j],
            false => [u0 + (u1 - u0) * cum[j] / total, v_side],
        })
        .collect()
}

/// Triangles of the region around `range` whose (u, v) are flipped (negative area; the map keeps
/// the surface's orientation).
fn flipped_in(topo: &Topology, uv: &[Option<[f32; 2]>], range: [f32; 2]) -> usize {
    topo.triangles
        .iter()
        .filter(|t| {
            let Some(p) = t
                .iter()
                .map(|&v| uv[v as usize])
                .collect::<Option<Vec<_>>>()
            else {
                return false;
            };
            let inside = p.iter().all(|c| c[0] >= range[0] && c[0] <= range[1]);
            let area = (p[1][0] - p[0][0]) * (p[2][1] - p[0][1])
                - (p[2][0] - p[0][0]) * (p[1][1] - p[0][1]);
            inside && area < 0.0
        })
        .count()
}

/// Half the cotangents of the angles facing each edge of `tris`, summed, at least
/// [`MIN_WEIGHT`]; keyed by (lower, higher) vertex.
fn cot_weights(topo: &Topology, tris: &[[u32; 3]]) -> HashMap<(u32, u32), f64> {
    let mut w: HashMap<(u32, u32), f64> = HashMap::new();
    for t in tris {
        for k in 0..3 {
            let (o, a, b) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
            let p = |v: u32| topo.positions[v as usize].as_dvec3();
            let (ea, eb) = (p(a) - p(o), p(b) - p(o));
            let cot = ea.dot(eb) / ea.cross(eb).length().max(1e-300);
            *w.entry((a.min(b), a.max(b))).or_default() += 0.5 * cot;
        }
    }
    w.values_mut().for_each(|x| *x = x.max(MIN_WEIGHT));
    w
}

/// The boundary loop of the triangle set (vertices in order) when the set is a disk: one
/// connected piece with Euler characteristic 1 whose boundary edges form one closed loop through
/// distinct vertices. `None` otherwise (a region with a hole, two pieces, or a pinch vertex would
/// leave unknowns no boundary value reaches, or a loop the walk cannot follow).
fn boundary_loop(tris: &[[u32; 3]]) -> Option<Vec<u32>> {
    let mut count: HashMap<(u32, u32), u32> = HashMap::new();
    let mut parent: HashMap<u32, u32> = HashMap::new();
    fn root(parent: &mut HashMap<u32, u32>, v: u32) -> u32 {
        let mut r = v;
        while let Some(&p) = parent.get(&r).filter(|&&p| p != r) {
            r = p;
        }
        parent.insert(v, r);
        r
    }
    for t in tris {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            *count.entry((a.min(b), a.max(b))).or_default() += 1;
            parent.entry(a).or_insert(a);
            let (ra, rb) = (root(&mut parent, a), root(&mut parent, b));
            parent.insert(ra, rb);
        }
    }
    let vertices: Vec<u32> = parent.keys().copied().collect();
    let roots: std::collections::HashSet<u32> =
        vertices.iter().map(|&v| root(&mut parent, v)).collect();
    let euler = vertices.len() as i64 - count.len() as i64 + tris.len() as i64;
    if roots.len() != 1 || euler != 1 {
        return None;
    }
    // Directed boundary edges, as the triangles run them; a vertex with two is a pinch.
    let mut next: HashMap<u32, u32> = HashMap::new();
    for t in tris {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            if count[&(a.min(b), a.max(b))] == 1 && next.insert(a, b).is_some() {
                return None;
            }
        }
    }
    let start = *next.keys().min()?;
    let mut lp = vec![start];
    let mut v = next[&start];
    while v != start {
        if lp.len() > next.len() {
            return None;
        }
        lp.push(v);
        v = *next.get(&v)?;
    }
    (lp.len() == next.len()).then_some(lp)
}

/// What a solver of the repair's two systems returns: the solutions of u and v and the CG
/// iterations (the larger of the two).
pub type Solution = crate::error::Result<([Vec<f64>; 2], u32)>;

/// What the repair did to one ribbon.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct RepairReport {
    /// The parts re-solved, as arc-length ranges along γ (model units).
    pub repaired: Vec<[f32; 2]>,
    /// Parts found curved whose region could not be repaired (not a disk with lateral ends: a
    /// strip that meets itself, a hole, two pieces).
    pub skipped: Vec<[f32; 2]>,
    /// Of `repaired`, the parts re-solved as the full harmonic map onto a rectangle (u alone still
    /// folded).
    pub rectangle: Vec<[f32; 2]>,
    /// Vertices of the repaired regions (re-solved, and held on their boundaries).
    pub vertices: u32,
    /// Conjugate-gradient iterations (the larger of the u and v systems, summed over parts).
    pub cg_iterations: u32,
}

/// Repairs `uv` (per welded vertex, `None` where not reached) over `parts`, solving each part's
/// systems with `solve` (matrix, right-hand sides → solutions and iterations). Each part is first
/// re-solved in u alone, its outer edges keeping the map's values where they run monotonically
/// ([`system`] with `full` false): v is the geodesic distance, which does not fold, and a part
/// that only crossed the threshold λ without folding keeps its map but for the discretisation of
/// u. Where triangles of the part are still flipped, the part is re-solved as the full harmonic
/// map onto the rectangle (`full`: u and v, straight sides, u by arc length along them).
pub fn repair(
    topo: &Topology,
    uv: &mut [Option<[f32; 2]>],
    parts: &[[f32; 2]],
    mut solve: impl FnMut(&Csr, &[Vec<f64>; 2]) -> Solution,
) -> crate::error::Result<RepairReport> {
    let mut report = RepairReport::default();
    for &range in parts {
        let Some(sys) = system(topo, uv, range, false) else {
            report.skipped.push(range);
            continue;
        };
        let mut trial = uv.to_vec();
        let ([u, _], iters) = solve(&sys.a, &sys.b)?;
        apply(&mut trial, &sys, &u, None);
        report.cg_iterations += iters;
        let mut count = sys.unknowns.len() + sys.fixed.len();
        if flipped_in(topo, &trial, range) > 0 {
            if let Some(full) = system(topo, uv, range, true) {
                let ([u, v], iters) = solve(&full.a, &full.b)?;
                trial = uv.to_vec();
                apply(&mut trial, &full, &u, Some(&v));
                report.cg_iterations += iters;
                report.rectangle.push(range);
                count = full.unknowns.len() + full.fixed.len();
            }
        }
        uv.copy_from_slice(&trial);
        report.repaired.push(range);
        report.vertices += count as u32;
    }
    Ok(report)
}

/// [`repair`] on a slot of coordinates (x, y, distance, valid per welded vertex: the map's u, v
/// through `xform` = (a, b, c, d), x = a u + b, y = c v + d), for a curve whose strip reaches `sides`
/// with threshold `lambda`: what the bake's ribbon pass, `decalbake param` and `decalbake extract`
/// share. Leaves `coords` as they are when no part is curved.
pub fn repair_coords(
    topo: &Topology,
    (curve, sides, lambda): (&Curve, [f32; 2], f32),
    coords: &mut [[f32; 4]],
    xform: [f32; 4],
    solve: impl FnMut(&Csr, &[Vec<f64>; 2]) -> Solution,
) -> crate::error::Result<RepairReport> {
    let parts = curved_parts(topo, curve, sides, lambda);
    if parts.is_empty() {
        return Ok(RepairReport::default());
    }
    let [a, b, c, d] = xform;
    let mut uv: Vec<Option<[f32; 2]>> = coords
        .iter()
        .map(|x| (x[3] > 0.5).then(|| [(x[0] - b) / a, (x[1] - d) / c]))
        .collect();
    let report = repair(topo, &mut uv, &parts, solve)?;
    for (x, m) in coords.iter_mut().zip(&uv) {
        if let Some([u, v]) = m {
            (x[0], x[1]) = (a * u + b, c * v + d);
        }
    }
    Ok(report)
}

/// Writes a solved system into `uv`: the unknowns' u (and v when given), the boundary's held values.
fn apply(uv: &mut [Option<[f32; 2]>], sys: &RepairSystem, u: &[f64], v: Option<&[f64]>) {
    for (k, &q) in sys.unknowns.iter().enumerate() {
        let old = uv[q as usize].expect("reached");
        uv[q as usize] = Some([u[k] as f32, v.map_or(old[1], |v| v[k] as f32)]);
    }
    for &(q, f) in &sys.fixed {
        uv[q as usize] = Some([f[0] as f32, f[1] as f32]);
    }
}

/// The CPU twin's solver for [`repair`]: f64 PCG on both right-hand sides.
pub fn solve_cpu(a: &Csr, b: &[Vec<f64>; 2]) -> Solution {
    let mut iters = 0;
    let x = [0, 1].map(|c| {
        let mut x = vec![0.0; a.rows];
        let rep = crate::solve::cg::pcg(a, &b[c], &mut x, 1e-7, 20 * a.rows as u32 + 100);
        iters = iters.max(rep.iterations);
        x
    });
    Ok((x, iters))
}

/// The GPU solver for [`repair`]: both right-hand sides as one block-diagonal batch of the GPU
/// conjugate gradient ([`crate::solve::gpu::cg_batched`]).
pub fn solve_gpu<'a>(
    ctx: &'a crate::gpu::GpuContext,
    pipes: &'a crate::gpu::pipelines::Pipelines,
) -> impl FnMut(&Csr, &[Vec<f64>; 2]) -> Solution + 'a {
    move |a, b| {
        use crate::solve::gpu::{cg_batched, SystemDesc};
        if a.rows == 0 {
            return Ok(([Vec::new(), Vec::new()], 0));
        }
        let (big, starts) = Csr::block_diagonal(&[a, a]);
        let rhs: Vec<f64> = b[0].iter().chain(&b[1]).copied().collect();
        let x0 = vec![0.0; rhs.len()];
        let descs: Vec<SystemDesc> = starts
            .iter()
            .map(|&r0| SystemDesc::new(r0, a.rows, 1e-6, 20 * a.rows as u32 + 100))
            .collect();
        let out = cg_batched(ctx, pipes, &big, &rhs, &x0, &descs)?;
        let iters = out.reports.iter().map(|r| r.iterations).max().unwrap_or(0);
        let x = [0, 1].map(|c| {
            out.x[starts[c]..starts[c] + a.rows]
                .iter()
                .map(|&v| v as f64)
                .collect()
        });
        Ok((x, iters))
    }
}
