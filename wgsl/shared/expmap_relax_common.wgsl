// SPDX-License-Identifier: MIT OR Apache-2.0
// What the two exponential-map relaxations share: `expmap_relax` (one workgroup a map, a chunk's
// maps in one dispatch) and `expmap_spread` (one large map over as many workgroups as its front
// needs, a dispatch a sweep). The job, the mesh and map bindings (0-7, 11-13), the seeds, the first
// front and the update of one front vertex. The importing kernel declares bindings 8 and 10 (each
// in its own layout) and `fn push_front(at: u32, q: u32)`, which appends q to the front list that
// starts at `fronts[at]`. Import after `expmap`.
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

// Clears entry i of the job's candidate list and halo (its coordinates, smooth state and mark; a
// halo vertex as "not a candidate"). The first step of a map.
fn clear_candidate(job: GeoJob, base: u32, i: u32) {
    let v = candidates[job.cand_offset + i];
    if (i < job.cand_count) {
        coords[base + v] = vec4<f32>(0.0, 0.0, INF, 0.0);
        state[base + v] = vec4<f32>(0.0, 1.0, 0.0, 0.0);
        atomicStore(&marks[base + v], 0u);
    } else {
        coords[base + v] = vec4<f32>(0.0);
    }
}

// Seed-triangle vertex i (0-2) set: its coordinates in the seed's frame, state and flag 2.
fn set_seed(job: GeoJob, base: u32, i: u32) {
    let seed_n = job.normal.xyz;
    let v = job.tri[i];
    let p = positions[v].xyz;
    let d = p - job.seed.xyz;
    if (job.smooth_mode != 0u) {
        let s = smooth_seed(job, i, seed_orient(job));
        coords[base + v] = vec4<f32>(s.uv, length(d), 2.0);
        state[base + v] = s.state;
    } else {
        coords[base + v] = vec4<f32>(transfer(job.seed.xyz, seed_n, p, seed_n, job.e1.xyz, job.e2.xyz), length(d), 2.0);
        state[base + v] = vec4<f32>(length(d), 1.0, 0.0, 0.0);
    }
}

// The first front: seed vertex i's neighbours that are candidates (marked with stamp 1; the
// sweeps' stamps start at 2), into the front list at 2 * cand_offset. Every other candidate
// first changes after a neighbour did, so it is queued then: a first front of every candidate
// (as the kernel once had) gave the same sweeps, its evaluations of vertices far from the seed
// finding nothing (about a fifth of a map's evaluations).
fn queue_seed_neighbours(job: GeoJob, base: u32, i: u32) {
    let v = job.tri[i];
    let k_end = adj_offsets[v + 1u];
    for (var k = adj_offsets[v]; k < k_end; k++) {
        let q = edges[k].x;
        let cq = coords[base + q];
        if ((cq.w > 0.5 || cq.z > 1.0e30) && cq.w < 1.5) {
            if (atomicExchange(&marks[base + q], 1u) != 1u) {
                push_front(2u * job.cand_offset, q);
            }
        }
    }
}

// One front vertex v of a sweep: takes the neighbour that minimises (graph distance + edge
// length) among reached, expandable neighbours, sets its normal coordinates (and smooth state)
// from it, and where they changed queues into the list at `nxt` (stamp `stamp`) the neighbours
// it could now be best for. `orient`: the job's `seed_orient`.
fn relax_vertex(job: GeoJob, base: u32, v: u32, orient: f32, stamp: u32, nxt: u32) {
    let seed_n = job.normal.xyz;
    let c = coords[base + v];
    if (c.w > 1.5) { return; }
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
            // would scan its neighbours and keep what it has (without the check a map's
            // vertices were evaluated 3.9-5 times each).
            if (best <= job.radius && abs(kv) <= job.curvature_stop) {
                for (var k = k_first; k < k_end; k++) {
                    let q = edges[k].x;
                    let cq = coords[base + q];
                    if ((cq.w > 0.5 || cq.z > 1.0e30) && cq.w < 1.5
                        && best + length(positions[q].xyz - pv) <= cq.z) {
                        if (atomicExchange(&marks[base + q], stamp) != stamp) {
                            push_front(nxt, q);
                        }
                    }
                }
            }
        }
    }
}

// The seed triangle set (invocations 0-2) and its neighbours queued as the first front, after the
// candidates were cleared. Called by a whole workgroup in uniform control flow (it has barriers).
fn seed_map(job: GeoJob, base: u32, lid: u32) {
    if (lid < 3u) {
        set_seed(job, base, lid);
    }
    storageBarrier();
    workgroupBarrier();
    if (lid < 3u) {
        queue_seed_neighbours(job, base, lid);
    }
    storageBarrier();
    workgroupBarrier();
}
