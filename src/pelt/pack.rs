// SPDX-License-Identifier: MIT OR Apache-2.0
//! Packing pelts into [0, 1]² (issue 14: "packing of several pelts with a margin in texels for a
//! given texture size"), with `etagere`'s shelf allocator.
//!
//! Every pelt is first scaled so its UV area equals its 3D area (the same texel density on every
//! piece), then one global scale, the largest for which every pelt's box plus `margin` texels on each
//! side fits the `size`² texture, is found by bisection. The boxes are placed tallest first, in
//! horizontal or vertical shelves, in one to three columns: whichever fits the largest scale.

use glam::DVec2;

/// Where each pelt goes: `uv = offset + (p − lo) · scale`, in [0, 1]².
#[derive(Debug, Clone)]
pub struct Placement {
    /// Per pelt: its box's low corner in its own coordinates.
    pub lo: Vec<DVec2>,
    /// Per pelt: where that corner lands in [0, 1]².
    pub offset: Vec<DVec2>,
    /// Per pelt: UV units per unit of its own coordinates.
    pub scale: Vec<f64>,
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
    }
}
