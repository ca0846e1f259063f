// SPDX-License-Identifier: MIT OR Apache-2.0
// Padding: every background texel whose nearest island texel (from the distance transform) lies
// within `params.aux` texels (0xffffffff = any distance) takes that texel's colour. Reads only island
// texels and writes only background texels, so one pass needs no ping-pong.
// Dispatch: (ceil(W / 8), ceil(H / 8), 1). CPU twin: `nearest_island` in src/compose_cpu.rs.
#import params
#import acc

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> mask: array<u32>;
@group(0) @binding(2) var<storage, read> nearest: array<u32>;

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let w = params.tex_size.x;
    if (gid.x >= w || gid.y >= params.tex_size.y) { return; }
    let idx = gid.y * w + gid.x;
    if (mask[idx] != 0u) { return; }
    let n = nearest[idx];
    if (n == 0xffffffffu) { return; }
    let dx = i32(n % w) - i32(gid.x);
    let dy = i32(n / w) - i32(gid.y);
    let d2 = u32(dx * dx + dy * dy);
    let radius = params.aux;
    if (radius == 0xffffffffu || d2 <= radius * radius) {
        acc_store(idx, acc_load(n));
    }
}
