//! T15: Alg 1 (sequential, direct deposits) ≡ Alg 2 (`CpuLpm`, propagate/collect) on the
//! CPU in f64 and f32, and ≡ the GPU's slotted form (lavapipe; skipped without an adapter
//! unless `SCATTERBENCH_REQUIRE_GPU=1`). The numbers in `alg1.rs`'s docs are printed here
//! (`cargo test --release -p solvers --lib lpm::alg1 -- --nocapture`).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use super::super::gpu_tests::{compare, lights, with_gpu};
use super::super::tests::random_medium;
use super::super::*;
use super::Alg1Lpm;
use crate::scene::Phase;
use crate::{Backend, Medium, Precision, Real};

fn alg1<T: Real>(m: &Medium<f64>, b: &BoundaryLight, cfg: &LpmConfig) -> LpmSolution<f64> {
    widen(
        Alg1Lpm::<T>::new(&m.cast(), cfg)
            .unwrap()
            .solve(b, |_, _| {})
            .unwrap(),
    )
}

fn alg2(p: Precision, m: &Medium<f64>, b: &BoundaryLight, cfg: &LpmConfig) -> LpmSolution<f64> {
    solve(&Backend::Cpu(p), m, b, cfg, |_, _| {}).unwrap()
}

/// The T15 cases: every wrap rule, the paper's formulas, HG with six I.
fn cases() -> Vec<(&'static str, LpmConfig)> {
    let base = LpmConfig {
        orders: Orders::Fixed(3),
        ..LpmConfig::default()
    };
    vec![
        ("open wrap, m = 5", base.clone()),
        (
            "zero wrap, m = 3",
            LpmConfig {
                m: 3,
                wrap: WrapBc::Zero,
                ..base.clone()
            },
        ),
        (
            "periodic wrap, m = 4",
            LpmConfig {
                m: 4,
                wrap: WrapBc::Periodic,
                ..base.clone()
            },
        ),
        (
            "paper formulas, m = 3",
            LpmConfig {
                m: 3,
                formulas: Formulas::paper(),
                ..base.clone()
            },
        ),
        (
            "HG g = 0.7, six I, m = 3",
            LpmConfig {
                m: 3,
                phase: Phase::HenyeyGreenstein { g: 0.7 },
                storage_i: StorageI::Six,
                ..base
            },
        ),
    ]
}

/// T15 on the CPU: Alg 1 ≡ Alg 2 to 10⁻¹³ relative in f64; in f32 the relative RMSE of
/// every field ≤ 10⁻⁶ and no voxel above 10⁻⁶ of the maximum off by more than 10⁻⁵ (T18's
/// pair of bounds); each form's own f32 error against f64 is printed beside it.
#[test]
fn t15_alg1_equals_alg2() {
    let medium = random_medium([9, 11, 8], 3);
    for (what, cfg) in cases() {
        let b = lights(cfg.m);
        let (w64, _) = compare(
            &format!("T15 f64 {what}"),
            &alg1::<f64>(&medium, &b, &cfg),
            &alg2(Precision::F64, &medium, &b, &cfg),
            1e-13,
        );
        assert!(w64 < 1e-13, "{what}: f64 max rel {w64:e}");
        let (w32, r32) = compare(
            &format!("T15 f32 {what}"),
            &alg1::<f32>(&medium, &b, &cfg),
            &alg2(Precision::F32, &medium, &b, &cfg),
            1e-6,
        );
        assert!(r32 < 1e-6 && w32 < 1e-5, "{what}: f32 {w32:e} / {r32:e}");
        // Where the f32 difference comes from: each form's own f32 rounding against f64.
        let exact = alg2(Precision::F64, &medium, &b, &cfg);
        let (_, e1) = compare(
            &format!("  Alg 1 f32 vs f64 {what}"),
            &alg1::<f32>(&medium, &b, &cfg),
            &exact,
            1e-5,
        );
        let (_, e2) = compare(
            &format!("  Alg 2 f32 vs f64 {what}"),
            &alg2(Precision::F32, &medium, &b, &cfg),
            &exact,
            1e-5,
        );
        assert!(e1 < 1e-5 && e2 < 1e-5, "{what}: f32 vs f64 {e1:e}, {e2:e}");
    }
}

/// The relative stopping rule (D1) stops Alg 1 and Alg 2 after the same order, with the
/// same fields (f64, 10⁻¹³).
#[test]
fn t15_alg1_stops_like_alg2() {
    let medium = random_medium([7, 6, 8], 11);
    let cfg = LpmConfig {
        m: 3,
        orders: Orders::Converge {
            rel: 1e-4,
            max_orders: 60,
        },
        ..LpmConfig::default()
    };
    let b = lights(3);
    let a = alg1::<f64>(&medium, &b, &cfg);
    let (w, _) = compare(
        "T15 converge rel 1e-4",
        &a,
        &alg2(Precision::F64, &medium, &b, &cfg),
        1e-13,
    );
    assert!(
        a.orders > 3,
        "the rule should need several orders: {}",
        a.orders
    );
    assert!(w < 1e-13, "{w:e}");
}

/// T15 on the GPU: the slotted kernels (f32) ≡ Alg 1 in f32, relative RMSE ≤ 10⁻⁶ and max
/// relative ≤ 10⁻⁵ on every field and tallies within 10⁻⁵ of the input (open wrap m = 5; HG g = 0.7, six I, m = 3).
#[test]
fn t15_gpu_slotted_equals_alg1() {
    with_gpu("t15_gpu_slotted_equals_alg1", |ctx| {
        let medium = random_medium([9, 11, 8], 3);
        for (what, cfg) in cases()
            .into_iter()
            .filter(|(w, _)| w.starts_with("open") || w.starts_with("HG"))
        {
            let b = lights(cfg.m);
            let g = solve(&Backend::Gpu(ctx), &medium, &b, &cfg, |_, _| {}).unwrap();
            let (w, r) = compare(
                &format!("T15 GPU vs Alg 1 f32 {what}"),
                &g,
                &alg1::<f32>(&medium, &b, &cfg),
                1e-5,
            );
            assert!(r < 1e-6 && w < 1e-5, "{what}: {w:e} / {r:e}");
        }
    });
}

/// `time_directions` over every direction counts exactly the sub-segments of an order, none
/// for no directions, and an index beyond the set is a typed error.
#[test]
fn time_directions_counts_one_order() {
    let medium = random_medium([6, 5, 7], 5);
    let cfg = LpmConfig {
        m: 3,
        orders: Orders::Fixed(1),
        ..LpmConfig::default()
    };
    let a = Alg1Lpm::<f64>::new(&medium, &cfg).unwrap();
    let b = lights(3);
    let all: Vec<usize> = (0..a.dirs.len()).collect();
    let (segs, secs) = a.time_directions(&b, &all).unwrap();
    assert_eq!(segs, a.sub_segments_per_order());
    assert!(secs.is_finite() && secs >= 0.0);
    assert!(matches!(
        a.time_directions(&b, &[a.dirs.len()]),
        Err(crate::SolverError::BadParameter { name: "dirs", .. })
    ));
    assert_eq!(a.time_directions(&b, &[]).unwrap().0, 0);
}
