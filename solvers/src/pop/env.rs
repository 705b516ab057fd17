//! Environment lighting by N ordinates (POP Sec 5.1, spec D10–D11): a deterministic
//! spherical Fibonacci set, each ordinate carrying the radiance of its Voronoi cell on the
//! sphere, with the exact first-moment prefilter (the paper's definition) or the paper's
//! heuristic.

use super::Ordinate;
use crate::SolverError;
use std::f64::consts::PI;

/// How the initial anisotropy a_n of an environment ordinate is set (Sec 5.1, spec D11, V7).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Prefilter {
    /// a_n = 1, d_n = the Fibonacci direction: no prefiltering (ray effects, Fig 6).
    None,
    /// D11 (default): d_n = the radiance-weighted centroid of the Voronoi cell,
    /// a_n = |∫_{Ω_n} L ω dω| / ∫_{Ω_n} L dω, the radiance-weighted mean cosine. Preserves
    /// energy and the first moment: Σ E_n a_n d_n = ∫ L ω dω.
    #[default]
    Voronoi,
    /// The paper's heuristic a_n = (1 − w_n/N)^β with w_n = NΩ_n/(4π) (the reading of
    /// spec V7 under which β = 1 is the cap value 1 − Ω_n/4π); d_n = the Fibonacci direction.
    Heuristic {
        /// β > 0.
        beta: f64,
    },
}

/// The spherical Fibonacci set of `n` directions (equal areas 4π/n; deterministic).
pub fn fibonacci(n: usize) -> Vec<[f64; 3]> {
    let golden = (1.0 + 5f64.sqrt()) / 2.0;
    (0..n)
        .map(|i| {
            let z = 1.0 - (2 * i + 1) as f64 / n as f64;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = 2.0 * PI * (i as f64 / golden).fract();
            [r * phi.cos(), r * phi.sin(), z]
        })
        .collect()
}

/// Exact ∫ ω dω over the latitude–longitude texel θ ∈ [θ0, θ1], φ ∈ [φ0, φ1]
/// (θ from +z), and its solid angle.
fn texel_moments(t0: f64, t1: f64, p0: f64, p1: f64) -> (f64, [f64; 3]) {
    let omega = (p1 - p0) * (t0.cos() - t1.cos());
    // ∫ sin²θ dθ = θ/2 − sin 2θ/4; ∫ sinθ cosθ dθ = sin²θ/2.
    let s2 = (t1 - t0) / 2.0 - ((2.0 * t1).sin() - (2.0 * t0).sin()) / 4.0;
    let sc = (t1.sin().powi(2) - t0.sin().powi(2)) / 2.0;
    (
        omega,
        [
            s2 * (p1.sin() - p0.sin()),
            s2 * (p0.cos() - p1.cos()),
            sc * (p1 - p0),
        ],
    )
}

/// The N ordinates of an environment of radiance `radiance(ω)` (ω the direction *from which*
/// light arrives, as seen from the medium; light travels along −ω), rasterised on a
/// `2r × r` latitude–longitude map whose texels are assigned to the nearest Fibonacci
/// direction (spec D10): E_n = Σ L Ω_texel, so Σ E_n = ∫ L dω for any piecewise-constant
/// map, exactly. Errors: n = 0, r < 2, β ≤ 0, a negative or non-finite radiance.
pub fn environment_ordinates(
    radiance: impl Fn([f64; 3]) -> f64,
    n: usize,
    prefilter: Prefilter,
    resolution: usize,
) -> Result<Vec<Ordinate>, SolverError> {
    if n == 0 {
        return Err(SolverError::BadParameter {
            name: "ordinates",
            value: 0.0,
            reason: "an environment needs at least one ordinate",
        });
    }
    if resolution < 2 {
        return Err(SolverError::BadParameter {
            name: "environment.resolution",
            value: resolution as f64,
            reason: "the latitude-longitude map needs at least 2 rows",
        });
    }
    if let Prefilter::Heuristic { beta } = prefilter {
        if !(beta.is_finite() && beta > 0.0) {
            return Err(SolverError::BadParameter {
                name: "prefilter.beta",
                value: beta,
                reason: "the heuristic's exponent must be finite and > 0",
            });
        }
    }
    let dirs = fibonacci(n);
    let mut energy = vec![0.0; n];
    let mut moment = vec![[0.0; 3]; n];
    let mut area = vec![0.0; n];
    let (rows, cols) = (resolution, 2 * resolution);
    for r in 0..rows {
        let t0 = PI * r as f64 / rows as f64;
        let t1 = PI * (r + 1) as f64 / rows as f64;
        for c in 0..cols {
            let p0 = 2.0 * PI * c as f64 / cols as f64;
            let p1 = 2.0 * PI * (c + 1) as f64 / cols as f64;
            let (tm, pm) = ((t0 + t1) / 2.0, (p0 + p1) / 2.0);
            let w = [tm.sin() * pm.cos(), tm.sin() * pm.sin(), tm.cos()];
            let l = radiance(w);
            if !(l.is_finite() && l >= 0.0) {
                return Err(SolverError::BadParameter {
                    name: "environment.radiance",
                    value: l,
                    reason: "must be finite and ≥ 0",
                });
            }
            // Nearest ordinate (first on ties: deterministic).
            let mut best = 0;
            let mut best_dot = f64::NEG_INFINITY;
            for (i, d) in dirs.iter().enumerate() {
                let dd = d[0] * w[0] + d[1] * w[1] + d[2] * w[2];
                if dd > best_dot {
                    best_dot = dd;
                    best = i;
                }
            }
            let (omega, m) = texel_moments(t0, t1, p0, p1);
            energy[best] += l * omega;
            area[best] += omega;
            for k in 0..3 {
                moment[best][k] += l * m[k];
            }
        }
    }
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        // The ordinate travels away from where the light comes from: direction −ω.
        let (direction, anisotropy) = match prefilter {
            Prefilter::None => (dirs[i].map(|v| -v), 1.0),
            Prefilter::Heuristic { beta } => (
                dirs[i].map(|v| -v),
                (1.0 - area[i] / (4.0 * PI)).max(0.0).powf(beta),
            ),
            Prefilter::Voronoi => {
                let m = moment[i];
                let len = (m[0] * m[0] + m[1] * m[1] + m[2] * m[2]).sqrt();
                if energy[i] > 0.0 && len > 0.0 {
                    (m.map(|v| -v / len), (len / energy[i]).min(1.0))
                } else {
                    (dirs[i].map(|v| -v), 1.0)
                }
            }
        };
        out.push(Ordinate {
            direction,
            irradiance: energy[i],
            anisotropy,
            emission: 0.0,
        });
    }
    Ok(out)
}

/// The ordinates that carry an isotropic volume emission (ours, not the paper's): the
/// ordinates of a constant unit environment (the same `n`, `prefilter` and `resolution` as
/// [`environment_ordinates`]), with no irradiance and the emission share w_n = E_n/Σ E =
/// Ω_n/4π of each, so Σ w_n = 1 and, with the D11 prefilter, Σ w_n a_n d_n = 0 (both the
/// energy and the first moment of isotropic emission; `pop/tests.rs`, `emission_…`).
/// Light emitted into the cap of ordinate n travels within that cap, whose mean cosine about
/// d_n is the a_n that D11 gives a constant environment's ordinate.
pub fn emission_ordinates(
    n: usize,
    prefilter: Prefilter,
    resolution: usize,
) -> Result<Vec<Ordinate>, SolverError> {
    let mut out = environment_ordinates(|_| 1.0, n, prefilter, resolution)?;
    let total: f64 = out.iter().map(|o| o.irradiance).sum();
    for o in &mut out {
        o.emission = (o.irradiance / total).min(1.0);
        o.irradiance = 0.0;
    }
    Ok(out)
}

/// Lets the ordinates `env` of a constant environment (from [`environment_ordinates`] with
/// the same `n`, prefilter and resolution as `emission`, the output of
/// [`emission_ordinates`]) carry the emission too, so both share one set of grids: each
/// takes the share of its twin. The twins have the same Voronoi cells; their directions and
/// anisotropies agree to rounding (a constant radiance scales the moments and the energy
/// alike). Returns false, changing nothing, when the sets differ in size or a pair differs
/// by more than 10⁻⁹ in direction or anisotropy (an environment of radiance 0 keeps the
/// Fibonacci directions): then the emission needs its own ordinates.
pub fn share_emission(env: &mut [Ordinate], emission: &[Ordinate]) -> bool {
    let twins = env.len() == emission.len()
        && env.iter().zip(emission).all(|(a, b)| {
            (0..3).all(|c| (a.direction[c] - b.direction[c]).abs() <= 1e-9)
                && (a.anisotropy - b.anisotropy).abs() <= 1e-9
        });
    if twins {
        for (a, b) in env.iter_mut().zip(emission) {
            a.emission = b.emission;
        }
    }
    twins
}
