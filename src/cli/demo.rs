// SPDX-License-Identifier: MIT OR Apache-2.0
//! The built-in demo scene: Keenan Crane's "Spot" (public domain, bundled in `assets/`) with four
//! decals generated in code, one per blend style, a conformal decal on a horn tip (a cone chart), a painted stroke over the UV seam along its back,
//! a blur stroke across the edges of the badge and a black patch beside it, and a ribbon of
//! stripes tiled along a wave on the other flank, an SVG logo on the rump and a line of text
//! along a flank (rendered from vectors at the sizes their maps need). The badge is warped by a thin-plate spline; the
//! ribbon is also animated along its wave (`frames.json`), and the badge extracted back from the
//! baked texture (`decalbake extract`). `decalbake demo` writes the scene's files (mesh,
//! decal PNGs, job file) next to its outputs, so the job can be edited and re-run with `decalbake bake`.

use decalbake::io::image::{srgb_to_linear, LinearImage};
use std::f32::consts::PI;

/// The demo's vector logo (`decals/logo.svg`): a gradient disc with a tick and a ring, drawn by
/// the bake at the size its map needs, not from a bitmap.
pub const LOGO_SVG: &str = r##"<svg xmlns="http://www.w3.org/2000/svg" width="100" height="100" viewBox="0 0 100 100">
  <defs>
    <linearGradient id="disc" x1="0" y1="0" x2="1" y2="1">
      <stop offset="0" stop-color="#ff7a18"/><stop offset="1" stop-color="#c2185b"/>
    </linearGradient>
  </defs>
  <circle cx="50" cy="50" r="46" fill="url(#disc)"/>
  <circle cx="50" cy="50" r="38" fill="none" stroke="#ffffff" stroke-width="2.5" stroke-dasharray="6 4"/>
  <path d="M29 52 L44 67 L72 35" fill="none" stroke="#ffffff" stroke-width="9" stroke-linecap="round" stroke-linejoin="round"/>
</svg>
"##;

/// The bundled mesh.
pub const SPOT_GLB: &[u8] = include_bytes!("../../assets/spot.glb");
/// Keenan Crane's crumpled developable sheet (public domain), unwrapped by the demo.
pub const CRUMPLED_GLB: &[u8] = include_bytes!("../../assets/crumpled_developable.glb");
/// Keenan Crane's bob (CC0), a model with a handle: the demo's patch with bridges.
pub const BOB_GLB: &[u8] = include_bytes!("../../assets/bob.glb");
/// The animated knight by Clement Wu, Nikolaus & Botanic (CC-BY 3.0; `assets/README.md`): a
/// skinned character of two materials with five animations, which the demo's bake keeps.
pub const KNIGHT_GLB: &[u8] = include_bytes!("../../assets/knight.glb");

/// The demo's knight job (`knight.json`): the badge on its chest, a surface-following material
/// decal: colour, an embossed normal map, roughness and metallic (gold metal, enamel not); and
/// rings painted on the shield, which lies in the knight's second material (`gear`): two
/// texture sets, each baked into its own textures.
pub fn knight_json() -> String {
    serde_json::to_string_pretty(&serde_json::json!({
        "mesh": "knight.glb",
        "texture": { "width": 1024, "height": 1024, "base": "material", "padding": 8 },
        "layers": [
            { "kind": "decal", "image": "decals/badge.png", "at": { "ray": { "origin": [0.0, 1.35, 3.0], "dir": [0, 0, -1] } },
              "size": [0.35, 0.35], "up": [0, 1, 0], "method": "expmap",
              "normal": "decals/badge_normal.png", "roughness": 0.3, "metallic": "decals/badge_metal.png" },
            { "kind": "decal", "image": "decals/rings.png", "at": { "ray": { "origin": [3.0, 1.62, -0.04], "dir": [-1, 0, 0] } },
              "size": [0.3, 0.3], "up": [0, 1, 0], "method": "expmap", "roughness": 0.6 }
        ],
        "output": { "texture": "knight-baked.png", "glb": "knight-baked.glb", "preview": "knight-preview.png", "report": "knight-report.json" }
    }))
    .expect("static JSON serializes")
}

fn img(side: u32, f: impl Fn(f32, f32) -> [f32; 4]) -> LinearImage {
    let mut out = LinearImage::solid(side, side, [0.0; 4]);
    for y in 0..side {
        for x in 0..side {
            // Centred coordinates in [-1, 1], y up.
            let u = 2.0 * (x as f32 + 0.5) / side as f32 - 1.0;
            let v = 1.0 - 2.0 * (y as f32 + 0.5) / side as f32;
            let c = f(u, v);
            out.pixels[(y * side + x) as usize] = [
                srgb_to_linear(c[0]),
                srgb_to_linear(c[1]),
                srgb_to_linear(c[2]),
                c[3],
            ];
        }
    }
    out
}

fn smooth_edge(d: f32, width: f32) -> f32 {
    (0.5 - d / width).clamp(0.0, 1.0)
}

/// A round badge with a five-pointed star (sRGB colours given, alpha outside the disc).
pub fn badge(side: u32) -> LinearImage {
    let aa = 2.0 / side as f32;
    img(side, |u, v| {
        let (ring, star, disc) = badge_parts(u, v, aa);
        let base = [0.75, 0.08, 0.1];
        let gold = [1.0, 0.8, 0.2];
        let mix = |a: [f32; 3], b: [f32; 3], t: f32| {
            [
                a[0] + (b[0] - a[0]) * t,
                a[1] + (b[1] - a[1]) * t,
                a[2] + (b[2] - a[2]) * t,
            ]
        };
        let c = mix(mix(base, gold, ring), gold, star);
        [c[0], c[1], c[2], disc]
    })
}

/// The badge's parts at centred (u, v), each in [0, 1] with edges `aa` wide: its ring, its
/// five-pointed star (radius between 0.3 and 0.72 by angle) and its disc.
fn badge_parts(u: f32, v: f32, aa: f32) -> (f32, f32, f32) {
    let r = (u * u + v * v).sqrt();
    let disc = smooth_edge(r - 0.95, aa);
    let ring = smooth_edge((r - 0.84).abs() - 0.05, aa);
    let a = v.atan2(u) - PI / 2.0;
    let sector = (a.rem_euclid(2.0 * PI / 5.0) - PI / 5.0).abs() / (PI / 5.0);
    let star_r = 0.3 + 0.42 * (1.0 - sector).powf(1.6);
    let star = smooth_edge(r - star_r, aa);
    (ring, star, disc)
}

/// The badge embossed: a tangent-space normal map (glTF's convention, green up) of its gold
/// raised over the enamel and the disc's rim, from the height field's slopes.
pub fn badge_normal(side: u32) -> LinearImage {
    // Soft edges so the slopes span a few texels.
    let soft = 0.06;
    let height = |u: f32, v: f32| {
        let (ring, star, disc) = badge_parts(u, v, soft);
        0.5 * disc + 0.6 * ring.max(star)
    };
    let d = 2.0 / side as f32;
    let depth = 0.05;
    img(side, |u, v| {
        let hx = (height(u + d, v) - height(u - d, v)) / (2.0 * d);
        let hy = (height(u, v + d) - height(u, v - d)) / (2.0 * d);
        let n = glam::Vec3::new(-hx * depth, -hy * depth, 1.0).normalize();
        [n.x * 0.5 + 0.5, n.y * 0.5 + 0.5, n.z * 0.5 + 0.5, 1.0]
    })
}

/// The badge's metallic: its gold 1, its enamel 0 (a data image: red read as stored).
pub fn badge_metal(side: u32) -> LinearImage {
    let aa = 2.0 / side as f32;
    img(side, |u, v| {
        let (ring, star, _) = badge_parts(u, v, aa);
        let gold = ring.max(star);
        [gold, gold, gold, 1.0]
    })
}

/// Diagonal racing stripes in a rounded rectangle.
pub fn stripes(side: u32) -> LinearImage {
    let aa = 2.0 / side as f32;
    img(side, |u, v| {
        let d = ((u.abs() - 0.9).max(0.0).powi(2) + (v.abs() - 0.9).max(0.0).powi(2)).sqrt();
        let inside = smooth_edge(d - 0.08, aa);
        let s = ((u + v) * 4.0).rem_euclid(2.0);
        let t = smooth_edge((s - 1.0).abs() - 0.5, aa * 8.0);
        let blue = [0.1, 0.25, 0.8];
        let white = [0.97, 0.97, 0.97];
        let c = [
            blue[0] + (white[0] - blue[0]) * t,
            blue[1] + (white[1] - blue[1]) * t,
            blue[2] + (white[2] - blue[2]) * t,
        ];
        [c[0], c[1], c[2], inside]
    })
}

/// Concentric rings (used with multiply).
pub fn rings(side: u32) -> LinearImage {
    let aa = 2.0 / side as f32;
    img(side, |u, v| {
        let r = (u * u + v * v).sqrt();
        let band = ((r * 5.0).rem_euclid(1.0) - 0.5).abs();
        let dark = smooth_edge(band - 0.22, aa * 5.0);
        let alpha = smooth_edge(r - 0.95, aa);
        let c = 1.0 - 0.85 * dark;
        [c * 0.4 + 0.1, c * 0.2 + 0.05, c, alpha]
    })
}

/// A soft glow (used with screen).
pub fn glow(side: u32) -> LinearImage {
    img(side, |u, v| {
        let r2 = u * u + v * v;
        let a = (-r2 * 4.0).exp() * (1.0 - r2).max(0.0);
        [1.0, 0.85, 0.3, a]
    })
}

/// A round brush tip: an opaque core with a soft rim (used by the stroke).
pub fn brush(side: u32) -> LinearImage {
    img(side, |u, v| {
        let r = (u * u + v * v).sqrt();
        let a = ((1.0 - r) / 0.35).clamp(0.0, 1.0);
        [0.1, 0.55, 0.25, a * a * (3.0 - 2.0 * a)]
    })
}

/// The demo stroke's path: rays from above, a wave across Spot's back (over the UV seam along the
/// spine), with pressure rising and falling.
fn stroke_path() -> (Vec<serde_json::Value>, Vec<f32>) {
    (0..9)
        .map(|k| {
            let t = k as f32 / 8.0;
            let x = -0.3 + 0.6 * t;
            let z = 0.22 + 0.09 * (t * 2.0 * PI).sin();
            let ray = serde_json::json!({ "ray": { "origin": [x, 1.5, z], "dir": [0, -1, 0] } });
            (ray, 0.4 + 0.6 * (t * PI).sin())
        })
        .unzip()
}

/// The demo ribbon's path: rays from Spot's right, a wave along its flank below the rings decal.
fn ribbon_path() -> Vec<serde_json::Value> {
    (0..11)
        .map(|k| {
            let t = k as f32 / 10.0;
            let z = 0.05 + 0.65 * t;
            let y = -0.22 + 0.04 * (t * 2.0 * PI).sin();
            serde_json::json!({ "ray": { "origin": [-1.5, y, z], "dir": [1, 0, 0] } })
        })
        .collect()
}

/// The demo text's curve: rays from +x, along Spot's flank below the badge, from the rump towards
/// the head (seen from +x, left to right: the glyphs' up is the curve's left).
fn text_path() -> Vec<serde_json::Value> {
    (0..9)
        .map(|k| {
            let t = k as f32 / 8.0;
            let z = 0.72 - 0.62 * t;
            let y = -0.26 + 0.03 * (t * PI).sin();
            serde_json::json!({ "ray": { "origin": [1.5, y, z], "dir": [-1, 0, 0] } })
        })
        .collect()
}

/// The job that bakes two decals into bob's pelt, patch and bridges (`decalbake unwrap --patch`
/// made `bob-patched.glb`: its seams have cycles, so the patch is cut across twice and bridged,
/// `pelt::bridge`), over the two places where the patch's cuts cross the pelt's seam (found once
/// from the file's `_PELT_BRIDGE`), and previews them blended.
pub fn bob_job_json() -> String {
    serde_json::to_string_pretty(&serde_json::json!({
        "mesh": "bob-patched.glb",
        "uv_set": [1, 2, 3],
        "texture": { "width": 1024, "height": 1024, "base": "material" },
        "layers": [
            { "kind": "decal", "image": "decals/rings.png", "at": [-0.369, -0.501, 0.036], "size": [0.3, 0.3] },
            { "kind": "decal", "image": "decals/badge.png", "at": [0.387, -0.234, -0.179], "size": [0.3, 0.3] }
        ],
        "output": { "texture": "bob_uv{uv}.png", "report": "bob-report-uv{uv}.json", "preview": "bob-blended.png" }
    }))
    .expect("static JSON")
}

/// The demo job (paths relative to the demo directory).
pub fn job_json() -> String {
    let (path, pressure) = stroke_path();
    // Across the top of the badge on the flank and the black patch beside it.
    let blur_path: Vec<serde_json::Value> = [0.28f32, 0.45, 0.62]
        .iter()
        .map(|z| serde_json::json!({ "ray": { "origin": [1.5, 0.15, z], "dir": [-1, 0, 0] } }))
        .collect();
    serde_json::to_string_pretty(&serde_json::json!({
        "$schema": "job.schema.json",
        "mesh": "spot.glb",
        "uv_set": 0,
        "texture": { "width": 1024, "height": 1024, "base": "material", "padding": 16, "samples": 4 },
        "layers": [
            { "kind": "decal", "image": "decals/badge.png", "at": { "ray": { "origin": [1.5, 0.0, 0.45], "dir": [-1, 0, 0] } },
              "size": [0.32, 0.32], "angle": 0.0, "up": [0, 1, 0], "method": "planar", "blend": "normal", "opacity": 1.0,
              // The star's centre pulled up and right, its lower left point down: a thin-plate
              // spline warp of the image.
              "warp": [[[0.5, 0.5], [0.58, 0.42]], [[0.25, 0.7], [0.2, 0.78]]] },
            { "kind": "decal", "image": "decals/stripes.png", "at": { "ray": { "origin": [0.0, 1.5, 0.55], "dir": [0, -1, 0] } },
              "size": [0.3, 0.3], "angle": 45.0, "up": [0, 0, 1], "method": "expmap", "blend": "normal", "opacity": 0.9 },
            { "kind": "decal", "image": "decals/rings.png", "at": { "ray": { "origin": [-1.5, 0.0, 0.45], "dir": [1, 0, 0] } },
              "size": [0.35, 0.35], "up": [0, 1, 0], "method": "lscm", "blend": "multiply" },
            { "kind": "decal", "image": "decals/glow.png", "at": { "ray": { "origin": [0.0, 0.55, -1.5], "dir": [0, 0, 1] } },
              "size": [0.3, 0.3], "method": "planar", "blend": "screen", "opacity": 0.8 },
            // On the tip of the left horn, just in front of it: a cone chart, opened along a cut
            // from the tip away from the placed point (down the back of the horn).
            { "kind": "decal", "image": "decals/rings.png", "at": [0.2, 0.95, -0.285],
              "size": [0.22, 0.22], "up": [0, 0, -1], "method": "lscm", "blend": "normal" },
            { "kind": "stroke", "image": "decals/brush.png", "path": path, "pressure": pressure,
              "size": [0.1, 0.1], "spacing": 0.15, "flow": 0.8, "opacity": 0.95, "method": "lscm" },
            { "kind": "stroke", "tool": "blur", "radius": 0.025, "image": "decals/brush.png",
              "path": blur_path,
              "size": [0.09, 0.09], "spacing": 0.2 },
            // Stripes tiled along a wave on the right flank: a ribbon (the curve's extended
            // exponential map).
            { "kind": "ribbon", "image": "decals/stripes.png", "path": ribbon_path(),
              "width": 0.09, "repeat": "tile" },
            // A vector logo on the rump: the SVG is rendered where it lands, at the texel
            // density there, so it stays sharp at any size.
            { "kind": "decal", "image": "decals/logo.svg", "at": { "ray": { "origin": [0.0, 0.05, 1.5], "dir": [0, 0, -1] } },
              "size": [0.26, 0.26], "up": [0, 1, 0], "method": "expmap" },
            // A line of text along the left flank, below the badge: shaped by rustybuzz,
            // its baseline on the curve.
            { "kind": "text", "text": "Spot · decalbake", "size": 0.075, "color": [0.08, 0.16, 0.45, 1.0],
              "path": text_path() }
        ],
        "output": { "texture": "baked.png", "bit_depth": 8, "glb": "baked.glb", "report": "report.json", "preview": "preview.png" }
    }))
    .expect("static JSON serializes")
}

/// The demo's animation (`frames.json`): the stripes, a third of the route long, travelling
/// along the demo ribbon's wave over 8 frames, one 512² texture each (`frames/ribbon_0.png` ...).
pub fn frames_json() -> String {
    serde_json::to_string_pretty(&serde_json::json!({
        "mesh": "spot.glb",
        "texture": { "width": 512, "height": 512, "base": "material", "padding": 8, "samples": 4 },
        "layers": [
            { "kind": "ribbon", "image": "decals/stripes.png", "width": 0.09, "repeat": "tile",
              "animate": { "route": ribbon_path(), "frames": 8, "length": 0.25 } }
        ],
        "output": { "texture": "frames/ribbon_{frame}.png", "report": null }
    }))
    .expect("static JSON serializes")
}

/// The decal images of the demo: (file name, image).
pub fn decals() -> Vec<(&'static str, LinearImage)> {
    vec![
        ("badge.png", badge(256)),
        ("badge_normal.png", badge_normal(256)),
        ("badge_metal.png", badge_metal(256)),
        ("stripes.png", stripes(256)),
        ("rings.png", rings(256)),
        ("glow.png", glow(256)),
        ("brush.png", brush(64)),
    ]
}
