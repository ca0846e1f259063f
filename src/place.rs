// SPDX-License-Identifier: MIT OR Apache-2.0
//! Placement: snapping a layer's point to the closest surface point, or casting its ray, on the GPU.
//!
//! All layers of a job are placed in one submission: `place_bvh` walks the mesh's BVH
//! ([`crate::mesh::bvh`]) once per query, nearest boxes first, keeping the best triangle (ties go to
//! the lower triangle id, so results are deterministic and equal the brute-force test's);
//! `place_candidates` tests every (non-degenerate) triangle against the queries whose walk was cut
//! short (a point equidistant from much of the mesh) and reduces per workgroup in a fixed order;
//! `place_reduce` finishes the reduction per layer and computes the point, barycentric coordinates
//! and the smooth normal there (the welded normals interpolated; a bake then takes the model's
//! shading normal, [`with_shading_normal`]). [`place_gpu_brute`] runs the brute-force test for every query (the
//! reference the tests and `decalbake bench` compare with); [`place_cpu`] is the plain CPU twin.

use crate::error::Result;
use crate::gpu::pipelines::Pipelines;
use crate::gpu::BufferInit;
use crate::gpu::GpuContext;
use crate::mesh::upload::GpuMesh;
use crate::mesh::Topology;
use glam::Vec3;

/// Workgroups per layer in `place_candidates`. Keep in sync with the WGSL constant.
pub const PLACE_GROUPS: u32 = 32;

/// A placement query.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Query {
    /// Snap this point to the surface.
    Point(Vec3),
    /// First hit of this ray (origin, direction).
    Ray(Vec3, Vec3),
}

/// GPU layout of a query. Keep in sync with `Query` in wgsl/shared/geometry.wgsl.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct GpuQuery {
    origin: [f32; 4],
    dir: [f32; 4],
}

/// Where a layer landed. Keep in sync with `PlaceResult` in wgsl/place/place_reduce.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable, serde::Serialize)]
pub struct Placement {
    /// The surface point.
    pub point: [f32; 3],
    /// Its triangle.
    pub triangle: u32,
    /// Barycentric coordinates in that triangle.
    pub bary: [f32; 3],
    /// Distance from the query point to the surface, or along the ray to the hit.
    pub distance: f32,
    /// Unit normal: the welded vertex normals interpolated, or after [`with_shading_normal`] (every
    /// placement a bake uses) the model's shading normal.
    pub normal: [f32; 3],
    /// 1 if anything was found (a ray can miss).
    pub found: u32,
}

impl Query {
    fn gpu(&self) -> GpuQuery {
        match *self {
            Query::Point(p) => GpuQuery {
                origin: [p.x, p.y, p.z, 0.0],
                dir: [0.0; 4],
            },
            Query::Ray(o, d) => {
                let d = d.normalize();
                GpuQuery {
                    origin: [o.x, o.y, o.z, 0.0],
                    dir: [d.x, d.y, d.z, 1.0],
                }
            }
        }
    }
}

/// Places every query on the GPU through the mesh's BVH, in one submission (three dispatches) and
/// one read-back.
pub fn place_gpu(
    ctx: &GpuContext,
    pipes: &Pipelines,
    mesh: &GpuMesh,
    queries: &[Query],
) -> Result<Vec<Placement>> {
    place_with(ctx, pipes, mesh, queries, true)
}

/// [`place_gpu`] testing every triangle against every query (no BVH): the reference.
pub fn place_gpu_brute(
    ctx: &GpuContext,
    pipes: &Pipelines,
    mesh: &GpuMesh,
    queries: &[Query],
) -> Result<Vec<Placement>> {
    place_with(ctx, pipes, mesh, queries, false)
}

fn place_with(
    ctx: &GpuContext,
    pipes: &Pipelines,
    mesh: &GpuMesh,
    queries: &[Query],
    bvh: bool,
) -> Result<Vec<Placement>> {
    if queries.is_empty() {
        return Ok(Vec::new());
    }
    let device = &ctx.device;
    ctx.scoped("placement", || {
        let q: Vec<GpuQuery> = queries.iter().map(Query::gpu).collect();
        let qbuf = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("place.queries"),
            contents: bytemuck::cast_slice(&q),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let n = queries.len() as u64;
        let partials = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("place.partials"),
            size: n * PLACE_GROUPS as u64 * 8,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        let result_size = n * std::mem::size_of::<Placement>() as u64;
        let results = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("place.results"),
            size: result_size,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        // 1 = test every triangle for this query; the BVH walk clears it where it finishes.
        let brute = ctx.storage_init(
            "place.brute",
            bytemuck::cast_slice(&vec![1u32; queries.len()]),
            wgpu::BufferUsages::empty(),
        );
        let bg0 = pipes.place_bvh.bind(
            device,
            "place.bvh",
            &[
                (0, mesh.positions.as_entire_binding()),
                (1, mesh.tris.as_entire_binding()),
                (2, qbuf.as_entire_binding()),
                (3, partials.as_entire_binding()),
                (4, mesh.bvh_nodes.as_entire_binding()),
                (5, mesh.bvh_triangles.as_entire_binding()),
                (6, brute.as_entire_binding()),
            ],
        );
        let bg1 = pipes.place_candidates.bind(
            device,
            "place.candidates",
            &[
                (0, mesh.positions.as_entire_binding()),
                (1, mesh.tris.as_entire_binding()),
                (2, qbuf.as_entire_binding()),
                (3, partials.as_entire_binding()),
                (4, brute.as_entire_binding()),
            ],
        );
        let bg2 = pipes.place_reduce.bind(
            device,
            "place.reduce",
            &[
                (0, mesh.positions.as_entire_binding()),
                (1, mesh.tris.as_entire_binding()),
                (2, mesh.normals.as_entire_binding()),
                (3, qbuf.as_entire_binding()),
                (4, partials.as_entire_binding()),
                (5, results.as_entire_binding()),
            ],
        );
        let mut enc = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("place"),
        });
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("place"),
                timestamp_writes: None,
            });
            // A mesh whose triangles are all degenerate has no tree: the brute force answers.
            if bvh && mesh.bvh_node_count > 0 {
                pass.set_pipeline(&pipes.place_bvh.pipeline);
                pass.set_bind_group(0, &bg0, &[]);
                pass.dispatch_workgroups((queries.len() as u32).div_ceil(64), 1, 1);
            }
            pass.set_pipeline(&pipes.place_candidates.pipeline);
            pass.set_bind_group(0, &bg1, &[]);
            pass.dispatch_workgroups(PLACE_GROUPS, queries.len() as u32, 1);
            pass.set_pipeline(&pipes.place_reduce.pipeline);
            pass.set_bind_group(0, &bg2, &[]);
            pass.dispatch_workgroups(queries.len() as u32, 1, 1);
        }
        ctx.queue.submit([enc.finish()]);
        (results, result_size)
    })
    .and_then(|(results, size)| {
        let bytes = ctx.read_buffer(&results, size, "placement read-back")?;
        Ok(bytemuck::cast_slice::<u8, Placement>(&bytes).to_vec())
    })
}

/// Closest point on triangle (a, b, c) to p, barycentric (Ericson 5.1.5). Twin of
/// `closest_barycentric` in wgsl/shared/geometry.wgsl.
pub fn closest_barycentric(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> Vec3 {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return Vec3::X;
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return Vec3::Y;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return Vec3::new(1.0 - v, v, 0.0);
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return Vec3::Z;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return Vec3::new(1.0 - w, 0.0, w);
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return Vec3::new(0.0, 1.0 - w, w);
    }
    let denom = 1.0 / (va + vb + vc);
    let v = vb * denom;
    let w = vc * denom;
    Vec3::new(1.0 - v - w, v, w)
}

pub use crate::mesh::bvh::ray_triangle;

/// CPU twin of the placement kernels: brute force over every non-degenerate triangle.
pub fn place_cpu(topo: &Topology, query: Query) -> Placement {
    let mut best: Option<(f32, u32)> = None;
    for t in 0..topo.triangles.len() as u32 {
        if topo.degenerate[t as usize] {
            continue;
        }
        if let Some(key) = triangle_key(topo, query, t) {
            if best.is_none_or(|(k, _)| key < k) {
                best = Some((key, t));
            }
        }
    }
    placement_of(topo, query, best)
}

/// The key of triangle `t` for `query` (squared distance to its closest point, or the distance
/// along the ray to the hit; `None` for a ray that misses it): twin of `candidate_key` in
/// wgsl/shared/geometry.wgsl. Like the kernels, which compare keys as bits, it keeps only keys
/// whose bits lie below +inf's: a hit at -0.0 (a ray starting on a triangle's plane), an infinite
/// or a NaN key counts as no hit.
fn triangle_key(topo: &Topology, query: Query, t: u32) -> Option<f32> {
    let [a, b, c] = topo.triangles[t as usize].map(|i| topo.positions[i as usize]);
    let key = match query {
        Query::Point(p) => {
            let bc = closest_barycentric(p, a, b, c);
            (bc.x * a + bc.y * b + bc.z * c).distance_squared(p)
        }
        Query::Ray(o, d) => ray_triangle(o, d.normalize(), a, b, c).0,
    };
    (key.to_bits() < f32::INFINITY.to_bits()).then_some(key)
}

/// CPU twin of `place_bvh` (wgsl/place/place_bvh.wgsl): the same walk of `bvh`, nearest child
/// first, a box skipped when its key exceeds the best triangle key so far by more than the
/// kernel's rounding margin (so ties are still visited and the lower triangle wins). It has no
/// step limit (the kernel hands a walk past 50,000 steps to the brute-force test). It answers as
/// [`place_cpu`] does wherever the margin covers the boxes' and keys' rounding, as the GPU walk
/// must too: `tests/placement.rs` checks it bit for bit on random points and rays, vertex ties and
/// a sphere's centre.
pub fn place_cpu_bvh(topo: &Topology, bvh: &crate::mesh::bvh::Bvh, query: Query) -> Placement {
    let mut best: Option<(f32, u32)> = None;
    let worth = |k: f32, best: Option<(f32, u32)>| match best {
        None => k < f32::INFINITY,
        Some((b, _)) => k <= b * (1.0 + 1e-5) + 1e-30,
    };
    let mut stack = Vec::with_capacity(64);
    if !bvh.nodes.is_empty() && !bvh.triangles.is_empty() {
        stack.push(0usize);
    }
    while let Some(i) = stack.pop() {
        let n = bvh.nodes[i];
        if !worth(box_key(query, n.lo, n.hi), best) {
            continue;
        }
        let first = n.first as usize;
        if n.count > 0 {
            for &t in &bvh.triangles[first..first + n.count as usize] {
                let Some(key) = triangle_key(topo, query, t) else {
                    continue;
                };
                if best.is_none_or(|(k, b)| key < k || (key == k && t < b)) {
                    best = Some((key, t));
                }
            }
            continue;
        }
        let (a, b) = (bvh.nodes[first], bvh.nodes[first + 1]);
        let (ka, kb) = (box_key(query, a.lo, a.hi), box_key(query, b.lo, b.hi));
        let (near, far, knear, kfar) = if kb < ka {
            (first + 1, first, kb, ka)
        } else {
            (first, first + 1, ka, kb)
        };
        if worth(kfar, best) {
            stack.push(far);
        }
        if worth(knear, best) {
            stack.push(near);
        }
    }
    placement_of(topo, query, best)
}

/// The key of box (lo, hi) for `query`, a lower bound of every key inside it: twin of `box_key`
/// in wgsl/place/place_bvh.wgsl (slabs for a ray, a zero direction component made tiny).
fn box_key(query: Query, lo: [f32; 3], hi: [f32; 3]) -> f32 {
    let (lo, hi) = (Vec3::from(lo), Vec3::from(hi));
    match query {
        Query::Point(p) => {
            let e = (lo - p).max(p - hi).max(Vec3::ZERO);
            e.dot(e)
        }
        Query::Ray(o, d) => {
            let d = d.normalize();
            let d = Vec3::select(d.abs().cmplt(Vec3::splat(1e-30)), Vec3::splat(1e-30), d);
            let inv = d.recip();
            let (t0, t1) = ((lo - o) * inv, (hi - o) * inv);
            let tmin = t0.min(t1).max_element().max(0.0);
            let tmax = t0.max(t1).min_element();
            if tmax < tmin {
                f32::INFINITY
            } else {
                tmin
            }
        }
    }
}

/// The placement of `query` on the best (key, triangle), or nothing found.
fn placement_of(topo: &Topology, query: Query, best: Option<(f32, u32)>) -> Placement {
    let Some((key, t)) = best else {
        return Placement {
            point: [0.0; 3],
            triangle: u32::MAX,
            bary: [0.0; 3],
            distance: 0.0,
            normal: [0.0; 3],
            found: 0,
        };
    };
    let tri = topo.triangles[t as usize];
    let [a, b, c] = tri.map(|i| topo.positions[i as usize]);
    let (bc, distance) = match query {
        Query::Point(p) => (closest_barycentric(p, a, b, c), key.sqrt()),
        Query::Ray(o, d) => {
            let (t, u, v) = ray_triangle(o, d.normalize(), a, b, c);
            (Vec3::new(1.0 - u - v, u, v), t)
        }
    };
    let point = bc.x * a + bc.y * b + bc.z * c;
    let n = bc.x * topo.normals[tri[0] as usize]
        + bc.y * topo.normals[tri[1] as usize]
        + bc.z * topo.normals[tri[2] as usize];
    let normal = if n.length_squared() > 1e-12 {
        n.normalize()
    } else {
        (b - a).cross(c - a).normalize()
    };
    Placement {
        point: point.to_array(),
        triangle: t,
        bary: bc.to_array(),
        distance,
        normal: normal.to_array(),
        found: 1,
    }
}

/// `p` with the model's shading normal at its point, as a viewer shades the model there: the
/// normals of its triangle's split vertices (the file's `NORMAL`) interpolated at the point, or,
/// in a primitive without normals, the triangle's own (glTF: "client implementations MUST
/// calculate flat normals"). The placements above interpolate the welded normals, each summed
/// over every face around a position, so on a hard-edged model (a box, a machined part) a point
/// on a flat face got a normal leaning towards the faces around the face's corners: a planar
/// decal there was projected along that slant, its depth limit cut the face's corners out, and a
/// decal off the face's centre covered nothing. Where the split normals cancel out or face away
/// from the triangle (a file's bad normals), the triangle's own; `p.normal` kept for a degenerate
/// triangle and where nothing was found. A mesh made in code (no primitives) uses its `normals`
/// as given.
pub fn with_shading_normal(mesh: &crate::mesh::Mesh, mut p: Placement) -> Placement {
    let t = p.triangle;
    let Some(tri) = mesh.triangles.get(t as usize).filter(|_| p.found != 0) else {
        return p;
    };
    let [a, b, c] = tri.map(|v| mesh.positions[v as usize]);
    let face = (b - a).cross(c - a);
    let flat = mesh
        .primitives
        .iter()
        .find(|q| (q.first_triangle..q.first_triangle + q.triangles).contains(&t))
        .is_some_and(|q| !q.has_normals);
    let n = match flat {
        true => face,
        false => tri
            .iter()
            .zip(p.bary)
            .fold(Vec3::ZERO, |n, (&v, w)| n + w * mesh.normals[v as usize]),
    };
    // Split normals that cancel out or face away from the triangle (a file's bad normals): the
    // triangle's own, which is what a viewer would have to fall back on too.
    let n = Some(n.normalize_or_zero())
        .filter(|n| n.dot(face) > 0.0)
        .unwrap_or_else(|| face.normalize_or_zero());
    if n != Vec3::ZERO {
        p.normal = n.to_array();
    }
    p
}
