// SPDX-License-Identifier: MIT OR Apache-2.0
//! The demo runs and its outputs decode (the `.glb` loads back with the baked texture); the library
//! API works on a host's device and hands back a GPU texture equal to the read-back bake; `.gltf`
//! files with external and data-URI buffers and node transforms load.

mod common;
use common::*;
use decalbake::io::image::LinearImage;
use decalbake::mesh::Mesh;
use decalbake::{Engine, Job};
use std::path::Path;

#[test]
fn demo_writes_decodable_outputs_and_a_glb_that_loads_back() {
    let dir = scratch("demo");
    let out = dir.join("demo");
    // `--all`: the unwraps of Spot and bob too (the plain demo is the first part of this).
    let (code, stdout, stderr) = cli(&["demo", "--all", "--out", out.to_str().unwrap()]);
    assert_eq!(code, 0, "demo failed:\n{stderr}");
    for f in ["baked.png", "baked.glb", "preview.png", "report.json"] {
        assert!(stdout.contains(f), "demo should list {f}: {stdout}");
    }
    let baked = LinearImage::load(&out.join("baked.png")).unwrap();
    assert_eq!((baked.width, baked.height), (1024, 1024));
    demo_jobs_follow_their_schema(&out);
    // The unwrapped sheet: its own flattening (TEXCOORD_0) and the pelt's (TEXCOORD_1).
    let sheet = decalbake::mesh::Mesh::load(&out.join("unwrapped.glb")).unwrap();
    assert_eq!(sheet.uv_sets.len(), 2);
    let r: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("unwrap-report.json")).unwrap()).unwrap();
    assert_eq!(
        (
            r["quality"]["flipped"].as_u64(),
            r["quality"]["overlaps"].as_u64()
        ),
        (Some(0), Some(0))
    );
    // Spot unwrapped by the automatic cut: a new set next to its own, no folds.
    let spot = decalbake::mesh::Mesh::load(&out.join("spot-unwrapped.glb")).unwrap();
    assert_eq!(spot.uv_sets.len(), 2);
    let r: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("spot-unwrap-report.json")).unwrap())
            .unwrap();
    assert_eq!(r["quality"]["flipped"], 0);
    assert_eq!(r["quality"]["overlaps"], 0);
    assert!(out.join("spot-unwrap-preview.png").exists());
    // bob unwrapped plain: its body split for the packing, more than half the texture used.
    let r: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("bob-unwrap-report.json")).unwrap())
            .unwrap();
    assert_eq!(
        (
            r["quality"]["flipped"].as_u64(),
            r["quality"]["overlaps"].as_u64()
        ),
        (Some(0), Some(0))
    );
    assert!(
        r["quality"]["texel_utilisation"].as_f64().unwrap() > 0.5,
        "{}",
        r["quality"]
    );
    assert!(out.join("bob-unwrap-preview.png").exists());
    let preview = LinearImage::load(&out.join("preview.png")).unwrap();
    assert_eq!((preview.width, preview.height), (1024, 1024));
    // Each quadrant of the preview shows the model: its centre is not the background colour.
    let bg = preview.pixels[0];
    for (qx, qy) in [(256, 256), (768, 256), (256, 768), (768, 768)] {
        let p = preview.pixels[qy * 1024 + qx];
        assert!(
            (p[0] - bg[0]).abs() + (p[1] - bg[1]).abs() + (p[2] - bg[2]).abs() > 0.05,
            "preview quadrant at ({qx},{qy}) is empty"
        );
    }
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    let layers = report["layers"].as_array().unwrap();
    assert_eq!(layers.len(), 10);
    // The SVG logo and the text along the flank, rendered at the sizes their maps need.
    assert!(layers[8]["image"].as_str().unwrap().ends_with("logo.svg"));
    assert_eq!(layers[9]["kind"], "ribbon");
    for l in &layers[8..] {
        let px = l["raster_px"]
            .as_array()
            .expect("a vector layer's raster size");
        assert!(px[0].as_u64().unwrap() >= 64, "{l}");
    }
    // The ribbon along the flank painted a strip.
    assert_eq!(layers[7]["kind"], "ribbon");
    assert!(
        layers[7]["texels_covered"].as_u64().unwrap() > 500,
        "{}",
        layers[7]
    );
    // The horn tip's decal is a cone chart.
    assert!(layers[4]["chart"]["cone"]["k"].as_f64().unwrap() < 0.8);
    assert_eq!(layers[5]["kind"], "stroke");
    assert_eq!(layers[6]["stroke"]["tool"], "blur");
    assert!(layers[5]["stroke"]["stamps"].as_u64().unwrap() > 50);
    for l in layers {
        assert!(
            l["texels_covered"].as_u64().unwrap() > 500,
            "every demo layer lands: {l}"
        );
        assert!(l["triangles_covered"].as_u64().unwrap() > 10);
    }
    assert!(report["adapter"].as_str().unwrap().len() > 3);
    // The glb loads back, with the baked texture as its base colour.
    let glb = Mesh::load(&out.join("baked.glb")).unwrap();
    assert_eq!(glb.triangles.len(), 5856);
    let tex = glb
        .material
        .as_ref()
        .and_then(|m| m.base_color_texture.as_ref())
        .expect("glb has a base-colour texture");
    assert_eq!((tex.width, tex.height), (1024, 1024));
    assert!(
        tex.pixels
            .iter()
            .zip(&baked.pixels)
            .all(|(a, b)| (0..4).all(|k| (a[k] - b[k]).abs() < 1e-6)),
        "glb texture differs from baked.png"
    );
    // The skinned knight goes out as it came in, its skin and five animations with it: only the
    // bytes of its image (replaced by the bake) differ, and its two materials take their
    // textures: the knight's the badge's channels (new images and textures: metallic-roughness
    // and normal), the untextured gear (sword and shield) a base colour of its own texture set,
    // its factor white now that the texture carries it.
    let (knight, _) = common::rich::read_model(&out.join("knight.glb"));
    let (baked_knight, bufs) = common::rich::read_model(&out.join("knight-baked.glb"));
    let mut diff = Vec::new();
    common::rich::json_diff(&knight, &baked_knight, "", &mut diff);
    let allowed = [
        "/buffers/",
        "/bufferViews/",
        "/images/",
        "/textures/",
        "/materials/0/pbrMetallicRoughness/",
        "/materials/0/normalTexture",
        "/materials/1/pbrMetallicRoughness/",
        "/materials/1/normalTexture",
    ];
    assert!(
        diff.iter()
            .all(|p| allowed.iter().any(|a| p.starts_with(a))),
        "{diff:?}"
    );
    assert_eq!(
        baked_knight["meshes"][0]["primitives"]
            .as_array()
            .unwrap()
            .len(),
        2
    );
    let m = &baked_knight["materials"][0];
    assert!(m["normalTexture"]["index"].is_u64(), "{m}");
    assert!(
        m["pbrMetallicRoughness"]["metallicRoughnessTexture"]["index"].is_u64(),
        "{m}"
    );
    // Each set's texture is the image its material reads, and the shield's rings are in the
    // gear's texture, not the knight's.
    let image_of = |material: usize| {
        let t = baked_knight["materials"][material]["pbrMetallicRoughness"]["baseColorTexture"]
            ["index"]
            .as_u64()
            .unwrap() as usize;
        let i = baked_knight["textures"][t]["source"].as_u64().unwrap() as usize;
        let v = baked_knight["images"][i]["bufferView"].as_u64().unwrap() as usize;
        common::rich::view(&baked_knight, &bufs, v)
    };
    for (material, set) in [(0, "knight"), (1, "gear")] {
        assert!(
            image_of(material)
                == std::fs::read(out.join(format!("knight-baked_{set}.png"))).unwrap(),
            "material {material} takes the {set} set's texture"
        );
    }
    let gear = image::open(out.join("knight-baked_gear.png"))
        .unwrap()
        .to_rgba8();
    let plain = gear.get_pixel(0, 0).0;
    assert!(
        gear.pixels().filter(|p| p.0 != plain).count() > 1000,
        "the rings are painted into the gear's texture"
    );
    let knight_report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("knight-report.json")).unwrap()).unwrap();
    let sets = knight_report["texture_sets"].as_array().unwrap();
    assert_eq!(sets.len(), 2, "{sets:?}");
    assert!(sets
        .iter()
        .all(|s| s["texels_covered"].as_u64().unwrap() > 500));
    assert_eq!(baked_knight["animations"].as_array().unwrap().len(), 5);
    assert!(stdout.contains("knight-preview.png"), "{stdout}");
    common::rich::validate(&out.join("knight-baked.glb"));
    // The demo's job file re-bakes with `decalbake bake`, writing into another directory.
    let again = dir.join("again");
    let (code, _, stderr) = cli(&[
        "bake",
        out.join("job.json").to_str().unwrap(),
        "--out",
        again.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{stderr}");
    assert_eq!(
        LinearImage::load(&again.join("baked.png")).unwrap(),
        baked,
        "the same job bakes the same texture"
    );
    clipped_raster_matches_whole_triangles(&out);
}

#[test]
fn host_device_api_returns_a_texture_equal_to_the_read_back() {
    // A host creates its own device...
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
        backends: wgpu::Backends::from_env().unwrap_or(wgpu::Backends::VULKAN | wgpu::Backends::GL),
        ..wgpu::InstanceDescriptor::new_without_display_handle()
    });
    let adapter =
        pollster::block_on(instance.request_adapter(&Default::default())).expect("adapter");
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("host"),
        required_limits: adapter.limits(),
        ..Default::default()
    }))
    .unwrap();
    let engine = Engine::from_adapter(&adapter, device.clone(), queue.clone()).unwrap();
    assert!(
        engine.ctx.adapter.contains(&adapter.get_info().name),
        "the report names the host's adapter"
    );
    assert!(Engine::from_device(device.clone(), queue.clone()).is_ok());
    let spot = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/spot.glb");
    let mesh = engine.load_mesh(&spot).unwrap();
    let dir = scratch("api");
    std::fs::write(dir.join("d.png"), test_image(32, 32, 4, true).encode_png(8)).unwrap();
    let text = r#"{ "mesh": "unused.glb", "texture": { "width": 200, "height": 136, "samples": 4 },
        "layers": [ { "image": "d.png", "at": { "ray": { "origin": [1.5, 0.0, 0.45], "dir": [-1, 0, 0] } }, "size": [0.4, 0.3], "blend": "overlay" } ] }"#;
    let job = Job::parse(text, &dir.join("job.json"), &dir, &dir).unwrap();
    // ...bakes many jobs against one loaded mesh...
    let baked = engine.bake(&mesh, &job).unwrap();
    let (texture, report) = engine.bake_to_texture(&mesh, &job).unwrap();
    assert_eq!(
        report.layers[0].triangles_covered,
        baked.report.layers[0].triangles_covered
    );
    assert_eq!(texture.format(), wgpu::TextureFormat::Rgba8UnormSrgb);
    // ...and reads the texture back itself.
    // Rows of 800 bytes, packed.
    let row = 800u32;
    let read = |texture: &wgpu::Texture| read_rgba8_texture(&engine, texture);
    let expected = baked.rgba8();
    // The same texture baked by tiles (assembled on the CPU, then uploaded).
    let mut tiled = job.clone();
    tiled.tile = Some(64);
    let (tiled_texture, tiled_report) = engine.bake_to_texture(&mesh, &tiled).unwrap();
    assert_eq!(tiled_report.tiles, Some([64, 12]));
    for bytes in [read(&texture), read(&tiled_texture)] {
        for y in 0..136usize {
            assert_eq!(
                &bytes[y * row as usize..y * row as usize + 800],
                &expected[y * 800..(y + 1) * 800],
                "row {y} differs"
            );
        }
    }
    assert!(baked.report.layers[0].texels_covered > 100);
    assert_eq!(
        report.layers[0].texels_covered,
        baked.report.layers[0].texels_covered
    );
}

#[test]
fn gltf_with_external_and_data_uri_buffers_and_node_transforms_loads() {
    let dir = scratch("gltf");
    let (pos, uv, idx) = book_mesh();
    let mut bin: Vec<u8> = Vec::new();
    bin.extend_from_slice(bytemuck::cast_slice(&pos));
    let uv_off = bin.len();
    bin.extend_from_slice(bytemuck::cast_slice(&uv));
    let idx_off = bin.len();
    bin.extend_from_slice(bytemuck::cast_slice(&idx));
    let doc = |uri: String| {
        serde_json::json!({
            "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
            "nodes": [{"children": [1], "translation": [1.0, 2.0, 3.0]}, {"mesh": 0, "scale": [2.0, 2.0, 2.0]}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2}]}],
            "buffers": [{"byteLength": bin.len(), "uri": uri}],
            "bufferViews": [
                {"buffer": 0, "byteOffset": 0, "byteLength": uv_off},
                {"buffer": 0, "byteOffset": uv_off, "byteLength": idx_off - uv_off},
                {"buffer": 0, "byteOffset": idx_off, "byteLength": bin.len() - idx_off}],
            "accessors": [
                {"bufferView": 0, "componentType": 5126, "count": pos.len(), "type": "VEC3", "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 0.25]},
                {"bufferView": 1, "componentType": 5126, "count": uv.len(), "type": "VEC2"},
                {"bufferView": 2, "componentType": 5125, "count": idx.len(), "type": "SCALAR"}]
        })
    };
    std::fs::write(dir.join("book.bin"), &bin).unwrap();
    std::fs::write(
        dir.join("external.gltf"),
        serde_json::to_vec(&doc("book.bin".into())).unwrap(),
    )
    .unwrap();
    let b64 = base64_encode(&bin);
    std::fs::write(
        dir.join("inline.gltf"),
        serde_json::to_vec(&doc(format!("data:application/octet-stream;base64,{b64}"))).unwrap(),
    )
    .unwrap();
    for f in ["external.gltf", "inline.gltf"] {
        let m = Mesh::load(&dir.join(f)).unwrap();
        assert_eq!(m.triangles.len(), idx.len() / 3, "{f}");
        assert_eq!(m.uv_sets.len(), 1);
        let (lo, hi) = m.bounds();
        assert!(
            (lo - glam::Vec3::new(1.0, 2.0, 3.0)).length() < 1e-6,
            "{f}: node transforms applied: {lo}"
        );
        assert!(
            (hi - glam::Vec3::new(3.0, 4.0, 3.5)).length() < 1e-6,
            "{f}: {hi}"
        );
        assert!(
            m.normals
                .iter()
                .all(|n| n.z > 0.0 || n.length() == 0.0 || n.x < 0.0),
            "{f}: computed normals point out of the book"
        );
    }
    let (code, out, err) = cli(&["info", dir.join("external.gltf").to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    let info: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(info["welded_vertices"], 45);
    // Each 4x4-quad panel has 16 border edges; the 4 they share are interior after welding.
    assert_eq!(info["boundary_edges"], 24);
    assert_eq!(info["components"], 1);
}

fn base64_encode(data: &[u8]) -> String {
    const T: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::new();
    for c in data.chunks(3) {
        let b = [c[0], *c.get(1).unwrap_or(&0), *c.get(2).unwrap_or(&0)];
        let n = (b[0] as u32) << 16 | (b[1] as u32) << 8 | b[2] as u32;
        for k in 0..4 {
            if k <= c.len() {
                s.push(T[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

/// One engine and one mesh shared by four threads baking different jobs at once give the same
/// bytes as baking them one after another (`Engine` and `LoadedMesh` are `Send + Sync`, checked
/// at compile time here).
#[test]
fn concurrent_bakes_on_one_engine_equal_serial_ones() {
    fn shared<T: Send + Sync>() {}
    shared::<decalbake::Engine>();
    shared::<decalbake::LoadedMesh>();
    let dir = scratch("concurrent");
    std::fs::write(
        dir.join("img.png"),
        test_image(16, 16, 5, true).encode_png(8),
    )
    .unwrap();
    let spot = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/spot.glb");
    let engine = engine();
    let mesh = engine.load_mesh(&spot).unwrap();
    let jobs: Vec<decalbake::Job> = (0..8)
        .map(|i| {
            let a = i as f32 * 0.8;
            let method = ["expmap", "lscm", "planar", "hybrid"][i % 4];
            let text = serde_json::json!({ "mesh": spot, "texture": { "width": 128, "height": 128, "padding": 2 },
                "layers": [{ "image": "img.png", "at": { "ray": { "origin": [2.0 * a.cos(), 0.3, 2.0 * a.sin()], "dir": [-a.cos(), 0.0, -a.sin()] } },
                             "size": [0.3, 0.3], "method": method }],
                "output": { "texture": null, "report": null } });
            decalbake::Job::parse(&text.to_string(), &dir.join("job.json"), &dir, &dir).unwrap()
        })
        .collect();
    let serial: Vec<Vec<u16>> = jobs
        .iter()
        .map(|j| engine.bake(&mesh, j).unwrap().texels.clone())
        .collect();
    let parallel: Vec<Vec<u16>> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..4)
            .map(|t| {
                let (engine, mesh, jobs) = (&engine, &mesh, &jobs);
                s.spawn(move || {
                    (t..jobs.len())
                        .step_by(4)
                        .map(|k| (k, engine.bake(mesh, &jobs[k]).unwrap().texels.clone()))
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        let mut out = vec![Vec::new(); jobs.len()];
        for h in handles {
            for (k, t) in h.join().unwrap() {
                out[k] = t;
            }
        }
        out
    });
    for (k, (a, b)) in serial.iter().zip(&parallel).enumerate() {
        assert!(!a.is_empty());
        assert!(
            a == b,
            "job {k}: concurrent bake differs from the serial one"
        );
    }
    // Keeping no buffers between bakes (`decalbake bake` of one job): every bake starts from
    // fresh buffers, the same bytes.
    engine.keep_buffers(0);
    for (k, j) in jobs.iter().enumerate().take(2) {
        let fresh = engine.bake(&mesh, j).unwrap().texels;
        assert!(fresh == serial[k], "job {k}: unpooled bake differs");
    }
}

/// The demo's job (every layer kind, every method, a warp, a cone chart, a blur stroke and a tiled
/// ribbon) at 512², 16 bits, baked with the layer raster clipped to each layer's image and margin
/// (the default) and with whole triangles (`Engine::unclipped_raster`): the texels the clip may
/// change are those whose covered samples it drops, and those of the cells the selection no
/// longer marks (it marks the clipped part's). Tolerance: 32 of 65535 (under a
/// tenth of an 8-bit level).
fn clipped_raster_matches_whole_triangles(demo: &Path) {
    let mut v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(demo.join("job.json")).unwrap()).unwrap();
    v["texture"]["width"] = 512.into();
    v["texture"]["height"] = 512.into();
    v["output"]["bit_depth"] = 16.into();
    let job = Job::parse(&v.to_string(), &demo.join("job.json"), demo, demo).unwrap();
    let mut engine = engine();
    // Spot's triangles cover about 27 texels each at 512², under the default threshold.
    engine.clip_min_texels = 0.0;
    let mesh = engine.load_mesh(&demo.join("spot.glb")).unwrap();
    let clipped = engine.bake(&mesh, &job).unwrap();
    engine.unclipped_raster = true;
    let whole = engine.bake(&mesh, &job).unwrap();
    let (a, b) = (&clipped.texels, &whole.texels);
    let mut worst = 0u16;
    let mut over = 0;
    for (x, y) in a.iter().zip(b.iter()) {
        let d = x.abs_diff(*y);
        worst = worst.max(d);
        over += (d > 257) as usize;
    }
    eprintln!(
        "clipped vs whole triangles: worst {worst} of 65535, {over} channels over one 8-bit level"
    );
    // Measured 4: the clipped polygons' new vertices interpolate the coordinates in another order.
    // With a margin of one texel instead of two it is 238 (a neighbouring triangle's smaller
    // gradient drops samples of an edge texel), with none 25,625 (718 channels over an 8-bit
    // level); with the selection marking cells for a part shrunk by two texels (the raster's
    // scissor then cuts painted texels) 47,706: all fail.
    assert!(
        worst <= 32,
        "the clipped raster changed texels by {worst} of 65535"
    );
}

/// The demo writes its job's schema beside it, `job.json` names it in `$schema`, and every job
/// file the demo writes validates against it.
fn demo_jobs_follow_their_schema(out: &Path) {
    let read = |name: &str| -> serde_json::Value {
        serde_json::from_slice(&std::fs::read(out.join(name)).unwrap()).unwrap()
    };
    let schema = read("job.schema.json");
    assert_eq!(
        schema,
        decalbake::io::schema::schema(decalbake::io::schema::Which::Job)
    );
    let validator = jsonschema::validator_for(&schema).unwrap();
    assert_eq!(read("job.json")["$schema"], "job.schema.json");
    for name in ["job.json", "bob-job.json", "frames.json", "knight.json"] {
        let errors: Vec<String> = validator
            .iter_errors(&read(name))
            .map(|e| format!("{}: {e}", e.instance_path()))
            .collect();
        assert!(errors.is_empty(), "the demo's {name}: {errors:#?}");
    }
}
