// SPDX-License-Identifier: MIT OR Apache-2.0
//! UV sets made since loading, added to the document's primitives; where pelting split or
//! reordered a primitive's vertices, every attribute and morph target of it is gathered anew
//! through [`Mesh::vertex_origin`] and its indices are rewritten.

use super::{component_size, component_value, type_width, Doc, ARRAY_BUFFER};
use crate::mesh::{Mesh, PrimitiveInfo};
use gltf::json as gj;
use serde_json::{json, Value};
use std::collections::{HashMap, HashSet};

impl Doc<'_> {
    /// Adds the mesh's new UV sets (and the pelt's weights) to every primitive of the document
    /// that the mesh holds; an instanced mesh takes the first instance's.
    pub(super) fn write_vertex_edits(&mut self, mesh: &Mesh) {
        let mut done: HashMap<(usize, usize), usize> = HashMap::new();
        let mut warned = HashSet::new();
        for p in &mesh.primitives {
            let key = (p.mesh_index, p.primitive_index);
            if let Some(&node) = done.get(&key) {
                if warned.insert(p.mesh_index) {
                    self.warnings.push(format!(
                        "meshes[{}] is drawn by nodes[{node}] and nodes[{}]; its new UV sets are laid out on nodes[{node}]'s instance, which the others share",
                        p.mesh_index, p.node
                    ));
                }
                continue;
            }
            done.insert(key, p.node);
            self.edit_primitive(mesh, p);
        }
    }

    fn edit_primitive(&mut self, mesh: &Mesh, p: &PrimitiveInfo) {
        let first = p.first_vertex as usize;
        let range = p.first_triangle as usize..(p.first_triangle + p.triangles) as usize;
        let tris = &mesh.triangles[range];
        // The primitive's vertices in the edited mesh, in order, and each one's vertex in the
        // document's primitive.
        let ids: Vec<u32> = if mesh.vertex_origin.is_empty() {
            (p.first_vertex..p.first_vertex + p.vertices).collect()
        } else {
            let mut v: Vec<u32> = tris.iter().flatten().copied().collect();
            v.sort_unstable();
            v.dedup();
            v
        };
        let locals: Vec<usize> = ids
            .iter()
            .map(|&i| {
                let o = mesh.vertex_origin.get(i as usize).copied().unwrap_or(i);
                (o as usize).wrapping_sub(first)
            })
            .collect();
        let what = format!("meshes[{}].primitives[{}]", p.mesh_index, p.primitive_index);
        if locals.iter().any(|&l| l >= p.vertices as usize) {
            self.warnings.push(format!(
                "{what}: its vertices were merged with another primitive's, so its new UV sets are not written"
            ));
            return;
        }
        let identity =
            locals.len() == p.vertices as usize && locals.iter().enumerate().all(|(k, &l)| k == l);
        let ptr = format!("/meshes/{}/primitives/{}", p.mesh_index, p.primitive_index);
        if !identity {
            self.gather_primitive(&ptr, &locals, &what);
            let at: HashMap<u32, u32> = ids
                .iter()
                .enumerate()
                .map(|(k, &i)| (i, k as u32))
                .collect();
            let idx: Vec<u32> = tris
                .iter()
                .flat_map(|t| {
                    // The loader turned a mirrored instance's triangles; the document's are not.
                    let t = if p.flipped { [t[0], t[2], t[1]] } else { *t };
                    t.map(|v| at[&v])
                })
                .collect();
            let old = self.json.pointer(&ptr).expect("the primitive")["indices"].as_u64();
            let acc = self.push_indices(&idx);
            let acc = self.in_place(old.map(|o| o as usize), acc);
            self.json.pointer_mut(&ptr).expect("the primitive")["indices"] = json!(acc);
        }
        let prim = self.json.pointer(&ptr).expect("the primitive");
        let have = (0..)
            .take_while(|n| prim["attributes"].get(format!("TEXCOORD_{n}")).is_some())
            .count();
        let top = mesh.new_uv_sets.iter().copied().max().map_or(0, |m| m + 1);
        for n in 0..top.min(mesh.uv_sets.len()) {
            if !(mesh.new_uv_sets.contains(&n) || n >= have) {
                continue;
            }
            let uv: Vec<f32> = ids
                .iter()
                .flat_map(|&i| mesh.uv_sets[n][i as usize].to_array())
                .collect();
            let acc = self.push_f32(&uv, gj::accessor::Type::Vec2, None);
            self.json.pointer_mut(&ptr).expect("the primitive")["attributes"]
                [format!("TEXCOORD_{n}")] = json!(acc);
        }
        for (name, w) in [("_PELT_BLEND", &mesh.blend), ("_PELT_BRIDGE", &mesh.bridge)] {
            let acc = (w.len() == mesh.positions.len()).then(|| {
                let v: Vec<f32> = ids.iter().map(|&i| w[i as usize]).collect();
                self.push_f32(&v, gj::accessor::Type::Scalar, None)
            });
            let attributes = &mut self.json.pointer_mut(&ptr).expect("the primitive")["attributes"];
            match acc {
                Some(a) => attributes[name] = json!(a),
                None => {
                    if let Some(o) = attributes.as_object_mut() {
                        o.remove(name);
                    }
                }
            }
        }
    }

    /// Every attribute and morph target of the primitive at `ptr` gathered at `locals` (the
    /// document's vertex of each new vertex); a Draco copy of the old vertices is dropped.
    fn gather_primitive(&mut self, ptr: &str, locals: &[usize], what: &str) {
        let prim = self.json.pointer(ptr).expect("the primitive").clone();
        let mut lists: Vec<(String, &Value)> = vec![("/attributes".into(), &prim["attributes"])];
        if let Some(targets) = prim.get("targets").and_then(Value::as_array) {
            for (t, target) in targets.iter().enumerate() {
                lists.push((format!("/targets/{t}"), target));
            }
        }
        for (sub, list) in lists {
            let Some(map) = list.as_object() else {
                continue;
            };
            for (name, acc) in map {
                let Some(acc) = acc.as_u64() else { continue };
                match self.gather(acc as usize, locals) {
                    Some(new) => {
                        let at = format!("{ptr}{sub}");
                        self.json.pointer_mut(&at).expect("the attribute map")[name] = json!(new);
                    }
                    None => self.warnings.push(format!(
                        "{what} {name}: accessors[{acc}] could not be read, so it keeps the old vertex order"
                    )),
                }
            }
        }
        let prim = self.json.pointer_mut(ptr).expect("the primitive");
        if let Some(ext) = prim.get_mut("extensions").and_then(Value::as_object_mut) {
            if ext.remove("KHR_draco_mesh_compression").is_some() {
                self.warnings.push(format!("{what}: its Draco-compressed copy holds the old vertices, so it is left out (the uncompressed attributes carry the new UV set)"));
            }
        }
    }

    /// A new accessor of accessor `acc`'s elements at `locals` (its name, type and `normalized`
    /// kept; `min` and `max` computed anew where it had them), in a buffer view of its own whose
    /// elements are 4-byte aligned as glTF requires of vertex attributes.
    fn gather(&mut self, acc: usize, locals: &[usize]) -> Option<usize> {
        let a = self.json.get("accessors")?.get(acc)?.clone();
        let comp = a.get("componentType")?.as_u64()?;
        let ty = a.get("type")?.as_str()?;
        let width = type_width(ty);
        let csize = component_size(comp);
        let esize = width * csize;
        let elements = self.elements(&a, esize)?;
        let padded = esize.next_multiple_of(4);
        let mut out = Vec::with_capacity(locals.len() * padded);
        let (mut lo, mut hi) = (vec![f64::MAX; width], vec![f64::MIN; width]);
        for &l in locals {
            let e = elements.get(l * esize..(l + 1) * esize)?;
            for c in 0..width {
                let v = component_value(&e[c * csize..], comp);
                lo[c] = lo[c].min(v);
                hi[c] = hi[c].max(v);
            }
            out.extend_from_slice(e);
            out.resize(out.len() + padded - esize, 0);
        }
        let view = self.push_view(out, Some(ARRAY_BUFFER), (padded != esize).then_some(padded));
        let mut new = a.clone();
        let obj = new.as_object_mut()?;
        for key in ["byteOffset", "sparse"] {
            obj.remove(key);
        }
        obj.insert("bufferView".into(), json!(view));
        obj.insert("count".into(), json!(locals.len()));
        if a.get("min").is_some() || a.get("max").is_some() {
            let number = |v: f64| {
                if comp == 5126 {
                    json!(v)
                } else {
                    json!(v as i64)
                }
            };
            obj.insert(
                "min".into(),
                Value::Array(lo.into_iter().map(number).collect()),
            );
            obj.insert(
                "max".into(),
                Value::Array(hi.into_iter().map(number).collect()),
            );
        }
        let list = super::array(&mut self.json, "accessors");
        list.push(new);
        let pushed = list.len() - 1;
        Some(self.in_place(Some(acc), pushed))
    }

    /// The accessor just pushed (`pushed`, the last) moved to index `old` where only the reference
    /// about to be rewritten names `old` (so no accessor is left holding the old data); `pushed`
    /// otherwise.
    fn in_place(&mut self, old: Option<usize>, pushed: usize) -> usize {
        match old {
            Some(o) if o < pushed && accessor_uses(&self.json, o) == 1 => {
                let list = super::array(&mut self.json, "accessors");
                let mut new = list.pop().expect("the pushed accessor");
                // The old accessor's name, extras and extensions stay with its index.
                for key in ["name", "extras", "extensions"] {
                    if let (Some(v), None) = (list[o].get(key).cloned(), new.get(key)) {
                        new[key] = v;
                    }
                }
                list[o] = new;
                o
            }
            _ => pushed,
        }
    }

    /// Accessor `a`'s elements, tightly packed (`esize` bytes each): from its buffer view (with
    /// its stride), zeros without one, and its sparse substitutions applied.
    fn elements(&self, a: &Value, esize: usize) -> Option<Vec<u8>> {
        let count = a.get("count")?.as_u64()? as usize;
        let mut out = vec![0u8; count.checked_mul(esize)?];
        if let Some(view) = a.get("bufferView").and_then(Value::as_u64) {
            let bytes = self.views.get(view as usize)?;
            let stride = self.json["bufferViews"][view as usize]
                .get("byteStride")
                .and_then(Value::as_u64)
                .map_or(esize, |s| s as usize);
            let offset = a.get("byteOffset").and_then(Value::as_u64).unwrap_or(0) as usize;
            for i in 0..count {
                let at = offset + i * stride;
                out[i * esize..(i + 1) * esize].copy_from_slice(bytes.get(at..at + esize)?);
            }
        }
        if let Some(sparse) = a.get("sparse") {
            let n = sparse.get("count")?.as_u64()? as usize;
            let ix = &sparse["indices"];
            let ic = ix.get("componentType")?.as_u64()?;
            let isize = component_size(ic);
            let iview = self.views.get(ix.get("bufferView")?.as_u64()? as usize)?;
            let ioff = ix.get("byteOffset").and_then(Value::as_u64).unwrap_or(0) as usize;
            let vx = &sparse["values"];
            let vview = self.views.get(vx.get("bufferView")?.as_u64()? as usize)?;
            let voff = vx.get("byteOffset").and_then(Value::as_u64).unwrap_or(0) as usize;
            for k in 0..n {
                let i = component_value(iview.get(ioff + k * isize..)?, ic) as usize;
                let v = vview.get(voff + k * esize..voff + (k + 1) * esize)?;
                out.get_mut(i * esize..(i + 1) * esize)?.copy_from_slice(v);
            }
        }
        Some(out)
    }
}

/// How often the document names accessor `a` (primitives' attributes, indices and morph
/// targets, skins' inverse bind matrices, animation samplers).
pub(super) fn accessor_uses(json: &Value, a: usize) -> usize {
    let is = |v: &Value| v.as_u64() == Some(a as u64);
    let mut n = 0;
    for mesh in json["meshes"].as_array().into_iter().flatten() {
        for prim in mesh["primitives"].as_array().into_iter().flatten() {
            n += prim["attributes"]
                .as_object()
                .into_iter()
                .flatten()
                .filter(|(_, v)| is(v))
                .count();
            n += usize::from(is(&prim["indices"]));
            for t in prim["targets"].as_array().into_iter().flatten() {
                n += t
                    .as_object()
                    .into_iter()
                    .flatten()
                    .filter(|(_, v)| is(v))
                    .count();
            }
        }
    }
    for skin in json["skins"].as_array().into_iter().flatten() {
        n += usize::from(is(&skin["inverseBindMatrices"]));
    }
    for anim in json["animations"].as_array().into_iter().flatten() {
        for s in anim["samplers"].as_array().into_iter().flatten() {
            n += usize::from(is(&s["input"])) + usize::from(is(&s["output"]));
        }
    }
    n
}
