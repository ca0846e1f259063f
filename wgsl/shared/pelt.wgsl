// SPDX-License-Identifier: MIT OR Apache-2.0
// What the pelting kernels (pelt_step.wgsl, pelt_check.wgsl) share: a piece's state between
// dispatches.

// Keep in sync with `PieceState` in src/pelt/gpu.rs.
struct Piece {
    v0: u32,
    n: u32,
    damping: f32,
    steps: u32,
    steady: u32,
    ke: f32,
    _pad0: u32,
    _pad1: u32,
}
