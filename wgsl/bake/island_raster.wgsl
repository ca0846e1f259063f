// SPDX-License-Identifier: MIT OR Apache-2.0
// Draws every non-degenerate triangle at its global UV into a supersampled coverage target: the UV
// islands, which padding grows. Non-indexed draw of 3 * triangles vertices; degenerate triangles are
// collapsed to a point so they produce no fragments. CPU twin: `islands_cpu` in src/bake/cpu.rs.
#import params

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> tris: array<vec4<u32>>;
@group(0) @binding(2) var<storage, read> split_tris: array<u32>;
@group(0) @binding(3) var<storage, read> uvs: array<vec2<f32>>;

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

@fragment
fn fs_main() -> @location(0) vec4<f32> {
    return vec4<f32>(1.0);
}
