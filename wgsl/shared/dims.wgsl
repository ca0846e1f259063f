// SPDX-License-Identifier: MIT OR Apache-2.0
// The one-number uniform of the simple streaming kernels (spmv, copy, chart_scatter): how many
// elements (rows, vec4s, items) to process, padded to 16 bytes.

struct Dims {
    len: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}
