// SPDX-License-Identifier: MIT OR Apache-2.0
// Preview: draws the textured mesh with a headlight and a little ambient light. Vertex buffers:
// position (vec3), normal (vec3), uv (vec2), a second uv (vec2) and a weight (f32): the colour is
// weight * baked(uv) + (1 - weight) * second(uv2), Piponi & Borshukov's blended rendering of a pelt
// and its patch (weight = `_PELT_BLEND`); a plain preview binds one texture twice with weight 1.
// Indexed by the split triangles.

struct View {
    view_proj: mat4x4<f32>,
    // xyz: direction towards the light (world space).
    light: vec4<f32>,
}

@group(0) @binding(0) var<uniform> view: View;
@group(0) @binding(1) var baked: texture_2d<f32>;
@group(0) @binding(2) var samp: sampler;
@group(0) @binding(3) var second: texture_2d<f32>;

struct VsOut {
    @builtin(position) pos: vec4<f32>,
    @location(0) normal: vec3<f32>,
    @location(1) uv: vec2<f32>,
    @location(2) uv2: vec2<f32>,
    @location(3) weight: f32,
}

@vertex
fn vs_main(
    @location(0) pos: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
    @location(3) uv2: vec2<f32>,
    @location(4) weight: f32,
) -> VsOut {
    var o: VsOut;
    o.pos = view.view_proj * vec4<f32>(pos, 1.0);
    o.normal = normal;
    o.uv = uv;
    o.uv2 = uv2;
    o.weight = weight;
    return o;
}

@fragment
fn fs_main(in: VsOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    let albedo = in.weight * textureSample(baked, samp, in.uv)
        + (1.0 - in.weight) * textureSample(second, samp, in.uv2);
    var n = normalize(in.normal);
    if (!front) { n = -n; }
    let diffuse = max(dot(n, view.light.xyz), 0.0);
    let lit = albedo.rgb * (0.25 + 0.75 * diffuse);
    return vec4<f32>(lit, 1.0);
}
