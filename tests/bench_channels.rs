// SPDX-License-Identifier: MIT OR Apache-2.0
//! `decalbake bench --channels` on a tiny workload: it runs, prints a JSON line per variant (the
//! full one with the orm and normal textures besides the colour) and the ratio line, and its table.

mod common;

#[test]
fn bench_channels_runs_small() {
    let args = [
        "bench",
        "--channels",
        "--sizes",
        "64",
        "--decals",
        "3",
        "--reps",
        "1",
    ];
    let (code, out, err) = common::cli(&args);
    assert_eq!(code, 0, "stdout:\n{out}\nstderr:\n{err}");
    let lines: Vec<serde_json::Value> = out
        .lines()
        .map(|l| serde_json::from_str(l).expect("a JSON line"))
        .collect();
    assert_eq!(lines.len(), 3, "{out}");
    let textures = |v: &serde_json::Value| v["textures"].clone();
    assert_eq!(lines[0]["variant"], "colour");
    assert_eq!(textures(&lines[0]), serde_json::json!(["base_color"]));
    assert_eq!(lines[0]["channels"], "none");
    assert_eq!(lines[1]["variant"], "full");
    // lavapipe holds the attachments: the channels are drawn beside the colour.
    assert_eq!(lines[1]["channels"], "fused");
    assert_eq!(
        textures(&lines[1]),
        serde_json::json!(["base_color", "orm", "normal"])
    );
    for l in &lines[..2] {
        assert_eq!(l["side"], 64);
        assert_eq!(l["decals"], 3);
        assert!(l["median_ms"].as_f64().is_some_and(|ms| ms > 0.0), "{l}");
    }
    let ratio = lines[2]["ratio_full_over_colour"].as_f64();
    assert!(ratio.is_some_and(|r| r.is_finite() && r > 0.0), "{out}");
    assert!(err.contains("| 64² | full / colour |"), "{err}");
}
