//! The thesis's P1 moment FTCS (thesis Eqs 3.23–3.26) as a negative control, and the
//! checkerboard detector that tells it from the RDE (thesis Fig 3.6(a)).
//!
//! In grid units (a = Ka∆, b = K′t∆ = 1/(3β), r = c∆t/∆, central differences
//! δ_j f = f_{+1} − f_{−1}), thesis Eq 3.26 with the spec's reading is
//!
//! φ ← (1 − r a) φ − (r/2) Σ_j δ_j E_j + r∆q,   E_j ← (1 − r b) E_j − (r/6) δ_j φ.
//!
//! **Decision** (spec §1.9): Ka in the φ row (thesis Eqs 3.23, B.7; thesis Eq 3.25 prints Kt)
//! and K′t in the E row (thesis Eq 3.26 prints Kt, equal when g = 0); [`P1Config::verbatim`]
//! uses Kt∆ = b in both rows (g = 0). Dirichlet walls: φ = E = 0 on the outermost layer.
//!
//! Because φ at p depends only on E_j at p ± e_j and E_j only on φ at p ± e_j, the grid splits
//! into 2³ independent sublattices: a one-voxel source fills only the voxels at even offsets
//! from it, and the other 7/8 stay exactly 0 (tests `c10_…`). CPU only, sequential: a control
//! on small grids.

use super::Coefficients;
use crate::{Real, SolverError};

/// Settings of the P1 control.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct P1Config {
    /// r = c∆t/∆.
    pub r: f64,
    /// Kt∆ in the φ row as printed (thesis Eq 3.25) instead of Ka∆.
    pub verbatim: bool,
    /// The difference stencil.
    pub stencil: P1Stencil,
}

/// The central difference δ_j of the P1 control.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum P1Stencil {
    /// f_{+1} − f_{−1} along j (thesis Eq 3.26).
    #[default]
    Central,
    /// Thesis Fig 3.6(b)'s "direct and diagonal neighbours", whose weights the thesis does not
    /// give: the same difference smoothed across the other two axes with Sobel weights
    /// (1, 2, 1)/4 each (our documented choice, spec §4 item 17).
    Sobel,
}

/// The P1 state: φ and the three components of E, natural layout.
#[derive(Debug, Clone, PartialEq)]
pub struct P1<T> {
    coef: Coefficients,
    cfg: P1Config,
    /// φ per voxel.
    pub phi: Vec<T>,
    /// E_x, E_y, E_z per voxel.
    pub e: [Vec<T>; 3],
    a: Vec<T>,
    b: Vec<T>,
    s: Vec<T>,
}

impl<T: Real> P1<T> {
    /// Zero initial state; fails on invalid coefficients, r ≤ 0 or a voxel with β = 0 (b = ∞).
    pub fn new(coef: &Coefficients, cfg: P1Config) -> Result<Self, SolverError> {
        coef.validate()?;
        if !(cfg.r.is_finite() && cfg.r > 0.0) {
            return Err(SolverError::BadParameter {
                name: "r",
                value: cfg.r,
                reason: "r = c∆t/∆ must be finite and > 0",
            });
        }
        if let Some(index) = coef.beta.iter().position(|&b| b <= 0.0) {
            return Err(SolverError::FieldValue {
                field: "beta",
                index,
                value: coef.beta[index],
                range: "(0, ∞) for the P1 control (K′t∆ = 1/(3β))",
            });
        }
        let n = coef.grid.len();
        let b: Vec<f64> = coef.beta.iter().map(|&x| 1.0 / (3.0 * x)).collect();
        let a: Vec<f64> = if cfg.verbatim {
            b.clone()
        } else {
            coef.ka_dl.clone()
        };
        let conv = |v: &[f64]| v.iter().map(|&x| T::c(x)).collect::<Vec<T>>();
        Ok(Self {
            cfg,
            phi: vec![T::zero(); n],
            e: [vec![T::zero(); n], vec![T::zero(); n], vec![T::zero(); n]],
            a: conv(&a),
            b: conv(&b),
            s: coef
                .source
                .iter()
                .map(|&q| T::c(q * coef.grid.dl))
                .collect(),
            coef: coef.clone(),
        })
    }

    /// One FTCS step of thesis Eq 3.26 (both rows from the old state).
    #[allow(clippy::needless_range_loop)] // the axis indexes E, the strides and the stencil
    pub fn step(&mut self) {
        let g = self.coef.grid;
        let [nx, ny, _] = g.n;
        let stride = [1, nx, nx * ny];
        let r = T::c(self.cfg.r);
        let (half, sixth) = (T::c(0.5), T::c(1.0 / 6.0));
        let mut phi = self.phi.clone();
        let mut e = self.e.clone();
        let sobel = self.cfg.stencil == P1Stencil::Sobel;
        let w = [T::c(0.25), T::c(0.5), T::c(0.25)];
        // δ along `axis` of field `f` at `idx` (Sobel: smoothed across the other axes).
        let delta = |f: &[T], idx: usize, axis: usize| -> T {
            let st = stride[axis];
            if !sobel {
                return f[idx + st] - f[idx - st];
            }
            let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
            let mut acc = T::zero();
            for (da, wa) in w.iter().enumerate() {
                for (db, wb) in w.iter().enumerate() {
                    let q = (idx + da * stride[a] + db * stride[b]) - stride[a] - stride[b];
                    acc = acc + *wa * *wb * (f[q + st] - f[q - st]);
                }
            }
            acc
        };
        for idx in 0..g.len() {
            let [i, j, k] = g.coords(idx);
            if g.is_boundary(i, j, k) {
                continue;
            }
            let mut div = T::zero();
            for axis in 0..3 {
                div = div + delta(&self.e[axis], idx, axis);
                let grad = delta(&self.phi, idx, axis);
                e[axis][idx] = (T::one() - r * self.b[idx]) * self.e[axis][idx] - r * sixth * grad;
            }
            phi[idx] =
                (T::one() - r * self.a[idx]) * self.phi[idx] - r * half * div + r * self.s[idx];
        }
        self.phi = phi;
        self.e = e;
    }
}

/// The checkerboard detector of spec §5 C11 for a field with a one-voxel source at `src`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Checkerboard {
    /// Σ|φ| off the source's sublattice (offsets not all even) / Σ|φ|: 0 for P1, ≈ 7/8 for a
    /// smooth field.
    pub off_sublattice: f64,
    /// Fraction of the spectral energy Σ|φ̂|² on the Nyquist planes θ_j = π (any j), by
    /// Parseval over the other axes and inclusion–exclusion over the planes.
    pub nyquist: f64,
}

impl Checkerboard {
    /// Whether the field shows the decoupled-sublattice artefact: off-sublattice fraction
    /// below 0.05 or Nyquist-plane energy above 0.1. Measured on a 19³ point source (β = 1/3,
    /// α = 0.9): P1 0 and 0.300, the RDE 0.831 and 0.0355 (test `c11_…`).
    pub fn is_checkerboard(&self) -> bool {
        self.off_sublattice < 0.05 || self.nyquist > 0.1
    }

    /// Measures `phi` (natural layout on `coef.grid`).
    pub fn measure(grid: &crate::Grid, phi: &[f64], src: [usize; 3]) -> Self {
        let n = grid.n;
        let (mut off, mut all, mut e2) = (0.0, 0.0, 0.0);
        for (idx, &v) in phi.iter().enumerate() {
            let c = grid.coords(idx);
            all += v.abs();
            e2 += v * v;
            if (0..3).any(|a| (c[a] + src[a]) % 2 == 1) {
                off += v.abs();
            }
        }
        // Energy on the set {θ_j = π for j in `axes`}: Σ over the other coordinates of
        // |Σ over `axes` of (−1)^{Σ coords} φ|², divided by Π_{axes} n_j · Σφ².
        let plane = |axes: &[usize]| {
            let mut sums = std::collections::HashMap::new();
            for (idx, &v) in phi.iter().enumerate() {
                let c = grid.coords(idx);
                let sign = if axes.iter().map(|&a| c[a]).sum::<usize>() % 2 == 0 {
                    1.0
                } else {
                    -1.0
                };
                let key: Vec<usize> = (0..3)
                    .map(|a| if axes.contains(&a) { 0 } else { c[a] })
                    .collect();
                *sums.entry(key).or_insert(0.0) += sign * v;
            }
            let norm: f64 = axes.iter().map(|&a| n[a] as f64).product();
            sums.values().map(|s: &f64| s * s).sum::<f64>() / (norm * e2)
        };
        let nyquist = plane(&[0]) + plane(&[1]) + plane(&[2])
            - plane(&[0, 1])
            - plane(&[0, 2])
            - plane(&[1, 2])
            + plane(&[0, 1, 2]);
        Self {
            off_sublattice: off / all,
            nyquist,
        }
    }
}

/// The exact von Neumann bound of the P1 FTCS in a uniform medium (spec §1.9): the largest
/// r with |λ| ≤ 1 for λ = 1 − (ra + rb)/2 ± √(((ra − rb)/2)² − r²S/3), S ∈ [0, 3], and
/// 1 − rb ∈ [−1, 1]; by bisection on a grid of S.
pub fn p1_critical_r(a: f64, b: f64) -> f64 {
    let stable = |r: f64| {
        if (1.0 - r * b).abs() > 1.0 {
            return false;
        }
        (0..=600).all(|i| {
            let s = 3.0 * i as f64 / 600.0;
            let (x, y) = (r * a, r * b);
            let m = 1.0 - (x + y) / 2.0;
            let disc = ((x - y) / 2.0).powi(2) - r * r * s / 3.0;
            if disc >= 0.0 {
                (m + disc.sqrt()).abs() <= 1.0 && (m - disc.sqrt()).abs() <= 1.0
            } else {
                m * m - disc <= 1.0
            }
        })
    };
    let (mut lo, mut hi) = (0.0, 10.0);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if stable(mid) { lo = mid } else { hi = mid }
    }
    lo
}
