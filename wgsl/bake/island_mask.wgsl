// SPDX-License-Identifier: MIT OR Apache-2.0
// Marks texels of a rasterized island rectangle: a texel is an island texel when any of its ss x ss
// samples is covered. Only ever sets 1, so overlapping rectangles (UV tiles) need no ordering; the
// first setter of a texel counts it in stats row `params.aux` (word 0).
// Dispatch: (ceil(rect w / 8), ceil(rect h / 8), 1). CPU twin: `islands_cpu` in src/bake/cpu.rs.
#import params
#import window

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var cov: texture_2d<f32>;
@group(0) @binding(2) var<storage, read_write> mask: array<atomic<u32>>;
@group(0) @binding(3) var<storage, read_write> stats: array<atomic<u32>>;

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= params.rect_size.x || gid.y >= params.rect_size.y) { return; }
    var any = false;
    for (var s = 0u; s < params.ss * params.ss; s++) {
        var p = gid.xy * params.ss + vec2<u32>(s % params.ss, s / params.ss);
        // The mip level, or the sample: signed, because naga's GLSL for an unsigned one calls
        // textureSize(sampler2D, uint), which GLSL does not have (wgpu's GL backend).
        var q = 0i;
        // The adaptive bake's variant (`gpu::shaders::msaa_kernel_source`): the texel's four
        // samples in its pixel, as the adaptive layer raster draws them.
        // MSAA: p = gid.xy;
        // MSAA: q = i32(s);
        any = any || textureLoad(cov, vec2<i32>(p), q).r > 0.5;
    }
    if (any) {
        let idx = win_index(vec2<i32>(gid.xy) + params.rect_origin);
        if (idx != 0xffffffffu && atomicExchange(&mask[idx], 1u) == 0u) {
            atomicAdd(&stats[params.aux * params.stats_stride], 1u);
        }
    }
}
