// SPDX-License-Identifier: MIT OR Apache-2.0
//! Packing pelts into [0, 1]² (several pelts, with a margin in texels for a
//! given texture size): by their boxes with `etagere`'s shelf allocator ([`pack`]), then by their
//! shapes on a grid ([`pack_shapes`], which `pelt::unwrap` uses). `decalbake bench --unwrap`
//! reports the texture used (`quality.texel_utilisation`): 53-62 % where there are several pelts,
//! against 41-47 % with the shelf packing alone (commit d77dedc, docs/unwrap.md's history).
//!
//! Every pelt is first scaled so its UV area equals its 3D area (the same texel density on every
//! piece), then one global scale, the largest for which every pelt's box plus `margin` texels on each
//! side fits the `size`² texture, is found by bisection. The boxes are placed tallest first, in
//! horizontal or vertical shelves, in one to three columns: whichever fits the largest scale.

use glam::DVec2;
use rayon::prelude::*;

/// Where each pelt goes: `uv = offset + (p − lo) · scale`, in [0, 1]².
#[derive(Debug, Clone)]
pub struct Placement {
    /// Per pelt: its box's low corner in its own coordinates.
    pub lo: Vec<DVec2>,
    /// Per pelt: where that corner lands in [0, 1]².
    pub offset: Vec<DVec2>,
    /// Per pelt: UV units per unit of its own coordinates.
    pub scale: Vec<f64>,
    /// Per pelt: how many quarter turns (counter-clockwise, `(x, y) → (−y, x)`) it is turned
    /// before `lo` is taken off ([`Placement::uv`]).
    pub turn: Vec<u8>,
}

impl Placement {
    /// Where pelt `i`'s point `p` (its own coordinates) lands in [0, 1]².
    pub fn uv(&self, i: usize, p: DVec2) -> DVec2 {
        let q = (0..self.turn[i]).fold(p, |q, _| q.perp());
        self.offset[i] + (q - self.lo[i]) * self.scale[i]
    }
}

/// Packs pelts given by their boxes (`lo`, `hi`, in their own coordinates) and `density` (UV units
/// per own unit that gives every pelt the same texel density) into a `size`² texture with `margin`
/// texels round each.
pub fn pack(boxes: &[(DVec2, DVec2)], density: &[f64], size: u32, margin: u32) -> Placement {
    // Shelf layouts differ a lot with a few large pelts: try several and keep the largest scale.
    let mut best: Option<Placement> = None;
    for vertical_shelves in [false, true] {
        for num_columns in [1, 2, 3] {
            let options = etagere::AllocatorOptions {
                vertical_shelves,
                num_columns,
                ..etagere::DEFAULT_OPTIONS
            };
            let p = pack_with(&options, boxes, density, size, margin);
            if best
                .as_ref()
                .is_none_or(|b| p.scale.first() > b.scale.first())
            {
                best = Some(p);
            }
        }
    }
    best.expect("six layouts tried")
}

/// [`pack`] with one allocator layout.
fn pack_with(
    options: &etagere::AllocatorOptions,
    boxes: &[(DVec2, DVec2)],
    density: &[f64],
    size: u32,
    margin: u32,
) -> Placement {
    let fits = |s: f64| -> Option<Vec<DVec2>> {
        let mut alloc = etagere::AtlasAllocator::with_options(
            etagere::size2(size as i32, size as i32),
            options,
        );
        let mut order: Vec<usize> = (0..boxes.len()).collect();
        let dims: Vec<(i32, i32)> = boxes
            .iter()
            .zip(density)
            .map(|((lo, hi), d)| {
                let e = (*hi - *lo) * (s * d * size as f64);
                (
                    e.x.ceil() as i32 + 2 * margin as i32 + 1,
                    e.y.ceil() as i32 + 2 * margin as i32 + 1,
                )
            })
            .collect();
        order.sort_by_key(|&i| std::cmp::Reverse((dims[i].1, dims[i].0)));
        let mut at = vec![DVec2::ZERO; boxes.len()];
        for i in order {
            let (w, h) = dims[i];
            if w > size as i32 || h > size as i32 {
                return None;
            }
            let a = alloc.allocate(etagere::size2(w, h))?;
            at[i] = DVec2::new(
                (a.rectangle.min.x + margin as i32) as f64,
                (a.rectangle.min.y + margin as i32) as f64,
            ) / size as f64;
        }
        Some(at)
    };
    // Bracket: s = 1 / (the largest pelt's largest side) fits one pelt alone.
    let largest = boxes
        .iter()
        .zip(density)
        .map(|((lo, hi), d)| (*hi - *lo).max_element() * d)
        .fold(f64::MIN_POSITIVE, f64::max);
    let (mut lo_s, mut hi_s) = (0.0, 1.0 / largest);
    let mut best = fits(lo_s).unwrap_or_else(|| vec![DVec2::ZERO; boxes.len()]);
    for _ in 0..30 {
        let mid = 0.5 * (lo_s + hi_s);
        match fits(mid) {
            Some(at) => {
                lo_s = mid;
                best = at;
            }
            None => hi_s = mid,
        }
    }
    Placement {
        lo: boxes.iter().map(|b| b.0).collect(),
        offset: best,
        scale: density.iter().map(|d| d * lo_s).collect(),
        turn: vec![0; boxes.len()],
    }
}

/// A pelt's layout in its own coordinates, for [`pack_shapes`].
#[derive(Debug, Clone, Copy)]
pub struct Shape<'a> {
    /// Its vertices.
    pub points: &'a [DVec2],
    /// Its triangles.
    pub triangles: &'a [[u32; 3]],
}

/// Cells across the occupancy grid of [`pack_shapes`] (at most the texture's size).
pub const GRID: u32 = 256;

/// Packs pelts by their shapes, not only their boxes: the box packing ([`pack`]) gives a scale that
/// fits; then the largest scale (bisection, up to the one at which the pelts' areas fill the
/// square) at which every pelt's rasterised footprint (the cells its triangles' boxes touch, grown
/// by the margin) finds room on a grid of [`GRID`]² cells, placed largest first at the lowest, then
/// leftmost free spot (bottom-left fill), so pelts nest in each other's bays as they do in xatlas's
/// packer. Whichever of the two gives the larger scale is kept.
pub fn pack_shapes(shapes: &[Shape], density: &[f64], size: u32, margin: u32) -> Placement {
    let boxes: Vec<(DVec2, DVec2)> = shapes.iter().map(|s| bounds(s.points)).collect();
    let by_box = pack(&boxes, density, size, margin);
    let Some(&d0) = density.first() else {
        return by_box;
    };
    let s_box = by_box.scale[0] / d0;
    let area: f64 = shapes
        .iter()
        .zip(density)
        .map(|(s, d)| shape_area(s) * d * d)
        .sum();
    let s_full = (1.0 / area.max(f64::MIN_POSITIVE)).sqrt();
    let g = GRID.min(size).max(1);
    let grow = (margin as f64 * g as f64 / size as f64).ceil() as i32;
    let turned_points: Vec<Vec<Vec<DVec2>>> = (1..4)
        .map(|k| {
            shapes
                .iter()
                .map(|s| {
                    s.points
                        .iter()
                        .map(|p| (0..k).fold(*p, |q, _| q.perp()))
                        .collect()
                })
                .collect()
        })
        .collect();
    let turned: Vec<Vec<Shape>> = turned_points
        .iter()
        .map(|pts| {
            shapes
                .iter()
                .zip(pts)
                .map(|(s, q)| Shape {
                    points: q,
                    triangles: s.triangles,
                })
                .collect()
        })
        .collect();
    let both = [shapes, &turned[0][..], &turned[1][..], &turned[2][..]];
    let (mut lo_s, mut hi_s, mut best) = (s_box, s_full.max(s_box), None);
    for _ in 0..10 {
        let mid = 0.5 * (lo_s + hi_s);
        match fill(both, density, mid, g, grow) {
            Some(cells) => {
                lo_s = mid;
                best = Some(cells);
            }
            None => hi_s = mid,
        }
    }
    let Some(cells) = best else {
        return by_box;
    };
    Placement {
        lo: cells
            .iter()
            .enumerate()
            .map(|(i, c)| bounds(both[usize::from(c.2)][i].points).0)
            .collect(),
        offset: cells
            .iter()
            .map(|&(x, y, _)| DVec2::new(x as f64, y as f64) / g as f64)
            .collect(),
        scale: density.iter().map(|d| d * lo_s).collect(),
        turn: cells.iter().map(|c| c.2).collect(),
    }
}

fn bounds(points: &[DVec2]) -> (DVec2, DVec2) {
    points.iter().fold((DVec2::MAX, DVec2::MIN), |(lo, hi), p| {
        (lo.min(*p), hi.max(*p))
    })
}

fn shape_area(s: &Shape) -> f64 {
    s.triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| s.points[i as usize]);
            0.5 * (b - a).perp_dot(c - a).abs()
        })
        .sum()
}

/// One pelt's footprint: per row (bottom up), the span of cells it covers, grown by the margin,
/// relative to the cell of its box's low corner minus the margin.
struct Footprint {
    rows: Vec<(i32, i32)>,
    width: i32,
}

fn footprint(s: &Shape, lo: DVec2, cells_per_unit: f64, grow: i32) -> Footprint {
    let cell = |p: DVec2| ((p - lo) * cells_per_unit).floor();
    let hi = cell(bounds(s.points).1);
    let (w, h) = (hi.x as i32 + 1 + 2 * grow, hi.y as i32 + 1 + 2 * grow);
    let mut rows = vec![(i32::MAX, i32::MIN); h.max(0) as usize];
    for t in s.triangles {
        let q = t.map(|i| (s.points[i as usize] - lo) * cells_per_unit);
        let (ylo, yhi) = (
            q[0].y.min(q[1].y).min(q[2].y),
            q[0].y.max(q[1].y).max(q[2].y),
        );
        // Each cell row the triangle crosses: the x extent of its part in that row.
        for cy in ylo.floor() as i32..=yhi.floor() as i32 {
            let Some((xa, xb)) = row_extent(q, cy as f64, cy as f64 + 1.0) else {
                continue;
            };
            let (a, b) = (xa.floor() as i32, xb.floor() as i32 + 2 * grow + 1);
            for y in cy.max(0)..=(cy + 2 * grow).min(h - 1) {
                let r = &mut rows[y as usize];
                *r = (r.0.min(a), r.1.max(b));
            }
        }
    }
    Footprint { rows, width: w }
}

/// The x extent of triangle `q`'s part between y = `y0` and `y1` (its corners there and its edges'
/// crossings of the two lines), or `None` if it does not reach that band.
fn row_extent(q: [DVec2; 3], y0: f64, y1: f64) -> Option<(f64, f64)> {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    let mut take = |x: f64| {
        lo = lo.min(x);
        hi = hi.max(x);
    };
    for k in 0..3 {
        let (a, b) = (q[k], q[(k + 1) % 3]);
        if a.y >= y0 && a.y <= y1 {
            take(a.x);
        }
        for y in [y0, y1] {
            if (a.y - y) * (b.y - y) < 0.0 {
                take(a.x + (b.x - a.x) * (y - a.y) / (b.y - a.y));
            }
        }
    }
    (lo <= hi).then_some((lo, hi))
}

/// Bottom-left fill of every pelt at global scale `s` on a `g`² grid, each turned by 0 to 3
/// quarters (`shapes[k]`), whichever finds the lower, then more leftward spot: each pelt's low
/// cell and its quarter turns, or `None` when one does not fit.
fn fill(
    shapes: [&[Shape]; 4],
    density: &[f64],
    s: f64,
    g: u32,
    grow: i32,
) -> Option<Vec<(i32, i32, u8)>> {
    let g = g as i32;
    // The four turns' footprints on every core (each a pass over every triangle of every pelt).
    let prints: Vec<Vec<Footprint>> = shapes
        .par_iter()
        .map(|list| {
            list.iter()
                .zip(density)
                .map(|(sh, d)| footprint(sh, bounds(sh.points).0, s * d * g as f64, grow))
                .collect()
        })
        .collect();
    let n = density.len();
    let mut order: Vec<usize> = (0..n).collect();
    let cover = |f: &Footprint| f.rows.iter().map(|r| (r.1 - r.0).max(0)).sum::<i32>();
    order.sort_by_key(|&i| std::cmp::Reverse(cover(&prints[0][i])));
    // Per row, the prefix count of taken cells (g + 1 entries).
    let mut taken = vec![vec![0i32; g as usize + 1]; g as usize];
    let mut at = vec![(0, 0, 0u8); n];
    for i in order {
        let lowest = |f: &Footprint| {
            let h = f.rows.len() as i32;
            if f.width > g || h > g {
                return None;
            }
            let free = |x: i32, y: i32| {
                f.rows.iter().enumerate().all(|(r, &(a, b))| {
                    a >= b || {
                        let row = &taken[(y + r as i32) as usize];
                        row[(x + b) as usize] == row[(x + a) as usize]
                    }
                })
            };
            (0..=g - h).find_map(|y| (0..=g - f.width).find(|&x| free(x, y)).map(|x| (y, x)))
        };
        let (turn, (y, x)) = (0..4u8)
            .filter_map(|t| lowest(&prints[usize::from(t)][i]).map(|p| (t, p)))
            .min_by_key(|&(_, p)| p)?;
        let f = &prints[usize::from(turn)][i];
        let spot = (x, y);
        for (r, &(a, b)) in f.rows.iter().enumerate() {
            if a >= b {
                continue;
            }
            let row = &mut taken[(spot.1 + r as i32) as usize];
            let mut cells: Vec<i32> = (0..g)
                .map(|c| row[c as usize + 1] - row[c as usize])
                .collect();
            for c in spot.0 + a..spot.0 + b {
                cells[c as usize] = 1;
            }
            for c in 0..g as usize {
                row[c + 1] = row[c] + cells[c];
            }
        }
        at[i] = (spot.0 + grow, spot.1 + grow, turn);
    }
    Some(at)
}
