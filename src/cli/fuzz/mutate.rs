// SPDX-License-Identifier: MIT OR Apache-2.0
//! The fuzzer's mutations. Every choice is made by an [`arbitrary::Unstructured`] over
//! pseudo-random bytes ([`Rng`], SplitMix64), so a run is a function of its seed.
//!
//! - **Byte havoc** ([`havoc`]), for every target: 1 to 8 stacked operations among bit flips,
//!   random bytes, interesting integers (8 to 64 bits, little- or big-endian, at any offset or a
//!   4-byte-aligned one: GLB chunk lengths are little-endian words, PNG and JPEG sizes big-endian),
//!   small additions, inserts, deletes, duplicated and overwritten chunks, splices with another
//!   corpus entry, dictionary tokens, truncation and runs of one byte.
//! - **JSON trees** ([`mutate_json`]), for job files, manifest lines, `.gltf` files and a GLB's
//!   JSON chunk: a node of the parsed `serde_json::Value` replaced by an interesting value (0, -1,
//!   2³², 1e308, `1e999` and `NaN` written raw, NaN-like strings, empty and huge arrays, long
//!   strings, deep nesting), given the wrong type, nudged, wrapped, or swapped for a subtree of
//!   another corpus entry; object keys dropped, duplicated (written twice in the text) or added from
//!   the keys the seeds use; array elements dropped or duplicated.
//! - **Containers**: a GLB is rebuilt with consistent chunk lengths after its JSON or its binary
//!   chunk was mutated (a whole-file havoc keeps the inconsistent ones too); a `.gltf`'s data URIs
//!   are decoded, havocked and encoded again; PNG chunk CRCs are recomputed after a mutation (in an
//!   image, a GLB's binary chunk or a data URI), so the decoder gets past its checksums.

use arbitrary::{Result, Unstructured};
use serde_json::{Map, Value};

/// SplitMix64.
pub struct Rng(u64);

impl Rng {
    /// A generator seeded with `seed`.
    pub fn new(seed: u64) -> Self {
        Rng(seed)
    }

    /// The next 64 bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Fills `buf` with pseudo-random bytes.
    pub fn fill(&mut self, buf: &mut [u8]) {
        for c in buf.chunks_mut(8) {
            let v = self.next_u64().to_le_bytes();
            c.copy_from_slice(&v[..c.len()]);
        }
    }
}

/// How a target's inputs are structured.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Shape {
    /// One JSON document (a job file).
    Json,
    /// JSON Lines (a manifest).
    Lines,
    /// A binary glTF container.
    Glb,
    /// glTF JSON with data URIs.
    Gltf,
    /// Encoded image bytes.
    Image,
}

/// What mutations draw on besides the input: the other corpus entries and the seeds' keys.
pub struct Pool<'a> {
    /// The corpus (splices, donor subtrees).
    pub entries: &'a [Vec<u8>],
    /// Every object key the seeds use.
    pub keys: &'a [String],
    /// The longest input produced.
    pub max_len: usize,
}

/// A mutation of `input`; `input` itself when the random bytes ran out.
pub fn mutate(shape: Shape, input: &[u8], pool: &Pool, u: &mut Unstructured) -> Vec<u8> {
    let mut out = match structured(shape, input, pool, u) {
        Ok(Some(v)) => v,
        _ => {
            let mut v = input.to_vec();
            let _ = havoc(&mut v, pool, u);
            if shape == Shape::Image && u.ratio(1, 2).unwrap_or(false) {
                fix_png_crcs(&mut v);
            }
            v
        }
    };
    out.truncate(pool.max_len);
    out
}

/// A structure-aware mutation where the shape has one and the input parses (`None`: use havoc).
fn structured(
    shape: Shape,
    input: &[u8],
    pool: &Pool,
    u: &mut Unstructured,
) -> Result<Option<Vec<u8>>> {
    match shape {
        Shape::Json => {
            if !u.ratio(2, 3)? {
                return Ok(None);
            }
            let Ok(mut v) = serde_json::from_slice::<Value>(input) else {
                return Ok(None);
            };
            mutate_json(&mut v, pool, u)?;
            Ok(Some(to_text(&v, u.ratio(1, 4)?).into_bytes()))
        }
        Shape::Lines => lines(input, pool, u),
        Shape::Glb => glb(input, pool, u),
        Shape::Gltf => gltf(input, pool, u),
        Shape::Image => Ok(None),
    }
}

/// A manifest: one line mutated as JSON, or lines dropped, duplicated or swapped.
fn lines(input: &[u8], pool: &Pool, u: &mut Unstructured) -> Result<Option<Vec<u8>>> {
    if !u.ratio(2, 3)? {
        return Ok(None);
    }
    let text = String::from_utf8_lossy(input);
    let mut lines: Vec<String> = text.split('\n').map(String::from).collect();
    let k = u.choose_index(lines.len())?;
    match u.choose_index(5)? {
        0 => {
            lines.remove(k);
        }
        1 => {
            let l = lines[k].clone();
            lines.insert(u.choose_index(lines.len() + 1)?, l);
        }
        2 => {
            let j = u.choose_index(lines.len())?;
            lines.swap(k, j);
        }
        3 => {
            let blank = *u.choose(&["", " ", "\r", "\t \r", "\u{feff}"])?;
            lines.insert(k, blank.to_string());
        }
        _ => {
            let Ok(mut v) = serde_json::from_str::<Value>(lines[k].trim_end_matches('\r')) else {
                return Ok(None);
            };
            mutate_json(&mut v, pool, u)?;
            lines[k] = to_text(&v, false);
        }
    }
    Ok(Some(lines.join("\n").into_bytes()))
}

/// A GLB: its JSON chunk mutated as a tree, or its binary chunk havocked, and the container
/// rebuilt with consistent lengths.
fn glb(input: &[u8], pool: &Pool, u: &mut Unstructured) -> Result<Option<Vec<u8>>> {
    let Some(mut chunks) = glb_chunks(input) else {
        return Ok(None);
    };
    match u.choose_index(5)? {
        0 | 1 => {
            let Some(json) = chunks.iter_mut().find(|c| &c.0 == b"JSON") else {
                return Ok(None);
            };
            let Ok(mut v) = serde_json::from_slice::<Value>(&json.1) else {
                return Ok(None);
            };
            mutate_json(&mut v, pool, u)?;
            json.1 = to_text(&v, false).into_bytes();
        }
        2 | 3 => {
            let Some(bin) = chunks.iter_mut().find(|c| &c.0 == b"BIN\0") else {
                return Ok(None);
            };
            havoc(&mut bin.1, pool, u)?;
            if u.ratio(1, 2)? {
                fix_png_crcs(&mut bin.1);
            }
        }
        _ => return Ok(None),
    }
    Ok(Some(glb_build(&chunks, u.ratio(7, 8)?)))
}

/// A `.gltf`: the tree mutated, or one data URI's bytes havocked.
fn gltf(input: &[u8], pool: &Pool, u: &mut Unstructured) -> Result<Option<Vec<u8>>> {
    if !u.ratio(4, 5)? {
        return Ok(None);
    }
    let Ok(mut v) = serde_json::from_slice::<Value>(input) else {
        return Ok(None);
    };
    let mut uris = Vec::new();
    collect_data_uris(&mut v, &mut uris);
    if !uris.is_empty() && u.ratio(1, 3)? {
        let k = u.choose_index(uris.len())?;
        let uri = &mut *uris[k];
        if let Value::String(s) = uri {
            if let Some((head, b64)) = s.split_once(";base64,") {
                let head = head.to_string();
                let mut bytes = base64_decode(b64);
                havoc(&mut bytes, pool, u)?;
                if u.ratio(1, 2)? {
                    fix_png_crcs(&mut bytes);
                }
                *s = format!("{head};base64,{}", base64_encode(&bytes));
            }
        }
    } else {
        drop(uris);
        mutate_json(&mut v, pool, u)?;
    }
    Ok(Some(to_text(&v, u.ratio(1, 4)?).into_bytes()))
}

fn collect_data_uris<'a>(v: &'a mut Value, out: &mut Vec<&'a mut Value>) {
    match v {
        Value::String(s) if s.starts_with("data:") => out.push(v),
        Value::Array(a) => a.iter_mut().for_each(|x| collect_data_uris(x, out)),
        Value::Object(m) => m.values_mut().for_each(|x| collect_data_uris(x, out)),
        _ => {}
    }
}

/// The chunks (type, data) of a GLB, if its header and chunk lengths are consistent.
pub fn glb_chunks(b: &[u8]) -> Option<Vec<([u8; 4], Vec<u8>)>> {
    if b.len() < 12 || &b[..4] != b"glTF" {
        return None;
    }
    let mut chunks = Vec::new();
    let mut at = 12;
    while at + 8 <= b.len() {
        let len = u32::from_le_bytes(b[at..at + 4].try_into().ok()?) as usize;
        let kind: [u8; 4] = b[at + 4..at + 8].try_into().ok()?;
        let data = b.get(at + 8..at + 8 + len)?;
        chunks.push((kind, data.to_vec()));
        at += 8 + len;
    }
    Some(chunks)
}

/// GLB bytes of `chunks` (the JSON chunk padded with spaces, others with zeros, when `pad`).
pub fn glb_build(chunks: &[([u8; 4], Vec<u8>)], pad: bool) -> Vec<u8> {
    let mut body = Vec::new();
    for (kind, data) in chunks {
        let mut data = data.clone();
        while pad && !data.len().is_multiple_of(4) {
            data.push(if kind == b"JSON" { b' ' } else { 0 });
        }
        body.extend_from_slice(&(data.len() as u32).to_le_bytes());
        body.extend_from_slice(kind);
        body.extend_from_slice(&data);
    }
    let mut out = b"glTF".to_vec();
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&((12 + body.len()) as u32).to_le_bytes());
    out.extend_from_slice(&body);
    out
}

/// Interesting little integers for bytes, words and JSON numbers.
const INTERESTING: &[i64] = &[
    0,
    1,
    -1,
    2,
    3,
    4,
    7,
    8,
    12,
    16,
    32,
    64,
    127,
    128,
    255,
    256,
    1000,
    1024,
    4096,
    5120,
    5121,
    5123,
    5125,
    5126,
    16383,
    16384,
    16385,
    32767,
    32768,
    65535,
    65536,
    1 << 20,
    100_000_000,
    1 << 30,
    i32::MAX as i64,
    1 << 31,
    u32::MAX as i64,
    1 << 32,
    1 << 53,
    i64::MAX,
    i64::MIN,
];

/// Tokens spliced into bytes: JSON punctuation and the formats' magic and chunk names.
const DICT: &[&[u8]] = &[
    b"\"",
    b"{",
    b"}",
    b"[",
    b"]",
    b",",
    b":",
    b"null",
    b"true",
    b"-",
    b"1e999",
    b"\\u0000",
    b"\\ud800",
    b"glTF",
    b"JSON",
    b"BIN\0",
    b"\x89PNG\r\n\x1a\n",
    b"IHDR",
    b"IDAT",
    b"IEND",
    b"PLTE",
    b"tRNS",
    b"\xff\xd8",
    b"\xff\xc0",
    b"\xff\xc2",
    b"\xff\xc4",
    b"\xff\xda",
    b"\xff\xdb",
    b"\xff\xd9",
    b"data:application/octet-stream;base64,",
    b"data:image/png;base64,",
    b"%FF",
];

/// 1 to 8 stacked byte operations on `b` (see the module doc).
pub fn havoc(b: &mut Vec<u8>, pool: &Pool, u: &mut Unstructured) -> Result<()> {
    let n = 1usize << u.int_in_range(0..=3)?;
    for _ in 0..n {
        havoc_one(b, pool, u)?;
    }
    Ok(())
}

/// An offset in `b` (4-byte aligned half of the time), for writing `width` bytes.
fn offset(b: &[u8], width: usize, u: &mut Unstructured) -> Result<Option<usize>> {
    if b.len() < width {
        return Ok(None);
    }
    let at = u.int_in_range(0..=b.len() - width)?;
    Ok(Some(if u.ratio(1, 2)? { at & !3 } else { at }))
}

fn havoc_one(b: &mut Vec<u8>, pool: &Pool, u: &mut Unstructured) -> Result<()> {
    let len = b.len();
    match u.choose_index(15)? {
        0 => {
            if len > 0 {
                let at = u.choose_index(len)?;
                b[at] ^= 1 << u.int_in_range(0..=7)?;
            }
        }
        1 => {
            if len > 0 {
                let at = u.choose_index(len)?;
                b[at] = u.arbitrary()?;
            }
        }
        2..=4 => {
            let width = *u.choose(&[1usize, 2, 4, 8])?;
            let v = *u.choose(INTERESTING)?;
            let v = if u.ratio(1, 4)? { v.wrapping_neg() } else { v };
            let bytes = if u.ratio(1, 3)? {
                v.to_be_bytes()[8 - width..].to_vec()
            } else {
                v.to_le_bytes()[..width].to_vec()
            };
            if let Some(at) = offset(b, width, u)? {
                b[at..at + width].copy_from_slice(&bytes);
            }
        }
        5 => {
            let width = *u.choose(&[1usize, 2, 4])?;
            if let Some(at) = offset(b, width, u)? {
                let mut w = [0u8; 4];
                w[..width].copy_from_slice(&b[at..at + width]);
                let d = u.int_in_range(1..=35)? as u32;
                let v = u32::from_le_bytes(w);
                let v = if u.arbitrary()? {
                    v.wrapping_add(d)
                } else {
                    v.wrapping_sub(d)
                };
                b[at..at + width].copy_from_slice(&v.to_le_bytes()[..width]);
            }
        }
        6 => {
            let at = u.int_in_range(0..=len)?;
            let n = u.int_in_range(1..=64)?;
            let bytes: Vec<u8> = (0..n).map(|_| u.arbitrary()).collect::<Result<_>>()?;
            b.splice(at..at, bytes);
        }
        7 => {
            if len > 1 {
                let at = u.choose_index(len)?;
                let n = u.int_in_range(1..=(len - at).min(len / 4 + 1))?;
                b.drain(at..at + n);
            }
        }
        8 | 9 => {
            // A chunk of the input duplicated at (8) or copied over (9) another place.
            if len > 1 {
                let from = u.choose_index(len)?;
                let n = u.int_in_range(1..=(len - from).min(256))?;
                let chunk = b[from..from + n].to_vec();
                let to = u.int_in_range(0..=len)?;
                if u.ratio(1, 2)? {
                    b.splice(to..to, chunk);
                } else {
                    let end = (to + n).min(len);
                    b.splice(to..end, chunk);
                }
            }
        }
        10 => {
            // Splice: this input's head and another entry's tail.
            let other = &pool.entries[u.choose_index(pool.entries.len())?];
            let cut = u.int_in_range(0..=len)?;
            let from = u.int_in_range(0..=other.len())?;
            b.truncate(cut);
            b.extend_from_slice(&other[from..]);
        }
        11 => {
            let token = *u.choose(DICT)?;
            let at = u.int_in_range(0..=len)?;
            if u.ratio(1, 2)? || at + token.len() > len {
                b.splice(at..at, token.iter().copied());
            } else {
                b[at..at + token.len()].copy_from_slice(token);
            }
        }
        12 => {
            let at = u.int_in_range(0..=len)?;
            b.truncate(at);
        }
        13 => {
            if len > 0 {
                let at = u.choose_index(len)?;
                let n = u.int_in_range(1..=(len - at).min(64))?;
                let v = *u.choose(&[0u8, 0xff, 0x7f, 0x80, b'9', b' '])?;
                b[at..at + n].fill(v);
            }
        }
        _ => {
            // The same input again with one byte at a random place.
            let at = u.int_in_range(0..=len)?;
            b.insert(at, u.arbitrary()?);
        }
    }
    Ok(())
}

/// Marks in strings that [`to_text`] turns into raw text: a value written as is, a key written
/// a second time.
const RAW: &str = "\u{0}raw:";
const DUP: &str = "\u{0}dup:";

/// Raw values no `Value` can hold.
const RAW_VALUES: &[&str] = &[
    "1e999",
    "-1e999",
    "NaN",
    "Infinity",
    "-0",
    "1E+400",
    "0.0000000000000000000000000000000000000000000001",
    "18446744073709551616",
    "-9223372036854775809",
    "340282356779733661637539395458142568448",
    "00012",
    "1.",
    "[1,]",
    "{\"a\":1,}",
];

/// The serialized tree: marks of [`RAW`] strings written raw, [`DUP`] keys as their key.
pub fn to_text(v: &Value, pretty: bool) -> String {
    let text = if pretty {
        serde_json::to_string_pretty(v)
    } else {
        serde_json::to_string(v)
    }
    .unwrap_or_default();
    if !text.contains("\\u0000") {
        return text;
    }
    let text = text.replace("\"\\u0000dup:", "\"");
    let mut out = String::with_capacity(text.len());
    let mut rest = text.as_str();
    while let Some(i) = rest.find("\"\\u0000raw:") {
        out.push_str(&rest[..i]);
        let after = &rest[i + "\"\\u0000raw:".len()..];
        // The closing quote: the first one no backslash escapes.
        let (mut end, mut escaped) = (after.len(), false);
        for (j, c) in after.char_indices() {
            match c {
                '"' if !escaped => {
                    end = j;
                    break;
                }
                '\\' => escaped = !escaped,
                _ => escaped = false,
            }
        }
        out.push_str(&after[..end].replace("\\\"", "\""));
        rest = &after[(end + 1).min(after.len())..];
    }
    out.push_str(rest);
    out
}

/// Number of nodes in the tree.
fn count(v: &Value) -> usize {
    1 + match v {
        Value::Array(a) => a.iter().map(count).sum(),
        Value::Object(m) => m.values().map(count).sum(),
        _ => 0,
    }
}

/// The `k`-th node in pre-order.
fn nth(v: &mut Value, k: usize) -> Option<&mut Value> {
    if k == 0 {
        return Some(v);
    }
    let mut k = k - 1;
    let children: Vec<&mut Value> = match v {
        Value::Array(a) => a.iter_mut().collect(),
        Value::Object(m) => m.values_mut().collect(),
        _ => return None,
    };
    for c in children {
        let n = count(c);
        if k < n {
            return nth(c, k);
        }
        k -= n;
    }
    None
}

/// A random subtree of a random corpus entry that parses as JSON (or of a GLB's JSON chunk).
fn donor(pool: &Pool, u: &mut Unstructured) -> Result<Option<Value>> {
    let entry = &pool.entries[u.choose_index(pool.entries.len())?];
    let parsed = serde_json::from_slice::<Value>(entry).ok().or_else(|| {
        glb_chunks(entry)?
            .into_iter()
            .find(|c| &c.0 == b"JSON")
            .and_then(|c| serde_json::from_slice(&c.1).ok())
    });
    let Some(mut v) = parsed else {
        return Ok(None);
    };
    let k = u.choose_index(count(&v))?;
    Ok(nth(&mut v, k).map(|n| n.take()))
}

/// An interesting value of the same JSON type as `v` where there is one (numbers for numbers,
/// strings for strings), else any interesting value.
fn interesting_like(v: &Value, u: &mut Unstructured) -> Result<Value> {
    Ok(match v {
        Value::Number(_) => match u.choose_index(3)? {
            0 => Value::from(*u.choose(INTERESTING)?),
            1 => Value::from(*u.choose(FLOATS)?),
            _ => Value::String(format!("{RAW}{}", u.choose(RAW_NUMBERS)?)),
        },
        Value::String(_) => Value::from(*u.choose(STRINGS)?),
        Value::Bool(b) => Value::Bool(!b),
        _ => interesting(u)?,
    })
}

const FLOATS: &[f64] = &[
    1e308,
    -1e308,
    f64::MAX,
    f64::MIN_POSITIVE,
    5e-324,
    3.5e38,
    -3.5e38,
    0.5,
    -0.0,
    1e-7,
    1e-20,
    1e30,
    1e31,
    4294967296.5,
];

/// Raw numbers no `Value` holds as written.
const RAW_NUMBERS: &[&str] = &[
    "1e999",
    "-1e999",
    "-0",
    "1E+400",
    "0.0000000000000000000000000000000000000000000001",
    "18446744073709551616",
    "-9223372036854775809",
    "340282356779733661637539395458142568448",
];

const STRINGS: &[&str] = &[
    "NaN",
    "nan",
    "inf",
    "-Infinity",
    "",
    " ",
    "0",
    "1e999",
    "auto",
    "full",
    "material",
    "stroke",
    "decal",
    "{uv}",
    "%FF",
    "data:",
    "../",
    "\u{0}",
    "planar",
    "expmap",
    "lscm",
    "hybrid",
    "paint",
    "blur",
    "smear",
    "clone",
    "fixed",
    "path",
    "fast",
    "smooth",
    "SCALAR",
    "VEC2",
    "VEC3",
    "VEC4",
    "MAT4",
    "image/png",
    "image/jpeg",
    "data:image/png;base64,",
    "data:application/octet-stream;base64,",
    "file:///dev/zero",
    "a%ZZb",
    "..\\..\\x",
];

/// An interesting JSON value (see the module doc).
fn interesting(u: &mut Unstructured) -> Result<Value> {
    Ok(match u.choose_index(14)? {
        0..=2 => Value::from(*u.choose(INTERESTING)?),
        3 => Value::from(*u.choose(FLOATS)?),
        4 => Value::String(format!("{RAW}{}", u.choose(RAW_VALUES)?)),
        5 => Value::from(*u.choose(STRINGS)?),
        6 => Value::Array(Vec::new()),
        7 => Value::Object(Map::new()),
        8 => {
            let n = *u.choose(&[3usize, 4, 100, 10_000])?;
            let fill = Value::from(*u.choose(&[0i64, 1, -1, 65535])?);
            Value::Array(vec![fill; n])
        }
        9 => Value::String("A".repeat(*u.choose(&[256usize, 65536])?)),
        10 => {
            let depth = u.int_in_range(20..=300)?;
            let mut v = Value::from(0);
            for _ in 0..depth {
                v = if u.ratio(1, 2)? {
                    Value::Array(vec![v])
                } else {
                    let mut m = Map::new();
                    m.insert("a".into(), v);
                    Value::Object(m)
                };
            }
            v
        }
        11 => Value::Bool(u.arbitrary()?),
        12 => Value::Null,
        _ => {
            let v: [f64; 3] = [
                *u.choose(&[0.0, 1.0, -1.0, 1e30, 1e31])?,
                *u.choose(&[0.0, 0.5, 1e-20])?,
                *u.choose(&[0.0, -0.5, 3.5e38])?,
            ];
            Value::from(v.to_vec())
        }
    })
}

/// The same value as another type (a number as a string, an object as an array, ...).
fn retype(v: &Value, u: &mut Unstructured) -> Result<Value> {
    Ok(match v {
        Value::Number(n) => {
            if u.ratio(1, 2)? {
                Value::String(n.to_string())
            } else {
                Value::Array(vec![v.clone()])
            }
        }
        Value::String(s) => s
            .parse::<f64>()
            .ok()
            .map(Value::from)
            .unwrap_or_else(|| Value::from(s.len())),
        Value::Array(a) => Value::Object(
            a.iter()
                .enumerate()
                .map(|(i, x)| (i.to_string(), x.clone()))
                .collect(),
        ),
        Value::Object(m) => Value::Array(m.values().cloned().collect()),
        Value::Bool(b) => Value::from(*b as i64),
        Value::Null => Value::from(0),
    })
}

/// 1 (half the time) to 4 structure-aware mutations of the tree `v` (see the module doc).
pub fn mutate_json(v: &mut Value, pool: &Pool, u: &mut Unstructured) -> Result<()> {
    let n = if u.ratio(1, 2)? {
        1
    } else {
        u.int_in_range(2..=4)?
    };
    for _ in 0..n {
        let k = u.choose_index(count(v))?;
        let donor = if u.ratio(1, 8)? {
            donor(pool, u)?
        } else {
            None
        };
        let Some(node) = nth(v, k) else {
            continue;
        };
        mutate_node(node, donor, pool, u)?;
    }
    Ok(())
}

fn mutate_node(
    node: &mut Value,
    donor: Option<Value>,
    pool: &Pool,
    u: &mut Unstructured,
) -> Result<()> {
    if let Some(d) = donor {
        *node = d;
        return Ok(());
    }
    match (u.choose_index(8)?, &mut *node) {
        (0, Value::Object(m)) if !m.is_empty() => {
            let key = m
                .keys()
                .nth(u.choose_index(m.len())?)
                .cloned()
                .unwrap_or_default();
            match u.choose_index(3)? {
                0 => {
                    m.remove(&key);
                }
                1 => {
                    let val = m[&key].clone();
                    m.insert(format!("{DUP}{key}"), val);
                }
                _ => {
                    let val = m.remove(&key).unwrap_or(Value::Null);
                    let to = u.choose(pool.keys)?.clone();
                    m.insert(to, val);
                }
            }
        }
        (1, Value::Object(m)) => {
            let key = if u.ratio(7, 8)? {
                u.choose(pool.keys)?.clone()
            } else {
                "unknown_field".into()
            };
            m.insert(key, interesting(u)?);
        }
        (0 | 1, Value::Array(a)) if !a.is_empty() => {
            let k = u.choose_index(a.len())?;
            match u.choose_index(3)? {
                0 => {
                    a.remove(k);
                }
                1 => {
                    let x = a[k].clone();
                    a.insert(u.choose_index(a.len() + 1)?, x);
                }
                _ => a.clear(),
            }
        }
        (2, Value::Number(n)) => {
            let x = n.as_f64().unwrap_or(0.0);
            let y = match u.choose_index(6)? {
                0 => x + 1.0,
                1 => x - 1.0,
                2 => -x,
                3 => x * 65536.0,
                4 => x / 3.0,
                _ => x * 1e30,
            };
            *node = if y.fract() == 0.0 && y.abs() < 9e15 {
                Value::from(y as i64)
            } else {
                Value::from(y)
            };
        }
        (3, _) => *node = retype(node, u)?,
        (7, _) => *node = interesting(u)?,
        (4, _) => {
            let inner = node.take();
            *node = if u.ratio(1, 2)? {
                Value::Array(vec![inner])
            } else {
                let mut m = Map::new();
                m.insert(u.choose(pool.keys)?.clone(), inner);
                Value::Object(m)
            };
        }
        _ => *node = interesting_like(node, u)?,
    }
    Ok(())
}

/// Recomputes the CRC of every chunk of each PNG in `b` (found by its signature), so that
/// mutations inside chunks reach the decoder.
pub fn fix_png_crcs(b: &mut [u8]) {
    const SIG: &[u8] = b"\x89PNG\r\n\x1a\n";
    let mut from = 0;
    while let Some(i) = b[from..].windows(8).position(|w| w == SIG) {
        let mut at = from + i + 8;
        while at + 12 <= b.len() {
            let len = u32::from_be_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]) as usize;
            let Some(end) = (at + 8).checked_add(len).filter(|e| e + 4 <= b.len()) else {
                break;
            };
            let crc = crc32(&b[at + 4..end]);
            b[end..end + 4].copy_from_slice(&crc.to_be_bytes());
            at = end + 4;
        }
        from = from + i + 8;
    }
}

/// CRC-32 (ISO-HDLC, as PNG uses).
fn crc32(data: &[u8]) -> u32 {
    let mut c = !0u32;
    for &x in data {
        c ^= x as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xedb8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}

const B64: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

/// Standard base64 with padding.
pub fn base64_encode(b: &[u8]) -> String {
    let mut out = String::with_capacity(b.len().div_ceil(3) * 4);
    for c in b.chunks(3) {
        let n = (c[0] as u32) << 16
            | (*c.get(1).unwrap_or(&0) as u32) << 8
            | *c.get(2).unwrap_or(&0) as u32;
        for k in 0..4 {
            if k <= c.len() {
                out.push(B64[(n >> (18 - 6 * k)) as usize & 63] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// Standard base64; characters outside the alphabet are skipped.
pub fn base64_decode(s: &str) -> Vec<u8> {
    let mut out = Vec::with_capacity(s.len() / 4 * 3);
    let (mut acc, mut bits) = (0u32, 0);
    for c in s.bytes() {
        let Some(v) = B64.iter().position(|&x| x == c) else {
            continue;
        };
        acc = acc << 6 | v as u32;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_round_trips() {
        for n in 0..10 {
            let b: Vec<u8> = (0..n).map(|i| (i * 37 + 5) as u8).collect();
            assert_eq!(base64_decode(&base64_encode(&b)), b);
        }
        assert_eq!(base64_encode(b"glTF"), "Z2xURg==");
    }

    #[test]
    fn raw_and_duplicate_marks_become_text() {
        let v = serde_json::json!({"a": format!("{RAW}1e999"), format!("{DUP}a"): 2});
        // The duplicate sorts first (`serde_json`'s map is ordered, and `\0` comes first).
        assert_eq!(to_text(&v, false), "{\"a\":2,\"a\":1e999}");
    }
}
