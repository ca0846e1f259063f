// SPDX-License-Identifier: MIT OR Apache-2.0
//! What each fuzz target runs on an input: the library's parsers as the commands call them, with no
//! file access and no GPU.
//!
//! - `job`: `Job::parse` (with a made-up source path and directories), then `Job::for_uv_set`
//!   for each set of a several-set job, as `decalbake bake` does, and the bake's memory estimate
//!   of each (`bake::memory::estimate`, whole, by the job's tiles, and streamed), which must not overflow
//!   (`assert!`: it saturates) and must grow with the texture.
//! - `manifest`: `io::manifest::parse`, then `Job::parse` of each inline job, as `decalbake batch`
//!   does.
//! - `glb`, `gltf`: what `decalbake info` does after reading the file: `Mesh::from_bytes` (with no
//!   base directory, so external URIs are refused), `Topology::build` (welding), `fill_normals` and
//!   the statistics; then the invariants the later stages index by (one normal and one UV per
//!   vertex in every set, indices in range), checked with `assert!`, so a loader that lets a broken
//!   mesh through is a finding here instead of a panic in a bake.
//! - `image`: `LinearImage::decode`, and its pixel count against its size.
//!
//! Each returns a short signature of the outcome (`ok` and the input's shape, or the error message
//! with its digits removed): the driver keeps inputs with new signatures as seeds, a cheap stand-in
//! for coverage feedback.

use decalbake::io::image::LinearImage;
use decalbake::mesh::{Mesh, Topology, DEFAULT_WELD_TOLERANCE};
use decalbake::Job;
use std::path::Path;

/// A fuzz target.
#[derive(Clone, Copy, PartialEq, Eq, Debug, clap::ValueEnum)]
pub enum Target {
    /// Job files.
    Job,
    /// Batch manifests.
    Manifest,
    /// Binary glTF.
    Glb,
    /// glTF JSON with data URIs.
    Gltf,
    /// PNG and JPEG images.
    Image,
    /// Every target above, the executions split evenly.
    All,
    /// The harness's own test: an input starting with `p` panics, `h` hangs, `a` allocates 4 GiB,
    /// `r` asks for 4 GiB fallibly; anything else passes.
    #[value(hide = true)]
    Selftest,
}

impl Target {
    /// The real targets, in the order `all` runs them.
    pub const ALL: [Target; 5] = [
        Target::Job,
        Target::Manifest,
        Target::Glb,
        Target::Gltf,
        Target::Image,
    ];

    /// The targets `self` stands for.
    pub fn expand(self) -> Vec<Target> {
        match self {
            Target::All => Self::ALL.to_vec(),
            t => vec![t],
        }
    }

    /// The name (the findings and regressions sub-folder).
    pub fn name(self) -> &'static str {
        match self {
            Target::Job => "job",
            Target::Manifest => "manifest",
            Target::Glb => "glb",
            Target::Gltf => "gltf",
            Target::Image => "image",
            Target::All => "all",
            Target::Selftest => "selftest",
        }
    }

    /// Runs the target on `input`; the outcome's signature.
    pub fn run(self, input: &[u8]) -> String {
        match self {
            Target::Job => job(&String::from_utf8_lossy(input)),
            Target::Manifest => manifest(&String::from_utf8_lossy(input)),
            Target::Glb => mesh(input, "fuzz.glb"),
            Target::Gltf => mesh(input, "fuzz.gltf"),
            Target::Image => image(input),
            Target::All => String::new(),
            Target::Selftest => selftest(input),
        }
    }
}

/// An error's signature: its message without digits, cut to 96 characters.
fn sig(e: impl std::fmt::Display) -> String {
    e.to_string()
        .chars()
        .filter(|c| !c.is_ascii_digit())
        .take(96)
        .collect()
}

fn job(text: &str) -> String {
    let dir = Path::new("fuzz");
    match Job::parse(text, &dir.join("job.json"), dir, &dir.join("out")) {
        Ok(job) => {
            for &set in &job.uv_list {
                let _ = job.for_uv_set(set);
            }
            check_estimate(&job);
            let kinds: Vec<String> = job
                .layers
                .iter()
                .take(4)
                .map(|l| format!("{:?}{:?}", l.kind, l.method))
                .collect();
            format!("ok {} {}", job.uv_list.len(), kinds.join(","))
        }
        Err(e) => sig(e),
    }
}

/// The limits' estimate of a parsed job, whole and by its tiles: at least the fixed part, at
/// least a byte a texel, and never wrapped round (a wrapped sum would let a huge bake through).
fn check_estimate(job: &Job) {
    use decalbake::bake::memory::{estimate, FIXED};
    let texels = job.width as u64 * job.height as u64;
    for tile in [None, job.tile.map(|t| [t, t])] {
        let e = estimate(job, 0, tile, false);
        assert!(e.host >= FIXED, "{e:?}");
        assert!(
            e.host.saturating_add(e.device) >= texels,
            "{e:?} for {texels} texels"
        );
    }
    // Streamed by tiles, a band of the texture at a time: at least a byte a texel of a band.
    if let Some(t) = job.tile {
        let e = estimate(job, 0, Some([t, t]), true);
        let band = job.width as u64 * t.min(job.height) as u64;
        assert!(
            e.host >= FIXED && e.host.saturating_add(e.device) >= band,
            "{e:?}"
        );
    }
}

fn manifest(text: &str) -> String {
    let path = Path::new("fuzz/manifest.jsonl");
    match decalbake::io::manifest::parse(text, path) {
        Ok(entries) => {
            let mut out = format!("ok {}", entries.len().min(8));
            for e in &entries {
                if let decalbake::io::manifest::EntryJob::Inline(t) = &e.job {
                    let source = Path::new("fuzz").join(format!("manifest.jsonl#line-{}", e.line));
                    let r = Job::parse(t, &source, Path::new("fuzz"), Path::new("fuzz/out"));
                    out.push(if r.is_ok() { '+' } else { '-' });
                }
            }
            out
        }
        Err(e) => sig(e),
    }
}

fn mesh(bytes: &[u8], name: &str) -> String {
    let mut m = match Mesh::from_bytes(bytes, Path::new(name), None) {
        Ok(m) => m,
        Err(e) => return sig(e),
    };
    let topo = Topology::build(&m, DEFAULT_WELD_TOLERANCE);
    topo.fill_normals(&mut m);
    let stats = decalbake::LoadedMesh::stats_of(&m, &topo);
    let n = m.positions.len();
    assert_eq!(m.normals.len(), n, "one normal per vertex");
    for (k, set) in m.uv_sets.iter().enumerate() {
        assert_eq!(set.len(), n, "TEXCOORD_{k}: one UV per vertex");
    }
    assert!(
        m.blend.is_empty() || m.blend.len() == n,
        "one blend weight per vertex"
    );
    assert!(
        m.bridge.is_empty() || m.bridge.len() == n,
        "one bridge weight per vertex"
    );
    assert!(
        m.triangles.iter().flatten().all(|&i| (i as usize) < n),
        "triangle indices in range"
    );
    assert_eq!(topo.welded_of.len(), n, "every vertex welded");
    format!(
        "ok p{} uv{} tex{} c{} d{}",
        stats.primitives.len().min(4),
        stats.uv_sets,
        stats.has_base_color_texture,
        stats.components.min(3),
        (stats.degenerate_triangles > 0) as u8,
    )
}

fn image(bytes: &[u8]) -> String {
    match LinearImage::decode(bytes) {
        Ok(img) => {
            assert_eq!(
                img.pixels.len() as u64,
                img.width as u64 * img.height as u64,
                "one pixel per texel"
            );
            format!("ok {}", (img.width > 1) as u8 + 2 * (img.height > 1) as u8)
        }
        Err(e) => sig(e),
    }
}

fn selftest(input: &[u8]) -> String {
    match input.first() {
        Some(b'p') => panic!("selftest: a panic"),
        Some(b'h') => loop {
            std::thread::sleep(std::time::Duration::from_millis(100));
        },
        Some(b'a') => {
            let v = vec![1u8; 4 << 30];
            format!("{}", v[v.len() - 1])
        }
        Some(b'r') => {
            let mut v: Vec<u8> = Vec::new();
            match v.try_reserve(4 << 30) {
                Ok(()) => "reserved".into(),
                Err(_) => "refused".into(),
            }
        }
        _ => "ok".into(),
    }
}
