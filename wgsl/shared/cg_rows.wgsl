// SPDX-License-Identifier: MIT OR Apache-2.0
// The row products of the multigrid CG kernels (cg_amg.wgsl: one workgroup a system; cg_wide.wgsl
// and cg_wide_plain.wgsl: one system over many): they read the bindings those kernels declare by
// the same names (row_ptr, cols, vals, b, x, r, pr_ptr, pr_cols, pr_vals, mg). Import after
// `cg_real` (or `cg_complex`).

// Σ_k A[i, k] mg[v0 + k]: row i of the level matrices times the vector at offset v0 of mg.
fn a_row(i: u32, v0: u32) -> V {
    var s = V(0.0);
    let end = row_ptr[i + 1u];
    for (var k = row_ptr[i]; k < end; k++) {
        s += mat_mul(vals[k], mg[v0 + cols[k]]);
    }
    return s;
}

// Row i of the prolongators (i < total) or restrictions (i >= total) times the vector at v0.
fn pr_row(i: u32, v0: u32) -> V {
    var s = V(0.0);
    let end = pr_ptr[i + 1u];
    for (var k = pr_ptr[i]; k < end; k++) {
        s += mat_mul(pr_vals[k], mg[v0 + pr_cols[k]]);
    }
    return s;
}

// r = b - A x (and the fine level's B = r) on the rows row0 + first, + stride, ... below row0 + n;
// returns (0, <r, r>, <b, b>, |(|A| |x|)|²) partials.
fn true_residual_rows(row0: u32, n: u32, first: u32, stride: u32) -> vec4<f32> {
    var part = vec4<f32>(0.0);
    for (var i = row0 + first; i < row0 + n; i += stride) {
        var ax = V(0.0);
        var ax_abs = V(0.0);
        let end = row_ptr[i + 1u];
        for (var k = row_ptr[i]; k < end; k++) {
            let m = vals[k];
            let xk = x[cols[k]];
            ax += mat_mul(m, xk);
            ax_abs += mat_abs_mul(m, xk);
        }
        let bi = b[i];
        let ri = bi - ax;
        r[i] = ri;
        mg[i] = ri;
        part += vec4<f32>(0.0, vdot(ri, ri), vdot(bi, bi), vdot(ax_abs, ax_abs));
    }
    return part;
}
