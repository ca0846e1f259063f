// SPDX-License-Identifier: MIT OR Apache-2.0
// Probe kernels for `decalbake bench --device` (src/cli/bench/device.rs): each entry point isolates
// one cost of the adapter. Not used by bakes.

struct Probe {
    // Workgroups dispatched (the probes index their output by it).
    groups: u32,
    // Rounds of the probe's loop.
    reps: u32,
    pad0: u32,
    pad1: u32,
}

@group(0) @binding(0) var<uniform> probe: Probe;
@group(0) @binding(1) var<storage, read_write> data: array<f32>;
@group(0) @binding(2) var<storage, read_write> counters: array<atomic<u32>>;

var<workgroup> lanes: array<f32, 64>;

// Does nothing: the cost of a dispatch.
@compute @workgroup_size(64)
fn empty() {}

// `reps` rounds of a shared-memory exchange with two workgroup barriers each.
@compute @workgroup_size(64)
fn with_barrier(@builtin(local_invocation_index) l: u32, @builtin(workgroup_id) w: vec3<u32>) {
    var x = f32(l);
    for (var i = 0u; i < probe.reps; i++) {
        lanes[l] = x;
        workgroupBarrier();
        x = x * 0.999 + lanes[(l + 1u) % 64u];
        workgroupBarrier();
    }
    data[w.x * 64u + l] = x;
}

// The same rounds reading the invocation's own slot, without barriers: the baseline.
@compute @workgroup_size(64)
fn no_barrier(@builtin(local_invocation_index) l: u32, @builtin(workgroup_id) w: vec3<u32>) {
    var x = f32(l);
    for (var i = 0u; i < probe.reps; i++) {
        lanes[l] = x;
        x = x * 0.999 + lanes[l];
    }
    data[w.x * 64u + l] = x;
}

// `reps` atomic additions by every invocation to one shared counter.
@compute @workgroup_size(64)
fn atomic_shared(@builtin(global_invocation_id) g: vec3<u32>) {
    for (var i = 0u; i < probe.reps; i++) {
        atomicAdd(&counters[0], 1u);
    }
}

// `reps` atomic additions by every invocation to its own counter.
@compute @workgroup_size(64)
fn atomic_private(@builtin(global_invocation_id) g: vec3<u32>) {
    for (var i = 0u; i < probe.reps; i++) {
        atomicAdd(&counters[1u + g.x], 1u);
    }
}

// A small dense problem: `reps` Jacobi sweeps on the 16 x 16 system A x = b of system `s`, with
// A = 20 I + (the cosine pattern below) (diagonally dominant) and b_i = 1 + i + s.
const DIM: u32 = 16u;

fn entry(s: u32, i: u32, j: u32) -> f32 {
    if i == j {
        return 20.0;
    }
    return cos(f32(i * 7u + j * 3u + s));
}

// One system per invocation: the whole sweep in the invocation's registers.
@compute @workgroup_size(64)
fn dense_per_invocation(@builtin(global_invocation_id) g: vec3<u32>) {
    let s = g.x;
    var x: array<f32, 16>;
    var y: array<f32, 16>;
    for (var r = 0u; r < probe.reps; r++) {
        for (var i = 0u; i < DIM; i++) {
            var acc = 1.0 + f32(i + s);
            for (var j = 0u; j < DIM; j++) {
                if j != i {
                    acc -= entry(s, i, j) * x[j];
                }
            }
            y[i] = acc / 20.0;
        }
        x = y;
    }
    data[s] = x[0];
}

var<workgroup> xs: array<f32, 16>;

// One system per workgroup of 16: invocation i owns row i; two barriers a sweep.
@compute @workgroup_size(16)
fn dense_per_workgroup(@builtin(local_invocation_index) i: u32, @builtin(workgroup_id) w: vec3<u32>) {
    let s = w.x;
    xs[i] = 0.0;
    workgroupBarrier();
    for (var r = 0u; r < probe.reps; r++) {
        var acc = 1.0 + f32(i + s);
        for (var j = 0u; j < DIM; j++) {
            if j != i {
                acc -= entry(s, i, j) * xs[j];
            }
        }
        workgroupBarrier();
        xs[i] = acc / 20.0;
        workgroupBarrier();
    }
    if i == 0u {
        data[s] = xs[0];
    }
}

// Loads from `data` (262,144 words, 1 MiB: it fits the caches, so these time the load itself, not
// memory): `reps` of them an invocation, each address from a linear congruential step. `seed` picks
// the step's start (the same for every invocation, or its own) and `offset` is added to the
// address (the invocation's place in its workgroup, or 0). The three loading entry points differ
// only in those two: every lane the same address, the lanes of a workgroup on neighbouring
// addresses (a CSR row's entries), every lane its own random address (a gather through column
// indices, as the CG's and the relaxations' neighbour scans make). `gather_none` runs the same
// loop with the address's bits summed instead of loaded: the loop's own cost, which the bench
// subtracts. CPU twin: `gather_cpu` in src/cli/bench/device.rs (the divergent loop on one thread).
const GATHER_MASK: u32 = 262143u;

fn gather(seed: u32, offset: u32, load: bool) -> f32 {
    var h = seed;
    var acc = 0.0;
    for (var i = 0u; i < probe.reps; i++) {
        h = h * 1664525u + 1013904223u;
        let a = ((h >> 14u) + offset) & GATHER_MASK;
        if load {
            acc += data[a];
        } else {
            acc += f32(a);
        }
    }
    return acc;
}

// Keeps the loop alive: the sum goes to `counters` (never read by the gathers).
fn keep(g: u32, acc: f32) {
    atomicStore(&counters[1u + g], bitcast<u32>(acc));
}

@compute @workgroup_size(64)
fn gather_none(@builtin(global_invocation_id) g: vec3<u32>) {
    keep(g.x, gather(g.x * 2654435761u + 1u, 0u, false));
}

@compute @workgroup_size(64)
fn gather_uniform(@builtin(global_invocation_id) g: vec3<u32>) {
    keep(g.x, gather(1u, 0u, true));
}

@compute @workgroup_size(64)
fn gather_contiguous(@builtin(global_invocation_id) g: vec3<u32>, @builtin(local_invocation_index) l: u32) {
    keep(g.x, gather(1u, l, true));
}

@compute @workgroup_size(64)
fn gather_divergent(@builtin(global_invocation_id) g: vec3<u32>) {
    keep(g.x, gather(g.x * 2654435761u + 1u, 0u, true));
}
