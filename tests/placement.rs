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
    // The kernels' placements as they come (the welded normals interpolated, as the twin's);
    // `Engine::place` then takes the model's shading normal, tested on a box below.
    let gpu = place_gpu(&engine.ctx, engine.pipelines(), &loaded.gpu, &queries)
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
    let queries = placement_queries(&loaded.topo.positions);
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

/// Random points near the vertices (1e-4 to 5 × the mesh's scale: on and off the mesh), rays from
/// outside and from the origin (some along the axes), and ties: points exactly at a vertex (at
/// distance 0 from its whole fan; the lower triangle wins) and rays through a vertex.
fn placement_queries(verts: &[Vec3]) -> Vec<Query> {
    let mut s = 777u32;
    let mut rnd = || {
        s = s.wrapping_mul(1664525).wrapping_add(1013904223);
        (s >> 8) as f32 / (1u32 << 24) as f32 * 2.0 - 1.0
    };
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
    queries
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
    let live = tree_holds_every_triangle_once(&topo, &bvh);
    let expect = ((live.len() as f64 / LEAF as f64).log2().ceil() as usize) + 1;
    assert!(bvh.depth <= expect, "depth {} > {expect}", bvh.depth);
    queries_through_the_tree_miss_none(&topo, &bvh, &live, 50);
    // The GPU build's tree (its CPU twin: the GPU gives it bit for bit, tested below) holds the
    // same invariants and answers the same box and ray queries.
    let lbvh = decalbake::mesh::lbvh::build_cpu(&topo);
    assert_eq!(tree_holds_every_triangle_once(&topo, &lbvh), live);
    queries_through_the_tree_miss_none(&topo, &lbvh, &live, 50);
}

/// Every non-degenerate triangle of `topo` sits in exactly one leaf of `bvh`, every leaf's box
/// holds its triangles' corners, every inner node's box its children's boxes, and the depth is
/// the deepest leaf's (root 1) within the walk's limit. Returns the non-degenerate triangles.
fn tree_holds_every_triangle_once(topo: &Topology, bvh: &decalbake::mesh::bvh::Bvh) -> Vec<u32> {
    use decalbake::mesh::bvh::MAX_DEPTH;
    let live: Vec<u32> = (0..topo.triangles.len() as u32)
        .filter(|&t| !topo.degenerate[t as usize])
        .collect();
    let mut held = bvh.triangles.clone();
    held.sort_unstable();
    assert_eq!(held, live);
    let corners = |t: u32| topo.triangles[t as usize].map(|v| topo.positions[v as usize]);
    let inside = |p: Vec3, n: &decalbake::mesh::bvh::BvhNode| {
        p.cmpge(Vec3::from(n.lo)).all() && p.cmple(Vec3::from(n.hi)).all()
    };
    // Walk from the root: every node reached exactly once, every entry of the triangle list in
    // exactly one leaf.
    let mut seen = vec![false; bvh.nodes.len()];
    let mut entry_seen = vec![false; bvh.triangles.len()];
    let (mut stack, mut deepest) = (vec![(0usize, 1usize)], 0);
    while let Some((i, d)) = stack.pop() {
        let n = bvh.nodes[i];
        assert!(!seen[i], "node {i} reached twice");
        seen[i] = true;
        deepest = deepest.max(d);
        if n.count > 0 {
            let entries = n.first as usize..(n.first + n.count) as usize;
            for (e, was) in entry_seen[entries].iter_mut().enumerate() {
                assert!(!*was, "entry {} in two leaves", n.first as usize + e);
                *was = true;
            }
            for &t in &bvh.triangles[n.first as usize..(n.first + n.count) as usize] {
                assert!(
                    corners(t).into_iter().all(|p| inside(p, &n)),
                    "leaf {i}, triangle {t}"
                );
            }
            continue;
        }
        for c in [n.first as usize, n.first as usize + 1] {
            let child = bvh.nodes[c];
            assert!(
                inside(child.lo.into(), &n) && inside(child.hi.into(), &n),
                "node {c} in {i}"
            );
            stack.push((c, d + 1));
        }
    }
    assert!(seen.iter().all(|&v| v), "every node reached");
    assert!(entry_seen.iter().all(|&v| v), "every entry in a leaf");
    assert_eq!(deepest, bvh.depth);
    assert!(bvh.depth <= MAX_DEPTH);
    live
}

/// Box queries ([`decalbake::mesh::bvh::Bvh::overlapping`]) and occlusion rays (`any_hit`) through
/// `bvh` answer as testing every triangle of `live` does; at least `min_each` of the rays hit and
/// as many miss (Bob: 50; the rays are laid out for Bob's size).
fn queries_through_the_tree_miss_none(
    topo: &Topology,
    bvh: &decalbake::mesh::bvh::Bvh,
    live: &[u32],
    min_each: usize,
) {
    let corners = |t: u32| topo.triangles[t as usize].map(|v| topo.positions[v as usize]);
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
        for &t in live {
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
        let got = bvh.any_hit(topo, o, d, 1e-5, tmax);
        assert_eq!(got, brute(o, d, 1e-5, tmax), "ray {k} from {o} along {d}");
        if got {
            hits += 1;
        } else {
            misses += 1;
        }
    }
    assert!(
        hits >= min_each && misses >= min_each,
        "{hits} hits, {misses} misses"
    );
}

/// A triangle soup as a mesh (flat normals, one UV set at zero).
fn soup(positions: Vec<Vec3>, triangles: Vec<[u32; 3]>) -> Mesh {
    let mut m = cylinder(3, 1);
    m.normals = vec![Vec3::Z; positions.len()];
    m.uv_sets = vec![vec![glam::Vec2::ZERO; positions.len()]];
    m.positions = positions;
    m.triangles = triangles;
    m
}

/// Meshes whose Morton codes tie: a 20 × 20 grid of quads 5e-4 across (inside one or a few grid
/// cells of 1/384) beside one large triangle, with a degenerate triangle; and meshes of one leaf
/// (three triangles) and two leaves (five).
fn tie_meshes() -> Vec<Mesh> {
    let mut pos = vec![
        Vec3::new(-1.0, -1.0, -1.0),
        Vec3::new(1.0, -1.0, 0.0),
        Vec3::new(0.0, 1.0, 1.0),
    ];
    let mut tris = vec![[0, 1, 2], [0, 0, 1]];
    let base = Vec3::new(0.3, 0.3, 0.3);
    let g = |i: u32, j: u32| i * 21 + j + 3;
    for i in 0..=20 {
        for j in 0..=20 {
            pos.push(base + Vec3::new(i as f32, j as f32, (i * j) as f32 * 0.05) * 2.5e-5);
        }
    }
    for i in 0..20 {
        for j in 0..20 {
            tris.push([g(i, j), g(i + 1, j), g(i + 1, j + 1)]);
            tris.push([g(i, j), g(i + 1, j + 1), g(i, j + 1)]);
        }
    }
    let fan = |k: u32| {
        let p: Vec<Vec3> = (0..=k)
            .map(|i| Vec3::new(i as f32, (i * i % 7) as f32, 0.5 * i as f32))
            .chain([Vec3::new(0.0, 0.0, 3.0)])
            .collect();
        let t = (0..k).map(|i| [i, i + 1, k + 1]).collect();
        soup(p, t)
    };
    vec![soup(pos, tris), fan(3), fan(5)]
}

/// The GPU's linear BVH (`mesh::lbvh::build_gpu`, through `Engine::bvh_build`) is its CPU twin's
/// tree bit for bit (exact arithmetic on both sides: no tolerance) on Bob and on meshes whose
/// Morton codes tie (the leaf index breaks them: Karras §4), of one leaf and of two; placement
/// through it, on the GPU and in the CPU twin of the walk, answers as testing every triangle does,
/// bit for bit, on the queries of `bvh_placement_matches_testing_every_triangle` (points off the
/// mesh, rays, vertex ties). Checked to fail: the bitonic step's direction reversed (`up` negated)
/// leaves the keys unsorted and the tree differs from the twin's.
#[test]
fn gpu_lbvh_is_its_twin_and_places_as_brute_force() {
    use decalbake::mesh::lbvh::build_cpu;
    let mut engine = engine();
    engine.bvh_build = decalbake::BvhBuild::Gpu;
    let bob = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/bob.glb");
    let mut meshes = vec![engine.load_mesh(&bob).unwrap()];
    for m in tie_meshes() {
        meshes.push(engine.prepare(m).unwrap());
    }
    let (ctx, pipes) = (&engine.ctx, engine.pipelines());
    for (k, loaded) in meshes.iter().enumerate() {
        let twin = build_cpu(&loaded.topo);
        let first_diff = |a: &[u32], b: &[u32]| a.iter().zip(b).position(|(x, y)| x != y);
        assert!(
            loaded.bvh.triangles == twin.triangles,
            "mesh {k}: leaf order differs first at {:?}",
            first_diff(&loaded.bvh.triangles, &twin.triangles)
        );
        let bits =
            |b: &decalbake::mesh::bvh::Bvh| -> Vec<u32> { bytemuck::cast_slice(&b.nodes).to_vec() };
        assert!(
            bits(&loaded.bvh) == bits(&twin),
            "mesh {k}: nodes differ first at word {:?} of {}",
            first_diff(&bits(&loaded.bvh), &bits(&twin)),
            bits(&twin).len()
        );
        assert_eq!(loaded.bvh.depth, twin.depth, "mesh {k}: depth");
        let live = tree_holds_every_triangle_once(&loaded.topo, &loaded.bvh);
        queries_through_the_tree_miss_none(
            &loaded.topo,
            &loaded.bvh,
            &live,
            if k == 0 { 50 } else { 0 },
        );
        let queries = placement_queries(&loaded.topo.positions);
        let fast = place_gpu(ctx, pipes, &loaded.gpu, &queries).unwrap();
        let brute = decalbake::place::place_gpu_brute(ctx, pipes, &loaded.gpu, &queries).unwrap();
        for (q, (a, b)) in queries.iter().zip(fast.iter().zip(&brute)) {
            assert_eq!(a, b, "mesh {k}, GPU walk, {q:?}");
            assert_eq!(
                place_cpu_bvh(&loaded.topo, &loaded.bvh, *q),
                place_cpu(&loaded.topo, *q),
                "mesh {k}, CPU walk, {q:?}"
            );
        }
    }
    // The tie mesh's grid: most of its 800 triangles share a few codes.
    let topo = &meshes[1].topo;
    let setup = decalbake::mesh::lbvh::setup(topo).unwrap();
    let mut codes: Vec<u32> = setup
        .ids
        .iter()
        .map(|&t| decalbake::mesh::lbvh::morton(&setup, topo, t))
        .collect();
    codes.sort_unstable();
    codes.dedup();
    assert!(
        codes.len() <= 16,
        "{} distinct codes for 801 triangles",
        codes.len()
    );
    assert!(meshes[1].bvh.depth > 8, "depth {}", meshes[1].bvh.depth);
    assert_eq!(meshes[2].bvh.nodes.len(), 1, "three triangles: one leaf");
    assert_eq!(meshes[3].bvh.nodes.len(), 3, "five triangles: two leaves");
}

/// A bake places its layers with the CPU twin on a CPU adapter and with the kernels on a GPU
/// (`StagePath::Auto`); forcing either gives the same placements within the twins' tolerance and
/// the same texture but for texels on a decal's edge, and the report names the path taken.
#[test]
fn a_bake_places_on_the_faster_path_and_both_paths_agree() {
    let (job, mut engine, mesh, auto) =
        spot_paths_bake("placement_paths", spot_ring("img.png", 0.2));
    let cpu_adapter = engine.ctx.device_type == Some(wgpu::DeviceType::Cpu);
    let expected = if cpu_adapter && !mesh.bvh.nodes.is_empty() {
        "cpu"
    } else {
        "gpu"
    };
    assert_eq!(auto.report.paths.placement, expected);
    let mut baked = Vec::new();
    for path in [decalbake::StagePath::Cpu, decalbake::StagePath::Gpu] {
        engine.stage_paths.placement = path;
        baked.push(engine.bake(&mesh, &job).unwrap());
    }
    let [cpu, gpu] = [&baked[0], &baked[1]];
    if !mesh.bvh.nodes.is_empty() {
        assert_eq!(cpu.report.paths.placement, "cpu");
    }
    assert_eq!(gpu.report.paths.placement, "gpu");
    for (c, g) in cpu.report.layers.iter().zip(&gpu.report.layers) {
        let d = Vec3::from(c.placement.point).distance(Vec3::from(g.placement.point));
        assert!(d < 2e-5, "layer {}: placements {d} apart", c.index);
    }
    let differ = cpu
        .texels
        .iter()
        .zip(&gpu.texels)
        .filter(|(a, b)| a != b)
        .count();
    assert!(
        differ * 1000 <= cpu.texels.len(),
        "{differ} of {} texel channels differ between the paths",
        cpu.texels.len()
    );
}

/// A cube's split vertices (positions, flat normals, UVs), its indices, and its top face's (+y)
/// UV cell (u0, v0, u1, v1).
struct Cube {
    pos: Vec<[f32; 3]>,
    flat: Vec<[f32; 3]>,
    uv: Vec<[f32; 2]>,
    idx: Vec<u32>,
    top: [f32; 4],
}

/// A cube of side 1 about the origin, each face its own two triangles (split along the diagonal
/// from its (0, 0) corner to its (1, 1) corner) and its own cell of a 3 × 2 UV atlas.
fn cube_faces() -> Cube {
    let (mut pos, mut nrm, mut uv, mut idx) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let (m, mut top) = (0.02f32, [0.0; 4]);
    for axis in 0..3 {
        for side in [-0.5f32, 0.5] {
            let f = pos.len() / 4;
            let (u0, v0) = ((f % 3) as f32 / 3.0 + m, (f / 3) as f32 / 2.0 + m);
            let (w, h) = (1.0 / 3.0 - 2.0 * m, 0.5 - 2.0 * m);
            if axis == 1 && side > 0.0 {
                top = [u0, v0, u0 + w, v0 + h];
            }
            let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
            let base = pos.len() as u32;
            for (i, j) in [(0.0f32, 0.0f32), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)] {
                let mut p = [0.0f32; 3];
                p[axis] = side;
                p[a] = i - 0.5;
                p[b] = j - 0.5;
                let mut n = [0.0f32; 3];
                n[axis] = side.signum();
                pos.push(p);
                nrm.push(n);
                uv.push([u0 + i * w, v0 + j * h]);
            }
            // Outward winding: (a, b, axis) is right-handed; turned on the negative side.
            let quad = match side > 0.0 {
                true => [0, 1, 2, 0, 2, 3],
                false => [0, 2, 1, 0, 3, 2],
            };
            idx.extend(quad.map(|k| base + k));
        }
    }
    Cube {
        pos,
        flat: nrm,
        uv,
        idx,
        top,
    }
}

/// A planar decal off the centre of a hard-edged cube's top face lies flat on that face: its
/// frame's normal is the face's, as a viewer shades it, whether the file gives flat normals or
/// none (glTF's flat normals), and it paints its whole square there and nothing of the other
/// faces. The welded normals, summed over the three faces at each corner, lean across the face:
/// placed by them, this decal's projection slanted, its depth limit cut off every corner of the
/// face and the bake was refused ("the decal covers no triangle facing it"; checked by keeping
/// the welded normal). Where the file's normals are smooth (every corner's the mean of its three
/// faces'), the placement takes them, interpolated at its point, and the decal, projected along
/// that slant, still covers the face: a triangle whose corners leave the depth limit is kept
/// where its part under the decal's rectangle is within it (refused before: checked).
#[test]
fn a_planar_decal_off_a_box_faces_centre_lies_flat_on_it() {
    let dir = scratch("place-box");
    let Cube {
        pos,
        flat,
        uv,
        idx,
        top,
    } = cube_faces();
    let smooth: Vec<[f32; 3]> = pos
        .iter()
        .map(|p| (Vec3::from(*p) * 2.0).normalize().to_array())
        .collect();
    write_raw_png(&dir.join("white.png"), 16, |_, _| [1.0; 4]);
    let engine = engine();
    let (side, size) = (512u32, 0.35f32);
    for (name, normals) in [
        ("flat", Some(&flat)),
        ("none", None),
        ("smooth", Some(&smooth)),
    ] {
        let model = dir.join(format!("{name}.glb"));
        write_glb_with_normals(&model, &pos, normals.map(|n| &n[..]), Some(&uv), &idx);
        let job = serde_json::json!({
            "mesh": model, "texture": {"width": side, "height": side, "padding": 0},
            "layers": [{"image": "white.png", "at": [0.1, 0.5, 0.2], "size": [size, size], "method": "planar"}],
            "output": {"texture": "out.png"}
        });
        std::fs::write(dir.join("job.json"), job.to_string()).unwrap();
        let job = decalbake::io::job::Job::load(&dir.join("job.json"), None).unwrap();
        let mesh = engine.load_mesh(&model).unwrap();
        if name == "smooth" {
            // The file's corner normals interpolated at the point (its triangle and weights).
            let p = engine
                .place(&mesh, &[Query::Point(Vec3::new(0.1, 0.5, 0.2))])
                .unwrap()[0];
            let t = &idx[3 * p.triangle as usize..][..3];
            let want = t
                .iter()
                .zip(p.bary)
                .fold(Vec3::ZERO, |s, (&v, w)| {
                    s + w * Vec3::from(smooth[v as usize])
                })
                .normalize();
            let n = Vec3::from(p.normal);
            assert!(n.distance(want) < 1e-5, "{name}: {n} against {want}");
            assert!(n.angle_between(Vec3::Y) > 0.05, "{name}: leans: {n}");
        }
        let baked = engine.bake(&mesh, &job);
        let layer = &baked.as_ref().expect(name).report.layers[0];
        let n = Vec3::from(layer.placement.normal);
        assert!(
            name == "smooth" || n.distance(Vec3::Y) < 1e-6,
            "{name}: normal {n}"
        );
        // The selection's CPU twin keeps the same triangles.
        let frame = decalbake::maps::Frame::new(&layer.placement, &job.layers[0]);
        let coords = decalbake::maps::planar::planar_coords(&mesh.topo, &frame);
        let twin = decalbake::bake::cpu::select_triangles(
            &mesh.mesh,
            &mesh.topo,
            &mesh.mesh.uv_sets[0],
            (&coords, None),
            &frame,
            true,
            [side, side],
        );
        assert_eq!(
            twin.triangles.len(),
            layer.triangles_covered as usize,
            "{name}: twin"
        );
        assert_eq!(layer.triangles_covered, 2, "{name}");
        // Every painted texel in the top face's cell; the square's area within its edge texels.
        let cell = top.map(|c| c * side as f32);
        let b = layer.texel_box.map(|v| v as f32);
        assert!(
            b[0] >= cell[0] - 1.0
                && b[1] >= cell[1] - 1.0
                && b[2] <= cell[2] + 1.0
                && b[3] <= cell[3] + 1.0,
            "{name}: texels {b:?} outside the top face's cell {cell:?}"
        );
        // The face is a unit square: its cell's sides are texels per unit along u and v; the
        // decal's square, projected along the placement's normal, covers 1 / cos of its lean.
        let (wu, wv) = (cell[2] - cell[0], cell[3] - cell[1]);
        let area = size * size * wu * wv / n.dot(Vec3::Y);
        let painted = layer.texels_covered as f32;
        assert!(
            painted > 0.95 * area && painted < area + 2.0 * size * (wu + wv) + 4.0,
            "{name}: {painted} texels painted, the square covers {area}"
        );
    }
}
