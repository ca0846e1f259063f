// SPDX-License-Identifier: MIT OR Apache-2.0
// Placement, stage 2 of 2: one workgroup per layer reduces the per-group candidates and writes the
// placed point (triangle, barycentric coordinates, smooth normal). Dispatch: (layers, 1, 1).
#import geometry

// Keep in sync with `PLACE_GROUPS` in src/place.rs and place_candidates.wgsl.
const PLACE_GROUPS: u32 = 32u;
const NO_TRI: u32 = 0xffffffffu;

// Keep in sync with `PlaceResult` in src/place.rs.
struct PlaceResult {
    point: vec3<f32>,
    triangle: u32,
    bary: vec3<f32>,
    // Distance from the query point to the surface (point), or along the ray (ray).
    distance: f32,
    normal: vec3<f32>,
    found: u32,
}

@group(0) @binding(0) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(1) var<storage, read> tris: array<vec4<u32>>;
@group(0) @binding(2) var<storage, read> normals: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> queries: array<Query>;
@group(0) @binding(4) var<storage, read> partials: array<vec2<u32>>;
@group(0) @binding(5) var<storage, read_write> results: array<PlaceResult>;

var<workgroup> sh: array<vec2<u32>, PLACE_GROUPS>;

fn better(a: vec2<u32>, b: vec2<u32>) -> vec2<u32> {
    if (b.x < a.x || (b.x == a.x && b.y < a.y)) { return b; }
    return a;
}

@compute @workgroup_size(32)
fn main(@builtin(local_invocation_id) lid: vec3<u32>, @builtin(workgroup_id) wid: vec3<u32>) {
    let layer = wid.x;
    sh[lid.x] = partials[layer * PLACE_GROUPS + lid.x];
    workgroupBarrier();
    for (var s = PLACE_GROUPS / 2u; s > 0u; s >>= 1u) {
        if (lid.x < s) {
            sh[lid.x] = better(sh[lid.x], sh[lid.x + s]);
        }
        workgroupBarrier();
    }
    if (lid.x != 0u) { return; }
    let best = sh[0];
    var r: PlaceResult;
    r.found = 0u;
    r.triangle = NO_TRI;
    if (best.y != NO_TRI) {
        let q = queries[layer];
        let tri = tris[best.y];
        let a = positions[tri.x].xyz;
        let b = positions[tri.y].xyz;
        let c = positions[tri.z].xyz;
        var bc: vec3<f32>;
        if (q.dir.w > 0.5) {
            let h = ray_triangle(q.origin.xyz, q.dir.xyz, a, b, c);
            bc = vec3<f32>(1.0 - h.y - h.z, h.y, h.z);
            r.distance = h.x;
        } else {
            bc = closest_barycentric(q.origin.xyz, a, b, c);
            r.distance = sqrt(bitcast<f32>(best.x));
        }
        r.point = bc.x * a + bc.y * b + bc.z * c;
        r.bary = bc;
        r.triangle = best.y;
        let face = normalize(cross(b - a, c - a));
        let smooth_n = bc.x * normals[tri.x].xyz + bc.y * normals[tri.y].xyz + bc.z * normals[tri.z].xyz;
        if (dot(smooth_n, smooth_n) > 1e-12) {
            r.normal = normalize(smooth_n);
        } else {
            r.normal = face;
        }
        r.found = 1u;
    }
    results[layer] = r;
}
