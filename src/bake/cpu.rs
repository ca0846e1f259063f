// SPDX-License-Identifier: MIT OR Apache-2.0
//! CPU twin of the raster and compose stages (`layer_raster`, `island_raster`,
//! `compose`, `base_init`) and of the padding rule, written plainly as the tests' oracle.
//!
//! It follows the GPU's sampling pattern exactly: sample (i, j) of texel (x, y) sits at
//! `(x + (i + 0.5) / ss, y + (j + 0.5) / ss)` in texel units; a job drawn adaptively
//! ([`Job::adaptive_sampling`]) has the four samples of [`SAMPLE_POS`] and evaluates each layer
//! once a texel and triangle, as `layer_raster`'s adaptive variant does
//! (`LayerRaster::sample_adaptive`). The twin follows the job, not the device: on a device without
//! four-sample targets the GPU draws the full pattern where the twin models the adaptive one. Decal images are sampled bilinearly on
//! mip level 0 with clamp-to-edge; the GPU picks a coarser level when a decal is minified, so
//! comparisons against this twin use magnified decals (see `tests/compose_vs_cpu.rs`).

use crate::bake::kinds::ribbon::RibbonUnit;
use crate::io::image::LinearImage;
use crate::io::job::{Job, Layer};
use crate::maps::chart::cone::Cone;
use crate::maps::{CpuCoords, Frame};
use crate::mesh::{Mesh, Topology};
use crate::place::Placement;
use glam::Vec2;

/// Bilinear sample with clamp-to-edge, texel centres at half-integers (straight or premultiplied
/// values, whatever `img` holds).
pub fn sample_bilinear(img: &LinearImage, uv: Vec2) -> [f32; 4] {
    img.bilinear(uv.x, uv.y, false)
}

/// Barycentric coordinates of `p` in triangle (a, b, c), or `None` outside (edges count as inside).
pub fn barycentric(p: Vec2, a: Vec2, b: Vec2, c: Vec2) -> Option<[f32; 3]> {
    let area = (b - a).perp_dot(c - a);
    if area.abs() < 1e-20 {
        return None;
    }
    let w0 = (b - p).perp_dot(c - p) / area;
    let w1 = (c - p).perp_dot(a - p) / area;
    let w2 = 1.0 - w0 - w1;
    (w0 >= 0.0 && w1 >= 0.0 && w2 >= 0.0).then_some([w0, w1, w2])
}

/// Result of the CPU bake before padding.
pub struct CpuBake {
    /// Linear straight-alpha texels after all layers (before padding).
    pub composed: LinearImage,
    /// Island mask (a texel with any covered sample).
    pub island: Vec<bool>,
    /// Triangles selected per layer.
    pub selected: Vec<Vec<u32>>,
}

/// Bakes `job` on the CPU. `images[i]` is layer i's (decal, mask) as loaded (straight alpha, mask
/// already raw), `base` the base image, `placements` the layers' placements. Decal layers only; a
/// job with strokes goes through [`bake_units_cpu`] with its units ([`crate::Engine::units`]).
pub fn bake_cpu(
    mesh: &Mesh,
    topo: &Topology,
    job: &Job,
    placements: &[Placement],
    base: &LinearImage,
    images: &[(LinearImage, Option<LinearImage>)],
) -> CpuBake {
    let frames: Vec<Frame> = job
        .layers
        .iter()
        .zip(placements)
        .map(|(l, p)| Frame::new(p, l))
        .collect();
    bake_units_cpu(
        mesh,
        topo,
        (job, placements, &frames),
        (&[], &[]),
        base,
        images,
    )
}

/// A stroke as the CPU twin composes it: its units, opacity and blend mode.
#[derive(Debug, Clone)]
pub struct StrokeCpu {
    /// The stroke's units (indices into the unit job).
    pub units: std::ops::Range<usize>,
    /// The stroke's opacity.
    pub opacity: f32,
    /// Its blend mode onto the layers below.
    pub blend: crate::io::job::BlendMode,
    /// Per unit of the stroke (`units.start + k`): a hidden chart (continuous strokes).
    pub hidden: Vec<bool>,
    /// Per unit of the stroke: coordinates blended from charts (unit indices of the bake).
    pub blends: Vec<Option<crate::maps::stamp::StampBlend>>,
    /// The stroke's tool (blur and smear read the canvas: [`crate::bake::cpu_tools`]).
    pub tool: crate::io::job::Tool,
    /// Per unit of the stroke: a clone's source stamp (flattened, not drawn).
    pub sources: Vec<bool>,
    /// Per unit of the stroke: a clone stamp's source unit (unit index of the bake).
    pub clone_of: Vec<Option<usize>>,
}

/// The CPU twin of the bake's stages after placement, on units (`job.layers[u]` at `placements[u]`
/// with frame `frames[u]`, image `images[u]`): each unit composed in order into the canvas, or,
/// for the units of a stroke, into the stroke buffer, which [`apply_stroke`] composes onto the
/// canvas after the stroke's last unit.
pub fn bake_units_cpu(
    mesh: &Mesh,
    topo: &Topology,
    (job, placements, frames): (&Job, &[Placement], &[Frame]),
    (strokes, ribbons): (&[StrokeCpu], &[Option<RibbonUnit>]),
    base: &LinearImage,
    images: &[(LinearImage, Option<LinearImage>)],
) -> CpuBake {
    let (w, h) = (job.width, job.height);
    let size = Vec2::new(w as f32, h as f32);
    let mut composed = LinearImage::solid(w, h, [0.0; 4]);
    for y in 0..h {
        for x in 0..w {
            let uv = (Vec2::new(x as f32, y as f32) + 0.5) / size;
            composed.pixels[(y * w + x) as usize] = sample_bilinear(base, uv);
        }
    }
    let island = islands_cpu(mesh, topo, job);
    let mut selected = Vec::new();
    let mut buffer = LinearImage::solid(w, h, [0.0; 4]);
    let surface = crate::mesh::SurfaceData::new(topo);
    let uvs = &mesh.uv_sets[job.uv_set as usize];
    let mut li = 0;
    while li < job.layers.len() {
        // A decal alone; a stroke's stamps together, blended per sample as the GPU draws them.
        let stroke = strokes.iter().find(|s| s.units.contains(&li));
        let group = stroke.map_or(li..li + 1, |s| li..s.units.end);
        let blend_of = |u: usize| stroke.and_then(|s| s.blends[u - s.units.start].as_ref());
        let hidden = |u: usize| stroke.is_some_and(|s| s.hidden[u - s.units.start]);
        let (mut coords, cones): (Vec<Vec<[f32; 4]>>, Vec<Option<Cone>>) = group
            .clone()
            .map(|u| match blend_of(u) {
                Some(_) => (Vec::new(), None),
                None => match ribbons.get(u).and_then(|r| r.as_ref()) {
                    Some(r) => (ribbon_coords_cpu(topo, r), None),
                    None => {
                        let (l, f, p) = (&job.layers[u], &frames[u], &placements[u]);
                        let paint =
                            stroke.is_none_or(|s| matches!(s.tool, crate::io::job::Tool::Paint));
                        let c = layer_coords_cpu(topo, &surface, l, f, p, !hidden(u) && paint);
                        (c.coords, c.cone)
                    }
                },
            })
            .unzip();
        for u in group.clone() {
            if let Some(b) = blend_of(u) {
                let charts: Vec<&[[f32; 4]]> = b
                    .charts
                    .iter()
                    .map(|c| &coords[c.0 - group.start][..])
                    .collect();
                coords[u - group.start] = crate::maps::stamp::blend_cpu(b, &charts);
            }
        }
        let sels: Vec<Selection> = group
            .clone()
            .zip(coords.iter().zip(&cones))
            .map(|(u, (c, cone))| {
                let (layer, frame) = (&job.layers[u], &frames[u]);
                let facing = crate::maps::method(layer.method).front_facing();
                if hidden(u) {
                    Selection::default()
                } else {
                    let map = (&c[..], cone.as_ref());
                    select_triangles(mesh, topo, uvs, map, frame, facing, [w, h])
                }
            })
            .collect();
        let mut flats = tool_flats(
            (mesh, topo, job),
            (group.clone(), stroke, &hidden),
            (&coords, &sels),
            &composed,
        );
        let rasters: Vec<LayerRaster> = group
            .clone()
            .zip(coords.iter().zip(&cones))
            .map(|(u, (c, cone))| LayerRaster {
                flat: flats[u - group.start].take(),
                cone: *cone,
                repeats: ribbons
                    .get(u)
                    .and_then(|r| r.as_ref())
                    .map_or(0.0, |r| r.repeats),
                ..LayerRaster::new(mesh, topo, job, &job.layers[u], c, &images[u])
            })
            .collect();
        // A clone's source stamps are flattened (above) but not drawn.
        let source = |u: usize| stroke.is_some_and(|s| s.sources[u - s.units.start]);
        let draw: Vec<Selection> = group
            .clone()
            .zip(&sels)
            .map(|(u, s)| {
                if source(u) {
                    Selection::default()
                } else {
                    s.clone()
                }
            })
            .collect();
        let b = draw
            .iter()
            .fold([i32::MAX, i32::MAX, i32::MIN, i32::MIN], |b, s| {
                let t = s.texel_box;
                [
                    b[0].min(t[0]),
                    b[1].min(t[1]),
                    b[2].max(t[2]),
                    b[3].max(t[3]),
                ]
            });
        let (target, mode) = match stroke {
            Some(_) => (&mut buffer, crate::io::job::BlendMode::Normal),
            None => (&mut composed, job.layers[li].blend),
        };
        for y in b[1].max(0)..b[3].min(h as i32) {
            for x in b[0].max(0)..b[2].min(w as i32) {
                let (x, y) = (x as u32, y as u32);
                let Some(src) = group_texel(&rasters, &draw, x, y) else {
                    continue;
                };
                let idx = (y * w + x) as usize;
                target.pixels[idx] = mode.blend(target.pixels[idx], src);
            }
        }
        if let Some(s) = stroke {
            apply_stroke(&mut composed, &mut buffer, s.blend, s.opacity);
        }
        selected.extend(sels.into_iter().map(|s| s.triangles));
        li = group.end;
    }
    CpuBake {
        composed,
        island,
        selected,
    }
}

/// A group's premultiplied colour at texel (x, y): per sample, the units covering it composed
/// source-over in order; averaged over the samples some unit covers. `None` when none is covered or
/// the result is transparent.
fn group_texel(rasters: &[LayerRaster], sels: &[Selection], x: u32, y: u32) -> Option<[f32; 4]> {
    let job = rasters.first()?.job;
    let size = Vec2::new(job.width as f32, job.height as f32);
    let points = texel_samples(job, x, y, size);
    let (mut sum, mut n) = ([0.0f32; 4], 0u32);
    for (i, &p) in points.iter().enumerate() {
        let mut acc: Option<[f32; 4]> = None;
        for (r, sel) in rasters.iter().zip(sels) {
            let s = match job.adaptive_sampling() {
                true => r.sample_adaptive(&points, i, &sel.triangles),
                false => r.sample(p, &sel.triangles),
            };
            if let Some(s) = s {
                let d = acc.unwrap_or([0.0; 4]);
                acc = Some(std::array::from_fn(|k| s[k] + d[k] * (1.0 - s[3])));
            }
        }
        if let Some(a) = acc {
            n += 1;
            for k in 0..4 {
                sum[k] += a[k];
            }
        }
    }
    let src = sum.map(|v| v / n.max(1) as f32);
    (n > 0 && src[3] > 0.0).then_some(src)
}

/// The filtered flat images of a blur or smear stroke's stamps (`None` for other units), from the
/// canvas as the layers below left it: twins of `bake/tools.rs`.
fn tool_flats(
    (mesh, topo, job): (&Mesh, &Topology, &Job),
    (group, stroke, hidden): (
        std::ops::Range<usize>,
        Option<&StrokeCpu>,
        &dyn Fn(usize) -> bool,
    ),
    (coords, sels): (&[Vec<[f32; 4]>], &[Selection]),
    canvas: &LinearImage,
) -> Vec<Option<LinearImage>> {
    use crate::bake::cpu_tools::{blur_cpu, flatten_cpu, smear_cpu};
    use crate::io::job::Tool;
    let mut out: Vec<Option<LinearImage>> = group.clone().map(|_| None).collect();
    let Some(s) = stroke.filter(|s| s.tool.reads_canvas()) else {
        return out;
    };
    // The units whose view of the canvas is flattened: the stamps, or a clone's sources.
    let clone_of = |u: usize| s.clone_of[u - s.units.start];
    let stamps: Vec<usize> = group
        .clone()
        .filter(|&u| !hidden(u) && clone_of(u).is_none())
        .collect();
    let mut flats: Vec<LinearImage> = stamps
        .iter()
        .map(|&u| {
            let k = u - group.start;
            let m = (mesh, topo, job.uv_set);
            flatten_cpu(
                m,
                &coords[k],
                job.layers[u].size,
                &sels[k].triangles,
                canvas,
            )
        })
        .collect();
    match s.tool {
        Tool::Blur { radius } => {
            for (f, &u) in flats.iter_mut().zip(&stamps) {
                let sigma =
                    0.5 * radius / job.layers[u].size[0] * crate::bake::params::FLAT_RES as f32;
                *f = blur_cpu(f, sigma);
            }
        }
        Tool::Smear { strength } => {
            let r = crate::bake::params::FLAT_RES;
            smear_cpu(
                &mut flats,
                strength,
                &mut LinearImage::solid(r, r, [0.0; 4]),
            );
        }
        Tool::Paint | Tool::Clone { .. } => {}
    }
    for (f, u) in flats.into_iter().zip(stamps) {
        out[u - group.start] = Some(f);
    }
    // A clone stamp paints its source's flat.
    for u in group.clone() {
        if let Some(src) = clone_of(u) {
            out[u - group.start] = out[src - group.start].clone();
        }
    }
    out
}

/// Twin of `stroke_apply`: the stroke buffer (straight alpha) at `opacity` × its alpha blended onto
/// the canvas with `blend`, and cleared.
pub fn apply_stroke(
    canvas: &mut LinearImage,
    buffer: &mut LinearImage,
    blend: crate::io::job::BlendMode,
    opacity: f32,
) {
    for (c, s) in canvas.pixels.iter_mut().zip(buffer.pixels.iter_mut()) {
        if s[3] <= 0.0 {
            continue;
        }
        let src = [
            s[0] * s[3] * opacity,
            s[1] * s[3] * opacity,
            s[2] * s[3] * opacity,
            s[3] * opacity,
        ];
        *c = blend.blend(*c, src);
        *s = [0.0; 4];
    }
}

/// Twin of the island raster: a texel is an island texel when any of its samples lies in a
/// triangle (UVs assumed inside the [0,1] tile here; the GPU also handles other tiles).
fn islands_cpu(mesh: &Mesh, topo: &Topology, job: &Job) -> Vec<bool> {
    let (w, h) = (job.width, job.height);
    let uvs = &mesh.uv_sets[job.uv_set as usize];
    let size = Vec2::new(w as f32, h as f32);
    let mut island = vec![false; (w * h) as usize];
    for (t, tri) in mesh.triangles.iter().enumerate() {
        if topo.degenerate[t] {
            continue;
        }
        let [a, b, c] = tri.map(|s| uvs[s as usize]);
        let lo = a.min(b).min(c) * size;
        let hi = a.max(b).max(c) * size;
        for y in (lo.y.floor().max(0.0) as u32)..(hi.y.ceil().min(h as f32) as u32) {
            for x in (lo.x.floor().max(0.0) as u32)..(hi.x.ceil().min(w as f32) as u32) {
                let idx = (y * w + x) as usize;
                if island[idx] {
                    continue;
                }
                island[idx] = texel_samples(job, x, y, size)
                    .into_iter()
                    .any(|p| barycentric(p, a, b, c).is_some());
            }
        }
    }
    island
}

/// Whether image point `p` lies in the image square [0, 1]².
fn in_unit(p: Vec2) -> bool {
    p.x >= 0.0 && p.y >= 0.0 && p.x <= 1.0 && p.y <= 1.0
}

/// Where the adaptive raster's four samples sit in a texel (the standard 4-sample pattern of
/// WebGPU and Vulkan; `SAMPLE_POS` in `wgsl/bake/layer_raster.wgsl`).
pub const SAMPLE_POS: [[f32; 2]; 4] = [
    [0.375, 0.125],
    [0.875, 0.375],
    [0.125, 0.625],
    [0.625, 0.875],
];

/// The sample points of texel (x, y) in UV space, in the GPU's order: the ss × ss grid row by
/// row, or the adaptive raster's four ([`SAMPLE_POS`]).
fn texel_samples(job: &Job, x: u32, y: u32, size: Vec2) -> Vec<Vec2> {
    match job.adaptive_sampling() {
        true => SAMPLE_POS
            .iter()
            .map(|o| Vec2::new(x as f32 + o[0], y as f32 + o[1]) / size)
            .collect(),
        false => (0..job.ss * job.ss)
            .map(|s| sample_pos(x, y, s % job.ss, s / job.ss, job.ss, size))
            .collect(),
    }
}

/// Sample (i, j) of texel (x, y) in UV space, on an ss × ss grid.
fn sample_pos(x: u32, y: u32, i: u32, j: u32, ss: u32, size: Vec2) -> Vec2 {
    Vec2::new(
        x as f32 + (i as f32 + 0.5) / ss as f32,
        y as f32 + (j as f32 + 0.5) / ss as f32,
    ) / size
}

/// A layer's coordinates as the map stage computes them, on the CPU: the layer's exponential map
/// ([`crate::maps::expmap::cpu::dem_cpu`]) where its method uses one, then the method's twin.
pub fn layer_coords_cpu(
    topo: &Topology,
    surface: &crate::mesh::SurfaceData,
    layer: &Layer,
    frame: &Frame,
    placement: &Placement,
    cone: bool,
) -> CpuCoords {
    let m = crate::maps::method(layer.method);
    let expmap = m.uses_expmap().then(|| {
        let opts = frame.expmap_options(layer);
        let seed = frame.seed(placement);
        let map = crate::maps::expmap::cpu::dem_cpu(topo, &seed, opts, surface);
        map.dist
            .iter()
            .zip(&map.uv)
            .map(|(d, uv)| [uv[0], uv[1], *d, if d.is_finite() { 1.0 } else { 0.0 }])
            .collect()
    });
    m.cpu_coords(topo, layer, frame, (placement.triangle, cone), expmap)
}

/// A ribbon unit's coordinates as the bake's ribbon pass writes them: the curve's map by the CPU
/// twin ([`crate::maps::ribbon::ribbon_cpu`]), its highly curved parts repaired (f64 PCG), through
/// the unit's image mapping: (x, y, graph distance, 1) per reached vertex.
pub fn ribbon_coords_cpu(topo: &Topology, r: &RibbonUnit) -> Vec<[f32; 4]> {
    let map = crate::maps::ribbon::ribbon_cpu(topo, &r.curve, r.reach);
    let mut coords: Vec<[f32; 4]> = (0..topo.positions.len())
        .map(|v| match map.reached(v) {
            true => [map.uv[v][0], map.uv[v][1], map.dist[v], 1.0],
            false => [0.0; 4],
        })
        .collect();
    crate::maps::ribbon::repair::repair_coords(
        topo,
        (&r.curve, r.sides, r.lambda),
        &mut coords,
        [1.0, 0.0, 1.0, 0.0],
        crate::maps::ribbon::repair::solve_cpu,
    )
    .expect("the CPU solver does not fail");
    let [a, b, c, d] = r.xform;
    for x in coords.iter_mut().filter(|x| x[3] > 0.5) {
        (x[0], x[1]) = (a * x[0] + b, c * x[1] + d);
    }
    coords
}

/// Twin of `layer_raster` + `compose`'s averaging for one layer.
struct LayerRaster<'a> {
    mesh: &'a Mesh,
    topo: &'a Topology,
    job: &'a Job,
    layer: &'a Layer,
    coords: &'a [[f32; 4]],
    premult: LinearImage,
    mask: Option<&'a LinearImage>,
    /// A blur or smear stamp's filtered flat image (colour; its image's alpha is the shape).
    flat: Option<LinearImage>,
    /// The cone that opens the layer's chart: applied per sample, as `layer_raster` does per
    /// fragment.
    cone: Option<Cone>,
    /// The layer's image warp (`layer_raster`'s FLAG_WARP).
    warp: Option<crate::maps::warp::Tps>,
    /// A tiled ribbon's copies of the image along x (`layer_raster`'s FLAG_REPEAT; 0: none).
    repeats: f32,
}

impl<'a> LayerRaster<'a> {
    fn new(
        mesh: &'a Mesh,
        topo: &'a Topology,
        job: &'a Job,
        layer: &'a Layer,
        coords: &'a [[f32; 4]],
        (img, mask): &'a (LinearImage, Option<LinearImage>),
    ) -> Self {
        let premult = LinearImage {
            pixels: img
                .pixels
                .iter()
                .map(|p| [p[0] * p[3], p[1] * p[3], p[2] * p[3], p[3]])
                .collect(),
            ..img.clone()
        };
        Self {
            mesh,
            topo,
            job,
            layer,
            coords,
            premult,
            mask: mask.as_ref(),
            flat: None,
            cone: None,
            warp: crate::maps::warp::Tps::fit(&layer.warp),
            repeats: 0.0,
        }
    }

    /// One sample: every selected triangle covering `p` composed source-over in list order; `None`
    /// when none covers it.
    fn sample(&self, p: Vec2, triangles: &[u32]) -> Option<[f32; 4]> {
        let mut covered = false;
        let mut acc = [0.0f32; 4];
        for &t in triangles {
            if self
                .corners(t)
                .is_none_or(|[a, b, c]| barycentric(p, a, b, c).is_none())
            {
                continue;
            }
            covered = true;
            let im = self.image_point(t, p);
            let s = match self.paints(im) {
                true => self.shade(im),
                false => [0.0; 4],
            };
            // Premultiplied source-over within the layer, in list order.
            for k in 0..4 {
                acc[k] = s[k] + acc[k] * (1.0 - s[3]);
            }
        }
        covered.then_some(acc)
    }

    /// Twin of the adaptive raster: sample `i` of the texel whose four samples are `points`. Every
    /// selected triangle covering it is evaluated once for the texel, at the texel's centre (its
    /// map extrapolated; clamped into the image), times the share of the samples it covers whose
    /// image point lies in the image; composed source-over in list order.
    fn sample_adaptive(&self, points: &[Vec2], i: usize, triangles: &[u32]) -> Option<[f32; 4]> {
        let mut covered = false;
        let mut acc = [0.0f32; 4];
        for &t in triangles {
            let Some([a, b, c]) = self.corners(t) else {
                continue;
            };
            let mine: Vec<Vec2> = points
                .iter()
                .copied()
                .filter(|&q| barycentric(q, a, b, c).is_some())
                .collect();
            if barycentric(points[i], a, b, c).is_none() {
                continue;
            }
            covered = true;
            let inside = mine
                .iter()
                .filter(|&&q| self.paints(self.image_point(t, q)))
                .count();
            let mut s = [0.0; 4];
            if inside > 0 {
                let at = points.iter().sum::<Vec2>() / points.len() as f32;
                let im = self
                    .image_point(t, at)
                    .clamp(Vec2::ZERO, Vec2::splat(0.999_999_94));
                let share = inside as f32 / mine.len() as f32;
                s = self.shade(im).map(|v| v * share);
            }
            for k in 0..4 {
                acc[k] = s[k] + acc[k] * (1.0 - s[3]);
            }
        }
        covered.then_some(acc)
    }

    /// Whether image point `im` is painted: in the image, and where the layer is warped, its
    /// warped point too.
    fn paints(&self, im: Vec2) -> bool {
        let mut w = im;
        if self.repeats > 0.0 {
            w.x = (w.x * self.repeats).fract();
        }
        in_unit(im)
            && self
                .warp
                .as_ref()
                .is_none_or(|t| in_unit(Vec2::from(t.eval(w.to_array()))))
    }

    /// Triangle `t`'s UV corners.
    fn corners(&self, t: u32) -> Option<[Vec2; 3]> {
        let uvs = &self.mesh.uv_sets[self.job.uv_set as usize];
        Some(self.mesh.triangles[t as usize].map(|s| uvs[s as usize]))
    }

    /// The image point of UV point `p` in triangle `t`'s map (affine, extrapolated outside it; a
    /// cone chart's opened), before tiling and warping.
    fn image_point(&self, t: u32, p: Vec2) -> Vec2 {
        let [a, b, c] = self.corners(t).expect("a triangle has corners");
        let area = (b - a).perp_dot(c - a);
        let w0 = (b - p).perp_dot(c - p) / area;
        let w1 = (c - p).perp_dot(a - p) / area;
        let bc = [w0, w1, 1.0 - w0 - w1];
        let lc = self.topo.triangles[t as usize].map(|v| self.coords[v as usize]);
        let mut lx = bc[0] * lc[0][0] + bc[1] * lc[1][0] + bc[2] * lc[2][0];
        let mut ly = bc[0] * lc[0][1] + bc[1] * lc[1][1] + bc[2] * lc[2][1];
        if let Some(cone) = &self.cone {
            let z = cone.apply(glam::DVec2::new(lx as f64, ly as f64));
            (lx, ly) = (z.x as f32, z.y as f32);
        }
        let layer = self.layer;
        Vec2::new(lx / layer.size[0] + 0.5, 0.5 - ly / layer.size[1])
    }

    /// The layer's premultiplied colour at image point `im`: tiled, warped, masked (clamped to the
    /// images' edges), a tool stamp's flat, times the opacity.
    fn shade(&self, im: Vec2) -> [f32; 4] {
        let flat_im = im;
        let mut im = im;
        if self.repeats > 0.0 {
            // Twin of FLAG_REPEAT (level 0: the twin has no mipmaps).
            im.x = (im.x * self.repeats).fract();
        }
        if let Some(t) = &self.warp {
            im = Vec2::from(t.eval(im.to_array()));
        }
        let mut s = sample_bilinear(&self.premult, im);
        if let Some(m) = self.mask {
            let mv = sample_bilinear(m, im);
            let f = mv[0] * mv[3];
            s = s.map(|v| v * f);
        }
        if let Some(f) = &self.flat {
            // Twin of `layer_raster`'s FLAG_TOOL: colour from the flat, shape = alpha.
            let c = sample_bilinear(f, flat_im);
            let shape = if c[3] > 0.0 { s[3] } else { 0.0 };
            s = [c[0] * shape, c[1] * shape, c[2] * shape, shape];
        }
        s.map(|v| v * self.layer.opacity)
    }
}

/// For every non-island texel, the squared distance to the nearest island texel and the island texels
/// at that distance (ties kept). Brute force: for small test textures only.
pub fn nearest_island(island: &[bool], w: u32, h: u32) -> Vec<Option<(u64, Vec<u32>)>> {
    let isl: Vec<(i64, i64)> = (0..w * h)
        .filter(|&i| island[i as usize])
        .map(|i| ((i % w) as i64, (i / w) as i64))
        .collect();
    (0..w * h)
        .map(|i| {
            if island[i as usize] || isl.is_empty() {
                return None;
            }
            let (x, y) = ((i % w) as i64, (i / w) as i64);
            let mut best = u64::MAX;
            let mut who = Vec::new();
            for &(ix, iy) in &isl {
                let d = ((ix - x).pow(2) + (iy - y).pow(2)) as u64;
                if d < best {
                    best = d;
                    who.clear();
                }
                if d == best {
                    who.push((iy * w as i64 + ix) as u32);
                }
            }
            Some((best, who))
        })
        .collect()
}

/// CPU twin of `edt_columns.wgsl` + `edt_rows.wgsl`: for every texel, the index of its nearest island
/// texel (exact Euclidean distance, Felzenszwalb & Huttenlocher 2012, separable), island texels
/// pointing at themselves, `u32::MAX` when there is no island. O(texels).
pub fn nearest_island_map(island: &[bool], w: u32, h: u32) -> Vec<u32> {
    let (wi, hi) = (w as usize, h as usize);
    let col_near = nearest_island_rows(island, wi, hi);
    // Pass 2, per row (rows are independent: split between the cores).
    let mut out = vec![u32::MAX; wi * hi];
    let threads = std::thread::available_parallelism().map_or(1, |t| t.get());
    let band = hi.div_ceil(threads).max(1);
    std::thread::scope(|s| {
        for (b, chunk) in out.chunks_mut((band * wi).max(1)).enumerate() {
            let col_near = &col_near;
            s.spawn(move || {
                let (mut v, mut z) = (vec![0i64; wi], vec![0f64; wi + 1]);
                for (r, row) in chunk.chunks_exact_mut(wi).enumerate() {
                    let y = b * band + r;
                    envelope_row(island, col_near, (wi, y), (&mut v, &mut z), row);
                }
            });
        }
    });
    out
}

/// Pass 1 of [`nearest_island_map`]: each texel's nearest island row in its column (`-1`: none),
/// the upper of two at the same distance. Walked row by row (one state per column), so that a
/// wide texture reads memory in order.
fn nearest_island_rows(island: &[bool], wi: usize, hi: usize) -> Vec<i32> {
    let mut col_near = vec![-1i32; wi * hi];
    let mut last = vec![-1i32; wi];
    for y in 0..hi {
        let row = &mut col_near[y * wi..(y + 1) * wi];
        for (x, c) in row.iter_mut().enumerate() {
            if island[y * wi + x] {
                last[x] = y as i32;
            }
            *c = last[x];
        }
    }
    let next = &mut last;
    next.fill(-1);
    for y in (0..hi).rev() {
        let row = &mut col_near[y * wi..(y + 1) * wi];
        for (x, c) in row.iter_mut().enumerate() {
            if island[y * wi + x] {
                next[x] = y as i32;
            }
            let (n, prev, yi) = (next[x], *c, y as i32);
            if n >= 0 && (prev < 0 || n - yi < yi - prev) {
                *c = n;
            }
        }
    }
    col_near
}

/// Pass 2 of [`nearest_island_map`] for row `y`: the lower envelope of the parabolas of the
/// row's island columns (`v`, `z`: scratch of `wi` and `wi + 1`), each texel's nearest written
/// to `out` (the row's `wi` entries).
fn envelope_row(
    island: &[bool],
    col_near: &[i32],
    (wi, y): (usize, usize),
    (v, z): (&mut [i64], &mut [f64]),
    out: &mut [u32],
) {
    let f = |q: i64| -> Option<i64> {
        let ny = col_near[y * wi + q as usize] as i64;
        (ny >= 0).then(|| (ny - y as i64).pow(2))
    };
    let mut k: i64 = -1;
    for q in 0..wi as i64 {
        let Some(fq) = f(q) else { continue };
        if k < 0 {
            k = 0;
            v[0] = q;
            z[0] = f64::NEG_INFINITY;
            z[1] = f64::INFINITY;
            continue;
        }
        let mut s;
        loop {
            let vk = v[k as usize];
            let fv = f(vk).expect("envelope holds island columns only");
            s = ((fq + q * q) - (fv + vk * vk)) as f64 / (2 * (q - vk)) as f64;
            if s <= z[k as usize] && k > 0 {
                k -= 1;
            } else {
                break;
            }
        }
        if s <= z[k as usize] {
            v[0] = q;
            z[0] = f64::NEG_INFINITY;
            z[1] = f64::INFINITY;
            k = 0;
            continue;
        }
        k += 1;
        v[k as usize] = q;
        z[k as usize] = s;
        z[k as usize + 1] = f64::INFINITY;
    }
    if k < 0 {
        return;
    }
    let mut j = 0usize;
    for (x, o) in out.iter_mut().enumerate() {
        while z[j + 1] < x as f64 {
            j += 1;
        }
        let idx = y * wi + x;
        if island[idx] {
            *o = idx as u32;
        } else {
            let vx = v[j] as usize;
            *o = (col_near[y * wi + vx] as usize * wi + vx) as u32;
        }
    }
}

/// What `select_triangles` produces for one layer.
#[derive(Debug, Clone, PartialEq)]
pub struct Selection {
    /// Covered triangles, ascending (the GPU appends in any order).
    pub triangles: Vec<u32>,
    /// Texel box (min x, min y, max x, max y), before UV wrapping.
    pub texel_box: [i32; 4],
}

impl Default for Selection {
    /// Nothing selected (a hidden chart).
    fn default() -> Self {
        Self {
            triangles: Vec::new(),
            texel_box: [i32::MAX, i32::MAX, i32::MIN, i32::MIN],
        }
    }
}

/// Twin of `planar_part_within_depth` in `wgsl/bake/select_triangles.wgsl`: whether the part of
/// the triangle with decal-frame corners `c` (x, y, depth) under the rectangle of half sides
/// `hx`, `hy` lies within `depth` everywhere (at that part's corners: the triangle clipped to the
/// rectangle in the kernel's order, each new corner `a + (b - a) * t` as WGSL's `mix`).
pub fn planar_part_within_depth(c: [[f32; 4]; 3], hx: f32, hy: f32, depth: f32) -> bool {
    // (depth, x, y), clipped by sgn * p[axis] + off >= 0 as `clip_side` does.
    let clip = |inp: &[[f32; 3]], axis: usize, sgn: f32, off: f32| -> Vec<[f32; 3]> {
        let mut out = Vec::with_capacity(inp.len() + 1);
        for i in 0..inp.len() {
            let (a, b) = (inp[i], inp[(i + 1) % inp.len()]);
            let (da, db) = (sgn * a[1 + axis] + off, sgn * b[1 + axis] + off);
            if da >= 0.0 {
                out.push(a);
            }
            if (da >= 0.0) != (db >= 0.0) {
                let t = da / (da - db);
                out.push([0, 1, 2].map(|k| a[k] * (1.0 - t) + b[k] * t));
            }
        }
        out
    };
    let p: Vec<[f32; 3]> = c.iter().map(|c| [c[2], c[0], c[1]]).collect();
    let p = clip(&p, 0, 1.0, hx);
    let p = clip(&p, 0, -1.0, hx);
    let p = clip(&p, 1, 1.0, hy);
    let p = clip(&p, 1, -1.0, hy);
    !p.is_empty() && p.iter().all(|q| q[0].abs() <= depth)
}

/// CPU twin of `select_triangles.wgsl`.
pub fn select_triangles(
    mesh: &Mesh,
    topo: &Topology,
    uvs: &[Vec2],
    (coords, cone): (&[[f32; 4]], Option<&Cone>),
    f: &Frame,
    facing: bool,
    tex: [u32; 2],
) -> Selection {
    let mut out = Selection {
        triangles: Vec::new(),
        texel_box: [i32::MAX, i32::MAX, i32::MIN, i32::MIN],
    };
    let (hx, hy) = (0.5 * f.size[0], 0.5 * f.size[1]);
    for (t, tri) in topo.triangles.iter().enumerate() {
        if topo.degenerate[t] {
            continue;
        }
        let c = tri.map(|v| coords[v as usize]);
        let part = |c: [[f32; 4]; 3]| planar_part_within_depth(c, hx, hy, f.depth);
        if c.iter().any(|c| c[3] < 0.5) && !(facing && part(c)) {
            continue;
        }
        let mut z = c.map(|c| Vec2::new(c[0], c[1]));
        let (mut hx, mut hy, mut cut) = (hx, hy, false);
        if let Some(cone) = cone {
            // Twin of the kernel's FLAG_CONE branch: the cut's triangles and those near the tip
            // are kept; the others are tested opened, with a margin of a tenth of their box.
            let w = z.map(|z| z.as_dvec2());
            cut = cone.cut_crosses(w) || cone.near_tip(w);
            z = w.map(|w| cone.apply(w).as_vec2());
            let ext = z[0].max(z[1]).max(z[2]) - z[0].min(z[1]).min(z[2]);
            hx += 0.1 * ext.max_element();
            hy += 0.1 * ext.max_element();
        }
        let lo = z[0].min(z[1]).min(z[2]);
        let hi = z[0].max(z[1]).max(z[2]);
        if !cut && (hi.x < -hx || lo.x > hx || hi.y < -hy || lo.y > hy) {
            continue;
        }
        if facing {
            let [a, b, cc] = tri.map(|v| topo.positions[v as usize]);
            if (b - a).cross(cc - a).dot(f.normal) <= 0.0 {
                continue;
            }
        }
        out.triangles.push(t as u32);
        let size = Vec2::new(tex[0] as f32, tex[1] as f32);
        let u = mesh.triangles[t].map(|s| uvs[s as usize] * size);
        let tlo = u[0].min(u[1]).min(u[2]).floor();
        let thi = u[0].max(u[1]).max(u[2]).ceil();
        out.texel_box[0] = out.texel_box[0].min(tlo.x as i32);
        out.texel_box[1] = out.texel_box[1].min(tlo.y as i32);
        out.texel_box[2] = out.texel_box[2].max(thi.x as i32);
        out.texel_box[3] = out.texel_box[3].max(thi.y as i32);
    }
    out
}
