// SPDX-License-Identifier: MIT OR Apache-2.0
// Draws a flattened SVG document (src/io/vector_paths.rs) by evaluating each path's coverage at
// ss x ss point samples of every pixel: the winding number of a sample is its row's backdrop in
// the pixel's tile (the signed crossings of that row by the path's segments that lie wholly right
// of the tile, summed on the CPU when binning) plus the crossings right of the sample by the
// segments listed in the tile. Paths are drawn in order, premultiplied source-over, as tiny-skia
// draws them (paint at the pixel centre, straight colour premultiplied, times the coverage); a
// pixel visits only the paths listed in its tile.
// The GPU alternative to resvg that `decalbake bench --vector` measures; bakes use resvg.
// One invocation per pixel; dispatch (ceil(w / 8), ceil(h / 8), 1).
// CPU twin: `coverage_cpu` in src/bake/vector_gpu.rs.

const TILE: u32 = 16u;

struct Uni {
    size: vec2<u32>,
    ss: u32,
    paths: u32,
}

// A path's tiles (x0, y0, x1, y1; x1 and y1 past the last), its first tile record, fill rule and
// paint offset.
struct PathRec {
    tiles: vec4<u32>,
    base: u32,
    even_odd: u32,
    paint: u32,
    pad: u32,
}

@group(0) @binding(0) var<uniform> u: Uni;
@group(0) @binding(1) var<storage, read> paths: array<PathRec>;
// Per tile record: (first entry in refs, count).
@group(0) @binding(2) var<storage, read> tiles: array<vec2<u32>>;
@group(0) @binding(3) var<storage, read> refs: array<u32>;
// Per tile record, TILE * ss rows of backdrop.
@group(0) @binding(4) var<storage, read> backdrops: array<i32>;
// (x0, y0, x1, y1), pixels.
@group(0) @binding(5) var<storage, read> segs: array<vec4<f32>>;
// A paint: vec4(kind, stops, spread, 0), then a solid colour, or (a, b, c, 0) of t and per stop
// vec4(offset, 0, 0, 0) and its colour; straight, sRGB-encoded.
@group(0) @binding(6) var<storage, read> paints: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read_write> out: array<vec4<f32>>;
// Per tile of the image (rows of ceil(w / TILE)): (first entry, count) of its list, then the
// lists' entries: (path, tile record) of each path whose tiles hold it, in drawing order.
@group(0) @binding(8) var<storage, read> grid: array<vec2<u32>>;

fn paint_at(off: u32, p: vec2<f32>) -> vec4<f32> {
    let h = paints[off];
    if (h.x == 0.0) {
        return paints[off + 1u];
    }
    let k = paints[off + 1u];
    let n = u32(h.y);
    var t = k.x * p.x + k.y * p.y + k.z;
    if (h.z == 1.0) {
        t = t - floor(t);
    } else if (h.z == 2.0) {
        let m = t - 2.0 * floor(t * 0.5);
        t = select(m, 2.0 - m, m > 1.0);
    }
    // Padded ends take the end stops (hard stops at 0 or 1 included).
    if (t <= 0.0) {
        return paints[off + 3u];
    }
    if (t >= 1.0) {
        return paints[off + 3u + 2u * (n - 1u)];
    }
    var i = 0u;
    while (i + 2u < n && paints[off + 2u + 2u * (i + 1u)].x <= t) {
        i++;
    }
    let o0 = paints[off + 2u + 2u * i].x;
    let o1 = paints[off + 2u + 2u * (i + 1u)].x;
    let c0 = paints[off + 3u + 2u * i];
    let c1 = paints[off + 3u + 2u * (i + 1u)];
    let f = select(1.0, (t - o0) / (o1 - o0), o1 > o0);
    return mix(c0, c1, clamp(f, 0.0, 1.0));
}

// The winding number at (x, y), sample row j, in tile record `rec` whose tile starts at row
// `row0` (in sample rows).
fn winding(rec: u32, row0: u32, j: u32, x: f32, y: f32) -> i32 {
    var w = backdrops[rec * TILE * u.ss + (j - row0)];
    let list = tiles[rec];
    for (var k = 0u; k < list.y; k++) {
        let s = segs[refs[list.x + k]];
        let down = s.y <= y && y < s.w;
        let up = s.w <= y && y < s.y;
        if (down || up) {
            let xc = s.x + (y - s.y) * (s.z - s.x) / (s.w - s.y);
            if (xc > x) {
                w += select(-1, 1, down);
            }
        }
    }
    return w;
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= u.size.x || gid.y >= u.size.y) { return; }
    let tx = gid.x / TILE;
    let ty = gid.y / TILE;
    let ss = u.ss;
    let fss = f32(ss);
    let centre = vec2<f32>(gid.xy) + 0.5;
    var acc = vec4<f32>(0.0);
    let cell = grid[ty * ((u.size.x + TILE - 1u) / TILE) + tx];
    for (var e = 0u; e < cell.y; e++) {
        let entry = grid[cell.x + e];
        let p = paths[entry.x];
        let rec = entry.y;
        var covered = 0u;
        for (var sj = 0u; sj < ss; sj++) {
            let j = gid.y * ss + sj;
            let y = (f32(j) + 0.5) / fss;
            for (var si = 0u; si < ss; si++) {
                let x = (f32(gid.x * ss + si) + 0.5) / fss;
                let w = winding(rec, ty * TILE * ss, j, x, y);
                let inside = select(w != 0, (w & 1) != 0, p.even_odd != 0u);
                covered += select(0u, 1u, inside);
            }
        }
        if (covered == 0u) { continue; }
        let c = paint_at(p.paint, centre);
        let src = vec4<f32>(c.rgb * c.a, c.a) * (f32(covered) / (fss * fss));
        acc = src + acc * (1.0 - src.a);
    }
    out[gid.y * u.size.x + gid.x] = acc;
}
