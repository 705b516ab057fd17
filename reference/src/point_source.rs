//! A unit-power isotropic point source in an infinite homogeneous medium with extinction σt
//! and single-scattering albedo α (FLD Section 4.1).
//!
//! All solutions are expressed through the optical depth τ = σt r and the normalised fluence
//! φ̃(τ) = 4π φ / σt² of FLD Eq 25, which is independent of σt ("universal"). The physical
//! fluence is φ(r) = σt²/(4π) · φ̃(σt r), in power per unit area for a unit-power source.

use crate::ReferenceError;

/// Which analytic solution.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Solution {
    /// Grosjean's approximation to transport (FLD Eq 24): ballistic plus a modified diffusion term.
    Grosjean,
    /// The CDA Green's function (FLD Eq 27).
    Cda,
    /// The transport limit of FLD (FLD Eq 29), e^{−(1−α)τ}/τ².
    TransportLimit,
}

/// Normalised Grosjean fluence (FLD Eqs 24, 25):
/// φ̃ = e^{−τ}/τ² + 3α/(2 − α) · e^{−λτ}/τ, λ² = 3(1 − α)/(2 − α).
pub fn grosjean(tau: f64, albedo: f64) -> f64 {
    let lambda = (3.0 * (1.0 - albedo) / (2.0 - albedo)).sqrt();
    (-tau).exp() / (tau * tau) + 3.0 * albedo / (2.0 - albedo) * (-lambda * tau).exp() / tau
}

/// Normalised CDA Green's function (FLD Eqs 25, 27): φ̃ = 3 e^{−√(3(1−α)) τ}/τ.
pub fn cda(tau: f64, albedo: f64) -> f64 {
    3.0 * (-(3.0 * (1.0 - albedo)).sqrt() * tau).exp() / tau
}

/// Normalised transport limit of FLD (FLD Eqs 25, 29): φ̃ = e^{−(1−α)τ}/τ².
pub fn transport_limit(tau: f64, albedo: f64) -> f64 {
    (-(1.0 - albedo) * tau).exp() / (tau * tau)
}

/// Knudsen number R = |∇φ|/(σt φ) = |dφ̃/dτ|/φ̃ of the Grosjean solution (FLD Eq 16,
/// Fig 3c), from the analytic derivative. R → 2/τ as τ → 0 (transport regime).
pub fn grosjean_knudsen(tau: f64, albedo: f64) -> f64 {
    let lambda = (3.0 * (1.0 - albedo) / (2.0 - albedo)).sqrt();
    let a = 3.0 * albedo / (2.0 - albedo);
    let (eb, ed) = ((-tau).exp(), (-lambda * tau).exp());
    let phi = eb / (tau * tau) + a * ed / tau;
    let dphi = -eb * (1.0 / (tau * tau) + 2.0 / (tau * tau * tau))
        - a * ed * (lambda / tau + 1.0 / (tau * tau));
    dphi.abs() / phi
}

impl Solution {
    /// Normalised fluence φ̃(τ).
    pub fn normalized(&self, tau: f64, albedo: f64) -> f64 {
        match self {
            Solution::Grosjean => grosjean(tau, albedo),
            Solution::Cda => cda(tau, albedo),
            Solution::TransportLimit => transport_limit(tau, albedo),
        }
    }
}

/// A unit-power point source in a medium with given σt and α, in physical units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointSource {
    /// Extinction σt [1/length], > 0.
    pub sigma_t: f64,
    /// Albedo α ∈ [0, 1].
    pub albedo: f64,
}

impl PointSource {
    /// Validates σt > 0 finite and α ∈ [0, 1].
    pub fn new(sigma_t: f64, albedo: f64) -> Result<Self, ReferenceError> {
        if !(sigma_t.is_finite() && sigma_t > 0.0) {
            return Err(ReferenceError::BadParameter {
                name: "sigma_t",
                value: sigma_t,
                reason: "must be finite and > 0",
            });
        }
        if !(0.0..=1.0).contains(&albedo) {
            return Err(ReferenceError::BadParameter {
                name: "albedo",
                value: albedo,
                reason: "must be in [0, 1]",
            });
        }
        Ok(Self { sigma_t, albedo })
    }

    /// Physical fluence φ(r) of `solution` at distance r > 0 from the source.
    pub fn fluence(&self, solution: Solution, r: f64) -> f64 {
        self.sigma_t * self.sigma_t / (4.0 * std::f64::consts::PI)
            * solution.normalized(self.sigma_t * r, self.albedo)
    }

    /// FLD Eq 25: the normalised fluence φ̃ = 4πφ/σt² of a physical fluence φ.
    pub fn normalize(&self, phi: f64) -> f64 {
        4.0 * std::f64::consts::PI * phi / (self.sigma_t * self.sigma_t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::quadrature::simpson;

    const ALBEDOS: [f64; 6] = [0.1, 0.3, 0.5, 0.7, 0.9, 0.99];

    /// Energy balance: absorbed power σa ∫ 4πr² φ dr equals the unit source power, for the
    /// Grosjean and CDA solutions (both conserve energy; Eq 24's weights are built to).
    #[test]
    fn grosjean_and_cda_conserve_energy() {
        for a in ALBEDOS.into_iter().filter(|&a| a < 0.95) {
            let ps = PointSource::new(2.5, a).unwrap();
            let sa = (1.0 - a) * ps.sigma_t;
            for sol in [Solution::Grosjean, Solution::Cda] {
                // Substitute r = u² to tame the 1/r² singularity of the ballistic term at 0.
                // The integrand 4πr²φ(r)·2u is bounded and → 0 as u → 0.
                let f = |u: f64| {
                    let r = u * u;
                    if r == 0.0 {
                        0.0
                    } else {
                        4.0 * std::f64::consts::PI * r * r * ps.fluence(sol, r) * 2.0 * u
                    }
                };
                let total = sa
                    * simpson(
                        f,
                        0.0,
                        (60.0 / ((1.0 - a).sqrt() * ps.sigma_t)).sqrt(),
                        200_000,
                    );
                assert!(
                    (total - 1.0).abs() < 1e-6,
                    "{sol:?} α={a}: absorbed power {total}"
                );
            }
        }
    }

    /// The CDA Green's function solves D(φ'' + 2φ'/r) = σa φ with D = 1/(3σt) (FLD Eq 26).
    #[test]
    fn cda_solves_screened_poisson() {
        for a in ALBEDOS {
            let ps = PointSource::new(3.0, a).unwrap();
            let d = 1.0 / (3.0 * ps.sigma_t);
            let sa = (1.0 - a) * ps.sigma_t;
            for r in [0.05, 0.3, 1.0, 2.0] {
                let h = 1e-3 * r;
                let f = |x: f64| ps.fluence(Solution::Cda, x);
                let (fm, f0, fp) = (f(r - h), f(r), f(r + h));
                let lap = (fp - 2.0 * f0 + fm) / (h * h) + 2.0 / r * (fp - fm) / (2.0 * h);
                // Tolerance relative to the size of the cancelling terms, d·2φ/r² (and the O(h²) error).
                let scale = (d * 2.0 * f0 / (r * r)).max(sa * f0);
                assert!(
                    (d * lap - sa * f0).abs() <= 1e-5 * scale,
                    "α={a} r={r}: {} vs {}",
                    d * lap,
                    sa * f0
                );
            }
        }
    }

    /// The transport limit solves FLD Eq 28 away from the source: (1/τ²) d(τ²φ̃)/dτ + (1−α)φ̃ = 0.
    #[test]
    fn transport_limit_solves_eq_28() {
        for a in ALBEDOS {
            for tau in [0.1, 1.0, 3.0] {
                let h = 1e-5;
                let g = |t: f64| t * t * transport_limit(t, a);
                let lhs = (g(tau + h) - g(tau - h)) / (2.0 * h) / (tau * tau)
                    + (1.0 - a) * transport_limit(tau, a);
                assert!(
                    lhs.abs() < 1e-6 * transport_limit(tau, a),
                    "α={a} τ={tau}: {lhs}"
                );
            }
        }
    }

    /// FLD Section 4.1: R → 2/τ as τ → 0; at α = 0 Grosjean is the exact ballistic solution
    /// and equals the transport limit; far out Grosjean's R tends to the slower of its two
    /// decay rates, λ for α > ½ and 1 (ballistic) for α < ½, plus the power-law term.
    #[test]
    fn grosjean_limits() {
        for a in ALBEDOS {
            let tau = 1e-4;
            assert!((grosjean_knudsen(tau, a) * tau / 2.0 - 1.0).abs() < 1e-3);
            let lambda = (3.0 * (1.0 - a) / (2.0 - a)).sqrt();
            let far = 200.0;
            let expected = if (lambda - 1.0).abs() < 1e-12 {
                1.0 + 1.0 / far // α = ½: equal rates, the 1/τ term wins
            } else if lambda < 1.0 {
                lambda + 1.0 / far
            } else {
                1.0 + 2.0 / far
            };
            assert!(
                (grosjean_knudsen(far, a) - expected).abs() < 1e-3,
                "α={a}: {} vs {expected}",
                grosjean_knudsen(far, a)
            );
        }
        for tau in [0.01, 0.5, 4.0] {
            assert!((grosjean(tau, 0.0) / transport_limit(tau, 0.0) - 1.0).abs() < 1e-14);
        }
    }

    #[test]
    fn bad_parameters_are_errors() {
        assert!(PointSource::new(0.0, 0.5).is_err());
        assert!(PointSource::new(1.0, 1.5).is_err());
        assert!(PointSource::new(f64::NAN, 0.5).is_err());
    }
}
