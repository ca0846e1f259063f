// SPDX-License-Identifier: MIT OR Apache-2.0
// Jacobi-preconditioned conjugate gradient, packed: one invocation per system of a block-diagonal CSR
// matrix, for batches of many small systems. The algorithm, the state kept between dispatches, the
// residual replacement every REPLACE iterations, the normwise stopping rule and the status codes are
// those of cg_batched.wgsl (read its header); what differs is the layout. There one workgroup owns a
// system and every dot product is a workgroup reduction with barriers, and on a CPU driver such as
// lavapipe a shader with barriers runs as coroutines that switch through every SIMD group at each
// barrier (`decalbake bench --device` measures it). Here an invocation walks its own system's rows
// serially, so there is no barrier and no reduction: the SIMD lanes and cores of the device work on
// different systems side by side. Sums run in row order (a different order from the reduction's, so
// results differ from cg_batched's in the last bits; tests/linalg.rs compares the two). Systems whose
// `wide` is not 2 belong to the other kernels. Dispatch: (ceil(systems / PACK_WG), 1, 1), the host
// sizes `round.iters` to stay under lavapipe's loop cut-off (src/solve/gpu.rs).
//
// The unknowns are of type V and the matrix entries of type M, with their products in the import
// `cg_real` (V = M = f32: any SPD matrix). The engine also builds this kernel with `cg_complex`
// instead (src/gpu/shaders.rs, `complex_source`): V = vec2 (u, v) per vertex and M = vec2 (a, b) per
// 2 × 2 block [[a, -b], [b, a]], for the LSCM systems, which have that structure (a Hermitian form
// in z = u + i v). The iteration is the same CG on the same real system; each product reads one
// 16-byte entry (column, a, b) for four real entries, and on lavapipe every load that differs
// between SIMD lanes costs a loop over the lanes, so that halves the loads of an iteration.
// CPU twin: `cg::pcg` in src/solve/cg.rs (f64, on the real form).
#import linalg
#import cg_state
#import cg_real
#import cg_row_ax

const PACK_WG: u32 = 64u;
const PACKED: u32 = 2u;

@group(0) @binding(0) var<uniform> round: Round;
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

// r = b - A x and z = D^-1 r over the system's rows; returns (<r, z>, <r, r>, <b, b>,
// |(|A| |x|)|²). With `set_p`, also p = z (the start of a solve).
fn true_residual(row0: u32, n: u32, set_p: bool) -> vec4<f32> {
    var part = vec4<f32>(0.0);
    for (var i = row0; i < row0 + n; i++) {
        let a = row_ax(i);
        let bi = b[i];
        let ri = bi - a.ax;
        r[i] = ri;
        let zi = dinv[i] * ri;
        if (set_p) {
            p[i] = zi;
        }
        part += vec4<f32>(vdot(ri, zi), vdot(ri, ri), vdot(bi, bi), vdot(a.ax_abs, a.ax_abs));
    }
    return part;
}

// The first dispatch of a solve: the true residual, p = z, and whether x0 already solves it.
fn start(row0: u32, n: u32, rtol: f32, st: ptr<function, State>) {
    let t = true_residual(row0, n, true);
    (*st).rz = t.x;
    (*st).bnorm = sqrt(t.z);
    (*st).scale = max((*st).bnorm, sqrt(t.w));
    (*st).iters = 0u;
    (*st).status = ST_RUN;
    if (!finite(t.x) || !finite(t.y) || !finite(t.z)) {
        (*st).status = ST_BREAK;
        (*st).rel_residual = 3.0e38;
    } else if (t.z == 0.0) {
        // b = 0: the answer is x = 0.
        (*st).status = ST_DONE;
        (*st).rel_residual = 0.0;
        for (var i = row0; i < row0 + n; i++) {
            x[i] = V(0.0);
        }
    } else {
        (*st).rel_residual = sqrt(t.y) / (*st).scale;
        if ((*st).rel_residual <= rtol) {
            (*st).status = ST_DONE;
        }
    }
}

// One fused iteration; returns the new status.
fn iterate(row0: u32, n: u32, rtol: f32, st: ptr<function, State>) -> u32 {
    // q = A p and <p, q>.
    var pap = 0.0;
    for (var i = row0; i < row0 + n; i++) {
        var q = V(0.0);
        let sp = spans[i];
        for (var k = sp.x; k < sp.y; k++) {
            let e = ents[k];
            q += mat_mul(ent_val(e), p[ent_col(e)]);
        }
        ap[i] = q;
        pap += vdot(p[i], q);
    }
    let alpha = (*st).rz / pap;
    (*st).iters += 1u;
    let replace = ((*st).iters % REPLACE) == 0u;
    var t = vec4<f32>(0.0);
    for (var i = row0; i < row0 + n; i++) {
        x[i] += alpha * p[i];
        let ri = r[i] - alpha * ap[i];
        r[i] = ri;
        t += vec4<f32>(dinv[i] * vdot(ri, ri), vdot(ri, ri), 0.0, 0.0);
    }
    if (replace) {
        t = true_residual(row0, n, false);
        (*st).scale = max((*st).bnorm, sqrt(t.w));
    }
    if (!(pap > 0.0) || !finite(pap) || !finite(t.x) || !finite(t.y)) {
        (*st).rel_residual = sqrt(t.y) / (*st).scale;
        return ST_BREAK;
    }
    if (sqrt(t.y) <= rtol * (*st).scale) {
        // Converged by the recursive residual: confirm with the true one before stopping.
        if (!replace) {
            t = true_residual(row0, n, false);
            (*st).scale = max((*st).bnorm, sqrt(t.w));
        }
        (*st).rel_residual = sqrt(t.y) / (*st).scale;
        if (sqrt(t.y) <= rtol * (*st).scale) {
            return ST_DONE;
        }
    }
    (*st).rel_residual = sqrt(t.y) / (*st).scale;
    let beta = t.x / (*st).rz;
    (*st).rz = t.x;
    for (var i = row0; i < row0 + n; i++) {
        p[i] = dinv[i] * r[i] + beta * p[i];
    }
    return ST_RUN;
}

@compute @workgroup_size(PACK_WG)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= round.count) {
        return;
    }
    let s = round.base + gid.x;
    let sys = systems[s];
    if (sys.wide != PACKED) {
        return;
    }
    var st = state[s];
    if (st.status == ST_INIT) {
        start(sys.row0, sys.n, sys.rtol, &st);
    }
    for (var k = 0u; k < round.iters; k++) {
        if (st.status != ST_RUN) {
            break;
        }
        if (st.iters >= sys.max_iter) {
            // Budget spent: report the true residual of the x handed back.
            let t = true_residual(sys.row0, sys.n, false);
            st.scale = max(st.bnorm, sqrt(t.w));
            st.rel_residual = sqrt(t.y) / st.scale;
            st.status = ST_BUDGET;
            break;
        }
        st.status = iterate(sys.row0, sys.n, sys.rtol, &st);
    }
    state[s] = st;
}
