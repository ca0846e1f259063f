// SPDX-License-Identifier: MIT OR Apache-2.0
//! A job baked into every texture set of its mesh ([`crate::mesh::TextureSet`]): one bake per
//! set on a copy of the mesh that paints only that set's primitives, with that set's material as
//! the base. Maps are computed on the whole surface in each bake, so a decal across a material
//! boundary continues from one set's texture into the other's as it does across a UV seam.

use super::engine::{Baked, Engine, LoadedMesh};
use crate::error::Result;
use crate::io::job::Job;
use crate::mesh::TextureSet;

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
            let m = self.prepare(mesh.mesh.for_texture_set(&set, job.uv_set)?)?;
            let j = job.for_texture_set(&set.name);
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
}
