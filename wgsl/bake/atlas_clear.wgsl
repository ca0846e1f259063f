// SPDX-License-Identifier: MIT OR Apache-2.0
// Clears the layer atlas targets inside the scissor: one triangle over the whole target, writing
// transparent colour and no coverage. A tile of a tiled bake (src/bake/compose.rs, `record_batch`)
// clears only its parts of the raster rectangles it draws, where a whole bake clears the target.
// Draw: 3 vertices, no bindings. CPU twin: none (a clear; tests/tiles.rs compares tiled bakes,
// which use it, with untiled ones, which do not).

@vertex
fn vs_main(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    // (−1, −1), (3, −1), (−1, 3): the triangle holds the whole viewport.
    let p = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    return vec4<f32>(p * 2.0 - 1.0, 0.0, 1.0);
}

// The fused variant (`// FUSED: ` lines live) clears the PBR channel groups' attachments too
// (2 to 4; a pipeline without one of them leaves its output unused).
struct Cleared {
    @location(0) color: vec4<f32>,
    @location(1) coverage: vec4<f32>,
    // FUSED: @location(2) orm: vec4<f32>,
    // FUSED: @location(3) nrm: vec4<f32>,
    // FUSED: @location(4) emissive: vec4<f32>,
}

@fragment
fn fs_main() -> Cleared {
    // Every member zero.
    var c: Cleared;
    return c;
}
