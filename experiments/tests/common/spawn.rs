//! Spawning the experiments' binaries under a time guard, for the tests that drive them as
//! a user would (hostile input, bounded work, flag checks).
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

use std::os::unix::process::ExitStatusExt as _;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// The guard: a child still running after this is killed and the test fails.
pub const GUARD: Duration = Duration::from_secs(10);

/// How a spawned binary ended.
pub struct Outcome {
    pub code: Option<i32>,
    pub signal: Option<i32>,
    pub stderr: String,
    pub seconds: f64,
}

/// Runs `bin` with `args` in `cwd` (stderr to a file, so no pipe can fill), under the guard.
pub fn spawn(bin: &str, args: &[&str], env: &[(&str, &str)], cwd: &Path) -> Outcome {
    let log = cwd.join(format!(
        ".stderr-{}-{}",
        Path::new(bin).file_name().unwrap().to_string_lossy(),
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap()
            .as_nanos()
    ));
    let mut cmd = Command::new(bin);
    cmd.args(args)
        .current_dir(cwd)
        .env_remove("SCATTERBENCH_MEMORY_BUDGET")
        .env_remove("SCATTERBENCH_WORK_BUDGET")
        .env_remove(experiments::common::TEST_EXIT_ENV)
        .env("RUST_BACKTRACE", "0")
        .env("RUST_LIB_BACKTRACE", "0")
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(&log).unwrap());
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
        std::thread::sleep(Duration::from_millis(10));
    };
    let seconds = t.elapsed().as_secs_f64();
    let stderr = std::fs::read_to_string(&log).unwrap_or_default();
    let _ = std::fs::remove_file(&log);
    Outcome {
        code: status.code(),
        signal: status.signal(),
        stderr,
        seconds,
    }
}
