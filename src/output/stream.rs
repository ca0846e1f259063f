// SPDX-License-Identifier: MIT OR Apache-2.0
//! A bake by tiles written as it is baked: each band of rows (`bake/bands.rs`), padded, goes
//! straight into the PNG (`io::image::png_rows`, the same bytes as a PNG encoded whole) or the
//! OpenEXR (`io::image::exr_rows`, the same floats as the linear canvas held whole) in a temporary
//! file beside the texture, so the texture is never whole in memory: a 16384² bake holds a few
//! bands of rows, its tile on the device, and a reduced copy for the preview.
//!
//! What streams: a bake that goes by tiles (`texture.tile`, a texture whose canvas does not fit
//! one storage buffer, or an EXR output) with a finite padding. `"padding": "full"` (a texel may
//! take its colour from anywhere in the texture) and the several-set bakes are baked whole in
//! memory ([`super::write_outputs`]), and so are bakes that paint PBR channels (their textures
//! are baked tile by tile beside the colour's and written whole). Where the job asks for a model, the model embeds the PNG's
//! bytes (read back from the temporary file, or, when the job writes no PNG texture, a PNG
//! written to memory beside the bands), so a model of a huge texture holds its compressed bytes,
//! not its texels.
//! The preview is drawn from a copy of the texture reduced by box filtering to at most
//! [`PREVIEW_MAX`] texels a side (a 512-pixel view samples far coarser mips anyway).
//!
//! Nothing is left half-written: the PNG is renamed into place with the other files only once
//! every band is baked and every other file is ready; a failure removes the temporary file.

use super::{commit, gltf, make_parent, preview, preview_png, tmp_path};
use crate::bake::bands::Band;
use crate::bake::report::Report;
use crate::bake::{Engine, LoadedMesh};
use crate::error::{Error, Result};
use crate::io::image::{exr_rows, png_rows, ExrRows, PngRows};
use crate::io::job::Job;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The largest side of the copy a streamed bake's preview is drawn from.
pub const PREVIEW_MAX: u32 = 2048;

/// Bakes `job` by tiles and writes its files as the bands come (see the module doc); `amend` sees
/// the report before it is written. `None`: this job does not stream, bake it whole
/// ([`Engine::bake_with_progress`], [`super::write_outputs`]).
pub fn write_streamed(
    engine: &Engine,
    mesh: &LoadedMesh,
    job: &Job,
    on_stage: &dyn Fn(&str),
    amend: &dyn Fn(&mut Report),
) -> Result<Option<(Report, Vec<PathBuf>)>> {
    let Some(shape) = crate::bake::streamed_shape(engine, job) else {
        return Ok(None);
    };
    // The PBR channels' textures are baked beside the colour's tile by tile, and held whole: a
    // job that paints them is baked in memory (its limits checked for that).
    if !crate::bake::channels::passes(job).is_empty() {
        return Ok(None);
    }
    // Sizes and memory before the file is begun.
    crate::bake::streamed_limits(engine, mesh, job)?;
    let before = engine.pipelines_spent();
    let mut texture = match &job.out_texture {
        Some(p) => Some(Staged::create(p)?),
        None => None,
    };
    let mut memory = Vec::new();
    let streamed = stream(
        engine,
        mesh,
        (job, shape),
        on_stage,
        (texture.as_mut(), &mut memory),
    );
    let (mut report, reduced) = match streamed.and_then(|r| {
        texture.as_mut().map_or(Ok(()), Staged::flush)?;
        Ok(r)
    }) {
        Ok(r) => r,
        Err(e) => {
            if let Some(t) = texture {
                t.remove();
            }
            return Err(e);
        }
    };
    let t = Instant::now();
    let files = match other_files(engine, mesh, job, (&texture, memory), reduced, &mut report) {
        Ok(files) => files,
        Err(e) => {
            if let Some(t) = texture {
                t.remove();
            }
            return Err(e);
        }
    };
    report.timings.write_ms += t.elapsed().as_secs_f64() * 1000.0;
    engine.note_start(&mut report, before);
    amend(&mut report);
    let mut files = files;
    if let Some(p) = &job.out_report {
        let json = serde_json::to_vec_pretty(&report).expect("the report serializes");
        files.push((p.clone(), json));
    }
    let staged: Vec<(PathBuf, PathBuf)> = texture
        .iter()
        .map(|t| (t.tmp.clone(), t.path.clone()))
        .collect();
    commit(&files, staged)?;
    let written = texture.iter().map(|t| t.path.clone());
    let written = written.chain(files.into_iter().map(|(p, _)| p)).collect();
    Ok(Some((report, written)))
}

/// Bakes the bands into the texture's file (a PNG, or an EXR), a PNG in `memory` where the job
/// asks for a model and the texture is not a PNG file, and a reduced copy for the preview, if the
/// job has one.
fn stream(
    engine: &Engine,
    mesh: &LoadedMesh,
    (job, shape): (&Job, [u32; 2]),
    on_stage: &dyn Fn(&str),
    (texture, memory): (Option<&mut Staged>, &mut Vec<u8>),
) -> Result<(Report, Option<preview::PreviewTexture>)> {
    let path = job.out_texture.as_ref().or(job.out_glb.as_ref());
    let path = path.map_or(Path::new(""), |p| p.as_path());
    let mut reduce = job.out_preview.as_ref().map(|_| Reduction::new(job));
    let size = [job.width, job.height];
    let depth = (job.bit_depth, job.compression);
    let cx = (engine, mesh, job, shape, on_stage, path);
    let glb = job.out_glb.is_some();
    let report = match texture {
        Some(t) if job.exr() => {
            let file = &mut t.out;
            match glb {
                true => png_rows(memory as &mut dyn Write, size, depth, path, |png| {
                    exr_rows(file, size, path, |exr| {
                        bands(cx, Some(png), Some(exr), &mut reduce)
                    })
                })?,
                false => exr_rows(file, size, path, |exr| {
                    bands(cx, None, Some(exr), &mut reduce)
                })?,
            }
        }
        Some(t) => png_rows(&mut t.out as &mut dyn Write, size, depth, path, |png| {
            bands(cx, Some(png), None, &mut reduce)
        })?,
        None if glb => png_rows(memory as &mut dyn Write, size, depth, path, |png| {
            bands(cx, Some(png), None, &mut reduce)
        })?,
        None => bands(cx, None, None, &mut reduce)?,
    };
    let uv_set = report.uv_set as usize;
    Ok((report, reduce.map(|r| r.finish(uv_set))))
}

/// What [`stream`] hands on to [`bands`]: the bake, and the path its write errors name.
type StreamCx<'a> = (
    &'a Engine,
    &'a LoadedMesh,
    &'a Job,
    [u32; 2],
    &'a dyn Fn(&str),
    &'a Path,
);

/// The bake's bands, each into the PNG, the EXR and the reduced copy that are given.
fn bands(
    (engine, mesh, job, shape, on_stage, path): StreamCx<'_>,
    mut png: Option<&mut PngRows<'_, &mut dyn Write>>,
    mut exr: Option<&mut ExrRows<'_, &mut std::io::BufWriter<std::fs::File>>>,
    reduce: &mut Option<Reduction>,
) -> Result<Report> {
    let io = |source: std::io::Error| Error::Io {
        path: path.to_path_buf(),
        action: "writing",
        source,
    };
    // The bands' encoding into the files, counted as writing.
    let mut writing = 0.0;
    let mut report = crate::bake::bake_bands(engine, mesh, job, shape, on_stage, &mut |band| {
        let t = Instant::now();
        if let Some(p) = png.as_mut() {
            p.write_texels(&band.texels).map_err(io)?;
        }
        if let (Some(e), Some(linear)) = (exr.as_mut(), &band.linear) {
            e.write_rows(band.y, linear)
                .map_err(|e| io(std::io::Error::other(e)))?;
        }
        writing += t.elapsed().as_secs_f64() * 1000.0;
        if let Some(r) = reduce.as_mut() {
            r.add(band);
        }
        Ok(())
    })?;
    report.timings.write_ms += writing;
    Ok(report)
}

/// The model and the preview of a streamed bake, from its PNG (`texture`'s file, or `memory`).
fn other_files(
    engine: &Engine,
    mesh: &LoadedMesh,
    job: &Job,
    (texture, memory): (&Option<Staged>, Vec<u8>),
    reduced: Option<preview::PreviewTexture>,
    report: &mut Report,
) -> Result<Vec<(PathBuf, Vec<u8>)>> {
    let mut files = Vec::new();
    if let Some(p) = &job.out_glb {
        let png = match texture {
            Some(t) if !job.exr() => std::fs::read(&t.tmp).map_err(|source| Error::Io {
                path: t.path.clone(),
                action: "reading back for the model",
                source,
            })?,
            _ => memory,
        };
        let color = gltf::BakedColor {
            png: &png,
            uv_set: job.uv_set,
            from_material: matches!(job.base, crate::io::job::Base::Material),
            set: None,
            channels: Vec::new(),
        };
        let written = gltf::write_model(&mesh.mesh, &[color], p)?;
        files.extend(written.files);
        report.warnings.extend(written.warnings);
    }
    if let (Some(p), Some(tex)) = (&job.out_preview, reduced) {
        let px = preview::render_texture_preview(engine, mesh, &tex)?;
        files.push((p.clone(), preview_png(&px, p)?));
    }
    Ok(files)
}

/// A file being written to its temporary name beside its target.
struct Staged {
    path: PathBuf,
    tmp: PathBuf,
    out: std::io::BufWriter<std::fs::File>,
}

impl Staged {
    fn create(path: &Path) -> Result<Self> {
        make_parent(path)?;
        let tmp = tmp_path(path);
        let file = std::fs::File::create(&tmp).map_err(|source| Error::Io {
            path: path.to_path_buf(),
            action: "writing",
            source,
        })?;
        Ok(Self {
            path: path.to_path_buf(),
            tmp,
            out: std::io::BufWriter::with_capacity(1 << 20, file),
        })
    }

    /// Flushes the file and waits until it is on the disk, before it is renamed into place
    /// (`io::image::write_durable`).
    fn flush(&mut self) -> Result<()> {
        let io = |source| Error::Io {
            path: self.path.clone(),
            action: "writing",
            source,
        };
        self.out.flush().map_err(io)?;
        self.out.get_ref().sync_all().map_err(io)
    }

    fn remove(self) {
        let tmp = self.tmp.clone();
        drop(self);
        let _ = std::fs::remove_file(tmp);
    }
}

/// A box-filtered copy of the texture, at most [`PREVIEW_MAX`] a side, summed as the bands pass.
struct Reduction {
    width: u32,
    height: u32,
    /// Texels of the texture a side of a block (a power of two).
    factor: u32,
    /// Reduced width and height.
    size: [u32; 2],
    /// Per reduced texel and channel, the sum of the 8-bit samples of its block.
    sums: Vec<u32>,
    wide: bool,
}

impl Reduction {
    fn new(job: &Job) -> Self {
        let mut factor = 1;
        while job.width.max(job.height).div_ceil(factor) > PREVIEW_MAX {
            factor *= 2;
        }
        let size = [job.width.div_ceil(factor), job.height.div_ceil(factor)];
        Self {
            width: job.width,
            height: job.height,
            factor,
            size,
            sums: vec![0; size[0] as usize * size[1] as usize * 4],
            wide: job.bit_depth == 16,
        }
    }

    fn add(&mut self, band: &Band) {
        let (w, f, rw) = (
            self.width as usize,
            self.factor as usize,
            self.size[0] as usize,
        );
        for (r, row) in band.texels.chunks_exact(w * 4).enumerate() {
            let ry = (band.y as usize + r) / f;
            let sums = &mut self.sums[ry * rw * 4..(ry + 1) * rw * 4];
            for (x, px) in row.chunks_exact(4).enumerate() {
                let at = x / f * 4;
                for c in 0..4 {
                    sums[at + c] += match self.wide {
                        true => (px[c] as u32 * 255 + 32767) / 65535,
                        false => px[c] as u32,
                    };
                }
            }
        }
    }

    fn finish(self, uv_set: usize) -> preview::PreviewTexture {
        let (f, [rw, rh]) = (self.factor, self.size);
        let mut rgba8 = vec![0u8; self.sums.len()];
        for y in 0..rh {
            let bh = f.min(self.height - y * f);
            for x in 0..rw {
                let n = bh * f.min(self.width - x * f);
                let at = (y * rw + x) as usize * 4;
                for c in 0..4 {
                    rgba8[at + c] = ((self.sums[at + c] + n / 2) / n) as u8;
                }
            }
        }
        preview::PreviewTexture {
            width: rw,
            height: rh,
            rgba8,
            uv_set,
            second: None,
            third: None,
            channels: Default::default(),
        }
    }
}
