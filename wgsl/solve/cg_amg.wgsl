// SPDX-License-Identifier: MIT OR Apache-2.0
// Conjugate gradient preconditioned by one smoothed-aggregation V-cycle per iteration, batched: one
// workgroup per system, `round.iters` iterations per dispatch, all state in buffers between
// dispatches; the same statuses, stopping rule and residual replacement as cg_batched.wgsl (read
// its header). Only systems whose `nlev` is set run here; the host builds their hierarchies
// (src/solve/amg.rs) and lays them out in one index space of `round.total` rows: the batch's own
// rows first, then every coarse level's. `spans` and `ents` hold every level's matrix in that
// space, `pr_*` the prolongators (rows 0 .. total) and their transposes (rows total .. 2 total),
// `dinv` the smoother's weights ω / dᵢ, `levels` each level's (first row, rows), `cinv` each
// coarsest level's dense inverse, and `mg` three vectors of `total` rows: the levels'
// right-hand sides (B), solutions (X) and residuals (T). The fine level's B is r and its X is z.
// The cycle: NU damped-Jacobi sweeps, the residual restricted, the next level, the correction
// prolonged, NU sweeps; symmetric, so the CG stays a CG. Passes are separated by storage barriers
// (about 65 ns each per workgroup on lavapipe, ARCHITECTURE.md), a few dozen per iteration.
// Unknowns are of type V and entries of type M (import `cg_real`: f32); the engine also builds it
// with `cg_complex` (src/gpu/shaders.rs, `complex_source`) for LSCM systems, whose every level keeps
// the 2 × 2 complex structure: then rows, levels and `round.total` count vertices, each unknown is
// a (u, v) vec2 and each entry an (a, b) block, half the loads of the real form.
// Dispatch: (systems, 1, 1). CPU twin: `amg::Hierarchy::apply` with `cg::pcg_with`.
#import linalg
#import cg_state
#import cg_real
#import cg_row_ax
#import cg_rows

// Keep in sync with `amg::NU` in src/solve/amg.rs.
const NU: u32 = 1u;
// The class of the systems this kernel solves (`MULTIGRID` in src/solve/gpu.rs).
const MULTIGRID: u32 = 3u;

@group(0) @binding(0) var<uniform> round: Round;
// Bindings 1-17 (the batch, the matrices, the CG's vectors, the hierarchy): wgsl/shared/cg_rows.wgsl.

var<workgroup> wg_status: u32;
var<workgroup> wg_iters: u32;

fn a_times_p(i: u32) -> V {
    var s = V(0.0);
    let sp = spans[i];
    for (var k = sp.x; k < sp.y; k++) {
        let e = ents[k];
        s += mat_mul(ent_val(e), p[ent_col(e)]);
    }
    return s;
}

// r = b - A x (and the fine level's B = r) for this invocation's rows; returns (0, <r, r>, <b, b>,
// |(|A| |x|)|²) partials.
fn true_residual(row0: u32, n: u32, lid: u32) -> vec4<f32> {
    return true_residual_rows(row0, n, lid, WG);
}

// One damped-Jacobi sweep on level rows [lo, lo + n): x += W (b - A x).
fn sweep(lo: u32, n: u32, lid: u32) {
    let tot = round.total;
    for (var i = lo + lid; i < lo + n; i += WG) {
        mg[2u * tot + i] = mg[i] - a_row(i, tot);
    }
    storageBarrier();
    for (var i = lo + lid; i < lo + n; i += WG) {
        mg[tot + i] += dinv[i] * mg[2u * tot + i];
    }
    storageBarrier();
}

// z = V(r): one V-cycle from the fine level's B (r), leaving z in the fine level's X.
fn vcycle(l0: u32, nl: u32, c0: u32, lid: u32) {
    let tot = round.total;
    for (var k = 0u; k + 1u < nl; k++) {
        let lv = levels[l0 + k];
        let nx = levels[l0 + k + 1u];
        for (var i = lv.x + lid; i < lv.x + lv.y; i += WG) {
            mg[tot + i] = dinv[i] * mg[i];
        }
        storageBarrier();
        for (var s = 1u; s < NU; s++) {
            sweep(lv.x, lv.y, lid);
        }
        for (var i = lv.x + lid; i < lv.x + lv.y; i += WG) {
            mg[2u * tot + i] = mg[i] - a_row(i, tot);
        }
        storageBarrier();
        for (var h = nx.x + lid; h < nx.x + nx.y; h += WG) {
            mg[h] = pr_row(tot + h, 2u * tot);
        }
        storageBarrier();
    }
    let lc = levels[l0 + nl - 1u];
    for (var h = lid; h < lc.y; h += WG) {
        var s = V(0.0);
        let row = c0 + h * lc.y;
        for (var j = 0u; j < lc.y; j++) {
            s += mat_mul(cinv[row + j], mg[lc.x + j]);
        }
        mg[tot + lc.x + h] = s;
    }
    storageBarrier();
    for (var k = nl - 1u; k > 0u; k--) {
        let lv = levels[l0 + k - 1u];
        for (var i = lv.x + lid; i < lv.x + lv.y; i += WG) {
            mg[tot + i] += pr_row(i, tot);
        }
        storageBarrier();
        for (var s = 0u; s < NU; s++) {
            sweep(lv.x, lv.y, lid);
        }
    }
}

// z = V(r), then <r, z> over the workgroup; with `set_p`, p = z, else p = z + beta p.
fn precondition(sys: System, lid: u32) -> f32 {
    storageBarrier();
    vcycle(sys.lvl0, sys.nlev, sys.cinv0, lid);
    var part = vec4<f32>(0.0);
    for (var i = sys.row0 + lid; i < sys.row0 + sys.n; i += WG) {
        part.x += vdot(r[i], mg[round.total + i]);
    }
    return reduce4(part, lid).x;
}

fn update_p(sys: System, beta: f32, lid: u32) {
    for (var i = sys.row0 + lid; i < sys.row0 + sys.n; i += WG) {
        p[i] = mg[round.total + i] + beta * p[i];
    }
    storageBarrier();
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
        // Systems of the other classes belong to the Jacobi kernels.
        if (sys.wide != MULTIGRID) {
            wg_status = ST_DONE + 100u;
        }
    }
    var status = workgroupUniformLoad(&wg_status);
    if (status == ST_DONE + 100u) {
        return;
    }
    var iters = workgroupUniformLoad(&wg_iters);
    if (status == ST_INIT) {
        let t = reduce4(true_residual(row0, n, lid), lid);
        st.bnorm = sqrt(t.z);
        st.scale = max(st.bnorm, sqrt(t.w));
        iters = 0u;
        if (lid == 0u) {
            var next = ST_RUN;
            if (!finite(t.y) || !finite(t.z) || !finite(t.w)) {
                next = ST_BREAK;
                st.rel_residual = 3.0e38;
            } else if (t.z == 0.0) {
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
                x[i] = V(0.0);
            }
        }
        if (status == ST_RUN) {
            st.rz = precondition(sys, lid);
            update_p(sys, 0.0, lid);
            if (lid == 0u && !finite(st.rz)) {
                wg_status = ST_BREAK;
            }
            status = workgroupUniformLoad(&wg_status);
        }
        storageBarrier();
    }
    for (var k = 0u; k < round.iters; k++) {
        if (status != ST_RUN) {
            break;
        }
        if (iters >= sys.max_iter) {
            let t = reduce4(true_residual(row0, n, lid), lid);
            st.scale = max(st.bnorm, sqrt(t.w));
            st.rel_residual = sqrt(t.y) / st.scale;
            status = ST_BUDGET;
            break;
        }
        var part = vec4<f32>(0.0);
        for (var i = row0 + lid; i < row0 + n; i += WG) {
            let q = a_times_p(i);
            ap[i] = q;
            part.x += vdot(p[i], q);
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
            mg[i] = ri;
            part.y += vdot(ri, ri);
        }
        if (replace) {
            storageBarrier();
            part = true_residual(row0, n, lid);
        }
        var t = reduce4(part, lid);
        if (replace) {
            st.scale = max(st.bnorm, sqrt(t.w));
        }
        if (lid == 0u) {
            var next = ST_RUN;
            if (!(pap > 0.0) || !finite(pap) || !finite(t.y)) {
                next = ST_BREAK;
            } else if (sqrt(t.y) <= sys.rtol * st.scale) {
                next = ST_DONE;
            }
            wg_status = next;
        }
        status = workgroupUniformLoad(&wg_status);
        if (status == ST_DONE && !replace) {
            // Converged by the recursive residual: confirm with the true one.
            storageBarrier();
            t = reduce4(true_residual(row0, n, lid), lid);
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
        let rz = precondition(sys, lid);
        if (lid == 0u && !finite(rz)) {
            wg_status = ST_BREAK;
        }
        status = workgroupUniformLoad(&wg_status);
        if (status != ST_RUN) {
            break;
        }
        let beta = rz / st.rz;
        st.rz = rz;
        update_p(sys, beta, lid);
    }
    if (lid == 0u) {
        st.status = status;
        st.iters = iters;
        state[s] = st;
    }
}
