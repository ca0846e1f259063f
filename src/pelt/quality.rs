// SPDX-License-Identifier: MIT OR Apache-2.0
//! How good a UV layout is: flipped triangles, overlaps, angle and area distortion, texel use.
//!
//! Per triangle, the map from the 3D triangle to its UV triangle has singular values σ1 ≥ σ2:
//! angle distortion is σ1 / σ2 (1 for a conformal map), area distortion is σ1σ2 divided by the
//! layout's total UV area over the total 3D area (1 where the triangle gets its fair share of
//! texels), reported as max(r, 1/r) so shrinking and growing count alike.

use glam::{DVec2, DVec3};

/// Mean (area-weighted), 95th percentile and maximum of a per-triangle measure.
#[derive(Debug, Clone, Copy, Default, serde::Serialize)]
pub struct Stat {
    /// Area-weighted mean.
    pub mean: f64,
    /// 95th percentile over triangles.
    pub p95: f64,
    /// Largest.
    pub max: f64,
}

/// Quality figures of a layout.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct Quality {
    /// σ1 / σ2 (module docs).
    pub angle_distortion: Stat,
    /// max(r, 1/r) of the normalised area ratio.
    pub area_distortion: Stat,
    /// Triangles with zero or negative UV area (wound against the majority).
    pub flipped: usize,
    /// Pairs of triangles whose UV interiors overlap.
    pub overlaps: usize,
    /// UV area inside [0, 1]² (the fraction of the texture the layout covers).
    pub texel_utilisation: f64,
}

fn stat(values: &[(f64, f64)]) -> Stat {
    if values.is_empty() {
        return Stat::default();
    }
    let w: f64 = values.iter().map(|v| v.1).sum();
    let mean = values.iter().map(|v| v.0 * v.1).sum::<f64>() / w.max(f64::MIN_POSITIVE);
    let mut sorted: Vec<f64> = values.iter().map(|v| v.0).collect();
    sorted.sort_unstable_by(f64::total_cmp);
    let p95 = sorted[((sorted.len() - 1) as f64 * 0.95).round() as usize];
    Stat {
        mean,
        p95,
        max: *sorted.last().expect("not empty"),
    }
}

/// Singular values (σ1 ≥ σ2) of the map from the 3D triangle `p` to the UV triangle `q`, with the
/// sign of the UV area.
pub fn singular_values(p: [DVec3; 3], q: [DVec2; 3]) -> (f64, f64, f64) {
    let e1 = p[1] - p[0];
    let e2 = p[2] - p[0];
    let x = e1.normalize_or_zero();
    let nrm = e1.cross(e2);
    let y = nrm.cross(e1).normalize_or_zero();
    // 3D triangle in its own plane: (0,0), (a,0), (b,c).
    let (a, b, c) = (e1.length(), e2.dot(x), e2.dot(y));
    let (f1, f2) = (q[1] - q[0], q[2] - q[0]);
    if a <= 0.0 || c <= 0.0 {
        return (0.0, 0.0, 0.0);
    }
    // J [a 0; b c] ... columns: J (1,0) = f1 / a, J (0,1) = (f2 - b/a f1) / c.
    let j0 = f1 / a;
    let j1 = (f2 - f1 * (b / a)) / c;
    let (p_, q_, r_, s_) = (j0.x, j1.x, j0.y, j1.y);
    let det = p_ * s_ - q_ * r_;
    let fro2 = p_ * p_ + q_ * q_ + r_ * r_ + s_ * s_;
    let disc = (fro2 * fro2 - 4.0 * det * det).max(0.0).sqrt();
    let s1 = ((fro2 + disc) / 2.0).max(0.0).sqrt();
    let s2 = ((fro2 - disc) / 2.0).max(0.0).sqrt();
    (s1, s2, det.signum() * (det != 0.0) as i32 as f64)
}

/// Measures the layout of `triangles` (3D positions `pos`, UVs `uv`, both indexed by the same
/// vertex ids). Triangles from different pieces never share ids.
pub fn measure(pos: &[DVec3], uv: &[DVec2], triangles: &[[u32; 3]]) -> Quality {
    let (mut area3, mut area2) = (0.0, 0.0);
    let mut signed = 0.0;
    for t in triangles {
        let p = t.map(|i| pos[i as usize]);
        let q = t.map(|i| uv[i as usize]);
        area3 += 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length();
        let s = 0.5 * (q[1] - q[0]).perp_dot(q[2] - q[0]);
        area2 += s.abs();
        signed += s;
    }
    let sign = if signed < 0.0 { -1.0 } else { 1.0 };
    let ratio = area2 / area3.max(f64::MIN_POSITIVE);
    let (mut angle, mut area) = (Vec::new(), Vec::new());
    let mut flipped = 0;
    for t in triangles {
        let p = t.map(|i| pos[i as usize]);
        let q = t.map(|i| uv[i as usize]);
        let w = 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length();
        let (s1, s2, sg) = singular_values(p, q);
        if sg * sign <= 0.0 {
            flipped += 1;
        }
        angle.push((if s2 > 0.0 { s1 / s2 } else { f64::INFINITY }, w));
        let r = s1 * s2 / ratio.max(f64::MIN_POSITIVE);
        area.push((
            if r > 0.0 {
                r.max(1.0 / r)
            } else {
                f64::INFINITY
            },
            w,
        ));
    }
    Quality {
        angle_distortion: stat(&angle),
        area_distortion: stat(&area),
        flipped,
        overlaps: overlaps(uv, triangles),
        texel_utilisation: area2,
    }
}

/// Pairs of triangles whose UV interiors overlap (shared vertices do not count): a uniform grid
/// over the layout's box, then an exact separating-axis test with a small inset.
pub fn overlaps(uv: &[DVec2], triangles: &[[u32; 3]]) -> usize {
    overlapping_pairs(uv, triangles).len()
}

/// The pairs (indices into `triangles`, smaller first, sorted) that [`overlaps`] counts.
pub fn overlapping_pairs(uv: &[DVec2], triangles: &[[u32; 3]]) -> Vec<(u32, u32)> {
    if triangles.is_empty() {
        return Vec::new();
    }
    let (mut lo, mut hi) = (DVec2::splat(f64::MAX), DVec2::splat(f64::MIN));
    for t in triangles {
        for &i in t {
            lo = lo.min(uv[i as usize]);
            hi = hi.max(uv[i as usize]);
        }
    }
    let cells = (triangles.len() as f64).sqrt().ceil().max(1.0) as usize;
    let size = (hi - lo).max_element().max(f64::MIN_POSITIVE) / cells as f64;
    let cell = |p: DVec2| {
        let c = ((p - lo) / size).floor();
        ((c.x as usize).min(cells - 1), (c.y as usize).min(cells - 1))
    };
    let mut grid: Vec<Vec<u32>> = vec![Vec::new(); cells * cells];
    for (ti, t) in triangles.iter().enumerate() {
        let q = t.map(|i| uv[i as usize]);
        let (a, b) = (
            cell(q[0].min(q[1]).min(q[2])),
            cell(q[0].max(q[1]).max(q[2])),
        );
        for y in a.1..=b.1 {
            for x in a.0..=b.0 {
                grid[y * cells + x].push(ti as u32);
            }
        }
    }
    let mut pairs: rustc_hash::FxHashSet<(u32, u32)> = Default::default();
    for list in &grid {
        for (k, &s) in list.iter().enumerate() {
            for &t in &list[k + 1..] {
                let (ts, tt) = (triangles[s as usize], triangles[t as usize]);
                if ts.iter().any(|v| tt.contains(v)) {
                    continue;
                }
                let (a, b) = (s.min(t), s.max(t));
                if !pairs.contains(&(a, b))
                    && intersect(ts.map(|i| uv[i as usize]), tt.map(|i| uv[i as usize]))
                {
                    pairs.insert((a, b));
                }
            }
        }
    }
    let mut pairs: Vec<(u32, u32)> = pairs.into_iter().collect();
    pairs.sort_unstable();
    pairs
}

/// Whether two triangles' interiors overlap by more than a sliver (separating axes of both, each
/// triangle shrunk by 1e-9 of its size towards its centroid).
fn intersect(a: [DVec2; 3], b: [DVec2; 3]) -> bool {
    let shrink = |t: [DVec2; 3]| {
        let c = (t[0] + t[1] + t[2]) / 3.0;
        t.map(|p| c + (p - c) * (1.0 - 1e-6))
    };
    let (a, b) = (shrink(a), shrink(b));
    for tri in [a, b] {
        for k in 0..3 {
            let e = tri[(k + 1) % 3] - tri[k];
            let n = DVec2::new(-e.y, e.x);
            let pa = a.map(|p| n.dot(p));
            let pb = b.map(|p| n.dot(p));
            let (amin, amax) = (pa[0].min(pa[1]).min(pa[2]), pa[0].max(pa[1]).max(pa[2]));
            let (bmin, bmax) = (pb[0].min(pb[1]).min(pb[2]), pb[0].max(pb[1]).max(pb[2]));
            if amax <= bmin || bmax <= amin {
                return false;
            }
        }
    }
    true
}
