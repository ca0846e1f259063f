// SPDX-License-Identifier: MIT OR Apache-2.0
// Draws a layer's triangles at their global UV (shifted by the UV tile and the raster rectangle) into a
// supersampled target, carrying the layer's local coordinates; the fragment stage samples the decal
// image (premultiplied, mipmapped: implicit derivatives pick the level) and the optional mask.
// Attachment 0: premultiplied colour; attachment 1: island coverage (1 where a triangle is drawn).
// Non-indexed draw of 3 * (triangles in the layer's list) vertices.
// CPU twin: `LayerRaster` in src/bake/cpu.rs.
#import params

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> lists: array<u32>;
@group(0) @binding(2) var<storage, read> split_tris: array<u32>;
@group(0) @binding(3) var<storage, read> uvs: array<vec2<f32>>;
@group(0) @binding(4) var<storage, read> welded_of: array<u32>;
@group(0) @binding(5) var<storage, read> coords: array<vec4<f32>>;
@group(0) @binding(6) var image: texture_2d<f32>;
@group(0) @binding(7) var mask: texture_2d<f32>;
@group(0) @binding(8) var samp: sampler;

struct VsOut {
    @builtin(position) pos: vec4<f32>,
    // Decal image coordinates: (0,0) top-left, (1,1) bottom-right.
    @location(0) img: vec2<f32>,
}

@vertex
fn vs_main(@builtin(vertex_index) vi: u32) -> VsOut {
    let t = lists[params.slot * params.triangle_count + vi / 3u];
    let s = split_tris[3u * t + vi % 3u];
    let uv = uvs[s] - vec2<f32>(params.tile);
    let c = coords[params.slot * params.vertex_count + welded_of[s]];
    let texel = uv * vec2<f32>(params.tex_size) - vec2<f32>(params.rect_origin);
    let ndc = texel / vec2<f32>(params.rect_size) * 2.0 - 1.0;
    var o: VsOut;
    o.pos = vec4<f32>(ndc.x, -ndc.y, 0.0, 1.0);
    o.img = vec2<f32>(c.x / params.axis_u.w + 0.5, 0.5 - c.y / params.axis_v.w);
    return o;
}

struct FsOut {
    @location(0) color: vec4<f32>,
    @location(1) coverage: vec4<f32>,
}

@fragment
fn fs_main(in: VsOut) -> FsOut {
    var c = textureSample(image, samp, in.img);
    let m = textureSample(mask, samp, in.img);
    if ((params.flags & FLAG_MASK) != 0u) {
        // Mask images are premultiplied like decals: red * alpha is the mask value.
        c = c * m.r;
    }
    let inside = all(in.img >= vec2<f32>(0.0)) && all(in.img <= vec2<f32>(1.0));
    var o: FsOut;
    o.color = select(vec4<f32>(0.0), c * params.opacity, inside);
    o.coverage = vec4<f32>(1.0);
    return o;
}
