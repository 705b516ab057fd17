//! Propagation and storage directions (spec §1.3, D7, D8, D10) and the phase matrix F of
//! LPM Eq 5.
//!
//! Propagation cells: each cube face f (outward normal ±e_a) is split into m×m cells in the
//! gnomonic (tangent) coordinates u, v ∈ [−1, 1]; the ray direction of cell (p, q) is the
//! normalised cell centre (±1, u_p, v_q) with u_p = (2p + 1 − m)/m; its exact solid angle is
//! Ω = Σ± atan2(xy, √(1 + x² + y²)) over the cell corners. Storage directions are the six
//! face cones (|Ω^d| = 4π/6) and d(i) is the face that owns i.

use crate::SolverError;
use crate::scene::Phase;
use std::f64::consts::PI;

/// Largest m accepted (m² cells per face, 6m² directions): 64 gives 24 576 directions.
pub const MAX_M: usize = 64;

/// Largest m for which the fine n × n phase matrix is built (n = 1536 directions).
pub const MAX_FINE_M: usize = 16;

/// Number of storage cones (one per cube face).
pub const CONES: usize = 6;

/// The lateral axes (b, c) of a face whose sweep axis is `a`: x stays the first lateral axis
/// where it can, so two of the three sweeps run along contiguous memory.
pub fn lateral_axes(a: usize) -> (usize, usize) {
    match a {
        0 => (1, 2),
        1 => (0, 2),
        _ => (0, 1),
    }
}

/// One propagation direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Direction {
    /// Face (LPM) index f = 2a + (0 for +e_a, 1 for −e_a); also its storage cone d(i).
    pub face: usize,
    /// Cell indices (p along the first lateral axis, q along the second).
    pub cell: [usize; 2],
    /// Unit direction of travel.
    pub omega: [f64; 3],
    /// Exact solid angle |Ω^i| of the cell.
    pub solid_angle: f64,
    /// |ω·n_f| = 1/√(1 + u² + v²), the axial cosine.
    pub cos_axis: f64,
    /// Lateral drift per slab in voxels along (b, c) as the exact fraction (U_b, U_c)/m with
    /// U = 2p + 1 − m (signed).
    pub drift_num: [i64; 2],
}

impl Direction {
    /// Sweep axis a and sign (+1 or −1) of the face.
    pub fn axis(&self) -> (usize, i64) {
        (self.face / 2, if self.face % 2 == 0 { 1 } else { -1 })
    }
}

/// The signed solid angle of the gnomonic rectangle [0, x] × [0, y] on a unit-distance face.
fn corner(x: f64, y: f64) -> f64 {
    (x * y).atan2((1.0 + x * x + y * y).sqrt())
}

/// Exact solid angle of the gnomonic cell [u0, u1] × [v0, v1].
pub fn cell_solid_angle(u0: f64, u1: f64, v0: f64, v1: f64) -> f64 {
    corner(u1, v1) - corner(u0, v1) - corner(u1, v0) + corner(u0, v0)
}

/// The direction set: 6 faces × m × m cells.
#[derive(Debug, Clone, PartialEq)]
pub struct Directions {
    /// Cells per face edge.
    pub m: usize,
    /// All 6m² directions, index i = f·m² + p·m + q.
    pub dirs: Vec<Direction>,
}

impl Directions {
    /// The m×m-per-face set (D10). Errors name `m`: 0 (no directions) or above [`MAX_M`].
    pub fn new(m: usize) -> Result<Self, SolverError> {
        if m == 0 {
            return Err(SolverError::BadParameter {
                name: "m",
                value: 0.0,
                reason: "zero directions: at least 1 propagation cell per face edge is needed",
            });
        }
        if m > MAX_M {
            return Err(SolverError::BadParameter {
                name: "m",
                value: m as f64,
                reason: "at most 64 propagation cells per face edge (24 576 directions)",
            });
        }
        let mf = m as f64;
        let edge = |p: usize| -1.0 + 2.0 * p as f64 / mf;
        let mut dirs = Vec::with_capacity(6 * m * m);
        for face in 0..6 {
            let a = face / 2;
            let sign = if face % 2 == 0 { 1.0 } else { -1.0 };
            let (b, c) = lateral_axes(a);
            for p in 0..m {
                for q in 0..m {
                    let ub = (2 * p + 1) as i64 - m as i64;
                    let uc = (2 * q + 1) as i64 - m as i64;
                    let (u, v) = (ub as f64 / mf, uc as f64 / mf);
                    let norm = (1.0 + u * u + v * v).sqrt();
                    let mut omega = [0.0; 3];
                    omega[a] = sign / norm;
                    omega[b] = u / norm;
                    omega[c] = v / norm;
                    dirs.push(Direction {
                        face,
                        cell: [p, q],
                        omega,
                        solid_angle: cell_solid_angle(edge(p), edge(p + 1), edge(q), edge(q + 1)),
                        cos_axis: 1.0 / norm,
                        drift_num: [ub, uc],
                    });
                }
            }
        }
        Ok(Self { m, dirs })
    }

    /// Number of directions, 6m².
    pub fn len(&self) -> usize {
        self.dirs.len()
    }

    /// Always false (m ≥ 1).
    pub fn is_empty(&self) -> bool {
        self.dirs.is_empty()
    }

    /// Directions per face, m².
    pub fn per_face(&self) -> usize {
        self.m * self.m
    }

    /// The index of the cell that contains the unit vector `w` (the snap of D13).
    pub fn containing(&self, w: [f64; 3]) -> usize {
        let a = (0..3)
            .max_by(|&x, &y| w[x].abs().total_cmp(&w[y].abs()))
            .unwrap_or(2);
        let face = 2 * a + usize::from(w[a] < 0.0);
        let (b, c) = lateral_axes(a);
        let m = self.m as f64;
        let cell =
            |t: f64| (((t / w[a].abs() + 1.0) * 0.5 * m).floor().max(0.0) as usize).min(self.m - 1);
        face * self.m * self.m + cell(w[b]) * self.m + cell(w[c])
    }
}

/// The solid angle of one storage cone, 4π/6.
pub const CONE_SOLID_ANGLE: f64 = 4.0 * PI / 6.0;

/// Gauss–Legendre nodes and weights on [−1, 1] (Newton on P_n).
pub fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    let mut out = Vec::with_capacity(n);
    for k in 0..n {
        let mut x = (PI * (k as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            let (mut p0, mut p1) = (1.0, x);
            for j in 2..=n {
                let p2 = ((2 * j - 1) as f64 * x * p1 - (j - 1) as f64 * p0) / j as f64;
                p0 = p1;
                p1 = p2;
            }
            dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
            let dx = p1 / dp;
            x -= dx;
            if dx.abs() < 1e-16 {
                break;
            }
        }
        out.push((x, 2.0 / ((1.0 - x * x) * dp * dp)));
    }
    out
}

/// The phase function ρ(cos θ) with ∫ρ dω = 4π (spec §1.1).
pub fn rho(phase: Phase, cos: f64) -> f64 {
    match phase {
        Phase::Isotropic => 1.0,
        Phase::HenyeyGreenstein { g } => (1.0 - g * g) / (1.0 + g * g - 2.0 * g * cos).powf(1.5),
    }
}

/// F of LPM Eq 5 between propagation cells and its coarse (cone) sums, after the symmetric
/// renormalisation of D8.
#[derive(Debug, Clone, PartialEq)]
pub struct PhaseMatrix {
    /// Number of directions n = 6m².
    pub n: usize,
    /// Fine F^{i,j} (n × n, row-major), symmetric, rows sum to |Ω^i|.
    pub fine: Vec<f64>,
    /// The raw quadrature F before renormalisation (n × n), for the error report of T2.
    pub raw: Vec<f64>,
    /// Coarse F^{i,d′} = Σ_{j ∈ cone d′} F^{i,j} (n × 6).
    pub coarse: Vec<f64>,
    /// Sinkhorn sweeps used.
    pub sinkhorn_sweeps: usize,
}

impl PhaseMatrix {
    /// F by `q`×`q` Gauss–Legendre points per cell in tangent coordinates
    /// (dω = du dv/(1 + u² + v²)^{3/2}), then Sinkhorn-scaled symmetrically,
    /// F ← c_i F c_j, until every row sum equals |Ω^i| to 10⁻¹⁵ (relative).
    ///
    /// The fine matrix has n² entries, so it is built only for m ≤ [`MAX_FINE_M`]; a larger
    /// m is an error naming `m` for Henyey–Greenstein, and for isotropic scattering the
    /// coarse matrix is the exact F^{i,d′} = |Ω^i||Ω^{d′}|/4π (the limit the renormalised
    /// quadrature reaches, T2) with `fine` and `raw` left empty.
    pub fn new(dirs: &Directions, phase: Phase, q: usize) -> Result<Self, SolverError> {
        phase.validate()?;
        if dirs.m > MAX_FINE_M {
            if let Phase::HenyeyGreenstein { .. } = phase {
                return Err(SolverError::BadParameter {
                    name: "m",
                    value: dirs.m as f64,
                    reason: "an anisotropic phase matrix is built for at most 16 cells per face edge",
                });
            }
            let n = dirs.len();
            let coarse = (0..n * CONES)
                .map(|k| dirs.dirs[k / CONES].solid_angle * CONE_SOLID_ANGLE / (4.0 * PI))
                .collect();
            return Ok(Self {
                n,
                fine: Vec::new(),
                raw: Vec::new(),
                coarse,
                sinkhorn_sweeps: 0,
            });
        }
        if q == 0 || q > 32 {
            return Err(SolverError::BadParameter {
                name: "quadrature",
                value: q as f64,
                reason: "Gauss points per cell axis must be in 1..=32",
            });
        }
        let m = dirs.m;
        let n = dirs.len();
        let gl = gauss_legendre(q);
        let h = 2.0 / m as f64;
        // Quadrature points: (direction, weight), q² per cell, cells in direction order.
        let mut pts: Vec<([f64; 3], f64)> = Vec::with_capacity(n * q * q);
        for d in &dirs.dirs {
            let (a, sign) = d.axis();
            let (b, c) = lateral_axes(a);
            let u0 = -1.0 + h * d.cell[0] as f64;
            let v0 = -1.0 + h * d.cell[1] as f64;
            for &(xu, wu) in &gl {
                for &(xv, wv) in &gl {
                    let u = u0 + 0.5 * h * (xu + 1.0);
                    let v = v0 + 0.5 * h * (xv + 1.0);
                    let r2 = 1.0 + u * u + v * v;
                    let norm = r2.sqrt();
                    let mut w = [0.0; 3];
                    w[a] = sign as f64 / norm;
                    w[b] = u / norm;
                    w[c] = v / norm;
                    pts.push((w, 0.25 * h * h * wu * wv / (r2 * norm)));
                }
            }
        }
        let qq = q * q;
        let mut raw = vec![0.0; n * n];
        match phase {
            Phase::Isotropic => {
                let sa: Vec<f64> = (0..n)
                    .map(|i| pts[i * qq..(i + 1) * qq].iter().map(|p| p.1).sum())
                    .collect();
                for i in 0..n {
                    for j in 0..n {
                        raw[i * n + j] = sa[i] * sa[j] / (4.0 * PI);
                    }
                }
            }
            Phase::HenyeyGreenstein { .. } => {
                use rayon::prelude::*;
                let rows: Vec<Vec<f64>> = (0..n)
                    .into_par_iter()
                    .map(|i| {
                        let pi = &pts[i * qq..(i + 1) * qq];
                        (0..n)
                            .map(|j| {
                                let pj = &pts[j * qq..(j + 1) * qq];
                                let mut s = 0.0;
                                for (wi, ai) in pi {
                                    let mut t = 0.0;
                                    for (wj, aj) in pj {
                                        let cos = wi[0] * wj[0] + wi[1] * wj[1] + wi[2] * wj[2];
                                        t += aj * rho(phase, cos);
                                    }
                                    s += ai * t;
                                }
                                s / (4.0 * PI)
                            })
                            .collect()
                    })
                    .collect();
                for i in 0..n {
                    for j in 0..n {
                        // Symmetrise the (already symmetric up to rounding) quadrature.
                        raw[i * n + j] = 0.5 * (rows[i][j] + rows[j][i]);
                    }
                }
            }
        }
        // Symmetric Sinkhorn: c_i ← c_i √(|Ω^i| / (c_i Σ_j F_ij c_j)).
        let target: Vec<f64> = dirs.dirs.iter().map(|d| d.solid_angle).collect();
        let mut c = vec![1.0; n];
        let mut sweeps = 0;
        for sweep in 1..=10_000 {
            sweeps = sweep;
            let mut worst: f64 = 0.0;
            let rows: Vec<f64> = (0..n)
                .map(|i| c[i] * (0..n).map(|j| raw[i * n + j] * c[j]).sum::<f64>())
                .collect();
            for i in 0..n {
                worst = worst.max((rows[i] / target[i] - 1.0).abs());
                c[i] *= (target[i] / rows[i]).sqrt();
            }
            if worst < 1e-15 {
                break;
            }
        }
        let mut fine = vec![0.0; n * n];
        for i in 0..n {
            for j in 0..n {
                fine[i * n + j] = c[i] * raw[i * n + j] * c[j];
            }
        }
        let per = m * m;
        let mut coarse = vec![0.0; n * CONES];
        if phase == Phase::Isotropic {
            for (k, f) in coarse.iter_mut().enumerate() {
                *f = dirs.dirs[k / CONES].solid_angle * CONE_SOLID_ANGLE / (4.0 * PI);
            }
        } else {
            for i in 0..n {
                for j in 0..n {
                    coarse[i * CONES + j / per] += fine[i * n + j];
                }
            }
        }
        Ok(Self {
            n,
            fine,
            raw,
            coarse,
            sinkhorn_sweeps: sweeps,
        })
    }

    /// Coarse F^{i,d′}.
    pub fn coarse(&self, i: usize, d: usize) -> f64 {
        self.coarse[i * CONES + d]
    }
}
