// SPDX-License-Identifier: MIT OR Apache-2.0
//! Every compute and render pipeline of the engine, created once per [`crate::Engine`], with their
//! bind-group layouts described as data (one [`Bind`] list per kernel, in WGSL binding order).

use crate::gpu::shaders;
use std::sync::atomic::{AtomicU32, AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};

/// Preferred format of the supersampled layer colour target (premultiplied, linear). Devices that
/// cannot render to it (wgpu's GL backend) use `Rgba16Float`; see [`Pipelines::layer_format`].
pub const LAYER_COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;
/// Format of the coverage targets.
pub const COVERAGE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R8Unorm;
/// Preview colour format.
pub const PREVIEW_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;

/// One binding's kind.
#[derive(Clone, Copy, Debug)]
pub enum Bind {
    /// A uniform with a dynamic offset (the bake's `Params`; a build's per-dispatch step).
    Params,
    /// A plain uniform buffer.
    Uniform,
    /// Read-only storage buffer.
    Ro,
    /// Read-write storage buffer.
    Rw,
    /// Read-write storage buffer that only the fragment stage sees (a vertex stage may not write
    /// storage without `VERTEX_WRITABLE_STORAGE`): the layer raster's block mask.
    RwFragment,
    /// Float texture; `true` = filterable.
    Tex(bool),
    /// Multisampled float texture (the adaptive raster's attachments).
    TexMs,
    /// Filtering sampler.
    Sampler,
}

fn layout(
    device: &wgpu::Device,
    label: &str,
    binds: &[(u32, Bind)],
    vis: wgpu::ShaderStages,
) -> wgpu::BindGroupLayout {
    let entries: Vec<wgpu::BindGroupLayoutEntry> = binds
        .iter()
        .map(|&(binding, kind)| {
            let buf = |ty, dynamic| wgpu::BindingType::Buffer {
                ty,
                has_dynamic_offset: dynamic,
                min_binding_size: None,
            };
            let ty = match kind {
                Bind::Params => buf(wgpu::BufferBindingType::Uniform, true),
                Bind::Uniform => buf(wgpu::BufferBindingType::Uniform, false),
                Bind::Ro => buf(wgpu::BufferBindingType::Storage { read_only: true }, false),
                Bind::Rw | Bind::RwFragment => {
                    buf(wgpu::BufferBindingType::Storage { read_only: false }, false)
                }
                Bind::Tex(filterable) => wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable },
                    view_dimension: wgpu::TextureViewDimension::D2,
                    multisampled: false,
                },
                Bind::TexMs => wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable: false },
                    view_dimension: wgpu::TextureViewDimension::D2,
                    multisampled: true,
                },
                Bind::Sampler => wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
            };
            let visibility = match kind {
                Bind::RwFragment => wgpu::ShaderStages::FRAGMENT,
                _ => vis,
            };
            wgpu::BindGroupLayoutEntry {
                binding,
                visibility,
                ty,
                count: None,
            }
        })
        .collect();
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(label),
        entries: &entries,
    })
}

/// The pipeline layout (one bind group) and shader module of kernel or pipeline `name` (or of
/// `text`, a variant of it).
fn layout_and_module(
    device: &wgpu::Device,
    name: &str,
    layout: &wgpu::BindGroupLayout,
    text: Option<String>,
) -> (wgpu::PipelineLayout, wgpu::ShaderModule) {
    let pl = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(name),
        bind_group_layouts: &[Some(layout)],
        immediate_size: 0,
    });
    let module = match text {
        Some(t) => shaders::module_from(device, name, t),
        None => shaders::module(device, name),
    };
    (pl, module)
}

/// A compute pipeline and its bind-group layout.
pub struct Kernel {
    /// The pipeline.
    pub pipeline: wgpu::ComputePipeline,
    /// Its group-0 layout.
    pub layout: wgpu::BindGroupLayout,
}

impl Kernel {
    fn new(device: &Builder, name: &str, binds: &[(u32, Bind)]) -> Self {
        Self::with_source(device, name, binds, None)
    }

    fn with_source(
        device: &Builder,
        name: &str,
        binds: &[(u32, Bind)],
        text: Option<String>,
    ) -> Self {
        let layout = layout(device, name, binds, wgpu::ShaderStages::COMPUTE);
        let (pl, module) = layout_and_module(device, name, &layout, text);
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(name),
            layout: Some(&pl),
            module: &module,
            entry_point: Some("main"),
            compilation_options: Default::default(),
            cache: device.cache(),
        });
        Self { pipeline, layout }
    }

    /// Builds a bind group from buffers/views/samplers in binding order.
    pub fn bind(
        &self,
        device: &wgpu::Device,
        label: &str,
        entries: &[(u32, wgpu::BindingResource<'_>)],
    ) -> wgpu::BindGroup {
        make_bind_group(device, &self.layout, label, entries)
    }
}

/// Builds a bind group.
pub fn make_bind_group(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    label: &str,
    entries: &[(u32, wgpu::BindingResource<'_>)],
) -> wgpu::BindGroup {
    let entries: Vec<wgpu::BindGroupEntry> = entries
        .iter()
        .map(|(binding, resource)| wgpu::BindGroupEntry {
            binding: *binding,
            resource: resource.clone(),
        })
        .collect();
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(label),
        layout,
        entries: &entries,
    })
}

/// A render pipeline and its bind-group layout.
pub struct Raster {
    /// The pipeline.
    pub pipeline: wgpu::RenderPipeline,
    /// Its group-0 layout.
    pub layout: wgpu::BindGroupLayout,
}

/// All pipelines, each built when first used (a bake compiles only what its job runs; see
/// [`Lazy`]).
pub struct Pipelines {
    /// Placement through the mesh's BVH (stage 1).
    pub place_bvh: Lazy<Kernel>,
    /// Placement stage 1, brute force (the queries the BVH walk flags, or all: the reference).
    pub place_candidates: Lazy<Kernel>,
    /// Placement stage 2.
    pub place_reduce: Lazy<Kernel>,
    /// Planar layer coordinates.
    pub planar_coords: Lazy<Kernel>,
    /// One step of the pelting dynamics (`decalbake unwrap`).
    pub pelt_step: Lazy<Kernel>,
    /// The pelting dynamics' steadiness check.
    pub pelt_check: Lazy<Kernel>,
    /// Triangle selection.
    pub select_triangles: Lazy<Kernel>,
    /// A layer's selection marks into its triangle list, in the tested order.
    pub compact_lists: Lazy<Kernel>,
    /// The layer raster family on the supersampling grid ([`Layers`]).
    pub grid: Layers,
    /// The same family at four samples a pixel (adaptive supersampling).
    pub msaa: Layers,
    /// Whether the device holds `msaa`'s targets (four samples of the layer format and of the
    /// coverage format, readable by shaders).
    pub msaa_ok: bool,
    /// Inverse rendering of the canvas into tool stamps' flat space.
    pub stamp_flatten: Lazy<Raster>,
    /// The tools' filters on the flat atlas (blur, smear).
    pub stamp_filter: Lazy<Kernel>,
    /// Texture transfer: the source texture drawn at the baked set's UVs.
    pub transfer_raster: Lazy<Raster>,
    /// Texture transfer: samples averaged into the canvas.
    pub transfer_resolve: Lazy<Kernel>,
    /// `wgsl/bake/vector_coverage.wgsl`: a flattened SVG drawn by point-sampled coverage (the
    /// alternative to resvg that `decalbake bench --vector` measures; not used by bakes).
    pub vector_coverage: Lazy<Kernel>,
    /// A finished stroke onto the canvas.
    pub stroke_apply: Lazy<Kernel>,
    /// Base fill.
    pub base_init: Lazy<Kernel>,
    /// EDT pass 1.
    pub edt_columns: Lazy<Kernel>,
    /// EDT pass 2: nearest island texel per texel.
    pub edt_rows: Lazy<Kernel>,
    /// Padding and encoding, per kind of output: index `linear * 2 + wide`
    /// ([`Pipelines::encode_for`], `shaders::encode_source`).
    pub encode: [Lazy<Kernel>; 4],
    /// Exponential-map relaxation, 64 invocations a map.
    pub expmap_relax: Lazy<Kernel>,
    /// The same, 256 invocations a map (`shaders::expmap_wide_source`): maps of many candidates.
    pub expmap_relax_wide: Lazy<Kernel>,
    /// One large exponential map over many workgroups, a dispatch a sweep
    /// (`wgsl/maps/expmap_spread.wgsl`; on a GPU adapter for lone maps of many candidates, never
    /// on a CPU adapter: `maps::expmap::gpu::SPREAD_MIN_CANDIDATES_OVERRIDE`). `None` on GL (whose
    /// maps come from the CPU twin) and where a stage binds fewer than its 14 storage buffers.
    pub expmap_spread: Lazy<Option<ExpmapSpread>>,
    /// The GPU build of the mesh's BVH (`wgsl/mesh/lbvh.wgsl`).
    pub lbvh: Lazy<Lbvh>,
    /// The extended exponential map of a curve (`wgsl/maps/ribbon_relax.wgsl`).
    pub ribbon_relax: Lazy<Kernel>,
    /// Per-layer distortion partials.
    pub distortion: Lazy<Kernel>,
    /// Batched Jacobi-preconditioned conjugate gradient, 256 invocations per system.
    pub cg_batched: Lazy<Kernel>,
    /// The same with 64 invocations per system (small systems).
    pub cg_batched_narrow: Lazy<Kernel>,
    /// `wgsl/solve/cg_packed.wgsl`: many small systems, one per invocation.
    pub cg_packed: Lazy<Kernel>,
    /// `cg_packed` on 2 × 2 complex blocks (`shaders::complex_source`): LSCM systems.
    pub cg_packed_complex: Lazy<Kernel>,
    /// `wgsl/solve/cg_amg.wgsl`: CG preconditioned by a multigrid V-cycle, 256 invocations per
    /// system (large systems).
    pub cg_amg: Option<Lazy<Kernel>>,
    /// (`None` on a device with fewer than [`AMG_STORAGE_BUFFERS`] storage buffers a stage: the
    /// solver then uses Jacobi. wgpu's GL backend binds 16, enough.)
    /// `cg_amg` on 2 × 2 complex blocks (`shaders::complex_source`): LSCM systems.
    pub cg_amg_complex: Option<Lazy<Kernel>>,
    /// `wgsl/solve/cg_wide.wgsl` and `cg_wide_plain.wgsl` on 2 × 2 complex blocks: `cg_amg`'s
    /// solve of one large LSCM system spread over many workgroups, a dispatch per pass (`None` on
    /// a device with fewer than [`WIDE_STORAGE_BUFFERS`] storage buffers a stage).
    pub cg_wide_complex: Option<[Lazy<Kernel>; 2]>,
    /// CSR sparse matrix-vector product.
    pub spmv: Lazy<Kernel>,
    /// Batched dot products and norms.
    pub dot_batched: Lazy<Kernel>,
    /// Streaming copy (bandwidth reference).
    pub copy: Lazy<Kernel>,
    /// Chart coordinates into coords slots.
    pub chart_scatter: Lazy<Kernel>,
    /// `wgsl/maps/chart_gather.wgsl`: the charts' exponential maps read where they can be valid.
    pub chart_gather: Lazy<Kernel>,
    /// Continuous stamp charts from their corners' charts.
    pub stamp_blend: Lazy<Kernel>,
    /// Preview.
    pub preview: Lazy<Raster>,
    /// `extract_raster` (`decalbake extract`), into the layer targets' format.
    pub extract_raster: Lazy<Raster>,
    /// Whether the layer target blends premultiplied source-over within a layer
    /// (needs `FLOAT32_BLENDABLE`; without it the last triangle drawn at a sample wins).
    pub layer_blending: bool,
    /// Whether `layer_raster` clips triangles to their layer's image and margin (the device has
    /// clip distances; `clip_planes` in `wgsl/bake/layer_raster.wgsl`).
    pub layer_clipped: bool,
    /// Format of the layer colour targets.
    pub layer_format: wgpu::TextureFormat,
    /// Format of decal/mask/base textures: `Rgba32Float` with `FLOAT32_FILTERABLE`, else `Rgba16Float`.
    pub image_format: wgpu::TextureFormat,
    /// What builds them (the device, the pipeline cache, the time spent).
    pub builder: Arc<Builder>,
}

impl Pipelines {
    /// Every pipeline of the engine on `builder`'s device, none of them built yet.
    ///
    /// Longer than a screen on purpose (about 160 lines): it is the table of the engine's compute
    /// kernels, one entry per kernel with its bindings in binding order (the data the style guide
    /// asks for, as vello's `add_shader!` list). Adding a kernel adds an entry here; kernels whose
    /// bindings are built rather than listed have a function of their own (`linalg_kernels`,
    /// `pelt_step`, `select_triangles`, `ribbon_relax`, `vector_coverage`, the fused channel
    /// passes' `Fused::new`...), and so do the
    /// render pipelines, which need more than a binding list. Splitting it by stage would scatter
    /// one table over several functions that each build part of one struct.
    pub fn new(builder: Arc<Builder>) -> Self {
        use Bind::*;
        let b = &builder;
        let features = b.features();
        let image_format = if features.contains(wgpu::Features::FLOAT32_FILTERABLE) {
            wgpu::TextureFormat::Rgba32Float
        } else {
            wgpu::TextureFormat::Rgba16Float
        };
        let f32_blends = features.contains(wgpu::Features::FLOAT32_BLENDABLE);
        let (layer_format, layer_blending) = layer_target(b, f32_blends);
        let clipped = features.contains(wgpu::Features::CLIP_DISTANCES);
        let kernel = |name: &'static str, binds: &'static [(u32, Bind)]| {
            Lazy::new(b, name, move |d| Kernel::new(d, name, binds))
        };
        let (linalg, cg_amg, cg_amg_complex, cg_wide_complex) = linalg_kernels(b);
        let [cg_batched, cg_batched_narrow, cg_packed, cg_packed_complex, spmv, dot_batched, copy] =
            linalg;
        Self {
            place_bvh: kernel(
                "place_bvh",
                &[
                    (0, Ro),
                    (1, Ro),
                    (2, Ro),
                    (3, Rw),
                    (4, Ro),
                    (5, Ro),
                    (6, Rw),
                ],
            ),
            place_candidates: kernel(
                "place_candidates",
                &[(0, Ro), (1, Ro), (2, Ro), (3, Rw), (4, Ro)],
            ),
            place_reduce: kernel(
                "place_reduce",
                &[(0, Ro), (1, Ro), (2, Ro), (3, Ro), (4, Ro), (5, Rw)],
            ),
            planar_coords: kernel("planar_coords", &[(0, Params), (1, Ro), (2, Rw)]),
            pelt_step: Lazy::new(b, "pelt_step", pelt_step),
            pelt_check: kernel("pelt_check", &[(0, Uniform), (1, Rw), (2, Ro)]),
            select_triangles: Lazy::new(b, "select_triangles", select_triangles),
            compact_lists: kernel("compact_lists", &[(0, Params), (1, Ro), (2, Ro), (3, Rw)]),
            grid: Layers::new(b, layer_format, layer_blending, 1),
            msaa: Layers::new(b, layer_format, layer_blending, 4),
            msaa_ok: multisampled(b, layer_format),
            stamp_flatten: Lazy::new(b, "stamp_flatten", move |d| flatten_raster(d, layer_format)),
            stamp_filter: kernel(
                "stamp_filter",
                &[
                    (0, Uniform),
                    (1, Tex(false)),
                    (2, Rw),
                    (3, Rw),
                    (4, Ro),
                    (5, Rw),
                ],
            ),
            transfer_raster: Lazy::new(b, "transfer_raster", move |d| {
                transfer_raster(d, layer_format)
            }),
            transfer_resolve: kernel(
                "transfer_resolve",
                &[
                    (0, Params),
                    (1, Tex(false)),
                    (2, Tex(false)),
                    (10, Rw),
                    (11, Rw),
                ],
            ),
            vector_coverage: Lazy::new(b, "vector_coverage", vector_coverage),
            stroke_apply: kernel(
                "stroke_apply",
                &[(0, Params), (3, Rw), (10, Rw), (11, Rw), (12, Rw), (13, Rw)],
            ),
            base_init: kernel(
                "base_init",
                &[
                    (0, Params),
                    (1, Tex(true)),
                    (2, Sampler),
                    (10, Rw),
                    (11, Rw),
                ],
            ),
            edt_columns: kernel("edt_columns", &[(0, Params), (1, Ro), (2, Rw), (3, Rw)]),
            edt_rows: kernel(
                "edt_rows",
                &[(0, Params), (1, Ro), (2, Ro), (3, Rw), (4, Rw), (5, Rw)],
            ),
            encode: std::array::from_fn(|i| {
                const NAMES: [&str; 4] =
                    ["encode", "encode_16", "encode_linear", "encode_linear_16"];
                let (name, linear, wide) = (NAMES[i], i >= 2, i % 2 == 1);
                Lazy::new(b, name, move |d| {
                    let binds = [
                        (0, Params),
                        (1, Rw),
                        (2, Ro),
                        (3, Ro),
                        (4, Ro),
                        (10, Rw),
                        (11, Rw),
                    ];
                    Kernel::with_source(d, name, &binds, Some(shaders::encode_source(linear, wide)))
                })
            }),
            distortion: kernel(
                "distortion",
                &[
                    (0, Params),
                    (1, Ro),
                    (2, Ro),
                    (3, Ro),
                    (4, Ro),
                    (5, Ro),
                    (6, Rw),
                ],
            ),
            cg_batched,
            cg_batched_narrow,
            cg_packed,
            cg_packed_complex,
            cg_amg,
            cg_amg_complex,
            cg_wide_complex,
            spmv,
            dot_batched,
            copy,
            chart_scatter: kernel("chart_scatter", &[(0, Uniform), (1, Ro), (2, Rw)]),
            chart_gather: kernel("chart_gather", &[(0, Uniform), (1, Ro), (2, Ro), (3, Rw)]),
            stamp_blend: kernel("stamp_blend", &[(0, Uniform), (1, Ro), (2, Rw), (3, Ro)]),
            expmap_relax: Lazy::new(b, "expmap_relax", |d| expmap_relax(d, None)),
            expmap_relax_wide: Lazy::new(b, "expmap_relax_wide", |d| {
                expmap_relax(d, Some(shaders::expmap_wide_source()))
            }),
            expmap_spread: Lazy::new(b, "expmap_spread", ExpmapSpread::new),
            lbvh: Lazy::new(b, "lbvh", Lbvh::new),
            ribbon_relax: Lazy::new(b, "ribbon_relax", ribbon_relax),
            preview: Lazy::new(b, "preview", preview_raster),
            extract_raster: Lazy::new(b, "extract_raster", move |d| {
                extract_raster(d, layer_format)
            }),
            layer_blending,
            layer_clipped: clipped,
            layer_format,
            image_format,
            builder,
        }
    }

    /// The padding and encoding of an output: `linear` (a data or normal channel) or sRGB, `wide`
    /// (16 bits a channel) or 8.
    pub fn encode_for(&self, linear: bool, wide: bool) -> &Lazy<Kernel> {
        &self.encode[usize::from(linear) * 2 + usize::from(wide)]
    }

    /// The layer raster family the bake draws with: at four samples a pixel where `msaa`
    /// (adaptive supersampling), else on the supersampling grid.
    pub fn family(&self, msaa: bool) -> &Layers {
        match msaa {
            false => &self.grid,
            true => &self.msaa,
        }
    }

    /// Builds the pipelines of `list` now, on every core (each on a thread of its own; a
    /// pipeline another thread is already building is waited for, never built twice).
    /// `decalbake bake` calls this with the pipelines its job will run while it reads the mesh.
    pub fn prepare(list: Vec<&dyn Prepare>) {
        std::thread::scope(|s| {
            for p in list {
                s.spawn(move || p.prepare());
            }
        });
    }
}

/// What builds the pipelines: the device and, where the backend keeps one, the pipeline cache
/// the engine loaded from disk (`gpu::cache`); it counts the time spent building. Dereferences to
/// the device.
pub struct Builder {
    device: wgpu::Device,
    cache: Option<wgpu::PipelineCache>,
    spent_us: AtomicU64,
    built: AtomicU32,
}

impl Builder {
    /// A builder on `device`, creating pipelines through `cache` when there is one.
    pub fn new(device: wgpu::Device, cache: Option<wgpu::PipelineCache>) -> Arc<Self> {
        Arc::new(Self {
            device,
            cache,
            spent_us: AtomicU64::new(0),
            built: AtomicU32::new(0),
        })
    }

    /// The pipeline cache pipelines are created through.
    pub fn cache(&self) -> Option<&wgpu::PipelineCache> {
        self.cache.as_ref()
    }

    /// Milliseconds spent building pipelines so far (summed over threads), and how many
    /// [`Lazy`] entries were built.
    pub fn spent(&self) -> (f64, u32) {
        (
            self.spent_us.load(Ordering::Relaxed) as f64 / 1000.0,
            self.built.load(Ordering::Relaxed),
        )
    }
}

impl std::ops::Deref for Builder {
    type Target = wgpu::Device;
    fn deref(&self) -> &wgpu::Device {
        &self.device
    }
}

type Make<T> = Box<dyn Fn(&Builder) -> T + Send + Sync>;

/// A pipeline (or a family of them) built on first use: it dereferences to the built value.
/// WGSL translation and the driver's compile happen then, not when the engine is created, so a
/// process that bakes one decal compiles the dozen pipelines its bake runs, not all fifty.
pub struct Lazy<T> {
    name: &'static str,
    cell: OnceLock<T>,
    builder: Arc<Builder>,
    make: Make<T>,
}

impl<T> Lazy<T> {
    fn new(
        builder: &Arc<Builder>,
        name: &'static str,
        make: impl Fn(&Builder) -> T + Send + Sync + 'static,
    ) -> Self {
        Self {
            name,
            cell: OnceLock::new(),
            builder: builder.clone(),
            make: Box::new(make),
        }
    }

    /// Whether it has been built.
    pub fn is_built(&self) -> bool {
        self.cell.get().is_some()
    }
}

impl<T> std::ops::Deref for Lazy<T> {
    type Target = T;
    fn deref(&self) -> &T {
        self.cell.get_or_init(|| {
            let start = std::time::Instant::now();
            let value = (self.make)(&self.builder);
            let us = start.elapsed().as_micros() as u64;
            self.builder.spent_us.fetch_add(us, Ordering::Relaxed);
            self.builder.built.fetch_add(1, Ordering::Relaxed);
            if std::env::var_os("DECALBAKE_DEBUG_PIPELINES").is_some() {
                eprintln!("pipeline {}: {:.1} ms", self.name, us as f64 / 1e3);
            }
            value
        })
    }
}

/// Something [`Pipelines::prepare`] can build ahead of its first use.
pub trait Prepare: Sync {
    /// Builds it if it is not built yet.
    fn prepare(&self);
}

impl<T: Send + Sync> Prepare for Lazy<T> {
    fn prepare(&self) {
        let _ = &**self;
    }
}

/// The layer targets' format and whether they blend: `Rgba32Float` where the device renders to it
/// (16-bit output stays exact), blending where it has `FLOAT32_BLENDABLE`; else `Rgba16Float`,
/// which blends (wgpu's GL backend). A 1 × 1 texture asks the device, so no pipeline is compiled
/// to find out.
fn layer_target(device: &wgpu::Device, f32_blends: bool) -> (wgpu::TextureFormat, bool) {
    let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let probe = device.create_texture(&wgpu::TextureDescriptor {
        label: Some("decalbake.layer_format_probe"),
        size: wgpu::Extent3d {
            width: 1,
            height: 1,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: LAYER_COLOR_FORMAT,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
        view_formats: &[],
    });
    let refused = pollster::block_on(scope.pop()).is_some();
    probe.destroy();
    match refused {
        false => (LAYER_COLOR_FORMAT, f32_blends),
        true => (wgpu::TextureFormat::Rgba16Float, true),
    }
}

/// `ribbon_relax`: one curve's extended exponential map, one workgroup.
fn ribbon_relax(device: &Builder) -> Kernel {
    use Bind::*;
    let mut binds = vec![(0, Uniform)];
    binds.extend([(1, Ro), (2, Rw)]);
    binds.extend((3..=7).map(|b| (b, Ro)));
    binds.extend((8..=11).map(|b| (b, Rw)));
    Kernel::new(device, "ribbon_relax", &binds)
}

/// `vector_coverage` (`bake::vector_gpu`): the uniform, six read-only arrays, the pixels written,
/// the tile grid.
fn vector_coverage(device: &Builder) -> Kernel {
    use Bind::*;
    let mut binds = vec![(0, Uniform)];
    binds.extend((1..=6).map(|b| (b, Ro)));
    binds.extend([(7, Rw), (8, Ro)]);
    Kernel::new(device, "vector_coverage", &binds)
}

/// `expmap_relax`'s bindings; `expmap_spread`'s less 9 (the rounds), with 14 (its dispatch sizes).
const EXPMAP_BINDS: [(u32, Bind); 14] = {
    use Bind::*;
    [
        (0, Ro),
        (1, Ro),
        (2, Ro),
        (3, Ro),
        (4, Ro),
        (5, Ro),
        (6, Ro),
        (7, Rw),
        (8, Rw),
        (9, Uniform),
        (10, Rw),
        (11, Rw),
        (12, Rw),
        (13, Rw),
    ]
};

/// `expmap_relax`: all exponential maps of a chunk, one workgroup per map (`text`: a variant).
fn expmap_relax(device: &Builder, text: Option<String>) -> Kernel {
    Kernel::with_source(device, "expmap_relax", &EXPMAP_BINDS, text)
}

/// The bind-group layout of kernel file `name` (several entry points on one layout) and a maker
/// of its entry points' pipelines.
fn entry_points<'d>(
    device: &'d Builder,
    name: &'d str,
    binds: &[(u32, Bind)],
) -> (
    wgpu::BindGroupLayout,
    impl Fn(&str) -> wgpu::ComputePipeline + 'd,
) {
    let layout = layout(device, name, binds, wgpu::ShaderStages::COMPUTE);
    let (pl, module) = layout_and_module(device, name, &layout, None);
    let entry = move |e: &str| {
        device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(name),
            layout: Some(&pl),
            module: &module,
            entry_point: Some(e),
            compilation_options: Default::default(),
            cache: device.cache(),
        })
    };
    (layout, entry)
}

/// `expmap_spread`'s five entry points on one bind-group layout (one bind group serves them all).
pub struct ExpmapSpread {
    /// The candidates and halo cleared.
    pub clear: wgpu::ComputePipeline,
    /// The seed triangle and the first front.
    pub seed: wgpu::ComputePipeline,
    /// One sweep over the front (indirect).
    pub sweep: wgpu::ComputePipeline,
    /// The next front made current; the next dispatches' sizes.
    pub advance: wgpu::ComputePipeline,
    /// The reached vertices counted (indirect).
    pub finish: wgpu::ComputePipeline,
    /// The group-0 layout.
    pub layout: wgpu::BindGroupLayout,
}

impl ExpmapSpread {
    fn new(device: &Builder) -> Option<Self> {
        let name = "expmap_spread";
        let mut binds: Vec<_> = EXPMAP_BINDS.into_iter().filter(|&(b, _)| b != 9).collect();
        binds.push((14, Bind::Rw));
        if device.adapter_info().backend == wgpu::Backend::Gl
            || device.limits().max_storage_buffers_per_shader_stage < binds.len() as u32
        {
            return None;
        }
        let (layout, entry) = entry_points(device, name, &binds);
        Some(Self {
            clear: entry("clear"),
            seed: entry("seed"),
            sweep: entry("sweep"),
            advance: entry("advance"),
            finish: entry("finish"),
            layout,
        })
    }
}

/// The GPU build of the mesh's BVH (`wgsl/mesh/lbvh.wgsl`, dispatched by `crate::mesh::lbvh`): six
/// entry points on one bind-group layout.
pub struct Lbvh {
    /// Morton codes of the triangles, keyed by triangle.
    pub morton: wgpu::ComputePipeline,
    /// One step of the bitonic sort of the keys.
    pub bitonic: wgpu::ComputePipeline,
    /// The radix tree's inner nodes: ranges, splits, their children's slots.
    pub karras: wgpu::ComputePipeline,
    /// The leaves at their slots.
    pub leaves: wgpu::ComputePipeline,
    /// The inner nodes at their slots, with their depths.
    pub inner: wgpu::ComputePipeline,
    /// One level of the inner nodes' boxes.
    pub boxes: wgpu::ComputePipeline,
    /// The group-0 layout.
    pub layout: wgpu::BindGroupLayout,
}

impl Lbvh {
    fn new(device: &Builder) -> Self {
        use Bind::*;
        let name = "lbvh";
        let binds = [
            (0, Ro),
            (1, Ro),
            (2, Ro),
            (3, Uniform),
            (4, Rw),
            (5, Params),
            (6, Rw),
            (7, Rw),
            (8, Rw),
        ];
        let (layout, entry) = entry_points(device, name, &binds);
        Self {
            morton: entry("morton"),
            bitonic: entry("bitonic"),
            karras: entry("karras"),
            leaves: entry("leaves"),
            inner: entry("inner"),
            boxes: entry("boxes"),
            layout,
        }
    }
}

/// `pelt_step`: one step of the pelting dynamics (`wgsl/pelt/`).
fn pelt_step(device: &Builder) -> Kernel {
    use Bind::*;
    let step: Vec<(u32, Bind)> = [(0, Uniform)]
        .into_iter()
        .chain((1..8).map(|b| (b, Ro)))
        .chain([(8, Rw), (9, Rw)])
        .collect();
    Kernel::new(device, "pelt_step", &step)
}

/// `atlas_clear`: clears the layer raster's targets inside the scissor (`samples` a pixel).
fn atlas_clear(device: &Builder, format: wgpu::TextureFormat, samples: u32) -> Raster {
    raster(
        device,
        "atlas_clear",
        None,
        layout(device, "atlas_clear", &[], wgpu::ShaderStages::VERTEX),
        &[],
        &[Some(format.into()), Some(COVERAGE_FORMAT.into())],
        None,
        samples,
    )
}

/// `compose`'s bindings.
const COMPOSE_BINDS: [(u32, Bind); 8] = [
    (0, Bind::Params),
    (1, Bind::Tex(false)),
    (2, Bind::Tex(false)),
    (3, Bind::Rw),
    (10, Bind::Rw),
    (11, Bind::Rw),
    (18, Bind::Ro),
    (19, Bind::Ro),
];

/// The layer raster family at `samples` a pixel ([`Pipelines::family`]): 1, the supersampling
/// grid; 4, adaptive supersampling, where the raster runs once a pixel and triangle (the
/// `// MSAA: ` lines of `wgsl/bake/layer_raster.wgsl`, `compose.wgsl` and `island_raster.wgsl`),
/// taken for jobs of four samples a texel where the device holds the targets
/// ([`Pipelines::msaa_ok`]; `Engine::adaptive_sampling`).
pub struct Layers {
    /// `layer_raster`.
    pub raster: Lazy<Raster>,
    /// Its normal variant (`shaders::normal_source`), same targets, three more bindings (split
    /// positions, normals, tangents).
    pub raster_normal: Lazy<Raster>,
    /// Clears the layer raster's targets inside the scissor (a job's raster rectangles).
    pub clear: Lazy<Raster>,
    /// The colour and the PBR channel groups drawn and composed in one pass ([`Fused`]).
    pub fused: Fused,
    /// The same rasters for layers with none of [`shaders::GENERAL_LAYER_FLAGS`]
    /// ([`Layers::raster_for`]).
    pub plain: PlainRasters,
    /// Layer composition.
    pub compose: Lazy<Kernel>,
    /// The islands drawn at the same samples, marking the island mask from the fragment stage.
    pub island_raster: Lazy<Raster>,
}

/// The names of [`Layers`]' pipelines (raster, normal, clear, compose, island raster) on the
/// grid, then at four samples.
const LAYERS_NAMES: [[&str; 5]; 2] = [
    [
        "layer_raster",
        "layer_raster_normal",
        "atlas_clear",
        "compose",
        "island_raster",
    ],
    [
        "layer_raster_msaa",
        "layer_raster_normal_msaa",
        "atlas_clear_msaa",
        "compose_msaa",
        "island_raster_msaa",
    ],
];

impl Layers {
    fn new(b: &Arc<Builder>, format: wgpu::TextureFormat, blending: bool, samples: u32) -> Self {
        let n = LAYERS_NAMES[usize::from(samples > 1)];
        Self {
            raster: Lazy::new(b, n[0], move |d| {
                layer_raster(d, format, blending, (false, samples, false))
            }),
            raster_normal: Lazy::new(b, n[1], move |d| {
                layer_raster(d, format, blending, (true, samples, false))
            }),
            clear: Lazy::new(b, n[2], move |d| atlas_clear(d, format, samples)),
            fused: Fused::new(b, format, blending, samples),
            plain: PlainRasters::new(b, format, blending, samples),
            compose: Lazy::new(b, n[3], move |d| {
                reading_targets(d, ("compose", n[3]), &COMPOSE_BINDS, samples)
            }),
            island_raster: Lazy::new(b, n[4], move |d| island_raster(d, samples)),
        }
    }

    /// The layer raster a unit is drawn with: the fused pass's for the channel groups
    /// `attached` (0: none), else the normal pass's where `normal`, else the colour's; the plain
    /// variant where the unit has none of [`shaders::GENERAL_LAYER_FLAGS`] (`plain`).
    pub fn raster_for(&self, normal: bool, attached: u32, plain: bool) -> &Lazy<Raster> {
        match (attached, normal, plain) {
            (0, false, false) => &self.raster,
            (0, false, true) => &self.plain.raster,
            (0, true, false) => &self.raster_normal,
            (0, true, true) => &self.plain.raster_normal,
            (b, _, false) => &self.fused.raster[b as usize - 1],
            (b, _, true) => &self.plain.fused[b as usize - 1],
        }
    }
}

/// [`Layers`]' rasters made for layers with none of [`shaders::GENERAL_LAYER_FLAGS`]
/// (`shaders::plain_layers`): the colour's, the normal pass's and the fused pass's per set of
/// channel groups (as [`Fused::raster`]).
pub struct PlainRasters {
    /// `layer_raster`, plain.
    pub raster: Lazy<Raster>,
    /// Its normal variant, plain.
    pub raster_normal: Lazy<Raster>,
    /// Its fused variants, plain.
    pub fused: [Lazy<Raster>; 7],
}

impl PlainRasters {
    fn new(b: &Arc<Builder>, format: wgpu::TextureFormat, blending: bool, samples: u32) -> Self {
        let msaa = if samples > 1 { "_msaa" } else { "" };
        Self {
            raster: Lazy::new(b, plain_name(&format!("layer_raster{msaa}")), move |d| {
                layer_raster(d, format, blending, (false, samples, true))
            }),
            raster_normal: Lazy::new(
                b,
                plain_name(&format!("layer_raster_normal{msaa}")),
                move |d| layer_raster(d, format, blending, (true, samples, true)),
            ),
            fused: std::array::from_fn(|k| {
                let bits = k as u32 + 1;
                let name = plain_name(&format!("layer_raster_fused{msaa}_{bits}"));
                Lazy::new(b, name, move |d| {
                    fused_raster(d, format, blending, (bits, samples, true))
                })
            }),
        }
    }
}

/// The plain variant's pipeline name of the layer raster `name`.
fn plain_name(name: &str) -> &'static str {
    kept_name(format!("{name}_plain"))
}

/// A pipeline name made at run time (a specialised variant's), kept for the process: each
/// distinct name is stored once, however many engines ask for it.
fn kept_name(name: String) -> &'static str {
    static NAMES: std::sync::Mutex<Vec<&'static str>> = std::sync::Mutex::new(Vec::new());
    let mut names = NAMES.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(n) = names.iter().find(|n| **n == name) {
        return n;
    }
    let n: &'static str = Box::leak(name.into_boxed_str());
    names.push(n);
    n
}

/// Kernel `name` (labelled `label`) that reads raster targets of `samples` a pixel: as written on
/// the grid; at four samples its adaptive variant, every texture multisampled.
fn reading_targets(
    d: &Builder,
    (name, label): (&str, &str),
    binds: &[(u32, Bind)],
    samples: u32,
) -> Kernel {
    match samples {
        1 => Kernel::new(d, label, binds),
        _ => {
            let text = shaders::msaa_kernel_source(name, false);
            Kernel::with_source(d, label, &multisampled_binds(binds), Some(text))
        }
    }
}

/// `binds` with every texture multisampled.
fn multisampled_binds(binds: &[(u32, Bind)]) -> Vec<(u32, Bind)> {
    binds
        .iter()
        .map(|&(k, b)| match b {
            Bind::Tex(_) => (k, Bind::TexMs),
            b => (k, b),
        })
        .collect()
}

/// Whether the device renders four samples a pixel into `format` and `COVERAGE_FORMAT` targets
/// that shaders read (`Rgba32Float` needs the adapter's own format features), asked with 1 × 1
/// textures as [`layer_target`] does.
fn multisampled(device: &wgpu::Device, format: wgpu::TextureFormat) -> bool {
    let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let probes = [format, COVERAGE_FORMAT].map(|f| {
        device.create_texture(&wgpu::TextureDescriptor {
            label: Some("decalbake.multisample_probe"),
            size: wgpu::Extent3d {
                width: 1,
                height: 1,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 4,
            dimension: wgpu::TextureDimension::D2,
            format: f,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        })
    });
    let refused = pollster::block_on(scope.pop()).is_some();
    for p in probes {
        p.destroy();
    }
    !refused
}

/// The fused channel passes' pipelines (`bake/compose.rs`): per set of PBR channel groups (bit 0
/// occlusion-roughness-metallic, 1 normal, 2 emissive; index = bits - 1), `layer_raster`'s fused
/// variant into the colour, coverage and those groups' attachments (2, 3, 4; the others `None`)
/// and the clear of the same attachments; and `compose`'s fused variant.
pub struct Fused {
    /// `layer_raster`'s fused variant (`shaders::fused_source`).
    pub raster: [Lazy<Raster>; 7],
    /// `atlas_clear`'s fused variant.
    pub clear: [Lazy<Raster>; 7],
    /// `compose`'s fused variant (`shaders::fused_kernel_source`) per pass: index
    /// `present * 8 + attached` ([`Fused::compose_for`]; `shaders::with_groups`).
    pub compose: [Lazy<Kernel>; 64],
}

/// Names of the fused pipelines per set of channel groups (then the same at four samples).
const FUSED_RASTER: [&str; 14] = [
    "layer_raster_fused_1",
    "layer_raster_fused_2",
    "layer_raster_fused_3",
    "layer_raster_fused_4",
    "layer_raster_fused_5",
    "layer_raster_fused_6",
    "layer_raster_fused_7",
    "layer_raster_fused_msaa_1",
    "layer_raster_fused_msaa_2",
    "layer_raster_fused_msaa_3",
    "layer_raster_fused_msaa_4",
    "layer_raster_fused_msaa_5",
    "layer_raster_fused_msaa_6",
    "layer_raster_fused_msaa_7",
];
/// See [`FUSED_RASTER`].
const FUSED_CLEAR: [&str; 14] = [
    "atlas_clear_fused_1",
    "atlas_clear_fused_2",
    "atlas_clear_fused_3",
    "atlas_clear_fused_4",
    "atlas_clear_fused_5",
    "atlas_clear_fused_6",
    "atlas_clear_fused_7",
    "atlas_clear_fused_msaa_1",
    "atlas_clear_fused_msaa_2",
    "atlas_clear_fused_msaa_3",
    "atlas_clear_fused_msaa_4",
    "atlas_clear_fused_msaa_5",
    "atlas_clear_fused_msaa_6",
    "atlas_clear_fused_msaa_7",
];

impl Fused {
    /// The family at `samples` a pixel (1, or 4: adaptive supersampling, [`Layers`]).
    fn new(b: &Arc<Builder>, format: wgpu::TextureFormat, blending: bool, samples: u32) -> Self {
        let named = move |k: usize| k + if samples > 1 { 7 } else { 0 };
        Self {
            raster: std::array::from_fn(|k| {
                let bits = k as u32 + 1;
                Lazy::new(b, FUSED_RASTER[named(k)], move |d| {
                    fused_raster(d, format, blending, (bits, samples, false))
                })
            }),
            clear: std::array::from_fn(|k| {
                let bits = k as u32 + 1;
                Lazy::new(b, FUSED_CLEAR[named(k)], move |d| {
                    fused_clear(d, format, (bits, samples))
                })
            }),
            compose: std::array::from_fn(|i| {
                let (present, attached) = (i as u32 / 8, i as u32 % 8);
                let name = fused_compose_name(samples, present, attached);
                Lazy::new(b, name, move |d| {
                    fused_compose(d, name, samples, (present, attached))
                })
            }),
        }
    }

    /// The fused compose of a pass whose channel groups are `present` (bits, as [`Fused`]'s),
    /// of which the raster drew attachments for `attached` (0: every group derived from the
    /// colour, `bake::compose`).
    pub fn compose_for(&self, present: u32, attached: u32) -> &Lazy<Kernel> {
        assert!(
            attached & !present == 0 && (1..8).contains(&present),
            "channel groups {present:#b}, attached {attached:#b}"
        );
        &self.compose[(present * 8 + attached) as usize]
    }

    /// Whether `limits` hold the fused passes: five colour attachments of `format`, twelve
    /// storage buffers a stage (the fused raster's fragment stage binds twelve, its compose
    /// eleven) and five textures.
    pub fn fits(limits: &wgpu::Limits, format: wgpu::TextureFormat) -> bool {
        let bytes = format.target_pixel_byte_cost().unwrap_or(u32::MAX);
        limits.max_color_attachments >= 5
            && limits.max_color_attachment_bytes_per_sample >= bytes.saturating_mul(4) + 4
            && limits.max_storage_buffers_per_shader_stage >= 12
            && limits.max_sampled_textures_per_shader_stage >= 5
    }
}

/// The colour targets of a fused pass for the channel groups `bits`: colour, coverage, then each
/// group's attachment or `None`. `blend`: the colour and channel targets' blend; `coverage`: the
/// coverage target's (the clear's overwrites it).
fn fused_targets(
    format: wgpu::TextureFormat,
    (blend, coverage): (Option<wgpu::BlendState>, wgpu::ColorTargetState),
    bits: u32,
) -> Vec<Option<wgpu::ColorTargetState>> {
    let colour = wgpu::ColorTargetState {
        format,
        blend,
        write_mask: wgpu::ColorWrites::ALL,
    };
    let mut targets: Vec<_> = [Some(colour.clone()), Some(coverage)]
        .into_iter()
        .chain((0..3).map(|k| (bits >> k & 1 == 1).then(|| colour.clone())))
        .collect();
    // None after the last group's (a render pass has as many attachments as its pipelines).
    while targets.last().is_some_and(Option::is_none) {
        targets.pop();
    }
    targets
}

/// The fused compose's pipeline name for groups `present`, `attached` at `samples` a pixel.
fn fused_compose_name(samples: u32, present: u32, attached: u32) -> &'static str {
    let msaa = if samples > 1 { "_msaa" } else { "" };
    kept_name(format!("compose_fused{msaa}_{present}_{attached}"))
}

/// `compose`'s fused variant for the channel groups `present`, `attached` (see [`Fused`]).
fn fused_compose(d: &Builder, name: &str, samples: u32, (present, attached): (u32, u32)) -> Kernel {
    use Bind::*;
    // The colour compose's bindings, the attachments of the three groups and their canvases' two
    // planes each.
    let binds: Vec<(u32, Bind)> = COMPOSE_BINDS
        .into_iter()
        .chain([(4, Tex(false)), (5, Tex(false)), (6, Tex(false))])
        .chain((12..18).map(|b| (b, Rw)))
        .collect();
    let (text, binds) = match samples {
        1 => (shaders::fused_kernel_source("compose"), binds),
        _ => (
            shaders::msaa_kernel_source("compose", true),
            multisampled_binds(&binds),
        ),
    };
    let text = shaders::with_groups(text, present, attached);
    Kernel::with_source(d, name, &binds, Some(text))
}

/// `atlas_clear`'s fused variant for the channel groups `bits`, at `samples` a pixel.
fn fused_clear(
    device: &Builder,
    format: wgpu::TextureFormat,
    (bits, samples): (u32, u32),
) -> Raster {
    let name = FUSED_CLEAR[bits as usize - 1 + if samples > 1 { 7 } else { 0 }];
    raster(
        device,
        name,
        Some(shaders::fused_kernel_source("atlas_clear")),
        layout(device, name, &[], wgpu::ShaderStages::VERTEX),
        &[],
        &fused_targets(format, (None, COVERAGE_FORMAT.into()), bits),
        None,
        samples,
    )
}

/// `layer_raster`'s fused variant for the channel groups `bits` at `samples` a pixel (see
/// [`Fused`]).
fn fused_raster(
    device: &Builder,
    format: wgpu::TextureFormat,
    blending: bool,
    (bits, samples, plain): (u32, u32, bool),
) -> Raster {
    use Bind::*;
    let binds: Vec<(u32, Bind)> = raster_binds()
        .chain(FRAME_BINDS)
        .chain([(14, Tex(true)), (15, Tex(true)), (16, Tex(true))])
        .collect();
    let name = FUSED_RASTER[bits as usize - 1 + if samples > 1 { 7 } else { 0 }];
    let name = if plain { plain_name(name) } else { name };
    let layer_layout = layout(device, name, &binds, wgpu::ShaderStages::VERTEX_FRAGMENT);
    let clipped = device.features().contains(wgpu::Features::CLIP_DISTANCES);
    let text = shaders::with_groups(shaders::fused_source(clipped), bits, bits);
    let text = if plain {
        shaders::plain_layers(text)
    } else {
        text
    };
    raster(
        device,
        name,
        Some(if samples > 1 {
            shaders::msaa_source(text)
        } else {
            text
        }),
        layer_layout,
        &[],
        &fused_targets(
            format,
            (blending.then_some(PREMULT_OVER), coverage_target()),
            bits,
        ),
        None,
        samples,
    )
}

/// The layer raster's coverage target: the largest value written stays (a sample drawn both
/// inside and outside its layer's image reads as inside; `COVERED_OUTSIDE` in
/// `wgsl/bake/layer_raster.wgsl`).
fn coverage_target() -> wgpu::ColorTargetState {
    let max = wgpu::BlendComponent {
        src_factor: wgpu::BlendFactor::One,
        dst_factor: wgpu::BlendFactor::One,
        operation: wgpu::BlendOperation::Max,
    };
    wgpu::ColorTargetState {
        format: COVERAGE_FORMAT,
        blend: Some(wgpu::BlendState {
            color: max,
            alpha: max,
        }),
        write_mask: wgpu::ColorWrites::ALL,
    }
}

/// Premultiplied source-over: what the layer raster's colour targets blend by where they blend.
const PREMULT_OVER: wgpu::BlendState = wgpu::BlendState {
    color: wgpu::BlendComponent {
        src_factor: wgpu::BlendFactor::One,
        dst_factor: wgpu::BlendFactor::OneMinusSrcAlpha,
        operation: wgpu::BlendOperation::Add,
    },
    alpha: wgpu::BlendComponent {
        src_factor: wgpu::BlendFactor::One,
        dst_factor: wgpu::BlendFactor::OneMinusSrcAlpha,
        operation: wgpu::BlendOperation::Add,
    },
};

/// Bindings the layer raster and the tools' inverse raster share: `Params`, triangle lists, split
/// triangles, UVs, welded ids, coordinates.
const UNIT_BINDS: [(u32, Bind); 6] = [
    (0, Bind::Params),
    (1, Bind::Ro),
    (2, Bind::Ro),
    (3, Bind::Ro),
    (4, Bind::Ro),
    (5, Bind::Ro),
];

/// The normal and fused layer rasters' mesh frames: split positions, normals, tangents.
const FRAME_BINDS: [(u32, Bind); 3] = [(11, Bind::Ro), (12, Bind::Ro), (13, Bind::Ro)];

/// Every layer raster variant's bindings: [`UNIT_BINDS`], image, mask, sampler, the tool stamps'
/// flats, the warps, the channel draws and the compose's block mask.
fn raster_binds() -> impl Iterator<Item = (u32, Bind)> {
    use Bind::*;
    UNIT_BINDS.into_iter().chain([
        (6, Tex(true)),
        (7, Tex(true)),
        (8, Sampler),
        (9, Ro),
        (10, Ro),
        (17, Ro),
        (18, RwFragment),
    ])
}

/// `layer_raster` into `format` targets (see [`layer_target`]) of `samples` a pixel (4: its
/// adaptive variant, `shaders::msaa_source`), blending premultiplied source-over where
/// `blending`. `normal`: its normal variant (`shaders::normal_source`).
fn layer_raster(
    device: &Builder,
    format: wgpu::TextureFormat,
    blending: bool,
    (normal, samples, plain): (bool, u32, bool),
) -> Raster {
    let extra: &[(u32, Bind)] = if normal { &FRAME_BINDS } else { &[] };
    let binds: Vec<(u32, Bind)> = raster_binds().chain(extra.iter().copied()).collect();
    let name = match (normal, samples > 1) {
        (false, false) => "layer_raster",
        (true, false) => "layer_raster_normal",
        (false, true) => "layer_raster_msaa",
        (true, true) => "layer_raster_normal_msaa",
    };
    let name = if plain { plain_name(name) } else { name };
    let layer_layout = layout(device, name, &binds, wgpu::ShaderStages::VERTEX_FRAGMENT);
    // Triangles clipped to their layer's image and a margin where the device clips
    // (`clip_planes` in the shader); GL without the extension draws them whole.
    let clipped = device.features().contains(wgpu::Features::CLIP_DISTANCES);
    let text = match normal {
        true => Some(shaders::normal_source(clipped)),
        false => clipped.then(|| shaders::clipped_source("layer_raster")),
    };
    let text = match plain {
        true => Some(shaders::plain_layers(
            text.unwrap_or_else(|| shaders::source("layer_raster")),
        )),
        false => text,
    };
    let text = match samples {
        1 => text,
        _ => Some(shaders::msaa_source(
            text.unwrap_or_else(|| shaders::source("layer_raster")),
        )),
    };
    raster(
        device,
        name,
        text,
        layer_layout,
        &[],
        &[
            Some(wgpu::ColorTargetState {
                format,
                blend: blending.then_some(PREMULT_OVER),
                write_mask: wgpu::ColorWrites::ALL,
            }),
            Some(coverage_target()),
        ],
        None,
        samples,
    )
}

/// `stamp_flatten`: the canvas drawn into tool stamps' flat cells, in the layer targets' format.
fn flatten_raster(device: &Builder, format: wgpu::TextureFormat) -> Raster {
    let binds: Vec<(u32, Bind)> = UNIT_BINDS
        .into_iter()
        .chain([(10, Bind::Ro), (11, Bind::Ro)])
        .collect();
    let vf = wgpu::ShaderStages::VERTEX_FRAGMENT;
    let flatten_layout = layout(device, "stamp_flatten", &binds, vf);
    raster(
        device,
        "stamp_flatten",
        None,
        flatten_layout,
        &[],
        &[Some(format.into())],
        None,
        1,
    )
}

/// `island_raster` into a coverage target of `samples` a pixel (its `// MSAA: ` line live at
/// four), writing the island mask from the fragment stage.
fn island_raster(device: &Builder, samples: u32) -> Raster {
    use Bind::*;
    let vf = wgpu::ShaderStages::VERTEX_FRAGMENT;
    let island_layout = layout(
        device,
        "island_raster",
        &[(0, Params), (1, Ro), (2, Ro), (3, Ro), (4, RwFragment)],
        vf,
    );
    let text = (samples > 1).then(|| shaders::msaa_source(shaders::source("island_raster")));
    raster(
        device,
        "island_raster",
        text,
        island_layout,
        &[],
        &[Some(COVERAGE_FORMAT.into())],
        None,
        samples,
    )
}

/// `transfer_raster`: the source texture at the baked set's samples, into the layer format
/// (no blending: a valid layout covers each sample once) and the coverage format.
fn transfer_raster(device: &Builder, format: wgpu::TextureFormat) -> Raster {
    use Bind::*;
    let binds = [
        (0, Params),
        (1, Ro),
        (2, Ro),
        (3, Ro),
        (4, Ro),
        (5, Tex(true)),
        (6, Sampler),
    ];
    let l = layout(
        device,
        "transfer_raster",
        &binds,
        wgpu::ShaderStages::VERTEX_FRAGMENT,
    );
    raster(
        device,
        "transfer_raster",
        None,
        l,
        &[],
        &[Some(format.into()), Some(COVERAGE_FORMAT.into())],
        None,
        1,
    )
}

/// `extract_raster`: a texture drawn along a layer's map into a flat image (`decalbake extract`).
fn extract_raster(device: &Builder, format: wgpu::TextureFormat) -> Raster {
    use Bind::*;
    let l = layout(
        device,
        "extract_raster",
        &[(0, Ro), (1, Tex(true)), (2, Sampler)],
        wgpu::ShaderStages::VERTEX_FRAGMENT,
    );
    raster(
        device,
        "extract_raster",
        None,
        l,
        &[],
        &[Some(format.into())],
        None,
        1,
    )
}

/// `preview`: the textured model, depth-tested, 4× MSAA; the colour textures (1, 3, 4), the
/// normal map, ORM and emissive (5, 6, 7); vertex buffers position, normal, three UVs, the
/// blend weights and the tangent (6, `vec4`).
fn preview_raster(device: &Builder) -> Raster {
    use Bind::*;
    let vf = wgpu::ShaderStages::VERTEX_FRAGMENT;
    let preview_layout = layout(
        device,
        "preview",
        &[
            (0, Uniform),
            (1, Tex(true)),
            (2, Sampler),
            (3, Tex(true)),
            (4, Tex(true)),
            (5, Tex(true)),
            (6, Tex(true)),
            (7, Tex(true)),
        ],
        vf,
    );
    let vb = |loc: u32, fmt: wgpu::VertexFormat| -> Vec<wgpu::VertexAttribute> {
        vec![wgpu::VertexAttribute {
            format: fmt,
            offset: 0,
            shader_location: loc,
        }]
    };
    let a0 = vb(0, wgpu::VertexFormat::Float32x3);
    let a1 = vb(1, wgpu::VertexFormat::Float32x3);
    let a2 = vb(2, wgpu::VertexFormat::Float32x2);
    let a3 = vb(3, wgpu::VertexFormat::Float32x2);
    let a4 = vb(4, wgpu::VertexFormat::Float32x2);
    let a5 = vb(5, wgpu::VertexFormat::Float32x2);
    let a6 = vb(6, wgpu::VertexFormat::Float32x4);
    let buffers = [
        Some(wgpu::VertexBufferLayout {
            array_stride: 12,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &a0,
        }),
        Some(wgpu::VertexBufferLayout {
            array_stride: 12,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &a1,
        }),
        Some(wgpu::VertexBufferLayout {
            array_stride: 8,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &a2,
        }),
        Some(wgpu::VertexBufferLayout {
            array_stride: 8,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &a3,
        }),
        Some(wgpu::VertexBufferLayout {
            array_stride: 8,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &a4,
        }),
        Some(wgpu::VertexBufferLayout {
            array_stride: 8,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &a5,
        }),
        Some(wgpu::VertexBufferLayout {
            array_stride: 16,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &a6,
        }),
    ];
    raster(
        device,
        "preview",
        None,
        preview_layout,
        &buffers,
        &[Some(PREVIEW_FORMAT.into())],
        Some(wgpu::DepthStencilState {
            format: wgpu::TextureFormat::Depth32Float,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::Less),
            stencil: Default::default(),
            bias: Default::default(),
        }),
        4,
    )
}

/// A render pipeline `name` (from `text`, a variant of its source, or its own: `None`) and its
/// layout.
#[allow(clippy::too_many_arguments)]
fn raster(
    device: &Builder,
    name: &str,
    text: Option<String>,
    layout: wgpu::BindGroupLayout,
    buffers: &[Option<wgpu::VertexBufferLayout<'_>>],
    targets: &[Option<wgpu::ColorTargetState>],
    depth: Option<wgpu::DepthStencilState>,
    samples: u32,
) -> Raster {
    let (pl, module) = layout_and_module(device, name, &layout, text);
    let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(name),
        layout: Some(&pl),
        vertex: wgpu::VertexState {
            module: &module,
            entry_point: Some("vs_main"),
            compilation_options: Default::default(),
            buffers,
        },
        primitive: wgpu::PrimitiveState {
            cull_mode: None,
            ..Default::default()
        },
        depth_stencil: depth,
        multisample: wgpu::MultisampleState {
            count: samples,
            ..Default::default()
        },
        fragment: Some(wgpu::FragmentState {
            module: &module,
            entry_point: Some("fs_main"),
            compilation_options: Default::default(),
            targets,
        }),
        multiview_mask: None,
        cache: device.cache(),
    });
    Raster { pipeline, layout }
}

/// The conjugate gradient's bindings, shared by its variants.
const CG_BINDS: [(u32, Bind); 11] = {
    use Bind::*;
    [
        (0, Uniform),
        (1, Ro),
        (2, Ro),
        (3, Ro),
        (5, Ro),
        (6, Ro),
        (7, Rw),
        (8, Rw),
        (9, Rw),
        (10, Rw),
        (11, Rw),
    ]
};

/// `cg_amg`'s bindings: the conjugate gradient's and the hierarchy's.
fn amg_binds() -> Vec<(u32, Bind)> {
    use Bind::*;
    [
        CG_BINDS.as_slice(),
        &[(12, Ro), (13, Ro), (15, Ro), (16, Ro), (17, Rw)],
    ]
    .concat()
}

/// `cg_wide`'s bindings: `cg_amg`'s, its pass selector in binding 0, and the partial sums.
fn wide_binds() -> Vec<(u32, Bind)> {
    [amg_binds().as_slice(), &[(18, Bind::Rw)]]
        .concat()
        .into_iter()
        .map(|(i, b)| if i == 0 { (0, Bind::Ro) } else { (i, b) })
        .collect()
}

/// `name` on 2 × 2 complex blocks with 64 invocations a workgroup (`shaders::narrow_source`'s
/// width): on lavapipe a workgroup's launch costs in proportion to its invocations.
fn narrow_complex(name: &str) -> String {
    let text = shaders::complex_source(name);
    shaders::with_workgroup(name, text, shaders::LINALG_WG, shaders::LINALG_WG_NARROW)
}

/// The linear-algebra kernels (`wgsl/solve/`), in the order of their `Pipelines` fields: the
/// conjugate gradient's four variants (one workgroup per system, 256 and 64 wide; one system per
/// invocation, real and on complex blocks), which share one binding list, then SpMV, batched dot
/// products and the streaming copy; the multigrid-preconditioned one, real and on complex blocks
/// (that list plus the hierarchy's), and the wide one, where the device binds that many storage
/// buffers.
#[allow(clippy::type_complexity)]
fn linalg_kernels(
    b: &Arc<Builder>,
) -> (
    [Lazy<Kernel>; 7],
    Option<Lazy<Kernel>>,
    Option<Lazy<Kernel>>,
    Option<[Lazy<Kernel>; 2]>,
) {
    use Bind::*;
    let limit = b.limits().max_storage_buffers_per_shader_stage;
    let amg = limit >= AMG_STORAGE_BUFFERS;
    let wide = limit >= WIDE_STORAGE_BUFFERS;
    let cg = |name: &'static str, text: Option<fn(&str) -> String>| {
        Lazy::new(b, name, move |d| {
            Kernel::with_source(d, name, &CG_BINDS, text.map(|t| t(name)))
        })
    };
    let kernels = [
        cg("cg_batched", None),
        cg("cg_batched", Some(shaders::narrow_source)),
        cg("cg_packed", None),
        cg("cg_packed", Some(shaders::complex_source)),
        Lazy::new(b, "spmv", |d| {
            Kernel::new(
                d,
                "spmv",
                &[(0, Uniform), (1, Ro), (2, Ro), (4, Ro), (5, Rw)],
            )
        }),
        Lazy::new(b, "dot_batched", |d| {
            Kernel::new(d, "dot_batched", &[(0, Ro), (1, Ro), (2, Ro), (3, Rw)])
        }),
        Lazy::new(b, "copy", |d| {
            Kernel::new(d, "copy", &[(0, Uniform), (1, Ro), (2, Rw)])
        }),
    ];
    let cg_amg = amg.then(|| Lazy::new(b, "cg_amg", |d| Kernel::new(d, "cg_amg", &amg_binds())));
    let cg_amg_complex = amg.then(|| {
        Lazy::new(b, "cg_amg_complex", |d| {
            let text = shaders::complex_source("cg_amg");
            Kernel::with_source(d, "cg_amg", &amg_binds(), Some(text))
        })
    });
    let wide_kernel = |name: &'static str| {
        Lazy::new(b, name, move |d| {
            Kernel::with_source(d, name, &wide_binds(), Some(narrow_complex(name)))
        })
    };
    let cg_wide = wide.then(|| [wide_kernel("cg_wide"), wide_kernel("cg_wide_plain")]);
    (kernels, cg_amg, cg_amg_complex, cg_wide)
}

/// Storage buffers `cg_amg.wgsl` binds (the CG's 10 and the hierarchy's 5).
pub const AMG_STORAGE_BUFFERS: u32 = 15;

/// Storage buffers `cg_wide.wgsl` binds (`cg_amg`'s, its pass selector in binding 0 instead of a
/// uniform, and the partial sums).
pub const WIDE_STORAGE_BUFFERS: u32 = 17;

/// `select_triangles`: marks a layer's covered triangles (`compact_lists` gathers the marks into
/// its list in triangle order).
fn select_triangles(device: &Builder) -> Kernel {
    use Bind::*;
    let mut select = vec![(0, Params)];
    select.extend((1..=5).map(|b| (b, Ro)));
    select.extend([(6, Rw), (7, Rw), (8, Ro), (9, Ro)]);
    Kernel::new(device, "select_triangles", &select)
}
