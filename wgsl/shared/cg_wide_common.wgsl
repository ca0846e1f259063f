// SPDX-License-Identifier: MIT OR Apache-2.0
// What the two kernels of a spread CG (cg_wide.wgsl: the passes with sums and the status;
// cg_wide_plain.wgsl: the V-cycle's passes without, which need no barrier) share: the pass
// selector, the bindings (cg_amg.wgsl's and the partial sums) and the smoothed row products. Import after
// `linalg`, `cg_state`, `cg_real` (or `cg_complex`) and `cg_rows`.

// Passes. Keep in sync with `pass` in src/solve/gpu_wide.rs.
const INIT_RESIDUAL: u32 = 0u;
const INIT_CHECK: u32 = 1u;
const SPMV: u32 = 2u;
const UPDATE: u32 = 3u;
const TRUE_RESIDUAL: u32 = 5u;
const TRUE_CHECK: u32 = 6u;
const DOWN: u32 = 7u;
const RESTRICT: u32 = 8u;
const COARSE: u32 = 9u;
const PROLONG: u32 = 10u;
const SMOOTH_RESIDUAL: u32 = 11u;
const SMOOTH_UPDATE: u32 = 12u;
const UPDATE_P: u32 = 13u;

// Keep in sync with `WideRound` in src/solve/gpu_wide.rs.
struct Wide {
    phase: u32,
    // The level a V-cycle pass works on (0: the system's own rows).
    level: u32,
    // Rows of the index space (cg_amg's `round.total`).
    total: u32,
    // The system (index into `systems` and `state`).
    sys: u32,
    // Workgroups of the fine-level passes: the partial sums to add.
    parts: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

@group(0) @binding(0) var<storage, read> wide: Wide;
@group(0) @binding(1) var<storage, read> systems: array<System>;
@group(0) @binding(2) var<storage, read> row_ptr: array<u32>;
@group(0) @binding(3) var<storage, read> cols: array<u32>;
@group(0) @binding(4) var<storage, read> vals: array<M>;
@group(0) @binding(5) var<storage, read> b: array<V>;
@group(0) @binding(6) var<storage, read> dinv: array<f32>;
@group(0) @binding(7) var<storage, read_write> x: array<V>;
@group(0) @binding(8) var<storage, read_write> r: array<V>;
@group(0) @binding(9) var<storage, read_write> p: array<V>;
@group(0) @binding(10) var<storage, read_write> ap: array<V>;
@group(0) @binding(11) var<storage, read_write> state: array<State>;
@group(0) @binding(12) var<storage, read> pr_ptr: array<u32>;
@group(0) @binding(13) var<storage, read> pr_cols: array<u32>;
@group(0) @binding(14) var<storage, read> pr_vals: array<M>;
@group(0) @binding(15) var<storage, read> levels: array<vec2<u32>>;
@group(0) @binding(16) var<storage, read> cinv: array<M>;
@group(0) @binding(17) var<storage, read_write> mg: array<V>;
@group(0) @binding(18) var<storage, read_write> partials: array<vec4<f32>>;


// Σ_k A[i, k] W_k B_k: row i of A times the pre-smoothed X = W B, without X being written first.
fn a_row_smoothed(i: u32) -> V {
    var s = V(0.0);
    let end = row_ptr[i + 1u];
    for (var k = row_ptr[i]; k < end; k++) {
        let c = cols[k];
        s += mat_mul(vals[k], dinv[c] * mg[c]);
    }
    return s;
}

// Row i of the prolongator times the smoothed X + W T of the level below (at offsets total and
// 2 total of mg): a coarse level's post-smoothing update, applied where it is read.
fn pr_row_smoothed(i: u32) -> V {
    let tot = wide.total;
    var s = V(0.0);
    let end = pr_ptr[i + 1u];
    for (var k = pr_ptr[i]; k < end; k++) {
        let c = pr_cols[k];
        s += mat_mul(pr_vals[k], mg[tot + c] + dinv[c] * mg[2u * tot + c]);
    }
    return s;
}
