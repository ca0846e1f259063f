// SPDX-License-Identifier: MIT OR Apache-2.0
// Composes a finished stroke onto the canvas and clears the stroke buffer. The stroke's stamps were
// composed into the stroke buffer (straight alpha, source-over, each at its flow) by `compose`; here
// the buffer, scaled by the stroke's opacity, is blended onto the canvas with the stroke's blend
// mode, so overlapping stamps of one stroke never exceed its opacity.
// Dispatch: (ceil(rect w / 8), ceil(rect h / 8), 1); the rectangle is the whole texture (a stroke's
// texels can be anywhere its stamps' UVs wrap to; a tighter box is left to the speed issue).
// CPU twin: `apply_stroke` in src/bake/cpu.rs.
#import params
#import blend
#import acc
#import window

@group(0) @binding(0) var<uniform> params: Params;
// Word 7 of row params.aux (the stroke's last unit) counts the texels the stroke changed.
@group(0) @binding(3) var<storage, read_write> stats: array<atomic<i32>>;
@group(0) @binding(12) var<storage, read_write> stroke_rg: array<vec2<f32>>;
@group(0) @binding(13) var<storage, read_write> stroke_ba: array<vec2<f32>>;

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= params.rect_size.x || gid.y >= params.rect_size.y) { return; }
    let idx = win_index(vec2<i32>(gid.xy) + params.rect_origin);
    if (idx == 0xffffffffu) { return; }
    let s = vec4<f32>(stroke_rg[idx], stroke_ba[idx]);
    if (s.a <= 0.0) { return; }
    stroke_rg[idx] = vec2<f32>(0.0);
    stroke_ba[idx] = vec2<f32>(0.0);
    let src = vec4<f32>(s.rgb * s.a, s.a) * params.opacity;
    acc_store(idx, blend_any(params.blend, acc_load(idx), src, params.chan));
    atomicAdd(&stats[params.aux * params.stats_stride + 7u], 1);
}
