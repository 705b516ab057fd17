//! LPM Fig 7 analog: bytes against volume size. Our exact per-buffer accounting
//! (`solvers::lpm::memory_bytes_sliced`, f32, one channel, m = 5: 25 directions per LPM, 6 U
//! and 1 I), unstreamed and with slice streaming at S = 16 slabs per slice (§4.2, D19: T holds
//! one slice), next to the paper's formulas without and with streaming (§5,
//! `solvers::lpm::paper_memory_bytes`, `paper_streaming_memory_bytes`) and, up to
//! `--measure-max`, the bytes the solver reports it allocated (Σ capacities of its resident
//! buffers after a one-order solve, unstreamed and streamed). Above `--measure-max` the rows
//! are formula only (`measured_by`). Lines at 1.5 GB, 2 GB (the paper's Fig 7) and 139 GiB
//! (one H200).

use crate::common::{CommonArgs, Ctx, list_item};
use crate::experiment::{BackendSupport, Experiment, Promise};
use crate::plot::{Axis, Series, Style, plot};
use crate::report::{Section, table};
use anyhow::{Context, Result, bail};
use serde::Serialize;
use solvers::lpm::{self, BoundaryLight, Directions, LpmConfig, Orders, Streaming};
use solvers::{Backend, Grid, Medium, Precision};

/// Flags of `lpm_memory`.
#[derive(Debug, Clone, clap::Parser)]
#[command(about = "LPM Fig 7: memory against volume size, formula vs measured")]
pub struct Args {
    /// Shared flags.
    #[command(flatten)]
    pub common: CommonArgs,
    /// Voxels per axis (default 16,32,64,128,256; 16,32 with --quick).
    #[arg(long, value_delimiter = ',', value_parser = list_item::<usize>)]
    pub n: Vec<usize>,
    /// Largest n that is also solved to measure the allocation (default 128; 32 with --quick).
    #[arg(long)]
    pub measure_max: Option<usize>,
}

/// One size (`memory.csv`).
#[derive(Debug, Clone, Serialize)]
pub struct MemoryRow {
    /// Voxels per axis.
    pub n: usize,
    /// Our formula, total (resident + transient ray states), bytes.
    pub formula_total: u64,
    /// Our formula, resident buffers, bytes.
    pub formula_resident: u64,
    /// Measured resident bytes (Σ capacities after a solve; empty above --measure-max).
    pub measured_resident: Option<u64>,
    /// Peak resident set of the process after this solve (VmHWM of /proc/self/status,
    /// bytes; sizes run in increasing order, so it is this solve's peak plus the process).
    pub rss_peak: Option<u64>,
    /// The paper's formula without streaming, one channel: 4((1 + 2U + I)n³ + p n² + p n³).
    pub paper: u64,
    /// The paper's formula, RGB (nbSpect = 3).
    pub paper_rgb: u64,
    /// The paper's streaming formula with S = 16, one channel: 4((1 + 2U + I)S n² + S p n² + p n²).
    pub paper_streaming_s16: u64,
    /// `solve` where the measured columns come from solves, `formula` above --measure-max.
    pub measured_by: String,
    /// Slabs per slice of the streamed columns (16, or n when n < 16).
    pub stream_slabs: usize,
    /// Our formula with streaming at `stream_slabs`, total, bytes.
    pub streamed_formula_total: u64,
    /// Our formula with streaming, resident buffers, bytes.
    pub streamed_formula_resident: u64,
    /// Measured resident bytes of the streamed solve (empty above --measure-max).
    pub streamed_measured_resident: Option<u64>,
    /// T of one slice with streaming, bytes.
    pub streamed_t: u64,
    /// CPU seconds (user + system, 2 threads) of the unstreamed one-order solve (empty above
    /// --measure-max).
    pub cpu_s_unstreamed: Option<f64>,
    /// CPU seconds of the streamed one-order solve.
    pub cpu_s_streamed: Option<f64>,
    /// Medium buffers (σt, σs, j/4π and the x-layout copies).
    pub medium: u64,
    /// Two U sets of 6 cones.
    pub u: u64,
    /// I.
    pub i: u64,
    /// T of one LPM's 25 directions.
    pub t: u64,
    /// Total and per-order fluence.
    pub fluence: u64,
    /// Geometry tables.
    pub tables: u64,
    /// Transient ray states and scratch.
    pub rays: u64,
}

/// Runs the experiment.
pub fn run(args: &Args) -> Result<Vec<MemoryRow>> {
    crate::experiment::run::<LpmMemory>(args)
}

/// CPU seconds (user + system, all threads) of this process so far, from /proc/self/stat
/// (clock ticks of 10 ms), where /proc is readable.
fn cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the parenthesised command name: state is field 3, utime 14, stime 15.
    let rest = stat.rsplit_once(')')?.1;
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0)
}

/// VmHWM (peak resident set) of this process in bytes, where /proc is readable.
fn peak_rss() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// One order, m = 5, unstreamed (the streamed runs set `Streaming::Slabs(16)`).
fn config() -> LpmConfig {
    LpmConfig {
        m: 5,
        orders: Orders::Fixed(1),
        streaming: Streaming::Whole,
        ..LpmConfig::default()
    }
}

fn run_in(ctx: &mut Ctx, args: &Args) -> Result<Vec<MemoryRow>> {
    let quick = args.common.quick;
    let ns = if args.n.is_empty() {
        if quick {
            vec![16, 32]
        } else {
            vec![16, 32, 64, 128, 256]
        }
    } else {
        args.n.clone()
    };
    if let Some(&n) = ns.iter().find(|&&n| !(3..=4096).contains(&n)) {
        bail!("--n: {n} is outside [3, 4096]");
    }
    let measure_max = args.measure_max.unwrap_or(if quick { 32 } else { 128 });
    let cfg = config();
    let mut work = crate::cost::Estimate::new();
    for &n in ns.iter().filter(|&&n| n <= measure_max) {
        // Two one-order solves (unstreamed and S = 16).
        work.add(
            format!("n = {n}: two one-order solves"),
            2.0 * 265.0 * (n as f64).powi(3),
        );
    }
    ctx.work(&work)?;
    ctx.start(
        serde_json::json!({"n": ns, "measure_max": measure_max, "m": cfg.m,
        "word_bytes": 4, "orders": 1, "stream_slabs": 16,
        "measured_by": "solve up to measure_max, formula above"}),
    )?;
    let pb = ctx.progress(ns.len() as u64, "lpm_memory");
    let mut rows = Vec::new();
    for &n in &ns {
        let grid = Grid::cube(n, 1.0)?;
        let f = lpm::memory_bytes_sliced(&grid, &cfg, 4, n);
        let stream_slabs = 16.min(n);
        let streamed_cfg = LpmConfig {
            streaming: Streaming::Slabs(stream_slabs),
            ..cfg.clone()
        };
        let fs = lpm::memory_bytes_sliced(&grid, &cfg, 4, stream_slabs);
        let measured = if n <= measure_max {
            solvers::budget::check(format!("lpm_memory n = {n}"), f.total())?;
            let medium = Medium::homogeneous(grid, 2.0 * n as f64, 0.9)?;
            let dirs = Directions::new(cfg.m)?;
            let mut one = |c: &LpmConfig, what: &str| -> Result<(u64, Option<f64>)> {
                let t0 = std::time::Instant::now();
                let c0 = cpu_seconds();
                let s = lpm::solve(
                    &Backend::Cpu(Precision::F32),
                    &medium,
                    &BoundaryLight::uniform(&dirs, 1.0),
                    c,
                    |_, _| {},
                )
                .with_context(|| format!("LPM solve at n = {n} ({what})"))?;
                ctx.timing(
                    format!("n = {n}: one order, {what}"),
                    t0.elapsed().as_secs_f64(),
                );
                if s.memory.resident_measured != s.memory.formula.resident() {
                    bail!(
                        "n = {n} ({what}): measured {} B differs from the formula's {} B",
                        s.memory.resident_measured,
                        s.memory.formula.resident()
                    );
                }
                let cpu = cpu_seconds()
                    .zip(c0)
                    .map(|(a, b)| ((a - b) * 100.0).round() / 100.0);
                Ok((s.memory.resident_measured, cpu))
            };
            let unstreamed = one(&cfg, "unstreamed")?;
            let rss = peak_rss();
            let streamed = one(&streamed_cfg, &format!("S = {stream_slabs}"))?;
            Some((unstreamed, rss, streamed))
        } else {
            None
        };
        let (measured, rss_peak, streamed_measured, cpu_u, cpu_s) = match measured {
            Some(((m, cu), r, (s, cs))) => (Some(m), r, Some(s), cu, cs),
            None => (None, None, None, None, None),
        };
        let n64 = n as u64;
        let paper = lpm::paper_memory_bytes(n64, 6, 1, 25, 1);
        let s = 16u64.min(n64);
        rows.push(MemoryRow {
            n,
            formula_total: f.total(),
            formula_resident: f.resident(),
            measured_resident: measured,
            rss_peak,
            paper,
            paper_rgb: lpm::paper_memory_bytes(n64, 6, 1, 25, 3),
            paper_streaming_s16: lpm::paper_streaming_memory_bytes(n64, 6, 1, 25, s, 1),
            measured_by: if measured.is_some() {
                "solve"
            } else {
                "formula"
            }
            .into(),
            stream_slabs,
            streamed_formula_total: fs.total(),
            streamed_formula_resident: fs.resident(),
            streamed_measured_resident: streamed_measured,
            streamed_t: fs.t,
            cpu_s_unstreamed: cpu_u,
            cpu_s_streamed: cpu_s,
            medium: f.medium,
            u: f.u,
            i: f.i,
            t: f.t,
            fluence: f.fluence,
            tables: f.tables,
            rays: f.rays,
        });
        pb.inc(1);
    }
    pb.finish_and_clear();
    ctx.csv("memory.csv", &rows)?;
    let gib = |b: u64| b as f64 / (1u64 << 30) as f64;
    let mut series = vec![
        Series::new(
            "ours: formula, total",
            rows.iter()
                .map(|r| (r.n as f64, gib(r.formula_total)))
                .collect(),
            Style::Line,
            0,
        ),
        Series::new(
            "ours: formula, resident",
            rows.iter()
                .map(|r| (r.n as f64, gib(r.formula_resident)))
                .collect(),
            Style::Dashed,
            0,
        ),
        Series::new(
            "ours: formula, streaming S = 16, total",
            rows.iter()
                .map(|r| (r.n as f64, gib(r.streamed_formula_total)))
                .collect(),
            Style::Line,
            3,
        ),
        Series::new(
            "paper §5, no streaming",
            rows.iter().map(|r| (r.n as f64, gib(r.paper))).collect(),
            Style::Line,
            1,
        ),
        Series::new(
            "paper §5, streaming S = 16",
            rows.iter()
                .map(|r| (r.n as f64, gib(r.paper_streaming_s16)))
                .collect(),
            Style::Dashed,
            1,
        ),
    ];
    let measured: Vec<(f64, f64)> = rows
        .iter()
        .filter_map(|r| r.measured_resident.map(|b| (r.n as f64, gib(b))))
        .collect();
    if !measured.is_empty() {
        series.push(Series::new(
            "ours: measured resident",
            measured,
            Style::Points,
            2,
        ));
    }
    let streamed: Vec<(f64, f64)> = rows
        .iter()
        .filter_map(|r| r.streamed_measured_resident.map(|b| (r.n as f64, gib(b))))
        .collect();
    if !streamed.is_empty() {
        series.push(Series::new(
            "ours: measured resident, streaming S = 16",
            streamed,
            Style::Points,
            4,
        ));
    }
    let (lo, hi) = (
        rows.iter().map(|r| r.n).min().unwrap_or(16) as f64,
        rows.iter().map(|r| r.n).max().unwrap_or(256) as f64,
    );
    for (label, bytes, colour) in [
        ("1.5 GB", 1.5e9, 5),
        ("2 GB", 2e9, 6),
        ("139 GiB (H200)", 139.0 * (1u64 << 30) as f64, 7),
    ] {
        let y = bytes / (1u64 << 30) as f64;
        series.push(Series::new(
            label,
            vec![(lo, y), (hi, y)],
            Style::Dashed,
            colour,
        ));
    }
    plot(
        &ctx.path("memory.png"),
        "LPM Fig 7: memory vs volume size (m = 5, f32, one channel)",
        &Axis::log("voxels per axis n"),
        &Axis::log("GiB"),
        &series,
    )?;
    Ok(rows)
}

/// LPM Fig 7 in the registry.
#[derive(Debug)]
pub struct LpmMemory;

impl Experiment for LpmMemory {
    const NAME: &'static str = "lpm_memory";
    const TITLE: &'static str = "LPM Fig 7: memory against volume size";
    const BACKEND: BackendSupport =
        BackendSupport::CpuOnly("byte counts of the CPU solver (no GPU LPM accounting here)");
    type Args = Args;
    type Summary = Vec<MemoryRow>;

    fn common(args: &Args) -> &CommonArgs {
        &args.common
    }

    fn promises(_args: &Args) -> Vec<Promise> {
        vec![
            Promise::csv(
                "memory.csv",
                &[
                    "n",
                    "formula_total",
                    "formula_resident",
                    "measured_resident",
                    "paper",
                    "paper_rgb",
                    "paper_streaming_s16",
                    "measured_by",
                    "stream_slabs",
                    "streamed_formula_total",
                    "streamed_formula_resident",
                    "streamed_measured_resident",
                ],
            ),
            Promise::file("memory.png"),
        ]
    }

    fn run(ctx: &mut Ctx, args: &Args) -> Result<Self::Summary> {
        run_in(ctx, args)
    }

    fn report(s: &Section<'_>) -> Result<String> {
        let t = s.csv("memory.csv")?;
        t.require(&["n", "formula_total", "formula_resident", "paper"])?;
        let mib = |v: f64| format!("{:.1}", v / (1u64 << 20) as f64);
        let mut out = String::from(
            "Bytes of one LPM solve (m = 5: 25 directions per LPM, 6 U cones, 1 I, f32, one \
             channel; RGB runs three such solves one after another) by our per-buffer formula, as \
             measured (Σ capacities the solver reports after a one-order solve), unstreamed and with \
             slice streaming at S = 16 slabs per slice (T holds one slice of the 25 directions; the \
             volume stays resident), and by the paper's §5 formulas without and with streaming \
             (S = 16; the paper's streams the volume too, ours only T). Rows above the measured \
             range are formula only.\n\n",
        );
        out.push_str(&table(
            &[
                "n",
                "ours total (MiB)",
                "ours resident (MiB)",
                "measured resident (MiB)",
                "process peak RSS (MiB)",
                "paper (MiB)",
                "paper RGB (MiB)",
                "paper streaming S=16 (MiB)",
                "ours streamed S=16 total (MiB)",
                "measured streamed resident (MiB)",
            ],
            t.rows().map(|r| {
                let measured = r.get("measured_resident");
                vec![
                    r.get("n").to_string(),
                    mib(r.num("formula_total")),
                    mib(r.num("formula_resident")),
                    if measured.is_empty() {
                        "not run".to_string()
                    } else {
                        mib(r.num("measured_resident"))
                    },
                    if r.get("rss_peak").is_empty() {
                        "–".to_string()
                    } else {
                        mib(r.num("rss_peak"))
                    },
                    mib(r.num("paper")),
                    mib(r.num("paper_rgb")),
                    mib(r.num("paper_streaming_s16")),
                    if r.get("streamed_formula_total").is_empty() {
                        "–".to_string()
                    } else {
                        mib(r.num("streamed_formula_total"))
                    },
                    if !r.get("streamed_measured_resident").is_empty() {
                        mib(r.num("streamed_measured_resident"))
                    } else {
                        "not run".to_string()
                    },
                ]
            }),
        ));
        out.push('\n');
        out.push_str(&s.png("memory.png"));
        Ok(out)
    }
}
