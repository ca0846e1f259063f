// SPDX-License-Identifier: MIT OR Apache-2.0
//! `decalbake fuzz`: a mutation fuzzer for the parsers that read what users hand the engine (job
//! files, batch manifests, `.glb` and `.gltf` meshes, PNG and JPEG images), built on the stable
//! toolchain: no instrumentation, no GPU, no files needed (the seeds are made in code, `seeds.rs`).
//!
//! Each execution takes a corpus entry (a seed, or an input whose outcome was new: `targets.rs`),
//! mutates it (`mutate.rs`) and runs the target on it (`targets.rs`) on a worker thread, inside
//! `catch_unwind` and under the counting allocator's cap (`alloc.rs`). Three things are findings,
//! and each saves the input as `FINDINGS/<target>/<hash>` with a line in `FINDINGS/findings.jsonl`:
//!
//! - **a panic**: caught (the default panic hook is silenced during the run, its message kept),
//!   saved (the first three inputs per panic location), and the run goes on;
//! - **an allocation past the cap** (`--max-alloc-mib`, one request or the live total): saved by
//!   the allocator before it refuses the request (see `alloc.rs` for why that cannot lose the
//!   input); the run goes on when the caller copes with the refusal, else the process aborts;
//! - **a hang**: the main thread is a watchdog; an execution running past `--timeout-ms` is saved
//!   from the allocator's input slot, the figures so far are printed and the process exits 1.
//!
//! Before each execution the input is also written to `FINDINGS/.in-flight` (one write of a few
//! KiB): a death nothing in the process sees (a stack overflow, the OOM killer) leaves it there,
//! and the next run files it as a finding of kind `died`.
//!
//! At the end: one JSON line per target (`target`, `execs`, `execs_per_s`, `findings`,
//! `peak_alloc_mib`: the highest live heap of the run above what was live at arming, and
//! `max_exec_ms`) and a `total` line; exit 1 if there were findings. `--replay DIR` runs every file
//! under `DIR/<target>/` once through the same harness (the regression suite,
//! `tests/fuzz/regressions`). `DECALBAKE_FUZZ_SIGNATURES=1` prints each target's most frequent
//! outcomes at its end (to see where mutations stop).

pub mod alloc;
mod mutate;
mod seeds;
mod targets;

use anyhow::{Context, Result};
use arbitrary::Unstructured;
use serde_json::json;
use std::collections::{HashMap, HashSet};
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering::Relaxed};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::{Duration, Instant};
pub use targets::Target;

/// `decalbake fuzz` options.
#[derive(clap::Args, Debug)]
pub struct FuzzArgs {
    /// Which parser: job, manifest, glb, gltf, image, or all.
    #[arg(long, value_enum, default_value = "all")]
    pub target: Target,
    /// Executions in all, split evenly over the targets.
    #[arg(long, default_value_t = 100_000)]
    pub execs: u64,
    /// Seed of the mutations (a run is a function of its seed).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Where findings go: DIR/<target>/<hash>, DIR/findings.jsonl.
    #[arg(long, default_value = "fuzz-findings")]
    pub findings: PathBuf,
    /// Run every file under DIR/<target>/ once instead of fuzzing.
    #[arg(long)]
    pub replay: Option<PathBuf>,
    /// Allocation cap in MiB: one request or the live heap above it is a finding.
    #[arg(long, default_value_t = 2048)]
    pub max_alloc_mib: u64,
    /// An execution running longer than this (milliseconds) is a hang.
    #[arg(long, default_value_t = 2000)]
    pub timeout_ms: u64,
    /// Write the seeds as DIR/<target>/seed-N (for other fuzzers, or to edit into regressions)
    /// instead of fuzzing.
    #[arg(long)]
    pub dump_seeds: Option<PathBuf>,
}

/// The longest input executed (mutations are cut to it).
const MAX_INPUT: usize = 128 << 10;
/// The largest input kept in the corpus, and the corpus's size.
const MAX_KEPT: usize = 32 << 10;
const MAX_CORPUS: usize = 1024;
/// Inputs saved per panic location.
const SAVED_PER_PANIC: usize = 3;
/// Seconds between progress lines.
const PROGRESS_EVERY: Duration = Duration::from_secs(5);

/// One target's figures.
#[derive(Debug, Clone, Default)]
struct Stats {
    target: &'static str,
    execs: u64,
    secs: f64,
    findings: u64,
    peak: i64,
    max_exec_ms: f64,
    corpus: usize,
    /// Executions the target accepted (parsed without an error).
    accepted: u64,
}

impl Stats {
    /// The target's line: (key, value) in the order printed.
    fn fields(&self, replay: bool) -> Vec<(&'static str, serde_json::Value)> {
        let ms = json!((self.max_exec_ms * 100.0).round() / 100.0);
        if replay {
            return vec![
                ("target", json!(self.target)),
                ("replayed", json!(self.execs)),
                ("findings", json!(self.findings)),
                ("peak_alloc_mib", json!(mib(self.peak))),
                ("max_exec_ms", ms),
            ];
        }
        vec![
            ("target", json!(self.target)),
            ("execs", json!(self.execs)),
            (
                "execs_per_s",
                json!((self.execs as f64 / self.secs.max(1e-9)).round()),
            ),
            ("findings", json!(self.findings)),
            ("peak_alloc_mib", json!(mib(self.peak))),
            ("max_exec_ms", ms),
            ("accepted", json!(self.accepted)),
            ("corpus", json!(self.corpus)),
        ]
    }
}

/// A JSON object with its keys in the order given (`serde_json`'s map would sort them).
fn line(fields: &[(&str, serde_json::Value)]) -> String {
    let body: Vec<String> = fields
        .iter()
        .map(|(k, v)| format!("{}:{v}", json!(k)))
        .collect();
    format!("{{{}}}", body.join(","))
}

fn mib(bytes: i64) -> f64 {
    (bytes.max(0) as f64 / 1_048_576.0 * 100.0).round() / 100.0
}

/// What the worker shares with the watchdog.
#[derive(Default)]
struct Live {
    /// Start of the running execution (ms since the run began, plus one); 0 when idle.
    started: AtomicU64,
    /// Executions of the current target.
    execs: AtomicU64,
    /// Findings of the current target.
    findings: AtomicU64,
    /// Index of the current target.
    target: AtomicUsize,
    /// Corpus size of the current target.
    corpus: AtomicUsize,
    /// Figures of the finished targets.
    done: Mutex<Vec<Stats>>,
}

fn clock() -> u64 {
    static T0: OnceLock<Instant> = OnceLock::new();
    T0.get_or_init(Instant::now).elapsed().as_millis() as u64 + 1
}

/// The message of the last panic (the silenced hook keeps it).
static LAST_PANIC: Mutex<String> = Mutex::new(String::new());

/// `decalbake fuzz`; the exit code (1 when there were findings).
pub fn run(args: &FuzzArgs) -> Result<i32> {
    let targets = args.target.expand();
    if let Some(dir) = &args.dump_seeds {
        for t in &targets {
            let sub = dir.join(t.name());
            std::fs::create_dir_all(&sub).with_context(|| format!("creating {}", sub.display()))?;
            for (i, s) in seeds_of(*t).0.iter().enumerate() {
                std::fs::write(sub.join(format!("seed-{i}")), s)?;
            }
        }
        return Ok(0);
    }
    let findings = args.replay.is_none().then(|| args.findings.clone());
    let mut leftover = Vec::new();
    let inflight = match &findings {
        Some(dir) => {
            std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
            let (f, left) = InFlight::open(dir)?;
            leftover.extend(left);
            Some(f)
        }
        None => None,
    };
    let live = Arc::new(Live::default());
    let mut harness = Harness {
        findings: findings.clone(),
        inflight,
        live: live.clone(),
        panics: HashMap::new(),
    };
    for (target, input) in &leftover {
        let detail = "the previous run ended while executing this input (a death the harness could not catch: a stack overflow, an abort, the OOM killer or a signal)";
        if let Some(dir) = &findings {
            let f = alloc::record(dir, target, "died", detail, input)?;
            eprintln!(
                "fuzz: finding (died) in {target}: {detail}; saved as {}",
                f.display()
            );
        }
    }
    let previous_hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|info| {
        *LAST_PANIC.lock().unwrap_or_else(|p| p.into_inner()) = info.to_string();
    }));
    alloc::arm(
        args.max_alloc_mib.saturating_mul(1 << 20),
        MAX_INPUT,
        findings.as_deref(),
    );
    let t0 = Instant::now();
    let (execs, seed, replay) = (args.execs, args.seed, args.replay.clone());
    let worker_targets = targets.clone();
    let worker = std::thread::Builder::new()
        .name("fuzz".into())
        .stack_size(64 << 20)
        .spawn(move || match &replay {
            Some(dir) => replay_all(dir, &worker_targets, &mut harness),
            None => fuzz_all(&worker_targets, execs, seed, &mut harness),
        })?;
    watch(&worker, &live, &targets, args, t0);
    let result = worker.join();
    alloc::disarm();
    std::panic::set_hook(previous_hook);
    let stats = result.map_err(|_| anyhow::anyhow!("the fuzzer itself failed"))?;
    if let Some(f) = harness_inflight_path(&findings) {
        let _ = std::fs::remove_file(f);
    }
    let total = print_stats(&stats, t0, args, leftover.len() as u64);
    Ok(if total > 0 { 1 } else { 0 })
}

fn harness_inflight_path(findings: &Option<PathBuf>) -> Option<PathBuf> {
    findings.as_ref().map(|d| d.join(".in-flight"))
}

/// Prints the JSON lines; the number of findings.
fn print_stats(stats: &[Stats], t0: Instant, args: &FuzzArgs, extra: u64) -> u64 {
    let replay = args.replay.is_some();
    for s in stats {
        println!("{}", line(&s.fields(replay)));
    }
    let total = Stats {
        target: "total",
        execs: stats.iter().map(|s| s.execs).sum(),
        secs: t0.elapsed().as_secs_f64(),
        findings: stats.iter().map(|s| s.findings).sum::<u64>() + extra,
        peak: stats.iter().map(|s| s.peak).max().unwrap_or(0),
        max_exec_ms: stats.iter().map(|s| s.max_exec_ms).fold(0.0, f64::max),
        corpus: 0,
        accepted: stats.iter().map(|s| s.accepted).sum(),
    };
    let mut fields = total.fields(replay);
    if !replay {
        fields.truncate(6);
        fields.push(("seed", json!(args.seed)));
        fields.push(("max_alloc_mib", json!(args.max_alloc_mib)));
    }
    fields.push(("wall_s", json!((total.secs * 100.0).round() / 100.0)));
    println!("{}", line(&fields));
    total.findings
}

/// The watchdog: progress every few seconds; an execution past the timeout is saved, the figures
/// so far printed, and the process exits 1.
fn watch(
    worker: &std::thread::JoinHandle<Vec<Stats>>,
    live: &Live,
    targets: &[Target],
    args: &FuzzArgs,
    t0: Instant,
) {
    let mut last = Instant::now();
    let (mut last_execs, mut last_target) = (0, 0);
    while !worker.is_finished() {
        std::thread::sleep(Duration::from_millis(20));
        let started = live.started.load(Relaxed);
        let target = live.target.load(Relaxed).min(targets.len() - 1);
        if target != last_target {
            (last_execs, last_target) = (0, target);
        }
        let name = targets[target].name();
        if started > 0 && clock().saturating_sub(started) > args.timeout_ms {
            hang(live, name, args, t0);
        }
        if last.elapsed() >= PROGRESS_EVERY {
            let execs = live.execs.load(Relaxed);
            let rate = execs.saturating_sub(last_execs) as f64 / last.elapsed().as_secs_f64();
            eprintln!(
                "fuzz: {name}: {execs} execs ({rate:.0}/s), {} findings, corpus {}, heap {:.1} MiB (peak {:.1})",
                live.findings.load(Relaxed),
                live.corpus.load(Relaxed),
                mib(alloc::live()),
                mib(alloc::peak()),
            );
            (last, last_execs) = (Instant::now(), execs);
        }
    }
}

/// A hang: saves the input from the allocator's slot and exits 1 after printing the figures.
fn hang(live: &Live, name: &'static str, args: &FuzzArgs, t0: Instant) -> ! {
    let (target, input) = alloc::current();
    let detail = format!("no answer after {} ms", args.timeout_ms);
    let saved = match args.replay.is_none().then_some(&args.findings) {
        Some(dir) => {
            let saved = alloc::record(dir, target, "hang", &detail, &input);
            // Filed here: the next run must not file it again as `died`.
            let _ = std::fs::remove_file(dir.join(".in-flight"));
            match saved {
                Ok(f) => format!("saved as {}", f.display()),
                Err(e) => format!("saving it failed: {e}"),
            }
        }
        None => "a replayed file".into(),
    };
    eprintln!("fuzz: finding (hang) in {target}: {detail}; {saved}; stopping");
    let mut stats = live.done.lock().map(|d| d.clone()).unwrap_or_default();
    stats.push(Stats {
        target: name,
        execs: live.execs.load(Relaxed),
        secs: t0.elapsed().as_secs_f64(),
        findings: live.findings.load(Relaxed) + 1,
        peak: alloc::peak(),
        max_exec_ms: args.timeout_ms as f64,
        corpus: live.corpus.load(Relaxed),
        accepted: 0,
    });
    print_stats(&stats, t0, args, 0);
    std::process::exit(1)
}

/// How an execution ended.
enum Outcome {
    /// Returned, with the outcome's signature.
    Ok(String),
    /// Panicked, with the message.
    Panic(String),
    /// Returned after an allocation was refused (already saved by the allocator).
    Alloc,
}

/// Runs targets on inputs and files findings.
struct Harness {
    findings: Option<PathBuf>,
    inflight: Option<InFlight>,
    live: Arc<Live>,
    /// Inputs saved per panic location.
    panics: HashMap<String, usize>,
}

impl Harness {
    /// One execution: (outcome, milliseconds).
    fn exec(&mut self, target: Target, input: &[u8]) -> (Outcome, f64) {
        alloc::set_current(target.name(), input);
        if let Some(f) = &mut self.inflight {
            f.write(target.name(), input);
        }
        self.live.started.store(clock(), Relaxed);
        let t = Instant::now();
        let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| target.run(input)));
        let ms = t.elapsed().as_secs_f64() * 1000.0;
        self.live.started.store(0, Relaxed);
        let breached = alloc::take_breach();
        let outcome = match r {
            Err(_) => Outcome::Panic(std::mem::take(
                &mut *LAST_PANIC.lock().unwrap_or_else(|p| p.into_inner()),
            )),
            Ok(_) if breached => Outcome::Alloc,
            Ok(sig) => Outcome::Ok(sig),
        };
        (outcome, ms)
    }

    /// Files a panic (the first few inputs per location) and prints it.
    fn file_panic(&mut self, target: Target, msg: &str, input: &[u8]) {
        let location = msg.lines().next().unwrap_or_default().to_string();
        let seen = self.panics.entry(location).or_default();
        *seen += 1;
        if *seen > SAVED_PER_PANIC {
            return;
        }
        let saved = match &self.findings {
            Some(dir) => match alloc::record(dir, target.name(), "panic", msg, input) {
                Ok(f) => format!("saved as {}", f.display()),
                Err(e) => format!("saving it failed: {e}"),
            },
            None => String::new(),
        };
        eprintln!(
            "fuzz: finding (panic) in {}: {}; {saved}",
            target.name(),
            msg.replace('\n', " ")
        );
    }
}

/// The seeds of a target and the shape its mutations follow.
fn seeds_of(t: Target) -> (Vec<Vec<u8>>, mutate::Shape) {
    use mutate::Shape;
    match t {
        Target::Job => (seeds::jobs(), Shape::Json),
        Target::Manifest => (seeds::manifests(), Shape::Lines),
        Target::Glb => (seeds::glbs(), Shape::Glb),
        Target::Gltf => (seeds::gltfs(), Shape::Gltf),
        Target::Image => (seeds::images(), Shape::Image),
        // The harness's tests choose the self-test's seed (`targets.rs`: `p` panics, `h` hangs...).
        Target::Selftest => (
            vec![std::env::var("DECALBAKE_FUZZ_SELFTEST")
                .unwrap_or_else(|_| "ok".into())
                .into_bytes()],
            Shape::Image,
        ),
        Target::All => (vec![b"ok".to_vec()], Shape::Image),
    }
}

/// Every object key the seeds use (JSON documents, JSON lines and GLB JSON chunks).
fn seed_keys(seeds: &[Vec<u8>]) -> Vec<String> {
    let mut keys = std::collections::BTreeSet::new();
    for s in seeds {
        let docs: Vec<serde_json::Value> = match mutate::glb_chunks(s) {
            Some(chunks) => chunks
                .iter()
                .filter(|c| &c.0 == b"JSON")
                .filter_map(|c| serde_json::from_slice(&c.1).ok())
                .collect(),
            None => String::from_utf8_lossy(s)
                .lines()
                .filter_map(|l| serde_json::from_str(l).ok())
                .chain(serde_json::from_slice(s).ok())
                .collect(),
        };
        docs.iter().for_each(|d| seeds::keys_of(d, &mut keys));
    }
    if keys.is_empty() {
        keys.insert("a".to_string());
    }
    keys.into_iter().collect()
}

/// Fuzzes each target for its share of `execs`.
fn fuzz_all(targets: &[Target], execs: u64, seed: u64, h: &mut Harness) -> Vec<Stats> {
    let n = targets.len() as u64;
    let mut out = Vec::new();
    for (i, &t) in targets.iter().enumerate() {
        let share = execs / n + u64::from((i as u64) < execs % n);
        h.live.target.store(i, Relaxed);
        let s = fuzz_target(t, share, seed, h);
        h.live
            .done
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .push(s.clone());
        out.push(s);
    }
    out
}

/// `execs` executions of target `t`: the seeds first, then mutations.
fn fuzz_target(t: Target, execs: u64, seed: u64, h: &mut Harness) -> Stats {
    let (mut corpus, shape) = seeds_of(t);
    let seeds = corpus.len();
    let keys = seed_keys(&corpus);
    let mut rng = mutate::Rng::new(seed ^ alloc::fnv1a(t.name().as_bytes()));
    let mut noise = vec![0u8; 4096];
    let mut signatures = HashSet::new();
    // Corpus entries the target accepted (the seeds are added as they run).
    let mut accepted: Vec<usize> = Vec::new();
    // DECALBAKE_FUZZ_SIGNATURES=1: the most frequent outcomes, printed at the end (for tuning).
    let mut histogram =
        std::env::var_os("DECALBAKE_FUZZ_SIGNATURES").map(|_| HashMap::<String, u64>::new());
    let mut stats = Stats {
        target: t.name(),
        ..Stats::default()
    };
    h.live.execs.store(0, Relaxed);
    h.live.findings.store(0, Relaxed);
    alloc::reset_peak();
    let t0 = Instant::now();
    for i in 0..execs {
        rng.fill(&mut noise);
        let mut u = Unstructured::new(&noise);
        let input = if (i as usize) < seeds {
            corpus[i as usize].clone()
        } else {
            // A seed (1 in 4), an accepted input (1 in 2, when there are some) or any entry.
            let from = match u.choose_index(4).unwrap_or(0) {
                0 => u.choose_index(seeds).unwrap_or(0),
                1 | 2 if !accepted.is_empty() => {
                    accepted[u.choose_index(accepted.len()).unwrap_or(0)]
                }
                _ => u.choose_index(corpus.len()).unwrap_or(0),
            };
            let pool = mutate::Pool {
                entries: &corpus,
                keys: &keys,
                max_len: MAX_INPUT,
            };
            mutate::mutate(shape, &corpus[from], &pool, &mut u)
        };
        let (outcome, ms) = h.exec(t, &input);
        stats.execs += 1;
        stats.max_exec_ms = stats.max_exec_ms.max(ms);
        match outcome {
            Outcome::Ok(sig) => {
                let ok = sig.starts_with("ok");
                stats.accepted += u64::from(ok);
                if let Some(h) = &mut histogram {
                    *h.entry(sig.clone()).or_insert(0u64) += 1;
                }
                if (i as usize) < seeds {
                    signatures.insert(sig);
                    if ok {
                        accepted.push(i as usize);
                    }
                } else if input.len() <= MAX_KEPT
                    && signatures.len() < 100_000
                    && signatures.insert(sig)
                {
                    let k = if corpus.len() < MAX_CORPUS {
                        corpus.push(input);
                        corpus.len() - 1
                    } else {
                        let k = seeds + (rng.next_u64() as usize) % (corpus.len() - seeds);
                        corpus[k] = input;
                        accepted.retain(|&a| a != k);
                        k
                    };
                    if ok {
                        accepted.push(k);
                    }
                }
            }
            Outcome::Panic(msg) => {
                stats.findings += 1;
                h.file_panic(t, &msg, &input);
            }
            Outcome::Alloc => stats.findings += 1,
        }
        h.live.execs.store(stats.execs, Relaxed);
        h.live.findings.store(stats.findings, Relaxed);
        h.live.corpus.store(corpus.len(), Relaxed);
    }
    stats.secs = t0.elapsed().as_secs_f64();
    stats.peak = alloc::peak();
    stats.corpus = corpus.len();
    if let Some(h) = histogram {
        let mut rows: Vec<_> = h.into_iter().collect();
        rows.sort_by_key(|r| std::cmp::Reverse(r.1));
        for (sig, n) in rows.iter().take(25) {
            eprintln!("fuzz: {}: {n:>8} {sig}", t.name());
        }
    }
    stats
}

/// Runs every file under `dir/<target>/` once.
fn replay_all(dir: &Path, targets: &[Target], h: &mut Harness) -> Vec<Stats> {
    let mut out = Vec::new();
    for (i, &t) in targets.iter().enumerate() {
        h.live.target.store(i, Relaxed);
        let mut files: Vec<PathBuf> = std::fs::read_dir(dir.join(t.name()))
            .map(|d| d.filter_map(|e| e.ok()).map(|e| e.path()).collect())
            .unwrap_or_default();
        files.retain(|f| f.is_file());
        files.sort();
        let mut stats = Stats {
            target: t.name(),
            ..Stats::default()
        };
        alloc::reset_peak();
        let t0 = Instant::now();
        for f in files {
            let Ok(bytes) = std::fs::read(&f) else {
                eprintln!("fuzz: cannot read {}", f.display());
                stats.findings += 1;
                continue;
            };
            let (outcome, ms) = h.exec(t, &bytes);
            stats.execs += 1;
            stats.max_exec_ms = stats.max_exec_ms.max(ms);
            let failure = match outcome {
                Outcome::Ok(_) => None,
                Outcome::Panic(msg) => Some(format!("panic: {}", msg.replace('\n', " "))),
                Outcome::Alloc => Some("an allocation past the cap".to_string()),
            };
            if let Some(why) = failure {
                stats.findings += 1;
                eprintln!("fuzz: replay of {} failed: {why}", f.display());
            }
            h.live.execs.store(stats.execs, Relaxed);
        }
        stats.secs = t0.elapsed().as_secs_f64();
        stats.peak = alloc::peak();
        out.push(stats);
    }
    out
}

/// What a run left in `.in-flight`: (target, input).
type Leftover = (String, Vec<u8>);

/// `FINDINGS/.in-flight`: the input being executed, written before it runs (`DBFZ`, the target's
/// name length and name, the input's length, the input).
struct InFlight {
    file: std::fs::File,
    buf: Vec<u8>,
}

impl InFlight {
    /// Opens the file; what a previous run left in it (target, input).
    fn open(dir: &Path) -> Result<(Self, Option<Leftover>)> {
        let path = dir.join(".in-flight");
        let mut file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&path)
            .with_context(|| format!("opening {}", path.display()))?;
        let mut old = Vec::new();
        file.read_to_end(&mut old)?;
        file.set_len(0)?;
        let left = (|| {
            let rest = old.strip_prefix(b"DBFZ")?;
            let (&n, rest) = rest.split_first()?;
            let name = std::str::from_utf8(rest.get(..n as usize)?).ok()?;
            let rest = &rest[n as usize..];
            let len = u32::from_le_bytes(rest.get(..4)?.try_into().ok()?) as usize;
            let input = rest.get(4..4 + len)?;
            let known = Target::ALL
                .iter()
                .chain([&Target::Selftest])
                .any(|t| t.name() == name);
            known.then(|| (name.to_string(), input.to_vec()))
        })();
        Ok((
            InFlight {
                file,
                buf: Vec::with_capacity(MAX_INPUT + 64),
            },
            left,
        ))
    }

    /// Writes `input` (one `write` after a seek; errors are ignored: the file is a safety net).
    fn write(&mut self, target: &str, input: &[u8]) {
        self.buf.clear();
        self.buf.extend_from_slice(b"DBFZ");
        self.buf.push(target.len() as u8);
        self.buf.extend_from_slice(target.as_bytes());
        self.buf
            .extend_from_slice(&(input.len() as u32).to_le_bytes());
        self.buf.extend_from_slice(input);
        let _ = self.file.seek(SeekFrom::Start(0));
        let _ = self.file.write_all(&self.buf);
    }
}
