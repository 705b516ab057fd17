//! FLD Fig 3: the analytic "universal" point-source solutions — (a) Grosjean (FLD Eq 24),
//! (b) CDA (FLD Eq 27), (c) the Knudsen number of the Grosjean solution — for albedos 0…1,
//! as normalised fluence φ̃ = 4πφ/σt² (FLD Eq 25) against optical depth τ.

use crate::common::{CommonArgs, Ctx, list_item};
use crate::experiment::{BackendSupport, Experiment, Promise};
use crate::plot::{Axis, Series, Style, plot};
use crate::report::{Section, table};
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
    #[arg(long, value_delimiter = ',', value_parser = list_item::<f64>, default_value = "0,0.2,0.4,0.6,0.8,0.9,0.95,0.99,1")]
    pub albedo: Vec<f64>,
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
    crate::experiment::run::<PointSourceAnalytic>(args)
}

fn run_in(ctx: &mut Ctx, args: &Args) -> Result<std::path::PathBuf> {
    let albedos: Vec<f64> = args.albedo.clone();
    if let Some(a) = albedos.iter().find(|a| !(0.0..=1.0).contains(*a)) {
        anyhow::bail!("--albedo: {a} is outside [0, 1]");
    }
    if !(args.tau_max.is_finite() && args.tau_max > 0.01) {
        anyhow::bail!("--tau-max must be > 0.01, got {}", args.tau_max);
    }
    ctx.start(serde_json::json!({"albedo": albedos, "tau_max": args.tau_max}))?;
    let out = ctx;
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
    Ok(out.target().to_path_buf())
}

/// FLD Fig 3 in the registry.
#[derive(Debug)]
pub struct PointSourceAnalytic;

impl Experiment for PointSourceAnalytic {
    const NAME: &'static str = "point_source_analytic";
    const TITLE: &'static str = "FLD Fig 3: analytic point-source solutions";
    const BACKEND: BackendSupport = BackendSupport::CpuOnly("closed-form curves, no solver");
    type Args = Args;
    type Summary = std::path::PathBuf;

    fn common(args: &Args) -> &CommonArgs {
        &args.common
    }

    fn promises(_args: &Args) -> Vec<Promise> {
        vec![
            Promise::csv(
                "fig3.csv",
                &[
                    "albedo",
                    "tau",
                    "grosjean",
                    "cda",
                    "transport_limit",
                    "knudsen_grosjean",
                ],
            ),
            Promise::file("fig3a_grosjean.png"),
            Promise::file("fig3b_cda.png"),
            Promise::file("fig3c_knudsen.png"),
        ]
    }

    fn run(ctx: &mut Ctx, args: &Args) -> Result<Self::Summary> {
        run_in(ctx, args)
    }

    fn report(s: &Section<'_>) -> Result<String> {
        let t = s.csv("fig3.csv")?;
        t.require(&["albedo", "tau", "grosjean", "cda"])?;
        let mut out = String::from(
            "Normalised fluence φ̃ = 4πφ/σt² (FLD Eq 25) of a unit point source against optical \
             depth τ, and the Knudsen number of the Grosjean solution. At τ = 1:\n\n",
        );
        let mut rows = Vec::new();
        for a in t.distinct("albedo") {
            // The tabulated τ closest to 1.
            if let Some(r) = t.rows().filter(|r| r.get("albedo") == a).min_by(|x, y| {
                (x.num("tau") - 1.0)
                    .abs()
                    .total_cmp(&(y.num("tau") - 1.0).abs())
            }) {
                rows.push(vec![
                    a.clone(),
                    r.fixed("tau", 3),
                    r.fixed("grosjean", 3),
                    r.fixed("cda", 3),
                    r.fixed("knudsen_grosjean", 3),
                ]);
            }
        }
        out.push_str(&table(
            &[
                "albedo α",
                "τ",
                "φ̃ Grosjean (Eq 24)",
                "φ̃ CDA (Eq 27)",
                "Knudsen R",
            ],
            rows,
        ));
        out.push('\n');
        out.push_str(&s.pngs(["fig3a_grosjean.png", "fig3b_cda.png", "fig3c_knudsen.png"]));
        Ok(out)
    }
}
