// SPDX-License-Identifier: MIT OR Apache-2.0
//! GPU placement equals its CPU twin (`decalbake::place::place_cpu`) on a real model, for snapped
//! points and for rays, and matches the analytic answer on a plane.
//!
//! Tolerance: positions 1e-5 × the model's size and distances 1e-5 (both sides do the same f32
//! arithmetic; only fused operations differ). The chosen triangle may differ only where two
//! triangles are equally close (a shared edge or vertex), in which case the points must still agree.

mod common;
use common::*;
use decalbake::mesh::{Mesh, Topology, DEFAULT_WELD_TOLERANCE};
use decalbake::place::{place_cpu, place_gpu, Query};
use glam::Vec3;
use std::path::Path;

#[test]
fn gpu_placement_matches_cpu_twin_on_spot() {
    let spot = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/spot.glb");
    let engine = engine();
    let loaded = engine.load_mesh(&spot).unwrap();
    let topo = Topology::build(&Mesh::load(&spot).unwrap(), DEFAULT_WELD_TOLERANCE);
    let mut queries = Vec::new();
    let mut s = 12345u32;
    let mut rnd = || {
        s = s.wrapping_mul(1664525).wrapping_add(1013904223);
        (s >> 8) as f32 / (1u32 << 24) as f32 * 2.0 - 1.0
    };
    for _ in 0..100 {
        queries.push(Query::Point(Vec3::new(
            rnd() * 0.7,
            rnd() * 1.1,
            rnd() * 1.1,
        )));
    }
    for _ in 0..60 {
        let o = Vec3::new(rnd(), rnd(), rnd()).normalize() * 3.0;
        let target = Vec3::new(rnd() * 0.2, rnd() * 0.3, rnd() * 0.3);
        queries.push(Query::Ray(o, target - o));
    }
    queries.push(Query::Ray(Vec3::new(5.0, 5.0, 5.0), Vec3::X));
    let gpu = engine
        .place(&loaded, &queries)
        .expect("placement on the GPU");
    let mut rays_hit = 0;
    for (q, g) in queries.iter().zip(&gpu) {
        let c = place_cpu(&topo, *q);
        assert_eq!(g.found, c.found, "{q:?}");
        if c.found == 0 {
            continue;
        }
        if matches!(q, Query::Ray(..)) {
            rays_hit += 1;
        }
        let dp = Vec3::from(g.point).distance(Vec3::from(c.point));
        assert!(
            dp < 2e-5,
            "{q:?}: GPU point {:?} vs CPU {:?}",
            g.point,
            c.point
        );
        assert!(
            (g.distance - c.distance).abs() < 1e-5,
            "{q:?}: distance {} vs {}",
            g.distance,
            c.distance
        );
        if g.triangle == c.triangle {
            assert!(
                Vec3::from(g.normal).distance(Vec3::from(c.normal)) < 1e-4,
                "{q:?}: normals differ"
            );
        }
    }
    assert!(rays_hit > 40, "most test rays aim at the model: {rays_hit}");
    let _ = place_gpu;
}

#[test]
fn placement_on_a_plane_is_exact() {
    let dir = scratch("place-plane");
    let (pos, uv, idx) = book_mesh();
    write_glb(&dir.join("book.glb"), &pos, Some(&uv), &idx);
    let engine = engine();
    let loaded = engine.load_mesh(&dir.join("book.glb")).unwrap();
    let q = [
        Query::Point(Vec3::new(0.3, 0.4, 0.25)),
        Query::Ray(Vec3::new(0.2, 0.7, 2.0), Vec3::new(0.0, 0.0, -1.0)),
    ];
    let r = engine.place(&loaded, &q).expect("placement on the GPU");
    assert!(Vec3::from(r[0].point).distance(Vec3::new(0.3, 0.4, 0.0)) < 1e-6);
    assert!((r[0].distance - 0.25).abs() < 1e-6);
    assert!(
        Vec3::from(r[0].normal).distance(Vec3::Z) < 1e-5,
        "{:?}",
        r[0].normal
    );
    assert!(Vec3::from(r[1].point).distance(Vec3::new(0.2, 0.7, 0.0)) < 1e-6);
    assert!((r[1].distance - 2.0).abs() < 1e-6);
    let b = r[0].bary;
    assert!((b[0] + b[1] + b[2] - 1.0).abs() < 1e-6 && b.iter().all(|x| *x >= 0.0));
}
