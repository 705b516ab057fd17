//! `render`: one scene file, one method → images, the plan and the timings.
//!
//! `--scene FILE --method pt|<registered method> --backend cpu|gpu --out DIR [--explain]`
//! renders the scene's camera image with the grid pipeline (`solvers::pipeline`: light
//! baking and raymarching on the CPU, the multiple-scattering solve with any method of
//! `solvers::method::METHODS` — `cda`, `fld[:limiter]`, `lbm`, … — on `--backend`) or with the path
//! tracer (`--method pt`, on exactly the effects the grid pipeline would render, via
//! `reference::effects`). The scene's `[effects]` table restricts what is rendered.
//!
//! Writes to `--out` (default `results/render/`) what the scene's `[outputs] write` lists
//! (default: the image):
//! * `image`: `image.pfm` (radiance in physical units, 1 or 3 channels) and `image.png` (gamma 2.2,
//!   white at the 99th percentile of the total image's largest channel);
//! * per component that ran, `single.*`, `multiple.*`, `emission.*` (same exposure);
//!   path tracer: also `image_stderr.pfm` (per-pixel standard errors);
//! * `fluence`: `fluence.vol`, a Mitsuba `.vol` grid of φ of the multiple-scattering solve on
//!   its solve grid (restricted and padded; the file's box is that grid's box), one channel
//!   per colour channel (1 or 3). Grid methods only: the path tracer's camera render has no
//!   fluence grid, and a plan without a multiple-scattering solve has no φ (both errors);
//!
//! and always:
//! * `plan.json`: method, effects, the plan (passes with why, skipped passes with why), the
//!   passes that ran with their seconds, and the multiple-scattering solves (method, grid,
//!   steps, last change, stop reason, seconds);
//! * `passes.csv`: `pass,channel,seconds`;
//! * `meta.json`: command, parameters, git revision, machine, timings.
//!
//! `--explain` prints the plan (and why each pass runs or not) before rendering.
//! `--quick` caps the image at 24×24 pixels and the path tracer at 16 samples per pixel.

use crate::common::{BackendArgs, CommonArgs, Output, PrecisionArg, value_names};
use crate::methods::Renderer;
use anyhow::{Context, Result, bail};
use plotters::prelude::*;
use reference::effects::{Component, components_from_parts, render_components_part};
use reference::pathtracer::{Contributions, RenderSettings};
use serde::Serialize;
use solvers::Precision;
use solvers::method::{Params, Tolerance};
use solvers::pipeline::{self, PipelineConfig, Shadows};
use solvers::scene::vol::VolGrid;
use solvers::scene::{OutputKind, Scene, SceneFile};
use std::path::{Path, PathBuf};

/// A `--shadows` value.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ShadowsArg {
    /// Exact shadow rays.
    Exact,
    /// The paper's deep shadow map.
    Dsm,
}

/// Flags of `render`.
#[derive(Debug, Clone, clap::Parser)]
#[command(
    about = "Render a scene file with the path tracer or the grid pipeline (any registered method)",
    allow_negative_numbers = true
)]
pub struct Args {
    /// Shared flags.
    #[command(flatten)]
    pub common: CommonArgs,
    /// Backend of the diffusion solve.
    #[command(flatten)]
    pub backend: BackendArgs,
    /// The scene file.
    #[arg(long)]
    pub scene: PathBuf,
    /// `pt` (path tracer) or a registered method (`cda`, `fld` = `fld:lp`, `fld:<limiter>`,
    /// `lbm`, …; case-insensitive).
    #[arg(long, default_value = "fld", long_help = crate::methods::help())]
    pub method: String,
    /// Print the plan and why each pass runs or not.
    #[arg(long)]
    pub explain: bool,
    /// Path-tracer samples per pixel (default: the scene's `[sampler] spp`; at least 16,
    /// the batches of the per-pixel standard errors). Path tracer only.
    #[arg(long, value_parser = crate::common::count_u32)]
    pub spp: Option<u32>,
    /// Path-tracer seed (default: the scene's `[sampler] seed`). Path tracer only.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Downsampling factor of the diffusion grid (default 4; every axis keeps at least 4
    /// voxels). Grid methods only.
    #[arg(long, value_parser = crate::common::count_usize)]
    pub downsample: Option<usize>,
    /// CPU precision of the diffusion solve (`f32` or `f64`, default f64; the GPU is f32).
    /// Grid methods on the CPU only.
    #[arg(long, value_enum)]
    pub precision: Option<PrecisionArg>,
    /// Raymarch sub-step as a fraction of a voxel (default 0.5; in [1e-3, 1]). Grid methods
    /// only.
    #[arg(long)]
    pub step: Option<f64>,
    /// Stratified rays per pixel and axis in the raymarch (default 1; at most 64). Grid
    /// methods only.
    #[arg(long, value_parser = crate::common::count_usize)]
    pub pixel_samples: Option<usize>,
    /// `exact` shadow rays (default) or the paper's `dsm` (deep shadow map) in single
    /// scattering. Grid methods only.
    #[arg(long, value_enum)]
    pub shadows: Option<ShadowsArg>,
    /// SOR factor of CDA/FLD (the method parameter `omega`; default 1.8).
    #[arg(long)]
    pub omega: Option<f64>,
    /// Method parameters, `name=value`, comma-separated (e.g. `omega=1.5,theta=1`); each
    /// method lists those it accepts in its error.
    #[arg(long, value_delimiter = ',')]
    pub param: Vec<String>,
    /// Stop the multiple-scattering solve at this tolerance (one meaning for every method,
    /// `solvers::method::Tolerance`; for CDA/FLD the normalised residual R̄/j̄, the paper's
    /// 10⁻⁴, the default; 0 runs exactly --max-iterations steps). Grid methods only.
    #[arg(long)]
    pub tolerance: Option<f64>,
    /// Step cap of the multiple-scattering solve (default 20000; a solve that hits it is
    /// reported in plan.json). Grid methods only.
    #[arg(long, value_parser = crate::common::count_usize)]
    pub max_iterations: Option<usize>,
    /// Solver of a `cda`/`fld` method: `sor` (red-black SOR, FLD Algorithm 1, the default),
    /// `multigrid` (FAS F(2,2), `solvers::fld::multigrid`, CPU and GPU; the same as the
    /// method's `:mg` variant) or `auto` (multigrid from 100³ voxels for CDA and 63³ for FLD,
    /// SOR below and where multigrid does not converge; the `:auto` variant,
    /// `solvers::fld::Solver::Auto`).
    /// Other methods have their own scheme and refuse it.
    #[arg(long, value_enum)]
    pub solver: Option<crate::point_source::SolverArg>,
}

/// `method` with `--solver` applied: `multigrid` (`auto`) appends the `:mg` (`:auto`)
/// variant to a `cda`/`fld` method (unchanged if it has it), and every `--solver` refuses a
/// method that names another solver's variant.
pub fn method_with_solver(
    method: &str,
    solver: Option<crate::point_source::SolverArg>,
) -> Result<String> {
    use crate::point_source::SolverArg;
    let m = method.trim();
    let mut tokens = m.split(':');
    let base = tokens.next().unwrap_or("").to_ascii_lowercase();
    // The solver variant the method names, if any.
    let named = tokens.find_map(|t| {
        if t.eq_ignore_ascii_case("mg") {
            Some(SolverArg::Multigrid)
        } else if t.eq_ignore_ascii_case("auto") {
            Some(SolverArg::Auto)
        } else {
            None
        }
    });
    let diffusion = base == "cda" || base == "fld";
    let suffix = |s: SolverArg| match s {
        SolverArg::Sor => "",
        SolverArg::Multigrid => ":mg",
        SolverArg::Auto => ":auto",
    };
    match (solver, named) {
        (None, _) => Ok(m.to_string()),
        (Some(_), _) if !diffusion => bail!(
            "--solver applies to the cda and fld methods only (SOR, multigrid or auto); \
             --method `{m}` has its own scheme"
        ),
        (Some(s), Some(n)) if s == n => Ok(m.to_string()),
        (Some(s), Some(n)) => bail!(
            "--solver {} with --method `{m}`: the `{}` variant is the {} solver",
            crate::common::value_names(&[s]),
            suffix(n),
            crate::common::value_names(&[n]),
        ),
        (Some(s), None) => Ok(format!("{m}{}", suffix(s))),
    }
}

/// The finest raymarch sub-step `--step` accepts, in voxels.
pub const MIN_STEP: f64 = 1e-3;

/// The most stratified raymarch rays per pixel and axis `--pixel-samples` accepts.
pub const MAX_PIXEL_SAMPLES: usize = 64;

/// The voxels every axis of the diffusion grid keeps at least (or all it has) under
/// `--downsample`.
pub const MIN_SOLVE_AXIS: usize = 4;

impl Args {
    /// The grid-method flags that were given, by name (the path tracer refuses them).
    fn grid_flags(&self) -> Vec<&'static str> {
        let mut v = Vec::new();
        for (given, name) in [
            (self.downsample.is_some(), "--downsample"),
            (self.precision.is_some(), "--precision"),
            (self.step.is_some(), "--step"),
            (self.pixel_samples.is_some(), "--pixel-samples"),
            (self.shadows.is_some(), "--shadows"),
            (self.omega.is_some(), "--omega"),
            (!self.param.is_empty(), "--param"),
            (self.tolerance.is_some(), "--tolerance"),
            (self.max_iterations.is_some(), "--max-iterations"),
            (self.solver.is_some(), "--solver"),
        ] {
            if given {
                v.push(name);
            }
        }
        v
    }
}

/// The largest `--downsample` that keeps [`MIN_SOLVE_AXIS`] voxels (or all there are) on
/// every axis of a grid of `n` voxels.
pub fn max_downsample(n: [usize; 3]) -> usize {
    (1..=n.iter().copied().max().unwrap_or(1).max(1))
        .take_while(|&d| n.iter().all(|&k| k.div_ceil(d) >= k.min(MIN_SOLVE_AXIS)))
        .last()
        .unwrap_or(1)
}

/// One row of `passes.csv`.
#[derive(Debug, Clone, Serialize)]
pub struct PassRow {
    /// Pass name (pipeline) or `pt_<component>_<orders>` (path tracer).
    pub pass: String,
    /// Colour channel.
    pub channel: usize,
    /// Wall seconds.
    pub seconds: f64,
}

/// Images of one render, per channel: total and components (with stderr for the path tracer).
#[derive(Debug, Clone)]
pub struct RenderOutput {
    /// Width, height.
    pub size: (usize, usize),
    /// `total`, `single`, `multiple`, `emission` per channel.
    pub images: Vec<(String, Vec<Vec<f64>>)>,
    /// The rows of `passes.csv`.
    pub passes: Vec<PassRow>,
}

fn contributions_json(c: &Contributions) -> serde_json::Value {
    serde_json::json!({
        "min_order": c.min_order, "max_order": c.max_order,
        "lights": c.lights, "emission": c.emission,
    })
}

/// Runs the experiment.
pub fn run(args: &Args) -> Result<RenderOutput> {
    run_with(args, None, None)
}

/// The binary's entry: [`run_with`] with the process's command line (a `--shard` run
/// records it for `merge`).
pub fn main() -> Result<()> {
    use clap::Parser as _;
    let args = Args::parse();
    let argv: Vec<String> = std::env::args().skip(1).collect();
    crate::common::estimate_ok(run_with(&args, Some(&argv), None).map(|_| ()))
}

/// Parses `argv` (flags only) and runs it as the merge of `joined`.
pub fn run_merged(argv: &[String], joined: crate::shard::Joined) -> Result<()> {
    use clap::Parser as _;
    let args =
        Args::try_parse_from(std::iter::once("render".to_string()).chain(argv.iter().cloned()))
            .with_context(|| format!("render {}", argv.join(" ")))?;
    run_with(&args, Some(argv), Some(joined)).map(|_| ())
}

/// [`run`] with the command line `argv` (for `--shard`) and, for a merge, the joined
/// shards (see [`crate::shard`]).
pub fn run_with(
    args: &Args,
    argv: Option<&[String]>,
    merged: Option<crate::shard::Joined>,
) -> Result<RenderOutput> {
    let mut file = SceneFile::load(&args.scene)
        .with_context(|| format!("loading --scene {}", args.scene.display()))?;
    let quick = args.common.quick;
    if quick {
        cap_resolution(&mut file, 24);
    }
    let pt = args
        .method
        .trim()
        .eq_ignore_ascii_case(crate::methods::PATH_TRACER);
    let mut channels = file.channels();
    let Some(camera) = channels[0].camera else {
        bail!("{}: the scene has no [camera]", args.scene.display());
    };
    if pt {
        let given = args.grid_flags();
        if !given.is_empty() {
            bail!(
                "{} only appl{} to the grid methods; the path tracer (--method pt) takes \
                 --spp, --seed and the scene's [sampler]",
                given.join(", "),
                if given.len() == 1 { "ies" } else { "y" }
            );
        }
        if args.backend.backend != crate::common::BackendChoice::Cpu {
            bail!(
                "--backend {}: the path tracer runs on the CPU only (in f64); --backend \
                 selects where the grid methods' multiple-scattering solve runs",
                args.backend.backend
            );
        }
    } else {
        for (given, flag) in [
            (args.spp.is_some(), "--spp"),
            (args.seed.is_some(), "--seed"),
        ] {
            if given {
                eprintln!(
                    "warning: {flag} applies to the path tracer (--method pt) only; the grid \
                     method {} ignores it",
                    args.method
                );
            }
        }
        if args.backend.backend == crate::common::BackendChoice::Gpu
            && args.precision == Some(PrecisionArg::F64)
        {
            bail!("--precision f64 with --backend gpu: the GPU solves in f32 only");
        }
        if args.backend.backend == crate::common::BackendChoice::Both {
            bail!("--backend both is not supported by render; pick cpu or gpu");
        }
    }
    let mut params = Params::parse(args.param.iter().map(String::as_str)).context("--param")?;
    if let Some(w) = args.omega {
        params = params.with("omega", w);
    }
    let method = if pt {
        args.method.clone()
    } else {
        method_with_solver(&args.method, args.solver)?
    };
    let renderer =
        Renderer::parse_with(&method, &params).with_context(|| format!("--method `{method}`"))?;
    let defaults = PipelineConfig::default();
    let downsample = args.downsample.unwrap_or(defaults.downsample);
    let step = args.step.unwrap_or(defaults.step);
    let pixel_samples = args.pixel_samples.unwrap_or(defaults.pixel_samples);
    let tolerance = args.tolerance.unwrap_or(defaults.tolerance.rel);
    let max_iterations = args.max_iterations.unwrap_or(defaults.tolerance.max_steps);
    let precision_arg = args.precision.unwrap_or(PrecisionArg::F64);
    let shadows_arg = args.shadows.unwrap_or(ShadowsArg::Exact);
    if !(MIN_STEP..=1.0).contains(&step) {
        bail!(
            "--step {}: the raymarch sub-step must be in [{MIN_STEP}, 1] voxels",
            solvers::error::Compact(step)
        );
    }
    if pixel_samples > MAX_PIXEL_SAMPLES {
        bail!(
            "--pixel-samples {pixel_samples}: at most {MAX_PIXEL_SAMPLES} stratified rays per \
             pixel and axis ({} rays per pixel)",
            MAX_PIXEL_SAMPLES * MAX_PIXEL_SAMPLES
        );
    }
    if !(tolerance.is_finite() && (0.0..1.0).contains(&tolerance)) {
        bail!(
            "--tolerance {}: must be in [0, 1) (0 runs exactly --max-iterations steps)",
            solvers::error::Compact(tolerance)
        );
    }
    let n = channels[0].medium.grid.n;
    if !pt {
        let most = max_downsample(n);
        if downsample > most {
            let [nx, ny, nz] = n;
            bail!(
                "--downsample {downsample} leaves a {}×{}×{} diffusion grid of the {nx}×{ny}×{nz} \
                 scene grid; at most --downsample {most} keeps {MIN_SOLVE_AXIS} voxels per axis",
                nx.div_ceil(downsample),
                ny.div_ceil(downsample),
                nz.div_ceil(downsample)
            );
        }
        if tolerance == 0.0 {
            eprintln!("note: --tolerance 0 runs exactly --max-iterations {max_iterations} steps");
        }
    }
    {
        // The grid solver's state on the (downsampled) grid (colour channels solve in turn).
        let [nx, ny, nz] = n;
        let d = downsample.max(1);
        let voxels = [nx, ny, nz].map(|k| k.div_ceil(d));
        let bytes = solvers::budget::bytes(&voxels, solvers::budget::SOLVER_BYTES_PER_VOXEL);
        solvers::budget::check(
            format!(
                "the grid of --scene {} ({nx}×{ny}×{nz} voxels, --downsample {d})",
                args.scene.display()
            ),
            bytes,
        )?;
    }
    let shadows = match shadows_arg {
        ShadowsArg::Exact => Shadows::Exact,
        ShadowsArg::Dsm => Shadows::DeepShadowMap,
    };
    let precision: Precision = precision_arg.precision();
    let mut config = PipelineConfig {
        downsample,
        step,
        pixel_samples,
        shadows,
        tolerance: Tolerance {
            rel: tolerance,
            max_steps: max_iterations,
        },
        ..defaults
    };
    if let Renderer::Pipeline(m) = &renderer {
        config.method = m.clone();
    }
    let write_image = file.outputs.contains(&OutputKind::Image);
    let write_fluence = file.outputs.contains(&OutputKind::Fluence);
    if pt && write_fluence {
        bail!(
            "{}: `[outputs] write` lists `fluence`, but the path tracer's camera render has no \
             fluence grid; use a grid method (e.g. --method fld) or drop `fluence`",
            args.scene.display()
        );
    }
    let spp = args
        .spp
        .unwrap_or(channels[0].sampler.spp)
        .min(if quick { 16 } else { u32::MAX });
    let seed = args.seed.unwrap_or(channels[0].sampler.seed);
    if pt && spp < reference::pathtracer::MIN_BATCHES {
        bail!(
            "{} = {spp}: the path tracer needs at least {} samples per pixel (one per batch of \
             its per-pixel standard errors)",
            if args.spp.is_some() {
                "--spp"
            } else {
                "the scene's [sampler] spp"
            },
            reference::pathtracer::MIN_BATCHES
        );
    }
    let (_, rendered) = pipeline::effects_of(&channels, &file.effects, &config)?;
    let mut work = crate::cost::Estimate::new();
    if pt {
        work.add(
            format!("path tracing, {spp} spp, {} channel(s)", channels.len()),
            crate::cost::pt_render(&channels, &rendered, spp),
        );
    } else {
        work.add(
            format!(
                "the pipeline: the solve (--max-iterations {max_iterations}, --tolerance {}) \
                 and the raymarch (--step {step}, --pixel-samples {pixel_samples}), {} \
                 channel(s)",
                solvers::error::Compact(tolerance),
                channels.len()
            ),
            crate::cost::pipeline_render(&channels, &config),
        );
    }
    let warnings = solvers::scene::warnings::degenerate(&channels[0], Some(&rendered));
    for w in &warnings {
        eprintln!("warning: {}: {w}", args.scene.display());
    }
    let mut out = Output::for_run("render", &args.common);
    if let Some(shard) = args.common.shard {
        if !pt {
            bail!("--shard {shard}: only the path tracer (--method pt) is sharded");
        }
        let Some(argv) = argv else {
            bail!("--shard needs the command line (run the `render` binary)");
        };
        out.set_argv(argv);
    }
    if let Some(j) = merged {
        out.merge_from(j);
    }
    out.work(&work)?;
    out.record("warnings", serde_json::json!(warnings));
    out.start(serde_json::json!({
        "scene": args.scene.display().to_string(), "method": args.method,
        "backend": args.backend.backend, "downsample": downsample, "spp": spp, "seed": seed,
        "precision": precision_arg.name(), "step": step, "pixel_samples": pixel_samples,
        "shadows": value_names(&[shadows_arg]), "omega": args.omega, "quick": quick,
        "tolerance": tolerance, "max_iterations": max_iterations,
        "solver": args.solver.map(|s| value_names(&[s])), "resolved_method": method,
    }))?;
    let [w, h] = camera.resolution;
    // φ of every channel's multiple-scattering solve as one `.vol` grid (grid methods only).
    let mut fluence: Option<VolGrid> = None;
    let (result, plan_json) = if pt {
        let (_, effects) = pipeline::effects_of(&channels, &file.effects, &config)?;
        // The majorant structure the tracker chose (the same for every channel: σt is).
        let majorant = reference::pathtracer::majorant_report(
            &channels[0],
            &reference::pathtracer::TraceOptions::of(&channels[0]),
        )
        .with_context(|| format!("{}: preparing the path tracer", args.scene.display()))?;
        if args.explain {
            println!(
                "method: path tracer ({spp} spp), rendered effects: {}",
                effects.names()
            );
            println!(
                "  majorant: {} ({} blocks of {}³ voxels, {} walked voxel by voxel, {} uniform; \
                 max {:.4e})",
                majorant.structure,
                majorant.blocks.iter().product::<usize>(),
                majorant.block,
                majorant.refined_blocks,
                majorant.uniform_blocks,
                majorant.max
            );
            for p in reference::effects::pt_passes(&channels[0], &effects) {
                println!("  {:?}: {:?}", p.component, p.contributions);
            }
        }
        let mut images: Vec<(String, Vec<Vec<f64>>)> =
            ["total", "single", "multiple", "emission", "stderr"]
                .iter()
                .map(|n| (n.to_string(), Vec::new()))
                .collect();
        let mut passes = Vec::new();
        let mut renders = Vec::new();
        for (c, scene) in channels.iter_mut().enumerate() {
            scene.sampler.spp = spp;
            scene.sampler.seed = seed;
            let settings = RenderSettings {
                spp,
                seed,
                batches: reference::pathtracer::MIN_BATCHES,
                contributions: Contributions::all(),
            };
            let sp = out.spinner("render");
            sp.set_message(format!("path tracing channel {c}, {spp} spp"));
            let what = format!("path tracing channel {c}");
            let tallied = out.tally(
                &what,
                |shard| {
                    render_components_part(scene, &effects, &settings, shard)
                        .with_context(|| what.clone())
                },
                |parts| Ok(components_from_parts(scene, &effects, parts)?),
            )?;
            sp.finish_and_clear();
            let Some(comp) = tallied else {
                continue;
            };
            for (component, contributions, seconds) in &comp.renders {
                let name = format!(
                    "pt_{}",
                    match component {
                        Component::Single => "single",
                        Component::Multiple => "multiple",
                        Component::Emission => "emission",
                        Component::Background => "background",
                    }
                );
                renders.push(serde_json::json!({
                    "pass": name, "channel": c, "seconds": seconds,
                    "contributions": contributions_json(contributions),
                }));
                passes.push(PassRow {
                    pass: name,
                    channel: c,
                    seconds: *seconds,
                });
            }
            images[0].1.push(comp.total.mean);
            images[1].1.push(comp.single.mean);
            images[2].1.push(comp.multiple.mean);
            images[3].1.push(comp.emission.mean);
            images[4].1.push(comp.total.stderr);
        }
        let json = serde_json::json!({
            "method": "pt", "spp": spp, "effects": effects, "passes_run": renders,
            "majorant": majorant,
        });
        (
            RenderOutput {
                size: (w, h),
                images,
                passes,
            },
            json,
        )
    } else {
        let plan = pipeline::plan_channels(&channels, &file.effects, &config)?;
        if write_fluence && !plan.runs("diffusion_solve") {
            bail!(
                "{}: `[outputs] write` lists `fluence`, but the plan runs no multiple-scattering \
                 solve (no φ to write): the rendered effects are {}",
                args.scene.display(),
                plan.effects.names()
            );
        }
        if args.explain {
            println!("method: {}, downsample {downsample}", config.method);
            print!("{}", plan.explain());
        }
        let backends = args.backend.open()?;
        let list = backends.list(precision);
        let Some(backend) = list.first() else {
            bail!("--backend selects no backend");
        };
        out.record("backends", backends.meta());
        let sp = out.spinner("render");
        sp.set_message(format!(
            "{} on {backend}, {} channel(s)",
            config.method,
            channels.len()
        ));
        let r = pipeline::render_channels(&channels, &file.effects, &config, backend)
            .context("rendering with the pipeline")?;
        sp.finish_and_clear();
        if write_fluence {
            fluence = Some(fluence_grid(&r.diffusion)?);
        }
        let pick = |f: &dyn Fn(&pipeline::ChannelImages) -> Vec<f64>| -> Vec<Vec<f64>> {
            r.channels.iter().map(f).collect()
        };
        let mut images = vec![("total".to_string(), pick(&|c| c.total.clone()))];
        for (name, pass) in [
            ("single", "raymarch_single"),
            ("multiple", "raymarch_multiple"),
            ("emission", "raymarch_emission"),
        ] {
            let v = match name {
                "single" => pick(&|c| c.single.clone()),
                "multiple" => pick(&|c| c.multiple.clone()),
                _ => pick(&|c| c.emission.clone()),
            };
            if r.plan.runs(pass) {
                images.push((name.to_string(), v));
            }
        }
        let passes = r
            .passes_run
            .iter()
            .map(|p| PassRow {
                pass: p.name.clone(),
                channel: p.channel,
                seconds: p.seconds,
            })
            .collect();
        let json = serde_json::json!({
            "method": config.method.name(), "backend": backend.to_string(),
            "downsample": downsample, "plan": r.plan,
            "passes_run": r.passes_run, "diffusion": r.diffusion,
        });
        (
            RenderOutput {
                size: (w, h),
                images,
                passes,
            },
            json,
        )
    };
    if out.sharding() {
        out.finish()?;
        return Ok(result);
    }
    for p in &result.passes {
        out.timing(format!("{} (channel {})", p.pass, p.channel), p.seconds);
    }
    std::fs::write(
        out.path("plan.json"),
        serde_json::to_string_pretty(&plan_json)?,
    )
    .context("writing plan.json")?;
    out.csv("passes.csv", &result.passes)?;
    if let Some(vol) = &fluence {
        let path = out.path("fluence.vol");
        vol.write(&path)
            .with_context(|| format!("writing {}", path.display()))?;
    }
    let white = white_point(&result.images[0].1);
    for (name, chans) in &result.images {
        if !write_image || chans.iter().all(|c| c.is_empty()) {
            continue;
        }
        let is_total = name == "total";
        let stem = match name.as_str() {
            "total" => "image".to_string(),
            "stderr" => "image_stderr".to_string(),
            other => other.to_string(),
        };
        // The path tracer's components are always written (they are zero when not rendered).
        if pt && !is_total && name != "stderr" && chans.iter().all(|c| c.iter().all(|&v| v == 0.0))
        {
            continue;
        }
        let refs: Vec<&[f64]> = chans.iter().map(|c| c.as_slice()).collect();
        solvers::pipeline::image::write_pfm(&out.path(&format!("{stem}.pfm")), w, h, &refs)
            .with_context(|| format!("writing {stem}.pfm"))?;
        if name != "stderr" {
            write_png(&out.path(&format!("{stem}.png")), w, h, &refs, white)?;
        }
    }
    out.finish()?;
    Ok(result)
}

/// φ of the channels' solves (one record per channel, all on one solve grid) as a `.vol`
/// grid with one channel per colour channel, on the solve grid's box.
pub fn fluence_grid(solves: &[pipeline::DiffusionRecord]) -> Result<VolGrid> {
    let Some(first) = solves.first() else {
        bail!("no multiple-scattering solve ran: no fluence to write");
    };
    let grid = first.solve_grid;
    if solves
        .iter()
        .any(|s| s.solve_grid != grid || s.phi.len() != grid.len())
    {
        bail!("the colour channels' solves differ in grid or size");
    }
    let one = VolGrid::from_field(&grid, &first.phi).context("fluence grid")?;
    let channels = solves.len();
    let mut data = vec![0.0f32; grid.len() * channels];
    for (c, s) in solves.iter().enumerate() {
        for (v, &p) in s.phi.iter().enumerate() {
            data[v * channels + c] = p as f32;
        }
    }
    VolGrid::new(one.dims, channels, one.min, one.max, data).context("fluence grid")
}

/// Caps the camera resolution at `max` pixels on the longer side (keeps the aspect).
fn cap_resolution(file: &mut SceneFile, max: usize) {
    let cap = |s: &mut Scene| {
        if let Some(c) = &mut s.camera {
            let [w, h] = c.resolution;
            let m = w.max(h);
            if m > max {
                c.resolution = [(w * max / m).max(1), (h * max / m).max(1)];
            }
        }
    };
    cap(&mut file.scene);
}

/// The 99th percentile of the largest channel per pixel (exposure of every PNG of a render).
pub fn white_point(total: &[Vec<f64>]) -> f64 {
    let n = total.first().map_or(0, Vec::len);
    let mut m: Vec<f64> = (0..n)
        .map(|p| total.iter().map(|c| c[p]).fold(0.0, f64::max))
        .collect();
    m.sort_by(f64::total_cmp);
    m.get((n * 99 / 100).min(n.saturating_sub(1)))
        .copied()
        .unwrap_or(1.0)
        .max(1e-30)
}

/// Tone-mapped PNG: value/white clamped to [0, 1], gamma 2.2; grey for one channel.
pub fn write_png(path: &Path, w: usize, h: usize, channels: &[&[f64]], white: f64) -> Result<()> {
    let root = BitMapBackend::new(path, (w as u32, h as u32)).into_drawing_area();
    let tone = |v: f64| ((v / white).clamp(0.0, 1.0).powf(1.0 / 2.2) * 255.0).round() as u8;
    for y in 0..h {
        for x in 0..w {
            let p = y * w + x;
            let c = match channels {
                [g] => {
                    let v = tone(g[p]);
                    RGBColor(v, v, v)
                }
                [r, g, b] => RGBColor(tone(r[p]), tone(g[p]), tone(b[p])),
                _ => bail!("PNG needs 1 or 3 channels"),
            };
            root.draw_pixel((x as i32, y as i32), &c)
                .map_err(|e| anyhow::anyhow!("drawing {}: {e}", path.display()))?;
        }
    }
    root.present()
        .map_err(|e| anyhow::anyhow!("writing {}: {e}", path.display()))?;
    Ok(())
}
