// SPDX-License-Identifier: MIT OR Apache-2.0
//! The GPU context: adapter selection, device creation, error scopes, device loss and read-back.
//!
//! decalbake runs headless. [`GpuContext::new`] prefers Vulkan and falls back to GL (both work on Mesa's
//! software drivers, lavapipe and llvmpipe); `WGPU_BACKEND` or an explicit backend name override the
//! choice. [`GpuContext::from_device`] wraps a host renderer's device and queue instead.
//!
//! Every GPU stage runs inside [`GpuContext::scoped`], which turns wgpu validation and out-of-memory
//! errors into [`Error::Gpu`]; a lost device is reported as [`Error::DeviceLost`] at the next wait.

use crate::error::{Error, Result};
pub mod cache;
pub mod pipelines;
pub mod shaders;
use std::sync::{Arc, Mutex};

/// A device and queue plus what the engine needs to know about them.
pub struct GpuContext {
    /// The wgpu device.
    pub device: wgpu::Device,
    /// The wgpu queue.
    pub queue: wgpu::Queue,
    /// Adapter description (name, backend, driver), for logs and reports.
    pub adapter: String,
    /// The backend, when known (`None` for a host device created elsewhere).
    pub backend: Option<wgpu::Backend>,
    /// The adapter's kind, when known (a software driver such as lavapipe is `Cpu`).
    pub device_type: Option<wgpu::DeviceType>,
    /// The compiled pipelines kept on disk (a headless device on Vulkan; see [`cache`]), and what
    /// it held when the device was made.
    pub pipeline_cache: (Option<Arc<cache::DiskCache>>, cache::Start),
    /// Milliseconds [`GpuContext::new`] took (instance, adapter, device, cache file); 0 for a
    /// host's device.
    pub startup_ms: f64,
    lost: Arc<Mutex<Option<String>>>,
}

/// `create_buffer_init` that survives a lost device. wgpu's own (`wgpu::util::DeviceExt`) panics
/// when the buffer cannot be mapped, which is what happens once the device is destroyed (by a host,
/// or from another thread in the middle of a bake); this one returns the unmapped, invalid buffer
/// instead, so the stage's error scope or the next wait reports [`Error::DeviceLost`]. The engine
/// imports this trait instead of wgpu's.
pub trait BufferInit {
    /// A buffer holding `desc.contents` (padded to a multiple of 4 bytes).
    fn create_buffer_init(&self, desc: &wgpu::util::BufferInitDescriptor<'_>) -> wgpu::Buffer;
}

impl BufferInit for wgpu::Device {
    fn create_buffer_init(&self, desc: &wgpu::util::BufferInitDescriptor<'_>) -> wgpu::Buffer {
        let size = (desc.contents.len() as u64).next_multiple_of(wgpu::COPY_BUFFER_ALIGNMENT);
        let buffer = self.create_buffer(&wgpu::BufferDescriptor {
            label: desc.label,
            size: size.max(wgpu::COPY_BUFFER_ALIGNMENT),
            usage: desc.usage,
            mapped_at_creation: true,
        });
        if let Ok(mut view) = buffer.get_mapped_range_mut(..) {
            view.slice(..desc.contents.len())
                .copy_from_slice(desc.contents);
            drop(view);
            buffer.unmap();
        }
        buffer
    }
}

/// Parses a backend name as accepted by `--backend` (`vulkan`, `gl`, `metal`, `dx12`, or a comma list).
pub fn parse_backends(name: &str) -> Option<wgpu::Backends> {
    let b = wgpu::Backends::from_comma_list(name);
    if b.is_empty() {
        None
    } else {
        Some(b)
    }
}

/// A render pass over `views`, each cleared to transparent first (the bake's raster targets).
pub fn cleared_pass<'e>(
    enc: &'e mut wgpu::CommandEncoder,
    label: &str,
    views: &[&wgpu::TextureView],
) -> wgpu::RenderPass<'e> {
    render_pass(
        enc,
        label,
        views,
        wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
    )
}

/// A render pass onto `views` that starts from their contents (`load`: keep them) or cleared.
pub fn render_pass<'e>(
    enc: &'e mut wgpu::CommandEncoder,
    label: &str,
    views: &[&wgpu::TextureView],
    load: wgpu::LoadOp<wgpu::Color>,
) -> wgpu::RenderPass<'e> {
    let views: Vec<Option<&wgpu::TextureView>> = views.iter().map(|&v| Some(v)).collect();
    render_pass_to(enc, label, &views, load)
}

/// [`render_pass`] into attachments of which some may be absent (`None`: the pipelines drawn
/// have no target there).
pub fn render_pass_to<'e>(
    enc: &'e mut wgpu::CommandEncoder,
    label: &str,
    views: &[Option<&wgpu::TextureView>],
    load: wgpu::LoadOp<wgpu::Color>,
) -> wgpu::RenderPass<'e> {
    let attachments: Vec<Option<wgpu::RenderPassColorAttachment>> = views
        .iter()
        .map(|view| {
            view.map(|view| wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load,
                    store: wgpu::StoreOp::Store,
                },
            })
        })
        .collect();
    enc.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some(label),
        color_attachments: &attachments,
        depth_stencil_attachment: None,
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    })
}

impl GpuContext {
    /// A storage buffer holding `bytes` (usable as `STORAGE | extra`); empty contents become one
    /// zero word, since wgpu rejects zero-sized bindings.
    pub fn storage_init(
        &self,
        label: &str,
        bytes: &[u8],
        extra: wgpu::BufferUsages,
    ) -> wgpu::Buffer {
        let pad = [0u8; 16];
        self.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: if bytes.is_empty() { &pad } else { bytes },
                usage: wgpu::BufferUsages::STORAGE | extra,
            })
    }

    /// A uniform buffer holding `bytes`.
    pub fn uniform_init(&self, label: &str, bytes: &[u8]) -> wgpu::Buffer {
        self.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: bytes,
                usage: wgpu::BufferUsages::UNIFORM,
            })
    }

    /// The kind of adapter [`Self::new`] would take for `backend`, without making a device (`None`
    /// where there is none): what a command asks before it decides whether it needs a device.
    pub fn adapter_type(backend: Option<&str>) -> Option<wgpu::DeviceType> {
        let attempts: Vec<wgpu::Backends> = match backend {
            Some(name) => vec![parse_backends(name)?],
            None => match wgpu::Backends::from_env() {
                Some(b) => vec![b],
                None => vec![wgpu::Backends::VULKAN, wgpu::Backends::GL],
            },
        };
        attempts.into_iter().find_map(|backends| {
            let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
                backends,
                ..wgpu::InstanceDescriptor::new_without_display_handle()
            });
            let adapter =
                pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
                    power_preference: wgpu::PowerPreference::HighPerformance,
                    ..Default::default()
                }))
                .ok()?;
            let compute = adapter
                .get_downlevel_capabilities()
                .flags
                .contains(wgpu::DownlevelFlags::COMPUTE_SHADERS);
            compute.then(|| adapter.get_info().device_type)
        })
    }

    /// Creates a headless device. `backend` (e.g. `"vulkan"`, `"gl"`) overrides `WGPU_BACKEND`; with
    /// neither, Vulkan is tried first and GL second.
    pub fn new(backend: Option<&str>) -> Result<Self> {
        let start = std::time::Instant::now();
        let requested = match backend {
            Some(name) => Some(parse_backends(name).ok_or_else(|| Error::NoAdapter {
                backends: name.to_string(),
                detail: "unknown backend name (use vulkan, gl, metal or dx12)".into(),
            })?),
            None => wgpu::Backends::from_env(),
        };
        let attempts: Vec<wgpu::Backends> = match requested {
            Some(b) => vec![b],
            None => vec![wgpu::Backends::VULKAN, wgpu::Backends::GL],
        };
        let mut last_err = String::from("no backend tried");
        for backends in &attempts {
            let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
                backends: *backends,
                ..wgpu::InstanceDescriptor::new_without_display_handle()
            });
            let adapter =
                match pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
                    power_preference: wgpu::PowerPreference::HighPerformance,
                    ..Default::default()
                })) {
                    Ok(a) => a,
                    Err(e) => {
                        last_err = e.to_string();
                        continue;
                    }
                };
            let info = adapter.get_info();
            let downlevel = adapter.get_downlevel_capabilities();
            if let Some(why) = unsuitable(downlevel.flags, &info.name) {
                last_err = why;
                continue;
            }
            let folder = cache::folder();
            let cached = match folder {
                Some(_) => wgpu::Features::PIPELINE_CACHE,
                None => wgpu::Features::empty(),
            };
            let (device, queue) =
                pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
                    label: Some("decalbake"),
                    required_features: adapter.features()
                        & (wgpu::Features::FLOAT32_FILTERABLE
                            | wgpu::Features::FLOAT32_BLENDABLE
                            | wgpu::Features::CLIP_DISTANCES
                            | wgpu::Features::TEXTURE_ADAPTER_SPECIFIC_FORMAT_FEATURES
                            | cached),
                    required_limits: adapter.limits(),
                    experimental_features: wgpu::ExperimentalFeatures::disabled(),
                    memory_hints: wgpu::MemoryHints::Performance,
                    trace: wgpu::Trace::Off,
                }))
                .map_err(|e| Error::DeviceCreation {
                    adapter: info.name.clone(),
                    detail: e.to_string(),
                })?;
            let pipeline_cache = match folder {
                None => (None, cache::Start::Off),
                Some(_) if !device.features().contains(wgpu::Features::PIPELINE_CACHE) => {
                    (None, cache::Start::Unsupported)
                }
                Some(f) => match cache::DiskCache::open(&device, &info, &f) {
                    Some((c, start)) => (Some(Arc::new(c)), start),
                    None => (None, cache::Start::Unsupported),
                },
            };
            let mut ctx = Self::from_device(device, queue, Some(info));
            ctx.pipeline_cache = pipeline_cache;
            ctx.startup_ms = start.elapsed().as_secs_f64() * 1e3;
            return Ok(ctx);
        }
        Err(Error::NoAdapter {
            backends: attempts
                .iter()
                .map(|b| format!("{b:?}"))
                .collect::<Vec<_>>()
                .join(" then "),
            detail: last_err,
        })
    }

    /// Wraps a host's device and queue. `info` names the adapter in reports (pass
    /// `adapter.get_info()`); without it the report says "host device".
    pub fn from_device(
        device: wgpu::Device,
        queue: wgpu::Queue,
        info: Option<wgpu::AdapterInfo>,
    ) -> Self {
        let lost = Arc::new(Mutex::new(None));
        let lost2 = lost.clone();
        device.set_device_lost_callback(move |reason, msg| {
            if let Ok(mut l) = lost2.lock() {
                *l = Some(if msg.is_empty() {
                    format!("{reason:?} (the device was destroyed or reset; bake on a new engine)")
                } else {
                    format!("{reason:?}: {msg}")
                });
            }
        });
        device.on_uncaptured_error(Arc::new(|e| {
            log::error!("uncaptured wgpu error: {e}");
        }));
        let backend = info.as_ref().map(|i| i.backend);
        let device_type = info.as_ref().map(|i| i.device_type);
        let adapter = match info {
            Some(i) => format!(
                "{} ({:?}, {:?}, {} {})",
                i.name, i.backend, i.device_type, i.driver, i.driver_info
            )
            .trim_end()
            .to_string(),
            None => "host device".to_string(),
        };
        Self {
            device_type,
            device,
            queue,
            adapter,
            backend,
            pipeline_cache: (None, cache::Start::Off),
            startup_ms: 0.0,
            lost,
        }
    }

    /// The most bytes one storage buffer may hold and bind on this device (the smaller of
    /// `max_buffer_size` and `max_storage_buffer_binding_size`), with the limit's name.
    pub fn storage_limit(&self) -> (u64, &'static str) {
        let l = self.device.limits();
        if l.max_storage_buffer_binding_size <= l.max_buffer_size {
            (
                l.max_storage_buffer_binding_size,
                "max_storage_buffer_binding_size",
            )
        } else {
            (l.max_buffer_size, "max_buffer_size")
        }
    }

    /// [`Error::DeviceLimit`] unless `bytes` fit one storage buffer ([`Self::storage_limit`]);
    /// checked before allocating, so a job too large for the device is a typed error, not a
    /// validation failure deep in a stage.
    pub fn fits(&self, what: impl FnOnce() -> String, bytes: u64, hint: &str) -> Result<()> {
        let (limit, limit_name) = self.storage_limit();
        if bytes > limit {
            return Err(Error::DeviceLimit {
                what: what(),
                needed: bytes,
                limit,
                limit_name,
                hint: hint.to_string(),
            });
        }
        Ok(())
    }

    /// The largest 2D texture side this device accepts.
    pub fn max_texture_side(&self) -> u32 {
        self.device.limits().max_texture_dimension_2d
    }

    /// Runs `f` inside validation and out-of-memory error scopes; a captured error becomes
    /// [`Error::Gpu`] naming `stage`.
    pub fn scoped<T>(&self, stage: &str, f: impl FnOnce() -> T) -> Result<T> {
        let oom = self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let val = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let out = f();
        let v = pollster::block_on(val.pop());
        let o = pollster::block_on(oom.pop());
        if let Some(e) = v.or(o) {
            return Err(self.gpu_error(stage, e));
        }
        self.check_lost(stage)?;
        Ok(out)
    }

    /// The error for a failed GPU operation: [`Error::DeviceLost`] when the device is gone (a
    /// destroyed device makes every later call fail validation, and the loss is the cause worth
    /// reporting), else [`Error::Gpu`] with `detail`.
    pub fn gpu_error(&self, stage: &str, detail: impl std::fmt::Display) -> Error {
        // The loss is delivered by a poll once the queue's work is done: a stage whose first
        // failure is a queue write (the CPU twins' uploads) has not waited since the device went
        // (a non-blocking poll left the loss undelivered under load).
        let _ = self.device.poll(wgpu::PollType::wait_indefinitely());
        match self.check_lost(stage) {
            Err(lost) => lost,
            Ok(()) => Error::Gpu {
                stage: stage.to_string(),
                detail: detail.to_string(),
            },
        }
    }

    /// True once the device is lost (destroyed by the host, driver reset): every later bake on
    /// this context fails with [`Error::DeviceLost`]; make a new engine.
    pub fn is_lost(&self) -> bool {
        self.lost.lock().map(|l| l.is_some()).unwrap_or(true)
    }

    /// Returns [`Error::DeviceLost`] if the device has been lost.
    pub fn check_lost(&self, stage: &str) -> Result<()> {
        if let Some(msg) = self.lost.lock().ok().and_then(|l| l.clone()) {
            return Err(Error::DeviceLost {
                stage: stage.to_string(),
                detail: msg,
            });
        }
        Ok(())
    }

    /// Blocks until all submitted work is done.
    pub fn wait(&self, stage: &str) -> Result<()> {
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| self.gpu_error(stage, e))?;
        self.check_lost(stage)
    }

    /// Copies `size` bytes of `src` (which needs `COPY_SRC`) to the CPU. One submit and one wait.
    pub fn read_buffer(&self, src: &wgpu::Buffer, size: u64, stage: &str) -> Result<Vec<u8>> {
        self.read_buffer_range(src, 0, size, stage)
    }

    /// Copies `size` bytes of `src` from `offset` (both multiples of 4) to the CPU.
    pub fn read_buffer_range(
        &self,
        src: &wgpu::Buffer,
        offset: u64,
        size: u64,
        stage: &str,
    ) -> Result<Vec<u8>> {
        self.read_range_with(src, offset, size, stage, |b| b.to_vec())
    }

    /// Copies `size` bytes of `src` (which needs `COPY_SRC`) to the CPU and hands them to `f`
    /// while mapped, without the copy into a `Vec` that [`Self::read_buffer`] makes (a tile's
    /// 64 MiB encode is unpacked straight from the mapping).
    pub fn read_buffer_with<R>(
        &self,
        src: &wgpu::Buffer,
        size: u64,
        stage: &str,
        f: impl FnOnce(&[u8]) -> R,
    ) -> Result<R> {
        self.read_range_with(src, 0, size, stage, f)
    }

    /// [`Self::read_buffer_with`] from `offset` (a multiple of 4).
    fn read_range_with<R>(
        &self,
        src: &wgpu::Buffer,
        offset: u64,
        size: u64,
        stage: &str,
        f: impl FnOnce(&[u8]) -> R,
    ) -> Result<R> {
        let staging = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("decalbake.readback"),
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut enc = self.device.create_command_encoder(&Default::default());
        enc.copy_buffer_to_buffer(src, offset, &staging, 0, size);
        self.queue.submit([enc.finish()]);
        self.map_with(&staging, stage, f)
    }

    /// Maps an already-filled `MAP_READ` buffer and returns its contents.
    pub fn map_and_read(&self, staging: &wgpu::Buffer, stage: &str) -> Result<Vec<u8>> {
        self.map_with(staging, stage, |b| b.to_vec())
    }

    /// Maps an already-filled `MAP_READ` buffer and hands its contents to `f`.
    pub(crate) fn map_with<R>(
        &self,
        staging: &wgpu::Buffer,
        stage: &str,
        f: impl FnOnce(&[u8]) -> R,
    ) -> Result<R> {
        let (tx, rx) = std::sync::mpsc::channel();
        staging.slice(..).map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        self.wait(stage)?;
        rx.recv()
            .map_err(|e| self.gpu_error(stage, e))?
            .map_err(|e| self.gpu_error(stage, e))?;
        let view = staging
            .slice(..)
            .get_mapped_range()
            .map_err(|e| self.gpu_error(stage, e))?;
        let out = f(&view);
        drop(view);
        staging.unmap();
        Ok(out)
    }
}

/// Why an adapter of these downlevel `flags` cannot bake (`None`: it can): the stages need
/// compute shaders, and the layer raster's fragment stage writes the compose's block mask
/// (`wgsl/shared/blocks.wgsl`), a storage buffer. Refused here, by name, rather than failing a
/// pipeline's validation in the middle of the first bake.
pub(crate) fn unsuitable(flags: wgpu::DownlevelFlags, adapter: &str) -> Option<String> {
    if !flags.contains(wgpu::DownlevelFlags::COMPUTE_SHADERS) {
        return Some(format!("adapter {adapter} has no compute shaders"));
    }
    if !flags.contains(wgpu::DownlevelFlags::FRAGMENT_WRITABLE_STORAGE) {
        return Some(format!(
            "adapter {adapter} cannot write storage buffers from fragment shaders, which the layer raster does"
        ));
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An adapter without compute shaders, or whose fragment stage cannot write storage
    /// buffers, is refused by name; one with both is taken.
    #[test]
    fn adapters_that_cannot_bake_are_named() {
        use wgpu::DownlevelFlags as F;
        let both = F::COMPUTE_SHADERS | F::FRAGMENT_WRITABLE_STORAGE;
        assert_eq!(unsuitable(both, "a"), None);
        let no_compute = unsuitable(F::FRAGMENT_WRITABLE_STORAGE, "a").unwrap();
        assert!(no_compute.contains("compute"), "{no_compute}");
        let no_writes = unsuitable(F::COMPUTE_SHADERS, "gles").unwrap();
        assert!(
            no_writes.contains("gles") && no_writes.contains("fragment"),
            "{no_writes}"
        );
    }
}
