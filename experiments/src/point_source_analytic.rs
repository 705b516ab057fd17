//! FLD Fig 3: the analytic "universal" point-source solutions — (a) Grosjean (FLD Eq 24),
//! (b) CDA (FLD Eq 27), (c) the Knudsen number of the Grosjean solution — for albedos 0…1,
//! as normalised fluence φ̃ = 4πφ/σt² (FLD Eq 25) against optical depth τ.

use crate::common::{CommonArgs, Output};
use crate::plot::{Axis, Series, Style, plot};
use anyhow::Result;
use reference::point_source::{cda, grosjean, grosjean_knudsen, transport_limit};
use serde::Serialize;

/// Flags of `point_source_analytic`.
#[derive(Debug, Clone, clap::Parser)]
#[command(about = "FLD Fig 3: analytic point-source solutions and the Knudsen number")]
pub struct Args {
    /// Shared flags.
    #[command(flatten)]
    pub common: CommonArgs,
    /// Albedos to tabulate.
    #[arg(long, default_value = "0,0.2,0.4,0.6,0.8,0.9,0.95,0.99,1")]
    pub albedo: String,
    /// Largest optical depth.
    #[arg(long, default_value_t = 10.0)]
    pub tau_max: f64,
}

#[derive(Debug, Serialize)]
struct Row {
    albedo: f64,
    tau: f64,
    grosjean: f64,
    cda: f64,
    transport_limit: f64,
    knudsen_grosjean: f64,
}

/// Runs the experiment; returns the output directory.
pub fn run(args: &Args) -> Result<std::path::PathBuf> {
    let albedos: Vec<f64> = crate::common::parse_list("albedo", &args.albedo)?;
    if let Some(a) = albedos.iter().find(|a| !(0.0..=1.0).contains(*a)) {
        anyhow::bail!("--albedo: {a} is outside [0, 1]");
    }
    if !(args.tau_max.is_finite() && args.tau_max > 0.01) {
        anyhow::bail!("--tau-max must be > 0.01, got {}", args.tau_max);
    }
    let out = Output::new(
        "point_source_analytic",
        &args.common,
        serde_json::json!({"albedo": albedos, "tau_max": args.tau_max}),
    )?;
    let npts = if args.common.quick { 60 } else { 400 };
    let taus: Vec<f64> = (0..npts)
        .map(|i| 0.01 * (args.tau_max / 0.01).powf(i as f64 / (npts - 1) as f64))
        .collect();
    let mut rows = Vec::new();
    for &a in &albedos {
        for &t in &taus {
            rows.push(Row {
                albedo: a,
                tau: t,
                grosjean: grosjean(t, a),
                cda: cda(t, a),
                transport_limit: transport_limit(t, a),
                knudsen_grosjean: grosjean_knudsen(t, a),
            });
        }
    }
    out.csv("fig3.csv", &rows)?;
    let series = |f: &dyn Fn(f64, f64) -> f64| -> Vec<Series> {
        albedos
            .iter()
            .enumerate()
            .map(|(c, &a)| {
                Series::new(
                    format!("α = {a}"),
                    taus.iter().map(|&t| (t, f(t, a))).collect(),
                    Style::Line,
                    c,
                )
            })
            .collect()
    };
    let x = Axis::log("optical depth τ");
    plot(
        &out.path("fig3a_grosjean.png"),
        "FLD Fig 3a: Grosjean (Eq 24)",
        &x,
        &Axis::log("normalised fluence φ̃ (Eq 25)").range(1e-5, 1e4),
        &series(&grosjean),
    )?;
    plot(
        &out.path("fig3b_cda.png"),
        "FLD Fig 3b: CDA Green's function (Eq 27)",
        &x,
        &Axis::log("normalised fluence φ̃ (Eq 25)").range(1e-5, 1e4),
        &series(&cda),
    )?;
    plot(
        &out.path("fig3c_knudsen.png"),
        "FLD Fig 3c: Knudsen number of the Grosjean solution",
        &x,
        &Axis::log("R = |∇φ|/(σt φ)"),
        &series(&grosjean_knudsen),
    )?;
    out.finish()?;
    Ok(out.dir.clone())
}
