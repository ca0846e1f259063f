// SPDX-License-Identifier: MIT OR Apache-2.0
//! `"kind": "ribbon"`: an image laid along a surface curve (Sun et al. 2013, "Texture Brush",
//! section 3). The path's points are joined along the surface as a stroke's are
//! ([`super::stroke::join_path`]), and the strip around the curve is mapped by the curve's
//! extended exponential map ([`crate::maps::ribbon`], computed in the map stage's ribbon pass,
//! `bake/maps.rs`): u along the curve, v across it. The layer is one unit whose image rectangle is
//! the curve's length × `width`; `"repeat": "tile"` repeats the image along the curve at its own
//! aspect (the raster wraps the image coordinate, `FLAG_REPEAT` in `wgsl/bake/layer_raster.wgsl`).

use super::{placement_problem, query_of, Expansion, Kind, Unit};
use crate::bake::stage::Cx;
use crate::error::{Error, Result};
use crate::io::job::Layer;
use crate::io::ribbon::{Align, Repeat};
use crate::maps::ribbon::Curve;
use crate::maps::Frame;
use crate::place::{Placement, Query};
use glam::Vec3;

/// `"kind": "ribbon"`.
pub struct RibbonKind;

/// What the map stage needs of a ribbon unit.
#[derive(Debug, Clone)]
pub struct RibbonUnit {
    /// The curve on the surface.
    pub curve: Curve,
    /// Graph distance the map spreads to from the curve: the strip's far edge, with a margin.
    pub reach: f32,
    /// The unit's coordinates from the map's (u, v): x = a u + b, y = c v + d, as (a, b, c, d).
    pub xform: [f32; 4],
    /// Copies of the image along the curve (`"repeat": "tile"`); 0 for one stretched copy.
    pub repeats: f32,
}

impl Kind for RibbonKind {
    fn queries(&self, layer: &Layer) -> Vec<Query> {
        let r = layer
            .ribbon
            .as_ref()
            .expect("a ribbon layer has its ribbon");
        r.path.iter().map(query_of).collect()
    }

    fn expand(
        &self,
        cx: Cx<'_>,
        index: usize,
        placements: &[Placement],
        _warnings: &mut Vec<String>,
    ) -> Result<Expansion> {
        let Cx { mesh, job, .. } = cx;
        let layer = &job.layers[index];
        let r = layer
            .ribbon
            .as_ref()
            .expect("a ribbon layer has its ribbon");
        let err = |detail: String| Error::Placement {
            path: job.source.clone(),
            layer: index,
            detail,
        };
        let diag = (Vec3::from(mesh.stats.bbox_max) - Vec3::from(mesh.stats.bbox_min)).length();
        let near = r.width.unwrap_or(0.05 * diag);
        for (k, (at, p)) in r.path.iter().zip(placements).enumerate() {
            if let Some(why) = placement_problem(at, p, (near, "the ribbon's width")) {
                return Err(err(format!("path[{k}]: {why}")));
            }
        }
        let limit = super::stroke::path::MAX_SEGMENT_FRACTION * diag;
        for (k, w) in placements.windows(2).enumerate() {
            let chord = (Vec3::from(w[1].point) - Vec3::from(w[0].point)).length();
            if chord > limit {
                return Err(err(format!(
                    "path[{k}] and path[{}] are {chord:.4} apart, more than one chart can join ({limit:.4}, half the model's size); add points in between",
                    k + 1
                )));
            }
        }
        let edge = super::stroke::path::mean_edge(&mesh.topo);
        let path = super::stroke::join_path(cx, placements, edge, &err)?;
        let length = path.length();
        if length <= 0.0 {
            return Err(err(
                "the path's points are all at one place; a ribbon needs a curve".into(),
            ));
        }
        let (iw, ih) = image::image_dimensions(&layer.image).map_err(|e| {
            Error::job(
                &job.source,
                format!("layers[{index}].image"),
                format!("{}: {e}", layer.image.display()),
            )
        })?;
        let aspect = ih as f32 / iw.max(1) as f32;
        let width = r.width.unwrap_or(aspect * length);
        let ribbon = mapping(
            r,
            length,
            width,
            aspect,
            edge,
            Curve {
                points: path.points,
                triangles: path.triangles,
            },
        );
        let mut unit_layer = layer.clone();
        unit_layer.size = [length, width];
        let frame = Frame::new(&placements[0], &unit_layer);
        Ok(Expansion {
            units: vec![Unit {
                ribbon: Some(ribbon),
                ..Unit::drawn(unit_layer, placements[0], frame)
            }],
            stroke: None,
            blocks: Vec::new(),
        })
    }
}

/// How the map's (u, v) become the unit's coordinates, whose image rectangle is `length` ×
/// `width` centred at the origin: x = u − length / 2; y = ±(v − the strip's middle), the sign
/// negative when `flip`; the strip's middle is on the curve (`center`), `width` / 2 to its left
/// (`left`, along N × T) or right. `aspect`: the image's height / width (a tiled copy is `width` /
/// `aspect` long). The map reaches the strip's far edge plus two mean edges (its graph distances
/// run a little long, and the selection needs whole triangles).
fn mapping(
    r: &crate::io::ribbon::Ribbon,
    length: f32,
    width: f32,
    aspect: f32,
    edge: f32,
    curve: Curve,
) -> RibbonUnit {
    let middle = match r.align {
        Align::Center => 0.0,
        Align::Left => 0.5 * width,
        Align::Right => -0.5 * width,
    };
    let sign = if r.flip { -1.0 } else { 1.0 };
    let far = middle.abs() + 0.5 * width;
    RibbonUnit {
        curve,
        reach: 1.2 * far + 2.0 * edge,
        xform: [1.0, -0.5 * length, sign, -sign * middle],
        repeats: match r.repeat {
            Repeat::Stretch => 0.0,
            Repeat::Tile => length * aspect / width,
        },
    }
}
