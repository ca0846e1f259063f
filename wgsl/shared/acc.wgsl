// SPDX-License-Identifier: MIT OR Apache-2.0
// The linear RGBA accumulation image, split in two planes (rg, ba) so that a 4096 x 4096 texture fits
// the 128 MiB storage-binding limit common on software drivers. Straight alpha, f32 per channel.
// Bound at 10 and 11 in every kernel that uses it; keep in sync with `AccBuffers` in src/bake/.
@group(0) @binding(10) var<storage, read_write> acc_rg: array<vec2<f32>>;
@group(0) @binding(11) var<storage, read_write> acc_ba: array<vec2<f32>>;

fn acc_load(i: u32) -> vec4<f32> {
    return vec4<f32>(acc_rg[i], acc_ba[i]);
}

fn acc_store(i: u32, c: vec4<f32>) {
    acc_rg[i] = c.rg;
    acc_ba[i] = c.ba;
}
