//! Hostile input and interrupted runs (issue 13, acceptance 1 and 2).
//!
//! Every binary is spawned with absurd sizes and `/dev/zero` inputs: each must exit non-zero
//! (never abort: no signal, no exit code 134) within 2 s (a 10 s guard kills a hung child),
//! with a message naming the flag or field and the bytes needed. Then the output layer is interrupted at
//! every step of a run (the `SCATTERBENCH_TEST_EXIT_AT` hook exits the process without
//! cleanup, as a kill would): the previous results must stay byte-identical; a held lock
//! must refuse a second writer; a rerun must leave no stale file.

#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::spawn::{scratch, spawn, workspace};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn tmp(tag: &str) -> PathBuf {
    scratch(&format!("hostile-{tag}"))
}

/// A plume scene with `from` replaced by `to` (for one hostile field).
fn plume_with(dir: &Path, name: &str, from: &str, to: &str) -> String {
    let text = std::fs::read_to_string(workspace().join("scenes/plume.toml")).unwrap();
    assert!(text.contains(from), "plume.toml has no `{from}`");
    let path = dir.join(name);
    std::fs::write(&path, text.replace(from, to)).unwrap();
    path.display().to_string()
}

/// A scene whose medium is the `.vol` file `vol`.
fn vol_scene(dir: &Path, name: &str, vol: &str) -> String {
    let text = std::fs::read_to_string(workspace().join("scenes/plume.toml")).unwrap();
    let text = text.replace(
        "generator = \"plume\"\nparams = { n = 64, seed = 2 }",
        &format!("file = \"{vol}\"\nalbedo = 0.5"),
    );
    assert!(text.contains("file = "));
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path.display().to_string()
}

/// A `.vol` whose header claims `n³` cells, with `data` cells of data after it.
fn vol_file(dir: &Path, name: &str, n: i32, data: usize) -> String {
    let mut b = b"VOL\x03".to_vec();
    for v in [1, n, n, n, 1] {
        b.extend_from_slice(&v.to_le_bytes());
    }
    for v in [0f32, 0., 0., 1., 1., 1.] {
        b.extend_from_slice(&v.to_le_bytes());
    }
    b.extend(std::iter::repeat_n(0u8, 4 * data));
    let path = dir.join(name);
    std::fs::write(&path, b).unwrap();
    path.display().to_string()
}

#[test]
fn absurd_sizes_and_device_inputs_are_clear_errors_never_aborts() {
    let dir = tmp("sizes");
    let out = dir.join("out").display().to_string();
    let scene = workspace()
        .join("scenes/cloud_directional.toml")
        .display()
        .to_string();
    let big_n = plume_with(&dir, "big_n.toml", "n = 64", "n = 100000");
    let big_cam = plume_with(
        &dir,
        "big_camera.toml",
        "resolution = [64, 64]",
        "resolution = [100000, 100000]",
    );
    let zero_vol = vol_scene(&dir, "zero_vol.toml", "/dev/zero");
    let lying = vol_file(&dir, "lying.vol", 1000, 0);
    let small = vol_file(&dir, "small.vol", 8, 512);
    let small_scene = vol_scene(&dir, "small_vol.toml", &small);
    let lying_scene = vol_scene(&dir, "lying_vol.toml", &lying);
    let o = out.as_str();
    // (binary, flags, environment, words the message must contain)
    type Case<'a> = (&'a str, Vec<&'a str>, Vec<(&'a str, &'a str)>, Vec<&'a str>);
    let cases: Vec<Case<'_>> = vec![
        (
            env!("CARGO_BIN_EXE_point_source"),
            vec!["--n", "99999", "--out", o],
            vec![],
            vec!["--n 99999", "bytes"],
        ),
        (
            env!("CARGO_BIN_EXE_convergence"),
            vec!["--resolutions", "99999", "--out", o],
            vec![],
            vec!["--resolutions 99999", "bytes"],
        ),
        (
            env!("CARGO_BIN_EXE_pt_render"),
            vec!["--n", "100000", "--out", o],
            vec![],
            vec!["--n 100000", "bytes"],
        ),
        (
            env!("CARGO_BIN_EXE_pt_render"),
            vec!["--res", "100000", "--out", o],
            vec![],
            vec!["--res 100000", "bytes"],
        ),
        (
            env!("CARGO_BIN_EXE_lbm_convergence"),
            vec!["--sizes", "100000", "--out", o],
            vec![],
            vec!["--sizes 100000", "bytes"],
        ),
        (
            env!("CARGO_BIN_EXE_lbm_diffusion_limit"),
            vec!["--n", "99999", "--out", o],
            vec![],
            vec!["--n 99999", "bytes"],
        ),
        (
            env!("CARGO_BIN_EXE_renderings"),
            vec!["--resolution", "100000,100000", "--out", o],
            vec![],
            vec!["--resolution 100000,100000", "bytes"],
        ),
        (
            env!("CARGO_BIN_EXE_accuracy_cost"),
            vec!["--resolution", "100000,100000", "--out", o],
            vec![],
            vec!["--resolution 100000,100000", "bytes"],
        ),
        (
            env!("CARGO_BIN_EXE_mitsuba_compare"),
            vec![
                "--scene",
                &scene,
                "--resolution",
                "100000,100000",
                "--out",
                o,
            ],
            vec![],
            vec!["--resolution 100000,100000", "bytes"],
        ),
        (
            env!("CARGO_BIN_EXE_render"),
            vec!["--scene", &big_n, "--out", o],
            vec![],
            vec!["medium.params.n", "bytes"],
        ),
        (
            env!("CARGO_BIN_EXE_render"),
            vec!["--scene", &big_cam, "--out", o],
            vec![],
            vec!["camera.resolution", "bytes"],
        ),
        (
            env!("CARGO_BIN_EXE_render"),
            vec!["--scene", &lying_scene, "--out", o],
            vec![],
            vec!["medium.file", "bytes"],
        ),
        (
            env!("CARGO_BIN_EXE_render"),
            vec!["--scene", &scene, "--out", o],
            vec![("SCATTERBENCH_MEMORY_BUDGET", "100000")],
            vec!["SCATTERBENCH_MEMORY_BUDGET", "bytes"],
        ),
        (
            env!("CARGO_BIN_EXE_render"),
            vec!["--scene", &small_scene, "--out", o],
            vec![("SCATTERBENCH_MEMORY_BUDGET", "5000")],
            vec!["medium.file", "SCATTERBENCH_MEMORY_BUDGET", "bytes"],
        ),
        // `/dev/zero` as an input file: refused at once, never read.
        (
            env!("CARGO_BIN_EXE_render"),
            vec!["--scene", "/dev/zero", "--out", o],
            vec![],
            vec!["--scene /dev/zero", "not a regular file"],
        ),
        (
            env!("CARGO_BIN_EXE_render"),
            vec!["--scene", &zero_vol, "--out", o],
            vec![],
            vec!["medium.file", "not a regular file"],
        ),
        (
            env!("CARGO_BIN_EXE_mitsuba_compare"),
            vec!["--scene", "/dev/zero", "--out", o],
            vec![],
            vec!["/dev/zero", "not a regular file"],
        ),
        (
            env!("CARGO_BIN_EXE_renderings"),
            vec!["--scenes", "/dev/zero", "--out", o],
            vec![],
            vec!["/dev/zero", "not a regular file"],
        ),
        (
            env!("CARGO_BIN_EXE_accuracy_cost"),
            vec!["--scenes", "/dev/zero", "--out", o],
            vec![],
            vec!["/dev/zero", "not a regular file"],
        ),
        // The binaries without size flags or input files: an output under `/dev/zero`.
        (
            env!("CARGO_BIN_EXE_point_source_analytic"),
            vec!["--quick", "--out", "/dev/zero/x"],
            vec![],
            vec!["/dev/zero"],
        ),
        (
            env!("CARGO_BIN_EXE_transport_references"),
            vec!["--quick", "--out", "/dev/zero/x"],
            vec![],
            vec!["/dev/zero"],
        ),
        (
            env!("CARGO_BIN_EXE_pt_point_source"),
            vec!["--quick", "--out", "/dev/zero/x"],
            vec![],
            vec!["/dev/zero"],
        ),
        (
            env!("CARGO_BIN_EXE_pt_slab"),
            vec!["--quick", "--out", "/dev/zero/x"],
            vec![],
            vec!["/dev/zero"],
        ),
        (
            env!("CARGO_BIN_EXE_i3rc_step_cloud"),
            vec!["--quick", "--out", "/dev/zero/x"],
            vec![],
            vec!["/dev/zero"],
        ),
        (
            env!("CARGO_BIN_EXE_figures"),
            vec!["--report-only", "--out", "/dev/zero/x"],
            vec![],
            vec!["/dev/zero"],
        ),
    ];
    let mut problems = Vec::new();
    for (bin, args, env, words) in &cases {
        let r = spawn(bin, args, env, &dir);
        let name = Path::new(bin).file_name().unwrap().to_string_lossy();
        eprintln!(
            "{name} {}: exit {:?}, signal {:?}, {:.2} s: {}",
            args.join(" "),
            r.code,
            r.signal,
            r.seconds,
            r.stderr.trim().replace('\n', " | ")
        );
        // Refused before any work: within the 2 s of the acceptance, not the guard.
        let ok_exit = r.signal.is_none()
            && matches!(r.code, Some(c) if c != 0 && c != 134)
            && r.seconds < 2.0;
        let missing: Vec<_> = words.iter().filter(|w| !r.stderr.contains(*w)).collect();
        if !ok_exit || !missing.is_empty() {
            problems.push(format!(
                "{name} {args:?}: exit {:?} signal {:?} after {:.2} s, missing {missing:?} in: {}",
                r.code, r.signal, r.seconds, r.stderr
            ));
        }
    }
    assert!(
        !dir.join("out").exists(),
        "a refused run created its output directory"
    );
    let _ = std::fs::remove_dir_all(&dir);
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// Every file under `dir` (relative path → bytes).
fn snapshot(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    fn walk(root: &Path, d: &Path, out: &mut BTreeMap<PathBuf, Vec<u8>>) {
        for e in std::fs::read_dir(d).unwrap().flatten() {
            let p = e.path();
            if p.is_dir() {
                walk(root, &p, out);
            } else {
                out.insert(
                    p.strip_prefix(root).unwrap().to_path_buf(),
                    std::fs::read(&p).unwrap(),
                );
            }
        }
    }
    let mut m = BTreeMap::new();
    walk(dir, dir, &mut m);
    m
}

/// The hidden siblings of `out` (`.<name>.*`): lock, staging and moved-aside directories.
fn siblings(out: &Path) -> Vec<PathBuf> {
    let name = out.file_name().unwrap().to_string_lossy().into_owned();
    std::fs::read_dir(out.parent().unwrap())
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            p.file_name()
                .unwrap()
                .to_string_lossy()
                .starts_with(&format!(".{name}."))
        })
        .collect()
}

#[test]
fn interrupted_concurrent_and_shrinking_runs_keep_results_consistent() {
    let bin = env!("CARGO_BIN_EXE_point_source_analytic");
    let dir = tmp("atomic");
    let out = dir.join("results").join("point_source_analytic");
    let o = out.display().to_string();
    let args = ["--quick", "--no-progress", "--out", o.as_str()];
    let exit_code = experiments::common::TEST_EXIT_CODE;

    // A first complete run, plus a file no run of this binary writes (an "earlier run's").
    let r = spawn(bin, &args, &[], &dir);
    assert_eq!(r.code, Some(0), "{}", r.stderr);
    std::fs::write(out.join("stale_from_earlier_run.png"), b"old").unwrap();
    let before = snapshot(&out);
    assert!(before.len() >= 3, "{:?}", before.keys());

    // Interrupt at every step of the output layer until a run gets through.
    let mut interrupted = 0;
    let mut completed = false;
    for k in 1..=60u32 {
        let ks = k.to_string();
        let r = spawn(
            bin,
            &args,
            &[(experiments::common::TEST_EXIT_ENV, ks.as_str())],
            &dir,
        );
        if r.code == Some(0) {
            completed = true;
            break;
        }
        assert_eq!(r.code, Some(exit_code), "step {k}: {}", r.stderr);
        interrupted += 1;
        if out.exists() {
            assert_eq!(snapshot(&out), before, "step {k}: results changed");
        } else {
            // Killed between the two renames of the commit: the old results sit intact
            // beside it, and the next run's start puts them back (it is killed at once).
            let aside: Vec<_> = siblings(&out)
                .into_iter()
                .filter(|p| p.to_string_lossy().contains(".old-"))
                .collect();
            assert_eq!(aside.len(), 1, "step {k}: {aside:?}");
            assert_eq!(
                snapshot(&aside[0]),
                before,
                "step {k}: moved-aside results changed"
            );
            let r = spawn(
                bin,
                &args,
                &[(experiments::common::TEST_EXIT_ENV, "1")],
                &dir,
            );
            assert_eq!(r.code, Some(exit_code), "{}", r.stderr);
            assert_eq!(snapshot(&out), before, "step {k}: not restored");
        }
    }
    assert!(completed, "no run completed");
    assert!(interrupted >= 4, "only {interrupted} interruption points");
    eprintln!("interrupted at {interrupted} points, results intact after each");
    let after = snapshot(&out);
    assert!(
        !after.contains_key(Path::new("stale_from_earlier_run.png")),
        "a stale file survived the rerun"
    );
    for f in before
        .keys()
        .filter(|f| f.to_string_lossy() != "stale_from_earlier_run.png")
    {
        assert!(after.contains_key(f), "{f:?} missing after the rerun");
    }
    assert!(siblings(&out).is_empty(), "leftovers: {:?}", siblings(&out));

    // A second writer while the lock is held (by this test's own, live process) fails.
    let lock = out.parent().unwrap().join(".point_source_analytic.lock");
    std::fs::write(&lock, std::process::id().to_string()).unwrap();
    let held = snapshot(&out);
    let r = spawn(bin, &args, &[], &dir);
    assert!(
        r.code.is_some_and(|c| c != 0 && c != exit_code),
        "{:?}: {}",
        r.code,
        r.stderr
    );
    assert!(
        r.stderr.contains("another run is writing into"),
        "{}",
        r.stderr
    );
    assert_eq!(snapshot(&out), held, "the refused run touched the results");
    assert!(lock.exists(), "the refused run removed the holder's lock");

    // A lock left by a process that no longer exists is taken over.
    let mut dead = Command::new("true").spawn().unwrap();
    let dead_pid = dead.id();
    dead.wait().unwrap();
    std::fs::write(&lock, dead_pid.to_string()).unwrap();
    let r = spawn(bin, &args, &[], &dir);
    assert_eq!(r.code, Some(0), "{}", r.stderr);
    assert!(!lock.exists());

    // Two real runs at once: at most one may fail, and only with the lock message; the
    // results are one complete run's.
    let children: Vec<_> = (0..2)
        .map(|i| {
            let log = dir.join(format!("concurrent-{i}.log"));
            let child = Command::new(bin)
                .args(args)
                .current_dir(&dir)
                .env_remove(experiments::common::TEST_EXIT_ENV)
                .stdout(Stdio::null())
                .stderr(std::fs::File::create(&log).unwrap())
                .spawn()
                .unwrap();
            (child, log)
        })
        .collect();
    let mut ok = 0;
    for (mut child, log) in children {
        let t = Instant::now();
        let status = loop {
            if let Some(s) = child.try_wait().unwrap() {
                break s;
            }
            if t.elapsed() > Duration::from_secs(60) {
                let _ = child.kill();
                panic!("concurrent run hung");
            }
            std::thread::sleep(Duration::from_millis(10));
        };
        let err = std::fs::read_to_string(&log).unwrap();
        if status.success() {
            ok += 1;
        } else {
            assert!(err.contains("another run is writing into"), "{err}");
        }
    }
    assert!(ok >= 1, "neither concurrent run succeeded");
    assert_eq!(
        snapshot(&out).keys().collect::<Vec<_>>(),
        held.keys().collect::<Vec<_>>()
    );
    let _ = std::fs::remove_dir_all(&dir);
}
