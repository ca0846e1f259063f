// SPDX-License-Identifier: MIT OR Apache-2.0
// Distortion of a layer's map over the triangles it covers: for each triangle, the singular values
// s1 >= s2 of the Jacobian from the triangle's own plane to the layer's (u, v) coordinates. Area ratio
// s1 s2 (signed: negative means the triangle is flipped), angle distortion s1 / s2; a triangle not
// flipped whose ratio is below COLLAPSED counts as collapsed, one whose |ratio| exceeds 1 / COLLAPSED
// as torn (the maps are in model units: 1 is an isometry). Each workgroup reduces its triangles
// (area-weighted sums, extremes, counts) into one partial; the host adds the partials in order. Dispatch: (DIST_GROUPS, 1, 1) per layer. CPU twin: `distortion` in src/maps/distortion.rs.
#import params
#import cone

const WG: u32 = 64u;
// Keep in sync with `DIST_GROUPS` in src/maps/distortion.rs.
const DIST_GROUPS: u32 = 16u;

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> tris: array<vec4<u32>>;
@group(0) @binding(3) var<storage, read> coords: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> lists: array<u32>;
@group(0) @binding(5) var<storage, read> stats: array<i32>;
// Per (slot, group), three vec4: (sum area, sum area * ratio, sum area * angle, flipped),
// (max angle, max ratio, min ratio, unused), (collapsed, torn, 0, 0).
@group(0) @binding(6) var<storage, read_write> partials: array<vec4<f32>>;
// Keep in sync with `COLLAPSED_RATIO` in src/maps/distortion.rs.
const COLLAPSED: f32 = 1e-3;

var<workgroup> sh_a: array<vec4<f32>, WG>;
var<workgroup> sh_b: array<vec4<f32>, WG>;
var<workgroup> sh_c: array<vec4<f32>, WG>;

@compute @workgroup_size(64)
fn main(@builtin(local_invocation_id) lid: vec3<u32>, @builtin(workgroup_id) wid: vec3<u32>) {
    let count = u32(max(stats[params.aux * params.stats_stride], 0));
    var a = vec4<f32>(0.0);
    var b = vec4<f32>(0.0, 0.0, 3.0e38, 0.0);
    var c = vec4<f32>(0.0);
    let base = params.slot * params.vertex_count;
    for (var i = wid.x * WG + lid.x; i < count; i += DIST_GROUPS * WG) {
        let t = tris[lists[params.slot * params.triangle_count + i]];
        let p0 = positions[t.x].xyz;
        let e1 = positions[t.y].xyz - p0;
        let e2 = positions[t.z].xyz - p0;
        let n = cross(e1, e2);
        let area = 0.5 * length(n);
        let l1 = length(e1);
        if (area <= 0.0 || l1 <= 0.0) { continue; }
        let x = e1 / l1;
        let y = normalize(cross(n, x));
        // Triangle in its own plane: columns P1 = (l1, 0), P2 = (e2.x, e2.y).
        let q2 = vec2<f32>(dot(e2, x), dot(e2, y));
        var c0 = coords[base + t.x].xy;
        var c1 = coords[base + t.y].xy;
        var c2 = coords[base + t.z].xy;
        if ((params.flags & FLAG_CONE) != 0u) {
            // A cone chart: measured opened; the cut's triangles are left out (drawn per fragment).
            if (cone_cut_crosses(params.cone_a, c0, c1, c2)) { continue; }
            c0 = cone_apply(params.cone_a, params.cone_b, c0);
            c1 = cone_apply(params.cone_a, params.cone_b, c1);
            c2 = cone_apply(params.cone_a, params.cone_b, c2);
        }
        let d1 = c1 - c0;
        let d2 = c2 - c0;
        // M = [d1 d2] * inverse([(l1, 0) q2]).
        let inv_det = 1.0 / (l1 * q2.y);
        let m00 = (d1.x * q2.y) * inv_det;
        let m10 = (d1.y * q2.y) * inv_det;
        let m01 = (d2.x * l1 - d1.x * q2.x) * inv_det;
        let m11 = (d2.y * l1 - d1.y * q2.x) * inv_det;
        let det = m00 * m11 - m01 * m10;
        // Singular values of a 2x2 matrix without cancellation: (sqrt(p) +- sqrt(q)) / 2.
        let p = sqrt((m00 + m11) * (m00 + m11) + (m10 - m01) * (m10 - m01));
        let q = sqrt((m00 - m11) * (m00 - m11) + (m10 + m01) * (m10 + m01));
        let s1 = 0.5 * (p + q);
        let s2 = 0.5 * abs(p - q);
        let angle = select(3.0e38, s1 / s2, s2 > 0.0);
        let ratio = det;
        a += vec4<f32>(area, area * ratio, area * min(angle, 1.0e6), select(0.0, 1.0, det < 0.0));
        b = vec4<f32>(max(b.x, angle), max(b.y, ratio), min(b.z, ratio), 0.0);
        c += vec4<f32>(select(0.0, 1.0, det >= 0.0 && det < COLLAPSED),
                       select(0.0, 1.0, abs(det) > 1.0 / COLLAPSED), 0.0, 0.0);
    }
    sh_a[lid.x] = a;
    sh_b[lid.x] = b;
    sh_c[lid.x] = c;
    workgroupBarrier();
    for (var s = WG / 2u; s > 0u; s >>= 1u) {
        if (lid.x < s) {
            sh_a[lid.x] += sh_a[lid.x + s];
            sh_c[lid.x] += sh_c[lid.x + s];
            let o = sh_b[lid.x + s];
            let m = sh_b[lid.x];
            sh_b[lid.x] = vec4<f32>(max(m.x, o.x), max(m.y, o.y), min(m.z, o.z), 0.0);
        }
        workgroupBarrier();
    }
    if (lid.x == 0u) {
        let k = 3u * (params.slot * DIST_GROUPS + wid.x);
        partials[k] = sh_a[0];
        partials[k + 1u] = sh_b[0];
        partials[k + 2u] = sh_c[0];
    }
}
