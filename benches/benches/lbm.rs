//! One lattice-Boltzmann step (D3Q19, isotropic, the paper's absorption) on the CPU (`f32`,
//! `f64`) and the GPU (wgpu, `f32`), with the bandwidth probes measured in the same run.
//!
//! * Criterion groups `lbm_step/<precision>` (CPU) and `lbm_step/gpu` with the lattice size n
//!   as parameter and `Throughput::Elements(n³)` (lattice updates per second). The medium is
//!   the LB Fig 5 cloud (`noise_cloud`, per-site σt = 0.25·density) lit by a directional
//!   light; each solver is warmed up for [`WARMUP`] steps.
//! * In benchmark mode (`--bench`), a summary per case: ms per step (median of
//!   [`SUMMARY_STEPS`] steps; GPU: median of batches of [`GPU_BATCH`] steps in one pass),
//!   million lattice updates per second (MLUPS), effective bytes/s counting 19 values read and
//!   19 written per site (`bytes_per_step`; the 2 medium values per site are not counted),
//!   and its ratio to the STREAM triad and copy (CPU, over the same footprint, best of runs
//!   before and after) or to the device copy probe (GPU). Printed and written to
//!   `results/bench/lbm.csv`.
//!
//! Sizes 64 and 128 by default; `SCATTERBENCH_BENCH_SIZES=64,128` overrides them; without
//! `--bench` (`cargo test --benches`) a 16³ smoke run. No GPU adapter: the GPU part is skipped.

use benches::bandwidth::{copy_gbs, len_for_total_bytes, triad_gbs};
use benches::median_seconds;
use criterion::{BenchmarkId, Criterion, SamplingMode, Throughput};
use solvers::gpu::{GpuContext, bandwidth};
use solvers::lbm::{CpuLbm, GpuLbm, Injection, LbmConfig, Resolve, SigmaMapping};
use solvers::scene::generators::{Generator, NoiseCloud};
use solvers::{Medium, Real};
use std::time::Duration;

const DEFAULT_SIZES: [usize; 2] = [64, 128];
const TEST_SIZES: [usize; 1] = [16];
const SIZES_ENV: &str = "SCATTERBENCH_BENCH_SIZES";
const WARMUP: usize = 5;
const SUMMARY_STEPS: usize = 7;
const GPU_BATCH: u32 = 10;
const PROBE_REPS: usize = 5;
const CSV_PATH: &str = "results/bench/lbm.csv";

fn fail(message: &str) -> ! {
    benches::cli::fail("lbm", message)
}

fn sizes(bench: bool) -> Vec<usize> {
    benches::cli::sizes(SIZES_ENV, bench, &DEFAULT_SIZES, &TEST_SIZES).unwrap_or_else(|e| fail(&e))
}

fn medium(n: usize) -> Medium<f64> {
    NoiseCloud {
        n,
        seed: 7,
        sigma_max: 0.25 * n as f64,
        albedo: 0.9,
        radius: 0.4,
        frequency: 4.0,
        octaves: 4,
    }
    .generate()
    .unwrap_or_else(|e| fail(&format!("building the {n}³ cloud: {e}")))
}

fn setup() -> (Injection, LbmConfig) {
    let inj = Injection::directional([0.0, 0.0, 1.0], 1.0, Resolve::FluxPreserving)
        .unwrap_or_else(|e| fail(&format!("injection: {e}")));
    let cfg = LbmConfig::default()
        .with_sigma_mapping(SigmaMapping::Linear)
        .fixed_steps(usize::MAX / 2);
    (inj, cfg)
}

#[derive(Debug)]
struct Row {
    backend: &'static str,
    device: String,
    n: usize,
    precision: &'static str,
    seconds: f64,
    bytes: usize,
    triad_gbs: f64,
    copy_gbs: f64,
    timer: String,
}

impl Row {
    fn mlups(&self) -> f64 {
        (self.n as f64).powi(3) / self.seconds / 1e6
    }
    fn gbs(&self) -> f64 {
        self.bytes as f64 / self.seconds / 1e9
    }
    fn csv(&self) -> String {
        format!(
            "{},{},{},{},{:.4},{:.2},{:.3},{:.3},{:.3},{:.4},{:.4},{}",
            self.backend,
            self.device.replace(',', ";"),
            self.n,
            self.precision,
            self.seconds * 1e3,
            self.mlups(),
            self.gbs(),
            self.triad_gbs,
            self.copy_gbs,
            self.gbs() / self.triad_gbs,
            self.gbs() / self.copy_gbs,
            self.timer
        )
    }
}

fn bench_cpu<T: Real>(c: &mut Criterion, sizes: &[usize], summary: bool, rows: &mut Vec<Row>) {
    let (inj, cfg) = setup();
    let mut group = c.benchmark_group(format!("lbm_step/{}", T::NAME));
    for &n in sizes {
        let mut lbm = CpuLbm::<T>::new(&medium(n), &inj, &cfg)
            .unwrap_or_else(|e| fail(&format!("{n}³: {e}")));
        for _ in 0..WARMUP {
            lbm.step();
        }
        group.throughput(Throughput::Elements((n * n * n) as u64));
        group.sampling_mode(if n >= 128 {
            SamplingMode::Flat
        } else {
            SamplingMode::Auto
        });
        group.bench_function(BenchmarkId::from_parameter(n), |b| b.iter(|| lbm.step()));
        if summary {
            let bytes = lbm.bytes_per_step();
            let probe = || {
                (
                    triad_gbs(len_for_total_bytes(bytes, 3), PROBE_REPS),
                    copy_gbs(len_for_total_bytes(bytes, 2), PROBE_REPS),
                )
            };
            let (t0, c0) = probe();
            let seconds = median_seconds(SUMMARY_STEPS, || lbm.step());
            let (t1, c1) = probe();
            println!(
                "summary: cpu {n}³ {}: {:.2} ms/step; triad {t0:.2}/{t1:.2}, copy {c0:.2}/{c1:.2} GB/s before/after",
                T::NAME,
                seconds * 1e3
            );
            rows.push(Row {
                backend: "cpu",
                device: format!(
                    "{} ({} threads)",
                    benches::cli::cpu_model(),
                    rayon::current_num_threads()
                ),
                n,
                precision: T::NAME,
                seconds,
                bytes,
                triad_gbs: t0.max(t1),
                copy_gbs: c0.max(c1),
                timer: "wall-clock".into(),
            });
        }
    }
    group.finish();
}

fn bench_gpu(c: &mut Criterion, sizes: &[usize], summary: bool, rows: &mut Vec<Row>) {
    let ctx = match GpuContext::from_env() {
        Ok(ctx) => ctx,
        Err(e) => {
            eprintln!("lbm bench: GPU part skipped: no GPU adapter ({e})");
            return;
        }
    };
    eprintln!("lbm bench GPU on {}", ctx.describe());
    let (inj, cfg) = setup();
    let mut group = c.benchmark_group("lbm_step/gpu");
    group.sampling_mode(SamplingMode::Flat);
    group.sample_size(10);
    for &n in sizes {
        let mut lbm = match GpuLbm::new(&ctx, &medium(n), &inj, &cfg) {
            Ok(l) => l,
            Err(e) => {
                eprintln!("gpu {n}³: skipped: {e}");
                continue;
            }
        };
        if let Err(e) = lbm.time_steps(WARMUP as u32) {
            fail(&format!("gpu {n}³: {e}"));
        }
        group.throughput(Throughput::Elements((n * n * n) as u64));
        group.bench_function(BenchmarkId::from_parameter(n), |b| {
            b.iter_custom(|iters| {
                let k = u32::try_from(iters).unwrap_or(u32::MAX).max(1);
                match lbm.time_steps(k) {
                    Ok(s) => Duration::from_secs_f64(s),
                    Err(e) => fail(&format!("gpu {n}³: {e}")),
                }
            })
        });
        if summary {
            let bytes = lbm.bytes_per_step();
            let probe = |ctx: &GpuContext| match bandwidth::copy_gbs(ctx, bytes as u64 / 2, 10, 3) {
                Ok(b) => b.gbs,
                Err(e) => fail(&format!("copy probe: {e}")),
            };
            let before = probe(&ctx);
            let mut times: Vec<f64> = (0..SUMMARY_STEPS)
                .map(|_| match lbm.time_steps(GPU_BATCH) {
                    Ok(s) => s / f64::from(GPU_BATCH),
                    Err(e) => fail(&format!("gpu {n}³: {e}")),
                })
                .collect();
            times.sort_by(f64::total_cmp);
            let after = probe(&ctx);
            let seconds = times[times.len() / 2];
            println!(
                "summary: gpu {n}³: {:.2} ms/step; copy {before:.2}/{after:.2} GB/s before/after",
                seconds * 1e3
            );
            rows.push(Row {
                backend: "gpu",
                device: ctx.describe(),
                n,
                precision: "f32",
                seconds,
                bytes,
                triad_gbs: f64::NAN,
                copy_gbs: before.max(after),
                timer: ctx.timer().to_string(),
            });
        }
    }
    group.finish();
}

fn main() {
    let bench = benches::cli::benchmark_mode();
    let sizes = sizes(bench);
    let mut c = Criterion::default()
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(3))
        .configure_from_args();
    let mut rows = Vec::new();
    bench_cpu::<f32>(&mut c, &sizes, bench, &mut rows);
    bench_cpu::<f64>(&mut c, &sizes, bench, &mut rows);
    bench_gpu(&mut c, &sizes, bench, &mut rows);
    c.final_summary();
    if !bench || rows.is_empty() {
        return;
    }
    let header = "backend,device,n,precision,ms_per_step,mlups,effective_gbs,triad_gbs,copy_gbs,ratio_triad,ratio_copy,timer";
    let lines: Vec<String> = rows.iter().map(Row::csv).collect();
    let note = "effective bytes: 19 values read + 19 written per site per step; triad counts 3 and copy 2 arrays; GB = 1e9 bytes";
    benches::cli::emit_table(CSV_PATH, header, &lines, note);
}
