// SPDX-License-Identifier: MIT OR Apache-2.0
//! GPU side of the discrete exponential maps: candidate discs (CPU, proportional to the disc) and the
//! one-dispatch relaxation (`wgsl/expmap_relax.wgsl`, one workgroup per decal).

use crate::error::Result;
use crate::geodesic::{Options, Seed};
use crate::gpu_mesh::GpuMesh;
use crate::mesh::Topology;
use crate::pipelines::Pipelines;
use wgpu::util::DeviceExt;

/// One decal's map request. Keep in sync with `GeoJob` in wgsl/expmap_relax.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GeoJob {
    seed: [f32; 4],
    normal: [f32; 4],
    e1: [f32; 4],
    e2: [f32; 4],
    tri: [u32; 4],
    radius: f32,
    curvature_stop: f32,
    cand_offset: u32,
    cand_count: u32,
    vertex_count: u32,
    max_sweeps: u32,
    pad: [u32; 2],
}

/// What the relaxation reports per decal. Keep in sync with `GeoResult` in wgsl/expmap_relax.wgsl.
#[repr(C)]
#[derive(
    Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable, serde::Serialize,
)]
pub struct GeoResult {
    /// Relaxation sweeps run (the last one changed nothing when converged).
    pub sweeps: u32,
    /// Vertices that received coordinates.
    pub reached: u32,
    /// 1 when a sweep changed nothing before the sweep limit.
    pub converged: u32,
    #[serde(skip)]
    pad: u32,
}

/// The vertices a map can reach: connected to the seed triangle through vertices within Euclidean
/// distance 1.5 × `radius` of the seed point, plus one ring. Geodesic distance is never shorter than
/// Euclidean, but the map's distance estimate |u| can be (it is an approximation), so the ball keeps
/// a margin. Cost proportional to the result.
pub fn candidates(topo: &Topology, seed: &Seed, radius: f32) -> Vec<u32> {
    let mut seen = std::collections::HashSet::new();
    let mut out = Vec::new();
    let mut stack = Vec::new();
    for &v in &topo.triangles[seed.triangle as usize] {
        if seen.insert(v) {
            out.push(v);
            stack.push(v);
        }
    }
    while let Some(v) = stack.pop() {
        if (topo.positions[v as usize] - seed.point).length() > 1.5 * radius {
            continue;
        }
        let (a, b) = (
            topo.adjacency_offsets[v as usize] as usize,
            topo.adjacency_offsets[v as usize + 1] as usize,
        );
        for &q in &topo.adjacency[a..b] {
            if seen.insert(q) {
                out.push(q);
                stack.push(q);
            }
        }
    }
    out
}

/// Builds the jobs and candidate lists for `maps` (seed, options, coords slot).
pub fn build_jobs(topo: &Topology, maps: &[(Seed, Options, u32)]) -> (Vec<GeoJob>, Vec<u32>) {
    let mut jobs = Vec::new();
    let mut cands = Vec::new();
    for (seed, opts, slot) in maps {
        let c = candidates(topo, seed, opts.radius);
        let t = topo.triangles[seed.triangle as usize];
        jobs.push(GeoJob {
            seed: seed.point.extend(0.0).to_array(),
            normal: seed.normal.extend(0.0).to_array(),
            e1: seed.e1.extend(0.0).to_array(),
            e2: seed.e2.extend(0.0).to_array(),
            tri: [t[0], t[1], t[2], *slot],
            radius: opts.radius,
            curvature_stop: opts.curvature_stop.min(f32::MAX),
            cand_offset: cands.len() as u32,
            cand_count: c.len() as u32,
            vertex_count: topo.positions.len() as u32,
            // Each sweep settles at least one more ring; four times the candidates is a generous cap.
            max_sweeps: 4 * c.len() as u32 + 16,
            pad: [0; 2],
        });
        cands.extend(c);
    }
    if cands.is_empty() {
        cands.push(0);
    }
    (jobs, cands)
}

/// Records the relaxation of `jobs` into `enc` (one dispatch). `coords` holds one slot of
/// `vertex_count` entries per job slot; the slots used are cleared first.
#[allow(
    clippy::too_many_arguments,
    reason = "the kernel's bindings, in binding order"
)]
pub fn record(
    device: &wgpu::Device,
    pipes: &Pipelines,
    mesh: &GpuMesh,
    jobs: &[GeoJob],
    cands: &[u32],
    coords: &wgpu::Buffer,
    results: &wgpu::Buffer,
    enc: &mut wgpu::CommandEncoder,
) {
    let slot_bytes = mesh.vertex_count as u64 * 16;
    for j in jobs {
        enc.clear_buffer(coords, j.tri[3] as u64 * slot_bytes, Some(slot_bytes));
    }
    let jobs_buf = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("expmap.jobs"),
        contents: bytemuck::cast_slice(jobs),
        usage: wgpu::BufferUsages::STORAGE,
    });
    let cand_buf = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("expmap.candidates"),
        contents: bytemuck::cast_slice(cands),
        usage: wgpu::BufferUsages::STORAGE,
    });
    let bg = pipes.expmap_relax.bind(
        device,
        "expmap.relax",
        &[
            (0, jobs_buf.as_entire_binding()),
            (1, mesh.positions.as_entire_binding()),
            (2, mesh.normals.as_entire_binding()),
            (3, mesh.adjacency_offsets.as_entire_binding()),
            (4, mesh.adjacency.as_entire_binding()),
            (5, mesh.curvature.as_entire_binding()),
            (6, cand_buf.as_entire_binding()),
            (7, coords.as_entire_binding()),
            (8, results.as_entire_binding()),
        ],
    );
    let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
        label: Some("expmap.relax"),
        timestamp_writes: None,
    });
    pass.set_pipeline(&pipes.expmap_relax.pipeline);
    pass.set_bind_group(0, &bg, &[]);
    pass.dispatch_workgroups(jobs.len() as u32, 1, 1);
}

/// Per-vertex result of a GPU map read back: (u, v, distance, state) with state 0 = unreached,
/// 1 = reached, 2 = seed-triangle vertex.
pub type MapCoords = Vec<[f32; 4]>;

/// Computes maps on the GPU and reads them back (for tests, `decalbake param` and benchmarks).
pub fn expmaps_gpu(
    engine: &crate::Engine,
    mesh: &crate::LoadedMesh,
    maps: &[(Seed, Options)],
) -> Result<Vec<(MapCoords, GeoResult)>> {
    let ctx = &engine.ctx;
    let dev = &ctx.device;
    let slots: Vec<(Seed, Options, u32)> = maps
        .iter()
        .enumerate()
        .map(|(i, (s, o))| (*s, *o, i as u32))
        .collect();
    let (jobs, cands) = build_jobs(&mesh.topo, &slots);
    let nv = mesh.gpu.vertex_count as u64;
    let coords_size = (maps.len() as u64 * nv * 16).max(16);
    let results_size = (maps.len() as u64 * 16).max(16);
    let (coords, results) = ctx.scoped("exponential maps", || {
        let coords = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("expmap.coords"),
            size: coords_size,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC
                | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let results = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("expmap.results"),
            size: results_size,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let mut enc = dev.create_command_encoder(&Default::default());
        record(
            dev,
            &engine.pipes,
            &mesh.gpu,
            &jobs,
            &cands,
            &coords,
            &results,
            &mut enc,
        );
        ctx.queue.submit([enc.finish()]);
        (coords, results)
    })?;
    let c = ctx.read_buffer(&coords, coords_size, "expmap read-back")?;
    let r = ctx.read_buffer(&results, results_size, "expmap results read-back")?;
    let c: &[[f32; 4]] = bytemuck::cast_slice(&c);
    let r: &[GeoResult] = bytemuck::cast_slice(&r);
    Ok((0..maps.len())
        .map(|i| (c[i * nv as usize..(i + 1) * nv as usize].to_vec(), r[i]))
        .collect())
}
