// SPDX-License-Identifier: MIT OR Apache-2.0
//! Stage 1, images: the base and every layer's image and mask decoded, checked against the
//! adapter's limits and uploaded (layer images with premultiplied mipmaps). Each file is decoded once
//! per bake, and layer images and masks stay on the GPU between bakes (the engine's
//! [`super::engine::ImageCache`]: a batch of jobs sharing a logo decodes it once); the
//! material's texture once per mesh.

use super::engine::{Engine, GpuImage, ImageKey, LoadedMesh};
use crate::error::{Error, Result};
use crate::io::image::LinearImage;
use crate::io::job::{Base, Job};
use std::borrow::Cow;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Every image a bake samples, on the GPU.
pub struct Images {
    /// The base texture.
    pub base: Arc<GpuImage>,
    /// Per layer: image and optional mask.
    pub layers: Vec<(Arc<GpuImage>, Option<Arc<GpuImage>>)>,
    /// A 1×1 white image bound where a layer has no mask.
    pub dummy: GpuImage,
    /// Every layer's thin-plate-spline warp ([`crate::maps::warp::Tps::pack`]), one after
    /// another (16 bytes when no layer warps).
    pub warps: Arc<wgpu::Buffer>,
    /// Per layer: where its warp starts in `warps` (vec4s), `None` without one.
    pub warp_at: Vec<Option<u32>>,
}

impl Images {
    /// The images per unit: unit u draws the image of job layer `origin[u].0` (shared, not copied).
    pub fn for_units(self, origin: &[(usize, usize)]) -> Images {
        Images {
            layers: origin
                .iter()
                .map(|&(l, _)| self.layers[l].clone())
                .collect(),
            warp_at: origin.iter().map(|&(l, _)| self.warp_at[l]).collect(),
            ..self
        }
    }
}

/// Where one layer image or mask comes from.
enum Source<'a> {
    /// A text layer's line.
    Text(&'a crate::io::job::Layer),
    /// A file (an SVG at the raster size), a mask when `raw`.
    File {
        path: &'a Path,
        raster: Option<[u32; 2]>,
        raw: bool,
    },
}

/// Loads and uploads the base and every layer's image and mask (vector images at each layer's
/// [`crate::io::job::Layer::raster`]). The images the engine does not keep yet are decoded (or
/// rendered) on every core, as many at a time as there are threads, and uploaded in job order.
pub fn load(engine: &Engine, mesh: &LoadedMesh, job: &Job) -> Result<Images> {
    let base = load_base(engine, mesh, job)?;
    // Every layer's image and mask: its key, where it comes from, the field that names it.
    let mut wanted: Vec<(ImageKey, Source<'_>, String)> = Vec::new();
    let mut keys = Vec::with_capacity(job.layers.len());
    for (i, l) in job.layers.iter().enumerate() {
        let image = match &l.text {
            Some(t) => {
                let curve = l.ribbon.as_ref().map(|_| l.size[0]);
                let key = (text_key(&t.svg(curve)), false, 0, None, l.raster);
                (key, Source::Text(l))
            }
            None => (
                file_key(&l.image, false, l.raster),
                Source::File {
                    path: &l.image,
                    raster: l.raster,
                    raw: false,
                },
            ),
        };
        let mask = l.mask.as_deref().map(|p| {
            let source = Source::File {
                path: p,
                raster: l.raster,
                raw: true,
            };
            (file_key(p, true, l.raster), source)
        });
        keys.push((image.0.clone(), mask.as_ref().map(|m| m.0.clone())));
        wanted.push((image.0, image.1, format!("layers[{i}].image")));
        if let Some((key, source)) = mask {
            wanted.push((key, source, format!("layers[{i}].mask")));
        }
    }
    let mut cache: HashMap<ImageKey, Arc<GpuImage>> = HashMap::new();
    let mut missing = Vec::new();
    for (key, source, field) in wanted {
        if cache.contains_key(&key) || missing.iter().any(|m: &(ImageKey, _, _)| m.0 == key) {
            continue;
        }
        match engine.images.lock().expect("image cache").get(&key) {
            Some(gi) => {
                cache.insert(key, gi);
            }
            None => missing.push((key, source, field)),
        }
    }
    let make = |(_, source, field): &(ImageKey, Source<'_>, String)| match source {
        Source::Text(l) => checked(engine, l.colour_image()?, &l.image, job, field),
        Source::File { path, raster, raw } => {
            checked_image(engine, path, *raster, job, field, *raw)
        }
    };
    use rayon::prelude::*;
    for batch in batches(&missing) {
        let made: Vec<Result<LinearImage>> = batch.par_iter().map(make).collect();
        for ((key, _, _), im) in batch.iter().zip(made) {
            let im = im?;
            let label = if key.1 { "layer.mask" } else { "layer.image" };
            let gi = Arc::new(upload_image(engine, &im, true, label));
            // f32 or f16 texels and a third more for the mipmaps.
            let bytes = im.width as u64 * im.height as u64 * 16 * 4 / 3;
            let mut kept = engine.images.lock().expect("image cache");
            kept.put(key.clone(), gi.clone(), bytes);
            cache.insert(key.clone(), gi);
        }
    }
    let layers = keys
        .into_iter()
        .map(|(image, mask)| (cache[&image].clone(), mask.map(|m| cache[&m].clone())))
        .collect();
    let dummy = upload_image(
        engine,
        &LinearImage::solid(1, 1, [1.0; 4]),
        false,
        "bake.dummy",
    );
    let (warps, warp_at) = warps(engine, job);
    Ok(Images {
        base,
        layers,
        dummy,
        warps,
        warp_at,
    })
}

/// The job layers' warps fitted and packed into one buffer, and where each starts.
fn warps(engine: &Engine, job: &Job) -> (Arc<wgpu::Buffer>, Vec<Option<u32>>) {
    let mut packed: Vec<[f32; 4]> = Vec::new();
    let at = job
        .layers
        .iter()
        .map(|l| {
            let t = crate::maps::warp::Tps::fit(&l.warp)?;
            let start = packed.len() as u32;
            packed.extend(t.pack());
            Some(start)
        })
        .collect();
    let buf = engine.ctx.storage_init(
        "bake.warps",
        bytemuck::cast_slice(&packed),
        wgpu::BufferUsages::empty(),
    );
    (Arc::new(buf), at)
}

/// Uploads `img` as a sampled texture (with premultiplied mipmaps when `mips`), in the engine's
/// image format (f32, or f16 where f32 is not filterable).
pub fn upload_image(engine: &Engine, img: &LinearImage, mips: bool, label: &str) -> GpuImage {
    // Without mips, the image itself: a 1024² base is 16 MiB of f32 texels, copied by the queue
    // once already.
    let levels: Vec<Cow<'_, LinearImage>> = match mips {
        true => img
            .premultiplied_mips()
            .into_iter()
            .map(Cow::Owned)
            .collect(),
        false => vec![Cow::Borrowed(img)],
    };
    let format = engine.pipes.image_format;
    let tex = engine.ctx.device.create_texture(&wgpu::TextureDescriptor {
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
        let (bytes, bpp): (Cow<'_, [u8]>, u32) = if format == wgpu::TextureFormat::Rgba32Float {
            (Cow::Borrowed(bytemuck::cast_slice(&l.pixels)), 16)
        } else {
            let h: Vec<u16> = l.pixels.iter().flatten().map(|v| f32_to_f16(*v)).collect();
            (Cow::Owned(bytemuck::cast_slice(&h).to_vec()), 8)
        };
        engine.ctx.queue.write_texture(
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

/// The base texture: the material's (uploaded once per mesh), an image, or a solid colour; for a
/// transfer, its source (which `bake::transfer` resamples).
fn load_base(engine: &Engine, mesh: &LoadedMesh, job: &Job) -> Result<Arc<GpuImage>> {
    load_base_of(engine, mesh, job, &job.base)
}

fn load_base_of(
    engine: &Engine,
    mesh: &LoadedMesh,
    job: &Job,
    base: &Base,
) -> Result<Arc<GpuImage>> {
    let solid = |c: [f32; 4]| {
        Arc::new(upload_image(
            engine,
            &LinearImage::solid(1, 1, c),
            false,
            "bake.base",
        ))
    };
    Ok(match base {
        Base::Transfer { source, .. } => return load_base_of(engine, mesh, job, source),
        Base::Color(c) => solid(*c),
        Base::Image(p) => {
            let img = checked_image(
                engine,
                p,
                Some([job.width, job.height]),
                job,
                "texture.base",
                false,
            )?;
            Arc::new(upload_image(engine, &img, false, "bake.base"))
        }
        Base::Material => match &mesh.mesh.material {
            Some(m) => match &m.base_color_texture {
                Some(t) => mesh
                    .material_texture
                    .get_or_init(|| Arc::new(upload_image(engine, t, false, "mesh.base_color")))
                    .clone(),
                None => solid(m.base_color_factor),
            },
            None => solid([0.5, 0.5, 0.5, 1.0]),
        },
    })
}

/// The most decoded pixels a batch of the images stage holds at once (2²⁶: 1 GiB as f32 RGBA),
/// unless one image alone is larger.
const BATCH_PIXELS: u64 = 1 << 26;

/// `missing` in batches decoded together: as many as there are threads, and together at most
/// [`BATCH_PIXELS`] by their sizes (a file's from its header, a vector image's raster size).
fn batches<'a, 'b>(
    missing: &'b [(ImageKey, Source<'a>, String)],
) -> impl Iterator<Item = &'b [(ImageKey, Source<'a>, String)]> {
    let threads = rayon::current_num_threads().max(1);
    let pixels = |(key, source, _): &(ImageKey, Source<'_>, String)| -> u64 {
        let px = match (key.4, source) {
            (Some(r), _) => (r[0], r[1]),
            (None, Source::File { path, .. }) => {
                crate::io::vector::dimensions(path).unwrap_or((1, 1))
            }
            (None, Source::Text(_)) => (crate::io::vector::DEFAULT_SIDE, 1),
        };
        px.0 as u64 * px.1 as u64
    };
    let mut start = 0;
    std::iter::from_fn(move || {
        if start >= missing.len() {
            return None;
        }
        let mut end = start + 1;
        let mut total = pixels(&missing[start]);
        while end < missing.len() && end - start < threads {
            total += pixels(&missing[end]);
            if total > BATCH_PIXELS {
                break;
            }
            end += 1;
        }
        let batch = &missing[start..end];
        start = end;
        Some(batch)
    })
}

/// The cache key of an image file: its path, length and modification time, and the size a
/// vector image is rendered at.
fn file_key(path: &Path, raw: bool, raster: Option<[u32; 2]>) -> ImageKey {
    let meta = std::fs::metadata(path).ok();
    let raster = raster.filter(|_| crate::io::vector::is_svg(path));
    (
        path.to_path_buf(),
        raw,
        meta.as_ref().map_or(0, |m| m.len()),
        meta.and_then(|m| m.modified().ok()),
        raster,
    )
}

/// The path part of a text's cache key: its SVG's hash (the text, font, colour, layout).
fn text_key(svg: &str) -> PathBuf {
    use std::hash::{Hash, Hasher};
    let mut h = std::collections::hash_map::DefaultHasher::new();
    svg.hash(&mut h);
    PathBuf::from(format!("<text {:016x} {}>", h.finish(), svg.len()))
}

/// An image file (an SVG at `raster`), refused (naming `field`) when it is larger than the
/// adapter's textures.
pub(crate) fn checked_image(
    engine: &Engine,
    path: &Path,
    raster: Option<[u32; 2]>,
    job: &Job,
    field: &str,
    raw: bool,
) -> Result<LinearImage> {
    let img = crate::io::vector::load_image(path, raster, raw)?;
    checked(engine, img, path, job, field)
}

/// `img` (read from `path`), refused (naming `field`) when it is larger than the adapter's
/// textures.
fn checked(
    engine: &Engine,
    img: LinearImage,
    path: &Path,
    job: &Job,
    field: &str,
) -> Result<LinearImage> {
    let max = engine.ctx.max_texture_side();
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

/// A mask image: its stored values, not sRGB-decoded (an SVG at its own size).
pub fn load_raw(path: &Path) -> Result<LinearImage> {
    crate::io::vector::load_image(path, None, true)
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
