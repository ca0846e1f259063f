// SPDX-License-Identifier: MIT OR Apache-2.0
//! Every WGSL file parses and validates with naga, imports resolved exactly as at run time. All
//! failures are collected and reported at once. Needs no GPU.

#[test]
fn every_wgsl_file_validates() {
    // Kernels live in one folder per module group (wgsl/bake, wgsl/maps, ...); wgsl/shared holds
    // the imports.
    let root = std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/wgsl"));
    let mut on_disk: Vec<String> = Vec::new();
    for dir in std::fs::read_dir(root).unwrap().filter_map(|e| e.ok()) {
        if !dir.path().is_dir() || dir.file_name() == "shared" {
            continue;
        }
        on_disk.extend(
            std::fs::read_dir(dir.path())
                .unwrap()
                .filter_map(|e| e.ok())
                .filter(|e| e.path().extension().is_some_and(|x| x == "wgsl"))
                .map(|e| e.path().file_stem().unwrap().to_string_lossy().into_owned()),
        );
    }
    let mut failures = Vec::new();
    for name in &on_disk {
        if !decalbake::gpu::shaders::KERNELS
            .iter()
            .any(|(n, _)| n == name)
        {
            failures.push(format!(
                "wgsl/{name}.wgsl is not registered in shaders::KERNELS"
            ));
        }
    }
    let mut sources: Vec<(String, String)> = decalbake::gpu::shaders::KERNELS
        .iter()
        .map(|(n, _)| (n.to_string(), decalbake::gpu::shaders::source(n)))
        .collect();
    // The narrow linear-algebra variant the engine builds by changing the workgroup size.
    sources.push((
        "cg_batched (narrow)".into(),
        decalbake::gpu::shaders::narrow_source("cg_batched"),
    ));
    // The conjugate gradients on complex blocks.
    for name in ["cg_packed", "cg_amg", "cg_wide", "cg_wide_plain"] {
        sources.push((
            format!("{name} (complex)"),
            decalbake::gpu::shaders::complex_source(name),
        ));
    }
    // The layer raster with clip distances (devices with `Features::CLIP_DISTANCES`).
    sources.push((
        "layer_raster (clipped)".into(),
        decalbake::gpu::shaders::clipped_source("layer_raster"),
    ));
    // The normal variant, and the fused variants that draw and compose the PBR channel groups
    // beside the colour.
    sources.push((
        "layer_raster (normal)".into(),
        decalbake::gpu::shaders::normal_source(true),
    ));
    sources.push((
        "layer_raster (fused)".into(),
        decalbake::gpu::shaders::fused_source(true),
    ));
    for name in ["compose", "atlas_clear"] {
        sources.push((
            format!("{name} (fused)"),
            decalbake::gpu::shaders::fused_kernel_source(name),
        ));
    }
    // The adaptive raster (four samples a pixel, once a texel and triangle) and what reads it.
    for (name, text) in [
        ("plain", decalbake::gpu::shaders::source("layer_raster")),
        (
            "clipped",
            decalbake::gpu::shaders::clipped_source("layer_raster"),
        ),
        ("normal", decalbake::gpu::shaders::normal_source(true)),
        ("fused", decalbake::gpu::shaders::fused_source(true)),
        ("islands", decalbake::gpu::shaders::source("island_raster")),
    ] {
        sources.push((
            format!("layer_raster ({name}, adaptive)"),
            decalbake::gpu::shaders::msaa_source(text),
        ));
    }
    for (name, fused) in [("compose", false), ("compose", true)] {
        sources.push((
            format!("{name} (adaptive, fused {fused})"),
            decalbake::gpu::shaders::msaa_kernel_source(name, fused),
        ));
    }
    // The fused variants as each pass makes them, for its channel groups (present, attached).
    use decalbake::gpu::shaders::{
        fused_kernel_source, fused_source, msaa_kernel_source, with_groups,
    };
    for present in 1..8u32 {
        for attached in (0..8).filter(|a| a & !present == 0) {
            for (kind, text) in [
                ("", fused_kernel_source("compose")),
                (", adaptive", msaa_kernel_source("compose", true)),
            ] {
                sources.push((
                    format!("compose (fused {present:#05b} {attached:#05b}{kind})"),
                    with_groups(text, present, attached),
                ));
            }
        }
        let raster = with_groups(fused_source(true), present, present);
        sources.push((
            format!("layer_raster (fused {present:#05b})"),
            raster.clone(),
        ));
        let plain = decalbake::gpu::shaders::plain_layers(raster);
        sources.push((format!("layer_raster (fused {present:#05b}, plain)"), plain));
    }
    // The rasters for layers without a cone, warp, tiled image, stamp, constant or mask.
    for (name, text) in [
        ("plain", decalbake::gpu::shaders::source("layer_raster")),
        ("normal", decalbake::gpu::shaders::normal_source(true)),
    ] {
        let plain = decalbake::gpu::shaders::plain_layers(text);
        sources.push((format!("layer_raster ({name}, plain)"), plain.clone()));
        let msaa = decalbake::gpu::shaders::msaa_source(plain);
        sources.push((format!("layer_raster ({name}, plain, adaptive)"), msaa));
    }
    for (linear, wide) in [(false, true), (true, false), (true, true)] {
        sources.push((
            format!("encode (linear {linear}, 16-bit {wide})"),
            decalbake::gpu::shaders::encode_source(linear, wide),
        ));
    }
    for (name, src) in &sources {
        let src = src.clone();
        let module = match naga::front::wgsl::parse_str(&src) {
            Ok(m) => m,
            Err(e) => {
                failures.push(e.emit_to_string_with_path(&src, &format!("wgsl/{name}.wgsl")));
                continue;
            }
        };
        let mut validator = naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::default() | naga::valid::Capabilities::CLIP_DISTANCES,
        );
        if let Err(e) = validator.validate(&module) {
            failures.push(e.emit_to_string_with_path(&src, &format!("wgsl/{name}.wgsl")));
        }
    }
    assert!(
        failures.is_empty(),
        "{} shader problem(s):\n{}",
        failures.len(),
        failures.join("\n")
    );
    assert!(
        on_disk.len() >= 12,
        "expected the kernel files under wgsl/, found {}",
        on_disk.len()
    );
}

/// The block mask's size and row length in `wgsl/shared/blocks.wgsl` are the planner's
/// (`bake::plan::BLOCK`, `BLOCKS_ROW`: the buffer the engine makes and clears row by row).
#[test]
fn the_block_masks_constants_are_the_planners() {
    use decalbake::bake::plan::{BLOCK, BLOCKS_ROW, TILE_TARGET};
    let text = decalbake::gpu::shaders::SHARED
        .iter()
        .find(|(n, _)| *n == "blocks")
        .expect("shared/blocks.wgsl is registered")
        .1;
    for line in [
        format!("const BLOCK: u32 = {BLOCK}u;"),
        format!("const BLOCKS_ROW: u32 = {BLOCKS_ROW}u;"),
    ] {
        assert!(text.contains(&line), "blocks.wgsl lacks `{line}`");
    }
    assert_eq!(BLOCKS_ROW * BLOCK, TILE_TARGET);
}
