//! Shared plumbing: output directories, provenance (`meta.json`), CSV writing, progress bars.

use anyhow::{Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Flags every experiment takes.
#[derive(Debug, Clone, clap::Args)]
pub struct CommonArgs {
    /// Output directory (default `results/<experiment name>` under the workspace root).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// CI-sized run: small grids, few parameter values.
    #[arg(long)]
    pub quick: bool,
    /// Hide progress bars (they are also hidden when stderr is not a terminal).
    #[arg(long)]
    pub no_progress: bool,
}

/// The workspace root (parent of this crate's manifest directory).
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_else(|| PathBuf::from("."))
}

/// An experiment's output directory, created on construction, plus its provenance record.
#[derive(Debug)]
pub struct Output {
    /// Where files go.
    pub dir: PathBuf,
    name: String,
    started: Instant,
    timings: Vec<(String, f64)>,
    params: serde_json::Value,
}

impl Output {
    /// Creates `args.out` or `results/<name>`.
    pub fn new(name: &str, args: &CommonArgs, params: impl Serialize) -> Result<Self> {
        let dir = args
            .out
            .clone()
            .unwrap_or_else(|| workspace_root().join("results").join(name));
        std::fs::create_dir_all(&dir)
            .with_context(|| format!("creating output directory {}", dir.display()))?;
        let params = serde_json::to_value(params).context("serialising parameters")?;
        Ok(Self {
            dir,
            name: name.to_string(),
            started: Instant::now(),
            timings: Vec::new(),
            params,
        })
    }

    /// Path of a file in the output directory.
    pub fn path(&self, file: &str) -> PathBuf {
        self.dir.join(file)
    }

    /// Records a named timing for `meta.json`.
    pub fn timing(&mut self, what: impl Into<String>, seconds: f64) {
        self.timings.push((what.into(), seconds));
    }

    /// Writes rows as CSV (header from the struct's field names).
    pub fn csv<T: Serialize>(&self, file: &str, rows: &[T]) -> Result<()> {
        let path = self.path(file);
        let mut w = csv::Writer::from_path(&path)
            .with_context(|| format!("creating {}", path.display()))?;
        for r in rows {
            w.serialize(r)
                .with_context(|| format!("writing {}", path.display()))?;
        }
        w.flush()
            .with_context(|| format!("writing {}", path.display()))?;
        Ok(())
    }

    /// Writes `meta.json`: experiment, command line, parameters, git revision, machine,
    /// timings and total wall time.
    pub fn finish(&self) -> Result<()> {
        let meta = serde_json::json!({
            "experiment": self.name,
            "command": std::env::args().collect::<Vec<_>>(),
            "parameters": self.params,
            "git_revision": git_revision(),
            "machine": machine(),
            "timings_seconds": self.timings.iter().map(|(k, v)| serde_json::json!({"what": k, "seconds": v})).collect::<Vec<_>>(),
            "wall_seconds": self.started.elapsed().as_secs_f64(),
            "crate_version": env!("CARGO_PKG_VERSION"),
        });
        let path = self.path("meta.json");
        std::fs::write(&path, serde_json::to_string_pretty(&meta)?)
            .with_context(|| format!("writing {}", path.display()))?;
        Ok(())
    }
}

/// `git describe --always --dirty` of the workspace, or "unknown" outside a checkout.
pub fn git_revision() -> String {
    std::process::Command::new("git")
        .args(["describe", "--always", "--dirty", "--abbrev=12"])
        .current_dir(workspace_root())
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
        .unwrap_or_else(|| "unknown".to_string())
}

/// Host name, CPU model, logical cores, OS and architecture.
pub fn machine() -> serde_json::Value {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|s| s.trim().to_string())
        })
        .unwrap_or_else(|| "unknown".to_string());
    let host = std::fs::read_to_string("/etc/hostname")
        .map(|s| s.trim().to_string())
        .unwrap_or_else(|_| "unknown".to_string());
    serde_json::json!({
        "hostname": host,
        "cpu": cpu,
        "logical_cores": std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1),
        "rayon_threads": rayon::current_num_threads(),
        "os": std::env::consts::OS,
        "arch": std::env::consts::ARCH,
    })
}

/// A progress bar over `len` steps (hidden with `--no-progress` or when stderr is no terminal).
pub fn progress(len: u64, args: &CommonArgs, what: &str) -> ProgressBar {
    if args.no_progress {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::new(len);
    if let Ok(style) =
        ProgressStyle::with_template("{prefix:>18} [{elapsed_precise}] {bar:30} {pos}/{len} {msg}")
    {
        pb.set_style(style);
    }
    pb.set_prefix(what.to_string());
    pb
}

/// Parses a comma-separated list (`"0.1,0.5"`), naming the flag in errors.
pub fn parse_list<T: std::str::FromStr>(flag: &str, s: &str) -> Result<Vec<T>>
where
    T::Err: std::fmt::Display,
{
    s.split(',')
        .filter(|t| !t.trim().is_empty())
        .map(|t| {
            t.trim()
                .parse::<T>()
                .map_err(|e| anyhow::anyhow!("--{flag}: cannot parse `{t}`: {e}"))
        })
        .collect()
}
