//! Procedural media used by the tests, the experiments and the benchmarks.

use crate::noise::{Perlin, SplitMix64};
use crate::{Grid, Medium, Real, SolverError};

/// FLD Section 6.1's point source: a cube of `n³` voxels (n odd) and extent 1, homogeneous
/// extinction σt = `tau_extent` (so the grid is `tau_extent` mean free paths across), albedo
/// `albedo`, and one emitting voxel at the centre with j = 1/Δl³ (a unit-power source).
///
/// Returns the medium and the centre voxel's coordinates.
pub fn point_source<T: Real>(
    n: usize,
    tau_extent: f64,
    albedo: f64,
) -> Result<(Medium<T>, [usize; 3]), SolverError> {
    if n % 2 == 0 {
        return Err(SolverError::BadParameter {
            name: "n",
            value: n as f64,
            reason: "the point source needs an odd grid so that one voxel sits at the centre",
        });
    }
    if !(tau_extent.is_finite() && tau_extent > 0.0) {
        return Err(SolverError::BadParameter {
            name: "tau_extent",
            value: tau_extent,
            reason: "must be finite and > 0",
        });
    }
    let grid = Grid::cube(n, 1.0)?;
    let mut m = Medium::homogeneous(grid, tau_extent, albedo)?;
    let c = n / 2;
    m.emission[grid.index(c, c, c)] = T::c(1.0 / grid.dl.powi(3));
    Ok((m, [c, c, c]))
}

/// The test case of FLD Fig 4: a spherical cloud in vacuum with internal emission from
/// Perlin noise. The paper gives no numbers; ours (documented here, used everywhere) are:
/// unit cube, cloud radius 0.35 centred, σt = 20 inside (optical diameter 14) and 0 outside,
/// albedo 0.9 inside, emission j = max(0, 0.5 + fbm(4x, 3 octaves)) inside and 0 outside.
pub fn vacuum_cloud<T: Real>(n: usize, seed: u64) -> Result<Medium<T>, SolverError> {
    let grid = Grid::cube(n, 1.0)?;
    let noise = Perlin::new(seed);
    let inside = |p: [f64; 3]| {
        (p[0] - 0.5).powi(2) + (p[1] - 0.5).powi(2) + (p[2] - 0.5).powi(2) <= 0.35 * 0.35
    };
    let sigma_t = grid.sample(|p| T::c(if inside(p) { 20.0 } else { 0.0 }));
    let albedo = grid.sample(|p| T::c(if inside(p) { 0.9 } else { 0.0 }));
    let emission = grid.sample(|p| {
        T::c(if inside(p) {
            (0.5 + noise.fbm(p.map(|x| 4.0 * x), 3)).max(0.0)
        } else {
            0.0
        })
    });
    Medium::new(grid, sigma_t, albedo, emission)
}

/// The point source's medium ([`point_source`]: unit cube, σt = `tau_extent`, `albedo`) with
/// its unit power spread evenly over the voxels whose centres lie within `radius` of the
/// centre voxel's, instead of one voxel: a source of fixed physical size, so that the
/// discrete problems converge to one continuous problem as n grows (the one-voxel source's
/// j = 1/Δl³ sharpens with n). The control of `multigrid_scaling`'s grid-independence runs.
pub fn ball_source<T: Real>(
    n: usize,
    tau_extent: f64,
    albedo: f64,
    radius: f64,
) -> Result<Medium<T>, SolverError> {
    let (mut m, c) = point_source::<T>(n, tau_extent, albedo)?;
    if !(radius.is_finite() && radius > 0.0) {
        return Err(SolverError::BadParameter {
            name: "radius",
            value: radius,
            reason: "must be finite and > 0",
        });
    }
    let g = m.grid;
    let centre = g.center(c[0], c[1], c[2]);
    let inside = |p: usize| {
        let [i, j, k] = g.coords(p);
        let q = g.center(i, j, k);
        (0..3).map(|a| (q[a] - centre[a]).powi(2)).sum::<f64>() <= radius * radius
    };
    let ball: Vec<usize> = (0..g.len()).filter(|&p| inside(p)).collect();
    let j = T::c(1.0 / (ball.len() as f64 * g.dl.powi(3)));
    m.emission.fill(T::zero());
    for p in ball {
        m.emission[p] = j;
    }
    Ok(m)
}

/// FLD Fig 4's cloud ([`vacuum_cloud`]) with its vacuum filled by a thin medium of
/// extinction `sigma_t` and albedo 0.9: the control that tells what vacuum (where FLD's
/// D → φ/|∇φ| and its equation stops being elliptic) does to a solver's convergence.
pub fn cloud_in_thin_medium<T: Real>(
    n: usize,
    seed: u64,
    sigma_t: f64,
) -> Result<Medium<T>, SolverError> {
    if !(sigma_t.is_finite() && sigma_t > 0.0) {
        return Err(SolverError::BadParameter {
            name: "sigma_t",
            value: sigma_t,
            reason: "must be finite and > 0",
        });
    }
    let mut m = vacuum_cloud::<T>(n, seed)?;
    for (s, a) in m.sigma_t.iter_mut().zip(m.albedo.iter_mut()) {
        if *s == T::zero() {
            *s = T::c(sigma_t);
            *a = T::c(0.9);
        }
    }
    Ok(m)
}

/// A random heterogeneous medium for conformance and stress tests: per voxel, with
/// probability `vacuum_fraction` vacuum (σt = 0), otherwise σt log-uniform in
/// [0.1, 1000]/L; albedo uniform in [0, 1] with 10 % of voxels exactly 1; emission log-uniform
/// in [10⁻³, 10³] in 5 % of voxels, 0 elsewhere.
pub fn random_heterogeneous<T: Real>(
    n: [usize; 3],
    seed: u64,
    vacuum_fraction: f64,
) -> Result<Medium<T>, SolverError> {
    let grid = Grid::new(n, 1.0 / n[0] as f64)?;
    let l = grid.extent();
    let mut rng = SplitMix64::new(seed);
    let len = grid.len();
    let (mut sigma_t, mut albedo, mut emission) = (
        Vec::with_capacity(len),
        Vec::with_capacity(len),
        Vec::with_capacity(len),
    );
    for _ in 0..len {
        let vac = rng.next_f64() < vacuum_fraction;
        let s = 10f64.powf(-1.0 + 4.0 * rng.next_f64()) / l;
        sigma_t.push(T::c(if vac { 0.0 } else { s }));
        let a = rng.next_f64();
        albedo.push(T::c(if rng.next_f64() < 0.1 { 1.0 } else { a }));
        let e = 10f64.powf(-3.0 + 6.0 * rng.next_f64());
        emission.push(T::c(if rng.next_f64() < 0.05 { e } else { 0.0 }));
    }
    Medium::new(grid, sigma_t, albedo, emission)
}

/// Issue 12's albedo-1 cube: an `n`³ homogeneous unit cube with σt·Δl = `tau` per voxel,
/// albedo 1, isotropic, lit by a directional light of irradiance 3 from (0.4, 0.5, −1) (the
/// convergence and default-stop checks).
pub fn lit_albedo1_cube(
    n: usize,
    tau: f64,
) -> Result<crate::scene::Scene, crate::scene::SceneFileError> {
    let text = format!(
        r#"
format = 1
[medium]
generator = "homogeneous"
params = {{ n = {n}, extent = 1.0, sigma_t = {}, albedo = 1.0 }}
[[light]]
type = "directional"
direction = [0.4, 0.5, -1.0]
irradiance = 3.0
"#,
        tau * n as f64
    );
    let file = crate::scene::SceneFile::parse(
        &text,
        std::path::Path::new("."),
        std::path::Path::new("cube.toml"),
    )?;
    Ok(file.scene)
}
