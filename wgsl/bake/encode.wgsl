// SPDX-License-Identifier: MIT OR Apache-2.0
// Pads and encodes. Padding: a background texel whose nearest island texel (exact distance transform,
// see edt_rows.wgsl) lies within `params.aux` texels (0xffffffff = any distance) takes that texel's
// colour. Encoding: sRGB (or, with FLAG_LINEAR, as stored: a data or normal channel), 8 bits (one u32 per texel, RGBA8) or, with flag bit 2, 16 bits (two u32 per
// texel, RGBA16), rows `rect_size.x` words apart; alpha stays linear. Over the canvas window only
// (shared/window.wgsl). CPU twins: `nearest_island` in
// src/bake/cpu.rs, `linear_to_srgb` in src/io/image.rs. Dispatch: (ceil(W / 8), ceil(H / 8), 1), or
// over a region of the window (a live bake's edit: `region_texel` in shared/window.wgsl).
#import params
#import acc
#import window

const FLAG_16BIT: u32 = 4u;
// A tile of a tiled bake: no padding here (src/bake/tiles.rs pads the whole texture on the CPU).
const FLAG_NO_PAD: u32 = 32u;

// Each output's pipeline is made with its own (`gpu::shaders::encode_source`): linear (a data or
// normal channel, FLAG_LINEAR) and 16-bit (FLAG_16BIT). Constants, not the flags, choose: llvmpipe
// runs both sides of a branch it cannot prove uniform, so a runtime choice costs every texel the
// sRGB curve and both stores.
const LINEAR: bool = false;
const WIDE: bool = false;

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> packed: array<u32>;
@group(0) @binding(2) var<storage, read> mask: array<u32>;
@group(0) @binding(3) var<storage, read> nearest: array<u32>;

fn to_srgb(c: f32) -> f32 {
    let x = clamp(c, 0.0, 1.0);
    if (x <= 0.0031308) { return x * 12.92; }
    return 1.055 * pow(x, 1.0 / 2.4) - 0.055;
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    // The canvas window's texels (the whole texture unless this is a tile, shared/window.wgsl).
    let size = win_size();
    let g = region_texel(gid.xy);
    if (g.x == 0xffffffffu) { return; }
    let w = size.x;
    let i = g.y * w + g.x;
    var src = i;
    if ((params.flags & FLAG_NO_PAD) == 0u && mask[i] == 0u) {
        let n = nearest[i];
        if (n != 0xffffffffu) {
            let dx = i32(n % w) - i32(g.x);
            let dy = i32(n / w) - i32(g.y);
            let d2 = u32(dx * dx + dy * dy);
            if (params.aux == 0xffffffffu || d2 <= params.aux * params.aux) {
                src = n;
            }
        }
    }
    let c = acc_load(src);
    // Row stride of `packed` in u32 words (rows padded to 256 bytes for texture copies).
    let row = g.y * params.rect_size.x;
    var e = clamp(c, vec4<f32>(0.0), vec4<f32>(1.0));
    if (!LINEAR) {
        e = vec4<f32>(to_srgb(c.r), to_srgb(c.g), to_srgb(c.b), e.a);
    }
    if (WIDE) {
        packed[row + 2u * g.x] = pack2x16unorm(e.rg);
        packed[row + 2u * g.x + 1u] = pack2x16unorm(e.ba);
    } else {
        packed[row + g.x] = pack4x8unorm(e);
    }
}
