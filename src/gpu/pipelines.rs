// SPDX-License-Identifier: MIT OR Apache-2.0
//! Every compute and render pipeline of the engine, created once per [`crate::Engine`], with their
//! bind-group layouts described as data (one [`Bind`] list per kernel, in WGSL binding order).

use crate::gpu::shaders;

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
    /// Float texture; `true` = filterable.
    Tex(bool),
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
                Bind::Rw => buf(wgpu::BufferBindingType::Storage { read_only: false }, false),
                Bind::Tex(filterable) => wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable },
                    view_dimension: wgpu::TextureViewDimension::D2,
                    multisampled: false,
                },
                Bind::Sampler => wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
            };
            wgpu::BindGroupLayoutEntry {
                binding,
                visibility: vis,
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
    fn new(device: &wgpu::Device, name: &str, binds: &[(u32, Bind)]) -> Self {
        Self::with_source(device, name, binds, None)
    }

    fn with_source(
        device: &wgpu::Device,
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
            cache: None,
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

/// All pipelines.
pub struct Pipelines {
    /// Placement through the mesh's BVH (stage 1).
    pub place_bvh: Kernel,
    /// Placement stage 1, brute force (the queries the BVH walk flags, or all: the reference).
    pub place_candidates: Kernel,
    /// Placement stage 2.
    pub place_reduce: Kernel,
    /// Planar layer coordinates.
    pub planar_coords: Kernel,
    /// One step of the pelting dynamics (`decalbake unwrap`).
    pub pelt_step: Kernel,
    /// The pelting dynamics' steadiness check.
    pub pelt_check: Kernel,
    /// Triangle selection.
    pub select_triangles: Kernel,
    /// A layer's selection marks into its triangle list, in the tested order.
    pub compact_lists: Kernel,
    /// Layer raster.
    pub layer_raster: Raster,
    /// `layer_raster`'s normal variant (`shaders::normal_source`), same targets, three more
    /// bindings (split positions, normals, tangents); built on first use
    /// ([`Pipelines::layer_raster_normal`]).
    layer_raster_normal: std::sync::OnceLock<Raster>,
    /// Clears the layer raster's targets inside the scissor (a tile's raster rectangles).
    pub atlas_clear: Raster,
    /// Inverse rendering of the canvas into tool stamps' flat space.
    pub stamp_flatten: Raster,
    /// The tools' filters on the flat atlas (blur, smear).
    pub stamp_filter: Kernel,
    /// Island raster.
    pub island_raster: Raster,
    /// Texture transfer: the source texture drawn at the baked set's UVs.
    pub transfer_raster: Raster,
    /// Texture transfer: samples averaged into the canvas.
    pub transfer_resolve: Kernel,
    /// Island mask reduction.
    pub island_mask: Kernel,
    /// Layer composition.
    pub compose: Kernel,
    /// A finished stroke onto the canvas.
    pub stroke_apply: Kernel,
    /// Base fill.
    pub base_init: Kernel,
    /// EDT pass 1.
    pub edt_columns: Kernel,
    /// EDT pass 2: nearest island texel per texel.
    pub edt_rows: Kernel,
    /// sRGB encode.
    pub encode: Kernel,
    /// Exponential-map relaxation, 64 invocations a map.
    pub expmap_relax: Kernel,
    /// The same, 256 invocations a map (`shaders::expmap_wide_source`): maps of many candidates.
    pub expmap_relax_wide: Kernel,
    /// One large exponential map over many workgroups, a dispatch a sweep
    /// (`wgsl/maps/expmap_spread.wgsl`; on a GPU adapter for lone maps of many candidates, never
    /// on a CPU adapter: `maps::expmap::gpu::SPREAD_MIN_CANDIDATES_OVERRIDE`). `None` on GL (whose
    /// maps come from the CPU twin) and where a stage binds fewer than its 14 storage buffers.
    /// Built on first use ([`Self::expmap_spread`]).
    expmap_spread: std::sync::OnceLock<Option<ExpmapSpread>>,
    /// The GPU build of the mesh's BVH (`wgsl/mesh/lbvh.wgsl`), built on first use
    /// ([`Self::lbvh`]).
    lbvh: std::sync::OnceLock<Lbvh>,
    /// The extended exponential map of a curve (`wgsl/maps/ribbon_relax.wgsl`).
    pub ribbon_relax: Kernel,
    /// Per-layer distortion partials.
    pub distortion: Kernel,
    /// Batched Jacobi-preconditioned conjugate gradient, 256 invocations per system.
    pub cg_batched: Kernel,
    /// The same with 64 invocations per system (small systems).
    pub cg_batched_narrow: Kernel,
    /// `wgsl/solve/cg_packed.wgsl`: many small systems, one per invocation.
    pub cg_packed: Kernel,
    /// `cg_packed` on 2 × 2 complex blocks (`shaders::complex_source`): LSCM systems.
    pub cg_packed_complex: Kernel,
    /// `wgsl/solve/cg_amg.wgsl`: CG preconditioned by a multigrid V-cycle, 256 invocations per
    /// system (large systems).
    pub cg_amg: Option<Kernel>,
    /// (`None` on a device with fewer than [`AMG_STORAGE_BUFFERS`] storage buffers a stage: the
    /// solver then uses Jacobi. wgpu's GL backend binds 16, enough.)
    /// `cg_amg` on 2 × 2 complex blocks (`shaders::complex_source`): LSCM systems.
    pub cg_amg_complex: Option<Kernel>,
    /// `wgsl/solve/cg_wide.wgsl` and `cg_wide_plain.wgsl` on 2 × 2 complex blocks: `cg_amg`'s
    /// solve of one large LSCM system spread over many workgroups, a dispatch per pass (`None` on
    /// a device with fewer than [`WIDE_STORAGE_BUFFERS`] storage buffers a stage).
    pub cg_wide_complex: Option<[Kernel; 2]>,
    /// CSR sparse matrix-vector product.
    pub spmv: Kernel,
    /// Batched dot products and norms.
    pub dot_batched: Kernel,
    /// Streaming copy (bandwidth reference).
    pub copy: Kernel,
    /// Chart coordinates into coords slots.
    pub chart_scatter: Kernel,
    /// `wgsl/maps/chart_gather.wgsl`: the charts' exponential maps read where they can be valid.
    pub chart_gather: Kernel,
    /// Continuous stamp charts from their corners' charts.
    pub stamp_blend: Kernel,
    /// Preview.
    pub preview: Raster,
    /// `extract_raster` (`decalbake extract`), into the layer targets' format.
    pub extract_raster: Raster,
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
}

impl Pipelines {
    /// `layer_raster`'s normal variant, built on the first call (a bake without normal decals
    /// never compiles it). Its targets are the layer raster's: the format that one got (the f16
    /// fallback blends).
    pub fn layer_raster_normal(&self, device: &wgpu::Device) -> &Raster {
        self.layer_raster_normal.get_or_init(|| {
            let blending = self.layer_blending;
            layer_raster(device, blending, true).0
        })
    }

    /// `expmap_spread`'s pipelines, built on the first call (`None` on GL and short storage
    /// limits).
    pub fn expmap_spread(&self, device: &wgpu::Device) -> Option<&ExpmapSpread> {
        self.expmap_spread
            .get_or_init(|| ExpmapSpread::new(device))
            .as_ref()
    }

    /// The GPU BVH build's pipelines (`crate::mesh::lbvh`), built on the first call.
    pub fn lbvh(&self, device: &wgpu::Device) -> &Lbvh {
        self.lbvh.get_or_init(|| Lbvh::new(device))
    }

    /// Creates every pipeline on `device`.
    ///
    /// Longer than a screen on purpose: it is the table of the engine's compute kernels, one entry
    /// per kernel with its bindings in binding order (the data the style guide asks for, as vello's
    /// `add_shader!` list). Adding a kernel adds an entry here; two families that share bindings
    /// or an owner are built by [`linalg_kernels`], [`slot_kernels`], [`place_kernels`],
    /// [`pelt_kernels`] and [`select_kernels`]. The render pipelines, which
    /// need more than a binding list, are built by [`Rasters`].
    pub fn new(device: &wgpu::Device) -> Self {
        use Bind::*;
        let features = device.features();
        let layer_blending = features.contains(wgpu::Features::FLOAT32_BLENDABLE);
        let image_format = if features.contains(wgpu::Features::FLOAT32_FILTERABLE) {
            wgpu::TextureFormat::Rgba32Float
        } else {
            wgpu::TextureFormat::Rgba16Float
        };
        let rasters = Rasters::new(device, layer_blending);
        let (
            [cg_batched, cg_batched_narrow, cg_packed, cg_packed_complex, spmv, dot_batched, copy],
            amg,
            cg_wide_complex,
        ) = linalg_kernels(device);
        let (cg_amg, cg_amg_complex) = match amg {
            Some([real, complex]) => (Some(real), Some(complex)),
            None => (None, None),
        };
        let [chart_scatter, chart_gather, stamp_blend] = slot_kernels(device);
        let [place_bvh, place_candidates, place_reduce] = place_kernels(device);
        let [pelt_step, pelt_check] = pelt_kernels(device);
        let [select_triangles, compact_lists] = select_kernels(device);
        Self {
            place_bvh,
            place_candidates,
            place_reduce,
            planar_coords: Kernel::new(device, "planar_coords", &[(0, Params), (1, Ro), (2, Rw)]),
            pelt_step,
            pelt_check,
            select_triangles,
            compact_lists,
            layer_raster: rasters.layer,
            layer_raster_normal: std::sync::OnceLock::new(),
            atlas_clear: rasters.clear,
            stamp_flatten: rasters.flatten,
            stamp_filter: Kernel::new(
                device,
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
            island_raster: rasters.island,
            transfer_raster: rasters.transfer,
            transfer_resolve: transfer_resolve(device),
            island_mask: Kernel::new(
                device,
                "island_mask",
                &[(0, Params), (1, Tex(false)), (2, Rw), (3, Rw)],
            ),
            compose: Kernel::new(
                device,
                "compose",
                &[
                    (0, Params),
                    (1, Tex(false)),
                    (2, Tex(false)),
                    (3, Rw),
                    (10, Rw),
                    (11, Rw),
                ],
            ),
            stroke_apply: Kernel::new(
                device,
                "stroke_apply",
                &[(0, Params), (3, Rw), (10, Rw), (11, Rw), (12, Rw), (13, Rw)],
            ),
            base_init: Kernel::new(
                device,
                "base_init",
                &[
                    (0, Params),
                    (1, Tex(true)),
                    (2, Sampler),
                    (10, Rw),
                    (11, Rw),
                ],
            ),
            edt_columns: Kernel::new(device, "edt_columns", &[(0, Params), (1, Ro), (2, Rw)]),
            edt_rows: Kernel::new(
                device,
                "edt_rows",
                &[(0, Params), (1, Ro), (2, Ro), (3, Rw), (4, Rw), (5, Rw)],
            ),
            encode: Kernel::new(
                device,
                "encode",
                &[(0, Params), (1, Rw), (2, Ro), (3, Ro), (10, Rw), (11, Rw)],
            ),
            distortion: Kernel::new(
                device,
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
            chart_scatter,
            chart_gather,
            stamp_blend,
            expmap_relax: expmap_relax(device, None),
            expmap_relax_wide: expmap_relax(device, Some(shaders::expmap_wide_source())),
            expmap_spread: std::sync::OnceLock::new(),
            lbvh: std::sync::OnceLock::new(),
            ribbon_relax: ribbon_relax(device),
            preview: rasters.preview,
            extract_raster: rasters.extract,
            layer_blending: rasters.layer_blending,
            layer_clipped: device.features().contains(wgpu::Features::CLIP_DISTANCES),
            layer_format: rasters.layer_format,
            image_format,
        }
    }
}

/// `ribbon_relax`: one curve's extended exponential map, one workgroup.
fn ribbon_relax(device: &wgpu::Device) -> Kernel {
    use Bind::*;
    let mut binds = vec![(0, Uniform)];
    binds.extend([(1, Ro), (2, Rw)]);
    binds.extend((3..=7).map(|b| (b, Ro)));
    binds.extend((8..=11).map(|b| (b, Rw)));
    Kernel::new(device, "ribbon_relax", &binds)
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
fn expmap_relax(device: &wgpu::Device, text: Option<String>) -> Kernel {
    Kernel::with_source(device, "expmap_relax", &EXPMAP_BINDS, text)
}

/// The bind-group layout of kernel file `name` (several entry points on one layout) and a maker
/// of its entry points' pipelines.
fn entry_points<'d>(
    device: &'d wgpu::Device,
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
            cache: None,
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
    fn new(device: &wgpu::Device) -> Option<Self> {
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
    fn new(device: &wgpu::Device) -> Self {
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

/// `transfer_resolve`: a texture transfer's samples averaged per texel into the canvas.
fn transfer_resolve(device: &wgpu::Device) -> Kernel {
    use Bind::*;
    let binds = [
        (0, Params),
        (1, Tex(false)),
        (2, Tex(false)),
        (10, Rw),
        (11, Rw),
    ];
    Kernel::new(device, "transfer_resolve", &binds)
}

/// The pelting kernels (`wgsl/pelt/`): one step of the dynamics, the steadiness check.
fn pelt_kernels(device: &wgpu::Device) -> [Kernel; 2] {
    use Bind::*;
    let step: Vec<(u32, Bind)> = [(0, Uniform)]
        .into_iter()
        .chain((1..8).map(|b| (b, Ro)))
        .chain([(8, Rw), (9, Rw)])
        .collect();
    [
        Kernel::new(device, "pelt_step", &step),
        Kernel::new(device, "pelt_check", &[(0, Uniform), (1, Rw), (2, Ro)]),
    ]
}

/// The render pipelines: the layer raster (with the format and blending it got) and its targets'
/// clear, the tools'
/// inverse raster into the same format, the island raster, the transfer raster and the preview.
struct Rasters {
    layer: Raster,
    clear: Raster,
    flatten: Raster,
    island: Raster,
    transfer: Raster,
    preview: Raster,
    extract: Raster,
    layer_format: wgpu::TextureFormat,
    layer_blending: bool,
}

impl Rasters {
    /// `layer_blending`: whether f32 targets blend on this device.
    fn new(device: &wgpu::Device, layer_blending: bool) -> Self {
        let (layer, layer_format, layer_blending) = layer_raster(device, layer_blending, false);
        let clear = raster(
            device,
            "atlas_clear",
            None,
            layout(device, "atlas_clear", &[], wgpu::ShaderStages::VERTEX),
            &[],
            &[Some(layer_format.into()), Some(COVERAGE_FORMAT.into())],
            None,
            1,
        );
        Self {
            layer,
            clear,
            flatten: flatten_raster(device, layer_format),
            island: island_raster(device),
            transfer: transfer_raster(device, layer_format),
            preview: preview_raster(device),
            extract: extract_raster(device, layer_format),
            layer_format,
            layer_blending,
        }
    }
}

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

/// `layer_raster` into f32 targets (blending premultiplied source-over where the device can), or
/// into f16 targets with blending where f32 is not renderable (GL); returns the pipeline, its
/// colour format and whether it blends. `normal`: its normal variant (`shaders::normal_source`).
fn layer_raster(
    device: &wgpu::Device,
    blending: bool,
    normal: bool,
) -> (Raster, wgpu::TextureFormat, bool) {
    use Bind::*;
    let extra: &[(u32, Bind)] = if normal {
        &[(11, Ro), (12, Ro), (13, Ro)]
    } else {
        &[]
    };
    let binds: Vec<(u32, Bind)> = UNIT_BINDS
        .into_iter()
        .chain([
            (6, Tex(true)),
            (7, Tex(true)),
            (8, Sampler),
            (9, Ro),
            (10, Ro),
        ])
        .chain(extra.iter().copied())
        .collect();
    let name = if normal {
        "layer_raster_normal"
    } else {
        "layer_raster"
    };
    let layer_layout = layout(device, name, &binds, wgpu::ShaderStages::VERTEX_FRAGMENT);
    let premult = wgpu::BlendComponent {
        src_factor: wgpu::BlendFactor::One,
        dst_factor: wgpu::BlendFactor::OneMinusSrcAlpha,
        operation: wgpu::BlendOperation::Add,
    };
    let premult_over = wgpu::BlendState {
        color: premult,
        alpha: premult,
    };
    // Triangles clipped to their layer's image and a margin where the device clips
    // (`clip_planes` in the shader); GL without the extension draws them whole.
    let clipped = device.features().contains(wgpu::Features::CLIP_DISTANCES);
    let make_layer = |format: wgpu::TextureFormat, blend: bool| {
        let text = match normal {
            true => Some(shaders::normal_source(clipped)),
            false => clipped.then(|| shaders::clipped_source("layer_raster")),
        };
        raster(
            device,
            name,
            text,
            layer_layout.clone(),
            &[],
            &[
                Some(wgpu::ColorTargetState {
                    format,
                    blend: blend.then_some(premult_over),
                    write_mask: wgpu::ColorWrites::ALL,
                }),
                Some(COVERAGE_FORMAT.into()),
            ],
            None,
            1,
        )
    };
    // f32 targets keep 16-bit output exact; where f32 is not renderable (GL), fall back to f16.
    let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let first = make_layer(LAYER_COLOR_FORMAT, blending);
    match pollster::block_on(scope.pop()) {
        None => (first, LAYER_COLOR_FORMAT, blending),
        Some(_) => {
            let f16 = wgpu::TextureFormat::Rgba16Float;
            (make_layer(f16, true), f16, true)
        }
    }
}

/// `stamp_flatten`: the canvas drawn into tool stamps' flat cells, in the layer targets' format.
fn flatten_raster(device: &wgpu::Device, format: wgpu::TextureFormat) -> Raster {
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

/// `island_raster`: island coverage at the texture's samples.
fn island_raster(device: &wgpu::Device) -> Raster {
    use Bind::*;
    let vf = wgpu::ShaderStages::VERTEX_FRAGMENT;
    let island_layout = layout(
        device,
        "island_raster",
        &[(0, Params), (1, Ro), (2, Ro), (3, Ro)],
        vf,
    );
    raster(
        device,
        "island_raster",
        None,
        island_layout,
        &[],
        &[Some(COVERAGE_FORMAT.into())],
        None,
        1,
    )
}

/// `transfer_raster`: the source texture at the baked set's samples, into the layer format
/// (no blending: a valid layout covers each sample once) and the coverage format.
fn transfer_raster(device: &wgpu::Device, format: wgpu::TextureFormat) -> Raster {
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
fn extract_raster(device: &wgpu::Device, format: wgpu::TextureFormat) -> Raster {
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
fn preview_raster(device: &wgpu::Device) -> Raster {
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
    device: &wgpu::Device,
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
        cache: None,
    });
    Raster { pipeline, layout }
}

/// The linear-algebra kernels (`wgsl/solve/`), in the order of their `Pipelines` fields: the
/// conjugate gradient's four variants (one workgroup per system, 256 and 64 wide; one system per
/// invocation, real and on complex blocks), which share one binding list, then SpMV, batched dot
/// products and the streaming copy; and the multigrid-preconditioned one, real and on complex
/// blocks (that list plus the hierarchy's), where the device binds that many storage buffers.
#[allow(clippy::type_complexity)]
fn linalg_kernels(
    device: &wgpu::Device,
) -> ([Kernel; 7], Option<[Kernel; 2]>, Option<[Kernel; 2]>) {
    use Bind::*;
    let cg = &[
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
    ];
    let variant = |name: &str, text: String| Kernel::with_source(device, name, cg, Some(text));
    let amg = [
        cg.as_slice(),
        &[(12, Ro), (13, Ro), (15, Ro), (16, Ro), (17, Rw)],
    ]
    .concat();
    let wide: Vec<(u32, Bind)> = [amg.as_slice(), &[(18, Rw)]]
        .concat()
        .into_iter()
        .map(|(i, b)| if i == 0 { (0, Ro) } else { (i, b) })
        .collect();
    let limit = device.limits().max_storage_buffers_per_shader_stage;
    // 64 invocations a workgroup (`shaders::narrow_source`'s width): on lavapipe a workgroup's
    // launch costs in proportion to its invocations.
    let narrow_complex = |name: &str| {
        let text = shaders::complex_source(name);
        shaders::with_workgroup(name, text, shaders::LINALG_WG, shaders::LINALG_WG_NARROW)
    };
    let cg_wide = (limit >= WIDE_STORAGE_BUFFERS).then(|| {
        [
            Kernel::with_source(device, "cg_wide", &wide, Some(narrow_complex("cg_wide"))),
            Kernel::with_source(
                device,
                "cg_wide_plain",
                &wide,
                Some(narrow_complex("cg_wide_plain")),
            ),
        ]
    });
    let amg = (limit >= AMG_STORAGE_BUFFERS).then(|| {
        [
            Kernel::new(device, "cg_amg", &amg),
            Kernel::with_source(
                device,
                "cg_amg",
                &amg,
                Some(shaders::complex_source("cg_amg")),
            ),
        ]
    });
    let kernels = [
        Kernel::new(device, "cg_batched", cg),
        variant("cg_batched", shaders::narrow_source("cg_batched")),
        Kernel::new(device, "cg_packed", cg),
        variant("cg_packed", shaders::complex_source("cg_packed")),
        Kernel::new(
            device,
            "spmv",
            &[(0, Uniform), (1, Ro), (2, Ro), (4, Ro), (5, Rw)],
        ),
        Kernel::new(device, "dot_batched", &[(0, Ro), (1, Ro), (2, Ro), (3, Rw)]),
        Kernel::new(device, "copy", &[(0, Uniform), (1, Ro), (2, Rw)]),
    ];
    (kernels, amg, cg_wide)
}

/// Storage buffers `cg_amg.wgsl` binds (the CG's 10 and the hierarchy's 5).
pub const AMG_STORAGE_BUFFERS: u32 = 15;

/// Storage buffers `cg_wide.wgsl` binds (`cg_amg`'s, its pass selector in binding 0 instead of a
/// uniform, and the partial sums).
pub const WIDE_STORAGE_BUFFERS: u32 = 17;

/// The selection stage's kernels: `select_triangles` (marks a layer's covered triangles) and
/// `compact_lists` (gathers the marks into its list in triangle order).
fn select_kernels(device: &wgpu::Device) -> [Kernel; 2] {
    use Bind::*;
    let mut select = vec![(0, Params)];
    select.extend((1..=5).map(|b| (b, Ro)));
    select.extend([(6, Rw), (7, Rw), (8, Ro), (9, Ro)]);
    [
        Kernel::new(device, "select_triangles", &select),
        Kernel::new(
            device,
            "compact_lists",
            &[(0, Params), (1, Ro), (2, Ro), (3, Rw)],
        ),
    ]
}

/// The placement kernels (`src/place.rs`): `place_bvh`, `place_candidates`, `place_reduce`.
fn place_kernels(device: &wgpu::Device) -> [Kernel; 3] {
    use Bind::*;
    [
        Kernel::new(
            device,
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
        Kernel::new(
            device,
            "place_candidates",
            &[(0, Ro), (1, Ro), (2, Ro), (3, Rw), (4, Ro)],
        ),
        Kernel::new(
            device,
            "place_reduce",
            &[(0, Ro), (1, Ro), (2, Ro), (3, Ro), (4, Ro), (5, Rw)],
        ),
    ]
}

/// The kernels the bake's map stage runs on the coordinate slots it owns (`bake/maps.rs`): chart
/// coordinates written in and the exponential maps read out over their discs, and the blended
/// stamps of continuous strokes.
fn slot_kernels(device: &wgpu::Device) -> [Kernel; 3] {
    use Bind::*;
    [
        Kernel::new(device, "chart_scatter", &[(0, Uniform), (1, Ro), (2, Rw)]),
        Kernel::new(
            device,
            "chart_gather",
            &[(0, Uniform), (1, Ro), (2, Ro), (3, Rw)],
        ),
        Kernel::new(
            device,
            "stamp_blend",
            &[(0, Uniform), (1, Ro), (2, Rw), (3, Ro)],
        ),
    ]
}
