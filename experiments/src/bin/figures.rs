//! Regenerates every figure: makes each registered experiment's runs (full size, or CI-sized
//! with `--quick`) and writes `results/README.md` from the experiments' own report sections.
//! `--report-only` re-renders the README from the run folders already there.

use anyhow::{Context, Result};
use clap::Parser;
use experiments::common::{BackendArgs, BackendChoice};
use experiments::experiment::{BackendSupport, EXPERIMENTS, unavailable};
use experiments::report::{RunOutcome, readme};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Debug, Parser)]
#[command(about = "Run every registered experiment and write results/README.md")]
struct Args {
    /// Results root (default `results/` in the current directory, `results-quick/` with
    /// `--quick`); each run writes a folder below it.
    #[arg(long)]
    out: Option<PathBuf>,
    /// CI-sized runs.
    #[arg(long)]
    quick: bool,
    /// Hide progress (each experiment's bars, or the plain lines written instead when stderr is
    /// not a terminal; see `experiments::progress`). The `[i/N]` line per run stays.
    #[arg(long)]
    no_progress: bool,
    /// Passed to every experiment that takes `--backend`.
    #[command(flatten)]
    backend: BackendArgs,
    /// Run nothing: re-render README.md from the run folders already under the root.
    #[arg(long)]
    report_only: bool,
    /// Run only these experiments (comma-separated names, e.g. `renderings,mitsuba_compare`)
    /// or runs (their folders, e.g. `accuracy_hg`, `mitsuba_compare/cloud_directional`); the
    /// README is re-rendered from the existing folders of the others.
    #[arg(long, value_delimiter = ',')]
    only: Vec<String>,
}

fn main() -> Result<()> {
    let args = Args::parse();
    let root = args.out.clone().unwrap_or_else(|| {
        PathBuf::from(if args.quick {
            "results-quick"
        } else {
            "results"
        })
    });
    let backend = args.backend.backend.to_string();
    let runs: Vec<_> = EXPERIMENTS
        .iter()
        .flat_map(|e| e.figure_runs(args.quick).into_iter().map(move |r| (e, r)))
        .collect();
    if let Some(bad) = args.only.iter().find(|n| {
        !runs
            .iter()
            .any(|(e, r)| e.name == n.as_str() || r.dir == n.as_str())
    }) {
        anyhow::bail!(
            "--only: no experiment or run `{bad}`; registered: {}",
            EXPERIMENTS
                .iter()
                .map(|e| e.name)
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    // Experiments skipped because something they need is not installed, with the reason.
    let mut unavailable_because: HashMap<&str, String> = HashMap::new();
    let mut outcomes = Vec::new();
    for (i, (e, run)) in runs.iter().enumerate() {
        let mut outcome = RunOutcome::new(e, run.clone());
        if let (BackendSupport::CpuOnly(why), false) =
            (e.backend, args.backend.backend == BackendChoice::Cpu)
        {
            outcome.notes.push(format!("Ran on the CPU only ({why})."));
        }
        if args.report_only
            || !(args.only.is_empty() || args.only.iter().any(|n| n == e.name || *n == run.dir))
        {
            outcomes.push(outcome);
            continue;
        }
        if let Some(why) = unavailable_because.get(e.name) {
            outcome.skipped = Some(why.clone());
            outcomes.push(outcome);
            continue;
        }
        eprintln!("[{}/{}] {} ({})", i + 1, runs.len(), run.title, run.dir);
        let argv = e.figure_argv(
            run,
            &root.join(&run.dir),
            args.quick,
            args.no_progress,
            &backend,
        );
        let t = Instant::now();
        match e.run(&argv) {
            Ok(()) => outcome.seconds = Some(t.elapsed().as_secs_f64()),
            Err(err) => {
                let Some(u) = unavailable(&err) else {
                    return Err(err.context(format!("running {}", run.dir)));
                };
                eprintln!("skipped {}: {u}", e.name);
                unavailable_because.insert(e.name, u.to_string());
                outcome.skipped = Some(u.to_string());
            }
        }
        outcomes.push(outcome);
    }
    let text = readme(&root, &outcomes, args.quick)?;
    let path = root.join("README.md");
    std::fs::create_dir_all(&root).with_context(|| format!("creating {}", root.display()))?;
    write_atomically(&path, &text)?;
    let total: f64 = outcomes
        .iter()
        .filter_map(|o| o.seconds)
        .fold(0.0, |a, b| a + b);
    eprintln!("done in {total:.0} s; see {}", path.display());
    Ok(())
}

/// Writes `text` to `path` through a temporary sibling renamed into place, so a reader (or
/// an interruption) sees the old file or the new one, never a part.
fn write_atomically(path: &Path, text: &str) -> Result<()> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = path.with_file_name(format!(".{name}.tmp-{}", std::process::id()));
    std::fs::write(&tmp, text).with_context(|| format!("writing {}", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| {
        let _ = std::fs::remove_file(&tmp);
        format!("renaming {} to {}", tmp.display(), path.display())
    })
}
