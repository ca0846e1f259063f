// SPDX-License-Identifier: MIT OR Apache-2.0
//! Texture sets: the unit of baking. A model's primitives are grouped by what their material
//! paints on the baked UV set: one set per distinct base-colour image on that set (materials that
//! share an image share a set), one per material without one, and one for primitives without a
//! material. A primitive without the UV set is in none (it is left unpainted).
//!
//! Each set is baked on its own ([`Mesh::for_texture_set`]): the same surface, so that maps and
//! decals flow across material boundaries as they do across UV seams, with the other sets'
//! triangles collapsed to one point of the UV set (they cover no texel) and the set's own
//! material as the base.

use super::load::material_info;
use super::Mesh;
use crate::error::Result;
use glam::Vec2;

/// One texture set of a mesh on a UV set.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct TextureSet {
    /// Its name in file names (`{set}`): the first material's name made file-safe, or
    /// `material<N>`, or `default` for primitives without a material; unique in the mesh.
    pub name: String,
    /// The materials it paints (document indices), in order.
    pub materials: Vec<usize>,
    /// Its primitives (indices into [`Mesh::primitives`]).
    pub primitives: Vec<usize>,
}

/// What groups primitives into one set.
#[derive(PartialEq)]
enum Key {
    Image(u64),
    Material(usize),
    Bare,
}

impl Mesh {
    /// The mesh's texture sets on UV set `uv_set`, in the order of their first primitive. A mesh
    /// without a document has one set of every primitive.
    pub fn texture_sets(&self, uv_set: u32) -> Vec<TextureSet> {
        let Some(doc) = &self.document else {
            return vec![TextureSet {
                name: "default".into(),
                materials: Vec::new(),
                primitives: (0..self.primitives.len()).collect(),
            }];
        };
        let new_set = self.new_uv_sets.contains(&(uv_set as usize));
        let mut keys: Vec<Key> = Vec::new();
        let mut sets: Vec<TextureSet> = Vec::new();
        for (i, p) in self.primitives.iter().enumerate() {
            if p.uv_sets <= uv_set && !new_set {
                continue;
            }
            let key = match p.material {
                None => Key::Bare,
                Some(m) => {
                    let tex = &doc
                        .array("materials")
                        .get(m)
                        .map(|m| &m["pbrMetallicRoughness"]["baseColorTexture"]);
                    let image = tex
                        .filter(|t| t["texCoord"].as_u64().unwrap_or(0) == uv_set as u64)
                        .and_then(|t| t["index"].as_u64())
                        .and_then(|t| doc.array("textures").get(t as usize)?["source"].as_u64());
                    image.map_or(Key::Material(m), Key::Image)
                }
            };
            match keys.iter().position(|k| *k == key) {
                Some(s) => {
                    sets[s].primitives.push(i);
                    if let Some(m) = p.material.filter(|m| !sets[s].materials.contains(m)) {
                        sets[s].materials.push(m);
                    }
                }
                None => {
                    keys.push(key);
                    sets.push(TextureSet {
                        name: String::new(),
                        materials: p.material.into_iter().collect(),
                        primitives: vec![i],
                    });
                }
            }
        }
        let mut names: Vec<String> = Vec::new();
        for s in &mut sets {
            let base = match s.materials.first() {
                None => "default".to_string(),
                Some(&m) => doc.array("materials")[m]["name"]
                    .as_str()
                    .map(file_safe)
                    .filter(|n| !n.is_empty())
                    .unwrap_or_else(|| format!("material{m}")),
            };
            let mut name = base.clone();
            let mut k = 2;
            while names.contains(&name) {
                name = format!("{base}_{k}");
                k += 1;
            }
            names.push(name.clone());
            s.name = name;
        }
        sets
    }

    /// A copy of the mesh for baking `set` alone on UV set `uv_set`: every other primitive's
    /// coordinates of that set at (0, 0), covering no texel, and the set's first material (its
    /// base-colour texture decoded) as the mesh's material.
    pub fn for_texture_set(&self, set: &TextureSet, uv_set: u32) -> Result<Mesh> {
        let mut out = self.clone();
        let mut keep = vec![false; self.primitives.len()];
        for &i in &set.primitives {
            keep[i] = true;
        }
        // Each vertex's primitive, by its vertex as loaded (primitives are in vertex order).
        let uv = &mut out.uv_sets[uv_set as usize];
        for (v, t) in uv.iter_mut().enumerate() {
            let o = self.vertex_origin.get(v).copied().unwrap_or(v as u32);
            let p = self.primitives.partition_point(|p| p.first_vertex <= o);
            if p == 0 || !keep[p - 1] {
                *t = Vec2::ZERO;
            }
        }
        out.material = match (set.materials.first(), &self.document) {
            (Some(&m), Some(doc)) if self.material.as_ref().map(|x| x.index) != Some(m) => {
                Some(material_info(doc, m)?)
            }
            (Some(_), _) => self.material.clone(),
            (None, _) => None,
        };
        Ok(out)
    }
}

impl Mesh {
    /// Material `m`'s name in the document (`None` without one, or without a document).
    pub fn material_name(&self, m: usize) -> Option<String> {
        let doc = self.document.as_ref()?;
        doc.array("materials").get(m)?["name"]
            .as_str()
            .map(String::from)
    }

    /// How many materials the document has (0 without a document).
    pub fn material_count(&self) -> usize {
        self.document
            .as_ref()
            .map_or(0, |d| d.array("materials").len())
    }
}

/// `name` with every character but letters, digits, `-` and `_` replaced by `_`.
fn file_safe(name: &str) -> String {
    name.chars()
        .map(|c| {
            if c.is_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect()
}
