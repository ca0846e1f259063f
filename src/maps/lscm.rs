// SPDX-License-Identifier: MIT OR Apache-2.0
//! `"method": "lscm"`: a local least-squares conformal chart around the placed point (Maillot,
//! "Continuous Local Parameterization of Polygons", sections 4, 6 and 9), warm-started from the
//! layer's exponential map and solved in the map stage's batched chart pass. The chart machinery
//! (selection, refinement, normalisation) is [`crate::maps::chart`].

use super::chart::{ChartKind, ChartRequest};
use super::{Frame, MapMethod};
use crate::io::job::Layer;

/// `"method": "lscm"`.
pub struct Lscm;

impl MapMethod for Lscm {
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
            kind: ChartKind::Lscm,
            max_iter: layer.cg_max_iterations,
            warm: Some(expmap),
            cone: true,
        })
    }
}
