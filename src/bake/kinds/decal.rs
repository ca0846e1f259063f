// SPDX-License-Identifier: MIT OR Apache-2.0
//! `"kind": "decal"`: one image placed at one surface point (`at`: a point snapped to the surface,
//! or the first hit of a ray), `size` wide and high, turned by `up` and `angle`.

use super::{placement_problem, query_of, Expansion, Kind, Unit};
use crate::bake::stage::Cx;
use crate::error::{Error, Result};
use crate::io::job::Layer;
use crate::maps::Frame;
use crate::place::{Placement, Query};

/// `"kind": "decal"`.
pub struct Decal;

impl Kind for Decal {
    fn queries(&self, layer: &Layer) -> Vec<Query> {
        vec![query_of(&layer.at)]
    }

    fn expand(
        &self,
        cx: Cx<'_>,
        index: usize,
        placements: &[Placement],
        warnings: &mut Vec<String>,
    ) -> Result<Expansion> {
        let job = cx.job;
        let (l, p) = (&job.layers[index], &placements[0]);
        let reach = l.size[0].max(l.size[1]);
        if let Some(detail) = placement_problem(&l.at, p, (reach, "the decal's size")) {
            return Err(Error::Placement {
                path: job.source.clone(),
                layer: index,
                detail,
            });
        }
        let f = Frame::new(p, l);
        if f.up_fallback {
            warnings.push(format!(
                "layer {index}: `up` is parallel to the surface normal there; used a world axis instead"
            ));
        }
        Ok(Expansion {
            units: vec![Unit::drawn(l.clone(), *p, f)],
            stroke: None,
            blocks: Vec::new(),
        })
    }
}
