// SPDX-License-Identifier: MIT OR Apache-2.0
//! Splitting a piece whose pelt folds into two (Piponi & Borshukov §4, end: "for alternative
//! topologies we can use more than one frame"), and cutting each part into disks again.
//!
//! A pelt folds (flipped or overlapping triangles) or stretches too far when its piece is too
//! curved for one frame: a whole closed animal, a long limb. Such a piece is split into the two
//! regions nearest to the ends of its longest shortest path (a geodesic Voronoi split of two far
//! seeds), each region is welded again from the mesh's own vertices, so the earlier cut through it
//! closes up, and cut anew with the automatic cut (a region may have holes or handles). The
//! parts are pelted on their own frames at the next level.

use super::cut::{self, CutSpec, Piece};
use crate::error::Result;
use crate::mesh::{Mesh, Topology};
use std::collections::{BinaryHeap, HashMap};
use std::path::Path;

/// The smallest share of a piece's triangles that a split at an overlap may give one side
/// ([`halves`]).
pub const MIN_SHARE: f64 = 0.2;

/// The triangles (mesh triangle ids) of the two regions of `piece` (module docs), or `None` when
/// the piece cannot be split (too few triangles, or one region would be empty). With `apart`
/// (two piece-local triangles whose layouts overlap), the seeds are a corner of each instead of
/// the ends of the longest path, so the overlap is split apart, unless that leaves one side less
/// than [`MIN_SHARE`] of the triangles.
pub fn halves(topo: &Topology, piece: &Piece, apart: Option<(u32, u32)>) -> Option<[Vec<u32>; 2]> {
    if piece.triangles.len() < 8 {
        return None;
    }
    let n = piece.welded.len();
    let mut nbrs: Vec<Vec<u32>> = vec![Vec::new(); n];
    for t in &piece.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            if !nbrs[a as usize].contains(&b) {
                nbrs[a as usize].push(b);
                nbrs[b as usize].push(a);
            }
        }
    }
    let len = |a: u32, b: u32| {
        (topo.positions[piece.welded[a as usize] as usize]
            - topo.positions[piece.welded[b as usize] as usize])
            .length() as f64
    };
    let far = |from: &[u32]| {
        let d = dijkstra(&nbrs, from, &len);
        let v = (0..n as u32)
            .max_by(|a, b| d[*a as usize].0.total_cmp(&d[*b as usize].0))
            .expect("a piece has vertices");
        (v, d)
    };
    let diameter = || {
        let (a, _) = far(&[0]);
        (a, far(&[a]).0)
    };
    let nbr = triangle_neighbours(piece);
    let sides = |(a, b): (u32, u32)| {
        let (_, labels) = far(&[a, b]);
        let mut side: Vec<bool> = piece
            .triangles
            .iter()
            .map(|tri| tri.iter().filter(|&&v| labels[v as usize].1 == b).count() >= 2)
            .collect();
        smooth_sides(&nbr, &mut side);
        keep_one_region_per_side(&nbr, &mut side);
        straighten(piece, &nbrs, &len, &side).unwrap_or(side)
    };
    let mut side = match apart {
        Some((s, t)) if piece.triangles[s as usize][0] != piece.triangles[t as usize][0] => {
            sides((
                piece.triangles[s as usize][0],
                piece.triangles[t as usize][0],
            ))
        }
        _ => sides(diameter()),
    };
    // Seeds at an overlap near a tip peel off a sliver and leave the rest to be pelted again
    // whole (measured on bob subdivided twice: ten levels of 66k-vertex pelts, each peeling
    // about 500 vertices); a split that uneven is replaced by the diameter's.
    let smaller = side
        .iter()
        .filter(|&&s| s)
        .count()
        .min(side.iter().filter(|&&s| !s).count());
    if apart.is_some() && (smaller as f64) < MIN_SHARE * side.len() as f64 {
        side = sides(diameter());
    }
    let mut parts: [Vec<u32>; 2] = [Vec::new(), Vec::new()];
    for (t, &s) in side.iter().enumerate() {
        parts[usize::from(s)].push(piece.source[t]);
    }
    if parts[0].is_empty() || parts[1].is_empty() {
        return None;
    }
    Some(parts)
}

/// The piece's triangles round each of its edges (piece vertex ids, smaller first).
fn edge_triangles(piece: &Piece) -> HashMap<(u32, u32), Vec<u32>> {
    let mut by_edge: HashMap<(u32, u32), Vec<u32>> = HashMap::new();
    for (t, tri) in piece.triangles.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            by_edge
                .entry((a.min(b), a.max(b)))
                .or_default()
                .push(t as u32);
        }
    }
    by_edge
}

/// The triangles across each triangle's edges (within the piece).
fn triangle_neighbours(piece: &Piece) -> Vec<Vec<u32>> {
    let by_edge = edge_triangles(piece);
    let mut nbr: Vec<Vec<u32>> = vec![Vec::new(); piece.triangles.len()];
    let mut keys: Vec<&(u32, u32)> = by_edge.keys().collect();
    keys.sort_unstable();
    for k in keys {
        if let [a, b] = by_edge[k][..] {
            nbr[a as usize].push(b);
            nbr[b as usize].push(a);
        }
    }
    nbr
}

/// Straightens the border between the sides: a triangle with at least two of its neighbours on
/// the other side goes over, for a few rounds. Without it the border follows the Voronoi labels'
/// staircase and the seam shows teeth one triangle deep.
fn smooth_sides(nbr: &[Vec<u32>], side: &mut [bool]) {
    for _ in 0..8 {
        let flip: Vec<usize> = (0..side.len())
            .filter(|&t| {
                nbr[t]
                    .iter()
                    .filter(|&&u| side[u as usize] != side[t])
                    .count()
                    >= 2
            })
            .collect();
        if flip.is_empty() {
            break;
        }
        for t in flip {
            side[t] = !side[t];
        }
    }
}

/// How far (in edges) from the Voronoi border its straightened path may stray (`straighten`).
pub const BAND: u32 = 4;
/// The straightened path's cost per edge grows by this share per edge of distance from the old
/// border (`straighten`).
pub const NEAR: f64 = 0.05;

/// The border between the sides replaced by the shortest edge path between its two ends on the
/// piece's boundary, within [`BAND`] edges of it: the labels' border follows the geodesic
/// Voronoi staircase (teeth several triangles deep on Spot even after `smooth_sides`), a
/// shortest path runs as straight as the edges allow, as the automatic cut's do. Each of the two
/// regions the path leaves takes the side most of its triangles had. `None` (the smoothed border
/// stays) when the border does not run once from boundary to boundary or the path does not split
/// the piece in two regions that were on different sides.
fn straighten(
    piece: &Piece,
    nbrs: &[Vec<u32>],
    len: &dyn Fn(u32, u32) -> f64,
    side: &[bool],
) -> Option<Vec<bool>> {
    let n = piece.welded.len();
    let by_edge = edge_triangles(piece);
    let mut on_boundary = vec![false; n];
    for &v in &piece.boundary {
        on_boundary[v as usize] = true;
    }
    let mut hop = vec![u32::MAX; n];
    let mut queue = std::collections::VecDeque::new();
    let mut ends = Vec::new();
    for (&(a, b), t) in &by_edge {
        if t.len() == 2 && side[t[0] as usize] != side[t[1] as usize] {
            for v in [a, b] {
                if hop[v as usize] != 0 {
                    hop[v as usize] = 0;
                    queue.push_back(v);
                    if on_boundary[v as usize] {
                        ends.push(v);
                    }
                }
            }
        }
    }
    ends.sort_unstable();
    let [from, to] = ends[..] else {
        return None;
    };
    while let Some(v) = queue.pop_front() {
        for &w in &nbrs[v as usize] {
            if hop[w as usize] == u32::MAX && hop[v as usize] < BAND {
                hop[w as usize] = hop[v as usize] + 1;
                queue.push_back(w);
            }
        }
    }
    // Dijkstra from one end to the other through the band's interior vertices.
    let mut dist = vec![f64::INFINITY; n];
    let mut parent = vec![u32::MAX; n];
    let mut heap = BinaryHeap::new();
    dist[from as usize] = 0.0;
    heap.push(std::cmp::Reverse((0u64, from)));
    while let Some(std::cmp::Reverse((_, v))) = heap.pop() {
        if v == to {
            break;
        }
        for &w in &nbrs[v as usize] {
            let inner = !on_boundary[w as usize] || w == to;
            let interior_edge = by_edge[&(v.min(w), v.max(w))].len() == 2;
            if hop[w as usize] == u32::MAX || !inner || !interior_edge {
                continue;
            }
            // Among paths of about the same length, the one nearest the old border (a grid has
            // many equally short staircases, and the farthest would move the split).
            let near = 1.0 + NEAR * (hop[v as usize] + hop[w as usize]) as f64;
            let nd = dist[v as usize] + len(v, w) * near;
            if nd < dist[w as usize] {
                dist[w as usize] = nd;
                parent[w as usize] = v;
                heap.push(std::cmp::Reverse(((nd * 1e9) as u64, w)));
            }
        }
    }
    if parent[to as usize] == u32::MAX {
        return None;
    }
    let mut cut = rustc_hash::FxHashSet::default();
    let mut v = to;
    while v != from {
        let p = parent[v as usize];
        cut.insert((v.min(p), v.max(p)));
        v = p;
    }
    // The regions the path leaves, and the side most of each one's triangles had.
    let mut region = vec![u32::MAX; side.len()];
    let mut votes: Vec<[usize; 2]> = Vec::new();
    for start in 0..side.len() {
        if region[start] != u32::MAX {
            continue;
        }
        let id = votes.len() as u32;
        votes.push([0, 0]);
        region[start] = id;
        let mut stack = vec![start as u32];
        while let Some(t) = stack.pop() {
            votes[id as usize][usize::from(side[t as usize])] += 1;
            let tri = piece.triangles[t as usize];
            for k in 0..3 {
                let e = (tri[k].min(tri[(k + 1) % 3]), tri[k].max(tri[(k + 1) % 3]));
                if cut.contains(&e) {
                    continue;
                }
                for &u in &by_edge[&e] {
                    if region[u as usize] == u32::MAX {
                        region[u as usize] = id;
                        stack.push(u);
                    }
                }
            }
        }
    }
    let pick: Vec<bool> = votes.iter().map(|v| v[1] > v[0]).collect();
    if pick.len() != 2 || pick[0] == pick[1] {
        return None;
    }
    Some(region.iter().map(|&r| pick[r as usize]).collect())
}

/// Gives every triangle that is cut off from the largest region of its side to the other side, so
/// each side is one connected region (no islands of a few triangles become pelts of their own).
fn keep_one_region_per_side(nbr: &[Vec<u32>], side: &mut [bool]) {
    for _ in 0..2 {
        // Regions of equal side; all but the largest of each side flip.
        let mut region = vec![u32::MAX; side.len()];
        let mut sizes: Vec<(usize, bool)> = Vec::new();
        for start in 0..side.len() {
            if region[start] != u32::MAX {
                continue;
            }
            let id = sizes.len() as u32;
            let mut stack = vec![start as u32];
            region[start] = id;
            let mut count = 0;
            while let Some(t) = stack.pop() {
                count += 1;
                for &u in &nbr[t as usize] {
                    if region[u as usize] == u32::MAX && side[u as usize] == side[start] {
                        region[u as usize] = id;
                        stack.push(u);
                    }
                }
            }
            sizes.push((count, side[start]));
        }
        let largest = |s: bool| {
            (0..sizes.len())
                .filter(|&i| sizes[i].1 == s)
                .max_by_key(|&i| sizes[i].0)
        };
        let keep = [largest(false), largest(true)];
        let mut changed = false;
        for t in 0..side.len() {
            let r = region[t] as usize;
            if Some(r) != keep[usize::from(side[t])] {
                side[t] = !side[t];
                changed = true;
            }
        }
        if !changed {
            break;
        }
    }
}

/// Multi-source Dijkstra: (distance, nearest source) per vertex.
fn dijkstra(nbrs: &[Vec<u32>], from: &[u32], len: &dyn Fn(u32, u32) -> f64) -> Vec<(f64, u32)> {
    let mut d = vec![(f64::INFINITY, u32::MAX); nbrs.len()];
    let mut heap = BinaryHeap::new();
    for &s in from {
        d[s as usize] = (0.0, s);
        heap.push(std::cmp::Reverse((0u64, s)));
    }
    while let Some(std::cmp::Reverse((_, v))) = heap.pop() {
        let (dv, src) = d[v as usize];
        for &w in &nbrs[v as usize] {
            let nd = dv + len(v, w);
            if nd < d[w as usize].0 {
                d[w as usize] = (nd, src);
                // Fixed-point keys keep the heap's order total; ties resolve by vertex id.
                heap.push(std::cmp::Reverse(((nd * 1e9) as u64, w)));
            }
        }
    }
    d
}

/// Cuts the region made of mesh triangles `tris` into disks, in the whole mesh's welded ids.
/// `exposure` is the whole mesh's (`hidden::exposure`, per welded vertex).
pub fn cut_region(
    topo: &Topology,
    tris: &[u32],
    split_non_manifold: bool,
    exposure: &[f32],
    path: &Path,
) -> Result<Vec<Piece>> {
    cut_region_with(
        topo,
        tris,
        &CutSpec::Auto,
        split_non_manifold,
        exposure,
        path,
    )
}

/// [`cut_region`] with another cut (`pelt::patch` cuts nothing, or the arcs of `pelt::bridge`
/// where the seams have cycles; `CutSpec::Edges` in the whole mesh's welded ids).
pub fn cut_region_with(
    topo: &Topology,
    tris: &[u32],
    spec: &CutSpec,
    split_non_manifold: bool,
    exposure: &[f32],
    path: &Path,
) -> Result<Vec<Piece>> {
    // The region as a mesh of its own, on the welded vertices it uses.
    let mut local: HashMap<u32, u32> = HashMap::new();
    let mut welded = Vec::new();
    let triangles: Vec<[u32; 3]> = tris
        .iter()
        .map(|&t| {
            topo.triangles[t as usize].map(|w| {
                *local.entry(w).or_insert_with(|| {
                    welded.push(w);
                    welded.len() as u32 - 1
                })
            })
        })
        .collect();
    let positions = welded.iter().map(|&w| topo.positions[w as usize]).collect();
    let mesh = Mesh {
        source: path.to_path_buf(),
        normals: vec![glam::Vec3::ZERO; welded.len()],
        uv_sets: Vec::new(),
        positions,
        triangles,
        primitives: Vec::new(),
        material: None,
        blend: Vec::new(),
        bridge: Vec::new(),
        ..Default::default()
    };
    // A tenth of the mesh's welding distance at most (the region is no larger than the mesh): the
    // welded vertices, further apart than that, stay apart.
    let sub = Topology::build(&mesh, 0.1 * crate::mesh::DEFAULT_WELD_TOLERANCE);
    // Sub-welded id -> the mesh's welded id (one region vertex per sub-welded id).
    let mut back = vec![u32::MAX; sub.positions.len()];
    for (v, &s) in sub.welded_of.iter().enumerate() {
        back[s as usize] = welded[v];
    }
    let seen: Vec<f32> = back
        .iter()
        .map(|&w| exposure.get(w as usize).copied().unwrap_or(1.0))
        .collect();
    // A cut's edges name the whole mesh's welded ids: into the region's (an edge off the region
    // keeps an id no region vertex has, and the cut refuses it by name).
    let local_spec = match spec {
        CutSpec::Edges(list) => CutSpec::Edges(
            list.iter()
                .map(|e| {
                    e.map(|w| {
                        local
                            .get(&w)
                            .map_or(u32::MAX, |&l| sub.welded_of[l as usize])
                    })
                })
                .collect(),
        ),
        other => other.clone(),
    };
    let c = cut::cut_exposed(
        &mesh,
        &sub,
        &local_spec,
        split_non_manifold,
        Some(&seen),
        path,
    )?;
    Ok(c.pieces
        .into_iter()
        .map(|p| Piece {
            welded: p.welded.iter().map(|&v| back[v as usize]).collect(),
            source: p.source.iter().map(|&t| tris[t as usize]).collect(),
            ..p
        })
        .collect())
}
