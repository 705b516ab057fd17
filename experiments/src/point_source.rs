//! FLD Fig 5 and the flux-limiter comparison: one emitting voxel with j = 1/Δl³ at the centre
//! of an odd grid (a unit-power point source, FLD Section 6.1), homogeneous medium τ across.
//!
//! (a) CDA with Dirichlet values from FLD Eq 27, (b) CDA with zero boundary, (c) FLD with the
//! Levermore–Pomraning limiter and zero boundary, and every other limiter on the same problem.
//! Numeric points are overlaid on the analytic curves of FLD Eqs 24 and 27.
//!
//! Boundary choice: with `--boundary auto` (default) CDA runs with both boundaries (Fig 5a, b)
//! and FLD with the zero boundary (Fig 5c). An analytic boundary for an FLD limiter takes its
//! values from Grosjean (FLD Eq 24), the transport reference, since FLD has no closed form.
//!
//! Errors (in `runs.csv` and `results/README.md`): relative L2 error of φ against Grosjean
//! over all voxels with 0 < τ < 1 ("near the source"), and over the +x profile up to τ = 1.5.

use crate::common::{BackendArgs, CommonArgs, Ctx, PrecisionArg, list_item, progress, value_names};
use crate::experiment::{BackendSupport, Experiment, FigureRun, Promise};
use crate::plot::{Axis, Series, Style, plot};
use crate::report::{Row, Section, table};
use anyhow::{Context, Result, bail};
use reference::point_source::{PointSource as Exact, Solution};
use serde::Serialize;
use solvers::fld::{self, Boundary, FldConfig, FluxLimiter, KnudsenSigma};
use solvers::{Backend, Precision, scenes};
use std::fmt::Write as _;

/// Flags of `point_source`.
#[derive(Debug, Clone, clap::Parser)]
#[command(about = "FLD Fig 5 and the flux-limiter comparison on a point source")]
pub struct Args {
    /// Shared flags.
    #[command(flatten)]
    pub common: CommonArgs,
    /// Shared backend flag.
    #[command(flatten)]
    pub backend: BackendArgs,
    /// Grid resolution (odd). Default 127 (31 with --quick).
    #[arg(long, value_parser = crate::common::count_usize)]
    pub n: Option<usize>,
    /// Optical depth across the grid.
    #[arg(long, default_value_t = 4.0)]
    pub tau_extent: f64,
    /// Albedos.
    #[arg(long, value_delimiter = ',', value_parser = list_item::<f64>, default_value = "0.1,0.3,0.5,0.7,0.9,0.99")]
    pub albedo: Vec<f64>,
    /// Flux limiters: cda, sum, max, kershaw, `larsen<n>`, lp, or `all`.
    #[arg(long, value_delimiter = ',', value_parser = limiter_item, default_value = "all")]
    pub limiter: Vec<String>,
    /// Boundaries: zero, analytic, or auto (CDA both, FLD zero).
    #[arg(long, value_delimiter = ',', value_enum, default_value = "auto")]
    pub boundary: Vec<BoundaryArg>,
    /// Also run the Levermore–Pomraning effective-albedo Knudsen number (R with α σt) for
    /// every FLD limiter.
    #[arg(long)]
    pub effective_albedo: bool,
    /// Precision of CPU runs: f32 or f64 (GPU runs are f32).
    #[arg(long, value_enum, default_value = "f64")]
    pub precision: PrecisionArg,
    /// SOR factor (default: the Poisson optimum 2/(1 + sin(π/n))).
    #[arg(long)]
    pub omega: Option<f64>,
    /// Tolerance on R̄/j̄ (default 1e-6 in f64, 1e-4 in f32).
    #[arg(long)]
    pub tolerance: Option<f64>,
    /// Iteration cap per solve (multigrid: cycles).
    #[arg(long, default_value_t = 20_000, value_parser = crate::common::count_usize)]
    pub max_iterations: usize,
    /// Solvers, each run on every case: `sor` (red-black SOR, FLD Algorithm 1, the
    /// reference), `multigrid` (FAS F(2,2), `solvers::fld::multigrid`, CPU and GPU) and/or
    /// `auto` (multigrid from 100³ voxels for CDA and 63³ for FLD, SOR below, handing over
    /// to multigrid after 200 sweeps, and SOR where multigrid does not converge:
    /// `solvers::fld::Solver::Auto`; `solved_by` in `runs.csv` says which ran). The plots and
    /// the error tables use the first; `rel_l2_vs_first_solver` in `runs.csv` compares the
    /// others with it.
    #[arg(long, value_delimiter = ',', value_enum, default_value = "auto")]
    pub solver: Vec<SolverArg>,
}

/// A `--solver` value.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum SolverArg {
    /// Red-black SOR (FLD Algorithm 1).
    Sor,
    /// FAS multigrid, F(2,2) cycles (CPU and GPU).
    Multigrid,
    /// Multigrid where it was measured faster, SOR elsewhere and as its fallback
    /// (`solvers::fld::Solver::Auto`).
    Auto,
}

impl SolverArg {
    /// The solver with default settings.
    pub fn solver(self) -> fld::Solver {
        match self {
            Self::Sor => fld::Solver::Sor,
            Self::Multigrid => fld::Solver::Multigrid(fld::multigrid::MgConfig::default()),
            Self::Auto => fld::Solver::Auto(fld::multigrid::MgConfig::default()),
        }
    }
}

/// A `--boundary` value.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum BoundaryArg {
    /// CDA with both boundaries, FLD with the zero boundary.
    Auto,
    /// φ = 0 outside the grid.
    Zero,
    /// Dirichlet values from the analytic solution (FLD Eq 27 for CDA, Grosjean for FLD).
    Analytic,
}

/// One `--limiter` item: `all` or a limiter name (checked here, expanded by `limiter_list`).
fn limiter_item(s: &str) -> std::result::Result<String, String> {
    let t: String = list_item(s)?;
    if t != "all" {
        t.parse::<FluxLimiter>().map_err(|e| e.to_string())?;
    }
    Ok(t)
}

/// The limiters of `--limiter` (`all` expands to every limiter of FLD Table 2).
fn limiter_list(items: &[String]) -> Result<Vec<FluxLimiter>> {
    if items.iter().any(|l| l == "all") {
        return Ok(FluxLimiter::ALL.to_vec());
    }
    items
        .iter()
        .map(|l| {
            l.parse()
                .map_err(|e| anyhow::anyhow!("--limiter `{l}`: {e}"))
        })
        .collect()
}

/// One voxel of a +x profile (`profiles.csv`).
#[derive(Debug, Serialize)]
struct ProfileRow {
    method: &'static str,
    limiter: String,
    boundary: &'static str,
    albedo: f64,
    n: usize,
    tau_extent: f64,
    tau: f64,
    phi_norm: f64,
    knudsen: &'static str,
    precision: &'static str,
    backend: &'static str,
    solver: &'static str,
}

/// Analytic curves (`analytic.csv`).
#[derive(Debug, Serialize)]
struct AnalyticRow {
    albedo: f64,
    tau: f64,
    grosjean: f64,
    cda: f64,
    transport_limit: f64,
}

/// One solve (`runs.csv`) with its errors.
#[derive(Debug, Clone, Serialize)]
pub struct RunRow {
    /// `cda` or `fld`.
    pub method: &'static str,
    /// Limiter name.
    pub limiter: String,
    /// `zero` or `analytic`.
    pub boundary: &'static str,
    /// `sigma_t` (the paper's) or `albedo_sigma_t` (LP81's effective albedo).
    pub knudsen: &'static str,
    /// Albedo.
    pub albedo: f64,
    /// Grid resolution.
    pub n: usize,
    /// Precision.
    pub precision: &'static str,
    /// `cpu` or `gpu`.
    pub backend: &'static str,
    /// The `--solver` value: `sor`, `multigrid` or `auto`.
    pub solver: &'static str,
    /// The solvers that produced φ, in order (`solvers::fld::FldTrace::solver`): `sor`,
    /// `multigrid`, or for `auto` e.g. `sor>multigrid` (SOR did not finish in its sweep
    /// budget, multigrid solved from scratch).
    pub solved_by: String,
    /// The relaxation factor of the solver that produced φ: SOR's, or multigrid's smoother
    /// (`MgConfig::smoother_omega`, 1.2 by default; until 2026-12-08 this column wrote 1 for
    /// multigrid, the smoother's factor before it was measured and raised).
    pub omega: f64,
    /// Iterations run (multigrid: cycles).
    pub iterations: usize,
    /// Work in fine red-black sweeps (SOR: the iterations; multigrid: smoothing sweeps,
    /// level ℓ counting 8^(−ℓ); transfers and residuals uncounted, see `seconds`).
    pub work_units: f64,
    /// Whether R̄/j̄ reached the tolerance.
    pub converged: bool,
    /// Why the solve stopped: `converged`, `cap`, `stalled` or `non_finite`.
    pub stop: String,
    /// Final R̄/j̄.
    pub residual: f64,
    /// Seconds of the solve (GPU: timestamp queries where available, see `timer`).
    pub seconds: f64,
    /// How `seconds` was measured: `wall-clock` or `gpu-timestamps`.
    pub timer: String,
    /// Seconds from the start of the solve until R̄/j̄ first fell below the tolerance
    /// (`FldTrace::seconds_to_tolerance`; empty where it never did or on the GPU). SOR stops
    /// there; multigrid's stop also waits for its error estimate, so its `seconds` can be a
    /// cycle longer. Issue 15's acceptance 3 compares these.
    pub seconds_to_tolerance: Option<f64>,
    /// Relative L2 error against Grosjean over voxels with 0 < τ < 1.
    pub err_grosjean_near: f64,
    /// Relative L2 error against Grosjean over the +x profile voxels with τ ≤ 1.5.
    pub err_grosjean_profile: f64,
    /// Relative L2 error against FLD Eq 27 over voxels with 0 < τ < 1.
    pub err_cda_near: f64,
    /// Relative L2 difference of φ (all voxels) from the first `--solver`'s φ of the same
    /// case and backend (0 for the first solver itself).
    pub rel_l2_vs_first_solver: f64,
}

#[derive(Debug, Clone, Copy)]
struct Case {
    limiter: FluxLimiter,
    boundary: &'static str,
    knudsen: KnudsenSigma,
    albedo: f64,
}

fn knudsen_name(k: KnudsenSigma) -> &'static str {
    match k {
        KnudsenSigma::Extinction => "sigma_t",
        KnudsenSigma::EffectiveAlbedo => "albedo_sigma_t",
    }
}

/// Runs the experiment; returns the per-solve rows (for `figures`).
pub fn run(args: &Args) -> Result<Vec<RunRow>> {
    crate::experiment::run::<PointSource>(args)
}

fn run_in(ctx: &mut Ctx, args: &Args) -> Result<Vec<RunRow>> {
    let n = args.n.unwrap_or(if args.common.quick { 31 } else { 127 });
    if n % 2 == 0 || n < 7 {
        bail!("--n must be odd and ≥ 7 so a single voxel sits at the centre, got {n}");
    }
    solvers::budget::check(format!("--n {n}"), solvers::budget::cube_solver_bytes(n))?;
    if !(args.tau_extent.is_finite() && args.tau_extent > 0.0) {
        bail!(
            "--tau-extent must be finite and > 0, got {}",
            args.tau_extent
        );
    }
    let albedos: Vec<f64> = args.albedo.clone();
    if let Some(a) = albedos.iter().find(|a| !(0.0..=1.0).contains(*a)) {
        bail!("--albedo: {a} is outside [0, 1]");
    }
    let limiters = limiter_list(&args.limiter)?;
    let mut solvers: Vec<SolverArg> = Vec::new();
    for &sv in &args.solver {
        if !solvers.contains(&sv) {
            solvers.push(sv);
        }
    }
    let boundaries: Vec<&'static str> = if args.boundary.contains(&BoundaryArg::Auto) {
        vec![]
    } else {
        args.boundary
            .iter()
            .map(|b| match b {
                BoundaryArg::Analytic => "analytic",
                _ => "zero",
            })
            .collect()
    };
    let mut cases = Vec::new();
    for &albedo in &albedos {
        for &limiter in &limiters {
            let bs: Vec<&'static str> = if boundaries.is_empty() {
                if limiter.is_constant() {
                    vec!["analytic", "zero"]
                } else {
                    vec!["zero"]
                }
            } else {
                boundaries.clone()
            };
            for &boundary in &bs {
                cases.push(Case {
                    limiter,
                    boundary,
                    knudsen: KnudsenSigma::Extinction,
                    albedo,
                });
                if args.effective_albedo && !limiter.is_constant() {
                    cases.push(Case {
                        limiter,
                        boundary,
                        knudsen: KnudsenSigma::EffectiveAlbedo,
                        albedo,
                    });
                }
            }
        }
    }
    if let Some(t) = args.tolerance
        && !(t.is_finite() && (0.0..1.0).contains(&t))
    {
        bail!("--tolerance {t}: must be in [0, 1) (0 runs exactly --max-iterations steps)");
    }
    let rel = args.tolerance.unwrap_or(match args.precision {
        PrecisionArg::F64 => 1e-6,
        PrecisionArg::F32 => 1e-4,
    });
    let mut work = crate::cost::Estimate::new();
    let voxels = (n as f64).powi(3);
    for &sv in &solvers {
        // `auto` ends in SOR where multigrid does not converge: costed as SOR.
        let mg = sv == SolverArg::Multigrid;
        for constant in [true, false] {
            let k = cases
                .iter()
                .filter(|c| c.limiter.is_constant() == constant)
                .count();
            if k == 0 {
                continue;
            }
            let steps = crate::cost::fld_steps(n, rel, args.max_iterations, constant);
            let what = match sv {
                SolverArg::Multigrid => "multigrid (costed as SOR's sweeps)".to_string(),
                SolverArg::Sor => format!("{steps:.0} SOR sweeps"),
                SolverArg::Auto => format!("auto (costed as {steps:.0} SOR sweeps)"),
            };
            work.add(
                format!(
                    "{k} {} cases × {what} × {n}³ voxels (tolerance {rel:e}, --max-iterations {})",
                    if constant { "CDA" } else { "FLD" },
                    args.max_iterations
                ),
                k as f64
                    * crate::cost::fld_solve(n, voxels, rel, args.max_iterations, constant, mg),
            );
        }
    }
    ctx.work(&work)?;
    let params = serde_json::json!({
        "n": n, "tau_extent": args.tau_extent, "albedo": albedos, "limiters": limiters.iter().map(|l| l.to_string()).collect::<Vec<_>>(),
        "boundary": value_names(&args.boundary), "effective_albedo": args.effective_albedo, "precision": args.precision.name(),
        "omega": args.omega.unwrap_or(FldConfig::poisson_optimal_omega(n)), "tolerance": args.tolerance, "max_iterations": args.max_iterations,
        "solver": value_names(&solvers),
    });
    let precision: Precision = args.precision.precision();
    let backends = args.backend.open()?;
    ctx.start(params)?;
    let out = ctx;
    out.record("backends", backends.meta());
    let list = backends.list(precision);
    let pb = progress(
        (cases.len() * list.len() * solvers.len()) as u64,
        &args.common,
        "point source",
    );
    let mut profiles = Vec::new();
    let mut runs = Vec::new();
    for case in &cases {
        for backend in &list {
            let mut first: Option<Vec<f64>> = None;
            for &sv in &solvers {
                pb.set_message(format!(
                    "{} {} α={} {backend} {}",
                    case.limiter,
                    case.boundary,
                    case.albedo,
                    sv.solver().name()
                ));
                let (mut run, prof, phi) = solve_case(args, n, case, backend, sv, &pb)?;
                run.rel_l2_vs_first_solver = match &first {
                    Some(f) => crate::convergence_check::rel_l2(&phi, f),
                    None => 0.0,
                };
                first.get_or_insert(phi);
                out.timing(
                    format!(
                        "{} {} {} α={} {backend} {}",
                        case.limiter,
                        case.boundary,
                        knudsen_name(case.knudsen),
                        case.albedo,
                        run.solver
                    ),
                    run.seconds,
                );
                runs.push(run);
                profiles.extend(prof);
                pb.inc(1);
            }
        }
    }
    pb.finish_and_clear();
    out.csv("profiles.csv", &profiles)?;
    out.csv("runs.csv", &runs)?;
    let tau_max = args.tau_extent / 2.0 * 3f64.sqrt();
    let taus: Vec<f64> = (0..300)
        .map(|i| 0.02 * (tau_max / 0.02).powf(i as f64 / 299.0))
        .collect();
    let analytic: Vec<AnalyticRow> = albedos
        .iter()
        .flat_map(|&a| {
            taus.iter().map(move |&t| AnalyticRow {
                albedo: a,
                tau: t,
                grosjean: Solution::Grosjean.normalized(t, a),
                cda: Solution::Cda.normalized(t, a),
                transport_limit: Solution::TransportLimit.normalized(t, a),
            })
        })
        .collect();
    out.csv("analytic.csv", &analytic)?;
    // The plots show the first solver (the others reach the same φ; see
    // `rel_l2_vs_first_solver`).
    let plotted = solvers[0].solver().name();
    for backend in &list {
        let kind = backend.kind();
        let prof: Vec<&ProfileRow> = profiles
            .iter()
            .filter(|p| p.backend == kind && p.solver == plotted)
            .collect();
        let rs: Vec<&RunRow> = runs
            .iter()
            .filter(|r| r.backend == kind && r.solver == plotted)
            .collect();
        let suffix = backends.plot_suffix(kind);
        let label = format!("{n}³, {backend}");
        plots(out, &albedos, &limiters, &prof, &rs, &taus, &label, suffix)?;
    }
    Ok(runs)
}

/// One solve: its `runs.csv` row, its +x profile and φ.
fn solve_case(
    args: &Args,
    n: usize,
    case: &Case,
    backend: &Backend<'_>,
    solver: SolverArg,
    pb: &indicatif::ProgressBar,
) -> Result<(RunRow, Vec<ProfileRow>, Vec<f64>)> {
    let solver = solver.solver();
    let (medium, src) = scenes::point_source::<f64>(n, args.tau_extent, case.albedo)
        .context("building the point-source medium")?;
    let g = medium.grid;
    let ps = Exact::new(args.tau_extent, case.albedo)?;
    let centre = g.center(src[0], src[1], src[2]);
    let dist = |p: [f64; 3]| {
        ((p[0] - centre[0]).powi(2) + (p[1] - centre[1]).powi(2) + (p[2] - centre[2]).powi(2))
            .sqrt()
    };
    let boundary = match case.boundary {
        "analytic" => {
            let sol = if case.limiter.is_constant() {
                Solution::Cda
            } else {
                Solution::Grosjean
            };
            Boundary::from_fn(&g, |p| ps.fluence(sol, dist(p)))
        }
        _ => Boundary::Zero,
    };
    let omega = args.omega.unwrap_or(FldConfig::poisson_optimal_omega(n));
    let cfg = FldConfig {
        limiter: case.limiter,
        omega,
        tolerance: args.tolerance,
        max_iterations: args.max_iterations,
        knudsen: case.knudsen,
        ..FldConfig::default()
    };
    // SOR reports every 25th iteration; multigrid (also under `auto`, whose SOR part is at
    // most 200 sweeps) every cycle.
    let every = if matches!(solver, fld::Solver::Sor) {
        25
    } else {
        1
    };
    let sol = fld::solve_with(backend, &medium, &boundary, &cfg, &solver, |it, r| {
        if it % every == 0 {
            pb.set_message(format!(
                "{} {} α={} {backend} {} it {it} R̄/j̄ {r:.2e}",
                case.limiter,
                case.boundary,
                case.albedo,
                solver.name()
            ));
        }
    })
    .with_context(|| {
        format!(
            "solving {} {} α={} on {backend} with {}",
            case.limiter,
            case.boundary,
            case.albedo,
            solver.name()
        )
    })?;
    let phi = &sol.phi;
    // 3D errors near the source.
    let (mut ng, mut dg, mut nc, mut dc) = (0.0, 0.0, 0.0, 0.0);
    for (idx, &v) in phi.iter().enumerate() {
        let [i, j, k] = g.coords(idx);
        let r = dist(g.center(i, j, k));
        let tau = ps.sigma_t * r;
        if r > 0.0 && tau < 1.0 {
            let (eg, ec) = (
                ps.fluence(Solution::Grosjean, r),
                ps.fluence(Solution::Cda, r),
            );
            ng += (v - eg).powi(2);
            dg += eg * eg;
            nc += (v - ec).powi(2);
            dc += ec * ec;
        }
    }
    let method = if case.limiter.is_constant() {
        "cda"
    } else {
        "fld"
    };
    let mut profile = Vec::new();
    let (mut np, mut dp) = (0.0, 0.0);
    for i in src[0] + 1..n {
        let r = dist(g.center(i, src[1], src[2]));
        let tau = ps.sigma_t * r;
        let v = phi[g.index(i, src[1], src[2])];
        if tau <= 1.5 {
            let e = ps.fluence(Solution::Grosjean, r);
            np += (v - e).powi(2);
            dp += e * e;
        }
        profile.push(ProfileRow {
            method,
            limiter: case.limiter.to_string(),
            boundary: case.boundary,
            albedo: case.albedo,
            n,
            tau_extent: args.tau_extent,
            tau,
            phi_norm: ps.normalize(v),
            knudsen: knudsen_name(case.knudsen),
            precision: backend.precision().name(),
            backend: backend.kind(),
            solver: solver.name(),
        });
    }
    let run = RunRow {
        method,
        limiter: case.limiter.to_string(),
        boundary: case.boundary,
        knudsen: knudsen_name(case.knudsen),
        albedo: case.albedo,
        n,
        precision: backend.precision().name(),
        backend: backend.kind(),
        solver: solver.name(),
        omega: match (&solver, sol.trace.solver_name()) {
            (fld::Solver::Multigrid(mg) | fld::Solver::Auto(mg), "multigrid") => mg.smoother_omega,
            _ => omega,
        },
        iterations: sol.steps,
        work_units: sol.trace.work_units,
        converged: sol.converged(),
        stop: sol.stop.to_string(),
        residual: sol.final_residual(),
        seconds: sol.seconds,
        timer: sol.timer.to_string(),
        seconds_to_tolerance: sol.trace.seconds_to_tolerance,
        err_grosjean_near: (ng / dg).sqrt(),
        err_grosjean_profile: (np / dp).sqrt(),
        err_cda_near: (nc / dc).sqrt(),
        rel_l2_vs_first_solver: 0.0,
        solved_by: sol.trace.solver.clone(),
    };
    Ok((run, profile, sol.phi))
}

#[allow(clippy::too_many_arguments)]
fn plots(
    out: &Ctx,
    albedos: &[f64],
    limiters: &[FluxLimiter],
    profiles: &[&ProfileRow],
    runs: &[&RunRow],
    taus: &[f64],
    label: &str,
    suffix: &str,
) -> Result<()> {
    let x = Axis::log("optical depth τ");
    let y = Axis::log("normalised fluence φ̃ (Eq 25)").range(1e-2, 1e4);
    let pick = |lim: &str, boundary: &str, knudsen: &str, a: f64| -> Vec<(f64, f64)> {
        profiles
            .iter()
            .filter(|p| {
                p.limiter == lim && p.boundary == boundary && p.knudsen == knudsen && p.albedo == a
            })
            .map(|p| (p.tau, p.phi_norm))
            .collect()
    };
    let curves = |sol: Solution, style: Style, label_first: &str| -> Vec<Series> {
        albedos
            .iter()
            .enumerate()
            .map(|(c, &a)| {
                Series::new(
                    if c == 0 {
                        label_first.to_string()
                    } else {
                        String::new()
                    },
                    taus.iter().map(|&t| (t, sol.normalized(t, a))).collect(),
                    style,
                    c,
                )
            })
            .collect()
    };
    let panels = [
        (
            "cda",
            "analytic",
            "fig5a_cda_analytic_boundary",
            "FLD Fig 5a: CDA, Dirichlet boundary from Eq 27",
        ),
        (
            "cda",
            "zero",
            "fig5b_cda_zero_boundary",
            "FLD Fig 5b: CDA, zero boundary",
        ),
        (
            "lp",
            "zero",
            "fig5c_fld_lp_zero_boundary",
            "FLD Fig 5c: FLD (Levermore–Pomraning), zero boundary",
        ),
    ];
    for (lim, boundary, file, title) in panels {
        if !profiles
            .iter()
            .any(|p| p.limiter == lim && p.boundary == boundary)
        {
            continue;
        }
        let mut series = curves(Solution::Cda, Style::Line, "CDA theory (Eq 27)");
        series.extend(curves(
            Solution::Grosjean,
            Style::Dashed,
            "Grosjean (Eq 24)",
        ));
        for (c, &a) in albedos.iter().enumerate() {
            series.push(Series::new(
                format!("α = {a}"),
                pick(lim, boundary, "sigma_t", a),
                Style::Points,
                c,
            ));
        }
        plot(
            &out.path(&format!("{file}{suffix}.png")),
            &format!("{title} ({label})"),
            &x,
            &y,
            &series,
        )?;
    }
    // Limiter comparison: one panel per albedo, every limiter against Grosjean.
    if limiters.len() > 1 {
        for &a in albedos {
            let mut series = vec![Series::new(
                "Grosjean (Eq 24)",
                taus.iter()
                    .map(|&t| (t, Solution::Grosjean.normalized(t, a)))
                    .collect(),
                Style::Line,
                7,
            )];
            for (c, lim) in limiters.iter().enumerate() {
                series.push(Series::new(
                    lim.to_string(),
                    pick(&lim.to_string(), "zero", "sigma_t", a),
                    Style::Points,
                    c,
                ));
            }
            plot(
                &out.path(&format!("limiters_albedo_{a}{suffix}.png")),
                &format!("Flux limiters, zero boundary, α = {a} ({label})"),
                &x,
                &y,
                &series,
            )?;
        }
        let mut series = Vec::new();
        for (c, lim) in limiters.iter().enumerate() {
            for (knudsen, style, suffix) in [
                ("sigma_t", Style::Line, ""),
                ("albedo_sigma_t", Style::Dashed, " (R with ασt)"),
            ] {
                let pts: Vec<(f64, f64)> = runs
                    .iter()
                    .filter(|r| {
                        r.limiter == lim.to_string() && r.boundary == "zero" && r.knudsen == knudsen
                    })
                    .map(|r| (r.albedo, r.err_grosjean_near))
                    .collect();
                if !pts.is_empty() {
                    series.push(Series::new(format!("{lim}{suffix}"), pts, style, c));
                }
            }
        }
        plot(
            &out.path(&format!("limiter_errors{suffix}.png")),
            &format!("Relative L2 error vs Grosjean for τ < 1 ({label}, zero boundary)"),
            &Axis::lin("albedo α"),
            &Axis::log("relative L2 error"),
            &series,
        )?;
    }
    Ok(())
}

/// FLD Fig 5 and the flux-limiter comparison in the registry.
#[derive(Debug)]
pub struct PointSource;

impl Experiment for PointSource {
    const NAME: &'static str = "point_source";
    const TITLE: &'static str = "FLD Fig 5: point source, numeric vs analytic";
    const BACKEND: BackendSupport = BackendSupport::Flag;
    type Args = Args;
    type Summary = Vec<RunRow>;

    fn common(args: &Args) -> &CommonArgs {
        &args.common
    }

    fn figure_runs(quick: bool) -> Vec<FigureRun> {
        let n_lim = if quick { 21 } else { 63 };
        vec![
            FigureRun::new("point_source", Self::TITLE).args(["--limiter", "cda,lp"]),
            FigureRun::new(
                "flux_limiters",
                "Flux-limiter comparison on the point source",
            )
            .args([
                "--limiter".to_string(),
                "all".into(),
                "--effective-albedo".into(),
                "--boundary".into(),
                "zero".into(),
                "--n".into(),
                n_lim.to_string(),
            ]),
        ]
    }

    fn promises(args: &Args) -> Vec<Promise> {
        let mut p = vec![
            Promise::csv(
                "runs.csv",
                &[
                    "method",
                    "limiter",
                    "boundary",
                    "knudsen",
                    "albedo",
                    "n",
                    "precision",
                    "backend",
                    "solver",
                    "solved_by",
                    "omega",
                    "iterations",
                    "work_units",
                    "converged",
                    "stop",
                    "residual",
                    "seconds",
                    "timer",
                    "seconds_to_tolerance",
                    "err_grosjean_near",
                    "err_grosjean_profile",
                    "err_cda_near",
                    "rel_l2_vs_first_solver",
                ],
            ),
            Promise::csv(
                "profiles.csv",
                &[
                    "method",
                    "limiter",
                    "boundary",
                    "albedo",
                    "n",
                    "tau_extent",
                    "tau",
                    "phi_norm",
                ],
            ),
            Promise::csv(
                "analytic.csv",
                &["albedo", "tau", "grosjean", "cda", "transport_limit"],
            ),
        ];
        let limiters = limiter_list(&args.limiter).unwrap_or_default();
        let has = |name: &str| limiters.iter().any(|l| l.to_string() == name);
        let auto = args.boundary.contains(&BoundaryArg::Auto);
        let bdy = |b: BoundaryArg| auto || args.boundary.contains(&b);
        for suffix in args.backend.plot_suffixes() {
            if has("cda") && bdy(BoundaryArg::Analytic) {
                p.push(Promise::file(format!(
                    "fig5a_cda_analytic_boundary{suffix}.png"
                )));
            }
            if has("cda") && bdy(BoundaryArg::Zero) {
                p.push(Promise::file(format!(
                    "fig5b_cda_zero_boundary{suffix}.png"
                )));
            }
            if has("lp") && bdy(BoundaryArg::Zero) {
                p.push(Promise::file(format!(
                    "fig5c_fld_lp_zero_boundary{suffix}.png"
                )));
            }
            if limiters.len() > 1 {
                p.push(Promise::file(format!("limiter_errors{suffix}.png")));
                for a in &args.albedo {
                    p.push(Promise::file(format!("limiters_albedo_{a}{suffix}.png")));
                }
            }
        }
        p
    }

    fn run(ctx: &mut Ctx, args: &Args) -> Result<Self::Summary> {
        run_in(ctx, args)
    }

    fn report(s: &Section<'_>) -> Result<String> {
        let t = s.csv("runs.csv")?;
        t.require(&[
            "limiter",
            "boundary",
            "knudsen",
            "albedo",
            "n",
            "iterations",
            "converged",
            "seconds",
            "err_grosjean_near",
            "err_cda_near",
            "backend",
        ])?;
        let mut out = String::new();
        let n = t
            .rows()
            .next()
            .map(|r| r.get("n").to_string())
            .unwrap_or_default();
        let limiters = t.distinct("limiter");
        // The tables read the first backend and the first solver (older runs.csv files have
        // no `solver` column: "" everywhere).
        let solvers = t.distinct("solver");
        let find_with = |lim: &str, b: &str, k: &str, a: &str, solver: &str| {
            t.rows().find(|r| {
                r.get("limiter") == lim
                    && r.get("boundary") == b
                    && r.get("knudsen") == k
                    && r.get("albedo") == a
                    && r.get("backend") == t.rows().next().map_or("", |f| f.get("backend"))
                    && r.get("solver") == solver
            })
        };
        let first_solver = solvers.first().cloned().unwrap_or_default();
        let find = |lim: &str, b: &str, k: &str, a: &str| find_with(lim, b, k, a, &first_solver);
        let cell = |r: Option<Row<'_>>, col: &str| r.map_or("–".to_string(), |r| r.fixed(col, 4));
        let solver_text = match first_solver.as_str() {
            "multigrid" => {
                "FAS multigrid, F(2,2) cycles (`solvers::fld::multigrid`; CPU: Krylov-accelerated, depth 3)"
            }
            "auto" => {
                "`auto` (`solvers::fld::Solver::Auto`): FAS multigrid, F(2,2) cycles, on grids of \
                 100³ voxels or more (FLD: 63³), red-black SOR at ω = 2/(1 + sin(π/n)) on smaller ones, handing \
                 over to multigrid after 200 sweeps and back to SOR where multigrid does not \
                 converge; `solved_by` in `runs.csv` says which ran, and the iterations below are \
                 multigrid cycles where multigrid solved"
            }
            _ => "red-black SOR at ω = 2/(1 + sin(π/n))",
        };
        let _ = writeln!(
            out,
            "{n}³ voxels, τ = 4 across, one emitting voxel. Relative L2 error of φ over all voxels with \
             0 < τ < 1, against Grosjean (FLD Eq 24) and, for CDA, against its own theory (FLD Eq 27). \
             Solver: {solver_text} (see `solver`, `solved_by`, `omega` and `residual` in `runs.csv`).\n"
        );
        if solvers.iter().any(|x| x == "sor") && solvers.iter().any(|x| x == "multigrid") {
            let _ = writeln!(
                out,
                "Time to solution, red-black SOR against FAS multigrid (F(2,2); CPU: Krylov depth 3), same run, same \
                 tolerance on R̄/j̄. Work units: fine red-black sweeps (multigrid's coarse sweeps \
                 count 8^(−level)). SOR stops when R̄/j̄ falls below the tolerance; multigrid's \
                 stop also waits for its error estimate (often one cycle more), so the table \
                 also gives multigrid's seconds until R̄/j̄ itself first fell below the \
                 tolerance and the speed-up at that like-for-like point (SOR's own: its \
                 seconds). Difference: relative L2 of φ, multigrid against SOR.\n"
            );
            let mut rows = Vec::new();
            for r in t.rows().filter(|r| r.get("solver") == "sor") {
                let (lim, b, k, a) = (
                    r.get("limiter"),
                    r.get("boundary"),
                    r.get("knudsen"),
                    r.get("albedo"),
                );
                let Some(m) = find_with(lim, b, k, a, "multigrid") else {
                    continue;
                };
                let stop = |x: Row<'_>| {
                    if x.flag("converged") {
                        String::new()
                    } else {
                        format!(" ({})", x.get("stop"))
                    }
                };
                rows.push(vec![
                    format!("{lim}, {b} boundary, α = {a}"),
                    format!("{}{}", r.get("iterations"), stop(r)),
                    r.fixed("seconds", 2),
                    format!("{}{}", m.get("iterations"), stop(m)),
                    m.fixed("work_units", 1),
                    m.fixed("seconds", 2),
                    crate::report::fixed(r.num("seconds") / m.num("seconds"), 1),
                    m.fixed("seconds_to_tolerance", 2),
                    crate::report::fixed(
                        r.num("seconds_to_tolerance") / m.num("seconds_to_tolerance"),
                        1,
                    ),
                    format!(
                        "{:.1e}",
                        m.num("rel_l2_vs_first_solver")
                            .max(r.num("rel_l2_vs_first_solver"))
                    ),
                ]);
            }
            out.push_str(&table(
                &[
                    "case",
                    "SOR iterations",
                    "SOR (s)",
                    "multigrid cycles",
                    "multigrid work units",
                    "multigrid (s)",
                    "speed-up (SOR s / multigrid s)",
                    "multigrid to R̄/j̄ < tol (s)",
                    "speed-up to R̄/j̄ < tol",
                    "difference",
                ],
                rows,
            ));
            out.push('\n');
        }
        // Fig 5 (a, b, c) needs CDA with both boundaries and FLD-LP; the limiter runs have no
        // analytic boundary.
        let fig5 = t.rows().any(|r| r.get("boundary") == "analytic");
        if fig5 && limiters.iter().any(|l| l == "cda") && limiters.iter().any(|l| l == "lp") {
            let rows = t.distinct("albedo").into_iter().map(|a| {
                let lp = find("lp", "zero", "sigma_t", &a);
                vec![
                    a.clone(),
                    cell(find("cda", "analytic", "sigma_t", &a), "err_cda_near"),
                    cell(find("cda", "zero", "sigma_t", &a), "err_cda_near"),
                    cell(find("cda", "zero", "sigma_t", &a), "err_grosjean_near"),
                    cell(lp, "err_grosjean_near"),
                    lp.map_or("–".into(), |r| {
                        let c = if r.flag("converged") {
                            ""
                        } else {
                            " (not converged)"
                        };
                        // `auto` runs: say which solver's steps these are.
                        let by = match r.get("solved_by") {
                            "" | "sor" => String::new(),
                            "multigrid" => " multigrid cycles".into(),
                            path => format!(" ({path})"),
                        };
                        format!("{}{by}{c}", r.get("iterations"))
                    }),
                    lp.map_or("–".into(), |r| r.fixed("seconds", 2)),
                ]
            });
            out.push_str(&table(
                &[
                    "albedo α",
                    "CDA, Eq 27 boundary: error vs Eq 27",
                    "CDA, zero boundary: vs Eq 27",
                    "CDA, zero boundary: vs Grosjean",
                    "FLD-LP, zero boundary: vs Grosjean",
                    "FLD-LP iterations",
                    "FLD-LP solve (s)",
                ],
                rows,
            ));
            out.push('\n');
            out.push_str(&s.pngs([
                "fig5a_cda_analytic_boundary.png",
                "fig5b_cda_zero_boundary.png",
                "fig5c_fld_lp_zero_boundary.png",
            ]));
        }
        if limiters.len() > 2 {
            let mut cols: Vec<(String, &str)> = Vec::new();
            for l in &limiters {
                cols.push((l.clone(), "sigma_t"));
                if t.rows()
                    .any(|r| r.get("limiter") == l && r.get("knudsen") == "albedo_sigma_t")
                {
                    cols.push((l.clone(), "albedo_sigma_t"));
                }
            }
            let _ = writeln!(
                out,
                "\nRelative L2 error against Grosjean near the source for every limiter of FLD Table 2, zero \
                 boundary; `(ασt)` is Levermore–Pomraning's effective-albedo Knudsen number R = |∇φ|/(α σt φ). \
                 **Bold**: the best per albedo.\n"
            );
            let mut header = vec!["albedo α".to_string()];
            header.extend(cols.iter().map(|(l, k)| {
                if *k == "albedo_sigma_t" {
                    format!("{l} (ασt)")
                } else {
                    l.clone()
                }
            }));
            let rows = t.distinct("albedo").into_iter().map(|a| {
                let vals: Vec<f64> = cols
                    .iter()
                    .map(|(l, k)| {
                        find(l, "zero", k, &a).map_or(f64::NAN, |r| r.num("err_grosjean_near"))
                    })
                    .collect();
                let best = vals
                    .iter()
                    .copied()
                    .filter(|v| v.is_finite())
                    .fold(f64::INFINITY, f64::min);
                let mut row = vec![a.clone()];
                row.extend(vals.iter().map(|&v| {
                    if v == best {
                        format!("**{v:.4}**")
                    } else {
                        crate::report::fixed(v, 4)
                    }
                }));
                row
            });
            let header: Vec<&str> = header.iter().map(String::as_str).collect();
            out.push_str(&table(&header, rows));
            let unconverged: Vec<String> = t
                .rows()
                .filter(|r| !r.flag("converged"))
                .map(|r| {
                    format!(
                        "{} ({}) α={}",
                        r.get("limiter"),
                        r.get("knudsen"),
                        r.get("albedo")
                    )
                })
                .collect();
            if !unconverged.is_empty() {
                let _ = writeln!(
                    out,
                    "\nNot converged within the iteration cap: {}.",
                    unconverged.join(", ")
                );
            }
            out.push('\n');
            out.push_str(&s.png("limiter_errors.png"));
        }
        Ok(out)
    }
}
