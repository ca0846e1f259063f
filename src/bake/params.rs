// SPDX-License-Identifier: MIT OR Apache-2.0
//! The per-dispatch `Params` block every bake kernel reads (one 256-byte slot per layer or raster job
//! in a uniform buffer, bound at a dynamic offset), its flags, and the helpers that build it.

use crate::gpu::BufferInit;
use crate::maps::Frame;

/// Per-dispatch parameters. Keep in sync with `Params` in wgsl/shared/params.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Params {
    /// Decal centre.
    pub center: [f32; 4],
    /// Image +x direction; w = width.
    pub axis_u: [f32; 4],
    /// Image +y direction; w = height.
    pub axis_v: [f32; 4],
    /// Projection normal; w = planar depth limit.
    pub normal: [f32; 4],
    /// Output texture size.
    pub tex_size: [u32; 2],
    /// Raster rectangle origin (texels).
    pub rect_origin: [i32; 2],
    /// Raster rectangle size (texels); the encode kernel reads `rect_size[0]` as its row stride.
    pub rect_size: [u32; 2],
    /// UV tile.
    pub tile: [i32; 2],
    /// Supersampling per axis.
    pub ss: u32,
    /// Blend mode id.
    pub blend: u32,
    /// Slot in the chunk.
    pub slot: u32,
    /// Flags (`FLAG_*`).
    pub flags: u32,
    /// Opacity.
    pub opacity: f32,
    /// Welded vertex count.
    pub vertex_count: u32,
    /// Triangle count.
    pub triangle_count: u32,
    /// Layer kernels: the layer's index in the job (stats row); `edt_rows_fill`: padding radius
    /// (`u32::MAX` = full).
    pub aux: u32,
    /// Words per row of the stats buffer (8 counters + the cell mask).
    pub stats_stride: u32,
    /// Side of a mask cell in texels.
    pub cell: u32,
    /// Cells per row and column.
    pub grid: [u32; 2],
    /// Raster job: origin of its samples in the batch's atlas target.
    pub atlas_origin: [u32; 2],
    /// Tool stamps: x = their cell in the flat atlas; `stamp_flatten`: y = the atlas's rows.
    pub pad: [u32; 2],
    /// A cone chart ([`FLAG_CONE`]): the tip's image, k, unused
    /// ([`crate::maps::chart::cone::Cone::params`]).
    pub cone_a: [f32; 4],
    /// A cone chart: α, β.
    pub cone_b: [f32; 4],
    /// The canvas window (`wgsl/shared/window.wgsl`): the texel rectangle x, y, w, h the canvas
    /// holds (a tile, `bake/tiles.rs`); w = 0: the whole texture.
    pub win: [u32; 4],
    /// [`FLAG_WARP`]: x = where the layer's thin-plate spline starts in the warps buffer (vec4s,
    /// [`crate::maps::warp::Tps::pack`]).
    pub warp: [u32; 4],
    /// A data channel's blend (`BLEND_DATA_*`, `wgsl/shared/blend.wgsl`): each output channel's
    /// weight on the source's alpha (its `<channel>_opacity`; 0 leaves it unchanged).
    pub chan: [f32; 4],
    /// Channel passes ([`crate::bake::channels::ChannelDraw`]): x = this entry's index in the
    /// raster and compose's buffer of channel draws; y = a separate pass's channel group (its
    /// constant's place).
    pub draw: [u32; 4],
}

const _: () = assert!(std::mem::size_of::<Params>() == 256);

impl Params {
    /// The canvas window x, y, w, h ([`Params::win`], the whole texture when unset).
    pub fn window(&self) -> [u32; 4] {
        if self.win[2] == 0 {
            [0, 0, self.tex_size[0], self.tex_size[1]]
        } else {
            self.win
        }
    }
}

/// Require front-facing triangles.
pub const FLAG_FACING: u32 = 1;
/// A mask image is bound.
pub const FLAG_MASK: u32 = 2;
/// Encode at 16 bits.
pub const FLAG_16BIT: u32 = 4;
/// A blur or smear stamp: colour from its flat image, shape from its image's alpha.
pub const FLAG_TOOL: u32 = 8;
/// The layer's chart is opened at a tip: its coordinates go through the cone transform in
/// `cone_a` / `cone_b` (`wgsl/shared/cone.wgsl`).
pub const FLAG_CONE: u32 = 16;
/// `encode`: no padding (a tile of a tiled bake; the tiles are padded together on the CPU).
pub const FLAG_NO_PAD: u32 = 32;
/// A tiled ribbon (`"repeat": "tile"`): the image repeats `cone_a[3]` times along its x
/// (`wgsl/bake/layer_raster.wgsl`).
pub const FLAG_REPEAT: u32 = 64;
/// The layer's image is warped by a thin-plate spline (`"warp"`; [`Params::warp`]).
pub const FLAG_WARP: u32 = 128;
/// `layer_raster`: draw the triangles whole, not clipped to the image and its margin
/// ([`crate::Engine::unclipped_raster`]).
pub const FLAG_NO_CLIP: u32 = 256;
/// `encode`: write the canvas as stored (a data or normal channel), not sRGB-encoded.
pub const FLAG_LINEAR: u32 = 512;
/// `layer_raster`'s normal variant: the normal map's green points down the image (`"dx"`).
pub const FLAG_NORMAL_DX: u32 = 1024;
/// `compose`: a live bake's edit ([`crate::bake::LiveBake`]): only the texels of the cells marked
/// in the stats buffer's last row are composed.
pub const FLAG_DIRTY: u32 = 2048;
/// `layer_raster`: a channel group drawn from a constant (its value in the channel draws, at
/// [`Params::draw`] x and y) times the colour image's alpha ([`crate::bake::channels::Draw`]).
pub const FLAG_CONSTANT: u32 = 4096;

/// Texels per side of a tool stamp's flat cell (`bake/tools.rs`). Keep in sync with `FLAT_RES` in
/// `wgsl/bake/stamp_flatten.wgsl`, `stamp_filter.wgsl` and `layer_raster.wgsl`.
pub const FLAT_RES: u32 = 64;
/// Cells per row of the flat atlas. Keep in sync with `FLAT_COLS` in the same WGSL files.
pub const FLAT_COLS: u32 = 16;

/// Stride of `Params` entries in the uniform buffers (dynamic offsets need 256-byte alignment).
pub const PARAMS_STRIDE: u64 = 256;

impl Params {
    /// Fills the frame fields of a `Params` block.
    pub fn of_frame(f: &Frame) -> Params {
        Params {
            center: f.center.extend(0.0).to_array(),
            axis_u: f.axis_u.extend(f.size[0]).to_array(),
            axis_v: f.axis_v.extend(f.size[1]).to_array(),
            normal: f.normal.extend(f.depth).to_array(),
            ..Default::default()
        }
    }
}

/// A `Params` binding (one entry at a dynamic offset).
pub fn pbind(buf: &wgpu::Buffer) -> wgpu::BindingResource<'_> {
    wgpu::BindingResource::Buffer(wgpu::BufferBinding {
        buffer: buf,
        offset: 0,
        size: wgpu::BufferSize::new(std::mem::size_of::<Params>() as u64),
    })
}

/// A uniform buffer with one `Params` entry per [`PARAMS_STRIDE`] bytes.
pub fn params_buffer(dev: &wgpu::Device, label: &str, entries: &[Params]) -> wgpu::Buffer {
    let mut bytes = vec![0u8; (entries.len().max(1) as u64 * PARAMS_STRIDE) as usize];
    for (i, p) in entries.iter().enumerate() {
        let o = i * PARAMS_STRIDE as usize;
        bytes[o..o + std::mem::size_of::<Params>()].copy_from_slice(bytemuck::bytes_of(p));
    }
    dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: &bytes,
        usage: wgpu::BufferUsages::UNIFORM,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The flags a plain layer raster leaves out (`gpu::shaders`, which the GPU side owns) are
    /// these: each one's code is in the general raster only.
    #[test]
    fn the_plain_rasters_flags_are_the_layer_features() {
        let features = FLAG_CONE | FLAG_WARP | FLAG_REPEAT | FLAG_TOOL | FLAG_CONSTANT | FLAG_MASK;
        assert_eq!(crate::gpu::shaders::GENERAL_LAYER_FLAGS, features);
    }
}
