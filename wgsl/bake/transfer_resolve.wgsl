// SPDX-License-Identifier: MIT OR Apache-2.0
// Texture transfer, second half: each texel of the raster job's rectangle takes the mean of its
// ss x ss samples that transfer_raster.wgsl drew (straight alpha); texels with none are left as
// they are (transparent: padding fills them). Dispatch: (ceil(rect w / 8), ceil(rect h / 8), 1).
// CPU twin: `transfer_cpu` in src/bake/cpu_tools.rs.
#import params
#import acc
#import window

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var color: texture_2d<f32>;
@group(0) @binding(2) var coverage: texture_2d<f32>;

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= params.rect_size.x || gid.y >= params.rect_size.y) { return; }
    let texel = vec2<i32>(gid.xy) + params.rect_origin;
    let idx = win_index(texel);
    if (idx == 0xffffffffu) { return; }
    var sum = vec4<f32>(0.0);
    var n = 0.0;
    for (var sy = 0u; sy < params.ss; sy = sy + 1u) {
        for (var sx = 0u; sx < params.ss; sx = sx + 1u) {
            let s = vec2<i32>(gid.xy * params.ss + vec2<u32>(sx, sy));
            if (textureLoad(coverage, s, 0).r > 0.5) {
                sum = sum + textureLoad(color, s, 0);
                n = n + 1.0;
            }
        }
    }
    if (n > 0.0) {
        acc_store(idx, sum / n);
    }
}
