// SPDX-License-Identifier: MIT OR Apache-2.0
//! The shape `ARCHITECTURE.md` promises, checked by reading `src/` (no GPU): each folder imports
//! only from the folders before it in pipeline order, no module imports form a circle, and no
//! function is longer than a screen and a half without saying why in its doc comment.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The library's folders (and top-level files) in pipeline order.
const ORDER: &[&str] = &[
    "error", "gpu", "io", "mesh", "solve", "place", "maps", "pelt", "bake", "output",
];

/// Longest function without a stated reason (lines from `fn` to its closing brace).
const MAX_FN_LINES: usize = 160;

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap().filter_map(|e| e.ok()) {
        let p = e.path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// The library's modules (`bake::maps`, `""` for the crate root) and their files; the binary
/// (`src/cli`) is not part of the library.
fn modules() -> BTreeMap<String, PathBuf> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let mut mods = BTreeMap::new();
    for f in files {
        let rel = f.strip_prefix(&src).unwrap().with_extension("");
        let mut parts: Vec<String> = rel
            .components()
            .map(|c| c.as_os_str().to_string_lossy().into_owned())
            .collect();
        if parts[0] == "cli" {
            continue;
        }
        if parts.last().is_some_and(|p| p == "mod" || p == "lib") {
            parts.pop();
        }
        mods.insert(parts.join("::"), f);
    }
    mods
}

/// Code lines without `//` comments.
fn code(path: &Path) -> String {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .filter(|l| !l.trim_start().starts_with("//"))
        .collect::<Vec<_>>()
        .join("\n")
}

/// Every `crate::a::b` and `super::a` path in `text`, as segments.
fn paths(text: &str) -> Vec<Vec<String>> {
    let mut out = Vec::new();
    let bytes = text.as_bytes();
    for start in ["crate::", "super::"] {
        let mut from = 0;
        while let Some(i) = text[from..].find(start) {
            let i = from + i;
            from = i + start.len();
            if i > 0 && (bytes[i - 1].is_ascii_alphanumeric() || bytes[i - 1] == b'_') {
                continue;
            }
            let mut end = i;
            while end < bytes.len()
                && (bytes[end].is_ascii_alphanumeric() || bytes[end] == b'_' || bytes[end] == b':')
            {
                end += 1;
            }
            out.push(
                text[i..end]
                    .split("::")
                    .filter(|s| !s.is_empty())
                    .map(String::from)
                    .collect(),
            );
        }
    }
    out
}

/// The module a path in module `cur` names (the longest known prefix), if any.
fn resolve(mods: &BTreeMap<String, PathBuf>, cur: &str, path: &[String]) -> Option<String> {
    let mut base: Vec<String> = if cur.is_empty() {
        Vec::new()
    } else {
        cur.split("::").map(String::from).collect()
    };
    let mut segs = path;
    if segs[0] == "crate" {
        base.clear();
        segs = &segs[1..];
    } else {
        while segs.first().is_some_and(|s| s == "super") {
            base.pop();
            segs = &segs[1..];
        }
    }
    let full: Vec<String> = base.into_iter().chain(segs.iter().cloned()).collect();
    (1..=full.len())
        .rev()
        .map(|k| full[..k].join("::"))
        .find(|m| mods.contains_key(m))
}

/// Module → the other modules it names (parents and children excluded: a folder's `mod.rs`
/// declares its children, and children may use what their parent re-exports).
fn graph() -> BTreeMap<String, BTreeSet<String>> {
    let mods = modules();
    let mut g = BTreeMap::new();
    for (m, f) in &mods {
        let deps: BTreeSet<String> = paths(&code(f))
            .iter()
            .filter_map(|p| resolve(&mods, m, p))
            .filter(|d| {
                d != m
                    && !d.is_empty()
                    && !m.starts_with(&format!("{d}::"))
                    && !d.starts_with(&format!("{m}::"))
            })
            .collect();
        g.insert(m.clone(), deps);
    }
    g
}

fn top(m: &str) -> &str {
    m.split("::").next().unwrap()
}

#[test]
fn folders_import_only_earlier_folders() {
    let mut bad = Vec::new();
    for (m, deps) in graph() {
        let Some(mine) = ORDER.iter().position(|t| *t == top(&m)) else {
            continue;
        };
        for d in deps {
            if let Some(theirs) = ORDER.iter().position(|t| *t == top(&d)) {
                if theirs > mine {
                    bad.push(format!("{m} uses {d}"));
                }
            }
        }
    }
    assert!(
        bad.is_empty(),
        "imports against the pipeline order {ORDER:?} (see ARCHITECTURE.md):\n{}",
        bad.join("\n")
    );
}

#[test]
fn no_import_circles() {
    let g = graph();
    // Depth-first search; a back edge closes a circle.
    fn visit(
        u: &str,
        g: &BTreeMap<String, BTreeSet<String>>,
        state: &mut BTreeMap<String, u8>,
        stack: &mut Vec<String>,
        found: &mut Vec<String>,
    ) {
        state.insert(u.to_string(), 1);
        stack.push(u.to_string());
        for v in &g[u] {
            match state.get(v) {
                Some(1) => {
                    let k = stack.iter().position(|s| s == v).unwrap();
                    found.push(format!("{} -> {v}", stack[k..].join(" -> ")));
                }
                None => visit(v, g, state, stack, found),
                _ => {}
            }
        }
        stack.pop();
        state.insert(u.to_string(), 2);
    }
    let (mut state, mut found) = (BTreeMap::new(), Vec::new());
    for m in g.keys() {
        if !state.contains_key(m) {
            visit(m, &g, &mut state, &mut Vec::new(), &mut found);
        }
    }
    assert!(
        g.len() > 30,
        "expected the library's modules, found {}",
        g.len()
    );
    assert!(found.is_empty(), "import circles:\n{}", found.join("\n"));
}

#[test]
fn long_functions_say_why() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let mut bad = Vec::new();
    for f in files {
        let text = std::fs::read_to_string(&f).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        for (i, l) in lines.iter().enumerate() {
            let t = l.trim_start();
            let indent = &l[..l.len() - t.len()];
            let is_fn = ["fn ", "pub fn ", "pub(crate) fn "]
                .iter()
                .any(|p| t.starts_with(p));
            if !is_fn {
                continue;
            }
            let close = format!("{indent}}}");
            let Some(end) = lines[i + 1..].iter().position(|x| *x == close) else {
                continue;
            };
            let len = end + 2;
            if len <= MAX_FN_LINES {
                continue;
            }
            let doc: Vec<&str> = lines[..i]
                .iter()
                .rev()
                .take_while(|x| {
                    x.trim_start().starts_with("///") || x.trim_start().starts_with("#[")
                })
                .copied()
                .collect();
            if !doc.iter().any(|d| d.contains("Longer than a screen")) {
                bad.push(format!("{}:{} ({len} lines): {t}", f.display(), i + 1));
            }
        }
    }
    assert!(
        bad.is_empty(),
        "functions over {MAX_FN_LINES} lines whose doc comment does not say why (\"Longer than a screen ...\"):\n{}",
        bad.join("\n")
    );
}
