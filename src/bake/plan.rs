// SPDX-License-Identifier: MIT OR Apache-2.0
//! Raster planning: which texel rectangles a layer's triangles are drawn into, and how those raster
//! jobs are packed into atlas targets. Plain CPU code over the selection stage's cell masks.

use super::params::Params;

/// Largest raster target side, in samples. A raster job covers at most `TILE_TARGET / ss` texels a side.
pub const TILE_TARGET: u32 = 2048;

/// Side, in texels, of the compose's empty-block mask's blocks (`wgsl/shared/blocks.wgsl`): the
/// raster marks the blocks it leaves anything in, the compose skips the rest.
pub const BLOCK: u32 = 8;

/// Words a row of the block mask: the blocks of the widest atlas target (one sample a texel).
pub const BLOCKS_ROW: u32 = TILE_TARGET / BLOCK;

/// Side of a cell of the per-layer coverage mask, in texels.
pub const CELL: u32 = 64;

/// Raster rectangles covering the marked cells of a layer's mask: runs of marked cells along each
/// cell row, merged downwards while the next row has the same run, each at most `max_side` texels a
/// side and clipped to the texture.
pub fn plan_cells(
    mask: &[i32],
    grid: [u32; 2],
    cell: u32,
    tex: [u32; 2],
    max_side: u32,
) -> Vec<[i32; 4]> {
    let bit = |cx: u32, cy: u32| {
        let b = cy * grid[0] + cx;
        (mask[(b / 32) as usize] as u32 >> (b % 32)) & 1 == 1
    };
    let max_cells = (max_side / cell).max(1);
    // Runs per row: (x0, x1) in cells, half-open.
    let mut open: Vec<[u32; 4]> = Vec::new(); // x0, x1, y0, y1 (cells)
    let mut done: Vec<[u32; 4]> = Vec::new();
    for cy in 0..grid[1] {
        let mut runs = Vec::new();
        let mut cx = 0;
        while cx < grid[0] {
            if bit(cx, cy) {
                let x0 = cx;
                while cx < grid[0] && bit(cx, cy) && cx - x0 < max_cells {
                    cx += 1;
                }
                runs.push((x0, cx));
            } else {
                cx += 1;
            }
        }
        let mut next_open = Vec::new();
        for r in open.drain(..) {
            if let Some(k) = runs.iter().position(|&(a, b)| a == r[0] && b == r[1]) {
                if r[3] - r[2] < max_cells {
                    runs.remove(k);
                    next_open.push([r[0], r[1], r[2], cy + 1]);
                    continue;
                }
            }
            done.push(r);
        }
        for (a, b) in runs {
            next_open.push([a, b, cy, cy + 1]);
        }
        open = next_open;
    }
    done.extend(open);
    done.iter()
        .map(|r| {
            let x0 = r[0] * cell;
            let y0 = r[2] * cell;
            let x1 = (r[1] * cell).min(tex[0]);
            let y1 = (r[3] * cell).min(tex[1]);
            [x0 as i32, y0 as i32, (x1 - x0) as i32, (y1 - y0) as i32]
        })
        .collect()
}

/// Pooled target side for a raster rectangle: the next power of two of its samples, at least 64.
pub fn target_side(rect: [u32; 2], ss: u32) -> u32 {
    (rect[0].max(rect[1]) * ss)
        .next_power_of_two()
        .clamp(64, TILE_TARGET)
}

/// Splits rectangle (x, y, w, h) into pieces of at most `tile` a side.
pub fn split_rect(r: [i32; 4], tile: u32) -> Vec<[i32; 4]> {
    let t = tile as i32;
    let mut out = Vec::new();
    let mut y = r[1];
    while y < r[1] + r[3] {
        let hh = t.min(r[1] + r[3] - y);
        let mut x = r[0];
        while x < r[0] + r[2] {
            let ww = t.min(r[0] + r[2] - x);
            out.push([x, y, ww, hh]);
            x += ww;
        }
        y += hh;
    }
    out
}

/// Integer UV tiles (min u, min v, max u, max v) a UV set touches.
pub fn uv_tile_range(uvs: &[glam::Vec2]) -> [i32; 4] {
    let mut r = [i32::MAX, i32::MAX, i32::MIN, i32::MIN];
    for u in uvs {
        // A UV exactly on 1.0 belongs to tile 0.
        let tx = if u.x == u.x.floor() && u.x > 0.0 {
            u.x as i32 - 1
        } else {
            u.x.floor() as i32
        };
        let ty = if u.y == u.y.floor() && u.y > 0.0 {
            u.y as i32 - 1
        } else {
            u.y.floor() as i32
        };
        r = [r[0].min(tx), r[1].min(ty), r[2].max(tx), r[3].max(ty)];
    }
    if r[0] == i32::MAX {
        return [0, 0, 0, 0];
    }
    // Guard against absurd UV ranges (each tile is a full-texture raster pass).
    [r[0].max(-8), r[1].max(-8), r[2].min(8), r[3].min(8)]
}

/// Raster jobs packed into one atlas target: (job index, origin in samples) and the height used.
pub type Batch = (Vec<(usize, [u32; 2])>, u32);

/// Packs raster rectangles (sizes in texels), in order, into atlas batches of [`TILE_TARGET`]
/// samples a side: rows filled left to right, a new batch when a job would overflow the bottom,
/// and at every job `starts` marks (the first of a job layer: a decal, or a stroke, whose stamps
/// share their targets). Returns each job's origin in samples and the batches; each batch is one
/// render pass (one clear).
///
/// A layer's places depend on its own rectangles only, so a layer draws the same samples, bit for
/// bit, whatever the other layers are: the rasterizer's arithmetic depends on where a triangle
/// lies in its target (one 8-bit step differed on a texel after an edit when layers shared
/// batches), and a live bake's edit re-draws some layers into the places a full bake of the
/// edited job gives them (`bake/live.rs`).
pub fn pack_atlas(sizes: &[[u32; 2]], starts: &[bool], ss: u32) -> (Vec<[u32; 2]>, Vec<Batch>) {
    let mut origins = Vec::with_capacity(sizes.len());
    let mut batches: Vec<Batch> = Vec::new();
    let (mut cur, mut sx, mut sy, mut sh) = (Vec::new(), 0u32, 0u32, 0u32);
    for (k, s) in sizes.iter().enumerate() {
        let (jw, jh) = (s[0] * ss, s[1] * ss);
        if sx + jw > TILE_TARGET {
            sy += sh;
            sx = 0;
            sh = 0;
        }
        if (sy + jh > TILE_TARGET || starts[k]) && !cur.is_empty() {
            batches.push((std::mem::take(&mut cur), sy + sh));
            (sx, sy, sh) = (0, 0, 0);
        }
        origins.push([sx, sy]);
        cur.push((k, [sx, sy]));
        sx += jw;
        sh = sh.max(jh);
    }
    if !cur.is_empty() {
        batches.push((cur, sy + sh));
    }
    (origins, batches)
}

/// Whether rectangle `r` (x, y, w, h, texels) meets the canvas window `win` (x, y, w, h).
pub fn meets(r: [i32; 4], win: [u32; 4]) -> bool {
    let w = win.map(|v| v as i32);
    r[0] < w[0] + w[2] && w[0] < r[0] + r[2] && r[1] < w[1] + w[3] && w[1] < r[1] + r[3]
}

/// The raster jobs that cover a texture laid out by `uvs` at `ss`² samples a texel: every UV tile
/// the layout reaches, split into rectangles of at most `TILE_TARGET / ss` texels a side (those
/// that meet the canvas window `global.win`: a tile draws exactly the rectangles, so exactly the
/// samples, that the whole texture's bake draws there),
/// each a copy of `global` with its rectangle and tile (the islands' and the texture transfer's
/// passes).
pub fn raster_jobs(uvs: &[glam::Vec2], global: Params) -> Vec<Params> {
    let range = uv_tile_range(uvs);
    let mut jobs = Vec::new();
    for tj in range[1]..=range[3] {
        for ti in range[0]..=range[2] {
            let [w, h] = global.tex_size.map(|v| v as i32);
            let split = split_rect([0, 0, w, h], TILE_TARGET / global.ss);
            for rect in split.into_iter().filter(|r| meets(*r, global.window())) {
                jobs.push(Params {
                    rect_origin: [rect[0], rect[1]],
                    rect_size: [rect[2] as u32, rect[3] as u32],
                    tile: [ti, tj],
                    ..global
                });
            }
        }
    }
    jobs
}
