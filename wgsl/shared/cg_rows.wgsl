// SPDX-License-Identifier: MIT OR Apache-2.0
// What the multigrid CG kernels (cg_amg.wgsl: one workgroup a system; cg_wide.wgsl and
// cg_wide_plain.wgsl: one system over many) share: bindings 1-17, less 4 and 14 (each entry's
// column and value are one load, `ents` and `pr_ents`; each kernel declares its own binding 0, and
// the spread ones binding 18) and the row products. Import after `linalg`,
// `cg_state`, `cg_real` (or `cg_complex`) and `cg_row_ax`.

@group(0) @binding(1) var<storage, read> systems: array<System>;
@group(0) @binding(2) var<storage, read> spans: array<vec2<u32>>;
@group(0) @binding(3) var<storage, read> ents: array<E>;
@group(0) @binding(5) var<storage, read> b: array<V>;
@group(0) @binding(6) var<storage, read> dinv: array<f32>;
@group(0) @binding(7) var<storage, read_write> x: array<V>;
@group(0) @binding(8) var<storage, read_write> r: array<V>;
@group(0) @binding(9) var<storage, read_write> p: array<V>;
@group(0) @binding(10) var<storage, read_write> ap: array<V>;
@group(0) @binding(11) var<storage, read_write> state: array<State>;
@group(0) @binding(12) var<storage, read> pr_spans: array<vec2<u32>>;
@group(0) @binding(13) var<storage, read> pr_ents: array<E>;
@group(0) @binding(15) var<storage, read> levels: array<vec2<u32>>;
@group(0) @binding(16) var<storage, read> cinv: array<M>;
@group(0) @binding(17) var<storage, read_write> mg: array<V>;

// Σ_k A[i, k] mg[v0 + k]: row i of the level matrices times the vector at offset v0 of mg.
fn a_row(i: u32, v0: u32) -> V {
    var s = V(0.0);
    let sp = spans[i];
    for (var k = sp.x; k < sp.y; k++) {
        let e = ents[k];
        s += mat_mul(ent_val(e), mg[v0 + ent_col(e)]);
    }
    return s;
}

// Row i of the prolongators (i < total) or restrictions (i >= total) times the vector at v0.
fn pr_row(i: u32, v0: u32) -> V {
    var s = V(0.0);
    let sp = pr_spans[i];
    for (var k = sp.x; k < sp.y; k++) {
        let e = pr_ents[k];
        s += mat_mul(ent_val(e), mg[v0 + ent_col(e)]);
    }
    return s;
}

// r = b - A x (and the fine level's B = r) on the rows row0 + first, + stride, ... below row0 + n;
// returns (0, <r, r>, <b, b>, |(|A| |x|)|²) partials.
fn true_residual_rows(row0: u32, n: u32, first: u32, stride: u32) -> vec4<f32> {
    var part = vec4<f32>(0.0);
    for (var i = row0 + first; i < row0 + n; i += stride) {
        let a = row_ax(i);
        let bi = b[i];
        let ri = bi - a.ax;
        r[i] = ri;
        mg[i] = ri;
        part += vec4<f32>(0.0, vdot(ri, ri), vdot(bi, bi), vdot(a.ax_abs, a.ax_abs));
    }
    return part;
}
