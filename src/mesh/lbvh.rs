// SPDX-License-Identifier: MIT OR Apache-2.0
//! The mesh's BVH built on the GPU: a linear BVH after Karras (2012, "Maximizing parallelism in the
//! construction of BVHs, octrees, and k-d trees", §3-4: Morton codes, a sort, each inner node of the
//! radix tree found on its own from the sorted keys), laid out as [`Bvh`] (a node's two children
//! side by side, leaves of at most [`LEAF`] triangles), so `place_bvh`, [`Bvh::any_hit`] and
//! [`Bvh::overlapping`] walk it unchanged. Kernels: `wgsl/mesh/lbvh.wgsl`; CPU twin: [`build_cpu`],
//! which gives the GPU's tree bit for bit where the device rounds adds to nearest and keeps
//! subnormals (Vulkan on lavapipe and NVIDIA; WGSL allows less): the steps are adds, a subtraction,
//! products by a power of two, floors, min/max and integer work, no division and no product
//! followed by an add that a compiler could fuse. Not covered: meshes whose coordinates reach
//! 1e38 (a vertex sum overflows) or whose size is below about 1e-37 (subnormals).
//!
//! The CPU does the set-up (one pass over the triangles: the non-degenerate ones, the bounds, the
//! grid, the box padding: [`Setup`]); the GPU the codes, the sort (bitonic: log₂ N (log₂ N + 1) / 2
//! dispatches over N padded keys, chosen for its size in code, not its work: see docs/performance.md,
//! "Placement"), the tree, the leaves' boxes and the inner boxes level by level from the deepest
//! (one read-back of the depth between). The leaves are four consecutive sorted triangles, keyed
//! for the tree by the first one's code; the leaf index breaks ties between equal codes (§4).
//!
//! Where the two builds differ: the median-split tree ([`Bvh::build`]) is balanced (depth
//! ⌈log₂(n / 4)⌉ + 1); this one is as deep as the codes make it, at most 31 + ⌈log₂ leaves⌉
//! (30 code bits and the leaf index's bits of prefix, and the leaf), within the walk's stack
//! ([`MAX_DEPTH`]) for any mesh of fewer than 2³¹ leaves, so the fallback of [`build_gpu`] is a
//! guard that is not expected to trigger. Queries answer the same on
//! either (the walk's result does not depend on the tree: `tests/placement.rs`).

use super::bvh::{Bvh, BvhNode, LEAF, MAX_DEPTH};
use super::upload::GpuMesh;
use super::Topology;
use crate::error::Result;
use crate::gpu::pipelines::Pipelines;
use crate::gpu::{BufferInit, GpuContext};
use bytemuck::Zeroable;
use glam::Vec3;

/// Grid cells along each axis of the Morton code (10 bits an axis).
const CELLS: f32 = 1024.0;
/// Workgroup size of every entry point (`WG` in lbvh.wgsl).
const WG: u32 = 256;
/// Stride of the per-dispatch steps in their uniform buffer (dynamic offsets need 256 bytes).
const STEP_STRIDE: u64 = 256;

/// What the CPU sets up before the GPU builds (also the twin's first step).
#[derive(Debug, Clone, PartialEq)]
pub struct Setup {
    /// The non-degenerate triangles, ascending.
    pub ids: Vec<u32>,
    /// The grid's origin: the least possible vertex sum, (lo + lo) + lo of the bounds.
    pub lo3: Vec3,
    /// The grid's scale, a power of two: every vertex sum lands in cells 0..1023.
    pub scale: f32,
    /// Box padding, as [`Bvh::build`]'s.
    pub pad: f32,
    /// The longest triangle edge ([`Bvh::max_edge`]).
    pub max_edge: f32,
}

/// Keep in sync with `Params` in lbvh.wgsl.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    n: u32,
    n_pad: u32,
    leaves: u32,
    _p0: u32,
    lo3: [f32; 3],
    scale: f32,
    pad: f32,
    _p1: [u32; 3],
}

/// The set-up of `topo`'s tree, `None` without non-degenerate triangles.
pub fn setup(topo: &Topology) -> Option<Setup> {
    let ids: Vec<u32> = (0..topo.triangles.len() as u32)
        .filter(|&t| !topo.degenerate[t as usize])
        .collect();
    if ids.is_empty() {
        return None;
    }
    let corners = |t: u32| topo.triangles[t as usize].map(|v| topo.positions[v as usize]);
    let (lo, hi) = ids
        .iter()
        .flat_map(|&t| corners(t))
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p), hi.max(p))
        });
    // The same padding as the median-split build.
    let pad = super::bvh::padding(lo, hi);
    let (lo3, hi3) = ((lo + lo) + lo, (hi + hi) + hi);
    let extent = (hi3 - lo3).max_element();
    let mut scale = 1.0f32;
    if extent.is_finite() && extent > 0.0 {
        // The largest power of two with extent × scale < CELLS (exact: a product by 2^k).
        let k = ((CELLS as f64 - 1.0) / extent as f64).log2().floor() as i32;
        scale = 2f32.powi(k.clamp(-126, 127));
        while extent * scale >= CELLS && scale > f32::MIN_POSITIVE {
            scale *= 0.5;
        }
    }
    let max_edge = super::bvh::longest_edge(topo, &ids);
    Some(Setup {
        ids,
        lo3,
        scale,
        pad,
        max_edge,
    })
}

/// 10 bits spread to every third bit.
fn spread_bits(v: u32) -> u32 {
    let mut x = v & 0x3ff;
    x = (x | (x << 16)) & 0x0300_00ff;
    x = (x | (x << 8)) & 0x0300_f00f;
    x = (x | (x << 4)) & 0x030c_30c3;
    (x | (x << 2)) & 0x0924_9249
}

/// Triangle `t`'s Morton code (twin of `morton` in lbvh.wgsl, bit for bit).
pub fn morton(setup: &Setup, topo: &Topology, t: u32) -> u32 {
    let [a, b, c] = topo.triangles[t as usize].map(|v| topo.positions[v as usize]);
    let s = (a + b) + c;
    let q = ((s - setup.lo3).max(Vec3::ZERO) * setup.scale)
        .floor()
        .min(Vec3::splat(CELLS - 1.0));
    (spread_bits(q.x as u32) << 2) | (spread_bits(q.y as u32) << 1) | spread_bits(q.z as u32)
}

/// The radix tree over the leaves' codes (Karras §4): per inner node, its split γ and the two
/// children (true: a leaf). Twin of `karras` in lbvh.wgsl.
fn karras(codes: &[u32]) -> Vec<(u32, bool, bool)> {
    let n = codes.len() as i64;
    let delta = |i: i64, j: i64| -> i64 {
        if j < 0 || j >= n {
            return -1;
        }
        let (a, b) = (codes[i as usize], codes[j as usize]);
        if a == b {
            32 + ((i ^ j) as u32).leading_zeros() as i64
        } else {
            (a ^ b).leading_zeros() as i64
        }
    };
    (0..n - 1)
        .map(|i| {
            let d = if delta(i, i + 1) - delta(i, i - 1) > 0 {
                1
            } else {
                -1
            };
            let dmin = delta(i, i - d);
            let mut lmax = 2;
            while delta(i, i + lmax * d) > dmin {
                lmax *= 2;
            }
            let (mut l, mut t) = (0, lmax / 2);
            while t >= 1 {
                if delta(i, i + (l + t) * d) > dmin {
                    l += t;
                }
                t /= 2;
            }
            let j = i + l * d;
            let dnode = delta(i, j);
            let (mut s, mut div) = (0, 2);
            loop {
                let step = (l + div - 1) / div;
                if delta(i, i + (s + step) * d) > dnode {
                    s += step;
                }
                if step <= 1 {
                    break;
                }
                div *= 2;
            }
            let gamma = i + s * d + d.min(0);
            (gamma as u32, i.min(j) == gamma, i.max(j) == gamma + 1)
        })
        .collect()
}

/// The tree of `topo` built as the GPU builds it, on the CPU: the twin of [`build_gpu`].
pub fn build_cpu(topo: &Topology) -> Bvh {
    let Some(setup) = setup(topo) else {
        return Bvh::default();
    };
    let mut keys: Vec<(u32, u32)> = setup
        .ids
        .iter()
        .map(|&t| (morton(&setup, topo, t), t))
        .collect();
    keys.sort_unstable();
    let n = keys.len();
    let leaves = n.div_ceil(LEAF);
    let codes: Vec<u32> = (0..leaves).map(|g| keys[g * LEAF].0).collect();
    let inner = karras(&codes);
    // Slots: the root at 0, inner node i's children at 2 γ + 1 and 2 γ + 2.
    let mut inner_slot = vec![0u32; inner.len()];
    let mut leaf_slot = vec![0u32; leaves];
    let mut parent = vec![u32::MAX; inner.len()];
    for (i, &(g, left_leaf, right_leaf)) in inner.iter().enumerate() {
        for (child, leaf, slot) in [(g, left_leaf, 2 * g + 1), (g + 1, right_leaf, 2 * g + 2)] {
            if leaf {
                leaf_slot[child as usize] = slot;
            } else {
                inner_slot[child as usize] = slot;
                parent[child as usize] = i as u32;
            }
        }
    }
    let mut nodes = vec![BvhNode::zeroed(); 2 * leaves - 1];
    let pad = Vec3::splat(setup.pad);
    for (g, &slot) in leaf_slot.iter().enumerate() {
        let first = g * LEAF;
        let count = LEAF.min(n - first);
        let (lo, hi) = keys[first..first + count]
            .iter()
            .flat_map(|&(_, t)| topo.triangles[t as usize].map(|v| topo.positions[v as usize]))
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(p), hi.max(p))
            });
        nodes[slot as usize] = BvhNode {
            lo: (lo - pad).to_array(),
            first: first as u32,
            hi: (hi + pad).to_array(),
            count: count as u32,
        };
    }
    let depth: Vec<usize> = (0..inner.len())
        .map(|i| {
            let (mut c, mut d) = (i, 0);
            while c != 0 {
                c = parent[c] as usize;
                d += 1;
            }
            d
        })
        .collect();
    let deepest = depth.iter().copied().max().unwrap_or(0);
    for (i, &(g, _, _)) in inner.iter().enumerate() {
        nodes[inner_slot[i] as usize].first = 2 * g + 1;
    }
    for level in (0..=deepest).rev() {
        for i in (0..inner.len()).filter(|&i| depth[i] == level) {
            let slot = inner_slot[i] as usize;
            let f = nodes[slot].first as usize;
            let (a, b) = (nodes[f], nodes[f + 1]);
            nodes[slot].lo = Vec3::from(a.lo).min(Vec3::from(b.lo)).to_array();
            nodes[slot].hi = Vec3::from(a.hi).max(Vec3::from(b.hi)).to_array();
        }
    }
    Bvh {
        nodes,
        triangles: keys.iter().map(|k| k.1).collect(),
        depth: if inner.is_empty() { 1 } else { deepest + 2 },
        max_edge: setup.max_edge,
    }
}

/// Workgroups for `items` invocations: (x, y), x at most 65,535 (the kernels flatten the two).
fn groups(items: usize) -> (u32, u32) {
    let g = items.div_ceil(WG as usize).max(1) as u32;
    (g.min(65_535), g.div_ceil(65_535))
}

/// The per-dispatch steps, each at its 256-byte slot of one uniform buffer: the bitonic sort's
/// (k, j) over `n_pad` keys, then the levels 0..=[`MAX_DEPTH`] for the boxes. Returns the sort's
/// step count and the bytes.
fn steps(n_pad: usize) -> (usize, Vec<u8>) {
    let mut steps: Vec<[u32; 2]> = Vec::new();
    let mut size = 2;
    while size <= n_pad {
        let mut j = size / 2;
        while j >= 1 {
            steps.push([size as u32, j as u32]);
            j /= 2;
        }
        size *= 2;
    }
    let sort_steps = steps.len();
    steps.extend((0..=MAX_DEPTH as u32).map(|l| [l, 0]));
    let mut bytes = vec![0u8; steps.len() * STEP_STRIDE as usize];
    for (s, v) in steps.iter().enumerate() {
        let at = s * STEP_STRIDE as usize;
        bytes[at..at + 8].copy_from_slice(bytemuck::cast_slice(v));
    }
    (sort_steps, bytes)
}

/// Builds `topo`'s tree on the GPU from `mesh`'s positions and triangles (uploaded from `topo`),
/// and reads it back: the same tree as [`build_cpu`]. Two submissions: the codes, sort, tree and
/// leaves, then the inner boxes once the depth is known. `None` when the tree would be deeper than
/// the walk's stack allows ([`MAX_DEPTH`]; the caller builds on the CPU instead).
pub fn build_gpu(
    ctx: &GpuContext,
    pipes: &Pipelines,
    mesh: &GpuMesh,
    topo: &Topology,
) -> Result<Option<Bvh>> {
    const STAGE: &str = "BVH build";
    let Some(setup) = setup(topo) else {
        return Ok(Some(Bvh::default()));
    };
    let n = setup.ids.len();
    let n_pad = n.next_power_of_two().max(2);
    let leaves = n.div_ceil(LEAF);
    let node_count = 2 * leaves - 1;
    ctx.fits(
        || format!("the BVH's sort keys ({n_pad} entries)"),
        8 * n_pad as u64,
        "a smaller mesh",
    )?;
    let k = &*pipes.lbvh;
    let dev = &ctx.device;
    let params = Params {
        n: n as u32,
        n_pad: n_pad as u32,
        leaves: leaves as u32,
        _p0: 0,
        lo3: setup.lo3.to_array(),
        scale: setup.scale,
        pad: setup.pad,
        _p1: [0; 3],
    };
    let (sort_steps, step_bytes) = steps(n_pad);
    let (ids, uni, step, keys, nodes, links, deepest) = ctx.scoped(STAGE, || {
        let storage = |label: &str, size: usize, extra: wgpu::BufferUsages| {
            dev.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: size.max(16) as u64,
                usage: wgpu::BufferUsages::STORAGE | extra,
                mapped_at_creation: false,
            })
        };
        let copy = wgpu::BufferUsages::COPY_SRC;
        (
            ctx.storage_init(
                "lbvh.ids",
                bytemuck::cast_slice(&setup.ids),
                wgpu::BufferUsages::empty(),
            ),
            ctx.uniform_init("lbvh.params", bytemuck::bytes_of(&params)),
            dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("lbvh.steps"),
                contents: &step_bytes,
                usage: wgpu::BufferUsages::UNIFORM,
            }),
            storage("lbvh.keys", 8 * n_pad, copy),
            storage("lbvh.nodes", 32 * node_count, copy),
            storage("lbvh.links", 4 * (5 * leaves), wgpu::BufferUsages::empty()),
            ctx.storage_init("lbvh.deepest", &[0u8; 4], copy),
        )
    })?;
    let step_binding = wgpu::BufferBinding {
        buffer: &step,
        offset: 0,
        size: std::num::NonZeroU64::new(8),
    };
    let group = crate::gpu::pipelines::make_bind_group(
        dev,
        &k.layout,
        "lbvh",
        &[
            (0, mesh.positions.as_entire_binding()),
            (1, mesh.tris.as_entire_binding()),
            (2, ids.as_entire_binding()),
            (3, uni.as_entire_binding()),
            (4, keys.as_entire_binding()),
            (5, wgpu::BindingResource::Buffer(step_binding)),
            (6, nodes.as_entire_binding()),
            (7, links.as_entire_binding()),
            (8, deepest.as_entire_binding()),
        ],
    );
    let dispatch = |pass: &mut wgpu::ComputePass<'_>,
                    pipe: &wgpu::ComputePipeline,
                    step: usize,
                    items: usize| {
        pass.set_pipeline(pipe);
        pass.set_bind_group(0, &group, &[(step as u64 * STEP_STRIDE) as u32]);
        let (x, y) = groups(items);
        pass.dispatch_workgroups(x, y, 1);
    };
    let mut enc = dev.create_command_encoder(&Default::default());
    {
        let mut pass = enc.begin_compute_pass(&Default::default());
        dispatch(&mut pass, &k.morton, 0, n_pad);
        for s in 0..sort_steps {
            dispatch(&mut pass, &k.bitonic, s, n_pad / 2);
        }
        if leaves > 1 {
            dispatch(&mut pass, &k.karras, 0, leaves - 1);
        }
        dispatch(&mut pass, &k.leaves, 0, leaves);
        if leaves > 1 {
            dispatch(&mut pass, &k.inner, 0, leaves - 1);
        }
    }
    ctx.scoped(STAGE, || ctx.queue.submit([enc.finish()]))?;
    let deepest_level = u32::from_le_bytes(
        ctx.read_buffer(&deepest, 4, STAGE)?[..4]
            .try_into()
            .expect("4 bytes"),
    ) as usize;
    if deepest_level + 2 > MAX_DEPTH {
        return Ok(None);
    }
    if leaves > 1 {
        let mut enc = dev.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            for level in (0..=deepest_level).rev() {
                dispatch(&mut pass, &k.boxes, sort_steps + level, leaves - 1);
            }
        }
        ctx.scoped(STAGE, || ctx.queue.submit([enc.finish()]))?;
    }
    let node_bytes = ctx.read_buffer(&nodes, 32 * node_count as u64, STAGE)?;
    let key_bytes = ctx.read_buffer(&keys, 8 * n as u64, STAGE)?;
    let keys: &[[u32; 2]] = bytemuck::cast_slice(&key_bytes);
    Ok(Some(Bvh {
        nodes: bytemuck::cast_slice(&node_bytes).to_vec(),
        triangles: keys.iter().map(|k| k[1]).collect(),
        depth: if leaves > 1 { deepest_level + 2 } else { 1 },
        max_edge: setup.max_edge,
    }))
}
