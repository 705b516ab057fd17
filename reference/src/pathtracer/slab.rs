//! A homogeneous plane-parallel slab 0 ≤ z ≤ τ (σt = 1, so z is optical depth; τ may be
//! infinite), laterally unbounded, albedo c and phase function p, lit by a collimated beam
//! entering the top face z = 0 at direction cosine μ0 ∈ (0, 1].
//!
//! All results are fractions of the incident power (flux ratios): reflectance R (power
//! leaving through z = 0 — Chandrasekhar's plane albedo for τ = ∞), diffuse transmittance
//! T_d (scattered power leaving through z = τ), direct transmittance T_dir = e^{−τ/μ0}
//! (exact, not sampled), and absorptance A. Energy conservation: R + T_d + T_dir + A = 1.
//!
//! Lateral position is irrelevant for a homogeneous, laterally infinite slab, so only depth
//! and the 3D direction are tracked. Free paths are exponential; a collision absorbs the
//! particle with probability 1 − c, scoring 1 to A (analog absorption, as for the
//! point-source shells, where it measured more efficient than implicit capture at high c).
//! Particles that cross z = 0 / z = τ score 1 to R / T_d. Flights leaving the slab before
//! any collision are the direct beam and score nothing (T_dir is known exactly).
//!
//! **Measured** (`results/pt_slab`, 4·10⁶ paths per case, 32 batches): for τ ∈ {1, ∞},
//! c ∈ {0.5, 0.9, 0.99}, g ∈ {0, 0.5, 0.9}, μ0 ∈ {1, 0.5}, all 54 R and T_d values are within
//! |z| ≤ 2.20 of the adding–doubling solver ([`crate::transport::slab`]), the isotropic
//! half-space R within |z| ≤ 2.08 of the H-function plane albedo, and the energy balance
//! within |z| ≤ 1.67.

use super::estimators::{Estimate, check_batches, run_batches};
use super::fluence::PathSettings;
use super::phase::sample_dir;
use super::rng::Rng;
use super::shard::{BatchSums, Shard};
use crate::ReferenceError;
use solvers::scene::Phase;

/// The slab problem.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SlabMedium {
    /// Optical thickness τ > 0 (`f64::INFINITY`: semi-infinite).
    pub tau: f64,
    /// Albedo c ∈ [0, 1] (< 1 if τ = ∞).
    pub albedo: f64,
    /// Phase function.
    pub phase: Phase,
}

/// Slab results as fractions of the incident power.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SlabTally {
    /// Reflectance R.
    pub reflectance: Estimate,
    /// Diffuse transmittance T_d.
    pub transmittance_diffuse: Estimate,
    /// Direct transmittance e^{−τ/μ0} (exact).
    pub transmittance_direct: f64,
    /// Absorptance A.
    pub absorptance: Estimate,
    /// R + T_d + A + T_dir, which is 1 for an unlimited depth (its stderr from the summed
    /// batch means, so correlations between the parts are included).
    pub balance: Estimate,
}

impl SlabMedium {
    /// Validates τ > 0, c ∈ [0, 1] (c < 1 if τ = ∞) and the phase function.
    pub fn new(tau: f64, albedo: f64, phase: Phase) -> Result<Self, ReferenceError> {
        if tau.is_nan() || tau <= 0.0 {
            return Err(ReferenceError::BadParameter {
                name: "tau",
                value: tau,
                reason: "must be > 0 (or infinite)",
            });
        }
        if !(0.0..=1.0).contains(&albedo) || (tau.is_infinite() && albedo >= 1.0) {
            return Err(ReferenceError::BadParameter {
                name: "albedo",
                value: albedo,
                reason: "must lie in [0, 1], and below 1 for a semi-infinite slab",
            });
        }
        phase.validate()?;
        Ok(Self { tau, albedo, phase })
    }

    /// Simulates collimated incidence at cosine `mu0` ∈ (0, 1].
    pub fn simulate(&self, mu0: f64, settings: &PathSettings) -> Result<SlabTally, ReferenceError> {
        let sums = self.simulate_part(mu0, settings, Shard::WHOLE)?;
        self.tally(mu0, &sums)
    }

    /// [`SlabMedium::simulate`] for `shard`'s batches: their per-batch sums (four bins: R,
    /// T_d, A, and the balance without T_dir), for [`SlabMedium::tally`] once joined.
    pub fn simulate_part(
        &self,
        mu0: f64,
        settings: &PathSettings,
        shard: Shard,
    ) -> Result<BatchSums, ReferenceError> {
        if !(mu0 > 0.0 && mu0 <= 1.0) {
            return Err(ReferenceError::BadParameter {
                name: "mu0",
                value: mu0,
                reason: "must lie in (0, 1]",
            });
        }
        check_batches(settings.batches, settings.paths, "paths")?;
        let tau = self.tau;
        run_batches(settings.paths, settings.batches, 4, shard, |i, t| {
            let mut rng = Rng::new(settings.seed, i);
            let mut z = 0.0f64;
            let mut d = [(1.0 - mu0 * mu0).max(0.0).sqrt(), 0.0, mu0];
            let mut depth = 0u32;
            loop {
                z += d[2] * rng.exponential();
                if z < 0.0 {
                    t[0] += 1.0;
                    t[3] += 1.0;
                    return;
                }
                if z > tau {
                    if depth > 0 {
                        t[1] += 1.0;
                        t[3] += 1.0;
                    }
                    return;
                }
                if settings.max_depth.is_some_and(|m| depth >= m) {
                    return;
                }
                if rng.uniform() >= self.albedo {
                    t[2] += 1.0;
                    t[3] += 1.0;
                    return;
                }
                depth += 1;
                d = sample_dir(&self.phase, d, rng.uniform(), rng.uniform());
            }
        })
    }

    /// The tally of a whole run from its joined per-batch sums ([`SlabMedium::simulate_part`]).
    pub fn tally(&self, mu0: f64, sums: &BatchSums) -> Result<SlabTally, ReferenceError> {
        if sums.bins != 4 {
            return Err(ReferenceError::ShardMismatch {
                what: format!("a slab tally has 4 bins, these sums {}", sums.bins),
            });
        }
        let est = sums.estimates()?;
        let direct = if self.tau.is_infinite() {
            0.0
        } else {
            (-self.tau / mu0).exp()
        };
        Ok(SlabTally {
            reflectance: est[0],
            transmittance_diffuse: est[1],
            transmittance_direct: direct,
            absorptance: est[2],
            balance: Estimate {
                mean: est[3].mean + direct,
                stderr: est[3].stderr,
            },
        })
    }
}
