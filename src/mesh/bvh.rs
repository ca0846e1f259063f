// SPDX-License-Identifier: MIT OR Apache-2.0
//! A bounding-volume hierarchy over the welded, non-degenerate triangles: placement walks it on the
//! GPU (`wgsl/place/place_bvh.wgsl`: one invocation per query, nearest child first, pruning boxes
//! farther than the best hit so far) instead of testing every triangle against every query, and the
//! selection of planar decals asks it on the CPU for the triangles near the decal's box
//! ([`Bvh::overlapping`]) instead of testing the whole mesh.
//!
//! Built on the CPU when a mesh is prepared: median splits along the longest axis of the centroids'
//! box (`select_nth_unstable`, ties by triangle id, so the tree is deterministic), leaves of at most
//! [`LEAF`] triangles, the two children of a node stored next to each other. Balanced by
//! construction: depth ⌈log₂(n / LEAF)⌉ + 1, so the GPU's fixed traversal stack ([`MAX_DEPTH`])
//! always suffices. Boxes are padded by [`PAD`] of the mesh's size (or of its largest coordinate,
//! for a mesh far from the origin) so that f32 rounding in the box tests never prunes a triangle
//! the brute-force test would pick.

use super::Topology;
use glam::Vec3;

/// Most triangles in a leaf.
pub const LEAF: usize = 4;
/// Relative padding of every box (times the larger of the mesh's bounding-box diagonal and its
/// largest coordinate).
pub const PAD: f32 = 1e-5;
/// Deepest tree a build may give: the GPU walk's stack (`STACK` = 64 in place_bvh.wgsl) needs
/// depth + 1 entries. The median split stays far below (depth 17 for 171k triangles); the GPU
/// build's tree (`super::lbvh`) is as deep as its Morton codes make it (at most 31 + ⌈log₂
/// leaves⌉) and refuses a deeper one.
pub const MAX_DEPTH: usize = 62;

/// One node, as the GPU reads it. Keep in sync with `Node` in wgsl/shared/bvh_node.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct BvhNode {
    /// Box minimum.
    pub lo: [f32; 3],
    /// Internal node: index of the first child (the second is next to it); leaf: first entry in
    /// [`Bvh::triangles`].
    pub first: u32,
    /// Box maximum.
    pub hi: [f32; 3],
    /// Leaf: its triangle count; internal node: 0.
    pub count: u32,
}

/// The hierarchy: nodes (root first) and the triangles in leaf order.
#[derive(Debug, Clone, Default)]
pub struct Bvh {
    /// Nodes, root at 0 (empty for a mesh without triangles).
    pub nodes: Vec<BvhNode>,
    /// Welded triangle ids, grouped by leaf.
    pub triangles: Vec<u32>,
    /// Depth of the deepest leaf (the root is depth 1).
    pub depth: usize,
    /// The longest edge of any triangle in the tree: every point of a triangle's box is within
    /// √3 times this of one of its corners.
    pub max_edge: f32,
}

impl Bvh {
    /// Builds the hierarchy over `topo`'s non-degenerate triangles.
    pub fn build(topo: &Topology) -> Self {
        let mut tris: Vec<u32> = (0..topo.triangles.len() as u32)
            .filter(|&t| !topo.degenerate[t as usize])
            .collect();
        if tris.is_empty() {
            return Self::default();
        }
        let corners = |t: u32| topo.triangles[t as usize].map(|v| topo.positions[v as usize]);
        let centroid = |t: u32| corners(t).iter().sum::<Vec3>() / 3.0;
        let bounds = |ts: &[u32]| {
            ts.iter()
                .flat_map(|&t| corners(t))
                .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| {
                    (lo.min(p), hi.max(p))
                })
        };
        let (lo, hi) = bounds(&tris);
        let pad = padding(lo, hi);
        let mut nodes = vec![BvhNode {
            lo: [0.0; 3],
            first: 0,
            hi: [0.0; 3],
            count: 0,
        }];
        let mut depth = 0;
        // (node, range of `tris`, depth)
        let mut work = vec![(0usize, 0usize, tris.len(), 1usize)];
        while let Some((node, start, end, d)) = work.pop() {
            depth = depth.max(d);
            let part = &mut tris[start..end];
            let (lo, hi) = bounds(part);
            nodes[node].lo = (lo - Vec3::splat(pad)).to_array();
            nodes[node].hi = (hi + Vec3::splat(pad)).to_array();
            if part.len() <= LEAF {
                nodes[node].first = start as u32;
                nodes[node].count = part.len() as u32;
                continue;
            }
            let (clo, chi) = part
                .iter()
                .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &t| {
                    (lo.min(centroid(t)), hi.max(centroid(t)))
                });
            let axis = (chi - clo).max_position();
            let mid = part.len() / 2;
            part.select_nth_unstable_by(mid, |&a, &b| {
                centroid(a)[axis]
                    .total_cmp(&centroid(b)[axis])
                    .then(a.cmp(&b))
            });
            let first = nodes.len();
            nodes[node].first = first as u32;
            nodes.extend([nodes[node]; 2]);
            work.push((first, start, start + mid, d + 1));
            work.push((first + 1, start + mid, end, d + 1));
        }
        assert!(
            depth <= MAX_DEPTH,
            "a median-split tree of {} triangles has depth {depth}",
            tris.len()
        );
        let max_edge = longest_edge(topo, &tris);
        Self {
            nodes,
            triangles: tris,
            depth,
            max_edge,
        }
    }

    /// Whether the ray `o + t d` hits any triangle of `topo` (both sides) for `t` in
    /// (`tmin`, `tmax`): the walk stops at the first hit (ambient occlusion, `pelt::hidden`).
    /// Children are visited nearer box first (an occluded ray, the common case, meets its blocker
    /// sooner) from a stack on the call's own frame (at most one entry per level and one more:
    /// [`MAX_DEPTH`] + 1); the answer does not depend on the order. Both took the exposure of bob
    /// subdivided twice (1.4M rays) from 1.27 s to 0.50 s (`pelt::hidden` says how to measure).
    pub fn any_hit(&self, topo: &Topology, o: Vec3, d: Vec3, tmin: f32, tmax: f32) -> bool {
        if self.nodes.is_empty() {
            return false;
        }
        let inv = d.recip();
        // Slab test (infinite reciprocals of zero components give the right answer unless the
        // origin lies exactly on a slab, where NaN compares false and the node is visited):
        // where the ray enters node i's box, if it does within (tmin, tmax).
        let enter = |i: usize| -> Option<f32> {
            let n = &self.nodes[i];
            let t1 = (Vec3::from(n.lo) - o) * inv;
            let t2 = (Vec3::from(n.hi) - o) * inv;
            let near = t1.min(t2).max_element().max(tmin);
            let far = t1.max(t2).min_element().min(tmax);
            (near <= far || near.is_nan() || far.is_nan()).then_some(near)
        };
        if enter(0).is_none() {
            return false;
        }
        let mut stack = [0u32; MAX_DEPTH + 1];
        let mut sp = 1;
        while sp > 0 {
            sp -= 1;
            let n = &self.nodes[stack[sp] as usize];
            let first = n.first as usize;
            if n.count == 0 {
                let (a, b) = (first as u32, first as u32 + 1);
                match (enter(first), enter(first + 1)) {
                    (Some(ta), Some(tb)) => {
                        let (near, far) = if ta <= tb { (a, b) } else { (b, a) };
                        stack[sp] = far;
                        stack[sp + 1] = near;
                        sp += 2;
                    }
                    (Some(_), None) => {
                        stack[sp] = a;
                        sp += 1;
                    }
                    (None, Some(_)) => {
                        stack[sp] = b;
                        sp += 1;
                    }
                    (None, None) => {}
                }
                continue;
            }
            for &t in &self.triangles[first..first + n.count as usize] {
                let [a, b, c] = topo.triangles[t as usize].map(|v| topo.positions[v as usize]);
                let (h, _, _) = ray_triangle(o, d, a, b, c);
                if h > tmin && h < tmax {
                    return true;
                }
            }
        }
        false
    }

    /// The triangles whose (padded) leaf boxes overlap the box `lo`..`hi`, ascending: a superset of
    /// those whose own boxes overlap it.
    pub fn overlapping(&self, lo: Vec3, hi: Vec3) -> Vec<u32> {
        let mut out = Vec::new();
        if self.nodes.is_empty() {
            return out;
        }
        let mut stack = vec![0usize];
        while let Some(i) = stack.pop() {
            let n = &self.nodes[i];
            if Vec3::from(n.lo).cmpgt(hi).any() || Vec3::from(n.hi).cmplt(lo).any() {
                continue;
            }
            let first = n.first as usize;
            if n.count > 0 {
                out.extend_from_slice(&self.triangles[first..first + n.count as usize]);
            } else {
                stack.extend([first, first + 1]);
            }
        }
        out.sort_unstable();
        out
    }
}

/// The padding of every box of a tree over the bounds `lo`..`hi` ([`PAD`] times the larger of the
/// diagonal and the largest coordinate: rounding in the keys grows with the coordinates'
/// magnitude, not only the mesh's size). Both builds use it (`super::lbvh`).
pub(crate) fn padding(lo: Vec3, hi: Vec3) -> f32 {
    let scale = (hi - lo).length().max(lo.abs().max(hi.abs()).max_element());
    PAD * scale.max(f32::MIN_POSITIVE) + 1e-30
}

/// The longest edge of `tris` ([`Bvh::max_edge`]).
pub(crate) fn longest_edge(topo: &Topology, tris: &[u32]) -> f32 {
    tris.iter().fold(0.0f32, |m, &t| {
        let c = topo.triangles[t as usize].map(|v| topo.positions[v as usize]);
        m.max(c[0].distance(c[1]))
            .max(c[1].distance(c[2]))
            .max(c[2].distance(c[0]))
    })
}

/// Ray/triangle (Moller-Trumbore, both sides): (t, u, v), t < 0 on a miss. Twin of `ray_triangle` in the placement kernels (`wgsl/place/`).
pub fn ray_triangle(o: Vec3, d: Vec3, a: Vec3, b: Vec3, c: Vec3) -> (f32, f32, f32) {
    let e1 = b - a;
    let e2 = c - a;
    let pv = d.cross(e2);
    let det = e1.dot(pv);
    if det.abs() < 1e-30 {
        return (-1.0, 0.0, 0.0);
    }
    let inv = 1.0 / det;
    let tv = o - a;
    let u = tv.dot(pv) * inv;
    if !(0.0..=1.0).contains(&u) {
        return (-1.0, 0.0, 0.0);
    }
    let qv = tv.cross(e1);
    let v = d.dot(qv) * inv;
    if v < 0.0 || u + v > 1.0 {
        return (-1.0, 0.0, 0.0);
    }
    (e2.dot(qv) * inv, u, v)
}
