// SPDX-License-Identifier: MIT OR Apache-2.0
// Per-layer / per-raster-job parameters. Keep in sync with `src/bake/params.rs` (`Params`).
struct Params {
    // Decal centre on the surface (xyz).
    center: vec4<f32>,
    // xyz: surface direction of the image's +x axis; w: decal width in model units.
    axis_u: vec4<f32>,
    // xyz: surface direction of the image's +y (up) axis; w: decal height in model units.
    axis_v: vec4<f32>,
    // xyz: projection normal (out of the surface); w: planar depth limit in model units.
    normal: vec4<f32>,
    // Output texture size in texels.
    tex_size: vec2<u32>,
    // Raster job: texel rectangle origin in texture space.
    rect_origin: vec2<i32>,
    // Raster job: rectangle size in texels.
    rect_size: vec2<u32>,
    // Raster job: integer UV tile being drawn (uv - tile lands in [0,1]).
    tile: vec2<i32>,
    // Supersampling factor per axis.
    ss: u32,
    // Blend mode id (see shared/blend.wgsl).
    blend: u32,
    // Slot of the layer in the current chunk (index into coords / lists).
    slot: u32,
    // Bit 0: require front-facing triangles (planar projection). Bit 1: a mask image is bound.
    // Bit 3: a tool stamp (flat image in `flats`, cell in _pad.x). (Bit 2 is encode's 16-bit flag.)
    flags: u32,
    opacity: f32,
    vertex_count: u32,
    triangle_count: u32,
    // Layer kernels: the layer's index in the job (row of the stats buffer).
    // edt_rows_fill: padding radius in texels (0xffffffff = fill everything).
    aux: u32,
    // Words per row of the stats buffer: 8 counters, then the layer's cell mask (one bit per
    // `cell` x `cell` texel block of the texture, `grid` blocks, row-major).
    stats_stride: u32,
    cell: u32,
    grid: vec2<u32>,
    // Raster job: where its samples sit in the batch's atlas target.
    atlas_origin: vec2<u32>,
    // Tool stamps: x = cell of the flat atlas; stamp_flatten: y = the atlas's rows of cells.
    _pad: vec2<u32>,
    // FLAG_CONE: the cone transform of the layer's chart (shared/cone.wgsl): tip (xy), k (z);
    // alpha (xy), beta (zw). FLAG_REPEAT: cone_a.w = copies of the image along x.
    cone_a: vec4<f32>,
    cone_b: vec4<f32>,
    // The canvas window (shared/window.wgsl): x, y, w, h in texels; w = 0: the whole texture.
    win: vec4<u32>,
    // FLAG_WARP: x = start of the layer's thin-plate spline in `warps` (layer_raster.wgsl).
    warp: vec4<u32>,
    // A data channel's blend (BLEND_DATA_*, shared/blend.wgsl): each output channel's weight on the
    // source's alpha (its `<channel>_opacity`; 0 leaves it unchanged).
    chan: vec4<f32>,
    // Channel passes (layer_raster, and compose's fused variant): x = this entry's index in the
    // `draws` buffer of channel draws; y = a separate pass's channel group (FLAG_CONSTANT).
    draw: vec4<u32>,
}

const FLAG_FACING: u32 = 1u;
const FLAG_MASK: u32 = 2u;
// Blur / smear stamps: colour from the stamp's flat image (`flats`), shape from the image's alpha.
const FLAG_TOOL: u32 = 8u;
// The layer's chart is opened at a tip: coordinates go through `cone_apply` (shared/cone.wgsl).
const FLAG_CONE: u32 = 16u;
// A tiled ribbon: the image repeats `cone_a.w` times along x (layer_raster.wgsl).
const FLAG_REPEAT: u32 = 64u;
// The image is warped by a thin-plate spline (params.warp, layer_raster.wgsl).
const FLAG_WARP: u32 = 128u;
// layer_raster.wgsl: triangles drawn whole (the reference of the clipped raster).
const FLAG_NO_CLIP: u32 = 256u;
// encode.wgsl: the canvas written as stored (a data or normal channel), not sRGB-encoded.
const FLAG_LINEAR: u32 = 512u;
// layer_raster.wgsl's normal variant: the normal map's green points down the image ("dx").
const FLAG_NORMAL_DX: u32 = 1024u;
// layer_raster: a channel group drawn from a constant (draws[draw.x].value[draw.y]) times the
// colour image's alpha.
const FLAG_CONSTANT: u32 = 4096u;
