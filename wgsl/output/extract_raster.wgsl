// SPDX-License-Identifier: MIT OR Apache-2.0
// `decalbake extract`: the inverse render of a texture along a layer's map (Sun et al. 2013,
// section 4.2). Each triangle the map covers is drawn at its image coordinates (x right, y down,
// [0, 1]^2 = the output image), carrying its texture UV; the fragment samples the texture there
// (bilinear, level 0, straight alpha, the UV wrapping as glTF's default sampler does). Pixels no
// triangle covers stay cleared (alpha 0). Non-indexed draw of 3 * triangles vertices.
// CPU twin: `extract_cpu` in src/output/extract.rs.

// Per corner: image coordinates (xy) and texture UV (zw).
@group(0) @binding(0) var<storage, read> corners: array<vec4<f32>>;
@group(0) @binding(1) var tex: texture_2d<f32>;
@group(0) @binding(2) var samp: sampler;

struct VsOut {
    @builtin(position) pos: vec4<f32>,
    @location(0) uv: vec2<f32>,
}

@vertex
fn vs_main(@builtin(vertex_index) vi: u32) -> VsOut {
    let c = corners[vi];
    var out: VsOut;
    out.pos = vec4<f32>(c.x * 2.0 - 1.0, 1.0 - c.y * 2.0, 0.0, 1.0);
    out.uv = c.zw;
    return out;
}

@fragment
fn fs_main(in: VsOut) -> @location(0) vec4<f32> {
    return textureSampleLevel(tex, samp, in.uv, 0.0);
}
