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
    let engine = engine();
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
