// SPDX-License-Identifier: MIT OR Apache-2.0
// Texture transfer ("texture.base": {"transfer": ...}): draws every non-degenerate triangle at its
// UV in the set being baked, carrying its UV in the source set, and samples the source texture
// there (bilinear, level 0, straight alpha) into the colour target; the coverage target marks the
// samples drawn. transfer_resolve.wgsl averages them per texel. Non-indexed draw of
// 3 * triangles vertices; degenerate triangles collapse to a point. CPU twin: `transfer_cpu` in
// src/bake/cpu_tools.rs.
#import params

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> tris: array<vec4<u32>>;
@group(0) @binding(2) var<storage, read> split_tris: array<u32>;
// The set being baked and the source's set, per split vertex.
@group(0) @binding(3) var<storage, read> uvs: array<vec2<f32>>;
@group(0) @binding(4) var<storage, read> src_uvs: array<vec2<f32>>;
@group(0) @binding(5) var src: texture_2d<f32>;
@group(0) @binding(6) var samp: sampler;

struct VsOut {
    @builtin(position) pos: vec4<f32>,
    @location(0) suv: vec2<f32>,
}

struct FsOut {
    @location(0) color: vec4<f32>,
    @location(1) coverage: vec4<f32>,
}

@vertex
fn vs_main(@builtin(vertex_index) vi: u32) -> VsOut {
    var out: VsOut;
    out.suv = vec2<f32>(0.0);
    let t = vi / 3u;
    if ((tris[t].w & 1u) != 0u) {
        out.pos = vec4<f32>(2.0, 2.0, 0.0, 1.0);
        return out;
    }
    let uv = uvs[split_tris[vi]] - vec2<f32>(params.tile);
    let texel = uv * vec2<f32>(params.tex_size) - vec2<f32>(params.rect_origin);
    let ndc = texel / vec2<f32>(params.rect_size) * 2.0 - 1.0;
    out.pos = vec4<f32>(ndc.x, -ndc.y, 0.0, 1.0);
    out.suv = src_uvs[split_tris[vi]];
    return out;
}

@fragment
fn fs_main(in: VsOut) -> FsOut {
    var out: FsOut;
    out.color = textureSampleLevel(src, samp, in.suv, 0.0);
    out.coverage = vec4<f32>(1.0);
    return out;
}
