// SPDX-License-Identifier: MIT OR Apache-2.0
//! Writes a `.glb` copy of the model whose material's base colour is the baked texture (or, for
//! `decalbake unwrap`, the model's own base-colour texture).
//!
//! The copy holds the mesh as decalbake loaded it: one primitive with world-space positions (node
//! transforms applied), normals, every UV set and the triangles, plus the PNG embedded as the
//! base-colour texture on the UV set it belongs to. The metallic and roughness factors of the
//! source material are kept; other texture maps (normal, occlusion, emissive) are not copied.

use crate::mesh::Mesh;
use serde_json::json;

fn pad4(buf: &mut Vec<u8>, fill: u8) {
    while !buf.len().is_multiple_of(4) {
        buf.push(fill);
    }
}

/// Builds GLB bytes for `m` textured with `png` on UV set `uv_set` (untextured without a PNG), with
/// the custom attributes `_PELT_BLEND` and `_PELT_BRIDGE` when the mesh has them (`Mesh::blend`,
/// `Mesh::bridge`).
pub fn build_glb(m: &Mesh, png: Option<&[u8]>, uv_set: u32) -> Vec<u8> {
    let mut bin: Vec<u8> = Vec::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    let mut push_view = |bin: &mut Vec<u8>, data: &[u8], target: Option<u32>| -> usize {
        pad4(bin, 0);
        let offset = bin.len();
        bin.extend_from_slice(data);
        let mut v = json!({"buffer": 0, "byteOffset": offset, "byteLength": data.len()});
        if let Some(t) = target {
            v["target"] = json!(t);
        }
        views.push(v);
        views.len() - 1
    };
    let (lo, hi) = m.bounds();
    let pos: Vec<f32> = m.positions.iter().flat_map(|p| p.to_array()).collect();
    let v = push_view(&mut bin, bytemuck::cast_slice(&pos), Some(34962));
    accessors.push(
        json!({"bufferView": v, "componentType": 5126, "count": m.positions.len(), "type": "VEC3",
        "min": lo.to_array(), "max": hi.to_array()}),
    );
    let nrm: Vec<f32> = m
        .normals
        .iter()
        .flat_map(|p| p.normalize_or_zero().to_array())
        .collect();
    let v = push_view(&mut bin, bytemuck::cast_slice(&nrm), Some(34962));
    accessors.push(
        json!({"bufferView": v, "componentType": 5126, "count": m.normals.len(), "type": "VEC3"}),
    );
    let mut attributes = json!({"POSITION": 0, "NORMAL": 1});
    for (i, set) in m.uv_sets.iter().enumerate() {
        let uv: Vec<f32> = set.iter().flat_map(|u| u.to_array()).collect();
        let v = push_view(&mut bin, bytemuck::cast_slice(&uv), Some(34962));
        accessors.push(
            json!({"bufferView": v, "componentType": 5126, "count": set.len(), "type": "VEC2"}),
        );
        attributes[format!("TEXCOORD_{i}")] = json!(accessors.len() - 1);
    }
    for (name, w) in [("_PELT_BLEND", &m.blend), ("_PELT_BRIDGE", &m.bridge)] {
        if w.len() == m.positions.len() {
            let v = push_view(&mut bin, bytemuck::cast_slice(w), Some(34962));
            accessors.push(
                json!({"bufferView": v, "componentType": 5126, "count": w.len(), "type": "SCALAR"}),
            );
            attributes[name] = json!(accessors.len() - 1);
        }
    }
    let idx: Vec<u32> = m.triangles.iter().flatten().copied().collect();
    let v = push_view(&mut bin, bytemuck::cast_slice(&idx), Some(34963));
    accessors.push(
        json!({"bufferView": v, "componentType": 5125, "count": idx.len(), "type": "SCALAR"}),
    );
    let indices = accessors.len() - 1;
    let img_view = png.map(|png| push_view(&mut bin, png, None));
    pad4(&mut bin, 0);

    let (factor, metallic, roughness) = match &m.material {
        Some(mat) if mat.base_color_texture.is_some() => {
            (mat.base_color_factor, mat.metallic, mat.roughness)
        }
        Some(mat) => ([1.0; 4], mat.metallic, mat.roughness),
        None => ([1.0; 4], 0.0, 1.0),
    };
    let mut doc = json!({
        "asset": {"version": "2.0", "generator": concat!("decalbake ", env!("CARGO_PKG_VERSION"))},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "name": "baked"}],
        "meshes": [{"primitives": [{"attributes": attributes, "indices": indices, "material": 0, "mode": 4}]}],
        "materials": [{"name": "baked", "pbrMetallicRoughness": {
            "baseColorTexture": {"index": 0, "texCoord": uv_set},
            "baseColorFactor": factor, "metallicFactor": metallic, "roughnessFactor": roughness}}],
        "textures": [{"source": 0, "sampler": 0}],
        "samplers": [{"magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 10497}],
        "images": [{"bufferView": img_view, "mimeType": "image/png"}],
        "buffers": [{"byteLength": bin.len()}],
        "bufferViews": views,
        "accessors": accessors,
    });
    if img_view.is_none() {
        let doc = doc.as_object_mut().expect("an object");
        for key in ["textures", "samplers", "images"] {
            doc.remove(key);
        }
        let pbr = &mut doc["materials"][0]["pbrMetallicRoughness"];
        pbr.as_object_mut()
            .expect("an object")
            .remove("baseColorTexture");
        if let Some(mat) = &m.material {
            pbr["baseColorFactor"] = json!(mat.base_color_factor);
        }
    }
    let mut json_bytes = serde_json::to_vec(&doc).expect("serializing a JSON value cannot fail");
    pad4(&mut json_bytes, b' ');
    let total = 12 + 8 + json_bytes.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json_bytes.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json_bytes);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}
