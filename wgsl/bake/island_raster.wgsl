// SPDX-License-Identifier: MIT OR Apache-2.0
// Draws every non-degenerate triangle at its global UV and marks the texels it covers: the UV
// islands, which padding grows. Non-indexed draw of 3 * triangles vertices; degenerate triangles are
// collapsed to a point so they produce no fragments. A texel is an island texel where any of its
// samples is covered: each fragment stores 1 into its texel's word of `mask` (a plain store: every
// writer writes the same value, in any order). The colour target is the render pass's attachment
// only. CPU twin: `islands_cpu` in src/bake/cpu.rs.
#import params
#import window

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> tris: array<vec4<u32>>;
@group(0) @binding(2) var<storage, read> split_tris: array<u32>;
@group(0) @binding(3) var<storage, read> uvs: array<vec2<f32>>;
@group(0) @binding(4) var<storage, read_write> mask: array<u32>;

@vertex
fn vs_main(@builtin(vertex_index) vi: u32) -> @builtin(position) vec4<f32> {
    let t = vi / 3u;
    if ((tris[t].w & 1u) != 0u) {
        return vec4<f32>(2.0, 2.0, 0.0, 1.0);
    }
    let uv = uvs[split_tris[vi]] - vec2<f32>(params.tile);
    let texel = uv * vec2<f32>(params.tex_size) - vec2<f32>(params.rect_origin);
    let ndc = texel / vec2<f32>(params.rect_size) * 2.0 - 1.0;
    return vec4<f32>(ndc.x, -ndc.y, 0.0, 1.0);
}

// Target pixels a texel a side: the texture's samples a side on the supersampling grid, one where
// the adaptive bake draws the islands at four samples a pixel (`// MSAA: ` line live,
// `gpu::shaders::msaa_source`).
fn pixels_per_texel() -> u32 {
    var k = params.ss;
    // MSAA: k = 1u;
    return k;
}

@fragment
fn fs_main(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    let texel = vec2<i32>(vec2<u32>(pos.xy) / pixels_per_texel()) + params.rect_origin;
    let idx = win_index(texel);
    if (idx != 0xffffffffu) {
        mask[idx] = 1u;
    }
    return vec4<f32>(1.0);
}
