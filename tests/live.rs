// SPDX-License-Identifier: MIT OR Apache-2.0
//! Live bakes (`Engine::live`, `bake/live.rs`): after every edit of random sequences of moves,
//! turns, resizes, re-weightings, additions, removals and re-orderings, the live texture's bytes
//! equal a full bake of the edited job; an edit re-computes one map and re-composes only the
//! cells it touched (decals by every method, ribbons and text layers); jobs a live bake cannot
//! take, and bad edits, are refused with the bake left as it was.

mod common;
use common::*;
use decalbake::io::at::{AtSpec, RaySpec};
use decalbake::io::job::{BlendMode, Method};
use decalbake::{Edit, Engine, Error, Job};
use std::path::Path;

/// A ray aimed at Spot's body from angle `t` round it, at height `y`.
fn ray(t: f32, y: f32) -> AtSpec {
    let origin = [2.0 * t.cos(), y, 0.2 + 2.0 * t.sin()];
    AtSpec::Ray {
        ray: RaySpec {
            origin,
            dir: [-origin[0], 0.0, 0.2 - origin[2]],
        },
    }
}

/// `n` decals round Spot by every method, at `side`², with `texture` fields added.
fn job(dir: &Path, side: u32, n: usize, texture: serde_json::Value) -> Job {
    let methods = ["planar", "expmap", "lscm", "hybrid"];
    let layers: Vec<_> = (0..n)
        .map(|i| {
            let t = i as f32 * 0.9;
            let origin = [2.0 * t.cos(), 0.15, 0.2 + 2.0 * t.sin()];
            serde_json::json!({ "image": "img.png", "method": methods[i % 4], "size": [0.3, 0.25],
                "angle": 20.0 * i as f32,
                "at": { "ray": { "origin": origin, "dir": [-origin[0], 0.0, 0.2 - origin[2]] } } })
        })
        .collect();
    let mut text = spot_job_json(dir, 7, serde_json::json!(layers), serde_json::json!({}));
    text["texture"] = serde_json::json!({ "width": side, "height": side });
    if let serde_json::Value::Object(m) = texture {
        for (k, v) in m {
            text["texture"][k] = v;
        }
    }
    Job::parse(&text.to_string(), &dir.join("job.json"), dir, dir).unwrap()
}

/// A small xorshift generator: the same edits on every run.
struct Rng(u32);
impl Rng {
    fn next(&mut self) -> u32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 17;
        self.0 ^= self.0 << 5;
        self.0
    }
    fn unit(&mut self) -> f32 {
        (self.next() % 10_000) as f32 / 10_000.0
    }
    fn below(&mut self, n: usize) -> usize {
        self.next() as usize % n
    }
}

/// One random edit of `job`'s layers, and its name.
fn random_edit(rng: &mut Rng, job: &Job) -> (Edit, &'static str) {
    let n = job.layers.len();
    let i = rng.below(n);
    let mut l = job.layers[i].clone();
    match rng.below(8) {
        0 | 1 => {
            l.at = ray(rng.unit() * std::f32::consts::TAU, 0.05 + 0.2 * rng.unit());
            (
                Edit::Set {
                    layer: i,
                    to: Box::new(l),
                },
                "move",
            )
        }
        2 => {
            l.angle = rng.unit() * 360.0;
            (
                Edit::Set {
                    layer: i,
                    to: Box::new(l),
                },
                "turn",
            )
        }
        3 => {
            let s = 0.15 + 0.25 * rng.unit();
            l.size = [s, s * (0.7 + 0.5 * rng.unit())];
            (
                Edit::Set {
                    layer: i,
                    to: Box::new(l),
                },
                "resize",
            )
        }
        4 => {
            l.opacity = 0.3 + 0.7 * rng.unit();
            l.blend = [BlendMode::Normal, BlendMode::Multiply, BlendMode::Screen][rng.below(3)];
            (
                Edit::Set {
                    layer: i,
                    to: Box::new(l),
                },
                "re-weight",
            )
        }
        5 if n < 9 => {
            l.at = ray(rng.unit() * std::f32::consts::TAU, 0.1);
            l.method = [Method::Planar, Method::Expmap][rng.below(2)];
            let at = rng.below(n + 1);
            (
                Edit::Add {
                    at,
                    layer: Box::new(l),
                },
                "add",
            )
        }
        6 if n > 2 => (Edit::Remove { layer: i }, "remove"),
        _ => {
            let to = rng.below(n);
            (Edit::Reorder { from: i, to }, "reorder")
        }
    }
}

/// The texels of a full bake of `job`.
fn full(engine: &Engine, mesh: &decalbake::LoadedMesh, job: &Job) -> Vec<u16> {
    engine.bake(mesh, job).unwrap().texels
}

/// Values that differ between `a` and `b`, with the first few texels named.
fn differ(a: &[u16], b: &[u16], side: u32) -> usize {
    let bad: Vec<usize> = (0..a.len()).filter(|&k| a[k] != b[k]).collect();
    for &k in bad.iter().take(6) {
        let t = k / 4;
        println!(
            "  texel ({}, {}) ch {}: live {} full {}",
            t as u32 % side,
            t as u32 / side,
            k % 4,
            a[k],
            b[k]
        );
    }
    bad.len()
}

#[test]
fn fifty_random_edits_give_a_full_bakes_bytes() {
    let dir = scratch("live_random");
    let engine = engine();
    for (seed, side, texture) in [
        (11u32, 512, serde_json::json!({})),
        (23, 256, serde_json::json!({ "padding": 3, "samples": 9 })),
        // Adaptive supersampling: the live bake draws as the full bake does.
        (37, 256, serde_json::json!({ "sampling": "adaptive" })),
    ] {
        let job = job(&dir, side, 5, texture);
        let mesh = engine.load_mesh(&job.mesh).unwrap();
        let mut live = engine.live(&mesh, &job).unwrap();
        assert_eq!(live.read().unwrap(), &full(&engine, &mesh, &job)[..]);
        let mut rng = Rng(seed);
        let cells = (side / 64) * (side / 64);
        let mut partial = 0;
        for step in 0..50 {
            let (edit, what) = random_edit(&mut rng, live.job());
            let chart = match &edit {
                Edit::Set { layer, .. } => matches!(
                    live.job().layers[*layer].method,
                    Method::Lscm | Method::Hybrid
                ),
                _ => false,
            };
            let report = live.apply(edit.clone()).unwrap();
            // One map a changed layer (a chart's company only where its batch packs: 16 charts).
            match edit {
                Edit::Set { .. } | Edit::Add { .. } if !chart => assert_eq!(report.maps, 1),
                Edit::Remove { .. } | Edit::Reorder { .. } => assert_eq!(report.maps, 0),
                _ => {}
            }
            assert!(report.cells <= cells);
            partial += usize::from(report.cells < cells);
            let bytes = full(&engine, &mesh, live.job());
            let d = differ(live.read().unwrap(), &bytes, side);
            println!(
                "{side}² step {step}: {what}, {} layers, {} maps, {} of {cells} cells: {d} values differ",
                live.job().layers.len(),
                report.maps,
                report.cells
            );
            assert_eq!(d, 0, "{side}² after edit {step} ({what})");
        }
        assert!(
            partial > 25,
            "most edits re-compose part of the texture: {partial}"
        );
    }
}

#[test]
fn the_live_texture_holds_the_read_bytes() {
    let dir = scratch("live_texture");
    let engine = engine();
    let job = job(&dir, 256, 3, serde_json::json!({ "padding": "full" }));
    let mesh = engine.load_mesh(&job.mesh).unwrap();
    let mut live = engine.live(&mesh, &job).unwrap();
    let mut l = live.job().layers[1].clone();
    l.at = ray(2.5, 0.2);
    live.apply(Edit::Set {
        layer: 1,
        to: Box::new(l),
    })
    .unwrap();
    let bytes: Vec<u8> = live.read().unwrap().iter().map(|&v| v as u8).collect();
    let want = full(&engine, &mesh, live.job());
    assert_eq!(live.read().unwrap(), &want[..]);
    // The texture, copied back.
    let ctx = &engine.ctx;
    let buf = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size: 256 * 256 * 4,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    enc.copy_texture_to_buffer(
        live.texture().as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer: &buf,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(256 * 4),
                rows_per_image: Some(256),
            },
        },
        live.texture().size(),
    );
    ctx.queue.submit([enc.finish()]);
    let tex = ctx.read_buffer(&buf, 256 * 256 * 4, "test").unwrap();
    assert_eq!(tex, bytes);
}

#[test]
fn refused_jobs_and_edits_leave_the_bake_as_it_was() {
    let dir = scratch("live_refused");
    let engine = engine();
    let job = job(&dir, 256, 3, serde_json::json!({}));
    let mesh = engine.load_mesh(&job.mesh).unwrap();
    // A stroke: refused by name.
    let mut stroked = job.clone();
    let text = serde_json::json!({ "mesh": spot_asset(), "texture": { "width": 256, "height": 256 },
        "layers": [{ "kind": "stroke", "image": "img.png", "size": [0.1, 0.1],
            "path": [{ "ray": { "origin": [0.0, 1.5, 0.2], "dir": [0, -1, 0] } },
                     { "ray": { "origin": [0.2, 1.5, 0.3], "dir": [0, -1, 0] } }] }] });
    let s = Job::parse(&text.to_string(), &dir.join("job.json"), &dir, &dir).unwrap();
    stroked.layers.push(s.layers[0].clone());
    let e = engine
        .live(&mesh, &stroked)
        .err()
        .expect("a stroke is refused");
    assert!(
        matches!(&e, Error::Job { field, .. } if field == "layers[3].kind"),
        "{e}"
    );
    assert!(e.to_string().contains("live bake"), "{e}");

    let mut live = engine.live(&mesh, &job).unwrap();
    let before = live.read().unwrap().to_vec();
    // A layer that does not exist.
    let e = live.apply(Edit::Remove { layer: 3 }).unwrap_err();
    assert!(e.to_string().contains("layer 3 does not exist"), "{e}");
    // A decal moved off the mesh: its placement fails, naming it.
    let mut l = live.job().layers[2].clone();
    l.at = AtSpec::Ray {
        ray: RaySpec {
            origin: [0.0, 10.0, 0.0],
            dir: [0.0, 1.0, 0.0],
        },
    };
    let e = live
        .apply(Edit::Set {
            layer: 2,
            to: Box::new(l),
        })
        .unwrap_err();
    assert!(matches!(e, Error::Placement { layer: 2, .. }), "{e}");
    // A negative size.
    let mut l = live.job().layers[0].clone();
    l.size = [-0.1, 0.2];
    let e = live
        .apply(Edit::Set {
            layer: 0,
            to: Box::new(l),
        })
        .unwrap_err();
    assert!(
        matches!(&e, Error::Job { field, .. } if field == "layers[0].size"),
        "{e}"
    );
    assert_eq!(live.job().layers.len(), 3);
    assert_eq!(live.read().unwrap(), &before[..]);
    assert_eq!(before, full(&engine, &mesh, &job));
}

/// Seventeen small conformal decals solved on the GPU: on a CPU adapter their charts are solved
/// packed, a chart a lane, as one batch (16 or more). An edit of one re-solves them all in one batch, as the full
/// bake of the edited job does (the report's map count), and gives its bytes at 16 bits. Solved
/// alone, an edited chart would run the per-workgroup kernel, whose x differs from the packed
/// kernel's in the last bits (`tests/linalg.rs`, `packed_systems_match_one_workgroup_each`); on
/// this input the 16-bit bytes happened to agree either way (tried), so the company is checked
/// by the count.
#[test]
fn an_edited_chart_is_solved_with_its_batch() {
    let dir = scratch("live_charts");
    let mut engine = engine();
    // The GPU's solves (a CPU adapter's default is the twin, whose solves do not depend on
    // their batch).
    engine.stage_paths.charts = decalbake::StagePath::Gpu;
    let mut job = job(&dir, 256, 17, serde_json::json!({}));
    job.bit_depth = 16;
    for (i, l) in job.layers.iter_mut().enumerate() {
        l.method = if i % 2 == 0 {
            Method::Lscm
        } else {
            Method::Hybrid
        };
        l.size = [0.12, 0.1];
        l.at = ray(i as f32 * 0.37, 0.05 + 0.01 * i as f32);
    }
    let mesh = engine.load_mesh(&job.mesh).unwrap();
    let mut live = engine.live(&mesh, &job).unwrap();
    let mut l = live.job().layers[4].clone();
    l.at = ray(1.3, 0.22);
    l.angle = 75.0;
    let report = live
        .apply(Edit::Set {
            layer: 4,
            to: Box::new(l),
        })
        .unwrap();
    let want = full(&engine, &mesh, live.job());
    assert_eq!(differ(live.read().unwrap(), &want, 256), 0);
    let cpu = engine.ctx.device_type == Some(wgpu::DeviceType::Cpu);
    assert_eq!(report.maps, if cpu { 17 } else { 1 });
}

/// Ribbons and text layers (a text decal and a line of text along a curve) in a live bake:
/// decals moved across them, the ribbon re-weighted and raised to the top, the text moved and a
/// line removed give a full bake's bytes after every edit.
#[test]
fn ribbons_and_text_edit_live() {
    let dir = scratch("live_ribbon_text");
    let engine = engine();
    let back = |k: usize, n: usize| {
        let t = k as f32 / (n - 1) as f32;
        serde_json::json!({ "ray": { "origin": [-0.3 + 0.6 * t, 1.5, 0.25 + 0.05 * (6.0 * t).sin()],
            "dir": [0, -1, 0] } })
    };
    let path: Vec<_> = (0..9).map(|k| back(k, 9)).collect();
    let top =
        |x: f32, z: f32| serde_json::json!({ "ray": { "origin": [x, 1.5, z], "dir": [0, -1, 0] } });
    let layers = serde_json::json!([
        { "image": "img.png", "size": [0.2, 0.2], "at": top(0.3, 0.5) },
        { "kind": "ribbon", "image": "img.png", "path": path, "width": 0.08 },
        { "kind": "text", "text": "Spot", "size": 0.06, "at": top(-0.1, 0.0), "color": [0.1, 0.2, 0.9, 1.0] },
        { "kind": "text", "text": "live bake", "size": 0.04, "path": path },
        { "image": "img.png", "size": [0.15, 0.15], "at": top(-0.3, 0.6), "method": "expmap" }
    ]);
    let text = spot_job_json(&dir, 5, layers, serde_json::json!({}));
    let job = Job::parse(&text.to_string(), &dir.join("job.json"), &dir, &dir).unwrap();
    let mesh = engine.load_mesh(&job.mesh).unwrap();
    let mut live = engine.live(&mesh, &job).unwrap();
    let at = |x: f32, z: f32| AtSpec::Ray {
        ray: RaySpec {
            origin: [x, 1.5, z],
            dir: [0.0, -1.0, 0.0],
        },
    };
    let set = |live: &decalbake::LiveBake, i: usize, f: &dyn Fn(&mut decalbake::io::job::Layer)| {
        let mut l = live.job().layers[i].clone();
        f(&mut l);
        Edit::Set {
            layer: i,
            to: Box::new(l),
        }
    };
    // Each edit made from the bake as the edits before left it (indices move with re-orders).
    type MakeEdit<'a> = Box<dyn Fn(&decalbake::LiveBake) -> Edit + 'a>;
    let edits: Vec<(&str, MakeEdit)> = vec![
        (
            "decal onto the ribbon",
            Box::new(|l| set(l, 0, &|d| d.at = at(0.0, 0.27))),
        ),
        (
            "ribbon re-weighted",
            Box::new(|l| set(l, 1, &|d| d.opacity = 0.5)),
        ),
        (
            "text moved",
            Box::new(|l| set(l, 2, &|d| d.at = at(0.05, 0.3))),
        ),
        (
            "ribbon on top",
            Box::new(|_| Edit::Reorder { from: 1, to: 4 }),
        ),
        // [decal, text, line of text, expmap decal, ribbon]
        (
            "expmap decal across",
            Box::new(|l| set(l, 3, &|d| d.at = at(0.1, 0.25))),
        ),
        (
            "line of text removed",
            Box::new(|_| Edit::Remove { layer: 2 }),
        ),
    ];
    for (what, make) in edits {
        let report = live.apply(make(&live)).unwrap();
        let want = full(&engine, &mesh, live.job());
        let d = differ(live.read().unwrap(), &want, 256);
        println!("{what}: {} cells, {d} values differ", report.cells);
        assert_eq!(d, 0, "{what}");
        assert!(report.cells > 0, "{what}");
    }
}
