// SPDX-License-Identifier: MIT OR Apache-2.0
//! Vector images: SVG files, parsed by `usvg` (CSS, transforms, gradients, `<use>`, text turned
//! into paths with the bundled font) and rendered by `resvg` at the pixel size the bake asks for.
//!
//! A layer whose image, mask or channel image is an SVG (or whose kind is `"text"`, [`super::text`])
//! is rendered after placement at the size its map needs on the triangles it paints
//! (`bake::vector::set_rasters`): twice the texels its image covers along each side, so each
//! texel's samples read the image's first mipmap level and edges carry the bake's own
//! anti-aliasing, never a fixed bitmap's blur. Before placement (the intrinsic size, e.g. a ribbon's
//! aspect) the SVG's own `width` and `height` are used.
//!
//! Colour is sRGB as in any image file; a mask's values are read as data. `<image>` elements that
//! embed bitmaps are not drawn (the `raster-images` feature of resvg is off): a logo that needs one
//! is a PNG decal.

use super::image::{srgb_to_linear, LinearImage};
use crate::error::{Error, Result};
use std::path::Path;
use std::sync::{Arc, OnceLock};

/// The bundled font (DejaVu Sans, `assets/fonts/`, its licence beside it): the default of text
/// layers and the only font SVG `<text>` elements find, so a bake gives the same bytes on every
/// machine.
pub static BUNDLED_FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

/// The family name of [`BUNDLED_FONT`].
pub const BUNDLED_FAMILY: &str = "DejaVu Sans";

/// The longest side an SVG is rendered at when nothing asks for a size (its own size when larger).
pub const DEFAULT_SIDE: u32 = 1024;

/// The longest side a vector image is rendered at.
pub const MAX_SIDE: u32 = 8192;

/// The most pixels one vector image is rendered with (4096², 256 MiB as f32 RGBA before
/// mipmaps).
pub const MAX_PIXELS: u64 = 1 << 24;

/// Whether `path` names an SVG file (by its extension, any case).
pub fn is_svg(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("svg"))
}

/// The font database usvg resolves `<text>` with: the bundled font alone.
fn fonts() -> Arc<resvg::usvg::fontdb::Database> {
    static DB: OnceLock<Arc<resvg::usvg::fontdb::Database>> = OnceLock::new();
    DB.get_or_init(|| {
        let mut db = resvg::usvg::fontdb::Database::new();
        db.load_font_data(BUNDLED_FONT.to_vec());
        db.set_sans_serif_family(BUNDLED_FAMILY);
        db.set_serif_family(BUNDLED_FAMILY);
        db.set_monospace_family(BUNDLED_FAMILY);
        Arc::new(db)
    })
    .clone()
}

/// A parsed SVG document.
pub struct Svg {
    tree: resvg::usvg::Tree,
}

impl std::fmt::Debug for Svg {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Svg({:?})", self.size())
    }
}

impl Svg {
    /// Parses SVG text; the error says why (usvg's message, with the line and column where the
    /// XML is malformed).
    pub fn parse(bytes: &[u8]) -> std::result::Result<Svg, String> {
        let options = resvg::usvg::Options {
            font_family: BUNDLED_FAMILY.into(),
            fontdb: fonts(),
            ..resvg::usvg::Options::default()
        };
        let tree = resvg::usvg::Tree::from_data(bytes, &options).map_err(|e| e.to_string())?;
        let s = tree.size();
        if !(s.width().is_finite() && s.height().is_finite()) {
            return Err("its width or height is not finite".into());
        }
        Ok(Svg { tree })
    }

    /// Reads and parses an SVG file; errors name the file.
    pub fn load(path: &Path) -> Result<Svg> {
        let bytes = std::fs::read(path).map_err(|source| Error::Io {
            path: path.to_path_buf(),
            action: "reading the image",
            source,
        })?;
        Svg::parse(&bytes).map_err(|detail| Error::Image {
            path: path.to_path_buf(),
            action: "decoding",
            detail: format!("the SVG does not parse: {detail}"),
        })
    }

    /// The parsed tree (for [`super::vector_paths`]).
    pub(super) fn tree(&self) -> &resvg::usvg::Tree {
        &self.tree
    }

    /// Width and height in the SVG's own units.
    pub fn size(&self) -> [f32; 2] {
        let s = self.tree.size();
        [s.width(), s.height()]
    }

    /// Pixel size at [`DEFAULT_SIDE`] on the longer side (or the SVG's own, when larger), with
    /// the SVG's aspect.
    /// The SVG's aspect is kept, and so are [`MAX_SIDE`] and [`MAX_PIXELS`].
    pub fn default_px(&self) -> [u32; 2] {
        let [w, h] = self.size();
        let longer = w.max(h).max(f32::MIN_POSITIVE);
        let mut scale = (DEFAULT_SIDE as f32 / longer).max(1.0);
        scale = scale.min(MAX_SIDE as f32 / longer);
        let pixels = (w * scale) as f64 * (h * scale) as f64;
        if pixels > MAX_PIXELS as f64 {
            scale *= (MAX_PIXELS as f64 / pixels).sqrt() as f32;
        }
        [
            ((w * scale).round() as u32).clamp(1, MAX_SIDE),
            ((h * scale).round() as u32).clamp(1, MAX_SIDE),
        ]
    }

    /// The document rendered over `px` pixels (stretched to that size): straight alpha; colour
    /// sRGB-decoded, or kept as stored when `raw` (a mask).
    /// Each side is held to [`MAX_SIDE`].
    pub fn render(&self, px: [u32; 2], raw: bool) -> LinearImage {
        let [w, h] = px.map(|p| p.clamp(1, MAX_SIDE));
        let mut pixmap = resvg::tiny_skia::Pixmap::new(w, h).expect("a non-empty pixmap");
        let [sw, sh] = self.size();
        let xf = resvg::tiny_skia::Transform::from_scale(w as f32 / sw, h as f32 / sh);
        resvg::render(&self.tree, xf, &mut pixmap.as_mut());
        LinearImage {
            width: w,
            height: h,
            pixels: pixmap
                .data()
                .chunks_exact(4)
                .map(|p| straight(p, raw))
                .collect(),
        }
    }
}

/// A premultiplied RGBA8 pixel as straight alpha in [0, 1], colour sRGB-decoded unless `raw`.
fn straight(p: &[u8], raw: bool) -> [f32; 4] {
    let a = p[3] as f32 / 255.0;
    let c = |v: u8| {
        let s = if p[3] == 0 {
            0.0
        } else {
            (v as f32 / 255.0 / a).min(1.0)
        };
        if raw {
            s
        } else {
            srgb_to_linear(s)
        }
    };
    [c(p[0]), c(p[1]), c(p[2]), a]
}

/// An image file rendered or decoded: an SVG at `px` (or [`Svg::default_px`]), anything else as
/// [`LinearImage::load`] reads it (`px` does not apply). `raw`: a mask's data, not sRGB colour.
pub fn load_image(path: &Path, px: Option<[u32; 2]>, raw: bool) -> Result<LinearImage> {
    if is_svg(path) {
        let svg = Svg::load(path)?;
        let px = px.unwrap_or_else(|| svg.default_px());
        return Ok(svg.render(px, raw));
    }
    let img = LinearImage::load(path)?;
    if !raw {
        return Ok(img);
    }
    // Masks are data, not colour: undo the sRGB decode so a mid-grey mask value means 50 %.
    Ok(LinearImage {
        pixels: img
            .pixels
            .iter()
            .map(|p| {
                [
                    super::image::linear_to_srgb(p[0]),
                    super::image::linear_to_srgb(p[1]),
                    super::image::linear_to_srgb(p[2]),
                    p[3],
                ]
            })
            .collect(),
        ..img
    })
}

/// An image file's width and height: an SVG's at [`Svg::default_px`] (its aspect), else read
/// from the header.
pub fn dimensions(path: &Path) -> std::result::Result<(u32, u32), String> {
    if is_svg(path) {
        let bytes = std::fs::read(path).map_err(|e| e.to_string())?;
        let svg = Svg::parse(&bytes).map_err(|e| format!("the SVG does not parse: {e}"))?;
        // At its default pixel size: the aspect of a small SVG survives the rounding.
        let [w, h] = svg.default_px();
        return Ok((w, h));
    }
    image::image_dimensions(path).map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An SVG that declares a huge size is rendered within the limits, with its aspect; a tiny
    /// one at the default side, its aspect kept (rounding its own size would make it square).
    #[test]
    fn default_sizes_keep_the_aspect_within_the_limits() {
        let svg = |w: &str, h: &str| {
            Svg::parse(
                format!(r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}"/>"#)
                    .as_bytes(),
            )
            .unwrap()
        };
        assert_eq!(svg("1e9", "1e9").default_px(), [4096, 4096]);
        assert_eq!(svg("100000", "10").default_px(), [8192, 1]);
        assert_eq!(svg("1", "0.3").default_px(), [1024, 307]);
        assert_eq!(svg("100", "50").default_px(), [1024, 512]);
        assert_eq!(svg("3000", "1000").default_px(), [3000, 1000]);
    }
}
