// SPDX-License-Identifier: MIT OR Apache-2.0
// Writes solved chart coordinates into the layers' coords slots: item k sets coords[index] = value
// ((x, y, distance or 0, valid) in model units in the decal frame). The slots are cleared first with
// a buffer clear. Dispatch: (ceil(items / 64), 1, 1). No CPU twin: a pure copy.
#import dims

struct Item {
    index: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
    value: vec4<f32>,
}

@group(0) @binding(0) var<uniform> dims: Dims;
@group(0) @binding(1) var<storage, read> items: array<Item>;
@group(0) @binding(2) var<storage, read_write> coords: array<vec4<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x < dims.len) {
        let it = items[gid.x];
        coords[it.index] = it.value;
    }
}
