// SPDX-License-Identifier: MIT OR Apache-2.0
//! A surface's extremities: the tips (horns, ears, fingers, a cube's corners) an automatic cut runs
//! through. A tip is where the angle defect (the integrated Gaussian curvature) gathers: at least
//! [`TIP_DEFECT`] radians within [`TIP_RADIUS`] × √area of a vertex that has the highest smoothed
//! defect within [`TIP_SPACING`] × √area. Piponi & Borshukov §4 leave the cut to the artist; these
//! are the places an artist cuts to, because a tip left inside a pelt is stretched over the frame.

use crate::mesh::Topology;
use std::collections::{BinaryHeap, HashMap};

/// Radius (× √area of the component) over which a tip's defect is summed.
pub const TIP_RADIUS: f64 = 0.08;
/// Least summed defect of a tip, radians (a cube's corner has π/2; a hemisphere's 0.08·√(2π)
/// disc about 0.13).
pub const TIP_DEFECT: f64 = 0.6;
/// Least distance between two tips (× √area).
pub const TIP_SPACING: f64 = 0.15;
/// Most tips per mesh.
pub const MAX_TIPS: usize = 12;
/// Most candidates whose defect ball is summed.
const MAX_CANDIDATES: usize = 256;

/// The angle defect of every interior vertex (0 at boundary and unused vertices).
pub fn angle_defects(topo: &Topology) -> Vec<f64> {
    let n = topo.positions.len();
    let mut angle = vec![0f64; n];
    let mut used = vec![false; n];
    for (t, tri) in topo.triangles.iter().enumerate() {
        if topo.degenerate[t] {
            continue;
        }
        let p = tri.map(|i| topo.positions[i as usize].as_dvec3());
        for k in 0..3 {
            let (u, v) = (p[(k + 1) % 3] - p[k], p[(k + 2) % 3] - p[k]);
            angle[tri[k] as usize] += u.cross(v).length().atan2(u.dot(v));
            used[tri[k] as usize] = true;
        }
    }
    for e in &topo.boundary_edges {
        used[e[0] as usize] = false;
        used[e[1] as usize] = false;
    }
    (0..n)
        .map(|v| {
            if used[v] {
                std::f64::consts::TAU - angle[v]
            } else {
                0.0
            }
        })
        .collect()
}

/// The defect smoothed over about [`TIP_RADIUS`] × √area by repeated neighbour averaging (the
/// number of rounds grows with the square of the radius in edges, at most 200).
pub fn tip_score(topo: &Topology) -> Vec<f64> {
    let mut s = angle_defects(topo);
    let (area, edge) = area_and_edge(topo);
    let hops = TIP_RADIUS * area.sqrt() / edge.max(f64::MIN_POSITIVE);
    let rounds = (hops * hops).clamp(1.0, 200.0) as usize;
    let off = &topo.adjacency_offsets;
    for _ in 0..rounds {
        s = (0..s.len())
            .map(|v| {
                let (a, b) = (off[v] as usize, off[v + 1] as usize);
                if a == b {
                    return s[v];
                }
                let mean: f64 = topo.adjacency[a..b]
                    .iter()
                    .map(|&w| s[w as usize])
                    .sum::<f64>()
                    / (b - a) as f64;
                0.5 * (s[v] + mean)
            })
            .collect();
    }
    s
}

/// Total area and mean edge length of the non-degenerate triangles.
pub fn area_and_edge(topo: &Topology) -> (f64, f64) {
    let (mut area, mut len, mut count) = (0.0, 0.0, 0usize);
    for (t, tri) in topo.triangles.iter().enumerate() {
        if topo.degenerate[t] {
            continue;
        }
        let p = tri.map(|i| topo.positions[i as usize].as_dvec3());
        area += 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length();
        for k in 0..3 {
            len += (p[(k + 1) % 3] - p[k]).length();
        }
        count += 3;
    }
    (area, len / count.max(1) as f64)
}

/// Dijkstra from `src` up to `radius`: the vertices reached and their distances.
pub fn ball(topo: &Topology, src: u32, radius: f64) -> HashMap<u32, f64> {
    let mut dist: HashMap<u32, f64> = HashMap::new();
    let mut heap = BinaryHeap::new();
    dist.insert(src, 0.0);
    heap.push(std::cmp::Reverse((Key(0.0), src)));
    while let Some(std::cmp::Reverse((Key(d), v))) = heap.pop() {
        if d > dist[&v] {
            continue;
        }
        let (a, b) = (
            topo.adjacency_offsets[v as usize] as usize,
            topo.adjacency_offsets[v as usize + 1] as usize,
        );
        for &w in &topo.adjacency[a..b] {
            let nd = d + (topo.positions[v as usize] - topo.positions[w as usize]).length() as f64;
            if nd <= radius && dist.get(&w).is_none_or(|&old| nd < old) {
                dist.insert(w, nd);
                heap.push(std::cmp::Reverse((Key(nd), w)));
            }
        }
    }
    dist
}

/// A distance ordered for a binary heap (the distances used are finite), shared by the searches
/// of `pelt`.
#[derive(PartialEq, PartialOrd, Clone, Copy)]
pub struct Key(pub f64);
impl Eq for Key {}
#[allow(
    clippy::derive_ord_xor_partial_ord,
    reason = "total on the finite distances used"
)]
impl Ord for Key {
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        self.0.total_cmp(&o.0)
    }
}

/// The tips (module docs), strongest first.
pub fn extremities(topo: &Topology, score: &[f64], used: &[bool]) -> Vec<u32> {
    let defect = angle_defects(topo);
    let (area, _) = area_and_edge(topo);
    let root_area = area.sqrt();
    let mut order: Vec<u32> = (0..score.len() as u32)
        .filter(|&v| used[v as usize] && score[v as usize] > 0.0)
        .collect();
    order.sort_unstable_by(|a, b| score[*b as usize].total_cmp(&score[*a as usize]));
    let mut tips: Vec<u32> = Vec::new();
    let mut near: rustc_hash::FxHashSet<u32> = Default::default();
    let mut tried = 0;
    for &v in &order {
        if tips.len() >= MAX_TIPS || tried >= MAX_CANDIDATES {
            break;
        }
        if near.contains(&v) {
            continue;
        }
        tried += 1;
        let b = ball(topo, v, TIP_RADIUS * root_area);
        let sum: f64 = b.keys().map(|&w| defect[w as usize]).sum();
        if sum < TIP_DEFECT {
            // Its neighbours score lower and sum about as much: not tips either.
            near.extend(b.keys());
            continue;
        }
        tips.push(v);
        near.extend(ball(topo, v, TIP_SPACING * root_area).keys());
    }
    tips
}
