// SPDX-License-Identifier: MIT OR Apache-2.0
//! The model goes out as it came in: a bake's `.glb` or `.gltf` and `decalbake unwrap`'s output
//! are the source document with only the bake's changes, compared by a structural diff of the two
//! JSON documents and by the data of every accessor, and they pass the Khronos glTF-Validator.

mod common;
use common::rich::{
    json_diff, read_accessor, read_model, read_uri, validate, view, write_rich_gltf,
    write_rich_overlapping,
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
    // Images 0 (an external file) and 1 (a data URI) are embedded; image 0 is the bake of the
    // set "painted" (its material's image, replaced in place), image 2 the bake of "glossy"
    // (untextured: a texture of its own, its factor in the texture).
    let odd = unexpected(
        &diff,
        &[
            "/buffers/",
            "/bufferViews/",
            "/images/",
            "/textures/2",
            "/materials/1/pbrMetallicRoughness/",
        ],
    );
    assert!(odd.is_empty(), "the bake changed {odd:?}");
    same_accessors(&input, &output);
    let image = |i: usize| {
        let v = output.0["images"][i]["bufferView"].as_u64().unwrap() as usize;
        view(&output.0, &output.1, v).to_vec()
    };
    assert_eq!(
        image(0),
        std::fs::read(dir.join("baked_painted.png")).unwrap(),
        "images[0] is the painted set's bake"
    );
    let normal = read_uri(&dir, input.0["images"][1]["uri"].as_str().unwrap());
    assert_eq!(
        image(1),
        normal,
        "images[1] is the source's normal map, embedded"
    );
    assert_eq!(
        image(2),
        std::fs::read(dir.join("baked_glossy.png")).unwrap(),
        "images[2] is the glossy set's bake"
    );
    let pbr = &output.0["materials"][1]["pbrMetallicRoughness"];
    assert_eq!(
        output.0["textures"][pbr["baseColorTexture"]["index"].as_u64().unwrap() as usize]["source"],
        2
    );
    assert_eq!(pbr["baseColorFactor"], json!([1.0, 1.0, 1.0, 1.0]));
    assert_eq!(
        pbr["roughnessFactor"],
        input.0["materials"][1]["pbrMetallicRoughness"]["roughnessFactor"]
    );
    // The glossy set's base is its factor (0.2, 0.4, 0.8), in sRGB.
    let glossy = image::open(dir.join("baked_glossy.png"))
        .unwrap()
        .to_rgba8();
    assert_eq!(glossy.get_pixel(120, 8).0, [124, 170, 231, 255]);
    // The report names what the model could not show.
    let report: Value =
        serde_json::from_slice(&std::fs::read(dir.join("report.json")).unwrap()).unwrap();
    let warnings = report["warnings"].to_string();
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
    let odd = unexpected(
        &diff,
        &[
            "/buffers/",
            "/bufferViews/",
            "/images/0/",
            "/images/2",
            "/textures/2",
            "/materials/1/pbrMetallicRoughness/",
        ],
    );
    assert!(odd.is_empty(), "the bake changed {odd:?}");
    assert_eq!(output.0["buffers"][0]["uri"], "model.bin");
    assert_eq!(output.0["images"][0]["uri"], "model_baked.png");
    assert_eq!(
        std::fs::read(out_dir.join("model_baked.png")).unwrap(),
        std::fs::read(dir.join("baked_painted.png")).unwrap()
    );
    assert_eq!(
        std::fs::read(out_dir.join("model_baked_2.png")).unwrap(),
        std::fs::read(dir.join("baked_glossy.png")).unwrap()
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

/// The rich model with its JSON changed by `edit`, written as `name` beside it.
fn edited(dir: &Path, name: &str, edit: impl FnOnce(&mut Value)) -> std::path::PathBuf {
    let src = write_rich_gltf(dir);
    let mut doc: Value = serde_json::from_slice(&std::fs::read(&src).unwrap()).unwrap();
    edit(&mut doc);
    let path = dir.join(name);
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    path
}

#[test]
fn required_extensions_refuse_only_what_changes_the_geometry() {
    let dir = common::scratch("document-required");
    // Harmless ones are kept and ignored.
    let fine = edited(&dir, "unlit.gltf", |d| {
        d["extensionsUsed"]
            .as_array_mut()
            .unwrap()
            .push(json!("KHR_materials_unlit"));
        d["extensionsRequired"]
            .as_array_mut()
            .unwrap()
            .push(json!("KHR_materials_unlit"));
        d["materials"][2]["extensions"] = json!({"KHR_materials_unlit": {}});
    });
    let (code, _, err) = common::cli(&["info", fine.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    // One that changes how the geometry is stored is refused by name, as is one nobody knows.
    for (ext, needle) in [
        ("EXT_mesh_gpu_instancing", "cannot decode it"),
        ("EXT_unheard_of", "does not know"),
    ] {
        let bad = edited(&dir, &format!("{ext}.gltf"), |d| {
            d["extensionsUsed"].as_array_mut().unwrap().push(json!(ext));
            d["extensionsRequired"]
                .as_array_mut()
                .unwrap()
                .push(json!(ext));
        });
        let (code, _, err) = common::cli(&["info", bad.to_str().unwrap()]);
        assert_eq!(code, 2, "{ext}: {err}");
        assert!(err.contains(ext) && err.contains(needle), "{ext}: {err}");
    }
}

#[test]
fn a_texture_transform_is_applied_to_the_base_and_left_out_of_the_bake() {
    let dir = common::scratch("document-transform");
    let src = edited(&dir, "shifted.gltf", |d| {
        d["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]["extensions"] =
            json!({"KHR_texture_transform": {"offset": [0.5, 0.0]}});
    });
    // Left half red, right half blue: shifted by half, the base at u = 0.25 is blue.
    let px: Vec<u16> = (0..4)
        .flat_map(|x| {
            if x < 2 {
                [255, 0, 0, 255]
            } else {
                [0, 0, 255, 255]
            }
        })
        .collect();
    std::fs::write(
        dir.join("albedo.png"),
        decalbake::io::image::png_bytes(4, 1, 8, &px),
    )
    .unwrap();
    let (code, _, err) = common::cli(&["bake", job(&dir, &src, "out.glb").to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    let baked = image::open(dir.join("baked_painted.png"))
        .unwrap()
        .to_rgba8();
    let at = |u: f32| baked.get_pixel((u * 128.0) as u32, 8).0;
    assert_eq!(
        at(0.25),
        [0, 0, 255, 255],
        "u = 0.25 shows the image at u = 0.75"
    );
    assert_eq!(
        at(0.75),
        [255, 0, 0, 255],
        "u = 0.75 shows the image at u = 0.25 (wrapped)"
    );
    // The material takes the bake without the transform; the source image is left as it was.
    let (out, _) = read_model(&dir.join("out.glb"));
    let info = &out["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"];
    assert!(info.get("extensions").is_none(), "{info}");
    assert_ne!(info["index"], 0, "a texture of its own: {info}");
    validate(&dir.join("out.glb"));
}

/// The rich model with two textured materials whose layouts overlap (u in 0..0.5 both), the
/// second's image a blue `second.png`, written into `dir`.
fn write_two_textured_sets(dir: &Path) -> std::path::PathBuf {
    let src = write_rich_overlapping(dir);
    let mut doc: Value = serde_json::from_slice(&std::fs::read(&src).unwrap()).unwrap();
    doc["images"]
        .as_array_mut()
        .unwrap()
        .push(json!({"uri": "second.png"}));
    doc["textures"]
        .as_array_mut()
        .unwrap()
        .push(json!({"source": 2}));
    doc["materials"][1]["pbrMetallicRoughness"]["baseColorTexture"] = json!({"index": 2});
    std::fs::write(&src, serde_json::to_vec(&doc).unwrap()).unwrap();
    let blue: Vec<u16> = (0..16).flat_map(|_| [30, 60, 220, 255]).collect();
    std::fs::write(
        dir.join("second.png"),
        decalbake::io::image::png_bytes(4, 4, 8, &blue),
    )
    .unwrap();
    src
}

#[test]
fn each_texture_set_gets_its_own_texture_continuous_across_the_material_boundary() {
    let dir = common::scratch("document-sets");
    let src = write_two_textured_sets(&dir);
    let job = job(&dir, &src, "out.glb");
    let mut j: Value = serde_json::from_slice(&std::fs::read(&job).unwrap()).unwrap();
    j["output"]["texture"] = json!("baked_{set}.png");
    j["output"]["preview"] = json!("preview.png");
    std::fs::write(&job, serde_json::to_vec(&j).unwrap()).unwrap();
    let (code, _, err) = common::cli(&["bake", job.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    let texel = |set: &str, x: f32| {
        // Row 64 is y = 0.5 on the plane; u = x / 2 on the first part, (x - 1) / 2 on the second.
        let img = image::open(dir.join(format!("baked_{set}.png")))
            .unwrap()
            .to_rgba8();
        let u = if x < 1.0 { x / 2.0 } else { (x - 1.0) / 2.0 };
        img.get_pixel((u * 128.0) as u32, 64).0
    };
    let green = [20, 200, 90, 255];
    // The decal covers x in 0.75..1.25: both sides of the boundary (x = 1) are green in their
    // own set's texture, right up to it.
    assert_eq!(texel("painted", 0.8), green);
    assert_eq!(texel("painted", 0.98), green);
    assert_eq!(texel("glossy", 1.02), green);
    assert_eq!(texel("glossy", 1.2), green);
    // Where the other part's triangles lie in the overlapping layout, each keeps its base.
    assert_eq!(
        texel("painted", 0.1),
        [200, 120, 40, 255],
        "the glossy part's paint stays out of the painted texture"
    );
    assert_eq!(
        texel("glossy", 1.9),
        [30, 60, 220, 255],
        "the painted part's paint stays out of the glossy texture"
    );
    let report: Value =
        serde_json::from_slice(&std::fs::read(dir.join("report.json")).unwrap()).unwrap();
    let sets = report["texture_sets"].as_array().unwrap();
    assert_eq!(sets.len(), 2, "{sets:?}");
    assert!(
        sets.iter()
            .all(|s| s["texels_covered"].as_u64().unwrap() > 0),
        "{sets:?}"
    );
    // The model: each set's bake replaced its own image.
    let (out, bufs) = read_model(&dir.join("out.glb"));
    for (image, set) in [(0, "painted"), (2, "glossy")] {
        let v = out["images"][image]["bufferView"].as_u64().unwrap() as usize;
        assert_eq!(
            view(&out, &bufs, v),
            std::fs::read(dir.join(format!("baked_{set}.png"))).unwrap()
        );
    }
    assert!(dir.join("preview.png").exists());
    validate(&dir.join("out.glb"));
}

/// `"uv_set": "auto"` on a non-manifold mesh without UVs (three triangles on one edge) opens the
/// shared edge into chart boundaries and bakes; the model carries the new set on its primitive.
#[test]
fn auto_uvs_open_non_manifold_edges() {
    let dir = common::scratch("document-fin");
    let fin = dir.join("fin.glb");
    common::write_fin(&fin);
    let img: Vec<u16> = (0..16 * 16).flat_map(|_| [20, 200, 90, 255]).collect();
    std::fs::write(
        dir.join("green.png"),
        decalbake::io::image::png_bytes(16, 16, 8, &img),
    )
    .unwrap();
    let job = json!({
        "mesh": "fin.glb", "uv_set": "auto",
        "texture": {"width": 64, "height": 64, "padding": 2},
        "layers": [{"image": "green.png", "at": [0.5, 0.2, 0.0], "size": [0.3, 0.3], "depth": 2.0, "method": "planar"}],
        "output": {"texture": "fin.png", "glb": "fin-out.glb", "report": "fin.json"}
    });
    let path = dir.join("job.json");
    std::fs::write(&path, serde_json::to_vec(&job).unwrap()).unwrap();
    let (code, _, err) = common::cli(&["bake", path.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    let report: Value =
        serde_json::from_slice(&std::fs::read(dir.join("fin.json")).unwrap()).unwrap();
    assert_eq!(
        report["unwrap"]["pieces"].as_array().unwrap().len(),
        3,
        "{}",
        report["unwrap"]
    );
    let (out, _) = read_model(&dir.join("fin-out.glb"));
    assert!(out["meshes"][0]["primitives"][0]["attributes"]
        .get("TEXCOORD_0")
        .is_some());
    validate(&dir.join("fin-out.glb"));
}

/// `decalbake batch` bakes a job on a model of two texture sets as `decalbake bake` does (a
/// texture per set, the same bytes), and `--resume` finds them done.
#[test]
fn a_batch_bakes_every_texture_set_and_resumes() {
    let dir = common::scratch("document-batch-sets");
    let src = write_rich_overlapping(&dir);
    let job = job(&dir, &src, "out.glb");
    let (code, _, err) = common::cli(&["bake", job.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    std::fs::write(
        dir.join("manifest.jsonl"),
        format!("{:?}\n", job.file_name().unwrap().to_str().unwrap()),
    )
    .unwrap();
    let out = dir.join("batch");
    let summary = out.join("summary.json");
    let run = |extra: &[&str]| {
        let manifest = dir.join("manifest.jsonl");
        let mut args = vec![
            "batch",
            manifest.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--summary",
            summary.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        common::cli(&args)
    };
    let (code, _, err) = run(&[]);
    assert_eq!(code, 0, "{err}");
    let job_dir = std::fs::read_dir(&out)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .find(|p| p.is_dir())
        .unwrap();
    for set in ["painted", "glossy"] {
        let name = format!("baked_{set}.png");
        assert_eq!(
            std::fs::read(job_dir.join(&name)).unwrap(),
            std::fs::read(dir.join(&name)).unwrap(),
            "{name}: the batch bakes what bake bakes"
        );
    }
    assert!(!job_dir.join("baked.png").exists());
    let (code, _, err) = run(&["--resume"]);
    assert_eq!(code, 0, "{err}");
    let s: Value = serde_json::from_slice(&std::fs::read(&summary).unwrap()).unwrap();
    assert_eq!(s["jobs"][0]["status"], "skipped", "{s}");
}

/// `texture.sets` sizes a material's set (by name or index); a key that names no material is
/// refused (exit 2) with the key and the materials there are, and nothing is written.
#[test]
fn texture_sets_take_their_own_sizes_and_unknown_materials_are_refused() {
    let dir = common::scratch("document-set-sizes");
    let src = write_rich_overlapping(&dir);
    let job = job(&dir, &src, "out.glb");
    let mut j: Value = serde_json::from_slice(&std::fs::read(&job).unwrap()).unwrap();
    j["texture"]["sets"] = json!({"glossy": {"width": 64}, "0": {"height": 32}});
    std::fs::write(&job, serde_json::to_vec(&j).unwrap()).unwrap();
    let (code, _, err) = common::cli(&["bake", job.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    let size = |set: &str| image::image_dimensions(dir.join(format!("baked_{set}.png"))).unwrap();
    assert_eq!(
        size("glossy"),
        (64, 128),
        "by name, its height the texture's"
    );
    assert_eq!(size("painted"), (128, 32), "by index");
    let out = dir.join("refused");
    j["texture"]["sets"] = json!({"chrome": {"width": 64}});
    j["output"] = json!({"texture": "refused/baked.png", "glb": "refused/out.glb"});
    std::fs::write(&job, serde_json::to_vec(&j).unwrap()).unwrap();
    let (code, _, err) = common::cli(&["bake", job.to_str().unwrap()]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("texture.sets.chrome") && err.contains("painted, glossy, trim"),
        "{err}"
    );
    assert!(!out.exists() || std::fs::read_dir(&out).unwrap().next().is_none());
}

/// An animated ribbon on a model of two texture sets whose UV layouts overlap: each frame bakes a
/// texture per set it touches, as an unanimated job does, through `decalbake bake` and `decalbake
/// batch` alike (the same files, the same bytes). The piece lies on the first material in frame 0
/// and on the second in frame 1, so frame 0 writes the first set's texture and frame 1 the
/// second's, each painted: a frame baked as one texture for the whole mesh was named after the
/// first set in both frames, and painted the second material's triangles into it.
#[test]
fn animated_frames_bake_a_texture_per_set() {
    let mut written = Vec::new();
    for command in ["bake", "batch"] {
        let dir = common::scratch(&format!("document-frames-{command}"));
        let src = write_rich_overlapping(&dir);
        let job = job(&dir, &src, "out.glb");
        let mut j: Value = serde_json::from_slice(&std::fs::read(&job).unwrap()).unwrap();
        let route: Vec<[f32; 3]> = (0..=14).map(|k| [0.3 + 0.1 * k as f32, 0.5, 0.0]).collect();
        j["layers"] = json!([{ "kind": "ribbon", "image": "green.png", "width": 0.2,
            "animate": { "route": route, "frames": 2, "length": 0.4 } }]);
        j["output"] = json!({ "texture": "anim_{set}_{frame}.png" });
        std::fs::write(&job, serde_json::to_vec(&j).unwrap()).unwrap();
        let (code, _, err) = common::bake_or_batch(command, &job);
        assert_eq!(code, 0, "{command}: {err}");
        let names = common::files_starting(&dir, "anim_");
        let expected = ["anim_glossy_1.png", "anim_painted_0.png"];
        assert_eq!(names, expected, "{command}");
        let green = |name: &str| {
            let img = image::open(dir.join(name)).unwrap().to_rgba8();
            img.pixels().filter(|p| p.0 == [20, 200, 90, 255]).count()
        };
        for name in expected {
            let n = green(name);
            println!("{command} {name}: {n} green texels");
            assert!(n > 0, "{command} {name}: {n} green texels");
        }
        let bytes: Vec<Vec<u8>> = names
            .iter()
            .map(|n| std::fs::read(dir.join(n)).unwrap())
            .collect();
        written.push(bytes);
    }
    assert!(
        written[0] == written[1],
        "bake and batch wrote different frames"
    );
}

/// Embedding: `Engine::bake_set_textures` gives every texture set its own GPU textures, each
/// holding the bytes `Engine::bake_texture_sets` bakes for that set (which the test above checks
/// against the surface: each set painted, neither taking the other's triangles in the
/// overlapping layout), at the set's own size; on a one-set model, one entry for the whole mesh.
#[test]
fn embedded_bakes_give_each_texture_set_its_own_textures() {
    let dir = common::scratch("document-set-textures");
    let src = write_two_textured_sets(&dir);
    let path = job(&dir, &src, "out.glb");
    let mut j: Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    j["texture"]["sets"] = json!({"glossy": {"width": 64}});
    j["layers"][0]["roughness"] = json!(0.25);
    std::fs::write(&path, serde_json::to_vec(&j).unwrap()).unwrap();
    let engine = common::engine();
    let job = decalbake::Job::load(&path, None).unwrap();
    let (mesh, job) = engine.load_mesh_for(&job).unwrap();
    let on_gpu = engine.bake_set_textures(&mesh, &job).unwrap();
    let sets = mesh.mesh.texture_sets(job.uv_set);
    let on_host = engine.bake_texture_sets(&mesh, &job, sets).unwrap();
    let names: Vec<&str> = on_gpu.iter().map(|s| s.set.name.as_str()).collect();
    assert_eq!(names, ["painted", "glossy"]);
    for (g, h) in on_gpu.iter().zip(&on_host) {
        assert_eq!(g.set, h.set);
        let color = &g.textures.color;
        assert_eq!(
            (color.width(), color.height()),
            (h.baked.width, h.baked.height),
            "{}",
            g.set.name
        );
        let bytes = common::read_rgba8_texture(&engine, color);
        let texels: Vec<u8> = h.baked.texels.iter().map(|&v| v as u8).collect();
        assert!(bytes == texels, "{}: the colour differs", g.set.name);
        assert_eq!(g.textures.channels.len(), h.baked.channels.len());
        for ((kind, t), c) in g.textures.channels.iter().zip(&h.baked.channels) {
            let texels: Vec<u8> = c.texels.iter().map(|&v| v as u8).collect();
            assert!(
                common::read_rgba8_texture(&engine, t) == texels,
                "{} {kind:?}",
                g.set.name
            );
        }
        assert!(g.report.layers[0].texels_covered > 0, "{}", g.set.name);
    }
    assert_eq!(
        on_gpu[1].textures.color.width(),
        64,
        "the glossy set's own width"
    );
    // A one-set model: one entry, the whole mesh.
    let plane = dir.join("plane.glb");
    common::write_plane(&plane, 8, false);
    let mut one = job.clone();
    one.mesh = plane.clone();
    one.set_sizes.clear();
    let mesh = engine.load_mesh(&plane).unwrap();
    let whole = engine.bake_set_textures(&mesh, &one).unwrap();
    assert_eq!(whole.len(), 1);
    assert_eq!(
        whole[0].set.primitives,
        (0..mesh.mesh.primitives.len()).collect::<Vec<_>>()
    );
}

/// A job of several UV sets (`"uv_set": [0, 1]`) on a model of two texture sets whose layouts
/// overlap on both UV sets: each UV set bakes a texture per texture set, as a job of that UV set
/// alone does, so neither texture takes the other part's paint; every UV set draws its own
/// preview (the blend of the sets' textures draws one texture a UV set); `decalbake batch` writes
/// the same files, byte for byte.
#[test]
fn a_list_of_uv_sets_bakes_each_texture_set() {
    let dir = common::scratch("document-uv-list-sets");
    let src = write_rich_overlapping(&dir);
    // The second UV set: the first's layout again, on every primitive that has one.
    let mut doc: Value = serde_json::from_slice(&std::fs::read(&src).unwrap()).unwrap();
    for mesh in doc["meshes"].as_array_mut().unwrap() {
        for p in mesh["primitives"].as_array_mut().unwrap() {
            if let Some(uv) = p["attributes"].get("TEXCOORD_0").cloned() {
                p["attributes"]["TEXCOORD_1"] = uv;
            }
        }
    }
    std::fs::write(&src, serde_json::to_vec(&doc).unwrap()).unwrap();
    // The job's file is named with a placeholder too (`job-out_{uv}.glb.json`): the batch's
    // folder for it must not take the UV set's number.
    let path = job(&dir, &src, "out_{uv}.glb");
    let mut j: Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    j["uv_set"] = json!([0, 1]);
    j["texture"]["base"] = json!([0.5, 0.5, 0.5, 1.0]);
    j["output"]["texture"] = json!("baked_{uv}_{set}.png");
    j["output"]["report"] = json!("report_{uv}.json");
    j["output"]["preview"] = json!("preview.png");
    std::fs::write(&path, serde_json::to_vec(&j).unwrap()).unwrap();
    let (code, _, err) = common::cli(&["bake", path.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    let green = [20, 200, 90, 255];
    let grey = [188, 188, 188, 255];
    for uv in [0, 1] {
        let texel = |set: &str, x: f32| {
            let img = image::open(dir.join(format!("baked_{uv}_{set}.png")))
                .unwrap()
                .to_rgba8();
            let u = if x < 1.0 { x / 2.0 } else { (x - 1.0) / 2.0 };
            img.get_pixel((u * 128.0) as u32, 64).0
        };
        assert_eq!(texel("painted", 0.9), green, "uv {uv}");
        assert_eq!(texel("glossy", 1.1), green, "uv {uv}");
        // The other part's paint lands where its triangles are, in its own texture only.
        assert_eq!(
            texel("painted", 0.1),
            grey,
            "uv {uv}: the glossy part's paint"
        );
        assert_eq!(
            texel("glossy", 1.9),
            grey,
            "uv {uv}: the painted part's paint"
        );
        assert!(dir.join(format!("preview-uv{uv}.png")).exists(), "uv {uv}");
        assert!(dir.join(format!("out_{uv}.glb")).exists(), "uv {uv}");
    }
    assert!(!dir.join("preview.png").exists());
    // The same job through `decalbake batch`.
    std::fs::write(
        dir.join("manifest.jsonl"),
        format!("{:?}\n", path.file_name().unwrap().to_str().unwrap()),
    )
    .unwrap();
    let out = dir.join("batch");
    let manifest = dir.join("manifest.jsonl");
    let (code, _, err) = common::cli(&[
        "batch",
        manifest.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let dirs: Vec<_> = std::fs::read_dir(&out)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.is_dir())
        .collect();
    assert_eq!(dirs.len(), 1, "one folder for the job: {dirs:?}");
    let job_dir = &dirs[0];
    for name in [
        "baked_0_painted.png",
        "baked_0_glossy.png",
        "baked_1_painted.png",
        "baked_1_glossy.png",
        "preview-uv0.png",
        "preview-uv1.png",
    ] {
        assert_eq!(
            std::fs::read(job_dir.join(name)).unwrap(),
            std::fs::read(dir.join(name)).unwrap(),
            "{name}: the batch bakes what bake bakes"
        );
    }
}
