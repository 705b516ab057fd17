//! Path-tracer throughput on a representative heterogeneous cloud: a camera render of a
//! noise-modulated cloud in vacuum (the kind of scene of FLD Figs 1 and 6–9), lit by a
//! directional light and a dim environment, rendered with the majorant grid (8³ blocks) and
//! with one global majorant (textbook Woodcock tracking). Reports paths per second.
//!
//! The cloud (documented here, used for the numbers in the results): unit cube, n³ voxels,
//! σt(p) = 60·max(0, fbm(5p, 4 octaves) + 0.25)·smoothstep of the distance to the centre
//! from 0.45 to 0.3 (0 outside radius 0.45), albedo `--albedo`, isotropic phase (or HG
//! `--g`), no emission; sun of irradiance 1 along (−0.4, −0.3, −1), environment 0.05;
//! perspective camera at (0.5, −1.4, 0.9) looking at the centre, 40° vertical field of view.
//!
//! Writes `timing.csv`, `image.csv` (x, y, mean, stderr of the majorant-grid render) and
//! `image.png` (gamma 2.2, exposure fitted to the 99th percentile).

use crate::common::{CommonArgs, Ctx, value_names};
use crate::experiment::{BackendSupport, Experiment, Promise};
use crate::report::{Section, table};
use anyhow::{Context, Result, bail};
use plotters::prelude::*;
use reference::effects::PassSums;
use reference::pathtracer::{
    Contributions, Image, Interpolation, RenderSettings, TraceOptions, camera::render_image_part,
};
use serde::Serialize;
use solvers::noise::Perlin;
use solvers::scene::{Camera, Light, Phase, Projection, Sampler, Scene};
use solvers::{Grid, Medium};
use std::time::Instant;

/// A `--interpolation` value.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum InterpolationArg {
    /// Piecewise-constant voxels.
    Nearest,
    /// Trilinear between voxel centres.
    Trilinear,
}

/// Flags of `pt_render`.
#[derive(Debug, Clone, clap::Parser)]
#[command(about = "Path-tracer throughput on a heterogeneous cloud render")]
pub struct Args {
    /// Shared flags.
    #[command(flatten)]
    pub common: CommonArgs,
    /// Grid resolution n (n³ voxels). Default 128 (32 with --quick).
    #[arg(long, value_parser = crate::common::count_usize)]
    pub n: Option<usize>,
    /// Image width and height in pixels. Default 128 (24 with --quick).
    #[arg(long, value_parser = crate::common::count_usize)]
    pub res: Option<usize>,
    /// Samples per pixel, at least 16 (the batches of the standard errors). Default 256 (16
    /// with --quick).
    #[arg(long, value_parser = crate::common::count_u32)]
    pub spp: Option<u32>,
    /// Albedo of the cloud.
    #[arg(long, default_value_t = 0.9)]
    pub albedo: f64,
    /// Henyey–Greenstein g (0: isotropic).
    #[arg(long, default_value_t = 0.0)]
    pub g: f64,
    /// nearest or trilinear.
    #[arg(long, value_enum, default_value = "nearest")]
    pub interpolation: InterpolationArg,
    /// Skip the comparison render with one global majorant (by default both the blocked
    /// and the global majorant render, so the table shows what the blocks buy).
    #[arg(long)]
    pub no_global: bool,
    /// Seed (noise and paths).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// One render (`timing.csv`).
#[derive(Debug, Clone, Serialize)]
pub struct TimingRow {
    /// `blocks8` or `global`.
    pub majorant: String,
    /// Interpolation.
    pub interpolation: String,
    /// Grid resolution.
    pub n: usize,
    /// Image width = height.
    pub res: usize,
    /// Samples per pixel.
    pub spp: u32,
    /// Camera paths traced.
    pub paths: u64,
    /// Wall seconds.
    pub seconds: f64,
    /// Paths per second (all threads).
    pub paths_per_second: f64,
    /// Process CPU seconds (user + system) of the render; NaN where /proc is unavailable.
    pub cpu_seconds: f64,
    /// Paths per CPU second: throughput per core, robust to a busy machine.
    pub paths_per_cpu_second: f64,
    /// Rayon threads.
    pub threads: usize,
    /// Mean over pixels of the radiance.
    pub mean_radiance: f64,
    /// Mean over pixels of stderr/mean (pixels with mean > 0).
    pub mean_rel_stderr: f64,
}

#[derive(Debug, Serialize)]
struct PixelRow {
    x: usize,
    y: usize,
    mean: f64,
    stderr: f64,
}

/// The cloud scene described in the module docs.
pub fn cloud_scene(n: usize, albedo: f64, g: f64, res: usize, seed: u64) -> Result<Scene> {
    let grid = Grid::cube(n, 1.0)?;
    let noise = Perlin::new(seed);
    let sigma = grid.sample(|p| {
        let r = ((p[0] - 0.5).powi(2) + (p[1] - 0.5).powi(2) + (p[2] - 0.5).powi(2)).sqrt();
        let s = ((0.45 - r) / 0.15).clamp(0.0, 1.0);
        let fall = s * s * (3.0 - 2.0 * s);
        60.0 * (noise.fbm(p.map(|x| 5.0 * x), 4) + 0.25).max(0.0) * fall
    });
    let len = grid.len();
    let medium = Medium::new(grid, sigma, vec![albedo; len], vec![0.0; len])?;
    let phase = if g == 0.0 {
        Phase::Isotropic
    } else {
        Phase::HenyeyGreenstein { g }
    };
    Ok(Scene {
        interpolation: Default::default(),
        medium,
        phase,
        lights: vec![
            Light::directional([-0.4, -0.3, -1.0], 1.0)?,
            Light::Environment { radiance: 0.05 },
        ],
        camera: Some(Camera {
            hide_background: false,
            eye: [0.5, -1.4, 0.9],
            target: [0.5, 0.5, 0.5],
            up: [0.0, 0.0, 1.0],
            projection: Projection::Perspective {
                fov_y_degrees: 40.0,
            },
            resolution: [res, res],
        }),
        sampler: Sampler { spp: 1, seed },
    })
}

/// Runs the experiment; returns the timing rows.
pub fn run(args: &Args) -> Result<Vec<TimingRow>> {
    crate::experiment::run::<PtRender>(args)
}

fn run_in(ctx: &mut Ctx, args: &Args) -> Result<Vec<TimingRow>> {
    let quick = args.common.quick;
    let n = args.n.unwrap_or(if quick { 32 } else { 128 });
    let res = args.res.unwrap_or(if quick { 24 } else { 128 });
    let spp = args.spp.unwrap_or(if quick { 16 } else { 256 });
    if res == 0 {
        bail!("--res must be at least 1");
    }
    solvers::budget::check(
        format!("--n {n}"),
        solvers::budget::bytes(&[n, n, n], solvers::budget::MEDIUM_BYTES_PER_VOXEL),
    )?;
    solvers::budget::check(
        format!("--res {res}"),
        solvers::budget::image_bytes(res, res),
    )?;
    let interpolation = match args.interpolation {
        InterpolationArg::Nearest => Interpolation::Nearest,
        InterpolationArg::Trilinear => Interpolation::Trilinear,
    };
    if spp < reference::pathtracer::MIN_BATCHES {
        bail!(
            "--spp {spp}: at least {} samples per pixel (one per batch of the standard errors)",
            reference::pathtracer::MIN_BATCHES
        );
    }
    let scene =
        cloud_scene(n, args.albedo, args.g, res, args.seed).context("building the cloud")?;
    let renders = if args.no_global { 1.0 } else { 2.0 };
    let events = crate::cost::path_events(&scene.medium, None);
    let mut work = crate::cost::Estimate::new();
    work.add(
        format!("{renders} renders of {spp} spp × {res}² pixels × {events:.3e} events"),
        renders * spp as f64 * (res * res) as f64 * events,
    );
    ctx.work(&work)?;
    ctx.start(serde_json::json!({
        "n": n, "res": res, "spp": spp, "albedo": args.albedo, "g": args.g,
        "interpolation": value_names(&[args.interpolation]), "seed": args.seed,
    }))?;
    let out = ctx;
    let settings = RenderSettings {
        spp,
        seed: args.seed,
        batches: reference::pathtracer::MIN_BATCHES,
        contributions: Contributions::all(),
    };
    let mut cases = vec![("blocks8", 8usize)];
    if !args.no_global {
        cases.push(("global", n));
    }
    let mut rows = Vec::new();
    let mut first: Option<Image> = None;
    for (name, block) in cases {
        let opts = TraceOptions {
            interpolation,
            majorant_block: block,
            ..TraceOptions::default()
        };
        let sp = out.spinner("pt_render");
        sp.set_message(format!("{name} majorants, {spp} spp × {res}² pixels"));
        // CPU seconds are known only where the render ran (NaN in a merge).
        let cpu = std::cell::Cell::new(f64::NAN);
        let [w, h] = [res, res];
        let tallied = out.tally(
            &format!("render with {name} majorants"),
            |shard| {
                let (t0, c0) = (Instant::now(), cpu_seconds());
                let sums = render_image_part(&scene, &settings, &opts, shard)?;
                cpu.set(cpu_seconds() - c0);
                Ok(vec![PassSums {
                    sums,
                    seconds: t0.elapsed().as_secs_f64(),
                }])
            },
            |parts| Ok((Image::from_sums(w, h, &parts[0].sums)?, parts[0].seconds)),
        )?;
        sp.finish_and_clear();
        let Some((img, seconds)) = tallied else {
            continue;
        };
        let cpu = cpu.get();
        out.timing(format!("render {name}"), seconds);
        let paths = (res * res) as u64 * spp as u64;
        let lit: Vec<(f64, f64)> = img
            .mean
            .iter()
            .zip(&img.stderr)
            .filter(|(m, _)| **m > 0.0)
            .map(|(m, e)| (*m, *e))
            .collect();
        rows.push(TimingRow {
            majorant: name.to_string(),
            interpolation: value_names(&[args.interpolation]),
            n,
            res,
            spp,
            paths,
            seconds,
            paths_per_second: paths as f64 / seconds,
            cpu_seconds: cpu,
            paths_per_cpu_second: paths as f64 / cpu,
            threads: rayon::current_num_threads(),
            mean_radiance: img.mean.iter().sum::<f64>() / img.mean.len() as f64,
            mean_rel_stderr: lit.iter().map(|(m, e)| e / m).sum::<f64>() / lit.len().max(1) as f64,
        });
        if first.is_none() {
            first = Some(img);
        }
    }
    if out.sharding() {
        return Ok(rows);
    }
    out.csv("timing.csv", &rows)?;
    if let Some(img) = first {
        let pixels: Vec<PixelRow> = (0..img.height)
            .flat_map(|y| (0..img.width).map(move |x| (x, y)))
            .map(|(x, y)| PixelRow {
                x,
                y,
                mean: img.mean[y * img.width + x],
                stderr: img.stderr[y * img.width + x],
            })
            .collect();
        out.csv("image.csv", &pixels)?;
        write_png(&out.path("image.png"), &img)?;
    }
    Ok(rows)
}

/// User + system CPU time of this process from `/proc/self/stat` (fields 14 and 15, in
/// USER_HZ = 100 ticks per second, the fixed Linux ABI value); NaN if unreadable.
fn cpu_seconds() -> f64 {
    std::fs::read_to_string("/proc/self/stat")
        .ok()
        .and_then(|s| {
            // Fields after the parenthesised command name, which may contain spaces.
            let rest = s.rsplit_once(')')?.1;
            let f: Vec<&str> = rest.split_whitespace().collect();
            let utime: f64 = f.get(11)?.parse().ok()?;
            let stime: f64 = f.get(12)?.parse().ok()?;
            Some((utime + stime) / 100.0)
        })
        .unwrap_or(f64::NAN)
}

/// Grey-scale PNG, gamma 2.2, white at the 99th percentile of the radiance.
fn write_png(path: &std::path::Path, img: &Image) -> Result<()> {
    let mut sorted = img.mean.clone();
    sorted.sort_by(f64::total_cmp);
    let white = sorted[(sorted.len() * 99 / 100).min(sorted.len() - 1)].max(1e-30);
    let root = BitMapBackend::new(path, (img.width as u32, img.height as u32)).into_drawing_area();
    for y in 0..img.height {
        for x in 0..img.width {
            let v = (img.mean[y * img.width + x] / white)
                .clamp(0.0, 1.0)
                .powf(1.0 / 2.2);
            let c = (v * 255.0).round() as u8;
            root.draw_pixel((x as i32, y as i32), &RGBColor(c, c, c))
                .map_err(|e| anyhow::anyhow!("drawing {}: {e}", path.display()))?;
        }
    }
    root.present()
        .map_err(|e| anyhow::anyhow!("writing {}: {e}", path.display()))?;
    Ok(())
}

/// The path tracer's throughput measurement in the registry.
#[derive(Debug)]
pub struct PtRender;

impl Experiment for PtRender {
    const NAME: &'static str = "pt_render";
    const TITLE: &'static str = "Path tracer: throughput";
    const BACKEND: BackendSupport = BackendSupport::CpuOnly("the path tracer runs on the CPU");
    const SHARDS: bool = true;
    type Args = Args;
    type Summary = Vec<TimingRow>;

    fn common(args: &Args) -> &CommonArgs {
        &args.common
    }

    fn promises(_args: &Args) -> Vec<Promise> {
        vec![
            Promise::csv(
                "timing.csv",
                &[
                    "majorant",
                    "interpolation",
                    "n",
                    "res",
                    "spp",
                    "paths",
                    "seconds",
                    "paths_per_second",
                    "cpu_seconds",
                    "paths_per_cpu_second",
                    "threads",
                    "mean_radiance",
                    "mean_rel_stderr",
                ],
            ),
            Promise::csv("image.csv", &["x", "y", "mean", "stderr"]),
            Promise::file("image.png"),
        ]
    }

    fn run(ctx: &mut Ctx, args: &Args) -> Result<Self::Summary> {
        run_in(ctx, args)
    }

    fn report(s: &Section<'_>) -> Result<String> {
        let t = s.csv("timing.csv")?;
        t.require(&[
            "majorant",
            "interpolation",
            "n",
            "res",
            "spp",
            "paths_per_second",
            "paths_per_cpu_second",
            "threads",
            "mean_rel_stderr",
        ])?;
        let mut out = String::from(
            "Paths per second on a noise cloud, majorant grid vs one global majorant:\n\n",
        );
        let rows = t.rows().map(|r| {
            vec![
                r.get("majorant").to_string(),
                r.get("interpolation").to_string(),
                r.get("n").to_string(),
                format!("{0}×{0}", r.get("res")),
                r.get("spp").to_string(),
                r.sci("paths_per_second", 3),
                r.sci("paths_per_cpu_second", 3),
                r.get("threads").to_string(),
                r.fixed("mean_rel_stderr", 4),
            ]
        });
        out.push_str(&table(
            &[
                "majorant",
                "interpolation",
                "medium N",
                "image",
                "spp",
                "paths/s",
                "paths per CPU-second",
                "threads",
                "mean relative std. error",
            ],
            rows,
        ));
        out.push('\n');
        out.push_str(&s.png("image.png"));
        Ok(out)
    }
}
