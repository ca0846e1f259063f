// SPDX-License-Identifier: MIT OR Apache-2.0
//! The pelting dynamics on the GPU: every piece's net in one set of buffers, one invocation per
//! vertex and one dispatch per step (`wgsl/pelt/pelt_step.wgsl`), a steadiness check per piece at
//! the end of every interval of [`SystemCfg::check_every`] steps (`wgsl/pelt/pelt_check.wgsl`,
//! exactly as the CPU twin checks), several intervals per submission, and one small read-back of
//! the pieces' states per submission.
//!
//! Why one dispatch per step: a loop of steps inside one workgroup needs a barrier per step, and
//! llvmpipe runs such a loop an invocation batch at a time: 17 ms a step on Spot's 3,200 vertices,
//! on one core, with the first kernel written for it (a workgroup per piece looping over steps; not
//! kept, so no command here reproduces it) against about 0.6 ms now (`decalbake bench --unwrap`:
//! `stages_ms.relax` over the steps run). A dispatch costs about 80 µs (`../shared/notes`).

use super::relax::{energy, Net, Relaxed, SystemCfg};
use crate::error::Result;
use crate::gpu::pipelines::Pipelines;
use crate::gpu::GpuContext;

/// Keep in sync with `Step` in wgsl/pelt/pelt_step.wgsl and `Check` in pelt_check.wgsl.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Uniform {
    a: u32,
    b: f32,
    pad: [u32; 2],
}

/// Keep in sync with `Piece` in wgsl/shared/pelt.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct PieceState {
    v0: u32,
    n: u32,
    damping: f32,
    steps: u32,
    steady: u32,
    ke: f32,
    pad: [u32; 2],
}

/// Check intervals per submission (the first; each next one doubles, up to [`MAX_INTERVALS`]).
const FIRST_INTERVALS: u32 = 2;
/// At most this many intervals per submission: steps submitted after every piece is steady are
/// wasted, and a submission costs about 0.3 ms, a few steps' worth.
const MAX_INTERVALS: u32 = 4;

/// Relaxes every net on the GPU; positions come back in f64 for the caller's projection.
pub fn relax_gpu(
    ctx: &GpuContext,
    pipes: &Pipelines,
    nets: &[Net],
    cfg: &SystemCfg,
) -> Result<Vec<Relaxed>> {
    if nets.is_empty() {
        return Ok(Vec::new());
    }
    let dev = &ctx.device;
    let Packed {
        offsets,
        other,
        spring,
        anchor,
        inv_mass,
        start,
        piece_of,
        mut states,
    } = pack(nets);
    let total = start.len();
    let mut x = start.clone();
    x.extend_from_slice(&start);
    // Intervals of an even number of steps end on the first half of `x`.
    let every = cfg.interval();
    let (state_buf, xb, keep) = ctx.scoped("pelting dynamics", || {
        let usage = wgpu::BufferUsages::empty();
        let st = ctx.storage_init(
            "pelt.pieces",
            bytemuck::cast_slice(&states),
            wgpu::BufferUsages::COPY_SRC,
        );
        let pb = ctx.storage_init(
            "pelt.piece_of",
            bytemuck::cast_slice(&pad(&piece_of)),
            usage,
        );
        let ob = ctx.storage_init("pelt.offsets", bytemuck::cast_slice(&offsets), usage);
        let nb = ctx.storage_init("pelt.other", bytemuck::cast_slice(&pad(&other)), usage);
        let sb = ctx.storage_init("pelt.spring", bytemuck::cast_slice(&pad(&spring)), usage);
        let ab = ctx.storage_init("pelt.anchor", bytemuck::cast_slice(&anchor), usage);
        let mb = ctx.storage_init("pelt.inv_mass", bytemuck::cast_slice(&inv_mass), usage);
        let xb = ctx.storage_init(
            "pelt.x",
            bytemuck::cast_slice(&x),
            wgpu::BufferUsages::COPY_SRC,
        );
        let vb = ctx.storage_init(
            "pelt.v",
            bytemuck::cast_slice(&vec![[0f32; 4]; total]),
            usage,
        );
        let uniform = |a: u32, b: f32| {
            ctx.uniform_init(
                "pelt.uniform",
                bytemuck::bytes_of(&Uniform { a, b, pad: [0; 2] }),
            )
        };
        let steps: Vec<(wgpu::Buffer, wgpu::BindGroup)> = (0..2)
            .map(|parity| {
                let u = uniform(parity, 0.0);
                let bg = pipes.pelt_step.bind(
                    dev,
                    "pelt_step",
                    &[
                        (0, u.as_entire_binding()),
                        (1, st.as_entire_binding()),
                        (2, pb.as_entire_binding()),
                        (3, ob.as_entire_binding()),
                        (4, nb.as_entire_binding()),
                        (5, sb.as_entire_binding()),
                        (6, ab.as_entire_binding()),
                        (7, mb.as_entire_binding()),
                        (8, xb.as_entire_binding()),
                        (9, vb.as_entire_binding()),
                    ],
                );
                (u, bg)
            })
            .collect();
        let cu = uniform(every, cfg.tol2 as f32);
        let check = pipes.pelt_check.bind(
            dev,
            "pelt_check",
            &[
                (0, cu.as_entire_binding()),
                (1, st.as_entire_binding()),
                (2, vb.as_entire_binding()),
            ],
        );
        (st, xb, (steps, (cu, check), pb, ob, nb, sb, ab, mb, vb))
    })?;
    let groups = (total as u32).div_ceil(64);
    let (mut done_steps, mut intervals) = (0u32, FIRST_INTERVALS);
    let state_size = (states.len() * std::mem::size_of::<PieceState>()) as u64;
    while done_steps + every <= cfg.max_steps {
        let mut enc = dev.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            let mut planned = 0;
            while planned < intervals && done_steps + every <= cfg.max_steps {
                pass.set_pipeline(&pipes.pelt_step.pipeline);
                for s in 0..every {
                    pass.set_bind_group(0, &keep.0[(s % 2) as usize].1, &[]);
                    pass.dispatch_workgroups(groups, 1, 1);
                }
                pass.set_pipeline(&pipes.pelt_check.pipeline);
                pass.set_bind_group(0, &keep.1 .1, &[]);
                pass.dispatch_workgroups(nets.len() as u32, 1, 1);
                done_steps += every;
                planned += 1;
            }
        }
        ctx.queue.submit([enc.finish()]);
        let bytes = ctx.read_buffer(&state_buf, state_size, "pelting dynamics status read-back")?;
        states = bytemuck::cast_slice(&bytes).to_vec();
        if states.iter().all(|s| s.steady != 0) {
            break;
        }
        intervals = (intervals * 2).min(MAX_INTERVALS);
    }
    let bytes = ctx.read_buffer(
        &xb,
        (total * 16) as u64,
        "pelting dynamics positions read-back",
    )?;
    drop(keep);
    Ok(results(nets, &states, bytemuck::cast_slice(&bytes)))
}

/// Every net's arrays end to end (vertex and spring ids offset), with each piece's state.
struct Packed {
    offsets: Vec<u32>,
    other: Vec<u32>,
    spring: Vec<[f32; 2]>,
    anchor: Vec<[f32; 4]>,
    inv_mass: Vec<f32>,
    start: Vec<[f32; 4]>,
    piece_of: Vec<u32>,
    states: Vec<PieceState>,
}

fn pack(nets: &[Net]) -> Packed {
    let mut p = Packed {
        offsets: vec![0],
        other: Vec::new(),
        spring: Vec::new(),
        anchor: Vec::new(),
        inv_mass: Vec::new(),
        start: Vec::new(),
        piece_of: Vec::new(),
        states: Vec::new(),
    };
    for (i, net) in nets.iter().enumerate() {
        let v0 = p.inv_mass.len() as u32;
        let e0 = p.other.len() as u32;
        p.offsets.extend(net.offsets[1..].iter().map(|o| o + e0));
        p.other.extend(net.other.iter().map(|j| j + v0));
        p.spring.extend_from_slice(&net.spring);
        p.anchor.extend_from_slice(&net.anchor);
        p.inv_mass.extend_from_slice(&net.inv_mass);
        p.start.extend_from_slice(&net.start);
        p.piece_of.extend(std::iter::repeat_n(i as u32, net.len()));
        p.states.push(PieceState {
            v0,
            n: net.len() as u32,
            damping: net.damping,
            steps: 0,
            steady: 0,
            ke: 0.0,
            pad: [0; 2],
        });
    }
    p
}

/// Each net's final positions (from the first half of `xs`) and energies.
fn results(nets: &[Net], states: &[PieceState], xs: &[[f32; 4]]) -> Vec<Relaxed> {
    let f64s = |p: &[f32; 4]| [p[0] as f64, p[1] as f64, p[2] as f64];
    nets.iter()
        .zip(states)
        .map(|(net, s)| {
            let x: Vec<[f64; 3]> = (0..net.len())
                .map(|i| f64s(&xs[s.v0 as usize + i]))
                .collect();
            let start: Vec<[f64; 3]> = net.start.iter().map(f64s).collect();
            Relaxed {
                energy: [energy(net, &start), energy(net, &x)],
                x,
                steps: s.steps,
                iterations: 0,
                steady: s.steady != 0,
                rest_scale: 1.0,
            }
        })
        .collect()
}

/// A storage buffer must not be empty.
fn pad<T: Copy + Default>(v: &[T]) -> Vec<T> {
    if v.is_empty() {
        vec![T::default()]
    } else {
        v.to_vec()
    }
}
