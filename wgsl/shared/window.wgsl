// SPDX-License-Identifier: MIT OR Apache-2.0
// The canvas window: the texel rectangle of the texture that the bake's canvas holds (a tile of a
// texture larger than one storage binding, `src/bake/tiles.rs`), `params.win` = (x, y, w, h);
// w = 0 means the whole texture. Kernels that index the canvas by texel go through `win_index`.
// Needs a `params: Params` uniform in the importing kernel.

fn win_origin() -> vec2<u32> {
    return params.win.xy;
}

fn win_size() -> vec2<u32> {
    if (params.win.z == 0u) { return params.tex_size; }
    return params.win.zw;
}

// The canvas index of texture texel t, or 0xffffffff when t is outside the window.
fn win_index(t: vec2<i32>) -> u32 {
    let s = vec2<i32>(win_size());
    let l = t - vec2<i32>(win_origin());
    if (l.x < 0 || l.y < 0 || l.x >= s.x || l.y >= s.y) { return 0xffffffffu; }
    return u32(l.y) * u32(s.x) + u32(l.x);
}

// The window texel an invocation of a per-texel pass handles, or 0xffffffff in x when it has
// none. Over the whole window, or over a region of it (a live bake's edit, src/bake/live.rs):
// `rect_origin` its first texel, `atlas_origin` its size (0: the whole window), dispatched over
// that size.
fn region_texel(gid: vec2<u32>) -> vec2<u32> {
    var g = gid;
    var end = win_size();
    if (params.atlas_origin.x > 0u) {
        g = gid + vec2<u32>(params.rect_origin);
        end = min(end, vec2<u32>(params.rect_origin) + params.atlas_origin);
    }
    if (g.x >= end.x || g.y >= end.y) { return vec2<u32>(0xffffffffu, 0u); }
    return g;
}
