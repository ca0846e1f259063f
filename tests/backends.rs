// SPDX-License-Identifier: MIT OR Apache-2.0
//! wgpu's GL backend (Mesa llvmpipe through EGL, the fallback where no Vulkan driver is
//! installed): a bake with decals by several methods and PBR channels runs there and gives the
//! Vulkan bake's texture within an 8-bit level a value (a job asking for adaptive sampling bakes
//! full there, as its report says)
//! (docs/backends.md says why not byte for byte: `Rgba16Float` layer targets). `.ci/run` installs
//! Mesa's EGL and GL drivers and the test requires them under CI; elsewhere, without a GL
//! adapter, it says so and checks nothing.

mod common;
use common::*;
use decalbake::{Engine, Job};
use std::path::Path;

/// Spot with material decals by three methods, at `sampling`.
fn job(dir: &Path, sampling: &str) -> Job {
    let spot = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/spot.glb");
    std::fs::write(dir.join("a.png"), test_image(32, 32, 5, true).encode_png(8)).unwrap();
    let ray = |o: [f32; 3]| serde_json::json!({ "ray": { "origin": o, "dir": [-o[0], 0.0, 0.2 - o[2]] } });
    let text = serde_json::json!({ "mesh": spot,
        "texture": { "width": 256, "height": 256, "padding": 4, "sampling": sampling },
        "layers": [
            { "image": "a.png", "at": ray([2.0, 0.1, 0.2]), "size": [0.3, 0.3], "method": "expmap",
              "roughness": 0.2, "metallic": 1.0 },
            { "image": "a.png", "at": ray([-2.0, 0.2, 0.2]), "size": [0.35, 0.3], "method": "planar",
              "blend": "multiply", "roughness": 0.8 },
            { "image": "a.png", "at": ray([0.0, 0.0, 2.2]), "size": [0.3, 0.3], "method": "lscm",
              "angle": 30 }
        ],
        "output": { "texture": "out.png" } });
    Job::parse(&text.to_string(), &dir.join("job.json"), dir, dir).unwrap()
}

#[test]
fn the_gl_backend_bakes_the_vulkan_texture_within_a_level() {
    let gl = match Engine::new(Some("gl")) {
        Ok(e) => e,
        Err(e) => {
            // `.ci/run` installs Mesa's EGL, so under CI the backend must be there.
            assert!(
                std::env::var_os("CI").is_none(),
                "no GL adapter under CI: {e}"
            );
            println!("no GL adapter here ({e}); nothing checked");
            return;
        }
    };
    let vk = engine();
    let dir = scratch("backends_gl");
    for sampling in ["full", "adaptive"] {
        let j = job(&dir, sampling);
        let on = |engine: &Engine| {
            let mesh = engine.load_mesh(&j.mesh).unwrap();
            engine
                .bake(&mesh, &j)
                .unwrap_or_else(|e| panic!("{sampling} on {}: {e}", engine.ctx.adapter))
        };
        let b = on(&gl);
        // GL draws four samples a texel once a sample (its shaders lack the sample mask input the
        // adaptive raster needs), as its report says: compare with Vulkan's bake of that.
        assert_eq!(b.report.paths.sampling, "full", "{sampling} on GL");
        let a = on(&vk);
        assert_eq!(a.report.paths.sampling, sampling);
        let a = match sampling {
            "full" => a,
            _ => {
                let mut full = j.clone();
                full.adaptive = false;
                let mesh = vk.load_mesh(&full.mesh).unwrap();
                vk.bake(&mesh, &full).unwrap()
            }
        };
        let planes = std::iter::once(("colour", &a.texels, &b.texels)).chain(
            a.channels
                .iter()
                .zip(&b.channels)
                .map(|(x, y)| (x.kind.name(), &x.texels, &y.texels)),
        );
        assert_eq!(a.channels.len(), 1, "the ORM texture");
        assert_eq!(b.channels.len(), a.channels.len());
        for (name, x, y) in planes {
            let worst = x.iter().zip(y).map(|(p, q)| p.abs_diff(*q)).max().unwrap();
            let differ = x.iter().zip(y).filter(|(p, q)| p != q).count();
            println!("{sampling} {name}: {differ} values differ, by at most {worst}");
            assert!(worst <= 1, "{sampling} {name}: {worst} levels apart");
        }
        for (l, m) in a.report.layers.iter().zip(&b.report.layers) {
            assert!(
                m.texels_covered > 0,
                "{sampling}: layer {} covers nothing on GL",
                l.index
            );
        }
    }
}
