// SPDX-License-Identifier: MIT OR Apache-2.0
// The complex form of cg_packed.wgsl: the unknowns (u, v) of a vertex as one vec2, a 2 × 2 block
// [[a, -b], [b, a]] of the real matrix as one vec2 (a, b). Every operation equals the real form's on
// the same two rows (src/solve/sparse.rs, `ComplexCsr`).

alias V = vec2<f32>;
alias M = vec2<f32>;

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
