//! Path-traced point source in an unbounded homogeneous medium (σt = 1, unit power):
//! spherical-shell averages of the radial density 4πr²φ(r) (FLD Section 4.1; 4πr²φ = τ²φ̃
//! with φ̃ of FLD Eq 25), total and collided, with batch-means standard errors, against
//! the analytic curves: the ballistic part e^{−r} (exact for any phase function) and, for
//! isotropic scattering, the exact Case–Zweifel solution
//! ([`reference::transport::point::ExactPointSource`], with z-scores), Grosjean (FLD Eq 24)
//! and the CDA Green's function (FLD Eq 27).
//!
//! Writes `shells.csv` (interface columns `albedo,g,r_inner,r_outer,radial_density,
//! radial_density_stderr,collided,collided_stderr`, then reference columns), `runs.csv`
//! (paths, seconds, paths/s per albedo), and plots.

use crate::common::{CommonArgs, Ctx, list_item, progress};
use crate::experiment::{BackendSupport, Experiment, Promise};
use crate::plot::{Axis, Series, Style, plot};
use crate::report::{Section, table};
use anyhow::{Context, Result, bail};
use reference::effects::PassSums;
use reference::pathtracer::infinite::shells_from;
use reference::pathtracer::{InfiniteMedium, PathSettings};
use reference::point_source::{cda, grosjean};
use reference::quadrature::simpson;
use reference::transport::point::ExactPointSource;
use serde::Serialize;
use solvers::scene::Phase;
use std::time::Instant;

/// Paths per albedo of a full run: 4·10⁷ keeps every shell's relative standard error
/// near 0.1 % (c = 0.3, outer shell, is the largest) — a 3σ band of ±0.3 % around the exact
/// solution, tight enough to see Grosjean's 0.1–3 % bias.
pub const DEFAULT_PATHS: u64 = 40_000_000;

/// Flags of `pt_point_source`.
#[derive(Debug, Clone, clap::Parser)]
#[command(about = "Path-traced point source in an infinite medium: shell tallies of 4πr²φ")]
pub struct Args {
    /// Shared flags.
    #[command(flatten)]
    pub common: CommonArgs,
    /// Single-scattering albedos c ∈ [0, 1), comma-separated.
    #[arg(long, value_delimiter = ',', value_parser = list_item::<f64>, default_value = "0.3,0.7,0.9,0.99")]
    pub albedo: Vec<f64>,
    /// Henyey–Greenstein mean cosine(s) g ∈ (−1, 1), comma-separated (0: isotropic).
    #[arg(long, value_delimiter = ',', value_parser = list_item::<f64>, default_value = "0")]
    pub g: Vec<f64>,
    /// Shell edges r0,r1,…,rk in mean free paths (strictly increasing, r0 ≥ 0).
    #[arg(long, value_delimiter = ',', value_parser = list_item::<f64>, default_value = "0,0.05,0.1,0.2,0.35,0.5,0.75,1,1.5,2,2.5,3,4,5")]
    pub edges: Vec<f64>,
    /// Paths per albedo (default 4e7; 2e5 with --quick).
    #[arg(long, value_parser = crate::common::count)]
    pub paths: Option<u64>,
    /// Seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Batches for the standard errors (≥ 16).
    #[arg(long, default_value_t = 32, value_parser = crate::common::count_u32)]
    pub batches: u32,
}

/// One shell (`shells.csv`).
#[derive(Debug, Clone, Serialize)]
pub struct ShellRow {
    /// Albedo c.
    pub albedo: f64,
    /// HG mean cosine.
    pub g: f64,
    /// Inner radius.
    pub r_inner: f64,
    /// Outer radius.
    pub r_outer: f64,
    /// Shell average of 4πr²φ (total).
    pub radial_density: f64,
    /// Its standard error.
    pub radial_density_stderr: f64,
    /// Shell average of the collided part.
    pub collided: f64,
    /// Its standard error.
    pub collided_stderr: f64,
    /// Shell average of the uncollided part.
    pub uncollided: f64,
    /// Its standard error.
    pub uncollided_stderr: f64,
    /// Exact ballistic shell average (e^{−a} − e^{−b})/Δr.
    pub ballistic: f64,
    /// z-score of `uncollided` against `ballistic`.
    pub z_ballistic: f64,
    /// Exact shell average of 4πr²φ (isotropic only, else empty).
    pub exact: Option<f64>,
    /// Exact shell average of the collided part (isotropic only).
    pub exact_collided: Option<f64>,
    /// (radial_density − exact)/radial_density_stderr (isotropic only).
    pub z: Option<f64>,
    /// (collided − exact_collided)/collided_stderr (isotropic only).
    pub z_collided: Option<f64>,
    /// Grosjean's shell average (FLD Eq 24; isotropic only, else empty).
    pub grosjean: Option<f64>,
    /// CDA shell average (FLD Eq 27; isotropic only, else empty).
    pub cda: Option<f64>,
    /// radial_density_stderr / radial_density.
    pub rel_stderr: f64,
}

/// One albedo's run (`runs.csv`).
#[derive(Debug, Clone, Serialize)]
pub struct RunRow {
    /// Albedo.
    pub albedo: f64,
    /// HG mean cosine.
    pub g: f64,
    /// Paths traced.
    pub paths: u64,
    /// Wall seconds.
    pub seconds: f64,
    /// Paths per second.
    pub paths_per_second: f64,
    /// Largest relative standard error over the shells.
    pub max_rel_stderr: f64,
    /// Largest |z| against the exact solution over total and collided shells (isotropic
    /// only).
    pub max_abs_z: Option<f64>,
}

/// Shell average (1/Δr)∫ f dr by Simpson's rule (f bounded on the shell).
fn shell_average(f: impl Fn(f64) -> f64, a: f64, b: f64) -> f64 {
    simpson(f, a, b, 2000) / (b - a)
}

/// Runs the experiment; returns the shell rows.
pub fn run(args: &Args) -> Result<Vec<ShellRow>> {
    crate::experiment::run::<PtPointSource>(args)
}

fn run_in(ctx: &mut Ctx, args: &Args) -> Result<Vec<ShellRow>> {
    let albedos: Vec<f64> = args.albedo.clone();
    if albedos.is_empty() {
        bail!("--albedo: no values given");
    }
    if let Some(a) = albedos.iter().find(|a| !(0.0..1.0).contains(*a)) {
        bail!("--albedo: {a} is outside [0, 1)");
    }
    let gs: Vec<f64> = args.g.clone();
    if let Some(g) = gs.iter().find(|g| g.is_nan() || g.abs() >= 1.0) {
        bail!("--g: {g} is outside (-1, 1)");
    }
    let edges: Vec<f64> = args.edges.clone();
    let paths = args.paths.unwrap_or(if args.common.quick {
        200_000
    } else {
        DEFAULT_PATHS
    });
    let mut work = crate::cost::Estimate::new();
    for &c in &albedos {
        work.add(
            format!(
                "--albedo {c}: {paths} paths × {:.3e} collisions × {} g values",
                crate::cost::infinite_events(c),
                gs.len()
            ),
            paths as f64 * crate::cost::infinite_events(c) * gs.len() as f64,
        );
    }
    ctx.work(&work)?;
    ctx.start(serde_json::json!({
        "albedo": albedos, "g": gs, "edges": edges, "paths": paths,
        "seed": args.seed, "batches": args.batches, "sigma_t": 1.0, "source_power": 1.0,
    }))?;
    let out = ctx;
    let settings = PathSettings {
        paths,
        seed: args.seed,
        batches: args.batches,
        max_depth: None,
    };
    let mut rows = Vec::new();
    let mut runs = Vec::new();
    let pb = progress(
        (albedos.len() * gs.len()) as u64,
        &args.common,
        "pt_point_source",
    );
    for &g in &gs {
        let phase = if g == 0.0 {
            Phase::Isotropic
        } else {
            Phase::HenyeyGreenstein { g }
        };
        for &c in &albedos {
            pb.set_message(format!("c={c} g={g}"));
            let medium = InfiniteMedium::new(c, phase)?;
            let what = format!("shell tallies for c = {c}, g = {g}");
            let tallied = out.tally(
                &what,
                |shard| {
                    let t0 = Instant::now();
                    let sums = medium
                        .shells_part(&edges, &settings, shard)
                        .with_context(|| what.clone())?;
                    Ok(vec![PassSums {
                        sums,
                        seconds: t0.elapsed().as_secs_f64(),
                    }])
                },
                |parts| Ok((shells_from(&edges, &parts[0].sums)?, parts[0].seconds)),
            )?;
            let Some((shells, seconds)) = tallied else {
                pb.inc(1);
                continue;
            };
            out.timing(format!("c={c} g={g}"), seconds);
            let exact = if g == 0.0 {
                Some(ExactPointSource::new(c)?)
            } else {
                None
            };
            let mut max_rel: f64 = 0.0;
            let mut max_z: Option<f64> = None;
            for s in &shells {
                let (a, b) = (s.r_inner, s.r_outer);
                let ballistic = ((-a).exp() - (-b).exp()) / (b - a);
                let iso = g == 0.0;
                let rel = s.radial_density.relative_stderr();
                max_rel = max_rel.max(rel);
                let ex = exact.as_ref().map(|e| e.shell_average(a, b));
                let z = ex.map(|(t, _)| s.radial_density.z(t));
                let zc = ex.map(|(_, col)| s.collided.z(col));
                if let (Some(z), Some(zc)) = (z, zc) {
                    max_z = Some(max_z.unwrap_or(0.0).max(z.abs()).max(zc.abs()));
                }
                rows.push(ShellRow {
                    albedo: c,
                    g,
                    r_inner: a,
                    r_outer: b,
                    radial_density: s.radial_density.mean,
                    radial_density_stderr: s.radial_density.stderr,
                    collided: s.collided.mean,
                    collided_stderr: s.collided.stderr,
                    uncollided: s.uncollided.mean,
                    uncollided_stderr: s.uncollided.stderr,
                    ballistic,
                    z_ballistic: s.uncollided.z(ballistic),
                    exact: ex.map(|e| e.0),
                    exact_collided: ex.map(|e| e.1),
                    z,
                    z_collided: zc,
                    grosjean: iso.then(|| shell_average(|r| r * r * grosjean(r, c), a, b)),
                    cda: iso.then(|| shell_average(|r| r * r * cda(r, c), a, b)),
                    rel_stderr: rel,
                });
            }
            runs.push(RunRow {
                albedo: c,
                g,
                paths,
                seconds,
                paths_per_second: paths as f64 / seconds,
                max_rel_stderr: max_rel,
                max_abs_z: max_z,
            });
            pb.inc(1);
        }
    }
    pb.finish_and_clear();
    if out.sharding() {
        return Ok(rows);
    }
    out.csv("shells.csv", &rows)?;
    out.csv("runs.csv", &runs)?;
    plots(out, &albedos, &gs, &rows)?;
    Ok(rows)
}

fn plots(out: &Ctx, albedos: &[f64], gs: &[f64], rows: &[ShellRow]) -> Result<()> {
    for &g in gs {
        // Curves first (exact solid, Grosjean dashed, both in the albedo's colour; CDA grey),
        // then the Monte Carlo shell averages on top.
        let mut series = Vec::new();
        let mut points = Vec::new();
        for (k, &c) in albedos.iter().enumerate() {
            let sel: Vec<&ShellRow> = rows.iter().filter(|r| r.albedo == c && r.g == g).collect();
            let mid = |r: &ShellRow| 0.5 * (r.r_inner + r.r_outer);
            points.push(Series::new(
                format!("MC c = {c}"),
                sel.iter().map(|r| (mid(r), r.radial_density)).collect(),
                Style::Points,
                k,
            ));
            if g == 0.0 {
                let (lo, hi) = (
                    sel.first().map_or(0.0, |r| r.r_inner).max(1e-3),
                    sel.last().map_or(1.0, |r| r.r_outer),
                );
                let rs: Vec<f64> = (0..200)
                    .map(|i| lo + (hi - lo) * i as f64 / 199.0)
                    .collect();
                let label = |s: &str| if k == 0 { s.to_string() } else { String::new() };
                let exact = ExactPointSource::new(c)?;
                series.push(Series::new(
                    label("exact transport (solid)"),
                    rs.iter().map(|&r| (r, exact.radial_density(r))).collect(),
                    Style::Line,
                    k,
                ));
                series.push(Series::new(
                    label("Grosjean, FLD Eq 24 (dashed)"),
                    rs.iter().map(|&r| (r, r * r * grosjean(r, c))).collect(),
                    Style::Dashed,
                    k,
                ));
                series.push(Series::new(
                    label("CDA, FLD Eq 27 (grey)"),
                    rs.iter().map(|&r| (r, r * r * cda(r, c))).collect(),
                    Style::Line,
                    7,
                ));
            }
        }
        series.extend(points);
        plot(
            &out.path(&format!("radial_density_g{g}.png")),
            &format!("Point source, σt = 1, g = {g}: shell averages of 4πr²φ"),
            &Axis::lin("r (mean free paths)"),
            &Axis::log("4πr²φ (shell average)").range(0.01, 20.0),
            &series,
        )?;
        // One series per albedo of a z-score column against the shell's mid radius.
        let z_series = |z_of: &dyn Fn(&ShellRow) -> Option<f64>| -> Vec<Series> {
            albedos
                .iter()
                .enumerate()
                .map(|(k, &c)| {
                    Series::new(
                        format!("c = {c}"),
                        rows.iter()
                            .filter(|r| r.albedo == c && r.g == g)
                            .filter_map(|r| z_of(r).map(|z| (0.5 * (r.r_inner + r.r_outer), z)))
                            .collect(),
                        Style::Points,
                        k,
                    )
                })
                .collect()
        };
        let z = z_series(&|r| Some(r.z_ballistic));
        if g == 0.0 {
            let z = z_series(&|r| r.z);
            plot(
                &out.path("z_exact.png"),
                "MC shell averages vs the exact solution: z-scores (total)",
                &Axis::lin("r (mean free paths)"),
                &Axis::lin("z").range(-5.0, 5.0),
                &z,
            )?;
        }
        plot(
            &out.path(&format!("z_ballistic_g{g}.png")),
            &format!("Uncollided part vs exact e^(−r), g = {g}: z-scores"),
            &Axis::lin("r (mean free paths)"),
            &Axis::lin("z").range(-5.0, 5.0),
            &z,
        )?;
    }
    Ok(())
}

/// The path tracer's point-source check in the registry.
#[derive(Debug)]
pub struct PtPointSource;

impl Experiment for PtPointSource {
    const NAME: &'static str = "pt_point_source";
    const TITLE: &'static str = "Path tracer: point-source shells vs exact";
    const BACKEND: BackendSupport = BackendSupport::CpuOnly("the path tracer runs on the CPU");
    const SHARDS: bool = true;
    type Args = Args;
    type Summary = Vec<ShellRow>;

    fn common(args: &Args) -> &CommonArgs {
        &args.common
    }

    fn promises(args: &Args) -> Vec<Promise> {
        let mut p = vec![
            Promise::csv(
                "shells.csv",
                &[
                    "albedo",
                    "g",
                    "r_inner",
                    "r_outer",
                    "radial_density",
                    "radial_density_stderr",
                    "collided",
                    "collided_stderr",
                    "uncollided",
                    "uncollided_stderr",
                    "ballistic",
                    "z_ballistic",
                    "exact",
                    "exact_collided",
                    "z",
                    "z_collided",
                    "grosjean",
                    "cda",
                    "rel_stderr",
                ],
            ),
            Promise::csv(
                "runs.csv",
                &[
                    "albedo",
                    "g",
                    "paths",
                    "seconds",
                    "paths_per_second",
                    "max_rel_stderr",
                    "max_abs_z",
                ],
            ),
        ];
        for g in &args.g {
            p.push(Promise::file(format!("radial_density_g{g}.png")));
            p.push(Promise::file(format!("z_ballistic_g{g}.png")));
        }
        if args.g.contains(&0.0) {
            p.push(Promise::file("z_exact.png"));
        }
        p
    }

    fn run(ctx: &mut Ctx, args: &Args) -> Result<Self::Summary> {
        run_in(ctx, args)
    }

    fn report(s: &Section<'_>) -> Result<String> {
        let t = s.csv("runs.csv")?;
        t.require(&[
            "albedo",
            "g",
            "paths",
            "paths_per_second",
            "max_rel_stderr",
            "max_abs_z",
        ])?;
        let mut out = String::from(
            "Average of 4πr²φ over each spherical shell, with batch-means standard errors, against the exact \
             solution (z-scores in `shells.csv`). Per run:\n\n",
        );
        let rows = t.rows().map(|r| {
            vec![
                r.get("albedo").to_string(),
                r.get("g").to_string(),
                r.get("paths").to_string(),
                r.sci("paths_per_second", 2),
                r.fixed("max_rel_stderr", 4),
                if r.get("max_abs_z").is_empty() {
                    "—".into()
                } else {
                    r.fixed("max_abs_z", 2)
                },
            ]
        });
        out.push_str(&table(
            &[
                "albedo",
                "g",
                "paths",
                "paths/s",
                "largest relative std. error",
                "largest |z| vs exact",
            ],
            rows,
        ));
        out.push('\n');
        out.push_str(&s.png("z_exact.png"));
        Ok(out)
    }
}
