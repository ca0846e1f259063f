// SPDX-License-Identifier: MIT OR Apache-2.0
//! The patch for seams with cycles: arcs that open the band into a disk, and the bridges, a third
//! chart that hides the patch's own seams (an extension of Piponi & Borshukov §5).
//!
//! §5's patch is a disk when the pelt's seams form a tree. On a model with handles the seams of
//! one pelt have cycles (a torus's cut is two loops that meet), and the band round them is not a
//! disk: round a torus's two loops it is a torus with one hole. It becomes one when it is cut
//! across once per independent cycle of the seam graph, which is what `arcs` does: it takes a
//! spanning forest of the seam graph built from the edges nearest its branch points first, so the
//! edges left out (one per cycle) lie as far from the branches as the cycle allows, and through
//! one end of each it cuts the band with the shortest path on either side of the seam to the
//! band's boundary (Dijkstra on edge lengths, never touching the seams or an earlier arc). A hole
//! of the model that the band closes round (a boundary loop wholly inside it: the rim of a thin
//! tube, a teapot spout's tip) makes the band an annulus the same way; the loop counts as a cycle,
//! and its arc runs from the loop's vertex farthest from the seams out to the band's edge or another
//! hole. The patch is then pelted with as many of those arcs as it takes to make it disks.
//!
//! An arc is a seam of the patch, and the patch is shown round the pelt's seams, so the arcs would
//! show where they cross the band. A **bridge** hides them as the patch hides the pelt's seams: S
//! is every arc vertex within C3 of the pelt's seams (where the patch can be shown), E_n the ring
//! of vertices n edges from S; each bridge is the region inside E4 (a thickened piece of an arc:
//! a disk), pelted on its own into a third set, with weight w = 1 up to E1, ½ on E2 and 0 from E3
//! on. The three weights are then w for the bridge, (1 − w) b0 for the pelt and (1 − w)(1 − b0)
//! for the patch (b0 the pelt's §5 weight): a partition of unity, with every chart's weight 0 on
//! the triangles that touch its seams: the pelt's (b0 = 0 within 2 edges of them), the patch's
//! (w = 1 within an edge of an arc where b0 < 1; beyond C3 b0 = 1) and the bridge's own boundary
//! (w = 0 from E3 on).

use super::cut::CutSpec;
use super::{layout, split, Device, Options, Unwrapped};
use crate::error::{Error, Result};
use crate::mesh::Topology;
use std::cmp::Reverse;
use std::collections::{BinaryHeap, HashSet, VecDeque};
use std::path::Path;

/// The bridges reach this many rings from their arcs (their boundary, E4).
pub const RINGS: u32 = 4;

/// The bridges of a patch.
#[derive(Debug, Clone)]
pub struct Bridges {
    /// The edges of the arcs the patch was cut along (welded vertex pairs).
    pub arcs: Vec<[u32; 2]>,
    /// How many arcs they make.
    pub arc_count: usize,
    /// The bridges' layout (their pieces cover only the bridges' triangles).
    pub layout: Unwrapped,
    /// Per welded vertex: w, the bridges' weight (1 up to E1, ½ on E2, 0 beyond).
    pub weight: Vec<f32>,
}

/// A vertex set's adjacency restricted to the triangles `tris`, and which of its vertices lie on
/// the region's boundary (an edge with one region triangle) or the mesh's.
struct Region {
    neighbours: Vec<Vec<u32>>,
    boundary: Vec<bool>,
}

impl Region {
    fn new(topo: &Topology, tris: &[u32]) -> Self {
        let n = topo.positions.len();
        let mut edge_count: std::collections::HashMap<(u32, u32), u32> = Default::default();
        let mut neighbours = vec![Vec::new(); n];
        for &t in tris {
            let tri = topo.triangles[t as usize];
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                *edge_count.entry((a.min(b), a.max(b))).or_default() += 1;
                neighbours[a as usize].push(b);
                neighbours[b as usize].push(a);
            }
        }
        for l in &mut neighbours {
            l.sort_unstable();
            l.dedup();
        }
        let mut boundary = vec![false; n];
        for (&(a, b), &c) in &edge_count {
            if c == 1 {
                boundary[a as usize] = true;
                boundary[b as usize] = true;
            }
        }
        Self {
            neighbours,
            boundary,
        }
    }
}

/// The seam edges left out of a spanning forest of the seam graph that takes the edges nearest
/// the graph's branch points and ends first: one per independent cycle, each as far from the
/// branches as its cycle allows. Returns (edge, the end of it farther from a branch).
fn cycle_edges(n: usize, seam: &[[u32; 2]]) -> Vec<([u32; 2], u32)> {
    let mut degree = vec![0u32; n];
    let mut adj = vec![Vec::new(); n];
    for &[a, b] in seam {
        degree[a as usize] += 1;
        degree[b as usize] += 1;
        adj[a as usize].push(b);
        adj[b as usize].push(a);
    }
    // Hops along the seams from the nearest vertex whose seam degree is not 2.
    let mut hops = vec![u32::MAX; n];
    let mut queue: VecDeque<u32> = (0..n as u32)
        .filter(|&v| degree[v as usize] != 0 && degree[v as usize] != 2)
        .collect();
    for &v in &queue {
        hops[v as usize] = 0;
    }
    while let Some(v) = queue.pop_front() {
        for &w in &adj[v as usize] {
            if hops[w as usize] == u32::MAX {
                hops[w as usize] = hops[v as usize] + 1;
                queue.push_back(w);
            }
        }
    }
    let mut order: Vec<[u32; 2]> = seam.to_vec();
    order.sort_by_key(|&[a, b]| (hops[a as usize].min(hops[b as usize]), a, b));
    let mut parent: Vec<u32> = (0..n as u32).collect();
    fn root(parent: &mut [u32], mut v: u32) -> u32 {
        while parent[v as usize] != v {
            parent[v as usize] = parent[parent[v as usize] as usize];
            v = parent[v as usize];
        }
        v
    }
    let mut left_out = Vec::new();
    for [a, b] in order {
        let (ra, rb) = (root(&mut parent, a), root(&mut parent, b));
        if ra == rb {
            let far = if hops[a as usize] >= hops[b as usize] {
                a
            } else {
                b
            };
            left_out.push(([a, b], far));
        } else {
            parent[ra as usize] = rb;
        }
    }
    left_out
}

/// The sides of the seams at `pivot`: its region triangles grouped across the edges from it that
/// are not seam edges (`cut`), each group's other vertices that are not on the seams.
fn sides(
    topo: &Topology,
    tris_of: &[Vec<u32>],
    cut: &HashSet<(u32, u32)>,
    on_seam: &[bool],
    pivot: u32,
) -> Vec<Vec<u32>> {
    let fan = &tris_of[pivot as usize];
    let mut group: Vec<usize> = (0..fan.len()).collect();
    let others = |t: u32| {
        topo.triangles[t as usize]
            .into_iter()
            .filter(move |&v| v != pivot)
    };
    // Two fan triangles are on one side when they share an edge from the pivot that is no seam.
    for i in 0..fan.len() {
        for j in i + 1..fan.len() {
            let shared = others(fan[i]).find(|&v| others(fan[j]).any(|w| w == v));
            if shared.is_some_and(|v| !cut.contains(&(pivot.min(v), pivot.max(v)))) {
                let (gi, gj) = (group[i], group[j]);
                for g in &mut group {
                    if *g == gj {
                        *g = gi;
                    }
                }
            }
        }
    }
    let mut ids: Vec<usize> = group.clone();
    ids.sort_unstable();
    ids.dedup();
    ids.iter()
        .map(|&g| {
            let mut vs: Vec<u32> = (0..fan.len())
                .filter(|&i| group[i] == g)
                .flat_map(|i| others(fan[i]))
                .filter(|&v| !on_seam[v as usize])
                .collect();
            vs.sort_unstable();
            vs.dedup();
            vs
        })
        .collect()
}

/// The shortest path (edge lengths) from `pivot` through one of `starts` to the region's
/// boundary, avoiding `blocked`; the path from the pivot's neighbour to the boundary vertex.
fn to_boundary(
    topo: &Topology,
    region: &Region,
    blocked: &[bool],
    pivot: u32,
    starts: &[u32],
) -> Option<Vec<u32>> {
    let n = topo.positions.len();
    let len =
        |a: u32, b: u32| (topo.positions[a as usize] - topo.positions[b as usize]).length() as f64;
    let mut dist = vec![f64::INFINITY; n];
    let mut prev = vec![u32::MAX; n];
    let mut heap = BinaryHeap::new();
    for &s in starts {
        if !blocked[s as usize] {
            dist[s as usize] = len(pivot, s);
            heap.push(Reverse((dist[s as usize].to_bits(), s)));
        }
    }
    while let Some(Reverse((d, v))) = heap.pop() {
        if f64::from_bits(d) > dist[v as usize] {
            continue;
        }
        if region.boundary[v as usize] {
            let mut path = vec![v];
            while prev[*path.last()? as usize] != u32::MAX {
                path.push(prev[*path.last()? as usize]);
            }
            path.reverse();
            return Some(path);
        }
        for &w in &region.neighbours[v as usize] {
            let nd = dist[v as usize] + len(v, w);
            if !blocked[w as usize] && nd < dist[w as usize] {
                dist[w as usize] = nd;
                prev[w as usize] = v;
                heap.push(Reverse((nd.to_bits(), w)));
            }
        }
    }
    None
}

/// The arcs that open the patch region `tris` round the pelt's opened edges `seam`: one per
/// independent cycle of the seams, together with the model's boundary loops that lie wholly in the
/// region (a hole the band closes round, as at the tip of a teapot's spout: the band is then an
/// annulus). A cycle through the seams is cut from the region's boundary on one side of the seam,
/// through it, to the boundary on the other; a hole's loop from the loop's vertex farthest from
/// where the seams meet it out to the region's boundary. A cycle whose other side the band encloses
/// (no boundary to reach) gets no arc: the region is a disk there already. Each arc as welded
/// vertex pairs, in the order found; `patch` takes as many as the region needs to become disks
/// (a tube the band wraps whole needs one arc between its two rims, not one from each).
pub fn arcs(topo: &Topology, seam: &[[u32; 2]], tris: &[u32]) -> Vec<Vec<[u32; 2]>> {
    let n = topo.positions.len();
    let mut tris_of = vec![Vec::new(); n];
    for &t in tris {
        for v in topo.triangles[t as usize] {
            tris_of[v as usize].push(t);
        }
    }
    let in_region: Vec<bool> = tris_of.iter().map(|l| !l.is_empty()).collect();
    let mut on_hole = vec![false; n];
    let mut graph = seam.to_vec();
    for &[a, b] in &topo.boundary_edges {
        if in_region[a as usize] && in_region[b as usize] {
            graph.push([a, b]);
            on_hole[a as usize] = true;
            on_hole[b as usize] = true;
        }
    }
    let mut blocked = vec![false; n];
    for &[a, b] in &graph {
        blocked[a as usize] = true;
        blocked[b as usize] = true;
    }
    let band = Band {
        topo,
        region: Region::new(topo, tris),
        cut: graph.iter().map(|&[a, b]| (a.min(b), a.max(b))).collect(),
        on_graph: blocked.clone(),
        on_hole,
        tris_of,
        graph,
    };
    let mut out = Vec::new();
    for ([a, b], far) in cycle_edges(n, &band.graph) {
        // Through the end farther from a branch, else through the other.
        let other = if far == a { b } else { a };
        let Some(path) = [far, other]
            .into_iter()
            .find_map(|pivot| band.arc_through(pivot, &blocked))
        else {
            log::warn!("no arc across the patch's band through seam edge ({a}, {b})");
            continue;
        };
        for &v in &path {
            blocked[v as usize] = true;
        }
        out.push(
            path.windows(2)
                .map(|w| [w[0].min(w[1]), w[0].max(w[1])])
                .collect(),
        );
    }
    out
}

/// The band round the seams as `arcs` sees it.
struct Band<'a> {
    topo: &'a Topology,
    region: Region,
    /// The seam edges and the boundary edges of holes inside the band (`graph`), as a set.
    cut: HashSet<(u32, u32)>,
    graph: Vec<[u32; 2]>,
    on_graph: Vec<bool>,
    on_hole: Vec<bool>,
    tris_of: Vec<Vec<u32>>,
}

impl Band<'_> {
    /// The arc through `pivot` (a vertex of the seams or of a hole's loop), avoiding `blocked`.
    fn arc_through(&self, pivot: u32, blocked: &[bool]) -> Option<Vec<u32>> {
        let (topo, region) = (self.topo, &self.region);
        if self.on_hole[pivot as usize] {
            // Out from the hole, to the band's edge or another hole: one side.
            let mut from_hole = blocked.to_vec();
            for (v, h) in self.on_hole.iter().enumerate() {
                from_hole[v] &= !h;
            }
            for v in hole_loop(&self.graph, &self.on_hole, pivot) {
                from_hole[v as usize] = true;
            }
            let starts = &region.neighbours[pivot as usize];
            let out = to_boundary(topo, region, &from_hole, pivot, starts)?;
            return Some(std::iter::once(pivot).chain(out).collect());
        }
        let sides = sides(topo, &self.tris_of, &self.cut, &self.on_graph, pivot);
        let [one, two] = &sides[..] else {
            return None;
        };
        let first = to_boundary(topo, region, blocked, pivot, one)?;
        let mut with_first = blocked.to_vec();
        for &v in &first {
            with_first[v as usize] = true;
        }
        let second = to_boundary(topo, region, &with_first, pivot, two)?;
        Some(
            first
                .iter()
                .rev()
                .chain(std::iter::once(&pivot))
                .chain(&second)
                .copied()
                .collect(),
        )
    }
}

/// The vertices of the model's boundary loop through `v` (its edges among `graph`'s).
fn hole_loop(graph: &[[u32; 2]], on_hole: &[bool], v: u32) -> Vec<u32> {
    let mut seen = vec![v];
    let mut queue = VecDeque::from([v]);
    while let Some(u) = queue.pop_front() {
        for &[a, b] in graph {
            let w = if a == u {
                b
            } else if b == u {
                a
            } else {
                continue;
            };
            if on_hole[w as usize] && on_hole[u as usize] && !seen.contains(&w) {
                seen.push(w);
                queue.push_back(w);
            }
        }
    }
    seen
}

/// The bridges over `arcs` (the patch's own seams) where the patch is shown: `e` is each welded
/// vertex's distance in edges (up to `RINGS + 1`) from the arcs' vertices within C3 of the pelt's
/// seams (`patch::rings`; the patch shows on C0..C2).
pub fn bridges(
    device: Device,
    topo: &Topology,
    (arcs, arc_count): (Vec<[u32; 2]>, usize),
    e: &[u32],
    opts: &Options,
    path: &Path,
) -> Result<Bridges> {
    let tris: Vec<u32> = (0..topo.triangles.len() as u32)
        .filter(|&t| {
            !topo.degenerate[t as usize]
                && topo.triangles[t as usize]
                    .iter()
                    .all(|&v| e[v as usize] <= RINGS)
        })
        .collect();
    let pieces = split::cut_region_with(
        topo,
        &tris,
        &CutSpec::Edges(Vec::new()),
        opts.split_non_manifold,
        &[],
        path,
    )
    .map_err(|err| {
        Error::mesh(
            path,
            format!(
                "--patch: the bridges over the patch's own seams (within {RINGS} edges of them) are not disks ({err}); the model's handles lie too close together for the patch: leave --patch out, or cut the model into genus-0 parts"
            ),
        )
    })?;
    let layout = layout(device, topo, pieces, super::Prior::default(), opts, path)?;
    let weight = e
        .iter()
        .map(|&r| match r {
            0 | 1 => 1.0,
            2 => 0.5,
            _ => 0.0,
        })
        .collect();
    Ok(Bridges {
        arcs,
        arc_count,
        layout,
        weight,
    })
}
