// SPDX-License-Identifier: MIT OR Apache-2.0
//! The ribbon fields of a job layer (`"kind": "ribbon"`, Sun et al. 2013): an image laid along a
//! surface curve by the curve's extended exponential map ([`crate::maps::ribbon`]). Validated here;
//! defaults (also in the README):
//!
//! | field | default |
//! |---|---|
//! | `path` | required: at least 2 surface points (points or rays, like `at`) |
//! | `width` | the image's height / width × the curve's length (the image spans the curve at its aspect) |
//! | `repeat` | `"stretch"` (the image spans the curve); `"tile"`: repeated at its own aspect |
//! | `align` | `"center"` (the strip straddles the curve); `"left"` or `"right"` of it, seen from outside |
//! | `flip` | `false`; `true` mirrors the image across the curve |

use super::at::{check_at, AtSpec};
use crate::error::{Error, Result};
use std::path::Path;

/// How the image runs along the curve.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Repeat {
    /// One image over the whole curve.
    #[default]
    Stretch,
    /// The image repeated along the curve at its own aspect (the last copy cut at the end).
    Tile,
}

/// Where the strip lies across the curve.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Align {
    /// Half on each side.
    #[default]
    Center,
    /// On the left of the curve seen from outside the surface (along N × T).
    Left,
    /// On the right.
    Right,
}

/// A validated ribbon.
#[derive(Debug, Clone, PartialEq)]
pub struct Ribbon {
    /// The curve's points, joined along the surface as a stroke's are.
    pub path: Vec<AtSpec>,
    /// Strip width in model units (`None`: from the image's aspect and the curve's length).
    pub width: Option<f32>,
    /// Stretch or tile.
    pub repeat: Repeat,
    /// Centre, left or right.
    pub align: Align,
    /// Mirror across the curve.
    pub flip: bool,
}

/// The ribbon fields of a layer as written.
pub(crate) struct Fields<'a> {
    pub path: &'a Option<Vec<AtSpec>>,
    pub width: Option<f32>,
    pub repeat: &'a Option<String>,
    pub align: &'a Option<String>,
    pub flip: Option<bool>,
}

impl Fields<'_> {
    /// The first ribbon-only field given (`path` is shared with strokes and not counted).
    pub fn given(&self) -> Option<&'static str> {
        [
            ("width", self.width.is_some()),
            ("repeat", self.repeat.is_some()),
            ("align", self.align.is_some()),
            ("flip", self.flip.is_some()),
        ]
        .into_iter()
        .find(|(_, g)| *g)
        .map(|(n, _)| n)
    }
}

/// Validates the ribbon fields of layer `i`; `src` names the job file in messages.
pub(crate) fn validate(l: &Fields<'_>, i: usize, src: &Path) -> Result<Ribbon> {
    let field = |name: &str| format!("layers[{i}].{name}");
    let err = |name: &str, detail: String| Error::job(src, field(name), detail);
    let path = match l.path {
        Some(p) if p.len() >= 2 => p.clone(),
        Some(p) => {
            return Err(err(
                "path",
                format!(
                    "has {} point(s); a ribbon's curve needs at least 2",
                    p.len()
                ),
            ))
        }
        None => {
            return Err(err(
                "path",
                "missing: a ribbon follows a curve of at least 2 surface points".into(),
            ))
        }
    };
    for (k, at) in path.iter().enumerate() {
        check_at(at, &field(&format!("path[{k}]")), src)?;
    }
    let width = match l.width {
        Some(w) if !w.is_finite() || w <= 0.0 || w > super::at::MAX_SIZE_MODEL_UNITS => {
            return Err(err(
                "width",
                format!("{w} must be a positive strip width in model units"),
            ))
        }
        w => w,
    };
    let repeat = match l.repeat.as_deref() {
        None | Some("stretch") => Repeat::Stretch,
        Some("tile") => Repeat::Tile,
        Some(other) => {
            return Err(err(
                "repeat",
                format!("unknown repeat \"{other}\"; use \"stretch\" or \"tile\""),
            ))
        }
    };
    let align = match l.align.as_deref() {
        None | Some("center") => Align::Center,
        Some("left") => Align::Left,
        Some("right") => Align::Right,
        Some(other) => {
            return Err(err(
                "align",
                format!("unknown align \"{other}\"; use \"center\", \"left\" or \"right\""),
            ))
        }
    };
    Ok(Ribbon {
        path,
        width,
        repeat,
        align,
        flip: l.flip.unwrap_or(false),
    })
}
