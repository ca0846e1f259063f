// SPDX-License-Identifier: MIT OR Apache-2.0
// Sparse matrix-vector product y = A x, one invocation per row, the row's entries two to a 16-byte
// load (`GpuPairs`: column, value bits, column, value bits; the last entry of a row of odd length
// in the row's span, with a zero entry on column 0 for a row of even length), in index order within
// the row, so the result is reproducible. Why pairs: llvmpipe runs every
// storage-buffer load as a loop over the SIMD lanes, one scalar load each, whatever the address
// pattern, and a vector load fetches all its components in the same loop; a 16-byte load of two
// entries replaces four 4-byte loads (docs/, "Linear algebra"). Dispatch: (min(groups, 65535),
// ceil(groups / 65535), 1) with groups = ceil(rows / 64). CPU twin: `Csr::mul` in
// src/solve/sparse.rs.
#import dims

@group(0) @binding(0) var<uniform> dims: Dims;
@group(0) @binding(1) var<storage, read> spans: array<vec4<u32>>;
@group(0) @binding(2) var<storage, read> pairs: array<vec4<u32>>;
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
    let span = spans[i];
    let end = span.x + span.y;
    for (var k = span.x; k < end; k++) {
        let p = pairs[k];
        s += bitcast<f32>(p.y) * x[p.x];
        s += bitcast<f32>(p.w) * x[p.z];
    }
    // Taken only for a row of odd length (a zero entry's product with a NaN would spoil it), but
    // loaded either way: a load under a branch costs the same on llvmpipe.
    let odd = bitcast<f32>(span.w) * x[span.z];
    if (span.w != 0u) {
        s += odd;
    }
    y[i] = s;
}
