// SPDX-License-Identifier: MIT OR Apache-2.0
//! The baked PBR channels in the document. Each channel is added as an image and a texture (never
//! written over the image it started from: that image's factor went into the bake, and other
//! materials may read it), and every material that shows the baked base colour takes it on the
//! baked UV set:
//! - `orm`: `pbrMetallicRoughness.metallicRoughnessTexture` (G roughness, B metallic), factors 1;
//!   where the material had an `occlusionTexture` or a layer painted occlusion, that too, read
//!   from R (strength 1);
//! - `normal`: `normalTexture` (scale 1: the bake holds the scaled normals);
//! - `emissive`: `emissiveTexture`, `emissiveFactor` white (`KHR_materials_emissive_strength`
//!   stays, as a multiplier of what the bake holds).
//!
//! A material under `KHR_materials_unlit` shows none of them: it is left as it is and named in a
//! warning.

use super::{BakedChannelPng, BakedColor, Doc};
use crate::bake::channels::ChannelKind;
use crate::mesh::Mesh;
use serde_json::{json, Value};
use std::collections::BTreeSet;
use std::path::Path;

impl Doc<'_> {
    /// `c`'s channels onto the materials that show its base colour, texture `colour`.
    pub(super) fn apply_channels(
        &mut self,
        mesh: &Mesh,
        c: &BakedColor,
        colour: usize,
        out: &Path,
    ) {
        let source = self.json["textures"][colour]["source"].as_u64();
        let primitives: Vec<usize> = match c.set {
            Some(set) => set.primitives.clone(),
            None => (0..mesh.primitives.len()).collect(),
        };
        let materials: BTreeSet<usize> = primitives
            .iter()
            .map(|&i| {
                (
                    mesh.primitives[i].mesh_index,
                    mesh.primitives[i].primitive_index,
                )
            })
            .filter_map(|(m, p)| self.primitive(m, p)["material"].as_u64())
            .map(|m| m as usize)
            .filter(|&m| {
                let t = self.base_texture(m).and_then(|t| t["index"].as_u64());
                let s = t.and_then(|t| self.json["textures"][t as usize]["source"].as_u64());
                s.is_some() && s == source
            })
            .collect();
        let (unlit, lit): (Vec<usize>, Vec<usize>) = materials.into_iter().partition(|&m| {
            self.json["materials"][m]
                .pointer("/extensions/KHR_materials_unlit")
                .is_some()
        });
        for &m in &unlit {
            let names: Vec<&str> = c.channels.iter().map(|k| k.kind.name()).collect();
            self.warnings.push(format!(
                "materials[{m}]{} is unlit (KHR_materials_unlit), so it shows no {} channel: left as it is",
                self.material_name(m),
                names.join(", ")
            ));
        }
        if lit.is_empty() {
            return;
        }
        for ch in &c.channels {
            let t = self.add_texture(ch.png, lit.first().copied(), out);
            for &m in &lit {
                self.set_channel(m, ch, t, c.uv_set);
            }
        }
    }

    /// Material `m` takes texture `t` (on set `uv`) for channel `ch`.
    fn set_channel(&mut self, m: usize, ch: &BakedChannelPng, t: usize, uv: u32) {
        let mat = &mut self.json["materials"][m];
        let info = json!({"index": t, "texCoord": uv});
        match ch.kind {
            ChannelKind::Orm => {
                if !mat
                    .get("pbrMetallicRoughness")
                    .is_some_and(Value::is_object)
                {
                    mat["pbrMetallicRoughness"] = json!({});
                }
                let pbr = &mut mat["pbrMetallicRoughness"];
                pbr["metallicRoughnessTexture"] = info.clone();
                pbr["metallicFactor"] = json!(1.0);
                pbr["roughnessFactor"] = json!(1.0);
                if ch.occlusion || mat.get("occlusionTexture").is_some() {
                    mat["occlusionTexture"] = info;
                }
            }
            ChannelKind::Normal => mat["normalTexture"] = info,
            ChannelKind::Emissive => {
                mat["emissiveTexture"] = info;
                mat["emissiveFactor"] = json!([1.0, 1.0, 1.0]);
            }
        }
    }
}
