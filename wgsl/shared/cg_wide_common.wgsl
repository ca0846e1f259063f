// SPDX-License-Identifier: MIT OR Apache-2.0
// What the two kernels of a spread CG (cg_wide.wgsl: the passes with sums and the status;
// cg_wide_plain.wgsl: the V-cycle's passes without, which need no barrier) share: the pass
// selector (binding 0), the partial sums (binding 18) and the smoothed row products. Import after
// `linalg`, `cg_state`, `cg_real` (or `cg_complex`) and `cg_rows` (bindings 1-17, less 4 and 14).

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
@group(0) @binding(18) var<storage, read_write> partials: array<vec4<f32>>;


// Σ_k A[i, k] W_k B_k: row i of A times the pre-smoothed X = W B, without X being written first
// (W_k is in the entry, `ent_w`: one gather an entry fewer).
fn a_row_smoothed(i: u32) -> V {
    var s = V(0.0);
    let sp = spans[i];
    for (var k = sp.x; k < sp.y; k++) {
        let e = ents[k];
        let c = ent_col(e);
        s += mat_mul(ent_val(e), ent_w(e) * mg[c]);
    }
    return s;
}

// Row i of the prolongator times the smoothed X + W T of the level below (at offsets total and
// 2 total of mg): a coarse level's post-smoothing update, applied where it is read.
fn pr_row_smoothed(i: u32) -> V {
    let tot = wide.total;
    var s = V(0.0);
    let sp = pr_spans[i];
    for (var k = sp.x; k < sp.y; k++) {
        let e = pr_ents[k];
        let c = ent_col(e);
        s += mat_mul(ent_val(e), mg[tot + c] + ent_w(e) * mg[2u * tot + c]);
    }
    return s;
}
