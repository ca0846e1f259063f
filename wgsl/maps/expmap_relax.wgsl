// SPDX-License-Identifier: MIT OR Apache-2.0
// Discrete exponential maps by parallel relaxation over an active front, one workgroup per decal
// (smooth mode: the update also carries a Jacobi field and a frame angle, see `Accuracy` in
// src/maps/expmap/cpu.rs):
// every sweep, each vertex of the front takes the neighbour that minimises (graph distance +
// edge length) among reached, expandable neighbours (graph distance <= radius, |K| <= curvature
// stop) and sets its normal coordinates from it (shared/expmap.wgsl); sweeps repeat until one changes
// nothing. Only vertices next to a vertex that changed in the previous sweep are in the next front,
// so the work is proportional to the updates, not to sweeps x disc. Distances only decrease
// (Bellman-Ford), so the in-place, unordered updates converge. The
// fixed point is the serial Dijkstra map of the paper (`dem_cpu` in src/maps/expmap/cpu.rs).
// Candidates (the connected vertices within a Euclidean ball that contains the geodesic disc, plus
// one ring) come from the CPU, so the work is proportional to the disc, not to the mesh.
// Output per vertex in the layer's coords slot: (u, v, graph distance, 1) reached, 2 for seed
// vertices. The geodesic distance estimate is |(u, v)| (Schmidt et al. 4.2).
// Rounds: the first dispatch (`round.init`) seeds the maps; each dispatch runs at most `round.sweeps`
// sweeps, so that no invocation loops too long (lavapipe cuts off shaders whose loops run more than
// 65535 iterations in all), and the host dispatches rounds until every map has converged.
// Dispatch: (decals, 1, 1) per round.
#import expmap

// 64 invocations: a map's fronts are a ring or two, so most of a wider workgroup idled through
// every sweep's barriers (256 maps of ~1,100 vertices on bob x 2: 1,078-1,160 -> 1,319-1,367
// maps/s in alternating runs, session 18).
// A chunk with a map of `WIDE_MIN_CANDIDATES` candidates or more (src/maps/expmap/gpu.rs) runs a variant of
// 256 (`shaders::expmap_wide_source`), whose set-up and count loops stay short of lavapipe's
// loop cut-off. Keep in sync with `shaders::EXPMAP_WG`.
const WG: u32 = 64u;
const INF: f32 = 3.0e38;
const NONE: u32 = 0xffffffffu;

// Keep in sync with `GeoJob` in src/maps/expmap/gpu.rs.
struct GeoJob {
    seed: vec4<f32>,
    normal: vec4<f32>,
    e1: vec4<f32>,
    e2: vec4<f32>,
    // Seed triangle's welded vertices; w: coords slot.
    tri: vec4<u32>,
    radius: f32,
    curvature_stop: f32,
    cand_offset: u32,
    cand_count: u32,
    vertex_count: u32,
    max_sweeps: u32,
    // Vertices around the candidates, listed right after them: reset to "not a candidate".
    halo_count: u32,
    // 1: smooth mode (second-order step with Jacobi field and carried frame), 0: the paper's update.
    smooth_mode: u32,
}

// Keep in sync with `Round` in src/maps/expmap/gpu.rs.
struct Round {
    init: u32,
    // At most this many sweeps a dispatch.
    sweeps: u32,
    // Loop steps an invocation may spend a dispatch: a sweep over a front of n vertices costs
    // ceil(n / WG) * `steps_per_vertex`; the sweeps go on while the next one fits (at least one).
    budget: u32,
    // Loop steps one front vertex may cost: 1 + 2 x the candidates
    // largest degree (the neighbour scan and the queueing).
    steps_per_vertex: u32,
}


// Keep in sync with `GeoResult` in src/maps/expmap/gpu.rs.
struct GeoResult {
    sweeps: u32,
    reached: u32,
    converged: u32,
    _pad: u32,
}

@group(0) @binding(0) var<storage, read> jobs: array<GeoJob>;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> normals: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> adj_offsets: array<u32>;
// Per CSR adjacency entry v -> r: (r, the edge's intrinsic angle at v, the reverse edge's at r,
// r's curvature), the floats as bits: one load where a neighbour scan took two (adjacency,
// curvature) and the smooth step two more scans (`relax_edges` in src/mesh/surface.rs).
@group(0) @binding(4) var<storage, read> edges: array<vec4<u32>>;
@group(0) @binding(5) var<storage, read> curvature: array<f32>;
@group(0) @binding(6) var<storage, read> candidates: array<u32>;
@group(0) @binding(7) var<storage, read_write> coords: array<vec4<f32>>;
@group(0) @binding(8) var<storage, read_write> results: array<GeoResult>;
@group(0) @binding(9) var<uniform> round: Round;
// Per map: front length, parity of the current front list, sweep stamp, sweeps so far.
@group(0) @binding(10) var<storage, read_write> fstate: array<u32>;
// Two front lists per map, each `cand_count` long, at 2 * cand_offset + parity * cand_count.
@group(0) @binding(11) var<storage, read_write> fronts: array<u32>;
// Per slot and vertex: the stamp of the sweep that last queued it (dedupes the next front).
@group(0) @binding(12) var<storage, read_write> marks: array<atomic<u32>>;
// Per slot and vertex: the smooth mode's state (G, G', frame angle, 0) (see shared/expmap.wgsl).
@group(0) @binding(13) var<storage, read_write> state: array<vec4<f32>>;
// The intrinsic angle of edge v -> q at v (0 when q is not a neighbour). Twin of `edge_angle` in
// src/maps/expmap/cpu.rs.
fn edge_angle(v: u32, q: u32) -> f32 {
    let k_end = adj_offsets[v + 1u];
    for (var k = adj_offsets[v]; k < k_end; k++) {
        let e = edges[k];
        if (e.x == q) { return bitcast<f32>(e.y); }
    }
    return 0.0;
}

// +1 when the seed frame (e1, e2) turns like the seed triangle's winding, -1 when mirrored.
// Twin of `orient` in `smooth_seed`, src/maps/expmap/cpu.rs.
fn seed_orient(job: GeoJob) -> f32 {
    let p0 = positions[job.tri.x].xyz;
    let nt = normalize(cross(positions[job.tri.y].xyz - p0, positions[job.tri.z].xyz - p0));
    let e1 = normalize(job.e1.xyz - nt * dot(job.e1.xyz, nt));
    return select(1.0, -1.0, dot(cross(nt, e1), job.e2.xyz) < 0.0);
}

// The smooth mode's start at seed-triangle vertex i: coordinates in the triangle's plane and the
// state (distance, 1, frame angle, 0). Twin of `smooth_seed` in src/maps/expmap/cpu.rs.
fn smooth_seed(job: GeoJob, i: u32, orient: f32) -> SmoothOut {
    let tri = array<u32, 3>(job.tri.x, job.tri.y, job.tri.z);
    let p = array<vec3<f32>, 3>(positions[tri[0]].xyz, positions[tri[1]].xyz, positions[tri[2]].xyz);
    let nt = normalize(cross(p[1] - p[0], p[2] - p[0]));
    let e1 = normalize(job.e1.xyz - nt * dot(job.e1.xyz, nt));
    let e2 = cross(nt, e1) * orient;
    let d = p[i] - job.seed.xyz;
    let en = p[(i + 1u) % 3u] - p[i];
    let ep = p[(i + 2u) % 3u] - p[i];
    let beta = atan2(dot(nt, cross(en, e1)), dot(en, e1));
    let corner = atan2(length(cross(en, ep)), dot(en, ep));
    let tn = edge_angle(tri[i], tri[(i + 1u) % 3u]);
    let tp = edge_angle(tri[i], tri[(i + 2u) % 3u]);
    var width = tp - tn;
    if (width < 0.0) { width += 2.0 * PI; }
    var scale = 1.0;
    if (corner > 0.0) { scale = width / corner; }
    var out: SmoothOut;
    out.uv = vec2<f32>(dot(d, e1), dot(d, e2));
    out.state = vec4<f32>(length(d), 1.0, tn + beta * scale, 0.0);
    return out;
}

var<workgroup> reached: atomic<u32>;
var<workgroup> done_before: u32;
var<workgroup> next_len: atomic<u32>;
var<workgroup> front_len: u32;

// The first dispatch of a map (`round.init`): its candidates cleared (coordinates, state, marks),
// the halo around them marked as not candidates, the seed triangle's vertices set, and the first
// front listed. Called in uniform control flow (it has barriers).
fn init_map(job: GeoJob, base: u32, seed_n: vec3<f32>, lid: u32, wid: u32) {
    for (var i = lid; i < job.cand_count; i += WG) {
        let v = candidates[job.cand_offset + i];
        coords[base + v] = vec4<f32>(0.0, 0.0, INF, 0.0);
        state[base + v] = vec4<f32>(0.0, 1.0, 0.0, 0.0);
        atomicStore(&marks[base + v], 0u);
    }
    for (var i = lid; i < job.halo_count; i += WG) {
        coords[base + candidates[job.cand_offset + job.cand_count + i]] = vec4<f32>(0.0);
    }
    storageBarrier();
    workgroupBarrier();
    if (lid < 3u) {
        let v = job.tri[lid];
        let p = positions[v].xyz;
        let d = p - job.seed.xyz;
        if (job.smooth_mode != 0u) {
            let s = smooth_seed(job, lid, seed_orient(job));
            coords[base + v] = vec4<f32>(s.uv, length(d), 2.0);
            state[base + v] = s.state;
        } else {
            coords[base + v] = vec4<f32>(transfer(job.seed.xyz, seed_n, p, seed_n, job.e1.xyz, job.e2.xyz), length(d), 2.0);
            state[base + v] = vec4<f32>(length(d), 1.0, 0.0, 0.0);
        }
    }
    storageBarrier();
    workgroupBarrier();
    // The first front: the seeds' neighbours that are candidates (marked with stamp 1; the
    // sweeps' stamps start at 2). Every other candidate first changes after a neighbour
    // did, so it is queued then: a first front of every candidate (as before session 18)
    // gave the same sweeps, its evaluations of vertices far from the seed finding nothing
    // (about a fifth of a map's evaluations).
    if (lid < 3u) {
        let v = job.tri[lid];
        let k_end = adj_offsets[v + 1u];
        for (var k = adj_offsets[v]; k < k_end; k++) {
            let q = edges[k].x;
            let cq = coords[base + q];
            if ((cq.w > 0.5 || cq.z > 1.0e30) && cq.w < 1.5) {
                if (atomicExchange(&marks[base + q], 1u) != 1u) {
                    fronts[2u * job.cand_offset + atomicAdd(&next_len, 1u)] = q;
                }
            }
        }
    }
    storageBarrier();
    workgroupBarrier();
    if (lid == 0u) {
        fstate[4u * wid] = atomicLoad(&next_len);
        fstate[4u * wid + 1u] = 0u;
        fstate[4u * wid + 2u] = 2u;
        fstate[4u * wid + 3u] = 0u;
    }
    storageBarrier();
    workgroupBarrier();
}

@compute @workgroup_size(WG)
fn main(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let job = jobs[wid.x];
    let base = job.tri.w * job.vertex_count;
    let seed_n = job.normal.xyz;
    let orient = seed_orient(job);
    if (lid == 0u) {
        atomicStore(&reached, 0u);
        atomicStore(&next_len, 0u);
        done_before = 0u;
        if (round.init == 0u) { done_before = results[wid.x].converged; }
    }
    if (workgroupUniformLoad(&done_before) != 0u) { return; }
    if (round.init != 0u) {
        init_map(job, base, seed_n, lid, wid.x);
    }
    var sweeps = 0u;
    var steps = 0u;
    var converged = false;
    loop {
        if (lid == 0u) {
            front_len = fstate[4u * wid.x];
            atomicStore(&next_len, 0u);
        }
        let len = workgroupUniformLoad(&front_len);
        // The fronts are a ring or two: a dispatch runs as many sweeps as fit its loop budget.
        let cost = (len + WG - 1u) / WG * round.steps_per_vertex;
        converged = len == 0u;
        if (converged || sweeps >= round.sweeps || (sweeps > 0u && steps + cost > round.budget)) { break; }
        steps += cost;
        let parity = fstate[4u * wid.x + 1u];
        let stamp = fstate[4u * wid.x + 2u];
        let cur = 2u * job.cand_offset + parity * job.cand_count;
        let nxt = 2u * job.cand_offset + (1u - parity) * job.cand_count;
        for (var i = lid; i < len; i += WG) {
            let v = fronts[cur + i];
            let c = coords[base + v];
            if (c.w > 1.5) { continue; }
            let pv = positions[v].xyz;
            var best = INF;
            var best_r = NONE;
            var best_k = 0u;
            // The best neighbour's coordinates and position, kept rather than loaded again.
            var best_c = vec4<f32>(0.0);
            var best_p = vec3<f32>(0.0);
            let k_first = adj_offsets[v];
            let k_end = adj_offsets[v + 1u];
            for (var k = k_first; k < k_end; k++) {
                let e = edges[k];
                let r = e.x;
                let cr = coords[base + r];
                if (cr.w > 0.5 && cr.z <= job.radius && abs(bitcast<f32>(e.w)) <= job.curvature_stop) {
                    let pr = positions[r].xyz;
                    let key = cr.z + length(pv - pr);
                    if (key < best || (key == best && r < best_r)) {
                        best = key;
                        best_r = r;
                        best_k = k;
                        best_c = cr;
                        best_p = pr;
                    }
                }
            }
            if (best_r != NONE) {
                let cr = best_c;
                let pr = best_p;
                let t = transfer(pr, normals[best_r].xyz, pv, seed_n, job.e1.xyz, job.e2.xyz);
                var uv = cr.xy + t;
                var sv = vec4<f32>(0.0, 1.0, 0.0, 0.0);
                let kv = curvature[v];
                if (job.smooth_mode != 0u) {
                    // The angles of best_r -> v at best_r and of v -> best_r at v.
                    let eb = edges[best_k];
                    let ty = bitcast<f32>(eb.z);
                    let tx = bitcast<f32>(eb.y);
                    let out = smooth_step(cr.xy, state[base + best_r], bitcast<f32>(eb.w), kv, length(pv - pr), ty, tx, orient);
                    uv = out.uv;
                    sv = out.state;
                }
                let nc = vec4<f32>(uv, best, 1.0);
                if (any(nc != c) || any(sv != state[base + v])) {
                    coords[base + v] = nc;
                    state[base + v] = sv;
                    // Queue the neighbours that are candidates (cleared non-candidates have z = 0,
                    // candidates start at INF) and not seed vertices, and for which v could now
                    // be the best neighbour: v expandable, and its key from q (the same sum q's
                    // scan forms) at most q's distance. Distances only decrease, so where v was
                    // q's best its key cannot have grown: `<=` keeps q queued when v's
                    // coordinates or state changed at the same distance, and a tie. Any other q
                    // would scan its neighbours and keep what it has (session 18: a map's
                    // vertices were evaluated 3.9-5 times each).
                    if (best <= job.radius && abs(kv) <= job.curvature_stop) {
                        for (var k = k_first; k < k_end; k++) {
                            let q = edges[k].x;
                            let cq = coords[base + q];
                            if ((cq.w > 0.5 || cq.z > 1.0e30) && cq.w < 1.5
                                && best + length(positions[q].xyz - pv) <= cq.z) {
                                if (atomicExchange(&marks[base + q], stamp) != stamp) {
                                    fronts[nxt + atomicAdd(&next_len, 1u)] = q;
                                }
                            }
                        }
                    }
                }
            }
        }
        storageBarrier();
        workgroupBarrier();
        if (lid == 0u) {
            fstate[4u * wid.x] = atomicLoad(&next_len);
            fstate[4u * wid.x + 1u] = 1u - parity;
            fstate[4u * wid.x + 2u] = stamp + 1u;
            fstate[4u * wid.x + 3u] += 1u;
        }
        storageBarrier();
        workgroupBarrier();
        sweeps += 1u;
    }
    // Counted once, when the map has converged (each invocation its share, then one shared add:
    // a contended add per reached vertex cost the 120k disc about 3 ms a round).
    // (Also when the map stops at its sweep cap, unconverged: the report shows how far it got.)
    if (converged || fstate[4u * wid.x + 3u] >= job.max_sweeps) {
        var mine = 0u;
        for (var i = lid; i < job.cand_count; i += WG) {
            if (coords[base + candidates[job.cand_offset + i]].w > 0.5) { mine += 1u; }
        }
        atomicAdd(&reached, mine);
    }
    workgroupBarrier();
    if (lid == 0u) {
        var r: GeoResult;
        r.sweeps = fstate[4u * wid.x + 3u];
        r.reached = atomicLoad(&reached);
        r.converged = select(0u, 1u, fstate[4u * wid.x] == 0u);
        results[wid.x] = r;
    }
}
