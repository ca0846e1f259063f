// SPDX-License-Identifier: MIT OR Apache-2.0
// Blend modes (W3C Compositing and Blending Level 1, separable modes; "add" is linear dodge), applied
// in linear light. Ids keep in sync with `BlendMode` in src/bake/blend.rs (schema: `io::job::BlendMode`), which is also the CPU twin.
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
