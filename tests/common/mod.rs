// SPDX-License-Identifier: MIT OR Apache-2.0
//! Helpers shared by the integration tests: a GPU engine, scratch directories, and small glTF files
//! written from code.
#![allow(dead_code, reason = "each test binary uses a different subset")]

use decalbake::io::image::LinearImage;
use decalbake::Engine;
use glam::Vec3;
use std::path::{Path, PathBuf};

/// An engine on the backend `WGPU_BACKEND` names (CI: vulkan = lavapipe).
pub fn engine() -> Engine {
    Engine::new(None).expect("a GPU adapter (install mesa-vulkan-drivers for lavapipe)")
}

/// An engine on a device whose limits are the adapter's as `lower` changes them (a smaller
/// device than the one the tests run on: tight buffers, fewer storage buffers a stage).
pub fn engine_with_limits(lower: impl FnOnce(&mut wgpu::Limits)) -> Engine {
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
        backends: wgpu::Backends::from_env().unwrap_or(wgpu::Backends::VULKAN),
        ..wgpu::InstanceDescriptor::new_without_display_handle()
    });
    let adapter =
        pollster::block_on(instance.request_adapter(&Default::default())).expect("an adapter");
    let mut limits = adapter.limits();
    lower(&mut limits);
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        required_features: adapter.features()
            & (wgpu::Features::FLOAT32_FILTERABLE | wgpu::Features::FLOAT32_BLENDABLE),
        required_limits: limits,
        ..Default::default()
    }))
    .unwrap();
    Engine::from_adapter(&adapter, device, queue).unwrap()
}

/// A fresh scratch directory for one test.
pub fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("decalbake-test-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The repository's test-data directory.
pub fn data(file: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(file)
}

/// Writes a non-manifold GLB without UVs: three triangles on one edge (a fin).
pub fn write_fin(path: &Path) {
    let pos = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.5, 1.0, 0.0],
        [0.5, -1.0, 0.0],
        [0.5, 0.0, 1.0],
    ];
    write_glb(path, &pos, None, &[0, 1, 2, 1, 0, 3, 0, 1, 4]);
}

/// Writes a minimal GLB: one primitive, no material.
pub fn write_glb(path: &Path, positions: &[[f32; 3]], uvs: Option<&[[f32; 2]]>, indices: &[u32]) {
    write_glb_with_normals(path, positions, None, uvs, indices);
}

/// [`write_glb`] with a `NORMAL` attribute where `normals` is given.
pub fn write_glb_with_normals(
    path: &Path,
    positions: &[[f32; 3]],
    normals: Option<&[[f32; 3]]>,
    uvs: Option<&[[f32; 2]]>,
    indices: &[u32],
) {
    let mut bin: Vec<u8> = Vec::new();
    let pos_bytes: &[u8] = bytemuck::cast_slice(positions);
    bin.extend_from_slice(pos_bytes);
    let mut views =
        vec![serde_json::json!({"buffer": 0, "byteOffset": 0, "byteLength": pos_bytes.len()})];
    let mut lo = [f32::MAX; 3];
    let mut hi = [f32::MIN; 3];
    for p in positions {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let mut accessors = vec![
        serde_json::json!({"bufferView": 0, "componentType": 5126, "count": positions.len(), "type": "VEC3", "min": lo, "max": hi}),
    ];
    let mut attributes = serde_json::json!({"POSITION": 0});
    // A float attribute: its bytes, view and accessor appended, named in `attributes`.
    let mut attribute = |name: &str, b: &[u8], count: usize, ty: &str| {
        let off = bin.len();
        bin.extend_from_slice(b);
        views.push(serde_json::json!({"buffer": 0, "byteOffset": off, "byteLength": b.len()}));
        accessors.push(serde_json::json!({"bufferView": views.len() - 1, "componentType": 5126, "count": count, "type": ty}));
        attributes[name] = serde_json::json!(accessors.len() - 1);
    };
    if let Some(n) = normals {
        attribute("NORMAL", bytemuck::cast_slice(n), n.len(), "VEC3");
    }
    if let Some(uv) = uvs {
        attribute("TEXCOORD_0", bytemuck::cast_slice(uv), uv.len(), "VEC2");
    }
    let off = bin.len();
    let ib: &[u8] = bytemuck::cast_slice(indices);
    bin.extend_from_slice(ib);
    views.push(serde_json::json!({"buffer": 0, "byteOffset": off, "byteLength": ib.len()}));
    accessors.push(serde_json::json!({"bufferView": views.len() - 1, "componentType": 5125, "count": indices.len(), "type": "SCALAR"}));
    let doc = serde_json::json!({
        "asset": {"version": "2.0"},
        "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": attributes, "indices": accessors.len() - 1}]}],
        "buffers": [{"byteLength": bin.len()}], "bufferViews": views, "accessors": accessors,
    });
    let mut json = serde_json::to_vec(&doc).unwrap();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::new();
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    std::fs::write(path, out).unwrap();
}

/// A small "open book": two 4×4-quad panels meeting at x = 0.5 (the right one tilted up), each its own
/// UV island, so the shared edge is a UV seam. Returns (positions, uvs, indices).
pub fn book_mesh() -> (Vec<[f32; 3]>, Vec<[f32; 2]>, Vec<u32>) {
    let n = 4;
    let mut pos = Vec::new();
    let mut uv = Vec::new();
    let mut idx = Vec::new();
    for panel in 0..2 {
        let base = pos.len() as u32;
        for j in 0..=n {
            for i in 0..=n {
                let s = i as f32 / n as f32;
                let t = j as f32 / n as f32;
                let x = 0.5 * panel as f32 + 0.5 * s;
                let z = if panel == 1 { 0.25 * s } else { 0.0 };
                pos.push([x, t, z]);
                let u0 = if panel == 0 { 0.1 } else { 0.55 };
                // v runs down the texture (glTF convention): top of the panel at small v.
                uv.push([u0 + 0.33 * s, 0.12 + 0.72 * (1.0 - t)]);
            }
        }
        for j in 0..n {
            for i in 0..n {
                let a = base + j * (n + 1) + i;
                let b = a + 1;
                let c = a + n + 1;
                let d = c + 1;
                idx.extend_from_slice(&[a, b, d, a, d, c]);
            }
        }
    }
    (pos, uv, idx)
}

/// The bundled Spot.
pub fn spot_asset() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/spot.glb")
}

/// The stage-path tests' start: `layers` on Spot (`spot_job_json`, seed 4, into `out.png`) in the
/// scratch folder `name`, an engine, the loaded mesh, and the bake at the engine's default paths.
pub fn spot_paths_bake(
    name: &str,
    layers: Vec<serde_json::Value>,
) -> (
    decalbake::Job,
    Engine,
    decalbake::bake::LoadedMesh,
    decalbake::bake::Baked,
) {
    let dir = scratch(name);
    let output = serde_json::json!({ "texture": "out.png" });
    let text = spot_job_json(&dir, 4, serde_json::Value::from(layers), output);
    let job = decalbake::Job::parse(&text.to_string(), &dir.join("job.json"), &dir, &dir).unwrap();
    let engine = engine();
    let mesh = engine.load_mesh(&spot_asset()).unwrap();
    let auto = engine.bake(&mesh, &job).unwrap();
    (job, engine, mesh, auto)
}

/// A 256² job on the bundled Spot with `layers` and `output`, its layers' `img.png` (a 32×32
/// `test_image` of `seed`, with alpha) written into `dir`.
pub fn spot_job_json(
    dir: &Path,
    seed: u32,
    layers: serde_json::Value,
    output: serde_json::Value,
) -> serde_json::Value {
    let image = test_image(32, 32, seed, true).encode_png(8);
    std::fs::write(dir.join("img.png"), image).unwrap();
    serde_json::json!({ "mesh": spot_asset(), "texture": { "width": 256, "height": 256 },
        "layers": layers, "output": output })
}

/// A deterministic pseudo-random image (xorshift), with smooth structure plus noise, alpha varying
/// when `alpha` is set.
pub fn test_image(w: u32, h: u32, seed: u32, alpha: bool) -> LinearImage {
    let mut s = seed.wrapping_mul(2654435761).max(1);
    let mut rnd = || {
        s ^= s << 13;
        s ^= s >> 17;
        s ^= s << 5;
        (s % 10000) as f32 / 10000.0
    };
    let mut img = LinearImage::solid(w, h, [0.0; 4]);
    for y in 0..h {
        for x in 0..w {
            let fx = x as f32 / w as f32;
            let fy = y as f32 / h as f32;
            let r = 0.5 + 0.45 * (6.0 * fx + seed as f32).sin();
            let g = 0.5 + 0.45 * (5.0 * fy).cos();
            let b = 0.3 * rnd() + 0.6 * fx * fy;
            let a = if alpha {
                (0.2 + 0.8 * ((3.0 * fx).sin() * (3.0 * fy).sin()).abs()).min(1.0)
            } else {
                1.0
            };
            img.pixels[(y * w + x) as usize] = [r, g, b, a];
        }
    }
    img
}

/// Runs the CLI, returning (exit code, stdout, stderr).
pub fn cli(args: &[&str]) -> (i32, String, String) {
    cli_env(args, &[])
}

/// Runs `decalbake bake JOB` (`command` "bake") or `decalbake batch` of a manifest naming `job`
/// alone, written beside it (`command` "batch"): (exit code, stdout, stderr).
pub fn bake_or_batch(command: &str, job: &Path) -> (i32, String, String) {
    match command {
        "bake" => cli(&["bake", job.to_str().unwrap()]),
        _ => {
            let manifest = job.with_extension("manifest.jsonl");
            let line = serde_json::json!(job.to_str().unwrap());
            std::fs::write(&manifest, format!("{line}\n")).unwrap();
            cli(&["batch", manifest.to_str().unwrap()])
        }
    }
}

/// The names of the files in `dir` that start with `prefix`, sorted.
pub fn files_starting(dir: &Path, prefix: &str) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with(prefix))
        .collect();
    names.sort();
    names
}

/// Runs the CLI with `envs` added to its environment: (exit code, stdout, stderr).
pub fn cli_env(args: &[&str], envs: &[(&str, &str)]) -> (i32, String, String) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_decalbake"))
        .args(args)
        .envs(envs.iter().copied())
        .output()
        .expect("runs the CLI");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Runs `decalbake param JOB --layer LAYER --out OUT`: (exit code, stdout, stderr).
pub fn param(job: &Path, layer: &str, out: &Path) -> (i32, String, String) {
    cli(&[
        "param",
        job.to_str().unwrap(),
        "--layer",
        layer,
        "--out",
        out.to_str().unwrap(),
    ])
}

/// An open cylinder of radius 1 and height 2, `n` segments around and `m` along.
pub fn cylinder(n: u32, m: u32) -> decalbake::mesh::Mesh {
    let mut pos = Vec::new();
    let mut tris = Vec::new();
    for j in 0..=m {
        for i in 0..n {
            let a = i as f32 / n as f32 * std::f32::consts::TAU;
            pos.push(Vec3::new(
                a.cos(),
                a.sin(),
                -1.0 + 2.0 * j as f32 / m as f32,
            ));
        }
    }
    for j in 0..m {
        for i in 0..n {
            let (a, b) = (j * n + i, j * n + (i + 1) % n);
            let (c, d) = (a + n, b + n);
            tris.push([a, b, d]);
            tris.push([a, d, c]);
        }
    }
    let normals = pos
        .iter()
        .map(|p| Vec3::new(p.x, p.y, 0.0).normalize())
        .collect();
    let uv = vec![glam::Vec2::ZERO; pos.len()];
    decalbake::mesh::Mesh {
        source: "cylinder".into(),
        positions: pos,
        normals,
        uv_sets: vec![uv],
        triangles: tris,
        primitives: vec![],
        material: None,
        blend: Vec::new(),
        bridge: Vec::new(),
        ..Default::default()
    }
}
/// The unit square at z = 0 in `n` × `n` cells, normal +z, UV (x, 1 - y) (image up is +y) or,
/// `mirrored`, (1 - x, 1 - y); counter-clockwise seen from +z.
pub fn write_plane(path: &Path, n: u32, mirrored: bool) {
    let mut pos = Vec::new();
    let mut uv = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (x, y) = (i as f32 / n as f32, j as f32 / n as f32);
            pos.push([x, y, 0.0]);
            uv.push([if mirrored { 1.0 - x } else { x }, 1.0 - y]);
        }
    }
    let mut idx = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let a = j * (n + 1) + i;
            let (b, c, d) = (a + 1, a + n + 1, a + n + 2);
            idx.extend([a, b, d, a, d, c]);
        }
    }
    write_glb(path, &pos, Some(&uv), &idx);
}

/// A 16-bit RGBA PNG of `f(s, t)` at `side`² texels (t down the image), written as stored (no
/// sRGB encoding): data and normal maps.
pub fn write_raw_png(path: &Path, side: u32, f: impl Fn(f32, f32) -> [f32; 4]) {
    let mut samples = Vec::new();
    for y in 0..side {
        for x in 0..side {
            let (s, t) = (
                (x as f32 + 0.5) / side as f32,
                (y as f32 + 0.5) / side as f32,
            );
            samples.extend(f(s, t).map(|v| (v.clamp(0.0, 1.0) * 65535.0).round() as u16));
        }
    }
    std::fs::write(
        path,
        decalbake::io::image::png_bytes(side, side, 16, &samples),
    )
    .unwrap();
}

/// 24 exponential-map decals of `image`, `size` square, aimed by rays round Spot's body in a
/// wave (neighbours overlap): the many-layer job of the reliability and determinism tests.
pub fn spot_ring(image: &str, size: f32) -> Vec<serde_json::Value> {
    (0..24)
        .map(|i| {
            let t = i as f32 * 0.26;
            let y = 0.1 + 0.15 * (2.0 * t).sin();
            let origin = [2.0 * t.cos(), y, 0.2 + 2.0 * t.sin()];
            let dir = [-origin[0], 0.0, 0.2 - origin[2]];
            serde_json::json!({ "image": image, "method": "expmap", "size": [size, size],
                "at": { "ray": { "origin": origin, "dir": dir } } })
        })
        .collect()
}

/// How many values of two textures' texels differ, and by at most how much (printed: the
/// tests that compare two paths of one bake quote it).
pub fn value_diffs(a: &[u16], b: &[u16]) -> (usize, u16) {
    let diffs: Vec<u16> = a
        .iter()
        .zip(b)
        .map(|(x, y)| x.abs_diff(*y))
        .filter(|d| *d > 0)
        .collect();
    let worst = diffs.iter().copied().max().unwrap_or(0);
    println!(
        "{} of {} values differ between the paths, worst {worst}",
        diffs.len(),
        a.len()
    );
    (diffs.len(), worst)
}

pub mod rich;

/// Peak resident memory of this process (`VmHWM`), bytes.
pub fn peak_resident() -> u64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap();
    let line = status.lines().find(|l| l.starts_with("VmHWM:")).unwrap();
    line.split_whitespace()
        .nth(1)
        .unwrap()
        .parse::<u64>()
        .unwrap()
        * 1024
}

/// An RGBA8 texture of `engine`'s device read back as a host would (a copy into a mappable
/// buffer of 256-byte-aligned rows), its rows packed tightly: 4 bytes a texel.
pub fn read_rgba8_texture(engine: &Engine, texture: &wgpu::Texture) -> Vec<u8> {
    let (device, queue) = (&engine.ctx.device, &engine.ctx.queue);
    let [w, h] = [texture.width(), texture.height()];
    let row = (w * 4).next_multiple_of(256);
    let buf = device.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size: (row * h) as u64,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut enc = device.create_command_encoder(&Default::default());
    enc.copy_texture_to_buffer(
        texture.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer: &buf,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(row),
                rows_per_image: None,
            },
        },
        texture.size(),
    );
    queue.submit([enc.finish()]);
    let bytes = engine.ctx.map_and_read(&buf, "test read-back").unwrap();
    (0..h as usize)
        .flat_map(|y| bytes[y * row as usize..][..w as usize * 4].to_vec())
        .collect()
}
