//! The RDE's steady state against CDA (spec §5 A1–A3) and time to tolerance of the FTCS
//! against CDA's red-black SOR on the same scenes (spec §5, "time to tolerance"), plus the
//! thesis's containment figures on synthetic phantoms (thesis Figs 3.3/3.4/4.4/4.6 analogs,
//! spec §3): Perona–Malik (thesis Eqs 3.1–3.5) and the RDE (conservative, gradient-mapped β)
//! on a wall with a one-voxel gap and a tube, with leak and fill fractions.
//!
//! * `steady.csv`: per scene (homogeneous β = 0.5 at α = 0.9, 0.99; a smooth β bump 0.5 →
//!   0.9; a one-voxel β step 0.1 | 0.9 at α = 0.99), CDA at R̄/j̄ < 10⁻¹¹ is the reference;
//!   each RDE operator runs to R̄/j̄ < 10⁻¹⁰ (f64, default r = 0.9 r_G): max|∆φ|/max φ and
//!   relative L2 vs CDA, steps, seconds, min φ.
//! * `time_to_tolerance.csv`: the same scenes to R̄/j̄ < 10⁻⁶ (f64): CDA-SOR (ω optimal for
//!   the Poisson problem), the conservative FTCS at 0.9 r_G, and with the local step (damped
//!   Jacobi): iterations and seconds (wall clock, 2 shared cores).
//! * `containment.csv`: leak fraction (energy outside the structure over the total) and fill
//!   fraction (mean over the structure relative to the source voxel) against iterations, for
//!   Perona–Malik (σ = 0.1, clamped source) and the RDE (β = max(exp(−(‖∇V‖/σ)²), 10⁻³),
//!   Ka∆ = 1 − β, the thesis's Fig 4.4 caption, or (1 − α)/(3β) at α = 0.99).
//! * `thesis_style_gap.png`, `thesis_style_tube.png`: the last checkpoint of each containment run drawn as the thesis
//!   draws it (`solvers::rde::dvr`, thesis Eqs 1.12–1.14): the phantom's data through a
//!   transfer function, the diffused energy in green on a 4-decade log scale; the gap
//!   phantom seen along z, the tube along x. An illustration only.

use crate::common::{CommonArgs, Ctx};
use crate::cost::Estimate;
use crate::experiment::{BackendSupport, Experiment, Promise};
use crate::images::{ColourMap, Tile, write_strip};
use crate::plot::{Axis, Series, Style, plot};
use crate::report::{Section, table};
use anyhow::{Context, Result};
use serde::Serialize;
use solvers::fld::{self, FldConfig};
use solvers::rde::dvr::{self, ThesisStyle};
use solvers::rde::pm::{Conductance, PeronaMalik, Phantom, PmConfig, fill_fraction, leak_fraction};
use solvers::rde::{BoundaryCondition, Coefficients, CpuRde, Operator, RdeConfig, TimeStep};
use solvers::{Backend, Grid, Medium, Precision};
use std::time::Instant;

/// Flags of `rde_steady`.
#[derive(Debug, Clone, clap::Parser)]
#[command(about = "RDE steady state vs CDA, time to tolerance vs CDA-SOR, phantom containment")]
pub struct Args {
    /// Shared flags.
    #[command(flatten)]
    pub common: CommonArgs,
}

#[derive(Debug, Serialize)]
struct SteadyRow {
    scene: String,
    method: String,
    steps: usize,
    seconds: f64,
    rel_max_vs_cda: f64,
    rel_l2_vs_cda: f64,
    min_phi: f64,
    expanded_violations: usize,
}

#[derive(Debug, Serialize)]
struct TimeRow {
    scene: String,
    method: String,
    tolerance: f64,
    iterations: usize,
    seconds: f64,
    converged: bool,
}

#[derive(Debug, Serialize)]
struct ContainRow {
    phantom: String,
    method: String,
    iterations: usize,
    leak_fraction: f64,
    fill_fraction: f64,
}

fn scenes(n: usize) -> Result<Vec<(String, Medium<f64>)>> {
    let grid = Grid::new([n; 3], 1.0)?;
    let len = grid.len();
    let centre = grid.index(n / 2, n / 2, n / 2);
    let mut out = Vec::new();
    for albedo in [0.9, 0.99] {
        let mut m = Medium::homogeneous(grid, 1.0 / 1.5, albedo)?;
        m.emission[centre] = 1.0;
        out.push((format!("homogeneous β = 0.5, α = {albedo}"), m));
    }
    let c = n as f64 / 2.0;
    let w = n as f64 / 4.0;
    let beta = grid.sample(|p| {
        let r2 = (0..3).map(|a| (p[a] - c).powi(2)).sum::<f64>();
        0.5 + 0.4 * (-r2 / (w * w)).exp()
    });
    let q = grid.sample(|p| {
        let r2 = (0..3).map(|a| (p[a] - 0.8 * c).powi(2)).sum::<f64>();
        (-r2 / (n as f64 / 8.0).powi(2)).exp()
    });
    let sigma_t: Vec<f64> = beta.iter().map(|b| 1.0 / (3.0 * b)).collect();
    out.push((
        "smooth β bump 0.5 → 0.9, α = 0.9".into(),
        Medium::new(grid, sigma_t, vec![0.9; len], q)?,
    ));
    let sigma_t: Vec<f64> = (0..len)
        .map(|idx| {
            1.0 / (3.0
                * if grid.coords(idx)[0] < n / 2 {
                    0.1
                } else {
                    0.9
                })
        })
        .collect();
    let mut q = vec![0.0; len];
    q[grid.index(n / 2 - 2, n / 2, n / 2)] = 1.0;
    out.push((
        "β step 0.1 : 0.9, α = 0.99".into(),
        Medium::new(grid, sigma_t, vec![0.99; len], q)?,
    ));
    Ok(out)
}

fn rel(a: &[f64], b: &[f64]) -> (f64, f64) {
    let maxb = b.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let maxd = a
        .iter()
        .zip(b)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
    let d: f64 = a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum();
    let nb: f64 = b.iter().map(|y| y * y).sum();
    (maxd / maxb, (d / nb).sqrt())
}

fn cda(m: &Medium<f64>, tol: f64) -> Result<(Vec<f64>, usize, f64, bool)> {
    let cfg = FldConfig::cda()
        .with_omega(FldConfig::poisson_optimal_omega(m.grid.n[0]))
        .with_tolerance(tol)
        .with_max_iterations(200_000);
    let t0 = Instant::now();
    let s = fld::solve(
        &Backend::Cpu(Precision::F64),
        m,
        &fld::Boundary::Zero,
        &cfg,
        |_, _| {},
    )?;
    let converged = s.converged();
    Ok((s.phi, s.steps, t0.elapsed().as_secs_f64(), converged))
}

/// Ka∆ as a function of β on a phantom.
type KaMap = fn(f64) -> f64;

/// Runs the containment methods on `ph`, appending rows at each checkpoint; returns each
/// method's field at the last checkpoint (for the thesis-style images).
fn containment(
    rows: &mut Vec<ContainRow>,
    name: &str,
    ph: &Phantom,
    checkpoints: &[usize],
) -> Result<Vec<(String, Vec<f64>)>> {
    // Perona–Malik, clamped source.
    let cfg = PmConfig {
        conductance: Conductance::Exponential,
        sigma: 0.1,
        lambda: None,
        source_level: 1.0,
    };
    let mut pm = PeronaMalik::<f64>::new(ph.grid, &ph.data, &ph.sources, &cfg)?;
    let mut done = 0;
    for &c in checkpoints {
        while done < c {
            pm.step();
            done += 1;
        }
        rows.push(ContainRow {
            phantom: name.into(),
            method: "Perona–Malik σ = 0.1".into(),
            iterations: c,
            leak_fraction: leak_fraction(pm.energy(), &ph.inside),
            fill_fraction: fill_fraction(pm.energy(), &ph.inside, 1.0),
        });
    }
    let mut last = vec![("Perona–Malik σ = 0.1".to_string(), pm.energy().to_vec())];
    // RDE, conservative, Neumann walls, gradient-mapped β.
    let beta = ph.gradient_beta(Conductance::Exponential, 0.1, 1e-3);
    let variants: [(&str, KaMap); 2] = [
        ("RDE Ka∆ = 1 − β", |b| 1.0 - b),
        ("RDE α = 0.99", |b| 0.01 / (3.0 * b)),
    ];
    for (label, ka) in variants {
        let coef: Coefficients = ph.rde_coefficients(beta.clone(), ka)?;
        let src = ph.sources[0];
        let sidx = ph.grid.index(src[0], src[1], src[2]);
        let mut prev = 0;
        let mut phi0: Option<Vec<f64>> = None;
        for &c in checkpoints {
            let mut co = coef.clone();
            if let Some(p) = phi0.take() {
                co = co.with_initial(p);
            }
            let cfg = RdeConfig::default()
                .with_boundary(BoundaryCondition::Neumann)
                .with_time_step(TimeStep::Gershgorin { safety: 0.9 })
                .frames(c - prev, 0);
            let s = CpuRde::<f64>::new(&co, &cfg)
                .with_context(|| format!("{name}: {label}"))?
                .run();
            rows.push(ContainRow {
                phantom: name.into(),
                method: label.into(),
                iterations: c,
                leak_fraction: leak_fraction(&s.phi, &ph.inside),
                fill_fraction: fill_fraction(&s.phi, &ph.inside, s.phi[sidx]),
            });
            prev = c;
            phi0 = Some(s.phi);
        }
        if let Some(phi) = phi0 {
            last.push((label.to_string(), phi));
        }
    }
    Ok(last)
}

/// One phantom's thesis-style strip: file suffix, phantom, ray axis, K_a∆ at data 1,
/// emission gain per voxel, and each method's last field.
struct StyleView<'a> {
    short: &'a str,
    ph: &'a Phantom,
    axis: usize,
    opacity: f64,
    gain: f64,
    fields: &'a [(String, Vec<f64>)],
}

/// Thesis-style strips, one per phantom (`thesis_style_<short>.png`): one tile per method at
/// the last checkpoint.
fn thesis_style(ctx: &Ctx, views: &[StyleView<'_>], iterations: usize) -> Result<()> {
    for &StyleView {
        short,
        ph,
        axis,
        opacity,
        gain,
        fields,
    } in views
    {
        let style = ThesisStyle {
            axis,
            opacity,
            gain,
            ..ThesisStyle::default()
        };
        let mut images = Vec::new();
        for (label, phi) in fields {
            // 0.9 r_G may exceed the positivity bound r_pos, so a step can leave rounding-size
            // negatives, which the image (emission ∝ φ) shows as zero.
            let phi: Vec<f64> = phi.iter().map(|&x| x.max(0.0)).collect();
            let img = dvr::render(&ph.grid, &ph.data, &phi, &style)
                .with_context(|| format!("thesis-style image of {label} on the {short}"))?;
            images.push((format!("{label}\n{iterations} iterations"), img));
        }
        let Some((w, h)) = images.first().map(|(_, i)| (i.w, i.h)) else {
            continue;
        };
        let tiles: Vec<Tile<'_>> = images
            .iter()
            .map(|(label, i)| {
                Tile::new(
                    i.rgb.iter().map(|c| c.as_slice()).collect(),
                    ColourMap::Radiance { white: 1.0 },
                )
                .labelled(label.clone())
            })
            .collect();
        write_strip(
            &ctx.path(&format!("thesis_style_{short}.png")),
            w,
            h,
            &tiles,
        )?;
    }
    Ok(())
}

fn run_in(ctx: &mut Ctx, _args: &Args) -> Result<()> {
    let quick = ctx.quick();
    let n = if quick { 15 } else { 33 };
    let (n2, n3) = if quick { (24, 16) } else { (48, 32) };
    let checkpoints: Vec<usize> = if quick {
        vec![10, 100, 1000]
    } else {
        vec![10, 100, 1000, 10_000, 30_000]
    };
    let vox = (n as f64).powi(3);
    let mut work = Estimate::new();
    work.add(
        "steady solves (4 scenes × 3 operators + CDA)",
        4.0 * 4.0 * 8000.0 * vox,
    );
    work.add("time to tolerance", 4.0 * 3.0 * 4000.0 * vox);
    let last = *checkpoints.last().unwrap_or(&0) as f64;
    work.add(
        "containment runs",
        3.0 * last * ((n2 * n2 * 3) as f64 + (n3 as f64).powi(3)),
    );
    ctx.work(&work)?;
    ctx.start(serde_json::json!({"n": n, "n_gap": n2, "n_tube": n3, "checkpoints": checkpoints}))?;

    let mut steady = Vec::new();
    let mut ttt = Vec::new();
    let scenes = scenes(n)?;
    let pb = ctx.progress(scenes.len() as u64, "scenes");
    for (name, m) in &scenes {
        let (reference, it, secs, _) = cda(m, 1e-11)?;
        steady.push(SteadyRow {
            scene: name.clone(),
            method: "CDA (reference, R̄/j̄ < 1e-11)".into(),
            steps: it,
            seconds: secs,
            rel_max_vs_cda: 0.0,
            rel_l2_vs_cda: 0.0,
            min_phi: reference.iter().cloned().fold(f64::INFINITY, f64::min),
            expanded_violations: 0,
        });
        let coef = Coefficients::from_medium(m, 0.0)?;
        for op in Operator::ALL {
            let cfg = RdeConfig::default()
                .with_operator(op)
                .steady(1e-10, 400_000);
            let t0 = Instant::now();
            let s = CpuRde::<f64>::new(&coef, &cfg)?.run();
            let secs = t0.elapsed().as_secs_f64();
            let (rm, rl) = rel(&s.phi, &reference);
            steady.push(SteadyRow {
                scene: name.clone(),
                method: format!("RDE {}", op.name()),
                steps: s.steps,
                seconds: secs,
                rel_max_vs_cda: rm,
                rel_l2_vs_cda: rl,
                min_phi: s.trace.min_phi,
                expanded_violations: s.trace.expanded_violations,
            });
        }
        let tol = 1e-6;
        let (_, it, secs, conv) = cda(m, tol)?;
        ttt.push(TimeRow {
            scene: name.clone(),
            method: "CDA red-black SOR".into(),
            tolerance: tol,
            iterations: it,
            seconds: secs,
            converged: conv,
        });
        for (label, ts) in [
            ("RDE FTCS r = 0.9 r_G", TimeStep::Gershgorin { safety: 0.9 }),
            (
                "RDE local step (damped Jacobi)",
                TimeStep::Local { safety: 0.9 },
            ),
        ] {
            let cfg = RdeConfig::default().with_time_step(ts).steady(tol, 400_000);
            let t0 = Instant::now();
            let s = CpuRde::<f64>::new(&coef, &cfg)?.run();
            ttt.push(TimeRow {
                scene: name.clone(),
                method: label.into(),
                tolerance: tol,
                iterations: s.steps,
                seconds: t0.elapsed().as_secs_f64(),
                converged: s.converged(),
            });
        }
        pb.inc(1);
    }
    pb.finish_and_clear();
    ctx.csv("steady.csv", &steady)?;
    ctx.csv("time_to_tolerance.csv", &ttt)?;

    let mut rows = Vec::new();
    let gap = Phantom::gap_edge(n2, 1)?;
    let gap_last = containment(
        &mut rows,
        "2D wall with a one-voxel gap",
        &gap,
        &checkpoints,
    )?;
    let tube = Phantom::tube(n3, n3 as f64 / 8.0)?;
    let tube_last = containment(&mut rows, "3D tube", &tube, &checkpoints)?;
    ctx.csv("containment.csv", &rows)?;
    // The gap phantom is 3 voxels thick (opaque wall: K_a∆ = 1, emission gain 0.12 per
    // voxel); the tube is seen across its diameter (K_a∆ = 0.15, gain 0.25 per voxel).
    thesis_style(
        ctx,
        &[
            StyleView {
                short: "gap",
                ph: &gap,
                axis: 2,
                opacity: 1.0,
                gain: 0.12,
                fields: &gap_last,
            },
            StyleView {
                short: "tube",
                ph: &tube,
                axis: 0,
                opacity: 0.15,
                gain: 0.25,
                fields: &tube_last,
            },
        ],
        *checkpoints.last().unwrap_or(&0),
    )?;
    let mut series = Vec::new();
    let methods: Vec<String> = {
        let mut v: Vec<String> = rows.iter().map(|r| r.method.clone()).collect();
        v.dedup();
        v.sort();
        v.dedup();
        v
    };
    for (pi, ph) in ["2D wall with a one-voxel gap", "3D tube"]
        .iter()
        .enumerate()
    {
        for (mi, m) in methods.iter().enumerate() {
            let pts: Vec<(f64, f64)> = rows
                .iter()
                .filter(|r| r.phantom == *ph && &r.method == m)
                .map(|r| (r.iterations as f64, r.leak_fraction.max(1e-12)))
                .collect();
            series.push(Series::new(
                format!("{m}, {}", if pi == 0 { "gap" } else { "tube" }),
                pts,
                if pi == 0 { Style::Line } else { Style::Dashed },
                mi,
            ));
        }
    }
    plot(
        &ctx.path("containment.png"),
        "Thesis Figs 3.3/3.4/4.4 analog: leak fraction against iterations",
        &Axis::log("iterations"),
        &Axis::log("leak fraction").range(1e-12, 1.0),
        &series,
    )?;
    Ok(())
}

/// The RDE's steady state vs CDA, time to tolerance and containment in the registry.
#[derive(Debug)]
pub struct RdeSteady;

impl Experiment for RdeSteady {
    const NAME: &'static str = "rde_steady";
    const TITLE: &'static str = "RDE (thesis Ch. 4): steady state vs CDA, time to tolerance vs CDA-SOR, containment on phantoms";
    const BACKEND: BackendSupport = BackendSupport::CpuOnly("f64 reference comparisons");
    type Args = Args;
    type Summary = ();

    fn common(args: &Args) -> &CommonArgs {
        &args.common
    }

    fn promises(_args: &Args) -> Vec<Promise> {
        vec![
            Promise::csv(
                "steady.csv",
                &[
                    "scene",
                    "method",
                    "steps",
                    "seconds",
                    "rel_max_vs_cda",
                    "rel_l2_vs_cda",
                    "min_phi",
                ],
            ),
            Promise::csv(
                "time_to_tolerance.csv",
                &[
                    "scene",
                    "method",
                    "tolerance",
                    "iterations",
                    "seconds",
                    "converged",
                ],
            ),
            Promise::csv(
                "containment.csv",
                &[
                    "phantom",
                    "method",
                    "iterations",
                    "leak_fraction",
                    "fill_fraction",
                ],
            ),
            Promise::file("containment.png"),
            Promise::file("thesis_style_gap.png"),
            Promise::file("thesis_style_tube.png"),
        ]
    }

    fn run(ctx: &mut Ctx, args: &Args) -> Result<()> {
        run_in(ctx, args)
    }

    fn report(s: &Section<'_>) -> Result<String> {
        let t = s.csv("steady.csv")?;
        t.require(&["scene", "method", "steps", "rel_max_vs_cda"])?;
        let mut out = String::from(
            "Steady state of the three RDE operators against CDA (f64; max|∆φ|/max φ and \
             relative L2; steps to R̄/j̄ < 10⁻¹⁰ at r = 0.9 r_G; wall seconds):\n\n",
        );
        out.push_str(&table(
            &[
                "scene",
                "method",
                "steps",
                "s",
                "max rel. diff",
                "L2 rel. diff",
                "min φ",
            ],
            t.rows().map(|r| {
                vec![
                    r.get("scene").to_string(),
                    r.get("method").to_string(),
                    r.get("steps").to_string(),
                    r.fixed("seconds", 3),
                    r.sci("rel_max_vs_cda", 2),
                    r.sci("rel_l2_vs_cda", 2),
                    r.sci("min_phi", 2),
                ]
            }),
        ));
        out.push_str("\nTime to R̄/j̄ < 10⁻⁶ (f64, same scenes):\n\n");
        let tt = s.csv("time_to_tolerance.csv")?;
        out.push_str(&table(
            &["scene", "method", "iterations", "s", "converged"],
            tt.rows().map(|r| {
                vec![
                    r.get("scene").to_string(),
                    r.get("method").to_string(),
                    r.get("iterations").to_string(),
                    r.fixed("seconds", 3),
                    r.get("converged").to_string(),
                ]
            }),
        ));
        out.push_str("\nContainment on the phantoms (last checkpoint):\n\n");
        let c = s.csv("containment.csv")?;
        let last = c.rows().map(|r| r.num("iterations")).fold(0.0f64, f64::max);
        out.push_str(&table(
            &[
                "phantom",
                "method",
                "iterations",
                "leak fraction",
                "fill fraction",
            ],
            c.rows().filter(|r| r.num("iterations") == last).map(|r| {
                vec![
                    r.get("phantom").to_string(),
                    r.get("method").to_string(),
                    r.get("iterations").to_string(),
                    r.sci("leak_fraction", 2),
                    r.fixed("fill_fraction", 3),
                ]
            }),
        ));
        out.push('\n');
        out.push_str(&s.png("containment.png"));
        out.push_str(
            "\nThe same runs drawn as the thesis draws them (illustration only; thesis \
             Eqs 1.12–1.14: data through a transfer function, diffused energy in green on \
             a 4-decade log scale; the gap seen along z, the tube along x):\n\n",
        );
        out.push_str(&s.pngs(["thesis_style_gap.png", "thesis_style_tube.png"]));
        Ok(out)
    }
}
