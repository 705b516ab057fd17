//! Perona–Malik selective diffusion (thesis Eqs 3.1–3.5), the thesis's "fluoroscopy-like"
//! proof of concept (thesis Figs 3.3, 3.4) and the motivation of the RDE.
//!
//! ## The thesis's equations
//! ∂I/∂t = C∆I + ∇C·∇I = ∇·(C∇I) (thesis Eq 3.1), conductance C = exp(−(‖∇I‖/σ)²) (thesis
//! Eq 3.2) or C = 1/(1 + (‖∇I‖/σ)²) (thesis Eq 3.3), and the explicit edge-flux scheme
//! Iᵗ⁺¹ = Iᵗ + λ Σ_P C_P δ_P I with C_P = C(|δ_P I|) over the 4 (2D, thesis Eq 3.4,
//! 0 ≤ λ ≤ 1/4) or 6 (3D, thesis Eq 3.5, 0 ≤ λ ≤ 1/6) neighbours.
//!
//! ## Decisions where the paper is silent (spec §1.11; tests `f25_…` in `tests.rs`)
//! * **Data and energy roles.** The diffused field is an energy volume E, zero except at the
//!   source; the conductances come from the data volume V, normalised to [0, 1] (min–max):
//!   C_P = C(|V_P − V_p|) (thesis Eq 3.5 writes δ_P V), computed once per face. So the
//!   update is E ← E + λ Σ_P C_P (E_P − E_p): symmetric per face, conservative.
//! * **Clamped source.** The source voxels are held at E_src after every step (the thesis:
//!   reachable voxels converge "toward the same level of energy as the light sources").
//!   With Neumann walls the steady state is E = E_src on the region connected to the source
//!   (measured, f64: within 2.1·10⁻¹¹ of E_src on both chambers of a 16² box joined by a
//!   one-voxel gap after 63 531 iterations; with the gap closed at σ = 0.05 the near chamber
//!   is within 3.9·10⁻¹² and the far one stays at 7.6·10⁻¹⁷¹; f32 creeps by ulps through the
//!   gap, 8.6·10⁻⁵ at every cap from 3·10⁴ to 4·10⁵ iterations (the test's is 10⁵);
//!   `f25_…_floods_the_connected_region`).
//! * **Walls.** Zero-flux Neumann: faces to outside the grid carry no flux (the thesis's
//!   "floods to the source level" needs no leak through the box).
//! * **Time step.** λ ≤ 1/(2d) with d the number of axes longer than one voxel (thesis
//!   Eqs 3.4–3.5; the 2D phantoms are three voxels thick and z-invariant, since every grid
//!   axis has ≥ 3 voxels, so they run under the 3D bound 1/6); with C ≤ 1 this is the positivity (maximum-principle) bound, so
//!   0 ≤ E ≤ E_src at every step (asserted in the tests); above it
//!   [`SolverError::StepAboveBound`] names `lambda`. Default the bound itself.
//! * **Capped iterations.** C > 0 everywhere and no absorption: the whole connected grid
//!   floods eventually (thesis l. 3128–3140), so runs take an iteration cap
//!   ([`PeronaMalik::run`]). The flood time across an edge of data contrast h scales as
//!   1/C(h) when the edge is the bottleneck: measured with thesis Eq 3.3 and h = 1 on a
//!   4×3(×3) two-chamber phantom fed by a clamped plane, t·C(h) = 8.36, 8.49, 8.96 at
//!   σ = 0.05, 0.1, 0.2 (spread 1.07, bound 1.2; `f25_flood_time_…`; an 8×4 phantom with a
//!   one-column source spreads 1.38, the chamber's own mixing time then adds to t). Thesis
//!   Eq 3.2 cannot span that σ range with a
//!   bottleneck edge (C = e⁻⁴⁰⁰ … e⁻²⁵ at h = 1), which is the thesis's "σ ≪ 0.01: almost
//!   no diffusion" regime.

use super::Coefficients;
use crate::{Grid, Real, SolverError};
use rayon::prelude::*;

/// The conductance function of thesis Eqs 3.2–3.3.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Conductance {
    /// C = exp(−(g/σ)²) (thesis Eq 3.2).
    #[default]
    Exponential,
    /// C = 1/(1 + (g/σ)²) (thesis Eq 3.3).
    Rational,
}

impl Conductance {
    /// C(g) for a data difference (or gradient magnitude) `g` and edge scale `sigma`.
    pub fn eval(self, g: f64, sigma: f64) -> f64 {
        let x = (g / sigma).powi(2);
        match self {
            Conductance::Exponential => (-x).exp(),
            Conductance::Rational => 1.0 / (1.0 + x),
        }
    }
}

/// Settings of a Perona–Malik run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PmConfig {
    /// Conductance function.
    pub conductance: Conductance,
    /// Edge scale σ (> 0), in units of the normalised data.
    pub sigma: f64,
    /// λ of thesis Eqs 3.4–3.5; `None`: the bound 1/(2d).
    pub lambda: Option<f64>,
    /// E_src, the level the source voxels are clamped to (> 0).
    pub source_level: f64,
}

impl Default for PmConfig {
    fn default() -> Self {
        Self {
            conductance: Conductance::Exponential,
            sigma: 0.1,
            lambda: None,
            source_level: 1.0,
        }
    }
}

/// How a [`PeronaMalik::run`] ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PmRun {
    /// Iterations run in this call.
    pub iterations: usize,
    /// max|∆E| of the last iteration, relative to E_src.
    pub last_change: f64,
    /// Whether it stopped on the tolerance (else on the cap).
    pub converged: bool,
}

/// The state of a Perona–Malik run: two energy buffers and the face conductances.
#[derive(Debug, Clone)]
pub struct PeronaMalik<T> {
    grid: Grid,
    e: [Vec<T>; 2],
    cur: usize,
    /// Conductance of the face to the +x, +y, +z neighbour (0 at the wall).
    c: [Vec<T>; 3],
    sources: Vec<usize>,
    level: T,
    lambda: T,
    iterations: usize,
}

/// The number of axes longer than one voxel.
fn dims(grid: &Grid) -> usize {
    grid.n.iter().filter(|&&n| n > 1).count()
}

impl<T: Real> PeronaMalik<T> {
    /// Normalises `data` to [0, 1], computes the face conductances, checks λ and places the
    /// clamped sources.
    pub fn new(
        grid: Grid,
        data: &[f64],
        sources: &[[usize; 3]],
        cfg: &PmConfig,
    ) -> Result<Self, SolverError> {
        let n = grid.len();
        if data.len() != n {
            return Err(SolverError::FieldSize {
                field: "data",
                expected: n,
                got: data.len(),
            });
        }
        if let Some(index) = data.iter().position(|x| !x.is_finite()) {
            return Err(SolverError::FieldValue {
                field: "data",
                index,
                value: data[index],
                range: "finite values",
            });
        }
        if !(cfg.sigma.is_finite() && cfg.sigma > 0.0) {
            return Err(SolverError::BadParameter {
                name: "sigma",
                value: cfg.sigma,
                reason: "the conductance's edge scale σ must be finite and > 0",
            });
        }
        if !(cfg.source_level.is_finite() && cfg.source_level > 0.0) {
            return Err(SolverError::BadParameter {
                name: "source_level",
                value: cfg.source_level,
                reason: "E_src must be finite and > 0",
            });
        }
        let d = dims(&grid).max(1);
        let bound = 1.0 / (2 * d) as f64;
        let lambda = cfg.lambda.unwrap_or(bound);
        if !(lambda.is_finite() && lambda > 0.0) {
            return Err(SolverError::BadParameter {
                name: "lambda",
                value: lambda,
                reason: "λ must be finite and > 0",
            });
        }
        if lambda > bound {
            return Err(SolverError::StepAboveBound {
                name: "lambda",
                value: lambda,
                bound,
                criterion: "thesis Eqs 3.4–3.5, λ ≤ 1/(2d) (positivity with C ≤ 1)",
            });
        }
        if sources.is_empty() {
            return Err(SolverError::BadParameter {
                name: "sources",
                value: 0.0,
                reason: "at least one clamped source voxel is needed",
            });
        }
        let mut src = Vec::with_capacity(sources.len());
        for v in sources {
            if let Some(a) = (0..3).find(|&a| v[a] >= grid.n[a]) {
                return Err(SolverError::BadParameter {
                    name: "sources",
                    value: v[a] as f64,
                    reason: "a source voxel index is outside the grid",
                });
            }
            src.push(grid.index(v[0], v[1], v[2]));
        }
        let (lo, hi) = data
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &x| {
                (l.min(x), h.max(x))
            });
        let span = if hi > lo { hi - lo } else { 1.0 };
        let v = |idx: usize| (data[idx] - lo) / span;
        let stride = [1, grid.n[0], grid.n[0] * grid.n[1]];
        let c = [0, 1, 2].map(|axis| {
            (0..n)
                .map(|idx| {
                    let p = grid.coords(idx);
                    if p[axis] + 1 >= grid.n[axis] {
                        return T::zero();
                    }
                    let q = idx + stride[axis];
                    T::c(cfg.conductance.eval((v(q) - v(idx)).abs(), cfg.sigma))
                })
                .collect::<Vec<T>>()
        });
        let mut e0 = vec![T::zero(); n];
        let level = T::c(cfg.source_level);
        for &s in &src {
            e0[s] = level;
        }
        Ok(Self {
            grid,
            e: [e0.clone(), e0],
            cur: 0,
            c,
            sources: src,
            level,
            lambda: T::c(lambda),
            iterations: 0,
        })
    }

    /// The grid.
    pub fn grid(&self) -> &Grid {
        &self.grid
    }

    /// λ in use.
    pub fn lambda(&self) -> f64 {
        self.lambda.f()
    }

    /// Iterations run so far.
    pub fn iterations(&self) -> usize {
        self.iterations
    }

    /// The current energy (natural layout).
    pub fn energy(&self) -> &[T] {
        &self.e[self.cur]
    }

    /// The conductance of the face between voxel `idx` and its + neighbour along `axis`.
    pub fn face_conductance(&self, axis: usize, idx: usize) -> f64 {
        self.c[axis][idx].f()
    }

    /// One iteration E ← E + λ Σ_P C_P (E_P − E_p), then the sources clamped; returns
    /// max|∆E|/E_src.
    pub fn step(&mut self) -> f64 {
        let [nx, ny, _] = self.grid.n;
        let slab = nx * ny;
        let (a, b) = self.e.split_at_mut(1);
        let (src, dst) = if self.cur == 0 {
            (&a[0], &mut b[0])
        } else {
            (&b[0], &mut a[0])
        };
        let [cx, cy, cz] = &self.c;
        let lambda = self.lambda;
        let len = src.len();
        let change = dst
            .par_chunks_mut(slab)
            .enumerate()
            .map(|(k, out)| {
                let mut m = 0.0f64;
                for (o, val) in out.iter_mut().enumerate() {
                    let idx = k * slab + o;
                    let p = src[idx];
                    let mut flux = T::zero();
                    // The − neighbours' faces are stored at the neighbour (0 at the wall).
                    if o % nx + 1 < nx {
                        flux = flux + cx[idx] * (src[idx + 1] - p);
                    }
                    if o % nx > 0 {
                        flux = flux + cx[idx - 1] * (src[idx - 1] - p);
                    }
                    if o / nx + 1 < ny {
                        flux = flux + cy[idx] * (src[idx + nx] - p);
                    }
                    if o / nx > 0 {
                        flux = flux + cy[idx - nx] * (src[idx - nx] - p);
                    }
                    if idx + slab < len {
                        flux = flux + cz[idx] * (src[idx + slab] - p);
                    }
                    if idx >= slab {
                        flux = flux + cz[idx - slab] * (src[idx - slab] - p);
                    }
                    let d = lambda * flux;
                    *val = p + d;
                    m = m.max(d.f().abs());
                }
                m
            })
            .reduce(|| 0.0, f64::max);
        for &s in &self.sources {
            dst[s] = self.level;
        }
        self.cur = 1 - self.cur;
        self.iterations += 1;
        change / self.level.f()
    }

    /// Iterates until max|∆E|/E_src ≤ `tolerance` or `max_iterations` (the thesis's cap
    /// against flooding).
    pub fn run(&mut self, max_iterations: usize, tolerance: f64) -> PmRun {
        let mut last = f64::NAN;
        for i in 0..max_iterations {
            last = self.step();
            if last <= tolerance {
                return PmRun {
                    iterations: i + 1,
                    last_change: last,
                    converged: true,
                };
            }
        }
        PmRun {
            iterations: max_iterations,
            last_change: last,
            converged: false,
        }
    }
}

/// A synthetic containment phantom (spec §3, standing in for the thesis's CT data): the
/// data volume, the structure the energy should stay in, and a source voxel inside it.
#[derive(Debug, Clone, PartialEq)]
pub struct Phantom {
    /// The grid (∆ = 1).
    pub grid: Grid,
    /// Data values in [0, 1].
    pub data: Vec<f64>,
    /// The structure (the region the energy should fill).
    pub inside: Vec<bool>,
    /// The source voxels inside the structure (one, or a z column for the 2D phantoms).
    pub sources: Vec<[usize; 3]>,
}

impl Phantom {
    /// 2D n × n (three voxels thick, z-invariant, since a grid axis has ≥ 3 voxels): a wall of data 1 along the column i = n/2 with a gap of
    /// `gap` voxels centred on it (0: closed), data 0 elsewhere; the structure is the left
    /// chamber i < n/2, the source the column (n/4, n/2, ·).
    pub fn gap_edge(n: usize, gap: usize) -> Result<Self, SolverError> {
        if n < 6 || gap > n {
            return Err(SolverError::BadParameter {
                name: "n",
                value: n as f64,
                reason: "the gap phantom needs n ≥ 6 and gap ≤ n",
            });
        }
        let grid = Grid::new([n, n, 3], 1.0)?;
        let (w, lo) = (n / 2, (n - gap) / 2);
        let hi = lo + gap;
        let mut data = vec![0.0; grid.len()];
        for k in 0..3 {
            for j in 0..n {
                if !(lo..hi).contains(&j) {
                    data[grid.index(w, j, k)] = 1.0;
                }
            }
        }
        let inside = (0..grid.len()).map(|idx| grid.coords(idx)[0] < w).collect();
        Ok(Self {
            grid,
            data,
            inside,
            sources: (0..3).map(|k| [n / 4, n / 2, k]).collect(),
        })
    }

    /// 3D n³: a tube (vessel) of data 1 and radius `radius` along z through the centre, data
    /// 0 outside; the structure is the tube, the source on its axis at k = n/4.
    pub fn tube(n: usize, radius: f64) -> Result<Self, SolverError> {
        if !(radius.is_finite() && radius >= 1.0 && radius < n as f64 / 2.0 - 1.0) {
            return Err(SolverError::BadParameter {
                name: "radius",
                value: radius,
                reason: "the tube radius must be in [1, n/2 − 1)",
            });
        }
        let grid = Grid::new([n; 3], 1.0)?;
        let c = n as f64 / 2.0;
        let inside: Vec<bool> = (0..grid.len())
            .map(|idx| {
                let [i, j, _] = grid.coords(idx);
                let (x, y) = (i as f64 + 0.5 - c, j as f64 + 0.5 - c);
                (x * x + y * y).sqrt() < radius
            })
            .collect();
        let data = inside.iter().map(|&b| if b { 1.0 } else { 0.0 }).collect();
        Ok(Self {
            grid,
            data,
            inside,
            sources: vec![[n / 2, n / 2, n / 4]],
        })
    }

    /// 2D nx × ny (three voxels thick, z-invariant): two chambers, data 0 for i < nx/2 and 1 beyond (one edge of contrast 1
    /// across the grid); the structure is the left chamber, the source the whole plane i = 0.
    pub fn step_edge(nx: usize, ny: usize) -> Result<Self, SolverError> {
        let grid = Grid::new([nx, ny, 3], 1.0)?;
        let inside: Vec<bool> = (0..grid.len())
            .map(|idx| grid.coords(idx)[0] < nx / 2)
            .collect();
        let data = inside.iter().map(|&b| if b { 0.0 } else { 1.0 }).collect();
        Ok(Self {
            grid,
            data,
            inside,
            sources: (0..3)
                .flat_map(|k| (0..ny).map(move |j| [0, j, k]))
                .collect(),
        })
    }

    /// The thesis's gradient mapping (thesis Sec 4.2.2): β = max(C(‖∇V‖, σ), floor) with
    /// ‖∇V‖ from central differences (one-sided at the walls), for the RDE on the phantom.
    pub fn gradient_beta(&self, conductance: Conductance, sigma: f64, floor: f64) -> Vec<f64> {
        let g = self.grid;
        (0..g.len())
            .map(|idx| {
                let p = g.coords(idx);
                let d = |axis: usize| -> f64 {
                    if g.n[axis] == 1 {
                        return 0.0;
                    }
                    let at = |dir: i64| {
                        let mut q = p;
                        q[axis] = (p[axis] as i64 + dir).clamp(0, g.n[axis] as i64 - 1) as usize;
                        self.data[g.index(q[0], q[1], q[2])]
                    };
                    (at(1) - at(-1)) / 2.0
                };
                let gn = (d(0).powi(2) + d(1).powi(2) + d(2).powi(2)).sqrt();
                conductance.eval(gn, sigma).max(floor)
            })
            .collect()
    }

    /// RDE coefficients on the phantom: β from [`Phantom::gradient_beta`], a = Ka∆ given per
    /// voxel by `ka_dl(β)` (the thesis's "1 − β", or (1 − α)/(3β) from an albedo), a unit
    /// volume source at each source voxel.
    pub fn rde_coefficients(
        &self,
        beta: Vec<f64>,
        ka_dl: impl Fn(f64) -> f64,
    ) -> Result<Coefficients, SolverError> {
        let ka = beta.iter().map(|&b| ka_dl(b)).collect();
        let mut src = vec![0.0; self.grid.len()];
        for s in &self.sources {
            src[self.grid.index(s[0], s[1], s[2])] = 1.0;
        }
        Coefficients::from_maps(self.grid, beta, ka, src)
    }
}

/// Leak fraction: the energy outside the structure over the total (0 when the total is 0).
pub fn leak_fraction<T: Real>(e: &[T], inside: &[bool]) -> f64 {
    let (mut out, mut all) = (0.0, 0.0);
    for (x, &b) in e.iter().zip(inside) {
        let v = x.f().max(0.0);
        all += v;
        if !b {
            out += v;
        }
    }
    if all > 0.0 { out / all } else { 0.0 }
}

/// Fill fraction: the mean energy over the structure relative to `level` (for the RDE, the
/// source voxel's value or max φ).
pub fn fill_fraction<T: Real>(e: &[T], inside: &[bool], level: f64) -> f64 {
    let (mut s, mut n) = (0.0, 0usize);
    for (x, &b) in e.iter().zip(inside) {
        if b {
            s += x.f().max(0.0);
            n += 1;
        }
    }
    if n == 0 || level <= 0.0 {
        0.0
    } else {
        s / n as f64 / level
    }
}
