//! Issue 12's emissive albedo-1 row, re-measured (acceptance 2): a 16³ homogeneous cube
//! (extent 1), albedo 1, emission j = 1, no lights, perspective 16×16 camera; the grid
//! pipeline with each `--methods` entry at downsampling 1…4 against the path tracer.
//!
//! With σa = 0 every unit of emitted power leaves the cube (1 in total), so each face emits
//! 1/6 and a Lambertian face has radiance 1/(6π) ≈ 0.053 (issue 12's "energy balance says
//! ≈ 0.053"); the image mean also counts background pixels, so the path tracer is the
//! reference. The solvers conserve that power (`solvers/tests/energy_balance.rs`); what the
//! image sees is φ within a mean free path of the surface, which the medium–vacuum face
//! coefficient sets (see the `fld` module docs).
//!
//! **Outputs**: `emissive_cube.csv` (`sigma_t, method, downsample, mean, stderr, rel_to_pt,
//! steps, stop`); the path tracer's rows have method `pt`, downsample 0.

use crate::common::{CommonArgs, Ctx, list_item};
use crate::experiment::{BackendSupport, Experiment, Promise};
use crate::methods::Renderer;
use crate::report::{Section, table};
use anyhow::{Context, Result, bail};
use reference::effects::{components_from_parts, render_components_part};
use reference::pathtracer::{Contributions, RenderSettings};
use serde::Serialize;
use solvers::pipeline::{self, PipelineConfig};
use solvers::scene::SceneFile;
use solvers::{Backend, Precision};
use std::path::Path;

/// Flags of `emissive_cube`.
#[derive(Debug, Clone, clap::Parser)]
#[command(about = "Issue 12's emissive albedo-1 cube: grid pipeline vs the path tracer")]
pub struct Args {
    /// Shared flags.
    #[command(flatten)]
    pub common: CommonArgs,
    /// Extinctions σt of the cube (extent 1, 16³: σt·Δl = σt/16).
    #[arg(long, value_delimiter = ',', value_parser = list_item::<f64>, default_value = "100,1000")]
    pub sigma_t: Vec<f64>,
    /// Grid methods (registry names, comma-separated).
    #[arg(long, default_value = "fld:lp,cda,lbm,fld:lp:marshak,cda:marshak")]
    pub methods: String,
    /// Downsampling factors of the diffusion solve (default 1,2,3,4; 1,4 with --quick).
    #[arg(long, value_delimiter = ',', value_parser = list_item::<usize>)]
    pub downsample: Option<Vec<usize>>,
    /// Path-tracer samples per pixel (≥ 16; default 1024, 16 with --quick).
    #[arg(long, value_parser = crate::common::count_u32)]
    pub spp: Option<u32>,
    /// The σt up to which the path tracer runs (its cost grows like σt²; above it the row
    /// is left out). Default 1000.
    #[arg(long, default_value_t = 1000.0)]
    pub pt_max_sigma_t: f64,
    /// Voxels per axis (default 16; 8 with --quick).
    #[arg(long, value_parser = crate::common::count_usize)]
    pub n: Option<usize>,
    /// Seed of the path tracer.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// The grid methods' tolerance (`Tolerance::rel`; default the pipeline's 10⁻⁴): a
    /// smaller one measures how much of a gap is under-convergence.
    #[arg(long, default_value_t = solvers::method::Tolerance::default().rel)]
    pub tol: f64,
    /// The grid methods' step cap (default the pipeline's 20 000).
    #[arg(long, default_value_t = solvers::method::Tolerance::default().max_steps)]
    pub max_steps: usize,
}

/// One row of `emissive_cube.csv`.
#[derive(Debug, Clone, Serialize)]
pub struct Row {
    /// Extinction.
    pub sigma_t: f64,
    /// `pt` or a grid method.
    pub method: String,
    /// Downsampling (0 for the path tracer).
    pub downsample: usize,
    /// Image mean of the total image.
    pub mean: f64,
    /// Its standard error (0 for grid methods).
    pub stderr: f64,
    /// mean / the path tracer's mean − 1 (NaN without a path-tracer row).
    pub rel_to_pt: f64,
    /// Steps of the diffusion solve.
    pub steps: usize,
    /// Its stop.
    pub stop: String,
}

/// The scene file of the emissive cube.
pub fn cube_file(n: usize, sigma_t: f64) -> Result<SceneFile> {
    let text = format!(
        r#"
format = 1
[medium]
generator = "homogeneous"
params = {{ n = {n}, extent = 1.0, sigma_t = {sigma_t}, albedo = 1.0 }}
emission = 1.0
[camera]
eye = [0.5, -1.5, 0.8]
target = [0.5, 0.5, 0.5]
up = [0.0, 0.0, 1.0]
projection = "perspective"
fov_y = 50.0
resolution = [16, 16]
"#
    );
    SceneFile::parse(&text, Path::new("."), Path::new("emissive_cube.toml"))
        .context("the emissive cube")
}

/// Runs it; returns its rows.
pub fn run(args: &Args) -> Result<Vec<Row>> {
    crate::experiment::run::<EmissiveCube>(args)
}

fn run_in(ctx: &mut Ctx, args: &Args) -> Result<Vec<Row>> {
    let quick = args.common.quick;
    let n = args.n.unwrap_or(if quick { 8 } else { 16 });
    let spp = args.spp.unwrap_or(if quick { 16 } else { 1024 });
    if spp < reference::pathtracer::MIN_BATCHES {
        bail!(
            "--spp {spp}: at least {}",
            reference::pathtracer::MIN_BATCHES
        );
    }
    let ds = args
        .downsample
        .clone()
        .unwrap_or(if quick { vec![1, 4] } else { vec![1, 2, 3, 4] });
    if ds.contains(&0) {
        bail!("--downsample: factors are ≥ 1");
    }
    let methods: Vec<_> = args
        .methods
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(Renderer::parse)
        .collect::<Result<_>>()
        .context("--methods")?;
    let mut files = Vec::new();
    for &s in &args.sigma_t {
        if !(s.is_finite() && s > 0.0) {
            bail!("--sigma-t: {s} must be finite and > 0");
        }
        files.push((s, cube_file(n, s)?));
    }
    let mut work = crate::cost::Estimate::new();
    for (s, f) in &files {
        let chans = f.channels();
        let (_, effects) = pipeline::effects_of(&chans, &f.effects, &PipelineConfig::default())?;
        if *s <= args.pt_max_sigma_t {
            work.add(
                format!("σt = {s}: path tracer, {spp} spp"),
                crate::cost::pt_render(&chans, &effects, spp),
            );
        }
        for m in &methods {
            if let Renderer::Pipeline(r) = m {
                for &d in &ds {
                    work.add(
                        format!("σt = {s}: {r} ds {d}"),
                        crate::cost::pipeline_render(
                            &chans,
                            &crate::accuracy_cost::grid_config(r, d, 1e-4),
                        ),
                    );
                }
            }
        }
    }
    ctx.start(serde_json::json!({
        "sigma_t": args.sigma_t, "n": n, "spp": spp, "downsample": ds,
        "methods": methods.iter().map(Renderer::name).collect::<Vec<_>>(),
        "pt_max_sigma_t": args.pt_max_sigma_t, "seed": args.seed,
    }))?;
    ctx.work(&work)?;
    let mut rows = Vec::new();
    for (s, f) in &files {
        let scene = &f.scene;
        let chans = f.channels();
        let (_, effects) = pipeline::effects_of(&chans, &f.effects, &PipelineConfig::default())?;
        let mut pt_mean = f64::NAN;
        if *s <= args.pt_max_sigma_t {
            let settings = RenderSettings {
                spp,
                seed: args.seed,
                batches: reference::pathtracer::MIN_BATCHES,
                contributions: Contributions::all(),
            };
            let what = format!("path tracer, σt = {s}");
            let got = ctx.tally(
                &what,
                |shard| {
                    render_components_part(scene, &effects, &settings, shard)
                        .with_context(|| what.clone())
                },
                |parts| Ok(components_from_parts(scene, &effects, parts)?),
            )?;
            if let Some(c) = got {
                let np = c.total.mean.len() as f64;
                pt_mean = c.total.mean.iter().sum::<f64>() / np;
                let se = c.total.stderr.iter().map(|x| x * x).sum::<f64>().sqrt() / np;
                rows.push(Row {
                    sigma_t: *s,
                    method: "pt".into(),
                    downsample: 0,
                    mean: pt_mean,
                    stderr: se,
                    rel_to_pt: 0.0,
                    steps: 0,
                    stop: String::new(),
                });
            }
        }
        for m in &methods {
            let Renderer::Pipeline(r) = m else {
                continue;
            };
            for &d in &ds {
                let cfg = crate::accuracy_cost::grid_config(r, d, 1e-4);
                let cfg = PipelineConfig {
                    tolerance: solvers::method::Tolerance {
                        rel: args.tol,
                        max_steps: args.max_steps,
                    },
                    ..cfg
                };
                let out = pipeline::render_file(f, &cfg, &Backend::Cpu(Precision::F64))
                    .with_context(|| format!("{r} at downsample {d}, σt = {s}"))?;
                let img = &out.channels[0].total;
                let mean = img.iter().sum::<f64>() / img.len() as f64;
                let (steps, stop) = out
                    .diffusion
                    .first()
                    .map_or((0, String::new()), |d| (d.steps, d.stop.to_string()));
                rows.push(Row {
                    sigma_t: *s,
                    method: r.name(),
                    downsample: d,
                    mean,
                    stderr: 0.0,
                    rel_to_pt: mean / pt_mean - 1.0,
                    steps,
                    stop,
                });
            }
        }
    }
    ctx.csv("emissive_cube.csv", &rows)?;
    Ok(rows)
}

/// Registry entry of `emissive_cube`.
#[derive(Debug)]
pub struct EmissiveCube;

impl Experiment for EmissiveCube {
    const NAME: &'static str = "emissive_cube";
    const TITLE: &'static str =
        "Emissive albedo-1 cube (issue 12): grid pipeline at downsampling 1-4 vs the path tracer";
    const BACKEND: BackendSupport =
        BackendSupport::CpuOnly("f64 grid renders against the path tracer");
    type Args = Args;
    type Summary = Vec<Row>;

    fn common(args: &Args) -> &CommonArgs {
        &args.common
    }

    fn promises(_args: &Args) -> Vec<Promise> {
        vec![Promise::csv(
            "emissive_cube.csv",
            &[
                "sigma_t",
                "method",
                "downsample",
                "mean",
                "stderr",
                "rel_to_pt",
                "steps",
                "stop",
            ],
        )]
    }

    fn run(ctx: &mut Ctx, args: &Args) -> Result<Vec<Row>> {
        run_in(ctx, args)
    }

    fn report(s: &Section<'_>) -> Result<String> {
        let t = s.csv("emissive_cube.csv")?;
        t.require(&["sigma_t", "method", "downsample", "mean", "stderr"])?;
        let mut out = String::from(
            "Image mean of the emissive albedo-1 cube (no lights, j = 1; the energy balance \
             puts a Lambertian face at 1/(6π) ≈ 0.053) for each grid method (CPU f64, the \
             default tolerance) at each downsampling, and the path tracer's mean ± its \
             standard error:\n\n",
        );
        let sigmas = t.distinct("sigma_t");
        let ds: Vec<String> = t
            .distinct("downsample")
            .into_iter()
            .filter(|d| d != "0")
            .collect();
        let mut header = vec!["σt".to_string(), "method".to_string()];
        header.extend(ds.iter().map(|d| format!("ds {d}")));
        let mut rows = Vec::new();
        for sg in &sigmas {
            if let Some(p) = t
                .rows()
                .find(|r| r.get("sigma_t") == sg && r.get("method") == "pt")
            {
                let mut r = vec![sg.clone(), "`pt`".into()];
                r.push(format!("{:.4} ± {:.4}", p.num("mean"), p.num("stderr")));
                r.extend(std::iter::repeat_n(
                    String::new(),
                    ds.len().saturating_sub(1),
                ));
                rows.push(r);
            }
            for m in t.distinct("method").iter().filter(|m| *m != "pt") {
                let mut r = vec![sg.clone(), format!("`{m}`")];
                for d in &ds {
                    r.push(
                        t.rows()
                            .find(|x| {
                                x.get("sigma_t") == sg
                                    && x.get("method") == m
                                    && x.get("downsample") == d
                            })
                            .map_or("—".into(), |x| {
                                let v = x.num("mean");
                                if v.abs() < 1e-3 {
                                    format!("{v:.2e}")
                                } else {
                                    format!("{v:.4}")
                                }
                            }),
                    );
                }
                rows.push(r);
            }
        }
        let h: Vec<&str> = header.iter().map(String::as_str).collect();
        out.push_str(&table(&h, rows));
        Ok(out)
    }
}
