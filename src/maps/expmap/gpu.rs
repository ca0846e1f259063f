// SPDX-License-Identifier: MIT OR Apache-2.0
//! GPU side of the discrete exponential maps: candidate discs (CPU, proportional to the disc) and the
//! relaxation (`wgsl/maps/expmap_relax.wgsl`, a chunk's maps in one dispatch a round, one workgroup
//! a map; `wgsl/maps/expmap_spread.wgsl`, one map over many workgroups, off by default).

use crate::error::Result;
use crate::gpu::pipelines::Pipelines;
use crate::maps::expmap::cpu::{Options, Seed};
use crate::mesh::{SurfaceRef, Topology};
use std::sync::atomic::Ordering::Relaxed;

/// One decal's map request. Keep in sync with `GeoJob` in wgsl/shared/expmap_relax_common.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GeoJob {
    seed: [f32; 4],
    normal: [f32; 4],
    e1: [f32; 4],
    e2: [f32; 4],
    tri: [u32; 4],
    radius: f32,
    curvature_stop: f32,
    cand_offset: u32,
    cand_count: u32,
    vertex_count: u32,
    max_sweeps: u32,
    /// Vertices next to the candidates but outside them, listed right after the candidates: the
    /// first round marks them as not reachable, so no slot ever needs clearing in full.
    halo_count: u32,
    /// 1 for [`crate::maps::expmap::Accuracy::Smooth`].
    smooth: u32,
}

/// What the relaxation reports per decal. Keep in sync with `GeoResult` in wgsl/maps/expmap_relax.wgsl.
#[repr(C)]
#[derive(
    Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable, serde::Serialize,
)]
pub struct GeoResult {
    /// Relaxation sweeps run (the last one changed nothing when converged).
    pub sweeps: u32,
    /// Vertices that received coordinates.
    pub reached: u32,
    /// 1 when a sweep changed nothing before the sweep limit.
    pub converged: u32,
    /// Triangles whose three vertices the map reached. Not computed by the relaxation (the kernel
    /// writes 0 in its padding word); a bake fills it in from its triangle selection
    /// (`wgsl/bake/select_triangles.wgsl`).
    pub triangles_reached: u32,
}

/// The vertices a map can reach: connected to the seed triangle through vertices within Euclidean
/// distance `radius` of the seed point (1.01 × `radius`, for f32 rounding), plus one ring. A vertex
/// expands when its graph distance is at most `radius` (the twin's rule, `dem_cpu`), and graph
/// distance is never shorter than Euclidean (the seed triangle's vertices start at their
/// Euclidean distance, each step adds an edge's length), so every expanded vertex and every
/// vertex on its upwind path lies in the ball, and what it reaches in the ring past it (this was
/// 1.5 × `radius`, from a time when the map's |u| decided: 2.2 times the candidates of a disc).
/// Cost proportional to the result. Breadth first (when the first sweep visited
/// every candidate in this order, it carried the map across more rings, 22 → 17 sweeps for a 1k
/// disc; now the first front is the seeds' neighbours and the order no longer
/// matters to the sweeps).
pub fn candidates(topo: &Topology, seed: &Seed, radius: f32) -> Vec<u32> {
    let mut seen = rustc_hash::FxHashSet::default();
    let mut out = Vec::new();
    let mut stack = std::collections::VecDeque::new();
    for &v in &topo.triangles[seed.triangle as usize] {
        if seen.insert(v) {
            out.push(v);
            stack.push_back(v);
        }
    }
    while let Some(v) = stack.pop_front() {
        if (topo.positions[v as usize] - seed.point).length() > 1.01 * radius {
            continue;
        }
        let (a, b) = (
            topo.adjacency_offsets[v as usize] as usize,
            topo.adjacency_offsets[v as usize + 1] as usize,
        );
        for &q in &topo.adjacency[a..b] {
            if seen.insert(q) {
                out.push(q);
                stack.push_back(q);
            }
        }
    }
    out
}

/// Builds the jobs and candidate lists for `maps` (seed, options, coords slot).
pub fn build_jobs(topo: &Topology, maps: &[(Seed, Options, u32)]) -> (Vec<GeoJob>, Vec<u32>) {
    let mut jobs = Vec::new();
    let mut cands = Vec::new();
    for (seed, opts, slot) in maps {
        let c = candidates(topo, seed, opts.radius);
        let inside: rustc_hash::FxHashSet<u32> = c.iter().copied().collect();
        let mut halo: Vec<u32> = Vec::new();
        let mut seen = rustc_hash::FxHashSet::default();
        for &v in &c {
            let (a, b) = (
                topo.adjacency_offsets[v as usize] as usize,
                topo.adjacency_offsets[v as usize + 1] as usize,
            );
            for &q in &topo.adjacency[a..b] {
                if !inside.contains(&q) && seen.insert(q) {
                    halo.push(q);
                }
            }
        }
        let t = topo.triangles[seed.triangle as usize];
        jobs.push(GeoJob {
            seed: seed.point.extend(0.0).to_array(),
            normal: seed.normal.extend(0.0).to_array(),
            e1: seed.e1.extend(0.0).to_array(),
            e2: seed.e2.extend(0.0).to_array(),
            tri: [t[0], t[1], t[2], *slot],
            radius: opts.radius,
            curvature_stop: opts.curvature_stop.min(f32::MAX),
            cand_offset: cands.len() as u32,
            cand_count: c.len() as u32,
            vertex_count: topo.positions.len() as u32,
            // Each sweep settles at least one more ring; four times the candidates is a generous cap.
            max_sweeps: 4 * c.len() as u32 + 16,
            halo_count: halo.len() as u32,
            smooth: u32::from(opts.accuracy == crate::maps::expmap::Accuracy::Smooth),
        });
        cands.extend(c);
        cands.extend(halo);
    }
    if cands.is_empty() {
        cands.push(0);
    }
    (jobs, cands)
}

/// Per-dispatch round parameters. Keep in sync with `Round` in wgsl/maps/expmap_relax.wgsl.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Round {
    init: u32,
    /// At most this many sweeps a dispatch.
    sweeps: u32,
    /// Loop steps an invocation may spend a dispatch ([`LOOP_BUDGET`]).
    budget: u32,
    /// Loop steps one front vertex may cost (see `run`).
    steps_per_vertex: u32,
}

/// Loop iterations one invocation may run in a dispatch, kept well under lavapipe's cut-off (65535
/// loop iterations per invocation, after which it silently abandons the shader).
const LOOP_BUDGET: u32 = 20_000;

/// When not 0, the loop budget of a dispatch instead of [`LOOP_BUDGET`]. Tests lower it to make a
/// map cross many rounds; results do not depend on it (rounds only split the same sweeps).
#[doc(hidden)]
pub static LOOP_BUDGET_OVERRIDE: std::sync::atomic::AtomicU32 =
    std::sync::atomic::AtomicU32::new(0);
/// Candidates of a map from which its chunk runs the relaxation 256 invocations a map
/// (`Pipelines::expmap_relax_wide`) instead of 64: the set-up and count loops (candidates / 64
/// steps an invocation each) then stay far below lavapipe's cut-off beside the sweeps' budget.
const WIDE_MIN_CANDIDATES: u32 = 64 * 4_096;

/// When not 0, the candidates from which a chunk runs the wide variant instead of
/// [`WIDE_MIN_CANDIDATES`]. Tests set it to 1 to run small maps through it; results do not
/// depend on the variant (the same sweeps, the fronts split among more invocations).
#[doc(hidden)]
pub static WIDE_MIN_CANDIDATES_OVERRIDE: std::sync::atomic::AtomicU32 =
    std::sync::atomic::AtomicU32::new(0);

/// Rounds recorded per submission before the host checks convergence.
const ROUNDS_PER_SUBMIT: u32 = 4;

/// When not 0, a map alone in its chunk with this many candidates or more runs spread over many
/// workgroups (`run_spread`, `wgsl/maps/expmap_spread.wgsl`) instead of in one; `u32::MAX` keeps
/// one workgroup a map; 0, the default, leaves the choice to the adapter: never on a CPU adapter,
/// from [`GPU_SPREAD_MIN_CANDIDATES`] on a GPU. Measured (`bench --geodesic`, which reports both
/// paths on any adapter: `gpu_ms`, `gpu_spread_ms`): on lavapipe a dispatch that wakes the second
/// core costs more than the sweep it carries (lavapipe on this 2-core machine: the 12k disc on bob × 2 21-24 ms spread
/// against 8.5-8.6 ms in one workgroup, 10.2 ms spread with `LP_NUM_THREADS=1`; the 120k disc
/// 123-134 against 115-116); on an NVIDIA H200 (2026-11-27, docs/performance.md, "On a real GPU") the spread
/// path is slower at 1k vertices (1.2 against 0.7 ms), even at 12k on bob × 2 (6.8 against 6.5),
/// ahead at 11k on bob × 3 (10.0 against 13.8) and 2.4× at 121k (42 against 103). Tests compare
/// the two paths; results do not depend on it (the same fixed point).
#[doc(hidden)]
pub static SPREAD_MIN_CANDIDATES_OVERRIDE: std::sync::atomic::AtomicU32 =
    std::sync::atomic::AtomicU32::new(0);

/// Candidates from which a lone map is spread over many workgroups on a GPU adapter (see
/// [`SPREAD_MIN_CANDIDATES_OVERRIDE`]): on the H200 spreading lost at 1k, was level at the 12k
/// disc on bob × 2 (6.8 against 6.5 ms), won 1.4× at the 11k disc on bob × 3 and 2.4× at the 121k
/// one; set above the discs where it was not a clear win.
pub const GPU_SPREAD_MIN_CANDIDATES: u32 = 32_768;

/// Sweeps recorded per submission of the spread path before the host reads the status back (a
/// sweep whose front is empty costs two near-empty dispatches).
const SPREAD_SWEEPS_PER_SUBMIT: u32 = 24;

/// Bytes of the spread path's state (`sstate` in wgsl/maps/expmap_spread.wgsl) and of its
/// indirect dispatch sizes (`args`: the sweep's at 0, `finish`'s at 16).
const SPREAD_STATE_BYTES: u64 = 32;
const SPREAD_ARGS_BYTES: u64 = 32;

/// Workgroup of the spread path's `clear` and `finish` (`WG_WIDE` in wgsl/maps/expmap_spread.wgsl;
/// `sweep`'s is sized on the GPU, by `advance`).
const SPREAD_WG_WIDE: u32 = 256;

/// The buffers both relaxations bind, less their own state (bindings 9 and 10).
struct MapBuffers {
    jobs: wgpu::Buffer,
    cands: wgpu::Buffer,
    results: wgpu::Buffer,
    fronts: wgpu::Buffer,
    marks: wgpu::Buffer,
    state: wgpu::Buffer,
}

impl MapBuffers {
    /// Allocates them for `jobs` and `cands`; the marks and smooth state are the mesh's kept
    /// scratch where it is large enough.
    fn new(
        ctx: &crate::gpu::GpuContext,
        mesh: &crate::mesh::GpuMesh,
        jobs: &[GeoJob],
        cands: &[u32],
    ) -> Self {
        let device = &ctx.device;
        let slots = jobs.iter().map(|j| j.tri[3] as u64 + 1).max().unwrap_or(1);
        let kept = mesh.expmap_scratch.lock().expect("expmap scratch").take();
        let size = slots * mesh.vertex_count as u64 * 4;
        let [marks, state] = match kept.filter(|[m, _]| m.size() >= size) {
            Some(pair) => pair,
            None => [
                plain(ctx, "expmap.marks", size),
                plain(ctx, "expmap.state", size * 4),
            ],
        };
        let none = wgpu::BufferUsages::empty();
        Self {
            jobs: ctx.storage_init("expmap.jobs", bytemuck::cast_slice(jobs), none),
            cands: ctx.storage_init("expmap.candidates", bytemuck::cast_slice(cands), none),
            results: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("expmap.results"),
                size: jobs.len() as u64 * 16,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
            fronts: plain(ctx, "expmap.fronts", 2 * cands.len() as u64 * 4),
            marks,
            state,
        }
    }

    /// Bindings 0-8 and 11-13 (the kernels' own state, 9 and 10, come from the caller).
    fn entries<'a>(
        &'a self,
        mesh: &'a crate::mesh::GpuMesh,
        coords: &'a wgpu::Buffer,
    ) -> Vec<(u32, wgpu::BindingResource<'a>)> {
        vec![
            (0, self.jobs.as_entire_binding()),
            (1, mesh.positions.as_entire_binding()),
            (2, mesh.normals.as_entire_binding()),
            (3, mesh.adjacency_offsets.as_entire_binding()),
            (4, mesh.relax_edges.as_entire_binding()),
            (5, mesh.curvature.as_entire_binding()),
            (6, self.cands.as_entire_binding()),
            (7, coords.as_entire_binding()),
            (8, self.results.as_entire_binding()),
            (11, self.fronts.as_entire_binding()),
            (12, self.marks.as_entire_binding()),
            (13, self.state.as_entire_binding()),
        ]
    }

    /// Hands the marks and smooth state back to the mesh for its next maps.
    fn keep(self, mesh: &crate::mesh::GpuMesh) {
        *mesh.expmap_scratch.lock().expect("expmap scratch") = Some([self.marks, self.state]);
    }
}

/// A zeroed storage buffer of `size` bytes (at least 16).
fn plain(ctx: &crate::gpu::GpuContext, label: &str, size: u64) -> wgpu::Buffer {
    ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: size.max(16),
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// Computes `maps` (seed, options, coords slot) into their slots of `coords`: builds the jobs and
/// candidate lists, then runs the relaxation to convergence: seeds the maps (clearing their coords
/// slots), then dispatches rounds of sweeps, `ROUNDS_PER_SUBMIT` per submission, reading back only
/// the per-map status between submissions. A map alone in its chunk with enough candidates runs
/// spread over many workgroups instead (`run_spread`: on a GPU from
/// [`GPU_SPREAD_MIN_CANDIDATES`], or as [`SPREAD_MIN_CANDIDATES_OVERRIDE`] says). Returns the per-map results and the dispatches issued.
///
/// On wgpu's GL backend the maps come from the CPU twin instead (see `run_cpu_twin`).
pub fn run(
    ctx: &crate::gpu::GpuContext,
    pipes: &Pipelines,
    mesh: SurfaceRef<'_>,
    maps: &[(Seed, Options, u32)],
    coords: &wgpu::Buffer,
) -> Result<(Vec<GeoResult>, u32)> {
    if maps.is_empty() {
        return Ok((Vec::new(), 0));
    }
    // On GL (see `run_cpu_twin`), and on a device whose storage bindings cannot hold the mesh's
    // edge records (`GpuMesh::relax_edges_fit`), the maps come from the CPU twin.
    if ctx.backend == Some(wgpu::Backend::Gl) || !mesh.gpu.relax_edges_fit {
        return run_cpu_twin(ctx, mesh, maps, coords);
    }
    let (topo, mesh) = (mesh.topo, mesh.gpu);
    let (jobs, cands) = build_jobs(topo, maps);
    let (jobs, cands) = (&jobs[..], &cands[..]);
    let spread_min = match SPREAD_MIN_CANDIDATES_OVERRIDE.load(Relaxed) {
        0 if ctx.device_type == Some(wgpu::DeviceType::Cpu) => u32::MAX,
        0 => GPU_SPREAD_MIN_CANDIDATES,
        n => n,
    };
    if jobs.len() == 1 && jobs[0].cand_count >= spread_min {
        if let Some(k) = pipes.expmap_spread.as_ref() {
            return run_spread(ctx, k, mesh, &jobs[0], cands, coords);
        }
    }
    let device = &ctx.device;
    // The kernel runs as many sweeps a dispatch as its fronts' sizes fit in `LOOP_BUDGET` (a sweep
    // over a front of n vertices: ceil(n / the workgroup's width) × `steps_per_vertex` steps),
    // at least one, at most 1,024. The fronts are a ring or two (the first: the seeds'
    // neighbours), so a dispatch runs many (the 120k disc: 265 sweeps in 268 dispatches when the
    // count was fixed from the first, which was then every candidate).
    let steps_per_vertex = steps_per_vertex(topo, cands);
    let round = |init| Round {
        init,
        sweeps: 1024,
        budget: match LOOP_BUDGET_OVERRIDE.load(Relaxed) {
            0 => LOOP_BUDGET,
            b => b,
        },
        steps_per_vertex,
    };
    let max_sweeps = jobs.iter().map(|j| j.max_sweeps).max().unwrap_or(16);
    let wide_min = match WIDE_MIN_CANDIDATES_OVERRIDE.load(Relaxed) {
        0 => WIDE_MIN_CANDIDATES,
        n => n,
    };
    let kernel = if jobs.iter().any(|j| j.cand_count >= wide_min) {
        &pipes.expmap_relax_wide
    } else {
        &pipes.expmap_relax
    };
    let (bufs, _fstate, bg_init, bg_more) = ctx.scoped("exponential maps", || {
        let bufs = MapBuffers::new(ctx, mesh, jobs, cands);
        let fstate = plain(ctx, "expmap.front_state", jobs.len() as u64 * 16);
        let bind = |r: Round| {
            let round = ctx.uniform_init("expmap.round", bytemuck::bytes_of(&r));
            let mut entries = bufs.entries(mesh, coords);
            entries.push((9, round.as_entire_binding()));
            entries.push((10, fstate.as_entire_binding()));
            kernel.bind(device, "expmap.relax", &entries)
        };
        let (bg_init, bg_more) = (bind(round(1)), bind(round(0)));
        (bufs, fstate, bg_init, bg_more)
    })?;
    let status = (&bufs.results, jobs.len() as u64 * 16, max_sweeps);
    let done = submit_rounds(ctx, kernel, [&bg_init, &bg_more], jobs.len() as u32, status);
    // Every dispatch has finished (the status read-backs waited for them), or failed.
    bufs.keep(mesh);
    done
}

/// One map, `job`, spread over many workgroups (`wgsl/maps/expmap_spread.wgsl`): the candidates
/// cleared over the whole device, the seeds set, then a dispatch a sweep over the front, one
/// invocation a front vertex, each followed by a one-invocation `advance` that makes the next
/// front current and sizes the next sweep's indirect dispatch; [`SPREAD_SWEEPS_PER_SUBMIT`]
/// sweeps and a `finish` (the reached count, indirect: empty until the map is done) a
/// submission, the status read back between submissions. The same fixed point as [`run`]'s
/// one workgroup a map (`tests/expmap.rs` compares them byte for byte). Returns the map's result
/// and the dispatches issued.
fn run_spread(
    ctx: &crate::gpu::GpuContext,
    k: &crate::gpu::pipelines::ExpmapSpread,
    mesh: &crate::mesh::GpuMesh,
    job: &GeoJob,
    cands: &[u32],
    coords: &wgpu::Buffer,
) -> Result<(Vec<GeoResult>, u32)> {
    // `bg` for the entry points that write the dispatch sizes, `bg_indirect` (a stand-in at 14)
    // for those dispatched from them.
    let (bufs, args, [bg, bg_indirect]) = ctx.scoped("exponential maps", || {
        let bufs = MapBuffers::new(ctx, mesh, std::slice::from_ref(job), cands);
        let sstate = plain(ctx, "expmap.spread_state", SPREAD_STATE_BYTES);
        let args = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("expmap.spread_args"),
            size: SPREAD_ARGS_BYTES,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::INDIRECT,
            mapped_at_creation: false,
        });
        let stand_in = plain(ctx, "expmap.spread_args_stand_in", SPREAD_ARGS_BYTES);
        let bind = |at_14: &wgpu::Buffer| {
            let mut entries = bufs.entries(mesh, coords);
            entries.push((10, sstate.as_entire_binding()));
            entries.push((14, at_14.as_entire_binding()));
            crate::gpu::pipelines::make_bind_group(
                &ctx.device,
                &k.layout,
                "expmap.spread",
                &entries,
            )
        };
        let bgs = [bind(&args), bind(&stand_in)];
        (bufs, args, bgs)
    })?;
    let groups = |n: u32, width: u32| {
        let g = n.div_ceil(width);
        (g.min(65_535), g.div_ceil(65_535))
    };
    let mut dispatches = 0;
    let done = loop {
        let recorded = ctx.scoped("exponential maps", || {
            let mut enc = ctx.device.create_command_encoder(&Default::default());
            let mut n = 0;
            {
                let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("expmap.spread"),
                    timestamp_writes: None,
                });
                if dispatches == 0 {
                    pass.set_bind_group(0, &bg, &[]);
                    let (x, y) = groups(job.cand_count + job.halo_count, SPREAD_WG_WIDE);
                    pass.set_pipeline(&k.clear);
                    pass.dispatch_workgroups(x, y, 1);
                    pass.set_pipeline(&k.seed);
                    pass.dispatch_workgroups(1, 1, 1);
                    n += 2;
                }
                for _ in 0..SPREAD_SWEEPS_PER_SUBMIT {
                    pass.set_bind_group(0, &bg_indirect, &[]);
                    pass.set_pipeline(&k.sweep);
                    pass.dispatch_workgroups_indirect(&args, 0);
                    pass.set_bind_group(0, &bg, &[]);
                    pass.set_pipeline(&k.advance);
                    pass.dispatch_workgroups(1, 1, 1);
                    n += 2;
                }
                pass.set_bind_group(0, &bg_indirect, &[]);
                pass.set_pipeline(&k.finish);
                pass.dispatch_workgroups_indirect(&args, 16);
            }
            ctx.queue.submit([enc.finish()]);
            n + 1
        });
        dispatches += match recorded {
            Ok(n) => n,
            Err(e) => break Err(e),
        };
        let bytes = ctx.read_buffer(&bufs.results, 16, "expmap status read-back");
        let r: GeoResult = match bytes {
            Ok(b) => bytemuck::pod_read_unaligned(&b[..16]),
            Err(e) => break Err(e),
        };
        if r.converged != 0 || r.sweeps >= job.max_sweeps {
            break Ok((vec![r], dispatches));
        }
    };
    // Every dispatch has finished (the status read-backs waited for them), or failed.
    bufs.keep(mesh);
    done
}

/// Loop steps a front vertex may cost an invocation: its neighbours scanned, then queued; lanes
/// run in step, so the candidates' largest degree prices every vertex (a fan-triangulated cap's
/// valence of 16: 33 steps). Smooth mode scanned two lists more for its edge angles until they
/// came with the edge records (`GpuMesh::relax_edges`), and is priced the same now.
fn steps_per_vertex(topo: &Topology, cands: &[u32]) -> u32 {
    let degree = cands
        .iter()
        .map(|&v| topo.adjacency_offsets[v as usize + 1] - topo.adjacency_offsets[v as usize])
        .max()
        .unwrap_or(0);
    1 + 2 * degree
}

/// Dispatches rounds of the relaxation over `maps` workgroups (the first with `init`),
/// [`ROUNDS_PER_SUBMIT`] a submission, until no map is pending: converged or at its sweep cap
/// (`status`: the results buffer, its size, the sweep cap). Returns the results and the
/// dispatches issued.
fn submit_rounds(
    ctx: &crate::gpu::GpuContext,
    kernel: &crate::gpu::pipelines::Kernel,
    [init, more]: [&wgpu::BindGroup; 2],
    maps: u32,
    (results, results_size, max_sweeps): (&wgpu::Buffer, u64, u32),
) -> Result<(Vec<GeoResult>, u32)> {
    let mut dispatches = 0;
    loop {
        ctx.scoped("exponential maps", || {
            let mut enc = ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("expmap"),
                });
            {
                let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("expmap.relax"),
                    timestamp_writes: None,
                });
                pass.set_pipeline(&kernel.pipeline);
                for k in 0..ROUNDS_PER_SUBMIT {
                    let first = dispatches == 0 && k == 0;
                    pass.set_bind_group(0, if first { init } else { more }, &[]);
                    pass.dispatch_workgroups(maps, 1, 1);
                }
            }
            ctx.queue.submit([enc.finish()]);
        })?;
        dispatches += ROUNDS_PER_SUBMIT;
        let bytes = ctx.read_buffer(results, results_size, "expmap status read-back")?;
        let res: Vec<GeoResult> = bytemuck::cast_slice(&bytes).to_vec();
        let pending = res
            .iter()
            .any(|r| r.converged == 0 && r.sweeps < max_sweeps);
        if !pending {
            return Ok((res, dispatches));
        }
    }
}

/// The CPU twin's maps, uploaded into their slots: the GL path of [`run`], and the bake's path on
/// a CPU adapter ([`crate::bake::StagePaths::expmap`]). On wgpu's GL backend (Mesa llvmpipe) the
/// relaxation settles on longer paths than the shortest for some vertices (seen on Spot even with
/// one invocation per workgroup, so not a race; not yet understood; on Vulkan it matches the
/// twin, `tests/expmap.rs`). Each map comes from [`crate::maps::expmap::cpu::dem_cpu`] (same
/// fixed point), the maps on every core, and its whole slot is uploaded: (u, v, distance, 1)
/// reached, 2 for seed-triangle vertices, zeros elsewhere.
pub(crate) fn run_cpu_twin(
    ctx: &crate::gpu::GpuContext,
    mesh: SurfaceRef<'_>,
    maps: &[(Seed, Options, u32)],
    coords: &wgpu::Buffer,
) -> Result<(Vec<GeoResult>, u32)> {
    use rayon::prelude::*;
    let (topo, k) = (mesh.topo, mesh.surface);
    let n = topo.positions.len();
    // A slot per map at a time on each core: the maps of a chunk together may not fit memory.
    let threads = rayon::current_num_threads().max(1);
    let mut results = Vec::with_capacity(maps.len());
    for batch in maps.chunks(threads) {
        let slots: Vec<(Vec<[f32; 4]>, u32)> = batch
            .par_iter()
            .map(|(seed, opts, _)| {
                let map = crate::maps::expmap::cpu::dem_cpu(topo, seed, *opts, k);
                let seed_tri = topo.triangles[seed.triangle as usize];
                let mut data = vec![[0f32; 4]; n];
                let mut reached = 0;
                for (v, d) in data.iter_mut().enumerate() {
                    if map.dist[v].is_finite() {
                        let flag = if seed_tri.contains(&(v as u32)) {
                            2.0
                        } else {
                            1.0
                        };
                        *d = [map.uv[v][0], map.uv[v][1], map.dist[v], flag];
                        reached += 1;
                    }
                }
                (data, reached)
            })
            .collect();
        for ((data, reached), (_, _, slot)) in slots.into_iter().zip(batch) {
            ctx.scoped("exponential maps (CPU twin upload)", || {
                ctx.queue.write_buffer(
                    coords,
                    *slot as u64 * n as u64 * 16,
                    bytemuck::cast_slice(&data),
                )
            })?;
            results.push(GeoResult {
                sweeps: 0,
                reached,
                converged: 1,
                triangles_reached: 0,
            });
        }
    }
    Ok((results, 0))
}

/// Per-vertex result of a GPU map read back: (u, v, distance, state) with state 0 = unreached,
/// 1 = reached, 2 = seed-triangle vertex.
pub type MapCoords = Vec<[f32; 4]>;

/// Runs `maps` in chunks whose coords slots fit 64 MiB, calling `each(results, coords, dispatches)`
/// after every chunk.
fn in_chunks(
    ctx: &crate::gpu::GpuContext,
    pipes: &Pipelines,
    mesh: SurfaceRef<'_>,
    maps: &[(Seed, Options)],
    mut each: impl FnMut(Vec<GeoResult>, &wgpu::Buffer, u32) -> Result<()>,
) -> Result<()> {
    let nv = mesh.gpu.vertex_count as u64;
    let per_chunk = ((64u64 << 20) / (nv * 16)).max(1) as usize;
    let coords = ctx.scoped("exponential maps", || {
        ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("expmap.coords"),
            size: per_chunk.min(maps.len().max(1)) as u64 * nv * 16,
            // COPY_DST: the GL path uploads its CPU-twin maps.
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC
                | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    })?;
    for (n, chunk) in maps.chunks(per_chunk).enumerate() {
        if n > 0 {
            // A map writes only its own disc: the previous chunk's maps must not stay valid.
            ctx.scoped("exponential maps", || {
                let mut enc = ctx.device.create_command_encoder(&Default::default());
                enc.clear_buffer(&coords, 0, None);
                ctx.queue.submit([enc.finish()]);
            })?;
        }
        let slots: Vec<(Seed, Options, u32)> = chunk
            .iter()
            .enumerate()
            .map(|(i, (s, o))| (*s, *o, i as u32))
            .collect();
        let (results, d) = run(ctx, pipes, mesh, &slots, &coords)?;
        each(results, &coords, d)?;
    }
    Ok(())
}

/// Computes maps on the GPU and reads back only their status (the coordinates stay on the GPU, as
/// in a bake); returns the status and the dispatches issued. For benchmarks.
pub fn expmaps_gpu_status(
    ctx: &crate::gpu::GpuContext,
    pipes: &Pipelines,
    mesh: SurfaceRef<'_>,
    maps: &[(Seed, Options)],
) -> Result<(Vec<GeoResult>, u32)> {
    let mut out = Vec::with_capacity(maps.len());
    let mut dispatches = 0;
    in_chunks(ctx, pipes, mesh, maps, |r, _, d| {
        out.extend(r);
        dispatches += d;
        Ok(())
    })?;
    Ok((out, dispatches))
}

/// Computes maps on the GPU and reads them back (for tests, `decalbake param` and benchmarks).
pub fn expmaps_gpu(
    ctx: &crate::gpu::GpuContext,
    pipes: &Pipelines,
    mesh: SurfaceRef<'_>,
    maps: &[(Seed, Options)],
) -> Result<Vec<(MapCoords, GeoResult)>> {
    let nv = mesh.gpu.vertex_count as usize;
    let mut out = Vec::with_capacity(maps.len());
    in_chunks(ctx, pipes, mesh, maps, |results, coords, _| {
        let size = (results.len() * nv * 16) as u64;
        let c = ctx.read_buffer(coords, size, "expmap read-back")?;
        let c: &[[f32; 4]] = bytemuck::cast_slice(&c);
        for (i, r) in results.iter().enumerate() {
            out.push((c[i * nv..(i + 1) * nv].to_vec(), *r));
        }
        Ok(())
    })?;
    Ok(out)
}
