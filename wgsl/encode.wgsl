// SPDX-License-Identifier: MIT OR Apache-2.0
// Encodes the linear accumulation buffer to sRGB: 8 bits (one u32 per texel, RGBA8) or, with flag
// bit 2, 16 bits (two u32 per texel, RGBA16). Alpha stays linear. CPU twin: `LinearImage::encode_png`
// and `linear_to_srgb` in src/image_io.rs. Dispatch: (ceil(W / 8), ceil(H / 8), 1).
#import params
#import acc

const FLAG_16BIT: u32 = 4u;

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> packed: array<u32>;

fn to_srgb(c: f32) -> f32 {
    let x = clamp(c, 0.0, 1.0);
    if (x <= 0.0031308) { return x * 12.92; }
    return 1.055 * pow(x, 1.0 / 2.4) - 0.055;
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= params.tex_size.x || gid.y >= params.tex_size.y) { return; }
    let i = gid.y * params.tex_size.x + gid.x;
    let c = acc_load(i);
    // Row stride of `packed` in u32 words (rows padded to 256 bytes for texture copies).
    let row = gid.y * params.rect_size.x;
    let e = vec4<f32>(to_srgb(c.r), to_srgb(c.g), to_srgb(c.b), clamp(c.a, 0.0, 1.0));
    if ((params.flags & FLAG_16BIT) != 0u) {
        packed[row + 2u * gid.x] = pack2x16unorm(e.rg);
        packed[row + 2u * gid.x + 1u] = pack2x16unorm(e.ba);
    } else {
        packed[row + gid.x] = pack4x8unorm(e);
    }
}
