//! POP Figs 6 and 14 (spec pop.md §3): ordinate count and prefiltering under the project's
//! constant environment, POP's own image (`solvers::pop::upsample::view_image`: the camera
//! as Eq 8's observer, σs·L_acc raymarched with the full-resolution transmittance) against
//! the path tracer's image of the same scene (every order, the environment seen directly
//! hidden), metric the relative RMSE over the pixels √Σ(a − r)²/√Σr² and the ratio of the
//! image means. Two scenes:
//! * **`slab`** (Fig 6: prefiltering): a thin slab 1 × 1 × 0.25 m (16 × 16 × 4 voxels), σt = 4
//!   m⁻¹ (τ = 1 across), albedo 0.99, g ∈ `--slab-g` (default 0.95, 0.99), seen obliquely
//!   from above; POP with N ∈ {8, 27, 64} Fibonacci ordinates, no prefilter (a_n = 1, the ray
//!   effects of Fig 6) vs D11's Voronoi prefilter vs the paper's heuristic (β = 1), converged
//!   (R/P_inj < 10⁻³); 16 cells per ordinate grid.
//! * **`smoke`** (Fig 14: ordinate count): a procedural smoke ball on 48³ voxels (σt up to 20
//!   m⁻¹ in a unit box, a sinusoidal modulation as the "procedural noise"), albedo 0.9,
//!   g = 0.9, N ∈ {8, 27, 64, 125, 216} with the Voronoi prefilter, 12 cells per ordinate
//!   grid (merged 24³ and brought to the 48³ voxels by JBU), at the paper's fixed M = 10
//!   ("10 iterations") and converged; at N = 64 converged also the trilinear and direct
//!   upsampling (W10: what the JBU buys against the path tracer). The stage times of each
//!   render (ordinates, solve, merge + upsampling, raymarch; CPU) stand beside the paper's
//!   Fig 14 breakdown (ordinates 2, grid init + propagation 14, merge + upsampling 4, ray
//!   marching 5 ms on a GTX 770).
//!
//! Outputs: `ordinates.csv`, `error_vs_ordinates.png`, `meta.json`.
//!
//! **Measured** (default flags, f32, 2-vCPU AMD EPYC with other jobs compiling; 14.0 s wall, `--quick` 0.7 s):
//! * slab (Fig 6), relative RMSE vs the path tracer (its own noise 0.042): g = 0.95, N = 8 /
//!   27 / 64: none 0.68 / 1.85 / 0.91, Voronoi 0.63 / 1.16 / 0.69, heuristic 0.61 / 1.20 /
//!   0.70; g = 0.99: none 0.89 / 4.86 / 3.74, Voronoi 0.69 / 2.95 / 2.35, heuristic 0.67 /
//!   3.06 / 2.39. Prefiltering removes 30–40 % of the error, but ray effects stay (W8):
//!   a constant environment's in-scattered radiance is uniform whatever g, while POP sums N
//!   lobes HG(u, a_n g) whose peaks (a_n = 1 − 1/N: HG(1, 0.953) = 71/sr at N = 27, g = 0.99)
//!   are far sharper than the caps they stand for (27/4π = 2.1/sr). The paper's β = 1
//!   heuristic and D11 differ by ≤ 0.04.
//! * smoke (Fig 14), JBU: N = 8 / 27 / 64 / 125 / 216 at M = 10: 0.23 / 0.34 / 0.072 / 0.093 /
//!   0.098 (mean ratio 0.88–1.17); converged 0.25 / 0.41 / 0.16 / 0.17 / 0.17 (mean ratio
//!   1.09–1.28; path-tracer noise 0.032). More than 64 ordinates does not help: the error is
//!   POP's (W2's over-bright lattice walk once converged, W5's truncation at M = 10, which
//!   here happen to cancel). At N = 64 converged: JBU 0.157, trilinear 0.155, direct 0.154:
//!   the guided upsampling buys nothing against the path tracer on this medium (W10).
//! * Stage times at N = 64, M = 10: ordinates 0.2 ms, solve 0.17 s, merge + JBU 0.18 s,
//!   raymarch 1.4 ms (32² pixels) — the paper's Fig 14 on a GTX 770: 2, 14, 4 and 5 ms.

use crate::common::{CommonArgs, Ctx};
use crate::experiment::{BackendSupport, Experiment, Promise};
use crate::images::relative_rmse;
use crate::plot::{Axis, Series, Style, plot};
use crate::report::{Section, table};
use anyhow::{Context, Result, bail};
use reference::pathtracer::{Contributions, RenderSettings, render_image};
use serde::Serialize;
use solvers::pop::upsample::view_image;
use solvers::pop::{PopConfig, Prefilter, Upsample, environment_ordinates};
use solvers::scene::{Camera, Light, Phase, Projection, Sampler, Scene};
use solvers::{Grid, Medium};
use std::time::Instant;

/// Flags of `pop_ordinates`.
#[derive(Debug, Clone, clap::Parser)]
#[command(
    about = "POP Figs 6 and 14: ordinate count and prefiltering under a constant environment"
)]
pub struct Args {
    /// Shared flags.
    #[command(flatten)]
    pub common: CommonArgs,
    /// g of the slab scene (Fig 6), each in [0, 1).
    #[arg(long, value_delimiter = ',', value_parser = crate::common::list_item::<f64>, default_value = "0.95,0.99")]
    pub slab_g: Vec<f64>,
    /// Ordinate counts of the smoke scene (Fig 14; default 8,27,64,125,216; 8,27 with --quick).
    #[arg(long, value_delimiter = ',', value_parser = crate::common::list_item::<usize>)]
    pub ordinates: Option<Vec<usize>>,
    /// Path-tracer samples per pixel (default 256; 16 with --quick).
    #[arg(long)]
    pub spp: Option<u32>,
    /// Image width and height in pixels (default 32; 16 with --quick).
    #[arg(long)]
    pub resolution: Option<usize>,
    /// Seed of the path tracer.
    #[arg(long, default_value_t = 6)]
    pub seed: u64,
}

/// One POP render of `ordinates.csv`.
#[derive(Debug, Clone, Serialize)]
pub struct OrdinateRow {
    /// `slab` (Fig 6) or `smoke` (Fig 14).
    pub scene: String,
    /// HG g.
    pub g: f64,
    /// `none`, `voronoi` or `heuristic`.
    pub prefilter: String,
    /// Ordinates N.
    pub ordinates: usize,
    /// `converged` (R/P_inj < 10⁻³) or `M=<k>` (the paper's fixed count).
    pub iterations: String,
    /// `direct`, `trilinear` or `jbu`.
    pub upsample: String,
    /// Propagation steps run (largest over the ordinates).
    pub steps: usize,
    /// Power still in flight / injected at the end (largest over the ordinates).
    pub residual: f64,
    /// Relative RMSE of POP's image vs the path tracer's.
    pub rel_rmse: f64,
    /// The path tracer's own noise in the same metric (√Σse²/√Σr²).
    pub pt_noise: f64,
    /// Mean of POP's image / mean of the path tracer's.
    pub mean_ratio: f64,
    /// Seconds: ordinates (prefilter).
    pub seconds_ordinates: f64,
    /// Seconds: solve (grids, resampling, injection, propagation).
    pub seconds_solve: f64,
    /// Seconds: merge and upsampling.
    pub seconds_merge: f64,
    /// Seconds: raymarch.
    pub seconds_march: f64,
}

/// Runs the experiment.
pub fn run(args: &Args) -> Result<Vec<OrdinateRow>> {
    crate::experiment::run::<PopOrdinates>(args)
}

/// The paper's fixed iteration count of Fig 14.
pub const PAPER_M: usize = 10;

/// The relative stop of the converged runs.
pub const TOLERANCE: f64 = 1e-3;

fn slab_medium() -> Result<Medium<f64>> {
    Ok(Medium::homogeneous(
        Grid::new([16, 16, 4], 1.0 / 16.0)?,
        4.0,
        0.99,
    )?)
}

/// The smoke ball: σt = 20·(1 − r/0.45)·(1 + 0.6 sin 9x sin 11y sin 13z) inside r < 0.45 of
/// the unit box's centre, 0 outside; albedo 0.9.
fn smoke_medium(n: usize) -> Result<Medium<f64>> {
    let grid = Grid::cube(n, 1.0)?;
    let sigma_t = grid.sample(|p| {
        let r = ((p[0] - 0.5).powi(2) + (p[1] - 0.5).powi(2) + (p[2] - 0.5).powi(2)).sqrt();
        let noise = 1.0 + 0.6 * (9.0 * p[0]).sin() * (11.0 * p[1]).sin() * (13.0 * p[2]).sin();
        (20.0 * (1.0 - r / 0.45)).max(0.0) * noise
    });
    let albedo = vec![0.9; grid.len()];
    let emission = vec![0.0; grid.len()];
    Ok(Medium::new(grid, sigma_t, albedo, emission)?)
}

fn camera(eye: [f64; 3], target: [f64; 3], res: usize) -> Camera {
    Camera {
        eye,
        target,
        up: [0.0, 0.0, 1.0],
        projection: Projection::Perspective {
            fov_y_degrees: 40.0,
        },
        resolution: [res, res],
        hide_background: true,
    }
}

struct Reference {
    mean: Vec<f64>,
    noise: f64,
}

fn reference(medium: &Medium<f64>, g: f64, cam: Camera, spp: u32, seed: u64) -> Result<Reference> {
    let scene = Scene {
        medium: medium.clone(),
        phase: Phase::HenyeyGreenstein { g },
        lights: vec![Light::Environment { radiance: 1.0 }],
        camera: Some(cam),
        sampler: Sampler { spp, seed },
        interpolation: Default::default(),
    };
    let img = render_image(
        &scene,
        &RenderSettings {
            spp,
            seed,
            batches: 16,
            contributions: Contributions::all(),
        },
    )
    .context("path-traced reference")?;
    let den: f64 = img.mean.iter().map(|r| r * r).sum();
    let var: f64 = img.stderr.iter().map(|s| s * s).sum();
    Ok(Reference {
        noise: (var / den).sqrt(),
        mean: img.mean,
    })
}

struct Case<'a> {
    scene: &'static str,
    medium: &'a Medium<f64>,
    g: f64,
    cam: Camera,
    cells: usize,
    reference: &'a Reference,
}

fn render(
    case: &Case<'_>,
    prefilter: (Prefilter, &str),
    n: usize,
    fixed_m: Option<usize>,
    upsample: (Upsample, &str),
) -> Result<OrdinateRow> {
    let t0 = Instant::now();
    let ords = environment_ordinates(|_| 1.0, n, prefilter.0, 32)?;
    let seconds_ordinates = t0.elapsed().as_secs_f64();
    let config = match fixed_m {
        Some(m) => PopConfig::fixed::<f32>(case.cells, m),
        None => PopConfig {
            tolerance: TOLERANCE,
            ..PopConfig::new::<f32>(case.cells)
        },
    };
    let img = view_image::<f32>(
        case.medium,
        case.g,
        &ords,
        &config,
        &case.cam,
        upsample.0,
        0.5,
        1,
    )?;
    let r = &case.reference.mean;
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    Ok(OrdinateRow {
        scene: case.scene.into(),
        g: case.g,
        prefilter: prefilter.1.into(),
        ordinates: n,
        iterations: fixed_m.map_or("converged".into(), |m| format!("M={m}")),
        upsample: upsample.1.into(),
        steps: img.steps,
        residual: img.residual,
        rel_rmse: relative_rmse(&[&img.pixels], &[r]),
        pt_noise: case.reference.noise,
        mean_ratio: mean(&img.pixels) / mean(r),
        seconds_ordinates,
        seconds_solve: img.seconds[0],
        seconds_merge: img.seconds[1],
        seconds_march: img.seconds[2],
    })
}

fn run_in(ctx: &mut Ctx, args: &Args) -> Result<Vec<OrdinateRow>> {
    let quick = args.common.quick;
    let counts = args.ordinates.clone().unwrap_or(if quick {
        vec![8, 27]
    } else {
        vec![8, 27, 64, 125, 216]
    });
    let spp = args.spp.unwrap_or(if quick { 16 } else { 256 });
    let res = args.resolution.unwrap_or(if quick { 16 } else { 32 });
    let smoke_n = if quick { 24 } else { 48 };
    let slab_counts: Vec<usize> = if quick { vec![8] } else { vec![8, 27, 64] };
    if counts.is_empty() || counts.iter().any(|&n| !(1..=1024).contains(&n)) {
        bail!("--ordinates: each in [1, 1024]");
    }
    if args.slab_g.iter().any(|g| !(0.0..1.0).contains(g)) {
        bail!("--slab-g: each g in [0, 1)");
    }
    if !(16..=1 << 20).contains(&spp) {
        bail!("--spp must be in [16, 2^20], got {spp}");
    }
    if !(4..=512).contains(&res) {
        bail!("--resolution must be in [4, 512], got {res}");
    }
    let mut work = crate::cost::Estimate::new();
    let smoke_ords: usize = counts.iter().sum();
    work.add(
        format!("smoke: {smoke_ords} ordinates × 12³ × ≈ 150 steps, twice"),
        2.0 * smoke_ords as f64 * 1728.0 * 150.0 * 40.0,
    );
    work.add(
        "path tracer: 1 + slab g images",
        (1 + args.slab_g.len()) as f64 * (res * res) as f64 * spp as f64 * 2000.0,
    );
    ctx.work(&work)?;
    ctx.start(serde_json::json!({
        "slab": {"voxels": [16, 16, 4], "dl": 1.0 / 16.0, "sigma_t": 4.0, "albedo": 0.99,
                 "g": args.slab_g, "cells": 16, "ordinates": slab_counts},
        "smoke": {"voxels": smoke_n, "albedo": 0.9, "g": 0.9, "cells": 12,
                  "ordinates": counts, "paper_m": PAPER_M},
        "tolerance": TOLERANCE, "spp": spp, "resolution": res, "seed": args.seed,
        "environment_radiance": 1.0, "precision": "f32",
    }))?;
    let slab = slab_medium()?;
    let smoke = smoke_medium(smoke_n)?;
    let slab_cam = camera([0.5, -0.9, 1.4], [0.5, 0.5, 0.125], res);
    let smoke_cam = camera([0.5, -1.8, 0.9], [0.5, 0.5, 0.5], res);
    let prefilters = [
        (Prefilter::None, "none"),
        (Prefilter::Voronoi, "voronoi"),
        (Prefilter::Heuristic { beta: 1.0 }, "heuristic"),
    ];
    let total = args.slab_g.len() * slab_counts.len() * prefilters.len() + 2 * counts.len() + 2;
    let pb = ctx.progress(total as u64, "pop_ordinates");
    let mut rows = Vec::new();
    for &g in &args.slab_g {
        pb.set_message(format!("slab g = {g}: path tracer"));
        let r = reference(&slab, g, slab_cam, spp, args.seed)?;
        let case = Case {
            scene: "slab",
            medium: &slab,
            g,
            cam: slab_cam,
            cells: 16,
            reference: &r,
        };
        for &pf in &prefilters {
            for &n in &slab_counts {
                pb.set_message(format!("slab g = {g}, {}, N = {n}", pf.1));
                rows.push(render(&case, pf, n, None, (Upsample::Jbu, "jbu"))?);
                pb.inc(1);
            }
        }
    }
    pb.set_message("smoke: path tracer");
    let r = reference(&smoke, 0.9, smoke_cam, spp, args.seed)?;
    let case = Case {
        scene: "smoke",
        medium: &smoke,
        g: 0.9,
        cam: smoke_cam,
        cells: 12,
        reference: &r,
    };
    let voronoi = (Prefilter::Voronoi, "voronoi");
    for &n in &counts {
        for m in [Some(PAPER_M), None] {
            pb.set_message(format!("smoke N = {n}, {m:?}"));
            rows.push(render(&case, voronoi, n, m, (Upsample::Jbu, "jbu"))?);
            pb.inc(1);
        }
    }
    let n_up = if counts.contains(&64) { 64 } else { counts[0] };
    for up in [
        (Upsample::Trilinear, "trilinear"),
        (Upsample::Direct, "direct"),
    ] {
        pb.set_message(format!("smoke N = {n_up}, {}", up.1));
        rows.push(render(&case, voronoi, n_up, None, up)?);
        pb.inc(1);
    }
    pb.finish_and_clear();
    ctx.csv("ordinates.csv", &rows)?;
    let mut series = Vec::new();
    let mut keys: Vec<(String, f64, String, String)> = Vec::new();
    for r in rows.iter().filter(|r| r.upsample == "jbu") {
        let key = (
            r.scene.clone(),
            r.g,
            r.prefilter.clone(),
            r.iterations.clone(),
        );
        if !keys.contains(&key) {
            keys.push(key);
        }
    }
    for (c, key) in keys.iter().enumerate() {
        let pts: Vec<(f64, f64)> = rows
            .iter()
            .filter(|r| {
                r.upsample == "jbu"
                    && r.scene == key.0
                    && r.g == key.1
                    && r.prefilter == key.2
                    && r.iterations == key.3
            })
            .map(|r| (r.ordinates as f64, r.rel_rmse))
            .collect();
        series.push(Series::new(
            format!("{} g={} {} {}", key.0, key.1, key.2, key.3),
            pts,
            if key.0 == "smoke" {
                Style::Line
            } else {
                Style::Dashed
            },
            c,
        ));
    }
    plot(
        &ctx.path("error_vs_ordinates.png"),
        "POP Figs 6/14: image error vs the path tracer by ordinate count",
        &Axis::log("ordinates N"),
        &Axis::log("relative RMSE vs path tracer"),
        &series,
    )?;
    Ok(rows)
}

/// POP Figs 6 and 14 in the registry.
#[derive(Debug)]
pub struct PopOrdinates;

const COLUMNS: [&str; 15] = [
    "scene",
    "g",
    "prefilter",
    "ordinates",
    "iterations",
    "upsample",
    "steps",
    "residual",
    "rel_rmse",
    "pt_noise",
    "mean_ratio",
    "seconds_ordinates",
    "seconds_solve",
    "seconds_merge",
    "seconds_march",
];

impl Experiment for PopOrdinates {
    const NAME: &'static str = "pop_ordinates";
    const TITLE: &'static str =
        "POP Figs 6 and 14: ordinate count and prefiltering under a constant environment";
    const BACKEND: BackendSupport =
        BackendSupport::CpuOnly("POP's image (merge, JBU, raymarch) runs on the CPU");
    type Args = Args;
    type Summary = Vec<OrdinateRow>;

    fn common(args: &Args) -> &CommonArgs {
        &args.common
    }

    fn promises(_args: &Args) -> Vec<Promise> {
        vec![
            Promise::csv("ordinates.csv", &COLUMNS),
            Promise::file("error_vs_ordinates.png"),
        ]
    }

    fn run(ctx: &mut Ctx, args: &Args) -> Result<Self::Summary> {
        run_in(ctx, args)
    }

    fn report(s: &Section<'_>) -> Result<String> {
        let t = s.csv("ordinates.csv")?;
        t.require(&COLUMNS)?;
        let mut out = String::from(
            "POP's own image under a unit constant environment against the path tracer (every order, \
             environment hidden): relative RMSE over the pixels and the ratio of image means. `slab`: Fig 6's \
             prefiltering (none = a_n 1, voronoi = D11, heuristic = the paper's β = 1), converged. `smoke`: Fig 14's \
             ordinate count at the paper's M = 10 and converged, JBU upsampling, plus trilinear and direct at one N. \
             Times are CPU seconds per stage (f32, 2 cores).\n\n",
        );
        out.push_str(&table(
            &[
                "scene",
                "g",
                "prefilter",
                "N",
                "iterations",
                "upsample",
                "steps",
                "rel RMSE",
                "PT noise",
                "mean ratio",
                "solve s",
                "merge s",
                "march s",
            ],
            t.rows().map(|r| {
                vec![
                    r.get("scene").to_string(),
                    r.get("g").to_string(),
                    r.get("prefilter").to_string(),
                    r.get("ordinates").to_string(),
                    r.get("iterations").to_string(),
                    r.get("upsample").to_string(),
                    r.get("steps").to_string(),
                    r.fixed("rel_rmse", 3),
                    r.fixed("pt_noise", 3),
                    r.fixed("mean_ratio", 3),
                    r.fixed("seconds_solve", 3),
                    r.fixed("seconds_merge", 3),
                    r.fixed("seconds_march", 3),
                ]
            }),
        ));
        out.push('\n');
        out.push_str(&s.png("error_vs_ordinates.png"));
        Ok(out)
    }
}
