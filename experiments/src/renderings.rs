//! FLD Figs 1, 6 and 7 analogs: heterogeneous volumes rendered by the path tracer, by the
//! FLD pipeline and by the CDA pipeline side by side, over an albedo sweep and at full and
//! reduced diffusion resolution, with error images and a table of image errors split into
//! single and multiple scattering, and timings.
//!
//! For every scene and albedo α (the albedo of every voxel with σt > 0 set to α, in every
//! colour channel), the reference is the path tracer's component images
//! (`reference::effects::render_components`, `--spp` samples per pixel). Each grid method
//! (`--methods`, default `cda,fld:lp,cda:marshak,fld:lp:marshak`: both with the paper's
//! medium–vacuum face and with the Marshak face, issue 15 acceptance 6) renders at each
//! downsampling factor (`--downsample`, default `1,4`: full and quarter resolution). A method
//! that does not run on a backend (the Marshak face is CPU-only) is skipped there, with a
//! warning and a `skipped` entry in `meta.json`.
//!
//! **Outputs** (`results/renderings/`):
//! * `errors.csv`: `scene,albedo,method,downsample,backend,error,error_single,error_multiple,
//!   reference_noise,reference_noise_multiple,seconds,diffusion_seconds,iterations,
//!   voxel_updates` — relative
//!   RMSEs (see [`crate::images`]) of the total image and of the single- and
//!   multiple-scattering components against the reference's;
//! * `claim.csv`: per scene and albedo ≥ 0.5, downsampling factor and vacuum face
//!   (`boundary`: `paper` pairs `fld:lp` with `cda`, `marshak` pairs `fld:lp:marshak` with
//!   `cda:marshak`), FLD-LP's and CDA's multiple-scattering errors and which is lower (FLD
//!   Section 6.2's claim, and whether it survives a proper boundary for CDA);
//! * `quarter.csv`: per scene, albedo and method, the diffusion-solve seconds at full and
//!   at the coarsest resolution, their ratio, the errors of both (FLD Fig 6), and the ratio
//!   of their voxel updates (`work_ratio`, the machine-independent cost the tests check);
//! * `<scene>_a<albedo>.png`: reference | each method and factor, one exposure;
//!   `<scene>_a<albedo>_error.png`: the signed multiple-scattering error of each (red: too
//!   bright, blue: too dark, saturated at 25 % of the white point).

use crate::accuracy_cost::{COARSEN_HELP, coarsen_factor, grid_config, scene_files};
use crate::common::{BackendArgs, CommonArgs, Ctx, list_item, progress};
use crate::experiment::{BackendSupport, Experiment, Promise};
use crate::images::{
    ColourMap, Tile, relative_noise, white_point, write_strip, write_strip_with_bar,
};
use crate::report::{Section, table};
use crate::scenes::{Prepared, errors, load, parse_resolution, render_reference};
use anyhow::{Context, Result, bail};
use serde::Serialize;
use solvers::method::MethodRef;
use solvers::pipeline::{self, ChannelImages};
use solvers::{Backend, Precision};
use std::time::Instant;

/// The scenes of the sweep without `--scenes` (relative to the workspace root).
pub const DEFAULT_SCENES: &str = "scenes/nebula.toml,scenes/shell_core.toml";

/// Flags of `renderings`.
#[derive(Debug, Clone, clap::Parser)]
#[command(about = "Path tracing vs FLD vs CDA renderings over an albedo sweep (FLD Figs 1, 6, 7)")]
pub struct Args {
    /// Shared flags.
    #[command(flatten)]
    pub common: CommonArgs,
    /// Shared backend flag (the diffusion solve runs there; CPU runs in f32).
    #[command(flatten)]
    pub backend: BackendArgs,
    /// Scene files, comma-separated; relative paths are from the current directory.
    /// Default: scenes/nebula.toml and scenes/shell_core.toml of the workspace.
    #[arg(long)]
    pub scenes: Option<String>,
    /// Albedos of the sweep (default 0.1,0.3,0.5,0.7,0.9,1.0; 0.3,0.9 with --quick).
    #[arg(long, value_delimiter = ',', value_parser = list_item::<f64>)]
    pub albedo: Option<Vec<f64>>,
    /// Grid methods, comma-separated: any registered method (see `render --help`).
    #[arg(long, default_value = "cda,fld:lp,cda:marshak,fld:lp:marshak", long_help = format!("Grid methods, comma-separated; {}", solvers::method::names()))]
    pub methods: String,
    /// Diffusion downsampling factors (1 = full resolution).
    #[arg(long, value_delimiter = ',', value_parser = list_item::<usize>, default_value = "1,4")]
    pub downsample: Vec<usize>,
    /// Albedos at which factor 1 (full resolution) also runs — it costs more than the
    /// rest of the sweep together (default 0.9).
    #[arg(long, value_delimiter = ',', value_parser = list_item::<f64>)]
    pub full_at: Option<Vec<f64>>,
    /// Samples per pixel of the reference (default 1024; 64 with --quick).
    #[arg(long, value_parser = crate::common::count_u32)]
    pub spp: Option<u32>,
    /// Solver tolerance (`solvers::method::Tolerance::rel`: R̄/j̄ for CDA/FLD; each method
    /// documents its mapping).
    #[arg(long, default_value_t = 1e-4)]
    pub tolerance: f64,
    /// Coarsening factor of the scenes' media (see [`COARSEN_HELP`]).
    #[arg(long, help = COARSEN_HELP, allow_negative_numbers = true)]
    pub coarsen: Option<usize>,
    /// Override the camera resolution `W,H` (default: the scene's; 24,24 with --quick).
    #[arg(long)]
    pub resolution: Option<String>,
    /// Seed of the reference.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// One row of `errors.csv`.
#[derive(Debug, Clone, Serialize)]
pub struct ErrorRow {
    /// Scene (file stem).
    pub scene: String,
    /// Albedo of the sweep.
    pub albedo: f64,
    /// `cda`, `fld:lp`, …
    pub method: String,
    /// Diffusion downsampling factor.
    pub downsample: usize,
    /// Backend of the diffusion solve.
    pub backend: String,
    /// Relative RMSE of the total image.
    pub error: f64,
    /// … of the single-scattering component.
    pub error_single: f64,
    /// … of the multiple-scattering component.
    pub error_multiple: f64,
    /// The reference's own relative noise (total image).
    pub reference_noise: f64,
    /// The reference's own relative noise (multiple-scattering component).
    pub reference_noise_multiple: f64,
    /// Wall-clock seconds of the render.
    pub seconds: f64,
    /// Seconds of the diffusion solve(s).
    pub diffusion_seconds: f64,
    /// Solver iterations per channel.
    pub iterations: String,
    /// Σ over the diffusion solves of voxels × steps (iterations; multigrid: cycles): the
    /// solve's work independent of the machine.
    pub voxel_updates: f64,
}

/// One row of `claim.csv`.
#[derive(Debug, Clone, Serialize)]
pub struct ClaimRow {
    /// Scene.
    pub scene: String,
    /// Albedo.
    pub albedo: f64,
    /// Downsampling factor.
    pub downsample: usize,
    /// FLD-LP's multiple-scattering error.
    pub fld_lp_error_multiple: f64,
    /// CDA's.
    pub cda_error_multiple: f64,
    /// The reference's noise in that component.
    pub reference_noise_multiple: f64,
    /// Whether FLD-LP's error is the lower one.
    pub fld_lower: bool,
    /// The medium–vacuum face of both: `paper` or `marshak`.
    pub boundary: String,
}

/// One row of `quarter.csv`.
#[derive(Debug, Clone, Serialize)]
pub struct QuarterRow {
    /// Scene.
    pub scene: String,
    /// Albedo.
    pub albedo: f64,
    /// Method.
    pub method: String,
    /// The reduced factor compared with 1.
    pub downsample: usize,
    /// Diffusion seconds at full resolution.
    pub full_seconds: f64,
    /// Diffusion seconds at the reduced resolution.
    pub reduced_seconds: f64,
    /// reduced / full.
    pub cost_ratio: f64,
    /// Total-image error at full resolution.
    pub full_error: f64,
    /// Total-image error at the reduced resolution.
    pub reduced_error: f64,
    /// Multiple-scattering error at full resolution.
    pub full_error_multiple: f64,
    /// Multiple-scattering error at the reduced resolution.
    pub reduced_error_multiple: f64,
    /// Reduced / full voxel updates (`ErrorRow::voxel_updates`): the cost ratio without
    /// the machine's timing noise. *Why*: `cost_ratio` of the quick run read 0.06–0.08 on a
    /// 2-vCPU Zen 5 host, where the 1/4-resolution solve's 0.02 s are mostly fixed costs.
    pub work_ratio: f64,
}

/// Everything the experiment measured.
#[derive(Debug)]
pub struct Outcome {
    /// `errors.csv`.
    pub errors: Vec<ErrorRow>,
    /// `claim.csv`.
    pub claim: Vec<ClaimRow>,
    /// `quarter.csv`.
    pub quarter: Vec<QuarterRow>,
}

fn set_albedo(scene: &mut Prepared, albedo: f64) {
    for ch in &mut scene.channels {
        let m = &mut ch.medium;
        for (a, s) in m.albedo.iter_mut().zip(&m.sigma_t) {
            if *s > 0.0 {
                *a = albedo;
            }
        }
    }
}

/// Runs the sweep.
pub fn run(args: &Args) -> Result<Outcome> {
    crate::experiment::run::<Renderings>(args)
}

fn run_in(ctx: &mut Ctx, args: &Args) -> Result<Outcome> {
    let quick = args.common.quick;
    let albedos: Vec<f64> = match &args.albedo {
        Some(v) => v.clone(),
        None if quick => vec![0.3, 0.9],
        None => vec![0.1, 0.3, 0.5, 0.7, 0.9, 1.0],
    };
    if let Some(a) = albedos.iter().find(|a| !(0.0..=1.0).contains(*a)) {
        bail!("--albedo: {a} is outside [0, 1]");
    }
    let methods: Vec<MethodRef> = args
        .methods
        .split(',')
        .map(|m| m.trim().parse::<MethodRef>())
        .collect::<Result<_, _>>()
        .context("--methods")?;
    let factors: Vec<usize> = args.downsample.clone();
    if factors.contains(&0) {
        bail!("--downsample factors must be at least 1");
    }
    let spp = args.spp.unwrap_or(if quick { 64 } else { 1024 });
    let full_at: Vec<f64> = match &args.full_at {
        Some(v) => v.clone(),
        None => vec![0.9],
    };
    let coarsen = coarsen_factor(args.coarsen, quick)?;
    let resolution = match &args.resolution {
        Some(s) => Some(parse_resolution(s)?),
        None if quick => Some([24, 24]),
        None => None,
    };
    let scenes = scene_files(args.scenes.as_deref(), DEFAULT_SCENES)?;
    let backends = args.backend.open()?;
    let params = serde_json::json!({
        "scenes": scenes, "albedo": albedos, "methods": args.methods, "downsample": factors,
        "spp": spp, "tolerance": args.tolerance, "coarsen": coarsen, "resolution": resolution,
        "full_at": full_at,
        "seed": args.seed,
    });
    let mut prepared = scenes
        .iter()
        .map(|p| load(p, coarsen, resolution))
        .collect::<Result<Vec<_>>>()?;
    let mut work = crate::cost::Estimate::new();
    for scene in &prepared {
        let reference = crate::cost::pt_render(&scene.channels, &scene.effects, spp);
        work.add(
            format!("{}: {} references of {spp} spp", scene.name, albedos.len()),
            reference * albedos.len() as f64,
        );
        for m in &methods {
            for &k in &factors {
                let runs = if k == 1 {
                    albedos.iter().filter(|a| full_at.contains(a)).count()
                } else {
                    albedos.len()
                } as f64;
                let one = crate::cost::pipeline_render(
                    &scene.channels,
                    &grid_config(m, k, args.tolerance),
                );
                let nb = backends
                    .list(Precision::F32)
                    .iter()
                    .filter(|b| m.capabilities().supports(b))
                    .count() as f64;
                work.add(
                    format!("{}: {m} ds={k}, {runs} albedos", scene.name),
                    one * runs * nb,
                );
            }
        }
    }
    ctx.work(&work)?;
    ctx.start(params)?;
    let out = ctx;
    out.record("backends", backends.meta());
    let mut rows = Vec::new();
    let mut skipped: Vec<(String, String)> = Vec::new();
    for scene in &mut prepared {
        let bar = progress(albedos.len() as u64, &args.common, &scene.name);
        for &albedo in &albedos {
            set_albedo(scene, albedo);
            render_reference(out, scene, spp, args.seed)
                .with_context(|| format!("albedo {albedo}"))?;
            out.timing(
                format!("{}/a{albedo}/reference", scene.name),
                scene.reference_seconds,
            );
            let ref_total: Vec<&[f64]> = scene
                .reference
                .iter()
                .map(|c| c.total.mean.as_slice())
                .collect();
            let ref_multi: Vec<&[f64]> = scene
                .reference
                .iter()
                .map(|c| c.multiple.mean.as_slice())
                .collect();
            let se_multi: Vec<&[f64]> = scene
                .reference
                .iter()
                .map(|c| c.multiple.stderr.as_slice())
                .collect();
            let noise_multi = relative_noise(&se_multi, &ref_multi);
            let noise = scene.noise();
            let mut renders: Vec<(String, usize, Vec<ChannelImages>)> = Vec::new();
            for b in backends.list(Precision::F32) {
                for m in &methods {
                    if !m.capabilities().supports(&b) {
                        if !skipped.contains(&(m.to_string(), b.to_string())) {
                            eprintln!("renderings: {m} does not run on {b}; skipped there");
                            skipped.push((m.to_string(), b.to_string()));
                        }
                        continue;
                    }
                    for &k in &factors {
                        if k == 1 && !full_at.contains(&albedo) {
                            continue;
                        }
                        let config = grid_config(m, k, args.tolerance);
                        let t0 = Instant::now();
                        let r = pipeline::render_channels(
                            &scene.channels,
                            &scene.selection,
                            &config,
                            &b,
                        )
                        .with_context(|| format!("{} α={albedo} {m} ds={k}", scene.name))?;
                        let seconds = t0.elapsed().as_secs_f64();
                        let (error, _, error_single, error_multiple) = errors(scene, &r.channels);
                        rows.push(ErrorRow {
                            scene: scene.name.clone(),
                            albedo,
                            method: m.to_string(),
                            downsample: k,
                            backend: b.to_string(),
                            error,
                            error_single,
                            error_multiple,
                            reference_noise: noise,
                            reference_noise_multiple: noise_multi,
                            seconds,
                            diffusion_seconds: r.diffusion.iter().map(|d| d.solve_seconds).sum(),
                            iterations: r
                                .diffusion
                                .iter()
                                .map(|d| d.steps.to_string())
                                .collect::<Vec<_>>()
                                .join("/"),
                            voxel_updates: r
                                .diffusion
                                .iter()
                                .map(|d| d.grid.iter().product::<usize>() as f64 * d.steps as f64)
                                .sum(),
                        });
                        if matches!(b, Backend::Cpu(_)) {
                            let g = r.diffusion.first().map_or([0; 3], |d| d.grid);
                            let label = format!("{m} ds={k}, {}×{}×{} grid", g[0], g[1], g[2]);
                            renders.push((label, k, r.channels));
                        }
                    }
                }
            }
            write_images(out, scene, albedo, &ref_total, &renders)?;
            bar.inc(1);
        }
        bar.finish_and_clear();
    }
    if !skipped.is_empty() {
        let list: Vec<String> = skipped.iter().map(|(m, b)| format!("{m} on {b}")).collect();
        out.record("skipped", serde_json::json!(list));
    }
    let outcome = Outcome {
        claim: claim(&rows),
        quarter: quarter(&rows),
        errors: rows,
    };
    out.csv("errors.csv", &outcome.errors)?;
    out.csv("claim.csv", &outcome.claim)?;
    out.csv("quarter.csv", &outcome.quarter)?;
    Ok(outcome)
}

fn write_images(
    out: &Ctx,
    scene: &Prepared,
    albedo: f64,
    ref_total: &[&[f64]],
    renders: &[(String, usize, Vec<ChannelImages>)],
) -> Result<()> {
    let Some(cam) = scene.channels.first().and_then(|c| c.camera) else {
        return Ok(());
    };
    let [w, h] = cam.resolution;
    let white = white_point(ref_total);
    let common = format!("α = {albedo}, {w}×{h} px");
    let mut tiles = vec![
        Tile::new(ref_total.to_vec(), ColourMap::Radiance { white })
            .labelled(format!("path tracer (reference)\n{common}")),
    ];
    for (label, _, im) in renders {
        tiles.push(
            Tile::new(
                im.iter().map(|c| c.total.as_slice()).collect(),
                ColourMap::Radiance { white },
            )
            .labelled(format!("{label}\n{common}")),
        );
    }
    let stem = format!("{}_a{albedo}", scene.name);
    write_strip(&out.path(&format!("{stem}.png")), w, h, &tiles)?;
    // Signed multiple-scattering error, channel-summed.
    let diffs: Vec<Vec<f64>> = renders
        .iter()
        .map(|(_, _, im)| {
            (0..w * h)
                .map(|p| {
                    im.iter()
                        .zip(&scene.reference)
                        .map(|(c, r)| c.multiple[p] - r.multiple.mean[p])
                        .sum()
                })
                .collect()
        })
        .collect();
    let tiles: Vec<Tile> = diffs
        .iter()
        .zip(renders)
        .map(|(d, (label, _, _))| {
            let scale = 0.25 * white * scene.channels.len() as f64;
            Tile::new(vec![d.as_slice()], ColourMap::Signed { scale })
                .labelled(format!("{label}\n{common}"))
        })
        .collect();
    if !tiles.is_empty() {
        let bar = "multiple-scattering radiance, method − path tracer (scene units, channel sum)";
        write_strip_with_bar(&out.path(&format!("{stem}_error.png")), w, h, &tiles, bar)?;
    }
    Ok(())
}

/// The (CDA, FLD-LP) pairs of `claim.csv`, one per medium–vacuum face.
const CLAIM_PAIRS: [(&str, &str, &str); 2] = [
    ("cda", "fld:lp", "paper"),
    ("cda:marshak", "fld:lp:marshak", "marshak"),
];

/// FLD-LP vs CDA multiple-scattering errors at albedo ≥ 0.5 (CPU rows), per vacuum face.
pub fn claim(rows: &[ErrorRow]) -> Vec<ClaimRow> {
    let find = |r: &ErrorRow, m: &str| {
        rows.iter().find(|x| {
            x.scene == r.scene
                && x.albedo == r.albedo
                && x.downsample == r.downsample
                && x.backend == r.backend
                && x.method == m
        })
    };
    CLAIM_PAIRS
        .iter()
        .flat_map(|&(c, f, boundary)| {
            rows.iter()
                .filter(move |r| r.method == c && r.albedo >= 0.5 && r.backend.starts_with("cpu"))
                .filter_map(move |cda| Some((find(cda, f)?, cda, boundary)))
        })
        .map(|(fld, cda, boundary)| ClaimRow {
            scene: cda.scene.clone(),
            albedo: cda.albedo,
            downsample: cda.downsample,
            fld_lp_error_multiple: fld.error_multiple,
            cda_error_multiple: cda.error_multiple,
            reference_noise_multiple: cda.reference_noise_multiple,
            fld_lower: fld.error_multiple < cda.error_multiple,
            boundary: boundary.to_string(),
        })
        .collect()
}

/// Reduced- vs full-resolution diffusion cost and error, per scene, albedo and method.
pub fn quarter(rows: &[ErrorRow]) -> Vec<QuarterRow> {
    rows.iter()
        .filter(|r| r.downsample > 1)
        .filter_map(|red| {
            let full = rows.iter().find(|x| {
                x.scene == red.scene
                    && x.albedo == red.albedo
                    && x.method == red.method
                    && x.backend == red.backend
                    && x.downsample == 1
            })?;
            Some(QuarterRow {
                scene: red.scene.clone(),
                albedo: red.albedo,
                method: format!("{} ({})", red.method, red.backend),
                downsample: red.downsample,
                full_seconds: full.diffusion_seconds,
                reduced_seconds: red.diffusion_seconds,
                cost_ratio: red.diffusion_seconds / full.diffusion_seconds,
                full_error: full.error,
                reduced_error: red.error,
                full_error_multiple: full.error_multiple,
                reduced_error_multiple: red.error_multiple,
                work_ratio: red.voxel_updates / full.voxel_updates,
            })
        })
        .collect()
}

/// FLD Figs 1, 6 and 7 in the registry.
#[derive(Debug)]
pub struct Renderings;

/// The columns of `claim.csv` (promised, and read back by the report).
const CLAIM_COLUMNS: &[&str] = &[
    "scene",
    "albedo",
    "downsample",
    "fld_lp_error_multiple",
    "cda_error_multiple",
    "reference_noise_multiple",
    "fld_lower",
    "boundary",
];

impl Experiment for Renderings {
    const NAME: &'static str = "renderings";
    const TITLE: &'static str = "Renderings: path tracing vs FLD vs CDA (FLD Figs 1, 6, 7)";
    const BACKEND: BackendSupport = BackendSupport::Flag;
    type Args = Args;
    type Summary = Outcome;

    fn common(args: &Args) -> &CommonArgs {
        &args.common
    }

    fn promises(_args: &Args) -> Vec<Promise> {
        vec![
            Promise::csv(
                "errors.csv",
                &[
                    "scene",
                    "albedo",
                    "method",
                    "downsample",
                    "backend",
                    "error",
                    "error_single",
                    "error_multiple",
                    "reference_noise",
                    "reference_noise_multiple",
                    "seconds",
                    "diffusion_seconds",
                    "iterations",
                    "voxel_updates",
                ],
            ),
            Promise::csv("claim.csv", CLAIM_COLUMNS),
            Promise::csv(
                "quarter.csv",
                &[
                    "scene",
                    "albedo",
                    "method",
                    "downsample",
                    "full_seconds",
                    "reduced_seconds",
                    "cost_ratio",
                    "full_error",
                    "reduced_error",
                    "full_error_multiple",
                    "reduced_error_multiple",
                    "work_ratio",
                ],
            ),
        ]
    }

    fn run(ctx: &mut Ctx, args: &Args) -> Result<Self::Summary> {
        run_in(ctx, args)
    }

    fn report(s: &Section<'_>) -> Result<String> {
        let claim = s.csv("claim.csv")?;
        claim.require(CLAIM_COLUMNS)?;
        let quarter = s.csv("quarter.csv")?;
        quarter.require(&[
            "scene",
            "albedo",
            "method",
            "downsample",
            "full_seconds",
            "reduced_seconds",
            "cost_ratio",
            "full_error_multiple",
            "reduced_error_multiple",
        ])?;
        let mut out = String::from(
            "Each scene's albedo set to α in every voxel and channel; reference: the path tracer's single-, multiple- \
             and emission components. Errors are relative RMSEs over all pixels and channels (`errors.csv` has every \
             run). Images `<scene>_a<α>.png`: reference | CDA and FLD-LP at each factor, one exposure; `_error.png`: \
             signed multiple-scattering error.\n\n\
             ### FLD's claim (Section 6.2): FLD-LP's multiple-scattering error below CDA's at albedo ≥ 0.5\n\n\
             Vacuum face `paper`: FLD's D_ps = (D_p + D_s)/2 with the floors of FLD Eqs 33/35 (CDA's vacuum D \
             pins the surface to φ ≈ 0); `marshak`: both methods with the Marshak (partial-current) face \
             (`cda:marshak`, `fld:lp:marshak`; `solvers::fld` module docs).\n\n",
        );
        let rows = claim.rows().map(|r| {
            vec![
                r.get("scene").to_string(),
                r.get("albedo").to_string(),
                r.get("downsample").to_string(),
                r.get("boundary").to_string(),
                r.fixed("fld_lp_error_multiple", 3),
                r.fixed("cda_error_multiple", 3),
                r.fixed("reference_noise_multiple", 3),
                if r.flag("fld_lower") { "yes" } else { "**no**" }.to_string(),
            ]
        });
        out.push_str(&table(
            &[
                "scene",
                "α",
                "downsample",
                "vacuum face",
                "FLD-LP error",
                "CDA error",
                "reference noise",
                "FLD lower",
            ],
            rows,
        ));
        out.push_str(
            "\n### Reduced-resolution diffusion (FLD Fig 6): cost and multiple-scattering error against full \
             resolution\n\n",
        );
        let rows = quarter.rows().map(|r| {
            vec![
                r.get("scene").to_string(),
                r.get("albedo").to_string(),
                r.get("method").to_string(),
                r.get("downsample").to_string(),
                r.fixed("full_seconds", 2),
                r.fixed("reduced_seconds", 3),
                format!("1/{:.0}", 1.0 / r.num("cost_ratio")),
                format!(
                    "{} → {}",
                    r.fixed("full_error_multiple", 3),
                    r.fixed("reduced_error_multiple", 3)
                ),
            ]
        });
        out.push_str(&table(
            &[
                "scene",
                "α",
                "method",
                "factor",
                "full solve (s)",
                "reduced solve (s)",
                "cost ratio",
                "error full → reduced",
            ],
            rows,
        ));
        out.push('\n');
        for sc in claim.distinct("scene") {
            for a in claim.distinct("albedo") {
                out.push_str(&s.pngs([format!("{sc}_a{a}.png"), format!("{sc}_a{a}_error.png")]));
            }
        }
        Ok(out)
    }
}
