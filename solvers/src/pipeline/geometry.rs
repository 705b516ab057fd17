//! Rays through the voxel grid: box intersection, exact voxel traversal (3D DDA), the
//! camera model, and trilinear interpolation of cell-centred fields.

use crate::Grid;
use crate::scene::{Camera, Projection};
use crate::vec3::{Vec3, cross, normalize, sub};

/// The parameter range `[t0, t1]` (with t0 ≥ `t_min`) over which the ray `o + t·d` lies in
/// the grid's box, or `None`.
pub fn ray_box(grid: &Grid, o: Vec3, d: Vec3, t_min: f64) -> Option<(f64, f64)> {
    let size = grid.size();
    let (mut t0, mut t1) = (t_min, f64::INFINITY);
    for a in 0..3 {
        let lo = grid.origin[a];
        let hi = lo + size[a];
        if d[a] == 0.0 {
            if o[a] < lo || o[a] > hi {
                return None;
            }
        } else {
            let (ta, tb) = ((lo - o[a]) / d[a], (hi - o[a]) / d[a]);
            t0 = t0.max(ta.min(tb));
            t1 = t1.min(ta.max(tb));
        }
    }
    (t0 < t1).then_some((t0, t1))
}

/// Visits the voxels the ray `o + t·d` crosses for t in `[t0, t1]` (which must lie inside
/// the box) in order, calling `f(voxel index, t_enter, t_exit)`; stops early when `f`
/// returns false. Segment lengths sum to t1 − t0 exactly up to rounding.
pub fn traverse(
    grid: &Grid,
    o: Vec3,
    d: Vec3,
    t0: f64,
    t1: f64,
    mut f: impl FnMut(usize, f64, f64) -> bool,
) {
    let p = [0, 1, 2].map(|a| o[a] + t0 * d[a]);
    let mut cell = [0usize; 3];
    let mut t_next = [f64::INFINITY; 3];
    let mut t_delta = [f64::INFINITY; 3];
    let mut step = [0isize; 3];
    for a in 0..3 {
        let u = (p[a] - grid.origin[a]) / grid.dl;
        // A ray entering through the upper face of an axis it moves down along starts in
        // the last cell, and vice versa: clamping handles both.
        let c = if d[a] < 0.0 {
            u.ceil() - 1.0
        } else {
            u.floor()
        };
        cell[a] = c.clamp(0.0, (grid.n[a] - 1) as f64) as usize;
        if d[a] > 0.0 {
            step[a] = 1;
            let b = grid.origin[a] + (cell[a] + 1) as f64 * grid.dl;
            t_next[a] = (b - o[a]) / d[a];
            t_delta[a] = grid.dl / d[a];
        } else if d[a] < 0.0 {
            step[a] = -1;
            let b = grid.origin[a] + cell[a] as f64 * grid.dl;
            t_next[a] = (b - o[a]) / d[a];
            t_delta[a] = -grid.dl / d[a];
        }
    }
    let mut t = t0;
    while t < t1 {
        let a = if t_next[0] <= t_next[1] && t_next[0] <= t_next[2] {
            0
        } else if t_next[1] <= t_next[2] {
            1
        } else {
            2
        };
        let te = t_next[a].min(t1);
        if te > t && !f(grid.index(cell[0], cell[1], cell[2]), t, te) {
            return;
        }
        t = t.max(te);
        let c = cell[a] as isize + step[a];
        if c < 0 || c >= grid.n[a] as isize {
            return;
        }
        cell[a] = c as usize;
        t_next[a] += t_delta[a];
    }
}

/// Optical depth ∫σt dt along `o + t·d`, t ∈ [0, t_max] (clipped to the box), exact for
/// the piecewise-constant field.
pub fn optical_depth(grid: &Grid, sigma_t: &[f64], o: Vec3, d: Vec3, t_max: f64) -> f64 {
    let Some((t0, t1)) = ray_box(grid, o, d, 0.0) else {
        return 0.0;
    };
    let t1 = t1.min(t_max);
    let mut tau = 0.0;
    if t1 > t0 {
        traverse(grid, o, d, t0, t1, |i, a, b| {
            tau += sigma_t[i] * (b - a);
            true
        });
    }
    tau
}

/// The camera model of `reference::pathtracer::camera` (the same conventions, so that
/// images line up pixel for pixel): forward f = normalize(target − eye), right
/// r = normalize(f × up), up u = r × f; image position (px, py) in pixel units, y down.
#[derive(Debug, Clone, Copy)]
pub struct CameraRays {
    eye: Vec3,
    f: Vec3,
    r: Vec3,
    u: Vec3,
    projection: Projection,
    /// Half extents of the image plane along r and u: tan(fov_y/2)·(W/H, 1) at unit
    /// distance for a perspective camera, (w/2)·(1, H/W) for an orthographic one. Computed
    /// once (a `tan` and three divisions per path were 7 % of a path-traced render's
    /// profile, `reference/examples/pt_profile.rs` on `scenes/emissive_sphere.toml`).
    half: [f64; 2],
    /// 2/W and 2/H: image coordinates by multiplication.
    scale: [f64; 2],
}

impl CameraRays {
    /// The rays of `camera`.
    pub fn new(c: &Camera) -> Self {
        let f = normalize(sub(c.target, c.eye));
        let r = normalize(cross(f, c.up));
        let u = cross(r, f);
        let (w, h) = (c.resolution[0] as f64, c.resolution[1] as f64);
        Self {
            eye: c.eye,
            f,
            r,
            u,
            projection: c.projection,
            half: match c.projection {
                Projection::Perspective { fov_y_degrees } => {
                    let t = (0.5 * fov_y_degrees.to_radians()).tan();
                    [t * w / h, t]
                }
                Projection::Orthographic { width } => [0.5 * width, 0.5 * width * h / w],
            },
            scale: [2.0 / w, 2.0 / h],
        }
    }

    /// Origin and unit direction of the ray through image position (px, py).
    #[inline]
    pub fn ray(&self, px: f64, py: f64) -> (Vec3, Vec3) {
        let sx = px * self.scale[0] - 1.0;
        let sy = 1.0 - py * self.scale[1];
        let (a, b) = (sx * self.half[0], sy * self.half[1]);
        match self.projection {
            Projection::Perspective { .. } => {
                let d = [0, 1, 2].map(|i| self.f[i] + a * self.r[i] + b * self.u[i]);
                (self.eye, normalize(d))
            }
            Projection::Orthographic { .. } => {
                let o = [0, 1, 2].map(|i| self.eye[i] + a * self.r[i] + b * self.u[i]);
                (o, self.f)
            }
        }
    }
}

/// Trilinear interpolation of a cell-centred field at `p`. `extrapolate`: outside the
/// hull of the cell centres (the outer half voxel) the outermost cells' linear trend is
/// continued (used for optical depths, which are linear along a homogeneous ray); else
/// the coordinates are clamped to the hull (constant continuation, used for φ).
pub fn trilinear(grid: &Grid, field: &[f64], p: Vec3, extrapolate: bool) -> f64 {
    let mut i0 = [0usize; 3];
    let mut fr = [0.0; 3];
    for a in 0..3 {
        let n = grid.n[a];
        let mut u = (p[a] - grid.origin[a]) / grid.dl - 0.5;
        if !extrapolate {
            u = u.clamp(0.0, (n - 1) as f64);
        }
        let base = u.floor().clamp(0.0, (n - 2) as f64);
        i0[a] = base as usize;
        fr[a] = u - base;
    }
    let mut v = 0.0;
    for dz in 0..2 {
        let wz = if dz == 0 { 1.0 - fr[2] } else { fr[2] };
        for dy in 0..2 {
            let wy = if dy == 0 { 1.0 - fr[1] } else { fr[1] };
            for dx in 0..2 {
                let wx = if dx == 0 { 1.0 - fr[0] } else { fr[0] };
                v += wx * wy * wz * field[grid.index(i0[0] + dx, i0[1] + dy, i0[2] + dz)];
            }
        }
    }
    v
}

/// The voxel containing `p` (clamped to the grid).
pub fn voxel_at(grid: &Grid, p: Vec3) -> usize {
    let c = [0, 1, 2].map(|a| {
        (((p[a] - grid.origin[a]) / grid.dl).floor()).clamp(0.0, (grid.n[a] - 1) as f64) as usize
    });
    grid.index(c[0], c[1], c[2])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn traversal_segments_cover_the_chord_and_match_the_lookup() {
        let g = Grid::with_origin([5, 4, 6], 0.25, [-0.5, 0.1, 0.0]).unwrap();
        let sigma: Vec<f64> = (0..g.len()).map(|i| (i % 7) as f64).collect();
        let dirs = [
            [0.3, 0.5, 0.81],
            [-0.7, 0.2, -0.1],
            [0.0, 0.0, 1.0],
            [0.0, -1.0, 0.0],
            [1.0, 1.0, 1.0],
        ];
        for d in dirs {
            let d = normalize(d);
            let o = [0.1 - 2.0 * d[0], 0.55 - 2.0 * d[1], 0.7 - 2.0 * d[2]];
            let (t0, t1) = ray_box(&g, o, d, 0.0).unwrap();
            let mut total = 0.0;
            let mut tau = 0.0;
            traverse(&g, o, d, t0, t1, |i, a, b| {
                // The midpoint of each segment lies in the voxel reported (rounding-sized
                // segments where the diagonal ray grazes a corner are exempt).
                let m = [0, 1, 2].map(|k| o[k] + 0.5 * (a + b) * d[k]);
                if b - a > 1e-9 {
                    assert_eq!(voxel_at(&g, m), i, "{d:?} {a} {b}");
                }
                total += b - a;
                tau += sigma[i] * (b - a);
                true
            });
            assert!((total - (t1 - t0)).abs() < 1e-12, "{d:?}");
            // Against fine midpoint sampling of the nearest-voxel field.
            let m = 200_000;
            let h = (t1 - t0) / m as f64;
            let brute: f64 = (0..m)
                .map(|k| {
                    let t = t0 + (k as f64 + 0.5) * h;
                    sigma[voxel_at(&g, [0, 1, 2].map(|a| o[a] + t * d[a]))] * h
                })
                .sum();
            assert!(
                (tau - brute).abs() < 1e-3 * brute.max(1.0),
                "{tau} vs {brute}"
            );
        }
    }

    #[test]
    fn trilinear_is_exact_for_linear_fields() {
        let g = Grid::with_origin([4, 5, 3], 0.5, [1.0, 0.0, -1.0]).unwrap();
        let lin = |p: Vec3| 2.0 * p[0] - 3.0 * p[1] + 0.5 * p[2] + 1.0;
        let field = g.sample(lin);
        for p in [[1.1, 0.05, -0.99], [2.9, 2.4, 0.49], [1.7, 1.3, -0.2]] {
            assert!((trilinear(&g, &field, p, true) - lin(p)).abs() < 1e-12);
        }
        // Clamped: constant continuation beyond the outermost centres.
        let c = trilinear(&g, &field, [1.0, 0.0, -1.0], false);
        assert!((c - lin(g.center(0, 0, 0))).abs() < 1e-12);
    }
}
