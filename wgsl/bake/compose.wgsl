// SPDX-License-Identifier: MIT OR Apache-2.0
// Composes one rasterized layer rectangle into the linear accumulation buffer. Each texel averages its
// ss x ss samples over the samples that fell inside the UV island (so island-edge texels keep the
// island's colour instead of mixing in background), then blends with the layer's mode.
// Dispatch: (ceil(rect w / 8), ceil(rect h / 8), 1). CPU twin: `LayerRaster::texel` and `BlendMode::blend` in src/bake/cpu.rs (whole bake: `bake_cpu`).
#import params
#import blend
#import acc
#import window

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var layer_color: texture_2d<f32>;
@group(0) @binding(2) var layer_cov: texture_2d<f32>;
// Per layer (params.aux), `stats_stride` words; word 5 counts texels the layer changed.
@group(0) @binding(3) var<storage, read_write> stats: array<atomic<i32>>;

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

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= params.rect_size.x || gid.y >= params.rect_size.y) { return; }
    if (outside_edit(vec2<i32>(gid.xy) + params.rect_origin)) { return; }
    var sum = vec4<f32>(0.0);
    var n = 0.0;
    for (var j = 0u; j < params.ss; j++) {
        for (var i = 0u; i < params.ss; i++) {
            let p = vec2<i32>(params.atlas_origin + gid.xy * params.ss + vec2<u32>(i, j));
            let cov = textureLoad(layer_cov, p, 0).r;
            if (cov > 0.5) {
                sum += textureLoad(layer_color, p, 0);
                n += 1.0;
            }
        }
    }
    if (n == 0.0) { return; }
    let src = sum / n;
    if (src.a <= 0.0) { return; }
    let idx = win_index(vec2<i32>(gid.xy) + params.rect_origin);
    if (idx == 0xffffffffu) { return; }
    acc_store(idx, blend_any(params.blend, acc_load(idx), src, params.chan));
    atomicAdd(&stats[params.aux * params.stats_stride + 5u], 1);
}
