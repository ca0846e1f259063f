// SPDX-License-Identifier: MIT OR Apache-2.0
//! Stage 4, triangle selection: which triangles each layer of a chunk covers (all three vertices
//! valid in its map, coordinate box meeting the decal rectangle, facing it for projections), appended
//! to the layer's triangle list, with its texel box and the 64×64-texel cells of the texture they
//! touch in its stats row. Each layer tests only its candidate triangles (those with a vertex its
//! map can reach: `LayerMaps::candidate_triangles`), so the work follows the decal's size, not the
//! mesh's. The list keeps the tested order (candidates sorted by triangle id, or the whole mesh in
//! id order): `select_triangles` marks each tested triangle at its position and `compact_lists`
//! gathers the marks, so overlapping triangles of one layer are drawn in the same order on every
//! run. Kernels `wgsl/bake/select_triangles.wgsl`, `wgsl/bake/compact_lists.wgsl`; CPU twin
//! [`crate::bake::cpu::select_triangles`] (over the whole mesh, in the same order).

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
        // One layer's marks at a time (each layer's selection is compacted before the next is
        // marked): as many entries as the most triangles a layer tests.
        let most = ranges.iter().map(|r| r[1]).max().unwrap_or(0).max(1);
        let marks = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("bake.select_marks"),
            size: most as u64 * 4,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        let compact = pipes.compact_lists.bind(
            dev,
            "bake.compact_lists",
            &[
                (0, pbind(&maps.buffer)),
                (1, ranges_buf.as_entire_binding()),
                (2, marks.as_entire_binding()),
                (3, slots.lists.as_entire_binding()),
            ],
        );
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
                (6, marks.as_entire_binding()),
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
            let start = maps.range.start;
            for k in (0..maps.range.len()).filter(|&k| !placed.hidden[start + k]) {
                let offset = [(k as u64 * PARAMS_STRIDE) as u32];
                pass.set_pipeline(&pipes.select_triangles.pipeline);
                pass.set_bind_group(0, &bg, &offset);
                pass.dispatch_workgroups(ranges[k][1].div_ceil(64).max(1), 1, 1);
                pass.set_pipeline(&pipes.compact_lists.pipeline);
                pass.set_bind_group(0, &compact, &offset);
                pass.dispatch_workgroups(1, 1, 1);
                log.commands += 2;
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
