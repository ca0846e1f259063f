// SPDX-License-Identifier: MIT OR Apache-2.0
//! The same job gives the same bytes: a job whose layers cover triangles that overlap in UV space
//! (a folded strip whose two halves share one UV square), the same strip under 1,000 layers, and
//! Spot with 24 exponential-map decals, each baked five times on one engine and in five
//! processes with one and two llvmpipe threads, give identical texels and identical distortion
//! figures in their reports.

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

/// Each layer's distortion figures as the f32s the engine computed (a report read from a file
/// carries them printed shortest, one held in memory widened to f64).
fn distortion(report: &serde_json::Value) -> Vec<Vec<(String, f32)>> {
    let layers = report["layers"].as_array().unwrap();
    layers
        .iter()
        .map(|l| {
            let d = l["distortion"].as_object().unwrap();
            d.iter()
                .map(|(k, v)| (k.clone(), v.as_f64().unwrap() as f32))
                .collect()
        })
        .collect()
}

/// Bakes `job` four more times on `engine` and checks each against `first`: every texel value
/// and the distortion figures.
fn bake_again_and_compare(
    engine: &decalbake::Engine,
    mesh: &decalbake::LoadedMesh,
    job: &Job,
    first: &decalbake::Baked,
) {
    let first_report = serde_json::to_value(&first.report).unwrap();
    for run in 1..5 {
        let again = engine.bake(mesh, job).unwrap();
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
}

/// `decalbake bake JOB` in five processes, with one and two rasterizer threads in turn: the
/// texture file each wrote, and its report where the job writes one.
fn bake_in_processes(
    job: &Path,
    texture: &Path,
    report: Option<&Path>,
) -> Vec<(Vec<u8>, Option<serde_json::Value>)> {
    ["1", "2", "1", "2", "1"]
        .iter()
        .map(|threads| {
            let (code, _, stderr) = cli_env(
                &["bake", job.to_str().unwrap()],
                &[("LP_NUM_THREADS", threads)],
            );
            assert_eq!(code, 0, "{stderr}");
            let report =
                report.map(|r| serde_json::from_slice(&std::fs::read(r).unwrap()).unwrap());
            (std::fs::read(texture).unwrap(), report)
        })
        .collect()
}

/// Every process of [`bake_in_processes`] wrote the first one's file, and a report whose
/// distortion figures are `first_report`'s.
fn processes_agree(
    runs: &[(Vec<u8>, Option<serde_json::Value>)],
    first_report: &serde_json::Value,
) {
    for (k, (file, report)) in runs.iter().enumerate() {
        let report = report.as_ref().unwrap();
        assert_eq!(distortion(report), distortion(first_report), "process {k}");
        assert!(*file == runs[0].0, "process {k} wrote a different file");
    }
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
    bake_again_and_compare(&engine, &mesh, &job, &first);

    // Separate processes, one and two rasterizer threads: the same file.
    let files = bake_in_processes(&path, &dir.join("out.png"), None);
    for (k, f) in files.iter().enumerate() {
        assert!(f.0 == files[0].0, "process {k} wrote a different file");
    }
    let decoded = decalbake::io::image::LinearImage::load(&dir.join("out.png")).unwrap();
    assert_eq!((decoded.width, decoded.height), (256, 256));
}

/// Spot with 24 overlapping exponential-map decals round its body, at 512².
fn write_spot_job(dir: &Path) -> std::path::PathBuf {
    let spot = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/spot.glb");
    std::fs::write(
        dir.join("img.png"),
        test_image(32, 32, 5, true).encode_png(8),
    )
    .unwrap();
    let layers = spot_ring("img.png", 0.3);
    let job = serde_json::json!({ "mesh": spot, "texture": { "width": 512, "height": 512 },
        "layers": layers, "output": { "texture": "spot.png", "report": "spot.json" } });
    let path = dir.join("spot-job.json");
    std::fs::write(&path, job.to_string()).unwrap();
    path
}

#[test]
fn twenty_four_decals_on_spot_bake_the_same_bytes_in_every_process() {
    let dir = scratch("determinism_spot");
    let path = write_spot_job(&dir);
    let job = Job::load(&path, None).unwrap();
    let engine = engine();
    let mesh = engine.load_mesh(&job.mesh).unwrap();
    let first = engine.bake(&mesh, &job).unwrap();
    let first_report = serde_json::to_value(&first.report).unwrap();
    bake_again_and_compare(&engine, &mesh, &job, &first);
    let runs = bake_in_processes(&path, &dir.join("spot.png"), Some(&dir.join("spot.json")));
    processes_agree(&runs, &first_report);
    // The file is the library's bake, encoded.
    let encoded = decalbake::io::image::png_bytes(512, 512, 8, &first.texels);
    let decoded = decalbake::io::image::LinearImage::decode(&encoded).unwrap();
    let written = decalbake::io::image::LinearImage::load(&dir.join("spot.png")).unwrap();
    assert!(
        decoded.pixels == written.pixels,
        "the CLI's file differs from the library's bake"
    );
}

/// 1,000 small layers, planar and exponential-map in turn, scattered over the folded strip (both
/// halves, so most of them overlap another in UV space), at 256².
#[test]
fn a_thousand_layers_bake_the_same_bytes_every_time() {
    let dir = scratch("determinism_1000");
    write_job(&dir);
    let layers: Vec<serde_json::Value> = (0..1000u32)
        .map(|k| {
            // A low-discrepancy walk over the 2 × 1 strip (golden-ratio steps).
            let (x, y) = (
                (k as f32 * 0.618034).fract() * 1.9 + 0.05,
                (k as f32 * 0.754878).fract() * 0.9 + 0.05,
            );
            let method = if k % 2 == 0 { "planar" } else { "expmap" };
            serde_json::json!({ "image": "img.png", "method": method, "size": [0.12, 0.12],
                "angle": (k * 37 % 360) as f32, "opacity": 0.6, "at": [x, y, 0.0] })
        })
        .collect();
    let text = serde_json::json!({ "mesh": "strip.glb", "texture": { "width": 256, "height": 256 },
        "layers": layers, "output": { "texture": "many.png", "report": "many.json" } });
    let path = dir.join("many-job.json");
    std::fs::write(&path, text.to_string()).unwrap();
    let job = Job::load(&path, None).unwrap();
    let engine = engine();
    let mesh = engine.load_mesh(&job.mesh).unwrap();
    let first = engine.bake(&mesh, &job).unwrap();
    assert_eq!(first.report.layers.len(), 1000);
    assert!(first.report.layers.iter().all(|l| l.texels_covered > 0));
    bake_again_and_compare(&engine, &mesh, &job, &first);
    let runs = bake_in_processes(&path, &dir.join("many.png"), Some(&dir.join("many.json")));
    processes_agree(&runs, &serde_json::to_value(&first.report).unwrap());
    assert!(
        runs[0].0 == first.to_png(),
        "the CLI's file is the library's bake, encoded"
    );
}
