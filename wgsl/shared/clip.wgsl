// SPDX-License-Identifier: MIT OR Apache-2.0
// The layer raster's clip (`clip_planes` in bake/layer_raster.wgsl) and the selection's cells of
// what it draws (`drawn_box` in bake/select_triangles.wgsl) share these: a triangle keeps its part
// within the image square [0, 1]² widened by CLIP_MARGIN texels of its own map. Needs a
// `params: Params` uniform in the importing kernel.

// Texels of margin around the image square (why two: `clip_planes`).
const CLIP_MARGIN: f32 = 2.0;

// Image coordinates ((0,0) top-left, (1,1) bottom-right) of local decal coordinates c.
fn image_point(c: vec2<f32>) -> vec2<f32> {
    return vec2<f32>(c.x / params.axis_u.w + 0.5, 0.5 - c.y / params.axis_v.w);
}

// The margin in image units along x and y of the triangle with texel corners t0..t2 and image
// corners i0..i2 (its map is affine: CLIP_MARGIN texels times the L1 norm of each image
// coordinate's texel gradient); negative for a degenerate triangle, which is not clipped.
fn clip_margin(t0: vec2<f32>, t1: vec2<f32>, t2: vec2<f32>,
               i0: vec2<f32>, i1: vec2<f32>, i2: vec2<f32>) -> vec2<f32> {
    let e1 = t1 - t0;
    let e2 = t2 - t0;
    let d1 = i1 - i0;
    let d2 = i2 - i0;
    let det = e1.x * e2.y - e1.y * e2.x;
    if (abs(det) < 1e-12) { return vec2<f32>(-1.0); }
    let gx = (d1 * e2.y - d2 * e1.y) / det;
    let gy = (d2 * e1.x - d1 * e2.x) / det;
    return CLIP_MARGIN * (abs(gx) + abs(gy));
}
