// SPDX-License-Identifier: MIT OR Apache-2.0
//! `decalbake param`: a layer's local coordinates per reached vertex, computed as the bake computes
//! them (placement on the GPU, then the layer's map method).

use super::engine::{Engine, LoadedMesh};
use crate::error::{Error, Result};
use crate::io::job::{Job, Method};
use crate::maps::chart::cone::Cone;
use crate::maps::distortion::Distortion;
use crate::maps::Frame;
use crate::mesh::Topology;
use crate::place::{place_gpu, Query};
use glam::{DVec2, DVec3, Vec3};
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
    /// A chart opened at a tip ([`crate::maps::chart::cone`]): the uncut chart's coordinates, which
    /// the bake carries over each triangle and opens per texel (`uv` is this vertex's image through
    /// the cone). Equal to `uv` for every other map.
    pub chart_uv: [f32; 2],
}

/// A layer's `param` rows and the cone its chart was opened by, if any.
pub type ParamMap = (Vec<ParamRow>, Option<Cone>);

impl Engine {
    /// The local coordinates of layer `index` of `job` for every vertex its map reaches: for
    /// `expmap` the GPU map's reached vertices (distance = |(u, v)|), for `planar` the vertices of the
    /// triangles the projection covers (no distance).
    pub fn layer_param(&self, mesh: &LoadedMesh, job: &Job, index: usize) -> Result<Vec<ParamRow>> {
        Ok(self.layer_param_map(mesh, job, index)?.0)
    }

    /// [`Engine::layer_param`] with the cone that opens the layer's chart at a tip, if any.
    pub fn layer_param_map(&self, mesh: &LoadedMesh, job: &Job, index: usize) -> Result<ParamMap> {
        Ok(self.layer_param_framed(mesh, job, index)?.0)
    }

    /// A decal layer's `param` rows with the footprint counts the bake reports for it
    /// (`footprint_flipped`, `footprint_collapsed`, `footprint_torn`, in a [`Distortion`]): the
    /// triangles the bake's selection keeps (the CPU twin of `select_triangles` over the rows'
    /// coordinates), measured by the twin of `distortion.wgsl`. `None` for a ribbon.
    pub fn layer_param_footprint(
        &self,
        mesh: &LoadedMesh,
        job: &Job,
        index: usize,
    ) -> Result<(Vec<ParamRow>, Option<Distortion>)> {
        let ((rows, cone), frame) = self.layer_param_framed(mesh, job, index)?;
        let Some(frame) = frame else {
            return Ok((rows, None));
        };
        let mut coords = vec![[0.0f32, 0.0, 0.0, 0.0]; mesh.topo.positions.len()];
        for r in &rows {
            coords[r.vertex as usize] = [r.chart_uv[0], r.chart_uv[1], 0.0, 1.0];
        }
        let planar = job.layers[index].method == Method::Planar;
        let no_uvs = vec![glam::Vec2::ZERO; mesh.mesh.positions.len()];
        let tris = crate::bake::cpu::select_triangles(
            &mesh.mesh,
            &mesh.topo,
            &no_uvs,
            (&coords, cone.as_ref()),
            &frame,
            planar,
            [1, 1],
        )
        .triangles;
        let d = crate::maps::distortion::distortion(&mesh.topo, (&coords, cone.as_ref()), &tris);
        Ok((rows, Some(d)))
    }

    /// [`Engine::layer_param_map`] with the decal's frame (`None` for a ribbon).
    fn layer_param_framed(
        &self,
        mesh: &LoadedMesh,
        job: &Job,
        index: usize,
    ) -> Result<(ParamMap, Option<Frame>)> {
        let layer = job.layer_at(index)?;
        match layer.kind {
            crate::io::job::LayerKind::Decal => {}
            crate::io::job::LayerKind::Ribbon => {
                return Ok(((self.ribbon_param(mesh, job, index)?, None), None))
            }
            crate::io::job::LayerKind::Stroke => {
                return Err(Error::job(
                    &job.source,
                    format!("layers[{index}].kind"),
                    "`decalbake param` exports a decal's or a ribbon's map; this layer is a stroke (its stamps' charts are in the bake report)",
                ))
            }
        }
        let query = match &layer.at {
            crate::io::job::AtSpec::Point(p) => Query::Point(Vec3::from(*p)),
            crate::io::job::AtSpec::Ray { ray } => {
                Query::Ray(Vec3::from(ray.origin), Vec3::from(ray.dir))
            }
        };
        let placement = crate::place::with_shading_normal(
            &mesh.mesh,
            place_gpu(&self.ctx, &self.pipes, &mesh.gpu, &[query])?[0],
        );
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
        let mut cone = None;
        // Every method but planar starts from the layer's exponential map, as in the bake.
        let expmap = match layer.method {
            Method::Planar | Method::Ribbon => Vec::new(),
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
                            chart_uv: [c[0], c[1]],
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
                if let Some(e) = super::maps::chart_error(job, index, &chart.report) {
                    return Err(e);
                }
                let replaces = chart.replaces_map;
                cone = chart.cone();
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
                    // Hybrid: the exponential map's distance where the map reached the vertex (a
                    // hybrid re-solved as a free chart can reach beyond it).
                    let e = expmap[v as usize];
                    let distance =
                        (hybrid && e[3] > 0.5).then(|| (e[0] * e[0] + e[1] * e[1]).sqrt());
                    rows.push(ParamRow {
                        vertex: v,
                        position: topo.positions[v as usize].to_array(),
                        distance,
                        // Per vertex through the cone; the bake opens the cut's triangles per texel.
                        uv: cone.map_or(c, |k| {
                            k.apply(DVec2::new(c[0] as f64, c[1] as f64))
                                .as_vec2()
                                .to_array()
                        }),
                        chart_uv: c,
                    });
                }
                rows.sort_by_key(|r| r.vertex);
            }
            // Ribbon layers are refused above (their kind).
            Method::Ribbon => {}
            Method::Planar => rows = planar_rows(mesh, &frame),
        }
        Ok(((rows, cone), Some(frame)))
    }

    /// A ribbon layer's map as a bake computes it: its curve placed and joined, the extended
    /// exponential map on the GPU and the repair of its highly curved parts; per welded vertex
    /// (u, v, graph distance, 1 where reached), u along the curve from its start and v across it
    /// in model units; with the layer's unit (its curve and image mapping) and its size
    /// ([length, width]).
    pub fn ribbon_map(
        &self,
        mesh: &LoadedMesh,
        job: &Job,
        index: usize,
    ) -> Result<(
        Vec<[f32; 4]>,
        crate::bake::kinds::ribbon::RibbonUnit,
        [f32; 2],
    )> {
        let units = self.units(mesh, job)?;
        let unit = units
            .origin
            .iter()
            .position(|o| o.0 == index)
            .expect("every layer has a unit");
        let r = units.ribbons[unit]
            .clone()
            .expect("a ribbon layer's unit carries its curve");
        let (mut coords, _) = crate::maps::ribbon::gpu::ribbon_gpu(
            &self.ctx,
            &self.pipes,
            mesh.surface_ref(),
            &r.curve,
            r.reach,
        )?;
        crate::maps::ribbon::repair::repair_coords(
            &mesh.topo,
            (&r.curve, r.sides, r.lambda),
            &mut coords,
            [1.0, 0.0, 1.0, 0.0],
            crate::maps::ribbon::repair::solve_gpu(&self.ctx, &self.pipes),
        )?;
        Ok((coords, r, units.job.layers[unit].size))
    }

    /// A ribbon layer's `param` rows ([`Engine::ribbon_map`]): one per vertex it reaches,
    /// distance = |v|.
    fn ribbon_param(&self, mesh: &LoadedMesh, job: &Job, index: usize) -> Result<Vec<ParamRow>> {
        let (coords, _, _) = self.ribbon_map(mesh, job, index)?;
        let topo = &mesh.topo;
        Ok(coords
            .iter()
            .enumerate()
            .filter(|(_, c)| c[3] > 0.5)
            .map(|(v, c)| ParamRow {
                vertex: v as u32,
                position: topo.positions[v].to_array(),
                distance: Some(c[1].abs()),
                uv: [c[0], c[1]],
                chart_uv: [c[0], c[1]],
            })
            .collect())
    }
}

/// What a layer's coordinates say about its size, the way `decalbake bench --scale` and the tests
/// measure it (independently of the engine's own chart report).
#[derive(Debug, Clone, Copy)]
pub struct SizeFigures {
    /// Median of |(u, v)| / |x − p| over the reached vertices within half the size of `p`.
    pub scale_half: f64,
    /// The same within 0.2 × the size.
    pub scale_fifth: f64,
    /// Triangles whose (u, v) meet the decal's square.
    pub footprint: usize,
    /// Of those, flipped (negative signed (u, v) area: the maps keep the surface's orientation).
    pub flipped: usize,
    /// Of those not flipped, collapsed (area ratio below 1e-3 of the median over the map).
    pub collapsed: usize,
    /// Of those, torn (area ratio above 1e3 times the median: stretched across a cut).
    pub torn: usize,
    /// Surface area whose (u, v) fall inside the square (15 × 15 barycentric samples a triangle).
    pub painted_area: f64,
}

/// [`SizeFigures`] of a square decal of side `size` placed at `p`, from its `param` rows (and the
/// cone of its chart: the cut's triangles are sampled through it, as the bake draws them, and left
/// out of the fold counts, as the chart's own check does).
pub fn size_figures(topo: &Topology, map: &ParamMap, p: DVec3, size: f64) -> SizeFigures {
    let (rows, cone) = (&map.0, map.1.as_ref());
    let uv: HashMap<u32, DVec2> = rows
        .iter()
        .map(|r| (r.vertex, DVec2::new(r.uv[0] as f64, r.uv[1] as f64)))
        .collect();
    let chart: HashMap<u32, DVec2> = rows
        .iter()
        .map(|r| {
            (
                r.vertex,
                DVec2::new(r.chart_uv[0] as f64, r.chart_uv[1] as f64),
            )
        })
        .collect();
    let scale = |radius: f64| {
        let mut s: Vec<f64> = rows
            .iter()
            .filter_map(|r| {
                let d = (DVec3::from(r.position.map(f64::from)) - p).length();
                (d > 1e-9 * size && d <= radius).then(|| uv[&r.vertex].length() / d)
            })
            .collect();
        s.sort_by(f64::total_cmp);
        s.get(s.len() / 2).copied().unwrap_or(f64::NAN)
    };
    let h = 0.5 * size;
    let mut ratios = Vec::new();
    let mut foot = Vec::new();
    let mut painted = 0.0;
    for tri in &topo.triangles {
        let Some(z) = tri
            .iter()
            .map(|v| uv.get(v).copied())
            .collect::<Option<Vec<_>>>()
        else {
            continue;
        };
        let x = tri.map(|v| topo.positions[v as usize].as_dvec3());
        let area3 = 0.5 * (x[1] - x[0]).cross(x[2] - x[0]).length();
        if area3 <= 0.0 {
            continue;
        }
        let w = tri.map(|v| chart[&v]);
        let cut = cone.is_some_and(|c| c.cut_crosses(w));
        // A point of the triangle's image, as the bake computes it per texel.
        let at = |a: f64, b: f64| match cone {
            Some(c) => c.apply(w[0] + a * (w[1] - w[0]) + b * (w[2] - w[0])),
            None => z[0] + a * (z[1] - z[0]) + b * (z[2] - z[0]),
        };
        let area2 = 0.5 * (z[1] - z[0]).perp_dot(z[2] - z[0]);
        if !cut {
            ratios.push(area2.abs() / area3);
            let lo = z[0].min(z[1]).min(z[2]);
            let hi = z[0].max(z[1]).max(z[2]);
            if hi.x < -h || lo.x > h || hi.y < -h || lo.y > h {
                continue;
            }
            foot.push((area2, area3));
        }
        // Painted area: the fraction of 15 × 15 barycentric samples inside the rectangle.
        let n = 15;
        let mut inside = 0;
        let mut total = 0;
        for i in 0..n {
            for j in 0..n - i {
                let (a, b) = (
                    (i as f64 + 1.0 / 3.0) / n as f64,
                    (j as f64 + 1.0 / 3.0) / n as f64,
                );
                let q = at(a, b);
                total += 1;
                inside += usize::from(q.x.abs() <= h && q.y.abs() <= h);
            }
        }
        painted += area3 * inside as f64 / total as f64;
    }
    ratios.sort_by(f64::total_cmp);
    let median = ratios.get(ratios.len() / 2).copied().unwrap_or(0.0);
    SizeFigures {
        scale_half: scale(0.5 * size),
        scale_fifth: scale(0.2 * size),
        footprint: foot.len(),
        flipped: foot.iter().filter(|(a2, _)| *a2 < 0.0).count(),
        collapsed: foot
            .iter()
            .filter(|(a2, a3)| *a2 >= 0.0 && a2 / a3 < 1e-3 * median)
            .count(),
        torn: foot
            .iter()
            .filter(|(a2, a3)| a2.abs() / a3 > 1e3 * median)
            .count(),
        painted_area: painted,
    }
}

/// A planar layer's rows: the vertices of the triangles its projection covers (no distance), in
/// vertex order.
fn planar_rows(mesh: &LoadedMesh, frame: &Frame) -> Vec<ParamRow> {
    let topo = &mesh.topo;
    let coords = crate::maps::planar::planar_coords(topo, frame);
    // Selection needs UVs only for the texel box, which param does not use.
    let no_uvs = vec![glam::Vec2::ZERO; mesh.mesh.positions.len()];
    let sel = crate::bake::cpu::select_triangles(
        &mesh.mesh,
        topo,
        &no_uvs,
        (&coords, None),
        frame,
        true,
        [1, 1],
    )
    .triangles;
    let mut seen = vec![false; topo.positions.len()];
    let mut rows = Vec::new();
    for t in sel {
        for v in topo.triangles[t as usize] {
            if !std::mem::replace(&mut seen[v as usize], true) {
                let c = coords[v as usize];
                rows.push(ParamRow {
                    vertex: v,
                    position: topo.positions[v as usize].to_array(),
                    distance: None,
                    uv: [c[0], c[1]],
                    chart_uv: [c[0], c[1]],
                });
            }
        }
    }
    rows.sort_by_key(|r| r.vertex);
    rows
}
