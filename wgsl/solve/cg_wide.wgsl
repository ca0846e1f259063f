// SPDX-License-Identifier: MIT OR Apache-2.0
// Conjugate gradient preconditioned by one smoothed-aggregation V-cycle per iteration, for ONE
// large system spread over many workgroups: each pass of cg_amg.wgsl (read its header: the same
// buffers, hierarchy layout, statuses and stopping rule) is a dispatch of its own, over as many
// workgroups as the host gives it, which stride the rows, so every core of the device works on
// the system, where cg_amg runs it on one workgroup (one CPU thread on lavapipe, one SM on a GPU).
// `wide.phase` selects the pass; the host records an iteration as a fixed sequence of dispatches
// (`solve::gpu_wide`) and reads the status only between submissions. This kernel has the passes
// that sum over the rows or decide the status; the V-cycle's other passes are in
// cg_wide_plain.wgsl, which has no barrier (on lavapipe a dispatch of a kernel with barriers costs
// several times one without, README "Linear algebra"). Passes that the status rules out return.
//
// Dot products: each workgroup of a fine-level pass writes its sum (fixed order, `reduce4`) to its
// slot of `partials`, and the next pass that needs the total adds the `wide.parts` slots in index
// order in every workgroup: the same value everywhere, and reproducible. Scalars derived from them
// (alpha, beta, whether the true residual is due) are recomputed where used rather than stored, so
// no pass reads what another workgroup of the same dispatch writes; the status and counters are
// written only by the one-workgroup passes (TRUE_CHECK, INIT_CHECK). <r, z> alternates between two
// slots by the parity of the iteration count, so beta = <r, z>_new / <r, z>_old needs no stored
// copy. Dispatch: (groups, 1, 1) per the host's sequence. CPU twin: `amg::Hierarchy::apply` with
// `cg::pcg_with` (the same as cg_amg's).
#import linalg
#import cg_state
#import cg_real
#import cg_row_ax
#import cg_rows
#import cg_wide_common

// Keep in sync with `amg::NU` in src/solve/amg.rs (this kernel's cycle is written for NU = 1: one
// pre-smoothing step X = W B, one post-smoothing sweep).
const NU: u32 = 1u;
// Partial-sum slots per quantity: the most workgroups a fine-level pass may have. Keep in sync with
// `PARTS` in src/solve/gpu_wide.rs.
const PARTS: u32 = 256u;
const SLOT_PAP: u32 = 0u;
const SLOT_RR: u32 = 1u;
const SLOT_TRUE: u32 = 2u;
const SLOT_RZ: u32 = 3u;

// Whether the true residual is due after an update, and why.
const TRUE_NONE: u32 = 0u;
const TRUE_REPLACE: u32 = 1u;
const TRUE_CONFIRM: u32 = 2u;
const TRUE_BUDGET: u32 = 3u;

var<workgroup> wg_status: u32;
// (status, iterations) as the pass starts.
var<workgroup> wg_state: vec2<u32>;

// The total of a quantity's partial sums (slot `slot`), the same in every invocation. Call in
// uniform control flow.
fn total(slot: u32, lid: u32) -> vec4<f32> {
    var s = vec4<f32>(0.0);
    for (var k = lid; k < wide.parts; k += WG) {
        s += partials[slot * PARTS + k];
    }
    return reduce4(s, lid);
}

// Writes this workgroup's sum of `part` to its slot. Call in uniform control flow.
fn put(slot: u32, part: vec4<f32>, wid: u32, lid: u32) {
    let t = reduce4(part, lid);
    if (lid == 0u) {
        partials[slot * PARTS + wid] = t;
    }
}

// r = b - A x (and the fine level's B = r) over the rows this invocation strides.
fn true_residual(sys: System, first: u32, stride: u32) -> vec4<f32> {
    return true_residual_rows(sys.row0, sys.n, first, stride);
}

// INIT_CHECK: the first residual's verdict (one workgroup).
fn init_check(sys: System, lid: u32) {
    var st = state[wide.sys];
    let t = total(SLOT_TRUE, lid);
    if (lid == 0u) {
        st.bnorm = sqrt(t.z);
        st.scale = max(st.bnorm, sqrt(t.w));
        st.iters = 0u;
        st.status = ST_RUN;
        if (!finite(t.y) || !finite(t.z) || !finite(t.w)) {
            st.status = ST_BREAK;
            st.rel_residual = 3.0e38;
        } else if (t.z == 0.0) {
            st.status = ST_DONE;
            st.rel_residual = 0.0;
        } else {
            st.rel_residual = sqrt(t.y) / st.scale;
            if (st.rel_residual <= sys.rtol) {
                st.status = ST_DONE;
            } else if (sys.max_iter == 0u) {
                st.status = ST_BUDGET;
            }
        }
        state[wide.sys] = st;
        wg_status = st.status;
    }
    let status = workgroupUniformLoad(&wg_status);
    if (status == ST_DONE && t.z == 0.0) {
        for (var i = sys.row0 + lid; i < sys.row0 + sys.n; i += WG) {
            x[i] = V(0.0);
        }
    }
}

// Whether the true residual is due after the update that made <p, Ap> = `pap` and <r, r> = `rr`
// (the `iters`-th iteration's): to confirm convergence, at the budget, or every REPLACE iterations.
fn due(sys: System, st: State, pap: f32, rr: f32, iters: u32) -> u32 {
    if (!(pap > 0.0) || !finite(pap) || !finite(rr)) {
        return TRUE_NONE;
    }
    // The budget first: a solve whose recursive residual converged but whose true one did not
    // must still stop at its budget (as cg_amg does).
    if (iters >= sys.max_iter) {
        return TRUE_BUDGET;
    }
    if (sqrt(rr) <= sys.rtol * st.scale) {
        return TRUE_CONFIRM;
    }
    if (iters % REPLACE == 0u) {
        return TRUE_REPLACE;
    }
    return TRUE_NONE;
}

// TRUE_CHECK (one workgroup): counts the iteration and gives the verdict: breakdown, or on the
// true residual where one was due.
fn true_check(sys: System, lid: u32) {
    let pap = total(SLOT_PAP, lid).x;
    let rr = total(SLOT_RR, lid).y;
    let t = total(SLOT_TRUE, lid);
    if (lid == 0u) {
        var st = state[wide.sys];
        st.iters += 1u;
        let why = due(sys, st, pap, rr, st.iters);
        st.rel_residual = sqrt(rr) / st.scale;
        if (!(pap > 0.0) || !finite(pap) || !finite(rr)) {
            st.status = ST_BREAK;
        } else if (why != TRUE_NONE && t.x > 0.0) {
            st.scale = max(st.bnorm, sqrt(t.w));
            st.rel_residual = sqrt(t.y) / st.scale;
            if (!finite(t.y)) {
                st.status = ST_BREAK;
            } else if (sqrt(t.y) <= sys.rtol * st.scale) {
                st.status = ST_DONE;
            } else if (why == TRUE_BUDGET) {
                st.status = ST_BUDGET;
            }
        }
        state[wide.sys] = st;
    }
}

@compute @workgroup_size(WG)
fn main(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let sys = systems[wide.sys];
    let phase = wide.phase;
    let wid = wg.x;
    let first = wid * WG + lid;
    let stride = groups.x * WG;
    if (lid == 0u) {
        let st = state[wide.sys];
        wg_state = vec2<u32>(st.status, st.iters);
    }
    let loaded = workgroupUniformLoad(&wg_state);
    let status = loaded.x;
    let iters = loaded.y;
    if (phase == INIT_RESIDUAL || phase == INIT_CHECK) {
        if (status != ST_INIT) {
            return;
        }
        if (phase == INIT_RESIDUAL) {
            put(SLOT_TRUE, true_residual(sys, first, stride), wid, lid);
        } else {
            init_check(sys, lid);
        }
        return;
    }
    if (status != ST_RUN) {
        return;
    }
    if (phase == SPMV) {
        var part = vec4<f32>(0.0);
        for (var i = sys.row0 + first; i < sys.row0 + sys.n; i += stride) {
            var q = V(0.0);
            let sp = spans[i];
            for (var k = sp.x; k < sp.y; k++) {
                let e = ents[k];
                q += mat_mul(ent_val(e), p[ent_col(e)]);
            }
            ap[i] = q;
            part.x += vdot(p[i], q);
        }
        put(SLOT_PAP, part, wid, lid);
    } else if (phase == UPDATE) {
        var alpha = total(SLOT_RZ + iters % 2u, lid).x / total(SLOT_PAP, lid).x;
        // A non-finite step (<r, z> or <p, Ap> broke down) leaves x as it was; TRUE_CHECK then
        // reports the breakdown from <p, Ap>.
        if (!finite(alpha)) {
            alpha = 0.0;
        }
        var part = vec4<f32>(0.0);
        for (var i = sys.row0 + first; i < sys.row0 + sys.n; i += stride) {
            x[i] += alpha * p[i];
            let ri = r[i] - alpha * ap[i];
            r[i] = ri;
            mg[i] = ri;
            part.y += vdot(ri, ri);
        }
        put(SLOT_RR, part, wid, lid);
    } else if (phase == TRUE_RESIDUAL) {
        // Every workgroup reaches the same verdict from the same sums; the rows are only touched
        // when the true residual is due (the partials are written either way, in uniform flow).
        let pap = total(SLOT_PAP, lid).x;
        let rr = total(SLOT_RR, lid).y;
        var part = vec4<f32>(0.0);
        if (due(sys, state[wide.sys], pap, rr, iters + 1u) != TRUE_NONE) {
            part = true_residual(sys, first, stride);
            // Marks the sums as taken: TRUE_CHECK acts on them only then.
            part.x = 1.0;
        }
        put(SLOT_TRUE, part, wid, lid);
    } else if (phase == TRUE_CHECK) {
        true_check(sys, lid);
    } else if (phase == SMOOTH_UPDATE) {
        // The fine level's post-smoothing update: z, and <r, z> into this iteration's slot.
        let tot = wide.total;
        var part = vec4<f32>(0.0);
        for (var i = sys.row0 + first; i < sys.row0 + sys.n; i += stride) {
            let z = mg[tot + i] + dinv[i] * mg[2u * tot + i];
            mg[tot + i] = z;
            part.x += vdot(r[i], z);
        }
        put(SLOT_RZ + iters % 2u, part, wid, lid);
    } else if (phase == UPDATE_P) {
        // p = z (the first direction) or z + beta p.
        var beta = 0.0;
        let rz = total(SLOT_RZ + iters % 2u, lid).x;
        let rz_old = total(SLOT_RZ + (iters + 1u) % 2u, lid).x;
        if (iters > 0u) {
            beta = rz / rz_old;
        }
        for (var i = sys.row0 + first; i < sys.row0 + sys.n; i += stride) {
            p[i] = mg[wide.total + i] + beta * p[i];
        }
    }
}
