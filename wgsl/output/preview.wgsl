// SPDX-License-Identifier: MIT OR Apache-2.0
// Preview: draws the textured mesh with a headlight and a little ambient light. Vertex buffers:
// position (vec3), normal (vec3), uv (vec2). Indexed by the split triangles.

struct View {
    view_proj: mat4x4<f32>,
    // xyz: direction towards the light (world space).
    light: vec4<f32>,
}

@group(0) @binding(0) var<uniform> view: View;
@group(0) @binding(1) var baked: texture_2d<f32>;
@group(0) @binding(2) var samp: sampler;

struct VsOut {
    @builtin(position) pos: vec4<f32>,
    @location(0) normal: vec3<f32>,
    @location(1) uv: vec2<f32>,
}

@vertex
fn vs_main(@location(0) pos: vec3<f32>, @location(1) normal: vec3<f32>, @location(2) uv: vec2<f32>) -> VsOut {
    var o: VsOut;
    o.pos = view.view_proj * vec4<f32>(pos, 1.0);
    o.normal = normal;
    o.uv = uv;
    return o;
}

@fragment
fn fs_main(in: VsOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    let albedo = textureSample(baked, samp, in.uv);
    var n = normalize(in.normal);
    if (!front) { n = -n; }
    let diffuse = max(dot(n, view.light.xyz), 0.0);
    let lit = albedo.rgb * (0.25 + 0.75 * diffuse);
    return vec4<f32>(lit, 1.0);
}
