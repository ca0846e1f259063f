// SPDX-License-Identifier: MIT OR Apache-2.0
// Placement, stage 1 of 2, brute force: every triangle is tested against a layer's query (closest
// point or ray hit); each workgroup reduces its triangles to the best (key, triangle) pair in a
// fixed order. Only for the queries flagged in `brute` (all of them for the whole-mesh reference;
// otherwise those whose BVH walk in place_bvh was cut short); the others return at once.
// Dispatch: (PLACE_GROUPS, layers, 1). CPU twin: `place_cpu` in src/place.rs.
#import geometry

const WG: u32 = 64u;
// Keep in sync with `PLACE_GROUPS` in src/place.rs.
const PLACE_GROUPS: u32 = 32u;
const NO_TRI: u32 = 0xffffffffu;

@group(0) @binding(0) var<storage, read> positions: array<vec4<f32>>;
// Welded triangles; w bit 0 = degenerate.
@group(0) @binding(1) var<storage, read> tris: array<vec4<u32>>;
@group(0) @binding(2) var<storage, read> queries: array<Query>;
// (key bits, triangle) per (layer, group).
@group(0) @binding(3) var<storage, read_write> partials: array<vec2<u32>>;
@group(0) @binding(4) var<storage, read> brute: array<u32>;

var<workgroup> sh: array<vec2<u32>, WG>;
var<workgroup> flagged: u32;

fn better(a: vec2<u32>, b: vec2<u32>) -> vec2<u32> {
    if (b.x < a.x || (b.x == a.x && b.y < a.y)) { return b; }
    return a;
}

@compute @workgroup_size(64)
fn main(@builtin(local_invocation_id) lid: vec3<u32>, @builtin(workgroup_id) wid: vec3<u32>) {
    let layer = wid.y;
    if (lid.x == 0u) { flagged = brute[layer]; }
    if (workgroupUniformLoad(&flagged) == 0u) { return; }
    let q = queries[layer];
    let n = arrayLength(&tris);
    var best = vec2<u32>(0x7f800000u, NO_TRI);
    for (var t = wid.x * WG + lid.x; t < n; t += PLACE_GROUPS * WG) {
        let tri = tris[t];
        if ((tri.w & 1u) != 0u) { continue; }
        let key = candidate_key(q, positions[tri.x].xyz, positions[tri.y].xyz, positions[tri.z].xyz);
        let bits = bitcast<u32>(key);
        // +inf (a ray miss) or NaN is never a candidate.
        if (bits < 0x7f800000u) {
            best = better(best, vec2<u32>(bits, t));
        }
    }
    sh[lid.x] = best;
    workgroupBarrier();
    for (var s = WG / 2u; s > 0u; s >>= 1u) {
        if (lid.x < s) {
            sh[lid.x] = better(sh[lid.x], sh[lid.x + s]);
        }
        workgroupBarrier();
    }
    if (lid.x == 0u) {
        partials[layer * PLACE_GROUPS + wid.x] = sh[0];
    }
}
