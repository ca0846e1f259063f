// SPDX-License-Identifier: MIT OR Apache-2.0
//! The same job gives the same bytes: a job whose layers cover triangles that overlap in UV space
//! (a folded strip whose two halves share one UV square) baked five times on one engine, and in
//! separate processes with one and two llvmpipe threads, gives identical texels, and identical
//! distortion figures in its report.

mod common;
use common::*;
use decalbake::Job;
use std::path::Path;

/// A 2 × 1 strip at z = 0 in `n` cells a unit, folded in UV space: the left half maps to
/// (x, 1 - y), the right half mirrored onto the same square, (2 - x, 1 - y). Every texel of the
/// square is drawn by one triangle of each half, so the draw order decides the texel.
fn write_folded_strip(path: &Path, n: u32) {
    let (mut pos, mut uv, mut idx) = (Vec::new(), Vec::new(), Vec::new());
    for half in 0..2u32 {
        let first = pos.len() as u32;
        for j in 0..=n {
            for i in 0..=n {
                let (x, y) = (i as f32 / n as f32, j as f32 / n as f32);
                pos.push([x + half as f32, y, 0.0]);
                uv.push([if half == 0 { x } else { 1.0 - x }, 1.0 - y]);
            }
        }
        for j in 0..n {
            for i in 0..n {
                let a = first + j * (n + 1) + i;
                let (b, c, d) = (a + 1, a + n + 1, a + n + 2);
                idx.extend([a, b, d, a, d, c]);
            }
        }
    }
    write_glb(path, &pos, Some(&uv), &idx);
}

/// Four overlapping layers, one per map method, around the fold.
fn write_job(dir: &Path) -> std::path::PathBuf {
    write_folded_strip(&dir.join("strip.glb"), 24);
    std::fs::write(
        dir.join("img.png"),
        test_image(64, 64, 11, true).encode_png(8),
    )
    .unwrap();
    let layers: Vec<serde_json::Value> = [
        ("planar", [0.5, 0.5]),
        ("expmap", [1.5, 0.5]),
        ("lscm", [1.0, 0.4]),
        ("hybrid", [1.0, 0.6]),
    ]
    .iter()
    .map(|(method, xy)| {
        serde_json::json!({ "image": "img.png", "method": method, "size": [0.9, 0.9],
            "angle": 20.0, "at": [xy[0], xy[1], 0.0] })
    })
    .collect();
    let job = serde_json::json!({ "mesh": "strip.glb", "texture": { "width": 256, "height": 256 },
        "layers": layers, "output": { "texture": "out.png" } });
    let path = dir.join("job.json");
    std::fs::write(&path, job.to_string()).unwrap();
    path
}

fn distortion(report: &serde_json::Value) -> Vec<serde_json::Value> {
    let layers = report["layers"].as_array().unwrap();
    layers.iter().map(|l| l["distortion"].clone()).collect()
}

#[test]
fn overlapping_triangles_bake_the_same_bytes_every_time() {
    let dir = scratch("determinism");
    let path = write_job(&dir);
    let job = Job::load(&path, None).unwrap();
    let engine = engine();
    let mesh = engine.load_mesh(&job.mesh).unwrap();
    let first = engine.bake(&mesh, &job).unwrap();
    let first_report = serde_json::to_value(&first.report).unwrap();
    // The fold matters: the two halves' triangles both cover the decal's texels.
    let covered: u64 = first_report["layers"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| l["triangles_covered"].as_u64().unwrap())
        .sum();
    assert!(covered > 400, "the layers cover too little: {covered}");
    for run in 1..5 {
        let again = engine.bake(&mesh, &job).unwrap();
        let differ = first
            .texels
            .iter()
            .zip(&again.texels)
            .filter(|(a, b)| a != b)
            .count();
        assert_eq!(differ, 0, "run {run}: {differ} texel values differ");
        let report = serde_json::to_value(&again.report).unwrap();
        assert_eq!(distortion(&report), distortion(&first_report), "run {run}");
    }

    // Separate processes, one and two rasterizer threads: the same file.
    let mut files = Vec::new();
    for threads in ["1", "2"] {
        let (code, _, stderr) = cli_env(
            &["bake", path.to_str().unwrap()],
            &[("LP_NUM_THREADS", threads)],
        );
        assert_eq!(code, 0, "{stderr}");
        files.push(std::fs::read(dir.join("out.png")).unwrap());
    }
    assert!(
        files[0] == files[1],
        "1 and 2 threads wrote different files"
    );
    let decoded = decalbake::io::image::LinearImage::load(&dir.join("out.png")).unwrap();
    assert_eq!((decoded.width, decoded.height), (256, 256));
}
