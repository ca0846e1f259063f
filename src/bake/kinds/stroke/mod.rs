// SPDX-License-Identifier: MIT OR Apache-2.0
//! `"kind": "stroke"`: stamps of an image along a path on the surface (Maillot, "Continuous Local
//! Parameterization of Polygons", sections 7 to 9). Each stamp is a small decal with its own chart
//! at its point (the layer's `method`, LSCM by default as in Maillot), so its width on the surface
//! is the size asked for wherever the UV layout stretches, and it continues across UV seams because
//! it is drawn through the mesh's own UVs.
//!
//! The stroke's path follows the surface between its points ([`path`]); stamps go every `spacing`
//! × stamp width of arc length with pressure ([`stamps`]). They build up in the stroke's own
//! buffer, each with alpha `flow` (source-over), and the buffer is composed onto the layers below
//! with the stroke's `blend` at `opacity` × its alpha, so overlapping stamps of one stroke never
//! exceed `opacity` (a painter's stroke; `bake/compose.rs`, kernel `stroke_apply`).

pub mod clone;
pub mod continuity;
pub mod path;
pub mod spline;
pub mod stamps;

use super::{placement_problem, query_of, Expansion, Kind};
pub use crate::bake::report::StrokeReport;
use crate::bake::stage::Cx;
use crate::error::{Error, Result};
use crate::io::job::Layer;
use crate::io::stroke::Interpolate;
use crate::maps::expmap::cpu::{Options, Seed};
use crate::place::{Placement, Query};
use glam::Vec3;

/// `"kind": "stroke"`.
pub struct StrokeKind;

impl Kind for StrokeKind {
    fn queries(&self, layer: &Layer) -> Vec<Query> {
        let stroke = layer
            .stroke
            .as_ref()
            .expect("a stroke layer has its stroke");
        let source = match &stroke.tool {
            crate::io::job::Tool::Clone { source } => Some(query_of(source)),
            _ => None,
        };
        stroke.path.iter().map(query_of).chain(source).collect()
    }

    fn expand(
        &self,
        cx: Cx<'_>,
        index: usize,
        placements: &[Placement],
        warnings: &mut Vec<String>,
    ) -> Result<Expansion> {
        let Cx { mesh, job, .. } = cx;
        let layer = &job.layers[index];
        let stroke = layer
            .stroke
            .as_ref()
            .expect("a stroke layer has its stroke");
        let err = |detail: String| Error::Placement {
            path: job.source.clone(),
            layer: index,
            detail,
        };
        check_points(layer, placements, &err)?;
        let (placements, source) = placements.split_at(stroke.path.len());
        let topo = &mesh.topo;
        let edge = path::mean_edge(topo);
        let (lo, hi) = (mesh.stats.bbox_min, mesh.stats.bbox_max);
        let diag = (Vec3::from(hi) - Vec3::from(lo)).length();
        let limit = path::MAX_SEGMENT_FRACTION * diag;
        let mut chord_length = 0.0;
        for (k, w) in placements.windows(2).enumerate() {
            let chord = (Vec3::from(w[1].point) - Vec3::from(w[0].point)).length();
            chord_length += chord;
            if chord > limit {
                return Err(err(format!(
                    "path[{k}] and path[{}] are {chord:.4} apart, more than one chart can join ({limit:.4}, half the model's size); add points in between",
                    k + 1
                )));
            }
        }
        let surface_path = join_path(cx, (placements, stroke.interpolate), edge, &err)?;
        let units = stamps::stamps(mesh, layer, stroke, &surface_path, &placements[0], &err)?;
        let stamps = units.len();
        let (units, pairs) = match source.first() {
            Some(src) => {
                let sources = clone::sources(mesh, &units, src, edge, &err)?;
                // Each stamp follows its source, in one block (one chunk flattens both).
                let mut out = Vec::with_capacity(2 * units.len());
                for (s, mut u) in sources.into_iter().zip(units) {
                    u.clone_of = Some(out.len());
                    out.push(s);
                    out.push(u);
                }
                let pairs: Vec<_> = (0..stamps).map(|k| 2 * k..2 * k + 2).collect();
                (out, Some(pairs))
            }
            None => (units, None),
        };
        let capacity = crate::bake::stage::unit_capacity(mesh);
        let fits = capacity > crate::maps::stamp::MAX_CHARTS;
        if stroke.continuity && !fits {
            warnings.push(format!(
                "layer {index}: a stamp and its {} corner charts do not fit one chunk on this mesh ({capacity} units); the stroke uses one chart per stamp (\"continuity\": false)",
                crate::maps::stamp::MAX_CHARTS
            ));
        }
        let continuity = stroke.continuity && fits;
        let (units, blocks, charts) = if continuity {
            let c = continuity::interpolate(topo, layer, units, capacity, edge);
            (c.units, c.blocks, c.charts)
        } else {
            let charts = units.len();
            (units, pairs.unwrap_or_default(), charts)
        };
        Ok(Expansion {
            blocks,
            stroke: Some(StrokeReport {
                tool: stroke.tool.clone(),
                path_points: stroke.path.len(),
                path_length: surface_path.length(),
                chord_length,
                path_vertices: surface_path.points.len(),
                stamps,
                spacing: stroke.spacing * layer.size[0],
                charts,
                cg_iterations: 0,
                continuity,
                opacity: layer.opacity,
            }),
            units,
        })
    }
}

/// Segments whose charts are computed in one GPU batch and walked before the next batch (a chart is
/// a full-mesh slot when read back: the batch bounds the memory a long path holds).
const SEGMENT_BATCH: usize = 16;

/// The path through `placements` on the surface: the geodesics between consecutive points
/// ([`geodesic_path`]), and for `"catmull-rom"` the smooth curve through the points laid along
/// them ([`spline::smooth`]).
pub(crate) fn join_path(
    cx: Cx<'_>,
    (placements, interpolate): (&[Placement], Interpolate),
    edge: f32,
    err: &dyn Fn(String) -> Error,
) -> Result<path::SurfacePath> {
    let joined = geodesic_path(cx, placements, edge, err)?;
    Ok(match interpolate {
        Interpolate::Linear => joined,
        Interpolate::CatmullRom => {
            let points: Vec<Vec3> = placements.iter().map(|p| Vec3::from(p.point)).collect();
            spline::smooth(&cx.mesh.topo, &joined, &points, 0.25 * edge)
        }
    })
}

/// The geodesics between consecutive placements: each segment's exponential map on the GPU (in
/// batches of [`SEGMENT_BATCH`]), walked back to the surface ([`path::extend`]).
fn geodesic_path(
    cx: Cx<'_>,
    placements: &[Placement],
    edge: f32,
    err: &dyn Fn(String) -> Error,
) -> Result<path::SurfacePath> {
    let (engine, mesh) = (cx.engine, cx.mesh);
    let topo = &mesh.topo;
    let mut surface_path = path::SurfacePath::start(&placements[0]);
    let segments: Vec<usize> = (0..placements.len().saturating_sub(1)).collect();
    for batch in segments.chunks(SEGMENT_BATCH) {
        let wanted: Vec<(Seed, Options)> = batch
            .iter()
            .filter(|&&k| placements[k].point != placements[k + 1].point)
            .map(|&k| path::segment_map(topo, &placements[k], &placements[k + 1], edge))
            .collect();
        let mut charts = engine.expmaps(mesh, &wanted)?.into_iter();
        for &k in batch {
            let chart = (placements[k].point != placements[k + 1].point)
                .then(|| charts.next().expect("one chart per moving segment").0);
            path::extend(
                topo,
                (k, &placements[k], &placements[k + 1]),
                chart,
                0.25 * edge,
                &mut surface_path,
                err,
            )?;
        }
    }
    Ok(surface_path)
}

/// Every path point (and a clone's `source`, after them in `placements`) was placed near the
/// surface.
fn check_points(
    layer: &Layer,
    placements: &[Placement],
    err: &dyn Fn(String) -> Error,
) -> Result<()> {
    let stroke = layer
        .stroke
        .as_ref()
        .expect("a stroke layer has its stroke");
    let reach = (layer.size[0].max(layer.size[1]), "the stamp size");
    let source = match &stroke.tool {
        crate::io::job::Tool::Clone { source } => Some(("`source`".to_string(), source)),
        _ => None,
    };
    let named = stroke
        .path
        .iter()
        .enumerate()
        .map(|(k, at)| (format!("path[{k}]"), at))
        .chain(source);
    for ((name, at), p) in named.zip(placements) {
        if let Some(why) = placement_problem(at, p, reach) {
            return Err(err(format!("{name}: {why}")));
        }
    }
    Ok(())
}
