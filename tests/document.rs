// SPDX-License-Identifier: MIT OR Apache-2.0
//! The model goes out as it came in: a bake's `.glb` or `.gltf` and `decalbake unwrap`'s output
//! are the source document with only the bake's changes, compared by a structural diff of the two
//! JSON documents and by the data of every accessor, and they pass the Khronos glTF-Validator.

mod common;
use common::rich::{
    json_diff, read_accessor, read_model, read_uri, validate, view, write_rich_gltf,
};
use serde_json::{json, Value};
use std::path::Path;

/// Writes a job baking one planar decal across the boundary of the rich model's two painted
/// primitives (x = 1) into `dir`, its model output named `model`.
fn job(dir: &Path, mesh: &Path, model: &str) -> std::path::PathBuf {
    let img: Vec<u16> = (0..16 * 16).flat_map(|_| [20, 200, 90, 255]).collect();
    std::fs::write(
        dir.join("green.png"),
        decalbake::io::image::png_bytes(16, 16, 8, &img),
    )
    .unwrap();
    let job = json!({
        "mesh": mesh,
        "texture": {"width": 128, "height": 128, "base": "material", "padding": 4},
        "layers": [{"kind": "decal", "image": "green.png", "at": [1.0, 0.5, 0.0], "size": [0.5, 0.5],
                    "up": [0, 1, 0], "method": "planar"}],
        "output": {"texture": "baked.png", "glb": model, "report": "report.json"}
    });
    let path = dir.join(format!("job-{}.json", model.replace('/', "-")));
    std::fs::write(&path, serde_json::to_vec_pretty(&job).unwrap()).unwrap();
    path
}

/// Paths of `diff` outside the parts a bake may change (buffers, buffer views, images).
fn unexpected<'a>(diff: &'a [String], allowed: &[&str]) -> Vec<&'a String> {
    diff.iter()
        .filter(|p| !allowed.iter().any(|a| p.starts_with(a)))
        .collect()
}

/// Every accessor of `a` holds the same elements in `b` (same index).
fn same_accessors(a: &(Value, Vec<Vec<u8>>), b: &(Value, Vec<Vec<u8>>)) {
    let n = a.0["accessors"].as_array().unwrap().len();
    for i in 0..n {
        assert_eq!(
            read_accessor(&a.0, &a.1, i),
            read_accessor(&b.0, &b.1, i),
            "accessors[{i}] changed"
        );
    }
}

#[test]
fn a_bake_keeps_the_document_and_replaces_the_image_it_baked() {
    let dir = common::scratch("document-bake");
    let src = write_rich_gltf(&dir);
    let (code, _, err) = common::cli(&["bake", job(&dir, &src, "out.glb").to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    let input = read_model(&src);
    let output = read_model(&dir.join("out.glb"));
    let mut diff = Vec::new();
    json_diff(&input.0, &output.0, "", &mut diff);
    // Images 0 (an external file) and 1 (a data URI) are embedded; image 0 is the bake.
    let odd = unexpected(
        &diff,
        &["/buffers/", "/bufferViews/", "/images/0/", "/images/1/"],
    );
    assert!(odd.is_empty(), "the bake changed {odd:?}");
    assert!(diff.iter().any(|p| p.starts_with("/images/0/")), "{diff:?}");
    same_accessors(&input, &output);
    let image = |i: usize| {
        let v = output.0["images"][i]["bufferView"].as_u64().unwrap() as usize;
        view(&output.0, &output.1, v).to_vec()
    };
    assert_eq!(
        image(0),
        std::fs::read(dir.join("baked.png")).unwrap(),
        "images[0] is the baked texture"
    );
    let normal = read_uri(&dir, input.0["images"][1]["uri"].as_str().unwrap());
    assert_eq!(
        image(1),
        normal,
        "images[1] is the source's normal map, embedded"
    );
    // The report names what the model could not show.
    let report: Value =
        serde_json::from_slice(&std::fs::read(dir.join("report.json")).unwrap()).unwrap();
    let warnings = report["warnings"].to_string();
    assert!(
        warnings.contains("materials[1] (\\\"glossy\\\") keeps its own base colour"),
        "{warnings}"
    );
    assert!(
        warnings.contains("meshes[0].primitives[2] without TEXCOORD_0"),
        "{warnings}"
    );
    validate(&dir.join("out.glb"));
}

#[test]
fn a_gltf_output_has_its_bin_and_image_files() {
    let dir = common::scratch("document-gltf");
    let src = write_rich_gltf(&dir);
    let out_dir = dir.join("out");
    std::fs::create_dir_all(&out_dir).unwrap();
    let (code, _, err) =
        common::cli(&["bake", job(&dir, &src, "out/model.gltf").to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    let output = read_model(&out_dir.join("model.gltf"));
    let input = read_model(&src);
    let mut diff = Vec::new();
    json_diff(&input.0, &output.0, "", &mut diff);
    let odd = unexpected(&diff, &["/buffers/", "/bufferViews/", "/images/0/"]);
    assert!(odd.is_empty(), "the bake changed {odd:?}");
    assert_eq!(output.0["buffers"][0]["uri"], "model.bin");
    assert_eq!(output.0["images"][0]["uri"], "model_baked.png");
    assert_eq!(
        std::fs::read(out_dir.join("model_baked.png")).unwrap(),
        std::fs::read(dir.join("baked.png")).unwrap()
    );
    assert_eq!(
        output.0["images"][1], input.0["images"][1],
        "a data URI stays"
    );
    same_accessors(&input, &output);
    validate(&out_dir.join("model.gltf"));
}

/// The corners of every triangle of `meshes[m].primitives[p]`: each corner's attributes (all of
/// them but the UV sets, and its morph target's delta), in the document's winding.
fn corners(model: &(Value, Vec<Vec<u8>>), m: usize, p: usize) -> Vec<Vec<Vec<f64>>> {
    let prim = &model.0["meshes"][m]["primitives"][p];
    let mut columns: Vec<Vec<Vec<f64>>> = Vec::new();
    for (name, a) in prim["attributes"].as_object().unwrap() {
        if !name.starts_with("TEXCOORD") {
            columns.push(read_accessor(
                &model.0,
                &model.1,
                a.as_u64().unwrap() as usize,
            ));
        }
    }
    for t in prim["targets"].as_array().into_iter().flatten() {
        columns.push(read_accessor(
            &model.0,
            &model.1,
            t["POSITION"].as_u64().unwrap() as usize,
        ));
    }
    let idx = read_accessor(
        &model.0,
        &model.1,
        prim["indices"].as_u64().unwrap() as usize,
    );
    idx.chunks(3)
        .map(|t| {
            t.iter()
                .map(|i| {
                    columns
                        .iter()
                        .flat_map(|c| c[i[0] as usize].clone())
                        .collect()
                })
                .collect()
        })
        .collect()
}

#[test]
fn unwrap_adds_a_uv_set_to_every_primitive_and_keeps_skin_targets_and_winding() {
    let dir = common::scratch("document-unwrap");
    let src = write_rich_gltf(&dir);
    let out = dir.join("unwrapped.glb");
    let (code, _, err) = common::cli(&[
        "unwrap",
        src.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--cpu",
    ]);
    assert_eq!(code, 0, "{err}");
    let input = read_model(&src);
    let output = read_model(&out);
    let mut diff = Vec::new();
    json_diff(&input.0, &output.0, "", &mut diff);
    let odd: Vec<&String> = unexpected(
        &diff,
        &["/buffers/", "/bufferViews/", "/images/", "/accessors/"],
    )
    .into_iter()
    .filter(|p| {
        // Attributes, indices and morph targets of primitives point at their gathered data.
        let parts: Vec<&str> = p.split('/').collect();
        !(parts.len() >= 6
            && parts[1] == "meshes"
            && parts[3] == "primitives"
            && ["attributes", "indices", "targets"].contains(&parts[5]))
    })
    .collect();
    assert!(odd.is_empty(), "unwrap changed {odd:?}");
    let mesh_count = input.0["meshes"].as_array().unwrap().len();
    for m in 0..mesh_count {
        let prims = input.0["meshes"][m]["primitives"].as_array().unwrap().len();
        for p in 0..prims {
            let attrs = &output.0["meshes"][m]["primitives"][p]["attributes"];
            assert!(
                attrs.get("TEXCOORD_1").is_some(),
                "meshes[{m}].primitives[{p}] has the new set: {attrs}"
            );
            // The same triangles, corner by corner, with the same joints, weights and targets.
            assert_eq!(
                corners(&input, m, p),
                corners(&output, m, p),
                "meshes[{m}].primitives[{p}]"
            );
        }
    }
    // The skin's and the animation's data are the source's.
    for a in [
        &input.0["skins"][0]["inverseBindMatrices"],
        &input.0["animations"][0]["samplers"][0]["output"],
    ] {
        let a = a.as_u64().unwrap() as usize;
        assert_eq!(
            read_accessor(&input.0, &input.1, a),
            read_accessor(&output.0, &output.1, a)
        );
    }
    validate(&out);
}

#[test]
fn bundled_models_keep_their_document() {
    let dir = common::scratch("document-bundled");
    for name in ["spot.glb", "bob.glb"] {
        let src = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("assets")
            .join(name);
        let model = format!("out-{name}");
        let job = json!({
            "mesh": src,
            "texture": {"width": 256, "height": 256, "base": "material", "padding": 4},
            "layers": [{"kind": "decal", "image": "green.png", "at": {"ray": {"origin": [2.0, 0.3, 0.2], "dir": [-1, 0, 0]}},
                        "size": [0.2, 0.2], "method": "expmap"}],
            "output": {"texture": format!("{name}.png"), "glb": model}
        });
        let img: Vec<u16> = (0..16 * 16).flat_map(|_| [20, 200, 90, 255]).collect();
        std::fs::write(
            dir.join("green.png"),
            decalbake::io::image::png_bytes(16, 16, 8, &img),
        )
        .unwrap();
        let path = dir.join(format!("{name}.json"));
        std::fs::write(&path, serde_json::to_vec(&job).unwrap()).unwrap();
        let (code, _, err) = common::cli(&["bake", path.to_str().unwrap()]);
        assert_eq!(code, 0, "{name}: {err}");
        let input = read_model(&src);
        let output = read_model(&dir.join(&model));
        let mut diff = Vec::new();
        json_diff(&input.0, &output.0, "", &mut diff);
        let odd = unexpected(&diff, &["/buffers/", "/bufferViews/"]);
        assert!(odd.is_empty(), "{name}: the bake changed {odd:?}");
        same_accessors(&input, &output);
        validate(&dir.join(&model));
    }
}
