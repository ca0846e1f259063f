// SPDX-License-Identifier: MIT OR Apache-2.0
// Compacts one layer's selection marks into its triangle list, in the order of the tested
// triangles (the candidate list, sorted by triangle id, or the whole mesh in id order), so the
// list, the raster's draw order and with it the winner among overlapping triangles never depend
// on which invocation ran first. `select_triangles` writes each tested triangle's id, or NONE, at
// its position in `marks`; this kernel keeps the ids in that order.
// One workgroup a layer (`params.slot`), in rounds of WG * PER tested triangles: each invocation
// counts the kept ids of its PER consecutive marks, the workgroup scans the counts, and each
// invocation writes its ids at its offset. The total is the atomic count `select_triangles` kept.
// Dispatch: (1, 1, 1). CPU twin: the triangle order of `select_triangles` in src/bake/cpu.rs.
#import params

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> ranges: array<vec2<u32>>;
@group(0) @binding(2) var<storage, read> marks: array<u32>;
@group(0) @binding(3) var<storage, read_write> lists: array<u32>;

const NONE: u32 = 0xffffffffu;
const WG: u32 = 64u;
const PER: u32 = 64u;

var<workgroup> sums: array<u32, 64>;

@compute @workgroup_size(64)
fn main(@builtin(local_invocation_index) li: u32) {
    let n = ranges[params.slot].y;
    let out0 = params.slot * params.triangle_count;
    let rounds = (n + WG * PER - 1u) / (WG * PER);
    var written = 0u;
    for (var r = 0u; r < rounds; r++) {
        let start = (r * WG + li) * PER;
        let end = min(start + PER, n);
        var c = 0u;
        for (var i = start; i < end; i++) {
            if (marks[i] != NONE) { c++; }
        }
        sums[li] = c;
        workgroupBarrier();
        // Inclusive scan of the 64 counts (Hillis-Steele).
        for (var d = 1u; d < WG; d = d * 2u) {
            var v = 0u;
            if (li >= d) { v = sums[li - d]; }
            workgroupBarrier();
            sums[li] += v;
            workgroupBarrier();
        }
        var o = written + sums[li] - c;
        for (var i = start; i < end; i++) {
            let t = marks[i];
            if (t != NONE) {
                lists[out0 + o] = t;
                o++;
            }
        }
        written += sums[WG - 1u];
        // Every invocation has read the totals before the next round overwrites them.
        workgroupBarrier();
    }
}
