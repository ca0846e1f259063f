// SPDX-License-Identifier: MIT OR Apache-2.0
// Plain streaming copy, dst = src, 16 bytes per invocation: the memory-bandwidth reference the SpMV
// benchmark is measured against. Dispatch: (min(groups, 65535), ceil(groups / 65535), 1) with
// groups = ceil(len / 256).
#import dims

@group(0) @binding(0) var<uniform> dims: Dims;
@group(0) @binding(1) var<storage, read> src: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> dst: array<vec4<f32>>;

@compute @workgroup_size(256)
fn main(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let i = (wid.y * groups.x + wid.x) * 256u + lid;
    if (i < dims.len) {
        dst[i] = src[i];
    }
}
