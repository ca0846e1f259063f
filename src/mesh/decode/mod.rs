// SPDX-License-Identifier: MIT OR Apache-2.0
//! Compressed geometry decoded before the `gltf` crate reads a model: the loader
//! (`super::load`) hands the document here first, and a document that uses
//! `EXT_meshopt_compression`, `KHR_draco_mesh_compression` or `KHR_mesh_quantization` comes back
//! as its uncompressed equivalent, JSON and buffers, which the `gltf` crate then reads and the
//! [`super::SourceDocument`] keeps.
//!
//! - `EXT_meshopt_compression` (`meshopt.rs`): every buffer view with the extension is decoded
//!   with meshoptimizer (modes `ATTRIBUTES`, `TRIANGLES`, `INDICES`; filters `OCTAHEDRAL`,
//!   `QUATERNION`, `EXPONENTIAL`) and its bytes become the view's data. A fallback buffer (one
//!   marked `fallback`, or without a URI and not the GLB's binary chunk) is not read: it has no
//!   data, and only compressed views may name it.
//! - `KHR_draco_mesh_compression` (`draco.rs`): every primitive with the extension (triangles
//!   only) is decoded with `draco-core`; the attributes its `attributes` map names become `FLOAT`
//!   accessors (of the type the primitive's accessor declares; `min`/`max` for `POSITION`) and its
//!   triangles `UNSIGNED_INT` indices. The primitive's own accessors, which only describe the decoded data,
//!   are filled in place (a new accessor where an earlier primitive filled one it shares).
//!   Attributes the map does not name keep their accessors.
//! - `KHR_mesh_quantization` (here): the `gltf` crate reads only `FLOAT` positions, normals and
//!   tangents and only normalised `UNSIGNED_BYTE`/`UNSIGNED_SHORT` texture coordinates (it panics
//!   on signed ones), so every `POSITION`, `NORMAL`, `TANGENT` and `TEXCOORD_n` (and morph target)
//!   accessor of an integer type becomes a `FLOAT` copy in place: a normalised component divided by
//!   127, 255, 32767 or 65535 (a signed one clamped at −1), an unnormalised one its integer value.
//!
//! Each extension is then removed from `extensionsUsed` and `extensionsRequired` when nothing uses
//! it any more, buffer views nothing reads after the decoding (a Draco stream, a quantized copy
//! replaced) and buffers no view reads (the compressed streams, the fallback) are dropped, and the
//! decoded data lives in one new buffer.
//!
//! **The model a bake writes is this decoded, uncompressed document**: the output is not
//! compressed again (run `gltf-transform draco`, `meshopt` or `quantize` from npm's
//! `@gltf-transform/cli` on it if it should be).
//!
//! What a file declares is checked before anything is allocated for it: a count or length that
//! does not fit the data (a compressed stream past its buffer, more elements than the stream could
//! hold, more than [`MAX_ELEMENTS`]) is an [`Error::Gltf`] naming the element.

mod draco;
mod meshopt;

use super::checks::{self, gltf_err, MAX_ELEMENTS};
use crate::error::{Error, Result};
use serde_json::{json, Value};
use std::collections::HashSet;
use std::path::Path;

/// The three extensions this module decodes.
pub(crate) const DRACO: &str = "KHR_draco_mesh_compression";
/// `EXT_meshopt_compression`.
pub(crate) const MESHOPT: &str = "EXT_meshopt_compression";
/// `KHR_mesh_quantization`.
pub(crate) const QUANTIZATION: &str = "KHR_mesh_quantization";

/// `ARRAY_BUFFER` and `ELEMENT_ARRAY_BUFFER`, a new view's `target`.
const VERTICES: u64 = 34962;
const INDICES: u64 = 34963;

/// A document decoded: what the loader goes on with instead of the file's.
pub(crate) struct Decoded {
    /// The decoded JSON, parsed and validated by the `gltf` crate.
    pub document: gltf::Document,
    /// Every buffer's bytes.
    pub buffers: Vec<gltf::buffer::Data>,
    /// The decoded JSON, for the [`super::SourceDocument`].
    pub json: Value,
}

/// Decodes the compressed geometry of `gltf` (parsed from `bytes` by [`checks::parse`]; `name` in
/// messages, `base` resolving external buffers). `None`: the document uses none of the three
/// extensions, and the loader reads it as it is.
pub(crate) fn decode(
    gltf: &gltf::Gltf,
    bytes: &[u8],
    name: &Path,
    base: Option<&Path>,
) -> Result<Option<Decoded>> {
    let used = &gltf.document.as_json().extensions_used;
    if !used
        .iter()
        .any(|e| [DRACO, MESHOPT, QUANTIZATION].contains(&e.as_str()))
    {
        return Ok(None);
    }
    let json = checks::raw_json(bytes, name)?;
    let buffers = load_buffers(&gltf.document, &json, gltf.blob.clone(), base, name)?;
    let mut work = Work::new(json, buffers, name);
    meshopt::decode_views(&mut work)?;
    draco::decode_primitives(&mut work)?;
    if declares(&work.json, QUANTIZATION) {
        work.dequantize()?;
    }
    work.finish();
    let text = serde_json::to_vec(&work.json).expect("JSON serializes");
    let document = checks::validated(checks::parse(&text, name)?.document, name)?;
    Ok(Some(Decoded {
        document,
        buffers: work.buffers.into_iter().map(gltf::buffer::Data).collect(),
        json: work.json,
    }))
}

/// Whether `extensionsUsed` or `extensionsRequired` names `ext`.
fn declares(json: &Value, ext: &str) -> bool {
    ["extensionsUsed", "extensionsRequired"].iter().any(|k| {
        json.get(k)
            .and_then(Value::as_array)
            .is_some_and(|a| a.iter().any(|e| e.as_str() == Some(ext)))
    })
}

/// Every buffer's bytes, as `gltf::import_buffers` reads them, except that a fallback buffer
/// (`EXT_meshopt_compression.fallback`, or one without a URI that is not the GLB's binary chunk)
/// is not read: it is empty here, and only compressed views may name it.
fn load_buffers(
    document: &gltf::Document,
    json: &Value,
    mut blob: Option<Vec<u8>>,
    base: Option<&Path>,
    name: &Path,
) -> Result<Vec<Vec<u8>>> {
    let mut out = Vec::new();
    for b in document.buffers() {
        let i = b.index();
        let fallback = json
            .pointer(&format!("/buffers/{i}/extensions/{MESHOPT}/fallback"))
            .and_then(Value::as_bool)
            .unwrap_or(false);
        let data = match b.source() {
            gltf::buffer::Source::Bin if i == 0 && blob.is_some() => {
                gltf::buffer::Data::from_source_and_blob(b.source(), base, &mut blob)
                    .map_err(|e| gltf_err(name, format!("loading buffers: {e}")))?
                    .0
            }
            gltf::buffer::Source::Bin => Vec::new(),
            gltf::buffer::Source::Uri(_) if fallback => Vec::new(),
            gltf::buffer::Source::Uri(_) => {
                gltf::buffer::Data::from_source(b.source(), base)
                    .map_err(|e| gltf_err(name, format!("loading buffers: buffers[{i}]: {e}")))?
                    .0
            }
        };
        if !data.is_empty() && data.len() < b.length() {
            return Err(gltf_err(
                name,
                format!(
                    "buffers[{i}] declares a byteLength of {} but holds {} bytes",
                    b.length(),
                    data.len()
                ),
            ));
        }
        out.push(data);
    }
    Ok(out)
}

/// `value[key]` as a `usize` (`None` when absent, not a whole number or too large).
fn uint(value: &Value, key: &str) -> Option<usize> {
    value
        .get(key)
        .and_then(Value::as_u64)
        .and_then(|x| usize::try_from(x).ok())
}

/// Every primitive of every mesh of the document.
fn primitives(json: &Value) -> impl Iterator<Item = &Value> {
    json.get("meshes")
        .and_then(Value::as_array)
        .into_iter()
        .flatten()
        .filter_map(|m| m.get("primitives").and_then(Value::as_array))
        .flatten()
}

/// The document's array `key`, mutably (`None` when absent or not an array).
fn array_mut<'v>(json: &'v mut Value, key: &str) -> Option<&'v mut Vec<Value>> {
    json.get_mut(key).and_then(Value::as_array_mut)
}

/// Removes `extensions.<ext>` from `object`, and `extensions` when that leaves it empty.
fn remove_extension(object: &mut Value, ext: &str) {
    let Some(o) = object.as_object_mut() else {
        return;
    };
    if let Some(e) = o.get_mut("extensions").and_then(Value::as_object_mut) {
        e.remove(ext);
        if e.is_empty() {
            o.remove("extensions");
        }
    }
}

/// Components of an accessor `type` (`None`: a matrix or unknown).
fn components(ty: &str) -> Option<usize> {
    match ty {
        "SCALAR" => Some(1),
        "VEC2" => Some(2),
        "VEC3" => Some(3),
        "VEC4" => Some(4),
        _ => None,
    }
}

/// A component type's size in bytes (`None`: unknown).
fn component_size(ct: u64) -> Option<usize> {
    match ct {
        5120 | 5121 => Some(1),
        5122 | 5123 => Some(2),
        5125 | 5126 => Some(4),
        _ => None,
    }
}

/// Component `b` (of type `ct`) as glTF reads it: normalised integers divided by their type's
/// largest value (signed ones clamped at −1), others as their value.
fn component_value(b: &[u8], ct: u64, normalized: bool) -> f32 {
    let (raw, scale, signed) = match ct {
        5120 => (b[0] as i8 as f32, 127.0, true),
        5121 => (b[0] as f32, 255.0, false),
        5122 => (i16::from_le_bytes([b[0], b[1]]) as f32, 32767.0, true),
        5123 => (u16::from_le_bytes([b[0], b[1]]) as f32, 65535.0, false),
        5125 => return u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f32,
        _ => return f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
    };
    match (normalized, signed) {
        (false, _) => raw,
        (true, true) => (raw / scale).max(-1.0),
        (true, false) => raw / scale,
    }
}

/// Per-component minimum and maximum of `values` (`n` components an element), as JSON arrays.
fn min_max(values: &[f32], n: usize) -> (Value, Value) {
    let mut lo = vec![f32::INFINITY; n];
    let mut hi = vec![f32::NEG_INFINITY; n];
    for e in values.chunks_exact(n) {
        for (k, &x) in e.iter().enumerate() {
            lo[k] = lo[k].min(x);
            hi[k] = hi[k].max(x);
        }
    }
    (json!(lo), json!(hi))
}

/// f32s as little-endian bytes.
fn f32_bytes(values: &[f32]) -> Vec<u8> {
    values.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// The document being decoded.
struct Work<'a> {
    /// Its JSON.
    json: Value,
    /// Every buffer's bytes (a fallback buffer's empty), the new one last.
    buffers: Vec<Vec<u8>>,
    /// The index of the new buffer that holds the decoded data.
    out: usize,
    /// The file (messages).
    name: &'a Path,
    /// Views the decoding stopped reading: dropped at the end where nothing else reads them.
    released: HashSet<usize>,
}

impl<'a> Work<'a> {
    fn new(mut json: Value, mut buffers: Vec<Vec<u8>>, name: &'a Path) -> Self {
        // `buffers` is read-only from here on except the new one, whose entry's byteLength is
        // set when the decoding is done.
        let out = buffers.len();
        buffers.push(Vec::new());
        if !json.get("buffers").is_some_and(Value::is_array) {
            json["buffers"] = json!([]);
        }
        if let Some(b) = array_mut(&mut json, "buffers") {
            b.resize(out, json!({}));
            b.push(json!({"byteLength": 0}));
        }
        Work {
            json,
            buffers,
            out,
            name,
            released: HashSet::new(),
        }
    }

    /// A malformed or unsupported file.
    fn err(&self, detail: impl std::fmt::Display) -> Error {
        gltf_err(self.name, detail)
    }

    /// Appends `bytes` to the new buffer (4-byte aligned); returns their offset.
    fn place(&mut self, bytes: &[u8]) -> usize {
        let data = &mut self.buffers[self.out];
        data.resize(data.len().next_multiple_of(4), 0);
        let offset = data.len();
        data.extend_from_slice(bytes);
        offset
    }

    /// A new buffer view of `bytes` in the new buffer; returns its index.
    fn push_view(&mut self, bytes: &[u8], target: u64) -> usize {
        let offset = self.place(bytes);
        let view = json!({"buffer": self.out, "byteOffset": offset, "byteLength": bytes.len(), "target": target});
        if !self.json.get("bufferViews").is_some_and(Value::is_array) {
            self.json["bufferViews"] = json!([]);
        }
        let views = array_mut(&mut self.json, "bufferViews").expect("an array");
        views.push(view);
        views.len() - 1
    }

    /// The bytes of `bufferViews[v]`, or what is wrong with its range.
    fn view_bytes(&self, v: usize) -> std::result::Result<&[u8], String> {
        let view = self
            .json
            .get("bufferViews")
            .and_then(|a| a.get(v))
            .ok_or_else(|| format!("bufferViews[{v}] does not exist"))?;
        let b = uint(view, "buffer").ok_or_else(|| format!("bufferViews[{v}] has no buffer"))?;
        let offset = uint(view, "byteOffset").unwrap_or(0);
        let length = uint(view, "byteLength")
            .ok_or_else(|| format!("bufferViews[{v}] has no byteLength"))?;
        let data = self
            .buffers
            .get(b)
            .ok_or_else(|| format!("bufferViews[{v}] names buffers[{b}], which does not exist"))?;
        offset
            .checked_add(length)
            .and_then(|end| data.get(offset..end))
            .ok_or_else(|| {
                format!(
                    "bufferViews[{v}] (bytes {offset} to {}) runs past the end of buffers[{b}] ({} bytes{})",
                    offset as u128 + length as u128,
                    data.len(),
                    if data.is_empty() { ", a fallback buffer with no data" } else { "" }
                )
            })
    }

    /// Converts every integer `POSITION`, `NORMAL`, `TANGENT` and `TEXCOORD_n` accessor of the
    /// meshes' primitives and morph targets to `FLOAT` in place (see the module's doc).
    fn dequantize(&mut self) -> Result<()> {
        let mut todo: Vec<(usize, String)> = Vec::new();
        let mut seen = HashSet::new();
        for (m, mesh) in self
            .json
            .get("meshes")
            .and_then(Value::as_array)
            .into_iter()
            .flatten()
            .enumerate()
        {
            let prims = mesh.get("primitives").and_then(Value::as_array);
            for (p, prim) in prims.into_iter().flatten().enumerate() {
                if prim.pointer(&format!("/extensions/{DRACO}")).is_some() {
                    continue;
                }
                let targets = prim.get("targets").and_then(Value::as_array);
                let sets = std::iter::once(("attributes".to_string(), prim.get("attributes")))
                    .chain(
                        targets
                            .into_iter()
                            .flatten()
                            .enumerate()
                            .map(|(t, x)| (format!("targets[{t}]"), Some(x))),
                    );
                for (set, attrs) in sets {
                    for (key, a) in attrs.and_then(Value::as_object).into_iter().flatten() {
                        let Some(a) = a.as_u64().and_then(|a| usize::try_from(a).ok()) else {
                            continue;
                        };
                        if quantized_semantic(key) && self.is_integer(a) && seen.insert(a) {
                            todo.push((a, format!("meshes[{m}].primitives[{p}].{set}.{key}")));
                        }
                    }
                }
            }
        }
        for (a, what) in todo {
            self.float_copy(a, &what)?;
        }
        Ok(())
    }

    /// Whether `accessors[a]` has an integer component type.
    fn is_integer(&self, a: usize) -> bool {
        self.json
            .pointer(&format!("/accessors/{a}/componentType"))
            .and_then(Value::as_u64)
            .is_some_and(|ct| (5120..=5125).contains(&ct))
    }

    /// `accessors[a]` (`what` in messages) replaced in place by a `FLOAT` copy of its elements
    /// in a new view.
    fn float_copy(&mut self, a: usize, what: &str) -> Result<()> {
        let (values, n) = self
            .read_f32(a)
            .map_err(|e| self.err(format!("{what} (accessors[{a}], {QUANTIZATION}): {e}")))?;
        let view = self.push_view(&f32_bytes(&values), VERTICES);
        let acc = &self.json["accessors"][a];
        let old = [
            "/bufferView",
            "/sparse/indices/bufferView",
            "/sparse/values/bufferView",
        ]
        .map(|p| acc.pointer(p).and_then(Value::as_u64));
        self.released
            .extend(old.into_iter().flatten().map(|v| v as usize));
        let acc = self.json["accessors"][a]
            .as_object_mut()
            .expect("an accessor object");
        for key in ["byteOffset", "normalized", "sparse"] {
            acc.remove(key);
        }
        acc.insert("bufferView".into(), json!(view));
        acc.insert("componentType".into(), json!(5126));
        if acc.contains_key("min") || acc.contains_key("max") || what.ends_with("POSITION") {
            let (lo, hi) = min_max(&values, n);
            acc.insert("min".into(), lo);
            acc.insert("max".into(), hi);
        }
        Ok(())
    }

    /// The elements of `accessors[a]` as f32 ([`component_value`]), with its sparse substitution,
    /// and its component count; every range checked before it is read.
    fn read_f32(&self, a: usize) -> std::result::Result<(Vec<f32>, usize), String> {
        let acc = &self.json["accessors"][a];
        let ct = acc
            .get("componentType")
            .and_then(Value::as_u64)
            .unwrap_or(0);
        let size = component_size(ct).ok_or_else(|| format!("has componentType {ct}"))?;
        let ty = acc.get("type").and_then(Value::as_str).unwrap_or("");
        let n = components(ty).ok_or_else(|| {
            format!("has type {ty:?}; a vertex attribute is SCALAR or VEC2 to VEC4")
        })?;
        let normalized = acc
            .get("normalized")
            .and_then(Value::as_bool)
            .unwrap_or(false);
        let count = uint(acc, "count").unwrap_or(0);
        if count == 0 || count > MAX_ELEMENTS {
            return Err(format!(
                "declares {count} elements; decalbake reads 1 to {MAX_ELEMENTS}"
            ));
        }
        let elem = n * size;
        let mut out = vec![0f32; count * n];
        let read = |bytes: &[u8], at: usize, out: &mut [f32]| {
            for (k, o) in out.iter_mut().enumerate() {
                *o = component_value(&bytes[at + k * size..], ct, normalized);
            }
        };
        if let Some(v) = uint(acc, "bufferView") {
            let bytes = self.view_bytes(v)?;
            let stride = self.json["bufferViews"][v]
                .get("byteStride")
                .and_then(Value::as_u64)
                .map_or(elem, |s| s as usize);
            let offset = uint(acc, "byteOffset").unwrap_or(0);
            fits(bytes.len(), offset, stride, elem, count)
                .map_err(|e| format!("{e} (bufferViews[{v}])"))?;
            for (i, o) in out.chunks_exact_mut(n).enumerate() {
                read(bytes, offset + i * stride, o);
            }
        }
        if let Some(sparse) = acc.get("sparse") {
            let k = uint(sparse, "count").unwrap_or(0);
            if k == 0 || k > count {
                return Err(format!(
                    "has a sparse count of {k}; it must be 1 to the accessor's count ({count})"
                ));
            }
            let (ix, vals) = (&sparse["indices"], &sparse["values"]);
            let ict = ix.get("componentType").and_then(Value::as_u64).unwrap_or(0);
            let isize = match ict {
                5121 | 5123 | 5125 => component_size(ict).expect("known"),
                _ => return Err(format!("has sparse indices of componentType {ict}")),
            };
            let iv = uint(ix, "bufferView").ok_or("has sparse indices without a bufferView")?;
            let vv = uint(vals, "bufferView").ok_or("has sparse values without a bufferView")?;
            let (ib, vb) = (self.view_bytes(iv)?, self.view_bytes(vv)?);
            let (io, vo) = (
                uint(ix, "byteOffset").unwrap_or(0),
                uint(vals, "byteOffset").unwrap_or(0),
            );
            fits(ib.len(), io, isize, isize, k)
                .map_err(|e| format!("sparse indices: {e} (bufferViews[{iv}])"))?;
            fits(vb.len(), vo, elem, elem, k)
                .map_err(|e| format!("sparse values: {e} (bufferViews[{vv}])"))?;
            for j in 0..k {
                let i = component_value(&ib[io + j * isize..], ict, false) as usize;
                let dst = out
                    .get_mut(i * n..(i + 1) * n)
                    .ok_or_else(|| format!("has sparse index {i}, past its {count} elements"))?;
                read(vb, vo + j * elem, dst);
            }
        }
        Ok((out, n))
    }

    /// Ends the decoding: the new buffer's length, the released views and the buffers nothing
    /// reads dropped, fallback marks and the extensions nothing uses removed.
    fn finish(&mut self) {
        let len = self.buffers[self.out].len();
        self.buffers[self.out].resize(len.next_multiple_of(4), 0);
        self.json["buffers"][self.out]["byteLength"] = json!(len);
        for b in array_mut(&mut self.json, "buffers").into_iter().flatten() {
            remove_extension(b, MESHOPT);
        }
        self.drop_released_views();
        self.drop_unread_buffers();
        let draco =
            primitives(&self.json).any(|p| p.pointer(&format!("/extensions/{DRACO}")).is_some());
        let meshopt = self
            .json
            .get("bufferViews")
            .and_then(Value::as_array)
            .into_iter()
            .flatten()
            .any(|v| v.pointer(&format!("/extensions/{MESHOPT}")).is_some());
        let quantized = self.quantized_left();
        for (ext, used) in [
            (DRACO, draco),
            (MESHOPT, meshopt),
            (QUANTIZATION, quantized),
        ] {
            if used {
                continue;
            }
            for key in ["extensionsUsed", "extensionsRequired"] {
                let Some(list) = array_mut(&mut self.json, key) else {
                    continue;
                };
                list.retain(|e| e.as_str() != Some(ext));
                if list.is_empty() {
                    self.json.as_object_mut().expect("an object").remove(key);
                }
            }
        }
    }

    /// Whether a primitive or morph target still has an integer `POSITION`, `NORMAL`, `TANGENT`
    /// or `TEXCOORD_n` that core glTF does not allow (normalised `UNSIGNED_BYTE` and
    /// `UNSIGNED_SHORT` texture coordinates it does).
    fn quantized_left(&self) -> bool {
        let prims =
            primitives(&self.json).filter(|p| p.pointer(&format!("/extensions/{DRACO}")).is_none());
        let attrs = prims.flat_map(|p| {
            let targets = p
                .get("targets")
                .and_then(Value::as_array)
                .into_iter()
                .flatten();
            std::iter::once(p.get("attributes"))
                .chain(targets.map(Some))
                .flatten()
        });
        attrs
            .filter_map(Value::as_object)
            .flatten()
            .any(|(key, a)| {
                let Some(acc) = a
                    .as_u64()
                    .and_then(|a| self.json.get("accessors")?.get(a as usize))
                else {
                    return false;
                };
                let ct = acc
                    .get("componentType")
                    .and_then(Value::as_u64)
                    .unwrap_or(5126);
                let normalized = acc
                    .get("normalized")
                    .and_then(Value::as_bool)
                    .unwrap_or(false);
                let core = key.starts_with("TEXCOORD_") && normalized && (ct == 5121 || ct == 5123);
                quantized_semantic(key) && ct != 5126 && !core
            })
    }

    /// Drops the released views that nothing reads any more, renumbering every `bufferView`.
    fn drop_released_views(&mut self) {
        let n = self
            .json
            .get("bufferViews")
            .and_then(Value::as_array)
            .map_or(0, Vec::len);
        let mut uses = vec![0usize; n];
        walk_views(&mut self.json, &mut |v| {
            if let Some(u) = uses.get_mut(*v) {
                *u += 1;
            }
        });
        let keep: Vec<bool> = (0..n)
            .map(|v| uses[v] > 0 || !self.released.contains(&v))
            .collect();
        if keep.iter().all(|&k| k) {
            return;
        }
        let mut index = Vec::with_capacity(n);
        let mut next = 0;
        for &k in &keep {
            index.push(next);
            next += k as usize;
        }
        walk_views(&mut self.json, &mut |v| {
            if let Some(&i) = index.get(*v) {
                *v = i;
            }
        });
        let mut k = keep.iter();
        if let Some(views) = array_mut(&mut self.json, "bufferViews") {
            views.retain(|_| *k.next().unwrap_or(&true));
        }
    }

    /// Drops the buffers that no buffer view reads, renumbering the views' `buffer`.
    fn drop_unread_buffers(&mut self) {
        let n = self.buffers.len();
        let mut read = vec![false; n];
        let views = self.json.get("bufferViews").and_then(Value::as_array);
        for v in views.into_iter().flatten() {
            for b in [
                v.get("buffer"),
                v.pointer(&format!("/extensions/{MESHOPT}/buffer")),
            ] {
                if let Some(r) = b
                    .and_then(Value::as_u64)
                    .and_then(|b| read.get_mut(b as usize))
                {
                    *r = true;
                }
            }
        }
        if read.iter().all(|&r| r) {
            return;
        }
        let mut index = Vec::with_capacity(n);
        let mut next = 0u64;
        for &r in &read {
            index.push(next);
            next += r as u64;
        }
        for v in array_mut(&mut self.json, "bufferViews")
            .into_iter()
            .flatten()
        {
            for key in [
                "/buffer".to_string(),
                format!("/extensions/{MESHOPT}/buffer"),
            ] {
                if let Some(b) = v.pointer_mut(&key) {
                    if let Some(&i) = b.as_u64().and_then(|b| index.get(b as usize)) {
                        *b = json!(i);
                    }
                }
            }
        }
        let mut r = read.iter();
        if let Some(buffers) = array_mut(&mut self.json, "buffers") {
            buffers.retain(|_| *r.next().unwrap_or(&true));
        }
        let mut r = read.iter();
        self.buffers.retain(|_| *r.next().unwrap_or(&true));
    }
}

/// Calls `f` on every `bufferView` index anywhere in the document (accessors, sparse accessors,
/// images, extensions), as the writer counts them.
fn walk_views(json: &mut Value, f: &mut impl FnMut(&mut usize)) {
    match json {
        Value::Object(o) => {
            for (k, x) in o.iter_mut() {
                match x.as_u64() {
                    Some(v) if k == "bufferView" => {
                        let mut i = v as usize;
                        f(&mut i);
                        *x = json!(i);
                    }
                    _ => walk_views(x, f),
                }
            }
        }
        Value::Array(a) => a.iter_mut().for_each(|x| walk_views(x, f)),
        _ => {}
    }
}

/// The attribute semantics `KHR_mesh_quantization` gives integer types.
fn quantized_semantic(key: &str) -> bool {
    matches!(key, "POSITION" | "NORMAL" | "TANGENT") || key.starts_with("TEXCOORD_")
}

/// Whether `count` elements of `size` bytes at `offset` with `stride` fit in `len` bytes.
fn fits(
    len: usize,
    offset: usize,
    stride: usize,
    size: usize,
    count: usize,
) -> std::result::Result<(), String> {
    if stride < size {
        return Err(format!(
            "has a byteStride of {stride}, less than its element's {size} bytes"
        ));
    }
    let end = stride
        .checked_mul(count.saturating_sub(1))
        .and_then(|x| x.checked_add(size))
        .and_then(|x| x.checked_add(offset));
    match end {
        Some(e) if e <= len => Ok(()),
        _ => Err(format!(
            "needs {} bytes from byte {offset} of a {len}-byte buffer view",
            stride as u128 * (count as u128).saturating_sub(1) + size as u128
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A document whose buffer 0 holds `streams` (each 4-byte aligned) and whose buffer 1 is a
    /// fallback without data; `views` are its buffer views (their streams' offsets filled in).
    fn meshopt_work(streams: &[Vec<u8>], mut views: Vec<Value>) -> Work<'static> {
        let mut data = Vec::new();
        for (s, v) in streams.iter().zip(&mut views) {
            data.resize(data.len().next_multiple_of(4), 0);
            v["extensions"][MESHOPT]["byteOffset"] = json!(data.len());
            v["extensions"][MESHOPT]["byteLength"] = json!(s.len());
            v["extensions"][MESHOPT]["buffer"] = json!(0);
            data.extend_from_slice(s);
        }
        let json = json!({
            "asset": {"version": "2.0"},
            "extensionsUsed": [MESHOPT], "extensionsRequired": [MESHOPT],
            "buffers": [{"byteLength": data.len()},
                        {"byteLength": 4096, "extensions": {MESHOPT: {"fallback": true}}}],
            "bufferViews": views,
        });
        Work::new(json, vec![data, Vec::new()], Path::new("test.glb"))
    }

    /// A compressed view of `count` elements of `stride` bytes in the fallback buffer.
    fn view(stride: usize, count: usize, mode: &str, filter: &str) -> Value {
        json!({"buffer": 1, "byteLength": stride * count,
               "extensions": {MESHOPT: {"byteStride": stride, "count": count, "mode": mode, "filter": filter}}})
    }

    fn floats(b: &[u8]) -> Vec<f32> {
        b.chunks_exact(4)
            .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
            .collect()
    }

    #[test]
    fn meshopt_modes_and_filters_decode() {
        let normals: Vec<[f32; 4]> = (0..40)
            .map(|i| {
                let (s, c) = (i as f32 * 0.37).sin_cos();
                let z = (i as f32 * 0.11).cos();
                let v = glam::Vec3::new(s, c, z).normalize();
                [v.x, v.y, v.z, 0.0]
            })
            .collect();
        let oct8 = ::meshopt::encode_filter_oct::<i8>(&normals, 8);
        let oct16 = ::meshopt::encode_filter_oct::<i16>(&normals, 16);
        let quats: Vec<[f32; 4]> = normals
            .iter()
            .map(|n| [n[0] * 0.6, n[1] * 0.6, n[2] * 0.6, 0.8])
            .map(|q| {
                let l = (q.iter().map(|x| x * x).sum::<f32>()).sqrt();
                q.map(|x| x / l)
            })
            .collect();
        let quat = ::meshopt::encode_filter_quat(&quats, 16);
        let points: Vec<[f32; 3]> = (0..40)
            .map(|i| [i as f32 * 0.25 - 3.0, (i * i) as f32 * 0.01, 1e3 + i as f32])
            .collect();
        let exp =
            ::meshopt::encode_filter_exp::<3>(&points, 24, ::meshopt::EncodeExpMode::Separate);
        let plain: Vec<[f32; 3]> = points.iter().map(|p| [p[2], p[0], p[1]]).collect();
        let tris: Vec<u32> = (0..38).flat_map(|i| [i, i + 1, i + 2]).collect();
        let seq: Vec<u32> = (0..50).map(|i| (i * 7) % 40).collect();
        let streams = vec![
            ::meshopt::encode_vertex_buffer(&oct8).unwrap(),
            ::meshopt::encode_vertex_buffer(&oct16).unwrap(),
            ::meshopt::encode_vertex_buffer(&quat).unwrap(),
            ::meshopt::encode_vertex_buffer(&exp).unwrap(),
            ::meshopt::encode_vertex_buffer(&plain).unwrap(),
            ::meshopt::encode_index_buffer(&tris, 40).unwrap(),
            ::meshopt::encode_index_sequence(&seq, 40).unwrap(),
        ];
        let views = vec![
            view(4, 40, "ATTRIBUTES", "OCTAHEDRAL"),
            view(8, 40, "ATTRIBUTES", "OCTAHEDRAL"),
            view(8, 40, "ATTRIBUTES", "QUATERNION"),
            view(12, 40, "ATTRIBUTES", "EXPONENTIAL"),
            view(12, 40, "ATTRIBUTES", "NONE"),
            view(2, tris.len(), "TRIANGLES", "NONE"),
            view(4, seq.len(), "INDICES", "NONE"),
        ];
        let mut w = meshopt_work(&streams, views);
        meshopt::decode_views(&mut w).unwrap();
        let b = |w: &Work, v: usize| w.view_bytes(v).unwrap().to_vec();
        // Octahedral: normalised signed components, within their precision of the unit vectors.
        let oct8: Vec<f32> = b(&w, 0)
            .iter()
            .map(|&x| (x as i8 as f32 / 127.0).max(-1.0))
            .collect();
        let oct16: Vec<f32> = b(&w, 1)
            .chunks_exact(2)
            .map(|c| i16::from_le_bytes([c[0], c[1]]) as f32 / 32767.0)
            .collect();
        let q: Vec<f32> = b(&w, 2)
            .chunks_exact(2)
            .map(|c| i16::from_le_bytes([c[0], c[1]]) as f32 / 32767.0)
            .collect();
        for (i, n) in normals.iter().enumerate() {
            for k in 0..3 {
                assert!(
                    (oct8[i * 4 + k] - n[k]).abs() < 0.03,
                    "oct8 {i}.{k}: {} vs {}",
                    oct8[i * 4 + k],
                    n[k]
                );
                assert!((oct16[i * 4 + k] - n[k]).abs() < 1e-3, "oct16 {i}.{k}");
            }
            // A quaternion and its negation are the same rotation.
            let dot: f32 = (0..4).map(|k| q[i * 4 + k] * quats[i][k]).sum();
            assert!(
                dot.abs() > 0.9999,
                "quaternion {i}: {:?} vs {:?}",
                &q[i * 4..i * 4 + 4],
                quats[i]
            );
        }
        let e = floats(&b(&w, 3));
        for (i, p) in points.iter().enumerate() {
            for k in 0..3 {
                assert!(
                    (e[i * 3 + k] - p[k]).abs() <= p[k].abs() * 1e-6,
                    "exp {i}.{k}: {} vs {}",
                    e[i * 3 + k],
                    p[k]
                );
            }
        }
        assert_eq!(
            floats(&b(&w, 4)),
            plain.concat(),
            "without a filter the bytes come back exactly"
        );
        let t: Vec<u32> = b(&w, 5)
            .chunks_exact(2)
            .map(|c| u16::from_le_bytes([c[0], c[1]]) as u32)
            .collect();
        // The triangle codec may rotate a triangle's corners; each triangle is the same.
        for (a, b) in t.chunks_exact(3).zip(tris.chunks_exact(3)) {
            let rot = |x: &[u32], r: usize| [x[r % 3], x[(r + 1) % 3], x[(r + 2) % 3]];
            assert!(
                (0..3).any(|r| rot(a, r) == [b[0], b[1], b[2]]),
                "{a:?} vs {b:?}"
            );
        }
        let s: Vec<u32> = b(&w, 6)
            .chunks_exact(4)
            .map(|c| u32::from_le_bytes(c.try_into().unwrap()))
            .collect();
        assert_eq!(s, seq);
        w.finish();
        // The compressed stream and the fallback are gone, the decoded data in one buffer.
        assert_eq!(
            w.json["buffers"].as_array().unwrap().len(),
            1,
            "{}",
            w.json["buffers"]
        );
        assert_eq!(w.buffers.len(), 1);
        assert!(
            w.json.get("extensionsUsed").is_none() && w.json.get("extensionsRequired").is_none()
        );
        for v in w.json["bufferViews"].as_array().unwrap() {
            assert_eq!(v["buffer"], 0);
            assert!(v.get("extensions").is_none(), "{v}");
        }
        assert_eq!(
            s,
            w.view_bytes(6)
                .unwrap()
                .chunks_exact(4)
                .map(|c| u32::from_le_bytes(c.try_into().unwrap()))
                .collect::<Vec<_>>()
        );
    }

    #[test]
    fn meshopt_declarations_that_do_not_fit_are_refused_by_name() {
        let stream = ::meshopt::encode_vertex_buffer(
            &(0..16)
                .map(|i| [i as f32, (i * i) as f32, -(i as f32)])
                .collect::<Vec<_>>(),
        )
        .unwrap();
        let cases: Vec<(Value, &str)> = vec![
            // More elements than the stream could hold: refused before anything is allocated.
            (view(12, 1 << 22, "ATTRIBUTES", "NONE"), "more than"),
            (
                view(12, MAX_ELEMENTS + 1, "ATTRIBUTES", "NONE"),
                "decalbake reads 1 to",
            ),
            (view(6, 16, "ATTRIBUTES", "NONE"), "byteStride of 6"),
            (view(12, 16, "ATTRIBUTES", "QUATERNION"), "byteStride of 12"),
            (view(12, 16, "SPLINES", "NONE"), "mode"),
            // A stream that is not what it claims to be.
            (view(12, 40, "ATTRIBUTES", "NONE"), "does not decode"),
        ];
        for (v, needle) in cases {
            let mut w = meshopt_work(std::slice::from_ref(&stream), vec![v.clone()]);
            let e = meshopt::decode_views(&mut w)
                .map_or_else(|e| e.to_string(), |()| "no error".into());
            assert!(
                e.contains("bufferViews[0] EXT_meshopt_compression") && e.contains(needle),
                "{v}: {e}"
            );
        }
        // The stream past its buffer.
        let mut w = meshopt_work(
            std::slice::from_ref(&stream),
            vec![view(12, 16, "ATTRIBUTES", "NONE")],
        );
        w.json["bufferViews"][0]["extensions"][MESHOPT]["byteLength"] = json!(stream.len() + 1);
        let e = meshopt::decode_views(&mut w).unwrap_err().to_string();
        assert!(
            e.contains("bufferViews[0]") && e.contains("which has"),
            "{e}"
        );
        // An uncompressed view cannot read the fallback buffer, which has no data.
        let mut w = meshopt_work(&[], vec![json!({"buffer": 1, "byteLength": 12})]);
        let e = meshopt::decode_views(&mut w).unwrap_err().to_string();
        assert!(
            e.contains("bufferViews[0] reads buffers[1], which has no data"),
            "{e}"
        );
    }

    #[test]
    fn quantized_attributes_become_floats_as_the_spec_reads_them() {
        // Interleaved: POSITION SHORT normalised VEC3 (stride 8) and TEXCOORD_0 UNSIGNED_BYTE
        // unnormalised VEC2 at byte 6; NORMAL BYTE normalised in its own view (stride 4);
        // TEXCOORD_1 UNSIGNED_SHORT normalised with one sparse substitution.
        let pos: [[i16; 3]; 3] = [[32767, 0, -32768], [-16384, 16384, 0], [1, 2, 3]];
        let uv: [[u8; 2]; 3] = [[0, 1], [2, 3], [255, 7]];
        let mut a = Vec::new();
        for (p, t) in pos.iter().zip(&uv) {
            a.extend(p.iter().flat_map(|c| c.to_le_bytes()));
            a.extend_from_slice(t);
        }
        let normal: [[i8; 4]; 3] = [[127, 0, -128, 0], [0, -127, 0, 0], [64, 64, 64, 0]];
        a.extend(normal.iter().flatten().map(|&c| c as u8));
        let uv1: [u16; 6] = [0, 65535, 32768, 0, 1, 2];
        a.extend(uv1.iter().flat_map(|c| c.to_le_bytes()));
        a.extend([2u8, 0, 0, 0]); // the sparse index (u8) and padding
        a.extend([65535u16, 65535].iter().flat_map(|c| c.to_le_bytes()));
        let json = json!({
            "asset": {"version": "2.0"},
            "extensionsUsed": [QUANTIZATION], "extensionsRequired": [QUANTIZATION],
            "buffers": [{"byteLength": a.len()}],
            "bufferViews": [
                {"buffer": 0, "byteOffset": 0, "byteLength": 24, "byteStride": 8},
                {"buffer": 0, "byteOffset": 24, "byteLength": 12, "byteStride": 4},
                {"buffer": 0, "byteOffset": 36, "byteLength": 12},
                {"buffer": 0, "byteOffset": 48, "byteLength": 4},
                {"buffer": 0, "byteOffset": 52, "byteLength": 4}
            ],
            "accessors": [
                {"bufferView": 0, "componentType": 5122, "normalized": true, "count": 3, "type": "VEC3", "min": [-32768, 0, -32768], "max": [32767, 16384, 3]},
                {"bufferView": 0, "byteOffset": 6, "componentType": 5121, "count": 3, "type": "VEC2"},
                {"bufferView": 1, "componentType": 5120, "normalized": true, "count": 3, "type": "VEC3"},
                {"bufferView": 2, "componentType": 5123, "normalized": true, "count": 3, "type": "VEC2",
                 "sparse": {"count": 1, "indices": {"bufferView": 3, "componentType": 5121}, "values": {"bufferView": 4}}}
            ],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1, "NORMAL": 2, "TEXCOORD_1": 3}}]}]
        });
        let mut w = Work::new(json, vec![a], Path::new("q.gltf"));
        w.dequantize().unwrap();
        w.finish();
        let read = |w: &Work, a: usize| w.read_f32(a).unwrap().0;
        let s = 32767.0;
        assert_eq!(
            read(&w, 0),
            vec![
                1.0,
                0.0,
                -1.0,
                -16384.0 / s,
                16384.0 / s,
                0.0,
                1.0 / s,
                2.0 / s,
                3.0 / s
            ]
        );
        assert_eq!(read(&w, 1), vec![0.0, 1.0, 2.0, 3.0, 255.0, 7.0]);
        let n = read(&w, 2);
        assert_eq!(&n[..6], &[1.0, 0.0, -1.0, 0.0, -1.0, 0.0]);
        assert!((n[6] - 64.0 / 127.0).abs() < 1e-7);
        assert_eq!(
            read(&w, 3),
            vec![0.0, 1.0, 32768.0 / 65535.0, 0.0, 1.0, 1.0]
        );
        let acc = &w.json["accessors"];
        assert_eq!(acc[0]["min"], json!([-16384.0f32 / 32767.0, 0.0, -1.0]));
        assert_eq!(
            acc[0]["max"],
            json!([1.0, 16384.0f32 / 32767.0, 3.0f32 / 32767.0])
        );
        for a in acc.as_array().unwrap() {
            assert_eq!(a["componentType"], 5126);
            assert!(
                a.get("normalized").is_none() && a.get("sparse").is_none(),
                "{a}"
            );
        }
        // The old views were dropped (nothing reads them), and the extension with them.
        assert_eq!(w.json["bufferViews"].as_array().unwrap().len(), 4);
        assert_eq!(w.json["buffers"].as_array().unwrap().len(), 1);
        assert!(w.json.get("extensionsUsed").is_none());
    }

    /// The bundled sheet and its Draco copy (tests/data/compressed): the same triangles, each
    /// vertex within Draco's 14-bit position and 12-bit UV quantization of the original's.
    #[test]
    fn a_draco_primitive_decodes_to_the_original_geometry() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let original =
            crate::mesh::Mesh::load(&root.join("assets/crumpled_developable.glb")).unwrap();
        let draco = crate::mesh::Mesh::load(&root.join("tests/data/compressed/crumpled-draco.glb"))
            .unwrap();
        assert_eq!(draco.triangles.len(), original.triangles.len());
        let (lo, hi) = original.bounds();
        let step = (hi - lo).max_element() / ((1 << 14) - 1) as f32;
        let mut area = [0.0f32; 2];
        for (k, m) in [&original, &draco].iter().enumerate() {
            for t in &m.triangles {
                let [a, b, c] = t.map(|i| m.positions[i as usize]);
                area[k] += (b - a).cross(c - a).length() / 2.0;
            }
        }
        assert!((area[0] - area[1]).abs() < area[0] * 1e-3, "areas {area:?}");
        for (v, p) in draco.positions.iter().enumerate() {
            let uv = draco.uv_sets[0][v];
            let near = (0..original.positions.len()).any(|o| {
                (original.positions[o] - *p).abs().max_element() <= step
                    && (original.uv_sets[0][o] - uv).abs().max_element() <= 1.0 / 2048.0
            });
            assert!(
                near,
                "decoded vertex {v} at {p}, uv {uv} is no original vertex"
            );
        }
        let doc = draco.document.as_ref().unwrap();
        assert!(
            doc.json.get("extensionsRequired").is_none()
                && doc.json.get("extensionsUsed").is_none()
        );
        assert!(doc.json["meshes"][0]["primitives"][0]
            .get("extensions")
            .is_none());
    }

    #[test]
    fn a_broken_draco_stream_is_refused_by_its_primitive() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let bytes = std::fs::read(root.join("tests/data/compressed/crumpled-draco.glb")).unwrap();
        let name = Path::new("draco.glb");
        let gltf = checks::parse(&bytes, name).unwrap();
        let json = checks::raw_json(&bytes, name).unwrap();
        let data = load_buffers(&gltf.document, &json, gltf.blob.clone(), None, name).unwrap();
        let len = json["bufferViews"][0]["byteLength"].as_u64().unwrap();
        for (edit, needle) in [
            (json!(len / 2), "does not decode"),
            (json!(len + 4096), "runs past the end of buffers[0]"),
        ] {
            let mut w = Work::new(json.clone(), data.clone(), name);
            w.json["bufferViews"][0]["byteLength"] = edit;
            let e = draco::decode_primitives(&mut w).unwrap_err().to_string();
            assert!(
                e.contains("meshes[0].primitives[0] KHR_draco_mesh_compression")
                    && e.contains(needle),
                "{e}"
            );
        }
        let mut w = Work::new(json.clone(), data.clone(), name);
        w.json["meshes"][0]["primitives"][0]["extensions"][DRACO]["attributes"]["TEXCOORD_0"] =
            json!(7);
        let e = draco::decode_primitives(&mut w).unwrap_err().to_string();
        assert!(
            e.contains("Draco attribute 7, which the stream does not have"),
            "{e}"
        );
    }
}
