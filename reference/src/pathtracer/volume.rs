//! Voxel lookups of σt, albedo and emission, ray–box clipping, the 3D DDA every traversal
//! uses, and exact line integrals of the voxel fields.
//!
//! Two reconstructions of the cell-centred samples:
//!
//! * [`Interpolation::Nearest`] — piecewise constant per voxel, the project's convention
//!   (`solvers::scene`): the grid solvers and every tally here see the same medium.
//! * [`Interpolation::Trilinear`] — trilinear between voxel centres, clamped to the outermost
//!   centres (so the outer half voxel is constant along the normal); Mitsuba's `gridvolume`
//!   with `filter_type = "trilinear"`. Each field (σt, albedo, emission) is interpolated on
//!   its own, as Mitsuba does.
//!
//! Outside the grid box the medium is vacuum in both cases.

use super::math::{Vec3, at};
use crate::ReferenceError;
use solvers::{Grid, Medium};

/// How voxel samples are reconstructed between voxel centres (the scene's
/// `interpolation`).
pub use solvers::scene::Interpolation;

/// A voxel medium in its bounding box, in `f64`.
#[derive(Debug, Clone)]
pub struct Volume {
    grid: Grid,
    interpolation: Interpolation,
    sigma_t: Vec<f64>,
    albedo: Vec<f64>,
    emission: Vec<f64>,
    /// The albedo where it is one value in every voxel (a lookup per scattering event
    /// saved; every reconstruction gives that value, up to the rounding of its weights).
    uniform_albedo: Option<f64>,
    /// 1/∆l: lookups multiply by it (three divisions per lookup were measurable in
    /// `reference/examples/pt_profile.rs`).
    inv_dl: f64,
    lo: Vec3,
    hi: Vec3,
}

/// The voxels and weights a lookup combines.
#[derive(Debug, Clone, Copy)]
enum Stencil {
    One(usize),
    Eight([usize; 8], [f64; 8]),
}

impl Volume {
    /// Validates `medium` and prepares lookups.
    pub fn new(medium: &Medium<f64>, interpolation: Interpolation) -> Result<Self, ReferenceError> {
        medium.validate()?;
        let grid = medium.grid;
        let size = grid.size();
        Ok(Self {
            grid,
            interpolation,
            sigma_t: medium.sigma_t.clone(),
            albedo: medium.albedo.clone(),
            emission: medium.emission.clone(),
            uniform_albedo: match medium.albedo.first() {
                Some(&a) if medium.albedo.iter().all(|&b| b == a) => Some(a),
                _ => None,
            },
            inv_dl: 1.0 / grid.dl,
            lo: grid.origin,
            hi: [
                grid.origin[0] + size[0],
                grid.origin[1] + size[1],
                grid.origin[2] + size[2],
            ],
        })
    }

    /// The grid.
    pub fn grid(&self) -> &Grid {
        &self.grid
    }

    /// The reconstruction in use.
    pub fn interpolation(&self) -> Interpolation {
        self.interpolation
    }

    /// Lower and upper corners of the box.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        (self.lo, self.hi)
    }

    /// Per-voxel σt samples.
    pub fn sigma_t_samples(&self) -> &[f64] {
        &self.sigma_t
    }

    /// Per-voxel emission samples j.
    pub fn emission_samples(&self) -> &[f64] {
        &self.emission
    }

    /// Whether any voxel emits.
    pub fn has_emission(&self) -> bool {
        self.emission.iter().any(|&j| j > 0.0)
    }

    #[inline(always)]
    fn stencil(&self, p: Vec3) -> Stencil {
        let g = &self.grid;
        match self.interpolation {
            Interpolation::Nearest => {
                let mut idx = [0usize; 3];
                for a in 0..3 {
                    // `as usize` truncates, which is floor for u ≥ 0 (and u < 0 clamps to
                    // 0 either way): the same index without a libm `floor` call, which the
                    // baseline x86-64 target cannot inline (5 % of a cloud render's profile).
                    let u = (p[a] - g.origin[a]) * self.inv_dl;
                    idx[a] = (u.max(0.0) as usize).min(g.n[a] - 1);
                }
                Stencil::One(g.index(idx[0], idx[1], idx[2]))
            }
            Interpolation::Trilinear => {
                let mut i0 = [0usize; 3];
                let mut f = [0.0f64; 3];
                for a in 0..3 {
                    let u =
                        ((p[a] - g.origin[a]) * self.inv_dl - 0.5).clamp(0.0, (g.n[a] - 1) as f64);
                    let i = (u as usize).min(g.n[a] - 2); // u ≥ 0: truncation is floor
                    i0[a] = i;
                    f[a] = u - i as f64;
                }
                let base = g.index(i0[0], i0[1], i0[2]);
                let (sx, sy, sz) = (1, g.n[0], g.n[0] * g.n[1]);
                let mut idx = [0usize; 8];
                let mut w = [0.0f64; 8];
                for c in 0..8 {
                    let (bx, by, bz) = (c & 1, (c >> 1) & 1, (c >> 2) & 1);
                    idx[c] = base + bx * sx + by * sy + bz * sz;
                    w[c] = (if bx == 1 { f[0] } else { 1.0 - f[0] })
                        * (if by == 1 { f[1] } else { 1.0 - f[1] })
                        * (if bz == 1 { f[2] } else { 1.0 - f[2] });
                }
                Stencil::Eight(idx, w)
            }
        }
    }

    #[inline(always)]
    fn apply(field: &[f64], s: &Stencil) -> f64 {
        match s {
            Stencil::One(i) => field[*i],
            Stencil::Eight(idx, w) => idx.iter().zip(w).map(|(&i, &w)| field[i] * w).sum(),
        }
    }

    /// σt at a point inside the box (points outside are clamped to it).
    #[inline(always)]
    pub fn sigma_t(&self, p: Vec3) -> f64 {
        Self::apply(&self.sigma_t, &self.stencil(p))
    }

    /// Albedo at a point inside the box.
    #[inline(always)]
    pub fn albedo(&self, p: Vec3) -> f64 {
        match self.uniform_albedo {
            Some(a) => a,
            None => Self::apply(&self.albedo, &self.stencil(p)),
        }
    }

    /// Emission j at a point inside the box.
    #[inline(always)]
    pub fn emission(&self, p: Vec3) -> f64 {
        Self::apply(&self.emission, &self.stencil(p))
    }

    /// The parameter interval `[t0, t1]` (t0 ≤ t1) where the ray `o + t·d` lies in the box,
    /// or `None` if it misses. `t0` may be negative (origin inside).
    #[inline]
    pub fn clip(&self, o: Vec3, d: Vec3) -> Option<(f64, f64)> {
        clip_box(self.lo, self.hi, o, d)
    }

    /// Whether `p` lies in the closed box.
    pub fn contains(&self, p: Vec3) -> bool {
        (0..3).all(|a| p[a] >= self.lo[a] && p[a] <= self.hi[a])
    }

    /// Visits the voxels crossed by `o + t·d` for t ∈ [ta, tb] (a sub-interval of the box's
    /// clip interval): `f(linear voxel index, t_enter, t_exit)`.
    #[inline]
    pub(crate) fn voxels(
        &self,
        o: Vec3,
        d: Vec3,
        ta: f64,
        tb: f64,
        mut f: impl FnMut(usize, f64, f64),
    ) {
        let g = &self.grid;
        traverse(g.origin, g.dl, g.n, o, d, ta, tb, |c, t0, t1| {
            f(g.index(c[0], c[1], c[2]), t0, t1);
            true
        });
    }

    /// ∫ field dt along `o + t·d` over [ta, tb] ∩ box, exactly for either reconstruction:
    /// per voxel for nearest; per half voxel with 2-point Gauss–Legendre for trilinear (on a
    /// half voxel the interpolant is a polynomial of degree ≤ 3 in t, which the rule
    /// integrates exactly).
    pub(crate) fn integrate(&self, field: &[f64], o: Vec3, d: Vec3, ta: f64, tb: f64) -> f64 {
        let Some((c0, c1)) = self.clip(o, d) else {
            return 0.0;
        };
        let (ta, tb) = (ta.max(c0), tb.min(c1));
        if ta >= tb {
            return 0.0;
        }
        let g = &self.grid;
        let mut sum = 0.0;
        match self.interpolation {
            Interpolation::Nearest => {
                traverse(g.origin, g.dl, g.n, o, d, ta, tb, |c, t0, t1| {
                    sum += field[g.index(c[0], c[1], c[2])] * (t1 - t0);
                    true
                });
            }
            Interpolation::Trilinear => {
                let half = [2 * g.n[0], 2 * g.n[1], 2 * g.n[2]];
                let node = 0.5 / 3f64.sqrt();
                traverse(g.origin, 0.5 * g.dl, half, o, d, ta, tb, |_, t0, t1| {
                    let (m, h) = (0.5 * (t0 + t1), t1 - t0);
                    let s = Self::apply(field, &self.stencil(at(o, d, m - node * h)))
                        + Self::apply(field, &self.stencil(at(o, d, m + node * h)));
                    sum += 0.5 * h * s;
                    true
                });
            }
        }
        sum
    }

    /// The exact optical depth ∫σt dt along `o + t·d` over [ta, tb] ∩ box.
    pub fn optical_depth(&self, o: Vec3, d: Vec3, ta: f64, tb: f64) -> f64 {
        self.integrate(&self.sigma_t, o, d, ta, tb)
    }

    /// The exact emission integral ∫ j dt along `o + t·d` over [ta, tb] ∩ box.
    pub fn emission_integral(&self, o: Vec3, d: Vec3, ta: f64, tb: f64) -> f64 {
        self.integrate(&self.emission, o, d, ta, tb)
    }
}

/// The parameter interval `[t0, t1]` (t0 ≤ t1) where the ray `o + t·d` lies in the box
/// [lo, hi], or `None` if it misses. `t0` may be negative (origin inside).
#[inline]
pub(crate) fn clip_box(lo: Vec3, hi: Vec3, o: Vec3, d: Vec3) -> Option<(f64, f64)> {
    let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
    for a in 0..3 {
        if d[a] == 0.0 {
            if o[a] < lo[a] || o[a] > hi[a] {
                return None;
            }
        } else {
            let inv = 1.0 / d[a];
            let (ta, tb) = ((lo[a] - o[a]) * inv, (hi[a] - o[a]) * inv);
            let (ta, tb) = if ta < tb { (ta, tb) } else { (tb, ta) };
            t0 = t0.max(ta);
            t1 = t1.min(tb);
        }
    }
    (t0 <= t1).then_some((t0, t1))
}

/// A 3D DDA (Amanatides & Woo 1987) over a regular lattice of `n` cubic cells of edge `cell`
/// whose lower corner is `origin`: calls `f(cell, t_enter, t_exit)` for each cell the ray
/// `o + t·d` crosses in [ta, tb], in order, until `f` returns false or the ray leaves the
/// lattice. The caller keeps [ta, tb] inside the lattice's box (up to rounding, which is
/// absorbed by clamping the first cell). Crossing parameters are computed from the absolute
/// cell index each step, so no error accumulates along long rays.
///
/// A step is a few multiplications and no unpredictable branch: the reciprocals of the
/// direction are taken once per ray, the axis of the next crossing is chosen by selects,
/// and a step off either end of an axis is one unsigned comparison (stepping below 0
/// wraps). With a division and two data-dependent branches per step, walking 2³ majorant
/// blocks cost 1.9× the time of 8³ on `scenes/cloud_directional.toml`
/// (`reference/examples/pt_profile.rs`); see the path tracer's module docs.
#[allow(clippy::too_many_arguments)]
#[inline]
pub(crate) fn traverse(
    origin: Vec3,
    cell: f64,
    n: [usize; 3],
    o: Vec3,
    d: Vec3,
    ta: f64,
    tb: f64,
    mut f: impl FnMut([usize; 3], f64, f64) -> bool,
) {
    if ta >= tb {
        return;
    }
    let p = at(o, d, ta);
    let inv_cell = 1.0 / cell;
    let mut idx = [0usize; 3];
    let mut next = [f64::INFINITY; 3];
    // Per axis: the index step (+1, or −1 as a wrapping add) and the crossing parameter of
    // cell i as c0 + i·c1 (c0 = (origin + face·cell − o)/d with face 1 for the upper face,
    // 0 for the lower; c1 = cell/d): absolute in i, so no error accumulates.
    let mut step = [0usize; 3];
    let mut c0 = [0.0f64; 3];
    let mut c1 = [0.0f64; 3];
    for a in 0..3 {
        let u = (p[a] - origin[a]) * inv_cell; // truncation below is floor (see `stencil`)
        idx[a] = (u.max(0.0) as usize).min(n[a] - 1);
        if d[a] != 0.0 {
            let inv = 1.0 / d[a];
            let face = if d[a] > 0.0 { cell } else { 0.0 };
            step[a] = if d[a] > 0.0 { 1 } else { usize::MAX };
            c0[a] = (origin[a] + face - o[a]) * inv;
            c1[a] = cell * inv;
            next[a] = c0[a] + idx[a] as f64 * c1[a];
        }
    }
    let mut t = ta;
    loop {
        // The axis crossed first (ties: the later axis), by selects.
        let first = usize::from(next[1] <= next[0]);
        let n_first = if first == 1 { next[1] } else { next[0] };
        let axis = if next[2] <= n_first { 2 } else { first };
        let tn = n_first.min(next[2]);
        let te = tn.min(tb);
        if te > t {
            if !f(idx, t, te) {
                return;
            }
            t = te;
        }
        if tn >= tb {
            return;
        }
        // Step along `axis` only; every lane is computed and selected, so that `idx` and
        // `next` stay in registers.
        let mut out = false;
        for a in 0..3 {
            let i = idx[a].wrapping_add(step[a]);
            let hit = a == axis;
            out |= hit & (i >= n[a]);
            idx[a] = if hit { i } else { idx[a] };
            next[a] = if hit {
                c0[a] + i as f64 * c1[a]
            } else {
                next[a]
            };
        }
        if out {
            return;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::math::normalize;
    use super::*;
    use crate::quadrature::simpson;

    fn medium() -> Medium<f64> {
        let grid = Grid::with_origin([5, 4, 6], 0.3, [-0.2, 0.1, 0.4]).unwrap();
        let sigma = grid.sample(|p| 1.0 + 3.0 * (p[0] * 2.0).sin().powi(2) + p[1] * p[2]);
        let n = grid.len();
        Medium::new(grid, sigma, vec![0.5; n], vec![0.0; n]).unwrap()
    }

    /// The DDA's voxel lengths sum to the clipped length and match brute-force sampling.
    #[test]
    fn exact_integrals_match_fine_quadrature() {
        let m = medium();
        for interp in [Interpolation::Nearest, Interpolation::Trilinear] {
            let v = Volume::new(&m, interp).unwrap();
            for (o, d) in [
                ([-1.0, 0.0, 0.0], normalize([1.0, 0.6, 0.9])),
                ([0.5, 0.5, 0.5], normalize([-0.3, 0.2, -1.0])),
                ([0.0, 0.55, 1.0], [1.0, 0.0, 0.0]),
            ] {
                let (t0, t1) = v.clip(o, d).unwrap();
                let (t0, t1) = (t0.max(0.0), t1);
                let exact = v.optical_depth(o, d, 0.0, f64::INFINITY);
                // Simpson on a very fine grid converges (slowly, for the discontinuous
                // nearest field) to the same value.
                let q = simpson(|t| v.sigma_t(at(o, d, t)), t0, t1, 2_000_000);
                assert!((exact - q).abs() < 1e-5 * q, "{interp:?}: {exact} vs {q}");
                let mut len = 0.0;
                v.voxels(o, d, t0, t1, |_, a, b| len += b - a);
                assert!((len - (t1 - t0)).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn trilinear_reproduces_centres_and_nearest_is_constant_per_voxel() {
        let m = medium();
        let g = m.grid;
        let t = Volume::new(&m, Interpolation::Trilinear).unwrap();
        let nn = Volume::new(&m, Interpolation::Nearest).unwrap();
        for idx in [0, 7, g.len() - 1] {
            let [i, j, k] = g.coords(idx);
            let c = g.center(i, j, k);
            assert!((t.sigma_t(c) - m.sigma_t[idx]).abs() < 1e-12);
            let off = [c[0] + 0.49 * g.dl, c[1] - 0.49 * g.dl, c[2] + 0.2 * g.dl];
            assert_eq!(nn.sigma_t(off), m.sigma_t[idx]);
        }
    }
}
