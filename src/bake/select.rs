// SPDX-License-Identifier: MIT OR Apache-2.0
//! Triangle selection: which triangles a layer covers, and the texel box they touch. Kernel
//! `wgsl/bake/select_triangles.wgsl`; CPU twin [`select_triangles`].

use crate::maps::Frame;
use crate::mesh::{Mesh, Topology};
use glam::Vec2;

/// What `select_triangles` produces for one layer.
#[derive(Debug, Clone, PartialEq)]
pub struct Selection {
    /// Covered triangles, ascending (the GPU appends in any order).
    pub triangles: Vec<u32>,
    /// Texel box (min x, min y, max x, max y), before UV wrapping.
    pub texel_box: [i32; 4],
}

/// CPU twin of `select_triangles.wgsl`.
pub fn select_triangles(
    mesh: &Mesh,
    topo: &Topology,
    uvs: &[Vec2],
    coords: &[[f32; 4]],
    f: &Frame,
    facing: bool,
    tex: [u32; 2],
) -> Selection {
    let mut out = Selection {
        triangles: Vec::new(),
        texel_box: [i32::MAX, i32::MAX, i32::MIN, i32::MIN],
    };
    let (hx, hy) = (0.5 * f.size[0], 0.5 * f.size[1]);
    for (t, tri) in topo.triangles.iter().enumerate() {
        if topo.degenerate[t] {
            continue;
        }
        let c = tri.map(|v| coords[v as usize]);
        if c.iter().any(|c| c[3] < 0.5) {
            continue;
        }
        let lo = Vec2::new(
            c[0][0].min(c[1][0]).min(c[2][0]),
            c[0][1].min(c[1][1]).min(c[2][1]),
        );
        let hi = Vec2::new(
            c[0][0].max(c[1][0]).max(c[2][0]),
            c[0][1].max(c[1][1]).max(c[2][1]),
        );
        if hi.x < -hx || lo.x > hx || hi.y < -hy || lo.y > hy {
            continue;
        }
        if facing {
            let [a, b, cc] = tri.map(|v| topo.positions[v as usize]);
            if (b - a).cross(cc - a).dot(f.normal) <= 0.0 {
                continue;
            }
        }
        out.triangles.push(t as u32);
        let size = Vec2::new(tex[0] as f32, tex[1] as f32);
        let u = mesh.triangles[t].map(|s| uvs[s as usize] * size);
        let tlo = u[0].min(u[1]).min(u[2]).floor();
        let thi = u[0].max(u[1]).max(u[2]).ceil();
        out.texel_box[0] = out.texel_box[0].min(tlo.x as i32);
        out.texel_box[1] = out.texel_box[1].min(tlo.y as i32);
        out.texel_box[2] = out.texel_box[2].max(thi.x as i32);
        out.texel_box[3] = out.texel_box[3].max(thi.y as i32);
    }
    out
}
