//! 3-vector helpers: the basic operations from [`solvers::vec3`], plus frames.

pub(crate) use solvers::vec3::*;

/// Two unit vectors `(s, t)` completing the unit vector `n` to a right-handed orthonormal
/// basis `(s, t, n)` (the branchless construction of Duff et al. 2017).
#[inline(always)]
pub(crate) fn basis(n: Vec3) -> (Vec3, Vec3) {
    let sign = 1f64.copysign(n[2]);
    let a = -1.0 / (sign + n[2]);
    let b = n[0] * n[1] * a;
    (
        [1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0]],
        [b, sign + n[1] * n[1] * a, -n[1]],
    )
}

/// The direction with cosine `cos` to the unit vector `axis` and azimuth 2π·`turn` about
/// it (`turn` ∈ [0, 1), a uniform variate when sampling: [`sin_cos_turn`]).
#[inline(always)]
pub(crate) fn around(axis: Vec3, cos: f64, turn: f64) -> Vec3 {
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    let (s, t) = basis(axis);
    let (sp, cp) = sin_cos_turn(turn);
    [
        sin * cp * s[0] + sin * sp * t[0] + cos * axis[0],
        sin * cp * s[1] + sin * sp * t[1] + cos * axis[1],
        sin * cp * s[2] + sin * sp * t[2] + cos * axis[2],
    ]
}

/// Taylor coefficients (−1)ᵏ/(2k+1)! of sin x, highest first.
const SIN: [f64; 8] = [
    -1.0 / 1_307_674_368_000.0,
    1.0 / 6_227_020_800.0,
    -1.0 / 39_916_800.0,
    1.0 / 362_880.0,
    -1.0 / 5_040.0,
    1.0 / 120.0,
    -1.0 / 6.0,
    1.0,
];

/// Taylor coefficients (−1)ᵏ/(2k)! of cos x, highest first.
const COS: [f64; 9] = [
    1.0 / 20_922_789_888_000.0,
    -1.0 / 87_178_291_200.0,
    1.0 / 479_001_600.0,
    -1.0 / 3_628_800.0,
    1.0 / 40_320.0,
    -1.0 / 720.0,
    1.0 / 24.0,
    -0.5,
    1.0,
];

/// (sin 2πu, cos 2πu) for `u` ∈ [0, 1]: the octant polynomials are within 2.3·10⁻¹⁶ of
/// libm's `sin_cos` of the same reduced argument, and the result within 10⁻¹⁵ of libm's
/// `(2π·u).sin_cos()`, whose own argument carries up to 7·10⁻¹⁶ of rounding
/// (`sin_cos_turn_matches_libm`).
///
/// Sampling only ever needs the azimuth as a fraction of a turn, where the range reduction
/// is exact: 4u splits into a quadrant q and a fraction f (both exact in binary), and the
/// half of the quadrant past π/4 is reflected (1 − f, exact by Sterbenz), leaving
/// x = (π/2)·min(f, 1 − f) ∈ [0, π/4], where Taylor series to x¹⁵ and x¹⁶ are below half
/// an ulp. The quadrant and the reflection are applied by swapping and sign bits, not
/// branches: q and the reflection are random, so branches on them would mispredict about
/// half the time. `__sincos` was 12 % of a path-traced render's profile
/// (`scenes/emissive_sphere.toml`, two calls per scattering event); see the path tracer's
/// module docs for the measurement.
#[inline(always)]
pub(crate) fn sin_cos_turn(u: f64) -> (f64, f64) {
    let v = 4.0 * u;
    let q = (v as u64).min(3);
    let f = v - q as f64;
    let (s, c) = sin_cos_octant(std::f64::consts::FRAC_PI_2 * f.min(1.0 - f));
    // Odd quadrants and reflected halves swap sine and cosine; quadrants 2, 3 negate the
    // sine, quadrants 1, 2 the cosine.
    let swap = (u64::from(f > 0.5) ^ (q & 1)).wrapping_neg();
    let (s, c) = (s.to_bits(), c.to_bits());
    let (a, b) = ((c & swap) | (s & !swap), (s & swap) | (c & !swap));
    (
        f64::from_bits(a ^ ((q >> 1) << 63)),
        f64::from_bits(b ^ (((q ^ (q >> 1)) & 1) << 63)),
    )
}

/// (sin x, cos x) for x ∈ [0, π/4] by the Taylor polynomials [`SIN`] and [`COS`] in x²,
/// evaluated by Estrin's scheme (independent pairs combined by powers of x²: a shorter
/// dependency chain than Horner's).
#[inline(always)]
fn sin_cos_octant(x: f64) -> (f64, f64) {
    let y = x * x;
    let y2 = y * y;
    let y4 = y2 * y2;
    // Coefficients are stored highest first: SIN[7] is that of y⁰.
    let p = |c: &[f64], k: usize| c[k] * y + c[k + 1];
    let sin = (p(&SIN, 0) * y2 + p(&SIN, 2)) * y4 + (p(&SIN, 4) * y2 + p(&SIN, 6));
    let cos = ((COS[0] * y2 + p(&COS, 1)) * y2 + p(&COS, 3)) * y4 + (p(&COS, 5) * y2 + p(&COS, 7));
    (x * sin, cos)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The octant polynomials agree with libm to 2.3·10⁻¹⁶ on [0, π/4]; the turn-based sine
    /// and cosine agree with libm's of 2πu to 10⁻¹⁵ over a fine grid of [0, 1), at the
    /// quadrant and octant boundaries and at the ends, and give exact zeros and ones at
    /// the quadrant points.
    #[test]
    fn sin_cos_turn_matches_libm() {
        let n = 1 << 20;
        let mut octant = 0.0f64;
        for i in 0..=n {
            let x = std::f64::consts::FRAC_PI_4 * i as f64 / n as f64;
            let (s, c) = sin_cos_octant(x);
            let (ls, lc) = x.sin_cos();
            octant = octant.max((s - ls).abs()).max((c - lc).abs());
        }
        assert!(
            octant < 2.3e-16,
            "octant polynomials off libm by {octant:e}"
        );
        let mut worst = 0.0f64;
        let points = (0..n)
            .map(|i| (i as f64 + 0.37) / n as f64)
            .chain((0..8).map(|k| k as f64 / 8.0))
            .chain((0..=8).flat_map(|k| {
                let b = k as f64 / 8.0;
                [b - 1e-17, b + 1e-17, b - 1e-12, b + 1e-12]
            }))
            .filter(|u| (0.0..1.0).contains(u))
            .chain([1.0 - f64::EPSILON / 2.0, 0.0, f64::MIN_POSITIVE, 1.0]);
        for u in points {
            let (s, c) = sin_cos_turn(u);
            let (ls, lc) = (2.0 * std::f64::consts::PI * u).sin_cos();
            worst = worst.max((s - ls).abs()).max((c - lc).abs());
            assert!((s * s + c * c - 1.0).abs() < 1e-15, "u = {u}: |(s, c)| − 1");
        }
        assert!(worst < 1e-15, "largest difference from libm {worst:e}");
        assert_eq!(sin_cos_turn(0.0), (0.0, 1.0));
        assert_eq!(sin_cos_turn(0.25), (1.0, -0.0));
        assert_eq!(sin_cos_turn(0.5), (-0.0, -1.0));
        assert_eq!(sin_cos_turn(0.75), (-1.0, 0.0));
    }

    #[test]
    fn basis_is_orthonormal_and_right_handed() {
        for n in [
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
            normalize([1.0, 2.0, -3.0]),
            normalize([-0.3, 0.1, 1e-9]),
        ] {
            let (s, t) = basis(n);
            for (a, b) in [(s, t), (s, n), (t, n)] {
                assert!(dot(a, b).abs() < 1e-12);
            }
            for v in [s, t] {
                assert!((norm(v) - 1.0).abs() < 1e-12);
            }
            let c = cross(s, t);
            assert!(norm(sub(c, n)) < 1e-12, "{c:?} vs {n:?}");
        }
    }
}
