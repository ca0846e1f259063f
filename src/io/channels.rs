// SPDX-License-Identifier: MIT OR Apache-2.0
//! A layer's PBR channels beside its colour `image`: `normal` (a tangent-space normal map, with
//! `normal_y` and `normal_blend`), `roughness`, `metallic`, `occlusion` (each an image, whose red
//! channel is read as data, or a number) and `emissive` (an image or a linear RGB triple), each
//! with its own `<channel>_opacity` (default: the layer's `opacity`), and `data_blend` for the
//! data channels. Every channel is masked by the layer's `mask` and its colour image's alpha.

use crate::error::{Error, Result};
use std::path::{Path, PathBuf};

/// A channel's value as written in the job file: a number, an RGB triple or an image path.
#[derive(Debug, Clone, serde::Deserialize, schemars::JsonSchema)]
#[serde(untagged)]
pub enum ValueSpec {
    /// A number in [0, 1].
    Number(f32),
    /// A linear RGB triple.
    Rgb([f32; 3]),
    /// An image file.
    Path(PathBuf),
}

/// A channel's value after validation.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    /// An image: a data channel reads its red channel as stored (no sRGB decode); emissive is
    /// colour (sRGB-decoded).
    Image(PathBuf),
    /// A constant, linear (a data channel's in all three components).
    Constant([f32; 3]),
}

/// One channel of a layer.
#[derive(Debug, Clone, PartialEq)]
pub struct Channel {
    /// What it paints.
    pub value: Value,
    /// Its opacity in [0, 1].
    pub opacity: f32,
}

/// How a normal decal's normal combines with the surface's.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum NormalBlend {
    /// Reoriented normal mapping (Barré-Brisebois & Hill 2012): the decal's normal turned by the
    /// rotation that takes the surface's up to the base normal. Over a flat base it is the
    /// decal's normal exactly.
    #[default]
    Rnm,
    /// Whiteout-free "UDN": the slopes added, the base's z kept.
    Udn,
    /// The decal's normal replaces the base's.
    Replace,
}

/// How a data channel (roughness, metallic, occlusion) combines with the texture's.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum DataBlend {
    /// The layer's value mixed in by its alpha × mask × opacity (a lerp).
    #[default]
    Normal,
    /// The layer's value, unmixed, wherever its alpha × mask × opacity is at least one half.
    Replace,
}

/// A normal decal.
#[derive(Debug, Clone, PartialEq)]
pub struct Normal {
    /// The normal map image (read as stored, not sRGB-decoded).
    pub image: PathBuf,
    /// Whether green points down the image (DirectX's convention; glTF's is up).
    pub y_down: bool,
    /// How it combines with the surface's normal.
    pub blend: NormalBlend,
    /// Its opacity.
    pub opacity: f32,
}

/// Every PBR channel of a layer beside its colour.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Channels {
    /// Tangent-space normal.
    pub normal: Option<Normal>,
    /// Roughness (the metallic-roughness texture's green).
    pub roughness: Option<Channel>,
    /// Metallic (its blue).
    pub metallic: Option<Channel>,
    /// Ambient occlusion (the occlusion texture's red).
    pub occlusion: Option<Channel>,
    /// Emissive colour.
    pub emissive: Option<Channel>,
    /// How roughness, metallic and occlusion blend.
    pub data_blend: DataBlend,
}

impl Channels {
    /// Whether every occlusion, roughness and metallic part painted is at `opacity` (the
    /// layer's; the default): the group is then drawn at that opacity with each part weighted 1.
    pub fn orm_at(&self, opacity: f32) -> bool {
        [&self.occlusion, &self.roughness, &self.metallic]
            .into_iter()
            .flatten()
            .all(|p| p.opacity == opacity)
    }

    /// The opacity group `kind` is drawn at by the raster, on a layer of `opacity`: ORM at the
    /// layer's where [`Channels::orm_at`] it, else 1 (its parts' opacities then weight the mix);
    /// normal and emissive at their own.
    pub fn draw_opacity(&self, kind: ChannelKind, opacity: f32) -> f32 {
        match kind {
            ChannelKind::Orm => match self.orm_at(opacity) {
                true => opacity,
                false => 1.0,
            },
            ChannelKind::Normal => self.normal.as_ref().map_or(0.0, |n| n.opacity),
            ChannelKind::Emissive => self.emissive.as_ref().map_or(0.0, |e| e.opacity),
        }
    }

    /// The value of group `kind` where every part of it the layer paints is a number (the parts
    /// it does not paint: 0, which its data weights leave unchanged): drawn from the colour's
    /// coverage. `None` where one is an image, or for normals.
    pub fn constant(&self, kind: ChannelKind) -> Option<[f32; 4]> {
        match kind {
            ChannelKind::Orm => {
                let mut out = [0.0; 4];
                let parts = [&self.occlusion, &self.roughness, &self.metallic];
                for (k, p) in parts.iter().enumerate() {
                    match p.as_ref().map(|p| &p.value) {
                        Some(Value::Constant(v)) => out[k] = v[0],
                        Some(Value::Image(_)) => return None,
                        None => {}
                    }
                }
                Some(out)
            }
            ChannelKind::Normal => None,
            ChannelKind::Emissive => match self.emissive.as_ref().map(|e| &e.value) {
                Some(Value::Constant(v)) => Some([v[0], v[1], v[2], 0.0]),
                _ => None,
            },
        }
    }

    /// Whether group `kind`, painted on a layer of `opacity`, is derived in the compose from the
    /// colour's samples (numbers drawn at the colour's opacity: their samples' alphas are the
    /// colour's), so a fused raster draws no attachment for it.
    pub fn derived(&self, kind: ChannelKind, opacity: f32) -> bool {
        self.constant(kind).is_some() && self.draw_opacity(kind, opacity) == opacity
    }

    /// Whether any channel but colour is painted.
    pub fn any(&self) -> bool {
        self.normal.is_some()
            || self.roughness.is_some()
            || self.metallic.is_some()
            || self.occlusion.is_some()
            || self.emissive.is_some()
    }

    /// Whether the layer paints the texture `kind`.
    pub fn paints(&self, kind: ChannelKind) -> bool {
        match kind {
            ChannelKind::Orm => self.any_data(),
            ChannelKind::Normal => self.normal.is_some(),
            ChannelKind::Emissive => self.emissive.is_some(),
        }
    }

    /// Whether a data channel (roughness, metallic, occlusion) is painted.
    pub fn any_data(&self) -> bool {
        self.roughness.is_some() || self.metallic.is_some() || self.occlusion.is_some()
    }

    /// Every channel image's path (the normal map's and each image-valued channel's).
    pub fn image_paths(&self) -> impl Iterator<Item = &std::path::Path> {
        let values = [
            &self.roughness,
            &self.metallic,
            &self.occlusion,
            &self.emissive,
        ];
        self.normal
            .as_ref()
            .map(|n| n.image.as_path())
            .into_iter()
            .chain(values.into_iter().flatten().filter_map(|c| match &c.value {
                Value::Image(p) => Some(p.as_path()),
                Value::Constant(_) => None,
            }))
    }
}

/// A texture a bake writes besides the colour.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ChannelKind {
    /// Occlusion (R), roughness (G), metallic (B), linear: glTF's metallic-roughness texture
    /// (which ignores R) and, where the material has one, its occlusion texture.
    Orm,
    /// A tangent-space normal map, linear (n * 0.5 + 0.5).
    Normal,
    /// Emissive colour, sRGB.
    Emissive,
}

impl ChannelKind {
    /// Every kind, in pass order.
    pub const ALL: [ChannelKind; 3] =
        [ChannelKind::Orm, ChannelKind::Normal, ChannelKind::Emissive];

    /// Its name in file names (`{channel}`) and reports.
    pub fn name(self) -> &'static str {
        match self {
            ChannelKind::Orm => "orm",
            ChannelKind::Normal => "normal",
            ChannelKind::Emissive => "emissive",
        }
    }

    /// Whether it is stored as is (data, normals) rather than sRGB-encoded.
    pub fn linear(self) -> bool {
        self != ChannelKind::Emissive
    }

    /// Its place among the groups (0, 1, 2: the bit of a set of groups, and the attachment after
    /// the colour and coverage where the groups are drawn beside the colour).
    pub fn slot(self) -> usize {
        match self {
            ChannelKind::Orm => 0,
            ChannelKind::Normal => 1,
            ChannelKind::Emissive => 2,
        }
    }
}

/// The job file's channel fields of one layer.
pub struct Fields<'a> {
    /// `normal`.
    pub normal: &'a Option<PathBuf>,
    /// `normal_y`.
    pub normal_y: &'a Option<String>,
    /// `normal_blend`.
    pub normal_blend: &'a Option<String>,
    /// `roughness`, `metallic`, `occlusion`, `emissive`.
    pub values: [&'a Option<ValueSpec>; 4],
    /// `normal_opacity`, `roughness_opacity`, `metallic_opacity`, `occlusion_opacity`,
    /// `emissive_opacity`.
    pub opacities: [Option<f32>; 5],
    /// `data_blend`.
    pub data_blend: &'a Option<String>,
}

const VALUE_NAMES: [&str; 4] = ["roughness", "metallic", "occlusion", "emissive"];

/// Validates layer `i`'s channel fields (`src`: the job file, for messages; paths resolved
/// against `dir`; `opacity`: the layer's, every channel's default).
pub fn validate(
    f: &Fields<'_>,
    i: usize,
    src: &Path,
    dir: &Path,
    opacity: f32,
) -> Result<Channels> {
    let err = |name: &str, detail: String| Error::job(src, format!("layers[{i}].{name}"), detail);
    let names = ["normal", "roughness", "metallic", "occlusion", "emissive"];
    let mut opacities = [opacity; 5];
    for (k, o) in f.opacities.iter().enumerate() {
        let Some(o) = *o else { continue };
        if !o.is_finite() || !(0.0..=1.0).contains(&o) {
            return Err(err(
                &format!("{}_opacity", names[k]),
                format!("{o} must be in [0, 1]"),
            ));
        }
        let given = match k {
            0 => f.normal.is_some(),
            _ => f.values[k - 1].is_some(),
        };
        if !given {
            return Err(err(
                &format!("{}_opacity", names[k]),
                format!("there is no `{}` on this layer to apply it to", names[k]),
            ));
        }
        opacities[k] = o;
    }
    let y_down = match f.normal_y.as_deref() {
        None | Some("gl") => false,
        Some("dx") => true,
        Some(other) => {
            return Err(err(
                "normal_y",
                format!("unknown convention \"{other}\"; use \"gl\" (glTF's, green up) or \"dx\" (green down)"),
            ))
        }
    };
    let blend = match f.normal_blend.as_deref() {
        None | Some("rnm") => NormalBlend::Rnm,
        Some("udn") => NormalBlend::Udn,
        Some("replace") => NormalBlend::Replace,
        Some(other) => {
            return Err(err(
                "normal_blend",
                format!("unknown normal blend \"{other}\"; use \"rnm\", \"udn\" or \"replace\""),
            ))
        }
    };
    if f.normal.is_none() && (f.normal_y.is_some() || f.normal_blend.is_some()) {
        let name = if f.normal_y.is_some() {
            "normal_y"
        } else {
            "normal_blend"
        };
        return Err(err(
            name,
            "applies to a `normal` image; add one or remove it".into(),
        ));
    }
    let data_blend = match f.data_blend.as_deref() {
        None | Some("normal") => DataBlend::Normal,
        Some("replace") => DataBlend::Replace,
        Some(other) => {
            return Err(err(
                "data_blend",
                format!("unknown data blend \"{other}\"; use \"normal\" (mix) or \"replace\""),
            ))
        }
    };
    let mut values: [Option<Channel>; 4] = Default::default();
    for (k, spec) in f.values.iter().enumerate() {
        let Some(spec) = spec else { continue };
        let name = VALUE_NAMES[k];
        let value = value(spec, k == 3, dir).map_err(|d| err(name, d))?;
        values[k] = Some(Channel {
            value,
            opacity: opacities[k + 1],
        });
    }
    let [roughness, metallic, occlusion, emissive] = values;
    Ok(Channels {
        normal: f.normal.as_ref().map(|p| Normal {
            image: dir.join(p),
            y_down,
            blend,
            opacity: opacities[0],
        }),
        roughness,
        metallic,
        occlusion,
        emissive,
        data_blend,
    })
}

/// A value spec checked: a data channel takes a number in [0, 1] or an image; emissive
/// (`rgb`) an RGB triple of non-negative numbers or an image.
fn value(spec: &ValueSpec, rgb: bool, dir: &Path) -> std::result::Result<Value, String> {
    match (spec, rgb) {
        (ValueSpec::Path(p), _) => Ok(Value::Image(dir.join(p))),
        (ValueSpec::Number(v), false) if v.is_finite() && (0.0..=1.0).contains(v) => {
            Ok(Value::Constant([*v; 3]))
        }
        (ValueSpec::Number(v), false) => Err(format!("{v} must be in [0, 1], or an image")),
        (ValueSpec::Rgb(c), true) if c.iter().all(|v| v.is_finite() && *v >= 0.0) => {
            Ok(Value::Constant(*c))
        }
        (ValueSpec::Rgb(c), true) => Err(format!(
            "{c:?} must be three finite non-negative numbers (linear RGB), or an image"
        )),
        (_, true) => Err("must be a linear RGB triple [r, g, b] or an image".into()),
        (_, false) => Err("must be a number in [0, 1] or an image".into()),
    }
}
