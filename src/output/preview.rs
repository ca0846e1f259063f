// SPDX-License-Identifier: MIT OR Apache-2.0
//! A preview of the textured mesh from four sides (front, right, back, left, slightly from above),
//! orthographic, 4× MSAA, in a 2×2 grid, shaded with the bake's PBR channels where it has them
//! (`wgsl/output/preview.wgsl`: Lambert diffuse from the key light and a constant ambient, as the
//! preview always was, plus GGX specular from a key and a fill light): a normal decal shows.

use crate::bake::{Baked, Engine, LoadedMesh};
use crate::error::Result;
use crate::gpu::pipelines::PREVIEW_FORMAT;
use crate::gpu::BufferInit;
use crate::io::channels::ChannelKind;
use glam::{Mat4, Vec3};

/// Side of one view in pixels.
pub const VIEW_SIDE: u32 = 512;

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct ViewUniform {
    view_proj: [[f32; 4]; 4],
    /// Towards the key light (world space).
    light: [f32; 4],
    /// Towards the fill light.
    fill: [f32; 4],
    /// Towards the camera.
    eye: [f32; 4],
    /// x: 1 where the normal texture is the bake's (else the geometric normal); y: the
    /// specular's weight, 1 where the ORM texture is the bake's (else 0: the old Lambert look).
    flags: [f32; 4],
}

/// A bake's PBR channels for the preview (`Baked::channels`): 8-bit RGBA at the colour's size, top
/// row first, laid out on the colour's UV set. One left out is shaded with its default (flat
/// normal; no specular, occlusion 1, metallic 0; no emission).
#[derive(Debug, Clone, Default)]
pub struct PreviewChannels {
    /// Tangent-space normal map as stored (n * 0.5 + 0.5, glTF's: +Y up the image; 128 reads
    /// as 0).
    pub normal: Option<Vec<u8>>,
    /// Occlusion, roughness, metallic (R, G, B) as stored.
    pub orm: Option<Vec<u8>>,
    /// Emissive colour, sRGB.
    pub emissive: Option<Vec<u8>>,
}

impl PreviewChannels {
    /// The channels `baked` painted.
    pub fn of(baked: &Baked) -> Self {
        let mut out = Self::default();
        for c in &baked.channels {
            out.set(c.kind, rgba8(&c.texels, baked.bit_depth));
        }
        out
    }

    /// Takes `bytes` (RGBA8, the colour texture's size) as the texture of `kind`.
    pub fn set(&mut self, kind: ChannelKind, bytes: Vec<u8>) {
        let slot = match kind {
            ChannelKind::Normal => &mut self.normal,
            ChannelKind::Orm => &mut self.orm,
            ChannelKind::Emissive => &mut self.emissive,
        };
        *slot = Some(bytes);
    }
}

/// 8- or 16-bit samples to bytes (16-bit rounded, as `Baked::rgba8`).
fn rgba8(texels: &[u16], bit_depth: u8) -> Vec<u8> {
    match bit_depth {
        16 => texels
            .iter()
            .map(|&v| ((v as u32 * 255 + 32767) / 65535) as u8)
            .collect(),
        _ => texels.iter().map(|&v| v as u8).collect(),
    }
}

/// A texture to preview: sRGB RGBA8 texels, top row first, on a UV set of the mesh.
pub struct PreviewTexture {
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
    /// sRGB RGBA8, 4 bytes a texel.
    pub rgba8: Vec<u8>,
    /// The UV set it is mapped by.
    pub uv_set: usize,
    /// A second texture blended in, weighted by `1 − mesh.blend` (the patch of a pelt, Piponi &
    /// Borshukov §5), or `1 − mesh.blend − mesh.bridge` with a third; needs the mesh's
    /// `_PELT_BLEND` (`Mesh::blend`).
    pub second: Option<Box<PreviewTexture>>,
    /// A third texture blended in, weighted by `mesh.bridge` (the bridges over the patch's seams,
    /// `crate::pelt::bridge`); needs a second and the mesh's `_PELT_BRIDGE` (`Mesh::bridge`).
    pub third: Option<Box<PreviewTexture>>,
    /// The bake's PBR channels the preview shades with (blended: the first texture's); default:
    /// none, the old Lambert look.
    pub channels: PreviewChannels,
}

impl PreviewTexture {
    /// A bake's texture on the set it was baked into.
    pub fn of(baked: &Baked) -> Self {
        Self {
            width: baked.width,
            height: baked.height,
            rgba8: baked.rgba8(),
            uv_set: baked.report.uv_set as usize,
            second: None,
            third: None,
            channels: PreviewChannels::of(baked),
        }
    }
}

/// Renders the preview of a bake, shaded with its channels, and returns sRGB RGBA8 pixels
/// (`2 * VIEW_SIDE` square).
pub fn render_preview(engine: &Engine, mesh: &LoadedMesh, baked: &Baked) -> Result<Vec<u8>> {
    render_texture_preview(engine, mesh, &PreviewTexture::of(baked))
}

/// Writes the preview of a several-set bake (`"uv_set": [..]`) to `path`: the first set's texture,
/// blended with the second's by the mesh's `_PELT_BLEND` when it has one (a pelt and its patch,
/// Piponi & Borshukov §5), and with the third's by `_PELT_BRIDGE` when it has that too (the
/// bridges of `crate::pelt::bridge`).
pub fn write_set_preview(
    engine: &Engine,
    mesh: &LoadedMesh,
    textures: Vec<PreviewTexture>,
    path: &std::path::Path,
) -> Result<()> {
    let mut it = textures.into_iter();
    let Some(mut first) = it.next() else {
        return Ok(());
    };
    let n = mesh.mesh.positions.len();
    if mesh.mesh.blend.len() == n {
        first.second = it.next().map(Box::new);
        if mesh.mesh.bridge.len() == n && first.second.is_some() {
            first.third = it.next().map(Box::new);
            if first.third.is_none() {
                log::warn!(
                    "{}: the model has bridges (_PELT_BRIDGE) but the job bakes two sets: the preview shows the patch where the bridges should be; bake the third set too",
                    path.display()
                );
            }
        }
    }
    let px = render_texture_preview(engine, mesh, &first)?;
    let n = 2 * VIEW_SIDE;
    let samples: Vec<u16> = px.iter().map(|&b| b as u16).collect();
    crate::io::image::write_atomic(path, &crate::io::image::png_bytes(n, n, 8, &samples))
}

/// Renders the preview of `mesh` wearing `baked`, shaded with its channels (for `decalbake
/// unwrap`: a checker on the new UVs).
pub fn render_texture_preview(
    engine: &Engine,
    mesh: &LoadedMesh,
    baked: &PreviewTexture,
) -> Result<Vec<u8>> {
    render_material_preview(engine, mesh, baked, &baked.channels)
}

/// Renders the preview of `mesh` wearing `baked` shaded with `channels` (on `baked`'s UV set and
/// size). Blending a second and third texture (`write_set_preview`), the channels are the first
/// texture's, weighted as it is.
pub fn render_material_preview(
    engine: &Engine,
    mesh: &LoadedMesh,
    baked: &PreviewTexture,
    channels: &PreviewChannels,
) -> Result<Vec<u8>> {
    let ctx = &engine.ctx;
    ctx.scoped("preview", || {
        let view = upload_colour(engine, baked);
        let sampler = preview_sampler(engine);
        let second = baked.second.as_ref().map(|t| upload_colour(engine, t));
        let third = baked.third.as_ref().map(|t| upload_colour(engine, t));
        let groups = view_groups(
            engine,
            mesh,
            [
                &view,
                second.as_ref().unwrap_or(&view),
                third.as_ref().unwrap_or(&view),
            ],
            &upload_channels(engine, baked, channels),
            &sampler,
        );
        let all = 0..mesh.mesh.triangles.len() as u32;
        let tangents = channels.normal.is_some();
        draw(engine, mesh, baked, tangents, &[(groups, vec![all])])
    })
    .and_then(|readback| ctx.map_and_read(&readback, "preview read-back"))
}

/// The preview of a bake into several texture sets: each set's triangles (`ranges`, triangle
/// index ranges) drawn with its own texture and channels, on the first texture's UV set.
pub fn render_sets_preview(
    engine: &Engine,
    mesh: &LoadedMesh,
    sets: &[(PreviewTexture, Vec<std::ops::Range<u32>>)],
) -> Result<Vec<u8>> {
    let sets: Vec<_> = sets
        .iter()
        .map(|(t, r)| (t, &t.channels, r.as_slice()))
        .collect();
    render_sets_material_preview(engine, mesh, &sets)
}

/// [`render_sets_preview`] with each set shaded with its own channels (`PreviewChannels::of` its
/// bake; a set whose bake painted none gets the defaults, the old look).
pub fn render_sets_material_preview(
    engine: &Engine,
    mesh: &LoadedMesh,
    sets: &[(&PreviewTexture, &PreviewChannels, &[std::ops::Range<u32>])],
) -> Result<Vec<u8>> {
    let ctx = &engine.ctx;
    let Some((first, _, _)) = sets.first() else {
        return Ok(Vec::new());
    };
    ctx.scoped("preview", || {
        let sampler = preview_sampler(engine);
        let draws: Vec<_> = sets
            .iter()
            .map(|(t, channels, ranges)| {
                let view = upload_colour(engine, t);
                let chans = upload_channels(engine, t, channels);
                (
                    view_groups(engine, mesh, [&view; 3], &chans, &sampler),
                    ranges.to_vec(),
                )
            })
            .collect();
        let tangents = sets.iter().any(|(_, c, _)| c.normal.is_some());
        draw(engine, mesh, first, tangents, &draws)
    })
    .and_then(|readback| ctx.map_and_read(&readback, "preview read-back"))
}

/// The preview's sampler: wrapping, trilinear, and anisotropic (8×) on a GPU. Not on a CPU
/// adapter, where llvmpipe's anisotropic taps took about 100 of a two-material knight's 260 ms of
/// preview (2026-11-29, lavapipe), for a picture that looked the same at the preview's size.
fn preview_sampler(engine: &Engine) -> wgpu::Sampler {
    let cpu = engine.ctx.device_type == Some(wgpu::DeviceType::Cpu);
    engine.ctx.device.create_sampler(&wgpu::SamplerDescriptor {
        label: Some("preview.sampler"),
        address_mode_u: wgpu::AddressMode::Repeat,
        address_mode_v: wgpu::AddressMode::Repeat,
        mag_filter: wgpu::FilterMode::Linear,
        min_filter: wgpu::FilterMode::Linear,
        mipmap_filter: wgpu::MipmapFilterMode::Linear,
        anisotropy_clamp: if cpu { 1 } else { 8 },
        ..Default::default()
    })
}

/// An RGBA8 image (`width` × `height`) with a box-filtered mip chain (in stored bytes: good enough
/// for a preview). Each level's rows are split between the cores.
fn mip_chain(width: u32, height: u32, rgba8: &[u8]) -> Vec<(u32, u32, Vec<u8>)> {
    let mut levels = vec![(width, height, rgba8.to_vec())];
    loop {
        let (w, h, px) = levels.last().expect("non-empty");
        let (w, h) = (*w as usize, *h as usize);
        if w <= 1 && h <= 1 {
            return levels;
        }
        let next = half(w, h, px);
        levels.push(next);
    }
}

/// One mip level below a `w` × `h` RGBA8 image: each texel the rounded mean of its 2 × 2 block
/// (clamped at an odd edge).
fn half(w: usize, h: usize, px: &[u8]) -> (u32, u32, Vec<u8>) {
    use rayon::prelude::*;
    let (nw, nh) = ((w / 2).max(1), (h / 2).max(1));
    let mut out = vec![0u8; nw * nh * 4];
    out.par_chunks_mut(nw * 4).enumerate().for_each(|(y, row)| {
        let r0 = &px[(2 * y).min(h - 1) * w * 4..][..w * 4];
        let r1 = &px[(2 * y + 1).min(h - 1) * w * 4..][..w * 4];
        for (x, t) in row.chunks_exact_mut(4).enumerate() {
            let (a, b) = ((2 * x).min(w - 1) * 4, (2 * x + 1).min(w - 1) * 4);
            for (k, v) in t.iter_mut().enumerate() {
                let s = r0[a + k] as u32 + r0[b + k] as u32 + r1[a + k] as u32 + r1[b + k] as u32;
                *v = ((s + 2) / 4) as u8;
            }
        }
    });
    (nw as u32, nh as u32, out)
}

/// A texture's views for one draw: the normal map, ORM and emissive (the bake's or 1 × 1
/// defaults), and whether the normal map is the bake's.
struct ChannelViews {
    normal: wgpu::TextureView,
    orm: wgpu::TextureView,
    emissive: wgpu::TextureView,
    has_normal: bool,
    has_orm: bool,
}

/// `channels` on the GPU, at `baked`'s size; each one missing (or not of that size) a 1 × 1
/// default: flat normal, (occlusion, roughness, metallic) = (1, 1, 0), no emission.
fn upload_channels(
    engine: &Engine,
    baked: &PreviewTexture,
    channels: &PreviewChannels,
) -> ChannelViews {
    use wgpu::TextureFormat::{Rgba8Unorm, Rgba8UnormSrgb};
    let len = baked.width as usize * baked.height as usize * 4;
    let given = |c: &Option<Vec<u8>>| c.as_ref().is_some_and(|px| px.len() == len);
    let up = |c: &Option<Vec<u8>>, default: [u8; 4], format| match c {
        Some(px) if px.len() == len => {
            upload_texture(engine, baked.width, baked.height, px, format)
        }
        _ => upload_texture(engine, 1, 1, &default, format),
    };
    ChannelViews {
        normal: up(&channels.normal, [128, 128, 255, 255], Rgba8Unorm),
        orm: up(&channels.orm, [255, 255, 0, 255], Rgba8Unorm),
        emissive: up(&channels.emissive, [0, 0, 0, 255], Rgba8UnormSrgb),
        has_normal: given(&channels.normal),
        has_orm: given(&channels.orm),
    }
}

/// The baked colour texture and its mips on the GPU.
fn upload_colour(engine: &Engine, baked: &PreviewTexture) -> wgpu::TextureView {
    let format = wgpu::TextureFormat::Rgba8UnormSrgb;
    upload_texture(engine, baked.width, baked.height, &baked.rgba8, format)
}

/// An RGBA8 image and its mips on the GPU in `format`.
fn upload_texture(
    engine: &Engine,
    width: u32,
    height: u32,
    rgba8: &[u8],
    format: wgpu::TextureFormat,
) -> wgpu::TextureView {
    let (ctx, dev) = (&engine.ctx, &engine.ctx.device);
    let levels = mip_chain(width, height, rgba8);
    let tex = dev.create_texture(&wgpu::TextureDescriptor {
        label: Some("preview.baked"),
        size: wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        },
        mip_level_count: levels.len() as u32,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    for (i, (w, h, px)) in levels.iter().enumerate() {
        ctx.queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: &tex,
                mip_level: i as u32,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            px,
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(w * 4),
                rows_per_image: Some(*h),
            },
            wgpu::Extent3d {
                width: *w,
                height: *h,
                depth_or_array_layers: 1,
            },
        );
    }
    tex.create_view(&Default::default())
}

/// One view-uniform bind group per side: orthographic, from 20° above, at 90° steps; the key
/// light above and right of the camera (as the preview's one light always was), the fill left
/// of it and a little below.
fn view_groups(
    engine: &Engine,
    mesh: &LoadedMesh,
    [view, second, third]: [&wgpu::TextureView; 3],
    channels: &ChannelViews,
    sampler: &wgpu::Sampler,
) -> Vec<(wgpu::BindGroup, wgpu::Buffer)> {
    let dev = &engine.ctx.device;
    let (lo, hi) = (
        Vec3::from(mesh.stats.bbox_min),
        Vec3::from(mesh.stats.bbox_max),
    );
    let center = 0.5 * (lo + hi);
    let r = 0.5 * (hi - lo).length().max(1e-6);
    let mut groups = Vec::new();
    for k in 0..4 {
        let az = k as f32 * std::f32::consts::FRAC_PI_2;
        let el = 20f32.to_radians();
        let dir = Vec3::new(az.sin() * el.cos(), el.sin(), az.cos() * el.cos());
        let eye = center + dir * 2.0 * r;
        let vp = Mat4::orthographic_rh(-r, r, -r, r, 0.5 * r, 3.5 * r)
            * Mat4::look_at_rh(eye, center, Vec3::Y);
        let light = (dir + Vec3::new(0.3, 0.5, 0.0)).normalize();
        let right = Vec3::Y.cross(dir).normalize();
        let fill = (dir - 0.9 * right - 0.2 * Vec3::Y).normalize();
        let flag = |b: bool| if b { 1.0 } else { 0.0 };
        let u = ViewUniform {
            view_proj: vp.to_cols_array_2d(),
            light: light.extend(0.0).to_array(),
            fill: fill.extend(0.0).to_array(),
            eye: dir.extend(0.0).to_array(),
            flags: [flag(channels.has_normal), flag(channels.has_orm), 0.0, 0.0],
        };
        let buf = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("preview.view"),
            contents: bytemuck::bytes_of(&u),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let bg = crate::gpu::pipelines::make_bind_group(
            dev,
            &engine.pipes.preview.layout,
            "preview",
            &[
                (0, buf.as_entire_binding()),
                (1, wgpu::BindingResource::TextureView(view)),
                (2, wgpu::BindingResource::Sampler(sampler)),
                (3, wgpu::BindingResource::TextureView(second)),
                (4, wgpu::BindingResource::TextureView(third)),
                (5, wgpu::BindingResource::TextureView(&channels.normal)),
                (6, wgpu::BindingResource::TextureView(&channels.orm)),
                (7, wgpu::BindingResource::TextureView(&channels.emissive)),
            ],
        );
        groups.push((bg, buf));
    }
    groups
}

/// Per split vertex, the first and third textures' weights: `_PELT_BLEND` and `_PELT_BRIDGE`
/// when blending, else 1 and 0 (the second's is 1 minus both), as a vertex buffer.
fn weight_buffer(engine: &Engine, mesh: &LoadedMesh, baked: &PreviewTexture) -> wgpu::Buffer {
    let dev = &engine.ctx.device;
    let n = mesh.mesh.positions.len();
    let blending = baked.second.is_some() && mesh.mesh.blend.len() == n;
    let first: Vec<f32> = match blending {
        true => mesh.mesh.blend.clone(),
        false => vec![1.0; n],
    };
    let third = match &baked.third {
        Some(_) if blending && mesh.mesh.bridge.len() == n => mesh.mesh.bridge.clone(),
        _ => vec![0.0; n],
    };
    let weights: Vec<[f32; 2]> = first.into_iter().zip(third).map(|(a, c)| [a, c]).collect();
    dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("preview.weight"),
        contents: bytemuck::cast_slice(&weights),
        usage: wgpu::BufferUsages::VERTEX,
    })
}

/// Each view's bind group (with its uniform buffer) for one texture, and the triangle ranges
/// drawn with it.
type ViewDraw = (
    Vec<(wgpu::BindGroup, wgpu::Buffer)>,
    Vec<std::ops::Range<u32>>,
);

/// Per split vertex, the tangent frame on `uv_set` (`crate::mesh::tangents`, xyz and the
/// bitangent's sign) as a vertex buffer; without a normal map (`needed` false) zeros, unread.
fn tangent_buffer(engine: &Engine, mesh: &LoadedMesh, uv_set: usize, needed: bool) -> wgpu::Buffer {
    let dev = &engine.ctx.device;
    let n = mesh.mesh.positions.len();
    let tangents = match needed {
        true => crate::mesh::tangents::tangents(&mesh.mesh, uv_set),
        false => vec![[0.0; 4]; n],
    };
    dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("preview.tangent"),
        contents: bytemuck::cast_slice(&tangents),
        usage: wgpu::BufferUsages::VERTEX,
    })
}

/// Draws the four views (4× MSAA, resolved) and copies the result into a mappable buffer;
/// `tangents`: whether a draw has a normal map.
fn draw(
    engine: &Engine,
    mesh: &LoadedMesh,
    baked: &PreviewTexture,
    tangents: bool,
    draws: &[ViewDraw],
) -> wgpu::Buffer {
    let (ctx, dev) = (&engine.ctx, &engine.ctx.device);
    let side = 2 * VIEW_SIDE;
    let uv_buf = &mesh.gpu.uvs[baked.uv_set];
    let uv2_buf = &mesh.gpu.uvs[baked.second.as_ref().map_or(baked.uv_set, |t| t.uv_set)];
    let uv3_buf = &mesh.gpu.uvs[baked.third.as_ref().map_or(baked.uv_set, |t| t.uv_set)];
    let weight_buf = weight_buffer(engine, mesh, baked);
    let tangent_buf = tangent_buffer(engine, mesh, baked.uv_set, tangents);
    let mk = |label: &str, format, samples, usage| {
        dev.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d {
                width: side,
                height: side,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: samples,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage,
            view_formats: &[],
        })
    };
    let msaa = mk(
        "preview.msaa",
        PREVIEW_FORMAT,
        4,
        wgpu::TextureUsages::RENDER_ATTACHMENT,
    );
    let resolved = mk(
        "preview.resolved",
        PREVIEW_FORMAT,
        1,
        wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
    );
    let depth = mk(
        "preview.depth",
        wgpu::TextureFormat::Depth32Float,
        4,
        wgpu::TextureUsages::RENDER_ATTACHMENT,
    );
    let readback = dev.create_buffer(&wgpu::BufferDescriptor {
        label: Some("preview.readback"),
        size: (side * side * 4) as u64,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut enc = dev.create_command_encoder(&Default::default());
    {
        let mview = msaa.create_view(&Default::default());
        let rview = resolved.create_view(&Default::default());
        let dview = depth.create_view(&Default::default());
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("preview"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &mview,
                depth_slice: None,
                resolve_target: Some(&rview),
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color {
                        r: 0.8,
                        g: 0.82,
                        b: 0.85,
                        a: 1.0,
                    }),
                    store: wgpu::StoreOp::Discard,
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &dview,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Discard,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&engine.pipes.preview.pipeline);
        pass.set_vertex_buffer(0, mesh.gpu.split_positions.slice(..));
        pass.set_vertex_buffer(1, mesh.gpu.split_normals.slice(..));
        pass.set_vertex_buffer(2, uv_buf.slice(..));
        pass.set_vertex_buffer(3, uv2_buf.slice(..));
        pass.set_vertex_buffer(4, weight_buf.slice(..));
        pass.set_vertex_buffer(5, uv3_buf.slice(..));
        pass.set_vertex_buffer(6, tangent_buf.slice(..));
        pass.set_index_buffer(mesh.gpu.split_tris.slice(..), wgpu::IndexFormat::Uint32);
        for k in 0..4u32 {
            let (x, y) = ((k % 2) * VIEW_SIDE, (k / 2) * VIEW_SIDE);
            pass.set_viewport(
                x as f32,
                y as f32,
                VIEW_SIDE as f32,
                VIEW_SIDE as f32,
                0.0,
                1.0,
            );
            for (groups, ranges) in draws {
                pass.set_bind_group(0, &groups[k as usize].0, &[]);
                for r in ranges {
                    pass.draw_indexed(3 * r.start..3 * r.end, 0, 0..1);
                }
            }
        }
    }
    enc.copy_texture_to_buffer(
        resolved.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer: &readback,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(side * 4),
                rows_per_image: Some(side),
            },
        },
        wgpu::Extent3d {
            width: side,
            height: side,
            depth_or_array_layers: 1,
        },
    );
    ctx.queue.submit([enc.finish()]);
    readback
}

#[cfg(test)]
mod mip_tests {
    /// The mip chain (rows split between the cores) against the plain loop it replaced, on
    /// images of odd and even sides: every level, byte for byte (the preview's bytes did not
    /// change), down to 1 × 1.
    #[test]
    fn mip_chain_is_the_box_filter() {
        let reference = |w: u32, h: u32, px: &[u8]| {
            let (nw, nh) = ((w / 2).max(1), (h / 2).max(1));
            let mut out = vec![0u8; (nw * nh * 4) as usize];
            for y in 0..nh {
                for x in 0..nw {
                    for k in 0..4 {
                        let mut s = 0u32;
                        for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                            let (sx, sy) = ((2 * x + dx).min(w - 1), (2 * y + dy).min(h - 1));
                            s += px[((sy * w + sx) * 4 + k) as usize] as u32;
                        }
                        out[((y * nw + x) * 4 + k) as usize] = ((s + 2) / 4) as u8;
                    }
                }
            }
            (nw, nh, out)
        };
        for (w, h) in [(13u32, 7u32), (16, 16), (1, 9), (64, 3)] {
            let px: Vec<u8> = (0..w * h * 4).map(|i| (i * 37 % 251) as u8).collect();
            let chain = super::mip_chain(w, h, &px);
            let mut want = vec![(w, h, px.clone())];
            while want.last().is_some_and(|l| l.0 > 1 || l.1 > 1) {
                let (lw, lh, l) = want.last().unwrap().clone();
                want.push(reference(lw, lh, &l));
            }
            assert_eq!(chain, want, "{w} x {h}");
        }
    }
}
