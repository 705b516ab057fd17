//! Our path tracer against Mitsuba 3 on a scene file: per-pixel agreement, image means and
//! paths per second.
//!
//! Both renderers trace `--spp` paths per pixel in total: ours in one render with
//! `--batches` batch means for its standard errors, Mitsuba in `--renders` K independent
//! renders of ⌈spp/K⌉ paths each (K − 1 degrees of freedom), for every `--variant`.
//! The comparison (`reference::compare`) is a per-pixel Welch t-test with Šidák correction
//! at family-wise α = `--alpha` (default 0.01), plus the image means with their standard
//! errors.
//!
//! Paths per second: ours = W·H·spp / wall time of `render_image` (scene set-up included);
//! Mitsuba = the paths of all renders / the summed `mi.render` times (scene loading and the
//! Python start-up excluded; LLVM variants include JIT compilation in their first render,
//! `mitsuba_warm_paths_per_second` leaves the first render out). Both use every core. On a
//! shared machine wall times depend on other load, so paths per CPU second (user + system
//! time of all threads of the rendering process: /proc/self/stat for ours, Python's
//! `process_time` around each `mi.render`) are reported too, with their ratio `speedup_cpu`.
//!
//! Writes into `results/mitsuba_compare/<scene stem>/` (or `--out`): `comparison.csv` (one row per variant), `pixels.csv` (per pixel, first variant),
//! `ours.png`, `mitsuba.png` (same exposure: the 99.5th percentile of both maps to white,
//! sRGB gamma; nearest-neighbour upscaling to at least 256 pixels wide), `difference.png`
//! (per-pixel t: red where ours is brighter, blue where darker, white at 0, saturated at
//! |t| = 5; pixels failing the corrected test in yellow), and `meta.json` (with Mitsuba's
//! version and variants under `parameters.mitsuba`).

use crate::common::{CommonArgs, Ctx, list_item};
use crate::experiment::{BackendSupport, Experiment, FigureRun, Promise};
use crate::report::{Section, table};
use anyhow::{Context, Result, bail};
use plotters::prelude::*;
use reference::compare::{Comparison, ImageEstimate, compare};
use reference::effects::PassSums;
use reference::mitsuba::{MitsubaConfig, MitsubaError, MitsubaSettings, render};
use reference::pathtracer::camera::render_image_part;
use reference::pathtracer::{Contributions, Image, MIN_BATCHES, RenderSettings, TraceOptions};
use serde::Serialize;
use solvers::scene::SceneFile;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Flags of `mitsuba_compare`.
#[derive(Debug, Clone, clap::Parser)]
#[command(about = "Compare our path tracer with Mitsuba 3 on a scene file")]
pub struct Args {
    /// Shared flags (`--quick`: 32×32 pixels and 64 spp unless given).
    #[command(flatten)]
    pub common: CommonArgs,
    /// Scene file (TOML, format 1); it needs a camera and no volume emission.
    #[arg(long)]
    pub scene: PathBuf,
    /// Paths per pixel for each renderer, at least --batches (default: the scene's
    /// sampler.spp; 64 with --quick).
    #[arg(long, value_parser = crate::common::count_u32)]
    pub spp: Option<u32>,
    /// Override the camera resolution, `W,H` (default: the scene's; 32,32 with --quick).
    #[arg(long)]
    pub resolution: Option<String>,
    /// Independent Mitsuba renders K for its standard errors.
    #[arg(long, default_value_t = 8, value_parser = crate::common::count_u32)]
    pub renders: u32,
    /// Batches of our render for its standard errors.
    #[arg(long, default_value_t = MIN_BATCHES, value_parser = crate::common::count_u32)]
    pub batches: u32,
    /// Mitsuba variants, comma-separated (e.g. `scalar_rgb,llvm_ad_rgb`).
    #[arg(long, value_delimiter = ',', value_parser = list_item::<String>, default_value = "scalar_rgb")]
    pub variant: Vec<String>,
    /// Family-wise significance level of the per-pixel test.
    #[arg(long, default_value_t = 0.01)]
    pub alpha: f64,
    /// Override the scene's seed.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Most scattering events per path (default: unlimited).
    #[arg(long, value_parser = crate::common::count_u32)]
    pub max_depth: Option<u32>,
    /// Kill a Mitsuba render that runs longer than this many seconds (default:
    /// `SCATTERBENCH_MITSUBA_TIMEOUT`, else 3600).
    #[arg(long)]
    pub mitsuba_timeout: Option<f64>,
}

/// One row of `comparison.csv`.
#[derive(Debug, Clone, Serialize)]
pub struct Row {
    /// Scene file name.
    pub scene: String,
    /// Mitsuba variant.
    pub variant: String,
    /// Number of pixels.
    pub pixels: usize,
    /// Fraction of pixels passing the corrected test.
    pub fraction_passing: f64,
    /// The verdict (`reference::compare::Comparison::passed`): ≥ 99 % of pixels pass and
    /// the image means agree within 3 combined standard errors.
    pub passed: bool,
    /// Our image mean.
    pub mean_ours: f64,
    /// Its standard error.
    pub mean_ours_stderr: f64,
    /// Mitsuba's image mean.
    pub mean_mitsuba: f64,
    /// Its standard error.
    pub mean_mitsuba_stderr: f64,
    /// (ours − Mitsuba)/Mitsuba of the image means.
    pub rel_diff: f64,
    /// Difference of the image means in combined standard errors.
    pub mean_z: f64,
    /// Σ|ours − Mitsuba| / Σ Mitsuba over pixels (noise included).
    pub l1_rel_diff: f64,
    /// Family-wise α.
    pub alpha: f64,
    /// Width and height.
    pub width: usize,
    /// Height.
    pub height: usize,
    /// Our paths per pixel.
    pub spp_ours: u32,
    /// Mitsuba's paths per pixel over all renders.
    pub spp_mitsuba: u32,
    /// Mitsuba renders K.
    pub renders: u32,
    /// Our render's wall seconds.
    pub ours_seconds: f64,
    /// Mitsuba's summed render seconds.
    pub mitsuba_seconds: f64,
    /// Our paths per second.
    pub ours_paths_per_second: f64,
    /// Mitsuba's paths per second (all renders).
    pub mitsuba_paths_per_second: f64,
    /// Mitsuba's paths per second without its first render.
    pub mitsuba_warm_paths_per_second: f64,
    /// ours_paths_per_second / mitsuba_paths_per_second.
    pub speedup: f64,
    /// CPU seconds (all threads) of our render (`NaN` where /proc is unavailable).
    pub ours_cpu_seconds: f64,
    /// CPU seconds (all threads) of Mitsuba's renders.
    pub mitsuba_cpu_seconds: f64,
    /// Our paths per CPU second.
    pub ours_paths_per_cpu_second: f64,
    /// Mitsuba's paths per CPU second.
    pub mitsuba_paths_per_cpu_second: f64,
    /// ours_paths_per_cpu_second / mitsuba_paths_per_cpu_second: the efficiency ratio,
    /// robust to other load on a shared machine.
    pub speedup_cpu: f64,
    /// Mitsuba's version.
    pub mitsuba_version: String,
}

/// One pixel of `pixels.csv`.
#[derive(Debug, Serialize)]
struct PixelRow {
    x: usize,
    y: usize,
    ours: f64,
    ours_stderr: f64,
    mitsuba: f64,
    mitsuba_stderr: f64,
    t: f64,
    p: f64,
    pass: bool,
}

fn parse_resolution(s: &str) -> Result<[usize; 2]> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    let [w, h] = parts[..] else {
        bail!("--resolution: expected W,H, got `{s}`");
    };
    let parse = |v: &str| {
        v.parse::<usize>()
            .ok()
            .filter(|&n| n > 0)
            .ok_or_else(|| anyhow::anyhow!("--resolution: `{v}` is not a positive integer"))
    };
    let [w, h] = [parse(w)?, parse(h)?];
    solvers::budget::check(
        format!("--resolution {w},{h}"),
        solvers::budget::image_bytes(w, h),
    )?;
    Ok([w, h])
}

/// The stem of the scene file (`scenes/cloud.toml` → `cloud`), naming its output folder.
fn scene_stem(scene: &std::path::Path) -> String {
    scene
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scene".into())
}

/// Runs the comparison; returns one row per variant.
pub fn run(args: &Args) -> Result<Vec<Row>> {
    crate::experiment::run::<MitsubaCompare>(args)
}

fn run_in(ctx: &mut Ctx, args: &Args) -> Result<Vec<Row>> {
    let file = SceneFile::load(&args.scene)
        .with_context(|| format!("loading scene {}", args.scene.display()))?;
    let mut scene = file.scene;
    let Some(mut camera) = scene.camera else {
        bail!("{}: the scene has no [camera]", args.scene.display());
    };
    if let Some(r) = &args.resolution {
        camera.resolution = parse_resolution(r)?;
    } else if args.common.quick {
        camera.resolution = [32, 32];
    }
    scene.camera = Some(camera);
    let spp = args.spp.unwrap_or(if args.common.quick {
        64
    } else {
        scene.sampler.spp
    });
    let seed = args.seed.unwrap_or(scene.sampler.seed);
    if args.renders < 2 {
        bail!("--renders must be at least 2 (Mitsuba's standard errors need them)");
    }
    if spp < args.batches {
        bail!(
            "--spp {spp} must be at least --batches {} (one path per batch)",
            args.batches
        );
    }
    let spp_per_render = spp.div_ceil(args.renders);
    let variants: Vec<String> = args.variant.clone();
    if variants.is_empty() {
        bail!("--variant: give at least one Mitsuba variant");
    }
    if let Some(t) = args.mitsuba_timeout
        && !(t.is_finite() && t > 0.0)
    {
        bail!("--mitsuba-timeout {t}: must be a positive number of seconds");
    }
    let [width, height] = camera.resolution;
    let events = crate::cost::path_events(&scene.medium, args.max_depth);
    let paths = spp as f64 * (width * height) as f64;
    let mut work = crate::cost::Estimate::new();
    work.add(
        format!("our render, {spp} spp × {width}×{height} pixels × {events:.3e} events"),
        paths * events,
    );
    work.add(
        format!("{} Mitsuba render(s) of the same paths", variants.len()),
        paths * events * variants.len() as f64,
    );
    ctx.work(&work)?;
    let warnings = solvers::scene::warnings::degenerate(&scene, None);
    for w in &warnings {
        eprintln!("warning: {}: {w}", args.scene.display());
    }
    ctx.record("warnings", serde_json::json!(warnings));
    let mut versions = Vec::new();
    for v in &variants {
        // Not installed is not a failure of the comparison: `figures` skips it with the hint.
        let version = MitsubaConfig::new(v).probe().map_err(|e| match e {
            MitsubaError::NotInstalled { .. } => {
                anyhow::Error::new(crate::experiment::Unavailable(e.to_string()))
            }
            e => anyhow::Error::new(e),
        })?;
        versions.push(version);
    }
    let scene_name = args
        .scene
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let params = serde_json::json!({
        "scene": args.scene.display().to_string(),
        "width": width, "height": height, "spp": spp, "seed": seed,
        "batches": args.batches, "renders": args.renders, "spp_per_render": spp_per_render,
        "alpha": args.alpha, "max_depth": args.max_depth,
        "mitsuba_timeout_seconds": args.mitsuba_timeout.unwrap_or_else(|| reference::mitsuba::default_timeout().as_secs_f64()),
        "mitsuba": {
            "version": versions.first(),
            "variants": variants,
            "python": MitsubaConfig::default_python().display().to_string(),
        },
    });
    // One directory per scene: results/mitsuba_compare/<scene stem>/ unless --out is given
    // (see `MitsubaCompare::dir_name`).
    ctx.start(params)?;
    let out = ctx;

    let settings = RenderSettings {
        spp,
        seed,
        batches: args.batches,
        contributions: args
            .max_depth
            .map_or(Contributions::all(), Contributions::up_to),
    };
    let sp = out.spinner("mitsuba_compare");
    sp.set_message(format!("our path tracer, {spp} spp"));
    // CPU seconds are known only where the render ran (NaN in a merge).
    let cpu = std::cell::Cell::new(f64::NAN);
    let tallied = out.tally(
        "our path tracer",
        |shard| {
            let t0 = Instant::now();
            let c0 = process_cpu_seconds();
            let sums = render_image_part(&scene, &settings, &TraceOptions::of(&scene), shard)
                .context("rendering with our path tracer")?;
            if let (Some(a), Some(b)) = (c0, process_cpu_seconds()) {
                cpu.set(b - a);
            }
            Ok(vec![PassSums {
                sums,
                seconds: t0.elapsed().as_secs_f64(),
            }])
        },
        |parts| {
            Ok((
                Image::from_sums(width, height, &parts[0].sums)?,
                parts[0].seconds,
            ))
        },
    )?;
    sp.finish_and_clear();
    let Some((ours, ours_seconds)) = tallied else {
        // A shard: Mitsuba's side and the comparison run in the merge.
        return Ok(Vec::new());
    };
    let ours_cpu = cpu.get();
    out.timing("ours", ours_seconds);
    let ours_est = estimate(&ours, args.batches);
    let ours_paths = (width * height) as f64 * f64::from(spp);
    let ours_pps = ours_paths / ours_seconds;
    let ours_cpu_pps = ours_paths / ours_cpu;

    let mut rows = Vec::new();
    for (i, variant) in variants.iter().enumerate() {
        let cfg = MitsubaConfig::new(variant);
        let ms = MitsubaSettings {
            spp: spp_per_render,
            renders: args.renders,
            seed,
            max_depth: args.max_depth,
            keep_dir: None,
            timeout: args.mitsuba_timeout.map(std::time::Duration::from_secs_f64),
        };
        let sp = out.spinner("mitsuba_compare");
        sp.set_message(format!("Mitsuba {variant}, {} renders", args.renders));
        let r = render(&scene, &ms, &cfg)
            .with_context(|| format!("rendering with Mitsuba {variant}"))?;
        sp.finish_and_clear();
        out.timing(
            format!("mitsuba {variant} (wall, with start-up)"),
            r.wall_seconds,
        );
        out.timing(
            format!("mitsuba {variant} (renders)"),
            r.render_seconds.iter().sum(),
        );
        let c = compare(&ours_est, &r.image, args.alpha).context("comparing the images")?;
        let mitsuba_pps = r.paths_per_second();
        rows.push(Row {
            scene: scene_name.clone(),
            variant: variant.clone(),
            pixels: c.pixels,
            fraction_passing: c.fraction_passing,
            passed: c.passed(),
            mean_ours: c.mean_ours.0,
            mean_ours_stderr: c.mean_ours.1,
            mean_mitsuba: c.mean_theirs.0,
            mean_mitsuba_stderr: c.mean_theirs.1,
            rel_diff: c.rel_diff,
            mean_z: c.mean_z,
            l1_rel_diff: c.l1_rel_diff,
            alpha: args.alpha,
            width,
            height,
            spp_ours: spp,
            spp_mitsuba: spp_per_render * args.renders,
            renders: args.renders,
            ours_seconds,
            mitsuba_seconds: r.render_seconds.iter().sum(),
            ours_paths_per_second: ours_pps,
            mitsuba_paths_per_second: mitsuba_pps,
            mitsuba_warm_paths_per_second: r.warm_paths_per_second(),
            speedup: ours_pps / mitsuba_pps,
            ours_cpu_seconds: ours_cpu,
            mitsuba_cpu_seconds: r.render_cpu_seconds.iter().sum(),
            ours_paths_per_cpu_second: ours_cpu_pps,
            mitsuba_paths_per_cpu_second: r.paths_per_cpu_second(),
            speedup_cpu: ours_cpu_pps / r.paths_per_cpu_second(),
            mitsuba_version: r.version.clone(),
        });
        if i == 0 {
            write_pixels(out, &ours_est, &r.image, &c)?;
            let exposure = exposure(&ours_est.mean, &r.image.mean);
            radiance_png(&out.path("ours.png"), &ours_est, exposure)?;
            radiance_png(&out.path("mitsuba.png"), &r.image, exposure)?;
            difference_png(&out.path("difference.png"), &c, width, height)?;
        }
    }
    out.csv("comparison.csv", &rows)?;
    Ok(rows)
}

/// CPU time (user + system, all threads) of this process from /proc/self/stat, in seconds
/// (clock ticks of 1/100 s, Linux's USER_HZ); `None` where unavailable.
fn process_cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the parenthesised command name; utime and stime are fields 14 and 15.
    let rest = stat.rsplit_once(')')?.1;
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let utime: f64 = fields.get(11)?.parse().ok()?;
    let stime: f64 = fields.get(12)?.parse().ok()?;
    Some((utime + stime) / 100.0)
}

fn estimate(image: &Image, batches: u32) -> ImageEstimate {
    ImageEstimate {
        width: image.width,
        height: image.height,
        mean: image.mean.clone(),
        stderr: image.stderr.clone(),
        dof: f64::from(batches.saturating_sub(1).max(1)),
    }
}

fn write_pixels(
    out: &Ctx,
    ours: &ImageEstimate,
    theirs: &ImageEstimate,
    c: &Comparison,
) -> Result<()> {
    let rows: Vec<PixelRow> = (0..c.pixels)
        .map(|i| PixelRow {
            x: i % ours.width,
            y: i / ours.width,
            ours: ours.mean[i],
            ours_stderr: ours.stderr[i],
            mitsuba: theirs.mean[i],
            mitsuba_stderr: theirs.stderr[i],
            t: c.t[i],
            p: c.p[i],
            pass: c.pass[i],
        })
        .collect();
    out.csv("pixels.csv", &rows)
}

/// The value shown as white: the 99.5th percentile of both images' pixels (at least the
/// smallest positive value, so an all-black image stays black).
fn exposure(a: &[f64], b: &[f64]) -> f64 {
    let mut v: Vec<f64> = a
        .iter()
        .chain(b)
        .copied()
        .filter(|x| x.is_finite())
        .collect();
    v.sort_by(f64::total_cmp);
    let q = v
        .get(((v.len() as f64 * 0.995) as usize).min(v.len().saturating_sub(1)))
        .copied()
        .unwrap_or(1.0);
    if q > 0.0 { q } else { 1.0 }
}

fn srgb(v: f64) -> u8 {
    let v = v.clamp(0.0, 1.0);
    let s = if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0).round() as u8
}

fn upscale(width: usize) -> usize {
    256usize.div_ceil(width.max(1)).max(1)
}

fn draw_pixels(
    path: &Path,
    width: usize,
    height: usize,
    color: impl Fn(usize) -> RGBColor,
) -> Result<()> {
    let s = upscale(width);
    let root =
        BitMapBackend::new(path, ((width * s) as u32, (height * s) as u32)).into_drawing_area();
    for y in 0..height {
        for x in 0..width {
            let c = color(y * width + x);
            let (x0, y0) = ((x * s) as i32, (y * s) as i32);
            let (x1, y1) = (x0 + s as i32, y0 + s as i32);
            root.draw(&Rectangle::new([(x0, y0), (x1, y1)], c.filled()))
                .map_err(|e| anyhow::anyhow!("drawing {}: {e}", path.display()))?;
        }
    }
    root.present()
        .map_err(|e| anyhow::anyhow!("writing {}: {e}", path.display()))?;
    Ok(())
}

fn radiance_png(path: &Path, image: &ImageEstimate, exposure: f64) -> Result<()> {
    draw_pixels(path, image.width, image.height, |i| {
        let g = srgb(image.mean[i] / exposure);
        RGBColor(g, g, g)
    })
}

fn difference_png(path: &Path, c: &Comparison, width: usize, height: usize) -> Result<()> {
    draw_pixels(path, width, height, |i| {
        if !c.pass[i] {
            return RGBColor(255, 220, 0);
        }
        let t = (c.t[i] / 5.0).clamp(-1.0, 1.0);
        let fade = (255.0 * (1.0 - t.abs())).round() as u8;
        if t >= 0.0 {
            RGBColor(255, fade, fade)
        } else {
            RGBColor(fade, fade, 255)
        }
    })
}

/// The comparison with Mitsuba 3 in the registry: one run per example scene.
#[derive(Debug)]
pub struct MitsubaCompare;

impl Experiment for MitsubaCompare {
    const NAME: &'static str = "mitsuba_compare";
    const TITLE: &'static str = "Path tracer vs Mitsuba 3";
    const BACKEND: BackendSupport = BackendSupport::CpuOnly("both path tracers run on the CPU");
    const SHARDS: bool = true;
    type Args = Args;
    type Summary = Vec<Row>;

    fn common(args: &Args) -> &CommonArgs {
        &args.common
    }

    fn dir_name(args: &Args) -> String {
        format!("{}/{}", Self::NAME, scene_stem(&args.scene))
    }

    fn figure_runs(quick: bool) -> Vec<FigureRun> {
        // Quick runs keep 1024 paths per pixel (on 32×32): enough power for the claims that
        // `tests/registry.rs` checks on them, at about the cost of Mitsuba's start-up.
        // `dense_voxel` keeps its 16×16 camera and 256 spp there: Mitsuba's global majorant
        // (σt = 1000 in one voxel) makes each of its paths cost ~10³ null collisions.
        // `dense_half_space` has an exact answer (Chandrasekhar's H-function) that our path
        // tracer matches and Mitsuba's float ray offsets miss (see the scene file); its paths
        // scatter ~10³ times, so its quick run is as small as `dense_voxel`'s: at 1024 spp on
        // 32×32 Mitsuba's scalar_rgb took 146 s of a 149 s run (2-vCPU AMD EPYC Zen 3), the
        // largest single item of the test suite, and no test reads its numbers (the quick
        // run checks its files and columns only).
        [
            "cloud_directional",
            "emissive_sphere",
            "dense_half_space",
            "dense_voxel",
            "environment_sphere",
        ]
        .into_iter()
        .map(|scene| {
            // Full runs compare with both CPU variants (issue 14 acceptance 2 reads the
            // ratio against each, llvm's warm rate included); quick runs keep scalar_rgb
            // (no JIT start-up in CI).
            let spp: &[&str] = match (quick, scene) {
                (false, _) => &["--variant", "scalar_rgb,llvm_ad_rgb"],
                (true, "dense_voxel" | "dense_half_space") => {
                    &["--spp", "256", "--resolution", "16,16"]
                }
                (true, _) => &["--spp", "1024"],
            };
            let path = crate::common::workspace_root()
                .join("scenes")
                .join(format!("{scene}.toml"));
            FigureRun::new(
                format!("{}/{scene}", Self::NAME),
                format!("{}: {scene}", Self::TITLE),
            )
            .args(["--scene".to_string(), path.display().to_string()])
            .args(spp.iter().copied())
        })
        .collect()
    }

    fn promises(_args: &Args) -> Vec<Promise> {
        vec![
            Promise::csv(
                "comparison.csv",
                &[
                    "scene",
                    "variant",
                    "pixels",
                    "fraction_passing",
                    "passed",
                    "mean_ours",
                    "mean_ours_stderr",
                    "mean_mitsuba",
                    "mean_mitsuba_stderr",
                    "rel_diff",
                    "mean_z",
                    "alpha",
                    "ours_paths_per_second",
                    "mitsuba_paths_per_second",
                    "speedup",
                    "mitsuba_version",
                ],
            ),
            Promise::csv(
                "pixels.csv",
                &[
                    "x",
                    "y",
                    "ours",
                    "ours_stderr",
                    "mitsuba",
                    "mitsuba_stderr",
                    "t",
                    "p",
                    "pass",
                ],
            ),
            Promise::file("ours.png"),
            Promise::file("mitsuba.png"),
            Promise::file("difference.png"),
        ]
    }

    fn run(ctx: &mut Ctx, args: &Args) -> Result<Self::Summary> {
        run_in(ctx, args)
    }

    fn report(s: &Section<'_>) -> Result<String> {
        let t = s.csv("comparison.csv")?;
        t.require(&[
            "variant",
            "fraction_passing",
            "passed",
            "mean_ours",
            "mean_ours_stderr",
            "mean_mitsuba",
            "mean_mitsuba_stderr",
            "rel_diff",
            "speedup",
            "alpha",
            "ours_paths_per_second",
            "mitsuba_paths_per_second",
            "mitsuba_warm_paths_per_second",
            "speedup_cpu",
        ])?;
        let mut out = String::from(
            "Per-pixel Welch t-test with Šidák correction (family-wise α in the table), image means with standard \
             errors, the verdict `passed` (at least 99 % of pixels pass and the image means agree within 3 \
             combined standard errors), and paths per second of both renderers measured in the same run.\n\n",
        );
        let rows = t.rows().map(|r| {
            vec![
                format!("`{}`", r.get("variant")),
                r.get("alpha").to_string(),
                r.fixed("fraction_passing", 4),
                r.get("passed").to_string(),
                format!(
                    "{} ± {}",
                    r.sci("mean_ours", 4),
                    r.sci("mean_ours_stderr", 1)
                ),
                format!(
                    "{} ± {}",
                    r.sci("mean_mitsuba", 4),
                    r.sci("mean_mitsuba_stderr", 1)
                ),
                r.sci("rel_diff", 2),
                r.fixed("speedup", 2),
            ]
        });
        out.push_str(&table(
            &[
                "Mitsuba variant",
                "α",
                "pixels passing",
                "passed (≥ 99 % of pixels and means within 3σ)",
                "mean, ours",
                "mean, Mitsuba",
                "relative difference",
                "speed-up (paths/s)",
            ],
            rows,
        ));
        out.push_str(
            "\nPaths per second of both renderers, same scene and spp, measured in the same run \
             (Mitsuba's warm rate leaves out each variant's first render, which carries llvm_ad_rgb's \
             JIT compilation; per CPU-second counts user + system time, robust to other load):\n\n",
        );
        let speed = t.rows().map(|r| {
            let ours = r.num("ours_paths_per_second");
            vec![
                format!("`{}`", r.get("variant")),
                r.sci("ours_paths_per_second", 3),
                r.sci("mitsuba_paths_per_second", 3),
                r.sci("mitsuba_warm_paths_per_second", 3),
                r.fixed("speedup", 2),
                crate::report::fixed(ours / r.num("mitsuba_warm_paths_per_second"), 2),
                r.fixed("speedup_cpu", 2),
            ]
        });
        out.push_str(&table(
            &[
                "Mitsuba variant",
                "ours (paths/s)",
                "Mitsuba (paths/s)",
                "Mitsuba warm (paths/s)",
                "ratio",
                "ratio vs warm",
                "ratio per CPU-second",
            ],
            speed,
        ));
        out.push('\n');
        out.push_str(&s.pngs(["ours.png", "mitsuba.png", "difference.png"]));
        Ok(out)
    }
}
