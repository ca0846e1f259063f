// SPDX-License-Identifier: MIT OR Apache-2.0
//! Embedding: a host application's own wgpu device bakes a decal into a `wgpu::Texture` that
//! never leaves the GPU, then reads one texel back to show it is there; then keeps the bake live
//! and moves the decal, as an editor does when its user drags it.
//!
//! ```text
//! cargo run --example embed
//! ```

use decalbake::{Edit, Engine, Job};
use std::path::Path;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // The host's device, made the way a renderer makes its own (any backend wgpu offers).
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
        backends: wgpu::Backends::from_env().unwrap_or(wgpu::Backends::VULKAN | wgpu::Backends::GL),
        ..wgpu::InstanceDescriptor::new_without_display_handle()
    });
    let adapter = pollster::block_on(instance.request_adapter(&Default::default()))?;
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("host"),
        required_limits: adapter.limits(),
        ..Default::default()
    }))?;
    // The engine shares it: every buffer and texture it makes is the host's to use.
    let engine = Engine::from_adapter(&adapter, device.clone(), queue.clone())?;

    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mesh = engine.load_mesh(&root.join("assets/spot.glb"))?;
    let dir = std::env::temp_dir().join(format!("decalbake-embed-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    std::fs::write(dir.join("dot.png"), red_dot(64))?;
    // A red dot on Spot's left flank, 256² texels.
    let job = Job::parse(
        r#"{ "mesh": "spot.glb", "texture": { "width": 256, "height": 256 },
             "layers": [ { "image": "dot.png", "size": [0.4, 0.4],
                           "at": { "ray": { "origin": [1.5, 0.0, 0.45], "dir": [-1, 0, 0] } } } ] }"#,
        &dir.join("job.json"),
        &dir,
        &dir,
    )?;
    let (texture, report) = engine.bake_to_texture(&mesh, &job)?;
    let layer = &report.layers[0];
    println!(
        "baked {}×{} {:?}: {} triangles, {} texels covered",
        texture.width(),
        texture.height(),
        texture.format(),
        layer.triangles_covered,
        layer.texels_covered
    );

    // The host reads one covered texel back, as it would sample the texture in its own pass.
    let baked = engine.bake(&mesh, &job)?; // the same bake read back, to find a covered texel
    let (x, y) = reddest(&baked.rgba8(), 256);
    let texel = read_texel(&device, &queue, &texture, x, y);
    println!("texel ({x}, {y}) of the GPU texture: sRGB {texel:?}");
    assert_eq!(
        &texel[..],
        &baked.rgba8()[(y * 256 + x) as usize * 4..][..4]
    );

    // A live bake: the user drags the dot to Spot's other flank; only the cells it left and
    // the cells it reached are re-baked, and the texture is current when `apply` returns.
    let mut live = engine.live(&mesh, &job)?;
    let mut dot = live.job().layers[0].clone();
    dot.at = decalbake::io::at::AtSpec::Ray {
        ray: decalbake::io::at::RaySpec {
            origin: [-1.5, 0.0, 0.45],
            dir: [1.0, 0.0, 0.0],
        },
    };
    let edit = live.apply(Edit::Set {
        layer: 0,
        to: Box::new(dot),
    })?;
    let moved = engine.bake(&mesh, live.job())?.rgba8();
    let (nx, ny) = reddest(&moved, 256);
    let texel = read_texel(&device, &queue, live.texture(), nx, ny);
    let was = read_texel(&device, &queue, live.texture(), x, y);
    println!(
        "moved in {:.1} ms ({} cells re-composed): texel ({nx}, {ny}) now sRGB {texel:?}, ({x}, {y}) back to {was:?}",
        edit.place_ms + edit.maps_ms + edit.compose_ms + edit.encode_ms,
        edit.cells
    );
    assert_eq!(&texel[..], &moved[(ny * 256 + nx) as usize * 4..][..4]);
    assert_eq!(&was[..], &moved[(y * 256 + x) as usize * 4..][..4]);
    std::fs::remove_dir_all(&dir)?;
    Ok(())
}

/// A 16-bit RGBA PNG: an opaque red disc on a transparent square.
fn red_dot(n: u32) -> Vec<u8> {
    let mut samples = Vec::with_capacity((n * n * 4) as usize);
    for y in 0..n {
        for x in 0..n {
            let d = ((x as f32 + 0.5 - n as f32 / 2.0).hypot(y as f32 + 0.5 - n as f32 / 2.0))
                / (n as f32 / 2.0);
            let a = if d < 0.8 { u16::MAX } else { 0 };
            samples.extend_from_slice(&[u16::MAX, 0, 0, a]);
        }
    }
    decalbake::io::image::png_bytes(n, n, 16, &samples)
}

/// The texel whose red most exceeds its green (the dot's middle).
fn reddest(rgba: &[u8], width: u32) -> (u32, u32) {
    let i = (0..rgba.len() / 4)
        .max_by_key(|&i| rgba[i * 4] as i32 - rgba[i * 4 + 1] as i32)
        .unwrap_or(0) as u32;
    (i % width, i / width)
}

/// One texel of `texture` (RGBA8) copied to a buffer and mapped, as a host would.
fn read_texel(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    texture: &wgpu::Texture,
    x: u32,
    y: u32,
) -> [u8; 4] {
    let buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("one texel"),
        size: 256,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut encoder = device.create_command_encoder(&Default::default());
    encoder.copy_texture_to_buffer(
        wgpu::TexelCopyTextureInfo {
            texture,
            mip_level: 0,
            origin: wgpu::Origin3d { x, y, z: 0 },
            aspect: wgpu::TextureAspect::All,
        },
        wgpu::TexelCopyBufferInfo {
            buffer: &buffer,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(256),
                rows_per_image: None,
            },
        },
        wgpu::Extent3d {
            width: 1,
            height: 1,
            depth_or_array_layers: 1,
        },
    );
    queue.submit([encoder.finish()]);
    let slice = buffer.slice(..);
    slice.map_async(wgpu::MapMode::Read, |r| r.expect("mapping the texel"));
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .expect("the copy finishes");
    let bytes = slice.get_mapped_range().expect("the mapped texel");
    [bytes[0], bytes[1], bytes[2], bytes[3]]
}
