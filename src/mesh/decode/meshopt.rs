// SPDX-License-Identifier: MIT OR Apache-2.0
//! `EXT_meshopt_compression`: each buffer view with the extension decoded with meshoptimizer
//! (the `meshopt` crate) into the new buffer, the view pointed at its bytes and the extension
//! removed from it.

use super::{remove_extension, uint, Work, MAX_ELEMENTS, MESHOPT};
use crate::error::Result;
use serde_json::{json, Value};

/// How one view is compressed, as its extension declares it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Mode {
    Attributes,
    Triangles,
    Indices,
}

/// The post-decoding filter of an `ATTRIBUTES` view.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Filter {
    None,
    Octahedral,
    Quaternion,
    Exponential,
}

/// A view's extension object, checked against the rules of the extension's specification.
#[derive(Debug)]
struct Spec {
    buffer: usize,
    offset: usize,
    length: usize,
    stride: usize,
    count: usize,
    mode: Mode,
    filter: Filter,
}

/// Most decoded bytes per compressed byte in `ATTRIBUTES` mode: a block of at most 256 elements
/// takes at least one control byte per four bytes of its stride (version 1 of the bitstream;
/// version 0 at least one header byte per byte of its stride).
const MAX_ATTRIBUTE_RATIO: usize = 1024;

/// Decodes every view with `EXT_meshopt_compression` into `work`'s new buffer; a view without it
/// that names a buffer without data (a fallback) is an error.
pub(super) fn decode_views(work: &mut Work) -> Result<()> {
    let n = work
        .json
        .get("bufferViews")
        .and_then(Value::as_array)
        .map_or(0, Vec::len);
    for v in 0..n {
        let view = &work.json["bufferViews"][v];
        let Some(ext) = view.pointer(&format!("/extensions/{MESHOPT}")) else {
            if let Some(b) = uint(view, "buffer") {
                if work.buffers.get(b).is_some_and(Vec::is_empty) && b != work.out {
                    return Err(work.err(format!("bufferViews[{v}] reads buffers[{b}], which has no data (a fallback buffer of {MESHOPT}, or no uri outside a .glb's binary chunk); only views compressed with {MESHOPT} may name it")));
                }
            }
            continue;
        };
        let what = format!("bufferViews[{v}] {MESHOPT}");
        let spec = parse(ext, view).map_err(|e| work.err(format!("{what}: {e}")))?;
        let bytes = decoded(work, &spec).map_err(|e| work.err(format!("{what}: {e}")))?;
        let offset = work.place(&bytes);
        let out = work.out;
        let view = &mut work.json["bufferViews"][v];
        view["buffer"] = json!(out);
        view["byteOffset"] = json!(offset);
        view["byteLength"] = json!(bytes.len());
        remove_extension(view, MESHOPT);
    }
    Ok(())
}

/// The extension object `ext` of `view`, checked.
fn parse(ext: &Value, view: &Value) -> std::result::Result<Spec, String> {
    let need = |key: &str| uint(ext, key).ok_or_else(|| format!("has no valid {key}"));
    let mode = match ext.get("mode").and_then(Value::as_str) {
        Some("ATTRIBUTES") => Mode::Attributes,
        Some("TRIANGLES") => Mode::Triangles,
        Some("INDICES") => Mode::Indices,
        m => {
            return Err(format!(
                "has mode {m:?}; it must be ATTRIBUTES, TRIANGLES or INDICES"
            ))
        }
    };
    let filter = match ext.get("filter").map(|f| f.as_str()) {
        None | Some(Some("NONE")) => Filter::None,
        Some(Some("OCTAHEDRAL")) => Filter::Octahedral,
        Some(Some("QUATERNION")) => Filter::Quaternion,
        Some(Some("EXPONENTIAL")) => Filter::Exponential,
        Some(f) => {
            return Err(format!(
                "has filter {f:?}; it must be NONE, OCTAHEDRAL, QUATERNION or EXPONENTIAL"
            ))
        }
    };
    let spec = Spec {
        buffer: need("buffer")?,
        offset: uint(ext, "byteOffset").unwrap_or(0),
        length: need("byteLength")?,
        stride: need("byteStride")?,
        count: need("count")?,
        mode,
        filter,
    };
    let (stride, count) = (spec.stride, spec.count);
    let stride_ok = match (mode, filter) {
        (Mode::Attributes, Filter::None) => stride > 0 && stride <= 256 && stride % 4 == 0,
        (Mode::Attributes, Filter::Octahedral) => stride == 4 || stride == 8,
        (Mode::Attributes, Filter::Quaternion) => stride == 8,
        (Mode::Attributes, Filter::Exponential) => stride > 0 && stride <= 256 && stride % 4 == 0,
        (_, Filter::None) => stride == 2 || stride == 4,
        (_, f) => {
            return Err(format!(
                "has mode {mode:?} with filter {f:?}; index data takes no filter"
            ))
        }
    };
    if !stride_ok {
        return Err(format!(
            "has a byteStride of {stride}, which mode {mode:?} with filter {filter:?} does not allow"
        ));
    }
    if uint(view, "byteStride").is_some_and(|s| s != stride) {
        return Err(format!(
            "has a byteStride of {stride}, but its bufferView's is {}",
            view["byteStride"]
        ));
    }
    if count == 0 || count > MAX_ELEMENTS {
        return Err(format!(
            "declares {count} elements; decalbake reads 1 to {MAX_ELEMENTS}"
        ));
    }
    if mode == Mode::Triangles && count % 3 != 0 {
        return Err(format!(
            "declares {count} indices in TRIANGLES mode, not a multiple of 3"
        ));
    }
    if uint(view, "byteLength") != Some(stride * count) {
        return Err(format!(
            "declares {count} elements of {stride} bytes, but its bufferView's byteLength is {}",
            view["byteLength"]
        ));
    }
    // What the compressed stream could hold at most (header and tail aside).
    let most = match mode {
        Mode::Attributes => spec.length.saturating_mul(MAX_ATTRIBUTE_RATIO),
        Mode::Triangles => spec.length.saturating_mul(3 * stride),
        Mode::Indices => spec.length.saturating_mul(stride),
    };
    if stride * count > most {
        return Err(format!(
            "declares {count} elements of {stride} bytes ({} bytes), more than {} compressed bytes can hold in {mode:?} mode",
            stride * count,
            spec.length
        ));
    }
    Ok(spec)
}

/// The decoded bytes of `spec`'s stream.
fn decoded(work: &Work, spec: &Spec) -> std::result::Result<Vec<u8>, String> {
    let data = work
        .buffers
        .get(spec.buffer)
        .ok_or_else(|| format!("names buffers[{}], which does not exist", spec.buffer))?;
    let src = spec
        .offset
        .checked_add(spec.length)
        .and_then(|end| data.get(spec.offset..end))
        .ok_or_else(|| {
            format!(
                "reads bytes {} to {} of buffers[{}], which has {} bytes",
                spec.offset,
                spec.offset as u128 + spec.length as u128,
                spec.buffer,
                data.len()
            )
        })?;
    let failed = |e: meshopt::Error| format!("the {:?} stream does not decode ({e})", spec.mode);
    Ok(match (spec.mode, spec.stride) {
        (Mode::Attributes, _) => attributes(src, spec)?,
        (Mode::Triangles, 2) => {
            bytes_of(&meshopt::decode_index_buffer::<u16>(src, spec.count).map_err(failed)?)
        }
        (Mode::Triangles, _) => {
            bytes_of(&meshopt::decode_index_buffer::<u32>(src, spec.count).map_err(failed)?)
        }
        (Mode::Indices, 2) => {
            bytes_of(&meshopt::decode_index_sequence::<u16>(src, spec.count).map_err(failed)?)
        }
        (Mode::Indices, _) => {
            bytes_of(&meshopt::decode_index_sequence::<u32>(src, spec.count).map_err(failed)?)
        }
    })
}

/// Little-endian bytes of decoded indices.
fn bytes_of<T: bytemuck::Pod>(values: &[T]) -> Vec<u8> {
    bytemuck::cast_slice(values).to_vec()
}

/// An `ATTRIBUTES` stream decoded and filtered.
fn attributes(src: &[u8], spec: &Spec) -> std::result::Result<Vec<u8>, String> {
    // u32 words: 4-byte aligned for the filters' views, and the stride a multiple of 4.
    let mut words = vec![0u32; spec.count * spec.stride / 4];
    // SAFETY: `words` holds `count × stride` bytes, what the decoder writes; `parse` checked the
    // stride (a multiple of 4, at most 256) that the decoder asserts; it reads at most
    // `src.len()` bytes of `src`.
    let code = unsafe {
        meshopt::ffi::meshopt_decodeVertexBuffer(
            words.as_mut_ptr().cast(),
            spec.count,
            spec.stride,
            src.as_ptr(),
            src.len(),
        )
    };
    if code != 0 {
        return Err(format!(
            "the ATTRIBUTES stream does not decode (meshoptimizer's error {code})"
        ));
    }
    match (spec.filter, spec.stride) {
        (Filter::None, _) => {}
        (Filter::Octahedral, 4) => {
            meshopt::decode_filter_oct::<i8>(bytemuck::cast_slice_mut(&mut words));
        }
        (Filter::Octahedral, _) => {
            meshopt::decode_filter_oct::<i16>(bytemuck::cast_slice_mut(&mut words));
        }
        (Filter::Quaternion, _) => {
            meshopt::decode_filter_quat(bytemuck::cast_slice_mut(&mut words))
        }
        // Each 32-bit component is decoded alone, so any stride is a run of one-word elements.
        (Filter::Exponential, _) => {
            meshopt::decode_filter_exp::<1>(bytemuck::cast_slice_mut(&mut words));
        }
    }
    Ok(bytemuck::cast_slice(&words).to_vec())
}
