// SPDX-License-Identifier: MIT OR Apache-2.0
//! The binary's global allocator: `std::alloc::System` that, while `decalbake fuzz` runs, counts
//! live bytes and their peak and enforces a cap.
//!
//! **Unarmed** (every other command, and the fuzzer before and after its run) an allocation costs
//! one relaxed atomic load more than `System`'s, and nothing is counted.
//!
//! **Armed** ([`arm`]), live bytes are counted from the moment of arming with relaxed atomics (the
//! count is exact whenever the threads are quiet, which is when the fuzzer reads it), and a request
//! larger than the cap, or one that would take the live total past it, is a *breach*:
//!
//! 1. Before it answers, the allocator saves the input being executed under
//!    `FINDINGS/<target>/<hash>` and appends a line to `FINDINGS/findings.jsonl` ([`record`]). The
//!    fuzzer copies each input into a slot whose capacity was reserved at arming ([`set_current`]),
//!    so filling it never allocates and the allocator can always read it. While it saves, a flag
//!    lets every allocation (its own and other threads') through unchecked, so saving can neither
//!    breach again nor recurse; the slot is taken with `try_lock`, so it cannot deadlock either.
//! 2. It then refuses the request (returns null). A caller that asked fallibly (`try_reserve`, as
//!    image decoders do) gets an error, and the fuzzer counts the finding and goes on; any other
//!    caller aborts the process in `handle_alloc_error` ("memory allocation of N bytes failed"),
//!    with the input already on disk and its line on stderr.
//!
//! Deaths the allocator cannot see (a stack overflow, the kernel's OOM killer, a signal) are covered
//! by the fuzzer itself, which writes each input to `FINDINGS/.in-flight` before running it
//! (`super::InFlight`); the next run files what it finds there.

use std::alloc::{GlobalAlloc, Layout, System};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicI64, AtomicU64, Ordering::Relaxed};
use std::sync::{Mutex, TryLockError};

/// `System`, counted and capped while armed (see the module doc).
pub struct Counting;

static ARMED: AtomicBool = AtomicBool::new(false);
/// Set while a breach is being saved: allocations pass through unchecked.
static SAVING: AtomicBool = AtomicBool::new(false);
/// Set by a breach; the fuzzer takes it after each execution ([`take_breach`]).
static BREACHED: AtomicBool = AtomicBool::new(false);
/// Live bytes allocated since arming, less those freed since (negative when blocks from before
/// arming are freed).
static LIVE: AtomicI64 = AtomicI64::new(0);
/// Highest `LIVE` since the last [`reset_peak`].
static PEAK: AtomicI64 = AtomicI64::new(0);
/// The cap in bytes.
static CAP: AtomicU64 = AtomicU64::new(u64::MAX);

/// The input being executed, for the breach path.
struct Current {
    /// Target name (the findings sub-folder).
    target: &'static str,
    /// The input; its capacity was reserved at arming.
    bytes: Vec<u8>,
    /// Where findings go; `None`: report only (replays).
    findings: Option<PathBuf>,
}

static CURRENT: Mutex<Current> = Mutex::new(Current {
    target: "",
    bytes: Vec::new(),
    findings: None,
});

/// Starts counting and capping at `cap` bytes; inputs up to `max_input` bytes can be saved on a
/// breach, into `findings` (`None`: only reported).
pub fn arm(cap: u64, max_input: usize, findings: Option<&Path>) {
    {
        let mut c = lock_current();
        let len = c.bytes.len();
        c.bytes.reserve(max_input.saturating_sub(len));
        c.findings = findings.map(Path::to_path_buf);
    }
    CAP.store(cap, Relaxed);
    LIVE.store(0, Relaxed);
    PEAK.store(0, Relaxed);
    BREACHED.store(false, Relaxed);
    ARMED.store(true, Relaxed);
}

/// Stops counting and capping.
pub fn disarm() {
    ARMED.store(false, Relaxed);
}

/// Copies `input` (at most the `max_input` given to [`arm`]) into the slot the breach path saves;
/// does not allocate.
pub fn set_current(target: &'static str, input: &[u8]) {
    let mut c = lock_current();
    c.target = target;
    c.bytes.clear();
    let room = c.bytes.capacity();
    c.bytes.extend_from_slice(&input[..input.len().min(room)]);
}

/// The input in the slot and its target (for the watchdog, when an execution hangs).
pub fn current() -> (&'static str, Vec<u8>) {
    let c = lock_current();
    (c.target, c.bytes.clone())
}

fn lock_current() -> std::sync::MutexGuard<'static, Current> {
    CURRENT.lock().unwrap_or_else(|p| p.into_inner())
}

/// Whether an allocation was refused since the last call.
pub fn take_breach() -> bool {
    BREACHED.swap(false, Relaxed)
}

/// Live bytes since arming.
pub fn live() -> i64 {
    LIVE.load(Relaxed)
}

/// The peak of live bytes since the last reset.
pub fn peak() -> i64 {
    PEAK.load(Relaxed)
}

/// Starts a new peak from the current live total.
pub fn reset_peak() {
    PEAK.store(LIVE.load(Relaxed), Relaxed);
}

/// Saves `input` as `dir/<target>/<hash>` and appends `{"target", "kind", "file", "detail"}` to
/// `dir/findings.jsonl`; returns the saved file.
pub fn record(
    dir: &Path,
    target: &str,
    kind: &str,
    detail: &str,
    input: &[u8],
) -> std::io::Result<PathBuf> {
    let sub = dir.join(target);
    std::fs::create_dir_all(&sub)?;
    let file = sub.join(format!("{:016x}", fnv1a(input)));
    std::fs::write(&file, input)?;
    let line = serde_json::json!({
        "target": target, "kind": kind, "file": file.display().to_string(), "detail": detail,
    });
    let mut log = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(dir.join("findings.jsonl"))?;
    writeln!(log, "{line}")?;
    Ok(file)
}

/// FNV-1a, 64 bits: the findings' file names.
pub fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// Counts `delta` more live bytes for a block of `block` bytes; false (nothing counted) on a breach.
fn admit(delta: usize, block: usize) -> bool {
    let live = LIVE.fetch_add(delta as i64, Relaxed) + delta as i64;
    if !SAVING.load(Relaxed) {
        let cap = CAP.load(Relaxed);
        if block as u64 > cap || live > cap as i64 {
            LIVE.fetch_sub(delta as i64, Relaxed);
            breach(block, live);
            return false;
        }
    }
    PEAK.fetch_max(live, Relaxed);
    true
}

/// Saves the current input and reports the breach (see the module doc); never unwinds.
#[cold]
fn breach(block: usize, live: i64) {
    if SAVING.swap(true, Relaxed) {
        return;
    }
    // Saved once per execution: after a refusal the process may be aborting (its backtrace
    // allocates too) or the target may try again.
    if BREACHED.swap(true, Relaxed) {
        SAVING.store(false, Relaxed);
        return;
    }
    let detail = format!(
        "allocation of {block} bytes refused: above the cap of {} bytes (live {live} bytes with it)",
        CAP.load(Relaxed)
    );
    let saved = match CURRENT.try_lock() {
        Ok(c) => save_breach(&c, &detail),
        Err(TryLockError::Poisoned(p)) => save_breach(&p.into_inner(), &detail),
        Err(TryLockError::WouldBlock) => "input slot busy; see .in-flight".to_string(),
    };
    let _ = writeln!(std::io::stderr(), "fuzz: {detail}; {saved}");
    SAVING.store(false, Relaxed);
}

fn save_breach(c: &Current, detail: &str) -> String {
    match &c.findings {
        Some(dir) => match record(dir, c.target, "alloc", detail, &c.bytes) {
            Ok(f) => {
                // Filed here: if the process now aborts, the next run must not file it again.
                let _ = std::fs::OpenOptions::new()
                    .write(true)
                    .open(dir.join(".in-flight"))
                    .and_then(|f| f.set_len(0));
                format!("input saved as {}", f.display())
            }
            Err(e) => format!("saving the input failed: {e}"),
        },
        None => format!("target {}", c.target),
    }
}

// SAFETY: every method forwards to `System` with the caller's layout and pointer unchanged; the
// counting only decides whether to forward an allocation or answer null, which `GlobalAlloc`
// allows. Nothing here unwinds (`breach` ignores every error).
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if ARMED.load(Relaxed) && !admit(layout.size(), layout.size()) {
            return std::ptr::null_mut();
        }
        let p = unsafe { System.alloc(layout) };
        if p.is_null() && ARMED.load(Relaxed) {
            LIVE.fetch_sub(layout.size() as i64, Relaxed);
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        if ARMED.load(Relaxed) && !admit(layout.size(), layout.size()) {
            return std::ptr::null_mut();
        }
        let p = unsafe { System.alloc_zeroed(layout) };
        if p.is_null() && ARMED.load(Relaxed) {
            LIVE.fetch_sub(layout.size() as i64, Relaxed);
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        if ARMED.load(Relaxed) {
            LIVE.fetch_sub(layout.size() as i64, Relaxed);
        }
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let old = layout.size();
        let armed = ARMED.load(Relaxed);
        if armed {
            if new_size > old {
                if !admit(new_size - old, new_size) {
                    return std::ptr::null_mut();
                }
            } else {
                LIVE.fetch_sub((old - new_size) as i64, Relaxed);
            }
        }
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if p.is_null() && armed {
            // The old block stays allocated.
            LIVE.fetch_add(old as i64 - new_size as i64, Relaxed);
        }
        p
    }
}
