// SPDX-License-Identifier: MIT OR Apache-2.0
//! GPU side of the extended exponential map of a curve: the candidate strip and the seeds (CPU
//! set-up, proportional to the strip) and the relaxation (`wgsl/maps/ribbon_relax.wgsl`, one
//! workgroup, rounds of sweeps until one changes nothing), whose fixed point is the CPU twin's
//! ([`super::ribbon_cpu`]).

use super::{seeds, Curve, Framed, GpuPiece};
use crate::error::Result;
use crate::gpu::pipelines::Pipelines;
use crate::gpu::{BufferInit, GpuContext};
use crate::mesh::{SurfaceRef, Topology};
use glam::Vec3;
use rustc_hash::{FxHashMap, FxHashSet};

/// Keep in sync with `RibbonJob` in `wgsl/maps/ribbon_relax.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct RibbonJob {
    cand_count: u32,
    halo_count: u32,
    seed_count: u32,
    piece_count: u32,
    reach: f32,
    length: f32,
    sweeps: u32,
    init: u32,
    /// First entry of the output slot in `coords`.
    slot_base: u32,
    pad: [u32; 3],
    /// Output (a u + b, c v + d) as (a, b, c, d).
    xform: [f32; 4],
}

/// Where [`run`] writes: the slot of `coords` (in vertices per slot) and the affine map from
/// (u, v) to the written coordinates ((a, b, c, d): x = a u + b, y = c v + d).
#[derive(Debug, Clone, Copy)]
pub struct Output {
    /// Slot index (entries `slot × vertex_count ..`).
    pub slot: u32,
    /// (a, b, c, d).
    pub xform: [f32; 4],
}

impl Output {
    /// Slot 0, (u, v) as they are.
    pub const PLAIN: Output = Output {
        slot: 0,
        xform: [1.0, 0.0, 1.0, 0.0],
    };
}

/// Keep in sync with `SeedState` in `wgsl/maps/ribbon_relax.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct GpuSeed {
    vertex: u32,
    piece: u32,
    s: f32,
    dist: f32,
    off: [f32; 2],
    pad: [f32; 2],
}

/// How the relaxation went.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct RibbonStatus {
    /// Sweeps run (the last changed nothing when converged).
    pub sweeps: u32,
    /// Whether a sweep changed nothing within the sweep limit.
    pub converged: bool,
    /// Vertices that received coordinates.
    pub reached: u32,
    /// Vertices the relaxation worked on (the strip's candidates).
    pub candidates: u32,
    /// Dispatches issued.
    pub dispatches: u32,
    /// Milliseconds of CPU set-up (the curve's frames, the seeds, the strip's candidates).
    pub setup_ms: f64,
    /// The largest v reached on the curve's left and |v| on its right (model units): how far
    /// the surface lets the strip spread on each side.
    pub extent: [f32; 2],
}

/// Loop iterations one invocation may run in a dispatch, well under lavapipe's cut-off (65535).
const LOOP_BUDGET: u32 = 20_000;

/// Pieces by cell of a uniform grid, each piece listed in every cell within `reach` of it (the
/// cells its box grown by `reach` overlaps): whether a point is within `reach` of the curve is
/// one cell's look-up and that cell's pieces. Cells are at least `reach` and the longest piece
/// wide, so a piece is in at most 4³ cells whatever the ribbon's width.
struct Grid {
    cell: f32,
    reach: f32,
    cells: FxHashMap<[i32; 3], Vec<u32>>,
}

impl Grid {
    fn new(framed: &Framed, reach: f32) -> Self {
        let longest = framed.pieces.iter().map(|p| p.len).fold(0.0f32, f32::max);
        let cell = reach.max(longest).max(1e-12);
        let mut cells: FxHashMap<[i32; 3], Vec<u32>> = FxHashMap::default();
        let at = |p: Vec3| (p / cell).floor().as_ivec3();
        for (k, p) in framed.pieces.iter().enumerate() {
            let (a, b) = (p.start, p.start + p.t * p.len);
            let (lo, hi) = (at(a.min(b) - reach), at(a.max(b) + reach));
            for x in lo.x..=hi.x {
                for y in lo.y..=hi.y {
                    for z in lo.z..=hi.z {
                        cells.entry([x, y, z]).or_default().push(k as u32);
                    }
                }
            }
        }
        Self { cell, reach, cells }
    }

    /// Whether `x` is within `reach` of a piece.
    fn near(&self, framed: &Framed, x: Vec3) -> bool {
        let c = (x / self.cell).floor().as_ivec3();
        self.cells.get(&c.to_array()).is_some_and(|ks| {
            ks.iter().any(|&k| {
                let p = &framed.pieces[k as usize];
                let along = (x - p.start).dot(p.t).clamp(0.0, p.len);
                (x - (p.start + p.t * along)).length() <= self.reach
            })
        })
    }
}

/// The strip the relaxation works on, in its own numbering: the candidates (breadth first from the
/// seeds), then the ring around them that is only reset; per local vertex its welded id, position
/// and normal, and the candidates' neighbours in local ids. The kernel reads only these, so a
/// sweep walks a few hundred kilobytes in order instead of scattering over mesh-sized buffers (the
/// subdivided bunny's 557k vertices lie far apart in its numbering: per strip vertex the map cost
/// 1.31× bob's before the strip was gathered).
struct Strip {
    global: Vec<u32>,
    cand_count: usize,
    vertices: Vec<StripVertex>,
    offsets: Vec<u32>,
    adjacency: Vec<u32>,
    /// Welded id to local id, for the seeds.
    local: FxHashMap<u32, u32>,
}

/// Keep in sync with `StripVertex` in `wgsl/maps/ribbon_relax.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct StripVertex {
    p: [f32; 4],
    n: [f32; 4],
}

/// The vertices the map can reach: connected to the seeds through vertices within Euclidean
/// distance `reach` of the curve (the caller's reach plus the seeds' largest offset: a vertex
/// within that graph distance is within that Euclidean distance, and so is every vertex on its
/// path from the seeds), and the ring around
/// those (reached from them, as the twin reaches one ring past `reach`); then the next ring,
/// only reset. Cost proportional to the result.
fn candidates(topo: &Topology, framed: &Framed, seeds: &[u32], reach: f32) -> Strip {
    let grid = Grid::new(framed, reach);
    // Local ids in the order vertices join: the ball breadth first, its ring, the halo.
    let mut local: FxHashMap<u32, u32> = FxHashMap::default();
    local.reserve(seeds.len() * 16);
    let mut out = Vec::new();
    let join = |v: u32, local: &mut FxHashMap<u32, u32>, out: &mut Vec<u32>| {
        let fresh = !local.contains_key(&v);
        if fresh {
            local.insert(v, out.len() as u32);
            out.push(v);
        }
        fresh
    };
    for &v in seeds {
        join(v, &mut local, &mut out);
    }
    let neighbours = |v: u32| {
        let (a, b) = (
            topo.adjacency_offsets[v as usize] as usize,
            topo.adjacency_offsets[v as usize + 1] as usize,
        );
        &topo.adjacency[a..b]
    };
    // Breadth first, so the candidates run outwards from the curve and a sweep (each invocation
    // taking a contiguous block of them) carries the map across several rings.
    let mut far: FxHashSet<u32> = FxHashSet::default();
    let mut next = 0;
    while next < out.len() {
        let v = out[next];
        next += 1;
        for &q in neighbours(v) {
            // A vertex found too far stays so: it is looked at once, not once per neighbour.
            if !local.contains_key(&q) && !far.contains(&q) {
                if grid.near(framed, topo.positions[q as usize]) {
                    join(q, &mut local, &mut out);
                } else {
                    far.insert(q);
                }
            }
        }
    }
    // The ring past the ball is reached too (from vertices within `reach`: the twin reaches one
    // ring past them); the ring past that is only reset.
    let ball = out.len();
    for i in 0..ball {
        for &q in neighbours(out[i]) {
            join(q, &mut local, &mut out);
        }
    }
    let cand_count = out.len();
    for i in ball..cand_count {
        for &q in neighbours(out[i]) {
            join(q, &mut local, &mut out);
        }
    }
    let mut offsets = Vec::with_capacity(cand_count + 1);
    let mut adjacency = Vec::with_capacity(cand_count * 7);
    offsets.push(0);
    for &v in &out[..cand_count] {
        adjacency.extend(neighbours(v).iter().map(|q| local[q]));
        offsets.push(adjacency.len() as u32);
    }
    Strip {
        vertices: out
            .iter()
            .map(|&v| StripVertex {
                p: topo.positions[v as usize].extend(0.0).to_array(),
                n: topo.normals[v as usize].extend(0.0).to_array(),
            })
            .collect(),
        global: out,
        cand_count,
        offsets,
        adjacency,
        local,
    }
}

/// The strip of `framed` within `reach` ([`candidates`]) and its seeds, in the strip's numbering.
fn strip_and_seeds(
    topo: &Topology,
    curve: &Curve,
    framed: &Framed,
    reach: f32,
) -> (Strip, Vec<GpuSeed>) {
    let feet = seeds(topo, curve, framed);
    let seed_vertices: Vec<u32> = feet.iter().map(|f| f.vertex).collect();
    // Graph distances are never shorter than straight ones, so a vertex within `reach` of the
    // seeds lies within `reach` of a seed, and the seeds lie within their offsets of the curve.
    let seed_far = feet.iter().map(|f| f.dist).fold(0.0f32, f32::max);
    let strip = candidates(topo, framed, &seed_vertices, reach + seed_far);
    let seeds = feet
        .iter()
        .map(|f| GpuSeed {
            vertex: strip.local[&f.vertex],
            piece: f.piece,
            s: f.s,
            dist: f.dist,
            off: f.off.to_array(),
            pad: [0.0; 2],
        })
        .collect();
    (strip, seeds)
}

/// Computes the map of `curve` within `reach` into slot `out.slot` of `coords` (one vec4 per
/// welded vertex: x, y (the map's u, v through `out.xform`), graph distance, 1 where reached; the
/// candidates' and their ring's entries are overwritten, others left as they are), on the GPU, in
/// the strip's own numbering (`Strip`). Returns the status and the candidate vertices (the only
/// ones the map can reach).
pub fn run(
    ctx: &GpuContext,
    pipes: &Pipelines,
    mesh: SurfaceRef<'_>,
    (curve, reach): (&Curve, f32),
    (coords, out): (&wgpu::Buffer, Output),
) -> Result<(RibbonStatus, Vec<u32>)> {
    let (topo, gpu) = (mesh.topo, mesh.gpu);
    let t = std::time::Instant::now();
    let framed = Framed::new(topo, curve, reach);
    if framed.pieces.is_empty() {
        return Ok((RibbonStatus::default(), Vec::new()));
    }
    let (strip, seeds) = strip_and_seeds(topo, curve, &framed, reach);
    let pieces: Vec<GpuPiece> = framed.pieces.iter().map(GpuPiece::from).collect();
    let cand_count = strip.cand_count as u32;
    let setup_ms = t.elapsed().as_secs_f64() * 1e3;
    // Per sweep an invocation visits ceil(candidates / 256) vertices, with about 40 loop steps
    // each (neighbours, the slide's steps, the piece searches).
    let sweeps = (LOOP_BUDGET / cand_count.div_ceil(256).max(1) / 40).clamp(1, 1024);
    let max_sweeps = 4 * cand_count + 16;
    let job = |init: u32| RibbonJob {
        cand_count,
        halo_count: (strip.global.len() - strip.cand_count) as u32,
        seed_count: seeds.len() as u32,
        piece_count: pieces.len() as u32,
        reach,
        length: framed.length,
        sweeps,
        init,
        slot_base: out.slot * gpu.vertex_count,
        pad: [0; 3],
        xform: out.xform,
    };
    let device = &ctx.device;
    let bind = ctx.scoped("ribbon map", || {
        let ro = |label, bytes: &[u8]| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: bytes,
                usage: wgpu::BufferUsages::STORAGE,
            })
        };
        let pieces_buf = ro("ribbon.pieces", bytemuck::cast_slice(&pieces));
        let global = ro("ribbon.global", bytemuck::cast_slice(&strip.global));
        let seeds_buf = ro("ribbon.seeds", bytemuck::cast_slice(&seeds));
        let verts = ro("ribbon.vertices", bytemuck::cast_slice(&strip.vertices));
        let offsets = ro("ribbon.offsets", bytemuck::cast_slice(&strip.offsets));
        let adjacency = ro("ribbon.adjacency", bytemuck::cast_slice(&strip.adjacency));
        let plain = |label, size: u64| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: size.max(16),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            })
        };
        let status = plain("ribbon.status", 32);
        let n = strip.global.len() as u64;
        let (state, link) = (plain("ribbon.state", n * 16), plain("ribbon.link", n * 8));
        let stamp = plain("ribbon.stamp", n * 4);
        let uniform = |init| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("ribbon.job"),
                contents: bytemuck::bytes_of(&job(init)),
                usage: wgpu::BufferUsages::UNIFORM,
            })
        };
        let group = |u: &wgpu::Buffer| {
            pipes.ribbon_relax.bind(
                device,
                "ribbon.relax",
                &[
                    (0, u.as_entire_binding()),
                    (1, verts.as_entire_binding()),
                    (2, stamp.as_entire_binding()),
                    (3, offsets.as_entire_binding()),
                    (4, adjacency.as_entire_binding()),
                    (5, pieces_buf.as_entire_binding()),
                    (6, global.as_entire_binding()),
                    (7, seeds_buf.as_entire_binding()),
                    (8, state.as_entire_binding()),
                    (9, link.as_entire_binding()),
                    (10, coords.as_entire_binding()),
                    (11, status.as_entire_binding()),
                ],
            )
        };
        (group(&uniform(1)), group(&uniform(0)), status)
    })?;
    let (first, more, status) = bind;
    let mut dispatches = 0;
    loop {
        ctx.scoped("ribbon map", || {
            let mut enc = device.create_command_encoder(&Default::default());
            {
                let mut pass = enc.begin_compute_pass(&Default::default());
                pass.set_pipeline(&pipes.ribbon_relax.pipeline);
                for k in 0..4 {
                    let bg = if dispatches == 0 && k == 0 {
                        &first
                    } else {
                        &more
                    };
                    pass.set_bind_group(0, bg, &[]);
                    pass.dispatch_workgroups(1, 1, 1);
                }
            }
            ctx.queue.submit([enc.finish()]);
        })?;
        dispatches += 4;
        let s = ctx.read_buffer(&status, 32, "ribbon status read-back")?;
        let s: &[u32] = bytemuck::cast_slice(&s);
        if s[1] != 0 || s[0] >= max_sweeps {
            let status = RibbonStatus {
                sweeps: s[0],
                converged: s[1] != 0,
                reached: s[2],
                candidates: cand_count,
                dispatches,
                setup_ms,
                extent: [f32::from_bits(s[3]), f32::from_bits(s[4])],
            };
            let mut cands = strip.global;
            cands.truncate(strip.cand_count);
            return Ok((status, cands));
        }
    }
}

/// [`run`] into a fresh buffer, read back (tests, `decalbake param`, benchmarks): per welded
/// vertex (u, v, graph distance, 1 where reached, else 0).
pub fn ribbon_gpu(
    ctx: &GpuContext,
    pipes: &Pipelines,
    mesh: SurfaceRef<'_>,
    curve: &Curve,
    reach: f32,
) -> Result<(Vec<[f32; 4]>, RibbonStatus)> {
    let size = mesh.gpu.vertex_count as u64 * 16;
    let coords = ctx.scoped("ribbon map", || {
        ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("ribbon.coords"),
            size: size.max(16),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        })
    })?;
    let (status, _) = run(ctx, pipes, mesh, (curve, reach), (&coords, Output::PLAIN))?;
    let bytes = ctx.read_buffer(&coords, size, "ribbon read-back")?;
    Ok((bytemuck::cast_slice(&bytes).to_vec(), status))
}
