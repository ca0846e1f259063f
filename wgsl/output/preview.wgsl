// SPDX-License-Identifier: MIT OR Apache-2.0
// Preview: draws the textured mesh with a headlight and a little ambient light. Vertex buffers:
// position (vec3), normal (vec3), uv (vec2), a second uv (vec2), weights (vec2) and a third uv
// (vec2): the colour is w.x * baked(uv) + (1 - w.x - w.y) * second(uv2) + w.y * third(uv3),
// Piponi & Borshukov's blended rendering of a pelt and its patch (w.x = `_PELT_BLEND`), with the
// bridges over the patch's own seams where the seams have cycles (w.y = `_PELT_BRIDGE`,
// src/pelt/bridge.rs); a plain preview binds one texture three times with weights (1, 0).
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
@group(0) @binding(4) var third: texture_2d<f32>;

struct VsOut {
    @builtin(position) pos: vec4<f32>,
    @location(0) normal: vec3<f32>,
    @location(1) uv: vec2<f32>,
    @location(2) uv2: vec2<f32>,
    @location(3) weight: vec2<f32>,
    @location(4) uv3: vec2<f32>,
}

@vertex
fn vs_main(
    @location(0) pos: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
    @location(3) uv2: vec2<f32>,
    @location(4) weight: vec2<f32>,
    @location(5) uv3: vec2<f32>,
) -> VsOut {
    var o: VsOut;
    o.pos = view.view_proj * vec4<f32>(pos, 1.0);
    o.normal = normal;
    o.uv = uv;
    o.uv2 = uv2;
    o.weight = weight;
    o.uv3 = uv3;
    return o;
}

@fragment
fn fs_main(in: VsOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    let albedo = in.weight.x * textureSample(baked, samp, in.uv)
        + (1.0 - in.weight.x - in.weight.y) * textureSample(second, samp, in.uv2)
        + in.weight.y * textureSample(third, samp, in.uv3);
    var n = normalize(in.normal);
    if (!front) { n = -n; }
    let diffuse = max(dot(n, view.light.xyz), 0.0);
    let lit = albedo.rgb * (0.25 + 0.75 * diffuse);
    return vec4<f32>(lit, 1.0);
}
