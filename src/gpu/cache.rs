// SPDX-License-Identifier: MIT OR Apache-2.0
//! Compiled pipelines kept across processes: wgpu's `PipelineCache` (Vulkan only) saved in the
//! user's cache folder, so the second `decalbake bake` on a machine skips the driver's compile.
//!
//! - **Where**: `$DECALBAKE_CACHE_DIR` when set (`off` or empty turns the cache off), else
//!   `$XDG_CACHE_HOME/decalbake`, else `$HOME/.cache/decalbake`.
//! - **Which file**: one per adapter, driver and engine version (`pipelines-<hash>.bin`, the hash
//!   of wgpu's cache key for the adapter, its name, driver, driver version and this engine's
//!   version), so a driver update or a new engine starts a new file instead of feeding the old.
//! - **Corrupt or foreign files are ignored**: the file carries the SHA-256 of the data it holds;
//!   one that does not match (truncated, edited, half-written by a crash) is ignored, the cache
//!   starts empty, and the next save replaces it. wgpu checks the rest (adapter, driver, its own
//!   format) and falls back to an empty cache on a mismatch.
//! - **Saved atomically**: written beside the file under a unique name, then renamed over it, so
//!   processes saving at once (a batch on a farm with a shared home) leave one whole file.
//! - **What it saves**: the driver's compiled code only. WGSL translation still happens in each
//!   process; pipelines are built lazily (`pipelines::Lazy`), so that is paid only for what a
//!   job runs.

use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::Mutex;

/// First bytes of a cache file (the format's version is its last digit).
const MAGIC: &[u8; 8] = b"DBKPC\x00\x00\x01";

/// The folder the cache lives in, or `None` where it is turned off.
pub fn folder() -> Option<PathBuf> {
    match std::env::var_os("DECALBAKE_CACHE_DIR") {
        Some(v) if v.is_empty() || v == "off" => None,
        Some(v) => Some(PathBuf::from(v)),
        None => std::env::var_os("XDG_CACHE_HOME")
            .filter(|v| !v.is_empty())
            .map(PathBuf::from)
            .or_else(|| std::env::var_os("HOME").map(|h| Path::new(&h).join(".cache")))
            .map(|c| c.join("decalbake")),
    }
}

/// The cache file for `info`'s adapter in `folder`, or `None` where the backend keeps no
/// pipeline cache.
pub fn file_for(folder: &Path, info: &wgpu::AdapterInfo) -> Option<PathBuf> {
    let key = wgpu::util::pipeline_cache_key(info)?;
    let mut h = Sha256::new();
    for part in [
        key.as_str(),
        &info.name,
        &info.driver,
        &info.driver_info,
        env!("CARGO_PKG_VERSION"),
    ] {
        h.update(part.as_bytes());
        h.update([0]);
    }
    let hash: String = h.finalize()[..8]
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    Some(folder.join(format!("pipelines-{hash}.bin")))
}

/// What the cache did when the engine started, for the report.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Start {
    /// Turned off (`DECALBAKE_CACHE_DIR=off`), or the engine runs on a host's device.
    Off,
    /// The backend or device keeps no pipeline cache (GL, or no `PIPELINE_CACHE` feature).
    Unsupported,
    /// No file yet: pipelines are compiled and saved.
    Cold,
    /// A file was read and handed to the driver.
    Warm,
    /// A file was there but did not check out (truncated or altered): ignored and replaced.
    Corrupt,
}

impl Start {
    /// The word the report carries.
    pub fn name(self) -> &'static str {
        match self {
            Start::Off => "off",
            Start::Unsupported => "unsupported",
            Start::Cold => "cold",
            Start::Warm => "warm",
            Start::Corrupt => "corrupt",
        }
    }
}

/// The payload of a cache file's bytes, if they check out.
fn payload(bytes: &[u8]) -> Option<&[u8]> {
    let rest = bytes.strip_prefix(MAGIC.as_slice())?;
    if rest.len() < 32 {
        return None;
    }
    let (sum, data) = rest.split_at(32);
    (Sha256::digest(data).as_slice() == sum).then_some(data)
}

/// A cache file's bytes for `data`.
fn framed(data: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(MAGIC.len() + 32 + data.len());
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&Sha256::digest(data));
    out.extend_from_slice(data);
    out
}

/// A pipeline cache bound to its file.
pub struct DiskCache {
    /// The cache pipelines are created through.
    pub cache: wgpu::PipelineCache,
    path: PathBuf,
    /// The SHA-256 of what the file holds (or held when read), to skip saving the same bytes.
    saved: Mutex<Option<[u8; 32]>>,
    /// Pipelines built when it was last saved ([`crate::gpu::pipelines::Builder::spent`]).
    built_at_save: AtomicU32,
}

impl DiskCache {
    /// Opens the cache for `device` (created with `PIPELINE_CACHE`) on `info`'s adapter in
    /// `folder`; reads its file when there is a good one.
    pub fn open(
        device: &wgpu::Device,
        info: &wgpu::AdapterInfo,
        folder: &Path,
    ) -> Option<(Self, Start)> {
        let path = file_for(folder, info)?;
        let bytes = std::fs::read(&path).ok();
        let data = bytes.as_deref().and_then(payload);
        let start = match (&bytes, data) {
            (None, _) => Start::Cold,
            (Some(_), None) => Start::Corrupt,
            (Some(_), Some(_)) => Start::Warm,
        };
        if start == Start::Corrupt {
            log::warn!("ignoring a corrupt pipeline cache: {}", path.display());
        }
        // SAFETY: `data` is what `PipelineCache::get_data` returned in an earlier process, as
        // saved by `save` with its SHA-256 and checked against it here; the file is named by
        // wgpu's cache key for this adapter and driver, and wgpu checks its own header against
        // the adapter again (`fallback: true`: an empty cache on any mismatch).
        let cache = unsafe {
            device.create_pipeline_cache(&wgpu::PipelineCacheDescriptor {
                label: Some("decalbake.pipelines"),
                data,
                fallback: true,
            })
        };
        let saved = data.map(|d| Sha256::digest(d).into());
        Some((
            Self {
                cache,
                path,
                saved: Mutex::new(saved),
                built_at_save: AtomicU32::new(0),
            },
            start,
        ))
    }

    /// The file it reads and saves.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Saves the cache's data if pipelines were built since the last save (`built`: how many
    /// have been built so far) and the data changed. Failures are logged, never raised: a cache
    /// that cannot be written costs the next process its compile, nothing else.
    pub fn save(&self, built: u32) {
        if self.built_at_save.swap(built, Ordering::Relaxed) == built {
            return;
        }
        let Some(data) = self.cache.get_data() else {
            return;
        };
        let sum: [u8; 32] = Sha256::digest(&data).into();
        let Ok(mut saved) = self.saved.lock() else {
            return;
        };
        if *saved == Some(sum) {
            return;
        }
        match write_replacing(&self.path, &framed(&data)) {
            Ok(()) => *saved = Some(sum),
            Err(e) => log::warn!("pipeline cache not saved to {}: {e}", self.path.display()),
        }
    }
}

/// Writes `bytes` to `path` through a file of its own beside it, then renames it over `path`.
fn write_replacing(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    static SERIAL: AtomicU32 = AtomicU32::new(0);
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent)?;
    }
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(format!(
        ".tmp-{}-{}",
        std::process::id(),
        SERIAL.fetch_add(1, Ordering::Relaxed)
    ));
    let tmp = PathBuf::from(tmp);
    let written = std::fs::write(&tmp, bytes).and_then(|()| std::fs::rename(&tmp, path));
    if written.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    written
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_checks_out_only_whole_and_unaltered() {
        let data = b"compiled pipelines".to_vec();
        let file = framed(&data);
        assert_eq!(payload(&file), Some(data.as_slice()));
        assert_eq!(payload(&file[..file.len() - 1]), None, "truncated");
        let mut flipped = file.clone();
        *flipped.last_mut().unwrap() ^= 1;
        assert_eq!(payload(&flipped), None, "altered data");
        let mut foreign = file.clone();
        foreign[0] = b'X';
        assert_eq!(payload(&foreign), None, "not ours");
        assert_eq!(payload(&[]), None, "empty");
    }

    #[test]
    fn files_differ_by_driver_and_only_vulkan_has_one() {
        let info = |driver_info: &str, backend| wgpu::AdapterInfo {
            name: "llvmpipe".into(),
            vendor: 0x10005,
            driver: "llvmpipe".into(),
            driver_info: driver_info.into(),
            ..wgpu::AdapterInfo::new(wgpu::DeviceType::Cpu, backend)
        };
        let dir = Path::new("/c");
        let a = file_for(dir, &info("Mesa 22.3.6", wgpu::Backend::Vulkan)).unwrap();
        let b = file_for(dir, &info("Mesa 23.0.0", wgpu::Backend::Vulkan)).unwrap();
        assert_ne!(a, b);
        assert_eq!(a.parent(), Some(dir));
        assert!(file_for(dir, &info("Mesa 22.3.6", wgpu::Backend::Gl)).is_none());
    }
}
