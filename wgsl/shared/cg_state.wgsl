// SPDX-License-Identifier: MIT OR Apache-2.0
// What the two conjugate-gradient kernels (cg_batched.wgsl: a workgroup per system; cg_packed.wgsl:
// an invocation per system) share: the per-dispatch round, the per-system state kept between
// dispatches, and the status codes (read cg_batched.wgsl's header).

// Iterations between recomputations of the true residual b - A x.
const REPLACE: u32 = 50u;
const ST_INIT: u32 = 0u;
const ST_RUN: u32 = 1u;
const ST_DONE: u32 = 2u;
const ST_BUDGET: u32 = 3u;
const ST_BREAK: u32 = 4u;

// Keep in sync with `CgRound` in src/solve/gpu.rs.
struct Round {
    iters: u32,
    // First system of this dispatch (dispatches cover at most 65535 systems each).
    base: u32,
    // Systems in this dispatch (the packed kernel's bound; the workgroup kernel has one group each).
    count: u32,
    // Rows of cg_amg.wgsl's index space (the batch's rows and every coarse level's).
    total: u32,
}

// Keep in sync with `CgState` in src/solve/gpu.rs.
struct State {
    status: u32,
    iters: u32,
    pad0: u32,
    pad1: u32,
    rz: f32,
    bnorm: f32,
    rel_residual: f32,
    // max(|b|, |(|A| |x|)|) at the last true residual: the residual's reference.
    scale: f32,
}

fn finite(v: f32) -> bool {
    return abs(v) <= 3.0e38;
}
