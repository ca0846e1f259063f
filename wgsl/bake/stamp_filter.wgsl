// SPDX-License-Identifier: MIT OR Apache-2.0
// The tools' filters on the flat atlas (Maillot section 10), per stamp cell of FLAT_RES^2 texels:
// - mode 0, 1: separable Gaussian blur, horizontal (flat texture -> tmp) then vertical (tmp -> out),
//   weighted by the flat's alpha (alpha 0 = unknown canvas: outside the mesh under the stamp), each
//   cell with its own standard deviation in texels (sigmas[cell]), cut at 3 sigma and at the cell;
// - mode 2: smear: for each texel, the stamps of the dispatch in order, each carrying the previous
//   one's colour mixed by `strength` (out_k = strength * out_(k-1) + (1 - strength) * flat_k; the first
//   stamp of the stroke takes its flat), the carry kept in `carry` for the stroke's next chunk;
// - mode 3: clone: the cell copied as it is (the clone stamps read their source stamps' cells).
// Dispatch: modes 0, 1, 3: (cols * FLAT_RES / 8, rows * FLAT_RES / 8, 1); mode 2: (FLAT_RES / 8, FLAT_RES / 8, 1).
// CPU twins: `blur_cpu`, `smear_cpu` in src/bake/cpu.rs.

struct Dims {
    mode: u32,
    cells: u32,
    // Smear: f32 bits of the strength; 1 in `fresh` when the carry starts empty (the stroke's start).
    strength: u32,
    fresh: u32,
}

// Keep in sync with src/bake/params.rs.
const FLAT_RES: u32 = 64u;
const FLAT_COLS: u32 = 16u;

@group(0) @binding(0) var<uniform> dims: Dims;
@group(0) @binding(1) var flat: texture_2d<f32>;
@group(0) @binding(2) var<storage, read_write> tmp: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> out: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> sigmas: array<f32>;
@group(0) @binding(5) var<storage, read_write> carry: array<vec4<f32>>;

fn flat_at(cell: u32, x: u32, y: u32) -> vec4<f32> {
    let p = vec2<u32>((cell % FLAT_COLS) * FLAT_RES + x, (cell / FLAT_COLS) * FLAT_RES + y);
    return textureLoad(flat, p, 0);
}

fn idx(cell: u32, x: u32, y: u32) -> u32 {
    return (cell * FLAT_RES + y) * FLAT_RES + x;
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (dims.mode == 2u) {
        smear(gid.x, gid.y);
        return;
    }
    let cell = (gid.y / FLAT_RES) * FLAT_COLS + gid.x / FLAT_RES;
    if (cell >= dims.cells) { return; }
    let x = gid.x % FLAT_RES;
    let y = gid.y % FLAT_RES;
    if (dims.mode == 3u) {
        // Clone: the source stamp's flat as it is.
        out[idx(cell, x, y)] = flat_at(cell, x, y);
        return;
    }
    let sigma = max(sigmas[cell], 1e-3);
    let reach = i32(min(ceil(3.0 * sigma), f32(FLAT_RES - 1u)));
    var sum = vec3<f32>(0.0);
    var weight = 0.0;
    for (var d = -reach; d <= reach; d++) {
        let w = exp(-0.5 * f32(d * d) / (sigma * sigma));
        var c: vec4<f32>;
        if (dims.mode == 0u) {
            let xx = i32(x) + d;
            if (xx < 0 || xx >= i32(FLAT_RES)) { continue; }
            c = flat_at(cell, u32(xx), y);
        } else {
            let yy = i32(y) + d;
            if (yy < 0 || yy >= i32(FLAT_RES)) { continue; }
            c = tmp[idx(cell, x, u32(yy))];
        }
        sum += w * c.a * c.rgb;
        weight += w * c.a;
    }
    var r = vec4<f32>(0.0);
    if (weight > 0.0) { r = vec4<f32>(sum / weight, 1.0); }
    if (dims.mode == 0u) {
        tmp[idx(cell, x, y)] = r;
    } else {
        // Unknown texels stay unknown.
        if (flat_at(cell, x, y).a <= 0.0) { r = vec4<f32>(0.0); }
        out[idx(cell, x, y)] = r;
    }
}

fn smear(x: u32, y: u32) {
    if (x >= FLAT_RES || y >= FLAT_RES) { return; }
    let s = bitcast<f32>(dims.strength);
    var c = carry[y * FLAT_RES + x];
    if (dims.fresh == 1u) { c = vec4<f32>(0.0); }
    for (var k = 0u; k < dims.cells; k++) {
        let f = flat_at(k, x, y);
        if (c.a <= 0.0) {
            c = f;
        } else if (f.a > 0.0) {
            c = vec4<f32>(mix(f.rgb, c.rgb, s), 1.0);
        }
        out[idx(k, x, y)] = c;
    }
    carry[y * FLAT_RES + x] = c;
}
