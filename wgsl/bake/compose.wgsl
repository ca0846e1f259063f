// SPDX-License-Identifier: MIT OR Apache-2.0
// Composes one rasterized layer rectangle into the linear accumulation buffer. Each texel averages its
// ss x ss samples over the samples that fell inside the UV island (so island-edge texels keep the
// island's colour instead of mixing in background), then blends with the layer's mode. A texel of
// an 8 x 8 block the raster left empty (shared/blocks.wgsl) returns before loading any sample.
// Dispatch: (ceil(rect w / 8), ceil(rect h / 8), 1). CPU twin: `LayerRaster::texel` and `BlendMode::blend` in src/bake/cpu.rs (whole bake: `bake_cpu`).
#import params
#import blend
#import acc
#import window
#import blocks

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var layer_color: texture_2d<f32>;
@group(0) @binding(2) var layer_cov: texture_2d<f32>;
// Per layer (params.aux), `stats_stride` words; word 5 counts texels the layer changed.
@group(0) @binding(3) var<storage, read_write> stats: array<atomic<i32>>;
// The raster's block mask (shared/blocks.wgsl): a texel of a block left at 0 composes nothing.
@group(0) @binding(19) var<storage, read> blocks: array<u32>;

// The fused variant (`// FUSED: ` lines live; `gpu::shaders::fused_kernel_source`) composes the
// PBR channel groups drawn beside the colour by the fused raster (attachments 2 to 4 of
// layer_raster) into their canvases (planes 12 to 17), each as the separate channel pass's compose
// would: the same covered samples, averaged in the same order, blended by the channel's blend and
// data weights (`draws[params.draw.x]`; keep `ChannelDraw` in sync with layer_raster.wgsl and
// src/bake/channels.rs). Their texels are not counted: the colour's counts are the report's.
// FUSED: @group(0) @binding(4) var orm_color: texture_2d<f32>;
// FUSED: @group(0) @binding(5) var nrm_color: texture_2d<f32>;
// FUSED: @group(0) @binding(6) var emissive_color: texture_2d<f32>;
// FUSED: @group(0) @binding(12) var<storage, read_write> orm_rg: array<vec2<f32>>;
// FUSED: @group(0) @binding(13) var<storage, read_write> orm_ba: array<vec2<f32>>;
// FUSED: @group(0) @binding(14) var<storage, read_write> nrm_rg: array<vec2<f32>>;
// FUSED: @group(0) @binding(15) var<storage, read_write> nrm_ba: array<vec2<f32>>;
// FUSED: @group(0) @binding(16) var<storage, read_write> emissive_rg: array<vec2<f32>>;
// FUSED: @group(0) @binding(17) var<storage, read_write> emissive_ba: array<vec2<f32>>;
// Written out per group, without arrays indexed at run time (llvmpipe keeps those in memory).
// Each fused pipeline is made for its pass's groups (`gpu::shaders::with_groups`): PRESENT, those
// with a canvas; ATTACHED, those the raster drew attachments for. Every group's bits are masked by
// them, so a pipeline holds no code for a group its pass lacks: llvmpipe runs both sides of a
// branch it cannot prove uniform, and a group's loads and blend cost every texel otherwise.
// FUSED: const PRESENT: u32 = 7u;
// FUSED: const ATTACHED: u32 = 7u;

// Each raster entry's channel draws (keep in sync with `ChannelDraw` in layer_raster.wgsl and
// src/bake/channels.rs): bits.x the groups a unit paints, bits.z those drawn from a constant
// (`value`), bits.w those whose samples are the colour's alphas times the constant (a constant
// group at the colour's opacity: the fused raster draws no attachment for it). A group drawn from
// a constant composes as its value times the average of its samples' alphas, in every pass (a
// separate pass's entry has FLAG_CONSTANT, its group in params.draw.y), so the fused and separate
// passes give the same bytes whichever alphas they sum.
struct ChannelDraw { opacity: vec4<f32>, blend: vec4<u32>, bits: vec4<u32>, chan: array<vec4<f32>, 3>, value: array<vec4<f32>, 3> }
@group(0) @binding(18) var<storage, read> draws: array<ChannelDraw>;

// The constant `k` over samples whose alphas sum to `a`, averaged over `n` samples.
fn constant_average(k: vec4<f32>, a: f32, n: f32) -> vec4<f32> {
    return vec4<f32>(k.rgb * a, a) / n;
}

// The adaptive variant (`// MSAA: ` lines live and every texture multisampled;
// `gpu::shaders::msaa_kernel_source`) reads the raster's four samples of a texel from its pixel
// (layer_raster.wgsl's adaptive variant), where the grid's sit on an ss x ss block of pixels.

// Where sample `s` of texel `t` of this raster job lies in the atlas target, and the index
// textureLoad takes with it (a mip level, 0; the adaptive variant's sample index).
fn sample_point(t: vec2<u32>, s: u32) -> vec2<i32> {
    var p = params.atlas_origin + t * params.ss + vec2<u32>(s % params.ss, s / params.ss);
    // MSAA: p = params.atlas_origin + t;
    return vec2<i32>(p);
}

// The atlas texel (the raster's block mask's index) of texel `t` of this raster job.
fn atlas_texel(t: vec2<u32>) -> vec2<u32> {
    var a = params.atlas_origin / params.ss + t;
    // MSAA: a = params.atlas_origin + t;
    return a;
}

// Signed: naga's GLSL for an unsigned level or sample calls textureSize(sampler2D, uint), which
// GLSL does not have (wgpu's GL backend).
fn sample_arg(s: u32) -> i32 {
    var a = 0i;
    // MSAA: a = i32(s);
    return a;
}

// A live bake's edit (src/bake/live.rs): only the texels of the cells marked in the stats buffer's
// last row (laid out as a layer's cell mask) are composed; the rest of the canvas is already baked.
const FLAG_DIRTY: u32 = 2048u;

fn outside_edit(t: vec2<i32>) -> bool {
    if ((params.flags & FLAG_DIRTY) == 0u) { return false; }
    let c = (u32(t.y) / params.cell) * params.grid.x + u32(t.x) / params.cell;
    let row = arrayLength(&stats) / params.stats_stride - 1u;
    let w = u32(atomicLoad(&stats[row * params.stats_stride + 8u + c / 32u]));
    return ((w >> (c % 32u)) & 1u) == 0u;
}

// The canvas's blend: any mode in the plain kernel, which also composes a separate channel pass;
// a colour mode in the fused one, whose canvas is always the colour's.
fn blend_canvas(mode: u32, dst: vec4<f32>, src: vec4<f32>, w: vec4<f32>) -> vec4<f32> {
    var colour = false;
    // FUSED: colour = true;
    if (colour) { return blend(mode, dst, src); }
    return blend_any(mode, dst, src, w);
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= params.rect_size.x || gid.y >= params.rect_size.y) { return; }
    if (blocks[block_of(atlas_texel(gid.xy))] == 0u) { return; }
    if (outside_edit(vec2<i32>(gid.xy) + params.rect_origin)) { return; }
    var sum = vec4<f32>(0.0);
    var n = 0.0;
    // FUSED: let bits = draws[params.draw.x].bits.x & ~draws[params.draw.x].bits.w & ATTACHED;
    // FUSED: var s0 = vec4<f32>(0.0);
    // FUSED: var s1 = vec4<f32>(0.0);
    // FUSED: var s2 = vec4<f32>(0.0);
    for (var s = 0u; s < params.ss * params.ss; s++) {
        let p = sample_point(gid.xy, s);
        let q = sample_arg(s);
        let cov = textureLoad(layer_cov, p, q).r;
        if (cov > 0.5) {
            n += 1.0;
            // Covered only outside the layer's image (layer_raster.wgsl, COVERED_OUTSIDE):
            // every attachment holds zeros there, which add nothing.
            if (cov > 0.8) {
                sum += textureLoad(layer_color, p, q);
                // FUSED: if ((bits & 1u) != 0u) { s0 += textureLoad(orm_color, p, q); }
                // FUSED: if ((bits & 2u) != 0u) { s1 += textureLoad(nrm_color, p, q); }
                // FUSED: if ((bits & 4u) != 0u) { s2 += textureLoad(emissive_color, p, q); }
            }
        }
    }
    if (n == 0.0) { return; }
    let idx = win_index(vec2<i32>(gid.xy) + params.rect_origin);
    if (idx == 0xffffffffu) { return; }
    // FUSED: let d = &draws[params.draw.x];
    // FUSED: let painted = (*d).bits.x & PRESENT;
    // FUSED: let derived = (*d).bits.w & PRESENT;
    // FUSED: let constant = (*d).bits.z & PRESENT;
    // FUSED: if ((derived & 1u) != 0u) { s0 = vec4<f32>(sum.a); }
    // FUSED: if ((derived & 4u) != 0u) { s2 = vec4<f32>(sum.a); }
    // FUSED: if ((painted & 1u) != 0u) {
    // FUSED:     var s = s0 / n;
    // FUSED:     if ((constant & 1u) != 0u) { s = constant_average((*d).value[0], s0.a, n); }
    // FUSED:     if (s.a > 0.0) {
    // FUSED:         let c = blend_data((*d).blend.x, vec4<f32>(orm_rg[idx], orm_ba[idx]), s, (*d).chan[0]);
    // FUSED:         orm_rg[idx] = c.rg;
    // FUSED:         orm_ba[idx] = c.ba;
    // FUSED:     }
    // FUSED: }
    // FUSED: if ((painted & 2u) != 0u) {
    // FUSED:     let s = s1 / n;
    // FUSED:     if (s.a > 0.0) {
    // FUSED:         let c = blend_normal((*d).blend.y, vec4<f32>(nrm_rg[idx], nrm_ba[idx]), s);
    // FUSED:         nrm_rg[idx] = c.rg;
    // FUSED:         nrm_ba[idx] = c.ba;
    // FUSED:     }
    // FUSED: }
    // FUSED: if ((painted & 4u) != 0u) {
    // FUSED:     var s = s2 / n;
    // FUSED:     if ((constant & 4u) != 0u) { s = constant_average((*d).value[2], s2.a, n); }
    // FUSED:     if (s.a > 0.0) {
    // FUSED:         let c = blend((*d).blend.z, vec4<f32>(emissive_rg[idx], emissive_ba[idx]), s);
    // FUSED:         emissive_rg[idx] = c.rg;
    // FUSED:         emissive_ba[idx] = c.ba;
    // FUSED:     }
    // FUSED: }
    var src = sum / n;
    if ((params.flags & FLAG_CONSTANT) != 0u) {
        src = constant_average(draws[params.draw.x].value[params.draw.y], sum.a, n);
    }
    if (src.a <= 0.0) { return; }
    acc_store(idx, blend_canvas(params.blend, acc_load(idx), src, params.chan));
    atomicAdd(&stats[params.aux * params.stats_stride + 5u], 1);
}
