// SPDX-License-Identifier: MIT OR Apache-2.0
//! Bakes by tiles (`bake/tiles.rs`): byte-identical to the untiled bake where both fit (decals by
//! every method, a continuous stroke, every padding, 8 and 16 bits, tiles that do not divide the
//! texture); chosen automatically when the canvas does not fit the device's storage buffers; a
//! blur stamp across a tile border is refused by name; EXR output holds the linear canvas, padded;
//! the compose's block mask changes no byte, whole or tiled.

mod common;
use common::*;
use decalbake::{Engine, Error, Job};
use std::path::Path;

/// The ray from outside Spot at `o` towards its middle, as a layer's `at`.
fn ray(o: [f32; 3]) -> serde_json::Value {
    serde_json::json!({ "ray": { "origin": o, "dir": [-o[0], 0.0, 0.2 - o[2]] } })
}

/// A job of `layers` on Spot in a `side` texture (padding 8, the texture fields `extra`), with the
/// images `a.png` and `b.png` written beside it, and its file `job.json`.
fn spot_job(
    dir: &Path,
    side: [u32; 2],
    layers: serde_json::Value,
    extra: serde_json::Value,
) -> Job {
    let spot = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/spot.glb");
    std::fs::write(dir.join("a.png"), test_image(32, 32, 5, true).encode_png(8)).unwrap();
    std::fs::write(
        dir.join("b.png"),
        test_image(24, 40, 8, false).encode_png(8),
    )
    .unwrap();
    let mut text = serde_json::json!({ "mesh": spot,
        "texture": { "width": side[0], "height": side[1], "padding": 8 },
        "layers": layers,
        "output": { "texture": "out.png" } });
    if let serde_json::Value::Object(m) = extra {
        for (k, v) in m {
            text["texture"][k] = v;
        }
    }
    std::fs::write(dir.join("job.json"), text.to_string()).unwrap();
    Job::parse(&text.to_string(), &dir.join("job.json"), dir, dir).unwrap()
}

/// Spot with decals by every method and blend mode, and a continuous paint stroke across the back.
fn job(dir: &Path, side: [u32; 2], extra: serde_json::Value) -> Job {
    let layers = serde_json::json!([
        { "image": "a.png", "at": ray([2.0, 0.1, 0.2]), "size": [0.3, 0.3], "method": "expmap" },
        { "image": "b.png", "at": ray([-2.0, 0.2, 0.2]), "size": [0.35, 0.3], "method": "planar", "blend": "multiply" },
        { "image": "a.png", "at": ray([0.0, 0.0, 2.2]), "size": [0.3, 0.3], "method": "lscm", "blend": "screen", "angle": 30 },
        { "image": "b.png", "at": ray([1.4, 0.25, 1.6]), "size": [0.25, 0.25], "method": "hybrid", "opacity": 0.7 },
        { "kind": "stroke", "image": "a.png", "size": [0.1, 0.1], "spacing": 0.2, "continuity": true,
          "path": (0..5).map(|k| { let t = k as f32 / 4.0;
              serde_json::json!({ "ray": { "origin": [-0.3 + 0.6 * t, 1.5, 0.22 + 0.09 * (std::f32::consts::TAU * t).sin()], "dir": [0, -1, 0] } }) })
              .collect::<Vec<_>>() }
    ]);
    spot_job(dir, side, layers, extra)
}

#[test]
fn tiled_bakes_are_the_untiled_bytes() {
    let dir = scratch("tiles_identical");
    let engine = engine();
    let cases = [
        ([256, 256], 128, serde_json::json!({})),
        ([256, 256], 64, serde_json::json!({ "padding": "full" })),
        (
            [200, 136],
            128,
            serde_json::json!({ "padding": 3, "samples": 9 }),
        ),
        // A padding that reaches past the next band of rows (the halo spans two bands).
        ([256, 256], 64, serde_json::json!({ "padding": 80 })),
        // Adaptive supersampling: tiles draw the whole bake's samples.
        (
            [256, 256],
            128,
            serde_json::json!({ "sampling": "adaptive" }),
        ),
    ];
    for (side, tile, extra) in cases {
        let mut j = job(&dir, side, extra.clone());
        let mesh = engine.load_mesh(&j.mesh).unwrap();
        for depth in [8, 16] {
            j.bit_depth = depth;
            j.tile = None;
            let whole = engine.bake(&mesh, &j).unwrap();
            j.tile = Some(tile);
            let tiled = engine.bake(&mesh, &j).unwrap();
            let differ = whole
                .texels
                .iter()
                .zip(&tiled.texels)
                .filter(|(a, b)| a != b)
                .count();
            println!("{side:?} tile {tile} {extra} {depth}-bit: {differ} values differ");
            if differ > 0 {
                let w = side[0] as usize;
                for (k, (a, b)) in whole
                    .texels
                    .iter()
                    .zip(&tiled.texels)
                    .enumerate()
                    .filter(|(_, (a, b))| a != b)
                    .take(12)
                {
                    let t = k / 4;
                    println!("  texel ({}, {}) ch {}: {a} vs {b}", t % w, t / w, k % 4);
                }
            }
            assert_eq!(
                differ, 0,
                "{side:?} in tiles of {tile}, {extra}, {depth} bits"
            );
            assert!(tiled.report.tiles.is_some() && whole.report.tiles.is_none());
            assert_eq!(tiled.report.island_texels, whole.report.island_texels);
            for (a, b) in whole.report.layers.iter().zip(&tiled.report.layers) {
                assert_eq!(
                    a.texels_covered, b.texels_covered,
                    "texels covered, layer {}",
                    a.index
                );
                assert!(a.texels_covered > 0, "layer {} covers nothing", a.index);
            }
        }
    }
}

/// A device whose storage buffers hold 1 MiB: a 512² canvas plane (2 MiB) cannot be one buffer, so
/// the bake goes by tiles by itself (bands the width across, 256 rows each), and gives the bytes
/// of the untiled bake on a device with room for it.
#[test]
fn a_texture_beyond_the_storage_limit_is_tiled_automatically() {
    let dir = scratch("tiles_auto");
    let mut j = job(&dir, [512, 512], serde_json::json!({}));
    // Decals only: the small device also solves the map stage in smaller chunks, and a stroke's
    // many charts are solved packed (16 or more in a chunk) or one per workgroup depending on the
    // chunk, which moves their last bits (tests/linalg.rs); decals' charts are solved alike.
    j.layers.truncate(4);
    let reference = {
        let engine = engine();
        let mesh = engine.load_mesh(&j.mesh).unwrap();
        engine.bake(&mesh, &j).unwrap()
    };
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
        backends: wgpu::Backends::from_env().unwrap_or(wgpu::Backends::VULKAN),
        ..wgpu::InstanceDescriptor::new_without_display_handle()
    });
    let adapter = pollster::block_on(instance.request_adapter(&Default::default())).unwrap();
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        required_features: adapter.features()
            & (wgpu::Features::FLOAT32_FILTERABLE | wgpu::Features::FLOAT32_BLENDABLE),
        required_limits: wgpu::Limits {
            max_storage_buffer_binding_size: 1 << 20,
            ..adapter.limits()
        },
        ..Default::default()
    }))
    .unwrap();
    let tight = Engine::from_adapter(&adapter, device, queue).unwrap();
    let mesh = tight.load_mesh(&j.mesh).unwrap();
    let baked = tight.bake(&mesh, &j).unwrap();
    assert_eq!(baked.report.tiles, Some([512, 2]));
    assert_eq!(baked.report.tile_size, Some([512, 256]));
    let differ: Vec<usize> = (0..baked.texels.len())
        .filter(|&k| baked.texels[k] != reference.texels[k])
        .collect();
    for &k in differ.iter().take(8) {
        let t = k / 4;
        println!(
            "texel ({}, {}) ch {}: {} vs {}",
            t % 512,
            t / 512,
            k % 4,
            reference.texels[k],
            baked.texels[k]
        );
    }
    assert!(
        differ.is_empty(),
        "tiled on a small device: {} values differ",
        differ.len()
    );
}

/// A blur stroke inside one tile bakes as untiled; one across a tile border is refused, naming
/// the layer and the stamp, and nothing is baked.
#[test]
fn a_blur_stamp_across_a_tile_border_is_refused_by_name() {
    let dir = scratch("tiles_blur");
    let engine = engine();
    let j = job(&dir, [256, 256], serde_json::json!({}));
    let blur: Job = {
        let layer = serde_json::json!({ "kind": "stroke", "tool": "blur", "radius": 0.03, "image": "a.png",
            "size": [0.15, 0.15], "spacing": 0.3, "path": [ray([2.0, 0.1, 0.1]), ray([2.0, 0.15, 0.4])] });
        let text = serde_json::json!({ "mesh": j.mesh, "texture": { "width": 256, "height": 256 },
            "layers": [layer] });
        Job::parse(&text.to_string(), &dir.join("blur.json"), &dir, &dir).unwrap()
    };
    let mesh = engine.load_mesh(&j.mesh).unwrap();
    // Where does the stroke land? Its texel box decides which tiles are safe.
    let whole = engine.bake(&mesh, &blur).unwrap();
    let b = whole.report.layers[0].texel_box;
    println!("blur stroke texel box {b:?}");
    // The stamps read their boxes and one texel around (bilinear): inside one tile of side t?
    let fits = |t: i32| (b[0] - 1) / t == (b[2] + 1) / t && (b[1] - 1) / t == (b[3] + 1) / t;
    let inside = [128, 64].into_iter().find(|&t| fits(t));
    let across = [128, 64]
        .into_iter()
        .find(|&t| !fits(t))
        .expect("a tile side the stroke crosses");
    let mut tiled = blur.clone();
    if let Some(t) = inside {
        tiled.tile = Some(t as u32);
        assert_eq!(engine.bake(&mesh, &tiled).unwrap().texels, whole.texels);
    }
    tiled.tile = Some(across as u32);
    match engine.bake(&mesh, &tiled) {
        Err(Error::Placement { layer, detail, .. }) => {
            assert_eq!(layer, 0);
            assert!(
                detail.contains("stamp") && detail.contains("tile"),
                "{detail}"
            );
        }
        other => panic!("expected a refusal, got {:?}", other.map(|_| ())),
    }
}

/// `output.texture` ending in `.exr`: the file is OpenEXR, 32-bit float linear RGBA, the padded
/// canvas; its sRGB encoding is the PNG's within one 8-bit level (GPU and CPU `pow` differ in the
/// last bit).
#[test]
fn exr_output_is_the_linear_padded_canvas() {
    let dir = scratch("tiles_exr");
    let engine = engine();
    let mut j = job(&dir, [128, 128], serde_json::json!({}));
    let mesh = engine.load_mesh(&j.mesh).unwrap();
    let png = engine.bake(&mesh, &j).unwrap();
    j.out_texture = Some(dir.join("out.exr"));
    let mut exr = engine.bake(&mesh, &j).unwrap();
    assert_eq!(
        exr.texels, png.texels,
        "the EXR job's 8-bit texels are the PNG job's"
    );
    decalbake::output::write_outputs(&engine, &mesh, &j, &mut exr).unwrap();
    let img = image::open(dir.join("out.exr")).unwrap().into_rgba32f();
    assert_eq!(img.dimensions(), (128, 128));
    let linear = exr.linear.as_ref().unwrap();
    assert_eq!(img.as_raw(), linear, "the file holds the baked floats");
    let mut worst = 0i32;
    for (k, v) in linear.iter().enumerate() {
        let e = if k % 4 == 3 {
            (v.clamp(0.0, 1.0) * 255.0).round()
        } else {
            (decalbake::io::image::linear_to_srgb(v.clamp(0.0, 1.0)) * 255.0).round()
        };
        worst = worst.max((e as i32 - png.texels[k] as i32).abs());
    }
    println!("EXR vs PNG: at most {worst} 8-bit levels apart");
    assert!(worst <= 1, "{worst}");
    // Padding reached the float image too: a background texel next to an island is not empty.
    assert!(linear.chunks(4).filter(|t| t[3] > 0.0).count() > png.report.island_texels as usize);
}

/// The compose's block mask (`Engine::skip_empty_blocks`, `wgsl/shared/blocks.wgsl`) skips only
/// texels that would compose nothing: with and without it the bytes are the same, whole and by
/// tiles, at 1, 4 and 9 samples a texel and adaptively, on sides that are not multiples of a
/// block (so raster rectangles of other widths move the atlas places off the block grid), with a
/// stroke's stamps blended in their targets.
#[test]
fn skipping_empty_blocks_changes_no_byte() {
    let dir = scratch("tiles_blocks");
    let skip = engine();
    let mut every = engine();
    every.skip_empty_blocks = false;
    let cases = [
        ([256, 256], None, serde_json::json!({})),
        ([250, 190], None, serde_json::json!({ "samples": 1 })),
        (
            [200, 136],
            Some(128),
            serde_json::json!({ "samples": 9, "padding": 3 }),
        ),
        (
            [256, 256],
            Some(128),
            serde_json::json!({ "sampling": "adaptive" }),
        ),
    ];
    for (side, tile, extra) in cases {
        let mut j = job(&dir, side, extra.clone());
        j.tile = tile;
        let bake = |e: &Engine| e.bake(&e.load_mesh(&j.mesh).unwrap(), &j).unwrap();
        let (a, b) = (bake(&skip), bake(&every));
        let differ = a
            .texels
            .iter()
            .zip(&b.texels)
            .filter(|(p, q)| p != q)
            .count();
        assert_eq!(differ, 0, "{side:?}, tile {tile:?}, {extra}: values differ");
        for l in &a.report.layers {
            assert!(l.texels_covered > 0, "layer {} covers nothing", l.index);
        }
    }
}

/// Spot with four material decals (a normal map, roughness, metallic, and emissive on two of
/// them) by several methods, in a `side` texture with the texture fields `extra`.
fn channel_job(dir: &Path, side: [u32; 2], extra: serde_json::Value) -> Job {
    write_raw_png(&dir.join("n.png"), 48, |s, t| {
        let (x, y) = (s - 0.5, t - 0.5);
        let z = (1.0 - 2.0 * (x * x + y * y)).max(0.1);
        let l = (x * x + y * y + z * z).sqrt();
        [
            x / l * 0.5 + 0.5,
            -y / l * 0.5 + 0.5,
            z / l * 0.5 + 0.5,
            1.0,
        ]
    });
    let layers = serde_json::json!([
        { "image": "a.png", "at": ray([2.0, 0.1, 0.2]), "size": [0.3, 0.3], "method": "expmap",
          "normal": "n.png", "roughness": 0.2, "metallic": 1.0 },
        { "image": "a.png", "at": ray([-2.0, 0.2, 0.2]), "size": [0.35, 0.3], "method": "planar",
          "normal": "n.png", "roughness": 0.7, "emissive": [1.0, 0.5, 0.0] },
        { "image": "a.png", "at": ray([0.0, 0.0, 2.2]), "size": [0.3, 0.3], "method": "lscm",
          "angle": 30, "metallic": "a.png" },
        { "image": "a.png", "at": ray([1.4, 0.25, 1.6]), "size": [0.25, 0.25], "method": "hybrid",
          "opacity": 0.7, "normal": "n.png", "emissive": "a.png" }
    ]);
    spot_job(dir, side, layers, extra)
}

/// PBR channels by tiles: material decals on Spot give every channel's texture byte for byte as
/// the untiled bake does, for bands with a finite padding (one whose halo spans two bands), a
/// full padding, and 16 bits; from the command line a tiled job writes each channel's PNG
/// beside the colour's (streamed band by band) with the library's bytes, and an EXR
/// output writes every channel as linear floats with a 16-bit bake's values.
#[test]
fn tiled_bakes_give_every_channels_untiled_bytes() {
    let dir = scratch("tiles_channels");
    let engine = engine();
    let cases = [
        (128, serde_json::json!({})),
        (64, serde_json::json!({ "padding": 80 })),
        (64, serde_json::json!({ "padding": "full" })),
    ];
    for (tile, extra) in cases {
        let mut j = channel_job(&dir, [256, 256], extra.clone());
        let mesh = engine.load_mesh(&j.mesh).unwrap();
        for depth in [8, 16] {
            j.bit_depth = depth;
            j.tile = None;
            let whole = engine.bake(&mesh, &j).unwrap();
            j.tile = Some(tile);
            let tiled = engine.bake(&mesh, &j).unwrap();
            assert!(tiled.report.tiles.is_some() && whole.report.tiles.is_none());
            let kinds: Vec<_> = whole.channels.iter().map(|c| c.kind.name()).collect();
            let tiled_kinds: Vec<_> = tiled.channels.iter().map(|c| c.kind.name()).collect();
            assert_eq!(kinds, ["orm", "normal", "emissive"], "{kinds:?}");
            assert_eq!(tiled_kinds, kinds);
            assert!(whole.texels == tiled.texels, "colour, tile {tile} {extra}");
            for (a, b) in whole.channels.iter().zip(&tiled.channels) {
                let name = a.kind.name();
                let differ = a
                    .texels
                    .iter()
                    .zip(&b.texels)
                    .filter(|(x, y)| x != y)
                    .count();
                println!("tile {tile} {extra} {depth}-bit {name}: {differ} values differ");
                assert_eq!(
                    differ, 0,
                    "{name} in tiles of {tile}, {extra}, {depth} bits"
                );
                // The decals reach the channel: not a texture of its base alone.
                let first = &a.texels[..4];
                assert!(a.texels.chunks(4).any(|t| t != first), "{name} is flat");
            }
        }
    }
    // The command line: tiled, each channel's file with the library's bytes.
    let mut j = channel_job(&dir, [256, 256], serde_json::json!({ "tile": 128 }));
    let mesh = engine.load_mesh(&j.mesh).unwrap();
    j.tile = None;
    let whole = engine.bake(&mesh, &j).unwrap();
    let job_path = dir.join("job.json");
    let (code, _, err) = cli(&["bake", job_path.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    for c in &whole.channels {
        let file = dir.join(format!("out_{}.png", c.kind.name()));
        let png = image::open(&file).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
        let px: Vec<u16> = png
            .to_rgba8()
            .into_raw()
            .into_iter()
            .map(u16::from)
            .collect();
        assert!(px == c.texels, "{} from the command line", c.kind.name());
    }
    // An EXR output: every channel's texture as linear floats too, padded, the values of a
    // 16-bit bake (sRGB-encoded for the emissive, as its PNG is; within a level, the GPU's and
    // this test's rounding and powers).
    j.bit_depth = 16;
    let wide = engine.bake(&mesh, &j).unwrap();
    let exr = std::fs::read_to_string(&job_path)
        .unwrap()
        .replace("out.png", "fresh.exr");
    std::fs::write(&job_path, exr).unwrap();
    let (code, _, err) = cli(&["bake", job_path.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    let srgb = |v: f32| match v <= 0.0031308 {
        true => 12.92 * v,
        false => 1.055 * v.powf(1.0 / 2.4) - 0.055,
    };
    for c in &wide.channels {
        let file = dir.join(format!("fresh_{}.exr", c.kind.name()));
        let img = image::open(&file).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
        let floats = img.to_rgba32f().into_raw();
        assert_eq!(floats.len(), c.texels.len(), "{}", c.kind.name());
        let worst = floats
            .iter()
            .zip(&c.texels)
            .enumerate()
            .map(|(k, (&f, &t))| {
                let v = match c.kind.linear() || k % 4 == 3 {
                    true => f.clamp(0.0, 1.0),
                    false => srgb(f.clamp(0.0, 1.0)),
                };
                (v * 65535.0 - t as f32).abs()
            })
            .fold(0.0f32, f32::max);
        println!(
            "{}: EXR against the 16-bit PNG, worst {worst} levels",
            c.kind.name()
        );
        assert!(worst <= 1.0, "{}: {worst} levels", c.kind.name());
    }
}

/// A material bake by tiles from the command line is streamed band by band into every texture's
/// file (the report says `streamed`), and writes the files the same job baked whole in memory
/// writes, byte for byte: the colour's and each channel's PNG at 16 bits, the model embedding
/// them, and the preview, shaded with the channels (a 256² texture: its reduced copy is the
/// texture itself).
#[test]
fn a_streamed_material_bake_writes_the_files_of_one_held_whole() {
    let dir = scratch("tiles_channels_streamed");
    channel_job(&dir, [256, 256], serde_json::json!({}));
    let job_path = dir.join("job.json");
    let text = std::fs::read_to_string(&job_path).unwrap();
    let mut json: serde_json::Value = serde_json::from_str(&text).unwrap();
    let mut bake = |name: &str, tile: Option<u32>| {
        let out = dir.join(name);
        json["output"] = serde_json::json!({ "texture": "t.png", "glb": "m.glb",
            "preview": "p.png", "report": "r.json", "bit_depth": 16 });
        json["texture"]["tile"] = tile.map_or(serde_json::Value::Null, |t| t.into());
        std::fs::write(&job_path, json.to_string()).unwrap();
        let (code, _, err) = cli(&[
            "bake",
            job_path.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        assert_eq!(code, 0, "{err}");
        let report: serde_json::Value =
            serde_json::from_slice(&std::fs::read(out.join("r.json")).unwrap()).unwrap();
        (out, report)
    };
    let (whole, whole_report) = bake("whole", None);
    let (streamed, streamed_report) = bake("streamed", Some(64));
    assert_eq!(streamed_report["streamed"], true, "{streamed_report}");
    assert!(whole_report.get("streamed").is_none(), "{whole_report}");
    let files = [
        "t.png",
        "t_orm.png",
        "t_normal.png",
        "t_emissive.png",
        "m.glb",
        "p.png",
    ];
    for f in files {
        let a = std::fs::read(whole.join(f)).unwrap_or_else(|e| panic!("whole {f}: {e}"));
        let b = std::fs::read(streamed.join(f)).unwrap_or_else(|e| panic!("streamed {f}: {e}"));
        assert!(a == b, "{f}: the streamed bake's differs");
    }
    // Nothing else beside them: no temporary file left.
    let mut names: Vec<String> = std::fs::read_dir(&streamed)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    let mut expected: Vec<String> = files.iter().map(|f| f.to_string()).collect();
    expected.push("r.json".into());
    expected.sort();
    assert_eq!(names, expected);
}
