// SPDX-License-Identifier: MIT OR Apache-2.0
//! A job baked into every texture set of its mesh ([`crate::mesh::TextureSet`]): one bake per
//! set on a copy of the mesh that paints only that set's primitives, with that set's material as
//! the base. Maps are computed on the whole surface in each bake, so a decal across a material
//! boundary continues from one set's texture into the other's as it does across a UV seam.

use super::engine::{Baked, BakedTextures, Engine, LoadedMesh};
use super::report::Report;
use crate::error::Error;
use crate::error::Result;
use crate::io::job::Job;
use crate::mesh::{Mesh, TextureSet};

/// One texture set's bake.
pub struct SetBake {
    /// The set.
    pub set: TextureSet,
    /// The mesh as this set's bake saw it (other sets' triangles covering no texel).
    pub mesh: LoadedMesh,
    /// The job with this set's output names (`Job::for_texture_set`).
    pub job: Job,
    /// Its texture and report.
    pub baked: Baked,
}

impl SetBake {
    /// Whether some layer painted a texel of this set.
    pub fn touched(&self) -> bool {
        self.baked
            .report
            .layers
            .iter()
            .any(|l| l.texels_covered > 0)
    }
}

impl Engine {
    /// Bakes `job` into each of `sets` (the mesh's texture sets on the job's UV set), every set
    /// before anything is written. Each set costs a bake of its own (placement and maps are
    /// computed again per set).
    pub fn bake_texture_sets(
        &self,
        mesh: &LoadedMesh,
        job: &Job,
        sets: Vec<TextureSet>,
    ) -> Result<Vec<SetBake>> {
        let mut out = Vec::with_capacity(sets.len());
        for set in sets {
            let (m, j) = self.set_inputs(mesh, job, &set)?;
            let baked = self.bake(&m, &j)?;
            out.push(SetBake {
                set,
                mesh: m,
                job: j,
                baked,
            });
        }
        Ok(out)
    }

    /// What one set's bake takes: the copy of the mesh that paints only `set`, and the job with
    /// the set's output names (`Job::for_texture_set`) and size ([`set_size`]).
    fn set_inputs(
        &self,
        mesh: &LoadedMesh,
        job: &Job,
        set: &TextureSet,
    ) -> Result<(LoadedMesh, Job)> {
        let m = self.prepare(mesh.mesh.for_texture_set(set, job.uv_set)?)?;
        let mut j = job.for_texture_set(&set.name);
        (j.width, j.height) = set_size(job, &mesh.mesh, set);
        Ok((m, j))
    }
}

/// One texture set's textures on the GPU ([`Engine::bake_set_textures`]).
pub struct SetTextures {
    /// The set; its `name` is what `{set}` becomes in output names.
    pub set: TextureSet,
    /// The set's textures (its own size: `texture.sets`, else the job's), as
    /// [`Engine::bake_textures`] gives them.
    pub textures: BakedTextures,
    /// The set's report.
    pub report: Report,
}

impl Engine {
    /// Bakes `job` into every texture set of `mesh` on the job's UV set, as
    /// [`Engine::bake_texture_sets`] does, into textures that never leave the GPU (one
    /// [`SetTextures`] per set, in the mesh's order of sets): a renderer that draws each material
    /// with its own texture takes each set's. On a mesh of one set (or none: no materials) the one
    /// entry covers the whole mesh, at the set's size. A `texture.sets` key that names no material
    /// is refused before any work.
    pub fn bake_set_textures(&self, mesh: &LoadedMesh, job: &Job) -> Result<Vec<SetTextures>> {
        check_set_keys(job, &mesh.mesh)?;
        let sets = mesh.mesh.texture_sets(job.uv_set);
        if sets.len() < 2 {
            let mut j = job.for_single_set(sets.first().map_or("default", |s| s.name.as_str()));
            if let Some(set) = sets.first() {
                (j.width, j.height) = set_size(&j, &mesh.mesh, set);
            }
            let (textures, report) = self.bake_textures(mesh, &j)?;
            let set = sets.into_iter().next().unwrap_or_else(|| TextureSet {
                name: "default".into(),
                materials: Vec::new(),
                primitives: (0..mesh.mesh.primitives.len()).collect(),
            });
            return Ok(vec![SetTextures {
                set,
                textures,
                report,
            }]);
        }
        let mut out = Vec::with_capacity(sets.len());
        for set in sets {
            let (m, j) = self.set_inputs(mesh, job, &set)?;
            let (textures, report) = self.bake_textures(&m, &j)?;
            out.push(SetTextures {
                set,
                textures,
                report,
            });
        }
        Ok(out)
    }
}

/// The size of `set`'s texture: its `texture.sets` entry (by a material's name or index), or the
/// job's.
pub fn set_size(job: &Job, mesh: &Mesh, set: &TextureSet) -> (u32, u32) {
    let names: Vec<(usize, Option<String>)> = set
        .materials
        .iter()
        .map(|&m| (m, mesh.material_name(m)))
        .collect();
    let named: Vec<(usize, Option<&str>)> = names.iter().map(|(m, n)| (*m, n.as_deref())).collect();
    job.set_size(&named)
}

/// Every `texture.sets` key names a material of the mesh (by name or index), or an error naming
/// the key and the materials there are.
pub fn check_set_keys(job: &Job, mesh: &Mesh) -> Result<()> {
    let count = mesh.material_count();
    for (key, _, _) in &job.set_sizes {
        let by_index = key.parse::<usize>().is_ok_and(|i| i < count);
        let by_name = (0..count).any(|m| mesh.material_name(m).as_deref() == Some(key.as_str()));
        if !by_index && !by_name {
            let names: Vec<String> = (0..count)
                .map(|m| mesh.material_name(m).unwrap_or_else(|| m.to_string()))
                .collect();
            return Err(Error::job(
                &job.source,
                format!("texture.sets.{key}"),
                format!(
                    "{} has no material named or numbered {key:?}; its materials are: {}",
                    mesh.source.display(),
                    if names.is_empty() {
                        "none".into()
                    } else {
                        names.join(", ")
                    }
                ),
            ));
        }
    }
    Ok(())
}
