// SPDX-License-Identifier: MIT OR Apache-2.0
//! A chart's region must be a topological disc: a conformal flattening of a region with a handle, or
//! of one that closes up, has to crush or fold part of it. [`topology`] reads a triangle set's Euler
//! characteristic, boundary loops and components; [`grow_disc`] shrinks a set that is not a disc
//! to a disc grown greedily from the placed triangle in order of distance from the placed point: a
//! handle is left open where the growing front meets itself. The triangles left out there keep their
//! corners in the chart, so if they lie inside the decal they would be drawn stretched across it; the
//! chart's fold check counts them (`footprint_torn`) and re-solves on a smaller region.

use crate::mesh::{Topology, NO_NEIGHBOR};
use glam::DVec3;
use rustc_hash::{FxHashMap as HashMap, FxHashSet as HashSet};
use std::collections::BinaryHeap;

/// The topology of a chart's region and what was done about it: the first selection's, or, when a
/// refinement round had to shrink the region, that round's.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct RegionReport {
    /// V − E + F of the selected triangles (1 for a disc).
    pub euler_characteristic: i32,
    /// Boundary loops (1 for a disc; loops that touch at a vertex count as one).
    pub boundary_loops: u32,
    /// Edge-connected components (1 for a disc).
    pub components: u32,
    /// Whether the selection was a disc.
    pub disc: bool,
    /// What was done when it was not.
    pub fix: RegionFix,
}

/// What was done to a region that is not a disc.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RegionFix {
    /// Nothing: the region was a disc.
    None,
    /// Shrunk to the largest disc grown from the placed triangle (handles cut open).
    ShrunkToDisc,
}

/// The topology of the triangle set `tris` (welded vertices; a mesh boundary edge is a boundary).
pub fn topology(topo: &Topology, tris: &[u32]) -> RegionReport {
    let set: HashSet<u32> = tris.iter().copied().collect();
    let vertices: HashSet<u32> = tris
        .iter()
        .flat_map(|&t| topo.triangles[t as usize])
        .collect();
    // Boundary edges (a, b) in winding order, and the components by edge adjacency.
    let mut boundary: Vec<(u32, u32)> = Vec::new();
    for &t in tris {
        let tri = topo.triangles[t as usize];
        for k in 0..3 {
            let nb = topo.triangle_neighbors[t as usize][k];
            if nb == NO_NEIGHBOR || !set.contains(&nb) {
                boundary.push((tri[k], tri[(k + 1) % 3]));
            }
        }
    }
    let f = tris.len() as i64;
    let e = (3 * f + boundary.len() as i64) / 2;
    let chi = vertices.len() as i64 - e + f;
    let mut seen = HashSet::default();
    let mut components = 0;
    for &t in tris {
        if !seen.insert(t) {
            continue;
        }
        components += 1;
        let mut stack = vec![t];
        while let Some(u) = stack.pop() {
            for nb in topo.triangle_neighbors[u as usize] {
                if nb != NO_NEIGHBOR && set.contains(&nb) && seen.insert(nb) {
                    stack.push(nb);
                }
            }
        }
    }
    let loops = loops(&boundary);
    let disc = components == 1 && chi == 1 && loops == 1;
    RegionReport {
        euler_characteristic: chi as i32,
        boundary_loops: loops,
        components,
        disc,
        fix: RegionFix::None,
    }
}

/// Connected components of the boundary-edge graph: the boundary loops of a manifold region.
fn loops(edges: &[(u32, u32)]) -> u32 {
    let mut parent: HashMap<u32, u32> = HashMap::default();
    fn find(p: &mut HashMap<u32, u32>, x: u32) -> u32 {
        let mut r = x;
        while let Some(&q) = p.get(&r) {
            if q == r {
                break;
            }
            r = q;
        }
        p.insert(x, r);
        r
    }
    for &(a, b) in edges {
        parent.entry(a).or_insert(a);
        parent.entry(b).or_insert(b);
        let (ra, rb) = (find(&mut parent, a), find(&mut parent, b));
        if ra != rb {
            parent.insert(ra, rb);
        }
    }
    let keys: Vec<u32> = parent.keys().copied().collect();
    keys.into_iter()
        .filter(|&v| find(&mut parent, v) == v)
        .count() as u32
}

/// The largest disc of `tris` grown from `start` (which must be in `tris`): triangles join in order
/// of their centroid's distance from `center`, and only when they keep the region a disc (across one
/// edge with a new vertex, or across two edges filling a notch). Deterministic: ties go to the lower
/// triangle id.
pub fn grow_disc(topo: &Topology, tris: &[u32], start: u32, center: DVec3) -> Vec<u32> {
    let allowed: HashSet<u32> = tris.iter().copied().collect();
    let key = |t: u32| {
        let c = topo.triangles[t as usize]
            .iter()
            .fold(DVec3::ZERO, |a, &v| {
                a + topo.positions[v as usize].as_dvec3()
            })
            / 3.0;
        // Max-heap: negate the distance (ordered as integers of nanometre-scale units).
        (
            std::cmp::Reverse((c - center).length().to_bits()),
            std::cmp::Reverse(t),
        )
    };
    let mut region: HashSet<u32> = HashSet::from_iter([start]);
    let mut verts: HashSet<u32> = topo.triangles[start as usize].into_iter().collect();
    let mut out = vec![start];
    let mut heap = BinaryHeap::new();
    let push_neighbors = |t: u32, heap: &mut BinaryHeap<_>, region: &HashSet<u32>| {
        for nb in topo.triangle_neighbors[t as usize] {
            if nb != NO_NEIGHBOR && allowed.contains(&nb) && !region.contains(&nb) {
                heap.push((key(nb), nb));
            }
        }
    };
    push_neighbors(start, &mut heap, &region);
    while let Some((_, t)) = heap.pop() {
        if region.contains(&t) {
            continue;
        }
        let shared = topo.triangle_neighbors[t as usize]
            .iter()
            .filter(|&&nb| nb != NO_NEIGHBOR && region.contains(&nb))
            .count();
        let tri = topo.triangles[t as usize];
        let known = tri.iter().filter(|v| verts.contains(v)).count();
        let keeps_disc = (shared == 1 && known == 2) || shared == 2;
        if !keeps_disc {
            continue;
        }
        region.insert(t);
        verts.extend(tri);
        out.push(t);
        push_neighbors(t, &mut heap, &region);
    }
    out
}
