// SPDX-License-Identifier: MIT OR Apache-2.0
//! The JSON Schemas of `decalbake schema`: every job in the repository and the docs validates
//! against the job schema, the schema and the loader refuse the same mistakes, the job-file
//! chapter names every field the schema has, and the command prints what the library generates.

mod common;
use common::{cli, scratch};
use decalbake::io::schema::{fields_markdown, schema, schema_text, Which};
use decalbake::Job;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn validator(which: Which) -> jsonschema::Validator {
    jsonschema::validator_for(&schema(which)).expect("the generated schema is a valid schema")
}

/// Every error the schema finds in `job`, as "path: message" lines.
fn schema_errors(v: &jsonschema::Validator, job: &Value) -> Vec<String> {
    v.iter_errors(job)
        .map(|e| format!("{}: {e}", e.instance_path()))
        .collect()
}

/// The fenced ```json blocks of a markdown file, with their first line numbers.
fn json_blocks(md: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    let mut open: Option<(usize, String)> = None;
    for (i, line) in md.lines().enumerate() {
        let fence = line.trim_start();
        match &mut open {
            None if fence.starts_with("```json") && fence.trim_end() == "```json" => {
                open = Some((i + 2, String::new()))
            }
            Some((start, text)) if fence.starts_with("```") => {
                out.push((*start, std::mem::take(text)));
                open = None;
            }
            Some((_, text)) => {
                text.push_str(line);
                text.push('\n');
            }
            None => {}
        }
    }
    out
}

/// README.md, the guide's chapters and the examples' notes: every markdown file of the project.
fn markdown_files() -> Vec<PathBuf> {
    let mut files = vec![root().join("README.md")];
    let mut docs: Vec<PathBuf> = std::fs::read_dir(root().join("docs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    docs.sort();
    files.extend(docs);
    files
}

/// Job files in the repository: `*.json` files outside `target/`, `.git/` and `node_modules/`
/// whose top level names a `mesh`. Today the jobs live in the docs (checked above) and in code;
/// a job file added to the repository is checked here.
fn job_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        if path.is_dir() {
            if !matches!(name.as_str(), "target" | ".git" | "node_modules") {
                job_files(&path, out);
            }
        } else if name.ends_with(".json") {
            let text = std::fs::read_to_string(&path).unwrap();
            if serde_json::from_str::<Value>(&text).is_ok_and(|v| v.get("mesh").is_some()) {
                out.push(path);
            }
        }
    }
}

#[test]
fn every_job_in_the_docs_and_the_repository_validates() {
    let v = validator(Which::Job);
    let (mut checked, mut readme_jobs) = (0, 0);
    for file in markdown_files() {
        let text = std::fs::read_to_string(&file).unwrap();
        for (line, block) in json_blocks(&text) {
            let here = format!("{}:{line}", file.display());
            let job: Value = serde_json::from_str(&block).unwrap_or_else(|e| {
                panic!("{here}: a ```json block that is not JSON ({e}); use ```jsonc or ```text for sketches")
            });
            if job.get("mesh").is_none() {
                continue; // a fragment (a layer, a report): shown, not a job
            }
            let errors = schema_errors(&v, &job);
            assert!(errors.is_empty(), "{here}: {errors:#?}");
            checked += 1;
        }
        if file.ends_with("README.md") {
            readme_jobs = checked;
        }
    }
    let mut files = Vec::new();
    job_files(root(), &mut files);
    for file in &files {
        let job: Value = serde_json::from_slice(&std::fs::read(file).unwrap()).unwrap();
        let errors = schema_errors(&v, &job);
        assert!(errors.is_empty(), "{}: {errors:#?}", file.display());
        checked += 1;
    }
    assert!(
        readme_jobs >= 1,
        "README.md's minimal job should be a ```json block the scan finds"
    );
    assert!(checked > readme_jobs, "no job found in docs/");
}

/// A job the loader accepts, with a layer of each kind, as the base of the mutations below.
fn base_job() -> Value {
    json!({
        "$schema": "job.schema.json",
        "mesh": "spot.glb",
        "uv_set": "auto",
        "max_memory": "2GiB",
        "texture": { "width": 256, "height": 128, "base": [0.5, 0.5, 0.5, 1.0], "padding": "full",
                     "samples": 9, "sets": { "0": { "width": 64 } } },
        "layers": [
            { "kind": "decal", "image": "d.png", "at": { "ray": { "origin": [1.5, 0, 0.45], "dir": [-1, 0, 0] } },
              "size": [0.3, 0.3], "method": "hybrid", "blend": "Color Dodge", "roughness": 0.4,
              "emissive": [1.0, 0.5, 0.0], "warp": [[[0.5, 0.5], [0.55, 0.5]]] },
            { "kind": "stroke", "image": "d.png", "tool": "smear", "strength": 0.5, "size": [0.1, 0.1],
              "path": [[0, 0, 0], { "ray": { "origin": [0, 2, 0], "dir": [0, -1, 0] } }],
              "pressure": [0.2, 1.0], "orient": "fixed" },
            { "kind": "ribbon", "image": "d.png", "width": 0.1, "repeat": "tile", "align": "left",
              "animate": { "route": [[0, 0, 0], [0, 0.5, 0]], "frames": 4, "length": 0.2 } }
        ],
        "output": { "texture": "out_{set}_{channel}_{frame:04}.png", "bit_depth": 16, "compression": "small",
                    "glb": null, "preview": null }
    })
}

#[test]
fn the_schema_and_the_loader_refuse_the_same_mistakes() {
    let dir = scratch("schema-mistakes");
    let image = common::test_image(8, 8, 1, true).encode_png(8);
    std::fs::write(dir.join("d.png"), image).unwrap();
    let v = validator(Which::Job);
    let load = |job: &Value| Job::parse(&job.to_string(), &dir.join("job.json"), &dir, &dir);
    let base = base_job();
    assert_eq!(schema_errors(&v, &base), Vec::<String>::new());
    load(&base).expect("the base job loads");

    // (what changes, the field the loader names)
    type Mutation = fn(&mut Value);
    let mistakes: [(Mutation, &str); 11] = [
        (|j| j["colour"] = json!(1), "colour"),
        (|j| j["texture"]["widht"] = json!(64), "widht"),
        (|j| j["layers"][0]["sise"] = json!([1, 1]), "sise"),
        (|j| j["output"]["png"] = json!("x.png"), "png"),
        (|j| j["layers"][1]["tool"] = json!("smudge"), "smudge"),
        (
            |j| j["layers"][0]["method"] = json!("cylindrical"),
            "cylindrical",
        ),
        (
            |j| j["output"]["compression"] = json!("best"),
            "compression",
        ),
        (|j| j["texture"]["width"] = json!("wide"), "texture.width"),
        (|j| j["layers"][2]["animate"]["loop"] = json!(true), "loop"),
        // Inside the object forms of untagged fields: a ray's placement, a transferred base.
        (
            |j| j["layers"][0]["at"]["sise"] = json!([1, 1]),
            "layers[0].at",
        ),
        (
            |j| j["texture"]["base"] = json!({ "transfer": { "from_uv_set": 0 }, "uv": 1 }),
            "texture.base",
        ),
    ];
    for (mutate, field) in mistakes {
        let mut job = base.clone();
        mutate(&mut job);
        let errors = schema_errors(&v, &job);
        assert!(
            !errors.is_empty(),
            "the schema accepts a job with {field} wrong"
        );
        let e = load(&job).expect_err(field).to_string();
        assert!(
            e.contains(field),
            "the loader's message should name {field}: {e}"
        );
    }
}

#[test]
fn a_manifest_line_is_a_path_or_a_job() {
    let v = validator(Which::Manifest);
    assert!(v.is_valid(&json!("jobs/a.json")));
    assert!(v.is_valid(&base_job()));
    assert!(!v.is_valid(&json!(42)));
    assert!(!v.is_valid(&json!({ "mesh": "m.glb", "layer": [] })));
}

/// The lines between `<!-- fields -->` and `<!-- /fields -->` in `docs/job-file.md`.
fn chapter_index() -> String {
    let chapter = std::fs::read_to_string(root().join("docs/job-file.md")).unwrap();
    let (_, after) = chapter
        .split_once("<!-- fields -->\n")
        .expect("docs/job-file.md has a <!-- fields --> index");
    let (index, _) = after
        .split_once("<!-- /fields -->")
        .expect("... and its end");
    index.to_string()
}

#[test]
fn the_job_file_chapter_indexes_every_field_of_the_schema() {
    let index = fields_markdown();
    // The index walks into every object: a layer's fields, a ray's, a transfer's.
    for field in [
        "layers[].tool",
        "layers[].at",
        "texture.base",
        "output.compression",
    ] {
        assert!(
            index.contains(&format!("| `{field}` |")),
            "{field} missing:\n{index}"
        );
    }
    for field in ["origin`", "from_uv_set`", "animate.route`", "texture.sets"] {
        assert!(index.contains(field), "{field} missing:\n{index}");
    }
    assert!(index.lines().count() > 70, "{index}");
    assert!(
        chapter_index() == index,
        "docs/job-file.md's field index is not the schema's: replace it with the output of \
         `cargo run -- schema job --fields`"
    );
}

#[test]
fn the_command_prints_the_schema_the_library_generates() {
    for (name, which) in [("job", Which::Job), ("manifest", Which::Manifest)] {
        let (code, stdout, stderr) = cli(&["schema", name]);
        assert_eq!(code, 0, "{stderr}");
        assert_eq!(stdout, schema_text(which));
    }
    let (code, _, stderr) = cli(&["schema", "layer"]);
    assert_eq!(code, 2, "an unknown schema is a usage error: {stderr}");
    let (code, stdout, _) = cli(&["schema", "job", "--fields"]);
    assert_eq!((code, stdout), (0, fields_markdown()));
    let (code, _, stderr) = cli(&["schema", "manifest", "--fields"]);
    assert!(
        code == 2 && stderr.contains("schema job --fields"),
        "{stderr}"
    );
}
