// SPDX-License-Identifier: MIT OR Apache-2.0
//! The base by texture transfer (`"texture.base": {"transfer": {"from_uv_set": N, "image": ...}}`):
//! the source texture, laid out on UV set N, resampled into the set being baked, so each texel's
//! surface point takes the colour the source has there (the usual step after a new
//! unwrap). Per raster job (the islands' tiling: `TILE_TARGET / ss` texels a side, every UV tile
//! the baked set reaches), `transfer_raster` draws every triangle at its baked UV carrying its
//! source UV into the pooled colour and coverage targets at the bake's supersampling, and
//! `transfer_resolve` writes each texel the mean of its drawn samples into the canvas (the others
//! stay transparent; padding fills them as it does every background texel). CPU twin:
//! `bake::cpu_tools::transfer_cpu`.

use super::engine::{Engine, GpuImage, LoadedMesh};
use super::params::{params_buffer, pbind, Params, PARAMS_STRIDE};
use super::plan::{raster_jobs, target_side};
use super::stage::Log;
use crate::error::Result;
use crate::gpu::pipelines::make_bind_group;
use crate::io::job::Job;

/// Fills the canvas planes `acc` with `source` (laid out on `from_uv_set`) transferred into
/// `job.uv_set`, in one submission.
pub fn fill(
    engine: &Engine,
    mesh: &LoadedMesh,
    job: &Job,
    (source, from_uv_set): (&GpuImage, u32),
    global: Params,
    acc: [&wgpu::Buffer; 2],
    log: &mut Log,
) -> Result<()> {
    let (dev, pipes, g) = (&engine.ctx.device, &engine.pipes, &mesh.gpu);
    let ss = global.ss;
    let jobs = raster_jobs(&mesh.mesh.uv_sets[job.uv_set as usize], global);
    let params = params_buffer(dev, "bake.transfer.params", &jobs);
    engine.ctx.scoped("texture transfer", || {
        let mut enc = dev.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("bake.transfer"),
        });
        // The planes are new (wgpu zero-fills them): transparent where nothing is drawn.
        let bg_raster = make_bind_group(
            dev,
            &pipes.transfer_raster.layout,
            "bake.transfer_raster",
            &[
                (0, pbind(&params)),
                (1, g.tris.as_entire_binding()),
                (2, g.split_tris.as_entire_binding()),
                (3, g.uvs[job.uv_set as usize].as_entire_binding()),
                (4, g.uvs[from_uv_set as usize].as_entire_binding()),
                (5, wgpu::BindingResource::TextureView(&source.view)),
                (6, wgpu::BindingResource::Sampler(&engine.linear_sampler)),
            ],
        );
        for (k, j) in jobs.iter().enumerate() {
            let off = (k as u64 * PARAMS_STRIDE) as u32;
            let side = target_side(j.rect_size, ss);
            let tg = engine.targets([side, side], 1);
            {
                let mut pass = crate::gpu::cleared_pass(
                    &mut enc,
                    "bake.transfer_raster",
                    &[&tg.color_view, &tg.cov_view],
                );
                pass.set_pipeline(&pipes.transfer_raster.pipeline);
                pass.set_bind_group(0, &bg_raster, &[off]);
                let [jw, jh] = j.rect_size.map(|v| (v * ss) as f32);
                pass.set_viewport(0.0, 0.0, jw, jh, 0.0, 1.0);
                pass.draw(0..3 * g.triangle_count, 0..1);
            }
            let bg_resolve = pipes.transfer_resolve.bind(
                dev,
                "bake.transfer_resolve",
                &[
                    (0, pbind(&params)),
                    (1, wgpu::BindingResource::TextureView(&tg.color_view)),
                    (2, wgpu::BindingResource::TextureView(&tg.cov_view)),
                    (10, acc[0].as_entire_binding()),
                    (11, acc[1].as_entire_binding()),
                ],
            );
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("bake.transfer_resolve"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&pipes.transfer_resolve.pipeline);
            pass.set_bind_group(0, &bg_resolve, &[off]);
            pass.dispatch_workgroups(j.rect_size[0].div_ceil(8), j.rect_size[1].div_ceil(8), 1);
        }
        log.commands += 2 * jobs.len() as u32;
        engine.ctx.queue.submit([enc.finish()]);
    })
}
