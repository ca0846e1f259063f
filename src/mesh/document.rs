// SPDX-License-Identifier: MIT OR Apache-2.0
//! The glTF document a mesh was loaded from, kept whole so that the writer
//! (`crate::output::gltf`) gives the model back as it came in: every node, mesh, skin, animation,
//! camera, material, texture, extension and `extras`, with only the bake's changes.
//!
//! The JSON is kept as `serde_json::Value`, the text as read: nothing the `gltf` crate's typed
//! model does not know (an extension it has no type for, a field a newer glTF version adds) can be
//! lost or normalised on the way out. The loader still reads the geometry through the `gltf`
//! crate; the writer builds what it adds with `gltf::json`'s types.

use std::path::{Path, PathBuf};

/// A loaded glTF document: its JSON and the bytes of every buffer.
#[derive(Debug)]
pub struct SourceDocument {
    /// The JSON as read.
    pub json: serde_json::Value,
    /// Each buffer's bytes (a `.glb`'s BIN chunk, external `.bin` files, data URIs), by index.
    pub buffers: Vec<Vec<u8>>,
    /// The file it was read from (messages, the names of copied images).
    pub path: PathBuf,
    /// The directory its external URIs resolve in (`None`: read from memory, embedded data only).
    pub base: Option<PathBuf>,
}

/// An encoded image of the document and its MIME type.
pub struct ImageData {
    /// The encoded bytes (PNG, JPEG, ...).
    pub bytes: Vec<u8>,
    /// `image/png`, `image/jpeg`, or what the document declares.
    pub mime: String,
    /// The file name of an external image (`None` when embedded).
    pub file_name: Option<String>,
}

impl SourceDocument {
    /// The bytes of `bufferViews[view]` (`None` when the view or its buffer is missing or out of
    /// range).
    pub fn view_bytes(&self, view: usize) -> Option<&[u8]> {
        let v = self.json.get("bufferViews")?.get(view)?;
        let buffer = self.buffers.get(v.get("buffer")?.as_u64()? as usize)?;
        let offset = v.get("byteOffset").and_then(|o| o.as_u64()).unwrap_or(0) as usize;
        let length = v.get("byteLength")?.as_u64()? as usize;
        buffer.get(offset..offset.checked_add(length)?)
    }

    /// The encoded bytes of `images[index]`, from its buffer view, data URI or external file.
    pub fn image(&self, index: usize) -> Result<ImageData, String> {
        let img = self
            .json
            .get("images")
            .and_then(|i| i.get(index))
            .ok_or_else(|| format!("images[{index}] does not exist"))?;
        let declared = img
            .get("mimeType")
            .and_then(|m| m.as_str())
            .map(String::from);
        if let Some(view) = img.get("bufferView").and_then(|v| v.as_u64()) {
            let bytes = self
                .view_bytes(view as usize)
                .ok_or_else(|| format!("images[{index}].bufferView {view} is out of range"))?;
            let mime = declared.unwrap_or_else(|| sniff(bytes).into());
            return Ok(ImageData {
                bytes: bytes.to_vec(),
                mime,
                file_name: None,
            });
        }
        let uri = img
            .get("uri")
            .and_then(|u| u.as_str())
            .ok_or_else(|| format!("images[{index}] has neither a uri nor a bufferView"))?;
        if let Some(data) = uri.strip_prefix("data:") {
            let (head, b64) = data.split_once(";base64,").unwrap_or(("", data));
            let bytes = base64::decode(b64)
                .map_err(|e| format!("images[{index}]'s data URI is not base64: {e}"))?;
            let mime = declared
                .or_else(|| (!head.is_empty()).then(|| head.to_string()))
                .unwrap_or_else(|| sniff(&bytes).into());
            return Ok(ImageData {
                bytes,
                mime,
                file_name: None,
            });
        }
        let base = self.base.as_deref().ok_or_else(|| {
            format!("images[{index}] is an external file, but the mesh was read from memory with no directory to find it in")
        })?;
        let decoded = urlencoding::decode(uri)
            .map_err(|e| format!("images[{index}].uri {uri:?} is not valid UTF-8: {e}"))?;
        let file = base.join(decoded.as_ref());
        let bytes = std::fs::read(&file)
            .map_err(|e| format!("images[{index}] ({}): {e}", file.display()))?;
        let mime = declared.unwrap_or_else(|| sniff(&bytes).into());
        Ok(ImageData {
            bytes,
            mime,
            file_name: Path::new(decoded.as_ref())
                .file_name()
                .map(|n| n.to_string_lossy().into_owned()),
        })
    }

    /// The document's `key` array (empty when absent).
    pub fn array(&self, key: &str) -> &[serde_json::Value] {
        self.json
            .get(key)
            .and_then(|a| a.as_array())
            .map_or(&[], |a| a.as_slice())
    }
}

/// The MIME type of encoded image bytes by their signature (`application/octet-stream` when
/// unknown).
pub fn sniff(bytes: &[u8]) -> &'static str {
    if bytes.starts_with(b"\x89PNG") {
        "image/png"
    } else if bytes.starts_with(&[0xFF, 0xD8]) {
        "image/jpeg"
    } else if bytes.len() > 12 && &bytes[..4] == b"RIFF" && &bytes[8..12] == b"WEBP" {
        "image/webp"
    } else if bytes.starts_with(b"\xABKTX 20") {
        "image/ktx2"
    } else {
        "application/octet-stream"
    }
}
