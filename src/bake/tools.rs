// SPDX-License-Identifier: MIT OR Apache-2.0
//! The blur and smear tools (Maillot section 10), part of the compose stage: before a chunk's raster,
//! each tool stamp's view of the canvas is rendered into its own flat R × R cell by inverse rendering
//! (`wgsl/bake/stamp_flatten.wgsl`: the stamp's triangles drawn at their stamp coordinates, fetching
//! the canvas at their UVs), then filtered in that flat space (`wgsl/bake/stamp_filter.wgsl`: a
//! Gaussian blur per cell, or the smear's carried colour from stamp to stamp), and the stamps paint
//! the result back with their image's alpha as the shape (`layer_raster`, `FLAG_TOOL`). Because the
//! filter runs in the stamp's flat space, it does not see UV seams. CPU twins: `flatten_cpu`,
//! `blur_cpu`, `smear_cpu` in [`crate::bake::cpu`].
//!
//! A tool stroke starts a chunk, and a new one every [`MAX_FLATS`] units, so the canvas it reads is
//! the layers below it (its own stamps build up in the stroke buffer until it is applied) and one
//! atlas of cells stays within texture limits.

use super::canvas::Canvas;
use super::maps::LayerMaps;
use super::params::{params_buffer, pbind, Params, PARAMS_STRIDE};
use super::place::Placed;
use super::stage::Cx;
use crate::gpu::BufferInit;
use crate::io::job::Tool;
use std::collections::HashMap;

pub use super::params::{FLAT_COLS, FLAT_RES};
/// Most tool units in one chunk (the atlas then has 64 rows of cells, 4096 texels high).
pub const MAX_FLATS: usize = 1024;

/// The chunk's filtered flat images: one cell per tool stamp.
pub struct Flats {
    /// `FLAT_RES`² straight-colour texels per cell, cell k for the k-th flattened unit of [`cells`]
    /// (alpha 0: nothing known there).
    pub buffer: wgpu::Buffer,
}

/// The units that start a chunk because of tools: each blur or smear stroke's first unit, and every
/// [`MAX_FLATS`]-th after it.
pub fn chunk_starts(placed: &Placed) -> Vec<usize> {
    placed
        .strokes
        .iter()
        .filter(|s| s.tool.reads_canvas())
        .flat_map(|s| s.units.clone().step_by(MAX_FLATS))
        .collect()
}

/// The chunk's flattened units, in order (the k-th has cell k: a blur or smear stroke's stamps, a
/// clone's source stamps), and the cell each drawn tool stamp reads.
pub fn cells(maps: &LayerMaps, placed: &Placed) -> (Vec<usize>, HashMap<usize, u32>) {
    let flattened: Vec<usize> = maps
        .range
        .clone()
        .filter(|&u| !placed.hidden[u])
        .filter(|&u| placed.stroke_of(u).is_some_and(|s| s.tool.reads_canvas()))
        .filter(|&u| placed.clone_of[u].is_none())
        .collect();
    let cell: HashMap<usize, u32> = flattened
        .iter()
        .enumerate()
        .map(|(k, &u)| (u, k as u32))
        .collect();
    let reads = maps
        .range
        .clone()
        .filter(|&u| !placed.sources[u])
        .filter_map(|u| match placed.clone_of[u] {
            Some(s) => cell.get(&s).map(|&c| (u, c)),
            None => cell.get(&u).map(|&c| (u, c)),
        })
        .collect();
    (flattened, reads)
}

/// In a tile of a tiled bake ([`super::tiles`]), a tool stamp reads the canvas around it, and that
/// must be inside the tile's window: a stamp whose texel box (one texel of bilinear reach around
/// it) crosses the window's border is refused, naming it ([`crate::Error::Placement`], renamed to
/// its layer and stamp by the caller), rather than blurred with a hole. Whole-texture canvases pass.
pub(crate) fn check_window(
    canvas: &Canvas,
    maps: &LayerMaps,
    stats: &[i32],
    placed: &Placed,
    source: &std::path::Path,
) -> crate::error::Result<()> {
    let g = canvas.global;
    let win = g.window().map(|v| v as i32);
    if win[..] == [0, 0, g.tex_size[0] as i32, g.tex_size[1] as i32] {
        return Ok(());
    }
    for u in cells(maps, placed).0 {
        let b = &canvas.row(stats, u)[1..5];
        if b[0] > b[2] {
            continue;
        }
        // The texels the stamp may read: its box, one more each side for the bilinear fetch.
        let reach = [b[0] - 1, b[1] - 1, b[2] - b[0] + 3, b[3] - b[1] + 3];
        let within = reach[0] >= win[0]
            && reach[1] >= win[1]
            && reach[0] + reach[2] <= win[0] + win[2]
            && reach[1] + reach[3] <= win[1] + win[3];
        if super::plan::meets(reach, g.window()) && !within {
            return Err(crate::Error::Placement {
                path: source.to_path_buf(),
                layer: u,
                detail: format!(
                    "this blur, smear or clone stamp (texels {}..{} x {}..{}) crosses the border of a {}x{} tile of this {}x{} texture, and a tiled bake cannot read across tiles; move the stroke off the border, or bake untiled (a texture whose canvas fits one storage buffer, without `texture.tile` or an EXR output)",
                    b[0], b[2], b[1], b[3], win[2], win[3], g.tex_size[0], g.tex_size[1],
                ),
            });
        }
    }
    Ok(())
}

/// Records the inverse rendering and the filter of the chunk's tool stamps into `enc`; `None` when
/// the chunk has none.
pub(crate) fn record(
    cx: Cx<'_>,
    canvas: &Canvas,
    (slots_coords, slots_lists): (&wgpu::Buffer, &wgpu::Buffer),
    maps: &LayerMaps,
    (stats, placed): (&[i32], &Placed),
    enc: &mut wgpu::CommandEncoder,
) -> Option<Flats> {
    let Cx { engine, mesh, job } = cx;
    let start = maps.range.start;
    let units = cells(maps, placed).0;
    let stroke = placed.stroke_of(*units.first()?)?;
    let (dev, pipes) = (&engine.ctx.device, &engine.pipes);
    let n = units.len() as u32;
    let rows = n.div_ceil(FLAT_COLS).next_power_of_two();
    // The pooled raster targets (reused by every bake; rows of cells rounded up to a power of two so
    // that chunks share a few sizes), whose colour target has the layer format.
    let size = [FLAT_COLS * FLAT_RES, rows * FLAT_RES];
    let targets = engine.targets(size, 1);
    let view = &targets.color_view;
    let entries: Vec<Params> = units
        .iter()
        .enumerate()
        .map(|(k, &u)| Params {
            pad: [k as u32, rows],
            win: canvas.global.win,
            ..maps.params[u - start]
        })
        .collect();
    let flat_params = params_buffer(dev, "bake.flat_params", &entries);
    let g = &mesh.gpu;
    let bg = crate::gpu::pipelines::make_bind_group(
        dev,
        &pipes.stamp_flatten.layout,
        "bake.stamp_flatten",
        &[
            (0, pbind(&flat_params)),
            (1, slots_lists.as_entire_binding()),
            (2, g.split_tris.as_entire_binding()),
            (3, g.uvs[job.uv_set as usize].as_entire_binding()),
            (4, g.welded_of.as_entire_binding()),
            (5, slots_coords.as_entire_binding()),
            (10, canvas.acc_rg.as_entire_binding()),
            (11, canvas.acc_ba.as_entire_binding()),
        ],
    );
    {
        let mut pass = crate::gpu::cleared_pass(enc, "bake.stamp_flatten", &[view]);
        pass.set_pipeline(&pipes.stamp_flatten.pipeline);
        for (k, &u) in units.iter().enumerate() {
            let k = k as u32;
            let count = (canvas.row(stats, u)[0].max(0) as u32).min(g.triangle_count);
            pass.set_bind_group(0, &bg, &[(k as u64 * PARAMS_STRIDE) as u32]);
            let (cx0, cy0) = ((k % FLAT_COLS) * FLAT_RES, (k / FLAT_COLS) * FLAT_RES);
            pass.set_scissor_rect(cx0, cy0, FLAT_RES, FLAT_RES);
            pass.draw(0..3 * count, 0..1);
        }
    }
    let cell_bytes = (FLAT_RES * FLAT_RES) as u64 * 16;
    let storage = |label| {
        dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: n as u64 * cell_bytes,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        })
    };
    let (tmp, out) = (storage("bake.flat_tmp"), storage("bake.flat_out"));
    let sigmas: Vec<f32> = units
        .iter()
        .map(|&u| match stroke.tool {
            // The radius is two standard deviations, on the surface; a cell spans the stamp's width.
            Tool::Blur { radius } => 0.5 * radius / job.layers[u].size[0] * FLAT_RES as f32,
            _ => 0.0,
        })
        .collect();
    let sigmas = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("bake.flat_sigmas"),
        contents: bytemuck::cast_slice(&sigmas),
        usage: wgpu::BufferUsages::STORAGE,
    });
    let carry = canvas
        .carry
        .as_ref()
        .expect("a job with strokes has a carry");
    let fresh = u32::from(maps.range.contains(&stroke.units.start));
    let modes: Vec<[u32; 4]> = match stroke.tool {
        Tool::Blur { .. } => vec![[0, n, 0, 0], [1, n, 0, 0]],
        Tool::Smear { strength } => vec![[2, n, strength.to_bits(), fresh]],
        Tool::Clone { .. } => vec![[3, n, 0, 0]],
        Tool::Paint => Vec::new(),
    };
    for m in modes {
        let dims = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("bake.flat_dims"),
            contents: bytemuck::cast_slice(&m),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let bg = pipes.stamp_filter.bind(
            dev,
            "bake.stamp_filter",
            &[
                (0, dims.as_entire_binding()),
                (1, wgpu::BindingResource::TextureView(view)),
                (2, tmp.as_entire_binding()),
                (3, out.as_entire_binding()),
                (4, sigmas.as_entire_binding()),
                (5, carry.as_entire_binding()),
            ],
        );
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("bake.stamp_filter"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&pipes.stamp_filter.pipeline);
        pass.set_bind_group(0, &bg, &[]);
        match m[0] {
            2 => pass.dispatch_workgroups(FLAT_RES / 8, FLAT_RES / 8, 1),
            _ => pass.dispatch_workgroups(size[0] / 8, size[1] / 8, 1),
        }
    }
    Some(Flats { buffer: out })
}
