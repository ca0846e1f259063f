// SPDX-License-Identifier: MIT OR Apache-2.0
// Discrete exponential map updates: the paper's (Schmidt, Grimm & Wyvill 2006, eq. 2-3: `transfer`)
// and the smooth mode's second-order step (`smooth_step`; see `Accuracy::Smooth` in
// src/maps/expmap/cpu.rs). Twins of the functions of the same names in src/maps/expmap/cpu.rs: keep the arithmetic
// in the same order.

// v rotated by the minimal rotation taking unit `n_from` onto unit `n_to`.
fn rotate_min(n_from: vec3<f32>, n_to: vec3<f32>, v: vec3<f32>) -> vec3<f32> {
    let a = cross(n_from, n_to);
    let c = dot(n_from, n_to);
    if (c <= -0.999999) { return -v; }
    return v * c + cross(a, v) + a * (dot(a, v) / (1.0 + c));
}

// Jacobi field (G, G') advanced by `dr` through curvature `k` (exact for constant curvature). Twin of
// `jacobi_step` in src/maps/expmap/cpu.rs.
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
// of `smooth_increment` in src/maps/expmap/cpu.rs.
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

// x's smooth-mode state (G, G', frame angle, 0) once its coordinates `c` are known; `carried` is
// y's frame angle carried across the edge. See `smooth_step` in src/maps/expmap/cpu.rs.
fn smooth_state(cy: vec2<f32>, sy: vec4<f32>, km: f32, carried: f32, orient: f32, c: vec2<f32>) -> vec4<f32> {
    let ry = sqrt(cy.x * cy.x + cy.y * cy.y);
    let r = sqrt(c.x * c.x + c.y * c.y);
    let g = jacobi_step(sy.xy, km, r - ry);
    var dtheta = 0.0;
    if (ry > 1.0e-12 && r > 1.0e-12) {
        dtheta = atan2(cy.x * c.y - cy.y * c.x, cy.x * c.x + cy.y * c.y);
    }
    let alpha = carried - orient * dtheta * (1.0 - 0.5 * (sy.y + g.y));
    return vec4<f32>(g.x, g.y, alpha, 0.0);
}

// Chart vector of an edge of length `len` whose intrinsic angle is `t` at a vertex with frame angle
// `alpha`.
fn edge_dir(len: f32, t: f32, alpha: f32, orient: f32) -> vec2<f32> {
    let a = orient * (t - alpha);
    return vec2<f32>(len * cos(a), len * sin(a));
}

struct SmoothOut {
    uv: vec2<f32>,
    state: vec4<f32>,
}

const PI: f32 = 3.14159265358979;

// One step of the smooth mode from upwind y to x (intrinsic frame carried across the edge,
// trapezoidal rule with a predictor). Twin of `smooth_step` in src/maps/expmap/cpu.rs: same operations in
// the same order.
fn smooth_step(cy: vec2<f32>, sy: vec4<f32>, ky: f32, kx: f32, len: f32, ty: f32, tx: f32, orient: f32) -> SmoothOut {
    let km = 0.5 * (ky + kx);
    let carried = sy.z + tx + PI - ty;
    let iy = smooth_increment(cy, sy.x, edge_dir(len, ty, sy.z, orient));
    let pred = vec2<f32>(cy.x + iy.x, cy.y + iy.y);
    let sp = smooth_state(cy, sy, km, carried, orient, pred);
    let ix = smooth_increment(pred, sp.x, edge_dir(len, tx + PI, sp.z, orient));
    let c = vec2<f32>(cy.x + 0.5 * (iy.x + ix.x), cy.y + 0.5 * (iy.y + ix.y));
    var out: SmoothOut;
    out.uv = c;
    out.state = smooth_state(cy, sy, km, carried, orient, c);
    return out;
}
