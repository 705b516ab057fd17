//! A unit-power isotropic point source at the origin of an unbounded homogeneous medium
//! with σt = 1 (lengths in mean free paths), albedo c < 1 and an isotropic or
//! Henyey–Greenstein phase function: spherical-shell tallies of the radial density
//! 4πr²φ(r), the quantity of FLD Section 4.1 (FLD Eq 25: φ̃ = 4πφ/σt², so 4πr²φ = τ²φ̃).
//!
//! **Estimator.** The shell average of the radial density over [r_i, r_{i+1}] is
//! (1/Δr) ∫ 4πr²φ dr = (1/Δr) ∫_shell φ dV = E[track length in the shell] / Δr for a unit
//! source, so each flight segment adds weight × (its length inside the shell) / Δr — an
//! exact chord computation per shell (the segment against the spheres r = r_i). Free paths
//! are exponential; at each collision the weight is multiplied by c (implicit capture,
//! Russian roulette below 0.1); the first flight is the *uncollided* (ballistic) part,
//! everything after the first collision *collided*.

use super::estimators::{Estimate, check_batches, run_paths};
use super::fluence::PathSettings;
use super::math::{Vec3, at, dot};
use super::phase::{sample_dir, uniform_sphere};
use super::rng::Rng;
use crate::ReferenceError;
use solvers::scene::Phase;

/// The unbounded medium (σt = 1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InfiniteMedium {
    /// Single-scattering albedo c ∈ [0, 1).
    pub albedo: f64,
    /// Phase function.
    pub phase: Phase,
}

/// Shell tally [r_inner, r_outer].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Shell {
    /// Inner radius (mean free paths).
    pub r_inner: f64,
    /// Outer radius.
    pub r_outer: f64,
    /// Shell average of 4πr²φ (total fluence, ballistic included).
    pub radial_density: Estimate,
    /// Shell average of the collided part of 4πr²φ.
    pub collided: Estimate,
    /// Shell average of the uncollided (ballistic) part of 4πr²φ.
    pub uncollided: Estimate,
}

const ROULETTE: f64 = 0.1;

impl InfiniteMedium {
    /// Validates c ∈ [0, 1) (at c = 1 no path would end) and the phase function.
    pub fn new(albedo: f64, phase: Phase) -> Result<Self, ReferenceError> {
        if !(0.0..1.0).contains(&albedo) {
            return Err(ReferenceError::BadParameter {
                name: "albedo",
                value: albedo,
                reason: "must lie in [0, 1) for an unbounded medium",
            });
        }
        phase.validate()?;
        Ok(Self { albedo, phase })
    }

    /// Shell averages of 4πr²φ between consecutive `edges` (≥ 2 values, 0 ≤ r₀ < r₁ < …).
    pub fn shells(
        &self,
        edges: &[f64],
        settings: &PathSettings,
    ) -> Result<Vec<Shell>, ReferenceError> {
        if edges.len() < 2 {
            return Err(ReferenceError::BadParameter {
                name: "edges",
                value: edges.len() as f64,
                reason: "need at least two shell edges",
            });
        }
        if let Some(w) = edges
            .windows(2)
            .find(|w| w[1].partial_cmp(&w[0]) != Some(std::cmp::Ordering::Greater))
        {
            return Err(ReferenceError::BadParameter {
                name: "edges",
                value: w[1],
                reason: "must be strictly increasing",
            });
        }
        if !(edges[0] >= 0.0 && edges[edges.len() - 1].is_finite()) {
            return Err(ReferenceError::BadParameter {
                name: "edges",
                value: edges[0],
                reason: "must be finite and ≥ 0",
            });
        }
        check_batches(settings.batches, settings.paths, "paths")?;
        let k = edges.len() - 1;
        let r2: Vec<f64> = edges.iter().map(|r| r * r).collect();
        let inv_dr: Vec<f64> = edges.windows(2).map(|w| 1.0 / (w[1] - w[0])).collect();
        let est = run_paths(settings.paths, settings.batches, 3 * k, |i, tally| {
            let mut rng = Rng::new(settings.seed, i);
            let mut p: Vec3 = [0.0; 3];
            let mut d = uniform_sphere(rng.uniform(), rng.uniform());
            let mut weight = 1.0;
            let mut depth = 0u32;
            let mut inside = vec![0.0; edges.len()];
            loop {
                let len = rng.exponential();
                // Chord length of the segment inside each ball r ≤ r_i.
                let b = dot(p, d);
                let c0 = dot(p, p);
                for (m, &rr) in r2.iter().enumerate() {
                    let disc = b * b - (c0 - rr);
                    inside[m] = if disc > 0.0 {
                        let s = disc.sqrt();
                        ((-b + s).min(len) - (-b - s).max(0.0)).max(0.0)
                    } else {
                        0.0
                    };
                }
                for j in 0..k {
                    let v = weight * (inside[j + 1] - inside[j]) * inv_dr[j];
                    tally[j] += v;
                    if depth > 0 {
                        tally[k + j] += v;
                    } else {
                        tally[2 * k + j] += v;
                    }
                }
                if settings.max_depth.is_some_and(|m| depth >= m) {
                    return;
                }
                p = at(p, d, len);
                weight *= self.albedo;
                if weight <= 0.0 {
                    return;
                }
                if weight < ROULETTE {
                    if rng.uniform() * ROULETTE >= weight {
                        return;
                    }
                    weight = ROULETTE;
                }
                depth += 1;
                d = sample_dir(&self.phase, d, rng.uniform(), rng.uniform());
            }
        });
        Ok((0..k)
            .map(|j| Shell {
                r_inner: edges[j],
                r_outer: edges[j + 1],
                radial_density: est[j],
                collided: est[k + j],
                uncollided: est[2 * k + j],
            })
            .collect())
    }
}
