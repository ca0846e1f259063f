// SPDX-License-Identifier: MIT OR Apache-2.0
//! `decalbake bench --device`: what the current adapter charges for the things the engine's kernels
//! are built from, measured with the probe kernels of `wgsl/gpu/device_probe.wgsl`. One JSON line per
//! figure:
//!
//! - `copy`: streaming-copy bandwidth (read + write, GB/s), the reference for memory-bound kernels;
//! - `dispatch`: the cost of one almost empty dispatch (many in one pass, one submission);
//! - `submit_wait`: one submission of one dispatch followed by a blocking wait;
//! - `barrier`: a workgroup barrier inside a 64-wide workgroup's loop (the difference between a
//!   loop with two barriers a round and the same loop without);
//! - `atomic`: an atomic add to one counter shared by every invocation, and to a private counter;
//! - `dense_small_systems`: many 16 × 16 dense Jacobi solves, one per invocation against one per
//!   16-wide workgroup (same arithmetic, same results), systems per second;
//! - `loads`: storage loads from a cached 1 MiB buffer, with every lane at the same address, the
//!   lanes of a workgroup on neighbouring addresses, and every lane at its own random address (a
//!   gather): the device's time a load (the whole device's wall time over all its loads, less the
//!   same loop without loads), against one round of the same gather loop in plain Rust on one
//!   CPU thread (`gather_cpu`) in the same run.

use decalbake::error::Result;
use decalbake::gpu::GpuContext;
use decalbake::Engine;
use std::time::Instant;
use wgpu::util::DeviceExt;

/// The probe's pipelines and buffers.
struct Probe<'a> {
    ctx: &'a GpuContext,
    layout: wgpu::BindGroupLayout,
    module: wgpu::ShaderModule,
    data: wgpu::Buffer,
    counters: wgpu::Buffer,
}

/// Largest workgroup count a probe dispatches (its output buffers are sized for it).
const MAX_GROUPS: u32 = 4096;

impl<'a> Probe<'a> {
    fn new(ctx: &'a GpuContext) -> Self {
        let dev = &ctx.device;
        let storage = |binding| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only: false },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let layout = dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("probe"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                storage(1),
                storage(2),
            ],
        });
        let module = decalbake::gpu::shaders::module(dev, "device_probe");
        let buf = |label, bytes: u64| {
            dev.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            })
        };
        Self {
            ctx,
            data: buf("probe.data", MAX_GROUPS as u64 * 64 * 4),
            counters: buf("probe.counters", (MAX_GROUPS as u64 * 64 + 1) * 4),
            layout,
            module,
        }
    }

    /// The pipeline of entry point `entry` and a bind group for `groups` workgroups, `reps` rounds.
    fn kernel(
        &self,
        entry: &str,
        groups: u32,
        reps: u32,
    ) -> (wgpu::ComputePipeline, wgpu::BindGroup) {
        let dev = &self.ctx.device;
        let pl = dev.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("probe"),
            bind_group_layouts: &[Some(&self.layout)],
            immediate_size: 0,
        });
        let pipeline = dev.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(entry),
            layout: Some(&pl),
            module: &self.module,
            entry_point: Some(entry),
            compilation_options: Default::default(),
            cache: None,
        });
        let uniform = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("probe.params"),
            contents: bytemuck::cast_slice(&[groups, reps, 0, 0]),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let bg = dev.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(entry),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: uniform.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: self.data.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: self.counters.as_entire_binding(),
                },
            ],
        });
        (pipeline, bg)
    }

    /// Seconds for `dispatches` dispatches of `groups` workgroups of `entry` in one pass, one
    /// submission and a wait (after one warm-up run).
    fn time(&self, entry: &str, groups: u32, reps: u32, dispatches: u32) -> Result<f64> {
        let (pipeline, bg) = self.kernel(entry, groups, reps);
        let run = || -> Result<f64> {
            let t = Instant::now();
            self.ctx.scoped("device probe", || {
                let mut enc = self.ctx.device.create_command_encoder(&Default::default());
                {
                    let mut pass = enc.begin_compute_pass(&Default::default());
                    pass.set_pipeline(&pipeline);
                    pass.set_bind_group(0, &bg, &[]);
                    for _ in 0..dispatches {
                        pass.dispatch_workgroups(groups, 1, 1);
                    }
                }
                self.ctx.queue.submit([enc.finish()]);
            })?;
            self.ctx.wait("device probe")?;
            Ok(t.elapsed().as_secs_f64())
        };
        run()?;
        run()
    }

    /// The first `n` values of the data buffer.
    fn read(&self, n: usize) -> Result<Vec<f32>> {
        let bytes = self
            .ctx
            .read_buffer(&self.data, n as u64 * 4, "device probe read-back")?;
        Ok(bytemuck::cast_slice(&bytes).to_vec())
    }
}

/// Runs the probe, calling `emit` per figure.
pub fn run(engine: &Engine, mut emit: impl FnMut(serde_json::Value)) -> Result<()> {
    let ctx = &engine.ctx;
    let p = Probe::new(ctx);
    let gbs = decalbake::solve::gpu::copy_bandwidth(ctx, engine.pipelines(), 64 << 20, 20)?;
    emit(serde_json::json!({ "probe": "copy", "bytes": 64u64 << 20, "gb_per_s": gbs }));

    let n = 2000;
    let one = p.time("empty", 1, 0, 1)?;
    let many = p.time("empty", 1, 0, n)?;
    emit(serde_json::json!({ "probe": "dispatch", "dispatches": n,
        "us_per_dispatch": (many - one) / (n - 1) as f64 * 1e6 }));

    let (pipeline, bg) = p.kernel("empty", 1, 0);
    let rounds = 200;
    let t = Instant::now();
    for _ in 0..rounds {
        ctx.scoped("device probe", || {
            let mut enc = ctx.device.create_command_encoder(&Default::default());
            {
                let mut pass = enc.begin_compute_pass(&Default::default());
                pass.set_pipeline(&pipeline);
                pass.set_bind_group(0, &bg, &[]);
                pass.dispatch_workgroups(1, 1, 1);
            }
            ctx.queue.submit([enc.finish()]);
        })?;
        ctx.wait("device probe")?;
    }
    emit(
        serde_json::json!({ "probe": "submit_wait", "rounds": rounds,
        "us_per_submit_wait": t.elapsed().as_secs_f64() / rounds as f64 * 1e6 }),
    );

    let (groups, reps) = (256, 2000);
    let with = p.time("with_barrier", groups, reps, 1)?;
    let without = p.time("no_barrier", groups, reps, 1)?;
    let barriers = 2.0 * reps as f64 * groups as f64;
    emit(
        serde_json::json!({ "probe": "barrier", "workgroups": groups, "workgroup_size": 64,
        "rounds": reps, "ms_with": with * 1e3, "ms_without": without * 1e3,
        "ns_per_workgroup_barrier": (with - without) / barriers * 1e9,
        "ratio_with_over_without": with / without }),
    );

    let (groups, reps) = (64, 1000);
    let shared = p.time("atomic_shared", groups, reps, 1)?;
    let private = p.time("atomic_private", groups, reps, 1)?;
    let ops = groups as f64 * 64.0 * reps as f64;
    emit(
        serde_json::json!({ "probe": "atomic", "invocations": groups * 64, "adds_each": reps,
        "ns_per_shared_add": shared / ops * 1e9, "ns_per_private_add": private / ops * 1e9,
        "no_barrier_loop_ns_per_round": without / (256.0 * 64.0 * 2000.0) * 1e9 }),
    );

    let (systems, sweeps) = (MAX_GROUPS, 30);
    let per_inv = p.time("dense_per_invocation", systems / 64, sweeps, 1)?;
    let a = p.read(systems as usize)?;
    let per_wg = p.time("dense_per_workgroup", systems, sweeps, 1)?;
    let b = p.read(systems as usize)?;
    let max_diff = a
        .iter()
        .zip(&b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0f32, f32::max);
    emit(
        serde_json::json!({ "probe": "dense_small_systems", "systems": systems, "dim": 16,
        "sweeps": sweeps, "per_invocation_systems_per_s": systems as f64 / per_inv,
        "per_workgroup_systems_per_s": systems as f64 / per_wg,
        "per_invocation_over_per_workgroup": per_wg / per_inv,
        "max_difference": max_diff }),
    );
    loads(&p, &mut emit)
}

/// The `loads` figure: the three gather probes, less the same loop without its loads
/// (`gather_none`), and the divergent loop's CPU twin on one thread (the best of four runs; its
/// sum and address chains bound it too, so it understates how fast the CPU loads).
fn loads(p: &Probe, emit: &mut impl FnMut(serde_json::Value)) -> Result<()> {
    let (groups, reps) = (256u32, 4000u32);
    let count = groups as f64 * 64.0 * reps as f64;
    let none = p.time("gather_none", groups, reps, 1)?;
    let net_ns = |entry| -> Result<f64> {
        Ok((p.time(entry, groups, reps, 1)? - none).max(0.0) / count * 1e9)
    };
    let uniform = net_ns("gather_uniform")?;
    let contiguous = net_ns("gather_contiguous")?;
    let divergent = net_ns("gather_divergent")?;
    let table = vec![0.5f32; GATHER_WORDS];
    let invocations = 1024u32;
    let mut cpu = f64::INFINITY;
    let mut sum = 0.0f32;
    for _ in 0..4 {
        let t = Instant::now();
        for g in 0..invocations {
            let seed = g.wrapping_mul(2654435761).wrapping_add(1);
            sum += gather_cpu(std::hint::black_box(&table), seed, reps);
        }
        cpu = cpu.min(t.elapsed().as_secs_f64() / (invocations as f64 * reps as f64) * 1e9);
    }
    std::hint::black_box(sum);
    emit(
        serde_json::json!({ "probe": "loads", "loads": count, "buffer_bytes": GATHER_WORDS * 4,
        "loop_only_ns_per_round": none / count * 1e9,
        "uniform_ns_per_load": uniform, "contiguous_ns_per_load": contiguous,
        "divergent_ns_per_load": divergent, "cpu_thread_ns_per_divergent_round": cpu,
        "device_divergent_load_over_cpu_round": divergent / cpu,
        "divergent_over_contiguous": divergent / contiguous }),
    );
    Ok(())
}

/// Words the gather probes read from (`GATHER_MASK` + 1 in `device_probe.wgsl`): the probe's
/// data buffer, `MAX_GROUPS` × 64 words.
const GATHER_WORDS: usize = 1 << 18;
const _: () = assert!(GATHER_WORDS == MAX_GROUPS as usize * 64);

/// CPU twin of `gather` in `wgsl/gpu/device_probe.wgsl` with a lane's own start (`gather_divergent`):
/// `reps` loads at addresses from the same linear congruential step.
fn gather_cpu(table: &[f32], seed: u32, reps: u32) -> f32 {
    let mut h = seed;
    let mut acc = 0.0;
    for _ in 0..reps {
        h = h.wrapping_mul(1664525).wrapping_add(1013904223);
        acc += table[(h >> 14) as usize & (GATHER_WORDS - 1)];
    }
    acc
}
