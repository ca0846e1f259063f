// SPDX-License-Identifier: MIT OR Apache-2.0
//! A mesh resident in GPU storage buffers, built once and baked against many times.
//!
//! Uploaded: welded positions and normals (`vec4<f32>`), welded triangles with a flags word
//! (`vec4<u32>`, bit 0 = degenerate), split triangles (`u32` × 3), split→welded map, every UV set
//! (`vec2<f32>` per split vertex), CSR vertex adjacency, triangle adjacency, boundary and
//! non-manifold edges, |Gaussian curvature| per vertex, and the exponential maps' edge records
//! (neighbour, edge angles, curvature per adjacency entry). The
//! placement, layer and raster kernels read these; later solvers (geodesics, conformal maps) walk the
//! adjacency.

use crate::gpu::BufferInit;
use crate::mesh::{Mesh, Topology};

/// GPU buffers of one mesh. Owns them; dropping frees them.
pub struct GpuMesh {
    /// Welded vertex count.
    pub vertex_count: u32,
    /// Triangle count (including degenerate ones, which carry a flag).
    pub triangle_count: u32,
    /// Split (glTF) vertex count.
    pub split_vertex_count: u32,
    /// Welded positions, `vec4<f32>`.
    pub positions: wgpu::Buffer,
    /// Welded unit normals, `vec4<f32>`.
    pub normals: wgpu::Buffer,
    /// Welded triangles + flags, `vec4<u32>`.
    pub tris: wgpu::Buffer,
    /// Split triangles, `u32` × 3 (also an index buffer for the preview).
    pub split_tris: wgpu::Buffer,
    /// Split → welded vertex id, `u32`.
    pub welded_of: wgpu::Buffer,
    /// One buffer per UV set, `vec2<f32>` per split vertex.
    pub uvs: Vec<wgpu::Buffer>,
    /// Split positions, `vec3<f32>` (preview vertex buffer).
    pub split_positions: wgpu::Buffer,
    /// Split normals, `vec3<f32>` (preview vertex buffer).
    pub split_normals: wgpu::Buffer,
    /// CSR offsets of the welded vertex adjacency, `u32` × (vertices + 1).
    pub adjacency_offsets: wgpu::Buffer,
    /// CSR neighbour lists, `u32`.
    pub adjacency: wgpu::Buffer,
    /// Triangle across each edge, `vec4<u32>` (w unused; `0xffffffff` = none).
    pub triangle_neighbors: wgpu::Buffer,
    /// |Gaussian curvature| per welded vertex, `f32` (partial decals).
    pub curvature: wgpu::Buffer,
    /// Per CSR adjacency entry, what the exponential maps' relaxation reads of it: the neighbour,
    /// the edge's intrinsic angle at its source, the reverse edge's at the neighbour and the
    /// neighbour's curvature, `vec4<u32>` (`crate::mesh::surface::relax_edges`); a 16-byte
    /// placeholder where that does not fit one storage binding ([`Self::relax_edges_fit`]) and on
    /// wgpu's GL backend, whose maps come from the CPU twin.
    pub relax_edges: wgpu::Buffer,
    /// Whether [`Self::relax_edges`] holds the records. They take 16 bytes an adjacency entry (about
    /// 96 a vertex), more than any other mesh buffer, so a mesh that fits the device otherwise
    /// may not fit them: then its exponential maps come from their CPU twin
    /// (`maps::expmap::gpu::run`) rather than the mesh being refused. False on wgpu's GL
    /// backend, where the CPU twin makes the maps anyway.
    pub relax_edges_fit: bool,
    /// Boundary edges (welded ids, smaller first), `vec2<u32>`.
    pub boundary_edges: wgpu::Buffer,
    /// Non-manifold edges, `vec2<u32>`.
    pub non_manifold_edges: wgpu::Buffer,
    /// Number of boundary edges.
    pub boundary_edge_count: u32,
    /// Number of non-manifold edges.
    pub non_manifold_edge_count: u32,
    /// The BVH's nodes ([`crate::mesh::bvh::BvhNode`]).
    pub bvh_nodes: wgpu::Buffer,
    /// The BVH's triangles in leaf order, `u32`.
    pub bvh_triangles: wgpu::Buffer,
    /// Nodes in the BVH (0: no triangle to place on).
    pub bvh_node_count: u32,
    /// The exponential maps' per-slot scratch (marks, state) of the last run on this mesh, kept for
    /// the next (`maps::expmap::gpu::run`): a fresh pair costs the device a zero-fill of 20 bytes
    /// per slot and vertex on every chunk of maps, which their kernel never needs (it sets every
    /// entry it reads). A run takes it out while it works, so two runs never share it.
    pub expmap_scratch: std::sync::Mutex<Option<[wgpu::Buffer; 2]>>,
}

/// The exponential maps' edge records ([`crate::mesh::surface::relax_edges`]) and whether they fit
/// one storage binding of `device`; none on wgpu's GL backend, where they would go unread.
fn relax_records(
    device: &wgpu::Device,
    topo: &Topology,
    surface: &crate::mesh::SurfaceData,
) -> (Vec<[u32; 4]>, bool) {
    // wgpu's GL backend makes the maps with the CPU twin (`maps::expmap::gpu::run`): no records.
    if device.adapter_info().backend == wgpu::Backend::Gl {
        return (Vec::new(), false);
    }
    let relax = crate::mesh::surface::relax_edges(topo, surface);
    let limits = device.limits();
    let fit = 16 * relax.len() as u64
        <= limits
            .max_buffer_size
            .min(limits.max_storage_buffer_binding_size);
    (relax, fit)
}

fn storage(
    device: &wgpu::Device,
    label: &str,
    bytes: &[u8],
    extra: wgpu::BufferUsages,
) -> wgpu::Buffer {
    // wgpu rejects zero-sized bindings; keep at least 16 bytes.
    let mut data = bytes.to_vec();
    if data.len() < 16 {
        data.resize(16, 0);
    }
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: &data,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | extra,
    })
}

impl GpuMesh {
    /// Replaces the BVH's buffers with `bvh`'s (a tree built after the upload: `crate::mesh::lbvh`).
    pub fn set_bvh(&mut self, device: &wgpu::Device, bvh: &crate::mesh::bvh::Bvh) {
        let none = wgpu::BufferUsages::empty();
        self.bvh_nodes = storage(
            device,
            "mesh.bvh_nodes",
            bytemuck::cast_slice(&bvh.nodes),
            none,
        );
        self.bvh_triangles = storage(
            device,
            "mesh.bvh_triangles",
            bytemuck::cast_slice(&bvh.triangles),
            none,
        );
        self.bvh_node_count = bvh.nodes.len() as u32;
    }

    /// Uploads a loaded mesh and its topology.
    pub fn upload(
        device: &wgpu::Device,
        mesh: &Mesh,
        topo: &Topology,
        surface: &crate::mesh::SurfaceData,
        bvh: &crate::mesh::bvh::Bvh,
    ) -> Self {
        let v4 = |v: &[glam::Vec3]| -> Vec<[f32; 4]> {
            v.iter().map(|p| [p.x, p.y, p.z, 0.0]).collect()
        };
        let tris: Vec<[u32; 4]> = topo
            .triangles
            .iter()
            .zip(&topo.degenerate)
            .map(|(t, d)| [t[0], t[1], t[2], u32::from(*d)])
            .collect();
        let split: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
        let neighbors: Vec<[u32; 4]> = topo
            .triangle_neighbors
            .iter()
            .map(|n| [n[0], n[1], n[2], 0])
            .collect();
        let p3: Vec<[f32; 3]> = mesh.positions.iter().map(|p| p.to_array()).collect();
        let (relax, relax_edges_fit) = relax_records(device, topo, surface);
        let n3: Vec<[f32; 3]> = mesh.normals.iter().map(|p| p.to_array()).collect();
        let none = wgpu::BufferUsages::empty();
        Self {
            vertex_count: topo.positions.len() as u32,
            triangle_count: topo.triangles.len() as u32,
            split_vertex_count: mesh.positions.len() as u32,
            positions: storage(
                device,
                "mesh.positions",
                bytemuck::cast_slice(&v4(&topo.positions)),
                none,
            ),
            normals: storage(
                device,
                "mesh.normals",
                bytemuck::cast_slice(&v4(&topo.normals)),
                none,
            ),
            tris: storage(device, "mesh.tris", bytemuck::cast_slice(&tris), none),
            split_tris: storage(
                device,
                "mesh.split_tris",
                bytemuck::cast_slice(&split),
                wgpu::BufferUsages::INDEX,
            ),
            welded_of: storage(
                device,
                "mesh.welded_of",
                bytemuck::cast_slice(&topo.welded_of),
                none,
            ),
            uvs: mesh
                .uv_sets
                .iter()
                .enumerate()
                .map(|(i, set)| {
                    let flat: Vec<[f32; 2]> = set.iter().map(|u| u.to_array()).collect();
                    storage(
                        device,
                        &format!("mesh.uv{i}"),
                        bytemuck::cast_slice(&flat),
                        wgpu::BufferUsages::VERTEX,
                    )
                })
                .collect(),
            split_positions: storage(
                device,
                "mesh.split_positions",
                bytemuck::cast_slice(&p3),
                wgpu::BufferUsages::VERTEX,
            ),
            split_normals: storage(
                device,
                "mesh.split_normals",
                bytemuck::cast_slice(&n3),
                wgpu::BufferUsages::VERTEX,
            ),
            adjacency_offsets: storage(
                device,
                "mesh.adjacency_offsets",
                bytemuck::cast_slice(&topo.adjacency_offsets),
                none,
            ),
            adjacency: storage(
                device,
                "mesh.adjacency",
                bytemuck::cast_slice(&topo.adjacency),
                none,
            ),
            triangle_neighbors: storage(
                device,
                "mesh.triangle_neighbors",
                bytemuck::cast_slice(&neighbors),
                none,
            ),
            boundary_edges: storage(
                device,
                "mesh.boundary_edges",
                bytemuck::cast_slice(&topo.boundary_edges),
                none,
            ),
            non_manifold_edges: storage(
                device,
                "mesh.non_manifold_edges",
                bytemuck::cast_slice(&topo.non_manifold_edges),
                none,
            ),
            bvh_nodes: storage(
                device,
                "mesh.bvh_nodes",
                bytemuck::cast_slice(&bvh.nodes),
                none,
            ),
            bvh_triangles: storage(
                device,
                "mesh.bvh_triangles",
                bytemuck::cast_slice(&bvh.triangles),
                none,
            ),
            bvh_node_count: bvh.nodes.len() as u32,
            expmap_scratch: Default::default(),
            boundary_edge_count: topo.boundary_edges.len() as u32,
            non_manifold_edge_count: topo.non_manifold_edges.len() as u32,
            curvature: storage(
                device,
                "mesh.curvature",
                bytemuck::cast_slice(&surface.curvature),
                none,
            ),
            relax_edges: storage(
                device,
                "mesh.relax_edges",
                if relax_edges_fit {
                    bytemuck::cast_slice(&relax)
                } else {
                    &[]
                },
                none,
            ),
            relax_edges_fit,
        }
    }
}
