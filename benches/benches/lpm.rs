//! LPM on the CPU (`solvers::lpm`, rayon propagate/collect) at the paper's benchmark setting:
//! m = 5 (150 directions, 25 per face), 3 orders (Alg 2's fixed count), isotropic, D_U = 6,
//! D_I = 1, RGB in f32 as three channel solves (issue 16 acceptance 3; the paper's 64³ took
//! 47 s for Fattal's sequential CPU code and 417 ms on its GPU).
//!
//! * Criterion group `lpm_rgb/<precision>` with the grid size n as parameter: one iteration
//!   is the three channel solves (orders only: the per-channel setup, directions, F and the
//!   geometry tables, is built once outside and reported in the summary).
//! * The medium: a noise cloud, σt·h ∈ [0, 2) per channel scaled by 1, 0.8, 0.6, albedo 0.9,
//!   under a uniform environment of radiance 1 plus a directional light (the LPM boundary
//!   source).
//! * In benchmark mode (`--bench`), a summary per case: seconds per RGB solve (median of
//!   [`SUMMARY_RUNS`]), measured sub-segments per second per channel
//!   ([`CpuLpm::sub_segments_per_order`]), the effective bytes/s (`LpmMethod::bytes_per_step`
//!   per order) and its ratio to the STREAM triad over the same footprint, best of probes
//!   before and after; printed and written to `results/bench/lpm.csv`. Beside the wall time
//!   the mean CPU seconds per RGB solve over the summary runs (all threads, Linux:
//!   `/proc/self/task/*/schedstat`; empty elsewhere): on a shared machine wall time
//!   includes other processes' time slices, CPU seconds do not.
//!
//! * Criterion group `lpm_rgb/gpu` (when an adapter exists): the same three channel solves
//!   with [`GpuLpm`] (buffers and tables built once per channel outside; one iteration
//!   includes the init copies and the final readback of I, U and φ); in benchmark mode a
//!   summary line with the kernels' own seconds (GPU timestamps where the device has them).
//!   Not in the CSV.
//!
//! Sizes 64 and 128 by default; `SCATTERBENCH_BENCH_SIZES` overrides them; without `--bench`
//! (`cargo test --benches`) a 12³ smoke run.

use benches::bandwidth::{len_for_total_bytes, triad_gbs};
use benches::median_seconds;
use criterion::{BenchmarkId, Criterion, SamplingMode, Throughput};
use solvers::gpu::GpuContext;
use solvers::lpm::{BoundaryLight, CpuLpm, GpuLpm, LpmConfig, LpmMethod};
use solvers::method::Method;
use solvers::noise::Perlin;
use solvers::{Grid, Medium, Precision, Real};
use std::time::Duration;

const DEFAULT_SIZES: [usize; 2] = [64, 128];
const TEST_SIZES: [usize; 1] = [12];
const SIZES_ENV: &str = "SCATTERBENCH_BENCH_SIZES";
const SUMMARY_RUNS: usize = 3;
const PROBE_REPS: usize = 5;
const CHANNEL_SCALE: [f64; 3] = [1.0, 0.8, 0.6];
const CSV_PATH: &str = "results/bench/lpm.csv";

fn fail(message: &str) -> ! {
    benches::cli::fail("lpm", message)
}

fn medium<T: Real>(n: usize, scale: f64) -> Medium<T> {
    let grid = Grid::cube(n, 1.0).unwrap_or_else(|e| fail(&format!("{n}³ grid: {e}")));
    let noise = Perlin::new(7);
    let h = grid.dl;
    let sigma_t = grid.sample(|p| {
        let d = noise.fbm([4.0 * p[0], 4.0 * p[1], 4.0 * p[2]], 4);
        T::c(scale * 2.0 / h * (0.5 + d).clamp(0.0, 0.999))
    });
    let len = grid.len();
    Medium::new(grid, sigma_t, vec![T::c(0.9); len], vec![T::zero(); len])
        .unwrap_or_else(|e| fail(&format!("{n}³ medium: {e}")))
}

struct Row {
    n: usize,
    precision: &'static str,
    setup_seconds: f64,
    seconds: f64,
    cpu_seconds: Option<f64>,
    segments: u64,
    bytes: usize,
    triad_gbs: f64,
}

fn bench_cpu<T: Real>(c: &mut Criterion, sizes: &[usize], summary: bool, rows: &mut Vec<Row>) {
    let cfg = LpmConfig {
        keep_orders: false,
        ..LpmConfig::default()
    };
    let mut group = c.benchmark_group(format!("lpm_rgb/{}", T::NAME));
    group.sampling_mode(SamplingMode::Flat);
    group.sample_size(10);
    for &n in sizes {
        let t0 = std::time::Instant::now();
        let solvers: Vec<CpuLpm<T>> = CHANNEL_SCALE
            .iter()
            .map(|&s| {
                CpuLpm::new(&medium::<T>(n, s), &cfg)
                    .unwrap_or_else(|e| fail(&format!("{n}³: {e}")))
            })
            .collect();
        let setup_seconds = t0.elapsed().as_secs_f64();
        let dirs = &solvers[0].dirs;
        let mut light = BoundaryLight::directional(dirs, [0.3, -0.4, -0.87], 5.0)
            .unwrap_or_else(|e| fail(&e.to_string()));
        for l in &mut light.radiance {
            *l += 1.0;
        }
        let rgb = || {
            for s in &solvers {
                if let Err(e) = s.solve(&light, |_, _| {}) {
                    fail(&format!("{n}³: {e}"));
                }
            }
        };
        group.throughput(Throughput::Elements((3 * n * n * n) as u64));
        group.bench_function(BenchmarkId::from_parameter(n), |b| b.iter(rgb));
        if summary {
            let orders = cfg.max_orders();
            let method = LpmMethod::default();
            let precision = if T::NAME == "f32" {
                Precision::F32
            } else {
                Precision::F64
            };
            let bytes = 3 * orders * method.bytes_per_step(&solvers[0].grid, precision);
            let footprint = solvers[0].memory_estimate() as usize;
            let probe = || triad_gbs(len_for_total_bytes(footprint, 3), PROBE_REPS);
            let p0 = probe();
            let c0 = cpu_seconds();
            let seconds = median_seconds(SUMMARY_RUNS, rgb);
            let cpu = match (c0, cpu_seconds()) {
                (Some(a), Some(b)) => Some((b - a) / SUMMARY_RUNS as f64),
                _ => None,
            };
            let p1 = probe();
            let segments = solvers[0].sub_segments_per_order() * orders as u64;
            let cpu_text = cpu.map_or("n/a".to_string(), |c| format!("{c:.3}"));
            println!(
                "summary: cpu {n}³ {} RGB, 3 orders: {seconds:.3} s, {cpu_text} CPU-s (setup {setup_seconds:.3} s), {:.1} Mseg/s per channel, triad {p0:.2}/{p1:.2} GB/s",
                T::NAME,
                3.0 * segments as f64 / seconds / 1e6
            );
            rows.push(Row {
                n,
                precision: T::NAME,
                setup_seconds,
                seconds,
                cpu_seconds: cpu,
                segments,
                bytes,
                triad_gbs: p0.max(p1),
            });
        }
    }
    group.finish();
}

fn bench_gpu(c: &mut Criterion, sizes: &[usize], summary: bool) {
    let ctx = match GpuContext::from_env() {
        Ok(ctx) => ctx,
        Err(e) => {
            eprintln!("lpm bench: GPU part skipped: no GPU adapter ({e})");
            return;
        }
    };
    eprintln!("lpm bench GPU on {}", ctx.describe());
    let cfg = LpmConfig {
        keep_orders: false,
        ..LpmConfig::default()
    };
    let mut group = c.benchmark_group("lpm_rgb/gpu");
    group.sampling_mode(SamplingMode::Flat);
    group.sample_size(10);
    for &n in sizes {
        let built: Result<Vec<GpuLpm<'_>>, _> = CHANNEL_SCALE
            .iter()
            .map(|&s| GpuLpm::new(&ctx, &medium::<f64>(n, s), &cfg))
            .collect();
        let mut solvers = match built {
            Ok(s) => s,
            Err(e) => {
                eprintln!("gpu {n}³: skipped: {e}");
                continue;
            }
        };
        let mut light = BoundaryLight::directional(&solvers[0].setup.dirs, [0.3, -0.4, -0.87], 5.0)
            .unwrap_or_else(|e| fail(&e.to_string()));
        for l in &mut light.radiance {
            *l += 1.0;
        }
        let mut rgb = || -> f64 {
            let mut kernel_seconds = 0.0;
            for s in &mut solvers {
                match s.solve(&light, |_, _| {}) {
                    Ok(sol) => kernel_seconds += sol.seconds,
                    Err(e) => fail(&format!("gpu {n}³: {e}")),
                }
            }
            kernel_seconds
        };
        group.throughput(Throughput::Elements((3 * n * n * n) as u64));
        group.bench_function(BenchmarkId::from_parameter(n), |b| b.iter(&mut rgb));
        if summary {
            let mut runs: Vec<f64> = (0..SUMMARY_RUNS).map(|_| rgb()).collect();
            runs.sort_by(f64::total_cmp);
            println!(
                "summary: gpu {n}³ f32 RGB, 3 orders: {:.2} ms kernel time per RGB solve (median of {SUMMARY_RUNS}, {})",
                runs[runs.len() / 2] * 1e3,
                ctx.timer()
            );
        }
    }
    group.finish();
}

/// CPU seconds the threads of this process have run so far: Σ over /proc/self/task of the
/// first field of `schedstat` (nanoseconds on the CPU); `None` where that is not readable
/// (not Linux). Rayon's workers live as long as the process, so a difference of two calls
/// counts the work in between.
fn cpu_seconds() -> Option<f64> {
    let mut ns: u64 = 0;
    for task in std::fs::read_dir("/proc/self/task").ok()? {
        let text = std::fs::read_to_string(task.ok()?.path().join("schedstat")).ok()?;
        ns += text.split_whitespace().next()?.parse::<u64>().ok()?;
    }
    Some(ns as f64 * 1e-9)
}

fn main() {
    let bench = benches::cli::benchmark_mode();
    let sizes = benches::cli::sizes(SIZES_ENV, bench, &DEFAULT_SIZES, &TEST_SIZES)
        .unwrap_or_else(|e| fail(&e));
    let mut c = Criterion::default()
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(5))
        .configure_from_args();
    let mut rows = Vec::new();
    bench_cpu::<f32>(&mut c, &sizes, bench, &mut rows);
    bench_gpu(&mut c, &sizes, bench);
    c.final_summary();
    if !bench || rows.is_empty() {
        return;
    }
    let header = "n,precision,threads,cpu,orders,m,setup_s,rgb_solve_s,rgb_solve_cpu_s,subsegments_per_order_channel,mseg_per_s,effective_gbs,triad_gbs,ratio_triad";
    let mut lines = Vec::new();
    for r in &rows {
        let gbs = r.bytes as f64 / r.seconds / 1e9;
        let line = format!(
            "{},{},{},{},3,5,{:.4},{:.4},{},{},{:.2},{:.3},{:.3},{:.4}",
            r.n,
            r.precision,
            rayon::current_num_threads(),
            benches::cli::cpu_model(),
            r.setup_seconds,
            r.seconds,
            r.cpu_seconds.map_or(String::new(), |c| format!("{c:.4}")),
            r.segments / 3, // per order (3 orders), per channel
            3.0 * r.segments as f64 / r.seconds / 1e6,
            gbs,
            r.triad_gbs,
            gbs / r.triad_gbs
        );
        lines.push(line);
    }
    let note = "targets (issue 16 acceptance 3): 64^3 RGB f32 3 orders <= 1.0 s on 2 cores, 128^3 <= 8 s; mseg_per_s counts sub-segments of all three channels";
    benches::cli::emit_table(CSV_PATH, header, &lines, note);
}
