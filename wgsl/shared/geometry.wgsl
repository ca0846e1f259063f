// SPDX-License-Identifier: MIT OR Apache-2.0
// Geometry helpers shared by the placement kernels. CPU twin: `place_cpu` in src/place.rs.

// Closest point on triangle (a, b, c) to p, as barycentric coordinates (Ericson, Real-Time Collision
// Detection, 5.1.5: Voronoi regions of the vertices, edges and face).
fn closest_barycentric(p: vec3<f32>, a: vec3<f32>, b: vec3<f32>, c: vec3<f32>) -> vec3<f32> {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = dot(ab, ap);
    let d2 = dot(ac, ap);
    if (d1 <= 0.0 && d2 <= 0.0) { return vec3<f32>(1.0, 0.0, 0.0); }
    let bp = p - b;
    let d3 = dot(ab, bp);
    let d4 = dot(ac, bp);
    if (d3 >= 0.0 && d4 <= d3) { return vec3<f32>(0.0, 1.0, 0.0); }
    let vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
        let v = d1 / (d1 - d3);
        return vec3<f32>(1.0 - v, v, 0.0);
    }
    let cp = p - c;
    let d5 = dot(ab, cp);
    let d6 = dot(ac, cp);
    if (d6 >= 0.0 && d5 <= d6) { return vec3<f32>(0.0, 0.0, 1.0); }
    let vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
        let w = d2 / (d2 - d6);
        return vec3<f32>(1.0 - w, 0.0, w);
    }
    let va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return vec3<f32>(0.0, 1.0 - w, w);
    }
    let denom = 1.0 / (va + vb + vc);
    let v = vb * denom;
    let w = vc * denom;
    return vec3<f32>(1.0 - v - w, v, w);
}

// Ray / triangle intersection (Moller-Trumbore, both sides). Returns (t, u, v) with t < 0 for a miss.
fn ray_triangle(o: vec3<f32>, d: vec3<f32>, a: vec3<f32>, b: vec3<f32>, c: vec3<f32>) -> vec3<f32> {
    let e1 = b - a;
    let e2 = c - a;
    let pv = cross(d, e2);
    let det = dot(e1, pv);
    if (abs(det) < 1e-30) { return vec3<f32>(-1.0, 0.0, 0.0); }
    let inv = 1.0 / det;
    let tv = o - a;
    let u = dot(tv, pv) * inv;
    if (u < 0.0 || u > 1.0) { return vec3<f32>(-1.0, 0.0, 0.0); }
    let qv = cross(tv, e1);
    let v = dot(d, qv) * inv;
    if (v < 0.0 || u + v > 1.0) { return vec3<f32>(-1.0, 0.0, 0.0); }
    let t = dot(e2, qv) * inv;
    return vec3<f32>(t, u, v);
}

// Placement query: a point to snap (kind 0) or a ray (kind 1).
struct Query {
    origin: vec4<f32>,
    // xyz: ray direction (unit); w: 1.0 for a ray, 0.0 for a point.
    dir: vec4<f32>,
}

// Key of triangle `t` for query `q`: squared distance (point) or hit distance (ray); +inf = no candidate.
fn candidate_key(q: Query, a: vec3<f32>, b: vec3<f32>, c: vec3<f32>) -> f32 {
    if (q.dir.w > 0.5) {
        let h = ray_triangle(q.origin.xyz, q.dir.xyz, a, b, c);
        if (h.x >= 0.0) { return h.x; }
        return bitcast<f32>(0x7f800000u);
    }
    let bc = closest_barycentric(q.origin.xyz, a, b, c);
    let p = bc.x * a + bc.y * b + bc.z * c;
    let d = p - q.origin.xyz;
    return dot(d, d);
}
