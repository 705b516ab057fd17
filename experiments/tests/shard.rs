//! Sharded Monte Carlo runs merge into exactly what an unsharded run writes (issue 20,
//! acceptance 1 and 3).
//!
//! Each producer runs once whole and once as N shards joined by `merge`; every estimate in
//! every CSV must be bit-identical (the columns that are wall-clock measurements are the
//! only ones left out: a merged tally's seconds are the sum over its shards), and images
//! (PFM, and PNGs of estimates) byte-identical. Then `merge` must refuse every set of
//! shards that does not make one run: a missing shard, a duplicated one, another seed,
//! another producer, another revision, a changed input file, a truncated file, a corrupt
//! one, and more shards than batches.

#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::sharding::{csv_without, small_atlas};
use common::spawn::workspace;
use std::path::{Path, PathBuf};
use std::process::Command;

fn scratch(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("scatterbench-shard-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Runs `bin args` in `cwd`; returns (success, stderr).
fn run(bin: &str, args: &[String], cwd: &Path) -> (bool, String) {
    let o = Command::new(bin)
        .args(args)
        .current_dir(cwd)
        .env("RUST_BACKTRACE", "0")
        .env_remove("SCATTERBENCH_WORK_BUDGET")
        .output()
        .unwrap();
    (
        o.status.success(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

fn ok(bin: &str, args: &[String], cwd: &Path) {
    let (success, err) = run(bin, args, cwd);
    assert!(success, "{bin} {}: {err}", args.join(" "));
}

fn strings(v: &[&str]) -> Vec<String> {
    v.iter().map(|s| s.to_string()).collect()
}

/// A file to compare: a CSV without its wall-clock columns, or any file byte for byte.
enum Same<'a> {
    Csv(&'a str, &'a [&'a str]),
    Bytes(&'a str),
}

/// Runs `bin args` whole and as `n` shards + merge, and compares `files`.
fn sharded_equals_whole(tag: &str, bin: &str, args: &[&str], n: u32, files: &[Same<'_>]) {
    let dir = scratch(tag);
    let mut whole = strings(args);
    whole.extend(strings(&["--no-progress", "--out", "whole"]));
    ok(bin, &whole, &dir);
    let mut shards = Vec::new();
    for i in 0..n {
        let mut a = strings(args);
        let out = format!("shard{i}");
        a.extend(strings(&[
            "--no-progress",
            "--shard",
            &format!("{i}/{n}"),
            "--out",
            &out,
        ]));
        ok(bin, &a, &dir);
        assert!(
            dir.join(&out).join("shard.bin").is_file(),
            "{tag}: shard {i} wrote no shard.bin"
        );
        shards.push(out);
    }
    let mut m = strings(&["--out", "merged"]);
    // Given in reverse order: the merge sorts them.
    m.extend(shards.iter().rev().cloned());
    ok(env!("CARGO_BIN_EXE_merge"), &m, &dir);
    for f in files {
        match f {
            Same::Csv(name, skip) => {
                let a = csv_without(&dir.join("whole").join(name), skip);
                let b = csv_without(&dir.join("merged").join(name), skip);
                assert!(a.len() > 1, "{tag}: {name} has no rows");
                assert_eq!(
                    a, b,
                    "{tag}: {name} differs between the whole and the merged run"
                );
            }
            Same::Bytes(name) => {
                let a = std::fs::read(dir.join("whole").join(name)).unwrap();
                let b = std::fs::read(dir.join("merged").join(name)).unwrap();
                assert!(
                    a == b,
                    "{tag}: {name} differs between the whole and the merged run"
                );
            }
        }
    }
    let meta = std::fs::read_to_string(dir.join("merged").join("meta.json")).unwrap();
    assert!(
        meta.contains("merged_from"),
        "{tag}: meta.json does not name its shards"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn pt_slab_merges_bit_identically() {
    sharded_equals_whole(
        "slab",
        env!("CARGO_BIN_EXE_pt_slab"),
        &[
            "--quick", "--paths", "64000", "--tau", "1,8", "--albedo", "0.9,1",
        ],
        4,
        &[Same::Csv("slab.csv", &["seconds"]), Same::Bytes("slab.png")],
    );
}

#[test]
fn pt_point_source_merges_bit_identically() {
    sharded_equals_whole(
        "point",
        env!("CARGO_BIN_EXE_pt_point_source"),
        &["--quick", "--paths", "40000"],
        3,
        &[
            Same::Csv("shells.csv", &[]),
            Same::Csv("runs.csv", &["seconds", "paths_per_second"]),
        ],
    );
}

#[test]
fn pt_render_merges_bit_identically() {
    sharded_equals_whole(
        "ptrender",
        env!("CARGO_BIN_EXE_pt_render"),
        &["--quick", "--n", "16", "--res", "12", "--spp", "32"],
        5,
        &[
            Same::Csv(
                "timing.csv",
                &[
                    "seconds",
                    "paths_per_second",
                    "cpu_seconds",
                    "paths_per_cpu_second",
                ],
            ),
            Same::Csv("image.csv", &[]),
            Same::Bytes("image.png"),
        ],
    );
}

#[test]
fn i3rc_step_cloud_merges_bit_identically() {
    sharded_equals_whole(
        "i3rc",
        env!("CARGO_BIN_EXE_i3rc_step_cloud"),
        &["--quick"],
        4,
        &[Same::Csv("columns.csv", &[]), Same::Csv("domain.csv", &[])],
    );
}

#[test]
fn render_pt_merges_bit_identically() {
    let scene = workspace().join("scenes/emissive_sphere.toml");
    let scene = scene.to_string_lossy().into_owned();
    sharded_equals_whole(
        "render",
        env!("CARGO_BIN_EXE_render"),
        &[
            "--scene", &scene, "--method", "pt", "--quick", "--spp", "32",
        ],
        2,
        &[
            Same::Bytes("image.pfm"),
            Same::Bytes("image_stderr.pfm"),
            Same::Bytes("image.png"),
            Same::Csv("passes.csv", &["seconds"]),
        ],
    );
}

#[test]
fn accuracy_atlas_merges_bit_identically() {
    let atlas = small_atlas();
    let flags: Vec<&str> = atlas.iter().map(String::as_str).collect();
    sharded_equals_whole(
        "atlas",
        env!("CARGO_BIN_EXE_accuracy_cost"),
        &flags,
        2,
        &[
            Same::Csv("points.csv", &["seconds", "paths_per_second"]),
            Same::Csv("references.csv", &["seconds", "paths_per_second"]),
            // The fastest point per target depends on wall times; its targets and whether
            // each is resolvable (the reference's noise) do not.
            Same::Csv(
                "fastest.csv",
                &["method", "setting", "backend", "seconds", "error"],
            ),
        ],
    );
}

/// Shards of one small `pt_slab` run, in `dir`: `shard0` … `shard3`.
fn slab_shards(dir: &Path, extra: &[&str], names: &[(u32, &str)]) {
    for &(i, out) in names {
        let mut a = strings(&[
            "--quick", "--paths", "16000", "--tau", "1", "--albedo", "0.5",
        ]);
        a.extend(strings(extra));
        a.extend(strings(&[
            "--no-progress",
            "--shard",
            &format!("{i}/4"),
            "--out",
            out,
        ]));
        ok(env!("CARGO_BIN_EXE_pt_slab"), &a, dir);
    }
}

fn merge_fails(dir: &Path, shards: &[&str], expect: &str) {
    let mut a = strings(&["--out", "merged"]);
    a.extend(strings(shards));
    let (success, err) = run(env!("CARGO_BIN_EXE_merge"), &a, dir);
    assert!(!success, "merge of {shards:?} succeeded");
    assert!(
        err.contains(expect),
        "merge of {shards:?}: expected `{expect}` in: {err}"
    );
    assert!(!err.contains("panicked"), "{err}");
    assert!(!dir.join("merged").exists(), "a refused merge left output");
}

#[test]
fn merge_refuses_shards_that_do_not_make_one_run() {
    let dir = scratch("refuse");
    slab_shards(&dir, &[], &[(0, "s0"), (1, "s1"), (2, "s2"), (3, "s3")]);
    slab_shards(&dir, &["--seed", "9"], &[(3, "seed9")]);
    // Missing and duplicated shards.
    merge_fails(
        &dir,
        &["s0", "s1", "s2"],
        "shard 3/4 of this 4-shard run is missing",
    );
    merge_fails(&dir, &["s0", "s1", "s1", "s2"], "shard 1/4 is given twice");
    // Another seed: the flags differ.
    merge_fails(&dir, &["s0", "s1", "s2", "seed9"], "flags");
    // Another producer.
    ok(
        env!("CARGO_BIN_EXE_pt_point_source"),
        &strings(&[
            "--quick",
            "--paths",
            "4000",
            "--no-progress",
            "--shard",
            "3/4",
            "--out",
            "pps",
        ]),
        &dir,
    );
    merge_fails(&dir, &["s0", "s1", "s2", "pps"], "producers differ");
    // Another revision: the same shard with its header's revision changed.
    let f = experiments::shard::read(&dir.join("s3")).unwrap();
    let mut h = f.header.clone();
    h.git_revision.push_str("-other");
    std::fs::create_dir_all(dir.join("rev")).unwrap();
    experiments::shard::write(&dir.join("rev/shard.bin"), &h, &f.tallies).unwrap();
    merge_fails(&dir, &["s0", "s1", "s2", "rev"], "revisions differ");
    // Truncated and corrupt files.
    let bytes = std::fs::read(dir.join("s3/shard.bin")).unwrap();
    std::fs::create_dir_all(dir.join("cut")).unwrap();
    std::fs::write(dir.join("cut/shard.bin"), &bytes[..bytes.len() - 8]).unwrap();
    merge_fails(&dir, &["s0", "s1", "s2", "cut"], "truncated or corrupt");
    std::fs::create_dir_all(dir.join("junk")).unwrap();
    std::fs::write(dir.join("junk/shard.bin"), b"not a shard").unwrap();
    merge_fails(
        &dir,
        &["s0", "s1", "s2", "junk"],
        "not a scatterbench shard file",
    );
    merge_fails(
        &dir,
        &["s0", "s1", "s2", "nowhere"],
        "did that shard finish?",
    );
    // The complete set merges.
    let mut a = strings(&["--out", "merged"]);
    a.extend(strings(&["s3", "s1", "s0", "s2"]));
    ok(env!("CARGO_BIN_EXE_merge"), &a, &dir);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn merge_refuses_a_changed_input_file() {
    let dir = scratch("input");
    let scene = dir.join("scene.toml");
    std::fs::copy(workspace().join("scenes/emissive_sphere.toml"), &scene).unwrap();
    let shard = |i: u32, out: &str| {
        strings(&[
            "--scene",
            "scene.toml",
            "--method",
            "pt",
            "--quick",
            "--spp",
            "16",
            "--no-progress",
            "--shard",
            &format!("{i}/2"),
            "--out",
            out,
        ])
    };
    ok(env!("CARGO_BIN_EXE_render"), &shard(0, "a"), &dir);
    let mut text = std::fs::read_to_string(&scene).unwrap();
    text.push_str("\n# edited between the shards\n");
    std::fs::write(&scene, text).unwrap();
    ok(env!("CARGO_BIN_EXE_render"), &shard(1, "b"), &dir);
    merge_fails(&dir, &["a", "b"], "input files differ");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn shard_flags_are_checked() {
    let dir = scratch("flags");
    let slab = env!("CARGO_BIN_EXE_pt_slab");
    for (args, expect) in [
        (vec!["--shard", "4/4"], "must be below the number of shards"),
        (vec!["--shard", "1/0"], "at least 1"),
        (vec!["--shard", "x"], "expected `i/N`"),
        // 16 batches cannot make 17 shards.
        (
            vec!["--quick", "--batches", "16", "--shard", "0/17"],
            "more shards than batches",
        ),
    ] {
        let (success, err) = run(slab, &strings(&args), &dir);
        assert!(!success && err.contains(expect), "{args:?}: {err}");
    }
    let (success, err) = run(
        env!("CARGO_BIN_EXE_point_source"),
        &strings(&["--quick", "--shard", "0/2"]),
        &dir,
    );
    assert!(
        !success && err.contains("no Monte Carlo part to shard"),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn atlas_tasks_merge_like_a_single_run() {
    let dir = scratch("tasks");
    let bin = env!("CARGO_BIN_EXE_accuracy_cost");
    let mut base = small_atlas();
    base.push("--no-progress".into());
    let o = Command::new(bin)
        .args(&base)
        .arg("--list-tasks")
        .current_dir(&dir)
        .output()
        .unwrap();
    assert!(o.status.success());
    let list = String::from_utf8_lossy(&o.stdout).into_owned();
    let lines: Vec<&str> = list.lines().collect();
    // One reference, two path-tracer points, the quick ladder's CDA setting and CDA's
    // multigrid twin (`cda:mg`, its `Method::param_settings`).
    assert_eq!(lines.len(), 5, "{list}");
    assert!(
        lines[0].contains("reference") && lines[3].contains("cda") && lines[4].contains("cda:mg"),
        "{list}"
    );
    let mut whole = base.clone();
    whole.extend(strings(&["--out", "whole"]));
    ok(bin, &whole, &dir);
    let mut dirs = Vec::new();
    for k in 0..lines.len() {
        let mut a = base.clone();
        let out = format!("task{k}");
        a.extend(strings(&["--task", &k.to_string(), "--out", &out]));
        ok(bin, &a, &dir);
        dirs.push(out);
    }
    let (_, err) = run(
        env!("CARGO_BIN_EXE_merge"),
        &strings(&["--out", "partial", "task0", "task1", "task3", "task4"]),
        &dir,
    );
    assert!(
        err.contains("task 2 of this 5-task sweep is missing"),
        "{err}"
    );
    let mut m = strings(&["--out", "merged"]);
    m.extend(dirs.iter().rev().cloned());
    ok(env!("CARGO_BIN_EXE_merge"), &m, &dir);
    // Every column but the seconds (a grid point's seconds are its task's own, so
    // fastest.csv and the plots follow from the same numbers as in one run).
    for name in ["points.csv", "references.csv"] {
        let a = csv_without(
            &dir.join("whole").join(name),
            &["seconds", "paths_per_second"],
        );
        let b = csv_without(
            &dir.join("merged").join(name),
            &["seconds", "paths_per_second"],
        );
        assert!(a.len() > 1);
        assert_eq!(a, b, "{name}");
    }
    for f in ["fastest.csv", "pareto_emissive_cloud.png", "meta.json"] {
        assert!(
            dir.join("merged").join(f).is_file(),
            "{f} missing from the merge"
        );
    }
    let mut bad = base.clone();
    bad.extend(strings(&["--task", "5"]));
    let (success, err) = run(bin, &bad, &dir);
    assert!(!success && err.contains("this sweep has 5 tasks"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}
