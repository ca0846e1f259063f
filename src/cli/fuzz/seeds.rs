// SPDX-License-Identifier: MIT OR Apache-2.0
//! The fuzzer's seeds, made in code so that it needs no files: small valid inputs for each target.
//!
//! - **Jobs**: every layer kind and field of the job-file and stroke chapters (docs/): decals at
//!   points and rays with each method and its own fields, every blend mode, masks, strokes with each
//!   tool and every stroke field, `uv_set` as a number, `"auto"` and a list, every `texture.base`
//!   form (material, image, colour, transfer from the material or an image), padding as texels and
//!   `"full"`, the sample counts, outputs switched off and 16-bit; and sizes at the edges (empty,
//!   huge and overflowing sides, odd tiles, `max_memory` as bytes and text).
//! - **Manifests**: job paths, inline jobs, blank and `\r\n` lines.
//! - **glTF**: three small scenes, each as a `.glb` and as a `.gltf` with data URIs: (1) a node tree
//!   with TRS and matrix transforms over a quad with positions, normals, two UV sets, 16-bit indices
//!   and a base-colour PNG; (2) interleaved positions and normals (`byteStride`), normalized 16-bit
//!   UVs, 32-bit indices, `_PELT_BLEND` and a JPEG texture; (3) a sparse UV set without a buffer
//!   view, a sparse position accessor over one, 8-bit indices, a primitive without indices or
//!   normals, and a line primitive (skipped by the loader).
//! - **Images**: PNG 8-bit RGBA, grey and grey + alpha, 16-bit RGB and RGBA; JPEG colour and grey.

use super::mutate::{base64_encode, glb_build};
use image::ImageEncoder;
use serde_json::{json, Value};

/// The seed jobs (JSON values).
pub fn job_values() -> Vec<Value> {
    let decal = json!({"image": "logo.png", "at": [0.1, 0.5, 0.2], "size": [0.3, 0.3]});
    let blends: Vec<Value> = ["add", "darken", "lighten", "color_dodge", "normal"]
        .iter()
        .map(|b| json!({"image": "x.png", "at": [0, 0, 0], "size": [0.1, 0.1], "blend": b}))
        .collect();
    vec![
        json!({"mesh": "model.glb", "layers": [decal]}),
        // The job-file chapter's example: every top-level field.
        json!({
            "mesh": "model.glb", "uv_set": 0,
            "texture": {"width": 2048, "height": 2048, "base": "material", "padding": 16, "samples": 4},
            "layers": [{"kind": "decal", "image": "logo.png", "mask": null, "at": [0.1, 0.5, 0.2],
                "size": [0.3, 0.3], "angle": 0.0, "up": [0, 1, 0], "method": "planar",
                "blend": "normal", "opacity": 1.0}],
            "output": {"texture": "baked.png", "bit_depth": 8, "glb": "baked.glb",
                "report": "report.json", "preview": "preview.png"}
        }),
        // Each method with its own fields, rays, masks, blend names.
        json!({
            "mesh": "sub/model.gltf", "uv_set": "auto",
            "texture": {"width": 512, "height": 256, "base": [0.5, 0.25, 1.0, 1.0], "padding": "full", "samples": 9},
            "layers": [
                {"image": "a.png", "at": {"ray": {"origin": [0, 2, 0], "dir": [0, -1, 0]}}, "size": [0.2, 0.1],
                 "method": "planar", "depth": 0.05, "blend": "multiply", "opacity": 0.5, "angle": 45},
                {"image": "b.jpg", "mask": "m.png", "at": [0, 0, 1], "size": [1, 1], "method": "expmap",
                 "curvature_stop": 4.0, "accuracy": "fast", "blend": "color dodge", "up": [0, 0, 1]},
                {"image": "c.png", "at": [1, 0, 0], "size": [0.5, 0.5], "method": "lscm",
                 "cg_max_iterations": 200, "accuracy": "smooth", "blend": "Color-Burn"},
                {"image": "d.png", "at": [0, 1, 0], "size": [0.5, 0.7], "method": "hybrid",
                 "hybrid_threshold": 1.25, "blend": "overlay"}
            ],
            "output": {"texture": "out/t.png", "bit_depth": 16, "glb": null, "report": null, "preview": null}
        }),
        // Several UV sets and a transfer from the material.
        json!({
            "mesh": "spot-patch.glb", "uv_set": [1, 2],
            "texture": {"base": {"transfer": {"from_uv_set": 0, "image": "material"}}, "samples": 1},
            "layers": [{"image": "logo.png", "at": [0.1, 0.5, 0.2], "size": [0.3, 0.3], "blend": "screen"}],
            "output": {"texture": "baked_uv{uv}.png", "preview": "blended.png", "report": "r{uv}.json", "glb": "g.glb"}
        }),
        // A transfer from an image, an image base, every other blend mode.
        json!({
            "mesh": "m.glb", "uv_set": 1,
            "texture": {"base": {"transfer": {"from_uv_set": 2, "image": "old.png"}}, "padding": 0, "samples": 16},
            "layers": blends
        }),
        json!({"mesh": "m.glb", "texture": {"base": "base.png", "width": 1, "height": 1},
            "layers": [{"kind": "decal", "image": "x.png", "at": [0, 0, 0], "size": [1e6, 1e-6]}]}),
        // Strokes: each tool and every stroke field.
        json!({
            "mesh": "bob.glb",
            "layers": [
                {"kind": "stroke", "tool": "paint", "image": "dot.png", "mask": null,
                 "path": [[0.1, 0.5, 0.2], [0.12, 0.52, 0.21], {"ray": {"origin": [0, 2, 0], "dir": [0, -1, 0]}}],
                 "pressure": [0.2, 1.0, 0.6], "size": [0.05, 0.05], "spacing": 0.1, "flow": 1.0,
                 "opacity": 1.0, "pressure_size": 1.0, "pressure_flow": 0.0, "orient": "path",
                 "angle": 0.0, "up": [0, 1, 0], "method": "lscm", "continuity": true, "blend": "normal"},
                {"kind": "stroke", "tool": "blur", "image": "dot.png", "path": [[0, 0, 0], [1, 0, 0]],
                 "size": [0.1, 0.1], "radius": 0.02, "orient": "fixed", "method": "expmap"},
                {"kind": "stroke", "tool": "smear", "image": "dot.png", "path": [[0, 0, 0]],
                 "size": [0.1, 0.2], "strength": 0.7, "spacing": 0.5, "continuity": false, "method": "hybrid"},
                {"kind": "stroke", "tool": "clone", "image": "dot.png", "path": [[0, 0, 0], [0, 1, 0]],
                 "source": {"ray": {"origin": [1, 1, 1], "dir": [-1, -1, -1]}}, "size": [0.1, 0.1],
                 "flow": 0.5, "pressure_flow": 1.0, "method": "planar"}
            ]
        }),
        // A decal and a stroke with a mask together.
        json!({
            "mesh": "model.glb",
            "layers": [decal, {"kind": "stroke", "image": "dot.png", "mask": "mask.png",
                "path": [[0, 0, 0], [0.1, 0, 0], [0.2, 0, 0], [0.3, 0.1, 0]], "pressure": [0, 0.5, 1, 0.25],
                "size": [0.02, 0.02], "pressure_size": 0.5}]
        }),
    ]
}

/// Jobs at the edges of the sizes: empty, huge and overflowing sides, odd tiles, memory limits.
fn size_values() -> Vec<Value> {
    let decal = json!({"image": "logo.png", "at": [0.1, 0.5, 0.2], "size": [0.3, 0.3]});
    let texture = |t: Value| json!({"mesh": "m.glb", "texture": t, "layers": [decal.clone()]});
    let mut out: Vec<Value> = [
        json!({"width": 0, "height": 1}),
        json!({"width": 1_000_000, "height": 1_000_000}),
        json!({"width": 4_294_967_295u64, "height": 4_294_967_295u64}),
        json!({"width": 16384, "height": 16384, "tile": 64}),
        json!({"width": 16384, "height": 1, "tile": 3}),
    ]
    .into_iter()
    .map(texture)
    .collect();
    for limit in [json!(1), json!("1.5GiB"), json!("0.5k"), json!(u64::MAX)] {
        let mut j = texture(json!({"width": 8192, "height": 8192}));
        j["max_memory"] = limit;
        out.push(j);
    }
    out
}

/// The seed jobs as text (pretty and compact).
pub fn jobs() -> Vec<Vec<u8>> {
    job_values()
        .into_iter()
        .chain(size_values())
        .collect::<Vec<_>>()
        .iter()
        .enumerate()
        .map(|(i, v)| {
            if i % 2 == 0 {
                serde_json::to_vec_pretty(v)
            } else {
                serde_json::to_vec(v)
            }
            .expect("a JSON value serializes")
        })
        .collect()
}

/// The seed manifests.
pub fn manifests() -> Vec<Vec<u8>> {
    let inline: Vec<String> = job_values().iter().map(Value::to_string).collect();
    vec![
        format!("\"job.json\"\n{}\n\n\"sub/other.json\"\n", inline[0]),
        format!("{}\r\n{}\r\n  \r\n\"../up.json\"\r\n", inline[2], inline[6]),
        inline.join("\n"),
        "\"a.json\"\n\"b.json\"\n\"c d.json\"\n".to_string(),
    ]
    .into_iter()
    .map(String::into_bytes)
    .collect()
}

/// An encoded test image: a gradient with some noise, `channels` 1 to 4, 8 or 16 bits (PNG), or
/// JPEG (8-bit, 1 or 3 channels).
fn image_bytes(w: u32, h: u32, channels: usize, sixteen: bool, jpeg: bool) -> Vec<u8> {
    use image::ExtendedColorType as C;
    let mut samples = Vec::new();
    for y in 0..h {
        for x in 0..w {
            for c in 0..channels {
                let v = ((x * 37 + y * 91 + c as u32 * 53) % 256) as u16;
                samples.push(if sixteen { v * 257 + (x as u16 & 3) } else { v });
            }
        }
    }
    let mut out = Vec::new();
    if jpeg {
        let raw: Vec<u8> = samples.iter().map(|&v| v as u8).collect();
        let color = if channels == 1 { C::L8 } else { C::Rgb8 };
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, 80)
            .write_image(&raw, w, h, color)
            .expect("JPEG encoding into memory");
        return out;
    }
    let raw: Vec<u8> = if sixteen {
        samples.iter().flat_map(|v| v.to_ne_bytes()).collect()
    } else {
        samples.iter().map(|&v| v as u8).collect()
    };
    let color = match (channels, sixteen) {
        (1, false) => C::L8,
        (2, false) => C::La8,
        (3, false) => C::Rgb8,
        (4, false) => C::Rgba8,
        (1, true) => C::L16,
        (2, true) => C::La16,
        (3, true) => C::Rgb16,
        _ => C::Rgba16,
    };
    image::codecs::png::PngEncoder::new(&mut out)
        .write_image(&raw, w, h, color)
        .expect("PNG encoding into memory");
    out
}

/// The seed images.
pub fn images() -> Vec<Vec<u8>> {
    vec![
        image_bytes(5, 3, 4, false, false),
        image_bytes(4, 4, 1, false, false),
        image_bytes(3, 2, 2, true, false),
        image_bytes(2, 3, 3, true, false),
        image_bytes(2, 2, 4, true, false),
        image_bytes(8, 8, 3, false, true),
        image_bytes(9, 5, 1, false, true),
    ]
}

/// A glTF document under construction: its JSON and its one buffer.
struct Doc {
    json: Value,
    bin: Vec<u8>,
}

impl Doc {
    fn new() -> Self {
        Doc {
            json: json!({"asset": {"version": "2.0"}, "bufferViews": [], "accessors": []}),
            bin: Vec::new(),
        }
    }

    /// Appends `data` as a buffer view; its index.
    fn view(&mut self, data: &[u8], stride: Option<usize>) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let mut v = json!({"buffer": 0, "byteOffset": self.bin.len(), "byteLength": data.len()});
        if let Some(s) = stride {
            v["byteStride"] = json!(s);
        }
        self.bin.extend_from_slice(data);
        push(&mut self.json["bufferViews"], v)
    }

    /// Appends an accessor; its index.
    fn accessor(&mut self, a: Value) -> usize {
        push(&mut self.json["accessors"], a)
    }

    /// A tightly packed f32 accessor of `ty` over `values`.
    fn floats(&mut self, values: &[f32], ty: &str, min_max: bool) -> usize {
        let per = match ty {
            "SCALAR" => 1,
            "VEC2" => 2,
            _ => 3,
        };
        let view = self.view(bytemuck::cast_slice(values), None);
        let mut a = json!({"bufferView": view, "componentType": 5126, "count": values.len() / per, "type": ty});
        if min_max {
            let (mut lo, mut hi) = (vec![f32::MAX; per], vec![f32::MIN; per]);
            for c in values.chunks(per) {
                for k in 0..per {
                    lo[k] = lo[k].min(c[k]);
                    hi[k] = hi[k].max(c[k]);
                }
            }
            a["min"] = json!(lo);
            a["max"] = json!(hi);
        }
        self.accessor(a)
    }

    /// The document with a base-colour texture made of `image` (`mime`) in a buffer view.
    fn textured(&mut self, image: &[u8], mime: &str) {
        let view = self.view(image, None);
        self.json["images"] = json!([{"bufferView": view, "mimeType": mime}]);
        self.json["textures"] = json!([{"source": 0, "sampler": 0}]);
        self.json["samplers"] = json!([{"magFilter": 9729, "wrapS": 10497}]);
        self.json["materials"] = json!([{"pbrMetallicRoughness": {
            "baseColorTexture": {"index": 0, "texCoord": 0}, "baseColorFactor": [1, 0.9, 0.8, 1],
            "metallicFactor": 0.1, "roughnessFactor": 0.7}}]);
    }

    /// GLB bytes.
    fn glb(&self) -> Vec<u8> {
        let mut json = self.json.clone();
        json["buffers"] = json!([{"byteLength": self.bin.len()}]);
        glb_build(
            &[
                (*b"JSON", serde_json::to_vec(&json).expect("JSON")),
                (*b"BIN\0", self.bin.clone()),
            ],
            true,
        )
    }

    /// `.gltf` bytes: the buffer and the images as data URIs.
    fn gltf(&self) -> Vec<u8> {
        let mut json = self.json.clone();
        json["buffers"] = json!([{"byteLength": self.bin.len(),
            "uri": format!("data:application/octet-stream;base64,{}", base64_encode(&self.bin))}]);
        if let Some(images) = json["images"].as_array_mut() {
            for img in images {
                let view =
                    &self.json["bufferViews"][img["bufferView"].as_u64().unwrap_or(0) as usize];
                let (at, len) = (
                    view["byteOffset"].as_u64().unwrap_or(0) as usize,
                    view["byteLength"].as_u64().unwrap_or(0) as usize,
                );
                let mime = img["mimeType"].as_str().unwrap_or("image/png").to_string();
                *img = json!({"uri": format!("data:{mime};base64,{}", base64_encode(&self.bin[at..at + len]))});
            }
        }
        serde_json::to_vec_pretty(&json).expect("JSON")
    }
}

fn push(arr: &mut Value, v: Value) -> usize {
    let a = arr.as_array_mut().expect("an array");
    a.push(v);
    a.len() - 1
}

/// Scene 1: a node tree with TRS and matrix transforms over a textured quad (two UV sets, u16
/// indices).
fn scene_tree() -> Doc {
    let mut d = Doc::new();
    let pos = [
        0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0, 2.0, 0.5, 0.2,
    ];
    let nrm = [
        0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.3, 0.9,
    ];
    let uv0 = [0.0, 0.0, 0.5, 0.0, 0.5, 0.5, 0.0, 0.5, 0.6, 0.6, 0.9, 0.8];
    let uv1 = [0.1, 0.1, 0.9, 0.1, 0.9, 0.9, 0.1, 0.9, 0.5, 0.5, 0.7, 0.7];
    let p = d.floats(&pos, "VEC3", true);
    let n = d.floats(&nrm, "VEC3", false);
    let t0 = d.floats(&uv0, "VEC2", false);
    let t1 = d.floats(&uv1, "VEC2", false);
    let idx: [u16; 9] = [0, 1, 2, 0, 2, 3, 2, 4, 5];
    let iv = d.view(bytemuck::cast_slice(&idx), None);
    let i =
        d.accessor(json!({"bufferView": iv, "componentType": 5123, "count": 9, "type": "SCALAR"}));
    d.textured(&image_bytes(4, 4, 4, false, false), "image/png");
    d.json["meshes"] = json!([{"primitives": [{"attributes": {"POSITION": p, "NORMAL": n,
        "TEXCOORD_0": t0, "TEXCOORD_1": t1}, "indices": i, "material": 0, "mode": 4}]}]);
    d.json["nodes"] = json!([
        {"children": [1, 2], "translation": [0.5, 0, 0], "rotation": [0, 0.6, 0, 0.8], "scale": [2, 2, 2]},
        {"mesh": 0},
        {"mesh": 0, "matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, -1, 0, 0, 0, 3, 1]}
    ]);
    d.json["scenes"] = json!([{"nodes": [0]}]);
    d.json["scene"] = json!(0);
    d
}

/// Scene 2: interleaved positions and normals, normalized u16 UVs, u32 indices, `_PELT_BLEND`, a
/// JPEG texture.
fn scene_interleaved() -> Doc {
    let mut d = Doc::new();
    let verts: [[f32; 3]; 4] = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ];
    let mut inter: Vec<f32> = Vec::new();
    for v in verts {
        inter.extend_from_slice(&v);
        inter.extend_from_slice(&[0.577, 0.577, 0.577]);
    }
    let view = d.view(bytemuck::cast_slice(&inter), Some(24));
    let p = d.accessor(
        json!({"bufferView": view, "byteOffset": 0, "componentType": 5126, "count": 4,
        "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 1]}),
    );
    let n = d.accessor(json!({"bufferView": view, "byteOffset": 12, "componentType": 5126, "count": 4, "type": "VEC3"}));
    let uv: [u16; 8] = [0, 0, 65535, 0, 0, 65535, 32768, 32768];
    let uvv = d.view(bytemuck::cast_slice(&uv), None);
    let t = d.accessor(json!({"bufferView": uvv, "componentType": 5123, "normalized": true, "count": 4, "type": "VEC2"}));
    let b = d.floats(&[0.0, 0.25, 0.75, 1.0], "SCALAR", false);
    let idx: [u32; 12] = [0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3];
    let iv = d.view(bytemuck::cast_slice(&idx), None);
    let i =
        d.accessor(json!({"bufferView": iv, "componentType": 5125, "count": 12, "type": "SCALAR"}));
    d.textured(&image_bytes(8, 8, 3, false, true), "image/jpeg");
    d.json["meshes"] = json!([{"primitives": [{"attributes": {"POSITION": p, "NORMAL": n,
        "TEXCOORD_0": t, "_PELT_BLEND": b}, "indices": i, "material": 0}]}]);
    d.json["nodes"] = json!([{"mesh": 0}]);
    d.json["scenes"] = json!([{"nodes": [0]}]);
    d
}

/// Scene 3: sparse accessors (one without a buffer view), u8 indices, a primitive without indices
/// or normals, a line primitive.
fn scene_sparse() -> Doc {
    let mut d = Doc::new();
    let pos = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0];
    let base = d.view(bytemuck::cast_slice(&pos), None);
    let sp_idx = d.view(&[3u8, 0, 0, 0], None);
    let sp_val = d.view(bytemuck::cast_slice(&[1.0f32, 1.0, 0.5]), None);
    let p = d.accessor(
        json!({"bufferView": base, "componentType": 5126, "count": 4, "type": "VEC3",
        "min": [0, 0, 0], "max": [1, 1, 0.5],
        "sparse": {"count": 1, "indices": {"bufferView": sp_idx, "componentType": 5121},
                   "values": {"bufferView": sp_val}}}),
    );
    let uv_idx = d.view(bytemuck::cast_slice(&[1u16, 2]), None);
    let uv_val = d.view(bytemuck::cast_slice(&[1.0f32, 0.0, 0.0, 1.0]), None);
    let t = d.accessor(json!({"componentType": 5126, "count": 4, "type": "VEC2",
        "sparse": {"count": 2, "indices": {"bufferView": uv_idx, "componentType": 5123},
                   "values": {"bufferView": uv_val}}}));
    let iv = d.view(&[0u8, 1, 2, 2, 1, 3], None);
    let i =
        d.accessor(json!({"bufferView": iv, "componentType": 5121, "count": 6, "type": "SCALAR"}));
    let tri = d.floats(&[0.0, 0.0, 2.0, 1.0, 0.0, 2.0, 0.0, 1.0, 2.0], "VEC3", true);
    d.json["meshes"] = json!([{"primitives": [
        {"attributes": {"POSITION": p, "TEXCOORD_0": t}, "indices": i},
        {"attributes": {"POSITION": tri}},
        {"attributes": {"POSITION": p}, "mode": 1}
    ]}]);
    d.json["nodes"] = json!([{"mesh": 0, "name": "sparse"}]);
    d.json["scenes"] = json!([{"nodes": [0]}]);
    d
}

/// The seed `.glb` files.
pub fn glbs() -> Vec<Vec<u8>> {
    [scene_tree(), scene_interleaved(), scene_sparse()]
        .iter()
        .map(Doc::glb)
        .collect()
}

/// The seed `.gltf` files (data URIs).
pub fn gltfs() -> Vec<Vec<u8>> {
    [scene_tree(), scene_interleaved(), scene_sparse()]
        .iter()
        .map(Doc::gltf)
        .collect()
}

/// Every object key in `v` (the structure-aware mutations add and rename keys from these).
pub fn keys_of(v: &Value, out: &mut std::collections::BTreeSet<String>) {
    match v {
        Value::Object(m) => {
            for (k, x) in m {
                out.insert(k.clone());
                keys_of(x, out);
            }
        }
        Value::Array(a) => a.iter().for_each(|x| keys_of(x, out)),
        _ => {}
    }
}
