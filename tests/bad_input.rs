// SPDX-License-Identifier: MIT OR Apache-2.0
//! Every bad-input case gets a clear message naming the file and the field or element, exit code 2,
//! and no output file left behind. Degenerate triangles are skipped and counted, not fatal.

mod common;
use common::*;
use std::path::Path;

/// A valid job for `book.glb` with `decal.png`, as JSON text, ready to be edited by each case.
fn good_job() -> serde_json::Value {
    serde_json::json!({
        "mesh": "book.glb",
        "texture": { "width": 64, "height": 64, "padding": 4, "samples": 1 },
        "layers": [ { "image": "decal.png", "at": [0.25, 0.5, 0.0], "size": [0.3, 0.3] } ],
        "output": { "texture": "out.png", "report": "report.json", "glb": "out.glb", "preview": "preview.png" }
    })
}

fn setup(dir: &Path) {
    let (pos, uv, idx) = book_mesh();
    write_glb(&dir.join("book.glb"), &pos, Some(&uv), &idx);
    std::fs::write(
        dir.join("decal.png"),
        test_image(8, 8, 1, true).encode_png(8),
    )
    .unwrap();
}

/// Runs one case: returns stderr after checking exit code 2 and an empty output directory.
fn run_case(name: &str, job: &serde_json::Value, prepare: impl FnOnce(&Path)) -> String {
    let dir = scratch(&format!("bad-{name}"));
    setup(&dir);
    prepare(&dir);
    let job_path = dir.join("job.json");
    std::fs::write(&job_path, serde_json::to_vec_pretty(job).unwrap()).unwrap();
    let out = dir.join("out");
    std::fs::create_dir_all(&out).unwrap();
    let (code, _stdout, stderr) = cli(&[
        "bake",
        job_path.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(
        code, 2,
        "{name}: expected exit code 2, got {code}; stderr:\n{stderr}"
    );
    let left: Vec<_> = std::fs::read_dir(&out).unwrap().collect();
    assert!(left.is_empty(), "{name}: output left behind: {left:?}");
    stderr
}

fn expect(stderr: &str, name: &str, needles: &[&str]) {
    for n in needles {
        assert!(
            stderr.contains(n),
            "{name}: message should mention {n:?}; got:\n{stderr}"
        );
    }
}

#[test]
fn bad_job_files() {
    let mut j = good_job();
    j["layers"][0]["colour"] = serde_json::json!("red");
    let e = run_case("unknown-field", &j, |_| {});
    expect(&e, "unknown field", &["job.json", "layers[0]", "colour"]);

    // Malformed JSON.
    let dir = scratch("bad-json-syntax");
    std::fs::write(dir.join("job.json"), "{ \"mesh\": \"a.glb\", ").unwrap();
    std::fs::create_dir_all(dir.join("out")).unwrap();
    let (code, _, err) = cli(&[
        "bake",
        dir.join("job.json").to_str().unwrap(),
        "--out",
        dir.join("out").to_str().unwrap(),
    ]);
    assert_eq!(code, 2, "{err}");
    expect(&err, "malformed json", &["job.json", "EOF"]);

    let (code, _, err) = cli(&["bake", "/nonexistent/job.json"]);
    assert_eq!(code, 2);
    expect(
        &err,
        "missing job",
        &["/nonexistent/job.json", "reading the job file"],
    );

    for (name, field, value, needles) in [
        (
            "zero-size",
            "size",
            serde_json::json!([0.0, 0.3]),
            vec!["layers[0].size", "positive"],
        ),
        (
            "negative-size",
            "size",
            serde_json::json!([0.3, -1.0]),
            vec!["layers[0].size", "positive"],
        ),
        (
            "absurd-size",
            "size",
            serde_json::json!([1e9, 0.3]),
            vec!["layers[0].size", "at most"],
        ),
        (
            "bad-blend",
            "blend",
            serde_json::json!("hue"),
            vec!["layers[0].blend", "color_burn"],
        ),
        (
            "bad-method",
            "method",
            serde_json::json!("magic"),
            vec!["layers[0].method", "planar"],
        ),
        (
            "bad-opacity",
            "opacity",
            serde_json::json!(2.0),
            vec!["layers[0].opacity"],
        ),
        (
            "zero-up",
            "up",
            serde_json::json!([0, 0, 0]),
            vec!["layers[0].up"],
        ),
        (
            "zero-ray",
            "at",
            serde_json::json!({"ray": {"origin": [0, 0, 1], "dir": [0, 0, 0]}}),
            vec!["layers[0].at.ray.dir"],
        ),
    ] {
        let mut j = good_job();
        j["layers"][0][field] = value;
        let e = run_case(name, &j, |_| {});
        expect(&e, name, &needles);
    }
    for (name, field, value, needles) in [
        (
            "zero-width",
            "width",
            serde_json::json!(0),
            vec!["texture.width", "at least 1"],
        ),
        (
            "huge-width",
            "width",
            serde_json::json!(1_000_000),
            vec!["texture.width", "limit"],
        ),
        (
            "bad-samples",
            "samples",
            serde_json::json!(3),
            vec!["texture.samples"],
        ),
        (
            "bad-padding",
            "padding",
            serde_json::json!("lots"),
            vec!["texture.padding"],
        ),
    ] {
        let mut j = good_job();
        j["texture"][field] = value;
        let e = run_case(name, &j, |_| {});
        expect(&e, name, &needles);
    }
    let mut j = good_job();
    j["uv_set"] = serde_json::json!(2);
    let e = run_case("missing-uv-set", &j, |_| {});
    expect(&e, "uv_set", &["uv_set", "1 UV set"]);
    let mut j = good_job();
    j["output"]["bit_depth"] = serde_json::json!(12);
    let e = run_case("bit-depth", &j, |_| {});
    expect(&e, "bit depth", &["output.bit_depth"]);
    let mut j = good_job();
    j["output"]["compression"] = serde_json::json!("best");
    let e = run_case("compression", &j, |_| {});
    expect(
        &e,
        "compression",
        &["output.compression", "\"fast\" or \"small\""],
    );
}

#[test]
fn bad_files_and_meshes() {
    let e = run_case("missing-mesh", &good_job(), |d| {
        std::fs::remove_file(d.join("book.glb")).unwrap()
    });
    expect(&e, "missing mesh", &["book.glb", "reading the mesh"]);
    let e = run_case("garbage-glb", &good_job(), |d| {
        std::fs::write(d.join("book.glb"), b"glTF\x02\0\0\0garbage").unwrap()
    });
    expect(&e, "garbage glb", &["book.glb", "glTF"]);
    let e = run_case("missing-image", &good_job(), |d| {
        std::fs::remove_file(d.join("decal.png")).unwrap()
    });
    expect(&e, "missing image", &["decal.png", "reading the image"]);
    let e = run_case("garbage-image", &good_job(), |d| {
        std::fs::write(d.join("decal.png"), b"\x89PNG not really").unwrap()
    });
    expect(&e, "garbage image", &["decal.png", "decoding"]);

    let e = run_case("nan-position", &good_job(), |d| {
        let (mut pos, uv, idx) = book_mesh();
        pos[3][1] = f32::NAN;
        write_glb(&d.join("book.glb"), &pos, Some(&uv), &idx);
    });
    expect(&e, "nan", &["book.glb", "POSITION[3]", "not finite"]);
    let e = run_case("index-range", &good_job(), |d| {
        let (pos, uv, mut idx) = book_mesh();
        idx[7] = 9999;
        write_glb(&d.join("book.glb"), &pos, Some(&uv), &idx);
    });
    expect(&e, "indices", &["book.glb", "indices[7]", "out of range"]);
    let e = run_case("no-uvs", &good_job(), |d| {
        let (pos, _, idx) = book_mesh();
        write_glb(&d.join("book.glb"), &pos, None, &idx);
    });
    expect(&e, "no uvs", &["book.glb", "no UV coordinates", "unwrap"]);
    let e = run_case("no-triangles", &good_job(), |d| {
        let doc = r#"{"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],"nodes":[{"name":"empty"}]}"#;
        std::fs::write(d.join("book.glb"), doc).unwrap();
    });
    expect(&e, "no triangles", &["book.glb", "no triangles"]);

    let mut j = good_job();
    j["layers"][0]["at"] = serde_json::json!([0.25, 0.5, 5.0]);
    let e = run_case("far-point", &j, |_| {});
    expect(
        &e,
        "far point",
        &["layer 0", "farther than the decal's size"],
    );
    let mut j = good_job();
    j["layers"][0]["at"] = serde_json::json!({"ray": {"origin": [5, 5, 5], "dir": [1, 0, 0]}});
    let e = run_case("ray-miss", &j, |_| {});
    expect(&e, "ray miss", &["layer 0", "misses the mesh"]);
}

#[test]
fn degenerate_triangles_are_skipped_and_counted() {
    let dir = scratch("degenerate");
    let (mut pos, mut uv, mut idx) = book_mesh();
    // Append a zero-area triangle (three collinear points) and one with a repeated vertex.
    let n = pos.len() as u32;
    pos.extend_from_slice(&[[0.1, 0.1, 0.0], [0.2, 0.1, 0.0], [0.3, 0.1, 0.0]]);
    uv.extend_from_slice(&[[0.9, 0.9], [0.95, 0.9], [0.9, 0.95]]);
    idx.extend_from_slice(&[n, n + 1, n + 2, 0, 0, 1]);
    write_glb(&dir.join("book.glb"), &pos, Some(&uv), &idx);
    std::fs::write(
        dir.join("decal.png"),
        test_image(8, 8, 1, true).encode_png(8),
    )
    .unwrap();
    std::fs::write(
        dir.join("job.json"),
        serde_json::to_vec(&good_job()).unwrap(),
    )
    .unwrap();
    let (code, _, err) = cli(&["bake", dir.join("job.json").to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["mesh"]["degenerate_triangles"], 2, "{report}");
    assert!(report["layers"][0]["texels_covered"].as_u64().unwrap() > 50);
}

/// A valid stroke job on the book: one stroke crossing the seam at x = 0.5.
fn stroke_job() -> serde_json::Value {
    let mut j = good_job();
    j["layers"] = serde_json::json!([{ "kind": "stroke", "image": "decal.png",
        "path": [[0.3, 0.5, 0.0], [0.6, 0.5, 0.05]], "size": [0.1, 0.1], "method": "expmap" }]);
    j
}

#[test]
fn bad_strokes() {
    // The valid job bakes (so each case below fails for its own reason).
    let dir = scratch("good-stroke");
    setup(&dir);
    std::fs::write(
        dir.join("job.json"),
        serde_json::to_vec(&stroke_job()).unwrap(),
    )
    .unwrap();
    let (code, _, err) = cli(&["bake", dir.join("job.json").to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");

    let far = serde_json::json!([[0.02, 0.02, 0.0], [0.98, 0.98, 0.24]]);
    let off = serde_json::json!([[0.3, 0.5, 0.0], [0.6, 0.5, 3.0]]);
    let miss =
        serde_json::json!([[0.3, 0.5, 0.0], {"ray": {"origin": [5, 5, 5], "dir": [1, 0, 0]}}]);
    for (name, field, value, needles) in [
        (
            "stroke-empty-path",
            "path",
            serde_json::json!([]),
            vec!["layers[0].path", "empty"],
        ),
        (
            "stroke-no-path",
            "path",
            serde_json::Value::Null,
            vec!["layers[0].path", "missing"],
        ),
        (
            "stroke-off-mesh",
            "path",
            off,
            vec!["layers[0]", "path[1]", "from the surface"],
        ),
        (
            "stroke-ray-misses",
            "path",
            miss,
            vec!["layers[0]", "path[1]", "misses"],
        ),
        (
            "stroke-too-far",
            "path",
            far,
            vec!["layers[0]", "path[0] and path[1]", "add points in between"],
        ),
        (
            "stroke-zero-spacing",
            "spacing",
            serde_json::json!(0.0),
            vec!["layers[0].spacing", "positive"],
        ),
        (
            "stroke-too-many",
            "spacing",
            serde_json::json!(1e-4),
            vec!["layers[0]", "stamps", "20000"],
        ),
        (
            "stroke-pressure-length",
            "pressure",
            serde_json::json!([1.0]),
            vec!["layers[0].pressure", "one pressure per point"],
        ),
        (
            "stroke-pressure-range",
            "pressure",
            serde_json::json!([1.0, 1.5]),
            vec!["layers[0].pressure[1]", "[0, 1]"],
        ),
        (
            "stroke-bad-flow",
            "flow",
            serde_json::json!(-0.5),
            vec!["layers[0].flow", "[0, 1]"],
        ),
        (
            "stroke-bad-orient",
            "orient",
            serde_json::json!("sideways"),
            vec!["layers[0].orient", "fixed"],
        ),
        (
            "stroke-bad-tool",
            "tool",
            serde_json::json!("spray"),
            vec!["layers[0].tool", "paint"],
        ),
        (
            "stroke-at",
            "at",
            serde_json::json!([0.3, 0.5, 0.0]),
            vec!["layers[0].at", "path"],
        ),
        (
            "stroke-radius-on-paint",
            "radius",
            serde_json::json!(0.1),
            vec!["layers[0].radius", "blur"],
        ),
    ] {
        let mut j = stroke_job();
        if value.is_null() {
            j["layers"][0].as_object_mut().unwrap().remove(field);
        } else {
            j["layers"][0][field] = value;
        }
        let e = run_case(name, &j, |_| {});
        expect(&e, name, &needles);
    }
    // Tools: a blur radius that is not positive, a clone source off the mesh or missing, a smear
    // strength out of range, a mask on a blur.
    for (name, fields, needles) in [
        (
            "stroke-blur-radius",
            serde_json::json!({"tool": "blur", "radius": 0.0}),
            vec!["layers[0].radius", "positive"],
        ),
        (
            "stroke-clone-off-mesh",
            serde_json::json!({"tool": "clone", "source": [0.3, 0.5, 3.0]}),
            vec!["layers[0]", "`source`", "from the surface"],
        ),
        (
            "stroke-clone-no-source",
            serde_json::json!({"tool": "clone"}),
            vec!["layers[0].source", "missing"],
        ),
        (
            "stroke-smear-strength",
            serde_json::json!({"tool": "smear", "strength": 2.0}),
            vec!["layers[0].strength", "[0, 1]"],
        ),
        (
            "stroke-blur-mask",
            serde_json::json!({"tool": "blur", "mask": "decal.png"}),
            vec!["layers[0].mask", "alpha"],
        ),
    ] {
        let mut j = stroke_job();
        for (k, v) in fields.as_object().unwrap() {
            j["layers"][0][k] = v.clone();
        }
        let e = run_case(name, &j, |_| {});
        expect(&e, name, &needles);
    }
    // Stroke fields on a decal, and a decal without `at`.
    let mut j = good_job();
    j["layers"][0]["spacing"] = serde_json::json!(0.2);
    let e = run_case("decal-with-spacing", &j, |_| {});
    expect(
        &e,
        "decal-with-spacing",
        &["layers[0].spacing", "strokes only"],
    );
    let mut j = good_job();
    j["layers"][0].as_object_mut().unwrap().remove("at");
    let e = run_case("decal-without-at", &j, |_| {});
    expect(&e, "decal-without-at", &["layers[0].at", "missing"]);
}

#[test]
fn files_that_cannot_be_read_exit_2_naming_the_os_error_once() {
    let dir = common::scratch("unreadable");
    let missing_job = dir.join("nope.json");
    let missing_manifest = dir.join("nope.jsonl");
    for args in [
        vec!["bake", missing_job.to_str().unwrap()],
        vec!["batch", missing_manifest.to_str().unwrap()],
    ] {
        let (code, _, stderr) = common::cli(&args);
        assert_eq!(code, 2, "{args:?}: {stderr}");
        assert_eq!(stderr.matches("os error").count(), 1, "{args:?}: {stderr}");
        assert!(stderr.contains("nope.json"), "{args:?}: {stderr}");
        assert!(
            !stderr.contains("adapter:"),
            "no device is made first: {stderr}"
        );
    }
}
