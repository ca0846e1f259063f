// SPDX-License-Identifier: MIT OR Apache-2.0
//! A model with what real files carry, written from code (`.gltf` + `.bin` + an external PNG and a
//! data-URI PNG), and the readers the document tests compare models with.
//!
//! The model: a skinned plane of two primitives (materials "painted", textured, and "glossy",
//! untextured with `KHR_materials_emissive_strength`), a third primitive without UVs ("trim"),
//! each with a morph target; POSITION and NORMAL interleaved in one view, normalised unsigned
//! short UVs on one primitive; a skin of two joints, an animation of a joint's rotation and of the
//! morph weights, a camera, a `KHR_lights_punctual` light, a mirrored node (scale -1) drawing a
//! second mesh, a sampler, `KHR_texture_transform` (required) on the normal texture, and `extras`
//! on the asset, a node, a mesh and a material.

use serde_json::{json, Value};
use std::path::{Path, PathBuf};

struct Bin {
    bytes: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Bin {
    fn view(&mut self, data: &[u8], target: Option<u32>, stride: Option<usize>) -> usize {
        while !self.bytes.len().is_multiple_of(4) {
            self.bytes.push(0);
        }
        let mut v = json!({"buffer": 0, "byteOffset": self.bytes.len(), "byteLength": data.len()});
        if let Some(t) = target {
            v["target"] = json!(t);
        }
        if let Some(s) = stride {
            v["byteStride"] = json!(s);
        }
        self.bytes.extend_from_slice(data);
        self.views.push(v);
        self.views.len() - 1
    }
    fn accessor(&mut self, a: Value) -> usize {
        self.accessors.push(a);
        self.accessors.len() - 1
    }
    fn f32s(
        &mut self,
        data: &[f32],
        ty: &str,
        n: usize,
        target: Option<u32>,
        minmax: bool,
    ) -> usize {
        let v = self.view(bytemuck::cast_slice(data), target, None);
        let mut a =
            json!({"bufferView": v, "componentType": 5126, "count": data.len() / n, "type": ty});
        if minmax {
            let (lo, hi) = min_max(data, n);
            a["min"] = json!(lo);
            a["max"] = json!(hi);
        }
        self.accessor(a)
    }
}

fn min_max(data: &[f32], n: usize) -> (Vec<f32>, Vec<f32>) {
    let mut lo = vec![f32::MAX; n];
    let mut hi = vec![f32::MIN; n];
    for e in data.chunks(n) {
        for c in 0..n {
            lo[c] = lo[c].min(e[c]);
            hi[c] = hi[c].max(e[c]);
        }
    }
    (lo, hi)
}

/// A grid of `nx` × `ny` quads over x in `x0..x1`, y in `0..1` at z = 0: positions, UVs (u over
/// `u0..u1`) and triangles.
fn grid(
    nx: u32,
    ny: u32,
    (x0, x1): (f32, f32),
    (u0, u1): (f32, f32),
) -> (Vec<[f32; 3]>, Vec<[f32; 2]>, Vec<u16>) {
    let mut p = Vec::new();
    let mut uv = Vec::new();
    for j in 0..=ny {
        for i in 0..=nx {
            let (s, t) = (i as f32 / nx as f32, j as f32 / ny as f32);
            p.push([x0 + s * (x1 - x0), t, 0.0]);
            uv.push([u0 + s * (u1 - u0), 1.0 - t]);
        }
    }
    let mut idx = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            let a = (j * (nx + 1) + i) as u16;
            let b = a + 1;
            let c = a + (nx + 1) as u16;
            let d = c + 1;
            idx.extend_from_slice(&[a, b, d, a, d, c]);
        }
    }
    (p, uv, idx)
}

/// A flat-normal PNG of `w` × `h` texels (`rgb` everywhere).
fn png(w: u32, h: u32, rgb: [u8; 3]) -> Vec<u8> {
    let px: Vec<u16> = (0..w * h)
        .flat_map(|_| [rgb[0] as u16, rgb[1] as u16, rgb[2] as u16, 255])
        .collect();
    decalbake::io::image::png_bytes(w, h, 8, &px)
}

/// Writes the model into `dir` (`rich.gltf`, `rich.bin`, `albedo.png`) and returns its path.
pub fn write_rich_gltf(dir: &Path) -> PathBuf {
    write_rich(dir, false)
}

/// The model with the second primitive's UVs laid over the first's (`u` in 0..0.5 both).
pub fn write_rich_overlapping(dir: &Path) -> PathBuf {
    write_rich(dir, true)
}

fn write_rich(dir: &Path, overlap: bool) -> PathBuf {
    let mut bin = Bin {
        bytes: Vec::new(),
        views: Vec::new(),
        accessors: Vec::new(),
    };
    let mut primitives = Vec::new();
    let parts = [
        ((0.0, 1.0), Some((0.0, 0.5)), 0, false),
        (
            (1.0, 2.0),
            Some(if overlap { (0.0, 0.5) } else { (0.5, 1.0) }),
            1,
            true,
        ),
        ((2.0, 2.25), None, 2, false),
    ];
    for ((x0, x1), u, material, short_uv) in parts {
        let (p, uv, idx) = grid(
            if u.is_some() { 6 } else { 1 },
            6,
            (x0, x1),
            u.unwrap_or((0.0, 1.0)),
        );
        let n = p.len();
        // POSITION and NORMAL interleaved.
        let mut inter: Vec<f32> = Vec::new();
        for q in &p {
            inter.extend_from_slice(q);
            inter.extend_from_slice(&[0.0, 0.0, 1.0]);
        }
        let v = bin.view(bytemuck::cast_slice(&inter), Some(34962), Some(24));
        let flat: Vec<f32> = p.iter().flatten().copied().collect();
        let (lo, hi) = min_max(&flat, 3);
        let pos = bin.accessor(json!({"bufferView": v, "componentType": 5126, "count": n, "type": "VEC3", "min": lo, "max": hi}));
        let nrm = bin.accessor(json!({"bufferView": v, "byteOffset": 12, "componentType": 5126, "count": n, "type": "VEC3"}));
        let mut attributes = json!({"POSITION": pos, "NORMAL": nrm});
        if u.is_some() {
            attributes["TEXCOORD_0"] = json!(if short_uv {
                let q: Vec<u16> = uv
                    .iter()
                    .flatten()
                    .map(|&x| (x * 65535.0).round() as u16)
                    .collect();
                let v = bin.view(bytemuck::cast_slice(&q), Some(34962), None);
                bin.accessor(json!({"bufferView": v, "componentType": 5123, "normalized": true, "count": n, "type": "VEC2"}))
            } else {
                let f: Vec<f32> = uv.iter().flatten().copied().collect();
                bin.f32s(&f, "VEC2", 2, Some(34962), false)
            });
        }
        let joints: Vec<u8> = p
            .iter()
            .flat_map(|q| {
                if q[1] > 0.5 {
                    [1, 0, 0, 0]
                } else {
                    [0, 1, 0, 0]
                }
            })
            .collect();
        let v = bin.view(&joints, Some(34962), None);
        attributes["JOINTS_0"] = json!(bin
            .accessor(json!({"bufferView": v, "componentType": 5121, "count": n, "type": "VEC4"})));
        let weights: Vec<f32> = p
            .iter()
            .flat_map(|q| [0.5 + 0.5 * q[1], 0.5 - 0.5 * q[1], 0.0, 0.0])
            .collect();
        attributes["WEIGHTS_0"] = json!(bin.f32s(&weights, "VEC4", 4, Some(34962), false));
        let delta: Vec<f32> = p
            .iter()
            .flat_map(|q| [0.0, 0.0, 0.1 * q[0] * q[1]])
            .collect();
        let target = bin.f32s(&delta, "VEC3", 3, Some(34962), true);
        let v = bin.view(bytemuck::cast_slice(&idx), Some(34963), None);
        let indices = bin.accessor(
            json!({"bufferView": v, "componentType": 5123, "count": idx.len(), "type": "SCALAR"}),
        );
        primitives.push(
            json!({"attributes": attributes, "indices": indices, "material": material,
            "targets": [{"POSITION": target}], "extras": {"part": material}}),
        );
    }
    // The mirrored badge: a quad of its own mesh.
    let (p, uv, idx) = grid(2, 2, (0.2, 0.6), (0.1, 0.4));
    let flat: Vec<f32> = p.iter().flatten().copied().collect();
    let pos = bin.f32s(&flat, "VEC3", 3, Some(34962), true);
    let f: Vec<f32> = uv.iter().flatten().copied().collect();
    let tex = bin.f32s(&f, "VEC2", 2, Some(34962), false);
    let v = bin.view(bytemuck::cast_slice(&idx), Some(34963), None);
    let badge_idx = bin.accessor(
        json!({"bufferView": v, "componentType": 5123, "count": idx.len(), "type": "SCALAR"}),
    );
    // Skin and animation.
    let ibm: Vec<f32> = [[0.0f32, 0.0, 0.0], [0.0, -0.5, 0.0]]
        .iter()
        .flat_map(|t| {
            [
                1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, t[0], t[1], t[2], 1.0,
            ]
        })
        .collect();
    let ibm = bin.f32s(&ibm, "MAT4", 16, None, false);
    let times = bin.f32s(&[0.0, 1.0], "SCALAR", 1, None, true);
    let h = std::f32::consts::FRAC_1_SQRT_2;
    let rot = bin.f32s(
        &[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, h, h],
        "VEC4",
        4,
        None,
        false,
    );
    let wts = bin.f32s(&[0.0, 1.0], "SCALAR", 1, None, false);
    while !bin.bytes.len().is_multiple_of(4) {
        bin.bytes.push(0);
    }
    std::fs::write(dir.join("rich.bin"), &bin.bytes).unwrap();
    std::fs::write(dir.join("albedo.png"), png(32, 32, [200, 120, 40])).unwrap();
    let normal_uri = format!(
        "data:image/png;base64,{}",
        base64::encode(png(8, 8, [128, 128, 255]))
    );
    let doc = json!({
        "asset": {"version": "2.0", "generator": "decalbake tests", "extras": {"origin": "written by tests/common/rich.rs"}},
        "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_emissive_strength", "KHR_texture_transform"],
        "extensionsRequired": ["KHR_texture_transform"],
        "extensions": {"KHR_lights_punctual": {"lights": [{"type": "point", "color": [1.0, 0.9, 0.8], "intensity": 20.0}]}},
        "scene": 0,
        "scenes": [{"name": "stage", "nodes": [0, 1, 4, 5, 6]}],
        "nodes": [
            {"name": "rig", "translation": [0.0, 0.0, 0.0], "children": [2]},
            {"name": "body", "mesh": 0, "skin": 0, "extras": {"tag": "skinned"}},
            {"name": "bone_a", "translation": [0.0, 0.0, 0.0], "children": [3]},
            {"name": "bone_b", "translation": [0.0, 0.5, 0.0], "rotation": [0.0, 0.0, 0.0, 1.0]},
            {"name": "camera", "camera": 0, "translation": [1.0, 0.5, 3.0]},
            {"name": "lamp", "translation": [1.0, 2.0, 1.0], "extensions": {"KHR_lights_punctual": {"light": 0}}},
            {"name": "mirror", "mesh": 1, "scale": [-1.0, 1.0, 1.0], "translation": [0.0, 0.0, 0.5]}
        ],
        "meshes": [
            {"name": "plane", "primitives": primitives, "weights": [0.0], "extras": {"lod": 0}},
            {"name": "badge", "primitives": [{"attributes": {"POSITION": pos, "TEXCOORD_0": tex}, "indices": badge_idx, "material": 0}]}
        ],
        "skins": [{"name": "skeleton", "joints": [2, 3], "inverseBindMatrices": ibm, "skeleton": 0}],
        "animations": [{"name": "wave", "samplers": [
            {"input": times, "output": rot, "interpolation": "LINEAR"},
            {"input": times, "output": wts, "interpolation": "STEP"}],
            "channels": [
            {"sampler": 0, "target": {"node": 3, "path": "rotation"}},
            {"sampler": 1, "target": {"node": 1, "path": "weights"}}]}],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.01, "zfar": 100.0, "aspectRatio": 1.5}}],
        "materials": [
            {"name": "painted", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0.0},
             "normalTexture": {"index": 1, "scale": 0.8, "extensions": {"KHR_texture_transform": {"scale": [2.0, 2.0]}}},
             "extras": {"note": "kept"}},
            {"name": "glossy", "pbrMetallicRoughness": {"baseColorFactor": [0.2, 0.4, 0.8, 1.0], "roughnessFactor": 0.2},
             "emissiveFactor": [1.0, 0.5, 0.0], "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 4.0}}},
            {"name": "trim", "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1.0]}, "doubleSided": true}
        ],
        "textures": [{"source": 0, "sampler": 0}, {"source": 1}],
        "samplers": [{"magFilter": 9728, "minFilter": 9728, "wrapS": 33071, "wrapT": 33071}],
        "images": [{"uri": "albedo.png", "name": "albedo"}, {"uri": normal_uri, "name": "normal"}],
        "buffers": [{"uri": "rich.bin", "byteLength": bin.bytes.len()}],
        "bufferViews": bin.views,
        "accessors": bin.accessors,
    });
    let path = dir.join("rich.gltf");
    std::fs::write(&path, serde_json::to_vec_pretty(&doc).unwrap()).unwrap();
    path
}

/// A model's JSON and its buffers (a `.glb`'s BIN chunk, or a `.gltf`'s files and data URIs).
pub fn read_model(path: &Path) -> (Value, Vec<Vec<u8>>) {
    let bytes = std::fs::read(path).unwrap();
    if bytes.starts_with(b"glTF") {
        let n = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
        let json: Value = serde_json::from_slice(&bytes[20..20 + n]).unwrap();
        let bin = bytes
            .get(20 + n + 8..)
            .map(<[u8]>::to_vec)
            .unwrap_or_default();
        return (json, vec![bin]);
    }
    let json: Value = serde_json::from_slice(&bytes).unwrap();
    let dir = path.parent().unwrap();
    let buffers = json["buffers"]
        .as_array()
        .into_iter()
        .flatten()
        .map(|b| read_uri(dir, b["uri"].as_str().unwrap()))
        .collect();
    (json, buffers)
}

/// The bytes a URI names: a data URI's, or a file's beside the model.
pub fn read_uri(dir: &Path, uri: &str) -> Vec<u8> {
    match uri.split_once(";base64,") {
        Some((_, b64)) if uri.starts_with("data:") => base64::decode(b64).unwrap(),
        _ => std::fs::read(dir.join(uri)).unwrap(),
    }
}

/// The bytes of buffer view `v`.
pub fn view<'a>(json: &Value, buffers: &'a [Vec<u8>], v: usize) -> &'a [u8] {
    let view = &json["bufferViews"][v];
    let offset = view["byteOffset"].as_u64().unwrap_or(0) as usize;
    let len = view["byteLength"].as_u64().unwrap() as usize;
    &buffers[view["buffer"].as_u64().unwrap() as usize][offset..offset + len]
}

/// Accessor `a`'s elements, each a list of its components as numbers (no sparse accessors).
pub fn read_accessor(json: &Value, buffers: &[Vec<u8>], a: usize) -> Vec<Vec<f64>> {
    let acc = &json["accessors"][a];
    let count = acc["count"].as_u64().unwrap() as usize;
    let comp = acc["componentType"].as_u64().unwrap();
    let width = match acc["type"].as_str().unwrap() {
        "SCALAR" => 1,
        "VEC2" => 2,
        "VEC3" => 3,
        "VEC4" => 4,
        "MAT4" => 16,
        t => panic!("type {t}"),
    };
    let size = match comp {
        5120 | 5121 => 1,
        5122 | 5123 => 2,
        _ => 4,
    };
    let v = acc["bufferView"].as_u64().expect("a buffer view") as usize;
    let bytes = view(json, buffers, v);
    let stride = json["bufferViews"][v]["byteStride"]
        .as_u64()
        .map_or(width * size, |s| s as usize);
    let offset = acc["byteOffset"].as_u64().unwrap_or(0) as usize;
    (0..count)
        .map(|i| {
            (0..width)
                .map(|c| {
                    let b = &bytes[offset + i * stride + c * size..];
                    match comp {
                        5121 => b[0] as f64,
                        5123 => u16::from_le_bytes([b[0], b[1]]) as f64,
                        5125 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
                        _ => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
                    }
                })
                .collect()
        })
        .collect()
}

/// The JSON paths where `a` and `b` differ (`/key/0/...`), appended to `out`.
pub fn json_diff(a: &Value, b: &Value, path: &str, out: &mut Vec<String>) {
    decalbake::output::gltf::json_diff(a, b, path, out)
}

/// Runs the Khronos glTF-Validator (`tests/gltf/validate.js`, installed by `.ci/run`) on a model
/// (`.glb`, or `.gltf` with its files beside it); panics on errors. Without node or the package it
/// says so and checks nothing, except under CI, where it fails.
pub fn validate(model: &Path) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/gltf");
    let have = dir.join("node_modules/gltf-validator").exists()
        && std::process::Command::new("node")
            .arg("--version")
            .output()
            .is_ok();
    if !have {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI must install the glTF validator (.ci/run: npm install --prefix tests/gltf gltf-validator)"
        );
        eprintln!("glTF-Validator not installed (npm install --prefix tests/gltf gltf-validator): not run");
        return;
    }
    let out = std::process::Command::new("node")
        .arg(dir.join("validate.js"))
        .arg(model)
        .output()
        .expect("node runs");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && text.contains("\"errors\":0"),
        "{}: the glTF-Validator reports errors: {text} {}",
        model.display(),
        String::from_utf8_lossy(&out.stderr)
    );
}
