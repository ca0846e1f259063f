// SPDX-License-Identifier: MIT OR Apache-2.0
//! `decalbake batch`: a failing job is reported and the others baked (exit 3), `--resume` skips
//! what is done and redoes what changed, shards cover the manifest once and merge, outputs are the
//! bytes `decalbake bake` writes for the same job, and a bad manifest stops everything (exit 2).

mod common;
use common::*;
use serde_json::Value;
use std::path::Path;

/// Spot, an image and a manifest of four jobs: a job file (line 1), an inline job (line 2), a job
/// whose image is missing (line 4, after a blank line) and an inline job on a second image (line 5).
fn setup(name: &str) -> std::path::PathBuf {
    let dir = scratch(name);
    let spot = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/spot.glb");
    std::fs::copy(spot, dir.join("spot.glb")).unwrap();
    std::fs::write(
        dir.join("img.png"),
        test_image(16, 16, 3, true).encode_png(8),
    )
    .unwrap();
    std::fs::write(
        dir.join("img2.png"),
        test_image(16, 16, 9, true).encode_png(8),
    )
    .unwrap();
    let job = |img: &str, at: [f32; 3], out: &str| {
        serde_json::json!({ "mesh": "spot.glb", "texture": { "width": 64, "height": 64, "padding": 2 },
            "layers": [{ "image": img, "at": at, "size": [0.3, 0.3], "method": "expmap" }],
            "output": { "texture": format!("{out}.png"), "report": format!("{out}.report.json") } })
    };
    std::fs::write(
        dir.join("a.json"),
        job("img.png", [0.17745, 0.95365, -0.26041], "a").to_string(),
    )
    .unwrap();
    let lines = [
        "\"a.json\"".to_string(),
        job("img.png", [0.5, 0.3, 0.2], "b").to_string(),
        String::new(),
        job("missing.png", [0.5, 0.3, 0.2], "c").to_string(),
        job("img2.png", [0.0, 0.5, 0.5], "d").to_string(),
    ];
    std::fs::write(dir.join("manifest.jsonl"), lines.join("\n")).unwrap();
    dir
}

fn summary(path: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

/// `decalbake batch --summary OUT --merge-summaries PARTS..`: (exit code, stdout, stderr).
fn merge(out: &Path, parts: &[std::path::PathBuf]) -> (i32, String, String) {
    let mut args = vec![
        "batch",
        "--summary",
        out.to_str().unwrap(),
        "--merge-summaries",
    ];
    args.extend(parts.iter().map(|p| p.to_str().unwrap()));
    cli(&args)
}

fn statuses(s: &Value) -> Vec<(u64, String)> {
    s["jobs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|j| {
            (
                j["line"].as_u64().unwrap(),
                j["status"].as_str().unwrap().to_string(),
            )
        })
        .collect()
}

#[test]
fn a_batch_isolates_failures_resumes_and_writes_what_bake_writes() {
    let dir = setup("batch_resume");
    let (m, out) = (dir.join("manifest.jsonl"), dir.join("out"));
    let run = |extra: &[&str]| {
        let mut args = vec!["batch", m.to_str().unwrap(), "--out", out.to_str().unwrap()];
        args.extend_from_slice(extra);
        cli(&args)
    };
    let (code, stdout, err) = run(&["--progress", "json"]);
    assert_eq!(code, 3, "some job failed: {err}");
    // --progress json: one event per job on stdout, then the counts.
    let events: Vec<Value> = stdout
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(events.len(), 5, "{stdout}");
    assert!(events[..4]
        .iter()
        .all(|e| e["event"] == "job" && e["total"] == 4));
    assert_eq!(events[2]["status"], "failed");
    assert_eq!(events[4]["event"], "done");
    assert_eq!(events[4]["counts"]["ok"], 3);
    let s = summary(&out.join("summary.json"));
    assert_eq!(
        statuses(&s),
        [(1, "ok"), (2, "ok"), (4, "failed"), (5, "ok")].map(|(l, s)| (l, s.to_string()))
    );
    let failed = &s["jobs"][2];
    assert_eq!(failed["class"], "input");
    assert!(
        failed["file"].as_str().unwrap().ends_with("missing.png"),
        "{failed}"
    );
    assert!(
        !out.join("line-4").exists(),
        "a failed job leaves no output directory"
    );
    // The same bytes as `decalbake bake` of the job file.
    let serial = dir.join("serial");
    let (code, _, err) = cli(&[
        "bake",
        dir.join("a.json").to_str().unwrap(),
        "--out",
        serial.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(
        std::fs::read(out.join("line-1-a/a.png")).unwrap(),
        std::fs::read(serial.join("a.png")).unwrap()
    );
    let report = summary(&out.join("line-1-a/a.report.json"));
    assert_eq!(report["input_hash"], s["jobs"][0]["input_hash"]);
    // Resume: what is done is skipped, the failure is tried again.
    let (code, _, _) = run(&["--resume"]);
    assert_eq!(code, 3);
    let s2 = summary(&out.join("summary.json"));
    assert_eq!(
        statuses(&s2),
        [
            (1, "skipped"),
            (2, "skipped"),
            (4, "failed"),
            (5, "skipped")
        ]
        .map(|(l, s)| (l, s.to_string()))
    );
    // A changed input changes the hash: the jobs that read it bake again.
    std::fs::write(
        dir.join("img2.png"),
        test_image(16, 16, 10, true).encode_png(8),
    )
    .unwrap();
    std::fs::remove_file(out.join("line-2/b.png")).unwrap();
    let (code, _, _) = run(&["--resume"]);
    assert_eq!(code, 3);
    assert_eq!(
        statuses(&summary(&out.join("summary.json"))),
        [(1, "skipped"), (2, "ok"), (4, "failed"), (5, "ok")].map(|(l, s)| (l, s.to_string()))
    );
    // --fail-fast stops at the failure.
    let (code, _, _) = run(&["--fail-fast"]);
    assert_eq!(code, 3);
    assert_eq!(
        summary(&out.join("summary.json"))["jobs"]
            .as_array()
            .unwrap()
            .len(),
        3
    );
}

#[test]
fn shards_cover_the_manifest_once_and_merge() {
    let dir = setup("batch_shards");
    let m = dir.join("manifest.jsonl");
    let full = dir.join("full");
    cli(&[
        "batch",
        m.to_str().unwrap(),
        "--out",
        full.to_str().unwrap(),
    ]);
    let mut parts = Vec::new();
    for i in 0..3 {
        let out = dir.join(format!("shard{i}"));
        let (code, _, err) = cli(&[
            "batch",
            m.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--shard",
            &format!("{i}/3"),
        ]);
        assert!(code == 0 || code == 3, "{err}");
        // Several shards: each its own summary-I.json.
        parts.push(out.join(format!("summary-{i}.json")));
    }
    let merged = dir.join("merged.json");
    let (code, _, err) = merge(&merged, &parts);
    assert_eq!(code, 3, "a shard had a failure: {err}");
    let (a, b) = (summary(&merged), summary(&full.join("summary.json")));
    assert_eq!(statuses(&a), statuses(&b));
    assert_eq!(a["counts"], b["counts"]);
    // Outputs do not depend on the shard: line 5 (position 3) ran in shard 0.
    assert_eq!(
        std::fs::read(dir.join("shard0/line-5/d.png")).unwrap(),
        std::fs::read(full.join("line-5/d.png")).unwrap()
    );
    // Two jobs at once on one engine: the same summary and the same bytes as one at a time.
    let par = dir.join("jobs2");
    let (code, _, err) = cli(&[
        "batch",
        m.to_str().unwrap(),
        "--out",
        par.to_str().unwrap(),
        "--jobs",
        "2",
    ]);
    assert_eq!(code, 3, "{err}");
    assert_eq!(statuses(&summary(&par.join("summary.json"))), statuses(&b));
    for f in [
        "line-1-a/a.png",
        "line-2/b.png",
        "line-5/d.png",
        "line-1-a/a.report.json",
    ] {
        let (x, y) = (
            std::fs::read(par.join(f)).unwrap(),
            std::fs::read(full.join(f)).unwrap(),
        );
        if f.ends_with(".png") {
            assert_eq!(x, y, "{f} differs between --jobs 2 and one at a time");
        } else {
            let (x, y): (Value, Value) = (
                serde_json::from_slice(&x).unwrap(),
                serde_json::from_slice(&y).unwrap(),
            );
            assert_eq!(x["input_hash"], y["input_hash"]);
        }
    }
    // A Slurm array task: index minus the array's first index, count from Slurm.
    let slurm = dir.join("slurm");
    let (_, _, err) = cli_env(
        &[
            "batch",
            m.to_str().unwrap(),
            "--out",
            slurm.to_str().unwrap(),
            "--shard",
            "auto",
        ],
        &[
            ("SLURM_ARRAY_TASK_ID", "8"),
            ("SLURM_ARRAY_TASK_MIN", "7"),
            ("SLURM_ARRAY_TASK_COUNT", "4"),
        ],
    );
    assert!(err.contains("shard 1/4 (Slurm job array)"), "{err}");
    assert_eq!(
        statuses(&summary(&dir.join("slurm/summary-1.json"))),
        [(2, "ok".to_string())]
    );
    // A shard index past the count is a bad option.
    let (code, _, err) = cli(&["batch", m.to_str().unwrap(), "--shard", "3/3"]);
    assert_eq!(code, 2, "{err}");
}

#[test]
fn a_bad_manifest_stops_before_baking() {
    let dir = setup("batch_bad");
    std::fs::write(dir.join("bad.jsonl"), "\"a.json\"\n42\n").unwrap();
    let out = dir.join("out");
    let (code, _, err) = cli(&[
        "batch",
        dir.join("bad.jsonl").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("bad.jsonl") && err.contains("line 2"), "{err}");
    assert!(!out.exists(), "nothing baked, no summary");
    // A job file that cannot be read fails its own job, not the batch.
    std::fs::write(dir.join("gone.jsonl"), "\"nope.json\"\n\"a.json\"\n").unwrap();
    let out = dir.join("gone");
    let (code, _, err) = cli(&[
        "batch",
        dir.join("gone.jsonl").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 3, "{err}");
    let s = summary(&out.join("summary.json"));
    assert_eq!(
        statuses(&s),
        [(1, "failed".to_string()), (2, "ok".to_string())]
    );
    assert!(
        s["jobs"][0]["file"]
            .as_str()
            .unwrap()
            .ends_with("nope.json"),
        "{s}"
    );
}

/// A device lost in the middle of a job (destroyed from another thread by the batch's fault
/// injection, `DECALBAKE_FAULT_LOSE_DEVICE=LINE:MS`) costs nothing: the job is baked again on a
/// fresh device, the rest go on, and every output is the bytes of an undisturbed run. Without the
/// recovery (`Devices::renew`) line 1 fails and every later job with it.
#[test]
fn a_lost_device_is_replaced_and_its_job_baked_again() {
    let dir = setup("batch_device_loss");
    let m = dir.join("manifest.jsonl");
    let (calm, lossy) = (dir.join("calm"), dir.join("lossy"));
    let (code, _, err) = cli(&[
        "batch",
        m.to_str().unwrap(),
        "--out",
        calm.to_str().unwrap(),
    ]);
    assert_eq!(code, 3, "{err}");
    for delay in ["0", "15"] {
        let _ = std::fs::remove_dir_all(&lossy);
        let fault = format!("1:{delay}");
        let (code, _, err) = cli_env(
            &[
                "batch",
                m.to_str().unwrap(),
                "--out",
                lossy.to_str().unwrap(),
            ],
            &[("DECALBAKE_FAULT_LOSE_DEVICE", &fault)],
        );
        assert_eq!(code, 3, "only line 4 fails: {err}");
        assert!(err.contains("destroying the GPU device"), "{err}");
        let s = summary(&lossy.join("summary.json"));
        assert_eq!(s["device_resets"], 1, "{s}");
        assert_eq!(
            statuses(&s),
            [(1, "ok"), (2, "ok"), (4, "failed"), (5, "ok")].map(|(l, s)| (l, s.to_string()))
        );
        // The loss lands in line 1's bake, or (when that bake beat the 15 ms) in the next one's.
        assert!(
            s["jobs"].as_array().unwrap()[..2]
                .iter()
                .any(|j| j["retried"] == true),
            "{s}"
        );
        for png in ["line-1-a/a.png", "line-2/b.png", "line-5/d.png"] {
            assert_eq!(
                std::fs::read(lossy.join(png)).unwrap(),
                std::fs::read(calm.join(png)).unwrap(),
                "{png} after a device loss (delay {delay} ms)"
            );
        }
    }
}

/// A Slurm task run again on its own (`sbatch --array=2`) sees an array of one; with
/// `DECALBAKE_SHARDS` its id is its shard. Merging counts each line once (a rerun that baked the
/// whole manifest does not list lines twice) and names the shards whose summary is missing.
#[test]
fn a_rerun_task_keeps_its_shard_and_merging_counts_each_line_once() {
    let dir = setup("batch_rerun");
    let m = dir.join("manifest.jsonl");
    let run = |out: &str, envs: &[(&str, &str)], extra: &[&str]| {
        let out = dir.join(out);
        let mut args = vec!["batch", m.to_str().unwrap(), "--out", out.to_str().unwrap()];
        args.extend_from_slice(extra);
        let (code, _, err) = cli_env(&args, envs);
        (code, err)
    };
    let slurm_rerun = [
        ("SLURM_ARRAY_TASK_ID", "2"),
        ("SLURM_ARRAY_TASK_MIN", "2"),
        ("SLURM_ARRAY_TASK_COUNT", "1"),
        ("DECALBAKE_SHARDS", "3"),
    ];
    let (_, err) = run("out", &slurm_rerun, &["--shard", "auto"]);
    assert!(
        err.contains("shard 2/3 (Slurm job array, DECALBAKE_SHARDS)"),
        "{err}"
    );
    let s2 = dir.join("out/summary-2.json");
    assert_eq!(statuses(&summary(&s2)), [(4, "failed".to_string())]);
    // Shard 0 and a whole-manifest run: every line once, the successes kept.
    run("out", &[], &["--shard", "0/3"]);
    run("whole", &[], &[]);
    let merged = dir.join("merged.json");
    let (code, _, _) = merge(
        &merged,
        &[
            dir.join("out/summary-0.json"),
            dir.join("whole/summary.json"),
        ],
    );
    assert_eq!(code, 3, "line 4 failed");
    assert_eq!(
        statuses(&summary(&merged)),
        [(1, "ok"), (2, "ok"), (4, "failed"), (5, "ok")].map(|(l, s)| (l, s.to_string()))
    );
    // Shards 0 and 2 of 3: shard 1 is missing, and the merge says so.
    let (code, _, err) = merge(&merged, &[dir.join("out/summary-0.json"), s2]);
    assert_eq!(code, 3);
    assert!(err.contains("shard(s) [1]"), "{err}");
    assert_eq!(summary(&merged)["shard"]["missing"], serde_json::json!([1]));
}

/// Every file under `dir` but the batch's own (journal, summary), by path relative to `dir`.
fn outputs_under(dir: &Path) -> std::collections::BTreeMap<String, Vec<u8>> {
    let mut out = std::collections::BTreeMap::new();
    for e in std::fs::read_dir(dir).unwrap().flatten() {
        if e.path().is_dir() {
            for f in std::fs::read_dir(e.path()).unwrap().flatten() {
                let name = f.path().strip_prefix(dir).unwrap().display().to_string();
                // A temporary file a kill left behind is not an output.
                if !name.contains(".tmp") {
                    out.insert(name, std::fs::read(f.path()).unwrap());
                }
            }
        }
    }
    out
}

#[test]
fn a_batch_killed_at_random_points_resumes_each_job_once_with_the_same_bytes() {
    let dir = scratch("batch_kill");
    write_plane(&dir.join("plane.glb"), 8, false);
    std::fs::write(
        dir.join("img.png"),
        test_image(16, 16, 4, true).encode_png(8),
    )
    .unwrap();
    // Eight small jobs that write no report: the journal alone tells what is done.
    let lines: Vec<String> = (0..8)
        .map(|k| {
            let at = [0.2 + 0.08 * k as f32, 0.5, 0.0];
            serde_json::json!({ "mesh": "plane.glb", "texture": { "width": 64, "height": 64 },
                "layers": [{ "image": "img.png", "at": at, "size": [0.3, 0.3] }],
                "output": { "texture": format!("t{k}.png"), "glb": format!("m{k}.glb"),
                    "report": null } })
            .to_string()
        })
        .collect();
    let m = dir.join("manifest.jsonl");
    std::fs::write(&m, lines.join("\n")).unwrap();
    let exe = env!("CARGO_BIN_EXE_decalbake");
    let batch = |out: &Path| {
        let mut c = std::process::Command::new(exe);
        c.args(["batch", m.to_str().unwrap(), "--out", out.to_str().unwrap()])
            .args(["--resume", "--progress", "lines"])
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped());
        c
    };
    let (full, killed) = (dir.join("full"), dir.join("killed"));
    assert!(batch(&full).status().unwrap().success());
    // Kills spread over the jobs: after the k-th job's progress line (k from 0: before the
    // first) and a random delay of up to 60 ms; a fixed sequence, so a failure can be replayed.
    let mut seed = 0x9e37_79b9_u32;
    let mut next = || {
        seed ^= seed << 13;
        seed ^= seed >> 17;
        seed ^= seed << 5;
        seed
    };
    for _ in 0..20 {
        let (after, delay) = (next() % 8, next() % 60);
        let mut child = batch(&killed).spawn().unwrap();
        let stderr = std::io::BufReader::new(child.stderr.take().unwrap());
        let (tx, rx) = std::sync::mpsc::channel();
        let reader = std::thread::spawn(move || {
            use std::io::BufRead;
            for line in stderr.lines().map_while(Result::ok) {
                if line.starts_with('[') && tx.send(()).is_err() {
                    break;
                }
            }
        });
        for _ in 0..after {
            if rx.recv().is_err() {
                break; // the batch ended (every job was done already)
            }
        }
        std::thread::sleep(std::time::Duration::from_millis(delay as u64));
        let _ = child.kill(); // SIGKILL (nothing to do for a process that has ended)
        child.wait().unwrap();
        drop(rx);
        reader.join().unwrap();
    }
    assert!(batch(&killed).status().unwrap().success());
    // Each job is recorded exactly once, and the outputs are the uninterrupted run's bytes.
    let journal = std::fs::read_to_string(killed.join("journal.jsonl")).unwrap();
    let mut done: Vec<u64> = journal
        .lines()
        .filter_map(|l| serde_json::from_str::<Value>(l).ok())
        .map(|r| r["line"].as_u64().unwrap())
        .collect();
    done.sort();
    assert_eq!(done, (1..=8).collect::<Vec<u64>>(), "{journal}");
    // The temporaries the kills left are gone (the jobs baked again cleared them), and the jobs'
    // folders hold only outputs.
    for e in std::fs::read_dir(&killed).unwrap().flatten() {
        if e.path().is_dir() {
            for f in std::fs::read_dir(e.path()).unwrap().flatten() {
                let name = f.file_name().to_string_lossy().into_owned();
                assert!(
                    !name.contains(".tmp-"),
                    "left behind: {}",
                    f.path().display()
                );
            }
        }
    }
    let (a, b) = (outputs_under(&full), outputs_under(&killed));
    assert_eq!(a.len(), 16, "a texture and a model a job: {:?}", a.keys());
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
    for (name, bytes) in &a {
        assert!(
            bytes == &b[name],
            "{name} differs from the uninterrupted run's"
        );
    }
    // The final run skipped what the journal holds: every job, now.
    let s = summary(&killed.join("summary.json"));
    assert!(s["jobs"].as_array().unwrap().len() == 8);
}

/// A manifest named without a folder, run from its own folder: the journal and summary go beside
/// it (its parent is the empty path, which cannot be listed; the current folder is meant).
#[test]
fn a_manifest_named_without_a_folder_is_read_from_the_current_one() {
    let dir = setup("batch_bare_manifest");
    let lines = std::fs::read_to_string(dir.join("manifest.jsonl")).unwrap();
    let first_two: Vec<&str> = lines.lines().take(2).collect();
    std::fs::write(dir.join("two.jsonl"), first_two.join("\n")).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_decalbake"))
        .args(["batch", "two.jsonl"])
        .current_dir(&dir)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    let s = summary(&dir.join("summary.json"));
    assert_eq!(
        statuses(&s),
        vec![(1, "ok".to_string()), (2, "ok".to_string())]
    );
    assert!(dir.join("journal.jsonl").exists() && dir.join("b.png").exists());
}
