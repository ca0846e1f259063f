// SPDX-License-Identifier: MIT OR Apache-2.0
//! What the loader checks in a glTF file before the `gltf` crate reads it. The crate trusts some
//! of what a file declares, and panics, loops or allocates what a count declares when it is
//! wrong: a GLB header shorter than itself, a `POSITION` naming a missing accessor (in the crate's
//! own validation), a URI that percent-decodes to invalid UTF-8, an external file that is a device
//! (read forever), a buffer view past its buffer, an image with neither a URI nor a MIME type, and
//! accessors of the wrong type, with no elements, a stride below their element size, data past
//! their buffer view or more elements than a file could hold. Each is refused here with an
//! [`Error::Gltf`] naming the file and the element (most were found by `decalbake fuzz`; every
//! case is a file under `tests/fuzz/regressions/` or a test in `tests/fuzz.rs`).

use crate::error::{Error, Result};
use gltf::accessor::{DataType, Dimensions};
use std::path::Path;

/// Most elements an accessor may declare, and most vertices (and triangles) a scene may have
/// after node instancing: 16,777,216.
pub const MAX_ELEMENTS: usize = 1 << 24;

/// A malformed or unsupported glTF file.
pub(crate) fn gltf_err(path: &Path, detail: impl std::fmt::Display) -> Error {
    Error::Gltf {
        path: path.to_path_buf(),
        detail: format!(
            "{detail}. decalbake reads glTF 2.0 (.gltf with its .bin/images, or .glb); check the file with the Khronos glTF-Validator"
        ),
    }
}

/// Parses and validates a `.gltf` or `.glb` (the `gltf` crate's `Gltf::from_slice`, with the
/// checks its parsing and validation lack done first).
pub(crate) fn parse(bytes: &[u8], name: &Path) -> Result<gltf::Gltf> {
    if let (Some(b"glTF"), Some(len)) = (bytes.get(..4), bytes.get(8..12)) {
        let declared = u32::from_le_bytes([len[0], len[1], len[2], len[3]]);
        if declared < 12 {
            return Err(gltf_err(
                name,
                format!("the GLB header declares a length of {declared} bytes, less than the header's own 12"),
            ));
        }
    }
    let gltf::Gltf { document, blob } =
        gltf::Gltf::from_slice_without_validation(bytes).map_err(|e| gltf_err(name, e))?;
    let root = document.into_json();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            let position = gltf::json::validation::Checked::Valid(gltf::Semantic::Positions);
            if let Some(ix) = prim.attributes.get(&position) {
                if ix.value() >= root.accessors.len() {
                    return Err(gltf_err(
                        name,
                        format!(
                            "meshes[{m}].primitives[{p}].attributes.POSITION is accessor {}, but the file has {} accessors",
                            ix.value(),
                            root.accessors.len()
                        ),
                    ));
                }
            }
        }
    }
    let mut root = root;
    required_extensions(&mut root.extensions_required, name)?;
    // Compressed geometry is validated once decoded (`super::decode`, [`validated`]): until then a
    // Draco primitive's accessors have no data of their own, which the crate's validation refuses.
    let compressed = root
        .extensions_used
        .iter()
        .any(|e| DECODED_EXTENSIONS.contains(&e.as_str()));
    let document = if compressed {
        gltf::Document::from_json_without_validation(root)
    } else {
        gltf::Document::from_json(root).map_err(|e| gltf_err(name, e))?
    };
    Ok(gltf::Gltf { document, blob })
}

/// `document` (parsed by [`parse`] without validation) validated by the `gltf` crate.
pub(crate) fn validated(document: gltf::Document, name: &Path) -> Result<gltf::Document> {
    gltf::Document::from_json(document.into_json()).map_err(|e| gltf_err(name, e))
}

/// Required extensions that change the geometry and that the loader cannot decode: a model that
/// requires one is refused with its name. (`KHR_draco_mesh_compression`,
/// `EXT_meshopt_compression` and `KHR_mesh_quantization` are decoded before the geometry is read,
/// `super::decode`.)
const GEOMETRY_EXTENSIONS: &[&str] = &["EXT_mesh_gpu_instancing"];

/// Required extensions that `super::decode` turns into an uncompressed document.
const DECODED_EXTENSIONS: &[&str] = &[
    "KHR_draco_mesh_compression",
    "EXT_meshopt_compression",
    "KHR_mesh_quantization",
];

/// Prefixes of extensions that do not change the geometry (materials, textures, lights, metadata):
/// a required one is kept in the output and otherwise ignored.
const HARMLESS_PREFIXES: &[&str] = &[
    "KHR_materials_",
    "KHR_texture_",
    "EXT_texture_",
    "MSFT_texture_",
    "KHR_lights_",
    "EXT_lights_",
    "KHR_xmp",
    "KHR_animation_pointer",
    "KHR_audio",
];

/// Checks `extensionsRequired` (of the typed model the loader reads with; the document the writer
/// keeps is untouched): one that changes the geometry and one the loader does not know refuse the
/// model with its name; the rest (the compression the loader decodes among them) are cleared, so
/// that the `gltf` crate's validation, which refuses every extension it does not implement, reads
/// the geometry as the extensions leave it.
fn required_extensions(required: &mut Vec<String>, name: &Path) -> Result<()> {
    for ext in required.iter() {
        if DECODED_EXTENSIONS.contains(&ext.as_str()) {
            continue;
        }
        if GEOMETRY_EXTENSIONS.contains(&ext.as_str()) {
            return Err(gltf_err(
                name,
                format!("extensionsRequired names {ext}, which changes how the geometry is stored, and decalbake cannot decode it; write a copy without it first (each instance as a node of its own)"),
            ));
        }
        if !HARMLESS_PREFIXES.iter().any(|p| ext.starts_with(p)) {
            return Err(gltf_err(
                name,
                format!("extensionsRequired names {ext}, which decalbake does not know, so it cannot tell whether the geometry it reads is the model's; write a copy without it"),
            ));
        }
    }
    required.clear();
    Ok(())
}

/// The document's JSON (a `.glb`'s JSON chunk) as it is, for the writer to keep.
pub(crate) fn raw_json(bytes: &[u8], name: &Path) -> Result<serde_json::Value> {
    let json: std::borrow::Cow<[u8]> = if bytes.starts_with(b"glTF") {
        gltf::binary::Glb::from_slice(bytes)
            .map_err(|e| gltf_err(name, e))?
            .json
    } else {
        bytes.into()
    };
    serde_json::from_slice(&json).map_err(|e| gltf_err(name, e))
}

/// Buffer and image URIs the `gltf` crate can resolve without panicking (it unwraps their
/// percent-decoding) or reading forever: with a `base` directory, an external file must be a
/// regular file (not `/dev/zero` or a pipe; a missing one is left for the crate to report).
pub(crate) fn uris(document: &gltf::Document, base: Option<&Path>, name: &Path) -> Result<()> {
    let json = document.as_json();
    let buffers = json.buffers.iter().map(|b| ("buffers", b.uri.as_deref()));
    let images = json.images.iter().map(|i| ("images", i.uri.as_deref()));
    let mut index = std::collections::HashMap::new();
    for (kind, uri) in buffers.chain(images) {
        let i = index.entry(kind).or_insert(0usize);
        let k = *i;
        *i += 1;
        let Some(uri) = uri else { continue };
        // Resolved as the crate does: `file:` URIs as they are, relative ones percent-decoded.
        let file = match uri
            .strip_prefix("file://")
            .or_else(|| uri.strip_prefix("file:"))
        {
            Some(path) => Some(std::path::PathBuf::from(path)),
            None if uri.contains(':') => None,
            None => match urlencoding::decode(uri) {
                Ok(path) => base.map(|b| b.join(&*path)),
                Err(_) => {
                    return Err(gltf_err(
                        name,
                        format!("{kind}[{k}].uri {uri:?} does not percent-decode to UTF-8 text"),
                    ))
                }
            },
        };
        if let (Some(f), Some(_)) = (file, base) {
            if std::fs::metadata(&f).is_ok_and(|m| !m.is_file()) {
                return Err(gltf_err(
                    name,
                    format!(
                        "{kind}[{k}].uri {uri:?} is {}, which is not a regular file",
                        f.display()
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// Every buffer view within its buffer's data.
pub(crate) fn views(
    document: &gltf::Document,
    buffers: &[gltf::buffer::Data],
    name: &Path,
) -> Result<()> {
    for v in document.views() {
        let b = v.buffer().index();
        let have = buffers.get(b).map_or(0, |d| d.len());
        let end = v.offset().checked_add(v.length());
        if end.is_none_or(|e| e > have) {
            return Err(gltf_err(
                name,
                format!(
                    "bufferViews[{}] (bytes {} to {}) runs past the end of buffers[{b}] ({have} bytes)",
                    v.index(),
                    v.offset(),
                    v.offset() as u128 + v.length() as u128
                ),
            ));
        }
    }
    Ok(())
}

/// Checks accessor `a` (`what`, e.g. `meshes[0].primitives[1] POSITION`, for messages) before it is
/// read: its type among `types`, at least one and at most [`MAX_ELEMENTS`] elements, its elements
/// (and a sparse accessor's indices and values) inside their buffer views with a stride no smaller
/// than an element; `stored`: its elements must come from a buffer view (not zeros the file only
/// declares). Returns its element count.
pub(crate) fn accessor(
    a: &gltf::Accessor,
    what: &str,
    types: &[(DataType, Dimensions)],
    stored: bool,
    name: &Path,
) -> Result<usize> {
    let err =
        |detail: String| gltf_err(name, format!("{what} (accessors[{}]) {detail}", a.index()));
    if !types.contains(&(a.data_type(), a.dimensions())) {
        let want: Vec<String> = types.iter().map(|&(d, n)| type_name(d, n)).collect();
        return Err(err(format!(
            "is {}; decalbake reads {}",
            type_name(a.data_type(), a.dimensions()),
            want.join(" or ")
        )));
    }
    let count = a.count();
    if count == 0 || count > MAX_ELEMENTS {
        return Err(err(format!(
            "declares {count} elements; decalbake reads 1 to {MAX_ELEMENTS}"
        )));
    }
    let size = a.size();
    match a.view() {
        Some(view) => within(&view, a.offset(), view.stride(), size, count)
            .map_err(|e| err(format!("{e} (bufferViews[{}])", view.index())))?,
        None if stored => {
            return Err(err(
                "has no bufferView: its elements would be zeros the file does not hold".into(),
            ))
        }
        None => {}
    }
    if let Some(sparse) = a.sparse() {
        let n = sparse.count();
        if n == 0 || n > count {
            return Err(err(format!(
                "has a sparse count of {n}; it must be 1 to the accessor's count ({count})"
            )));
        }
        let ix = sparse.indices();
        let ix_size = ix.index_type().size();
        within(&ix.view(), ix.offset(), ix.view().stride(), ix_size, n).map_err(|e| {
            err(format!(
                "sparse indices: {e} (bufferViews[{}])",
                ix.view().index()
            ))
        })?;
        let vals = sparse.values();
        within(&vals.view(), vals.offset(), vals.view().stride(), size, n).map_err(|e| {
            err(format!(
                "sparse values: {e} (bufferViews[{}])",
                vals.view().index()
            ))
        })?;
    }
    Ok(count)
}

/// An accessor type as glTF spells it: `VEC2 of UNSIGNED_SHORT (5123)`.
fn type_name(d: DataType, n: Dimensions) -> String {
    let (name, code) = match d {
        DataType::I8 => ("BYTE", 5120),
        DataType::U8 => ("UNSIGNED_BYTE", 5121),
        DataType::I16 => ("SHORT", 5122),
        DataType::U16 => ("UNSIGNED_SHORT", 5123),
        DataType::U32 => ("UNSIGNED_INT", 5125),
        DataType::F32 => ("FLOAT", 5126),
    };
    format!("{} of {name} ({code})", format!("{n:?}").to_uppercase())
}

/// Whether `count` elements of `size` bytes at `offset` with `stride` fit in `view`.
fn within(
    view: &gltf::buffer::View,
    offset: usize,
    stride: Option<usize>,
    size: usize,
    count: usize,
) -> std::result::Result<(), String> {
    let stride = stride.unwrap_or(size);
    if stride < size {
        return Err(format!(
            "has a byteStride of {stride}, less than its element's {size} bytes"
        ));
    }
    let end = stride
        .checked_mul(count - 1)
        .and_then(|x| x.checked_add(size))
        .and_then(|x| x.checked_add(offset));
    match end {
        Some(e) if e <= view.length() => Ok(()),
        _ => Err(format!(
            "needs {} bytes from byte {offset} of a {}-byte buffer view",
            stride as u128 * (count as u128 - 1) + size as u128,
            view.length()
        )),
    }
}
