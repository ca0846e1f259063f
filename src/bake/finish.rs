// SPDX-License-Identifier: MIT OR Apache-2.0
//! Stages 6 and 7, padding and encoding, in one pass (`wgsl/bake/encode.wgsl`): background texels
//! within `padding` of an island (or all, for `"full"`) take the colour of their nearest island texel
//! (from the islands' distance transform), then every texel is encoded to sRGB 8 or 16 bits into a
//! packed buffer with 256-byte rows, ready for one read-back or a copy into a host texture.

use super::canvas::Canvas;
use super::params::{params_buffer, pbind, Params, FLAG_16BIT, FLAG_LINEAR, FLAG_NO_PAD};
use super::stage::{Cx, Log};
use crate::error::Result;
use crate::io::job::Padding;

/// The encoded texture on the GPU.
pub struct Encoded {
    /// Packed texels: RGBA8 in one word, or RGBA16 in two, rows `stride` words apart.
    pub packed: wgpu::Buffer,
    /// Bytes of `packed`.
    pub packed_size: u64,
    /// Words per row.
    pub stride: u32,
}

/// Pads and encodes the canvas.
/// `pad`: pad here (false for a tile of a tiled bake, which is padded on the CPU); the encoded
/// texels are the canvas window's. `linear`: write the values as stored (a data or normal
/// channel), not sRGB-encoded.
pub(crate) fn pad_and_encode(
    cx: Cx<'_>,
    canvas: &Canvas,
    (pad, linear): (bool, bool),
    log: &mut Log,
) -> Result<Encoded> {
    let Cx { engine, job, .. } = cx;
    let [_, _, w, h] = canvas.global.window();
    let stride = if job.bit_depth == 16 {
        (2 * w).next_multiple_of(64)
    } else {
        w.next_multiple_of(64)
    };
    let packed_size = stride as u64 * h as u64 * 4;
    // Every word a reader reads (w texels a row, never the row padding) is written below, so a
    // buffer from the pool serves as well as a new one.
    let usage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC;
    let (packed, _) = engine.pooled_buffer("bake.packed", packed_size, usage);
    let encoded = Encoded {
        packed,
        packed_size,
        stride,
    };
    encode_regions(cx, canvas, (pad, linear), (&encoded, &[]), log)?;
    Ok(encoded)
}

/// Pads and encodes `regions` (x, y, w, h texel rectangles of the canvas window; none: the whole
/// window) into `encoded`, whose other texels keep their bytes: a live bake's edit
/// ([`crate::bake::LiveBake`]) encodes only its cells and the padding they reach.
pub(crate) fn encode_regions(
    cx: Cx<'_>,
    canvas: &Canvas,
    (pad, linear): (bool, bool),
    (encoded, regions): (&Encoded, &[[u32; 4]]),
    log: &mut Log,
) -> Result<()> {
    let Cx { engine, job, .. } = cx;
    let (dev, pipes) = (&engine.ctx.device, &engine.pipes);
    let [_, _, w, h] = canvas.global.window();
    let whole = [[0, 0, w, h]];
    let fin = Params {
        rect_size: [encoded.stride, 0],
        flags: if job.bit_depth == 16 { FLAG_16BIT } else { 0 }
            | if pad { 0 } else { FLAG_NO_PAD }
            | if linear { FLAG_LINEAR } else { 0 },
        aux: padding_radius(job.padding),
        ..canvas.global
    };
    let entries: Vec<Params> = match regions {
        [] => vec![fin],
        r => r
            .iter()
            .map(|r| Params {
                rect_origin: [r[0] as i32, r[1] as i32],
                atlas_origin: [r[2], r[3]],
                ..fin
            })
            .collect(),
    };
    let sizes = if regions.is_empty() {
        &whole[..]
    } else {
        regions
    };
    let fin_params = params_buffer(dev, "bake.final_params", &entries);
    let encode = pipes.encode_for(linear, job.bit_depth == 16);
    engine.ctx.scoped("padding and encode", || {
        let mut enc = dev.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("bake.finish"),
        });
        let bg_enc = encode.bind(
            dev,
            "bake.encode",
            &[
                (0, pbind(&fin_params)),
                (1, encoded.packed.as_entire_binding()),
                (2, canvas.islands.mask.as_entire_binding()),
                (3, canvas.islands.nearest.as_entire_binding()),
                (10, canvas.acc_rg.as_entire_binding()),
                (11, canvas.acc_ba.as_entire_binding()),
            ],
        );
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("bake.finish"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&encode.pipeline);
            for (k, r) in sizes.iter().enumerate() {
                let offset = (k as u64 * super::params::PARAMS_STRIDE) as u32;
                pass.set_bind_group(0, &bg_enc, &[offset]);
                pass.dispatch_workgroups(r[2].div_ceil(8), r[3].div_ceil(8), 1);
                log.commands += 1;
            }
        }
        engine.ctx.queue.submit([enc.finish()]);
    })?;
    engine.ctx.wait("padding")
}

/// The encode kernel's padding radius in texels (`u32::MAX` = the whole background).
pub fn padding_radius(p: Padding) -> u32 {
    match p {
        Padding::Texels(n) => n,
        Padding::Full => u32::MAX,
    }
}
