// SPDX-License-Identifier: MIT OR Apache-2.0
//! The UV layout rasterized at a texture size (which texels the islands cover) and its exact
//! Euclidean distance transform (every texel's nearest island texel), computed once per mesh, UV set,
//! size and sampling and cached on the mesh. Kernels `wgsl/bake/island_raster.wgsl`,
//! (whose fragments mark the island mask), `edt_columns.wgsl`, `edt_rows.wgsl`; CPU twin
//! [`crate::bake::cpu::nearest_island_map`], which computes the transform instead of the two
//! kernels where `StagePaths::islands` says (a CPU adapter, by default; wgpu's GL backend,
//! always). The padding stage reads the result.

use super::engine::{Engine, IslandKey, Islands, LoadedMesh, TiledIslands};
use super::params::{params_buffer, pbind, Params, PARAMS_STRIDE};
use super::plan::{raster_jobs, target_side};
use crate::error::Result;
use crate::gpu::pipelines::make_bind_group;
use std::sync::Arc;

/// The islands of `mesh` for a UV set, texture size and sampling (`ss`, and whether the layers
/// are drawn adaptively, at the four samples of one pixel: [`Engine::adaptive_sampling`]; the
/// islands are drawn at the same samples), computed on first use and cached on the mesh. Counts
/// its dispatches and draws into `commands`; [`Islands::path`] says where the distance transform
/// ran when they were computed.
pub fn islands(
    engine: &Engine,
    mesh: &LoadedMesh,
    uv_set: u32,
    size: [u32; 2],
    (ss, msaa): (u32, bool),
    commands: &mut u32,
) -> Result<Arc<Islands>> {
    let key = (uv_set, size[0], size[1], ss, msaa);
    let cache = || mesh.islands.lock().expect("island cache poisoned");
    if let Some(c) = cache().get(&key) {
        return Ok(c.clone());
    }
    let islands = Arc::new(compute(engine, mesh, key, commands)?);
    cache().insert(key, islands.clone());
    Ok(islands)
}

/// The island raster (per UV tile, in target-sized pieces) and the distance transform, in one
/// submission, with the island count (counted by `edt_columns`, or by the CPU over the mask the
/// twin reads).
fn compute(
    engine: &Engine,
    mesh: &LoadedMesh,
    (uv_set, w, h, ss, msaa): IslandKey,
    commands: &mut u32,
) -> Result<Islands> {
    let dev = &engine.ctx.device;
    let texels = w as u64 * h as u64;
    let on_cpu = engine.stage_paths.islands_on_cpu(engine);
    let global = Pass::global(mesh, [w, h], ss, [0; 4]);
    // The twin's nearest map stays on the CPU (`Islands::gpu` uploads it where a kernel needs it).
    let nearest_bytes = if on_cpu { 16 } else { texels * 4 };
    let (pass, jobs) = Pass::new(
        engine,
        mesh,
        (uv_set, ss, msaa),
        global,
        [texels * 4, nearest_bytes],
    );
    let buf = |label, bytes: u64| {
        dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: bytes,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        })
    };
    // The island count, added up by `edt_columns` (the kernels' path only: the twin counts the
    // mask it reads back).
    let counter = (!on_cpu).then(|| {
        dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("islands.count"),
            size: 16,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC
                | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    });
    engine.ctx.scoped("islands", || {
        let mut enc = dev.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("islands"),
        });
        enc.clear_buffer(&pass.mask, 0, None);
        *commands += pass.record_raster(&jobs, &mut enc);
        if let Some(counter) = &counter {
            enc.clear_buffer(counter, 0, None);
            let edt = [
                buf("islands.edt.col_near", texels * 4),
                buf("islands.edt.env_v", texels * 4),
                buf("islands.edt.env_z", (w as u64 + 1) * h as u64 * 4),
            ];
            *commands += pass.record_edt([w, h], (&edt, counter), &mut enc);
        }
        engine.ctx.queue.submit([enc.finish()]);
    })?;
    let (count, host) = if let Some(counter) = &counter {
        let count = engine
            .ctx
            .read_buffer(counter, 16, "island count read-back")?;
        (bytemuck::cast_slice::<u8, u32>(&count)[0] as u64, None)
    } else {
        // The same exact transform by its CPU twin, uploaded: the faster on a CPU adapter, and
        // the only right one on wgpu's GL backend (Mesa llvmpipe there gets the kernels' answer
        // wrong, not yet understood; Vulkan is exact, see tests/padding_edt.rs).
        let m = engine
            .ctx
            .read_buffer(&pass.mask, texels * 4, "island mask read-back")?;
        let island: Vec<bool> = bytemuck::cast_slice::<u8, u32>(&m)
            .iter()
            .map(|v| *v != 0)
            .collect();
        let near = crate::bake::cpu::nearest_island_map(&island, w, h);
        let count = island.iter().filter(|i| **i).count() as u64;
        let host = TiledIslands {
            mask: island,
            nearest: near,
            count,
        };
        (count, Some(host))
    };
    let gpu = std::sync::OnceLock::new();
    if host.is_none() {
        let _ = gpu.set([pass.mask, pass.nearest]);
    }
    Ok(Islands {
        count,
        gpu,
        path: if on_cpu { "cpu" } else { "gpu" },
        host,
    })
}

/// The island mask of one window (x, y, w, h) of a `size` texture: 1 per island texel, row-major
/// over the window (a tile of a tiled bake, `bake/tiles.rs`, which assembles the tiles' masks and
/// computes the distance transform on the CPU). The same raster as [`islands`], restricted to the
/// window's rectangles.
pub(crate) fn window_mask(
    engine: &Engine,
    mesh: &LoadedMesh,
    (uv_set, ss, msaa): (u32, u32, bool),
    size: [u32; 2],
    win: [u32; 4],
    commands: &mut u32,
) -> Result<Vec<u32>> {
    let dev = &engine.ctx.device;
    let bytes = win[2] as u64 * win[3] as u64 * 4;
    let global = Pass::global(mesh, size, ss, win);
    // No distance transform here (the tiles' is on the CPU): a placeholder nearest map.
    let (pass, jobs) = Pass::new(engine, mesh, (uv_set, ss, msaa), global, [bytes, 16]);
    engine.ctx.scoped("islands", || {
        let mut enc = dev.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("islands.window"),
        });
        enc.clear_buffer(&pass.mask, 0, None);
        *commands += pass.record_raster(&jobs, &mut enc);
        engine.ctx.queue.submit([enc.finish()]);
    })?;
    let m = engine
        .ctx
        .read_buffer(&pass.mask, bytes, "island mask read-back")?;
    Ok(bytemuck::cast_slice(&m).to_vec())
}

/// What the island passes bind.
struct Pass<'a> {
    engine: &'a Engine,
    mesh: &'a LoadedMesh,
    uv_set: u32,
    ss: u32,
    /// Drawn at the four samples of one pixel a texel (the adaptive bake's pattern).
    msaa: bool,
    /// Entry 0: the whole texture; entry k + 1: raster job k.
    params: wgpu::Buffer,
    mask: wgpu::Buffer,
    nearest: wgpu::Buffer,
}

impl<'a> Pass<'a> {
    /// The passes' shared `Params`: a `size` texture at `ss`² samples, the canvas window `win`
    /// (all zero: the whole texture).
    fn global(mesh: &LoadedMesh, size: [u32; 2], ss: u32, win: [u32; 4]) -> Params {
        Params {
            tex_size: size,
            ss,
            triangle_count: mesh.gpu.triangle_count,
            stats_stride: 1,
            win,
            ..Default::default()
        }
    }

    /// The buffers (mask and nearest map of `[mask, nearest]` bytes; the caller clears the mask)
    /// and the raster jobs that cover `global`'s window.
    fn new(
        engine: &'a Engine,
        mesh: &'a LoadedMesh,
        (uv_set, ss, msaa): (u32, u32, bool),
        global: Params,
        [mask_bytes, nearest_bytes]: [u64; 2],
    ) -> (Self, Vec<Params>) {
        let dev = &engine.ctx.device;
        let buf = |label, bytes: u64| {
            dev.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes,
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_SRC
                    | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let jobs = raster_jobs(&mesh.mesh.uv_sets[uv_set as usize], global);
        let mut entries = vec![global];
        entries.extend(jobs.iter().copied());
        let pass = Pass {
            engine,
            mesh,
            uv_set,
            ss,
            msaa,
            params: params_buffer(dev, "islands.params", &entries),
            mask: buf("islands.mask", mask_bytes),
            nearest: buf("islands.nearest", nearest_bytes),
        };
        (pass, jobs)
    }

    /// Per raster job: `island_raster` draws every triangle, its fragments marking the mask
    /// (the texels with any covered sample). Its colour target only completes the render pass:
    /// nothing reads it, so it is not cleared first. Returns the draws recorded.
    fn record_raster(&self, jobs: &[Params], enc: &mut wgpu::CommandEncoder) -> u32 {
        let (dev, pipes, g) = (&self.engine.ctx.device, &self.engine.pipes, &self.mesh.gpu);
        // Target pixels a texel a side, and samples a pixel.
        let (ss, samples) = if self.msaa { (1, 4) } else { (self.ss, 1) };
        let raster = &pipes.family(self.msaa).island_raster;
        let bg_island = make_bind_group(
            dev,
            &raster.layout,
            "islands.raster",
            &[
                (0, pbind(&self.params)),
                (1, g.tris.as_entire_binding()),
                (2, g.split_tris.as_entire_binding()),
                (3, g.uvs[self.uv_set as usize].as_entire_binding()),
                (4, self.mask.as_entire_binding()),
            ],
        );
        for (k, j) in jobs.iter().enumerate() {
            let off = ((k + 1) as u64 * PARAMS_STRIDE) as u32;
            let side = target_side(j.rect_size, ss);
            let tg = self.engine.targets([side, side], samples);
            let mut pass =
                crate::gpu::render_pass(enc, "islands.raster", &[&tg.cov_view], wgpu::LoadOp::Load);
            pass.set_pipeline(&raster.pipeline);
            pass.set_bind_group(0, &bg_island, &[off]);
            let [jw, jh] = j.rect_size.map(|v| (v * ss) as f32);
            pass.set_viewport(0.0, 0.0, jw, jh, 0.0, 1.0);
            pass.draw(0..3 * g.triangle_count, 0..1);
        }
        jobs.len() as u32
    }

    /// The exact Euclidean distance transform of the mask (Felzenszwalb & Huttenlocher): nearest
    /// island texel per column (`edt_columns`), then the lower envelope along each row
    /// (`edt_rows`), the first also counting the island texels into `counter`. `scratch`: column
    /// nearest, envelope vertices, envelope boundaries.
    fn record_edt(
        &self,
        [w, h]: [u32; 2],
        (scratch, counter): (&[wgpu::Buffer; 3], &wgpu::Buffer),
        enc: &mut wgpu::CommandEncoder,
    ) -> u32 {
        let (dev, pipes) = (&self.engine.ctx.device, &self.engine.pipes);
        let [col_near, env_v, env_z] = scratch;
        let bg_cols = pipes.edt_columns.bind(
            dev,
            "islands.edt_columns",
            &[
                (0, pbind(&self.params)),
                (1, self.mask.as_entire_binding()),
                (2, col_near.as_entire_binding()),
                (3, counter.as_entire_binding()),
            ],
        );
        let bg_rows = pipes.edt_rows.bind(
            dev,
            "islands.edt_rows",
            &[
                (0, pbind(&self.params)),
                (1, self.mask.as_entire_binding()),
                (2, col_near.as_entire_binding()),
                (3, env_v.as_entire_binding()),
                (4, env_z.as_entire_binding()),
                (5, self.nearest.as_entire_binding()),
            ],
        );
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("islands.edt"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&pipes.edt_columns.pipeline);
        pass.set_bind_group(0, &bg_cols, &[0]);
        pass.dispatch_workgroups(w.div_ceil(64), 1, 1);
        pass.set_pipeline(&pipes.edt_rows.pipeline);
        pass.set_bind_group(0, &bg_rows, &[0]);
        pass.dispatch_workgroups(h.div_ceil(64), 1, 1);
        2
    }
}

impl Engine {
    /// The island mask (1 = island texel) and the nearest-island-texel index of every texel, as the
    /// bake uses them, read back to the CPU. For tests and debugging; `samples` is 1, 4, 9 or 16.
    pub fn island_maps(
        &self,
        mesh: &LoadedMesh,
        uv_set: u32,
        size: [u32; 2],
        samples: u32,
    ) -> Result<(Vec<u32>, Vec<u32>)> {
        let ss = (samples as f32).sqrt().round() as u32;
        let mut commands = 0;
        let isl = islands(self, mesh, uv_set, size, (ss.max(1), false), &mut commands)?;
        if let Some(host) = &isl.host {
            return Ok((host.mask_words(), host.nearest.clone()));
        }
        let bytes = size[0] as u64 * size[1] as u64 * 4;
        let [mask, nearest] = isl.gpu(&self.ctx);
        let mask = self.ctx.read_buffer(mask, bytes, "island mask read-back")?;
        let nearest = self
            .ctx
            .read_buffer(nearest, bytes, "nearest map read-back")?;
        Ok((
            bytemuck::cast_slice(&mask).to_vec(),
            bytemuck::cast_slice(&nearest).to_vec(),
        ))
    }
}
