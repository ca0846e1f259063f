// SPDX-License-Identifier: MIT OR Apache-2.0
// One large exponential map spread over many workgroups (off by default: slower on lavapipe,
// see `SPREAD_MIN_CANDIDATES_OVERRIDE` in src/maps/expmap/gpu.rs): the relaxation of `expmap_relax` (the
// same update of a front vertex, shared/expmap_relax_common.wgsl, so the same fixed point), but a
// sweep is one dispatch over the front, one invocation a front vertex, in as many workgroups as
// the front needs, instead of a loop inside one workgroup. On lavapipe a single map in one
// workgroup ran on one of the two cores; on a GPU, on one of its many. Five entry points:
//   clear    the candidates and halo (one invocation each)
//   seed     the seed triangle and the first front (one workgroup)
//   sweep    one sweep (indirect: `args` words 0-2, written by `advance`)
//   advance  the next front becomes the current one; the next sweep's and `finish`'s sizes
//   finish   the reached vertices counted once the map has converged or met its sweep cap
//            (indirect: `args` words 4-6, 0 workgroups until then)
// The host records `clear`, `seed`, then (`sweep`, `advance`) pairs and `finish` a submission, and
// reads back `results` between submissions (src/maps/expmap/gpu.rs, `run_spread`). Across
// workgroups a sweep's reads of a neighbour may be stale (an older, larger distance, or a vec4
// half written): the neighbour changed, so it queued the reader for the next sweep (every change
// queues the neighbours it could now be best for), whose dispatch sees the new value; the fixed
// point is the one-workgroup kernel's, and `tests/expmap.rs` compares the two byte for byte.
// CPU twin: `dem_cpu` in src/maps/expmap/cpu.rs. Job: `jobs[0]`.
#import expmap
#import expmap_relax_common

// The front's vertices a workgroup of `sweep` takes (`advance` sizes its dispatch).
const WG: u32 = 64u;
// Workgroup of `clear` and `finish`. Keep in sync with `SPREAD_WG_WIDE` in src/maps/expmap/gpu.rs.
const WG_WIDE: u32 = 256u;

// The map's GeoResult (src/maps/expmap/gpu.rs) as words: sweeps, reached, converged, 0.
@group(0) @binding(8) var<storage, read_write> results: array<atomic<u32>>;
// Words: 0 front length, 1 parity of the current front list, 2 sweep stamp, 3 sweeps so far,
// 4 the next front's length (appended to by `push_front`).
@group(0) @binding(10) var<storage, read_write> sstate: array<atomic<u32>>;
// The indirect dispatches' sizes: words 0-2 `sweep`'s, 4-6 `finish`'s. A buffer of its own, bound
// only to the entry points that write it (`sweep` and `finish` get a stand-in: a buffer may not be
// bound for storage and read as indirect arguments in one dispatch). Keep in sync with
// `SPREAD_ARGS_BYTES` in src/maps/expmap/gpu.rs.
@group(0) @binding(14) var<storage, read_write> args: array<u32>;

fn push_front(at: u32, q: u32) {
    fronts[at + atomicAdd(&sstate[4], 1u)] = q;
}

// The flat invocation index of a dispatch laid out as (x, y) workgroups of `width`.
fn flat_index(gid: vec3<u32>, groups: vec3<u32>, width: u32) -> u32 {
    return gid.y * groups.x * width + gid.x;
}

@compute @workgroup_size(WG_WIDE)
fn clear(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let job = jobs[0];
    let i = flat_index(gid, groups, WG_WIDE);
    if (i < job.cand_count + job.halo_count) {
        clear_candidate(job, job.tri.w * job.vertex_count, i);
    }
}

// Writes the sizes of the next `sweep` and of `finish` for a front of `len` after `sweeps`
// sweeps, and the map's status.
fn schedule(job: GeoJob, len: u32, sweeps: u32) {
    let live = len != 0u && sweeps < job.max_sweeps;
    args[0] = select(0u, min((len + WG - 1u) / WG, 65535u), live);
    args[1] = 1u;
    args[2] = 1u;
    let groups = (job.cand_count + WG_WIDE - 1u) / WG_WIDE;
    args[4] = select(min(groups, 65535u), 0u, live);
    args[5] = select((groups + 65534u) / 65535u, 1u, live);
    args[6] = 1u;
    atomicStore(&results[0], sweeps);
    atomicStore(&results[1], 0u);
    atomicStore(&results[2], select(0u, 1u, len == 0u));
    atomicStore(&results[3], 0u);
}

@compute @workgroup_size(WG)
fn seed(@builtin(local_invocation_index) lid: u32) {
    let job = jobs[0];
    let base = job.tri.w * job.vertex_count;
    if (lid == 0u) {
        atomicStore(&sstate[4], 0u);
    }
    seed_map(job, base, lid);
    if (lid == 0u) {
        let len = atomicLoad(&sstate[4]);
        atomicStore(&sstate[0], len);
        atomicStore(&sstate[1], 0u);
        atomicStore(&sstate[2], 2u);
        atomicStore(&sstate[3], 0u);
        atomicStore(&sstate[4], 0u);
        schedule(job, len, 0u);
    }
}

@compute @workgroup_size(WG)
fn sweep(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let job = jobs[0];
    let len = atomicLoad(&sstate[0]);
    let parity = atomicLoad(&sstate[1]);
    let stamp = atomicLoad(&sstate[2]);
    let cur = 2u * job.cand_offset + parity * job.cand_count;
    let nxt = 2u * job.cand_offset + (1u - parity) * job.cand_count;
    if (gid.x >= len) { return; }
    let base = job.tri.w * job.vertex_count;
    let orient = seed_orient(job);
    // One front vertex an invocation (more only past 65,535 workgroups).
    for (var i = gid.x; i < len; i += groups.x * WG) {
        relax_vertex(job, base, fronts[cur + i], orient, stamp, nxt);
    }
}

@compute @workgroup_size(1)
fn advance() {
    let job = jobs[0];
    var len = atomicLoad(&sstate[0]);
    var sweeps = atomicLoad(&sstate[3]);
    if (len != 0u && sweeps < job.max_sweeps) {
        len = atomicLoad(&sstate[4]);
        sweeps += 1u;
        atomicStore(&sstate[0], len);
        atomicStore(&sstate[1], 1u - atomicLoad(&sstate[1]));
        atomicStore(&sstate[2], atomicLoad(&sstate[2]) + 1u);
        atomicStore(&sstate[3], sweeps);
        atomicStore(&sstate[4], 0u);
    }
    schedule(job, len, sweeps);
}

var<workgroup> counted: atomic<u32>;

@compute @workgroup_size(WG_WIDE)
fn finish(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let job = jobs[0];
    let i = flat_index(gid, groups, WG_WIDE);
    if (i < job.cand_count) {
        if (coords[job.tri.w * job.vertex_count + candidates[job.cand_offset + i]].w > 0.5) {
            atomicAdd(&counted, 1u);
        }
    }
    workgroupBarrier();
    if (lid == 0u) {
        atomicAdd(&results[1], atomicLoad(&counted));
    }
}
