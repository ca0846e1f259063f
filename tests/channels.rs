// SPDX-License-Identifier: MIT OR Apache-2.0
//! PBR channels: normal decals turned into the mesh's tangent frame (against the analytic
//! normal of a bump on a plane, turned by `angle`, on mirrored UVs), reoriented normal mapping,
//! roughness and metallic in the metallic-roughness texture's G and B, and the colour texture
//! unchanged by the channels a layer adds.

mod common;

use decalbake::bake::channels::{combine_normals, ChannelKind};
use decalbake::io::channels::NormalBlend;
use decalbake::{Baked, Engine, Job};
use glam::{Vec2, Vec3};
use serde_json::json;
use std::path::Path;

/// Grid cells of the plane a side.
const N: u32 = 16;
/// Texture side.
const SIZE: u32 = 128;
/// The bump's slope: the normal at image point (s, t) is normalize(A (s - ½), A (½ - t), 1).
const A: f32 = 1.2;

/// The bump's normal in the decal's frame at image point (s, t) (t down the image).
fn bump(s: f32, t: f32) -> Vec3 {
    Vec3::new(A * (s - 0.5), A * (0.5 - t), 1.0).normalize()
}

/// Writes the images (white colour, the bump's normal map) and bakes one normal decal of
/// `size` at the plane's centre, turned by `angle`, with the extra layer fields `extra`.
fn bake(dir: &Path, mirrored: bool, angle: f32, extra: serde_json::Value) -> (Baked, Job) {
    common::write_plane(&dir.join("plane.glb"), N, mirrored);
    common::write_raw_png(&dir.join("white.png"), 8, |_, _| [1.0; 4]);
    common::write_raw_png(&dir.join("bump.png"), 256, |s, t| {
        let n = bump(s, t) * 0.5 + 0.5;
        [n.x, n.y, n.z, 1.0]
    });
    let mut layer = json!({
        "image": "white.png", "normal": "bump.png", "at": [0.5, 0.5, 0.0], "size": [0.5, 0.5],
        "angle": angle, "up": [0.0, 1.0, 0.0]
    });
    for (k, v) in extra.as_object().unwrap() {
        layer[k] = v.clone();
    }
    let job = json!({
        "mesh": "plane.glb",
        "texture": {"width": SIZE, "height": SIZE, "base": [0.5, 0.5, 0.5, 1.0], "padding": 2},
        "output": {"texture": "baked.png", "bit_depth": 16},
        "layers": [layer]
    });
    std::fs::write(dir.join("job.json"), job.to_string()).unwrap();
    let job = Job::load(&dir.join("job.json"), None).unwrap();
    let engine: Engine = common::engine();
    let (mesh, job) = engine.load_mesh_for(&job).unwrap();
    (engine.bake(&mesh, &job).unwrap(), job)
}

/// Writes `disc.png` (a colour ramp with a round alpha, 64²) and `bump.png` (the bump's normal
/// map, 96²) into `dir`.
fn write_disc_and_bump(dir: &Path) {
    common::write_raw_png(&dir.join("disc.png"), 64, |s, t| {
        let r = ((s - 0.5).powi(2) + (t - 0.5).powi(2)).sqrt();
        [s, 0.4, t, (1.0 - 2.0 * r).clamp(0.0, 1.0)]
    });
    common::write_raw_png(&dir.join("bump.png"), 96, |s, t| {
        let n = bump(s, t) * 0.5 + 0.5;
        [n.x, n.y, n.z, 1.0]
    });
}

/// Channel `kind`'s texel (x, y) as stored, in [0, 1].
fn texel(b: &Baked, kind: ChannelKind, x: u32, y: u32) -> [f32; 4] {
    let c = b
        .channels
        .iter()
        .find(|c| c.kind == kind)
        .expect("the channel");
    let i = ((y * b.width + x) * 4) as usize;
    std::array::from_fn(|k| c.texels[i + k] as f32 / 65535.0)
}

/// The world normal at every texel well inside the decal (image point in [0.1, 0.9]²),
/// decoded from the baked tangent-space normal with the plane's frame (tangent ±x by the UVs,
/// bitangent +y, normal +z), with the expected world normal there: the bump's, turned by
/// `angle` about +z.
fn world_normals(b: &Baked, mirrored: bool, angle: f32) -> Vec<(Vec3, Vec3)> {
    let (sn, cs) = angle.to_radians().sin_cos();
    let tangent = if mirrored { Vec3::NEG_X } else { Vec3::X };
    let mut out = Vec::new();
    for y in 0..SIZE {
        for x in 0..SIZE {
            let (u, v) = (
                (x as f32 + 0.5) / SIZE as f32,
                (y as f32 + 0.5) / SIZE as f32,
            );
            let px = if mirrored { 1.0 - u } else { u };
            let p = Vec2::new(px - 0.5, (1.0 - v) - 0.5);
            // The decal's frame: image x along (cos, sin), image up along (-sin, cos).
            let local = Vec2::new(p.x * cs + p.y * sn, -p.x * sn + p.y * cs) / 0.5;
            let (s, t) = (local.x + 0.5, 0.5 - local.y);
            if !(0.1..=0.9).contains(&s) || !(0.1..=0.9).contains(&t) {
                continue;
            }
            let d = bump(s, t);
            let want = Vec3::new(d.x * cs - d.y * sn, d.x * sn + d.y * cs, d.z);
            let e = texel(b, ChannelKind::Normal, x, y);
            let ts = Vec3::new(e[0], e[1], e[2]) * 2.0 - 1.0;
            let got = (ts.x * tangent + ts.y * Vec3::Y + ts.z * Vec3::Z).normalize();
            out.push((got, want));
        }
    }
    assert!(out.len() > 1500, "{} texels inside the decal", out.len());
    out
}

fn max_angle_deg(pairs: &[(Vec3, Vec3)]) -> f32 {
    pairs
        .iter()
        .map(|(a, b)| a.dot(*b).clamp(-1.0, 1.0).acos().to_degrees())
        .fold(0.0, f32::max)
}

#[test]
fn normal_decal_reproduces_a_bump_on_a_plane() {
    let dir = common::scratch("channels-bump");
    let (b, _) = bake(&dir, false, 0.0, json!({}));
    let err = max_angle_deg(&world_normals(&b, false, 0.0));
    assert!(err < 1.0, "worst texel {err}° from the bump's normal");
}

#[test]
fn a_turned_decal_and_mirrored_uvs_give_the_same_world_normals() {
    let dir = common::scratch("channels-turned");
    let (b, _) = bake(&dir, false, 90.0, json!({}));
    let err = max_angle_deg(&world_normals(&b, false, 90.0));
    assert!(err < 1.0, "turned 90°: worst texel {err}°");
    let (b, _) = bake(&dir, false, 30.0, json!({}));
    let err = max_angle_deg(&world_normals(&b, false, 30.0));
    assert!(err < 1.0, "turned 30°: worst texel {err}°");
    let (b, _) = bake(&dir, true, 30.0, json!({}));
    let err = max_angle_deg(&world_normals(&b, true, 30.0));
    assert!(err < 1.0, "mirrored UVs, turned 30°: worst texel {err}°");
}

#[test]
fn dx_normal_maps_flip_green() {
    let dir = common::scratch("channels-dx");
    // The same map read as DirectX's: its slopes up the image turn over.
    let (b, _) = bake(&dir, false, 0.0, json!({"normal_y": "dx"}));
    let pairs: Vec<(Vec3, Vec3)> = world_normals(&b, false, 0.0)
        .into_iter()
        .map(|(got, want)| (got, Vec3::new(want.x, -want.y, want.z)))
        .collect();
    let err = max_angle_deg(&pairs);
    assert!(err < 1.0, "worst texel {err}°");
}

#[test]
fn rnm_over_a_flat_base_is_the_decals_normal() {
    let flat = Vec3::Z;
    for d in [
        Vec3::new(0.3, -0.2, 0.9).normalize(),
        Vec3::new(-0.7, 0.1, 0.3).normalize(),
        Vec3::Z,
    ] {
        let r = combine_normals(NormalBlend::Rnm, flat, d);
        assert!((r - d).length() < 1e-6, "{r} != {d}");
    }
    // Over a tilted base RNM turns the detail with the base: a flat detail gives the base.
    let base = Vec3::new(0.4, 0.1, 0.9).normalize();
    let r = combine_normals(NormalBlend::Rnm, base, Vec3::Z);
    assert!((r - base).length() < 1e-6, "{r} != {base}");
    // UDN keeps the base's z: not the same as RNM on a tilted base.
    let d = Vec3::new(0.3, 0.0, 0.95).normalize();
    let udn = combine_normals(NormalBlend::Udn, base, d);
    let rnm = combine_normals(NormalBlend::Rnm, base, d);
    assert!((udn - rnm).length() > 1e-3);
}

#[test]
fn roughness_and_metallic_land_in_g_and_b_and_leave_the_colour_alone() {
    let dir = common::scratch("channels-data");
    let extra = json!({"roughness": 0.25, "metallic": 0.75, "metallic_opacity": 0.5});
    let (b, _) = bake(&dir, false, 0.0, extra);
    let orm = |x, y| texel(&b, ChannelKind::Orm, x, y);
    // Inside: roughness replaces, metallic mixes half way from the default factor 1.
    let c = orm(SIZE / 2, SIZE / 2);
    assert!((c[1] - 0.25).abs() < 1e-3, "roughness {c:?}");
    assert!((c[2] - 0.875).abs() < 1e-3, "metallic {c:?}");
    assert_eq!(c[0], 1.0, "occlusion untouched: {c:?}");
    // Outside the decal: the material's defaults (roughness 1, metallic 1, occlusion 1).
    for (x, y) in [(2, 2), (SIZE - 3, 5), (10, SIZE / 2)] {
        assert_eq!(orm(x, y), [1.0; 4], "texel ({x}, {y})");
    }
    // The colour is the same texture as without the channels, bit for bit.
    let plain = common::scratch("channels-data-plain");
    let (c0, _) = bake(&plain, false, 0.0, json!({}));
    assert_eq!(
        b.texels, c0.texels,
        "the channels changed the colour texture"
    );
    // The normal pass ran only for the layer with a normal; both have one here.
    assert!(b.channels.iter().any(|c| c.kind == ChannelKind::Normal));
}

/// A material decal (colour, normal, roughness, metallic, emissive) across the rich model's two
/// materials: each texture set gets every channel's texture, the model's materials take them
/// (factors white, the normal map's scale and transform gone into the bake), nothing else of the
/// document changes, and the glTF-Validator reports no errors.
#[test]
fn a_material_decal_writes_every_channel_into_each_set_it_touches() {
    use common::rich::{json_diff, read_model, validate, view, write_rich_gltf};
    let dir = common::scratch("channels-model");
    let src = write_rich_gltf(&dir);
    common::write_raw_png(&dir.join("white.png"), 8, |_, _| [1.0; 4]);
    common::write_raw_png(&dir.join("bump.png"), 64, |s, t| {
        let n = bump(s, t) * 0.5 + 0.5;
        [n.x, n.y, n.z, 1.0]
    });
    let job = json!({
        "mesh": src,
        "texture": {"width": 128, "height": 128, "base": "material", "padding": 4},
        "layers": [{"image": "white.png", "at": [1.0, 0.5, 0.0], "size": [0.5, 0.5],
                    "up": [0, 1, 0], "method": "planar", "normal": "bump.png",
                    "roughness": 0.6, "metallic": 0.9, "emissive": [1.0, 0.25, 0.0]}],
        "output": {"texture": "baked_{set}_{channel}.png", "glb": "out.glb", "report": "report.json"}
    });
    std::fs::write(dir.join("job.json"), job.to_string()).unwrap();
    let (code, _, err) = common::cli(&["bake", dir.join("job.json").to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    let input = read_model(&src);
    let output = read_model(&dir.join("out.glb"));
    let mut diff = Vec::new();
    json_diff(&input.0, &output.0, "", &mut diff);
    let allowed = [
        "/buffers/",
        "/bufferViews/",
        "/images/",
        "/textures/",
        "/materials/0/pbrMetallicRoughness/",
        "/materials/0/normalTexture",
        "/materials/0/emissive",
        "/materials/1/pbrMetallicRoughness/",
        "/materials/1/normalTexture",
        "/materials/1/emissive",
    ];
    let odd: Vec<&String> = diff
        .iter()
        .filter(|p| !allowed.iter().any(|a| p.starts_with(a)))
        .collect();
    assert!(odd.is_empty(), "the bake changed {odd:?}");
    let image_of = |info: &serde_json::Value| {
        let t = info["index"].as_u64().unwrap() as usize;
        let i = output.0["textures"][t]["source"].as_u64().unwrap() as usize;
        let v = output.0["images"][i]["bufferView"].as_u64().unwrap() as usize;
        view(&output.0, &output.1, v).to_vec()
    };
    for (m, set) in [(0, "painted"), (1, "glossy")] {
        let mat = &output.0["materials"][m];
        let pbr = &mat["pbrMetallicRoughness"];
        for (info, channel) in [
            (&pbr["metallicRoughnessTexture"], "orm"),
            (&mat["normalTexture"], "normal"),
            (&mat["emissiveTexture"], "emissive"),
        ] {
            let file = std::fs::read(dir.join(format!("baked_{set}_{channel}.png"))).unwrap();
            assert_eq!(image_of(info), file, "materials[{m}] {channel}");
            assert!(info.get("extensions").is_none() && info.get("scale").is_none());
        }
        assert_eq!(pbr["roughnessFactor"], json!(1.0));
        assert_eq!(pbr["metallicFactor"], json!(1.0));
        assert_eq!(mat["emissiveFactor"], json!([1.0, 1.0, 1.0]));
    }
    // The glossy set's ORM outside the decal holds its factors (roughness 0.2, metallic 1),
    // inside the decal's (0.6, 0.9); its emissive outside, the factor (1, 0.5, 0) in sRGB,
    // inside the decal's (1, 0.25, 0). Texel 70 of row 64 is x = 1.1, y = 0.5.
    let orm = image::open(dir.join("baked_glossy_orm.png"))
        .unwrap()
        .to_rgba8();
    assert_eq!(orm.get_pixel(120, 8).0, [255, 51, 255, 255]);
    let inside = orm.get_pixel(70, 64).0;
    assert_eq!(&inside[..3], &[255, 153, 230]);
    let emissive = image::open(dir.join("baked_glossy_emissive.png"))
        .unwrap()
        .to_rgba8();
    assert_eq!(emissive.get_pixel(120, 8).0, [255, 188, 0, 255]);
    assert_eq!(emissive.get_pixel(70, 64).0, [255, 137, 0, 255]);
    validate(&dir.join("out.glb"));
}

/// An unlit material shows no channel: it keeps its material and the report says so; a `normal`
/// image that is not a normal map (a colour photo's worth of short vectors) is named.
#[test]
fn unlit_materials_and_images_that_are_not_normal_maps_are_named() {
    let dir = common::scratch("channels-warnings");
    let src = common::rich::write_rich_gltf(&dir);
    let mut doc: serde_json::Value = serde_json::from_slice(&std::fs::read(&src).unwrap()).unwrap();
    doc["materials"][1]["extensions"]["KHR_materials_unlit"] = json!({});
    doc["extensionsUsed"]
        .as_array_mut()
        .unwrap()
        .push(json!("KHR_materials_unlit"));
    std::fs::write(&src, serde_json::to_vec(&doc).unwrap()).unwrap();
    common::write_raw_png(&dir.join("white.png"), 8, |_, _| [1.0; 4]);
    // Mid-grey: every decoded vector is (0, 0, 0).
    common::write_raw_png(&dir.join("grey.png"), 16, |_, _| [0.5, 0.5, 0.5, 1.0]);
    let job = json!({
        "mesh": src,
        "texture": {"width": 64, "height": 64, "base": "material"},
        "layers": [{"image": "white.png", "at": [1.0, 0.5, 0.0], "size": [0.5, 0.5],
                    "up": [0, 1, 0], "method": "planar", "normal": "grey.png"}],
        "output": {"texture": "baked_{set}_{channel}.png", "glb": "out.glb", "report": "report.json"}
    });
    std::fs::write(dir.join("job.json"), job.to_string()).unwrap();
    let (code, _, err) = common::cli(&["bake", dir.join("job.json").to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("report.json")).unwrap()).unwrap();
    let warnings = report["warnings"].to_string();
    assert!(
        warnings.contains("is unlit (KHR_materials_unlit)"),
        "{warnings}"
    );
    assert!(
        warnings.contains("layer 0")
            && warnings.contains("grey.png does not look like a tangent-space normal map"),
        "{warnings}"
    );
    let (out, _) = common::rich::read_model(&dir.join("out.glb"));
    assert!(out["materials"][1].get("normalTexture").is_none());
    assert!(out["materials"][0].get("normalTexture").is_some());
}

/// Half a cylinder of radius 1 about +y (θ in [-90°, 90°], y in [0, 1]), outward normals, UV
/// (u, v) = ((θ + 90°) / 180°, 1 - y): the tangent is the circumference's direction, the
/// bitangent +y.
fn write_half_cylinder(path: &Path) {
    let (n, m) = (96u32, 12u32);
    let mut pos = Vec::new();
    let mut uv = Vec::new();
    for j in 0..=m {
        for i in 0..=n {
            let (s, y) = (i as f32 / n as f32, j as f32 / m as f32);
            let th = (s - 0.5) * std::f32::consts::PI;
            pos.push([th.sin(), y, th.cos()]);
            uv.push([s, 1.0 - y]);
        }
    }
    let mut idx = Vec::new();
    for j in 0..m {
        for i in 0..n {
            let a = j * (n + 1) + i;
            let (b, c, d) = (a + 1, a + n + 1, a + n + 2);
            idx.extend([a, b, d, a, d, c]);
        }
    }
    common::write_glb(path, &pos, Some(&uv), &idx);
}

/// A surface-following (expmap) normal decal wrapped round a cylinder, turned by 40°: its
/// constant normal, tilted along the decal's x axis, lands in world space tilted along that axis
/// as the surface carries it (on the developable cylinder the unrolled decal keeps its angle to
/// the circumference), checked per texel against the analytic frame, and the CPU twin of the
/// turn into tangent space agrees with the baked texels.
#[test]
fn a_curved_decals_normal_follows_the_surface_frame() {
    use decalbake::bake::channels::to_tangent_space;
    let dir = common::scratch("channels-cylinder");
    write_half_cylinder(&dir.join("cyl.glb"));
    common::write_raw_png(&dir.join("white.png"), 8, |_, _| [1.0; 4]);
    let tilt = Vec3::new(0.5, 0.0, 1.0).normalize();
    common::write_raw_png(&dir.join("tilt.png"), 8, |_, _| {
        let e = tilt * 0.5 + 0.5;
        [e.x, e.y, e.z, 1.0]
    });
    let (w, h, angle) = (1.6f32, 0.5f32, 40.0f32);
    let job = json!({
        "mesh": "cyl.glb",
        "texture": {"width": 256, "height": 128, "base": [0.5, 0.5, 0.5, 1.0], "padding": 2},
        "output": {"texture": "baked.png", "bit_depth": 16},
        "layers": [{"image": "white.png", "normal": "tilt.png", "at": [0.0, 0.5, 1.0],
                    "size": [w, h], "angle": angle, "up": [0.0, 1.0, 0.0], "method": "expmap"}]
    });
    std::fs::write(dir.join("job.json"), job.to_string()).unwrap();
    let job = Job::load(&dir.join("job.json"), None).unwrap();
    let engine = common::engine();
    let (mesh, job) = engine.load_mesh_for(&job).unwrap();
    let b = engine.bake(&mesh, &job).unwrap();
    let (sn, cs) = angle.to_radians().sin_cos();
    let (mut worst, mut twin_worst, mut count) = (0.0f32, 0.0f32, 0);
    for y in 0..128u32 {
        for x in 0..256u32 {
            let (u, v) = ((x as f32 + 0.5) / 256.0, (y as f32 + 0.5) / 128.0);
            let th = (u - 0.5) * std::f32::consts::PI;
            // The unrolled decal's own coordinates of this texel (arc length, height).
            let (arc, up) = (th, (1.0 - v) - 0.5);
            let (lx, ly) = (arc * cs + up * sn, -arc * sn + up * cs);
            if lx.abs() > 0.4 * w || ly.abs() > 0.35 * h {
                continue;
            }
            let n = Vec3::new(th.sin(), 0.0, th.cos());
            let t = Vec3::new(th.cos(), 0.0, -th.sin());
            // The decal's axes on the surface: x turned by the angle from the circumference.
            let ex = cs * t + sn * Vec3::Y;
            let ey = -sn * t + cs * Vec3::Y;
            let want = (tilt.x * ex + tilt.y * ey + tilt.z * n).normalize();
            let e = texel(&b, ChannelKind::Normal, x, y);
            let ts = Vec3::new(e[0], e[1], e[2]) * 2.0 - 1.0;
            let got = (ts.x * t + ts.y * Vec3::Y + ts.z * n).normalize();
            worst = worst.max(got.dot(want).clamp(-1.0, 1.0).acos().to_degrees());
            // The twin, from the image coordinates' and the position's change along u and v.
            let twin = to_tangent_space(
                tilt,
                (t * std::f32::consts::PI, -Vec3::Y),
                (
                    Vec2::new(std::f32::consts::PI * cs / w, std::f32::consts::PI * sn / h),
                    Vec2::new(-sn / w, cs / h),
                ),
                n,
                glam::Vec4::new(t.x, t.y, t.z, 1.0),
            );
            twin_worst = twin_worst.max(
                twin.dot(ts.normalize())
                    .clamp(-1.0, 1.0)
                    .acos()
                    .to_degrees(),
            );
            count += 1;
        }
    }
    assert!(count > 2000, "{count} texels checked");
    assert!(
        worst < 1.5,
        "worst texel {worst}° from the surface frame's normal"
    );
    assert!(
        twin_worst < 1.5,
        "worst texel {twin_worst}° from the CPU twin"
    );
}

/// Strokes and ribbons carry channels as decals do: a stroke's roughness along its path, a
/// ribbon's metallic and emissive along its curve, the rest of each texture untouched.
#[test]
fn strokes_and_ribbons_paint_channels() {
    let dir = common::scratch("channels-kinds");
    common::write_plane(&dir.join("plane.glb"), N, false);
    common::write_raw_png(&dir.join("white.png"), 8, |_, _| [1.0; 4]);
    let ribbon_path: Vec<[f32; 3]> = (0..=20)
        .map(|k| [0.2 + 0.6 * k as f32 / 20.0, 0.7, 0.0])
        .collect();
    let job = json!({
        "mesh": "plane.glb",
        "texture": {"width": SIZE, "height": SIZE, "base": [0.5, 0.5, 0.5, 1.0], "padding": 2},
        "output": {"texture": "baked.png", "bit_depth": 16},
        "layers": [
            {"kind": "stroke", "image": "white.png", "path": [[0.2, 0.3, 0.0], [0.8, 0.3, 0.0]],
             "size": [0.1, 0.1], "spacing": 0.1, "method": "expmap", "roughness": 0.25},
            {"kind": "ribbon", "image": "white.png", "path": ribbon_path, "width": 0.1,
             "metallic": 0.0, "emissive": [0.0, 1.0, 0.0]}
        ]
    });
    std::fs::write(dir.join("job.json"), job.to_string()).unwrap();
    let job = Job::load(&dir.join("job.json"), None).unwrap();
    let engine = common::engine();
    let (mesh, job) = engine.load_mesh_for(&job).unwrap();
    let b = engine.bake(&mesh, &job).unwrap();
    let at = |x: f32, y: f32| ((x * SIZE as f32) as u32, ((1.0 - y) * SIZE as f32) as u32);
    let (sx, sy) = at(0.5, 0.3);
    let stroke = texel(&b, ChannelKind::Orm, sx, sy);
    assert!(
        (stroke[1] - 0.25).abs() < 2e-3,
        "roughness on the stroke: {stroke:?}"
    );
    assert_eq!(
        stroke[2], 1.0,
        "metallic untouched on the stroke: {stroke:?}"
    );
    let (rx, ry) = at(0.5, 0.7);
    let ribbon = texel(&b, ChannelKind::Orm, rx, ry);
    assert!(ribbon[2] < 2e-3, "metallic on the ribbon: {ribbon:?}");
    assert_eq!(
        ribbon[1], 1.0,
        "roughness untouched on the ribbon: {ribbon:?}"
    );
    let glow = texel(&b, ChannelKind::Emissive, rx, ry);
    assert!(
        glow[1] > 0.99 && glow[0] == 0.0,
        "emissive on the ribbon: {glow:?}"
    );
    let (ox, oy) = at(0.5, 0.05);
    assert_eq!(texel(&b, ChannelKind::Orm, ox, oy), [1.0; 4]);
    assert_eq!(texel(&b, ChannelKind::Emissive, ox, oy)[..3], [0.0; 3]);
    // Layers that paint no normal leave no normal texture.
    assert!(b.channels.iter().all(|c| c.kind != ChannelKind::Normal));
}

/// The channel groups drawn and composed beside the colour in one pass give the separate passes'
/// bytes: every texture of a job whose layers paint different channel sets (one none, one only a
/// "dx" normal by UDN, one a masked material with a metallic image of another size than its
/// colour, a ribbon replacing its data), 16 bits a channel, on mirrored UVs; a job of two
/// groups with a gap between their attachments (orm and emissive); and a job whose groups are all
/// numbers at their layers' opacities (derived from the colour's samples, no channel
/// attachment). The separate passes are taken
/// when asked for and where the device has too few attachments.
#[test]
fn fused_channel_passes_give_the_separate_passes_bytes() {
    let dir = common::scratch("channels-fused");
    common::write_plane(&dir.join("plane.glb"), N, true);
    write_disc_and_bump(&dir);
    common::write_raw_png(&dir.join("ramp.png"), 40, |s, _| [s, s, s, 1.0]);
    common::write_raw_png(&dir.join("mask.png"), 32, |s, t| [s * t, 0.0, 0.0, 1.0]);
    let ribbon: Vec<[f32; 3]> = (0..=16)
        .map(|k| {
            [
                0.15 + 0.7 * k as f32 / 16.0,
                0.3 + 0.1 * (k as f32 * 0.5).sin(),
                0.0,
            ]
        })
        .collect();
    let full = json!([
        {"image": "disc.png", "at": [0.45, 0.5, 0.0], "size": [0.5, 0.5], "angle": 20,
         "mask": "mask.png", "opacity": 0.8, "normal": "bump.png", "normal_opacity": 0.6,
         "roughness": 0.3, "metallic": "ramp.png", "emissive": [1.0, 0.5, 0.0]},
        {"image": "disc.png", "at": [0.55, 0.45, 0.0], "size": [0.4, 0.4], "method": "planar",
         "blend": "multiply"},
        {"image": "disc.png", "at": [0.6, 0.6, 0.0], "size": [0.3, 0.3], "angle": -30,
         "normal": "bump.png", "normal_y": "dx", "normal_blend": "udn"},
        {"kind": "ribbon", "image": "disc.png", "path": ribbon, "width": 0.12,
         "roughness": 0.9, "occlusion": 0.5, "data_blend": "replace", "emissive": "ramp.png"}
    ]);
    let gap = json!([
        {"image": "disc.png", "at": [0.5, 0.5, 0.0], "size": [0.6, 0.6], "roughness": 0.2,
         "emissive": "ramp.png", "emissive_opacity": 0.7},
        {"image": "disc.png", "at": [0.4, 0.4, 0.0], "size": [0.3, 0.3], "metallic": 0.0}
    ]);
    let fused = common::engine();
    let mut separate = common::engine();
    separate.separate_channel_passes = true;
    let few = common::engine_with_limits(|l| l.max_color_attachments = 4);
    // Every group from numbers at its layer's opacity: the fused raster draws the colour alone
    // and its compose derives the groups from the colour's samples.
    let numbers = json!([
        {"image": "disc.png", "at": [0.5, 0.5, 0.0], "size": [0.6, 0.6], "opacity": 0.7,
         "roughness": 0.2, "metallic": 1.0, "emissive": [0.0, 1.0, 0.0]},
        {"image": "disc.png", "at": [0.4, 0.4, 0.0], "size": [0.3, 0.3], "angle": 40,
         "mask": "mask.png", "occlusion": 0.25, "blend": "multiply"}
    ]);
    for (name, layers) in [("full", full), ("gap", gap), ("numbers", numbers)] {
        let job = json!({
            "mesh": "plane.glb",
            "texture": {"width": SIZE, "height": SIZE, "base": [0.5, 0.5, 0.5, 1.0], "padding": 2},
            "output": {"texture": "baked.png", "bit_depth": 16},
            "layers": layers
        });
        let path = dir.join(format!("{name}.json"));
        std::fs::write(&path, job.to_string()).unwrap();
        let job = Job::load(&path, None).unwrap();
        let bake = |engine: &Engine| {
            let (mesh, job) = engine.load_mesh_for(&job).unwrap();
            engine.bake(&mesh, &job).unwrap()
        };
        let (a, b, c) = (bake(&fused), bake(&separate), bake(&few));
        assert_eq!(a.report.paths.channels, "fused", "{name}");
        assert_eq!(b.report.paths.channels, "separate", "{name}");
        assert_eq!(c.report.paths.channels, "separate", "{name}: 4 attachments");
        assert!(
            a.channels.len() >= 2,
            "{name}: {} channel textures",
            a.channels.len()
        );
        for other in [&b, &c] {
            assert_eq!(a.texels, other.texels, "{name}: the colour differs");
            assert_eq!(a.channels.len(), other.channels.len());
            for (x, y) in a.channels.iter().zip(&other.channels) {
                assert_eq!(x.kind, y.kind);
                let differ = x
                    .texels
                    .iter()
                    .zip(&y.texels)
                    .filter(|(p, q)| p != q)
                    .count();
                assert_eq!(
                    differ,
                    0,
                    "{name}: {} differs in {differ} values",
                    x.kind.name()
                );
            }
        }
        // The bake painted each group: some texel of each channel texture left its base.
        for ch in &a.channels {
            let first = &ch.texels[..4];
            assert!(
                ch.texels.chunks_exact(4).any(|t| t != first),
                "{name}: {} is flat",
                ch.kind.name()
            );
        }
    }
}

/// `Engine::bake_textures`: the colour and every channel group a job paints as GPU textures, each
/// holding the bytes of the 8-bit PNG `Engine::bake` writes for it (read back here as a host
/// would), in the formats the glTF material reads them in: emissive and colour sRGB, the
/// occlusion-roughness-metallic and normal textures linear; whole and by tiles.
#[test]
fn bake_textures_gives_every_channel_on_the_gpu() {
    let dir = common::scratch("channels-textures");
    common::write_plane(&dir.join("plane.glb"), N, false);
    write_disc_and_bump(&dir);
    let job = json!({
        "mesh": "plane.glb",
        "texture": {"width": 100, "height": 72, "base": [0.5, 0.5, 0.5, 1.0], "padding": 2},
        "output": {"texture": "baked.png"},
        "layers": [{"image": "disc.png", "at": [0.45, 0.5, 0.0], "size": [0.6, 0.6],
                    "normal": "bump.png", "roughness": 0.2, "metallic": 0.9,
                    "emissive": [1.0, 0.5, 0.0]}]
    });
    std::fs::write(dir.join("job.json"), job.to_string()).unwrap();
    let job = Job::load(&dir.join("job.json"), None).unwrap();
    let engine = common::engine();
    let (mesh, job) = engine.load_mesh_for(&job).unwrap();
    let baked = engine.bake(&mesh, &job).unwrap();
    // Whole, and by tiles (assembled on the host and uploaded).
    for tile in [None, Some(64)] {
        let mut job = job.clone();
        job.tile = tile;
        let (textures, report) = engine.bake_textures(&mesh, &job).unwrap();
        assert_eq!(report.tiles.is_some(), tile.is_some());
        assert_eq!(
            report.layers[0].texels_covered,
            baked.report.layers[0].texels_covered
        );
        let kinds: Vec<ChannelKind> = textures.channels.iter().map(|(k, _)| *k).collect();
        let expected: Vec<ChannelKind> = baked.channels.iter().map(|c| c.kind).collect();
        assert_eq!(kinds, expected);
        assert_eq!(
            kinds,
            [ChannelKind::Orm, ChannelKind::Normal, ChannelKind::Emissive]
        );
        let read = |texture: &wgpu::Texture| common::read_rgba8_texture(&engine, texture);
        // Values that differ from the PNG's 8-bit texels.
        let differ = |bytes: &[u8], t: &[u16]| {
            assert_eq!(bytes.len(), t.len());
            bytes
                .iter()
                .zip(t)
                .filter(|(b, v)| **b as u16 != **v)
                .count()
        };
        assert_eq!(textures.color.format(), wgpu::TextureFormat::Rgba8UnormSrgb);
        assert_eq!(differ(&read(&textures.color), &baked.texels), 0, "colour");
        for ((kind, texture), channel) in textures.channels.iter().zip(&baked.channels) {
            let format = match kind {
                ChannelKind::Emissive => wgpu::TextureFormat::Rgba8UnormSrgb,
                _ => wgpu::TextureFormat::Rgba8Unorm,
            };
            assert_eq!(texture.format(), format, "{kind:?}");
            let bytes = read(texture);
            assert_eq!(differ(&bytes, &channel.texels), 0, "{kind:?}");
            // The decal painted something of its own into each channel.
            let base = &bytes[..4];
            assert!(
                bytes.chunks_exact(4).any(|t| t != base),
                "{kind:?} is one colour"
            );
        }
    }
}

/// On a model of one texture set, `{set}` and `{channel}` in `output.texture` name every texture
/// the same way through `decalbake bake` and `decalbake batch`: the colour `…_base_color.png`,
/// each channel `…_orm.png` and `…_normal.png` (not the colour's resolved name with the channel
/// appended, nor a file named with the placeholder), and the two commands write the same bytes;
/// `bake` lists the colour's file first, then the channels' in the bake's order.
#[test]
fn channel_file_names_fill_their_placeholders_in_bake_and_batch() {
    let mut written = Vec::new();
    for command in ["bake", "batch"] {
        let dir = common::scratch(&format!("channels-names-{command}"));
        common::write_plane(&dir.join("plane.glb"), 8, false);
        write_disc_and_bump(&dir);
        let job = json!({
            "mesh": "plane.glb",
            "texture": {"width": 64, "height": 64},
            "layers": [{"image": "disc.png", "normal": "bump.png", "roughness": 0.25,
                        "at": [0.5, 0.5, 0.0], "size": [0.5, 0.5], "up": [0.0, 1.0, 0.0]}],
            "output": {"texture": "t_{set}_{channel}.png"}
        });
        let path = dir.join("job.json");
        std::fs::write(&path, job.to_string()).unwrap();
        let (code, out, err) = common::bake_or_batch(command, &path);
        assert_eq!(code, 0, "{command}: {err}");
        let names = common::files_starting(&dir, "t_");
        assert_eq!(names.len(), 3, "{command} wrote {names:?}");
        let stem = names[0].strip_suffix("base_color.png");
        let stem = stem.unwrap_or_else(|| panic!("{command} wrote {names:?}"));
        assert!(!stem.contains('{'), "{command} wrote {names:?}");
        assert_eq!(names[1], format!("{stem}normal.png"), "{command}");
        assert_eq!(names[2], format!("{stem}orm.png"), "{command}");
        if command == "bake" {
            // Listed as written: the colour, then the channels in the bake's order.
            let listed: Vec<&str> = out
                .lines()
                .filter_map(|l| Path::new(l).file_name()?.to_str())
                .filter(|n| n.starts_with("t_"))
                .collect();
            let expected = ["base_color", "orm", "normal"].map(|c| format!("{stem}{c}.png"));
            assert_eq!(listed, expected, "{out}");
        }
        let bytes: Vec<Vec<u8>> = names
            .iter()
            .map(|n| std::fs::read(dir.join(n)).unwrap())
            .collect();
        written.push((names, bytes));
    }
    assert_eq!(
        written[0], written[1],
        "bake and batch wrote different files"
    );
}

/// A ribbon mirrored across its curve (`flip`) mirrors its normal map too: a normal tilted up
/// the image tilts to one side of the curve, and to the other when flipped, by the same angle
/// (the decal frame's handedness about the surface normal, which no unmirrored map has).
#[test]
fn a_flipped_ribbon_mirrors_its_normals() {
    let dir = common::scratch("channels-flip");
    common::write_plane(&dir.join("plane.glb"), N, false);
    common::write_raw_png(&dir.join("white.png"), 8, |_, _| [1.0; 4]);
    let tilt = Vec3::new(0.0, 0.6, 1.0).normalize();
    common::write_raw_png(&dir.join("tilt.png"), 8, |_, _| {
        let e = tilt * 0.5 + 0.5;
        [e.x, e.y, e.z, 1.0]
    });
    let engine = common::engine();
    let side = |flip: bool| {
        let job = json!({
            "mesh": "plane.glb",
            "texture": {"width": SIZE, "height": SIZE, "base": [0.5, 0.5, 0.5, 1.0], "padding": 2},
            "output": {"texture": "baked.png", "bit_depth": 16},
            "layers": [{"kind": "ribbon", "image": "white.png", "normal": "tilt.png",
                        "path": [[0.2, 0.5, 0.0], [0.5, 0.5, 0.0], [0.8, 0.5, 0.0]],
                        "width": 0.2, "flip": flip}]
        });
        std::fs::write(dir.join("job.json"), job.to_string()).unwrap();
        let job = Job::load(&dir.join("job.json"), None).unwrap();
        let (mesh, job) = engine.load_mesh_for(&job).unwrap();
        let b = engine.bake(&mesh, &job).unwrap();
        let e = texel(&b, ChannelKind::Normal, SIZE / 2, SIZE / 2);
        Vec3::new(e[0], e[1], e[2]) * 2.0 - 1.0
    };
    let (plain, flipped) = (side(false), side(true));
    for n in [plain, flipped] {
        // Tilted across the curve (the plane's y) by the image's tilt, not along it.
        assert!(n.x.abs() < 0.01, "{n}");
        assert!(
            (n.y.abs() - tilt.y).abs() < 0.01,
            "{n} against a tilt of {}",
            tilt.y
        );
    }
    assert!(
        plain.y * flipped.y < 0.0,
        "a flipped ribbon tilts its normals to the other side: {plain} and {flipped}"
    );
}
