// SPDX-License-Identifier: MIT OR Apache-2.0
//! GPU sparse linear algebra: CSR matrices in storage buffers ([`GpuCsr`]), the product `A x`
//! (`wgsl/solve/spmv.wgsl`), batched dot products and norms (`wgsl/solve/dot_batched.wgsl`) and a batched
//! Jacobi-preconditioned conjugate gradient (`wgsl/solve/cg_batched.wgsl`), plus the streaming copy used as
//! the bandwidth reference in benchmarks. CPU twins: [`crate::solve::sparse`], [`crate::solve::cg`].
//!
//! The solver is built around what lavapipe charges (about 80 µs per dispatch, 280 µs per
//! submit-and-wait) and what it cannot do (an invocation that loops more than about 65535 times is
//! silently abandoned): one workgroup per system runs a whole block of fused iterations per dispatch,
//! sized to stay under the loop cut-off; all state lives in buffers; a submission carries enough
//! dispatches for about [`ITERS_PER_SUBMIT`] iterations and the host reads back only the per-system
//! status between submissions (the first submission covers [`FIRST_SUBMIT_ITERS`] iterations, each
//! next one twice as many). All arithmetic is f32 with a fixed reduction order, so within one kernel
//! a system's iteration count and result do not depend on the rest of its batch.
//!
//! On a CPU adapter (lavapipe), batches of at least [`PACK_MIN_SYSTEMS`] systems solve their small
//! systems one per invocation instead (`wgsl/solve/cg_packed.wgsl`, [`Packing`]): no barriers, and
//! the SIMD lanes and both cores of lavapipe each work on their own system (on a GPU each keeps its
//! workgroup: the device probe finds packing 5× slower there). On lavapipe (Mesa 22.3) every storage load whose address differs
//! between the lanes runs as a loop over the lanes, about 5-10 ns a lane, and the CG's loads
//! dominate its time (hoisting one load per matrix entry out of the product loop made the packed
//! solve 1.21× faster), so what counts is loads per iteration. LSCM systems are real forms of
//! Hermitian matrices: batches of them are solved on their complex 2 × 2 blocks
//! ([`ComplexCsr`], `wgsl/shared/cg_complex.wgsl`), one column and one (a, b) read for four real
//! entries, 2.4× faster than the packed real CSR on a stroke's charts.
//!
//! Large systems (from [`crate::solve::amg::AMG_MIN_ROWS`] rows) are preconditioned by a
//! smoothed-aggregation V-cycle instead of Jacobi (`wgsl/solve/cg_amg.wgsl`, the hierarchy laid
//! out by `src/solve/gpu_amg.rs`): 17-39× fewer iterations on LSCM charts of 10k-100k
//! vertices, each costing about 1.7 Jacobi ones on complex blocks (docs/, "Linear algebra").
//!
//! A batch of one such system of at least [`gpu_wide::wide_min_rows`] block rows is spread over
//! many workgroups instead, a dispatch per pass of the iteration ([`gpu_wide`]), so that every core
//! works on it.

use crate::error::{Error, Result};
use crate::gpu::pipelines::{Kernel, Pipelines};
use crate::gpu::GpuContext;
use crate::solve::amg::Hierarchy;
use crate::solve::gpu_amg::{self, all_fit, AmgBatch};
use crate::solve::gpu_wide;
use crate::solve::sparse::{CgReport, CgStatus, ComplexCsr, Csr, PreconditionerKind};

/// Loop steps one invocation may run per dispatch (lavapipe abandons invocations past about 65535).
const LOOP_BUDGET: usize = 20_000;
/// Loop steps per invocation above which a single iteration is refused (lavapipe abandons an
/// invocation past about 65535).
const HARD_LOOP_LIMIT: usize = 50_000;
/// Iterations per submission before the host looks at the status (at most; see [`FIRST_SUBMIT_ITERS`]).
pub const ITERS_PER_SUBMIT: u32 = 512;
/// Iterations of a solve's first submission; each next submission doubles them.
pub const FIRST_SUBMIT_ITERS: u32 = 16;
/// Workgroup size of the batched kernels (`WG` in wgsl/shared/linalg.wgsl).
const WG: usize = 256;
/// The class of systems solved one per invocation (`wgsl/solve/cg_packed.wgsl`).
const PACKED: u32 = 2;
/// The class of systems preconditioned by a multigrid V-cycle (`wgsl/solve/cg_amg.wgsl`).
const MULTIGRID: u32 = 3;
/// Asked for by [`SystemDesc::jacobi_only`]; replaced by a Jacobi class before any kernel runs.
const JACOBI_ONLY: u32 = 4;
/// Class of a system kept in one workgroup even where it would be spread over many
/// ([`SystemDesc::one_workgroup`]).
const ONE_WORKGROUP: u32 = 5;
/// Workgroup size of the packed kernel (`PACK_WG` there).
const PACK_WG: u32 = 64;
/// Batches with at least this many systems pack the small ones one per invocation (where
/// [`Packing`] says so): enough to fill both cores' SIMD lanes of lavapipe (2 × 8), see
/// `kernel_classes`.
pub const PACK_MIN_SYSTEMS: usize = 16;

/// Whether a batch's small systems are solved one per invocation (`cg_packed`) or one per
/// workgroup (`cg_batched`, `cg_amg`).
///
/// The device probe (`decalbake bench --device`, `dense_small_systems`; docs/, "On a real GPU")
/// decides the default: on lavapipe one small system per invocation is 2.6-3.7× faster than one
/// per workgroup (no barriers, each SIMD lane its own system); on an NVIDIA H200 it is 5× slower
/// (a warp's lanes each walking their own system). So [`Packing::Auto`] packs on a CPU adapter
/// only; an adapter of unknown kind (a host's device handed in) is taken for a GPU.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Packing {
    /// Pack batches of at least [`PACK_MIN_SYSTEMS`] systems on a CPU adapter (lavapipe), not on
    /// a GPU.
    #[default]
    Auto,
    /// Pack batches of at least [`PACK_MIN_SYSTEMS`] systems on any adapter.
    Packed,
    /// Never pack: every system gets a workgroup (or, if large, many).
    PerWorkgroup,
}

impl Packing {
    /// Whether a batch of `systems` systems is packed on `ctx`'s adapter.
    pub fn packs(self, ctx: &GpuContext, systems: usize) -> bool {
        systems >= PACK_MIN_SYSTEMS
            && match self {
                Packing::Auto => ctx.device_type == Some(wgpu::DeviceType::Cpu),
                Packing::Packed => true,
                Packing::PerWorkgroup => false,
            }
    }
}

/// One system of a batch. Keep in sync with `System` in wgsl/shared/linalg.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub struct SystemDesc {
    /// First row.
    pub row0: u32,
    /// Rows.
    pub n: u32,
    /// Iteration budget.
    pub max_iter: u32,
    /// Set by the solver: 1 = solved by the 256-wide kernel, 0 = by the 64-wide one, 2 = packed
    /// (one per invocation).
    wide: u32,
    /// Target relative residual |b - A x| / |b|.
    pub rtol: f32,
    /// Set by the solver for [`MULTIGRID`] systems: first level, levels, coarsest inverse's
    /// offset (`System` in wgsl/shared/linalg.wgsl).
    amg: [u32; 3],
}

impl SystemDesc {
    /// System of rows `row0 .. row0 + n`.
    pub fn new(row0: usize, n: usize, rtol: f32, max_iter: u32) -> Self {
        Self {
            row0: row0 as u32,
            n: n as u32,
            max_iter,
            rtol,
            ..Default::default()
        }
    }

    /// The same system preconditioned by Jacobi even where it would get a V-cycle (the
    /// benchmarks' baseline).
    pub fn jacobi_only(self) -> Self {
        Self {
            wide: JACOBI_ONLY,
            ..self
        }
    }

    /// The same system solved in one workgroup (`cg_amg`) even where a lone system would be
    /// spread over many (`cg_wide`, [`crate::solve::gpu_wide`]): the tests' and benchmarks'
    /// baseline.
    pub fn one_workgroup(self) -> Self {
        Self {
            wide: ONE_WORKGROUP,
            ..self
        }
    }
}

/// Keep in sync with `Round` in wgsl/shared/cg_state.wgsl.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct CgRound {
    iters: u32,
    base: u32,
    /// Systems in this dispatch (the packed kernel's bound; the workgroup kernels use one group each).
    count: u32,
    /// Rows of the multigrid kernel's index space (`gpu_amg::AmgBatch::total`).
    total: u32,
}

/// Keep in sync with `State` in wgsl/shared/cg_state.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct CgState {
    status: u32,
    iters: u32,
    pad0: [u32; 2],
    rz: f32,
    bnorm: f32,
    rel_residual: f32,
    scale: f32,
}

/// A CSR matrix in storage buffers (values f32), each row's (first, end) entry in one load and each
/// stored entry's column and value side by side ([`entries`]): on lavapipe every storage load is a
/// loop over the SIMD lanes, so one load of both instead of two takes a third of the loads out of
/// a row product (docs/, "Linear algebra").
pub struct GpuCsr {
    /// Per row, (first entry, end) ([`spans`]).
    pub spans: wgpu::Buffer,
    /// The entries: (column, value bits) on the real form, (column, a bits, b bits, w bits) on
    /// complex blocks (w: the smoother's weight of the column's row, or 0; [`entries`]).
    pub ents: wgpu::Buffer,
    /// Rows.
    pub rows: u32,
    /// Stored entries.
    pub nnz: u32,
    /// Longest row.
    pub max_row_len: u32,
}

/// A real matrix in the standalone product's layout ([`spmv`]): per row (first pair, pairs, and
/// the last entry of a row of odd length: column, value bits), and the other entries two to a
/// 16-byte pair (column, value bits, column, value bits). A row's loads are then one span, its
/// pairs and one gather an entry (with the odd entry in a pair of its own, a mesh Laplacian's
/// rows of 7 entries took a gather of a zero too).
pub struct GpuPairs {
    /// (first pair, pairs, odd entry's column, its value bits) of each row; (.., 0, 0) for a row
    /// of even length.
    pub spans: wgpu::Buffer,
    /// The pairs.
    pub pairs: wgpu::Buffer,
    /// Rows.
    pub rows: u32,
    /// Stored entries (without the padding).
    pub nnz: u32,
}

impl GpuPairs {
    /// Uploads `a` (values rounded to f32) in the paired layout.
    pub fn upload(ctx: &GpuContext, a: &Csr) -> Result<Self> {
        let (spans, pairs) = paired(a);
        let buf =
            |label: &str, bytes: &[u8]| ctx.storage_init(label, bytes, wgpu::BufferUsages::empty());
        ctx.scoped("sparse matrix upload", || Self {
            spans: buf("pairs.spans", bytemuck::cast_slice(&spans)),
            pairs: buf("pairs.pairs", bytemuck::cast_slice(&pairs)),
            rows: a.rows as u32,
            nnz: a.nnz() as u32,
        })
    }

    /// Bytes one product streams at least once, counted as for CSR (8 per entry, 12 per row for
    /// the row offsets, x and y), so the figure compares with the earlier layout's.
    pub fn bytes_per_product(&self) -> u64 {
        self.nnz as u64 * 8 + self.rows as u64 * 4 * 3
    }
}

/// The paired layout of `a` ([`GpuPairs`]): per row (first pair, pairs, odd entry), and the pairs.
pub fn paired(a: &Csr) -> (Vec<[u32; 4]>, Vec<[u32; 4]>) {
    let mut spans = Vec::with_capacity(a.rows);
    let mut pairs = Vec::with_capacity(a.nnz() / 2 + a.rows);
    for i in 0..a.rows {
        let first = pairs.len() as u32;
        let row: Vec<(usize, f64)> = a.row(i).collect();
        let mut odd = [0, 0];
        for two in row.chunks(2) {
            let (c0, v0) = two[0];
            match two.get(1) {
                Some(&(c1, v1)) => pairs.push([
                    c0 as u32,
                    (v0 as f32).to_bits(),
                    c1 as u32,
                    (v1 as f32).to_bits(),
                ]),
                None => odd = [c0 as u32, (v0 as f32).to_bits()],
            }
        }
        spans.push([first, pairs.len() as u32 - first, odd[0], odd[1]]);
    }
    (spans, pairs)
}

/// The entries of a CSR matrix (`cols`, and `vals` with one or two values an entry) as the CG
/// kernels read them (`E` in `wgsl/shared/cg_real.wgsl` and `cg_complex.wgsl`): one value an entry
/// gives (column, value bits), two give (column, a bits, b bits, w bits), a 16-byte load, w the
/// smoother's weight of the column's row (`col_weights`; 0 without): the spread CG's smoothed
/// row products (`wgsl/shared/cg_wide_common.wgsl`) read it there instead of gathering it.
pub fn entries(cols: &[u32], vals: &[f32], col_weights: Option<&[f32]>) -> Vec<u32> {
    let per = if cols.is_empty() {
        1
    } else {
        vals.len() / cols.len()
    };
    assert!(per == 1 || per == 2, "entries: {per} values an entry");
    let mut out = Vec::with_capacity(cols.len() * 2 * per);
    for (&c, v) in cols.iter().zip(vals.chunks(per)) {
        out.push(c);
        out.extend(v.iter().map(|x| x.to_bits()));
        if per == 2 {
            out.push(col_weights.map_or(0, |w| w[c as usize].to_bits()));
        }
    }
    out
}

/// Row offsets as each row's (first entry, end): one 8-byte load a row instead of two.
pub fn spans(row_ptr: &[u32]) -> Vec<[u32; 2]> {
    row_ptr.windows(2).map(|w| [w[0], w[1]]).collect()
}

fn f32s(v: &[f64]) -> Vec<f32> {
    v.iter().map(|&x| x as f32).collect()
}

impl GpuCsr {
    /// Uploads `a` (values rounded to f32).
    pub fn upload(ctx: &GpuContext, a: &Csr) -> Result<Self> {
        let ents = entries(&a.cols, &f32s(&a.vals), None);
        Self::upload_parts(ctx, (&a.row_ptr, &ents, a.nnz()), a.max_row_len())
    }

    /// Uploads the blocks of `c` (each (a, b) as two f32; `rows`, `nnz` and `max_row_len` count
    /// blocks), each with the weight of its column's row in `col_weights` where given.
    pub fn upload_complex(
        ctx: &GpuContext,
        c: &ComplexCsr,
        col_weights: Option<&[f32]>,
    ) -> Result<Self> {
        let vals: Vec<f32> = c.vals.iter().flatten().map(|&v| v as f32).collect();
        let ents = entries(&c.cols, &vals, col_weights);
        Self::upload_parts(ctx, (&c.row_ptr, &ents, c.cols.len()), c.max_row_len())
    }

    fn upload_parts(
        ctx: &GpuContext,
        (row_ptr, ents, nnz): (&[u32], &[u32], usize),
        max_row_len: usize,
    ) -> Result<Self> {
        let buf =
            |label: &str, bytes: &[u8]| ctx.storage_init(label, bytes, wgpu::BufferUsages::empty());
        ctx.scoped("sparse matrix upload", || Self {
            spans: buf("csr.spans", bytemuck::cast_slice(&spans(row_ptr))),
            ents: buf("csr.entries", bytemuck::cast_slice(ents)),
            rows: row_ptr.len() as u32 - 1,
            nnz: nnz as u32,
            max_row_len: max_row_len as u32,
        })
    }

    /// Bytes one product streams at least once: the matrix, x and y.
    pub fn bytes_per_product(&self) -> u64 {
        self.nnz as u64 * 8 + self.rows as u64 * 4 * 3
    }
}

/// Workgroup grid for `groups` one-dimensional workgroups, within the 65535 per-dimension limit.
fn grid(groups: u32) -> (u32, u32) {
    let x = groups.clamp(1, 65535);
    (x, groups.div_ceil(x).max(1))
}

/// `y = A x` on the GPU, `reps` times in one submission (for benchmarks; 1 for a plain product).
/// Returns y and the seconds the submission took.
pub fn spmv(
    ctx: &GpuContext,
    pipes: &Pipelines,
    a: &GpuPairs,
    x: &[f32],
    reps: u32,
) -> Result<(Vec<f32>, f64)> {
    let dev = &ctx.device;
    let (xb, yb, dims, bg) = ctx.scoped("spmv", || {
        let xb = ctx.storage_init(
            "spmv.x",
            bytemuck::cast_slice(x),
            wgpu::BufferUsages::empty(),
        );
        let yb = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("spmv.y"),
            size: (a.rows as u64 * 4).max(16),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let dims = ctx.uniform_init("spmv.dims", bytemuck::cast_slice(&[a.rows, 0, 0, 0]));
        let bg = pipes.spmv.bind(
            dev,
            "spmv",
            &[
                (0, dims.as_entire_binding()),
                (1, a.spans.as_entire_binding()),
                (2, a.pairs.as_entire_binding()),
                (4, xb.as_entire_binding()),
                (5, yb.as_entire_binding()),
            ],
        );
        (xb, yb, dims, bg)
    })?;
    let t = std::time::Instant::now();
    ctx.scoped("spmv", || {
        let mut enc = dev.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(&pipes.spmv.pipeline);
            pass.set_bind_group(0, &bg, &[]);
            let (gx, gy) = grid(a.rows.div_ceil(64));
            for _ in 0..reps.max(1) {
                pass.dispatch_workgroups(gx, gy, 1);
            }
        }
        ctx.queue.submit([enc.finish()]);
    })?;
    ctx.wait("spmv")?;
    let secs = t.elapsed().as_secs_f64();
    let y = ctx.read_buffer(&yb, a.rows as u64 * 4, "spmv read-back")?;
    drop((xb, dims));
    Ok((
        bytemuck::cast_slice(&y[..a.rows as usize * 4]).to_vec(),
        secs,
    ))
}

/// Batched dot products: per segment (`row0`, `n` of each [`SystemDesc`]), (<a, b>, <a, a>, <b, b>)
/// with the CG kernel's fixed reduction order.
pub fn dots(
    ctx: &GpuContext,
    pipes: &Pipelines,
    a: &[f32],
    b: &[f32],
    segments: &[SystemDesc],
) -> Result<Vec<[f32; 3]>> {
    let dev = &ctx.device;
    let out_size = (segments.len() as u64 * 16).max(16);
    let (out, bg, keep) = ctx.scoped("dot products", || {
        let sys = ctx.storage_init(
            "dot.systems",
            bytemuck::cast_slice(segments),
            wgpu::BufferUsages::empty(),
        );
        let ab = ctx.storage_init(
            "dot.a",
            bytemuck::cast_slice(a),
            wgpu::BufferUsages::empty(),
        );
        let bb = ctx.storage_init(
            "dot.b",
            bytemuck::cast_slice(b),
            wgpu::BufferUsages::empty(),
        );
        let out = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("dot.out"),
            size: out_size,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let bg = pipes.dot_batched.bind(
            dev,
            "dot",
            &[
                (0, sys.as_entire_binding()),
                (1, ab.as_entire_binding()),
                (2, bb.as_entire_binding()),
                (3, out.as_entire_binding()),
            ],
        );
        (out, bg, (sys, ab, bb))
    })?;
    ctx.scoped("dot products", || {
        let mut enc = dev.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(&pipes.dot_batched.pipeline);
            pass.set_bind_group(0, &bg, &[]);
            for base in (0..segments.len()).step_by(65535) {
                // Segments beyond the first 65535 would need an offset; benchmarks and tests stay below.
                debug_assert_eq!(base, 0, "at most 65535 segments");
                pass.dispatch_workgroups((segments.len() - base).min(65535) as u32, 1, 1);
            }
        }
        ctx.queue.submit([enc.finish()]);
    })?;
    let bytes = ctx.read_buffer(&out, out_size, "dot read-back")?;
    drop(keep);
    let v: &[[f32; 4]] = bytemuck::cast_slice(&bytes);
    Ok(v[..segments.len()]
        .iter()
        .map(|r| [r[0], r[1], r[2]])
        .collect())
}

/// Streams `bytes` (rounded to 16) from one buffer to another `reps` times in one submission;
/// returns the achieved bandwidth in GB/s (read + write bytes per second).
pub fn copy_bandwidth(ctx: &GpuContext, pipes: &Pipelines, bytes: u64, reps: u32) -> Result<f64> {
    let dev = &ctx.device;
    let len = (bytes / 16).max(1) as u32;
    let (bg, keep) = ctx.scoped("copy", || {
        let src = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("copy.src"),
            size: len as u64 * 16,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        let dst = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("copy.dst"),
            size: len as u64 * 16,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        let dims = ctx.uniform_init("copy.dims", bytemuck::cast_slice(&[len, 0, 0, 0]));
        let bg = pipes.copy.bind(
            dev,
            "copy",
            &[
                (0, dims.as_entire_binding()),
                (1, src.as_entire_binding()),
                (2, dst.as_entire_binding()),
            ],
        );
        (bg, (src, dst, dims))
    })?;
    let run = |n: u32| -> Result<f64> {
        let t = std::time::Instant::now();
        ctx.scoped("copy", || {
            let mut enc = dev.create_command_encoder(&Default::default());
            {
                let mut pass = enc.begin_compute_pass(&Default::default());
                pass.set_pipeline(&pipes.copy.pipeline);
                pass.set_bind_group(0, &bg, &[]);
                let (gx, gy) = grid(len.div_ceil(256));
                for _ in 0..n {
                    pass.dispatch_workgroups(gx, gy, 1);
                }
            }
            ctx.queue.submit([enc.finish()]);
        })?;
        ctx.wait("copy")?;
        Ok(t.elapsed().as_secs_f64())
    };
    run(1)?; // warm-up
    let secs = run(reps.max(1))?;
    drop(keep);
    Ok(2.0 * len as f64 * 16.0 * reps.max(1) as f64 / secs / 1e9)
}

/// Result of a batched solve.
#[derive(Debug, Clone)]
pub struct Solved {
    /// Solution, all systems (rows of the block-diagonal matrix).
    pub x: Vec<f32>,
    /// Per system.
    pub reports: Vec<CgReport>,
    /// Compute dispatches issued.
    pub dispatches: u32,
    /// Submissions (each followed by one status read-back).
    pub submits: u32,
    /// Systems solved one per invocation (`cg_packed.wgsl`); the rest had a workgroup each.
    pub packed: u32,
    /// Whether the packed systems, or the V-cycle's, were solved on complex 2 × 2 blocks
    /// ([`ComplexCsr`]).
    pub complex: bool,
    /// Systems preconditioned by a multigrid V-cycle (`cg_amg.wgsl`); the rest by Jacobi.
    pub multigrid: u32,
    /// Systems spread over many workgroups (`cg_wide.wgsl`, [`gpu_wide`]).
    pub spread: u32,
}

/// Solves every system of the block-diagonal SPD matrix `a` (`systems` give each block's rows,
/// tolerance and budget) by preconditioned CG from the warm start `x0`, on the GPU: a multigrid
/// V-cycle per iteration for systems of at least [`crate::solve::amg::AMG_MIN_ROWS`] rows whose
/// hierarchy builds and fits the loop limit (`cg_amg`, on complex 2 × 2 blocks for LSCM systems;
/// a batch that mixes such systems with others is solved as two), Jacobi for the rest.
///
/// A batch that [`Packing::Auto`] packs (at least [`PACK_MIN_SYSTEMS`] systems, on a CPU adapter)
/// whose matrix has the complex 2 × 2 block structure of LSCM systems ([`ComplexCsr`], every
/// system on whole blocks) is solved by the packed kernel on the blocks; otherwise see
/// `kernel_classes`.
pub fn cg_batched(
    ctx: &GpuContext,
    pipes: &Pipelines,
    a: &Csr,
    b: &[f64],
    x0: &[f64],
    systems: &[SystemDesc],
) -> Result<Solved> {
    cg_batched_with(ctx, pipes, (a, b, x0), systems, Packing::Auto)
}

/// [`cg_batched`] with the batch's [`Packing`] chosen by the caller (the tests and benchmarks
/// compare the two packings on one adapter).
pub fn cg_batched_with(
    ctx: &GpuContext,
    pipes: &Pipelines,
    (a, b, x0): (&Csr, &[f64], &[f64]),
    systems: &[SystemDesc],
    packing: Packing,
) -> Result<Solved> {
    let pack = packing.packs(ctx, systems.len());
    if let Some(c) = pack.then(|| complex_batch(a, systems)).flatten() {
        check_sizes(a, b, x0)?;
        let gpu = GpuCsr::upload_complex(ctx, &c, None)?;
        // One Jacobi weight per block row: the diagonal block's a (both real rows' diagonal).
        let dinv = jacobi((0..c.rows).map(|i| {
            let (s, e) = (c.row_ptr[i] as usize, c.row_ptr[i + 1] as usize);
            (s..e)
                .find(|&k| c.cols[k] as usize == i)
                .map_or(0.0, |k| c.vals[k][0])
        }));
        let max_n = systems.iter().map(|s| s.n / 2).max().unwrap_or(0);
        let per_iter = packed_steps(gpu.max_row_len, max_n);
        let halves: Vec<SystemDesc> = systems
            .iter()
            .map(|s| SystemDesc {
                row0: s.row0 / 2,
                n: s.n / 2,
                wide: PACKED,
                ..*s
            })
            .collect();
        let classes = [(
            PACKED,
            &*pipes.cg_packed_complex,
            iters_per_dispatch(per_iter),
        )];
        let solved = run(ctx, &gpu, &dinv, a.rows, b, x0, &halves, &classes, None)?;
        return Ok(Solved {
            complex: true,
            ..solved
        });
    }
    check_sizes(a, b, x0)?;
    let row_len = a.max_row_len() as u32;
    let ranges: Vec<(usize, usize)> = systems
        .iter()
        .map(|s| (s.row0 as usize, s.n as usize))
        .collect();
    // Systems the packed kernel takes stay there (Jacobi); the rest of at least AMG_MIN_ROWS rows
    // get a V-cycle when one iteration of it fits the loop limit.
    let wants = |k: usize| {
        pipes.cg_amg.is_some()
            && systems[k].wide != JACOBI_ONLY
            && !(pack && packed_steps(row_len, systems[k].n) <= LOOP_BUDGET)
    };
    let hs = gpu_amg::hierarchies(a, &ranges, wants);
    // On complex blocks the V-cycle kernel reads half the loads and systems twice as large fit
    // the loop limit, but every system of its batch must have a hierarchy: a batch that mixes
    // the two kinds is solved as two.
    let blocks = hs.iter().any(Option::is_some)
        && systems.iter().all(|s| s.row0 % 2 + s.n % 2 == 0)
        && ComplexCsr::from_real(a).is_some();
    let fits: Vec<bool> = hs
        .iter()
        .map(|h| blocks && all_fit(std::slice::from_ref(h), WG, HARD_LOOP_LIMIT, 2))
        .collect();
    if fits.iter().any(|&f| f) && !fits.iter().all(|&f| f) {
        let split = |group: bool| (0..systems.len()).filter(|&k| fits[k] == group).collect();
        let groups = [(split(true), true), (split(false), false)];
        return solve_apart(ctx, pipes, (a, b, x0), systems, (hs, packing), &groups);
    }
    multigrid(ctx, pipes, (a, b, x0), systems, (hs, packing), blocks)
}

/// Solves each group of systems as a batch of its own: `(systems, true)` with their hierarchies
/// `hs` on complex blocks, `(systems, false)` by Jacobi (packed as `packing` says); puts the
/// results back in order. Used for
/// the systems whose V-cycle fits on complex blocks against the rest, and for the large LSCM
/// systems of a batch, each alone so that it is spread over workgroups ([`gpu_wide`]).
fn solve_apart(
    ctx: &GpuContext,
    pipes: &Pipelines,
    (a, b, x0): (&Csr, &[f64], &[f64]),
    systems: &[SystemDesc],
    (mut hs, packing): (Vec<Option<Hierarchy>>, Packing),
    groups: &[(Vec<usize>, bool)],
) -> Result<Solved> {
    let mut x = f32s(x0);
    let mut reports = vec![None; systems.len()];
    let mut total = Solved {
        x: Vec::new(),
        reports: Vec::new(),
        dispatches: 0,
        submits: 0,
        packed: 0,
        complex: false,
        multigrid: 0,
        spread: 0,
    };
    for (idx, group) in groups.iter().filter(|g| !g.0.is_empty()) {
        let group = *group;
        let mats: Vec<Csr> = idx
            .iter()
            .map(|&k| a.sub_block(systems[k].row0 as usize, systems[k].n as usize))
            .collect();
        let (sub, starts) = Csr::block_diagonal(&mats.iter().collect::<Vec<_>>());
        let rows = |k: usize| systems[k].row0 as usize..(systems[k].row0 + systems[k].n) as usize;
        let sb: Vec<f64> = idx.iter().flat_map(|&k| b[rows(k)].to_vec()).collect();
        let sx: Vec<f64> = idx.iter().flat_map(|&k| x0[rows(k)].to_vec()).collect();
        let descs: Vec<SystemDesc> = idx
            .iter()
            .zip(&starts)
            .map(|(&k, &r0)| {
                let d = SystemDesc {
                    row0: r0 as u32,
                    ..systems[k]
                };
                if group {
                    d
                } else {
                    d.jacobi_only()
                }
            })
            .collect();
        let out = if group {
            let sub_hs = idx.iter().map(|&k| hs[k].take()).collect();
            multigrid(
                ctx,
                pipes,
                (&sub, &sb, &sx),
                &descs,
                (sub_hs, packing),
                true,
            )?
        } else {
            cg_batched_with(ctx, pipes, (&sub, &sb, &sx), &descs, packing)?
        };
        for ((&k, &r0), rep) in idx.iter().zip(&starts).zip(&out.reports) {
            x[rows(k)].copy_from_slice(&out.x[r0..r0 + systems[k].n as usize]);
            reports[k] = Some(*rep);
        }
        total.dispatches += out.dispatches;
        total.submits += out.submits;
        total.packed += out.packed;
        total.multigrid += out.multigrid;
        total.spread += out.spread;
        total.complex |= out.complex;
    }
    Ok(Solved {
        x,
        reports: reports
            .into_iter()
            .map(|r| r.expect("every system solved"))
            .collect(),
        ..total
    })
}

/// The batch's solve once its hierarchies `hs` are known (`None`: Jacobi), on complex blocks
/// when `blocks` and every system has one that fits there; the Jacobi systems packed as
/// `packing` says.
fn multigrid(
    ctx: &GpuContext,
    pipes: &Pipelines,
    (a, b, x0): (&Csr, &[f64], &[f64]),
    systems: &[SystemDesc],
    (hs, packing): (Vec<Option<Hierarchy>>, Packing),
    blocks: bool,
) -> Result<Solved> {
    let pack = packing.packs(ctx, systems.len());
    let row_len = a.max_row_len() as u32;
    let dinv = jacobi(a.diagonal().into_iter());
    let ranges: Vec<(usize, usize)> = systems
        .iter()
        .map(|s| (s.row0 as usize, s.n as usize))
        .collect();
    let on_blocks = blocks && all_fit(&hs, WG, HARD_LOOP_LIMIT, 2);
    let lone_class = systems.first().map_or(0, |s| s.wide);
    // Large LSCM systems among others: each alone, spread over workgroups (a lone one is spread
    // below); the rest as one batch.
    let large: Vec<usize> = (0..systems.len())
        .filter(|&k| {
            hs[k].is_some()
                && systems[k].n as usize >= 2 * gpu_wide::wide_min_rows(ctx)
                && systems[k].wide != ONE_WORKGROUP
        })
        .collect();
    if systems.len() > 1 && on_blocks && pipes.cg_wide_complex.is_some() && !large.is_empty() {
        let rest = (0..systems.len()).filter(|k| !large.contains(k)).collect();
        let mut groups: Vec<(Vec<usize>, bool)> = large.iter().map(|&k| (vec![k], true)).collect();
        groups.push((rest, true));
        return solve_apart(ctx, pipes, (a, b, x0), systems, (hs, packing), &groups);
    }
    let unit = if on_blocks { 2 } else { 1 };
    let limits = (WG, HARD_LOOP_LIMIT, unit);
    let Some(mg) = AmgBatch::build(a, &ranges, hs, limits, dinv.clone()) else {
        let gpu = GpuCsr::upload(ctx, a)?;
        let (systems, classes) = kernel_classes(pipes, (row_len, pack), systems, None)?;
        return run(ctx, &gpu, &dinv, a.rows, b, x0, &systems, &classes, None);
    };
    let steps = mg.systems.iter().flatten().map(|h| h.steps).max();
    if let Some(c) = on_blocks.then(|| mg.complex()).flatten() {
        return multigrid_complex(ctx, pipes, &c, (a.rows, b, x0), systems, steps, lone_class);
    }
    // On the real form (also when a complex layout did not hold after all: then a system whose
    // real iteration passes the loop limit keeps Jacobi).
    let fits_real = |h: &&gpu_amg::AmgSystem| h.steps_real <= HARD_LOOP_LIMIT;
    let systems: Vec<SystemDesc> = systems
        .iter()
        .zip(&mg.systems)
        .map(|(s, h)| match h.as_ref().filter(fits_real) {
            Some(h) => SystemDesc {
                wide: MULTIGRID,
                amg: [h.lvl0, h.nlev, h.cinv0],
                ..*s
            },
            None => *s,
        })
        .collect();
    let steps = mg
        .systems
        .iter()
        .flatten()
        .filter(fits_real)
        .map(|h| h.steps_real)
        .max();
    // A system left to Jacobi gets Jacobi's weights back.
    let mut weights = mg.weights.clone();
    for (s, h) in systems.iter().zip(&mg.systems) {
        if h.is_some() && s.wide != MULTIGRID {
            let r = s.row0 as usize..(s.row0 + s.n) as usize;
            weights[r.clone()].copy_from_slice(&dinv[r]);
        }
    }
    let gpu = GpuCsr::upload(ctx, &mg.a)?;
    let amg = steps.map(|st| (st, amg_kernel(pipes.cg_amg.as_deref())));
    let (systems, classes) = kernel_classes(pipes, (row_len, pack), &systems, amg)?;
    let vals = f32s(&mg.pr.vals);
    let bufs = ctx.scoped("conjugate gradient", || {
        MultigridBuffers::upload(
            ctx,
            (&mg.pr.row_ptr, &entries(&mg.pr.cols, &vals, None)),
            &mg.levels,
            &mg.cinv,
            mg.total,
            4,
        )
    })?;
    run(
        ctx,
        &gpu,
        &weights,
        a.rows,
        b,
        x0,
        &systems,
        &classes,
        Some(&bufs),
    )
}

/// [`multigrid`] on complex 2 × 2 blocks (`c`, the hierarchies' layout; `steps`, the loop steps of
/// the largest V-cycle iteration): a batch of one large system spread over workgroups
/// ([`gpu_wide`]) unless its class (`lone_class`) keeps it in one, else `cg_amg`.
fn multigrid_complex(
    ctx: &GpuContext,
    pipes: &Pipelines,
    c: &gpu_amg::ComplexLayout,
    (rows, b, x0): (usize, &[f64], &[f64]),
    systems: &[SystemDesc],
    steps: Option<usize>,
    lone_class: u32,
) -> Result<Solved> {
    let systems: Vec<SystemDesc> = systems
        .iter()
        .zip(&c.systems)
        .map(|(s, &amg)| SystemDesc {
            row0: s.row0 / 2,
            n: s.n / 2,
            wide: MULTIGRID,
            amg,
            ..*s
        })
        .collect();
    let gpu = GpuCsr::upload_complex(ctx, &c.a, Some(&c.weights))?;
    let vals: Vec<f32> = c.pr.vals.iter().flatten().map(|&v| v as f32).collect();
    let cinv: Vec<f32> = c.cinv.iter().flatten().copied().collect();
    let bufs = ctx.scoped("conjugate gradient", || {
        MultigridBuffers::upload(
            ctx,
            (&c.pr.row_ptr, &entries(&c.pr.cols, &vals, Some(&c.weights))),
            &c.levels,
            &cinv,
            c.pr.rows / 2,
            8,
        )
    })?;
    let spread = match (pipes.cg_wide_complex.as_ref(), &systems[..]) {
        (Some([k, plain]), [one]) => (one.n as usize >= gpu_wide::wide_min_rows(ctx)
            && lone_class != ONE_WORKGROUP)
            .then_some((&**k, &**plain)),
        _ => None,
    };
    if let Some(kernels) = spread {
        let levels = &c.levels;
        return run_wide(
            ctx,
            kernels,
            &gpu,
            &c.weights,
            (b, x0),
            systems[0],
            levels,
            &bufs,
        );
    }
    let classes = [(
        MULTIGRID,
        amg_kernel(pipes.cg_amg_complex.as_deref()),
        iters_per_dispatch(steps.unwrap_or(0)),
    )];
    let solved = run(
        ctx,
        &gpu,
        &c.weights,
        rows,
        b,
        x0,
        &systems,
        &classes,
        Some(&bufs),
    )?;
    Ok(Solved {
        complex: true,
        ..solved
    })
}

/// Solves the one system `sys` (on complex blocks, with its hierarchy in `bufs`) spread over
/// many workgroups (`cg_wide`, [`gpu_wide`]).
#[allow(clippy::too_many_arguments)]
fn run_wide(
    ctx: &GpuContext,
    kernels: (&Kernel, &Kernel),
    gpu: &GpuCsr,
    weights: &[f32],
    (b, x0): (&[f64], &[f64]),
    sys: SystemDesc,
    levels: &[[u32; 2]],
    bufs: &MultigridBuffers,
) -> Result<Solved> {
    let rows = b.len();
    let (bb, db, xb) = ctx.scoped("conjugate gradient", || {
        let init = |label: &str, d: &[f32]| {
            ctx.storage_init(label, bytemuck::cast_slice(d), wgpu::BufferUsages::COPY_SRC)
        };
        (
            init("cg.b", &f32s(b)),
            init("cg.dinv", weights),
            init("cg.x", &f32s(x0)),
        )
    })?;
    let [lvl0, nlev, _] = sys.amg;
    let inputs = gpu_wide::WideInputs {
        system: bytemuck::bytes_of(&sys),
        rows: (sys.row0, sys.n),
        max_iter: sys.max_iter,
        matrix: [&gpu.spans, &gpu.ents],
        b: &bb,
        dinv: &db,
        x: &xb,
        vector_bytes: rows as u64 * 4,
        hierarchy: [
            &bufs.pr_spans,
            &bufs.pr_ents,
            &bufs.levels,
            &bufs.cinv,
            &bufs.vectors,
        ],
        total: bufs.total,
        levels: levels[lvl0 as usize..(lvl0 + nlev) as usize].to_vec(),
    };
    let solved = gpu_wide::solve(ctx, kernels, &inputs)?;
    let xbytes = ctx.read_buffer(
        &xb,
        rows as u64 * 4,
        "conjugate-gradient solution read-back",
    )?;
    Ok(Solved {
        x: bytemuck::cast_slice(&xbytes[..rows * 4]).to_vec(),
        reports: vec![solved.report],
        dispatches: solved.dispatches,
        submits: solved.submits,
        packed: 0,
        complex: true,
        multigrid: 1,
        spread: 1,
    })
}

/// A multigrid kernel: present whenever a hierarchy was built (none are without it, see `wants`
/// in [`cg_batched`]).
fn amg_kernel(k: Option<&Kernel>) -> &Kernel {
    k.expect("hierarchies are built only where the device has the multigrid kernel")
}

/// The hierarchy's buffers (bindings 12-17 of `cg_amg.wgsl`, less 14).
struct MultigridBuffers {
    pr_spans: wgpu::Buffer,
    pr_ents: wgpu::Buffer,
    levels: wgpu::Buffer,
    cinv: wgpu::Buffer,
    vectors: wgpu::Buffer,
    total: u32,
}

impl MultigridBuffers {
    /// Uploads the prolongators and restrictions (`pr`: row offsets and [`entries`]), the
    /// levels, the coarsest inverses and room for three vectors of `total` kernel rows of
    /// `row_bytes` each.
    fn upload(
        ctx: &GpuContext,
        pr: (&[u32], &[u32]),
        levels: &[[u32; 2]],
        cinv: &[f32],
        total: usize,
        row_bytes: u64,
    ) -> Self {
        let init =
            |label: &str, bytes: &[u8]| ctx.storage_init(label, bytes, wgpu::BufferUsages::empty());
        Self {
            pr_spans: init("cg.pr_spans", bytemuck::cast_slice(&spans(pr.0))),
            pr_ents: init("cg.pr_entries", bytemuck::cast_slice(pr.1)),
            levels: init("cg.levels", bytemuck::cast_slice(levels)),
            cinv: init("cg.cinv", bytemuck::cast_slice(cinv)),
            vectors: ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("cg.multigrid_vectors"),
                size: (3 * total as u64 * row_bytes).max(16),
                usage: wgpu::BufferUsages::STORAGE,
                mapped_at_creation: false,
            }),
            total: total as u32,
        }
    }
}

/// The blocks of `a` for a batch that packs, when each system starts and ends on a block, `a` has the complex block structure and one packed iteration of the largest fits
/// the loop budget.
fn complex_batch(a: &Csr, systems: &[SystemDesc]) -> Option<ComplexCsr> {
    if systems.iter().any(|s| s.row0 % 2 + s.n % 2 != 0) {
        return None;
    }
    let c = ComplexCsr::from_real(a)?;
    let max_n = systems.iter().map(|s| s.n / 2).max().unwrap_or(0);
    (packed_steps(c.max_row_len() as u32, max_n) <= LOOP_BUDGET).then_some(c)
}

/// Loop steps of one packed iteration of a system of `n` rows of up to `row_len` entries: every
/// row is walked by the product, the updates and p, and on replacement iterations by the product
/// again.
fn packed_steps(row_len: u32, n: u32) -> usize {
    n as usize * (2 * row_len as usize + 4) + 16
}

/// Iterations per dispatch for a kernel class whose iteration takes `per_iter` loop steps.
fn iters_per_dispatch(per_iter: usize) -> u32 {
    (LOOP_BUDGET / per_iter.max(1)).clamp(1, 256) as u32
}

/// 1 / d for each diagonal entry (1 where d is 0 or not finite), in f32.
fn jacobi(diagonal: impl Iterator<Item = f64>) -> Vec<f32> {
    diagonal
        .map(|d| {
            if d != 0.0 && d.is_finite() {
                (1.0 / d) as f32
            } else {
                1.0
            }
        })
        .collect()
}

fn check_sizes(a: &Csr, b: &[f64], x0: &[f64]) -> Result<()> {
    if b.len() != a.rows || x0.len() != a.rows {
        return Err(Error::Gpu {
            stage: "conjugate gradient".into(),
            detail: format!("{} rows but b has {} and x0 {}", a.rows, b.len(), x0.len()),
        });
    }
    Ok(())
}

/// Runs the CG of `systems` (their kernel classes set) on the uploaded matrix: state and vector
/// buffers (`rows` f32 each), one bind group per class and 65535 systems, the submissions, the
/// read-back of x.
#[allow(clippy::too_many_arguments, reason = "the solve's inputs")]
fn run(
    ctx: &GpuContext,
    gpu: &GpuCsr,
    dinv: &[f32],
    rows: usize,
    b: &[f64],
    x0: &[f64],
    systems: &[SystemDesc],
    classes: &[(u32, &Kernel, u32)],
    mg: Option<&MultigridBuffers>,
) -> Result<Solved> {
    let dev = &ctx.device;
    if systems.is_empty() {
        return Ok(Solved {
            x: f32s(x0),
            reports: Vec::new(),
            dispatches: 0,
            submits: 0,
            packed: 0,
            complex: false,
            multigrid: 0,
            spread: 0,
        });
    }
    let max_iter = systems.iter().map(|s| s.max_iter).max().unwrap_or(1);
    let state_size = systems.len() as u64 * 32;
    let vec_buf = |label: &str, data: Option<&[f32]>| -> wgpu::Buffer {
        match data {
            Some(d) => {
                ctx.storage_init(label, bytemuck::cast_slice(d), wgpu::BufferUsages::COPY_SRC)
            }
            None => dev.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: (rows as u64 * 4).max(16),
                usage: wgpu::BufferUsages::STORAGE,
                mapped_at_creation: false,
            }),
        }
    };
    let (xb, state, bgs, keep) = ctx.scoped("conjugate gradient", || {
        let sys = ctx.storage_init(
            "cg.systems",
            bytemuck::cast_slice(systems),
            wgpu::BufferUsages::empty(),
        );
        let bb = vec_buf("cg.b", Some(&f32s(b)));
        let db = vec_buf("cg.dinv", Some(dinv));
        let xb = vec_buf("cg.x", Some(&f32s(x0)));
        let (rb, pb, qb) = (
            vec_buf("cg.r", None),
            vec_buf("cg.p", None),
            vec_buf("cg.ap", None),
        );
        let state = ctx.storage_init(
            "cg.state",
            bytemuck::cast_slice(&vec![CgState::default(); systems.len()]),
            wgpu::BufferUsages::COPY_SRC,
        );
        let mut rounds = Vec::new();
        // Per class: (kernel, iterations per dispatch, [(bind group, workgroups)]).
        let mut bgs = Vec::new();
        for &(wide, kernel, iters) in classes {
            let mut groups = Vec::new();
            for base in (0..systems.len()).step_by(65535) {
                let count = (systems.len() - base).min(65535) as u32;
                let round = ctx.uniform_init(
                    "cg.round",
                    bytemuck::bytes_of(&CgRound {
                        iters,
                        base: base as u32,
                        count,
                        total: mg.map_or(rows as u32, |m| m.total),
                    }),
                );
                let mut entries = vec![
                    (0, round.as_entire_binding()),
                    (1, sys.as_entire_binding()),
                    (2, gpu.spans.as_entire_binding()),
                    (3, gpu.ents.as_entire_binding()),
                    (5, bb.as_entire_binding()),
                    (6, db.as_entire_binding()),
                    (7, xb.as_entire_binding()),
                    (8, rb.as_entire_binding()),
                    (9, pb.as_entire_binding()),
                    (10, qb.as_entire_binding()),
                    (11, state.as_entire_binding()),
                ];
                if let (MULTIGRID, Some(m)) = (wide, mg) {
                    entries.extend([
                        (12, m.pr_spans.as_entire_binding()),
                        (13, m.pr_ents.as_entire_binding()),
                        (15, m.levels.as_entire_binding()),
                        (16, m.cinv.as_entire_binding()),
                        (17, m.vectors.as_entire_binding()),
                    ]);
                }
                groups.push((
                    kernel.bind(dev, "cg", &entries),
                    if wide == PACKED {
                        count.div_ceil(PACK_WG)
                    } else {
                        count
                    },
                ));
                rounds.push(round);
            }
            bgs.push((kernel, iters, groups));
        }
        (xb, state, bgs, (sys, bb, db, rb, pb, qb, rounds))
    })?;
    let (states, dispatches, submits) = iterate(ctx, &bgs, max_iter, &state, state_size)?;
    let xbytes = ctx.read_buffer(
        &xb,
        rows as u64 * 4,
        "conjugate-gradient solution read-back",
    )?;
    drop(keep);
    let reports = states
        .iter()
        .zip(systems)
        .map(|(s, d)| CgReport {
            preconditioner: if d.wide == MULTIGRID {
                PreconditionerKind::Amg
            } else {
                PreconditionerKind::Jacobi
            },
            status: match s.status {
                2 => CgStatus::Converged,
                3 => CgStatus::NotConverged,
                _ => CgStatus::Breakdown,
            },
            iterations: s.iters,
            residual: s.rel_residual as f64,
        })
        .collect();
    Ok(Solved {
        x: bytemuck::cast_slice(&xbytes[..rows * 4]).to_vec(),
        reports,
        dispatches,
        submits,
        packed: systems.iter().filter(|s| s.wide == PACKED).count() as u32,
        complex: false,
        multigrid: systems.iter().filter(|s| s.wide == MULTIGRID).count() as u32,
        spread: 0,
    })
}

/// Per system, its kernel; per kernel class (class, kernel, iterations per dispatch).
///
/// A batch that packs (`pack`: [`Packing::packs`]) puts every system that one invocation can
/// iterate within the loop budget into the packed kernel (one system per invocation; class
/// [`PACKED`]); the rest, and every system of a smaller batch, get the 64-wide workgroup kernel
/// when one iteration of it stays well under the loop budget with 64 invocations, else the
/// 256-wide one. Within each kernel a system's arithmetic does not depend on the rest of its
/// batch; whether it is packed does (a lone chart would leave all lanes but one idle in the packed
/// kernel, so it keeps a workgroup). The two orders of summation give results that agree to the
/// solve's tolerance (tests/linalg.rs). Systems already marked [`MULTIGRID`] keep that class
/// (`amg`: the loop steps of their largest iteration and `cg_amg`); `row_len` is the longest row
/// of the batch's own matrix.
#[allow(clippy::type_complexity)]
fn kernel_classes<'p>(
    pipes: &'p Pipelines,
    (row_len, pack): (u32, bool),
    systems: &[SystemDesc],
    amg: Option<(usize, &'p Kernel)>,
) -> Result<(Vec<SystemDesc>, Vec<(u32, &'p Kernel, u32)>)> {
    // Iterations per dispatch per class: each
    // iteration an invocation walks its rows (ceil(n / WG)) a few times, each row's entries, plus
    // the reductions' fixed steps.
    let max_row_len = row_len;
    let row_len = 3 * row_len as usize + 8;
    let cost = |n: u32, wg: u32| (n as usize).div_ceil(wg as usize).max(1) * row_len + 60;
    let packed_cost = |n: u32| packed_steps(max_row_len, n);
    let narrow_wg = crate::gpu::shaders::LINALG_WG_NARROW;
    let systems: Vec<SystemDesc> = systems
        .iter()
        .map(|s| SystemDesc {
            wide: if s.wide == MULTIGRID {
                MULTIGRID
            } else if pack && packed_cost(s.n) <= LOOP_BUDGET {
                PACKED
            } else {
                u32::from(cost(s.n, narrow_wg) > LOOP_BUDGET / 8)
            },
            ..*s
        })
        .collect();
    let mut classes = Vec::new();
    for (wide, kernel) in [
        (0u32, Some(&*pipes.cg_batched_narrow)),
        (1u32, Some(&*pipes.cg_batched)),
        (PACKED, Some(&*pipes.cg_packed)),
        (MULTIGRID, amg.map(|a| a.1).or(pipes.cg_amg.as_deref())),
    ] {
        let Some(max_n) = systems.iter().filter(|s| s.wide == wide).map(|s| s.n).max() else {
            continue;
        };
        let kernel = amg_kernel(kernel);
        let per_iter = match wide {
            0 => cost(max_n, narrow_wg),
            1 => cost(max_n, WG as u32),
            MULTIGRID => amg.map_or(0, |a| a.0),
            _ => packed_cost(max_n),
        };
        if per_iter > HARD_LOOP_LIMIT {
            return Err(Error::Gpu {
                stage: "conjugate gradient".into(),
                detail: format!(
                    "a system of {max_n} unknowns (rows up to {} entries) is too large for one workgroup: one iteration would loop about {per_iter} times per invocation, past the {HARD_LOOP_LIMIT} a software driver runs reliably; split it (a smaller decal) or solve it on the CPU",
                    max_row_len
                ),
            });
        }
        classes.push((wide, kernel, iters_per_dispatch(per_iter)));
    }
    Ok((systems, classes))
}

/// Submissions of fused iterations until every system has a final status (converged, budget spent
/// or breakdown), reading back only the 32-byte status per system between them. Returns the
/// statuses, dispatches and submissions.
#[allow(clippy::type_complexity)]
fn iterate(
    ctx: &GpuContext,
    bgs: &[(&Kernel, u32, Vec<(wgpu::BindGroup, u32)>)],
    max_iter: u32,
    state: &wgpu::Buffer,
    state_size: u64,
) -> Result<(Vec<CgState>, u32, u32)> {
    let dev = &ctx.device;
    // The first submission covers FIRST_SUBMIT_ITERS iterations, each next one twice as many up to
    // ITERS_PER_SUBMIT: warm-started charts often converge in a few iterations, and a submission's
    // dispatches cost their fixed price even when every system has finished.
    let mut span = FIRST_SUBMIT_ITERS;
    let (mut dispatches, mut submits) = (0u32, 0u32);
    let states = loop {
        let target = span.min(max_iter.saturating_add(1));
        let per_submit = |iters: u32| target.div_ceil(iters).max(1);
        span = (span * 2).min(ITERS_PER_SUBMIT);
        ctx.scoped("conjugate gradient", || {
            let mut enc =
                dev.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("cg") });
            {
                let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("cg.iterate"),
                    timestamp_writes: None,
                });
                for (kernel, iters, groups) in bgs {
                    pass.set_pipeline(&kernel.pipeline);
                    for _ in 0..per_submit(*iters) {
                        for (bg, count) in groups {
                            pass.set_bind_group(0, bg, &[]);
                            pass.dispatch_workgroups(*count, 1, 1);
                        }
                    }
                }
            }
            ctx.queue.submit([enc.finish()]);
        })?;
        dispatches += bgs
            .iter()
            .map(|(_, iters, groups)| per_submit(*iters) * groups.len() as u32)
            .sum::<u32>();
        submits += 1;
        let bytes = ctx.read_buffer(state, state_size, "conjugate-gradient status read-back")?;
        let st: Vec<CgState> = bytemuck::cast_slice(&bytes).to_vec();
        if st.iter().all(|s| s.status >= 2) {
            break st;
        }
    };
    Ok((states, dispatches, submits))
}
