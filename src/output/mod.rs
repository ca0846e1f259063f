// SPDX-License-Identifier: MIT OR Apache-2.0
//! Writing a bake's files: texture PNG, `.glb`, preview PNG and JSON report.
//!
//! Every file's bytes are produced first; then each is written to a temporary file beside its target
//! and renamed into place. A failure before the renames leaves no output behind.

pub mod extract;
pub mod gltf;
pub mod matte;
pub mod preview;
pub mod stream;

use crate::bake::{Baked, Engine, LoadedMesh};
use crate::error::{Error, Result};
use crate::io::job::Job;
use std::path::PathBuf;
use std::time::Instant;

/// OpenEXR bytes of a linear RGBA f32 image (32-bit float channels, the `image` crate's encoder).
fn exr_bytes(w: u32, h: u32, linear: &[f32], path: &std::path::Path) -> Result<Vec<u8>> {
    use image::ImageEncoder;
    let mut out = std::io::Cursor::new(Vec::new());
    image::codecs::openexr::OpenExrEncoder::new(&mut out)
        .write_image(
            bytemuck::cast_slice(linear),
            w,
            h,
            image::ExtendedColorType::Rgba32F,
        )
        .map_err(|e| Error::Image {
            path: path.to_path_buf(),
            action: "encoding",
            detail: e.to_string(),
        })?;
    Ok(out.into_inner())
}

/// Bakes `job` and writes its files: streamed band by band where the bake goes by tiles to a PNG
/// with a finite padding ([`stream`]), else baked whole ([`Engine::bake_with_progress`]) and
/// written by [`write_outputs`]. `amend` sees the report before it is written. Returns the report
/// and the files written, in order.
pub fn bake_and_write(
    engine: &Engine,
    mesh: &LoadedMesh,
    job: &Job,
    on_stage: &dyn Fn(&str),
    amend: &dyn Fn(&mut crate::bake::report::Report),
) -> Result<(crate::bake::report::Report, Vec<PathBuf>)> {
    if let Some(done) = stream::write_streamed(engine, mesh, job, on_stage, amend)? {
        engine.save_pipeline_cache();
        return Ok(done);
    }
    let mut baked = engine.bake_with_progress(mesh, job, on_stage)?;
    amend(&mut baked.report);
    let files = write_outputs(engine, mesh, job, &mut baked)?;
    // The preview's pipeline is built after the bake's report.
    engine.save_pipeline_cache();
    Ok((baked.report, files))
}

/// Files written, in order.
pub fn write_outputs(
    engine: &Engine,
    mesh: &LoadedMesh,
    job: &Job,
    baked: &mut Baked,
) -> Result<Vec<PathBuf>> {
    let t = Instant::now();
    let mut files: Vec<(PathBuf, Vec<u8>)> = Vec::new();
    let png = baked.to_png_with(job.compression);
    let channel_pngs = baked.channel_pngs_with(job.compression);
    if let Some(p) = &job.out_glb {
        let color = gltf::BakedColor {
            png: &png,
            uv_set: job.uv_set,
            from_material: matches!(job.base, crate::io::job::Base::Material),
            set: None,
            channels: channel_list(job, baked.channels.iter().map(|c| c.kind), &channel_pngs),
        };
        let written = gltf::write_model(&mesh.mesh, &[color], p)?;
        files.extend(written.files);
        baked.report.warnings.extend(written.warnings);
    }
    if let Some(p) = &job.out_preview {
        let px = preview::render_preview(engine, mesh, baked)?;
        files.push((p.clone(), preview_png(&px, p)?));
    }
    if let Some(p) = &job.out_texture {
        let bytes = match &baked.linear {
            Some(linear) if job.exr() => exr_bytes(baked.width, baked.height, linear, p)?,
            _ => png,
        };
        files.insert(0, (p.clone(), bytes));
        // The channel textures follow the colour's, in the bake's order.
        let mut next = 1;
        for (c, png) in baked.channels.iter().zip(channel_pngs) {
            if let Some(q) = job.texture_path(None, c.kind.name()) {
                let bytes = match &c.linear {
                    Some(linear) if job.exr() => exr_bytes(baked.width, baked.height, linear, &q)?,
                    _ => png,
                };
                files.insert(next, (q, bytes));
                next += 1;
            }
        }
    }
    baked.report.timings.write_ms = t.elapsed().as_secs_f64() * 1000.0;
    if let Some(p) = &job.out_report {
        let json = serde_json::to_vec_pretty(&baked.report).expect("the report serializes");
        files.push((p.clone(), json));
    }
    write_files(&files)?;
    Ok(files.into_iter().map(|(p, _)| p).collect())
}

/// The channel textures of `kinds`, with their PNGs, for the model.
fn channel_list<'a>(
    job: &Job,
    kinds: impl Iterator<Item = crate::bake::channels::ChannelKind>,
    pngs: &'a [Vec<u8>],
) -> Vec<gltf::BakedChannelPng<'a>> {
    let occlusion = job.layers.iter().any(|l| l.channels.occlusion.is_some());
    kinds
        .zip(pngs)
        .map(|(kind, png)| gltf::BakedChannelPng {
            kind,
            png,
            occlusion,
        })
        .collect()
}

/// Writes every file: each to a temporary file beside its target, then all renamed into place; a
/// failure leaves none of them (output directories are made as needed).
pub fn write_files(files: &[(PathBuf, Vec<u8>)]) -> Result<()> {
    commit(files, Vec::new())
}

/// [`write_files`], after `staged`: files already written to their temporaries (temporary,
/// target), renamed first; a failure removes them too.
fn commit(files: &[(PathBuf, Vec<u8>)], mut staged: Vec<(PathBuf, PathBuf)>) -> Result<()> {
    let drop_staged = |staged: &[(PathBuf, PathBuf)]| {
        for (t, _) in staged {
            let _ = std::fs::remove_file(t);
        }
    };
    for (p, _) in files {
        if let Err(e) = make_parent(p) {
            drop_staged(&staged);
            return Err(e);
        }
    }
    // Stage everything, then rename.
    for (p, bytes) in files {
        let tmp = tmp_path(p);
        if let Err(source) = crate::io::image::write_durable(&tmp, bytes) {
            drop_staged(&staged);
            let _ = std::fs::remove_file(&tmp);
            return Err(Error::Io {
                path: p.clone(),
                action: "writing",
                source,
            });
        }
        staged.push((tmp, p.clone()));
    }
    for (k, (tmp, p)) in staged.iter().enumerate() {
        if let Err(source) = std::fs::rename(tmp, p) {
            // Nothing of this bake stays: the files already renamed and the rest staged.
            for (t, q) in &staged[..k] {
                let _ = std::fs::remove_file(q);
                let _ = std::fs::remove_file(t);
            }
            drop_staged(&staged[k..]);
            return Err(Error::Io {
                path: p.clone(),
                action: "renaming into place",
                source,
            });
        }
    }
    // The renames made durable, once per folder.
    let mut dirs: Vec<&std::path::Path> = staged
        .iter()
        .map(|(_, p)| p.parent().filter(|d| !d.as_os_str().is_empty()))
        .map(|d| d.unwrap_or(std::path::Path::new(".")))
        .collect();
    dirs.sort();
    dirs.dedup();
    for d in dirs {
        crate::io::image::sync_dir(d);
    }
    Ok(())
}

/// Makes the folder `p` goes in, if it has one; the folders it creates are synced into their
/// parents (`io::image::sync_dir`), so an output synced inside a new folder is not lost with the
/// folder's entry after a power loss.
fn make_parent(p: &std::path::Path) -> Result<()> {
    let Some(dir) = p.parent().filter(|d| !d.as_os_str().is_empty()) else {
        return Ok(());
    };
    let made: Vec<&std::path::Path> = dir.ancestors().take_while(|a| !a.exists()).collect();
    std::fs::create_dir_all(dir).map_err(|source| Error::Io {
        path: dir.to_path_buf(),
        action: "creating the output directory",
        source,
    })?;
    for d in made {
        let parent = d.parent().filter(|d| !d.as_os_str().is_empty());
        crate::io::image::sync_dir(parent.unwrap_or(std::path::Path::new(".")));
    }
    Ok(())
}

/// One UV set's bake of a job's list of UV sets (`"uv_set": [..]`, `Job::for_uv_set`): the
/// whole mesh into one texture, or, on a mesh of several texture sets on that UV set, one
/// texture per set (`Engine::bake_texture_sets`), as a job of that UV set alone bakes.
pub enum UvBake {
    /// One texture for the UV set.
    One(Job, Box<Baked>),
    /// A texture per texture set.
    Sets(Job, Vec<crate::bake::sets::SetBake>),
}

/// Writes the bakes of a job's UV sets, every one baked before this is called, and returns each
/// one's report and files, in order. The job's `output.preview` (`preview`) blends the sets'
/// textures in one picture where each UV set baked one texture; where some UV set baked a
/// texture per texture set, every UV set draws its own preview instead, named as its other
/// outputs are (`{uv}`, or `-uv<N>` added).
pub fn write_uv_bakes(
    engine: &Engine,
    mesh: &LoadedMesh,
    bakes: Vec<UvBake>,
    preview: Option<&std::path::Path>,
) -> Result<Vec<(crate::bake::report::Report, Vec<PathBuf>)>> {
    let blended = bakes.iter().all(|b| matches!(b, UvBake::One(..)));
    let own_preview = |j: &mut Job| {
        if !blended {
            j.out_preview = preview.map(|p| crate::io::job::uv_set_name(p, j.uv_set));
        }
    };
    let mut out = Vec::with_capacity(bakes.len());
    let mut textures = Vec::new();
    for b in bakes {
        match b {
            UvBake::One(mut j, mut baked) => {
                own_preview(&mut j);
                let files = write_outputs(engine, mesh, &j, &mut baked)?;
                textures.push(preview::PreviewTexture::of(&baked));
                out.push((baked.report, files));
            }
            UvBake::Sets(mut j, mut sets) => {
                own_preview(&mut j);
                let files = write_set_outputs(engine, mesh, &j, &mut sets)?;
                out.push((sets.swap_remove(0).baked.report, files));
            }
        }
    }
    if let (Some(p), true, Some(last)) = (preview, blended, out.last_mut()) {
        preview::write_set_preview(engine, mesh, textures, p)?;
        last.1.push(p.to_path_buf());
    }
    Ok(out)
}

/// Writes a bake into several texture sets (`Engine::bake_texture_sets`): the texture of every
/// set a layer touched (every set's when none was), one model whose materials take them, one
/// preview drawing each set with its texture, and one report (the first set's, with
/// `texture_sets` and each layer's coverage added up over the sets). Files written, in order.
pub fn write_set_outputs(
    engine: &Engine,
    mesh: &LoadedMesh,
    job: &Job,
    bakes: &mut [crate::bake::sets::SetBake],
) -> Result<Vec<PathBuf>> {
    let t = Instant::now();
    let any = bakes.iter().any(|b| b.touched());
    let written: Vec<bool> = bakes.iter().map(|b| b.touched() || !any).collect();
    let pngs: Vec<Vec<u8>> = bakes
        .iter()
        .map(|b| b.baked.to_png_with(b.job.compression))
        .collect();
    let channel_pngs: Vec<Vec<Vec<u8>>> = bakes
        .iter()
        .map(|b| b.baked.channel_pngs_with(b.job.compression))
        .collect();
    let mut files: Vec<(PathBuf, Vec<u8>)> = Vec::new();
    let mut warnings = Vec::new();
    for (((b, png), &w), cpngs) in bakes.iter().zip(&pngs).zip(&written).zip(&channel_pngs) {
        if let (Some(p), true) = (&b.job.out_texture, w) {
            let bytes = match &b.baked.linear {
                Some(linear) if job.exr() => exr_bytes(b.baked.width, b.baked.height, linear, p)?,
                _ => png.clone(),
            };
            files.push((p.clone(), bytes));
            for (c, cpng) in b.baked.channels.iter().zip(cpngs) {
                if let Some(q) = job.texture_path(Some(&b.set.name), c.kind.name()) {
                    let (w, h) = (b.baked.width, b.baked.height);
                    let bytes = match &c.linear {
                        Some(linear) if job.exr() => exr_bytes(w, h, linear, &q)?,
                        _ => cpng.clone(),
                    };
                    files.push((q, bytes));
                }
            }
        }
    }
    if let Some(p) = &job.out_glb {
        let colors: Vec<gltf::BakedColor> = bakes
            .iter()
            .zip(&pngs)
            .zip(&written)
            .zip(&channel_pngs)
            .filter(|((_, &w), _)| w)
            .map(|(((b, png), _), cpngs)| gltf::BakedColor {
                png,
                uv_set: job.uv_set,
                from_material: matches!(job.base, crate::io::job::Base::Material),
                set: Some(&b.set),
                channels: channel_list(job, b.baked.channels.iter().map(|c| c.kind), cpngs),
            })
            .collect();
        let model = gltf::write_model(&mesh.mesh, &colors, p)?;
        files.extend(model.files);
        warnings.extend(model.warnings);
    }
    if let Some(p) = &job.out_preview {
        let sets: Vec<_> = bakes
            .iter()
            .map(|b| {
                let ranges = b.set.primitives.iter().map(|&i| {
                    let q = &mesh.mesh.primitives[i];
                    q.first_triangle..q.first_triangle + q.triangles
                });
                (preview::PreviewTexture::of(&b.baked), ranges.collect())
            })
            .collect();
        let px = preview::render_sets_preview(engine, mesh, &sets)?;
        files.push((p.clone(), preview_png(&px, p)?));
    }
    let mut report = bakes[0].baked.report.clone();
    for b in &bakes[1..] {
        for (l, o) in report.layers.iter_mut().zip(&b.baked.report.layers) {
            l.texels_covered += o.texels_covered;
        }
        warnings.extend(b.baked.report.warnings.iter().cloned());
    }
    report.warnings.extend(warnings);
    let mut seen = std::collections::HashSet::new();
    report.warnings.retain(|w| seen.insert(w.clone()));
    report.texture_sets = bakes
        .iter()
        .zip(&written)
        .map(|(b, &w)| crate::bake::report::SetReport {
            name: b.set.name.clone(),
            materials: b.set.materials.clone(),
            primitives: b
                .set
                .primitives
                .iter()
                .map(|&i| mesh.mesh.primitives[i].name.clone())
                .collect(),
            texture: b
                .job
                .out_texture
                .as_ref()
                .filter(|_| w)
                .map(|p| p.display().to_string()),
            texels_covered: b
                .baked
                .report
                .layers
                .iter()
                .map(|l| l.texels_covered as u64)
                .sum(),
        })
        .collect();
    report.timings.write_ms = t.elapsed().as_secs_f64() * 1000.0;
    if let Some(p) = &job.out_report {
        files.push((
            p.clone(),
            serde_json::to_vec_pretty(&report).expect("the report serializes"),
        ));
    }
    bakes[0].baked.report = report;
    write_files(&files)?;
    Ok(files.into_iter().map(|(p, _)| p).collect())
}

/// A preview's pixels as PNG bytes.
fn preview_png(px: &[u8], p: &std::path::Path) -> Result<Vec<u8>> {
    use image::ImageEncoder;
    let side = 2 * preview::VIEW_SIDE;
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new(&mut out)
        .write_image(px, side, side, image::ExtendedColorType::Rgba8)
        .map_err(|e| Error::Image {
            path: p.to_path_buf(),
            action: "encoding",
            detail: e.to_string(),
        })?;
    Ok(out)
}

fn tmp_path(p: &std::path::Path) -> PathBuf {
    let name = p
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    p.with_file_name(format!(".{name}.tmp-{}", std::process::id()))
}
