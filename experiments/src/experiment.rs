//! The experiment interface and the one registry `figures` and the tests read.
//!
//! Each experiment module implements [`Experiment`] next to its plots: its name, title, the
//! runs `figures` makes of it (quick and full), the files and CSV columns each run promises,
//! how to run it, and how to render its section of `results/README.md` from the files it
//! wrote. [`EXPERIMENTS`] lists them, one line each; `figures` loops over it and the generic
//! quick test (`tests/registry.rs`) runs every entry with `--quick` and checks each promise.

use crate::common::{CommonArgs, Ctx};
use anyhow::{Context, Result};
use std::path::Path;

/// Whether an experiment takes the shared `--backend` flag.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BackendSupport {
    /// It takes `--backend cpu|gpu|both`; `figures --backend` is passed on.
    Flag,
    /// It always runs on the CPU, for the reason given (reported by `figures --backend`).
    CpuOnly(&'static str),
}

/// One run `figures` makes of an experiment: its directory under the results root, a label,
/// and its flags (without `--out`, `--quick`, `--no-progress` and `--backend`, which
/// `figures` adds).
#[derive(Debug, Clone)]
pub struct FigureRun {
    /// Directory under the results root, e.g. `point_source` or `mitsuba_compare/cloud`.
    pub dir: String,
    /// Heading of the run's README section.
    pub title: String,
    /// Flags passed to the experiment.
    pub args: Vec<String>,
}

impl FigureRun {
    /// A run into `dir` titled `title`, with the experiment's default flags.
    pub fn new(dir: impl Into<String>, title: impl Into<String>) -> Self {
        Self {
            dir: dir.into(),
            title: title.into(),
            args: Vec::new(),
        }
    }

    /// Adds flags.
    pub fn args<S: Into<String>>(mut self, args: impl IntoIterator<Item = S>) -> Self {
        self.args.extend(args.into_iter().map(Into::into));
        self
    }
}

/// A file a run promises to write and, for a CSV, columns its header must contain.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Promise {
    /// File name relative to the run's output directory.
    pub file: String,
    /// Columns the CSV header contains (empty for other files).
    pub columns: Vec<&'static str>,
}

impl Promise {
    /// A file without a column contract (a PNG, `meta.json`, …).
    pub fn file(file: impl Into<String>) -> Self {
        Self {
            file: file.into(),
            columns: Vec::new(),
        }
    }

    /// A CSV whose header contains `columns`.
    pub fn csv(file: impl Into<String>, columns: &[&'static str]) -> Self {
        Self {
            file: file.into(),
            columns: columns.to_vec(),
        }
    }
}

/// An external program a run needs is not installed: `figures` skips the experiment's runs
/// with this note instead of failing. Return it (possibly wrapped in context) from
/// [`Experiment::run`].
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct Unavailable(pub String);

/// Whether `e` (or an error in its chain) is an [`Unavailable`].
pub fn unavailable(e: &anyhow::Error) -> Option<&Unavailable> {
    e.chain().find_map(|c| c.downcast_ref::<Unavailable>())
}

/// One experiment: a paper figure or a reference check, with its binary of the same name.
pub trait Experiment {
    /// Binary name and default directory, `results/<NAME>/`.
    const NAME: &'static str;
    /// One line: what it shows.
    const TITLE: &'static str;
    /// Whether it takes `--backend`.
    const BACKEND: BackendSupport;
    /// Whether it is a Monte Carlo producer that takes `--shard i/N` (its estimates come
    /// through [`Ctx::tally`]; see [`crate::shard`]).
    const SHARDS: bool = false;
    /// Its flags.
    type Args: clap::Parser + Clone;
    /// What [`Experiment::run`] returns to a caller (tests check claims on it).
    type Summary;

    /// The shared flags inside `args`.
    fn common(args: &Self::Args) -> &CommonArgs;

    /// Output directory name under `results/` when `--out` is not given.
    fn dir_name(_args: &Self::Args) -> String {
        Self::NAME.to_string()
    }

    /// The runs `figures` makes (one by default, with default flags).
    fn figure_runs(_quick: bool) -> Vec<FigureRun> {
        vec![FigureRun::new(Self::NAME, Self::TITLE)]
    }

    /// Every file (and CSV column) a run with `args` promises, `meta.json` aside.
    fn promises(args: &Self::Args) -> Vec<Promise>;

    /// Runs the experiment into `ctx` (which writes `meta.json` afterwards).
    fn run(ctx: &mut Ctx, args: &Self::Args) -> Result<Self::Summary>;

    /// Its README section body (below the run's title), rendered from the files in `dir`.
    fn report(dir: &crate::report::Section<'_>) -> Result<String>;
}

/// Runs `X` with `args` (the binary's and the tests' entry point): output directory,
/// the run, then `meta.json`.
pub fn run<X: Experiment>(args: &X::Args) -> Result<X::Summary> {
    run_with::<X>(args, None, None)
}

/// [`run`] with the command-line flags `argv` (a shard records them for the merge) and,
/// for a merge, the joined shards.
pub fn run_with<X: Experiment>(
    args: &X::Args,
    argv: Option<&[String]>,
    merged: Option<crate::shard::Joined>,
) -> Result<X::Summary> {
    let common = X::common(args);
    let mut ctx = Ctx::for_run(&X::dir_name(args), common);
    if let Some(shard) = common.shard {
        if !X::SHARDS {
            anyhow::bail!(
                "--shard {shard}: {} has no Monte Carlo part to shard (producers: {})",
                X::NAME,
                producers().join(", ")
            );
        }
        if argv.is_none() {
            anyhow::bail!("--shard needs the command line (run the binary or `figures`)");
        }
    }
    if let Some(argv) = argv {
        ctx.set_argv(argv);
    }
    if let Some(j) = merged {
        ctx.merge_from(j);
    }
    let summary = X::run(&mut ctx, args)?;
    ctx.finish()?;
    Ok(summary)
}

/// Names of the producers that take `--shard` (`render` and the sharding experiments).
pub fn producers() -> Vec<&'static str> {
    std::iter::once("render")
        .chain(EXPERIMENTS.iter().filter(|e| e.shards).map(|e| e.name))
        .collect()
}

/// `main` of experiment `X`'s binary: parses its flags and runs it.
pub fn main<X: Experiment>() -> Result<()> {
    use clap::Parser as _;
    let args = X::Args::parse();
    let argv: Vec<String> = std::env::args().skip(1).collect();
    crate::common::estimate_ok(run_with::<X>(&args, Some(&argv), None).map(|_| ()))
}

/// The `main` of an experiment's binary: `experiments::experiment_main!(point_source::PointSource);`.
#[macro_export]
macro_rules! experiment_main {
    ($x:ty) => {
        fn main() -> anyhow::Result<()> {
            $crate::experiment::main::<$x>()
        }
    };
}

/// `main` of a binary that is a tool rather than a registered experiment (`render`): parses
/// `A` and calls `run`.
pub fn tool_main<A: clap::Parser, R>(run: fn(&A) -> Result<R>) -> Result<()> {
    run(&A::parse()).map(|_| ())
}

fn parse<X: Experiment>(argv: &[String]) -> Result<X::Args> {
    use clap::Parser as _;
    X::Args::try_parse_from(std::iter::once(X::NAME.to_string()).chain(argv.iter().cloned()))
        .with_context(|| format!("{} {}", X::NAME, argv.join(" ")))
}

fn run_argv<X: Experiment>(argv: &[String]) -> Result<()> {
    run_with::<X>(&parse::<X>(argv)?, Some(argv), None).map(|_| ())
}

fn run_merged<X: Experiment>(argv: &[String], joined: crate::shard::Joined) -> Result<()> {
    run_with::<X>(&parse::<X>(argv)?, Some(argv), Some(joined)).map(|_| ())
}

fn promises_argv<X: Experiment>(argv: &[String]) -> Result<Vec<Promise>> {
    let mut p = X::promises(&parse::<X>(argv)?);
    p.push(Promise::file("meta.json"));
    Ok(p)
}

/// A registered experiment, its type erased.
#[derive(Debug, Clone, Copy)]
pub struct ExperimentEntry {
    /// [`Experiment::NAME`].
    pub name: &'static str,
    /// [`Experiment::TITLE`].
    pub title: &'static str,
    /// [`Experiment::BACKEND`].
    pub backend: BackendSupport,
    /// [`Experiment::SHARDS`].
    pub shards: bool,
    figure_runs: fn(bool) -> Vec<FigureRun>,
    run: fn(&[String]) -> Result<()>,
    run_merged: fn(&[String], crate::shard::Joined) -> Result<()>,
    promises: fn(&[String]) -> Result<Vec<Promise>>,
    report: fn(&crate::report::Section<'_>) -> Result<String>,
}

impl ExperimentEntry {
    /// The entry of experiment `X`.
    pub const fn of<X: Experiment>() -> Self {
        Self {
            name: X::NAME,
            title: X::TITLE,
            backend: X::BACKEND,
            shards: X::SHARDS,
            figure_runs: X::figure_runs,
            run: run_argv::<X>,
            run_merged: run_merged::<X>,
            promises: promises_argv::<X>,
            report: X::report,
        }
    }

    /// The runs `figures` makes of it.
    pub fn figure_runs(&self, quick: bool) -> Vec<FigureRun> {
        (self.figure_runs)(quick)
    }

    /// Parses `argv` (flags only, no program name) and runs it.
    pub fn run(&self, argv: &[String]) -> Result<()> {
        (self.run)(argv)
    }

    /// Runs it with `argv` as the merge of `joined` (see [`crate::shard`]).
    pub fn run_merged(&self, argv: &[String], joined: crate::shard::Joined) -> Result<()> {
        (self.run_merged)(argv, joined)
    }

    /// The files a run with `argv` promises, `meta.json` included.
    pub fn promises(&self, argv: &[String]) -> Result<Vec<Promise>> {
        (self.promises)(argv)
    }

    /// Its README section body for a run whose files are in `section`.
    pub fn report(&self, section: &crate::report::Section<'_>) -> Result<String> {
        (self.report)(section)
    }

    /// The flags `figures` passes to `run`: the run's own, then `--out`, `--quick`,
    /// `--no-progress` and (if it takes one) `--backend`.
    pub fn figure_argv(
        &self,
        run: &FigureRun,
        out: &Path,
        quick: bool,
        no_progress: bool,
        backend: &str,
    ) -> Vec<String> {
        let mut v = run.args.clone();
        v.push("--out".into());
        v.push(out.display().to_string());
        if quick {
            v.push("--quick".into());
        }
        if no_progress {
            v.push("--no-progress".into());
        }
        if self.backend == BackendSupport::Flag {
            v.push("--backend".into());
            v.push(backend.to_string());
        }
        v
    }
}

/// Every experiment `figures` runs, in README order. Add new ones here, one line each.
pub static EXPERIMENTS: &[ExperimentEntry] = &[
    ExperimentEntry::of::<crate::point_source_analytic::PointSourceAnalytic>(),
    ExperimentEntry::of::<crate::point_source::PointSource>(),
    ExperimentEntry::of::<crate::convergence::Convergence>(),
    ExperimentEntry::of::<crate::convergence_check::ConvergenceCheck>(),
    ExperimentEntry::of::<crate::multigrid_scaling::MultigridScaling>(),
    ExperimentEntry::of::<crate::emissive_cube::EmissiveCube>(),
    ExperimentEntry::of::<crate::lbm_convergence::LbmConvergence>(),
    ExperimentEntry::of::<crate::lbm_diffusion_limit::LbmDiffusionLimit>(),
    ExperimentEntry::of::<crate::lpm_memory::LpmMemory>(),
    ExperimentEntry::of::<crate::lpm_accuracy::LpmAccuracy>(),
    ExperimentEntry::of::<crate::lpm_speedup::LpmSpeedup>(),
    ExperimentEntry::of::<crate::lpm_cloud::LpmCloud>(),
    ExperimentEntry::of::<crate::transport_references::TransportReferences>(),
    ExperimentEntry::of::<crate::pt_point_source::PtPointSource>(),
    ExperimentEntry::of::<crate::pt_slab::PtSlab>(),
    ExperimentEntry::of::<crate::i3rc_step_cloud::I3rcStepCloud>(),
    ExperimentEntry::of::<crate::pt_render::PtRender>(),
    ExperimentEntry::of::<crate::renderings::Renderings>(),
    ExperimentEntry::of::<crate::accuracy_cost::AccuracyCost>(),
    ExperimentEntry::of::<crate::rde_stability::RdeStability>(),
    ExperimentEntry::of::<crate::rde_steady::RdeSteady>(),
    ExperimentEntry::of::<crate::rde_controls::RdeControls>(),
    ExperimentEntry::of::<crate::mitsuba_compare::MitsubaCompare>(),
    ExperimentEntry::of::<crate::pop_cube::PopCube>(),
    ExperimentEntry::of::<crate::pop_convergence::PopConvergence>(),
    ExperimentEntry::of::<crate::pop_residuum::PopResiduum>(),
    ExperimentEntry::of::<crate::pop_ordinates::PopOrdinates>(),
    ExperimentEntry::of::<crate::pop_weaknesses::PopWeaknesses>(),
    ExperimentEntry::of::<crate::pop_radial::PopRadial>(),
];

/// The registered experiment called `name`.
pub fn find(name: &str) -> Option<&'static ExperimentEntry> {
    EXPERIMENTS.iter().find(|e| e.name == name)
}
