// SPDX-License-Identifier: MIT OR Apache-2.0
//! The patch and its blend function (Piponi & Borshukov §5, `decalbake unwrap --patch`).
//!
//! The pelt's texture coordinates are arbitrary at the cut, so a texture painted on the pelt shows
//! a seam there. §5 hides it with a second chart: C0 is the cut, C_n the ring of vertices n edges
//! from it (here: hop distance along the welded edges); the **patch** is the region inside C4
//! (every triangle whose corners are all within 4 edges of the cut, and what that band encloses),
//! pelted on its own into a second UV set; the **blend function** b0 (the pelt's weight) is 0 up to C2 and 1 from C3 on,
//! interpolated across the triangles between (per vertex here, so linear across them), and
//! b1 = 1 − b0 is the patch's. Rendering `b0 · pelt texture + b1 · patch texture` has no seam: at
//! the cut only the patch is seen, and the patch is continuous there.
//!
//! The patch must itself be a disk where it is used: the band round a cut that is a tree is one,
//! but round seams with cycles (a handle's loops) it is not. Then the band is cut across once per
//! cycle, and a third chart, the bridges, hides those cuts where the patch is shown (`bridge`:
//! the arcs, the bridges and the three weights). `--patch` pelts the model without splits (the
//! borders between split pelts would be cycles everywhere).

use super::cut::CutSpec;
use super::{layout, split, Device, Options, Unwrapped};
use crate::error::{Error, Result};
use crate::mesh::Topology;
use std::collections::VecDeque;
use std::path::Path;

/// The patch reaches this many rings from the cut (the paper's C4).
pub const RINGS: u32 = 4;
/// The pelt's weight is 0 up to this ring (C2) and 1 beyond (from C3 on).
pub const BLEND_ZERO_TO: u32 = 2;

/// The patch of a layout.
#[derive(Debug, Clone)]
pub struct Patch {
    /// The patch's own layout (its pieces cover only the patch's triangles).
    pub layout: Unwrapped,
    /// Per welded vertex: edges from the cut (`u32::MAX` beyond the patch).
    pub rings: Vec<u32>,
    /// Per welded vertex: the pelt's weight: b0 (0 or 1), times 1 − w where there are bridges
    /// (the patch's is 1 − blend − w).
    pub blend: Vec<f32>,
    /// The bridges over the patch's own seams, when the pelt's seams have cycles.
    pub bridges: Option<super::bridge::Bridges>,
}

/// Hop distances from `sources` along the welded edges, up to `limit` (beyond: `u32::MAX`).
pub fn rings(topo: &Topology, sources: &[u32], limit: u32) -> Vec<u32> {
    let mut d = vec![u32::MAX; topo.positions.len()];
    let mut queue = VecDeque::new();
    for &s in sources {
        d[s as usize] = 0;
        queue.push_back(s);
    }
    while let Some(v) = queue.pop_front() {
        if d[v as usize] >= limit {
            continue;
        }
        let (a, b) = (
            topo.adjacency_offsets[v as usize] as usize,
            topo.adjacency_offsets[v as usize + 1] as usize,
        );
        for &w in &topo.adjacency[a..b] {
            if d[w as usize] == u32::MAX {
                d[w as usize] = d[v as usize] + 1;
                queue.push_back(w);
            }
        }
    }
    d
}

/// The region inside C4 (§5: "the loop ... going around C3 containing the smallest area"): the
/// band's triangles and every part of the rest that the band encloses, that is all but the largest
/// connected part outside it. Where two branches of the cut pass within eight edges of each other
/// the band closes round the surface between them (Spot's cut through its tips: two such holes),
/// and the patch must cover those too to be a disk.
fn enclosed(topo: &Topology, in_band: &[bool]) -> Vec<u32> {
    let n = in_band.len();
    let mut part = vec![u32::MAX; n];
    let mut sizes = Vec::new();
    for start in 0..n {
        if in_band[start] || topo.degenerate[start] || part[start] != u32::MAX {
            continue;
        }
        let id = sizes.len() as u32;
        let (mut stack, mut count) = (vec![start], 0usize);
        part[start] = id;
        while let Some(t) = stack.pop() {
            count += 1;
            for &u in &topo.triangle_neighbors[t] {
                let u = u as usize;
                if u < n && !in_band[u] && !topo.degenerate[u] && part[u] == u32::MAX {
                    part[u] = id;
                    stack.push(u);
                }
            }
        }
        sizes.push(count);
    }
    let outside = (0..sizes.len()).max_by_key(|&i| sizes[i]).map(|i| i as u32);
    (0..n as u32)
        .filter(|&t| {
            let t = t as usize;
            !topo.degenerate[t] && (in_band[t] || Some(part[t]) != outside)
        })
        .collect()
}

/// The patch of `main` (its cut's opened edges are C0), laid out with `opts` (no splits).
pub fn patch(
    device: Device,
    topo: &Topology,
    main: &Unwrapped,
    opts: &Options,
    path: &Path,
) -> Result<Patch> {
    let mut seam: Vec<u32> = main.cut.edges.iter().flatten().copied().collect();
    seam.sort_unstable();
    seam.dedup();
    if seam.is_empty() {
        return Err(Error::mesh(
            path,
            "--patch: the layout has no seams (the model is a disk as it is), so there is nothing for a patch to hide; leave --patch out",
        ));
    }
    let d = rings(topo, &seam, RINGS + 1);
    let in_band: Vec<bool> = (0..topo.triangles.len())
        .map(|t| !topo.degenerate[t] && topo.triangles[t].iter().all(|&v| d[v as usize] <= RINGS))
        .collect();
    let tris = enclosed(topo, &in_band);
    let no_splits = Options {
        max_split_levels: 0,
        ..opts.clone()
    };
    let whole = CutSpec::Edges(Vec::new());
    let (pieces, bridges) =
        match split::cut_region_with(topo, &tris, &whole, opts.split_non_manifold, &[], path) {
            Ok(pieces) => (pieces, None),
            Err(first) => {
                // Seams with cycles: the band is opened by arcs, and bridges hide them.
                let (arcs, count, pieces) =
                    open_band(topo, &tris, &main.cut.edges, opts, path, first)?;
                let mut near: Vec<u32> = arcs
                    .iter()
                    .flatten()
                    .copied()
                    .filter(|&v| d[v as usize] <= BLEND_ZERO_TO + 1)
                    .collect();
                near.sort_unstable();
                near.dedup();
                let e = rings(topo, &near, super::bridge::RINGS + 1);
                let b = super::bridge::bridges(device, topo, (arcs, count), &e, &no_splits, path)?;
                (pieces, Some(b))
            }
        };
    let layout = layout(
        device,
        topo,
        pieces,
        super::Prior::default(),
        &no_splits,
        path,
    )?;
    let blend = d
        .iter()
        .enumerate()
        .map(|(v, &r)| {
            let b0 = if r <= BLEND_ZERO_TO { 0.0 } else { 1.0 };
            b0 * (1.0 - bridges.as_ref().map_or(0.0, |b| b.weight[v]))
        })
        .collect();
    Ok(Patch {
        layout,
        rings: d,
        blend,
        bridges,
    })
}

/// The band `tris` cut by as many of `bridge::arcs` as it takes to make it disks (in their order):
/// the arcs' edges, how many arcs, and the pieces. `first` is why the band uncut is not disks: the
/// error when no arc is found (then the seams have no cycles, and something else is wrong: a
/// non-manifold edge, say).
fn open_band(
    topo: &Topology,
    tris: &[u32],
    seam: &[[u32; 2]],
    opts: &Options,
    path: &Path,
    first: Error,
) -> Result<(Vec<[u32; 2]>, usize, Vec<super::cut::Piece>)> {
    let arcs = super::bridge::arcs(topo, seam, tris);
    if arcs.is_empty() {
        return Err(first);
    }
    let mut used = Vec::new();
    let mut last = first;
    for (k, arc) in arcs.into_iter().enumerate() {
        used.extend(arc);
        let spec = CutSpec::Edges(used.clone());
        match split::cut_region_with(topo, tris, &spec, opts.split_non_manifold, &[], path) {
            Ok(pieces) => return Ok((used, k + 1, pieces)),
            Err(e) => last = e,
        }
    }
    Err(not_disks(path, last))
}

/// The error for a band that the arcs did not open into disks.
fn not_disks(path: &Path, e: Error) -> Error {
    Error::mesh(
        path,
        format!(
            "--patch: the band within {RINGS} edges of the seams is not made of disks, even cut across once per cycle of the seams ({e}); the model's seams run too close to each other or to its boundary for a patch: leave --patch out, or cut the model into genus-0 parts"
        ),
    )
}
