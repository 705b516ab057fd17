//! Sharded runs through a real Slurm (issue 20, acceptance 2): `slurm/submit` sends a
//! 4-shard path-traced reference and a 4-shard accuracy sweep as job arrays with a dependent
//! merge job; the merged files must equal the unsharded runs bit for bit (wall-clock columns
//! aside, as in `tests/shard.rs`).
//!
//! Needs `sbatch` and a running cluster (`slurm/local-cluster.sh start DIR` makes a one-node
//! one here; `.ci/run` does). Without `sbatch` the test prints one line and passes, unless
//! `SCATTERBENCH_REQUIRE_SLURM=1` (set by `.ci/run`), which makes it fail. The job ids and
//! node of every job are printed and, with `SCATTERBENCH_SLURM_LOG=FILE`, appended there.

#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::sharding::{csv_without, small_atlas};
use common::spawn::workspace;
use std::io::Write as _;
use std::path::PathBuf;
use std::process::Command;

fn have_slurm() -> bool {
    let required = std::env::var("SCATTERBENCH_REQUIRE_SLURM").is_ok_and(|v| v == "1");
    let sbatch = Command::new("sbatch").arg("--version").output().is_ok();
    if !sbatch {
        assert!(
            !required,
            "SCATTERBENCH_REQUIRE_SLURM=1 but `sbatch` is not installed"
        );
        eprintln!(
            "skipped: no Slurm (`sbatch` not found); set SCATTERBENCH_REQUIRE_SLURM=1 to require it"
        );
        return false;
    }
    let up = Command::new("sinfo")
        .args(["-h", "-o", "%T"])
        .output()
        .is_ok_and(|o| o.status.success() && !o.stdout.is_empty());
    assert!(
        up || !required,
        "SCATTERBENCH_REQUIRE_SLURM=1 but no Slurm controller answers (start one with \
         slurm/local-cluster.sh start DIR and export SLURM_CONF)"
    );
    if !up {
        eprintln!("skipped: `sbatch` is installed but no Slurm controller answers");
    }
    up
}

fn log(line: &str) {
    eprintln!("{line}");
    if let Ok(path) = std::env::var("SCATTERBENCH_SLURM_LOG")
        && let Ok(mut f) = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)
    {
        let _ = writeln!(f, "{line}");
    }
}

/// Submits `producer flags` as 4 shards (or, with `tasks`, one array task per line of its
/// `--list-tasks`) with `--wait`, runs it unsharded, compares `files`.
fn through_slurm(
    tag: &str,
    split: &[&str],
    jobs: usize,
    producer: &str,
    flags: &[&str],
    files: &[(&str, &[&str])],
) {
    let dir = std::env::temp_dir().join(format!("scatterbench-slurm-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let bin = PathBuf::from(env!("CARGO_BIN_EXE_merge"));
    let bindir = bin.parent().unwrap();
    let t0 = std::time::Instant::now();
    let o = Command::new(workspace().join("slurm/submit"))
        .args(split)
        .args(["--cpus", "1", "--mem", "1G", "--wait"])
        .arg("--bin-dir")
        .arg(bindir)
        .arg("--work")
        .arg(dir.join("work"))
        .arg("--out")
        .arg(dir.join("merged"))
        .arg("--")
        .arg(producer)
        .args(flags)
        .output()
        .unwrap();
    let seconds = t0.elapsed().as_secs_f64();
    let stderr = String::from_utf8_lossy(&o.stderr);
    let mut outs: Vec<PathBuf> = std::fs::read_dir(dir.join("work"))
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "out"))
        .collect();
    outs.sort();
    let job_lines: Vec<String> = outs
        .iter()
        .flat_map(|p| {
            std::fs::read_to_string(p)
                .unwrap_or_default()
                .lines()
                .filter(|l| l.starts_with("scatterbench "))
                .map(String::from)
                .collect::<Vec<_>>()
        })
        .collect();
    log(&format!(
        "slurm {tag}: `{producer} {}` as {} + merge in {seconds:.1} s; job ids {}",
        flags.join(" "),
        split.join(" "),
        String::from_utf8_lossy(&o.stdout).trim()
    ));
    for l in &job_lines {
        log(&format!("slurm {tag}:   {l}"));
    }
    assert!(
        o.status.success(),
        "slurm/submit failed: {stderr}\njobs: {job_lines:?}"
    );
    assert_eq!(
        job_lines.len(),
        jobs + 1,
        "expected {jobs} array jobs and 1 merge job in the job logs: {job_lines:?}"
    );
    let mut whole: Vec<String> = flags.iter().map(|s| s.to_string()).collect();
    whole.extend(["--no-progress".into(), "--out".into(), "whole".into()]);
    let st = Command::new(bindir.join(producer))
        .args(&whole)
        .current_dir(&dir)
        .status()
        .unwrap();
    assert!(st.success());
    for (name, skip) in files {
        let a = csv_without(&dir.join("whole").join(name), skip);
        let b = csv_without(&dir.join("merged").join(name), skip);
        assert!(a.len() > 1, "{tag}: {name} has no rows");
        assert_eq!(
            a, b,
            "{tag}: {name} differs between the unsharded and the Slurm run"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn sharded_runs_through_slurm_merge_bit_identically() {
    if !have_slurm() {
        return;
    }
    through_slurm(
        "reference",
        &["--shards", "4"],
        4,
        "pt_slab",
        &["--quick", "--paths", "64000", "--tau", "1,8"],
        &[("slab.csv", &["seconds"])],
    );
    let atlas = small_atlas();
    let atlas: Vec<&str> = atlas.iter().map(String::as_str).collect();
    let files: &[(&str, &[&str])] = &[
        ("points.csv", &["seconds", "paths_per_second"]),
        ("references.csv", &["seconds", "paths_per_second"]),
    ];
    // The sweep's Monte Carlo as 4 shards (grid methods in the merge job) …
    through_slurm(
        "atlas-shards",
        &["--shards", "4"],
        4,
        "accuracy_cost",
        &atlas,
        files,
    );
    // … and as its 5 tasks (reference, 2 path-tracer points, the quick ladder's CDA setting,
    // `cda:mg`).
    through_slurm(
        "atlas-tasks",
        &["--tasks"],
        5,
        "accuracy_cost",
        &atlas,
        files,
    );
}
