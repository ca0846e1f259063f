// SPDX-License-Identifier: MIT OR Apache-2.0
//! A layer's `warp` field: pairs of image points `[from, to]` in [0, 1]² that deform how the image
//! is laid on the surface by a thin-plate spline (Schmidt et al. 2006, section 6.1; Sun et al. 2013,
//! section 4.4). The image content at `from` appears at `to`; the image's four corners stay where
//! they are unless a pair moves one (its `to` lies on the corner). Allowed on decals, strokes (every
//! stamp) and ribbons. The spline itself is [`crate::maps::warp::Tps`].

use crate::error::{Error, Result};
use std::path::Path;

/// The most pairs a layer may give (the spline is a dense solve on the CPU and a per-fragment sum
/// on the GPU: 32 + 4 corner centres is under 40 kernel terms per sample).
pub const MAX_WARP_PAIRS: usize = 32;

/// Two `to` points closer than this (in image units) would make the spline's system singular or
/// its deformation a fold.
pub const MIN_WARP_SPACING: f32 = 1e-3;

/// Validates layer `i`'s warp pairs; `src` names the job file in messages.
pub(crate) fn validate(
    warp: &Option<Vec<[[f32; 2]; 2]>>,
    i: usize,
    src: &Path,
) -> Result<Vec<[[f32; 2]; 2]>> {
    let Some(pairs) = warp else {
        return Ok(Vec::new());
    };
    let err = |k: Option<usize>, detail: String| {
        let at = k.map_or(String::new(), |k| format!("[{k}]"));
        Error::job(src, format!("layers[{i}].warp{at}"), detail)
    };
    if pairs.len() > MAX_WARP_PAIRS {
        return Err(err(
            None,
            format!(
                "has {} pairs; at most {MAX_WARP_PAIRS} are allowed",
                pairs.len()
            ),
        ));
    }
    for (k, pair) in pairs.iter().enumerate() {
        let inside = pair
            .iter()
            .flatten()
            .all(|x| x.is_finite() && (0.0..=1.0).contains(x));
        if !inside {
            return Err(err(
                Some(k),
                format!(
                    "{pair:?}: both points of a [from, to] pair must be image coordinates in [0, 1]²"
                ),
            ));
        }
        for (j, other) in pairs[..k].iter().enumerate() {
            let d = (pair[1][0] - other[1][0]).hypot(pair[1][1] - other[1][1]);
            if d < MIN_WARP_SPACING {
                return Err(err(
                    Some(k),
                    format!(
                        "its target {:?} is {d:.1e} from warp[{j}]'s; targets must be at least \
                         {MIN_WARP_SPACING} apart (one image point cannot go to two places)",
                        pair[1]
                    ),
                ));
            }
        }
    }
    Ok(pairs.clone())
}
