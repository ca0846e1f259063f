// SPDX-License-Identifier: MIT OR Apache-2.0
//! The planar method: the tangent-plane projection of Schmidt, Grimm & Wyvill 2006 (section 3, the
//! projection their exponential map improves upon). Kernel `wgsl/maps/planar_coords.wgsl`, recorded in
//! the bake's selection pass just before `select_triangles`; CPU twin [`planar_coords`].

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
