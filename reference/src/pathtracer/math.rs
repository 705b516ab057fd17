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

/// The direction with cosine `cos` to the unit vector `axis` and azimuth `phi` about it.
#[inline(always)]
pub(crate) fn around(axis: Vec3, cos: f64, phi: f64) -> Vec3 {
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    let (s, t) = basis(axis);
    let (sp, cp) = phi.sin_cos();
    [
        sin * cp * s[0] + sin * sp * t[0] + cos * axis[0],
        sin * cp * s[1] + sin * sp * t[1] + cos * axis[1],
        sin * cp * s[2] + sin * sp * t[2] + cos * axis[2],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

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
