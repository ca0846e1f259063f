// SPDX-License-Identifier: MIT OR Apache-2.0
//! The pixel size each layer's vector images (SVG files, text, `crate::io::vector`) are rendered
//! at, decided after placement from what each unit's map needs on the triangles it paints
//! (`super::vector_maps`; a stroke's stamps from the texel density where they land), within the
//! bake's budget ([`set_rasters`]), and a text layer's warnings (missing glyphs, text cut at its
//! curve's end).
//! The images stage ([`super::images`]) then renders them at that size.

use super::engine::{Engine, LoadedMesh};
use super::place::Placed;
use crate::io::job::{Job, Layer};

pub use super::vector_maps::VECTOR_OVERSAMPLE;

/// The longest side a vector image is rendered at (the adapter's texture limit may be lower).
pub const VECTOR_MAX_SIDE: u32 = crate::io::vector::MAX_SIDE;

/// The most pixels a vector image is rendered with: a layer that would need more is rendered at
/// this size, with its aspect.
pub const VECTOR_MAX_PIXELS: u64 = crate::io::vector::MAX_PIXELS;

/// Triangle `t`'s area on the surface and its UV area in texels (0 where it has none).
fn areas(mesh: &LoadedMesh, job: &Job, t: usize) -> (f32, f32) {
    let m = &mesh.mesh;
    let (Some(tri), Some(uv)) = (m.triangles.get(t), m.uv_sets.get(job.uv_set as usize)) else {
        return (0.0, 0.0);
    };
    let scale = glam::Vec2::new(job.width as f32, job.height as f32);
    let p = tri.map(|v| m.positions[v as usize]);
    let q = tri.map(|v| uv[v as usize] * scale);
    let surface = (p[1] - p[0]).cross(p[2] - p[0]).length();
    let texels = (q[1] - q[0]).perp_dot(q[2] - q[0]).abs();
    if surface.is_finite() && texels.is_finite() {
        (surface, texels)
    } else {
        (0.0, 0.0)
    }
}

/// Texels of the bake per model unit around triangle `t`: the square root of the UV area in
/// texels over the area on the surface of the triangles that share a vertex with it (an area
/// mean, so that one sliver does not decide); `None` where either is zero.
fn texel_density(mesh: &LoadedMesh, job: &Job, t: u32) -> Option<f32> {
    let topo = &mesh.topo;
    let tri = topo.triangles.get(t as usize)?;
    let mut ring: Vec<u32> = tri
        .iter()
        .flat_map(|&v| topo.triangles_around(v).iter().copied())
        .collect();
    ring.sort_unstable();
    ring.dedup();
    let (surface, texels) = ring.iter().fold((0.0f32, 0.0f32), |acc, &k| {
        let (s, x) = areas(mesh, job, k as usize);
        (acc.0 + s, acc.1 + x)
    });
    (surface > 0.0 && texels > 0.0).then(|| (texels / surface).sqrt())
}

/// The mesh's mean texel density over the UV set: where a layer's own triangle has none.
fn mean_density(mesh: &LoadedMesh, job: &Job) -> f32 {
    let (mut surface, mut texels) = (0.0f64, 0.0f64);
    let m = &mesh.mesh;
    let Some(uv) = m.uv_sets.get(job.uv_set as usize) else {
        return 1.0;
    };
    let scale = glam::Vec2::new(job.width as f32, job.height as f32);
    for tri in &m.triangles {
        let p = tri.map(|v| m.positions[v as usize]);
        let q = tri.map(|v| uv[v as usize] * scale);
        surface += (p[1] - p[0]).cross(p[2] - p[0]).length() as f64;
        texels += (q[1] - q[0]).perp_dot(q[2] - q[0]).abs() as f64;
    }
    if surface > 0.0 && texels > 0.0 {
        (texels / surface).sqrt() as f32
    } else {
        1.0
    }
}

/// Each triangle's [`texel_density`], kept for the bake.
type Densities = std::cell::RefCell<std::collections::HashMap<u32, Option<f32>>>;

/// Texels per model unit that unit `u`'s vector images need: the largest [`texel_density`] over
/// the triangles whose centroids lie in the ball around its placed point that holds its image
/// rectangle and that face the side it was placed on (not the far side of a thin part), so a
/// decal that reaches parts of the texture laid out denser than where it landed is drawn at their
/// density; a ribbon and text along a curve take the largest over the triangles their curve runs
/// through (the strip follows the curve, not a ball). For the units without a map's needs
/// (`super::vector_maps::unit_pixels`): a stroke's stamps, and a unit whose map paints nothing.
fn unit_density(
    (mesh, job, densities): (&LoadedMesh, &Job, &Densities),
    placed: &Placed,
    u: usize,
) -> Option<f32> {
    let density = |t: u32| {
        *densities
            .borrow_mut()
            .entry(t)
            .or_insert_with(|| texel_density(mesh, job, t))
    };
    let p = &placed.placements[u];
    let layer = &placed.job.layers[u];
    let landed = density(p.triangle);
    let densest = |tris: Vec<u32>| {
        tris.into_iter()
            .filter_map(density)
            .fold(landed, |a, d| Some(a.map_or(d, |a| a.max(d))))
    };
    if let Some(ribbon) = placed.ribbons.get(u).and_then(Option::as_ref) {
        let mut tris = ribbon.curve.triangles.clone();
        tris.sort_unstable();
        tris.dedup();
        return densest(tris);
    }
    let r = 0.5 * glam::Vec2::from(layer.size).length();
    if layer.ribbon.is_some() || !(r.is_finite() && r > 0.0) {
        return landed;
    }
    let (c, n) = (glam::Vec3::from(p.point), glam::Vec3::from(p.normal));
    let m = &mesh.mesh;
    let near_side = |tri: &[u32; 3]| {
        let [a, b, d] = tri.map(|v| m.positions[v as usize]);
        ((a + b + d) / 3.0).distance(c) <= r && (b - a).cross(d - a).dot(n) >= 0.0
    };
    let near = mesh
        .bvh
        .overlapping(c - glam::Vec3::splat(r), c + glam::Vec3::splat(r));
    // The BVH's leaf boxes hold more than the ball.
    densest(
        near.into_iter()
            .filter(|&t| m.triangles.get(t as usize).is_some_and(near_side))
            .collect(),
    )
}

/// The pixels along the image's x and y that a unit's image rectangle (`size`, model units) needs
/// at texel density `density` ([`unit_density`]): [`VECTOR_OVERSAMPLE`] pixels a texel.
fn density_pixels(size: [f32; 2], density: f32) -> [f32; 2] {
    size.map(|s| s * density * VECTOR_OVERSAMPLE)
}

/// The pixel size a unit's vector images are rendered at, for `need` pixels along x and y
/// ([`map_pixels`], [`density_pixels`]), within the limits above and the adapter's.
fn raster_size(need: [f32; 2], max_side: u32) -> [u32; 2] {
    let side = |s: f32| s.ceil().clamp(8.0, max_side as f32);
    let (mut w, mut h) = (side(need[0]), side(need[1]));
    let pixels = w as f64 * h as f64;
    if pixels > VECTOR_MAX_PIXELS as f64 {
        let k = (VECTOR_MAX_PIXELS as f64 / pixels).sqrt() as f32;
        w = (w * k).floor().max(1.0);
        h = (h * k).floor().max(1.0);
    }
    [w as u32, h as u32]
}

/// Sets [`Layer::raster`] of every layer with vector images (SVG files, text) in `job` and in
/// the units of `placed`: per job layer, the largest any of its units needs, from the unit's map
/// (`super::vector_maps::Needs`: the size that gives a share of its texels two pixels a texel)
/// or, for a stroke's stamps, from the densest texel layout its rectangle reaches
/// ([`unit_density`]). The share is the largest of `super::vector_maps::SHARES` whose sizes fit
/// [`VECTOR_BUDGET_PIXELS`]; past the last, [`within_budget`] scales them. Returns the job with
/// the rasters set (`job` itself when no layer has vectors), and warns of a lowered share, of a
/// text's missing glyphs and of text cut at its curve's end.
pub(crate) fn set_rasters<'a>(
    engine: &Engine,
    mesh: &LoadedMesh,
    job: &'a Job,
    placed: &mut Placed,
    log: &mut super::stage::Log,
) -> std::borrow::Cow<'a, Job> {
    let warnings = &mut log.warnings;
    if !job.layers.iter().any(Layer::has_vectors) {
        return std::borrow::Cow::Borrowed(job);
    }
    let max_side = engine.ctx.max_texture_side().min(VECTOR_MAX_SIDE);
    let mean = std::sync::OnceLock::new();
    // Each triangle's density, computed once for the bake's units.
    let densities = std::cell::RefCell::new(std::collections::HashMap::new());
    let t = std::time::Instant::now();
    let from_maps = super::vector_maps::unit_pixels(mesh, job, placed);
    log.timings.vector_maps_ms = super::stage::ms(t);
    // Units without a map's needs (a stroke's stamps) take the density where they land.
    let fixed: Vec<Option<[f32; 2]>> = (0..placed.job.layers.len())
        .map(|u| {
            let vectors = job.layers[placed.origin[u].0].has_vectors();
            (vectors && from_maps[u].is_none()).then(|| {
                let density = unit_density((mesh, job, &densities), placed, u)
                    .unwrap_or_else(|| *mean.get_or_init(|| mean_density(mesh, job)));
                density_pixels(placed.job.layers[u].size, density)
            })
        })
        .collect();
    let sizes_at = |share: f64| -> Vec<Option<[u32; 2]>> {
        let need = |u: usize| match &from_maps[u] {
            Some(needs) => needs.at(share),
            None => fixed[u].unwrap_or([0.0; 2]),
        };
        job.layers
            .iter()
            .enumerate()
            .map(|(l, layer)| {
                layer.has_vectors().then(|| {
                    placed.units_of[l].clone().fold([0u32; 2], |px, u| {
                        let r = raster_size(need(u), max_side);
                        [px[0].max(r[0]), px[1].max(r[1])]
                    })
                })
            })
            .collect()
    };
    let (share, mut sizes) = largest_share(&sizes_at);
    let shares = super::vector_maps::SHARES;
    if share < shares[0] {
        let percent = |s: f64| s * 100.0;
        warnings.push(format!(
            "the layers' vector images need {} pixels to give {:.0} % of the texels they paint two pixels a texel, above {VECTOR_BUDGET_PIXELS}; they are rendered for {:.0} % of them (fewer or smaller vector layers keep them sharp)",
            total_pixels(&sizes_at(shares[0])),
            percent(shares[0]),
            percent(share)
        ));
    }
    within_budget(&mut sizes, warnings);
    let mut out = job.clone();
    for (l, (layer, px)) in out.layers.iter_mut().zip(sizes).enumerate() {
        let Some(px) = px else { continue };
        let units = placed.units_of[l].clone();
        layer.raster = Some(px);
        if layer.text.is_some() && layer.ribbon.is_some() {
            // Text along a curve is one unit: its strip spans the curve's length.
            layer.size = placed.job.layers[units.start].size;
        }
        for u in units.clone() {
            placed.job.layers[u].raster = Some(px);
        }
        if let Some(t) = &layer.text {
            text_warnings(l, t, units.map(|u| &placed.job.layers[u]), warnings);
        }
    }
    std::borrow::Cow::Owned(out)
}

/// The most pixels a bake's vector images take together (2²⁵: 512 MiB as f32 RGBA before
/// mipmaps); past it every layer's size is scaled down by one factor, with a warning.
pub const VECTOR_BUDGET_PIXELS: u64 = 1 << 25;

/// Scales every raster size down by one factor when together they pass
/// [`VECTOR_BUDGET_PIXELS`], and warns.
fn within_budget(sizes: &mut [Option<[u32; 2]>], warnings: &mut Vec<String>) {
    let total = total_pixels(sizes);
    if total <= VECTOR_BUDGET_PIXELS {
        return;
    }
    let k = (VECTOR_BUDGET_PIXELS as f64 / total as f64).sqrt();
    for p in sizes.iter_mut().flatten() {
        *p = p.map(|s| ((s as f64 * k).floor() as u32).max(8));
    }
    warnings.push(format!(
        "the layers' vector images need {total} pixels together, above {VECTOR_BUDGET_PIXELS}; each is rendered at {:.0} % of its size (fewer or smaller vector layers keep them sharp)",
        k * 100.0
    ));
}

/// The largest share of the texels the layers paint (`super::vector_maps::SHARES`) whose sizes
/// (`sizes_at`) fit [`VECTOR_BUDGET_PIXELS`] together, with those sizes; the smallest share and
/// its sizes when none does.
fn largest_share(sizes_at: &dyn Fn(f64) -> Vec<Option<[u32; 2]>>) -> (f64, Vec<Option<[u32; 2]>>) {
    let shares = super::vector_maps::SHARES;
    for &s in &shares[..shares.len() - 1] {
        let at = sizes_at(s);
        if total_pixels(&at) <= VECTOR_BUDGET_PIXELS {
            return (s, at);
        }
    }
    let last = shares[shares.len() - 1];
    (last, sizes_at(last))
}

/// The pixels of `sizes` together.
fn total_pixels(sizes: &[Option<[u32; 2]>]) -> u64 {
    sizes
        .iter()
        .flatten()
        .map(|p| p[0] as u64 * p[1] as u64)
        .sum()
}

/// Warnings of text layer `l`: characters its font lacks, and text cut at its curve's end.
fn text_warnings<'a>(
    l: usize,
    t: &crate::io::text::Text,
    units: impl Iterator<Item = &'a Layer>,
    warnings: &mut Vec<String>,
) {
    if !t.block.missing.is_empty() {
        let chars: String = t.block.missing.iter().collect();
        warnings.push(format!(
            "layers[{l}].text: the font has no glyph for {chars:?}; drawn as its missing-glyph box (.notdef); choose a font that covers them"
        ));
    }
    for unit in units.filter(|u| u.ribbon.is_some()) {
        if t.fit_on(unit.size[0]).1 {
            warnings.push(format!(
                "layers[{l}].text is longer than its curve ({:.4} model units) and is cut at its end; lengthen the path, lower `size`, or set \"fit\": \"shrink\"",
                unit.size[0]
            ));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Sizes under the budget are kept; over it, all are scaled by one factor to within it, with
    /// a warning (leaving them whole fails the total's check).
    #[test]
    fn rasters_keep_within_the_budget() {
        let mut warnings = Vec::new();
        let mut small = vec![Some([1024, 512]), None];
        within_budget(&mut small, &mut warnings);
        assert_eq!(small, [Some([1024, 512]), None]);
        assert!(warnings.is_empty());
        let mut big = vec![Some([8192, 4096]), None, Some([4096, 4096])];
        within_budget(&mut big, &mut warnings);
        let total: u64 = big
            .iter()
            .flatten()
            .map(|p| p[0] as u64 * p[1] as u64)
            .sum();
        assert!(total <= VECTOR_BUDGET_PIXELS, "{total}");
        let [a, c] = [big[0].unwrap(), big[2].unwrap()];
        assert_eq!(a[0], 2 * a[1], "the aspect is kept: {a:?}");
        assert_eq!(a[1], c[1], "one factor for all: {a:?} {c:?}");
        assert_eq!(warnings.len(), 1);
    }

    /// Over the budget, the share of texels given two pixels a texel is lowered for all layers at
    /// once: a layer whose needs spread (a planar decal over steep parts) shrinks, one whose
    /// needs are even keeps its size (scaling both by one factor would shrink it too).
    #[test]
    fn a_lower_share_shrinks_the_spread_needs_first() {
        // Layer 0: 95 % of its texels need 2,048 pixels a side, 5 % need 8,192; layer 1: 3,000.
        let sizes_at = |share: f64| {
            let spread = if share > 0.95 { 8192 } else { 2048 };
            vec![Some([spread, spread]), None, Some([3000, 3000])]
        };
        assert!(total_pixels(&sizes_at(0.99)) > VECTOR_BUDGET_PIXELS);
        let (share, sizes) = largest_share(&sizes_at);
        assert_eq!(share, 0.95);
        assert_eq!(sizes, [Some([2048, 2048]), None, Some([3000, 3000])]);
        // Needs that fit at the first share keep it.
        let small = |_: f64| vec![Some([1024, 1024])];
        assert_eq!(largest_share(&small), (0.99, vec![Some([1024, 1024])]));
    }

    /// A raster covers its rectangle at two pixels a texel, within the side limit.
    #[test]
    fn raster_sizes_follow_the_density() {
        let px = |size, density| raster_size(density_pixels(size, density), 8192);
        assert_eq!(px([0.5, 0.25], 256.0), [256, 128]);
        assert_eq!(px([100.0, 1.0], 256.0), [8192, 512]);
        assert_eq!(px([0.001, 0.001], 256.0), [8, 8]);
    }
}
