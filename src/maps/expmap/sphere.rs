// SPDX-License-Identifier: MIT OR Apache-2.0
//! Analytic test shapes and their exact answers, shared by the tests and `decalbake bench`: the
//! class-I geodesic icosphere of `../shared/peers` (`peerlib.icosphere_freq`: same base icosahedron,
//! same lattice, so the same vertices) and the exact log map of the unit sphere.

use crate::maps::expmap::cpu::Seed;
use crate::mesh::{Mesh, Topology};
use glam::{Vec2, Vec3};

/// A unit icosphere with each icosahedron edge split into `f` segments: 20 f² triangles,
/// 10 f² + 2 welded vertices (glTF-style: each base face has its own copy of its edge vertices,
/// welded by [`Topology::build`]). UVs are (0.5 + x / 2, 0.5 + y / 2); normals are left for the
/// engine to compute.
pub fn icosphere(f: u32) -> Mesh {
    let t = (1.0 + 5f32.sqrt()) / 2.0;
    let v = [
        Vec3::new(-1.0, t, 0.0),
        Vec3::new(1.0, t, 0.0),
        Vec3::new(-1.0, -t, 0.0),
        Vec3::new(1.0, -t, 0.0),
        Vec3::new(0.0, -1.0, t),
        Vec3::new(0.0, 1.0, t),
        Vec3::new(0.0, -1.0, -t),
        Vec3::new(0.0, 1.0, -t),
        Vec3::new(t, 0.0, -1.0),
        Vec3::new(t, 0.0, 1.0),
        Vec3::new(-t, 0.0, -1.0),
        Vec3::new(-t, 0.0, 1.0),
    ];
    let faces = [
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    for face in faces {
        let [a, b, c] = face.map(|i| v[i]);
        let base = positions.len() as u32;
        let row = |i: u32| base + i * (i + 1) / 2;
        for i in 0..=f {
            for j in 0..=i {
                let p = a + (b - a) * (i as f32 / f as f32) + (c - b) * (j as f32 / f as f32);
                positions.push(p.normalize());
            }
        }
        for i in 0..f {
            for j in 0..=i {
                triangles.push([row(i) + j, row(i + 1) + j, row(i + 1) + j + 1]);
                if j < i {
                    triangles.push([row(i) + j, row(i + 1) + j + 1, row(i) + j + 1]);
                }
            }
        }
    }
    let uv = positions
        .iter()
        .map(|p| Vec2::new(0.5 + 0.5 * p.x, 0.5 + 0.5 * p.y))
        .collect();
    Mesh {
        source: format!("icosphere f{f}").into(),
        normals: vec![Vec3::ZERO; positions.len()],
        positions,
        uv_sets: vec![uv],
        triangles,
        primitives: vec![],
        material: None,
        blend: Vec::new(),
        bridge: Vec::new(),
        ..Default::default()
    }
}

/// Errors of a map against the exact log map of the unit sphere at the seed, over the vertices
/// within geodesic distance `radius` that the map reached.
#[derive(Debug, Clone, Copy, Default, serde::Serialize)]
pub struct SphereErrors {
    /// Largest 2D position error (model units), no rotation fitted: the map must use the seed's
    /// own frame.
    pub max: f32,
    /// RMS 2D position error.
    pub rms: f32,
    /// Largest error of the distance |uv|.
    pub dist_max: f32,
    /// RMS error of the distance.
    pub dist_rms: f32,
    /// Vertices compared.
    pub vertices: usize,
}

/// Compares `uv` (per welded vertex, `None` where the map did not reach) with the exact log map of
/// the unit sphere at the seed point (projected onto the sphere), read in the seed's frame
/// (e1, e2): angle × the unit tangent direction towards the vertex.
pub fn unit_sphere_log_errors(
    topo: &Topology,
    seed: &Seed,
    radius: f32,
    uv: impl Fn(usize) -> Option<[f32; 2]>,
) -> SphereErrors {
    let p = seed.point.normalize();
    let (mut max, mut sum2, mut n, mut dist_max, mut sum_d2) = (0.0f32, 0.0f64, 0, 0.0f32, 0.0f64);
    for (v, q) in topo.positions.iter().enumerate() {
        let Some(c) = uv(v) else { continue };
        let q = q.normalize();
        let angle = p.dot(q).clamp(-1.0, 1.0).acos();
        if angle > radius {
            continue;
        }
        let t = q - p * p.dot(q);
        let dir = if t.length() > 1e-9 {
            t.normalize()
        } else {
            Vec3::ZERO
        };
        let exact = [angle * dir.dot(seed.e1), angle * dir.dot(seed.e2)];
        let e = (c[0] - exact[0]).hypot(c[1] - exact[1]);
        let e = if e.is_nan() { f32::INFINITY } else { e };
        max = max.max(e);
        sum2 += (e as f64).powi(2);
        let de = (c[0].hypot(c[1]) - angle).abs();
        dist_max = dist_max.max(de);
        sum_d2 += (de as f64).powi(2);
        n += 1;
    }
    let rms = |s: f64| {
        if n > 0 {
            (s / n as f64).sqrt() as f32
        } else {
            0.0
        }
    };
    SphereErrors {
        max,
        rms: rms(sum2),
        dist_max,
        dist_rms: rms(sum_d2),
        vertices: n,
    }
}

/// The vertex `../shared/peers/accuracy.py` seeds its sphere log maps from: the one furthest along
/// (0.31, 0.47, 0.83).
pub fn peers_seed_vertex(topo: &Topology) -> Vec3 {
    let d = Vec3::new(0.31, 0.47, 0.83).normalize();
    topo.positions
        .iter()
        .copied()
        .max_by(|a, b| a.dot(d).total_cmp(&b.dot(d)))
        .unwrap_or(Vec3::Z)
}
