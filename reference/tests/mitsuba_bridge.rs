//! The Mitsuba bridge against an analytic answer: an absorbing voxel grid in front of a
//! constant environment, seen by an orthographic camera whose pixels each cover exactly one
//! voxel column. Pixel (col, row) must show L·exp(−σt(col, ·, 3 − row)·1), which checks the
//! `.vol` export, the nearest-neighbour cell mapping and bounding box, the camera's
//! orientation (pixel (0, 0) top-left) and the environment light in one go.
//!
//! Skips (with one line) when Mitsuba is not installed, fails instead when
//! SCATTERBENCH_REQUIRE_MITSUBA=1.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use reference::compare::{ImageEstimate, compare};
use reference::mitsuba::{MitsubaConfig, MitsubaError, MitsubaSettings, render};
use solvers::scene::{Camera, Light, Phase, Projection, Sampler, Scene};
use solvers::{Grid, Medium};

fn mitsuba_or_skip(variant: &str) -> Option<MitsubaConfig> {
    MitsubaConfig::available_or_skip(variant).unwrap()
}

#[test]
fn absorbing_columns_match_beer_lambert_pixel_by_pixel() {
    let Some(cfg) = mitsuba_or_skip("scalar_rgb") else {
        return;
    };
    let n = 4;
    let grid = Grid::cube(n, 1.0).unwrap();
    // σt depends on the column (i, k) only; rays travel along +y through one column.
    let sigma = |i: usize, k: usize| 0.25 * (1 + i + n * k) as f64;
    let mut sigma_t = vec![0.0; grid.len()];
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                sigma_t[grid.index(i, j, k)] = sigma(i, k);
            }
        }
    }
    let medium = Medium::new(grid, sigma_t, vec![0.0; grid.len()], vec![0.0; grid.len()]).unwrap();
    let radiance = 2.0;
    let scene = Scene {
        interpolation: Default::default(),
        medium,
        phase: Phase::Isotropic,
        lights: vec![Light::Environment { radiance }],
        camera: Some(Camera {
            hide_background: false,
            eye: [0.5, -1.0, 0.5],
            target: [0.5, 0.5, 0.5],
            up: [0.0, 0.0, 1.0],
            projection: Projection::Orthographic { width: 1.0 },
            resolution: [n, n],
        }),
        sampler: Sampler { spp: 256, seed: 0 },
    };
    let settings = MitsubaSettings {
        spp: 4096,
        renders: 8,
        seed: 5,
        max_depth: None,
        keep_dir: None,
        timeout: None,
    };
    let r = render(&scene, &settings, &cfg).unwrap();
    assert_eq!(r.variant, "scalar_rgb");
    assert_eq!(r.max_channel_difference, 0.0);
    let mut exact = Vec::new();
    for row in 0..n {
        for col in 0..n {
            exact.push(radiance * (-sigma(col, n - 1 - row)).exp());
        }
    }
    let truth = ImageEstimate {
        width: n,
        height: n,
        mean: exact.clone(),
        stderr: vec![0.0; n * n],
        dof: f64::INFINITY,
    };
    let c = compare(&truth, &r.image, 0.01).unwrap();
    assert_eq!(
        c.fraction_passing, 1.0,
        "Mitsuba {:?}\nexact {exact:?}",
        r.image.mean
    );
    assert!(c.means_agree(3.0), "image means differ by {} se", c.mean_z);
    // The test has power: the same truth upside down or mirrored fails almost everywhere.
    for flip in [
        |r: usize, c: usize| (3 - r, c),
        |r: usize, c: usize| (r, 3 - c),
    ] {
        let mut wrong = truth.clone();
        for row in 0..n {
            for col in 0..n {
                let (r2, c2) = flip(row, col);
                wrong.mean[row * n + col] = exact[r2 * n + c2];
            }
        }
        let c = compare(&wrong, &r.image, 0.01).unwrap();
        assert_eq!(c.fraction_passing, 0.0);
    }
}

/// A Mitsuba child that never returns is killed at its time limit: an interpreter that
/// sleeps (a shell script standing in for Python) gives `TimedOut` after the limit, not a
/// hang. Needs no Mitsuba.
#[test]
fn a_child_that_never_returns_is_killed_at_its_limit() {
    use std::os::unix::fs::PermissionsExt as _;
    let dir = std::env::temp_dir().join(format!("scatterbench-hang-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let fake = dir.join("python");
    std::fs::write(&fake, "#!/bin/sh\nexec sleep 600\n").unwrap();
    std::fs::set_permissions(&fake, std::fs::Permissions::from_mode(0o755)).unwrap();
    let cfg = MitsubaConfig {
        python: fake,
        variant: "scalar_rgb".into(),
    };
    // Another test of this binary may fork a Mitsuba child while `fake` is still open for
    // writing here; until that child execs, it holds the descriptor, and executing `fake`
    // fails with ETXTBSY ("Text file busy", os error 26; seen once in CI). That is the
    // kernel's race, not the bridge's, so the spawn is retried.
    let (e, took) = (0..50)
        .map(|_| {
            let t0 = std::time::Instant::now();
            let e = cfg
                .probe_within(std::time::Duration::from_millis(500))
                .unwrap_err();
            (e, t0.elapsed().as_secs_f64())
        })
        .find(|(e, _)| {
            let busy = e.to_string().contains("os error 26");
            if busy {
                std::thread::sleep(std::time::Duration::from_millis(20));
            }
            !busy
        })
        .unwrap();
    assert!(matches!(e, MitsubaError::TimedOut { .. }), "{e}");
    assert!((0.5..5.0).contains(&took), "killed after {took} s");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Ours against Mitsuba on `scene` (full, unbiased renders of both); returns the comparison
/// after printing the numbers.
fn ours_vs_mitsuba(
    label: &str,
    scene: &Scene,
    cfg: &MitsubaConfig,
    spp: u32,
) -> reference::compare::Comparison {
    use reference::pathtracer::{Contributions, RenderSettings, render_image};
    let batches = 16;
    let ours = render_image(
        scene,
        &RenderSettings {
            spp,
            seed: 17,
            batches,
            contributions: Contributions::all(),
        },
    )
    .unwrap();
    let settings = MitsubaSettings {
        spp: spp / 8,
        renders: 8,
        seed: 9,
        max_depth: None,
        keep_dir: None,
        timeout: None,
    };
    let r = render(scene, &settings, cfg).unwrap();
    let ours = ImageEstimate::batched(ours.width, ours.height, ours.mean, ours.stderr, batches);
    let c = compare(&ours, &r.image, 0.01).unwrap();
    eprintln!(
        "{label}: ours {:.5} ± {:.1e}, Mitsuba {:.5} ± {:.1e}, z {:+.2}, passing {:.3}, passed {}",
        c.mean_ours.0,
        c.mean_ours.1,
        c.mean_theirs.0,
        c.mean_theirs.1,
        c.mean_z,
        c.fraction_passing,
        c.passed()
    );
    c
}

/// Issue 12, acceptance 5: the albedo-1 cube of σt = 100 (16³, τ = 6.25 per voxel,
/// directional light, perspective 16×16). With Mitsuba's default Russian roulette
/// (`rr_depth` 5; at albedo 1 every one of a path's hundreds of scatterings rolls at 0.95
/// and the survivors' weight grows as 0.95⁻ⁿ) the issue measured ours 0.1065 ± 0.0002
/// against Mitsuba 0.0981 ± 0.0014 (z 5.8), and a later stop 0.1827 ± 0.0003 against
/// 0.1741 ± 0.0049 with 96.9 % of the pixels passing. Our export turns the roulette off
/// (`mitsuba::RR_DEPTH`), and the two agree: `passed`. Measured at 512 spp: ours 0.18216 ±
/// 0.00073, Mitsuba 0.18120 ± 0.00082 (z +0.87, every pixel passing); with `RR_DEPTH` set
/// back to 5 the same test fails (Mitsuba 0.16865 ± 0.0037, z +3.60, 99.2 % passing).
#[test]
fn albedo_1_dense_cube_agrees_with_mitsuba_without_roulette() {
    let Some(cfg) = mitsuba_or_skip("scalar_rgb") else {
        return;
    };
    let grid = Grid::cube(16, 1.0).unwrap();
    let scene = Scene {
        interpolation: Default::default(),
        medium: Medium::homogeneous(grid, 100.0, 1.0).unwrap(),
        phase: Phase::Isotropic,
        lights: vec![Light::directional([0.4, 0.5, -1.0], 3.0).unwrap()],
        camera: Some(Camera {
            hide_background: false,
            eye: [0.5, -1.5, 0.8],
            target: [0.5, 0.5, 0.5],
            up: [0.0, 0.0, 1.0],
            projection: Projection::Perspective {
                fov_y_degrees: 50.0,
            },
            resolution: [16, 16],
        }),
        sampler: Sampler { spp: 16, seed: 0 },
    };
    let c = ours_vs_mitsuba("albedo-1 cube, σt = 100", &scene, &cfg, 512);
    assert!(c.passed(), "z {} passing {}", c.mean_z, c.fraction_passing);
    // The test has power: a 3 % bias would be > 4 combined standard errors.
    let combined = c.mean_ours.1.hypot(c.mean_theirs.1);
    assert!(0.03 * c.mean_ours.0 > 4.0 * combined, "{combined}");
}

/// Issue 12, acceptance 4: an environment-lit dense HG sphere (σt = 20, albedo 0.9,
/// g = 0.5, 16³) in vacuum with the environment visible (Mitsuba shows it by default, ours
/// renders it as order 0), and with it hidden (`hide_background` → `hide_emitters`).
#[test]
fn environment_lit_hg_sphere_with_visible_and_hidden_background() {
    let Some(cfg) = mitsuba_or_skip("scalar_rgb") else {
        return;
    };
    let grid = Grid::cube(16, 1.0).unwrap();
    let sigma = grid.sample(|p| {
        let r2: f64 = (0..3).map(|a| (p[a] - 0.5) * (p[a] - 0.5)).sum();
        if r2 < 0.35 * 0.35 { 20.0 } else { 0.0 }
    });
    let n = grid.len();
    for hide_background in [false, true] {
        let scene = Scene {
            interpolation: Default::default(),
            medium: Medium::new(grid, sigma.clone(), vec![0.9; n], vec![0.0; n]).unwrap(),
            phase: Phase::HenyeyGreenstein { g: 0.5 },
            lights: vec![Light::Environment { radiance: 2.0 }],
            camera: Some(Camera {
                hide_background,
                eye: [0.5, -2.0, 0.5],
                target: [0.5, 0.5, 0.5],
                up: [0.0, 0.0, 1.0],
                projection: Projection::Orthographic { width: 1.25 },
                resolution: [20, 20],
            }),
            sampler: Sampler { spp: 16, seed: 0 },
        };
        let c = ours_vs_mitsuba(
            &format!("env sphere, hide_background = {hide_background}"),
            &scene,
            &cfg,
            1024,
        );
        assert!(c.passed(), "z {} passing {}", c.mean_z, c.fraction_passing);
        // The corner pixels see vacuum: L_env when visible, 0 when hidden, in both.
        assert_eq!(c.mean_ours.0 > 1.0, !hide_background);
    }
}

/// Issue 12, acceptance 7: a heterogeneous medium with `interpolation = "trilinear"`
/// against Mitsuba's trilinear `gridvolume` filter (8³ random σt ∈ [0, 12), random albedo,
/// HG g = 0.3, a directional light), and the same render with nearest lookups on our side
/// fails against it (the test has power).
#[test]
fn trilinear_heterogeneous_medium_matches_mitsubas_trilinear_filter() {
    let Some(cfg) = mitsuba_or_skip("scalar_rgb") else {
        return;
    };
    let grid = Grid::cube(8, 1.0).unwrap();
    let mut rng = solvers::noise::SplitMix64::new(42);
    let n = grid.len();
    let sigma: Vec<f64> = (0..n).map(|_| 12.0 * rng.next_f64()).collect();
    let albedo: Vec<f64> = (0..n).map(|_| 0.5 + 0.5 * rng.next_f64()).collect();
    let scene = Scene {
        interpolation: solvers::scene::Interpolation::Trilinear,
        medium: Medium::new(grid, sigma, albedo, vec![0.0; n]).unwrap(),
        phase: Phase::HenyeyGreenstein { g: 0.3 },
        lights: vec![Light::directional([0.3, 0.2, -1.0], 1.0).unwrap()],
        camera: Some(Camera {
            hide_background: false,
            eye: [0.5, -2.0, 0.5],
            target: [0.5, 0.5, 0.5],
            up: [0.0, 0.0, 1.0],
            projection: Projection::Orthographic { width: 1.0 },
            resolution: [16, 16],
        }),
        sampler: Sampler { spp: 16, seed: 0 },
    };
    let c = ours_vs_mitsuba("trilinear heterogeneous", &scene, &cfg, 2048);
    assert!(c.passed(), "z {} passing {}", c.mean_z, c.fraction_passing);
    // Our nearest render of the same voxels against Mitsuba's trilinear one: different media.
    use reference::pathtracer::{
        Contributions, Interpolation, RenderSettings, TraceOptions, render_image_with,
    };
    let near = render_image_with(
        &scene,
        &RenderSettings {
            spp: 2048,
            seed: 23,
            batches: 16,
            contributions: Contributions::all(),
        },
        &TraceOptions {
            interpolation: Interpolation::Nearest,
            ..TraceOptions::default()
        },
    )
    .unwrap();
    let settings = MitsubaSettings {
        spp: 256,
        renders: 8,
        seed: 9,
        max_depth: None,
        keep_dir: None,
        timeout: None,
    };
    let r = render(&scene, &settings, &cfg).unwrap();
    let near = ImageEstimate::batched(near.width, near.height, near.mean, near.stderr, 16);
    let c = compare(&near, &r.image, 0.01).unwrap();
    eprintln!(
        "nearest (ours) vs trilinear (Mitsuba): z {:+.2}, passing {:.3}",
        c.mean_z, c.fraction_passing
    );
    assert!(!c.passed());
}
