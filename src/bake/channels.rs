// SPDX-License-Identifier: MIT OR Apache-2.0
//! PBR channels beside the colour: each channel group a layer paints (`Orm`: occlusion,
//! roughness and metallic as R, G, B; `Normal`; `Emissive`) is drawn into its own canvas by the
//! raster and compose stage, over the maps and triangle selections the colour computed: beside
//! the colour in the same pass where `Engine::fuses_channels` says (the channel draws,
//! [`ChannelDraw`]), else in a pass of its own ([`Pass`]; a chunk's maps are shared by every
//! pass; only raster and compose repeat). Each layer's channel image is made here on the CPU: the
//! channel's values with the colour image's alpha (so every channel is masked by the image's
//! alpha, and by the layer's `mask` as the colour is), at the larger of the two images' sizes; a
//! group of numbers only has none (it is drawn as the numbers times the colour sample's alpha). A canvas starts from the material's texture for that channel times its
//! factor, or from the factor alone (normals: flat, (0.5, 0.5, 1)).
//!
//! Tool strokes (blur, smear, clone) work on every channel as on the colour: their pass draws
//! use the colour's image and blend. A layer without the channel is not drawn in its pass.

use super::engine::{Engine, GpuImage, LoadedMesh};
use super::images::upload_image;
use super::params::{FLAG_CONSTANT, FLAG_NORMAL_DX};
use crate::error::{Error, Result};
use crate::io::channels::{Channel, DataBlend, NormalBlend, Value};
use crate::io::image::LinearImage;
use crate::io::job::Job;
use crate::io::vector::load_image;
use crate::mesh::material::{as_stored, MaterialChannels};
use std::sync::Arc;

pub use crate::io::channels::ChannelKind;

/// The channel passes `job` needs, in order.
pub fn passes(job: &Job) -> Vec<ChannelKind> {
    ChannelKind::ALL
        .into_iter()
        .filter(|&k| job.layers.iter().any(|l| l.channels.paints(k)))
        .collect()
}

/// How one job layer is drawn in a pass.
#[derive(Clone)]
pub enum Draw {
    /// Not at all (it does not paint this channel).
    Skip,
    /// As in the colour pass (a tool stroke: blur, smear, clone).
    Colour,
    /// Its channel image or constant, opacity, blend id, data weights (`Params::chan`) and
    /// raster flags.
    Channel {
        /// The channel's image; `None` where the channel is a constant (`constant`), drawn from
        /// the colour image's coverage.
        image: Option<Arc<GpuImage>>,
        /// A constant channel's value (a data channel's parts R, G, B; emissive RGB): drawn as
        /// the value times the colour image's alpha where it is sampled (what an image of the
        /// value with the colour's alpha holds), with [`super::params::FLAG_CONSTANT`].
        constant: Option<[f32; 4]>,
        /// The channel's opacity.
        opacity: f32,
        /// The blend's id in the compose shader.
        blend: u32,
        /// The data channels' weights (`Params::chan`).
        chan: [f32; 4],
        /// The raster's flags for this channel.
        flags: u32,
    },
}

/// One channel pass: what each job layer draws, the canvas's base, and for normals the mesh's
/// tangent frames on the baked UV set.
pub struct Pass {
    /// Which channel.
    pub kind: ChannelKind,
    /// Per job layer.
    pub draws: Vec<Draw>,
    /// The base texture, with the UV set it is laid out on.
    pub base: (Arc<GpuImage>, u32),
    /// Normals: tangents per split vertex (`vec4<f32>`, xyz and the bitangent sign).
    pub tangents: Option<wgpu::Buffer>,
}

/// One raster entry's channel draws in a fused pass (`ChannelDraw` in `wgsl/bake/layer_raster.wgsl`
/// and `compose.wgsl`): per group (orm, normal, emissive) the opacity, blend and data weights the
/// separate pass's entry would carry; `bits[0]`: the groups the unit paints, `bits[1]`: its normal
/// map is "dx", `bits[2]`: the groups drawn from a constant (`value`), `bits[3]`: of those, the
/// groups at the colour's opacity, whose samples are the colour's alphas times the constant: a
/// fused raster draws nothing for them and its compose derives them from the colour's samples
/// (`compose::channel_draws`). A separate pass's raster reads its group's `value` (at
/// `Params::draw` y) where it has `FLAG_CONSTANT`. Every compose composes a constant group as its
/// value times its samples' average alpha, so the fused and separate passes agree bit for bit.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub struct ChannelDraw {
    /// Opacity per group.
    pub opacity: [f32; 4],
    /// Blend id per group.
    pub blend: [u32; 4],
    /// Painted groups, "dx", constant groups, derived groups.
    pub bits: [u32; 4],
    /// Data weights per group (`Params::chan`).
    pub chan: [[f32; 4]; 3],
    /// A constant group's value ([`Draw::Channel`]'s `constant`).
    pub value: [[f32; 4]; 3],
}

impl ChannelDraw {
    /// Unit `u`'s draws over `passes` (its layer `layer`): what [`Draw::Channel`] gives each.
    pub(crate) fn of(passes: &[&Pass], layer: usize) -> Self {
        let mut d = Self::default();
        for p in passes {
            let k = p.kind.slot();
            if let Draw::Channel {
                opacity,
                blend,
                chan,
                flags,
                constant,
                ..
            } = &p.draws[layer]
            {
                d.opacity[k] = *opacity;
                d.blend[k] = *blend;
                d.chan[k] = *chan;
                d.bits[0] |= 1 << k;
                if let Some(v) = constant {
                    d.bits[2] |= 1 << k;
                    d.value[k] = *v;
                }
                if flags & FLAG_NORMAL_DX != 0 {
                    d.bits[1] = 1;
                }
            }
        }
        d
    }
}

/// Blend ids of `wgsl/shared/blend.wgsl` beyond the colour modes.
pub const BLEND_DATA_MIX: u32 = 16;
/// See [`BLEND_DATA_MIX`].
pub const BLEND_DATA_REPLACE: u32 = 17;
/// Reoriented normal mapping.
pub const BLEND_NRM_RNM: u32 = 20;
/// UDN.
pub const BLEND_NRM_UDN: u32 = 21;
/// The decal's normal replaces the base's.
pub const BLEND_NRM_REPLACE: u32 = 22;

/// Builds the pass of `kind`: each layer's channel image, uploaded; the base; the tangents.
/// Warnings (a `normal` image that is not a normal map) go to `warnings`.
pub(crate) fn pass(
    engine: &Engine,
    mesh: &LoadedMesh,
    job: &Job,
    kind: ChannelKind,
    warnings: &mut Vec<String>,
) -> Result<Pass> {
    let mut draws = Vec::with_capacity(job.layers.len());
    // Layers with the same colour image and channels share one channel image (a job of many
    // copies of a decal makes and uploads it once).
    let mut made: std::collections::HashMap<String, Arc<GpuImage>> = Default::default();
    for (i, l) in job.layers.iter().enumerate() {
        let tool = l
            .stroke
            .as_ref()
            .is_some_and(|s| !matches!(s.tool, crate::io::stroke::Tool::Paint));
        if tool {
            draws.push(Draw::Colour);
            continue;
        }
        if !l.channels.paints(kind) {
            draws.push(Draw::Skip);
            continue;
        }
        let (opacity, blend, chan, mut flags) = draw_params(l, kind);
        let constant = l.channels.constant(kind);
        let key = format!("{:?} {:?}", l.image, l.channels);
        let image = match (constant, made.get(&key)) {
            (Some(_), _) => {
                flags |= FLAG_CONSTANT;
                None
            }
            (None, Some(m)) => Some(m.clone()),
            (None, None) => {
                let img = layer_image(job, i, kind, warnings)?;
                let label = format!("bake.channel.{}", kind.name());
                let m = Arc::new(upload_image(engine, &img, true, &label));
                made.insert(key, m.clone());
                Some(m)
            }
        };
        draws.push(Draw::Channel {
            image,
            constant,
            opacity,
            blend,
            chan,
            flags,
        });
    }
    let mat = material_channels(mesh)?;
    let (base, uv) = base_image(&mat, kind);
    let base = Arc::new(upload_image(engine, &base, false, "bake.channel_base"));
    let tangents = (kind == ChannelKind::Normal).then(|| {
        let t = crate::mesh::tangents::tangents(&mesh.mesh, job.uv_set as usize);
        engine.ctx.storage_init(
            "bake.tangents",
            bytemuck::cast_slice(&t),
            wgpu::BufferUsages::empty(),
        )
    });
    Ok(Pass {
        kind,
        draws,
        base: (base, uv.unwrap_or(job.uv_set)),
        tangents,
    })
}

/// The mesh's material channels (the default material's where it has none or no document).
fn material_channels(mesh: &LoadedMesh) -> Result<MaterialChannels> {
    let (Some(doc), Some(m)) = (&mesh.mesh.document, &mesh.mesh.material) else {
        return Ok(MaterialChannels::default());
    };
    crate::mesh::material::channels(doc, m.index).map_err(|detail| Error::Image {
        path: mesh.mesh.source.clone(),
        action: "decoding",
        detail,
    })
}

/// Layer `l`'s draw in the pass of `kind`: opacity, blend id, data weights and raster flags.
fn draw_params(l: &crate::io::job::Layer, kind: ChannelKind) -> (f32, u32, [f32; 4], u32) {
    let c = &l.channels;
    match kind {
        ChannelKind::Orm => {
            let weight = |p: &Option<Channel>| p.as_ref().map_or(0.0, |c| c.opacity);
            let chan = [
                weight(&c.occlusion),
                weight(&c.roughness),
                weight(&c.metallic),
                0.0,
            ];
            let blend = match c.data_blend {
                DataBlend::Normal => BLEND_DATA_MIX,
                DataBlend::Replace => BLEND_DATA_REPLACE,
            };
            // Every part at the layer's opacity (the default): the group drawn at it, each part
            // weighted 1 (the same mix, a * w: the opacity moves from w into a), so its samples'
            // alphas are the colour's and a constant group is derived from them
            // (`compose::channel_draws`).
            let parts = [&c.occlusion, &c.roughness, &c.metallic];
            match c.orm_at(l.opacity) {
                true => {
                    let w = parts.map(|p| if p.is_some() { 1.0 } else { 0.0 });
                    (l.opacity, blend, [w[0], w[1], w[2], 0.0], 0)
                }
                false => (1.0, blend, chan, 0),
            }
        }
        ChannelKind::Normal => {
            let n = c
                .normal
                .as_ref()
                .expect("a normal pass draws layers with normals");
            let blend = match n.blend {
                NormalBlend::Rnm => BLEND_NRM_RNM,
                NormalBlend::Udn => BLEND_NRM_UDN,
                NormalBlend::Replace => BLEND_NRM_REPLACE,
            };
            let flags = if n.y_down { FLAG_NORMAL_DX } else { 0 };
            (n.opacity, blend, [0.0; 4], flags)
        }
        ChannelKind::Emissive => {
            let e = c
                .emissive
                .as_ref()
                .expect("an emissive pass draws layers with emissive");
            (e.opacity, l.blend as u32, [0.0; 4], 0)
        }
    }
}

/// Layer `i`'s image for `kind`: the channel's values with the colour image's alpha.
fn layer_image(
    job: &Job,
    i: usize,
    kind: ChannelKind,
    warnings: &mut Vec<String>,
) -> Result<LinearImage> {
    let l = &job.layers[i];
    let colour = l.colour_image()?;
    let c = &l.channels;
    Ok(match kind {
        ChannelKind::Orm => {
            let parts = [&c.occlusion, &c.roughness, &c.metallic];
            let mut loaded = Vec::new();
            for p in parts.iter().copied().flatten() {
                if let Value::Image(path) = &p.value {
                    loaded.push(as_stored(load_image(path, l.raster, false)?));
                }
            }
            let (w, h) = largest(&colour, loaded.iter());
            let mut next = loaded.into_iter();
            let mut sources: Vec<Option<Source>> = Vec::new();
            for p in parts {
                sources.push(p.as_ref().map(|ch| source(ch, &mut next)));
            }
            compose_image(&colour, w, h, |u, v| {
                let mut out = [0.0; 3];
                for (k, s) in sources.iter().enumerate() {
                    if let Some(s) = s {
                        out[k] = s.at(u, v)[0];
                    }
                }
                (out, 1.0)
            })
        }
        ChannelKind::Normal => {
            let n = c
                .normal
                .as_ref()
                .expect("a normal pass draws layers with normals");
            let map = as_stored(load_image(&n.image, l.raster, false)?);
            check_normal_map(&map, i, &n.image, warnings);
            let (w, h) = largest(&colour, std::iter::once(&map));
            compose_image(&colour, w, h, |u, v| {
                let p = map.bilinear(u, v, false);
                ([p[0], p[1], p[2]], p[3])
            })
        }
        ChannelKind::Emissive => {
            let e = c
                .emissive
                .as_ref()
                .expect("an emissive pass draws layers with emissive");
            let loaded = match &e.value {
                Value::Image(p) => Some(load_image(p, l.raster, false)?),
                Value::Constant(_) => None,
            };
            let (w, h) = largest(&colour, loaded.iter());
            compose_image(&colour, w, h, |u, v| match (&e.value, &loaded) {
                (Value::Constant(rgb), _) => (*rgb, 1.0),
                (_, Some(m)) => {
                    let p = m.bilinear(u, v, false);
                    ([p[0], p[1], p[2]], 1.0)
                }
                _ => ([0.0; 3], 1.0),
            })
        }
    })
}

/// Where a data channel's value comes from.
enum Source {
    Constant(f32),
    Image(LinearImage),
}

impl Source {
    fn at(&self, u: f32, v: f32) -> [f32; 4] {
        match self {
            Source::Constant(x) => [*x; 4],
            Source::Image(m) => m.bilinear(u, v, false),
        }
    }
}

fn source(ch: &Channel, images: &mut impl Iterator<Item = LinearImage>) -> Source {
    match &ch.value {
        Value::Constant(c) => Source::Constant(c[0]),
        Value::Image(_) => Source::Image(images.next().expect("loaded in order")),
    }
}

/// The larger of the colour image's and the channel images' sizes (by texel count).
fn largest<'a>(colour: &LinearImage, others: impl Iterator<Item = &'a LinearImage>) -> (u32, u32) {
    others
        .map(|m| (m.width, m.height))
        .chain([(colour.width, colour.height)])
        .max_by_key(|&(w, h)| w as u64 * h as u64)
        .expect("the colour image")
}

/// A `w`×`h` image whose texel at (u, v) is `value(u, v)`'s RGB with the colour image's alpha
/// there times `value`'s alpha.
fn compose_image(
    colour: &LinearImage,
    w: u32,
    h: u32,
    value: impl Fn(f32, f32) -> ([f32; 3], f32),
) -> LinearImage {
    let same = (w, h) == (colour.width, colour.height);
    let pixels = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| {
            let (u, v) = ((x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32);
            let a = match same {
                true => colour.pixels[(y * w + x) as usize][3],
                false => colour.bilinear(u, v, false)[3],
            };
            let (rgb, a2) = value(u, v);
            [rgb[0], rgb[1], rgb[2], a * a2]
        })
        .collect();
    LinearImage {
        width: w,
        height: h,
        pixels,
    }
}

/// Warns when `map` does not look like a tangent-space normal map: the mean length of its
/// decoded vectors over its visible texels is far from 1, or most point into the surface.
fn check_normal_map(
    map: &LinearImage,
    i: usize,
    path: &std::path::Path,
    warnings: &mut Vec<String>,
) {
    let (mut sum, mut below, mut n) = (0.0f64, 0usize, 0usize);
    for p in map.pixels.iter().filter(|p| p[3] > 0.5) {
        let v = [p[0] * 2.0 - 1.0, p[1] * 2.0 - 1.0, p[2] * 2.0 - 1.0];
        sum += (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt() as f64;
        below += (v[2] < 0.0) as usize;
        n += 1;
    }
    if n == 0 {
        return;
    }
    let mean = sum / n as f64;
    if (mean - 1.0).abs() > 0.2 || below * 2 > n {
        warnings.push(format!(
            "layer {i}: {} does not look like a tangent-space normal map (decoded vectors' mean length {mean:.2}, {:.0} % pointing into the surface); it is baked as given",
            path.display(),
            100.0 * below as f64 / n as f64
        ));
    }
}

/// The canvas base for `kind` from the material (a 1 × 1 image of the factor where the material
/// has no texture), and the UV set its texture is laid out on (`None`: any).
pub fn base_image(m: &MaterialChannels, kind: ChannelKind) -> (LinearImage, Option<u32>) {
    match kind {
        ChannelKind::Orm => {
            let (mr, occ) = (&m.metallic_roughness, &m.occlusion);
            // The occlusion texture joins only where it shares the metallic-roughness one's UVs.
            let occ = occ
                .as_ref()
                .filter(|o| mr.as_ref().is_none_or(|t| t.uv_set == o.uv_set));
            let sizes = [mr.as_ref(), occ].into_iter().flatten();
            let (w, h) = sizes
                .clone()
                .map(|t| (t.pixels.width, t.pixels.height))
                .max_by_key(|&(w, h)| w as u64 * h as u64)
                .unwrap_or((1, 1));
            let uv = sizes.map(|t| t.uv_set).next();
            let img = LinearImage {
                width: w,
                height: h,
                pixels: grid(w, h)
                    .map(|(u, v)| {
                        let o = occ.map_or(1.0, |t| {
                            1.0 + m.occlusion_strength * (t.pixels.bilinear(u, v, true)[0] - 1.0)
                        });
                        let t = mr
                            .as_ref()
                            .map_or([1.0; 4], |t| t.pixels.bilinear(u, v, true));
                        [o, t[1] * m.roughness, t[2] * m.metallic, 1.0]
                    })
                    .collect(),
            };
            (img, uv)
        }
        ChannelKind::Normal => match &m.normal {
            None => (LinearImage::solid(1, 1, [0.5, 0.5, 1.0, 1.0]), None),
            Some(t) => {
                let s = m.normal_scale;
                let pixels = t
                    .pixels
                    .pixels
                    .iter()
                    .map(|p| {
                        let n = glam::Vec3::new(
                            (p[0] * 2.0 - 1.0) * s,
                            (p[1] * 2.0 - 1.0) * s,
                            p[2] * 2.0 - 1.0,
                        )
                        .normalize_or(glam::Vec3::Z);
                        let e = n * 0.5 + 0.5;
                        [e.x, e.y, e.z, 1.0]
                    })
                    .collect();
                let img = LinearImage {
                    pixels,
                    ..t.pixels.clone()
                };
                (img, Some(t.uv_set))
            }
        },
        ChannelKind::Emissive => {
            let f = m.emissive_factor;
            match &m.emissive {
                None => (LinearImage::solid(1, 1, [f[0], f[1], f[2], 1.0]), None),
                Some(t) => {
                    let pixels = t
                        .pixels
                        .pixels
                        .iter()
                        .map(|p| [p[0] * f[0], p[1] * f[1], p[2] * f[2], 1.0])
                        .collect();
                    let img = LinearImage {
                        pixels,
                        ..t.pixels.clone()
                    };
                    (img, Some(t.uv_set))
                }
            }
        }
    }
}

/// Texel centres of a `w`×`h` image, row by row, as (u, v).
fn grid(w: u32, h: u32) -> impl Iterator<Item = (f32, f32)> + Clone {
    (0..h).flat_map(move |y| {
        (0..w).map(move |x| ((x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32))
    })
}

/// CPU twin of `to_tangent_space` in `wgsl/bake/layer_raster.wgsl`: decal normal `nd` (unit, in
/// the decal's frame: image x right, image y up, z out) at a point whose position and image
/// coordinates change by (`dpx`, `gx`) and (`dpy`, `gy`) along two directions, turned into the
/// tangent frame (`tangent` xyz and the bitangent sign w) about the unit normal `n`.
///
/// The decal's axes on the surface are d pos / d img: x = [dpx dpy] [gx gy]⁻¹ eₓ, and up is
/// −d pos / d img.y (image y runs down). In the tangent plane the decal's frame and the mesh's
/// are both orthonormal, so the turn between them is a rotation (c, s) in that plane, flipped by
/// each frame's handedness: c = x̂·t̂, s = n·(x̂ × t̂), with x and t projected onto the plane. The
/// result is (R nd.xy, nd.z), normalised: what projecting the decal's normal on its orthonormal
/// frame and reading it in the mesh's gives, with three square roots instead of five.
pub fn to_tangent_space(
    nd: glam::Vec3,
    (dpx, dpy): (glam::Vec3, glam::Vec3),
    (gx, gy): (glam::Vec2, glam::Vec2),
    n: glam::Vec3,
    tangent: glam::Vec4,
) -> glam::Vec3 {
    let det = gx.x * gy.y - gy.x * gx.y;
    let n = n.normalize();
    // The decal's x and y axes (times det) in the tangent plane.
    let ax = dpx * gy.y - dpy * gx.y;
    let ay = dpx * gy.x - dpy * gx.x;
    let x = ax - n * n.dot(ax);
    let y = ay - n * n.dot(ay);
    let t = tangent.truncate();
    let t = t - n * n.dot(t);
    // The decal frame's handedness about n (y's side of x), and the mesh's (the bitangent sign).
    let h = if n.dot(x.cross(y)) < 0.0 { -1.0 } else { 1.0 };
    let s = if tangent.w < 0.0 { -1.0 } else { 1.0 };
    let cs = glam::Vec2::new(x.dot(t), n.dot(x.cross(t))).normalize() * det.signum();
    glam::Vec3::new(
        nd.x * cs.x + nd.y * h * cs.y,
        s * (h * cs.x * nd.y - cs.y * nd.x),
        nd.z,
    )
    .normalize()
}

/// CPU twin of `normal_combine` in `wgsl/shared/blend.wgsl`: base `n1` and detail `n2` (unit,
/// tangent space) combined by `blend`, unit length.
pub fn combine_normals(blend: NormalBlend, n1: glam::Vec3, n2: glam::Vec3) -> glam::Vec3 {
    match blend {
        NormalBlend::Rnm => {
            let t = n1 + glam::Vec3::Z;
            let u = n2 * glam::Vec3::new(-1.0, -1.0, 1.0);
            (t * t.dot(u) / t.z - u).normalize()
        }
        NormalBlend::Udn => glam::Vec3::new(n1.x + n2.x, n1.y + n2.y, n1.z).normalize(),
        NormalBlend::Replace => n2,
    }
}

#[cfg(test)]
mod tests {
    use super::to_tangent_space;
    use glam::{Vec2, Vec3, Vec4};

    /// The turn by a rotation in the tangent plane equals projecting the decal's normal onto its
    /// orthonormal frame (Gram-Schmidt of d pos / d img about n) and reading it in the mesh's
    /// frame, written out the long way, for sheared, mirrored and turned maps, tangents of either
    /// sign and normals off the plane of the derivatives, within 1e-5: f32 rounding of unit
    /// vectors (about 6e-8), amplified by up to 1/0.05 where the map's determinant or the frames'
    /// angles come near the limits the test keeps (measured: at most 2.6e-6).
    #[test]
    fn the_rotation_equals_the_projection() {
        let reference =
            |nd: Vec3, (dpx, dpy): (Vec3, Vec3), (gx, gy): (Vec2, Vec2), n: Vec3, t: Vec4| {
                let n = n.normalize();
                let det = gx.x * gy.y - gy.x * gx.y;
                let ex = (dpx * gy.y - dpy * gx.y) / det;
                let ey = -(dpy * gx.x - dpx * gy.x) / det;
                let ex = (ex - n * n.dot(ex)).normalize();
                let ey = (ey - n * n.dot(ey) - ex * ex.dot(ey)).normalize();
                let w = (nd.x * ex + nd.y * ey + nd.z * n).normalize();
                let t3 = t.truncate();
                let tt = (t3 - n * n.dot(t3)).normalize();
                let b = n.cross(tt) * t.w.signum();
                Vec3::new(w.dot(tt), w.dot(b), w.dot(n))
            };
        // A small deterministic generator (no dependency for a test).
        let mut s = 0x2545_f491_u32;
        let mut r = || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            s as f32 / u32::MAX as f32 * 2.0 - 1.0
        };
        let mut checked = 0;
        for _ in 0..2000 {
            let v3 = |r: &mut dyn FnMut() -> f32| Vec3::new(r(), r(), r());
            let n = v3(&mut r) + Vec3::Z * 0.5;
            let (dpx, dpy) = (v3(&mut r), v3(&mut r));
            let (gx, gy) = (Vec2::new(r(), r()), Vec2::new(r(), r()));
            let t = v3(&mut r).extend(if r() < 0.0 { -1.0 } else { 1.0 });
            let nd = Vec3::new(r() * 0.7, r() * 0.7, 1.0).normalize();
            let det = gx.x * gy.y - gy.x * gx.y;
            let plane = (n.normalize().cross(dpx)).length() * n.normalize().cross(dpy).length();
            // Keep frames away from degenerate ones, where both are ill-conditioned.
            if det.abs() < 0.05 || plane < 0.05 || n.length() < 0.3 {
                continue;
            }
            let x = dpx * gy.y - dpy * gx.y;
            let y = dpx * gy.x - dpy * gx.x;
            let nn = n.normalize();
            let (xp, yp) = (x - nn * nn.dot(x), y - nn * nn.dot(y));
            let tp = t.truncate() - nn * nn.dot(t.truncate());
            if xp.normalize().cross(yp.normalize()).length() < 0.1 || tp.length() < 0.2 {
                continue;
            }
            let got = to_tangent_space(nd, (dpx, dpy), (gx, gy), n, t);
            let want = reference(nd, (dpx, dpy), (gx, gy), n, t);
            assert!(
                (got - want).abs().max_element() < 1e-5,
                "{got} against {want} (n {n}, dpx {dpx}, dpy {dpy}, gx {gx}, gy {gy}, t {t})"
            );
            checked += 1;
        }
        assert!(checked > 300, "{checked} frames checked");
    }
}
