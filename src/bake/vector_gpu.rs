// SPDX-License-Identifier: MIT OR Apache-2.0
//! The GPU alternative to resvg for vector images: a flattened document
//! ([`crate::io::vector_paths`]) binned into 16 × 16-pixel tiles on the CPU ([`bin`]) and drawn by
//! point-sampled coverage on the GPU (`wgsl/bake/vector_coverage.wgsl`, [`Engine::draw_flat`];
//! twin [`coverage_cpu`]). `decalbake bench --vector` measures it against resvg at the pixel
//! sizes the bake chooses; bakes render with resvg (the performance chapter says why).
//!
//! One sample a pixel is what evaluating coverage per bake sample in the layer raster would cost:
//! vector images are rendered at two pixels a texel along each side, four a texel, as many as the
//! bake's 2 × 2 samples. `ss` > 1 takes ss × ss samples a pixel (the tests compare with resvg so).
//!
//! Binning: each path gets the tiles its segments' box covers (and each image tile lists the
//! paths whose tiles hold it, so a pixel visits only those); a path's tile lists every segment whose
//! box meets it, and per sample row a backdrop, the signed crossings of that row by the segments
//! whose box lies wholly right of the tile (a segment that crosses a row of the tile inside the
//! tile's columns has a box that meets the tile, so the two never count a crossing twice, and
//! which one counts it is decided from the boxes alone, never from a crossing's rounded x).

use super::engine::Engine;
use crate::error::Result;
use crate::io::vector_paths::{FlatPaint, FlatScene};

/// Tile side, pixels. Keep in sync with `TILE` in `wgsl/bake/vector_coverage.wgsl`.
pub const TILE: u32 = 16;

/// Uniform block of `vector_coverage.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Uni {
    size: [u32; 2],
    ss: u32,
    paths: u32,
}

/// A path's tiles (x0, y0, x1, y1, the last two past the end), first tile record, fill rule and
/// paint offset (`PathRec` in the kernel).
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct PathRec {
    tiles: [u32; 4],
    base: u32,
    even_odd: u32,
    paint: u32,
    pad: u32,
}

/// A scene binned for the kernel: every array it reads.
#[derive(Clone, Debug, Default)]
pub struct Binned {
    /// Pixels.
    pub size: [u32; 2],
    /// Samples a pixel along each side.
    pub ss: u32,
    paths: Vec<PathRec>,
    /// Per tile record: (first entry of `refs`, count).
    tiles: Vec<[u32; 2]>,
    refs: Vec<u32>,
    /// Per tile record, `TILE * ss` rows.
    backdrops: Vec<i32>,
    segs: Vec<[f32; 4]>,
    paints: Vec<[f32; 4]>,
    /// Per image tile (first entry, count), then the entries: (path, tile record).
    grid: Vec<[u32; 2]>,
}

impl Binned {
    /// Segment references over all tiles (a measure of the kernel's work).
    pub fn refs(&self) -> usize {
        self.refs.len()
    }
}

/// Bins `scene` for ss × ss samples a pixel (1, 2 or 4: a power of two keeps the sample rows'
/// positions exact, so the backdrops and the kernel agree on which rows a segment crosses).
pub fn bin(scene: &FlatScene, ss: u32) -> Binned {
    let ss = ss.clamp(1, 4).next_power_of_two();
    let [w, h] = scene.size;
    let (tw_all, th_all) = (w.div_ceil(TILE) as i64, h.div_ceil(TILE) as i64);
    let mut b = Binned {
        size: scene.size,
        ss,
        ..Binned::default()
    };
    let tile = |v: f32| (v / TILE as f32).floor() as i64;
    for path in &scene.paths {
        let Some(bx) = bounds(&path.segments) else {
            continue;
        };
        let (tx0, tx1) = (
            tile(bx[0]).clamp(0, tw_all),
            (tile(bx[2]) + 1).clamp(0, tw_all),
        );
        let (ty0, ty1) = (
            tile(bx[1]).clamp(0, th_all),
            (tile(bx[3]) + 1).clamp(0, th_all),
        );
        if tx0 >= tx1 || ty0 >= ty1 {
            continue;
        }
        let (tw, th) = ((tx1 - tx0) as usize, (ty1 - ty0) as usize);
        let seg0 = b.segs.len() as u32;
        b.segs.extend_from_slice(&path.segments);
        // Tile lists: count, offsets, fill (in segment order).
        let span = |s: &[f32; 4]| {
            let (x0, x1) = (tile(s[0].min(s[2])), tile(s[0].max(s[2])));
            let (y0, y1) = (tile(s[1].min(s[3])), tile(s[1].max(s[3])));
            (x0, x1, y0, y1)
        };
        let mut lists: Vec<Vec<u32>> = vec![Vec::new(); tw * th];
        for (k, s) in path.segments.iter().enumerate() {
            let (x0, x1, y0, y1) = span(s);
            for cy in y0.max(ty0)..=y1.min(ty1 - 1) {
                for cx in x0.max(tx0)..=x1.min(tx1 - 1) {
                    lists[(cy - ty0) as usize * tw + (cx - tx0) as usize].push(seg0 + k as u32);
                }
            }
        }
        // Backdrops: per sample row of the path's tiles, the crossings bucketed by the first
        // tile column of the crossing segment's box (tw: right of every tile), then summed from
        // the right.
        let rows = TILE as usize * ss as usize;
        let mut buckets = vec![0i32; th * rows * (tw + 1)];
        let row_lo = ty0 as usize * rows;
        let row_hi = ty1 as usize * rows;
        for s in &path.segments {
            let (x0, _, _, _) = span(s);
            let col = (x0 - tx0).clamp(0, tw as i64) as usize;
            let (lo, hi) = (s[1].min(s[3]), s[1].max(s[3]));
            let dir = if s[1] < s[3] { 1 } else { -1 };
            let first = ((lo * ss as f32 - 0.5).floor().max(0.0) as usize).max(row_lo);
            let mut j = first;
            while j < row_hi {
                let y = (j as f32 + 0.5) / ss as f32;
                if y >= hi {
                    break;
                }
                if y >= lo {
                    buckets[(j - row_lo) * (tw + 1) + col] += dir;
                }
                j += 1;
            }
        }
        let mut suffix = vec![0i32; th * rows * (tw + 2)];
        for (row, sums) in buckets.chunks(tw + 1).zip(suffix.chunks_mut(tw + 2)) {
            for c in (0..=tw).rev() {
                sums[c] = sums[c + 1] + row[c];
            }
        }
        let base = b.tiles.len() as u32;
        for (i, list) in lists.into_iter().enumerate() {
            b.tiles.push([b.refs.len() as u32, list.len() as u32]);
            b.refs.extend(list);
            let (cy, cx) = (i / tw, i % tw);
            for r in 0..rows {
                // Summed from the right: entry c holds the crossings of buckets c..=tw.
                b.backdrops
                    .push(suffix[(cy * rows + r) * (tw + 2) + cx + 1]);
            }
        }
        b.paths.push(PathRec {
            tiles: [tx0 as u32, ty0 as u32, tx1 as u32, ty1 as u32],
            base,
            even_odd: path.even_odd as u32,
            paint: b.paints.len() as u32,
            pad: 0,
        });
        push_paint(&mut b.paints, &path.paint);
    }
    b.grid = grid(&b.paths, tw_all as u32, th_all as u32);
    b
}

/// The image tiles' lists of (path, tile record), in drawing order, after a (first, count) per
/// tile.
fn grid(paths: &[PathRec], tw: u32, th: u32) -> Vec<[u32; 2]> {
    let tiles = (tw * th) as usize;
    let mut counts = vec![0u32; tiles];
    for p in paths {
        for ty in p.tiles[1]..p.tiles[3] {
            for tx in p.tiles[0]..p.tiles[2] {
                counts[(ty * tw + tx) as usize] += 1;
            }
        }
    }
    let mut grid = Vec::with_capacity(tiles + counts.iter().sum::<u32>() as usize);
    let mut next = tiles as u32;
    for &c in &counts {
        grid.push([next, 0]);
        next += c;
    }
    grid.resize(next as usize, [0, 0]);
    for (i, p) in paths.iter().enumerate() {
        let t = p.tiles;
        for ty in t[1]..t[3] {
            for tx in t[0]..t[2] {
                let cell = (ty * tw + tx) as usize;
                let [first, n] = grid[cell];
                grid[(first + n) as usize] =
                    [i as u32, p.base + (ty - t[1]) * (t[2] - t[0]) + (tx - t[0])];
                grid[cell][1] += 1;
            }
        }
    }
    grid
}

/// The segments' box (x0, y0, x1, y1), `None` when there are none.
fn bounds(segs: &[[f32; 4]]) -> Option<[f32; 4]> {
    let first = segs.first()?;
    let init = [
        first[0].min(first[2]),
        first[1].min(first[3]),
        first[0].max(first[2]),
        first[1].max(first[3]),
    ];
    Some(segs.iter().fold(init, |b, s| {
        [
            b[0].min(s[0]).min(s[2]),
            b[1].min(s[1]).min(s[3]),
            b[2].max(s[0]).max(s[2]),
            b[3].max(s[1]).max(s[3]),
        ]
    }))
}

fn push_paint(out: &mut Vec<[f32; 4]>, paint: &FlatPaint) {
    match paint {
        FlatPaint::Solid(c) => {
            out.push([0.0; 4]);
            out.push(*c);
        }
        FlatPaint::Linear { t, spread, stops } => {
            out.push([1.0, stops.len() as f32, *spread as f32, 0.0]);
            out.push([t[0], t[1], t[2], 0.0]);
            for (o, c) in stops {
                out.push([*o, 0.0, 0.0, 0.0]);
                out.push(*c);
            }
        }
    }
}

/// `paint_at` of the kernel: the straight colour of paint `off` at pixel point `p`.
fn paint_at(paints: &[[f32; 4]], off: usize, p: [f32; 2]) -> [f32; 4] {
    let h = paints[off];
    if h[0] == 0.0 {
        return paints[off + 1];
    }
    let k = paints[off + 1];
    let n = h[1] as usize;
    let mut t = k[0] * p[0] + k[1] * p[1] + k[2];
    if h[2] == 1.0 {
        t -= t.floor();
    } else if h[2] == 2.0 {
        let m = t - 2.0 * (t * 0.5).floor();
        t = if m > 1.0 { 2.0 - m } else { m };
    }
    // Padded ends take the end stops (hard stops at 0 or 1 included).
    if t <= 0.0 {
        return paints[off + 3];
    }
    if t >= 1.0 {
        return paints[off + 3 + 2 * (n - 1)];
    }
    let mut i = 0;
    while i + 2 < n && paints[off + 2 + 2 * (i + 1)][0] <= t {
        i += 1;
    }
    let (o0, o1) = (paints[off + 2 + 2 * i][0], paints[off + 2 + 2 * (i + 1)][0]);
    let (c0, c1) = (paints[off + 3 + 2 * i], paints[off + 3 + 2 * (i + 1)]);
    let f = if o1 > o0 { (t - o0) / (o1 - o0) } else { 1.0 }.clamp(0.0, 1.0);
    std::array::from_fn(|c| c0[c] + (c1[c] - c0[c]) * f)
}

/// `winding` of the kernel.
fn winding(b: &Binned, rec: usize, row0: usize, j: usize, x: f32, y: f32) -> i32 {
    let mut w = b.backdrops[rec * (TILE * b.ss) as usize + (j - row0)];
    let [first, count] = b.tiles[rec];
    for &r in &b.refs[first as usize..(first + count) as usize] {
        let s = b.segs[r as usize];
        let down = s[1] <= y && y < s[3];
        let up = s[3] <= y && y < s[1];
        if down || up {
            let xc = s[0] + (y - s[1]) * (s[2] - s[0]) / (s[3] - s[1]);
            if xc > x {
                w += if down { 1 } else { -1 };
            }
        }
    }
    w
}

/// CPU twin of `vector_coverage.wgsl`: premultiplied, sRGB-encoded RGBA per pixel, rows top
/// first.
pub fn coverage_cpu(b: &Binned) -> Vec<[f32; 4]> {
    let [w, h] = b.size;
    let ss = b.ss as usize;
    let rows = TILE as usize * ss;
    let mut out = vec![[0.0f32; 4]; w as usize * h as usize];
    for y in 0..h as usize {
        for x in 0..w as usize {
            let (tx, ty) = ((x / TILE as usize) as u32, (y / TILE as usize) as u32);
            let mut acc = [0.0f32; 4];
            let [first, count] = b.grid[(ty * b.size[0].div_ceil(TILE) + tx) as usize];
            for &[pi, rec] in &b.grid[first as usize..(first + count) as usize] {
                let p = &b.paths[pi as usize];
                let rec = rec as usize;
                let mut covered = 0u32;
                for sj in 0..ss {
                    let j = y * ss + sj;
                    let sy = (j as f32 + 0.5) / ss as f32;
                    for si in 0..ss {
                        let sx = ((x * ss + si) as f32 + 0.5) / ss as f32;
                        let wn = winding(b, rec, ty as usize * rows, j, sx, sy);
                        let inside = if p.even_odd != 0 {
                            wn & 1 != 0
                        } else {
                            wn != 0
                        };
                        covered += inside as u32;
                    }
                }
                if covered == 0 {
                    continue;
                }
                let c = paint_at(
                    &b.paints,
                    p.paint as usize,
                    [x as f32 + 0.5, y as f32 + 0.5],
                );
                let cov = covered as f32 / (ss * ss) as f32;
                let src = [
                    c[0] * c[3] * cov,
                    c[1] * c[3] * cov,
                    c[2] * c[3] * cov,
                    c[3] * cov,
                ];
                acc = std::array::from_fn(|i| src[i] + acc[i] * (1.0 - src[3]));
            }
            out[y * w as usize + x] = acc;
        }
    }
    out
}

impl Engine {
    /// Draws a binned scene on the GPU (`vector_coverage.wgsl`): premultiplied, sRGB-encoded
    /// RGBA per pixel, rows top first. One submission and one read-back.
    pub fn draw_flat(&self, b: &Binned) -> Result<Vec<[f32; 4]>> {
        self.draw_flat_timed(b).map(|(pixels, _)| pixels)
    }

    /// [`Engine::draw_flat`], and the milliseconds from the submission to the kernel's end (the
    /// buffers' creation and the read-back left out).
    pub fn draw_flat_timed(&self, b: &Binned) -> Result<(Vec<[f32; 4]>, f64)> {
        let ctx = &self.ctx;
        let pixels = b.size[0] as u64 * b.size[1] as u64;
        let what = || format!("a {} × {} vector image's pixels", b.size[0], b.size[1]);
        ctx.fits(what, pixels * 16, "draw it smaller")?;
        for (name, bytes) in [
            ("segments", b.segs.len() * 16),
            ("tile lists", b.refs.len() * 4),
            ("backdrops", b.backdrops.len() * 4),
            ("tile grid", b.grid.len() * 8),
        ] {
            ctx.fits(
                || format!("a vector image's {name}"),
                bytes as u64,
                "draw it smaller",
            )?;
        }
        let groups = [b.size[0].div_ceil(8), b.size[1].div_ceil(8)];
        let most = ctx.device.limits().max_compute_workgroups_per_dimension;
        if groups.iter().any(|&g| g > most) {
            return Err(crate::error::Error::DeviceLimit {
                what: what(),
                needed: groups[0].max(groups[1]) as u64,
                limit: most as u64,
                limit_name: "max_compute_workgroups_per_dimension",
                hint: "draw it smaller".into(),
            });
        }
        let dev = &ctx.device;
        let kernel = &self.pipes.vector_coverage;
        let uni = Uni {
            size: b.size,
            ss: b.ss,
            paths: b.paths.len() as u32,
        };
        // Buffers, bindings and the commands under the context's error scopes: a failed
        // allocation or binding is an error naming the stage, not a panic.
        let (out, commands) = ctx.scoped("vector coverage", || {
            let u = ctx.uniform_init("vector.uniform", bytemuck::bytes_of(&uni));
            let ro = |label: &str, bytes: &[u8]| {
                ctx.storage_init(label, bytes, wgpu::BufferUsages::empty())
            };
            let paths = ro("vector.paths", bytemuck::cast_slice(&b.paths));
            let tiles = ro("vector.tiles", bytemuck::cast_slice(&b.tiles));
            let refs = ro("vector.refs", bytemuck::cast_slice(&b.refs));
            let backdrops = ro("vector.backdrops", bytemuck::cast_slice(&b.backdrops));
            let segs = ro("vector.segments", bytemuck::cast_slice(&b.segs));
            let paints = ro("vector.paints", bytemuck::cast_slice(&b.paints));
            let grid = ro("vector.grid", bytemuck::cast_slice(&b.grid));
            let out = dev.create_buffer(&wgpu::BufferDescriptor {
                label: Some("vector.out"),
                size: (pixels * 16).max(16),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            let bg = kernel.bind(
                dev,
                "vector_coverage",
                &[
                    (0, u.as_entire_binding()),
                    (1, paths.as_entire_binding()),
                    (2, tiles.as_entire_binding()),
                    (3, refs.as_entire_binding()),
                    (4, backdrops.as_entire_binding()),
                    (5, segs.as_entire_binding()),
                    (6, paints.as_entire_binding()),
                    (7, out.as_entire_binding()),
                    (8, grid.as_entire_binding()),
                ],
            );
            let mut enc = dev.create_command_encoder(&Default::default());
            {
                let mut pass = enc.begin_compute_pass(&Default::default());
                pass.set_pipeline(&kernel.pipeline);
                pass.set_bind_group(0, &bg, &[]);
                pass.dispatch_workgroups(groups[0], groups[1], 1);
            }
            (out, enc.finish())
        })?;
        let t = std::time::Instant::now();
        ctx.queue.submit([commands]);
        ctx.wait("vector coverage")?;
        let kernel_ms = t.elapsed().as_secs_f64() * 1000.0;
        let bytes = ctx.read_buffer(&out, pixels * 16, "vector coverage read-back")?;
        Ok((bytemuck::cast_slice(&bytes).to_vec(), kernel_ms))
    }
}
