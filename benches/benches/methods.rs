//! Every registered method (`solvers::method::METHODS`, each family with its defaults) on every
//! backend it claims, through the one `Method::solve` interface, with a STREAM triad probe run
//! in the same process. A newly registered method is benchmarked without an edit here.
//!
//! * Criterion groups `step/<backend>/<method>` with the grid size n as parameter: criterion
//!   asks for `iters` steps, the bench runs one fixed-step solve of that many steps on the FLD
//!   Fig 4 vacuum cloud and reports the solver's own time for them (`Solution::seconds`: setup
//!   excluded; GPU timestamps where the adapter has them). `Throughput::Elements(n³)`.
//! * In benchmark mode only (`--bench`, no `--test`/`--list`/`--profile-time`), a summary per
//!   method, backend and size: the median ms per step over [`SUMMARY_RUNS`] solves of
//!   [`SUMMARY_STEPS`] steps, the effective bandwidth `Method::bytes_per_step / seconds`, and
//!   a bandwidth probe over the same footprint run right after in the same process (CPU rows:
//!   the STREAM triad; GPU rows: the device's own copy kernel, `solvers::gpu::bandwidth`), with
//!   the CPU model and the GPU adapter in every row; printed and written to
//!   `results/bench/methods.csv`.
//!
//! Sizes: 32, 64, 128 by default; `SCATTERBENCH_BENCH_SIZES` overrides them; test mode
//! (`cargo test --benches`) runs 12³ once per case.

use benches::bandwidth::{len_for_total_bytes, triad_gbs};
use benches::cli::{benchmark_mode, fail, sizes, write_result};
use criterion::{BenchmarkId, Criterion, Throughput};
use solvers::gpu::{GpuContext, bandwidth};
use solvers::method::{self, Method, Params, Problem, Tolerance};
use solvers::scene::Phase;
use solvers::{Backend, Medium, Precision, scenes};
use std::fmt::Write as _;
use std::time::Duration;

const DEFAULT_SIZES: [usize; 3] = [32, 64, 128];
const TEST_SIZES: [usize; 1] = [12];
const SIZES_ENV: &str = "SCATTERBENCH_BENCH_SIZES";
const SEED: u64 = 1;
/// Steps of each summary solve.
const SUMMARY_STEPS: usize = 20;
/// Solves whose median the summary reports.
const SUMMARY_RUNS: usize = 3;
const CSV_PATH: &str = "results/bench/methods.csv";
const CSV_HEADER: &str = "n,method,backend,timer,ms_per_step,mvox_per_s,effective_gbs,probe,probe_gbs,ratio_probe,cpu,adapter";

fn methods() -> Vec<Box<dyn Method>> {
    method::METHODS
        .iter()
        .map(|f| {
            (f.build)(None, &Params::none()).unwrap_or_else(|e| fail("methods", &e.to_string()))
        })
        .collect()
}

/// Seconds of `steps` steps of one solve (the solver's own timer) and how it was timed.
fn steps_seconds(
    m: &dyn Method,
    b: &Backend<'_>,
    medium: &Medium<f64>,
    steps: usize,
) -> (f64, String) {
    let problem = Problem {
        medium,
        lights: &[],
        phase: Phase::Isotropic,
    };
    match m.solve(b, &problem, &Tolerance::fixed_steps(steps), &mut |_, _| {}) {
        Ok(sol) => (sol.seconds, sol.timer.to_string()),
        Err(e) => fail("methods", &format!("{} on {b}: {e}", m.name())),
    }
}

fn main() {
    let bench = benchmark_mode();
    let sizes = sizes(SIZES_ENV, bench, &DEFAULT_SIZES, &TEST_SIZES)
        .unwrap_or_else(|e| fail("methods", &e));
    let gpu = match GpuContext::from_env() {
        Ok(ctx) => Some(ctx),
        Err(e) => {
            eprintln!("methods bench: GPU rows skipped: {e}");
            None
        }
    };
    let mut backends = vec![Backend::Cpu(Precision::F32), Backend::Cpu(Precision::F64)];
    if let Some(ctx) = &gpu {
        backends.push(Backend::Gpu(ctx));
    }
    let methods = methods();
    let media: Vec<(usize, Medium<f64>)> = sizes
        .iter()
        .map(|&n| match scenes::vacuum_cloud::<f64>(n, SEED) {
            Ok(m) => (n, m),
            Err(e) => fail("methods", &format!("vacuum cloud {n}³: {e}")),
        })
        .collect();

    let mut c = Criterion::default().configure_from_args();
    for b in &backends {
        for m in &methods {
            if !m.capabilities().supports(b) {
                continue;
            }
            let mut group = c.benchmark_group(format!("step/{b}/{}", m.name()));
            group
                .sample_size(10)
                .measurement_time(Duration::from_secs(3));
            for (n, medium) in &media {
                group.throughput(Throughput::Elements((n * n * n) as u64));
                group.bench_with_input(BenchmarkId::from_parameter(n), medium, |bch, medium| {
                    bch.iter_custom(|iters| {
                        Duration::from_secs_f64(
                            steps_seconds(m.as_ref(), b, medium, iters.max(1) as usize).0,
                        )
                    })
                });
            }
            group.finish();
        }
    }
    c.final_summary();
    if !bench {
        return;
    }

    let cpu = benches::cli::cpu_model();
    let mut csv = format!("{CSV_HEADER}\n");
    println!("\nmethods bench summary ({SUMMARY_STEPS} steps, median of {SUMMARY_RUNS} solves)");
    for b in &backends {
        for m in &methods {
            if !m.capabilities().supports(b) {
                continue;
            }
            for (n, medium) in &media {
                let mut runs: Vec<(f64, String)> = (0..SUMMARY_RUNS)
                    .map(|_| steps_seconds(m.as_ref(), b, medium, SUMMARY_STEPS))
                    .collect();
                runs.sort_by(|a, b| a.0.total_cmp(&b.0));
                let (seconds, timer) = runs[runs.len() / 2].clone();
                let per_step = seconds / SUMMARY_STEPS as f64;
                let bytes = m.bytes_per_step(&medium.grid, b.precision());
                let effective = bytes as f64 / per_step / 1e9;
                let (probe, probe_gbs) = match b {
                    Backend::Cpu(_) => ("triad", triad_gbs(len_for_total_bytes(bytes, 3), 5)),
                    Backend::Gpu(ctx) => {
                        match bandwidth::copy_gbs(ctx, (bytes / 2) as u64, 10, 3) {
                            Ok(c) => ("gpu-copy", c.gbs),
                            Err(e) => fail("methods", &format!("GPU copy probe: {e}")),
                        }
                    }
                };
                let mvox = medium.grid.len() as f64 / per_step / 1e6;
                let adapter = b
                    .gpu()
                    .map_or("none".to_string(), |c| c.info().name.replace(',', " "));
                let line = format!(
                    "{n},{},{b},{timer},{:.4},{mvox:.2},{effective:.3},{probe},{probe_gbs:.3},{:.4},{cpu},{adapter}",
                    m.name(),
                    per_step * 1e3,
                    effective / probe_gbs
                );
                println!("{line}");
                let _ = writeln!(csv, "{line}");
            }
        }
    }
    match write_result(CSV_PATH, &csv) {
        Ok(p) => println!("wrote {}", p.display()),
        Err(e) => fail("methods", &format!("writing {CSV_PATH}: {e}")),
    }
}
