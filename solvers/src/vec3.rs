//! Small 3-vector helpers on `[f64; 3]`, shared by scenes, cameras and the path tracer.

/// A 3-vector.
pub type Vec3 = [f64; 3];

/// `a + b`.
#[inline(always)]
pub fn add(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// `a − b`.
#[inline(always)]
pub fn sub(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// `s·a`.
#[inline(always)]
pub fn scale(a: Vec3, s: f64) -> Vec3 {
    [a[0] * s, a[1] * s, a[2] * s]
}

/// `o + t·d`.
#[inline(always)]
pub fn at(o: Vec3, d: Vec3, t: f64) -> Vec3 {
    [o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]]
}

/// `a · b`.
#[inline(always)]
pub fn dot(a: Vec3, b: Vec3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// `a × b`.
#[inline(always)]
pub fn cross(a: Vec3, b: Vec3) -> Vec3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// `|a|`.
#[inline(always)]
pub fn norm(a: Vec3) -> f64 {
    dot(a, a).sqrt()
}

/// `a/|a|`; the caller guarantees `a ≠ 0`.
#[inline(always)]
pub fn normalize(a: Vec3) -> Vec3 {
    scale(a, 1.0 / norm(a))
}
