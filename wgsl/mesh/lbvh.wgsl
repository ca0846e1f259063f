// SPDX-License-Identifier: MIT OR Apache-2.0
// The mesh's BVH built on the GPU as a linear BVH (Karras 2012, "Maximizing parallelism in the
// construction of BVHs, octrees, and k-d trees"), in the node layout `place_bvh` walks
// (src/mesh/bvh.rs: a node's two children side by side, leaves of at most four triangles).
// Entry points, in order (src/mesh/lbvh.rs dispatches them; CPU twin `lbvh::build_cpu`):
//   morton   one per padded entry: the 30-bit Morton code of the triangle's vertex sum on a grid
//            whose cell is a power of two (exact arithmetic: adds, a subtraction, a product by a
//            power of two, so every conforming driver gives the twin's codes), key (code, triangle)
//   bitonic  one per pair, per step (k, j) of a bitonic sort of the keys (unique: the triangle id
//            breaks ties), the padding (all ones) last
//   karras   one per inner node of the radix tree over the leaves (four sorted keys each, keyed by
//            the first): its range and split; its children's slots: inner node i's children go
//            to slots 2 γ + 1 and 2 γ + 2, γ its split, unique per inner node, the root to slot 0
//   leaves   one per leaf: its padded box, first entry and count, at its slot
//   inner    one per inner node: its first child's slot at its own, and its depth (parents climbed)
//   boxes    one per inner node, per level from the deepest: the union of its children's boxes
// Dispatch: (groups, 1, 1) or, past 65,535 groups, (65,535, rows, 1); index = flat group × 256 + lane.

#import bvh_node

struct Params {
    // Entries (non-degenerate triangles), padded entries (a power of two), leaves.
    n: u32,
    n_pad: u32,
    leaves: u32,
    _p0: u32,
    // The grid's origin (the least vertex sum) and its scale (a power of two).
    lo3: vec3<f32>,
    scale: f32,
    // Box padding (src/mesh/bvh.rs, `PAD`).
    pad: f32,
    _p1: u32,
    _p2: u32,
    _p3: u32,
}

// Per dispatch: bitonic (k, j); boxes (level, -).
struct Step {
    a: u32,
    b: u32,
}


@group(0) @binding(0) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(1) var<storage, read> tris: array<vec4<u32>>;
@group(0) @binding(2) var<storage, read> ids: array<u32>;
@group(0) @binding(3) var<uniform> params: Params;
@group(0) @binding(4) var<storage, read_write> keys: array<vec2<u32>>;
@group(0) @binding(5) var<uniform> pass_step: Step;
@group(0) @binding(6) var<storage, read_write> nodes: array<Node>;
// Per inner node (leaves - 1 each): split, parent, slot, depth; then per leaf: slot.
@group(0) @binding(7) var<storage, read_write> links: array<u32>;
// [0]: the deepest inner node's depth (the root's is 0).
@group(0) @binding(8) var<storage, read_write> deepest: array<atomic<u32>>;

const WG: u32 = 256u;
const NONE: u32 = 0xffffffffu;
const LEAF: u32 = 4u;

fn flat(g: vec3<u32>, n: vec3<u32>, lane: u32) -> u32 {
    return (g.y * n.x + g.x) * WG + lane;
}

fn inner_count() -> u32 {
    return params.leaves - 1u;
}

fn split_at(i: u32) -> u32 { return i; }
fn parent_at(i: u32) -> u32 { return inner_count() + i; }
fn slot_at(i: u32) -> u32 { return 2u * inner_count() + i; }
fn depth_at(i: u32) -> u32 { return 3u * inner_count() + i; }
fn leaf_slot_at(g: u32) -> u32 { return 4u * inner_count() + g; }

fn spread_bits(v: u32) -> u32 {
    var x = v & 0x3ffu;
    x = (x | (x << 16u)) & 0x030000ffu;
    x = (x | (x << 8u)) & 0x0300f00fu;
    x = (x | (x << 4u)) & 0x030c30c3u;
    x = (x | (x << 2u)) & 0x09249249u;
    return x;
}

@compute @workgroup_size(256)
fn morton(@builtin(workgroup_id) g: vec3<u32>, @builtin(num_workgroups) ng: vec3<u32>,
          @builtin(local_invocation_index) lane: u32) {
    let i = flat(g, ng, lane);
    if (i >= params.n_pad) { return; }
    if (i >= params.n) {
        keys[i] = vec2<u32>(NONE, NONE);
        return;
    }
    let t = ids[i];
    let v = tris[t];
    let s = (positions[v.x].xyz + positions[v.y].xyz) + positions[v.z].xyz;
    let q = min(floor(max(s - params.lo3, vec3<f32>(0.0)) * params.scale), vec3<f32>(1023.0));
    let c = vec3<u32>(q);
    keys[i] = vec2<u32>((spread_bits(c.x) << 2u) | (spread_bits(c.y) << 1u) | spread_bits(c.z), t);
}

fn greater(a: vec2<u32>, b: vec2<u32>) -> bool {
    return a.x > b.x || (a.x == b.x && a.y > b.y);
}

@compute @workgroup_size(256)
fn bitonic(@builtin(workgroup_id) g: vec3<u32>, @builtin(num_workgroups) ng: vec3<u32>,
           @builtin(local_invocation_index) lane: u32) {
    let p = flat(g, ng, lane);
    if (p >= params.n_pad / 2u) { return; }
    let k = pass_step.a;
    let j = pass_step.b;
    let i = (p / j) * 2u * j + p % j;
    let l = i + j;
    let a = keys[i];
    let b = keys[l];
    let up = (i & k) == 0u;
    if (greater(a, b) == up) {
        keys[i] = b;
        keys[l] = a;
    }
}

// The leaf's key: the code of its first entry.
fn code(g: u32) -> u32 {
    return keys[g * LEAF].x;
}

// Length of the common prefix of leaves i and j (-1 outside), the leaf index breaking ties.
fn delta(i: i32, j: i32) -> i32 {
    if (j < 0 || j >= i32(params.leaves)) { return -1; }
    let a = code(u32(i));
    let b = code(u32(j));
    if (a == b) { return 32 + i32(countLeadingZeros(u32(i) ^ u32(j))); }
    return i32(countLeadingZeros(a ^ b));
}

@compute @workgroup_size(256)
fn karras(@builtin(workgroup_id) g: vec3<u32>, @builtin(num_workgroups) ng: vec3<u32>,
          @builtin(local_invocation_index) lane: u32) {
    let iu = flat(g, ng, lane);
    if (iu >= inner_count()) { return; }
    let i = i32(iu);
    let d = select(-1, 1, delta(i, i + 1) - delta(i, i - 1) > 0);
    let dmin = delta(i, i - d);
    var lmax = 2;
    while (delta(i, i + lmax * d) > dmin) { lmax = lmax * 2; }
    var l = 0;
    var t = lmax / 2;
    while (t >= 1) {
        if (delta(i, i + (l + t) * d) > dmin) { l = l + t; }
        t = t / 2;
    }
    let j = i + l * d;
    let dnode = delta(i, j);
    var s = 0;
    var div = 2;
    loop {
        let step_len = (l + div - 1) / div;
        if (delta(i, i + (s + step_len) * d) > dnode) { s = s + step_len; }
        if (step_len <= 1) { break; }
        div = div * 2;
    }
    let gamma = u32(i + s * d + min(d, 0));
    let lo = u32(min(i, j));
    let hi = u32(max(i, j));
    links[split_at(iu)] = gamma;
    if (iu == 0u) {
        links[slot_at(0u)] = 0u;
        links[parent_at(0u)] = NONE;
    }
    if (lo == gamma) {
        links[leaf_slot_at(gamma)] = 2u * gamma + 1u;
    } else {
        links[slot_at(gamma)] = 2u * gamma + 1u;
        links[parent_at(gamma)] = iu;
    }
    if (hi == gamma + 1u) {
        links[leaf_slot_at(gamma + 1u)] = 2u * gamma + 2u;
    } else {
        links[slot_at(gamma + 1u)] = 2u * gamma + 2u;
        links[parent_at(gamma + 1u)] = iu;
    }
}

@compute @workgroup_size(256)
fn leaves(@builtin(workgroup_id) g: vec3<u32>, @builtin(num_workgroups) ng: vec3<u32>,
          @builtin(local_invocation_index) lane: u32) {
    let leaf = flat(g, ng, lane);
    if (leaf >= params.leaves) { return; }
    let first = leaf * LEAF;
    let count = min(LEAF, params.n - first);
    var lo = vec3<f32>(bitcast<f32>(0x7f800000u));
    var hi = -lo;
    for (var e = first; e < first + count; e = e + 1u) {
        let v = tris[keys[e].y];
        for (var c = 0u; c < 3u; c = c + 1u) {
            let p = positions[v[c]].xyz;
            lo = min(lo, p);
            hi = max(hi, p);
        }
    }
    var slot = 0u;
    if (params.leaves > 1u) { slot = links[leaf_slot_at(leaf)]; }
    nodes[slot] = Node(lo - vec3<f32>(params.pad), first, hi + vec3<f32>(params.pad), count);
}

@compute @workgroup_size(256)
fn inner(@builtin(workgroup_id) g: vec3<u32>, @builtin(num_workgroups) ng: vec3<u32>,
         @builtin(local_invocation_index) lane: u32) {
    let i = flat(g, ng, lane);
    if (i >= inner_count()) { return; }
    var depth = 0u;
    var c = i;
    while (c != 0u && depth < 64u) {
        c = links[parent_at(c)];
        depth = depth + 1u;
    }
    links[depth_at(i)] = depth;
    atomicMax(&deepest[0], depth);
    let slot = links[slot_at(i)];
    nodes[slot].first = 2u * links[split_at(i)] + 1u;
    nodes[slot].count = 0u;
}

@compute @workgroup_size(256)
fn boxes(@builtin(workgroup_id) g: vec3<u32>, @builtin(num_workgroups) ng: vec3<u32>,
         @builtin(local_invocation_index) lane: u32) {
    let i = flat(g, ng, lane);
    if (i >= inner_count() || links[depth_at(i)] != pass_step.a) { return; }
    let slot = links[slot_at(i)];
    let f = nodes[slot].first;
    let a = nodes[f];
    let b = nodes[f + 1u];
    nodes[slot].lo = min(a.lo, b.lo);
    nodes[slot].hi = max(a.hi, b.hi);
}
