// SPDX-License-Identifier: MIT OR Apache-2.0
//! Compressed geometry bakes like the uncompressed original: the bundled crumpled sheet and its
//! copies made by gltf-transform (`tests/data/compressed/make.sh`: `draco`, `meshopt`, `quantize`)
//! bake the same texture with the same job, and the model written is the decoded document.

mod common;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

/// A 64² decal image with detail at every scale (a gradient under a checker of 8-texel squares),
/// so that a decal moved by a fraction of a texel changes texels along every edge of it.
fn write_image(dir: &Path) -> PathBuf {
    let px: Vec<u16> = (0..64u32 * 64)
        .flat_map(|i| {
            let (x, y) = (i % 64, i / 64);
            let check = ((x / 8 + y / 8) % 2) as u16 * 120;
            [20 + check, (x * 3) as u16 + 30, (y * 3) as u16 + 30, 255]
        })
        .collect();
    let path = dir.join("decal.png");
    std::fs::write(&path, decalbake::io::image::png_bytes(64, 64, 8, &px)).unwrap();
    path
}

/// Bakes `mesh` in `dir` with one planar and one exponential-map decal on the sheet; returns the
/// baked texture's RGBA8 texels and the written model's path.
fn bake(dir: &Path, mesh: &Path) -> (Vec<u8>, PathBuf) {
    let image = write_image(dir);
    let job = json!({
        "mesh": mesh,
        "texture": {"width": 256, "height": 256, "base": [0.5, 0.5, 0.5, 1.0], "padding": 2},
        "layers": [
            {"kind": "decal", "image": image, "at": [0.2, 0.0, 0.15], "size": [0.7, 0.7],
             "up": [0, 0, 1], "method": "planar"},
            {"kind": "decal", "image": image, "at": [-0.3, 0.0, -0.3], "size": [0.5, 0.5],
             "up": [1, 0, 0], "method": "expmap"}
        ],
        "output": {"texture": "baked.png", "glb": "out.glb"}
    });
    let path = dir.join("job.json");
    std::fs::write(&path, serde_json::to_vec_pretty(&job).unwrap()).unwrap();
    let (code, _, err) = common::cli(&["bake", path.to_str().unwrap()]);
    assert_eq!(code, 0, "{}: {err}", mesh.display());
    let baked = image::open(dir.join("baked.png")).unwrap().to_rgba8();
    (baked.into_raw(), dir.join("out.glb"))
}

/// The JSON chunk of a `.glb`.
fn glb_json(path: &Path) -> Value {
    let b = std::fs::read(path).unwrap();
    let len = u32::from_le_bytes(b[12..16].try_into().unwrap()) as usize;
    serde_json::from_slice(&b[20..20 + len]).unwrap()
}

/// Texels (of 256²) whose largest channel difference exceeds `levels`, and the largest one.
fn differing(a: &[u8], b: &[u8], levels: u8) -> (usize, u8) {
    assert_eq!(a.len(), b.len());
    let diffs: Vec<u8> = a
        .chunks_exact(4)
        .zip(b.chunks_exact(4))
        .map(|(p, q)| (0..4).map(|k| p[k].abs_diff(q[k])).max().unwrap())
        .collect();
    (
        diffs.iter().filter(|&&d| d > levels).count(),
        diffs.iter().copied().max().unwrap(),
    )
}

/// Each copy against the original. The copies' vertices are not the original's bit for bit, so
/// the comparison has a tolerance, per copy:
///
/// - `quantized` and `meshopt` (which quantizes the same way before compressing) store positions
///   as 16-bit normalised integers under a node scale: a vertex moves by up to 1/65,534 of the
///   sheet, and the UVs stay floats. Only a texel whose sample falls that close to an edge (a
///   decal's, a checker square's, a triangle's) can change: at most 0.1 % of the 65,536 texels
///   (65) may differ by more than 2 levels of 255. Measured: 21 (the largest 81 levels), the
///   same for both.
/// - `draco` quantizes positions to 14 bits and UVs to 12 bits over their range, which on this
///   sheet is 2.7 wide (its UVs wrap the texture): a UV moves by up to 3.3e-4, 0.08 texel at 256²,
///   which shifts every sharp edge of the baked image (the checker's 120-level steps, about two
///   texels wide) by up to about 5 levels everywhere. So at most 0.5 % of the texels (327) may
///   differ by more than 8 levels. Measured: 123 (1,302 by more than 2; the largest 153).
///
/// A decoder that gives wrong geometry moves or loses whole decals: thousands of texels.
#[test]
fn compressed_copies_bake_like_the_original() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = common::scratch("compressed-original");
    let (reference, _) = bake(&dir, &root.join("assets/crumpled_developable.glb"));
    // The decals are on the sheet: most texels are not the base's colour (the commonest one).
    let mut counts = std::collections::HashMap::new();
    for p in reference.chunks_exact(4) {
        *counts.entry(p).or_insert(0usize) += 1;
    }
    let base = counts
        .into_iter()
        .max_by_key(|&(_, n)| n)
        .unwrap()
        .0
        .to_vec();
    let (covered, _) = differing(&reference, &base.repeat(256 * 256), 8);
    assert!(covered > 20000, "the decals cover {covered} texels");
    let mut report = Vec::new();
    for (copy, ext) in [
        ("draco", "KHR_draco_mesh_compression"),
        ("meshopt", "EXT_meshopt_compression"),
        ("quantized", "KHR_mesh_quantization"),
    ] {
        let src = common::data(&format!("compressed/crumpled-{copy}.glb"));
        assert!(
            glb_json(&src)["extensionsRequired"]
                .as_array()
                .is_some_and(|r| r.contains(&json!(ext))),
            "{copy} requires {ext}"
        );
        let dir = common::scratch(&format!("compressed-{copy}"));
        let (baked, model) = bake(&dir, &src);
        let (levels, most) = if copy == "draco" { (8, 327) } else { (2, 65) };
        let (n, largest) = differing(&reference, &baked, levels);
        report.push(format!(
            "{copy}: {n} texels differ by more than {levels} levels (at most {most}; the largest by {largest})"
        ));
        assert!(n <= most, "{report:#?}");
        // The model written is the decoded document: no compression left, and valid glTF.
        let out = glb_json(&model);
        let text = out.to_string();
        for ext in [
            "KHR_draco_mesh_compression",
            "EXT_meshopt_compression",
            "KHR_mesh_quantization",
        ] {
            assert!(
                !text.contains(ext),
                "{copy}: the written model still names {ext}"
            );
        }
        common::rich::validate(&model);
    }
    eprintln!("the decals cover {covered} texels; {report:#?}");
}

/// A Draco stream cut short is refused (exit 2) naming the primitive it belongs to.
#[test]
fn a_truncated_draco_view_is_refused_naming_its_primitive() {
    let dir = common::scratch("compressed-truncated");
    let b = std::fs::read(common::data("compressed/crumpled-draco.glb")).unwrap();
    let len = u32::from_le_bytes(b[12..16].try_into().unwrap()) as usize;
    let mut json: Value = serde_json::from_slice(&b[20..20 + len]).unwrap();
    let bin = &b[20 + len + 8..];
    let view = json["bufferViews"][0]["byteLength"].as_u64().unwrap();
    json["bufferViews"][0]["byteLength"] = json!(view / 2);
    json["buffers"][0]["uri"] = json!("truncated.bin");
    std::fs::write(dir.join("truncated.bin"), bin).unwrap();
    let path = dir.join("truncated.gltf");
    std::fs::write(&path, serde_json::to_vec(&json).unwrap()).unwrap();
    let (code, _, err) = common::cli(&["info", path.to_str().unwrap()]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("meshes[0].primitives[0] KHR_draco_mesh_compression")
            && err.contains("does not decode"),
        "{err}"
    );
}
