// SPDX-License-Identifier: MIT OR Apache-2.0
//! Layer kinds: what each kind of job layer (`"kind"` in the job) contributes to the bake's stages,
//! one module per kind behind [`Kind`], dispatched in one place ([`kind`]).
//!
//! Today a kind says where its layer lands (the placement query) and turns the placement into the
//! layer's [`Frame`], refusing placements it cannot use; the map, selection, raster and compose
//! stages then treat every layer alike (one map, one image, one blend). A kind that expands into
//! several maps (a stroke's stamps, a ribbon's curve) extends this trait with the hook it needs and
//! the stage that calls it; see `ARCHITECTURE.md`, "Adding a layer kind".

mod decal;

use crate::error::Result;
use crate::io::job::{Job, Layer, LayerKind};
use crate::maps::Frame;
use crate::place::{Placement, Query};

/// What a layer kind does in the bake's stages.
pub trait Kind: Sync {
    /// Where the layer is placed.
    fn query(&self, layer: &Layer) -> Query;

    /// The layer's frame at its placement, or an error naming the layer when the placement cannot be
    /// used. Warnings (recoverable oddities) go to `warnings`.
    fn frame(
        &self,
        job: &Job,
        index: usize,
        placement: &Placement,
        warnings: &mut Vec<String>,
    ) -> Result<Frame>;
}

/// The one place where a job layer's `kind` becomes its implementation.
pub fn kind(k: LayerKind) -> &'static dyn Kind {
    match k {
        LayerKind::Decal => &decal::Decal,
    }
}
