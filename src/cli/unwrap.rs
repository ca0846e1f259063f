// SPDX-License-Identifier: MIT OR Apache-2.0
//! `decalbake unwrap`: a copy of the model with a new UV set made by pelting (`decalbake::pelt`),
//! its report, and a preview of the model wearing a checker on the new UVs.

use anyhow::{Context, Result};
use decalbake::mesh::{Mesh, Topology, DEFAULT_WELD_TOLERANCE};
use decalbake::pelt::{self, CutSpec, Device, Frame, Options};
use decalbake::{Engine, Error};
use std::path::{Path, PathBuf};

/// The command's arguments.
#[derive(clap::Args)]
pub struct UnwrapArgs {
    /// The model (.gltf or .glb).
    pub mesh: PathBuf,
    /// The copy with the new UV set (.glb).
    #[arg(long)]
    pub out: PathBuf,
    /// The cut: `auto` (through the model's tips, opening handles and joining holes), `seams`
    /// (the model's UV seams on its base-colour set), or a JSON file: {"edges": [[a, b], ...]}
    /// (welded vertex ids) or {"polylines": [[[x, y, z], ...], ...]} (points on the surface,
    /// joined along the edges).
    #[arg(long, default_value = "auto")]
    pub cut: String,
    /// The frame the pelts are stretched on.
    #[arg(long, value_enum, default_value = "circle")]
    pub frame: FrameArg,
    /// What follows the pelting: a least-squares conformal map from each pelt, kept where it does
    /// not fold (conformal), or nothing (none: the pelts as the dynamics left them).
    #[arg(long, value_enum, default_value = "conformal")]
    pub refine: RefineArg,
    /// Which TEXCOORD_n to write (default: the next free set).
    #[arg(long)]
    pub uv_set: Option<usize>,
    /// Allow `--uv-set` to replace a set the model has.
    #[arg(long)]
    pub force: bool,
    /// Texture side the packing margin is measured in.
    #[arg(long, default_value_t = 1024)]
    pub size: u32,
    /// Margin round each pelt, in texels.
    #[arg(long, default_value_t = 4)]
    pub margin: u32,
    /// Write the report (JSON) here.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Write a preview (the model wearing a checker on the new UVs) here.
    #[arg(long)]
    pub preview: Option<PathBuf>,
    /// Also write the patch (Piponi & Borshukov §5): the band within 4 edges of the seams pelted on
    /// its own into the next UV set, and the blend function as the vertex attribute `_PELT_BLEND`
    /// (the pelt's weight: 0 within 2 edges of the seams, 1 from 3 on). Turns the splits off. On a
    /// model with handles (seams with cycles) the band is cut across once per cycle and a third
    /// set, the bridges, hides those cuts, weighted by `_PELT_BRIDGE` (the patch's weight is
    /// 1 − `_PELT_BLEND` − `_PELT_BRIDGE`).
    #[arg(long)]
    pub patch: bool,
    /// Open non-manifold edges (each triangle fan round them ends there) instead of refusing them.
    #[arg(long)]
    pub split_non_manifold: bool,
    /// Run the dynamics on the CPU twin (no GPU device is made unless `--preview` needs one).
    /// Default: the twin on a CPU adapter such as lavapipe, where it is faster, else the GPU.
    #[arg(long)]
    pub cpu: bool,
    /// Run the dynamics on the GPU kernels even on a CPU adapter.
    #[arg(long, conflicts_with = "cpu")]
    pub gpu: bool,
    /// Keep elongated pelts whole even where the packing would use less than 45 % of the texture
    /// (by default the largest such pelt is split in two across its length: `pelt::repack`).
    #[arg(long)]
    pub no_pack_splits: bool,
}

/// `--refine`.
#[derive(Clone, Copy, clap::ValueEnum)]
pub enum RefineArg {
    /// The pelts as they are.
    None,
    /// LSCM from each pelt.
    Conformal,
}

/// `--frame`.
#[derive(Clone, Copy, clap::ValueEnum)]
pub enum FrameArg {
    /// A circle.
    Circle,
    /// A square.
    Square,
}

fn input(path: &Path, field: &str, detail: String) -> anyhow::Error {
    Error::Job {
        path: path.to_path_buf(),
        field: field.to_string(),
        detail,
    }
    .into()
}

/// Runs the command (`engine` is made only when needed: `--cpu` needs none unless a preview is
/// asked for, nor does the default where the adapter is a CPU, on which the CPU twin is the
/// faster path: the adapter's kind is asked without making a device). The adapter is asked, or
/// the engine made, on a thread of its own while the model loads.
pub fn run(
    args: &UnwrapArgs,
    backend: Option<&str>,
    engine: impl Fn() -> Result<Engine> + Sync,
) -> Result<()> {
    let needed = !(args.cpu && args.preview.is_none());
    let probe = !args.gpu && !args.cpu && args.preview.is_none();
    let make = || -> Result<Option<Engine>> {
        let on_cpu = Some(wgpu::DeviceType::Cpu);
        if probe && decalbake::gpu::GpuContext::adapter_type(backend) == on_cpu {
            return Ok(None);
        }
        engine().map(Some)
    };
    std::thread::scope(|scope| {
        let made = needed.then(|| scope.spawn(make));
        prepare(args, |args, mesh, topo, set, opts| {
            let engine = match made {
                Some(thread) => thread.join().unwrap_or_else(|_| make())?,
                None => None,
            };
            run_on(args, mesh, topo, set, opts, engine.as_ref())
        })
    })
}

/// Runs the command on an engine the caller has (the demo).
pub fn run_with(args: &UnwrapArgs, engine: &Engine) -> Result<()> {
    prepare(args, |args, mesh, topo, set, opts| {
        run_on(args, mesh, topo, set, opts, Some(engine))
    })
}

/// Loads and checks the model and the options, then hands them to `go`.
fn prepare(
    args: &UnwrapArgs,
    go: impl FnOnce(&UnwrapArgs, Mesh, &Topology, usize, Options) -> Result<()>,
) -> Result<()> {
    check_out(args)?;
    let mut mesh = Mesh::load(&args.mesh)?;
    let topo = Topology::build(&mesh, DEFAULT_WELD_TOLERANCE);
    topo.fill_normals(&mut mesh);
    let set = args.uv_set.unwrap_or(mesh.uv_sets.len());
    if set > mesh.uv_sets.len() {
        return Err(input(
            &args.mesh,
            "--uv-set",
            format!(
                "TEXCOORD_{set} would leave a gap: the model has {} UV sets, so the new one is TEXCOORD_{} (or replace one with --force)",
                mesh.uv_sets.len(),
                mesh.uv_sets.len()
            ),
        ));
    }
    if args.patch && set + 1 < mesh.uv_sets.len() && !args.force {
        return Err(input(
            &args.mesh,
            "--uv-set",
            format!(
                "--patch writes TEXCOORD_{} too, which the model has; add --force to replace it",
                set + 1
            ),
        ));
    }
    if set < mesh.uv_sets.len() && !args.force {
        return Err(input(
            &args.mesh,
            "--uv-set",
            format!(
                "the model already has TEXCOORD_{set}; add --force to replace it, or leave --uv-set out to write TEXCOORD_{}",
                mesh.uv_sets.len()
            ),
        ));
    }
    let opts = Options {
        cut: cut_spec(&args.cut, &mesh, &topo)?,
        frame: match args.frame {
            FrameArg::Circle => Frame::Circle,
            FrameArg::Square => Frame::Square,
        },
        size: args.size,
        margin: args.margin,
        split_non_manifold: args.split_non_manifold,
        pack_splits: !args.no_pack_splits,
        max_split_levels: if args.patch {
            0
        } else {
            pelt::MAX_SPLIT_LEVELS
        },
        refine: match args.refine {
            RefineArg::None => pelt::Refine::None,
            RefineArg::Conformal => pelt::Refine::Conformal,
        },
        ..Options::default()
    };
    go(args, mesh, &topo, set, opts)
}

/// The command once the model is loaded and checked, on `engine` (required for the GPU dynamics
/// and for the preview).
fn run_on(
    args: &UnwrapArgs,
    mesh: Mesh,
    topo: &Topology,
    set: usize,
    opts: Options,
    engine: Option<&Engine>,
) -> Result<()> {
    let device = match engine {
        Some(e) if args.gpu => Device::Gpu(&e.ctx, e.pipelines()),
        Some(e) if !args.cpu => e.pelt_device(),
        _ => Device::Cpu,
    };
    let un = pelt::unwrap(device, &mesh, topo, &opts, &args.mesh)?;
    let patch = if args.patch {
        Some(pelt::patch::patch(device, topo, &un, &opts, &args.mesh)?)
    } else {
        None
    };
    let bridges = patch.as_ref().and_then(|p| p.bridges.as_ref());
    let mut layouts = vec![(&un, set)];
    if let Some(p) = &patch {
        layouts.push((&p.layout, set + 1));
    }
    if let Some(b) = bridges {
        layouts.push((&b.layout, set + 2));
    }
    let (mut out_mesh, split_of) = pelt::apply_all(&mesh, &layouts);
    let per_split = |w: &[f32]| -> Vec<f32> {
        split_of
            .iter()
            .map(|&s| w[topo.welded_of[s as usize] as usize])
            .collect()
    };
    if let Some(p) = &patch {
        out_mesh.blend = per_split(&p.blend);
        out_mesh.bridge = bridges.map_or_else(Vec::new, |b| per_split(&b.weight));
    } else if set < mesh.uv_sets.len() && !(mesh.blend.is_empty() && mesh.bridge.is_empty()) {
        // The model's weights were made with the layouts of an earlier `--patch` run, and which
        // sets they pair is not recorded: a replaced set may be one of them, and a new pelt
        // blended with an old patch shows both. Appending a set leaves them valid.
        out_mesh.blend.clear();
        out_mesh.bridge.clear();
        eprintln!(
            "{}: TEXCOORD_{set} replaced, so the model's _PELT_BLEND and _PELT_BRIDGE weights (made for the old layouts) are left out; add --patch to make new ones",
            args.out.display()
        );
    }
    // The model as it came in, with the new sets (its own images, unchanged).
    let written = decalbake::output::gltf::write_model(&out_mesh, &[], &args.out)?;
    decalbake::output::write_files(&written.files)?;
    for w in &written.warnings {
        eprintln!("warning: {}: {w}", args.out.display());
    }
    let q = &un.report.quality;
    eprintln!(
        "{}: TEXCOORD_{set} from {} pelts ({} splits), {}, angle distortion mean {:.3} p95 {:.3}, {} flipped, {} overlaps, {:.0} % of the texture used, {:.0} ms",
        args.out.display(),
        un.report.pieces.len(),
        un.report.splits,
        match un.report.steps {
            0 => "refined from the Tutte start".to_string(),
            n => format!("{n} steps"),
        },
        q.angle_distortion.mean,
        q.angle_distortion.p95,
        q.flipped,
        q.overlaps,
        q.texel_utilisation * 100.0,
        un.report.ms.total()
    );
    if let Some(r) = &args.report {
        let mut v = serde_json::to_value(&un.report)?;
        v["uv_set"] = serde_json::json!(set);
        if let Some(p) = &patch {
            v["patch"] = layout_report(&p.layout, set + 1)?;
        }
        if let Some(b) = bridges {
            v["bridges"] = layout_report(&b.layout, set + 2)?;
            v["bridges"]["arcs"] = serde_json::json!(b.arc_count);
            v["bridges"]["arc_edges"] = serde_json::json!(b.arcs.len());
        }
        v["mesh"] = serde_json::json!(args.mesh);
        v["out"] = serde_json::json!(args.out);
        decalbake::io::image::write_atomic(r, serde_json::to_string_pretty(&v)?.as_bytes())?;
    }
    if let (Some(p), Some(engine)) = (&args.preview, engine) {
        preview(engine, out_mesh, set, p)?;
    }
    Ok(())
}

/// A second or third layout's report (the patch's, the bridges'): its set and triangles too.
fn layout_report(layout: &pelt::Unwrapped, set: usize) -> Result<serde_json::Value> {
    let mut r = serde_json::to_value(&layout.report)?;
    r["uv_set"] = serde_json::json!(set);
    let tris = layout.cut.triangle_piece.iter().flatten().count();
    r["triangles"] = serde_json::json!(tris);
    Ok(r)
}

/// Parses `--cut`.
fn cut_spec(arg: &str, mesh: &Mesh, topo: &Topology) -> Result<CutSpec> {
    match arg {
        "auto" => Ok(CutSpec::Auto),
        "seams" => Ok(CutSpec::Seams(
            mesh.material.as_ref().map_or(0, |m| m.base_color_uv_set),
        )),
        file => {
            let path = Path::new(file);
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("reading the cut file {}", path.display()))
                .map_err(|e| {
                    input(
                        path,
                        "--cut",
                        format!("{e:#}; --cut takes auto, seams or a JSON file"),
                    )
                })?;
            let v: serde_json::Value = serde_json::from_str(&text)
                .map_err(|e| input(path, "(file)", format!("not JSON: {e}")))?;
            cut_file(path, &v, topo)
        }
    }
}

/// A cut file: {"edges": [[a, b], ...]} or {"polylines": [[[x, y, z], ...], ...]}.
fn cut_file(path: &Path, v: &serde_json::Value, topo: &Topology) -> Result<CutSpec> {
    if let Some(edges) = v.get("edges") {
        let list: Vec<[u32; 2]> = serde_json::from_value(edges.clone()).map_err(|e| {
            input(
                path,
                "edges",
                format!("expected [[a, b], ...] of welded vertex ids: {e}"),
            )
        })?;
        return Ok(CutSpec::Edges(list));
    }
    if let Some(lines) = v.get("polylines") {
        let lines: Vec<Vec<[f32; 3]>> = serde_json::from_value(lines.clone()).map_err(|e| {
            input(
                path,
                "polylines",
                format!("expected [[[x, y, z], ...], ...]: {e}"),
            )
        })?;
        let mut edges = Vec::new();
        for (i, line) in lines.iter().enumerate() {
            if line.len() < 2 {
                return Err(input(
                    path,
                    &format!("polylines[{i}]"),
                    "a polyline needs at least two points".into(),
                ));
            }
            edges.extend(pelt::cut::polyline_edges(topo, line));
        }
        return Ok(CutSpec::Edges(edges));
    }
    Err(input(
        path,
        "(file)",
        "a cut file has `edges` ([[a, b], ...], welded vertex ids) or `polylines` ([[[x, y, z], ...], ...])".into(),
    ))
}

/// Renders `mesh` wearing a checker on UV set `set` into `path`.
fn preview(engine: &Engine, mesh: Mesh, set: usize, path: &Path) -> Result<()> {
    let side = 1024u32;
    let mut rgba8 = Vec::with_capacity((side * side * 4) as usize);
    for y in 0..side {
        for x in 0..side {
            let (cx, cy) = (x / 64, y / 64);
            let line = x % 64 == 0 || y % 64 == 0;
            let c = if line {
                [30, 30, 30]
            } else if (cx + cy) % 2 == 0 {
                [235, 235, 225]
            } else {
                // A hue per column, so mirrored or rotated pelts show.
                let h = cx as f32 / 16.0 * std::f32::consts::TAU;
                [
                    (120.0 + 100.0 * h.cos()) as u8,
                    (120.0 + 100.0 * (h + 2.1).cos()) as u8,
                    (120.0 + 100.0 * (h + 4.2).cos()) as u8,
                ]
            };
            rgba8.extend_from_slice(&[c[0], c[1], c[2], 255]);
        }
    }
    let loaded = engine.prepare(mesh)?;
    let tex = decalbake::output::preview::PreviewTexture {
        width: side,
        height: side,
        rgba8,
        uv_set: set,
        second: None,
        third: None,
        channels: Default::default(),
    };
    let px = decalbake::output::preview::render_texture_preview(engine, &loaded, &tex)?;
    let n = 2 * decalbake::output::preview::VIEW_SIDE;
    let samples: Vec<u16> = px.iter().map(|&b| b as u16).collect();
    decalbake::io::image::write_atomic(path, &decalbake::io::image::png_bytes(n, n, 8, &samples))?;
    Ok(())
}

/// The output must be a glTF: a `.glb`, or a `.gltf` (with its `.bin` and images beside it).
fn check_out(args: &UnwrapArgs) -> Result<()> {
    let ext = args.out.extension().and_then(|e| e.to_str());
    if !matches!(ext, Some("glb" | "gltf")) {
        return Err(input(
            &args.out,
            "--out",
            "the output is a glTF model: give it a .glb name (or .gltf for JSON with a .bin and image files beside it)".into(),
        ));
    }
    Ok(())
}
