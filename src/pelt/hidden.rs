// SPDX-License-Identifier: MIT OR Apache-2.0
//! Where a seam shows least: the automatic cut's edge costs. Piponi & Borshukov (§4) leave the cut
//! to the artist, who puts it where nobody looks; the automatic cut is asked to run "through curved
//! or hidden parts rather than across flat visible ones", so each edge costs its length times
//!
//! `(HIDDEN_FLOOR + (1 − HIDDEN_FLOOR) · exposure) / (1 + CREASE · bend)`,
//!
//! - **exposure**: per welded vertex, the cosine-weighted share of the hemisphere round its
//!   normal from which the rest of the model does not hide it (ambient occlusion's open share):
//!   [`RAYS`] fixed directions on a Fibonacci spiral, each tested against the mesh's bounding-volume
//!   hierarchy ([`crate::mesh::bvh::Bvh::any_hit`]), then averaged once with the neighbours (16
//!   rays are coarse). Between the legs, under the chin, inside a crease: low. An edge takes the
//!   mean of its ends.
//! - **bend**: the angle between the normals of an edge's two triangles (0 on a flat, π/2 on a
//!   right-angled crease): a seam along a crease or a sharp fold is where the texture changes
//!   direction anyway.
//!
//! A fully hidden edge costs [`HIDDEN_FLOOR`] of its length, a right-angled crease 1 / (1 + π/2)
//! of it: paths bend towards such places but do not wander across the whole model for them.
//! Tips (the angle defect, `tips`) stay the cut's terminals; these costs decide the way between.
//!
//! The rays run on the CPU, on every core (`std::thread::scope`), as the rest of the cut does; on
//! bob subdivided twice (86k vertices, 1.4M rays) they take 0.50-0.54 s of the cut stage
//! (`stages_ms.exposure` and `cut` of `decalbake bench --unwrap --mesh assets/bob.glb
//! --subdivide 2`), since `Bvh::any_hit` visits the nearer child first from a stack on its frame;
//! 1.27 s before (a one-off timing at commit 10edf91's parent).

use crate::mesh::bvh::Bvh;
use crate::mesh::Topology;
use glam::Vec3;
use rustc_hash::FxHashMap;

/// Rays per vertex.
pub const RAYS: u32 = 16;
/// The cost of a fully hidden edge, as a share of its length.
pub const HIDDEN_FLOOR: f64 = 0.25;
/// How much a bend (radians) lowers an edge's cost.
pub const CREASE: f64 = 1.0;

/// The exposure of every welded vertex of `topo` (module docs), in [0, 1]; vertices of no
/// triangle get 1.
pub fn exposure(topo: &Topology) -> Vec<f32> {
    let bvh = Bvh::build(topo);
    let n = topo.positions.len();
    let (lo, hi) = topo
        .positions
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(l, h), p| {
            (l.min(*p), h.max(*p))
        });
    let eps = 1e-4 * (hi - lo).length().max(1e-12);
    let dirs: Vec<Vec3> = (0..RAYS)
        .map(|k| {
            let u = (k as f32 + 0.5) / RAYS as f32;
            let phi = k as f32 * 2.399_963; // the golden angle
            let r = u.sqrt();
            Vec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u).sqrt())
        })
        .collect();
    let open = |v: usize| -> f32 {
        let nrm = topo.normals[v];
        if nrm == Vec3::ZERO || !nrm.is_finite() {
            return 1.0;
        }
        let (e1, e2) = nrm.any_orthonormal_pair();
        let o = topo.positions[v] + nrm * eps;
        let seen = dirs
            .iter()
            .filter(|d| {
                let dir = e1 * d.x + e2 * d.y + nrm * d.z;
                !bvh.any_hit(topo, o, dir, eps, f32::INFINITY)
            })
            .count();
        seen as f32 / RAYS as f32
    };
    let threads = std::thread::available_parallelism().map_or(1, |t| t.get());
    let chunk = n.div_ceil(threads).max(1);
    let mut raw = vec![1.0f32; n];
    std::thread::scope(|s| {
        for (c, out) in raw.chunks_mut(chunk).enumerate() {
            let open = &open;
            s.spawn(move || {
                for (i, e) in out.iter_mut().enumerate() {
                    *e = open(c * chunk + i);
                }
            });
        }
    });
    (0..n)
        .map(|v| {
            let (s, e) = (
                topo.adjacency_offsets[v] as usize,
                topo.adjacency_offsets[v + 1] as usize,
            );
            let nb = &topo.adjacency[s..e];
            (raw[v] + nb.iter().map(|&w| raw[w as usize]).sum::<f32>()) / (1 + nb.len()) as f32
        })
        .collect()
}

/// The cost of every interior edge (welded ids, smaller first) of the surface whose edge→triangles
/// map is `faces`, given each vertex's `exposure` (module docs).
pub fn edge_costs(
    topo: &Topology,
    faces: &std::collections::HashMap<(u32, u32), Vec<u32>>,
    exposure: &[f32],
) -> FxHashMap<(u32, u32), f64> {
    let normal = |t: u32| {
        let [a, b, c] = topo.triangles[t as usize].map(|v| topo.positions[v as usize]);
        (b - a).cross(c - a).normalize_or_zero()
    };
    faces
        .iter()
        .map(|(&(a, b), f)| {
            let len = (topo.positions[a as usize] - topo.positions[b as usize]).length() as f64;
            let bend = match f[..] {
                [s, t] => normal(s).dot(normal(t)).clamp(-1.0, 1.0).acos() as f64,
                _ => 0.0,
            };
            let seen = 0.5 * (exposure[a as usize] + exposure[b as usize]) as f64;
            let cost = len * (HIDDEN_FLOOR + (1.0 - HIDDEN_FLOOR) * seen) / (1.0 + CREASE * bend);
            ((a, b), cost)
        })
        .collect()
}
