//! Issue 14's homogeneous cube (`scenes/dense_voxel.toml` with `centre_sigma_t = 4`: σt = 4
//! filling the unit box, albedo 0.9, isotropic, directional light (0.3, 0.4, −1) of
//! irradiance 2, orthographic camera of width 1.1 looking along +y) by scattering order,
//! against an **independent** estimator that shares no tracking code with the path tracer.
//!
//! The independent estimator is an analog light tracer with exact exponential free paths in
//! the homogeneous cube (no majorants, no DDA, no camera): photons enter through the three
//! lit faces (z = 1, x = 0, y = 0) in proportion to their projected areas, carry power
//! P = E·(|dx| + |dy| + |dz|) (unit faces), are multiplied by the albedo at each collision
//! (implicit capture) and, at each collision, score the point-detector estimate of the
//! radiant intensity towards −y, w·p(·)·exp(−σt·y) with p = 1/4π (the exit along −y is
//! always through the face y = 0, at distance y). The radiant intensity I(−y) of the cube
//! is ∫ L(x, z, −y) dA over the face y = 0, so the image mean of the orthographic camera,
//! whose film covers 1.1 × 1.1 around the face, is I / 1.21. Order n tallies photons with
//! exactly n collisions; paths are cut after 400 collisions (remaining weight ≤ 0.9⁴⁰⁰ ≈ 5e-19
//! of the power).
//!
//! Measured here (the analog tracer, 2²² photons) against the path tracer and Mitsuba
//! 3.9.1: see `reference/src/mitsuba.rs`, "Homogeneous cube at high orders".
#![allow(clippy::unwrap_used, clippy::expect_used)]

use rayon::prelude::*;
use reference::pathtracer::rng::Rng;
use reference::pathtracer::{Contributions, RenderSettings, render_image};
use solvers::scene::{Camera, Light, Phase, Projection, Sampler, Scene};
use solvers::{Grid, Medium};
use std::f64::consts::PI;

const SIGMA_T: f64 = 4.0;
const ALBEDO: f64 = 0.9;
const LIGHT: [f64; 3] = [0.3, 0.4, -1.0];
const IRRADIANCE: f64 = 2.0;
const WIDTH: f64 = 1.1;
/// Orders tallied one by one; everything above goes into the last bin.
const MAX_ORDER: usize = 400;

/// The cube scene of `scenes/dense_voxel.toml` with a homogeneous σt.
fn cube_scene(centre: f64, resolution: usize) -> Scene {
    let grid = Grid::cube(N, 1.0).unwrap();
    let mut medium = Medium::homogeneous(grid, SIGMA_T, ALBEDO).unwrap();
    medium.sigma_t[grid.index(N / 2, N / 2, N / 2)] = centre;
    Scene {
        interpolation: Default::default(),
        medium,
        phase: Phase::Isotropic,
        lights: vec![Light::directional(LIGHT, IRRADIANCE).unwrap()],
        camera: Some(Camera {
            hide_background: false,
            eye: [0.5, -1.5, 0.5],
            target: [0.5, 0.5, 0.5],
            up: [0.0, 0.0, 1.0],
            projection: Projection::Orthographic { width: WIDTH },
            resolution: [resolution; 2],
        }),
        sampler: Sampler { spp: 64, seed: 4 },
    }
}

/// Per-order image-mean contributions from the analog light tracer: `(mean, stderr)` of
/// the cumulative image mean for orders 1..=k, for each k in `orders` (`u32::MAX`: all).
fn analog_cube(centre: f64, photons: u64, seed: u64, orders: &[u32]) -> Vec<(f64, f64)> {
    let cube = Cube::new(centre);
    let len = (LIGHT[0] * LIGHT[0] + LIGHT[1] * LIGHT[1] + LIGHT[2] * LIGHT[2]).sqrt();
    let d = LIGHT.map(|v| v / len);
    let proj = d.map(f64::abs);
    let power = IRRADIANCE * (proj[0] + proj[1] + proj[2]);
    // Per photon: for each tallied k, the photon's cumulative score; sums and sums of squares.
    let per_chunk = 1u64 << 12;
    let chunks = photons.div_ceil(per_chunk);
    let k = orders.len();
    let partial: Vec<(Vec<f64>, Vec<f64>)> = (0..chunks)
        .into_par_iter()
        .map(|c| {
            let mut sum = vec![0.0; k];
            let mut sum_sq = vec![0.0; k];
            let mut by_order = vec![0.0; MAX_ORDER + 1];
            for i in c * per_chunk..((c + 1) * per_chunk).min(photons) {
                let mut rng = Rng::new(seed, i);
                by_order.iter_mut().for_each(|v| *v = 0.0);
                trace_photon(&cube, &mut rng, d, proj, power, &mut by_order);
                for (j, &o) in orders.iter().enumerate() {
                    let top = (o as usize).min(MAX_ORDER);
                    let s: f64 = by_order[1..=top].iter().sum();
                    sum[j] += s;
                    sum_sq[j] += s * s;
                }
            }
            (sum, sum_sq)
        })
        .collect();
    let n = photons as f64;
    (0..k)
        .map(|j| {
            let s: f64 = partial.iter().map(|p| p.0[j]).sum();
            let s2: f64 = partial.iter().map(|p| p.1[j]).sum();
            let mean = s / n;
            let var = (s2 / n - mean * mean).max(0.0) * n / (n - 1.0);
            let area = WIDTH * WIDTH;
            (mean / area, (var / n).sqrt() / area)
        })
        .collect()
}

/// The cube's piecewise-constant σt: `N³` voxels of [`SIGMA_T`], the voxel (N/2, N/2, N/2)
/// of `centre` (the `dense_voxel` generator's layout, written here independently).
struct Cube {
    sigma: Vec<f64>,
}

/// Voxels per axis.
const N: usize = 8;

impl Cube {
    fn new(centre: f64) -> Self {
        let mut sigma = vec![SIGMA_T; N * N * N];
        let c = N / 2;
        sigma[c + N * (c + N * c)] = centre;
        Self { sigma }
    }

    fn at(&self, i: usize, j: usize, k: usize) -> f64 {
        self.sigma[i + N * (j + N * k)]
    }

    /// Optical depth from `x` straight down −y to the face y = 0 (one voxel column).
    fn depth_to_front(&self, x: [f64; 3]) -> f64 {
        let cell = |v: f64| ((v * N as f64).floor() as usize).min(N - 1);
        let (i, j0, k) = (cell(x[0]), cell(x[1]), cell(x[2]));
        let h = 1.0 / N as f64;
        let below: f64 = (0..j0).map(|j| self.at(i, j, k) * h).sum();
        below + self.at(i, j0, k) * (x[1] - j0 as f64 * h)
    }

    /// Exact free flight: walks the voxels from `x` along `dir` spending optical depth
    /// `tau`; the collision point, or `None` when the photon leaves the cube first.
    fn fly(&self, x: [f64; 3], dir: [f64; 3], mut tau: f64) -> Option<[f64; 3]> {
        let nf = N as f64;
        let mut cell = [0usize; 3];
        let mut next = [f64::INFINITY; 3];
        let mut step = [0.0f64; 3];
        for a in 0..3 {
            let c = ((x[a] * nf).floor().max(0.0) as usize).min(N - 1);
            cell[a] = c;
            if dir[a] > 0.0 {
                next[a] = ((c + 1) as f64 / nf - x[a]) / dir[a];
                step[a] = 1.0 / (nf * dir[a]);
            } else if dir[a] < 0.0 {
                next[a] = (c as f64 / nf - x[a]) / dir[a];
                step[a] = -1.0 / (nf * dir[a]);
            }
        }
        let mut t = 0.0;
        loop {
            let a = (0..3)
                .min_by(|&p, &q| next[p].total_cmp(&next[q]))
                .unwrap_or(0);
            let t_out = next[a].max(t);
            let sigma = self.at(cell[0], cell[1], cell[2]);
            let seg = sigma * (t_out - t);
            if seg >= tau {
                let s = t + tau / sigma;
                return Some([0, 1, 2].map(|b| x[b] + s * dir[b]));
            }
            tau -= seg;
            t = t_out;
            if dir[a] > 0.0 {
                if cell[a] + 1 == N {
                    return None;
                }
                cell[a] += 1;
            } else {
                if cell[a] == 0 {
                    return None;
                }
                cell[a] -= 1;
            }
            next[a] += step[a];
        }
    }
}

/// One analog photon; adds its point-detector scores (radiant intensity towards −y) to
/// `by_order[n]` for the collision of order n.
fn trace_photon(
    cube: &Cube,
    rng: &mut Rng,
    d: [f64; 3],
    proj: [f64; 3],
    power: f64,
    by_order: &mut [f64],
) {
    // Entry face in proportion to |d·n|: x = 0, y = 0 or z = 1.
    let u = rng.uniform() * (proj[0] + proj[1] + proj[2]);
    let (a, b) = (rng.uniform(), rng.uniform());
    let mut x = if u < proj[0] {
        [0.0, a, b]
    } else if u < proj[0] + proj[1] {
        [a, 0.0, b]
    } else {
        [a, b, 1.0]
    };
    let mut dir = d;
    let mut w = power;
    for slot in by_order.iter_mut().skip(1) {
        let tau = -(1.0 - rng.uniform()).ln();
        let Some(p) = cube.fly(x, dir, tau) else {
            return;
        };
        x = p;
        w *= ALBEDO;
        *slot += w / (4.0 * PI) * (-cube.depth_to_front(x)).exp();
        let cos = 2.0 * rng.uniform() - 1.0;
        let phi = 2.0 * PI * rng.uniform();
        let sin = (1.0 - cos * cos).max(0.0).sqrt();
        dir = [sin * phi.cos(), sin * phi.sin(), cos];
    }
}

/// The path tracer's image mean and its standard error (pixels independent).
fn ours(centre: f64, spp: u32, contributions: Contributions) -> (f64, f64) {
    let scene = cube_scene(centre, 16);
    let img = render_image(
        &scene,
        &RenderSettings {
            spp,
            seed: 11,
            batches: 16,
            contributions,
        },
    )
    .unwrap();
    let n = img.mean.len() as f64;
    let mean = img.mean.iter().sum::<f64>() / n;
    let se = img.stderr.iter().map(|s| s * s).sum::<f64>().sqrt() / n;
    (mean, se)
}

/// The path tracer (camera paths, delta tracking on its majorant grid, NEE to the light)
/// against the analog light tracer (photons from the light, exact free paths, point
/// detector) order by order (≤ 1, ≤ 2, ≤ 8 and all orders), within 4 combined standard
/// errors: two independent estimators of the same integral.
#[test]
fn path_tracer_matches_an_independent_analog_light_tracer_by_order() {
    let orders = [1, 2, 8, u32::MAX];
    let analog = analog_cube(SIGMA_T, 1 << 20, 3, &orders);
    for (&k, &(a, a_se)) in orders.iter().zip(&analog) {
        let c = if k == u32::MAX {
            Contributions::all()
        } else {
            Contributions::up_to(k)
        };
        let (o, o_se) = ours(SIGMA_T, 512, c);
        let z = (o - a) / (o_se * o_se + a_se * a_se).sqrt();
        eprintln!("orders ≤ {k}: ours {o:.6} ± {o_se:.6}, analog {a:.6} ± {a_se:.6}, z {z:+.2}");
        assert!(z.abs() < 4.0, "orders ≤ {k}: z = {z}");
        // Power: the comparison resolves the gap Mitsuba shows (1.2 % at all orders).
        let se = (o_se * o_se + a_se * a_se).sqrt();
        assert!(se < 0.0035 * a, "too noisy to resolve 1 %: {se}");
    }
}

/// The measurement behind the documented numbers (not a check: prints the analog tracer's
/// cumulative orders at 2²³ photons and the path tracer's at 1024 spp, for centre σt from
/// `CUBE_CENTRE`, default 4).
#[test]
#[ignore = "measurement: cargo test --release -p reference --test cube_orders -- --ignored --nocapture"]
fn measure_orders() {
    let centre = std::env::var("CUBE_CENTRE")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(SIGMA_T);
    let orders = [1, 2, 4, 8, 16, 29, u32::MAX];
    let analog = analog_cube(centre, 1 << 23, 7, &orders);
    for (&k, &(a, a_se)) in orders.iter().zip(&analog) {
        eprintln!("centre {centre}: analog orders <= {k}: {a:.6} +- {a_se:.6}");
    }
    let (o, o_se) = ours(centre, 1024, Contributions::all());
    eprintln!("centre {centre}: ours all orders 1024 spp: {o:.6} +- {o_se:.6}");
}

/// Issue 14's dense centre voxel (σt = 1000 in the σt = 4 cube) in Mitsuba 3 as
/// `reference::mitsuba` exports it (global majorant 1000, ~250 null collisions per real one)
/// agrees with the analog light tracer within 4 standard errors. Before the export set
/// `rr_depth` (Mitsuba's default 5: Russian roulette at every null collision) this failed:
/// Mitsuba gave 0.10381 ± 0.00051 at 256 spp against the analog 0.10927 ± 0.00005. The image
/// mean does not depend on the resolution, so 4×4 pixels keep Mitsuba's cost down.
#[test]
fn mitsuba_without_russian_roulette_matches_the_analog_tracer_on_the_dense_voxel() {
    let Some(cfg) = reference::mitsuba::MitsubaConfig::available_or_skip("scalar_rgb").unwrap()
    else {
        return;
    };
    let centre = 1000.0;
    let scene = cube_scene(centre, 4);
    let settings = reference::mitsuba::MitsubaSettings {
        spp: 128,
        renders: 8,
        seed: 9,
        max_depth: None,
        keep_dir: None,
        timeout: None,
    };
    let r = reference::mitsuba::render(&scene, &settings, &cfg).unwrap();
    let n = r.image.mean.len() as f64;
    let m = r.image.mean.iter().sum::<f64>() / n;
    // The K renders are independent: the image mean's error from the per-pixel errors
    // understates nothing (pixels of one render are independent paths).
    let m_se = r.image.stderr.iter().map(|s| s * s).sum::<f64>().sqrt() / n;
    let (a, a_se) = analog_cube(centre, 1 << 20, 5, &[u32::MAX])[0];
    let z = (m - a) / (m_se * m_se + a_se * a_se).sqrt();
    eprintln!("dense voxel: Mitsuba {m:.6} ± {m_se:.6}, analog {a:.6} ± {a_se:.6}, z {z:+.2}");
    assert!(
        z.abs() < 4.0,
        "Mitsuba {m} ± {m_se} vs analog {a} ± {a_se}: z = {z}"
    );
    assert!(
        m_se < 0.01 * a,
        "too noisy to resolve the 5 % deficit: {m_se}"
    );
}
