// SPDX-License-Identifier: MIT OR Apache-2.0
//! `decalbake extract`: texture extraction, the inverse of a bake (Sun et al. 2013, section 4.2,
//! "texture cloning"). The job's texture (its `texture.base`: the material's texture, an image or
//! a colour) is rendered along one layer's map into a flat image: every triangle the map covers is
//! drawn at its image coordinates carrying its UV, and the texture is sampled there
//! (`wgsl/output/extract_raster.wgsl`; CPU twin [`extract_cpu`]). The image's alpha is the
//! coverage times the layer's mask, or, with `--matte`, an automatic matte ([`super::matte`]).
//! The PNG can be the `image` of a ribbon or decal on another model.
//!
//! The output spans the layer's image rectangle: a decal's image, a ribbon's whole strip (a tiled
//! ribbon's copies side by side), x to the right and y down as in the layer's image. Its default
//! size is the layer image's (times the copies, rounded, for a tiled ribbon). A warp is not
//! undone: the output is the map's rectangle, as the unwarped image lies in it.

use crate::bake::{Engine, LoadedMesh};
use crate::error::{Error, Result};
use crate::io::image::LinearImage;
use crate::io::job::{Base, Job, LayerKind};

/// What `decalbake extract` produced.
pub struct Extracted {
    /// The flat image: linear, straight alpha.
    pub image: LinearImage,
    /// Pixels the map covered.
    pub covered: usize,
    /// The automatic matte's figures (`--matte`).
    pub matte: Option<super::matte::MatteReport>,
}

/// Layer `index`'s texture extracted into a flat image of `size` (default: [`Flat::size`]), its
/// alpha the coverage times the layer's mask, or the automatic matte when `matte`.
pub fn extract(
    engine: &Engine,
    mesh: &LoadedMesh,
    job: &Job,
    index: usize,
    (size, matte): (Option<[u32; 2]>, bool),
) -> Result<Extracted> {
    if job
        .layers
        .get(index)
        .is_some_and(|l| l.kind == LayerKind::Stroke)
    {
        return Err(Error::job(
            &job.source,
            format!("layers[{index}].kind"),
            "extract follows a decal's or a ribbon's map; this layer is a stroke (many small maps)",
        ));
    }
    let tex = source_texture(engine, mesh, job)?;
    let flat = flat_triangles(engine, mesh, job, index)?;
    let size = size.unwrap_or(flat.size);
    crate::io::image::check_image_size(size[0], size[1])
        .map_err(|d| Error::job(&job.source, "--size", d))?;
    let max = engine.ctx.max_texture_side();
    if size[0] > max || size[1] > max {
        return Err(Error::job(
            &job.source,
            "--size",
            format!(
                "{}x{} is above this adapter's texture limit of {max}",
                size[0], size[1]
            ),
        ));
    }
    let mut image = extract_gpu(engine, &flat, &tex, size)?;
    let covered = image.pixels.iter().filter(|p| p[3] > 0.0).count();
    if covered == 0 {
        return Err(Error::job(
            &job.source,
            format!("layers[{index}]"),
            "its map covers no triangle whose three vertices it reaches; nothing to extract",
        ));
    }
    let report = if matte {
        let sys = super::matte::system(&image);
        let (alpha, solve) = super::matte::solve_gpu(engine, &sys)?;
        super::matte::apply(&mut image, &sys, &alpha);
        Some(super::matte::MatteReport {
            unknowns: sys.b.len(),
            border_colors: sys.border_colors,
            solve,
        })
    } else {
        if let Some(m) = &job.layers[index].mask {
            let copies = flat.size[0] as f32 / layer_width(job, index)? as f32;
            apply_mask(&mut image, &crate::bake::load_raw(m)?, copies.max(1.0));
        }
        None
    };
    Ok(Extracted {
        image,
        covered,
        matte: report,
    })
}

/// The width of layer `index`'s image.
fn layer_width(job: &Job, index: usize) -> Result<u32> {
    Ok(job.layer_at(index)?.image_dimensions(&job.source, index)?.0)
}

/// Multiplies each pixel's alpha by the mask (red × alpha) at the same image point, the mask
/// repeated `copies` times along x as a tiled ribbon's raster repeats it.
fn apply_mask(img: &mut LinearImage, mask: &LinearImage, copies: f32) {
    let (w, h) = (img.width as f32, img.height as f32);
    for (i, p) in img.pixels.iter_mut().enumerate() {
        let (x, y) = ((i as u32 % img.width) as f32, (i as u32 / img.width) as f32);
        let m = mask.bilinear(((x + 0.5) / w * copies).fract(), (y + 0.5) / h, false);
        p[3] *= m[0] * m[3];
    }
}

/// The flat triangles of a layer's map: per covered triangle three corners, each image
/// coordinates (x right, y down, [0, 1]² the output) and texture UV.
pub struct Flat {
    /// `[x, y, u, v]` per corner, three per triangle.
    pub corners: Vec<[f32; 4]>,
    /// The default output size (the layer image's, times a tiled ribbon's copies).
    pub size: [u32; 2],
}

/// Layer `index`'s map as flat triangles: each mesh triangle whose three vertices the map reaches.
pub fn flat_triangles(engine: &Engine, mesh: &LoadedMesh, job: &Job, index: usize) -> Result<Flat> {
    let layer = job.layer_at(index)?;
    let (iw, ih) = layer.image_dimensions(&job.source, index)?;
    // Image coordinates per welded vertex.
    let mut img: Vec<Option<[f32; 2]>> = vec![None; mesh.topo.positions.len()];
    let mut copies = 1.0f32;
    match layer.kind {
        LayerKind::Ribbon => {
            let (coords, r, [length, width]) = engine.ribbon_map(mesh, job, index)?;
            let [a, b, c, d] = r.xform;
            for (v, co) in coords.iter().enumerate().filter(|(_, co)| co[3] > 0.5) {
                let (x, y) = (a * co[0] + b, c * co[1] + d);
                img[v] = Some([x / length + 0.5, 0.5 - y / width]);
            }
            copies = r.repeats.max(1.0);
        }
        _ => {
            let (rows, cone) = engine.layer_param_map(mesh, job, index)?;
            if cone.is_some() {
                // The bake opens such a chart per texel (the cut runs through triangles); drawn per
                // vertex, the triangles across the cut would smear over the image.
                return Err(Error::job(
                    &job.source,
                    format!("layers[{index}].method"),
                    "this decal's chart is opened at a tip (a cone chart); extract does not follow those yet: move the decal off the tip or use \"expmap\"",
                ));
            }
            let [w, h] = layer.size;
            for r in rows {
                img[r.vertex as usize] = Some([r.uv[0] / w + 0.5, 0.5 - r.uv[1] / h]);
            }
        }
    }
    let uvs = &mesh.mesh.uv_sets[job.uv_set as usize];
    let mut corners = Vec::new();
    for (split, welded) in mesh.mesh.triangles.iter().zip(&mesh.topo.triangles) {
        let [Some(p0), Some(p1), Some(p2)] = welded.map(|v| img[v as usize]) else {
            continue;
        };
        for (p, s) in [p0, p1, p2].into_iter().zip(split) {
            let uv = uvs[*s as usize];
            corners.push([p[0], p[1], uv.x, uv.y]);
        }
    }
    Ok(Flat {
        corners,
        size: [((iw as f32 * copies).round() as u32).max(1), ih],
    })
}

/// The texture `decalbake extract` reads: the job's base on its own UV set (an image within the
/// adapter's texture limit, as a bake's base).
pub fn source_texture(engine: &Engine, mesh: &LoadedMesh, job: &Job) -> Result<LinearImage> {
    Ok(match &job.base {
        Base::Image(p) => crate::bake::checked_image(engine, p, None, job, "texture.base", false)?,
        Base::Color(c) => LinearImage::solid(1, 1, *c),
        Base::Material => match &mesh.mesh.material {
            Some(m) => match &m.base_color_texture {
                Some(t) => t.clone(),
                None => LinearImage::solid(1, 1, m.base_color_factor),
            },
            None => LinearImage::solid(1, 1, [0.5, 0.5, 0.5, 1.0]),
        },
        Base::Transfer { .. } => {
            return Err(Error::job(
                &job.source,
                "texture.base",
                "a transfer base lies on another UV set; extract from a job whose base is the texture on the set it bakes (an image, or \"material\")",
            ))
        }
    })
}

/// The flat triangles rendered on the GPU into a `size` image sampling `tex` (straight alpha;
/// uncovered pixels transparent black).
pub fn extract_gpu(
    engine: &Engine,
    flat: &Flat,
    tex: &LinearImage,
    size: [u32; 2],
) -> Result<LinearImage> {
    let ctx = &engine.ctx;
    let dev = &ctx.device;
    let gpu_tex = crate::bake::upload_image(engine, tex, false, "extract.texture");
    let corners = ctx.storage_init(
        "extract.corners",
        bytemuck::cast_slice(&flat.corners),
        wgpu::BufferUsages::empty(),
    );
    let sampler = dev.create_sampler(&wgpu::SamplerDescriptor {
        label: Some("extract.sampler"),
        address_mode_u: wgpu::AddressMode::Repeat,
        address_mode_v: wgpu::AddressMode::Repeat,
        mag_filter: wgpu::FilterMode::Linear,
        min_filter: wgpu::FilterMode::Linear,
        ..Default::default()
    });
    let format = engine.pipes.layer_format;
    let target = dev.create_texture(&wgpu::TextureDescriptor {
        label: Some("extract.target"),
        size: wgpu::Extent3d {
            width: size[0],
            height: size[1],
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    });
    let view = target.create_view(&Default::default());
    let pipe = &engine.pipes.extract_raster;
    let bg = crate::gpu::pipelines::make_bind_group(
        dev,
        &pipe.layout,
        "extract_raster",
        &[
            (0, corners.as_entire_binding()),
            (1, wgpu::BindingResource::TextureView(&gpu_tex.view)),
            (2, wgpu::BindingResource::Sampler(&sampler)),
        ],
    );
    let bpp = format.block_copy_size(None).expect("a colour format");
    let row = (size[0] * bpp).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
    let readback = dev.create_buffer(&wgpu::BufferDescriptor {
        label: Some("extract.readback"),
        size: row as u64 * size[1] as u64,
        usage: wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut enc = dev.create_command_encoder(&Default::default());
    {
        let mut pass = crate::gpu::cleared_pass(&mut enc, "extract_raster", &[&view]);
        pass.set_pipeline(&pipe.pipeline);
        pass.set_bind_group(0, &bg, &[]);
        pass.draw(0..flat.corners.len() as u32, 0..1);
    }
    enc.copy_texture_to_buffer(
        target.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer: &readback,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(row),
                rows_per_image: Some(size[1]),
            },
        },
        wgpu::Extent3d {
            width: size[0],
            height: size[1],
            depth_or_array_layers: 1,
        },
    );
    ctx.queue.submit([enc.finish()]);
    let bytes = ctx.read_buffer(&readback, row as u64 * size[1] as u64, "extract")?;
    let mut pixels = Vec::with_capacity((size[0] * size[1]) as usize);
    for y in 0..size[1] as usize {
        let line = &bytes[y * row as usize..][..(size[0] * bpp) as usize];
        if bpp == 16 {
            pixels.extend(bytemuck::pod_collect_to_vec::<u8, [f32; 4]>(line));
        } else {
            let h: Vec<u16> = bytemuck::pod_collect_to_vec(line);
            pixels.extend(h.chunks(4).map(|c| [0, 1, 2, 3].map(|k| half_to_f32(c[k]))));
        }
    }
    Ok(LinearImage {
        width: size[0],
        height: size[1],
        pixels,
    })
}

/// An IEEE half's value (the GL backend's f16 targets).
fn half_to_f32(h: u16) -> f32 {
    let (sign, exp, frac) = ((h >> 15) as u32, ((h >> 10) & 31) as i32, (h & 1023) as f32);
    let v = match exp {
        0 => frac * 2f32.powi(-24),
        31 => f32::INFINITY,
        e => (1.0 + frac / 1024.0) * 2f32.powi(e - 15),
    };
    if sign == 1 {
        -v
    } else {
        v
    }
}

/// CPU twin of [`extract_gpu`]: each pixel centre takes the last flat triangle that covers it
/// (the GPU's draw order), the texture sampled bilinearly with wrapping at the interpolated UV.
pub fn extract_cpu(flat: &Flat, tex: &LinearImage, size: [u32; 2]) -> LinearImage {
    let (w, h) = (size[0] as usize, size[1] as usize);
    let mut pixels = vec![[0.0f32; 4]; w * h];
    for tri in flat.corners.chunks_exact(3) {
        let tri: [[f32; 4]; 3] = [tri[0], tri[1], tri[2]];
        let p = tri.map(|c| glam::Vec2::new(c[0] * w as f32, c[1] * h as f32));
        let lo = p[0].min(p[1]).min(p[2]).floor().max(glam::Vec2::ZERO);
        let hi = p[0]
            .max(p[1])
            .max(p[2])
            .ceil()
            .min(glam::Vec2::new(w as f32, h as f32));
        for y in lo.y as usize..hi.y as usize {
            for x in lo.x as usize..hi.x as usize {
                let c = glam::Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                let Some(bc) = crate::bake::cpu::barycentric(c, p[0], p[1], p[2]) else {
                    continue;
                };
                let uv = [2, 3].map(|k| bc[0] * tri[0][k] + bc[1] * tri[1][k] + bc[2] * tri[2][k]);
                pixels[y * w + x] = tex.bilinear(uv[0], uv[1], true);
            }
        }
    }
    LinearImage {
        width: size[0],
        height: size[1],
        pixels,
    }
}
