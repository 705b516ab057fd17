//! Scene-level tests of the path tracer: determinism, vacuum limits, analytic single
//! scattering, emission, majorant-grid consistency, fluence, slab and point-source checks.
//! Comparisons of many bins at once use Šidák-corrected thresholds for a family-wise
//! false-alarm rate of 0.27 % (the 3σ rule for one comparison).

use super::estimators::sidak_z;
use super::*;
use crate::quadrature::simpson;
use solvers::scene::{Camera, Light, Phase, Projection, Sampler, Scene};
use solvers::{Grid, Medium};

const FAMILY: f64 = 0.0027;

fn scene(medium: Medium<f64>, phase: Phase, lights: Vec<Light>, camera: Option<Camera>) -> Scene {
    Scene {
        interpolation: Default::default(),
        medium,
        phase,
        lights,
        camera,
        sampler: Sampler { spp: 1, seed: 0 },
    }
}

/// Orthographic camera looking down −z at the unit cube, image `w` wide.
fn top_camera(res: usize, width: f64) -> Camera {
    Camera {
        hide_background: false,
        eye: [0.5, 0.5, 3.0],
        target: [0.5, 0.5, 0.0],
        up: [0.0, 1.0, 0.0],
        projection: Projection::Orthographic { width },
        resolution: [res, res],
    }
}

fn settings(spp: u32, seed: u64, max_depth: Option<u32>) -> RenderSettings {
    RenderSettings {
        spp,
        seed,
        batches: 16,
        contributions: max_depth.map_or(Contributions::all(), Contributions::up_to),
    }
}

fn unit_cube(n: usize, sigma: f64, albedo: f64, emission: f64) -> Medium<f64> {
    let grid = Grid::cube(n, 1.0).unwrap();
    let len = grid.len();
    Medium::new(
        grid,
        vec![sigma; len],
        vec![albedo; len],
        vec![emission; len],
    )
    .unwrap()
}

/// A cloud with a dense core and an even denser small blob in a corner, vacuum elsewhere.
fn cloud(n: usize) -> Medium<f64> {
    let grid = Grid::cube(n, 1.0).unwrap();
    let sigma = grid.sample(|p| {
        let r2 = (p[0] - 0.5).powi(2) + (p[1] - 0.5).powi(2) + (p[2] - 0.5).powi(2);
        let b2 = (p[0] - 0.85).powi(2) + (p[1] - 0.15).powi(2) + (p[2] - 0.8).powi(2);
        if b2 < 0.01 {
            150.0
        } else if r2 < 0.09 {
            8.0 + 6.0 * (9.0 * p[0]).sin()
        } else {
            0.0
        }
    });
    let albedo = grid.sample(|p| 0.7 + 0.25 * (5.0 * p[1]).cos());
    let len = grid.len();
    Medium::new(grid, sigma, albedo, vec![0.0; len]).unwrap()
}

fn sun() -> Light {
    Light::directional([0.3, -0.2, -1.0], 2.0).unwrap()
}

#[test]
fn results_are_bit_identical_for_one_and_two_threads() {
    let s = scene(
        cloud(16),
        Phase::HenyeyGreenstein { g: 0.4 },
        vec![
            sun(),
            Light::Point {
                position: [0.2, 0.8, 0.5],
                power: 3.0,
            },
            Light::Environment { radiance: 0.1 },
        ],
        Some(top_camera(6, 1.2)),
    );
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let img = render_image(&s, &settings(32, 11, None)).unwrap();
            let flu = fluence(&s, &PathSettings::new(3000, 5)).unwrap();
            let sh = InfiniteMedium::new(0.9, Phase::Isotropic)
                .unwrap()
                .shells(&[0.0, 0.5, 1.0, 3.0], &PathSettings::new(20_000, 3))
                .unwrap();
            let sl = SlabMedium::new(2.0, 0.9, Phase::HenyeyGreenstein { g: 0.7 })
                .unwrap()
                .simulate(0.6, &PathSettings::new(20_000, 3))
                .unwrap();
            (img, flu, sh, sl)
        })
    };
    let (a, b) = (run(1), run(2));
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&a.0.mean), bits(&b.0.mean));
    assert_eq!(bits(&a.0.stderr), bits(&b.0.stderr));
    assert_eq!(bits(&a.1.total.mean), bits(&b.1.total.mean));
    assert_eq!(bits(&a.1.collided.stderr), bits(&b.1.collided.stderr));
    assert_eq!(a.2, b.2);
    assert_eq!(a.3, b.3);
    assert!(a.0.mean.iter().any(|&x| x > 0.0));
}

#[test]
fn vacuum_renders_exactly_black_or_exactly_the_environment() {
    let cam = Camera {
        hide_background: false,
        eye: [0.5, -2.0, 0.5],
        target: [0.5, 0.5, 0.5],
        up: [0.0, 0.0, 1.0],
        projection: Projection::Perspective {
            fov_y_degrees: 50.0,
        },
        resolution: [7, 5],
    };
    let lights = vec![
        sun(),
        Light::Point {
            position: [0.5, 0.5, 0.5],
            power: 10.0,
        },
        Light::Sphere {
            center: [0.5, 0.5, 5.0],
            radius: 0.5,
            radiance: 4.0,
        },
    ];
    let s = scene(
        unit_cube(5, 0.0, 0.8, 0.0),
        Phase::Isotropic,
        lights,
        Some(cam),
    );
    let img = render_image(&s, &settings(16, 1, None)).unwrap();
    assert_eq!((img.width, img.height), (7, 5));
    assert!(img.mean.iter().chain(&img.stderr).all(|&x| x == 0.0));

    let env = 0.37;
    let s = scene(
        unit_cube(5, 0.0, 0.8, 0.0),
        Phase::Isotropic,
        vec![Light::Environment { radiance: env }],
        Some(cam),
    );
    let img = render_image(&s, &settings(16, 1, None)).unwrap();
    for (m, e) in img.mean.iter().zip(&img.stderr) {
        // Exact up to the rounding of summing 16 equal values.
        assert!((m - env).abs() <= 4.0 * f64::EPSILON * env, "{m}");
        assert!(*e <= 4.0 * f64::EPSILON * env, "{e}");
    }
}

/// Single scattering (max_depth 1) of a directional light in a homogeneous cube seen by an
/// orthographic camera, against ∫ σs e^{−σt t} p(cos θ) E e^{−σt s_l} dt by quadrature,
/// averaged over each pixel; for isotropic and HG phase functions.
#[test]
fn single_scattering_matches_quadrature() {
    let (sigma, albedo) = (2.0, 0.6);
    let light = sun();
    let Light::Directional {
        direction,
        irradiance,
    } = light
    else {
        unreachable!()
    };
    let to_light = direction.map(|v| -v);
    let res = 4;
    let width = 0.8;
    let cam = top_camera(res, width);
    let v = volume::Volume::new(&unit_cube(4, sigma, albedo, 0.0), Interpolation::Nearest).unwrap();
    let zmax = sidak_z(2 * res * res, FAMILY);
    for phase in [Phase::Isotropic, Phase::HenyeyGreenstein { g: 0.5 }] {
        let s = scene(
            unit_cube(4, sigma, albedo, 0.0),
            phase,
            vec![light],
            Some(cam),
        );
        let img = render_image(&s, &settings(4000, 2, Some(1))).unwrap();
        let cos = -to_light[2]; // ω_l · d_cam with d_cam = (0, 0, −1)
        let p = phase::eval(&phase, cos);
        for py in 0..res {
            for px in 0..res {
                let sub = 6;
                let mut acc = 0.0;
                for a in 0..sub {
                    for b in 0..sub {
                        let x = 0.5
                            + width
                                * ((px as f64 + (a as f64 + 0.5) / sub as f64) / res as f64 - 0.5);
                        let y = 0.5
                            - width
                                * ((py as f64 + (b as f64 + 0.5) / sub as f64) / res as f64 - 0.5);
                        acc += simpson(
                            |t| {
                                let q = [x, y, 1.0 - t];
                                let s_l = v.clip(q, to_light).map_or(0.0, |c| c.1.max(0.0));
                                sigma
                                    * albedo
                                    * (-sigma * t).exp()
                                    * p
                                    * irradiance
                                    * (-sigma * s_l).exp()
                            },
                            0.0,
                            1.0,
                            2000,
                        );
                    }
                }
                let exact = acc / (sub * sub) as f64;
                let i = py * res + px;
                let z = (img.mean[i] - exact) / img.stderr[i];
                assert!(
                    z.abs() < zmax,
                    "{phase:?} pixel ({px},{py}): {} ± {} vs {exact}",
                    img.mean[i],
                    img.stderr[i]
                );
            }
        }
    }
}

/// Volume emission seen through a purely absorbing cube: L = j/(4πσt)(1 − e^{−σt}); with
/// σt = 0 exactly j/(4π) per unit length.
#[test]
fn emission_is_collected_along_the_path() {
    let j = 3.0;
    let cam = top_camera(3, 0.9);
    let s = scene(
        unit_cube(4, 0.0, 0.0, j),
        Phase::Isotropic,
        vec![],
        Some(cam),
    );
    let img = render_image(&s, &settings(16, 3, None)).unwrap();
    let exact = j / (4.0 * std::f64::consts::PI);
    assert!(img.mean.iter().all(|m| (m - exact).abs() < 1e-12 * exact));
    for interp in [Interpolation::Nearest, Interpolation::Trilinear] {
        let sigma = 2.0;
        let s = scene(
            unit_cube(4, sigma, 0.0, j),
            Phase::Isotropic,
            vec![],
            Some(cam),
        );
        let opts = TraceOptions {
            interpolation: interp,
            ..TraceOptions::default()
        };
        let img = render_image_with(&s, &settings(2000, 4, None), &opts).unwrap();
        let exact = j / (4.0 * std::f64::consts::PI * sigma) * (1.0 - (-sigma).exp());
        let zmax = sidak_z(9, FAMILY);
        for (m, e) in img.mean.iter().zip(&img.stderr) {
            assert!(
                ((m - exact) / e).abs() < zmax,
                "{interp:?}: {m} ± {e} vs {exact}"
            );
        }
    }
}

/// The order-and-emitter split of [`Contributions`] partitions the radiance: single +
/// multiple scattering of the light + direct + scattered emission = the full image, pixel
/// by pixel within Šidák-corrected z over the pixels (independent seeds per part). The
/// emission-only part of a *scattering* cube is the purely absorbing closed form
/// j/(4πσt)(1 − e^{−σt}), because no scattered light may enter it.
#[test]
fn contributions_partition_the_radiance() {
    let (sigma, albedo, j) = (2.0, 0.8, 3.0);
    let res = 3;
    let s = scene(
        unit_cube(4, sigma, albedo, j),
        Phase::HenyeyGreenstein { g: 0.3 },
        vec![sun()],
        Some(top_camera(res, 0.9)),
    );
    let run = |c: Contributions, seed: u64| {
        render_image(
            &s,
            &RenderSettings {
                contributions: c,
                ..settings(3000, seed, None)
            },
        )
        .unwrap()
    };
    let full = run(Contributions::all(), 1);
    let parts = [
        run(Contributions::single_scattering(), 2),
        run(Contributions::multiple_scattering(), 3),
        run(Contributions::emission_only(), 4),
        run(Contributions::scattered_emission(), 5),
    ];
    let zmax = sidak_z(2 * res * res, FAMILY);
    for i in 0..res * res {
        let sum: f64 = parts.iter().map(|p| p.mean[i]).sum();
        let var: f64 =
            parts.iter().map(|p| p.stderr[i].powi(2)).sum::<f64>() + full.stderr[i].powi(2);
        let z = (sum - full.mean[i]) / var.sqrt();
        assert!(
            z.abs() < zmax,
            "pixel {i}: parts {sum} vs full {} (z = {z})",
            full.mean[i]
        );
        assert!(
            parts.iter().all(|p| p.mean[i] > 0.0),
            "pixel {i}: an empty part"
        );
    }
    let exact = j / (4.0 * std::f64::consts::PI * sigma) * (1.0 - (-sigma).exp());
    for (m, e) in parts[2].mean.iter().zip(&parts[2].stderr) {
        assert!(
            ((m - exact) / e).abs() < zmax,
            "emission only: {m} ± {e} vs {exact}"
        );
    }
    assert!(matches!(
        render_image(
            &s,
            &RenderSettings {
                contributions: Contributions {
                    min_order: 2,
                    ..Contributions::up_to(1)
                },
                ..settings(16, 0, None)
            }
        ),
        Err(crate::ReferenceError::BadParameter { .. })
    ));
}

/// The majorant grid (8³ blocks) and one global majorant sample the same process: images of
/// a sparse cloud with a very dense blob agree pixel by pixel (independent seeds).
#[test]
fn majorant_grid_matches_global_majorant() {
    let cam = Camera {
        hide_background: false,
        eye: [0.5, -1.5, 1.3],
        target: [0.5, 0.5, 0.5],
        up: [0.0, 0.0, 1.0],
        projection: Projection::Perspective {
            fov_y_degrees: 45.0,
        },
        resolution: [6, 6],
    };
    let s = scene(
        cloud(24),
        Phase::HenyeyGreenstein { g: 0.3 },
        vec![sun(), Light::Environment { radiance: 0.2 }],
        Some(cam),
    );
    let blocks = render_image(&s, &settings(400, 7, None)).unwrap();
    let global = render_image_with(
        &s,
        &settings(400, 8, None),
        &TraceOptions {
            majorant_block: 1000,
            ..TraceOptions::default()
        },
    )
    .unwrap();
    let zmax = sidak_z(36, FAMILY);
    for i in 0..36 {
        let (a, b) = (
            Estimate {
                mean: blocks.mean[i],
                stderr: blocks.stderr[i],
            },
            Estimate {
                mean: global.mean[i],
                stderr: global.stderr[i],
            },
        );
        assert!(a.z_diff(&b).abs() < zmax, "pixel {i}: {a:?} vs {b:?}");
    }
}

/// Issue 14's dense voxel: an 8³ cube of σt = 4 with two centre voxels of σt = 10³. Its image
/// with refined blocks (cell-by-cell walk) and with one global majorant (the textbook
/// Woodcock tracker, ~10³ null collisions per unit length) agree per pixel (Šidák) and in
/// the image mean, nearest and trilinear; the dense voxel is then raised to 10⁶ and 3·10³⁸
/// (nearest), which only the refined tracker can render: all three are the opaque-voxel
/// limit (σt∆l ≥ 125) and agree with each other.
#[test]
fn dense_voxel_refined_blocks_match_the_global_majorant() {
    let cube = |centre: f64| {
        let grid = Grid::new([8, 8, 8], 0.125).unwrap();
        let mut sigma = vec![4.0; grid.len()];
        sigma[grid.index(4, 4, 4)] = centre;
        sigma[grid.index(3, 4, 4)] = centre;
        let n = grid.len();
        Medium::new(grid, sigma, vec![0.9; n], vec![0.0; n]).unwrap()
    };
    let cam = Camera {
        hide_background: false,
        eye: [0.5, -1.2, 0.9],
        target: [0.5, 0.5, 0.5],
        up: [0.0, 0.0, 1.0],
        projection: Projection::Perspective {
            fov_y_degrees: 30.0,
        },
        resolution: [6, 6],
    };
    let scene_of = |centre| scene(cube(centre), Phase::Isotropic, vec![sun()], Some(cam));
    let zmax = sidak_z(36 + 1, FAMILY);
    let compare = |a: &Image, b: &Image, what: &str| -> f64 {
        let mut worst = 0.0f64;
        for i in 0..36 {
            let (x, y) = (
                Estimate {
                    mean: a.mean[i],
                    stderr: a.stderr[i],
                },
                Estimate {
                    mean: b.mean[i],
                    stderr: b.stderr[i],
                },
            );
            assert!(
                x.z_diff(&y).abs() < zmax,
                "{what}, pixel {i}: {x:?} vs {y:?}"
            );
            worst = worst.max(x.z_diff(&y).abs());
        }
        let mean = |m: &Image| {
            let v = m.mean.iter().sum::<f64>() / 36.0;
            let e = m.stderr.iter().map(|s| s * s).sum::<f64>().sqrt() / 36.0;
            Estimate { mean: v, stderr: e }
        };
        let z = mean(a).z_diff(&mean(b));
        assert!(z.abs() < zmax, "{what}, image mean: z = {z}");
        z
    };
    for interp in [Interpolation::Nearest, Interpolation::Trilinear] {
        let s = scene_of(1e3);
        let opts = TraceOptions {
            interpolation: interp,
            ..TraceOptions::default()
        };
        let refined = render_image_with(&s, &settings(256, 11, None), &opts).unwrap();
        let global = render_image_with(
            &s,
            &settings(256, 12, None),
            &TraceOptions {
                majorant_block: 1000,
                refine: false,
                ..opts
            },
        )
        .unwrap();
        compare(&refined, &global, &format!("{interp:?} refined vs global"));
    }
    let opts = TraceOptions::default();
    let thousand = render_image_with(&scene_of(1e3), &settings(256, 13, None), &opts).unwrap();
    let million = render_image_with(&scene_of(1e6), &settings(256, 14, None), &opts).unwrap();
    let huge = render_image_with(&scene_of(3e38), &settings(256, 15, None), &opts).unwrap();
    compare(&million, &huge, "10^6 vs 3e38");
    assert!(huge.mean.iter().all(|v| v.is_finite()));
    // At σt∆l = 125 the voxels are already opaque: 10³ is the limit too.
    compare(&thousand, &huge, "10^3 vs 3e38");
}

/// Track-length fluence of a collimated beam in a purely absorbing box: the voxel average of
/// E e^{−σt·depth}, no collided light.
#[test]
fn fluence_of_an_absorbing_box_is_the_attenuated_beam() {
    let grid = Grid::new([4, 4, 10], 0.1).unwrap();
    let len = grid.len();
    let sigma = 3.0;
    let m = Medium::new(grid, vec![sigma; len], vec![0.0; len], vec![0.0; len]).unwrap();
    let e = 2.0;
    let s = scene(
        m,
        Phase::Isotropic,
        vec![Light::directional([0.0, 0.0, -1.0], e).unwrap()],
        None,
    );
    let f = fluence(&s, &PathSettings::new(40_000, 9)).unwrap();
    assert!((f.source_power - e * 0.4 * 0.4).abs() < 1e-12);
    let zmax = sidak_z(len, FAMILY);
    for idx in 0..len {
        let [_, _, k] = grid.coords(idx);
        let top = 1.0 - (k + 1) as f64 * 0.1;
        let exact = e * ((-sigma * top).exp() - (-sigma * (top + 0.1)).exp()) / (sigma * 0.1);
        let est = Estimate {
            mean: f.total.mean[idx],
            stderr: f.total.stderr[idx],
        };
        assert!(est.z(exact).abs() < zmax, "voxel {idx}: {est:?} vs {exact}");
        assert_eq!(f.collided.mean[idx], 0.0);
    }
}

/// In vacuum, environment plus a sphere light give φ = 4πL_e + (L_s − L_e)·Ω_sphere(x) at
/// every point; voxel averages by 5³-point quadrature.
#[test]
fn fluence_in_vacuum_from_environment_and_sphere() {
    let (le, ls, c, r) = (0.5, 3.0, [0.5, 0.5, -1.0], 0.6);
    let s = scene(
        unit_cube(5, 0.0, 0.0, 0.0),
        Phase::Isotropic,
        vec![
            Light::Environment { radiance: le },
            Light::Sphere {
                center: c,
                radius: r,
                radiance: ls,
            },
        ],
        None,
    );
    let f = fluence(&s, &PathSettings::new(200_000, 4)).unwrap();
    let g = f.grid;
    let zmax = sidak_z(g.len(), FAMILY);
    let phi = |p: [f64; 3]| {
        let d2 = (p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + (p[2] - c[2]).powi(2);
        let omega = 2.0 * std::f64::consts::PI * (1.0 - (1.0 - r * r / d2).sqrt());
        4.0 * std::f64::consts::PI * le + (ls - le) * omega
    };
    for idx in 0..g.len() {
        let [i, j, k] = g.coords(idx);
        let q = 5;
        let mut acc = 0.0;
        for a in 0..q {
            for b in 0..q {
                for cc in 0..q {
                    let off = |n: usize| (n as f64 + 0.5) / q as f64;
                    acc += phi([
                        (i as f64 + off(a)) * g.dl,
                        (j as f64 + off(b)) * g.dl,
                        (k as f64 + off(cc)) * g.dl,
                    ]);
                }
            }
        }
        let exact = acc / (q * q * q) as f64;
        let est = Estimate {
            mean: f.total.mean[idx],
            stderr: f.total.stderr[idx],
        };
        assert!(est.z(exact).abs() < zmax, "voxel {idx}: {est:?} vs {exact}");
    }
}

/// Slab energy balance: R + T_d + T_dir (+ A) = 1 within 3σ, for a conservative slab (A = 0
/// exactly) and an absorbing HG slab.
#[test]
fn slab_conserves_energy() {
    for (tau, c, g, mu0) in [
        (1.0, 1.0, 0.0, 1.0),
        (3.0, 1.0, 0.8, 0.5),
        (2.0, 0.7, 0.5, 0.3),
    ] {
        let phase = if g == 0.0 {
            Phase::Isotropic
        } else {
            Phase::HenyeyGreenstein { g }
        };
        let t = SlabMedium::new(tau, c, phase)
            .unwrap()
            .simulate(mu0, &PathSettings::new(100_000, 1))
            .unwrap();
        assert!(
            t.balance.z(1.0).abs() < 3.0,
            "τ={tau} c={c}: {:?}",
            t.balance
        );
        if c == 1.0 {
            assert_eq!(t.absorptance.mean, 0.0);
            let sum = t.reflectance.mean + t.transmittance_diffuse.mean + t.transmittance_direct;
            assert!((sum - t.balance.mean).abs() < 1e-12);
        }
        assert!((t.transmittance_direct - (-tau / mu0).exp()).abs() < 1e-15);
    }
}

/// Single scattering in an isotropic slab (max_depth 1) against the closed forms
/// R₁ = (c/2)∫₀¹ μ/(μ + μ0)(1 − e^{−τ(1/μ0 + 1/μ)}) dμ and
/// T₁ = (c/2)∫₀¹ μ(e^{−τ/μ} − e^{−τ/μ0})/(μ − μ0) dμ.
#[test]
fn slab_single_scattering_matches_closed_form() {
    let mut cases = Vec::new();
    for (tau, c, mu0) in [(0.5, 0.9, 1.0), (2.0, 0.6, 0.4), (f64::INFINITY, 0.8, 0.7)] {
        let t = SlabMedium::new(tau, c, Phase::Isotropic)
            .unwrap()
            .simulate(
                mu0,
                &PathSettings {
                    max_depth: Some(1),
                    ..PathSettings::new(200_000, 2)
                },
            )
            .unwrap();
        let r1 = 0.5
            * c
            * simpson(
                |m| {
                    if m == 0.0 {
                        0.0
                    } else {
                        m / (m + mu0) * (1.0 - (-tau * (1.0 / mu0 + 1.0 / m)).exp())
                    }
                },
                0.0,
                1.0,
                20_000,
            );
        let t1 = if tau.is_infinite() {
            0.0
        } else {
            0.5 * c
                * simpson(
                    |m| {
                        if m == 0.0 {
                            0.0
                        } else if (m - mu0).abs() < 1e-9 {
                            tau * (-tau / mu0).exp() / mu0 * m
                        } else {
                            m * ((-tau / m).exp() - (-tau / mu0).exp()) / (m - mu0)
                        }
                    },
                    0.0,
                    1.0,
                    20_001,
                )
        };
        cases.push((t.reflectance, r1));
        cases.push((t.transmittance_diffuse, t1));
    }
    let zmax = sidak_z(cases.len(), FAMILY);
    for (e, exact) in cases {
        if exact == 0.0 {
            assert_eq!(e.mean, 0.0);
        } else {
            assert!(e.z(exact).abs() < zmax, "{e:?} vs {exact}");
        }
    }
}

/// Invalid shell edges are named by their index and value: the entry that is wrong, not the
/// first one (issue 13: `0,1,inf` used to blame `edges = 0`).
#[test]
fn bad_shell_edges_name_the_offending_entry() {
    let m = InfiniteMedium::new(0.3, Phase::Isotropic).unwrap();
    let settings = PathSettings::new(1000, 1);
    let cases: [(&[f64], &str); 5] = [
        (
            &[0.0, 1.0, f64::INFINITY],
            "parameter `edges[2]` = inf is invalid: must be finite and ≥ 0",
        ),
        (&[0.0, f64::NAN, 2.0], "`edges[1]` = NaN is invalid"),
        (
            &[-1.0, 1.0],
            "`edges[0]` = -1 is invalid: must be finite and ≥ 0",
        ),
        (
            &[0.0, 2.0, 1.0],
            "`edges[2]` = 1 is invalid: must be greater",
        ),
        (
            &[0.0, 1e300, 1e300],
            "`edges[2]` = 1e300 is invalid: must be greater",
        ),
    ];
    for (edges, want) in cases {
        match m.shells(edges, &settings) {
            Err(e) => assert!(e.to_string().contains(want), "{edges:?}: {e}"),
            Ok(_) => panic!("{edges:?} accepted"),
        }
    }
}

/// Point source in an unbounded medium: with c = 0 the radial density is the ballistic
/// e^{−r} (shell average (e^{−a} − e^{−b})/Δr) and nothing is collided; for c > 0 the
/// uncollided part still is; and every path is eventually absorbed, so
/// (1 − c)·∫4πr²φ dr = 1 (one shell out to 2000 mean free paths).
#[test]
fn point_source_ballistic_part_and_absorption() {
    let edges = [0.0, 0.1, 0.3, 0.6, 1.0, 1.5, 2.5, 4.0];
    let mut checks = Vec::new();
    for c in [0.0, 0.5, 0.9] {
        let sh = InfiniteMedium::new(c, Phase::Isotropic)
            .unwrap()
            .shells(&edges, &PathSettings::new(100_000, 6))
            .unwrap();
        for s in &sh {
            let exact = ((-s.r_inner).exp() - (-s.r_outer).exp()) / (s.r_outer - s.r_inner);
            checks.push((s.uncollided, exact));
            if c == 0.0 {
                assert_eq!(s.collided.mean, 0.0);
                checks.push((s.radial_density, exact));
            }
        }
        let all = InfiniteMedium::new(c, Phase::HenyeyGreenstein { g: 0.6 })
            .unwrap()
            .shells(&[0.0, 2000.0], &PathSettings::new(40_000, 7))
            .unwrap();
        let absorbed = Estimate {
            mean: (1.0 - c) * 2000.0 * all[0].radial_density.mean,
            stderr: (1.0 - c) * 2000.0 * all[0].radial_density.stderr,
        };
        checks.push((absorbed, 1.0));
    }
    let zmax = sidak_z(checks.len(), FAMILY);
    for (e, exact) in checks {
        assert!(e.z(exact).abs() < zmax, "{e:?} vs {exact}");
    }
}

#[test]
fn bad_inputs_are_typed_errors() {
    let s = scene(
        unit_cube(4, 1.0, 0.5, 0.0),
        Phase::Isotropic,
        vec![sun()],
        None,
    );
    assert_eq!(
        render_image(&s, &settings(16, 0, None)),
        Err(crate::ReferenceError::NoCamera)
    );
    let s = scene(
        unit_cube(4, 1.0, 0.5, 0.0),
        Phase::Isotropic,
        vec![sun()],
        Some(top_camera(2, 1.0)),
    );
    assert!(matches!(
        render_image(
            &s,
            &RenderSettings {
                batches: 4,
                ..settings(16, 0, None)
            }
        ),
        Err(crate::ReferenceError::TooFewBatches { .. })
    ));
    assert!(render_image(&s, &settings(8, 0, None)).is_err());
    let mut bad = s.clone();
    bad.phase = Phase::HenyeyGreenstein { g: 1.0 };
    assert!(matches!(
        render_image(&bad, &settings(16, 0, None)),
        Err(crate::ReferenceError::Scene(_))
    ));
    let dark = scene(unit_cube(4, 1.0, 0.5, 0.0), Phase::Isotropic, vec![], None);
    assert!(fluence(&dark, &PathSettings::new(100, 0)).is_err());
    assert!(InfiniteMedium::new(1.0, Phase::Isotropic).is_err());
    let m = InfiniteMedium::new(0.5, Phase::Isotropic).unwrap();
    assert!(
        m.shells(&[0.0, 1.0, 1.0], &PathSettings::new(100, 0))
            .is_err()
    );
    assert!(m.shells(&[1.0], &PathSettings::new(100, 0)).is_err());
    assert!(SlabMedium::new(f64::INFINITY, 1.0, Phase::Isotropic).is_err());
    assert!(SlabMedium::new(-1.0, 0.5, Phase::Isotropic).is_err());
    let slab = SlabMedium::new(1.0, 0.5, Phase::Isotropic).unwrap();
    assert!(slab.simulate(0.0, &PathSettings::new(100, 0)).is_err());
    assert!(slab.simulate(0.5, &PathSettings::new(10, 0)).is_err());
}

/// Acceptance (CI size): shell averages of 4πr²φ around a point source, isotropic
/// scattering, c ∈ {0.3, 0.7, 0.9, 0.99}, total and collided, against the exact
/// Case–Zweifel solution ([`crate::transport::point::ExactPointSource`]), every shell within
/// a Šidák 3σ-family band. The same tallies are many standard errors away from Grosjean's
/// approximation (FLD Eq 24), so the check can tell transport from a good approximation.
#[test]
fn point_source_shells_match_the_exact_solution() {
    use crate::transport::point::ExactPointSource;
    let edges = [0.0, 0.1, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 5.0];
    let albedos = [0.3, 0.7, 0.9, 0.99];
    let mut checks = Vec::new();
    let mut z_grosjean: f64 = 0.0;
    for (k, &c) in albedos.iter().enumerate() {
        let exact = ExactPointSource::new(c).unwrap();
        let shells = InfiniteMedium::new(c, Phase::Isotropic)
            .unwrap()
            .shells(&edges, &PathSettings::new(100_000, 20 + k as u64))
            .unwrap();
        for s in &shells {
            let (total, collided) = exact.shell_average(s.r_inner, s.r_outer);
            checks.push((c, s.r_inner, s.radial_density, total));
            checks.push((c, s.r_inner, s.collided, collided));
            let g = simpson(
                |r| r * r * crate::point_source::grosjean(r, c),
                s.r_inner,
                s.r_outer,
                2000,
            ) / (s.r_outer - s.r_inner);
            z_grosjean = z_grosjean.max(s.radial_density.z(g).abs());
        }
    }
    let zmax = sidak_z(checks.len(), FAMILY);
    for (c, r, e, exact) in &checks {
        assert!(
            e.z(*exact).abs() < zmax,
            "c={c} shell at r={r}: {e:?} vs exact {exact} (z = {:.2})",
            e.z(*exact)
        );
    }
    assert!(
        z_grosjean > 3.0 * zmax,
        "Grosjean is only {z_grosjean} standard errors away"
    );
}

/// Acceptance (CI size): slab R and T_d for c ∈ {0.5, 0.9, 0.99}, g ∈ {0, 0.5, 0.9},
/// τ ∈ {1, ∞}, μ0 = 0.6, against the adding–doubling solver
/// ([`crate::transport::slab::Slab`]) and, for isotropic half-spaces, against Chandrasekhar's
/// plane albedo 1 − √(1 − c)H(μ0) ([`crate::transport::hfunction::plane_albedo`]); all within
/// a Šidák 3σ-family band.
#[test]
fn slab_matches_adding_doubling_and_h_function() {
    use crate::transport::hfunction::plane_albedo;
    use crate::transport::slab::Slab;
    let mu0 = 0.6;
    let mut checks = Vec::new();
    let mut seed = 40;
    for tau in [1.0, f64::INFINITY] {
        for g in [0.0, 0.5, 0.9] {
            for c in [0.5, 0.9, 0.99] {
                let phase = if g == 0.0 {
                    Phase::Isotropic
                } else {
                    Phase::HenyeyGreenstein { g }
                };
                seed += 1;
                let mc = SlabMedium::new(tau, c, phase)
                    .unwrap()
                    .simulate(mu0, &PathSettings::new(60_000, seed))
                    .unwrap();
                let exact = Slab::new(tau, c, g).unwrap().solve(mu0).unwrap();
                assert!((exact.transmittance_direct - mc.transmittance_direct).abs() < 1e-15);
                checks.push((tau, g, c, "R", mc.reflectance, exact.reflectance));
                if tau.is_finite() {
                    checks.push((
                        tau,
                        g,
                        c,
                        "T_d",
                        mc.transmittance_diffuse,
                        exact.transmittance_diffuse,
                    ));
                } else {
                    assert_eq!(mc.transmittance_diffuse.mean, 0.0);
                    if g == 0.0 {
                        let h = plane_albedo(c, mu0).unwrap();
                        checks.push((tau, g, c, "R (H-function)", mc.reflectance, h));
                    }
                }
            }
        }
    }
    let zmax = sidak_z(checks.len(), FAMILY);
    for (tau, g, c, what, e, exact) in &checks {
        assert!(
            e.z(*exact).abs() < zmax,
            "τ={tau} g={g} c={c} {what}: {e:?} vs {exact} (z = {:.2})",
            e.z(*exact)
        );
    }
}
