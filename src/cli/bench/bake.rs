// SPDX-License-Identifier: MIT OR Apache-2.0
//! `decalbake bench`: bake time per stage for N planar decals at several texture sizes, printed as one
//! JSON object per configuration, with the CPU twin (`bake::cpu::bake_cpu`) timed in the same run as the
//! baseline where it finishes in reasonable time.
//!
//! Decals are placed at deterministic pseudo-random surface points (area-weighted), each 8 % of the
//! bounding-box diagonal wide, with random angles and the blend modes in turn.

use super::common::{largest_uv_mesh, median, random_job, SHARED_MESHES};
use decalbake::bake::{Engine, LoadedMesh};
use decalbake::error::Result;
use decalbake::io::image::LinearImage;
use decalbake::io::job::Job;
use decalbake::mesh::Mesh;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Options of `decalbake bench`.
pub struct BenchOptions {
    /// Mesh file (default: the largest mesh with UVs in [`SHARED_MESHES`], else the bundled Spot).
    pub mesh: Option<PathBuf>,
    /// Midpoint subdivisions applied to the mesh first.
    pub subdivide: u32,
    /// Texture sides.
    pub sizes: Vec<u32>,
    /// Decal counts.
    pub decals: Vec<usize>,
    /// Repetitions (median reported).
    pub reps: usize,
    /// Largest `decals × side²` for which the CPU twin is timed too.
    pub cpu_budget: u64,
    /// Decal method of the bake benchmark's layers (`"planar"` by default; `"expmap"` measures the
    /// maps inside a bake).
    pub method: String,
    /// Exponential-map update rule (geodesic benchmark, and expmap layers of the bake benchmark).
    pub accuracy: decalbake::maps::expmap::Accuracy,
    /// Geodesic benchmark: `../shared/peers`, to time potpourri3d's log maps on the same meshes and
    /// seed vertices in the same run.
    pub peers: Option<PathBuf>,
    /// Bake with `texture.sampling` adaptive (four samples a pixel, once a texel and triangle).
    pub adaptive: bool,
}

/// Runs the benchmark, calling `emit` with one JSON object per configuration.
pub fn run(
    engine: &mut Engine,
    opts: &BenchOptions,
    mut emit: impl FnMut(serde_json::Value),
) -> Result<()> {
    let t = Instant::now();
    let path = opts
        .mesh
        .clone()
        .or_else(|| largest_uv_mesh(Path::new(SHARED_MESHES)));
    let mut mesh = match &path {
        Some(p) => Mesh::load(p)?,
        None => Mesh::from_bytes(crate::demo::SPOT_GLB, Path::new("spot.glb (bundled)"), None)?,
    };
    for _ in 0..opts.subdivide {
        mesh = mesh.subdivide();
    }
    let load_ms = t.elapsed().as_secs_f64() * 1000.0;
    let mut loaded = engine.prepare(mesh)?;
    let dir = std::env::temp_dir().join(format!("decalbake-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).map_err(|source| decalbake::Error::Io {
        path: dir.clone(),
        action: "creating",
        source,
    })?;
    for &side in &opts.sizes {
        for &n in &opts.decals {
            let mut job = random_job(&loaded, n, side, &dir, 7 + n as u32, &opts.method)?;
            job.adaptive = opts.adaptive;
            // Cold run: the first bake at a size rasterizes the islands and their distance transform
            // (then cached on the mesh) and compiles pipelines in the driver.
            let t_cold = Instant::now();
            engine.bake(&loaded, &job)?;
            let cold_ms = t_cold.elapsed().as_secs_f64() * 1000.0;
            let mut totals = Vec::new();
            let mut stages: Vec<decalbake::bake::report::Timings> = Vec::new();
            let mut last = None;
            for _ in 0..opts.reps.max(1) {
                let t = Instant::now();
                let baked = engine.bake(&loaded, &job)?;
                let te = Instant::now();
                let png = baked.to_png();
                let encode_png_ms = te.elapsed().as_secs_f64() * 1000.0;
                let total = t.elapsed().as_secs_f64() * 1000.0;
                totals.push(total);
                let mut tm = baked.report.timings.clone();
                tm.write_ms = encode_png_ms;
                stages.push(tm);
                let _ = png;
                last = Some(baked);
            }
            let baked = last.expect("at least one repetition");
            let texels: u64 = baked
                .report
                .layers
                .iter()
                .map(|l| l.texels_covered as u64)
                .sum();
            let med = |f: fn(&decalbake::bake::report::Timings) -> f64| {
                median(stages.iter().map(f).collect())
            };
            let compose = med(|t| t.compose_ms);
            let gpu_total = median(totals.clone());
            let brute_ms = brute_placement_ms(engine, &loaded, &job)?;
            // The placement BVH's build (part of the mesh's weld time), timed on its own.
            let t_bvh = Instant::now();
            let _ = decalbake::mesh::bvh::Bvh::build(&loaded.topo);
            let bvh_ms = t_bvh.elapsed().as_secs_f64() * 1000.0;
            let bvh = bvh_figures(engine, &mut loaded, &job)?;
            // The same bake with every layer selected over the whole mesh (no BVH candidates).
            engine.whole_mesh_selection = true;
            let whole = engine.bake(&loaded, &job);
            engine.whole_mesh_selection = false;
            let whole_compose_ms = whole?.report.timings.compose_ms;
            // The same bake drawing whole triangles (no clip to each layer's image and margin).
            engine.unclipped_raster = true;
            let unclipped = engine.bake(&loaded, &job);
            engine.unclipped_raster = false;
            let unclipped_compose_ms = unclipped?.report.timings.compose_ms;
            let (every_block_ms, block_mask_ms, every_block_identical) =
                block_mask_pairs(engine, &loaded, &job, opts.reps)?;
            let islands = islands_paths(engine, &loaded, side, opts.reps)?;
            let mut cpu_ms = None;
            if (n as u64) * (side as u64).pow(2) <= opts.cpu_budget {
                let topo = &loaded.topo;
                let images: Vec<(LinearImage, Option<LinearImage>)> = job
                    .layers
                    .iter()
                    .map(|l| LinearImage::load(&l.image).map(|i| (i, None)))
                    .collect::<Result<_>>()?;
                let placements: Vec<_> = baked.report.layers.iter().map(|l| l.placement).collect();
                let base = loaded
                    .mesh
                    .material
                    .as_ref()
                    .and_then(|m| m.base_color_texture.clone())
                    .unwrap_or_else(|| LinearImage::solid(1, 1, [0.5, 0.5, 0.5, 1.0]));
                let t = Instant::now();
                let _ = decalbake::bake::cpu::bake_cpu(
                    &loaded.mesh,
                    topo,
                    &job,
                    &placements,
                    &base,
                    &images,
                );
                cpu_ms = Some(t.elapsed().as_secs_f64() * 1000.0);
            }
            emit(serde_json::json!({
                "mesh": loaded.stats.source,
                "triangles": loaded.stats.triangles,
                "welded_vertices": loaded.stats.welded_vertices,
                "texture": side,
                "decals": n,
                "method": opts.method,
                "reps": opts.reps,
                "adapter": engine.ctx.adapter,
                "median_ms": {
                    "total": gpu_total,
                    "load": load_ms, "weld": loaded.timings.1, "upload": loaded.timings.2,
                    "images": med(|t| t.images_ms), "placement": med(|t| t.placement_ms),
                    "compose": compose, "padding": med(|t| t.padding_ms), "encode_readback": med(|t| t.encode_ms),
                    "png_encode": med(|t| t.write_ms),
                },
                "cold_total_ms": cold_ms,
                "placement_brute_ms": brute_ms,
                "bvh_build_ms": bvh_ms,
                "bvh_depth": loaded.bvh.depth,
                "bvh": bvh,
                "compose_whole_mesh_selection_ms": whole_compose_ms,
                "compose_unclipped_ms": unclipped_compose_ms,
                "compose_every_block_ms": every_block_ms,
                "compose_block_mask_paired_ms": block_mask_ms,
                "every_block_identical": every_block_identical,
                "islands_ms": islands,
                "texels_composed": texels,
                "composed_texels_per_s": texels as f64 / (compose / 1000.0),
                "gpu_commands": baked.report.gpu_commands,
                "sampling": baked.report.paths.sampling,
                "cpu_twin_compose_ms": cpu_ms,
                "cpu_twin_over_gpu_compose": cpu_ms.map(|c| c / compose),
                "png": png_figures(&baked, &dir)?,
            }));
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    Ok(())
}

/// The bake composing every texel of every raster rectangle (`Engine::skip_empty_blocks` off)
/// and the engine's, alternating, `reps` pairs in one run (this machine's speed drifts by more
/// than the difference): the medians of their compose stages, ms, and whether every pair gave the
/// same bytes.
fn block_mask_pairs(
    engine: &mut Engine,
    loaded: &decalbake::LoadedMesh,
    job: &decalbake::Job,
    reps: usize,
) -> Result<(f64, f64, bool)> {
    let mut pairs = (Vec::new(), Vec::new());
    let mut identical = true;
    for _ in 0..reps.max(1) {
        engine.skip_empty_blocks = false;
        let every = engine.bake(loaded, job);
        engine.skip_empty_blocks = true;
        let every = every?;
        let masked = engine.bake(loaded, job)?;
        identical &= every.texels == masked.texels;
        pairs.0.push(every.report.timings.compose_ms);
        pairs.1.push(masked.report.timings.compose_ms);
    }
    Ok((median(pairs.0), median(pairs.1), identical))
}

/// The islands of the mesh at `side`² (4 samples a texel) computed on a fresh copy of the mesh
/// (nothing cached) by each path of their distance transform, alternating, medians of `reps`,
/// ms: `Engine::island_maps`, so each figure also holds the read-back of the mask and the map
/// (the same for both), and whether the two maps were equal.
fn islands_paths(
    engine: &mut Engine,
    loaded: &decalbake::LoadedMesh,
    side: u32,
    reps: usize,
) -> Result<serde_json::Value> {
    let kept = engine.stage_paths.islands;
    let (mut gpu, mut cpu, mut same) = (Vec::new(), Vec::new(), true);
    for _ in 0..reps.max(1) {
        let mut maps = Vec::new();
        for (path, times) in [
            (decalbake::StagePath::Gpu, &mut gpu),
            (decalbake::StagePath::Cpu, &mut cpu),
        ] {
            engine.stage_paths.islands = path;
            let fresh = engine.prepare(loaded.mesh.clone());
            let t = Instant::now();
            let m = fresh.and_then(|f| engine.island_maps(&f, 0, [side, side], 4));
            times.push(t.elapsed().as_secs_f64() * 1000.0);
            match m {
                Ok(m) => maps.push(m),
                Err(e) => {
                    engine.stage_paths.islands = kept;
                    return Err(e);
                }
            }
        }
        same &= maps[0] == maps[1];
    }
    engine.stage_paths.islands = kept;
    Ok(serde_json::json!({
        "gpu": median(gpu),
        "cpu": median(cpu),
        "identical": same,
    }))
}

/// The PNG encode against a file copy of the same samples, in one run (medians of 3, interleaved):
/// the engine's encoding on every core and on one, the `png` crate's single-stream fast encoding
/// (the engine's before it deflated bands), and `std::fs::copy` of the raw 8-bit samples (written
/// to the scratch folder first, so the copy reads from the page cache), in ms and MB/s of raw
/// samples.
fn png_figures(baked: &decalbake::bake::Baked, dir: &Path) -> Result<serde_json::Value> {
    let (w, h, depth) = (baked.width, baked.height, baked.bit_depth);
    let raw: Vec<u8> = match depth {
        16 => baked.texels.iter().flat_map(|v| v.to_be_bytes()).collect(),
        _ => baked.texels.iter().map(|v| *v as u8).collect(),
    };
    let (src, dst) = (dir.join("raw.bin"), dir.join("raw-copy.bin"));
    let io = |path: &Path, source| decalbake::Error::Io {
        path: path.to_path_buf(),
        action: "writing",
        source,
    };
    std::fs::write(&src, &raw).map_err(|e| io(&src, e))?;
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().ok();
    let (mut cores, mut single, mut stream, mut copy) = (vec![], vec![], vec![], vec![]);
    let mut png_bytes = 0;
    let time = |f: &mut dyn FnMut() -> usize| {
        let t = Instant::now();
        let n = f();
        (t.elapsed().as_secs_f64() * 1000.0, n)
    };
    for _ in 0..3 {
        let (ms, n) = time(&mut || baked.to_png().len());
        cores.push(ms);
        png_bytes = n;
        if let Some(one) = &one {
            single.push(time(&mut || one.install(|| baked.to_png().len())).0);
        }
        stream.push(time(&mut || single_stream_png(w, h, depth, &baked.texels)).0);
        let (ms, _) = time(&mut || std::fs::copy(&src, &dst).map(|n| n as usize).unwrap_or(0));
        copy.push(ms);
    }
    let _ = (std::fs::remove_file(&src), std::fs::remove_file(&dst));
    let mb = raw.len() as f64 / 1e6;
    let single = (!single.is_empty()).then(|| median(single));
    let (cores, stream, copy) = (median(cores), median(stream), median(copy));
    Ok(serde_json::json!({
        "raw_mb": mb,
        "png_bytes": png_bytes,
        "threads": rayon::current_num_threads(),
        "encode_ms": cores,
        "encode_one_core_ms": single,
        "single_stream_ms": stream,
        "copy_ms": copy,
        "encode_mb_s": mb / (cores / 1000.0),
        "copy_mb_s": mb / (copy / 1000.0),
        "encode_over_copy": cores / copy,
    }))
}

/// The `png` crate's fast encoding of the raw samples in one deflate stream (adaptive filters,
/// `fdeflate`), the samples converted to bytes first as the engine's encoding converts them: the
/// bytes' length.
fn single_stream_png(width: u32, height: u32, depth: u8, texels: &[u16]) -> usize {
    let raw: Vec<u8> = match depth {
        16 => texels.iter().flat_map(|v| v.to_be_bytes()).collect(),
        _ => texels.iter().map(|v| *v as u8).collect(),
    };
    let mut out = Vec::new();
    let mut enc = png::Encoder::new(&mut out, width, height);
    enc.set_color(png::ColorType::Rgba);
    enc.set_depth(match depth {
        16 => png::BitDepth::Sixteen,
        _ => png::BitDepth::Eight,
    });
    enc.set_compression(png::Compression::Fast);
    enc.set_filter(png::Filter::Adaptive);
    if let Ok(mut w) = enc.write_header() {
        let _ = w.write_image_data(&raw);
    }
    out.len()
}

/// The same placements tested against every triangle (`place::place_gpu_brute`, the reference the
/// BVH walk replaced), timed in the same run: median of 3, ms.
fn brute_placement_ms(engine: &Engine, loaded: &LoadedMesh, job: &Job) -> Result<f64> {
    placement_ms(engine, loaded, job, false)
}

/// Median of three placements of `job`'s points: through the mesh's BVH (`walk`) or testing every
/// triangle.
fn placement_ms(engine: &Engine, loaded: &LoadedMesh, job: &Job, walk: bool) -> Result<f64> {
    use decalbake::io::job::AtSpec;
    use decalbake::place::Query;
    let queries: Vec<Query> = job
        .layers
        .iter()
        .map(|l| match &l.at {
            AtSpec::Point(p) => Query::Point(glam::Vec3::from(*p)),
            AtSpec::Ray { ray } => Query::Ray(ray.origin.into(), ray.dir.into()),
        })
        .collect();
    let (ctx, pipes) = (&engine.ctx, engine.pipelines());
    let mut times = Vec::new();
    for _ in 0..3 {
        let t = Instant::now();
        if walk {
            decalbake::place::place_gpu(ctx, pipes, &loaded.gpu, &queries)?;
        } else {
            decalbake::place::place_gpu_brute(ctx, pipes, &loaded.gpu, &queries)?;
        }
        times.push(t.elapsed().as_secs_f64() * 1000.0);
    }
    Ok(median(times))
}

/// The two BVH builds timed on `loaded` (median of three each: the median split on the CPU, the
/// linear BVH on the GPU and its CPU twin) and placement through each tree (the GPU's swapped in,
/// then the median split's; `loaded` keeps the tree it came with).
fn bvh_figures(engine: &Engine, loaded: &mut LoadedMesh, job: &Job) -> Result<serde_json::Value> {
    use decalbake::mesh::{bvh::Bvh, lbvh};
    let time3 = |f: &mut dyn FnMut() -> Result<()>| -> Result<f64> {
        let mut times = Vec::new();
        for _ in 0..3 {
            let t = Instant::now();
            f()?;
            times.push(t.elapsed().as_secs_f64() * 1000.0);
        }
        Ok(median(times))
    };
    let (ctx, pipes) = (&engine.ctx, engine.pipelines());
    let mut gpu_tree = None;
    let gpu_ms = time3(&mut || {
        gpu_tree = lbvh::build_gpu(ctx, pipes, &loaded.gpu, &loaded.topo)?;
        Ok(())
    })?;
    let median_ms = time3(&mut || {
        Bvh::build(&loaded.topo);
        Ok(())
    })?;
    let twin_ms = time3(&mut || {
        lbvh::build_cpu(&loaded.topo);
        Ok(())
    })?;
    let kept = loaded.bvh.clone();
    let median_tree = Bvh::build(&loaded.topo);
    let mut walks = Vec::new();
    for tree in [gpu_tree.as_ref(), Some(&median_tree)] {
        walks.push(match tree {
            Some(t) => {
                loaded.gpu.set_bvh(&ctx.device, t);
                Some(placement_ms(engine, loaded, job, true)?)
            }
            None => None,
        });
    }
    loaded.gpu.set_bvh(&ctx.device, &kept);
    Ok(serde_json::json!({
        "median_split_cpu_ms": median_ms, "lbvh_gpu_ms": gpu_ms, "lbvh_cpu_twin_ms": twin_ms,
        "lbvh_depth": gpu_tree.as_ref().map(|t| t.depth), "median_split_depth": median_tree.depth,
        "placement_walk_lbvh_ms": walks[0], "placement_walk_median_split_ms": walks[1],
    }))
}
