// SPDX-License-Identifier: MIT OR Apache-2.0
//! The engine and what it keeps between bakes: the device and its pipelines, pooled raster targets
//! ([`Engine`]); meshes loaded, welded and uploaded once, with their per-mesh caches (the material
//! texture, the islands per size) ([`LoadedMesh`]); and the read-back result ([`Baked`]). The bake
//! itself is [`super::run`], stage by stage.

use crate::bake::report::{MeshStats, Report};
use crate::error::Result;
use crate::gpu::pipelines::{Builder, Pipelines, Prepare, COVERAGE_FORMAT};
use crate::gpu::GpuContext;
use crate::io::job::Job;
use crate::mesh::upload::GpuMesh;
use crate::mesh::{Mesh, Topology};
use crate::place::{place_gpu, Query};
use std::collections::HashMap;
use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// A mesh loaded, welded and resident on the GPU.
///
/// Load it once with [`Engine::load_mesh`] and bake any number of jobs against it, from any
/// number of threads:
///
/// ```
/// # fn main() -> decalbake::Result<()> {
/// let engine = decalbake::Engine::new(None)?;
/// let spot = engine.load_mesh(std::path::Path::new("assets/spot.glb"))?;
/// // Its welded surface, the weld having joined glTF's vertices split along UV seams.
/// assert!(spot.stats.welded_vertices < spot.stats.vertices);
/// assert_eq!(spot.stats.triangles, spot.topo.triangles.len());
/// println!("{} triangles, {} UV sets", spot.stats.triangles, spot.stats.uv_sets);
/// # Ok(())
/// # }
/// ```
pub struct LoadedMesh {
    /// The mesh as loaded.
    pub mesh: Mesh,
    /// Its welded surface.
    pub topo: Topology,
    /// Curvature and intrinsic edge angles of the welded surface (exponential maps), computed
    /// once; the GPU copies are in `gpu`.
    pub surface: crate::mesh::SurfaceData,
    /// Its GPU buffers.
    pub gpu: GpuMesh,
    /// The BVH over its triangles (placement on the GPU, planar decals' candidates on the CPU).
    pub bvh: crate::mesh::bvh::Bvh,
    /// Statistics.
    pub stats: MeshStats,
    /// Load, weld and upload times (ms).
    pub timings: (f64, f64, f64),
    /// The pelting that made its UVs (`"uv_set": "auto"` on a mesh without any).
    pub unwrap: Option<crate::pelt::UnwrapReport>,
    /// The most bytes one storage buffer holds on the device the mesh lives on (the map stage's
    /// chunks fit it).
    pub(crate) storage_limit: u64,
    /// The material's base-colour texture on the GPU, uploaded by the first bake that uses it.
    pub(crate) material_texture: std::sync::OnceLock<Arc<GpuImage>>,
    /// Island masks and nearest-island maps by (UV set, width, height, supersampling).
    pub(crate) islands: Mutex<HashMap<IslandKey, Arc<Islands>>>,
    /// The same for tiled bakes, on the CPU (`bake/tiles.rs`).
    pub(crate) tiled_islands: Mutex<HashMap<IslandKey, Arc<TiledIslands>>>,
    /// What each vector unit's map needs (`bake/vector_maps.rs`), by a key that names everything
    /// the map depends on, so that a bake's tile windows and a live bake's edits map each unit
    /// once.
    pub(crate) vector_needs: Mutex<HashMap<String, Option<Arc<VectorNeeds>>>>,
}

/// One unit's needs along the image's x and y (pixels, with the texels that need them),
/// ascending ([`LoadedMesh::vector_needs`]).
pub(crate) type VectorNeeds = [Vec<(f32, f64)>; 2];

impl LoadedMesh {
    /// Forgets what its vector layers' maps needed (kept so that tile windows and live edits map
    /// each unit once), so that the next bake maps them as a one-off bake does: for benchmarks.
    pub fn forget_vector_needs(&self) {
        self.vector_needs.lock().expect("vector needs").clear();
    }

    /// The welded surface as the map kernels read it.
    pub fn surface_ref(&self) -> crate::mesh::SurfaceRef<'_> {
        crate::mesh::SurfaceRef {
            topo: &self.topo,
            surface: &self.surface,
            gpu: &self.gpu,
        }
    }

    /// Statistics of a mesh and its topology.
    pub fn stats_of(mesh: &Mesh, topo: &Topology) -> MeshStats {
        let (lo, hi) = mesh.bounds();
        MeshStats {
            source: mesh.source.display().to_string(),
            primitives: mesh.primitives.clone(),
            vertices: mesh.positions.len(),
            welded_vertices: topo.positions.len(),
            triangles: mesh.triangles.len(),
            degenerate_triangles: topo.degenerate_count(),
            uv_sets: mesh.uv_sets.len(),
            texture_sets: mesh.texture_sets(0),
            boundary_edges: topo.boundary_edges.len(),
            non_manifold_edges: topo.non_manifold_edges.len(),
            components: topo.components,
            bbox_min: lo.to_array(),
            bbox_max: hi.to_array(),
            weld_distance: topo.weld_distance,
            has_base_color_texture: mesh
                .material
                .as_ref()
                .is_some_and(|m| m.base_color_texture.is_some()),
        }
    }
}

/// A baked texture on the CPU.
#[derive(Debug, Clone)]
pub struct Baked {
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
    /// 8 or 16.
    pub bit_depth: u8,
    /// sRGB-encoded RGBA, row-major, top row first: 4 values a texel (0..=255 or 0..=65535).
    pub texels: Vec<u16>,
    /// For a float output (`output.texture` ending in `.exr`): the padded canvas, linear
    /// straight-alpha RGBA f32, 4 values a texel.
    pub linear: Option<Vec<f32>>,
    /// Each PBR channel the layers painted besides the colour (`bake::channels`), in pass
    /// order: its texels as `texels` holds the colour's (data and normals as stored, emissive
    /// sRGB-encoded).
    pub channels: Vec<BakedChannel>,
    /// The report.
    pub report: Report,
}

/// A bake's textures on the GPU ([`Engine::bake_textures`]); usages `TEXTURE_BINDING | COPY_SRC |
/// COPY_DST`, 8 bits a channel.
pub struct BakedTextures {
    /// The base colour, `Rgba8UnormSrgb`.
    pub color: wgpu::Texture,
    /// Each PBR channel group the job's layers paint, in the order of [`Baked::channels`]: emissive
    /// `Rgba8UnormSrgb`; occlusion-roughness-metallic (R, G, B) and the tangent-space normal
    /// (`n * 0.5 + 0.5`) `Rgba8Unorm`, their bytes as stored.
    pub channels: Vec<(crate::io::channels::ChannelKind, wgpu::Texture)>,
}

/// One channel's texture of a [`Baked`].
#[derive(Debug, Clone)]
pub struct BakedChannel {
    /// Which.
    pub kind: crate::io::channels::ChannelKind,
    /// RGBA, 4 values a texel, as [`Baked::texels`].
    pub texels: Vec<u16>,
    /// The channel's canvas, linear RGBA f32 padded like `texels`, for a float (EXR) output, as
    /// [`Baked::linear`] is the colour's.
    pub linear: Option<Vec<f32>>,
}

impl Baked {
    /// Texel (x, y) decoded to linear RGBA in [0, 1].
    pub fn linear(&self, x: u32, y: u32) -> [f32; 4] {
        let i = ((y * self.width + x) * 4) as usize;
        let max = if self.bit_depth == 16 { 65535.0 } else { 255.0 };
        let c = |k: usize| self.texels[i + k] as f32 / max;
        [
            crate::io::image::srgb_to_linear(c(0)),
            crate::io::image::srgb_to_linear(c(1)),
            crate::io::image::srgb_to_linear(c(2)),
            c(3),
        ]
    }

    /// PNG bytes at the bake's bit depth.
    pub fn to_png(&self) -> Vec<u8> {
        self.to_png_with(Default::default())
    }

    /// [`Self::to_png`] at a chosen compression (a job's `output.compression`).
    pub fn to_png_with(&self, compression: crate::io::image::PngCompression) -> Vec<u8> {
        let (w, h, depth) = (self.width, self.height, self.bit_depth);
        crate::io::image::png_bytes_with(w, h, depth, &self.texels, compression)
    }

    /// Each channel's PNG, in [`Self::channels`]' order, at a chosen compression.
    pub fn channel_pngs_with(&self, compression: crate::io::image::PngCompression) -> Vec<Vec<u8>> {
        let (w, h, depth) = (self.width, self.height, self.bit_depth);
        self.channels
            .iter()
            .map(|c| crate::io::image::png_bytes_with(w, h, depth, &c.texels, compression))
            .collect()
    }

    /// sRGB RGBA8 bytes (16-bit bakes are rounded).
    pub fn rgba8(&self) -> Vec<u8> {
        if self.bit_depth == 16 {
            self.texels
                .iter()
                .map(|v| ((*v as u32 * 255 + 32767) / 65535) as u8)
                .collect()
        } else {
            self.texels.iter().map(|v| *v as u8).collect()
        }
    }
}

/// Pooled raster targets of one size.
pub(crate) struct Targets {
    pub color_view: wgpu::TextureView,
    pub cov_view: wgpu::TextureView,
    _color: wgpu::Texture,
    _cov: wgpu::Texture,
}

/// A layer raster attachment pair's key: its size and samples a pixel.
type TargetKey = ([u32; 2], u32);

/// A fused channel attachment's key: its size, channel group and samples a pixel.
type ChannelTarget = ([u32; 2], usize, u32);

/// Where [`Engine::prepare`] builds a mesh's BVH (placement's walk, planar decals' candidates).
///
/// Measured (docs/, "Placement"): on lavapipe the median-split build on the CPU is the faster
/// (the GPU build's sort runs on the same two cores at the device's load rate), on a GPU the GPU
/// build; both trees answer every query alike (`tests/placement.rs`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum BvhBuild {
    /// On the GPU ([`crate::mesh::lbvh`]) unless the adapter is a CPU (lavapipe) or the backend
    /// is GL (where the build was run on llvmpipe only: `tests/placement.rs` under
    /// `WGPU_BACKEND=gl`).
    #[default]
    Auto,
    /// Median splits on the CPU ([`crate::mesh::bvh::Bvh::build`]).
    Cpu,
    /// A linear BVH on the GPU ([`crate::mesh::lbvh::build_gpu`]).
    Gpu,
}

/// Where the bake runs the stages that have a CPU twin. `Auto` takes the faster on the adapter
/// in use, measured: on a CPU adapter (lavapipe) the twin, on a GPU the kernels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum StagePath {
    /// The twin on a CPU adapter, the GPU path elsewhere.
    #[default]
    Auto,
    /// Always the CPU twin (where the stage's inputs allow).
    Cpu,
    /// Always the GPU path.
    Gpu,
}

impl StagePath {
    /// Whether the stage takes its CPU twin on `engine`: `Auto` does on a CPU adapter.
    fn on_cpu(self, engine: &Engine) -> bool {
        match self {
            StagePath::Auto => engine.ctx.device_type == Some(wgpu::DeviceType::Cpu),
            StagePath::Cpu => true,
            StagePath::Gpu => false,
        }
    }
}

/// [`StagePath`] per stage that has a CPU twin in the bake ([`Engine::stage_paths`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct StagePaths {
    /// Placement: the BVH walk on the CPU (`place::place_cpu_bvh`) against `place_bvh`. On
    /// lavapipe the twin answers a one-decal job in microseconds where the kernels cost their
    /// compile (about 0.2 s of a cold start, `startup.md`) and a submission; the answers agree
    /// within 2e-5 (`tests/placement.rs`).
    pub placement: StagePath,
    /// Unwrapping (`"uv_set": "auto"` on a mesh without UVs, `decalbake unwrap`): the spring
    /// dynamics' CPU twin (`pelt::relax`) against `pelt_step`. On lavapipe the twin unwraps Spot
    /// about 10× faster as a whole process (2026-11-28: 0.9-1.2 s against 11-12 s, most of it the
    /// conformal refinement's batched solves; benches/results/2026-11-28-lavapipe); both give layouts without flips or overlaps (`tests/pelt.rs`).
    pub unwrap: StagePath,
    /// Exponential maps (the `expmap` and `hybrid` methods, and the maps charts start from): the
    /// CPU twin (`maps::expmap::cpu::dem_cpu`, the maps of a chunk on every core, each uploaded
    /// into its slot) against `expmap_relax`. On lavapipe the relaxation is 1.3-2.2× slower than
    /// the twin (`bench --geodesic`, 2026-11-25); on GL the twin is taken whatever this says
    /// (`maps::expmap::gpu::run`). Both give the same maps within `tests/expmap.rs`'s tolerance.
    pub expmap: StagePath,
    /// Conformal charts (the `lscm` and `hybrid` methods): the CPU twin's f64 conjugate gradient
    /// (`solve::cg::pcg`, the charts of a batch on every core) against the batched GPU CG
    /// (`cg_batched`, `cg_packed`, `cg_wide`). On lavapipe the GPU solves 256 small charts at
    /// 0.42× the twin's charts a second and a 10k-vertex chart in about twice the twin's time
    /// (2026-11-25, "Linear algebra and LSCM charts" in the guide's performance chapter).
    pub charts: StagePath,
    /// The islands' distance transform (each padding texel's nearest island texel, computed
    /// once per mesh, UV set, size and sampling and cached on the mesh): the CPU twin
    /// (`cpu::nearest_island_map`, its rows on every core) over the island mask read back,
    /// against `edt_columns` and `edt_rows`. On lavapipe the twin takes a small part of the
    /// kernels' time (most of a one-decal bake's cold start went to them; the guide's
    /// performance chapter, "Start-up"); on wgpu's GL backend the twin is taken whatever this
    /// says (`bake::islands`). Both give the same map, bit for bit (`tests/padding_edt.rs`).
    pub islands: StagePath,
    /// Padding and encoding an 8-bit texture baked whole: the canvas read back band by band,
    /// quantised and padded on every core (`finish::pad_and_encode`), against the `encode`
    /// kernel, which costs llvmpipe about 40 ns a texel (0.65 s at 4096², 2026-11-29, the guide's
    /// performance chapter); it needs the islands on the CPU
    /// (`islands` on the twin), and takes the kernel otherwise (16-bit and tiled bakes, live
    /// bakes). Both give the same bytes: one exact quantisation by thresholds
    /// (`finish::Quantiser`; `tests/padding_edt.rs`).
    pub padding: StagePath,
}

impl StagePaths {
    /// Whether the bake's conformal charts are solved by the CPU twin.
    pub(crate) fn charts_on_cpu(&self, engine: &Engine) -> bool {
        self.charts.on_cpu(engine)
    }

    /// Whether the bake's exponential maps come from the CPU twin.
    pub(crate) fn expmap_on_cpu(&self, engine: &Engine) -> bool {
        self.expmap.on_cpu(engine)
    }

    /// Whether the islands' distance transform runs on the CPU twin (always on wgpu's GL
    /// backend, whose kernels get it wrong: `bake::islands`).
    pub(crate) fn islands_on_cpu(&self, engine: &Engine) -> bool {
        engine.ctx.backend == Some(wgpu::Backend::Gl) || self.islands.on_cpu(engine)
    }

    /// Whether an output of `bit_depth` bits, baked whole, is padded and encoded on the CPU:
    /// 8 bits, the islands on the twin (the CPU pads from its copy) and `padding` on the CPU.
    /// `finish::finish` decides by it (with the islands' copy at hand), `prepare_for` too.
    pub(crate) fn pads_on_cpu(&self, engine: &Engine, bit_depth: u8) -> bool {
        bit_depth == 8 && self.islands_on_cpu(engine) && self.padding.on_cpu(engine)
    }

    /// Whether unwrapping runs the dynamics on the CPU twin.
    pub(crate) fn unwrap_on_cpu(&self, engine: &Engine) -> bool {
        self.unwrap.on_cpu(engine)
    }

    /// Whether placement runs on the CPU: the twin walks the CPU-built BVH, so a mesh whose
    /// tree was built on the GPU places on the GPU.
    pub(crate) fn placement_on_cpu(&self, engine: &Engine, mesh: &LoadedMesh) -> bool {
        self.placement_prefers_cpu(engine) && !mesh.bvh.nodes.is_empty()
    }

    /// Whether placement asks for the twin, before the mesh's tree is known.
    fn placement_prefers_cpu(&self, engine: &Engine) -> bool {
        self.placement.on_cpu(engine)
    }
}

/// The engine: a device, its pipelines and pooled targets. Load meshes once, bake many jobs.
///
/// `Engine` and [`LoadedMesh`] are `Send` and `Sync`: several threads may bake with one engine
/// and one mesh at once (`decalbake batch --jobs`, a host renderer's worker threads). Each bake
/// records its raster and compose into one command buffer, so the raster targets the engine pools
/// by size are never used by two bakes in flight; the mesh's caches (islands, material texture)
/// are behind a lock. Results are the same bytes as baking one after another
/// (`tests/demo_and_api.rs`). Settings such as [`Engine::whole_mesh_selection`] are fields: set
/// them before sharing the engine.
///
/// A host renderer hands over its own device and keeps the result on the GPU:
///
/// ```
/// # fn main() -> Result<(), Box<dyn std::error::Error>> {
/// use decalbake::{Engine, Job};
/// use std::path::Path;
///
/// # let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
/// #     backends: wgpu::Backends::from_env().unwrap_or(wgpu::Backends::VULKAN | wgpu::Backends::GL),
/// #     ..wgpu::InstanceDescriptor::new_without_display_handle()
/// # });
/// # let adapter = pollster::block_on(instance.request_adapter(&Default::default()))?;
/// # let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
/// #     required_limits: adapter.limits(),
/// #     ..Default::default()
/// # }))?;
/// // `device` and `queue`: the host's own, made with the adapter's limits (wgpu's defaults
/// // allow 8 storage buffers a stage; the map and solver kernels bind up to 13).
/// let engine = Engine::from_device(device, queue)?;
/// let mesh = engine.load_mesh(Path::new("assets/spot.glb"))?;
/// let job = Job::parse(
///     r#"{ "mesh": "spot.glb", "texture": { "width": 128, "height": 128 } }"#,
///     Path::new("job.json"),
///     Path::new("assets"),
///     Path::new("."),
/// )?;
/// let (texture, report) = engine.bake_to_texture(&mesh, &job)?;
/// assert_eq!(texture.format(), wgpu::TextureFormat::Rgba8UnormSrgb);
/// assert_eq!((texture.width(), report.texture), (128, [128, 128]));
/// # Ok(())
/// # }
/// ```
pub struct Engine {
    /// The GPU context.
    pub ctx: GpuContext,
    pub(crate) pipes: Pipelines,
    /// The layer raster's attachments, by size and samples a pixel.
    targets: Mutex<HashMap<TargetKey, Arc<Targets>>>,
    /// The fused channel passes' attachments, by size, channel group (0 occlusion-roughness-
    /// metallic, 1 normal, 2 emissive) and samples a pixel, made when a bake first needs them.
    channel_targets: Mutex<HashMap<ChannelTarget, Arc<wgpu::TextureView>>>,
    /// The 8-bit quantiser's table on the GPU (`finish::Quantiser`), uploaded once, when the
    /// `encode` kernel first runs.
    pub(crate) quantiser: std::sync::OnceLock<wgpu::Buffer>,
    pub(crate) linear_sampler: wgpu::Sampler,
    /// Select every layer's triangles from the whole mesh instead of from the vertices its map can
    /// reach (`bake::maps::LayerMaps::candidate_triangles`). The results are the same; this is the
    /// reference the tests and `decalbake bench --strokes` compare the candidate lists with.
    /// Default `false`.
    pub whole_mesh_selection: bool,
    /// Draw every layer's triangles whole, and select the cells of whole triangles, instead of
    /// clipping them to the layer's image and a two-texel margin (`clip_planes` in
    /// `wgsl/bake/layer_raster.wgsl`, on devices with clip distances). The texels are the same
    /// within 32 of 65535; this is the reference `tests/demo_and_api.rs` and `decalbake bench`
    /// (`compose_unclipped_ms`) compare the clipped raster with. Default `false`.
    pub unclipped_raster: bool,
    /// Compose only the 8 × 8 texel blocks of a raster rectangle in which the raster left
    /// anything (`wgsl/shared/blocks.wgsl`): the texels of the others would compose nothing, so
    /// the bytes are the same either way. `false` composes every texel of every rectangle: the
    /// reference `tests/tiles.rs` and `decalbake bench` (`compose_every_block_ms`) compare
    /// with. Default `true`.
    pub skip_empty_blocks: bool,
    /// Where a prepared mesh's BVH is built ([`BvhBuild`]). Default [`BvhBuild::Auto`].
    pub bvh_build: BvhBuild,
    /// Draw and compose each PBR channel group in a pass of its own, after the colour's, instead
    /// of beside the colour in one fused pass (`bake/compose.rs`). The fused pass is taken where
    /// the device holds five attachments and the job has no strokes; both give the same bytes
    /// (`tests/channels.rs`); the separate passes are its reference and the fallback. Default
    /// `false`.
    pub separate_channel_passes: bool,
    /// Where the stages with a CPU twin run ([`StagePaths`]). Default: the faster on the adapter.
    pub stage_paths: StagePaths,
    /// The raster clips a layer's triangles only where the mesh's triangles cover at least this
    /// many texels on average at the bake's size (its UV area over its triangles): clipping
    /// costs each triangle three corners' reads and pays back through the fringe it drops, which
    /// shrinks with the triangles. Measured, 256 decals (compose, clipped against whole
    /// triangles, same run of `decalbake bench`): bob at 4096² (about 940 texels a triangle) 2.79
    /// against 3.51 s, at 2048² (235) 1.13 against 1.32 s; with the threshold at 0 (a scratch
    /// build), bob subdivided twice at 4096² (59) 4.05 against 3.96 s, at 2048² (15) 2.12
    /// against 2.03 s. Below it, neither the raster nor the selection clips. Default 128.
    pub clip_min_texels: f32,
    /// Layer images and masks decoded and uploaded by earlier bakes (`bake/images.rs`).
    pub(crate) images: Mutex<ImageCache>,
    /// Whether a bake's report has carried the engine's start-up time.
    startup_reported: std::sync::atomic::AtomicBool,
    /// Canvas-sized buffers of finished bakes, for the next bake or tile ([`BufferPool`]).
    pub(crate) buffers: Mutex<BufferPool>,
}

/// Copies an encoded window (x, y, w, h; rows `stride` words apart in `words`: RGBA8 in one word,
/// RGBA16 in two) into `texels` (4 values a texel, rows `tex_w` texels wide) at its place. Row
/// bands on every core: a tile's 16M texels are 64 MiB of fresh memory to write.
pub(crate) fn unpack_rows(
    texels: &mut [u16],
    tex_w: u32,
    win: [u32; 4],
    words: &[u32],
    stride: u32,
    depth: u8,
) {
    let [x, y, w, h] = win.map(|v| v as usize);
    let (tex_w, stride) = (tex_w as usize, stride as usize);
    let rows = &mut texels[y * tex_w * 4..(y + h) * tex_w * 4];
    let threads = std::thread::available_parallelism().map_or(1, |t| t.get());
    let band = h.div_ceil(threads).max(1);
    std::thread::scope(|s| {
        for (b, chunk) in rows.chunks_mut(band * tex_w * 4).enumerate() {
            s.spawn(move || {
                for (r, row) in chunk.chunks_exact_mut(tex_w * 4).enumerate() {
                    let src = &words[(b * band + r) * stride..];
                    let dst = &mut row[x * 4..(x + w) * 4];
                    if depth == 16 {
                        for (d, word) in dst.chunks_exact_mut(2).zip(&src[..2 * w]) {
                            d[0] = (word & 0xffff) as u16;
                            d[1] = (word >> 16) as u16;
                        }
                    } else {
                        for (d, word) in dst.chunks_exact_mut(4).zip(&src[..w]) {
                            d.copy_from_slice(&word.to_le_bytes().map(u16::from));
                        }
                    }
                }
            });
        }
    });
}

/// Large buffers handed back by a finished bake (the canvas planes, the encoded texture) for the
/// next bake of the same size, or the next tile of a tiled one: a fresh 128 MiB buffer costs the
/// device a zero-fill and, on lavapipe, the host its page faults (190 ms for a 4096² canvas's two
/// planes, and up to 700 ms when the host is short of free pages; timed with temporary prints in
/// `bench --tiles` runs, not kept).
/// A taken buffer holds its last user's bytes: the taker overwrites or clears it. At most
/// [`BufferPool::BYTES`] are kept (or what [`Engine::keep_buffers`] says), the most recently
/// returned first.
pub(crate) struct BufferPool {
    free: Vec<wgpu::Buffer>,
    cap: u64,
}

impl Default for BufferPool {
    fn default() -> Self {
        Self {
            free: Vec::new(),
            cap: Self::BYTES,
        }
    }
}

impl BufferPool {
    /// The most bytes kept: a 4096² canvas (two 128 MiB planes) and its encode (64 MiB, or 128 MiB
    /// at 16 bits), twice over, for two bakes of different sizes or two threads.
    pub const BYTES: u64 = Engine::DEFAULT_KEPT_BUFFERS;

    /// A free buffer of exactly `size` bytes and `usage`, if one is kept.
    pub fn take(&mut self, size: u64, usage: wgpu::BufferUsages) -> Option<wgpu::Buffer> {
        let k = self
            .free
            .iter()
            .rposition(|b| b.size() == size && b.usage() == usage)?;
        Some(self.free.remove(k))
    }

    /// Keeps `buffer` for a later [`Self::take`], dropping the oldest beyond the cap.
    pub fn give(&mut self, buffer: wgpu::Buffer) {
        self.free.push(buffer);
        self.trim();
    }

    fn trim(&mut self) {
        while self.free.iter().map(|b| b.size()).sum::<u64>() > self.cap {
            self.free.remove(0);
        }
    }
}

impl Drop for Engine {
    fn drop(&mut self) {
        self.save_pipeline_cache();
    }
}

impl Engine {
    /// An engine on its own headless device (see [`GpuContext::new`]).
    pub fn new(backend: Option<&str>) -> Result<Self> {
        Self::with_context(GpuContext::new(backend)?)
    }

    /// An engine on the host's device and queue. The device must support compute shaders and be
    /// made with the adapter's limits (`required_limits: adapter.limits()`): wgpu's default
    /// limits allow 8 storage buffers a shader stage, and the map and solver kernels bind up to
    /// 13, so an exponential-map or conformal decal would fail with `Error::Gpu`.
    pub fn from_device(device: wgpu::Device, queue: wgpu::Queue) -> Result<Self> {
        Self::with_context(GpuContext::from_device(device, queue, None))
    }

    /// An engine on the host's device and queue, naming the adapter they came from: the report then
    /// names it, and backend-specific workarounds (wgpu's GL backend) apply. An adapter that
    /// cannot bake (no compute shaders, or a fragment stage that cannot write storage buffers, as
    /// `Engine::new` passes over) is refused here with [`crate::Error::DeviceCreation`] naming
    /// why, not in the middle of the first bake.
    pub fn from_adapter(
        adapter: &wgpu::Adapter,
        device: wgpu::Device,
        queue: wgpu::Queue,
    ) -> Result<Self> {
        let info = adapter.get_info();
        let flags = adapter.get_downlevel_capabilities().flags;
        if let Some(why) = crate::gpu::unsuitable(flags, &info.name) {
            return Err(crate::Error::DeviceCreation {
                adapter: info.name,
                detail: why,
            });
        }
        Self::with_context(GpuContext::from_device(device, queue, Some(info)))
    }

    /// An engine on an existing context.
    pub fn with_context(ctx: GpuContext) -> Result<Self> {
        let cache = ctx.pipeline_cache.0.as_ref().map(|c| c.cache.clone());
        let builder = Builder::new(ctx.device.clone(), cache);
        let pipes = ctx.scoped("pipeline creation", || Pipelines::new(builder))?;
        let linear_sampler = ctx.device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("decalbake.linear"),
            address_mode_u: wgpu::AddressMode::ClampToEdge,
            address_mode_v: wgpu::AddressMode::ClampToEdge,
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            mipmap_filter: wgpu::MipmapFilterMode::Linear,
            // Trilinear, no anisotropic filtering: lavapipe's anisotropic path (Mesa 22.3) shifts
            // samples by half a texel even at an explicit level 0, which blurs the base copy.
            anisotropy_clamp: 1,
            ..Default::default()
        });
        Ok(Self {
            ctx,
            pipes,
            targets: Mutex::new(HashMap::new()),
            channel_targets: Mutex::new(HashMap::new()),
            quantiser: std::sync::OnceLock::new(),
            separate_channel_passes: false,
            buffers: Mutex::new(BufferPool::default()),
            linear_sampler,
            whole_mesh_selection: false,
            unclipped_raster: false,
            skip_empty_blocks: true,
            bvh_build: BvhBuild::Auto,
            stage_paths: StagePaths::default(),
            clip_min_texels: 128.0,
            images: Mutex::new(Default::default()),
            startup_reported: Default::default(),
        })
    }

    /// Layer images and masks kept on the GPU between bakes (each file once, as it was when read).
    pub fn cached_images(&self) -> usize {
        self.images.lock().map_or(0, |c| c.len())
    }

    /// Drops the layer images and masks kept between bakes: the next bake decodes (or renders)
    /// them again, as a one-off bake does.
    pub fn clear_image_cache(&self) {
        if let Ok(mut c) = self.images.lock() {
            c.clear();
        }
    }

    /// The engine's compiled pipelines (for the linear-algebra entry points).
    pub fn pipelines(&self) -> &Pipelines {
        &self.pipes
    }

    /// Chart solves on this engine's device (batched GPU CG).
    pub fn solver(&self) -> crate::maps::chart::Solver<'_> {
        crate::maps::chart::Solver::Gpu(&self.ctx, &self.pipes)
    }

    /// Places `queries` on `mesh` on the GPU (see [`crate::place::place_gpu`]), each with the
    /// model's shading normal at its point ([`crate::place::with_shading_normal`]), as a bake does.
    pub fn place(
        &self,
        mesh: &LoadedMesh,
        queries: &[Query],
    ) -> Result<Vec<crate::place::Placement>> {
        let placed = place_gpu(&self.ctx, &self.pipes, &mesh.gpu, queries)?;
        Ok(placed
            .into_iter()
            .map(|p| crate::place::with_shading_normal(&mesh.mesh, p))
            .collect())
    }

    /// Computes exponential maps on the GPU and reads them back (tests, `decalbake param`,
    /// benchmarks); see [`crate::maps::expmap::gpu::expmaps_gpu`].
    pub fn expmaps(
        &self,
        mesh: &LoadedMesh,
        maps: &[(crate::maps::expmap::Seed, crate::maps::expmap::Options)],
    ) -> Result<
        Vec<(
            crate::maps::expmap::gpu::MapCoords,
            crate::maps::expmap::GeoResult,
        )>,
    > {
        crate::maps::expmap::gpu::expmaps_gpu(&self.ctx, &self.pipes, mesh.surface_ref(), maps)
    }

    /// Computes exponential maps on the GPU and reads back only their status and the dispatches
    /// issued (benchmarks).
    pub fn expmaps_status(
        &self,
        mesh: &LoadedMesh,
        maps: &[(crate::maps::expmap::Seed, crate::maps::expmap::Options)],
    ) -> Result<(Vec<crate::maps::expmap::GeoResult>, u32)> {
        crate::maps::expmap::gpu::expmaps_gpu_status(
            &self.ctx,
            &self.pipes,
            mesh.surface_ref(),
            maps,
        )
    }

    /// Loads a mesh file, welds it and uploads it.
    pub fn load_mesh(&self, path: &Path) -> Result<LoadedMesh> {
        let t0 = Instant::now();
        let mesh = Mesh::load(path)?;
        self.prepare_mesh(mesh, t0)
    }

    /// Loads glTF bytes (embedded data only), welds and uploads.
    pub fn load_mesh_bytes(&self, bytes: &[u8], name: &Path) -> Result<LoadedMesh> {
        let t0 = Instant::now();
        let mesh = Mesh::from_bytes(bytes, name, None)?;
        self.prepare_mesh(mesh, t0)
    }

    /// Loads the mesh of `job` and resolves `"uv_set": "auto"`: the base-colour texture's set
    /// (0 without one), or, on a mesh without UVs, a `TEXCOORD_0` made by pelting on this engine's
    /// GPU (`crate::pelt::unwrap` with its defaults, as `decalbake unwrap`, non-manifold edges
    /// opened as `--split-non-manifold` does), which the mesh then
    /// carries into the `.glb` and its report into the bake's (`unwrap`). Returns the job with its
    /// set resolved.
    pub fn load_mesh_for(&self, job: &Job) -> Result<(LoadedMesh, Job)> {
        let mut job = job.clone();
        if !job.uv_auto {
            return Ok((self.load_mesh(&job.mesh)?, job));
        }
        let t0 = Instant::now();
        let mut mesh = Mesh::load(&job.mesh)?;
        let mut unwrap = None;
        if mesh.uv_sets.is_empty() {
            let topo = Topology::build(&mesh, crate::mesh::DEFAULT_WELD_TOLERANCE);
            topo.fill_normals(&mut mesh);
            let dev = self.pelt_device();
            // Non-manifold edges (a body whose parts meet at shared edges) become chart
            // boundaries, as xatlas and Blender do, instead of refusing the model.
            let opts = crate::pelt::Options {
                size: job.width.max(job.height),
                split_non_manifold: true,
                ..Default::default()
            };
            let un = crate::pelt::unwrap(dev, &mesh, &topo, &opts, &job.mesh)?;
            mesh = crate::pelt::apply(&mesh, &un, 0);
            unwrap = Some(un.report);
            job.uv_set = 0;
        } else {
            job.uv_set = mesh.material.as_ref().map_or(0, |m| m.base_color_uv_set);
        }
        let mut loaded = self.prepare_mesh(mesh, t0)?;
        loaded.unwrap = unwrap;
        Ok((loaded, job))
    }

    /// Whether a prepared mesh's BVH is built on the GPU ([`Self::bvh_build`]).
    fn bvh_on_gpu(&self) -> bool {
        match self.bvh_build {
            BvhBuild::Auto => {
                self.ctx.device_type != Some(wgpu::DeviceType::Cpu)
                    && self.ctx.backend != Some(wgpu::Backend::Gl)
            }
            BvhBuild::Cpu => false,
            BvhBuild::Gpu => true,
        }
    }

    /// Welds and uploads a mesh already in memory.
    pub fn prepare(&self, mesh: Mesh) -> Result<LoadedMesh> {
        self.prepare_mesh(mesh, Instant::now())
    }

    fn prepare_mesh(&self, mut mesh: Mesh, t0: Instant) -> Result<LoadedMesh> {
        let load = ms(t0);
        let t1 = Instant::now();
        let topo = Topology::build(&mesh, crate::mesh::DEFAULT_WELD_TOLERANCE);
        let surface = crate::mesh::SurfaceData::new(&topo);
        let on_gpu = self.bvh_on_gpu();
        let bvh = if on_gpu {
            crate::mesh::bvh::Bvh::default()
        } else {
            crate::mesh::bvh::Bvh::build(&topo)
        };
        topo.fill_normals(&mut mesh);
        let weld = ms(t1);
        let t2 = Instant::now();
        // The largest of the mesh's GPU buffers (16 bytes a welded vertex or triangle, 8 a split
        // vertex's UV, 4 an adjacency entry, 32 a BVH node) must fit one storage buffer.
        let biggest = [
            16 * topo.positions.len().max(topo.triangles.len()),
            8 * mesh.positions.len(),
            4 * topo.adjacency.len(),
            32 * bvh.nodes.len().max(2 * topo.triangles.len().div_ceil(4)),
        ];
        self.ctx.fits(
            || format!("the mesh {}", mesh.source.display()),
            biggest.into_iter().max().unwrap_or(0) as u64,
            "bake on a device with larger storage buffers, or decimate the mesh",
        )?;
        let mut gpu = self.ctx.scoped("mesh upload", || {
            GpuMesh::upload(&self.ctx.device, &mesh, &topo, &surface, &bvh)
        })?;
        let bvh = if on_gpu {
            self.gpu_bvh(&mut gpu, &topo)?
        } else {
            bvh
        };
        let upload = ms(t2);
        let stats = LoadedMesh::stats_of(&mesh, &topo);
        Ok(LoadedMesh {
            mesh,
            topo,
            surface,
            gpu,
            bvh,
            stats,
            timings: (load, weld, upload),
            unwrap: None,
            storage_limit: self.ctx.storage_limit().0,
            material_texture: std::sync::OnceLock::new(),
            islands: Mutex::new(HashMap::new()),
            tiled_islands: Mutex::new(HashMap::new()),
            vector_needs: Mutex::new(HashMap::new()),
        })
    }

    /// The BVH of an uploaded mesh built on the GPU ([`crate::mesh::lbvh::build_gpu`]) and put in
    /// `gpu`; the median-split build on the CPU where the GPU's tree would be deeper than the walk
    /// allows.
    fn gpu_bvh(&self, gpu: &mut GpuMesh, topo: &Topology) -> Result<crate::mesh::bvh::Bvh> {
        let bvh = crate::mesh::lbvh::build_gpu(&self.ctx, &self.pipes, gpu, topo)?
            .unwrap_or_else(|| crate::mesh::bvh::Bvh::build(topo));
        self.ctx
            .scoped("mesh upload", || gpu.set_bvh(&self.ctx.device, &bvh))?;
        Ok(bvh)
    }

    /// A buffer of `size` bytes and `usage` from the pool ([`BufferPool`]; it holds a previous
    /// bake's bytes), or a new one (zero-filled); `true` when it is new.
    pub(crate) fn pooled_buffer(
        &self,
        label: &str,
        size: u64,
        usage: wgpu::BufferUsages,
    ) -> (wgpu::Buffer, bool) {
        let kept = self
            .buffers
            .lock()
            .expect("buffer pool poisoned")
            .take(size, usage);
        match kept {
            Some(b) => (b, false),
            None => (
                self.ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size,
                    usage,
                    mapped_at_creation: false,
                }),
                true,
            ),
        }
    }

    /// Keeps at most `bytes` of canvas-sized buffers between bakes (`BufferPool::BYTES`, 768 MiB,
    /// by default). 0 keeps none: a bake's canvas planes are then freed before its read-back, which
    /// lowers the peak memory of a process that bakes once (`decalbake bake` of one job; 256
    /// decals at 4096² on bob, `/usr/bin/time -v`: 1.23 GB resident, 0.95 GB without, docs/performance.md) at
    /// the price of a fresh canvas for every later bake.
    pub fn keep_buffers(&self, bytes: u64) {
        // (The default is [`Engine::DEFAULT_KEPT_BUFFERS`].)
        let mut pool = self.buffers.lock().expect("buffer pool poisoned");
        pool.cap = bytes;
        pool.trim();
    }

    /// What [`Engine::keep_buffers`] is by default: 768 MiB, a 4096² canvas (two 128 MiB planes)
    /// and its encode (64 MiB, or 128 MiB at 16 bits), twice over, for two bakes of different
    /// sizes or two threads.
    pub const DEFAULT_KEPT_BUFFERS: u64 = 768 << 20;

    /// Hands buffers back to the pool once no submitted work reads or writes them.
    pub(crate) fn return_buffers(&self, buffers: impl IntoIterator<Item = wgpu::Buffer>) {
        let mut pool = self.buffers.lock().expect("buffer pool poisoned");
        for b in buffers {
            pool.give(b);
        }
    }

    /// The layer raster's colour and coverage attachments of `size` at `samples` a pixel (4: the
    /// adaptive raster's, [`Engine::adaptive_sampling`]).
    pub(crate) fn targets(&self, size: [u32; 2], samples: u32) -> Arc<Targets> {
        let mut pool = self.targets.lock().expect("target pool poisoned");
        pool.entry((size, samples))
            .or_insert_with(|| {
                let mk = |label: &str, format| self.attachment(label, (size, samples), format);
                let color = mk("bake.target.color", self.pipes.layer_format);
                let cov = mk("bake.target.coverage", COVERAGE_FORMAT);
                Arc::new(Targets {
                    color_view: color.create_view(&Default::default()),
                    cov_view: cov.create_view(&Default::default()),
                    _color: color,
                    _cov: cov,
                })
            })
            .clone()
    }

    /// The fused channel passes' attachment of `size` at `samples` a pixel for channel group `k`
    /// (0 occlusion-roughness-metallic, 1 normal, 2 emissive), in the layer target's format.
    pub(crate) fn channel_target(
        &self,
        size: [u32; 2],
        k: usize,
        samples: u32,
    ) -> Arc<wgpu::TextureView> {
        let mut pool = self.channel_targets.lock().expect("target pool poisoned");
        pool.entry((size, k, samples))
            .or_insert_with(|| {
                let format = self.pipes.layer_format;
                let t = self.attachment("bake.target.channel", (size, samples), format);
                Arc::new(t.create_view(&Default::default()))
            })
            .clone()
    }

    /// A render attachment of `size`, `samples` a pixel and `format` that shaders can read.
    fn attachment(
        &self,
        label: &str,
        (size, samples): ([u32; 2], u32),
        format: wgpu::TextureFormat,
    ) -> wgpu::Texture {
        self.ctx.device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d {
                width: size[0],
                height: size[1],
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: samples,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        })
    }

    /// Whether `job`'s layers are drawn at four samples a pixel, once a texel and triangle
    /// (adaptive supersampling, `wgsl/bake/layer_raster.wgsl`'s `// MSAA: ` lines): the job asks
    /// for it ([`Job::adaptive_sampling`]: four samples a texel, `texture.sampling` not `"full"`)
    /// and the device holds four-sample targets of the layer format
    /// ([`crate::gpu::pipelines::Pipelines::msaa_ok`]). Otherwise once a sample, on the grid.
    /// wgpu's GL backend is left out: its shaders' sample mask input needs an extension the
    /// textures' probe does not ask about.
    pub(crate) fn adaptive_sampling(&self, job: &Job) -> bool {
        job.adaptive_sampling() && self.pipes.msaa_ok && self.ctx.backend != Some(wgpu::Backend::Gl)
    }

    /// Whether `job`'s PBR channel groups are drawn beside its colour in one pass
    /// (`bake/compose.rs`; each group's values are those of a pass of its own, bit for bit), or a
    /// pass each after the colour's: fused where the job paints channels and has no strokes (a
    /// stroke's stamps build up in a stroke buffer per canvas, and tool strokes read their own
    /// canvas, which the separate passes keep), the device holds the attachments
    /// ([`crate::gpu::pipelines::Fused::fits`]) and [`Engine::separate_channel_passes`] is unset.
    pub(crate) fn fuses_channels(&self, job: &Job) -> bool {
        !self.separate_channel_passes
            && job.channel_groups() != 0
            && job
                .layers
                .iter()
                .all(|l| l.kind != crate::io::job::LayerKind::Stroke)
            && crate::gpu::pipelines::Fused::fits(
                &self.ctx.device.limits(),
                self.pipes.layer_format,
            )
    }

    /// Bakes `job` onto `mesh` and reads the texture back: the bytes are the same on every run
    /// and every thread (a bake holds no state between jobs that changes its output).
    ///
    /// ```
    /// # fn main() -> decalbake::Result<()> {
    /// use decalbake::{Engine, Job};
    /// use std::path::Path;
    ///
    /// let engine = Engine::new(None)?;
    /// let mesh = engine.load_mesh(Path::new("assets/spot.glb"))?;
    /// // A job without layers bakes the model's own texture, padded.
    /// let job = Job::parse(
    ///     r#"{ "mesh": "spot.glb", "texture": { "width": 64, "height": 64 } }"#,
    ///     Path::new("job.json"),
    ///     Path::new("assets"),
    ///     Path::new("."),
    /// )?;
    /// let baked = engine.bake(&mesh, &job)?;
    /// assert_eq!(baked.rgba8().len(), 64 * 64 * 4);
    /// # Ok(())
    /// # }
    /// ```
    pub fn bake(&self, mesh: &LoadedMesh, job: &Job) -> Result<Baked> {
        self.bake_with_progress(mesh, job, &|_| {})
    }

    /// Where this engine runs the pelting's dynamics: its GPU, or the CPU twin where
    /// [`StagePaths::unwrap`] says so (by default on a CPU adapter such as lavapipe).
    pub fn pelt_device(&self) -> crate::pelt::Device<'_> {
        if self.stage_paths.unwrap_on_cpu(self) {
            crate::pelt::Device::Cpu
        } else {
            crate::pelt::Device::Gpu(&self.ctx, &self.pipes)
        }
    }

    /// [`Self::bake`], naming each stage to `on_stage` as it starts (`"placement"`, `"images"`,
    /// `"canvas"`, `"maps, selection and compose: units a-b of n"` per chunk, `"padding and
    /// encode"`, `"read-back"`): what a progress display shows during a long bake.
    pub fn bake_with_progress(
        &self,
        mesh: &LoadedMesh,
        job: &Job,
        on_stage: &dyn Fn(&str),
    ) -> Result<Baked> {
        let before = self.pipelines_spent();
        let mut baked = self.bake_whole_or_tiled(mesh, job, on_stage)?;
        self.note_start(&mut baked.report, before);
        Ok(baked)
    }

    /// Milliseconds spent building pipelines on this engine so far.
    pub(crate) fn pipelines_spent(&self) -> f64 {
        self.pipes.builder.spent().0
    }

    /// Notes in a finished bake's report the pipelines it built (`before`: [`Self::pipelines_spent`]
    /// when it began), the engine's start-up if no report has carried it yet, and the pipeline
    /// cache's state; saves the cache if pipelines were built since its last save.
    pub(crate) fn note_start(&self, report: &mut Report, before: f64) {
        let (spent, built) = self.pipes.builder.spent();
        let first = !self
            .startup_reported
            .swap(true, std::sync::atomic::Ordering::Relaxed);
        // The first bake counts what was built before it too (`prepare_for`).
        report.timings.pipelines_ms = if first { spent } else { spent - before };
        report.timings.startup_ms = if first { self.ctx.startup_ms } else { 0.0 };
        report.pipeline_cache = self.ctx.pipeline_cache.1.name();
        if let Some(cache) = &self.ctx.pipeline_cache.0 {
            cache.save(built);
        }
    }

    /// Saves the pipeline cache (`gpu::cache`) if pipelines were built since its last save: the
    /// bakes do, and so does dropping the engine; a command that builds pipelines after its bake
    /// (the preview) calls this once its files are written.
    pub fn save_pipeline_cache(&self) {
        if let Some(cache) = &self.ctx.pipeline_cache.0 {
            cache.save(self.pipes.builder.spent().1);
        }
    }

    /// Builds, on every core, the pipelines `job` will run (those of every bake, and those its
    /// layers' kinds and outputs need), so that a caller can overlap them with reading the mesh
    /// and images (`decalbake bake` does). Pipelines are otherwise built when first used; this
    /// changes no result.
    pub fn prepare_for(&self, job: &Job) {
        Pipelines::prepare(pipelines_for(self, job));
    }

    fn bake_whole_or_tiled(
        &self,
        mesh: &LoadedMesh,
        job: &Job,
        on_stage: &dyn Fn(&str),
    ) -> Result<Baked> {
        super::limits(self, mesh, job)?;
        if let Some(tiled) = super::tiled(self, mesh, job, on_stage) {
            return tiled;
        }
        let run = super::run(self, mesh, job, on_stage)?;
        on_stage("read-back");
        let t = Instant::now();
        let texels = self.read_finished(run.encoded, job)?;
        let mut channels = Vec::with_capacity(run.channels.len());
        for (kind, e) in run.channels {
            let texels = self.read_finished(e, job)?;
            channels.push(BakedChannel {
                kind,
                texels,
                linear: None,
            });
        }
        let mut report = run.report;
        report.timings.encode_ms += ms(t);
        Ok(Baked {
            width: job.width,
            height: job.height,
            bit_depth: job.bit_depth,
            texels,
            linear: None,
            channels,
            report,
        })
    }

    /// A finished texture's texels: read back from the GPU ([`Engine::read_encoded`]) or as the
    /// CPU's padding left them.
    fn read_finished(&self, finished: super::Finished, job: &Job) -> Result<Vec<u16>> {
        match finished {
            super::Finished::Gpu(e) => self.read_encoded((&e.packed, e.packed_size, e.stride), job),
            super::Finished::Host(texels) => Ok(texels),
        }
    }

    /// An encoded texture (packed buffer, its bytes, words a row) read back into texels (the
    /// packed buffer then goes back to the pool).
    fn read_encoded(
        &self,
        (packed, size, stride): (&wgpu::Buffer, u64, u32),
        job: &Job,
    ) -> Result<Vec<u16>> {
        let (w, h) = (job.width, job.height);
        let mut texels = vec![0u16; (w * h * 4) as usize];
        self.ctx
            .read_buffer_with(packed, size, "encode read-back", |bytes| {
                let words = bytemuck::cast_slice(bytes);
                unpack_rows(&mut texels, w, [0, 0, w, h], words, stride, job.bit_depth)
            })?;
        self.return_buffers([packed.clone()]);
        Ok(texels)
    }

    /// Bakes `job` onto `mesh` and returns the result as an `Rgba8UnormSrgb` texture that never leaves
    /// the GPU (usages: `TEXTURE_BINDING | COPY_SRC | COPY_DST`). The job's `bit_depth` is ignored.
    /// A texture that is baked by tiles (beyond one storage buffer) is assembled on the CPU and
    /// uploaded. The colour only: [`Engine::bake_textures`] gives the PBR channels too.
    pub fn bake_to_texture(&self, mesh: &LoadedMesh, job: &Job) -> Result<(wgpu::Texture, Report)> {
        let (textures, report) = self.bake_textures(mesh, job)?;
        Ok((textures.color, report))
    }

    /// Bakes `job` onto `mesh` into textures that never leave the GPU: the colour, as
    /// [`Engine::bake_to_texture`] gives it, and one texture per PBR channel group the job's
    /// layers paint ([`BakedTextures`]), 8 bits a channel, each holding the bytes of the PNG
    /// [`Engine::bake`] would write for it. A texture baked by tiles is assembled on the CPU and
    /// uploaded, each channel's too.
    pub fn bake_textures(&self, mesh: &LoadedMesh, job: &Job) -> Result<(BakedTextures, Report)> {
        let before = self.pipelines_spent();
        let (textures, mut report) = self.bake_textures_unnoted(mesh, job)?;
        self.note_start(&mut report, before);
        Ok((textures, report))
    }

    fn bake_textures_unnoted(
        &self,
        mesh: &LoadedMesh,
        job: &Job,
    ) -> Result<(BakedTextures, Report)> {
        let mut job8 = job.clone();
        job8.bit_depth = 8;
        super::limits(self, mesh, &job8)?;
        let srgb = wgpu::TextureFormat::Rgba8UnormSrgb;
        if let Some(tiled) = super::tiled(self, mesh, &job8, &|_| {}) {
            let baked = tiled?;
            let textures = self.ctx.scoped("texture output", || {
                let color = self.upload_texels(&baked.texels, job, srgb);
                let channels = baked
                    .channels
                    .iter()
                    .map(|c| {
                        let format = match c.kind.linear() {
                            true => wgpu::TextureFormat::Rgba8Unorm,
                            false => srgb,
                        };
                        (c.kind, self.upload_texels(&c.texels, job, format))
                    })
                    .collect();
                BakedTextures { color, channels }
            })?;
            return Ok((textures, baked.report));
        }
        let run = super::run(self, mesh, &job8, &|_| {})?;
        let textures = self.ctx.scoped("texture output", || {
            let mut enc = self.ctx.device.create_command_encoder(&Default::default());
            let mut texture = |finished: &super::Finished, format| match finished {
                super::Finished::Gpu(e) => {
                    self.copy_to_texture(&mut enc, (&e.packed, e.stride), job, format)
                }
                super::Finished::Host(texels) => self.upload_texels(texels, job, format),
            };
            let color = texture(&run.encoded, srgb);
            let channels = run
                .channels
                .iter()
                .map(|(kind, encoded)| {
                    let format = match kind.linear() {
                        true => wgpu::TextureFormat::Rgba8Unorm,
                        false => srgb,
                    };
                    (*kind, texture(encoded, format))
                })
                .collect();
            self.ctx.queue.submit([enc.finish()]);
            BakedTextures { color, channels }
        })?;
        let packed = std::iter::once(&run.encoded)
            .chain(run.channels.iter().map(|(_, e)| e))
            .filter_map(|e| match e {
                super::Finished::Gpu(e) => Some(e.packed.clone()),
                super::Finished::Host(_) => None,
            });
        self.return_buffers(packed);
        Ok((textures, run.report))
    }

    /// A new `format` texture of the job's size holding `texels` (8-bit values, 4 a texel, as
    /// [`Baked::texels`] holds them), written through the queue.
    fn upload_texels(
        &self,
        texels: &[u16],
        job: &Job,
        format: wgpu::TextureFormat,
    ) -> wgpu::Texture {
        let tex = self.output_texture(job.width, job.height, format);
        let bytes: Vec<u8> = texels.iter().map(|&v| v as u8).collect();
        self.ctx.queue.write_texture(
            tex.as_image_copy(),
            &bytes,
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(job.width * 4),
                rows_per_image: Some(job.height),
            },
            tex.size(),
        );
        tex
    }

    /// A new `format` texture of the job's size, recorded into `enc` as a copy of an encoded
    /// texture's 8-bit rows (`packed`, `stride` words a row).
    fn copy_to_texture(
        &self,
        enc: &mut wgpu::CommandEncoder,
        (packed, stride): (&wgpu::Buffer, u32),
        job: &Job,
        format: wgpu::TextureFormat,
    ) -> wgpu::Texture {
        let tex = self.output_texture(job.width, job.height, format);
        enc.copy_buffer_to_texture(
            wgpu::TexelCopyBufferInfo {
                buffer: packed,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(stride * 4),
                    rows_per_image: Some(job.height),
                },
            },
            tex.as_image_copy(),
            wgpu::Extent3d {
                width: job.width,
                height: job.height,
                depth_or_array_layers: 1,
            },
        );
        tex
    }

    fn output_texture(
        &self,
        width: u32,
        height: u32,
        format: wgpu::TextureFormat,
    ) -> wgpu::Texture {
        self.ctx.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("decalbake.baked"),
            size: wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage: wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_SRC
                | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        })
    }
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1000.0
}

/// A decoded image on the GPU.
pub struct GpuImage {
    /// Its view.
    pub view: wgpu::TextureView,
    pub(crate) _tex: wgpu::Texture,
}

impl Islands {
    /// No islands (a tile's canvas: the tiled bake pads on the CPU, `bake/tiles.rs`): 16-byte
    /// placeholders for the bindings.
    pub(crate) fn none(dev: &wgpu::Device) -> Self {
        let buf = |label| {
            dev.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: 16,
                usage: wgpu::BufferUsages::STORAGE,
                mapped_at_creation: false,
            })
        };
        Self {
            gpu: [buf("islands.none.mask"), buf("islands.none.nearest")].into(),
            count: 0,
            path: "none",
            host: None,
        }
    }

    /// The mask (a word per texel) and the nearest map on the GPU, for the `encode` kernel:
    /// uploaded from [`Islands::host`] on first use where the twin computed them (a CPU path
    /// pads from the host copy and never needs them).
    pub(crate) fn gpu(&self, ctx: &crate::gpu::GpuContext) -> &[wgpu::Buffer; 2] {
        self.gpu.get_or_init(|| {
            let host = self
                .host
                .as_ref()
                .expect("islands without buffers have a host copy");
            let mask = host.mask_words();
            let none = wgpu::BufferUsages::empty();
            [
                ctx.storage_init("islands.mask", bytemuck::cast_slice(&mask), none),
                ctx.storage_init("islands.nearest", bytemuck::cast_slice(&host.nearest), none),
            ]
        })
    }
}

/// The islands of a texture on the CPU, assembled from its tiles (`bake/tiles.rs`) or computed
/// by the distance transform's twin ([`Islands::host`]): the mask and every texel's nearest
/// island texel (`u32::MAX`: none), over the whole texture.
pub struct TiledIslands {
    /// True per island texel.
    pub mask: Vec<bool>,
    /// Nearest island texel per texel.
    pub nearest: Vec<u32>,
    /// Island texels.
    pub count: u64,
}

impl TiledIslands {
    /// The mask as the kernels read it: a word per texel, 1 on an island.
    pub(crate) fn mask_words(&self) -> Vec<u32> {
        self.mask.iter().map(|&m| u32::from(m)).collect()
    }
}

/// GPU bytes of layer images kept between bakes.
pub const IMAGE_BUDGET: u64 = 512 << 20;

/// A file as it was when it was read: path, whether read raw (a mask), length and modification
/// time, so that a file rewritten between bakes is read again.
/// A layer image's key: its path (a text's: its SVG's hash), whether it is a mask, the file's
/// length and modification time, and the size a vector image is rendered at.
pub(crate) type ImageKey = (
    std::path::PathBuf,
    bool,
    u64,
    Option<std::time::SystemTime>,
    Option<[u32; 2]>,
);

/// Uploaded layer images and masks by [`ImageKey`], least recently used first.
#[derive(Default)]
pub struct ImageCache {
    entries: Vec<(ImageKey, Arc<GpuImage>, u64)>,
}

impl ImageCache {
    pub(crate) fn clear(&mut self) {
        self.entries.clear();
    }

    pub(crate) fn get(&mut self, key: &ImageKey) -> Option<Arc<GpuImage>> {
        let i = self.entries.iter().position(|e| &e.0 == key)?;
        let e = self.entries.remove(i);
        let found = e.1.clone();
        self.entries.push(e);
        Some(found)
    }

    pub(crate) fn put(&mut self, key: ImageKey, image: Arc<GpuImage>, bytes: u64) {
        self.entries.retain(|e| e.0 .0 != key.0 || e.0 .1 != key.1);
        while !self.entries.is_empty()
            && self.entries.iter().map(|e| e.2).sum::<u64>() + bytes > IMAGE_BUDGET
        {
            self.entries.remove(0);
        }
        self.entries.push((key, image, bytes));
    }

    /// Images held.
    pub fn len(&self) -> usize {
        self.entries.len()
    }
}

/// (UV set, width, height, supersampling).
pub type IslandKey = (u32, u32, u32, u32, bool);

/// A UV layout rasterized at one texture size: which texels the islands cover, and for every texel
/// the index of its nearest island texel (exact Euclidean distance transform).
pub struct Islands {
    /// On the GPU: 1 per island texel, and the index of the nearest island texel per texel
    /// ([`Islands::gpu`]).
    pub(crate) gpu: std::sync::OnceLock<[wgpu::Buffer; 2]>,
    /// Island texels.
    pub count: u64,
    /// Where the distance transform ran: `"gpu"` or `"cpu"` (`report::Paths::islands`; `"none"`
    /// for a tile's placeholder).
    pub path: &'static str,
    /// The mask and the nearest map on the CPU too, where the twin computed them: what the
    /// padding's CPU path reads (`finish::pad_and_encode`).
    pub host: Option<TiledIslands>,
}

/// Which layer rasters `job`'s layers are likely drawn by (plain: none of
/// [`crate::gpu::shaders::GENERAL_LAYER_FLAGS`]), from what the job says: a mask, a warp, a ribbon
/// (tiled images) or a stroke (tool stamps) takes the general one. A cone chart, decided while
/// baking, builds its raster when it is drawn.
fn raster_variants(job: &Job) -> Vec<bool> {
    use crate::io::job::LayerKind;
    let general = |l: &crate::io::job::Layer| {
        l.mask.is_some()
            || !l.warp.is_empty()
            || matches!(l.kind, LayerKind::Ribbon | LayerKind::Stroke)
    };
    let mut v = Vec::new();
    if job.layers.iter().any(|l| !general(l)) {
        v.push(true);
    }
    if job.layers.iter().any(general) {
        v.push(false);
    }
    v
}

/// The pipelines a bake of `job` will run, for [`Engine::prepare_for`]: those every bake runs
/// (canvas, islands, selection, raster, compose, padding and encode), placement when it has
/// layers, each layer kind's and method's, and the preview's when it writes one. A pipeline left
/// out is built when first used; one put in needlessly costs its compile on a spare core.
fn pipelines_for<'p>(engine: &'p Engine, job: &Job) -> Vec<&'p dyn Prepare> {
    use crate::io::job::{LayerKind, Method};
    let p = &engine.pipes;
    let family = p.family(engine.adaptive_sampling(job));
    let mut list: Vec<&dyn Prepare> = vec![&p.base_init, &family.island_raster];
    if !engine.stage_paths.islands_on_cpu(engine) {
        list.extend([&p.edt_columns as &dyn Prepare, &p.edt_rows]);
    }
    let wide = job.bit_depth == 16;
    // Padded on the CPU (`finish::finish`: 8 bits, whole, the twin's islands): no encode kernel.
    let pads_on_cpu = engine.stage_paths.pads_on_cpu(engine, job.bit_depth)
        && super::tile_shape(engine, job).is_none();
    if !pads_on_cpu {
        list.push(p.encode_for(false, wide));
        if job.channel_groups() & !(1 << crate::io::channels::ChannelKind::Emissive.slot()) != 0 {
            list.push(p.encode_for(true, wide));
        }
    }
    let placed_on_cpu = !engine.bvh_on_gpu() && engine.stage_paths.placement_prefers_cpu(engine);
    if !job.layers.is_empty() && !placed_on_cpu {
        list.extend([&p.place_bvh as &dyn Prepare, &p.place_reduce]);
    }
    // Where the channel groups are fused beside the colour: those the raster draws attachments
    // for, as bits (none: the colour's raster, with the fused compose).
    let fused = engine.fuses_channels(job);
    let drawn = job.drawn_channel_groups();
    let present = job.channel_groups();
    if !job.layers.is_empty() {
        list.extend([
            &p.select_triangles as &dyn Prepare,
            &p.compact_lists,
            &p.distortion,
        ]);
        let (attached, compose) = match (fused, drawn) {
            (false, _) => (0, &family.compose),
            (true, g) => (g, family.fused.compose_for(present, g)),
        };
        let clear = match attached {
            0 => &family.clear,
            g => &family.fused.clear[g as usize - 1],
        };
        list.extend([clear as &dyn Prepare, compose]);
        for plain in raster_variants(job) {
            list.push(family.raster_for(false, attached, plain));
            if !fused && job.layers.iter().any(|l| l.channels.normal.is_some()) {
                list.push(family.raster_for(true, 0, plain));
            }
        }
    }
    let any = |f: &dyn Fn(&crate::io::job::Layer) -> bool| job.layers.iter().any(f);
    if any(&|l| l.method == Method::Planar) {
        list.push(&p.planar_coords);
    }
    let maps_on_cpu = engine.stage_paths.expmap_on_cpu(engine);
    if !maps_on_cpu && any(&|l| matches!(l.method, Method::Expmap | Method::Lscm | Method::Hybrid))
    {
        list.push(&p.expmap_relax);
    }
    if any(&|l| matches!(l.method, Method::Lscm | Method::Hybrid)) {
        list.extend([&p.chart_gather as &dyn Prepare, &p.chart_scatter]);
        if !engine.stage_paths.charts_on_cpu(engine) {
            list.extend([&p.cg_batched as &dyn Prepare, &p.cg_packed_complex]);
        }
    }
    if any(&|l| l.kind == LayerKind::Stroke) {
        list.extend([&p.stroke_apply as &dyn Prepare, &p.stamp_blend]);
    }
    if any(&|l| l.kind == LayerKind::Ribbon) {
        list.push(&p.ribbon_relax);
    }
    if job.out_preview.is_some() {
        list.push(&p.preview);
    }
    list
}
