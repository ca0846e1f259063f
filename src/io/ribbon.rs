// SPDX-License-Identifier: MIT OR Apache-2.0
//! The ribbon fields of a job layer (`"kind": "ribbon"`, Sun et al. 2013): an image laid along a
//! surface curve by the curve's extended exponential map ([`crate::maps::ribbon`]). Validated here;
//! defaults (also in docs/ribbons.md):
//!
//! | field | default |
//! |---|---|
//! | `path` | required: at least 2 surface points (points or rays, like `at`) |
//! | `interpolate` | `"catmull-rom"`: the curve is the smooth spline through the points; `"linear"`: the geodesics between consecutive points ([`super::stroke::Interpolate`]) |
//! | `width` | the image's height / width × the curve's length (the image spans the curve at its aspect) |
//! | `repeat` | `"stretch"` (the image spans the curve); `"tile"`: repeated at its own aspect |
//! | `align` | `"center"` (the strip straddles the curve); `"left"` or `"right"` of it, seen from outside |
//! | `flip` | `false`; `true` mirrors the image across the curve |
//! | `curved_threshold` | 0.2: the λ of Sun et al. §3 step 4; parts where the strip's offset
//! stretches or shrinks by more than this are re-solved harmonically, u alone first, the full map
//! onto a rectangle where that still folds ([`crate::maps::ribbon::repair`]) |
//! | `animate` | none; `{"route": [points], "frames": N, "length": L, "closed": false}`: the image
//! occupies `length` of the route and moves along it over the frames (Sun et al. §4.3); replaces
//! `path` |

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
    /// How the curve runs between its points (an animated ribbon's route too).
    pub interpolate: super::stroke::Interpolate,
    /// Strip width in model units (`None`: from the image's aspect and the curve's length).
    pub width: Option<f32>,
    /// Stretch or tile.
    pub repeat: Repeat,
    /// Centre, left or right.
    pub align: Align,
    /// Mirror across the curve.
    pub flip: bool,
    /// An animated ribbon: its curve is the piece of the route ([`Ribbon::path`]) this frame shows.
    pub animate: Option<Animate>,
    /// λ of the curved parts' detection (Sun et al. §3 step 4).
    pub curved_threshold: f32,
}

/// The most frames an animation may have (one bake and one texture each).
pub const MAX_FRAMES: u32 = 1000;

/// An animated ribbon (`"animate"`, Sun et al. 2013, §4.3): the image occupies a piece of
/// `length` model units of the route (the ribbon's `path`, closed back to its first point when
/// `closed`), which moves along the route over `frames` frames: from the route's start to its
/// end on an open route (frame f starts at f / (frames − 1) of the route's length less `length`),
/// once around a closed one (at f / frames of its length, wrapping past the start).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Animate {
    /// Frames in the animation.
    pub frames: u32,
    /// The piece's length along the route, model units.
    pub length: f32,
    /// The route is a loop.
    pub closed: bool,
    /// The frame this job bakes (set by [`super::job::Job::for_frame`]; 0 as parsed).
    pub frame: u32,
}

impl Animate {
    /// Where frame `self.frame`'s piece starts along a route of length `route`.
    pub fn start(&self, route: f32) -> f32 {
        let f = self.frame as f32;
        if self.closed {
            route * f / self.frames as f32
        } else if self.frames > 1 {
            (route - self.length).max(0.0) * f / (self.frames - 1) as f32
        } else {
            0.0
        }
    }
}

/// `"animate"` as written.
#[derive(Debug, Clone, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct AnimateSpec {
    /// The route: surface points like `path`'s.
    pub route: Vec<AtSpec>,
    /// How many frames (one texture each).
    pub frames: u32,
    /// The image's length along the route, model units.
    pub length: f32,
    /// Join the route's last point back to its first.
    #[serde(default)]
    pub closed: bool,
}

/// The ribbon fields of a layer as written.
pub(crate) struct Fields<'a> {
    pub path: &'a Option<Vec<AtSpec>>,
    pub interpolate: &'a Option<String>,
    pub width: Option<f32>,
    pub repeat: &'a Option<String>,
    pub align: &'a Option<String>,
    pub flip: Option<bool>,
    pub animate: &'a Option<AnimateSpec>,
    pub curved_threshold: Option<f32>,
}

impl Fields<'_> {
    /// The first ribbon-only field given (`path` and `interpolate` are shared with strokes and not
    /// counted).
    pub fn given(&self) -> Option<&'static str> {
        [
            ("width", self.width.is_some()),
            ("repeat", self.repeat.is_some()),
            ("align", self.align.is_some()),
            ("flip", self.flip.is_some()),
            ("animate", self.animate.is_some()),
            ("curved_threshold", self.curved_threshold.is_some()),
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
    let animate = match (l.animate, l.path) {
        (Some(_), Some(_)) => {
            return Err(err(
                "path",
                "an animated ribbon follows `animate.route`; remove `path`".into(),
            ))
        }
        (Some(a), None) => Some(animate(a, i, src)?),
        (None, _) => None,
    };
    let route = l.animate.as_ref().map(|a| {
        let mut r = a.route.clone();
        if a.closed && r.len() >= 2 {
            r.push(r[0].clone());
        }
        r
    });
    let path = match route.as_ref().or(l.path.as_ref()) {
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
    let points = if animate.is_some() {
        "animate.route"
    } else {
        "path"
    };
    for (k, at) in path.iter().enumerate() {
        check_at(at, &field(&format!("{points}[{k}]")), src)?;
    }
    let interpolate = super::stroke::Interpolate::parse(l.interpolate.as_deref())
        .map_err(|d| err("interpolate", d))?;
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
        interpolate,
        width,
        repeat,
        align,
        flip: l.flip.unwrap_or(false),
        animate,
        curved_threshold: match l.curved_threshold {
            Some(t) if !t.is_finite() || t <= 0.0 || t > 1e6 => {
                return Err(err(
                    "curved_threshold",
                    format!("{t} must be a positive ratio (Sun et al.'s λ, default 0.2; a large value turns the repair off)"),
                ))
            }
            Some(t) => t,
            None => 0.2,
        },
    })
}

/// Validates layer `i`'s `animate` (the route's points are checked with the path's).
fn animate(a: &AnimateSpec, i: usize, src: &Path) -> Result<Animate> {
    let err =
        |name: &str, detail: String| Error::job(src, format!("layers[{i}].animate.{name}"), detail);
    if a.route.len() < 2 {
        return Err(err(
            "route",
            format!("has {} point(s); a route needs at least 2", a.route.len()),
        ));
    }
    if a.frames == 0 || a.frames > MAX_FRAMES {
        return Err(err(
            "frames",
            format!(
                "{} must be 1 to {MAX_FRAMES} (one bake and one texture a frame)",
                a.frames
            ),
        ));
    }
    if !a.length.is_finite() || a.length <= 0.0 || a.length > super::at::MAX_SIZE_MODEL_UNITS {
        return Err(err(
            "length",
            format!(
                "{} must be a positive length along the route, model units",
                a.length
            ),
        ));
    }
    Ok(Animate {
        frames: a.frames,
        length: a.length,
        closed: a.closed,
        frame: 0,
    })
}

/// `text` with its `{frame}` or `{frame:0N}` placeholder replaced by `f` (zero-padded to N digits,
/// N at most 9); `None` without a valid placeholder.
pub fn frame_name(text: &str, f: u32) -> Option<String> {
    let start = text.find("{frame")?;
    let end = start + text[start..].find('}')?;
    let width = match &text[start + 6..end] {
        "" => 0,
        spec => spec
            .strip_prefix(":0")?
            .parse::<usize>()
            .ok()
            .filter(|&w| w <= 9)?,
    };
    Some(format!("{}{f:0width$}{}", &text[..start], &text[end + 1..]))
}

#[cfg(test)]
mod tests {
    use super::frame_name;

    #[test]
    fn frame_placeholders_are_replaced() {
        assert_eq!(frame_name("a_{frame}.png", 7).as_deref(), Some("a_7.png"));
        assert_eq!(
            frame_name("a_{frame:04}.png", 7).as_deref(),
            Some("a_0007.png")
        );
        assert_eq!(frame_name("a.png", 7), None);
        assert_eq!(frame_name("a_{frame:x}.png", 7), None);
        assert_eq!(frame_name("a_{frame:010000000000}.png", 7), None);
    }
}
