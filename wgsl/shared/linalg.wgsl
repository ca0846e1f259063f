// SPDX-License-Identifier: MIT OR Apache-2.0
// Shared pieces of the sparse linear-algebra kernels: the per-system descriptor of a batch (a batch is
// one block-diagonal CSR matrix; system s owns rows row0 .. row0 + n) and a workgroup reduction whose
// order is fixed (each invocation sums its rows in index order, then a fixed binary tree), so sums,
// and therefore iteration counts, are reproducible run to run and batch to batch.

const WG: u32 = 256u;

// Keep in sync with `SystemDesc` in src/linalg_gpu.rs.
struct System {
    row0: u32,
    n: u32,
    max_iter: u32,
    pad0: u32,
    rtol: f32,
    pad1: f32,
    pad2: f32,
    pad3: f32,
}

var<workgroup> red: array<vec4<f32>, WG>;

// Sum of `v` over the workgroup, identical in every invocation. Call in uniform control flow.
fn reduce4(v: vec4<f32>, lid: u32) -> vec4<f32> {
    red[lid] = v;
    workgroupBarrier();
    for (var s = WG / 2u; s > 0u; s = s >> 1u) {
        if (lid < s) {
            red[lid] = red[lid] + red[lid + s];
        }
        workgroupBarrier();
    }
    let out = red[0];
    workgroupBarrier();
    return out;
}
