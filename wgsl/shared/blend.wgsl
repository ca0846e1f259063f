// SPDX-License-Identifier: MIT OR Apache-2.0
// Blend modes (W3C Compositing and Blending Level 1, separable modes; "add" is linear dodge), applied
// in linear light; then the PBR channels' blends (BLEND_DATA_*, BLEND_NRM_*, `blend_any`). Ids keep in sync with `BlendMode` in src/bake/blend.rs (schema: `io::job::BlendMode`), which is also the CPU twin.
const BLEND_NORMAL: u32 = 0u;
const BLEND_MULTIPLY: u32 = 1u;
const BLEND_SCREEN: u32 = 2u;
const BLEND_OVERLAY: u32 = 3u;
const BLEND_ADD: u32 = 4u;
const BLEND_DARKEN: u32 = 5u;
const BLEND_LIGHTEN: u32 = 6u;
const BLEND_COLOR_DODGE: u32 = 7u;
const BLEND_COLOR_BURN: u32 = 8u;

fn blend_channel(mode: u32, cb: f32, cs: f32) -> f32 {
    switch mode {
        case 1u: { return cb * cs; }
        case 2u: { return cb + cs - cb * cs; }
        case 3u: {
            if (cb <= 0.5) { return 2.0 * cb * cs; }
            let s = 2.0 * cb - 1.0;
            return cs + s - cs * s;
        }
        case 4u: { return min(1.0, cb + cs); }
        case 5u: { return min(cb, cs); }
        case 6u: { return max(cb, cs); }
        case 7u: {
            if (cb <= 0.0) { return 0.0; }
            if (cs >= 1.0) { return 1.0; }
            return min(1.0, cb / (1.0 - cs));
        }
        case 8u: {
            if (cb >= 1.0) { return 1.0; }
            if (cs <= 0.0) { return 0.0; }
            return 1.0 - min(1.0, (1.0 - cb) / cs);
        }
        default: { return cs; }
    }
}

// Composes premultiplied source `src` over straight-alpha backdrop `dst`; returns straight alpha.
fn blend(mode: u32, dst: vec4<f32>, src: vec4<f32>) -> vec4<f32> {
    let as_ = src.a;
    if (as_ <= 0.0) { return dst; }
    let cs = src.rgb / as_;
    let ab = dst.a;
    let cb = dst.rgb;
    let mixed = vec3<f32>(blend_channel(mode, cb.r, cs.r), blend_channel(mode, cb.g, cs.g), blend_channel(mode, cb.b, cs.b));
    let ao = as_ + ab * (1.0 - as_);
    let co = (1.0 - as_) * ab * cb + (1.0 - ab) * as_ * cs + as_ * ab * mixed;
    if (ao <= 0.0) { return vec4<f32>(0.0); }
    return vec4<f32>(co / ao, ao);
}

// A data channel (roughness, metallic, occlusion): each output channel k mixes towards the
// source by the source's alpha times its weight w[k] (BLEND_DATA_MIX), or takes the source's value
// where that product is at least one half (BLEND_DATA_REPLACE). The backdrop's alpha is kept.
const BLEND_DATA_MIX: u32 = 16u;
const BLEND_DATA_REPLACE: u32 = 17u;
// A tangent-space normal channel, stored encoded (n * 0.5 + 0.5): the source's normal combined
// with the backdrop's by reoriented normal mapping (Barre-Brisebois & Hill 2012), UDN or
// replacement, then mixed by the source's alpha and renormalised.
const BLEND_NRM_RNM: u32 = 20u;
const BLEND_NRM_UDN: u32 = 21u;
const BLEND_NRM_REPLACE: u32 = 22u;

fn decode_normal(e: vec3<f32>) -> vec3<f32> {
    let n = e * 2.0 - 1.0;
    let l = length(n);
    if (l < 1e-12) { return vec3<f32>(0.0, 0.0, 1.0); }
    return n / l;
}

// n1: the base, n2: the detail (unit, tangent space).
fn normal_combine(mode: u32, n1: vec3<f32>, n2: vec3<f32>) -> vec3<f32> {
    switch mode {
        case 20u: {
            let t = n1 + vec3<f32>(0.0, 0.0, 1.0);
            let u = n2 * vec3<f32>(-1.0, -1.0, 1.0);
            return t * dot(t, u) / t.z - u;
        }
        case 21u: { return vec3<f32>(n1.xy + n2.xy, n1.z); }
        default: { return n2; }
    }
}

// A data channel's blend (BLEND_DATA_*), premultiplied `src` over `dst`; `w` weighs its outputs.
fn blend_data(mode: u32, dst: vec4<f32>, src: vec4<f32>, w: vec4<f32>) -> vec4<f32> {
    let a = src.a;
    if (a <= 0.0) { return dst; }
    let cs = src.rgb / a;
    if (mode == BLEND_DATA_REPLACE) {
        return vec4<f32>(select(dst.rgb, cs, a * w.rgb >= vec3<f32>(0.5)), dst.a);
    }
    return vec4<f32>(mix(dst.rgb, cs, clamp(a * w.rgb, vec3<f32>(0.0), vec3<f32>(1.0))), dst.a);
}

// A normal channel's blend (BLEND_NRM_*), premultiplied encoded `src` over encoded `dst`.
fn blend_normal(mode: u32, dst: vec4<f32>, src: vec4<f32>) -> vec4<f32> {
    let a = src.a;
    if (a <= 0.0) { return dst; }
    let cs = src.rgb / a;
    let n1 = decode_normal(dst.rgb);
    let n2 = decode_normal(cs);
    let r = normalize(normal_combine(mode, n1, n2));
    var n = mix(n1, r, min(a, 1.0));
    let l = length(n);
    n = select(r, n / l, l > 1e-6);
    return vec4<f32>(n * 0.5 + 0.5, dst.a);
}

// Any blend: colour modes (ids 0-8) by `blend`, data and normal channels by their own rules;
// `w` weighs a data channel's outputs (Params.chan). A kernel that knows its channel calls that
// channel's function instead: llvmpipe runs both sides of a branch it cannot prove uniform, so
// every mode here costs every texel that calls this.
fn blend_any(mode: u32, dst: vec4<f32>, src: vec4<f32>, w: vec4<f32>) -> vec4<f32> {
    if (mode < 16u) { return blend(mode, dst, src); }
    if (mode < BLEND_NRM_RNM) { return blend_data(mode, dst, src, w); }
    return blend_normal(mode, dst, src);
}
