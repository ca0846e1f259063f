// SPDX-License-Identifier: MIT OR Apache-2.0
//! The baked base colour in the document.
//!
//! - The bake's base was the material's own base-colour texture on the baked UV set (with no
//!   `KHR_texture_transform`): that image is replaced in place; every material that shares it
//!   shows the bake.
//! - Otherwise the bake is added as an image and a texture, and the painted materials take it as
//!   their `baseColorTexture` on the baked set: with a material base, the bake's material and those
//!   with the same untextured base (their factor went into the texture, so it becomes white);
//!   with a job's own base (an image, a colour, a transfer), every material of a painted
//!   primitive (factor white).
//! - A painted primitive without a material gets one with the bake.
//! - A painted material with a base of its own that the bake did not start from keeps it and is
//!   named in a warning: a bake writes one base-colour texture.

use super::{array, BakedColor, Doc};
use crate::mesh::Mesh;
use serde_json::{json, Value};
use std::collections::BTreeSet;
use std::path::Path;

impl Doc<'_> {
    /// The bake of one texture set: the image its materials share replaced, or a new texture for
    /// its materials (a new material for its primitives without one). Returns the bake's texture.
    pub(super) fn apply_set_color(
        &mut self,
        mesh: &Mesh,
        c: &BakedColor,
        set: &crate::mesh::TextureSet,
        out: &Path,
    ) -> usize {
        let home = set.materials.first().copied();
        let replaced = home
            .filter(|_| c.from_material)
            .and_then(|m| self.base_image(m, c.uv_set as usize));
        let texture = match replaced {
            Some(image) => {
                self.set_image(image, c.png, out);
                self.texture_of(image)
            }
            None => {
                let t = self.add_texture(c.png, home, out);
                for &m in &set.materials {
                    let white = !c.from_material || self.base_texture(m).is_none();
                    self.set_base_texture(m, t, c.uv_set, white);
                }
                t
            }
        };
        let bare: Vec<(usize, usize)> = set
            .primitives
            .iter()
            .map(|&i| {
                (
                    mesh.primitives[i].mesh_index,
                    mesh.primitives[i].primitive_index,
                )
            })
            .filter(|&(m, p)| self.primitive(m, p).get("material").is_none())
            .collect();
        self.add_material(bare, texture, c.uv_set);
        texture
    }

    /// A material painted with texture `t` on set `uv_set` for `primitives` (none: nothing).
    fn add_material(&mut self, primitives: Vec<(usize, usize)>, t: usize, uv_set: u32) {
        if primitives.is_empty() {
            return;
        }
        let list = array(&mut self.json, "materials");
        list.push(json!({"name": "decalbake", "pbrMetallicRoughness": {
            "baseColorTexture": {"index": t, "texCoord": uv_set},
            "metallicFactor": 0.0, "roughnessFactor": 1.0}}));
        let k = list.len() - 1;
        for (m, p) in primitives {
            self.json["meshes"][m]["primitives"][p]["material"] = json!(k);
        }
    }

    /// The bake of the whole mesh's one texture; returns the bake's texture.
    pub(super) fn apply_color(&mut self, mesh: &Mesh, c: &BakedColor, out: &Path) -> usize {
        let set = c.uv_set as usize;
        let painted: Vec<(usize, usize)> = mesh
            .primitives
            .iter()
            .filter(|p| p.uv_sets as usize > set || mesh.new_uv_sets.contains(&set))
            .map(|p| (p.mesh_index, p.primitive_index))
            .collect();
        let materials: BTreeSet<usize> = painted
            .iter()
            .filter_map(|&(m, p)| self.primitive(m, p)["material"].as_u64())
            .map(|m| m as usize)
            .collect();
        let home = mesh.material.as_ref().map(|m| m.index);
        let replaced = home
            .filter(|_| c.from_material)
            .and_then(|m| self.base_image(m, set));
        let texture = match replaced {
            Some(image) => {
                self.set_image(image, c.png, out);
                None
            }
            None => Some(self.add_texture(c.png, home, out)),
        };
        let home_factor = home.map(|m| self.factor(m));
        for &m in &materials {
            let own_image = self.base_image(m, set);
            let shares = match (replaced, own_image) {
                (Some(r), Some(i)) => r == i,
                (Some(_), None) => false,
                (None, _) if !c.from_material => true,
                (None, _) => {
                    Some(m) == home
                        || (self.base_texture(m).is_none() && Some(self.factor(m)) == home_factor)
                }
            };
            match (shares, texture) {
                (true, Some(t)) => {
                    let white = !c.from_material || self.base_texture(m).is_none();
                    self.set_base_texture(m, t, c.uv_set, white)
                }
                (true, None) => {}
                (false, _) => self.warnings.push(format!(
                    "materials[{m}]{} keeps its own base colour: a bake writes one base-colour texture, {}, so the paint on its primitives is not in the model",
                    self.material_name(m),
                    match home {
                        Some(h) => format!("the one of materials[{h}]{}", self.material_name(h)),
                        None => "a new one".into(),
                    }
                )),
            }
        }
        let bare: Vec<(usize, usize)> = painted
            .into_iter()
            .filter(|&(m, p)| self.primitive(m, p).get("material").is_none())
            .collect();
        let t = match (texture, replaced) {
            (Some(t), _) => t,
            (None, Some(image)) => self.texture_of(image),
            (None, None) => unreachable!("a texture is added where no image is replaced"),
        };
        self.add_material(bare, t, c.uv_set);
        t
    }

    pub(super) fn primitive(&self, m: usize, p: usize) -> &Value {
        &self.json["meshes"][m]["primitives"][p]
    }

    pub(super) fn material_name(&self, m: usize) -> String {
        self.json["materials"][m]["name"]
            .as_str()
            .map_or_else(String::new, |n| format!(" ({n:?})"))
    }

    pub(super) fn base_texture(&self, m: usize) -> Option<&Value> {
        self.json["materials"][m]
            .pointer("/pbrMetallicRoughness/baseColorTexture")
            .filter(|t| t.is_object())
    }

    fn factor(&self, m: usize) -> Vec<f64> {
        self.json["materials"][m]
            .pointer("/pbrMetallicRoughness/baseColorFactor")
            .and_then(Value::as_array)
            .map_or_else(
                || vec![1.0; 4],
                |a| a.iter().filter_map(Value::as_f64).collect(),
            )
    }

    /// The image of material `m`'s base-colour texture when it is laid out on UV set `set` as it
    /// is (no `KHR_texture_transform`).
    fn base_image(&self, m: usize, set: usize) -> Option<usize> {
        let info = self.base_texture(m)?;
        let tex_coord = info.get("texCoord").and_then(Value::as_u64).unwrap_or(0);
        if tex_coord as usize != set || info.pointer("/extensions/KHR_texture_transform").is_some()
        {
            return None;
        }
        let t = info.get("index")?.as_u64()? as usize;
        Some(self.json["textures"].get(t)?.get("source")?.as_u64()? as usize)
    }

    /// The first texture whose source is `image` (one is added where none is).
    fn texture_of(&mut self, image: usize) -> usize {
        let found = self.json["textures"].as_array().and_then(|ts| {
            ts.iter()
                .position(|t| t["source"].as_u64() == Some(image as u64))
        });
        found.unwrap_or_else(|| {
            let list = array(&mut self.json, "textures");
            list.push(json!({"source": image}));
            list.len() - 1
        })
    }

    /// Material `m`'s base colour becomes texture `t` on set `set`; its factor becomes white
    /// where the bake's base holds it (`white`: a job's own base, or a material base without a
    /// texture, whose factor was the base), and stays where it multiplies the material's texture.
    fn set_base_texture(&mut self, m: usize, t: usize, set: u32, white: bool) {
        let mat = &mut self.json["materials"][m];
        if !mat
            .get("pbrMetallicRoughness")
            .is_some_and(Value::is_object)
        {
            mat["pbrMetallicRoughness"] = json!({});
        }
        let pbr = &mut mat["pbrMetallicRoughness"];
        pbr["baseColorTexture"] = json!({"index": t, "texCoord": set});
        if white {
            pbr["baseColorFactor"] = json!([1.0, 1.0, 1.0, 1.0]);
        }
    }

    /// The bake as a new image and texture (sampled as material `home`'s base colour was, where it
    /// had one); returns the texture.
    pub(super) fn add_texture(&mut self, png: &[u8], home: Option<usize>, out: &Path) -> usize {
        let sampler = home
            .and_then(|m| self.base_texture(m))
            .and_then(|info| info.get("index")?.as_u64())
            .and_then(|t| {
                self.json["textures"]
                    .get(t as usize)?
                    .get("sampler")?
                    .as_u64()
            });
        let images = array(&mut self.json, "images");
        images.push(json!({"name": "decalbake"}));
        let image = images.len() - 1;
        self.set_image(image, png, out);
        let mut texture = json!({"source": image});
        if let Some(s) = sampler {
            texture["sampler"] = json!(s);
        }
        let list = array(&mut self.json, "textures");
        list.push(texture);
        list.len() - 1
    }

    /// Image `image` becomes `png`: in a buffer view (its own, where no other element reads it),
    /// or a file beside a `.gltf`.
    fn set_image(&mut self, image: usize, png: &[u8], out: &Path) {
        let old_view = self.json["images"][image]["bufferView"].as_u64();
        let img = self.json["images"][image]
            .as_object_mut()
            .expect("an image object");
        img.remove("uri");
        img.remove("bufferView");
        img.insert("mimeType".into(), json!("image/png"));
        if super::is_gltf_name(out) {
            let stem = out
                .file_stem()
                .map_or_else(|| "model".into(), |s| s.to_string_lossy().into_owned());
            let name = format!(
                "{stem}_baked{}.png",
                if image == 0 {
                    String::new()
                } else {
                    format!("_{image}")
                }
            );
            img.remove("mimeType");
            img.insert("uri".into(), json!(super::uri_of(&name)));
            self.image_files.push((name, png.to_vec()));
            return;
        }
        let view = match old_view {
            Some(v) if super::view_uses(&self.json, self.views.len())[v as usize] == 0 => {
                self.views[v as usize] = png.to_vec().into();
                v as usize
            }
            _ => self.push_view(png.to_vec(), None, None),
        };
        self.json["images"][image]["bufferView"] = json!(view);
    }
}
