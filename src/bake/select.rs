// SPDX-License-Identifier: MIT OR Apache-2.0
//! Stage 4, triangle selection: which triangles each layer of a chunk covers (all three vertices
//! valid in its map, coordinate box meeting the decal rectangle, facing it for projections), appended
//! to the layer's triangle list, with its texel box and the 64×64-texel cells of the texture they
//! touch in its stats row. Kernel `wgsl/bake/select_triangles.wgsl`; CPU twin [`select_triangles`].

use super::canvas::Canvas;
use super::maps::{LayerMaps, Slots};
use super::params::{pbind, PARAMS_STRIDE};
use super::{Cx, Log};
use crate::error::{Error, Result};
use crate::maps::Frame;
use crate::mesh::{Mesh, Topology};
use glam::Vec2;

/// Selects the triangles of the chunk's layers on the GPU and reads the stats rows back (every
/// layer's, as the buffer holds them). A layer that covers no triangle is an error naming it.
pub(crate) fn select(
    cx: Cx<'_>,
    canvas: &Canvas,
    slots: &Slots,
    maps: &LayerMaps,
    log: &mut Log,
) -> Result<Vec<i32>> {
    let Cx { engine, mesh, job } = cx;
    let (dev, pipes, g) = (&engine.ctx.device, &engine.pipes, &mesh.gpu);
    let uvs = &g.uvs[job.uv_set as usize];
    engine.ctx.scoped("layer selection", || {
        let bg = pipes.select_triangles.bind(
            dev,
            "bake.select_triangles",
            &[
                (0, pbind(&maps.buffer)),
                (1, g.positions.as_entire_binding()),
                (2, g.tris.as_entire_binding()),
                (3, g.split_tris.as_entire_binding()),
                (4, uvs.as_entire_binding()),
                (5, slots.coords.as_entire_binding()),
                (6, slots.lists.as_entire_binding()),
                (7, canvas.stats.as_entire_binding()),
            ],
        );
        let mut enc = dev.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("bake.select"),
        });
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("bake.select"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&pipes.select_triangles.pipeline);
            for k in 0..maps.range.len() {
                pass.set_bind_group(0, &bg, &[(k as u64 * PARAMS_STRIDE) as u32]);
                pass.dispatch_workgroups(g.triangle_count.div_ceil(64), 1, 1);
                log.commands += 1;
            }
        }
        engine.ctx.queue.submit([enc.finish()]);
    })?;
    let stats = canvas.read_stats(engine, "layer selection read-back")?;
    for i in maps.range.clone() {
        if canvas.row(&stats, i)[0] <= 0 {
            return Err(Error::Placement {
                path: job.source.clone(),
                layer: i,
                detail: "the decal covers no triangle facing it (it misses the mesh, or all triangles under it face away); check `at`, `size` and `depth`".into(),
            });
        }
    }
    Ok(stats)
}

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
