// SPDX-License-Identifier: MIT OR Apache-2.0
//! `decalbake fuzz` (`src/cli/fuzz/`): every input that made a parser panic, hang or allocate past
//! the cap is replayed, each with a named test of the error it now gives; CI's short run; and the
//! harness's own failure paths (a panic, a hang, an allocation past the cap, a death), each shown
//! to fail the run and to keep its input. No GPU.

mod common;

use common::{cli, scratch};
use decalbake::io::image::LinearImage;
use decalbake::mesh::{Mesh, Topology, DEFAULT_WELD_TOLERANCE};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

/// `tests/fuzz/regressions`: one folder per target, one input per file (`INDEX.md` says what each
/// did to the unfixed code).
fn regressions() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz/regressions")
}

/// The JSON lines `decalbake fuzz` printed: (target line, total line).
fn lines(stdout: &str) -> Vec<serde_json::Value> {
    stdout
        .lines()
        .filter_map(|l| serde_json::from_str(l).ok())
        .collect()
}

/// The replay of every regression input through its target: no panic, hang or allocation past
/// the cap. Checked against the library before the fixes (the harness's commit with the fixes
/// stashed, each file replayed on its own): 19 of the 20 inputs fail, 13 with a panic and 6 past
/// the allocation cap (4 of which abort the process); the 20th, `glb/node-transform-overflows`,
/// loaded as a mesh whose every triangle is degenerate (`INDEX.md`, file by file).
#[test]
fn every_regression_replays_clean() {
    let dir = scratch("fuzz-replay");
    let (code, out, err) = cli(&[
        "fuzz",
        "--replay",
        regressions().to_str().unwrap(),
        "--findings",
        dir.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{out}\n{err}");
    let total = lines(&out).pop().expect("a total line");
    assert_eq!(total["findings"], 0, "{out}");
    let files = std::fs::read_dir(regressions())
        .unwrap()
        .filter_map(|d| d.ok())
        .filter(|d| d.path().is_dir())
        .map(|d| std::fs::read_dir(d.path()).unwrap().count())
        .sum::<usize>();
    assert_eq!(total["replayed"], files as u64, "{out}");
}

/// CI's short run: 20,000 executions over the five targets, seed 1, no finding. Its time is
/// printed (a few seconds in the test profile; well under 30 s).
#[test]
fn a_short_run_finds_nothing() {
    let dir = scratch("fuzz-short");
    let t = Instant::now();
    let (code, out, err) = cli(&[
        "fuzz",
        "--target",
        "all",
        "--execs",
        "20000",
        "--seed",
        "1",
        "--findings",
        dir.to_str().unwrap(),
    ]);
    eprintln!("short run: {:.1} s", t.elapsed().as_secs_f64());
    assert_eq!(code, 0, "{out}\n{err}");
    let l = lines(&out);
    assert_eq!(l.len(), 6, "five targets and the total: {out}");
    let total = &l[5];
    assert_eq!(total["target"], "total");
    assert_eq!(total["execs"], 20_000);
    assert_eq!(total["findings"], 0, "{out}\n{err}");
    for t in &l[..5] {
        assert!(
            t["accepted"].as_u64().unwrap() > 0,
            "some inputs parse: {t}"
        );
        assert!(t["peak_alloc_mib"].as_f64().unwrap() < 1024.0, "{t}");
    }
    assert!(
        !dir.join(".in-flight").exists(),
        "a clean end leaves no input in flight"
    );
}

/// `decalbake fuzz --target selftest` with the seed `seed`: (exit code, stdout, stderr).
fn selftest(seed: &str, findings: &Path, extra: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_decalbake"))
        .args([
            "fuzz",
            "--target",
            "selftest",
            "--execs",
            "20",
            "--findings",
        ])
        .arg(findings)
        .args(extra)
        .env("DECALBAKE_FUZZ_SELFTEST", seed)
        .output()
        .expect("runs the CLI");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The finding files a run left for the self-test, and the kinds `findings.jsonl` recorded.
fn findings_of(dir: &Path) -> (Vec<Vec<u8>>, Vec<String>) {
    let files = std::fs::read_dir(dir.join("selftest"))
        .map(|d| {
            d.filter_map(|e| e.ok())
                .map(|e| std::fs::read(e.path()).unwrap())
                .collect()
        })
        .unwrap_or_default();
    let kinds = std::fs::read_to_string(dir.join("findings.jsonl"))
        .unwrap_or_default()
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap()["kind"].to_string())
        .collect();
    (files, kinds)
}

/// A panic is caught, its input saved, the run goes on and exits 1.
#[test]
fn a_panic_is_saved_and_the_run_goes_on() {
    let dir = scratch("fuzz-panic");
    let (code, out, err) = selftest("p", &dir, &[]);
    assert_eq!(code, 1, "{out}\n{err}");
    let l = lines(&out);
    assert_eq!(l[0]["execs"], 20, "the run went on after the panic: {out}");
    assert!(err.contains("selftest: a panic"), "{err}");
    let (files, kinds) = findings_of(&dir);
    assert!(
        files.iter().any(|f| f == b"p"),
        "the seed that panicked is saved"
    );
    assert!(kinds.iter().all(|k| k == "\"panic\""), "{kinds:?}");
}

/// An execution past `--timeout-ms` is a hang: its input saved, the figures printed, exit 1.
#[test]
fn a_hang_is_saved_and_stops_the_run() {
    let dir = scratch("fuzz-hang");
    let t = Instant::now();
    let (code, out, err) = selftest("h", &dir, &["--timeout-ms", "300"]);
    assert!(t.elapsed() < Duration::from_secs(20));
    assert_eq!(code, 1, "{out}\n{err}");
    assert!(err.contains("finding (hang)"), "{err}");
    assert_eq!(lines(&out).last().unwrap()["findings"], 1, "{out}");
    let (files, kinds) = findings_of(&dir);
    assert_eq!(
        (files, kinds),
        (vec![b"h".to_vec()], vec!["\"hang\"".to_string()])
    );
    assert!(
        !dir.join(".in-flight").exists(),
        "filed once, not again as `died`"
    );
}

/// An allocation past the cap that the caller cannot survive (a plain `vec!`) aborts the process,
/// with the input saved by the allocator before it refused the request.
#[test]
fn an_allocation_past_the_cap_is_saved_before_the_abort() {
    let dir = scratch("fuzz-alloc");
    let (code, _, err) = selftest("a", &dir, &["--max-alloc-mib", "64"]);
    assert_ne!(code, 0, "{err}");
    assert!(err.contains("above the cap of 67108864 bytes"), "{err}");
    let (files, kinds) = findings_of(&dir);
    assert_eq!(
        (files, kinds),
        (vec![b"a".to_vec()], vec!["\"alloc\"".to_string()])
    );
    // The next run does not file it again as `died`.
    let (code, out, _) = selftest("ok", &dir, &[]);
    assert_eq!(code, 0, "{out}");
}

/// A refused allocation the caller copes with (`try_reserve`) is a finding, and the run goes on.
#[test]
fn a_refused_fallible_allocation_is_a_finding_and_the_run_goes_on() {
    let dir = scratch("fuzz-reserve");
    let (code, out, err) = selftest("r", &dir, &["--max-alloc-mib", "64"]);
    assert_eq!(code, 1, "{out}\n{err}");
    let l = lines(&out);
    assert_eq!(l[0]["execs"], 20, "{out}");
    assert!(l[0]["findings"].as_u64().unwrap() >= 1, "{out}");
    let (files, _) = findings_of(&dir);
    assert!(files.iter().any(|f| f == b"r"), "{err}");
}

/// A death nothing in the process saw (here: an in-flight record left as a killed run leaves
/// it) is filed by the next run as a finding of kind `died`.
#[test]
fn an_input_left_in_flight_is_filed_by_the_next_run() {
    let dir = scratch("fuzz-died");
    let mut rec = b"DBFZ\x08selftest".to_vec();
    rec.extend_from_slice(&3u32.to_le_bytes());
    rec.extend_from_slice(b"xyz");
    std::fs::write(dir.join(".in-flight"), rec).unwrap();
    let (code, out, err) = selftest("ok", &dir, &[]);
    assert_eq!(code, 1, "{out}\n{err}");
    let (files, kinds) = findings_of(&dir);
    assert_eq!(
        (files, kinds),
        (vec![b"xyz".to_vec()], vec!["\"died\"".to_string()])
    );
}

/// The error a regression input of a mesh target now gives (the library, as the fuzz target calls
/// it: no base directory, then welding).
fn mesh_error(file: &str) -> String {
    let bytes = std::fs::read(regressions().join(file)).unwrap();
    match Mesh::from_bytes(&bytes, Path::new(file), None) {
        Ok(m) => {
            let _ = Topology::build(&m, DEFAULT_WELD_TOLERANCE);
            "ok".into()
        }
        Err(e) => e.to_string(),
    }
}

/// A named test per regression input: the file, and what its error must say.
macro_rules! mesh_regression {
    ($name:ident, $file:literal, $($needle:literal),+) => {
        #[test]
        fn $name() {
            let e = mesh_error($file);
            for needle in [$($needle),+] {
                assert!(e.contains(needle), "{}: {e}", $file);
            }
        }
    };
}

mesh_regression!(
    glb_header_length_below_12,
    "glb/header-length-below-12",
    "header declares a length of 0 bytes"
);
mesh_regression!(
    glb_position_accessor_missing,
    "glb/position-accessor-missing",
    "attributes.POSITION is accessor 2147483648, but the file has 4 accessors"
);
mesh_regression!(
    glb_accessor_count_zero,
    "glb/accessor-count-zero",
    "indices (accessors[2]) declares 0 elements"
);
mesh_regression!(
    glb_accessor_count_overflows_stride,
    "glb/accessor-count-overflows-stride",
    "POSITION (accessors[0]) declares 9223372036854775807 elements"
);
mesh_regression!(
    glb_accessor_wrong_type,
    "glb/accessor-wrong-type",
    "TEXCOORD_1 (accessors[4]) is SCALAR of UNSIGNED_SHORT (5123)",
    "VEC2 of FLOAT (5126)"
);
mesh_regression!(
    glb_indices_wrong_component_type,
    "glb/indices-wrong-component-type",
    "indices (accessors[3]) is VEC3 of FLOAT (5126)"
);
mesh_regression!(
    glb_texcoord_count_mismatch,
    "glb/texcoord-count-mismatch",
    "has 6 POSITION elements but 2 TEXCOORD_0 elements"
);
mesh_regression!(
    glb_sparse_accessor_huge_count,
    "glb/sparse-accessor-huge-count",
    "TEXCOORD_0 (accessors[1]) declares 9007199254740992 elements",
    "1 to 16777216"
);
mesh_regression!(
    glb_image_without_source,
    "glb/image-without-source",
    "images[0] has neither a uri nor a bufferView"
);
mesh_regression!(
    glb_image_view_past_buffer,
    "glb/image-view-past-buffer",
    "bufferViews[5] (bytes 260 to 4492) runs past the end of buffers[0] (396 bytes)"
);
mesh_regression!(
    glb_node_cycle,
    "glb/node-cycle",
    "nodes[0] is reached twice from scenes[0]"
);
mesh_regression!(
    glb_node_transform_overflows,
    "glb/node-transform-overflows",
    "POSITION[0] is [inf",
    "after its node transforms (not finite)"
);
mesh_regression!(
    glb_texture_jpeg_claims_8192_square,
    "glb/texture-jpeg-claims-8192-square",
    "images[0]",
    "8192 x 8193 pixels is above decalbake's image limits"
);
mesh_regression!(glb_weld_cell_overflow, "glb/weld-cell-overflow", "ok");
mesh_regression!(
    gltf_texcoord_wrong_component_type,
    "gltf/texcoord-wrong-component-type",
    "TEXCOORD_1 (accessors[3]) is VEC2 of UNSIGNED_INT (5125)"
);
mesh_regression!(
    gltf_image_without_uri,
    "gltf/image-without-uri",
    "images[0] has neither a uri nor a bufferView"
);
mesh_regression!(
    gltf_buffer_uri_not_utf8,
    "gltf/buffer-uri-not-utf8",
    "buffers[1].uri \"mesh%FF.bin\" does not percent-decode to UTF-8"
);
mesh_regression!(
    gltf_image_uri_reads_dev_zero,
    "gltf/image-uri-reads-dev-zero",
    "is an external file, but the mesh was read from memory"
);

/// The error a regression input of the image target now gives.
fn image_error(file: &str) -> String {
    let bytes = std::fs::read(regressions().join(file)).unwrap();
    LinearImage::decode(&bytes).map_or_else(|e| e, |_| "ok".into())
}

#[test]
fn image_jpeg_claims_8192_square() {
    let e = image_error("image/jpeg-claims-8192-square");
    assert!(
        e.contains("8192 x 8193 pixels is above decalbake's image limits"),
        "{e}"
    );
}

#[test]
fn image_jpeg_grey_claims_16384_square() {
    let e = image_error("image/jpeg-grey-claims-16384-square");
    assert!(e.contains("16384 x 16384 pixels"), "{e}");
}

/// A JPEG wider than 16384 pixels stops at the decoder's own limit, which the message names.
#[test]
fn image_wider_than_the_limit_names_it() {
    let mut jpeg = std::fs::read(regressions().join("image/jpeg-claims-8192-square")).unwrap();
    // The frame header (SOF0) holds height and width, big-endian, after its length and precision.
    let sof = jpeg.windows(2).position(|w| w == [0xff, 0xc0]).unwrap();
    jpeg[sof + 7..sof + 9].copy_from_slice(&20000u16.to_be_bytes());
    jpeg[sof + 5..sof + 7].copy_from_slice(&100u16.to_be_bytes());
    let e = LinearImage::decode(&jpeg).unwrap_err();
    assert!(e.contains("16384 pixels a side"), "{e}");
}

/// From a file (with a base directory), an external file that is a device is refused before the
/// `gltf` crate reads it forever.
#[test]
fn an_external_device_file_is_refused() {
    let dir = scratch("fuzz-dev-zero");
    let f = dir.join("dev-zero.gltf");
    std::fs::copy(regressions().join("gltf/image-uri-reads-dev-zero"), &f).unwrap();
    let t = Instant::now();
    let e = Mesh::load(&f).unwrap_err().to_string();
    assert!(t.elapsed() < Duration::from_secs(10));
    assert!(
        e.contains("\"file:///dev/zero\" is /dev/zero, which is not a regular file"),
        "{e}"
    );
}
