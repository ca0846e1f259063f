// SPDX-License-Identifier: MIT OR Apache-2.0
// The end of a check interval of the pelting dynamics: per piece (one workgroup each), the mean
// squared speed of its vertices; below `check.tol2` the piece is steady and pelt_step.wgsl stops
// moving it. A piece that was still moving counts the interval's steps. Dispatch: (pieces, 1, 1).
// CPU twin: the check in `relax_cpu` (src/pelt/relax.rs).
#import pelt

struct Check {
    steps: u32,
    tol2: f32,
    _pad0: u32,
    _pad1: u32,
}

const WG: u32 = 64u;

@group(0) @binding(0) var<uniform> check: Check;
@group(0) @binding(1) var<storage, read_write> pieces: array<Piece>;
@group(0) @binding(2) var<storage, read> v: array<vec4<f32>>;

var<workgroup> sums: array<f32, WG>;

@compute @workgroup_size(64)
fn main(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let p = wid.x;
    let piece = pieces[p];
    var ke = 0.0;
    for (var i = lid; i < piece.n; i = i + WG) {
        let w = v[piece.v0 + i].xyz;
        ke = ke + dot(w, w);
    }
    sums[lid] = ke;
    workgroupBarrier();
    for (var h = WG / 2u; h > 0u; h = h / 2u) {
        if (lid < h) {
            sums[lid] = sums[lid] + sums[lid + h];
        }
        workgroupBarrier();
    }
    if (lid == 0u && piece.steady == 0u) {
        let mean = sums[0] / f32(max(piece.n, 1u));
        pieces[p].steps = piece.steps + check.steps;
        pieces[p].ke = mean;
        pieces[p].steady = select(0u, 1u, mean < check.tol2);
    }
}
