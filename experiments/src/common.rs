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

/// Where the grid solvers run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum BackendChoice {
    /// The CPU, in the experiment's `--precision`.
    Cpu,
    /// The GPU (wgpu, f32).
    Gpu,
    /// Both, CPU first.
    Both,
}

impl std::fmt::Display for BackendChoice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            BackendChoice::Cpu => "cpu",
            BackendChoice::Gpu => "gpu",
            BackendChoice::Both => "both",
        })
    }
}

/// A `--precision` flag's value.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum PrecisionArg {
    /// `f32`.
    F32,
    /// `f64`.
    F64,
}

impl PrecisionArg {
    /// The solvers' precision.
    pub fn precision(self) -> solvers::Precision {
        match self {
            PrecisionArg::F32 => solvers::Precision::F32,
            PrecisionArg::F64 => solvers::Precision::F64,
        }
    }

    /// `f32` or `f64`.
    pub fn name(self) -> &'static str {
        self.precision().name()
    }
}

/// The `--backend` flag of every experiment that runs a grid solver.
#[derive(Debug, Clone, clap::Args)]
pub struct BackendArgs {
    /// Where the solvers run: `cpu`, `gpu` (wgpu, f32; adapter from WGPU_ADAPTER_NAME /
    /// WGPU_BACKEND) or `both`. `--precision` applies to CPU runs; GPU runs are f32.
    #[arg(long, value_enum, default_value_t = BackendChoice::Cpu)]
    pub backend: BackendChoice,
}

/// The backends an experiment runs on, with the GPU context they borrow.
#[derive(Debug)]
pub struct Backends {
    cpu: bool,
    gpu: Option<solvers::gpu::GpuContext>,
}

impl BackendArgs {
    /// Opens the GPU if one is asked for (an error, with the reason, if there is none).
    pub fn open(&self) -> Result<Backends> {
        let (cpu, gpu) = match self.backend {
            BackendChoice::Cpu => (true, false),
            BackendChoice::Gpu => (false, true),
            BackendChoice::Both => (true, true),
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

    /// The plot-file suffixes a run writes (see [`Backends::plot_suffix`]): `""`, and
    /// `"_gpu"` too with `both`.
    pub fn plot_suffixes(&self) -> Vec<&'static str> {
        match self.backend {
            BackendChoice::Both => vec!["", "_gpu"],
            _ => vec![""],
        }
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

/// The context an experiment runs in: its output directory, its provenance record
/// (`meta.json`: parameters, timings, backends), and its progress bars.
///
/// [`crate::experiment::run`] makes one from the shared flags, hands it to
/// [`Experiment::run`](crate::experiment::Experiment::run), and writes `meta.json` when the
/// run returns. The directory is created by [`Ctx::start`], once the flags are validated.
#[derive(Debug)]
pub struct Ctx {
    /// Where files go.
    pub dir: PathBuf,
    name: String,
    quick: bool,
    no_progress: bool,
    started: Instant,
    timings: Vec<(String, f64)>,
    params: serde_json::Value,
    extra: serde_json::Map<String, serde_json::Value>,
}

/// The former name of [`Ctx`].
pub type Output = Ctx;

impl Ctx {
    /// The context of experiment `name`: `args.out`, or `results/<name>` (not created yet).
    pub fn for_run(name: &str, args: &CommonArgs) -> Self {
        let dir = args
            .out
            .clone()
            .unwrap_or_else(|| workspace_root().join("results").join(name));
        Self {
            dir,
            name: name.to_string(),
            quick: args.quick,
            no_progress: args.no_progress,
            started: Instant::now(),
            timings: Vec::new(),
            params: serde_json::Value::Null,
            extra: serde_json::Map::new(),
        }
    }

    /// [`Ctx::for_run`] then [`Ctx::start`] (for callers outside the registry).
    pub fn new(name: &str, args: &CommonArgs, params: impl Serialize) -> Result<Self> {
        let mut ctx = Self::for_run(name, args);
        ctx.start(params)?;
        Ok(ctx)
    }

    /// Records the run's resolved parameters for `meta.json` and creates the directory.
    pub fn start(&mut self, params: impl Serialize) -> Result<()> {
        std::fs::create_dir_all(&self.dir)
            .with_context(|| format!("creating output directory {}", self.dir.display()))?;
        self.params = serde_json::to_value(params).context("serialising parameters")?;
        Ok(())
    }

    /// Whether this is a CI-sized (`--quick`) run.
    pub fn quick(&self) -> bool {
        self.quick
    }

    /// Opens the backends of `--backend` and records them (with the GPU adapter) in
    /// `meta.json`.
    pub fn backends(&mut self, args: &BackendArgs) -> Result<Backends> {
        let b = args.open()?;
        self.record("backends", b.meta());
        Ok(b)
    }

    /// A progress bar over `len` steps (hidden with `--no-progress` or when stderr is no
    /// terminal).
    pub fn progress(&self, len: u64, what: &str) -> ProgressBar {
        bar(len, self.no_progress, what)
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
    bar(len, args.no_progress, what)
}

fn bar(len: u64, hidden: bool, what: &str) -> ProgressBar {
    if hidden {
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

/// Parses one item of a comma-separated list flag (`value_parser = list_item::<f64>`, with
/// `value_delimiter = ','`): surrounding blanks are ignored, an empty item is an error (so
/// an empty list is one too).
pub fn list_item<T: std::str::FromStr>(s: &str) -> std::result::Result<T, String>
where
    T::Err: std::fmt::Display,
{
    let t = s.trim();
    if t.is_empty() {
        return Err("empty list item (give at least one value, comma-separated)".into());
    }
    t.parse::<T>()
        .map_err(|e| format!("cannot parse `{t}`: {e}"))
}

/// The command-line spellings of `values`, comma-separated (`zero,analytic`), for
/// `meta.json`.
pub fn value_names<T: clap::ValueEnum>(values: &[T]) -> String {
    values
        .iter()
        .filter_map(|v| v.to_possible_value().map(|p| p.get_name().to_string()))
        .collect::<Vec<_>>()
        .join(",")
}

/// Parses a comma-separated list (`"0.1,0.5"`), naming the flag in errors; an empty list is
/// an error.
pub fn parse_list<T: std::str::FromStr>(flag: &str, s: &str) -> Result<Vec<T>>
where
    T::Err: std::fmt::Display,
{
    let v: Vec<T> = s
        .split(',')
        .filter(|t| !t.trim().is_empty())
        .map(|t| {
            t.trim()
                .parse::<T>()
                .map_err(|e| anyhow::anyhow!("--{flag}: cannot parse `{t}`: {e}"))
        })
        .collect::<Result<_>>()?;
    if v.is_empty() {
        anyhow::bail!("--{flag}: give at least one value (comma-separated)");
    }
    Ok(v)
}
