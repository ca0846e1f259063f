// SPDX-License-Identifier: MIT OR Apache-2.0
//! The planar method: the tangent-plane projection of Schmidt, Grimm & Wyvill 2006 (section 3, the
//! projection their exponential map improves upon). Kernel `wgsl/maps/planar_coords.wgsl`, recorded in
//! the map stage's direct pass ([`super::MapMethod::record`]); CPU twin [`planar_coords`].

use crate::maps::Frame;
use crate::mesh::Topology;

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
