//! Shared plumbing: output directories, provenance (`meta.json`), CSV writing, progress bars.

use anyhow::{Context, Result};
use indicatif::ProgressBar;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Flags every experiment takes.
#[derive(Debug, Clone, clap::Args)]
pub struct CommonArgs {
    /// Output directory (default `results/<experiment name>` in the current directory;
    /// `results-quick/<experiment name>` with `--quick`). A run writes into a fresh hidden
    /// sibling and renames it into place at the end; a second run into the same directory
    /// at the same time is refused.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// CI-sized run: small grids, few parameter values.
    #[arg(long)]
    pub quick: bool,
    /// Hide progress: the bars on a terminal, and the plain lines written instead when stderr
    /// is not one (at most one every `SCATTERBENCH_PROGRESS_SECONDS`, default 60; 0 = none).
    #[arg(long)]
    pub no_progress: bool,
    /// Run even when the cost estimate exceeds the work budget (see `experiments::cost`:
    /// 4 h of this machine's cores at a nominal rate, or `SCATTERBENCH_WORK_BUDGET`
    /// operations).
    #[arg(long)]
    pub force: bool,
    /// Compute only shard `i` of `N` (0-based) of the run's Monte Carlo batches and write
    /// them as `shard.bin` (default `--out`: `<default>.shard-i-of-N`); `merge` joins the N
    /// shards into the files an unsharded run writes. Only Monte Carlo producers take it.
    #[arg(long, value_parser = parse_shard)]
    pub shard: Option<reference::pathtracer::Shard>,
    /// Print the run's cost estimate (one JSON line: operations, and seconds on one core at
    /// the nominal rate; for `--shard`, one shard's part) and exit without running it.
    /// `slurm/submit` sizes its time requests from it.
    #[arg(long)]
    pub estimate: bool,
}

/// Returned when a run only prints what was asked (`--estimate` from [`Ctx::work`],
/// `--list-tasks`) and is not made: the binaries exit 0 on it.
#[derive(Debug, thiserror::Error)]
#[error("{0}: printed, the run is not made")]
pub struct PrintOnly(pub &'static str);

/// A binary's result with [`PrintOnly`] turned into success.
pub fn estimate_ok(r: Result<()>) -> Result<()> {
    match r {
        Err(e) if e.downcast_ref::<PrintOnly>().is_some() => Ok(()),
        other => other,
    }
}

fn parse_shard(s: &str) -> std::result::Result<reference::pathtracer::Shard, String> {
    s.parse()
        .map_err(|e: reference::ReferenceError| e.to_string())
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

/// Where results go when `--out` is not given: `results/<name>`, or `results-quick/<name>`
/// for `--quick` runs (so CI-sized runs never overwrite committed full results), relative
/// to the current directory.
pub fn default_out(name: &str, quick: bool) -> PathBuf {
    PathBuf::from(if quick { "results-quick" } else { "results" }).join(name)
}

/// The test hook that simulates an interrupted run: with `SCATTERBENCH_TEST_EXIT_AT=k`,
/// the process exits (code [`TEST_EXIT_CODE`], no cleanup, as after a kill) at the `k`-th
/// step of the output layer, counting from 1: each [`Ctx::path`] call (one per file written,
/// `meta.json` last), then the two renames that put the finished run in place.
pub const TEST_EXIT_ENV: &str = "SCATTERBENCH_TEST_EXIT_AT";

/// The exit code of the [`TEST_EXIT_ENV`] hook.
pub const TEST_EXIT_CODE: i32 = 86;

/// The context an experiment runs in: its output directory, its provenance record
/// (`meta.json`: parameters, timings, backends), and its progress bars.
///
/// [`crate::experiment::run`] makes one from the shared flags, hands it to
/// [`Experiment::run`](crate::experiment::Experiment::run), and writes `meta.json` when the
/// run returns. [`Ctx::start`], once the flags are validated, takes the lock of the target
/// directory and creates a fresh staging directory beside it; [`Ctx::finish`] writes
/// `meta.json` there and renames it into place, so the previous results stay intact until
/// the new ones are complete and no file of an earlier run survives.
#[derive(Debug)]
pub struct Ctx {
    /// Where files go: the staging directory once started (use [`Ctx::path`]).
    pub dir: PathBuf,
    target: PathBuf,
    staging: Option<Staging>,
    steps: std::cell::Cell<u64>,
    name: String,
    quick: bool,
    no_progress: bool,
    force: bool,
    estimate: bool,
    out_given: bool,
    argv: Option<Vec<String>>,
    started: Instant,
    timings: Vec<(String, f64)>,
    params: serde_json::Value,
    extra: serde_json::Map<String, serde_json::Value>,
    mc: crate::shard::Mc,
}

/// The former name of [`Ctx`].
pub type Output = Ctx;

/// A started run's lock file and staging directory (both removed on drop unless committed).
#[derive(Debug)]
struct Staging {
    lock: PathBuf,
    dir: PathBuf,
    committed: bool,
}

impl Drop for Staging {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_dir_all(&self.dir);
        }
        let _ = std::fs::remove_file(&self.lock);
    }
}

/// The directory `target` is in (`.` for a bare name).
fn parent_of(target: &Path) -> &Path {
    match target.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// `parent/.<file name of target>.<suffix>`.
fn sibling(target: &Path, suffix: &str) -> PathBuf {
    let name = target
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "out".to_string());
    parent_of(target).join(format!(".{name}.{suffix}"))
}

/// Whether process `pid` is alive (Linux `/proc`; elsewhere assumed alive).
fn alive(pid: u32) -> bool {
    if cfg!(target_os = "linux") {
        Path::new(&format!("/proc/{pid}")).exists()
    } else {
        true
    }
}

/// Takes the lock file of `target`: created exclusively with this process's id; a lock left
/// by a process that no longer exists is taken over.
fn lock(target: &Path) -> Result<PathBuf> {
    use std::io::Write as _;
    let path = sibling(target, "lock");
    for _ in 0..2 {
        match std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&path)
        {
            Ok(mut f) => {
                write!(f, "{}", std::process::id())
                    .with_context(|| format!("writing lock file {}", path.display()))?;
                return Ok(path);
            }
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                let holder = std::fs::read_to_string(&path)
                    .ok()
                    .and_then(|s| s.trim().parse::<u32>().ok());
                match holder {
                    Some(pid) if !alive(pid) => {
                        let _ = std::fs::remove_file(&path);
                    }
                    _ => anyhow::bail!(
                        "another run is writing into {} (lock file {}{}); wait for it to \
                         finish, or delete the lock file if no such run exists",
                        target.display(),
                        path.display(),
                        holder.map(|p| format!(", process {p}")).unwrap_or_default()
                    ),
                }
            }
            Err(e) => {
                return Err(e).with_context(|| format!("creating lock file {}", path.display()));
            }
        }
    }
    anyhow::bail!(
        "could not take the lock file {} of {}",
        path.display(),
        target.display()
    )
}

/// With the lock held: puts back results an interrupted commit moved aside, and removes the
/// staging directories of interrupted runs.
fn recover(target: &Path) -> Result<()> {
    let parent = parent_of(target);
    let Some(name) = target.file_name().map(|n| n.to_string_lossy().into_owned()) else {
        return Ok(());
    };
    let Ok(entries) = std::fs::read_dir(parent) else {
        return Ok(());
    };
    for e in entries.flatten() {
        let file = e.file_name().to_string_lossy().into_owned();
        let Some(rest) = file.strip_prefix(&format!(".{name}.")) else {
            continue;
        };
        let path = e.path();
        if rest.starts_with("old-") && !target.exists() {
            std::fs::rename(&path, target).with_context(|| {
                format!("restoring {} from {}", target.display(), path.display())
            })?;
        } else if rest.starts_with("old-") || rest.starts_with("partial-") {
            std::fs::remove_dir_all(&path)
                .with_context(|| format!("removing the leftover {}", path.display()))?;
        }
    }
    Ok(())
}

impl Ctx {
    /// The context of experiment `name`: `args.out`, or [`default_out`] (not created yet).
    pub fn for_run(name: &str, args: &CommonArgs) -> Self {
        let target = args.out.clone().unwrap_or_else(|| {
            let d = default_out(name, args.quick);
            match args.shard {
                Some(s) => {
                    let file = d.file_name().map(|n| n.to_string_lossy().into_owned());
                    d.with_file_name(format!(
                        "{}.shard-{}-of-{}",
                        file.unwrap_or_else(|| name.to_string()),
                        s.index(),
                        s.count()
                    ))
                }
                None => d,
            }
        });
        let mc = match args.shard {
            Some(shard) => crate::shard::Mc::Shard {
                shard,
                argv: Vec::new(),
                tallies: Vec::new(),
                task: None,
            },
            None => crate::shard::Mc::Whole,
        };
        Self {
            dir: target.clone(),
            target,
            staging: None,
            steps: std::cell::Cell::new(0),
            name: name.to_string(),
            quick: args.quick,
            no_progress: args.no_progress,
            force: args.force,
            estimate: args.estimate,
            out_given: args.out.is_some(),
            argv: None,
            started: Instant::now(),
            timings: Vec::new(),
            params: serde_json::Value::Null,
            extra: serde_json::Map::new(),
            mc,
        }
    }

    /// The run's command-line flags, for a shard's or task's header (`--out`, `--shard`,
    /// `--task` and cosmetic flags are dropped there).
    pub fn set_argv(&mut self, argv: &[String]) {
        self.argv = Some(argv.to_vec());
        if let crate::shard::Mc::Shard { argv: a, .. } = &mut self.mc {
            *a = crate::shard::strip_flags(argv);
        }
    }

    /// Serves this run's tallies from merged shards instead of computing them.
    pub fn merge_from(&mut self, joined: crate::shard::Joined) {
        self.mc = crate::shard::Mc::Merge {
            tallies: joined.tallies,
            provenance: joined.provenance,
            from_tasks: joined.from_tasks,
        };
    }

    /// Makes this a `--task K` run of a sweep of `count` tasks (before [`Ctx::start`]): only
    /// unit K ([`Ctx::unit`]) is computed, whole, and written as `shard.bin` for `merge`.
    /// Without `--out`, the output goes to `<default>.task-K`.
    pub fn set_task(&mut self, index: u32, count: u32) -> Result<()> {
        if index >= count {
            anyhow::bail!(
                "--task {index}: this sweep has {count} tasks (0 … {}; see --list-tasks)",
                count.saturating_sub(1)
            );
        }
        if !matches!(self.mc, crate::shard::Mc::Whole) {
            anyhow::bail!("--task cannot be combined with --shard");
        }
        let Some(argv) = self.argv.clone() else {
            anyhow::bail!("--task needs the command line (run the binary)");
        };
        if !self.out_given {
            let file = self
                .target
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_else(|| self.name.clone());
            self.target = self.target.with_file_name(format!("{file}.task-{index}"));
            self.dir = self.target.clone();
        }
        self.mc = crate::shard::Mc::Shard {
            shard: reference::pathtracer::Shard::WHOLE,
            argv: crate::shard::strip_flags(&argv),
            tallies: Vec::new(),
            task: Some(crate::shard::TaskSel {
                index,
                count,
                seen: 0,
            }),
        };
        Ok(())
    }

    /// Starts the next unit of a sweep (one line of `--list-tasks`); returns whether this
    /// run computes it (always, except in a `--task K` run: only unit K).
    pub fn unit(&mut self) -> bool {
        match &mut self.mc {
            crate::shard::Mc::Shard { task: Some(t), .. } => {
                let mine = t.seen == t.index;
                t.seen += 1;
                mine
            }
            _ => true,
        }
    }

    /// Whether this run computes one shard (`--shard`) or one task (`--task`): it then
    /// writes no results, only its tallies, so a producer skips its output once every
    /// tally is taken.
    pub fn sharding(&self) -> bool {
        matches!(self.mc, crate::shard::Mc::Shard { .. })
    }

    /// The run's next Monte Carlo estimate, `label`led: `compute(shard)` returns the
    /// per-batch sums of its parts for a shard's batches (the whole run: `Shard::WHOLE`),
    /// `finish` turns joined sums into the estimate. A normal run computes and finishes;
    /// with `--shard` the sums are kept for the shard file and `None` comes back; in a
    /// merge the joined sums of the shards are finished (and `compute` never runs).
    pub fn tally<T>(
        &mut self,
        label: &str,
        compute: impl FnOnce(reference::pathtracer::Shard) -> Result<Vec<reference::effects::PassSums>>,
        finish: impl FnOnce(&[reference::effects::PassSums]) -> Result<T>,
    ) -> Result<Option<T>> {
        use crate::shard::Mc;
        match &mut self.mc {
            Mc::Whole => {
                let parts = compute(reference::pathtracer::Shard::WHOLE)?;
                finish(&parts).map(Some)
            }
            Mc::Shard {
                shard,
                tallies,
                task,
                ..
            } => {
                // In a `--task K` run, only unit K's tallies are computed.
                if task.is_some_and(|t| t.seen != t.index + 1) {
                    return Ok(None);
                }
                let parts = compute(*shard)?;
                tallies.push(crate::shard::Tally {
                    label: label.to_string(),
                    parts,
                    note: String::new(),
                });
                Ok(None)
            }
            Mc::Merge { tallies, .. } => {
                let t = crate::shard::next_stored(tallies, label)?;
                finish(&t.parts).map(Some)
            }
        }
    }

    /// A deterministic unit of a sweep (a grid render of the atlas), `label`led:
    /// `compute` returns its result as exact f64 arrays and a note, `finish` rebuilds it.
    /// A normal run computes and finishes; a `--task K` run computes and keeps it when it
    /// is unit K (else skips it); a `--shard` run skips it (the merge computes it); a merge
    /// of tasks finishes the stored result, a merge of shards computes it.
    pub fn deterministic<T>(
        &mut self,
        label: &str,
        compute: impl FnOnce() -> Result<(Vec<reference::effects::PassSums>, String)>,
        finish: impl FnOnce(&[reference::effects::PassSums], &str) -> Result<T>,
    ) -> Result<Option<T>> {
        use crate::shard::Mc;
        match &mut self.mc {
            Mc::Whole
            | Mc::Merge {
                from_tasks: false, ..
            } => {
                let (parts, note) = compute()?;
                finish(&parts, &note).map(Some)
            }
            Mc::Shard { task: None, .. } => Ok(None),
            Mc::Shard {
                task: Some(t),
                tallies,
                ..
            } => {
                if t.seen != t.index + 1 {
                    return Ok(None);
                }
                let (parts, note) = compute()?;
                tallies.push(crate::shard::Tally {
                    label: label.to_string(),
                    parts,
                    note,
                });
                Ok(None)
            }
            Mc::Merge {
                tallies,
                from_tasks: true,
                ..
            } => {
                let t = crate::shard::next_stored(tallies, label)?;
                finish(&t.parts, &t.note).map(Some)
            }
        }
    }

    /// [`Ctx::for_run`] then [`Ctx::start`] (for callers outside the registry).
    pub fn new(name: &str, args: &CommonArgs, params: impl Serialize) -> Result<Self> {
        let mut ctx = Self::for_run(name, args);
        ctx.start(params)?;
        Ok(ctx)
    }

    /// Records the run's resolved parameters for `meta.json`, takes the lock of the output
    /// directory and creates the fresh staging directory the run writes into.
    pub fn start(&mut self, params: impl Serialize) -> Result<()> {
        self.params = serde_json::to_value(params).context("serialising parameters")?;
        if self.staging.is_some() {
            return Ok(());
        }
        let target = self.target.clone();
        let parent = parent_of(&target);
        std::fs::create_dir_all(parent)
            .with_context(|| format!("creating directory {}", parent.display()))?;
        if target.exists() && !target.is_dir() {
            anyhow::bail!("--out {} exists and is not a directory", target.display());
        }
        let lock = lock(&target)?;
        let dir = sibling(&target, &format!("partial-{}", std::process::id()));
        let staging = Staging {
            lock,
            dir: dir.clone(),
            committed: false,
        };
        recover(&target)?;
        std::fs::create_dir(&dir)
            .with_context(|| format!("creating output directory {}", dir.display()))?;
        self.dir = dir;
        self.staging = Some(staging);
        Ok(())
    }

    /// The output directory the run ends up in (`--out` or the default).
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// One step of the output layer, for the [`TEST_EXIT_ENV`] hook.
    fn step(&self) {
        let k = self.steps.get() + 1;
        self.steps.set(k);
        let at = std::env::var(TEST_EXIT_ENV)
            .ok()
            .and_then(|v| v.trim().parse::<u64>().ok());
        if at == Some(k) {
            eprintln!("{TEST_EXIT_ENV}={k}: exiting as if interrupted");
            std::process::exit(TEST_EXIT_CODE);
        }
    }

    /// Moves the finished staging directory into place (the old results aside, then away).
    fn commit(&mut self) -> Result<()> {
        let Some(mut staging) = self.staging.take() else {
            return Ok(());
        };
        let target = self.target.clone();
        let old = sibling(&target, &format!("old-{}", std::process::id()));
        let had_old = target.exists();
        self.step();
        if had_old {
            std::fs::rename(&target, &old)
                .with_context(|| format!("moving the previous {} aside", target.display()))?;
        }
        self.step();
        if let Err(e) = std::fs::rename(&staging.dir, &target) {
            if had_old {
                let _ = std::fs::rename(&old, &target);
            }
            return Err(e).with_context(|| {
                format!(
                    "moving {} into place as {}",
                    staging.dir.display(),
                    target.display()
                )
            });
        }
        staging.committed = true;
        self.dir = target;
        if had_old {
            std::fs::remove_dir_all(&old)
                .with_context(|| format!("removing the previous results {}", old.display()))?;
        }
        Ok(())
    }

    /// Checks the run's cost estimate against the work budget (refused unless `--force`)
    /// and records it in `meta.json` as `work_estimate`. Call it before the work starts.
    pub fn work(&mut self, estimate: &crate::cost::Estimate) -> Result<()> {
        if self.estimate {
            let mine = match &self.mc {
                crate::shard::Mc::Shard { shard, .. } => estimate.per_shard(shard.count()),
                _ => estimate.clone(),
            };
            let ops = mine.total();
            println!(
                "{}",
                serde_json::json!({
                    "experiment": self.name,
                    "operations": ops,
                    "seconds_one_core": ops / crate::cost::NOMINAL_RATE,
                    "nominal_rate_per_core": crate::cost::NOMINAL_RATE,
                })
            );
            return Err(PrintOnly("--estimate").into());
        }
        match &self.mc {
            crate::shard::Mc::Whole => estimate.check(self.force)?,
            // A shard does its part of the Monte Carlo (which dominates every producer).
            crate::shard::Mc::Shard { shard, .. } => {
                estimate.per_shard(shard.count()).check(self.force)?
            }
            // The shards did the Monte Carlo; a merge was accepted when they were.
            crate::shard::Mc::Merge { .. } => {}
        }
        self.record("work_estimate", estimate.meta());
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

    /// A progress bar over `len` steps (hidden with `--no-progress`; plain lines when stderr is
    /// no terminal, [`crate::progress`]).
    pub fn progress(&self, len: u64, what: &str) -> ProgressBar {
        crate::progress::bar(Some(len), self.no_progress, what)
    }

    /// A spinner with elapsed time for one long step without a step count (hidden like
    /// [`Ctx::progress`]); finish it with `finish_and_clear`.
    pub fn spinner(&self, what: &str) -> ProgressBar {
        crate::progress::bar(None, self.no_progress, what)
    }

    /// Path of a file in the output directory (the staging directory while the run is in
    /// progress).
    pub fn path(&self, file: &str) -> PathBuf {
        self.step();
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

    /// Writes `meta.json` (experiment, command line, parameters, git revision, machine,
    /// timings and total wall time), then renames the staging directory into place.
    pub fn finish(&mut self) -> Result<()> {
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
        match std::mem::take(&mut self.mc) {
            crate::shard::Mc::Whole => {}
            crate::shard::Mc::Shard {
                shard,
                argv,
                tallies,
                task,
            } => {
                if tallies.is_empty() && task.is_none() {
                    anyhow::bail!("{}: this run has no Monte Carlo tally to shard", self.name);
                }
                let header = crate::shard::header(&self.name, &argv, shard, task, &tallies);
                if let Some(m) = meta.as_object_mut() {
                    m.insert("shard".into(), serde_json::json!(shard.to_string()));
                }
                crate::shard::write(&self.path(crate::shard::SHARD_FILE), &header, &tallies)?;
            }
            crate::shard::Mc::Merge {
                tallies,
                provenance,
                ..
            } => {
                if let Some(t) = tallies.front() {
                    anyhow::bail!(
                        "the shards hold tallies this run did not take (first: `{}`): not \
                         shards of this run",
                        t.label
                    );
                }
                if let Some(m) = meta.as_object_mut() {
                    m.insert("merged_from".into(), provenance);
                }
            }
        }
        let path = self.path("meta.json");
        std::fs::write(&path, serde_json::to_string_pretty(&meta)?)
            .with_context(|| format!("writing {}", path.display()))?;
        self.commit()
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

/// The step (counting from 1) after which a residual history first fell below `tolerance`;
/// `None` where it never did.
pub fn first_below(history: &[f64], tolerance: f64) -> Option<usize> {
    history.iter().position(|&r| r < tolerance).map(|i| i + 1)
}

/// The workspace's revision (`git describe --always`), with `-dirty` when a tracked file
/// outside `results/` differs from it; "unknown" outside a checkout.
pub fn git_revision() -> String {
    git_revision_at(&workspace_root())
}

/// [`git_revision`] of the checkout at `dir`. *Why not `git describe --dirty`*: a `figures`
/// run rewrites the committed files under `results/` as it goes, so from its second
/// experiment on every `meta.json` said `-dirty` whatever the code was (the committed results
/// of 1da8410 and 516fb08 did); only a change to the code or the inputs makes a result's
/// revision unreliable.
fn git_revision_at(dir: &Path) -> String {
    let git = |args: &[&str]| {
        std::process::Command::new("git")
            .args(args)
            .current_dir(dir)
            .output()
            .ok()
            .filter(|o| o.status.success())
            .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
    };
    let Some(rev) = git(&["describe", "--always", "--abbrev=12"]) else {
        return "unknown".to_string();
    };
    let changed = git(&[
        "status",
        "--porcelain",
        "--untracked-files=no",
        "--",
        ".",
        ":(exclude)results",
    ]);
    match changed {
        Some(c) if c.is_empty() => rev,
        _ => format!("{rev}-dirty"),
    }
}

/// Host name, CPU model (with its x86 family and model numbers and cpu 0's L3 where Linux says:
/// a virtual machine's model name is often just "AMD EPYC", which hosts of this project have
/// worn with Zen 3 and Zen 5 cores of twice the bandwidth), logical cores, OS and
/// architecture.
pub fn machine() -> serde_json::Value {
    let cpuinfo = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
    let field = |key: &str| {
        cpuinfo
            .lines()
            .take_while(|l| !l.trim().is_empty())
            .find_map(|l| {
                let (k, v) = l.split_once(':')?;
                (k.trim() == key).then(|| v.trim().to_string())
            })
    };
    let cpu = field("model name").unwrap_or_else(|| "unknown".to_string());
    let cpu_id = match (field("cpu family"), field("model")) {
        (Some(f), Some(m)) => format!("family {f} model {m}"),
        _ => "unknown".to_string(),
    };
    // The last-level cache cpu 0 sees (on AMD one CCX's share, not the socket's).
    let cache = |f: &str| {
        std::fs::read_to_string(format!("/sys/devices/system/cpu/cpu0/cache/index3/{f}"))
            .map(|s| s.trim().to_string())
            .ok()
    };
    let l3 = match (cache("level").as_deref(), cache("size")) {
        (Some("3"), Some(size)) => size,
        _ => "unknown".to_string(),
    };
    let host = std::fs::read_to_string("/etc/hostname")
        .map(|s| s.trim().to_string())
        .unwrap_or_else(|_| "unknown".to_string());
    serde_json::json!({
        "hostname": host,
        "cpu": cpu,
        "cpu_id": cpu_id,
        "l3": l3,
        "logical_cores": std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1),
        "rayon_threads": rayon::current_num_threads(),
        "os": std::env::consts::OS,
        "arch": std::env::consts::ARCH,
    })
}

/// A progress bar over `len` steps (hidden with `--no-progress`; plain lines when stderr is no
/// terminal, [`crate::progress`]).
pub fn progress(len: u64, args: &CommonArgs, what: &str) -> ProgressBar {
    crate::progress::bar(Some(len), args.no_progress, what)
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

/// Parses a count flag (`value_parser = count`): a whole number ≥ 1, also in the float
/// notation the help texts use (`4e6`, `1e3`, `2.5e5`); `_` separators (`4_000_000`) are
/// accepted. Zero is refused: no count flag (paths, samples, steps, sizes) means anything
/// at 0.
pub fn count(s: &str) -> std::result::Result<u64, String> {
    let t = s.trim().replace('_', "");
    if let Ok(v) = t.parse::<u64>() {
        return if v >= 1 {
            Ok(v)
        } else {
            Err("must be at least 1".into())
        };
    }
    let v: f64 = t
        .parse()
        .map_err(|_| format!("`{s}` is not a count (write e.g. 4000000 or 4e6)"))?;
    if !(v.is_finite() && v >= 1.0 && v.fract() == 0.0 && v < 1.8e19) {
        return Err(format!("`{s}` is not a whole number in [1, 1.8e19)"));
    }
    Ok(v as u64)
}

/// [`count`] for `u32` flags (samples per pixel, batches).
pub fn count_u32(s: &str) -> std::result::Result<u32, String> {
    let v = count(s)?;
    u32::try_from(v).map_err(|_| format!("`{s}` is more than {}", u32::MAX))
}

/// [`count`] for `usize` flags (grid sizes, resolutions, step caps).
pub fn count_usize(s: &str) -> std::result::Result<usize, String> {
    let v = count(s)?;
    usize::try_from(v).map_err(|_| format!("`{s}` is too large"))
}

#[cfg(test)]
mod count_tests {
    use super::count;

    #[test]
    fn counts_in_float_notation() {
        assert_eq!(count("4e6"), Ok(4_000_000));
        assert_eq!(count("1e3"), Ok(1000));
        assert_eq!(count("2.5e5"), Ok(250_000));
        assert_eq!(count("4_000_000"), Ok(4_000_000));
        assert_eq!(count(" 64000 "), Ok(64_000));
        assert!(count("0").is_err());
        assert!(count("0e0").is_err());
        assert!(count("1.5").is_err());
        assert!(count("-1").is_err());
        assert!(count("1e30").is_err());
        assert!(count("inf").is_err());
        assert!(count("many").is_err());
    }
}

#[cfg(test)]
mod revision_tests {
    use super::git_revision_at;
    use std::process::Command;

    /// A result's revision ignores the run's own rewrites of `results/` and is `-dirty` for a
    /// change anywhere else.
    #[test]
    fn the_revision_is_dirty_for_code_changes_not_for_results() {
        let dir = std::env::temp_dir().join(format!("scatterbench-rev-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join("results/run")).unwrap();
        let git = |args: &[&str]| {
            let ok = Command::new("git")
                .args(["-c", "user.name=t", "-c", "user.email=t@t"])
                .args(args)
                .current_dir(&dir)
                .output()
                .map(|o| o.status.success());
            assert_eq!(ok.ok(), Some(true), "git {args:?}");
        };
        std::fs::write(dir.join("code.rs"), "a").unwrap();
        std::fs::write(dir.join("results/run/meta.json"), "{}").unwrap();
        git(&["init", "-q"]);
        git(&["add", "."]);
        git(&["commit", "-q", "-m", "c"]);
        let clean = git_revision_at(&dir);
        assert!(!clean.ends_with("-dirty") && clean.len() == 12, "{clean}");
        std::fs::write(dir.join("results/run/meta.json"), "{\"x\": 1}").unwrap();
        std::fs::write(dir.join("untracked.rs"), "b").unwrap();
        assert_eq!(git_revision_at(&dir), clean);
        std::fs::write(dir.join("code.rs"), "changed").unwrap();
        assert_eq!(git_revision_at(&dir), format!("{clean}-dirty"));
        let _ = std::fs::remove_dir_all(&dir);
        assert_eq!(git_revision_at(&dir), "unknown");
    }
}
