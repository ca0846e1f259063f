// SPDX-License-Identifier: MIT OR Apache-2.0
//! `"method": "hybrid"`: the exponential map with its most distorted triangles (σ1/σ2 above the
//! layer's `hybrid_threshold`, with two rings around them) re-solved conformally, the rest held
//! (Schmidt, Grimm & Wyvill 2006, section 5.1). Solved in the map stage's batched chart pass; the
//! vertices the chart does not move keep their exponential-map coordinates.

use super::chart::{ChartKind, ChartRequest};
use super::{Frame, MapMethod};
use crate::io::job::Layer;

/// `"method": "hybrid"`.
pub struct Hybrid;

impl MapMethod for Hybrid {
    fn uses_expmap(&self) -> bool {
        true
    }

    fn solves_chart(&self) -> bool {
        true
    }

    fn chart<'a>(
        &self,
        layer: &Layer,
        frame: Frame,
        triangle: u32,
        expmap: &'a [[f32; 4]],
    ) -> Option<ChartRequest<'a>> {
        Some(ChartRequest {
            frame,
            triangle,
            kind: ChartKind::Hybrid {
                expmap,
                threshold: layer.hybrid_threshold,
            },
            max_iter: layer.cg_max_iterations,
            warm: None,
            cone: true,
        })
    }
}
