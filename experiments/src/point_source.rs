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

use crate::common::{BackendArgs, CommonArgs, Output, parse_list, progress};
use crate::plot::{Axis, Series, Style, plot};
use anyhow::{Context, Result, bail};
use reference::point_source::{PointSource, Solution};
use serde::Serialize;
use solvers::fld::{self, Boundary, FldConfig, FluxLimiter, KnudsenSigma};
use solvers::{Backend, Precision, scenes};

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
    #[arg(long)]
    pub n: Option<usize>,
    /// Optical depth across the grid.
    #[arg(long, default_value_t = 4.0)]
    pub tau_extent: f64,
    /// Albedos.
    #[arg(long, default_value = "0.1,0.3,0.5,0.7,0.9,0.99")]
    pub albedo: String,
    /// Flux limiters: cda, sum, max, kershaw, larsen<n>, lp, or `all`.
    #[arg(long, default_value = "all")]
    pub limiter: String,
    /// Boundaries: zero, analytic, or auto (CDA both, FLD zero).
    #[arg(long, default_value = "auto")]
    pub boundary: String,
    /// Also run the Levermore–Pomraning effective-albedo Knudsen number (R with α σt) for
    /// every FLD limiter.
    #[arg(long)]
    pub effective_albedo: bool,
    /// Precision of CPU runs: f32 or f64 (GPU runs are f32).
    #[arg(long, default_value = "f64")]
    pub precision: String,
    /// SOR factor (default: the Poisson optimum 2/(1 + sin(π/n))).
    #[arg(long)]
    pub omega: Option<f64>,
    /// Tolerance on R̄/j̄ (default 1e-6 in f64, 1e-4 in f32).
    #[arg(long)]
    pub tolerance: Option<f64>,
    /// Iteration cap per solve.
    #[arg(long, default_value_t = 20_000)]
    pub max_iterations: usize,
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
    /// SOR factor used.
    pub omega: f64,
    /// Iterations run.
    pub iterations: usize,
    /// Whether R̄/j̄ reached the tolerance.
    pub converged: bool,
    /// Final R̄/j̄.
    pub residual: f64,
    /// Seconds of the solve (GPU: timestamp queries where available, see `timer`).
    pub seconds: f64,
    /// How `seconds` was measured: `wall-clock` or `gpu-timestamps`.
    pub timer: String,
    /// Relative L2 error against Grosjean over voxels with 0 < τ < 1.
    pub err_grosjean_near: f64,
    /// Relative L2 error against Grosjean over the +x profile voxels with τ ≤ 1.5.
    pub err_grosjean_profile: f64,
    /// Relative L2 error against FLD Eq 27 over voxels with 0 < τ < 1.
    pub err_cda_near: f64,
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

fn parse_limiters(s: &str) -> Result<Vec<FluxLimiter>> {
    if s.trim() == "all" {
        return Ok(FluxLimiter::ALL.to_vec());
    }
    parse_list("limiter", s)
}

/// Runs the experiment; returns the per-solve rows (for `figures`).
pub fn run(args: &Args) -> Result<Vec<RunRow>> {
    let n = args.n.unwrap_or(if args.common.quick { 31 } else { 127 });
    if n % 2 == 0 || n < 7 {
        bail!("--n must be odd and ≥ 7 so a single voxel sits at the centre, got {n}");
    }
    if !(args.tau_extent.is_finite() && args.tau_extent > 0.0) {
        bail!(
            "--tau-extent must be finite and > 0, got {}",
            args.tau_extent
        );
    }
    let albedos: Vec<f64> = parse_list("albedo", &args.albedo)?;
    if let Some(a) = albedos.iter().find(|a| !(0.0..=1.0).contains(*a)) {
        bail!("--albedo: {a} is outside [0, 1]");
    }
    let limiters = parse_limiters(&args.limiter)?;
    let boundaries: Vec<&'static str> = match args.boundary.trim() {
        "auto" => vec![],
        s => s
            .split(',')
            .map(|b| match b.trim() {
                "zero" => Ok("zero"),
                "analytic" => Ok("analytic"),
                other => Err(anyhow::anyhow!(
                    "--boundary: `{other}` is not zero, analytic or auto"
                )),
            })
            .collect::<Result<_>>()?,
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
    let params = serde_json::json!({
        "n": n, "tau_extent": args.tau_extent, "albedo": albedos, "limiters": limiters.iter().map(|l| l.to_string()).collect::<Vec<_>>(),
        "boundary": args.boundary, "effective_albedo": args.effective_albedo, "precision": args.precision,
        "omega": args.omega.unwrap_or(FldConfig::poisson_optimal_omega(n)), "tolerance": args.tolerance, "max_iterations": args.max_iterations,
    });
    let precision: Precision = args
        .precision
        .parse()
        .with_context(|| format!("--precision `{}`", args.precision))?;
    let backends = args.backend.open()?;
    let mut out = Output::new("point_source", &args.common, params)?;
    out.record("backends", backends.meta());
    let list = backends.list(precision);
    let pb = progress(
        (cases.len() * list.len()) as u64,
        &args.common,
        "point source",
    );
    let mut profiles = Vec::new();
    let mut runs = Vec::new();
    for case in &cases {
        for backend in &list {
            pb.set_message(format!(
                "{} {} α={} {backend}",
                case.limiter, case.boundary, case.albedo
            ));
            let (run, prof) = solve_case(args, n, case, backend, &pb)?;
            out.timing(
                format!(
                    "{} {} {} α={} {backend}",
                    case.limiter,
                    case.boundary,
                    knudsen_name(case.knudsen),
                    case.albedo
                ),
                run.seconds,
            );
            runs.push(run);
            profiles.extend(prof);
            pb.inc(1);
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
    for backend in &list {
        let kind = backend.kind();
        let prof: Vec<&ProfileRow> = profiles.iter().filter(|p| p.backend == kind).collect();
        let rs: Vec<&RunRow> = runs.iter().filter(|r| r.backend == kind).collect();
        let suffix = backends.plot_suffix(kind);
        let label = format!("{n}³, {backend}");
        plots(&out, &albedos, &limiters, &prof, &rs, &taus, &label, suffix)?;
    }
    out.finish()?;
    Ok(runs)
}

fn solve_case(
    args: &Args,
    n: usize,
    case: &Case,
    backend: &Backend<'_>,
    pb: &indicatif::ProgressBar,
) -> Result<(RunRow, Vec<ProfileRow>)> {
    let (medium, src) = scenes::point_source::<f64>(n, args.tau_extent, case.albedo)
        .context("building the point-source medium")?;
    let g = medium.grid;
    let ps = PointSource::new(args.tau_extent, case.albedo)?;
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
    let sol = fld::solve(backend, &medium, &boundary, &cfg, |it, r| {
        if it % 25 == 0 {
            pb.set_message(format!(
                "{} {} α={} {backend} it {it} R̄/j̄ {r:.2e}",
                case.limiter, case.boundary, case.albedo
            ));
        }
    })
    .with_context(|| {
        format!(
            "solving {} {} α={} on {backend}",
            case.limiter, case.boundary, case.albedo
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
        omega,
        iterations: sol.steps,
        converged: sol.converged(),
        residual: sol.final_residual(),
        seconds: sol.seconds,
        timer: sol.timer.to_string(),
        err_grosjean_near: (ng / dg).sqrt(),
        err_grosjean_profile: (np / dp).sqrt(),
        err_cda_near: (nc / dc).sqrt(),
    };
    Ok((run, profile))
}

#[allow(clippy::too_many_arguments)]
fn plots(
    out: &Output,
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
