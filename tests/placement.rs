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
use decalbake::place::{place_cpu, place_cpu_bvh, place_gpu, Query};
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

/// Placement through the BVH (`place_bvh`) finds exactly what testing every triangle finds
/// (`place_gpu_brute`; same triangle, same point bit for bit, ties to the lower triangle), for
/// points near and far from Bob, points exactly at vertices and rays through them (ties between
/// the triangles of a fan), rays from outside and from inside, and rays that miss; and on a
/// finely tessellated sphere (`icosphere(128)`) for its centre, nearly equidistant from all 328k triangles:
/// the walk there is cut short and the brute-force test finishes the query (without that fallback
/// the query would come back empty or wrong). The walk's CPU twin (`place_cpu_bvh`) gives the CPU
/// brute force's answers bit for bit on the same queries (it fails with its pruning margin replaced
/// by a strict `<`, which drops ties: checked).
#[test]
fn bvh_placement_matches_testing_every_triangle() {
    use decalbake::place::place_gpu_brute;
    let engine = engine();
    let bob = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/bob.glb");
    let loaded = engine.load_mesh(&bob).unwrap();
    assert!(
        loaded.bvh.depth > 8,
        "a tree, not a list: depth {}",
        loaded.bvh.depth
    );
    let mut s = 777u32;
    let mut rnd = || {
        s = s.wrapping_mul(1664525).wrapping_add(1013904223);
        (s >> 8) as f32 / (1u32 << 24) as f32 * 2.0 - 1.0
    };
    let verts = &loaded.topo.positions;
    let mut queries = Vec::new();
    for k in 0..200 {
        let v = verts[(k * 7919) % verts.len()];
        let scale = [1e-4, 1e-2, 0.1, 1.0, 5.0][k % 5];
        queries.push(Query::Point(v + Vec3::new(rnd(), rnd(), rnd()) * scale));
    }
    for _ in 0..100 {
        let o = Vec3::new(rnd(), rnd(), rnd()).normalize() * 3.0;
        let target = verts[(rnd().abs() * verts.len() as f32) as usize % verts.len()];
        queries.push(Query::Ray(o, target - o));
        // From inside the model outwards, and along a coordinate axis (zero direction components).
        queries.push(Query::Ray(Vec3::ZERO, Vec3::new(rnd(), rnd(), rnd())));
    }
    queries.push(Query::Ray(Vec3::new(0.0, 0.1, 5.0), -Vec3::Z));
    queries.push(Query::Ray(Vec3::new(5.0, 5.0, 5.0), Vec3::X));
    // Ties: a point exactly at a vertex is at distance 0 from every triangle of its fan (the lower
    // triangle wins), and a ray through a vertex hits its fan at the same distance.
    for k in 0..50 {
        let v = verts[(k * 104_729) % verts.len()];
        queries.push(Query::Point(v));
        queries.push(Query::Ray(
            v + Vec3::new(0.0, 2.0, 0.0),
            Vec3::new(0.0, -1.0, 0.0),
        ));
    }
    let (ctx, pipes) = (&engine.ctx, engine.pipelines());
    let fast = decalbake::place::place_gpu(ctx, pipes, &loaded.gpu, &queries).unwrap();
    let brute = place_gpu_brute(ctx, pipes, &loaded.gpu, &queries).unwrap();
    let hits = brute.iter().filter(|p| p.found == 1).count();
    assert!(hits > 300, "most queries land: {hits}");
    for (q, (a, b)) in queries.iter().zip(fast.iter().zip(&brute)) {
        assert_eq!(a, b, "{q:?}");
    }
    // The walk's CPU twin answers as the CPU's brute force, bit for bit (same f32 arithmetic).
    for q in &queries {
        let walk = place_cpu_bvh(&loaded.topo, &loaded.bvh, *q);
        assert_eq!(walk, place_cpu(&loaded.topo, *q), "CPU walk, {q:?}");
    }
    // The sphere's centre.
    let sphere = engine
        .prepare(decalbake::maps::expmap::sphere::icosphere(128))
        .unwrap();
    let q = [
        Query::Point(Vec3::ZERO),
        Query::Point(Vec3::new(0.0, 0.0, 0.5)),
    ];
    let fast = decalbake::place::place_gpu(ctx, pipes, &sphere.gpu, &q).unwrap();
    let brute = place_gpu_brute(ctx, pipes, &sphere.gpu, &q).unwrap();
    assert_eq!(fast, brute);
    assert_eq!(fast[0].found, 1);
    for q in q {
        let walk = place_cpu_bvh(&sphere.topo, &sphere.bvh, q);
        assert_eq!(
            walk,
            place_cpu(&sphere.topo, q),
            "CPU walk on the sphere, {q:?}"
        );
    }
}

/// The BVH's own invariants on Bob: every non-degenerate triangle sits in exactly one leaf, every
/// box contains its triangles, the tree is balanced (depth ⌈log₂(n / 4)⌉ + 1 for median splits),
/// and a box query returns every triangle whose box meets the query box (checked against all
/// triangles for 50 random boxes); `any_hit` (the automatic cut's occlusion rays) answers as
/// testing every triangle does, for rays from the surface outwards and inwards, rays from outside
/// that hit and miss, rays along the axes (zero direction components) and rays cut short by
/// `tmax`. Reversing the test of a box (skipping the boxes a ray enters) fails it (checked).
#[test]
fn bvh_holds_every_triangle_once_and_box_queries_miss_none() {
    use decalbake::mesh::bvh::{Bvh, LEAF};
    let bob = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/bob.glb");
    let topo = Topology::build(&Mesh::load(&bob).unwrap(), DEFAULT_WELD_TOLERANCE);
    let bvh = Bvh::build(&topo);
    let live: Vec<u32> = (0..topo.triangles.len() as u32)
        .filter(|&t| !topo.degenerate[t as usize])
        .collect();
    let mut held = bvh.triangles.clone();
    held.sort_unstable();
    assert_eq!(held, live);
    let expect = ((live.len() as f64 / LEAF as f64).log2().ceil() as usize) + 1;
    assert!(bvh.depth <= expect, "depth {} > {expect}", bvh.depth);
    let corners = |t: u32| topo.triangles[t as usize].map(|v| topo.positions[v as usize]);
    for n in bvh.nodes.iter().filter(|n| n.count > 0) {
        for &t in &bvh.triangles[n.first as usize..(n.first + n.count) as usize] {
            for p in corners(t) {
                assert!(p.cmpge(Vec3::from(n.lo)).all() && p.cmple(Vec3::from(n.hi)).all());
            }
        }
    }
    let mut s = 99u32;
    let mut rnd = || {
        s = s.wrapping_mul(1664525).wrapping_add(1013904223);
        (s >> 8) as f32 / (1u32 << 24) as f32 * 2.0 - 1.0
    };
    for _ in 0..50 {
        let c = Vec3::new(rnd(), rnd(), rnd()) * 0.8;
        let h = Vec3::new(rnd().abs(), rnd().abs(), rnd().abs()) * 0.2;
        let (lo, hi) = (c - h, c + h);
        let got = bvh.overlapping(lo, hi);
        for &t in &live {
            let p = corners(t);
            let (tlo, thi) = (p[0].min(p[1]).min(p[2]), p[0].max(p[1]).max(p[2]));
            if tlo.cmple(hi).all() && thi.cmpge(lo).all() {
                assert!(got.binary_search(&t).is_ok(), "triangle {t} missed");
            }
        }
    }
    let brute = |o: Vec3, d: Vec3, tmin: f32, tmax: f32| {
        live.iter().any(|&t| {
            let [a, b, c] = corners(t);
            let h = decalbake::mesh::bvh::ray_triangle(o, d, a, b, c).0;
            h > tmin && h < tmax
        })
    };
    let (mut hits, mut misses) = (0, 0);
    for k in 0..400 {
        let v = (k * 7919) % topo.positions.len();
        let dir = Vec3::new(rnd(), rnd(), rnd());
        let (o, d, tmax) = match k % 4 {
            0 => (
                topo.positions[v] + topo.normals[v] * 1e-4,
                dir,
                f32::INFINITY,
            ),
            1 => (
                topo.positions[v] - topo.normals[v] * 1e-4,
                dir,
                f32::INFINITY,
            ),
            2 => (
                dir.normalize() * 3.0,
                topo.positions[v] - dir.normalize() * 3.0,
                0.99,
            ),
            _ => (
                Vec3::new(rnd(), rnd(), rnd()),
                [Vec3::X, Vec3::Y, Vec3::Z][k % 3],
                0.3,
            ),
        };
        let got = bvh.any_hit(&topo, o, d, 1e-5, tmax);
        assert_eq!(got, brute(o, d, 1e-5, tmax), "ray {k} from {o} along {d}");
        if got {
            hits += 1;
        } else {
            misses += 1;
        }
    }
    assert!(hits > 50 && misses > 50, "{hits} hits, {misses} misses");
}
