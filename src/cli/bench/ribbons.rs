// SPDX-License-Identifier: MIT OR Apache-2.0
//! `decalbake bench --ribbons`: the extended exponential map of a curve (`maps::ribbon`, Sun et al.
//! 2013 §3) on the GPU against its CPU twin, one JSON line per mesh: a curve of `samples` pieces
//! along the mesh's edges, a strip 2 % of the mesh's bounding-box diagonal wide (1 % each side);
//! time of the GPU map (set-up, relaxation, status read-back; the coordinates stay on the GPU, as
//! in a bake) and of the twin, the strip's vertices,
//! sweeps and the cost per strip vertex. Issue 13's target: the cost follows the strip, not the
//! mesh (per strip vertex within 1.2× between bob subdivided twice, 171k triangles, and the bunny
//! subdivided twice, 1.1M).

use super::common::median;
use decalbake::maps::ribbon::gpu::{ribbon_gpu, run as ribbon_run, Output, Scratch};
use decalbake::maps::ribbon::{ribbon_cpu, Curve};
use decalbake::mesh::{Mesh, Topology};
use decalbake::Engine;
use glam::Vec3;
use std::time::Instant;

/// A curve of `pieces` mesh edges: from the vertex farthest along −x, each step to the unvisited
/// neighbour whose edge points most along +x (the greedy walk stops early only in a dead end).
pub fn edge_curve(topo: &Topology, pieces: usize) -> Curve {
    let n = topo.positions.len();
    let start = (0..n)
        .filter(|&v| topo.vertex_triangle_offsets[v] < topo.vertex_triangle_offsets[v + 1])
        .min_by(|&a, &b| topo.positions[a].x.total_cmp(&topo.positions[b].x))
        .expect("a mesh with triangles");
    let mut visited = vec![false; n];
    let (mut points, mut triangles) = (vec![topo.positions[start]], Vec::new());
    let mut v = start;
    visited[v] = true;
    for _ in 0..pieces {
        let (a, b) = (
            topo.adjacency_offsets[v] as usize,
            topo.adjacency_offsets[v + 1] as usize,
        );
        let along = |w: u32| {
            let d = topo.positions[w as usize] - topo.positions[v];
            d.dot(Vec3::X) / d.length().max(1e-30)
        };
        let Some(&w) = topo.adjacency[a..b]
            .iter()
            .filter(|&&w| !visited[w as usize])
            .max_by(|&&p, &&q| along(p).total_cmp(&along(q)))
        else {
            break;
        };
        let (s, e) = (
            topo.vertex_triangle_offsets[v] as usize,
            topo.vertex_triangle_offsets[v + 1] as usize,
        );
        let tri = topo.vertex_triangles[s..e]
            .iter()
            .copied()
            .find(|&t| topo.triangles[t as usize].contains(&w))
            .expect("an edge has a triangle");
        triangles.push(tri);
        points.push(topo.positions[w as usize]);
        visited[w as usize] = true;
        v = w as usize;
    }
    Curve { points, triangles }
}

/// Runs the benchmark on `meshes` (name, mesh, subdivisions); JSON lines through `emit`.
pub fn run(
    engine: &Engine,
    meshes: Vec<(String, Mesh, u32)>,
    samples: usize,
    reps: usize,
    mut emit: impl FnMut(serde_json::Value),
) -> anyhow::Result<()> {
    for (name, mut mesh, levels) in meshes {
        for _ in 0..levels {
            mesh = mesh.subdivide();
        }
        let loaded = engine.prepare(mesh)?;
        let topo = &loaded.topo;
        let (lo, hi) = topo.positions.iter().fold(
            (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
            |(lo, hi), p| (lo.min(*p), hi.max(*p)),
        );
        let reach = 0.01 * (hi - lo).length();
        let curve = edge_curve(topo, samples);
        let length: f32 = curve
            .points
            .windows(2)
            .map(|w| (w[1] - w[0]).length())
            .sum();
        // Warm: the pipelines compiled. The coordinates and the scratch are made once per mesh,
        // as a bake's are; a map's time is its set-up, relaxation and status read-back.
        let (ctx, pipes, surface) = (&engine.ctx, engine.pipelines(), loaded.surface_ref());
        ribbon_gpu(ctx, pipes, surface, &curve, reach)?;
        let scratch = Scratch::new(ctx, loaded.gpu.vertex_count)?;
        let coords = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("bench.ribbon_coords"),
            size: loaded.gpu.vertex_count as u64 * 16,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        let (mut gpu_ms, mut cpu_ms) = (Vec::new(), Vec::new());
        let mut status = Default::default();
        let mut strip = 0;
        for _ in 0..reps.max(1) {
            let t = Instant::now();
            let out = (&coords, Output::PLAIN);
            let (s, _) = ribbon_run(ctx, pipes, surface, (&curve, reach), out, &scratch)?;
            gpu_ms.push(t.elapsed().as_secs_f64() * 1e3);
            status = s;
            let t = Instant::now();
            let twin = ribbon_cpu(topo, &curve, reach);
            cpu_ms.push(t.elapsed().as_secs_f64() * 1e3);
            strip = (0..topo.positions.len())
                .filter(|&v| twin.reached(v))
                .count();
        }
        let (g, c) = (median(gpu_ms), median(cpu_ms));
        emit(serde_json::json!({
            "bench": "ribbons", "mesh": name, "subdivisions": levels,
            "triangles": topo.triangles.len(), "vertices": topo.positions.len(),
            "curve_pieces": curve.triangles.len(), "curve_length": length, "reach": reach,
            "strip_vertices": strip, "gpu": status,
            "gpu_ms": g, "cpu_twin_ms": c, "gpu_vs_twin": g / c,
            "gpu_ns_per_strip_vertex": g * 1e6 / strip.max(1) as f64,
            "gpu_ns_per_candidate_sweep":
                g * 1e6 / (status.candidates.max(1) as f64 * status.sweeps.max(1) as f64),
            "cpu_ns_per_strip_vertex": c * 1e6 / strip.max(1) as f64,
            "adapter": engine.ctx.adapter,
        }));
    }
    Ok(())
}
