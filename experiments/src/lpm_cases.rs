//! The LPM accuracy cases of spec §5/§6 (T9–T12 and the ray-effect case), shared by the
//! `lpm_accuracy` experiment and the tests in `experiments/tests/lpm_accuracy.rs`. Every
//! case runs `solvers::lpm::solve` on the CPU in f64 and compares with an independent
//! reference: a surface quadrature of the uncollided fluence (T9), adding–doubling (T10),
//! the exact Case–Zweifel point source (T11), the path tracer restricted to the same
//! scattering orders (T12), and for the collimated beam of spec §5 (a) ([`beam_case`]) the
//! exact uncollided beam and an exact single-scattering quadrature.
//!
//! **Collimated beam, the geometry (a decision where the spec is silent).** The spec asks
//! for a beam 1 voxel wide, but `BoundaryLight` is uniform over the boundary. The beam is
//! therefore cut by the medium: a black one-voxel shell (σt·h = [`BEAM_MASK_SIGMA_T_H`],
//! albedo 0) with a vacuum hole in its top layer, so every path into the interior but those
//! through the hole crosses at least one whole black voxel (e^{−500}). The exact fields then
//! follow from geometry alone. Two consequences, measured: a tilted beam loses the fraction
//! tan θ of the hole's width on its walls (exact) while LPM's one ray per face cell passes
//! whole, so the order-0 power of the 10° rows is +21…+23 % (1/(1 − tan 10°) − 1 = +21 %),
//! which also enters their order-1 numbers; and centroids are voxel-quantised, so the offset
//! matches its snap prediction to ≤ √2/2 voxel. Spec §5 (a) asks 64³; the case runs 32³
//! (2 orders, 12 solves in 6.6 s under load) to stay within the experiment's time.

use anyhow::{Context, Result, bail};
use rayon::prelude::*;
use reference::pathtracer::{PathSettings, fluence};
use reference::transport::point::ExactPointSource;
use reference::transport::slab::Slab;
use serde::Serialize;
use solvers::lpm::{self, BoundaryLight, Directions, LpmConfig, LpmSolution, Orders, WrapBc};
use solvers::scene::generators::{Generator, NoiseCloud};
use solvers::scene::{Light, Phase, Sampler, Scene};
use solvers::{Backend, Grid, Medium, Precision};
use std::f64::consts::PI;
use std::time::Instant;

/// Gauss–Legendre nodes and weights on [−1, 1] (Newton on P_n from the Chebyshev guess).
pub fn gauss_legendre(n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut x = vec![0.0; n];
    let mut w = vec![0.0; n];
    for i in 0..n.div_ceil(2) {
        let mut z = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            let (mut p0, mut p1) = (1.0, z);
            for k in 2..=n {
                let p2 = ((2 * k - 1) as f64 * z * p1 - (k - 1) as f64 * p0) / k as f64;
                p0 = p1;
                p1 = p2;
            }
            let pn = if n == 1 { z } else { p1 };
            let pm = if n == 1 { 1.0 } else { p0 };
            dp = n as f64 * (z * pn - pm) / (z * z - 1.0);
            let dz = pn / dp;
            z -= dz;
            if dz.abs() < 1e-15 {
                break;
            }
        }
        x[i] = -z;
        x[n - 1 - i] = z;
        w[i] = 2.0 / ((1.0 - z * z) * dp * dp);
        w[n - 1 - i] = w[i];
    }
    (x, w)
}

/// Exponential integral E_n(x), x > 0, n ≥ 1 (series for x ≤ 1, continued fraction above);
/// E_n(0) = 1/(n − 1) for n ≥ 2.
pub fn expint(n: usize, x: f64) -> f64 {
    const EULER: f64 = 0.577_215_664_901_532_9;
    if x == 0.0 {
        return if n >= 2 {
            1.0 / (n - 1) as f64
        } else {
            f64::INFINITY
        };
    }
    let nm1 = n as f64 - 1.0;
    if x > 1.0 {
        // Modified Lentz on the continued fraction of e^{x} E_n(x).
        let tiny = 1e-300;
        let mut b = x + n as f64;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..1000 {
            let a = -(i as f64) * (nm1 + i as f64);
            b += 2.0;
            d = 1.0 / (a * d + b);
            c = b + a / c;
            let del = c * d;
            h *= del;
            if (del - 1.0).abs() < 1e-16 {
                break;
            }
        }
        return h * (-x).exp();
    }
    let mut ans = if n == 1 { -x.ln() - EULER } else { 1.0 / nm1 };
    let mut fact = 1.0;
    for i in 1..1000 {
        fact *= -x / i as f64;
        let del = if (i as f64) != nm1 {
            -fact / (i as f64 - nm1)
        } else {
            let psi = -EULER + (1..n).map(|k| 1.0 / k as f64).sum::<f64>();
            fact * (-x.ln() + psi)
        };
        ans += del;
        if del.abs() < ans.abs() * 1e-17 {
            break;
        }
    }
    ans
}

/// One LPM solve on the CPU in f64.
pub fn solve(
    medium: &Medium<f64>,
    boundary: &BoundaryLight,
    config: &LpmConfig,
) -> Result<LpmSolution<f64>> {
    lpm::solve(
        &Backend::Cpu(Precision::F64),
        medium,
        boundary,
        config,
        |_, _| {},
    )
    .with_context(|| format!("LPM solve (m = {}, grid {:?})", config.m, medium.grid.n))
}

/// Least-squares slope of ln y against ln x, negated: the order p of y ∝ x^{−p}.
pub fn fitted_order(points: &[(f64, f64)]) -> f64 {
    let n = points.len() as f64;
    let (sx, sy) = points
        .iter()
        .fold((0.0, 0.0), |(a, b), &(x, y)| (a + x.ln(), b + y.ln()));
    let (mx, my) = (sx / n, sy / n);
    let (num, den) = points.iter().fold((0.0, 0.0), |(a, b), &(x, y)| {
        let dx = x.ln() - mx;
        (a + dx * (y.ln() - my), b + dx * dx)
    });
    -num / den
}

// ---------------------------------------------------------------------------------------
// T9: order 1 under uniform light.

/// Uncollided fluence ∫L e^{−σt ℓ(p,−ω)}dω at p inside the cube [0, a]³ for L = 1, as a sum
/// over the six faces of ∫ e^{−σt r} d/r³ dA, each face split into four rectangles at the
/// foot of p and integrated in u = d sinh s, v = d sinh t by `q`-point Gauss–Legendre (a
/// smooth integrand; with σt = 0 the sum is 4π, checked by the test).
pub fn uncollided_uniform(p: [f64; 3], a: f64, sigma_t: f64, gl: &(Vec<f64>, Vec<f64>)) -> f64 {
    let (xs, ws) = gl;
    let mut total = 0.0;
    for axis in 0..3 {
        let (b, c) = ((axis + 1) % 3, (axis + 2) % 3);
        for d in [p[axis], a - p[axis]] {
            for ue in [p[b], a - p[b]] {
                for ve in [p[c], a - p[c]] {
                    let (s1, t1) = ((ue / d).asinh(), (ve / d).asinh());
                    let mut sum = 0.0;
                    for (xi, wi) in xs.iter().zip(ws) {
                        let s = 0.5 * s1 * (xi + 1.0);
                        let (sh, ch) = (s.sinh(), s.cosh());
                        for (xj, wj) in xs.iter().zip(ws) {
                            let t = 0.5 * t1 * (xj + 1.0);
                            let (th, cht) = (t.sinh(), t.cosh());
                            let q = (1.0 + sh * sh + th * th).sqrt();
                            sum += wi * wj * (-sigma_t * d * q).exp() * ch * cht / (q * q * q);
                        }
                    }
                    total += sum * 0.25 * s1 * t1;
                }
            }
        }
    }
    total
}

/// One m of T9.
#[derive(Debug, Clone, Serialize)]
pub struct Order1Row {
    /// Cells per face edge.
    pub m: usize,
    /// Propagation directions 6m².
    pub directions: usize,
    /// Voxels per axis.
    pub n: usize,
    /// σt·h.
    pub sigma_t_h: f64,
    /// ‖I − I_ref‖₂/‖I_ref‖₂ over all voxels.
    pub rel_l2: f64,
    /// max |I − I_ref|/I_ref.
    pub max_rel: f64,
    /// Solve seconds.
    pub seconds: f64,
}

/// Voxel-averaged (`sub`³ Gauss points) reference of ∫e^{−σt ℓ}dω on the n³ cube of edge 1,
/// `q`² Gauss points per face rectangle.
pub fn order1_reference(n: usize, sigma_t: f64, q: usize, sub: usize) -> Result<Vec<f64>> {
    if n % 2 != 0 {
        bail!("order1_reference: n = {n} must be even (octant symmetry)");
    }
    let grid = Grid::cube(n, 1.0)?;
    let h = grid.dl;
    let gl = gauss_legendre(q);
    let g3 = gauss_legendre(sub);
    let half = n / 2;
    // The 48 cube symmetries: only voxels with folded indices i ≤ j ≤ k are integrated.
    let fold = |x: usize| if x < half { x } else { n - 1 - x };
    let key = |i: usize, j: usize, k: usize| {
        let mut v = [fold(i), fold(j), fold(k)];
        v.sort_unstable();
        v[0] + half * (v[1] + half * v[2])
    };
    let mut unique: Vec<[usize; 3]> = Vec::new();
    for k in 0..half {
        for j in 0..=k {
            for i in 0..=j {
                unique.push([i, j, k]);
            }
        }
    }
    let values: Vec<f64> = unique
        .par_iter()
        .map(|&[i, j, k]| {
            let mut acc = 0.0;
            for (xa, wa) in g3.0.iter().zip(&g3.1) {
                for (xb, wb) in g3.0.iter().zip(&g3.1) {
                    for (xc, wc) in g3.0.iter().zip(&g3.1) {
                        let p = [
                            h * (i as f64 + 0.5 + 0.5 * xa),
                            h * (j as f64 + 0.5 + 0.5 * xb),
                            h * (k as f64 + 0.5 + 0.5 * xc),
                        ];
                        acc += wa * wb * wc * uncollided_uniform(p, 1.0, sigma_t, &gl);
                    }
                }
            }
            acc / 8.0
        })
        .collect();
    let mut table = vec![0.0; half * half * half];
    for (&[i, j, k], v) in unique.iter().zip(values) {
        table[i + half * (j + half * k)] = v;
    }
    let mut out = vec![0.0; grid.len()];
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                out[grid.index(i, j, k)] = table[key(i, j, k)];
            }
        }
    }
    Ok(out)
}

/// T9: a homogeneous unit cube (n³, σt, albedo 0.5) under a uniform environment L = 1, one
/// order: I = σs φ⁰/4π against σs/4π × [`order1_reference`], for each m.
pub fn order1_uniform(n: usize, sigma_t: f64, ms: &[usize]) -> Result<Vec<Order1Row>> {
    let albedo = 0.5;
    let medium = Medium::homogeneous(Grid::cube(n, 1.0)?, sigma_t, albedo)?;
    let phi_ref = order1_reference(n, sigma_t, 20, 4)?;
    let i_ref: Vec<f64> = phi_ref
        .iter()
        .map(|p| sigma_t * albedo * p / (4.0 * PI))
        .collect();
    let mut rows = Vec::new();
    for &m in ms {
        let dirs = Directions::new(m)?;
        let cfg = LpmConfig {
            m,
            orders: Orders::Fixed(1),
            ..LpmConfig::default()
        };
        let t0 = Instant::now();
        let s = solve(&medium, &BoundaryLight::uniform(&dirs, 1.0), &cfg)?;
        let seconds = t0.elapsed().as_secs_f64();
        let i = s.mean_intensity();
        let (rel_l2, max_rel) = rel_errors(&i, &i_ref);
        rows.push(Order1Row {
            m,
            directions: dirs.len(),
            n,
            sigma_t_h: sigma_t / n as f64,
            rel_l2,
            max_rel,
            seconds,
        });
    }
    Ok(rows)
}

/// (‖a − b‖₂/‖b‖₂, max |a − b|/|b|).
pub fn rel_errors(a: &[f64], b: &[f64]) -> (f64, f64) {
    let (mut num, mut den, mut max) = (0.0, 0.0, 0.0f64);
    for (x, y) in a.iter().zip(b) {
        num += (x - y) * (x - y);
        den += y * y;
        max = max.max((x - y).abs() / y.abs());
    }
    ((num / den).sqrt(), max)
}

// ---------------------------------------------------------------------------------------
// T10: slab vs adding–doubling.

/// One slab case of T10.
#[derive(Debug, Clone, Serialize)]
pub struct SlabRow {
    /// Optical thickness.
    pub tau: f64,
    /// Albedo.
    pub albedo: f64,
    /// Cells per face edge.
    pub m: usize,
    /// Voxels across the slab.
    pub nz: usize,
    /// Lateral voxels per axis.
    pub lateral: usize,
    /// Side re-entry rule (`open` or `periodic`).
    pub wrap: String,
    /// Reflectance from the LPM source (exact exit integral).
    #[serde(rename = "R")]
    pub r: f64,
    /// Diffuse transmittance from the LPM source.
    #[serde(rename = "T")]
    pub t: f64,
    /// Adding–doubling reflectance.
    #[serde(rename = "R_ad")]
    pub r_ad: f64,
    /// Adding–doubling diffuse transmittance.
    #[serde(rename = "T_ad")]
    pub t_ad: f64,
    /// |R − R_ad|.
    pub dr: f64,
    /// |T − T_ad|.
    pub dt: f64,
    /// Orders run.
    pub orders: usize,
    /// Solve seconds.
    pub seconds: f64,
}

/// T10: an isotropic slab of optical thickness τ (σt = 1), albedo c, under a normal
/// collimated beam (irradiance 1 along −z, the exact centre cell of the −z face), on a grid
/// of `nz` voxels across and `lateral_mfp` mean free paths wide (odd voxel count), orders to
/// 10⁻⁷ of the first. The solver has no per-face exit tally, so R and T_d come from the
/// central column's scattered source I(z) (voxel constants) through the exact exit
/// integral of an isotropic layer, 2π∫I(z)E₂(σt·depth)dz = 2π Σ_k I_k (E₃(σt d_k) −
/// E₃(σt d_{k+1}))/σt: the LPM's angular and spatial discretisation enters through I, the
/// last exit step is exact.
pub fn slab_case(
    tau: f64,
    albedo: f64,
    m: usize,
    nz: usize,
    lateral_mfp: f64,
    wrap: WrapBc,
) -> Result<SlabRow> {
    let h = tau / nz as f64;
    let mut lateral = (lateral_mfp / h).ceil() as usize;
    if lateral % 2 == 0 {
        lateral += 1;
    }
    let grid = Grid::new([lateral, lateral, nz], h)?;
    solvers::budget::check(
        format!("slab grid {lateral}x{lateral}x{nz}"),
        lpm::memory_bytes(&grid, &LpmConfig::default(), 8).total(),
    )?;
    let medium = Medium::homogeneous(grid, 1.0, albedo)?;
    let dirs = Directions::new(m)?;
    let light = BoundaryLight::directional(&dirs, [0.0, 0.0, -1.0], 1.0)?;
    let cfg = LpmConfig {
        m,
        wrap,
        orders: Orders::Converge {
            rel: 1e-7,
            max_orders: 500,
        },
        keep_orders: false,
        ..LpmConfig::default()
    };
    let t0 = Instant::now();
    let s = solve(&medium, &light, &cfg)?;
    let seconds = t0.elapsed().as_secs_f64();
    let intensity = s.mean_intensity();
    let c = lateral / 2;
    let (mut r, mut t) = (0.0, 0.0);
    for k in 0..nz {
        let i = intensity[grid.index(c, c, k)];
        let (z0, z1) = (k as f64 * h, (k + 1) as f64 * h);
        // Reflectance leaves through the top z = τ, T through the bottom z = 0.
        r += i * (expint(3, (tau - z1).max(0.0)) - expint(3, (tau - z0).max(0.0)));
        t += i * (expint(3, z0) - expint(3, z1));
    }
    r *= 2.0 * PI;
    t *= 2.0 * PI;
    let ad = Slab::new(tau, albedo, 0.0)?.solve(1.0)?;
    Ok(SlabRow {
        tau,
        albedo,
        m,
        nz,
        lateral,
        wrap: match wrap {
            WrapBc::Open => "open",
            WrapBc::Periodic => "periodic",
            WrapBc::Zero => "zero",
        }
        .into(),
        r,
        t,
        r_ad: ad.reflectance,
        t_ad: ad.transmittance_diffuse,
        dr: (r - ad.reflectance).abs(),
        dt: (t - ad.transmittance_diffuse).abs(),
        orders: s.orders,
        seconds,
    })
}

// ---------------------------------------------------------------------------------------
// T11: point source in an infinite medium.

/// One shell of T11.
#[derive(Debug, Clone, Serialize)]
pub struct ShellRow {
    /// Albedo.
    pub albedo: f64,
    /// Cells per face edge.
    pub m: usize,
    /// Inner radius / h (voxel centres in [r0, r0 + 1)h).
    pub r0_h: f64,
    /// Voxels in the shell.
    pub voxels: usize,
    /// Mean uncollided fluence, LPM.
    pub unc_lpm: f64,
    /// Mean uncollided fluence, exact (voxel-averaged source and target).
    pub unc_exact: f64,
    /// Mean collided fluence, LPM.
    pub col_lpm: f64,
    /// Mean collided fluence, exact.
    pub col_exact: f64,
    /// unc_lpm/unc_exact − 1.
    pub unc_err: f64,
    /// col_lpm/col_exact − 1.
    pub col_err: f64,
    /// Coefficient of variation of φ_unc,LPM/φ_unc,exact over the shell's voxels.
    pub unc_cv: f64,
    /// Orders run.
    pub orders: usize,
}

/// The exact fluence of a unit-power uniform cube source (edge h, centred at the origin)
/// averaged over the voxel centred at `c` (3³ × 3³ Gauss pairs), σt = `sigma_t`:
/// (uncollided, collided). `g` is 4πuφ_c(u) of the σt = 1 solution on a table of step `du`.
fn exact_voxel(c: [f64; 3], h: f64, sigma_t: f64, table: &(Vec<f64>, f64)) -> (f64, f64) {
    let g3 = gauss_legendre(3);
    let mut pts: Vec<([f64; 3], f64)> = Vec::with_capacity(27);
    for (xa, wa) in g3.0.iter().zip(&g3.1) {
        for (xb, wb) in g3.0.iter().zip(&g3.1) {
            for (xc, wc) in g3.0.iter().zip(&g3.1) {
                pts.push((
                    [0.5 * h * xa, 0.5 * h * xb, 0.5 * h * xc],
                    wa * wb * wc / 8.0,
                ));
            }
        }
    }
    let (g, du) = table;
    let interp = |u: f64| {
        let x = u / du - 0.5;
        let i = (x.floor().max(0.0) as usize).min(g.len() - 2);
        let f = x - i as f64;
        g[i] * (1.0 - f) + g[i + 1] * f
    };
    let (mut unc, mut col) = (0.0, 0.0);
    for (ps, ws) in &pts {
        for (pt, wt) in &pts {
            let d = [
                c[0] + pt[0] - ps[0],
                c[1] + pt[1] - ps[1],
                c[2] + pt[2] - ps[2],
            ];
            let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            let w = ws * wt;
            unc += w * (-sigma_t * r).exp() / (4.0 * PI * r * r);
            col += w * sigma_t * interp(sigma_t * r) / (4.0 * PI * r);
        }
    }
    (unc, col)
}

/// The exact uncollided and collided voxel averages around a unit source voxel at the
/// centre of an n³ grid (n odd) of spacing h, for every voxel whose centre lies within
/// `r_max_h`·h (others NaN).
fn exact_field(
    grid: &Grid,
    sigma_t: f64,
    exact: Option<&ExactPointSource>,
    r_max_h: f64,
) -> (Vec<f64>, Vec<f64>) {
    let h = grid.dl;
    let n = grid.n[0];
    let umax = sigma_t * h * (r_max_h + 3.0);
    let steps = 4000;
    let du = umax / steps as f64;
    let g: Vec<f64> = (0..=steps)
        .map(|j| {
            let u = (j as f64 + 0.5) * du;
            exact.map_or(0.0, |e| 4.0 * PI * u * e.collided(u))
        })
        .collect();
    let table = (g, du);
    let c = (n / 2) as f64;
    let out: Vec<(f64, f64)> = (0..grid.len())
        .into_par_iter()
        .map(|v| {
            let [i, j, k] = grid.coords(v);
            let d = [(i as f64 - c) * h, (j as f64 - c) * h, (k as f64 - c) * h];
            let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() / h;
            if r > r_max_h || r < 1.0 {
                (f64::NAN, f64::NAN)
            } else {
                exact_voxel(d, h, sigma_t, &table)
            }
        })
        .collect();
    out.into_iter().unzip()
}

/// A centred one-voxel source of unit power in an n³ cube (n odd) of spacing h = 1.
fn point_medium(n: usize, sigma_t: f64, albedo: f64) -> Result<Medium<f64>> {
    if n % 2 == 0 {
        bail!("point source: n = {n} must be odd (a centre voxel)");
    }
    let grid = Grid::new([n; 3], 1.0)?;
    let mut emission = vec![0.0; grid.len()];
    emission[grid.index(n / 2, n / 2, n / 2)] = 1.0;
    Ok(Medium::new(
        grid,
        vec![sigma_t; grid.len()],
        vec![albedo; grid.len()],
        emission,
    )?)
}

/// Shell means over voxels with centre distance in [r0, r0 + 1)h, r0 = `lo`..`hi`:
/// (r0, voxels, mean a, mean b, CV of a/b).
fn shells(
    grid: &Grid,
    a: &[f64],
    b: &[f64],
    lo: usize,
    hi: usize,
) -> Vec<(f64, usize, f64, f64, f64)> {
    let c = (grid.n[0] / 2) as f64;
    (lo..hi)
        .map(|r0| {
            let (mut na, mut sa, mut sb, mut sq, mut sr) = (0usize, 0.0, 0.0, 0.0, 0.0);
            for v in 0..grid.len() {
                let [i, j, k] = grid.coords(v);
                let r = ((i as f64 - c).powi(2) + (j as f64 - c).powi(2) + (k as f64 - c).powi(2))
                    .sqrt();
                if r >= r0 as f64 && r < (r0 + 1) as f64 {
                    na += 1;
                    sa += a[v];
                    sb += b[v];
                    let q = a[v] / b[v];
                    sr += q;
                    sq += q * q;
                }
            }
            let k = na as f64;
            let mean_q = sr / k;
            let cv = ((sq / k - mean_q * mean_q).max(0.0)).sqrt() / mean_q;
            (r0 as f64, na, sa / k, sb / k, cv)
        })
        .collect()
}

/// T11: a unit-power voxel source at the centre of an n³ grid (n odd, h = 1, σt = `sigma_t_h`,
/// albedo c < 1), orders to 10⁻⁶ of the first, against the exact solution (voxel-averaged
/// source and target) on shells r ∈ [3h, 10h).
pub fn point_source(n: usize, sigma_t_h: f64, albedo: f64, m: usize) -> Result<Vec<ShellRow>> {
    let medium = point_medium(n, sigma_t_h, albedo)?;
    let grid = medium.grid;
    let dirs = Directions::new(m)?;
    let cfg = LpmConfig {
        m,
        orders: Orders::Converge {
            rel: 1e-6,
            max_orders: 400,
        },
        ..LpmConfig::default()
    };
    let s = solve(&medium, &BoundaryLight::none(&dirs), &cfg)?;
    let unc_lpm = s.phi_orders.first().context("no order kept")?.clone();
    let col_lpm: Vec<f64> = s.phi.iter().zip(&unc_lpm).map(|(t, u)| t - u).collect();
    let exact = ExactPointSource::new(albedo)?;
    let (unc_ex, col_ex) = exact_field(&grid, sigma_t_h, Some(&exact), 10.5);
    let su = shells(&grid, &unc_lpm, &unc_ex, 3, 10);
    let sc = shells(&grid, &col_lpm, &col_ex, 3, 10);
    Ok(su
        .iter()
        .zip(&sc)
        .map(|(u, c)| ShellRow {
            albedo,
            m,
            r0_h: u.0,
            voxels: u.1,
            unc_lpm: u.2,
            unc_exact: u.3,
            col_lpm: c.2,
            col_exact: c.3,
            unc_err: u.2 / u.3 - 1.0,
            col_err: c.2 / c.3 - 1.0,
            unc_cv: u.4,
            orders: s.orders,
        })
        .collect())
}

// ---------------------------------------------------------------------------------------
// Ray effect (spec §5 b).

/// One (m, shell) of the ray-effect case.
#[derive(Debug, Clone, Serialize)]
pub struct RayEffectRow {
    /// Cells per face edge.
    pub m: usize,
    /// Inner shell radius / h.
    pub r0_h: f64,
    /// CV of φ⁰_LPM/φ⁰_exact over the shell's voxels.
    pub cv: f64,
    /// Fraction of the shell's voxels with φ⁰_LPM < 0.1 φ⁰_exact ("gaps").
    pub gaps: f64,
    /// Shell-mean φ⁰_LPM/φ⁰_exact − 1.
    pub shell_err: f64,
}

/// Spec §5 (b): a one-voxel isotropic emitter at the centre of an n³ grid (n odd), σt·h =
/// 0.01, albedo 0.1, one order; the uncollided fluence on shells [r, r + 1)h against the
/// exact voxel-averaged e^{−σt r}/(4πr²), for each m.
pub fn ray_effect(n: usize, ms: &[usize]) -> Result<Vec<RayEffectRow>> {
    let medium = point_medium(n, 0.01, 0.1)?;
    let grid = medium.grid;
    let r_max = (n / 2) as f64;
    let (unc_ex, _) = exact_field(&grid, 0.01, None, r_max);
    let mut rows = Vec::new();
    for &m in ms {
        let dirs = Directions::new(m)?;
        let cfg = LpmConfig {
            m,
            orders: Orders::Fixed(1),
            ..LpmConfig::default()
        };
        let s = solve(&medium, &BoundaryLight::none(&dirs), &cfg)?;
        let unc = s.phi_orders.first().context("no order kept")?;
        let c = (n / 2) as f64;
        for r0 in 2..(n / 2) {
            let (mut k, mut gaps, mut sa, mut sb, mut sr, mut sq) =
                (0usize, 0usize, 0.0, 0.0, 0.0, 0.0);
            for v in 0..grid.len() {
                let [i, j, kk] = grid.coords(v);
                let r = ((i as f64 - c).powi(2) + (j as f64 - c).powi(2) + (kk as f64 - c).powi(2))
                    .sqrt();
                if r >= r0 as f64 && r < (r0 + 1) as f64 {
                    let q = unc[v] / unc_ex[v];
                    k += 1;
                    sa += unc[v];
                    sb += unc_ex[v];
                    sr += q;
                    sq += q * q;
                    if q < 0.1 {
                        gaps += 1;
                    }
                }
            }
            let kf = k as f64;
            let mq = sr / kf;
            rows.push(RayEffectRow {
                m,
                r0_h: r0 as f64,
                cv: ((sq / kf - mq * mq).max(0.0)).sqrt() / mq,
                gaps: gaps as f64 / kf,
                shell_err: sa / sb - 1.0,
            });
        }
    }
    Ok(rows)
}

// ---------------------------------------------------------------------------------------
// T12: per order vs the path tracer.

/// One order of T12.
#[derive(Debug, Clone, Serialize)]
pub struct PerOrderRow {
    /// Scattering order (0: uncollided).
    pub order: usize,
    /// Relative L2 of LPM against the mean of two path-traced runs, debiased by their noise.
    pub rel_l2: f64,
    /// The same without debiasing.
    pub rel_l2_raw: f64,
    /// Relative L2 noise of the two-run mean (from their difference).
    pub noise: f64,
    /// Σφ_LPM/Σφ_PT − 1.
    pub total_err: f64,
    /// Paths per run.
    pub paths: u64,
}

/// T12: the `noise_cloud` generator (n³, defaults otherwise: σt ≤ 20 on the unit cube,
/// albedo 0.9) under a directional light of irradiance 1 along −z (the exact centre cell),
/// LPM with 4 orders (fluence of orders 0–3) against the path tracer's track-length fluence
/// per order: order k = collided(max_depth k) − collided(max_depth k − 1) with a common
/// seed (the same paths up to the k-th scattering), order 1 = collided(max_depth 1), order
/// 0 = uncollided. Two seeds; the noise of their mean is estimated from their difference.
pub fn per_order_vs_pt(n: usize, m: usize, paths: u64, seed: u64) -> Result<Vec<PerOrderRow>> {
    let medium = NoiseCloud {
        n,
        ..NoiseCloud::default()
    }
    .generate()?;
    let scene = Scene {
        medium: medium.clone(),
        phase: Phase::Isotropic,
        lights: vec![Light::directional([0.0, 0.0, -1.0], 1.0)?],
        camera: None,
        sampler: Sampler { spp: 1, seed },
        interpolation: Default::default(),
    };
    let per_order = |seed: u64| -> Result<Vec<Vec<f64>>> {
        let mut out: Vec<Vec<f64>> = Vec::new();
        let mut prev: Option<Vec<f64>> = None;
        for k in 1..=3u32 {
            let f = fluence(
                &scene,
                &PathSettings {
                    paths,
                    seed,
                    batches: 16,
                    max_depth: Some(k),
                },
            )
            .with_context(|| format!("path tracer, max_depth {k}"))?;
            if k == 1 {
                out.push(f.uncollided.mean.clone());
            }
            let col = f.collided.mean;
            out.push(match &prev {
                None => col.clone(),
                Some(p) => col.iter().zip(p).map(|(a, b)| a - b).collect(),
            });
            prev = Some(col);
        }
        Ok(out)
    };
    let a = per_order(seed)?;
    let b = per_order(seed.wrapping_add(7919))?;
    let dirs = Directions::new(m)?;
    let cfg = LpmConfig {
        m,
        orders: Orders::Fixed(4),
        ..LpmConfig::default()
    };
    let s = solve(
        &medium,
        &BoundaryLight::directional(&dirs, [0.0, 0.0, -1.0], 1.0)?,
        &cfg,
    )?;
    Ok((0..4)
        .map(|k| {
            let (mut e2, mut n2, mut r2, mut sl, mut sp) = (0.0, 0.0, 0.0, 0.0, 0.0);
            for v in 0..medium.grid.len() {
                let r = 0.5 * (a[k][v] + b[k][v]);
                let d = s.phi_orders[k][v] - r;
                e2 += d * d;
                n2 += 0.25 * (a[k][v] - b[k][v]).powi(2);
                r2 += r * r;
                sl += s.phi_orders[k][v];
                sp += r;
            }
            PerOrderRow {
                order: k,
                rel_l2: ((e2 - n2).max(0.0) / r2).sqrt(),
                rel_l2_raw: (e2 / r2).sqrt(),
                noise: (n2 / r2).sqrt(),
                total_err: sl / sp - 1.0,
                paths,
            }
        })
        .collect())
}

// ---------------------------------------------------------------------------------------
// Collimated beam in a thin medium (spec §5 a).

/// σt·h of the black mask around the beam case's medium: e^{−500} per voxel crossed.
pub const BEAM_MASK_SIGMA_T_H: f64 = 500.0;

/// One LPM run of the collimated-beam case.
#[derive(Debug, Clone, Serialize)]
pub struct BeamRow {
    /// Cells per face edge.
    pub m: usize,
    /// Angle of the beam from the −z axis, in the x–z plane (degrees).
    pub tilt_deg: f64,
    /// Henyey–Greenstein g.
    pub g: f64,
    /// Angle between the beam and the centre direction of the cell it is snapped to
    /// (degrees).
    pub snap_deg: f64,
    /// Order 0: fraction of the LPM fluence (interior voxels) outside the tube that the
    /// snapped direction sweeps from the hole: light spread off its own characteristic
    /// (false scattering); 0 for exact characteristics.
    pub false_frac: f64,
    /// Order 0: fraction of the LPM fluence in voxels where the exact beam's is zero.
    pub off_beam_frac: f64,
    /// Order 0: distance between the LPM and the exact beam centroid in the deepest
    /// interior slab, in voxels.
    pub offset_h: f64,
    /// The same predicted from the snap: the two tubes' centres d·|tan-plane difference|.
    pub offset_pred_h: f64,
    /// Order 0: ΣLPM/Σexact − 1 over the interior voxels.
    pub power0_err: f64,
    /// Order 0: lateral RMS width about the centroid, mean over the interior slabs, LPM
    /// (voxels).
    pub width0_lpm_h: f64,
    /// The same for the exact beam (voxel-averaged).
    pub width0_exact_h: f64,
    /// Order 1 on three slabs (depth ¼, ½, ¾): ΣLPM/Σexact − 1.
    pub power1_err: f64,
    /// Order 1: relative L2 over the voxels of those slabs with exact φ¹ > 10⁻³ of its max.
    pub rel_l2_1: f64,
    /// Order 1: lateral RMS distance from the exact beam's axis, LPM (voxels, mean of the
    /// three slabs).
    pub width1_lpm_h: f64,
    /// The same, exact.
    pub width1_exact_h: f64,
    /// Solve seconds (2 orders).
    pub seconds: f64,
}

/// The geometry of the beam case: an n³ unit cube whose one-voxel boundary shell is black
/// (σt·h = [`BEAM_MASK_SIGMA_T_H`], albedo 0) but for a `w`×`w` vacuum hole centred in the
/// top layer; inside, a homogeneous medium (σt·h, albedo). The beam of irradiance 1 enters
/// through the hole's top face at z = 1.
#[derive(Debug, Clone, Copy)]
pub struct BeamGeometry {
    /// Voxels per axis.
    pub n: usize,
    /// Hole width in voxels.
    pub w: usize,
    /// σt·h inside.
    pub sigma_t_h: f64,
    /// Albedo inside.
    pub albedo: f64,
}

impl BeamGeometry {
    fn h(&self) -> f64 {
        1.0 / self.n as f64
    }

    /// The hole's lateral extent [x0, x1] (the same in y).
    fn hole(&self) -> (f64, f64) {
        let i0 = (self.n - self.w) / 2;
        (i0 as f64 * self.h(), (i0 + self.w) as f64 * self.h())
    }

    /// The medium.
    pub fn medium(&self) -> Result<Medium<f64>> {
        let grid = Grid::cube(self.n, 1.0)?;
        let n = self.n;
        let h = self.h();
        let i0 = (n - self.w) / 2;
        let hole = |i: usize| i >= i0 && i < i0 + self.w;
        let mut st = vec![self.sigma_t_h / h; grid.len()];
        let mut al = vec![self.albedo; grid.len()];
        for v in 0..grid.len() {
            let [i, j, k] = grid.coords(v);
            let shell = [i, j, k].iter().any(|&c| c == 0 || c == n - 1);
            if k == n - 1 && hole(i) && hole(j) {
                st[v] = 0.0;
                al[v] = 0.0;
            } else if shell {
                st[v] = BEAM_MASK_SIGMA_T_H / h;
                al[v] = 0.0;
            }
        }
        Ok(Medium::new(grid, st, al, vec![0.0; grid.len()])?)
    }

    /// The tube of a beam along the unit `w` (travelling down) where it enters the medium
    /// at z = 1 − h: the hole ∩ (the hole shifted by h·s) per lateral axis, s = w⊥/|w_z|
    /// the drift per unit depth.
    fn entry(&self, w: [f64; 3]) -> ([f64; 2], [(f64, f64); 2]) {
        let s = [w[0] / w[2].abs(), w[1] / w[2].abs()];
        let (a, b) = self.hole();
        let h = self.h();
        let r = |sh: f64| (a.max(a + sh), b.min(b + sh));
        (s, [r(h * s[0]), r(h * s[1])])
    }
}

/// Henyey–Greenstein phase function (per steradian).
fn hg(g: f64, mu: f64) -> f64 {
    (1.0 - g * g) / (4.0 * PI * (1.0 + g * g - 2.0 * g * mu).powf(1.5))
}

/// Exact order-0 fluence of the beam along `w` (irradiance 1) averaged over voxel v by
/// `q`³ midpoint samples: e^{−σt s} where the sample's back-projection to z = 1 − h lands
/// in the entry rectangle, s the path length below it.
fn beam_order0(geo: &BeamGeometry, w: [f64; 3], grid: &Grid, v: usize, q: usize) -> f64 {
    let h = geo.h();
    let sigma = geo.sigma_t_h / h;
    let (s, rect) = geo.entry(w);
    let [i, j, k] = grid.coords(v);
    let mut acc = 0.0;
    for a in 0..q {
        for b in 0..q {
            for c in 0..q {
                let x = (i as f64 + (a as f64 + 0.5) / q as f64) * h;
                let y = (j as f64 + (b as f64 + 0.5) / q as f64) * h;
                let z = (k as f64 + (c as f64 + 0.5) / q as f64) * h;
                let depth = 1.0 - h - z;
                let (x0, y0) = (x - depth * s[0], y - depth * s[1]);
                if (rect[0].0..rect[0].1).contains(&x0) && (rect[1].0..rect[1].1).contains(&y0) {
                    acc += (-sigma * depth / w[2].abs()).exp();
                }
            }
        }
    }
    acc / (q * q * q) as f64
}

/// Exact order-1 fluence at x of the beam along `w` (irradiance 1, single scattering with
/// HG g): ∫_A∫_0^{s_max} σs e^{−σt s} p(μ) e^{−σt r}/r² |w_z| ds dA over the entry
/// rectangle A (`gq`² Gauss points) and the path below it, in s = s* + b·tan ψ (ds/r² =
/// dψ/b, `nq` Gauss points in ψ).
fn beam_order1(
    geo: &BeamGeometry,
    w: [f64; 3],
    g: f64,
    x: [f64; 3],
    gq: &(Vec<f64>, Vec<f64>),
    gpsi: &(Vec<f64>, Vec<f64>),
) -> f64 {
    let h = geo.h();
    let sigma = geo.sigma_t_h / h;
    let sigma_s = sigma * geo.albedo;
    let (_, rect) = geo.entry(w);
    let s_max = (1.0 - 2.0 * h) / w[2].abs();
    let mut total = 0.0;
    for (xa, wa) in gq.0.iter().zip(&gq.1) {
        let ax = rect[0].0 + 0.5 * (rect[0].1 - rect[0].0) * (xa + 1.0);
        for (xb, wb) in gq.0.iter().zip(&gq.1) {
            let ay = rect[1].0 + 0.5 * (rect[1].1 - rect[1].0) * (xb + 1.0);
            let a = [ax, ay, 1.0 - h];
            let d = [x[0] - a[0], x[1] - a[1], x[2] - a[2]];
            let s_star = d[0] * w[0] + d[1] * w[1] + d[2] * w[2];
            let perp = [
                d[0] - s_star * w[0],
                d[1] - s_star * w[1],
                d[2] - s_star * w[2],
            ];
            let b = (perp[0] * perp[0] + perp[1] * perp[1] + perp[2] * perp[2])
                .sqrt()
                .max(1e-12);
            let (p0, p1) = ((-s_star / b).atan(), ((s_max - s_star) / b).atan());
            let mut line = 0.0;
            for (xp, wp) in gpsi.0.iter().zip(&gpsi.1) {
                let psi = p0 + 0.5 * (p1 - p0) * (xp + 1.0);
                let s = s_star + b * psi.tan();
                let r = b / psi.cos();
                // μ = w·(x − y)/r with x − y = (s* − s)w + perp.
                let mu = (s_star - s) / r;
                line += wp * (-sigma * (s + r)).exp() * hg(g, mu);
            }
            line *= 0.5 * (p1 - p0) / b;
            let area = 0.25 * (rect[0].1 - rect[0].0) * (rect[1].1 - rect[1].0);
            total += wa * wb * area * line;
        }
    }
    sigma_s * w[2].abs() * total
}

/// Gauss points of the exact order-1 beam field: per voxel axis, per entry-rectangle axis, and
/// in ψ along the beam.
#[derive(Debug, Clone, Copy)]
pub struct BeamQuadrature {
    /// Per voxel axis (the voxel average).
    pub voxel: usize,
    /// Per axis of the beam's entry rectangle.
    pub entry: usize,
    /// Along the beam, in ψ.
    pub psi: usize,
}

impl Default for BeamQuadrature {
    /// 2, 3 and 48: the beam case's reference.
    fn default() -> Self {
        Self {
            voxel: 2,
            entry: 3,
            psi: 48,
        }
    }
}

/// The exact order-1 fluence of the beam along the unit `w` averaged over voxel `v` of
/// `geo` (see [`beam_case`]) with quadrature `q`.
pub fn beam_order1_voxel(
    geo: &BeamGeometry,
    w: [f64; 3],
    g: f64,
    v: usize,
    q: &BeamQuadrature,
) -> f64 {
    let h = geo.h();
    let n = geo.n;
    let [i, j, k] = [v % n, (v / n) % n, v / (n * n)];
    let gv = gauss_legendre(q.voxel);
    let gq = gauss_legendre(q.entry);
    let gpsi = gauss_legendre(q.psi);
    let mut acc = 0.0;
    for (xa, wa) in gv.0.iter().zip(&gv.1) {
        for (xb, wb) in gv.0.iter().zip(&gv.1) {
            for (xc, wc) in gv.0.iter().zip(&gv.1) {
                let x = [
                    h * (i as f64 + 0.5 + 0.5 * xa),
                    h * (j as f64 + 0.5 + 0.5 * xb),
                    h * (k as f64 + 0.5 + 0.5 * xc),
                ];
                acc += wa * wb * wc * beam_order1(geo, w, g, x, &gq, &gpsi);
            }
        }
    }
    acc / 8.0
}

/// Lateral centroid and RMS width (about `centre`, or about the centroid when `None`) of
/// `f` on slab k (interior voxels), in world units: (cx, cy, width, Σf).
fn slab_moments(
    grid: &Grid,
    f: &[f64],
    k: usize,
    centre: Option<[f64; 2]>,
) -> (f64, f64, f64, f64) {
    let n = grid.n[0];
    let h = grid.dl;
    let (mut s, mut sx, mut sy) = (0.0, 0.0, 0.0);
    for j in 1..n - 1 {
        for i in 1..n - 1 {
            let v = f[grid.index(i, j, k)];
            s += v;
            sx += v * (i as f64 + 0.5) * h;
            sy += v * (j as f64 + 0.5) * h;
        }
    }
    let (cx, cy) = match centre {
        Some(c) => (c[0], c[1]),
        None => (sx / s, sy / s),
    };
    let mut m2 = 0.0;
    for j in 1..n - 1 {
        for i in 1..n - 1 {
            let v = f[grid.index(i, j, k)];
            let (dx, dy) = ((i as f64 + 0.5) * h - cx, (j as f64 + 0.5) * h - cy);
            m2 += v * (dx * dx + dy * dy);
        }
    }
    (cx, cy, (m2 / s).sqrt(), s)
}

/// Spec §5 (a): a collimated beam of irradiance 1 through a `geo.w`-voxel hole into the
/// thin homogeneous medium of [`BeamGeometry`], tilted `tilt_deg` from −z in the x–z
/// plane, HG g; LPM (CPU f64, boundary injection snapped to its cell, D13) runs 2 orders
/// for each m. Order 0 against the exact beam (voxel averages of `q0`³ samples), order 1
/// against the exact single-scattering quadrature on three slabs (2³ Gauss samples per
/// voxel, 3×3 over the entry, 48 in ψ); the exact fields are computed once per call.
pub fn beam_case(geo: &BeamGeometry, tilt_deg: f64, g: f64, ms: &[usize]) -> Result<Vec<BeamRow>> {
    let medium = geo.medium()?;
    let grid = medium.grid;
    let n = geo.n;
    let h = geo.h();
    let t = tilt_deg.to_radians();
    let w = [t.sin(), 0.0, -t.cos()];
    let exact0: Vec<f64> = (0..grid.len())
        .into_par_iter()
        .map(|v| beam_order0(geo, w, &grid, v, 4))
        .collect();
    let slabs: Vec<usize> = [0.25, 0.5, 0.75]
        .iter()
        .map(|f| (((1.0 - f) * (n - 2) as f64) as usize).clamp(1, n - 2))
        .collect();
    let mut exact1 = vec![0.0; grid.len()];
    let voxels: Vec<usize> = slabs
        .iter()
        .flat_map(|&k| (1..n - 1).flat_map(move |j| (1..n - 1).map(move |i| (i, j, k))))
        .map(|(i, j, k)| grid.index(i, j, k))
        .collect();
    let q = BeamQuadrature::default();
    let vals: Vec<f64> = voxels
        .par_iter()
        .map(|&v| beam_order1_voxel(geo, w, g, v, &q))
        .collect();
    for (&v, x) in voxels.iter().zip(vals) {
        exact1[v] = x;
    }
    let interior = |v: usize| {
        let [i, j, k] = grid.coords(v);
        [i, j, k].iter().all(|c| (1..=n - 2).contains(c))
    };
    let (entry_s, entry_rect) = geo.entry(w);
    let centre_at = |s: [f64; 2], rect: [(f64, f64); 2], k: usize| {
        let depth = 1.0 - h - (k as f64 + 0.5) * h;
        [
            0.5 * (rect[0].0 + rect[0].1) + depth * s[0],
            0.5 * (rect[1].0 + rect[1].1) + depth * s[1],
        ]
    };
    let mut rows = Vec::new();
    for &m in ms {
        let dirs = Directions::new(m)?;
        let light = BoundaryLight::directional(&dirs, w, 1.0)?;
        let snapped = dirs.dirs[dirs.containing(w)].omega;
        let cos = (snapped[0] * w[0] + snapped[1] * w[1] + snapped[2] * w[2]).clamp(-1.0, 1.0);
        let cfg = LpmConfig {
            m,
            phase: if g == 0.0 {
                Phase::Isotropic
            } else {
                Phase::HenyeyGreenstein { g }
            },
            orders: Orders::Fixed(2),
            ..LpmConfig::default()
        };
        let t0 = Instant::now();
        let s = solve(&medium, &light, &cfg)?;
        let seconds = t0.elapsed().as_secs_f64();
        let phi0 = s.phi_orders.first().context("no order 0 kept")?;
        let phi1 = s.phi_orders.get(1).context("no order 1 kept")?;
        // The snapped tube's footprint: voxels its cross-section overlaps at some depth.
        let (ss, srect) = geo.entry(snapped);
        let in_tube = |v: usize| {
            let [i, j, k] = grid.coords(v);
            let (z0, z1) = (k as f64 * h, (k + 1) as f64 * h);
            let (d0, d1) = ((1.0 - h - z1).max(0.0), (1.0 - h - z0).max(0.0));
            (0..2).all(|ax| {
                let lo = srect[ax].0 + (d0 * ss[ax]).min(d1 * ss[ax]);
                let hi = srect[ax].1 + (d0 * ss[ax]).max(d1 * ss[ax]);
                let c = if ax == 0 { i } else { j } as f64 * h;
                c < hi + 1e-9 * h && c + h > lo - 1e-9 * h
            })
        };
        let (mut tot, mut off_tube, mut off_beam, mut ex_tot) = (0.0, 0.0, 0.0, 0.0);
        for v in (0..grid.len()).filter(|&v| interior(v)) {
            tot += phi0[v];
            ex_tot += exact0[v];
            if !in_tube(v) {
                off_tube += phi0[v];
            }
            if exact0[v] == 0.0 {
                off_beam += phi0[v];
            }
        }
        let deep = 1;
        let (lx, ly, _, _) = slab_moments(&grid, phi0, deep, None);
        let (ex, ey, _, _) = slab_moments(&grid, &exact0, deep, None);
        let pred_l = centre_at(ss, srect, deep);
        let pred_e = centre_at(entry_s, entry_rect, deep);
        let (mut wl, mut we) = (0.0, 0.0);
        for k in 1..n - 1 {
            wl += slab_moments(&grid, phi0, k, None).2;
            we += slab_moments(&grid, &exact0, k, None).2;
        }
        let slabs_n = (n - 2) as f64;
        let (mut p1l, mut p1e, mut w1l, mut w1e) = (0.0, 0.0, 0.0, 0.0);
        let max1 = voxels.iter().map(|&v| exact1[v]).fold(0.0f64, f64::max);
        let (mut e2, mut r2) = (0.0, 0.0);
        for &k in &slabs {
            let c = centre_at(entry_s, entry_rect, k);
            let (_, _, wlk, sl) = slab_moments(&grid, phi1, k, Some(c));
            let (_, _, wek, se) = slab_moments(&grid, &exact1, k, Some(c));
            p1l += sl;
            p1e += se;
            w1l += wlk / slabs.len() as f64;
            w1e += wek / slabs.len() as f64;
        }
        for &v in &voxels {
            if exact1[v] > 1e-3 * max1 {
                e2 += (phi1[v] - exact1[v]).powi(2);
                r2 += exact1[v] * exact1[v];
            }
        }
        rows.push(BeamRow {
            m,
            tilt_deg,
            g,
            snap_deg: cos.acos().to_degrees(),
            false_frac: off_tube / tot,
            off_beam_frac: off_beam / tot,
            offset_h: ((lx - ex).powi(2) + (ly - ey).powi(2)).sqrt() / h,
            offset_pred_h: ((pred_l[0] - pred_e[0]).powi(2) + (pred_l[1] - pred_e[1]).powi(2))
                .sqrt()
                / h,
            power0_err: tot / ex_tot - 1.0,
            width0_lpm_h: wl / slabs_n / h,
            width0_exact_h: we / slabs_n / h,
            power1_err: p1l / p1e - 1.0,
            rel_l2_1: (e2 / r2).sqrt(),
            width1_lpm_h: w1l / h,
            width1_exact_h: w1e / h,
            seconds,
        });
    }
    Ok(rows)
}
