// SPDX-License-Identifier: MIT OR Apache-2.0
//! The exact distance transform behind padding: the GPU's nearest-island map (`edt_columns`,
//! `edt_rows`) and its CPU twin (`nearest_island_map`) both give every background texel an island
//! texel at exactly the minimal Euclidean distance, checked against brute force on a real UV layout
//! (Spot, 13 islands, UVs spilling over the texture's left edge). Distances are integers (squared
//! texel offsets), so the comparison is exact; ties may pick either texel.

mod common;
use common::*;
use decalbake::bake::cpu::{nearest_island, nearest_island_map};
use std::path::Path;

#[test]
fn gpu_and_cpu_nearest_island_maps_are_exact_on_spot() {
    let mut engine = engine();
    // The kernels, not the twin a CPU adapter takes by default (`StagePaths::islands`).
    engine.stage_paths.islands = decalbake::StagePath::Gpu;
    let spot = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/spot.glb");
    let mesh = engine.load_mesh(&spot).unwrap();
    for (w, h, samples) in [(96u32, 96u32, 4u32), (200, 136, 1), (160, 160, 9)] {
        let (mask, gpu) = engine.island_maps(&mesh, 0, [w, h], samples).unwrap();
        let island: Vec<bool> = mask.iter().map(|m| *m != 0).collect();
        let islands = island.iter().filter(|b| **b).count();
        assert!(
            islands > (w * h / 4) as usize && islands < (w * h) as usize,
            "{w}x{h}: {islands} island texels"
        );
        let brute = nearest_island(&island, w, h);
        let cpu = nearest_island_map(&island, w, h);
        let d2 = |i: usize, n: u32| {
            let (x, y) = ((n % w) as i64, (n / w) as i64);
            let (px, py) = ((i as u32 % w) as i64, (i as u32 / w) as i64);
            ((x - px).pow(2) + (y - py).pow(2)) as u64
        };
        for i in 0..(w * h) as usize {
            match &brute[i] {
                None => {
                    assert_eq!(
                        gpu[i], i as u32,
                        "{w}x{h}: island texel {i} must point at itself (GPU)"
                    );
                    assert_eq!(
                        cpu[i], i as u32,
                        "{w}x{h}: island texel {i} must point at itself (CPU)"
                    );
                }
                Some((best, _)) => {
                    assert!(
                        island[gpu[i] as usize] && island[cpu[i] as usize],
                        "{w}x{h}: texel {i} points at background"
                    );
                    assert_eq!(
                        d2(i, gpu[i]),
                        *best,
                        "{w}x{h}: GPU nearest of texel {i} is not at the minimal distance"
                    );
                    assert_eq!(
                        d2(i, cpu[i]),
                        *best,
                        "{w}x{h}: CPU nearest of texel {i} is not at the minimal distance"
                    );
                }
            }
        }
    }
}

/// A bake's islands' distance transform comes from the CPU twin on a CPU adapter and from the
/// kernels on a GPU (`StagePaths::islands`, `Auto`; always the twin on GL). The two transforms
/// pick the same texel on ties, so either path gives the same padded texture byte for byte, at
/// two sizes and with full padding; the report says which ran, the same in a later bake that
/// reuses the mesh's islands. (With the twin's row pass made to prefer the right of two equally
/// near texels, 442 of the 262,144 values differ.)
#[test]
fn a_bake_pads_from_either_distance_transform_with_the_same_bytes() {
    let (job, mut engine, mesh, auto) = spot_paths_bake("islands_paths", spot_ring("img.png", 0.2));
    let cpu_adapter = engine.ctx.device_type == Some(wgpu::DeviceType::Cpu);
    let gl = engine.ctx.backend == Some(wgpu::Backend::Gl);
    let expected = if cpu_adapter || gl { "cpu" } else { "gpu" };
    assert_eq!(auto.report.paths.islands, expected);
    assert_eq!(
        engine.bake(&mesh, &job).unwrap().report.paths.islands,
        expected
    );
    let mut sized = job.clone();
    sized.width = 200;
    sized.height = 136;
    let mut full = job.clone();
    full.padding = decalbake::io::job::Padding::Full;
    for job in [&job, &sized, &full] {
        let mut baked = Vec::new();
        for path in [decalbake::StagePath::Cpu, decalbake::StagePath::Gpu] {
            engine.stage_paths.islands = path;
            // A fresh copy of the mesh: nothing cached.
            let fresh = engine.prepare(mesh.mesh.clone()).unwrap();
            baked.push(engine.bake(&fresh, job).unwrap());
        }
        let [cpu, gpu] = [&baked[0], &baked[1]];
        assert_eq!(cpu.report.paths.islands, "cpu");
        assert_eq!(gpu.report.paths.islands, if gl { "cpu" } else { "gpu" });
        // Counted by `edt_columns` on the GPU, over the mask read back on the CPU.
        assert_eq!(cpu.report.island_texels, gpu.report.island_texels);
        assert!(cpu.report.island_texels > 0);
        let (differ, worst) = value_diffs(&cpu.texels, &gpu.texels);
        assert_eq!(
            (differ, worst),
            (0, 0),
            "{}x{} {:?}: the two paths' textures differ",
            job.width,
            job.height,
            job.padding
        );
    }
}

/// Padding and encoding on the CPU (a CPU adapter's default where the islands are there too,
/// `StagePaths::padding`) give the `encode` kernel's bytes: the colour and the emissive
/// (sRGB), the occlusion-roughness-metallic and the normal (linear), at 256², at 200 × 137
/// (the CPU's last band of rows shorter than the others) and with full padding; the report
/// names the path. Both quantise by one table of exact thresholds (`finish::Quantiser`): with
/// the kernel's former `pow` and `pack4x8unorm` instead, 2 of the 262,144 colour values differ
/// by one (checked).
#[test]
fn padding_on_the_cpu_gives_the_kernels_bytes() {
    let dir = scratch("padding_paths");
    let layers: Vec<serde_json::Value> = spot_ring("img.png", 0.2)
        .into_iter()
        .map(|mut l| {
            l["roughness"] = serde_json::json!(0.35);
            l["metallic"] = serde_json::json!(0.8);
            l["emissive"] = serde_json::json!([1.0, 0.5, 0.2]);
            l["normal"] = serde_json::json!("bump.png");
            l
        })
        .collect();
    let output = serde_json::json!({ "texture": "out.png" });
    let text = spot_job_json(&dir, 4, serde_json::Value::from(layers), output);
    write_raw_png(&dir.join("bump.png"), 32, |s, t| {
        let (x, y) = (s - 0.5, t - 0.5);
        let n = glam::Vec3::new(x, y, 0.6).normalize() * 0.5 + 0.5;
        [n.x, n.y, n.z, 1.0]
    });
    let job = decalbake::Job::parse(&text.to_string(), &dir.join("job.json"), &dir, &dir).unwrap();
    let mut engine = engine();
    // The twin's islands: the CPU path pads from them.
    engine.stage_paths.islands = decalbake::StagePath::Cpu;
    let mesh = engine.load_mesh(&spot_asset()).unwrap();
    let mut sized = job.clone();
    sized.width = 200;
    sized.height = 137;
    let mut full = job.clone();
    full.padding = decalbake::io::job::Padding::Full;
    for job in [&job, &sized, &full] {
        let baked: Vec<_> = [decalbake::StagePath::Cpu, decalbake::StagePath::Gpu]
            .into_iter()
            .map(|path| {
                engine.stage_paths.padding = path;
                engine.bake(&mesh, job).unwrap()
            })
            .collect();
        let [cpu, gpu] = [&baked[0], &baked[1]];
        assert_eq!(
            (cpu.report.paths.padding, gpu.report.paths.padding),
            ("cpu", "gpu")
        );
        assert_eq!(cpu.channels.len(), 3, "orm, normal, emissive");
        let textures = std::iter::once((&cpu.texels, &gpu.texels)).chain(
            cpu.channels
                .iter()
                .zip(&gpu.channels)
                .map(|(a, b)| (&a.texels, &b.texels)),
        );
        for (k, (a, b)) in textures.enumerate() {
            assert_eq!(
                value_diffs(a, b),
                (0, 0),
                "{}x{} {:?}: texture {k} differs between the padding paths",
                job.width,
                job.height,
                job.padding
            );
        }
    }
}
