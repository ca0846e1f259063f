// SPDX-License-Identifier: MIT OR Apache-2.0
// One step of the pelting dynamics (Piponi & Borshukov §3-4) for every vertex of every piece: an
// invocation per vertex, all pieces in one dispatch, one dispatch per step (no barriers: llvmpipe
// runs a barrier-heavy loop inside one workgroup an invocation batch at a time: see src/pelt/gpu.rs). Per vertex:
// v <- damping * v + F(x) / m, x <- x + v, where F sums the vertex's edge springs (rest length,
// stiffness), its frame spring (zero rest length) and its pull towards the plane z = 0. Positions
// ping-pong between the two halves of `x` by `step.parity`; a steady piece only copies its
// positions across, so both halves stay equal. Dispatch: (ceil(vertices / 64), 1, 1).
// CPU twin: `relax_cpu` in src/pelt/relax.rs.
#import pelt

struct Step {
    parity: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

@group(0) @binding(0) var<uniform> step: Step;
@group(0) @binding(1) var<storage, read> pieces: array<Piece>;
// The piece of each vertex.
@group(0) @binding(2) var<storage, read> piece_of: array<u32>;
// Spring CSR over all pieces' vertices (global ids).
@group(0) @binding(3) var<storage, read> offsets: array<u32>;
@group(0) @binding(4) var<storage, read> other: array<u32>;
@group(0) @binding(5) var<storage, read> spring: array<vec2<f32>>;
// (frame x, frame y, plane-pull stiffness, frame stiffness) and 1 / mass per vertex.
@group(0) @binding(6) var<storage, read> anchor: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read> inv_mass: array<f32>;
// Positions: [0, total) and [total, 2 total); velocities.
@group(0) @binding(8) var<storage, read_write> x: array<vec4<f32>>;
@group(0) @binding(9) var<storage, read_write> v: array<vec4<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let total = arrayLength(&x) / 2u;
    let g = gid.x;
    if (g >= total) {
        return;
    }
    let cur = step.parity * total;
    let nxt = total - cur;
    let xi = x[cur + g];
    let piece = pieces[piece_of[g]];
    if (piece.steady != 0u) {
        x[nxt + g] = xi;
        return;
    }
    let a = anchor[g];
    var f = (vec3<f32>(a.xy, 0.0) - xi.xyz) * a.w - vec3<f32>(0.0, 0.0, xi.z * a.z);
    let k_end = offsets[g + 1u];
    for (var k = offsets[g]; k < k_end; k = k + 1u) {
        let d = x[cur + other[k]].xyz - xi.xyz;
        let l = length(d);
        if (l > 1e-12) {
            let sp = spring[k];
            f = f + d * (sp.y * (l - sp.x) / l);
        }
    }
    let vel = v[g].xyz * piece.damping + f * inv_mass[g];
    v[g] = vec4<f32>(vel, 0.0);
    x[nxt + g] = vec4<f32>(xi.xyz + vel, 0.0);
}
