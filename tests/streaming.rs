// SPDX-License-Identifier: MIT OR Apache-2.0
//! Tiled bakes streamed to their files band by band (`bake/bands.rs`, `output/stream.rs`): the
//! same bytes as the bake held whole (texture and model, 8 and 16 bits, a padding that spans
//! bands), an EXR with the same floats, and a 16384² bake under a memory limit that the whole texture exceeds, its peak
//! resident memory (`VmHWM`) measured by the test itself.

mod common;
use common::*;
use decalbake::bake::memory;
use decalbake::{Engine, Job};
use std::path::Path;

/// Spot with decals by several methods, written to texture, model and report.
fn spot_job(dir: &Path, texture: serde_json::Value) -> Job {
    let spot = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/spot.glb");
    std::fs::write(dir.join("a.png"), test_image(32, 32, 5, true).encode_png(8)).unwrap();
    let ray = |o: [f32; 3]| serde_json::json!({ "ray": { "origin": o, "dir": [-o[0], 0.0, 0.2 - o[2]] } });
    let text = serde_json::json!({ "mesh": spot, "texture": texture,
        "layers": [
            { "image": "a.png", "at": ray([2.0, 0.1, 0.2]), "size": [0.3, 0.3], "method": "expmap" },
            { "image": "a.png", "at": ray([-2.0, 0.2, 0.2]), "size": [0.35, 0.3], "method": "planar" },
            { "image": "a.png", "at": ray([0.0, 0.0, 2.2]), "size": [0.3, 0.3], "method": "lscm", "angle": 30 }
        ],
        "output": { "texture": "out.png", "glb": "out.glb", "report": "report.json" } });
    Job::parse(&text.to_string(), &dir.join("job.json"), dir, dir).unwrap()
}

#[test]
fn a_streamed_bake_writes_the_bytes_of_the_bake_held_whole() {
    let dir = scratch("streaming_bytes");
    let engine = engine();
    let cases = [
        (
            serde_json::json!({ "width": 320, "height": 256, "padding": 8 }),
            8,
        ),
        (
            serde_json::json!({ "width": 256, "height": 320, "padding": 100 }),
            16,
        ),
    ];
    for (texture, depth) in cases {
        let mut job = spot_job(&dir, texture.clone());
        job.bit_depth = depth;
        let mesh = engine.load_mesh(&job.mesh).unwrap();
        // Held whole: one pass, encoded and written by the engine's writer.
        let mut whole = engine.bake(&mesh, &job).unwrap();
        assert!(whole.report.tiles.is_none());
        decalbake::output::write_outputs(&engine, &mesh, &job, &mut whole).unwrap();
        let texture_whole = std::fs::read(dir.join("out.png")).unwrap();
        let model_whole = std::fs::read(dir.join("out.glb")).unwrap();
        std::fs::remove_file(dir.join("out.png")).unwrap();
        // Streamed: tiles of 64, so 4 or 5 bands of rows.
        job.tile = Some(64);
        let (report, files) =
            decalbake::output::bake_and_write(&engine, &mesh, &job, &|_| {}, &|r| {
                r.input_hash = Some("amended".into())
            })
            .unwrap();
        assert_eq!(report.tile_size, Some([64, 64]), "{texture}");
        assert_eq!(files[0], dir.join("out.png"));
        let streamed = std::fs::read(dir.join("out.png")).unwrap();
        println!(
            "{texture} {depth}-bit: {} bytes whole, {} streamed",
            texture_whole.len(),
            streamed.len()
        );
        assert!(streamed == texture_whole, "{texture}, {depth} bits");
        assert!(
            std::fs::read(dir.join("out.glb")).unwrap() == model_whole,
            "the model embeds the same PNG"
        );
        let written: serde_json::Value =
            serde_json::from_slice(&std::fs::read(dir.join("report.json")).unwrap()).unwrap();
        assert_eq!(written["input_hash"], "amended");
        assert_eq!(written["island_texels"], whole.report.island_texels);
        // No temporary file is left beside the outputs.
        let left: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .filter_map(|e| e.ok())
            .filter(|e| e.file_name().to_string_lossy().contains(".tmp-"))
            .collect();
        assert!(left.is_empty(), "{left:?}");
    }
}

/// A quad whose UV island covers the middle tenth of the texture: the 16384² bake's cost is its
/// texels, not its triangles.
fn quad(dir: &Path) {
    let pos = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
    ];
    let uv = [[0.45, 0.55], [0.55, 0.55], [0.55, 0.45], [0.45, 0.45]];
    write_glb(&dir.join("quad.glb"), &pos, Some(&uv), &[0, 1, 2, 0, 2, 3]);
    std::fs::write(
        dir.join("img.png"),
        test_image(16, 16, 3, false).encode_png(8),
    )
    .unwrap();
}

#[test]
fn a_16384_bake_streams_under_a_limit_the_whole_texture_exceeds() {
    let dir = scratch("streaming_16384");
    quad(&dir);
    let limit: u64 = 2_000_000_000;
    let text = serde_json::json!({ "mesh": "quad.glb",
        "texture": { "width": 16384, "height": 16384, "padding": 4, "samples": 1 },
        "max_memory": limit,
        "layers": [{ "image": "img.png", "at": [0.5, 0.5, 0.0], "size": [0.5, 0.5], "method": "planar" }],
        "output": { "texture": "big.png", "glb": "big.glb", "preview": "big_preview.png", "report": null } });
    let job = Job::parse(&text.to_string(), &dir.join("job.json"), &dir, &dir).unwrap();
    let engine: Engine = engine();
    let mesh = engine.load_mesh(&job.mesh).unwrap();
    // The library's bake, which holds the texture, is refused under this limit.
    match engine.bake(&mesh, &job) {
        Err(e) => assert!(e.to_string().contains("needs about"), "{e}"),
        Ok(_) => panic!("a 16384² texture held whole fits no 2 GB"),
    }
    let (report, files) =
        decalbake::output::bake_and_write(&engine, &mesh, &job, &|_| {}, &|_| {}).unwrap();
    let peak = peak_resident();
    println!(
        "peak {} MiB, report tiles {:?} of {:?}",
        peak >> 20,
        report.tiles,
        report.tile_size
    );
    assert!(peak < limit, "peak resident {peak} bytes");
    let tile = report
        .tile_size
        .expect("a 16384² bake goes by tiles on lavapipe");
    // Held whole, in one pass or by the same tiles, the estimate is above the limit.
    for tiles in [None, Some(tile)] {
        let e = memory::estimate(&job, 0, tiles, false);
        assert!(e.host > limit, "{e:?}");
    }
    assert_eq!(files.len(), 3, "{files:?}");
    // The PNG decodes row by row to 16384²: its corner is the background beyond the padding, the
    // base colour a small bake of the same job held whole has there, and its centre, under the
    // decal, is not.
    let mut small = job.clone();
    (small.width, small.height, small.max_memory) = (256, 256, None);
    let base = engine.bake(&mesh, &small).unwrap().rgba8()[..4].to_vec();
    let file = std::fs::File::open(dir.join("big.png")).unwrap();
    let mut reader = png::Decoder::new(std::io::BufReader::new(file))
        .read_info()
        .unwrap();
    assert_eq!((reader.info().width, reader.info().height), (16384, 16384));
    let (mut rows, mut centre, mut corner) = (0, [0u8; 4], [1u8; 4]);
    while let Some(row) = reader.next_row().unwrap() {
        let data = row.data();
        if rows == 8192 {
            centre.copy_from_slice(&data[8192 * 4..8192 * 4 + 4]);
        }
        if rows == 0 {
            corner.copy_from_slice(&data[..4]);
        }
        rows += 1;
    }
    assert_eq!(rows, 16384);
    assert_eq!(corner[..], base[..]);
    assert!(centre[..] != base[..], "{centre:?}");
    let preview = image::open(dir.join("big_preview.png")).unwrap();
    assert!(preview.width() > 0);
}

/// An EXR streamed band by band holds the floats of the bake held whole, and its model the same
/// PNG.
#[test]
fn a_streamed_exr_holds_the_floats_of_the_bake_held_whole() {
    let dir = scratch("streaming_exr");
    let engine = engine();
    let mut job = spot_job(
        &dir,
        serde_json::json!({ "width": 256, "height": 200, "padding": 8 }),
    );
    job.out_texture = Some(dir.join("out.exr"));
    let mesh = engine.load_mesh(&job.mesh).unwrap();
    // Held whole: an EXR goes as one tile when the texture fits.
    let mut whole = engine.bake(&mesh, &job).unwrap();
    assert_eq!(whole.report.tile_size, Some([256, 256]));
    decalbake::output::write_outputs(&engine, &mesh, &job, &mut whole).unwrap();
    let model_whole = std::fs::read(dir.join("out.glb")).unwrap();
    std::fs::remove_file(dir.join("out.exr")).unwrap();
    job.tile = Some(64);
    let (report, _) =
        decalbake::output::bake_and_write(&engine, &mesh, &job, &|_| {}, &|_| {}).unwrap();
    assert_eq!(report.tiles, Some([64, 16]));
    let decoded = image::open(dir.join("out.exr")).unwrap().into_rgba32f();
    assert_eq!(decoded.dimensions(), (256, 200));
    let linear = whole.linear.as_ref().unwrap();
    let differ = decoded
        .as_raw()
        .iter()
        .zip(linear)
        .filter(|(a, b)| a.to_bits() != b.to_bits())
        .count();
    assert_eq!(differ, 0, "{differ} of {} floats differ", linear.len());
    assert!(std::fs::read(dir.join("out.glb")).unwrap() == model_whole);
}

/// `output.compression: "small"` writes smaller PNGs holding the same samples as `"fast"`, held
/// whole and streamed alike (the streamed texture the same bytes as the whole one).
#[test]
fn small_compression_writes_smaller_pngs_of_the_same_samples() {
    let dir = scratch("streaming_compression");
    let engine = engine();
    let mut job = spot_job(&dir, serde_json::json!({ "width": 256, "height": 256 }));
    let mesh = engine.load_mesh(&job.mesh).unwrap();
    let mut files = Vec::new();
    for (compression, tile) in [
        (decalbake::io::image::PngCompression::Fast, None),
        (decalbake::io::image::PngCompression::Small, None),
        (decalbake::io::image::PngCompression::Small, Some(64)),
    ] {
        job.compression = compression;
        job.tile = tile;
        decalbake::output::bake_and_write(&engine, &mesh, &job, &|_| {}, &|_| {}).unwrap();
        files.push(std::fs::read(dir.join("out.png")).unwrap());
    }
    let decode = |b: &[u8]| decalbake::io::image::LinearImage::decode(b).unwrap().pixels;
    assert!(decode(&files[0]) == decode(&files[1]), "the same samples");
    assert!(
        decode(&files[0]) == decode(&files[2]),
        "the same samples, streamed"
    );
    assert!(
        files[1].len() <= files[0].len(),
        "small {} bytes against fast {}",
        files[1].len(),
        files[0].len()
    );
}

/// `"small"` keeps the smallest of its encodings, so it is never larger than `"fast"`, and on a
/// texture with large flat areas (the kind the strongest deflate wins on) it is smaller.
#[test]
fn small_compression_is_never_larger_and_wins_on_flat_textures() {
    use decalbake::io::image::{png_bytes_with, PngCompression};
    let (w, h) = (256u32, 256u32);
    let flat: Vec<u16> = (0..w * h)
        .flat_map(|i| {
            let (x, y) = (i % w, i / w);
            let c = if (x / 32 + y / 32) % 2 == 0 { 200 } else { 40 };
            [c, (x / 8) as u16, 90, 255]
        })
        .collect();
    let noisy: Vec<u16> = (0..w * h * 4)
        .map(|i| ((i as u64 * 2_654_435_761) >> 7) as u16 & 255)
        .collect();
    for (name, texels) in [("flat", &flat), ("noisy", &noisy)] {
        let fast = png_bytes_with(w, h, 8, texels, PngCompression::Fast);
        let small = png_bytes_with(w, h, 8, texels, PngCompression::Small);
        assert!(
            small.len() <= fast.len(),
            "{name}: {} > {}",
            small.len(),
            fast.len()
        );
        let decode = |b: &[u8]| decalbake::io::image::LinearImage::decode(b).unwrap().pixels;
        assert!(decode(&fast) == decode(&small), "{name}: the same samples");
        if name == "flat" {
            assert!(
                small.len() < fast.len(),
                "flat: {} against {}",
                small.len(),
                fast.len()
            );
        }
    }
}
