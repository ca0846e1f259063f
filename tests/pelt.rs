// SPDX-License-Identifier: MIT OR Apache-2.0
//! Pelting (`decalbake unwrap`, Piponi & Borshukov §3-4): the dynamics against its CPU twin, the
//! analytic shapes (a hemisphere on its circle, a cylinder unrolled), closed models cut into disks,
//! and the command's output and errors.
mod common;
use common::rich::validate;

use decalbake::mesh::{Mesh, Topology, DEFAULT_WELD_TOLERANCE};
use decalbake::pelt::{self, relax, CutSpec, Device, Frame, Options, Refine, SystemCfg};
use glam::{DVec2, DVec3, Vec3};
use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};

/// A unit hemisphere (z ≥ 0) with `rings` rings of `segments` vertices below the pole.
fn hemisphere(rings: u32, segments: u32) -> Mesh {
    let mut pos = vec![Vec3::Z];
    for j in 1..=rings {
        let th = std::f32::consts::FRAC_PI_2 * j as f32 / rings as f32;
        for i in 0..segments {
            let a = i as f32 / segments as f32 * std::f32::consts::TAU;
            pos.push(Vec3::new(th.sin() * a.cos(), th.sin() * a.sin(), th.cos()));
        }
    }
    let mut tris = Vec::new();
    let at = |j: u32, i: u32| 1 + (j - 1) * segments + i % segments;
    for i in 0..segments {
        tris.push([0, at(1, i), at(1, i + 1)]);
    }
    for j in 1..rings {
        for i in 0..segments {
            let (a, b, c, d) = (at(j, i), at(j, i + 1), at(j + 1, i), at(j + 1, i + 1));
            tris.push([a, c, d]);
            tris.push([a, d, b]);
        }
    }
    Mesh {
        source: "hemisphere".into(),
        normals: pos.clone(),
        uv_sets: vec![],
        positions: pos,
        triangles: tris,
        primitives: vec![],
        material: None,
        blend: Vec::new(),
        bridge: Vec::new(),
        ..Default::default()
    }
}

/// `decalbake unwrap MESH --out OUT --cpu EXTRA...`: (exit code, stdout, stderr).
fn unwrap_cli(mesh: &Path, out: &Path, extra: &[&str]) -> (i32, String, String) {
    let mut args = vec![
        "unwrap",
        mesh.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--cpu",
    ];
    args.extend_from_slice(extra);
    common::cli(&args)
}

fn asset(f: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("assets").join(f)
}

fn gpu_unwrap(engine: &decalbake::Engine, mesh: &Mesh, opts: &Options) -> pelt::Unwrapped {
    let topo = Topology::build(mesh, DEFAULT_WELD_TOLERANCE);
    let dev = Device::Gpu(&engine.ctx, engine.pipelines());
    pelt::unwrap(dev, mesh, &topo, opts, Path::new("test")).unwrap()
}

/// The hemisphere is a disk: no cut, one pelt on the circle, nothing folded. Bounds: the measured
/// figures (pelt: angle p95 1.71, area p95 1.44; refined: angle p95 1.09) plus about 5 %; a
/// hemisphere has no isometric layout, so neither can approach 1.
#[test]
fn hemisphere_pelts_on_its_circle() {
    let engine = common::engine();
    let mesh = hemisphere(12, 48);
    let plain = Options {
        refine: Refine::None,
        ..Options::default()
    };
    let un = gpu_unwrap(&engine, &mesh, &plain);
    let q = &un.report.quality;
    assert_eq!((un.cut.edges.len(), un.cut.pieces.len()), (0, 1));
    assert_eq!((q.flipped, q.overlaps), (0, 0), "{q:?}");
    assert!(
        q.angle_distortion.p95 < 1.8 && q.area_distortion.p95 < 1.5,
        "{q:?}"
    );
    assert!(un.report.pieces[0].relax.steady);
    // The rim lies on the frame: every boundary vertex at the same distance from the centre of the
    // boundary, within 1 % (the frame springs are stiff, not rigid).
    let piece = &un.cut.pieces[0];
    let uv = &un.uv[0];
    let rim: Vec<DVec2> = piece
        .boundary
        .iter()
        .map(|&v| uv[v as usize].as_dvec2())
        .collect();
    let c = rim.iter().sum::<DVec2>() / rim.len() as f64;
    let r: Vec<f64> = rim.iter().map(|p| (*p - c).length()).collect();
    let (lo, hi) = r
        .iter()
        .fold((f64::MAX, 0f64), |a, &x| (a.0.min(x), a.1.max(x)));
    assert!(hi / lo < 1.01, "rim radii {lo}..{hi}");
    // Conformal refinement from the pelt: nearly conformal, still no folds.
    let refined = gpu_unwrap(&engine, &mesh, &Options::default());
    let q = &refined.report.quality;
    assert_eq!((q.flipped, q.overlaps), (0, 0));
    assert!(q.angle_distortion.p95 < 1.12, "{q:?}");
    assert!(refined.report.pieces[0].refine.unwrap().kept);
}

/// The GPU dynamics against the CPU twin on the same net: the same number of steps (the steadiness
/// check is the same), positions within 1e-4 of the frame radius (f32 against f64 over about 800
/// steps; measured 2e-5), and the energy at every check falls (the damped dynamics only loses
/// energy once the frame has pulled the rim out; measured from the first check on). With the
/// kernel's spring force turned round the GPU never settles (19,968 steps against the twin's 832).
#[test]
fn gpu_dynamics_match_the_cpu_twin() {
    let engine = common::engine();
    let mesh = hemisphere(8, 32);
    let topo = Topology::build(&mesh, DEFAULT_WELD_TOLERANCE);
    let cut = pelt::cut::cut(&mesh, &topo, &CutSpec::Auto, Path::new("h")).unwrap();
    let net = relax::net(&topo, &cut.pieces[0], Frame::Circle);
    let cfg = SystemCfg::default();
    let mut trace = Vec::new();
    let cpu = relax::relax_cpu(&net, &cfg, Some(&mut trace));
    let gpu = pelt::gpu::relax_gpu(
        &engine.ctx,
        engine.pipelines(),
        std::slice::from_ref(&net),
        &cfg,
    )
    .unwrap();
    let gpu = &gpu[0];
    assert_eq!((gpu.steps, gpu.steady), (cpu.steps, cpu.steady));
    assert!(cpu.steady && cpu.steps > 2 * cfg.interval());
    let radius = net
        .anchor
        .iter()
        .map(|a| (a[0] as f64).hypot(a[1] as f64))
        .fold(0.0, f64::max);
    let worst = cpu
        .x
        .iter()
        .zip(&gpu.x)
        .map(|(a, b)| (DVec3::from(*a) - DVec3::from(*b)).length())
        .fold(0.0, f64::max);
    assert!(worst < 1e-4 * radius, "worst {worst} of radius {radius}");
    assert!(
        trace.windows(2).all(|w| w[1] <= w[0]),
        "energy at the checks: {trace:?}"
    );
    assert!(trace.last().unwrap() < &(1e-2 * cpu.energy[0]));
    // The GPU's own trajectory, cut at the first checks, falls too.
    let energies: Vec<f64> = (1..=4)
        .map(|k| {
            let cut_short = SystemCfg {
                max_steps: k * cfg.interval(),
                ..cfg
            };
            let r = pelt::gpu::relax_gpu(
                &engine.ctx,
                engine.pipelines(),
                std::slice::from_ref(&net),
                &cut_short,
            )
            .unwrap();
            r[0].energy[1]
        })
        .collect();
    assert!(energies.windows(2).all(|w| w[1] <= w[0]), "{energies:?}");
    for (g, c) in energies.iter().zip(&trace) {
        assert!(
            (g - c).abs() <= 1e-3 * c,
            "GPU energy {g} against the twin's {c}"
        );
    }
}

/// The last rung solved directly (`pelt::tutte`) is the dynamics' steady state: on a hemisphere
/// of 1,537 vertices (3,074 unknowns: the multigrid V-cycle), the CPU solve against the twin's
/// dynamics of the same net run to a tight steadiness (positions within 1e-4 of the frame radius:
/// the dynamics stops at a speed, not at the state; measured 2.1e-6) and no lower energy than the
/// solve's (the solve is the quadratic energy's minimiser), the GPU solve (f32) against the CPU
/// one within 1e-5 of the radius (measured 5e-7), and the analytic answer: the layout has the
/// hemisphere's 64-fold symmetry, so the pole lies at the frame's centre and every ring on a
/// circle (within 1e-5 of the radius; f32 frame points). With the frame springs left out of the
/// right-hand side the solve is the origin, and the comparison with the dynamics fails (checked).
#[test]
fn tutte_solve_is_the_dynamics_steady_state() {
    let engine = common::engine();
    let mesh = hemisphere(24, 64);
    let topo = Topology::build(&mesh, DEFAULT_WELD_TOLERANCE);
    let cut = pelt::cut::cut(&mesh, &topo, &CutSpec::Auto, Path::new("h")).unwrap();
    let piece = &cut.pieces[0];
    let net = relax::net(&topo, piece, Frame::Circle).with_rest_scale(0.0);
    let radius = net
        .anchor
        .iter()
        .map(|a| (a[0] as f64).hypot(a[1] as f64))
        .fold(0.0, f64::max);
    let cpu = &pelt::tutte::settle(Device::Cpu, std::slice::from_ref(&net)).unwrap()[0];
    let dev = Device::Gpu(&engine.ctx, engine.pipelines());
    let gpu = &pelt::tutte::settle(dev, std::slice::from_ref(&net)).unwrap()[0];
    let tight = SystemCfg {
        tol2: 1e-16,
        max_steps: 100_000,
        ..SystemCfg::default()
    };
    let dynamics = relax::relax_cpu(&net, &tight, None);
    assert!(cpu.steady && gpu.steady && dynamics.steady);
    let worst = |a: &[[f64; 3]], b: &[[f64; 3]]| {
        a.iter()
            .zip(b)
            .map(|(p, q)| (DVec3::from(*p) - DVec3::from(*q)).length())
            .fold(0.0, f64::max)
    };
    let (d_dyn, d_gpu) = (worst(&cpu.x, &dynamics.x), worst(&cpu.x, &gpu.x));
    println!(
        "radius {radius:.2}: solve vs dynamics ({} steps) {d_dyn:.2e}, GPU vs CPU {d_gpu:.2e}; \
         energy solve {:.6e} dynamics {:.6e}; {} / {} CG iterations",
        dynamics.steps, cpu.energy[1], dynamics.energy[1], cpu.iterations, gpu.iterations
    );
    assert!(d_dyn < 1e-4 * radius, "solve against the dynamics: {d_dyn}");
    assert!(d_gpu < 1e-5 * radius, "GPU against CPU: {d_gpu}");
    assert!(cpu.energy[1] <= dynamics.energy[1] * (1.0 + 1e-9));
    let pole = piece
        .welded
        .iter()
        .position(|&w| topo.positions[w as usize].z > 0.9999)
        .expect("the pole");
    for r in [cpu, gpu] {
        let c = DVec2::new(r.x[pole][0], r.x[pole][1]);
        assert!(c.length() < 1e-5 * radius, "pole at {c}");
        let mut rings: HashMap<i64, (f64, f64)> = HashMap::new();
        for (i, &w) in piece.welded.iter().enumerate() {
            let z = (topo.positions[w as usize].z as f64 * 1e4).round() as i64;
            let d = r.x[i][0].hypot(r.x[i][1]);
            let e = rings.entry(z).or_insert((f64::MAX, 0.0));
            *e = (e.0.min(d), e.1.max(d));
        }
        assert_eq!(rings.len(), 25);
        for (z, (lo, hi)) in rings {
            assert!(hi - lo < 1e-5 * radius, "ring at z {z}: {lo} .. {hi}");
        }
    }
}

/// An open cylinder has two rims: the cut must join them (one path from rim to rim), and the
/// conformal layout of a developable piece is its unrolling: every triangle keeps its shape and
/// size (σ1/σ2 and the area ratio within 1 %; the mesh is exactly developable, so only the f32
/// solve's residual remains) and the layout is a rectangle of the circumference by the height.
/// The packing's split is off: the rectangle, π times as long as high, would be cut in two to
/// fill the square (`pelt::repack`).
#[test]
fn cylinder_is_cut_rim_to_rim_and_unrolled() {
    let engine = common::engine();
    let (n, m) = (32, 8);
    let mesh = common::cylinder(n, m);
    let topo = Topology::build(&mesh, DEFAULT_WELD_TOLERANCE);
    let whole = Options {
        pack_splits: false,
        ..Options::default()
    };
    let un = gpu_unwrap(&engine, &mesh, &whole);
    assert_eq!(un.cut.pieces.len(), 1);
    assert!(!un.cut.edges.is_empty());
    // The opened edges connect a vertex of the bottom rim to one of the top rim.
    let z = |v: u32| topo.positions[v as usize].z;
    let mut adj: HashMap<u32, Vec<u32>> = HashMap::new();
    for e in &un.cut.edges {
        adj.entry(e[0]).or_default().push(e[1]);
        adj.entry(e[1]).or_default().push(e[0]);
    }
    let start = *adj
        .keys()
        .find(|&&v| z(v) < -0.99)
        .expect("the cut reaches the bottom rim");
    let mut seen = HashSet::from([start]);
    let mut stack = vec![start];
    while let Some(v) = stack.pop() {
        for &w in &adj[&v] {
            if seen.insert(w) {
                stack.push(w);
            }
        }
    }
    assert!(
        seen.iter().any(|&v| z(v) > 0.99),
        "the cut does not reach the top rim"
    );
    let q = &un.report.quality;
    assert_eq!((q.flipped, q.overlaps), (0, 0));
    assert!(
        q.angle_distortion.max < 1.01 && q.area_distortion.max < 1.01,
        "{q:?}"
    );
    let (lo, hi) = un.uv[0]
        .iter()
        .fold((DVec2::MAX, DVec2::MIN), |(lo, hi), p| {
            (lo.min(p.as_dvec2()), hi.max(p.as_dvec2()))
        });
    let side = hi - lo;
    let circumference = n as f64 * 2.0 * (std::f64::consts::PI / n as f64).sin();
    let aspect = side.max_element() / side.min_element();
    assert!(
        (aspect / (circumference / 2.0) - 1.0).abs() < 0.01,
        "box {side:?}: aspect {aspect} against {}",
        circumference / 2.0
    );
}

/// Independent checks of a layout: every piece a disk (V − E + F = 1, one boundary loop), no
/// triangle of the written UV set flipped within its piece, no two triangles overlapping (brute
/// force over all pairs, not the engine's grid).
fn check_layout(mesh: &Mesh, un: &pelt::Unwrapped) {
    for (i, p) in un.cut.pieces.iter().enumerate() {
        let mut edges = HashSet::new();
        for t in &p.triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                edges.insert((a.min(b), a.max(b)));
            }
        }
        let chi = p.welded.len() as i64 - edges.len() as i64 + p.triangles.len() as i64;
        let loops = pelt::cut::boundary_loops(&p.triangles).len();
        assert_eq!((chi, loops), (1, 1), "piece {i}");
    }
    let out = pelt::apply(mesh, un, mesh.uv_sets.len());
    assert_eq!(out.triangles.len(), mesh.triangles.len());
    let uv = out.uv_sets.last().unwrap();
    assert!(uv
        .iter()
        .all(|p| (0.0..=1.0).contains(&p.x) && (0.0..=1.0).contains(&p.y)));
    let tris: Vec<[DVec2; 3]> = out
        .triangles
        .iter()
        .map(|t| t.map(|v| uv[v as usize].as_dvec2()))
        .collect();
    // glTF's v runs down: a layout that keeps the mesh's winding is clockwise in (u, v).
    let flipped = tris
        .iter()
        .filter(|q| (q[1] - q[0]).perp_dot(q[2] - q[0]) >= 0.0)
        .count();
    assert_eq!(flipped, 0);
    let mut overlapping = 0;
    for (i, a) in tris.iter().enumerate() {
        let share = |j: usize| {
            out.triangles[i]
                .iter()
                .any(|v| out.triangles[j].contains(v))
        };
        for (j, b) in tris.iter().enumerate().skip(i + 1) {
            if !share(j) && overlap(a, b) {
                overlapping += 1;
            }
        }
    }
    assert_eq!(overlapping, 0);
}

/// Whether two triangles' interiors overlap by more than 1e-9 (separating axes).
fn overlap(a: &[DVec2; 3], b: &[DVec2; 3]) -> bool {
    for t in [a, b] {
        for k in 0..3 {
            let e = t[(k + 1) % 3] - t[k];
            let n = DVec2::new(-e.y, e.x);
            let pa = a.map(|p| n.dot(p));
            let pb = b.map(|p| n.dot(p));
            let eps = 1e-9 * n.length();
            let (amin, amax) = (pa[0].min(pa[1]).min(pa[2]), pa[0].max(pa[1]).max(pa[2]));
            let (bmin, bmax) = (pb[0].min(pb[1]).min(pb[2]), pb[0].max(pb[1]).max(pb[2]));
            if amax <= bmin + eps || bmax <= amin + eps {
                return false;
            }
        }
    }
    true
}

/// Spot (closed, genus 0) and bob (closed, genus 1) with the automatic cut: every piece
/// a disk, nothing flipped or overlapping after packing, the written file valid, and at least half
/// the texture used (bob's body, 2.6 times as long as wide, is split for the packing: 64 %
/// measured, 34 % without `pelt::repack`, which fails this). The genus is asserted from the welded
/// surface (V − E + F = 2 − 2g) so the test covers a handle.
#[test]
fn closed_models_become_disks() {
    let engine = common::engine();
    for (file, genus) in [("spot.glb", 0), ("bob.glb", 1)] {
        let mesh = Mesh::load(&asset(file)).unwrap();
        let topo = Topology::build(&mesh, DEFAULT_WELD_TOLERANCE);
        let mut edges = HashSet::new();
        for t in &topo.triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                edges.insert((a.min(b), a.max(b)));
            }
        }
        let chi = topo.positions.len() as i64 - edges.len() as i64 + topo.triangles.len() as i64;
        assert_eq!(chi, 2 - 2 * genus, "{file}");
        assert!(topo.boundary_edges.is_empty(), "{file} is closed");
        // Spot through the GPU; bob through the CPU twin of the whole pipeline (the twin is
        // compared with the GPU on the dynamics and the Tutte solve above).
        let un = if genus == 0 {
            gpu_unwrap(&engine, &mesh, &Options::default())
        } else {
            pelt::unwrap(
                Device::Cpu,
                &mesh,
                &topo,
                &Options::default(),
                Path::new(file),
            )
            .unwrap()
        };
        check_layout(&mesh, &un);
        let mut filled = mesh.clone();
        topo.fill_normals(&mut filled);
        let out = pelt::apply(&filled, &un, mesh.uv_sets.len());
        let glb = common::scratch(&format!("closed-{genus}")).join(file);
        let written = decalbake::output::gltf::write_model(&out, &[], &glb).unwrap();
        std::fs::write(&glb, &written.files[0].1).unwrap();
        validate(&glb);
        let q = &un.report.quality;
        eprintln!("{file}: {} pelts, {q:?}", un.cut.pieces.len());
        assert!(q.texel_utilisation >= 0.5, "{file}: {q:?}");
    }
}

fn write_mesh(path: &Path, mesh: &Mesh) {
    let pos: Vec<[f32; 3]> = mesh.positions.iter().map(|p| p.to_array()).collect();
    let idx: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
    common::write_glb(path, &pos, None, &idx);
}

/// `decalbake unwrap` on a mesh without UVs writes TEXCOORD_0, a report and a preview; on Spot
/// (textured, TEXCOORD_0) it writes TEXCOORD_1 next to the old set and keeps the texture. Both
/// files pass the Khronos validator.
#[test]
fn unwrap_command_writes_a_valid_glb() {
    let dir = common::scratch("unwrap-cli");
    let src = dir.join("dome.glb");
    write_mesh(&src, &hemisphere(6, 24));
    let out = dir.join("dome-unwrapped.glb");
    let report = dir.join("dome.json");
    let preview = dir.join("dome.png");
    let (code, _, err) = common::cli(&[
        "unwrap",
        src.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
        "--preview",
        preview.to_str().unwrap(),
        "--gpu",
    ]);
    assert_eq!(code, 0, "{err}");
    let m = Mesh::load(&out).unwrap();
    assert_eq!(m.uv_sets.len(), 1);
    let read = |p: &Path| -> serde_json::Value {
        serde_json::from_slice(&std::fs::read(p).unwrap()).unwrap()
    };
    let r = read(&report);
    assert_eq!(r["uv_set"], 0);
    assert_eq!(r["quality"]["flipped"], 0);
    assert_eq!(r["device"], "gpu");
    // Without `--gpu` or `--cpu`: the CPU twin on a CPU adapter (lavapipe), the kernels on a GPU.
    let (code, _, err) = common::cli(&[
        "unwrap",
        src.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let kind = common::engine().ctx.device_type;
    // The command decided from the adapter's kind, asked without a device: the engine's.
    assert_eq!(decalbake::gpu::GpuContext::adapter_type(None), kind);
    let cpu_adapter = kind == Some(wgpu::DeviceType::Cpu);
    let r = read(&report);
    assert_eq!(r["device"], if cpu_adapter { "cpu" } else { "gpu" });
    assert_eq!(
        (
            r["quality"]["flipped"].as_u64(),
            r["quality"]["overlaps"].as_u64()
        ),
        (Some(0), Some(0))
    );
    let img = image::open(&preview).unwrap();
    assert_eq!((img.width(), img.height()), (1024, 1024));
    validate(&out);

    let spot = dir.join("spot-unwrapped.glb");
    let (code, _, err) = common::cli(&[
        "unwrap",
        asset("spot.glb").to_str().unwrap(),
        "--out",
        spot.to_str().unwrap(),
        "--cpu",
    ]);
    assert_eq!(code, 0, "{err}");
    let m = Mesh::load(&spot).unwrap();
    assert_eq!(m.uv_sets.len(), 2);
    assert!(m.material.unwrap().base_color_texture.is_some());
    validate(&spot);
}

/// Bad input: exit 2, a message naming what is wrong and what to do, and no output file.
#[test]
fn unwrap_command_refuses_bad_input() {
    let dir = common::scratch("unwrap-bad");
    let out = dir.join("out.glb");
    let run = |mesh: &Path, extra: &[&str]| {
        let (code, _, err) = unwrap_cli(mesh, &out, extra);
        assert!(!out.exists(), "no output on failure");
        (code, err)
    };
    let spot = asset("spot.glb");
    let (code, err) = run(&spot, &["--uv-set", "0"]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("TEXCOORD_0") && err.contains("--force"),
        "{err}"
    );
    let (code, err) = run(&spot, &["--uv-set", "3"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("gap"), "{err}");

    let cyl = dir.join("cylinder.glb");
    write_mesh(&cyl, &common::cylinder(16, 4));
    let cut = dir.join("cut.json");
    std::fs::write(&cut, r#"{"edges": [[0, 999]]}"#).unwrap();
    let (code, err) = run(&cyl, &["--cut", cut.to_str().unwrap()]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("cut edge 0 (0, 999) is not an edge"), "{err}");
    std::fs::write(&cut, r#"{"edges": []}"#).unwrap();
    let (code, err) = run(&cyl, &["--cut", cut.to_str().unwrap()]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("is not a disk") && err.contains("2 boundary loops"),
        "{err}"
    );
    std::fs::write(&cut, r#"{"cuts": []}"#).unwrap();
    let (code, err) = run(&cyl, &["--cut", cut.to_str().unwrap()]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("`edges`") && err.contains("`polylines`"),
        "{err}"
    );

    // Three triangles on one edge.
    let fin = dir.join("fin.glb");
    common::write_fin(&fin);
    let (code, err) = run(&fin, &[]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("non-manifold") && err.contains("--split-non-manifold"),
        "{err}"
    );
    // Offered the split, it takes it: each triangle of the fin is a pelt of its own.
    let report = dir.join("fin.json");
    let (code, _, err) = common::cli(&[
        "unwrap",
        fin.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--cpu",
        "--split-non-manifold",
        "--report",
        report.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let r: serde_json::Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    assert_eq!(r["pieces"].as_array().unwrap().len(), 3);
    assert_eq!(r["quality"]["overlaps"], 0);
    std::fs::remove_file(&out).unwrap();
}

/// An artist's cut drawn as a polyline on the surface: the cylinder cut along a line from rim to
/// rim becomes one disk, its seam the polyline's path.
#[test]
fn polyline_cut_opens_the_cylinder() {
    let mesh = common::cylinder(16, 4);
    let topo = Topology::build(&mesh, DEFAULT_WELD_TOLERANCE);
    let edges = pelt::cut::polyline_edges(&topo, &[[1.0, 0.0, -1.0], [1.0, 0.0, 1.0]]);
    assert_eq!(edges.len(), 4, "{edges:?}");
    for e in &edges {
        for v in e {
            let p = topo.positions[*v as usize];
            assert!(
                (p.x - 1.0).abs() < 1e-6 && p.y.abs() < 1e-6,
                "{p:?} is off the line"
            );
        }
    }
    let cut = pelt::cut::cut(&mesh, &topo, &CutSpec::Edges(edges), Path::new("c")).unwrap();
    assert_eq!(cut.pieces.len(), 1);
}

/// Keenan Crane's crumpled developable sheet (bundled) is an open disc whose UVs are its exact
/// isometric flattening: the unwrap (pelt, then conformal refinement) must find that flattening.
/// After the best similarity (complex least squares, either orientation) every vertex lies within
/// 1e-3 of the sheet's UV size of its own UV, and no triangle changes shape or size by more than
/// 0.5 % (measured 0.19 % with the solve's tolerance at 1e-6, 0.034 % at 1e-7; at 1e-5 the area
/// distortion was 29 %, which this catches).
#[test]
fn developable_sheet_unwraps_to_its_flattening() {
    let engine = common::engine();
    let mesh = Mesh::load(&asset("crumpled_developable.glb")).unwrap();
    let topo = Topology::build(&mesh, DEFAULT_WELD_TOLERANCE);
    let un = gpu_unwrap(&engine, &mesh, &Options::default());
    let q = &un.report.quality;
    assert_eq!((un.cut.pieces.len(), q.flipped, q.overlaps), (1, 0, 0));
    assert!(
        q.angle_distortion.max < 1.005 && q.area_distortion.max < 1.005,
        "{q:?}"
    );
    // Pairs (ours, theirs) per welded vertex.
    let mut split_of = vec![0usize; topo.positions.len()];
    for (s, &w) in topo.welded_of.iter().enumerate() {
        split_of[w as usize] = s;
    }
    let piece = &un.cut.pieces[0];
    let pairs: Vec<(DVec2, DVec2)> = piece
        .welded
        .iter()
        .enumerate()
        .map(|(i, &w)| {
            (
                un.uv[0][i].as_dvec2(),
                mesh.uv_sets[0][split_of[w as usize]].as_dvec2(),
            )
        })
        .collect();
    let size = {
        let (lo, hi) = pairs.iter().fold((DVec2::MAX, DVec2::MIN), |(lo, hi), p| {
            (lo.min(p.1), hi.max(p.1))
        });
        (hi - lo).max_element()
    };
    let worst = [false, true]
        .iter()
        .map(|&mirror| {
            let z: Vec<DVec2> = pairs
                .iter()
                .map(|p| {
                    if mirror {
                        DVec2::new(p.0.x, -p.0.y)
                    } else {
                        p.0
                    }
                })
                .collect();
            let w: Vec<DVec2> = pairs.iter().map(|p| p.1).collect();
            let n = z.len() as f64;
            let (zc, wc) = (z.iter().sum::<DVec2>() / n, w.iter().sum::<DVec2>() / n);
            // a = Σ conj(z') w' / Σ |z'|², as complex numbers.
            let (mut num, mut den) = (DVec2::ZERO, 0.0);
            for (a, b) in z.iter().zip(&w) {
                let (a, b) = (*a - zc, *b - wc);
                num += DVec2::new(a.x * b.x + a.y * b.y, a.x * b.y - a.y * b.x);
                den += a.length_squared();
            }
            let a = num / den;
            z.iter()
                .zip(&w)
                .map(|(p, q)| {
                    let d = *p - zc;
                    let r = DVec2::new(a.x * d.x - a.y * d.y, a.x * d.y + a.y * d.x) + wc;
                    (r - *q).length()
                })
                .fold(0.0, f64::max)
        })
        .fold(f64::MAX, f64::min);
    assert!(worst < 1e-3 * size, "worst {worst} of {size}");
}

/// `"uv_set": "auto"` on a mesh without UVs (the crumpled sheet with its UVs stripped): the bake
/// unwraps it on the GPU, bakes the decal into the new set, and writes a `.glb` that carries the
/// set (and passes the validator); the report says how the set was made. Without `"auto"` the same
/// job is refused (exit 2) and says to add it.
#[test]
fn bake_with_auto_uv_set_unwraps_a_mesh_without_uvs() {
    let dir = common::scratch("auto-uv");
    let sheet = Mesh::load(&asset("crumpled_developable.glb")).unwrap();
    write_mesh(&dir.join("sheet.glb"), &sheet);
    std::fs::write(
        dir.join("logo.png"),
        common::test_image(32, 32, 3, false).encode_png(8),
    )
    .unwrap();
    let centre = sheet.positions[sheet.positions.len() / 2];
    let job = |uv_set: serde_json::Value| {
        serde_json::json!({ "mesh": "sheet.glb", "uv_set": uv_set,
            "texture": { "width": 256, "height": 256, "base": [0.5, 0.5, 0.5, 1.0] },
            "layers": [{ "image": "logo.png", "at": centre.to_array(), "size": [0.5, 0.5] }],
            "output": { "texture": "baked.png", "glb": "baked.glb", "report": "report.json" } })
        .to_string()
    };
    std::fs::write(dir.join("plain.json"), job(serde_json::json!(0))).unwrap();
    let (code, _, err) = common::cli(&["bake", dir.join("plain.json").to_str().unwrap()]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("\"uv_set\": \"auto\""), "{err}");
    assert!(!dir.join("baked.png").exists());

    std::fs::write(dir.join("auto.json"), job(serde_json::json!("auto"))).unwrap();
    let (code, _, err) = common::cli(&["bake", dir.join("auto.json").to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    let out = Mesh::load(&dir.join("baked.glb")).unwrap();
    assert_eq!(out.uv_sets.len(), 1);
    let r: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("report.json")).unwrap()).unwrap();
    assert_eq!(r["uv_set"], 0);
    assert_eq!(r["unwrap"]["quality"]["flipped"], 0);
    assert_eq!(r["unwrap"]["quality"]["overlaps"], 0);
    // The decal is in the texture: the texels it covers are not the grey base.
    let covered = r["layers"][0]["texels_covered"].as_u64().unwrap();
    assert!(covered > 500, "{covered} texels covered");
    let img = decalbake::io::image::LinearImage::load(&dir.join("baked.png")).unwrap();
    let grey = decalbake::io::image::srgb_to_linear(0.5);
    let changed = img
        .pixels
        .iter()
        .filter(|p| (p[0] - grey).abs() > 0.05 || (p[1] - grey).abs() > 0.05)
        .count();
    assert!(changed > 500, "{changed} texels differ from the base");
    validate(&dir.join("baked.glb"));

    std::fs::write(dir.join("bad.json"), job(serde_json::json!("automatic"))).unwrap();
    let (code, _, err) = common::cli(&["bake", dir.join("bad.json").to_str().unwrap()]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("uv_set") && err.contains("\"auto\""), "{err}");
}

/// Bakes `base` into `uv_set` of `mesh` at `side`², no layers, no padding.
fn transfer_bake(
    engine: &decalbake::Engine,
    mesh: &decalbake::LoadedMesh,
    dir: &Path,
    base: serde_json::Value,
    uv_set: u32,
    side: u32,
) -> decalbake::Baked {
    let text = serde_json::json!({ "mesh": "unused.glb", "uv_set": uv_set,
        "texture": { "width": side, "height": side, "base": base, "padding": 0 } })
    .to_string();
    let job = decalbake::Job::parse(&text, &dir.join("job.json"), dir, dir).unwrap();
    engine.bake(mesh, &job).unwrap()
}

/// Spot's own texture (on TEXCOORD_0) transferred into a new unwrap (TEXCOORD_1). The transfer on
/// the GPU equals its CPU twin (the same samples averaged): within 1/255 in sRGB
/// 8-bit at 99.5 % of the covered texels (measured: all but a handful equal; the rest, up to 8/255,
/// are texels with a sample on a triangle's edge, which the raster gives to one triangle and the
/// twin to both, next to a sharp edge of the texture), and the transferred texture, sampled at random surface points through
/// the new set, matches the source sampled through the old one (points inside triangles, away from
/// their edges): median difference below 1e-3 and 90 % below 0.01 (linear) at 1024² (measured
/// 3e-8 and 1.9e-4: the new layout has about the old one's texel density, so resampling loses
/// little); back into the old set, below 1e-3 and 0.03 (measured 0 and 0.0074: two resamplings).
/// Read through the wrong set the same measure's p90 is above 0.1.
#[test]
fn texture_transfer_matches_the_source() {
    let engine = common::engine();
    let dir = common::scratch("transfer");
    let spot = Mesh::load(&asset("spot.glb")).unwrap();
    let topo = Topology::build(&spot, DEFAULT_WELD_TOLERANCE);
    let opts = Options {
        size: 1024,
        ..Options::default()
    };
    let un = pelt::unwrap(Device::Cpu, &spot, &topo, &opts, Path::new("spot")).unwrap();
    let two = pelt::apply(&spot, &un, 1);
    let source = spot.material.clone().unwrap().base_color_texture.unwrap();
    let loaded = engine.prepare(two.clone()).unwrap();
    let material = serde_json::json!({"transfer": {"from_uv_set": 0}});

    // GPU against the twin at 128².
    let side = 128;
    let baked = transfer_bake(&engine, &loaded, &dir, material.clone(), 1, side);
    let twin =
        decalbake::bake::cpu_tools::transfer_cpu((&two, &topo, 1), 0, &source, [side, side], 2);
    let mut diffs = Vec::new();
    for (i, t) in twin.iter().enumerate() {
        let Some(t) = t else { continue };
        let (x, y) = (i as u32 % side, i as u32 / side);
        let g = baked.linear(x, y);
        let d = (0..3)
            .map(|k| {
                let enc = |v: f32| (decalbake::io::image::linear_to_srgb(v) * 255.0).round();
                (enc(g[k]) - enc(t[k])).abs()
            })
            .fold(0f32, f32::max);
        diffs.push(d);
    }
    diffs.sort_by(f32::total_cmp);
    assert!(diffs.len() > 2000, "{} covered texels", diffs.len());
    let over = diffs.iter().filter(|&&d| d > 1.0).count();
    assert!(
        over * 200 <= diffs.len(),
        "{over} of {} texels differ by more than 1/255 (max {:?})",
        diffs.len(),
        diffs.last()
    );

    // Against the source at random surface points, there and back.
    let side = 1024;
    let forth = transfer_bake(&engine, &loaded, &dir, material, 1, side);
    let img = |b: &decalbake::Baked| decalbake::io::image::LinearImage {
        width: b.width,
        height: b.height,
        pixels: (0..b.height)
            .flat_map(|y| (0..b.width).map(move |x| (x, y)))
            .map(|(x, y)| b.linear(x, y))
            .collect(),
    };
    let forth_img = img(&forth);
    std::fs::write(dir.join("forth.png"), forth_img.encode_png(8)).unwrap();
    let back = transfer_bake(
        &engine,
        &loaded,
        &dir,
        serde_json::json!({"transfer": {"from_uv_set": 1, "image": "forth.png"}}),
        0,
        side,
    );
    let back_img = img(&back);
    let stats = |a: &decalbake::io::image::LinearImage,
                 set_a: usize,
                 b: &decalbake::io::image::LinearImage,
                 set_b: usize| {
        let mut rng = 12345u64;
        let mut next = || {
            rng = rng
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((rng >> 33) as f32) / (1u64 << 31) as f32
        };
        let mut d = Vec::new();
        for _ in 0..4000 {
            let t = (next() * two.triangles.len() as f32) as usize % two.triangles.len();
            let (r, s) = (0.15 + 0.7 * next(), 0.15 + 0.7 * next());
            // Reflected into the triangle: every barycentric at least 0.15 (0.85 - s >= 0).
            let (r, s) = if r + s > 0.85 {
                (0.85 - s, 0.85 - r)
            } else {
                (r, s)
            };
            let bary = [1.0 - r - s, r, s];
            let at = |set: usize| {
                two.triangles[t]
                    .iter()
                    .zip(bary)
                    .map(|(&v, w)| two.uv_sets[set][v as usize] * w)
                    .sum::<glam::Vec2>()
            };
            let (ua, ub) = (at(set_a), at(set_b));
            let (pa, pb) = (a.bilinear(ua.x, ua.y, false), b.bilinear(ub.x, ub.y, false));
            d.push((0..3).map(|k| (pa[k] - pb[k]).abs()).fold(0f32, f32::max));
        }
        d.sort_by(f32::total_cmp);
        (d[d.len() / 2], d[d.len() * 9 / 10])
    };
    let (median, p90) = stats(&source, 0, &forth_img, 1);
    assert!(
        median < 1e-3 && p90 < 0.01,
        "forth: median {median}, p90 {p90}"
    );
    let (median2, p902) = stats(&source, 0, &back_img, 0);
    assert!(
        median2 < 1e-3 && p902 < 0.03,
        "back: median {median2}, p90 {p902}"
    );
    // The measure can fail: the texture read through the wrong set is far off.
    let wrong = transfer_bake(
        &engine,
        &loaded,
        &dir,
        serde_json::json!({"transfer": {"from_uv_set": 1}}),
        1,
        side,
    );
    let (_, p90_wrong) = stats(&source, 0, &img(&wrong), 1);
    assert!(p90_wrong > 0.1, "wrong set: p90 {p90_wrong}");
    eprintln!("transfer: forth median {median} p90 {p90}; back median {median2} p90 {p902}");
}

/// A float attribute of a `.glb` written by decalbake (one primitive), read from its JSON and BIN.
fn glb_attribute(path: &Path, name: &str) -> Vec<f32> {
    let bytes = std::fs::read(path).unwrap();
    let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let doc: serde_json::Value = serde_json::from_slice(&bytes[20..20 + json_len]).unwrap();
    let bin = &bytes[20 + json_len + 8..];
    let acc = &doc["accessors"][doc["meshes"][0]["primitives"][0]["attributes"][name]
        .as_u64()
        .unwrap_or_else(|| panic!("no {name}")) as usize];
    let view = &doc["bufferViews"][acc["bufferView"].as_u64().unwrap() as usize];
    let off = view["byteOffset"].as_u64().unwrap() as usize;
    let n = acc["count"].as_u64().unwrap() as usize;
    bytemuck::pod_collect_to_vec(&bin[off..off + 4 * n])
}

/// Re-unwrapping a model that has `_PELT_BLEND`, without `--patch`: replacing the pelt's set
/// (`--uv-set 1 --force`) leaves the old weights out (they paired the old layouts) and says so;
/// appending a set keeps them, since the sets they pair are untouched. Before, a replaced pelt
/// kept the old weights and the blended preview mixed the new pelt with the old patch.
fn stale_weights_are_left_out(patched: &Path, dir: &Path) {
    let unwrap = |out: &Path, extra: &[&str]| unwrap_cli(patched, out, extra);
    let replaced = dir.join("replaced.glb");
    let (code, _, err) = unwrap(&replaced, &["--uv-set", "1", "--force"]);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("_PELT_BLEND"), "{err}");
    let m = Mesh::load(&replaced).unwrap();
    assert_eq!((m.uv_sets.len(), m.blend.len(), m.bridge.len()), (3, 0, 0));
    let appended = dir.join("appended.glb");
    let (code, _, err) = unwrap(&appended, &[]);
    assert_eq!(code, 0, "{err}");
    let m = Mesh::load(&appended).unwrap();
    assert_eq!((m.uv_sets.len(), m.blend.len()), (4, m.positions.len()));
}

/// `--patch` (Piponi & Borshukov §5) on Spot: the pelt (TEXCOORD_1, one pelt: the seam is the cut
/// tree), the patch (TEXCOORD_2) and `_PELT_BLEND` (b0) in a file the validator passes. Checked
/// from the file alone: the seam is every edge whose two triangles give it different pelt UVs; b0
/// is 0 exactly on
/// the vertices within 2 edges of it and 1 elsewhere (so b0 and b1 = 1 − b0 are a partition of
/// unity, each in [0, 1]); and every triangle where the patch shows (a corner with b0 < 1) has
/// patch UVs that are not flipped and overlap no other such triangle.
#[test]
fn patch_and_blend_function_hide_the_cut() {
    let dir = common::scratch("patch");
    let out = dir.join("spot.glb");
    let (code, _, err) = common::cli(&[
        "unwrap",
        asset("spot.glb").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--patch",
        "--cpu",
    ]);
    assert_eq!(code, 0, "{err}");
    validate(&out);
    let m = Mesh::load(&out).unwrap();
    assert_eq!(m.uv_sets.len(), 3);
    let b0 = glb_attribute(&out, "_PELT_BLEND");
    assert_eq!(b0.len(), m.positions.len());
    let topo = Topology::build(&m, DEFAULT_WELD_TOLERANCE);
    // The seam (C0): the ends of every edge whose two triangles give it different pelt UVs.
    let mut seam: Vec<u32> = seam_edges(&m, &topo, 1)
        .into_iter()
        .flat_map(|(a, b)| [a, b])
        .collect();
    seam.sort_unstable();
    seam.dedup();
    assert!(seam.len() > 20, "{} seam vertices", seam.len());
    let d = pelt::patch::rings(&topo, &seam, 10);
    for (s, &w) in topo.welded_of.iter().enumerate() {
        let want = if d[w as usize] <= 2 { 0.0 } else { 1.0 };
        assert_eq!(
            b0[s], want,
            "vertex {s}, {} edges from the seam",
            d[w as usize]
        );
    }
    let shown: Vec<[DVec2; 3]> = m
        .triangles
        .iter()
        .filter(|t| t.iter().any(|&v| b0[v as usize] < 1.0))
        .map(|t| t.map(|v| m.uv_sets[2][v as usize].as_dvec2()))
        .collect();
    assert!(shown.len() > 100);
    assert_eq!(flipped_and_overlapping(&shown), (0, 0));
    stale_weights_are_left_out(&out, &dir);

    // Both sets baked by one job: a texture and a report per set. At 256² texels: the patch keeps
    // the seams' tips uncut, so its layout shrinks round them (area distortion up to about 2,000 on
    // Spot) and a small decal near one covers only a few texels of the patch's set.
    std::fs::write(
        dir.join("logo.png"),
        common::test_image(32, 32, 5, false).encode_png(8),
    )
    .unwrap();
    let seam_point = topo.positions[seam[seam.len() / 2] as usize];
    let job = |texture: &str| {
        serde_json::json!({ "mesh": "spot.glb", "uv_set": [1, 2],
            "texture": { "width": 256, "height": 256 },
            "layers": [{ "image": "logo.png", "at": seam_point.to_array(), "size": [0.2, 0.2] }],
            "output": { "texture": texture, "preview": "blended.png" } })
        .to_string()
    };
    std::fs::write(dir.join("both.json"), job("baked_uv{uv}.png")).unwrap();
    let (code, _, err) = common::cli(&["bake", dir.join("both.json").to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    for set in [1, 2] {
        let img = image::open(dir.join(format!("baked_uv{set}.png"))).unwrap();
        assert_eq!(img.width(), 256);
        let r: serde_json::Value = serde_json::from_slice(
            &std::fs::read(dir.join(format!("report-uv{set}.json"))).unwrap(),
        )
        .unwrap();
        assert_eq!(r["uv_set"], set);
        assert!(r["layers"][0]["texels_covered"].as_u64().unwrap() > 0);
    }
    let blended = image::open(dir.join("blended.png")).unwrap();
    assert_eq!(blended.width(), 1024);
    // No colour jump across the cut in the blended rendering: at the midpoint of every seam edge,
    // b0 · pelt + (1 − b0) · patch is the same from both of its triangles (b0 = 0 on the seam, the
    // patch's UVs are continuous there), while the pelt alone jumps where the decal crosses.
    let tex = |set: u32| {
        decalbake::io::image::LinearImage::load(&dir.join(format!("baked_uv{set}.png"))).unwrap()
    };
    let (t1, t2) = (tex(1), tex(2));
    // Per welded edge, from each of its triangles: (blended colour, pelt colour).
    type Sides = Vec<([f32; 4], [f32; 4])>;
    let mut by_edge: HashMap<(u32, u32), Sides> = HashMap::new();
    for t in &m.triangles {
        for k in 0..3 {
            let (a, b) = (t[k] as usize, t[(k + 1) % 3] as usize);
            let (wa, wb) = (topo.welded_of[a], topo.welded_of[b]);
            let mid = |set: usize| 0.5 * (m.uv_sets[set][a] + m.uv_sets[set][b]);
            let w = 0.5 * (b0[a] + b0[b]);
            let (p1, p2) = (mid(1), mid(2));
            let c1 = t1.bilinear(p1.x, p1.y, false);
            let c2 = t2.bilinear(p2.x, p2.y, false);
            let mixed = std::array::from_fn(|i| w * c1[i] + (1.0 - w) * c2[i]);
            by_edge
                .entry((wa.min(wb), wa.max(wb)))
                .or_default()
                .push((mixed, c1));
        }
    }
    let (mut blended_jump, mut pelt_jump) = (0f32, 0f32);
    for sides in by_edge.values().filter(|l| l.len() == 2) {
        let d = |x: [f32; 4], y: [f32; 4]| (0..3).map(|i| (x[i] - y[i]).abs()).fold(0f32, f32::max);
        blended_jump = blended_jump.max(d(sides[0].0, sides[1].0));
        pelt_jump = pelt_jump.max(d(sides[0].1, sides[1].1));
    }
    assert!(
        blended_jump < 1e-3,
        "blended rendering jumps by {blended_jump} across an edge"
    );
    assert!(
        pelt_jump > 0.1,
        "the pelt alone should show its seam: {pelt_jump}"
    );
    // The same job through `decalbake batch`: the same files, and a resumed run skips it.
    std::fs::write(dir.join("jobs.jsonl"), "\"both.json\"\n").unwrap();
    let batch = |extra: &[&str]| {
        let manifest = dir.join("jobs.jsonl");
        let summary = dir.join("summary.json");
        let mut args = vec![
            "batch",
            manifest.to_str().unwrap(),
            "--summary",
            summary.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let (code, _, err) = common::cli(&args);
        assert_eq!(code, 0, "{err}");
        let s: serde_json::Value =
            serde_json::from_slice(&std::fs::read(&summary).unwrap()).unwrap();
        s["jobs"][0]["status"].as_str().unwrap().to_string()
    };
    std::fs::remove_file(dir.join("blended.png")).unwrap();
    assert_eq!(batch(&[]), "ok");
    assert!(dir.join("blended.png").exists() && dir.join("baked_uv2.png").exists());
    assert_eq!(batch(&["--resume"]), "skipped");
    std::fs::write(dir.join("clash.json"), job("baked.png")).unwrap();
    let (code, _, err) = common::cli(&["bake", dir.join("clash.json").to_str().unwrap()]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("output.texture") && err.contains("{uv}"),
        "{err}"
    );
}

/// UV triangles (v down) that are flipped or degenerate, and pairs that overlap without sharing a
/// corner.
fn flipped_and_overlapping(shown: &[[DVec2; 3]]) -> (usize, usize) {
    let flipped = shown
        .iter()
        .filter(|q| (q[1] - q[0]).perp_dot(q[2] - q[0]) >= 0.0)
        .count();
    let overlapping = (0..shown.len())
        .flat_map(|i| (i + 1..shown.len()).map(move |j| (i, j)))
        .filter(|&(i, j)| {
            let share = shown[i].iter().any(|p| shown[j].contains(p));
            !share && overlap(&shown[i], &shown[j])
        })
        .count();
    (flipped, overlapping)
}

/// The welded edges (smaller id first) whose two triangles give them different UVs in `set`.
fn seam_edges(m: &Mesh, topo: &Topology, set: usize) -> HashSet<(u32, u32)> {
    let mut sides: HashMap<(u32, u32), Vec<[u32; 4]>> = HashMap::new();
    for t in &m.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            let (wa, wb) = (topo.welded_of[a as usize], topo.welded_of[b as usize]);
            let (ua, ub) = (m.uv_sets[set][a as usize], m.uv_sets[set][b as usize]);
            let (key, uv) = if wa < wb {
                ((wa, wb), [ua.x, ua.y, ub.x, ub.y])
            } else {
                ((wb, wa), [ub.x, ub.y, ua.x, ua.y])
            };
            sides.entry(key).or_default().push(uv.map(f32::to_bits));
        }
    }
    sides
        .into_iter()
        .filter(|(_, l)| l.iter().any(|u| *u != l[0]))
        .map(|(e, _)| e)
        .collect()
}

/// `--patch` on bob, whose seams have cycles (a handle: the pelt's cut is two loops): the patch
/// is cut across the band once per cycle and the bridges (TEXCOORD_3, `_PELT_BRIDGE`) hide those
/// arcs (`pelt::bridge`). Checked from the written file alone: the three weights are a partition
/// of unity; every chart's weight is 0 on each triangle that touches one of its seams (an edge
/// whose two triangles give it different UVs in its set), so no seam can show; each chart is
/// unflipped and overlaps itself nowhere it is shown. Then a decal baked into the three sets over
/// both places where an arc crosses the pelt's seam: the blended colour has no jump across any
/// edge, while the pelt alone, and the pelt and patch blended without the bridges (the §5
/// rendering, b0 = 0 within 2 edges of the pelt's seam and 1 beyond), both jump there.
#[test]
fn patch_with_bridges_hides_the_seams_of_a_handle() {
    let dir = common::scratch("patch-bridges");
    let out = dir.join("bob.glb");
    let (code, _, err) = common::cli(&[
        "unwrap",
        asset("bob.glb").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--patch",
        "--cpu",
    ]);
    assert_eq!(code, 0, "{err}");
    validate(&out);
    let m = Mesh::load(&out).unwrap();
    assert_eq!(
        m.uv_sets.len(),
        4,
        "bob's own set, the pelt, the patch, the bridges"
    );
    let (w1, w3) = (
        glb_attribute(&out, "_PELT_BLEND"),
        glb_attribute(&out, "_PELT_BRIDGE"),
    );
    let weights = |v: usize| [w1[v], 1.0 - w1[v] - w3[v], w3[v]];
    for v in 0..m.positions.len() {
        for w in weights(v) {
            assert!(
                (0.0..=1.0).contains(&w),
                "vertex {v}: weights {:?}",
                weights(v)
            );
        }
    }
    let topo = Topology::build(&m, DEFAULT_WELD_TOLERANCE);
    for (chart, set) in [(0, 1), (1, 2), (2, 3)] {
        let seams = seam_edges(&m, &topo, set);
        assert!(seams.len() > 10, "set {set}: {} seam edges", seams.len());
        let mut shown = Vec::new();
        for t in &m.triangles {
            let touches = (0..3).any(|k| {
                let (a, b) = (
                    topo.welded_of[t[k] as usize],
                    topo.welded_of[t[(k + 1) % 3] as usize],
                );
                seams.contains(&(a.min(b), a.max(b)))
            });
            let w = t.map(|v| weights(v as usize)[chart]);
            if touches {
                assert_eq!(w, [0.0; 3], "set {set}: a triangle on its seam is shown");
            }
            if w.iter().any(|&x| x > 0.0) {
                shown.push(t.map(|v| m.uv_sets[set][v as usize].as_dvec2()));
            }
        }
        assert_eq!(flipped_and_overlapping(&shown), (0, 0), "set {set}");
    }

    // The arcs cross the pelt's seam where a seam vertex has bridge weight 1: one decal on the
    // first such vertex and one on the farthest from it (bob's two loops).
    let on_seam: HashSet<u32> = seam_edges(&m, &topo, 1)
        .into_iter()
        .flat_map(|(a, b)| [a, b])
        .collect();
    // §5's b0 alone (0 within 2 edges of the pelt's seam, 1 beyond), for the rendering without
    // bridges.
    let seam_list: Vec<u32> = on_seam.iter().copied().collect();
    let d = pelt::patch::rings(&topo, &seam_list, 10);
    let b0 = |v: usize| {
        if d[topo.welded_of[v] as usize] <= 2 {
            0.0
        } else {
            1.0
        }
    };
    let crossing: Vec<Vec3> = (0..m.positions.len())
        .filter(|&v| w3[v] == 1.0 && on_seam.contains(&topo.welded_of[v]))
        .map(|v| m.positions[v])
        .collect();
    assert!(!crossing.is_empty());
    let far = crossing
        .iter()
        .copied()
        .max_by(|a, b| a.distance(crossing[0]).total_cmp(&b.distance(crossing[0])))
        .unwrap();
    std::fs::write(
        dir.join("logo.png"),
        common::test_image(32, 32, 5, false).encode_png(8),
    )
    .unwrap();
    let layer = |p: Vec3| serde_json::json!({ "image": "logo.png", "at": p.to_array(), "size": [0.25, 0.25] });
    let job = serde_json::json!({ "mesh": "bob.glb", "uv_set": [1, 2, 3],
        "texture": { "width": 512, "height": 512 },
        "layers": [layer(crossing[0]), layer(far)],
        "output": { "texture": "baked_uv{uv}.png", "preview": "blended.png" } });
    std::fs::write(dir.join("job.json"), job.to_string()).unwrap();
    let (code, _, err) = common::cli(&["bake", dir.join("job.json").to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(image::open(dir.join("blended.png")).unwrap().width(), 1024);
    let tex: Vec<_> = (1..=3)
        .map(|set| {
            decalbake::io::image::LinearImage::load(&dir.join(format!("baked_uv{set}.png")))
                .unwrap()
        })
        .collect();
    // Per welded edge, from each of its triangles: the three-chart blend, the pelt alone, and the
    // pelt and patch blended without the bridges.
    let mut by_edge: HashMap<(u32, u32), Vec<[[f32; 4]; 3]>> = HashMap::new();
    for t in &m.triangles {
        for k in 0..3 {
            let (a, b) = (t[k] as usize, t[(k + 1) % 3] as usize);
            let (wa, wb) = (topo.welded_of[a], topo.welded_of[b]);
            let c: Vec<[f32; 4]> = (0..3)
                .map(|i| {
                    let p = 0.5 * (m.uv_sets[i + 1][a] + m.uv_sets[i + 1][b]);
                    tex[i].bilinear(p.x, p.y, false)
                })
                .collect();
            let w: Vec<f32> = (0..3)
                .map(|i| 0.5 * (weights(a)[i] + weights(b)[i]))
                .collect();
            let mix = |w: [f32; 3]| std::array::from_fn(|ch| (0..3).map(|i| w[i] * c[i][ch]).sum());
            let blended = mix([w[0], w[1], w[2]]);
            let b0 = 0.5 * (b0(a) + b0(b));
            let no_bridges = mix([b0, 1.0 - b0, 0.0]);
            by_edge
                .entry((wa.min(wb), wa.max(wb)))
                .or_default()
                .push([blended, c[0], no_bridges]);
        }
    }
    let mut jump = [0f32; 3];
    for sides in by_edge.values().filter(|l| l.len() == 2) {
        for (i, j) in jump.iter_mut().enumerate() {
            let d = (0..3)
                .map(|ch| (sides[0][i][ch] - sides[1][i][ch]).abs())
                .fold(0f32, f32::max);
            *j = j.max(d);
        }
    }
    println!(
        "largest jump across an edge: blended {}, pelt alone {}, without bridges {}",
        jump[0], jump[1], jump[2]
    );
    assert!(jump[0] < 1e-3, "the blended rendering jumps by {}", jump[0]);
    assert!(
        jump[1] > 0.1,
        "the pelt alone should show its seam: {}",
        jump[1]
    );
    assert!(
        jump[2] > 0.1,
        "without the bridges the patch's arcs should show: {}",
        jump[2]
    );
}

/// A flat n × n grid of unit squares in the plane z = 0 (one disk).
fn grid(n: u32) -> Mesh {
    grid_wh(n, n)
}

/// A flat w × h grid of unit squares in the plane z = 0, each cut by its (1, 1) diagonal.
fn grid_wh(w: u32, h: u32) -> Mesh {
    let mut pos = Vec::new();
    let mut tris = Vec::new();
    for j in 0..=h {
        for i in 0..=w {
            pos.push(Vec3::new(i as f32, j as f32, 0.0));
        }
    }
    for j in 0..h {
        for i in 0..w {
            let a = j * (w + 1) + i;
            let (b, c, d) = (a + 1, a + w + 1, a + w + 2);
            tris.push([a, b, d]);
            tris.push([a, d, c]);
        }
    }
    Mesh {
        source: "grid".into(),
        normals: vec![Vec3::Z; pos.len()],
        uv_sets: Vec::new(),
        positions: pos,
        triangles: tris,
        primitives: vec![],
        material: None,
        blend: Vec::new(),
        bridge: Vec::new(),
        ..Default::default()
    }
}

/// A split seeded at an overlapping pair of triangles next to each other in a corner would cut a
/// sliver off (the two seeds' Voronoi border runs between them, one column from the edge) and
/// leave the rest to be pelted whole again; the split falls back to the diameter's ends instead,
/// and each side keeps at least `MIN_SHARE` of the triangles. Seeded far apart, the overlap's
/// seeds are kept (the two sides then hold the two seeds).
#[test]
fn an_uneven_split_at_an_overlap_falls_back_to_halves() {
    let mesh = grid(12);
    let topo = Topology::build(&mesh, DEFAULT_WELD_TOLERANCE);
    let cut = pelt::cut::cut(&mesh, &topo, &CutSpec::Auto, Path::new("grid")).unwrap();
    assert_eq!(cut.pieces.len(), 1);
    let p = &cut.pieces[0];
    let n = p.triangles.len();
    // The piece-local triangle whose first corner is the welded vertex at (x, y).
    let at = |x: f32, y: f32| {
        (0..n as u32)
            .find(|&t| {
                let w = p.welded[p.triangles[t as usize][0] as usize];
                topo.positions[w as usize].distance(Vec3::new(x, y, 0.0)) < 1e-4
            })
            .unwrap()
    };
    let share = |parts: &[Vec<u32>; 2]| parts[0].len().min(parts[1].len()) as f64 / n as f64;
    let near = pelt::split::halves(&topo, p, Some((at(0.0, 5.0), at(1.0, 5.0)))).unwrap();
    assert!(share(&near) >= pelt::split::MIN_SHARE, "{}", share(&near));
    let far = pelt::split::halves(&topo, p, Some((at(0.0, 0.0), at(11.0, 11.0)))).unwrap();
    assert!(share(&far) > 0.3, "{}", share(&far));
}

/// A mesh of the given parts (positions, triangles), without UVs.
fn parts(list: &[(Vec<Vec3>, Vec<[u32; 3]>)]) -> Mesh {
    let (mut positions, mut triangles) = (Vec::new(), Vec::new());
    for (p, t) in list {
        let base = positions.len() as u32;
        positions.extend_from_slice(p);
        triangles.extend(t.iter().map(|t| t.map(|v| v + base)));
    }
    Mesh {
        source: "parts".into(),
        normals: vec![Vec3::ZERO; positions.len()],
        uv_sets: Vec::new(),
        positions,
        triangles,
        primitives: vec![],
        material: None,
        blend: Vec::new(),
        bridge: Vec::new(),
        ..Default::default()
    }
}

/// The welded vertices on the automatic cut's opened edges.
fn cut_vertices(mesh: &Mesh) -> Vec<Vec3> {
    let topo = Topology::build(mesh, DEFAULT_WELD_TOLERANCE);
    let cut = pelt::cut::cut(mesh, &topo, &CutSpec::Auto, Path::new("parts")).unwrap();
    cut.edges
        .iter()
        .flatten()
        .map(|&v| topo.positions[v as usize])
        .collect()
}

/// The automatic cut runs where a seam shows least (`pelt::hidden`). An open tube needs one cut
/// from rim to rim, and every straight one is as short as the others: with a wall standing next
/// to one side, the cut runs along the side the wall hides, and follows the wall when it moves to
/// the other side (so no fixed choice passes both). A square tube is cut along one of its corners,
/// not across a flat face. Without the costs (every edge its length: the broken variant) the
/// cut stays where the search happens to meet the rim first and fails at least one of these.
#[test]
fn automatic_cut_runs_through_hidden_and_creased_parts() {
    let tube = common::cylinder(24, 6);
    let tube = (tube.positions, tube.triangles);
    for side in [1.0f32, -1.0] {
        let wall = grid(8);
        let wall_pos = wall
            .positions
            .iter()
            .map(|p| Vec3::new(1.4 * side, p.x * 0.75 - 3.0, p.y * 0.5 - 2.0))
            .collect();
        let mesh = parts(&[tube.clone(), (wall_pos, wall.triangles)]);
        let on_tube: Vec<Vec3> = cut_vertices(&mesh)
            .into_iter()
            .filter(|p| (p.x * p.x + p.y * p.y - 1.0).abs() < 1e-3)
            .collect();
        assert!(!on_tube.is_empty());
        for p in &on_tube {
            assert!(
                p.x * side > 0.9,
                "wall at x = {}: cut vertex {p}",
                1.4 * side
            );
        }
    }
    // A square tube of side 2, each face 6 × 6 quads.
    let (n, m) = (24u32, 6u32);
    let mut pos = Vec::new();
    for j in 0..=m {
        for i in 0..n {
            // Numbered from the middle of a face, where the search starts.
            let k = (i + 3) % n;
            let (f, t) = (k / 6, (k % 6) as f32 / 6.0 * 2.0 - 1.0);
            let [x, y] = match f {
                0 => [1.0, t],
                1 => [-t, 1.0],
                2 => [-1.0, -t],
                _ => [t, -1.0],
            };
            pos.push(Vec3::new(x, y, -1.0 + 2.0 * j as f32 / m as f32));
        }
    }
    let mut tris = Vec::new();
    for j in 0..m {
        for i in 0..n {
            let (a, b) = (j * n + i, j * n + (i + 1) % n);
            tris.extend([[a, b, b + n], [a, b + n, a + n]]);
        }
    }
    let cut = cut_vertices(&parts(&[(pos, tris)]));
    assert!(!cut.is_empty());
    for p in &cut {
        assert!(
            (p.x.abs() - 1.0).abs() < 1e-4 && (p.y.abs() - 1.0).abs() < 1e-4,
            "cut vertex {p} is not on a corner"
        );
    }
}

/// The shape packing (`pelt::pack::pack_shapes`) nests pelts in each other's bays and keeps the
/// margin: eight right-angled triangles (half a unit square each; two make a square when one is
/// turned half round) packed into 256² texels with a 2-texel margin come out larger than the box
/// packing can make them (a square each), every point in [0, 1]², and no two pelts closer than
/// twice the margin (each has the margin round it): the closest distance is between a vertex of
/// one and an edge of the other, measured exactly.
#[test]
fn shape_packing_nests_pelts_and_keeps_the_margin() {
    let points = vec![DVec2::ZERO, DVec2::X, DVec2::Y];
    let triangles = vec![[0u32, 1, 2]];
    let shape = pelt::pack::Shape {
        points: &points,
        triangles: &triangles,
    };
    let (size, margin) = (256u32, 2u32);
    let density = [1.0; 8];
    let placed = pelt::pack::pack_shapes(&[shape; 8], &density, size, margin);
    let boxes = [(DVec2::ZERO, DVec2::ONE); 8];
    let by_box = pelt::pack::pack(&boxes, &density, size, margin);
    assert!(
        placed.scale[0] > 1.1 * by_box.scale[0],
        "{} against {}",
        placed.scale[0],
        by_box.scale[0]
    );
    let laid: Vec<Vec<DVec2>> = (0..8)
        .map(|i| {
            points
                .iter()
                .map(|&p| placed.uv(i, p) * size as f64)
                .collect()
        })
        .collect();
    for q in laid.iter().flatten() {
        assert!(
            q.min_element() >= 0.0 && q.max_element() <= size as f64,
            "{q}"
        );
    }
    let seg = |p: DVec2, a: DVec2, b: DVec2| {
        let t = ((p - a).dot(b - a) / (b - a).length_squared()).clamp(0.0, 1.0);
        (a + (b - a) * t).distance(p)
    };
    let gap = |a: &[DVec2], b: &[DVec2]| {
        let mut d = f64::MAX;
        for t in &triangles {
            for k in 0..3 {
                let (u, v) = (t[k] as usize, t[(k + 1) % 3] as usize);
                for p in a {
                    d = d.min(seg(*p, b[u], b[v]));
                }
            }
        }
        d
    };
    for i in 0..8 {
        for j in 0..8 {
            if i != j {
                let d = gap(&laid[i], &laid[j]);
                assert!(
                    d >= 2.0 * margin as f64 - 1e-9,
                    "pelts {i} and {j} are {d} texels apart"
                );
            }
        }
    }
}

/// A split's border is the shortest edge path between its ends (`pelt::split::BAND`), not the
/// geodesic Voronoi staircase: a 24 × 8 strip split at the ends of its longest path is cut across
/// by a border no longer than the shortest path along the edges between its two ends on the rim
/// (the Voronoi border alone, the broken variant, zigzags and is longer).
#[test]
fn split_border_runs_straight() {
    let mesh = grid_wh(24, 8);
    let topo = Topology::build(&mesh, DEFAULT_WELD_TOLERANCE);
    let cut = pelt::cut::cut(&mesh, &topo, &CutSpec::Auto, Path::new("strip")).unwrap();
    let parts = pelt::split::halves(&topo, &cut.pieces[0], None).unwrap();
    let mut part_of = vec![0; topo.triangles.len()];
    for t in &parts[1] {
        part_of[*t as usize] = 1;
    }
    let mut by_edge: HashMap<(u32, u32), Vec<usize>> = HashMap::new();
    for (t, tri) in topo.triangles.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            by_edge.entry((a.min(b), a.max(b))).or_default().push(t);
        }
    }
    let border: Vec<(u32, u32)> = by_edge
        .iter()
        .filter(|(_, t)| t.len() == 2 && part_of[t[0]] != part_of[t[1]])
        .map(|(e, _)| *e)
        .collect();
    let mut degree: HashMap<u32, u32> = HashMap::new();
    for &(a, b) in &border {
        *degree.entry(a).or_default() += 1;
        *degree.entry(b).or_default() += 1;
    }
    let ends: Vec<u32> = degree
        .iter()
        .filter(|(_, d)| **d == 1)
        .map(|(v, _)| *v)
        .collect();
    assert_eq!(ends.len(), 2, "{border:?}");
    let dist = |a: u32, b: u32| topo.positions[a as usize].distance(topo.positions[b as usize]);
    let length: f32 = border.iter().map(|&(a, b)| dist(a, b)).sum();
    // The shortest path along the edges between the two ends (Bellman-Ford: the mesh is small).
    let mut d = vec![f32::INFINITY; topo.positions.len()];
    d[ends[0] as usize] = 0.0;
    for _ in 0..topo.positions.len() {
        let mut changed = false;
        for &(a, b) in by_edge.keys() {
            for (u, v) in [(a, b), (b, a)] {
                let nd = d[u as usize] + dist(u, v);
                if nd < d[v as usize] - 1e-6 {
                    d[v as usize] = nd;
                    changed = true;
                }
            }
        }
        if !changed {
            break;
        }
    }
    let shortest = d[ends[1] as usize];
    assert!(
        length <= shortest + 1e-4,
        "border {length} against {shortest}"
    );
}

/// The engine hands a finished bake's canvas to the next bake of the same size
/// (`bake::engine::BufferPool`); a transferred base leaves the texels no triangle covers as they
/// start, so it must start from a cleared canvas, not the last bake's: a transfer baked right after
/// a solid red bake equals the same transfer on a fresh engine, byte for byte (without the clear,
/// every background texel of the second is the first's red).
#[test]
fn a_transfer_after_another_bake_starts_from_a_clear_canvas() {
    let dir = common::scratch("transfer_pool");
    let spot = Mesh::load(&asset("spot.glb")).unwrap();
    let material = serde_json::json!({"transfer": {"from_uv_set": 0}});
    let fresh = {
        let engine = common::engine();
        let loaded = engine.prepare(spot.clone()).unwrap();
        transfer_bake(&engine, &loaded, &dir, material.clone(), 0, 64)
    };
    let engine = common::engine();
    let loaded = engine.prepare(spot).unwrap();
    let red = serde_json::json!([1.0, 0.0, 0.0, 1.0]);
    let first = transfer_bake(&engine, &loaded, &dir, red, 0, 64);
    assert_eq!(&first.texels[..4], &[255, 0, 0, 255]);
    let after = transfer_bake(&engine, &loaded, &dir, material, 0, 64);
    let background = fresh.texels.chunks(4).filter(|t| t[3] == 0).count();
    assert!(background > 100, "{background} transparent texels");
    assert!(
        fresh.texels == after.texels,
        "the second bake kept the first's texels"
    );
}

/// A thin open tube (8 edges round) pelted without splits: the band within 4 edges of its
/// rim-to-rim seam wraps the whole tube, an annulus between the two rims, so the patch is opened
/// by one arc from rim to rim away from the seam (one, not one from each rim: `patch::open_band`
/// stops as soon as the band is disks) and that arc is bridged. Every weight lies in [0, 1] and
/// they add to 1; the pelt's is 0 on the triangles touching its seam, the patch's on those
/// touching the arc, and each chart's outside its own layout.
#[test]
fn patch_of_a_thin_tube_is_opened_rim_to_rim() {
    let mesh = common::cylinder(8, 12);
    let topo = Topology::build(&mesh, DEFAULT_WELD_TOLERANCE);
    let opts = Options {
        max_split_levels: 0,
        ..Options::default()
    };
    let path = Path::new("tube");
    let un = pelt::unwrap(Device::Cpu, &mesh, &topo, &opts, path).unwrap();
    let p = pelt::patch::patch(Device::Cpu, &topo, &un, &opts, path).unwrap();
    let b = p
        .bridges
        .as_ref()
        .expect("an annulus needs an arc and bridges");
    let z = |v: u32| topo.positions[v as usize].z;
    let seam: HashSet<u32> = un.cut.edges.iter().flatten().copied().collect();
    let arc: HashSet<u32> = b.arcs.iter().flatten().copied().collect();
    assert_eq!(b.arcs.len(), arc.len() - 1, "one simple path: {:?}", b.arcs);
    let (lo, hi) = arc.iter().fold((f32::MAX, f32::MIN), |(l, h), &v| {
        (l.min(z(v)), h.max(z(v)))
    });
    assert!(lo < -0.99 && hi > 0.99, "the arc spans z {lo} .. {hi}");
    assert!(arc.is_disjoint(&seam), "the arc runs on the seam");
    let pelt_w = |v: u32| p.blend[v as usize];
    let bridge_w = |v: u32| b.weight[v as usize];
    let patch_w = |v: u32| 1.0 - pelt_w(v) - bridge_w(v);
    for v in 0..topo.positions.len() as u32 {
        for w in [pelt_w(v), patch_w(v), bridge_w(v)] {
            assert!((0.0..=1.0).contains(&w), "vertex {v}");
        }
    }
    let touches = |t: [u32; 3], edges: &[[u32; 2]]| {
        (0..3).any(|k| {
            let (a, c) = (t[k], t[(k + 1) % 3]);
            edges.contains(&[a.min(c), a.max(c)])
        })
    };
    for (i, &t) in topo.triangles.iter().enumerate() {
        let all_zero = |f: &dyn Fn(u32) -> f32| t.iter().all(|&v| f(v) == 0.0);
        if touches(t, &un.cut.edges) {
            assert!(all_zero(&pelt_w), "triangle {i} shows the pelt at its seam");
        }
        if touches(t, &b.arcs) || p.layout.cut.triangle_piece[i].is_none() {
            assert!(
                all_zero(&patch_w),
                "triangle {i} shows the patch at its edge"
            );
        }
        if b.layout.cut.triangle_piece[i].is_none() {
            assert!(
                all_zero(&bridge_w),
                "triangle {i} shows the bridges outside them"
            );
        }
    }
}

/// `mesh` as one piece of a cut (its welded surface uncut), for [`pelt::cut::disk_charts`].
fn whole_piece(mesh: &Mesh) -> (Topology, pelt::cut::Piece) {
    let topo = Topology::build(mesh, DEFAULT_WELD_TOLERANCE);
    let piece = pelt::cut::Piece {
        welded: (0..topo.positions.len() as u32).collect(),
        triangles: topo.triangles.clone(),
        source: (0..topo.triangles.len() as u32).collect(),
        boundary: Vec::new(),
    };
    (topo, piece)
}

/// A closed cube of side 1 at `at` (its lowest corner), eight vertices and twelve triangles
/// wound outwards, appended to `pos` and `tris`.
fn push_cube(pos: &mut Vec<Vec3>, tris: &mut Vec<[u32; 3]>, at: Vec3) {
    let base = pos.len() as u32;
    for k in 0..8u32 {
        pos.push(at + Vec3::new((k & 1) as f32, (k >> 1 & 1) as f32, (k >> 2 & 1) as f32));
    }
    // Faces as corner quads (a, b, c, d) counter-clockwise seen from outside.
    for q in [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ] {
        let [a, b, c, d] = q.map(|v| base + v);
        tris.push([a, b, c]);
        tris.push([a, c, d]);
    }
}

fn mesh_of(pos: Vec<Vec3>, tris: Vec<[u32; 3]>) -> Mesh {
    Mesh {
        source: "made".into(),
        normals: vec![Vec3::ZERO; pos.len()],
        positions: pos,
        triangles: tris,
        ..Default::default()
    }
}

/// Pieces that are not disks are cut into disks grown triangle by triangle
/// (`pelt::cut::disk_charts`): an annulus (two boundary loops), a closed cube, and bob (closed,
/// genus 1), each taken whole as one piece, are all disks once cut along the edges it returns
/// (`CutSpec::Edges` refuses a piece that is not). It fails with a chart allowed to take a
/// triangle that shares one edge and no new vertex (the chart then closes round the hole, the
/// handle or the surface: checked). And where the automatic cut leaves a piece that is not a
/// disk (a part of a real model whose winding flips across an edge), it cuts that piece further
/// instead of refusing the model (refused before: checked), and the unwrap completes.
#[test]
fn pieces_that_are_not_disks_are_cut_into_disks() {
    let mut annulus = grid_wh(3, 3);
    // The middle square's two triangles out: a hole.
    annulus.triangles.drain(8..10);
    let (mut pos, mut tris) = (Vec::new(), Vec::new());
    push_cube(&mut pos, &mut tris, Vec3::ZERO);
    let cube = mesh_of(pos, tris);
    let bob = Mesh::load(&asset("bob.glb")).unwrap();
    for (name, mesh) in [("annulus", &annulus), ("cube", &cube), ("bob", &bob)] {
        let (topo, piece) = whole_piece(mesh);
        let edges = pelt::cut::disk_charts(&piece);
        assert!(!edges.is_empty(), "{name}: not a disk, so something is cut");
        let cut = pelt::cut::cut(mesh, &topo, &CutSpec::Edges(edges), Path::new(name))
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        // One chart never holds a surface that is not a disk.
        assert!(cut.pieces.len() >= 2, "{name}: {} pieces", cut.pieces.len());
    }
    // The connectivity of what the automatic cut left uncut in a real model (a rat's ear, once
    // its non-manifold edges were opened; the positions are made up): nine triangles, two of
    // which meet wound against each other (both hold the edge 3 -> 4), so the boundary walk
    // finds three loops.
    let ear = mesh_of(
        (0..10)
            .map(|k| {
                let a = k as f32 * 0.628;
                Vec3::new(a.cos(), a.sin(), 0.1 * (k % 3) as f32)
            })
            .collect(),
        vec![
            [0, 1, 2],
            [2, 1, 3],
            [2, 3, 4],
            [5, 6, 7],
            [5, 7, 8],
            [9, 6, 5],
            [4, 7, 6],
            [9, 3, 4],
            [9, 4, 6],
        ],
    );
    let topo = Topology::build(&ear, DEFAULT_WELD_TOLERANCE);
    let cut = pelt::cut::cut(&ear, &topo, &CutSpec::Auto, Path::new("ear")).unwrap();
    assert!(
        cut.regrown > 0,
        "the tree-cotree cut alone leaves a piece that is not a disk"
    );
    let un = pelt::unwrap(
        Device::Cpu,
        &ear,
        &topo,
        &Options::default(),
        Path::new("ear"),
    )
    .unwrap();
    assert!(un.cut.pieces.len() >= 2, "{} pieces", un.cut.pieces.len());
    assert_eq!(un.report.regrown, cut.regrown, "the report says so");
}
