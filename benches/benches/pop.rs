//! Principal-ordinates propagation (`solvers::pop`) at the paper's Fig 14 setting: 64
//! environment ordinates × 20³ cells × 10 iterations, RGB (three channels), on the CPU
//! (`f32`, `f64`), with the bandwidth probes measured in the same run (issue 17,
//! acceptance 3: CPU on 2 cores ≤ 0.5 s propagation, ≥ 10⁷ cell-updates/s).
//!
//! * Criterion groups `pop_fig14/<precision>`: the propagation of all 64 ordinates (entry
//!   slice injection plus 10 iterations each, rayon over ordinates and slices), on grids
//!   built and resampled beforehand; and `pop_fig14_solve/<precision>`: the whole
//!   [`solvers::pop::solve`] (grids, MIP resampling and links included).
//! * The medium: a 40³ smoky ball (σs per channel {2.9, 3.6, 4.2}·(0.6 + 0.4 sin …), albedo
//!   0.95, g = 0.9, the Fig 11/14 smoke's magnitudes), a constant environment decomposed into
//!   64 Fibonacci ordinates with the Voronoi prefilter.
//! * In benchmark mode (`--bench`), a summary per precision: seconds for the propagation
//!   (median of [`SUMMARY_RUNS`]), RGB cell-updates/s, effective bytes/s counting the arrays
//!   each update reads and writes once ([`BYTES_PER_UPDATE_VALUES`] values per channel), and
//!   its ratio to the STREAM triad and copy over the same footprint (best before and after).
//!   Printed and written to `results/bench/pop.csv`.
//!
//! * `pop_fig14/gpu` (when a GPU adapter exists): the same propagation on
//!   [`solvers::pop::GpuPop`], the grids prepared and injected on the host beforehand and
//!   each loaded (uploaded) before its timed steps; the time is the sum of the 64 ordinates'
//!   step passes (GPU timestamps when the device has them). Its summary row has no CPU
//!   bandwidth probes (NaN) and the wall-clock `pop::gpu::solve` as `solve_ms`.
//!
//! Without `--bench` (`cargo test --benches`) a smoke run at 8³ × 8 ordinates × 2 iterations.

use benches::bandwidth::{copy_gbs, len_for_total_bytes, stream_rule_len, triad_gbs};
use benches::median_seconds;
use criterion::{Criterion, Throughput};
use rayon::prelude::*;
use solvers::gpu::GpuContext;
use solvers::pop::{
    self, CpuPop, GpuPop, Ordinate, PopConfig, PopMedium, Prefilter, PropagationGrid,
};
use solvers::{Grid, Real};
use std::time::Duration;

const SUMMARY_RUNS: usize = 7;
const PROBE_REPS: usize = 5;
const CSV_PATH: &str = "results/bench/pop.csv";
/// Values per cell and channel one update touches once: state read (L, a) and written (2+2),
/// fractions written and read (3+3), links read (7), accumulators read and written (2·3).
const BYTES_PER_UPDATE_VALUES: usize = 23;

fn fail(message: &str) -> ! {
    benches::cli::fail("pop", message)
}

struct Setting {
    medium_n: usize,
    n: usize,
    ordinates: usize,
    iterations: usize,
}

fn medium(s: &Setting) -> PopMedium {
    let grid = Grid::cube(s.medium_n, 1.0).unwrap_or_else(|e| fail(&format!("grid: {e}")));
    let base = grid.sample(|p| {
        let r2 = (p[0] - 0.5).powi(2) + (p[1] - 0.5).powi(2) + (p[2] - 0.5).powi(2);
        if r2 > 0.2 {
            0.0
        } else {
            0.6 + 0.4 * (11.0 * p[0] + 7.0 * p[1] * p[2]).sin()
        }
    });
    let mut sigma_s = Vec::new();
    let mut sigma_a = Vec::new();
    for scale in [2.9, 3.6, 4.2] {
        sigma_s.push(base.iter().map(|b| scale * b * 0.95).collect());
        sigma_a.push(base.iter().map(|b| scale * b * 0.05).collect());
    }
    let m = PopMedium {
        grid,
        sigma_s,
        sigma_a,
        g: vec![0.9; 3],
    };
    m.validate()
        .unwrap_or_else(|e| fail(&format!("medium: {e}")));
    m
}

fn ordinates(s: &Setting) -> Vec<Ordinate> {
    pop::environment_ordinates(|_| 1.0, s.ordinates, Prefilter::Voronoi, 128)
        .unwrap_or_else(|e| fail(&format!("ordinates: {e}")))
}

/// The prepared grids of every ordinate (built and resampled once).
fn prepared<T: Real>(m: &PopMedium, ords: &[Ordinate], cfg: &PopConfig) -> Vec<CpuPop<T>> {
    ords.par_iter()
        .map(|o| {
            let grid = PropagationGrid::over(&m.grid, o.direction, cfg.n);
            let mip = pop::grid::box_filter(m, pop::grid::mip_level(&m.grid, grid.dx));
            CpuPop::new(grid, &mip, &m.g, cfg)
        })
        .collect()
}

/// Injection plus `iterations` steps of every prepared grid (fresh copies).
fn propagate<T: Real>(grids: &[CpuPop<T>], ords: &[Ordinate], cfg: &PopConfig) -> f64 {
    grids
        .par_iter()
        .zip(ords)
        .map(|(g, o)| {
            let mut p = g.clone();
            p.inject(o, cfg.init);
            p.run(0.0, cfg.max_iterations);
            p.ledger()[0].in_flight
        })
        .sum()
}

fn bench<T: Real>(c: &mut Criterion, s: &Setting, summary: bool, rows: &mut Vec<String>) {
    let m = medium(s);
    let ords = ordinates(s);
    let cfg = PopConfig::fixed::<T>(s.n, s.iterations);
    let grids = prepared::<T>(&m, &ords, &cfg);
    let updates = (s.ordinates * s.n.pow(3) * s.iterations) as u64;
    let mut group = c.benchmark_group(format!("pop_fig14/{}", T::NAME));
    group.throughput(Throughput::Elements(updates));
    group.bench_function("propagation", |b| b.iter(|| propagate(&grids, &ords, &cfg)));
    group.finish();
    let mut group = c.benchmark_group(format!("pop_fig14_solve/{}", T::NAME));
    group.throughput(Throughput::Elements(updates));
    group.bench_function("solve", |b| {
        b.iter(|| pop::solve::<T>(&m, &ords, &cfg).unwrap_or_else(|e| fail(&e.to_string())))
    });
    group.finish();
    if !summary {
        return;
    }
    let bytes_per_step =
        s.ordinates * s.n.pow(3) * 3 * BYTES_PER_UPDATE_VALUES * std::mem::size_of::<T>();
    let footprint = bytes_per_step / 2;
    let probe = || {
        (
            triad_gbs(len_for_total_bytes(footprint, 3), PROBE_REPS),
            copy_gbs(len_for_total_bytes(footprint, 2), PROBE_REPS),
        )
    };
    let (t0, c0) = probe();
    // The state of 64 grids of 20³ is cache-sized; the STREAM-rule triad (arrays ≥ 4× the
    // largest cache) is the main-memory figure.
    let stream = triad_gbs(stream_rule_len(), PROBE_REPS);
    let seconds = median_seconds(SUMMARY_RUNS, || propagate(&grids, &ords, &cfg));
    let solve_seconds =
        median_seconds(3, || pop::solve::<T>(&m, &ords, &cfg).map(|s| s.runs.len()));
    let (t1, c1) = probe();
    let rate = updates as f64 / seconds;
    let gbs = bytes_per_step as f64 * s.iterations as f64 / seconds / 1e9;
    let (triad, copy) = (t0.max(t1), c0.max(c1));
    println!(
        "summary: pop {} {}x{}^3x{}: propagation {:.1} ms ({:.3e} RGB cell-updates/s), solve {:.1} ms; {:.2} GB/s = {:.3} of triad {:.2}, {:.3} of copy {:.2}, {:.3} of STREAM-rule triad {:.2} GB/s",
        T::NAME,
        s.ordinates,
        s.n,
        s.iterations,
        seconds * 1e3,
        rate,
        solve_seconds * 1e3,
        gbs,
        gbs / triad,
        triad,
        gbs / copy,
        copy,
        gbs / stream,
        stream
    );
    rows.push(format!(
        "cpu,{},{},{},{},{},{:.4},{:.4},{:.4e},{:.3},{:.3},{:.3},{:.3},{:.4},{:.4},{:.4}",
        rayon::current_num_threads(),
        T::NAME,
        s.ordinates,
        s.n,
        s.iterations,
        seconds * 1e3,
        solve_seconds * 1e3,
        rate,
        gbs,
        triad,
        copy,
        stream,
        gbs / triad,
        gbs / copy,
        gbs / stream
    ));
}

/// Seconds of `iterations` GPU steps of every ordinate (each loaded first, untimed).
fn propagate_gpu(
    gpu: &mut GpuPop<'_>,
    grids: &[CpuPop<f32>],
    ords: &[Ordinate],
    cfg: &PopConfig,
) -> f64 {
    let mut seconds = 0.0;
    for (g, o) in grids.iter().zip(ords) {
        let mut p = g.clone();
        p.inject(o, cfg.init);
        let steps = u32::try_from(cfg.max_iterations).unwrap_or(u32::MAX);
        seconds += gpu
            .load(&p)
            .and_then(|()| gpu.time_steps(steps))
            .unwrap_or_else(|e| fail(&format!("gpu: {e}")));
    }
    seconds
}

fn bench_gpu(c: &mut Criterion, s: &Setting, summary: bool, rows: &mut Vec<String>) {
    let ctx = match GpuContext::from_env() {
        Ok(ctx) => ctx,
        Err(e) => {
            eprintln!("pop bench: GPU part skipped: no GPU adapter ({e})");
            return;
        }
    };
    eprintln!("pop bench GPU on {}", ctx.describe());
    let m = medium(s);
    let ords = ordinates(s);
    let cfg = PopConfig::fixed::<f32>(s.n, s.iterations);
    let grids = prepared::<f32>(&m, &ords, &cfg);
    let mut gpu = GpuPop::new(&ctx, s.n, m.channels(), cfg.lateral, false)
        .unwrap_or_else(|e| fail(&format!("gpu: {e}")));
    let updates = (s.ordinates * s.n.pow(3) * s.iterations) as u64;
    let mut group = c.benchmark_group("pop_fig14/gpu");
    group.throughput(Throughput::Elements(updates));
    group.bench_function("propagation", |b| {
        b.iter_custom(|iters| {
            let total: f64 = (0..iters)
                .map(|_| propagate_gpu(&mut gpu, &grids, &ords, &cfg))
                .sum();
            Duration::from_secs_f64(total)
        })
    });
    group.finish();
    if !summary {
        return;
    }
    let mut times: Vec<f64> = (0..SUMMARY_RUNS)
        .map(|_| propagate_gpu(&mut gpu, &grids, &ords, &cfg))
        .collect();
    times.sort_by(f64::total_cmp);
    let seconds = times[times.len() / 2];
    let solve_seconds = median_seconds(3, || {
        pop::gpu::solve(&ctx, &m, &ords, &cfg).map(|s| s.runs.len())
    });
    let bytes_per_step = s.ordinates * s.n.pow(3) * 3 * BYTES_PER_UPDATE_VALUES * 4;
    let rate = updates as f64 / seconds;
    let gbs = bytes_per_step as f64 * s.iterations as f64 / seconds / 1e9;
    println!(
        "summary: pop gpu f32 {}x{}^3x{} on {}: propagation {:.3} ms ({:.3e} RGB cell-updates/s, {} timer), solve {:.1} ms; {:.2} GB/s effective",
        s.ordinates,
        s.n,
        s.iterations,
        ctx.describe(),
        seconds * 1e3,
        rate,
        ctx.timer(),
        solve_seconds * 1e3,
        gbs
    );
    rows.push(format!(
        "gpu,0,f32,{},{},{},{:.4},{:.4},{:.4e},{:.3},NaN,NaN,NaN,NaN,NaN,NaN",
        s.ordinates,
        s.n,
        s.iterations,
        seconds * 1e3,
        solve_seconds * 1e3,
        rate,
        gbs
    ));
}

fn main() {
    let bench_mode = benches::cli::benchmark_mode();
    let s = if bench_mode {
        Setting {
            medium_n: 40,
            n: 20,
            ordinates: 64,
            iterations: 10,
        }
    } else {
        Setting {
            medium_n: 12,
            n: 8,
            ordinates: 8,
            iterations: 2,
        }
    };
    let mut c = Criterion::default()
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(3))
        .configure_from_args();
    let mut rows = Vec::new();
    bench::<f32>(&mut c, &s, bench_mode, &mut rows);
    bench::<f64>(&mut c, &s, bench_mode, &mut rows);
    bench_gpu(&mut c, &s, bench_mode, &mut rows);
    c.final_summary();
    if !bench_mode || rows.is_empty() {
        return;
    }
    let header = "backend,threads,precision,ordinates,n,iterations,propagation_ms,solve_ms,cell_updates_per_s,effective_gbs,triad_gbs,copy_gbs,stream_triad_gbs,ratio_triad,ratio_copy,ratio_stream_triad";
    let note = format!(
        "effective bytes: {BYTES_PER_UPDATE_VALUES} values per cell and channel per update, RGB; target (issue 17): propagation <= 500 ms on 2 cores (>= 1e7 updates/s)"
    );
    benches::cli::emit_table(CSV_PATH, header, &rows, &note);
}
