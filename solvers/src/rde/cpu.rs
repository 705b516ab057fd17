//! The CPU kernel of the RDE's FTCS update, parallel with rayon over z-slabs, generic over
//! `f32`/`f64`.
//!
//! ## Layout
//! Natural layout (x fastest), two φ buffers (ping-pong, thesis Fig 4.2): a step reads one
//! and writes the other, so the update is exactly the explicit map φⁿ⁺¹ = φⁿ + r B(φⁿ)
//! whatever the order of the voxels or the number of threads. Per voxel and step it reads
//! φ (7 values, the neighbours from cached rows), β (7), a, s and writes φ: five streams,
//! 20 bytes per voxel in `f32`. Measured at 128³ f32 on this project's 2 shared cores:
//! 2.5 ms per step (16.6 GB/s of the counted traffic), 2.9 ms with the residual (the squared
//! brackets go to a row scratch and are summed in eight fixed lanes afterwards; summing them
//! inside the update loop cost 8.5 ms).
//!
//! With the solve's fields in normalised units (q/j̄), grid units ∆ = 1 in the bracket:
//! B_p = s_p − a_p φ_p + L(φ)_p, s = ∆q/j̄, and R_p = B_p/∆ is FLD Eq 37's residual
//! (the steady-state residual (φⁿ⁺¹ − φⁿ)/(c∆t)), evaluated before the update as in FLD.

use super::{
    BoundaryCondition, Coefficients, RdeConfig, RdeSolution, RdeTrace, ResolvedStep, Run,
    resolve_step,
};
use crate::fld::residual::ResidualWindow;
use crate::gpu::Timer;
use crate::method::Stop;
use crate::{Grid, Real, SolverError};
use rayon::prelude::*;
use std::time::Instant;

/// The state of one RDE run: two φ buffers and the per-voxel coefficients.
///
/// Build with [`CpuRde::new`], then [`CpuRde::run`] (the configured run mode) or
/// [`CpuRde::step`] one step at a time (tests, benchmarks, interactive use).
#[derive(Debug, Clone)]
pub struct CpuRde<T> {
    grid: Grid,
    config: RdeConfig,
    phi: [Vec<T>; 2],
    /// Which of `phi` holds the current field.
    cur: usize,
    beta: Vec<T>,
    absorb: Vec<T>,
    src: Vec<T>,
    /// r_p of the `Local` time step; empty for a global r.
    rloc: Vec<T>,
    r: T,
    window: ResidualWindow,
    /// j̄ (or its substitute), the fields' normalisation.
    j_ref: f64,
    trivial: bool,
    steps: usize,
    residuals: Vec<f64>,
    trace: RdeTrace<T>,
    setup_seconds: f64,
}

impl<T: Real> CpuRde<T> {
    /// Validates the inputs, resolves and checks the time step, and builds the state.
    pub fn new(coef: &Coefficients, config: &RdeConfig) -> Result<Self, SolverError> {
        let t0 = Instant::now();
        coef.validate()?;
        config.validate()?;
        let grid = coef.grid;
        let bc = config.boundary;
        let bounds = coef.bounds(bc);
        let step = resolve_step(coef, config, &bounds)?;
        let dl = grid.dl;
        let n = grid.len();
        let jbar = (coef.source.iter().map(|q| q * q).sum::<f64>() / n as f64).sqrt();
        let init_max = coef
            .initial
            .as_ref()
            .map(|v| v.iter().fold(0.0f64, |m, x| m.max(x.abs())))
            .unwrap_or(0.0);
        let j_ref = if jbar > 0.0 { jbar } else { init_max / dl };
        let trivial = j_ref == 0.0;
        let scale = if trivial { 1.0 } else { j_ref };
        let mut phi0 = vec![T::zero(); n];
        if let Some(init) = &coef.initial {
            // Dirichlet: the boundary layer keeps these values for the whole run.
            for (p, &v) in phi0.iter_mut().zip(init) {
                *p = T::c(v / scale);
            }
        }
        let (r, rloc, local) = match &step {
            ResolvedStep::Global(r) => (*r, Vec::new(), false),
            ResolvedStep::Local(v) => (
                v.iter().cloned().fold(0.0, f64::max),
                v.iter().map(|&x| T::c(x)).collect(),
                true,
            ),
        };
        let trace = RdeTrace {
            r,
            local,
            bounds,
            beta_capped: coef.beta_capped,
            expanded_violations: match config.operator {
                super::Operator::Conservative => 0,
                _ => coef.expanded_violations(bc),
            },
            ..RdeTrace::default()
        };
        let conv = |v: &[f64]| v.iter().map(|&x| T::c(x)).collect::<Vec<T>>();
        Ok(Self {
            grid,
            config: config.clone(),
            phi: [phi0.clone(), phi0],
            cur: 0,
            beta: conv(&coef.beta),
            absorb: conv(&coef.ka_dl),
            src: coef.source.iter().map(|&q| T::c(q / scale * dl)).collect(),
            rloc,
            r: T::c(r),
            window: super::window(&grid, config.residual_margin),
            j_ref,
            trivial,
            steps: 0,
            residuals: Vec::new(),
            trace,
            setup_seconds: t0.elapsed().as_secs_f64(),
        })
    }

    /// The grid.
    pub fn grid(&self) -> &Grid {
        &self.grid
    }

    /// Steps run so far.
    pub fn steps(&self) -> usize {
        self.steps
    }

    /// r = c∆t/∆ (`Local`: the largest r_p).
    pub fn r(&self) -> f64 {
        self.trace.r
    }

    /// What is known before running: r, bounds, cap and violation counts.
    pub fn trace(&self) -> &RdeTrace<T> {
        &self.trace
    }

    /// j̄, the normalisation of the fields (and of the residual).
    pub fn j_ref(&self) -> f64 {
        self.j_ref
    }

    /// The tolerance of a `Steady` run in this precision.
    pub fn tolerance(&self) -> f64 {
        match self.config.run {
            Run::Steady { tolerance, .. } => tolerance.unwrap_or(T::DEFAULT_TOLERANCE),
            Run::Frames { .. } => 0.0,
        }
    }

    /// No source and no initial field: φ = 0 without stepping.
    pub(crate) fn is_trivial(&self) -> bool {
        self.trivial
    }

    /// The residual window.
    pub(crate) fn window(&self) -> ResidualWindow {
        self.window
    }

    /// The initial fields for the GPU: φ, β, a, s (normalised) and r_p (empty if global).
    pub(crate) fn fields(&self) -> [&[T]; 5] {
        [
            &self.phi[self.cur],
            &self.beta,
            &self.absorb,
            &self.src,
            &self.rloc,
        ]
    }

    /// Bytes one step moves at least: φ read and written, β, a, s read (and r_p for
    /// `Local`), once per voxel.
    pub fn bytes_per_step(&self) -> usize {
        let words = if self.rloc.is_empty() { 5 } else { 6 };
        words * self.grid.len() * std::mem::size_of::<T>()
    }

    /// The current φ (natural layout, caller's units).
    pub fn phi(&self) -> Vec<T> {
        let scale = if self.trivial { 1.0 } else { self.j_ref };
        self.phi[self.cur]
            .iter()
            .map(|&x| T::c(x.f() * scale))
            .collect()
    }

    /// One FTCS step; with `residual`, returns R̄/j̄ of the field before the step (FLD
    /// Eq 37), else NaN.
    pub fn step(&mut self, residual: bool) -> f64 {
        self.steps += 1;
        if self.trivial {
            return 0.0;
        }
        let op = self.config.operator.id();
        let local = !self.rloc.is_empty();
        let sumsq = match (op, local, residual) {
            (0, false, false) => self.sweep::<0, false, false>(),
            (0, false, true) => self.sweep::<0, false, true>(),
            (0, true, false) => self.sweep::<0, true, false>(),
            (0, true, true) => self.sweep::<0, true, true>(),
            (1, false, false) => self.sweep::<1, false, false>(),
            (1, false, true) => self.sweep::<1, false, true>(),
            (1, true, false) => self.sweep::<1, true, false>(),
            (1, true, true) => self.sweep::<1, true, true>(),
            (_, false, false) => self.sweep::<2, false, false>(),
            (_, false, true) => self.sweep::<2, false, true>(),
            (_, true, false) => self.sweep::<2, true, false>(),
            (_, true, true) => self.sweep::<2, true, true>(),
        };
        self.cur = 1 - self.cur;
        if residual {
            // R = B/∆ (module docs).
            self.window.rms(sumsq / (self.grid.dl * self.grid.dl))
        } else {
            f64::NAN
        }
    }

    /// Runs the configured mode.
    pub fn run(self) -> RdeSolution<T> {
        self.run_observed(|_, _| {})
    }

    /// As [`CpuRde::run`], calling `observer(step, R̄/j̄)` after every step of a `Steady` run.
    pub fn run_observed(mut self, mut observer: impl FnMut(usize, f64)) -> RdeSolution<T> {
        let t0 = Instant::now();
        let mut stop = Stop::Cap;
        match self.config.run {
            Run::Steady { max_steps, .. } => {
                let tol = self.tolerance();
                let by_error = self.config.stop == super::SteadyStop::ErrorBound;
                let every = self.config.check_every as usize;
                let mut bound = super::ErrorBound::default();
                if self.trivial {
                    stop = Stop::Converged;
                } else {
                    if by_error {
                        bound.observe(&self.phi[self.cur]);
                    }
                    while self.steps < max_steps {
                        let r = self.step(true);
                        self.residuals.push(r);
                        observer(self.steps, r);
                        if !r.is_finite() {
                            stop = Stop::NonFinite;
                            break;
                        }
                        if by_error {
                            if self.steps % every == 0 {
                                let e = bound.observe(&self.phi[self.cur]);
                                self.trace.error_estimates.push((self.steps, e));
                                if e < tol {
                                    stop = Stop::Converged;
                                    break;
                                }
                            }
                        } else if r < tol {
                            stop = Stop::Converged;
                            break;
                        }
                    }
                }
            }
            Run::Frames {
                steps,
                snapshot_every,
            } => {
                for _ in 0..steps {
                    self.step(false);
                    if snapshot_every > 0 && self.steps % snapshot_every == 0 {
                        let snap = self.phi();
                        self.trace.snapshots.push((self.steps, snap));
                    }
                }
                if self.phi[self.cur].iter().any(|x| !x.is_finite()) {
                    stop = Stop::NonFinite;
                }
            }
        }
        let seconds = t0.elapsed().as_secs_f64();
        let phi = self.phi();
        let mut trace = std::mem::take(&mut self.trace);
        trace.residuals = std::mem::take(&mut self.residuals);
        super::solution(
            self.grid,
            phi,
            self.steps,
            stop,
            seconds,
            self.setup_seconds,
            Timer::WallClock,
            trace,
            self.grid.dl,
        )
    }

    /// One step over every updated voxel; returns Σ R² over the window (0 without `RES`).
    fn sweep<const OP: u8, const LOCAL: bool, const RES: bool>(&mut self) -> f64 {
        let [nx, ny, nz] = self.grid.n;
        let slab = nx * ny;
        let neumann = self.config.boundary == BoundaryCondition::Neumann;
        let (a, b) = self.phi.split_at_mut(1);
        let (src_phi, dst) = if self.cur == 0 {
            (&a[0], &mut b[0])
        } else {
            (&b[0], &mut a[0])
        };
        let f = Fields {
            phi: src_phi,
            beta: &self.beta,
            absorb: &self.absorb,
            src: &self.src,
            rloc: &self.rloc,
            r: self.r,
        };
        let w = self.window;
        let partial: Vec<f64> = dst
            .par_chunks_mut(slab)
            .enumerate()
            .map(|(k, out)| {
                if !neumann && (k == 0 || k + 1 == nz) {
                    return 0.0;
                }
                let km = if k == 0 { 0 } else { k - 1 };
                let kp = (k + 1).min(nz - 1);
                let mut acc = 0.0;
                let mut scratch = if RES { vec![T::zero(); nx] } else { Vec::new() };
                let (j0, j1) = if neumann { (0, ny) } else { (1, ny - 1) };
                for j in j0..j1 {
                    let jm = if j == 0 { 0 } else { j - 1 };
                    let jp = (j + 1).min(ny - 1);
                    let rows = [
                        (k * ny + j) * nx,
                        (k * ny + jm) * nx,
                        (k * ny + jp) * nx,
                        (km * ny + j) * nx,
                        (kp * ny + j) * nx,
                    ];
                    let counted = if RES && w.counts_row(j, k) {
                        w.lo..w.hi[0] + 1
                    } else {
                        0..0
                    };
                    acc += row::<T, OP, LOCAL, RES>(
                        &mut out[j * nx..(j + 1) * nx],
                        &f,
                        rows,
                        nx,
                        neumann,
                        counted,
                        &mut scratch,
                    );
                }
                acc
            })
            .collect();
        // Summed in slab order so the result does not depend on the thread count.
        partial.iter().sum()
    }
}

/// The read-only fields of a step.
struct Fields<'a, T> {
    phi: &'a [T],
    beta: &'a [T],
    absorb: &'a [T],
    src: &'a [T],
    rloc: &'a [T],
    r: T,
}

/// The bracket B_p = s − aφ_p + L(φ)_p of one voxel, with the six neighbours in the order
/// x−, x+, y−, y+, z−, z+ (module docs of [`super`] for the three operators).
#[inline(always)]
pub(crate) fn bracket<T: Real, const OP: u8>(p: T, bp: T, n: [T; 6], bn: [T; 6], a: T, s: T) -> T {
    let sum = n[0] + n[1] + n[2] + n[3] + n[4] + n[5];
    let lap = sum - T::c(6.0) * p;
    if OP == 0 {
        // Σ_s (β_p + β_s)/2 (φ_s − φ_p) = ½[β_p(Σφ_s − 6φ_p) + Σ β_s φ_s − φ_p Σ β_s].
        let bsum = bn[0] + bn[1] + bn[2] + bn[3] + bn[4] + bn[5];
        let bphi =
            bn[0] * n[0] + bn[1] * n[1] + bn[2] * n[2] + bn[3] * n[3] + bn[4] * n[4] + bn[5] * n[5];
        s - a * p + T::c(0.5) * (bp * lap + bphi - p * bsum)
    } else {
        // Thesis Eq 4.8: β_p Σ(φ_s − φ_p) ± ¼ Σ_axes (β₊ − β₋)(φ₊ − φ₋).
        let grad = (bn[1] - bn[0]) * (n[1] - n[0])
            + (bn[3] - bn[2]) * (n[3] - n[2])
            + (bn[5] - bn[4]) * (n[5] - n[4]);
        let g = T::c(0.25) * grad;
        let g = if OP == 1 { g } else { -g };
        s - a * p + bp * lap + g
    }
}

/// Updates one row (rows = [centre, y−, y+, z−, z+] start offsets); returns Σ R² over
/// `counted`.
#[inline(always)]
fn row<T: Real, const OP: u8, const LOCAL: bool, const RES: bool>(
    out: &mut [T],
    f: &Fields<'_, T>,
    rows: [usize; 5],
    nx: usize,
    neumann: bool,
    counted: std::ops::Range<usize>,
    scratch: &mut [T],
) -> f64 {
    let [c, ym, yp, zm, zp] = rows;
    let phi = f.phi;
    let beta = f.beta;
    let voxel = |i: usize, xm: usize, xp: usize| -> (T, T) {
        let p = phi[c + i];
        let n = [
            phi[c + xm],
            phi[c + xp],
            phi[ym + i],
            phi[yp + i],
            phi[zm + i],
            phi[zp + i],
        ];
        let bn = [
            beta[c + xm],
            beta[c + xp],
            beta[ym + i],
            beta[yp + i],
            beta[zm + i],
            beta[zp + i],
        ];
        let b = bracket::<T, OP>(p, beta[c + i], n, bn, f.absorb[c + i], f.src[c + i]);
        let r = if LOCAL { f.rloc[c + i] } else { f.r };
        (p + r * b, b)
    };
    let mut acc = 0.0f64;
    let mut count = |i: usize, b: T| {
        if RES && counted.contains(&i) {
            let v = b.f();
            acc += v * v;
        }
    };
    if neumann {
        let (v, b) = voxel(0, 0, 1);
        out[0] = v;
        count(0, b);
        let (v, b) = voxel(nx - 1, nx - 2, nx - 1);
        out[nx - 1] = v;
        count(nx - 1, b);
    }
    // Interior of the row, cut to equal-length slices so the loop vectorises.
    let len = nx - 2;
    fn cut<T>(f: &[T], start: usize, len: usize) -> &[T] {
        &f[start..start + len]
    }
    let cut = |f, start| cut(f, start, len);
    let (p, pxm, pxp, pym, pyp, pzm, pzp) = (
        cut(phi, c + 1),
        cut(phi, c),
        cut(phi, c + 2),
        cut(phi, ym + 1),
        cut(phi, yp + 1),
        cut(phi, zm + 1),
        cut(phi, zp + 1),
    );
    let (bp, bxm, bxp, bym, byp, bzm, bzp) = (
        cut(beta, c + 1),
        cut(beta, c),
        cut(beta, c + 2),
        cut(beta, ym + 1),
        cut(beta, yp + 1),
        cut(beta, zm + 1),
        cut(beta, zp + 1),
    );
    let (ab, sr) = (cut(f.absorb, c + 1), cut(f.src, c + 1));
    let rl = if LOCAL { cut(f.rloc, c + 1) } else { &[][..] };
    let o = &mut out[1..1 + len];
    let (c_lo, c_hi) = (
        counted.start.saturating_sub(1).min(len),
        counted.end.saturating_sub(1).min(len),
    );
    let scratch: &mut [T] = if RES { &mut scratch[..len] } else { &mut [] };
    for q in 0..len {
        let b = bracket::<T, OP>(
            p[q],
            bp[q],
            [pxm[q], pxp[q], pym[q], pyp[q], pzm[q], pzp[q]],
            [bxm[q], bxp[q], bym[q], byp[q], bzm[q], bzp[q]],
            ab[q],
            sr[q],
        );
        let r = if LOCAL { rl[q] } else { f.r };
        o[q] = p[q] + r * b;
        if RES {
            scratch[q] = b;
        }
    }
    if RES && c_hi > c_lo {
        // Eight partial sums in a fixed order: deterministic for any thread count, and the
        // loop above stays vectorisable.
        let mut lanes = [T::zero(); 8];
        let chunks = scratch[c_lo..c_hi].chunks_exact(8);
        let tail = chunks.remainder();
        for c in chunks {
            for (l, &v) in lanes.iter_mut().zip(c) {
                *l = *l + v * v;
            }
        }
        acc += lanes.iter().map(|x| x.f()).sum::<f64>()
            + tail.iter().map(|x| x.f() * x.f()).sum::<f64>();
    }
    acc
}

#[cfg(test)]
pub(crate) mod naive {
    //! The FTCS update written as plainly as possible (natural layout, one voxel at a time,
    //! `f64`), for the kernel tests.
    use super::super::{BoundaryCondition, Coefficients, Operator};

    /// One step of φ ← φ + r_p B(φ) with the bracket in grid units (s = ∆q).
    pub fn step(
        coef: &Coefficients,
        op: Operator,
        bc: BoundaryCondition,
        r: &dyn Fn(usize) -> f64,
        phi: &[f64],
    ) -> Vec<f64> {
        let g = coef.grid;
        let mut out = phi.to_vec();
        for idx in 0..g.len() {
            if !coef.is_updated(bc, idx) {
                continue;
            }
            let p = g.coords(idx);
            let nb = |axis: usize, dir: i64| {
                let mut q = p;
                q[axis] = (p[axis] as i64 + dir).clamp(0, g.n[axis] as i64 - 1) as usize;
                g.index(q[0], q[1], q[2])
            };
            let mut lap = 0.0;
            for axis in 0..3 {
                let (m, pl) = (nb(axis, -1), nb(axis, 1));
                match op {
                    Operator::Conservative => {
                        for s in [m, pl] {
                            lap += 0.5 * (coef.beta[idx] + coef.beta[s]) * (phi[s] - phi[idx]);
                        }
                    }
                    _ => {
                        let sign = if op == Operator::ThesisExpanded {
                            1.0
                        } else {
                            -1.0
                        };
                        lap += coef.beta[idx] * (phi[m] + phi[pl] - 2.0 * phi[idx])
                            + sign * 0.25 * (coef.beta[pl] - coef.beta[m]) * (phi[pl] - phi[m]);
                    }
                }
            }
            let b = coef.source[idx] * g.dl - coef.ka_dl[idx] * phi[idx] + lap;
            out[idx] = phi[idx] + r(idx) * b;
        }
        out
    }
}
