//! The I3RC Phase 1 step cloud (Case 1 of the Intercomparison of 3D Radiation Codes,
//! Cahalan et al. 2005), path-traced with the periodic slab tracer
//! ([`reference::pathtracer::PeriodicSlab`]): the first case here scored against results
//! from outside this project.
//!
//! **The case.** A 2-D cloud, periodic in x with period 0.5 km and homogeneous in y; 32
//! columns of 15.625 m; the layer is 0.25 km thick and sits on the ground; optical depth
//! τ = 2 in columns 1–16 and τ = 18 in columns 17–32 (σt = 8 and 72 km⁻¹, constant within a
//! column); Henyey–Greenstein phase function with g = 0.85; black surface; no atmosphere;
//! unit solar flux on a horizontal surface. Four experiments (I3RC numbering):
//!
//! | experiment | solar zenith | ω0 |
//! |---|---|---|
//! | 1 | 0° | 1 |
//! | 2 | 60° | 1 |
//! | 3 | 0° | 0.99 |
//! | 4 | 60° | 0.99 |
//!
//! The sun is in the x–z plane; its light propagates towards +x (so at 60° the beam enters
//! the thick half through its face at the boundary of columns 16 and 17, and the thick
//! half shades columns 1, 2, … after the periodic wrap).
//!
//! **Grid.** Voxels are cubes of 15.625 m: 32 × 3 × 16 (y is homogeneous: 3 voxels, the
//! grid minimum, periodic). Tracking is exact for the piecewise-constant medium.
//!
//! **Outputs.** `columns.csv` (`experiment,column,R,R_stderr,T,T_stderr,T_direct,A,A_stderr`;
//! column 1–32, fluxes relative to the power incident on that column: R = upward flux at
//! the cloud top, T = downward flux at the ground (direct + diffuse), T_direct its
//! never-scattered part, A = absorptance), `domain.csv`
//! (`experiment,R,R_stderr,T,T_stderr,A,A_stderr`, means over the period),
//! `columns_<experiment>.png` (R, T and T_direct per column) and `meta.json`. Standard
//! errors by batch means over 64 batches.

use crate::common::{CommonArgs, Ctx, progress};
use crate::experiment::{BackendSupport, Experiment, Promise};
use crate::plot::{Axis, Series, Style, plot};
use crate::report::{Section, table};
use anyhow::{Context, Result};
use reference::effects::PassSums;
use reference::pathtracer::periodic::periodic_tally;
use reference::pathtracer::{Beam, PathSettings, PeriodicSlab, PeriodicTally};
use serde::Serialize;
use solvers::scene::Phase;
use solvers::{Grid, Medium};
use std::time::Instant;

/// Columns per period.
pub const COLUMNS: usize = 32;
/// Period, km.
pub const PERIOD_KM: f64 = 0.5;
/// Cloud thickness, km.
pub const THICKNESS_KM: f64 = 0.25;
/// Henyey–Greenstein asymmetry.
pub const G: f64 = 0.85;
/// Default paths per experiment: per-column standard errors ≤ 0.002 with margin
/// (measured: largest 0.00146 in R, 0.00162 in T, over all 4 × 32 columns, seed 1, 64
/// batches; the full run took 94 s wall on 2 shared cores, 98 s CPU).
pub const DEFAULT_PATHS: u64 = 16_000_000;
/// Paths per experiment with `--quick`.
pub const QUICK_PATHS: u64 = 64_000;

/// Optical depth of column `i` (0-based x index).
pub fn column_tau(i: usize) -> f64 {
    if i < COLUMNS / 2 { 2.0 } else { 18.0 }
}

/// One of the four I3RC experiments.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Case {
    /// I3RC experiment number, 1–4.
    pub experiment: u32,
    /// Solar zenith angle, degrees.
    pub zenith_deg: f64,
    /// Single-scattering albedo ω0.
    pub albedo: f64,
}

/// The four experiments, in I3RC order.
pub const CASES: [Case; 4] = [
    Case {
        experiment: 1,
        zenith_deg: 0.0,
        albedo: 1.0,
    },
    Case {
        experiment: 2,
        zenith_deg: 60.0,
        albedo: 1.0,
    },
    Case {
        experiment: 3,
        zenith_deg: 0.0,
        albedo: 0.99,
    },
    Case {
        experiment: 4,
        zenith_deg: 60.0,
        albedo: 0.99,
    },
];

/// Flags of `i3rc_step_cloud`.
#[derive(Debug, Clone, clap::Parser)]
#[command(about = "I3RC Phase 1 step cloud: per-column reflectance, transmittance, absorptance")]
pub struct Args {
    /// Shared flags.
    #[command(flatten)]
    pub common: CommonArgs,
    /// Paths per experiment (default 1.6e7; 64000 with --quick). Accepts 1e6 notation.
    #[arg(long, value_parser = crate::common::count)]
    pub paths: Option<u64>,
    /// Seed (experiment k uses seed + k − 1).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Batches for the standard errors (≥ 16; 64 so that the stderr estimates themselves
    /// scatter by only ~9 %).
    #[arg(long, default_value_t = 64, value_parser = crate::common::count_u32)]
    pub batches: u32,
}

/// One column of one experiment (`columns.csv`).
#[derive(Debug, Clone, Serialize)]
pub struct ColumnRow {
    /// I3RC experiment number.
    pub experiment: u32,
    /// Column, 1–32.
    pub column: usize,
    /// Reflectance.
    #[serde(rename = "R")]
    pub r: f64,
    /// Its standard error.
    #[serde(rename = "R_stderr")]
    pub r_stderr: f64,
    /// Transmittance (direct + diffuse).
    #[serde(rename = "T")]
    pub t: f64,
    /// Its standard error.
    #[serde(rename = "T_stderr")]
    pub t_stderr: f64,
    /// Direct (never scattered) part of T.
    #[serde(rename = "T_direct")]
    pub t_direct: f64,
    /// Absorptance.
    #[serde(rename = "A")]
    pub a: f64,
    /// Its standard error.
    #[serde(rename = "A_stderr")]
    pub a_stderr: f64,
}

/// Domain means of one experiment (`domain.csv`).
#[derive(Debug, Clone, Serialize)]
pub struct DomainRow {
    /// I3RC experiment number.
    pub experiment: u32,
    /// Reflectance.
    #[serde(rename = "R")]
    pub r: f64,
    /// Its standard error.
    #[serde(rename = "R_stderr")]
    pub r_stderr: f64,
    /// Transmittance.
    #[serde(rename = "T")]
    pub t: f64,
    /// Its standard error.
    #[serde(rename = "T_stderr")]
    pub t_stderr: f64,
    /// Absorptance.
    #[serde(rename = "A")]
    pub a: f64,
    /// Its standard error.
    #[serde(rename = "A_stderr")]
    pub a_stderr: f64,
}

/// What a run returns.
#[derive(Debug, Clone, Serialize)]
pub struct Summary {
    /// Per-column rows, experiment by experiment.
    pub columns: Vec<ColumnRow>,
    /// Domain rows.
    pub domain: Vec<DomainRow>,
    /// R + T + A of the domain means, per experiment.
    pub balance: Vec<f64>,
    /// Paths per experiment.
    pub paths: u64,
    /// Largest per-column standard error of R and of T over all experiments.
    pub max_column_stderr: [f64; 2],
    /// Wall seconds per experiment.
    pub seconds: Vec<f64>,
}

/// The step-cloud medium at albedo ω0 (lengths in km).
pub fn step_cloud(albedo: f64) -> Result<PeriodicSlab> {
    let dl = PERIOD_KM / COLUMNS as f64;
    let nz = (THICKNESS_KM / dl).round() as usize;
    let grid = Grid::new([COLUMNS, 3, nz], dl).context("step-cloud grid")?;
    let sigma: Vec<f64> = (0..grid.len())
        .map(|v| column_tau(grid.coords(v)[0]) / THICKNESS_KM)
        .collect();
    let n = grid.len();
    let medium =
        Medium::new(grid, sigma, vec![albedo; n], vec![0.0; n]).context("step-cloud medium")?;
    Ok(PeriodicSlab::new(
        &medium,
        Phase::HenyeyGreenstein { g: G },
    )?)
}

/// Traces one experiment.
pub fn simulate(case: &Case, settings: &PathSettings) -> Result<PeriodicTally> {
    let slab = step_cloud(case.albedo)?;
    let beam = Beam::from_degrees(case.zenith_deg, 0.0)?;
    slab.simulate(&beam, settings)
        .with_context(|| format!("tracing I3RC experiment {}", case.experiment))
}

/// Runs the four experiments; writes the CSVs, plots and `meta.json`.
pub fn run(args: &Args) -> Result<Summary> {
    crate::experiment::run::<I3rcStepCloud>(args)
}

fn run_in(out: &mut Ctx, args: &Args) -> Result<Summary> {
    let paths = args.paths.unwrap_or(if args.common.quick {
        QUICK_PATHS
    } else {
        DEFAULT_PATHS
    });
    let mut work = crate::cost::Estimate::new();
    for case in &CASES {
        let events = crate::cost::slab_events(18.0, case.albedo);
        work.add(
            format!(
                "experiment {}: {paths} paths × {events:.3e} events",
                case.experiment
            ),
            paths as f64 * events,
        );
    }
    out.work(&work)?;
    out.start(serde_json::json!({
        "paths_per_experiment": paths, "seed": args.seed, "batches": args.batches,
        "cases": CASES, "columns": COLUMNS, "period_km": PERIOD_KM,
        "thickness_km": THICKNESS_KM, "tau": [2.0, 18.0], "g": G,
        "grid": [COLUMNS, 3, 16], "sun": "in the x-z plane, light propagating towards +x",
    }))?;
    let pb = progress(CASES.len() as u64, &args.common, "i3rc_step_cloud");
    let (mut columns, mut domain, mut balance, mut seconds) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut max_se = [0.0f64; 2];
    for case in &CASES {
        pb.set_message(format!(
            "experiment {}: θ0 = {}°, ω0 = {}",
            case.experiment, case.zenith_deg, case.albedo
        ));
        let settings = PathSettings {
            paths,
            seed: args.seed.wrapping_add(u64::from(case.experiment) - 1),
            batches: args.batches,
            max_depth: None,
        };
        let what = format!("I3RC experiment {}", case.experiment);
        let slab = step_cloud(case.albedo)?;
        let beam = Beam::from_degrees(case.zenith_deg, 0.0)?;
        let tallied = out.tally(
            &what,
            |shard| {
                let t0 = Instant::now();
                let sums = slab
                    .simulate_part(&beam, &settings, shard)
                    .with_context(|| format!("tracing {what}"))?;
                Ok(vec![PassSums {
                    sums,
                    seconds: t0.elapsed().as_secs_f64(),
                }])
            },
            |parts| Ok((periodic_tally(&parts[0].sums)?, parts[0].seconds)),
        )?;
        let Some((tally, secs)) = tallied else {
            pb.inc(1);
            continue;
        };
        out.timing(format!("experiment {}", case.experiment), secs);
        seconds.push(secs);
        let rows: Vec<ColumnRow> = tally
            .columns
            .iter()
            .enumerate()
            .map(|(i, c)| ColumnRow {
                experiment: case.experiment,
                column: i + 1,
                r: c.reflectance.mean,
                r_stderr: c.reflectance.stderr,
                t: c.transmittance.mean,
                t_stderr: c.transmittance.stderr,
                t_direct: c.transmittance_direct.mean,
                a: c.absorptance.mean,
                a_stderr: c.absorptance.stderr,
            })
            .collect();
        for r in &rows {
            max_se[0] = max_se[0].max(r.r_stderr);
            max_se[1] = max_se[1].max(r.t_stderr);
        }
        let d = &tally.domain;
        domain.push(DomainRow {
            experiment: case.experiment,
            r: d.reflectance.mean,
            r_stderr: d.reflectance.stderr,
            t: d.transmittance.mean,
            t_stderr: d.transmittance.stderr,
            a: d.absorptance.mean,
            a_stderr: d.absorptance.stderr,
        });
        balance.push(tally.balance.mean);
        plot_case(out, case, &rows)?;
        columns.extend(rows);
        pb.inc(1);
    }
    pb.finish_and_clear();
    if out.sharding() {
        return Ok(Summary {
            columns,
            domain,
            balance,
            paths,
            max_column_stderr: max_se,
            seconds,
        });
    }
    out.csv("columns.csv", &columns)?;
    out.csv("domain.csv", &domain)?;
    out.record(
        "max_column_stderr",
        serde_json::json!({ "R": max_se[0], "T": max_se[1] }),
    );
    out.record("balance", serde_json::json!(balance));
    Ok(Summary {
        columns,
        domain,
        balance,
        paths,
        max_column_stderr: max_se,
        seconds,
    })
}

/// R, T and T_direct against column for one experiment.
fn plot_case(out: &Ctx, case: &Case, rows: &[ColumnRow]) -> Result<()> {
    let pts = |f: &dyn Fn(&ColumnRow) -> f64| -> Vec<(f64, f64)> {
        rows.iter().map(|r| (r.column as f64, f(r))).collect()
    };
    let mut series = vec![
        Series::new("R", pts(&|r| r.r), Style::Points, 0),
        Series::new(String::new(), pts(&|r| r.r), Style::Line, 0),
        Series::new("T", pts(&|r| r.t), Style::Points, 1),
        Series::new(String::new(), pts(&|r| r.t), Style::Line, 1),
        Series::new("T direct", pts(&|r| r.t_direct), Style::Dashed, 2),
    ];
    if case.albedo < 1.0 {
        series.push(Series::new("A", pts(&|r| r.a), Style::Dashed, 3));
    }
    plot(
        &out.path(&format!("columns_{}.png", case.experiment)),
        &format!(
            "I3RC step cloud, experiment {}: θ0 = {}°, ω0 = {} (τ = 2 | 18)",
            case.experiment, case.zenith_deg, case.albedo
        ),
        &Axis::lin("column (1–16: τ = 2, 17–32: τ = 18)").range(0.5, 32.5),
        &Axis::lin("fraction of incident flux").range(0.0, 1.2),
        &series,
    )
}

/// The registry entry (see [`crate::experiment`]).
#[derive(Debug, Clone, Copy)]
pub struct I3rcStepCloud;

const COLUMN_CSV: [&str; 9] = [
    "experiment",
    "column",
    "R",
    "R_stderr",
    "T",
    "T_stderr",
    "T_direct",
    "A",
    "A_stderr",
];
const DOMAIN_CSV: [&str; 7] = [
    "experiment",
    "R",
    "R_stderr",
    "T",
    "T_stderr",
    "A",
    "A_stderr",
];

impl Experiment for I3rcStepCloud {
    const NAME: &'static str = "i3rc_step_cloud";
    const TITLE: &'static str = "I3RC Phase 1 step cloud: path-traced R, T, A per column";
    const BACKEND: BackendSupport = BackendSupport::CpuOnly("the path tracer runs on the CPU");
    const SHARDS: bool = true;
    type Args = Args;
    type Summary = Summary;

    fn common(args: &Args) -> &CommonArgs {
        &args.common
    }

    fn promises(_args: &Args) -> Vec<Promise> {
        let mut p = vec![
            Promise::csv("columns.csv", &COLUMN_CSV),
            Promise::csv("domain.csv", &DOMAIN_CSV),
        ];
        p.extend(
            CASES
                .iter()
                .map(|c| Promise::file(format!("columns_{}.png", c.experiment))),
        );
        p
    }

    fn run(ctx: &mut Ctx, args: &Args) -> Result<Summary> {
        run_in(ctx, args)
    }

    fn report(s: &Section<'_>) -> Result<String> {
        let domain = s.csv("domain.csv")?;
        domain.require(&DOMAIN_CSV)?;
        let columns = s.csv("columns.csv")?;
        columns.require(&COLUMN_CSV)?;
        let mut out = String::from(
            "The I3RC Phase 1 step cloud (Case 1): period 0.5 km of 32 columns, 0.25 km thick, \
             τ = 2 in columns 1–16 and 18 in 17–32, HG g = 0.85, black ground, sun in the x–z \
             plane (light travelling towards +x). Fluxes relative to the incident flux on a \
             horizontal surface, ± one standard error (batch means). Experiments: \
             1: θ0 = 0°, ω0 = 1; 2: 60°, 1; 3: 0°, 0.99; 4: 60°, 0.99.\n\n",
        );
        let se = |r: &crate::report::Row<'_>, v: &str| {
            format!("{} ± {}", r.fixed(v, 4), r.fixed(&format!("{v}_stderr"), 4))
        };
        out.push_str(&table(
            &["experiment", "R", "T", "A"],
            domain.rows().map(|r| {
                vec![
                    r.get("experiment").to_string(),
                    se(&r, "R"),
                    se(&r, "T"),
                    se(&r, "A"),
                ]
            }),
        ));
        out.push_str("\nPer column (R / T):\n\n");
        let ids = columns.distinct("experiment");
        let mut header = vec!["column".to_string()];
        header.extend(ids.iter().map(|e| format!("exp {e}: R / T")));
        let header: Vec<&str> = header.iter().map(String::as_str).collect();
        let ncol = columns.distinct("column");
        let rows = ncol.iter().map(|c| {
            let mut row = vec![c.clone()];
            for e in &ids {
                let cell = columns
                    .rows()
                    .find(|r| r.get("experiment") == e && r.get("column") == c)
                    .map(|r| format!("{} / {}", r.fixed("R", 4), r.fixed("T", 4)))
                    .unwrap_or_default();
                row.push(cell);
            }
            row
        });
        out.push_str(&table(&header, rows));
        out.push('\n');
        out.push_str(&s.pngs(ids.iter().map(|e| format!("columns_{e}.png"))));
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::common::csv_header;
    use clap::Parser;

    /// The quick run writes its interface, conserves energy per experiment, and shows the
    /// physics of the step: the thick half reflects more than the thin half, the thin half
    /// transmits more under an overhead sun, absorption only where ω0 < 1; overhead, each
    /// half is mirror symmetric; at 60° the thick half shades the thin columns after it.
    #[test]
    fn quick_run_writes_its_interface_and_the_step_shows() {
        let dir = std::env::temp_dir().join(format!("scatterbench-i3rc-{}", std::process::id()));
        let args = Args::parse_from([
            "i3rc_step_cloud",
            "--quick",
            "--no-progress",
            "--out",
            dir.to_str().unwrap(),
        ]);
        let s = run(&args).unwrap();
        assert_eq!(
            csv_header(&dir.join("columns.csv")).unwrap(),
            [
                "experiment",
                "column",
                "R",
                "R_stderr",
                "T",
                "T_stderr",
                "T_direct",
                "A",
                "A_stderr"
            ]
        );
        assert_eq!(
            csv_header(&dir.join("domain.csv")).unwrap(),
            [
                "experiment",
                "R",
                "R_stderr",
                "T",
                "T_stderr",
                "A",
                "A_stderr"
            ]
        );
        for k in 1..=4 {
            assert!(dir.join(format!("columns_{k}.png")).exists());
        }
        assert!(dir.join("meta.json").exists());
        assert_eq!(s.columns.len(), 4 * COLUMNS);
        for (b, d) in s.balance.iter().zip(&s.domain) {
            assert!((b - 1.0).abs() < 1e-12, "{b}");
            assert!((d.r + d.t + d.a - 1.0).abs() < 1e-12);
        }
        for case in &CASES {
            let rows: Vec<&ColumnRow> = s
                .columns
                .iter()
                .filter(|r| r.experiment == case.experiment)
                .collect();
            let mean = |lo: usize, hi: usize, f: &dyn Fn(&ColumnRow) -> f64| {
                rows[lo..hi].iter().map(|r| f(r)).sum::<f64>() / (hi - lo) as f64
            };
            assert!(mean(16, 32, &|r| r.r) > mean(0, 16, &|r| r.r) + 0.1);
            let a = mean(0, 32, &|r| r.a);
            if case.albedo == 1.0 {
                assert_eq!(a, 0.0);
            } else {
                assert!(a > 0.01);
            }
            if case.zenith_deg > 0.0 {
                // The slant beam crosses both halves, but the thick half shades the thin
                // columns right after it (1, 2, … after the wrap); the last thin column,
                // just before the thick half, is lit.
                assert!(
                    rows[15].t > rows[0].t + 0.1,
                    "{} vs {}",
                    rows[15].t,
                    rows[0].t
                );
            } else {
                assert!(mean(0, 16, &|r| r.t) > mean(16, 32, &|r| r.t) + 0.1);
                // Overhead sun: each half is mirror symmetric, column c ↔ 17 − c (thin) and
                // 49 − c (thick), within 4.5 combined standard errors.
                type Part = fn(&ColumnRow) -> (f64, f64);
                let parts: [Part; 2] = [|r| (r.r, r.r_stderr), |r| (r.t, r.t_stderr)];
                for c in 0..16 {
                    for (i, j) in [(c, 15 - c), (16 + c, 31 - c)] {
                        for f in parts {
                            let ((x, sx), (y, sy)) = (f(rows[i]), f(rows[j]));
                            assert!((x - y).abs() < 4.5 * sx.hypot(sy), "{i} vs {j}");
                        }
                    }
                }
            }
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}
