//! Spawning the experiments' binaries under a time guard, for the tests that drive them as
//! a user would (hostile input, bounded work, flag checks, error messages).
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

use std::os::unix::process::ExitStatusExt as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// The guard: a child still running after this is killed and the test fails.
pub const GUARD: Duration = Duration::from_secs(20);

/// How a spawned binary ended.
pub struct Outcome {
    /// Exit code (`None` after a signal).
    pub code: Option<i32>,
    /// The signal that ended it, if any.
    pub signal: Option<i32>,
    /// Its standard output.
    pub stdout: String,
    /// Its standard error.
    pub stderr: String,
    /// Wall seconds from spawn to exit.
    pub seconds: f64,
}

/// The workspace root.
pub fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf()
}

/// A fresh, empty directory for one test (`<tmp>/scatterbench-<tag>-<pid>`).
pub fn scratch(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("scatterbench-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Runs `bin` with `args` in `cwd`, `env` set (the budgets, the exit hook and backtraces
/// cleared first); see [`spawn_with`].
pub fn spawn(bin: &str, args: &[&str], env: &[(&str, &str)], cwd: &Path) -> Outcome {
    spawn_with(bin, args, env, &[], cwd)
}

/// Runs `bin` with `args` in `cwd`, with `env` set and `unset` removed, stdin closed and
/// its output in files (no pipe can fill), under [`GUARD`].
pub fn spawn_with(
    bin: &str,
    args: &[&str],
    env: &[(&str, &str)],
    unset: &[&str],
    cwd: &Path,
) -> Outcome {
    let stamp = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_nanos();
    let name = Path::new(bin).file_name().unwrap().to_string_lossy();
    let (out_log, err_log) = (
        cwd.join(format!(".stdout-{name}-{stamp}")),
        cwd.join(format!(".stderr-{name}-{stamp}")),
    );
    let mut cmd = Command::new(bin);
    cmd.args(args)
        .current_dir(cwd)
        .env_remove("SCATTERBENCH_MEMORY_BUDGET")
        .env_remove("SCATTERBENCH_WORK_BUDGET")
        .env_remove(experiments::common::TEST_EXIT_ENV)
        .env("RUST_BACKTRACE", "0")
        .env("RUST_LIB_BACKTRACE", "0")
        .stdin(Stdio::null())
        .stdout(std::fs::File::create(&out_log).unwrap())
        .stderr(std::fs::File::create(&err_log).unwrap());
    for k in unset {
        cmd.env_remove(k);
    }
    for (k, v) in env {
        cmd.env(k, v);
    }
    let t = Instant::now();
    let mut child = cmd.spawn().unwrap();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if t.elapsed() > GUARD {
            let _ = child.kill();
            let _ = child.wait();
            panic!("{bin} {args:?} still running after {GUARD:?}");
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    let seconds = t.elapsed().as_secs_f64();
    let read = |p: &Path| {
        let s = std::fs::read_to_string(p).unwrap_or_default();
        let _ = std::fs::remove_file(p);
        s
    };
    Outcome {
        code: status.code(),
        signal: status.signal(),
        stdout: read(&out_log),
        stderr: read(&err_log),
        seconds,
    }
}
