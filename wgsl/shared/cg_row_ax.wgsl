// SPDX-License-Identifier: MIT OR Apache-2.0
// Row i of A x and of |A| |x| (a true residual's product and its reference), for the kernels that
// declare `row_ptr`, `cols`, `vals` and `x` (cg_packed.wgsl, wgsl/shared/cg_rows.wgsl). Import
// after `cg_real` (or `cg_complex`).

struct RowAx {
    ax: V,
    ax_abs: V,
}

fn row_ax(i: u32) -> RowAx {
    var out = RowAx(V(0.0), V(0.0));
    let end = row_ptr[i + 1u];
    for (var k = row_ptr[i]; k < end; k++) {
        let m = vals[k];
        let xk = x[cols[k]];
        out.ax += mat_mul(m, xk);
        out.ax_abs += mat_abs_mul(m, xk);
    }
    return out;
}
