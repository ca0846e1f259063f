// SPDX-License-Identifier: MIT OR Apache-2.0
// The cone transform of a chart opened at a tip (FLAG_CONE): with q = -i (w - tip),
// z = beta + alpha * i * q^k on the principal branch; the cut is the ray from the tip along -y.
// `a` = Params.cone_a (tip xy, k z), `b` = Params.cone_b (alpha xy, beta zw).
// CPU twin: `Cone` in src/maps/chart/cone.rs (`apply`, `cut_crosses`).

fn cone_q(a: vec4<f32>, w: vec2<f32>) -> vec2<f32> {
    let d = w - a.xy;
    return vec2<f32>(d.y, -d.x);
}

fn cone_cmul(x: vec2<f32>, y: vec2<f32>) -> vec2<f32> {
    return vec2<f32>(x.x * y.x - x.y * y.y, x.x * y.y + x.y * y.x);
}

// The opened chart's coordinates of the uncut chart's point w.
fn cone_apply(a: vec4<f32>, b: vec4<f32>, w: vec2<f32>) -> vec2<f32> {
    let q = cone_q(a, w);
    let r = length(q);
    var raw = vec2<f32>(0.0);
    if (r > 0.0) {
        let t = a.z * atan2(q.y, q.x);
        let m = pow(r, a.z);
        raw = vec2<f32>(-m * sin(t), m * cos(t));
    }
    return cone_cmul(b.xy, raw) + b.zw;
}

// Whether the cut (q's negative real axis) crosses the triangle with uncut images w0, w1, w2.
fn cone_cut_crosses(a: vec4<f32>, w0: vec2<f32>, w1: vec2<f32>, w2: vec2<f32>) -> bool {
    let q = array<vec2<f32>, 3>(cone_q(a, w0), cone_q(a, w1), cone_q(a, w2));
    for (var i = 0u; i < 3u; i++) {
        let p = q[i];
        let s = q[(i + 1u) % 3u];
        if ((p.y >= 0.0) != (s.y >= 0.0)) {
            if (p.x + (s.x - p.x) * p.y / (p.y - s.y) < 0.0) { return true; }
        }
    }
    return false;
}
