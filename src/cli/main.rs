// SPDX-License-Identifier: MIT OR Apache-2.0
//! The `decalbake` command line.

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use decalbake::mesh::Mesh;
use decalbake::{Engine, Job};

mod batch;
mod bench;
mod demo;
mod fuzz;
mod journal;
mod unwrap;
use std::path::{Path, PathBuf};

/// Counts live heap bytes and caps them while `decalbake fuzz` runs (`fuzz/alloc.rs`); otherwise
/// `System` plus one relaxed atomic load per call.
#[global_allocator]
static ALLOC: fuzz::alloc::Counting = fuzz::alloc::Counting;

#[derive(Parser)]
#[command(
    name = "decalbake",
    version,
    about = "Bakes decals onto 3D meshes, straight into the mesh's texture, on the GPU."
)]
struct Cli {
    /// GPU backend: vulkan or gl (default: WGPU_BACKEND, else Vulkan then GL).
    #[arg(long, global = true)]
    backend: Option<String>,
    /// The most memory a bake may take (`bake`, `batch`): bytes or a size with a unit
    /// ("512MiB", "2GB"); a job's own `max_memory` lowers it. Default: the memory available.
    #[arg(long, global = true, value_parser = memory_size)]
    max_memory: Option<u64>,
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Bake the built-in demo scene (Spot with five decals, two strokes, a ribbon, an SVG logo and
    /// a line of text along its flank; the knight with a material decal and two texture sets; an
    /// unwrapped sheet) into a folder, with its job files.
    Demo {
        /// Output directory.
        #[arg(long, default_value = "decalbake-demo")]
        out: PathBuf,
        /// Also unwrap Spot and bob (new UV sets by pelting, bob with its patch) and bake bob's
        /// three sets: about 9 s more on a 2-core software device.
        #[arg(long)]
        all: bool,
    },
    /// Bake the jobs of a manifest (JSON Lines: job file paths or job objects) in one process:
    /// failures isolated, `--resume` after a killed node, shards for job arrays.
    Batch {
        /// The manifest.
        manifest: Option<PathBuf>,
        /// Output root: each job's outputs go to DIR/line-N[-stem]/ (default: as each job says).
        #[arg(long)]
        out: Option<PathBuf>,
        /// This process's share: I/N (jobs whose position is I modulo N), or auto (Slurm, Kubernetes
        /// or AWS Batch array index).
        #[arg(long)]
        shard: Option<String>,
        /// Skip jobs whose outputs exist with the same input hash.
        #[arg(long)]
        resume: bool,
        /// Stop at the first failed job.
        #[arg(long)]
        fail_fast: bool,
        /// Summary JSON (default: summary.json in the output root, else beside the manifest).
        #[arg(long)]
        summary: Option<PathBuf>,
        /// Join these shard summaries into --summary instead of baking.
        #[arg(long, num_args = 1..)]
        merge_summaries: Vec<PathBuf>,
        /// Progress: a bar on a terminal, else one line per job (auto), lines, or JSON events on
        /// stdout (json).
        #[arg(long, value_enum, default_value = "auto")]
        progress: batch::ProgressMode,
        /// Jobs baked at once (threads sharing the engine).
        #[arg(long, default_value_t = 1)]
        jobs: usize,
    },
    /// Bake a job file.
    Bake {
        /// The job file (JSON).
        job: PathBuf,
        /// Output directory (default: next to the job file).
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Write a layer's local coordinates per reached vertex as CSV: x,y,z,distance,u,v.
    Param {
        /// The job file (JSON).
        job: PathBuf,
        /// Which layer (0-based).
        #[arg(long, default_value_t = 0)]
        layer: usize,
        /// Output CSV file.
        #[arg(long)]
        out: PathBuf,
    },
    /// Extract the job's texture along a ribbon's or decal's map into a flat image (texture
    /// cloning, Sun et al. 2013 section 4.2): the PNG can be another layer's `image`.
    Extract {
        /// The job file (JSON); its `texture.base` is the texture read.
        job: PathBuf,
        /// Which layer (0-based): a decal or a ribbon.
        #[arg(long, default_value_t = 0)]
        layer: usize,
        /// Output PNG (16-bit RGBA, straight alpha).
        #[arg(long)]
        out: PathBuf,
        /// Output size in pixels (default: the layer image's; a tiled ribbon's copies side by side).
        #[arg(long, num_args = 2, value_names = ["W", "H"])]
        size: Option<Vec<u32>>,
        /// Alpha from an automatic matte (colour distance to the strip's border, smoothed by a
        /// sparse solve on the GPU) instead of the layer's mask.
        #[arg(long)]
        matte: bool,
    },
    /// Write a copy of a model with a new UV set made by pelting (cut to disks, stretched on frames
    /// by spring dynamics on the GPU, packed).
    Unwrap(unwrap::UnwrapArgs),
    /// Fuzz the parsers of job files, manifests, glTF and images (no GPU, no files needed): a
    /// mutation fuzzer whose findings (panics, hangs, allocations past a cap) are saved as inputs
    /// under `--findings DIR/<target>/`; `--replay DIR` runs such inputs again.
    Fuzz(fuzz::FuzzArgs),
    /// Print what the engine sees in a mesh.
    Info {
        /// A .gltf or .glb file.
        mesh: PathBuf,
    },
    /// Benchmark the bake and print JSON figures.
    Bench(BenchArgs),
    /// Print the JSON Schema (draft 2020-12) of a job file or of one line of a batch manifest,
    /// for editors and for checking job files before a bake.
    Schema {
        /// `job` or `manifest`.
        #[arg(default_value = "job", value_parser = ["job", "manifest"])]
        which: String,
        /// Write it to this file instead of standard output.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Print the job file's fields as a markdown table instead (the index of
        /// docs/job-file.md).
        #[arg(long)]
        fields: bool,
    },
}

/// `decalbake bench`'s options.
#[derive(clap::Args)]
struct BenchArgs {
    /// Mesh to bake onto (default: the largest mesh with UVs in ../shared/data/meshes, else the demo mesh).
    #[arg(long)]
    mesh: Option<PathBuf>,
    /// Texture sides to measure.
    #[arg(long, value_delimiter = ',', default_value = "2048,4096")]
    sizes: Vec<u32>,
    /// Decal counts to measure.
    #[arg(long, value_delimiter = ',', default_value = "1,16,256")]
    decals: Vec<usize>,
    /// Repetitions per configuration (the median is reported).
    #[arg(long, default_value_t = 3)]
    reps: usize,
    /// Midpoint subdivisions of the mesh (each multiplies the triangles by 4).
    #[arg(long, default_value_t = 0)]
    subdivide: u32,
    /// Time the CPU twin too when decals × side² is at most this.
    #[arg(long, default_value_t = 16 * 2048 * 2048)]
    cpu_budget: u64,
    /// Benchmark exponential maps instead of bakes (discs of about 1k, 10k and 100k vertices on
    /// the mesh subdivided 2 and 3 times, or `--subdivide` times; then a batch of small maps).
    #[arg(long)]
    geodesic: bool,
    /// Decal method of the bake benchmark's layers and of `--vector`'s SVG decals: `planar`
    /// (default) or `expmap` (then the bake includes every decal's exponential map).
    #[arg(long, default_value = "planar")]
    method: String,
    /// With `--geodesic`: the paper's plain update instead of the smooth mode.
    #[arg(long)]
    fast: bool,
    /// Maps in the batched geodesic benchmark (charts in the batched `--linalg` one: 1024).
    #[arg(long)]
    batch: Option<usize>,
    /// Benchmark the GPU linear algebra and LSCM charts instead of bakes (copy bandwidth, SpMV,
    /// charts of about 1k, 10k and 100k vertices on the mesh subdivided `--subdivide` times
    /// (default 3), and a batch of small charts).
    #[arg(long)]
    linalg: bool,
    /// Measure whether decals keep their size: one decal at each mesh's highest vertex per method
    /// (expmap, lscm, hybrid); `--mesh` or the shared spot, fandisk, bob and Duck.
    #[arg(long)]
    scale: bool,
    /// Benchmark strokes: a stroke of `--stamps` stamps over `--mesh` (default the bundled bob,
    /// subdivided twice unless `--subdivide` says otherwise) at the first of `--sizes`, per stamp
    /// method, against as many separate decals and the CPU twin.
    #[arg(long)]
    strokes: bool,
    /// With `--strokes`: stamps in the stroke.
    #[arg(long, default_value_t = 1000)]
    stamps: usize,
    /// Measure the adapter itself: copy bandwidth, dispatch, submit + wait, workgroup barrier,
    /// atomics, small dense systems per invocation against per workgroup.
    #[arg(long)]
    device: bool,
    /// With `--linalg`, `--geodesic`, `--unwrap` or `--ribbons`: the `../shared/peers` directory,
    /// to run libigl's LSCM, potpourri3d's log maps, xatlas, ARAP and harmonic maps, or
    /// potpourri3d's heat-method distance from the curve, on the same patches / meshes and seeds.
    #[arg(long)]
    peers: Option<PathBuf>,
    /// Jobs per minute of `decalbake batch` against one `decalbake bake` process per job:
    /// the first `--decals` value is the number of jobs, at `--sizes` in turn.
    #[arg(long)]
    batch_bake: bool,
    /// Benchmark `decalbake unwrap` on the GPU and through its CPU twin (Spot, bob, the
    /// bunny, bob subdivided twice, or `--mesh`), with `--peers`: xatlas, libigl ARAP and
    /// harmonic on the same meshes.
    #[arg(long)]
    unwrap: bool,
    /// With `--unwrap`: skip the GPU run of meshes over this many triangles (the bunny's, 69k,
    /// takes about 23 s on lavapipe; bob subdivided twice's, 171k, several minutes).
    #[arg(long, default_value_t = 100_000)]
    gpu_max_triangles: usize,
    /// Soak: this many bakes in one process (four jobs in turn on `--mesh`, default the
    /// bundled Spot), resident memory after every hundred and whether it stayed flat after
    /// warm-up.
    #[arg(long)]
    soak: Option<usize>,
    /// Bake the same `--decals` (first value, default 16) at each of `--sizes`, tiled where
    /// the canvas does not fit one storage buffer: cost per texel against the first size.
    #[arg(long)]
    tiles: bool,
    /// Benchmark the extended exponential map of a curve (ribbons' map) on the GPU against its
    /// CPU twin: `--mesh` subdivided `--subdivide` times, or bob and the shared bunny subdivided
    /// twice; a curve of `--stamps` pieces.
    #[arg(long)]
    ribbons: bool,
    /// With `--linalg`: chart sizes (vertices) to solve one at a time.
    #[arg(long, value_delimiter = ',', default_value = "1000,10000,100000")]
    charts: Vec<usize>,
    /// Bake one decal onto every glTF model of this corpus (`benches/corpus/fetch.sh DIR`): a
    /// row per model, baked or refused and why, seconds, and whether its document was kept.
    #[arg(long)]
    corpus: Option<PathBuf>,
    /// What PBR channels add to a bake: the largest `--decals` value (default 256) on `--mesh`
    /// (default the bundled bob) at each of `--sizes`, colour only against colour + normal +
    /// roughness + metallic, median of `--reps`; JSON lines on stdout, a table on stderr.
    #[arg(long)]
    channels: bool,
    /// What vector images cost: `--decals` SVG decals (its first value; 64 when not given) on `--mesh`
    /// (default the bundled bob) and 1,000 glyphs along curves on a plane, against the same
    /// layers as PNGs at the same pixel sizes, at each of `--sizes`; JSON lines on stdout.
    #[arg(long)]
    vector: bool,
    /// What an edit of a live bake costs: the largest `--decals` value (default 256) on `--mesh`
    /// (default the bundled bob) at each of `--sizes`, a full bake (median of `--reps`) against
    /// moving one decal 20 times (`full_ms`, `edit_ms`, `identical`); JSON lines on stdout.
    #[arg(long)]
    edit: bool,
    /// The bake and `--channels` benchmarks' `texture.sampling`: `full` (once a sample) or
    /// `adaptive` (four samples a pixel, once a texel and triangle).
    #[arg(long, default_value = "full", value_parser = ["full", "adaptive"])]
    sampling: String,
}

/// The engine's diagnostics (`log`) on stderr: its warnings and errors by default; with
/// `DECALBAKE_LOG=error|warn|info|debug|trace` that level, wgpu's and the other crates' records
/// included (`off` silences them all).
struct StderrLog {
    /// Only the engine's own records (no `DECALBAKE_LOG`).
    own_only: std::sync::atomic::AtomicBool,
}

impl log::Log for StderrLog {
    fn enabled(&self, metadata: &log::Metadata) -> bool {
        let own = metadata.target().starts_with("decalbake");
        metadata.level() <= log::max_level()
            && (own || !self.own_only.load(std::sync::atomic::Ordering::Relaxed))
    }
    fn log(&self, record: &log::Record) {
        if self.enabled(record.metadata()) {
            let level = match record.level() {
                log::Level::Warn => "warning".to_string(),
                other => other.as_str().to_ascii_lowercase(),
            };
            eprintln!("{level}: {}", record.args());
        }
    }
    fn flush(&self) {}
}

fn main() {
    static LOG: StderrLog = StderrLog {
        own_only: std::sync::atomic::AtomicBool::new(true),
    };
    let chosen = std::env::var("DECALBAKE_LOG")
        .ok()
        .and_then(|l| l.parse::<log::LevelFilter>().ok());
    LOG.own_only
        .store(chosen.is_none(), std::sync::atomic::Ordering::Relaxed);
    let level = chosen.unwrap_or(log::LevelFilter::Warn);
    if log::set_logger(&LOG).is_ok() {
        log::set_max_level(level);
    }
    let cli = Cli::parse();
    if let Err(e) = run(cli) {
        eprintln!("error: {}", message(&e));
        let input = e.chain().any(|c| {
            c.downcast_ref::<decalbake::Error>()
                .is_some_and(|d| d.is_input_error())
        });
        std::process::exit(if input { 2 } else { 1 });
    }
}

/// The error and its causes, joined by ": ", each cause left out when the message before it
/// already says it (`decalbake::Error::Io` names its OS error, which is also its cause).
fn message(e: &anyhow::Error) -> String {
    let mut out = String::new();
    for cause in e.chain() {
        let text = cause.to_string();
        if !out.ends_with(&text) {
            if !out.is_empty() {
                out.push_str(": ");
            }
            out.push_str(&text);
        }
    }
    out
}

fn run(cli: Cli) -> Result<()> {
    match cli.cmd {
        Cmd::Demo { out, all } => demo(&out, all, cli.backend.as_deref()),
        Cmd::Bake { job, out } => {
            let mut job = Job::load(&job, out.as_deref())?;
            job.max_memory = lower_limit(job.max_memory, cli.max_memory);
            let engine = engine(cli.backend.as_deref())?;
            // One plain bake in this process: nothing to pool its canvas for (docs/, "Peak
            // memory"). Animations and several-set jobs bake more than once: they keep the pool.
            if job.uv_list.is_empty() && job.frames().is_none() {
                engine.keep_buffers(0);
            }
            bake(&engine, &job)
        }
        Cmd::Info { mesh } => info(&mesh),
        Cmd::Fuzz(args) => {
            let code = fuzz::run(&args)?;
            if code != 0 {
                std::process::exit(code);
            }
            Ok(())
        }
        Cmd::Unwrap(args) => {
            let backend = cli.backend.clone();
            unwrap::run(&args, backend.as_deref(), || engine(backend.as_deref()))
        }
        Cmd::Batch {
            manifest,
            out,
            shard,
            resume,
            fail_fast,
            summary,
            merge_summaries,
            progress,
            jobs,
        } => {
            let opts = manifest.map(|manifest| batch::BatchOptions {
                max_memory: cli.max_memory,
                manifest,
                out,
                shard,
                resume,
                fail_fast,
                summary: summary.clone(),
                progress,
                jobs,
            });
            batch_cmd(cli.backend.as_deref(), opts, &merge_summaries, summary)
        }
        Cmd::Param { job, layer, out } => param(cli.backend.as_deref(), &job, layer, &out),
        Cmd::Extract {
            job,
            layer,
            out,
            size,
            matte,
        } => {
            let job = Job::load(&job, None)?;
            let engine = engine(cli.backend.as_deref())?;
            let (mesh, job) = engine.load_mesh_for(&job)?;
            let size = size.map(|s| [s[0], s[1]]);
            let x =
                decalbake::output::extract::extract(&engine, &mesh, &job, layer, (size, matte))?;
            decalbake::io::image::write_atomic(&out, &x.image.encode_png(16))?;
            eprintln!(
                "{} of {} pixels covered{}",
                x.covered,
                x.image.pixels.len(),
                x.matte.map_or(String::new(), |m| format!(
                    "; matte: {} unknowns, {} border colours, CG {} iterations, residual {:.1e}",
                    m.unknowns, m.border_colors, m.solve.iterations, m.solve.residual
                ))
            );
            println!("{}", out.display());
            Ok(())
        }
        Cmd::Bench(args) => bench_cmd(cli.backend.as_deref(), args),
        Cmd::Schema { which, out, fields } => {
            use decalbake::io::schema::{fields_markdown, schema_text, Which};
            let which = Which::parse(&which).context("clap checks the schema's name")?;
            if fields && which != Which::Job {
                anyhow::bail!(decalbake::Error::Job {
                    path: PathBuf::from("decalbake schema"),
                    field: "--fields".into(),
                    detail: "lists a job file's fields: use `decalbake schema job --fields`".into(),
                });
            }
            let text = if fields {
                fields_markdown()
            } else {
                schema_text(which)
            };
            match out {
                Some(path) => decalbake::io::image::write_atomic(&path, text.as_bytes())?,
                None => print!("{text}"),
            }
            Ok(())
        }
    }
}

/// `decalbake bench --channels`, `--vector` or `--edit` (`which`): what a layer's channels or
/// vector images cost on `mesh` (default the bundled bob) against the same bake without them, or
/// an edit of a live bake against a full bake.
fn layer_bench(
    engine: &Engine,
    which: &str,
    mesh: Option<PathBuf>,
    (sizes, decals, reps): (Vec<u32>, &[usize], usize),
    (adaptive, method): (bool, &str),
) -> Result<()> {
    let mesh = mesh.unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/bob.glb"));
    if which == "edit" {
        let opts = bench::edit::EditBenchOptions {
            mesh,
            sizes,
            decals: decals.iter().copied().max().unwrap_or(256),
            reps,
        };
        return bench::edit::run(engine, &opts, |v| println!("{v}"));
    }
    if which == "vector" {
        let opts = bench::vector::VectorBenchOptions {
            mesh,
            sizes,
            // The default `--decals` list is the bake bench's; this one's default is 64.
            decals: match decals {
                [1, 16, 256] | [] => 64,
                d => d[0],
            },
            reps,
            method: method.to_string(),
        };
        return bench::vector::run(engine, &opts, |v| println!("{v}"));
    }
    let opts = bench::channels::ChannelBenchOptions {
        mesh,
        sizes,
        decals: decals.iter().copied().max().unwrap_or(256),
        reps,
        adaptive,
    };
    let table = |l: &str| eprintln!("{l}");
    bench::channels::run(engine, &opts, |v| println!("{v}"), table)
}

/// `decalbake bench`: the benchmark its flags pick, JSON lines on stdout.
fn bench_cmd(backend: Option<&str>, args: BenchArgs) -> Result<()> {
    let BenchArgs {
        mesh,
        subdivide,
        sizes,
        decals,
        reps,
        cpu_budget,
        method,
        geodesic,
        fast,
        batch,
        linalg,
        scale,
        strokes,
        stamps,
        device,
        peers,
        charts,
        batch_bake,
        unwrap,
        gpu_max_triangles,
        soak,
        tiles,
        ribbons,
        corpus,
        channels,
        vector,
        edit,
        sampling,
    } = args;
    let adaptive = sampling == "adaptive";
    let mut engine = engine(backend)?;
    if channels || vector || edit {
        let which = match (vector, edit) {
            (true, _) => "vector",
            (_, true) => "edit",
            _ => "channels",
        };
        return layer_bench(
            &engine,
            which,
            mesh,
            (sizes, &decals, reps),
            (adaptive, &method),
        );
    }
    if let Some(dir) = corpus {
        return bench::corpus::run(&engine, &dir, |v| println!("{v}"));
    }
    if ribbons {
        return bench::ribbons::run(
            &engine,
            ribbon_meshes(mesh, subdivide)?,
            stamps,
            reps,
            peers.as_deref(),
            |v| println!("{v}"),
        );
    }
    if tiles {
        let mesh =
            mesh.unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/bob.glb"));
        let n = decals.first().copied().unwrap_or(16);
        return bench::tiles::run(&engine, &mesh, &sizes, n, reps, |v| println!("{v}"));
    }
    if let Some(bakes) = soak {
        let mesh =
            mesh.unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/spot.glb"));
        return bench::soak::run(&engine, &mesh, bakes, |v| println!("{v}"));
    }
    if unwrap {
        let opts = bench::unwrap::UnwrapBenchOptions {
            mesh,
            peers,
            gpu_max_triangles,
            subdivide,
        };
        return bench::unwrap::run(&engine, &opts, |v| println!("{v}"));
    }
    if batch_bake {
        let count = decals.first().copied().unwrap_or(40);
        let devices = batch::Devices::new(engine, backend);
        return bench::batch::run(&devices, count, &sizes, |v| println!("{v}"));
    }
    if strokes {
        let opts = bench::strokes::StrokeBenchOptions {
            mesh,
            subdivide: if subdivide == 0 { 2 } else { subdivide },
            side: sizes.first().copied().unwrap_or(2048),
            stamps,
            reps,
            cpu_budget,
        };
        bench::strokes::run(&mut engine, &opts, |v| println!("{v}"))?;
        return Ok(());
    }
    if device {
        bench::device::run(&engine, |v| println!("{v}"))?;
        return Ok(());
    }
    if scale {
        let meshes = match mesh {
            Some(m) => vec![m],
            None => bench::scale::default_meshes(Path::new(bench::common::SHARED_MESHES)),
        };
        bench::scale::run(&engine, &meshes, |v| println!("{v}"))?;
        return Ok(());
    }
    if linalg {
        let opts = bench::linalg::LinalgOptions {
            mesh,
            subdivide: if subdivide == 0 { 3 } else { subdivide },
            batch: batch.unwrap_or(1024),
            reps,
            peers,
            charts,
        };
        bench::linalg::run(&engine, &opts, |v| println!("{v}"))?;
        return Ok(());
    }
    let opts = bench::bake::BenchOptions {
        mesh,
        subdivide,
        sizes,
        decals,
        reps,
        cpu_budget,
        method,
        accuracy: if fast {
            decalbake::maps::expmap::Accuracy::Fast
        } else {
            decalbake::maps::expmap::Accuracy::Smooth
        },
        peers: peers.clone(),
        adaptive,
    };
    if geodesic {
        if let Some(dir) = &opts.peers {
            bench::geodesic::run_sphere_accuracy(&engine, dir, |v| println!("{v}"))?;
        }
        bench::geodesic::run_geodesic(&engine, &opts, batch.unwrap_or(256), |v| println!("{v}"))?;
    } else {
        bench::bake::run(&mut engine, &opts, |v| println!("{v}"))?;
    }
    Ok(())
}

/// `decalbake bench --ribbons`'s meshes: `mesh` subdivided `subdivide` times, or the bundled bob
/// and the shared bunny (when `../shared/data/meshes` has it) subdivided twice.
fn ribbon_meshes(mesh: Option<PathBuf>, subdivide: u32) -> Result<Vec<(String, Mesh, u32)>> {
    if let Some(p) = mesh {
        return Ok(vec![(p.display().to_string(), Mesh::load(&p)?, subdivide)]);
    }
    let bob = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/bob.glb");
    let mut out = vec![("bob".to_string(), Mesh::load(&bob)?, 2)];
    let bunny = Path::new(bench::common::SHARED_MESHES).join("stanford_bunny.glb");
    match bunny.exists() {
        true => out.push(("stanford_bunny".into(), Mesh::load(&bunny)?, 2)),
        false => eprintln!("{} not found: bob only", bunny.display()),
    }
    Ok(out)
}

/// `decalbake batch`: bake a manifest (`opts`), or join shard summaries into `summary`; exits
/// with the batch's code (3: some job failed).
fn batch_cmd(
    backend: Option<&str>,
    opts: Option<batch::BatchOptions>,
    merge: &[PathBuf],
    summary: Option<PathBuf>,
) -> Result<()> {
    let code = if !merge.is_empty() {
        let Some(summary) = summary else {
            anyhow::bail!(bad_usage("--merge-summaries needs --summary OUT.json"));
        };
        batch::merge(merge, &summary)?
    } else {
        let Some(opts) = opts else {
            anyhow::bail!(bad_usage("give a manifest (or --merge-summaries)"));
        };
        // A manifest that cannot be opened fails before a device is made (exit 2).
        if let Err(source) = std::fs::File::open(&opts.manifest) {
            anyhow::bail!(decalbake::Error::Io {
                path: opts.manifest.clone(),
                action: "reading the manifest",
                source,
            });
        }
        batch::run(&batch::Devices::new(engine(backend)?, backend), &opts)?
    };
    if code != 0 {
        std::process::exit(code);
    }
    Ok(())
}

/// A usage mistake, reported as an input error (exit 2).
fn bad_usage(msg: &str) -> decalbake::Error {
    decalbake::Error::Job {
        path: PathBuf::from("decalbake batch"),
        field: "options".into(),
        detail: msg.into(),
    }
}

/// A headless engine, its adapter named on stderr.
fn engine(backend: Option<&str>) -> Result<Engine> {
    let engine = Engine::new(backend)?;
    eprintln!("adapter: {}", engine.ctx.adapter);
    Ok(engine)
}

fn bake(engine: &Engine, job: &Job) -> Result<()> {
    use decalbake::output::UvBake;
    if !job.uv_list.is_empty() {
        // One bake per set on the same loaded mesh (`decalbake unwrap --patch`: pelt and patch),
        // every set baked before any file is written, as `decalbake batch` does; a UV set on
        // which the mesh has several texture sets bakes a texture per texture set, as a job of
        // that UV set alone does.
        let (mesh, _) = engine.load_mesh_for(job)?;
        let mut baked = Vec::new();
        for &set in &job.uv_list {
            let j = job.for_uv_set(set);
            let sets = mesh.mesh.texture_sets(set);
            baked.push(match sets.len() > 1 {
                true => UvBake::Sets(j.clone(), engine.bake_texture_sets(&mesh, &j, sets)?),
                false => {
                    let j = named_for_one_set(&mesh, j);
                    UvBake::One(j.clone(), Box::new(engine.bake(&mesh, &j)?))
                }
            });
        }
        let preview = job.out_preview.as_deref();
        for (report, files) in decalbake::output::write_uv_bakes(engine, &mesh, baked, preview)? {
            print_bake(&report, files);
        }
        return Ok(());
    }
    // The pipelines the job runs are built on the other cores while the mesh loads.
    let (mesh, job) = std::thread::scope(|s| {
        s.spawn(|| engine.prepare_for(job));
        engine.load_mesh_for(job)
    })?;
    if let Some(frames) = job.frames() {
        return bake_frames(engine, &mesh, &job, frames);
    }
    // One texture per texture set (material image or material) of the baked UV set.
    let sets = mesh.mesh.texture_sets(job.uv_set);
    if sets.len() > 1 {
        let mut bakes = engine.bake_texture_sets(&mesh, &job, sets)?;
        let files = decalbake::output::write_set_outputs(engine, &mesh, &job, &mut bakes)?;
        print_bake(&bakes[0].baked.report, files);
        return Ok(());
    }
    let mut job = named_for_one_set(&mesh, job);
    if let Some(set) = sets.first() {
        (job.width, job.height) = decalbake::bake::sets::set_size(&job, &mesh.mesh, set);
    }
    let (report, files) = decalbake::output::bake_and_write(engine, &mesh, &job, &|_| {}, &|_| {})?;
    print_bake(&report, files);
    Ok(())
}

/// `job` with `{set}` and `{channel}` in its texture's name resolved for the first texture set of
/// its UV set on `mesh` (`Job::for_single_set`): the colour's file, and the name the channels'
/// files are made from.
fn named_for_one_set(mesh: &decalbake::LoadedMesh, job: Job) -> Job {
    let sets = mesh.mesh.texture_sets(job.uv_set);
    job.for_single_set(sets.first().map_or("default", |s| s.name.as_str()))
}

/// An animated job: one bake and one set of outputs per frame, written as each frame is baked
/// (holding every frame's texture would cost frames × the texture); a frame that fails removes
/// the frames written before it and the folders it made (`batch::Undo`), so a failed job leaves no outputs.
fn bake_frames(
    engine: &Engine,
    mesh: &decalbake::LoadedMesh,
    job: &Job,
    frames: u32,
) -> Result<()> {
    // On a mesh of several texture sets, each frame bakes a texture per set, as an unanimated
    // job does.
    let sets = mesh.mesh.texture_sets(job.uv_set);
    let first = sets.first().map_or("default", |s| s.name.as_str());
    let jobs: Vec<Job> = (0..frames)
        .map(|f| match sets.len() > 1 {
            true => job.for_frame(f),
            false => job.for_frame(f).for_single_set(first),
        })
        .collect();
    let outputs: Vec<PathBuf> = jobs
        .iter()
        .flat_map(|j| [&j.out_texture, &j.out_glb, &j.out_report, &j.out_preview])
        .flatten()
        .cloned()
        .collect();
    let mut undo = batch::Undo::default();
    let write = |undo: &mut batch::Undo| -> Result<()> {
        undo.prepare(&jobs, &outputs)?;
        for j in &jobs {
            let files = match sets.len() > 1 {
                true => {
                    let mut bakes = engine.bake_texture_sets(mesh, j, sets.clone())?;
                    decalbake::output::write_set_outputs(engine, mesh, j, &mut bakes)?
                }
                false => decalbake::output::bake_and_write(engine, mesh, j, &|_| {}, &|_| {})?.1,
            };
            undo.files.extend(files);
        }
        Ok(())
    };
    if let Err(e) = write(&mut undo) {
        undo.undo();
        return Err(e);
    }
    for p in &undo.files {
        println!("{}", p.display());
    }
    Ok(())
}

/// What a bake prints: each layer's coverage and the warnings on stderr, the files on stdout.
fn print_bake(r: &decalbake::bake::report::Report, files: Vec<PathBuf>) {
    for l in &r.layers {
        eprintln!(
            "layer {}: {} triangles, {} texels, placed at {:?} (moved {:.4})",
            l.index, l.triangles_covered, l.texels_covered, l.placement.point, l.distance_moved
        );
    }
    for w in &r.warnings {
        eprintln!("warning: {w}");
    }
    for f in files {
        println!("{}", f.display());
    }
}

/// The demo's animated ribbon (`frames.json`: 8 textures) and the badge extracted from the baked
/// texture along its map (`extracted_badge.png`, what `decalbake extract` writes).
fn demo_ribbon_extras(engine: &Engine, out: &Path, job_path: &Path) -> Result<()> {
    let frames = out.join("frames.json");
    decalbake::io::image::write_atomic(&frames, demo::frames_json().as_bytes())?;
    bake(engine, &Job::load(&frames, None)?)?;
    let mut job = Job::load(job_path, None)?;
    job.base = decalbake::io::job::Base::Image(out.join("baked.png"));
    let (mesh, job) = engine.load_mesh_for(&job)?;
    let x = decalbake::output::extract::extract(engine, &mesh, &job, 0, (None, false))?;
    let patch = out.join("extracted_badge.png");
    decalbake::io::image::write_atomic(&patch, &x.image.encode_png(8))?;
    println!("{}", patch.display());
    Ok(())
}

/// Names a demo step on stderr as it starts and says how long it took when the next starts
/// (every step of more than a moment shows it is running).
struct Steps(Option<(String, std::time::Instant)>);

impl Steps {
    fn start(&mut self, name: &str) {
        self.done();
        eprintln!("demo: {name}...");
        self.0 = Some((name.to_string(), std::time::Instant::now()));
    }

    fn done(&mut self) {
        if let Some((name, t)) = self.0.take() {
            eprintln!("demo: {name}: {:.1} s", t.elapsed().as_secs_f64());
        }
    }
}

fn demo(out: &Path, all: bool, backend: Option<&str>) -> Result<()> {
    let mut steps = Steps(None);
    steps.start("writing the scene");
    std::fs::create_dir_all(out.join("decals"))
        .with_context(|| format!("creating {}", out.display()))?;
    decalbake::io::image::write_atomic(&out.join("spot.glb"), demo::SPOT_GLB)?;
    for (name, img) in demo::decals() {
        decalbake::io::image::write_atomic(&out.join("decals").join(name), &img.encode_png(8))?;
    }
    let logo = out.join("decals").join("logo.svg");
    decalbake::io::image::write_atomic(&logo, demo::LOGO_SVG.as_bytes())?;
    let job_path = out.join("job.json");
    decalbake::io::image::write_atomic(&job_path, demo::job_json().as_bytes())?;
    // The schema beside the job, which names it in `$schema`: editors check and complete it.
    let schema = decalbake::io::schema::schema_text(decalbake::io::schema::Which::Job);
    decalbake::io::image::write_atomic(&out.join("job.schema.json"), schema.as_bytes())?;
    let job = Job::load(&job_path, None)?;
    steps.start("starting the GPU");
    let engine = engine(backend)?;
    steps.start("baking Spot's decals, stroke and ribbon");
    bake(&engine, &job)?;
    // The same texture as linear 32-bit floats (OpenEXR, padded like the PNG).
    steps.start("baking the same as linear floats (baked.exr)");
    let mut exr = job.clone();
    exr.out_texture = Some(out.join("baked.exr"));
    (exr.out_glb, exr.out_report, exr.out_preview) = (None, None, None);
    bake(&engine, &exr)?;
    steps.start("animating the ribbon and extracting the badge");
    demo_ribbon_extras(&engine, out, &job_path)?;
    // A skinned, animated character: the model goes out with its skin and animations.
    steps.start("baking the knight's badge (colour, normal, roughness, metallic) and shield (two texture sets)");
    decalbake::io::image::write_atomic(&out.join("knight.glb"), demo::KNIGHT_GLB)?;
    let knight = out.join("knight.json");
    decalbake::io::image::write_atomic(&knight, demo::knight_json().as_bytes())?;
    bake(&engine, &Job::load(&knight, None)?)?;
    steps.start("unwrapping the crumpled sheet");
    let args = demo_sheet_unwrap(out)?;
    unwrap::run_with(&args, &engine)?;
    if all {
        demo_unwraps(&engine, out, args, &mut steps)?;
    }
    steps.done();
    eprintln!(
        "demo written to {} (edit job.json and run `decalbake bake {}` to re-bake; `decalbake unwrap` made unwrapped.glb{})",
        out.display(),
        job_path.display(),
        if all {
            ", spot-unwrapped.glb, bob-unwrapped.glb and bob-patched.glb"
        } else {
            "; `decalbake demo --all` also unwraps Spot and bob"
        }
    );
    Ok(())
}

/// The crumpled sheet written stood up (it lies in the xz plane, so the preview's side views see
/// its face) and the arguments that unwrap it: a new UV set by pelting, which refines to its
/// isometric flattening.
fn demo_sheet_unwrap(out: &Path) -> Result<unwrap::UnwrapArgs> {
    let sheet = out.join("crumpled.glb");
    let mut m = decalbake::mesh::Mesh::from_bytes(demo::CRUMPLED_GLB, &sheet, None)?;
    for p in m.positions.iter_mut().chain(m.normals.iter_mut()) {
        *p = glam::Vec3::new(p.x, -p.z, p.y);
    }
    // Turned in memory: a model of its own, not the bundled document.
    m.document = None;
    let written = decalbake::output::gltf::write_model(&m, &[], &sheet)?;
    decalbake::io::image::write_atomic(&sheet, &written.files[0].1)?;
    Ok(unwrap::UnwrapArgs {
        mesh: sheet,
        out: out.join("unwrapped.glb"),
        cut: "auto".into(),
        frame: unwrap::FrameArg::Circle,
        refine: unwrap::RefineArg::Conformal,
        patch: false,
        split_non_manifold: false,
        uv_set: None,
        force: false,
        size: 1024,
        margin: 4,
        report: Some(out.join("unwrap-report.json")),
        preview: Some(out.join("unwrap-preview.png")),
        cpu: false,
        gpu: false,
        no_pack_splits: false,
    })
}

/// `decalbake demo --all`: Spot and bob unwrapped, and bob's three sets baked.
fn demo_unwraps(
    engine: &Engine,
    out: &Path,
    args: unwrap::UnwrapArgs,
    steps: &mut Steps,
) -> Result<()> {
    // Spot itself, cut automatically (through its tips, along hidden and creased edges), pelted,
    // refined, split where it folds and packed.
    steps.start("unwrapping Spot");
    let spot = unwrap::UnwrapArgs {
        mesh: out.join("spot.glb"),
        out: out.join("spot-unwrapped.glb"),
        report: Some(out.join("spot-unwrap-report.json")),
        preview: Some(out.join("spot-unwrap-preview.png")),
        ..args
    };
    unwrap::run_with(&spot, engine)?;
    // bob has a handle: `--patch` cuts the band round its seams across and bridges the cuts with
    // a third set; two decals baked into the three sets over the crossings, previewed blended.
    decalbake::io::image::write_atomic(&out.join("bob.glb"), demo::BOB_GLB)?;
    // bob without the patch first: its long body is split in two so the packing fills the
    // texture (`pelt::repack`).
    steps.start("unwrapping bob");
    let bob_plain = unwrap::UnwrapArgs {
        mesh: out.join("bob.glb"),
        out: out.join("bob-unwrapped.glb"),
        report: Some(out.join("bob-unwrap-report.json")),
        preview: Some(out.join("bob-unwrap-preview.png")),
        ..spot
    };
    unwrap::run_with(&bob_plain, engine)?;
    steps.start("unwrapping bob with a patch over its seams");
    let bob = unwrap::UnwrapArgs {
        out: out.join("bob-patched.glb"),
        patch: true,
        report: Some(out.join("bob-patch-report.json")),
        preview: None,
        ..bob_plain
    };
    unwrap::run_with(&bob, engine)?;
    steps.start("baking bob's three sets");
    let bob_job = out.join("bob-job.json");
    decalbake::io::image::write_atomic(&bob_job, demo::bob_job_json().as_bytes())?;
    bake(engine, &Job::load(&bob_job, None)?)?;
    Ok(())
}

/// `--max-memory`: a size in bytes, with or without a unit.
fn memory_size(text: &str) -> std::result::Result<u64, String> {
    decalbake::io::job::parse_size(text).ok_or_else(|| {
        format!(
            "\"{text}\" is not a size: give bytes, or a number with a unit (\"512MiB\", \"2GB\")"
        )
    })
}

/// The lower of a job's memory limit and the command line's.
pub(crate) fn lower_limit(job: Option<u64>, cli: Option<u64>) -> Option<u64> {
    match (job, cli) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
}

/// `decalbake param`: a layer's local coordinates per reached vertex, as CSV.
fn param(backend: Option<&str>, job: &Path, layer: usize, out: &Path) -> Result<()> {
    let job = Job::load(job, None)?;
    let engine = engine(backend)?;
    let mesh = engine.load_mesh(&job.mesh)?;
    let (rows, footprint) = engine.layer_param_footprint(&mesh, &job, layer)?;
    if let Some(d) = footprint {
        // The counts the bake's report gives the layer (`footprint_*`).
        eprintln!(
            "footprint: {} flipped, {} collapsed, {} torn",
            d.flipped, d.collapsed, d.torn
        );
        if d.folds() > 0 {
            eprintln!("warning: layer {layer}: its map folds where it is drawn; make the decal smaller, move it off the tip or saddle, or try another `method`");
        }
    }
    let mut csv = String::from("x,y,z,distance,u,v\n");
    for r in &rows {
        let d = r.distance.map(|d| d.to_string()).unwrap_or_default();
        csv.push_str(&format!(
            "{},{},{},{d},{},{}\n",
            r.position[0], r.position[1], r.position[2], r.uv[0], r.uv[1]
        ));
    }
    decalbake::io::image::write_atomic(out, csv.as_bytes())?;
    eprintln!("{} vertices written to {}", rows.len(), out.display());
    Ok(())
}

fn info(path: &Path) -> Result<()> {
    let t = std::time::Instant::now();
    let mesh = decalbake::mesh::Mesh::load(path)?;
    let topo = decalbake::mesh::Topology::build(&mesh, decalbake::mesh::DEFAULT_WELD_TOLERANCE);
    let stats = decalbake::LoadedMesh::stats_of(&mesh, &topo);
    println!("{}", serde_json::to_string_pretty(&stats)?);
    eprintln!("({:.1} ms)", t.elapsed().as_secs_f64() * 1000.0);
    Ok(())
}
