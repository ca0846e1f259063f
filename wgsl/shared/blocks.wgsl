// SPDX-License-Identifier: MIT OR Apache-2.0
// The compose's block mask (src/bake/compose.rs, `block_mask`): one word per BLOCK x BLOCK texels of
// the layer raster's atlas target, BLOCKS_ROW words a row (TILE_TARGET / BLOCK in
// src/bake/plan.rs: the widest atlas, one sample a texel). layer_raster.wgsl sets a block's word
// where a fragment leaves anything the compose reads (an output's alpha not <= 0); compose.wgsl
// skips the texels of a block left at 0, all of whose samples would compose nothing. Cleared
// before each atlas batch.
const BLOCK: u32 = 8u;
const BLOCKS_ROW: u32 = 256u;

// The mask word of atlas texel `t`.
fn block_of(t: vec2<u32>) -> u32 {
    return (t.y / BLOCK) * BLOCKS_ROW + t.x / BLOCK;
}
