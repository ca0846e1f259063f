// SPDX-License-Identifier: MIT OR Apache-2.0
//! Layer kinds: what each kind of job layer (`"kind"` in the job) contributes to the bake's stages,
//! one module per kind behind `Kind`, dispatched in one place (`kind`).
//!
//! A kind names the surface points its layer needs placed (`Kind::queries`: a decal one, a stroke
//! one per path point) and turns their placements into **units** (`Kind::expand`): each unit is
//! one map, one image and one blend, which the map, selection, raster and compose stages treat
//! alike. A decal is one unit; a stroke is one unit per stamp, composed through the stroke's own
//! buffer ([`Expansion::stroke`], `bake/compose.rs`). See `ARCHITECTURE.md`, "Layer kinds".

mod decal;
pub mod ribbon;
pub mod stroke;

use super::stage::Cx;
use crate::error::Result;
use crate::io::job::{Layer, LayerKind};
use crate::maps::Frame;
use crate::place::{Placement, Query};

/// One map, one image and one blend: what the stages after placement draw.
#[derive(Debug, Clone)]
pub struct Unit {
    /// The unit as a decal layer (its size, method, opacity and blend are what is drawn).
    pub layer: Layer,
    /// Where it sits.
    pub placement: Placement,
    /// Its frame there.
    pub frame: Frame,
    /// A chart other units blend from, not drawn itself (continuous strokes).
    pub hidden: bool,
    /// Coordinates blended from other units' charts instead of solved (continuous strokes; chart
    /// unit indices are within the layer's units).
    pub blend: Option<crate::maps::stamp::StampBlend>,
    /// A clone stroke's source stamp: selected and flattened, not drawn.
    pub source: bool,
    /// A clone stamp: its source unit (within the layer's units).
    pub clone_of: Option<usize>,
    /// A ribbon: its curve and how its map becomes image coordinates.
    pub ribbon: Option<ribbon::RibbonUnit>,
}

impl Unit {
    /// A drawn unit whose map its method solves.
    pub fn drawn(layer: Layer, placement: Placement, frame: Frame) -> Self {
        Self {
            layer,
            placement,
            frame,
            hidden: false,
            blend: None,
            source: false,
            clone_of: None,
            ribbon: None,
        }
    }
}

/// A layer as units, with what its kind reports.
pub struct Expansion {
    /// The units, in drawing order.
    pub units: Vec<Unit>,
    /// A stroke's report block (and the sign that its units compose through the stroke buffer).
    pub stroke: Option<stroke::StrokeReport>,
    /// Ranges of `units` the map stage must keep in one chunk (a blended stamp with its charts);
    /// units outside them are blocks of their own. Each at most `crate::bake::stage::unit_capacity`.
    pub blocks: Vec<std::ops::Range<usize>>,
}

/// What a layer kind does in the bake's stages.
pub(crate) trait Kind: Sync {
    /// The surface points the layer needs placed, in the order [`Kind::expand`] receives them.
    fn queries(&self, layer: &Layer) -> Vec<Query>;

    /// The layer's units from its placements, or an error naming the layer (and the field or path
    /// index) when the placements cannot be used. Warnings (recoverable oddities) go to `warnings`.
    fn expand(
        &self,
        cx: Cx<'_>,
        index: usize,
        placements: &[Placement],
        warnings: &mut Vec<String>,
    ) -> Result<Expansion>;
}

/// The one place where a job layer's `kind` becomes its implementation.
pub(crate) fn kind(k: LayerKind) -> &'static dyn Kind {
    match k {
        LayerKind::Decal => &decal::Decal,
        LayerKind::Stroke => &stroke::StrokeKind,
        LayerKind::Ribbon => &ribbon::RibbonKind,
    }
}

/// The query of a decal's `at` or a stroke's path point.
pub fn query_of(at: &crate::io::job::AtSpec) -> Query {
    use crate::io::job::AtSpec;
    use glam::Vec3;
    match at {
        AtSpec::Point(p) => Query::Point(Vec3::from(*p)),
        AtSpec::Ray { ray } => Query::Ray(Vec3::from(ray.origin), Vec3::from(ray.dir)),
    }
}

/// Why the placement `p` of `at` cannot be used, or `None`: a ray that missed the mesh, or a point
/// farther from the surface than `reach` (`what` names that size in the message: "the decal's
/// size", "the stamp size"). Callers prefix the field (`path[3]: `, `` `source`: ``).
pub fn placement_problem(
    at: &crate::io::job::AtSpec,
    p: &Placement,
    (reach, what): (f32, &str),
) -> Option<String> {
    if p.found == 0 {
        return Some("the ray misses the mesh; aim it at the model (check origin, direction and the model's units in `decalbake info`)".into());
    }
    match at {
        crate::io::job::AtSpec::Point(q) if p.distance > reach => Some(format!(
            "the point {q:?} is {:.4} from the surface, farther than {what} {reach:.4}; place it on the mesh (its bounding box is in `decalbake info`) or use a ray",
            p.distance
        )),
        _ => None,
    }
}
