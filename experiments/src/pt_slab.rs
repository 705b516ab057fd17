//! Path-traced plane-parallel slab (σt = 1, optical thickness τ, finite or semi-infinite),
//! albedo c, isotropic or Henyey–Greenstein scattering, collimated incidence at cosine μ0:
//! reflectance R, diffuse transmittance T_d (with batch-means standard errors), direct
//! transmittance T_dir = e^{−τ/μ0}, absorptance A and the energy balance R + T_d + T_dir + A
//! (FLD Section 6.2 validates its path tracer on Chandrasekhar's slab solution).
//!
//! References: the adding–doubling solver ([`reference::transport::slab::Slab`]) for every
//! case, and Chandrasekhar's plane albedo 1 − √(1 − c)H(μ0)
//! ([`reference::transport::hfunction::plane_albedo`]) for isotropic half-spaces.
//!
//! Writes `slab.csv` (interface columns `tau,albedo,g,mu0,R,R_stderr,T_diffuse,
//! T_diffuse_stderr,T_direct`, then `A`, the balance, the references with z-scores, and
//! timings) and a plot of R and T_d.

use crate::common::{CommonArgs, Ctx, list_item, progress};
use crate::experiment::{BackendSupport, Experiment, Promise};
use crate::plot::{Axis, Series, Style, plot};
use crate::report::{Section, table};
use anyhow::{Context, Result, bail};
use reference::effects::PassSums;
use reference::pathtracer::{PathSettings, SlabMedium};
use reference::transport::hfunction::plane_albedo;
use reference::transport::slab::Slab;
use serde::Serialize;
use solvers::scene::Phase;
use std::time::Instant;

/// Flags of `pt_slab`.
#[derive(Debug, Clone, clap::Parser)]
#[command(about = "Path-traced slab: reflectance and transmittance under collimated incidence")]
pub struct Args {
    /// Shared flags.
    #[command(flatten)]
    pub common: CommonArgs,
    /// Optical thicknesses τ (`inf` for a semi-infinite medium), comma-separated.
    #[arg(long, value_delimiter = ',', value_parser = list_item::<f64>, default_value = "1,inf")]
    pub tau: Vec<f64>,
    /// Albedos c, comma-separated (c < 1 when τ = inf).
    #[arg(long, value_delimiter = ',', value_parser = list_item::<f64>, default_value = "0.5,0.9,0.99")]
    pub albedo: Vec<f64>,
    /// Henyey–Greenstein mean cosines (0: isotropic), comma-separated.
    #[arg(long, value_delimiter = ',', value_parser = list_item::<f64>, default_value = "0,0.5,0.9")]
    pub g: Vec<f64>,
    /// Incidence cosines μ0 ∈ (0, 1], comma-separated.
    #[arg(long, value_delimiter = ',', value_parser = list_item::<f64>, default_value = "1,0.5")]
    pub mu0: Vec<f64>,
    /// Paths per case (default 4e6; 1e5 with --quick).
    #[arg(long, value_parser = crate::common::count)]
    pub paths: Option<u64>,
    /// Seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Batches for the standard errors (≥ 16).
    #[arg(long, default_value_t = 32, value_parser = crate::common::count_u32)]
    pub batches: u32,
}

/// One case (`slab.csv`).
#[derive(Debug, Clone, Serialize)]
pub struct SlabRow {
    /// Optical thickness (inf for semi-infinite).
    pub tau: f64,
    /// Albedo.
    pub albedo: f64,
    /// HG mean cosine.
    pub g: f64,
    /// Incidence cosine.
    pub mu0: f64,
    /// Reflectance.
    #[serde(rename = "R")]
    pub r: f64,
    /// Its standard error.
    #[serde(rename = "R_stderr")]
    pub r_stderr: f64,
    /// Diffuse transmittance.
    #[serde(rename = "T_diffuse")]
    pub t_diffuse: f64,
    /// Its standard error.
    #[serde(rename = "T_diffuse_stderr")]
    pub t_diffuse_stderr: f64,
    /// Direct transmittance e^{−τ/μ0} (exact).
    #[serde(rename = "T_direct")]
    pub t_direct: f64,
    /// Absorptance.
    #[serde(rename = "A")]
    pub a: f64,
    /// Its standard error.
    #[serde(rename = "A_stderr")]
    pub a_stderr: f64,
    /// R + T_d + T_dir + A (1 up to noise).
    pub balance: f64,
    /// Its standard error.
    pub balance_stderr: f64,
    /// Reflectance of the adding–doubling solver.
    #[serde(rename = "R_ref")]
    pub r_ref: f64,
    /// Diffuse transmittance of the adding–doubling solver.
    #[serde(rename = "T_diffuse_ref")]
    pub t_diffuse_ref: f64,
    /// (R − R_ref)/R_stderr.
    pub z_r: f64,
    /// (T_diffuse − T_diffuse_ref)/T_diffuse_stderr (0 for a half-space).
    pub z_t: f64,
    /// Plane albedo from the H-function (isotropic half-spaces only, else empty).
    #[serde(rename = "R_hfunction")]
    pub r_hfunction: Option<f64>,
    /// Paths traced.
    pub paths: u64,
    /// Wall seconds.
    pub seconds: f64,
}

/// Runs the experiment; returns the rows.
pub fn run(args: &Args) -> Result<Vec<SlabRow>> {
    crate::experiment::run::<PtSlab>(args)
}

fn run_in(ctx: &mut Ctx, args: &Args) -> Result<Vec<SlabRow>> {
    let taus: Vec<f64> = args.tau.clone();
    let albedos: Vec<f64> = args.albedo.clone();
    let gs: Vec<f64> = args.g.clone();
    let mu0s: Vec<f64> = args.mu0.clone();
    for (flag, v) in [
        ("tau", &taus),
        ("albedo", &albedos),
        ("g", &gs),
        ("mu0", &mu0s),
    ] {
        if v.is_empty() {
            bail!("--{flag}: no values given");
        }
    }
    if let Some(g) = gs.iter().find(|g| g.is_nan() || g.abs() >= 1.0) {
        bail!("--g: {g} is outside (-1, 1)");
    }
    let paths = args.paths.unwrap_or(if args.common.quick {
        100_000
    } else {
        4_000_000
    });
    if let Some(c) = albedos.iter().find(|c| !(0.0..=1.0).contains(*c)) {
        bail!("--albedo: {c} is outside [0, 1]");
    }
    if taus.iter().any(|t| t.is_infinite()) && albedos.iter().any(|&c| c >= 1.0) {
        bail!(
            "--tau inf with --albedo 1: in a conservative half-space a path's expected number \
             of collisions is infinite (no path is absorbed), so the run would never finish; \
             use c < 1 with τ = inf, or a finite τ"
        );
    }
    let mut work = crate::cost::Estimate::new();
    let per_case = (gs.len() * mu0s.len()) as f64;
    for &tau in &taus {
        for &c in &albedos {
            let events = crate::cost::slab_events(tau, c);
            work.add(
                format!("--tau {tau} --albedo {c}: {paths} paths × {events:.3e} events"),
                paths as f64 * events * per_case,
            );
        }
    }
    ctx.work(&work)?;
    ctx.start(serde_json::json!({
        "tau": taus.iter().map(|t| t.to_string()).collect::<Vec<_>>(),
        "albedo": albedos, "g": gs, "mu0": mu0s, "paths": paths,
        "seed": args.seed, "batches": args.batches,
    }))?;
    let out = ctx;
    let settings = PathSettings {
        paths,
        seed: args.seed,
        batches: args.batches,
        max_depth: None,
    };
    let mut rows = Vec::new();
    let n = (taus.len() * albedos.len() * gs.len() * mu0s.len()) as u64;
    let pb = progress(n, &args.common, "pt_slab");
    for &tau in &taus {
        for &g in &gs {
            let phase = if g == 0.0 {
                Phase::Isotropic
            } else {
                Phase::HenyeyGreenstein { g }
            };
            for &c in &albedos {
                let slab = SlabMedium::new(tau, c, phase)
                    .with_context(|| format!("slab τ = {tau}, c = {c}, g = {g}"))?;
                for &mu0 in &mu0s {
                    pb.set_message(format!("τ={tau} c={c} g={g} μ0={mu0}"));
                    let what = format!("slab τ = {tau}, c = {c}, g = {g}, μ0 = {mu0}");
                    let tallied = out.tally(
                        &what,
                        |shard| {
                            let t0 = Instant::now();
                            let sums = slab
                                .simulate_part(mu0, &settings, shard)
                                .with_context(|| what.clone())?;
                            Ok(vec![PassSums {
                                sums,
                                seconds: t0.elapsed().as_secs_f64(),
                            }])
                        },
                        |parts| Ok((slab.tally(mu0, &parts[0].sums)?, parts[0].seconds)),
                    )?;
                    pb.inc(1);
                    let Some((t, seconds)) = tallied else {
                        continue;
                    };
                    let exact = Slab::new(tau, c, g)?.solve(mu0).with_context(|| {
                        format!("adding–doubling for τ = {tau}, c = {c}, g = {g}")
                    })?;
                    let r_hfunction = if tau.is_infinite() && g == 0.0 {
                        Some(plane_albedo(c, mu0)?)
                    } else {
                        None
                    };
                    out.timing(format!("tau={tau} c={c} g={g} mu0={mu0}"), seconds);
                    rows.push(SlabRow {
                        tau,
                        albedo: c,
                        g,
                        mu0,
                        r: t.reflectance.mean,
                        r_stderr: t.reflectance.stderr,
                        t_diffuse: t.transmittance_diffuse.mean,
                        t_diffuse_stderr: t.transmittance_diffuse.stderr,
                        t_direct: t.transmittance_direct,
                        a: t.absorptance.mean,
                        a_stderr: t.absorptance.stderr,
                        balance: t.balance.mean,
                        balance_stderr: t.balance.stderr,
                        r_ref: exact.reflectance,
                        t_diffuse_ref: exact.transmittance_diffuse,
                        z_r: t.reflectance.z(exact.reflectance),
                        z_t: t.transmittance_diffuse.z(exact.transmittance_diffuse),
                        r_hfunction,
                        paths,
                        seconds,
                    });
                }
            }
        }
    }
    pb.finish_and_clear();
    if out.sharding() {
        return Ok(rows);
    }
    out.csv("slab.csv", &rows)?;
    // R and T_d against albedo at the first μ0, one colour per (τ, g).
    let mu0 = mu0s[0];
    let mut series = Vec::new();
    for (k, &tau) in taus.iter().enumerate() {
        for (j, &g) in gs.iter().enumerate() {
            let sel = |f: &dyn Fn(&SlabRow) -> f64| -> Vec<(f64, f64)> {
                rows.iter()
                    .filter(|r| r.tau == tau && r.g == g && r.mu0 == mu0)
                    .map(|r| (r.albedo, f(r)))
                    .collect()
            };
            let color = k * gs.len() + j;
            series.push(Series::new(
                format!("R, τ={tau}, g={g}"),
                sel(&|r| r.r),
                Style::Points,
                color,
            ));
            series.push(Series::new(
                String::new(),
                sel(&|r| r.r_ref),
                Style::Line,
                color,
            ));
            if tau.is_finite() {
                series.push(Series::new(
                    format!("T_d, τ={tau}, g={g}"),
                    sel(&|r| r.t_diffuse),
                    Style::Points,
                    color,
                ));
                series.push(Series::new(
                    String::new(),
                    sel(&|r| r.t_diffuse_ref),
                    Style::Dashed,
                    color,
                ));
            }
        }
    }
    plot(
        &out.path("slab.png"),
        &format!(
            "Slab reflectance and diffuse transmittance, μ0 = {}",
            mu0s[0]
        ),
        &Axis::lin("albedo c"),
        &Axis::lin("fraction of incident power"),
        &series,
    )?;
    Ok(rows)
}

/// The path tracer's slab check in the registry.
#[derive(Debug)]
pub struct PtSlab;

impl Experiment for PtSlab {
    const NAME: &'static str = "pt_slab";
    const TITLE: &'static str = "Path tracer: slabs vs adding–doubling and H";
    const BACKEND: BackendSupport = BackendSupport::CpuOnly("the path tracer runs on the CPU");
    const SHARDS: bool = true;
    type Args = Args;
    type Summary = Vec<SlabRow>;

    fn common(args: &Args) -> &CommonArgs {
        &args.common
    }

    fn promises(_args: &Args) -> Vec<Promise> {
        vec![
            Promise::csv(
                "slab.csv",
                &[
                    "tau",
                    "albedo",
                    "g",
                    "mu0",
                    "R",
                    "R_stderr",
                    "T_diffuse",
                    "T_diffuse_stderr",
                    "T_direct",
                    "A",
                    "A_stderr",
                    "balance",
                    "balance_stderr",
                    "R_ref",
                    "T_diffuse_ref",
                    "z_r",
                    "z_t",
                    "R_hfunction",
                    "paths",
                    "seconds",
                ],
            ),
            Promise::file("slab.png"),
        ]
    }

    fn run(ctx: &mut Ctx, args: &Args) -> Result<Self::Summary> {
        run_in(ctx, args)
    }

    fn report(s: &Section<'_>) -> Result<String> {
        let t = s.csv("slab.csv")?;
        t.require(&[
            "tau",
            "albedo",
            "g",
            "mu0",
            "R",
            "R_stderr",
            "R_ref",
            "z_r",
            "T_diffuse",
            "T_diffuse_stderr",
            "T_diffuse_ref",
            "z_t",
        ])?;
        let mut out = String::from(
            "Diffuse reflectance R and transmittance T of slabs lit at cosine μ₀, against the adding–doubling solver \
             (z = (MC − reference)/standard error):\n\n",
        );
        let rows = t.rows().map(|r| {
            vec![
                r.get("tau").to_string(),
                r.get("albedo").to_string(),
                r.get("g").to_string(),
                r.get("mu0").to_string(),
                format!("{} ± {}", r.fixed("R", 4), r.fixed("R_stderr", 4)),
                r.fixed("R_ref", 4),
                r.fixed("z_r", 2),
                format!(
                    "{} ± {}",
                    r.fixed("T_diffuse", 4),
                    r.fixed("T_diffuse_stderr", 4)
                ),
                r.fixed("T_diffuse_ref", 4),
                r.fixed("z_t", 2),
            ]
        });
        out.push_str(&table(
            &[
                "τ",
                "albedo",
                "g",
                "μ₀",
                "R (MC)",
                "R (reference)",
                "z(R)",
                "T (MC)",
                "T (reference)",
                "z(T)",
            ],
            rows,
        ));
        out.push('\n');
        out.push_str(&s.png("slab.png"));
        Ok(out)
    }
}
