//! The floating-point abstraction: every CPU kernel is generic over [`Real`] and runs in
//! `f32` (the precision of the GPU kernels and of the paper's CUDA solver) or `f64` (the
//! paper's validated reference solver).

use num_traits::{Float, FloatConst, FromPrimitive, ToPrimitive};
use std::fmt::{Debug, Display};
use std::iter::Sum;

/// A floating-point scalar a solver can run in (`f32` or `f64`).
pub trait Real:
    Float
    + FloatConst
    + FromPrimitive
    + ToPrimitive
    + Sum
    + Send
    + Sync
    + Debug
    + Display
    + Default
    + 'static
{
    /// Short name used in CSV files and reports: `"f32"` or `"f64"`.
    const NAME: &'static str;
    /// Default convergence tolerance on the normalised residual R̄/j̄ (FLD Section 5:
    /// 10⁻⁶ in double precision, 10⁻⁴ "the practical limit for single precision", Section 6.2).
    const DEFAULT_TOLERANCE: f64;
    /// Default ε of FLD Eq 35 and of the initial values φ = ε j̄ Δl, D = ε Δl. The paper's
    /// 10⁻²⁰ in `f64`. In `f32` that value makes products in the stencil (|∇φ|², D·φ at the
    /// initial values) subnormal, which costs ~2× per iteration on x86 (measured: 67 vs 37 ms
    /// per LP iteration at 128³) and buys nothing at 7 digits, so `f32` uses 10⁻¹⁰.
    const DEFAULT_EPSILON: f64;
    /// Converts an `f64` constant; values outside the range saturate to ±∞ (never panics).
    fn c(x: f64) -> Self;
    /// Widens to `f64` (exact for `f32` and `f64`).
    fn f(self) -> f64;
    /// `1.5·2^m + bias` (m mantissa bits): adding it to y/ln 2 rounds to the integer n in the
    /// low mantissa bits, which [`Real::pow2_shifted`] turns into 2ⁿ (the branch-free exp of
    /// `fld::limiter`).
    const POW2_SHIFT: f64;
    /// Smallest argument of that exp: 2ⁿ stays normal (n ≥ −126 / −1022).
    const EXP_MIN: f64;
    /// Degree of the Taylor polynomial of e^r on |r| ≤ ln 2/2 in that exp: truncation
    /// 1.2·10⁻⁷ (`f32`, 6) and 6·10⁻¹⁵ (`f64`, 11) relative (see `fld::limiter`).
    const EXP_DEGREE: usize;
    /// 2ⁿ from `k = n + POW2_SHIFT` (n an integer with a normal 2ⁿ): shifts the low mantissa bits of k into the exponent field. Branch-free and
    /// vectorisable (a bit cast and an integer shift).
    fn pow2_shifted(k: Self) -> Self;
}

impl Real for f32 {
    const NAME: &'static str = "f32";
    const DEFAULT_TOLERANCE: f64 = 1e-4;
    const DEFAULT_EPSILON: f64 = 1e-10;
    const POW2_SHIFT: f64 = 1.5 * 8_388_608.0 + 127.0;
    const EXP_MIN: f64 = -87.0;
    const EXP_DEGREE: usize = 6;
    #[inline(always)]
    fn pow2_shifted(k: Self) -> Self {
        f32::from_bits(k.to_bits() << 23)
    }
    #[inline(always)]
    fn c(x: f64) -> Self {
        x as f32
    }
    #[inline(always)]
    fn f(self) -> f64 {
        self as f64
    }
}

impl Real for f64 {
    const NAME: &'static str = "f64";
    const DEFAULT_TOLERANCE: f64 = 1e-6;
    const DEFAULT_EPSILON: f64 = 1e-20;
    const POW2_SHIFT: f64 = 1.5 * 4_503_599_627_370_496.0 + 1023.0;
    const EXP_MIN: f64 = -708.0;
    const EXP_DEGREE: usize = 11;
    #[inline(always)]
    fn pow2_shifted(k: Self) -> Self {
        f64::from_bits(k.to_bits() << 52)
    }
    #[inline(always)]
    fn c(x: f64) -> Self {
        x
    }
    #[inline(always)]
    fn f(self) -> f64 {
        self
    }
}
