// SPDX-License-Identifier: MIT OR Apache-2.0
//! The batch manifest of `decalbake batch`: JSON Lines, one job per line, either a string (a job
//! file's path, relative to the manifest) or an object (the job itself, the job-file schema).
//! Blank lines are skipped; any other line is an error naming the manifest and the line, and no
//! job of the manifest runs. [`parse`] works on the manifest's text, so the binary reads the file
//! and the fuzzer (`decalbake fuzz --target manifest`) feeds it bytes.

use crate::error::{Error, Result};
use serde_json::Value;
use std::path::{Path, PathBuf};

/// One job of the manifest.
#[derive(Debug, Clone, PartialEq)]
pub struct Entry {
    /// Line number (1-based): the job's number in messages, summaries and output directories.
    pub line: usize,
    /// Where the job's text comes from.
    pub job: EntryJob,
}

/// A manifest line's job.
#[derive(Debug, Clone, PartialEq)]
pub enum EntryJob {
    /// A job file, resolved against the manifest's directory (read when the job runs, so a missing
    /// file fails its own job, not the batch).
    File(PathBuf),
    /// An inline job object, as compact JSON text.
    Inline(String),
}

impl Entry {
    /// The job file of a path entry.
    pub fn file(&self) -> Option<&Path> {
        match &self.job {
            EntryJob::File(f) => Some(f),
            EntryJob::Inline(_) => None,
        }
    }
}

/// The jobs of the manifest `text`; `path` (the manifest) names it in messages and resolves the
/// job files' relative paths. A line that is neither a JSON string nor a JSON object is an
/// [`Error::Job`] whose field is `line N`.
pub fn parse(text: &str, path: &Path) -> Result<Vec<Entry>> {
    let dir = path.parent().unwrap_or(Path::new(""));
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let bad = |why: String| {
            Error::job(
                path,
                format!("line {}", i + 1),
                format!("{why}; each line is a job file's path (a JSON string) or a job object"),
            )
        };
        let job = match serde_json::from_str::<Value>(line).map_err(|e| bad(e.to_string()))? {
            Value::String(p) => EntryJob::File(dir.join(p)),
            v @ Value::Object(_) => EntryJob::Inline(v.to_string()),
            other => return Err(bad(format!("found {other}"))),
        };
        out.push(Entry { line: i + 1, job });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_and_inline_jobs_keep_their_line_numbers() {
        let text = "\"a.json\"\n\n  \r\n{\"mesh\": \"m.glb\"}\r\n";
        let entries = parse(text, Path::new("jobs/m.jsonl")).unwrap();
        assert_eq!(
            entries,
            [
                Entry {
                    line: 1,
                    job: EntryJob::File(PathBuf::from("jobs/a.json"))
                },
                Entry {
                    line: 4,
                    job: EntryJob::Inline("{\"mesh\":\"m.glb\"}".into())
                },
            ]
        );
    }

    #[test]
    fn a_line_that_is_neither_names_the_manifest_and_line() {
        let e = parse("\"a.json\"\n42\n", Path::new("m.jsonl")).unwrap_err();
        assert_eq!(
            e.to_string(),
            "m.jsonl: field `line 2`: found 42; each line is a job file's path (a JSON string) or a job object"
        );
    }
}
