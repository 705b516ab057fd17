//! One red-black iteration of the CPU diffusion solver (CDA and FLD with the
//! Levermore-Pomraning limiter, `f32` and `f64`) on the FLD Fig 4 vacuum cloud, with a
//! STREAM-like bandwidth probe run in the same process.
//!
//! * Criterion groups `iteration/<precision>/<method>` with the grid size n as parameter time
//!   one [`CpuFld::iterate`] each, with `Throughput::Elements(n³)` so criterion reports voxel
//!   updates per second. Every solver is built once and run for [`WARMUP_ITERATIONS`]
//!   iterations before it is measured (the first iterations start from tiny values).
//! * Then, in benchmark mode only (`--bench` given, no `--list`, `--test` or
//!   `--profile-time`), a summary: per case the median seconds of [`SUMMARY_ITERATIONS`]
//!   iterations, the effective bandwidth `bytes_per_iteration / seconds`, and triad and copy
//!   probes over buffers of the same total byte size as `bytes_per_iteration`, run right
//!   before and right after the solver (the better of the two is reported), and the triad
//!   sized by STREAM's rule (`triad_dram_gbs`, each array ≥ 4× the largest cache, so it
//!   measures main memory; `ratio_triad_dram`), which issue 15's targets are read against
//!   (a 128³ footprint is near the 32 MiB L3 of the 2-core EPYC). The table is
//!   printed and written to `results/bench/diffusion_cpu.csv` in the workspace root. Only the
//!   cases the criterion groups ran are summarised, so a criterion filter applies here too.
//!
//! Sizes: 64, 128, 256 by default; `SCATTERBENCH_BENCH_SIZES=64,128` overrides them. Without
//! `--bench` (`cargo test --benches`) criterion runs each benchmark once as a smoke test; the
//! default sizes are then replaced by [`TEST_SIZES`] so that nothing heavy runs.

use benches::bandwidth::{copy_gbs, len_for_total_bytes, stream_rule_len, triad_gbs};
use benches::median_seconds;
use criterion::{BenchmarkId, Criterion, SamplingMode, Throughput};
use solvers::fld::{Boundary, CpuFld, FldConfig, FluxLimiter};
use solvers::{Medium, Real, scenes};
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// Grid sizes n (n³ voxels) benchmarked by default.
const DEFAULT_SIZES: [usize; 3] = [64, 128, 256];
/// Sizes used when criterion runs in test mode and no sizes are given.
const TEST_SIZES: [usize; 1] = [16];
/// Environment variable overriding the size list, e.g. `64,128`.
const SIZES_ENV: &str = "SCATTERBENCH_BENCH_SIZES";
/// Seed of the Perlin emission of the vacuum cloud (the one the acceptance tests use).
const SEED: u64 = 1;
/// Grid size from which criterion samples flat (the same iteration count in every sample).
const FLAT_SAMPLING_FROM: usize = 128;
/// Iterations run on a fresh solver before anything is timed.
const WARMUP_ITERATIONS: usize = 20;
/// Iterations whose median the summary reports.
const SUMMARY_ITERATIONS: usize = 5;
/// Repetitions of each bandwidth probe (the best is kept).
const PROBE_REPS: usize = 5;
/// Output of the summary, relative to the workspace root.
const CSV_PATH: &str = "results/bench/diffusion_cpu.csv";
const CSV_HEADER: &str = "n,precision,method,ms_per_iter,mvox_per_s,effective_gbs,triad_gbs,copy_gbs,ratio_triad,triad_dram_gbs,ratio_triad_dram,threads,cpu";

/// The two benchmarked diffusion methods.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Method {
    Cda,
    FldLp,
}

impl Method {
    const ALL: [Method; 2] = [Method::Cda, Method::FldLp];

    fn name(self) -> &'static str {
        match self {
            Method::Cda => "CDA",
            Method::FldLp => "FLD-LP",
        }
    }

    fn config(self) -> FldConfig {
        match self {
            Method::Cda => FldConfig::cda(),
            Method::FldLp => FldConfig::fld(FluxLimiter::LevermorePomraning),
        }
    }

    fn index(self) -> usize {
        self as usize
    }
}

/// What criterion was asked to do, from the command line (criterion parses it again).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum RunMode {
    /// `cargo bench`: measure, then print and save the summary.
    Benchmark,
    /// `--list`: criterion only prints the benchmark names (no closure runs).
    List,
    /// `cargo test --benches`, `--test` or `--profile-time`: no summary.
    Other,
}

fn run_mode() -> RunMode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let has = |flag: &str| {
        args.iter()
            .any(|a| a == flag || a.starts_with(&format!("{flag}=")))
    };
    if has("--list") {
        RunMode::List
    } else if has("--bench") && !has("--test") && !has("--profile-time") {
        RunMode::Benchmark
    } else {
        RunMode::Other
    }
}

/// Parses a comma-separated size list such as `64,128` (shared rules: `benches::cli`).
fn parse_sizes(text: &str) -> Result<Vec<usize>, String> {
    benches::cli::parse_sizes(SIZES_ENV, text)
}

/// The size list: from [`SIZES_ENV`] if set, else the defaults for `mode`.
fn sizes(mode: RunMode) -> Result<Vec<usize>, String> {
    match std::env::var(SIZES_ENV) {
        Ok(text) => parse_sizes(&text),
        Err(std::env::VarError::NotPresent) => Ok(if mode == RunMode::Other {
            TEST_SIZES.to_vec()
        } else {
            DEFAULT_SIZES.to_vec()
        }),
        Err(std::env::VarError::NotUnicode(raw)) => {
            Err(format!("{SIZES_ENV}={raw:?} is not valid UTF-8"))
        }
    }
}

/// Prints `message` and exits with status 2 (used for bad input, instead of a panic).
fn fail(message: &str) -> ! {
    eprintln!("error: {message}");
    std::process::exit(2)
}

/// The solvers of one grid size and precision, built on first use and kept for the summary.
struct Case<T: Real> {
    n: usize,
    medium: Option<Medium<T>>,
    solvers: [Option<CpuFld<T>>; 2],
}

impl<T: Real> Case<T> {
    fn new(n: usize) -> Self {
        Self {
            n,
            medium: None,
            solvers: [None, None],
        }
    }

    fn voxels(&self) -> u64 {
        (self.n as u64).pow(3)
    }

    /// The warmed-up solver of `method`, built on first use. The medium is dropped once both
    /// solvers exist. Exits with a message if the solver cannot be built.
    fn solver(&mut self, method: Method) -> &mut CpuFld<T> {
        let Self { n, medium, solvers } = self;
        let last_missing = solvers.iter().filter(|s| s.is_none()).count() == 1;
        solvers[method.index()].get_or_insert_with(|| {
            let solver = build(*n, medium, method);
            if last_missing {
                *medium = None;
            }
            solver
        })
    }
}

/// Builds the solver of `method` on the vacuum cloud of `n`³ voxels (building the medium into
/// `medium` if it is not there yet) and runs [`WARMUP_ITERATIONS`] iterations.
fn build<T: Real>(n: usize, medium: &mut Option<Medium<T>>, method: Method) -> CpuFld<T> {
    let what = || format!("the {} {} solver on {n}³ voxels", T::NAME, method.name());
    let t0 = Instant::now();
    let m = match medium {
        Some(m) => &*m,
        None => &*medium.insert(
            scenes::vacuum_cloud::<T>(n, SEED)
                .unwrap_or_else(|e| fail(&format!("cannot build the medium of {}: {e}", what()))),
        ),
    };
    let t1 = Instant::now();
    let mut solver = CpuFld::new(m, &Boundary::Zero, &method.config())
        .unwrap_or_else(|e| fail(&format!("cannot build {}: {e}", what())));
    let t2 = Instant::now();
    for _ in 0..WARMUP_ITERATIONS {
        solver.iterate();
    }
    eprintln!(
        "setup of {}: medium {:.2} s, solver {:.2} s, {WARMUP_ITERATIONS} warm-up iterations {:.2} s",
        what(),
        (t1 - t0).as_secs_f64(),
        (t2 - t1).as_secs_f64(),
        t2.elapsed().as_secs_f64()
    );
    solver
}

/// Criterion groups `iteration/<precision>/<method>` over the sizes of `cases`.
fn bench_precision<T: Real>(c: &mut Criterion, cases: &mut [Case<T>]) {
    for method in Method::ALL {
        let mut group = c.benchmark_group(format!("iteration/{}/{}", T::NAME, method.name()));
        for case in cases.iter_mut() {
            group.throughput(Throughput::Elements(case.voxels()));
            // From 128³ on an iteration takes tens to hundreds of ms: linear sampling would need
            // 55 iterations for 10 samples, far beyond the measurement time.
            group.sampling_mode(if case.n >= FLAT_SAMPLING_FROM {
                SamplingMode::Flat
            } else {
                SamplingMode::Auto
            });
            group.bench_function(BenchmarkId::from_parameter(case.n), |b| {
                let solver = case.solver(method);
                b.iter(|| solver.iterate());
            });
        }
        group.finish();
    }
}

/// One row of the summary.
#[derive(Debug, Clone)]
struct Row {
    n: usize,
    precision: &'static str,
    method: &'static str,
    seconds: f64,
    voxels: u64,
    bytes: usize,
    triad_gbs: f64,
    copy_gbs: f64,
    /// The STREAM-rule triad (each array ≥ 4× the largest cache), best of before and after.
    triad_dram_gbs: f64,
}

impl Row {
    fn mvox_per_s(&self) -> f64 {
        self.voxels as f64 / self.seconds / 1e6
    }

    fn effective_gbs(&self) -> f64 {
        self.bytes as f64 / self.seconds / 1e9
    }

    fn ratio_triad(&self) -> f64 {
        self.effective_gbs() / self.triad_gbs
    }

    fn ratio_triad_dram(&self) -> f64 {
        self.effective_gbs() / self.triad_dram_gbs
    }

    fn csv(&self) -> String {
        format!(
            "{},{},{},{:.4},{:.3},{:.3},{:.3},{:.3},{:.4},{:.3},{:.4},{},{}",
            self.n,
            self.precision,
            self.method,
            self.seconds * 1e3,
            self.mvox_per_s(),
            self.effective_gbs(),
            self.triad_gbs,
            self.copy_gbs,
            self.ratio_triad(),
            self.triad_dram_gbs,
            self.ratio_triad_dram(),
            rayon::current_num_threads(),
            benches::cli::cpu_model()
        )
    }
}

/// Triad and copy GB/s over buffers holding `bytes` bytes in total, and the STREAM-rule triad.
fn probe(bytes: usize) -> (f64, f64, f64) {
    (
        triad_gbs(len_for_total_bytes(bytes, 3), PROBE_REPS),
        copy_gbs(len_for_total_bytes(bytes, 2), PROBE_REPS),
        triad_gbs(stream_rule_len(), PROBE_REPS),
    )
}

/// Summary rows of one precision, for the solvers the criterion groups built (so a criterion
/// filter applies to the summary too); every solver is dropped after its row is measured.
fn summarise<T: Real>(cases: &mut [Case<T>], rows: &mut Vec<Row>) {
    for method in Method::ALL {
        for case in cases.iter_mut() {
            if case.solvers[method.index()].is_none() {
                continue;
            }
            let voxels = case.voxels();
            let n = case.n;
            let solver = case.solver(method);
            let bytes = solver.bytes_per_iteration();
            let (triad_before, copy_before, dram_before) = probe(bytes);
            let seconds = median_seconds(SUMMARY_ITERATIONS, || solver.iterate());
            let (triad_after, copy_after, dram_after) = probe(bytes);
            case.solvers[method.index()] = None;
            let row = Row {
                n,
                precision: T::NAME,
                method: method.name(),
                seconds,
                voxels,
                bytes,
                triad_gbs: triad_before.max(triad_after),
                copy_gbs: copy_before.max(copy_after),
                triad_dram_gbs: dram_before.max(dram_after),
            };
            println!(
                "summary: {n}³ {} {}: {:.2} ms/iter; triad {triad_before:.2} before / {triad_after:.2} after, \
                 copy {copy_before:.2} / {copy_after:.2}, STREAM-rule triad {dram_before:.2} / {dram_after:.2} GB/s \
                 (footprint {:.0} MiB)",
                row.precision,
                row.method,
                seconds * 1e3,
                bytes as f64 / (1 << 20) as f64
            );
            rows.push(row);
        }
    }
}

fn table(rows: &[Row]) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "{:>5} {:>4} {:>7} {:>10} {:>9} {:>9} {:>9} {:>9} {:>11} {:>9} {:>10}",
        "n",
        "prec",
        "method",
        "ms/iter",
        "Mvox/s",
        "eff GB/s",
        "triad",
        "copy",
        "eff/triad",
        "dram",
        "eff/dram"
    );
    for r in rows {
        let _ = writeln!(
            out,
            "{:>5} {:>4} {:>7} {:>10.2} {:>9.1} {:>9.2} {:>9.2} {:>9.2} {:>11.3} {:>9.2} {:>10.3}",
            r.n,
            r.precision,
            r.method,
            r.seconds * 1e3,
            r.mvox_per_s(),
            r.effective_gbs(),
            r.triad_gbs,
            r.copy_gbs,
            r.ratio_triad(),
            r.triad_dram_gbs,
            r.ratio_triad_dram()
        );
    }
    out
}

/// The workspace root: the parent of this crate's manifest directory.
fn workspace_root() -> PathBuf {
    let manifest = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    manifest.parent().map(PathBuf::from).unwrap_or(manifest)
}

fn write_csv(rows: &[Row]) -> std::io::Result<PathBuf> {
    let path = workspace_root().join(CSV_PATH);
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir)?;
    }
    let mut text = format!("{CSV_HEADER}\n");
    for r in rows {
        text.push_str(&r.csv());
        text.push('\n');
    }
    std::fs::write(&path, text)?;
    Ok(path)
}

fn main() {
    let mode = run_mode();
    let sizes = sizes(mode).unwrap_or_else(|e| fail(&e));
    let mut c = Criterion::default()
        .sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3))
        .configure_from_args();
    let mut cases32: Vec<Case<f32>> = sizes.iter().map(|&n| Case::new(n)).collect();
    let mut cases64: Vec<Case<f64>> = sizes.iter().map(|&n| Case::new(n)).collect();
    bench_precision(&mut c, &mut cases32);
    bench_precision(&mut c, &mut cases64);
    c.final_summary();

    if mode != RunMode::Benchmark {
        return;
    }
    println!(
        "\nsummary ({} rayon threads): median of {SUMMARY_ITERATIONS} iterations after warm-up; \
         triad/copy: best of {PROBE_REPS} runs before and after, over the solver's bytes per iteration",
        rayon::current_num_threads()
    );
    let mut rows = Vec::new();
    summarise(&mut cases32, &mut rows);
    drop(cases32);
    summarise(&mut cases64, &mut rows);
    if rows.is_empty() {
        println!("no benchmark matched the filter; {CSV_PATH} left as it is");
        return;
    }
    println!("\n{}", table(&rows));
    println!(
        "effective bytes: 7 (CDA) / 9 (FLD) values per voxel per iteration; triad counts 3 and copy 2 arrays \
         (no write-allocate traffic), GB = 1e9 bytes"
    );
    match write_csv(&rows) {
        Ok(path) => println!("wrote {}", path.display()),
        Err(e) => eprintln!("error: cannot write {CSV_PATH}: {e}"),
    }
}
