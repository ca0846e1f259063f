// SPDX-License-Identifier: MIT OR Apache-2.0
//! Limits before work: impossible sizes and bakes that would not fit the memory limit exit 2
//! with a message naming the field, before anything large is allocated (the peak resident
//! memory, `VmHWM`, is measured by the test itself).

mod common;
use common::*;
use decalbake::{Error, Job};
use std::path::Path;

fn job_text(texture: serde_json::Value, extra: Option<(&str, serde_json::Value)>) -> String {
    let mut job = serde_json::json!({ "mesh": "plane.glb", "texture": texture,
        "layers": [{ "image": "img.png", "at": [0.5, 0.5, 0.0], "size": [0.3, 0.3] }],
        "output": { "texture": "out.png", "glb": null, "preview": null, "report": null } });
    if let Some((k, v)) = extra {
        job[k] = v;
    }
    job.to_string()
}

fn setup(name: &str) -> std::path::PathBuf {
    let dir = scratch(name);
    write_plane(&dir.join("plane.glb"), 4, false);
    std::fs::write(dir.join("img.png"), test_image(8, 8, 1, true).encode_png(8)).unwrap();
    dir
}

#[test]
fn impossible_sizes_exit_2_naming_the_field() {
    let dir = setup("limits_sizes");
    let cases: Vec<(serde_json::Value, &str)> = vec![
        (
            serde_json::json!({ "width": 0, "height": 64 }),
            "texture.width",
        ),
        (serde_json::json!({ "width": -1, "height": 64 }), "width"),
        (
            serde_json::json!({ "width": 1_000_000, "height": 1_000_000 }),
            "texture.width",
        ),
        (
            serde_json::json!({ "width": 4_294_967_296u64, "height": 64 }),
            "width",
        ),
        (
            serde_json::json!({ "width": 65_536, "height": 65_536 }),
            "texture.width",
        ),
        (
            serde_json::json!({ "width": 4_294_967_295u64, "height": 4_294_967_295u64 }),
            "texture.width",
        ),
        (
            serde_json::json!({ "width": 256, "height": 256, "tile": 3 }),
            "texture.tile",
        ),
    ];
    for (k, (texture, field)) in cases.into_iter().enumerate() {
        let path = dir.join(format!("job{k}.json"));
        std::fs::write(&path, job_text(texture.clone(), None)).unwrap();
        let (code, _, stderr) = cli(&["bake", path.to_str().unwrap()]);
        assert_eq!(code, 2, "{texture}: {stderr}");
        assert!(stderr.contains(field), "{texture}: names {field}: {stderr}");
        assert!(!dir.join("out.png").exists(), "{texture}: nothing written");
    }
    let bad = job_text(
        serde_json::json!({ "width": 64, "height": 64 }),
        Some(("max_memory", "lots".into())),
    );
    std::fs::write(dir.join("bad_limit.json"), bad).unwrap();
    let (code, _, stderr) = cli(&["bake", dir.join("bad_limit.json").to_str().unwrap()]);
    assert_eq!(code, 2, "{stderr}");
    assert!(stderr.contains("max_memory"), "{stderr}");
}

#[test]
fn a_bake_beyond_the_memory_limit_is_refused_before_it_allocates() {
    let dir = setup("limits_memory");
    let limit = 1u64 << 30;
    let text = job_text(
        serde_json::json!({ "width": 16384, "height": 16384 }),
        Some(("max_memory", "1GiB".into())),
    );
    let job = Job::parse(&text, &dir.join("job.json"), &dir, &dir).unwrap();
    assert_eq!(job.max_memory, Some(limit));
    let engine = engine();
    let mesh = engine.load_mesh(&dir.join("plane.glb")).unwrap();
    let before = peak_resident();
    let err = match engine.bake(&mesh, &job) {
        Err(e @ Error::Job { .. }) => e.to_string(),
        other => panic!("a 16384² bake fits no 1 GiB: {:?}", other.map(|b| b.width)),
    };
    assert!(
        err.contains("1.0 GiB") && err.contains("needs about"),
        "{err}"
    );
    // Nothing the size of the texture was allocated: the peak grew by less than one 16384²
    // plane of 8-bit texels (1 GiB).
    let grown = peak_resident().saturating_sub(before);
    assert!(grown < 64 << 20, "the refusal allocated {grown} bytes");
    assert!(peak_resident() < limit, "peak {} bytes", peak_resident());
    // The command line's limit applies too, and the same job with room bakes.
    let path = dir.join("small.json");
    let small = job_text(serde_json::json!({ "width": 64, "height": 64 }), None);
    std::fs::write(&path, small).unwrap();
    let (code, _, stderr) = cli(&["bake", path.to_str().unwrap(), "--max-memory", "1M"]);
    assert_eq!(code, 2, "{stderr}");
    assert!(stderr.contains("needs about"), "{stderr}");
    assert!(stderr.contains("smaller tiles"), "{stderr}");
    // A job that paints a channel is told what it costs, and that its textures stream too.
    let rough = job_text(serde_json::json!({ "width": 64, "height": 64 }), None)
        .replace("\"size\":", "\"roughness\":0.5,\"size\":");
    assert!(rough.contains("roughness"), "{rough}");
    std::fs::write(dir.join("rough.json"), rough).unwrap();
    let rough_path = dir.join("rough.json");
    let (code, _, stderr) = cli(&["bake", rough_path.to_str().unwrap(), "--max-memory", "1M"]);
    assert_eq!(code, 2, "{stderr}");
    assert!(stderr.contains("fewer PBR channels"), "{stderr}");
    assert!(stderr.contains("every channel's texture too"), "{stderr}");
    let (code, _, stderr) = cli(&["bake", path.to_str().unwrap(), "--max-memory", "4GiB"]);
    assert_eq!(code, 0, "{stderr}");
    assert!(Path::new(&dir.join("out.png")).exists());
}

/// A PNG that is only its header: `w` × `h`, 8-bit RGBA, an empty image data chunk (where a
/// reader's header ends) and no pixels (decoding it fails). Written by the `png` crate.
fn header_only_png(w: u32, h: u32) -> Vec<u8> {
    let mut png = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut png, w, h);
        enc.set_color(png::ColorType::Rgba);
        enc.set_depth(png::BitDepth::Eight);
        let mut writer = enc.write_header().unwrap();
        writer.write_chunk(png::chunk::IDAT, &[]).unwrap();
        // Dropping the writer ends the file (IEND).
    }
    png
}

/// The layers' images count against the limit, from their headers, before any is decoded: a
/// 64² bake whose decal is an 8192² PNG (3 GiB as the engine holds it) is refused under 1 GiB
/// with the images named in the message, and the same job with a small image passes the check
/// (it bakes). The big PNG is only a header, so a bake that decoded it would fail otherwise.
#[test]
fn layer_images_count_against_the_memory_limit() {
    let dir = setup("limits_images");
    std::fs::write(dir.join("big.png"), header_only_png(8192, 8192)).unwrap();
    let text = job_text(
        serde_json::json!({ "width": 64, "height": 64 }),
        Some(("max_memory", "1GiB".into())),
    );
    let big = text.replace("img.png", "big.png");
    let engine = engine();
    let mesh = engine.load_mesh(&dir.join("plane.glb")).unwrap();
    let job = Job::parse(&big, &dir.join("big.json"), &dir, &dir).unwrap();
    let err = match engine.bake(&mesh, &job) {
        Err(e @ Error::Job { .. }) => e.to_string(),
        other => panic!("an 8192² image fits no 1 GiB: {:?}", other.map(|b| b.width)),
    };
    assert!(
        err.contains("needs about") && err.contains("67108864 pixels"),
        "{err}"
    );
    let job = Job::parse(&text, &dir.join("small.json"), &dir, &dir).unwrap();
    engine.bake(&mesh, &job).unwrap();
}
