//! The accuracy-versus-time atlas: for each dataset and every method setting, the wall time
//! of a render and its image error against a converged path-traced reference.
//!
//! **Reference.** The path tracer renders the scene's effect set (the file's `[effects]`
//! restriction applied) component by component (`reference::effects::render_components`:
//! single scattering, multiple scattering, emission) at `--reference-spp` samples per
//! pixel, seed `--seed`. Its own noise, √Σse²/√Σr² over all channels and pixels, is the
//! `error_stderr` of every point of that scene: the error a perfect method would show.
//!
//! **Error.** Relative RMSE over all channels and pixels of the total image,
//! √Σ(a − r)²/√Σr² ([`crate::images::relative_rmse`]); `error_debiased` removes the
//! reference variance; `error_single` / `error_multiple` are the same metric per component
//! (relative to that component of the reference).
//!
//! **Methods** come from the registry ([`methods`]: the path tracer and every family of
//! `solvers::method::METHODS` with its defaults); a grid method's settings are
//! downsampling × tolerance × precision, the path tracer's its samples per pixel. The path tracer itself is a method
//! (settings: samples per pixel, an independent seed), which gives its error-vs-time curve.
//! A grid method's time is the wall clock of the whole render (light baking, diffusion
//! solve, raymarch), on each selected backend.
//!
//! **Fixed step counts.** A method whose registry entry has fixed step counts
//! (`Method::step_settings`: LPM, where one step is one scattering order, counts 1, 2, 3)
//! also runs exactly that many steps at downsampling [`STEP_DOWNSAMPLE`] in f32 (setting
//! `ds=2 steps=k f32`); `orders.csv` puts those points beside the same method converged at
//! that downsampling (tolerance [`STEP_TOLERANCE`]) and every other grid method there
//! ([`orders`]). Downsampling 2, not 4: a render's time on these datasets is mostly the
//! single-scattering raymarch, which does not depend on it (LPM, 1 order, `nebula`: 6.8 s at
//! ds 2, 6.5 s at ds 4; `plume`: 42 s and 47 s, under a load of 6 on 2 cores), and at ds 2
//! the converged errors are 20–40 % lower. The 12 renders they add to a full run took 92
//! CPU-seconds (`--methods lpm --grid 2:steps=1:f32,2:steps=2:f32,2:steps=3:f32`, user time,
//! at a load of about 8 on 2 cores), three quarters of it plume's point-light raymarch.
//!
//! **Settings of a method's own parameters** (`Method::param_settings`, a registry hook: no
//! method is named here). Each runs at downsampling [`STEP_DOWNSAMPLE`] in f32, converged
//! ([`STEP_TOLERANCE`]) and at its own fixed step counts ([`param_settings`]). POP has two
//! kinds: 8 and 216 ordinates (with its default 64, the paper's N ∈ {8, 64, 216}; labelled
//! `… ordinates=8`), rendered only on scenes with an environment light or volume emission,
//! the two things POP spreads over its ordinate set (a directional light is one ordinate and
//! a point light a radial grid whatever N: on `nebula` and `shell_core` the settings would
//! repeat the default bit for bit), and its variants `pop:residuum` (POP Sec 5.4, Eq 10
//! switch) and `pop:residuum-fld` (ours), recorded as methods of their own. POP's fixed step
//! count is the paper's M = 16 (`pop`'s `ds=2 steps=16 f32`; orders.csv has it beside the
//! converged point).
//!
//! **POP in the full run** (2026-12-05, 2-vCPU AMD EPYC; the other methods' render times
//! against the previous committed run's: median ratio 0.94 over the 123 points above 1 s,
//! so the machine was comparable). POP has points on all four datasets (`emissive_cloud` and `plume` through
//! its emission ordinates, `plume`'s point light through its radial grid; `skipped.csv` is
//! empty). Errors (relative L2 vs the path tracer) converged at ds=2 / at M = 16: `nebula`
//! 1.138 / 0.536, `emissive_cloud` 0.918 / 0.333, `shell_core` 3.456 / 0.325, `plume`
//! 10.95 / 0.527: the converged isotropised random walk is several times too bright
//! (`solvers::pop`, W2), the paper's M = 16 stops it early and lands closer.
//! `pop:residuum-fld` 0.350 / 0.602 / 0.852 / 8.21. The ordinate settings, N = 8 / 64 /
//! 216: `emissive_cloud` converged 0.912 / 0.918 / 0.919 in 3.8 / 30.7 / 102.7 s, at M = 16
//! 0.326 / 0.333 / 0.333 in 0.17 / 0.86 / 2.83 s; `plume` converged 10.951 / 10.951 / 10.951
//! in 36.9 / 165.6 / 522.1 s, at M = 16 0.5272 / 0.5273 / 0.5273 in 12.0 / 14.9 / 20.3 s:
//! on these scenes N hardly moves the error (the random walk's bias dominates), it moves
//! the time ∝ N. **Cost:** POP's points took 1750 s of the run's 2607 s of render time
//! (`plume` 1431 s, its converged N = 216 point alone 522 s; before emission and point
//! lights: 29 s on two datasets); `--methods` without `pop` leaves it out. On
//! `environment_sphere` (16³, constant environment, `--reference-spp 1024`, an earlier
//! run): converged at ds=2, N = 8 / 64 / 216: error 0.290 / 0.266 / 0.264 in 0.06 / 0.46 /
//! 1.46 s; at M = 16 0.234 / 0.216 / 0.215.
//! **POP by g** (`accuracy_hg`, converged at ds=2, 1e-3, f32; same run): `cloud_directional`
//! g = 0.3 / 0.7 / 0.9 / 0.99: 1.42 / 1.51 / 2.80 / 27.3, `shell_core` 2.26 / 1.65 / 2.35 /
//! 6.57, growing with g like the paper (non-similarity) variants of FLD-LP (22.3 and 3.58 at
//! 0.99) and LBM (26.3, 5.15), not falling as spec W1 leads one to expect: the pipeline
//! re-emits σs·φ_s isotropically, which a forward-peaked collided field is not (POP's
//! view-dependent L_acc, `pipeline::raymarch::Term::ViewSource`, is not used by the atlas).
//!
//! **Lights a method refuses.** A method that takes the lights itself refuses sphere lights,
//! and point lights unless it has radial grids for them (`Capabilities::direct_points`: POP);
//! where the registry offers its baked form (`Method::with_baked_lights`:
//! `lpm` → `lpm:baked`, spec D13's first-collision injection, which agrees with `lpm` to
//! 2.6·10⁻³ on the multiple-scattering image, see `solvers::lpm::method`), the atlas renders
//! that form on such a scene and records it under its own name, with `in place of lpm` in
//! `detail`; only a method without one is skipped (`skipped.csv`). Of the four datasets only
//! `plume` has a point light, so LPM has points on every dataset: `lpm` on three, `lpm:baked`
//! on `plume`. Running `lpm:baked` everywhere would make the rows alike, but would replace
//! the default's own boundary injection on the three scenes that it can render.
//!
//! **Outputs** (`results/accuracy_cost/`): `orders.csv` (the fixed-step table above), `points.csv`
//! (`scene,method,setting,backend,seconds,error,error_stderr` and more; `paths_per_second`
//! for the path-tracer points, wall-clock like `seconds`), a log–log Pareto
//! plot per scene (`pareto_<scene>.png`), `fastest.csv` (per scene and error target 5 %,
//! 2 %, 1 %: the fastest point whose debiased error reaches it), `skipped.csv` (the method
//! settings whose plan refuses a scene, with the typed reason), `references.csv` (with the
//! reference's `paths_per_second`) and
//! `meta.json`.

use crate::common::{BackendArgs, CommonArgs, Ctx, list_item, progress};
use crate::experiment::{BackendSupport, Experiment, FigureRun, Promise};
use crate::methods::Renderer;
use crate::plot::{Axis, Series, Style, plot};
use crate::report::{Section, table};
pub use crate::scenes::{Prepared, errors, load, parse_resolution, render_reference, scene_paths};
use anyhow::{Context, Result, bail};
use reference::effects::{PassSums, PtComponents, components_from_parts, render_components_part};
use reference::pathtracer::BatchSums;
use reference::pathtracer::{Contributions, RenderSettings};
use serde::Serialize;
use solvers::method::{MethodRef, Tolerance};
use solvers::pipeline::{self, ChannelImages, PipelineConfig};
use solvers::{Backend, Precision};
use std::time::Instant;

/// The datasets of the atlas (scene files relative to the workspace root).
pub const DEFAULT_SCENES: &str =
    "scenes/nebula.toml,scenes/emissive_cloud.toml,scenes/shell_core.toml,scenes/plume.toml";

/// The help of `--coarsen`, word for word the same in `accuracy_cost` and `renderings`.
pub const COARSEN_HELP: &str = "Coarsen every scene's medium by this factor first (conservative restriction; the reference sees the same coarsened scene); 1 means no coarsening. Default 1 (2 with --quick)";

/// The `--coarsen` factor of `accuracy_cost` and `renderings`: the flag's value, or 1 (2
/// with `--quick`); 0 is an error (it means no factor at all, not "no coarsening").
pub fn coarsen_factor(flag: Option<usize>, quick: bool) -> Result<usize> {
    match flag {
        Some(0) => bail!("--coarsen must be ≥ 1; 1 means no coarsening"),
        Some(c) => Ok(c),
        None => Ok(if quick { 2 } else { 1 }),
    }
}

/// The scene files of a `--scenes` flag of `accuracy_cost` and `renderings`. A list given
/// on the command line is taken as typed: relative paths are from the current directory,
/// and an error about one shows it as typed. Without the flag, `default`, whose relative
/// paths are taken from the workspace root when the current directory does not have them
/// ([`scene_paths`]), so the defaults work from anywhere.
pub fn scene_files(flag: Option<&str>, default: &str) -> Result<Vec<std::path::PathBuf>> {
    let Some(list) = flag else {
        return scene_paths(default);
    };
    let v: Vec<std::path::PathBuf> = list
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(std::path::PathBuf::from)
        .collect();
    if v.is_empty() {
        bail!("--scenes: no scene files given");
    }
    Ok(v)
}

/// Error targets of `fastest.csv`.
pub const TARGETS: [f64; 3] = [0.05, 0.02, 0.01];

/// Flags of `accuracy_cost`.
#[derive(Debug, Clone, clap::Parser)]
#[command(about = "Accuracy versus time of every method setting against a path-traced reference")]
pub struct Args {
    /// Shared flags.
    #[command(flatten)]
    pub common: CommonArgs,
    /// Shared backend flag (grid methods run on each; the path tracer on the CPU).
    #[command(flatten)]
    pub backend: BackendArgs,
    /// Scene files, comma-separated; relative paths are from the current directory.
    /// Default: the atlas's datasets, scenes/nebula.toml, scenes/emissive_cloud.toml,
    /// scenes/shell_core.toml and scenes/plume.toml of the workspace.
    #[arg(long)]
    pub scenes: Option<String>,
    /// Samples per pixel of the reference (default 4096; 256 with --quick).
    #[arg(long, value_parser = crate::common::count_u32)]
    pub reference_spp: Option<u32>,
    /// Samples per pixel of the path tracer's own points, each ≥ 16 (default
    /// 16,64,256,1024,2048; 16,32 with --quick).
    #[arg(long, value_delimiter = ',', value_parser = list_item::<u32>)]
    pub spp: Option<Vec<u32>>,
    /// Methods to run (names from the registry, comma-separated; default all).
    #[arg(long)]
    pub methods: Option<String>,
    /// Coarsening factor of the scenes' media (see [`COARSEN_HELP`]).
    #[arg(long, help = COARSEN_HELP, allow_negative_numbers = true)]
    pub coarsen: Option<usize>,
    /// Override the camera resolution, `W,H` (default: the scene's; 24,24 with --quick).
    #[arg(long)]
    pub resolution: Option<String>,
    /// Replace every scene's phase function by Henyey–Greenstein with each of these g, one
    /// scene per value, named `<stem>_g<g>` (e.g. `shell_core_g0.9`); default: the scene's own.
    #[arg(long, value_delimiter = ',', value_parser = list_item::<f64>, allow_negative_numbers = true)]
    pub g: Option<Vec<f64>>,
    /// The grid methods' settings, `DS:TOL:PRECISION` each (e.g. `2:1e-3:f32`; `TOL` may be
    /// `steps=K`, exactly K steps), comma-separated; default the ladder of `grid_settings`
    /// (quick: `4:1e-3:f32`) and each method's fixed step counts.
    #[arg(long, value_delimiter = ',', value_parser = parse_grid_setting)]
    pub grid: Option<Vec<Setting>>,
    /// Seed of the reference (the path tracer's points use seed + 1000).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Print the sweep's tasks, one line each (`K<TAB>scene<TAB>method<TAB>setting<TAB>backend`;
    /// each scene's reference is a task), and exit.
    #[arg(long)]
    pub list_tasks: bool,
    /// Run only task K of `--list-tasks` (default `--out`: `<default>.task-K`); its result
    /// goes to `shard.bin`, and `merge` assembles every task's into `points.csv`,
    /// `fastest.csv`, the plots and the README section as a single run writes them.
    #[arg(long)]
    pub task: Option<u32>,
}

/// One point of the atlas.
#[derive(Debug, Clone, Serialize)]
pub struct Point {
    /// Scene (file stem).
    pub scene: String,
    /// Method name from the registry.
    pub method: String,
    /// The setting, e.g. `ds=4 tol=1e-3 f32`.
    pub setting: String,
    /// `cpu-f32`, `cpu-f64`, `gpu-f32`.
    pub backend: String,
    /// Wall-clock seconds of the render.
    pub seconds: f64,
    /// Relative RMSE of the total image against the reference.
    pub error: f64,
    /// The reference's own relative noise (same metric).
    pub error_stderr: f64,
    /// `error` with the reference variance removed.
    pub error_debiased: f64,
    /// Relative RMSE of the single-scattering component (NaN if the scene has none).
    pub error_single: f64,
    /// Relative RMSE of the multiple-scattering component (NaN if the scene has none).
    pub error_multiple: f64,
    /// What else the method reports (iterations, passes).
    pub detail: String,
    /// The scene's mean cosine g (0 for isotropic scattering).
    pub g: f64,
    /// Camera paths per wall-clock second (path tracer settings; NaN for grid methods):
    /// the cost per path that moves the Pareto front when the tracer gets faster.
    pub paths_per_second: f64,
}

/// A method setting.
#[derive(Debug, Clone, PartialEq)]
pub struct Setting {
    /// How it appears in `points.csv`.
    pub label: String,
    /// Diffusion grid downsampling factor.
    pub downsample: usize,
    /// Solver tolerance.
    pub tolerance: f64,
    /// CPU precision (GPU runs are f32 and skip f64 settings).
    pub precision: Precision,
    /// Samples per pixel (path tracer).
    pub spp: u32,
    /// A fixed step count instead of the tolerance (`steps=K` in the label; a method's
    /// [`solvers::method::StepSettings`], e.g. LPM's scattering orders).
    pub steps: Option<usize>,
    /// A setting of the method's own parameters or a variant of it
    /// ([`solvers::method::Method::param_settings`]): this method renders instead of the
    /// entry's, and the point is recorded under its name.
    pub method: Option<MethodRef>,
    /// Rendered only on scenes with an environment light or volume emission
    /// ([`solvers::method::ParamSetting::ordinate_set_only`]).
    pub ordinate_set_only: bool,
}

impl Setting {
    /// The pipeline settings of `method` (or of the setting's own [`Setting::method`]) at
    /// this setting ([`grid_config`], with exactly `steps` steps when the setting fixes
    /// them).
    pub fn config(&self, method: &MethodRef) -> PipelineConfig {
        let method = self.method.as_ref().unwrap_or(method);
        let mut c = grid_config(method, self.downsample, self.tolerance);
        if let Some(k) = self.steps {
            c.tolerance = Tolerance::fixed_steps(k);
        }
        c
    }
}

/// What one render of a method returns: the components per channel and its wall time.
#[derive(Debug)]
pub struct Run {
    /// Per channel.
    pub images: Vec<ChannelImages>,
    /// Wall-clock seconds.
    pub seconds: f64,
    /// Free-form detail (iterations etc.).
    pub detail: String,
    /// Camera paths traced (path tracer; 0 for grid methods).
    pub paths: u64,
}

/// One render job.
#[derive(Debug)]
pub struct Job<'a> {
    /// The scene.
    pub scene: &'a Prepared,
    /// The setting.
    pub setting: &'a Setting,
    /// Where grid solvers run.
    pub backend: &'a Backend<'a>,
    /// Seed for stochastic methods.
    pub seed: u64,
}

/// A method of the atlas: the path tracer, or the pipeline with a method of the registry.
#[derive(Debug, Clone)]
pub struct MethodEntry {
    /// Name in `points.csv` and `--methods`.
    pub name: String,
    /// What renders.
    pub renderer: Renderer,
}

impl From<Renderer> for MethodEntry {
    fn from(renderer: Renderer) -> Self {
        MethodEntry {
            name: renderer.name(),
            renderer,
        }
    }
}

impl MethodEntry {
    /// Its settings (`quick` for CI-sized runs; `spp` is the path tracer's ladder; `grid`
    /// replaces the grid methods' ladder, fixed step counts and parameter settings
    /// included). A grid method whose registry entry has fixed step counts
    /// ([`solvers::method::Method::step_settings`]) runs each of them at [`STEP_DOWNSAMPLE`]
    /// in f32 after the ladder; then each of its parameter settings
    /// ([`solvers::method::Method::param_settings`]) at that downsampling, converged
    /// ([`STEP_TOLERANCE`], f32) and at its own fixed step counts ([`param_settings`]).
    pub fn settings(&self, quick: bool, spp: &[u32], grid: Option<&[Setting]>) -> Vec<Setting> {
        match (&self.renderer, grid) {
            (Renderer::PathTracer, _) => pt_settings(quick, spp),
            (Renderer::Pipeline(_), Some(g)) => g.to_vec(),
            (Renderer::Pipeline(m), None) => {
                let mut v = grid_settings(quick, spp);
                if let Some(st) = m.step_settings() {
                    let d = step_downsample(quick);
                    v.extend(
                        st.counts
                            .iter()
                            .map(|&k| step_setting(d, k, Precision::F32)),
                    );
                }
                v.extend(param_settings(m, quick));
                v
            }
        }
    }

    /// The method a setting renders: the setting's own ([`Setting::method`]) or the entry's.
    fn renderer_for(&self, setting: &Setting) -> Renderer {
        match &setting.method {
            Some(m) => Renderer::Pipeline(m.clone()),
            None => self.renderer.clone(),
        }
    }

    /// The registry's form of this method that takes the pipeline's baked lights
    /// ([`solvers::method::Method::with_baked_lights`]; LPM: `lpm:baked`), which the atlas
    /// renders in its place on a scene whose lights it refuses.
    pub fn baked_stand_in(&self) -> Option<MethodEntry> {
        match &self.renderer {
            Renderer::PathTracer => None,
            Renderer::Pipeline(m) => m
                .with_baked_lights()
                .map(|b| MethodEntry::from(Renderer::Pipeline(MethodRef::new(b)))),
        }
    }

    /// Renders one setting. The path tracer's renders are [`Ctx::tally`]s: with `--shard`
    /// they compute the shard's batches only and nothing comes back, and grid methods are
    /// left to the merge (`None` too).
    pub fn run(&self, job: &Job<'_>, ctx: &mut Ctx) -> Result<Option<Run>> {
        match &self.renderer {
            Renderer::PathTracer => run_pt(job, ctx),
            Renderer::Pipeline(m) => {
                let m = job.setting.method.as_ref().unwrap_or(m);
                let label = format!(
                    "{} {m} [{}] {}",
                    job.scene.name, job.setting.label, job.backend
                );
                ctx.deterministic(
                    &label,
                    || {
                        let r = run_grid(job, m)?;
                        Ok((encode_images(&r.images, r.seconds), r.detail))
                    },
                    decode_images,
                )
            }
        }
    }
}

/// Why `entry` cannot render `scene` at `setting`, if its plan refuses it: a method that cannot
/// render a dataset's effects (a method that takes the lights itself without point-light
/// support: LPM on `plume`) gets no point there, and `skipped.csv` keeps the plan's typed error.
fn refusal(entry: &MethodEntry, scene: &Prepared, setting: &Setting) -> Option<String> {
    let Renderer::Pipeline(m) = &entry.renderer else {
        return None;
    };
    let config = setting.config(m);
    match pipeline::plan_channels(&scene.channels, &scene.selection, &config) {
        Err(
            e @ (pipeline::PipelineError::MethodCannot { .. }
            | pipeline::PipelineError::Solver(solvers::SolverError::LightKind { .. })),
        ) => Some(e.to_string()),
        _ => None,
    }
}

/// A method setting the atlas left out on a scene, and why (`skipped.csv`).
#[derive(Debug, Clone, Serialize)]
pub struct Skipped {
    /// Scene (file stem).
    pub scene: String,
    /// Method name from the registry.
    pub method: String,
    /// The setting.
    pub setting: String,
    /// The backend.
    pub backend: String,
    /// The plan's typed refusal.
    pub reason: String,
}

/// Every method of the atlas: the path tracer and each family of
/// [`solvers::method::METHODS`] with its defaults (`cda`, `fld:lp`, `lbm`, …). A method
/// registered there joins the atlas without an edit here.
pub fn methods() -> Vec<MethodEntry> {
    Renderer::all().into_iter().map(MethodEntry::from).collect()
}

fn pt_settings(_quick: bool, spp: &[u32]) -> Vec<Setting> {
    spp.iter()
        .map(|&s| Setting {
            label: format!("spp={s}"),
            downsample: 1,
            tolerance: 0.0,
            precision: Precision::F64,
            spp: s,
            steps: None,
            method: None,
            ordinate_set_only: false,
        })
        .collect()
}

/// Downsampling × tolerance × precision. Full: quarter resolution (ds 4) at tolerances
/// 1e-2, 1e-3, 1e-4 in f32 and 1e-4 in f64; half resolution (ds 2) at 1e-2, 1e-3 in f32 and
/// 1e-4 in f64; full resolution at 1e-3 in f32 (a full-resolution solve costs about as much
/// as all the others together). Quick: ds = 4, 1e-3, f32 (with ds = 2 as well, POP's RGB
/// solve of the plume at ds = 2 alone took 26 s of the quick atlas's 78 s, the largest item
/// of the test suite after Mitsuba's dense half-space; no test reads the ds = 2 points).
fn grid_settings(quick: bool, _spp: &[u32]) -> Vec<Setting> {
    use Precision::{F32, F64};
    let list: &[(usize, f64, Precision)] = if quick {
        &[(4, 1e-3, F32)]
    } else {
        &[
            (4, 1e-2, F32),
            (4, 1e-3, F32),
            (4, 1e-4, F32),
            (4, 1e-4, F64),
            (2, 1e-2, F32),
            (2, 1e-3, F32),
            (2, 1e-4, F64),
            (1, 1e-3, F32),
        ]
    };
    list.iter()
        .map(|&(d, t, p)| grid_setting(d, t, p))
        .collect()
}

fn grid_setting(downsample: usize, tolerance: f64, precision: Precision) -> Setting {
    Setting {
        label: format!(
            "ds={downsample} tol={tolerance:e} {}",
            if precision == Precision::F32 {
                "f32"
            } else {
                "f64"
            }
        ),
        downsample,
        tolerance,
        precision,
        spp: 0,
        steps: None,
        method: None,
        ordinate_set_only: false,
    }
}

/// The settings of `method`'s own parameters ([`solvers::method::Method::param_settings`]):
/// each at [`STEP_DOWNSAMPLE`] (quick: 4) in f32, converged at [`STEP_TOLERANCE`] and at its
/// fixed step counts. A setting whose method keeps the family's name (a parameter, e.g. POP's
/// `ordinates=8`) appends its label to the setting's (`ds=2 tol=1e-3 f32 ordinates=8`); a
/// variant (`pop:residuum`) is a method of its own in `points.csv`.
pub fn param_settings(method: &MethodRef, quick: bool) -> Vec<Setting> {
    let d = step_downsample(quick);
    let mut v = Vec::new();
    for ps in method.param_settings() {
        let own = MethodRef::new(ps.method);
        let suffix = (own.name() == method.name()).then(|| ps.label.clone());
        let mut list = vec![grid_setting(d, STEP_TOLERANCE, Precision::F32)];
        if let Some(st) = own.step_settings() {
            list.extend(
                st.counts
                    .iter()
                    .map(|&k| step_setting(d, k, Precision::F32)),
            );
        }
        for mut s in list {
            if let Some(l) = &suffix {
                s.label = format!("{} {l}", s.label);
            }
            s.method = Some(own.clone());
            s.ordinate_set_only = ps.ordinate_set_only;
            v.push(s);
        }
    }
    v
}

/// Whether `scene` has an environment light or renders volume emission (where settings that
/// are [`Setting::ordinate_set_only`] render: POP spreads both over its ordinate set).
fn uses_ordinate_set(scene: &Prepared) -> bool {
    scene.effects.contains(solvers::scene::Effect::Emission)
        || scene.channels.iter().any(|c| {
            c.lights
                .iter()
                .any(|l| matches!(l, solvers::scene::Light::Environment { .. }))
        })
}

/// The downsampling of the fixed-step settings: 2 (quick: 4), where the full ladder has
/// tolerance 10⁻³ in f32 too, the converged point they are compared with ([`orders`]).
pub const STEP_DOWNSAMPLE: usize = 2;

/// The tolerance of the converged point beside the fixed-step points (in both ladders).
pub const STEP_TOLERANCE: f64 = 1e-3;

fn step_downsample(quick: bool) -> usize {
    if quick { 4 } else { STEP_DOWNSAMPLE }
}

/// Exactly `steps` steps at `downsample` (label `ds=2 steps=3 f32`).
fn step_setting(downsample: usize, steps: usize, precision: Precision) -> Setting {
    let mut s = grid_setting(downsample, 0.0, precision);
    s.label = format!(
        "ds={downsample} steps={steps} {}",
        if precision == Precision::F32 {
            "f32"
        } else {
            "f64"
        }
    );
    s.steps = Some(steps);
    s
}

/// Parses one `--grid` item, `DS:TOL:PRECISION` (downsampling ≥ 1, tolerance finite and
/// ≥ 0, `f32` or `f64`); `TOL` may be `steps=K` (exactly K ≥ 1 steps, e.g. `2:steps=3:f32`).
pub fn parse_grid_setting(s: &str) -> std::result::Result<Setting, String> {
    let parts: Vec<&str> = s.trim().split(':').map(str::trim).collect();
    let [d, t, p] = parts.as_slice() else {
        return Err(format!("`{s}`: expected DS:TOL:PRECISION, e.g. 2:1e-3:f32"));
    };
    let d: usize = d
        .parse()
        .ok()
        .filter(|&d| d >= 1)
        .ok_or_else(|| format!("`{s}`: the downsampling `{d}` must be an integer ≥ 1"))?;
    let p = match p.to_ascii_lowercase().as_str() {
        "f32" => Precision::F32,
        "f64" => Precision::F64,
        _ => return Err(format!("`{s}`: the precision `{p}` must be f32 or f64")),
    };
    if let Some(k) = t.strip_prefix("steps=") {
        let k: usize = k
            .parse()
            .ok()
            .filter(|&k| k >= 1)
            .ok_or_else(|| format!("`{s}`: the step count `{k}` must be an integer ≥ 1"))?;
        return Ok(step_setting(d, k, p));
    }
    let t: f64 = t
        .parse()
        .ok()
        .filter(|t: &f64| t.is_finite() && *t >= 0.0)
        .ok_or_else(|| format!("`{s}`: the tolerance `{t}` must be a number ≥ 0"))?;
    Ok(grid_setting(d, t, p))
}

/// The scenes of `--g`: each scene once per g, with HG phase g, named `<name>_g<g>`, its
/// effects recomputed; without `--g` the scenes as they are.
pub fn with_phases(scenes: Vec<Prepared>, g: Option<&[f64]>) -> Result<Vec<Prepared>> {
    let Some(gs) = g else {
        return Ok(scenes);
    };
    if gs.is_empty() {
        bail!("--g: no values given");
    }
    let mut out = Vec::new();
    for sc in &scenes {
        for &g in gs {
            let phase = solvers::scene::Phase::HenyeyGreenstein { g };
            phase.validate().with_context(|| format!("--g {g}"))?;
            let mut channels = sc.channels.clone();
            channels.iter_mut().for_each(|c| c.phase = phase);
            let (_, effects) =
                pipeline::effects_of(&channels, &sc.selection, &PipelineConfig::default())
                    .with_context(|| format!("the effects of {} at g = {g}", sc.name))?;
            out.push(Prepared {
                name: phase_scene_name(&sc.name, g),
                channels,
                selection: sc.selection.clone(),
                effects,
                reference: Vec::new(),
                reference_seconds: 0.0,
            });
        }
    }
    Ok(out)
}

/// The name of scene `stem` with its phase replaced by HG `g` (`--g`).
pub fn phase_scene_name(stem: &str, g: f64) -> String {
    format!("{stem}_g{g}")
}

fn run_pt(job: &Job<'_>, ctx: &mut Ctx) -> Result<Option<Run>> {
    let settings = RenderSettings {
        spp: job.setting.spp,
        seed: job.seed,
        batches: reference::pathtracer::MIN_BATCHES,
        contributions: Contributions::all(),
    };
    let mut images = Vec::new();
    let mut seconds = 0.0;
    let mut paths = 0;
    for (c, ch) in job.scene.channels.iter().enumerate() {
        let what = format!(
            "path tracer point of {} [{}], channel {c}",
            job.scene.name, job.setting.label
        );
        let tallied = ctx.tally(
            &what,
            |shard| {
                render_components_part(ch, &job.scene.effects, &settings, shard)
                    .with_context(|| what.clone())
            },
            |parts| {
                let s: f64 = parts.iter().map(|p| p.seconds).sum();
                Ok((components_from_parts(ch, &job.scene.effects, parts)?, s))
            },
        )?;
        if let Some((comp, s)) = tallied {
            images.push(to_channel_images(&comp));
            paths += comp.paths(settings.spp);
            seconds += s;
        }
    }
    if ctx.sharding() {
        return Ok(None);
    }
    Ok(Some(Run {
        images,
        seconds,
        detail: format!("spp={}", settings.spp),
        paths,
    }))
}

/// A grid run's images as exact f64 arrays for a `--task` result: per channel, total,
/// single, multiple, emission and background; the run's seconds with the first.
fn encode_images(images: &[ChannelImages], seconds: f64) -> Vec<PassSums> {
    let one = |v: &Vec<f64>, seconds: f64| PassSums {
        sums: BatchSums {
            bins: v.len(),
            total_batches: 1,
            total_samples: 1,
            first: 0,
            sizes: vec![1],
            sums: v.clone(),
        },
        seconds,
    };
    let mut out = Vec::with_capacity(IMAGES_PER_CHANNEL * images.len());
    for (c, im) in images.iter().enumerate() {
        let s = if c == 0 { seconds } else { 0.0 };
        out.push(one(&im.total, s));
        for v in [&im.single, &im.multiple, &im.emission, &im.background] {
            out.push(one(v, 0.0));
        }
    }
    out
}

/// Arrays per channel in [`encode_images`].
const IMAGES_PER_CHANNEL: usize = 5;

/// The inverse of [`encode_images`].
fn decode_images(parts: &[PassSums], detail: &str) -> Result<Run> {
    if parts.len() % IMAGES_PER_CHANNEL != 0 {
        bail!(
            "a grid task result holds {} arrays, not {IMAGES_PER_CHANNEL} per channel",
            parts.len()
        );
    }
    Ok(Run {
        images: parts
            .chunks(IMAGES_PER_CHANNEL)
            .map(|p| ChannelImages {
                total: p[0].sums.sums.clone(),
                single: p[1].sums.sums.clone(),
                multiple: p[2].sums.sums.clone(),
                emission: p[3].sums.sums.clone(),
                background: p[4].sums.sums.clone(),
            })
            .collect(),
        seconds: parts.first().map_or(0.0, |p| p.seconds),
        detail: detail.to_string(),
        paths: 0,
    })
}

fn to_channel_images(c: &PtComponents) -> ChannelImages {
    ChannelImages {
        total: c.total.mean.clone(),
        single: c.single.mean.clone(),
        multiple: c.multiple.mean.clone(),
        emission: c.emission.mean.clone(),
        background: c.background.mean.clone(),
    }
}

/// Iteration cap of the grid solves in the experiments: CDA in vacuum (D = 1/(3σ_ε)) can
/// need far more, and then reports `max_iterations` in the point's detail.
pub const MAX_ITERATIONS: usize = 5000;

/// Stratified rays per pixel and axis of the grid methods' raymarch, so that their pixels
/// average over the pixel's area like the path tracer's (box filter).
pub const PIXEL_SAMPLES: usize = 3;

/// The pipeline settings of a grid method in the experiments: the pipeline's defaults
/// (ω = 1.8, exact shadow rays) with this method, downsampling and tolerance, an iteration
/// cap of [`MAX_ITERATIONS`] and [`PIXEL_SAMPLES`]² rays per pixel.
pub fn grid_config(method: &MethodRef, downsample: usize, tolerance: f64) -> PipelineConfig {
    PipelineConfig {
        method: method.clone(),
        downsample,
        tolerance: Tolerance {
            rel: tolerance,
            max_steps: MAX_ITERATIONS,
        },
        pixel_samples: PIXEL_SAMPLES,
        ..PipelineConfig::default()
    }
}

fn run_grid(job: &Job<'_>, method: &MethodRef) -> Result<Run> {
    let config = job.setting.config(method);
    let t0 = Instant::now();
    let r = pipeline::render_channels(
        &job.scene.channels,
        &job.scene.selection,
        &config,
        job.backend,
    )
    .with_context(|| format!("rendering with {method} ({})", job.setting.label))?;
    let seconds = t0.elapsed().as_secs_f64();
    let iterations: Vec<String> = r
        .diffusion
        .iter()
        .map(|d| format!("{}:{}", d.steps, d.stop))
        .collect();
    Ok(Run {
        images: r.channels,
        seconds,
        detail: format!("iterations={}", iterations.join("/")),
        paths: 0,
    })
}

/// The reference's noise row.
#[derive(Debug, Clone, Serialize)]
pub struct ReferenceRow {
    /// Scene.
    pub scene: String,
    /// Samples per pixel.
    pub spp: u32,
    /// Seconds.
    pub seconds: f64,
    /// Relative noise of the total image.
    pub noise: f64,
    /// Channels.
    pub channels: usize,
    /// Effects rendered.
    pub effects: String,
    /// Camera paths per wall-clock second of the reference render.
    pub paths_per_second: f64,
}

/// `paths / seconds`; NaN when nothing was traced (grid methods) or no time was measured.
fn per_second(paths: u64, seconds: f64) -> f64 {
    if paths == 0 || seconds <= 0.0 {
        f64::NAN
    } else {
        paths as f64 / seconds
    }
}

/// The fastest point reaching an error target.
#[derive(Debug, Clone, Serialize)]
pub struct Fastest {
    /// Scene.
    pub scene: String,
    /// Target relative RMSE.
    pub target: f64,
    /// Method (empty if none reached it).
    pub method: String,
    /// Setting.
    pub setting: String,
    /// Backend.
    pub backend: String,
    /// Seconds.
    pub seconds: f64,
    /// Its error (debiased).
    pub error: f64,
    /// Whether the reference's noise is below half the target (else the target cannot be
    /// resolved reliably).
    pub resolvable: bool,
}

/// For each scene and target, the fastest point whose error with the reference's variance
/// removed (`error_debiased`, the estimate of its true error) is ≤ target. A target is
/// `resolvable` when the reference's own noise is below half of it.
pub fn fastest(points: &[Point]) -> Vec<Fastest> {
    let mut scenes: Vec<&str> = points.iter().map(|p| p.scene.as_str()).collect();
    scenes.dedup();
    let mut out = Vec::new();
    for s in scenes {
        for &t in &TARGETS {
            let best = points
                .iter()
                .filter(|p| p.scene == s && p.error_debiased <= t)
                .min_by(|a, b| a.seconds.total_cmp(&b.seconds));
            let noise = points
                .iter()
                .find(|p| p.scene == s)
                .map_or(f64::NAN, |p| p.error_stderr);
            out.push(match best {
                Some(p) => Fastest {
                    scene: s.into(),
                    target: t,
                    method: p.method.clone(),
                    setting: p.setting.clone(),
                    backend: p.backend.clone(),
                    seconds: p.seconds,
                    error: p.error_debiased,
                    resolvable: noise < 0.5 * t,
                },
                None => Fastest {
                    scene: s.into(),
                    target: t,
                    method: String::new(),
                    setting: String::new(),
                    backend: String::new(),
                    seconds: f64::NAN,
                    error: f64::NAN,
                    resolvable: noise < 0.5 * t,
                },
            });
        }
    }
    out
}

/// One row of `orders.csv`: a point of a method with fixed step counts (LPM: scattering
/// orders) at one of them or converged, or another grid method at the converged setting.
#[derive(Debug, Clone, Serialize)]
pub struct OrderRow {
    /// Scene.
    pub scene: String,
    /// The method as run (`lpm`; `lpm:baked` in its place on a scene with point lights).
    pub method: String,
    /// `fixed` (exactly `steps` steps), `converged` (the same method at tolerance
    /// [`STEP_TOLERANCE`]) or `comparison` (another method at that setting).
    pub kind: String,
    /// Steps run: the fixed count, or per channel as the solve reported them.
    pub steps: String,
    /// The setting's label.
    pub setting: String,
    /// Backend.
    pub backend: String,
    /// Wall-clock seconds of the render.
    pub seconds: f64,
    /// Relative RMSE against the reference.
    pub error: f64,
    /// The same with the reference variance removed.
    pub error_debiased: f64,
    /// The reference's own noise.
    pub error_stderr: f64,
}

/// The rows of `orders.csv`: for every method of `methods` with fixed step counts (as run,
/// its baked stand-in included), its fixed-step points and its converged point at the same
/// downsampling and precision (tolerance [`STEP_TOLERANCE`]), and every other grid method's
/// point at that converged setting, per scene and backend.
pub fn orders(methods: &[MethodEntry], points: &[Point], quick: bool) -> Vec<OrderRow> {
    let mut names = Vec::new();
    let mut labels = Vec::new();
    for m in methods {
        let Renderer::Pipeline(r) = &m.renderer else {
            continue;
        };
        let Some(st) = r.step_settings() else {
            continue;
        };
        names.push(m.name.clone());
        names.extend(m.baked_stand_in().map(|t| t.name));
        let d = step_downsample(quick);
        labels.extend(
            st.counts
                .iter()
                .map(|&k| (step_setting(d, k, Precision::F32).label, k)),
        );
    }
    if names.is_empty() {
        return Vec::new();
    }
    let converged = grid_setting(step_downsample(quick), STEP_TOLERANCE, Precision::F32).label;
    let grid_names: Vec<String> = methods
        .iter()
        .filter(|m| matches!(m.renderer, Renderer::Pipeline(_)))
        .map(|m| m.name.clone())
        .collect();
    let row = |p: &Point, kind: &str, steps: String| OrderRow {
        scene: p.scene.clone(),
        method: p.method.clone(),
        kind: kind.into(),
        steps,
        setting: p.setting.clone(),
        backend: p.backend.clone(),
        seconds: p.seconds,
        error: p.error,
        error_debiased: p.error_debiased,
        error_stderr: p.error_stderr,
    };
    let mut out = Vec::new();
    for p in points {
        let mine = names.contains(&p.method);
        if let Some((_, k)) = labels.iter().find(|(l, _)| *l == p.setting) {
            if mine {
                out.push(row(p, "fixed", k.to_string()));
            }
        } else if p.setting == converged {
            // Steps per channel (`37/41/43`; a stop other than `converged` is kept).
            let steps = p
                .detail
                .strip_prefix("iterations=")
                .and_then(|d| d.split(' ').next())
                .unwrap_or_default()
                .split('/')
                .map(|c| c.strip_suffix(":converged").unwrap_or(c))
                .collect::<Vec<_>>()
                .join("/");
            if mine {
                out.push(row(p, "converged", steps));
            } else if grid_names.contains(&p.method) {
                out.push(row(p, "comparison", steps));
            }
        }
    }
    out
}

/// The points on the Pareto front (no other point both faster and more accurate), by time.
pub fn pareto(points: &[&Point]) -> Vec<(f64, f64)> {
    let mut v: Vec<(f64, f64)> = points
        .iter()
        .filter(|p| p.error.is_finite() && p.seconds > 0.0)
        .map(|p| (p.seconds, p.error))
        .collect();
    v.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut front = Vec::new();
    let mut best = f64::INFINITY;
    for (t, e) in v {
        if e < best {
            best = e;
            front.push((t, e));
        }
    }
    front
}

/// The methods of a run: `--methods`, or every method ([`methods`]).
fn method_entries(args: &Args) -> Result<Vec<MethodEntry>> {
    Ok(match &args.methods {
        None => methods(),
        Some(list) => crate::methods::parse_list(
            &list
                .split(',')
                .map(|s| s.trim().to_string())
                .collect::<Vec<_>>(),
        )
        .context("--methods")?
        .into_iter()
        .map(MethodEntry::from)
        .collect(),
    })
}

/// The columns of `orders.csv` (promised, and read back by the report).
const ORDER_COLUMNS: &[&str] = &[
    "scene",
    "method",
    "kind",
    "steps",
    "setting",
    "backend",
    "seconds",
    "error",
    "error_debiased",
    "error_stderr",
];

/// Runs the atlas; returns its points.
pub fn run(args: &Args) -> Result<Vec<Point>> {
    crate::experiment::run::<AccuracyCost>(args)
}

fn run_in(ctx: &mut Ctx, args: &Args) -> Result<Vec<Point>> {
    let quick = args.common.quick;
    let ref_spp = args.reference_spp.unwrap_or(if quick { 256 } else { 4096 });
    let spp: Vec<u32> = match &args.spp {
        Some(v) => v.clone(),
        None if quick => vec![16, 32],
        None => vec![16, 64, 256, 1024, 2048],
    };
    if let Some(s) = spp
        .iter()
        .find(|&&s| s < reference::pathtracer::MIN_BATCHES)
    {
        bail!(
            "--spp: {s} is below {} (the batches of a standard error)",
            reference::pathtracer::MIN_BATCHES
        );
    }
    let coarsen = coarsen_factor(args.coarsen, quick)?;
    let resolution = match &args.resolution {
        Some(s) => Some(parse_resolution(s)?),
        None if quick => Some([24, 24]),
        None => None,
    };
    let methods = method_entries(args)?;
    let scenes = scene_files(args.scenes.as_deref(), DEFAULT_SCENES)?;
    let backends = args.backend.open()?;
    let params = serde_json::json!({
        "scenes": scenes, "reference_spp": ref_spp, "spp": spp, "coarsen": coarsen,
        "resolution": resolution, "seed": args.seed, "g": args.g,
        "grid": args.grid.as_ref().map(|v| v.iter().map(|s| s.label.clone()).collect::<Vec<_>>()),
        "methods": methods.iter().map(|m| m.name.clone()).collect::<Vec<_>>(),
        "targets": TARGETS,
    });
    let prepared = scenes
        .iter()
        .map(|p| load(p, coarsen, resolution))
        .collect::<Result<Vec<_>>>()?;
    let mut prepared = with_phases(prepared, args.g.as_deref())?;
    let grid = args.grid.as_deref();
    let mut work = crate::cost::Estimate::new();
    for scene in &prepared {
        work.add(
            format!("{}: the reference, {ref_spp} spp", scene.name),
            crate::cost::pt_render(&scene.channels, &scene.effects, ref_spp),
        );
        for m in &methods {
            for st in m.settings(quick, &spp, grid) {
                if st.ordinate_set_only && !uses_ordinate_set(scene) {
                    continue;
                }
                let backends_run = backends
                    .list(st.precision)
                    .iter()
                    .filter(|b| m.renderer_for(&st).supports(b, st.precision))
                    .count() as f64;
                let one = match &m.renderer {
                    Renderer::PathTracer => {
                        crate::cost::pt_render(&scene.channels, &scene.effects, st.spp)
                    }
                    Renderer::Pipeline(r) => {
                        crate::cost::pipeline_render(&scene.channels, &st.config(r))
                    }
                };
                work.add(
                    format!("{}: {} [{}]", scene.name, m.name, st.label),
                    one * backends_run,
                );
            }
        }
    }
    let mut jobs = Vec::new();
    for m in &methods {
        for s in m.settings(quick, &spp, grid) {
            for b in backends.list(s.precision) {
                if !m.renderer_for(&s).supports(&b, s.precision) {
                    continue;
                }
                jobs.push((m, s.clone(), b));
            }
        }
    }
    let tasks = prepared.len() * (1 + jobs.len());
    if args.list_tasks {
        let mut k = 0;
        for scene in &prepared {
            println!("{k}\t{}\treference\tspp={ref_spp}\tcpu-f64", scene.name);
            k += 1;
            for (m, s, b) in &jobs {
                let name = s
                    .method
                    .as_ref()
                    .map_or_else(|| m.name.clone(), |o| o.name());
                println!("{k}\t{}\t{name}\t{}\t{b}", scene.name, s.label);
                k += 1;
            }
        }
        return Err(crate::common::PrintOnly("--list-tasks").into());
    }
    if let Some(k) = args.task {
        ctx.set_task(k, u32::try_from(tasks).unwrap_or(u32::MAX))?;
    }
    ctx.work(&work)?;
    ctx.start(params)?;
    let out = ctx;
    out.record("backends", backends.meta());

    let mut points = Vec::new();
    let mut refs = Vec::new();
    let mut skipped = Vec::new();
    for scene in &mut prepared {
        out.unit();
        if !render_reference(out, scene, ref_spp, args.seed)? && !out.sharding() {
            bail!("the reference of {} is incomplete", scene.name);
        }
        out.timing(format!("{}/reference", scene.name), scene.reference_seconds);
        let noise = scene.noise();
        refs.push(ReferenceRow {
            scene: scene.name.clone(),
            spp: ref_spp,
            seconds: scene.reference_seconds,
            noise,
            channels: scene.channels.len(),
            effects: scene.effects.names(),
            paths_per_second: per_second(
                scene.reference.iter().map(|c| c.paths(ref_spp)).sum(),
                scene.reference_seconds,
            ),
        });
        let bar = progress(jobs.len() as u64, &args.common, &scene.name);
        for (m, s, b) in &jobs {
            if !out.unit() || (s.ordinate_set_only && !uses_ordinate_set(scene)) {
                bar.inc(1);
                continue;
            }
            // A method whose plan refuses the scene's lights runs as its baked form where the
            // registry offers one (the point's `method` names what ran).
            let (entry, in_place_of) = match refusal(m, scene, s) {
                None => (std::borrow::Cow::Borrowed(*m), None),
                Some(reason) => match m
                    .baked_stand_in()
                    .filter(|t| s.method.is_none() && refusal(t, scene, s).is_none())
                {
                    Some(t) => (std::borrow::Cow::Owned(t), Some(m.name.clone())),
                    None => {
                        eprintln!(
                            "{} {} [{}] {b}: skipped: {reason}",
                            scene.name, m.name, s.label
                        );
                        skipped.push(Skipped {
                            scene: scene.name.clone(),
                            method: s
                                .method
                                .as_ref()
                                .map_or_else(|| m.name.clone(), |o| o.name()),
                            setting: s.label.clone(),
                            backend: b.to_string(),
                            reason,
                        });
                        bar.inc(1);
                        continue;
                    }
                },
            };
            let job = Job {
                scene,
                setting: s,
                backend: b,
                seed: args.seed + 1000,
            };
            let Some(r) = entry.run(&job, out)? else {
                bar.inc(1);
                continue;
            };
            let (error, debiased, single, multiple) = errors(scene, &r.images);
            points.push(Point {
                scene: scene.name.clone(),
                method: s
                    .method
                    .as_ref()
                    .map_or_else(|| entry.name.clone(), |o| o.name()),
                setting: s.label.clone(),
                backend: match entry.renderer {
                    Renderer::PathTracer => "cpu-f64".into(),
                    Renderer::Pipeline(_) => b.to_string(),
                },
                seconds: r.seconds,
                error,
                error_stderr: noise,
                error_debiased: debiased,
                error_single: single,
                error_multiple: multiple,
                detail: match &in_place_of {
                    None => r.detail,
                    Some(m) => format!("{} in place of {m}", r.detail),
                },
                g: scene
                    .channels
                    .first()
                    .map_or(0.0, |c| c.phase.mean_cosine()),
                paths_per_second: per_second(r.paths, r.seconds),
            });
            if let Some(p) = points.last() {
                let line = format!(
                    "{} {} [{}] {}: {:.3} s, error {:.4}",
                    p.scene, p.method, p.setting, p.backend, p.seconds, p.error
                );
                crate::progress::note(&bar, &line);
            }
            bar.inc(1);
        }
        bar.finish_and_clear();
        if !out.sharding() {
            plot_scene(out, &scene.name, &points)?;
        }
    }
    if out.sharding() {
        return Ok(points);
    }
    out.csv("points.csv", &points)?;
    out.csv("references.csv", &refs)?;
    out.csv("skipped.csv", &skipped)?;
    out.csv("fastest.csv", &fastest(&points))?;
    out.csv("orders.csv", &orders(&methods, &points, quick))?;
    Ok(points)
}

fn plot_scene(out: &Ctx, scene: &str, points: &[Point]) -> Result<()> {
    let mine: Vec<&Point> = points.iter().filter(|p| p.scene == scene).collect();
    let mut keys: Vec<(String, String)> = mine
        .iter()
        .map(|p| (p.method.clone(), p.backend.clone()))
        .collect();
    keys.sort();
    keys.dedup();
    let mut series: Vec<Series> = keys
        .iter()
        .enumerate()
        .map(|(i, (m, b))| {
            let pts = mine
                .iter()
                .filter(|p| &p.method == m && &p.backend == b && p.error.is_finite())
                .map(|p| (p.seconds, p.error))
                .collect();
            Series::new(format!("{m} ({b})"), pts, Style::Points, i)
        })
        .collect();
    series.push(Series::new(
        "Pareto front",
        pareto(&mine),
        Style::Dashed,
        keys.len(),
    ));
    if let Some(noise) = mine.first().map(|p| p.error_stderr)
        && noise.is_finite()
        && noise > 0.0
    {
        let (lo, hi) = mine.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), p| {
            (lo.min(p.seconds), hi.max(p.seconds))
        });
        series.push(Series::new(
            "reference noise",
            vec![(lo, noise), (hi, noise)],
            Style::Line,
            keys.len() + 1,
        ));
    }
    plot(
        &out.path(&format!("pareto_{scene}.png")),
        &format!("{scene}: image error vs time"),
        &Axis::log("wall time (s)"),
        &Axis::log("relative RMSE vs path-traced reference"),
        &series,
    )
}

/// The section of `orders.csv`: per scene and backend, the fixed-step method's debiased error
/// (and seconds) at each count and converged, beside every other grid method at the converged
/// setting.
fn orders_report(t: &crate::report::Table) -> String {
    let mut counts: Vec<String> = t
        .rows()
        .filter(|r| r.get("kind") == "fixed")
        .map(|r| r.get("steps").to_string())
        .collect();
    counts.sort_by_key(|c| c.parse::<usize>().unwrap_or(usize::MAX));
    counts.dedup();
    let mut others: Vec<String> = Vec::new();
    for r in t.rows().filter(|r| r.get("kind") == "comparison") {
        if !others.iter().any(|o| o == r.get("method")) {
            others.push(r.get("method").to_string());
        }
    }
    let cell = |r: Option<crate::report::Row<'_>>| match r {
        Some(r) => format!(
            "{} ({} s)",
            r.fixed("error_debiased", 3),
            r.fixed("seconds", 1)
        ),
        None => "–".into(),
    };
    let mut header: Vec<String> = vec!["scene".into(), "backend".into(), "LPM as run".into()];
    header.extend(
        counts
            .iter()
            .map(|k| format!("{k} order{}", if k == "1" { "" } else { "s" })),
    );
    header.push("converged".into());
    header.extend(others.iter().cloned());
    let mut rows = Vec::new();
    let mut setting = String::new();
    for sc in t.distinct("scene") {
        for b in t.distinct("backend") {
            let mine: Vec<_> = t
                .rows()
                .filter(|r| r.get("scene") == sc && r.get("backend") == b)
                .collect();
            let Some(first) = mine.iter().find(|r| r.get("kind") != "comparison") else {
                continue;
            };
            let name = first.get("method").to_string();
            let mut row = vec![sc.clone(), b.clone(), name.clone()];
            for k in &counts {
                row.push(cell(mine.iter().copied().find(|r| {
                    r.get("kind") == "fixed" && r.get("steps") == k && r.get("method") == name
                })));
            }
            let conv = mine
                .iter()
                .copied()
                .find(|r| r.get("kind") == "converged" && r.get("method") == name);
            if let Some(c) = &conv {
                setting = c.get("setting").to_string();
            }
            row.push(match conv {
                Some(c) => format!("{} [{}]", cell(Some(c)), c.get("steps")),
                None => "–".into(),
            });
            for o in &others {
                row.push(cell(
                    mine.iter()
                        .copied()
                        .find(|r| r.get("kind") == "comparison" && r.get("method") == o),
                ));
            }
            rows.push(row);
        }
    }
    let header: Vec<&str> = header.iter().map(String::as_str).collect();
    format!(
        "### LPM by scattering order, beside the other methods (`orders.csv`)\n\n\
         Debiased relative RMSE against the path-traced reference (wall seconds of the whole render). \
         LPM runs exactly k orders at the downsampling of the converged column (`{setting}`, orders \
         per channel in brackets), where every other method is shown too. `lpm` takes the lights as \
         boundary radiance: k orders render scattering orders 1 … k (k = 1 is single scattering \
         alone). On a scene with a point light (plume) `lpm` cannot take it, and the atlas runs \
         `lpm:baked` (the registry's baked form, spec D13's first collision): its k orders render \
         orders 1 … k + 1.\n\n{}\n",
        table(&header, rows)
    )
}

/// The folder of the atlas's anisotropy sub-run (see [`AccuracyCost`]'s figure runs).
pub const HG_DIR: &str = "accuracy_hg";
/// Its title.
pub const HG_TITLE: &str = "Accuracy atlas: anisotropy variants under HG g (paper vs similarity)";
/// Its datasets (the noise cloud and the shell/core scene, phase replaced by HG g).
pub const HG_SCENES: [&str; 2] = ["scenes/cloud_directional.toml", "scenes/shell_core.toml"];
/// Its values of g (issue 12, acceptance 3).
pub const HG_G: &str = "0.3,0.7,0.9,0.99";
/// Its methods: both variants of CDA, FLD-LP and LBM, and POP (issue 17, acceptance 4: its
/// errors by g next to the others; it has no variant, a lobe's anisotropy is its own Eq 4).
pub const HG_METHODS: &str = "cda,cda:similarity,fld:lp,fld:lp:similarity,lbm,lbm:similarity,pop";
/// The size of its full run: the scenes coarsened to 32³, 32×32 pixels, a 2048-spp reference.
pub const HG_FULL: [&str; 6] = [
    "--coarsen",
    "2",
    "--resolution",
    "32,32",
    "--reference-spp",
    "2048",
];

/// The accuracy vs time atlas in the registry.
#[derive(Debug)]
pub struct AccuracyCost;

/// The columns of `fastest.csv` (promised, and read back by the report).
const FASTEST_COLUMNS: &[&str] = &[
    "scene",
    "target",
    "method",
    "setting",
    "backend",
    "seconds",
    "error",
    "resolvable",
];

impl Experiment for AccuracyCost {
    const NAME: &'static str = "accuracy_cost";
    const TITLE: &'static str = "Accuracy vs time atlas";
    const BACKEND: BackendSupport = BackendSupport::Flag;
    const SHARDS: bool = true;
    type Args = Args;
    type Summary = Vec<Point>;

    fn common(args: &Args) -> &CommonArgs {
        &args.common
    }

    /// The atlas, and its anisotropy sub-run (issue 12, acceptance 3) into its own folder
    /// `accuracy_hg`: [`HG_SCENES`] at HG g ∈ [`HG_G`], both anisotropy variants of CDA,
    /// FLD-LP and LBM, and POP ([`HG_METHODS`]) at tolerance 1e-3 in f32 (quick: downsampling 4; full:
    /// 4 and 2) and no path-tracer points; [`HG_FULL`] sizes the full run.
    fn figure_runs(quick: bool) -> Vec<FigureRun> {
        let root = crate::common::workspace_root();
        let scenes: Vec<String> = HG_SCENES
            .iter()
            .map(|s| root.join(s).display().to_string())
            .collect();
        let mut hg = FigureRun::new(HG_DIR, HG_TITLE).args([
            "--scenes".to_string(),
            scenes.join(","),
            "--g".into(),
            HG_G.into(),
            "--methods".into(),
            HG_METHODS.into(),
            "--grid".into(),
            if quick {
                "4:1e-3:f32"
            } else {
                "4:1e-3:f32,2:1e-3:f32"
            }
            .into(),
        ]);
        if !quick {
            hg = hg.args(HG_FULL.iter().copied());
        }
        vec![FigureRun::new(Self::NAME, Self::TITLE), hg]
    }

    fn promises(args: &Args) -> Vec<Promise> {
        let mut p = vec![
            Promise::csv(
                "points.csv",
                &[
                    "scene",
                    "method",
                    "setting",
                    "backend",
                    "seconds",
                    "error",
                    "error_stderr",
                    "error_debiased",
                    "error_single",
                    "error_multiple",
                    "detail",
                    "g",
                ],
            ),
            Promise::csv(
                "references.csv",
                &["scene", "spp", "seconds", "noise", "channels", "effects"],
            ),
            Promise::csv("fastest.csv", FASTEST_COLUMNS),
        ];
        // The fixed-step table, when the default ladder runs a method that has fixed steps.
        let stepped = method_entries(args)
            .unwrap_or_default()
            .iter()
            .any(|m| matches!(&m.renderer, Renderer::Pipeline(r) if r.step_settings().is_some()));
        if stepped && args.grid.is_none() {
            p.push(Promise::csv("orders.csv", ORDER_COLUMNS));
        }
        // Plots are named after the scene, which the registered datasets name after their file.
        for path in scene_files(args.scenes.as_deref(), DEFAULT_SCENES).unwrap_or_default() {
            if let Some(stem) = path.file_stem() {
                let stem = stem.to_string_lossy();
                let names = match &args.g {
                    None => vec![stem.to_string()],
                    Some(gs) => gs.iter().map(|&g| phase_scene_name(&stem, g)).collect(),
                };
                for name in names {
                    p.push(Promise::file(format!("pareto_{name}.png")));
                }
            }
        }
        p
    }

    fn run(ctx: &mut Ctx, args: &Args) -> Result<Self::Summary> {
        run_in(ctx, args)
    }

    fn report(s: &Section<'_>) -> Result<String> {
        let fastest = s.csv("fastest.csv")?;
        fastest.require(FASTEST_COLUMNS)?;
        let points = s.csv("points.csv")?;
        points.require(&[
            "scene",
            "method",
            "setting",
            "seconds",
            "error",
            "error_stderr",
        ])?;
        let mut out = String::from(
            "Every method setting on every dataset against a path-traced reference. `error_stderr` in `points.csv` \
             is the reference's own relative noise, the floor below which errors cannot be resolved. Methods: the \
             path tracer at increasing spp, and the grid pipeline with each registered multiple-scattering method \
             at diffusion downsampling 4, 2, 1, tolerances and precisions (`setting`).\n\n\
             ### Fastest to 5 %, 2 % and 1 % relative RMSE (debiased: the reference's variance removed)\n\n",
        );
        let rows = fastest.rows().map(|r| {
            let what = if r.get("method").is_empty() {
                "none reached it"
            } else {
                r.get("method")
            };
            let floor = if r.flag("resolvable") {
                ""
            } else {
                " (below the reference noise)"
            };
            vec![
                r.get("scene").to_string(),
                format!("{:.0} %", 100.0 * r.num("target")),
                format!("{what}{floor}"),
                r.get("setting").to_string(),
                r.get("backend").to_string(),
                r.fixed("seconds", 2),
                r.fixed("error", 4),
            ]
        });
        out.push_str(&table(
            &[
                "scene", "target", "fastest", "setting", "backend", "time (s)", "error",
            ],
            rows,
        ));
        out.push_str("\n### Best error per method and scene (and its time)\n\n");
        let mut rows = Vec::new();
        for sc in points.distinct("scene") {
            for m in points.distinct("method") {
                if let Some(p) = points
                    .rows()
                    .filter(|p| p.get("scene") == sc && p.get("method") == m)
                    .min_by(|a, b| a.num("error").total_cmp(&b.num("error")))
                {
                    rows.push(vec![
                        sc.clone(),
                        m.clone(),
                        p.fixed("error", 4),
                        p.get("setting").to_string(),
                        p.fixed("seconds", 2),
                        p.fixed("error_stderr", 4),
                    ]);
                }
            }
        }
        out.push_str(&table(
            &[
                "scene",
                "method",
                "best error",
                "setting",
                "time (s)",
                "reference noise",
            ],
            rows,
        ));
        out.push('\n');
        if s.path("orders.csv").is_file() {
            let t = s.csv("orders.csv")?;
            if !t.is_empty() {
                t.require(ORDER_COLUMNS)?;
                out.push_str(&orders_report(&t));
            }
        }
        if let Some(variants) = crate::report::anisotropy_variants(&points) {
            out.push_str(&variants);
            out.push('\n');
        }
        out.push_str(
            &s.pngs(
                points
                    .distinct("scene")
                    .iter()
                    .map(|sc| format!("pareto_{sc}.png")),
            ),
        );
        Ok(out)
    }
}
