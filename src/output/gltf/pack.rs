// SPDX-License-Identifier: MIT OR Apache-2.0
//! The edited document packed and serialised: its buffer views in one buffer (in order, each
//! 4-byte aligned), images embedded in a `.glb` or written beside a `.gltf`.

use super::{is_gltf_name, Doc, Written};
use crate::error::{Error, Result};
use serde_json::{json, Value};
use std::path::Path;

/// How often the document names each buffer view (a `bufferView` key anywhere: accessors,
/// sparse accessors, images, extensions), by index (`n` views).
pub(super) fn view_uses(json: &Value, n: usize) -> Vec<usize> {
    fn walk(json: &Value, uses: &mut [usize]) {
        match json {
            Value::Object(o) => {
                for (k, x) in o {
                    match x.as_u64() {
                        Some(v) if k == "bufferView" && (v as usize) < uses.len() => {
                            uses[v as usize] += 1
                        }
                        _ => walk(x, uses),
                    }
                }
            }
            Value::Array(a) => a.iter().for_each(|x| walk(x, uses)),
            _ => {}
        }
    }
    let mut uses = vec![0; n];
    walk(json, &mut uses);
    uses
}

/// A file name as a relative URI.
pub(super) fn uri_of(name: &str) -> String {
    urlencoding::encode(name).into_owned()
}

impl Doc<'_> {
    pub(super) fn finish(mut self, out: &Path) -> Result<Written> {
        let gltf = is_gltf_name(out);
        self.place_images(gltf);
        // Views that the edits left unread (an attribute gathered anew, an image replaced)
        // shrink to nothing worth carrying.
        let uses = view_uses(&self.json, self.views.len());
        for (v, &n) in uses.iter().enumerate() {
            if self.used_views.get(v).copied().unwrap_or(false) && n == 0 {
                self.views[v] = vec![0u8; 4].into();
                if let Some(view) = self.json["bufferViews"][v].as_object_mut() {
                    view.remove("byteStride");
                    view.remove("target");
                }
            }
        }
        let mut bin: Vec<u8> = Vec::new();
        for (v, bytes) in self.views.iter().enumerate() {
            bin.resize(bin.len().next_multiple_of(4), 0);
            let view = &mut self.json["bufferViews"][v];
            view["buffer"] = json!(0);
            view["byteOffset"] = json!(bin.len());
            view["byteLength"] = json!(bytes.len());
            bin.extend_from_slice(bytes);
        }
        bin.resize(bin.len().next_multiple_of(4), 0);
        let stem = out
            .file_stem()
            .map_or_else(|| "model".into(), |s| s.to_string_lossy().into_owned());
        let bin_name = format!("{stem}.bin");
        let mut buffer = self.json["buffers"]
            .get(0)
            .cloned()
            .filter(Value::is_object)
            .unwrap_or_else(|| json!({}));
        let b = buffer.as_object_mut().expect("an object");
        b.remove("uri");
        b.insert("byteLength".into(), json!(bin.len()));
        if gltf {
            b.insert("uri".into(), json!(uri_of(&bin_name)));
        }
        if bin.is_empty() {
            if let Some(o) = self.json.as_object_mut() {
                o.remove("buffers");
            }
        } else {
            self.json["buffers"] = json!([buffer]);
        }
        let dir = out.parent().unwrap_or(Path::new(""));
        let mut files = Vec::new();
        if gltf {
            let text = serde_json::to_vec_pretty(&self.json).expect("JSON serializes");
            files.push((out.to_path_buf(), text));
            if !bin.is_empty() {
                files.push((dir.join(&bin_name), bin));
            }
            for (name, bytes) in self.image_files {
                files.push((dir.join(name), bytes));
            }
        } else {
            files.push((out.to_path_buf(), glb_bytes(&self.json, &bin, out)?));
        }
        Ok(Written {
            files,
            warnings: self.warnings,
        })
    }

    /// Images in a `.glb` are embedded (external files and data URIs into buffer views); beside a
    /// `.gltf`, external files are copied under their own names (numbered where two share one).
    fn place_images(&mut self, gltf: bool) {
        let Some(src) = self.src else { return };
        let count = self.json["images"].as_array().map_or(0, Vec::len);
        for i in 0..count {
            let Some(uri) = self.json["images"][i]["uri"].as_str().map(String::from) else {
                continue;
            };
            if gltf && uri.starts_with("data:") {
                continue;
            }
            if self.image_files.iter().any(|(n, _)| uri_of(n) == uri) {
                continue;
            }
            let data = match src.image(i) {
                Ok(d) => d,
                Err(e) => {
                    self.warnings.push(format!(
                        "{e}; the model names it by its URI {uri:?} as it was"
                    ));
                    continue;
                }
            };
            if gltf {
                let base = data.file_name.unwrap_or_else(|| format!("image{i}"));
                let mut name = base.clone();
                let mut k = 1;
                while self.image_files.iter().any(|(n, _)| *n == name) {
                    name = format!("{k}_{base}");
                    k += 1;
                }
                self.json["images"][i]["uri"] = json!(uri_of(&name));
                self.image_files.push((name, data.bytes));
            } else {
                let view = self.push_view(data.bytes, None, None);
                let img = self.json["images"][i].as_object_mut().expect("an image");
                img.remove("uri");
                img.insert("bufferView".into(), json!(view));
                img.insert("mimeType".into(), json!(data.mime));
            }
        }
    }
}

/// A `.glb`: the JSON chunk (space-padded) and the BIN chunk.
fn glb_bytes(json: &Value, bin: &[u8], out: &Path) -> Result<Vec<u8>> {
    let mut text = serde_json::to_vec(json).expect("JSON serializes");
    text.resize(text.len().next_multiple_of(4), b' ');
    let total = 12 + 8 + text.len() + if bin.is_empty() { 0 } else { 8 + bin.len() };
    if total > u32::MAX as usize {
        return Err(Error::Mesh {
            path: out.to_path_buf(),
            detail: format!("the model would be {total} bytes, more than a .glb holds (4 GiB); write a .gltf instead"),
        });
    }
    let mut glb = Vec::with_capacity(total);
    glb.extend_from_slice(b"glTF");
    glb.extend_from_slice(&2u32.to_le_bytes());
    glb.extend_from_slice(&(total as u32).to_le_bytes());
    glb.extend_from_slice(&(text.len() as u32).to_le_bytes());
    glb.extend_from_slice(b"JSON");
    glb.extend_from_slice(&text);
    if !bin.is_empty() {
        glb.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        glb.extend_from_slice(b"BIN\0");
        glb.extend_from_slice(bin);
    }
    Ok(glb)
}
