// SPDX-License-Identifier: MIT OR Apache-2.0
//! `decalbake param`: a layer's local coordinates per reached vertex, computed as the bake computes
//! them (placement on the GPU, then the layer's map method).

use super::engine::{Engine, LoadedMesh};
use crate::error::{Error, Result};
use crate::io::job::{Job, Method};
use crate::maps::Frame;
use crate::place::{place_gpu, Query};
use glam::Vec3;
use std::collections::HashMap;

/// One row of `decalbake param`: a welded vertex reached by a layer's map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamRow {
    /// Welded vertex id.
    pub vertex: u32,
    /// Position (model units).
    pub position: [f32; 3],
    /// Geodesic distance estimate (|normal coordinates|), where the method computes one.
    pub distance: Option<f32>,
    /// Local coordinates in model units (image +x, image +y), before scaling to the image.
    pub uv: [f32; 2],
}

impl Engine {
    /// The local coordinates of layer `index` of `job` for every vertex its map reaches: for
    /// `expmap` the GPU map's reached vertices (distance = |(u, v)|), for `planar` the vertices of the
    /// triangles the projection covers (no distance).
    pub fn layer_param(&self, mesh: &LoadedMesh, job: &Job, index: usize) -> Result<Vec<ParamRow>> {
        let layer = job.layers.get(index).ok_or_else(|| {
            Error::job(
                &job.source,
                "layers",
                format!(
                    "--layer {index} does not exist: the job has {} layer(s)",
                    job.layers.len()
                ),
            )
        })?;
        let query = match &layer.at {
            crate::io::job::AtSpec::Point(p) => Query::Point(Vec3::from(*p)),
            crate::io::job::AtSpec::Ray { ray } => {
                Query::Ray(Vec3::from(ray.origin), Vec3::from(ray.dir))
            }
        };
        let placement = place_gpu(&self.ctx, &self.pipes, &mesh.gpu, &[query])?[0];
        if placement.found == 0 {
            return Err(Error::Placement {
                path: job.source.clone(),
                layer: index,
                detail: "the ray misses the mesh".into(),
            });
        }
        let frame = Frame::new(&placement, layer);
        let topo = &mesh.topo;
        let mut rows = Vec::new();
        // Every method but planar starts from the layer's exponential map, as in the bake.
        let expmap = match layer.method {
            Method::Planar => Vec::new(),
            _ => {
                let seed = frame.seed(&placement);
                self.expmaps(mesh, &[(seed, frame.expmap_options(layer))])?
                    .remove(0)
                    .0
            }
        };
        match layer.method {
            Method::Expmap => {
                for (v, c) in expmap.iter().enumerate() {
                    if c[3] > 0.5 {
                        rows.push(ParamRow {
                            vertex: v as u32,
                            position: topo.positions[v].to_array(),
                            distance: Some((c[0] * c[0] + c[1] * c[1]).sqrt()),
                            uv: [c[0], c[1]],
                        });
                    }
                }
            }
            Method::Lscm | Method::Hybrid => {
                let hybrid = layer.method == Method::Hybrid;
                let req = crate::maps::chart::ChartRequest::for_layer(
                    frame,
                    placement.triangle,
                    layer,
                    &expmap,
                );
                let chart = crate::maps::chart::build(
                    topo,
                    &[req],
                    &self.solver(),
                    &mut Default::default(),
                )?
                .remove(0);
                let replaces = chart.replaces_map;
                let mut uv: HashMap<u32, [f32; 2]> = chart.coords.into_iter().collect();
                if !replaces {
                    // Vertices the hybrid solve did not move keep their exponential-map position.
                    for (v, c) in expmap.iter().enumerate() {
                        if c[3] > 0.5 {
                            uv.entry(v as u32).or_insert([c[0], c[1]]);
                        }
                    }
                }
                for (v, c) in uv {
                    let distance = hybrid.then(|| {
                        let e = expmap[v as usize];
                        (e[0] * e[0] + e[1] * e[1]).sqrt()
                    });
                    rows.push(ParamRow {
                        vertex: v,
                        position: topo.positions[v as usize].to_array(),
                        distance,
                        uv: c,
                    });
                }
                rows.sort_by_key(|r| r.vertex);
            }
            Method::Planar => {
                let coords = crate::maps::planar::planar_coords(topo, &frame);
                // Selection needs UVs only for the texel box, which param does not use.
                let no_uvs = vec![glam::Vec2::ZERO; mesh.mesh.positions.len()];
                let sel = crate::bake::cpu::select_triangles(
                    &mesh.mesh,
                    topo,
                    &no_uvs,
                    &coords,
                    &frame,
                    true,
                    [1, 1],
                )
                .triangles;
                let mut seen = vec![false; topo.positions.len()];
                for t in sel {
                    for v in topo.triangles[t as usize] {
                        if !std::mem::replace(&mut seen[v as usize], true) {
                            let c = coords[v as usize];
                            rows.push(ParamRow {
                                vertex: v,
                                position: topo.positions[v as usize].to_array(),
                                distance: None,
                                uv: [c[0], c[1]],
                            });
                        }
                    }
                }
                rows.sort_by_key(|r| r.vertex);
            }
        }
        Ok(rows)
    }
}
