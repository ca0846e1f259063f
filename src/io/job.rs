// SPDX-License-Identifier: MIT OR Apache-2.0
//! The job file: what to bake, onto which mesh, and where the results go.
//!
//! JSON, with paths relative to the job file. Unknown fields are an error that names them. Defaults
//! (documented in docs/job-file.md as well):
//!
//! | field | default |
//! |---|---|
//! | `uv_set` | `0` (a set's number, or `"auto"`: the base-colour texture's set, or on a mesh without UVs a `TEXCOORD_0` made by pelting, `crate::pelt`) |
//! | `texture.width`, `texture.height` | `2048` |
//! | `texture.sets` | none (a material's name or index to its texture set's `width` and `height`) |
//! | `texture.base` | `"material"` (the material's base-colour texture; its factor as a solid colour if it has none; mid grey without a material); also an image path, a linear RGBA colour, or `{"transfer": {"from_uv_set": N, "image": "material" or a path}}` |
//! | `texture.padding` | `16` texels (`"full"` fills the whole background) |
//! | `texture.samples` | `4` (2×2 supersampling; 1, 4, 9 or 16) |
//! | `texture.sampling` | `"full"` (the raster runs once a sample); `"adaptive"`: with four samples, once a texel and triangle where the device holds four-sample targets |
//! | `texture.tile` | none: tiles of the largest power-of-two side that fits one storage buffer, only when the whole texture does not; or a multiple of 64 |
//! | layer `kind` | `"decal"` |
//! | layer `mask` | none |
//! | layer `angle` | `0` degrees |
//! | layer `up` | `[0, 1, 0]` |
//! | layer `method` | `"expmap"` (decals), `"lscm"` (strokes) |
//! | layer `blend` | `"normal"` |
//! | layer `opacity` | `1.0` |
//! | layer `depth` (planar) | half the larger of the two sizes |
//! | `output.texture` | `"baked.png"` (`.exr`: OpenEXR, linear 32-bit float) |
//! | `output.bit_depth` | `8` |
//! | `output.compression` | `"fast"` (PNG: fast deflate; `"small"`: the smallest files, slower) |
//! | `output.report` | `"report.json"` |
//! | `output.glb`, `output.preview` | none |

use crate::error::{Error, Result};
use crate::io::at::check_at;
pub use crate::io::at::{AtSpec, RaySpec};
pub use crate::io::stroke::{Orient, Stroke, Tool};
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// The whole job.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(title = "decalbake job")]
pub struct JobFile {
    /// The JSON Schema this file follows (`decalbake schema job` prints it); the bake ignores it.
    #[serde(rename = "$schema", default)]
    pub schema: Option<String>,
    /// The mesh (`.gltf` or `.glb`).
    pub mesh: PathBuf,
    /// Which `TEXCOORD_n` set to bake into: a number, a list of numbers (one texture each), or
    /// `"auto"` (the base-colour texture's set; on a mesh without UVs, one made by pelting).
    #[serde(default)]
    pub uv_set: UvSetField,
    /// The output texture.
    #[serde(default)]
    pub texture: TextureSpec,
    /// Layers, applied in order.
    #[serde(default)]
    pub layers: Vec<LayerSpec>,
    /// Output files.
    #[serde(default)]
    pub output: OutputSpec,
    /// The most memory the bake may take (host, and device on a CPU adapter): bytes, or text
    /// with a unit (`"512MiB"`, `"2GB"`); default: the memory the machine has available.
    #[serde(default)]
    pub max_memory: Option<MemorySpec>,
}

/// `max_memory` in bytes: 0 and text that is not a size are refused, naming the field.
fn max_memory(spec: Option<&MemorySpec>, src: &Path) -> Result<Option<u64>> {
    let err = |detail: String| Error::job(src, "max_memory", detail);
    match spec {
        None => Ok(None),
        Some(MemorySpec::Bytes(0)) => Err(err("0 bytes leaves no room for any bake".into())),
        Some(MemorySpec::Bytes(b)) => Ok(Some(*b)),
        Some(MemorySpec::Text(t)) => parse_size(t).map(Some).ok_or_else(|| {
            err(format!(
                "\"{t}\" is not a size: give bytes, or a number with a unit (\"512MiB\", \"2GB\")"
            ))
        }),
    }
}

/// `texture.sampling`: whether four samples a texel are drawn adaptively (not by default).
fn sampling(t: &TextureSpec, src: &Path) -> Result<bool> {
    match t.sampling.as_deref() {
        Some("adaptive") => Ok(true),
        None | Some("full") => Ok(false),
        Some(other) => Err(Error::job(
            src,
            "texture.sampling",
            format!("\"{other}\" is not a sampling; use \"adaptive\" or \"full\""),
        )),
    }
}

/// The output's PNG compression, once its bit depth is checked (8 or 16): any other depth or
/// compression is refused, naming the field.
fn output_encoding(o: &OutputSpec, src: &Path) -> Result<crate::io::image::PngCompression> {
    use crate::io::image::PngCompression;
    if o.bit_depth != 8 && o.bit_depth != 16 {
        let detail = format!("{} is not 8 or 16", o.bit_depth);
        return Err(Error::job(src, "output.bit_depth", detail));
    }
    match o.compression.as_deref() {
        None | Some("fast") => Ok(PngCompression::Fast),
        Some("small") => Ok(PngCompression::Small),
        Some(other) => Err(Error::job(
            src,
            "output.compression",
            format!("\"{other}\" is not a compression; use \"fast\" or \"small\""),
        )),
    }
}

/// Parses a memory size: a number of bytes, or a number with a unit (`k`, `M`, `G`, `T`, with
/// or without `i` and `B`: powers of 1024; `"1.5GiB"`, `"512M"`, `"2GB"`).
pub fn parse_size(text: &str) -> Option<u64> {
    let t = text.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (num, unit) = t.split_at(split);
    let value: f64 = num.parse().ok()?;
    let unit = unit
        .trim()
        .trim_end_matches(['B', 'b'])
        .trim_end_matches('i');
    let scale: u64 = match unit.to_ascii_lowercase().as_str() {
        "" => 1,
        "k" => 1 << 10,
        "m" => 1 << 20,
        "g" => 1 << 30,
        "t" => 1 << 40,
        _ => return None,
    };
    let bytes = value * scale as f64;
    (value.is_finite() && value > 0.0 && bytes < u64::MAX as f64).then_some(bytes as u64)
}

/// `max_memory`: bytes, or a number with a unit.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(untagged)]
pub enum MemorySpec {
    /// Bytes.
    Bytes(u64),
    /// `"512MiB"`, `"2GB"`, `"1.5G"`.
    Text(String),
}

/// `uv_set`: a set's number or `"auto"`.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(untagged)]
pub enum UvSetField {
    /// `TEXCOORD_n`.
    Index(u32),
    /// `"auto"` (any other text is an error).
    Named(#[schemars(extend("enum" = ["auto"]))] String),
    /// Several sets at once (`[0, 1]`: a model with a pelt and its patch, `decalbake unwrap
    /// --patch`): one texture per set, `{uv}` in `output.texture` naming them.
    List(Vec<u32>),
}

impl Default for UvSetField {
    fn default() -> Self {
        Self::Index(0)
    }
}

/// Output texture settings.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TextureSpec {
    /// Width in texels.
    #[serde(default = "default_side")]
    pub width: u32,
    /// Height in texels.
    #[serde(default = "default_side")]
    pub height: u32,
    /// What the layers are composed onto: `"material"` (the model's base-colour texture), an
    /// image path, a linear RGBA colour, or a texture transferred from another UV set.
    #[serde(default)]
    pub base: BaseSpec,
    /// How far each UV island is grown into the background, in texels, or `"full"`.
    #[serde(default)]
    pub padding: PaddingSpec,
    /// Samples per texel (a square: 1, 4, 9, 16).
    #[serde(default = "default_samples")]
    #[schemars(extend("enum" = [1, 4, 9, 16]))]
    pub samples: u32,
    /// How four samples a texel are drawn: `"full"` (once a sample; the default) or `"adaptive"`
    /// (once a texel and triangle, written to the samples it covers).
    #[serde(default)]
    #[schemars(extend("enum" = ["adaptive", "full"]))]
    pub sampling: Option<String>,
    /// Bake by tiles of this many texels a side (a multiple of 64); default: tiles only when the
    /// texture does not fit one storage buffer of the device.
    #[serde(default)]
    pub tile: Option<u32>,
    /// Per texture set sizes: a material's name or index to its set's `width` and `height`
    /// (each defaulting to the texture's).
    #[serde(default)]
    pub sets: std::collections::BTreeMap<String, SetSize>,
}

/// `texture.sets.<material>`: the size of that material's texture set.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SetSize {
    /// Width in texels (default: `texture.width`).
    pub width: Option<u32>,
    /// Height in texels (default: `texture.height`).
    pub height: Option<u32>,
}

/// Every side `texture.sets` gives is at least 1 texel.
fn check_set_sizes(t: &TextureSpec, src: &Path) -> Result<()> {
    for (key, size) in &t.sets {
        for (side, v) in [("width", size.width), ("height", size.height)] {
            if v == Some(0) {
                return Err(Error::job(
                    src,
                    format!("texture.sets.{key}.{side}"),
                    "must be at least 1 texel",
                ));
            }
        }
    }
    Ok(())
}

fn default_side() -> u32 {
    2048
}
fn default_samples() -> u32 {
    4
}

impl Default for TextureSpec {
    fn default() -> Self {
        Self {
            width: default_side(),
            height: default_side(),
            base: BaseSpec::default(),
            padding: PaddingSpec::default(),
            samples: default_samples(),
            sampling: None,
            tile: None,
            sets: Default::default(),
        }
    }
}

/// The base the layers are composed onto.
#[derive(Debug, Clone, Deserialize, PartialEq, schemars::JsonSchema)]
#[serde(untagged, deny_unknown_fields)]
pub enum BaseSpec {
    /// A linear RGBA colour in [0, 1].
    Color([f32; 4]),
    /// `"material"` or an image path.
    Name(String),
    /// `{"transfer": {"from_uv_set": 0, "image": "material"}}`.
    Transfer {
        /// The texture and the set it is laid out on.
        transfer: TransferSpec,
    },
}

/// `texture.base.transfer`: an existing texture laid out on another UV set, resampled into the set
/// being baked (each texel's surface point looks the texture up at its UV in `from_uv_set`): the
/// usual step after a new unwrap.
#[derive(Debug, Clone, Deserialize, PartialEq, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TransferSpec {
    /// The set the texture is laid out on.
    pub from_uv_set: u32,
    /// `"material"` (the default) or an image path.
    #[serde(default = "material")]
    pub image: String,
}

fn material() -> String {
    "material".into()
}

impl Default for BaseSpec {
    fn default() -> Self {
        BaseSpec::Name("material".into())
    }
}

/// How far islands are grown.
#[derive(Debug, Clone, Deserialize, PartialEq, schemars::JsonSchema)]
#[serde(untagged)]
pub enum PaddingSpec {
    /// Texels.
    Texels(u32),
    /// `"full"`.
    Word(#[schemars(extend("enum" = ["full"]))] String),
}

impl Default for PaddingSpec {
    fn default() -> Self {
        PaddingSpec::Texels(16)
    }
}

/// One layer.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct LayerSpec {
    /// What the layer is: a `"decal"` placed at one point, a `"stroke"` of stamps along a path, a
    /// `"ribbon"` laid along a curve, or `"text"` (at a point or along a curve).
    #[serde(default = "default_kind")]
    #[schemars(extend("enum" = ["decal", "stroke", "ribbon", "text"]))]
    pub kind: String,
    /// The layer's colour image (PNG or JPEG, 8 or 16 bits, sRGB, or SVG, rendered at the
    /// surface's texel density; a stroke's stamp, a ribbon's strip). Required, except for text.
    #[serde(default)]
    pub image: Option<PathBuf>,
    /// Optional mask image (red × alpha, read without sRGB decoding).
    #[serde(default)]
    pub mask: Option<PathBuf>,
    /// Placement (decals; strokes use `path`).
    #[serde(default)]
    pub at: Option<AtSpec>,
    /// Width and height on the surface, model units (a stroke's stamp at full pressure); not for
    /// ribbons, whose length is their curve's and whose width is `width`. Text: one number, the
    /// em size.
    #[serde(default)]
    pub size: Option<SizeSpec>,
    /// Degrees, counter-clockwise seen from outside.
    #[serde(default)]
    pub angle: f32,
    /// Image up direction before `angle`.
    #[serde(default = "default_up")]
    pub up: [f32; 3],
    /// Placement method (default: `"expmap"` for decals, `"lscm"` for strokes).
    #[serde(default)]
    #[schemars(extend("enum" = ["planar", "expmap", "lscm", "hybrid", null]))]
    pub method: Option<String>,
    /// Blend mode name: `normal`, `multiply`, `screen`, `overlay`, `add`, `darken`, `lighten`,
    /// `color_dodge` or `color_burn` (any case; spaces or hyphens for the underscore).
    #[serde(default = "default_blend")]
    #[schemars(extend("examples" = ["normal", "multiply", "screen", "overlay", "add", "darken", "lighten", "color_dodge", "color_burn"]))]
    pub blend: String,
    /// Opacity in [0, 1].
    #[serde(default = "default_opacity")]
    pub opacity: f32,
    /// Planar projection depth limit (model units, each side of the surface).
    #[serde(default)]
    pub depth: Option<f32>,
    /// Expmap: halt propagation at vertices whose |Gaussian curvature| exceeds this (partial decals).
    #[serde(default)]
    pub curvature_stop: Option<f32>,
    /// Expmap: `"smooth"` (default; a second-order update along the paper's upwind paths) or
    /// `"fast"` (the paper's update).
    #[serde(default)]
    #[schemars(extend("enum" = ["smooth", "fast", null]))]
    pub accuracy: Option<String>,
    /// Hybrid: triangles of the exponential map whose angle distortion (s1 / s2) exceeds this are
    /// re-solved conformally (default 1.1).
    #[serde(default)]
    pub hybrid_threshold: Option<f32>,
    /// LSCM / hybrid: conjugate-gradient iteration budget of the final solve (default grows with the
    /// chart: 50 sqrt(unknowns) + 500).
    #[serde(default)]
    pub cg_max_iterations: Option<u32>,
    /// Stroke: `"paint"` (default), `"blur"`, `"smear"` or `"clone"`.
    #[serde(default)]
    #[schemars(extend("enum" = ["paint", "blur", "smear", "clone", null]))]
    pub tool: Option<String>,
    /// Stroke: surface points (like `at`), joined along the surface.
    #[serde(default)]
    pub path: Option<Vec<AtSpec>>,
    /// Stroke, ribbon: `"catmull-rom"` (default; a smooth curve through the path's points) or
    /// `"linear"` (the geodesics between them).
    #[serde(default)]
    #[schemars(extend("enum" = ["catmull-rom", "linear", null]))]
    pub interpolate: Option<String>,
    /// Stroke: pressure in [0, 1] per path point.
    #[serde(default)]
    pub pressure: Option<Vec<f32>>,
    /// Stroke: stamp distance as a fraction of the stamp width (default 0.1).
    #[serde(default)]
    pub spacing: Option<f32>,
    /// Stroke: each stamp's alpha (default 1).
    #[serde(default)]
    pub flow: Option<f32>,
    /// Stroke: how much pressure scales the size (default 1).
    #[serde(default)]
    pub pressure_size: Option<f32>,
    /// Stroke: how much pressure scales the flow (default 0).
    #[serde(default)]
    pub pressure_flow: Option<f32>,
    /// Stroke: `"path"` (default) or `"fixed"`.
    #[serde(default)]
    #[schemars(extend("enum" = ["path", "fixed", null]))]
    pub orient: Option<String>,
    /// Stroke: per-vertex charts interpolated (Maillot section 7).
    #[serde(default)]
    pub continuity: Option<bool>,
    /// Blur stroke: blur radius on the surface, model units.
    #[serde(default)]
    pub radius: Option<f32>,
    /// Smear stroke: how much colour each stamp carries, in [0, 1].
    #[serde(default)]
    pub strength: Option<f32>,
    /// Clone stroke: the source point (like `at`).
    #[serde(default)]
    pub source: Option<AtSpec>,
    /// Ribbon: the strip's width, model units.
    #[serde(default)]
    pub width: Option<f32>,
    /// Ribbon: `"stretch"` (default) or `"tile"`.
    #[serde(default)]
    #[schemars(extend("enum" = ["stretch", "tile", null]))]
    pub repeat: Option<String>,
    /// Ribbon: `"center"` (default), `"left"` or `"right"`. Text: `"start"`, `"center"`
    /// (default) or `"end"`.
    #[serde(default)]
    #[schemars(extend("enum" = ["center", "left", "right", "start", "end", null]))]
    pub align: Option<String>,
    /// Ribbon: mirror the image across the curve.
    #[serde(default)]
    pub flip: Option<bool>,
    /// Ribbon: the image moving along a route over frames (one bake per frame).
    #[serde(default)]
    pub animate: Option<super::ribbon::AnimateSpec>,
    /// Ribbon: λ of the curved parts' harmonic repair (default 0.2).
    #[serde(default)]
    pub curved_threshold: Option<f32>,
    /// Decal, stroke, ribbon: `[from, to]` image-point pairs (in [0, 1]²) of a thin-plate-spline
    /// warp: the image content at each `from` moves to its `to`.
    #[serde(default)]
    pub warp: Option<Vec<[[f32; 2]; 2]>>,
    /// A tangent-space normal map baked into the model's normal texture.
    #[serde(default)]
    pub normal: Option<PathBuf>,
    /// The normal map's green axis: `"gl"` (default, +Y up, as glTF) or `"dx"` (+Y down).
    #[serde(default)]
    #[schemars(extend("enum" = ["gl", "dx", null]))]
    pub normal_y: Option<String>,
    /// How the normal map combines with the model's: `"rnm"` (default, reoriented normal
    /// mapping), `"udn"` or `"replace"`.
    #[serde(default)]
    #[schemars(extend("enum" = ["rnm", "udn", "replace", null]))]
    pub normal_blend: Option<String>,
    /// Roughness: a number in [0, 1] or an image (its red channel).
    #[serde(default)]
    pub roughness: Option<super::channels::ValueSpec>,
    /// Metallic: a number in [0, 1] or an image.
    #[serde(default)]
    pub metallic: Option<super::channels::ValueSpec>,
    /// Ambient occlusion: a number in [0, 1] or an image.
    #[serde(default)]
    pub occlusion: Option<super::channels::ValueSpec>,
    /// Emissive: a linear RGB triple or an image.
    #[serde(default)]
    pub emissive: Option<super::channels::ValueSpec>,
    /// The normal's opacity (default: `opacity`).
    #[serde(default)]
    pub normal_opacity: Option<f32>,
    /// Roughness's opacity.
    #[serde(default)]
    pub roughness_opacity: Option<f32>,
    /// Metallic's opacity.
    #[serde(default)]
    pub metallic_opacity: Option<f32>,
    /// Occlusion's opacity.
    #[serde(default)]
    pub occlusion_opacity: Option<f32>,
    /// Emissive's opacity.
    #[serde(default)]
    pub emissive_opacity: Option<f32>,
    /// How roughness, metallic and occlusion blend: `"normal"` (default) or `"replace"`.
    #[serde(default)]
    #[schemars(extend("enum" = ["normal", "replace", null]))]
    pub data_blend: Option<String>,
    /// Text: the string (UTF-8, one line).
    #[serde(default)]
    pub text: Option<String>,
    /// Text: a TrueType or OpenType font file (default: the bundled DejaVu Sans).
    #[serde(default)]
    pub font: Option<PathBuf>,
    /// Text: sRGB RGBA in [0, 1] (default opaque black).
    #[serde(default)]
    pub color: Option<[f32; 4]>,
    /// Text: extra space after each glyph, em units (default 0).
    #[serde(default)]
    pub letter_spacing: Option<f32>,
    /// Text along a curve: the glyphs' up is the curve's `"left"` (default) or `"right"`, seen
    /// from outside.
    #[serde(default)]
    #[schemars(extend("enum" = ["left", "right", null]))]
    pub side: Option<String>,
    /// Text along a curve longer than the text: `"clip"` (default; a warning) or `"shrink"`.
    #[serde(default)]
    #[schemars(extend("enum" = ["clip", "shrink", null]))]
    pub fit: Option<String>,
}

/// A layer's `size`: `[width, height]`, or a text layer's em size.
#[derive(Debug, Clone, Copy, Deserialize, schemars::JsonSchema)]
#[serde(untagged)]
pub enum SizeSpec {
    /// Width and height, model units.
    Pair([f32; 2]),
    /// A text layer's em size, model units.
    Em(f32),
}

fn default_kind() -> String {
    "decal".into()
}
fn default_up() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}
fn default_blend() -> String {
    "normal".into()
}
fn default_opacity() -> f32 {
    1.0
}

/// Output files; `None` skips one.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct OutputSpec {
    /// The baked texture: a PNG, or a name ending in `.exr` (linear 32-bit floats); `{set}`,
    /// `{channel}`, `{uv}` and `{frame}` name a model's several textures and an animation's frames.
    #[serde(default = "default_texture_out")]
    pub texture: Option<PathBuf>,
    /// Bits per PNG sample: 8 or 16.
    #[serde(default = "default_bit_depth")]
    #[schemars(extend("enum" = [8, 16]))]
    pub bit_depth: u8,
    /// A `.glb` copy of the model with the baked texture.
    #[serde(default)]
    pub glb: Option<PathBuf>,
    /// The JSON report: placements, coverage, distortion, warnings, timings.
    #[serde(default = "default_report")]
    pub report: Option<PathBuf>,
    /// A PNG of the textured model from four sides.
    #[serde(default)]
    pub preview: Option<PathBuf>,
    /// `"fast"` (default) or `"small"`: how hard PNG outputs are compressed.
    #[serde(default)]
    #[schemars(extend("enum" = ["fast", "small", null]))]
    pub compression: Option<String>,
}

fn default_texture_out() -> Option<PathBuf> {
    Some("baked.png".into())
}
fn default_bit_depth() -> u8 {
    8
}
fn default_report() -> Option<PathBuf> {
    Some("report.json".into())
}

impl Default for OutputSpec {
    fn default() -> Self {
        Self {
            texture: default_texture_out(),
            bit_depth: 8,
            glb: None,
            report: default_report(),
            preview: None,
            compression: None,
        }
    }
}

pub use super::at::MAX_SIZE_MODEL_UNITS;

/// How a layer's local coordinates are computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// Tangent-plane projection along the normal at the placed point.
    Planar,
    /// Discrete exponential map around the placed point (Schmidt et al. 2006): follows the surface.
    Expmap,
    /// Local least-squares conformal chart (Maillot; Levy et al. 2002): keeps angles.
    Lscm,
    /// Exponential map with its most distorted triangles re-solved conformally (Schmidt et al.
    /// 2006, section 5.1).
    Hybrid,
    /// A ribbon's curve map (Sun et al. 2013, section 3); set by `"kind": "ribbon"`, not a
    /// `method` a job names.
    Ribbon,
}

impl Method {
    fn parse(s: &str) -> std::result::Result<Self, String> {
        match s {
            "planar" => Ok(Method::Planar),
            "expmap" => Ok(Method::Expmap),
            "lscm" => Ok(Method::Lscm),
            "hybrid" => Ok(Method::Hybrid),
            other => Err(format!(
                "unknown method \"{other}\"; use \"planar\", \"expmap\", \"lscm\" or \"hybrid\""
            )),
        }
    }
}

/// What a layer is; each kind is a module under `src/bake/kinds/`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum LayerKind {
    /// An image placed at one surface point.
    #[default]
    Decal,
    /// Stamps of an image along a surface path (Maillot 3D paint).
    Stroke,
    /// An image laid along a surface curve (Sun et al., Texture Brush).
    Ribbon,
}

impl LayerKind {
    fn parse(s: &str) -> std::result::Result<Self, String> {
        match s {
            "decal" => Ok(LayerKind::Decal),
            "stroke" => Ok(LayerKind::Stroke),
            "ribbon" => Ok(LayerKind::Ribbon),
            other => Err(format!(
                "\"{other}\" is not a layer kind this build knows; use \"decal\", \"stroke\" or \"ribbon\""
            )),
        }
    }
}

/// A layer after validation, paths resolved.
#[derive(Debug, Clone)]
pub struct Layer {
    /// Kind.
    pub kind: LayerKind,
    /// Decal image path.
    pub image: PathBuf,
    /// Mask image path.
    pub mask: Option<PathBuf>,
    /// Placement (a stroke: its first path point).
    pub at: AtSpec,
    /// Width, height (model units).
    pub size: [f32; 2],
    /// Degrees.
    pub angle: f32,
    /// Up hint.
    pub up: [f32; 3],
    /// Method.
    pub method: Method,
    /// Blend mode.
    pub blend: BlendMode,
    /// Opacity.
    pub opacity: f32,
    /// Planar depth limit.
    pub depth: f32,
    /// Expmap curvature stop (`f32::INFINITY` = off).
    pub curvature_stop: f32,
    /// Expmap update rule (also the start of lscm and hybrid layers).
    pub accuracy: Accuracy,
    /// Hybrid re-solve threshold on s1 / s2.
    pub hybrid_threshold: f32,
    /// LSCM / hybrid final-solve iteration budget (`None` = automatic).
    pub cg_max_iterations: Option<u32>,
    /// The stroke of a `"stroke"` layer (`None` for decals).
    pub stroke: Option<Box<super::stroke::Stroke>>,
    /// The ribbon of a `"ribbon"` layer.
    pub ribbon: Option<Box<super::ribbon::Ribbon>>,
    /// The image's thin-plate-spline warp: `[from, to]` pairs in image coordinates (empty: none;
    /// [`super::warp`]).
    pub warp: Vec<[[f32; 2]; 2]>,
    /// The PBR channels it paints beside its colour (none by default).
    pub channels: super::channels::Channels,
    /// A text layer's text (its `kind` is then a decal's, placed by `at`, or a ribbon's, along
    /// `path`; its image is the text's, [`super::text`]).
    pub text: Option<std::sync::Arc<super::text::Text>>,
    /// The pixel size its vector images (SVG files, text) are rendered at, set by the bake after
    /// placement from what its map needs on the triangles it paints; `None` before (their own
    /// size).
    pub raster: Option<[u32; 2]>,
}

impl Layer {
    /// Whether any of its images is drawn from vectors: text, or an SVG image, mask or channel
    /// image.
    pub fn has_vectors(&self) -> bool {
        use super::vector::is_svg;
        self.text.is_some()
            || is_svg(&self.image)
            || self.mask.as_deref().is_some_and(is_svg)
            || self.channels.image_paths().any(is_svg)
    }

    /// The layer's colour image: its text or its file, vector images at [`Layer::raster`].
    pub fn colour_image(&self) -> Result<super::image::LinearImage> {
        match self.colour_svg()? {
            Some(svg) => {
                let px = self.raster.unwrap_or_else(|| svg.default_px());
                Ok(svg.render(px, false))
            }
            None => super::vector::load_image(&self.image, self.raster, false),
        }
    }

    /// The layer's colour image as a vector document: its text's, or its SVG file; `None` for a
    /// bitmap.
    pub fn colour_svg(&self) -> Result<Option<super::vector::Svg>> {
        match &self.text {
            Some(t) => {
                let curve = self.ribbon.as_ref().map(|_| self.size[0]);
                let svg = super::vector::Svg::parse(t.svg(curve).as_bytes()).map_err(|e| {
                    Error::Image {
                        path: self.image.clone(),
                        action: "rendering",
                        detail: format!("the text's SVG does not parse: {e}"),
                    }
                })?;
                Ok(Some(svg))
            }
            None if super::vector::is_svg(&self.image) => {
                Ok(Some(super::vector::Svg::load(&self.image)?))
            }
            None => Ok(None),
        }
    }

    /// The width and height of the layer's image (read from its header; an SVG's or a text
    /// block's own size), or an error naming `layers[index].image` of job file `src`.
    pub fn image_dimensions(&self, src: &Path, index: usize) -> Result<(u32, u32)> {
        if let Some(t) = &self.text {
            let b = &t.block;
            let h = if self.ribbon.is_some() {
                b.strip_height()
            } else {
                b.line_height()
            };
            return Ok(((b.advance.round() as u32).max(1), (h.round() as u32).max(1)));
        }
        super::vector::dimensions(&self.image).map_err(|e| {
            Error::job(
                src,
                format!("layers[{index}].image"),
                format!("{}: {e}", self.image.display()),
            )
        })
    }
}

/// Texture base after validation.
#[derive(Debug, Clone, PartialEq)]
pub enum Base {
    /// The material's base colour.
    Material,
    /// An image file.
    Image(PathBuf),
    /// A solid linear colour.
    Color([f32; 4]),
    /// `source` (the material's texture or an image) laid out on `from_uv_set`, resampled into
    /// the set being baked.
    Transfer {
        /// The set `source` is laid out on.
        from_uv_set: u32,
        /// The texture (never itself a transfer or a colour).
        source: Box<Base>,
    },
}

/// Padding after validation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Padding {
    /// Texels.
    Texels(u32),
    /// Whole background.
    Full,
}

/// A validated job: everything checked that can be checked without the mesh and the GPU.
///
/// [`Job::load`] reads a job file; [`Job::parse`] takes its text. A mistake is an
/// [`Error::Job`] that names the file and the field:
///
/// ```
/// use decalbake::Job;
/// use std::path::Path;
///
/// let here = Path::new(".");
/// let job = Job::parse(r#"{ "mesh": "model.glb" }"#, Path::new("job.json"), here, here).unwrap();
/// assert_eq!((job.width, job.height), (2048, 2048));
///
/// let typo = r#"{ "mesh": "model.glb", "texture": { "widht": 512 } }"#;
/// let e = Job::parse(typo, Path::new("job.json"), here, here).unwrap_err();
/// assert!(e.to_string().starts_with("job.json: field `texture.widht`: unknown field"), "{e}");
/// ```
#[derive(Debug, Clone)]
pub struct Job {
    /// The job file (or a name for in-memory jobs), for messages.
    pub source: PathBuf,
    /// Mesh path.
    pub mesh: PathBuf,
    /// UV set (0 until resolved when `uv_auto`).
    pub uv_set: u32,
    /// `"uv_set": "auto"`: resolved by [`crate::Engine::load_mesh_for`] (the base-colour
    /// texture's set, or a new set by pelting on a mesh without UVs).
    pub uv_auto: bool,
    /// `"uv_set": [a, b, ..]`: every set to bake ([`Job::for_uv_set`]); empty for one set.
    pub uv_list: Vec<u32>,
    /// Width, height.
    pub width: u32,
    /// Height.
    pub height: u32,
    /// `texture.sets`: a material's name or index, and its set's width and height.
    pub set_sizes: Vec<(String, u32, u32)>,
    /// Base.
    pub base: Base,
    /// Padding.
    pub padding: Padding,
    /// Supersampling factor per axis (sqrt of samples).
    pub ss: u32,
    /// `texture.sampling`: four samples drawn once a texel and triangle (true) or once a sample
    /// (false, the default).
    pub adaptive: bool,
    /// `texture.tile`: bake by tiles of this side (a multiple of 64).
    pub tile: Option<u32>,
    /// Layers.
    pub layers: Vec<Layer>,
    /// Output texture path.
    pub out_texture: Option<PathBuf>,
    /// The name the PBR channels' textures are named from (`output.texture` with its `{channel}`
    /// kept) where `out_texture` holds the colour's resolved name ([`Job::for_single_set`]);
    /// `None`: `out_texture` names them.
    pub channel_texture: Option<PathBuf>,
    /// Bits per PNG sample: 8 or 16.
    pub bit_depth: u8,
    /// Output glb.
    pub out_glb: Option<PathBuf>,
    /// Output report.
    pub out_report: Option<PathBuf>,
    /// Output preview.
    pub out_preview: Option<PathBuf>,
    /// How hard the texture PNGs (and the model's embedded PNGs) are compressed.
    pub compression: crate::io::image::PngCompression,
    /// `max_memory` in bytes (`crate::bake::memory`); `None`: the memory available.
    pub max_memory: Option<u64>,
}

impl Job {
    /// Whether the bake draws its layers at four samples a pixel, once a texel and triangle
    /// (`texture.sampling` adaptive with four samples a texel), where the device holds the
    /// targets (`crate::Engine::adaptive_sampling`); the CPU twin follows this.
    pub fn adaptive_sampling(&self) -> bool {
        self.adaptive && self.ss == 2
    }

    /// The PBR channel groups the layers paint, as bits
    /// ([`crate::io::channels::ChannelKind::slot`]).
    pub fn channel_groups(&self) -> u32 {
        crate::io::channels::ChannelKind::ALL
            .into_iter()
            .filter(|&k| self.layers.iter().any(|l| l.channels.paints(k)))
            .fold(0, |b, k| b | 1 << k.slot())
    }

    /// The channel groups a fused pass of this job draws attachments for, as
    /// [`Job::channel_groups`]'s bits: those a layer paints other than as numbers at its colour's
    /// opacity ([`crate::io::channels::Channels::derived`]; the compose derives those from the
    /// colour, as `bake::compose` decides per raster entry). For preparing pipelines.
    pub fn drawn_channel_groups(&self) -> u32 {
        let mut bits = 0;
        for l in &self.layers {
            for k in crate::io::channels::ChannelKind::ALL {
                if l.channels.paints(k) && !l.channels.derived(k, l.opacity) {
                    bits |= 1 << k.slot();
                }
            }
        }
        bits
    }

    /// Whether the texture is written as OpenEXR (`output.texture` ends in `.exr`): linear RGBA,
    /// 32-bit float, padded like the PNG; `output.bit_depth` then applies to the `.glb`'s PNG only.
    pub fn exr(&self) -> bool {
        self.out_texture
            .as_ref()
            .and_then(|p| p.extension())
            .is_some_and(|e| e.eq_ignore_ascii_case("exr"))
    }

    /// The job for set `set` of a several-set job (`"uv_set": [..]`): `{uv}` in every output path
    /// replaced by the set's number; a report or `.glb` path without `{uv}` gets `-uvN` before its
    /// extension, so the sets' files do not overwrite each other; no preview (the sets share one,
    /// which the caller renders).
    pub fn for_uv_set(&self, set: u32) -> Job {
        let name = |p: &Option<PathBuf>| p.as_ref().map(|p| uv_set_name(p, set));
        Job {
            uv_set: set,
            uv_list: Vec::new(),
            out_texture: name(&self.out_texture),
            out_glb: name(&self.out_glb),
            out_report: name(&self.out_report),
            // The sets share one preview (`decalbake bake` blends them by `_PELT_BLEND`).
            out_preview: None,
            ..self.clone()
        }
    }

    /// The texture file of texture set `set` (`None`: the whole mesh's one texture) and
    /// `channel` (`base_color`, or a [`crate::bake::channels::ChannelKind`]'s name): `{set}` and
    /// `{channel}` in `output.texture` replaced by them; a name without `{set}` gets `_<set>`
    /// before its extension (for a set), and one without `{channel}` gets `_<channel>` (for a
    /// channel other than the colour): `baked.png` gives `baked.png` and `baked_normal.png`.
    pub fn texture_path(&self, set: Option<&str>, channel: &str) -> Option<PathBuf> {
        let p = self
            .channel_texture
            .as_ref()
            .or(self.out_texture.as_ref())?;
        let text = p.to_string_lossy();
        if text.contains("{set}") || text.contains("{channel}") {
            let full = text
                .replace("{set}", set.unwrap_or("model"))
                .replace("{channel}", channel);
            return Some(PathBuf::from(full));
        }
        let ext = p.extension().map(|e| format!(".{}", e.to_string_lossy()));
        let stem = p
            .file_stem()
            .unwrap_or_default()
            .to_string_lossy()
            .into_owned();
        let mut stem_out = stem;
        if let Some(s) = set {
            stem_out = format!("{stem_out}_{s}");
        }
        if channel != "base_color" {
            stem_out = format!("{stem_out}_{channel}");
        }
        Some(p.with_file_name(format!("{stem_out}{}", ext.unwrap_or_default())))
    }

    /// This job's bake of texture set `set` (its name): its texture file
    /// ([`Self::texture_path`] of the colour); no `.glb`, report or preview (one each for all the
    /// sets, written by the caller).
    pub fn for_texture_set(&self, set: &str) -> Job {
        let texture = self.texture_path(Some(set), "base_color");
        Job {
            out_texture: texture,
            out_glb: None,
            out_report: None,
            out_preview: None,
            ..self.clone()
        }
    }

    /// The size of the texture set of `materials` (index and name of each): the first
    /// `texture.sets` entry naming one of them by name or index, else `texture.width` × `height`.
    pub fn set_size(&self, materials: &[(usize, Option<&str>)]) -> (u32, u32) {
        for &(m, name) in materials {
            let hit = self
                .set_sizes
                .iter()
                .find(|(k, _, _)| Some(k.as_str()) == name || *k == m.to_string());
            if let Some(&(_, w, h)) = hit {
                return (w, h);
            }
        }
        (self.width, self.height)
    }

    /// The job for a mesh of one texture set, `set`: `{set}` and `{channel}` in the texture's
    /// name replaced (`base_color`), the name with `{set}` alone replaced kept for the channels'
    /// textures (`channel_texture`); the same job where the name has neither.
    pub fn for_single_set(&self, set: &str) -> Job {
        let mut job = self.clone();
        if let Some(p) = &self.out_texture {
            let text = p.to_string_lossy();
            if text.contains("{set}") || text.contains("{channel}") {
                let named = text.replace("{set}", set);
                job.out_texture = Some(PathBuf::from(named.replace("{channel}", "base_color")));
                job.channel_texture = Some(PathBuf::from(named));
            }
        }
        job
    }

    /// Layer `index` (a command's `--layer`), or an error naming how many there are.
    pub fn layer_at(&self, index: usize) -> Result<&Layer> {
        self.layers.get(index).ok_or_else(|| {
            Error::job(
                &self.source,
                "layers",
                format!(
                    "--layer {index} does not exist: the job has {} layer(s)",
                    self.layers.len()
                ),
            )
        })
    }

    /// Frames of an animated job (its ribbons' `animate.frames`), `None` without animation.
    pub fn frames(&self) -> Option<u32> {
        self.layers
            .iter()
            .find_map(|l| l.ribbon.as_ref()?.animate.map(|a| a.frames))
    }

    /// Frame `f` of an animated job: each animated ribbon at frame `f`, `{frame}` (or
    /// `{frame:0N}`, zero-padded to N digits) in the output names replaced by `f`; a `.glb`,
    /// report or preview named without a placeholder gets `-frame{f:04}` before its extension.
    pub fn for_frame(&self, f: u32) -> Job {
        let name = |p: &Option<PathBuf>| {
            p.as_ref().map(|p| {
                let text = p.to_string_lossy();
                match super::ribbon::frame_name(&text, f) {
                    Some(named) => PathBuf::from(named),
                    None => {
                        let stem = p.file_stem().unwrap_or_default().to_string_lossy();
                        let ext = p.extension().map(|e| format!(".{}", e.to_string_lossy()));
                        p.with_file_name(format!("{stem}-frame{f:04}{}", ext.unwrap_or_default()))
                    }
                }
            })
        };
        let mut job = Job {
            out_texture: name(&self.out_texture),
            out_glb: name(&self.out_glb),
            out_report: name(&self.out_report),
            out_preview: name(&self.out_preview),
            ..self.clone()
        };
        for l in &mut job.layers {
            if let Some(a) = l.ribbon.as_mut().and_then(|r| r.animate.as_mut()) {
                a.frame = f;
            }
        }
        job
    }

    /// Reads and validates a job file. Outputs go to `out_dir` when given, else next to the job file.
    pub fn load(path: &Path, out_dir: Option<&Path>) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|source| Error::Io {
            path: path.to_path_buf(),
            action: "reading the job file",
            source,
        })?;
        let dir = path.parent().unwrap_or(Path::new("")).to_path_buf();
        Self::parse(&text, path, &dir, out_dir.unwrap_or(&dir))
    }

    /// Parses and validates job JSON. Inputs are resolved against `input_dir`, outputs against
    /// `output_dir`.
    pub fn parse(text: &str, source: &Path, input_dir: &Path, output_dir: &Path) -> Result<Self> {
        let de = &mut serde_json::Deserializer::from_str(text);
        let file: JobFile = serde_path_to_error::deserialize(de).map_err(|e| {
            let field = e.path().to_string();
            let inner = e.into_inner();
            Error::job(
                source,
                if field == "." {
                    "(top level)".to_string()
                } else {
                    field
                },
                format!("{inner}; docs/job-file.md lists every field"),
            )
        })?;
        Self::validate(file, source, input_dir, output_dir)
    }

    fn validate(f: JobFile, src: &Path, input_dir: &Path, output_dir: &Path) -> Result<Self> {
        let err = |field: &str, detail: String| Error::job(src, field, detail);
        if let UvSetField::Named(name) = &f.uv_set {
            if name != "auto" {
                return Err(err(
                    "uv_set",
                    format!("\"{name}\" is not a UV set: give a number (TEXCOORD_n) or \"auto\""),
                ));
            }
        }
        if let UvSetField::List(list) = &f.uv_set {
            let mut sorted = list.clone();
            sorted.sort_unstable();
            sorted.dedup();
            if list.is_empty() || sorted.len() != list.len() || list.len() > 8 {
                return Err(err(
                    "uv_set",
                    format!("{list:?}: a list of UV sets needs 1 to 8 different set numbers"),
                ));
            }
            if !f
                .output
                .texture
                .as_ref()
                .is_some_and(|t| t.to_string_lossy().contains("{uv}"))
            {
                return Err(err(
                    "output.texture",
                    "with several UV sets (\"uv_set\": [..]) the texture's name needs {uv} (for example \"baked_uv{uv}.png\"), replaced by each set's number".into(),
                ));
            }
        }
        let t = &f.texture;
        for (name, v) in [("texture.width", t.width), ("texture.height", t.height)] {
            if v == 0 {
                return Err(err(name, "must be at least 1 texel".into()));
            }
        }
        check_set_sizes(t, src)?;
        let ss = match t.samples {
            1 => 1,
            4 => 2,
            9 => 3,
            16 => 4,
            other => {
                return Err(err(
                    "texture.samples",
                    format!("{other} is not 1, 4, 9 or 16 (square supersampling patterns)"),
                ))
            }
        };
        let base = match &t.base {
            BaseSpec::Name(n) if n == "material" => Base::Material,
            BaseSpec::Name(n) => Base::Image(input_dir.join(n)),
            BaseSpec::Transfer { transfer: tr } => Base::Transfer {
                from_uv_set: tr.from_uv_set,
                source: Box::new(if tr.image == "material" {
                    Base::Material
                } else {
                    Base::Image(input_dir.join(&tr.image))
                }),
            },
            BaseSpec::Color(c) => {
                if c.iter().any(|v| !v.is_finite() || *v < 0.0 || *v > 1.0) {
                    return Err(err(
                        "texture.base",
                        format!("colour {c:?} must have 4 components in [0, 1] (linear RGBA)"),
                    ));
                }
                Base::Color(*c)
            }
        };
        let padding = match &t.padding {
            PaddingSpec::Texels(n) => Padding::Texels(*n),
            PaddingSpec::Word(w) if w == "full" => Padding::Full,
            PaddingSpec::Word(w) => {
                return Err(err(
                    "texture.padding",
                    format!("\"{w}\" is neither a texel count nor \"full\""),
                ))
            }
        };
        if let Some(t) = t.tile.filter(|t| *t == 0 || t % 64 != 0) {
            return Err(err(
                "texture.tile",
                format!("{t} is not a positive multiple of 64 texels (the bake's cell size)"),
            ));
        }
        let max_memory = max_memory(f.max_memory.as_ref(), src)?;
        let compression = output_encoding(&f.output, src)?;
        let layers = f
            .layers
            .iter()
            .enumerate()
            .map(|(i, l)| validate_layer(l, i, src, input_dir))
            .collect::<Result<Vec<_>>>()?;
        check_frames(&layers, f.output.texture.as_deref(), src)?;
        if matches!(f.uv_set, UvSetField::List(_))
            && layers
                .iter()
                .any(|l| l.ribbon.as_ref().is_some_and(|r| r.animate.is_some()))
        {
            return Err(err(
                "uv_set",
                "an animated job bakes one UV set (a list of sets with `animate` would need frames × sets textures); give one set".into(),
            ));
        }
        let out = |p: &Option<PathBuf>| p.as_ref().map(|p| output_dir.join(p));
        Ok(Job {
            source: src.to_path_buf(),
            mesh: input_dir.join(&f.mesh),
            uv_set: match &f.uv_set {
                UvSetField::Index(i) => *i,
                UvSetField::Named(_) => 0,
                UvSetField::List(l) => l[0],
            },
            uv_auto: matches!(f.uv_set, UvSetField::Named(_)),
            uv_list: match &f.uv_set {
                UvSetField::List(l) => l.clone(),
                _ => Vec::new(),
            },
            width: t.width,
            height: t.height,
            set_sizes: t
                .sets
                .iter()
                .map(|(k, v)| {
                    let (w, h) = (v.width.unwrap_or(t.width), v.height.unwrap_or(t.height));
                    (k.clone(), w, h)
                })
                .collect(),
            base,
            padding,
            ss,
            adaptive: sampling(t, src)?,
            tile: t.tile,
            layers,
            out_texture: out(&f.output.texture),
            channel_texture: None,
            bit_depth: f.output.bit_depth,
            out_glb: out(&f.output.glb),
            out_report: out(&f.output.report),
            out_preview: out(&f.output.preview),
            compression,
            max_memory,
        })
    }
}

/// A layer's blend mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
#[repr(u32)]
pub enum BlendMode {
    /// Source-over.
    Normal = 0,
    /// Cb × Cs.
    Multiply = 1,
    /// Cb + Cs − Cb·Cs.
    Screen = 2,
    /// Hard light with the roles swapped.
    Overlay = 3,
    /// min(1, Cb + Cs).
    Add = 4,
    /// min(Cb, Cs).
    Darken = 5,
    /// max(Cb, Cs).
    Lighten = 6,
    /// Cb / (1 − Cs).
    ColorDodge = 7,
    /// 1 − (1 − Cb) / Cs.
    ColorBurn = 8,
}

impl BlendMode {
    /// Every mode, in id order.
    pub const ALL: [BlendMode; 9] = [
        BlendMode::Normal,
        BlendMode::Multiply,
        BlendMode::Screen,
        BlendMode::Overlay,
        BlendMode::Add,
        BlendMode::Darken,
        BlendMode::Lighten,
        BlendMode::ColorDodge,
        BlendMode::ColorBurn,
    ];

    /// The job-file name.
    pub fn name(self) -> &'static str {
        match self {
            BlendMode::Normal => "normal",
            BlendMode::Multiply => "multiply",
            BlendMode::Screen => "screen",
            BlendMode::Overlay => "overlay",
            BlendMode::Add => "add",
            BlendMode::Darken => "darken",
            BlendMode::Lighten => "lighten",
            BlendMode::ColorDodge => "color_dodge",
            BlendMode::ColorBurn => "color_burn",
        }
    }

    /// Parses a job-file name (`"color dodge"`, `"color-dodge"` and `"color_dodge"` all work).
    pub fn parse(s: &str) -> std::result::Result<Self, String> {
        let norm = s.trim().to_ascii_lowercase().replace([' ', '-'], "_");
        Self::ALL
            .into_iter()
            .find(|m| m.name() == norm)
            .ok_or_else(|| {
                format!(
                    "unknown blend mode \"{s}\"; use one of {}",
                    Self::ALL.map(|m| m.name()).join(", ")
                )
            })
    }
}

/// How a vertex's normal coordinates follow from its upwind neighbour's.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Accuracy {
    /// The paper's update (Schmidt et al. eq. 2-3): the edge, laid into the neighbour's tangent
    /// plane, turned into the seed's plane by the minimal rotation between the normals.
    Fast,
    /// The differential of the log map, integrated edge by edge along the same upwind paths. At a
    /// point at geodesic distance r the log map keeps the radial component of a tangent vector
    /// and stretches the angular one by r / G(r), after parallel transport to the seed along the
    /// radial geodesic (geodesic polar coordinates have metric dr² + G² dθ²; G is the Jacobi field,
    /// G'' = -K G, G(0) = 0, G'(0) = 1). Three discrete pieces make that exact in the limit:
    /// - **Stretch**: G is integrated along the upwind path with the Gaussian curvature averaged over
    ///   each step (exact for constant curvature); the edge's angular component is scaled by r / G.
    /// - **Frame**: each vertex carries the angle α of the seed frame in its intrinsic tangent
    ///   coordinates ([`crate::mesh::surface::edge_angles`]: corner angles only, no normals). Crossing an edge adds
    ///   tx + π - ty (parallel transport, exact on any flat mesh, sharp creases included) and
    ///   subtracts the holonomy of the wedge (seed, y, x), ∫K dA = dθ (1 - G') (Gauss-Bonnet; dθ the
    ///   step's turn around the seed in the chart), which turns transport along the zigzag path
    ///   into transport along the radial geodesic.
    /// - **Trapezoidal rule**: the edge is mapped with the differential at both ends (x's end from
    ///   a predictor step) and the two images are averaged.
    ///
    /// Second order: on the unit sphere (within radius 1) the max 2D error is 8.3e-3, 2.1e-3,
    /// 6.8e-4, 2.3e-4 at 642, 2.6k, 10k, 41k vertices (potpourri3d's AffineLocal: 1.0e-2 to 1.7e-3;
    /// 2.8e-3 at 10k); on a cone (developable) it falls by about 4× per halving of the edge length;
    /// a crumpled developable sheet is unfolded to 1e-5 of the disc radius.
    /// The fixed point is still set by the upwind tree, so the GPU relaxation reaches the twin's
    /// values (up to f32 rounding).
    #[default]
    Smooth,
}

/// A layer's stroke or ribbon (at most one of the two), as its kind validates them.
type KindFields = (
    Option<Box<super::stroke::Stroke>>,
    Option<Box<super::ribbon::Ribbon>>,
);

impl LayerSpec {
    /// This layer's stroke or ribbon, validated by its kind (`i`, `src`: for messages;
    /// `stamp`: the layer's width).
    fn kind_fields(
        &self,
        kind: LayerKind,
        (i, src): (usize, &Path),
        stamp: f32,
        text_strip: Option<f32>,
    ) -> Result<KindFields> {
        let fields = super::stroke::Fields {
            tool: &self.tool,
            path: &self.path,
            interpolate: &self.interpolate,
            pressure: &self.pressure,
            spacing: self.spacing,
            flow: self.flow,
            pressure_size: self.pressure_size,
            pressure_flow: self.pressure_flow,
            orient: &self.orient,
            continuity: self.continuity,
            radius: self.radius,
            strength: self.strength,
            source: &self.source,
        };
        let ribbon_fields = super::ribbon::Fields {
            path: &self.path,
            interpolate: &self.interpolate,
            width: text_strip.or(self.width),
            repeat: &self.repeat,
            align: if self.kind == "text" {
                &None
            } else {
                &self.align
            },
            flip: self.flip,
            animate: &self.animate,
            curved_threshold: self.curved_threshold,
        };
        kind_fields(
            kind,
            (&fields, &ribbon_fields),
            (i, src),
            (stamp, self.mask.is_some()),
        )
    }

    /// The job file's PBR channel fields of this layer (`super::channels`).
    fn channel_fields(&self) -> super::channels::Fields<'_> {
        super::channels::Fields {
            normal: &self.normal,
            normal_y: &self.normal_y,
            normal_blend: &self.normal_blend,
            values: [
                &self.roughness,
                &self.metallic,
                &self.occlusion,
                &self.emissive,
            ],
            opacities: [
                self.normal_opacity,
                self.roughness_opacity,
                self.metallic_opacity,
                self.occlusion_opacity,
                self.emissive_opacity,
            ],
            data_blend: &self.data_blend,
        }
    }
}

/// Validates layer `i` of a job file (`src`, for messages), resolving its paths against
/// `input_dir`.
fn validate_layer(l: &LayerSpec, i: usize, src: &Path, input_dir: &Path) -> Result<Layer> {
    let err = |field: &str, detail: String| Error::job(src, field, detail);
    let field = |name: &str| format!("layers[{i}].{name}");
    let text = text_of(l, i, src, input_dir)?;
    let kind = match &text {
        Some(_) if l.path.is_some() => LayerKind::Ribbon,
        Some(_) => LayerKind::Decal,
        None => LayerKind::parse(&l.kind).map_err(|d| err(&field("kind"), d))?,
    };
    let size = match &text {
        Some(t) => t.block_size(),
        None => layer_size(kind, l.size, i, src)?,
    };
    let finite3 = |v: &[f32; 3]| v.iter().all(|x| x.is_finite() && x.abs() <= 1e30);
    let strip = text
        .as_ref()
        .filter(|_| l.path.is_some())
        .map(|t| t.strip_width());
    let (stroke, ribbon) = l.kind_fields(kind, (i, src), size[0], strip)?;
    let image = match (&text, &l.image) {
        (Some(_), Some(_)) => {
            return Err(err(
                &field("image"),
                "a text layer draws its glyphs in `color`; remove `image`".into(),
            ))
        }
        (Some(_), None) => PathBuf::from(format!("<text of layers[{i}]>")),
        (None, Some(p)) => input_dir.join(p),
        (None, None) => {
            return Err(err(
                &field("image"),
                "missing: the layer's image (PNG, JPEG or SVG)".into(),
            ))
        }
    };
    let path = stroke
        .as_ref()
        .map(|s| &s.path)
        .or(ribbon.as_ref().map(|r| &r.path));
    let at = match (&l.at, path) {
        (Some(_), Some(_)) => {
            return Err(err(
                &field("at"),
                "a stroke or ribbon is placed by its `path`; remove `at`".into(),
            ))
        }
        (None, Some(p)) => p[0].clone(),
        (Some(at), None) => at.clone(),
        (None, None) => {
            return Err(err(
                &field("at"),
                "missing: a decal needs `at` (a point [x, y, z] or {\"ray\": {\"origin\": …, \"dir\": …}})".into(),
            ))
        }
    };
    check_at(&at, &field("at"), src)?;
    if !finite3(&l.up) || l.up.iter().map(|x| x * x).sum::<f32>() <= 1e-20 {
        return Err(err(
            &field("up"),
            format!("{:?} must be a non-zero finite direction", l.up),
        ));
    }
    if !l.angle.is_finite() {
        return Err(err(&field("angle"), "must be finite (degrees)".into()));
    }
    if !l.opacity.is_finite() || !(0.0..=1.0).contains(&l.opacity) {
        return Err(err(
            &field("opacity"),
            format!("{} must be in [0, 1]", l.opacity),
        ));
    }
    let method = layer_method(l.method.as_deref(), kind, &field("method"), src)?;
    let blend = BlendMode::parse(&l.blend).map_err(|d| err(&field("blend"), d))?;
    let curvature_stop = match l.curvature_stop {
        Some(k) if !k.is_finite() || k < 0.0 => {
            return Err(err(
                &field("curvature_stop"),
                format!("{k} must be a non-negative curvature (1 / model units²)"),
            ))
        }
        Some(k) => k,
        None => f32::INFINITY,
    };
    let depth = match l.depth {
        Some(d) if !d.is_finite() || d <= 0.0 => {
            return Err(err(
                &field("depth"),
                format!("{d} must be a positive distance"),
            ))
        }
        Some(d) => d,
        None => 0.5 * size[0].max(size[1]),
    };
    let hybrid_threshold = match l.hybrid_threshold {
        Some(k) if !k.is_finite() || k < 1.0 => {
            return Err(err(
                &field("hybrid_threshold"),
                format!("{k} must be at least 1 (a ratio of singular values, s1 / s2)"),
            ))
        }
        Some(k) => k,
        None => 1.1,
    };
    let accuracy = match l.accuracy.as_deref() {
        None | Some("smooth") => Accuracy::Smooth,
        Some("fast") => Accuracy::Fast,
        Some(other) => {
            return Err(err(
                &field("accuracy"),
                format!("unknown accuracy \"{other}\"; use \"smooth\" or \"fast\""),
            ))
        }
    };
    if l.cg_max_iterations == Some(0) {
        return Err(err(
            &field("cg_max_iterations"),
            "must be at least 1 (leave it out for the automatic budget)".into(),
        ));
    }
    let layer = Layer {
        kind,
        image,
        mask: l.mask.as_ref().map(|m| input_dir.join(m)),
        at,
        size,
        angle: l.angle,
        up: l.up,
        method,
        blend,
        opacity: l.opacity,
        depth,
        curvature_stop,
        accuracy,
        hybrid_threshold,
        cg_max_iterations: l.cg_max_iterations,
        stroke,
        ribbon,
        warp: super::warp::validate(&l.warp, i, src)?,
        channels: super::channels::validate(&l.channel_fields(), i, src, input_dir, l.opacity)?,
        text: text.map(std::sync::Arc::new),
        raster: None,
    };
    check_svgs(&layer, i, src)?;
    Ok(layer)
}

/// Every SVG file of layer `i` (image, mask, channel images) parses: a malformed one is refused
/// when the job loads, before any device work, naming the job file, the field and the SVG. A file
/// that cannot be read is left to the bake, which names it.
fn check_svgs(layer: &Layer, i: usize, src: &Path) -> Result<()> {
    use super::vector::{is_svg, Svg};
    let paths = [("image", layer.image.as_path())]
        .into_iter()
        .chain(layer.mask.as_deref().map(|p| ("mask", p)))
        .chain(layer.channels.image_paths().map(|p| ("channels", p)));
    for (name, p) in paths.filter(|(_, p)| is_svg(p) && p.is_file()) {
        if let Err(e) = Svg::load(p) {
            let field = match name {
                "channels" => format!("layers[{i}] (a channel image)"),
                n => format!("layers[{i}].{n}"),
            };
            return Err(Error::job(src, field, e.to_string()));
        }
    }
    Ok(())
}

/// Layer `i`'s text, shaped, when its kind is `"text"`; a text field on another kind is an error
/// naming it.
fn text_of(
    l: &LayerSpec,
    i: usize,
    src: &Path,
    input_dir: &Path,
) -> Result<Option<super::text::Text>> {
    let fields = super::text::Fields {
        text: &l.text,
        font: &l.font,
        size: match l.size {
            Some(SizeSpec::Em(s)) => Some(s),
            _ => None,
        },
        color: l.color,
        align: &l.align,
        letter_spacing: l.letter_spacing,
        side: &l.side,
        fit: &l.fit,
    };
    if l.kind != "text" {
        return match fields.given() {
            Some(name) => Err(Error::job(
                src,
                format!("layers[{i}].{name}"),
                "applies to text layers only; set \"kind\": \"text\" or remove it",
            )),
            None => Ok(None),
        };
    }
    if let Some(SizeSpec::Pair(_)) = l.size {
        return Err(Error::job(
            src,
            format!("layers[{i}].size"),
            "a text layer's size is one number, its em size in model units",
        ));
    }
    if l.path.is_some() {
        if let Some(name) = [
            ("width", l.width.is_some()),
            ("repeat", l.repeat.is_some()),
            ("flip", l.flip.is_some()),
            ("animate", l.animate.is_some()),
            ("method", l.method.is_some()),
        ]
        .into_iter()
        .find(|x| x.1)
        .map(|x| x.0)
        {
            return Err(Error::job(
                src,
                format!("layers[{i}].{name}"),
                "text along a curve takes its strip from the font (the baseline on the curve); remove it",
            ));
        }
    }
    let along = l.path.is_some();
    super::text::validate(&fields, i, src, input_dir, along).map(Some)
}

/// A layer's method (`field` names it in messages): a ribbon is mapped by its curve and takes
/// none; a stroke's stamps default to LSCM, a decal to the exponential map.
fn layer_method(given: Option<&str>, kind: LayerKind, field: &str, src: &Path) -> Result<Method> {
    Ok(match (given, kind) {
        (Some(_), LayerKind::Ribbon) => {
            return Err(Error::job(
                src,
                field,
                "a ribbon is mapped by its curve (the extended exponential map); remove `method`",
            ))
        }
        (None, LayerKind::Ribbon) => Method::Ribbon,
        (Some(m), _) => Method::parse(m).map_err(|d| Error::job(src, field, d))?,
        (None, LayerKind::Stroke) => Method::Lscm,
        (None, LayerKind::Decal) => Method::Expmap,
    })
}

/// Layer `i`'s size: a decal's or stroke's, checked; a ribbon has none (its length is its curve's,
/// its width `width`: a placeholder until it is placed).
fn layer_size(kind: LayerKind, given: Option<SizeSpec>, i: usize, src: &Path) -> Result<[f32; 2]> {
    let err = |detail: String| Error::job(src, format!("layers[{i}].size"), detail);
    let given = match given {
        Some(SizeSpec::Em(_)) if kind != LayerKind::Ribbon => return Err(err(
            "one number is a text layer's em size; a decal's or stamp's size is [width, height]"
                .into(),
        )),
        Some(SizeSpec::Em(_)) => Some([1.0, 1.0]),
        Some(SizeSpec::Pair(p)) => Some(p),
        None => None,
    };
    let size = match (kind, given) {
        (LayerKind::Ribbon, Some(_)) => {
            return Err(err(
                "a ribbon's length is its curve's and its width is `width`; remove `size`".into(),
            ))
        }
        (LayerKind::Ribbon, None) => return Ok([1.0, 1.0]),
        (_, Some(size)) => size,
        (_, None) => {
            return Err(err(
                "missing: the decal's (or stamp's) [width, height] on the surface, in model units"
                    .into(),
            ))
        }
    };
    for (k, s) in size.iter().enumerate() {
        if !s.is_finite() || *s <= 0.0 || *s > MAX_SIZE_MODEL_UNITS {
            return Err(err(format!("size[{k}] = {s} must be a positive decal width/height in model units (at most {MAX_SIZE_MODEL_UNITS})")));
        }
    }
    Ok(size)
}

/// A stroke or ribbon layer's own fields, validated; a field of one kind on another is an error
/// naming it. `stamp`: the stamp width and whether the layer has a mask (strokes).
#[allow(clippy::type_complexity)]
fn kind_fields(
    kind: LayerKind,
    (stroke, ribbon): (&super::stroke::Fields<'_>, &super::ribbon::Fields<'_>),
    (i, src): (usize, &Path),
    stamp: (f32, bool),
) -> Result<(
    Option<Box<super::stroke::Stroke>>,
    Option<Box<super::ribbon::Ribbon>>,
)> {
    let misplaced = |name: &str, what: &str| {
        Error::job(
            src,
            format!("layers[{i}].{name}"),
            format!("applies to {what} only; set \"kind\" or remove it"),
        )
    };
    if kind != LayerKind::Ribbon {
        if let Some(name) = ribbon.given() {
            return Err(misplaced(name, "ribbons"));
        }
    }
    match kind {
        LayerKind::Stroke => Ok((
            Some(Box::new(super::stroke::validate(stroke, i, src, stamp)?)),
            None,
        )),
        LayerKind::Ribbon => {
            let others = super::stroke::Fields {
                path: &None,
                interpolate: &None,
                ..*stroke
            };
            if let Some(name) = others.given() {
                return Err(misplaced(name, "strokes"));
            }
            Ok((
                None,
                Some(Box::new(super::ribbon::validate(ribbon, i, src)?)),
            ))
        }
        LayerKind::Decal => match stroke.given() {
            Some(name @ ("path" | "interpolate")) => Err(misplaced(name, "strokes and ribbons")),
            Some(name) => Err(misplaced(name, "strokes")),
            None => Ok((None, None)),
        },
    }
}

/// An animated job's frames agree (every animated ribbon has the same `frames`) and its texture is
/// named per frame (`{frame}` or `{frame:0N}` in `output.texture`); `src` names the job file.
fn check_frames(layers: &[Layer], texture: Option<&Path>, src: &Path) -> Result<()> {
    let mut frames = None;
    for (i, l) in layers.iter().enumerate() {
        let Some(a) = l.ribbon.as_ref().and_then(|r| r.animate) else {
            continue;
        };
        match frames {
            Some((n, first)) if n != a.frames => {
                return Err(Error::job(
                    src,
                    format!("layers[{i}].animate.frames"),
                    format!("{} differs from layers[{first}]'s {n}; a job's animated layers share one frame count", a.frames),
                ))
            }
            Some(_) => {}
            None => frames = Some((a.frames, i)),
        }
    }
    let named =
        texture.is_some_and(|t| super::ribbon::frame_name(&t.to_string_lossy(), 0).is_some());
    if frames.is_some() && !named {
        return Err(Error::job(
            src,
            "output.texture",
            "an animated job writes one texture per frame: its name needs {frame} or {frame:04} (for example \"baked_{frame:04}.png\")".to_string(),
        ));
    }
    Ok(())
}

/// `p` named for UV set `set` of a job's list: `{uv}` replaced by the set, or `-uv<set>` added
/// before the extension.
pub fn uv_set_name(p: &std::path::Path, set: u32) -> PathBuf {
    let text = p.to_string_lossy();
    if text.contains("{uv}") {
        return PathBuf::from(text.replace("{uv}", &set.to_string()));
    }
    let stem = p.file_stem().unwrap_or_default().to_string_lossy();
    let ext = p.extension().map(|e| format!(".{}", e.to_string_lossy()));
    p.with_file_name(format!("{stem}-uv{set}{}", ext.unwrap_or_default()))
}

#[cfg(test)]
mod size_tests {
    use super::parse_size;

    #[test]
    fn sizes_parse_with_and_without_units() {
        assert_eq!(parse_size("1024"), Some(1024));
        assert_eq!(parse_size("512M"), Some(512 << 20));
        assert_eq!(parse_size("1.5GiB"), Some(3 << 29));
        assert_eq!(parse_size("2 GB"), Some(2 << 30));
        assert_eq!(parse_size("4k"), Some(4096));
        for bad in ["", "-1", "0", "1X", "GiB", "nan"] {
            assert_eq!(parse_size(bad), None, "{bad}");
        }
    }
}
