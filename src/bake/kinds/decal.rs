// SPDX-License-Identifier: MIT OR Apache-2.0
//! `"kind": "decal"`: one image placed at one surface point (`at`: a point snapped to the surface,
//! or the first hit of a ray), `size` wide and high, turned by `up` and `angle`.

use super::Kind;
use crate::error::{Error, Result};
use crate::io::job::{AtSpec, Job, Layer};
use crate::maps::Frame;
use crate::place::{Placement, Query};
use glam::Vec3;

/// `"kind": "decal"`.
pub struct Decal;

impl Kind for Decal {
    fn query(&self, layer: &Layer) -> Query {
        match &layer.at {
            AtSpec::Point(p) => Query::Point(Vec3::from(*p)),
            AtSpec::Ray { ray } => Query::Ray(Vec3::from(ray.origin), Vec3::from(ray.dir)),
        }
    }

    fn frame(
        &self,
        job: &Job,
        index: usize,
        p: &Placement,
        warnings: &mut Vec<String>,
    ) -> Result<Frame> {
        let l = &job.layers[index];
        if p.found == 0 {
            return Err(Error::Placement {
                path: job.source.clone(),
                layer: index,
                detail: "the ray misses the mesh; aim it at the model (check origin, direction and the model's units in `decalbake info`)".into(),
            });
        }
        let reach = l.size[0].max(l.size[1]);
        if let AtSpec::Point(at) = l.at {
            if p.distance > reach {
                return Err(Error::Placement {
                    path: job.source.clone(),
                    layer: index,
                    detail: format!(
                        "the point {at:?} is {:.4} from the surface, farther than the decal's size {reach:.4}; place it on the mesh (its bounding box is in `decalbake info`) or use a ray",
                        p.distance,
                    ),
                });
            }
        }
        let f = Frame::new(p, l);
        if f.up_fallback {
            warnings.push(format!(
                "layer {index}: `up` is parallel to the surface normal there; used a world axis instead"
            ));
        }
        Ok(f)
    }
}
