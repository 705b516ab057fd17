//! One red-black iteration of the GPU diffusion solver (wgpu, f32; CDA and FLD with the
//! Levermore–Pomraning limiter) on the FLD Fig 4 vacuum cloud, with a device copy-bandwidth
//! probe run in the same process.
//!
//! * Criterion groups `gpu_iteration/<method>` with the grid size n as parameter; each sample
//!   times a batch of iterations recorded into one compute pass, measured by GPU timestamp
//!   queries when the adapter has them (else the wall clock around submit and wait).
//! * In benchmark mode (`--bench`), a summary per case: milliseconds per iteration (median
//!   of [`SUMMARY_BATCHES`] batches of [`BATCH`] iterations), effective bytes/s
//!   (`bytes_per_iteration / seconds`, 9 f32 values per voxel for FLD and 7 for CDA), the
//!   copy bandwidth of the same device measured right before and after (best kept), and
//!   their ratio. Printed and written to `results/bench/diffusion_gpu.csv` with the adapter.
//!
//! Sizes: 64, 128, 256, and 512 on a discrete/integrated GPU (not on CPU adapters such as
//! lavapipe, where one 512³ iteration takes seconds) by default;
//! `SCATTERBENCH_BENCH_SIZES=64,128` overrides them. No adapter: one "skipped" line, exit 0.

use criterion::{BenchmarkId, Criterion, SamplingMode, Throughput};
use solvers::fld::{Boundary, FldConfig, FluxLimiter, GpuFld};
use solvers::gpu::{GpuContext, bandwidth};
use solvers::scenes;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Duration;

const DEFAULT_SIZES: [usize; 4] = [64, 128, 256, 512];
const TEST_SIZES: [usize; 1] = [16];
const SIZES_ENV: &str = "SCATTERBENCH_BENCH_SIZES";
const SEED: u64 = 1;
/// Iterations per timed batch.
const BATCH: u32 = 20;
/// Batches whose median the summary reports.
const SUMMARY_BATCHES: usize = 7;
const CSV_PATH: &str = "results/bench/diffusion_gpu.csv";

fn fail(message: &str) -> ! {
    benches::cli::fail("diffusion_gpu", message)
}

/// The size list; on a CPU adapter (lavapipe) the defaults stop at 256³.
fn sizes(bench: bool, cpu_adapter: bool) -> Vec<usize> {
    let defaults: Vec<usize> = DEFAULT_SIZES
        .into_iter()
        .filter(|&n| !(cpu_adapter && n > 256))
        .collect();
    benches::cli::sizes(SIZES_ENV, bench, &defaults, &TEST_SIZES).unwrap_or_else(|e| fail(&e))
}

fn config(method: &str) -> FldConfig {
    let cfg = if method == "CDA" {
        FldConfig::cda()
    } else {
        FldConfig::fld(FluxLimiter::LevermorePomraning)
    };
    // Tolerance 0: the GPU never raises `done`, every timed iteration does the full work.
    cfg.with_tolerance(0.0).with_max_iterations(usize::MAX / 2)
}

struct Row {
    n: usize,
    method: &'static str,
    ms_per_iter: f64,
    effective_gbs: f64,
    copy_gbs: f64,
    timer: String,
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let bench = benches::cli::benchmark_mode();
    let ctx = match GpuContext::from_env() {
        Ok(ctx) => ctx,
        Err(e) => {
            eprintln!("diffusion_gpu bench: skipped: no GPU adapter ({e})");
            return;
        }
    };
    eprintln!("diffusion_gpu bench on {}", ctx.describe());
    let mut c = Criterion::default()
        .configure_from_args()
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(3));
    let mut rows = Vec::new();
    let cpu_adapter = ctx.info().device_type == solvers::gpu::wgpu::DeviceType::Cpu;
    for n in sizes(bench, cpu_adapter) {
        let medium = match scenes::vacuum_cloud::<f32>(n, SEED) {
            Ok(m) => m,
            Err(e) => fail(&format!("building the {n}³ cloud: {e}")),
        };
        for method in ["CDA", "FLD-LP"] {
            let mut solver = match GpuFld::new(&ctx, &medium, &Boundary::Zero, &config(method)) {
                Ok(s) => s,
                Err(e) => {
                    eprintln!("{method} {n}³: skipped: {e}");
                    continue;
                }
            };
            // Warm-up: the first iterations start from tiny values.
            if let Err(e) = solver.time_iterations(BATCH) {
                fail(&format!("{method} {n}³: {e}"));
            }
            let mut group = c.benchmark_group(format!("gpu_iteration/{method}"));
            group.throughput(Throughput::Elements((n * n * n) as u64));
            group.sampling_mode(SamplingMode::Flat);
            group.sample_size(10);
            group.bench_function(BenchmarkId::from_parameter(n), |b| {
                b.iter_custom(|iters| {
                    let k = u32::try_from(iters).unwrap_or(u32::MAX).max(1);
                    match solver.time_iterations(k) {
                        Ok(s) => Duration::from_secs_f64(s),
                        Err(e) => fail(&format!("{method} {n}³: {e}")),
                    }
                })
            });
            group.finish();
            if !bench {
                continue;
            }
            let bytes = solver.bytes_per_iteration() as u64;
            let probe = |ctx: &GpuContext| match bandwidth::copy_gbs(ctx, bytes / 2, 10, 3) {
                Ok(b) => b.gbs,
                Err(e) => fail(&format!("copy probe: {e}")),
            };
            let before = probe(&ctx);
            let times: Vec<f64> = (0..SUMMARY_BATCHES)
                .map(|_| match solver.time_iterations(BATCH) {
                    Ok(s) => s / f64::from(BATCH),
                    Err(e) => fail(&format!("{method} {n}³: {e}")),
                })
                .collect();
            let after = probe(&ctx);
            let t = median(times);
            rows.push(Row {
                n,
                method,
                ms_per_iter: t * 1e3,
                effective_gbs: bytes as f64 / t / 1e9,
                copy_gbs: before.max(after),
                timer: solver.timer().to_string(),
            });
        }
    }
    c.final_summary();
    if !bench || rows.is_empty() {
        return;
    }
    let adapter = ctx.describe().replace(',', ";");
    let mut text = String::from(
        "adapter,n,method,ms_per_iter,mvox_per_s,effective_gbs,copy_gbs,ratio_copy,timer\n",
    );
    println!(
        "\n{:>5} {:>7} {:>11} {:>10} {:>10} {:>9} {:>7}",
        "n", "method", "ms/iter", "Mvox/s", "eff GB/s", "copy GB/s", "ratio"
    );
    for r in &rows {
        let mvox = (r.n * r.n * r.n) as f64 / (r.ms_per_iter * 1e-3) / 1e6;
        let ratio = r.effective_gbs / r.copy_gbs;
        println!(
            "{:>5} {:>7} {:>11.4} {:>10.1} {:>10.1} {:>9.1} {:>7.3}",
            r.n, r.method, r.ms_per_iter, mvox, r.effective_gbs, r.copy_gbs, ratio
        );
        let _ = writeln!(
            text,
            "{adapter},{},{},{:.6},{:.3},{:.3},{:.3},{:.4},{}",
            r.n, r.method, r.ms_per_iter, mvox, r.effective_gbs, r.copy_gbs, ratio, r.timer
        );
    }
    println!("adapter: {}", ctx.describe());
    let path = std::env::var("SCATTERBENCH_GPU_BENCH_CSV")
        .map(PathBuf::from)
        .unwrap_or_else(|_| {
            PathBuf::from(env!("CARGO_MANIFEST_DIR"))
                .parent()
                .map(|p| p.join(CSV_PATH))
                .unwrap_or_else(|| PathBuf::from(CSV_PATH))
        });
    if let Some(dir) = path.parent() {
        let _ = std::fs::create_dir_all(dir);
    }
    match std::fs::write(&path, text) {
        Ok(()) => println!("wrote {}", path.display()),
        Err(e) => fail(&format!("writing {}: {e}", path.display())),
    }
}
