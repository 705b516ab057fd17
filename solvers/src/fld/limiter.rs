//! Flux limiters F(R) of FLD Table 2, plus the constant 1/3 of classical diffusion (CDA).
//!
//! A flux limiter turns the Knudsen number R = |∇φ|/(σt φ) (FLD Eq 16) into the
//! dimensionless factor of the diffusion coefficient D = F(R)/σt (FLD Eq 15). Every limiter
//! here except [`FluxLimiter::Cda`] satisfies FLD Eq 19, F(0) = 1/3 and R·F(R) → 1, and the
//! flux constraint F ≤ 1/R of FLD Eq 17; the property tests below check all three over
//! R ∈ [0, 10⁶] in both precisions.
//!
//! Every formula is written so it cannot overflow or cancel catastrophically in `f32`
//! (the GPU precision): Kershaw uses a hypotenuse instead of `9 + 4R²`, Larsen-n factors out
//! max(3, R) before raising to the n-th power, and Levermore–Pomraning is evaluated through
//! its continued fraction near 0 (see [`levermore_pomraning`]).

use crate::{Real, SolverError};
use std::fmt;
use std::str::FromStr;

/// The flux limiter F(R) (FLD Table 2) and, as the constant case, classical diffusion.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FluxLimiter {
    /// Classical diffusion, F = 1/3 (FLD Eq 11; "the FLD solver with flux limiter set to
    /// constant F = 1/3", Section 6.1). Not a limiter: it violates F ≤ 1/R for R > 3.
    Cda,
    /// Sum limiter [BW82], F = 1/(3 + R).
    Sum,
    /// Max limiter [BW82], F = 1/max(3, R).
    Max,
    /// Kershaw [Ker76], F = 2/(3 + √(9 + 4R²)).
    Kershaw,
    /// Larsen-n [LK74], F = (3ⁿ + Rⁿ)^(−1/n), n > 0 (commonly 2).
    Larsen(f64),
    /// Levermore–Pomraning [LP81], F = (coth R − 1/R)/R. The paper's choice for all its images.
    LevermorePomraning,
}

impl FluxLimiter {
    /// Every limiter compared in the flux-limiter figure, in display order (Larsen with n = 2).
    pub const ALL: [FluxLimiter; 6] = [
        FluxLimiter::Cda,
        FluxLimiter::Sum,
        FluxLimiter::Max,
        FluxLimiter::Kershaw,
        FluxLimiter::Larsen(2.0),
        FluxLimiter::LevermorePomraning,
    ];

    /// Whether F depends on R. CDA does not, so its solve skips the Knudsen number entirely.
    pub fn is_constant(&self) -> bool {
        matches!(self, FluxLimiter::Cda)
    }

    /// Checks the limiter's parameter (Larsen's n must be finite and > 0).
    pub fn validate(&self) -> Result<(), SolverError> {
        match *self {
            FluxLimiter::Larsen(n) if !(n.is_finite() && n > 0.0) => {
                Err(SolverError::BadParameter {
                    name: "larsen n",
                    value: n,
                    reason: "must be finite and > 0",
                })
            }
            _ => Ok(()),
        }
    }

    /// F(R) for R ≥ 0 (a negative or NaN R is treated as 0).
    #[inline(always)]
    pub fn eval<T: Real>(&self, r: T) -> T {
        let r = if r > T::zero() { r } else { T::zero() };
        let three = T::c(3.0);
        match *self {
            FluxLimiter::Cda => T::one() / three,
            FluxLimiter::Sum => T::one() / (three + r),
            FluxLimiter::Max => T::one() / three.max(r),
            FluxLimiter::Kershaw => T::c(2.0) / (three + three.hypot(T::c(2.0) * r)),
            FluxLimiter::Larsen(n) => {
                // (3ⁿ + Rⁿ)^(−1/n) = 1 / (m · ((3/m)ⁿ + (R/m)ⁿ)^(1/n)), m = max(3, R): no overflow.
                let n = T::c(n);
                let m = three.max(r);
                let s = (three / m).powf(n) + (r / m).powf(n);
                T::one() / (m * s.powf(T::one() / n))
            }
            FluxLimiter::LevermorePomraning => levermore_pomraning(r),
        }
    }
}

/// Depth of the continued fraction used for R ≤ [`LP_SWITCH`]: relative truncation error
/// below 10⁻¹⁵ there (measured against 40-digit arithmetic when this was written).
const LP_DEPTH: usize = 10;
/// Knudsen number above which the closed form is used (its cancellation costs < 1 bit there).
const LP_SWITCH: f64 = 2.0;

/// The Levermore–Pomraning limiter F(R) = (coth R − 1/R)/R (FLD Table 2), accurate and
/// continuous in `f32` and `f64` for all R ≥ 0.
///
/// The closed form cancels catastrophically as R → 0 (coth R ≈ 1/R). Near 0 we use Lambert's
/// continued fraction of coth, which gives
/// F(R) = 1/(3 + R²/(5 + R²/(7 + R²/(9 + …)))),
/// the convergent form of the series 1/3 − R²/45 + 2R⁴/945 − …: every term is positive, so
/// there is no cancellation at all, and F(0) = 1/3 exactly. It is evaluated with the forward
/// recurrence for numerator and denominator (one division, vectorisable, and the same code
/// runs in WGSL). For R > 2, coth R = (1 + e)/(1 − e) with e = exp(−2R) ≤ 0.02, and
/// coth R − 1/R ≥ 0.53·coth R, so the closed form loses less than one bit; R·F(R) → 1 as
/// R → ∞ with no overflow.
#[inline(always)]
pub fn levermore_pomraning<T: Real>(r: T) -> T {
    if r <= T::c(LP_SWITCH) {
        // Convergent A/B of b0 + a/(b1 + a/(b2 + …)), b_k = 2k + 3, a = R².
        let a = r * r;
        let (mut a_prev, mut a_cur) = (T::one(), T::c(3.0));
        let (mut b_prev, mut b_cur) = (T::zero(), T::one());
        for k in 1..=LP_DEPTH {
            let bk = T::c((2 * k + 3) as f64);
            let a_next = bk * a_cur + a * a_prev;
            let b_next = bk * b_cur + a * b_prev;
            (a_prev, a_cur, b_prev, b_cur) = (a_cur, a_next, b_cur, b_next);
        }
        b_cur / a_cur
    } else {
        let e = (T::c(-2.0) * r).exp();
        let coth = (T::one() + e) / (T::one() - e);
        (coth - T::one() / r) / r
    }
}

impl fmt::Display for FluxLimiter {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FluxLimiter::Cda => write!(f, "cda"),
            FluxLimiter::Sum => write!(f, "sum"),
            FluxLimiter::Max => write!(f, "max"),
            FluxLimiter::Kershaw => write!(f, "kershaw"),
            FluxLimiter::Larsen(n) => write!(f, "larsen{n}"),
            FluxLimiter::LevermorePomraning => write!(f, "lp"),
        }
    }
}

impl FromStr for FluxLimiter {
    type Err = SolverError;
    /// Parses `cda`, `sum`, `max`, `kershaw`, `larsen` (n = 2), `larsen<n>` / `larsen-<n>`,
    /// `lp` / `levermore-pomraning` (case-insensitive).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let t = s.trim().to_ascii_lowercase();
        let lim = match t.as_str() {
            "cda" | "classical" => FluxLimiter::Cda,
            "sum" => FluxLimiter::Sum,
            "max" => FluxLimiter::Max,
            "kershaw" => FluxLimiter::Kershaw,
            "lp" | "levermore-pomraning" | "levermorepomraning" => FluxLimiter::LevermorePomraning,
            "larsen" => FluxLimiter::Larsen(2.0),
            _ => match t.strip_prefix("larsen") {
                Some(n) => {
                    let n: f64 = n
                        .trim_start_matches(['-', '_'])
                        .parse()
                        .map_err(|_| SolverError::UnknownLimiter(s.to_string()))?;
                    FluxLimiter::Larsen(n)
                }
                None => return Err(SolverError::UnknownLimiter(s.to_string())),
            },
        };
        lim.validate()?;
        Ok(lim)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Reference LP in f64 by the series (R < 0.1) or closed form, independent of the code above.
    fn lp_reference(r: f64) -> f64 {
        if r < 0.1 {
            let x2 = r * r;
            1.0 / 3.0 - x2 / 45.0 + 2.0 * x2 * x2 / 945.0 - x2 * x2 * x2 / 4725.0
                + 2.0 * x2.powi(4) / 93555.0
        } else {
            (1.0 / r.tanh() - 1.0 / r) / r
        }
    }

    const LIMITERS: [FluxLimiter; 7] = [
        FluxLimiter::Sum,
        FluxLimiter::Max,
        FluxLimiter::Kershaw,
        FluxLimiter::Larsen(1.0),
        FluxLimiter::Larsen(2.0),
        FluxLimiter::Larsen(7.5),
        FluxLimiter::LevermorePomraning,
    ];

    #[test]
    fn limits_of_eq_19_hold() {
        for lim in LIMITERS {
            assert!(
                (lim.eval(0.0f64) - 1.0 / 3.0).abs() < 1e-15,
                "{lim}: F(0) = {}",
                lim.eval(0.0f64)
            );
            assert!((lim.eval(0.0f32) - 1.0 / 3.0).abs() < 1e-7, "{lim}: F32(0)");
            let r = 1e6f64;
            let rf = r * lim.eval(r);
            assert!((rf - 1.0).abs() < 1e-5, "{lim}: R·F(R) at R = 1e6 is {rf}");
            let rf32 = 1e6f32 * lim.eval(1e6f32);
            assert!(
                (rf32 - 1.0).abs() < 1e-5,
                "{lim}: f32 R·F(R) at R = 1e6 is {rf32}"
            );
        }
    }

    #[test]
    fn lp_matches_independent_reference_and_is_continuous_at_switch() {
        for i in 0..=4000 {
            let r = i as f64 * 1e-3;
            let (a, b) = (levermore_pomraning(r), lp_reference(r));
            assert!((a / b - 1.0).abs() < 2e-13, "R = {r}: {a} vs {b}");
        }
        let below = levermore_pomraning(LP_SWITCH);
        let above = levermore_pomraning(LP_SWITCH * (1.0 + 1e-15));
        assert!((below / above - 1.0).abs() < 1e-13);
    }

    #[test]
    fn parse_roundtrip() {
        for lim in FluxLimiter::ALL {
            assert_eq!(lim.to_string().parse::<FluxLimiter>().unwrap(), lim);
        }
        assert_eq!(
            "Larsen-3".parse::<FluxLimiter>().unwrap(),
            FluxLimiter::Larsen(3.0)
        );
        assert!("larsen0".parse::<FluxLimiter>().is_err());
        assert!("foo".parse::<FluxLimiter>().is_err());
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]

        /// FLD Eqs 17 and 19 over R ∈ [0, 10⁶]: F ≥ 0, F ≤ 1/R, F non-increasing.
        #[test]
        fn limiter_bounds(r in prop_oneof![0.0f64..1e-3, 0.0f64..10.0, 0.0f64..1e6], lim_idx in 0usize..7) {
            let lim = LIMITERS[lim_idx];
            let f = lim.eval(r);
            prop_assert!(f.is_finite() && f >= 0.0);
            prop_assert!(f <= 1.0 / 3.0 + 1e-15);
            prop_assert!(r * f <= 1.0 + 1e-12, "{lim}: R·F = {} at R = {r}", r * f);
            prop_assert!(lim.eval(r * 1.01 + 1e-9) <= f * (1.0 + 1e-12), "{lim} increases at R = {r}");
            let f32v = lim.eval(r as f32) as f64;
            prop_assert!(f32v >= 0.0 && (r as f32 as f64) * f32v <= 1.0 + 1e-6);
        }

        /// LP in f32 within 10⁻⁶ relative of its f64 value (evaluated at the same, f32-representable R).
        #[test]
        fn lp_f32_accuracy(r in prop_oneof![0.0f32..1e-3, 0.0f32..4.0, 0.0f32..1e6]) {
            let lo = levermore_pomraning(r) as f64;
            let hi = levermore_pomraning(r as f64);
            prop_assert!((lo / hi - 1.0).abs() <= 1e-6, "R = {r}: f32 {lo} vs f64 {hi}, rel {}", (lo / hi - 1.0).abs());
        }
    }
}
