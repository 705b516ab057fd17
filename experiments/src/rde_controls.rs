//! The thesis's negative controls (spec §1.9, §1.12, §3): thesis Fig 3.6(a) (the P1 moment
//! FTCS of thesis Eqs 3.23–3.26 decouples into 8 sublattices), Fig 3.6(b) (the extended
//! stencil, Sobel weights (1, 2, 1)/4, our choice) and Fig 3.5 (the FE steady RTE with
//! Jacobi, thesis Eq 3.22, sign flips and growth), with the checkerboard detector's numbers.
//!
//! * `checkerboard.csv`: a one-voxel source in a uniform medium (β = 1/3, α = 0.9; n³
//!   Dirichlet): P1 (central), P1 (Sobel), the RDE, and the run the thesis's P1 criterion
//!   admits but which is unstable (β = 1, α = 0.9, r = 1.0): off-sublattice fraction,
//!   Nyquist-plane energy, min φ/max φ, whether the detector flags it, growth of max|φ| over
//!   the second half of the run.
//! * `fe.csv`: FE Jacobi per iteration factor of a uniform field and of a random start (2D
//!   and 3D periodic, Kt∆ ∈ {0.1, 1, 10, 100}); the exact uniform factor is 1 − 1/δ₀ = −5/4
//!   (2D), −19/8 (3D).

use crate::common::{CommonArgs, Ctx};
use crate::cost::Estimate;
use crate::experiment::{BackendSupport, Experiment, Promise};
use crate::plot::{Axis, Series, Style, plot};
use crate::report::{Section, table};
use anyhow::Result;
use serde::Serialize;
use solvers::Grid;
use solvers::noise::SplitMix64;
use solvers::rde::fe::FeJacobi;
use solvers::rde::p1::{Checkerboard, P1, P1Config, P1Stencil, p1_critical_r};
use solvers::rde::{Coefficients, CpuRde, PointSource, RdeConfig};

/// Flags of `rde_controls`.
#[derive(Debug, Clone, clap::Parser)]
#[command(about = "Thesis Figs 3.5, 3.6(a)/(b): P1 checkerboard, extended stencil, FE Jacobi")]
pub struct Args {
    /// Shared flags.
    #[command(flatten)]
    pub common: CommonArgs,
}

#[derive(Debug, Serialize)]
struct CbRow {
    scheme: String,
    beta: f64,
    albedo: f64,
    r: f64,
    steps: usize,
    off_sublattice: f64,
    nyquist: f64,
    min_over_max: f64,
    flagged: bool,
    growth_second_half: f64,
}

#[derive(Debug, Serialize)]
struct FeRow {
    dims: usize,
    kt_dl: f64,
    start: &'static str,
    iterations: usize,
    factor_per_iteration: f64,
    exact_uniform_factor: f64,
}

fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0f64, |m, x| m.max(x.abs()))
}

fn source_coef(n: usize, beta: f64, albedo: f64) -> Result<(Coefficients, [usize; 3])> {
    let grid = Grid::new([n; 3], 1.0)?;
    let src = [n / 2 - 1; 3];
    let c =
        Coefficients::uniform(grid, beta, (1.0 - albedo) / (3.0 * beta))?.with_point_sources(&[
            PointSource {
                voxel: src,
                power: 1.0,
            },
        ])?;
    Ok((c, src))
}

/// Runs P1 for `steps`; returns φ, max|φ| at steps/2 and at the end.
fn p1_run(coef: &Coefficients, cfg: P1Config, steps: usize) -> Result<(Vec<f64>, f64, f64)> {
    let mut s = P1::<f64>::new(coef, cfg)?;
    let mut half = 0.0;
    for i in 0..steps {
        s.step();
        if i + 1 == steps / 2 {
            half = max_abs(&s.phi);
        }
    }
    let end = max_abs(&s.phi);
    Ok((s.phi, half, end))
}

fn run_in(ctx: &mut Ctx, _args: &Args) -> Result<()> {
    let quick = ctx.quick();
    let (n, steps) = if quick { (13, 600) } else { (19, 2000) };
    let fe_n: usize = if quick { 6 } else { 8 };
    let mut work = Estimate::new();
    work.add(
        "P1 runs",
        3.0 * steps as f64 * 4.0 * (n as f64).powi(3) * 3.0,
    );
    work.add("RDE steady", 3000.0 * (n as f64).powi(3));
    work.add("FE Jacobi", 8.0 * 40.0 * 4.0 * (fe_n as f64).powi(3) * 27.0);
    ctx.work(&work)?;
    ctx.start(serde_json::json!({"n": n, "steps": steps, "fe_n": fe_n}))?;

    let mut rows = Vec::new();
    let mut profiles = Vec::new();
    let (beta, albedo) = (1.0 / 3.0, 0.9);
    let (coef, src) = source_coef(n, beta, albedo)?;
    let g = coef.grid;
    let a = coef.ka_dl[0];
    let rc = p1_critical_r(a, 1.0 / (3.0 * beta));
    let row_of = |phi: &[f64]| -> Vec<(f64, f64)> {
        let m = max_abs(phi);
        (0..n)
            .map(|i| (i as f64, phi[g.index(i, src[1], src[2])] / m))
            .collect()
    };
    for (label, stencil, r) in [
        ("P1 central (Eq 3.26)", P1Stencil::Central, 0.9 * rc),
        ("P1 Sobel (Fig 3.6(b))", P1Stencil::Sobel, 0.45 * rc),
    ] {
        let cfg = P1Config {
            r,
            verbatim: false,
            stencil,
        };
        let (phi, half, end) = p1_run(&coef, cfg, steps)?;
        let d = Checkerboard::measure(&g, &phi, src);
        let mx = max_abs(&phi);
        rows.push(CbRow {
            scheme: label.into(),
            beta,
            albedo,
            r,
            steps,
            off_sublattice: d.off_sublattice,
            nyquist: d.nyquist,
            min_over_max: phi.iter().cloned().fold(f64::INFINITY, f64::min) / mx,
            flagged: d.is_checkerboard(),
            growth_second_half: end / half,
        });
        profiles.push((label.to_string(), row_of(&phi)));
    }
    let rde = CpuRde::<f64>::new(&coef, &RdeConfig::default().steady(1e-10, 100_000))?.run();
    let d = Checkerboard::measure(&g, &rde.phi, src);
    let mx = max_abs(&rde.phi);
    rows.push(CbRow {
        scheme: "RDE conservative".into(),
        beta,
        albedo,
        r: rde.trace.r,
        steps: rde.steps,
        off_sublattice: d.off_sublattice,
        nyquist: d.nyquist,
        min_over_max: rde.trace.min_phi / mx,
        flagged: d.is_checkerboard(),
        growth_second_half: f64::NAN,
    });
    profiles.push(("RDE conservative".to_string(), row_of(&rde.phi)));
    // The run the thesis's criterion admits (β = 1, α = 0.9, r = 1.0): 60 steps.
    let (c1, s1) = source_coef(n, 1.0, 0.9)?;
    let cfg = P1Config {
        r: 1.0,
        verbatim: false,
        stencil: P1Stencil::Central,
    };
    let (phi, half, end) = p1_run(&c1, cfg, 60)?;
    let d = Checkerboard::measure(&c1.grid, &phi, s1);
    let mx = max_abs(&phi);
    rows.push(CbRow {
        scheme: "P1 central, thesis-admitted r = 1.0".into(),
        beta: 1.0,
        albedo: 0.9,
        r: 1.0,
        steps: 60,
        off_sublattice: d.off_sublattice,
        nyquist: d.nyquist,
        min_over_max: phi.iter().cloned().fold(f64::INFINITY, f64::min) / mx,
        flagged: d.is_checkerboard(),
        growth_second_half: end / half,
    });
    ctx.csv("checkerboard.csv", &rows)?;
    let series: Vec<Series> = profiles
        .into_iter()
        .enumerate()
        .map(|(c, (l, p))| Series::new(l, p, Style::Line, c))
        .collect();
    plot(
        &ctx.path("fig3_6.png"),
        "Thesis Fig 3.6 analog: φ/max φ on the row through the source",
        &Axis::lin("x (voxels)"),
        &Axis::lin("φ / max|φ|"),
        &series,
    )?;

    // Fig 3.5: FE Jacobi.
    let mut fe = Vec::new();
    let mut curves = Vec::new();
    for dims in [2usize, 3] {
        for kt in [0.1, 1.0, 10.0, 100.0] {
            for start in ["uniform", "random"] {
                let mut rng = SplitMix64::new(5);
                let len = fe_n.pow(dims as u32) * (dims + 1);
                let vals: Vec<f64> = (0..len).map(|_| rng.next_f64() - 0.5).collect();
                let cells = fe_n.pow(dims as u32);
                let mut s = FeJacobi::<f64>::new(dims, fe_n, kt, |c, i| {
                    if start == "uniform" {
                        if c == 0 { 1.0 } else { 0.0 }
                    } else {
                        vals[c * cells + i]
                    }
                });
                let exact = 1.0 - 1.0 / s.delta0();
                let its = 30;
                let norm = |s: &FeJacobi<f64>| {
                    s.x.iter()
                        .flat_map(|v| v.iter())
                        .map(|x| x * x)
                        .sum::<f64>()
                        .sqrt()
                };
                let mut curve = Vec::new();
                let mut prev = norm(&s);
                let mut factor = f64::NAN;
                for it in 1..=its {
                    let m0 = s.x[0][0];
                    s.iterate();
                    let now = norm(&s);
                    factor = if start == "uniform" {
                        s.x[0][0] / m0
                    } else {
                        now / prev
                    };
                    prev = now;
                    curve.push((it as f64, now));
                }
                if kt == 1.0 {
                    curves.push(Series::new(
                        format!("{dims}D, {start} start, Kt∆ = 1"),
                        curve,
                        if start == "uniform" {
                            Style::Line
                        } else {
                            Style::Dashed
                        },
                        dims,
                    ));
                }
                fe.push(FeRow {
                    dims,
                    kt_dl: kt,
                    start,
                    iterations: its,
                    factor_per_iteration: factor,
                    exact_uniform_factor: exact,
                });
            }
        }
    }
    ctx.csv("fe.csv", &fe)?;
    plot(
        &ctx.path("fig3_5.png"),
        "Thesis Fig 3.5 analog: FE + Jacobi (Eq 3.22) diverges",
        &Axis::lin("iteration"),
        &Axis::log("‖x‖₂"),
        &curves,
    )?;
    Ok(())
}

/// The thesis's negative controls in the registry.
#[derive(Debug)]
pub struct RdeControls;

impl Experiment for RdeControls {
    const NAME: &'static str = "rde_controls";
    const TITLE: &'static str =
        "Thesis Figs 3.5, 3.6(a)/(b): P1 checkerboard, extended stencil and FE Jacobi controls";
    const BACKEND: BackendSupport = BackendSupport::CpuOnly("small f64 negative controls");
    type Args = Args;
    type Summary = ();

    fn common(args: &Args) -> &CommonArgs {
        &args.common
    }

    fn promises(_args: &Args) -> Vec<Promise> {
        vec![
            Promise::csv(
                "checkerboard.csv",
                &[
                    "scheme",
                    "r",
                    "steps",
                    "off_sublattice",
                    "nyquist",
                    "min_over_max",
                    "flagged",
                ],
            ),
            Promise::csv(
                "fe.csv",
                &[
                    "dims",
                    "kt_dl",
                    "start",
                    "factor_per_iteration",
                    "exact_uniform_factor",
                ],
            ),
            Promise::file("fig3_6.png"),
            Promise::file("fig3_5.png"),
        ]
    }

    fn run(ctx: &mut Ctx, args: &Args) -> Result<()> {
        run_in(ctx, args)
    }

    fn report(s: &Section<'_>) -> Result<String> {
        let t = s.csv("checkerboard.csv")?;
        t.require(&["scheme", "off_sublattice", "nyquist", "flagged"])?;
        let mut out = String::from(
            "Checkerboard detector on a one-voxel source (off-sublattice fraction of Σ|φ|, \
             spectral energy on the Nyquist planes):\n\n",
        );
        out.push_str(&table(
            &[
                "scheme",
                "r",
                "steps",
                "off-sublattice",
                "Nyquist",
                "min/max φ",
                "flagged",
                "growth",
            ],
            t.rows().map(|r| {
                vec![
                    r.get("scheme").to_string(),
                    r.fixed("r", 4),
                    r.get("steps").to_string(),
                    r.fixed("off_sublattice", 3),
                    r.fixed("nyquist", 4),
                    r.fixed("min_over_max", 3),
                    r.get("flagged").to_string(),
                    r.sci("growth_second_half", 2),
                ]
            }),
        ));
        out.push_str("\nFE + Jacobi (thesis Eq 3.22), factor per iteration:\n\n");
        let f = s.csv("fe.csv")?;
        out.push_str(&table(
            &["dims", "Kt∆", "start", "factor", "exact (uniform)"],
            f.rows().map(|r| {
                vec![
                    r.get("dims").to_string(),
                    r.get("kt_dl").to_string(),
                    r.get("start").to_string(),
                    r.fixed("factor_per_iteration", 4),
                    r.fixed("exact_uniform_factor", 4),
                ]
            }),
        ));
        out.push('\n');
        out.push_str(&s.pngs(["fig3_6.png", "fig3_5.png"]));
        Ok(out)
    }
}
