// SPDX-License-Identifier: MIT OR Apache-2.0
//! `KHR_draco_mesh_compression`: each triangle primitive with the extension decoded with the
//! pure-Rust `draco-core`, its attributes and indices written into the new buffer.

use super::{components, f32_bytes, min_max, remove_extension, uint, Work, DRACO, INDICES};
use super::{MAX_ELEMENTS, VERTICES};
use crate::error::Result;
use draco_core::{DataType, DecodeLimits, DecoderBuffer, Mesh, MeshDecoder};
use serde_json::{json, Map, Value};
use std::collections::HashSet;

/// Decodes every primitive with `KHR_draco_mesh_compression` (one of another mode than triangles
/// is an error).
pub(super) fn decode_primitives(work: &mut Work) -> Result<()> {
    let meshes = work
        .json
        .get("meshes")
        .and_then(Value::as_array)
        .map_or(0, Vec::len);
    // Accessors already filled by a primitive: one that another primitive shares gets a new one.
    let mut filled = HashSet::new();
    for m in 0..meshes {
        let prims = work.json["meshes"][m]
            .get("primitives")
            .and_then(Value::as_array)
            .map_or(0, Vec::len);
        for p in 0..prims {
            let prim = &work.json["meshes"][m]["primitives"][p];
            let Some(ext) = prim.pointer(&format!("/extensions/{DRACO}")).cloned() else {
                continue;
            };
            let what = format!("meshes[{m}].primitives[{p}] {DRACO}");
            let mode = prim.get("mode").and_then(Value::as_u64).unwrap_or(4);
            if mode != 4 {
                return Err(work.err(format!("{what}: the primitive's mode is {mode}; decalbake decodes Draco triangle meshes (mode 4) only")));
            }
            primitive(work, (m, p), &ext, &mut filled)
                .map_err(|e| work.err(format!("{what}: {e}")))?;
        }
    }
    Ok(())
}

/// Decodes primitive `(m, p)` whose extension object is `ext`.
fn primitive(
    work: &mut Work,
    (m, p): (usize, usize),
    ext: &Value,
    filled: &mut HashSet<usize>,
) -> std::result::Result<(), String> {
    let view = uint(ext, "bufferView").ok_or("has no valid bufferView")?;
    let map = ext
        .get("attributes")
        .and_then(Value::as_object)
        .ok_or("has no attributes map")?;
    let attrs = work.json["meshes"][m]["primitives"][p]["attributes"].clone();
    // (glTF name, Draco unique id, the primitive's accessor), checked before decoding.
    let mut wanted = Vec::new();
    for (key, id) in map {
        let id = id
            .as_u64()
            .and_then(|i| u32::try_from(i).ok())
            .ok_or_else(|| format!("attributes.{key} is {id}, not a Draco attribute id"))?;
        let a = uint(&attrs, key).ok_or_else(|| {
            format!("names attribute {key}, which the primitive's attributes do not have")
        })?;
        let acc = work
            .json
            .get("accessors")
            .and_then(|x| x.get(a))
            .ok_or_else(|| format!("{key} is accessors[{a}], which does not exist"))?;
        let ty = acc.get("type").and_then(Value::as_str).unwrap_or("");
        let n = components(ty).ok_or_else(|| {
            format!("{key} (accessors[{a}]) has type {ty:?}; decalbake decodes SCALAR to VEC4")
        })?;
        let normalized = acc
            .get("normalized")
            .and_then(Value::as_bool)
            .unwrap_or(false);
        wanted.push((key.clone(), id, a, n, normalized));
    }
    let stream = work.view_bytes(view)?;
    let mesh = decode_stream(stream)?;
    let points = mesh.num_points();
    let mut decoded = Vec::new();
    for (key, id, a, n, normalized) in wanted {
        let att = mesh.attribute_by_unique_id(id).ok_or_else(|| {
            format!("attributes.{key} is Draco attribute {id}, which the stream does not have")
        })?;
        let have = att.num_components() as usize;
        if have < n {
            return Err(format!(
                "Draco attribute {id} ({key}) has {have} components; accessors[{a}] needs {n}"
            ));
        }
        let mut values = att.read_f32s(points, n);
        if normalized {
            if let Some(scale) = integer_scale(att.data_type()) {
                values.iter_mut().for_each(|x| *x = (*x / scale).max(-1.0));
            }
        }
        decoded.push((key, a, n, values));
    }
    let indices: Vec<u32> = mesh.faces().iter().flatten().map(|i| i.0).collect();
    for (key, a, n, values) in decoded {
        let view = work.push_view(&f32_bytes(&values), VERTICES);
        let mut acc = json!({"bufferView": view, "componentType": 5126, "count": points});
        if key == "POSITION" {
            let (lo, hi) = min_max(&values, n);
            (acc["min"], acc["max"]) = (lo, hi);
        }
        let a = fill(work, a, acc, filled);
        work.json["meshes"][m]["primitives"][p]["attributes"][&key] = json!(a);
    }
    let bytes: Vec<u8> = indices.iter().flat_map(|i| i.to_le_bytes()).collect();
    let view_ix = work.push_view(&bytes, INDICES);
    let mut acc = json!({"bufferView": view_ix, "componentType": 5125, "count": indices.len(), "type": "SCALAR"});
    let max = indices.iter().max().copied().unwrap_or(0);
    let min = indices.iter().min().copied().unwrap_or(0);
    (acc["min"], acc["max"]) = (json!([min]), json!([max]));
    let prim = &work.json["meshes"][m]["primitives"][p];
    let a = match uint(prim, "indices") {
        Some(a) if work.json.get("accessors").and_then(|x| x.get(a)).is_some() => {
            fill(work, a, acc, filled)
        }
        _ => append(work, acc),
    };
    let prim = &mut work.json["meshes"][m]["primitives"][p];
    prim["indices"] = json!(a);
    remove_extension(prim, DRACO);
    work.released.insert(view);
    Ok(())
}

/// The Draco stream decoded, its points and faces at most [`MAX_ELEMENTS`].
fn decode_stream(stream: &[u8]) -> std::result::Result<Mesh, String> {
    let limits = DecodeLimits::default()
        .with_max_points(MAX_ELEMENTS as u64)
        .with_max_faces(MAX_ELEMENTS as u64);
    let mut buffer = DecoderBuffer::new(stream).with_limits(limits);
    let mut mesh = Mesh::new();
    MeshDecoder::new()
        .decode(&mut buffer, &mut mesh)
        .map_err(|e| {
            format!(
                "the Draco stream ({} bytes) does not decode: {e}",
                stream.len()
            )
        })?;
    if mesh.num_faces() == 0 {
        return Err("the Draco stream has no triangles".into());
    }
    Ok(mesh)
}

/// The largest value of an integer Draco type (what a normalised one is divided by).
fn integer_scale(t: DataType) -> Option<f32> {
    match t {
        DataType::Int8 => Some(127.0),
        DataType::Uint8 => Some(255.0),
        DataType::Int16 => Some(32767.0),
        DataType::Uint16 => Some(65535.0),
        _ => None,
    }
}

/// Accessor `a` filled in place with `new`'s fields (its name, type, extras kept; its old
/// layout, normalisation, sparse and bounds dropped), or, when an earlier primitive filled it,
/// `new` appended with `a`'s type; returns the accessor's index.
fn fill(work: &mut Work, a: usize, new: Value, filled: &mut HashSet<usize>) -> usize {
    let old = work.json["accessors"][a]
        .as_object()
        .cloned()
        .unwrap_or_default();
    let mut acc: Map<String, Value> = old
        .into_iter()
        .filter(|(k, _)| {
            !["byteOffset", "normalized", "sparse", "min", "max"].contains(&k.as_str())
        })
        .collect();
    acc.extend(new.as_object().cloned().unwrap_or_default());
    if filled.insert(a) {
        work.json["accessors"][a] = Value::Object(acc);
        a
    } else {
        acc.remove("name");
        append(work, Value::Object(acc))
    }
}

/// A new accessor; returns its index.
fn append(work: &mut Work, acc: Value) -> usize {
    if !work.json.get("accessors").is_some_and(Value::is_array) {
        work.json["accessors"] = json!([]);
    }
    let list = work.json["accessors"].as_array_mut().expect("an array");
    list.push(acc);
    list.len() - 1
}
