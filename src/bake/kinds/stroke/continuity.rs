// SPDX-License-Identifier: MIT OR Apache-2.0
//! `continuity: true` (Maillot section 7): each stamp's coordinates are blended from charts solved at
//! the corners of its triangle ([`crate::maps::stamp`]) instead of a chart solved at its point, so a
//! stroke's stamps vary continuously as they move. This module turns a stroke's stamps into units:
//! hidden chart units (one per corner and size level, shared by every stamp of a block that needs
//! it: the cache of section 9) followed by the stamps that blend them, in blocks that fit one chunk
//! of the map stage.
//!
//! Size levels (section 7): when pressure changes the stamp size, charts are solved at sizes
//! quantised in steps of the mean edge length, and each stamp blends the two levels around its size
//! (six charts); a stroke whose stamps all have one size uses that size (three charts).

use crate::bake::kinds::Unit;
use crate::io::job::Layer;
use crate::maps::stamp::{StampBlend, MAX_CHARTS};
use crate::maps::Frame;
use crate::mesh::Topology;
use crate::place::Placement;
use std::collections::HashMap;
use std::ops::Range;

/// A stroke's units with continuous charts.
pub struct Continuous {
    /// Charts and stamps, in drawing order.
    pub units: Vec<Unit>,
    /// Blocks of `units` to keep in one chunk.
    pub blocks: Vec<Range<usize>>,
    /// Chart units solved.
    pub charts: usize,
}

/// A chart's key: its vertex and size level (`u32::MAX`: the stroke's one stamp size).
type Key = (u32, u32);

/// Interleaves `stamps` (solved-at-their-point units) with the corner charts they blend, in blocks
/// of at most `capacity` units (more than [`MAX_CHARTS`]: the caller checks); `step` is the
/// size-level step (the mean edge length).
pub fn interpolate(
    topo: &Topology,
    layer: &Layer,
    stamps: Vec<Unit>,
    capacity: usize,
    step: f32,
) -> Continuous {
    debug_assert!(
        capacity > MAX_CHARTS,
        "the caller checks that a stamp and its charts fit"
    );
    let widths: Vec<f32> = stamps.iter().map(|u| u.frame.size[0]).collect();
    let varies = widths
        .iter()
        .any(|w| (w - widths[0]).abs() > 1e-6 * widths[0]);
    let aspect = layer.size[1] / layer.size[0];
    let mut out = Continuous {
        units: Vec::new(),
        blocks: Vec::new(),
        charts: 0,
    };
    let mut cache: HashMap<Key, usize> = HashMap::new();
    let mut block_start = 0;
    for stamp in stamps {
        let levels = levels(stamp.frame.size[0], varies, step);
        let corners = topo.triangles[stamp.placement.triangle as usize];
        let wanted: Vec<(usize, Key, f32)> = (0..3)
            .filter(|&j| stamp.placement.bary[j] > 1e-7)
            .flat_map(|j| levels.iter().map(move |&(l, w)| (j, (corners[j], l), w)))
            .collect();
        let new = wanted
            .iter()
            .filter(|(_, k, _)| !cache.contains_key(k))
            .count();
        if out.units.len() - block_start + new + 1 > capacity {
            out.blocks.push(block_start..out.units.len());
            block_start = out.units.len();
            cache.clear();
        }
        let mut charts = Vec::with_capacity(wanted.len());
        for (j, key, w) in wanted {
            let index = match cache.get(&key) {
                Some(&i) => i,
                None => {
                    // Level k serves stamps up to (k + 1) steps wide (it is blended with level k + 1).
                    let width = if key.1 == u32::MAX {
                        stamp.frame.size[0]
                    } else {
                        (key.1 + 1) as f32 * step
                    };
                    out.units
                        .push(chart_unit(topo, layer, key.0, [width, width * aspect]));
                    out.charts += 1;
                    cache.insert(key, out.units.len() - 1);
                    out.units.len() - 1
                }
            };
            let f = &out.units[index].frame;
            let t = stamp.frame.axis_u;
            let theta = t.dot(f.axis_v).atan2(t.dot(f.axis_u));
            charts.push((index, stamp.placement.bary[j] * w, theta));
        }
        let blend = StampBlend {
            charts,
            corners,
            bary: stamp.placement.bary,
        };
        out.units.push(Unit {
            blend: Some(blend),
            ..stamp
        });
    }
    out.blocks.push(block_start..out.units.len());
    out
}

/// The size levels a stamp of width `w` blends, with their weights: the two quantised levels
/// around it when sizes vary (step `step`), else the stroke's one size.
fn levels(w: f32, varies: bool, step: f32) -> Vec<(u32, f32)> {
    if !varies {
        return vec![(u32::MAX, 1.0)];
    }
    let x = w / step;
    let k = x.floor();
    let lambda = x - k;
    [(k as u32, 1.0 - lambda), (k as u32 + 1, lambda)]
        .into_iter()
        .filter(|&(_, wt)| wt > 1e-6)
        .collect()
}

/// The hidden chart unit at vertex `v` for stamps of size `size`: centred on the vertex, its frame
/// from the layer's `up` (any frame serves: stamps turn each chart by their own axis), and grown so
/// that it covers such a stamp turned any way with its point anywhere in a triangle around `v`
/// (half-diagonal plus the longest edge at `v`, Maillot section 7).
fn chart_unit(topo: &Topology, layer: &Layer, v: u32, size: [f32; 2]) -> Unit {
    let tris = topo.triangles_around(v);
    let p = topo.positions[v as usize];
    let longest = tris
        .iter()
        .flat_map(|&t| topo.triangles[t as usize])
        .map(|w| (topo.positions[w as usize] - p).length())
        .fold(0.0f32, f32::max);
    let t = tris[0];
    let corner = topo.triangles[t as usize]
        .iter()
        .position(|&w| w == v)
        .expect("an incident triangle has the vertex");
    let mut bary = [0.0; 3];
    bary[corner] = 1.0;
    let n = Some(topo.normals[v as usize])
        .filter(|n| n.length() > 1e-12)
        .or_else(|| {
            tris.iter()
                .map(|&t| {
                    let [a, b, c] = topo.triangles[t as usize].map(|w| topo.positions[w as usize]);
                    (b - a).cross(c - a)
                })
                .find(|n| n.length() > 1e-20)
        })
        .unwrap_or(glam::Vec3::Z)
        .normalize();
    let placement = Placement {
        point: p.to_array(),
        triangle: t,
        bary,
        distance: 0.0,
        normal: n.to_array(),
        found: 1,
    };
    let half_diagonal = 0.5 * (size[0] * size[0] + size[1] * size[1]).sqrt();
    let d = std::f32::consts::SQRT_2 * (longest + half_diagonal);
    let chart_layer = Layer {
        kind: crate::io::job::LayerKind::Decal,
        size: [d, d],
        depth: d,
        angle: 0.0,
        blend: crate::io::job::BlendMode::Normal,
        opacity: 1.0,
        stroke: None,
        ..layer.clone()
    };
    let frame = Frame::new(&placement, &chart_layer);
    Unit {
        layer: chart_layer,
        placement,
        frame,
        hidden: true,
        blend: None,
        source: false,
        clone_of: None,
        ribbon: None,
    }
}
