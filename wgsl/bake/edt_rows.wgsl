// SPDX-License-Identifier: MIT OR Apache-2.0
// Exact Euclidean distance transform, pass 2 of 2: per row, the lower envelope of the parabolas
// (x - q)^2 + g(q)^2 over columns q (g from pass 1) gives each texel its nearest island texel, written
// as a texel index (island texels point at themselves; 0xffffffff when there is no island at all).
// One invocation per row. Dispatch: (ceil(H / 64), 1, 1). CPU twin: `nearest_island` in
// src/bake/cpu.rs.
#import params

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> mask: array<u32>;
@group(0) @binding(2) var<storage, read> col_near: array<i32>;
@group(0) @binding(3) var<storage, read_write> env_v: array<i32>;
@group(0) @binding(4) var<storage, read_write> env_z: array<f32>;
@group(0) @binding(5) var<storage, read_write> nearest: array<u32>;

fn f_of(y: i32, w: u32, q: i32) -> i32 {
    let ny = col_near[u32(y) * w + u32(q)];
    if (ny < 0) { return -1; }
    let g = ny - y;
    return g * g;
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let w = params.tex_size.x;
    let h = params.tex_size.y;
    if (gid.x >= h) { return; }
    let y = i32(gid.x);
    let vb = gid.x * w;
    let zb = gid.x * (w + 1u);
    var k = -1;
    for (var q = 0; q < i32(w); q++) {
        let fq = f_of(y, w, q);
        if (fq < 0) { continue; }
        if (k < 0) {
            k = 0;
            env_v[vb] = q;
            env_z[zb] = -3.0e38;
            env_z[zb + 1u] = 3.0e38;
            continue;
        }
        var s = 0.0;
        loop {
            let vk = env_v[vb + u32(k)];
            let fv = f_of(y, w, vk);
            s = f32((fq + q * q) - (fv + vk * vk)) / f32(2 * (q - vk));
            if (s <= env_z[zb + u32(k)] && k > 0) {
                k -= 1;
            } else {
                break;
            }
        }
        if (s <= env_z[zb + u32(k)]) {
            // k == 0 and the new parabola dominates the first one everywhere.
            env_v[vb] = q;
            env_z[zb] = -3.0e38;
            env_z[zb + 1u] = 3.0e38;
            continue;
        }
        k += 1;
        env_v[vb + u32(k)] = q;
        env_z[zb + u32(k)] = s;
        env_z[zb + u32(k) + 1u] = 3.0e38;
    }
    if (k < 0) {
        for (var x = 0u; x < w; x++) { nearest[vb + x] = 0xffffffffu; }
        return;
    }
    var j = 0;
    for (var x = 0; x < i32(w); x++) {
        while (env_z[zb + u32(j) + 1u] < f32(x)) { j += 1; }
        let idx = vb + u32(x);
        if (mask[idx] != 0u) {
            nearest[idx] = idx;
            continue;
        }
        let vx = env_v[vb + u32(j)];
        let ny = col_near[vb + u32(vx)];
        nearest[idx] = u32(ny) * w + u32(vx);
    }
}
