// SPDX-License-Identifier: MIT OR Apache-2.0
//! A bake by tiles written as it is baked: each band of rows (`bake/bands.rs`), padded, goes
//! straight into the PNG (`io::image::png_rows`, the same bytes as a PNG encoded whole) or the
//! OpenEXR (`io::image::exr_rows`, the same floats as the linear canvas held whole) in a temporary
//! file beside the texture, so the texture is never whole in memory: a 16384² bake holds a few
//! bands of rows, its tile on the device, and a reduced copy for the preview. A job that paints
//! PBR channels streams each channel's texture the same way, beside the colour's: one writer
//! thread a texture, each fed the band's rows of its texture as the bake hands them on (at most
//! one band waiting a writer), so the textures are encoded while the next band bakes.
//!
//! What streams: a bake that goes by tiles (`texture.tile`, a texture whose canvas does not fit
//! one storage buffer, or an EXR output) with a finite padding. `"padding": "full"` (a texel may
//! take its colour from anywhere in the texture) and the several-set bakes are baked whole in
//! memory ([`super::write_outputs`]). Where the job asks for a model, the model embeds each
//! texture's PNG bytes (read back from its temporary file, or, when the job writes no PNG
//! texture, a PNG written to memory beside the bands), so a model of a huge texture holds its
//! compressed bytes, not its texels.
//! The preview is drawn from copies of the textures reduced by box filtering to at most
//! [`PREVIEW_MAX`] texels a side (a 512-pixel view samples far coarser mips anyway), the
//! channels' too, so it shades with them as a preview of a bake held whole does.
//!
//! Nothing is left half-written: the textures are renamed into place with the other files only
//! once every band is baked and every other file is ready; a failure removes the temporary files.

use super::{commit, gltf, make_parent, preview, preview_png, tmp_path};
use crate::bake::bands::Band;
use crate::bake::channels::ChannelKind;
use crate::bake::report::Report;
use crate::bake::{Engine, LoadedMesh};
use crate::error::{Error, Result};
use crate::io::image::{exr_rows, png_rows, ExrRows, PngRows};
use crate::io::job::Job;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::mpsc::{sync_channel, Receiver};
use std::time::Instant;

/// The largest side of the copy a streamed bake's preview is drawn from.
pub const PREVIEW_MAX: u32 = 2048;

/// One texture a streamed bake writes: the colour's (`kind` `None`) or a PBR channel group's.
struct Target {
    kind: Option<ChannelKind>,
    /// Its file, written under a temporary name (`None`: the job writes no texture file).
    file: Option<Staged>,
    /// Its PNG in memory, for the model, where its file is not a PNG (or there is none).
    memory: Vec<u8>,
}

impl Target {
    /// The PNG bytes the model embeds: the file's, read back, or the ones in memory.
    fn png(&mut self, exr: bool) -> Result<Vec<u8>> {
        match &self.file {
            Some(f) if !exr => std::fs::read(&f.tmp).map_err(|source| Error::Io {
                path: f.path.clone(),
                action: "reading back for the model",
                source,
            }),
            _ => Ok(std::mem::take(&mut self.memory)),
        }
    }
}

/// Removes every target's temporary file.
fn remove(targets: Vec<Target>) {
    for t in targets {
        if let Some(f) = t.file {
            f.remove();
        }
    }
}

/// The textures `job` writes, their files begun: the colour's, then each channel group's in
/// pass order (`channels::passes`; their files named as a bake held whole names them).
fn begin(job: &Job) -> Result<Vec<Target>> {
    let mut kinds = vec![None];
    kinds.extend(crate::bake::channels::passes(job).into_iter().map(Some));
    let mut targets: Vec<Target> = Vec::with_capacity(kinds.len());
    for kind in kinds {
        let path = match (kind, &job.out_texture) {
            (_, None) => None,
            (None, Some(p)) => Some(p.clone()),
            (Some(k), Some(_)) => job.texture_path(None, k.name()),
        };
        let file = match path.as_deref().map(Staged::create).transpose() {
            Ok(f) => f,
            Err(e) => {
                remove(targets);
                return Err(e);
            }
        };
        targets.push(Target {
            kind,
            file,
            memory: Vec::new(),
        });
    }
    Ok(targets)
}

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
    // Sizes and memory before the files are begun.
    crate::bake::streamed_limits(engine, mesh, job)?;
    let before = engine.pipelines_spent();
    let mut targets = begin(job)?;
    let streamed = stream(engine, mesh, (job, shape), on_stage, &mut targets).and_then(|r| {
        for f in targets.iter_mut().filter_map(|t| t.file.as_mut()) {
            f.flush()?;
        }
        Ok(r)
    });
    let (mut report, reduced) = match streamed {
        Ok(r) => r,
        Err(e) => {
            remove(targets);
            return Err(e);
        }
    };
    let t = Instant::now();
    let files = match other_files(engine, mesh, job, &mut targets, reduced, &mut report) {
        Ok(files) => files,
        Err(e) => {
            remove(targets);
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
    let staged: Vec<(PathBuf, PathBuf)> = targets
        .iter()
        .filter_map(|t| t.file.as_ref())
        .map(|f| (f.tmp.clone(), f.path.clone()))
        .collect();
    let written: Vec<PathBuf> = staged.iter().map(|(_, p)| p.clone()).collect();
    commit(&files, staged)?;
    let written = written.into_iter().chain(files.into_iter().map(|(p, _)| p));
    Ok(Some((report, written.collect())))
}

/// One band's rows of one texture, on their way to its writer.
struct Rows {
    /// The band's first row.
    y: u32,
    /// Encoded RGBA samples.
    texels: Vec<u16>,
    /// Linear RGBA floats, for an EXR.
    linear: Option<Vec<f32>>,
}

impl Rows {
    /// Texture `k`'s rows of `band` (0 the colour's, then the channels' in pass order).
    fn of(band: &Band, k: usize) -> Self {
        let (texels, linear) = match k {
            0 => (band.texels.clone(), band.linear.clone()),
            k => (
                band.channels[k - 1].clone(),
                band.channel_linear.get(k - 1).cloned(),
            ),
        };
        Self {
            y: band.y,
            texels,
            linear,
        }
    }
}

/// Bakes the bands into every target (one writer thread each, [`write_target`]) and the reduced
/// copies for the preview, if the job has one. A writer's error stops the bake and is the one
/// returned; the bake's own error otherwise.
fn stream(
    engine: &Engine,
    mesh: &LoadedMesh,
    (job, shape): (&Job, [u32; 2]),
    on_stage: &dyn Fn(&str),
    targets: &mut [Target],
) -> Result<(Report, Option<preview::PreviewTexture>)> {
    let kinds: Vec<Option<ChannelKind>> = targets.iter().map(|t| t.kind).collect();
    let mut reduce = job
        .out_preview
        .as_ref()
        .map(|_| Reduction::new(job, kinds.len()));
    let (baked, written) = std::thread::scope(|s| {
        let mut senders = Vec::with_capacity(targets.len());
        let mut writers = Vec::with_capacity(targets.len());
        for t in targets.iter_mut() {
            let (tx, rx) = sync_channel::<Rows>(1);
            senders.push(tx);
            writers.push(s.spawn(move || write_target(t, job, rx)));
        }
        let mut stopped = false;
        let baked =
            crate::bake::bake_bands(engine, mesh, job, shape, on_stage, &mut |band: &Band| {
                for (k, tx) in senders.iter().enumerate() {
                    if tx.send(Rows::of(band, k)).is_err() {
                        stopped = true;
                        return Err(Error::Io {
                            path: PathBuf::new(),
                            action: "writing",
                            source: std::io::Error::other("a texture's writer stopped"),
                        });
                    }
                }
                if let Some(r) = reduce.as_mut() {
                    r.add(band);
                }
                Ok(())
            });
        drop(senders);
        let written: Vec<Result<f64>> = writers
            .into_iter()
            .map(|w| w.join().expect("a texture writer panicked"))
            .collect();
        (baked.map_err(|e| (e, stopped)), written)
    });
    let mut writing = 0.0f64;
    let mut failed = None;
    for w in written {
        match w {
            Ok(ms) => writing = writing.max(ms),
            Err(e) => failed = failed.or(Some(e)),
        }
    }
    let mut report = match (baked, failed) {
        (Err((_, true)), Some(e)) | (Ok(_), Some(e)) => return Err(e),
        (Err((e, _)), _) => return Err(e),
        (Ok(r), None) => r,
    };
    // The encoding ran beside the bake: the busiest writer's time.
    report.timings.write_ms += writing;
    report.streamed = true;
    let uv_set = report.uv_set as usize;
    Ok((report, reduce.map(|r| r.finish(uv_set, &kinds))))
}

/// Writes the rows `rx` brings into `target`'s file (a PNG, or an EXR and, for a model, a PNG in
/// memory) or, with no file and a model asked for, a PNG in memory. Returns the milliseconds
/// spent encoding and writing.
fn write_target(target: &mut Target, job: &Job, rx: Receiver<Rows>) -> Result<f64> {
    let size = [job.width, job.height];
    let depth = (job.bit_depth, job.compression);
    let glb = job.out_glb.is_some();
    let name = match &target.file {
        Some(f) => f.path.clone(),
        None => job.out_glb.clone().unwrap_or_default(),
    };
    let path = name.as_path();
    let memory = &mut target.memory;
    match target.file.as_mut() {
        Some(t) if job.exr() => {
            let file = &mut t.out;
            match glb {
                true => png_rows(memory as &mut dyn Write, size, depth, path, |png| {
                    exr_rows(file, size, path, |exr| feed(rx, Some(png), Some(exr), path))
                }),
                false => exr_rows(file, size, path, |exr| feed(rx, None, Some(exr), path)),
            }
        }
        Some(t) => png_rows(&mut t.out as &mut dyn Write, size, depth, path, |png| {
            feed(rx, Some(png), None, path)
        }),
        None if glb => png_rows(memory as &mut dyn Write, size, depth, path, |png| {
            feed(rx, Some(png), None, path)
        }),
        None => feed(rx, None, None, path),
    }
}

/// Every band's rows from `rx` into the PNG and the EXR that are given (write errors name
/// `path`); the milliseconds spent.
fn feed(
    rx: Receiver<Rows>,
    mut png: Option<&mut PngRows<'_, &mut dyn Write>>,
    mut exr: Option<&mut ExrRows<'_, &mut std::io::BufWriter<std::fs::File>>>,
    path: &Path,
) -> Result<f64> {
    let io = |source: std::io::Error| Error::Io {
        path: path.to_path_buf(),
        action: "writing",
        source,
    };
    let mut ms = 0.0;
    for rows in rx {
        let t = Instant::now();
        if let Some(p) = png.as_mut() {
            p.write_texels(&rows.texels).map_err(io)?;
        }
        if let (Some(e), Some(linear)) = (exr.as_mut(), &rows.linear) {
            e.write_rows(rows.y, linear)
                .map_err(|e| io(std::io::Error::other(e)))?;
        }
        ms += t.elapsed().as_secs_f64() * 1000.0;
    }
    Ok(ms)
}

/// The model and the preview of a streamed bake, from its textures' PNGs.
fn other_files(
    engine: &Engine,
    mesh: &LoadedMesh,
    job: &Job,
    targets: &mut [Target],
    reduced: Option<preview::PreviewTexture>,
    report: &mut Report,
) -> Result<Vec<(PathBuf, Vec<u8>)>> {
    let mut files = Vec::new();
    if let Some(p) = &job.out_glb {
        let pngs: Vec<Vec<u8>> = targets
            .iter_mut()
            .map(|t| t.png(job.exr()))
            .collect::<Result<_>>()?;
        let kinds = targets.iter().filter_map(|t| t.kind);
        let channels = super::channel_list(job, kinds, &pngs[1..]);
        let color = gltf::BakedColor {
            png: &pngs[0],
            uv_set: job.uv_set,
            from_material: matches!(job.base, crate::io::job::Base::Material),
            set: None,
            channels,
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

/// Box-filtered copies of the textures (the colour's, then the channels'), at most
/// [`PREVIEW_MAX`] a side, summed as the bands pass.
struct Reduction {
    width: u32,
    height: u32,
    /// Texels of the texture a side of a block (a power of two).
    factor: u32,
    /// Reduced width and height.
    size: [u32; 2],
    /// Per texture, reduced texel and channel, the sum of the 8-bit samples of its block.
    sums: Vec<Vec<u32>>,
    wide: bool,
}

impl Reduction {
    fn new(job: &Job, textures: usize) -> Self {
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
            sums: vec![vec![0; size[0] as usize * size[1] as usize * 4]; textures],
            wide: job.bit_depth == 16,
        }
    }

    fn add(&mut self, band: &Band) {
        let (w, f, rw) = (
            self.width as usize,
            self.factor as usize,
            self.size[0] as usize,
        );
        let wide = self.wide;
        let textures = std::iter::once(&band.texels).chain(&band.channels);
        for (texels, sums) in textures.zip(&mut self.sums) {
            for (r, row) in texels.chunks_exact(w * 4).enumerate() {
                let ry = (band.y as usize + r) / f;
                let sums = &mut sums[ry * rw * 4..(ry + 1) * rw * 4];
                for (x, px) in row.chunks_exact(4).enumerate() {
                    let at = x / f * 4;
                    for c in 0..4 {
                        sums[at + c] += match wide {
                            true => (px[c] as u32 * 255 + 32767) / 65535,
                            false => px[c] as u32,
                        };
                    }
                }
            }
        }
    }

    /// The reduced colour, shaded with the reduced channels (`kinds`: each texture's).
    fn finish(self, uv_set: usize, kinds: &[Option<ChannelKind>]) -> preview::PreviewTexture {
        let (f, [rw, rh]) = (self.factor, self.size);
        let (width, height) = (self.width, self.height);
        let average = |sums: &[u32]| {
            let mut rgba8 = vec![0u8; sums.len()];
            for y in 0..rh {
                let bh = f.min(height - y * f);
                for x in 0..rw {
                    let n = bh * f.min(width - x * f);
                    let at = (y * rw + x) as usize * 4;
                    for c in 0..4 {
                        rgba8[at + c] = ((sums[at + c] + n / 2) / n) as u8;
                    }
                }
            }
            rgba8
        };
        let mut channels = preview::PreviewChannels::default();
        for (kind, sums) in kinds.iter().zip(&self.sums) {
            if let Some(kind) = kind {
                channels.set(*kind, average(sums));
            }
        }
        preview::PreviewTexture {
            width: rw,
            height: rh,
            rgba8: average(&self.sums[0]),
            uv_set,
            second: None,
            third: None,
            channels,
        }
    }
}
