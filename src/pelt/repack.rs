// SPDX-License-Identifier: MIT OR Apache-2.0
//! Splitting an elongated pelt so the packing fills the square texture.
//!
//! The packing places every pelt at one texel density (`pack`), so a pelt much longer than it is
//! wide sets the scale by its length and leaves the rest of the square empty: bob's body came out
//! 2.6 times as long as wide and the layout used 34 % of the texture, where xatlas's 15 charts
//! used 58 % and Blender's 47 islands 61 %. Piponi & Borshukov (§4, end) already split a model
//! into several pelts where one would stretch; this is the same split, asked for by the texture's
//! shape: when the packed layout uses less than [`PACK_SPLIT_BELOW`] of the texture, the largest
//! pelt whose upright box is at least [`PACK_SPLIT_ASPECT`] times as long as wide is split in two
//! across its length (`split::halves`: seeded at the ends of its longest path), the halves are
//! pelted and refined like any piece (without further splits), and the result is kept if it packs
//! at least [`PACK_SPLIT_GAIN`] times as densely; at most [`MAX_PACK_SPLITS`] times. It costs a seam
//! across the pelt (reported in `splits` and `seam_length`) and buys texel density;
//! `--no-pack-splits` (`Options::pack_splits`) and `--patch`, which turns every split off
//! (`Options::max_split_levels` 0), keep the pelts whole.

use super::{cut, one_level, place, split, upright, Device, Done, Options, Timings};
use crate::error::Result;
use crate::mesh::Topology;
use glam::{DVec2, Vec2};
use rayon::prelude::*;
use std::path::Path;
use std::time::Instant;

/// The packed share of the texture below which an elongated pelt is split (module docs).
pub const PACK_SPLIT_BELOW: f64 = 0.45;
/// How elongated (upright box, long side over short) a pelt must be to be split for the packing.
pub const PACK_SPLIT_ASPECT: f64 = 1.8;
/// How much denser the split layout must pack to be kept.
pub const PACK_SPLIT_GAIN: f64 = 1.1;
/// Most pelts split for the packing.
pub const MAX_PACK_SPLITS: usize = 2;

/// The share of the square that `uv` (per piece, per vertex) covers.
fn covered(pieces: &[&cut::Piece], uv: &[Vec<Vec2>]) -> f64 {
    pieces
        .iter()
        .zip(uv)
        .map(|(p, u)| {
            p.triangles
                .iter()
                .map(|t| {
                    let [a, b, c] = t.map(|i| u[i as usize].as_dvec2());
                    0.5 * (b - a).perp_dot(c - a).abs()
                })
                .sum::<f64>()
        })
        .sum()
}

/// Packs `done` as `layout` does; returns the layout and the share of the texture it covers.
fn packed(topo: &Topology, done: &[&Done], opts: &Options) -> (Vec<Vec<Vec2>>, f64) {
    let pieces: Vec<&cut::Piece> = done.iter().map(|d| &d.0).collect();
    let flat: Vec<&[DVec2]> = done.iter().map(|d| &d.2[..]).collect();
    let uv = place(topo, &pieces, &flat, opts);
    let share = covered(&pieces, &uv);
    (uv, share)
}

/// Long side over short side of the flat piece turned to its smallest box.
fn aspect(flat: &[DVec2]) -> f64 {
    let (lo, hi) = upright(flat)
        .iter()
        .fold((DVec2::MAX, DVec2::MIN), |(lo, hi), p| {
            (lo.min(*p), hi.max(*p))
        });
    let d = hi - lo;
    d.max_element() / d.min_element().max(f64::MIN_POSITIVE)
}

/// The module's splits, applied to the laid-out pieces `done`; returns the pieces, how many were
/// split and, when it packed them (splits on), their packed layout, in their order. `exposure` is
/// measured here if the cut did not.
#[allow(
    clippy::type_complexity,
    reason = "the pieces, a count and their layout"
)]
pub(super) fn split_for_packing(
    device: Device,
    topo: &Topology,
    mut done: Vec<Done>,
    opts: &Options,
    exposure: &mut Vec<f32>,
    path: &Path,
    timings: &mut Timings,
) -> Result<(Vec<Done>, usize, Option<Vec<Vec<Vec2>>>)> {
    let mut splits = 0;
    if opts.max_split_levels == 0 || !opts.pack_splits {
        return Ok((done, 0, None));
    }
    let t = Instant::now();
    let (mut uv, mut now) = packed(topo, &done.iter().collect::<Vec<_>>(), opts);
    timings.pack += super::ms(t);
    while splits < MAX_PACK_SPLITS && now < PACK_SPLIT_BELOW {
        let area = |d: &Done| -> f64 {
            d.0.triangles
                .iter()
                .map(|t| {
                    let [a, b, c] = t.map(|i| topo.positions[d.0.welded[i as usize] as usize]);
                    0.5 * (b - a).cross(c - a).length() as f64
                })
                .sum()
        };
        let Some(k) = (0..done.len())
            .filter(|&k| aspect(&done[k].2) >= PACK_SPLIT_ASPECT)
            .max_by(|&a, &b| area(&done[a]).total_cmp(&area(&done[b])))
        else {
            break;
        };
        let t = Instant::now();
        let Some(halves) = split::halves(topo, &done[k].0, None) else {
            break;
        };
        if exposure.is_empty() {
            *exposure = super::measure_exposure(topo, timings);
        }
        let nm = opts.split_non_manifold;
        // A half that cannot be cut into disks leaves the layout as it is: this split is for the
        // packing only, and the unsplit layout is valid.
        let Ok(cuts) = halves
            .par_iter()
            .map(|half| split::cut_region(topo, half, nm, exposure, path))
            .collect::<Result<Vec<Vec<cut::Piece>>>>()
        else {
            break;
        };
        timings.cut += super::ms(t);
        let pieces: Vec<cut::Piece> = cuts.into_iter().flatten().collect();
        let (kept, _) = one_level(device, topo, pieces, opts, false, timings)?;
        // The layout without piece k and with its halves at the end, in that order.
        let trial: Vec<&Done> = (done.iter().enumerate())
            .filter(|&(i, _)| i != k)
            .map(|(_, d)| d)
            .chain(&kept)
            .collect();
        let t = Instant::now();
        let (layout, then) = packed(topo, &trial, opts);
        timings.pack += super::ms(t);
        if then < now * PACK_SPLIT_GAIN {
            break;
        }
        done.remove(k);
        done.extend(kept);
        (uv, now) = (layout, then);
        splits += 1;
    }
    Ok((done, splits, Some(uv)))
}
