// SPDX-License-Identifier: MIT OR Apache-2.0
// One node of the mesh's BVH as the placement walk reads it and the GPU build writes it
// (`place_bvh.wgsl`, `wgsl/mesh/lbvh.wgsl`). Keep in sync with `BvhNode` in src/mesh/bvh.rs:
// internal node: `first` = its first child (the second next to it), `count` = 0; leaf: `first` =
// its first entry of the leaf-ordered triangles, `count` = how many.
struct Node {
    lo: vec3<f32>,
    first: u32,
    hi: vec3<f32>,
    count: u32,
}
