// SPDX-License-Identifier: MIT OR Apache-2.0
// Pads and encodes. Padding: a background texel whose nearest island texel (exact distance transform,
// see edt_rows.wgsl) lies within `params.aux` texels (0xffffffff = any distance) takes that texel's
// colour. Encoding: sRGB (or, with FLAG_LINEAR, as stored: a data or normal channel), 8 bits (one
// u32 per texel, RGBA8, by the exact quantiser's table) or, with flag bit 2, 16 bits (two u32 per
// texel, RGBA16), rows `rect_size.x` words apart; alpha stays linear. Over the canvas window only
// (shared/window.wgsl). CPU twins: `nearest_island` in src/bake/cpu.rs, `linear_to_srgb` in
// src/io/image.rs; the 8-bit bytes exactly: `finish::pad_and_encode_host` (src/bake/finish.rs),
// which a CPU adapter takes instead. Dispatch: (ceil(W / 8), ceil(H / 8), 1), or
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
// The 8-bit quantiser's table (src/bake/finish.rs, `Quantiser`): per curve (sRGB, linear) 257
// thresholds as f32 bits, then per curve the byte at the start of each of 4096 cells and at 1.
@group(0) @binding(4) var<storage, read> quant: array<u32>;

const THRESHOLDS: u32 = 257u;
const CELLS: u32 = 4096u;

// `x`'s byte on `curve` (0 sRGB, 1 linear): the thresholds at or below it, counted in two loads
// (the twin: `Quantiser::quantise`), the same bytes on every device.
fn quantise(x: f32, curve: u32) -> u32 {
    let v = clamp(x, 0.0, 1.0);
    let k = quant[2u * THRESHOLDS + curve * (CELLS + 1u) + u32(v * f32(CELLS))];
    let next = bitcast<f32>(quant[curve * THRESHOLDS + k + 1u]);
    return k + select(0u, 1u, v >= next);
}

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
    if (WIDE) {
        var e = clamp(c, vec4<f32>(0.0), vec4<f32>(1.0));
        if (!LINEAR) {
            e = vec4<f32>(to_srgb(c.r), to_srgb(c.g), to_srgb(c.b), e.a);
        }
        packed[row + 2u * g.x] = pack2x16unorm(e.rg);
        packed[row + 2u * g.x + 1u] = pack2x16unorm(e.ba);
    } else {
        let curve = select(0u, 1u, LINEAR);
        packed[row + g.x] = quantise(c.r, curve) | (quantise(c.g, curve) << 8u)
            | (quantise(c.b, curve) << 16u) | (quantise(c.a, 1u) << 24u);
    }
}
