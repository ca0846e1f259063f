// SPDX-License-Identifier: MIT OR Apache-2.0
// Continuous stamp charts (Maillot section 7): each stamp's coordinates interpolated from the charts
// of its triangle's corners, each moved so the stamp's point is the origin and turned by the angle of
// the stamp's x axis in the corner's frame: C(x) = sum_k w_k R(-theta_k) (C_k(x) - sum_j b_j C_k(corner_j)).
// Valid where every chart is. One record of 9 vec4 per stamp (see `blend_pass` in src/bake/maps.rs):
// [0] = (destination slot, charts, first, count), [1] = corners, [2] = barycentric (f32 bits),
// [3 + k] = (chart slot, weight, cos theta, sin theta) (f32 bits but the slot). The vertices
// written are `verts[first .. first + count]` (the charts' reach, src/bake/maps.rs; the slot is zero
// elsewhere, cleared before the chunk), or every vertex where `first` is ALL_VERTICES.
// Dispatch: (ceil(most vertices of a stamp / 64), stamps from `first`, at most 65,535, 1).
// CPU twin: `maps::stamp::blend_cpu` (every vertex).

struct Dims {
    vertex_count: u32,
    stamps: u32,
    // First stamp of this dispatch (dispatches hold at most 65,535 stamps).
    first: u32,
    _pad: u32,
}

@group(0) @binding(0) var<uniform> dims: Dims;
@group(0) @binding(1) var<storage, read> records: array<vec4<u32>>;
@group(0) @binding(2) var<storage, read_write> coords: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> verts: array<u32>;

const ALL_VERTICES: u32 = 0xffffffffu;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let stamp = dims.first + gid.y;
    if (stamp >= dims.stamps) { return; }
    let r = stamp * 9u;
    let head = records[r];
    var x = gid.x;
    if (head.z == ALL_VERTICES) {
        if (x >= dims.vertex_count) { return; }
    } else {
        if (x >= head.w) { return; }
        x = verts[head.z + x];
    }
    let corners = records[r + 1u].xyz;
    let bary = bitcast<vec3<f32>>(records[r + 2u].xyz);
    let nv = dims.vertex_count;
    // Most vertices lie outside the charts: one read each rejects them.
    for (var k = 0u; k < head.y; k++) {
        if (coords[records[r + 3u + k].x * nv + x].w < 0.5) {
            coords[head.x * nv + x] = vec4<f32>(0.0);
            return;
        }
    }
    var acc = vec2<f32>(0.0);
    for (var k = 0u; k < head.y; k++) {
        let e = records[r + 3u + k];
        let base = e.x * nv;
        let c = coords[base + x];
        let centre = bary.x * coords[base + corners.x].xy + bary.y * coords[base + corners.y].xy
            + bary.z * coords[base + corners.z].xy;
        let w = bitcast<f32>(e.y);
        let co = bitcast<f32>(e.z);
        let s = bitcast<f32>(e.w);
        let d = c.xy - centre;
        acc += w * vec2<f32>(co * d.x + s * d.y, -s * d.x + co * d.y);
    }
    coords[head.x * nv + x] = vec4<f32>(acc, 0.0, 1.0);
}
