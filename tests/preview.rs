// SPDX-License-Identifier: MIT OR Apache-2.0
//! The preview shades with the bake's normal map: a dome-shaped normal decal on a plane lights up
//! on its side towards the key light and darkens on the other against the same bake without the
//! normal map, and away from the decal the two previews agree within 1/255; in a several-set
//! preview, only on the set given the channels.

mod common;

use decalbake::output::preview::{
    render_preview, render_sets_material_preview, PreviewChannels, PreviewTexture, VIEW_SIDE,
};
use decalbake::{Baked, Engine, LoadedMesh};
use glam::{Mat4, Vec3};
use serde_json::json;
use std::path::Path;

/// Grid cells of the plane a side.
const N: u32 = 16;
/// The dome's slope: its normal at image point (s, t) (t down the image) is
/// normalize(A (s - ½), A (½ - t), 1).
const A: f32 = 1.2;

/// Bakes a white decal of half the plane's side at its centre, with the dome's normal map when
/// `normal`.
fn bake(engine: &Engine, dir: &Path, normal: bool) -> (LoadedMesh, Baked) {
    common::write_plane(&dir.join("plane.glb"), N, false);
    common::write_raw_png(&dir.join("white.png"), 8, |_, _| [1.0; 4]);
    common::write_raw_png(&dir.join("dome.png"), 128, |s, t| {
        let n = Vec3::new(A * (s - 0.5), A * (0.5 - t), 1.0).normalize() * 0.5 + 0.5;
        [n.x, n.y, n.z, 1.0]
    });
    let mut layer = json!({
        "image": "white.png", "at": [0.5, 0.5, 0.0], "size": [0.5, 0.5], "up": [0.0, 1.0, 0.0]
    });
    if normal {
        layer["normal"] = json!("dome.png");
    }
    let job = json!({
        "mesh": "plane.glb",
        "texture": {"width": 128, "height": 128, "base": [0.5, 0.5, 0.5, 1.0], "padding": 2},
        "output": {"texture": "baked.png"},
        "layers": [layer]
    });
    std::fs::write(dir.join("job.json"), job.to_string()).unwrap();
    let job = decalbake::Job::load(&dir.join("job.json"), None).unwrap();
    let (mesh, job) = engine.load_mesh_for(&job).unwrap();
    let baked = engine.bake(&mesh, &job).unwrap();
    assert_eq!(baked.channels.len(), normal as usize);
    (mesh, baked)
}

/// The front view (`VIEW_SIDE`², sRGB RGBA8) of a preview's pixels.
fn front(px: &[u8]) -> Vec<u8> {
    let (side, view) = (2 * VIEW_SIDE as usize, VIEW_SIDE as usize);
    (0..view)
        .flat_map(|y| px[y * side * 4..(y * side + view) * 4].to_vec())
        .collect()
}

/// The front view's pixel of plane point (x, y), as `preview.rs` projects it: orthographic from
/// 20° above +z, around the plane's box.
fn pixel(x: f32, y: f32) -> (usize, usize) {
    let (center, r) = (Vec3::new(0.5, 0.5, 0.0), 0.5 * 2f32.sqrt());
    let el = 20f32.to_radians();
    let eye = center + Vec3::new(0.0, el.sin(), el.cos()) * 2.0 * r;
    let vp = Mat4::orthographic_rh(-r, r, -r, r, 0.5 * r, 3.5 * r)
        * Mat4::look_at_rh(eye, center, Vec3::Y);
    let c = vp.project_point3(Vec3::new(x, y, 0.0));
    let side = VIEW_SIDE as f32;
    (
        ((c.x + 1.0) * 0.5 * side) as usize,
        ((1.0 - c.y) * 0.5 * side) as usize,
    )
}

/// Mean of `bumped - flat` (red, in 1/255) over the plane points of `[x0, x1] × [y0, y1]`.
fn mean_diff(bumped: &[u8], flat: &[u8], [x0, x1, y0, y1]: [f32; 4]) -> f32 {
    let (mut sum, mut n) = (0.0, 0);
    for j in 0..=20 {
        for i in 0..=20 {
            let (x, y) = (
                x0 + (x1 - x0) * i as f32 / 20.0,
                y0 + (y1 - y0) * j as f32 / 20.0,
            );
            let (px, py) = pixel(x, y);
            let k = (py * VIEW_SIDE as usize + px) * 4;
            sum += bumped[k] as f32 - flat[k] as f32;
            n += 1;
        }
    }
    sum / n as f32
}

/// Checks that `bumped` differs from `flat` over the dome's half `[y0, y1]` of the plane's width
/// as `want` says (+1: brighter, -1: darker, 0: within 1/255) and returns the mean difference.
fn compare(bumped: &[u8], flat: &[u8], [y0, y1]: [f32; 2], want: i32) -> f32 {
    let d = mean_diff(bumped, flat, [0.4, 0.6, y0, y1]);
    match want {
        1 => assert!(d > 8.0, "y in [{y0}, {y1}]: {d:.1}/255, not brighter"),
        -1 => assert!(d < -15.0, "y in [{y0}, {y1}]: {d:.1}/255, not darker"),
        _ => assert!(
            d.abs() <= 1.0,
            "y in [{y0}, {y1}]: {d:.1}/255, not the same"
        ),
    }
    d
}

/// Asserts `a` and `b` agree within 1/255 away from the decal (plane points outside
/// [0.2, 0.8]²: the decal's [0.25, 0.75]² and a margin for filtering; a rectangle on screen), on
/// the plane and the background, and returns how many pixels it compared.
fn same_outside(a: &[u8], b: &[u8]) -> usize {
    let ((x0, y1), (x1, y0)) = (pixel(0.2, 0.2), pixel(0.8, 0.8));
    let mut checked = 0;
    for py in 0..VIEW_SIDE as usize {
        for px in 0..VIEW_SIDE as usize {
            if (x0..=x1).contains(&px) && (y0..=y1).contains(&py) {
                continue;
            }
            let k = (py * VIEW_SIDE as usize + px) * 4;
            for c in 0..3 {
                let d = (a[k + c] as i32 - b[k + c] as i32).abs();
                assert!(d <= 1, "pixel ({px}, {py}) channel {c}: {d}/255 apart");
            }
            checked += 1;
        }
    }
    assert!(checked > 100_000, "{checked} pixels away from the decal");
    checked
}

/// The key light comes from above (+y) and to the right: the dome's upper half faces it more
/// than the plane does, its lower half less; away from the decal the previews with and without
/// the normal map agree.
#[test]
fn normal_decal_shows_in_the_preview() {
    let engine = common::engine();
    let (mesh, flat) = bake(&engine, &common::scratch("preview-flat"), false);
    let (_, bumped) = bake(&engine, &common::scratch("preview-bumped"), true);
    let flat_px = front(&render_preview(&engine, &mesh, &flat).unwrap());
    let bumped_px = front(&render_preview(&engine, &mesh, &bumped).unwrap());
    let upper = compare(&bumped_px, &flat_px, [0.6, 0.7], 1);
    let lower = compare(&bumped_px, &flat_px, [0.3, 0.4], -1);
    eprintln!(
        "over the dome against the flat preview: upper half {upper:+.1}/255, lower {lower:+.1}/255"
    );
    same_outside(&bumped_px, &flat_px);

    // Several sets: the plane's lower half (triangles of rows y < ½) a set with the normal map,
    // the upper half one without: only the lower half's dome shows.
    let half = N * N;
    let (tex, channels, none) = (
        PreviewTexture::of(&bumped),
        PreviewChannels::of(&bumped),
        PreviewChannels::default(),
    );
    let (lo, hi) = (0..half, half..2 * half);
    let sets = [
        (&tex, &channels, std::slice::from_ref(&lo)),
        (&tex, &none, std::slice::from_ref(&hi)),
    ];
    let split = front(&render_sets_material_preview(&engine, &mesh, &sets).unwrap());
    compare(&split, &flat_px, [0.6, 0.7], 0);
    compare(&split, &flat_px, [0.3, 0.4], -1);
    same_outside(&split, &flat_px);
}
