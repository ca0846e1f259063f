// SPDX-License-Identifier: MIT OR Apache-2.0
//! CPU twins of the blur and smear tools (`bake/tools.rs`): inverse rendering of the canvas into a
//! stamp's flat cell ([`flatten_cpu`], twin of `stamp_flatten.wgsl`) and the filters
//! ([`blur_cpu`], [`smear_cpu`], twins of `stamp_filter.wgsl`), written plainly.

use super::params::FLAT_RES;
use crate::io::image::LinearImage;
use crate::mesh::{Mesh, Topology};
use glam::Vec2;

/// The canvas under a stamp in its flat space: `FLAT_RES`² texels over the stamp's rectangle
/// (`size`), each the canvas at the UV of the stamp's point there, found among `triangles` (the
/// stamp's selection) by their stamp coordinates `coords`; alpha 0 where no triangle is.
pub fn flatten_cpu(
    (mesh, topo, uv_set): (&Mesh, &Topology, u32),
    coords: &[[f32; 4]],
    size: [f32; 2],
    triangles: &[u32],
    canvas: &LinearImage,
) -> LinearImage {
    let r = FLAT_RES;
    let uvs = &mesh.uv_sets[uv_set as usize];
    let mut out = LinearImage::solid(r, r, [0.0; 4]);
    for j in 0..r {
        for i in 0..r {
            let img = Vec2::new((i as f32 + 0.5) / r as f32, (j as f32 + 0.5) / r as f32);
            let p = Vec2::new((img.x - 0.5) * size[0], (0.5 - img.y) * size[1]);
            for &t in triangles {
                let c = topo.triangles[t as usize].map(|v| coords[v as usize]);
                let [a, b, cc] = c.map(|c| Vec2::new(c[0], c[1]));
                let area = (b - a).perp_dot(cc - a);
                if area.abs() < 1e-30 {
                    continue;
                }
                let w0 = (b - p).perp_dot(cc - p) / area;
                let w1 = (cc - p).perp_dot(a - p) / area;
                let w2 = 1.0 - w0 - w1;
                if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                    continue;
                }
                let [ua, ub, uc] = mesh.triangles[t as usize].map(|s| uvs[s as usize]);
                let uv = ua * w0 + ub * w1 + uc * w2;
                let s = canvas.bilinear(uv.x, uv.y, true);
                out.pixels[(j * r + i) as usize] = [s[0], s[1], s[2], 1.0];
                break;
            }
        }
    }
    out
}

/// Gaussian blur of a flat cell with standard deviation `sigma` texels, horizontal then vertical,
/// weighted by alpha, cut at 3 σ and at the cell; unknown texels stay unknown.
pub fn blur_cpu(flat: &LinearImage, sigma: f32) -> LinearImage {
    let r = FLAT_RES as i32;
    let sigma = sigma.max(1e-3);
    let reach = (3.0 * sigma).ceil().min((r - 1) as f32) as i32;
    let pass = |src: &LinearImage, horizontal: bool| {
        let mut out = LinearImage::solid(r as u32, r as u32, [0.0; 4]);
        for y in 0..r {
            for x in 0..r {
                let (mut sum, mut weight) = ([0.0f32; 3], 0.0f32);
                for d in -reach..=reach {
                    let (xx, yy) = if horizontal { (x + d, y) } else { (x, y + d) };
                    if !(0..r).contains(&xx) || !(0..r).contains(&yy) {
                        continue;
                    }
                    let w = (-0.5 * (d * d) as f32 / (sigma * sigma)).exp();
                    let c = src.pixels[(yy * r + xx) as usize];
                    for k in 0..3 {
                        sum[k] += w * c[3] * c[k];
                    }
                    weight += w * c[3];
                }
                if weight > 0.0 {
                    out.pixels[(y * r + x) as usize] =
                        [sum[0] / weight, sum[1] / weight, sum[2] / weight, 1.0];
                }
            }
        }
        out
    };
    let mut out = pass(&pass(flat, true), false);
    for (o, f) in out.pixels.iter_mut().zip(&flat.pixels) {
        if f[3] <= 0.0 {
            *o = [0.0; 4];
        }
    }
    out
}

/// Smear: each flat in order becomes `strength` × the previous result + (1 − strength) × itself
/// where both are known; `carry` is the previous stroke chunk's last result (alpha 0 at the start).
pub fn smear_cpu(flats: &mut [LinearImage], strength: f32, carry: &mut LinearImage) {
    for f in flats.iter_mut() {
        for (c, p) in carry.pixels.iter_mut().zip(f.pixels.iter_mut()) {
            if c[3] <= 0.0 {
                *c = *p;
            } else if p[3] > 0.0 {
                for k in 0..3 {
                    c[k] = p[k] + (c[k] - p[k]) * strength;
                }
                c[3] = 1.0;
            }
            *p = *c;
        }
    }
}

/// Twin of the texture transfer (`bake/transfer.rs`: `transfer_raster.wgsl` then
/// `transfer_resolve.wgsl`): per texel of a `size` texture laid out on `uv_set`, the mean of
/// `source` (laid out on `from_uv_set`, bilinear, clamp to edge) at the source UV of each of its
/// `ss`² sample centres that a non-degenerate triangle covers; `None` where none does. UVs in the
/// first tile ([0, 1]²) only.
pub fn transfer_cpu(
    (mesh, topo, uv_set): (&Mesh, &Topology, u32),
    from_uv_set: u32,
    source: &LinearImage,
    size: [u32; 2],
    ss: u32,
) -> Vec<Option<[f32; 4]>> {
    let (uv, src) = (
        &mesh.uv_sets[uv_set as usize],
        &mesh.uv_sets[from_uv_set as usize],
    );
    let [w, h] = size;
    let (sw, sh) = ((w * ss) as f32, (h * ss) as f32);
    let mut sum = vec![([0f32; 4], 0u32); (w * h) as usize];
    for (t, tri) in mesh.triangles.iter().enumerate() {
        if topo.degenerate[t] {
            continue;
        }
        let p = tri.map(|v| uv[v as usize] * Vec2::new(sw, sh));
        let q = tri.map(|v| src[v as usize]);
        let area = (p[1] - p[0]).perp_dot(p[2] - p[0]);
        if area == 0.0 {
            continue;
        }
        let lo = p[0].min(p[1]).min(p[2]).max(Vec2::ZERO);
        let hi = p[0].max(p[1]).max(p[2]).min(Vec2::new(sw, sh));
        for sy in lo.y.floor() as u32..hi.y.ceil() as u32 {
            for sx in lo.x.floor() as u32..hi.x.ceil() as u32 {
                let c = Vec2::new(sx as f32 + 0.5, sy as f32 + 0.5);
                let b = [
                    (p[2] - p[1]).perp_dot(c - p[1]) / area,
                    (p[0] - p[2]).perp_dot(c - p[2]) / area,
                    (p[1] - p[0]).perp_dot(c - p[0]) / area,
                ];
                if b.iter().any(|&x| x < 0.0) {
                    continue;
                }
                let s = q[0] * b[0] + q[1] * b[1] + q[2] * b[2];
                let v = source.bilinear(s.x, s.y, false);
                let e = &mut sum[((sy / ss) * w + sx / ss) as usize];
                for (acc, x) in e.0.iter_mut().zip(v) {
                    *acc += x;
                }
                e.1 += 1;
            }
        }
    }
    sum.into_iter()
        .map(|(c, n)| (n > 0).then(|| c.map(|x| x / n as f32)))
        .collect()
}
