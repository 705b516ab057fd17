//! Tables and plots of the exact transport references in `reference::transport`:
//!
//! * the exact point-source radial density 4πr²φ (Case–Zweifel, σt = 1) with Grosjean
//!   (FLD Eq 24) and CDA (FLD Eq 27) overlaid, and their relative errors;
//! * Chandrasekhar's H-function (both computations) and the half-space plane albedo;
//! * slab diffuse reflectance and transmittance against optical thickness for a few albedos
//!   and Henyey–Greenstein asymmetries (adding–doubling, normal incidence by default), plus
//!   the half-space reflectance and, for isotropic scattering, the plane albedo it must equal.
//!
//! Everything is deterministic; the full run takes a few seconds.
//!
//! CSV interfaces (`results/transport_references/`):
//! * `point_source.csv`: `albedo, r, radial_density, radial_density_collided,
//!   grosjean_radial_density, cda_radial_density, rel_err_grosjean, rel_err_cda`
//! * `point_source_summary.csv`: `albedo, nu0, discrete_amplitude, energy_balance,
//!   grosjean_max_abs_rel_err_near, grosjean_max_abs_rel_err_far, cda_max_abs_rel_err_far`
//!   (near: r ∈ [0.01, 1], far: r ∈ [1, 10])
//! * `h_function.csv`: `albedo, mu, h_integral, h_nystrom, plane_albedo`
//! * `slab.csv`: `albedo, g, mu0, tau, streams, reflectance, transmittance_diffuse,
//!   transmittance_direct`
//! * `slab_half_space.csv`: `albedo, g, mu0, streams, reflectance, plane_albedo`
//!   (`plane_albedo` empty unless g = 0)

use crate::common::{CommonArgs, Ctx, list_item};
use crate::experiment::{BackendSupport, Experiment, Promise};
use crate::plot::{Axis, Series, Style, plot};
use crate::report::{Section, table};
use anyhow::{Context, Result, bail};
use reference::point_source::{cda, grosjean};
use reference::transport::hfunction::{HFunction, h_function, plane_albedo};
use reference::transport::point::ExactPointSource;
use reference::transport::slab::Slab;
use serde::Serialize;
use solvers::error::Compact;
use std::time::Instant;

/// Flags of `transport_references`.
#[derive(Debug, Clone, clap::Parser)]
#[command(about = "Exact transport references: point source, H-function, slab R/T")]
pub struct Args {
    /// Shared flags.
    #[command(flatten)]
    pub common: CommonArgs,
    /// Albedos of the point-source curves.
    #[arg(long, value_delimiter = ',', value_parser = list_item::<f64>, default_value = "0.3,0.7,0.9,0.99")]
    pub albedo: Vec<f64>,
    /// Largest radius (mean free paths) of the point-source curves, in (0.01, 400]
    /// (see [`R_MAX_LIMIT`]).
    #[arg(long, default_value_t = 50.0, allow_negative_numbers = true)]
    pub r_max: f64,
    /// Albedos of the H-function curves (c ≤ 1).
    #[arg(long, value_delimiter = ',', value_parser = list_item::<f64>, default_value = "0.1,0.5,0.9,0.99,0.999999,1")]
    pub h_albedo: Vec<f64>,
    /// Albedos of the slab curves (c ≤ 1).
    #[arg(long, value_delimiter = ',', value_parser = list_item::<f64>, default_value = "0.5,0.9,0.99,1")]
    pub slab_albedo: Vec<f64>,
    /// Henyey–Greenstein asymmetries of the slab curves.
    #[arg(long, value_delimiter = ',', value_parser = list_item::<f64>, default_value = "0,0.5,0.9")]
    pub g: Vec<f64>,
    /// Incidence cosine of the slab curves.
    #[arg(long, default_value_t = 1.0)]
    pub mu0: f64,
}

/// The largest `--r-max`: up to here every column of `point_source.csv` is a normal f64 for
/// every albedo in [0, 1), so the relative errors are ratios of numbers with full precision.
/// Measured (first r where the exact, Grosjean or CDA radial density leaves the normal
/// range): 413 mean free paths at c = 0, where the CDA density 3r e^{−√3 r} falls below
/// 2.2·10⁻³⁰⁸ first (c = 0.3: 494, c = 0.9: 1309, c = 0.999999: 4.2·10⁵). Beyond it the
/// relative errors are ratios of subnormals, then −1 (CDA underflowed to 0) and, from
/// r ≈ 745 at low albedos, where e^{−r} and the exact density underflow too, 0/0 = NaN.
/// (The exact solution itself is accurate wherever it is representable; the limit is
/// f64's range, not the series or the quadrature.)
pub const R_MAX_LIMIT: f64 = 400.0;

#[derive(Debug, Serialize)]
struct PointRow {
    albedo: f64,
    r: f64,
    radial_density: f64,
    radial_density_collided: f64,
    grosjean_radial_density: f64,
    cda_radial_density: f64,
    rel_err_grosjean: f64,
    rel_err_cda: f64,
}

/// Per-albedo summary of the point source (`point_source_summary.csv`).
#[derive(Debug, Clone, Serialize)]
pub struct PointSummary {
    /// Albedo c.
    pub albedo: f64,
    /// Discrete eigenvalue ν0.
    pub nu0: f64,
    /// Discrete-mode amplitude A0 of 4πrφ.
    pub discrete_amplitude: f64,
    /// (1 − c) ∫ 4πr²φ dr (should be 1).
    pub energy_balance: f64,
    /// max |Grosjean/exact − 1| on r ∈ [0.01, 1].
    pub grosjean_max_abs_rel_err_near: f64,
    /// max |Grosjean/exact − 1| on r ∈ [1, 10].
    pub grosjean_max_abs_rel_err_far: f64,
    /// max |CDA/exact − 1| on r ∈ [1, 10].
    pub cda_max_abs_rel_err_far: f64,
}

#[derive(Debug, Serialize)]
struct HRow {
    albedo: f64,
    mu: f64,
    h_integral: f64,
    h_nystrom: f64,
    plane_albedo: f64,
}

#[derive(Debug, Serialize)]
struct SlabRow {
    albedo: f64,
    g: f64,
    mu0: f64,
    tau: f64,
    streams: usize,
    reflectance: f64,
    transmittance_diffuse: f64,
    transmittance_direct: f64,
}

#[derive(Debug, Serialize)]
struct HalfSpaceRow {
    albedo: f64,
    g: f64,
    mu0: f64,
    streams: usize,
    reflectance: f64,
    plane_albedo: Option<f64>,
}

fn log_grid(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| lo * (hi / lo).powf(i as f64 / (n - 1).max(1) as f64))
        .collect()
}

/// Runs the experiment; returns the point-source summaries.
pub fn run(args: &Args) -> Result<Vec<PointSummary>> {
    crate::experiment::run::<TransportReferences>(args)
}

fn run_in(ctx: &mut Ctx, args: &Args) -> Result<Vec<PointSummary>> {
    let quick = args.common.quick;
    let albedos: Vec<f64> = args.albedo.clone();
    if let Some(a) = albedos.iter().find(|a| !(0.0..1.0).contains(*a)) {
        bail!("--albedo: {a} is outside [0, 1) (the point source needs absorption)");
    }
    let h_albedos: Vec<f64> = args.h_albedo.clone();
    let slab_albedos: Vec<f64> = args.slab_albedo.clone();
    for (flag, list) in [("h-albedo", &h_albedos), ("slab-albedo", &slab_albedos)] {
        if let Some(a) = list.iter().find(|a| !(0.0..=1.0).contains(*a)) {
            bail!("--{flag}: {a} is outside [0, 1]");
        }
    }
    let gs: Vec<f64> = args.g.clone();
    if let Some(g) = gs.iter().find(|g| g.is_nan() || g.abs() >= 1.0) {
        bail!("--g: {g} is outside (−1, 1)");
    }
    if !(args.r_max > 0.01 && args.r_max <= R_MAX_LIMIT) {
        bail!(
            "--r-max must be in (0.01, {R_MAX_LIMIT}] mean free paths, got {}: beyond r ≈ 413 the CDA density (at c = 0) underflows f64, and from r ≈ 745 the exact density too, so the relative-error columns become −1 and NaN",
            Compact(args.r_max)
        );
    }
    if !(args.mu0 > 0.0 && args.mu0 <= 1.0) {
        bail!("--mu0 must be in (0, 1], got {}", args.mu0);
    }
    let params = serde_json::json!({
        "albedo": albedos, "r_max": args.r_max, "h_albedo": h_albedos,
        "slab_albedo": slab_albedos, "g": gs, "mu0": args.mu0, "quick": quick,
    });
    ctx.start(params)?;
    let out = ctx;

    // Point source.
    let t0 = Instant::now();
    let rs = log_grid(1e-3, args.r_max, if quick { 60 } else { 300 });
    let mut point_rows = Vec::new();
    let mut summaries = Vec::new();
    for &c in &albedos {
        let p = ExactPointSource::new(c).with_context(|| format!("point source c = {c}"))?;
        // reference::point_source returns φ̃ = 4πφ/σt² (FLD Eq 25); with σt = 1 the radial
        // density 4πr²φ is r²φ̃.
        for &r in &rs {
            let exact = p.radial_density(r);
            let (g, d) = (r * r * grosjean(r, c), r * r * cda(r, c));
            point_rows.push(PointRow {
                albedo: c,
                r,
                radial_density: exact,
                radial_density_collided: exact - (-r).exp(),
                grosjean_radial_density: g,
                cda_radial_density: d,
                rel_err_grosjean: g / exact - 1.0,
                rel_err_cda: d / exact - 1.0,
            });
        }
        let max_err = |r0: f64, r1: f64, f: &dyn Fn(f64) -> f64| {
            log_grid(r0, r1, 201)
                .into_iter()
                .map(|r| (f(r) / p.radial_density(r) - 1.0).abs())
                .fold(0.0, f64::max)
        };
        let r_end = 44.0 * p.nu0();
        summaries.push(PointSummary {
            albedo: c,
            nu0: p.nu0(),
            discrete_amplitude: p.discrete_amplitude(),
            energy_balance: (1.0 - c) * r_end * p.shell_average(0.0, r_end).0,
            grosjean_max_abs_rel_err_near: max_err(0.01, 1.0, &|r| r * r * grosjean(r, c)),
            grosjean_max_abs_rel_err_far: max_err(1.0, 10.0, &|r| r * r * grosjean(r, c)),
            cda_max_abs_rel_err_far: max_err(1.0, 10.0, &|r| r * r * cda(r, c)),
        });
    }
    out.timing("point source", t0.elapsed().as_secs_f64());
    out.csv("point_source.csv", &point_rows)?;
    out.csv("point_source_summary.csv", &summaries)?;

    // H-function and plane albedo.
    let t0 = Instant::now();
    let n_mu = if quick { 21 } else { 201 };
    let mut h_rows = Vec::new();
    for &c in &h_albedos {
        let hf = HFunction::new(c).with_context(|| format!("H-function c = {c}"))?;
        for i in 0..n_mu {
            let mu = i as f64 / (n_mu - 1) as f64;
            h_rows.push(HRow {
                albedo: c,
                mu,
                h_integral: h_function(c, mu)?,
                h_nystrom: hf.eval(mu)?,
                plane_albedo: plane_albedo(c, mu)?,
            });
        }
    }
    out.timing("H-function", t0.elapsed().as_secs_f64());
    out.csv("h_function.csv", &h_rows)?;

    // Slabs: τ = 2^k / 64 so one grid covers thin to thick.
    let t0 = Instant::now();
    let taus: Vec<f64> = if quick {
        vec![0.0625, 1.0, 16.0]
    } else {
        (0..=16).map(|k| 2f64.powi(k) / 64.0).collect()
    };
    let mut slab_rows = Vec::new();
    let mut half_rows = Vec::new();
    for &g in &gs {
        for &c in &slab_albedos {
            for &tau in &taus {
                let slab = Slab::new(tau, c, g)?;
                let r = slab
                    .solve(args.mu0)
                    .with_context(|| format!("slab τ = {tau}, c = {c}, g = {g}"))?;
                slab_rows.push(SlabRow {
                    albedo: c,
                    g,
                    mu0: args.mu0,
                    tau,
                    streams: slab.default_streams(),
                    reflectance: r.reflectance,
                    transmittance_diffuse: r.transmittance_diffuse,
                    transmittance_direct: r.transmittance_direct,
                });
            }
            let slab = Slab::new(f64::INFINITY, c, g)?;
            let r = slab
                .solve(args.mu0)
                .with_context(|| format!("half-space c = {c}, g = {g}"))?;
            half_rows.push(HalfSpaceRow {
                albedo: c,
                g,
                mu0: args.mu0,
                streams: slab.default_streams(),
                reflectance: r.reflectance,
                plane_albedo: if g == 0.0 {
                    Some(plane_albedo(c, args.mu0)?)
                } else {
                    None
                },
            });
        }
    }
    out.timing("slab", t0.elapsed().as_secs_f64());
    out.csv("slab.csv", &slab_rows)?;
    out.csv("slab_half_space.csv", &half_rows)?;

    plots(
        out,
        &albedos,
        &point_rows,
        &h_albedos,
        &h_rows,
        &gs,
        &slab_rows,
    )?;
    Ok(summaries)
}

fn plots(
    out: &Ctx,
    albedos: &[f64],
    point: &[PointRow],
    h_albedos: &[f64],
    h: &[HRow],
    gs: &[f64],
    slab: &[SlabRow],
) -> Result<()> {
    let r_axis = Axis::log("r (mean free paths)");
    let mut dens = Vec::new();
    let mut errs = Vec::new();
    for (k, &c) in albedos.iter().enumerate() {
        let rows: Vec<&PointRow> = point.iter().filter(|p| p.albedo == c).collect();
        let pts = |f: &dyn Fn(&PointRow) -> f64| rows.iter().map(|p| (p.r, f(p))).collect();
        let first = |s: &str| if k == 0 { s.to_string() } else { String::new() };
        dens.push(Series::new(
            format!("exact, c = {c}"),
            pts(&|p| p.radial_density),
            Style::Line,
            k,
        ));
        dens.push(Series::new(
            first("Grosjean (FLD Eq 24)"),
            pts(&|p| p.grosjean_radial_density),
            Style::Dashed,
            k,
        ));
        dens.push(Series::new(
            first("CDA (FLD Eq 27)"),
            rows.iter()
                .step_by(6)
                .map(|p| (p.r, p.cda_radial_density))
                .collect(),
            Style::Points,
            k,
        ));
        errs.push(Series::new(
            format!("Grosjean, c = {c}"),
            pts(&|p| p.rel_err_grosjean),
            Style::Line,
            k,
        ));
        errs.push(Series::new(
            first("CDA (dashed)"),
            pts(&|p| p.rel_err_cda),
            Style::Dashed,
            k,
        ));
    }
    plot(
        &out.path("point_radial_density.png"),
        "Point source: exact 4πr²φ (σt = 1) with Grosjean and CDA",
        &r_axis,
        &Axis::log("radial density 4πr²φ").range(1e-8, 10.0),
        &dens,
    )?;
    plot(
        &out.path("point_relative_error.png"),
        "Point source: approximation / exact − 1",
        &r_axis,
        &Axis::lin("relative error").range(-1.0, 0.5),
        &errs,
    )?;
    let mu_axis = Axis::lin("μ");
    let curves = |f: &dyn Fn(&HRow) -> f64| -> Vec<Series> {
        h_albedos
            .iter()
            .enumerate()
            .map(|(k, &c)| {
                Series::new(
                    format!("c = {c}"),
                    h.iter()
                        .filter(|r| r.albedo == c)
                        .map(|r| (r.mu, f(r)))
                        .collect(),
                    Style::Line,
                    k,
                )
            })
            .collect()
    };
    plot(
        &out.path("h_function.png"),
        "Chandrasekhar H-function, isotropic scattering",
        &mu_axis,
        &Axis::lin("H(μ)"),
        &curves(&|r| r.h_integral),
    )?;
    plot(
        &out.path("plane_albedo.png"),
        "Half-space plane albedo R(μ0) = 1 − √(1−c) H(μ0)",
        &Axis::lin("μ0"),
        &Axis::lin("diffuse reflectance"),
        &curves(&|r| r.plane_albedo),
    )?;
    let slab_albedos: Vec<f64> = {
        let mut v: Vec<f64> = slab.iter().map(|r| r.albedo).collect();
        v.sort_by(f64::total_cmp);
        v.dedup();
        v
    };
    let styles = [Style::Line, Style::Dashed, Style::Points];
    for (name, title, f) in [
        (
            "slab_reflectance.png",
            "Slab diffuse reflectance (adding–doubling)",
            (|r: &SlabRow| r.reflectance) as fn(&SlabRow) -> f64,
        ),
        (
            "slab_transmittance.png",
            "Slab diffuse transmittance (adding–doubling)",
            |r: &SlabRow| r.transmittance_diffuse,
        ),
    ] {
        let mut series = Vec::new();
        for (gi, &g) in gs.iter().enumerate() {
            for (k, &c) in slab_albedos.iter().enumerate() {
                series.push(Series::new(
                    format!("c = {c}, g = {g}"),
                    slab.iter()
                        .filter(|r| r.g == g && r.albedo == c)
                        .map(|r| (r.tau, f(r)))
                        .collect(),
                    styles[gi % styles.len()],
                    k,
                ));
            }
        }
        plot(
            &out.path(name),
            title,
            &Axis::log("optical thickness τ"),
            &Axis::lin("fraction of incident power"),
            &series,
        )?;
    }
    Ok(())
}

/// The exact transport references in the registry.
#[derive(Debug)]
pub struct TransportReferences;

impl Experiment for TransportReferences {
    const NAME: &'static str = "transport_references";
    const TITLE: &'static str = "Exact transport references";
    const BACKEND: BackendSupport = BackendSupport::CpuOnly("exact solutions, no grid solver");
    type Args = Args;
    type Summary = Vec<PointSummary>;

    fn common(args: &Args) -> &CommonArgs {
        &args.common
    }

    fn promises(_args: &Args) -> Vec<Promise> {
        let mut p = vec![
            Promise::csv(
                "point_source.csv",
                &[
                    "albedo",
                    "r",
                    "radial_density",
                    "radial_density_collided",
                    "grosjean_radial_density",
                    "cda_radial_density",
                    "rel_err_grosjean",
                    "rel_err_cda",
                ],
            ),
            Promise::csv(
                "point_source_summary.csv",
                &[
                    "albedo",
                    "nu0",
                    "discrete_amplitude",
                    "energy_balance",
                    "grosjean_max_abs_rel_err_near",
                    "grosjean_max_abs_rel_err_far",
                    "cda_max_abs_rel_err_far",
                ],
            ),
            Promise::csv(
                "h_function.csv",
                &["albedo", "mu", "h_integral", "h_nystrom", "plane_albedo"],
            ),
            Promise::csv(
                "slab.csv",
                &[
                    "albedo",
                    "g",
                    "mu0",
                    "tau",
                    "streams",
                    "reflectance",
                    "transmittance_diffuse",
                    "transmittance_direct",
                ],
            ),
            Promise::csv(
                "slab_half_space.csv",
                &[
                    "albedo",
                    "g",
                    "mu0",
                    "streams",
                    "reflectance",
                    "plane_albedo",
                ],
            ),
        ];
        for f in [
            "point_radial_density.png",
            "point_relative_error.png",
            "h_function.png",
            "plane_albedo.png",
            "slab_reflectance.png",
            "slab_transmittance.png",
        ] {
            p.push(Promise::file(f));
        }
        p
    }

    fn run(ctx: &mut Ctx, args: &Args) -> Result<Self::Summary> {
        run_in(ctx, args)
    }

    fn report(s: &Section<'_>) -> Result<String> {
        let t = s.csv("point_source_summary.csv")?;
        t.require(&[
            "albedo",
            "nu0",
            "energy_balance",
            "grosjean_max_abs_rel_err_near",
            "grosjean_max_abs_rel_err_far",
            "cda_max_abs_rel_err_far",
        ])?;
        let mut out = String::from(
            "Case–Zweifel point source, Chandrasekhar H-function and adding–doubling slabs, each checked against an \
             independent second computation (see `reference::transport`). Grosjean's and CDA's largest relative \
             error against the exact point source, near (r from 0.01 to 1 mean free path) and far (r from 1 to 10):\n\n",
        );
        let rows = t.rows().map(|r| {
            vec![
                r.get("albedo").to_string(),
                r.fixed("nu0", 4),
                format!("{:.1e}", (r.num("energy_balance") - 1.0).abs()),
                r.fixed("grosjean_max_abs_rel_err_near", 4),
                r.fixed("grosjean_max_abs_rel_err_far", 4),
                r.fixed("cda_max_abs_rel_err_far", 4),
            ]
        });
        out.push_str(&table(
            &[
                "albedo",
                "ν₀",
                "|energy balance − 1|",
                "Grosjean max rel. error, near",
                "Grosjean, far",
                "CDA, far",
            ],
            rows,
        ));
        out.push('\n');
        out.push_str(&s.pngs([
            "point_radial_density.png",
            "point_relative_error.png",
            "h_function.png",
            "plane_albedo.png",
            "slab_reflectance.png",
            "slab_transmittance.png",
        ]));
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every column of `point_source.csv` is a normal f64, with finite relative errors, out to
    /// [`R_MAX_LIMIT`] for albedos across [0, 1); past the measured 413 (c = 0) it is not.
    #[test]
    fn the_r_max_limit_keeps_every_column_representable() {
        let row = |p: &ExactPointSource, c: f64, r: f64| {
            let exact = p.radial_density(r);
            let (g, d) = (r * r * grosjean(r, c), r * r * cda(r, c));
            [exact, g, d, g / exact - 1.0, d / exact - 1.0]
        };
        for k in 0..=20 {
            let c = 0.05 * k as f64 * 0.99999;
            let p = ExactPointSource::new(c).unwrap_or_else(|e| panic!("{e}"));
            for r in [1.0, 100.0, R_MAX_LIMIT] {
                let v = row(&p, c, r);
                assert!(
                    v[..3].iter().all(|x| x.is_normal()),
                    "c = {c}, r = {r}: {v:?}"
                );
                assert!(
                    v[3..].iter().all(|x| x.is_finite()),
                    "c = {c}, r = {r}: {v:?}"
                );
            }
        }
        let p = ExactPointSource::new(0.0).unwrap_or_else(|e| panic!("{e}"));
        assert!(!row(&p, 0.0, 414.0)[2].is_normal());
        assert!(row(&p, 0.0, 750.0)[3].is_nan());
    }
}
