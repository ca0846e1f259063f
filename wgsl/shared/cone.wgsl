// SPDX-License-Identifier: MIT OR Apache-2.0
// The cone transform of a chart opened at a tip (FLAG_CONE): with rho = -e^(i cut) and
// q = (w - tip) conj(rho), z = beta + alpha rho q^k on the principal branch; the cut is the ray from
// the tip in direction `cut`. `a` = Params.cone_a (tip xy, k z, cut angle w), `b` = Params.cone_b
// (alpha xy, beta zw). CPU twin: `Cone` in src/maps/chart/cone.rs (`apply`, `cut_crosses`).

fn cone_cmul(x: vec2<f32>, y: vec2<f32>) -> vec2<f32> {
    return vec2<f32>(x.x * y.x - x.y * y.y, x.x * y.y + x.y * y.x);
}

fn cone_rho(a: vec4<f32>) -> vec2<f32> {
    return -vec2<f32>(cos(a.w), sin(a.w));
}

// q, with -0 as +0 in its imaginary part (a point on the cut's line lies on the same side as in
// the CPU twin; `select`, not `+ 0.0`, which a compiler may drop).
fn cone_q(a: vec4<f32>, w: vec2<f32>) -> vec2<f32> {
    let r = cone_rho(a);
    let q = cone_cmul(w - a.xy, vec2<f32>(r.x, -r.y));
    return vec2<f32>(q.x, select(q.y, 0.0, q.y == 0.0));
}

// The opened chart's coordinates of the uncut chart's point w.
fn cone_apply(a: vec4<f32>, b: vec4<f32>, w: vec2<f32>) -> vec2<f32> {
    let q = cone_q(a, w);
    let r = length(q);
    var raw = vec2<f32>(0.0);
    if (r > 0.0) {
        let t = a.z * atan2(q.y, q.x);
        let m = pow(r, a.z);
        raw = cone_cmul(cone_rho(a), vec2<f32>(m * cos(t), m * sin(t)));
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

// Whether the triangle lies near the tip: a corner closer to it (in the uncut chart) than the
// triangle's own extent. Its opened edges bend most; the selection keeps it without testing its box.
fn cone_near_tip(a: vec4<f32>, w0: vec2<f32>, w1: vec2<f32>, w2: vec2<f32>) -> bool {
    let ext = max(max(w0, w1), w2) - min(min(w0, w1), w2);
    let e = max(ext.x, ext.y);
    return min(min(length(w0 - a.xy), length(w1 - a.xy)), length(w2 - a.xy)) < e;
}
