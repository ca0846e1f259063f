// SPDX-License-Identifier: MIT OR Apache-2.0
//! Stage 0, checks: what can only be checked against the mesh and the device (texture size against
//! the adapter's limits, the mesh has the UV set).

use super::engine::{Engine, LoadedMesh};
use crate::error::{Error, Result};
use crate::io::job::Job;

/// Checks `job` against `mesh` and the engine's device.
/// `window`: the tile (x, y, w, h) whose canvas this bake holds, `None` for the whole bake.
pub fn check_job(
    engine: &Engine,
    mesh: &LoadedMesh,
    job: &Job,
    window: Option<[u32; 4]>,
) -> Result<()> {
    let src = &job.source;
    sides(engine, job)?;
    let (max_binding, limit_name) = engine.ctx.storage_limit();
    // The canvas holds the window, or one tile of a tiled bake, or the whole texture.
    let [_, _, cw, ch] = window.unwrap_or_else(|| match super::tiles::tile_shape(engine, job) {
        Some([tw, th]) => [0, 0, tw.min(job.width), th.min(job.height)],
        None => [0, 0, job.width, job.height],
    });
    let texels = cw as u64 * ch as u64;
    if texels * 8 > max_binding {
        let side = 1u64 << ((max_binding / 8).max(1).ilog2() / 2);
        return Err(Error::job(
            src,
            if job.tile.is_some() {
                "texture.tile"
            } else {
                "texture.width"
            },
            format!(
                "{}x{} needs {} per accumulation plane, above this adapter's {limit_name} of {} (at most {} texels, e.g. {side}x{side}); give a smaller `texture.tile`",
                cw,
                ch,
                crate::error::bytes_text(texels * 8),
                crate::error::bytes_text(max_binding),
                max_binding / 8,
            ),
        ));
    }
    super::stage::check_units(super::stage::Cx { engine, mesh, job })?;
    super::sets::check_set_keys(job, &mesh.mesh)?;
    let sets = mesh.mesh.uv_sets.len();
    if sets == 0 {
        return Err(Error::mesh(
                &mesh.mesh.source,
                "the mesh has no UV coordinates (no TEXCOORD_0), so there is no texture layout to bake into; give the job \"uv_set\": \"auto\" to have decalbake make one by pelting, or run `decalbake unwrap` (or Blender's Smart UV Project) first",
            ));
    }
    if let crate::io::job::Base::Transfer { from_uv_set, .. } = &job.base {
        if *from_uv_set as usize >= sets {
            return Err(Error::job(
                src,
                "texture.base.transfer.from_uv_set",
                format!(
                    "{from_uv_set} does not exist: {} has {sets} UV set(s) (TEXCOORD_0..TEXCOORD_{})",
                    mesh.mesh.source.display(),
                    sets - 1
                ),
            ));
        }
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

/// The texture's sides against the adapter's 2D texture limit (every bake, whole or by tiles,
/// draws its layers into textures of the texture's side at most).
pub fn sides(engine: &Engine, job: &Job) -> Result<()> {
    let max_side = engine.ctx.max_texture_side();
    for (field, v) in [("texture.width", job.width), ("texture.height", job.height)] {
        if v > max_side {
            return Err(Error::job(
                &job.source,
                field,
                format!("{v} exceeds this adapter's texture limit of {max_side} texels; bake at most {max_side}x{max_side}"),
            ));
        }
    }
    Ok(())
}

/// A warning for each primitive without the baked UV set: its triangles cover no texel of it
/// (the loader gives it (0, 0)), so decals flow across it on the surface but leave no paint.
pub fn unpainted(mesh: &LoadedMesh, job: &Job) -> Vec<String> {
    let set = job.uv_set as usize;
    if mesh.mesh.new_uv_sets.contains(&set) {
        return Vec::new();
    }
    let bare: Vec<&str> = mesh
        .mesh
        .primitives
        .iter()
        .filter(|p| p.uv_sets as usize <= set)
        .map(|p| p.name.as_str())
        .collect();
    if bare.is_empty() {
        return Vec::new();
    }
    vec![format!(
        "{}: {} without TEXCOORD_{set}: left unpainted (decals still flow across on the surface); give every part UVs in your modelling tool to paint it",
        mesh.mesh.source.display(),
        bare.join(", "),
    )]
}
