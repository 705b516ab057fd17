//! Regenerates every figure: runs each experiment (full size, or CI-sized with `--quick`) and
//! writes `results/README.md` with every plot embedded and a table of key numbers.

use anyhow::{Context, Result};
use clap::Parser;
use experiments::common::{CommonArgs, git_revision, workspace_root};
use experiments::{
    accuracy_cost, convergence, lbm_convergence, lbm_diffusion_limit, mitsuba_compare,
    point_source, point_source_analytic, pt_point_source, pt_render, pt_slab, renderings,
    transport_references,
};
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Debug, Parser)]
#[command(about = "Run every experiment and write results/README.md")]
struct Args {
    /// Results root (default `results/` in the workspace).
    #[arg(long)]
    out: Option<PathBuf>,
    /// CI-sized runs.
    #[arg(long)]
    quick: bool,
    /// Hide progress bars.
    #[arg(long)]
    no_progress: bool,
    /// Where the grid solvers run: cpu, gpu or both (passed to every experiment that solves).
    #[arg(long, default_value = "cpu")]
    backend: String,
}

fn main() -> Result<()> {
    let args = Args::parse();
    let root = args
        .out
        .clone()
        .unwrap_or_else(|| workspace_root().join("results"));
    let common = |name: &str| CommonArgs {
        out: Some(root.join(name)),
        quick: args.quick,
        no_progress: args.no_progress,
    };
    let t0 = Instant::now();

    let mut times = Vec::new();
    timed(
        &mut times,
        "point_source_analytic",
        "[1/9] FLD Fig 3".into(),
        || {
            let mut a = point_source_analytic::Args::parse_from(["point_source_analytic"]);
            a.common = common("point_source_analytic");
            point_source_analytic::run(&a)
        },
    )?;
    let n5 = if args.quick { 31 } else { 127 };
    let fig5 = timed(
        &mut times,
        "point_source",
        format!("[2/9] FLD Fig 5: CDA and FLD-LP, {n5}³"),
        || {
            let mut a = point_source::Args::parse_from(["point_source", "--limiter", "cda,lp"]);
            a.common = common("point_source");
            a.backend.backend = args.backend.clone();
            point_source::run(&a)
        },
    )?;
    let n_lim = if args.quick { 21 } else { 63 };
    let limiters = timed(
        &mut times,
        "flux_limiters",
        format!("[3/9] every limiter, both Knudsen forms, {n_lim}³"),
        || {
            let mut a = point_source::Args::parse_from([
                "point_source",
                "--limiter",
                "all",
                "--effective-albedo",
                "--boundary",
                "zero",
            ]);
            a.n = Some(n_lim);
            a.common = common("flux_limiters");
            a.backend.backend = args.backend.clone();
            point_source::run(&a)
        },
    )?;
    let conv = timed(&mut times, "convergence", "[4/9] FLD Fig 4".into(), || {
        let mut a = convergence::Args::parse_from(["convergence"]);
        a.common = common("convergence");
        a.backend.backend = args.backend.clone();
        convergence::run(&a)
    })?;
    let lbm_conv = timed(
        &mut times,
        "lbm_convergence",
        "[LB 1/2] LB Fig 5: total lattice density, steps to steady state vs N".into(),
        || {
            let mut a = lbm_convergence::Args::parse_from(["lbm_convergence"]);
            a.common = common("lbm_convergence");
            a.backend.backend = args.backend.clone();
            lbm_convergence::run(&a)
        },
    )?;
    let lbm_diff = timed(
        &mut times,
        "lbm_diffusion_limit",
        "[LB 2/2] LB Eq 19: fitted diffusion coefficient".into(),
        || {
            let mut a = lbm_diffusion_limit::Args::parse_from(["lbm_diffusion_limit"]);
            a.common = common("lbm_diffusion_limit");
            lbm_diffusion_limit::run(&a)
        },
    )?;

    timed(
        &mut times,
        "transport_references",
        "[5/9] exact transport references".into(),
        || {
            let mut a = transport_references::Args::parse_from(["transport_references"]);
            a.common = common("transport_references");
            transport_references::run(&a)
        },
    )?;
    timed(
        &mut times,
        "pt_point_source",
        "[6/9] path tracer: point-source shells vs exact".into(),
        || {
            let mut a = pt_point_source::Args::parse_from(["pt_point_source"]);
            a.common = common("pt_point_source");
            pt_point_source::run(&a)
        },
    )?;
    timed(
        &mut times,
        "pt_slab",
        "[7/9] path tracer: slabs vs adding-doubling and H".into(),
        || {
            let mut a = pt_slab::Args::parse_from(["pt_slab"]);
            a.common = common("pt_slab");
            pt_slab::run(&a)
        },
    )?;
    timed(
        &mut times,
        "pt_render",
        "[8/9] path tracer throughput".into(),
        || {
            let mut a = pt_render::Args::parse_from(["pt_render"]);
            a.common = common("pt_render");
            pt_render::run(&a)
        },
    )?;
    let rend = timed(
        &mut times,
        "renderings",
        "[R 1/2] FLD Figs 1, 6, 7: path tracing vs FLD vs CDA, albedo sweep".into(),
        || {
            let mut a = renderings::Args::parse_from(["renderings"]);
            a.common = common("renderings");
            a.backend.backend = args.backend.clone();
            renderings::run(&a)
        },
    )?;
    let atlas = timed(
        &mut times,
        "accuracy_cost",
        "[R 2/2] accuracy vs time atlas".into(),
        || {
            let mut a = accuracy_cost::Args::parse_from(["accuracy_cost"]);
            a.common = common("accuracy_cost");
            a.backend.backend = args.backend.clone();
            accuracy_cost::run(&a)
        },
    )?;
    // Mitsuba is optional for the figures: without its venv the comparison is skipped with a
    // note (the tests require it in CI).
    let mut mitsuba_note = String::new();
    for scene in ["cloud_directional", "emissive_sphere"] {
        let path = workspace_root()
            .join("scenes")
            .join(format!("{scene}.toml"));
        let name: &'static str = if scene == "cloud_directional" {
            "mitsuba_compare/cloud_directional"
        } else {
            "mitsuba_compare/emissive_sphere"
        };
        let r = timed(
            &mut times,
            name,
            format!("[9/9] path tracer vs Mitsuba 3: {scene}"),
            || {
                let mut a = mitsuba_compare::Args::parse_from([
                    "mitsuba_compare",
                    "--scene",
                    path.to_str().unwrap_or_default(),
                ]);
                a.common = common(name);
                mitsuba_compare::run(&a)
            },
        );
        if let Err(e) = r {
            let msg = format!("{e:#}");
            if msg.contains("setup-mitsuba.sh") {
                eprintln!("skipped mitsuba_compare: {msg}");
                mitsuba_note = format!("Mitsuba comparison skipped: {msg}");
                break;
            }
            return Err(e);
        }
    }

    let total = t0.elapsed().as_secs_f64();
    let mut readme = report(&args, &fig5, &limiters, &conv, &times, total);
    readme.push_str(&reference_sections(&root, &mitsuba_note));
    readme.push_str(&lbm_section(&lbm_conv, &lbm_diff));
    readme.push_str(&pipeline_sections(&rend, &atlas));
    let path = root.join("README.md");
    std::fs::write(&path, readme).with_context(|| format!("writing {}", path.display()))?;
    eprintln!("done in {total:.0} s; see {}", path.display());
    Ok(())
}

/// Sections for the reference experiments: their plots and CSV tables as written.
fn reference_sections(root: &std::path::Path, mitsuba_note: &str) -> String {
    let mut s = String::new();
    let csv = |rel: &str| std::fs::read_to_string(root.join(rel)).unwrap_or_default();
    let pngs = |dir: &str| -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(root.join(dir))
            .map(|it| {
                it.filter_map(|e| e.ok())
                    .map(|e| e.file_name().to_string_lossy().to_string())
                    .filter(|n| n.ends_with(".png"))
                    .collect()
            })
            .unwrap_or_default();
        v.sort();
        v
    };
    let sections = [
        (
            "transport_references",
            "Exact transport references (`transport_references/`)",
            "Case–Zweifel point source, Chandrasekhar H-function and adding–doubling slabs, each \
             checked against an independent second computation (see `reference::transport`). \
             Grosjean's error against the exact point source:",
            "point_source_summary.csv",
        ),
        (
            "pt_point_source",
            "Path tracer: point-source shells (`pt_point_source/`)",
            "Average of 4πr²φ over each shell, with batch-means standard errors, against the exact \
             solution (`z` column):",
            "shells.csv",
        ),
        (
            "pt_slab",
            "Path tracer: slabs (`pt_slab/`)",
            "Diffuse reflectance and transmittance against the adding–doubling solver and the \
             H-function (`z_*` columns):",
            "slab.csv",
        ),
        (
            "pt_render",
            "Path tracer: throughput (`pt_render/`)",
            "Paths per second on a noise cloud, majorant grid vs one global majorant:",
            "timing.csv",
        ),
    ];
    for (dir, title, text, table) in sections {
        let _ = writeln!(s, "\n## {title}\n\n{text}\n");
        let t = csv(&format!("{dir}/{table}"));
        if !t.is_empty() {
            let _ = writeln!(s, "```\n{t}```");
        }
        for p in pngs(dir) {
            let _ = writeln!(s, "![{p}]({dir}/{p})");
        }
    }
    let _ = writeln!(
        s,
        "\n## Path tracer vs Mitsuba 3 (`mitsuba_compare/`)\n\n\
         Per-pixel Welch t-test with Šidák correction (family-wise α = 0.01), image means with \
         standard errors, and paths per second of both renderers measured in the same run."
    );
    if !mitsuba_note.is_empty() {
        let _ = writeln!(s, "\n{mitsuba_note}");
    }
    for scene in ["cloud_directional", "emissive_sphere"] {
        let dir = format!("mitsuba_compare/{scene}");
        let t = csv(&format!("{dir}/comparison.csv"));
        if t.is_empty() {
            continue;
        }
        let _ = writeln!(s, "\n### `{scene}`\n\n```\n{t}```");
        for p in ["ours.png", "mitsuba.png", "difference.png"] {
            let _ = writeln!(s, "![{scene} {p}]({dir}/{p})");
        }
    }
    s
}

/// The lattice-Boltzmann section: LB Fig 5 (steps to steady state vs N) and the LB Eq 19 fit.
fn lbm_section(
    conv: &[lbm_convergence::StepsRow],
    diff: &[lbm_diffusion_limit::CaseRow],
) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "\n## Lattice-Boltzmann lighting: LB Fig 5 (`lbm_convergence/`)\n\n\
         Noise cloud lit by a directional light, albedo 0.9, the paper's model. `paper`: per-site σt = 0.25·density \
         (LB Section 4; optical size grows with N); `physical`: the same physical cloud at every N. Steps until the \
         relative change of the total density per step is below the tolerance (LB Section 5 observes about 2N).\n"
    );
    let _ = writeln!(
        s,
        "| series | N | backend | tolerance | steps | steps/N | (injected − outflow)/injected | MLUPS |\n|---|---|---|---|---|---|---|---|"
    );
    for r in conv {
        let _ = writeln!(
            s,
            "| {} | {} | {}-{} | {:.0e} | {}{} | {:.2} | {:.1e} | {:.1} |",
            r.series,
            r.n,
            r.backend,
            r.precision,
            r.tolerance,
            r.steps,
            if r.converged { "" } else { " (cap)" },
            r.steps_over_n,
            r.balance,
            r.mlups
        );
    }
    for f in ["fig5_total_density.png", "steps_vs_n.png"] {
        let _ = writeln!(s, "![{f}](lbm_convergence/{f})");
    }
    let n = diff.first().map(|r| r.n).unwrap_or(0);
    let _ = writeln!(
        s,
        "\n## Lattice-Boltzmann diffusion limit: LB Eq 19 (`lbm_diffusion_limit/`)\n\n\
         Steady point source on a {n}³ lattice (paper's model, f64); ρ fitted with a/r + b, D_fit = 1/(4πa), against \
         D = (2/σt − 1)/(4(1 + σa)). Kn = (1/σt)/r_min; the limit is taken to apply for Kn ≤ 0.5.\n"
    );
    let _ = writeln!(
        s,
        "| σt | σa | steps | D Eq 19 | D fit | ratio | Kn | applies |\n|---|---|---|---|---|---|---|---|"
    );
    for r in diff {
        let _ = writeln!(
            s,
            "| {} | {} | {}{} | {:.4} | {:.4} | {:.4} | {:.2} | {} |",
            r.sigma_t,
            r.sigma_a,
            r.steps,
            if r.steady { "" } else { " (cap)" },
            r.d_eq19,
            r.d_fit,
            r.ratio,
            r.knudsen,
            r.applies
        );
    }
    for f in ["d_fit_vs_eq19.png", "rho_profiles.png"] {
        let _ = writeln!(s, "![{f}](lbm_diffusion_limit/{f})");
    }
    if let Ok(csv) = std::fs::read_to_string(workspace_root().join("results/bench/lbm.csv")) {
        let _ = writeln!(
            s,
            "\n### Benchmark (`cargo bench -p benches --bench lbm`, last committed run)\n\n\
             MLUPS and effective bytes/s (19 f32/f64 values read + 19 written per site) against the STREAM triad and \
             copy of the same machine (CPU) or the device copy probe (GPU; `llvmpipe` is Mesa's CPU Vulkan driver).\n\n```\n{csv}```"
        );
    }
    s
}

/// The renderings tables (FLD's claim, quarter resolution) and the atlas's summary.
fn pipeline_sections(rend: &renderings::Outcome, atlas: &[accuracy_cost::Point]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "\n## Renderings: path tracing vs FLD vs CDA (`renderings/`, FLD Figs 1, 6, 7)\n\n\
         Each scene's albedo set to α in every voxel and channel; reference: the path tracer's single-, multiple- \
         and emission components. Errors are relative RMSEs over all pixels and channels (`errors.csv` has every \
         run; images `<scene>_a<α>.png`: reference | CDA and FLD-LP at each factor, one exposure; \
         `_error.png`: signed multiple-scattering error).\n\n\
         ### FLD's claim (Section 6.2): FLD-LP's multiple-scattering error below CDA's at albedo ≥ 0.5\n"
    );
    let _ = writeln!(
        s,
        "| scene | α | downsample | FLD-LP | CDA | reference noise | FLD lower |\n|---|---|---|---|---|---|---|"
    );
    for c in &rend.claim {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.3} | {:.3} | {:.3} | {} |",
            c.scene,
            c.albedo,
            c.downsample,
            c.fld_lp_error_multiple,
            c.cda_error_multiple,
            c.reference_noise_multiple,
            if c.fld_lower { "yes" } else { "**no**" }
        );
    }
    let _ = writeln!(
        s,
        "\n### Reduced-resolution diffusion (FLD Fig 6): cost and error against full resolution\n\n\
         | scene | α | method | factor | full solve (s) | reduced solve (s) | cost ratio | error full → reduced | multiple-scattering error full → reduced |\n|---|---|---|---|---|---|---|---|---|"
    );
    for q in &rend.quarter {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {:.2} | {:.3} | 1/{:.0} | {:.3} → {:.3} | {:.3} → {:.3} |",
            q.scene,
            q.albedo,
            q.method,
            q.downsample,
            q.full_seconds,
            q.reduced_seconds,
            1.0 / q.cost_ratio,
            q.full_error,
            q.reduced_error,
            q.full_error_multiple,
            q.reduced_error_multiple
        );
    }
    let mut scenes: Vec<&str> = rend.errors.iter().map(|e| e.scene.as_str()).collect();
    scenes.dedup();
    for sc in scenes {
        let _ = writeln!(
            s,
            "\n![{sc}](renderings/{sc}_a0.9.png)\n![{sc} error](renderings/{sc}_a0.9_error.png)"
        );
    }
    let _ = writeln!(
        s,
        "\n## Accuracy vs time atlas (`accuracy_cost/`)\n\n\
         Every method setting on every dataset against a path-traced reference (`points.csv`: \
         `scene,method,setting,backend,seconds,error,error_stderr`, …; `error_stderr` is the reference's own \
         relative noise, the floor below which errors cannot be resolved). Methods: the path tracer at increasing \
         spp, and the grid pipeline with CDA, FLD-LP and lattice-Boltzmann (LB) as the multiple-scattering pass \
         at diffusion downsampling 4, 2, 1, tolerances and precisions (`setting`).\n\n\
         ### Fastest to 5 %, 2 % and 1 % relative RMSE (debiased: the reference's variance removed)\n\n\
         | scene | target | fastest | setting | backend | seconds | error |\n|---|---|---|---|---|---|---|"
    );
    for f in accuracy_cost::fastest(atlas) {
        let what = if f.method.is_empty() {
            "none reached it".to_string()
        } else {
            f.method.clone()
        };
        let _ = writeln!(
            s,
            "| {} | {:.0} % | {}{} | {} | {} | {} | {} |",
            f.scene,
            100.0 * f.target,
            what,
            if f.resolvable {
                ""
            } else {
                " (below the reference noise)"
            },
            f.setting,
            f.backend,
            if f.seconds.is_finite() {
                format!("{:.2}", f.seconds)
            } else {
                "—".into()
            },
            if f.error.is_finite() {
                format!("{:.4}", f.error)
            } else {
                "—".into()
            },
        );
    }
    let _ = writeln!(
        s,
        "\n### Best error per method and scene (and its time)\n\n| scene | method | best error | setting | seconds | reference noise |\n|---|---|---|---|---|---|"
    );
    let mut keys: Vec<(&str, &str)> = atlas
        .iter()
        .map(|p| (p.scene.as_str(), p.method.as_str()))
        .collect();
    keys.dedup();
    for (sc, m) in keys {
        if let Some(p) = atlas
            .iter()
            .filter(|p| p.scene == sc && p.method == m)
            .min_by(|a, b| a.error.total_cmp(&b.error))
        {
            let _ = writeln!(
                s,
                "| {sc} | {m} | {:.4} | {} | {:.2} | {:.4} |",
                p.error, p.setting, p.seconds, p.error_stderr
            );
        }
    }
    let mut scenes: Vec<&str> = atlas.iter().map(|p| p.scene.as_str()).collect();
    scenes.dedup();
    for sc in scenes {
        let _ = writeln!(s, "\n![{sc}](accuracy_cost/pareto_{sc}.png)");
    }
    s
}

/// Runs one experiment, printing `label` first and recording its wall time under `name`.
fn timed<R>(
    times: &mut Vec<(&'static str, f64)>,
    name: &'static str,
    label: String,
    f: impl FnOnce() -> Result<R>,
) -> Result<R> {
    eprintln!("{label} ({name})");
    let t = Instant::now();
    let r = f()?;
    times.push((name, t.elapsed().as_secs_f64()));
    Ok(r)
}

/// The distinct values of `it`, sorted.
fn distinct<T: PartialOrd>(it: impl Iterator<Item = T>) -> Vec<T> {
    let mut v: Vec<T> = it.collect();
    v.sort_by(|a, b| a.partial_cmp(b).unwrap_or(std::cmp::Ordering::Equal));
    v.dedup();
    v
}

fn report(
    args: &Args,
    fig5: &[point_source::RunRow],
    lim: &[point_source::RunRow],
    conv: &[convergence::IterRow],
    times: &[(&str, f64)],
    total: f64,
) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# scatterbench results\n");
    let _ = writeln!(
        s,
        "Generated by `cargo run --release -p experiments --bin figures{}` at git revision `{}` in {:.0} s on {} logical cores. \
         Every number below was measured in that run; each experiment's `meta.json` has its parameters, machine and timings.\n",
        if args.quick { " -- --quick" } else { "" },
        git_revision(),
        total,
        std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1)
    );
    let _ = writeln!(s, "| experiment | wall time (s) |\n|---|---|");
    for (name, t) in times {
        let _ = writeln!(s, "| `{name}` | {t:.1} |");
    }

    let _ = writeln!(
        s,
        "\n## FLD Fig 3: analytic point-source solutions (`point_source_analytic/`)\n"
    );
    for f in ["fig3a_grosjean.png", "fig3b_cda.png", "fig3c_knudsen.png"] {
        let _ = writeln!(s, "![{f}](point_source_analytic/{f})");
    }

    let n5 = fig5.first().map(|r| r.n).unwrap_or(0);
    let _ = writeln!(
        s,
        "\n## FLD Fig 5: point source, numeric vs analytic (`point_source/`, {n5}³, τ = 4 across)\n"
    );
    for f in [
        "fig5a_cda_analytic_boundary.png",
        "fig5b_cda_zero_boundary.png",
        "fig5c_fld_lp_zero_boundary.png",
    ] {
        let _ = writeln!(s, "![{f}](point_source/{f})");
    }
    let _ = writeln!(
        s,
        "\nRelative L2 error of φ over all voxels with 0 < τ < 1 (near the source), against Grosjean (FLD Eq 24) \
         and, for CDA, against its own theory (FLD Eq 27). Solver: red-black SOR, ω = 2/(1 + sin(π/n)), R̄/j̄ < 10⁻⁶, f64.\n"
    );
    let _ = writeln!(
        s,
        "| albedo | CDA analytic bdy vs Eq 27 | CDA zero bdy vs Eq 27 | CDA zero bdy vs Grosjean | FLD-LP zero bdy vs Grosjean | FLD-LP iterations | FLD-LP seconds |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|");
    let find = |rows: &[point_source::RunRow], lim: &str, b: &str, k: &str, a: f64| {
        rows.iter()
            .find(|r| r.limiter == lim && r.boundary == b && r.knudsen == k && r.albedo == a)
            .cloned()
    };
    let albedos = distinct(fig5.iter().map(|r| r.albedo));
    for &a in &albedos {
        let (ca, cz, lp) = (
            find(fig5, "cda", "analytic", "sigma_t", a),
            find(fig5, "cda", "zero", "sigma_t", a),
            find(fig5, "lp", "zero", "sigma_t", a),
        );
        let f = |r: &Option<point_source::RunRow>, g: fn(&point_source::RunRow) -> f64| {
            r.as_ref()
                .map(|r| format!("{:.4}", g(r)))
                .unwrap_or_else(|| "–".into())
        };
        let _ = writeln!(
            s,
            "| {a} | {} | {} | {} | {} | {} | {} |",
            f(&ca, |r| r.err_cda_near),
            f(&cz, |r| r.err_cda_near),
            f(&cz, |r| r.err_grosjean_near),
            f(&lp, |r| r.err_grosjean_near),
            lp.as_ref()
                .map(|r| format!(
                    "{}{}",
                    r.iterations,
                    if r.converged { "" } else { " (not converged)" }
                ))
                .unwrap_or_default(),
            lp.as_ref()
                .map(|r| format!("{:.1}", r.seconds))
                .unwrap_or_default()
        );
    }

    let nl = lim.first().map(|r| r.n).unwrap_or(0);
    let _ = writeln!(
        s,
        "\n## Flux-limiter comparison (`flux_limiters/`, {nl}³, zero boundary)\n"
    );
    let _ = writeln!(
        s,
        "Relative L2 error against Grosjean over voxels with 0 < τ < 1, for every limiter of FLD Table 2, with the paper's Knudsen number \
         R = |∇φ|/(σt φ) and with Levermore–Pomraning's effective-albedo form R = |∇φ|/(α σt φ), D = F(R)/(α σt). Lower is better; **bold** is the best per albedo.\n"
    );
    let limiters = distinct(lim.iter().map(|r| r.limiter.clone()));
    let mut cols = Vec::new();
    for l in &limiters {
        cols.push((l.clone(), "sigma_t"));
        if l != "cda" {
            cols.push((l.clone(), "albedo_sigma_t"));
        }
    }
    let _ = write!(s, "| albedo |");
    for (l, k) in &cols {
        let _ = write!(
            s,
            " {l}{} |",
            if *k == "albedo_sigma_t" {
                " (ασt)"
            } else {
                ""
            }
        );
    }
    let _ = write!(s, "\n|---|");
    for _ in &cols {
        let _ = write!(s, "---|");
    }
    let _ = writeln!(s);
    let lim_albedos = distinct(lim.iter().map(|r| r.albedo));
    for &a in &lim_albedos {
        let vals: Vec<Option<f64>> = cols
            .iter()
            .map(|(l, k)| find(lim, l, "zero", k, a).map(|r| r.err_grosjean_near))
            .collect();
        let best = vals.iter().flatten().copied().fold(f64::INFINITY, f64::min);
        let _ = write!(s, "| {a} |");
        for v in vals {
            match v {
                Some(v) if v == best => {
                    let _ = write!(s, " **{v:.4}** |");
                }
                Some(v) => {
                    let _ = write!(s, " {v:.4} |");
                }
                None => {
                    let _ = write!(s, " – |");
                }
            }
        }
        let _ = writeln!(s);
    }
    let unconverged: Vec<String> = lim
        .iter()
        .filter(|r| !r.converged)
        .map(|r| format!("{} ({}) α={}", r.limiter, r.knudsen, r.albedo))
        .collect();
    if !unconverged.is_empty() {
        let _ = writeln!(
            s,
            "\nNot converged within the iteration cap: {}.",
            unconverged.join(", ")
        );
    }
    let _ = writeln!(s, "\n![limiter errors](flux_limiters/limiter_errors.png)");
    for &a in &lim_albedos {
        let _ = writeln!(
            s,
            "![limiters α = {a}](flux_limiters/limiters_albedo_{a}.png)"
        );
    }

    let _ = writeln!(
        s,
        "\n## FLD Fig 4: convergence (`convergence/`, spherical cloud in vacuum, Perlin emission, FLD-LP)\n"
    );
    for f in [
        "fig4a_residual_vs_iteration.png",
        "fig4b_iterations_vs_resolution.png",
        "fig4c_sigma_eps.png",
    ] {
        let _ = writeln!(s, "![{f}](convergence/{f})");
    }
    let _ = writeln!(
        s,
        "\n| case | ω | n | σε | θ | precision | iterations | converged | seconds |\n|---|---|---|---|---|---|---|---|---|"
    );
    for r in conv {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.0e} | {} | {} | {} | {} | {:.2} |",
            r.case,
            r.omega,
            r.n,
            r.sigma_eps,
            r.theta,
            r.precision,
            r.iterations,
            r.converged,
            r.seconds
        );
    }
    let _ = writeln!(
        s,
        "\n`sor`: our default D under-relaxation θ = 0.5; `sor_theta1`: FLD Algorithm 1 verbatim (θ = 1); `resolution`: Fig 4b; \
         `sigma_eps`: Fig 4c in f32 (tolerance 10⁻⁴). See `solvers::fld` for why θ = 0.5 is the default."
    );
    let bench = workspace_root().join("results/bench/diffusion_cpu.csv");
    if let Ok(csv) = std::fs::read_to_string(&bench) {
        let _ = writeln!(
            s,
            "\n## Benchmark: one red-black iteration vs memory bandwidth (`bench/`, from `cargo bench -p benches`)\n"
        );
        let _ = writeln!(
            s,
            "Not regenerated by `figures`; the CSV below is the last committed bench run.\n\n```\n{}```",
            csv
        );
    }
    let gpu_bench = workspace_root().join("results/bench/diffusion_gpu.csv");
    if let Ok(csv) = std::fs::read_to_string(&gpu_bench) {
        let _ = writeln!(
            s,
            "\n### GPU backend (`cargo bench -p benches --bench diffusion_gpu`)\n\n\
             ms per iteration, effective bytes/s (9 f32 values per voxel for FLD, 7 for CDA) and the same \
             device's copy bandwidth measured in the same run. The adapter is in the first column; on \
             `llvmpipe` (Mesa's CPU Vulkan driver) these are emulation numbers, not GPU numbers.\n\n```\n{}```",
            csv
        );
    }
    s
}
