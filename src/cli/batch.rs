// SPDX-License-Identifier: MIT OR Apache-2.0
//! `decalbake batch MANIFEST`: many bakes in one process, each mesh loaded once, a failing job
//! reported and the others baked, a rerun after a killed node redoing only what is missing, and the
//! work split over the array tasks of the scheduler a site already runs.
//!
//! - **Manifest**: JSON Lines, one job per line: a string (a job file's path) or an object (the job
//!   itself, the same schema). Paths are relative to the manifest (a job file's own paths to the job
//!   file). Blank lines are skipped; a line that is neither is a bad manifest (exit 2, nothing
//!   baked); a job file that cannot be read fails its own job. A job's number is its line number.
//! - **Outputs**: as each job says; with `--out DIR`, under `DIR/<job>/` (`<job>`: `line-N` and, for
//!   a job file, its stem), so jobs that name the same outputs do not overwrite each other. Every
//!   file is written atomically (temporary file and rename).
//! - **Failures**: a job that fails is recorded in the summary (line, job file, field, message,
//!   class: `input` for what exit code 2 means for `bake`, `engine` otherwise) and the batch goes on
//!   (`--fail-fast` stops it). Exit 0 when every job succeeded, 3 when some failed, 2 for a bad
//!   manifest or options.
//! - **Resume**: each job's `input_hash` is the SHA-256 of the engine version, the job's text and
//!   the bytes of its mesh (with a `.gltf`'s external files) and images (colour, mask, channel
//!   images); its report carries it too. Each finished job appends a line to the batch's journal
//!   (`journal.rs`: the hash, the output folder and every output's SHA-256, synced to the disk).
//!   `--resume` skips a job whose journal line matches its hash and folder and whose outputs still
//!   have those bytes, whether or not the job writes a report.
//! - **Shards**: `--shard I/N` takes the jobs whose position in the manifest (0-based) is I modulo N;
//!   `--shard auto` reads I and N from a Slurm job array (`SLURM_ARRAY_TASK_ID` minus
//!   `SLURM_ARRAY_TASK_MIN`, `SLURM_ARRAY_TASK_COUNT`), a Kubernetes indexed job
//!   (`JOB_COMPLETION_INDEX`, with `DECALBAKE_SHARDS` for N) or an AWS Batch array job
//!   (`AWS_BATCH_JOB_ARRAY_INDEX`, `AWS_BATCH_JOB_ARRAY_SIZE`), and says which; a stepped Slurm
//!   array (`SLURM_ARRAY_TASK_STEP`) counts in steps. Each shard's default summary is
//!   `summary-I.json`; `--merge-summaries` joins them into one.
//! - **Meshes** stay loaded between jobs, least recently used first out when their estimated size
//!   passes [`MESH_BUDGET`].
//!
//! `--jobs K` bakes K jobs at once on threads sharing one engine (and the mesh cache; a mesh loads
//! under its lock); outputs do not depend on the shard, order, concurrency or the meshes cached (a
//! bake is deterministic and each bake's raster and compose are one command buffer, so the raster
//! targets the engine pools are never shared between two bakes in flight), which `tests/batch.rs`
//! checks byte for byte.

use crate::journal::Journal;
use anyhow::{bail, Context, Result};
use decalbake::io::manifest::{Entry, EntryJob};
use decalbake::output::UvBake;
use decalbake::{Engine, Job, LoadedMesh};
use serde_json::{json, Value};
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

/// Estimated bytes of loaded meshes kept between jobs (CPU and GPU copies; see [`mesh_bytes`]).
pub const MESH_BUDGET: u64 = 2 << 30;

/// What `decalbake batch` was asked to do.
pub struct BatchOptions {
    /// The manifest (JSON Lines).
    pub manifest: PathBuf,
    /// Output root (`DIR/<job>/`), or the jobs' own output paths.
    pub out: Option<PathBuf>,
    /// `I/N`, `auto`, or none (every job).
    pub shard: Option<String>,
    /// Skip jobs whose outputs exist with the same input hash.
    pub resume: bool,
    /// Stop at the first failure.
    pub fail_fast: bool,
    /// Where the summary goes (default: `summary.json` in the output root or beside the manifest).
    pub summary: Option<PathBuf>,
    /// How progress is shown.
    pub progress: ProgressMode,
    /// Jobs baked at once, on threads sharing the engine (outputs do not depend on it).
    pub jobs: usize,
    /// `--max-memory`: the most memory one bake may take (a job's `max_memory` lowers it).
    pub max_memory: Option<u64>,
}

/// `--progress`: a bar on a terminal, log lines otherwise (`auto`), or JSON events on stdout.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ProgressMode {
    /// A bar when stderr is a terminal, else one log line per job.
    Auto,
    /// One log line per job on stderr.
    Lines,
    /// One JSON object per job on stdout (`{"event": "job", ...}`), then `{"event": "done", ...}`.
    Json,
    /// Nothing (`decalbake bench --batch-bake`).
    None,
}

/// Progress as it is shown (see [`ProgressMode`]).
enum Progress {
    Bar(indicatif::ProgressBar),
    Lines,
    Json,
    None,
}

impl Progress {
    fn new(mode: ProgressMode, total: usize) -> Self {
        use std::io::IsTerminal;
        match mode {
            ProgressMode::Json => Progress::Json,
            ProgressMode::None => Progress::None,
            ProgressMode::Auto if std::io::stderr().is_terminal() => {
                let bar = indicatif::ProgressBar::new(total as u64);
                bar.set_style(
                    indicatif::ProgressStyle::with_template(
                        "{spinner} {bar:40} {pos}/{len} jobs, {per_sec}, ETA {eta}  {msg}",
                    )
                    .expect("a valid template"),
                );
                // The spinner turns while a long bake is inside one stage; `stage` names it.
                bar.enable_steady_tick(std::time::Duration::from_millis(120));
                Progress::Bar(bar)
            }
            _ => Progress::Lines,
        }
    }

    /// The job of manifest line `line` entered bake stage `stage` (shown on the bar only).
    fn stage(&self, line: usize, stage: &str) {
        if let Progress::Bar(bar) = self {
            bar.set_message(format!("line {line}: {stage}"));
        }
    }

    /// Job `done` of `total` finished with summary row `row`.
    fn job(&self, done: usize, total: usize, row: &Value) {
        let status = row["status"].as_str().unwrap_or("?");
        let why = row["message"]
            .as_str()
            .map(|m| format!(": {m}"))
            .unwrap_or_default();
        let line = row["line"].as_u64().unwrap_or(0);
        match self {
            Progress::Bar(bar) => {
                if status == "failed" {
                    bar.println(format!("line {line}: failed{why}"));
                }
                bar.set_message(format!("line {line}: {status}"));
                bar.inc(1);
            }
            Progress::Lines => eprintln!("[{done}/{total}] line {line}: {status}{why}"),
            Progress::Json => println!(
                "{}",
                json!({ "event": "job", "done": done, "total": total, "line": line,
                        "status": status, "ms": row["ms"], "message": row["message"] })
            ),
            Progress::None => {}
        }
    }

    fn finish(&self, summary: &Value, path: &Path) {
        match self {
            Progress::Bar(bar) => bar.finish_with_message(format!("summary: {}", path.display())),
            Progress::Lines => eprintln!("summary: {}", path.display()),
            Progress::Json => println!(
                "{}",
                json!({ "event": "done", "counts": summary["counts"], "summary": path.display().to_string() })
            ),
            Progress::None => {}
        }
    }
}

/// The batch's engine, replaced by a fresh one when its device is lost (a driver reset, or the
/// fault injected by `DECALBAKE_FAULT_LOSE_DEVICE`): the job that saw the loss is baked again on
/// the new device, once, and the meshes cached on the old one are dropped.
pub struct Devices {
    /// (generation, engine): the generation counts replacements.
    current: std::sync::RwLock<(u32, Arc<Engine>)>,
    backend: Option<String>,
}

impl Devices {
    /// Starts with `engine`; replacements are made on `backend` (as `--backend`).
    pub fn new(engine: Engine, backend: Option<&str>) -> Self {
        Self {
            current: std::sync::RwLock::new((0, Arc::new(engine))),
            backend: backend.map(str::to_string),
        }
    }

    /// The engine now, with its generation.
    fn get(&self) -> (u32, Arc<Engine>) {
        let c = self.current.read().expect("devices");
        (c.0, c.1.clone())
    }

    /// Replaces generation `lost` with a fresh engine (a no-op when another thread already has);
    /// the engine to retry on.
    fn renew(&self, lost: u32) -> Result<(u32, Arc<Engine>)> {
        let mut c = self.current.write().expect("devices");
        if c.0 == lost {
            let engine = Engine::new(self.backend.as_deref())
                .context("making a fresh GPU device after the old one was lost")?;
            eprintln!("batch: the GPU device was lost; continuing on a fresh one");
            *c = (lost + 1, Arc::new(engine));
        }
        Ok((c.0, c.1.clone()))
    }

    /// The current engine's adapter.
    pub fn adapter(&self) -> String {
        self.get().1.ctx.adapter.clone()
    }

    /// Device replacements so far.
    fn resets(&self) -> u32 {
        self.current.read().expect("devices").0
    }
}

/// Whether `e` is (or wraps) a lost device.
fn device_lost(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        matches!(
            c.downcast_ref::<decalbake::Error>(),
            Some(decalbake::Error::DeviceLost { .. })
        )
    })
}

/// Exit code of a batch: 0, or 3 when some job failed.
pub fn run(devices: &Devices, opts: &BatchOptions) -> Result<i32> {
    let t0 = Instant::now();
    let entries = read_manifest(&opts.manifest)?;
    let (index, count, source) = shard(opts.shard.as_deref())?;
    eprintln!(
        "batch: {} jobs in {}, shard {index}/{count} ({source})",
        entries.len(),
        opts.manifest.display()
    );
    let mine: Vec<&Entry> = entries
        .iter()
        .enumerate()
        .filter(|(k, _)| k % count == index)
        .map(|(_, e)| e)
        .collect();
    // A manifest named without a folder (`m.jsonl`) has the empty path as its parent, which
    // cannot be listed: its folder is the current one.
    let root = opts.out.clone().unwrap_or_else(|| {
        match opts.manifest.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        }
        .to_path_buf()
    });
    // Shards writing into one directory keep their own journals and summaries.
    let (journal, summary_name) = if count > 1 {
        (
            format!("journal-{index}.jsonl"),
            format!("summary-{index}.json"),
        )
    } else {
        ("journal.jsonl".to_string(), "summary.json".to_string())
    };
    let journal = Journal::open(&root, &journal)?;
    let progress = Progress::new(opts.progress, mine.len());
    let rows = bake_all(devices, (opts, &journal), &mine, &progress);
    let failed = rows.iter().filter(|r| r["status"] == "failed").count();
    let mut summary = summary_of(
        rows,
        json!({ "index": index, "count": count, "source": source }),
        t0,
    );
    summary["device_resets"] = json!(devices.resets());
    // `--merge-summaries` joins the shards' summaries.
    let path = opts
        .summary
        .clone()
        .unwrap_or_else(|| root.join(summary_name));
    write_json(&path, &summary)?;
    progress.finish(&summary, &path);
    Ok(if failed > 0 { 3 } else { 0 })
}

/// Bakes `mine` on `opts.jobs` threads sharing the engine and the mesh cache, each taking the next
/// job in manifest order (`--fail-fast`: no new job after a failure); their summary rows.
fn bake_all(
    devices: &Devices,
    (opts, journal): (&BatchOptions, &Journal),
    mine: &[&Entry],
    progress: &Progress,
) -> Vec<Value> {
    use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
    use std::sync::Mutex;
    let (next, done, stop) = (
        AtomicUsize::new(0),
        AtomicUsize::new(0),
        AtomicBool::new(false),
    );
    let shared = Shared::default();
    let rows = Mutex::new(Vec::new());
    std::thread::scope(|scope| {
        for _ in 0..opts.jobs.max(1) {
            scope.spawn(|| loop {
                let k = next.fetch_add(1, Ordering::SeqCst);
                if k >= mine.len() || stop.load(Ordering::SeqCst) {
                    break;
                }
                let (entry, t) = (mine[k], Instant::now());
                let mut retried = false;
                let (mut gen, mut engine) = devices.get();
                let stage = |s: &str| progress.stage(entry.line, s);
                let mut result = fault::lose_device_during(entry.line, &engine, || {
                    bake_entry(&engine, gen, (opts, journal), entry, &shared, &stage)
                });
                if result.as_ref().is_err_and(device_lost) {
                    retried = true;
                    result = devices.renew(gen).and_then(|(g, e)| {
                        (gen, engine) = (g, e);
                        bake_entry(&engine, gen, (opts, journal), entry, &shared, &stage)
                    });
                }
                let mut row = match result {
                    Ok((status, outputs, hash)) => {
                        json!({ "status": status, "outputs": outputs, "input_hash": hash })
                    }
                    Err(e) => {
                        stop.fetch_or(opts.fail_fast, Ordering::SeqCst);
                        failure(&e)
                    }
                };
                row["line"] = json!(entry.line);
                row["job"] = json!(entry.file().map(|f| f.display().to_string()));
                row["ms"] = json!(t.elapsed().as_secs_f64() * 1000.0);
                if retried {
                    // Baked again on a fresh device after the first try lost it.
                    row["retried"] = json!(true);
                }
                progress.job(done.fetch_add(1, Ordering::SeqCst) + 1, mine.len(), &row);
                rows.lock().expect("rows").push(row);
            });
        }
    });
    rows.into_inner().expect("rows")
}

/// The manifest's jobs; any line that is neither a string nor an object stops the batch.
fn read_manifest(path: &Path) -> Result<Vec<Entry>> {
    // A manifest that cannot be read is the user's input, like a job file: exit 2.
    let text = std::fs::read_to_string(path).map_err(|source| decalbake::Error::Io {
        path: path.to_path_buf(),
        action: "reading the manifest",
        source,
    })?;
    Ok(decalbake::io::manifest::parse(&text, path)?)
}

/// (index, count, where they came from) of this process's shard.
fn shard(spec: Option<&str>) -> Result<(usize, usize, String)> {
    let env = |k: &str| {
        std::env::var(k)
            .ok()
            .and_then(|v| v.trim().parse::<usize>().ok())
    };
    let (index, count, source) = match spec {
        None => (0, 1, "all jobs".to_string()),
        Some("auto") => {
            let slurm = env("SLURM_ARRAY_TASK_ID");
            if let (Some(id), Some(n)) = (slurm, env("DECALBAKE_SHARDS")) {
                // A task run again on its own (`sbatch --array=2`) sees an array of one: with
                // DECALBAKE_SHARDS set, the task id is the shard and the count is fixed.
                (id, n, "Slurm job array, DECALBAKE_SHARDS".into())
            } else if let (Some(id), Some(n)) = (slurm, env("SLURM_ARRAY_TASK_COUNT")) {
                // Arrays like --array=4-16:4 step their ids: 4, 8, 12, 16 are shards 0..3.
                let min = env("SLURM_ARRAY_TASK_MIN").unwrap_or(0);
                let step = env("SLURM_ARRAY_TASK_STEP").unwrap_or(1).max(1);
                ((id - min.min(id)) / step, n, "Slurm job array".into())
            } else if let (Some(id), Some(n)) =
                (env("JOB_COMPLETION_INDEX"), env("DECALBAKE_SHARDS"))
            {
                (id, n, "Kubernetes indexed job".into())
            } else if let (Some(id), Some(n)) = (
                env("AWS_BATCH_JOB_ARRAY_INDEX"),
                env("AWS_BATCH_JOB_ARRAY_SIZE"),
            ) {
                (id, n, "AWS Batch array job".into())
            } else {
                bail!(bad_option("--shard auto found no array index: set SLURM_ARRAY_TASK_ID and SLURM_ARRAY_TASK_COUNT, JOB_COMPLETION_INDEX and DECALBAKE_SHARDS, or AWS_BATCH_JOB_ARRAY_INDEX and AWS_BATCH_JOB_ARRAY_SIZE"))
            }
        }
        Some(s) => {
            let parsed = s
                .split_once('/')
                .and_then(|(i, n)| Some((i.trim().parse().ok()?, n.trim().parse().ok()?)));
            match parsed {
                Some((i, n)) => (i, n, "--shard".into()),
                None => bail!(bad_option(&format!(
                    "--shard {s}: use I/N (for example 0/4) or auto"
                ))),
            }
        }
    };
    if count == 0 || index >= count {
        bail!(bad_option(&format!(
            "shard {index} of {count} ({source}): the index must be below the count"
        )));
    }
    Ok((index, count, source))
}

/// A bad option, as an input error (exit 2).
fn bad_option(msg: &str) -> decalbake::Error {
    job_error(Path::new("decalbake batch"), "options", msg)
}

/// Bakes one job (or skips it on `--resume`): (status, outputs, input hash).
fn bake_entry(
    engine: &Engine,
    generation: u32,
    (opts, journal): (&BatchOptions, &Journal),
    entry: &Entry,
    shared: &Shared,
    on_stage: &dyn Fn(&str),
) -> Result<(&'static str, Vec<String>, String)> {
    let manifest_dir = opts.manifest.parent().unwrap_or(Path::new(""));
    let (source, input_dir) = match entry.file() {
        Some(f) => (
            f.to_path_buf(),
            f.parent().unwrap_or(Path::new("")).to_path_buf(),
        ),
        None => (
            PathBuf::from(format!("{}#line-{}", opts.manifest.display(), entry.line)),
            manifest_dir.to_path_buf(),
        ),
    };
    let out_dir = match &opts.out {
        Some(root) => {
            // Braces become `_`, so that the output names' placeholders (`{uv}`, `{set}`,
            // `{channel}`, `{frame}`) never match the job's own folder.
            let stem = entry
                .file()
                .and_then(|f| f.file_stem())
                .map(|s| format!("-{}", s.to_string_lossy().replace(['{', '}'], "_")))
                .unwrap_or_default();
            root.join(format!("line-{}{stem}", entry.line))
        }
        None => input_dir.clone(),
    };
    let text = match &entry.job {
        EntryJob::Inline(t) => t.clone(),
        EntryJob::File(f) => std::fs::read_to_string(f).map_err(|source| decalbake::Error::Io {
            path: f.clone(),
            action: "reading the job file",
            source,
        })?,
    };
    let mut job = Job::parse(&text, &source, &input_dir, &out_dir)?;
    job.max_memory = crate::lower_limit(job.max_memory, opts.max_memory);
    let hash = input_hash(&text, &job, shared)?;
    // A several-set job (`"uv_set": [..]`) bakes once per set and shares one (blended) preview.
    // An animated job bakes once per frame.
    let animated = job.uv_list.is_empty() && job.frames().is_some();
    let jobs: Vec<Job> = match (job.uv_list.is_empty(), job.frames()) {
        (true, Some(n)) => (0..n).map(|f| job.for_frame(f)).collect(),
        (true, None) => vec![job.clone()],
        (false, _) => job.uv_list.iter().map(|&s| job.for_uv_set(s)).collect(),
    };
    let set_preview = job.out_preview.clone().filter(|_| !job.uv_list.is_empty());
    let outputs: Vec<PathBuf> = jobs
        .iter()
        .flat_map(|j| [&j.out_texture, &j.out_glb, &j.out_report, &j.out_preview])
        .flatten()
        .cloned()
        .chain(set_preview.clone())
        .collect();
    if opts.resume {
        if let Some(done) = journal.done(&hash, &out_dir) {
            return Ok(("skipped", done, hash));
        }
    }
    clear_stale_temporaries(&out_dir);
    let cx = (engine, generation, shared, hash.as_str(), on_stage);
    let mut undo = Undo::default();
    let done = if animated {
        write_frames(cx, jobs, &outputs, &mut undo)
    } else {
        write_sets(cx, jobs, (&outputs, set_preview.as_deref()), &mut undo)
    };
    let recorded = done
        .and_then(|()| journal.record((entry.line, entry.file()), &hash, &out_dir, &undo.files));
    if let Err(e) = recorded {
        undo.undo();
        return Err(e);
    }
    let names = outputs.iter().map(|p| p.display().to_string()).collect();
    Ok(("ok", names, hash))
}

/// Removes the temporary files (`.NAME.tmp-PID`, `io::image::write_atomic`) that a process
/// killed while writing left in `dir`: those whose process no longer runs (`/proc/PID`), so a
/// resumed batch leaves only outputs behind. A file of a live process (another bake writing
/// there now) is left alone.
fn clear_stale_temporaries(dir: &Path) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        let Some((_, pid)) = name.strip_prefix('.').and_then(|n| n.rsplit_once(".tmp-")) else {
            continue;
        };
        let Ok(pid) = pid.parse::<u32>() else {
            continue;
        };
        if pid != std::process::id() && !Path::new(&format!("/proc/{pid}")).exists() {
            let _ = std::fs::remove_file(e.path());
        }
    }
}

/// What [`write_sets`] and [`write_frames`] share: the engine, the device's generation, the run's
/// shared state, the job's input hash and the progress callback.
type WriteCx<'a> = (&'a Engine, u32, &'a Shared, &'a str, &'a dyn Fn(&str));

/// What a job has written, taken back when it fails: its files, then the directories it created
/// (those left empty), so a failed job leaves no output directory and no partial set of files.
/// Also `decalbake bake`'s animated jobs (`bake_frames` in main.rs).
#[derive(Default)]
pub(crate) struct Undo {
    pub(crate) files: Vec<PathBuf>,
    dirs: Vec<PathBuf>,
}

impl Undo {
    /// Removes the old reports of `outputs` (a run killed between renames must not leave one
    /// vouching for a half-replaced set of outputs) and creates the folders they need.
    pub(crate) fn prepare(&mut self, jobs: &[Job], outputs: &[PathBuf]) -> Result<()> {
        for r in jobs.iter().filter_map(|j| j.out_report.as_ref()) {
            let _ = std::fs::remove_file(r);
        }
        for dir in outputs.iter().filter_map(|p| p.parent()) {
            let missing: Vec<PathBuf> = dir
                .ancestors()
                .take_while(|d| !d.as_os_str().is_empty() && !d.exists())
                .map(Path::to_path_buf)
                .collect();
            std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
            self.dirs.extend(missing);
        }
        Ok(())
    }

    pub(crate) fn undo(self) {
        for f in &self.files {
            let _ = std::fs::remove_file(f);
        }
        // Deepest first; only empty ones go.
        let mut dirs = self.dirs;
        dirs.sort_by_key(|d| std::cmp::Reverse(d.components().count()));
        for d in &dirs {
            let _ = std::fs::remove_dir(d);
        }
    }
}

/// `job`'s mesh from the run's cache (loaded on first use) and its UV set resolved.
fn cached_mesh(cx: WriteCx<'_>, job: &Job) -> Result<(Arc<LoadedMesh>, u32)> {
    let (engine, generation, shared, _, _) = cx;
    let got = shared
        .meshes
        .lock()
        .expect("mesh cache")
        .get(engine, generation, job)?;
    Ok(got)
}

/// One job of a set, ready to bake: its mesh from the run's cache, its UV set resolved and, on a
/// mesh of one texture set, that set's size.
fn prepare_one(cx: WriteCx<'_>, mut j: Job) -> Result<(Arc<LoadedMesh>, Job)> {
    let (mesh, uv_set) = cached_mesh(cx, &j)?;
    j.uv_set = uv_set;
    let sets = mesh.mesh.texture_sets(uv_set);
    // `{set}` and `{channel}` named as `decalbake bake` names them for a mesh of one set.
    j = j.for_single_set(sets.first().map_or("default", |s| s.name.as_str()));
    if let [set] = sets.as_slice() {
        (j.width, j.height) = decalbake::bake::sets::set_size(&j, &mesh.mesh, set);
    }
    Ok((mesh, j))
}

/// Bakes one job of a set (its mesh from the run's cache), the input hash in its report.
fn bake_one(cx: WriteCx<'_>, j: Job) -> Result<(Arc<LoadedMesh>, Job, decalbake::Baked)> {
    let (mesh, j) = prepare_one(cx, j)?;
    let mut baked = cx.0.bake_with_progress(&mesh, &j, cx.4)?;
    baked.report.input_hash = Some(cx.3.to_string());
    Ok((mesh, j, baked))
}

/// Bakes one job and writes its files (streamed band by band where it goes by tiles,
/// `decalbake::output::bake_and_write`), the input hash in its report; `undo` learns the files.
fn write_one(cx: WriteCx<'_>, j: Job, outputs: &[PathBuf], undo: &mut Undo) -> Result<()> {
    let (mesh, j) = prepare_one(cx, j)?;
    undo.prepare(std::slice::from_ref(&j), outputs)?;
    let hash = cx.3.to_string();
    let amend = |r: &mut decalbake::bake::report::Report| r.input_hash = Some(hash.clone());
    let (_, files) = decalbake::output::bake_and_write(cx.0, &mesh, &j, cx.4, &amend)?;
    undo.files.extend(files);
    Ok(())
}

/// A job's UV sets (or its one bake): every set baked before anything is written, then written,
/// then the blended preview of the sets.
fn write_sets(
    cx: WriteCx<'_>,
    jobs: Vec<Job>,
    (outputs, set_preview): (&[PathBuf], Option<&Path>),
    undo: &mut Undo,
) -> Result<()> {
    if let [job] = jobs.as_slice() {
        if write_texture_sets(cx, job, outputs, undo)? {
            return Ok(());
        }
        if set_preview.is_none() {
            return write_one(cx, job.clone(), outputs, undo);
        }
    }
    // Every UV set of the list baked before anything is written; one of several texture sets
    // bakes a texture per set, as a job of that UV set alone does.
    let mut baked = Vec::with_capacity(jobs.len());
    let mut mesh = None;
    for j in jobs {
        let (m, uv) = bake_uv_set(cx, j)?;
        mesh = Some(m);
        baked.push(uv);
    }
    let Some(mesh) = mesh else { return Ok(()) };
    let jobs: Vec<Job> = baked
        .iter()
        .map(|b| match b {
            UvBake::One(j, _) | UvBake::Sets(j, _) => j.clone(),
        })
        .collect();
    undo.prepare(&jobs, outputs)?;
    (cx.4)("writing outputs");
    for (_, files) in decalbake::output::write_uv_bakes(cx.0, &mesh, baked, set_preview)? {
        undo.files.extend(files);
    }
    Ok(())
}

/// One UV set of a job's list (`Job::for_uv_set`): the whole mesh into one texture
/// ([`bake_one`]), or a texture per texture set where the mesh has several on that UV set.
fn bake_uv_set(cx: WriteCx<'_>, j: Job) -> Result<(Arc<LoadedMesh>, UvBake)> {
    let (engine, _, _, hash, _) = cx;
    let (mesh, uv_set) = cached_mesh(cx, &j)?;
    let sets = mesh.mesh.texture_sets(uv_set);
    if sets.len() < 2 {
        let (mesh, j, baked) = bake_one(cx, j)?;
        return Ok((mesh, UvBake::One(j, Box::new(baked))));
    }
    let mut bakes = engine.bake_texture_sets(&mesh, &j, sets)?;
    bakes[0].baked.report.input_hash = Some(hash.to_string());
    Ok((mesh, UvBake::Sets(j, bakes)))
}

/// A job on a mesh of several texture sets: one texture per set, one model, preview and report
/// (`decalbake::output::write_set_outputs`, as `decalbake bake` writes them); `false`, having
/// done nothing, for a mesh of one set.
fn write_texture_sets(
    cx: WriteCx<'_>,
    job: &Job,
    outputs: &[PathBuf],
    undo: &mut Undo,
) -> Result<bool> {
    let (engine, _, _, hash, on_stage) = cx;
    let (mesh, uv_set) = cached_mesh(cx, job)?;
    let mut j = job.clone();
    j.uv_set = uv_set;
    let sets = mesh.mesh.texture_sets(uv_set);
    if sets.len() < 2 {
        return Ok(false);
    }
    on_stage("texture sets");
    let mut bakes = engine.bake_texture_sets(&mesh, &j, sets)?;
    bakes[0].baked.report.input_hash = Some(hash.to_string());
    undo.prepare(std::slice::from_ref(&j), outputs)?;
    on_stage("writing outputs");
    let files = decalbake::output::write_set_outputs(engine, &mesh, &j, &mut bakes)?;
    undo.files.extend(files);
    Ok(true)
}

/// An animated job's frames, each written as soon as it is baked (a thousand 4096² frames are not
/// held in memory); a frame that fails takes back the ones written before it.
fn write_frames(
    cx: WriteCx<'_>,
    jobs: Vec<Job>,
    outputs: &[PathBuf],
    undo: &mut Undo,
) -> Result<()> {
    undo.prepare(&jobs, outputs)?;
    for j in jobs {
        // On a mesh of several texture sets, a texture per set, as an unanimated job bakes.
        if !write_texture_sets(cx, &j, outputs, undo)? {
            write_one(cx, j, outputs, undo)?;
        }
    }
    Ok(())
}

/// What the jobs of one run share: loaded meshes and the digests of the files they read.
#[derive(Default)]
struct Shared {
    meshes: std::sync::Mutex<MeshCache>,
    /// SHA-256 of each input file read so far, by path: a mesh that 200 jobs use is read and
    /// hashed once per run (its bytes do not change while the batch runs).
    digests: std::sync::Mutex<std::collections::HashMap<PathBuf, [u8; 32]>>,
}

impl Shared {
    /// The file's SHA-256 (of no bytes when it cannot be read: that is the bake's error to report,
    /// with its own message).
    fn digest(&self, f: &Path) -> [u8; 32] {
        if let Some(d) = self.digests.lock().expect("digests").get(f) {
            return *d;
        }
        let d: [u8; 32] = Sha256::digest(std::fs::read(f).unwrap_or_default()).into();
        self.digests
            .lock()
            .expect("digests")
            .insert(f.to_path_buf(), d);
        d
    }
}

/// SHA-256 of the engine version, the job's text and the digests of every file it reads (the
/// mesh, a `.gltf`'s external buffers and images, the base image, the layers' images and masks),
/// each part prefixed by its length.
fn input_hash(text: &str, job: &Job, shared: &Shared) -> Result<String> {
    let mut h = Sha256::new();
    let mut part = |bytes: &[u8]| {
        h.update((bytes.len() as u64).to_le_bytes());
        h.update(bytes);
    };
    part(env!("CARGO_PKG_VERSION").as_bytes());
    part(text.as_bytes());
    let mut files = vec![job.mesh.clone()];
    files.extend(gltf_external_files(&job.mesh));
    match &job.base {
        decalbake::io::job::Base::Image(p) => files.push(p.clone()),
        decalbake::io::job::Base::Transfer { source, .. } => {
            if let decalbake::io::job::Base::Image(p) = &**source {
                files.push(p.clone());
            }
        }
        _ => {}
    }
    for l in &job.layers {
        match &l.text {
            // A text layer's glyphs come from its font (the bundled one is the binary's).
            Some(t) => files.extend(t.font.clone()),
            None => files.push(l.image.clone()),
        }
        files.extend(l.mask.clone());
        let c = &l.channels;
        files.extend(c.normal.as_ref().map(|n| n.image.clone()));
        for ch in [&c.roughness, &c.metallic, &c.occlusion, &c.emissive]
            .into_iter()
            .flatten()
        {
            if let decalbake::io::channels::Value::Image(p) = &ch.value {
                files.push(p.clone());
            }
        }
    }
    for f in files {
        part(&shared.digest(&f));
    }
    Ok(format!("{:x}", h.finalize()))
}

/// The files a `.gltf` names by URI (buffers and images; data URIs are in the file itself).
fn gltf_external_files(mesh: &Path) -> Vec<PathBuf> {
    let is_gltf = mesh
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("gltf"));
    let Some(doc) = is_gltf
        .then(|| std::fs::read(mesh).ok())
        .flatten()
        .and_then(|b| serde_json::from_slice::<Value>(&b).ok())
    else {
        return Vec::new();
    };
    let dir = mesh.parent().unwrap_or(Path::new(""));
    ["buffers", "images"]
        .iter()
        .flat_map(|k| doc[*k].as_array().cloned().unwrap_or_default())
        .filter_map(|e| e["uri"].as_str().map(str::to_string))
        .filter(|u| !u.starts_with("data:"))
        .map(|u| dir.join(u))
        .collect()
}

/// A failed job's summary row: message, file and field where the error names them, class.
fn failure(e: &anyhow::Error) -> Value {
    let engine_error = e.chain().find_map(|c| c.downcast_ref::<decalbake::Error>());
    let (file, field) = match engine_error {
        Some(decalbake::Error::Job { path, field, .. }) => {
            (Some(path.display().to_string()), Some(field.clone()))
        }
        Some(
            decalbake::Error::Io { path, .. }
            | decalbake::Error::Image { path, .. }
            | decalbake::Error::Gltf { path, .. }
            | decalbake::Error::Mesh { path, .. }
            | decalbake::Error::Placement { path, .. },
        ) => (Some(path.display().to_string()), None),
        _ => (None, None),
    };
    let input = engine_error.is_some_and(|d| d.is_input_error());
    // The engine's errors say everything (their sources included); others show their chain.
    let message = match engine_error {
        Some(d) => d.to_string(),
        None => format!("{e:#}"),
    };
    json!({
        "status": "failed",
        "message": message,
        "file": file,
        "field": field,
        "class": if input { "input" } else { "engine" },
    })
}

/// The summary of `rows` (job rows, in manifest order).
fn summary_of(mut rows: Vec<Value>, shard: Value, t0: Instant) -> Value {
    rows.sort_by_key(|r| r["line"].as_u64());
    let count = |s: &str| rows.iter().filter(|r| r["status"] == s).count();
    json!({
        "version": env!("CARGO_PKG_VERSION"),
        "shard": shard,
        "counts": { "ok": count("ok"), "skipped": count("skipped"), "failed": count("failed") },
        "seconds": t0.elapsed().as_secs_f64(),
        "jobs": rows,
    })
}

/// `--merge-summaries`: the shards' summaries as one (jobs in manifest order, counts added up);
/// exit 3 when a job failed in any of them.
pub fn merge(inputs: &[PathBuf], out: &Path) -> Result<i32> {
    let t0 = Instant::now();
    let (mut rows, mut shards, mut seconds) = (Vec::new(), Vec::new(), Vec::new());
    for p in inputs {
        let v: Value = serde_json::from_slice(
            &std::fs::read(p).with_context(|| format!("reading the summary {}", p.display()))?,
        )
        .map_err(|e| job_error(p, "(top level)", format!("not a summary: {e}")))?;
        let Some(jobs) = v["jobs"].as_array() else {
            bail!(job_error(p, "jobs", "a summary has a jobs array"));
        };
        rows.extend(jobs.iter().cloned());
        shards.push(v["shard"].clone());
        seconds.push(v["seconds"].as_f64().unwrap_or(0.0));
    }
    // A line in several summaries (a task run again on its own baked the whole manifest) counts
    // once: its last success, else its last row.
    let mut by_line: std::collections::BTreeMap<u64, Value> = Default::default();
    for r in rows {
        let line = r["line"].as_u64().unwrap_or(0);
        let keep_old = by_line
            .get(&line)
            .is_some_and(|old| old["status"] != "failed" && r["status"] == "failed");
        if !keep_old {
            by_line.insert(line, r);
        }
    }
    let rows: Vec<Value> = by_line.into_values().collect();
    let failed = rows.iter().any(|r| r["status"] == "failed");
    let missing = missing_shards(&shards);
    let mut summary = summary_of(rows, Value::Null, t0);
    summary["shard"] = json!({ "merged": shards, "missing": missing });
    // The shards ran side by side: the batch took as long as the slowest.
    summary["seconds"] = json!(seconds.iter().cloned().fold(0.0, f64::max));
    write_json(out, &summary)?;
    eprintln!("merged {} summaries into {}", inputs.len(), out.display());
    if !missing.is_empty() {
        eprintln!(
            "merged summary: no summary from shard(s) {missing:?}: their jobs are not listed"
        );
    }
    Ok(if failed || !missing.is_empty() { 3 } else { 0 })
}

/// The shard indices below the count the summaries' `shard` blocks name that none of them is
/// (empty when the counts disagree or a summary was not sharded).
fn missing_shards(shards: &[Value]) -> Vec<u64> {
    let counts: std::collections::BTreeSet<u64> =
        shards.iter().filter_map(|s| s["count"].as_u64()).collect();
    let (Some(&n), 1) = (counts.iter().next(), counts.len()) else {
        return Vec::new();
    };
    let have: std::collections::BTreeSet<u64> =
        shards.iter().filter_map(|s| s["index"].as_u64()).collect();
    (0..n).filter(|i| !have.contains(i)).collect()
}

fn write_json(path: &Path, v: &Value) -> Result<()> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let text = serde_json::to_string_pretty(v)?;
    decalbake::io::image::write_atomic(path, text.as_bytes())?;
    Ok(())
}

/// A cached mesh: its path, and for `"uv_set": "auto"` the texture side its unwrap was packed for
/// (an auto-unwrapped mesh is not the plain one).
type MeshKey = (PathBuf, Option<u32>);

/// Loaded meshes by path, least recently used first out past [`MESH_BUDGET`].
#[derive(Default)]
struct MeshCache {
    /// (key, mesh, the UV set a job of that key bakes into, estimated bytes), most recently used
    /// last.
    entries: Vec<(MeshKey, Arc<LoadedMesh>, u32, u64)>,
    /// The engine generation the meshes live on ([`Devices`]).
    generation: u32,
}

impl MeshCache {
    /// The mesh of `job` on `engine` (of `generation`: meshes of an older, lost device are
    /// dropped) and the UV set it bakes into (`"auto"` resolved).
    fn get(
        &mut self,
        engine: &Engine,
        generation: u32,
        job: &Job,
    ) -> Result<(Arc<LoadedMesh>, u32)> {
        if generation != self.generation {
            self.entries.clear();
            self.generation = generation;
        }
        let key = (
            job.mesh.clone(),
            job.uv_auto.then_some(job.width.max(job.height)),
        );
        if let Some(i) = self.entries.iter().position(|e| e.0 == key) {
            let e = self.entries.remove(i);
            let found = (e.1.clone(), if job.uv_auto { e.2 } else { job.uv_set });
            self.entries.push(e);
            return Ok(found);
        }
        let (mesh, resolved) = engine.load_mesh_for(job)?;
        let mesh = Arc::new(mesh);
        let bytes = mesh_bytes(&mesh);
        while !self.entries.is_empty()
            && self.entries.iter().map(|e| e.3).sum::<u64>() + bytes > MESH_BUDGET
        {
            self.entries.remove(0);
        }
        self.entries
            .push((key, mesh.clone(), resolved.uv_set, bytes));
        Ok((mesh, resolved.uv_set))
    }
}

/// A loaded mesh's estimated size: about 200 bytes a welded vertex and 150 a triangle over its CPU
/// and GPU copies (positions, normals, UVs, adjacency, curvature, BVH), plus its material texture.
fn mesh_bytes(m: &LoadedMesh) -> u64 {
    let tex = m
        .mesh
        .material
        .as_ref()
        .and_then(|mt| mt.base_color_texture.as_ref())
        .map_or(0, |t| t.width as u64 * t.height as u64 * 32);
    200 * m.stats.welded_vertices as u64 + 150 * m.stats.triangles as u64 + tex
}

/// An input error naming `path` and `field` (exit 2 for `bake`; class `input` in a summary).
fn job_error(path: &Path, field: impl Into<String>, detail: impl Into<String>) -> decalbake::Error {
    decalbake::Error::Job {
        path: path.to_path_buf(),
        field: field.into(),
        detail: detail.into(),
    }
}

/// Fault injection for the reliability tests: `DECALBAKE_FAULT_LOSE_DEVICE=LINE[:MS]` destroys
/// the engine's device from another thread MS milliseconds (default 20) into the first bake of the
/// manifest's line LINE, as a driver reset would. Unset, nothing happens.
mod fault {
    use decalbake::Engine;
    use std::sync::atomic::{AtomicBool, Ordering};

    static FIRED: AtomicBool = AtomicBool::new(false);

    /// Runs `bake` (the job of manifest line `line`), losing the device during it when asked to.
    pub fn lose_device_during<T>(line: usize, engine: &Engine, bake: impl FnOnce() -> T) -> T {
        let spec = std::env::var("DECALBAKE_FAULT_LOSE_DEVICE").unwrap_or_default();
        let mut parts = spec.split(':');
        let target = parts.next().and_then(|l| l.parse::<usize>().ok());
        let ms = parts.next().and_then(|m| m.parse().ok()).unwrap_or(20);
        if target != Some(line) || FIRED.swap(true, Ordering::SeqCst) {
            return bake();
        }
        std::thread::scope(|s| {
            s.spawn(|| {
                std::thread::sleep(std::time::Duration::from_millis(ms));
                eprintln!("fault injection: destroying the GPU device during line {line}");
                engine.ctx.device.destroy();
            });
            bake()
        })
    }
}

#[cfg(test)]
mod tests {
    use super::clear_stale_temporaries;

    #[test]
    fn stale_temporaries_go_and_live_ones_and_outputs_stay() {
        let dir = std::env::temp_dir().join(format!("decalbake-stale-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        // No process has an id above the kernel's pid_max (at most 2^22).
        let dead = ".a.png.tmp-99999999";
        let live = format!(".b.png.tmp-{}", std::process::id());
        for name in [dead, live.as_str(), "a.png", ".hidden.tmp-notapid"] {
            std::fs::write(dir.join(name), b"x").unwrap();
        }
        clear_stale_temporaries(&dir);
        assert!(!dir.join(dead).exists(), "a dead process's temporary stays");
        for name in [live.as_str(), "a.png", ".hidden.tmp-notapid"] {
            assert!(dir.join(name).exists(), "{name} was removed");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
