// SPDX-License-Identifier: MIT OR Apache-2.0
// The V-cycle passes of a spread CG (cg_wide.wgsl: read its header) that neither sum over the rows
// nor decide the status: no barrier and no workgroup memory, so a pass the status rules out costs
// lavapipe the launch alone. One level per dispatch (`wide.level`), the rows strided over the
// workgroups; the same arithmetic as cg_amg.wgsl's `vcycle` and `sweep`, with NU = 1: the
// pre-smoothing X = W B folded into the residual's pass (DOWN), and the post-smoothing update of a
// coarse level into the prolongation that reads it (PROLONG; the fine level's, with its <r, z>, is
// cg_wide's SMOOTH_UPDATE). Dispatch: (groups, 1, 1). CPU twin: `amg::Hierarchy::apply`.
#import linalg
#import cg_state
#import cg_real
#import cg_row_ax
#import cg_rows
#import cg_wide_common

@compute @workgroup_size(WG)
fn main(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    if (state[wide.sys].status != ST_RUN) {
        return;
    }
    let sys = systems[wide.sys];
    let first = wg.x * WG + lid;
    let stride = groups.x * WG;
    let tot = wide.total;
    let lv = levels[sys.lvl0 + wide.level];
    let end = lv.x + lv.y;
    let phase = wide.phase;
    if (phase == DOWN) {
        // Pre-smoothing X = W B and the residual T = B - A X in one pass.
        for (var i = lv.x + first; i < end; i += stride) {
            let bi = mg[i];
            mg[tot + i] = dinv[i] * bi;
            mg[2u * tot + i] = bi - a_row_smoothed(i);
        }
    } else if (phase == RESTRICT) {
        // The next level's B = R T (rows of the transposes, `pr_*` rows total ..).
        let nx = levels[sys.lvl0 + wide.level + 1u];
        for (var h = nx.x + first; h < nx.x + nx.y; h += stride) {
            mg[h] = pr_row(tot + h, 2u * tot);
        }
    } else if (phase == COARSE) {
        for (var h = first; h < lv.y; h += stride) {
            var s = V(0.0);
            let row = sys.cinv0 + h * lv.y;
            for (var j = 0u; j < lv.y; j++) {
                s += mat_mul(cinv[row + j], mg[lv.x + j]);
            }
            mg[tot + lv.x + h] = s;
        }
    } else if (phase == PROLONG) {
        // The next level's X, from the coarsest solve as it is, else with its post-smoothing
        // update applied here: X + W T (no pass of its own; nothing else reads it).
        if (wide.level + 2u >= sys.nlev) {
            for (var i = lv.x + first; i < end; i += stride) {
                mg[tot + i] += pr_row(i, tot);
            }
        } else {
            for (var i = lv.x + first; i < end; i += stride) {
                mg[tot + i] += pr_row_smoothed(i);
            }
        }
    } else if (phase == SMOOTH_RESIDUAL) {
        for (var i = lv.x + first; i < end; i += stride) {
            mg[2u * tot + i] = mg[i] - a_row(i, tot);
        }
    }
}
