// SPDX-License-Identifier: MIT OR Apache-2.0
// Batched dot products and norms with a fixed reduction order (the same one the CG kernel uses): one
// workgroup per segment, out[s] = (<a, b>, <a, a>, <b, b>, 0) over the segment's rows. Dispatch:
// (segments, 1, 1). CPU twin: plain f64 sums in the tests.
#import linalg

@group(0) @binding(0) var<storage, read> systems: array<System>;
@group(0) @binding(1) var<storage, read> a: array<f32>;
@group(0) @binding(2) var<storage, read> b: array<f32>;
@group(0) @binding(3) var<storage, read_write> out: array<vec4<f32>>;

@compute @workgroup_size(WG)
fn main(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let sys = systems[wid.x];
    var part = vec4<f32>(0.0);
    for (var i = sys.row0 + lid; i < sys.row0 + sys.n; i += WG) {
        part += vec4<f32>(a[i] * b[i], a[i] * a[i], b[i] * b[i], 0.0);
    }
    let t = reduce4(part, lid);
    if (lid == 0u) {
        out[wid.x] = t;
    }
}
