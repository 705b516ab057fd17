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
}

impl Real for f32 {
    const NAME: &'static str = "f32";
    const DEFAULT_TOLERANCE: f64 = 1e-4;
    const DEFAULT_EPSILON: f64 = 1e-10;
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
    #[inline(always)]
    fn c(x: f64) -> Self {
        x
    }
    #[inline(always)]
    fn f(self) -> f64 {
        self
    }
}
