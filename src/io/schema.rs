// SPDX-License-Identifier: MIT OR Apache-2.0
//! JSON Schemas (draft 2020-12) of the job file and of one line of a batch manifest, derived from
//! the serde types the loader reads ([`super::job::JobFile`]), so a field the loader accepts is a
//! field the schema lists: `decalbake schema job|manifest` prints them, editors check and complete
//! job files with them (`"$schema": "job.schema.json"`). Unknown fields are forbidden, as the
//! loader forbids them.
//!
//! The schema checks the shape of a job (fields, types, the words a field takes); the loader
//! checks the rest (ranges, files, combinations of fields that only some layer kinds take) and
//! names the field it refuses.

use super::job::JobFile;
use schemars::JsonSchema;
use std::path::PathBuf;

/// The URI a schema is published under in its `$id` (a name, not fetched).
const ID_BASE: &str = "https://decalbake.invalid/schema";

/// One line of a `decalbake batch` manifest (JSON Lines).
#[derive(serde::Deserialize, JsonSchema)]
#[serde(untagged)]
#[schemars(title = "decalbake manifest line")]
#[allow(dead_code)] // Read only for its schema: `manifest::parse` reads lines itself.
enum ManifestLine {
    /// A job file's path, relative to the manifest.
    Path(PathBuf),
    /// A job itself, with the job file's fields.
    Job(Box<JobFile>),
}

/// Which schema.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Which {
    /// A job file (`decalbake bake`).
    Job,
    /// One line of a batch manifest: a job file's path or a job object.
    Manifest,
}

impl Which {
    /// `"job"` or `"manifest"`.
    pub fn parse(name: &str) -> Option<Self> {
        match name {
            "job" => Some(Which::Job),
            "manifest" => Some(Which::Manifest),
            _ => None,
        }
    }
}

/// The schema as JSON, with `$schema` (draft 2020-12), `$id` and a description.
pub fn schema(which: Which) -> serde_json::Value {
    let (mut s, name, what) = match which {
        Which::Job => (
            schemars::schema_for!(JobFile),
            "job",
            "A decalbake job file: a mesh, its texture, the layers baked onto it in order, and the \
             outputs.",
        ),
        Which::Manifest => (
            schemars::schema_for!(ManifestLine),
            "manifest",
            "One line of a decalbake batch manifest (JSON Lines): a job file's path, relative to \
             the manifest, or a job object.",
        ),
    };
    s.insert("$id".into(), format!("{ID_BASE}/{name}.schema.json").into());
    s.insert("description".into(), what.into());
    s.to_value()
}

/// The schema as pretty JSON text with a final newline, as `decalbake schema` prints it.
pub fn schema_text(which: Which) -> String {
    let mut text = serde_json::to_string_pretty(&schema(which)).expect("a schema serialises");
    text.push('\n');
    text
}

/// Every field of the job schema as a markdown table (field, what it takes, default, meaning),
/// in alphabetical order: the index of `docs/job-file.md`, which a test keeps equal to this. A
/// type used in several places (a point: `at`, `path`, `source`, `animate.route`) has its rows
/// under its shortest path; the others say "as" that path.
pub fn fields_markdown() -> String {
    let s = schema(Which::Job);
    // First pass: every path each shared type is met at; the shortest one gets its rows.
    let mut walk = Walk {
        defs: &s["$defs"],
        home: BTreeMap::new(),
        met: BTreeMap::new(),
        rows: Vec::new(),
    };
    walk.object(&s, "");
    let home = walk
        .met
        .iter()
        .filter_map(|(def, paths)| {
            let best = paths.iter().min_by_key(|p| (p.len(), p.as_str()))?;
            Some((def.clone(), best.clone()))
        })
        .collect();
    let mut walk = Walk {
        defs: &s["$defs"],
        home,
        met: BTreeMap::new(),
        rows: Vec::new(),
    };
    walk.object(&s, "");
    let mut out = String::from("| field | takes | default | meaning |\n|---|---|---|---|\n");
    for row in walk.rows {
        out.push_str(&row);
        out.push('\n');
    }
    out
}

use serde_json::Value;
use std::collections::BTreeMap;

/// A walk over the job schema that writes one row per field.
struct Walk<'a> {
    defs: &'a Value,
    /// The path each shared type's rows go under (empty in the first pass: rows everywhere).
    home: BTreeMap<String, String>,
    /// Every path each type is met at.
    met: BTreeMap<String, Vec<String>>,
    rows: Vec<String>,
}

impl Walk<'_> {
    /// The rows of an object schema's properties under `path`.
    fn object(&mut self, obj: &Value, path: &str) {
        let Some(props) = obj["properties"].as_object() else {
            return;
        };
        for (name, sub) in props {
            let full = if path.is_empty() {
                name.clone()
            } else {
                format!("{path}.{name}")
            };
            let default = sub
                .get("default")
                .filter(|d| !d.is_null())
                .map_or(String::new(), |d| format!("`{d}`"));
            let meaning = sub["description"]
                .as_str()
                .unwrap_or("")
                .replace('\n', " ")
                .replace('|', "\\|");
            let row_at = self.rows.len();
            self.rows.push(String::new());
            let takes = self.takes(sub, &full);
            self.rows[row_at] = format!("| `{full}` | {takes} | {default} | {meaning} |");
        }
    }

    /// What a field's schema takes, in words; the rows of the object types it holds follow it.
    fn takes(&mut self, sub: &Value, path: &str) -> String {
        if let Some(r) = sub.get("$ref").and_then(|r| r.as_str()) {
            let name = r.trim_start_matches("#/$defs/").to_string();
            self.met.entry(name.clone()).or_default().push(path.into());
            if let Some(home) = self.home.get(&name).filter(|h| *h != path) {
                return format!("as `{home}`");
            }
            let def = &self.defs[&name];
            return self.takes(def, path);
        }
        if let Some(values) = sub.get("enum").and_then(|e| e.as_array()) {
            let words: Vec<String> = values
                .iter()
                .filter(|v| !v.is_null())
                .map(|v| format!("`{v}`"))
                .collect();
            return words.join(", ");
        }
        if let Some(branches) = sub.get("anyOf").and_then(|b| b.as_array()) {
            let words: Vec<String> = branches
                .iter()
                .filter(|b| b["type"] != "null")
                .map(|b| self.takes(b, path))
                .collect();
            return words.join("; or ");
        }
        let kind = match &sub["type"] {
            Value::Array(t) => t.iter().find(|t| *t != "null").and_then(|t| t.as_str()),
            t => t.as_str(),
        };
        match kind.unwrap_or("any") {
            "object" if sub.get("properties").is_some() => {
                self.object(sub, path);
                "object".into()
            }
            "object" => match sub.get("additionalProperties") {
                Some(v) if v.is_object() => {
                    let of = self.takes(v, &format!("{path}.<name>"));
                    format!("map of name to {of}")
                }
                _ => "object".into(),
            },
            "array" => {
                let n = sub
                    .get("minItems")
                    .filter(|m| sub.get("maxItems") == Some(*m));
                let item = self.takes(&sub["items"], &format!("{path}[]"));
                match n {
                    Some(n) => format!("{n} × {item}"),
                    None if item.starts_with("as ") => format!("array of items {item}"),
                    None => format!("array of {item}"),
                }
            }
            "integer" if sub.get("minimum").and_then(|m| m.as_f64()) == Some(0.0) => {
                "integer ≥ 0".into()
            }
            other => other.to_string(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn job_schema_is_draft_2020_12_and_forbids_unknown_fields() {
        let s = schema(Which::Job);
        assert_eq!(s["$schema"], "https://json-schema.org/draft/2020-12/schema");
        assert_eq!(s["additionalProperties"], false);
        assert_eq!(s["required"], serde_json::json!(["mesh"]));
        let layer = &s["$defs"]["LayerSpec"];
        assert_eq!(layer["additionalProperties"], false);
        assert!(layer["properties"]["tool"]["enum"]
            .as_array()
            .unwrap()
            .contains(&"clone".into()));
    }
}
