// SPDX-License-Identifier: MIT OR Apache-2.0
// Exact Euclidean distance transform, pass 1 of 2 (Felzenszwalb & Huttenlocher 2012, "Distance
// Transforms of Sampled Functions", separable form): for every texel, the row of the nearest island
// texel in its column (-1 if the column has none). One invocation per column, which also adds its
// column's island texels to `count`.
// Dispatch: (ceil(W / 64), 1, 1). CPU twin: `nearest_island_map` in src/bake/cpu.rs.
#import params

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> mask: array<u32>;
@group(0) @binding(2) var<storage, read_write> col_near: array<i32>;
// Word 0: the island texels, counted here (one add a column).
@group(0) @binding(3) var<storage, read_write> count: array<atomic<u32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let w = params.tex_size.x;
    let h = params.tex_size.y;
    let x = gid.x;
    if (x >= w) { return; }
    var last = -1;
    var islands = 0u;
    for (var y = 0u; y < h; y++) {
        if (mask[y * w + x] != 0u) {
            last = i32(y);
            islands += 1u;
        }
        col_near[y * w + x] = last;
    }
    atomicAdd(&count[0], islands);
    var next = -1;
    for (var yy = 0u; yy < h; yy++) {
        let y = h - 1u - yy;
        if (mask[y * w + x] != 0u) { next = i32(y); }
        let prev = col_near[y * w + x];
        if (next >= 0 && (prev < 0 || next - i32(y) < i32(y) - prev)) {
            col_near[y * w + x] = next;
        }
    }
}
