// SPDX-License-Identifier: MIT OR Apache-2.0
// Placement through the mesh's BVH (src/mesh/bvh.rs): one invocation per query walks the tree,
// nearest child first, skipping boxes whose key (squared distance to the box for a point, entry
// distance for a ray) exceeds the best triangle key so far (by more than a rounding margin: ties
// are still visited, so the lower triangle wins as in the brute-force test). Writes the query's
// best (key, triangle) into its first partial slot and empties the others, so `place_reduce`
// finishes as after `place_candidates`. A walk longer than MAX_STEPS (a point equidistant from much
// of the mesh, as the centre of a sphere) stops and flags the query: `place_candidates` then tests
// every triangle for it (lavapipe abandons loops past 65,535 iterations).
// Dispatch: (ceil(queries / 64), 1, 1). CPU twin: `place_cpu_bvh` in src/place.rs (the same walk;
// `place_cpu` is the brute force both answer as).
#import geometry
#import bvh_node

const PLACE_GROUPS: u32 = 32u;
const NO_TRI: u32 = 0xffffffffu;
// The walk holds at most depth + 1 entries; `MAX_DEPTH` in src/mesh/bvh.rs keeps the tree below.
const STACK: u32 = 64u;
const MAX_STEPS: u32 = 50000u;


@group(0) @binding(0) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(1) var<storage, read> tris: array<vec4<u32>>;
@group(0) @binding(2) var<storage, read> queries: array<Query>;
@group(0) @binding(3) var<storage, read_write> partials: array<vec2<u32>>;
@group(0) @binding(4) var<storage, read> nodes: array<Node>;
@group(0) @binding(5) var<storage, read> leaf_tris: array<u32>;
// Per query: 1 = the walk was cut short, test every triangle (place_candidates).
@group(0) @binding(6) var<storage, read_write> brute: array<u32>;

fn better(a: vec2<u32>, b: vec2<u32>) -> vec2<u32> {
    if (b.x < a.x || (b.x == a.x && b.y < a.y)) { return b; }
    return a;
}

// The key of box (lo, hi) for query q: a lower bound of the key of every triangle inside.
fn box_key(q: Query, lo: vec3<f32>, hi: vec3<f32>) -> f32 {
    if (q.dir.w > 0.5) {
        // Slabs; a zero direction component becomes tiny, so a ray inside that slab spans it.
        let d = select(q.dir.xyz, vec3<f32>(1e-30), abs(q.dir.xyz) < vec3<f32>(1e-30));
        let inv = 1.0 / d;
        let t0 = (lo - q.origin.xyz) * inv;
        let t1 = (hi - q.origin.xyz) * inv;
        let tmin = max(max(min(t0.x, t1.x), min(t0.y, t1.y)), max(min(t0.z, t1.z), 0.0));
        let tmax = min(min(max(t0.x, t1.x), max(t0.y, t1.y)), max(t0.z, t1.z));
        if (tmax < tmin) { return bitcast<f32>(0x7f800000u); }
        return tmin;
    }
    let e = max(max(lo - q.origin.xyz, q.origin.xyz - hi), vec3<f32>(0.0));
    return dot(e, e);
}

// Whether a box with key k may hold a triangle at least as good as the best key `best_bits`.
fn worth(k: f32, best_bits: u32) -> bool {
    if (best_bits >= 0x7f800000u) { return k < bitcast<f32>(0x7f800000u); }
    let b = bitcast<f32>(best_bits);
    return k <= b * (1.0 + 1e-5) + 1e-30;
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let qi = gid.x;
    if (qi >= arrayLength(&queries)) { return; }
    let q = queries[qi];
    var best = vec2<u32>(0x7f800000u, NO_TRI);
    var stack: array<u32, STACK>;
    var sp = 0u;
    if (arrayLength(&nodes) > 0u && arrayLength(&leaf_tris) > 0u) {
        stack[0] = 0u;
        sp = 1u;
    }
    var steps = 0u;
    while (sp > 0u && steps < MAX_STEPS) {
        steps += 1u;
        sp -= 1u;
        let n = nodes[stack[sp]];
        if (!worth(box_key(q, n.lo, n.hi), best.x)) { continue; }
        if (n.count > 0u) {
            for (var i = 0u; i < n.count; i++) {
                let t = leaf_tris[n.first + i];
                let tri = tris[t];
                let key = candidate_key(q, positions[tri.x].xyz, positions[tri.y].xyz, positions[tri.z].xyz);
                let bits = bitcast<u32>(key);
                if (bits < 0x7f800000u) {
                    best = better(best, vec2<u32>(bits, t));
                }
            }
        } else {
            // Push the farther child first, so the nearer one is walked first.
            let a = nodes[n.first];
            let b = nodes[n.first + 1u];
            let ka = box_key(q, a.lo, a.hi);
            let kb = box_key(q, b.lo, b.hi);
            var near = n.first;
            var far = n.first + 1u;
            var kfar = kb;
            var knear = ka;
            if (kb < ka) {
                near = n.first + 1u;
                far = n.first;
                kfar = ka;
                knear = kb;
            }
            if (worth(kfar, best.x)) {
                stack[sp] = far;
                sp += 1u;
            }
            if (worth(knear, best.x)) {
                stack[sp] = near;
                sp += 1u;
            }
        }
    }
    brute[qi] = select(0u, 1u, sp > 0u);
    partials[qi * PLACE_GROUPS] = best;
    for (var g = 1u; g < PLACE_GROUPS; g++) {
        partials[qi * PLACE_GROUPS + g] = vec2<u32>(0x7f800000u, NO_TRI);
    }
}
