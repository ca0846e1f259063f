// SPDX-License-Identifier: MIT OR Apache-2.0
//! Stage 4, triangle selection: which triangles each layer of a chunk covers (all three vertices
//! valid in its map, coordinate box meeting the decal rectangle, facing it for projections), appended
//! to the layer's triangle list, with its texel box and the 64×64-texel cells of the texture they
//! touch in its stats row. Each layer tests only its candidate triangles (those with a vertex its
//! map can reach: [`LayerMaps::candidate_triangles`]), so the work follows the decal's size, not the
//! mesh's. Kernel `wgsl/bake/select_triangles.wgsl`; CPU twin
//! [`crate::bake::cpu::select_triangles`] (over the whole mesh).

use super::canvas::Canvas;
use super::maps::{LayerMaps, Slots};
use super::params::{pbind, PARAMS_STRIDE};
use super::place::Placed;
use super::stage::{Cx, Log};
use crate::error::{Error, Result};

/// `ranges` offset of a layer tested against every triangle (`NO_CANDIDATES` in the kernel).
const NO_CANDIDATES: u32 = u32::MAX;

/// Selects the triangles of the chunk's layers on the GPU (not the hidden corner charts of
/// continuous strokes) and reads the stats rows back (every layer's, as the buffer holds them). A
/// layer that covers no triangle is an error naming it.
pub(crate) fn select(
    cx: Cx<'_>,
    canvas: &Canvas,
    (slots, maps): (&Slots, &LayerMaps),
    placed: &Placed,
    log: &mut Log,
) -> Result<Vec<i32>> {
    let Cx { engine, mesh, job } = cx;
    let (dev, pipes, g) = (&engine.ctx.device, &engine.pipes, &mesh.gpu);
    let uvs = &g.uvs[job.uv_set as usize];
    // Each slot's candidate triangles (offset, count) in one list; NO_CANDIDATES: the whole mesh.
    let candidates = if engine.whole_mesh_selection {
        vec![None; maps.range.len()]
    } else {
        maps.candidate_triangles(&mesh.topo)
    };
    let mut ranges: Vec<[u32; 2]> = Vec::with_capacity(candidates.len());
    let mut cands: Vec<u32> = Vec::new();
    for c in &candidates {
        ranges.push(match c {
            Some(t) => {
                cands.extend_from_slice(t);
                [(cands.len() - t.len()) as u32, t.len() as u32]
            }
            None => [NO_CANDIDATES, g.triangle_count],
        });
    }
    engine.ctx.scoped("layer selection", || {
        let none = wgpu::BufferUsages::empty();
        let ranges_buf =
            engine
                .ctx
                .storage_init("bake.select_ranges", bytemuck::cast_slice(&ranges), none);
        let cands_buf =
            engine
                .ctx
                .storage_init("bake.select_candidates", bytemuck::cast_slice(&cands), none);
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
                (8, ranges_buf.as_entire_binding()),
                (9, cands_buf.as_entire_binding()),
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
            let start = maps.range.start;
            for k in (0..maps.range.len()).filter(|&k| !placed.hidden[start + k]) {
                pass.set_bind_group(0, &bg, &[(k as u64 * PARAMS_STRIDE) as u32]);
                pass.dispatch_workgroups(ranges[k][1].div_ceil(64).max(1), 1, 1);
                log.commands += 1;
            }
        }
        engine.ctx.queue.submit([enc.finish()]);
    })?;
    let stats = canvas.read_stats(engine, "layer selection read-back")?;
    for i in maps.range.clone() {
        if !placed.hidden[i] && canvas.row(&stats, i)[0] <= 0 {
            return Err(Error::Placement {
                path: job.source.clone(),
                layer: i,
                detail: "the decal covers no triangle facing it (it misses the mesh, or all triangles under it face away); check `at`, `size` and `depth`".into(),
            });
        }
    }
    Ok(stats)
}
