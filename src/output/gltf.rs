// SPDX-License-Identifier: MIT OR Apache-2.0
//! Writes the model back as it came in: the document it was loaded from ([`Mesh::document`]) with
//! only the bake's changes, as a `.glb` or as a `.gltf` with its `.bin` and image files (chosen by
//! the output's extension).
//!
//! Every node, mesh, primitive (attributes, morph targets, modes), skin, animation, camera,
//! material, texture, sampler, image, extension and `extras` is the source's JSON, untouched
//! except where the bake changes it:
//! - the baked base colour replaces the image it was baked from ([`BakedColor`]), or is added as
//!   an image and texture that the painted materials reference;
//! - baked PBR channels are added as images and textures that the materials showing the bake
//!   reference (`gltf/channels.rs`);
//! - UV sets made since loading ([`Mesh::new_uv_sets`], by pelting) are added to the primitives as
//!   `TEXCOORD_n` (with `_PELT_BLEND` / `_PELT_BRIDGE` when the mesh has them); where pelting split
//!   or reordered vertices ([`Mesh::vertex_origin`]) every attribute and morph target of the
//!   primitive is gathered anew and its indices rewritten: the mesh is never flattened, and a
//!   skinned primitive keeps its joints and weights;
//! - the buffers are packed into one (each buffer view's bytes in order, 4-byte aligned), with
//!   the images embedded in a `.glb`.
//!
//! A mesh made in code (no document) gets a new document of one node and one primitive.

use crate::error::Result;
use crate::mesh::{Mesh, SourceDocument};
use gltf::json as gj;
use serde_json::{json, Value};
use std::borrow::Cow;
use std::path::{Path, PathBuf};

/// The baked base colour the model's materials take.
pub struct BakedColor<'a> {
    /// The encoded PNG.
    pub png: &'a [u8],
    /// The UV set it is laid out on.
    pub uv_set: u32,
    /// Whether the bake's base was the material's own (`texture.base: "material"`): the image it
    /// came from is then replaced in place, and materials that share it see the bake.
    pub from_material: bool,
    /// The texture set it was baked for (`None`: the whole mesh's one texture).
    pub set: Option<&'a crate::mesh::TextureSet>,
    /// The PBR channels baked with it (`bake::channels`), each an encoded PNG.
    pub channels: Vec<BakedChannelPng<'a>>,
}

/// A baked channel the materials that show a [`BakedColor`] take.
pub struct BakedChannelPng<'a> {
    /// Which.
    pub kind: crate::bake::channels::ChannelKind,
    /// The encoded PNG.
    pub png: &'a [u8],
    /// For [`crate::bake::channels::ChannelKind::Orm`]: whether a layer painted occlusion (the
    /// materials then read it from R as their `occlusionTexture`).
    pub occlusion: bool,
}

/// A written model's files (the `.glb`, or the `.gltf`, its `.bin` and its images), not yet on
/// disk, and what the writer could not keep.
#[derive(Debug, Default)]
pub struct Written {
    /// Each file's path and bytes, the model first.
    pub files: Vec<(PathBuf, Vec<u8>)>,
    /// What the writer could not keep or paint, for the report.
    pub warnings: Vec<String>,
}

const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
const F32: u32 = 5126;

/// The JSON paths (`/key/0/...`) where documents `a` and `b` differ, appended to `out`: a key or
/// element one side lacks is named whole. How the tests and `decalbake bench --corpus` check that
/// a model went out as it came in.
pub fn json_diff(a: &Value, b: &Value, path: &str, out: &mut Vec<String>) {
    match (a, b) {
        (Value::Object(x), Value::Object(y)) => {
            for k in x.keys().chain(y.keys().filter(|k| !x.contains_key(*k))) {
                let p = format!("{path}/{k}");
                match (x.get(k), y.get(k)) {
                    (Some(u), Some(v)) => json_diff(u, v, &p, out),
                    _ => out.push(p),
                }
            }
        }
        (Value::Array(x), Value::Array(y)) => {
            for i in 0..x.len().max(y.len()) {
                let p = format!("{path}/{i}");
                match (x.get(i), y.get(i)) {
                    (Some(u), Some(v)) => json_diff(u, v, &p, out),
                    _ => out.push(p),
                }
            }
        }
        _ if a != b => out.push(path.to_string()),
        _ => {}
    }
}

/// Whether `out` names a `.gltf` (JSON with a `.bin` and image files) rather than a `.glb`.
pub fn is_gltf_name(out: &Path) -> bool {
    out.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("gltf"))
}

/// The model of `mesh` with `colors` as its base colours (one per texture set; none: the
/// document's own), written to `out` (`.glb`, or `.gltf` with `<stem>.bin` and image files beside
/// it).
pub fn write_model(mesh: &Mesh, colors: &[BakedColor], out: &Path) -> Result<Written> {
    let mut doc = match mesh.document.as_deref() {
        Some(src) => Doc::from_source(src),
        None => Doc::fresh(mesh),
    };
    if mesh.document.is_some() && (!mesh.new_uv_sets.is_empty() || !mesh.vertex_origin.is_empty()) {
        doc.write_vertex_edits(mesh);
    }
    for c in colors {
        let texture = match c.set {
            Some(set) => doc.apply_set_color(mesh, c, set, out),
            None => doc.apply_color(mesh, c, out),
        };
        if !c.channels.is_empty() {
            doc.apply_channels(mesh, c, texture, out);
        }
    }
    doc.finish(out)
}

/// The document being edited: its JSON and each buffer view's bytes (by index), packed into one
/// buffer at the end.
struct Doc<'a> {
    json: Value,
    views: Vec<Cow<'a, [u8]>>,
    src: Option<&'a SourceDocument>,
    /// Which views the source document read (those the edits leave unread are dropped).
    used_views: Vec<bool>,
    /// Files to write beside a `.gltf` (name, bytes).
    image_files: Vec<(String, Vec<u8>)>,
    warnings: Vec<String>,
}

/// `json[key]` as a mutable array, made when absent.
fn array<'v>(json: &'v mut Value, key: &str) -> &'v mut Vec<Value> {
    if !json.get(key).is_some_and(Value::is_array) {
        json[key] = json!([]);
    }
    json[key].as_array_mut().expect("an array")
}

fn to_value<T: serde::Serialize>(t: &T) -> Value {
    serde_json::to_value(t).expect("glTF JSON types serialize")
}

impl<'a> Doc<'a> {
    fn from_source(src: &'a SourceDocument) -> Doc<'a> {
        let views = (0..src.array("bufferViews").len())
            .map(|i| match src.view_bytes(i) {
                Some(b) => Cow::Borrowed(b),
                // A view of a buffer without data (a compression extension's fallback): zeros.
                None => {
                    let n = src.array("bufferViews")[i]
                        .get("byteLength")
                        .and_then(Value::as_u64)
                        .unwrap_or(0);
                    Cow::Owned(vec![0; n as usize])
                }
            })
            .collect();
        let used_views = view_uses(&src.json, src.array("bufferViews").len())
            .into_iter()
            .map(|n| n > 0)
            .collect();
        Doc {
            json: src.json.clone(),
            views,
            used_views,
            src: Some(src),
            image_files: Vec::new(),
            warnings: Vec::new(),
        }
    }

    /// A new document for a mesh made in code: one node, one primitive with positions, normals,
    /// every UV set, the pelt's weights and the triangles.
    fn fresh(m: &Mesh) -> Doc<'a> {
        let mut doc = Doc {
            json: json!({
                "asset": {"version": "2.0", "generator": concat!("decalbake ", env!("CARGO_PKG_VERSION"))},
                "scene": 0,
                "scenes": [{"nodes": [0]}],
                "nodes": [{"mesh": 0, "name": "decalbake"}],
            }),
            views: Vec::new(),
            used_views: Vec::new(),
            src: None,
            image_files: Vec::new(),
            warnings: Vec::new(),
        };
        let pos: Vec<[f32; 3]> = m.positions.iter().map(|p| p.to_array()).collect();
        let (lo, hi) = m.bounds();
        let mut attributes = json!({});
        attributes["POSITION"] = json!(doc.push_f32(
            bytemuck::cast_slice(&pos),
            gj::accessor::Type::Vec3,
            Some((lo.to_array().to_vec(), hi.to_array().to_vec()))
        ));
        // Normals where every vertex has one (glTF wants unit vectors; without, viewers shade flat).
        let nrm: Vec<[f32; 3]> = m
            .normals
            .iter()
            .map(|n| n.normalize_or_zero().to_array())
            .collect();
        if m.normals.len() == m.positions.len() && nrm.iter().all(|n| n != &[0.0; 3]) {
            attributes["NORMAL"] =
                json!(doc.push_f32(bytemuck::cast_slice(&nrm), gj::accessor::Type::Vec3, None));
        }
        for (i, set) in m.uv_sets.iter().enumerate() {
            let uv: Vec<[f32; 2]> = set.iter().map(|u| u.to_array()).collect();
            attributes[format!("TEXCOORD_{i}")] =
                json!(doc.push_f32(bytemuck::cast_slice(&uv), gj::accessor::Type::Vec2, None));
        }
        for (name, w) in [("_PELT_BLEND", &m.blend), ("_PELT_BRIDGE", &m.bridge)] {
            if w.len() == m.positions.len() {
                attributes[name] = json!(doc.push_f32(w, gj::accessor::Type::Scalar, None));
            }
        }
        let idx: Vec<u32> = m.triangles.iter().flatten().copied().collect();
        let indices = doc.push_indices(&idx);
        let mut prim = json!({"attributes": attributes, "indices": indices, "mode": 4});
        if let Some(mat) = &m.material {
            let [r, g, b, a] = mat.base_color_factor;
            array(&mut doc.json, "materials").push(json!({"pbrMetallicRoughness": {
                "baseColorFactor": [r, g, b, a], "metallicFactor": mat.metallic,
                "roughnessFactor": mat.roughness}}));
            prim["material"] = json!(0);
        }
        array(&mut doc.json, "meshes").push(json!({"primitives": [prim]}));
        doc
    }

    /// Appends a buffer view holding `bytes` (`stride` for vertex attributes whose elements are
    /// padded) and returns its index.
    fn push_view(&mut self, bytes: Vec<u8>, target: Option<u32>, stride: Option<usize>) -> usize {
        let view = gj::buffer::View {
            buffer: gj::Index::new(0),
            byte_length: gj::validation::USize64(bytes.len() as u64),
            byte_offset: None,
            byte_stride: stride.map(gj::buffer::Stride),
            name: None,
            target: target.map(|t| {
                gj::validation::Checked::Valid(if t == ELEMENT_ARRAY_BUFFER {
                    gj::buffer::Target::ElementArrayBuffer
                } else {
                    gj::buffer::Target::ArrayBuffer
                })
            }),
            extensions: None,
            extras: Default::default(),
        };
        array(&mut self.json, "bufferViews").push(to_value(&view));
        self.views.push(Cow::Owned(bytes));
        self.views.len() - 1
    }

    /// Appends a float accessor over `data` (`min_max` for positions) and returns its index.
    fn push_f32(
        &mut self,
        data: &[f32],
        ty: gj::accessor::Type,
        min_max: Option<(Vec<f32>, Vec<f32>)>,
    ) -> usize {
        let count = data.len() / ty.multiplicity();
        let view = self.push_view(
            bytemuck::cast_slice(data).to_vec(),
            Some(ARRAY_BUFFER),
            None,
        );
        self.push_accessor(
            view,
            F32,
            ty,
            count,
            false,
            min_max.map(|(a, b)| (json!(a), json!(b))),
        )
    }

    /// Appends an accessor over all of buffer view `view` and returns its index.
    fn push_accessor(
        &mut self,
        view: usize,
        component: u32,
        ty: gj::accessor::Type,
        count: usize,
        normalized: bool,
        min_max: Option<(Value, Value)>,
    ) -> usize {
        let (min, max) = min_max.unzip();
        let accessor = gj::Accessor {
            buffer_view: Some(gj::Index::new(view as u32)),
            byte_offset: None,
            count: gj::validation::USize64(count as u64),
            component_type: gj::validation::Checked::Valid(gj::accessor::GenericComponentType(
                component_type(component),
            )),
            extensions: None,
            extras: Default::default(),
            type_: gj::validation::Checked::Valid(ty),
            min,
            max,
            name: None,
            normalized,
            sparse: None,
        };
        let list = array(&mut self.json, "accessors");
        list.push(to_value(&accessor));
        list.len() - 1
    }

    /// Appends an index accessor (unsigned short where every index fits, else unsigned int).
    fn push_indices(&mut self, idx: &[u32]) -> usize {
        let (bytes, component) = if idx.iter().all(|&i| i < u16::MAX as u32) {
            let short: Vec<u16> = idx.iter().map(|&i| i as u16).collect();
            (bytemuck::cast_slice(&short).to_vec(), 5123)
        } else {
            (bytemuck::cast_slice(idx).to_vec(), 5125)
        };
        let view = self.push_view(bytes, Some(ELEMENT_ARRAY_BUFFER), None);
        self.push_accessor(
            view,
            component,
            gj::accessor::Type::Scalar,
            idx.len(),
            false,
            None,
        )
    }
}

fn component_type(c: u32) -> gj::accessor::ComponentType {
    use gj::accessor::ComponentType as C;
    match c {
        5120 => C::I8,
        5121 => C::U8,
        5122 => C::I16,
        5123 => C::U16,
        5125 => C::U32,
        _ => C::F32,
    }
}

/// Bytes of one component of `componentType` `c`.
fn component_size(c: u64) -> usize {
    match c {
        5120 | 5121 => 1,
        5122 | 5123 => 2,
        _ => 4,
    }
}

/// Components of an accessor `type`.
fn type_width(t: &str) -> usize {
    match t {
        "SCALAR" => 1,
        "VEC2" => 2,
        "VEC3" => 3,
        "VEC4" | "MAT2" => 4,
        "MAT3" => 9,
        "MAT4" => 16,
        _ => 1,
    }
}

/// One component at the start of `b` as a number.
fn component_value(b: &[u8], c: u64) -> f64 {
    match c {
        5120 => b[0] as i8 as f64,
        5121 => b[0] as f64,
        5122 => i16::from_le_bytes([b[0], b[1]]) as f64,
        5123 => u16::from_le_bytes([b[0], b[1]]) as f64,
        5125 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
        _ => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
    }
}

mod channels;
mod color;
mod pack;
mod vertices;

use pack::{uri_of, view_uses};
