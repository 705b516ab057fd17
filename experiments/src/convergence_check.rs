//! How converged is "converged" (issue 12, item 4): for each grid method at its default
//! tolerance, the relative L2 distance of its φ to a tightly converged solve of the same
//! problem.
//!
//! **Problems.** Exactly what the pipeline's multiple-scattering pass solves: the scene's
//! lights baked into q_ri = σs·L_ri (FLD Eq 6), plus the emission j when the scene renders
//! it, restricted by the downsampling factor and padded by one vacuum layer
//! ([`solvers::pipeline::restrict`]). Datasets: the atlas's scenes (channel 0, downsample 4,
//! the pipeline's default), and albedo-1 cubes (16³, extent 1, one directional light, as in
//! issue 12's acceptance 1) with σt·Δl ∈ {0.6, 6, 60, 6000} at downsample 1 (so σt·Δl is the
//! solve grid's).
//!
//! **Default stop.** [`Tolerance::default`] (the pipeline's: rel = 10⁻⁴, at most 20 000
//! steps), in f32 and f64 on the CPU.
//!
//! **Tight solve.** The same discrete equation in f64 at rel = `--tight` (default 10⁻¹⁰) with
//! `--tight-steps` steps at most, by the method itself, except that a multigrid method
//! (`…:mg`) is measured against the SOR solve of its limiter (the same equation; they agree
//! to 2·10⁻¹⁰ on the point source, `solvers/tests/fld_multigrid.rs`). *How we know it is
//! converged*: a second solve at rel = `--tight`/100 (with twice the steps);
//! `tight_self_distance` is the relative L2 distance between the two. A tight solve that
//! reached its cap or stalled says so in `tight_stop`.
//!
//! **Findings** (full run, `results/convergence_check`): with the residual window counting
//! every interior voxel (the `fld` module docs, "Residual window") CDA and every FLD limiter
//! stop within 10⁻⁴ of the tight solve everywhere; multigrid still stops far from it on the
//! thick cubes and `shell_core` (marked in the table). The steady RDE, with its error-bound
//! stop (`rde/mod.rs`, "Stopping rule"; its rows re-measured with `--methods rde`), stops
//! within 5·10⁻⁵ everywhere except `shell_core`, where its damped Jacobi reaches the
//! 20 000-step cap 34 % from the tight solve (which itself caps at 200 000 steps). At σt·Δl = 6000
//! the baked source q_ri, evaluated at voxel centres, is 0 (e^(−3000)), so that row is
//! trivially 0.
//!
//! **Outputs**: `convergence_check.csv` (`method, dataset, precision, tolerance, iterations,
//! last_change, stop_reason, rel_l2_to_tight, tight_tolerance, tight_iterations, tight_stop,
//! tight_self_distance, seconds`).

use crate::common::{CommonArgs, Ctx, list_item};
use crate::experiment::{BackendSupport, Experiment, Promise};
use crate::report::{Section, table};
use anyhow::{Context, Result, bail};
use serde::Serialize;
use solvers::method::{self, Fluence, MethodRef, Problem, Tolerance};
use solvers::pipeline::{bake, restrict};
use solvers::scene::{Effect, Scene};
use solvers::{Backend, Medium, Precision};
use std::time::Instant;

/// The methods measured by default: CDA, FLD with each limiter, LBM, the steady RDE and the
/// multigrid variants.
pub const DEFAULT_METHODS: &str = "cda,fld:lp,fld:sum,fld:max,fld:kershaw,fld:larsen2,lbm,rde,\
cda:mg,fld:lp:mg,fld:sum:mg,fld:max:mg,fld:kershaw:mg,fld:larsen2:mg,cda:marshak,fld:lp:marshak";

/// The methods of `--quick`.
pub const QUICK_METHODS: &str = "cda,fld:lp,fld:kershaw,lbm,rde,cda:mg,fld:lp:mg";

/// Flags of `convergence_check`.
#[derive(Debug, Clone, clap::Parser)]
#[command(about = "Distance of each method's default stop to a tightly converged solve")]
pub struct Args {
    /// Shared flags.
    #[command(flatten)]
    pub common: CommonArgs,
    /// Methods (registry names, comma-separated). Default: CDA, every FLD limiter, LBM,
    /// RDE and their multigrid variants (a smaller list with --quick).
    #[arg(long)]
    pub methods: Option<String>,
    /// Scene files of the datasets, comma-separated (default: the atlas's, with --quick
    /// only scenes/nebula.toml).
    #[arg(long)]
    pub scenes: Option<String>,
    /// Downsampling of the datasets' solve (the pipeline's default 4).
    #[arg(long, default_value_t = 4, value_parser = crate::common::count_usize)]
    pub downsample: usize,
    /// Coarsen the datasets first (1: none; default 1, 2 with --quick).
    #[arg(long, value_parser = crate::common::count_usize)]
    pub coarsen: Option<usize>,
    /// σt·Δl of the albedo-1 cubes (solved at downsample 1).
    #[arg(long, value_delimiter = ',', value_parser = list_item::<f64>, default_value = "0.6,6,60,6000")]
    pub cube_tau: Vec<f64>,
    /// Voxels per axis of the cubes (default 16; 8 with --quick).
    #[arg(long, value_parser = crate::common::count_usize)]
    pub cube_n: Option<usize>,
    /// Tolerance of the tight solve (f64); the check solve uses a hundredth of it.
    #[arg(long, default_value_t = 1e-10)]
    pub tight: f64,
    /// Step cap of the tight solve (the check solve gets twice as many). Default 200000
    /// (20000 with --quick).
    #[arg(long, value_parser = crate::common::count_usize)]
    pub tight_steps: Option<usize>,
    /// The tolerance measured (default: the pipeline's, `Tolerance::default().rel`).
    #[arg(long)]
    pub tolerance: Option<f64>,
}

/// One row of `convergence_check.csv`.
#[derive(Debug, Clone, Serialize)]
pub struct Row {
    /// Method name.
    pub method: String,
    /// Dataset (scene stem, or `cube_tau<σt·Δl>`).
    pub dataset: String,
    /// Solve grid voxels per axis (largest).
    pub grid: usize,
    /// `f32` or `f64` (CPU).
    pub precision: String,
    /// The default tolerance rel.
    pub tolerance: f64,
    /// Steps of the default solve.
    pub iterations: usize,
    /// Its last convergence measure.
    pub last_change: f64,
    /// Why it stopped.
    pub stop_reason: String,
    /// ‖φ − φ_tight‖₂/‖φ_tight‖₂.
    pub rel_l2_to_tight: f64,
    /// Tolerance of the tight solve.
    pub tight_tolerance: f64,
    /// The method that made the tight solve.
    pub tight_method: String,
    /// Its steps.
    pub tight_iterations: usize,
    /// Why it stopped.
    pub tight_stop: String,
    /// Relative L2 distance between the tight solve and the check solve at a hundredth of
    /// its tolerance.
    pub tight_self_distance: f64,
    /// For a multigrid method, the distance to its own tight solve (its fixed point); for
    /// the others the same as `rel_l2_to_tight`.
    pub rel_l2_to_own_tight: f64,
    /// Steps and stop of that own tight solve (`steps:stop`).
    pub own_tight: String,
    /// Seconds of the default solve.
    pub seconds: f64,
}

/// One problem: a name and the solve medium (source in its emission).
struct Case {
    name: String,
    medium: Medium<f64>,
    scene: Scene,
}

/// ‖a − b‖₂/‖b‖₂: 0 if both are zero, NaN if only b is or the lengths differ.
pub fn rel_l2(a: &[f64], b: &[f64]) -> f64 {
    if a.len() != b.len() {
        return f64::NAN;
    }
    let d: f64 = a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum();
    let n: f64 = b.iter().map(|y| y * y).sum();
    if d == 0.0 {
        return 0.0;
    }
    (d / n).sqrt()
}

/// The solve medium the pipeline's multiple-scattering pass builds for `scene` (all effects
/// its file allows): q = q_ri of every light, + j if emission is rendered, restricted by
/// `downsample` and padded by one vacuum layer.
pub fn solve_medium(scene: &Scene, with_emission: bool, downsample: usize) -> Result<Medium<f64>> {
    let m = &scene.medium;
    let baked: Vec<bake::BakedLight> = scene
        .lights
        .iter()
        .enumerate()
        .map(|(i, l)| bake::bake(m, i, l).with_context(|| format!("light {i} cannot be baked")))
        .collect::<Result<_>>()?;
    let mut q = bake::q_ri(m, &baked);
    if with_emission {
        q.iter_mut().zip(&m.emission).for_each(|(q, j)| *q += j);
    }
    Ok(restrict::restrict_with(
        m,
        &q,
        downsample,
        1,
        scene.interpolation,
    )?)
}

/// The albedo-1 cube of issue 12 (acceptance 1) with σt·Δl = `tau` on an `n`³ grid.
pub fn lit_cube(n: usize, tau: f64) -> Result<Scene> {
    solvers::scenes::lit_albedo1_cube(n, tau).context("the albedo-1 cube")
}

fn cases(args: &Args, quick: bool) -> Result<Vec<Case>> {
    let coarsen = crate::accuracy_cost::coarsen_factor(args.coarsen, quick)?;
    let default = if quick {
        "scenes/nebula.toml"
    } else {
        crate::accuracy_cost::DEFAULT_SCENES
    };
    let files = crate::accuracy_cost::scene_files(args.scenes.as_deref(), default)?;
    let mut out = Vec::new();
    for f in &files {
        let p = crate::scenes::load(f, coarsen, None)?;
        if !p.effects.contains(Effect::MultipleScattering) {
            continue;
        }
        let Some(scene) = p.channels.first() else {
            bail!("{} has no channel", f.display());
        };
        let medium = solve_medium(scene, p.effects.contains(Effect::Emission), args.downsample)
            .with_context(|| format!("the solve medium of {}", p.name))?;
        out.push(Case {
            name: p.name.clone(),
            medium,
            scene: scene.clone(),
        });
    }
    let n = args.cube_n.unwrap_or(if quick { 8 } else { 16 });
    for &tau in &args.cube_tau {
        if !(tau.is_finite() && tau > 0.0) {
            bail!("--cube-tau: {tau} must be finite and > 0");
        }
        let scene = lit_cube(n, tau)?;
        let medium = solve_medium(&scene, false, 1)?;
        out.push(Case {
            name: format!("cube_tau{tau}"),
            medium,
            scene,
        });
    }
    Ok(out)
}

fn solve(m: &MethodRef, case: &Case, backend: &Backend<'_>, tol: &Tolerance) -> Result<Fluence> {
    let p = Problem {
        medium: &case.medium,
        lights: &case.scene.lights,
        phase: case.scene.phase,
    };
    m.solve(backend, &p, tol, &mut |_, _| {})
        .with_context(|| format!("{} on {}", m.name(), case.name))
}

/// The method that makes the tight solve of `name`: itself, or for `…:mg` the SOR solve of
/// the same equation.
pub fn tight_method(name: &str) -> String {
    name.strip_suffix(":mg").unwrap_or(name).to_string()
}

/// Runs the check; returns its rows.
pub fn run(args: &Args) -> Result<Vec<Row>> {
    crate::experiment::run::<ConvergenceCheck>(args)
}

fn run_in(ctx: &mut Ctx, args: &Args) -> Result<Vec<Row>> {
    let quick = args.common.quick;
    if !(args.tight.is_finite() && args.tight > 0.0 && args.tight < 1e-4) {
        bail!("--tight: {} must be in (0, 1e-4)", args.tight);
    }
    let tight_steps = args
        .tight_steps
        .unwrap_or(if quick { 20_000 } else { 200_000 });
    let list = args.methods.clone().unwrap_or_else(|| {
        if quick {
            QUICK_METHODS
        } else {
            DEFAULT_METHODS
        }
        .to_string()
    });
    let methods: Vec<MethodRef> = list
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| method::parse(s).map(MethodRef::new))
        .collect::<Result<_, _>>()
        .context("--methods")?;
    if methods.is_empty() {
        bail!("--methods: the list is empty");
    }
    let cases = cases(args, quick)?;
    let mut default = Tolerance::default();
    if let Some(t) = args.tolerance {
        if !(t.is_finite() && t > 0.0) {
            bail!("--tolerance: {t} must be finite and > 0");
        }
        default.rel = t;
    }
    let mut work = crate::cost::Estimate::new();
    for c in &cases {
        let n = c.medium.grid.n.iter().copied().max().unwrap_or(1);
        let voxels = c.medium.grid.len() as f64;
        let per = crate::cost::solve_steps(n, default.rel, default.max_steps) * 2.0
            + crate::cost::solve_steps(n, args.tight, tight_steps)
            + crate::cost::solve_steps(n, args.tight * 1e-2, 2 * tight_steps);
        work.add(
            format!("{}: {} methods", c.name, methods.len()),
            per * voxels * methods.len() as f64,
        );
    }
    ctx.start(serde_json::json!({
        "methods": methods.iter().map(|m| m.name()).collect::<Vec<_>>(),
        "datasets": cases.iter().map(|c| c.name.clone()).collect::<Vec<_>>(),
        "downsample": args.downsample, "tight": args.tight, "tight_steps": tight_steps,
        "default_tolerance": default.rel, "default_max_steps": default.max_steps,
    }))?;
    ctx.work(&work)?;
    let f64b = Backend::Cpu(Precision::F64);
    let f32b = Backend::Cpu(Precision::F32);
    let mut rows = Vec::new();
    let pb = ctx.progress((cases.len() * methods.len()) as u64, "convergence_check");
    for c in &cases {
        // Tight solves, one per equation (shared by a method and its multigrid variant).
        let mut tights: Vec<(String, Fluence, f64)> = Vec::new();
        for m in &methods {
            let tname = tight_method(&m.name());
            if !tights.iter().any(|(n, _, _)| *n == tname) {
                let tm = MethodRef::new(method::parse(&tname)?);
                let t0 = Instant::now();
                let a = solve(
                    &tm,
                    c,
                    &f64b,
                    &Tolerance {
                        rel: args.tight,
                        max_steps: tight_steps,
                    },
                )?;
                let b = solve(
                    &tm,
                    c,
                    &f64b,
                    &Tolerance {
                        rel: args.tight * 1e-2,
                        max_steps: 2 * tight_steps,
                    },
                )?;
                ctx.timing(
                    format!("{} tight {tname}", c.name),
                    t0.elapsed().as_secs_f64(),
                );
                let self_d = rel_l2(&a.phi, &b.phi);
                tights.push((tname, a, self_d));
            }
            let Some((tname, tight, self_d)) = tights
                .iter()
                .find(|(n, _, _)| *n == tight_method(&m.name()))
            else {
                bail!("internal: no tight solve of {}", m.name());
            };
            let own = if *tname == m.name() {
                None
            } else {
                let tol = Tolerance {
                    rel: args.tight,
                    max_steps: tight_steps,
                };
                Some(solve(m, c, &f64b, &tol)?)
            };
            for (label, be) in [("f64", &f64b), ("f32", &f32b)] {
                let t0 = Instant::now();
                let s = solve(m, c, be, &default)?;
                let seconds = t0.elapsed().as_secs_f64();
                rows.push(Row {
                    method: m.name(),
                    dataset: c.name.clone(),
                    grid: c.medium.grid.n.iter().copied().max().unwrap_or(0),
                    precision: label.into(),
                    tolerance: default.rel,
                    iterations: s.steps,
                    last_change: s.last_change,
                    stop_reason: s.stop.to_string(),
                    rel_l2_to_tight: rel_l2(&s.phi, &tight.phi),
                    tight_tolerance: args.tight,
                    tight_method: tname.clone(),
                    tight_iterations: tight.steps,
                    tight_stop: tight.stop.to_string(),
                    tight_self_distance: *self_d,
                    rel_l2_to_own_tight: rel_l2(&s.phi, &own.as_ref().unwrap_or(tight).phi),
                    own_tight: own
                        .as_ref()
                        .map_or(String::new(), |o| format!("{}:{}", o.steps, o.stop)),
                    seconds,
                });
            }
            pb.inc(1);
        }
    }
    pb.finish_and_clear();
    ctx.csv("convergence_check.csv", &rows)?;
    Ok(rows)
}

/// Registry entry of `convergence_check`.
#[derive(Debug)]
pub struct ConvergenceCheck;

impl Experiment for ConvergenceCheck {
    const NAME: &'static str = "convergence_check";
    const TITLE: &'static str =
        "How converged is converged: each method's default stop against a tight solve (issue 12)";
    const BACKEND: BackendSupport =
        BackendSupport::CpuOnly("f64 tight solves; the default stop is measured in f32 and f64");
    type Args = Args;
    type Summary = Vec<Row>;

    fn common(args: &Args) -> &CommonArgs {
        &args.common
    }

    fn promises(_args: &Args) -> Vec<Promise> {
        vec![Promise::csv(
            "convergence_check.csv",
            &[
                "method",
                "dataset",
                "precision",
                "tolerance",
                "iterations",
                "last_change",
                "stop_reason",
                "rel_l2_to_tight",
                "tight_iterations",
                "tight_stop",
                "tight_self_distance",
            ],
        )]
    }

    fn run(ctx: &mut Ctx, args: &Args) -> Result<Vec<Row>> {
        run_in(ctx, args)
    }

    fn report(s: &Section<'_>) -> Result<String> {
        let t = s.csv("convergence_check.csv")?;
        t.require(&[
            "method",
            "dataset",
            "precision",
            "iterations",
            "stop_reason",
            "rel_l2_to_tight",
            "tight_stop",
            "tight_self_distance",
        ])?;
        let datasets = t.distinct("dataset");
        let methods = t.distinct("method");
        let mut out = String::from(
            "Relative L2 distance of φ at each method's default stop (the pipeline's \
             `Tolerance::default()`) to a tight f64 solve of the same problem, f64/f32. \
             `*`: above 1 %. The last row is the largest distance between the tight solve and a check solve at a \
             hundredth of its tolerance (how converged the tight solve is). At \
             σt·Δl = 6000 the baked source is 0 (q_ri = σs·E·e^(−τ) at the voxel centres, \
             τ = 3000), so φ = 0 and every distance is 0.\n\n",
        );
        let mut header = vec!["method".to_string()];
        header.extend(datasets.iter().cloned());
        let cell = |m: &str, d: &str, p: &str| {
            t.rows()
                .find(|r| r.get("method") == m && r.get("dataset") == d && r.get("precision") == p)
        };
        let mut rows = Vec::new();
        let mut steps = Vec::new();
        for m in &methods {
            let mut r = vec![format!("`{m}`")];
            let mut st = vec![format!("`{m}`")];
            for d in &datasets {
                let (a, b) = (cell(m, d, "f64"), cell(m, d, "f32"));
                let fmt = |x: Option<crate::report::Row<'_>>| match x {
                    Some(x) => {
                        let v = x.num("rel_l2_to_tight");
                        format!("{v:.0e}{}", if v > 0.01 { "*" } else { "" })
                    }
                    None => "—".into(),
                };
                r.push(format!("{}/{}", fmt(a), fmt(b)));
                st.push(a.map_or("—".into(), |x| match x.get("stop_reason") {
                    "converged" => x.get("iterations").to_string(),
                    why => format!("{} {why}", x.get("iterations")),
                }));
            }
            rows.push(r);
            steps.push(st);
        }
        let mut tight = vec!["tight self-distance".to_string()];
        for d in &datasets {
            let worst = t
                .rows()
                .filter(|r| r.get("dataset") == d)
                .map(|r| r.num("tight_self_distance"))
                .fold(0.0f64, f64::max);
            let capped = t
                .rows()
                .any(|r| r.get("dataset") == d && r.get("tight_stop") != "converged");
            tight.push(format!(
                "{worst:.0e}{}",
                if capped { " (a cap)" } else { "" }
            ));
        }
        rows.push(tight);
        let h: Vec<&str> = header.iter().map(String::as_str).collect();
        out.push_str(&table(&h, rows));
        out.push_str(
            "\nSteps of the default solve (f64) and why it stopped, if not converged:\n\n",
        );
        out.push_str(&table(&h, steps));
        Ok(out)
    }
}
