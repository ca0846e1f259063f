// SPDX-License-Identifier: MIT OR Apache-2.0
// Layer coordinates by tangent-plane projection ("method": "planar"): each welded vertex gets its
// position in the decal's frame, in model units: (x along axis_u, y along axis_v, depth along the
// normal, valid). Valid when |depth| <= the depth limit. Dispatch: (ceil(vertices / 64), 1, 1).
// CPU twin: `planar_coords` in src/maps/planar.rs.
#import params

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> coords: array<vec4<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let v = gid.x;
    if (v >= params.vertex_count) { return; }
    let d = positions[v].xyz - params.center.xyz;
    let z = dot(d, params.normal.xyz);
    let valid = select(0.0, 1.0, abs(z) <= params.normal.w);
    coords[params.slot * params.vertex_count + v] = vec4<f32>(dot(d, params.axis_u.xyz), dot(d, params.axis_v.xyz), z, valid);
}
