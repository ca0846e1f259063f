// SPDX-License-Identifier: MIT OR Apache-2.0
//! Text layers (`"kind": "text"`): a line of UTF-8 text shaped by `rustybuzz` (kerning, ligatures,
//! right-to-left scripts, in the font's own order of glyphs), its outlines read from the font by
//! `ttf-parser`, and written as one SVG document that goes through the same vector path as an SVG
//! image ([`super::vector`]): rendered at the size the layer's map needs where it paints.
//!
//! | field | default |
//! |---|---|
//! | `text` | required, not empty |
//! | `font` | the bundled DejaVu Sans; a TTF or OTF file |
//! | `size` | required: the em size, model units on the surface |
//! | `color` | `[0, 0, 0, 1]`: sRGB RGBA in [0, 1] |
//! | `align` | `"center"`; `"start"` or `"end"` (of the line, or of the curve) |
//! | `letter_spacing` | 0 (em units, added after every glyph) |
//! | `at` or `path` | a decal at one point (the text block's centre there), or along a curve |
//! | `side` | `"left"`: along a curve, glyphs stand on the curve with their up to its left, seen from outside; `"right"` |
//! | `fit` | `"clip"`: text longer than its curve starts at its start and is cut at its end (a warning); `"shrink"`: scaled down to fit |
//!
//! Placed by `at`, a text layer is a decal whose image is the text block (the line's advance by
//! the font's ascender to descender); along a `path` it is a ribbon centred on the curve, as wide
//! as twice the font's larger of ascender and descender, with the baseline on the curve.

use crate::error::{Error, Result};
use std::fmt::Write;
use std::path::{Path, PathBuf};

/// Where the line sits in its block or along its curve.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TextAlign {
    /// At the start (the left end of the line as drawn, the curve's start).
    Start,
    /// Centred.
    Center,
    /// At the end.
    End,
}

/// What happens to text longer than its curve.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fit {
    /// Cut at the curve's end.
    Clip,
    /// Scaled down to the curve's length.
    Shrink,
}

/// Which side of its curve a text's glyphs stand on (their up direction).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    /// Up is the curve's left, seen from outside the surface.
    Left,
    /// Up is its right: the text reads from the curve's end towards its start.
    Right,
}

/// One glyph: its outline as SVG path data in font units (y up), and where its origin sits on
/// the line (font units from the line's start).
#[derive(Debug, Clone, PartialEq)]
struct Glyph {
    path: String,
    x: f32,
    y: f32,
}

/// A shaped line of text with everything its SVG needs.
#[derive(Debug, Clone, PartialEq)]
pub struct TextBlock {
    glyphs: Vec<Glyph>,
    /// The line's advance, font units (letter spacing included, but not after the last glyph).
    pub advance: f32,
    /// The font's ascender, font units.
    pub ascender: f32,
    /// The font's descender, font units (negative below the baseline).
    pub descender: f32,
    /// Units per em.
    pub units_per_em: f32,
    /// Glyph ids in shaping order (what rustybuzz returned, for tests and reports).
    pub glyph_ids: Vec<u16>,
    /// Characters the font has no glyph for (drawn as its .notdef).
    pub missing: Vec<char>,
}

/// A validated text layer: the shaped block and how it is drawn.
#[derive(Debug, Clone, PartialEq)]
pub struct Text {
    /// The string.
    pub text: String,
    /// The font file (`None`: the bundled font).
    pub font: Option<PathBuf>,
    /// The em size, model units.
    pub size: f32,
    /// sRGB RGBA in [0, 1].
    pub color: [f32; 4],
    /// Alignment.
    pub align: TextAlign,
    /// Which side of a curve (text along a path).
    pub side: Side,
    /// Text longer than its curve.
    pub fit: Fit,
    /// The shaped line.
    pub block: TextBlock,
}

/// Shapes `text` with the font `bytes` (face 0). `letter_spacing` in em units.
pub fn shape(
    text: &str,
    bytes: &[u8],
    letter_spacing: f32,
) -> std::result::Result<TextBlock, String> {
    let face = rustybuzz::Face::from_slice(bytes, 0)
        .ok_or("not a TrueType or OpenType font (ttf-parser cannot read its tables)")?;
    let mut buffer = rustybuzz::UnicodeBuffer::new();
    buffer.push_str(text);
    buffer.guess_segment_properties();
    let shaped = rustybuzz::shape(&face, &[], buffer);
    let upem = face.units_per_em() as f32;
    let spacing = letter_spacing * upem;
    let mut glyphs = Vec::new();
    let mut glyph_ids = Vec::new();
    let mut missing = Vec::new();
    let mut pen = 0.0f32;
    let n = shaped.len();
    for (k, (info, pos)) in shaped
        .glyph_infos()
        .iter()
        .zip(shaped.glyph_positions())
        .enumerate()
    {
        let id = info.glyph_id as u16;
        glyph_ids.push(id);
        if id == 0 {
            if let Some(c) = text[info.cluster as usize..].chars().next() {
                if !missing.contains(&c) {
                    missing.push(c);
                }
            }
        }
        let mut outline = Outline(String::new());
        let drawn = face
            .outline_glyph(ttf_parser::GlyphId(id), &mut outline)
            .is_some();
        if drawn {
            glyphs.push(Glyph {
                path: outline.0,
                x: pen + pos.x_offset as f32,
                y: pos.y_offset as f32,
            });
        }
        pen += pos.x_advance as f32;
        if k + 1 < n {
            pen += spacing;
        }
    }
    Ok(TextBlock {
        glyphs,
        advance: pen,
        ascender: face.ascender() as f32,
        descender: face.descender() as f32,
        units_per_em: upem,
        glyph_ids,
        missing,
    })
}

/// Glyph outlines as SVG path data.
struct Outline(String);

impl ttf_parser::OutlineBuilder for Outline {
    fn move_to(&mut self, x: f32, y: f32) {
        let _ = write!(self.0, "M{x} {y}");
    }
    fn line_to(&mut self, x: f32, y: f32) {
        let _ = write!(self.0, "L{x} {y}");
    }
    fn quad_to(&mut self, x1: f32, y1: f32, x: f32, y: f32) {
        let _ = write!(self.0, "Q{x1} {y1} {x} {y}");
    }
    fn curve_to(&mut self, x1: f32, y1: f32, x2: f32, y2: f32, x: f32, y: f32) {
        let _ = write!(self.0, "C{x1} {y1} {x2} {y2} {x} {y}");
    }
    fn close(&mut self) {
        self.0.push('Z');
    }
}

impl TextBlock {
    /// The block's height as a decal: ascender to descender, font units.
    pub fn line_height(&self) -> f32 {
        self.ascender - self.descender
    }

    /// The strip's width along a curve: twice the larger of ascender and descender (the
    /// baseline in its middle), font units.
    pub fn strip_height(&self) -> f32 {
        2.0 * self.ascender.max(-self.descender)
    }
}

impl Text {
    /// The decal size of the block at `at`: the line's advance by its height, model units.
    pub fn block_size(&self) -> [f32; 2] {
        let s = self.size / self.block.units_per_em;
        [
            (self.block.advance * s).max(1e-6),
            self.block.line_height() * s,
        ]
    }

    /// The strip's width along a curve, model units.
    pub fn strip_width(&self) -> f32 {
        self.block.strip_height() * self.size / self.block.units_per_em
    }

    /// How much of the line a curve of `length` model units holds: (the scale the glyphs are
    /// drawn at, 1 unless shrunk; whether glyphs are cut).
    pub fn fit_on(&self, length: f32) -> (f32, bool) {
        let line = self.block.advance * self.size / self.block.units_per_em;
        if line <= length {
            return (1.0, false);
        }
        match self.fit {
            Fit::Shrink => (length / line, false),
            Fit::Clip => (1.0, true),
        }
    }

    /// The SVG of the text: as a decal block (`curve`: `None`), or as the strip along a curve of
    /// `curve` model units (the image spans the curve; the baseline in the strip's middle).
    pub fn svg(&self, curve: Option<f32>) -> String {
        let b = &self.block;
        let (width, height, baseline, scale) = match curve {
            None => (b.advance.max(1.0), b.line_height(), b.ascender, 1.0),
            Some(length) => {
                let units = length * b.units_per_em / self.size;
                let (scale, _) = self.fit_on(length);
                (
                    units.max(1.0),
                    b.strip_height(),
                    0.5 * b.strip_height(),
                    scale,
                )
            }
        };
        let line = b.advance * scale;
        let x0 = match self.align {
            // Text longer than its curve starts at the curve's start and is cut at its end.
            _ if line > width => 0.0,
            TextAlign::Start => 0.0,
            TextAlign::Center => 0.5 * (width - line),
            TextAlign::End => width - line,
        };
        let [r, g, bl, a] = self.color.map(|c| c.clamp(0.0, 1.0));
        let mut s = format!(
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{width}\" height=\"{height}\" viewBox=\"0 0 {width} {height}\">"
        );
        let turn = if curve.is_some() && self.side == Side::Right {
            format!(
                " transform=\"rotate(180 {} {})\"",
                0.5 * width,
                0.5 * height
            )
        } else {
            String::new()
        };
        let _ = write!(
            s,
            "<g{turn} fill=\"rgb({:.4}%,{:.4}%,{:.4}%)\" fill-opacity=\"{a}\">",
            r * 100.0,
            g * 100.0,
            bl * 100.0
        );
        for glyph in &b.glyphs {
            let _ = write!(
                s,
                "<path transform=\"translate({} {}) scale({scale} {})\" d=\"{}\"/>",
                x0 + glyph.x * scale,
                baseline - glyph.y * scale,
                -scale,
                glyph.path
            );
        }
        s.push_str("</g></svg>");
        s
    }
}

/// Reads a text layer's font: the file, or the bundled font; errors name the field.
pub fn font_bytes(font: Option<&Path>, field: &str, src: &Path) -> Result<Vec<u8>> {
    match font {
        None => Ok(super::vector::BUNDLED_FONT.to_vec()),
        Some(p) => std::fs::read(p).map_err(|e| {
            Error::job(
                src,
                field,
                format!("{}: the font does not load: {e}", p.display()),
            )
        }),
    }
}

/// The job file's text fields of one layer.
pub struct Fields<'a> {
    /// `text`.
    pub text: &'a Option<String>,
    /// `font`.
    pub font: &'a Option<PathBuf>,
    /// `size`, when one number.
    pub size: Option<f32>,
    /// `color`.
    pub color: Option<[f32; 4]>,
    /// `align`.
    pub align: &'a Option<String>,
    /// `letter_spacing`.
    pub letter_spacing: Option<f32>,
    /// `side`.
    pub side: &'a Option<String>,
    /// `fit`.
    pub fit: &'a Option<String>,
}

impl Fields<'_> {
    /// The first text field given (for messages on other kinds).
    pub fn given(&self) -> Option<&'static str> {
        [
            ("text", self.text.is_some()),
            ("font", self.font.is_some()),
            ("color", self.color.is_some()),
            ("letter_spacing", self.letter_spacing.is_some()),
            ("side", self.side.is_some()),
            ("fit", self.fit.is_some()),
        ]
        .into_iter()
        .find(|f| f.1)
        .map(|f| f.0)
    }
}

/// Validates layer `i`'s text fields and shapes its text (`src`: the job file, for messages;
/// `input_dir`: where `font` is resolved). `along`: placed along a curve.
pub fn validate(
    f: &Fields<'_>,
    i: usize,
    src: &Path,
    input_dir: &Path,
    along: bool,
) -> Result<Text> {
    let field = |name: &str| format!("layers[{i}].{name}");
    let err = |name: &str, detail: String| Error::job(src, field(name), detail);
    let text = match f.text.as_deref() {
        None => return Err(err("text", "missing: a text layer needs `text`".into())),
        Some(t) if t.trim().is_empty() => {
            return Err(err("text", "is empty; give the text to draw".into()))
        }
        Some(t) if t.contains(['\n', '\r']) => {
            return Err(err(
                "text",
                "holds a line break; a text layer draws one line (use one layer per line)".into(),
            ))
        }
        Some(t) if t.len() > MAX_TEXT_BYTES => {
            return Err(err(
                "text",
                format!("is {} bytes long, above {MAX_TEXT_BYTES}", t.len()),
            ))
        }
        Some(t) => t.to_string(),
    };
    let size = match f.size {
        Some(s) if (1e-6..=super::at::MAX_SIZE_MODEL_UNITS).contains(&s) => s,
        Some(s) => {
            return Err(err(
                "size",
                format!(
                    "{s} must be an em size in model units, from 1e-6 to {}",
                    super::at::MAX_SIZE_MODEL_UNITS
                ),
            ))
        }
        None => {
            return Err(err(
                "size",
                "missing: a text layer's em size on the surface, one number in model units".into(),
            ))
        }
    };
    let color = f.color.unwrap_or([0.0, 0.0, 0.0, 1.0]);
    if color
        .iter()
        .any(|c| !c.is_finite() || !(0.0..=1.0).contains(c))
    {
        return Err(err(
            "color",
            format!("{color:?} must be sRGB RGBA, each in [0, 1]"),
        ));
    }
    let align = match f.align.as_deref() {
        None | Some("center") => TextAlign::Center,
        Some("start") => TextAlign::Start,
        Some("end") => TextAlign::End,
        Some(o) => {
            return Err(err(
                "align",
                format!("unknown \"{o}\"; a text layer takes \"start\", \"center\" or \"end\""),
            ))
        }
    };
    let side = match f.side.as_deref() {
        None | Some("left") => Side::Left,
        Some("right") => Side::Right,
        Some(o) => {
            return Err(err(
                "side",
                format!("unknown \"{o}\"; use \"left\" or \"right\""),
            ))
        }
    };
    let fit = match f.fit.as_deref() {
        None | Some("clip") => Fit::Clip,
        Some("shrink") => Fit::Shrink,
        Some(o) => {
            return Err(err(
                "fit",
                format!("unknown \"{o}\"; use \"clip\" or \"shrink\""),
            ))
        }
    };
    if !along {
        if let Some(name) = [("side", f.side.is_some()), ("fit", f.fit.is_some())]
            .into_iter()
            .find(|x| x.1)
            .map(|x| x.0)
        {
            return Err(err(
                name,
                "applies to text along a `path` only; remove it or place the text by `path`".into(),
            ));
        }
    }
    let spacing = f.letter_spacing.unwrap_or(0.0);
    if !spacing.is_finite() || spacing.abs() > 10.0 {
        return Err(err(
            "letter_spacing",
            format!("{spacing} must be a finite number of ems, at most 10 either way"),
        ));
    }
    let font = f.font.as_ref().map(|p| input_dir.join(p));
    let bytes = font_bytes(font.as_deref(), &field("font"), src)?;
    let block = shape(&text, &bytes, spacing).map_err(|e| {
        let name = font
            .as_ref()
            .map_or("the bundled font".to_string(), |p| p.display().to_string());
        err("font", format!("{name}: the font does not load: {e}"))
    })?;
    if block.advance <= 0.0 {
        return Err(err(
            "text",
            "draws nothing: its glyphs have no width in this font".into(),
        ));
    }
    if block.line_height() <= 0.0 || block.strip_height() <= 0.0 || block.units_per_em <= 0.0 {
        return Err(err(
            "font",
            format!(
                "its ascender ({}) and descender ({}) give its lines no height; choose another font",
                block.ascender, block.descender
            ),
        ));
    }
    Ok(Text {
        text,
        font,
        size,
        color,
        align,
        side,
        fit,
        block,
    })
}

/// The longest `text` a layer takes, bytes.
pub const MAX_TEXT_BYTES: usize = 65536;
