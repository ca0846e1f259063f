// SPDX-License-Identifier: MIT OR Apache-2.0
// Shared pieces of the sparse linear-algebra kernels: the per-system descriptor of a batch (a batch is
// one block-diagonal CSR matrix; system s owns rows row0 .. row0 + n) and a workgroup reduction whose
// order is fixed (each invocation sums its rows in index order, then a fixed binary tree), so sums,
// and therefore iteration counts, are reproducible run to run and batch to batch.

const WG: u32 = 256u;

// Keep in sync with `SystemDesc` in src/solve/gpu.rs.
struct System {
    row0: u32,
    n: u32,
    max_iter: u32,
    // 1: solved by the 256-wide variant, 0: by the 64-wide one (set by the host per system).
    wide: u32,
    rtol: f32,
    // The multigrid hierarchy of a system solved by cg_amg.wgsl (nlev = 0: none): its first entry
    // in `levels`, its number of levels and the offset of its coarsest inverse in `cinv`.
    lvl0: u32,
    nlev: u32,
    cinv0: u32,
}

// Partials are added in two fixed-order stages: RS groups of RL consecutive invocations, then the RS
// group sums. Three barriers per reduction (a log-depth tree would need eight, and on a CPU driver
// such as lavapipe each barrier switches through every SIMD group of the workgroup).
const RL: u32 = 16u;
const RS: u32 = WG / RL;

var<workgroup> red: array<vec4<f32>, WG>;
var<workgroup> red2: array<vec4<f32>, RS>;

// Sum of `v` over the workgroup, identical in every invocation. Call in uniform control flow.
fn reduce4(v: vec4<f32>, lid: u32) -> vec4<f32> {
    red[lid] = v;
    workgroupBarrier();
    if (lid < RS) {
        var s = vec4<f32>(0.0);
        for (var k = 0u; k < RL; k++) {
            s += red[lid * RL + k];
        }
        red2[lid] = s;
    }
    workgroupBarrier();
    var out = vec4<f32>(0.0);
    for (var k = 0u; k < RS; k++) {
        out += red2[k];
    }
    workgroupBarrier();
    return out;
}
