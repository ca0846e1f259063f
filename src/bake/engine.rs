// SPDX-License-Identifier: MIT OR Apache-2.0
//! The bake: layers placed, rasterized at their global UVs and composed into the texture, then
//! padding and encoding, all on the GPU.
//!
//! How it works:
//! 1. `base_init` fills a linear f32 accumulation image (two planes, see `wgsl/shared/acc.wgsl`) with
//!    the base; `island_raster` + `island_mask` mark the texels the UV islands cover (any of the
//!    ss × ss samples inside a triangle).
//! 2. All layers are placed in one submission ([`crate::place`]).
//! 3. Layers are processed in chunks sized to a memory budget. Per chunk, one submission computes each
//!    layer's local coordinates (`planar_coords`) and selects its triangles (`select_triangles`), and
//!    one small read-back returns each layer's triangle count and texel box. The box is cut into
//!    raster jobs (per integer UV tile, at most [`TILE_TARGET`] samples a side); each job draws the
//!    layer's triangles into a pooled supersampled target and `compose` blends the covered texels
//!    into the accumulation image with the layer's blend mode. Layers apply in job order.
//! 4. Padding: an exact Euclidean distance transform of the island mask (`edt_columns`,
//!    `edt_rows_fill`) gives each background texel its nearest island texel; those within `padding`
//!    (or all, for `"full"`) copy its colour.
//! 5. `encode` writes sRGB 8- or 16-bit texels; one read-back (or a copy into a host texture).

use crate::bake::params::{Params, FLAG_16BIT, FLAG_FACING, FLAG_MASK};
use crate::bake::report::{LayerReport, MeshStats, Report, Timings};
use crate::error::{Error, Result};
use crate::gpu::pipelines::{Pipelines, COVERAGE_FORMAT};
use crate::gpu::GpuContext;
use crate::io::image::LinearImage;
use crate::io::job::{Base, Job, Method, Padding};
use crate::maps::Frame;
use crate::mesh::upload::GpuMesh;
use crate::mesh::{Mesh, Topology};
use crate::place::{place_gpu, Query};
use glam::Vec3;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Instant;
use wgpu::util::DeviceExt;

/// Largest raster target side, in samples. A raster job covers at most `TILE_TARGET / ss` texels a side.
pub const TILE_TARGET: u32 = 2048;
/// Memory budget for one chunk's per-layer coordinates and triangle lists.
const CHUNK_BUDGET: u64 = 64 << 20;
/// Stride of `Params` entries in the uniform buffers (dynamic offsets need 256-byte alignment).
const PARAMS_STRIDE: u64 = 256;

/// A mesh loaded, welded and resident on the GPU.
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
    /// Statistics.
    pub stats: MeshStats,
    /// Load, weld and upload times (ms).
    pub timings: (f64, f64, f64),
    /// The material's base-colour texture on the GPU, uploaded by the first bake that uses it.
    material_texture: std::sync::OnceLock<Arc<GpuImage>>,
    /// Island masks and nearest-island maps by (UV set, width, height, supersampling).
    islands: Mutex<HashMap<IslandKey, Arc<Islands>>>,
}

/// (UV set, width, height, supersampling).
type IslandKey = (u32, u32, u32, u32);

/// A UV layout rasterized at one texture size: which texels the islands cover, and for every texel
/// the index of its nearest island texel (exact Euclidean distance transform).
struct Islands {
    mask: wgpu::Buffer,
    nearest: wgpu::Buffer,
    count: u64,
}

impl LoadedMesh {
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
    /// The report.
    pub report: Report,
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
        crate::io::image::png_bytes(self.width, self.height, self.bit_depth, &self.texels)
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
struct Targets {
    color_view: wgpu::TextureView,
    cov_view: wgpu::TextureView,
    _color: wgpu::Texture,
    _cov: wgpu::Texture,
}

/// The engine: a device, its pipelines and pooled targets. Load meshes once, bake many jobs.
pub struct Engine {
    /// The GPU context.
    pub ctx: GpuContext,
    pub(crate) pipes: Pipelines,
    targets: Mutex<HashMap<[u32; 2], Arc<Targets>>>,
    pub(crate) linear_sampler: wgpu::Sampler,
}

/// A decoded image on the GPU.
struct GpuImage {
    view: wgpu::TextureView,
    _tex: wgpu::Texture,
}

impl Engine {
    /// An engine on its own headless device (see [`GpuContext::new`]).
    pub fn new(backend: Option<&str>) -> Result<Self> {
        Self::with_context(GpuContext::new(backend)?)
    }

    /// An engine on the host's device and queue. The device must support compute shaders.
    pub fn from_device(device: wgpu::Device, queue: wgpu::Queue) -> Result<Self> {
        Self::with_context(GpuContext::from_device(device, queue, None))
    }

    /// An engine on the host's device and queue, naming the adapter they came from: the report then
    /// names it, and backend-specific workarounds (wgpu's GL backend) apply.
    pub fn from_adapter(
        adapter: &wgpu::Adapter,
        device: wgpu::Device,
        queue: wgpu::Queue,
    ) -> Result<Self> {
        Self::with_context(GpuContext::from_device(
            device,
            queue,
            Some(adapter.get_info()),
        ))
    }

    /// An engine on an existing context.
    pub fn with_context(ctx: GpuContext) -> Result<Self> {
        let pipes = ctx.scoped("pipeline creation", || Pipelines::new(&ctx.device))?;
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
            linear_sampler,
        })
    }

    /// The engine's compiled pipelines (for the linear-algebra entry points).
    pub fn pipelines(&self) -> &Pipelines {
        &self.pipes
    }

    /// Chart solves on this engine's device (batched GPU CG).
    pub fn solver(&self) -> crate::maps::chart::Solver<'_> {
        crate::maps::chart::Solver::Gpu(&self.ctx, &self.pipes)
    }

    /// Places `queries` on `mesh` on the GPU (see [`crate::place::place_gpu`]).
    pub fn place(
        &self,
        mesh: &LoadedMesh,
        queries: &[Query],
    ) -> Result<Vec<crate::place::Placement>> {
        place_gpu(&self.ctx, &self.pipes, &mesh.gpu, queries)
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

    /// Welds and uploads a mesh already in memory.
    pub fn prepare(&self, mesh: Mesh) -> Result<LoadedMesh> {
        self.prepare_mesh(mesh, Instant::now())
    }

    fn prepare_mesh(&self, mut mesh: Mesh, t0: Instant) -> Result<LoadedMesh> {
        let load = ms(t0);
        let t1 = Instant::now();
        let topo = Topology::build(&mesh, crate::mesh::DEFAULT_WELD_TOLERANCE);
        let surface = crate::mesh::SurfaceData::new(&topo);
        for (i, n) in mesh.normals.iter_mut().enumerate() {
            if *n == Vec3::ZERO {
                *n = topo.normals[topo.welded_of[i] as usize];
            }
        }
        let weld = ms(t1);
        let t2 = Instant::now();
        let gpu = self.ctx.scoped("mesh upload", || {
            GpuMesh::upload(&self.ctx.device, &mesh, &topo, &surface)
        })?;
        let upload = ms(t2);
        let stats = LoadedMesh::stats_of(&mesh, &topo);
        Ok(LoadedMesh {
            mesh,
            topo,
            surface,
            gpu,
            stats,
            timings: (load, weld, upload),
            material_texture: std::sync::OnceLock::new(),
            islands: Mutex::new(HashMap::new()),
        })
    }

    fn targets(&self, size: [u32; 2]) -> Arc<Targets> {
        let mut pool = self.targets.lock().expect("target pool poisoned");
        pool.entry(size)
            .or_insert_with(|| {
                let mk = |label: &str, format| {
                    self.ctx.device.create_texture(&wgpu::TextureDescriptor {
                        label: Some(label),
                        size: wgpu::Extent3d {
                            width: size[0],
                            height: size[1],
                            depth_or_array_layers: 1,
                        },
                        mip_level_count: 1,
                        sample_count: 1,
                        dimension: wgpu::TextureDimension::D2,
                        format,
                        usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                            | wgpu::TextureUsages::TEXTURE_BINDING,
                        view_formats: &[],
                    })
                };
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

    fn upload_image(&self, img: &LinearImage, mips: bool, label: &str) -> GpuImage {
        let levels = if mips {
            img.premultiplied_mips()
        } else {
            vec![img.clone()]
        };
        let format = self.pipes.image_format;
        let tex = self.ctx.device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d {
                width: img.width,
                height: img.height,
                depth_or_array_layers: 1,
            },
            mip_level_count: levels.len() as u32,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        });
        for (level, l) in levels.iter().enumerate() {
            let (bytes, bpp): (Vec<u8>, u32) = if format == wgpu::TextureFormat::Rgba32Float {
                (bytemuck::cast_slice(&l.pixels).to_vec(), 16)
            } else {
                let h: Vec<u16> = l.pixels.iter().flatten().map(|v| f32_to_f16(*v)).collect();
                (bytemuck::cast_slice(&h).to_vec(), 8)
            };
            self.ctx.queue.write_texture(
                wgpu::TexelCopyTextureInfo {
                    texture: &tex,
                    mip_level: level as u32,
                    origin: wgpu::Origin3d::ZERO,
                    aspect: wgpu::TextureAspect::All,
                },
                &bytes,
                wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(l.width * bpp),
                    rows_per_image: Some(l.height),
                },
                wgpu::Extent3d {
                    width: l.width,
                    height: l.height,
                    depth_or_array_layers: 1,
                },
            );
        }
        GpuImage {
            view: tex.create_view(&Default::default()),
            _tex: tex,
        }
    }

    /// Bakes `job` onto `mesh` and reads the texture back.
    pub fn bake(&self, mesh: &LoadedMesh, job: &Job) -> Result<Baked> {
        let run = self.run(mesh, job)?;
        let t = Instant::now();
        let (w, h) = (job.width, job.height);
        let bytes = self
            .ctx
            .read_buffer(&run.packed, run.packed_size, "encode read-back")?;
        let words: &[u32] = bytemuck::cast_slice(&bytes);
        let mut texels = Vec::with_capacity((w * h * 4) as usize);
        for y in 0..h {
            let row = &words[(y * run.stride) as usize..];
            if job.bit_depth == 16 {
                for &word in &row[..(2 * w) as usize] {
                    texels.push((word & 0xffff) as u16);
                    texels.push((word >> 16) as u16);
                }
            } else {
                for &word in &row[..w as usize] {
                    texels.extend(word.to_le_bytes().map(u16::from));
                }
            }
        }
        let mut report = run.report;
        report.timings.encode_ms += ms(t);
        Ok(Baked {
            width: w,
            height: h,
            bit_depth: job.bit_depth,
            texels,
            report,
        })
    }

    /// Bakes `job` onto `mesh` and returns the result as an `Rgba8UnormSrgb` texture that never leaves
    /// the GPU (usages: `TEXTURE_BINDING | COPY_SRC | COPY_DST`). The job's `bit_depth` is ignored.
    pub fn bake_to_texture(&self, mesh: &LoadedMesh, job: &Job) -> Result<(wgpu::Texture, Report)> {
        let mut job8 = job.clone();
        job8.bit_depth = 8;
        let run = self.run(mesh, &job8)?;
        let tex = self.ctx.scoped("texture output", || {
            let tex = self.ctx.device.create_texture(&wgpu::TextureDescriptor {
                label: Some("decalbake.baked"),
                size: wgpu::Extent3d {
                    width: job.width,
                    height: job.height,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: wgpu::TextureFormat::Rgba8UnormSrgb,
                usage: wgpu::TextureUsages::TEXTURE_BINDING
                    | wgpu::TextureUsages::COPY_SRC
                    | wgpu::TextureUsages::COPY_DST,
                view_formats: &[],
            });
            let mut enc = self.ctx.device.create_command_encoder(&Default::default());
            enc.copy_buffer_to_texture(
                wgpu::TexelCopyBufferInfo {
                    buffer: &run.packed,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some(run.stride * 4),
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
            self.ctx.queue.submit([enc.finish()]);
            tex
        })?;
        Ok((tex, run.report))
    }

    /// The island mask and nearest-island map of `mesh` for a UV set, texture size and sampling,
    /// computed on first use and cached on the mesh: the island raster (`island_raster`,
    /// `island_mask`) and the exact distance transform (`edt_columns`, `edt_rows`).
    fn islands(
        &self,
        mesh: &LoadedMesh,
        uv_set: u32,
        size: [u32; 2],
        ss: u32,
        commands: &mut u32,
    ) -> Result<Arc<Islands>> {
        let key = (uv_set, size[0], size[1], ss);
        if let Some(c) = mesh
            .islands
            .lock()
            .expect("island cache poisoned")
            .get(&key)
        {
            return Ok(c.clone());
        }
        let dev = &self.ctx.device;
        let pipes = &self.pipes;
        let g = &mesh.gpu;
        let uvs = &g.uvs[uv_set as usize];
        let [w, h] = size;
        let texels = w as u64 * h as u64;
        let buf = |label, bytes: u64| {
            dev.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes,
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_SRC
                    | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let mask = buf("islands.mask", texels * 4);
        let nearest = buf("islands.nearest", texels * 4);
        let counter = buf("islands.count", 16);
        let global = Params {
            tex_size: size,
            ss,
            triangle_count: g.triangle_count,
            stats_stride: 1,
            ..Default::default()
        };
        let range = uv_tile_range(&mesh.mesh.uv_sets[uv_set as usize]);
        let mut jobs = Vec::new();
        for tj in range[1]..=range[3] {
            for ti in range[0]..=range[2] {
                for rect in split_rect([0, 0, w as i32, h as i32], TILE_TARGET / ss) {
                    jobs.push(Params {
                        rect_origin: [rect[0], rect[1]],
                        rect_size: [rect[2] as u32, rect[3] as u32],
                        tile: [ti, tj],
                        ..global
                    });
                }
            }
        }
        let mut entries = vec![global];
        entries.extend(jobs.iter().copied());
        let params = params_buffer(dev, "islands.params", &entries);
        self.ctx.scoped("islands", || {
            let mut enc = dev.create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("islands"),
            });
            enc.clear_buffer(&mask, 0, None);
            enc.clear_buffer(&counter, 0, None);
            let bg_island = make_bg(
                dev,
                &pipes.island_raster.layout,
                "islands.raster",
                &[
                    (0, pbind(&params)),
                    (1, g.tris.as_entire_binding()),
                    (2, g.split_tris.as_entire_binding()),
                    (3, uvs.as_entire_binding()),
                ],
            );
            for (k, j) in jobs.iter().enumerate() {
                let off = ((k + 1) as u64 * PARAMS_STRIDE) as u32;
                let side = target_side(j.rect_size, ss);
                let tg = self.targets([side, side]);
                {
                    let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                        label: Some("islands.raster"),
                        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                            view: &tg.cov_view,
                            depth_slice: None,
                            resolve_target: None,
                            ops: wgpu::Operations {
                                load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                                store: wgpu::StoreOp::Store,
                            },
                        })],
                        depth_stencil_attachment: None,
                        timestamp_writes: None,
                        occlusion_query_set: None,
                        multiview_mask: None,
                    });
                    pass.set_pipeline(&pipes.island_raster.pipeline);
                    pass.set_bind_group(0, &bg_island, &[off]);
                    pass.set_viewport(
                        0.0,
                        0.0,
                        (j.rect_size[0] * ss) as f32,
                        (j.rect_size[1] * ss) as f32,
                        0.0,
                        1.0,
                    );
                    pass.draw(0..3 * g.triangle_count, 0..1);
                }
                let bg_mask = pipes.island_mask.bind(
                    dev,
                    "islands.mask",
                    &[
                        (0, pbind(&params)),
                        (1, wgpu::BindingResource::TextureView(&tg.cov_view)),
                        (2, mask.as_entire_binding()),
                        (3, counter.as_entire_binding()),
                    ],
                );
                let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("islands.mask"),
                    timestamp_writes: None,
                });
                pass.set_pipeline(&pipes.island_mask.pipeline);
                pass.set_bind_group(0, &bg_mask, &[off]);
                pass.dispatch_workgroups(j.rect_size[0].div_ceil(8), j.rect_size[1].div_ceil(8), 1);
                *commands += 2;
            }
            let col_near = buf("islands.edt.col_near", texels * 4);
            let env_v = buf("islands.edt.env_v", texels * 4);
            let env_z = buf("islands.edt.env_z", (w as u64 + 1) * h as u64 * 4);
            let bg_cols = pipes.edt_columns.bind(
                dev,
                "islands.edt_columns",
                &[
                    (0, pbind(&params)),
                    (1, mask.as_entire_binding()),
                    (2, col_near.as_entire_binding()),
                ],
            );
            let bg_rows = pipes.edt_rows.bind(
                dev,
                "islands.edt_rows",
                &[
                    (0, pbind(&params)),
                    (1, mask.as_entire_binding()),
                    (2, col_near.as_entire_binding()),
                    (3, env_v.as_entire_binding()),
                    (4, env_z.as_entire_binding()),
                    (5, nearest.as_entire_binding()),
                ],
            );
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("islands.edt"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&pipes.edt_columns.pipeline);
            pass.set_bind_group(0, &bg_cols, &[0]);
            pass.dispatch_workgroups(w.div_ceil(64), 1, 1);
            pass.set_pipeline(&pipes.edt_rows.pipeline);
            pass.set_bind_group(0, &bg_rows, &[0]);
            pass.dispatch_workgroups(h.div_ceil(64), 1, 1);
            *commands += 2;
            drop(pass);
            self.ctx.queue.submit([enc.finish()]);
        })?;
        if self.ctx.backend == Some(wgpu::Backend::Gl) {
            // wgpu's GL backend (Mesa llvmpipe) gets the GPU distance transform wrong (not yet
            // understood; Vulkan is exact, see tests/padding_edt.rs). There, compute the same exact
            // transform with its CPU twin, once per mesh and size, and upload it.
            let m = self
                .ctx
                .read_buffer(&mask, texels * 4, "island mask read-back")?;
            let island: Vec<bool> = bytemuck::cast_slice::<u8, u32>(&m)
                .iter()
                .map(|v| *v != 0)
                .collect();
            let near = crate::bake::cpu::nearest_island_map(&island, w, h);
            self.ctx
                .queue
                .write_buffer(&nearest, 0, bytemuck::cast_slice(&near));
        }
        let count_bytes = self
            .ctx
            .read_buffer(&counter, 16, "island count read-back")?;
        let count = bytemuck::cast_slice::<u8, u32>(&count_bytes)[0] as u64;
        let islands = Arc::new(Islands {
            mask,
            nearest,
            count,
        });
        mesh.islands
            .lock()
            .expect("island cache poisoned")
            .insert(key, islands.clone());
        Ok(islands)
    }

    /// The island mask (1 = island texel) and the nearest-island-texel index of every texel, as the
    /// bake uses them, read back to the CPU. For tests and debugging; `samples` is 1, 4, 9 or 16.
    pub fn island_maps(
        &self,
        mesh: &LoadedMesh,
        uv_set: u32,
        size: [u32; 2],
        samples: u32,
    ) -> Result<(Vec<u32>, Vec<u32>)> {
        let ss = (samples as f32).sqrt().round() as u32;
        let mut commands = 0;
        let isl = self.islands(mesh, uv_set, size, ss.max(1), &mut commands)?;
        let bytes = size[0] as u64 * size[1] as u64 * 4;
        let mask = self
            .ctx
            .read_buffer(&isl.mask, bytes, "island mask read-back")?;
        let nearest = self
            .ctx
            .read_buffer(&isl.nearest, bytes, "nearest map read-back")?;
        Ok((
            bytemuck::cast_slice(&mask).to_vec(),
            bytemuck::cast_slice(&nearest).to_vec(),
        ))
    }

    /// Checks what can only be checked against the mesh and the device.
    fn check_job(&self, mesh: &LoadedMesh, job: &Job) -> Result<()> {
        let src = &job.source;
        let max_side = self.ctx.max_texture_side();
        for (field, v) in [("texture.width", job.width), ("texture.height", job.height)] {
            if v > max_side {
                return Err(Error::job(
                    src,
                    field,
                    format!("{v} exceeds this adapter's texture limit of {max_side} texels"),
                ));
            }
        }
        let limits = self.ctx.device.limits();
        let max_binding = limits.max_storage_buffer_binding_size;
        let texels = job.width as u64 * job.height as u64;
        if texels * 8 > max_binding {
            return Err(Error::job(
                src,
                "texture.width",
                format!(
                    "{}x{} needs {} MiB per accumulation plane, above this adapter's storage binding limit of {} MiB (at most {} texels, e.g. {}x{})",
                    job.width,
                    job.height,
                    (texels * 8) >> 20,
                    max_binding >> 20,
                    max_binding / 8,
                    1u64 << ((max_binding / 8).ilog2() / 2),
                    1u64 << ((max_binding / 8).ilog2() / 2)
                ),
            ));
        }
        let sets = mesh.mesh.uv_sets.len();
        if sets == 0 {
            return Err(Error::mesh(
                &mesh.mesh.source,
                "the mesh has no UV coordinates (no TEXCOORD_0), so there is no texture layout to bake into; unwrap it first (for example Blender's Smart UV Project) and export again",
            ));
        }
        if job.uv_set as usize >= sets {
            return Err(Error::job(
                src,
                "uv_set",
                format!(
                    "{} does not exist: {} has {sets} UV set(s) (TEXCOORD_0..TEXCOORD_{})",
                    job.uv_set,
                    mesh.mesh.source.display(),
                    sets - 1
                ),
            ));
        }
        Ok(())
    }

    fn load_base(&self, mesh: &LoadedMesh, job: &Job) -> Result<Arc<GpuImage>> {
        let solid = |c: [f32; 4]| {
            Arc::new(self.upload_image(&LinearImage::solid(1, 1, c), false, "bake.base"))
        };
        Ok(match &job.base {
            Base::Color(c) => solid(*c),
            Base::Image(p) => {
                let img = self.checked_image(p, job, "texture.base", false)?;
                Arc::new(self.upload_image(&img, false, "bake.base"))
            }
            Base::Material => match &mesh.mesh.material {
                Some(m) => match &m.base_color_texture {
                    Some(t) => mesh
                        .material_texture
                        .get_or_init(|| Arc::new(self.upload_image(t, false, "mesh.base_color")))
                        .clone(),
                    None => solid(m.base_color_factor),
                },
                None => solid([0.5, 0.5, 0.5, 1.0]),
            },
        })
    }

    fn checked_image(&self, path: &Path, job: &Job, field: &str, raw: bool) -> Result<LinearImage> {
        let img = if raw {
            load_raw(path)?
        } else {
            LinearImage::load(path)?
        };
        let max = self.ctx.max_texture_side();
        if img.width > max || img.height > max {
            return Err(Error::job(
                &job.source,
                field,
                format!(
                    "{} is {}x{}, above this adapter's texture limit of {max}; downscale it",
                    path.display(),
                    img.width,
                    img.height
                ),
            ));
        }
        Ok(img)
    }

    fn run(&self, mesh: &LoadedMesh, job: &Job) -> Result<Run> {
        self.check_job(mesh, job)?;
        let dev = &self.ctx.device;
        let pipes = &self.pipes;
        let g = &mesh.gpu;
        let (w, h, ss) = (job.width, job.height, job.ss);
        let mut timings = Timings {
            load_ms: mesh.timings.0,
            weld_ms: mesh.timings.1,
            upload_ms: mesh.timings.2,
            ..Default::default()
        };
        let mut warnings = Vec::new();
        let mut commands = 0u32;
        let uvs = &g.uvs[job.uv_set as usize];

        // Images.
        let t = Instant::now();
        let base_gpu = self.load_base(mesh, job)?;
        let mut images: HashMap<PathBuf, Arc<GpuImage>> = HashMap::new();
        let mut masks: HashMap<PathBuf, Arc<GpuImage>> = HashMap::new();
        let mut layer_images = Vec::new();
        for (i, l) in job.layers.iter().enumerate() {
            let img = match images.get(&l.image) {
                Some(x) => x.clone(),
                None => {
                    let im =
                        self.checked_image(&l.image, job, &format!("layers[{i}].image"), false)?;
                    let gi = Arc::new(self.upload_image(&im, true, "layer.image"));
                    images.insert(l.image.clone(), gi.clone());
                    gi
                }
            };
            let mask = match &l.mask {
                None => None,
                Some(p) => Some(match masks.get(p) {
                    Some(x) => x.clone(),
                    None => {
                        let im = self.checked_image(p, job, &format!("layers[{i}].mask"), true)?;
                        let gi = Arc::new(self.upload_image(&im, true, "layer.mask"));
                        masks.insert(p.clone(), gi.clone());
                        gi
                    }
                }),
            };
            layer_images.push((img, mask));
        }

        let dummy = self.upload_image(&LinearImage::solid(1, 1, [1.0; 4]), false, "bake.dummy");
        timings.images_ms = ms(t);

        // Placement.
        let t = Instant::now();
        let queries: Vec<Query> = job
            .layers
            .iter()
            .map(|l| match &l.at {
                crate::io::job::AtSpec::Point(p) => Query::Point(Vec3::from(*p)),
                crate::io::job::AtSpec::Ray { ray } => {
                    Query::Ray(Vec3::from(ray.origin), Vec3::from(ray.dir))
                }
            })
            .collect();
        let placements = place_gpu(&self.ctx, pipes, g, &queries)?;
        commands += 2;
        let mut frames = Vec::new();
        for (i, (l, p)) in job.layers.iter().zip(&placements).enumerate() {
            if p.found == 0 {
                return Err(Error::Placement {
                    path: job.source.clone(),
                    layer: i,
                    detail: "the ray misses the mesh; aim it at the model (check origin, direction and the model's units in `decalbake info`)".into(),
                });
            }
            let reach = l.size[0].max(l.size[1]);
            if matches!(l.at, crate::io::job::AtSpec::Point(_)) && p.distance > reach {
                return Err(Error::Placement {
                    path: job.source.clone(),
                    layer: i,
                    detail: format!(
                        "the point {:?} is {:.4} from the surface, farther than the decal's size {:.4}; place it on the mesh (its bounding box is in `decalbake info`) or use a ray",
                        match l.at { crate::io::job::AtSpec::Point(p) => p, _ => [0.0; 3] },
                        p.distance,
                        reach
                    ),
                });
            }
            let f = Frame::new(p, l);
            if f.up_fallback {
                warnings.push(format!("layer {i}: `up` is parallel to the surface normal there; used a world axis instead"));
            }
            frames.push(f);
        }
        timings.placement_ms = ms(t);

        let t_compose = Instant::now();
        // Accumulation image, island mask, stats.
        let texels = w as u64 * h as u64;
        let plane = |label| {
            dev.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: texels * 8,
                usage: wgpu::BufferUsages::STORAGE,
                mapped_at_creation: false,
            })
        };
        let acc_rg = plane("bake.acc_rg");
        let acc_ba = plane("bake.acc_ba");
        // One stats row per layer: 8 counters (see wgsl/bake/select_triangles.wgsl) and the layer's
        // cell mask.
        let nl = job.layers.len().max(1) as u64;
        let grid = [w.div_ceil(CELL), h.div_ceil(CELL)];
        let mask_words = (grid[0] * grid[1]).div_ceil(32);
        let stats_stride = 8 + mask_words;
        let stats_init: Vec<i32> = (0..nl)
            .flat_map(|_| {
                [0, i32::MAX, i32::MAX, i32::MIN, i32::MIN, 0, 0, 0]
                    .into_iter()
                    .chain(std::iter::repeat_n(0, mask_words as usize))
            })
            .collect();
        let stats = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("bake.stats"),
            contents: bytemuck::cast_slice(&stats_init),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        });
        let stats_size = nl * stats_stride as u64 * 4;

        let global = Params {
            tex_size: [w, h],
            ss,
            vertex_count: g.vertex_count,
            triangle_count: g.triangle_count,
            stats_stride,
            cell: CELL,
            grid,
            ..Default::default()
        };

        // Islands and their distance transform: cached per (UV set, size, samples) on the mesh.
        let islands = self.islands(mesh, job.uv_set, [w, h], ss, &mut commands)?;
        let base_params = params_buffer(dev, "bake.base_params", &[global]);
        self.ctx.scoped("base", || {
            let mut enc = dev.create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("bake.base"),
            });
            let bg_base = pipes.base_init.bind(
                dev,
                "bake.base_init",
                &[
                    (0, pbind(&base_params)),
                    (1, wgpu::BindingResource::TextureView(&base_gpu.view)),
                    (2, wgpu::BindingResource::Sampler(&self.linear_sampler)),
                    (10, acc_rg.as_entire_binding()),
                    (11, acc_ba.as_entire_binding()),
                ],
            );
            {
                let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("bake.base_init"),
                    timestamp_writes: None,
                });
                pass.set_pipeline(&pipes.base_init.pipeline);
                pass.set_bind_group(0, &bg_base, &[0]);
                pass.dispatch_workgroups(w.div_ceil(8), h.div_ceil(8), 1);
            }
            commands += 1;
            self.ctx.queue.submit([enc.finish()]);
        })?;

        // Layers, in chunks.
        let per_layer = g.vertex_count as u64 * 16 + g.triangle_count as u64 * 4;
        let chunk =
            ((CHUNK_BUDGET / per_layer.max(1)).max(1) as usize).min(job.layers.len().max(1));
        let coords = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("bake.coords"),
            size: (chunk as u64 * g.vertex_count as u64 * 16).max(16),
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_DST
                | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let lists = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("bake.lists"),
            size: (chunk as u64 * g.triangle_count as u64 * 4).max(16),
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        let mut layer_reports = Vec::new();
        for start in (0..job.layers.len()).step_by(chunk) {
            let end = (start + chunk).min(job.layers.len());
            if start > 0 {
                // The exponential maps only write the vertices of their disc (and mark its halo);
                // a slot's other vertices must not keep the previous chunk's layer as valid.
                self.ctx.scoped("coords clear", || {
                    let mut enc = dev.create_command_encoder(&wgpu::CommandEncoderDescriptor {
                        label: Some("bake.coords_clear"),
                    });
                    enc.clear_buffer(&coords, 0, None);
                    self.ctx.queue.submit([enc.finish()]);
                })?;
                commands += 1;
            }
            let mut lp = Vec::new();
            for (i, (l, frame)) in job
                .layers
                .iter()
                .zip(&frames)
                .enumerate()
                .take(end)
                .skip(start)
            {
                let mut p = Params {
                    center: [0.0; 4],
                    ..global
                };
                let f = Params::of_frame(frame);
                (p.center, p.axis_u, p.axis_v, p.normal) = (f.center, f.axis_u, f.axis_v, f.normal);
                p.slot = (i - start) as u32;
                p.aux = i as u32;
                p.vertex_count = g.vertex_count;
                p.triangle_count = g.triangle_count;
                p.blend = l.blend as u32;
                p.opacity = l.opacity;
                p.flags = match l.method {
                    Method::Planar => FLAG_FACING,
                    Method::Expmap | Method::Lscm | Method::Hybrid => 0,
                } | if l.mask.is_some() { FLAG_MASK } else { 0 };
                lp.push(p);
            }
            let layer_params = params_buffer(dev, "bake.layer_params", &lp);
            // Exponential maps of this chunk: one dispatch, one workgroup per decal.
            let geo_layers: Vec<usize> = (start..end)
                .filter(|&i| job.layers[i].method != Method::Planar)
                .collect();
            let geo_maps: Vec<_> = geo_layers
                .iter()
                .map(|&i| {
                    let opts = frames[i].expmap_options(&job.layers[i]);
                    (frames[i].seed(&placements[i]), opts, (i - start) as u32)
                })
                .collect();
            let (geo_stats, geo_dispatches) = crate::maps::expmap::gpu::run(
                &self.ctx,
                pipes,
                mesh.surface_ref(),
                &geo_maps,
                &coords,
            )?;
            commands += geo_dispatches;
            // Conformal charts of this chunk (LSCM and hybrid), solved in batches on the GPU, then
            // written into their coords slots.
            let chart_layers: Vec<usize> = (start..end)
                .filter(|&i| matches!(job.layers[i].method, Method::Lscm | Method::Hybrid))
                .collect();
            let mut chart_reports: HashMap<usize, crate::maps::chart::ChartReport> = HashMap::new();
            if !chart_layers.is_empty() {
                let t = Instant::now();
                let nv = g.vertex_count as u64;
                let mut expmaps: HashMap<usize, Vec<[f32; 4]>> = HashMap::new();
                // Both kinds start from the layer's exponential map (computed above with the
                // expmap layers): hybrid re-solves part of it, LSCM uses it as its warm start.
                // One read-back from the first to the last chart layer's slot (the slots of other
                // layers in between come along).
                let (first, last) = (chart_layers[0], chart_layers[chart_layers.len() - 1]);
                let bytes = self.ctx.read_buffer_range(
                    &coords,
                    (first - start) as u64 * nv * 16,
                    (last - first + 1) as u64 * nv * 16,
                    "chart exponential-map read-back",
                )?;
                let all: &[[f32; 4]] = bytemuck::cast_slice(&bytes);
                let n = nv as usize;
                for &i in &chart_layers {
                    let k = i - first;
                    expmaps.insert(i, all[k * n..(k + 1) * n].to_vec());
                }
                let requests: Vec<crate::maps::chart::ChartRequest> = chart_layers
                    .iter()
                    .map(|&i| {
                        crate::maps::chart::ChartRequest::for_layer(
                            frames[i],
                            placements[i].triangle,
                            &job.layers[i],
                            &expmaps[&i],
                        )
                    })
                    .collect();
                let mut solve_stats = crate::maps::chart::SolveStats::default();
                let charts = crate::maps::chart::build(
                    &mesh.topo,
                    &requests,
                    &self.solver(),
                    &mut solve_stats,
                )?;
                commands += solve_stats.dispatches;
                let mut items: Vec<[u32; 8]> = Vec::new();
                for (&i, chart) in chart_layers.iter().zip(&charts) {
                    let r = chart.report;
                    if r.status != crate::solve::sparse::CgStatus::Converged {
                        return Err(Error::Placement {
                            path: job.source.clone(),
                            layer: i,
                            detail: format!(
                                "the conformal chart ({} triangles) did not converge: {:?} after {} conjugate-gradient iterations, relative residual {:.2e} (target {:.0e}); raise `cg_max_iterations`, make the decal smaller, or use \"expmap\"",
                                r.triangles, r.status, r.cg_iterations, r.residual, crate::maps::chart::FINAL_RTOL
                            ),
                        });
                    }
                    if !r.settled {
                        warnings.push(format!(
                            "layer {i}: the conformal chart was still growing after {} refinement rounds (the decal wraps around a rounded feature); it is conformal but its size varies: make the decal smaller, or use \"expmap\" or \"hybrid\"",
                            crate::maps::chart::MAX_ROUNDS
                        ));
                    }
                    chart_reports.insert(i, r);
                    let base = (i - start) as u64 * nv;
                    for &(v, c) in &chart.coords {
                        let value = [c[0], c[1], 0.0, 1.0];
                        let mut item = [0u32; 8];
                        item[0] = (base + v as u64) as u32;
                        item[4..].copy_from_slice(bytemuck::cast_slice(&value));
                        items.push(item);
                    }
                }
                self.ctx.scoped("chart coordinates", || {
                    let items_buf = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                        label: Some("bake.chart_items"),
                        contents: bytemuck::cast_slice(if items.is_empty() {
                            &[[0u32; 8]][..]
                        } else {
                            &items
                        }),
                        usage: wgpu::BufferUsages::STORAGE,
                    });
                    let dims = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                        label: Some("bake.chart_dims"),
                        contents: bytemuck::cast_slice(&[items.len() as u32, 0, 0, 0]),
                        usage: wgpu::BufferUsages::UNIFORM,
                    });
                    let bg = pipes.chart_scatter.bind(
                        dev,
                        "bake.chart_scatter",
                        &[
                            (0, dims.as_entire_binding()),
                            (1, items_buf.as_entire_binding()),
                            (2, coords.as_entire_binding()),
                        ],
                    );
                    let mut enc = dev.create_command_encoder(&wgpu::CommandEncoderDescriptor {
                        label: Some("bake.charts"),
                    });
                    for &i in &chart_layers {
                        if job.layers[i].method == Method::Lscm {
                            enc.clear_buffer(&coords, (i - start) as u64 * nv * 16, Some(nv * 16));
                        }
                    }
                    {
                        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                            label: Some("bake.chart_scatter"),
                            timestamp_writes: None,
                        });
                        pass.set_pipeline(&pipes.chart_scatter.pipeline);
                        pass.set_bind_group(0, &bg, &[]);
                        pass.dispatch_workgroups((items.len() as u32).div_ceil(64).max(1), 1, 1);
                    }
                    self.ctx.queue.submit([enc.finish()]);
                })?;
                commands += 1;
                timings.charts_ms += ms(t);
            }
            self.ctx.scoped("layer coordinates", || {
                let bg_planar = pipes.planar_coords.bind(
                    dev,
                    "bake.planar_coords",
                    &[
                        (0, pbind(&layer_params)),
                        (1, g.positions.as_entire_binding()),
                        (2, coords.as_entire_binding()),
                    ],
                );
                let bg_select = pipes.select_triangles.bind(
                    dev,
                    "bake.select_triangles",
                    &[
                        (0, pbind(&layer_params)),
                        (1, g.positions.as_entire_binding()),
                        (2, g.tris.as_entire_binding()),
                        (3, g.split_tris.as_entire_binding()),
                        (4, uvs.as_entire_binding()),
                        (5, coords.as_entire_binding()),
                        (6, lists.as_entire_binding()),
                        (7, stats.as_entire_binding()),
                    ],
                );
                let mut enc = dev.create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("bake.layers"),
                });
                {
                    let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                        label: Some("bake.layers"),
                        timestamp_writes: None,
                    });
                    for (k, l) in job.layers[start..end].iter().enumerate() {
                        let off = (k as u64 * PARAMS_STRIDE) as u32;
                        match l.method {
                            Method::Planar => {
                                pass.set_pipeline(&pipes.planar_coords.pipeline);
                                pass.set_bind_group(0, &bg_planar, &[off]);
                                pass.dispatch_workgroups(g.vertex_count.div_ceil(64), 1, 1);
                                commands += 1;
                            }
                            Method::Expmap | Method::Lscm | Method::Hybrid => {}
                        }
                        pass.set_pipeline(&pipes.select_triangles.pipeline);
                        pass.set_bind_group(0, &bg_select, &[off]);
                        pass.dispatch_workgroups(g.triangle_count.div_ceil(64), 1, 1);
                        commands += 1;
                    }
                }
                self.ctx.queue.submit([enc.finish()]);
            })?;
            let sbytes = self
                .ctx
                .read_buffer(&stats, stats_size, "layer selection read-back")?;
            let s: &[i32] = bytemuck::cast_slice(&sbytes);

            // Plan raster jobs.
            let mut raster_jobs: Vec<(usize, Params)> = Vec::new();
            for i in start..end {
                let row = &s[i * stats_stride as usize..(i + 1) * stats_stride as usize];
                let count = row[0].max(0) as u32;
                let bx = [row[1], row[2], row[3], row[4]];
                if count == 0 {
                    return Err(Error::Placement {
                    path: job.source.clone(),
                        layer: i,
                        detail: "the decal covers no triangle facing it (it misses the mesh, or all triangles under it face away); check `at`, `size` and `depth`".into(),
                    });
                }
                layer_reports.push(LayerReport {
                    index: i,
                    image: job.layers[i].image.display().to_string(),
                    method: job.layers[i].method,
                    blend: job.layers[i].blend,
                    placement: placements[i],
                    distance_moved: placements[i].distance,
                    frame: frames[i],
                    triangles_covered: count,
                    texels_covered: 0,
                    texel_box: bx,
                    distortion: Default::default(),
                    expmap: geo_layers.iter().position(|&g| g == i).map(|k| {
                        crate::maps::expmap::gpu::GeoResult {
                            triangles_reached: row[6].max(0) as u32,
                            ..geo_stats[k]
                        }
                    }),
                    chart: chart_reports.get(&i).copied(),
                });
                if let Some(gs) = geo_layers
                    .iter()
                    .position(|&g| g == i)
                    .map(|k| geo_stats[k])
                {
                    if gs.converged == 0 {
                        warnings.push(format!(
                            "layer {i}: the exponential map did not converge in {} sweeps; the decal may be incomplete",
                            gs.sweeps
                        ));
                    }
                }
                let base = lp[i - start];
                let rects = plan_cells(&row[8..], grid, CELL, [w, h], TILE_TARGET / ss);
                for tj in bx[1].div_euclid(h as i32)..=(bx[3] - 1).max(bx[1]).div_euclid(h as i32) {
                    for ti in
                        bx[0].div_euclid(w as i32)..=(bx[2] - 1).max(bx[0]).div_euclid(w as i32)
                    {
                        for r in &rects {
                            raster_jobs.push((
                                i,
                                Params {
                                    rect_origin: [r[0], r[1]],
                                    rect_size: [r[2] as u32, r[3] as u32],
                                    tile: [ti, tj],
                                    ..base
                                },
                            ));
                        }
                    }
                }
            }
            // Pack the raster jobs, in order, into atlas batches: one render pass (one clear) per
            // batch, each job drawn into its own region, then one compose dispatch per job in job
            // order (so overlapping layers still apply in order).
            let mut batches: Vec<Batch> = Vec::new();
            {
                let (mut cur, mut sx, mut sy, mut sh) = (Vec::new(), 0u32, 0u32, 0u32);
                for (k, (_, p)) in raster_jobs.iter_mut().enumerate() {
                    let (jw, jh) = (p.rect_size[0] * ss, p.rect_size[1] * ss);
                    if sx + jw > TILE_TARGET {
                        sy += sh;
                        sx = 0;
                        sh = 0;
                    }
                    if sy + jh > TILE_TARGET {
                        batches.push((std::mem::take(&mut cur), sy + sh));
                        (sx, sy, sh) = (0, 0, 0);
                    }
                    p.atlas_origin = [sx, sy];
                    cur.push((k, [sx, sy]));
                    sx += jw;
                    sh = sh.max(jh);
                }
                if !cur.is_empty() {
                    batches.push((cur, sy + sh));
                }
            }
            if std::env::var("DECALBAKE_DEBUG").is_ok() {
                let covered: u64 = raster_jobs
                    .iter()
                    .map(|(_, p)| p.rect_size[0] as u64 * p.rect_size[1] as u64)
                    .sum();
                eprintln!(
                    "raster jobs {} in {} batches, rect texels {covered}",
                    raster_jobs.len(),
                    batches.len()
                );
            }
            let jp: Vec<Params> = raster_jobs.iter().map(|(_, p)| *p).collect();
            let job_params = params_buffer(dev, "bake.raster_params", &jp);
            let n_chunk = (end - start) as u64;
            let partials_size = n_chunk * crate::maps::distortion::DIST_GROUPS as u64 * 32;
            let partials = dev.create_buffer(&wgpu::BufferDescriptor {
                label: Some("bake.distortion"),
                size: partials_size,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            self.ctx.scoped("raster and compose", || {
                let mut enc = dev.create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("bake.compose"),
                });
                {
                    // Distortion of each layer's map over its triangles (reads coords and lists).
                    let bg = pipes.distortion.bind(
                        dev,
                        "bake.distortion",
                        &[
                            (0, pbind(&layer_params)),
                            (1, g.positions.as_entire_binding()),
                            (2, g.tris.as_entire_binding()),
                            (3, coords.as_entire_binding()),
                            (4, lists.as_entire_binding()),
                            (5, stats.as_entire_binding()),
                            (6, partials.as_entire_binding()),
                        ],
                    );
                    let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                        label: Some("bake.distortion"),
                        timestamp_writes: None,
                    });
                    pass.set_pipeline(&pipes.distortion.pipeline);
                    for k in 0..n_chunk {
                        pass.set_bind_group(0, &bg, &[(k * PARAMS_STRIDE) as u32]);
                        pass.dispatch_workgroups(crate::maps::distortion::DIST_GROUPS, 1, 1);
                        commands += 1;
                    }
                }
                let mut layer_bgs: HashMap<usize, wgpu::BindGroup> = HashMap::new();
                for (batch, used_h) in &batches {
                    let tg = self.targets([TILE_TARGET, used_h.next_power_of_two().max(64)]);
                    {
                        let clear = wgpu::Operations {
                            load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                            store: wgpu::StoreOp::Store,
                        };
                        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                            label: Some("bake.layer_raster"),
                            color_attachments: &[
                                Some(wgpu::RenderPassColorAttachment {
                                    view: &tg.color_view,
                                    depth_slice: None,
                                    resolve_target: None,
                                    ops: clear,
                                }),
                                Some(wgpu::RenderPassColorAttachment {
                                    view: &tg.cov_view,
                                    depth_slice: None,
                                    resolve_target: None,
                                    ops: clear,
                                }),
                            ],
                            depth_stencil_attachment: None,
                            timestamp_writes: None,
                            occlusion_query_set: None,
                            multiview_mask: None,
                        });
                        pass.set_pipeline(&pipes.layer_raster.pipeline);
                        for &(k, origin) in batch {
                            let (i, p) = &raster_jobs[k];
                            let off = (k as u64 * PARAMS_STRIDE) as u32;
                            let bg = layer_bgs.entry(*i).or_insert_with(|| {
                                let (img, m) = &layer_images[*i];
                                let mview = m.as_ref().map(|m| &m.view).unwrap_or(&dummy.view);
                                make_bg(
                                    dev,
                                    &pipes.layer_raster.layout,
                                    "bake.layer_raster",
                                    &[
                                        (0, pbind(&job_params)),
                                        (1, lists.as_entire_binding()),
                                        (2, g.split_tris.as_entire_binding()),
                                        (3, uvs.as_entire_binding()),
                                        (4, g.welded_of.as_entire_binding()),
                                        (5, coords.as_entire_binding()),
                                        (6, wgpu::BindingResource::TextureView(&img.view)),
                                        (7, wgpu::BindingResource::TextureView(mview)),
                                        (8, wgpu::BindingResource::Sampler(&self.linear_sampler)),
                                    ],
                                )
                            });
                            let count =
                                (s[i * stats_stride as usize].max(0) as u32).min(g.triangle_count);
                            let (jw, jh) = (p.rect_size[0] * ss, p.rect_size[1] * ss);
                            pass.set_bind_group(0, &*bg, &[off]);
                            pass.set_viewport(
                                origin[0] as f32,
                                origin[1] as f32,
                                jw as f32,
                                jh as f32,
                                0.0,
                                1.0,
                            );
                            pass.set_scissor_rect(origin[0], origin[1], jw, jh);
                            pass.draw(0..3 * count, 0..1);
                            commands += 1;
                        }
                    }
                    let bg_compose = pipes.compose.bind(
                        dev,
                        "bake.compose",
                        &[
                            (0, pbind(&job_params)),
                            (1, wgpu::BindingResource::TextureView(&tg.color_view)),
                            (2, wgpu::BindingResource::TextureView(&tg.cov_view)),
                            (3, stats.as_entire_binding()),
                            (10, acc_rg.as_entire_binding()),
                            (11, acc_ba.as_entire_binding()),
                        ],
                    );
                    let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                        label: Some("bake.compose"),
                        timestamp_writes: None,
                    });
                    pass.set_pipeline(&pipes.compose.pipeline);
                    for &(k, _) in batch {
                        let p = &raster_jobs[k].1;
                        pass.set_bind_group(0, &bg_compose, &[(k as u64 * PARAMS_STRIDE) as u32]);
                        pass.dispatch_workgroups(
                            p.rect_size[0].div_ceil(8),
                            p.rect_size[1].div_ceil(8),
                            1,
                        );
                        commands += 1;
                    }
                }
                self.ctx.queue.submit([enc.finish()]);
            })?;
            let pb = self
                .ctx
                .read_buffer(&partials, partials_size, "distortion read-back")?;
            let pf: &[[f32; 4]] = bytemuck::cast_slice(&pb);
            let per = 2 * crate::maps::distortion::DIST_GROUPS as usize;
            for l in layer_reports
                .iter_mut()
                .filter(|l| l.index >= start && l.index < end)
            {
                let k = l.index - start;
                l.distortion =
                    crate::maps::distortion::Distortion::from_partials(&pf[k * per..(k + 1) * per]);
            }
        }
        self.ctx.wait("compose")?;
        timings.compose_ms = ms(t_compose);

        // Padding and encode.
        let t = Instant::now();
        let pad = match job.padding {
            Padding::Texels(n) => n,
            Padding::Full => u32::MAX,
        };
        let stride = if job.bit_depth == 16 {
            (2 * w).next_multiple_of(64)
        } else {
            w.next_multiple_of(64)
        };
        let fin = [Params {
            rect_size: [stride, 0],
            flags: if job.bit_depth == 16 { FLAG_16BIT } else { 0 },
            aux: pad,
            ..global
        }];
        let fin_params = params_buffer(dev, "bake.final_params", &fin);
        let packed_size = stride as u64 * h as u64 * 4;
        let packed = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("bake.packed"),
            size: packed_size,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        self.ctx.scoped("padding and encode", || {
            let mut enc = dev.create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("bake.finish"),
            });
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("bake.finish"),
                timestamp_writes: None,
            });
            let bg_enc = pipes.encode.bind(
                dev,
                "bake.encode",
                &[
                    (0, pbind(&fin_params)),
                    (1, packed.as_entire_binding()),
                    (2, islands.mask.as_entire_binding()),
                    (3, islands.nearest.as_entire_binding()),
                    (10, acc_rg.as_entire_binding()),
                    (11, acc_ba.as_entire_binding()),
                ],
            );
            pass.set_pipeline(&pipes.encode.pipeline);
            pass.set_bind_group(0, &bg_enc, &[0]);
            pass.dispatch_workgroups(w.div_ceil(8), h.div_ceil(8), 1);
            commands += 1;
            drop(pass);
            self.ctx.queue.submit([enc.finish()]);
        })?;
        self.ctx.wait("padding")?;
        timings.padding_ms = ms(t);

        let stats_bytes = self
            .ctx
            .read_buffer(&stats, stats_size, "stats read-back")?;
        let stats_words: &[i32] = bytemuck::cast_slice(&stats_bytes);
        for l in &mut layer_reports {
            l.texels_covered = stats_words[l.index * stats_stride as usize + 5].max(0) as u32;
        }
        let island_texels = islands.count;

        let report = Report {
            version: env!("CARGO_PKG_VERSION"),
            adapter: self.ctx.adapter.clone(),
            job: job.source.display().to_string(),
            mesh: mesh.stats.clone(),
            uv_set: job.uv_set,
            texture: [w, h],
            samples: ss * ss,
            padding: if pad == u32::MAX { None } else { Some(pad) },
            layers: layer_reports,
            island_texels,
            warnings,
            timings,
            gpu_commands: commands,
        };
        Ok(Run {
            packed,
            packed_size,
            stride,
            report,
        })
    }
}

/// Raster jobs packed into one atlas target: (job index, origin in samples) and the height used.
type Batch = (Vec<(usize, [u32; 2])>, u32);

/// GPU results of a bake before read-back.
struct Run {
    packed: wgpu::Buffer,
    packed_size: u64,
    stride: u32,
    report: Report,
}

/// A `Params` binding (one entry at a dynamic offset).
fn pbind(buf: &wgpu::Buffer) -> wgpu::BindingResource<'_> {
    wgpu::BindingResource::Buffer(wgpu::BufferBinding {
        buffer: buf,
        offset: 0,
        size: wgpu::BufferSize::new(std::mem::size_of::<Params>() as u64),
    })
}

fn make_bg(
    dev: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    label: &str,
    entries: &[(u32, wgpu::BindingResource<'_>)],
) -> wgpu::BindGroup {
    crate::gpu::pipelines::make_bind_group(dev, layout, label, entries)
}

fn params_buffer(dev: &wgpu::Device, label: &str, entries: &[Params]) -> wgpu::Buffer {
    let mut bytes = vec![0u8; (entries.len().max(1) as u64 * PARAMS_STRIDE) as usize];
    for (i, p) in entries.iter().enumerate() {
        let o = i * PARAMS_STRIDE as usize;
        bytes[o..o + std::mem::size_of::<Params>()].copy_from_slice(bytemuck::bytes_of(p));
    }
    dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: &bytes,
        usage: wgpu::BufferUsages::UNIFORM,
    })
}

/// Side of a cell of the per-layer coverage mask, in texels.
pub const CELL: u32 = 64;

/// Raster rectangles covering the marked cells of a layer's mask: runs of marked cells along each
/// cell row, merged downwards while the next row has the same run, each at most `max_side` texels a
/// side and clipped to the texture.
pub fn plan_cells(
    mask: &[i32],
    grid: [u32; 2],
    cell: u32,
    tex: [u32; 2],
    max_side: u32,
) -> Vec<[i32; 4]> {
    let bit = |cx: u32, cy: u32| {
        let b = cy * grid[0] + cx;
        (mask[(b / 32) as usize] as u32 >> (b % 32)) & 1 == 1
    };
    let max_cells = (max_side / cell).max(1);
    // Runs per row: (x0, x1) in cells, half-open.
    let mut open: Vec<[u32; 4]> = Vec::new(); // x0, x1, y0, y1 (cells)
    let mut done: Vec<[u32; 4]> = Vec::new();
    for cy in 0..grid[1] {
        let mut runs = Vec::new();
        let mut cx = 0;
        while cx < grid[0] {
            if bit(cx, cy) {
                let x0 = cx;
                while cx < grid[0] && bit(cx, cy) && cx - x0 < max_cells {
                    cx += 1;
                }
                runs.push((x0, cx));
            } else {
                cx += 1;
            }
        }
        let mut next_open = Vec::new();
        for r in open.drain(..) {
            if let Some(k) = runs.iter().position(|&(a, b)| a == r[0] && b == r[1]) {
                if r[3] - r[2] < max_cells {
                    runs.remove(k);
                    next_open.push([r[0], r[1], r[2], cy + 1]);
                    continue;
                }
            }
            done.push(r);
        }
        for (a, b) in runs {
            next_open.push([a, b, cy, cy + 1]);
        }
        open = next_open;
    }
    done.extend(open);
    done.iter()
        .map(|r| {
            let x0 = r[0] * cell;
            let y0 = r[2] * cell;
            let x1 = (r[1] * cell).min(tex[0]);
            let y1 = (r[3] * cell).min(tex[1]);
            [x0 as i32, y0 as i32, (x1 - x0) as i32, (y1 - y0) as i32]
        })
        .collect()
}

/// Pooled target side for a raster rectangle: the next power of two of its samples, at least 64.
fn target_side(rect: [u32; 2], ss: u32) -> u32 {
    (rect[0].max(rect[1]) * ss)
        .next_power_of_two()
        .clamp(64, TILE_TARGET)
}

/// Splits rectangle (x, y, w, h) into pieces of at most `tile` a side.
pub fn split_rect(r: [i32; 4], tile: u32) -> Vec<[i32; 4]> {
    let t = tile as i32;
    let mut out = Vec::new();
    let mut y = r[1];
    while y < r[1] + r[3] {
        let hh = t.min(r[1] + r[3] - y);
        let mut x = r[0];
        while x < r[0] + r[2] {
            let ww = t.min(r[0] + r[2] - x);
            out.push([x, y, ww, hh]);
            x += ww;
        }
        y += hh;
    }
    out
}

/// Integer UV tiles (min u, min v, max u, max v) a UV set touches.
fn uv_tile_range(uvs: &[glam::Vec2]) -> [i32; 4] {
    let mut r = [i32::MAX, i32::MAX, i32::MIN, i32::MIN];
    for u in uvs {
        // A UV exactly on 1.0 belongs to tile 0.
        let tx = if u.x == u.x.floor() && u.x > 0.0 {
            u.x as i32 - 1
        } else {
            u.x.floor() as i32
        };
        let ty = if u.y == u.y.floor() && u.y > 0.0 {
            u.y as i32 - 1
        } else {
            u.y.floor() as i32
        };
        r = [r[0].min(tx), r[1].min(ty), r[2].max(tx), r[3].max(ty)];
    }
    if r[0] == i32::MAX {
        return [0, 0, 0, 0];
    }
    // Guard against absurd UV ranges (each tile is a full-texture raster pass).
    [r[0].max(-8), r[1].max(-8), r[2].min(8), r[3].min(8)]
}

fn load_raw(path: &Path) -> Result<LinearImage> {
    let img = LinearImage::load(path)?;
    // Masks are data, not colour: undo the sRGB decode so a mid-grey mask value means 50 %.
    Ok(LinearImage {
        pixels: img
            .pixels
            .iter()
            .map(|p| {
                [
                    crate::io::image::linear_to_srgb(p[0]),
                    crate::io::image::linear_to_srgb(p[1]),
                    crate::io::image::linear_to_srgb(p[2]),
                    p[3],
                ]
            })
            .collect(),
        ..img
    })
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1000.0
}

/// f32 → IEEE half bits, round to nearest even (for devices without filterable f32 textures).
pub fn f32_to_f16(v: f32) -> u16 {
    let x = v.to_bits();
    let sign = ((x >> 16) & 0x8000) as u16;
    let exp = ((x >> 23) & 0xff) as i32;
    let mant = x & 0x7f_ffff;
    if exp == 255 {
        return sign | 0x7c00 | if mant != 0 { 0x200 } else { 0 };
    }
    let e = exp - 127 + 15;
    if e >= 31 {
        return sign | 0x7c00;
    }
    if e <= 0 {
        if e < -10 {
            return sign;
        }
        let m = mant | 0x80_0000;
        let shift = (14 - e) as u32;
        let half = 1u32 << (shift - 1);
        let rounded = (m + half - 1 + ((m >> shift) & 1)) >> shift;
        return sign | rounded as u16;
    }
    let rounded = mant + 0xfff + ((mant >> 13) & 1);
    if rounded & 0x80_0000 != 0 {
        let e2 = e + 1;
        if e2 >= 31 {
            return sign | 0x7c00;
        }
        return sign | ((e2 as u16) << 10);
    }
    sign | ((e as u16) << 10) | (rounded >> 13) as u16
}

/// One row of `decalbake param`: a welded vertex reached by a layer's map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamRow {
    /// Welded vertex id.
    pub vertex: u32,
    /// Position (model units).
    pub position: [f32; 3],
    /// Geodesic distance estimate (|normal coordinates|), where the method computes one.
    pub distance: Option<f32>,
    /// Local coordinates in model units (image +x, image +y), before scaling to the image.
    pub uv: [f32; 2],
}

impl Engine {
    /// The local coordinates of layer `index` of `job` for every vertex its map reaches: for
    /// `expmap` the GPU map's reached vertices (distance = |(u, v)|), for `planar` the vertices of the
    /// triangles the projection covers (no distance).
    pub fn layer_param(&self, mesh: &LoadedMesh, job: &Job, index: usize) -> Result<Vec<ParamRow>> {
        let layer = job.layers.get(index).ok_or_else(|| {
            Error::job(
                &job.source,
                "layers",
                format!(
                    "--layer {index} does not exist: the job has {} layer(s)",
                    job.layers.len()
                ),
            )
        })?;
        let query = match &layer.at {
            crate::io::job::AtSpec::Point(p) => Query::Point(Vec3::from(*p)),
            crate::io::job::AtSpec::Ray { ray } => {
                Query::Ray(Vec3::from(ray.origin), Vec3::from(ray.dir))
            }
        };
        let placement = place_gpu(&self.ctx, &self.pipes, &mesh.gpu, &[query])?[0];
        if placement.found == 0 {
            return Err(Error::Placement {
                path: job.source.clone(),
                layer: index,
                detail: "the ray misses the mesh".into(),
            });
        }
        let frame = Frame::new(&placement, layer);
        let topo = &mesh.topo;
        let mut rows = Vec::new();
        // Every method but planar starts from the layer's exponential map, as in the bake.
        let expmap = match layer.method {
            Method::Planar => Vec::new(),
            _ => {
                let seed = frame.seed(&placement);
                self.expmaps(mesh, &[(seed, frame.expmap_options(layer))])?
                    .remove(0)
                    .0
            }
        };
        match layer.method {
            Method::Expmap => {
                for (v, c) in expmap.iter().enumerate() {
                    if c[3] > 0.5 {
                        rows.push(ParamRow {
                            vertex: v as u32,
                            position: topo.positions[v].to_array(),
                            distance: Some((c[0] * c[0] + c[1] * c[1]).sqrt()),
                            uv: [c[0], c[1]],
                        });
                    }
                }
            }
            Method::Lscm | Method::Hybrid => {
                let hybrid = layer.method == Method::Hybrid;
                let req = crate::maps::chart::ChartRequest::for_layer(
                    frame,
                    placement.triangle,
                    layer,
                    &expmap,
                );
                let chart = crate::maps::chart::build(
                    topo,
                    &[req],
                    &self.solver(),
                    &mut Default::default(),
                )?
                .remove(0);
                let mut uv: HashMap<u32, [f32; 2]> = chart.coords.into_iter().collect();
                if hybrid {
                    // Vertices the hybrid solve did not move keep their exponential-map position.
                    for (v, c) in expmap.iter().enumerate() {
                        if c[3] > 0.5 {
                            uv.entry(v as u32).or_insert([c[0], c[1]]);
                        }
                    }
                }
                for (v, c) in uv {
                    let distance = hybrid.then(|| {
                        let e = expmap[v as usize];
                        (e[0] * e[0] + e[1] * e[1]).sqrt()
                    });
                    rows.push(ParamRow {
                        vertex: v,
                        position: topo.positions[v as usize].to_array(),
                        distance,
                        uv: c,
                    });
                }
                rows.sort_by_key(|r| r.vertex);
            }
            Method::Planar => {
                let coords = crate::maps::planar::planar_coords(topo, &frame);
                // Selection needs UVs only for the texel box, which param does not use.
                let no_uvs = vec![glam::Vec2::ZERO; mesh.mesh.positions.len()];
                let sel = crate::bake::select::select_triangles(
                    &mesh.mesh,
                    topo,
                    &no_uvs,
                    &coords,
                    &frame,
                    true,
                    [1, 1],
                )
                .triangles;
                let mut seen = vec![false; topo.positions.len()];
                for t in sel {
                    for v in topo.triangles[t as usize] {
                        if !std::mem::replace(&mut seen[v as usize], true) {
                            let c = coords[v as usize];
                            rows.push(ParamRow {
                                vertex: v,
                                position: topo.positions[v as usize].to_array(),
                                distance: None,
                                uv: [c[0], c[1]],
                            });
                        }
                    }
                }
                rows.sort_by_key(|r| r.vertex);
            }
        }
        Ok(rows)
    }
}
