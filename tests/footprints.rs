// SPDX-License-Identifier: MIT OR Apache-2.0
//! Honest reports: every layer reports the triangles its map folds where the bake draws it
//! (`footprint_flipped`, `footprint_collapsed`, `footprint_torn`) with a warning, `decalbake param`
//! gives the same counts, and a hybrid decal at a tip where its conformal re-solves fold keeps
//! its exponential map instead of being refused.

mod common;
use common::*;
use serde_json::Value;
use std::path::Path;

/// The tip of Spot's right horn.
const HORN: [f32; 3] = [0.17745, 0.95365, -0.26041];

fn write_job(dir: &Path, method: &str, at: [f32; 3], size: f32) -> std::path::PathBuf {
    let spot = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/spot.glb");
    std::fs::write(
        dir.join("img.png"),
        test_image(32, 32, 2, false).encode_png(8),
    )
    .unwrap();
    let job = serde_json::json!({ "mesh": spot, "texture": { "width": 256, "height": 256 },
        "layers": [{ "image": "img.png", "method": method, "at": at, "size": [size, size] }],
        "output": { "texture": format!("{method}.png"), "report": format!("{method}.json") } });
    let path = dir.join(format!("{method}.job.json"));
    std::fs::write(&path, job.to_string()).unwrap();
    path
}

fn report(path: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

fn counts(layer: &Value) -> [u64; 3] {
    ["footprint_flipped", "footprint_collapsed", "footprint_torn"].map(|k| {
        layer[k]
            .as_u64()
            .unwrap_or_else(|| panic!("{k} missing: {layer}"))
    })
}

#[test]
fn an_expmap_decal_at_a_horn_reports_its_folds_and_param_agrees() {
    let dir = scratch("footprint_horn");
    let job = write_job(&dir, "expmap", HORN, 0.3);
    let (code, _, stderr) = cli(&["bake", job.to_str().unwrap()]);
    assert_eq!(code, 0, "{stderr}");
    let r = report(&dir.join("expmap.json"));
    let layer = &r["layers"][0];
    let c = counts(layer);
    assert!(
        c[0] > 0,
        "the horn's tip folds the exponential map: {layer}"
    );
    assert_eq!(c[0], layer["distortion"]["flipped"].as_u64().unwrap());
    let warned = r["warnings"].as_array().unwrap();
    assert!(
        warned
            .iter()
            .any(|w| w.as_str().unwrap().contains("layer 0: its map folds")),
        "{warned:?}"
    );
    // `decalbake param` counts the same triangles.
    let (code, _, stderr) = param(&job, "0", &dir.join("expmap.csv"));
    assert_eq!(code, 0, "{stderr}");
    let line = stderr
        .lines()
        .find(|l| l.starts_with("footprint:"))
        .unwrap_or_else(|| panic!("no footprint line: {stderr}"));
    assert_eq!(
        line,
        format!(
            "footprint: {} flipped, {} collapsed, {} torn",
            c[0], c[1], c[2]
        )
    );
    // A decal on a smooth, gently curved part of the body folds nowhere and warns of nothing.
    let flat = write_job(&dir, "planar", [0.0, 0.2, 0.6], 0.2);
    let (code, _, stderr) = cli(&["bake", flat.to_str().unwrap()]);
    assert_eq!(code, 0, "{stderr}");
    let r = report(&dir.join("planar.json"));
    assert_eq!(counts(&r["layers"][0]), [0, 0, 0], "{}", r["layers"][0]);
    assert!(
        r["warnings"].as_array().unwrap().is_empty(),
        "{}",
        r["warnings"]
    );
}

#[test]
fn a_hybrid_at_the_horn_bakes_where_the_expmap_does() {
    let dir = scratch("footprint_hybrid");
    let job = write_job(&dir, "hybrid", HORN, 0.3);
    let (code, _, stderr) = cli(&["bake", job.to_str().unwrap()]);
    assert_eq!(code, 0, "a hybrid at the horn is baked: {stderr}");
    let r = report(&dir.join("hybrid.json"));
    let layer = &r["layers"][0];
    let fallback = layer["chart"]["fallback"].as_str().unwrap();
    assert_ne!(fallback, "refused", "{layer}");
    counts(layer);
}
