// SPDX-License-Identifier: MIT OR Apache-2.0
// Chooses the triangles a layer covers, for any placement method: all three vertices have valid layer
// coordinates (a planar decal: or its part under the rectangle within the depth limit,
// `planar_part_within_depth`), the triangle's coordinate box overlaps the decal rectangle, and
// (planar projection only) the triangle faces the projection. Marks them at their tested position in `marks` (id, or NONE),
// which `compact_lists` turns into the layer's list in the tested order (an atomic only counts
// them: the list's order never depends on the invocations' timing), and grows the layer's texel
// bounding box in the output texture; marks the cells of the part the layer raster draws (the
// triangle clipped to the image and margin, `drawn_box`: on bob at 4096² with 256 decals the
// raster rectangles cover 28.6M texels instead of 37.9M). A cone chart (FLAG_CONE, shared/cone.wgsl) is tested by its
// opened images. The triangles tested are the layer's candidates
// (`ranges[params.slot]`: offset and count in `cands`, every triangle with a vertex its map can
// reach, src/bake/maps.rs), or every triangle of the mesh where the offset is NO_CANDIDATES.
// Dispatch: (ceil(tested / 64), 1, 1). CPU twin: `select_triangles` in src/bake/cpu.rs (over the
// whole mesh, so the tests also check the candidates miss nothing).
#import params
#import cone
#import clip

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> tris: array<vec4<u32>>;
@group(0) @binding(3) var<storage, read> split_tris: array<u32>;
@group(0) @binding(4) var<storage, read> uvs: array<vec2<f32>>;
@group(0) @binding(5) var<storage, read> coords: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read_write> marks: array<u32>;
// Per layer (params.aux), `stats_stride` words: count, min x, min y, max x, max y (texels), texels
// composed, triangles with all three coordinates valid (reached by the layer's map; a planar
// decal's, or its part under the rectangle within the depth limit), 1 unused, then
// the cell mask: the texel blocks this layer's triangles touch, wrapped into
// the texture (UV repeat), so rasterization only visits blocks that can change.
@group(0) @binding(7) var<storage, read_write> stats: array<atomic<i32>>;
@group(0) @binding(8) var<storage, read> ranges: array<vec2<u32>>;
@group(0) @binding(9) var<storage, read> cands: array<u32>;

const NO_CANDIDATES: u32 = 0xffffffffu;
const NONE: u32 = 0xffffffffu;

// Polygon `inp` (n corners: texel xy, image zw) clipped to sgn * image[axis] + off >= 0, into
// `out`; returns its corners.
fn clip_side(inp: array<vec4<f32>, 8>, n: u32, axis: u32, sgn: f32, off: f32,
             out: ptr<function, array<vec4<f32>, 8>>) -> u32 {
    var k = 0u;
    for (var i = 0u; i < n; i++) {
        let a = inp[i];
        let b = inp[(i + 1u) % n];
        let da = sgn * a[2u + axis] + off;
        let db = sgn * b[2u + axis] + off;
        if (da >= 0.0) {
            (*out)[k] = a;
            k++;
        }
        if ((da >= 0.0) != (db >= 0.0)) {
            (*out)[k] = mix(a, b, da / (da - db));
            k++;
        }
    }
    return k;
}

// The texel box (lo xy, hi zw; lo > hi: empty) of the part of the triangle with texel corners
// t0..t2 and image corners i0..i2 that `clip_planes` in layer_raster.wgsl keeps: the image
// square widened by CLIP_MARGIN texels of the triangle's own map (shared/clip.wgsl; across the
// width only for a tiled ribbon); the whole triangle's box for a degenerate one.
fn drawn_box(t0: vec2<f32>, t1: vec2<f32>, t2: vec2<f32>, i0: vec2<f32>, i1: vec2<f32>, i2: vec2<f32>) -> vec4<f32> {
    let m = clip_margin(t0, t1, t2, i0, i1, i2);
    if (m.x < 0.0) { return vec4<f32>(min(min(t0, t1), t2), max(max(t0, t1), t2)); }
    var a = array<vec4<f32>, 8>();
    var b = array<vec4<f32>, 8>();
    a[0] = vec4<f32>(t0, i0);
    a[1] = vec4<f32>(t1, i1);
    a[2] = vec4<f32>(t2, i2);
    var n = 3u;
    if ((params.flags & FLAG_REPEAT) == 0u) {
        n = clip_side(a, n, 0u, 1.0, m.x, &b);
        n = clip_side(b, n, 0u, -1.0, 1.0 + m.x, &a);
    }
    n = clip_side(a, n, 1u, 1.0, m.y, &b);
    n = clip_side(b, n, 1u, -1.0, 1.0 + m.y, &a);
    var lo = vec2<f32>(1e30);
    var hi = vec2<f32>(-1e30);
    for (var i = 0u; i < n; i++) {
        lo = min(lo, a[i].xy);
        hi = max(hi, a[i].xy);
    }
    return vec4<f32>(lo, hi);
}

// A planar decal's triangle with corners `c0..c2` in the decal's frame (x, y, depth) whose part
// under the decal's rectangle (half sides hx, hy) lies within the depth limit (params.normal.w)
// everywhere: depth is affine over the triangle, so it is checked at that part's corners (the
// triangle clipped to the rectangle, `clip_side` on (depth, 0, x, y)). Such a triangle is drawn
// though a far corner leaves the projector's box: what the raster paints of it lies under the
// rectangle. A large triangle under a small decal on a smooth-shaded low-poly model (its normal
// leaning across the face) was dropped otherwise, and with it every texel under the decal.
// CPU twin: `planar_part_within_depth` in src/bake/cpu.rs.
fn planar_part_within_depth(c0: vec3<f32>, c1: vec3<f32>, c2: vec3<f32>, hx: f32, hy: f32) -> bool {
    var a = array<vec4<f32>, 8>();
    var b = array<vec4<f32>, 8>();
    a[0] = vec4<f32>(c0.z, 0.0, c0.xy);
    a[1] = vec4<f32>(c1.z, 0.0, c1.xy);
    a[2] = vec4<f32>(c2.z, 0.0, c2.xy);
    var n = clip_side(a, 3u, 0u, 1.0, hx, &b);
    n = clip_side(b, n, 0u, -1.0, hx, &a);
    n = clip_side(a, n, 1u, 1.0, hy, &b);
    n = clip_side(b, n, 1u, -1.0, hy, &a);
    if (n == 0u) { return false; }
    for (var i = 0u; i < n; i++) {
        if (abs(a[i].x) > params.normal.w) { return false; }
    }
    return true;
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let range = ranges[params.slot];
    var t = gid.x;
    if (range.x == NO_CANDIDATES) {
        if (t >= params.triangle_count) { return; }
    } else {
        if (t >= range.y) { return; }
        t = cands[range.x + t];
    }
    marks[gid.x] = NONE;
    let tri = tris[t];
    if ((tri.w & 1u) != 0u) { return; }
    let base = params.slot * params.vertex_count;
    let c0 = coords[base + tri.x];
    let c1 = coords[base + tri.y];
    let c2 = coords[base + tri.z];
    var hx = 0.5 * params.axis_u.w;
    var hy = 0.5 * params.axis_v.w;
    if (c0.w < 0.5 || c1.w < 0.5 || c2.w < 0.5) {
        let planar = (params.flags & FLAG_FACING) != 0u;
        if (!planar || !planar_part_within_depth(c0.xyz, c1.xyz, c2.xyz, hx, hy)) { return; }
    }
    let s = params.aux * params.stats_stride;
    atomicAdd(&stats[s + 6u], 1);
    var z0 = c0.xy;
    var z1 = c1.xy;
    var z2 = c2.xy;
    var cut = false;
    if ((params.flags & FLAG_CONE) != 0u) {
        // A cone chart: the cut's triangles and those near the tip are drawn (the fragments
        // outside the decal are not painted); the others are tested by their opened images, with
        // a margin of a tenth of their box for their curved edges.
        cut = cone_cut_crosses(params.cone_a, z0, z1, z2) || cone_near_tip(params.cone_a, z0, z1, z2);
        z0 = cone_apply(params.cone_a, params.cone_b, z0);
        z1 = cone_apply(params.cone_a, params.cone_b, z1);
        z2 = cone_apply(params.cone_a, params.cone_b, z2);
        let ext = max(max(z0, z1), z2) - min(min(z0, z1), z2);
        hx += 0.1 * max(ext.x, ext.y);
        hy += 0.1 * max(ext.x, ext.y);
    }
    let lo = min(min(z0, z1), z2);
    let hi = max(max(z0, z1), z2);
    if (!cut && (hi.x < -hx || lo.x > hx || hi.y < -hy || lo.y > hy)) { return; }
    if ((params.flags & FLAG_FACING) != 0u) {
        let a = positions[tri.x].xyz;
        let n = cross(positions[tri.y].xyz - a, positions[tri.z].xyz - a);
        if (dot(n, params.normal.xyz) <= 0.0) { return; }
    }
    atomicAdd(&stats[s], 1);
    marks[gid.x] = t;
    let size = vec2<f32>(params.tex_size);
    let u0 = uvs[split_tris[3u * t]] * size;
    let u1 = uvs[split_tris[3u * t + 1u]] * size;
    let u2 = uvs[split_tris[3u * t + 2u]] * size;
    let tlo = vec2<i32>(floor(min(min(u0, u1), u2)));
    let thi = vec2<i32>(ceil(max(max(u0, u1), u2)));
    atomicMin(&stats[s + 1u], tlo.x);
    atomicMin(&stats[s + 2u], tlo.y);
    atomicMax(&stats[s + 3u], thi.x);
    atomicMax(&stats[s + 4u], thi.y);
    // The cells: those of the part of the triangle the raster draws (clipped like `clip_planes`
    // in layer_raster.wgsl, grown by a texel for rounding), or of the whole triangle.
    var clo = tlo;
    var chi = thi;
    if ((params.flags & (FLAG_CONE | FLAG_NO_CLIP)) == 0u) {
        let b = drawn_box(u0, u1, u2, image_point(c0.xy), image_point(c1.xy), image_point(c2.xy));
        if (b.x > b.z) { return; }
        clo = max(clo, vec2<i32>(floor(b.xy)) - vec2<i32>(1));
        chi = min(chi, vec2<i32>(ceil(b.zw)) + vec2<i32>(1));
    }
    let g = vec2<i32>(params.grid);
    let first = vec2<i32>(floor(vec2<f32>(clo) / f32(params.cell)));
    let last = vec2<i32>(floor(vec2<f32>(chi - vec2<i32>(1)) / f32(params.cell)));
    // A triangle spanning more than the whole grid touches every block; clamp the loop to one wrap.
    let cy1 = min(last.y, first.y + g.y - 1);
    let cx1 = min(last.x, first.x + g.x - 1);
    for (var cy = first.y; cy <= cy1; cy++) {
        for (var cx = first.x; cx <= cx1; cx++) {
            let wx = ((cx % g.x) + g.x) % g.x;
            let wy = ((cy % g.y) + g.y) % g.y;
            let bit = u32(wy * g.x + wx);
            atomicOr(&stats[s + 8u + bit / 32u], i32(1u << (bit % 32u)));
        }
    }
}
