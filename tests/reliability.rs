// SPDX-License-Identifier: MIT OR Apache-2.0
//! Reliability: a device destroyed from another thread in the middle of a bake gives
//! `Error::DeviceLost` (never a panic, never a wrong texture), a fresh engine bakes the same bytes
//! again; allocations beyond the adapter's limits are typed errors; one process baking many jobs
//! keeps its resident memory flat.

mod common;
use common::*;
use decalbake::{Error, Job};
use std::path::Path;
use std::time::{Duration, Instant};

/// Spot with 24 exponential-map decals at 512²: long enough on lavapipe (a few hundred ms warm)
/// for a destroy to land inside it.
fn heavy_job(dir: &Path) -> Job {
    let spot = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/spot.glb");
    std::fs::write(
        dir.join("img.png"),
        test_image(32, 32, 5, true).encode_png(8),
    )
    .unwrap();
    let layers = spot_ring("img.png", 0.25);
    let text = serde_json::json!({ "mesh": spot, "texture": { "width": 512, "height": 512 },
        "layers": layers, "output": { "texture": "out.png" } });
    Job::parse(&text.to_string(), &dir.join("job.json"), dir, dir).unwrap()
}

/// Bakes `job` on a fresh engine while another thread destroys its device `after` the bake
/// started (`None`: destroyed before it starts). Returns the result and whether the destroy came
/// before the bake returned.
fn bake_and_destroy(
    job: &Job,
    after: Option<Duration>,
) -> (decalbake::Result<decalbake::Baked>, bool) {
    let engine = engine();
    let mesh = engine.load_mesh(&job.mesh).unwrap();
    // Warm the pipelines and the mesh's caches, so the destroy lands in the bake's own work.
    engine.bake(&mesh, job).unwrap();
    let (out, destroyed_at) = match after {
        None => {
            engine.ctx.device.destroy();
            (engine.bake(&mesh, job), true)
        }
        Some(after) => std::thread::scope(|s| {
            let killer = s.spawn(|| {
                std::thread::sleep(after);
                engine.ctx.device.destroy();
                Instant::now()
            });
            let out = engine.bake(&mesh, job);
            let returned = Instant::now();
            (out, killer.join().unwrap() < returned)
        }),
    };
    // Once lost, every later bake on the engine says so at once.
    assert!(engine.ctx.is_lost());
    assert!(matches!(
        engine.bake(&mesh, job),
        Err(Error::DeviceLost { .. })
    ));
    (out, destroyed_at)
}

#[test]
fn a_device_destroyed_mid_bake_gives_device_lost_and_a_fresh_engine_bakes_the_same_bytes() {
    let dir = scratch("device_loss");
    let job = heavy_job(&dir);
    let reference = {
        let engine = engine();
        let mesh = engine.load_mesh(&job.mesh).unwrap();
        engine.bake(&mesh, &job).unwrap();
        let t = Instant::now();
        let baked = engine.bake(&mesh, &job).unwrap();
        (baked, t.elapsed())
    };
    let (reference, warm) = reference;
    println!("warm bake: {warm:?}");
    // A device destroyed before the bake: lost, whatever the machine's load.
    let (out, _) = bake_and_destroy(&job, None);
    assert!(
        matches!(out, Err(Error::DeviceLost { .. })),
        "a bake on a destroyed device must give DeviceLost"
    );
    // Destroyed while it runs, at fractions of a warm bake. On a loaded machine the destroying
    // thread may wake only after the bake returned (`destroyed_first` false): that bake had
    // nothing taken from it. A bake that returns Ok had read its texture back, so its bytes are
    // the reference's; one that fails says DeviceLost.
    let mut lost = 0;
    for frac in [0.0, 0.1, 0.5] {
        let (out, destroyed_first) = bake_and_destroy(&job, Some(warm.mul_f64(frac)));
        match out {
            Err(Error::DeviceLost { stage, detail }) => {
                lost += 1;
                println!("destroyed at {frac} of a bake: lost during {stage}: {detail}")
            }
            Err(e) => panic!("a destroyed device must give DeviceLost, got: {e}"),
            Ok(b) => {
                println!(
                    "destroyed at {frac} of a bake (before it returned: {destroyed_first}): Ok"
                );
                assert_eq!(b.texels, reference.texels, "a bake that survived differs");
            }
        }
    }
    assert!(
        lost > 0,
        "no bake was lost though a device was destroyed under each"
    );
    // A fresh engine after a loss bakes the very same bytes.
    let engine = engine();
    let mesh = engine.load_mesh(&job.mesh).unwrap();
    assert_eq!(engine.bake(&mesh, &job).unwrap().texels, reference.texels);
}

/// An engine on a device whose buffer limits are `binding` (storage binding) and `buffer` (any
/// buffer) bytes: the adapter's own limits, lowered.
fn tight_engine(binding: u64, buffer: u64) -> decalbake::Engine {
    common::engine_with_limits(|l| {
        l.max_storage_buffer_binding_size = binding;
        l.max_buffer_size = buffer;
    })
}

/// On a device whose buffers are smaller than the bake's budgets, the map stage works in smaller
/// chunks and bakes the same bytes; a texture beyond them goes by tiles; what cannot fit at all (a
/// tile the job asks for, the mesh's buffers) is a
/// typed error naming the field or the mesh, never a validation failure or an abort.
#[test]
fn allocations_beyond_the_device_limits_are_typed_errors() {
    let dir = scratch("tight_limits");
    let mut job = heavy_job(&dir);
    (job.width, job.height) = (128, 128);
    let reference = {
        let engine = engine();
        let mesh = engine.load_mesh(&job.mesh).unwrap();
        engine.bake(&mesh, &job).unwrap().texels
    };
    let bake = |binding: u64, buffer: u64, side: u32| {
        let engine = tight_engine(binding, buffer);
        let mut job = job.clone();
        (job.width, job.height) = (side, side);
        let r = engine
            .load_mesh(&job.mesh)
            .and_then(|mesh| engine.bake(&mesh, &job));
        println!(
            "binding {binding}, buffer {buffer}, {side}²: {:?}",
            r.as_ref().map(|_| ())
        );
        r
    };
    // 1 MiB buffers: Spot's 24 coordinate slots (92 KiB each, with their triangle lists) go in chunks of 14; same bytes.
    assert_eq!(bake(1 << 20, 2 << 20, 128).unwrap().texels, reference);
    // A 256² canvas plane (512 KiB) does not fit 256 KiB: the bake goes by bands of 128 rows by
    // itself (tests/tiles.rs checks the bytes), but tiles of 256 that the job asks for are refused.
    assert_eq!(
        bake(256 << 10, 1 << 20, 256).unwrap().report.tile_size,
        Some([256, 128])
    );
    let mut tiled = job.clone();
    tiled.tile = Some(256);
    (tiled.width, tiled.height) = (256, 256);
    let engine = tight_engine(256 << 10, 1 << 20);
    let mesh = engine.load_mesh(&tiled.mesh).unwrap();
    // Spot's edge records for the exponential maps (16 bytes an adjacency entry: 281 KB) do not
    // fit 256 KiB either: the bake above took its maps from the CPU twin instead of failing.
    assert!(!mesh.gpu.relax_edges_fit);
    match engine.bake(&mesh, &tiled) {
        Err(Error::Job { field, detail, .. }) => {
            assert_eq!(field, "texture.tile");
            assert!(detail.contains("512 KiB"), "{detail}");
        }
        other => panic!("expected a tile-size error, got {:?}", other.map(|_| ())),
    }
    // 64 KiB buffers: Spot's adjacency lists (128 KiB) do not fit: the mesh is named.
    match bake(64 << 10, 256 << 10, 64) {
        Err(e @ Error::DeviceLimit { .. }) => {
            let msg = e.to_string();
            assert!(msg.contains("spot.glb") && msg.contains("64 KiB"), "{msg}");
            assert!(e.is_input_error());
        }
        other => panic!("expected DeviceLimit, got {:?}", other.map(|_| ())),
    }
}

/// Resident memory of this process (Linux: `/proc/self/statm`), bytes.
fn rss() -> u64 {
    let statm = std::fs::read_to_string("/proc/self/statm").unwrap();
    let pages: u64 = statm.split_whitespace().nth(1).unwrap().parse().unwrap();
    pages * 4096
}

/// A soak: 300 bakes of four different jobs (decals by every method, a stroke, sizes 64² and
/// 128²) in one process on one engine and mesh. After 60 bakes of warm-up (pipelines compiled,
/// islands cached per size, the driver's pools grown) resident memory stays within 24 MiB: a leak
/// of one canvas (128² × 16 bytes = 256 KiB) per bake would add 60 MiB. `decalbake bench --soak`
/// runs the 1,000-bake version.
#[test]
fn many_bakes_in_one_process_keep_resident_memory_flat() {
    let dir = scratch("soak");
    let base = heavy_job(&dir);
    let engine = engine();
    let mesh = engine.load_mesh(&base.mesh).unwrap();
    let jobs: Vec<Job> = (0..4)
        .map(|k| {
            let mut j = base.clone();
            let side = [64, 128][k % 2];
            (j.width, j.height) = (side, side);
            j.layers.truncate(4 + 4 * k);
            j
        })
        .collect();
    let (warm, total) = (60, 300);
    let mut after_warm = 0;
    for i in 0..total {
        let baked = engine.bake(&mesh, &jobs[i % jobs.len()]).unwrap();
        assert!(baked.texels.iter().any(|&t| t > 0));
        if i + 1 == warm {
            after_warm = rss();
        }
    }
    let end = rss();
    let growth = end.saturating_sub(after_warm);
    println!(
        "rss after {warm} bakes: {} MiB, after {total}: {} MiB (+{} KiB)",
        after_warm >> 20,
        end >> 20,
        growth >> 10
    );
    assert!(
        growth < 24 << 20,
        "resident memory grew {} KiB over {} bakes after warm-up",
        growth >> 10,
        total - warm
    );
}

/// `bake_with_progress` names the stages in order, one message per chunk of the map stage (a
/// device with 1 MiB buffers splits Spot's 24 decals into chunks), and bakes the same bytes.
#[test]
fn a_bake_names_its_stages_as_it_goes() {
    let dir = scratch("stages");
    let mut job = heavy_job(&dir);
    (job.width, job.height) = (128, 128);
    let engine = tight_engine(1 << 20, 2 << 20);
    let mesh = engine.load_mesh(&job.mesh).unwrap();
    let seen = std::sync::Mutex::new(Vec::new());
    let baked = engine
        .bake_with_progress(&mesh, &job, &|s| seen.lock().unwrap().push(s.to_string()))
        .unwrap();
    let seen = seen.into_inner().unwrap();
    println!("{seen:#?}");
    assert_eq!(seen[..3], ["placement", "images", "canvas"]);
    assert_eq!(seen[seen.len() - 2..], ["padding and encode", "read-back"]);
    let chunks = &seen[3..seen.len() - 2];
    assert!(chunks.len() >= 2, "{chunks:?}");
    assert!(chunks[0].ends_with("units 1-14 of 24"), "{chunks:?}");
    assert!(chunks.last().unwrap().ends_with("of 24"));
    assert_eq!(engine.bake(&mesh, &job).unwrap().texels, baked.texels);
}

/// Layer images stay on the GPU between bakes (one upload for many jobs), and a file rewritten
/// between bakes (same path) is read again: the second bake shows the new image, the
/// bytes a fresh engine bakes. Keyed by path alone, the cache would bake the old image.
#[test]
fn images_are_kept_between_bakes_and_read_again_when_rewritten() {
    let dir = scratch("image_cache");
    let mut job = heavy_job(&dir);
    (job.width, job.height) = (128, 128);
    job.layers.truncate(3);
    let engine = engine();
    let mesh = engine.load_mesh(&job.mesh).unwrap();
    let first = engine.bake(&mesh, &job).unwrap();
    assert_eq!(engine.cached_images(), 1, "one image file, read once");
    assert_eq!(engine.bake(&mesh, &job).unwrap().texels, first.texels);
    assert_eq!(engine.cached_images(), 1);
    std::thread::sleep(Duration::from_millis(20));
    std::fs::write(
        dir.join("img.png"),
        test_image(32, 32, 77, true).encode_png(8),
    )
    .unwrap();
    let second = engine.bake(&mesh, &job).unwrap();
    assert_ne!(second.texels, first.texels, "the rewritten image is used");
    let fresh = {
        let engine = common::engine();
        let mesh = engine.load_mesh(&job.mesh).unwrap();
        engine.bake(&mesh, &job).unwrap()
    };
    assert_eq!(second.texels, fresh.texels);
    assert_eq!(engine.cached_images(), 1, "the old upload was replaced");
}

/// A one-decal job on Spot writing a texture and a report into `dir`.
fn small_cli_job(dir: &Path) -> std::path::PathBuf {
    let job = spot_job_json(
        dir,
        9,
        serde_json::json!([{ "image": "img.png", "at": [0.0, 0.3, 0.4], "size": [0.3, 0.3] }]),
        serde_json::json!({ "texture": "out.png", "report": "report.json" }),
    );
    let path = dir.join("job.json");
    std::fs::write(&path, job.to_string()).unwrap();
    path
}

/// Bakes `job` with the pipeline cache in `cache`: the report's `pipeline_cache`, its adapter and
/// the texture's bytes.
fn bake_cached(job: &Path, cache: &Path) -> (String, String, Vec<u8>) {
    let (code, _, err) = cli_env(
        &["bake", job.to_str().unwrap()],
        &[("DECALBAKE_CACHE_DIR", cache.to_str().unwrap())],
    );
    assert_eq!(code, 0, "{err}");
    let dir = job.parent().unwrap();
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("report.json")).unwrap()).unwrap();
    let state = report["pipeline_cache"].as_str().unwrap().to_string();
    let adapter = report["adapter"].as_str().unwrap().to_string();
    (state, adapter, std::fs::read(dir.join("out.png")).unwrap())
}

#[test]
fn the_pipeline_cache_is_saved_read_and_replaced_when_corrupt_without_changing_a_byte() {
    let dir = scratch("pipeline_cache");
    let cache = dir.join("cache");
    let job = small_cli_job(&dir);
    let (cold, adapter, first) = bake_cached(&job, &cache);
    if cold == "unsupported" {
        assert!(
            !adapter.contains("Vulkan"),
            "Vulkan keeps a pipeline cache: {adapter}"
        );
        return;
    }
    assert_eq!(cold, "cold");
    let files: Vec<_> = std::fs::read_dir(&cache).unwrap().flatten().collect();
    assert_eq!(files.len(), 1, "one file, no temporary left: {files:?}");
    let file = files[0].path();
    let saved = std::fs::read(&file).unwrap();
    assert!(saved.len() > 40, "the file holds data beyond its header");

    let (warm, _, second) = bake_cached(&job, &cache);
    assert_eq!(warm, "warm");
    assert!(first == second, "a warm cache changes no byte");

    // A truncated file, then one with a byte flipped: ignored, the bake unchanged, the file
    // replaced by a good one.
    for damage in [0, 1] {
        let mut bad = saved.clone();
        match damage {
            0 => bad.truncate(saved.len() / 2),
            _ => *bad.last_mut().unwrap() ^= 0x55,
        }
        std::fs::write(&file, &bad).unwrap();
        let (state, _, third) = bake_cached(&job, &cache);
        assert_eq!(state, "corrupt", "damage {damage}");
        assert!(first == third, "a corrupt cache changes no byte");
        assert_eq!(
            bake_cached(&job, &cache).0,
            "warm",
            "replaced after damage {damage}"
        );
    }

    let (code, _, err) = cli_env(
        &["bake", job.to_str().unwrap()],
        &[("DECALBAKE_CACHE_DIR", "off")],
    );
    assert_eq!(code, 0, "{err}");
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["pipeline_cache"], "off");
}

#[test]
fn a_bake_builds_only_the_pipelines_it_runs_and_preparing_them_changes_no_byte() {
    let dir = scratch("lazy_pipelines");
    let layers = serde_json::json!([{ "image": "img.png", "at": [0.0, 0.3, 0.4],
                                      "size": [0.3, 0.3], "method": "planar" }]);
    let text = spot_job_json(&dir, 3, layers, serde_json::json!({ "texture": "out.png" }));
    let job = Job::parse(&text.to_string(), &dir.join("job.json"), &dir, &dir).unwrap();

    let lazy = engine();
    let p = lazy.pipelines();
    assert_eq!(p.builder.spent().1, 0, "nothing is built before a bake");
    let mesh = lazy.load_mesh(&job.mesh).unwrap();
    let plain = lazy.bake(&mesh, &job).unwrap();
    let built = p.builder.spent().1;
    // A planar decal without a mask: the plain raster, not the general one.
    let raster = &p.grid.plain.raster;
    assert!(p.grid.compose.is_built() && raster.is_built() && p.planar_coords.is_built());
    assert!(!p.grid.raster.is_built(), "the general raster");
    assert!(!p.preview.is_built(), "no preview asked");
    assert!(
        !p.expmap_relax.is_built() && !p.cg_batched.is_built(),
        "no chart or map"
    );
    assert!(!p.ribbon_relax.is_built() && !p.pelt_step.is_built());
    assert!(built < 20, "{built} pipelines built for one planar decal");
    assert!(plain.report.timings.pipelines_ms > 0.0);

    // On a CPU adapter the texture is padded and encoded on the CPU: no encode kernel.
    let cpu_pads = lazy.ctx.device_type == Some(wgpu::DeviceType::Cpu);
    let encodes =
        |p: &decalbake::gpu::pipelines::Pipelines| p.encode.iter().filter(|e| e.is_built()).count();
    assert_eq!(
        plain.report.paths.padding,
        if cpu_pads { "cpu" } else { "gpu" }
    );
    assert_eq!(encodes(p), usize::from(!cpu_pads), "the 8-bit sRGB encode");

    let eager = engine();
    eager.prepare_for(&job);
    let q = eager.pipelines();
    assert!(q.grid.compose.is_built() && q.planar_coords.is_built());
    assert_eq!(encodes(q), usize::from(!cpu_pads), "the 8-bit sRGB encode");
    let mesh = eager.load_mesh(&job.mesh).unwrap();
    let prepared = eager.bake(&mesh, &job).unwrap();
    assert!(plain.texels == prepared.texels, "preparing changes no byte");
}

/// A material decal whose roughness and metallic are numbers at the layer's opacity and whose
/// normal is an image: the engine prepares the fused pipelines of the normal group alone (the
/// compose derives the constant group from the colour), and the bake builds no pipeline of those
/// families beyond them.
#[test]
fn preparing_a_material_bake_builds_the_fused_pipelines_it_draws() {
    let dir = scratch("lazy_fused");
    let layers = serde_json::json!([{ "image": "img.png", "at": [0.0, 0.3, 0.4],
        "size": [0.3, 0.3], "method": "planar", "normal": "img.png",
        "roughness": 0.4, "metallic": 1.0 }]);
    let text = spot_job_json(&dir, 3, layers, serde_json::json!({ "texture": "out.png" }));
    let job = Job::parse(&text.to_string(), &dir.join("job.json"), &dir, &dir).unwrap();
    let eager = engine();
    eager.prepare_for(&job);
    let q = eager.pipelines();
    let fused = &q.grid.fused;
    // Bits 0b010 (the normal group): index 1.
    // The compose made for the pass's groups: orm and normal present, the normal attached.
    let compose = fused.compose_for(0b011, 0b010);
    let raster = &q.grid.plain.fused[1];
    assert!(raster.is_built() && fused.clear[1].is_built() && compose.is_built());
    let mesh = eager.load_mesh(&job.mesh).unwrap();
    let baked = eager.bake(&mesh, &job).unwrap();
    assert_eq!(baked.report.paths.channels, "fused");
    assert_eq!(baked.channels.len(), 2, "orm and normal");
    let plain = &q.grid.plain.fused;
    for (k, (r, c)) in plain.iter().zip(&fused.clear).enumerate() {
        assert_eq!(r.is_built(), k == 1, "fused raster {}", k + 1);
        assert_eq!(c.is_built(), k == 1, "fused clear {}", k + 1);
    }
    assert!(
        fused.raster.iter().all(|r| !r.is_built()),
        "a general fused raster"
    );
    let built = fused.compose.iter().filter(|c| c.is_built()).count();
    assert_eq!(built, 1, "fused composes built");
}
