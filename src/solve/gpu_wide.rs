// SPDX-License-Identifier: MIT OR Apache-2.0
//! One large system's multigrid-preconditioned CG spread over many workgroups
//! (`wgsl/solve/cg_wide.wgsl`): the same iteration as `cg_amg.wgsl`, whose single workgroup runs
//! on one CPU thread of lavapipe (and one SM of a GPU), cut into its passes, each a dispatch over
//! as many workgroups as the rows need. What it costs and why (`decalbake bench --device`,
//! docs/performance.md): a dispatch costs about 9 µs on this machine's lavapipe and a workgroup barrier about
//! 65 ns, so an iteration of about 20 dispatches costs some 0.2 ms of fixed price against the
//! 20 ms one iteration of a 10k-vertex chart takes in one workgroup; spreading it lets both cores
//! work and takes the barriers between passes out of the loop (the dispatch boundary is the
//! barrier). `solve::gpu::cg_batched` sends a batch of one LSCM system (complex 2 × 2 blocks,
//! with a multigrid hierarchy) of at least [`wide_min_rows`] block rows here; a lone system on the
//! real form stays in one workgroup.

use crate::error::Result;
use crate::gpu::pipelines::Kernel;
use crate::gpu::GpuContext;
use crate::solve::sparse::{CgReport, CgStatus, PreconditionerKind};

/// Block rows (vertices of an LSCM chart) from which a lone system is spread over workgroups on a
/// CPU adapter. Below it the fixed price of a dispatch per pass outweighs the second core
/// (docs/, "Linear algebra": measured on 1k and 10k charts).
pub const WIDE_MIN_ROWS: usize = 4_096;
/// The same on a GPU. On an NVIDIA H200 (docs/, "On a real GPU"; `bench --linalg`'s
/// `gpu_one_workgroup_ms` and `gpu_spread_forced_ms`) the 10k chart took, in one workgroup
/// against spread, 147/175, 118/119, 181/76 and 124/92 ms in four runs (medians 136 against
/// 106), the 20k chart 326/224, the 40k 945/518 and 746/418, the 100k 2.08/1.26 s: spread below
/// the 10k chart. See [`wide_min_rows`].
pub const GPU_WIDE_MIN_ROWS: usize = 8_192;

/// When not 0, the block rows from which a lone system is spread (the benchmarks force both
/// paths); 0, the default, leaves it to [`wide_min_rows`].
#[doc(hidden)]
pub static WIDE_MIN_ROWS_OVERRIDE: std::sync::atomic::AtomicUsize =
    std::sync::atomic::AtomicUsize::new(0);

/// Block rows from which a lone system is spread on `ctx`'s adapter: [`WIDE_MIN_ROWS`] on a CPU
/// adapter (lavapipe), [`GPU_WIDE_MIN_ROWS`] on a GPU, unless [`WIDE_MIN_ROWS_OVERRIDE`] is set.
pub fn wide_min_rows(ctx: &GpuContext) -> usize {
    match WIDE_MIN_ROWS_OVERRIDE.load(std::sync::atomic::Ordering::Relaxed) {
        0 if ctx.device_type == Some(wgpu::DeviceType::Cpu) => WIDE_MIN_ROWS,
        0 => GPU_WIDE_MIN_ROWS,
        n => n,
    }
}
/// Partial-sum slots per quantity (`PARTS` in cg_wide.wgsl): the most workgroups of a fine pass.
const PARTS: u32 = 256;
/// Quantities with partial sums: <p, Ap>, <r, r>, the true residual's, <r, z> twice.
const SLOTS: u64 = 5;
/// Invocations per workgroup (`WG` of the `linalg` import).
const WG: u32 = 64;
/// Iterations a submission records. Few: an iteration is about 20 dispatches here (one in
/// `cg_amg`), and those recorded after convergence still cost their launches, where a submission
/// and its status read-back cost some 40 µs (`bench --device`).
const ITERS_PER_SUBMIT: u32 = 8;

/// The passes of cg_wide.wgsl and cg_wide_plain.wgsl (keep in sync with
/// wgsl/shared/cg_wide_common.wgsl).
mod pass {
    pub const INIT_RESIDUAL: u32 = 0;
    pub const INIT_CHECK: u32 = 1;
    pub const SPMV: u32 = 2;
    pub const UPDATE: u32 = 3;
    pub const TRUE_RESIDUAL: u32 = 5;
    pub const TRUE_CHECK: u32 = 6;
    pub const DOWN: u32 = 7;
    pub const RESTRICT: u32 = 8;
    pub const COARSE: u32 = 9;
    pub const PROLONG: u32 = 10;
    pub const SMOOTH_RESIDUAL: u32 = 11;
    pub const SMOOTH_UPDATE: u32 = 12;
    pub const UPDATE_P: u32 = 13;
}

/// Keep in sync with `Wide` in cg_wide.wgsl.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct WideRound {
    phase: u32,
    level: u32,
    total: u32,
    sys: u32,
    parts: u32,
    pad: [u32; 3],
}

/// Keep in sync with `State` in wgsl/shared/cg_state.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct State {
    status: u32,
    iters: u32,
    pad: [u32; 2],
    rz: f32,
    bnorm: f32,
    rel_residual: f32,
    scale: f32,
}

/// What the kernel binds, uploaded by `solve::gpu` (bindings 1-6 and 12-17 of cg_amg.wgsl, less 4
/// and 14), and the one system's hierarchy.
pub struct WideInputs<'a> {
    /// The `System` row of the one system (`SystemDesc`'s bytes), its rows in block units.
    pub system: &'a [u8],
    /// Its first row and rows.
    pub rows: (u32, u32),
    /// Its iteration budget.
    pub max_iter: u32,
    /// The matrix: row spans, entries ([`crate::solve::gpu::GpuCsr`]).
    pub matrix: [&'a wgpu::Buffer; 2],
    /// Right-hand side.
    pub b: &'a wgpu::Buffer,
    /// The Jacobi weights (the diagonal's inverse).
    pub dinv: &'a wgpu::Buffer,
    /// The start, overwritten by the solution.
    pub x: &'a wgpu::Buffer,
    /// Bytes of one vector (r, p, Ap).
    pub vector_bytes: u64,
    /// Prolongators (row spans, entries), levels, coarsest inverse, the V-cycle's three vectors.
    pub hierarchy: [&'a wgpu::Buffer; 5],
    /// Rows of the index space (every level).
    pub total: u32,
    /// (first row, rows) of each of the system's levels, fine first.
    pub levels: Vec<[u32; 2]>,
}

/// The solve's outcome: the report, dispatches and submissions.
pub struct WideSolved {
    /// Iterations, residual and status.
    pub report: CgReport,
    /// Compute dispatches recorded.
    pub dispatches: u32,
    /// Queue submissions.
    pub submits: u32,
}

/// When not 0, a spread solve, once finished, times its fine level's main passes, this many
/// dispatches of each in one submission, into [`LAST_PASS_TIMES`] (`decalbake bench --linalg`:
/// the CG's phases against the copy bandwidth). The solve's result is not touched: the timed
/// passes write a scratch `x`.
#[doc(hidden)]
pub static TIME_PASSES_REPS: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
/// The last timed solve's passes (see [`TIME_PASSES_REPS`]).
#[doc(hidden)]
pub static LAST_PASS_TIMES: std::sync::Mutex<Vec<PassTime>> = std::sync::Mutex::new(Vec::new());

/// One pass's time and the bytes it moves.
#[derive(Clone, Debug, serde::Serialize)]
pub struct PassTime {
    /// `spmv` (Ap and <p, Ap>), `update` (x, r and the multigrid's input, <r, r>),
    /// `smooth_update` (z, <r, z>), `update_p` (p); the V-cycle's `down`, `restrict`, `coarse`,
    /// `prolong`, `smooth_residual`; `true_residual`.
    pub pass: &'static str,
    /// Its multigrid level (0: the fine one).
    pub level: u32,
    /// Workgroups of its dispatch.
    pub workgroups: u32,
    /// Microseconds a dispatch.
    pub us: f64,
    /// Bytes a dispatch reads and writes once each: the matrix's spans and entries and three
    /// vectors for `spmv`; x, r read and written, p, Ap read, the multigrid's input written for
    /// `update` (56 bytes a block row); z read and written, its two inputs and r read for
    /// `smooth_update` (36); z read, p read and written for `update_p` (24); 0 for the rest (not
    /// counted).
    pub bytes: u64,
}

/// The buffers a spread solve adds to its inputs.
struct Scratch {
    sys: wgpu::Buffer,
    r: wgpu::Buffer,
    p: wgpu::Buffer,
    ap: wgpu::Buffer,
    state: wgpu::Buffer,
    partials: wgpu::Buffer,
}

impl Scratch {
    fn new(ctx: &GpuContext, inputs: &WideInputs) -> Self {
        let dev = &ctx.device;
        let vector = |label: &str| {
            dev.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: inputs.vector_bytes.max(16),
                usage: wgpu::BufferUsages::STORAGE,
                mapped_at_creation: false,
            })
        };
        Self {
            sys: ctx.storage_init("cg.systems", inputs.system, wgpu::BufferUsages::empty()),
            r: vector("cg.r"),
            p: vector("cg.p"),
            ap: vector("cg.ap"),
            state: ctx.storage_init(
                "cg.state",
                bytemuck::bytes_of(&State::default()),
                wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
            ),
            partials: dev.create_buffer(&wgpu::BufferDescriptor {
                label: Some("cg.partials"),
                size: SLOTS * PARTS as u64 * 16,
                usage: wgpu::BufferUsages::STORAGE,
                mapped_at_creation: false,
            }),
        }
    }

    /// One bind group per (pass, level) of `keys`, for its kernel, with `x` as the solution.
    fn groups(
        &self,
        ctx: &GpuContext,
        kernels: (&Kernel, &Kernel),
        inputs: &WideInputs,
        fine: u32,
        keys: &[(u32, u32)],
        x: &wgpu::Buffer,
    ) -> std::collections::HashMap<(u32, u32), wgpu::BindGroup> {
        let mut keys = keys.to_vec();
        keys.sort_unstable();
        keys.dedup();
        let mut bind_groups = std::collections::HashMap::new();
        for (phase, level) in keys {
            let u = ctx.storage_init(
                "cg.wide",
                bytemuck::bytes_of(&WideRound {
                    phase,
                    level,
                    total: inputs.total,
                    sys: 0,
                    parts: fine,
                    pad: [0; 3],
                }),
                wgpu::BufferUsages::empty(),
            );
            let [rp, ents] = inputs.matrix;
            let h = inputs.hierarchy;
            let entries = [
                (0, u.as_entire_binding()),
                (1, self.sys.as_entire_binding()),
                (2, rp.as_entire_binding()),
                (3, ents.as_entire_binding()),
                (5, inputs.b.as_entire_binding()),
                (6, inputs.dinv.as_entire_binding()),
                (7, x.as_entire_binding()),
                (8, self.r.as_entire_binding()),
                (9, self.p.as_entire_binding()),
                (10, self.ap.as_entire_binding()),
                (11, self.state.as_entire_binding()),
                (12, h[0].as_entire_binding()),
                (13, h[1].as_entire_binding()),
                (15, h[2].as_entire_binding()),
                (16, h[3].as_entire_binding()),
                (17, h[4].as_entire_binding()),
                (18, self.partials.as_entire_binding()),
            ];
            let kernel = if plain(phase) { kernels.1 } else { kernels.0 };
            bind_groups.insert(
                (phase, level),
                kernel.bind(&ctx.device, "cg.wide", &entries),
            );
        }
        bind_groups
    }
}

/// A pass's name in the benchmark's output.
fn pass_name(phase: u32) -> &'static str {
    match phase {
        pass::SPMV => "spmv",
        pass::UPDATE => "update",
        pass::TRUE_RESIDUAL => "true_residual",
        pass::DOWN => "down",
        pass::RESTRICT => "restrict",
        pass::COARSE => "coarse",
        pass::PROLONG => "prolong",
        pass::SMOOTH_RESIDUAL => "smooth_residual",
        pass::SMOOTH_UPDATE => "smooth_update",
        pass::UPDATE_P => "update_p",
        _ => "other",
    }
}

/// Times every step of an iteration after a solve (see [`TIME_PASSES_REPS`]) but the status
/// check: the state set running again, each step `reps` times in one submission on a scratch `x`,
/// wall time over `reps` (a dispatch's own cost included, as in a solve); the bytes counted for
/// the four fine passes [`PassTime`] names.
fn time_passes(
    ctx: &GpuContext,
    kernels: (&Kernel, &Kernel),
    inputs: &WideInputs,
    (bufs, fine, iteration): (&Scratch, u32, &[Step]),
    reps: u32,
) -> Result<Vec<PassTime>> {
    let n = inputs.rows.1 as u64;
    let matrix = inputs.matrix[0].size() + inputs.matrix[1].size();
    let bytes = |phase: u32, level: u32| match (phase, level) {
        (pass::SPMV, 0) => matrix + 3 * 8 * n,
        (pass::UPDATE, 0) => 56 * n,
        (pass::SMOOTH_UPDATE, 0) => 36 * n,
        (pass::UPDATE_P, 0) => 24 * n,
        _ => 0,
    };
    let mut steps: Vec<Step> = iteration
        .iter()
        .copied()
        .filter(|s| s.0 != pass::TRUE_CHECK)
        .collect();
    steps.dedup();
    let x = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("cg.x_timing"),
        size: inputs.vector_bytes.max(16),
        usage: wgpu::BufferUsages::STORAGE,
        mapped_at_creation: false,
    });
    let keys: Vec<(u32, u32)> = steps.iter().map(|s| (s.0, s.1)).collect();
    let groups = ctx.scoped("conjugate gradient", || {
        bufs.groups(ctx, kernels, inputs, fine, &keys, &x)
    })?;
    // Running, one iteration in (the passes that read the iteration count pick their slots).
    let running = State {
        status: 1,
        iters: 1,
        ..State::default()
    };
    let mut out = Vec::new();
    for (phase, level, wgs) in steps {
        let run = |count: u32| -> Result<f64> {
            ctx.queue
                .write_buffer(&bufs.state, 0, bytemuck::bytes_of(&running));
            let t = std::time::Instant::now();
            ctx.scoped("conjugate gradient", || {
                let mut enc = ctx.device.create_command_encoder(&Default::default());
                {
                    let mut cp = enc.begin_compute_pass(&Default::default());
                    let kernel = if plain(phase) { kernels.1 } else { kernels.0 };
                    cp.set_pipeline(&kernel.pipeline);
                    cp.set_bind_group(0, &groups[&(phase, level)], &[]);
                    for _ in 0..count {
                        cp.dispatch_workgroups(wgs, 1, 1);
                    }
                }
                ctx.queue.submit([enc.finish()]);
            })?;
            ctx.wait("conjugate gradient")?;
            Ok(t.elapsed().as_secs_f64() * 1e6)
        };
        run(1)?;
        let us = (run(reps)? / reps as f64).min(run(reps)? / reps as f64);
        out.push(PassTime {
            pass: pass_name(phase),
            level,
            workgroups: wgs,
            us,
            bytes: bytes(phase, level),
        });
    }
    Ok(out)
}

/// One dispatch: (pass, level, workgroups).
type Step = (u32, u32, u32);

/// Whether `phase` runs in cg_wide_plain.wgsl (no sums, no barriers) rather than cg_wide.wgsl.
fn plain(phase: u32) -> bool {
    (pass::DOWN..=pass::SMOOTH_RESIDUAL).contains(&phase)
}

/// The dispatches of one V-cycle and the `p` update over `levels`, a pass over `n` rows on
/// `groups(n)` workgroups.
fn vcycle(levels: &[[u32; 2]], groups: impl Fn(u32) -> u32) -> Vec<Step> {
    let nl = levels.len() as u32;
    let g = |k: u32| groups(levels[k as usize][1]);
    let mut seq = Vec::new();
    for k in 0..nl - 1 {
        seq.push((pass::DOWN, k, g(k)));
        seq.push((pass::RESTRICT, k, g(k + 1)));
    }
    seq.push((pass::COARSE, nl - 1, g(nl - 1)));
    // A coarse level's post-smoothing update is applied by the prolongation that reads it
    // (cg_wide_plain.wgsl); the fine level's gives z and <r, z>.
    for k in (0..nl - 1).rev() {
        seq.push((pass::PROLONG, k, g(k)));
        seq.push((pass::SMOOTH_RESIDUAL, k, g(k)));
    }
    seq.push((pass::SMOOTH_UPDATE, 0, g(0)));
    seq.push((pass::UPDATE_P, 0, g(0)));
    seq
}

/// The most workgroups a pass gets: on a software driver (lavapipe: a workgroup runs on one
/// thread, and every workgroup of a dispatch costs its launch) two per core, which keeps every
/// core busy; on a GPU [`PARTS`].
fn max_groups(ctx: &GpuContext) -> u32 {
    match ctx.device_type {
        Some(wgpu::DeviceType::Cpu) => std::thread::available_parallelism()
            .map_or(2, |n| 2 * n.get() as u32)
            .min(PARTS),
        _ => PARTS,
    }
}

/// Solves the one system of `inputs` into `inputs.x` (left on the GPU for the caller to read), with
/// `kernels` = (cg_wide, cg_wide_plain).
pub fn solve(
    ctx: &GpuContext,
    kernels: (&Kernel, &Kernel),
    inputs: &WideInputs,
) -> Result<WideSolved> {
    let cap = max_groups(ctx);
    let groups = |n: u32| n.div_ceil(WG).clamp(1, cap);
    let fine = groups(inputs.rows.1);
    let init: Vec<Step> = [(pass::INIT_RESIDUAL, 0, fine), (pass::INIT_CHECK, 0, 1)]
        .into_iter()
        .chain(vcycle(&inputs.levels, groups))
        .collect();
    let iteration: Vec<Step> = [
        (pass::SPMV, 0, fine),
        (pass::UPDATE, 0, fine),
        (pass::TRUE_RESIDUAL, 0, fine),
        (pass::TRUE_CHECK, 0, 1),
    ]
    .into_iter()
    .chain(vcycle(&inputs.levels, groups))
    .collect();
    let keys: Vec<(u32, u32)> = init.iter().chain(&iteration).map(|s| (s.0, s.1)).collect();
    let bufs = ctx.scoped("conjugate gradient", || Scratch::new(ctx, inputs))?;
    let bind_groups = ctx.scoped("conjugate gradient", || {
        bufs.groups(ctx, kernels, inputs, fine, &keys, inputs.x)
    })?;
    let state = &bufs.state;
    let sequences = Sequences {
        init: &init,
        iteration: &iteration,
        kernels,
        bind_groups: &bind_groups,
    };
    let (st, dispatches, submits) = sequences.run(ctx, state, inputs.max_iter)?;
    let reps = TIME_PASSES_REPS.load(std::sync::atomic::Ordering::Relaxed);
    if reps > 0 {
        let times = time_passes(ctx, kernels, inputs, (&bufs, fine, &iteration), reps)?;
        *LAST_PASS_TIMES.lock().unwrap_or_else(|e| e.into_inner()) = times;
    }
    Ok(WideSolved {
        report: CgReport {
            preconditioner: PreconditionerKind::Amg,
            status: match st.status {
                2 => CgStatus::Converged,
                3 | 1 => CgStatus::NotConverged,
                _ => CgStatus::Breakdown,
            },
            iterations: st.iters,
            residual: st.rel_residual as f64,
        },
        dispatches,
        submits,
    })
}

/// The recorded passes of a solve and what they bind.
struct Sequences<'a> {
    init: &'a [Step],
    iteration: &'a [Step],
    /// (cg_wide, cg_wide_plain).
    kernels: (&'a Kernel, &'a Kernel),
    bind_groups: &'a std::collections::HashMap<(u32, u32), wgpu::BindGroup>,
}

impl Sequences<'_> {
    /// Submits the initialisation and then [`ITERS_PER_SUBMIT`] iterations at a time until the
    /// status in `state` is final or `max_iter` iterations were recorded; returns the last
    /// status, the dispatches and the submissions.
    fn run(
        &self,
        ctx: &GpuContext,
        state: &wgpu::Buffer,
        max_iter: u32,
    ) -> Result<(State, u32, u32)> {
        let (mut dispatches, mut submits, mut recorded) = (0u32, 0u32, 0u32);
        loop {
            let iters = ITERS_PER_SUBMIT.min(max_iter.saturating_add(1));
            ctx.scoped("conjugate gradient", || {
                let mut enc = ctx
                    .device
                    .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                        label: Some("cg.wide"),
                    });
                {
                    let mut cp = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                        label: Some("cg.wide"),
                        timestamp_writes: None,
                    });
                    let first = (submits == 0).then_some(self.init);
                    let repeated = std::iter::repeat_n(self.iteration, iters as usize);
                    for &(phase, level, n) in first.into_iter().chain(repeated).flatten() {
                        let kernel = if plain(phase) {
                            self.kernels.1
                        } else {
                            self.kernels.0
                        };
                        cp.set_pipeline(&kernel.pipeline);
                        cp.set_bind_group(0, &self.bind_groups[&(phase, level)], &[]);
                        cp.dispatch_workgroups(n, 1, 1);
                        dispatches += 1;
                    }
                }
                ctx.queue.submit([enc.finish()]);
            })?;
            submits += 1;
            recorded += iters;
            let bytes = ctx.read_buffer(state, 32, "conjugate-gradient status read-back")?;
            let st: State = bytemuck::pod_read_unaligned(&bytes[..32]);
            if st.status >= 2 || recorded > max_iter {
                return Ok((st, dispatches, submits));
            }
        }
    }
}
