// SPDX-License-Identifier: MIT OR Apache-2.0
//! An SVG document as flat line segments in pixel space, per filled path, with its paint: the
//! input of the GPU coverage evaluation that `decalbake bench --vector` measures against resvg
//! (`bake::vector_gpu`). What the bake itself uses is resvg's rendering ([`super::vector`]).
//!
//! Paths are transformed as resvg draws them over `px` pixels (the document's own units scaled to
//! that size, each path's absolute transform), curves flattened to lines within
//! [`FLATTEN_TOLERANCE`] pixels, every subpath closed (a fill closes them), and strokes turned
//! into the outlines resvg fills for them (dashed, then stroked by tiny-skia's stroker at the same
//! resolution scale). Paints are solid colours and linear gradients (pad, repeat, reflect), colour
//! as stored (sRGB-encoded, straight), each stop's alpha times the fill's opacity, quantised to
//! 8 bits as resvg's paints are. What the evaluation does not draw is an error naming it: radial
//! gradients, patterns, embedded images, and groups that resvg draws into a layer of their own
//! (opacity, clip paths, masks, filters, blend modes).

use super::vector::Svg;
use resvg::tiny_skia::{PathSegment, PathStroker, Point, Transform};
use resvg::usvg;

/// How far a flattened curve may stray from the curve, in pixels.
pub const FLATTEN_TOLERANCE: f32 = 0.1;

/// The most lines one curve is flattened into.
const MAX_PIECES: usize = 4096;

/// A paint: what a covered pixel of its path shows.
#[derive(Clone, Debug, PartialEq)]
pub enum FlatPaint {
    /// One straight-alpha colour, sRGB-encoded, in [0, 1].
    Solid([f32; 4]),
    /// A linear gradient: `t = a x + b y + c` at pixel centre (x, y), `spread` 0 pad, 1 repeat,
    /// 2 reflect, and its stops (offset, straight colour) with offsets rising from 0 to 1.
    Linear {
        /// The coefficients of t over pixel coordinates.
        t: [f32; 3],
        /// 0 pad, 1 repeat, 2 reflect.
        spread: u32,
        /// (offset, straight colour), offsets from 0 to 1, non-decreasing.
        stops: Vec<(f32, [f32; 4])>,
    },
}

/// One filled path: its closed outline as segments `[x0, y0, x1, y1]` in pixels (y down),
/// horizontal ones left out (they cross no row), its fill rule and paint.
#[derive(Clone, Debug)]
pub struct FlatPath {
    /// Segments, pixels.
    pub segments: Vec<[f32; 4]>,
    /// Even-odd (else non-zero).
    pub even_odd: bool,
    /// The paint.
    pub paint: FlatPaint,
}

/// A document over `size` pixels: its filled paths in drawing order (source-over).
#[derive(Clone, Debug)]
pub struct FlatScene {
    /// Width and height, pixels.
    pub size: [u32; 2],
    /// Paths, bottom first.
    pub paths: Vec<FlatPath>,
}

impl FlatScene {
    /// Every segment of the scene.
    pub fn segment_count(&self) -> usize {
        self.paths.iter().map(|p| p.segments.len()).sum()
    }
}

impl Svg {
    /// The document as flat paths over `px` pixels (stretched to that size, each side held to
    /// [`super::vector::MAX_SIDE`], as [`Svg::render`]); an error names what the flat form
    /// cannot hold.
    pub fn flatten(&self, px: [u32; 2]) -> Result<FlatScene, String> {
        let [w, h] = px.map(|p| p.clamp(1, super::vector::MAX_SIDE));
        let [sw, sh] = self.size();
        let xf = Transform::from_scale(w as f32 / sw, h as f32 / sh);
        let mut paths = Vec::new();
        flatten_group(self.tree().root(), xf, &mut paths)?;
        Ok(FlatScene {
            size: [w, h],
            paths,
        })
    }
}

fn flatten_group(
    group: &usvg::Group,
    xf: Transform,
    out: &mut Vec<FlatPath>,
) -> Result<(), String> {
    let xf = xf.pre_concat(group.transform());
    if group.should_isolate() {
        return Err(format!(
            "group \"{}\" is drawn as a layer of its own (opacity, clip path, mask, filter or blend mode)",
            group.id()
        ));
    }
    for node in group.children() {
        match node {
            usvg::Node::Group(g) => flatten_group(g, xf, out)?,
            usvg::Node::Text(t) => flatten_group(t.flattened(), xf, out)?,
            usvg::Node::Image(i) => return Err(format!("image \"{}\" is embedded", i.id())),
            usvg::Node::Path(p) => flatten_path(p, xf, out)?,
        }
    }
    Ok(())
}

/// A path's fill and stroke, in its paint order, as resvg draws them.
fn flatten_path(path: &usvg::Path, xf: Transform, out: &mut Vec<FlatPath>) -> Result<(), String> {
    if !path.is_visible() {
        return Ok(());
    }
    // usvg keeps transforms on groups: a path is drawn under its group's.
    let ts = xf;
    let fill = |out: &mut Vec<FlatPath>| -> Result<(), String> {
        let Some(f) = path.fill() else { return Ok(()) };
        let b = path.data().bounds();
        // resvg does not fill a path without area.
        if b.width() == 0.0 || b.height() == 0.0 {
            return Ok(());
        }
        let paint = flat_paint(f.paint(), f.opacity(), ts, path.id())?;
        out.push(FlatPath {
            segments: segments(path.data(), ts),
            even_odd: f.rule() == usvg::FillRule::EvenOdd,
            paint,
        });
        Ok(())
    };
    let stroke = |out: &mut Vec<FlatPath>| -> Result<(), String> {
        let Some(s) = path.stroke() else {
            return Ok(());
        };
        let paint = flat_paint(s.paint(), s.opacity(), ts, path.id())?;
        let sk = s.to_tiny_skia();
        let res = PathStroker::compute_resolution_scale(&ts);
        let dashed;
        let src = match &sk.dash {
            Some(d) => {
                dashed = path.data().dash(d, res);
                match &dashed {
                    Some(p) => p,
                    None => return Ok(()),
                }
            }
            None => path.data(),
        };
        let Some(outline) = src.stroke(&sk, res) else {
            return Ok(());
        };
        out.push(FlatPath {
            segments: segments(&outline, ts),
            even_odd: false,
            paint,
        });
        Ok(())
    };
    match path.paint_order() {
        usvg::PaintOrder::FillAndStroke => {
            fill(out)?;
            stroke(out)
        }
        usvg::PaintOrder::StrokeAndFill => {
            stroke(out)?;
            fill(out)
        }
    }
}

/// A usvg paint as a flat one, under the path's transform `ts` (gradients are evaluated in pixel
/// space).
fn flat_paint(
    paint: &usvg::Paint,
    opacity: usvg::Opacity,
    ts: Transform,
    id: &str,
) -> Result<FlatPaint, String> {
    let u8f = |v: u8| v as f32 / 255.0;
    match paint {
        usvg::Paint::Color(c) => Ok(FlatPaint::Solid([
            u8f(c.red),
            u8f(c.green),
            u8f(c.blue),
            u8f(opacity.to_u8()),
        ])),
        usvg::Paint::LinearGradient(lg) => {
            // Pixel → gradient space, then t along (x1, y1) → (x2, y2): affine in the pixel.
            let inv = ts.pre_concat(lg.transform()).invert().ok_or_else(|| {
                format!("path \"{id}\": its gradient's transform cannot be inverted")
            })?;
            let (dx, dy) = (lg.x2() - lg.x1(), lg.y2() - lg.y1());
            let len2 = dx * dx + dy * dy;
            let t = if len2 > 1e-12 {
                // t = ((inv p) - p1) · d / |d|², inv p = (sx x + kx y + tx, ky x + sy y + ty).
                [
                    (inv.sx * dx + inv.ky * dy) / len2,
                    (inv.kx * dx + inv.sy * dy) / len2,
                    ((inv.tx - lg.x1()) * dx + (inv.ty - lg.y1()) * dy) / len2,
                ]
            } else if lg.spread_method() == usvg::SpreadMethod::Pad {
                // tiny-skia draws a degenerate padded gradient in its last stop's colour.
                [0.0, 0.0, 1.0]
            } else {
                return Err(format!(
                    "path \"{id}\": its repeated or reflected gradient has no length"
                ));
            };
            let spread = match lg.spread_method() {
                usvg::SpreadMethod::Pad => 0,
                usvg::SpreadMethod::Repeat => 1,
                usvg::SpreadMethod::Reflect => 2,
            };
            let mut stops: Vec<(f32, [f32; 4])> = Vec::new();
            for s in lg.stops() {
                let c = s.color();
                let a = (s.opacity() * opacity).to_u8();
                let last = stops.last().map_or(0.0, |l| l.0);
                let colour = [u8f(c.red), u8f(c.green), u8f(c.blue), u8f(a)];
                stops.push((s.offset().get().clamp(last, 1.0), colour));
            }
            let (Some(first), Some(last)) = (stops.first().copied(), stops.last().copied()) else {
                return Err(format!("path \"{id}\": its gradient has no stops"));
            };
            if first.0 > 0.0 {
                stops.insert(0, (0.0, first.1));
            }
            if last.0 < 1.0 {
                stops.push((1.0, last.1));
            }
            Ok(FlatPaint::Linear { t, spread, stops })
        }
        usvg::Paint::RadialGradient(_) => Err(format!("path \"{id}\" has a radial gradient")),
        usvg::Paint::Pattern(_) => Err(format!("path \"{id}\" has a pattern")),
    }
}

/// The path's outline under `ts` as line segments, each subpath closed, curves flattened.
fn segments(path: &resvg::tiny_skia::Path, ts: Transform) -> Vec<[f32; 4]> {
    let map = |p: Point| {
        let mut q = p;
        ts.map_point(&mut q);
        [q.x, q.y]
    };
    let mut out = Vec::new();
    let (mut start, mut at) = ([0.0f32; 2], [0.0f32; 2]);
    // Horizontal lines cross no row; a line with a non-finite end (a transform out of range) is
    // left out rather than binned.
    let line = |a: [f32; 2], b: [f32; 2], out: &mut Vec<[f32; 4]>| {
        if a[1] != b[1] && a.iter().chain(&b).all(|v| v.is_finite()) {
            out.push([a[0], a[1], b[0], b[1]]);
        }
    };
    for seg in path.segments() {
        match seg {
            PathSegment::MoveTo(p) => {
                line(at, start, &mut out);
                start = map(p);
                at = start;
            }
            PathSegment::LineTo(p) => {
                let q = map(p);
                line(at, q, &mut out);
                at = q;
            }
            PathSegment::QuadTo(c, p) => {
                let (c, q) = (map(c), map(p));
                let dev = 0.25 * len([at[0] - 2.0 * c[0] + q[0], at[1] - 2.0 * c[1] + q[1]]);
                let n = pieces(dev);
                let mut prev = at;
                for i in 1..=n {
                    let t = i as f32 / n as f32;
                    let u = 1.0 - t;
                    let p = [
                        u * u * at[0] + 2.0 * u * t * c[0] + t * t * q[0],
                        u * u * at[1] + 2.0 * u * t * c[1] + t * t * q[1],
                    ];
                    line(prev, p, &mut out);
                    prev = p;
                }
                at = q;
            }
            PathSegment::CubicTo(c1, c2, p) => {
                let (c1, c2, q) = (map(c1), map(c2), map(p));
                let d1 = len([at[0] - 2.0 * c1[0] + c2[0], at[1] - 2.0 * c1[1] + c2[1]]);
                let d2 = len([c1[0] - 2.0 * c2[0] + q[0], c1[1] - 2.0 * c2[1] + q[1]]);
                let n = pieces(0.75 * d1.max(d2));
                let mut prev = at;
                for i in 1..=n {
                    let t = i as f32 / n as f32;
                    let u = 1.0 - t;
                    let (a, b, c, d) = (u * u * u, 3.0 * u * u * t, 3.0 * u * t * t, t * t * t);
                    let p = [
                        a * at[0] + b * c1[0] + c * c2[0] + d * q[0],
                        a * at[1] + b * c1[1] + c * c2[1] + d * q[1],
                    ];
                    line(prev, p, &mut out);
                    prev = p;
                }
                at = q;
            }
            PathSegment::Close => {
                line(at, start, &mut out);
                at = start;
            }
        }
    }
    line(at, start, &mut out);
    out
}

fn len(v: [f32; 2]) -> f32 {
    (v[0] * v[0] + v[1] * v[1]).sqrt()
}

/// Lines for a curve whose control polygon strays `dev` pixels from its chord: the error of n
/// lines falls as 1/n².
fn pieces(dev: f32) -> usize {
    if !dev.is_finite() {
        return 1;
    }
    ((dev / FLATTEN_TOLERANCE).sqrt().ceil() as usize).clamp(1, MAX_PIECES)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_square_keeps_its_upright_sides_a_circle_stays_within_the_tolerance_and_a_stroke_rings() {
        let svg = Svg::parse(
            br#"<svg xmlns="http://www.w3.org/2000/svg" width="10" height="10">
            <rect x="2" y="2" width="6" height="6" fill="red"/>
            <circle cx="5" cy="5" r="4" fill="none" stroke="blue" stroke-width="1"/>
            <circle cx="5" cy="5" r="3" fill="green"/></svg>"#,
        )
        .unwrap();
        let scene = svg.flatten([100, 100]).unwrap();
        assert_eq!(scene.paths.len(), 3);
        // The square: two vertical sides (the horizontal ones cross no row), at 20 and 80 px.
        let sq = &scene.paths[0];
        assert_eq!(sq.segments.len(), 2, "{:?}", sq.segments);
        assert!(sq
            .segments
            .iter()
            .all(|s| s[0] == s[2] && (s[0] == 20.0 || s[0] == 80.0)));
        assert_eq!(sq.paint, FlatPaint::Solid([1.0, 0.0, 0.0, 1.0]));
        let radius = |x: f32, y: f32| ((x - 50.0).powi(2) + (y - 50.0).powi(2)).sqrt();
        // The filled circle (r 30 px, four cubic arcs 0.01 px from the circle): each line's ends
        // on it, its middle inside by at most the flattening tolerance.
        let disc = &scene.paths[2];
        assert!(disc.segments.len() > 40);
        for s in &disc.segments {
            assert!((radius(s[0], s[1]) - 30.0).abs() < 0.02, "{s:?}");
            let mid = radius(0.5 * (s[0] + s[2]), 0.5 * (s[1] + s[3]));
            assert!(
                (30.0 - FLATTEN_TOLERANCE - 0.02..=30.02).contains(&mid),
                "{mid}"
            );
        }
        // The stroke's outline: two rings at radii 35 and 45 px (tiny-skia's stroker offsets the
        // circle by curves of its own, within about 0.2 px).
        let ring = &scene.paths[1];
        for s in &ring.segments {
            let r = radius(s[0], s[1]);
            assert!((r - 35.0).abs() < 0.2 || (r - 45.0).abs() < 0.2, "{r}");
        }
    }

    #[test]
    fn what_the_flat_form_cannot_hold_is_named() {
        let svg = Svg::parse(
            br#"<svg xmlns="http://www.w3.org/2000/svg" width="10" height="10">
            <g opacity="0.5"><rect id="r" width="5" height="5"/></g></svg>"#,
        )
        .unwrap();
        let e = svg.flatten([10, 10]).unwrap_err();
        assert!(e.contains("layer of its own"), "{e}");
        let svg = Svg::parse(
            br#"<svg xmlns="http://www.w3.org/2000/svg" width="10" height="10">
            <defs><radialGradient id="g"><stop offset="0" stop-color="red"/><stop offset="1" stop-color="blue"/></radialGradient></defs>
            <rect id="box" width="5" height="5" fill="url(#g)"/></svg>"#,
        )
        .unwrap();
        let e = svg.flatten([10, 10]).unwrap_err();
        assert!(e.contains("radial gradient"), "{e}");
    }
}
