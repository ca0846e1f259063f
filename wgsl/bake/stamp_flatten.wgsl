// SPDX-License-Identifier: MIT OR Apache-2.0
// Inverse rendering (Maillot section 10): the canvas as it is under a stamp, drawn into the stamp's
// flat space. Each of the stamp's selected triangles is drawn at its stamp coordinates into the
// stamp's R x R cell of the flat atlas (viewport = atlas, scissor = cell), carrying its global UV;
// the fragment fetches the canvas there (bilinear, UVs repeat). Texels no triangle covers stay
// transparent (alpha 0 = unknown). Non-indexed draw of 3 * (triangles in the stamp's list).
// CPU twin: `flatten_cpu` in src/bake/cpu.rs.
#import params
#import window

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> lists: array<u32>;
@group(0) @binding(2) var<storage, read> split_tris: array<u32>;
@group(0) @binding(3) var<storage, read> uvs: array<vec2<f32>>;
@group(0) @binding(4) var<storage, read> welded_of: array<u32>;
@group(0) @binding(5) var<storage, read> coords: array<vec4<f32>>;
@group(0) @binding(10) var<storage, read> acc_rg: array<vec2<f32>>;
@group(0) @binding(11) var<storage, read> acc_ba: array<vec2<f32>>;

// Texels per side of a stamp's cell; keep in sync with `FLAT_RES` in src/bake/tools.rs.
const FLAT_RES: u32 = 64u;
// Cells per atlas row; keep in sync with `FLAT_COLS` in src/bake/params.rs.
const FLAT_COLS: u32 = 16u;

struct VsOut {
    @builtin(position) pos: vec4<f32>,
    @location(0) uv: vec2<f32>,
}

@vertex
fn vs_main(@builtin(vertex_index) vi: u32) -> VsOut {
    let t = lists[params.slot * params.triangle_count + vi / 3u];
    let s = split_tris[3u * t + vi % 3u];
    let c = coords[params.slot * params.vertex_count + welded_of[s]];
    let img = vec2<f32>(c.x / params.axis_u.w + 0.5, 0.5 - c.y / params.axis_v.w);
    let cell = params._pad.x;
    let origin = vec2<f32>(f32(cell % FLAT_COLS), f32(cell / FLAT_COLS));
    // Atlas size in cells: FLAT_COLS x params._pad.y rows.
    let atlas = vec2<f32>(f32(FLAT_COLS), f32(params._pad.y));
    let ndc = (origin + img) / atlas * 2.0 - 1.0;
    var o: VsOut;
    o.pos = vec4<f32>(ndc.x, -ndc.y, 0.0, 1.0);
    o.uv = uvs[s];
    return o;
}

fn canvas_at(x: i32, y: i32) -> vec4<f32> {
    let size = vec2<i32>(params.tex_size);
    let p = vec2<i32>(((x % size.x) + size.x) % size.x, ((y % size.y) + size.y) % size.y);
    // Outside the window (a tiled bake): `tools::check_windows` refuses such stamps first.
    let i = win_index(p);
    if (i == 0xffffffffu) { return vec4<f32>(0.0); }
    return vec4<f32>(acc_rg[i], acc_ba[i]);
}

@fragment
fn fs_main(in: VsOut) -> @location(0) vec4<f32> {
    let p = in.uv * vec2<f32>(params.tex_size) - 0.5;
    let p0 = floor(p);
    let f = p - p0;
    let x = i32(p0.x);
    let y = i32(p0.y);
    let c = mix(mix(canvas_at(x, y), canvas_at(x + 1, y), f.x),
                mix(canvas_at(x, y + 1), canvas_at(x + 1, y + 1), f.x), f.y);
    return vec4<f32>(c.rgb, 1.0);
}
