//! FLD Fig 4: convergence of the FLD solver (Levermore–Pomraning) on the paper's test case,
//! a spherical cloud in vacuum with Perlin-noise emission ([`solvers::scenes::vacuum_cloud`]).
//!
//! (a) normalised RMS residual R̄/j̄ against iteration for several SOR factors at 51³ in f64,
//!     with our default D under-relaxation θ = 0.5 and with Algorithm 1 verbatim (θ = 1);
//! (b) iterations to R̄/j̄ < 10⁻⁶ against grid resolution;
//! (c) the effect of the extinction floor σ_ε on convergence in f32 (the paper uses its
//!     Nebulae dataset; we use the same cloud, whose vacuum is where σ_ε acts).

use crate::common::{BackendArgs, CommonArgs, Ctx, list_item, progress};
use crate::experiment::{BackendSupport, Experiment, Promise};
use crate::plot::{Axis, Series, Style, plot};
use crate::report::{Section, table};
use anyhow::{Context, Result, bail};
use serde::Serialize;
use solvers::fld::{self, Boundary, FldConfig, FluxLimiter};
use solvers::{Backend, Precision, scenes};

/// Flags of `convergence`.
#[derive(Debug, Clone, clap::Parser)]
#[command(
    about = "FLD Fig 4: residual vs iteration, iterations vs resolution, effect of sigma_eps"
)]
pub struct Args {
    /// Shared flags.
    #[command(flatten)]
    pub common: CommonArgs,
    /// Shared backend flag (GPU runs are f32, so on the GPU (a) and (b) stop at the f32
    /// tolerance R̄/j̄ < 1e-4 instead of 1e-6).
    #[command(flatten)]
    pub backend: BackendArgs,
    /// Grid for (a) and (c). Default 51 (25 with --quick).
    #[arg(long, value_parser = crate::common::count_usize)]
    pub n: Option<usize>,
    /// SOR factors for (a).
    #[arg(long, value_delimiter = ',', value_parser = list_item::<f64>, default_value = "1.0,1.3,1.5,1.7,1.8,1.9")]
    pub omega: Vec<f64>,
    /// Resolutions for (b). Default 17,25,33,51,65,81 (13,17,25 with --quick).
    #[arg(long, value_delimiter = ',', value_parser = list_item::<usize>)]
    pub resolutions: Option<Vec<usize>>,
    /// SOR factor for (b) and (c).
    #[arg(long, default_value_t = 1.8)]
    pub omega_sweep: f64,
    /// σ_ε·L values for (c).
    #[arg(long, value_delimiter = ',', value_parser = list_item::<f64>, default_value = "1e-1,1e-2,1e-3,1e-4,1e-5,1e-6")]
    pub sigma_eps: Vec<f64>,
    /// Iteration cap per solve.
    #[arg(long, default_value_t = 6000, value_parser = crate::common::count_usize)]
    pub max_iterations: usize,
    /// Seed of the Perlin emission.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// `residuals.csv` row.
#[derive(Debug, Serialize)]
struct ResidualRow {
    case: &'static str,
    omega: f64,
    n: usize,
    sigma_eps: f64,
    iteration: usize,
    residual: f64,
    theta: f64,
    precision: &'static str,
    backend: &'static str,
}

/// `iterations.csv` row.
#[derive(Debug, Clone, Serialize)]
pub struct IterRow {
    /// `sor` (a, θ = 0.5), `sor_theta1` (a, θ = 1), `resolution` (b), `sigma_eps` (c).
    pub case: &'static str,
    /// SOR factor.
    pub omega: f64,
    /// Grid resolution.
    pub n: usize,
    /// σ_ε (absolute; the cloud has L = 1).
    pub sigma_eps: f64,
    /// Iterations run.
    pub iterations: usize,
    /// Seconds of the iterations (GPU: timestamp queries where available, see `timer`).
    pub seconds: f64,
    /// How `seconds` was measured: `wall-clock` or `gpu-timestamps`.
    pub timer: String,
    /// Whether R̄/j̄ reached the tolerance.
    pub converged: bool,
    /// D under-relaxation θ.
    pub theta: f64,
    /// Precision.
    pub precision: &'static str,
    /// `cpu` or `gpu`.
    pub backend: &'static str,
}

struct Job {
    case: &'static str,
    omega: f64,
    n: usize,
    sigma_eps: Option<f64>,
    theta: f64,
    f32: bool,
}

/// Runs the experiment; returns the `iterations.csv` rows.
pub fn run(args: &Args) -> Result<Vec<IterRow>> {
    crate::experiment::run::<Convergence>(args)
}

fn run_in(ctx: &mut Ctx, args: &Args) -> Result<Vec<IterRow>> {
    let q = args.common.quick;
    let n = args.n.unwrap_or(if q { 25 } else { 51 });
    let omegas: Vec<f64> = args.omega.clone();
    let resolutions: Vec<usize> = args.resolutions.clone().unwrap_or_else(|| {
        if q {
            vec![13, 17, 25]
        } else {
            vec![17, 25, 33, 51, 65, 81]
        }
    });
    let eps: Vec<f64> = args.sigma_eps.clone();
    for &o in omegas.iter().chain([&args.omega_sweep]) {
        if !(o > 0.0 && o < 2.0) {
            bail!("SOR factor {o} is outside (0, 2)");
        }
    }
    if let Some(e) = eps.iter().find(|e| !(e.is_finite() && **e > 0.0)) {
        bail!("--sigma-eps: {e} must be finite and > 0");
    }
    if let Some(r) = resolutions.iter().chain([&n]).find(|r| **r < 5) {
        bail!("grid resolution {r} is too small (≥ 5)");
    }
    solvers::budget::check(format!("--n {n}"), solvers::budget::cube_solver_bytes(n))?;
    for &r in &resolutions {
        solvers::budget::check(
            format!("--resolutions {r}"),
            solvers::budget::cube_solver_bytes(r),
        )?;
    }
    let mut jobs = Vec::new();
    for &omega in &omegas {
        jobs.push(Job {
            case: "sor",
            omega,
            n,
            sigma_eps: None,
            theta: 0.5,
            f32: false,
        });
        jobs.push(Job {
            case: "sor_theta1",
            omega,
            n,
            sigma_eps: None,
            theta: 1.0,
            f32: false,
        });
    }
    for &r in &resolutions {
        jobs.push(Job {
            case: "resolution",
            omega: args.omega_sweep,
            n: r,
            sigma_eps: None,
            theta: 0.5,
            f32: false,
        });
    }
    for &e in &eps {
        jobs.push(Job {
            case: "sigma_eps",
            omega: args.omega_sweep,
            n,
            sigma_eps: Some(e),
            theta: 0.5,
            f32: true,
        });
    }
    let mut work = crate::cost::Estimate::new();
    for j in &jobs {
        work.add(
            format!(
                "case {} (n = {}): --max-iterations {} × {}³ FLD-LP voxel updates",
                j.case, j.n, args.max_iterations, j.n
            ),
            args.max_iterations as f64 * (j.n as f64).powi(3) * crate::cost::FLD_VOXEL,
        );
    }
    ctx.work(&work)?;
    let params = serde_json::json!({"n": n, "omega": omegas, "resolutions": resolutions, "omega_sweep": args.omega_sweep, "sigma_eps_times_L": eps, "max_iterations": args.max_iterations, "seed": args.seed, "limiter": "lp"});
    let backends = args.backend.open()?;
    ctx.start(params)?;
    let out = ctx;
    out.record("backends", backends.meta());
    let kinds = backends.list(Precision::F64).len();
    let pb = progress((jobs.len() * kinds) as u64, &args.common, "convergence");
    let (mut residuals, mut iters) = (Vec::new(), Vec::new());
    for job in &jobs {
        let precision = if job.f32 {
            Precision::F32
        } else {
            Precision::F64
        };
        for backend in backends.list(precision) {
            pb.set_message(format!(
                "{} ω={} n={} {backend}",
                job.case, job.omega, job.n
            ));
            let (row, res) = solve(args, job, &backend, &pb)?;
            out.timing(
                format!(
                    "{} ω={} n={} σε={:?} θ={} {backend}",
                    job.case, job.omega, job.n, job.sigma_eps, job.theta
                ),
                row.seconds,
            );
            for (i, r) in res.into_iter().enumerate() {
                residuals.push(ResidualRow {
                    case: job.case,
                    omega: job.omega,
                    n: job.n,
                    sigma_eps: row.sigma_eps,
                    iteration: i + 1,
                    residual: r,
                    theta: job.theta,
                    precision: row.precision,
                    backend: row.backend,
                });
            }
            iters.push(row);
            pb.inc(1);
        }
    }
    pb.finish_and_clear();
    out.csv("residuals.csv", &residuals)?;
    out.csv("iterations.csv", &iters)?;
    for backend in backends.list(Precision::F64) {
        let kind = backend.kind();
        let res: Vec<&ResidualRow> = residuals.iter().filter(|r| r.backend == kind).collect();
        let its: Vec<&IterRow> = iters.iter().filter(|r| r.backend == kind).collect();
        plots(
            out,
            args,
            n,
            &omegas,
            &eps,
            &res,
            &its,
            &backend,
            backends.plot_suffix(kind),
        )?;
    }
    Ok(iters)
}

/// The three panels of Fig 4 for one backend.
#[allow(clippy::too_many_arguments)]
fn plots(
    out: &Ctx,
    args: &Args,
    n: usize,
    omegas: &[f64],
    eps: &[f64],
    residuals: &[&ResidualRow],
    iters: &[&IterRow],
    backend: &Backend<'_>,
    suffix: &str,
) -> Result<()> {
    let (prec_ab, tol_ab) = match backend {
        Backend::Gpu(_) => ("f32", "1e-4"),
        Backend::Cpu(_) => ("f64", "1e-6"),
    };
    let on = backend.kind();

    let curve = |case: &str, key: &dyn Fn(&ResidualRow) -> bool| -> Vec<(f64, f64)> {
        residuals
            .iter()
            .filter(|r| r.case == case && key(r))
            .map(|r| (r.iteration as f64, r.residual))
            .collect()
    };
    let y = Axis::log("normalised RMS residual R̄/j̄");
    let mut series = Vec::new();
    for (c, &o) in omegas.iter().enumerate() {
        series.push(Series::new(
            format!("ω = {o}"),
            curve("sor", &|r| r.omega == o),
            Style::Line,
            c,
        ));
        series.push(Series::new(
            if c == 0 {
                "dashed: θ = 1 (Algorithm 1 verbatim)".to_string()
            } else {
                String::new()
            },
            curve("sor_theta1", &|r| r.omega == o),
            Style::Dashed,
            c,
        ));
    }
    plot(
        &out.path(&format!("fig4a_residual_vs_iteration{suffix}.png")),
        &format!("FLD Fig 4a: FLD-LP on the vacuum cloud, {n}³, {on}-{prec_ab}"),
        &Axis::lin("iteration"),
        &y,
        &series,
    )?;
    let pts: Vec<(f64, f64)> = iters
        .iter()
        .filter(|r| r.case == "resolution" && r.converged)
        .map(|r| (r.n as f64, r.iterations as f64))
        .collect();
    plot(
        &out.path(&format!("fig4b_iterations_vs_resolution{suffix}.png")),
        &format!(
            "FLD Fig 4b: iterations to R̄/j̄ < {tol_ab}, ω = {}, {on}",
            args.omega_sweep
        ),
        &Axis::lin("grid resolution n (n³ voxels)"),
        &Axis::lin("iterations"),
        &[
            Series::new(
                format!("FLD-LP, {on}-{prec_ab}"),
                pts.clone(),
                Style::Line,
                0,
            ),
            Series::new("", pts, Style::Points, 0),
        ],
    )?;
    let series: Vec<Series> = eps
        .iter()
        .enumerate()
        .map(|(c, &e)| {
            Series::new(
                format!("σε·L = {e:e}"),
                curve("sigma_eps", &|r| r.sigma_eps == e),
                Style::Line,
                c,
            )
        })
        .collect();
    plot(
        &out.path(&format!("fig4c_sigma_eps{suffix}.png")),
        &format!(
            "FLD Fig 4c: extinction floor σε, {n}³, {on}-f32, ω = {}",
            args.omega_sweep
        ),
        &Axis::lin("iteration"),
        &y,
        &series,
    )?;
    Ok(())
}

fn solve(
    args: &Args,
    job: &Job,
    backend: &Backend<'_>,
    pb: &indicatif::ProgressBar,
) -> Result<(IterRow, Vec<f64>)> {
    let medium = scenes::vacuum_cloud::<f64>(job.n, args.seed)?;
    let cfg = FldConfig {
        limiter: FluxLimiter::LevermorePomraning,
        omega: job.omega,
        max_iterations: args.max_iterations,
        sigma_eps: job.sigma_eps,
        d_relaxation: job.theta,
        ..FldConfig::default()
    };
    let sigma_eps = job.sigma_eps.unwrap_or(1e-3 / medium.grid.extent());
    let sol = fld::solve(backend, &medium, &Boundary::Zero, &cfg, |it, r| {
        if it % 50 == 0 {
            pb.set_message(format!(
                "{} ω={} n={} {backend} it {it} R̄/j̄ {r:.2e}",
                job.case, job.omega, job.n
            ));
        }
    })
    .with_context(|| format!("{} ω={} n={} on {backend}", job.case, job.omega, job.n))?;
    let row = IterRow {
        case: job.case,
        omega: job.omega,
        n: job.n,
        sigma_eps,
        iterations: sol.steps,
        seconds: sol.seconds,
        timer: sol.timer.to_string(),
        converged: sol.converged(),
        theta: job.theta,
        precision: backend.precision().name(),
        backend: backend.kind(),
    };
    Ok((row, sol.trace.residuals))
}

/// FLD Fig 4 in the registry.
#[derive(Debug)]
pub struct Convergence;

impl Experiment for Convergence {
    const NAME: &'static str = "convergence";
    const TITLE: &'static str =
        "FLD Fig 4: convergence (spherical cloud in vacuum, Perlin emission, FLD-LP)";
    const BACKEND: BackendSupport = BackendSupport::Flag;
    type Args = Args;
    type Summary = Vec<IterRow>;

    fn common(args: &Args) -> &CommonArgs {
        &args.common
    }

    fn promises(args: &Args) -> Vec<Promise> {
        let mut p = vec![
            Promise::csv(
                "residuals.csv",
                &[
                    "case",
                    "omega",
                    "n",
                    "sigma_eps",
                    "iteration",
                    "residual",
                    "theta",
                    "precision",
                    "backend",
                ],
            ),
            Promise::csv(
                "iterations.csv",
                &[
                    "case",
                    "omega",
                    "n",
                    "sigma_eps",
                    "iterations",
                    "seconds",
                    "timer",
                    "converged",
                    "theta",
                    "precision",
                    "backend",
                ],
            ),
        ];
        for s in args.backend.plot_suffixes() {
            for f in [
                "fig4a_residual_vs_iteration",
                "fig4b_iterations_vs_resolution",
                "fig4c_sigma_eps",
            ] {
                p.push(Promise::file(format!("{f}{s}.png")));
            }
        }
        p
    }

    fn run(ctx: &mut Ctx, args: &Args) -> Result<Self::Summary> {
        run_in(ctx, args)
    }

    fn report(s: &Section<'_>) -> Result<String> {
        let t = s.csv("iterations.csv")?;
        t.require(&[
            "case",
            "omega",
            "n",
            "sigma_eps",
            "theta",
            "precision",
            "iterations",
            "converged",
            "seconds",
        ])?;
        let mut out = s.pngs([
            "fig4a_residual_vs_iteration.png",
            "fig4b_iterations_vs_resolution.png",
            "fig4c_sigma_eps.png",
        ]);
        out.push('\n');
        let rows = t.rows().map(|r| {
            vec![
                format!("`{}`", r.get("case")),
                r.get("omega").to_string(),
                r.get("n").to_string(),
                r.sci("sigma_eps", 0),
                r.get("theta").to_string(),
                format!("{} {}", r.get("backend"), r.get("precision")),
                format!(
                    "{}{}",
                    r.get("iterations"),
                    if r.flag("converged") { "" } else { " (cap)" }
                ),
                r.fixed("seconds", 2),
            ]
        });
        out.push_str(&table(
            &[
                "case",
                "ω",
                "n",
                "σε",
                "θ",
                "backend",
                "iterations",
                "solve (s)",
            ],
            rows,
        ));
        out.push_str(
            "\n`sor`: our default D under-relaxation θ = 0.5; `sor_theta1`: FLD Algorithm 1 verbatim (θ = 1); \
             `resolution`: Fig 4b; `sigma_eps`: Fig 4c in f32 (tolerance 10⁻⁴). See `solvers::fld` for why θ = 0.5 \
             is the default.\n",
        );
        out.push_str(&bench());
        Ok(out)
    }
}

/// The committed diffusion benchmarks (`cargo bench -p benches`), curated (empty if none).
fn bench() -> String {
    use crate::report::{Table, short_device};
    let dir = crate::common::workspace_root().join("results/bench");
    let mut out = String::new();
    if let Ok(t) = Table::read(&dir.join("diffusion_cpu.csv")) {
        let rows = t.rows().map(|r| {
            vec![
                r.get("method").to_string(),
                r.get("n").to_string(),
                r.get("precision").to_string(),
                r.fixed("ms_per_iter", 3),
                r.fixed("mvox_per_s", 0),
                r.fixed("effective_gbs", 1),
                r.fixed("triad_gbs", 1),
                r.fixed("ratio_triad", 2),
                r.fixed("triad_dram_gbs", 1),
                r.fixed("ratio_triad_dram", 2),
                match r.get("cpu") {
                    "" => "—".to_string(),
                    cpu => format!("{cpu} ({} threads)", r.get("threads")),
                },
            ]
        });
        out.push_str(
            "\n### Benchmark: one red-black iteration vs memory bandwidth (CPU, last committed \
             `cargo bench -p benches` run, [`bench/diffusion_cpu.csv`](bench/diffusion_cpu.csv))\n\n",
        );
        out.push_str(&table(
            &[
                "method",
                "n",
                "precision",
                "ms/iteration",
                "Mvoxel/s",
                "effective GB/s",
                "triad GB/s (same bytes)",
                "÷ triad",
                "STREAM-rule triad GB/s",
                "÷ STREAM-rule triad",
                "CPU",
            ],
            rows,
        ));
    }
    if let Ok(t) = Table::read(&dir.join("diffusion_gpu.csv")) {
        let rows = t.rows().map(|r| {
            vec![
                short_device(r.get("adapter")),
                r.get("method").to_string(),
                r.get("n").to_string(),
                r.fixed("ms_per_iter", 3),
                r.fixed("mvox_per_s", 1),
                r.fixed("effective_gbs", 2),
                r.fixed("copy_gbs", 2),
                r.fixed("ratio_copy", 3),
                r.get("timer").to_string(),
            ]
        });
        out.push_str(
            "\n### GPU backend (`cargo bench -p benches --bench diffusion_gpu`, \
             [`bench/diffusion_gpu.csv`](bench/diffusion_gpu.csv))\n\n\
             Effective bandwidth counts 9 f32 values per voxel for FLD, 7 for CDA, against the same device's copy \
             bandwidth measured in the same run. On `llvmpipe` (Mesa's CPU Vulkan driver) these are emulation \
             numbers, not GPU numbers.\n\n",
        );
        out.push_str(&table(
            &[
                "adapter",
                "method",
                "n",
                "ms/iteration",
                "Mvoxel/s",
                "effective GB/s",
                "copy GB/s",
                "÷ copy",
                "timer",
            ],
            rows,
        ));
    }
    out
}
