// SPDX-License-Identifier: MIT OR Apache-2.0
//! The pixels a unit's vector images need, from the unit's own map: the Jacobian of texel →
//! image coordinates on every triangle the unit paints ([`unit_pixels`]). The map is the one the
//! map stage computes, by its CPU twin ([`crate::bake::cpu::layer_coords_cpu`],
//! [`crate::bake::cpu::ribbon_coords_cpu`]), and the triangles are the selection's
//! ([`crate::bake::cpu::select_triangles`]), so a planar projection that compresses the image on a
//! slope, a chart whose scale grows away from its centre, a warp and a denser part of the UV
//! layout all raise the size where they do, and along the axis where they do.

use super::cpu::{layer_coords_cpu, ribbon_coords_cpu, select_triangles};
use super::engine::{LoadedMesh, VectorNeeds};
use super::place::Placed;
use crate::io::job::Job;
use glam::Vec2;
use rayon::prelude::*;

/// How many image pixels a vector image gets per texel it covers, along each side: its samples
/// then read the first mipmap level, a box over 2 × 2 pixels, and edges keep the bake's own
/// anti-aliasing.
pub const VECTOR_OVERSAMPLE: f32 = 2.0;

/// The shares of the texels a unit paints whose triangles get [`VECTOR_OVERSAMPLE`] pixels a
/// texel, tried in order until the bake's vector images fit their budget
/// (`super::vector::VECTOR_BUDGET_PIXELS`): never all of them, so that the steepest slopes of a
/// planar projection and slivers do not decide the size of a whole image for a few texels.
pub const SHARES: [f64; 8] = [0.99, 0.98, 0.95, 0.9, 0.8, 0.7, 0.6, 0.5];

/// What one unit's triangles need ([`map_pixels`]): along x and along y, each need with
/// the triangle's texels, ascending.
#[derive(Debug, Clone)]
pub(crate) struct Needs {
    axes: std::sync::Arc<VectorNeeds>,
    texels: f64,
}

impl Needs {
    /// From (need along x and y, texels) per triangle; `None` when there are none.
    fn new(needs: &[([f32; 2], f64)]) -> Option<Needs> {
        if needs.is_empty() {
            return None;
        }
        let axes = [0, 1].map(|a| {
            let mut v: Vec<(f32, f64)> = needs.iter().map(|n| (n.0[a], n.1)).collect();
            v.sort_by(|p, q| p.0.total_cmp(&q.0));
            v
        });
        Some(Needs::of(std::sync::Arc::new(axes)))
    }

    /// From the needs kept for a unit.
    fn of(axes: std::sync::Arc<VectorNeeds>) -> Needs {
        let texels = axes[0].iter().map(|n| n.1).sum();
        Needs { axes, texels }
    }

    /// The least size along x and y that `share` of the unit's texels are content with.
    pub(crate) fn at(&self, share: f64) -> [f32; 2] {
        [0, 1].map(|a| covering(&self.axes[a], self.texels * share))
    }
}

/// Per unit of `placed`: what its triangles need along the image's x and y, from its map
/// ([`map_pixels`]); `None` for a unit of a layer without vector images, a stroke's stamp
/// (its stamps are many and small: the texel density where they land decides,
/// `super::vector::unit_density`), and a unit whose map paints nothing. The units are mapped in
/// parallel, each on its own.
pub(crate) fn unit_pixels(mesh: &LoadedMesh, job: &Job, placed: &Placed) -> Vec<Option<Needs>> {
    let mapped = |u: usize| {
        let (l, _) = placed.origin[u];
        job.layers[l].has_vectors() && !placed.strokes.iter().any(|s| s.units.contains(&u))
    };
    (0..placed.job.layers.len())
        .into_par_iter()
        .map(|u| mapped(u).then(|| kept_pixels(mesh, placed, u)).flatten())
        .collect()
}

/// The most units whose needs a mesh keeps; past it the kept ones are forgotten.
const KEPT_UNITS: usize = 4096;

/// [`map_pixels`] of unit `u`, kept by the mesh ([`LoadedMesh::vector_needs`]) under a key that
/// names what the map and the selection read: the unit's layer (every field), frame, placement
/// and ribbon, the UV set and the texture's size.
fn kept_pixels(mesh: &LoadedMesh, placed: &Placed, u: usize) -> Option<Needs> {
    let job = &placed.job;
    let key = format!(
        "{:?}|{:?}|{:?}|{:?}|{}|{}x{}",
        job.layers[u],
        placed.frames[u],
        placed.placements[u],
        placed.ribbons.get(u),
        job.uv_set,
        job.width,
        job.height
    );
    if let Some(kept) = mesh.vector_needs.lock().expect("vector needs").get(&key) {
        return kept.clone().map(Needs::of);
    }
    let needs = map_pixels(mesh, placed, u);
    let mut kept = mesh.vector_needs.lock().expect("vector needs");
    if kept.len() >= KEPT_UNITS {
        kept.clear();
    }
    kept.insert(key, needs.as_ref().map(|n| n.axes.clone()));
    needs
}

/// Unit `u`'s map by the CPU twin of the map stage: (x, y, extra, valid) per welded vertex, and
/// a cone chart's cone.
fn unit_map(
    mesh: &LoadedMesh,
    placed: &Placed,
    u: usize,
) -> (Vec<[f32; 4]>, Option<crate::maps::chart::cone::Cone>) {
    match placed.ribbons.get(u).and_then(Option::as_ref) {
        Some(r) => (ribbon_coords_cpu(&mesh.topo, r), None),
        None => {
            let (layer, frame) = (&placed.job.layers[u], &placed.frames[u]);
            let c = layer_coords_cpu(
                &mesh.topo,
                &mesh.surface,
                layer,
                frame,
                &placed.placements[u],
                true,
            );
            (c.coords, c.cone)
        }
    }
}

/// The pixels along the image's x and y that unit `u`'s vector images need: on each triangle it
/// paints, the map from image coordinates to texels is affine, J = E D⁻¹ (E the triangle's texel
/// edges, D its image edges); one image pixel along x spans |J e_x| / width texels, so two pixels a
/// texel need a width of 2 |J e_x|, and likewise a height of 2 |J e_y|. Where the image is not
/// sampled at the image point itself, J is taken through the sampling's own Jacobian S at the
/// triangle's centre: a tiled ribbon's image repeats `repeats` times along x, and a warp samples
/// it at T(image point) (of each copy), so J S⁻¹. Each triangle weighs its texels that lie in the
/// image ([`share_in_image`]). A cone chart's triangles that its cut crosses are left out (their corners open onto both sides of the cut). `None` when it paints no
/// triangle.
pub(crate) fn map_pixels(mesh: &LoadedMesh, placed: &Placed, u: usize) -> Option<Needs> {
    let job = &placed.job;
    let (layer, frame) = (&job.layers[u], &placed.frames[u]);
    let uvs = mesh.mesh.uv_sets.get(job.uv_set as usize)?;
    let (coords, cone) = unit_map(mesh, placed, u);
    let facing = crate::maps::method(layer.method).front_facing();
    let tex = [job.width, job.height];
    let sel = select_triangles(
        &mesh.mesh,
        &mesh.topo,
        uvs,
        (&coords, cone.as_ref()),
        frame,
        facing,
        tex,
    );
    let repeats = placed
        .ribbons
        .get(u)
        .and_then(Option::as_ref)
        .map_or(0.0, |r| r.repeats);
    let sampling = Sampling {
        repeats,
        warp: crate::maps::warp::Tps::fit(&layer.warp),
    };
    let scale = Vec2::new(tex[0] as f32, tex[1] as f32);
    let image_point = |c: [f32; 4]| {
        let (mut x, mut y) = (c[0], c[1]);
        if let Some(cone) = &cone {
            let z = cone.apply(glam::DVec2::new(x as f64, y as f64));
            (x, y) = (z.x as f32, z.y as f32);
        }
        Vec2::new(x / layer.size[0] + 0.5, 0.5 - y / layer.size[1])
    };
    let mut needs: Vec<([f32; 2], f64)> = Vec::with_capacity(sel.triangles.len());
    for &t in &sel.triangles {
        let welded = mesh.topo.triangles[t as usize].map(|v| coords[v as usize]);
        if welded.iter().any(|c| c[3] < 0.5) {
            continue;
        }
        if let Some(cone) = &cone {
            if cone.cut_crosses(welded.map(|c| glam::DVec2::new(c[0] as f64, c[1] as f64))) {
                continue;
            }
        }
        let i = welded.map(image_point);
        let e = mesh.mesh.triangles[t as usize].map(|v| uvs[v as usize] * scale);
        let Some(j) = triangle_jacobian(e, i) else {
            continue;
        };
        let j = match sampling.jacobian((i[0] + i[1] + i[2]) / 3.0) {
            Some(s) if s.determinant().abs() > 1e-12 => j * s.inverse(),
            Some(_) => continue,
            None => j,
        };
        let need = [j.x_axis.length(), j.y_axis.length()].map(|s| s * VECTOR_OVERSAMPLE);
        // The texels of the triangle that lie in the image: those the layer paints.
        let inside = share_in_image(i, repeats > 0.0);
        if need.iter().all(|n| n.is_finite()) && inside > 0.0 {
            let texels = ((e[1] - e[0]).perp_dot(e[2] - e[0]).abs() * 0.5) as f64;
            needs.push((need, texels * inside as f64));
        }
    }
    Needs::new(&needs)
}

/// The share of a triangle's area (image corners `i`, affine on it as its texels are) that lies in
/// the image square [0, 1]², or, for an image repeated along x (`repeating`), in the band
/// 0 ≤ y ≤ 1: the triangle clipped by each side in turn (Sutherland-Hodgman) over its whole area.
fn share_in_image(i: [Vec2; 3], repeating: bool) -> f32 {
    let area = |p: &[Vec2]| {
        let n = p.len();
        (0..n)
            .map(|k| p[k].perp_dot(p[(k + 1) % n]))
            .sum::<f32>()
            .abs()
            * 0.5
    };
    let whole = area(&i);
    if !whole.is_normal() {
        return 0.0;
    }
    // Each side as (axis, bound, keep the side below it).
    let sides: &[(usize, f32, bool)] = if repeating {
        &[(1, 0.0, false), (1, 1.0, true)]
    } else {
        &[
            (0, 0.0, false),
            (0, 1.0, true),
            (1, 0.0, false),
            (1, 1.0, true),
        ]
    };
    let mut poly: Vec<Vec2> = i.to_vec();
    for &(axis, bound, below) in sides {
        let keep = |p: Vec2| (p[axis] <= bound) == below || p[axis] == bound;
        let mut out = Vec::with_capacity(poly.len() + 2);
        for k in 0..poly.len() {
            let (a, b) = (poly[k], poly[(k + 1) % poly.len()]);
            if keep(a) {
                out.push(a);
            }
            if keep(a) != keep(b) {
                let t = (bound - a[axis]) / (b[axis] - a[axis]);
                out.push(a + (b - a) * t);
            }
        }
        poly = out;
        if poly.len() < 3 {
            return 0.0;
        }
    }
    (area(&poly) / whole).clamp(0.0, 1.0)
}

/// How the raster samples a unit's image at an image point: copies along x, then a warp.
struct Sampling {
    /// Copies of the image along x (a tiled ribbon); 0 for one.
    repeats: f32,
    /// The layer's thin-plate spline, applied to each copy.
    warp: Option<crate::maps::warp::Tps>,
}

impl Sampling {
    /// The Jacobian of the sampled point over the image point at `p`; `None` where the image is
    /// sampled at the image point itself. The warp's by central differences.
    fn jacobian(&self, p: Vec2) -> Option<glam::Mat2> {
        let r = if self.repeats > 0.0 {
            self.repeats
        } else {
            1.0
        };
        let copies = glam::Mat2::from_diagonal(Vec2::new(r, 1.0));
        let Some(t) = &self.warp else {
            return (self.repeats > 0.0).then_some(copies);
        };
        let x = if self.repeats > 0.0 {
            (p.x * r).rem_euclid(1.0)
        } else {
            p.x
        };
        let h = 1e-3;
        let at = |dx: f32, dy: f32| Vec2::from(t.eval([x + dx, p.y + dy]));
        let tx = (at(h, 0.0) - at(-h, 0.0)) / (2.0 * h);
        let ty = (at(0.0, h) - at(0.0, -h)) / (2.0 * h);
        Some(glam::Mat2::from_cols(tx, ty) * copies)
    }
}

/// The Jacobian of texels over image coordinates of a triangle with texel corners `e` and image
/// corners `i` (J = E D⁻¹; its columns are the texels one image unit spans along x and y); `None`
/// for a triangle degenerate in either space.
fn triangle_jacobian(e: [Vec2; 3], i: [Vec2; 3]) -> Option<glam::Mat2> {
    let (e1, e2) = (e[1] - e[0], e[2] - e[0]);
    let (d1, d2) = (i[1] - i[0], i[2] - i[0]);
    let det = d1.perp_dot(d2);
    if e1.perp_dot(e2) == 0.0 || !det.is_normal() {
        return None;
    }
    // D⁻¹ = [d2.y, −d2.x; −d1.y, d1.x] / det; J's columns are E times D⁻¹'s columns.
    let jx = (e1 * d2.y - e2 * d1.y) / det;
    let jy = (e2 * d1.x - e1 * d2.x) / det;
    Some(glam::Mat2::from_cols(jx, jy))
}

/// The pixels along x and y a triangle with texel corners `e` and image corners `i` needs, sampled
/// at the image point itself: [`VECTOR_OVERSAMPLE`] times the lengths of the columns of
/// [`triangle_jacobian`].
#[cfg(test)]
fn triangle_pixels(e: [Vec2; 3], i: [Vec2; 3]) -> Option<[f32; 2]> {
    let j = triangle_jacobian(e, i)?;
    Some([j.x_axis.length(), j.y_axis.length()].map(|s| s * VECTOR_OVERSAMPLE))
}

/// The least need in `sorted` (need, texels, ascending) whose texels and those of every smaller
/// need reach `texels`; 0 when there are none.
fn covering(sorted: &[(f32, f64)], texels: f64) -> f32 {
    let mut below = 0.0;
    for &(need, t) in sorted {
        below += t;
        if below >= texels {
            return need;
        }
    }
    sorted.last().map_or(0.0, |n| n.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An image stretched twice as fast along x as y over texels: x needs half the pixels of y;
    /// a turned map gives the same lengths; a degenerate triangle none.
    #[test]
    fn triangle_pixels_are_the_jacobians_columns() {
        let e = [Vec2::ZERO, Vec2::new(100.0, 0.0), Vec2::new(0.0, 100.0)];
        let i = [Vec2::ZERO, Vec2::new(0.5, 0.0), Vec2::new(0.0, 0.25)];
        let need = triangle_pixels(e, i).unwrap();
        assert_eq!(need, [400.0, 800.0]);
        // Texels turned by 90°: the same spans.
        let turned = e.map(|p| Vec2::new(-p.y, p.x));
        let t = triangle_pixels(turned, i).unwrap();
        assert!(
            (t[0] - 400.0).abs() < 1e-3 && (t[1] - 800.0).abs() < 1e-3,
            "{t:?}"
        );
        let flat = [Vec2::ZERO, Vec2::new(0.5, 0.0), Vec2::new(1.0, 0.0)];
        assert_eq!(triangle_pixels(e, flat), None);
    }

    /// The share of a triangle in the image: whole inside, half across a side, none outside; a
    /// repeated image is bounded only in y.
    #[test]
    fn the_share_in_the_image_clips_by_its_sides() {
        let tri = |o: Vec2| [o, o + Vec2::new(0.2, 0.0), o + Vec2::new(0.0, 0.2)];
        assert!((share_in_image(tri(Vec2::splat(0.4)), false) - 1.0).abs() < 1e-6);
        assert_eq!(share_in_image(tri(Vec2::new(1.5, 0.4)), false), 0.0);
        // Across x = 1 at its legs' middle: the part left of it is 3/4 of the area.
        let across = share_in_image(tri(Vec2::new(0.9, 0.4)), false);
        assert!((across - 0.75).abs() < 1e-5, "{across}");
        assert!((share_in_image(tri(Vec2::new(1.5, 0.4)), true) - 1.0).abs() < 1e-6);
        // Over the image's corner, cut by both x = 0 and y = 0: the part inside has legs 0.2 of
        // the whole's 0.4.
        let big = [
            Vec2::new(-0.1, -0.1),
            Vec2::new(0.3, -0.1),
            Vec2::new(-0.1, 0.3),
        ];
        let corner = share_in_image(big, false);
        assert!((corner - 0.25).abs() < 1e-5, "{corner}");
    }

    /// A tiled image's copies along x and a warp that doubles x divide what the image needs along
    /// x by the copies and by two; a plain image is sampled where it lies.
    #[test]
    fn the_sampling_jacobian_takes_copies_and_warps() {
        let plain = Sampling {
            repeats: 0.0,
            warp: None,
        };
        assert_eq!(plain.jacobian(Vec2::splat(0.5)), None);
        let tiled = Sampling {
            repeats: 4.0,
            warp: None,
        };
        let s = tiled.jacobian(Vec2::splat(0.3)).unwrap();
        assert_eq!(s, glam::Mat2::from_diagonal(Vec2::new(4.0, 1.0)));
        // T(x, y) = (2x − 0.5, y): four pairs [from, to] with T(to) = from, at the corners (which
        // are then not pinned), fit it exactly (affine, no bending).
        let pairs = [[0.0f32, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]]
            .map(|p| [[2.0 * p[0] - 0.5, p[1]], p]);
        let warp = crate::maps::warp::Tps::fit(&pairs);
        assert!(warp.is_some());
        let warped = Sampling { repeats: 3.0, warp };
        let s = warped.jacobian(Vec2::new(0.7, 0.4)).unwrap();
        assert!((s.x_axis - Vec2::new(6.0, 0.0)).length() < 1e-2, "{s:?}");
        assert!((s.y_axis - Vec2::new(0.0, 1.0)).length() < 1e-2, "{s:?}");
        // What a triangle needs along x through it: a sixth.
        let e = [Vec2::ZERO, Vec2::new(100.0, 0.0), Vec2::new(0.0, 100.0)];
        let i = [Vec2::ZERO, Vec2::new(0.5, 0.0), Vec2::new(0.0, 0.25)];
        let j = triangle_jacobian(e, i).unwrap() * s.inverse();
        assert!((j.x_axis.length() - 200.0 / 6.0).abs() < 0.1, "{j:?}");
        assert!((j.y_axis.length() - 400.0).abs() < 0.5, "{j:?}");
    }

    /// The size at a share leaves out the last texels, not the last triangle; each axis is sorted
    /// on its own.
    #[test]
    fn the_size_at_a_share_leaves_out_the_last_texels() {
        let needs = Needs::new(&[
            ([10.0, 3.0], 98.0),
            ([20.0, 2.0], 1.5),
            ([1000.0, 1.0], 0.5),
        ])
        .unwrap();
        assert_eq!(needs.at(0.99), [20.0, 3.0]);
        assert_eq!(needs.at(0.5), [10.0, 3.0]);
        assert_eq!(needs.at(1.0), [1000.0, 3.0]);
        let big = Needs::new(&[([10.0, 1.0], 90.0), ([1000.0, 3.0], 10.0)]).unwrap();
        assert_eq!(big.at(0.99), [1000.0, 3.0]);
        assert_eq!(big.at(0.85), [10.0, 1.0]);
        assert!(Needs::new(&[]).is_none());
    }
}
