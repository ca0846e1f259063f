// SPDX-License-Identifier: MIT OR Apache-2.0
// Sparse matrix-vector product y = A x for a CSR matrix, one invocation per row (rows in index order
// within the row, so the result is reproducible). Dispatch: (min(groups, 65535), ceil(groups / 65535), 1)
// with groups = ceil(rows / 64). CPU twin: `Csr::mul` in src/solve/sparse.rs.
#import dims

@group(0) @binding(0) var<uniform> dims: Dims;
@group(0) @binding(1) var<storage, read> row_ptr: array<u32>;
@group(0) @binding(2) var<storage, read> cols: array<u32>;
@group(0) @binding(3) var<storage, read> vals: array<f32>;
@group(0) @binding(4) var<storage, read> x: array<f32>;
@group(0) @binding(5) var<storage, read_write> y: array<f32>;

@compute @workgroup_size(64)
fn main(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let i = (wid.y * groups.x + wid.x) * 64u + lid;
    if (i >= dims.len) {
        return;
    }
    var s = 0.0;
    // The row's end read once, not per entry (lavapipe does not hoist the load: 7.3 → 5.2 ms on
    // the 342k-row Laplacian of `bench --linalg`).
    let end = row_ptr[i + 1u];
    for (var k = row_ptr[i]; k < end; k++) {
        s += vals[k] * x[cols[k]];
    }
    y[i] = s;
}
