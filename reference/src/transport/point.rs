//! The exact fluence of a unit-power isotropic point source in an infinite homogeneous medium
//! with isotropic scattering: σt = 1 (lengths are optical depths), single-scattering albedo
//! c ∈ [0, 1).
//!
//! # Derivation (Case & Zweifel 1967; Case, de Hoffmann & Placzek 1953)
//!
//! The plane-source Green's function (scalar flux of a unit isotropic plane source at x = 0)
//! has the singular-eigenfunction expansion
//!
//! ```text
//! φ_pl(x) = ½ [ e^{−|x|/ν0} / N0  +  ∫_0^1 e^{−|x|/ν} / N(ν) dν ],
//! ```
//!
//! where ν0 > 1 is the discrete eigenvalue, the positive root of the dispersion relation
//! `1 = c ν0 atanh(1/ν0)`, the discrete normalisation is
//! `N0 = (c ν0³/2) [c/(ν0² − 1) − 1/ν0²]` and the continuum normalisation is
//! `N(ν) = ν g(ν)`, `g(ν) = λ(ν)² + (π c ν/2)²`, `λ(ν) = 1 − c ν atanh ν`.
//! The point-source fluence follows from the plane one by `φ(r) = −φ_pl'(r)/(2π r)`:
//!
//! ```text
//! 4π r φ(r) = A0 e^{−r/ν0} + ∫_0^1 e^{−r/ν} dν / (ν² g(ν)),      A0 = 1/(ν0 N0).
//! ```
//!
//! For c = 0 the continuum integral is `∫_0^1 e^{−r/ν} ν^{−2} dν = e^{−r}/r`, the ballistic
//! (uncollided) term e^{−r}/(4π r²). Subtracting it and substituting u = 1/ν − 1 ∈ (0, ∞)
//! (dν/ν² = du) gives the collided fluence as a Laplace transform,
//!
//! ```text
//! 4π r φ_c(r) = A0 e^{−κ r} + e^{−r} ∫_0^∞ e^{−r u} h(u) du,    h = 1/g − 1,  κ = 1/ν0.
//! ```
//!
//! # Numerics
//!
//! * **Discrete eigenvalue.** With s = atanh(1/ν0) the dispersion relation is tanh s = c s;
//!   it is solved by Newton's method in the cancellation-free form
//!   `(1 − c) s − (s − tanh s) = 0` (monotone from s = 1/c, concave function), so that
//!   κ = tanh s, ν0 = coth s, and `A0 = 4 s² tanh s / (sinh 2s − 2s)` (N0 rewritten with
//!   c = tanh(s)/s; `sinh x − x` by its positive series), all accurate to a few ulp for
//!   c → 1 (where A0 → 3, the diffusion amplitude of FLD Eq 27) and for c → 0 (where
//!   ν0 − 1 ≈ 2 e^{−2/c} and A0 ≈ 8 e^{−2/c}/c² vanish).
//! * **Continuum endpoints.** In u the two awkward ends of the ν integral become harmless:
//!   ν → 1 (g ~ (c/2)² ln²(2/u), a logarithmic endpoint) is u → 0, and ν → 0 (where g → 1 and
//!   `1 − g = c[2t − c(t² + (πν/2)²)]`, t = ν atanh ν = ln(1 + 2/u)/(2(1 + u)), is evaluated
//!   in that expanded form so h ~ O(1/u²) keeps full relative accuracy) is u → ∞.
//! * **Quadrature.** The Laplace integral is taken in y = ln u over
//!   y ∈ [−46, ln(46/r)] with 20-point Gauss–Legendre panels of width ≤ 1. The integrand is
//!   analytic in the strip |Im y| < π/2 for every c (the poles of 1/g, at ν = ±ν0, sit at
//!   u = ±κ − 1 < 0, i.e. Im y = π; e^{−ru} stays bounded for |Im y| < π/2), so the panels
//!   converge geometrically; the small-r
//!   behaviour (`4πrφ_c → cπ²/4 + O(r ln r)`, the logarithmic singularity of the collided
//!   fluence) is the flat ∝ 1/u tail up to u ~ 1/r, which the log variable covers uniformly.
//! * **Shell averages** integrate r analytically:
//!   `∫_{r0}^{r1} r e^{−a r} dr` in closed form (or by a 16-point Gauss rule when a(r1 − r0)
//!   < ½, where the closed form cancels), then the same u quadrature.
//!
//! # Measured accuracy (tests below)
//!
//! * Against an independent real-axis Fourier inversion of the transport equation
//!   (`φ̂(k) = L/(1 − cL)`, L = atan(k)/k, no eigenvalues or normalisations involved) for
//!   c ∈ {0.1, 0.3, 0.5, 0.7, 0.9, 0.99, 0.999}, r ∈ [10⁻³, 30]: |Δ(4πrφ_c)| ≤ 1.2·10⁻¹³,
//!   relative ≤ 1.8·10⁻¹³ wherever 4πrφ_c ≥ 0.1 (4πrφ_c is O(1) near the source; where it
//!   has decayed the Fourier side's absolute rounding, ~3·10⁻¹⁴, dominates the comparison).
//! * Quadrature: 30-point panels of half the width change φ_c by ≤ 1.3·10⁻¹⁵ relative on
//!   r ∈ [10⁻³, 50] (all albedos above). Where the Fourier check loses resolution (large r,
//!   low c) this convergence, the far-field check below and the conditioning of the
//!   representation (Σ|terms|/|Σ terms| ≤ 1.43 over r ∈ [10⁻³, 50], c ∈ [0.1, 0.999]: the
//!   discrete mode, the continuum and the sign change of h hardly cancel) are what carry the
//!   ~10⁻¹³ relative accuracy out to r = 50, well inside the 10⁻⁸ target.
//! * Energy: (1 − c) ∫ 4πr²φ dr = 1 to ≤ 5.6·10⁻¹⁶ (shell average, analytic in r) and
//!   ≤ 6.7·10⁻¹⁶ (independent Gauss quadrature of `radial_density` over r), c ≤ 0.999.
//! * Source singularity: 4πrφ_c → cπ²/4 with the r ln r coefficient 2c − c²π²/4 (to 10⁻³).
//! * Far field: beyond r ≈ 800 only the discrete mode remains (checked to 10⁻¹²); φ
//!   underflows to 0 gracefully (no NaN) for huge r.
//! * Grosjean (FLD Eq 24) against this solution: within 3% for r ∈ [1, 10] when c ≥ 0.7,
//!   within ≈ 5% for r ∈ [0.01, 1] for all c; −23% at r = 10 for c = 0.3 (table in the
//!   `grosjean_band` test).
//!
//! Cost: about 1 200 evaluations of elementary functions per call (tens of µs).

use super::{GaussRule, check_albedo, sinh_minus_x, x_minus_tanh};
use crate::ReferenceError;
use std::f64::consts::PI;

/// Lower end of the y = ln u range: e^{−46} ≈ 10⁻²⁰ bounds what is left out below.
const Y_LO: f64 = -46.0;
/// e^{−r u} < e^{−46} beyond u = 46/r.
const U_CUT: f64 = 46.0;
/// Gauss points per panel.
const GAUSS_N: usize = 20;

/// The exact point-source solution for one albedo (σt = 1, unit power).
#[derive(Debug, Clone)]
pub struct ExactPointSource {
    albedo: f64,
    /// κ = 1/ν0 = tanh s, the asymptotic decay rate (1 for c = 0).
    kappa: f64,
    /// A0 = 1/(ν0 N0), the discrete-mode amplitude of 4πrφ.
    a0: f64,
    rule: GaussRule,
    /// Width of the Gauss panels in y = ln u.
    panel_width: f64,
    rule16: GaussRule,
}

impl ExactPointSource {
    /// The solution for albedo `c` ∈ [0, 1).
    pub fn new(albedo: f64) -> Result<Self, ReferenceError> {
        check_albedo(albedo, false)?;
        let s = dispersion_root(albedo);
        let (kappa, a0) = if s.is_infinite() {
            (1.0, 0.0)
        } else if s > 20.0 {
            let e = (-2.0 * s).exp();
            (s.tanh(), 8.0 * s * s * s.tanh() * e / (1.0 - 4.0 * s * e))
        } else {
            (s.tanh(), 4.0 * s * s * s.tanh() / sinh_minus_x(2.0 * s))
        };
        Ok(Self {
            albedo,
            kappa,
            a0,
            rule: GaussRule::new(GAUSS_N),
            panel_width: 1.0,
            rule16: GaussRule::new(16),
        })
    }

    /// The same solution with another u quadrature (convergence tests).
    #[cfg(test)]
    fn with_quadrature(albedo: f64, points: usize, panel_width: f64) -> Self {
        let mut p = Self::new(albedo).unwrap_or_else(|e| panic!("{e}"));
        p.rule = GaussRule::new(points);
        p.panel_width = panel_width;
        p
    }

    /// The single-scattering albedo c.
    pub fn albedo(&self) -> f64 {
        self.albedo
    }

    /// The discrete eigenvalue ν0 > 1 of `1 = c ν0 atanh(1/ν0)`; the collided fluence decays as
    /// e^{−r/ν0}/r far from the source (the diffusion length).
    ///
    /// Decision: for c = 0 there is no discrete mode (its amplitude vanishes); this returns the
    /// limit ν0 → 1 (decay e^{−r}), not ∞ — ν0 grows to ∞ only as c → 1
    /// (ν0² ≈ 1/(3(1 − c))). For c ≲ 0.02, ν0 − 1 ≈ 2e^{−2/c} is below the f64 resolution
    /// and ν0 rounds to 1.
    pub fn nu0(&self) -> f64 {
        1.0 / self.kappa
    }

    /// Amplitude A0 = 1/(ν0 N0) of the discrete mode in 4πrφ (A0 → 3 as c → 1, FLD Eq 27).
    pub fn discrete_amplitude(&self) -> f64 {
        self.a0
    }

    /// Total fluence φ(r) (ballistic + collided), power per unit area for a unit-power
    /// source, σt = 1. +∞ at r = 0, NaN for r < 0 or NaN.
    pub fn fluence(&self, r: f64) -> f64 {
        self.uncollided(r) + self.collided(r)
    }

    /// Uncollided (ballistic) fluence e^{−r}/(4π r²).
    pub fn uncollided(&self, r: f64) -> f64 {
        if r.is_nan() || r < 0.0 {
            return f64::NAN;
        }
        (-r).exp() / (4.0 * PI * r * r)
    }

    /// Collided fluence φ_c(r) (light scattered at least once). +∞ at r = 0 (it grows as
    /// c π/(16 r) there), NaN for r < 0 or NaN.
    pub fn collided(&self, r: f64) -> f64 {
        if r.is_nan() || r < 0.0 {
            return f64::NAN;
        }
        if r == 0.0 {
            return if self.albedo > 0.0 {
                f64::INFINITY
            } else {
                0.0
            };
        }
        self.collided_reduced(r) / (4.0 * PI * r)
    }

    /// Radial density 4π r² φ(r): the power crossing the sphere of radius r per unit radius
    /// direction, i.e. φ integrated over that sphere (1 at r = 0).
    pub fn radial_density(&self, r: f64) -> f64 {
        if r.is_nan() || r < 0.0 {
            return f64::NAN;
        }
        if r == 0.0 {
            return 1.0;
        }
        if r.is_infinite() {
            return 0.0;
        }
        (-r).exp() + r * self.collided_reduced(r)
    }

    /// Averages over r ∈ [r0, r1] of 4πr²φ: (total, collided). r0 may be 0.
    /// NaN unless 0 ≤ r0 ≤ r1 < ∞; r0 = r1 gives the point values.
    pub fn shell_average(&self, r0: f64, r1: f64) -> (f64, f64) {
        if !(r0 >= 0.0 && r1 >= r0 && r1.is_finite()) {
            return (f64::NAN, f64::NAN);
        }
        if r1 == r0 {
            let c = if r0 == 0.0 {
                0.0
            } else {
                r0 * self.collided_reduced(r0)
            };
            return (self.radial_density(r0), c);
        }
        let d = r1 - r0;
        let uncollided = (-r0).exp() * -(-d).exp_m1();
        let mut collided = if self.a0 > 0.0 {
            self.a0 * self.shell_moment(self.kappa, r0, r1)
        } else {
            0.0
        };
        if self.albedo > 0.0 {
            // Integrand J(1 + u) h(u) u in y = ln u; for r0 = 0 it decays like e^{−3y}.
            let y_hi = if r0 > 0.0 {
                (U_CUT / r0).ln().min(16.0)
            } else {
                16.0
            };
            collided += self.u_integral(y_hi, |u| {
                self.shell_moment(1.0 + u, r0, r1) * continuum(self.albedo, u).0
            });
        }
        ((uncollided + collided) / d, collided / d)
    }

    /// 4π r φ_c(r) for r > 0.
    fn collided_reduced(&self, r: f64) -> f64 {
        if self.albedo == 0.0 {
            return 0.0;
        }
        let discrete = self.a0 * (-self.kappa * r).exp();
        let er = (-r).exp();
        if er == 0.0 {
            return discrete;
        }
        let y_hi = (U_CUT / r).ln();
        let cont = self.u_integral(y_hi, |u| (-r * u).exp() * continuum(self.albedo, u).0);
        discrete + er * cont
    }

    /// ∫_0^∞ F(u) du taken as ∫ F(e^y) e^y dy over [Y_LO, y_hi] on Gauss panels of width ≤ 1.
    fn u_integral(&self, y_hi: f64, f: impl Fn(f64) -> f64) -> f64 {
        if y_hi <= Y_LO {
            return 0.0;
        }
        let panels = ((y_hi - Y_LO) / self.panel_width).ceil() as usize;
        self.rule.composite(Y_LO, y_hi, panels, |y| {
            let u = y.exp();
            f(u) * u
        })
    }

    /// ∫_{r0}^{r1} r e^{−a r} dr.
    fn shell_moment(&self, a: f64, r0: f64, r1: f64) -> f64 {
        let d = r1 - r0;
        if a * d < 0.5 {
            self.rule16.panel(r0, r1, |r| r * (-a * r).exp())
        } else {
            let e0 = (-a * r0).exp();
            if e0 == 0.0 {
                return 0.0;
            }
            e0 * ((1.0 + a * r0) - (-a * d).exp() * (1.0 + a * r1)) / (a * a)
        }
    }
}

/// Root s > 0 of tanh s = c s (∞ for c = 0).
fn dispersion_root(c: f64) -> f64 {
    if c == 0.0 {
        return f64::INFINITY;
    }
    let mut s = 1.0 / c;
    if s > 20.0 {
        // tanh s = 1 − 2e^{−2s} + …: the fixed point s = tanh(s)/c contracts by sech²(s)/c < 10⁻¹⁵.
        for _ in 0..3 {
            s = s.tanh() / c;
        }
        return s;
    }
    let one_minus_c = 1.0 - c;
    for _ in 0..200 {
        let f = one_minus_c * s - x_minus_tanh(s);
        let t = s.tanh();
        let df = one_minus_c - t * t;
        let step = f / df;
        s -= step;
        if step.abs() <= 1e-15 * s {
            break;
        }
    }
    s
}

/// (h, 1/g) at u = 1/ν − 1 > 0, where g = (1 − cν atanh ν)² + (πcν/2)² and h = 1/g − 1
/// with 1 − g = c[2t − c(t² + (πν/2)²)], t = ν atanh ν.
fn continuum(c: f64, u: f64) -> (f64, f64) {
    let nu = 1.0 / (1.0 + u);
    let t = nu * 0.5 * (2.0 / u).ln_1p();
    let lam = 1.0 - c * t;
    let b = 0.5 * PI * nu;
    let g = lam * lam + c * c * b * b;
    let one_minus_g = c * (2.0 * t - c * (t * t + b * b));
    (one_minus_g / g, 1.0 / g)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::point_source::grosjean;
    use crate::transport::GaussRule;

    const ALBEDOS: [f64; 7] = [0.1, 0.3, 0.5, 0.7, 0.9, 0.99, 0.999];

    /// ν0 solves the dispersion relation; ν0² → 1/(3(1 − c)) for c → 1 (diffusion theory) with
    /// the correction ν0² = 1/(3(1−c)) + 4/15 + O(1 − c) (from atanh κ/κ = 1 + κ²/3 + κ⁴/5 + …);
    /// A0 → 3; ν0 → 1 for c → 0.
    #[test]
    fn discrete_eigenvalue() {
        for c in [0.05, 0.2, 0.5, 0.8, 0.95, 0.999, 1.0 - 1e-9] {
            let p = ExactPointSource::new(c).unwrap();
            let nu0 = p.nu0();
            let resid = c * nu0 * (1.0 / nu0).atanh() - 1.0;
            // atanh(1/ν0) is ill-conditioned near ν0 = 1; compare in s instead.
            let s = dispersion_root(c);
            assert!(
                ((s.tanh() / s) / c - 1.0).abs() < 4e-16,
                "c={c}: tanh s/s = {}",
                s.tanh() / s
            );
            if c > 0.3 {
                assert!(resid.abs() < 1e-13, "c={c}: residual {resid}");
            }
        }
        let c = 1.0 - 1e-6;
        let p = ExactPointSource::new(c).unwrap();
        let nu2 = p.nu0().powi(2);
        assert!(
            (nu2 - 1.0 / (3.0 * (1.0 - c)) - 4.0 / 15.0).abs() < 1e-4,
            "{nu2}"
        );
        assert!((p.discrete_amplitude() - 3.0).abs() < 1e-5);
        let p = ExactPointSource::new(0.02).unwrap();
        assert_eq!(p.nu0(), 1.0);
        let p = ExactPointSource::new(0.0).unwrap();
        assert_eq!((p.nu0(), p.discrete_amplitude()), (1.0, 0.0));
        assert_eq!(p.collided(0.7), 0.0);
    }

    /// Independent reference: real-axis Fourier inversion of the transport equation.
    /// φ̂(k) = L/(1 − cL), L = atan(k)/k (the 3-D transform of e^{−r}/(4πr²)), so the collided
    /// part is φ̂_c = cL²/(1 − cL) and 4πrφ_c(r) = (2/π) ∫_0^∞ sin(kr) f(k) dk, f = k φ̂_c.
    /// [0, K] (K r ≥ 2000) by 20-point Gauss panels resolving both the scale κ near k = 0 and
    /// the oscillation; the tail by repeated integration by parts,
    /// ∫_K^∞ sin(kr) f = Σ_m (−1)^m r^{−2m} [cos(Kr) f^{(2m)}(K)/r − sin(Kr) f^{(2m+1)}(K)/r²],
    /// with the derivatives from the convergent expansion f = Σ b_n k^{−n} (w = 1/k:
    /// L = w(π/2 − atan w), series arithmetic). No eigenvalue or normalisation is involved.
    pub(super) fn fourier_collided_reduced(c: f64, r: f64) -> f64 {
        let f = |k: f64| {
            let l = crate::transport::atan_ratio(k);
            let one_minus_cl = (1.0 - c) + c * crate::transport::one_minus_atan_ratio(k);
            k * c * l * l / one_minus_cl
        };
        // Series of L in w: ℓ[1] = π/2, ℓ[2m+2] = −(−1)^m/(2m+1).
        const NS: usize = 40;
        let mut ell = [0.0; NS];
        ell[1] = PI / 2.0;
        let mut m = 0;
        while 2 * m + 2 < NS {
            ell[2 * m + 2] = -(if m % 2 == 0 { 1.0 } else { -1.0 }) / (2 * m + 1) as f64;
            m += 1;
        }
        let mul = |a: &[f64; NS], b: &[f64; NS]| {
            let mut p = [0.0; NS];
            for i in 0..NS {
                for j in 0..NS - i {
                    p[i + j] += a[i] * b[j];
                }
            }
            p
        };
        let mut binv = [0.0; NS]; // 1/(1 − cℓ)
        binv[0] = 1.0;
        for n in 1..NS {
            binv[n] = c * (1..=n).map(|j| ell[j] * binv[n - j]).sum::<f64>();
        }
        let mut a = mul(&ell, &ell);
        for v in a.iter_mut() {
            *v *= c;
        }
        let p = mul(&a, &binv);
        // f = Σ_{n≥1} b_n k^{−n}, b_n = p[n + 1].
        let b: Vec<f64> = (1..NS - 1).map(|n| p[n + 1]).collect();
        let kk = (2000.0 / r).max(20.0);
        // j-th derivative of f at K: Σ b_n (−1)^j n(n+1)…(n+j−1) K^{−n−j}.
        let deriv = |j: usize| -> f64 {
            b.iter()
                .enumerate()
                .map(|(i, bn)| {
                    let n = (i + 1) as f64;
                    let rising: f64 = (0..j).map(|q| n + q as f64).product();
                    let sign = if j % 2 == 0 { 1.0 } else { -1.0 };
                    bn * sign * rising * kk.powf(-n - j as f64)
                })
                .sum()
        };
        let (ck, sk) = ((kk * r).cos(), (kk * r).sin());
        let mut tail = 0.0;
        for mm in 0..6 {
            let sign = if mm % 2 == 0 { 1.0 } else { -1.0 };
            tail += sign / r.powi(2 * mm as i32)
                * (ck * deriv(2 * mm) / r - sk * deriv(2 * mm + 1) / (r * r));
        }
        let rule = GaussRule::new(20);
        let kappa = ExactPointSource::new(c).map(|p| p.kappa).unwrap_or(1.0);
        let s0 = kappa.min(1.0) / 16.0;
        let mut lo = 0.0;
        let mut sum = 0.0;
        while lo < kk {
            let width = (0.5 * lo).max(s0).min(PI / r);
            let hi = (lo + width).min(kk);
            sum += rule.panel(lo, hi, |k| (k * r).sin() * f(k));
            lo = hi;
        }
        2.0 / PI * (sum + tail)
    }

    /// Case–Zweifel against the independent Fourier inversion. Tolerance: relative 5·10⁻¹³
    /// plus an absolute 5·10⁻¹⁴ for the Fourier side's rounding, which dominates where the
    /// collided fluence has decayed (measured: ≤ 1.5·10⁻¹³ relative where 4πrφ_c ≥ 10⁻⁴).
    #[test]
    fn matches_fourier_inversion() {
        let (mut worst_rel, mut worst_abs): (f64, f64) = (0.0, 0.0);
        for c in ALBEDOS {
            let p = ExactPointSource::new(c).unwrap();
            for r in [1e-3, 0.01, 0.1, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 30.0] {
                let (a, b) = (p.collided_reduced(r), fourier_collided_reduced(c, r));
                assert!(
                    (a - b).abs() <= 5e-13 * a + 5e-14,
                    "c={c} r={r}: {a:e} vs {b:e}"
                );
                worst_abs = worst_abs.max((a - b).abs());
                if a >= 0.1 {
                    worst_rel = worst_rel.max((a / b - 1.0).abs());
                }
            }
        }
        eprintln!(
            "Case–Zweifel vs Fourier: max |Δ(4πrφ_c)| {worst_abs:.2e}, \
             max relative {worst_rel:.2e} where 4πrφ_c ≥ 0.1"
        );
    }

    /// Finer panels and more points change the result by ≤ 10⁻¹³ relative on r ∈ [10⁻³, 50].
    #[test]
    fn u_quadrature_is_converged() {
        let mut worst: f64 = 0.0;
        for c in ALBEDOS {
            let p = ExactPointSource::new(c).unwrap();
            let fine = ExactPointSource::with_quadrature(c, 30, 0.5);
            for i in 0..=40 {
                let r = 1e-3 * (5e4f64).powf(i as f64 / 40.0);
                let (a, b) = (p.collided(r), fine.collided(r));
                let rel = (a / b - 1.0).abs();
                worst = worst.max(rel);
                assert!(rel < 1e-13, "c={c} r={r}: {a:e} vs {b:e}");
            }
        }
        eprintln!("u quadrature refinement: max relative change {worst:.2e}");
    }

    /// Condition of the representation: Σ|terms| / |Σ terms| of 4πrφ_c (discrete mode plus
    /// continuum, with |h| inside the integral) stays small for r ∈ [10⁻³, 50], so the
    /// quadrature's relative accuracy carries over to φ_c (measured maximum printed).
    #[test]
    fn representation_is_well_conditioned() {
        let mut worst: f64 = 0.0;
        for c in ALBEDOS {
            let p = ExactPointSource::new(c).unwrap();
            for i in 0..=40 {
                let r = 1e-3 * (5e4f64).powf(i as f64 / 40.0);
                let y_hi = (U_CUT / r).ln();
                let abs_cont =
                    (-r).exp() * p.u_integral(y_hi, |u| (-r * u).exp() * continuum(c, u).0.abs());
                let disc = p.a0 * (-p.kappa * r).exp();
                let cond = (disc + abs_cont) / p.collided_reduced(r).abs();
                worst = worst.max(cond);
            }
        }
        eprintln!("condition Σ|terms|/|Σ terms|: max {worst:.2}");
        assert!(worst < 10.0, "{worst}");
    }

    /// (1 − c) ∫_0^∞ 4πr²φ dr = 1: all emitted power is absorbed. Two ways: the analytic-in-r
    /// shell average, and an independent Gauss quadrature over r of `radial_density`.
    #[test]
    fn energy_is_conserved() {
        let rule = GaussRule::new(20);
        let (mut w_shell, mut w_quad): (f64, f64) = (0.0, 0.0);
        for c in [0.0, 0.1, 0.5, 0.9, 0.99, 0.999] {
            let p = ExactPointSource::new(c).unwrap();
            let r_max = 44.0 / p.kappa;
            let shell = (1.0 - c) * r_max * p.shell_average(0.0, r_max).0;
            // Panels: geometric towards the source (the density has an r ln r term there),
            // then of width ≤ 2/κ.
            let mut edges = vec![0.0];
            let mut e = 1e-9;
            while e < 1.0 {
                edges.push(e);
                e *= 2.0;
            }
            let mut lo: f64 = 1.0;
            while lo < r_max {
                edges.push(lo);
                lo += (0.5 * lo).clamp(0.5, 2.0 / p.kappa);
            }
            edges.push(r_max);
            let quad: f64 = (1.0 - c)
                * edges
                    .windows(2)
                    .map(|w| rule.panel(w[0], w[1], |r| p.radial_density(r)))
                    .sum::<f64>();
            w_shell = w_shell.max((shell - 1.0).abs());
            w_quad = w_quad.max((quad - 1.0).abs());
            assert!((shell - 1.0).abs() < 1e-12, "c={c}: shell {shell}");
            assert!((quad - 1.0).abs() < 1e-10, "c={c}: quadrature {quad}");
        }
        eprintln!("energy: |shell − 1| ≤ {w_shell:.1e}, |quadrature − 1| ≤ {w_quad:.1e}");
    }

    /// Shell averages equal the r-quadrature of the pointwise radial density, total and
    /// collided, including shells that start at the source.
    #[test]
    fn shell_average_matches_pointwise_density() {
        let rule = GaussRule::new(20);
        for c in [0.3, 0.9, 0.99] {
            let p = ExactPointSource::new(c).unwrap();
            for (r0, r1) in [
                (0.0, 1e-4),
                (0.0, 0.1),
                (0.5, 0.7),
                (2.0, 7.0),
                (10.0, 10.5),
            ] {
                let (tot, col) = p.shell_average(r0, r1);
                // u = √(r − r0) removes the √-type behaviour at r0 = 0 of the r ln r term.
                let avg = |f: &dyn Fn(f64) -> f64| {
                    let h = (r1 - r0).sqrt();
                    rule.composite(0.0, h, 16, |u| f(r0 + u * u) * 2.0 * u) / (r1 - r0)
                };
                let tq = avg(&|r| p.radial_density(r));
                let cq = avg(&|r| {
                    if r == 0.0 {
                        0.0
                    } else {
                        r * p.collided_reduced(r)
                    }
                });
                assert!(
                    (tot / tq - 1.0).abs() < 1e-11,
                    "c={c} [{r0},{r1}]: {tot} vs {tq}"
                );
                assert!(
                    (col / cq - 1.0).abs() < 1e-11,
                    "c={c} [{r0},{r1}]: {col} vs {cq}"
                );
            }
            let (t, c0) = p.shell_average(1.5, 1.5);
            assert_eq!(t, p.radial_density(1.5));
            assert!((c0 - (t - (-1.5f64).exp())).abs() < 1e-15);
            assert!(p.shell_average(1.0, 0.5).0.is_nan());
        }
    }

    /// Near the source only the first collision is singular: 4πrφ_c → b1 = cπ²/4, and the next
    /// term is the logarithmic one, (2c − c²π²/4) r ln r (from the 1/k and 1/k² terms of the
    /// Fourier transform k φ̂_c).
    #[test]
    fn collided_log_singularity_at_the_source() {
        for c in [0.2, 0.6, 0.95] {
            let p = ExactPointSource::new(c).unwrap();
            let b1 = c * PI * PI / 4.0;
            let d = |r: f64| (p.collided_reduced(r) - b1) / r;
            let (r1, r2) = (1e-7, 1e-9);
            let slope = (d(r1) - d(r2)) / (r1.ln() - r2.ln());
            let expected = 2.0 * c - c * c * PI * PI / 4.0;
            assert!(
                (slope - expected).abs() < 1e-3 * expected.abs().max(0.1),
                "c={c}: slope {slope} vs {expected}"
            );
            assert!((p.collided_reduced(1e-12) - b1).abs() < 1e-10);
        }
    }

    #[test]
    fn consistency_and_far_field() {
        let p = ExactPointSource::new(0.99).unwrap();
        for r in [1e-3, 0.3, 4.0] {
            assert_eq!(p.fluence(r), p.uncollided(r) + p.collided(r));
            let rd = 4.0 * PI * r * r * p.fluence(r);
            assert!((p.radial_density(r) / rd - 1.0).abs() < 1e-14);
        }
        assert_eq!(p.radial_density(0.0), 1.0);
        assert!(p.fluence(0.0).is_infinite() && p.fluence(-1.0).is_nan());
        // Far out the discrete mode alone remains: 4πrφ → A0 e^{−r/ν0}.
        for r in [800.0, 2000.0] {
            let rel = 4.0 * PI * r * p.fluence(r) / (p.a0 * (-r / p.nu0()).exp()) - 1.0;
            assert!(rel.abs() < 1e-12, "r={r}: {rel}");
        }
        assert_eq!(p.fluence(1e6), 0.0);
    }

    /// Grosjean's approximation (FLD Eq 24) against the exact solution. Measured bands of
    /// grosjean/exact − 1 (201 log-spaced r each):
    ///
    /// | c     | r ∈ [1, 10]        | r ∈ [0.01, 1]      |
    /// |-------|--------------------|--------------------|
    /// | 0.3   | [−0.2306, +0.0286] | [−0.0188, +0.0001] |
    /// | 0.5   | [−0.1377, +0.0229] | [−0.0204, −0.0022] |
    /// | 0.7   | [−0.0165, +0.0056] | [−0.0086, −0.0010] |
    /// | 0.9   | [−0.0091, +0.0130] | [+0.0022, +0.0242] |
    /// | 0.99  | [−0.0027, +0.0274] | [+0.0047, +0.0485] |
    /// | 0.999 | [−0.0003, +0.0277] | [+0.0050, +0.0508] |
    ///
    /// So Grosjean is within 3% away from the source (1–10 mean free paths) for c ≥ 0.7 and
    /// within ≈ 5% inside the first mean free path for every c; for low albedo it drifts away
    /// far out because its decay rate λ = √(3(1−c)/(2−c)) differs from the exact 1/ν0 (the
    /// ratio then changes like e^{(1/ν0 − λ) r}). Asserted: each band widened by 10% + 0.001.
    #[test]
    fn grosjean_band() {
        // (c, far band on [1, 10], near band on [0.01, 1]) as measured.
        let bands = [
            (0.3, (-0.2306, 0.0286), (-0.0188, 0.0001)),
            (0.5, (-0.1377, 0.0229), (-0.0204, -0.0022)),
            (0.7, (-0.0165, 0.0056), (-0.0086, -0.0010)),
            (0.9, (-0.0091, 0.0130), (0.0022, 0.0242)),
            (0.99, (-0.0027, 0.0274), (0.0047, 0.0485)),
            (0.999, (-0.0003, 0.0277), (0.0050, 0.0508)),
        ];
        let band = |p: &ExactPointSource, r0: f64, r1: f64| {
            let (mut mn, mut mx) = (f64::INFINITY, f64::NEG_INFINITY);
            for i in 0..=200 {
                let r = r0 * (r1 / r0).powf(i as f64 / 200.0);
                let rel = grosjean(r, p.albedo()) / (4.0 * PI * p.fluence(r)) - 1.0;
                mn = mn.min(rel);
                mx = mx.max(rel);
            }
            (mn, mx)
        };
        let inside = |(mn, mx): (f64, f64), (lo, hi): (f64, f64)| {
            let margin = |v: f64| 0.1 * v.abs() + 0.001;
            mn >= lo - margin(lo) && mx <= hi + margin(hi)
        };
        for (c, far, near) in bands {
            let p = ExactPointSource::new(c).unwrap();
            let (f, n) = (band(&p, 1.0, 10.0), band(&p, 0.01, 1.0));
            eprintln!(
                "c={c}: r∈[1,10] [{:.4}, {:.4}]  r∈[0.01,1] [{:.4}, {:.4}]",
                f.0, f.1, n.0, n.1
            );
            assert!(inside(f, far), "c={c}: far band {f:?}");
            assert!(inside(n, near), "c={c}: near band {n:?}");
            if c >= 0.7 {
                assert!(f.0 > -0.03 && f.1 < 0.03, "c={c}: {f:?}");
            }
        }
    }

    #[test]
    fn bad_albedo_is_an_error() {
        for c in [-0.1, 1.0, 1.5, f64::NAN] {
            assert!(ExactPointSource::new(c).is_err(), "{c}");
        }
    }
}
