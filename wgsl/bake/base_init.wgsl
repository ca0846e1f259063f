// SPDX-License-Identifier: MIT OR Apache-2.0
// Fills the linear accumulation buffer with the base: the base image sampled bilinearly at each texel
// centre (a 1x1 image for a solid colour), straight alpha. Dispatch: (ceil(W / 8), ceil(H / 8), 1), or
// over a region of the window (a live bake's edit: `region_texel` in shared/window.wgsl).
#import params
#import acc
#import window

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var base: texture_2d<f32>;
@group(0) @binding(2) var samp: sampler;

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let size = win_size();
    let g = region_texel(gid.xy);
    if (g.x == 0xffffffffu) { return; }
    let uv = (vec2<f32>(win_origin() + g) + 0.5) / vec2<f32>(params.tex_size);
    acc_store(g.y * size.x + g.x, textureSampleLevel(base, samp, uv, 0.0));
}
