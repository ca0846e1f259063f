// SPDX-License-Identifier: MIT OR Apache-2.0
// Discrete exponential map update (Schmidt, Grimm & Wyvill 2006, eq. 2-3). Twins of `rotate_min` and
// `transfer` in src/geodesic.rs: keep the arithmetic in the same order.

// v rotated by the minimal rotation taking unit `n_from` onto unit `n_to`.
fn rotate_min(n_from: vec3<f32>, n_to: vec3<f32>, v: vec3<f32>) -> vec3<f32> {
    let a = cross(n_from, n_to);
    let c = dot(n_from, n_to);
    if (c <= -0.999999) { return -v; }
    return v * c + cross(a, v) + a * (dot(a, v) / (1.0 + c));
}

// The edge r -> q laid into r's tangent plane (length kept), turned into the seed's plane and read in
// the seed frame (e1, e2).
fn transfer(r: vec3<f32>, nr: vec3<f32>, q: vec3<f32>, seed_n: vec3<f32>, e1: vec3<f32>, e2: vec3<f32>) -> vec2<f32> {
    let d = q - r;
    let len = length(d);
    let t = d - nr * dot(d, nr);
    let tl = length(t);
    if (tl <= 0.0 || len <= 0.0) { return vec2<f32>(0.0); }
    let v = rotate_min(nr, seed_n, t * (len / tl));
    return vec2<f32>(dot(v, e1), dot(v, e2));
}
