//! LB Fig 5: the total lattice density per step for a cloud lit by a directional light, and
//! the steps to steady state against the lattice size N (the paper: "about 2N").
//!
//! The cloud is the `noise_cloud` generator (fbm density sphere, seed 7, radius 0.4, the
//! `scenes/cloud_directional.toml` cloud) lit along (0.4, 0.5, −1) with irradiance 1,
//! albedo 0.9, isotropic scattering, the paper's absorption (LB Eqs 4–6 verbatim). Two series:
//! * `paper`: LB Section 4's setting: per-site σt = 0.25 × density (density ∈ [0, 1]), i.e.
//!   σt = 0.25·density/Δl with the linear σ mapping; the optical size grows with N.
//! * `physical`: the same physical cloud at every N (σt,max = 20 on the unit cube, the
//!   exponential σ mapping); per-site σ shrinks as 1/N.
//!
//! Steps to steady state are read from one run per (series, N) for each tolerance on the
//! relative change of the total density per step (`steps.csv`); the run stops at the
//! smallest tolerance or at `max-steps-factor`·N steps (then the tolerances not reached are
//! reported as not converged). Budget: the full run (N up to 128, CPU f32) is a few minutes
//! on 2 cores.

use crate::common::{BackendArgs, CommonArgs, Ctx, PrecisionArg, list_item, progress};
use crate::experiment::{BackendSupport, Experiment, Promise};
use crate::plot::{Axis, Series, Style, plot};
use crate::report::{Section, table};
use anyhow::{Context, Result, bail};
use serde::Serialize;
use solvers::Precision;
use solvers::lbm::{self, Injection, LbmConfig, Resolve, SigmaMapping, StepRecord};
use solvers::scene::generators::{Generator, NoiseCloud};

/// Flags of `lbm_convergence`.
#[derive(Debug, Clone, clap::Parser)]
#[command(about = "LB Fig 5: total lattice density per step and steps to steady state vs N")]
pub struct Args {
    /// Shared flags.
    #[command(flatten)]
    pub common: CommonArgs,
    /// Shared backend flag (GPU totals are read at checkpoints every 16 steps).
    #[command(flatten)]
    pub backend: BackendArgs,
    /// Lattice sizes N. Default 16,32,64,128 (12,16,24 with --quick).
    #[arg(long, value_delimiter = ',', value_parser = list_item::<usize>)]
    pub sizes: Option<Vec<usize>>,
    /// Tolerances on the relative change of the total density per step.
    #[arg(long, value_delimiter = ',', value_parser = list_item::<f64>, default_value = "1e-3,1e-4,1e-5")]
    pub tolerance: Vec<f64>,
    /// Step cap as a multiple of N.
    #[arg(long, default_value_t = 10, value_parser = crate::common::count_usize)]
    pub max_steps_factor: usize,
    /// Precision of CPU runs.
    #[arg(long, value_enum, default_value = "f32")]
    pub precision: PrecisionArg,
}

/// `history.csv` row: one step (CPU) or checkpoint (GPU).
#[derive(Debug, Serialize)]
struct HistoryRow {
    series: &'static str,
    n: usize,
    backend: &'static str,
    step: usize,
    total_density: f64,
    injected: f64,
    outflow: f64,
    rel_change: f64,
}

/// `steps.csv` row.
#[derive(Debug, Clone, Serialize)]
pub struct StepsRow {
    /// `paper` or `physical`.
    pub series: &'static str,
    /// Lattice size.
    pub n: usize,
    /// `cpu` or `gpu`.
    pub backend: &'static str,
    /// Precision.
    pub precision: &'static str,
    /// Tolerance on the relative change per step.
    pub tolerance: f64,
    /// Steps until the relative change fell below the tolerance (the cap if never).
    pub steps: usize,
    /// steps / N.
    pub steps_over_n: f64,
    /// Whether the tolerance was reached.
    pub converged: bool,
    /// (injected − outflow)/injected at the last step.
    pub balance: f64,
    /// Seconds of the whole run (to the smallest tolerance).
    pub seconds: f64,
    /// Lattice site updates per second of the run, in millions.
    pub mlups: f64,
}

fn cloud(series: &str, n: usize) -> Result<solvers::Medium<f64>> {
    let sigma_max = if series == "paper" {
        0.25 * n as f64
    } else {
        20.0
    };
    NoiseCloud {
        n,
        seed: 7,
        sigma_max,
        albedo: 0.9,
        radius: 0.4,
        frequency: 4.0,
        octaves: 4,
    }
    .generate()
    .context("building the noise cloud")
}

/// First step whose relative change per step is below `tol` (from consecutive records).
fn steps_to(history: &[StepRecord], tol: f64) -> Option<usize> {
    history.windows(2).find_map(|w| {
        let (a, b) = (w[0], w[1]);
        let ds = (b.step - a.step).max(1) as f64;
        let rel = (b.total_density - a.total_density).abs() / (b.total_density.abs() * ds);
        (rel < tol).then_some(b.step)
    })
}

/// Runs the experiment; returns the `steps.csv` rows (for `figures`).
pub fn run(args: &Args) -> Result<Vec<StepsRow>> {
    crate::experiment::run::<LbmConvergence>(args)
}

fn run_in(ctx: &mut Ctx, args: &Args) -> Result<Vec<StepsRow>> {
    let sizes: Vec<usize> = match &args.sizes {
        Some(s) => s.clone(),
        None if args.common.quick => vec![12, 16, 24],
        None => vec![16, 32, 64, 128],
    };
    if let Some(n) = sizes.iter().find(|&&n| n < 4) {
        bail!("--sizes: {n} is too small (at least 4)");
    }
    for &n in &sizes {
        solvers::budget::check(
            format!("--sizes {n}"),
            solvers::budget::cube_solver_bytes(n),
        )?;
    }
    let tols: Vec<f64> = args.tolerance.clone();
    if tols.is_empty() || tols.iter().any(|t| !(t.is_finite() && *t > 0.0)) {
        bail!("--tolerance needs positive values, got {:?}", tols);
    }
    let tmin = tols.iter().cloned().fold(f64::INFINITY, f64::min);
    let precision: Precision = args.precision.precision();
    let backends = args.backend.open()?;
    let mut work = crate::cost::Estimate::new();
    for &n in &sizes {
        work.add(
            format!("--sizes {n}: 2 series × {} backend(s) × --max-steps-factor {} × {n} steps × {n}³ voxels", backends.list(precision).len(), args.max_steps_factor),
            2.0 * backends.list(precision).len() as f64
                * args.max_steps_factor as f64
                * (n as f64).powi(4),
        );
    }
    ctx.work(&work)?;
    let params = serde_json::json!({
        "sizes": sizes, "tolerance": tols, "max_steps_factor": args.max_steps_factor,
        "precision": args.precision.name(), "light": [0.4, 0.5, -1.0], "albedo": 0.9, "seed": 7,
    });
    ctx.start(params)?;
    let out = ctx;
    out.record("backends", backends.meta());
    let list = backends.list(precision);
    let series = ["paper", "physical"];
    let pb = progress(
        (series.len() * sizes.len() * list.len()) as u64,
        &args.common,
        "lbm convergence",
    );
    let inj = Injection::directional(
        {
            let d = [0.4f64, 0.5, -1.0];
            let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            d.map(|x| x / l)
        },
        1.0,
        Resolve::FluxPreserving,
    )?;
    let mut hist = Vec::new();
    let mut rows = Vec::new();
    for backend in &list {
        for s in series {
            for &n in &sizes {
                pb.set_message(format!("{s} {n}³ {backend}"));
                let medium = cloud(s, n)?;
                let cfg = LbmConfig {
                    sigma_mapping: if s == "paper" {
                        SigmaMapping::Linear
                    } else {
                        SigmaMapping::Exponential
                    },
                    ..LbmConfig::default()
                }
                .with_tolerance(tmin)
                .with_max_steps(args.max_steps_factor * n);
                let sol = lbm::solve(backend, &medium, &inj, &cfg, |step, _| {
                    if step % 64 == 0 {
                        pb.set_message(format!("{s} {n}³ {backend} step {step}"));
                    }
                })
                .with_context(|| format!("{s} {n}³ on {backend}"))?;
                out.timing(format!("{s} {n}³ {backend}"), sol.seconds);
                let mut prev: Option<StepRecord> = None;
                for r in &sol.trace.history {
                    let rel = prev
                        .map(|p| {
                            (r.total_density - p.total_density).abs()
                                / (r.total_density.abs() * (r.step - p.step).max(1) as f64)
                        })
                        .unwrap_or(f64::NAN);
                    hist.push(HistoryRow {
                        series: s,
                        n,
                        backend: backend.kind(),
                        step: r.step,
                        total_density: r.total_density,
                        injected: r.injected,
                        outflow: r.outflow,
                        rel_change: rel,
                    });
                    prev = Some(*r);
                }
                let last = sol.last().copied();
                for &t in &tols {
                    let st = steps_to(&sol.trace.history, t);
                    rows.push(StepsRow {
                        series: s,
                        n,
                        backend: backend.kind(),
                        precision: backend.precision().name(),
                        tolerance: t,
                        steps: st.unwrap_or(sol.steps),
                        steps_over_n: st.unwrap_or(sol.steps) as f64 / n as f64,
                        converged: st.is_some(),
                        balance: last
                            .map(|r| (r.injected - r.outflow) / r.injected)
                            .unwrap_or(f64::NAN),
                        seconds: sol.seconds,
                        mlups: (n * n * n * sol.steps) as f64 / sol.seconds.max(1e-12) / 1e6,
                    });
                }
                pb.inc(1);
            }
        }
    }
    pb.finish_and_clear();
    out.csv("history.csv", &hist)?;
    out.csv("steps.csv", &rows)?;
    for backend in &list {
        let kind = backend.kind();
        let suffix = backends.plot_suffix(kind);
        let nmax = sizes.iter().copied().max().unwrap_or(0);
        let mut fig5 = Vec::new();
        for (c, s) in series.iter().enumerate() {
            let pts: Vec<(f64, f64)> = hist
                .iter()
                .filter(|h| h.series == *s && h.n == nmax && h.backend == kind)
                .map(|h| (h.step as f64, h.total_density))
                .collect();
            fig5.push(Series::new(
                format!("{s} cloud, {nmax}³"),
                pts,
                Style::Line,
                c,
            ));
        }
        plot(
            &out.path(&format!("fig5_total_density{suffix}.png")),
            &format!("LB Fig 5: total lattice density per step ({nmax}³, {backend})"),
            &Axis::lin("step"),
            &Axis::lin("total density (power units)"),
            &fig5,
        )?;
        let mut sv = Vec::new();
        for (c, s) in series.iter().enumerate() {
            for (k, &t) in tols.iter().enumerate() {
                let pts: Vec<(f64, f64)> = rows
                    .iter()
                    .filter(|r| {
                        r.series == *s && r.tolerance == t && r.backend == kind && r.converged
                    })
                    .map(|r| (r.n as f64, r.steps as f64))
                    .collect();
                let style = if k == 0 { Style::Line } else { Style::Dashed };
                sv.push(Series::new(format!("{s}, tol {t:.0e}"), pts, style, c));
            }
        }
        sv.push(Series::new(
            "2N (LB Section 5)",
            sizes.iter().map(|&n| (n as f64, 2.0 * n as f64)).collect(),
            Style::Points,
            7,
        ));
        plot(
            &out.path(&format!("steps_vs_n{suffix}.png")),
            &format!("Steps to steady state vs lattice size ({backend})"),
            &Axis::log("N"),
            &Axis::log("steps"),
            &sv,
        )?;
    }
    Ok(rows)
}

/// LB Fig 5 in the registry.
#[derive(Debug)]
pub struct LbmConvergence;

impl Experiment for LbmConvergence {
    const NAME: &'static str = "lbm_convergence";
    const TITLE: &'static str = "Lattice-Boltzmann lighting: LB Fig 5, steps to steady state vs N";
    const BACKEND: BackendSupport = BackendSupport::Flag;
    type Args = Args;
    type Summary = Vec<StepsRow>;

    fn common(args: &Args) -> &CommonArgs {
        &args.common
    }

    fn promises(args: &Args) -> Vec<Promise> {
        let mut p = vec![
            Promise::csv(
                "history.csv",
                &[
                    "series",
                    "n",
                    "backend",
                    "step",
                    "total_density",
                    "injected",
                    "outflow",
                    "rel_change",
                ],
            ),
            Promise::csv(
                "steps.csv",
                &[
                    "series",
                    "n",
                    "backend",
                    "precision",
                    "tolerance",
                    "steps",
                    "steps_over_n",
                    "converged",
                    "balance",
                    "seconds",
                    "mlups",
                ],
            ),
        ];
        for s in args.backend.plot_suffixes() {
            p.push(Promise::file(format!("fig5_total_density{s}.png")));
            p.push(Promise::file(format!("steps_vs_n{s}.png")));
        }
        p
    }

    fn run(ctx: &mut Ctx, args: &Args) -> Result<Self::Summary> {
        run_in(ctx, args)
    }

    fn report(s: &Section<'_>) -> Result<String> {
        let t = s.csv("steps.csv")?;
        t.require(&[
            "series",
            "n",
            "backend",
            "precision",
            "tolerance",
            "steps",
            "converged",
            "steps_over_n",
            "balance",
            "mlups",
        ])?;
        let mut out = String::from(
            "Noise cloud lit by a directional light, albedo 0.9, the paper's model. `paper`: per-site σt = \
             0.25·density (LB Section 4; optical size grows with N); `physical`: the same physical cloud at every N. \
             Steps until the relative change of the total density per step is below the tolerance (LB Section 5 \
             observes about 2N).\n\n",
        );
        let rows = t.rows().map(|r| {
            vec![
                r.get("series").to_string(),
                r.get("n").to_string(),
                format!("{}-{}", r.get("backend"), r.get("precision")),
                r.sci("tolerance", 0),
                format!(
                    "{}{}",
                    r.get("steps"),
                    if r.flag("converged") { "" } else { " (cap)" }
                ),
                r.fixed("steps_over_n", 2),
                r.sci("balance", 1),
                r.fixed("mlups", 1),
            ]
        });
        out.push_str(&table(
            &[
                "series",
                "N",
                "backend",
                "tolerance",
                "steps",
                "steps/N",
                "(injected − outflow)/injected",
                "MLUPS",
            ],
            rows,
        ));
        out.push('\n');
        out.push_str(&s.pngs(["fig5_total_density.png", "steps_vs_n.png"]));
        out.push_str(&bench());
        Ok(out)
    }
}

/// The committed `cargo bench --bench lbm` table, curated (empty if there is none).
fn bench() -> String {
    let Ok(t) =
        crate::report::Table::read(&crate::common::workspace_root().join("results/bench/lbm.csv"))
    else {
        return String::new();
    };
    let rows = t.rows().map(|r| {
        vec![
            r.get("backend").to_string(),
            crate::report::short_device(r.get("device")),
            r.get("n").to_string(),
            r.get("precision").to_string(),
            r.fixed("ms_per_step", 2),
            r.fixed("mlups", 1),
            r.fixed("effective_gbs", 1),
            r.fixed("ratio_triad", 2),
            r.fixed("ratio_copy", 2),
        ]
    });
    format!(
        "\n### Benchmark (`cargo bench -p benches --bench lbm`, last committed run, [`bench/lbm.csv`](bench/lbm.csv))\n\n\
         Effective bandwidth counts 19 values read and 19 written per site, against the STREAM triad and copy of the \
         same machine (CPU) or the device copy probe (GPU; `llvmpipe` is Mesa's CPU Vulkan driver).\n\n{}",
        crate::report::table(
            &[
                "backend",
                "device",
                "N",
                "precision",
                "ms/step",
                "MLUPS",
                "effective GB/s",
                "÷ triad",
                "÷ copy"
            ],
            rows
        )
    )
}
