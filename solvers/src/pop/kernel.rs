//! The per-cell formulas of POP, generic over [`Real`]: Henyey–Greenstein (Sec 4), the
//! cumulative G of Eq 1 in the cancellation-free closed form of spec §1.6, the Eq 3 patch
//! fractions and the Eq 4 anisotropy decay.

use crate::Real;

/// f_hg(μ, g) = (1/4π)·(1 − g²)/(1 + g² − 2gμ)^{3/2}, normalised over the sphere. Infinite
/// at g = μ = 1; [`hg_view`] is the clamped form Eq 8 evaluates.
#[inline(always)]
pub fn hg<T: Real>(mu: T, g: T) -> T {
    let one = T::one();
    // 1 + g² − 2gμ written as (1 − g)² + 2g(1 − μ), and 1 − g² as (1 − g)(1 + g): no
    // cancellation as g, μ → 1 (in f32 the expanded form gives d ≤ 0 at g = 1 − 10⁻⁴, μ = 1).
    let d = (one - g) * (one - g) + (g + g) * (one - mu);
    (one - g) * (one + g) / (T::c(4.0 * std::f64::consts::PI) * d * d.sqrt())
}

/// The largest lobe parameter Eq 8 evaluates (spec D8, V16): f_hg(1, 1) is a Dirac spike.
pub const A_MAX_VIEW: f64 = 1.0 - 1e-4;

/// [`hg`] with g clamped to [0, [`A_MAX_VIEW`]]: finite for every g ∈ [0, 1].
#[inline(always)]
pub fn hg_view<T: Real>(mu: T, g: T) -> T {
    hg(mu, g.max(T::zero()).min(T::c(A_MAX_VIEW)))
}

/// G(μ, a) = 2π·F_hg(μ, a) = ∫_{−1}^{μ} 2π f_hg(μ′, a) dμ′ (POP Eq 1 with the azimuth
/// applied), in the closed form of spec §1.6: G = (1 − a)(1 + μ)/(s(1 + a + s)),
/// s = √(1 + a² − 2aμ). No cancellation; (1 + μ)/2 at a = 0; 0 at a = 1 for μ < 1.
/// Defined for μ ∈ [−1, 1), a ∈ [0, 1] (and μ = 1 for a < 1, where it is 1).
#[inline(always)]
pub fn cumulative<T: Real>(mu: T, a: T) -> T {
    let one = T::one();
    let s = (one + a * a - (a + a) * mu).sqrt();
    (one - a) * (one + mu) / (s * (one + a + s))
}

/// Fractions of a cell's radiance that Eq 3's patches send to its front neighbour (the
/// cone θ ∈ [0, π/4] about d), to each of the four lateral neighbours (a quarter of the
/// band θ ∈ [π/4, 3π/4]) and to the back neighbour (θ ∈ [3π/4, π]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fractions<T> {
    /// To the neighbour ahead along d: 1 − G(1/√2, a).
    pub front: T,
    /// To each lateral neighbour: (G(1/√2, a) − G(−1/√2, a))/4.
    pub side: T,
    /// To the neighbour behind: G(−1/√2, a).
    pub back: T,
}

/// The Eq 2–3 fractions of a lobe of anisotropy `a` ∈ [0, 1] (front + 4·side + back = 1 to
/// rounding, test T1).
#[inline(always)]
pub fn fractions<T: Real>(a: T) -> Fractions<T> {
    let c = T::FRAC_1_SQRT_2();
    let gp = cumulative(c, a);
    let gm = cumulative(-c, a);
    Fractions {
        front: T::one() - gp,
        side: (gp - gm) * T::c(0.25),
        back: gm,
    }
}

/// γ = g^{x} with x = σ̄s·z (POP Eq 4: the anisotropy factor over a distance z), with the
/// branches of spec V16: x = 0 (vacuum) gives 1 whatever g (also g = 0: no pow(0, 0)), and
/// g = 0 with x > 0 gives 0.
#[inline(always)]
pub fn decay(g: f64, x: f64) -> f64 {
    if x == 0.0 {
        1.0
    } else if g == 0.0 {
        0.0
    } else {
        g.powf(x)
    }
}
