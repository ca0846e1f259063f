// SPDX-License-Identifier: MIT OR Apache-2.0
//! WGSL sources, one file per kernel or pipeline under `wgsl/`, with shared code under `wgsl/shared/`.
//!
//! A line `#import name` pulls in `wgsl/shared/name.wgsl` (once per shader). [`source`] does that for
//! the runtime; the naga validation test (`tests/shader_validation.rs`) uses the same function, so
//! what is validated is exactly what runs.

/// Kernel and pipeline files: (name, text).
pub const KERNELS: &[(&str, &str)] = &[
    ("lbvh", include_str!("../../wgsl/mesh/lbvh.wgsl")),
    ("place_bvh", include_str!("../../wgsl/place/place_bvh.wgsl")),
    (
        "place_candidates",
        include_str!("../../wgsl/place/place_candidates.wgsl"),
    ),
    (
        "place_reduce",
        include_str!("../../wgsl/place/place_reduce.wgsl"),
    ),
    ("pelt_step", include_str!("../../wgsl/pelt/pelt_step.wgsl")),
    (
        "pelt_check",
        include_str!("../../wgsl/pelt/pelt_check.wgsl"),
    ),
    (
        "planar_coords",
        include_str!("../../wgsl/maps/planar_coords.wgsl"),
    ),
    (
        "select_triangles",
        include_str!("../../wgsl/bake/select_triangles.wgsl"),
    ),
    (
        "compact_lists",
        include_str!("../../wgsl/bake/compact_lists.wgsl"),
    ),
    (
        "extract_raster",
        include_str!("../../wgsl/output/extract_raster.wgsl"),
    ),
    (
        "transfer_raster",
        include_str!("../../wgsl/bake/transfer_raster.wgsl"),
    ),
    (
        "transfer_resolve",
        include_str!("../../wgsl/bake/transfer_resolve.wgsl"),
    ),
    (
        "layer_raster",
        include_str!("../../wgsl/bake/layer_raster.wgsl"),
    ),
    (
        "atlas_clear",
        include_str!("../../wgsl/bake/atlas_clear.wgsl"),
    ),
    (
        "island_raster",
        include_str!("../../wgsl/bake/island_raster.wgsl"),
    ),
    ("compose", include_str!("../../wgsl/bake/compose.wgsl")),
    (
        "vector_coverage",
        include_str!("../../wgsl/bake/vector_coverage.wgsl"),
    ),
    (
        "stamp_flatten",
        include_str!("../../wgsl/bake/stamp_flatten.wgsl"),
    ),
    (
        "stamp_filter",
        include_str!("../../wgsl/bake/stamp_filter.wgsl"),
    ),
    (
        "stroke_apply",
        include_str!("../../wgsl/bake/stroke_apply.wgsl"),
    ),
    ("base_init", include_str!("../../wgsl/bake/base_init.wgsl")),
    (
        "edt_columns",
        include_str!("../../wgsl/bake/edt_columns.wgsl"),
    ),
    ("edt_rows", include_str!("../../wgsl/bake/edt_rows.wgsl")),
    ("encode", include_str!("../../wgsl/bake/encode.wgsl")),
    ("preview", include_str!("../../wgsl/output/preview.wgsl")),
    (
        "expmap_relax",
        include_str!("../../wgsl/maps/expmap_relax.wgsl"),
    ),
    (
        "expmap_spread",
        include_str!("../../wgsl/maps/expmap_spread.wgsl"),
    ),
    (
        "ribbon_relax",
        include_str!("../../wgsl/maps/ribbon_relax.wgsl"),
    ),
    (
        "distortion",
        include_str!("../../wgsl/maps/distortion.wgsl"),
    ),
    (
        "cg_batched",
        include_str!("../../wgsl/solve/cg_batched.wgsl"),
    ),
    ("cg_packed", include_str!("../../wgsl/solve/cg_packed.wgsl")),
    ("cg_amg", include_str!("../../wgsl/solve/cg_amg.wgsl")),
    ("cg_wide", include_str!("../../wgsl/solve/cg_wide.wgsl")),
    (
        "cg_wide_plain",
        include_str!("../../wgsl/solve/cg_wide_plain.wgsl"),
    ),
    ("spmv", include_str!("../../wgsl/solve/spmv.wgsl")),
    (
        "dot_batched",
        include_str!("../../wgsl/solve/dot_batched.wgsl"),
    ),
    ("copy", include_str!("../../wgsl/solve/copy.wgsl")),
    (
        "chart_scatter",
        include_str!("../../wgsl/maps/chart_scatter.wgsl"),
    ),
    (
        "chart_gather",
        include_str!("../../wgsl/maps/chart_gather.wgsl"),
    ),
    (
        "stamp_blend",
        include_str!("../../wgsl/maps/stamp_blend.wgsl"),
    ),
    (
        "device_probe",
        include_str!("../../wgsl/gpu/device_probe.wgsl"),
    ),
];

/// Shared files that `#import` can name.
pub const SHARED: &[(&str, &str)] = &[
    ("params", include_str!("../../wgsl/shared/params.wgsl")),
    ("pelt", include_str!("../../wgsl/shared/pelt.wgsl")),
    ("cone", include_str!("../../wgsl/shared/cone.wgsl")),
    ("geometry", include_str!("../../wgsl/shared/geometry.wgsl")),
    ("bvh_node", include_str!("../../wgsl/shared/bvh_node.wgsl")),
    ("blend", include_str!("../../wgsl/shared/blend.wgsl")),
    ("acc", include_str!("../../wgsl/shared/acc.wgsl")),
    ("clip", include_str!("../../wgsl/shared/clip.wgsl")),
    ("window", include_str!("../../wgsl/shared/window.wgsl")),
    ("blocks", include_str!("../../wgsl/shared/blocks.wgsl")),
    ("expmap", include_str!("../../wgsl/shared/expmap.wgsl")),
    (
        "expmap_relax_common",
        include_str!("../../wgsl/shared/expmap_relax_common.wgsl"),
    ),
    ("linalg", include_str!("../../wgsl/shared/linalg.wgsl")),
    ("dims", include_str!("../../wgsl/shared/dims.wgsl")),
    ("cg_state", include_str!("../../wgsl/shared/cg_state.wgsl")),
    ("cg_real", include_str!("../../wgsl/shared/cg_real.wgsl")),
    ("cg_rows", include_str!("../../wgsl/shared/cg_rows.wgsl")),
    (
        "cg_row_ax",
        include_str!("../../wgsl/shared/cg_row_ax.wgsl"),
    ),
    (
        "cg_wide_common",
        include_str!("../../wgsl/shared/cg_wide_common.wgsl"),
    ),
    (
        "cg_complex",
        include_str!("../../wgsl/shared/cg_complex.wgsl"),
    ),
];

/// The complete WGSL text of kernel `name`, imports resolved. Panics on an unknown name or import:
/// both are programming errors caught by the validation test.
pub fn source(name: &str) -> String {
    let text = KERNELS
        .iter()
        .find(|(n, _)| *n == name)
        .unwrap_or_else(|| panic!("unknown shader {name}"))
        .1;
    resolve(text)
}

/// Resolves `#import` lines in `text`.
pub fn resolve(text: &str) -> String {
    let mut out = String::new();
    let mut seen: Vec<&str> = Vec::new();
    for line in text.lines() {
        if let Some(name) = line.trim().strip_prefix("#import ") {
            let name = name.trim();
            if !seen.contains(&name) {
                seen.push(name);
                let shared = SHARED
                    .iter()
                    .find(|(n, _)| *n == name)
                    .unwrap_or_else(|| panic!("unknown WGSL import {name}"))
                    .1;
                out.push_str(shared);
                out.push('\n');
            }
        } else {
            out.push_str(line);
            out.push('\n');
        }
    }
    out
}

/// Workgroup size of the linear-algebra kernels as written (`WG` in wgsl/shared/linalg.wgsl).
pub const LINALG_WG: u32 = 256;
/// Workgroup size of their narrow variant, for systems small enough that 64 invocations per system
/// stay under the loop budget (fewer idle lanes and cheaper barriers on small charts).
pub const LINALG_WG_NARROW: u32 = 64;

/// Workgroup size of `expmap_relax` (`const WG` there).
pub const EXPMAP_WG: u32 = 64;
/// Workgroup size of its variant for maps of many candidates ([`expmap_wide_source`]).
pub const EXPMAP_WG_WIDE: u32 = 256;

/// `expmap_relax` with a workgroup of [`EXPMAP_WG_WIDE`].
pub fn expmap_wide_source() -> String {
    with_workgroup(
        "expmap_relax",
        source("expmap_relax"),
        EXPMAP_WG,
        EXPMAP_WG_WIDE,
    )
}

/// Kernel `name`'s source `text` with its `const WG: u32 = {from}u;` (which `@workgroup_size`
/// and its loops' strides use) set to `to`.
pub fn with_workgroup(name: &str, text: String, from: u32, to: u32) -> String {
    let from = format!("const WG: u32 = {from}u;");
    assert!(text.contains(&from), "{name} has no `{from}`");
    text.replace(&from, &format!("const WG: u32 = {to}u;"))
}

/// The source of linear-algebra kernel `name` with a workgroup of [`LINALG_WG_NARROW`].
pub fn narrow_source(name: &str) -> String {
    with_workgroup(name, source(name), LINALG_WG, LINALG_WG_NARROW)
}

/// A conjugate gradient on 2 × 2 complex blocks: kernel `name` (`cg_packed`, `cg_amg`, `cg_wide`) with the
/// `cg_complex` import in place of `cg_real` (see the kernels' headers).
pub fn complex_source(name: &str) -> String {
    let text = KERNELS
        .iter()
        .find(|(n, _)| *n == name)
        .expect("a kernel")
        .1;
    assert!(
        text.contains("#import cg_real"),
        "{name} has no `#import cg_real`"
    );
    resolve(&text.replace("#import cg_real", "#import cg_complex"))
}

/// Raster pipeline `name` with clip distances (`layer_raster`: the device has
/// `Features::CLIP_DISTANCES`): `enable clip_distances;` first, and its `// CLIP: ` lines live.
pub fn clipped_source(name: &str) -> String {
    let text = source(name);
    assert!(
        text.contains("// CLIP: "),
        "{name} has no `// CLIP: ` lines"
    );
    format!("enable clip_distances;\n{}", text.replace("// CLIP: ", ""))
}

/// `layer_raster`'s normal variant (a layer's tangent-space normal map, turned into the mesh's
/// tangent frame per sample): its `// NORMAL: ` lines live, and its `// CLIP: ` lines too when
/// `clipped`.
pub fn normal_source(clipped: bool) -> String {
    let text = match clipped {
        true => clipped_source("layer_raster"),
        false => source("layer_raster"),
    };
    assert!(
        text.contains("// NORMAL: ") && text.contains("// NORMAL PASS: "),
        "layer_raster has no `// NORMAL: ` or `// NORMAL PASS: ` lines"
    );
    text.replace("// NORMAL: ", "")
        .replace("// NORMAL PASS: ", "")
}

/// `layer_raster`'s fused variant (the colour and every PBR channel group of a layer drawn in
/// one pass, into attachments 0 to 4): its `// NORMAL: ` lines (the mesh's frames) and
/// `// FUSED: ` lines live, and its `// CLIP: ` lines too when `clipped`.
pub fn fused_source(clipped: bool) -> String {
    let text = match clipped {
        true => clipped_source("layer_raster"),
        false => source("layer_raster"),
    };
    assert!(
        text.contains("// FUSED: "),
        "layer_raster has no `// FUSED: ` lines"
    );
    text.replace("// NORMAL: ", "").replace("// FUSED: ", "")
}

/// Kernel `name` (`compose`, `atlas_clear`) with its `// FUSED: ` lines live: the variant that
/// handles the PBR channel groups' attachments beside the colour's.
pub fn fused_kernel_source(name: &str) -> String {
    let text = source(name);
    assert!(
        text.contains("// FUSED: "),
        "{name} has no `// FUSED: ` lines"
    );
    text.replace("// FUSED: ", "")
}

/// The layer raster's flags a layer drawn by the plain variant ([`plain_layers`]) has none of:
/// a cone chart, a warp, a tiled image, a tool stamp, a separate pass's constant channel, a mask
/// (`crate::bake::params`'s `FLAG_*`).
pub const GENERAL_LAYER_FLAGS: u32 = 16 | 128 | 64 | 8 | 4096 | 2;

/// A `layer_raster` source (any of the variants above) for layers with none of
/// [`GENERAL_LAYER_FLAGS`]: its `FEATURES` without them, so it holds none of their code
/// (llvmpipe runs both sides of a branch it cannot prove uniform).
pub fn plain_layers(text: String) -> String {
    let features = format!("{}u", !GENERAL_LAYER_FLAGS);
    set_constant(text, "FEATURES: u32", "0xffffffffu", &features)
}

/// `text` with its module constant `const {decl} = {default};` set to `value` (a pipeline's
/// specialisation: the driver drops the code the constant rules out). Panics where the source
/// lacks the line, so a renamed constant cannot silently leave every variant the same.
fn set_constant(text: String, decl: &str, default: &str, value: &str) -> String {
    let line = format!("const {decl} = {default};");
    assert!(text.contains(&line), "a source without `{line}`");
    text.replace(&line, &format!("const {decl} = {value};"))
}

/// `encode` for one kind of output: `linear` (a data or normal channel, stored values) or sRGB,
/// `wide` (16 bits a channel) or 8 (`wgsl/bake/encode.wgsl`).
pub fn encode_source(linear: bool, wide: bool) -> String {
    let text = set_constant(
        source("encode"),
        "LINEAR: bool",
        "false",
        &linear.to_string(),
    );
    set_constant(text, "WIDE: bool", "false", &wide.to_string())
}

/// A fused variant (`text`: [`fused_source`], or [`fused_kernel_source`] or
/// [`msaa_kernel_source`] of `compose`) made for one pass's channel groups (bit 0
/// occlusion-roughness-metallic, 1 normal, 2 emissive): `attached`, those the raster draws
/// attachments for, and for the compose `present`, those with a canvas. The sources' defaults
/// (7: every group) compile every group's code; llvmpipe runs both sides of every branch whose
/// condition it cannot prove uniform, so a pipeline made for its groups skips the others' loads,
/// sampling and blends.
pub fn with_groups(text: String, present: u32, attached: u32) -> String {
    assert!(
        attached & !present == 0 && present <= 7,
        "groups {present:#b} {attached:#b}"
    );
    let text = set_constant(text, "ATTACHED: u32", "7u", &format!("{attached}u"));
    // The raster has no PRESENT (it draws what it has attachments for).
    match text.contains("const PRESENT: u32 = 7u;") {
        true => set_constant(text, "PRESENT: u32", "7u", &format!("{present}u")),
        false => text,
    }
}

/// The adaptive-supersampling variant of a layer raster source (`text`: `layer_raster` as any of
/// the functions above make it, or `island_raster`): its `// MSAA: ` lines live. It draws into
/// targets of four samples a pixel, once a pixel and triangle (`wgsl/bake/layer_raster.wgsl`).
pub fn msaa_source(text: String) -> String {
    assert!(
        text.contains("// MSAA: "),
        "the raster source has no `// MSAA: ` lines"
    );
    text.replace("// MSAA: ", "")
}

/// `compose` (its fused variant where `fused`) reading the adaptive raster's multisampled
/// attachments: its `// MSAA: ` lines live and every `texture_2d<f32>` multisampled (the kernel
/// binds no other texture).
pub fn msaa_kernel_source(name: &str, fused: bool) -> String {
    let text = match fused {
        true => fused_kernel_source(name),
        false => source(name),
    };
    assert!(
        text.contains("// MSAA: "),
        "{name} has no `// MSAA: ` lines"
    );
    text.replace("// MSAA: ", "")
        .replace("texture_2d<f32>", "texture_multisampled_2d<f32>")
}

/// Creates a shader module for kernel `name`.
pub fn module(device: &wgpu::Device, name: &str) -> wgpu::ShaderModule {
    module_from(device, name, source(name))
}

/// Creates a shader module from WGSL text.
pub fn module_from(device: &wgpu::Device, label: &str, text: String) -> wgpu::ShaderModule {
    device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(text.into()),
    })
}
