// SPDX-License-Identifier: MIT OR Apache-2.0
//! Vector graphics and text on the surface (Schmidt et al. 2006, §6.2): SVG images rendered at the
//! sizes their maps need, and text layers shaped by rustybuzz, as decals and along curves.
mod common;

use decalbake::io::image::{linear_to_srgb, srgb_to_linear};
use decalbake::io::text::shape;
use decalbake::io::vector::{Svg, BUNDLED_FONT};
use std::f32::consts::PI;
use std::path::Path;

/// An SVG of large shapes with straight, curved and slanted edges and a gradient, 100 units
/// square, asymmetric (a mirrored or turned bake fails the comparison).
const SHAPES: &str = r##"<svg xmlns="http://www.w3.org/2000/svg" width="100" height="100" viewBox="0 0 100 100">
  <defs><linearGradient id="g" x1="0" y1="0" x2="1" y2="0">
    <stop offset="0" stop-color="#1060d0"/><stop offset="1" stop-color="#20c080"/></linearGradient></defs>
  <rect x="10.3" y="8.6" width="45.2" height="30.1" fill="#d02020"/>
  <circle cx="66" cy="64" r="27.3" fill="url(#g)"/>
  <path d="M8 92 L40 50 L44 90 Z" fill="#f0c000" fill-opacity="0.8"/>
</svg>"##;

/// The plane scene: the unit square (UV = (x, 1 − y)), a white base, `layers`, a `side`² texture.
fn plane_job(dir: &Path, side: u32, samples: u32, layers: serde_json::Value) -> decalbake::Job {
    common::write_plane(&dir.join("plane.glb"), 16, false);
    let text = serde_json::json!({ "mesh": "plane.glb",
        "texture": { "width": side, "height": side, "padding": 0, "samples": samples,
                     "base": [1.0, 1.0, 1.0, 1.0] },
        "layers": layers })
    .to_string();
    decalbake::Job::parse(&text, &dir.join("job.json"), dir, dir).unwrap()
}

/// `img` (straight alpha, linear colour) over white, as 8-bit sRGB values.
fn over_white(p: [f32; 4]) -> [f32; 3] {
    let c = |v: f32| (linear_to_srgb(v * p[3] + (1.0 - p[3])) * 255.0).round();
    [c(p[0]), c(p[1]), c(p[2])]
}

/// Where a row of values crosses `level` first, in texels from the row's start (interpolated
/// between texel centres).
fn crossing(row: &[f32], level: f32) -> Option<f32> {
    row.windows(2).enumerate().find_map(|(i, w)| {
        ((w[0] - level) * (w[1] - level) <= 0.0 && w[0] != w[1])
            .then(|| i as f32 + 0.5 + (level - w[0]) / (w[1] - w[0]))
    })
}

/// The position of the first step in a row that crosses `level`, to a fraction of a texel: over
/// the five texels each side of the crossing, the values scaled between the plateaus at the
/// window's ends, summed (a step at p from the window's start sums to p, whatever its blur).
fn edge(row: &[f32], level: f32) -> Option<f32> {
    let c = crossing(row, level)? as usize;
    let (a, b) = (c.checked_sub(5)?, c + 5);
    let (left, right) = (row[a], *row.get(b)?);
    if (left - right).abs() < 1e-3 {
        return None;
    }
    Some(
        a as f32
            + row[a..=b]
                .iter()
                .map(|v| (v - right) / (left - right))
                .sum::<f32>(),
    )
}

/// An SVG decal on a plane, planar, covering texels 64 to 192 of a 256² bake, against resvg's own
/// rendering of the same SVG at 128² composed over the same white base: the mean error over the
/// decal is at most 1/255 (8-bit values, all channels), and every edge crossing along the rows
/// and columns through the rectangle's sides and the circle's centre lies within half a texel
/// of resvg's (each edge's position summed from the values across it, to a fraction of a
/// texel). The bake renders the SVG at 256² (two pixels a texel), its samples read the first
/// mipmap level: measured mean 0.21, edges within 0.16 texel. Placing the decal one texel off
/// fails both checks (mean 2.5, an edge 1.1 texel off).
#[test]
fn svg_decal_matches_resvg_at_the_same_resolution() {
    let engine = common::engine();
    let dir = common::scratch("vector_resvg");
    std::fs::write(dir.join("shapes.svg"), SHAPES).unwrap();
    let job = plane_job(
        &dir,
        256,
        4,
        serde_json::json!([{ "image": "shapes.svg", "at": [0.5, 0.5, 0.0], "size": [0.5, 0.5],
        "up": [0, 1, 0], "method": "planar" }]),
    );
    let mesh = engine.load_mesh(&job.mesh).unwrap();
    let baked = engine.bake(&mesh, &job).unwrap();
    let reference = Svg::parse(SHAPES.as_bytes())
        .unwrap()
        .render([128, 128], false);
    let want = |x: u32, y: u32| over_white(reference.pixels[(y * 128 + x) as usize]);
    let got = |x: u32, y: u32| {
        let i = (((y + 64) * 256 + x + 64) * 4) as usize;
        [0, 1, 2].map(|k| baked.texels[i + k] as f32)
    };
    let mut sum = 0.0f64;
    for y in 0..128 {
        for x in 0..128 {
            let (a, b) = (want(x, y), got(x, y));
            sum += (0..3).map(|k| (a[k] - b[k]).abs() as f64).sum::<f64>();
        }
    }
    let mean = sum / (128.0 * 128.0 * 3.0);
    // Edges: rows through the rectangle and the circle, columns through the rectangle.
    // Ink: how far from the white base (summed over the channels).
    let ink = |v: [f32; 3]| 765.0 - v[0] - v[1] - v[2];
    let mut worst = 0.0f32;
    let mut edges = 0;
    for line in [20u32, 30, 64, 80] {
        for (along_rows, reversed) in [(true, false), (true, true), (false, false), (false, true)] {
            let sample = |f: &dyn Fn(u32, u32) -> [f32; 3]| -> Vec<f32> {
                let mut v: Vec<f32> = (0..128)
                    .map(|k| {
                        if along_rows {
                            ink(f(k, line))
                        } else {
                            ink(f(line, k))
                        }
                    })
                    .collect();
                if reversed {
                    v.reverse();
                }
                v
            };
            let (a, b) = (sample(&want), sample(&got));
            let (lo, hi) = a
                .iter()
                .fold((f32::MAX, f32::MIN), |m, &x| (m.0.min(x), m.1.max(x)));
            if hi - lo < 60.0 {
                continue;
            }
            let level = 0.5 * (lo + hi);
            if let (Some(ca), Some(cb)) = (edge(&a, level), edge(&b, level)) {
                worst = worst.max((ca - cb).abs());
                edges += 1;
            }
        }
    }
    eprintln!("mean error {mean:.3} (8-bit), {edges} edges, worst {worst:.3} texel");
    assert!(edges >= 8, "{edges} edges found");
    assert!(mean <= 1.0, "mean error {mean:.3} of 255");
    assert!(worst <= 0.5, "an edge is {worst:.3} texel off");
}

/// The profile of a dark disc's edge along the row through its centre: (radius in texels where
/// the value crosses one half, the width from 10 % to 90 % coverage).
fn disc_edge(baked: &decalbake::Baked, side: u32) -> (f32, f32) {
    let y = side / 2;
    // Coverage from the luminance over white (linear; the disc is black).
    let row: Vec<f32> = (0..side).map(|x| 1.0 - baked.linear(x, y)[1]).collect();
    let right = &row[side as usize / 2..];
    let c50 = crossing(right, 0.5).expect("the edge");
    let (c10, c90) = (crossing(right, 0.1).unwrap(), crossing(right, 0.9).unwrap());
    (c50, (c10 - c90).abs())
}

/// A circle of radius 40 from a 100-unit SVG, magnified over the whole 1024² bake: its edge is at
/// most two texels wide (10 % to 90 %; measured 1.6) and its radius, 409.6 texels, within one
/// texel (measured 0.1 off). The same circle as a 64-pixel PNG smears over 26 texels from 10 %
/// to 90 % (16 texels a pixel), which is what the vector path exists to avoid: held to the SVG's
/// two texels, the PNG fails.
#[test]
fn a_magnified_svg_circle_keeps_a_sharp_edge() {
    let engine = common::engine();
    let dir = common::scratch("vector_circle");
    let circle = r#"<svg xmlns="http://www.w3.org/2000/svg" width="100" height="100"><circle cx="50" cy="50" r="40" fill="black"/></svg>"#;
    std::fs::write(dir.join("circle.svg"), circle).unwrap();
    let small = Svg::parse(circle.as_bytes())
        .unwrap()
        .render([64, 64], false);
    std::fs::write(dir.join("circle.png"), small.encode_png(8)).unwrap();
    let mut widths = Vec::new();
    for image in ["circle.svg", "circle.png"] {
        let job = plane_job(
            &dir,
            1024,
            4,
            serde_json::json!([{ "image": image, "at": [0.5, 0.5, 0.0], "size": [1.0, 1.0],
                "up": [0, 1, 0], "method": "planar" }]),
        );
        let mesh = engine.load_mesh(&job.mesh).unwrap();
        let baked = engine.bake(&mesh, &job).unwrap();
        let (radius, width) = disc_edge(&baked, 1024);
        eprintln!("{image}: radius {radius:.2} texels, edge {width:.2} texels wide");
        widths.push(width);
        if image.ends_with("svg") {
            assert!(width <= 2.0, "the SVG's edge is {width:.2} texels wide");
            assert!(
                (radius - 409.6).abs() <= 1.0,
                "the SVG's radius is {radius:.2} texels, not 409.6"
            );
        }
    }
    assert!(
        widths[1] > 8.0,
        "the PNG's edge is {} texels wide",
        widths[1]
    );
}

/// A UV sphere of radius 1 (`rings` × `segments`), equirectangular UVs: u = longitude / 2π + 1/2,
/// v = 1/2 − latitude / π.
fn write_sphere(path: &Path, rings: u32, segments: u32) {
    let mut pos = Vec::new();
    let mut uv = Vec::new();
    for j in 0..=rings {
        let lat = PI / 2.0 - PI * j as f32 / rings as f32;
        for i in 0..=segments {
            let lon = -PI + 2.0 * PI * i as f32 / segments as f32;
            pos.push([lat.cos() * lon.sin(), lat.sin(), lat.cos() * lon.cos()]);
            uv.push([i as f32 / segments as f32, j as f32 / rings as f32]);
        }
    }
    let mut idx = Vec::new();
    for j in 0..rings {
        for i in 0..segments {
            let a = j * (segments + 1) + i;
            let (b, c, d) = (a + 1, a + segments + 1, a + segments + 2);
            idx.extend([a, c, d, a, d, b]);
        }
    }
    common::write_glb(path, &pos, Some(&uv), &idx);
}

/// One texel's signed distance from the curve (positive on its left, seen from outside) and its
/// position along it, both in model units.
type Frame = dyn Fn(f32, f32) -> (f32, f32);

/// Text of flat-bottomed capitals (`"EEEEE"`, no descenders, the bottoms on the baseline) along a
/// curve, checked at every texel the text paints (coverage ≥ 1/2 against the white base): it lies
/// within one em of the curve; on the curve's left (`side` left: the glyphs' up is the curve's
/// left seen from outside) and above the baseline by at most the cap height and 2 % of an em;
/// and, in each fifth of the line, the lowest painted texel is on the baseline within 1 % of the
/// em plus half a texel (the coverage's threshold falls anywhere in a texel); the painted texels
/// run along the curve over the line's advance, within 0.15 em at each end (the first and last
/// glyphs' side bearings). Returns the worst baseline error in ems. A `"side": "right"` bake fails the side check; a strip drawn with
/// its baseline off the curve (a ribbon of the text's block) fails the baseline check.
fn check_text_on_curve(
    baked: &decalbake::Baked,
    frame: &Frame,
    em: f32,
    texel: f32,
    span: (f32, f32),
) -> f32 {
    let cap = 0.73 * em;
    let mut lowest = [f32::MAX; 5];
    let mut painted = 0;
    let mut extent = (f32::MAX, f32::MIN);
    for y in 0..baked.height {
        for x in 0..baked.width {
            let c = baked.linear(x, y);
            if 1.0 - c[0] < 0.5 {
                continue;
            }
            painted += 1;
            let (u, v) = (
                (x as f32 + 0.5) / baked.width as f32,
                (y as f32 + 0.5) / baked.height as f32,
            );
            let (d, s) = frame(u, v);
            assert!(
                d.abs() <= em,
                "a painted texel {d:.4} from the curve (em {em})"
            );
            assert!(
                d >= -0.02 * em - texel && d <= cap + 0.02 * em + texel,
                "a painted texel at {d:.4} across the curve: not on its left within the cap height"
            );
            extent = (extent.0.min(s), extent.1.max(s));
            let k = (((s - span.0) / (span.1 - span.0)) * 5.0).floor();
            if (0.0..5.0).contains(&k) {
                lowest[k as usize] = lowest[k as usize].min(d);
            }
        }
    }
    assert!(painted > 500, "{painted} texels painted");
    // The line's extent along the curve is its advance (the glyphs' side bearings inside it).
    let (first, last) = extent;
    assert!(
        (first - span.0).abs() <= 0.15 * em && (last - span.1).abs() <= 0.15 * em,
        "the text runs from {first:.4} to {last:.4} along the curve, not {:.4} to {:.4}",
        span.0,
        span.1
    );
    let worst = lowest
        .iter()
        .map(|&d| {
            assert!(d < f32::MAX, "a fifth of the line is empty");
            d.abs()
        })
        .fold(0.0f32, f32::max);
    eprintln!(
        "{painted} texels painted; baseline off by at most {:.4} em",
        worst / em
    );
    assert!(
        worst <= 0.01 * em + 0.5 * texel,
        "the lowest texel of a fifth of the line is {worst:.5} off the baseline (em {em})"
    );
    worst / em
}

/// Text along a circle on a plane: the square [−1, 1]² (64 × 64 cells, UV = ((x + 1) / 2,
/// (1 − y) / 2)), the arc of radius 0.8 around the origin over 216°, counter-clockwise (its left
/// is the centre), em 0.15 on a 2048² bake (1 % of the em is 1.5 texels); see
/// [`check_text_on_curve`]. The strip's inner edge shrinks by 17 %, under the ribbon's
/// `curved_threshold` (0.2), so the map there is the extended exponential map, not its harmonic
/// repair (which a tighter circle gets, and which puts the cap height up to 3 % of an em off).
#[test]
fn text_follows_a_circle_on_a_plane() {
    let engine = common::engine();
    let dir = common::scratch("vector_text_plane");
    let n = 64u32;
    let mut pos = Vec::new();
    let mut uv = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (x, y) = (
                -1.0 + 2.0 * i as f32 / n as f32,
                -1.0 + 2.0 * j as f32 / n as f32,
            );
            pos.push([x, y, 0.0]);
            uv.push([(x + 1.0) / 2.0, (1.0 - y) / 2.0]);
        }
    }
    let idx: Vec<u32> = (0..n)
        .flat_map(|j| (0..n).map(move |i| (j, i)))
        .flat_map(|(j, i)| {
            let a = j * (n + 1) + i;
            [a, a + 1, a + n + 2, a, a + n + 2, a + n + 1]
        })
        .collect();
    common::write_glb(&dir.join("plane.glb"), &pos, Some(&uv), &idx);
    let path: Vec<[f32; 3]> = (0..=120)
        .map(|k| {
            let t = -0.6 * PI + 1.2 * PI * k as f32 / 120.0;
            [0.8 * t.cos(), 0.8 * t.sin(), 0.0]
        })
        .collect();
    let em = 0.15;
    let text = serde_json::json!({ "mesh": "plane.glb",
        "texture": { "width": 2048, "height": 2048, "padding": 0, "base": [1.0, 1.0, 1.0, 1.0] },
        "layers": [{ "kind": "text", "text": "EEEEE", "size": em, "path": path }] })
    .to_string();
    let job = decalbake::Job::parse(&text, &dir.join("job.json"), &dir, &dir).unwrap();
    let mesh = engine.load_mesh(&job.mesh).unwrap();
    let baked = engine.bake(&mesh, &job).unwrap();
    let w = &baked.report.warnings;
    assert!(!w.iter().any(|w| w.contains("longer than")), "{w:?}");
    let frame = |u: f32, v: f32| {
        let (x, y) = (2.0 * u - 1.0, 1.0 - 2.0 * v);
        (0.8 - x.hypot(y), 0.8 * y.atan2(x))
    };
    let block = shape("EEEEE", BUNDLED_FONT, 0.0).unwrap();
    let half = 0.5 * block.advance / block.units_per_em * em;
    check_text_on_curve(&baked, &frame, em, 2.0 / 2048.0, (-half, half));
}

/// Text along the latitude 20° of the unit sphere, travelling east (its left is north), on a
/// 2048 × 1024 equirectangular bake; see [`check_text_on_curve`] (distances along the meridian
/// and the parallel).
#[test]
fn text_follows_a_parallel_on_a_sphere() {
    let engine = common::engine();
    let dir = common::scratch("vector_text_sphere");
    write_sphere(&dir.join("sphere.glb"), 64, 128);
    let lat0 = 20f32.to_radians();
    let path: Vec<serde_json::Value> = (0..=40)
        .map(|k| {
            let lon = -1.0 + 2.0 * k as f32 / 40.0;
            let p = [lat0.cos() * lon.sin(), lat0.sin(), lat0.cos() * lon.cos()];
            serde_json::json!({ "ray": { "origin": p.map(|c| 2.0 * c), "dir": p.map(|c| -c) } })
        })
        .collect();
    let em = 0.4;
    let text = serde_json::json!({ "mesh": "sphere.glb",
        "texture": { "width": 2048, "height": 1024, "padding": 0, "base": [1.0, 1.0, 1.0, 1.0] },
        "layers": [{ "kind": "text", "text": "EEEEE", "size": em, "path": path }] })
    .to_string();
    let job = decalbake::Job::parse(&text, &dir.join("job.json"), &dir, &dir).unwrap();
    let mesh = engine.load_mesh(&job.mesh).unwrap();
    let baked = engine.bake(&mesh, &job).unwrap();
    let frame = move |u: f32, v: f32| {
        let (lon, lat) = ((u - 0.5) * 2.0 * PI, (0.5 - v) * PI);
        (lat - lat0, lon * lat0.cos())
    };
    let block = shape("EEEEE", BUNDLED_FONT, 0.0).unwrap();
    let half = 0.5 * block.advance / block.units_per_em * em;
    check_text_on_curve(&baked, &frame, em, PI / 1024.0, (-half, half));
}

/// Shaping is rustybuzz's: a Hebrew word comes out in visual order (its last letter's glyph
/// first) with the same glyphs rustybuzz gives; "fi" becomes DejaVu Sans's one ligature glyph;
/// "AV" is kerned tighter than its two advances. Breaking any of these (shaping each character
/// alone, reversing the order) fails.
#[test]
fn shaping_follows_rustybuzz() {
    let face = rustybuzz::Face::from_slice(BUNDLED_FONT, 0).unwrap();
    let direct = |text: &str| -> Vec<u16> {
        let mut b = rustybuzz::UnicodeBuffer::new();
        b.push_str(text);
        b.guess_segment_properties();
        let out = rustybuzz::shape(&face, &[], b);
        out.glyph_infos()
            .iter()
            .map(|g| g.glyph_id as u16)
            .collect()
    };
    let glyph = |c: char| face.glyph_index(c).unwrap().0;
    let hebrew = "שלום";
    let ours = shape(hebrew, BUNDLED_FONT, 0.0).unwrap();
    assert_eq!(ours.glyph_ids, direct(hebrew));
    assert_eq!(
        ours.glyph_ids[0],
        glyph('ם'),
        "visual order: the last letter leftmost"
    );
    assert_eq!(*ours.glyph_ids.last().unwrap(), glyph('ש'));
    let fi = shape("fi", BUNDLED_FONT, 0.0).unwrap();
    assert_eq!(
        fi.glyph_ids.len(),
        1,
        "fi is one ligature glyph: {:?}",
        fi.glyph_ids
    );
    assert_ne!(fi.glyph_ids[0], glyph('f'));
    let av = shape("AV", BUNDLED_FONT, 0.0).unwrap();
    let apart = shape("A", BUNDLED_FONT, 0.0).unwrap().advance
        + shape("V", BUNDLED_FONT, 0.0).unwrap().advance;
    assert!(av.advance < apart, "AV {} against {apart}", av.advance);
    let spaced = shape("AV", BUNDLED_FONT, 0.5).unwrap();
    assert_eq!(spaced.advance, av.advance + 0.5 * av.units_per_em);
}

/// A text decal at a point: its block (advance by ascender to descender, at the em size) centred
/// there, upright along `up`. On the plane at 512², "HH" in red: every painted texel lies inside
/// the block's rectangle, and the painted part's bounding box spans the capitals' height (0.73
/// em, within two texels) above the baseline, which sits the descender's depth above the
/// block's bottom (within two texels). Turning the text by 180° (`"angle": 180`) moves the glyphs'
/// bottom below the baseline and fails.
#[test]
fn text_decals_stand_upright_in_their_block() {
    let engine = common::engine();
    let dir = common::scratch("vector_text_decal");
    let em = 0.25;
    let job = plane_job(
        &dir,
        512,
        4,
        serde_json::json!([{ "kind": "text", "text": "HH", "size": em, "color": [1.0, 0.0, 0.0, 1.0],
            "at": [0.5, 0.5, 0.0], "up": [0, 1, 0], "method": "planar" }]),
    );
    let mesh = engine.load_mesh(&job.mesh).unwrap();
    let baked = engine.bake(&mesh, &job).unwrap();
    let block = shape("HH", BUNDLED_FONT, 0.0).unwrap();
    let s = em / block.units_per_em;
    let (bw, bh) = (block.advance * s, (block.ascender - block.descender) * s);
    let baseline = 0.5 - 0.5 * bh - block.descender * s;
    let (mut lo, mut hi) = (f32::MAX, f32::MIN);
    let texel = 1.0 / 512.0;
    for y in 0..512 {
        for x in 0..512 {
            let c = baked.linear(x, y);
            if c[1] > 0.5 {
                continue;
            }
            let (px, py) = ((x as f32 + 0.5) * texel, 1.0 - (y as f32 + 0.5) * texel);
            assert!(
                (px - 0.5).abs() <= 0.5 * bw + texel,
                "x {px} outside the block"
            );
            assert!(
                (py - 0.5).abs() <= 0.5 * bh + texel,
                "y {py} outside the block"
            );
            lo = lo.min(py);
            hi = hi.max(py);
        }
    }
    eprintln!(
        "painted from {lo:.4} to {hi:.4}; baseline {baseline:.4}, cap {:.4}",
        baseline + 0.73 * em
    );
    assert!(
        (lo - baseline).abs() <= 2.0 * texel,
        "bottom {lo} against the baseline {baseline}"
    );
    assert!(
        (hi - (baseline + 0.729 * em)).abs() <= 2.0 * texel,
        "top {hi}"
    );
}

/// The colour of the rendered SVG is the file's sRGB colour decoded, and a mask SVG is data:
/// a mid-grey (#808080) mask halves a layer (0.502 of alpha), as a PNG mask of 128 does.
#[test]
fn svg_colour_and_masks_read_as_images_do() {
    let svg = br##"<svg xmlns="http://www.w3.org/2000/svg" width="4" height="4"><rect width="4" height="4" fill="#808080"/></svg>"##;
    let s = Svg::parse(svg).unwrap();
    let colour = s.render([4, 4], false);
    let mask = s.render([4, 4], true);
    assert!((colour.pixels[5][0] - srgb_to_linear(128.0 / 255.0)).abs() < 1e-6);
    assert!((mask.pixels[5][0] - 128.0 / 255.0).abs() < 1e-6);
    assert_eq!(mask.pixels[5][3], 1.0);
}

/// Bad vector input exits 2 with a message naming the file or field, before the GPU starts, and
/// writes nothing: an SVG
/// that does not parse (its line and column), a font that does not load, a missing font, an
/// empty text, text on a non-text layer. A font without some characters and text longer than
/// its curve bake with a warning that names them; `"fit": "shrink"` bakes the long text without
/// one.
#[test]
fn bad_vector_input_is_refused_by_file_and_field() {
    let dir = common::scratch("vector_bad");
    common::write_plane(&dir.join("plane.glb"), 8, false);
    std::fs::write(
        dir.join("bad.svg"),
        "<svg xmlns=\"http://www.w3.org/2000/svg\">\n<rect width=\"4\"\n</svg>",
    )
    .unwrap();
    std::fs::write(dir.join("notafont.ttf"), "this is not a font").unwrap();
    let decal = |extra: serde_json::Value| {
        let mut l = serde_json::json!({ "at": [0.5, 0.5, 0.0], "size": [0.3, 0.3] });
        for (k, v) in extra.as_object().unwrap() {
            l[k] = v.clone();
        }
        l
    };
    let short: Vec<[f32; 3]> = vec![[0.3, 0.5, 0.0], [0.5, 0.52, 0.0], [0.7, 0.5, 0.0]];
    let cases: Vec<(&str, serde_json::Value, &[&str])> = vec![
        (
            "svg",
            decal(serde_json::json!({ "image": "bad.svg" })),
            &["layers[0].image", "bad.svg", "does not parse", "3:1"],
        ),
        (
            "font",
            serde_json::json!({ "kind": "text", "text": "Hi", "size": 0.1, "at": [0.5, 0.5, 0.0], "font": "notafont.ttf" }),
            &["layers[0].font", "notafont.ttf", "does not load"],
        ),
        (
            "missing font",
            serde_json::json!({ "kind": "text", "text": "Hi", "size": 0.1, "at": [0.5, 0.5, 0.0], "font": "nowhere.otf" }),
            &["layers[0].font", "nowhere.otf"],
        ),
        (
            "empty",
            serde_json::json!({ "kind": "text", "text": " ", "size": 0.1, "at": [0.5, 0.5, 0.0] }),
            &["layers[0].text", "empty"],
        ),
        (
            "no size",
            serde_json::json!({ "kind": "text", "text": "Hi", "at": [0.5, 0.5, 0.0] }),
            &["layers[0].size", "em size"],
        ),
        (
            "text on a decal",
            decal(serde_json::json!({ "image": "bad.svg", "text": "Hi" })),
            &["layers[0].text", "text layers only"],
        ),
        (
            "side on a text decal",
            serde_json::json!({ "kind": "text", "text": "Hi", "size": 0.1, "at": [0.5, 0.5, 0.0], "side": "right" }),
            &["layers[0].side", "along a `path`"],
        ),
    ];
    for (name, layer, want) in cases {
        let job = serde_json::json!({ "mesh": "plane.glb", "texture": { "width": 64, "height": 64 },
            "layers": [layer], "output": { "texture": "out.png", "report": null } });
        std::fs::write(dir.join("job.json"), job.to_string()).unwrap();
        let (code, _, err) = common::cli(&["bake", dir.join("job.json").to_str().unwrap()]);
        assert_eq!(code, 2, "{name}: {err}");
        for w in want {
            assert!(err.contains(w), "{name}: {w:?} not in {err}");
        }
        assert!(
            !dir.join("out.png").exists(),
            "{name}: an output was written"
        );
        assert!(
            !err.contains("adapter:"),
            "{name}: refused only after the GPU started: {err}"
        );
    }
    let warned = |layer: serde_json::Value| -> Vec<String> {
        let job = serde_json::json!({ "mesh": "plane.glb", "texture": { "width": 128, "height": 128 },
            "layers": [layer], "output": { "texture": "out.png", "report": "report.json" } });
        std::fs::write(dir.join("job.json"), job.to_string()).unwrap();
        let (code, _, err) = common::cli(&["bake", dir.join("job.json").to_str().unwrap()]);
        assert_eq!(code, 0, "{err}");
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("report.json")).unwrap())
                .unwrap();
        report["warnings"]
            .as_array()
            .unwrap()
            .iter()
            .map(|w| w.as_str().unwrap().to_string())
            .collect()
    };
    let w = warned(
        serde_json::json!({ "kind": "text", "text": "Ab漢字", "size": 0.1, "at": [0.5, 0.5, 0.0] }),
    );
    assert!(
        w.iter()
            .any(|w| w.contains("layers[0].text") && w.contains("漢字")),
        "{w:?}"
    );
    let long = serde_json::json!({ "kind": "text", "text": "a line far too long for its curve", "size": 0.1, "path": short });
    let w = warned(long.clone());
    assert!(
        w.iter()
            .any(|w| w.contains("longer than its curve") && w.contains("shrink")),
        "{w:?}"
    );
    let mut shrunk = long;
    shrunk["fit"] = "shrink".into();
    let w = warned(shrunk);
    assert!(!w.iter().any(|w| w.contains("longer than")), "{w:?}");
}

/// `decalbake param` exports a text layer along a curve like a ribbon: a row per vertex the map
/// reaches, `u` along the curve and `v` across it; on the straight path along y = 0.5 of the
/// plane, u is x less the path's start and v is y − 0.5 (within 1e-4).
#[test]
fn param_exports_a_text_layers_map() {
    let dir = common::scratch("vector_param");
    common::write_plane(&dir.join("plane.glb"), 32, false);
    let job = serde_json::json!({ "mesh": "plane.glb", "layers": [{ "kind": "text", "text": "Hello",
        "size": 0.1, "path": [[0.2, 0.5, 0.0], [0.8, 0.5, 0.0]], "interpolate": "linear" }] });
    std::fs::write(dir.join("job.json"), job.to_string()).unwrap();
    let out = dir.join("text.csv");
    let (code, _, err) = common::param(&dir.join("job.json"), "0", &out);
    assert_eq!(code, 0, "{err}");
    let text = std::fs::read_to_string(&out).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("x,y,z,distance,u,v"));
    let (mut worst, mut n) = (0.0f32, 0);
    for line in lines {
        let f: Vec<f32> = line.split(',').map(|x| x.parse().unwrap()).collect();
        if f[0] > 0.25 && f[0] < 0.75 {
            worst = worst
                .max((f[4] - (f[0] - 0.2)).abs())
                .max((f[5] - (f[1] - 0.5)).abs());
            n += 1;
        }
    }
    eprintln!("{n} rows inside, max error {worst:.2e}");
    assert!(n > 50, "{n} rows");
    assert!(worst < 1e-4, "max error {worst:.2e}");
}

/// SVG works for every layer kind and channel: a stroke of SVG stamps with an SVG mask, a ribbon
/// of an SVG strip, and a decal whose roughness and emissive are SVG images, on the plane at 256².
/// Each layer reports the pixel size its vectors were rendered at (`raster_px`), and the bake
/// equals, within one 8-bit step, the same job with every SVG replaced by a PNG of its rendering
/// at that size (the colour and the ORM and emissive textures). Rendering the PNGs at half the
/// size fails the comparison.
#[test]
fn svg_works_for_every_layer_kind_and_channel() {
    let engine = common::engine();
    let dir = common::scratch("vector_kinds");
    std::fs::write(dir.join("shapes.svg"), SHAPES).unwrap();
    let ring = r#"<svg xmlns="http://www.w3.org/2000/svg" width="40" height="40"><circle cx="20" cy="20" r="15" fill="none" stroke="white" stroke-width="8"/></svg>"#;
    std::fs::write(dir.join("ring.svg"), ring).unwrap();
    let layers = |ext: &str| {
        let f = |stem: &str| format!("{stem}{ext}");
        serde_json::json!([
            { "kind": "stroke", "image": f("shapes"), "mask": f("ring"), "size": [0.15, 0.15],
              "path": [[0.15, 0.2, 0.0], [0.5, 0.3, 0.0], [0.85, 0.2, 0.0]], "spacing": 0.3 },
            { "kind": "ribbon", "image": f("shapes"), "width": 0.1,
              "path": [[0.15, 0.5, 0.0], [0.5, 0.55, 0.0], [0.85, 0.5, 0.0]] },
            { "image": f("shapes"), "at": [0.5, 0.8, 0.0], "size": [0.3, 0.3], "method": "planar",
              "roughness": f("ring"), "emissive": f("shapes") }
        ])
    };
    let vector = plane_job(&dir, 256, 4, layers(".svg"));
    let mesh = engine.load_mesh(&vector.mesh).unwrap();
    let baked = engine.bake(&mesh, &vector).unwrap();
    let kinds: Vec<_> = baked.channels.iter().map(|c| c.kind.name()).collect();
    assert_eq!(kinds, ["orm", "emissive"]);
    for half in [false, true] {
        // Each layer's SVGs rendered at that layer's size, into files of its own.
        let mut twin = layers(".png");
        for (i, r) in baked.report.layers.iter().enumerate() {
            let px = r
                .raster_px
                .unwrap_or_else(|| panic!("layer {i} has no raster_px"));
            let px = if half { px.map(|p| p / 2) } else { px };
            for (stem, text, raw) in [("shapes", SHAPES, false), ("ring", ring, true)] {
                let name = format!("{stem}{i}.png");
                let img = Svg::parse(text.as_bytes()).unwrap().render(px, raw);
                let bytes = if raw {
                    // A mask (and a data channel) is read as stored: write the values as they are.
                    let samples: Vec<u16> = img
                        .pixels
                        .iter()
                        .flat_map(|p| p.map(|v| (v * 255.0).round() as u16))
                        .collect();
                    decalbake::io::image::png_bytes(px[0], px[1], 8, &samples)
                } else {
                    img.encode_png(8)
                };
                std::fs::write(dir.join(&name), bytes).unwrap();
                for (k, v) in twin[i].as_object_mut().unwrap().iter_mut() {
                    if v == &serde_json::json!(format!("{stem}.png")) && k != "kind" {
                        *v = name.clone().into();
                    }
                }
            }
        }
        let job = plane_job(&dir, 256, 4, twin);
        let other = engine.bake(&mesh, &job).unwrap();
        let diff = |a: &[u16], b: &[u16]| {
            a.iter()
                .zip(b)
                .map(|(x, y)| x.abs_diff(*y))
                .max()
                .unwrap_or(0)
        };
        let mut worst = diff(&baked.texels, &other.texels);
        for (c, d) in baked.channels.iter().zip(&other.channels) {
            worst = worst.max(diff(&c.texels, &d.texels));
        }
        eprintln!(
            "PNGs at {} size: largest difference {worst} of 255",
            if half { "half" } else { "the same" }
        );
        if half {
            assert!(worst > 8, "half-size PNGs differ by only {worst}");
        } else {
            assert!(
                worst <= 1,
                "the SVG bake differs from its PNG twin by {worst} of 255"
            );
        }
    }
}

/// The GPU alternative to resvg that `bench --vector` measures (`bake::vector_gpu`): the flat
/// document drawn by point-sampled coverage on the GPU equals its CPU twin; with 4 × 4 samples a
/// pixel it matches resvg's anti-aliased rendering (mean error under 1/255: what differs is the
/// edge pixels, 16 point samples against resvg's analytic coverage); a disc's coverage sums to
/// its area.
#[test]
fn gpu_coverage_matches_its_twin_resvg_and_the_area() {
    use decalbake::bake::vector_gpu::{bin, coverage_cpu};
    let engine = common::engine();
    // SHAPES (fills, a gradient, fill opacity) and strokes: dashed, round caps and joins.
    let strokes = SHAPES.replace(
        "</svg>",
        r##"<circle cx="50" cy="50" r="38" fill="none" stroke="#102030" stroke-width="2.5" stroke-dasharray="6 4"/>
  <path d="M29 52 L44 67 L72 35" fill="none" stroke="#ffffff" stroke-width="9" stroke-linecap="round" stroke-linejoin="round"/>
  <path d="M5 5 C 60 0, 40 60, 95 40 Q 90 90 50 95 Z" fill="#6030a0" fill-rule="evenodd" fill-opacity="0.6"/>
</svg>"##,
    );
    let svg = Svg::parse(strokes.as_bytes()).unwrap();
    let px = [203u32, 157];
    let scene = svg.flatten(px).unwrap();
    // One sample a pixel (the bench's): GPU against twin. A crossing's x is computed alike, but
    // the GPU may fuse the multiply-add: a sample within rounding of an edge may fall either side.
    let one = bin(&scene, 1);
    let gpu = engine.draw_flat(&one).unwrap();
    let cpu = coverage_cpu(&one);
    let differ = gpu
        .iter()
        .zip(&cpu)
        .filter(|(g, c)| g.iter().zip(c.iter()).any(|(a, b)| (a - b).abs() > 1e-5))
        .count();
    assert!(
        differ * 1000 <= gpu.len(),
        "{differ} of {} pixels differ from the twin",
        gpu.len()
    );
    assert!(cpu.iter().any(|p| p[3] > 0.99) && cpu.iter().any(|p| p[3] == 0.0));
    // 4 × 4 samples a pixel against resvg (premultiplied 8-bit).
    let fine = bin(&scene, 4);
    let gpu = engine.draw_flat(&fine).unwrap();
    let mut pixmap = resvg::tiny_skia::Pixmap::new(px[0], px[1]).unwrap();
    let [sw, sh] = svg.size();
    let xf = resvg::tiny_skia::Transform::from_scale(px[0] as f32 / sw, px[1] as f32 / sh);
    resvg::render(&svg_tree(&strokes), xf, &mut pixmap.as_mut());
    let (mut sum, mut worst_inner) = (0.0f64, 0.0f32);
    for (i, (g, r)) in gpu.iter().zip(pixmap.data().chunks_exact(4)).enumerate() {
        let errs: Vec<f32> = (0..4).map(|c| (g[c] * 255.0 - r[c] as f32).abs()).collect();
        sum += errs.iter().map(|&e| e as f64).sum::<f64>();
        // Away from every edge (the 3 × 3 pixels around agree in resvg), at most 1.5/255:
        // rounding, and the gradient's 8-bit stops.
        let (x, y) = (i % px[0] as usize, i / px[0] as usize);
        let flat = (x > 0 && y > 0 && x + 1 < px[0] as usize && y + 1 < px[1] as usize)
            && (0..9).all(|k| {
                let q = (y + k / 3 - 1) * px[0] as usize + x + k % 3 - 1;
                pixmap.data()[4 * q..4 * q + 4] == pixmap.data()[4 * i..4 * i + 4]
            });
        if flat {
            worst_inner = worst_inner.max(errs.iter().copied().fold(0.0, f32::max));
        }
    }
    let mean = sum / (gpu.len() * 4) as f64;
    eprintln!("against resvg: mean {mean:.3}/255, away from edges {worst_inner}/255");
    assert!(mean < 0.3, "mean error {mean:.3}/255 against resvg");
    assert!(worst_inner <= 1.5, "{worst_inner}/255 away from the edges");
    // A disc of radius 40.3 px: its coverage sums to π r², less at most the perimeter times the
    // flattening tolerance (the chords lie inside the arc), within the samples' noise (2 px²).
    let disc = Svg::parse(
        br#"<svg xmlns="http://www.w3.org/2000/svg" width="100" height="100">
        <circle cx="50.2" cy="49.7" r="40.3" fill="black"/></svg>"#,
    )
    .unwrap();
    let cov = engine
        .draw_flat(&bin(&disc.flatten([100, 100]).unwrap(), 4))
        .unwrap();
    let area: f32 = cov.iter().map(|p| p[3]).sum();
    let exact = PI * 40.3 * 40.3;
    let chords = 2.0 * PI * 40.3 * decalbake::io::vector_paths::FLATTEN_TOLERANCE;
    assert!(
        area <= exact + 2.0 && area >= exact - chords - 2.0,
        "area {area} against {exact} (chords {chords})"
    );
}

/// Gradients as tiny-skia paints them (turned, several stops, hard stops at the ends, pad,
/// repeat and reflect) and shapes that cross every border of the image: the GPU coverage path at
/// 4 × 4 samples a pixel against resvg, pixel by pixel, within 3/255 wherever resvg's 3 × 3
/// neighbourhood is smooth (no step above 12/255: gradients, not edges), and a mean under 0.4/255.
#[test]
fn gpu_coverage_paints_gradients_and_crosses_the_borders_as_resvg() {
    use decalbake::bake::vector_gpu::bin;
    let engine = common::engine();
    let text = r##"<svg xmlns="http://www.w3.org/2000/svg" width="100" height="80" viewBox="0 0 100 80">
  <defs>
    <linearGradient id="pad" x1="10" y1="10" x2="60" y2="40" gradientUnits="userSpaceOnUse"
        gradientTransform="rotate(20 50 40)">
      <stop offset="0" stop-color="#ff0000"/><stop offset="0.3" stop-color="#00ff00"/>
      <stop offset="0.3" stop-color="#0000ff"/><stop offset="1" stop-color="#ffff00"/>
      <stop offset="1" stop-color="#00ffff"/></linearGradient>
    <linearGradient id="rep" x1="0" y1="0" x2="0.25" y2="0.1" spreadMethod="repeat">
      <stop offset="0" stop-color="#202080"/><stop offset="1" stop-color="#e0e020" stop-opacity="0.5"/></linearGradient>
    <linearGradient id="ref" x1="0" y1="0" x2="0.2" y2="0.3" spreadMethod="reflect">
      <stop offset="0" stop-color="#ffffff"/><stop offset="0.5" stop-color="#ff8000"/>
      <stop offset="1" stop-color="#004000"/></linearGradient>
  </defs>
  <rect x="-20" y="-15" width="140" height="110" fill="url(#pad)"/>
  <ellipse cx="95" cy="10" rx="30" ry="25" fill="url(#rep)"/>
  <path d="M-10 70 C 20 40, 60 120, 110 60 L 110 90 L -10 90 Z" fill="url(#ref)"/>
</svg>"##;
    let svg = Svg::parse(text.as_bytes()).unwrap();
    let px = [150u32, 120];
    let gpu = engine
        .draw_flat(&bin(&svg.flatten(px).unwrap(), 4))
        .unwrap();
    let mut pixmap = resvg::tiny_skia::Pixmap::new(px[0], px[1]).unwrap();
    let xf = resvg::tiny_skia::Transform::from_scale(1.5, 1.5);
    resvg::render(&svg_tree(text), xf, &mut pixmap.as_mut());
    let r = pixmap.data();
    let w = px[0] as usize;
    let (mut sum, mut worst) = (0.0f64, 0.0f32);
    for (i, g) in gpu.iter().enumerate() {
        let errs: Vec<f32> = (0..4)
            .map(|c| (g[c] * 255.0 - r[4 * i + c] as f32).abs())
            .collect();
        sum += errs.iter().map(|&e| e as f64).sum::<f64>();
        let (x, y) = (i % w, i / w);
        let smooth = x > 0
            && y > 0
            && x + 1 < w
            && y + 1 < px[1] as usize
            && (0..9).all(|k| {
                let q = (y + k / 3 - 1) * w + x + k % 3 - 1;
                (0..4).all(|c| (r[4 * q + c] as i32 - r[4 * i + c] as i32).abs() <= 12)
            });
        if smooth {
            worst = worst.max(errs.iter().copied().fold(0.0, f32::max));
        }
    }
    let mean = sum / (gpu.len() * 4) as f64;
    eprintln!("gradients against resvg: mean {mean:.3}/255, smooth parts {worst}/255");
    assert!(mean < 0.4, "mean {mean:.3}/255");
    assert!(worst <= 3.0, "{worst}/255 where resvg is smooth");
}

/// The usvg tree resvg renders `text` (without `<text>`) from.
fn svg_tree(text: &str) -> resvg::usvg::Tree {
    resvg::usvg::Tree::from_data(text.as_bytes(), &resvg::usvg::Options::default()).unwrap()
}

/// A vector decal is rendered at what its own map needs on every triangle it paints (the
/// Jacobian of texel → image coordinates), along each image axis: on a plane whose u runs four
/// times as fast left of x = 0.5 as right of it (1.6 and 0.4 texture widths a model unit; v runs
/// one texture height a unit on both halves), a decal placed right of the line but reaching across
/// it gets the left's density along x and the plane's along y (rendered at the density where it
/// landed, it would get a quarter of the pixels along x; at the isotropic mean of the two axes,
/// 0.79 of them and 1.26 times those along y); one wholly on the right keeps the right's. The
/// same decal by the default method (an exponential map) gets what the planar one gets.
#[test]
fn vector_raster_follows_the_densest_part_a_decal_reaches() {
    let engine = common::engine();
    let dir = common::scratch("vector_density");
    write_uneven_plane(&dir.join("plane.glb"));
    std::fs::write(dir.join("shapes.svg"), SHAPES).unwrap();
    let side = 512.0f32;
    let job = serde_json::json!({ "mesh": "plane.glb",
        "texture": { "width": 512, "height": 512, "padding": 0, "base": [1.0, 1.0, 1.0, 1.0] },
        "layers": [
            { "image": "shapes.svg", "at": [0.6, 0.5, 0.0], "size": [0.32, 0.32], "up": [0, 1, 0], "method": "planar" },
            { "image": "shapes.svg", "at": [0.85, 0.5, 0.0], "size": [0.2, 0.2], "up": [0, 1, 0], "method": "planar" },
            { "image": "shapes.svg", "at": [0.6, 0.5, 0.0], "size": [0.32, 0.32], "up": [0, 1, 0] }
        ] })
    .to_string();
    let job = decalbake::Job::parse(&job, &dir.join("job.json"), &dir, &dir).unwrap();
    let mesh = engine.load_mesh(&job.mesh).unwrap();
    let baked = engine.bake(&mesh, &job).unwrap();
    let px = |l: usize| baked.report.layers[l].raster_px.unwrap();
    // Texels per model unit along x on each half, and along y.
    let (dense, coarse, along_y) = (1.6 * side, 0.4 * side, side);
    let want = |size: f32, density: f32| (size * density * 2.0).ceil() as u32;
    assert_eq!(
        px(0),
        [want(0.32, dense), want(0.32, along_y)],
        "reaching the dense half"
    );
    assert_eq!(
        px(1),
        [want(0.2, coarse), want(0.2, along_y)],
        "wholly on the coarse half"
    );
    // The default method's exponential map is the plane's own length: the same as planar.
    assert_eq!(px(2), px(0), "by the exponential map");
    // The mesh keeps each unit's needs: the same layers moved, on the same mesh, are mapped
    // again (both now wholly on the coarse half), not read back from the first bake.
    let moved = serde_json::json!({ "mesh": "plane.glb",
        "texture": { "width": 512, "height": 512, "padding": 0, "base": [1.0, 1.0, 1.0, 1.0] },
        "layers": [
            { "image": "shapes.svg", "at": [0.85, 0.5, 0.0], "size": [0.32, 0.32], "up": [0, 1, 0], "method": "planar" },
            { "image": "shapes.svg", "at": [0.62, 0.5, 0.0], "size": [0.2, 0.2], "up": [0, 1, 0], "method": "planar" }
        ] })
    .to_string();
    let moved = decalbake::Job::parse(&moved, &dir.join("moved.json"), &dir, &dir).unwrap();
    let again = engine.bake(&mesh, &moved).unwrap();
    let px = |l: usize| again.report.layers[l].raster_px.unwrap();
    assert_eq!(px(0), [want(0.32, coarse), want(0.32, along_y)], "moved");
    assert_eq!(px(1), [want(0.2, coarse), want(0.2, along_y)], "moved");
}

/// A planar decal over a fold: the plane's right half turns down by 60°, its UVs laid out by
/// length on the surface (one texture width a model unit on both halves). Projected from the
/// flat half, the image's x spans twice the surface, and so twice the texels, on the slope, which
/// holds most of what the decal paints: its vector image gets twice the pixels along x as along
/// y. The same decal mapped by its exponential map, which follows the surface, gets the same along
/// both (the texel density where it lands, the old rule, gives the planar decal the same too).
#[test]
fn a_planar_vector_decal_gets_the_pixels_its_slope_needs() {
    let engine = common::engine();
    let dir = common::scratch("vector_slope");
    write_folded_plane(&dir.join("fold.glb"), 60f32.to_radians());
    std::fs::write(dir.join("shapes.svg"), SHAPES).unwrap();
    let decal = |method: &str| {
        serde_json::json!({ "image": "shapes.svg", "at": [0.45, 0.5, 0.0], "size": [0.4, 0.4],
            "up": [0, 1, 0], "method": method, "depth": 1.0 })
    };
    let job = serde_json::json!({ "mesh": "fold.glb",
        "texture": { "width": 512, "height": 512, "padding": 0, "base": [1.0, 1.0, 1.0, 1.0] },
        "layers": [decal("planar"), decal("expmap")] })
    .to_string();
    let job = decalbake::Job::parse(&job, &dir.join("job.json"), &dir, &dir).unwrap();
    let mesh = engine.load_mesh(&job.mesh).unwrap();
    let baked = engine.bake(&mesh, &job).unwrap();
    let px = |l: usize| baked.report.layers[l].raster_px.unwrap().map(|p| p as f32);
    let (planar, expmap) = (px(0), px(1));
    let along_y = (0.4f32 * 512.0 * 2.0).ceil();
    assert_eq!(planar[1], along_y, "{planar:?}");
    let ratio = planar[0] / planar[1];
    assert!(
        (ratio - 2.0).abs() < 0.02,
        "planar over the slope: {planar:?}"
    );
    let ratio = expmap[0] / expmap[1];
    assert!(
        (ratio - 1.0).abs() < 0.02,
        "the exponential map follows the slope: {expmap:?}"
    );
}

/// A plane of 32 × 16 cells over x, y in [0, 1], flat for x ≤ 0.5 and turned down by `angle`
/// beyond, its u the length along the surface (so texel density is the same on both halves).
fn write_folded_plane(path: &Path, angle: f32) {
    let (nx, ny) = (32, 16);
    let (mut pos, mut uv, mut idx) = (Vec::new(), Vec::new(), Vec::new());
    for j in 0..=ny {
        for i in 0..=nx {
            let (s, y) = (i as f32 / nx as f32, j as f32 / ny as f32);
            let p = if s <= 0.5 {
                [s, y, 0.0]
            } else {
                let d = s - 0.5;
                [0.5 + d * angle.cos(), y, -d * angle.sin()]
            };
            pos.push(p);
            uv.push([s, 1.0 - y]);
        }
    }
    for j in 0..ny {
        for i in 0..nx {
            let a = j * (nx + 1) + i;
            idx.extend([a, a + 1, a + nx + 2, a, a + nx + 2, a + nx + 1]);
        }
    }
    common::write_glb(path, &pos, Some(&uv), &idx);
}

/// The unit square in 16 × 16 cells whose UVs run four times as fast left of x = 0.5 (u = 1.6 x)
/// as right of it: texel densities in the ratio 2 : 1.
fn write_uneven_plane(path: &Path) {
    let n = 16;
    let u_of = |x: f32| {
        if x <= 0.5 {
            1.6 * x
        } else {
            0.8 + 0.4 * (x - 0.5)
        }
    };
    let (mut pos, mut uv, mut idx) = (Vec::new(), Vec::new(), Vec::new());
    for j in 0..=n {
        for i in 0..=n {
            let (x, y) = (i as f32 / n as f32, j as f32 / n as f32);
            pos.push([x, y, 0.0]);
            uv.push([u_of(x), 1.0 - y]);
        }
    }
    for j in 0..n {
        for i in 0..n {
            let a = j * (n + 1) + i;
            idx.extend([a, a + 1, a + n + 2, a, a + n + 2, a + n + 1]);
        }
    }
    common::write_glb(path, &pos, Some(&uv), &idx);
}

/// Text along a curve that starts on the coarse half of that plane and runs into the dense half
/// is rendered at the dense half's density along the curve (four times the pixels a model unit
/// of a line wholly on the coarse half) and at the plane's across it, where v runs the same on
/// both halves (the same pixels across as that line; at the isotropic density the old rule took,
/// twice them).
#[test]
fn text_along_a_curve_follows_the_densest_part_it_crosses() {
    let engine = common::engine();
    let dir = common::scratch("vector_density_text");
    write_uneven_plane(&dir.join("plane.glb"));
    let line = |x0: f32, x1: f32, y: f32| {
        let path: Vec<[f32; 3]> = (0..=4)
            .map(|i| [x0 + (x1 - x0) * i as f32 / 4.0, y, 0.0])
            .collect();
        serde_json::json!({ "kind": "text", "text": "density", "size": 0.04, "path": path,
            "interpolate": "linear", "fit": "shrink" })
    };
    let job = serde_json::json!({ "mesh": "plane.glb",
        "texture": { "width": 512, "height": 512, "padding": 0, "base": [1.0, 1.0, 1.0, 1.0] },
        "layers": [line(0.95, 0.15, 0.3), line(0.95, 0.6, 0.7)] })
    .to_string();
    let job = decalbake::Job::parse(&job, &dir.join("job.json"), &dir, &dir).unwrap();
    let mesh = engine.load_mesh(&job.mesh).unwrap();
    let baked = engine.bake(&mesh, &job).unwrap();
    let px = |l: usize| baked.report.layers[l].raster_px.unwrap().map(|p| p as f32);
    // Pixels a model unit along each line (0.8 and 0.35 units long).
    let along = [px(0)[0] / 0.8, px(1)[0] / 0.35];
    let ratio = along[0] / along[1];
    assert!((ratio - 4.0).abs() < 0.1, "along: {along:?}");
    let ratio = px(0)[1] / px(1)[1];
    assert!(
        (ratio - 1.0).abs() < 0.05,
        "{:?} against {:?} pixels across",
        px(0),
        px(1)
    );
}
