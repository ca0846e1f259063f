// SPDX-License-Identifier: MIT OR Apache-2.0
// Reads the exponential maps the charts start from, only where they can be valid: out[k] =
// coords[indices[k]], the candidate discs of the chunk's chart layers (src/bake/maps.rs), so the
// read-back is as large as the discs, not as the mesh times the layers. Dispatch:
// (ceil(len / 64), 1, 1). No CPU twin: a pure copy.
#import dims

@group(0) @binding(0) var<uniform> dims: Dims;
@group(0) @binding(1) var<storage, read> indices: array<u32>;
@group(0) @binding(2) var<storage, read> coords: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> out: array<vec4<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x < dims.len) {
        out[gid.x] = coords[indices[gid.x]];
    }
}
