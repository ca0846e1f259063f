// SPDX-License-Identifier: MIT OR Apache-2.0
//! The stroke fields of a job layer (`"kind": "stroke"`): the path, pressure, spacing, flow and the
//! tool, validated. Defaults (also in docs/strokes.md):
//!
//! | field | default |
//! |---|---|
//! | `tool` | `"paint"` |
//! | `pressure` | 1 at every path point |
//! | `spacing` | `0.1` (stamp distance / stamp width) |
//! | `flow` | `1.0` |
//! | `pressure_size` | `1.0` |
//! | `pressure_flow` | `0.0` |
//! | `orient` | `"path"` |
//! | `method` | `"lscm"` for strokes (Maillot) |
//! | `continuity` | `true` (Maillot section 7; see [`crate::maps::stamp`]) |
//! | `interpolate` | `"catmull-rom"`: the path is the smooth curve through its points; `"linear"`: the geodesics between consecutive points (also for ribbons; [`Interpolate`]) |

use super::at::{check_at, AtSpec};
use crate::error::{Error, Result};
use std::path::Path;

/// What a stroke's stamps do.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
#[serde(rename_all = "lowercase", tag = "tool")]
pub enum Tool {
    /// Paint the stamp image.
    Paint,
    /// Blur what is below under each stamp, in the stamp's flat space (Maillot section 10).
    Blur {
        /// Gaussian radius on the surface (model units): two standard deviations.
        radius: f32,
    },
    /// Each stamp carries the colour the previous stamp picked up, mixed by `strength`.
    Smear {
        /// How much of the carried colour each stamp keeps, in [0, 1].
        strength: f32,
    },
    /// Each stamp copies what is below a source stamp that follows the stroke from `source`.
    Clone {
        /// Where the source starts (like `at`).
        source: AtSpec,
    },
}

impl Tool {
    /// Whether the tool paints what is below (inverse rendering) instead of the stamp image.
    pub fn reads_canvas(&self) -> bool {
        !matches!(self, Tool::Paint)
    }
}

/// How each stamp's image is turned on the surface.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Orient {
    /// The image's x axis along the path's tangent (Maillot section 7).
    Path,
    /// `up` and `angle`, like a decal.
    Fixed,
}

/// How a path (a stroke's or a ribbon's) runs between its points (`"interpolate"`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
pub enum Interpolate {
    /// `"catmull-rom"`: the centripetal Catmull-Rom spline through the points, laid on the surface
    /// (`bake/kinds/stroke/spline.rs`): the path turns smoothly at its points.
    #[default]
    #[serde(rename = "catmull-rom")]
    CatmullRom,
    /// `"linear"`: the geodesic from each point to the next; the path has a corner at each point.
    #[serde(rename = "linear")]
    Linear,
}

impl Interpolate {
    /// `"interpolate"` as given (`None`: the default); `Err` says what it may be.
    pub(crate) fn parse(given: Option<&str>) -> std::result::Result<Self, String> {
        match given {
            None | Some("catmull-rom") => Ok(Interpolate::CatmullRom),
            Some("linear") => Ok(Interpolate::Linear),
            Some(other) => Err(format!(
                "unknown interpolation \"{other}\"; use \"catmull-rom\" (a smooth curve through the points) or \"linear\" (geodesics between them)"
            )),
        }
    }
}

/// A validated stroke.
#[derive(Debug, Clone)]
pub struct Stroke {
    /// The tool.
    pub tool: Tool,
    /// Surface points, joined along the surface.
    pub path: Vec<AtSpec>,
    /// How the path runs between its points.
    pub interpolate: Interpolate,
    /// Pressure per path point (1 everywhere when not given).
    pub pressure: Vec<f32>,
    /// Stamp distance as a fraction of the (pressure-scaled) stamp width.
    pub spacing: f32,
    /// Each stamp's alpha.
    pub flow: f32,
    /// Size factor at pressure p: `1 - pressure_size (1 - p)`.
    pub pressure_size: f32,
    /// Flow factor at pressure p: `1 - pressure_flow (1 - p)`.
    pub pressure_flow: f32,
    /// Stamp orientation.
    pub orient: Orient,
    /// Per-vertex charts interpolated (Maillot section 7, [`crate::maps::stamp`]); `false`: one
    /// chart per stamp at its point.
    pub continuity: bool,
}

/// A job layer's stroke fields as given (see `LayerSpec` in [`super::job`] for each one's meaning).
pub(crate) struct Fields<'a> {
    pub tool: &'a Option<String>,
    pub path: &'a Option<Vec<AtSpec>>,
    pub interpolate: &'a Option<String>,
    pub pressure: &'a Option<Vec<f32>>,
    pub spacing: Option<f32>,
    pub flow: Option<f32>,
    pub pressure_size: Option<f32>,
    pub pressure_flow: Option<f32>,
    pub orient: &'a Option<String>,
    pub continuity: Option<bool>,
    pub radius: Option<f32>,
    pub strength: Option<f32>,
    pub source: &'a Option<AtSpec>,
}

impl Fields<'_> {
    /// The first stroke field given (for layers that are not strokes, which must not carry them).
    pub fn given(&self) -> Option<&'static str> {
        [
            ("tool", self.tool.is_some()),
            ("path", self.path.is_some()),
            ("interpolate", self.interpolate.is_some()),
            ("pressure", self.pressure.is_some()),
            ("spacing", self.spacing.is_some()),
            ("flow", self.flow.is_some()),
            ("pressure_size", self.pressure_size.is_some()),
            ("pressure_flow", self.pressure_flow.is_some()),
            ("orient", self.orient.is_some()),
            ("continuity", self.continuity.is_some()),
            ("radius", self.radius.is_some()),
            ("strength", self.strength.is_some()),
            ("source", self.source.is_some()),
        ]
        .into_iter()
        .find(|(_, g)| *g)
        .map(|(n, _)| n)
    }
}

/// Validates the stroke fields of layer `i` (a stroke); `src` names the job file in messages.
/// `size_x` is the stamp width (the default blur radius is a tenth of it); `mask`: whether the layer
/// has a mask (tools that read the canvas use the stamp image's alpha as their shape instead).
pub(crate) fn validate(
    l: &Fields<'_>,
    i: usize,
    src: &Path,
    (size_x, mask): (f32, bool),
) -> Result<Stroke> {
    let field = |name: &str| format!("layers[{i}].{name}");
    let err = |name: &str, detail: String| Error::job(src, field(name), detail);
    let path = match &l.path {
        None => {
            return Err(err(
                "path",
                "missing: a stroke needs a `path` of surface points".into(),
            ))
        }
        Some(p) if p.is_empty() => {
            return Err(err(
                "path",
                "is empty: give at least one surface point".into(),
            ))
        }
        Some(p) => p.clone(),
    };
    for (k, at) in path.iter().enumerate() {
        check_at(at, &field(&format!("path[{k}]")), src)?;
    }
    let interpolate =
        Interpolate::parse(l.interpolate.as_deref()).map_err(|d| err("interpolate", d))?;
    let pressure = match &l.pressure {
        None => vec![1.0; path.len()],
        Some(p) if p.len() != path.len() => {
            return Err(err(
                "pressure",
                format!(
                    "has {} values for {} path points; give one pressure per point",
                    p.len(),
                    path.len()
                ),
            ))
        }
        Some(p) => {
            if let Some(k) = p
                .iter()
                .position(|v| !v.is_finite() || !(0.0..=1.0).contains(v))
            {
                return Err(err(
                    &format!("pressure[{k}]"),
                    format!("{} must be in [0, 1]", p[k]),
                ));
            }
            p.clone()
        }
    };
    let unit = |name: &str, v: Option<f32>, default: f32| -> Result<f32> {
        match v {
            Some(x) if !x.is_finite() || !(0.0..=1.0).contains(&x) => {
                Err(err(name, format!("{x} must be in [0, 1]")))
            }
            Some(x) => Ok(x),
            None => Ok(default),
        }
    };
    let spacing = match l.spacing {
        Some(s) if !s.is_finite() || s <= 0.0 => {
            return Err(err(
                "spacing",
                format!("{s} must be positive (stamp distance as a fraction of the stamp width; 0.1 is dense, 1 puts stamps edge to edge)"),
            ))
        }
        Some(s) => s,
        None => 0.1,
    };
    let orient = match l.orient.as_deref() {
        None | Some("path") => Orient::Path,
        Some("fixed") => Orient::Fixed,
        Some(other) => {
            return Err(err(
                "orient",
                format!("unknown orientation \"{other}\"; use \"path\" or \"fixed\""),
            ))
        }
    };
    let tool = tool(l, &err, size_x)?;
    if let Tool::Clone { source } = &tool {
        check_at(source, &field("source"), src)?;
    }
    if tool.reads_canvas() && mask {
        return Err(err(
            "mask",
            "a blur, smear or clone stroke's shape is its image's alpha; remove `mask` (or bake it into the image's alpha)".into(),
        ));
    }
    // A clone's source stamps are solved at their points; so are its stamps (a pair per block).
    let continuity = l.continuity.unwrap_or(true) && !matches!(tool, Tool::Clone { .. });
    Ok(Stroke {
        tool,
        path,
        interpolate,
        pressure,
        spacing,
        flow: unit("flow", l.flow, 1.0)?,
        pressure_size: unit("pressure_size", l.pressure_size, 1.0)?,
        pressure_flow: unit("pressure_flow", l.pressure_flow, 0.0)?,
        orient,
        continuity,
    })
}

/// The stroke's tool and its fields (`size_x`: the stamp width, for the default blur radius).
fn tool(l: &Fields<'_>, err: &dyn Fn(&str, String) -> Error, size_x: f32) -> Result<Tool> {
    let name = l.tool.as_deref().unwrap_or("paint");
    let misplaced = |f: &str, belongs: &str| {
        err(
            f,
            format!("applies to the \"{belongs}\" tool only (this stroke's tool is \"{name}\")"),
        )
    };
    let only = |allowed: &str| -> Result<()> {
        for (field, given, belongs) in [
            ("radius", l.radius.is_some(), "blur"),
            ("strength", l.strength.is_some(), "smear"),
            ("source", l.source.is_some(), "clone"),
        ] {
            if given && belongs != allowed {
                return Err(misplaced(field, belongs));
            }
        }
        Ok(())
    };
    match name {
        "paint" => {
            only("paint")?;
            Ok(Tool::Paint)
        }
        "blur" => {
            only("blur")?;
            let radius = l.radius.unwrap_or(0.1 * size_x);
            if !radius.is_finite() || radius <= 0.0 {
                return Err(err(
                    "radius",
                    format!("{radius} must be a positive distance on the surface (model units)"),
                ));
            }
            Ok(Tool::Blur { radius })
        }
        "smear" => {
            only("smear")?;
            let strength = l.strength.unwrap_or(0.5);
            if !strength.is_finite() || !(0.0..=1.0).contains(&strength) {
                return Err(err("strength", format!("{strength} must be in [0, 1]")));
            }
            Ok(Tool::Smear { strength })
        }
        "clone" => {
            only("clone")?;
            let Some(source) = l.source.clone() else {
                return Err(err(
                    "source",
                    "missing: a clone stroke needs a `source` point (like `at`)".into(),
                ));
            };
            Ok(Tool::Clone { source })
        }
        other => Err(err(
            "tool",
            format!("unknown tool \"{other}\"; use \"paint\", \"blur\", \"smear\" or \"clone\""),
        )),
    }
}

/// Stamps a stroke may place before it is refused (each stamp is a chart and a draw).
pub const MAX_STAMPS: usize = 20_000;
