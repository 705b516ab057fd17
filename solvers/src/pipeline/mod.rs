//! The rendering pipeline of FLD Fig 2, driven by the effects a scene calls for.
//!
//! 1. **Light baking** ([`bake`]): per directional or point light a deep shadow map and the
//!    source q_ri = σs·L_ri (FLD Eq 6). CPU (rayon).
//! 2. **Multiple scattering** (`diffusion_solve`): any registered [`crate::Method`]
//!    ([`PipelineConfig::method`]: CDA, FLD, LBM, …, on the caller's [`Backend`]: CPU f32/f64
//!    or GPU) for φ with source q_ri + j, on the grid
//!    restricted by [`PipelineConfig::downsample`] (the paper uses 4; see [`restrict`] for
//!    the conservative restriction) and padded by [`PipelineConfig::pad`] vacuum voxels.
//! 3. **Primary raymarch** ([`raymarch`], FLD Eq 3 with the source of FLD Eq 8): single
//!    scattering with the scene's phase function, σs φ/4π with φ upsampled trilinearly,
//!    j/4π, and the environment seen through the medium (L_env·T, order 0, unless
//!    `[camera] hide_background`), as separate images. CPU (rayon). With
//!    `[medium] interpolation = "trilinear"` only the restriction follows the interpolant
//!    ([`restrict::restrict_with`]); baking and the raymarch use the per-voxel values.
//!
//! **Methods that take the lights themselves** ([`crate::method::LightInput::Direct`]: LPM,
//! POP) get no baked q_ri, only j when emission is rendered, and [`Problem::lights`]; their
//! φ holds what the contract in [`crate::method::LightInput`] says (a directional light's
//! scattered light only, so its single scattering stays the exact raymarch's; an
//! environment's every order, so its single scattering is σs·φ/4π). The plan's `computes`
//! says which pass renders which effect.
//!
//! [`planner`] turns the effect set (implied by the scene, restricted by its `[effects]`
//! table and by [`PipelineConfig::effects`]) into the minimal list of passes; every render
//! returns the plan and the passes that ran, with their wall-clock seconds.
//!
//! **Colour.** RGB is three independent monochrome problems
//! ([`crate::scene::SceneFile::channels`]); [`render_channels`] plans once for the union of
//! the channels' effects and runs every pass per channel.
//!
//! **Components and scattering orders** (what the path tracer must render to compare, see
//! [`crate::scene::effects`]): `single` = order 1 from lights; `multiple` = orders ≥ 2 from
//! lights plus orders ≥ 1 from emission (φ is sourced by q_ri + j, FLD Eq 12); `emission` =
//! order-0 emission; `background` = order 0 from the lights (the environment seen through
//! the medium, L_env·T, unless `[camera] hide_background`). `total` is their sum. Images are radiance in physical units
//! (power per area per steradian), row-major, top-left first.
//!
//! **Anisotropy.** Single scattering sees the phase function. The multiple-scattering pass
//! sees it only if its method says so ([`crate::method::Capabilities::anisotropic`]: LBM's
//! paper variant, on the lattice); CDA and FLD scatter isotropically with the medium as given,
//! as in the paper, and every one of the three has the similarity variant `:similarity`
//! (σs' = (1 − g)σs, [`crate::method::AnisotropyScaling`]), whose source is δ-scaled as
//! well: the lights are baked again through σt' = σa + σs' and scattered at σs' (the forward
//! fraction g of each scattering stays in the beam). The raymarch's in-scattering of φ keeps
//! the true σs (in-scattering of a nearly isotropic field is σs φ/4π whatever the phase
//! function). The plan's `diffusion_solve` records which variant ran, and the plan warns when
//! `paper` runs with |g| > 0.5.

pub mod bake;
pub mod geometry;
pub mod image;
pub mod planner;
pub mod raymarch;
pub mod restrict;

pub use planner::{Pass, Plan, Planned, Skipped};

use crate::fld::{FldMethod, FluxLimiter};
use crate::method::{LightInput, MethodRef, Problem, Stop, Tolerance};
use crate::scene::{EffectSelection, Effects, EffectsError, Scene, SceneFile};
use crate::{Backend, SolverError};
use bake::BakedLight;
pub use bake::Shadows;
use raymarch::Term;
use serde::Serialize;
use std::time::Instant;
use thiserror::Error;

/// Errors of the pipeline.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum PipelineError {
    /// A solver or parameter error.
    #[error(transparent)]
    Solver(#[from] SolverError),
    /// An invalid effect selection.
    #[error(transparent)]
    Effects(#[from] EffectsError),
    /// The scene has no camera.
    #[error("the scene has no [camera]; the pipeline renders camera images")]
    NoCamera,
    /// A light the plan needs is of a kind the grid pipeline cannot bake.
    #[error(
        "light {index} is {} light, which the grid pipeline does not support (directional and point lights only); exclude its effects or use the path tracer",
        crate::error::indefinite(kind)
    )]
    UnsupportedLight {
        /// Index of the light.
        index: usize,
        /// Its kind.
        kind: &'static str,
    },
    /// The chosen multiple-scattering method cannot render what the plan needs.
    #[error("method {method} cannot {what}")]
    MethodCannot {
        /// The method's name.
        method: String,
        /// What it cannot do.
        what: &'static str,
    },
    /// No channels, or channels that differ in more than their medium's values.
    #[error("colour channels must be 1 or 3 scenes that differ only in their medium values: {0}")]
    Channels(String),
}

/// Settings of a render.
#[derive(Debug, Clone, PartialEq)]
pub struct PipelineConfig {
    /// The multiple-scattering method (any of [`crate::method::METHODS`]; default FLD with
    /// the Levermore–Pomraning limiter and ω = 1.8).
    pub method: MethodRef,
    /// Grid downsampling factor of the diffusion solve (≥ 1; the paper's is 4).
    pub downsample: usize,
    /// Vacuum voxels added around the restricted grid (its outermost layer is the Dirichlet
    /// φ = 0 boundary). Default 1.
    pub pad: usize,
    /// When the multiple-scattering solve stops ([`Tolerance`], one meaning for every
    /// method). Default: R̄/j̄ < 10⁻⁴ (the paper's stopping level for its renderings, FLD
    /// Section 6.2), at most 20 000 steps (a solve that stops there is reported in
    /// [`Rendered::diffusion`], not an error). FLD's default ω = 1.8 was measured at
    /// downsample 4 (18³ solve grids): ω = 1.0 / 1.5 / 1.8 took 372 / 189 / 150 iterations on
    /// `nebula`, and on `shell_core` (vacuum between a dense core and a shell) 20 000 (stalled
    /// at 6·10⁻²) / 20 000 (5.6·10⁻³) / 16 125.
    pub tolerance: Tolerance,
    /// Raymarch sub-step as a fraction of the voxel edge Δl (default 0.5).
    pub step: f64,
    /// Stratified ray positions per pixel and axis (default 1: the pixel centre).
    pub pixel_samples: usize,
    /// A further restriction of the effects (applied after the scene file's).
    pub effects: EffectSelection,
    /// Optical depth to the lights in the single-scattering raymarch: exact shadow rays
    /// (default) or the paper's deep shadow map (see [`bake`]).
    pub shadows: Shadows,
}

impl Default for PipelineConfig {
    fn default() -> Self {
        Self {
            method: MethodRef::new(Box::new(FldMethod::new(FluxLimiter::LevermorePomraning))),
            downsample: 4,
            pad: 1,
            tolerance: Tolerance::default(),
            step: 0.5,
            pixel_samples: 1,
            effects: EffectSelection::all(),
            shadows: Shadows::Exact,
        }
    }
}

impl PipelineConfig {
    /// Checks every parameter.
    pub fn validate(&self) -> Result<(), PipelineError> {
        if self.downsample == 0 {
            return Err(SolverError::BadParameter {
                name: "downsample",
                value: 0.0,
                reason: "must be at least 1",
            }
            .into());
        }
        if !(self.step.is_finite() && self.step > 0.0) {
            return Err(SolverError::BadParameter {
                name: "step",
                value: self.step,
                reason: "the raymarch step (fraction of a voxel) must be finite and > 0",
            }
            .into());
        }
        if self.pixel_samples == 0 {
            return Err(SolverError::BadParameter {
                name: "pixel_samples",
                value: 0.0,
                reason: "must be at least 1",
            }
            .into());
        }
        self.tolerance.validate()?;
        Ok(())
    }
}

/// The images of one colour channel: radiance per pixel, row-major.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ChannelImages {
    /// single + multiple + emission + background.
    pub total: Vec<f64>,
    /// Order 1 from lights.
    pub single: Vec<f64>,
    /// Orders ≥ 2 from lights, orders ≥ 1 from emission.
    pub multiple: Vec<f64>,
    /// Order-0 emission.
    pub emission: Vec<f64>,
    /// Order-0 light from the lights: the environment seen through the medium.
    pub background: Vec<f64>,
}

/// A pass that ran.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PassRecord {
    /// [`Pass::name`].
    pub name: String,
    /// Colour channel (0 for monochrome).
    pub channel: usize,
    /// Wall-clock seconds.
    pub seconds: f64,
}

/// What the diffusion solve of one channel did.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DiffusionRecord {
    /// Colour channel.
    pub channel: usize,
    /// The solve grid (restricted and padded).
    pub grid: [usize; 3],
    /// Its voxel edge.
    pub dl: f64,
    /// The method ([`crate::Method::name`]).
    pub method: String,
    /// Steps run (FLD iterations, LB lattice steps).
    pub steps: usize,
    /// The method's last convergence measure ([`crate::Solution::last_change`]).
    pub last_change: f64,
    /// Why it stopped: `converged`, `cap` or `non_finite`.
    pub stop: Stop,
    /// Seconds of the steps (solver's own timer).
    pub solve_seconds: f64,
    /// Seconds of the solver's setup.
    pub setup_seconds: f64,
    /// Backend, e.g. `cpu-f64`.
    pub backend: String,
    /// The solve grid with its box (origin and Δl; not serialised, `grid` and `dl` are).
    #[serde(skip)]
    pub solve_grid: crate::Grid,
    /// The solution φ on [`DiffusionRecord::solve_grid`], one value per voxel in the grid's
    /// index order (not serialised: it is a field, not a record; `render` writes it as the
    /// `fluence` output).
    #[serde(skip)]
    pub phi: Vec<f64>,
}

/// A rendered scene.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Rendered {
    /// Pixels per row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// One entry per colour channel (1 or 3).
    pub channels: Vec<ChannelImages>,
    /// The plan.
    pub plan: Plan,
    /// The passes that ran, in order, per channel.
    pub passes_run: Vec<PassRecord>,
    /// The diffusion solves (empty if none ran).
    pub diffusion: Vec<DiffusionRecord>,
}

impl Rendered {
    /// Total seconds of the passes named `name` over all channels.
    pub fn seconds_of(&self, name: &str) -> f64 {
        self.passes_run
            .iter()
            .filter(|p| p.name == name)
            .map(|p| p.seconds)
            .sum()
    }

    /// Total seconds of all passes.
    pub fn total_seconds(&self) -> f64 {
        self.passes_run.iter().map(|p| p.seconds).sum()
    }
}

/// Renders a monochrome scene with its implied effects, restricted by `config.effects`.
pub fn render(
    scene: &Scene,
    config: &PipelineConfig,
    backend: &Backend<'_>,
) -> Result<Rendered, PipelineError> {
    render_channels(
        std::slice::from_ref(scene),
        &EffectSelection::all(),
        config,
        backend,
    )
}

/// Renders a scene file: every colour channel, with the file's `[effects]` restriction and
/// then `config.effects`.
pub fn render_file(
    file: &SceneFile,
    config: &PipelineConfig,
    backend: &Backend<'_>,
) -> Result<Rendered, PipelineError> {
    render_channels(&file.channels(), &file.effects, config, backend)
}

/// The effects the channels imply (union), and those rendered after `selection` and
/// `config.effects`.
pub fn effects_of(
    channels: &[Scene],
    selection: &EffectSelection,
    config: &PipelineConfig,
) -> Result<(Effects, Effects), PipelineError> {
    let first = channels
        .first()
        .ok_or_else(|| PipelineError::Channels("no channels".into()))?;
    let lights = first.lights.len();
    let implied = channels
        .iter()
        .fold(Effects::none(), |acc, s| acc.union(&s.implied_effects()));
    let effects = implied
        .restrict(selection, lights)?
        .restrict(&config.effects, lights)?;
    Ok((implied, effects))
}

/// The plan of a render, without running it (for `--explain`).
pub fn plan_channels(
    channels: &[Scene],
    selection: &EffectSelection,
    config: &PipelineConfig,
) -> Result<Plan, PipelineError> {
    config.validate()?;
    let (implied, effects) = effects_of(channels, selection, config)?;
    let mut plan = planner::plan(
        &channels[0].lights,
        &implied,
        &effects,
        config.method.get(),
        config.downsample,
    )?;
    let g = plan.effects.apply_phase(channels[0].phase).mean_cosine();
    if plan.runs("diffusion_solve")
        && config.method.anisotropy() == Some(crate::method::AnisotropyScaling::Paper)
        && g.abs() > 0.5
    {
        let what = if config.method.capabilities().anisotropic {
            "scatters with the lattice's Henyey–Greenstein kernel (the paper's variant `paper`), \
             whose discrete mean cosine overshoots g on D3Q19 for |g| > 0.5"
        } else {
            "scatters isotropically with σs as given (the paper's variant `paper`)"
        };
        plan.warnings.push(format!(
            "{} {what} under g = {g}; the variant `:similarity` uses σs' = (1 − g)σs",
            config.method.name()
        ));
    }
    Ok(plan)
}

/// The source q_ri of the similarity variant (`:similarity`, [`AnisotropyScaling`]) under a
/// phase function with g ≠ 0: each baked light baked again through the scaled medium
/// (σt' = σa + σs', σs' = (1 − g)σs) and q_ri = σs'·L_ri' (FLD Eq 6 on the scaled medium), the
/// δ-scaling's diffuse source: the forward fraction g of each scattering stays in the
/// reduced beam L_ri', which the scaled medium attenuates less. `None` for the paper's variant
/// or g = 0 (the source is the medium's own q_ri). Measured against keeping σs·L_ri
/// (`results/accuracy_hg`, see the `fld` module docs).
///
/// [`AnisotropyScaling`]: crate::method::AnisotropyScaling
fn similarity_source(
    config: &PipelineConfig,
    medium: &crate::Medium<f64>,
    phase: crate::scene::Phase,
    baked: &[BakedLight],
    lights: &[crate::scene::Light],
) -> Result<Option<Vec<f64>>, PipelineError> {
    let Some(a) = config.method.anisotropy() else {
        return Ok(None);
    };
    if a != crate::method::AnisotropyScaling::Similarity {
        return Ok(None);
    }
    let Some(scaled) = a.apply(medium, phase) else {
        return Ok(None);
    };
    let mut rebaked = Vec::with_capacity(baked.len());
    for b in baked {
        let light = lights.get(b.index).unwrap_or(&b.light);
        rebaked.push(bake::bake(&scaled, b.index, light).ok_or(
            PipelineError::UnsupportedLight {
                index: b.index,
                kind: "non-bakeable",
            },
        )?);
    }
    Ok(Some(bake::q_ri(&scaled, &rebaked)))
}

/// Renders 1 or 3 colour channels (scenes that differ only in their medium values) with
/// the effects they imply, restricted by `selection` and then `config.effects`.
pub fn render_channels(
    channels: &[Scene],
    selection: &EffectSelection,
    config: &PipelineConfig,
    backend: &Backend<'_>,
) -> Result<Rendered, PipelineError> {
    check_channels(channels)?;
    let plan = plan_channels(channels, selection, config)?;
    let camera = channels[0].camera.ok_or(PipelineError::NoCamera)?;
    let [width, height] = camera.resolution;
    let npix = width * height;
    let mut passes_run = Vec::new();
    let mut diffusion = Vec::new();
    let mut images = Vec::new();
    for (c, scene) in channels.iter().enumerate() {
        let medium = &scene.medium;
        let phase = plan.effects.apply_phase(scene.phase);
        let mut baked: Vec<BakedLight> = Vec::new();
        let mut phi: Option<(crate::Grid, Vec<f64>)> = None;
        let mut img = ChannelImages {
            total: vec![0.0; npix],
            single: vec![0.0; npix],
            multiple: vec![0.0; npix],
            emission: vec![0.0; npix],
            background: vec![0.0; npix],
        };
        for planned in &plan.passes {
            let t0 = Instant::now();
            match &planned.pass {
                Pass::BakeDirectional { light } | Pass::BakePoint { light } => {
                    let b = bake::bake(medium, *light, &scene.lights[*light]).ok_or(
                        PipelineError::UnsupportedLight {
                            index: *light,
                            kind: "non-bakeable",
                        },
                    )?;
                    baked.push(b);
                }
                Pass::DiffusionSolve {
                    with_emission,
                    downsample,
                    ..
                } => {
                    // The similarity variant's source is the δ-scaled one: the lights baked
                    // through σt' = σa + (1 − g)σs and scattered at σs' = (1 − g)σs (the
                    // forward peak g·σs stays in the beam); see `similarity_source`.
                    // A method that takes the lights itself gets no q_ri: the lights baked
                    // here are for the single-scattering raymarch only (the contract of φ,
                    // `LightInput`).
                    let direct = config.method.capabilities().lights == LightInput::Direct;
                    let mut q = if direct {
                        vec![0.0; medium.grid.len()]
                    } else {
                        match similarity_source(config, medium, phase, &baked, &scene.lights)? {
                            Some(q) => q,
                            None => bake::q_ri(medium, &baked),
                        }
                    };
                    if *with_emission {
                        q.iter_mut()
                            .zip(&medium.emission)
                            .for_each(|(q, j)| *q += j);
                    }
                    let coarse = restrict::restrict_with(
                        medium,
                        &q,
                        *downsample,
                        config.pad,
                        scene.interpolation,
                    )?;
                    let problem = Problem {
                        medium: &coarse,
                        lights: &scene.lights,
                        phase,
                    };
                    let sol = config.method.solve(
                        backend,
                        &problem,
                        &config.tolerance,
                        &mut |_, _| {},
                    )?;
                    diffusion.push(DiffusionRecord {
                        channel: c,
                        grid: coarse.grid.n,
                        dl: coarse.grid.dl,
                        method: config.method.name(),
                        steps: sol.steps,
                        last_change: sol.last_change,
                        stop: sol.stop,
                        solve_seconds: sol.seconds,
                        setup_seconds: sol.setup_seconds,
                        backend: backend.to_string(),
                        solve_grid: coarse.grid,
                        phi: sol.phi.clone(),
                    });
                    // With the Marshak face, φ inside a surface voxel is reconstructed from
                    // the face value ([`crate::fld::marshak_ghosts`]).
                    let march = match config.method.vacuum_face() {
                        crate::fld::VacuumFace::Paper => sol.phi,
                        crate::fld::VacuumFace::Marshak => {
                            crate::fld::marshak_ghosts(&coarse, &sol.phi)
                        }
                    };
                    phi = Some((coarse.grid, march));
                }
                Pass::RaymarchSingle { lights, .. } => {
                    let ls: Vec<BakedLight> = baked
                        .iter()
                        .filter(|b| lights.contains(&b.index))
                        .cloned()
                        .collect();
                    img.single = raymarch::render_term(
                        medium,
                        &camera,
                        Term::Single {
                            lights: &ls,
                            phase,
                            shadows: config.shadows,
                        },
                        config.step,
                        config.pixel_samples,
                    );
                }
                Pass::RaymarchMultiple => {
                    if let Some((grid, phi)) = &phi {
                        img.multiple = raymarch::render_term(
                            medium,
                            &camera,
                            Term::Multiple { grid, phi },
                            config.step,
                            config.pixel_samples,
                        );
                    }
                }
                Pass::RaymarchBackground { radiance } => {
                    img.background = raymarch::render_term(
                        medium,
                        &camera,
                        Term::Background {
                            radiance: *radiance,
                        },
                        config.step,
                        config.pixel_samples,
                    );
                }
                Pass::RaymarchEmission => {
                    img.emission = raymarch::render_term(
                        medium,
                        &camera,
                        Term::Emission,
                        config.step,
                        config.pixel_samples,
                    );
                }
            }
            passes_run.push(PassRecord {
                name: planned.pass.name(),
                channel: c,
                seconds: t0.elapsed().as_secs_f64(),
            });
        }
        let runs = |n: &str| plan.runs(n);
        for p in 0..npix {
            let mut t = 0.0;
            if runs("raymarch_single") {
                t += img.single[p];
            }
            if runs("raymarch_multiple") {
                t += img.multiple[p];
            }
            if runs("raymarch_emission") {
                t += img.emission[p];
            }
            if runs("raymarch_background") {
                t += img.background[p];
            }
            img.total[p] = t;
        }
        images.push(img);
    }
    Ok(Rendered {
        width,
        height,
        channels: images,
        plan,
        passes_run,
        diffusion,
    })
}

fn check_channels(channels: &[Scene]) -> Result<(), PipelineError> {
    let Some(first) = channels.first() else {
        return Err(PipelineError::Channels("no channels".into()));
    };
    if channels.len() != 1 && channels.len() != 3 {
        return Err(PipelineError::Channels(format!(
            "{} channels",
            channels.len()
        )));
    }
    for (c, s) in channels.iter().enumerate() {
        s.validate()?;
        if s.medium.grid != first.medium.grid
            || s.lights != first.lights
            || s.camera != first.camera
            || s.phase != first.phase
        {
            return Err(PipelineError::Channels(format!(
                "channel {c} differs from channel 0 in grid, lights, camera or phase"
            )));
        }
    }
    Ok(())
}
