// SPDX-License-Identifier: MIT OR Apache-2.0
// The real form of cg_packed.wgsl: one f32 unknown per row, one f32 per stored entry.

alias V = f32;
alias M = f32;
// A stored entry: its column and its value's bits, one 8-byte load (`GpuCsr` in src/solve/gpu.rs).
alias E = vec2<u32>;

fn ent_col(e: E) -> u32 {
    return e.x;
}

fn ent_val(e: E) -> M {
    return bitcast<f32>(e.y);
}

// The smoother's weight of the entry's column: no room in a real entry, so gathered from `dinv`
// (declared by every kernel that imports this file; the complex form carries it in the entry).
fn ent_w(e: E) -> f32 {
    return dinv[e.x];
}

// The entry times the unknown.
fn mat_mul(m: M, v: V) -> V {
    return m * v;
}

// |entry| times |unknown|: a row's terms of |A| |x|, the residual's reference.
fn mat_abs_mul(m: M, v: V) -> V {
    return abs(m * v);
}

// The real inner product's term.
fn vdot(a: V, c: V) -> f32 {
    return a * c;
}
