// SPDX-License-Identifier: MIT OR Apache-2.0
// Draws a layer's triangles at their global UV (shifted by the UV tile and the raster rectangle) into a
// supersampled target, carrying the layer's local coordinates; the fragment stage samples the decal
// image (premultiplied, mipmapped: implicit derivatives pick the level) and the optional mask.
// A cone chart (FLAG_CONE) carries its uncut chart coordinates in `img` and opens them per fragment
// (shared/cone.wgsl), so its cut runs exactly through the triangles it crosses. The mip level comes
// from the implicit derivatives of the opened coordinates: exact off the cut; the 2 x 2 quads that
// straddle the cut see the jump across it and sample a coarser level there, which blends the two
// sides on the seam's own line of samples (measured: an analytic derivative, and the varying it
// needs, made every layer's raster about 15 % slower on lavapipe).
// Attachment 0: premultiplied colour; attachment 1: island coverage (1 where a triangle is drawn
// inside the layer's image, COVERED_OUTSIDE where only outside it: every attachment holds exact
// zeros there, and compose.wgsl reads nothing more of such a sample; the target keeps the largest
// value written, so a sample drawn inside and outside reads 1).
// A tiled ribbon (FLAG_REPEAT) repeats the image cone_a.w times along x.
// A warped layer (FLAG_WARP) samples its image at T(img), T the layer's thin-plate spline
// (`warps`, from params.warp.x; twin `Tps::eval` in src/maps/warp.rs), each copy of a tiled ribbon
// alike; it paints only where T(img) lies in the image.
// The normal variant (`// NORMAL: ` and `// NORMAL PASS: ` lines live; `gpu::shaders::normal_source`) draws a layer's
// tangent-space normal map: each sample's normal, given in the decal's own frame (image x right,
// image y up, z out of the surface), is turned into the mesh's tangent frame at that point
// (`to_tangent_space`; CPU twin `bake::channels::to_tangent_space`).
// The fused variant (`// NORMAL: ` and `// FUSED: ` lines live; `gpu::shaders::fused_source`) draws
// the colour and every PBR channel group of a layer in one pass: attachments 2, 3 and 4 take its
// occlusion-roughness-metallic, normal and emissive images, sampled at the same point, masked by
// the same mask and weighted by each channel's opacity (`draws[params.draw.x]`), each the value
// the separate channel pass would write (src/bake/compose.rs; `tests/channels.rs` compares them).
// The adaptive variant (`// MSAA: ` lines live; `gpu::shaders::msaa_source`) draws into targets
// of one pixel a texel with four samples each (the standard 4-sample pattern, SAMPLE_POS), and
// runs once a pixel and triangle instead of once a sample: the layer is evaluated at the texel's
// centre (the triangle's map extrapolated where the centre lies outside it; clamped to the
// image), at the mip level of the 2 x 2 grid (derivatives / ss), and written to the samples the triangle covers
// weighted by the share of them inside the image (`image_share`), so that the compose's average
// over covered samples keeps the image's edge anti-aliased. Where the four samples would read
// the same value (inside a triangle and the image, a magnified image) the texel is the grid's;
// elsewhere it differs by what one sample at the centre differs from four around it
// (docs/performance.md, "Adaptive supersampling"). CPU twin: `LayerRaster::sample_adaptive` in
// src/bake/cpu.rs.
// Non-indexed draw of 3 * (triangles in the layer's list) vertices.
// CPU twin: `LayerRaster` in src/bake/cpu.rs.
#import params
#import cone
#import clip
#import blocks

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> lists: array<u32>;
@group(0) @binding(2) var<storage, read> split_tris: array<u32>;
@group(0) @binding(3) var<storage, read> uvs: array<vec2<f32>>;
@group(0) @binding(4) var<storage, read> welded_of: array<u32>;
@group(0) @binding(5) var<storage, read> coords: array<vec4<f32>>;
@group(0) @binding(6) var image: texture_2d<f32>;
@group(0) @binding(7) var mask: texture_2d<f32>;
@group(0) @binding(8) var samp: sampler;
// Blur and smear stamps (FLAG_TOOL): the filtered flat images, FLAT_RES^2 texels per cell (cell
// params._pad.x), straight colour, alpha 0 = unknown; the stamp's shape is then the image's alpha.
// Keep FLAT_RES in sync with src/bake/params.rs.
@group(0) @binding(9) var<storage, read> flats: array<vec4<f32>>;
const FLAT_RES: u32 = 64u;
// The thin-plate splines of warped layers: vec4(a0, a1), vec4(a2, centres, 0), then vec4(c, w)
// per centre (src/maps/warp.rs, `Tps::pack`).
@group(0) @binding(10) var<storage, read> warps: array<vec4<f32>>;
// The normal variant: split positions and normals (xyz, 3 floats a vertex, model space) and the
// tangent frames of the baked UV set (xyz, bitangent sign w) per split vertex.
// NORMAL: @group(0) @binding(11) var<storage, read> split_pos: array<f32>;
// NORMAL: @group(0) @binding(12) var<storage, read> split_nrm: array<f32>;
// NORMAL: @group(0) @binding(13) var<storage, read> tangents: array<vec4<f32>>;
// Each raster entry's channel draws (bits.x: which of orm, normal, emissive the layer paints;
// bits.y: its normal map is "dx"; bits.z: the groups drawn from a constant, `value`; bits.w: of
// those, the ones at the colour's opacity, which the compose derives from the colour; keep in sync
// with `ChannelDraw` in src/bake/channels.rs): the fused variant's, and a separate channel pass's
// constants (FLAG_CONSTANT: draws[params.draw.x].value[params.draw.y]).
struct ChannelDraw {
    opacity: vec4<f32>,
    blend: vec4<u32>,
    bits: vec4<u32>,
    chan: array<vec4<f32>, 3>,
    value: array<vec4<f32>, 3>,
}
@group(0) @binding(17) var<storage, read> draws: array<ChannelDraw>;
// The compose's block mask (shared/blocks.wgsl), seen by the fragment stage only.
@group(0) @binding(18) var<storage, read_write> blocks: array<u32>;
// The fused variant's channel images.
// FUSED: @group(0) @binding(14) var orm_image: texture_2d<f32>;
// FUSED: @group(0) @binding(15) var normal_image: texture_2d<f32>;
// FUSED: @group(0) @binding(16) var emissive_image: texture_2d<f32>;
// The layer flags this pipeline honours: every one, or (`gpu::shaders::plain_layers`, the variant
// for the many layers with none of them) all but a cone, a warp, a tiled image, a tool stamp, a
// constant channel and a mask. llvmpipe runs both sides of a branch it cannot prove uniform, so
// a flag tested at run time costs every fragment its code (a cone's atan2 and pow, a warp's
// spline, a stamp's four reads), taken or not.
const FEATURES: u32 = 0xffffffffu;

fn layer_has(flag: u32) -> bool {
    return (params.flags & FEATURES & flag) != 0u;
}

// The groups this pipeline draws attachments for (bit 0 orm, 1 normal, 2 emissive).
// FUSED: const ATTACHED: u32 = 7u;

// T(p) = a0 + a1 p.x + a2 p.y + sum_k w_k phi(|p - c_k|), phi(r) = r^2 ln r; in the twin's order of
// operations, so an identity spline returns p bit for bit.
fn warp_apply(p: vec2<f32>) -> vec2<f32> {
    let o = params.warp.x;
    let h0 = warps[o];
    let h1 = warps[o + 1u];
    var q = h0.xy + h0.zw * p.x + h1.xy * p.y;
    let n = u32(h1.z);
    for (var k = 0u; k < n; k++) {
        let c = warps[o + 2u + k];
        let d = p - c.xy;
        let r2 = dot(d, d);
        // Branch-free (0 at a centre): llvmpipe's implicit derivatives after a divergent branch
        // in the loop were wrong (the image showed holes along the centres' rows and columns).
        q += c.zw * (0.5 * r2 * log(max(r2, 1e-30)));
    }
    return q;
}

// The spline's Jacobian at p (columns d/dx, d/dy): grad phi = (ln r^2 + 1) (p - c).
fn warp_jacobian(p: vec2<f32>) -> mat2x2<f32> {
    let o = params.warp.x;
    let h0 = warps[o];
    let h1 = warps[o + 1u];
    var j = mat2x2<f32>(h0.zw, h1.xy);
    let n = u32(h1.z);
    for (var k = 0u; k < n; k++) {
        let c = warps[o + 2u + k];
        let d = p - c.xy;
        let r2 = dot(d, d);
        let g = (log(max(r2, 1e-30)) + 1.0) * d;
        j += mat2x2<f32>(c.zw * g.x, c.zw * g.y);
    }
    return j;
}

// The adaptive variant: where the four samples of a pixel sit (WebGPU's and Vulkan's standard
// pattern; keep in sync with `SAMPLE_POS` in src/bake/cpu.rs).
const SAMPLE_POS = array<vec2<f32>, 4>(vec2<f32>(0.375, 0.125), vec2<f32>(0.875, 0.375),
                                       vec2<f32>(0.125, 0.625), vec2<f32>(0.625, 0.875));

// The image point of the layer's coordinates `u` as the fragment stage maps them (a cone chart's
// opened), before tiling and warping.
fn image_of(u: vec2<f32>) -> vec2<f32> {
    if (layer_has(FLAG_CONE)) {
        let z = cone_apply(params.cone_a, params.cone_b, u);
        return vec2<f32>(z.x / params.axis_u.w + 0.5, 0.5 - z.y / params.axis_v.w);
    }
    return u;
}

// The adaptive variant: of the samples `covered` (the fragment's sample mask), the share whose
// image point lies in the image (and, for a warped layer, whose warped point does). `u`, `ux`,
// `uy`: the layer's coordinates at the pixel centre and their derivatives (affine on a triangle,
// so exact at each sample).
fn image_share(covered: u32, u: vec2<f32>, ux: vec2<f32>, uy: vec2<f32>) -> f32 {
    var k = 0.0;
    var m = 0.0;
    for (var i = 0u; i < 4u; i++) {
        if (((covered >> i) & 1u) == 0u) { continue; }
        k += 1.0;
        let o = SAMPLE_POS[i] - 0.5;
        let p = image_of(u + ux * o.x + uy * o.y);
        var inside = in_image(p);
        if (layer_has(FLAG_WARP)) {
            var w = p;
            if (layer_has(FLAG_REPEAT)) {
                w.x = fract(p.x * params.cone_a.w);
            }
            inside = inside && in_image(warp_apply(w));
        }
        m += select(0.0, 1.0, inside);
    }
    return select(0.0, m / k, k > 0.0);
}

// Coverage of a sample drawn only outside the layer's image (an R8Unorm target: 153/255).
const COVERED_OUTSIDE: f32 = 0.6;

fn in_image(p: vec2<f32>) -> bool {
    return all(p >= vec2<f32>(0.0)) && all(p <= vec2<f32>(1.0));
}

fn flat_texel(x: i32, y: i32) -> vec4<f32> {
    let r = i32(FLAT_RES);
    let p = vec2<u32>(vec2<i32>(clamp(x, 0, r - 1), clamp(y, 0, r - 1)));
    return flats[(params._pad.x * FLAT_RES + p.y) * FLAT_RES + p.x];
}

// Bilinear within the stamp's cell (clamped at its edges), image coordinates in [0, 1].
fn flat_at(img: vec2<f32>) -> vec4<f32> {
    let p = clamp(img, vec2<f32>(0.0), vec2<f32>(1.0)) * f32(FLAT_RES) - 0.5;
    let p0 = floor(p);
    let f = p - p0;
    let x = i32(p0.x);
    let y = i32(p0.y);
    return mix(mix(flat_texel(x, y), flat_texel(x + 1, y), f.x),
               mix(flat_texel(x, y + 1), flat_texel(x + 1, y + 1), f.x), f.y);
}

struct VsOut {
    @builtin(position) pos: vec4<f32>,
    // Decal image coordinates: (0,0) top-left, (1,1) bottom-right; a cone chart's uncut chart
    // coordinates (model units), opened in the fragment stage.
    @location(0) img: vec2<f32>,
    // NORMAL: @location(1) wpos: vec3<f32>,
    // NORMAL: @location(2) wnrm: vec3<f32>,
    // NORMAL: @location(3) wtan: vec4<f32>,
    // CLIP: @builtin(clip_distances) clip: array<f32, 4>,
}

// The split vertex of corner `vi`.
fn split_of(vi: u32) -> u32 {
    let t = lists[params.slot * params.triangle_count + vi / 3u];
    return split_tris[3u * t + vi % 3u];
}

// Texel position (in the raster rectangle) and local coordinates (xy of the layer's slot) of
// corner `vi` of its triangle.
fn corner(vi: u32) -> array<vec2<f32>, 2> {
    let s = split_of(vi);
    let uv = uvs[s] - vec2<f32>(params.tile);
    let c = coords[params.slot * params.vertex_count + welded_of[s]];
    let texel = uv * vec2<f32>(params.tex_size) - vec2<f32>(params.rect_origin);
    return array<vec2<f32>, 2>(texel, c.xy);
}

// The clip distances of vertex `vi` at image coordinates `img`: the image square [0, 1]², widened
// by CLIP_MARGIN texels in the triangle's own map (shared/clip.wgsl; img is affine over a
// triangle, so is each distance, and the clipped triangle is exactly its part within the margin).
// A texel with a sample in the image has all its samples of the same triangle within one texel;
// the second texel of margin keeps the samples of a neighbouring triangle whose map is up to twice
// as slow. So every texel the layer paints keeps its covered samples and its average: what is
// dropped is the fringe (covered, transparent samples) beyond the margin, which composed nothing,
// about a quarter of the raster's time on bob at 4096² with 256 decals. The CPU twin draws whole
// triangles (`LayerRaster` in src/bake/cpu.rs): the reference; `tests/demo_and_api.rs` bakes the
// demo both ways (`Engine::unclipped_raster`) and bounds the difference. Not clipped: cone charts
// (their coordinates are opened per fragment), a degenerate triangle, and every unit with
// FLAG_NO_CLIP (src/bake/maps.rs: warped images, whose T(img) is not affine; meshes whose
// triangles are small at the bake's size, `Engine::clip_min_texels`, where the fringe is thin and
// the clip costs more than it saves); a tiled ribbon only across its width.
fn clip_planes(vi: u32, img: vec2<f32>) -> array<f32, 4> {
    var d = array<f32, 4>(1.0, 1.0, 1.0, 1.0);
    if (layer_has(FLAG_CONE | FLAG_NO_CLIP)) { return d; }
    let b = vi - vi % 3u;
    let c0 = corner(b);
    let c1 = corner(b + 1u);
    let c2 = corner(b + 2u);
    let m = clip_margin(c0[0], c1[0], c2[0],
                        image_point(c0[1]), image_point(c1[1]), image_point(c2[1]));
    if (m.x < 0.0) { return d; }
    if (!layer_has(FLAG_REPEAT)) {
        d[0] = img.x + m.x;
        d[1] = 1.0 + m.x - img.x;
    }
    d[2] = img.y + m.y;
    d[3] = 1.0 + m.y - img.y;
    return d;
}

@vertex
fn vs_main(@builtin(vertex_index) vi: u32) -> VsOut {
    let c = corner(vi);
    let ndc = c[0] / vec2<f32>(params.rect_size) * 2.0 - 1.0;
    var o: VsOut;
    o.pos = vec4<f32>(ndc.x, -ndc.y, 0.0, 1.0);
    o.img = image_point(c[1]);
    // CLIP: o.clip = clip_planes(vi, o.img);
    // NORMAL: let sv = split_of(vi);
    // NORMAL: o.wpos = vec3<f32>(split_pos[3u * sv], split_pos[3u * sv + 1u], split_pos[3u * sv + 2u]);
    // NORMAL: o.wnrm = vec3<f32>(split_nrm[3u * sv], split_nrm[3u * sv + 1u], split_nrm[3u * sv + 2u]);
    // NORMAL: o.wtan = tangents[sv];
    if (layer_has(FLAG_CONE)) {
        o.img = c[1];
    }
    return o;
}

// The fragment stage's inputs (the vertex stage's outputs less the clip distances, which a
// fragment stage may not read).
struct FsIn {
    @builtin(position) pos: vec4<f32>,
    @location(0) img: vec2<f32>,
    // NORMAL: @location(1) wpos: vec3<f32>,
    // NORMAL: @location(2) wnrm: vec3<f32>,
    // NORMAL: @location(3) wtan: vec4<f32>,
    // MSAA: @builtin(sample_mask) covered: u32,
}

// A decal normal `c` (premultiplied, encoded n * 0.5 + 0.5, in the decal's frame) turned into the
// mesh's tangent frame. The decal's axes on the surface come from the derivatives of position
// and image coordinates over the raster (both affine on a triangle, so this is the triangle's
// own map, and it follows a bent map, an opened cone, a warp or a tiled ribbon): d pos / d img =
// [dpx dpy] [gx gy]^-1; image x is right, image y down, so up is -d pos / d img.y. In the
// tangent plane about the interpolated normal, the decal's orthonormal frame (its x axis, and
// up on the side its y axis lies: a sheared map keeps its x axis and its handedness) and the
// mesh's (t, cross(n, t) * w, as glTF's bitangent is) differ by a rotation, c = x.t and
// s = n.(x x t) of the unit projections, flipped by each frame's handedness; the normal is
// (R nd.xy, nd.z), normalised. The same as projecting onto both frames, with three square roots
// instead of five (the fused raster's largest cost after its samples).
fn to_tangent_space(c: vec4<f32>, dx: bool, dpx: vec3<f32>, dpy: vec3<f32>, gx: vec2<f32>,
                    gy: vec2<f32>, nrm: vec3<f32>, tan: vec4<f32>) -> vec4<f32> {
    if (c.a <= 0.0) { return c; }
    var nd = c.rgb / c.a * 2.0 - 1.0;
    if (dx) { nd.y = -nd.y; }
    let det = gx.x * gy.y - gy.x * gx.y;
    let n = normalize(nrm);
    // d pos / d img.x and d pos / d img.y, times det, projected onto the tangent plane.
    let ax = dpx * gy.y - dpy * gx.y;
    let ay = dpx * gy.x - dpy * gx.x;
    let x = ax - n * dot(n, ax);
    let y = ay - n * dot(n, ay);
    let t = tan.xyz - n * dot(n, tan.xyz);
    let h = select(1.0, -1.0, dot(n, cross(x, y)) < 0.0);
    let s = select(1.0, -1.0, tan.w < 0.0);
    let cs = normalize(vec2<f32>(dot(x, t), dot(n, cross(x, t)))) * sign(det);
    let ts = normalize(vec3<f32>(nd.x * cs.x + nd.y * h * cs.y, s * (h * cs.x * nd.y - cs.y * nd.x), nd.z));
    if (any(ts != ts) || abs(det) < 1e-30) { return vec4<f32>(0.0); }
    return vec4<f32>((ts * 0.5 + 0.5) * c.a, c.a);
}

struct FsOut {
    @location(0) color: vec4<f32>,
    @location(1) coverage: vec4<f32>,
    // FUSED: @location(2) orm: vec4<f32>,
    // FUSED: @location(3) nrm: vec4<f32>,
    // FUSED: @location(4) emissive: vec4<f32>,
}

// A constant channel value `k` where the colour sample `c` (masked) is: what an image of the value
// with the colour image's alpha gives, premultiplied.
fn constant_channel(k: vec4<f32>, c: vec4<f32>) -> vec4<f32> {
    return vec4<f32>(k.rgb * c.a, c.a);
}

// The layer's mask at `img`, 1 where it has none (mask images are premultiplied like decals: red *
// alpha is the mask value). Sampled once a fragment and multiplied into every image sample
// (`c * 1.0` is `c`): llvmpipe samples a branch's texture whether or not any lane takes it.
fn mask_at(img: vec2<f32>, gx: vec2<f32>, gy: vec2<f32>) -> f32 {
    if (!layer_has(FLAG_MASK)) { return 1.0; }
    return textureSampleGrad(mask, samp, img, gx, gy).r;
}

@fragment
fn fs_main(in: FsIn) -> FsOut {
    var img = image_of(in.img);
    // MSAA: let ux = dpdx(in.img);
    // MSAA: let uy = dpdy(in.img);
    // A tiled ribbon wraps x into one copy of the image; the mip level comes from the unwrapped
    // coordinate's derivatives (the wrapped one jumps at each copy's edge). A warped image's
    // derivatives go through the spline's Jacobian: on lavapipe the implicit derivatives of T(img)
    // were wrong along every triangle edge (seen as holes; helper invocations' storage reads, we
    // believe), explicit level 0 was right.
    let repeat = layer_has(FLAG_REPEAT);
    let warped = layer_has(FLAG_WARP);
    let unwrapped = img * vec2<f32>(select(1.0, params.cone_a.w, repeat), 1.0);
    var gx = dpdx(unwrapped);
    var gy = dpdy(unwrapped);
    // One pixel a texel: the 2 x 2 grid's mip level.
    // MSAA: gx = gx / f32(params.ss);
    // MSAA: gy = gy / f32(params.ss);
    // The texel's centre (the triangle's map extrapolated where the centre lies outside it),
    // clamped into the image.
    // MSAA: img = clamp(img, vec2<f32>(0.0), vec2<f32>(0.99999994));
    // NORMAL: let dpx = dpdx(in.wpos);
    // NORMAL: let dpy = dpdy(in.wpos);
    var inside = in_image(img);
    // Where the stamp's flat image (FLAG_TOOL) is read: its cell is laid out unwarped.
    let flat_img = img;
    if (repeat) {
        img.x = fract(img.x * params.cone_a.w);
    }
    if (warped) {
        let wj = warp_jacobian(img);
        gx = wj * gx;
        gy = wj * gy;
        img = warp_apply(img);
        inside = inside && in_image(img);
    }
    var share = 1.0;
    // MSAA: share = image_share(in.covered, in.img, ux, uy);
    // MSAA: inside = share > 0.0;
    var o: FsOut;
    o.coverage = vec4<f32>(1.0);
    // A sample outside the image is covered but transparent, and samples nothing: on a decal's
    // raster rectangles most samples are (bob, 256 decals at 4096²: 37.9M rectangle texels for
    // 10.7M composed), and llvmpipe skips the sampling below for a SIMD group that all returned.
    // The explicit gradients are the implicit ones (taken above, in uniform control flow).
    if (!inside) {
        o.color = vec4<f32>(0.0);
        o.coverage = vec4<f32>(COVERED_OUTSIDE);
        return o;
    }
    let m = mask_at(img, gx, gy);
    var c = textureSampleGrad(image, samp, img, gx, gy) * m;
    if (layer_has(FLAG_CONSTANT)) {
        // A separate channel pass of a constant group: `image` is the colour's.
        c = constant_channel(draws[params.draw.x].value[params.draw.y], c);
    }
    if (layer_has(FLAG_TOOL)) {
        // What is below, filtered in the stamp's flat space, with the stamp image's alpha as shape.
        let f = flat_at(flat_img);
        let shape = select(0.0, c.a, f.a > 0.0);
        c = vec4<f32>(f.rgb * shape, shape);
    }
    // NORMAL PASS: let dx = layer_has(FLAG_NORMAL_DX);
    // NORMAL PASS: c = to_tangent_space(c, dx, dpx, dpy, gx, gy, in.wnrm, in.wtan);
    o.color = c * params.opacity * share;
    // The groups this pipeline draws attachments for (ATTACHED, set per pipeline by
    // `gpu::shaders::with_groups`) mask every group's bits, so a pipeline holds no code for the
    // others (llvmpipe runs both sides of a branch it cannot prove uniform).
    // FUSED: let bits = draws[params.draw.x].bits & vec4<u32>(ATTACHED, 0xffffffffu, ATTACHED, 0xffffffffu);
    // FUSED: let opacity = draws[params.draw.x].opacity;
    // A group at the colour's opacity drawn from a constant (bits.w) is the colour's alphas
    // times the constant: the compose derives it from the colour's samples, nothing is drawn.
    // FUSED: if ((bits.w & 1u) != 0u) {
    // FUSED: } else if ((bits.z & 1u) != 0u) {
    // FUSED:     o.orm = constant_channel(draws[params.draw.x].value[0], c) * opacity.x * share;
    // FUSED: } else if ((bits.x & 1u) != 0u) {
    // FUSED:     o.orm = textureSampleGrad(orm_image, samp, img, gx, gy) * m * opacity.x * share;
    // FUSED: }
    // FUSED: if ((bits.x & 2u) != 0u) {
    // FUSED:     let n = textureSampleGrad(normal_image, samp, img, gx, gy) * m;
    // FUSED:     o.nrm = to_tangent_space(n, bits.y != 0u, dpx, dpy, gx, gy, in.wnrm, in.wtan) * opacity.y * share;
    // FUSED: }
    // FUSED: if ((bits.w & 4u) != 0u) {
    // FUSED: } else if ((bits.z & 4u) != 0u) {
    // FUSED:     o.emissive = constant_channel(draws[params.draw.x].value[2], c) * opacity.z * share;
    // FUSED: } else if ((bits.x & 4u) != 0u) {
    // FUSED:     o.emissive = textureSampleGrad(emissive_image, samp, img, gx, gy) * m * opacity.z * share;
    // FUSED: }
    mark_block(in.pos.xy, o);
    return o;
}

// Marks the block of the texel at framebuffer position `pos` for the compose where `o` leaves
// anything it reads: an output with alpha not <= 0 (a sample whose alphas are all 0 adds nothing
// to the compose's sums, whatever it blends over; NaN is marked). The grid's texels are ss x ss
// pixels, the adaptive raster's one.
fn mark_block(pos: vec2<f32>, o: FsOut) {
    var leaves = !(o.color.a <= 0.0);
    // FUSED: leaves = leaves || !(o.orm.a <= 0.0) || !(o.nrm.a <= 0.0) || !(o.emissive.a <= 0.0);
    if (!leaves) { return; }
    var px = params.ss;
    // MSAA: px = 1u;
    blocks[block_of(vec2<u32>(pos) / px)] = 1u;
}
