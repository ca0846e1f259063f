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

// Jacobi field (G, G') advanced by `dr` through curvature `k` (exact for constant curvature). Twin of
// `jacobi_step` in src/geodesic.rs.
fn jacobi_step(g: vec2<f32>, k: f32, dr: f32) -> vec2<f32> {
    if (k > 1.0e-12) {
        let w = sqrt(k);
        let sn = sin(w * dr);
        let cs = cos(w * dr);
        return vec2<f32>(g.x * cs + g.y * sn / w, g.y * cs - g.x * w * sn);
    } else if (k < -1.0e-12) {
        let w = sqrt(-k);
        let e = exp(w * dr);
        let ei = exp(-w * dr);
        let sn = 0.5 * (e - ei);
        let cs = 0.5 * (e + ei);
        return vec2<f32>(g.x * cs + g.y * sn / w, g.y * cs + g.x * w * sn);
    }
    return vec2<f32>(g.x + g.y * dr, g.y);
}

// The smooth mode's increment: `t` with its component perpendicular to `c` scaled by |c| / g. Twin
// of `smooth_increment` in src/geodesic.rs.
fn smooth_increment(c: vec2<f32>, g: f32, t: vec2<f32>) -> vec2<f32> {
    let r = sqrt(c.x * c.x + c.y * c.y);
    if (r <= 1.0e-12 || g <= 1.0e-12) { return t; }
    let u = vec2<f32>(c.x / r, c.y / r);
    let w = vec2<f32>(-u.y, u.x);
    let k = r / g;
    let a = t.x * u.x + t.y * u.y;
    let b = k * (t.x * w.x + t.y * w.y);
    return vec2<f32>(u.x * a + w.x * b, u.y * a + w.y * b);
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
