// SPDX-License-Identifier: MIT OR Apache-2.0
//! Cutting a surface into topological disks (Piponi & Borshukov §4: "a cut is a collection of edges
//! that form a connected tree"; the cut edges and vertices are duplicated, connectivity only).
//!
//! The automatic cut is a tree-cotree cut graph (the greedy system of loops of Erickson and Whittlesey,
//! "Greedy optimal homotopy and homology generators", 2005) pruned to the vertices it must reach:
//! - `T`: the shortest-path tree from a root vertex over the welded edges, each costing its length
//!   weighted by how much a seam there would show (`hidden`: less in crevices and along creases);
//! - the dual graph: one node per triangle plus one per boundary loop (the hole closed by a virtual
//!   face); a maximum spanning tree of the dual edges not in `T`, by the length of the loop an edge
//!   closes (`d(u) + |uv| + d(v)`), leaves the `2g` edges `X` whose loops generate the homology;
//! - the cut graph `T ∪ X` cuts the closed-up surface into one disk; pruning its dangling branches
//!   keeps that true, so it is pruned down to the loops of `X` plus the paths in `T` to the
//!   **terminals**: one vertex per boundary loop (so holes are joined to the cut and the piece's
//!   boundary is one loop), and the component's extremities (tips where the smoothed angle defect
//!   peaks: horns, ears, fingers), through which a pelt's cut should run, because a tip that stays
//!   inside the pelt is stretched over the frame. A closed genus-0 piece gets at least two terminals
//!   (one cut path): the ends of its geodesic diameter when it has fewer extremities.
//!
//! The split then gives every vertex one copy per sector of triangles between cut (or boundary)
//! edges around it, and each connected piece is checked to be a disk (Euler characteristic 1, one
//! boundary loop).

use super::tips::Key;
use crate::error::{Error, Result};
use crate::mesh::{Mesh, Topology};
use std::cmp::Reverse;
use std::collections::{BinaryHeap, HashMap};
use std::path::Path;

/// How the cut is chosen (`decalbake unwrap --cut`).
#[derive(Debug, Clone)]
pub enum CutSpec {
    /// The tree-cotree cut graph through the extremities (the module docs).
    Auto,
    /// The model's own UV seams on this set: every edge whose two triangles use different split
    /// vertices with different UVs.
    Seams(u32),
    /// These edges (welded vertex pairs), as an artist's cut file lists them.
    Edges(Vec<[u32; 2]>),
}

/// One piece of the cut surface: a topological disk.
#[derive(Debug, Clone)]
pub struct Piece {
    /// The welded vertex of each of the piece's vertices (a vertex on the cut appears once per side).
    pub welded: Vec<u32>,
    /// Triangles in the piece's vertex ids, wound as in the mesh.
    pub triangles: Vec<[u32; 3]>,
    /// The mesh triangle (index into [`Topology::triangles`]) of each triangle.
    pub source: Vec<u32>,
    /// The boundary loop in the piece's vertex ids, with the piece on its left (the mesh's winding).
    pub boundary: Vec<u32>,
}

/// A surface cut into disks.
#[derive(Debug, Clone)]
pub struct Cut {
    /// The disks.
    pub pieces: Vec<Piece>,
    /// For each mesh triangle, (piece, piece-local triangle), or `None` for degenerate triangles.
    pub triangle_piece: Vec<Option<(u32, u32)>>,
    /// The interior edges that were opened (welded ids, smaller first).
    pub edges: Vec<[u32; 2]>,
    /// The terminals the automatic cut reaches (empty for other cuts).
    pub terminals: Vec<u32>,
    /// Each welded vertex's exposure (`hidden::exposure`), where the automatic cut measured it
    /// (empty for other cuts); the splits' cuts reuse it.
    pub exposure: Vec<f32>,
    /// Milliseconds the exposure took here (0 where it was given or not needed).
    pub exposure_ms: f64,
    /// Pieces the automatic cut left that were not disks, each split into disks by
    /// [`disk_charts`] (0 for other cuts, which refuse them).
    pub regrown: usize,
}

impl Cut {
    /// The cut made of `pieces` (each a disk, in the mesh's welded ids): which piece each mesh
    /// triangle went to, and the opened edges (those whose two triangles do not share both ends'
    /// piece vertices).
    pub fn assemble(topo: &Topology, pieces: Vec<Piece>, terminals: Vec<u32>) -> Self {
        let mut triangle_piece = vec![None; topo.triangles.len()];
        for (pi, p) in pieces.iter().enumerate() {
            for (lt, &t) in p.source.iter().enumerate() {
                triangle_piece[t as usize] = Some((pi as u32, lt as u32));
            }
        }
        let corner = |t: u32, w: u32| -> Option<(u32, u32)> {
            let (pi, lt) = triangle_piece[t as usize]?;
            let k = topo.triangles[t as usize].iter().position(|&x| x == w)?;
            Some((pi, pieces[pi as usize].triangles[lt as usize][k]))
        };
        let mut edges: Vec<[u32; 2]> = edge_faces(topo)
            .into_iter()
            .filter(|(_, f)| f.len() == 2)
            .filter(|((a, b), f)| {
                corner(f[0], *a) != corner(f[1], *a) || corner(f[0], *b) != corner(f[1], *b)
            })
            .map(|((a, b), _)| [a, b])
            .collect();
        edges.sort_unstable();
        Self {
            pieces,
            triangle_piece,
            edges,
            terminals,
            exposure: Vec::new(),
            exposure_ms: 0.0,
            regrown: 0,
        }
    }

    /// The summed 3D length of the opened edges (each counted once; the seam shows on both sides).
    pub fn seam_length(&self, topo: &Topology) -> f64 {
        self.edges.iter().map(|e| edge_len(topo, e[0], e[1])).sum()
    }
}

fn edge_len(topo: &Topology, a: u32, b: u32) -> f64 {
    (topo.positions[a as usize].as_dvec3() - topo.positions[b as usize].as_dvec3()).length()
}

/// Edge key, smaller vertex first.
fn key(a: u32, b: u32) -> (u32, u32) {
    (a.min(b), a.max(b))
}

/// The triangles using each edge (non-degenerate ones).
fn edge_faces(topo: &Topology) -> HashMap<(u32, u32), Vec<u32>> {
    let mut m: HashMap<(u32, u32), Vec<u32>> = HashMap::with_capacity(topo.triangles.len() * 2);
    for (t, tri) in topo.triangles.iter().enumerate() {
        if topo.degenerate[t] {
            continue;
        }
        for k in 0..3 {
            m.entry(key(tri[k], tri[(k + 1) % 3]))
                .or_default()
                .push(t as u32);
        }
    }
    m
}

/// Cuts `topo` into disks as `spec` says. `path` names the mesh in errors. A non-manifold edge is
/// an error that says where.
pub fn cut(mesh: &Mesh, topo: &Topology, spec: &CutSpec, path: &Path) -> Result<Cut> {
    cut_with(mesh, topo, spec, false, path)
}

/// [`cut`]; with `split_non_manifold`, an edge of more than two triangles is opened for all of
/// them (each fan of triangles round it ends there, as at a boundary) instead of refused.
pub fn cut_with(
    mesh: &Mesh,
    topo: &Topology,
    spec: &CutSpec,
    split_non_manifold: bool,
    path: &Path,
) -> Result<Cut> {
    cut_exposed(mesh, topo, spec, split_non_manifold, None, path)
}

/// [`cut_with`] with each welded vertex's exposure given (`hidden::exposure`; measured here when
/// `None` and the cut is automatic): a region of a mesh is cut with the whole mesh's exposure,
/// since parts outside the region hide it too.
pub fn cut_exposed(
    mesh: &Mesh,
    topo: &Topology,
    spec: &CutSpec,
    split_non_manifold: bool,
    exposure: Option<&[f32]>,
    path: &Path,
) -> Result<Cut> {
    if let Some(e) = topo
        .non_manifold_edges
        .first()
        .filter(|_| !split_non_manifold)
    {
        let p = topo.positions[e[0] as usize];
        return Err(Error::mesh(
            path,
            format!(
                "{} non-manifold edges (more than two triangles share them), the first at vertex {} ({:.4}, {:.4}, {:.4}); pelting needs a manifold surface: add --split-non-manifold to open those edges (every triangle fan round them becomes a separate edge), or split the mesh there yourself (in Blender: Mesh > Clean Up > Split Non-Manifold)",
                topo.non_manifold_edges.len(),
                e[0],
                p.x,
                p.y,
                p.z
            ),
        ));
    }
    let faces = edge_faces(topo);
    let mut measured = Vec::new();
    let mut exposure_ms = 0.0;
    let (opened, terminals) = match spec {
        CutSpec::Auto => {
            let exposure = match exposure {
                Some(e) => e,
                None => {
                    let t = std::time::Instant::now();
                    measured = super::hidden::exposure(topo);
                    exposure_ms = t.elapsed().as_secs_f64() * 1e3;
                    &measured
                }
            };
            auto_cut(
                topo,
                &faces,
                super::hidden::edge_costs(topo, &faces, exposure),
            )
        }
        CutSpec::Seams(set) => (seam_edges(mesh, topo, &faces, *set, path)?, Vec::new()),
        CutSpec::Edges(list) => {
            for (i, e) in list.iter().enumerate() {
                if !faces.contains_key(&key(e[0], e[1])) {
                    return Err(Error::mesh(
                        path,
                        format!(
                            "cut edge {i} ({}, {}) is not an edge of the mesh (vertices are welded ids, 0..{}); list edges of the welded mesh as `decalbake unwrap --report` names them",
                            e[0],
                            e[1],
                            topo.positions.len()
                        ),
                    ));
                }
            }
            (list.iter().map(|e| key(e[0], e[1])).collect(), Vec::new())
        }
    };
    let mut edges: Vec<[u32; 2]> = opened
        .into_iter()
        .filter(|e| faces.get(e).is_some_and(|f| f.len() == 2))
        .map(|(a, b)| [a, b])
        .collect();
    edges.sort_unstable();
    edges.dedup();
    let (mut pieces, mut triangle_piece) = split(topo, &faces, &edges);
    // The automatic cut should leave disks; where it does not (seen on real models: a small
    // closed part, a part whose holes the pruned cut graph misses), that piece is cut further
    // into disks grown triangle by triangle, rather than the model refused. A cut the user
    // chose (seams, edges) is refused instead, naming the piece, so that they can mend it.
    let mut regrown = 0;
    if matches!(spec, CutSpec::Auto) {
        let extra: Vec<[u32; 2]> = pieces
            .iter()
            .filter(|p| !is_disk(p))
            .inspect(|_| regrown += 1)
            .flat_map(disk_charts)
            .collect();
        if !extra.is_empty() {
            log::info!(
                "the automatic cut left {regrown} pieces that are not disks; each is cut into disks grown triangle by triangle ({} more cut edges)",
                extra.len()
            );
            edges.extend(
                extra
                    .into_iter()
                    .filter(|e| faces.get(&(e[0], e[1])).is_some_and(|f| f.len() == 2)),
            );
            edges.sort_unstable();
            edges.dedup();
            (pieces, triangle_piece) = split(topo, &faces, &edges);
        }
    }
    for (i, p) in pieces.iter().enumerate() {
        check_disk(topo, p, i, path)?;
    }
    Ok(Cut {
        pieces,
        triangle_piece,
        edges,
        terminals,
        exposure: measured,
        exposure_ms,
        regrown,
    })
}

/// A piece's Euler characteristic V − E + F and its number of boundary loops (a disk: 1 and 1).
fn disk_shape(p: &Piece) -> (i64, usize) {
    let mut edges: rustc_hash::FxHashSet<(u32, u32)> = Default::default();
    for t in &p.triangles {
        for k in 0..3 {
            edges.insert(key(t[k], t[(k + 1) % 3]));
        }
    }
    let chi = p.welded.len() as i64 - edges.len() as i64 + p.triangles.len() as i64;
    (chi, boundary_loops(&p.triangles).len())
}

fn is_disk(p: &Piece) -> bool {
    disk_shape(p) == (1, 1)
}

/// The welded edges that cut piece `p` into disks grown one triangle at a time: from its first
/// triangle not yet in a chart, across the piece's inner edges in breadth-first order, a
/// triangle joins the chart where it keeps the chart's Euler characteristic at 1 (it shares one
/// edge with the chart and brings a new vertex, or shares two and closes the fan between them);
/// otherwise (it would close a loop round a hole or a handle, or close the surface), or where it
/// is wound against the chart (a file whose winding flips across an edge), it waits for a chart
/// of its own. A connected, consistently wound surface with a boundary and characteristic 1 is
/// a disk, so every chart is one, and the edges between charts are returned (the piece's vertex ids mapped
/// to the welded ids the cut lists). Deterministic: the order is the piece's.
pub fn disk_charts(p: &Piece) -> Vec<[u32; 2]> {
    let mut around: HashMap<(u32, u32), Vec<u32>> = HashMap::new();
    for (i, t) in p.triangles.iter().enumerate() {
        for k in 0..3 {
            around
                .entry(key(t[k], t[(k + 1) % 3]))
                .or_default()
                .push(i as u32);
        }
    }
    let n = p.triangles.len();
    let mut chart = vec![u32::MAX; n];
    let mut charts = 0u32;
    for seed in 0..n {
        if chart[seed] != u32::MAX {
            continue;
        }
        let c = charts;
        charts += 1;
        let mut vertices: rustc_hash::FxHashSet<u32> = p.triangles[seed].into_iter().collect();
        let mut edges: rustc_hash::FxHashSet<(u32, u32)> = Default::default();
        let mut walked: rustc_hash::FxHashSet<(u32, u32)> = Default::default();
        let mut queue = std::collections::VecDeque::from([seed as u32]);
        let mut first = true;
        while let Some(t) = queue.pop_front() {
            if chart[t as usize] != u32::MAX {
                continue;
            }
            let tri = p.triangles[t as usize];
            let directed = [0, 1, 2].map(|k| (tri[k], tri[(k + 1) % 3]));
            let sides = directed.map(|(a, b)| key(a, b));
            let shared = sides.iter().filter(|e| edges.contains(e)).count();
            let fresh = tri.iter().filter(|v| !vertices.contains(v)).count();
            // Wound against the chart across a shared edge (the chart holds that edge in the same
            // direction): the file's winding flips there, and the edge must be cut.
            let flipped = directed.iter().any(|d| walked.contains(d));
            let keeps_disk = first || (shared == 1 && fresh == 1) || (shared == 2 && fresh == 0);
            if !keeps_disk || flipped {
                continue;
            }
            first = false;
            chart[t as usize] = c;
            vertices.extend(tri);
            edges.extend(sides);
            walked.extend(directed);
            for e in sides {
                for &u in &around[&e] {
                    if chart[u as usize] == u32::MAX {
                        queue.push_back(u);
                    }
                }
            }
        }
    }
    let mut out: Vec<[u32; 2]> = around
        .iter()
        .filter(|(_, f)| f.len() == 2 && chart[f[0] as usize] != chart[f[1] as usize])
        .map(|(&(a, b), _)| {
            let (a, b) = key(p.welded[a as usize], p.welded[b as usize]);
            [a, b]
        })
        .collect();
    out.sort_unstable();
    out
}

/// Edges whose two triangles use different split vertices with different UVs in `set`.
fn seam_edges(
    mesh: &Mesh,
    topo: &Topology,
    faces: &HashMap<(u32, u32), Vec<u32>>,
    set: u32,
    path: &Path,
) -> Result<Vec<(u32, u32)>> {
    let uv = mesh.uv_sets.get(set as usize).ok_or_else(|| {
        Error::mesh(
            path,
            format!(
                "`--cut seams` reads UV set {set}, but the mesh has {} UV sets; use `--cut auto` or a cut file",
                mesh.uv_sets.len()
            ),
        )
    })?;
    let split_of = |t: u32, w: u32| -> u32 {
        let k = topo.triangles[t as usize]
            .iter()
            .position(|&x| x == w)
            .expect("edge vertex is in its triangle");
        mesh.triangles[t as usize][k]
    };
    let mut out = Vec::new();
    for (&(a, b), f) in faces {
        if f.len() != 2 {
            continue;
        }
        let differs = [a, b].iter().any(|&w| {
            let (s0, s1) = (split_of(f[0], w), split_of(f[1], w));
            s0 != s1 && uv[s0 as usize] != uv[s1 as usize]
        });
        if differs {
            out.push((a, b));
        }
    }
    Ok(out)
}

/// Disjoint sets with path halving.
struct Sets(Vec<u32>);

impl Sets {
    fn new(n: usize) -> Self {
        Self((0..n as u32).collect())
    }
    fn find(&mut self, mut x: u32) -> u32 {
        while self.0[x as usize] != x {
            let p = self.0[self.0[x as usize] as usize];
            self.0[x as usize] = p;
            x = p;
        }
        x
    }
    fn union(&mut self, a: u32, b: u32) -> bool {
        let (a, b) = (self.find(a), self.find(b));
        if a == b {
            return false;
        }
        self.0[a.max(b) as usize] = a.min(b);
        true
    }
}

/// Splits along `cut` (and the boundary): corners of triangles that meet across an uncut edge share
/// a vertex; triangles that meet across one share a piece.
fn split(
    topo: &Topology,
    faces: &HashMap<(u32, u32), Vec<u32>>,
    cut: &[[u32; 2]],
) -> (Vec<Piece>, Vec<Option<(u32, u32)>>) {
    let nt = topo.triangles.len();
    let cut: rustc_hash::FxHashSet<(u32, u32)> = cut.iter().map(|e| (e[0], e[1])).collect();
    let mut corners = Sets::new(nt * 3);
    let mut tris = Sets::new(nt);
    let corner = |t: u32, w: u32| -> u32 {
        let k = topo.triangles[t as usize]
            .iter()
            .position(|&x| x == w)
            .expect("edge vertex is in its triangle");
        t * 3 + k as u32
    };
    let mut keys: Vec<&(u32, u32)> = faces.keys().collect();
    keys.sort_unstable();
    for &(a, b) in keys {
        let f = &faces[&(a, b)];
        if f.len() != 2 || cut.contains(&(a, b)) {
            continue;
        }
        tris.union(f[0], f[1]);
        corners.union(corner(f[0], a), corner(f[1], a));
        corners.union(corner(f[0], b), corner(f[1], b));
    }
    let mut piece_of: HashMap<u32, u32> = HashMap::new();
    let mut vertex_of: HashMap<u32, u32> = HashMap::new();
    let mut pieces: Vec<Piece> = Vec::new();
    let mut triangle_piece = vec![None; nt];
    for t in 0..nt as u32 {
        if topo.degenerate[t as usize] {
            continue;
        }
        let root = tris.find(t);
        let p = *piece_of.entry(root).or_insert_with(|| {
            pieces.push(Piece {
                welded: Vec::new(),
                triangles: Vec::new(),
                source: Vec::new(),
                boundary: Vec::new(),
            });
            pieces.len() as u32 - 1
        });
        let piece = &mut pieces[p as usize];
        let mut local = [0u32; 3];
        for (k, l) in local.iter_mut().enumerate() {
            let c = corners.find(t * 3 + k as u32);
            *l = *vertex_of.entry(c).or_insert_with(|| {
                piece.welded.push(topo.triangles[t as usize][k]);
                piece.welded.len() as u32 - 1
            });
        }
        triangle_piece[t as usize] = Some((p, piece.triangles.len() as u32));
        piece.triangles.push(local);
        piece.source.push(t);
    }
    for piece in &mut pieces {
        piece.boundary = boundary_loops(&piece.triangles)
            .into_iter()
            .max_by_key(|l| l.len())
            .unwrap_or_default();
    }
    (pieces, triangle_piece)
}

/// The boundary loops of a triangle set (directed edges without their reverse), each walked with
/// the triangles on its left.
pub fn boundary_loops(triangles: &[[u32; 3]]) -> Vec<Vec<u32>> {
    let mut directed: rustc_hash::FxHashSet<(u32, u32)> = Default::default();
    for t in triangles {
        for k in 0..3 {
            directed.insert((t[k], t[(k + 1) % 3]));
        }
    }
    let mut next: HashMap<u32, Vec<u32>> = HashMap::new();
    let mut starts: Vec<(u32, u32)> = directed
        .iter()
        .filter(|(a, b)| !directed.contains(&(*b, *a)))
        .copied()
        .collect();
    starts.sort_unstable();
    for &(a, b) in &starts {
        next.entry(a).or_default().push(b);
    }
    let mut loops = Vec::new();
    for &(a, _) in &starts {
        while next.get(&a).is_some_and(|v| !v.is_empty()) {
            let mut l = vec![a];
            let mut cur = a;
            while let Some(n) = next.get_mut(&cur).and_then(|v| v.pop()) {
                if n == a {
                    break;
                }
                l.push(n);
                cur = n;
            }
            loops.push(l);
        }
    }
    loops
}

/// A piece must be a disk: V − E + F = 1 and one boundary loop.
fn check_disk(topo: &Topology, p: &Piece, i: usize, path: &Path) -> Result<()> {
    let (chi, loops) = disk_shape(p);
    if chi == 1 && loops == 1 {
        return Ok(());
    }
    let w = p.welded[0];
    let at = topo.positions[w as usize];
    Err(Error::mesh(
        path,
        format!(
            "piece {i} of the cut surface (the one holding vertex {w} at ({:.4}, {:.4}, {:.4}), {} triangles) is not a disk: Euler characteristic {chi} with {loops} boundary loops (a disk has 1 and 1){}; the cut must join every hole and open every handle of the piece: add edges to the cut, or use `--cut auto`",
            at.x,
            at.y,
            at.z,
            p.triangles.len(),
            if loops == 0 { ", it is closed" } else { "" }
        ),
    ))
}

/// Dijkstra over the welded edges from `root`, within its component, by `cost` (`hidden`):
/// distances and parents. Edges not in `cost` cost nothing: the automatic cut leaves the mesh's
/// boundary edges out, because a
/// path that runs along the boundary and leaves it twice would cut off the triangles between
/// (measured: halves of Spot came back with pieces of 2 and 14 triangles), while a free boundary
/// is left at most once by any shortest path.
fn shortest_tree(topo: &Topology, root: u32, cost: &Costs, dist: &mut [f64], parent: &mut [u32]) {
    let mut heap = BinaryHeap::new();
    dist[root as usize] = 0.0;
    parent[root as usize] = root;
    heap.push(Reverse((Key(0.0), root)));
    while let Some(Reverse((Key(d), v))) = heap.pop() {
        if d > dist[v as usize] {
            continue;
        }
        let (s, e) = (
            topo.adjacency_offsets[v as usize] as usize,
            topo.adjacency_offsets[v as usize + 1] as usize,
        );
        for &w in &topo.adjacency[s..e] {
            let nd = d + cost.get(&key(v, w)).copied().unwrap_or(0.0);
            if nd < dist[w as usize] {
                dist[w as usize] = nd;
                parent[w as usize] = v;
                heap.push(Reverse((Key(nd), w)));
            }
        }
    }
}

/// Edge costs by welded pair (smaller first).
type Costs = rustc_hash::FxHashMap<(u32, u32), f64>;

/// The automatic cut (module docs) with edge costs `cost` (`hidden::edge_costs`): the opened
/// edges and the terminals.
fn auto_cut(
    topo: &Topology,
    faces: &HashMap<(u32, u32), Vec<u32>>,
    mut cost: Costs,
) -> (Vec<(u32, u32)>, Vec<u32>) {
    let nv = topo.positions.len();
    let used = used_vertices(topo);
    let score = super::tips::tip_score(topo);
    let mut dist = vec![f64::INFINITY; nv];
    let mut parent = vec![u32::MAX; nv];
    let faces_ok: Vec<[u32; 3]> = topo
        .triangles
        .iter()
        .zip(&topo.degenerate)
        .filter(|(_, d)| !**d)
        .map(|(t, _)| *t)
        .collect();
    let loops = boundary_loops(&faces_ok);
    // One root per component: a vertex of its first boundary loop, or its strongest tip.
    let comp_of = vertex_components(topo);
    let mut comp_root: HashMap<u32, u32> = HashMap::new();
    for l in &loops {
        comp_root.entry(comp_of[l[0] as usize]).or_insert(l[0]);
    }
    let open: rustc_hash::FxHashSet<u32> = comp_root.keys().copied().collect();
    for v in 0..nv as u32 {
        let c = comp_of[v as usize];
        if c == u32::MAX || open.contains(&c) {
            continue;
        }
        let r = comp_root.entry(c).or_insert(v);
        if score[v as usize] > score[*r as usize] {
            *r = v;
        }
    }
    let mut roots: Vec<u32> = comp_root.values().copied().collect();
    roots.sort_unstable();
    let mut terminals = roots.clone();
    for e in &topo.boundary_edges {
        cost.remove(&key(e[0], e[1]));
    }
    for &r in &roots {
        shortest_tree(topo, r, &cost, &mut dist, &mut parent);
    }
    for l in &loops {
        let nearest = *l
            .iter()
            .min_by(|a, b| dist[**a as usize].total_cmp(&dist[**b as usize]))
            .expect("loops are not empty");
        terminals.push(nearest);
    }
    terminals.extend(super::tips::extremities(topo, &score, &used));
    // A closed component whose cut would be a single vertex gets its geodesic diameter's far end.
    for &r in &roots {
        let c = comp_of[r as usize];
        let mine = terminals
            .iter()
            .filter(|&&t| comp_of[t as usize] == c && t != r)
            .count();
        if mine == 0 && !open.contains(&c) {
            let far = (0..nv as u32)
                .filter(|&v| comp_of[v as usize] == c)
                .max_by(|a, b| dist[*a as usize].total_cmp(&dist[*b as usize]))
                .expect("the component has its root");
            terminals.push(far);
        }
    }
    terminals.sort_unstable();
    terminals.dedup();
    let x = cotree_leftovers(topo, faces, &loops, &dist, &parent, &cost);
    let edges = prune(topo, &parent, &x, &terminals, &used);
    (edges, terminals)
}

/// The component of each welded vertex (`u32::MAX` for vertices of no triangle).
fn vertex_components(topo: &Topology) -> Vec<u32> {
    let mut comp = vec![u32::MAX; topo.positions.len()];
    for (t, tri) in topo.triangles.iter().enumerate() {
        if !topo.degenerate[t] {
            for &v in tri {
                comp[v as usize] = topo.triangle_component[t];
            }
        }
    }
    comp
}

fn used_vertices(topo: &Topology) -> Vec<bool> {
    let mut used = vec![false; topo.positions.len()];
    for (t, tri) in topo.triangles.iter().enumerate() {
        if !topo.degenerate[t] {
            for &v in tri {
                used[v as usize] = true;
            }
        }
    }
    used
}

/// The edges left over by a maximum spanning tree of the dual graph (triangles and one virtual face
/// per boundary loop) over the edges not in the primal tree, by the cost of the loop they close.
fn cotree_leftovers(
    topo: &Topology,
    faces: &HashMap<(u32, u32), Vec<u32>>,
    loops: &[Vec<u32>],
    dist: &[f64],
    parent: &[u32],
    cost: &Costs,
) -> Vec<(u32, u32)> {
    let nt = topo.triangles.len() as u32;
    let mut hole_of: HashMap<(u32, u32), u32> = HashMap::new();
    for (i, l) in loops.iter().enumerate() {
        for k in 0..l.len() {
            hole_of.insert(key(l[k], l[(k + 1) % l.len()]), nt + i as u32);
        }
    }
    let in_tree = |a: u32, b: u32| parent[a as usize] == b || parent[b as usize] == a;
    let mut dual: Vec<(f64, (u32, u32), u32, u32)> = faces
        .iter()
        .filter(|(e, _)| !in_tree(e.0, e.1))
        .filter_map(|(&e, f)| {
            let other = if f.len() == 2 {
                f[1]
            } else {
                *hole_of.get(&e)?
            };
            let sigma = dist[e.0 as usize] + dist[e.1 as usize] + cost.get(&e).unwrap_or(&0.0);
            Some((sigma, e, f[0], other))
        })
        .collect();
    dual.sort_unstable_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    let mut sets = Sets::new(nt as usize + loops.len());
    dual.into_iter()
        .filter(|&(_, _, f, g)| !sets.union(f, g))
        .map(|(_, e, _, _)| e)
        .collect()
}

/// `T ∪ X`, with branches that end at a non-terminal removed until none is left.
fn prune(
    topo: &Topology,
    parent: &[u32],
    x: &[(u32, u32)],
    terminals: &[u32],
    used: &[bool],
) -> Vec<(u32, u32)> {
    let nv = topo.positions.len();
    let mut adj: Vec<Vec<u32>> = vec![Vec::new(); nv];
    let add = |a: u32, b: u32, adj: &mut Vec<Vec<u32>>| {
        adj[a as usize].push(b);
        adj[b as usize].push(a);
    };
    for v in 0..nv as u32 {
        let p = parent[v as usize];
        if used[v as usize] && p != u32::MAX && p != v {
            add(v, p, &mut adj);
        }
    }
    for &(a, b) in x {
        add(a, b, &mut adj);
    }
    let mut keep = vec![false; nv];
    for &t in terminals {
        keep[t as usize] = true;
    }
    let mut stack: Vec<u32> = (0..nv as u32)
        .filter(|&v| adj[v as usize].len() == 1 && !keep[v as usize])
        .collect();
    while let Some(v) = stack.pop() {
        if adj[v as usize].len() != 1 || keep[v as usize] {
            continue;
        }
        let w = adj[v as usize].pop().expect("one neighbour");
        let list = &mut adj[w as usize];
        list.remove(list.iter().position(|&u| u == v).expect("symmetric"));
        if list.len() == 1 {
            stack.push(w);
        }
    }
    let mut out = Vec::new();
    for (v, list) in adj.iter().enumerate() {
        for &w in list {
            if (v as u32) < w {
                out.push((v as u32, w));
            }
        }
    }
    out
}

/// The welded edges of an artist's cut drawn as a polyline of surface points: each point snaps to
/// the nearest welded vertex, and consecutive ones are joined by the shortest path along the edges.
pub fn polyline_edges(topo: &Topology, points: &[[f32; 3]]) -> Vec<[u32; 2]> {
    let nearest = |p: glam::Vec3| -> u32 {
        (0..topo.positions.len() as u32)
            .min_by(|a, b| {
                topo.positions[*a as usize]
                    .distance_squared(p)
                    .total_cmp(&topo.positions[*b as usize].distance_squared(p))
            })
            .unwrap_or(0)
    };
    let snapped: Vec<u32> = points
        .iter()
        .map(|p| nearest(glam::Vec3::from(*p)))
        .collect();
    let nv = topo.positions.len();
    let mut edges = Vec::new();
    for w in snapped.windows(2) {
        let (mut dist, mut parent) = (vec![f64::INFINITY; nv], vec![u32::MAX; nv]);
        shortest_tree(topo, w[0], &Default::default(), &mut dist, &mut parent);
        let mut v = w[1];
        while parent[v as usize] != u32::MAX && parent[v as usize] != v {
            let p = parent[v as usize];
            edges.push([v.min(p), v.max(p)]);
            v = p;
        }
    }
    edges
}
