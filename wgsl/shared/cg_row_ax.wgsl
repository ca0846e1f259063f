// SPDX-License-Identifier: MIT OR Apache-2.0
// Row i of A x and of |A| |x| (a true residual's product and its reference), for the kernels that
// declare `spans`, `ents` and `x` (cg_packed.wgsl, wgsl/shared/cg_rows.wgsl). Import
// after `cg_real` (or `cg_complex`).

struct RowAx {
    ax: V,
    ax_abs: V,
}

fn row_ax(i: u32) -> RowAx {
    var out = RowAx(V(0.0), V(0.0));
    let sp = spans[i];
    for (var k = sp.x; k < sp.y; k++) {
        let e = ents[k];
        let m = ent_val(e);
        let xk = x[ent_col(e)];
        out.ax += mat_mul(m, xk);
        out.ax_abs += mat_abs_mul(m, xk);
    }
    return out;
}
