// SPDX-License-Identifier: MIT OR Apache-2.0
//! Stage 2, placement: every surface point the layers name (a decal's `at`, a stroke's path) placed
//! on the mesh in one GPU submission ([`crate::place::place_gpu`]: `place_candidates` and
//! `place_reduce` in `wgsl/place/`, CPU twin [`crate::place::place_cpu`]), then each layer's kind
//! turns its placements into **units** (one map, one image, one blend each: a decal is one, a stroke one per
//! stamp). The stages after this one work on the units ([`Placed::job`]).

use super::kinds::{kind, stroke::StrokeReport};
use super::stage::{Cx, Log};
use crate::error::{Error, Result};
use crate::io::job::{BlendMode, Job};
use crate::maps::Frame;
use crate::place::{place_cpu_bvh, place_gpu, with_shading_normal, Placement};
use std::ops::Range;

/// Where every unit landed, and its frame there.
pub struct Placed {
    /// Per unit.
    pub placements: Vec<Placement>,
    /// Per unit.
    pub frames: Vec<Frame>,
    /// The job as units: the job's fields, with one layer per unit.
    pub job: Job,
    /// Per unit: (job layer, index of the unit within its layer).
    pub origin: Vec<(usize, usize)>,
    /// Per job layer: its units.
    pub units_of: Vec<Range<usize>>,
    /// Per unit: a chart other units blend from, not drawn.
    pub hidden: Vec<bool>,
    /// Per unit: its coordinates blended from other units' charts (unit indices of the bake).
    pub blends: Vec<Option<crate::maps::stamp::StampBlend>>,
    /// Per unit: a clone stroke's source stamp (selected and flattened, not drawn).
    pub sources: Vec<bool>,
    /// Per unit: a clone stamp's source unit (unit index of the bake).
    pub clone_of: Vec<Option<usize>>,
    /// The units in blocks the map stage keeps in one chunk, in order, covering every unit.
    pub blocks: Vec<Range<usize>>,
    /// The strokes, in job order.
    pub strokes: Vec<StrokeGroup>,
    /// Per unit: a ribbon's curve and image mapping (the map stage's ribbon pass).
    pub ribbons: Vec<Option<crate::bake::kinds::ribbon::RibbonUnit>>,
}

/// A stroke's units, composed through the stroke buffer and then onto the canvas.
#[derive(Debug, Clone)]
pub struct StrokeGroup {
    /// The job layer.
    pub layer: usize,
    /// Its units.
    pub units: Range<usize>,
    /// What the whole stroke may reach.
    pub opacity: f32,
    /// How it composes onto the layers below.
    pub blend: BlendMode,
    /// Its tool.
    pub tool: crate::io::job::Tool,
    /// Its report block.
    pub report: StrokeReport,
}

/// Places every layer of `job` on `mesh` and expands the layers into units.
pub(crate) fn place(cx: Cx<'_>, log: &mut Log) -> Result<Placed> {
    let Cx { engine, mesh, job } = cx;
    let per_layer: Vec<_> = job.layers.iter().map(|l| kind(l.kind).queries(l)).collect();
    let queries: Vec<_> = per_layer.iter().flatten().copied().collect();
    let all = if engine.stage_paths.placement_on_cpu(engine, mesh) {
        log.paths.placement = "cpu";
        queries
            .iter()
            .map(|&q| place_cpu_bvh(&mesh.topo, &mesh.bvh, q))
            .collect()
    } else {
        log.commands += 2;
        place_gpu(&engine.ctx, &engine.pipes, &mesh.gpu, &queries)?
    };
    let all: Vec<Placement> = all
        .into_iter()
        .map(|p| with_shading_normal(&mesh.mesh, p))
        .collect();
    let mut placed = Placed {
        placements: Vec::new(),
        frames: Vec::new(),
        job: Job {
            layers: Vec::new(),
            ..job.clone()
        },
        origin: Vec::new(),
        units_of: Vec::new(),
        hidden: Vec::new(),
        blends: Vec::new(),
        sources: Vec::new(),
        clone_of: Vec::new(),
        blocks: Vec::new(),
        strokes: Vec::new(),
        ribbons: Vec::new(),
    };
    let mut at = 0;
    for (i, (l, q)) in job.layers.iter().zip(&per_layer).enumerate() {
        let e = kind(l.kind).expand(cx, i, &all[at..at + q.len()], &mut log.warnings)?;
        at += q.len();
        let first = placed.placements.len();
        let mut covered = first;
        for b in &e.blocks {
            placed
                .blocks
                .extend((covered..first + b.start).map(|u| u..u + 1));
            placed.blocks.push(first + b.start..first + b.end);
            covered = first + b.end;
        }
        let n = e.units.len();
        placed.blocks.extend((covered..first + n).map(|u| u..u + 1));
        for (k, u) in e.units.into_iter().enumerate() {
            placed.placements.push(u.placement);
            placed.frames.push(u.frame);
            placed.job.layers.push(u.layer);
            placed.origin.push((i, k));
            placed.hidden.push(u.hidden);
            placed.ribbons.push(u.ribbon);
            placed.sources.push(u.source);
            placed.clone_of.push(u.clone_of.map(|c| c + first));
            placed.blends.push(u.blend.map(|mut b| {
                for c in &mut b.charts {
                    c.0 += first;
                }
                b
            }));
        }
        let units = first..placed.placements.len();
        if let Some(report) = e.stroke {
            placed.strokes.push(StrokeGroup {
                layer: i,
                units: units.clone(),
                opacity: l.opacity,
                blend: l.blend,
                tool: l
                    .stroke
                    .as_ref()
                    .map_or(crate::io::job::Tool::Paint, |s| s.tool.clone()),
                report,
            });
        }
        placed.units_of.push(units);
    }
    Ok(placed)
}

impl Placed {
    /// An error of a later stage that names a unit, renamed to name its job layer (and the stamp).
    pub fn rename(&self, e: Error) -> Error {
        match e {
            Error::Placement {
                path,
                layer,
                detail,
            } if layer < self.origin.len() => {
                let l = self.origin[layer].0;
                let before = |hidden: bool| {
                    self.units_of[l]
                        .clone()
                        .filter(|&u| u < layer && self.hidden[u] == hidden)
                        .count()
                };
                let detail = if self.hidden[layer] {
                    format!(
                        "corner chart {} of the stroke (`continuity`): {detail}",
                        before(true)
                    )
                } else if self.strokes.iter().any(|s| s.layer == l) {
                    let stamp = self.units_of[l]
                        .clone()
                        .filter(|&u| u < layer && !self.hidden[u])
                        .count();
                    format!("stamp {stamp} of the stroke: {detail}")
                } else {
                    detail
                };
                Error::Placement {
                    path,
                    layer: l,
                    detail,
                }
            }
            other => other,
        }
    }

    /// The stroke a unit belongs to, if any.
    pub fn stroke_of(&self, unit: usize) -> Option<&StrokeGroup> {
        let l = self.origin[unit].0;
        self.strokes.iter().find(|s| s.layer == l)
    }
}

/// A job as the stages after placement see it: one layer per unit (a decal, or one stamp of a
/// stroke), for the CPU twin ([`crate::bake::cpu::bake_units_cpu`]), tests and tools.
#[derive(Debug, Clone)]
pub struct Units {
    /// The job's fields with one layer per unit.
    pub job: Job,
    /// Per unit.
    pub placements: Vec<Placement>,
    /// Per unit.
    pub frames: Vec<Frame>,
    /// Per unit: (job layer, index of the unit within its layer).
    pub origin: Vec<(usize, usize)>,
    /// The strokes, in job order.
    pub strokes: Vec<crate::bake::cpu::StrokeCpu>,
    /// Per unit: a ribbon's curve and image mapping.
    pub ribbons: Vec<Option<crate::bake::kinds::ribbon::RibbonUnit>>,
}

impl crate::bake::Engine {
    /// Places `job`'s layers on `mesh` and expands them into units, as a bake does before its map
    /// stage.
    pub fn units(&self, mesh: &crate::bake::LoadedMesh, job: &Job) -> Result<Units> {
        super::check::check_job(self, mesh, job, None)?;
        let mut log = Log {
            timings: Default::default(),
            warnings: Vec::new(),
            commands: 0,
            paths: Default::default(),
        };
        let p = place(
            Cx {
                engine: self,
                mesh,
                job,
            },
            &mut log,
        )?;
        Ok(Units {
            strokes: p
                .strokes
                .iter()
                .map(|s| crate::bake::cpu::StrokeCpu {
                    units: s.units.clone(),
                    opacity: s.opacity,
                    blend: s.blend,
                    hidden: p.hidden[s.units.clone()].to_vec(),
                    blends: p.blends[s.units.clone()].to_vec(),
                    tool: s.tool.clone(),
                    sources: p.sources[s.units.clone()].to_vec(),
                    clone_of: p.clone_of[s.units.clone()].to_vec(),
                })
                .collect(),
            ribbons: p.ribbons,
            job: p.job,
            placements: p.placements,
            frames: p.frames,
            origin: p.origin,
        })
    }
}
