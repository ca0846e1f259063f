// SPDX-License-Identifier: MIT OR Apache-2.0
// The complex form of cg_packed.wgsl: the unknowns (u, v) of a vertex as one vec2, a 2 × 2 block
// [[a, -b], [b, a]] of the real matrix as one vec2 (a, b). Every operation equals the real form's on
// the same two rows (src/solve/sparse.rs, `ComplexCsr`).

alias V = vec2<f32>;
alias M = vec2<f32>;
// A stored block: its column, a's and b's bits and the smoother's weight of the column's row (0
// outside the multigrid kernels), one 16-byte load (`GpuCsr` and `entries` in src/solve/gpu.rs).
alias E = vec4<u32>;

// The weight of the entry's column: `dinv[ent_col(e)]` without the gather (cg_wide_common.wgsl).
fn ent_w(e: E) -> f32 {
    return bitcast<f32>(e.w);
}

fn ent_col(e: E) -> u32 {
    return e.x;
}

fn ent_val(e: E) -> M {
    return bitcast<vec2<f32>>(e.yz);
}

// [[a, -b], [b, a]] (u, v): the complex product (a + i b)(u + i v).
fn mat_mul(m: M, v: V) -> V {
    return vec2<f32>(m.x * v.x - m.y * v.y, m.y * v.x + m.x * v.y);
}

// The two rows' terms of |A| |x|.
fn mat_abs_mul(m: M, v: V) -> V {
    let a = abs(m);
    let w = abs(v);
    return vec2<f32>(a.x * w.x + a.y * w.y, a.y * w.x + a.x * w.y);
}

// The real inner product over the two rows (the real part of the Hermitian one).
fn vdot(a: V, c: V) -> f32 {
    return a.x * c.x + a.y * c.y;
}
