// SPDX-License-Identifier: MIT OR Apache-2.0
//! The planar method: the tangent-plane projection of Schmidt, Grimm & Wyvill 2006 (section 3, the
//! projection their exponential map improves upon). Kernel `wgsl/maps/planar_coords.wgsl`, recorded in
//! the map stage's direct pass ([`super::MapMethod::record`]); CPU twin [`planar_coords`].

use crate::maps::Frame;
use crate::mesh::bvh::Bvh;
use crate::mesh::Topology;
use glam::Vec3;

/// CPU twin of `planar_coords.wgsl`: `(x, y, depth, valid)` per welded vertex.
pub fn planar_coords(topo: &Topology, f: &Frame) -> Vec<[f32; 4]> {
    topo.positions
        .iter()
        .map(|p| {
            let d = *p - f.center;
            let z = d.dot(f.normal);
            [
                d.dot(f.axis_u),
                d.dot(f.axis_v),
                z,
                if z.abs() <= f.depth { 1.0 } else { 0.0 },
            ]
        })
        .collect()
}

/// `"method": "planar"`.
pub struct Planar;

impl super::MapMethod for Planar {
    fn front_facing(&self) -> bool {
        true
    }

    fn record(
        &self,
        cx: &super::Record<'_>,
        pass: &mut wgpu::ComputePass<'_>,
        offsets: &[u32],
    ) -> u32 {
        let bg = cx.pipes.planar_coords.bind(
            cx.device,
            "bake.planar_coords",
            &[
                (0, cx.params.clone()),
                (1, cx.mesh.gpu.positions.as_entire_binding()),
                (2, cx.coords.as_entire_binding()),
            ],
        );
        pass.set_pipeline(&cx.pipes.planar_coords.pipeline);
        for &off in offsets {
            pass.set_bind_group(0, &bg, &[off]);
            pass.dispatch_workgroups(cx.mesh.gpu.vertex_count.div_ceil(64), 1, 1);
        }
        offsets.len() as u32
    }

    fn reach(&self, topo: &Topology, bvh: &Bvh, frame: &Frame) -> Option<Vec<u32>> {
        Some(reach(topo, bvh, frame))
    }

    fn cpu_coords(
        &self,
        topo: &Topology,
        _layer: &crate::io::job::Layer,
        frame: &Frame,
        _at: (u32, bool),
        _expmap: Option<Vec<[f32; 4]>>,
    ) -> super::CpuCoords {
        super::CpuCoords {
            coords: planar_coords(topo, frame),
            cone: None,
        }
    }
}

/// The vertices a planar decal's selection needs: those of the triangles near the decal's box (its
/// rectangle times the depth limit), found in the mesh's BVH. The selection keeps a triangle whose
/// coordinate box, in the decal's frame, meets that box; every point of a triangle's box lies within
/// √3 × its longest edge of one of its corners, so such a triangle has a corner within
/// √3 × [`Bvh::max_edge`] of the decal's box, and its world box meets the decal's world box grown by
/// that much. The triangles around these vertices are therefore a superset of what a pass over the
/// whole mesh selects ([`crate::bake::cpu::select_triangles`] is that pass; the tests compare).
pub fn reach(topo: &Topology, bvh: &Bvh, frame: &Frame) -> Vec<u32> {
    let ext = frame.axis_u.abs() * (0.5 * frame.size[0])
        + frame.axis_v.abs() * (0.5 * frame.size[1])
        + frame.normal.abs() * frame.depth;
    let grow = Vec3::splat(3f32.sqrt() * bvh.max_edge);
    let lo = frame.center - ext - grow;
    let hi = frame.center + ext + grow;
    let mut verts: Vec<u32> = bvh
        .overlapping(lo, hi)
        .into_iter()
        .flat_map(|t| topo.triangles[t as usize])
        .collect();
    verts.sort_unstable();
    verts.dedup();
    verts
}
