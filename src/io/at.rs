// SPDX-License-Identifier: MIT OR Apache-2.0
//! Where something goes on the surface: a point snapped to it or a ray (a decal's `at`, a stroke's
//! path points).

use crate::error::{Error, Result};
use serde::Deserialize;
use std::path::Path;

/// Largest decal or texture value accepted before "absurd": guards against typos such as 1e30.
pub const MAX_SIZE_MODEL_UNITS: f32 = 1.0e6;

/// Where a layer goes.
#[derive(Debug, Clone, Deserialize, serde::Serialize, PartialEq, schemars::JsonSchema)]
#[serde(untagged, deny_unknown_fields)]
pub enum AtSpec {
    /// A point, snapped to the closest surface point.
    Point([f32; 3]),
    /// A ray; the first hit is used.
    Ray {
        /// A ray, usually from outside the model; its first hit on the surface is used.
        ray: RaySpec,
    },
}

/// A ray.
#[derive(Debug, Clone, Deserialize, serde::Serialize, PartialEq, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RaySpec {
    /// The ray's origin, model units.
    pub origin: [f32; 3],
    /// The ray's direction (need not be unit length).
    pub dir: [f32; 3],
}

/// Checks a placement (`at`, or a stroke's path point) for finite values and a non-zero ray;
/// `field` names it in the message.
pub(crate) fn check_at(at: &AtSpec, field: &str, src: &Path) -> Result<()> {
    let finite3 = |v: &[f32; 3]| v.iter().all(|x| x.is_finite() && x.abs() <= 1e30);
    match at {
        AtSpec::Point(p) if !finite3(p) => {
            Err(Error::job(src, field, format!("point {p:?} is not finite")))
        }
        AtSpec::Ray { ray } if !finite3(&ray.origin) || !finite3(&ray.dir) => Err(Error::job(
            src,
            format!("{field}.ray"),
            "origin and dir must be finite",
        )),
        AtSpec::Ray { ray } if ray.dir.iter().map(|x| x * x).sum::<f32>() <= 1e-20 => Err(
            Error::job(src, format!("{field}.ray.dir"), "the ray direction is zero"),
        ),
        _ => Ok(()),
    }
}
