// SPDX-License-Identifier: MIT OR Apache-2.0
//! The batch's journal: what `--resume` trusts. One JSON line per finished job, appended to
//! `journal.jsonl` (`journal-I.jsonl` for shard I of several) in the batch's root (`--out DIR`,
//! else the manifest's folder), written and synced to the disk before the next job's line, after
//! every output of the job is in place:
//!
//! `{"line": 3, "job": "a.json", "input_hash": "…", "out_dir": "…", "outputs": [{"path": "…",
//! "sha256": "…", "bytes": 1234}]}`
//!
//! `--resume` skips a job when a line of any journal in the root has the job's `input_hash` and
//! output folder and every output it lists still has its recorded SHA-256: whether or not the job
//! writes a report. A line cut short by a kill does not parse and is ignored (its job bakes
//! again); a job whose outputs changed or went missing bakes again. Lines are never rewritten:
//! a later line for the same job supersedes nothing, the first that still matches is enough.

use anyhow::{Context, Result};
use serde_json::{json, Value};
use sha2::{Digest, Sha256};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// An open journal and the lines it held when the batch started.
pub struct Journal {
    file: Mutex<std::fs::File>,
    /// The path (for messages).
    pub path: PathBuf,
    /// Every parsed line of every journal in the root when the batch started.
    records: Vec<Value>,
}

impl Journal {
    /// Opens (creates) `root/name` for appending and reads every `journal*.jsonl` in `root`.
    pub fn open(root: &Path, name: &str) -> Result<Self> {
        std::fs::create_dir_all(root).with_context(|| format!("creating {}", root.display()))?;
        let mut records = Vec::new();
        let mut names: Vec<PathBuf> = std::fs::read_dir(root)
            .with_context(|| format!("reading {}", root.display()))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| {
                p.file_name()
                    .and_then(|n| n.to_str())
                    .is_some_and(|n| n.starts_with("journal") && n.ends_with(".jsonl"))
            })
            .collect();
        names.sort();
        for p in names {
            let text = std::fs::read_to_string(&p).unwrap_or_default();
            records.extend(
                text.lines()
                    .filter_map(|l| serde_json::from_str::<Value>(l).ok())
                    .filter(|v| v.is_object()),
            );
        }
        let path = root.join(name);
        let file = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&path)
            .with_context(|| format!("opening the batch journal {}", path.display()))?;
        // A line cut short by a kill is ended, so the next line starts on its own.
        let cut = std::fs::read(&path).is_ok_and(|b| b.last().is_some_and(|&c| c != b'\n'));
        if cut {
            (&file)
                .write_all(b"\n")
                .with_context(|| format!("writing the batch journal {}", path.display()))?;
        }
        Ok(Self {
            file: Mutex::new(file),
            path,
            records,
        })
    }

    /// Whether a line records the job of `hash` into `out_dir` with outputs that still have their
    /// bytes; its output paths when one does.
    pub fn done(&self, hash: &str, out_dir: &Path) -> Option<Vec<String>> {
        let out_dir = out_dir.display().to_string();
        self.records
            .iter()
            .filter(|r| r["input_hash"] == hash && r["out_dir"] == out_dir.as_str())
            .find_map(|r| {
                let outputs = r["outputs"].as_array()?;
                let mut paths = Vec::new();
                for o in outputs {
                    let path = o["path"].as_str()?;
                    if sha256_of(Path::new(path)).ok()? != o["sha256"].as_str()? {
                        return None;
                    }
                    paths.push(path.to_string());
                }
                Some(paths)
            })
    }

    /// Appends the finished job's line (its outputs hashed now, as they lie on the disk) and
    /// syncs it to the disk.
    pub fn record(
        &self,
        (line, job): (usize, Option<&Path>),
        hash: &str,
        out_dir: &Path,
        outputs: &[PathBuf],
    ) -> Result<()> {
        let mut files = Vec::with_capacity(outputs.len());
        for p in outputs {
            let bytes = std::fs::metadata(p)
                .with_context(|| format!("reading the output {}", p.display()))?
                .len();
            files.push(
                json!({ "path": p.display().to_string(), "sha256": sha256_of(p)?,
                "bytes": bytes }),
            );
        }
        let row = json!({ "line": line, "job": job.map(|j| j.display().to_string()),
            "input_hash": hash, "out_dir": out_dir.display().to_string(), "outputs": files });
        let mut text = serde_json::to_string(&row)?;
        text.push('\n');
        let file = self.file.lock().expect("journal");
        (&*file)
            .write_all(text.as_bytes())
            .and_then(|_| file.sync_data())
            .with_context(|| format!("writing the batch journal {}", self.path.display()))
    }
}

/// The file's SHA-256, in hex.
fn sha256_of(path: &Path) -> Result<String> {
    let mut f = std::fs::File::open(path).with_context(|| format!("reading {}", path.display()))?;
    let mut h = Sha256::new();
    std::io::copy(&mut f, &mut h).with_context(|| format!("reading {}", path.display()))?;
    Ok(format!("{:x}", h.finalize()))
}
