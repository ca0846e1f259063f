// SPDX-License-Identifier: MIT OR Apache-2.0
// The extended exponential map of a curve (Sun et al. 2013, section 3) by parallel relaxation, one
// workgroup for one curve. CPU twin: `ribbon_cpu` in src/maps/ribbon/mod.rs, whose fixed point this
// is (the same seeds, upwind rule, update, slide and reading; float functions differ in the last
// bits). Every sweep, each candidate vertex that is not a seed takes the neighbour that minimises
// (graph distance + edge length) among neighbours within `reach` (ties: the lower id), carries that
// neighbour's foot and offset across the edge (the exponential map's update, shared/expmap.wgsl)
// and slides the foot along the curve; sweeps repeat until one changes nothing (Bellman-Ford:
// in-place, unordered updates settle on the serial Dijkstra tree). Then each reached vertex's
// offset is read against the arc its piece stands for: (a u + b, c v + d, graph distance, 1) in
// the output slot of `coords` (`job.xform` = (a, b, c, d): the layer's image coordinates).
// Candidates (the vertices near the curve, plus one ring that is only reset) come from the CPU,
// gathered into the strip's own numbering (positions and normals, adjacency, state and links are
// per local vertex; `global` gives the welded id for ties and the output), so the work is
// proportional to the strip and a sweep reads compact buffers in order. Rounds: `job.init` seeds; each dispatch runs at most
// `job.sweeps` sweeps (lavapipe abandons invocations that loop more than 65535 times); the host
// dispatches rounds until `status[1]` says converged.
// Dispatch: (1, 1, 1) per round.
#import expmap

const WG: u32 = 256u;
const INF: f32 = 3.0e38;
const NONE: u32 = 0xffffffffu;
// `link.x` of a seed vertex: final, never updated.
const SEED: u32 = 0xfffffffeu;

// Keep in sync with `RibbonJob` in src/maps/ribbon/gpu.rs.
struct RibbonJob {
    cand_count: u32,
    halo_count: u32,
    seed_count: u32,
    piece_count: u32,
    reach: f32,
    length: f32,
    sweeps: u32,
    init: u32,
    // First entry of the output slot in `coords`.
    slot_base: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
    // Output (a u + b, c v + d) as (a, b, c, d).
    xform: vec4<f32>,
}

// Keep in sync with `GpuPiece` in src/maps/ribbon/mod.rs: start (xyz) and arc length there; unit
// tangent and length; the triangle's normal and the curvature the piece stands for; N x T.
struct Piece {
    start: vec4<f32>,
    t: vec4<f32>,
    n: vec4<f32>,
    b: vec4<f32>,
}

// Keep in sync with `GpuSeed` in src/maps/ribbon/gpu.rs.
struct SeedState {
    vertex: u32,
    piece: u32,
    s: f32,
    dist: f32,
    off: vec2<f32>,
    pad: vec2<f32>,
}

@group(0) @binding(0) var<uniform> job: RibbonJob;
// Keep in sync with `StripVertex` in src/maps/ribbon/gpu.rs: position and unit normal (w unused).
struct StripVertex {
    p: vec4<f32>,
    n: vec4<f32>,
}

// Per local vertex (the candidates, then the ring around them).
@group(0) @binding(1) var<storage, read> verts: array<StripVertex>;
// Per local vertex: 1 + the sweep (counted over all rounds) that last changed it; set to 1 at
// init. A candidate none of whose neighbours changed in the previous sweep or this one would
// compute what it holds, so it is skipped (the fixed point and the twin's agreement are kept:
// its inputs are the neighbours' state and links only). `bench --ribbons`: 5 sweeps either way,
// kernel time 0.8 (bob) and 0.65 (the bunny) of computing every candidate every sweep.
@group(0) @binding(2) var<storage, read_write> stamp: array<u32>;
// Per candidate: its neighbours' local ids.
@group(0) @binding(3) var<storage, read> adj_offsets: array<u32>;
@group(0) @binding(4) var<storage, read> adjacency: array<u32>;
@group(0) @binding(5) var<storage, read> pieces: array<Piece>;
// Per local vertex: its welded id.
@group(0) @binding(6) var<storage, read> global: array<u32>;
// Seed vertices in local ids.
@group(0) @binding(7) var<storage, read> seeds: array<SeedState>;
// Per local vertex: (foot arc length, offset x, offset y, graph distance).
@group(0) @binding(8) var<storage, read_write> state: array<vec4<f32>>;
// Per local vertex: (upwind neighbour's local id or NONE / SEED, the foot's piece).
@group(0) @binding(9) var<storage, read_write> link: array<vec2<u32>>;
@group(0) @binding(10) var<storage, read_write> coords: array<vec4<f32>>;
// Sweeps so far, converged, vertices reached, the largest v reached on the left and on the right
// (f32 bits), 0, 0, 0.
@group(0) @binding(11) var<storage, read_write> status: array<u32>;

// The piece holding arc length s (partition point of the pieces' start arcs, the last at the end).
// Twin of `Framed::piece_at`.
fn piece_at(s: f32) -> u32 {
    var lo = 0u;
    var hi = job.piece_count;
    loop {
        if (lo >= hi) { break; }
        let mid = (lo + hi) / 2u;
        if (pieces[mid].start.w <= s) { lo = mid + 1u; } else { hi = mid; }
    }
    return clamp(lo, 1u, job.piece_count) - 1u;
}

fn point_on(k: u32, s: f32) -> vec3<f32> {
    let p = pieces[k];
    return p.start.xyz + p.t.xyz * (s - p.start.w);
}

fn rotate2(v: vec2<f32>, a: f32) -> vec2<f32> {
    let c = cos(a);
    let s = sin(a);
    return vec2<f32>(c * v.x - s * v.y, s * v.x + c * v.y);
}

struct Foot {
    piece: u32,
    s: f32,
    off: vec2<f32>,
}

// Slides the foot along the curve until the offset has no tangential part. Twin of `slide`.
fn slide(k0: u32, s0: f32, off0: vec2<f32>) -> Foot {
    var k = k0;
    var s = s0;
    var off = off0;
    for (var i = 0u; i < 8u; i++) {
        let s2 = clamp(s + off.x, 0.0, job.length);
        if (abs(s2 - s) <= 1e-7 * job.length) { break; }
        let k2 = piece_at(s2);
        let a = pieces[k];
        let b = pieces[k2];
        let chord = point_on(k2, s2) - point_on(k, s);
        let d = off - vec2<f32>(dot(chord, a.t.xyz), dot(chord, a.b.xyz));
        let phi = atan2(dot(b.t.xyz, a.b.xyz), dot(b.t.xyz, a.t.xyz));
        off = rotate2(d, -phi);
        k = k2;
        s = s2;
    }
    return Foot(k, s, off);
}

// Keep in sync with `MAX_BEND` in src/maps/ribbon/mod.rs.
const MAX_BEND: f32 = 0.75;

// The curvature a point at offset y across the curve reads its piece with: limited on the inside
// of the turn so that y kappa stays within MAX_BEND (never at or beyond the arc's centre). Twin of
// `reading_curvature`.
fn reading_curvature(kappa: f32, y: f32) -> f32 {
    if (y * kappa > 0.0) {
        let most = MAX_BEND / abs(y);
        return clamp(kappa, -most, most);
    }
    return kappa;
}

// (u, v) of the offset `off` from the foot at s on piece k, read against the arc the piece stands
// for. Twin of `Framed::fermi`.
fn fermi(k: u32, s: f32, off: vec2<f32>) -> vec2<f32> {
    let p = pieces[k];
    let len = p.t.w;
    // Past the curve's ends: straight on along its tangent there, the end piece's chord turned by
    // half the piece's turning. Twin of `Framed::past_end`.
    let half = 0.5 * p.n.w * len;
    let at_start = k == 0u && s <= 0.0;
    let at_end = k == job.piece_count - 1u && s >= job.length;
    if (at_start || at_end) {
        let o = rotate2(off, select(-half, half, at_start));
        if ((at_start && o.x < 0.0) || (at_end && o.x > 0.0)) { return vec2<f32>(s + o.x, o.y); }
    }
    let kappa = reading_curvature(p.n.w, off.y);
    if (abs(kappa) * len < 1e-5) { return vec2<f32>(s + off.x, off.y); }
    let at = vec2<f32>(s - p.start.w + off.x, off.y);
    let r = 1.0 / abs(kappa);
    let h = sqrt(max(r * r - 0.25 * len * len, 0.0)) * sign(kappa);
    let c = vec2<f32>(0.5 * len, h);
    let sc = -c;
    let qa = at - c;
    let qe = vec2<f32>(len, 0.0) - c;
    let angle = atan2(sc.x * qa.y - sc.y * qa.x, dot(sc, qa));
    let end = atan2(sc.x * qe.y - sc.y * qe.x, dot(sc, qe));
    return vec2<f32>(p.start.w + len * angle / end, (r - length(qa)) * sign(kappa));
}

var<workgroup> changed: atomic<u32>;
var<workgroup> any_changed: u32;
var<workgroup> done_before: u32;
var<workgroup> sweep_base: u32;
var<workgroup> reached: atomic<u32>;
// The largest |v| reached on each side, as f32 bits (non-negative floats order as their bits).
var<workgroup> left_max: atomic<u32>;
var<workgroup> right_max: atomic<u32>;

@compute @workgroup_size(256)
fn main(@builtin(local_invocation_index) lid: u32) {
    if (lid == 0u) {
        done_before = 0u;
        sweep_base = 0u;
        if (job.init == 0u) {
            done_before = status[1];
            sweep_base = status[0];
        }
        atomicStore(&reached, 0u);
        atomicStore(&left_max, 0u);
        atomicStore(&right_max, 0u);
    }
    if (workgroupUniformLoad(&done_before) != 0u) { return; }
    let all = job.cand_count + job.halo_count;
    if (job.init != 0u) {
        for (var i = lid; i < all; i += WG) {
            state[i] = vec4<f32>(0.0, 0.0, 0.0, INF);
            link[i] = vec2<u32>(NONE, 0u);
            stamp[i] = 1u;
            coords[job.slot_base + global[i]] = vec4<f32>(0.0);
        }
        storageBarrier();
        workgroupBarrier();
        // A vertex in several pieces' triangles keeps its nearest foot (the CPU lists the seeds so
        // that each vertex appears once, with that foot).
        for (var i = lid; i < job.seed_count; i += WG) {
            let sd = seeds[i];
            state[sd.vertex] = vec4<f32>(sd.s, sd.off, sd.dist);
            link[sd.vertex] = vec2<u32>(SEED, sd.piece);
        }
        if (lid == 0u) {
            status[0] = 0u;
            status[1] = 0u;
            status[2] = 0u;
        }
        storageBarrier();
        workgroupBarrier();
    }
    let base = workgroupUniformLoad(&sweep_base);
    var sweeps = 0u;
    var converged = false;
    loop {
        if (sweeps >= job.sweeps) { break; }
        if (lid == 0u) { atomicStore(&changed, 0u); }
        workgroupBarrier();
        // Each invocation takes a contiguous block of the candidates (listed breadth first from
        // the curve): llvmpipe runs a SIMD group's invocations through the whole loop before the
        // next group's (nothing here waits at a barrier), so blocks make the sweep visit the strip
        // outwards, ring after ring, and a sweep carries the map across all of it (strided
        // indices visited one ring in 256 per step: bob 6 and the bunny 9 sweeps; see the README).
        let block = (job.cand_count + WG - 1u) / WG;
        let end = min(job.cand_count, (lid + 1u) * block);
        for (var q = lid * block; q < end; q++) {
            let old_link = link[q];
            if (old_link.x == SEED) { continue; }
            var dirty = false;
            let e_end = adj_offsets[q + 1u];
            for (var e = adj_offsets[q]; e < e_end; e++) {
                if (stamp[adjacency[e]] >= base + sweeps) {
                    dirty = true;
                    break;
                }
            }
            if (!dirty) { continue; }
            let pq = verts[q].p.xyz;
            var best = INF;
            var best_r = NONE;
            for (var e = adj_offsets[q]; e < e_end; e++) {
                let r = adjacency[e];
                let dr = state[r].w;
                if (dr > job.reach) { continue; }
                let key = dr + length(pq - verts[r].p.xyz);
                // Ties go to the lower welded id, as in the twin.
                if (key < best || (key == best && best_r != NONE && global[r] < global[best_r])) {
                    best = key;
                    best_r = r;
                }
            }
            if (best_r == NONE) { continue; }
            let sr = state[best_r];
            let k = link[best_r].y;
            let p = pieces[k];
            let t = transfer(verts[best_r].p.xyz, verts[best_r].n.xyz, pq, p.n.xyz, p.t.xyz, p.b.xyz);
            let f = slide(k, sr.x, sr.yz + t);
            let next = vec4<f32>(f.s, f.off, best);
            let next_link = vec2<u32>(best_r, f.piece);
            if (any(next != state[q]) || any(next_link != old_link)) {
                state[q] = next;
                link[q] = next_link;
                stamp[q] = base + sweeps + 1u;
                atomicStore(&changed, 1u);
            }
        }
        storageBarrier();
        workgroupBarrier();
        if (lid == 0u) { any_changed = atomicLoad(&changed); }
        sweeps += 1u;
        if (workgroupUniformLoad(&any_changed) == 0u) {
            converged = true;
            break;
        }
    }
    if (converged) {
        for (var v = lid; v < job.cand_count; v += WG) {
            let st = state[v];
            if (st.w < INF) {
                let uv = fermi(link[v].y, st.x, st.yz);
                let x = job.xform.xy;
                let y = job.xform.zw;
                coords[job.slot_base + global[v]] = vec4<f32>(x.x * uv.x + x.y, y.x * uv.y + y.y, st.w, 1.0);
                atomicAdd(&reached, 1u);
                if (uv.y > 0.0) {
                    atomicMax(&left_max, bitcast<u32>(uv.y));
                } else {
                    // abs, not negation: -(+0.0) is -0.0, whose bits outrank every positive
                    // float's as a u32 (a curve along mesh edges has vertices at v = 0 exactly).
                    atomicMax(&right_max, bitcast<u32>(abs(uv.y)));
                }
            }
        }
    }
    workgroupBarrier();
    if (lid == 0u) {
        status[0] += sweeps;
        if (converged) {
            status[1] = 1u;
            status[2] = atomicLoad(&reached);
            status[3] = atomicLoad(&left_max);
            status[4] = atomicLoad(&right_max);
        }
    }
}
