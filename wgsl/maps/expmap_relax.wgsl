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
#import expmap_relax_common

// 64 invocations: a map's fronts are a ring or two, so most of a wider workgroup idled through
// every sweep's barriers (256 maps of ~1,100 vertices on bob x 2: 1,078-1,160 -> 1,319-1,367
// maps/s in alternating runs on lavapipe).
// A chunk with a map of `WIDE_MIN_CANDIDATES` candidates or more (src/maps/expmap/gpu.rs) runs a variant of
// 256 (`shaders::expmap_wide_source`), whose set-up and count loops stay short of lavapipe's
// loop cut-off. Keep in sync with `shaders::EXPMAP_WG`.
const WG: u32 = 64u;
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

@group(0) @binding(8) var<storage, read_write> results: array<GeoResult>;
@group(0) @binding(9) var<uniform> round: Round;
// Per map: front length, parity of the current front list, sweep stamp, sweeps so far.
@group(0) @binding(10) var<storage, read_write> fstate: array<u32>;
var<workgroup> reached: atomic<u32>;
var<workgroup> done_before: u32;
var<workgroup> next_len: atomic<u32>;
var<workgroup> front_len: u32;

// The first dispatch of a map (`round.init`): its candidates cleared (coordinates, state, marks),
// the halo around them marked as not candidates, the seed triangle's vertices set, and the first
// front listed. Called in uniform control flow (it has barriers).
fn init_map(job: GeoJob, base: u32, lid: u32, wid: u32) {
    for (var i = lid; i < job.cand_count + job.halo_count; i += WG) {
        clear_candidate(job, base, i);
    }
    storageBarrier();
    workgroupBarrier();
    seed_map(job, base, lid);
    if (lid == 0u) {
        fstate[4u * wid] = atomicLoad(&next_len);
        fstate[4u * wid + 1u] = 0u;
        fstate[4u * wid + 2u] = 2u;
        fstate[4u * wid + 3u] = 0u;
    }
    storageBarrier();
    workgroupBarrier();
}

fn push_front(at: u32, q: u32) {
    fronts[at + atomicAdd(&next_len, 1u)] = q;
}

@compute @workgroup_size(WG)
fn main(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let job = jobs[wid.x];
    let base = job.tri.w * job.vertex_count;
    let orient = seed_orient(job);
    if (lid == 0u) {
        atomicStore(&reached, 0u);
        atomicStore(&next_len, 0u);
        done_before = 0u;
        if (round.init == 0u) { done_before = results[wid.x].converged; }
    }
    if (workgroupUniformLoad(&done_before) != 0u) { return; }
    if (round.init != 0u) {
        init_map(job, base, lid, wid.x);
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
            relax_vertex(job, base, v, orient, stamp, nxt);
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
