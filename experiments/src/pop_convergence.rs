//! POP Fig 13 (spec pop.md §3): convergence of the Fig 12 cube (unit cube, σs = 4, albedo 1,
//! one ordinate d = +x) in iterations, at g = 0.7 by default: the residual power R^M/P_inj
//! after every iteration, the iterations to 10⁻², 10⁻³ and 10⁻⁶, and the volume-mean φ and
//! the centre probe's ⟨μ⟩ at M = 4, 8, …, 512 and at convergence, for 16³ and 32³ grids
//! (spec W2, W5: iterations grow ∝ N², and the converged φ grows with N).
//!
//! **Cost** (measured once, default flags, on the 2 shared cores at load average 6):
//! `pop_cube` 10.3 s wall (4.7 s CPU), `pop_convergence` 15.0 s (7.9 s), `pop_residuum`
//! 12.3 s (3.1 s): 38 s together; with `--quick` 1.7 + 0.2 + 0.2 s.

use crate::common::{CommonArgs, Ctx, list_item, progress};
use crate::experiment::{BackendSupport, Experiment, Promise};
use crate::plot::{Axis, Series, Style, plot};
use crate::report::{Section, table};
use anyhow::{Result, bail};
use serde::Serialize;
use solvers::Grid;
use solvers::pop::grid::{box_filter, mip_level};
use solvers::pop::{CpuPop, Ordinate, PopConfig, PopMedium, PropagationGrid};
use std::time::Instant;

/// Flags of `pop_convergence`.
#[derive(Debug, Clone, clap::Parser)]
#[command(about = "POP Fig 13: residual power vs iterations in the lit cube")]
pub struct Args {
    /// Shared flags.
    #[command(flatten)]
    pub common: CommonArgs,
    /// Grid sizes N (default 16,32; 8,16 with --quick).
    #[arg(long, value_delimiter = ',', value_parser = list_item::<usize>)]
    pub n: Option<Vec<usize>>,
    /// HG g ∈ [0, 1).
    #[arg(long, default_value_t = 0.7)]
    pub g: f64,
    /// σs of the cube.
    #[arg(long, default_value_t = 4.0)]
    pub sigma_s: f64,
    /// Stop when R/P_inj falls below this (default 1e-6; 1e-4 with --quick).
    #[arg(long)]
    pub tolerance: Option<f64>,
    /// Iteration cap.
    #[arg(long, default_value_t = 20_000)]
    pub max_iterations: usize,
}

/// One iteration of `residual.csv`.
#[derive(Debug, Clone, Serialize)]
pub struct ResidualRow {
    /// N.
    pub n: usize,
    /// Iteration m.
    pub iteration: usize,
    /// R^m/P_inj.
    pub residual: f64,
}

/// One snapshot of `snapshots.csv`.
#[derive(Debug, Clone, Serialize)]
pub struct SnapshotRow {
    /// N.
    pub n: usize,
    /// Iterations M (the last row per N: converged).
    pub iterations: usize,
    /// Whether this is the converged state.
    pub converged: bool,
    /// R^M/P_inj.
    pub residual: f64,
    /// Volume-mean φ.
    pub phi_mean: f64,
    /// ⟨μ⟩ over the central 2×2×2 cells.
    pub mu_centre: f64,
    /// φ over the central 2×2×2 cells.
    pub phi_centre: f64,
}

/// One N of `summary.csv`.
#[derive(Debug, Clone, Serialize)]
pub struct SummaryRow {
    /// N.
    pub n: usize,
    /// First m with R^m/P_inj < 10⁻² (empty if never).
    pub iterations_1e2: Option<usize>,
    /// … < 10⁻³.
    pub iterations_1e3: Option<usize>,
    /// … < 10⁻⁶.
    pub iterations_1e6: Option<usize>,
    /// Iterations run.
    pub iterations: usize,
    /// Converged volume-mean φ.
    pub phi_mean: f64,
    /// Wall seconds (shared machine).
    pub seconds: f64,
}

/// Runs the experiment.
pub fn run(args: &Args) -> Result<Vec<SummaryRow>> {
    crate::experiment::run::<PopConvergence>(args)
}

fn run_in(ctx: &mut Ctx, args: &Args) -> Result<Vec<SummaryRow>> {
    let quick = args.common.quick;
    let ns = args
        .n
        .clone()
        .unwrap_or(if quick { vec![8, 16] } else { vec![16, 32] });
    if ns.is_empty() {
        bail!("--n: no values given");
    }
    if let Some(n) = ns.iter().find(|&&n| !(4..=64).contains(&n) || n % 2 != 0) {
        bail!("--n: {n} must be even and in [4, 64]");
    }
    if !(0.0..1.0).contains(&args.g) {
        bail!("--g must be in [0, 1), got {}", args.g);
    }
    if !(args.sigma_s.is_finite() && args.sigma_s > 0.0 && args.sigma_s <= 100.0) {
        bail!("--sigma-s must be in (0, 100], got {}", args.sigma_s);
    }
    let tol = args.tolerance.unwrap_or(if quick { 1e-4 } else { 1e-6 });
    if !(tol > 0.0 && tol < 1.0) {
        bail!("--tolerance must be in (0, 1), got {tol}");
    }
    let mut work = crate::cost::Estimate::new();
    for &n in &ns {
        let its = (3.5 * (n * n) as f64).min(args.max_iterations as f64);
        work.add(
            format!("N = {n}: ≈ {its:.0} iterations × {} cells", n * n * n),
            its * (n * n * n) as f64 * 40.0,
        );
    }
    ctx.work(&work)?;
    ctx.start(serde_json::json!({
        "n": ns, "g": args.g, "sigma_s": args.sigma_s, "tolerance": tol,
        "max_iterations": args.max_iterations,
    }))?;
    let marks: Vec<usize> = (2..=9).map(|k| 1usize << k).collect();
    let pb = progress(ns.len() as u64, &args.common, "pop_convergence");
    let mut residuals = Vec::new();
    let mut snaps = Vec::new();
    let mut summary = Vec::new();
    for &n in &ns {
        pb.set_message(format!("N = {n}"));
        let t0 = Instant::now();
        let grid = Grid::cube(n, 1.0)?;
        let m = PopMedium::homogeneous(grid, args.sigma_s, 0.0, args.g)?;
        let cfg = PopConfig::new::<f64>(n);
        cfg.validate::<f64>(1, 1)?;
        let pg = PropagationGrid::over(&grid, [1.0, 0.0, 0.0], n);
        let mip = box_filter(&m, mip_level(&grid, pg.dx));
        let mut pop = CpuPop::<f64>::new(pg, &mip, &m.g, &cfg);
        pop.inject(&Ordinate::directional([1.0, 0.0, 0.0], 1.0)?, cfg.init);
        let h = n / 2;
        let centre: Vec<usize> = (0..8)
            .map(|c| {
                let (i, j, k) = (h - 1 + (c & 1), h - 1 + ((c >> 1) & 1), h - 1 + (c >> 2));
                i + n * (j + n * k)
            })
            .collect();
        let snap = |pop: &CpuPop<f64>, converged: bool| {
            let acc = pop.accumulators();
            let s = solvers::pop::cpu::ACC;
            let cells = pop.grid().len();
            let phi_mean = (0..cells).map(|c| acc[c * s]).sum::<f64>() / cells as f64;
            let phi_c: f64 = centre.iter().map(|&c| acc[c * s]).sum();
            let j_c: f64 = centre.iter().map(|&c| acc[c * s + 1]).sum();
            SnapshotRow {
                n,
                iterations: pop.steps(),
                converged,
                residual: pop.history().last().copied().unwrap_or(1.0),
                phi_mean,
                mu_centre: j_c / phi_c,
                phi_centre: phi_c / 8.0,
            }
        };
        let mut stop = solvers::method::Stop::Cap;
        for &mk in &marks {
            stop = pop.run(tol, mk.min(args.max_iterations));
            if stop != solvers::method::Stop::Cap || pop.steps() < mk {
                break;
            }
            snaps.push(snap(&pop, false));
        }
        if stop == solvers::method::Stop::Cap {
            stop = pop.run(tol, args.max_iterations);
        }
        let last = snap(&pop, stop == solvers::method::Stop::Converged);
        let seconds = t0.elapsed().as_secs_f64();
        ctx.timing(format!("N={n}"), seconds);
        let hist = pop.history();
        for (i, &r) in hist.iter().enumerate() {
            residuals.push(ResidualRow {
                n,
                iteration: i + 1,
                residual: r,
            });
        }
        summary.push(SummaryRow {
            n,
            iterations_1e2: crate::common::first_below(hist, 1e-2),
            iterations_1e3: crate::common::first_below(hist, 1e-3),
            iterations_1e6: crate::common::first_below(hist, 1e-6),
            iterations: pop.steps(),
            phi_mean: last.phi_mean,
            seconds,
        });
        snaps.push(last);
        pb.inc(1);
    }
    pb.finish_and_clear();
    ctx.csv("residual.csv", &residuals)?;
    ctx.csv("snapshots.csv", &snaps)?;
    ctx.csv("summary.csv", &summary)?;
    let series: Vec<Series> = ns
        .iter()
        .enumerate()
        .map(|(c, &n)| {
            Series::new(
                format!("{n}³"),
                residuals
                    .iter()
                    .filter(|r| r.n == n && r.residual > 0.0)
                    .map(|r| (r.iteration as f64, r.residual))
                    .collect(),
                Style::Line,
                c,
            )
        })
        .collect();
    plot(
        &ctx.path("residual.png"),
        &format!(
            "POP Fig 13: power in flight, cube σs = {}, g = {}",
            args.sigma_s, args.g
        ),
        &Axis::log("iterations M"),
        &Axis::log("R^M / P_inj"),
        &series,
    )?;
    Ok(summary)
}

/// POP Fig 13 in the registry.
#[derive(Debug)]
pub struct PopConvergence;

impl Experiment for PopConvergence {
    const NAME: &'static str = "pop_convergence";
    const TITLE: &'static str = "POP Fig 13: convergence in iterations (residual power)";
    const BACKEND: BackendSupport = BackendSupport::CpuOnly("POP's CPU core (iteration counts)");
    type Args = Args;
    type Summary = Vec<SummaryRow>;

    fn common(args: &Args) -> &CommonArgs {
        &args.common
    }

    fn promises(_args: &Args) -> Vec<Promise> {
        vec![
            Promise::csv("residual.csv", &["n", "iteration", "residual"]),
            Promise::csv(
                "snapshots.csv",
                &[
                    "n",
                    "iterations",
                    "converged",
                    "residual",
                    "phi_mean",
                    "mu_centre",
                    "phi_centre",
                ],
            ),
            Promise::csv(
                "summary.csv",
                &[
                    "n",
                    "iterations_1e2",
                    "iterations_1e3",
                    "iterations_1e6",
                    "iterations",
                    "phi_mean",
                    "seconds",
                ],
            ),
            Promise::file("residual.png"),
        ]
    }

    fn run(ctx: &mut Ctx, args: &Args) -> Result<Self::Summary> {
        run_in(ctx, args)
    }

    fn report(s: &Section<'_>) -> Result<String> {
        let t = s.csv("summary.csv")?;
        t.require(&[
            "n",
            "iterations_1e2",
            "iterations_1e3",
            "iterations_1e6",
            "phi_mean",
        ])?;
        let mut out = String::from(
            "Power still in flight R^M/P_inj of the Fig 12 cube (one ordinate, albedo 1) against the \
             iteration count M. Iterations to a relative residual and the converged volume-mean φ:\n\n",
        );
        out.push_str(&table(
            &[
                "N",
                "M to 10⁻²",
                "M to 10⁻³",
                "M to 10⁻⁶",
                "converged mean φ",
            ],
            t.rows().map(|r| {
                vec![
                    r.get("n").to_string(),
                    r.get("iterations_1e2").to_string(),
                    r.get("iterations_1e3").to_string(),
                    r.get("iterations_1e6").to_string(),
                    r.fixed("phi_mean", 3),
                ]
            }),
        ));
        let sn = s.csv("snapshots.csv")?;
        sn.require(&["n", "iterations", "residual", "phi_mean", "mu_centre"])?;
        out.push_str(
            "\nAt fixed M (the paper uses 10–20) and at convergence (last row per N):\n\n",
        );
        out.push_str(&table(
            &["N", "M", "R^M/P_inj", "mean φ", "centre ⟨μ⟩"],
            sn.rows().map(|r| {
                vec![
                    r.get("n").to_string(),
                    r.get("iterations").to_string(),
                    r.sci("residual", 2),
                    r.fixed("phi_mean", 3),
                    r.fixed("mu_centre", 3),
                ]
            }),
        ));
        out.push('\n');
        out.push_str(&s.png("residual.png"));
        Ok(out)
    }
}
