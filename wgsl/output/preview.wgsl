// SPDX-License-Identifier: MIT OR Apache-2.0
// Preview: draws the textured mesh, shaded with the bake's PBR channels. Vertex buffers:
// position (vec3), normal (vec3), uv (vec2), a second uv (vec2), weights (vec2), a third uv
// (vec2) and the tangent (vec4: xyz and the bitangent's sign, glTF's TANGENT, on uv's set,
// src/mesh/tangents.rs). The colour is w.x * baked(uv) + (1 - w.x - w.y) * second(uv2) +
// w.y * third(uv3), Piponi & Borshukov's blended rendering of a pelt and its patch
// (w.x = `_PELT_BLEND`), with the bridges over the patch's own seams where the seams have cycles
// (w.y = `_PELT_BRIDGE`, src/pelt/bridge.rs); a plain preview binds one texture three times with
// weights (1, 0). The channels (normal, ORM, emissive) are the first texture's, weighted by w.x.
// Indexed by the split triangles.
//
// Shading model: glTF's metallic-roughness material (F0 = mix(0.04, albedo, metallic), diffuse
// colour albedo * (1 - metallic), alpha = roughness^2) lit by
// - Lambert diffuse from the key light plus a constant ambient, 0.25 + 0.75 * max(n.l, 0): the
//   preview's light before it had channels, unchanged, so a bake without any looks as it did;
// - Cook-Torrance specular from the key (0.75) and a fill light (0.3, specular only): GGX
//   (Trowbridge-Reitz) distribution, Smith-Schlick visibility (k = alpha / 2), Schlick Fresnel;
//   only with an ORM texture (without one: roughness 1, metallic 0 and no specular, the old
//   Lambert look exactly);
// - the ambient applied to the albedo (a dielectric's diffuse, a metal's F0), times occlusion;
// - plus emissive.
// The normal is the normal map's (tangent space: bitangent = cross(n, t.xyz) * t.w, +Y up the
// image; bytes decoded with 128 as 0, so a flat 8-bit texel is exactly flat) where the bake has
// one, else the interpolated normal.

struct View {
    view_proj: mat4x4<f32>,
    // xyz: towards the key light, the fill light and the camera (world space).
    light: vec4<f32>,
    fill: vec4<f32>,
    eye: vec4<f32>,
    // x: 1 with a normal map; y: the specular's weight (1 with an ORM texture).
    flags: vec4<f32>,
}

@group(0) @binding(0) var<uniform> view: View;
@group(0) @binding(1) var baked: texture_2d<f32>;
@group(0) @binding(2) var samp: sampler;
@group(0) @binding(3) var second: texture_2d<f32>;
@group(0) @binding(4) var third: texture_2d<f32>;
@group(0) @binding(5) var normal_map: texture_2d<f32>;
@group(0) @binding(6) var orm_map: texture_2d<f32>;
@group(0) @binding(7) var emissive_map: texture_2d<f32>;

const PI: f32 = 3.14159265;
const AMBIENT: f32 = 0.25;
const KEY: f32 = 0.75;
const FILL: f32 = 0.3;

struct VsOut {
    @builtin(position) pos: vec4<f32>,
    @location(0) normal: vec3<f32>,
    @location(1) uv: vec2<f32>,
    @location(2) uv2: vec2<f32>,
    @location(3) weight: vec2<f32>,
    @location(4) uv3: vec2<f32>,
    @location(5) tangent: vec4<f32>,
}

@vertex
fn vs_main(
    @location(0) pos: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
    @location(3) uv2: vec2<f32>,
    @location(4) weight: vec2<f32>,
    @location(5) uv3: vec2<f32>,
    @location(6) tangent: vec4<f32>,
) -> VsOut {
    var o: VsOut;
    o.pos = view.view_proj * vec4<f32>(pos, 1.0);
    o.normal = normal;
    o.uv = uv;
    o.uv2 = uv2;
    o.weight = weight;
    o.uv3 = uv3;
    o.tangent = tangent;
    return o;
}

// GGX specular of one light of irradiance `e` (pi * e: Lambert's albedo / pi then gives e * albedo):
// D * F * G / (4 n.l n.v) * n.l.
fn specular(n: vec3<f32>, v: vec3<f32>, l: vec3<f32>, alpha: f32, f0: vec3<f32>, e: f32) -> vec3<f32> {
    let nl = max(dot(n, l), 0.0);
    let nv = max(dot(n, v), 1e-4);
    let h = normalize(v + l);
    let a2 = alpha * alpha;
    let dn = max(dot(n, h), 0.0);
    let q = dn * dn * (a2 - 1.0) + 1.0;
    let d = a2 / (PI * q * q);
    let k = 0.5 * alpha;
    let vis = 1.0 / (4.0 * (nl * (1.0 - k) + k) * (nv * (1.0 - k) + k));
    let f = f0 + (1.0 - f0) * pow(1.0 - max(dot(v, h), 0.0), 5.0);
    return f * (d * vis * nl * PI * e);
}

@fragment
fn fs_main(in: VsOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    let albedo = (in.weight.x * textureSample(baked, samp, in.uv)
        + (1.0 - in.weight.x - in.weight.y) * textureSample(second, samp, in.uv2)
        + in.weight.y * textureSample(third, samp, in.uv3)).rgb;
    // Sampled outside the branch: textureSample needs uniform control flow.
    let nt = textureSample(normal_map, samp, in.uv).xyz;
    let orm = mix(vec3<f32>(1.0, 1.0, 0.0), textureSample(orm_map, samp, in.uv).xyz, in.weight.x);
    let emissive = in.weight.x * textureSample(emissive_map, samp, in.uv).rgb;
    var n = normalize(in.normal);
    if (view.flags.x > 0.5) {
        // The TBN frame (Gram-Schmidt), the map's normal in it, weighted as its texture is.
        let t = normalize(in.tangent.xyz - n * dot(n, in.tangent.xyz));
        let b = cross(n, t) * in.tangent.w;
        let m = clamp((nt * 255.0 - 128.0) / 127.0, vec3<f32>(-1.0), vec3<f32>(1.0));
        let ts = mix(vec3<f32>(0.0, 0.0, 1.0), m, in.weight.x);
        n = normalize(ts.x * t + ts.y * b + ts.z * n);
    }
    if (!front) { n = -n; }
    let metallic = orm.z;
    let alpha = max(orm.y * orm.y, 0.003);
    let f0 = mix(vec3<f32>(0.04), albedo, metallic);
    let v = view.eye.xyz;
    let diffuse = KEY * max(dot(n, view.light.xyz), 0.0) * (1.0 - metallic) * albedo;
    let spec = specular(n, v, view.light.xyz, alpha, f0, KEY)
        + specular(n, v, view.fill.xyz, alpha, f0, FILL);
    let lit = AMBIENT * orm.x * albedo + diffuse + view.flags.y * spec + emissive;
    return vec4<f32>(lit, 1.0);
}
