//! Thesis Fig 4.1 analog: the thesis's stability condition (thesis Eq 4.9, r ≤
//! 6β/(72β² + 9β + 2(1 − α))) over (β, α) against the von Neumann bound r_vN = 2/(a + 12β),
//! the positivity bound r_pos = 1/(a + 6β) (a = (1 − α)/(3β), g = 0) and the *measured*
//! critical r, with the thesis's r = 0.1 plane (spec §1.7, §3).
//!
//! * Uniform media: r_crit measured as 2/μ_max, μ_max the largest eigenvalue of the
//!   conservative operator −L (a + Σ face terms) on an N³ Dirichlet grid by power iteration,
//!   next to the exact Dirichlet value 2/(a + 12β cos²(π/(2(N−1)))) (N − 2 interior voxels).
//! * Heterogeneous media (β step 1 | 0.01, random β ∈ U[0.01, 1], the thesis's gradient
//!   mapping of a tube phantom; α ∈ {0, 0.99}): r_crit of each operator measured by bisection
//!   on growth of ‖φ‖ between steps K/2 and K of the FTCS itself from a random start; 0 means
//!   it grows at the smallest r tried.

use crate::common::{CommonArgs, Ctx};
use crate::cost::Estimate;
use crate::experiment::{BackendSupport, Experiment, Promise};
use crate::plot::{Axis, Series, Style, plot};
use crate::report::{Section, fixed, table};
use anyhow::{Context, Result};
use serde::Serialize;
use solvers::Grid;
use solvers::noise::SplitMix64;
use solvers::rde::pm::{Conductance, Phantom};
use solvers::rde::{
    Coefficients, CpuRde, Operator, RdeConfig, StepCheck, TimeStep, eq_4_9_printed,
};

/// Flags of `rde_stability`.
#[derive(Debug, Clone, clap::Parser)]
#[command(about = "Thesis Fig 4.1: Eq 4.9 vs the von Neumann, positivity and measured r_crit")]
pub struct Args {
    /// Shared flags.
    #[command(flatten)]
    pub common: CommonArgs,
}

#[derive(Debug, Serialize)]
struct Region {
    beta: f64,
    albedo: f64,
    eq49: f64,
    r_pos: f64,
    r_vn: f64,
    r01_eq49: bool,
    r01_pos: bool,
    r01_vn: bool,
}

#[derive(Debug, Serialize)]
struct Measured {
    beta: f64,
    albedo: f64,
    n: usize,
    eq49: f64,
    r_pos: f64,
    r_vn: f64,
    r_exact_dirichlet: f64,
    r_measured: f64,
    power_iterations: usize,
}

#[derive(Debug, Serialize)]
struct Hetero {
    medium: String,
    albedo: f64,
    operator: &'static str,
    r_measured: f64,
    r_gershgorin: f64,
    eq49_min: f64,
    expanded_violations: usize,
}

fn a_of(beta: f64, albedo: f64) -> f64 {
    (1.0 - albedo) / (3.0 * beta)
}

/// μ_max of −L (conservative, uniform β, a) on an n³ Dirichlet grid by power iteration.
fn mu_max(n: usize, beta: f64, a: f64, iterations: usize) -> f64 {
    let m = n - 2; // interior
    let idx = |i: usize, j: usize, k: usize| (k * m + j) * m + i;
    let mut rng = SplitMix64::new(11);
    let mut v: Vec<f64> = (0..m * m * m).map(|_| rng.next_f64() - 0.5).collect();
    let mut mu = 0.0;
    for _ in 0..iterations {
        let mut w = vec![0.0; v.len()];
        for k in 0..m {
            for j in 0..m {
                for i in 0..m {
                    let p = v[idx(i, j, k)];
                    let at = |ii: isize, jj: isize, kk: isize| {
                        if ii < 0
                            || jj < 0
                            || kk < 0
                            || ii >= m as isize
                            || jj >= m as isize
                            || kk >= m as isize
                        {
                            0.0
                        } else {
                            v[idx(ii as usize, jj as usize, kk as usize)]
                        }
                    };
                    let (i, j, k) = (i as isize, j as isize, k as isize);
                    let s = at(i - 1, j, k)
                        + at(i + 1, j, k)
                        + at(i, j - 1, k)
                        + at(i, j + 1, k)
                        + at(i, j, k - 1)
                        + at(i, j, k + 1);
                    w[idx(i as usize, j as usize, k as usize)] = (a + 6.0 * beta) * p - beta * s;
                }
            }
        }
        let norm = w.iter().map(|x| x * x).sum::<f64>().sqrt();
        mu = norm / v.iter().map(|x| x * x).sum::<f64>().sqrt();
        v = w.into_iter().map(|x| x / norm).collect();
    }
    mu
}

/// ‖φ_K‖/‖φ_{K/2}‖ of the FTCS at r from a random start (no source).
fn growth(coef: &Coefficients, op: Operator, r: f64, steps: usize) -> Result<f64> {
    let cfg = RdeConfig::default()
        .with_operator(op)
        .with_time_step(TimeStep::Fixed(r))
        .with_check(StepCheck::Unchecked)
        .frames(steps, steps / 2);
    let s = CpuRde::<f64>::new(coef, &cfg)?.run();
    let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    let snaps = &s.trace.snapshots;
    let (a, b) = (norm(&snaps[0].1), norm(&snaps[snaps.len() - 1].1));
    Ok(if a.is_finite() && b.is_finite() {
        b / a
    } else {
        f64::INFINITY
    })
}

/// The largest r at which ‖φ‖ does not grow (bisection on [lo, hi]); 0 if it grows at lo.
fn critical_r(coef: &Coefficients, op: Operator, steps: usize, bisections: usize) -> Result<f64> {
    let (mut lo, mut hi) = (1e-3, 1.0);
    if growth(coef, op, lo, steps)? > 1.0 {
        return Ok(0.0);
    }
    for _ in 0..bisections {
        let mid = (lo * hi).sqrt();
        if growth(coef, op, mid, steps)? > 1.0 {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    Ok(lo)
}

fn hetero_media(n: usize, albedo: f64) -> Result<Vec<(String, Coefficients)>> {
    let grid = Grid::new([n; 3], 1.0)?;
    let len = grid.len();
    let with_a = |beta: Vec<f64>| -> Result<Coefficients> {
        let ka = beta.iter().map(|&b| a_of(b, albedo)).collect();
        let mut rng = SplitMix64::new(3);
        let init: Vec<f64> = (0..len)
            .map(|idx| {
                let [i, j, k] = grid.coords(idx);
                if grid.is_boundary(i, j, k) {
                    0.0
                } else {
                    rng.next_f64() - 0.5
                }
            })
            .collect();
        Ok(Coefficients::from_maps(grid, beta, ka, vec![0.0; len])?.with_initial(init))
    };
    let step = (0..len)
        .map(|idx| {
            if grid.coords(idx)[0] < n / 2 {
                1.0
            } else {
                0.01
            }
        })
        .collect();
    let mut rng = SplitMix64::new(1);
    let random = (0..len).map(|_| 0.01 + 0.99 * rng.next_f64()).collect();
    let tube = Phantom::tube(n, (n as f64 / 4.0).max(1.5))?.gradient_beta(
        Conductance::Exponential,
        0.1,
        1e-3,
    );
    Ok(vec![
        ("step β 1 : 0.01".to_string(), with_a(step)?),
        ("random β ~ U[0.01, 1]".to_string(), with_a(random)?),
        ("tube, gradient mapping σ = 0.1".to_string(), with_a(tube)?),
    ])
}

fn run_in(ctx: &mut Ctx, _args: &Args) -> Result<()> {
    let quick = ctx.quick();
    let grid_pts = if quick { 12 } else { 60 };
    let (n_uniform, power) = if quick { (10, 300) } else { (16, 1500) };
    let betas_m: Vec<f64> = if quick {
        vec![1.0 / 6.0, 1.0]
    } else {
        vec![0.05, 1.0 / 6.0, 0.5, 1.0]
    };
    let albedos_m: Vec<f64> = if quick {
        vec![0.0, 0.99]
    } else {
        vec![0.0, 0.9, 0.99]
    };
    let (n_het, steps, bis) = if quick { (8, 600, 6) } else { (10, 3000, 12) };
    let het_albedos = [0.0, 0.99, 1.0];
    let mut work = Estimate::new();
    let m3 = ((n_uniform - 2) as f64).powi(3);
    work.add(
        "uniform power iterations",
        (betas_m.len() * albedos_m.len()) as f64 * power as f64 * m3 * 8.0,
    );
    work.add(
        "heterogeneous bisections",
        (3 * 3 * het_albedos.len()) as f64
            * (bis + 1) as f64
            * steps as f64
            * (n_het as f64).powi(3),
    );
    ctx.work(&work)?;
    ctx.start(serde_json::json!({
        "grid_points": grid_pts, "n_uniform": n_uniform, "power_iterations": power,
        "n_heterogeneous": n_het, "growth_steps": steps, "bisections": bis,
    }))?;

    // The (β, α) square.
    let mut region = Vec::new();
    for ib in 0..grid_pts {
        let beta = (ib as f64 + 0.5) / grid_pts as f64;
        for ia in 0..grid_pts {
            let albedo = ia as f64 / (grid_pts - 1) as f64;
            let a = a_of(beta, albedo);
            let (eq49, r_pos, r_vn) = (
                eq_4_9_printed(beta, albedo),
                1.0 / (a + 6.0 * beta),
                2.0 / (a + 12.0 * beta),
            );
            region.push(Region {
                beta,
                albedo,
                eq49,
                r_pos,
                r_vn,
                r01_eq49: eq49 >= 0.1,
                r01_pos: r_pos >= 0.1,
                r01_vn: r_vn >= 0.1,
            });
        }
    }
    ctx.csv("region.csv", &region)?;
    let frac = |f: fn(&Region) -> bool| {
        region.iter().filter(|r| f(r)).count() as f64 / region.len() as f64
    };
    ctx.record(
        "r01_admissible_fraction",
        serde_json::json!({
            "eq49": frac(|r| r.r01_eq49), "positivity": frac(|r| r.r01_pos), "von_neumann": frac(|r| r.r01_vn)
        }),
    );

    // Uniform, measured.
    let mut measured = Vec::new();
    let pb = ctx.progress((betas_m.len() * albedos_m.len()) as u64, "uniform r_crit");
    for &beta in &betas_m {
        for &albedo in &albedos_m {
            let a = a_of(beta, albedo);
            let mu = mu_max(n_uniform, beta, a, power);
            let c = (std::f64::consts::PI / (2.0 * (n_uniform - 1) as f64)).cos();
            measured.push(Measured {
                beta,
                albedo,
                n: n_uniform,
                eq49: eq_4_9_printed(beta, albedo),
                r_pos: 1.0 / (a + 6.0 * beta),
                r_vn: 2.0 / (a + 12.0 * beta),
                r_exact_dirichlet: 2.0 / (a + 12.0 * beta * c * c),
                r_measured: 2.0 / mu,
                power_iterations: power,
            });
            pb.inc(1);
        }
    }
    pb.finish_and_clear();
    ctx.csv("uniform.csv", &measured)?;

    // Heterogeneous, measured by the FTCS itself.
    let mut hetero = Vec::new();
    let pb = ctx.progress((3 * 3 * het_albedos.len()) as u64, "heterogeneous r_crit");
    for &albedo in &het_albedos {
        for (name, coef) in hetero_media(n_het, albedo)? {
            let bounds = coef.bounds(solvers::rde::BoundaryCondition::Dirichlet);
            for op in Operator::ALL {
                let r = critical_r(&coef, op, steps, bis)
                    .with_context(|| format!("{name}, α = {albedo}, {}", op.name()))?;
                hetero.push(Hetero {
                    medium: name.clone(),
                    albedo,
                    operator: op.name(),
                    r_measured: r,
                    r_gershgorin: bounds.gershgorin,
                    eq49_min: bounds.eq49,
                    expanded_violations: coef
                        .expanded_violations(solvers::rde::BoundaryCondition::Dirichlet),
                });
                pb.inc(1);
            }
        }
    }
    pb.finish_and_clear();
    ctx.csv("heterogeneous.csv", &hetero)?;

    // Fig 4.1 as curves over β at α = 0 and 0.99.
    let mut series = Vec::new();
    for (c, &albedo) in [0.0, 0.99].iter().enumerate() {
        let pts = |f: &dyn Fn(f64) -> f64| -> Vec<(f64, f64)> {
            (1..=200)
                .map(|i| {
                    let b = i as f64 / 200.0;
                    (b, f(b))
                })
                .collect()
        };
        series.push(Series::new(
            format!("Eq 4.9, α = {albedo}"),
            pts(&|b| eq_4_9_printed(b, albedo)),
            Style::Line,
            3 * c,
        ));
        series.push(Series::new(
            format!("von Neumann, α = {albedo}"),
            pts(&|b| 2.0 / (a_of(b, albedo) + 12.0 * b)),
            Style::Dashed,
            3 * c + 1,
        ));
        series.push(Series::new(
            format!("positivity, α = {albedo}"),
            pts(&|b| 1.0 / (a_of(b, albedo) + 6.0 * b)),
            Style::Dashed,
            3 * c + 2,
        ));
        let m: Vec<(f64, f64)> = measured
            .iter()
            .filter(|m| m.albedo == albedo)
            .map(|m| (m.beta, m.r_measured))
            .collect();
        if !m.is_empty() {
            series.push(Series::new(
                format!("measured r_crit ({n_uniform}³), α = {albedo}"),
                m,
                Style::Points,
                3 * c + 1,
            ));
        }
    }
    series.push(Series::new(
        "r = 0.1 (thesis)",
        vec![(0.005, 0.1), (1.0, 0.1)],
        Style::Line,
        6,
    ));
    plot(
        &ctx.path("fig4_1.png"),
        "Thesis Fig 4.1: stability bounds on r = c∆t/∆ (uniform media)",
        &Axis::log("β = D/∆"),
        &Axis::log("r").range(0.01, 10.0),
        &series,
    )?;
    Ok(())
}

/// Thesis Fig 4.1 in the registry.
#[derive(Debug)]
pub struct RdeStability;

impl Experiment for RdeStability {
    const NAME: &'static str = "rde_stability";
    const TITLE: &'static str =
        "Thesis Fig 4.1: Eq 4.9 vs the von Neumann, positivity and measured critical r";
    const BACKEND: BackendSupport = BackendSupport::CpuOnly("small f64 eigen/growth studies");
    type Args = Args;
    type Summary = ();

    fn common(args: &Args) -> &CommonArgs {
        &args.common
    }

    fn promises(_args: &Args) -> Vec<Promise> {
        vec![
            Promise::csv(
                "region.csv",
                &[
                    "beta", "albedo", "eq49", "r_pos", "r_vn", "r01_eq49", "r01_pos", "r01_vn",
                ],
            ),
            Promise::csv(
                "uniform.csv",
                &[
                    "beta",
                    "albedo",
                    "eq49",
                    "r_vn",
                    "r_exact_dirichlet",
                    "r_measured",
                ],
            ),
            Promise::csv(
                "heterogeneous.csv",
                &[
                    "medium",
                    "albedo",
                    "operator",
                    "r_measured",
                    "r_gershgorin",
                    "eq49_min",
                ],
            ),
            Promise::file("fig4_1.png"),
        ]
    }

    fn run(ctx: &mut Ctx, args: &Args) -> Result<()> {
        run_in(ctx, args)
    }

    fn report(s: &Section<'_>) -> Result<String> {
        let region = s.csv("region.csv")?;
        region.require(&["r01_eq49", "r01_pos", "r01_vn"])?;
        let n = region.rows().count().max(1) as f64;
        let share = |c: &str| region.rows().filter(|r| r.flag(c)).count() as f64 / n;
        let mut out = format!(
            "The thesis's r = 0.1 is admissible on {:.0} % of the (β, α) unit square by its own \
             Eq 4.9, on {:.0} % by positivity and {:.0} % by von Neumann (thesis l. 4688 claims \
             \"nearly all\"). Uniform media, measured critical r (power iteration, Dirichlet):\n\n",
            100.0 * share("r01_eq49"),
            100.0 * share("r01_pos"),
            100.0 * share("r01_vn"),
        );
        let u = s.csv("uniform.csv")?;
        out.push_str(&table(
            &[
                "β",
                "α",
                "Eq 4.9",
                "positivity",
                "von Neumann",
                "exact Dirichlet",
                "measured",
            ],
            u.rows().map(|r| {
                vec![
                    r.fixed("beta", 3),
                    r.get("albedo").to_string(),
                    r.fixed("eq49", 3),
                    r.fixed("r_pos", 3),
                    r.fixed("r_vn", 3),
                    r.fixed("r_exact_dirichlet", 3),
                    r.fixed("r_measured", 3),
                ]
            }),
        ));
        out.push_str(
            "\nHeterogeneous media, critical r of the FTCS itself (growth of ‖φ‖; 0 = grows at \
             every r ≥ 10⁻³):\n\n",
        );
        let h = s.csv("heterogeneous.csv")?;
        out.push_str(&table(
            &[
                "medium",
                "α",
                "operator",
                "measured r_crit",
                "r_G",
                "min Eq 4.9",
            ],
            h.rows().map(|r| {
                vec![
                    r.get("medium").to_string(),
                    r.get("albedo").to_string(),
                    r.get("operator").to_string(),
                    fixed(r.num("r_measured"), 4),
                    r.fixed("r_gershgorin", 4),
                    r.fixed("eq49_min", 4),
                ]
            }),
        ));
        out.push('\n');
        out.push_str(&s.png("fig4_1.png"));
        Ok(out)
    }
}
