// SPDX-License-Identifier: MIT OR Apache-2.0
// Jacobi-preconditioned conjugate gradient, batched: one workgroup per system of a block-diagonal CSR
// matrix, `round.iters` iterations per dispatch (sized by the host to stay under lavapipe's loop
// cut-off), all state kept in buffers between dispatches so a solve spans as many dispatches as it
// needs with no read-back in between. Each iteration is fused: SpMV + <p, Ap> in one pass, the
// updates of x, r and z plus <r, z> and <r, r> in the next, then p; every REPLACE iterations, and
// before declaring convergence, the residual is recomputed as b - A x so that f32 drift cannot fake
// convergence. The residual is measured against max(|b|, |(|A| |x|)|), the normwise backward
// error: relative to |b| alone, a well-solved system whose right-hand side is small next to the
// terms of A x (LSCM: only two pinned vertices feed b) could never get under a tight target in f32.
// Status per system: 0 = not started, 1 = running, 2 = converged, 3 = iteration budget
// spent (not converged), 4 = breakdown (NaN/Inf seen, or <p, Ap> <= 0: the matrix is not SPD).
// Dispatch: (systems, 1, 1). CPU twin: `cg::pcg` in src/solve/cg.rs (f64).
#import linalg
#import cg_state

const ST_OTHER: u32 = 99u;

@group(0) @binding(0) var<uniform> round: Round;
@group(0) @binding(1) var<storage, read> systems: array<System>;
@group(0) @binding(2) var<storage, read> spans: array<vec2<u32>>;
// Per stored entry: its column and its value's bits (`GpuCsr` in src/solve/gpu.rs).
@group(0) @binding(3) var<storage, read> ents: array<vec2<u32>>;
@group(0) @binding(5) var<storage, read> b: array<f32>;
@group(0) @binding(6) var<storage, read> dinv: array<f32>;
@group(0) @binding(7) var<storage, read_write> x: array<f32>;
@group(0) @binding(8) var<storage, read_write> r: array<f32>;
@group(0) @binding(9) var<storage, read_write> p: array<f32>;
@group(0) @binding(10) var<storage, read_write> ap: array<f32>;
@group(0) @binding(11) var<storage, read_write> state: array<State>;

var<workgroup> wg_status: u32;
var<workgroup> wg_iters: u32;

fn a_times_p(i: u32) -> f32 {
    var s = 0.0;
    let sp = spans[i];
    for (var k = sp.x; k < sp.y; k++) {
        let e = ents[k];
        s += bitcast<f32>(e.y) * p[e.x];
    }
    return s;
}

// (A x)_i and (|A| |x|)_i.
fn a_times_x(i: u32) -> vec2<f32> {
    var s = vec2<f32>(0.0);
    let sp = spans[i];
    for (var k = sp.x; k < sp.y; k++) {
        let e = ents[k];
        let t = bitcast<f32>(e.y) * x[e.x];
        s += vec2<f32>(t, abs(t));
    }
    return s;
}

// r = b - A x and z = D^-1 r for this invocation's rows; returns (<r, z>, <r, r>, <b, b>,
// |(|A| |x|)|²) partials. With `set_p`, also p = z (the start of a solve).
fn true_residual(row0: u32, n: u32, lid: u32, set_p: bool) -> vec4<f32> {
    var part = vec4<f32>(0.0);
    for (var i = row0 + lid; i < row0 + n; i += WG) {
        let ax = a_times_x(i);
        let ri = b[i] - ax.x;
        r[i] = ri;
        let zi = dinv[i] * ri;
        if (set_p) {
            p[i] = zi;
        }
        part += vec4<f32>(ri * zi, ri * ri, b[i] * b[i], ax.y * ax.y);
    }
    return part;
}

@compute @workgroup_size(WG)
fn main(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let s = round.base + wid.x;
    let sys = systems[s];
    let row0 = sys.row0;
    let n = sys.n;
    var st = state[s];
    if (lid == 0u) {
        wg_status = st.status;
        wg_iters = st.iters;
        // Systems of the other width class belong to the other variant of this kernel.
        if (sys.wide != u32(WG > 64u)) {
            wg_status = ST_OTHER;
        }
    }
    var status = workgroupUniformLoad(&wg_status);
    if (status == ST_OTHER) {
        return;
    }
    var iters = workgroupUniformLoad(&wg_iters);
    if (status == ST_INIT) {
        let t = reduce4(true_residual(row0, n, lid, true), lid);
        st.rz = t.x;
        st.bnorm = sqrt(t.z);
        st.scale = max(st.bnorm, sqrt(t.w));
        iters = 0u;
        if (lid == 0u) {
            var next = ST_RUN;
            if (!finite(t.x) || !finite(t.y) || !finite(t.z)) {
                next = ST_BREAK;
                st.rel_residual = 3.0e38;
            } else if (t.z == 0.0) {
                // b = 0: the answer is x = 0.
                next = ST_DONE;
                st.rel_residual = 0.0;
            } else {
                st.rel_residual = sqrt(t.y) / st.scale;
                if (st.rel_residual <= sys.rtol) {
                    next = ST_DONE;
                }
            }
            wg_status = next;
        }
        status = workgroupUniformLoad(&wg_status);
        if (status == ST_DONE && st.bnorm == 0.0) {
            for (var i = row0 + lid; i < row0 + n; i += WG) {
                x[i] = 0.0;
            }
        }
        storageBarrier();
    }
    for (var k = 0u; k < round.iters; k++) {
        if (status != ST_RUN) {
            break;
        }
        if (iters >= sys.max_iter) {
            // Budget spent: report the true residual of the x handed back.
            let t = reduce4(true_residual(row0, n, lid, false), lid);
            st.scale = max(st.bnorm, sqrt(t.w));
            st.rel_residual = sqrt(t.y) / st.scale;
            status = ST_BUDGET;
            break;
        }
        // q = A p and <p, q>.
        var part = vec4<f32>(0.0);
        for (var i = row0 + lid; i < row0 + n; i += WG) {
            let q = a_times_p(i);
            ap[i] = q;
            part.x += p[i] * q;
        }
        let pap = reduce4(part, lid).x;
        let alpha = st.rz / pap;
        iters += 1u;
        let replace = (iters % REPLACE) == 0u;
        part = vec4<f32>(0.0);
        for (var i = row0 + lid; i < row0 + n; i += WG) {
            x[i] += alpha * p[i];
            let ri = r[i] - alpha * ap[i];
            r[i] = ri;
            part += vec4<f32>(dinv[i] * ri * ri, ri * ri, 0.0, 0.0);
        }
        if (replace) {
            storageBarrier();
            part = true_residual(row0, n, lid, false);
        }
        var t = reduce4(part, lid);
        if (replace) {
            st.scale = max(st.bnorm, sqrt(t.w));
        }
        // Converged by the recursive residual: confirm with the true one before stopping.
        if (lid == 0u) {
            var next = ST_RUN;
            if (!(pap > 0.0) || !finite(pap) || !finite(t.x) || !finite(t.y)) {
                next = ST_BREAK;
            } else if (sqrt(t.y) <= sys.rtol * st.scale) {
                next = ST_DONE;
            }
            wg_status = next;
        }
        status = workgroupUniformLoad(&wg_status);
        if (status == ST_DONE && !replace) {
            storageBarrier();
            t = reduce4(true_residual(row0, n, lid, false), lid);
            st.scale = max(st.bnorm, sqrt(t.w));
            if (lid == 0u) {
                wg_status = select(ST_RUN, ST_DONE, sqrt(t.y) <= sys.rtol * st.scale);
            }
            status = workgroupUniformLoad(&wg_status);
        }
        st.rel_residual = sqrt(t.y) / st.scale;
        if (status != ST_RUN) {
            break;
        }
        let beta = t.x / st.rz;
        st.rz = t.x;
        for (var i = row0 + lid; i < row0 + n; i += WG) {
            p[i] = dinv[i] * r[i] + beta * p[i];
        }
        storageBarrier();
    }
    if (lid == 0u) {
        st.status = status;
        st.iters = iters;
        state[s] = st;
    }
}
