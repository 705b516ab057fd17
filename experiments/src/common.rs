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

/// The `--backend` flag of every experiment that runs a grid solver.
#[derive(Debug, Clone, clap::Args)]
pub struct BackendArgs {
    /// Where the solvers run: `cpu`, `gpu` (wgpu, f32; adapter from WGPU_ADAPTER_NAME /
    /// WGPU_BACKEND) or `both`. `--precision` applies to CPU runs; GPU runs are f32.
    #[arg(long, default_value = "cpu")]
    pub backend: String,
}

/// The backends an experiment runs on, with the GPU context they borrow.
#[derive(Debug)]
pub struct Backends {
    cpu: bool,
    gpu: Option<solvers::gpu::GpuContext>,
}

impl BackendArgs {
    /// Parses the flag and opens the GPU if one is asked for (an error, with the reason,
    /// if there is none).
    pub fn open(&self) -> Result<Backends> {
        let (cpu, gpu) = match self.backend.trim() {
            "cpu" => (true, false),
            "gpu" => (false, true),
            "both" => (true, true),
            other => anyhow::bail!("--backend must be cpu, gpu or both, got `{other}`"),
        };
        let gpu = if gpu {
            let ctx =
                solvers::gpu::GpuContext::from_env().context("opening the GPU for --backend")?;
            Some(ctx)
        } else {
            None
        };
        Ok(Backends { cpu, gpu })
    }
}

impl Backends {
    /// The selected backends, CPU first; the CPU one in `cpu_precision`.
    pub fn list(&self, cpu_precision: solvers::Precision) -> Vec<solvers::Backend<'_>> {
        let mut v = Vec::new();
        if self.cpu {
            v.push(solvers::Backend::Cpu(cpu_precision));
        }
        if let Some(ctx) = &self.gpu {
            v.push(solvers::Backend::Gpu(ctx));
        }
        v
    }

    /// File-name suffix for the plots of `backend`: empty for the first backend in the list,
    /// `_gpu` for the GPU when the CPU also runs.
    pub fn plot_suffix(&self, backend: &str) -> &'static str {
        if backend == "gpu" && self.cpu {
            "_gpu"
        } else {
            ""
        }
    }

    /// What `meta.json` records: the backends, and the adapter's name, backend, type, driver
    /// and timer when a GPU is used.
    pub fn meta(&self) -> serde_json::Value {
        let gpu = self.gpu.as_ref().map(|ctx| {
            let i = ctx.info();
            serde_json::json!({
                "adapter": i.name,
                "backend": format!("{:?}", i.backend),
                "device_type": format!("{:?}", i.device_type),
                "driver": i.driver,
                "driver_info": i.driver_info,
                "timer": ctx.timer().to_string(),
            })
        });
        serde_json::json!({ "cpu": self.cpu, "gpu": gpu })
    }
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
    extra: serde_json::Map<String, serde_json::Value>,
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
            extra: serde_json::Map::new(),
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

    /// Adds a top-level entry to `meta.json` (e.g. `backends` with the GPU adapter).
    pub fn record(&mut self, key: &str, value: serde_json::Value) {
        self.extra.insert(key.to_string(), value);
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
        let mut meta = serde_json::json!({
            "experiment": self.name,
            "command": std::env::args().collect::<Vec<_>>(),
            "parameters": self.params,
            "git_revision": git_revision(),
            "machine": machine(),
            "timings_seconds": self.timings.iter().map(|(k, v)| serde_json::json!({"what": k, "seconds": v})).collect::<Vec<_>>(),
            "wall_seconds": self.started.elapsed().as_secs_f64(),
            "crate_version": env!("CARGO_PKG_VERSION"),
        });
        if let Some(m) = meta.as_object_mut() {
            m.extend(self.extra.clone());
        }
        let path = self.path("meta.json");
        std::fs::write(&path, serde_json::to_string_pretty(&meta)?)
            .with_context(|| format!("writing {}", path.display()))?;
        Ok(())
    }
}

/// The column names (header row) of a CSV file, for checking an experiment's interface.
pub fn csv_header(path: &Path) -> Result<Vec<String>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    Ok(text
        .lines()
        .next()
        .unwrap_or_default()
        .split(',')
        .map(str::to_string)
        .collect())
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
