//! Tests of the LPM GPU kernels (T7, T15, T16, T17, T18, T20 on the GPU; T24 is `tests/wgsl.rs` and
//! `tests/kernel_contract.rs`). Without an adapter each test prints one "skipped" line and
//! passes, unless `SCATTERBENCH_REQUIRE_GPU=1`. Sizes are for lavapipe (≤ 16³, m ≤ 5).
//! Numbers quoted in `mod.rs` are printed by these tests
//! (`cargo test --release -p solvers --lib lpm::gpu_tests -- --nocapture`).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::needless_range_loop)]

use super::directions::Directions;
use super::tests::random_medium;
use super::*;
use crate::gpu::GpuContext;
use crate::{Backend, Grid, Medium, Precision};
use std::f64::consts::PI;
use std::sync::{Mutex, OnceLock};

static GPU: OnceLock<Option<Mutex<GpuContext>>> = OnceLock::new();

/// Runs `body` on the shared test device (one test at a time), or prints that it skipped.
pub(super) fn with_gpu(test: &str, body: impl FnOnce(&GpuContext)) {
    let gpu = GPU.get_or_init(|| {
        GpuContext::for_tests()
            .unwrap_or_else(|e| panic!("SCATTERBENCH_REQUIRE_GPU is set: {e}"))
            .map(Mutex::new)
    });
    match gpu {
        None => crate::gpu::log_uncaptured(&format!("{test}: skipped: no GPU adapter")),
        Some(m) => {
            let ctx = m.lock().unwrap_or_else(|e| e.into_inner());
            crate::gpu::log_uncaptured(&format!("{test}: ran on {}", ctx.describe()));
            body(&ctx);
        }
    }
}

/// An environment of radiance 1 plus a directional light of irradiance 2.
pub(super) fn lights(m: usize) -> BoundaryLight {
    let dirs = Directions::new(m).unwrap();
    let mut b = BoundaryLight::uniform(&dirs, 1.0);
    let d = BoundaryLight::directional(&dirs, [0.3, -0.2, 0.9], 2.0).unwrap();
    for (x, y) in b.radiance.iter_mut().zip(&d.radiance) {
        *x += y;
    }
    b
}

/// (max |a − r|/r where r > 10⁻⁶ max r, relative RMSE √(Σ(a − r)²/Σr²)).
pub(super) fn diff(a: &[f64], r: &[f64]) -> (f64, f64) {
    let max = r.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let worst = a
        .iter()
        .zip(r)
        .filter(|(_, r)| r.abs() > 1e-6 * max)
        .fold(0.0f64, |m, (a, r)| m.max((a - r).abs() / r.abs()));
    let num: f64 = a.iter().zip(r).map(|(a, r)| (a - r).powi(2)).sum();
    let den: f64 = r.iter().map(|r| r * r).sum();
    (worst, if den > 0.0 { (num / den).sqrt() } else { 0.0 })
}

/// Every field of two solutions, `g` against the reference `c` (GPU vs CPU-f32 here, Alg 1
/// vs Alg 2 in `alg1::tests`): (max relative, relative RMSE) over I, U, φ and the per-order
/// fluences; the order counts and stops agree and the tallies agree to `tally_tol` of the
/// input.
pub(super) fn compare(
    what: &str,
    g: &LpmSolution<f64>,
    c: &LpmSolution<f64>,
    tally_tol: f64,
) -> (f64, f64) {
    assert_eq!(g.orders, c.orders, "{what}: orders");
    assert_eq!(g.stop, c.stop, "{what}: stop");
    assert_eq!(
        g.phi_orders.len(),
        c.phi_orders.len(),
        "{what}: kept orders"
    );
    assert_eq!(g.intensity.len(), c.intensity.len(), "{what}: I buffers");
    let mut fields: Vec<(&[f64], &[f64])> = vec![(&g.phi, &c.phi)];
    for (a, b) in g.intensity.iter().zip(&c.intensity) {
        fields.push((a, b));
    }
    for (a, b) in g.unshot.iter().zip(&c.unshot) {
        fields.push((a, b));
    }
    for (a, b) in g.phi_orders.iter().zip(&c.phi_orders) {
        fields.push((a, b));
    }
    let (mut worst, mut rmse) = (0.0f64, 0.0f64);
    for (a, b) in fields {
        let (w, r) = diff(a, b);
        worst = worst.max(w);
        rmse = rmse.max(r);
    }
    let mut tally: f64 = 0.0;
    for (a, b) in g.tallies.iter().zip(&c.tallies) {
        let scale = (b.injected + b.emitted).abs().max(1e-30);
        for (x, y) in [
            (a.injected, b.injected),
            (a.emitted, b.emitted),
            (a.exited, b.exited),
            (a.absorbed, b.absorbed),
            (a.scattered, b.scattered),
        ] {
            tally = tally.max((x - y).abs() / scale);
        }
    }
    eprintln!(
        "{what}: max rel {worst:.2e}, rel RMSE {rmse:.2e}, tallies {tally:.2e} ({} orders)",
        g.orders
    );
    assert!(tally < tally_tol, "{what}: tallies differ by {tally:e}");
    (worst, rmse)
}

fn gpu_run(
    ctx: &GpuContext,
    m: &Medium<f64>,
    b: &BoundaryLight,
    cfg: &LpmConfig,
) -> LpmSolution<f64> {
    solve(&Backend::Gpu(ctx), m, b, cfg, |_, _| {}).unwrap()
}

fn cpu_run(m: &Medium<f64>, b: &BoundaryLight, cfg: &LpmConfig) -> LpmSolution<f64> {
    solve(&Backend::Cpu(Precision::F32), m, b, cfg, |_, _| {}).unwrap()
}

/// T18: GPU-f32 vs CPU-f32 on a 12×10×14 white-noise medium (vacuum voxels, σt·h to 3)
/// under an environment plus a directional light, m = 5 (150 directions), 3 orders: every
/// field (I, the six U, φ and the per-order φ) within the bounds below where the CPU value
/// exceeds 10⁻⁶ of its maximum, and the per-order tallies within 10⁻⁵ of the input power.
#[test]
fn t18_gpu_matches_cpu_f32() {
    with_gpu("t18_gpu_matches_cpu_f32", |ctx| {
        let medium = random_medium([12, 10, 14], 21);
        let b = lights(5);
        let cfg = LpmConfig::default();
        let (worst, rmse) = compare(
            "T18",
            &gpu_run(ctx, &medium, &b, &cfg),
            &cpu_run(&medium, &b, &cfg),
            1e-5,
        );
        assert!(worst < 1e-5 && rmse < 1e-6, "T18: {worst:e}, {rmse:e}");
    });
}

/// T15: the class-slotted GPU form (per-ray sweep threads, per-voxel gather) is the CPU's
/// Algorithm 2 form: for every wrap rule, the paper's area and path factors, Henyey–Greenstein
/// with six I buffers and the relative stopping rule (the GPU stops at the CPU's order),
/// on non-cubic grids, within the bounds below.
#[test]
fn t15_gpu_slotted_form_equals_cpu_alg2() {
    with_gpu("t15_gpu_slotted_form_equals_cpu_alg2", |ctx| {
        let medium = random_medium([9, 11, 8], 3);
        let cases = [
            (
                "zero wrap m = 3",
                3,
                Phase::Isotropic,
                WrapBc::Zero,
                Formulas::exact(),
            ),
            (
                "periodic m = 4",
                4,
                Phase::Isotropic,
                WrapBc::Periodic,
                Formulas::exact(),
            ),
            (
                "face area, Δl/ω_z m = 3",
                3,
                Phase::Isotropic,
                WrapBc::Open,
                Formulas {
                    area: Area::Face,
                    path: PathLength::Paper,
                    ..Formulas::exact()
                },
            ),
            (
                "HG g = 0.7, six I, m = 3",
                3,
                Phase::HenyeyGreenstein { g: 0.7 },
                WrapBc::Open,
                Formulas::exact(),
            ),
        ];
        for (what, m, phase, wrap, formulas) in cases {
            let cfg = LpmConfig {
                m,
                phase,
                wrap,
                formulas,
                storage_i: if phase == Phase::Isotropic {
                    StorageI::One
                } else {
                    StorageI::Six
                },
                orders: Orders::Converge {
                    rel: 1e-4,
                    max_orders: 60,
                },
                ..LpmConfig::default()
            };
            let b = lights(m);
            let (worst, rmse) = compare(
                &format!("T15 {what}"),
                &gpu_run(ctx, &medium, &b, &cfg),
                &cpu_run(&medium, &b, &cfg),
                1e-5,
            );
            assert!(
                worst < 1e-5 && rmse < 1e-6,
                "T15 {what}: {worst:e}, {rmse:e}"
            );
        }
    });
}

/// T18 (D17): five GPU solves, four on reused buffers and one on a fresh solver, are bitwise
/// identical (I, U, φ, per-order φ and tallies).
#[test]
fn t18_gpu_runs_are_bitwise_identical() {
    with_gpu("t18_gpu_runs_are_bitwise_identical", |ctx| {
        let medium = random_medium([10, 12, 9], 8);
        let b = lights(5);
        let cfg = LpmConfig::default();
        let mut solver = GpuLpm::new(ctx, &medium, &cfg).unwrap();
        let first = solver.solve(&b, |_, _| {}).unwrap();
        let mut runs: Vec<LpmSolution<f32>> = (0..3)
            .map(|_| solver.solve(&b, |_, _| {}).unwrap())
            .collect();
        runs.push(
            GpuLpm::new(ctx, &medium, &cfg)
                .unwrap()
                .solve(&b, |_, _| {})
                .unwrap(),
        );
        for (k, r) in runs.iter().enumerate() {
            assert_eq!(r.intensity, first.intensity, "run {k}: I");
            assert_eq!(r.unshot, first.unshot, "run {k}: U");
            assert_eq!(r.phi, first.phi, "run {k}: φ");
            assert_eq!(r.phi_orders, first.phi_orders, "run {k}: per-order φ");
            assert_eq!(r.tallies, first.tallies, "run {k}: tallies");
        }
        assert!(first.phi.iter().any(|x| *x > 0.0));
    });
}

/// T7 on the GPU: the furnace (16³, α = 1, uniform L = 1, open wrap, orders to ε = 10⁻⁹)
/// gives I = σs L within 10⁻⁴ for σt h ∈ {0.01, 0.1} and g ∈ {0, 0.9}.
#[test]
fn t7_furnace_on_gpu() {
    with_gpu("t7_furnace_on_gpu", |ctx| {
        let h = 1.0 / 16.0;
        let dirs = Directions::new(5).unwrap();
        let boundary = BoundaryLight::uniform(&dirs, 1.0);
        for tau_h in [0.01, 0.1] {
            for g in [0.0, 0.9] {
                let medium =
                    Medium::homogeneous(Grid::new([16; 3], h).unwrap(), tau_h / h, 1.0).unwrap();
                let phase = if g == 0.0 {
                    Phase::Isotropic
                } else {
                    Phase::HenyeyGreenstein { g }
                };
                let cfg = LpmConfig {
                    phase,
                    storage_i: if g == 0.0 {
                        StorageI::One
                    } else {
                        StorageI::Six
                    },
                    orders: Orders::Converge {
                        rel: 1e-9,
                        max_orders: 400,
                    },
                    keep_orders: false,
                    ..LpmConfig::default()
                };
                let s = gpu_run(ctx, &medium, &boundary, &cfg);
                let want = tau_h / h;
                let err = s
                    .intensity
                    .iter()
                    .flat_map(|b| b.iter())
                    .fold(0.0f64, |a, x| a.max((x / want - 1.0).abs()));
                eprintln!(
                    "T7 GPU σt·h = {tau_h} g = {g}: max |I/σsL − 1| = {err:.2e} ({} orders, {:?})",
                    s.orders, s.stop
                );
                assert_eq!(s.stop, crate::method::Stop::Converged);
                assert!(err < 1e-4, "σt·h = {tau_h} g = {g}: {err:e}");
            }
        }
    });
}

/// T20 on the GPU: vacuum voxels, albedo 0, ½ and 1 and σt·h from 0 to 10³ in one 7×5×9 grid
/// give finite, non-negative I and φ; albedo 0 leaves I = j/4π (10⁻⁶) and U¹ = 0; an all-zero
/// medium gives I = 0; vacuum under L = 1 gives φ = 4π (10⁻⁶); bad input is a typed error
/// (wrong boundary size, the paper's deposit, a T buffer beyond the device's binding limit).
#[test]
fn t20_hard_inputs_on_gpu() {
    with_gpu("t20_hard_inputs_on_gpu", |ctx| {
        let grid = Grid::new([7, 5, 9], 0.2).unwrap();
        let nv = grid.len();
        let levels = [0.0, 1e-9, 1e-3, 1.0, 50.0, 5e3];
        let st: Vec<f64> = (0..nv).map(|v| levels[v % levels.len()]).collect();
        let al: Vec<f64> = (0..nv).map(|v| [0.0, 0.5, 1.0][v % 3]).collect();
        let em: Vec<f64> = (0..nv)
            .map(|v| if v % 11 == 0 { 2.0 } else { 0.0 })
            .collect();
        let dirs = Directions::new(5).unwrap();
        let b = BoundaryLight::uniform(&dirs, 1.0);
        let cfg = LpmConfig::default();
        let m = Medium::new(grid, st.clone(), al, em.clone()).unwrap();
        let s = gpu_run(ctx, &m, &b, &cfg);
        for buf in s.intensity.iter().chain(s.unshot.iter()).chain([&s.phi]) {
            assert!(buf.iter().all(|x| x.is_finite() && *x >= 0.0), "bad value");
        }
        let m0 = Medium::new(grid, st, vec![0.0; nv], em.clone()).unwrap();
        let s0 = gpu_run(ctx, &m0, &b, &cfg);
        for v in 0..nv {
            let want = em[v] / (4.0 * PI);
            assert!(
                (s0.intensity[0][v] - want).abs() <= 1e-6 * want,
                "voxel {v}"
            );
        }
        assert!(s0.unshot.iter().all(|u| u.iter().all(|x| *x == 0.0)));
        let mz = Medium::homogeneous(grid, 0.0, 0.0).unwrap();
        let sz = gpu_run(ctx, &mz, &BoundaryLight::none(&dirs), &cfg);
        assert!(sz.intensity[0].iter().all(|x| *x == 0.0));
        let sv = gpu_run(ctx, &mz, &b, &cfg);
        let worst = sv
            .phi
            .iter()
            .fold(0.0f64, |a, x| a.max((x / (4.0 * PI) - 1.0).abs()));
        eprintln!("T20 GPU: vacuum fluence max |φ/4π − 1| = {worst:.2e}");
        assert!(worst < 1e-6, "vacuum fluence {worst:e}");
        // Typed errors.
        let mut solver = GpuLpm::new(ctx, &m, &cfg).unwrap();
        assert!(matches!(
            solver.solve(
                &BoundaryLight {
                    radiance: vec![1.0; 3]
                },
                |_, _| {}
            ),
            Err(SolverError::FieldSize { .. })
        ));
        let paper = LpmConfig {
            formulas: Formulas::paper(),
            ..LpmConfig::default()
        };
        assert!(matches!(
            GpuLpm::new(ctx, &m, &paper),
            Err(SolverError::Unsupported(_))
        ));
        let big = Grid::cube(128, 1.0).unwrap();
        let t_bytes = 25 * 3 * big.len() as u64 * 4;
        if t_bytes > ctx.limits().max_storage_buffer_binding_size {
            let hb = Medium::homogeneous(big, 1.0, 0.5).unwrap();
            let whole = LpmConfig {
                streaming: Streaming::Whole,
                ..cfg.clone()
            };
            match GpuLpm::new(ctx, &hb, &whole) {
                Err(e) => {
                    let msg = e.to_string();
                    assert!(msg.contains("T buffer"), "{msg}");
                }
                Ok(_) => panic!("a {t_bytes}-byte T buffer was accepted"),
            }
        }
    });
}

/// T16 on the GPU: S ∈ {1, 4, 16, n} slabs per slice on a non-cubic 20×13×18 white-noise
/// medium under an environment plus a directional light give the unstreamed GPU solve's
/// fields, orders and tallies (bound 10⁻⁶ relative; measured bitwise, asserted below as
/// well), for the open and the periodic wrap, six I buffers with g = 0.6 and the stopping
/// rule; and the streamed GPU matches CPU-f32 within T18's bounds. T17 on the GPU: the sizes
/// of the allocated wgpu buffers equal our device formula exactly at every S, and a memory
/// budget between the S = 1 and the unstreamed bytes makes `Auto` stream within it (below
/// S = 1 it is a typed error).
#[test]
fn t16_gpu_streamed_equals_unstreamed() {
    with_gpu("t16_gpu_streamed_equals_unstreamed", |ctx| {
        let medium = random_medium([20, 13, 18], 31);
        let b = lights(5);
        let cases = [
            ("open", LpmConfig::default()),
            (
                "periodic, HG g = 0.6, six I, converge",
                LpmConfig {
                    wrap: WrapBc::Periodic,
                    phase: crate::scene::Phase::HenyeyGreenstein { g: 0.6 },
                    storage_i: StorageI::Six,
                    orders: Orders::Converge {
                        rel: 1e-3,
                        max_orders: 6,
                    },
                    ..LpmConfig::default()
                },
            ),
        ];
        for (what, cfg) in cases {
            let at = |streaming| LpmConfig {
                streaming,
                ..cfg.clone()
            };
            let whole = gpu_run(ctx, &medium, &b, &at(Streaming::Whole));
            assert_eq!(whole.memory.slabs, 20);
            for s in [1, 4, 16, 20] {
                let g = gpu_run(ctx, &medium, &b, &at(Streaming::Slabs(s)));
                assert_eq!(g.memory.slabs, s);
                assert_eq!(g.memory.resident_measured, g.memory.formula.total());
                assert_eq!(g.memory.formula.rays, 0);
                assert_eq!(g.orders, whole.orders);
                assert_eq!(g.stop, whole.stop);
                let mut fields: Vec<(&[f64], &[f64])> = vec![(&g.phi, &whole.phi)];
                for (x, y) in g.intensity.iter().zip(&whole.intensity) {
                    fields.push((x, y));
                }
                for (x, y) in g.unshot.iter().zip(&whole.unshot) {
                    fields.push((x, y));
                }
                for (x, y) in g.phi_orders.iter().zip(&whole.phi_orders) {
                    fields.push((x, y));
                }
                let worst = fields
                    .iter()
                    .map(|(x, y)| diff(x, y).0)
                    .fold(0.0f64, f64::max);
                let bitwise = fields.iter().all(|(x, y)| x == y) && g.tallies == whole.tallies;
                eprintln!(
                    "T16 GPU {what} S = {s}: max rel vs unstreamed {worst:.2e}, bitwise {bitwise}, device bytes {}",
                    g.memory.resident_measured
                );
                assert!(worst <= 1e-6, "T16 GPU {what} S = {s}: {worst:e}");
                assert!(bitwise, "T16 GPU {what} S = {s}: not bitwise");
            }
            // T17 on the GPU: a budget halfway between the S = 1 and the unstreamed device
            // bytes makes Auto stream, within the budget, with the same results.
            let one = gpu_run(ctx, &medium, &b, &at(Streaming::Slabs(1)));
            let budget = (one.memory.formula.total() + whole.memory.formula.total()) / 2;
            let auto = gpu_run(
                ctx,
                &medium,
                &b,
                &LpmConfig {
                    memory_budget: Some(budget),
                    ..at(Streaming::Auto)
                },
            );
            eprintln!(
                "T17 GPU {what}: budget {budget} B → Auto S = {}, device bytes {} (S = 1 {}, unstreamed {})",
                auto.memory.slabs,
                auto.memory.resident_measured,
                one.memory.resident_measured,
                whole.memory.resident_measured
            );
            assert!((1..20).contains(&auto.memory.slabs));
            assert!(auto.memory.resident_measured <= budget);
            assert_eq!(auto.memory.resident_measured, auto.memory.formula.total());
            assert!(auto.phi == whole.phi && auto.intensity == whole.intensity);
            assert!(matches!(
                GpuLpm::new(
                    ctx,
                    &medium,
                    &LpmConfig {
                        memory_budget: Some(one.memory.formula.total() - 1),
                        ..at(Streaming::Auto)
                    }
                ),
                Err(SolverError::TooLarge(_))
            ));
            let (worst, rmse) = compare(
                &format!("T16 GPU {what} S = 4 vs CPU-f32"),
                &gpu_run(ctx, &medium, &b, &at(Streaming::Slabs(4))),
                &cpu_run(&medium, &b, &at(Streaming::Slabs(4))),
                1e-5,
            );
            assert!(worst < 1e-5 && rmse < 1e-6, "{worst:e}, {rmse:e}");
        }
    });
}

/// 64³ (m = 5) solves on the GPU with slice streaming where the unstreamed T exceeds the
/// storage-binding limit, on a device whose binding is capped at 16 MiB
/// (`GpuContext::with_binding_limit`), so the streaming runs on every adapter (lavapipe's
/// own 128 MiB needed 128³, 56 s of the suite; a real GPU's binding typically holds 128³ unstreamed;
/// `t20_hard_inputs_on_gpu` keeps the refusal of `Streaming::Whole`): `Auto` picks the
/// largest S whose T fits one binding, the device bytes equal our formula, and one order on a
/// homogeneous σt h = 0.05, α = 0.9 cube under L = 1 is finite, positive and balanced
/// (imbalance ≤ 10⁻⁴ of the input, f32).
#[test]
fn gpu_64_cubed_solves_with_streaming_under_a_16_mib_binding() {
    with_gpu(
        "gpu_64_cubed_solves_with_streaming_under_a_16_mib_binding",
        |full| {
            let ctx = &full.with_binding_limit(16 << 20).unwrap();
            let grid = Grid::new([64, 64, 64], 0.05).unwrap();
            let t_bytes = 25 * 3 * grid.len() as u64 * 4;
            let bind = ctx.limits().max_storage_buffer_binding_size;
            assert!(
                bind <= 16 << 20 && t_bytes > bind,
                "binding {bind} B, T {t_bytes} B"
            );
            let medium = Medium::homogeneous(grid, 1.0, 0.9).unwrap();
            let dirs = Directions::new(5).unwrap();
            let cfg = LpmConfig {
                orders: Orders::Fixed(1),
                keep_orders: false,
                ..LpmConfig::default()
            };
            let mut solver = GpuLpm::new(ctx, &medium, &cfg).unwrap();
            let s = solver.slabs();
            assert!((1..64).contains(&s), "Auto chose S = {s}");
            let t0 = std::time::Instant::now();
            let sol = solver
                .solve(&BoundaryLight::uniform(&dirs, 1.0), |_, _| {})
                .unwrap();
            assert_eq!(sol.memory.resident_measured, sol.memory.formula.total());
            assert!(sol.memory.formula.t <= bind);
            assert!(sol.phi.iter().all(|x| x.is_finite() && *x > 0.0));
            assert!(sol.intensity[0].iter().all(|x| x.is_finite() && *x > 0.0));
            let imbalance = sol.tallies[0].imbalance().abs();
            eprintln!(
                "64³ GPU: Auto S = {s} (T {} B ≤ binding {bind} B; unstreamed T {t_bytes} B), device bytes {}, one order {:.1} s wall, imbalance {imbalance:.2e}",
                sol.memory.formula.t,
                sol.memory.resident_measured,
                t0.elapsed().as_secs_f64()
            );
            assert!(imbalance < 1e-4, "{imbalance:e}");
        },
    );
}
