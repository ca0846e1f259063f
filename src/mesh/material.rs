// SPDX-License-Identifier: MIT OR Apache-2.0
//! A material's PBR channels beside its base colour, read from the source document: the
//! metallic-roughness, occlusion, normal and emissive textures (decoded) with their factors, and
//! whether the material is unlit (`KHR_materials_unlit`: it shows none of them). The bake's
//! channel canvases start from these (`bake::channels`).

use super::document::SourceDocument;
use crate::io::image::LinearImage;
use serde_json::Value;

/// One of a material's textures, decoded.
#[derive(Debug, Clone)]
pub struct ChannelTexture {
    /// The document's image it is.
    pub image: usize,
    /// Its `texCoord`.
    pub uv_set: u32,
    /// Its pixels: as stored (data and normals) or sRGB-decoded (emissive).
    pub pixels: LinearImage,
}

/// A material's channels beside its base colour.
#[derive(Debug, Clone)]
pub struct MaterialChannels {
    /// `pbrMetallicRoughness.metallicRoughnessTexture` (G roughness, B metallic).
    pub metallic_roughness: Option<ChannelTexture>,
    /// `occlusionTexture` (R).
    pub occlusion: Option<ChannelTexture>,
    /// `normalTexture`.
    pub normal: Option<ChannelTexture>,
    /// `emissiveTexture`.
    pub emissive: Option<ChannelTexture>,
    /// `metallicFactor`, `roughnessFactor`.
    pub metallic: f32,
    /// `roughnessFactor`.
    pub roughness: f32,
    /// `normalTexture.scale`.
    pub normal_scale: f32,
    /// `occlusionTexture.strength`.
    pub occlusion_strength: f32,
    /// `emissiveFactor`, linear.
    pub emissive_factor: [f32; 3],
    /// `KHR_materials_unlit`: the material shows its base colour only.
    pub unlit: bool,
}

impl Default for MaterialChannels {
    fn default() -> Self {
        Self {
            metallic_roughness: None,
            occlusion: None,
            normal: None,
            emissive: None,
            metallic: 1.0,
            roughness: 1.0,
            normal_scale: 1.0,
            occlusion_strength: 1.0,
            emissive_factor: [0.0; 3],
            unlit: false,
        }
    }
}

/// Material `index` of `doc`'s channels; an image that does not decode is an error naming the
/// material, the field and the image.
pub fn channels(doc: &SourceDocument, index: usize) -> Result<MaterialChannels, String> {
    let Some(mat) = doc.array("materials").get(index) else {
        return Ok(MaterialChannels::default());
    };
    let pbr = &mat["pbrMetallicRoughness"];
    let number = |v: &Value, d: f32| v.as_f64().map_or(d, |x| x as f32);
    let mut emissive_factor = [0.0f32; 3];
    if let Some(f) = mat["emissiveFactor"].as_array() {
        for (k, v) in f.iter().take(3).enumerate() {
            emissive_factor[k] = number(v, 0.0);
        }
    }
    let tex = |info: &Value, field: &str, srgb: bool| texture(doc, index, info, field, srgb);
    Ok(MaterialChannels {
        metallic_roughness: tex(
            &pbr["metallicRoughnessTexture"],
            "pbrMetallicRoughness.metallicRoughnessTexture",
            false,
        )?,
        occlusion: tex(&mat["occlusionTexture"], "occlusionTexture", false)?,
        normal: tex(&mat["normalTexture"], "normalTexture", false)?,
        emissive: tex(&mat["emissiveTexture"], "emissiveTexture", true)?,
        metallic: number(&pbr["metallicFactor"], 1.0),
        roughness: number(&pbr["roughnessFactor"], 1.0),
        normal_scale: number(&mat["normalTexture"]["scale"], 1.0),
        occlusion_strength: number(&mat["occlusionTexture"]["strength"], 1.0),
        emissive_factor,
        unlit: mat.pointer("/extensions/KHR_materials_unlit").is_some(),
    })
}

/// The texture a texture-info object names, decoded (`None` without one).
fn texture(
    doc: &SourceDocument,
    material: usize,
    info: &Value,
    field: &str,
    srgb: bool,
) -> Result<Option<ChannelTexture>, String> {
    let Some(t) = info["index"].as_u64() else {
        return Ok(None);
    };
    let Some(image) = doc
        .array("textures")
        .get(t as usize)
        .and_then(|t| t["source"].as_u64())
    else {
        return Err(format!(
            "materials[{material}].{field} names textures[{t}], which does not exist or has no source"
        ));
    };
    let what = format!("materials[{material}].{field} (images[{image}])");
    let data = doc
        .image(image as usize)
        .map_err(|e| format!("{what}: {e}"))?;
    let img = LinearImage::decode(&data.bytes).map_err(|e| format!("{what}: {e}"))?;
    let mut pixels = match srgb {
        true => img,
        false => as_stored(img),
    };
    let mut uv_set = info["texCoord"].as_u64().unwrap_or(0) as u32;
    // A `KHR_texture_transform` is applied (as the base colour's is): the channel's bake starts
    // from the texture as laid out on its UVs, and the bake needs none.
    if let Some((m, set)) = super::load::texture_transform(info) {
        pixels = super::load::transformed(&pixels, m);
        uv_set = set.unwrap_or(uv_set);
    }
    Ok(Some(ChannelTexture {
        image: image as usize,
        uv_set,
        pixels,
    }))
}

/// An image's stored values (the decoder's sRGB decode undone): data, not colour.
pub fn as_stored(img: LinearImage) -> LinearImage {
    use crate::io::image::linear_to_srgb;
    LinearImage {
        pixels: img
            .pixels
            .iter()
            .map(|p| {
                [
                    linear_to_srgb(p[0]),
                    linear_to_srgb(p[1]),
                    linear_to_srgb(p[2]),
                    p[3],
                ]
            })
            .collect(),
        ..img
    }
}
