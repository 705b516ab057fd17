//! The CPU kernel of the lattice-Boltzmann update (LB Eq 3, Appendix B), parallel with
//! rayon, generic over `f32`/`f64`.
//!
//! ## Layout and update
//! Structure of arrays in z-slabs: the state holds, for each z, 19 planes of nx·ny values
//! (direction i of site (x, y, z) at `((z·19 + i)·ny + y)·nx + x`), so one rayon task owns
//! one contiguous slab of every direction. Two such buffers ping-pong. The stored values are
//! the *post-collision* densities; one step pulls, for every site r and direction i, the
//! value of direction i at r − cᵢ (the boundary inflow if that is outside the grid),
//! collides (LB Eqs 4–6) and writes the 19 results: 19 values read and 19 written per site,
//! streaming fused with collision, plus σs and σa (and the emission, if any) per site.
//!
//! Per row (y, z) the interior sites x ∈ [1, nx − 2] read the 19 upstream rows directly
//! (shifted by −cᵢx; a row of inflow values where the upstream row lies outside the grid), so
//! the collision runs branch-free as whole-row passes over equal-length slices, which the
//! compiler vectorises; the two end sites of the row are gathered one by one. Totals are summed per slab and then in slab order: results are
//! bit-identical for any thread count.

use super::{
    Absorption, C, Injection, LbmConfig, LbmSolution, LbmTrace, Q, Scattering, StepRecord, W, speed,
};
use crate::gpu::Timer;
use crate::method::Stop as Status;
use crate::{Grid, Medium, Real, SolverError};
use rayon::prelude::*;
use std::time::Instant;

/// Everything a step needs besides the state: the packed medium and the constants.
#[derive(Debug, Clone)]
pub(super) struct Setup<T> {
    pub(super) grid: Grid,
    /// Per-step σs per site (natural layout).
    pub(super) ss: Vec<T>,
    /// Per-step σa per site (natural layout).
    pub(super) sa: Vec<T>,
    /// Emission j Δl³ per site and step, if any site emits.
    pub(super) src: Option<Vec<T>>,
    /// Inflow per direction, per boundary site and step (`Injection::inflow`).
    pub(super) inflow: [T; Q],
    /// Direction i's inflow repeated over a row (nx values per direction).
    inflow_rows: Vec<T>,
    /// Sᵢⱼ of the anisotropic kernel; `None` for isotropic scattering.
    pub(super) scatter: Option<Box<[[T; Q]; Q]>>,
    /// The kernel in f64 (GPU upload, docs).
    pub(super) scatter64: Scattering,
    /// Column 0 of Θ re-emits (LB Eqs 5–6) or not ([`Absorption::Loss`]).
    pub(super) reemit: bool,
    /// Density injected per step: boundary inflow plus emission.
    pub(super) injected: f64,
    pub(super) clamped: usize,
    pub(super) tolerance: f64,
    pub(super) max_steps: usize,
    pub(super) setup_seconds: f64,
}

/// Checks the medium, the injection and the configuration (both kernels call this before
/// anything else, the GPU one before its device-limit checks).
pub(super) fn validate(
    medium: &Medium<f64>,
    injection: &Injection,
    config: &LbmConfig,
) -> Result<(), SolverError> {
    medium.validate()?;
    config.validate()?;
    injection.validate()
}

impl<T: Real> Setup<T> {
    /// The host-side setup of validated inputs (see [`validate`]).
    pub(super) fn new(
        medium: &Medium<f64>,
        injection: &Injection,
        config: &LbmConfig,
    ) -> Result<Self, SolverError> {
        let t0 = Instant::now();
        let grid = medium.grid;
        let n = grid.len();
        let (mut ss, mut sa) = (Vec::with_capacity(n), Vec::with_capacity(n));
        let mut clamped = 0;
        for (&st, &al) in medium.sigma_t.iter().zip(&medium.albedo) {
            let (s, c) = config.sigma_mapping.lattice_sigma(st, grid.dl);
            clamped += usize::from(c);
            ss.push(T::c(al * s));
            sa.push(T::c((1.0 - al) * s));
        }
        let volume = grid.dl.powi(3);
        let src = medium
            .emission
            .iter()
            .any(|&j| j > 0.0)
            .then(|| medium.emission.iter().map(|&j| T::c(j * volume)).collect());
        let emitted: f64 = medium.emission.iter().map(|&j| j * volume).sum();
        let inflow64 = injection.inflow(grid.dl);
        let [nx, ny, nz] = grid.n;
        let mut injected = emitted;
        for (i, f) in inflow64.iter().enumerate().skip(1) {
            let c = C[i];
            let inner = (nx - c[0].unsigned_abs() as usize)
                * (ny - c[1].unsigned_abs() as usize)
                * (nz - c[2].unsigned_abs() as usize);
            // Sum of the values as the kernel stores them.
            injected += T::c(*f).f() * (n - inner) as f64;
        }
        let scatter64 = Scattering::new(config.phase, config.hg)?;
        let scatter = (!scatter64.isotropic).then(|| {
            let mut s = Box::new([[T::zero(); Q]; Q]);
            for (row, r64) in s.iter_mut().zip(&scatter64.s) {
                for (v, x) in row.iter_mut().zip(r64) {
                    *v = T::c(*x);
                }
            }
            s
        });
        Ok(Self {
            grid,
            ss,
            sa,
            src,
            inflow: inflow64.map(T::c),
            inflow_rows: (0..Q)
                .flat_map(|i| std::iter::repeat_n(T::c(inflow64[i]), nx))
                .collect(),
            scatter,
            scatter64,
            reemit: config.absorption == Absorption::PaperDelay,
            injected,
            clamped,
            tolerance: config.tolerance_for::<T>(),
            max_steps: config.max_steps,
            setup_seconds: t0.elapsed().as_secs_f64(),
        })
    }

    /// Values per z-slab of the state.
    fn slab(&self) -> usize {
        Q * self.grid.n[0] * self.grid.n[1]
    }

    /// The 19 upstream rows of row (y, z): direction i's row at (y − cᵢy, z − cᵢz), or a row
    /// of its inflow value where that lies outside the grid.
    fn upstream<'s>(&'s self, state: &'s [T], y: usize, z: usize) -> [&'s [T]; Q] {
        let [nx, ny, nz] = self.grid.n;
        std::array::from_fn(|i| {
            let c = C[i];
            let ys = y as isize - c[1] as isize;
            let zs = z as isize - c[2] as isize;
            if ys < 0 || zs < 0 || ys >= ny as isize || zs >= nz as isize {
                &self.inflow_rows[i * nx..(i + 1) * nx]
            } else {
                let start = ((zs as usize * Q + i) * ny + ys as usize) * nx;
                &state[start..start + nx]
            }
        })
    }

    /// Density arriving at site x of a row from upstream rows `rows` in direction i.
    fn arriving(&self, rows: &[&[T]; Q], i: usize, x: usize) -> T {
        let sx = x as isize - C[i][0] as isize;
        if sx < 0 || sx >= self.grid.n[0] as isize {
            self.inflow[i]
        } else {
            rows[i][sx as usize]
        }
    }

    /// Collides row (y, z) into `outs` (19 rows of nx): the interior x ∈ [1, nx − 2] straight
    /// from the upstream rows (shifted by −cᵢx), the two end sites from gathered values.
    /// Returns (total density arriving, density absorbed and removed).
    fn row(
        &self,
        state: &[T],
        y: usize,
        z: usize,
        outs: &mut [&mut [T]],
        scratch: &mut [T],
    ) -> (f64, f64) {
        let nx = self.grid.n[0];
        let base = (z * self.grid.n[1] + y) * nx;
        let rows = self.upstream(state, y, z);
        let run =
            |ins: &[&[T]; Q], lo: usize, hi: usize, outs: &mut [&mut [T]], scratch: &mut [T]| {
                let mut o: Vec<&mut [T]> = outs.iter_mut().map(|r| &mut r[lo..hi]).collect();
                let (ss, sa) = (
                    &self.ss[base + lo..base + hi],
                    &self.sa[base + lo..base + hi],
                );
                let src = self.src.as_ref().map(|s| &s[base + lo..base + hi]);
                match &self.scatter {
                    None => {
                        collide::<T, true>(ins, ss, sa, src, self.reemit, None, &mut o, scratch)
                    }
                    Some(s) => {
                        collide::<T, false>(ins, ss, sa, src, self.reemit, Some(s), &mut o, scratch)
                    }
                }
            };
        let (mut total, mut absorbed) = (0.0, 0.0);
        if nx > 2 {
            let ins: [&[T]; Q] = std::array::from_fn(|i| {
                let off = (1 - C[i][0]) as usize;
                &rows[i][off..off + nx - 2]
            });
            let (t, a) = run(&ins, 1, nx - 1, outs, scratch);
            total += t;
            absorbed += a;
        }
        for x in [0, nx - 1] {
            let vals: [T; Q] = std::array::from_fn(|i| self.arriving(&rows, i, x));
            let ins: [&[T]; Q] = std::array::from_fn(|i| std::slice::from_ref(&vals[i]));
            let (t, a) = run(&ins, x, x + 1, outs, scratch);
            total += t;
            absorbed += a;
        }
        (total, absorbed)
    }

    /// One step of z-slab `z`: reads `state`, writes the slab `out`; returns (total, outflow,
    /// absorbed) of the slab.
    fn step_slab(&self, state: &[T], z: usize, out: &mut [T], scratch: &mut [T]) -> [f64; 3] {
        let [nx, ny, nz] = self.grid.n;
        let mut planes: Vec<&mut [T]> = out.chunks_mut(nx * ny).collect();
        let (mut total, mut outflow, mut absorbed) = (0.0, 0.0, 0.0);
        for y in 0..ny {
            let mut outs: Vec<&mut [T]> = planes
                .iter_mut()
                .map(|p| &mut p[y * nx..(y + 1) * nx])
                .collect();
            let (t, a) = self.row(state, y, z, &mut outs, scratch);
            total += t;
            absorbed += a;
            // Sink: post-collision density whose downstream site is outside the grid.
            for (i, c) in C.iter().enumerate().skip(1) {
                let yd = y as isize + c[1] as isize;
                let zd = z as isize + c[2] as isize;
                let row = &outs[i];
                if yd < 0 || zd < 0 || yd >= ny as isize || zd >= nz as isize {
                    outflow += lane_sum(row);
                } else if c[0] == 1 {
                    outflow += row[nx - 1].f();
                } else if c[0] == -1 {
                    outflow += row[0].f();
                }
            }
        }
        [total, outflow, absorbed]
    }

    /// φ (physical) and ρ (lattice) of the next step's arriving densities, natural layout.
    pub(super) fn fields(&self, state: &[T]) -> (Vec<T>, Vec<T>) {
        let [nx, ny, _] = self.grid.n;
        let dl2 = self.grid.dl * self.grid.dl;
        let weights: [T; Q] = std::array::from_fn(|i| T::c(speed(i) / (2.0 * dl2)));
        let mut phi = vec![T::zero(); self.grid.len()];
        let mut rho = vec![T::zero(); self.grid.len()];
        phi.par_chunks_mut(nx * ny)
            .zip(rho.par_chunks_mut(nx * ny))
            .enumerate()
            .for_each(|(z, (phi, rho))| {
                let mut scratch = vec![T::zero(); 4 * nx];
                let mut tmp = vec![T::zero(); Q * nx];
                for y in 0..ny {
                    let mut outs: Vec<&mut [T]> = tmp.chunks_mut(nx).collect();
                    self.row(state, y, z, &mut outs, &mut scratch);
                    let rows = self.upstream(state, y, z);
                    for x in 0..nx {
                        let (mut p, mut r) = (T::zero(), T::zero());
                        for i in 0..Q {
                            let inv = self.arriving(&rows, i, x);
                            p = p + weights[i] * (inv + outs[i][x]);
                            if i > 0 || self.reemit {
                                r = r + inv;
                            }
                        }
                        phi[y * nx + x] = p;
                        rho[y * nx + x] = r;
                    }
                }
            });
        (phi, rho)
    }
}

/// Σ of a row in a fixed order (eight interleaved partial sums: deterministic and
/// vectorisable), widened to f64.
fn lane_sum<T: Real>(v: &[T]) -> f64 {
    let mut lanes = [T::zero(); 8];
    let chunks = v.chunks_exact(8);
    let tail = chunks.remainder();
    for c in chunks {
        for (l, &x) in lanes.iter_mut().zip(c) {
            *l = *l + x;
        }
    }
    lanes.iter().chain(tail).fold(T::zero(), |a, &b| a + b).f()
}

/// The collision of LB Eqs 4–6 over one row, as whole-row passes over equal-length slices
/// (each a simple zip the compiler vectorises). `scratch` holds at least 4 rows.
/// `ISO`: Sᵢⱼ = wᵢ (no matrix product). Returns (Σ arriving density, Σ removed absorption).
#[allow(clippy::too_many_arguments)]
fn collide<T: Real, const ISO: bool>(
    ins: &[&[T]; Q],
    ss: &[T],
    sa: &[T],
    src: Option<&[T]>,
    reemit: bool,
    scatter: Option<&[[T; Q]; Q]>,
    outs: &mut [&mut [T]],
    scratch: &mut [T],
) -> (f64, f64) {
    let n = ss.len();
    let (m, rest) = scratch.split_at_mut(n);
    let (keep, rest) = rest.split_at_mut(n);
    let (iso, rest) = rest.split_at_mut(n);
    let acc = &mut rest[..n];
    let sa = &sa[..n];
    // m = Σⱼ₌₁¹⁸ inⱼ, in direction order (the GPU's order).
    m.copy_from_slice(&ins[1][..n]);
    for inp in &ins[2..] {
        for (mq, &v) in m.iter_mut().zip(&inp[..n]) {
            *mq = *mq + v;
        }
    }
    let rest_in = &ins[0][..n];
    let mut total = lane_sum(m);
    if reemit {
        total += lane_sum(rest_in);
    }
    for (((k, i), (&s, &a)), (&mq, &r)) in keep
        .iter_mut()
        .zip(iso.iter_mut())
        .zip(ss.iter().zip(sa))
        .zip(m.iter().zip(rest_in))
    {
        *k = T::one() - s - a;
        let r = if reemit { r } else { T::zero() };
        // Re-emission (column 0) and emission share the isotropic weights.
        *i = if ISO { s * mq + r } else { r };
    }
    if let Some(e) = src {
        for (i, &e) in iso.iter_mut().zip(&e[..n]) {
            *i = *i + e;
        }
    }
    for ((o, &a), &mq) in outs[0][..n].iter_mut().zip(sa).zip(m.iter()) {
        *o = a * mq;
    }
    let absorbed = if reemit { 0.0 } else { lane_sum(&outs[0][..n]) };
    for i in 1..Q {
        let wi = T::c(W[i]);
        let fi = &ins[i][..n];
        let out = &mut outs[i][..n];
        if ISO {
            for ((o, &f), (&k, &e)) in out.iter_mut().zip(fi).zip(keep.iter().zip(iso.iter())) {
                *o = k * f + wi * e;
            }
        } else if let Some(s) = scatter {
            acc.fill(T::zero());
            for (j, inp) in ins.iter().enumerate().skip(1) {
                let sij = s[i][j];
                for (a, &v) in acc.iter_mut().zip(&inp[..n]) {
                    *a = *a + sij * v;
                }
            }
            for (((o, &f), (&k, &e)), (&a, &sv)) in out
                .iter_mut()
                .zip(fi)
                .zip(keep.iter().zip(iso.iter()))
                .zip(acc.iter().zip(ss))
            {
                *o = k * f + sv * a + wi * e;
            }
        }
    }
    (total, absorbed)
}

/// The state of one lattice-Boltzmann solve on the CPU.
///
/// Build with [`CpuLbm::new`], then [`CpuLbm::solve`] to the steady state or
/// [`CpuLbm::step`] one step at a time (benchmarks, experiments).
#[derive(Debug, Clone)]
pub struct CpuLbm<T> {
    setup: Setup<T>,
    state: Vec<T>,
    next: Vec<T>,
    steps: usize,
    history: Vec<StepRecord>,
}

impl<T: Real> CpuLbm<T> {
    /// Validates the inputs, maps σ to lattice units (see [`super`]) and starts from an empty
    /// lattice (the paper's random initial values only change the transient).
    pub fn new(
        medium: &Medium<f64>,
        injection: &Injection,
        config: &LbmConfig,
    ) -> Result<Self, SolverError> {
        validate(medium, injection, config)?;
        let setup = Setup::new(medium, injection, config)?;
        let len = Q * setup.grid.len();
        Ok(Self {
            setup,
            state: vec![T::zero(); len],
            next: vec![T::zero(); len],
            steps: 0,
            history: Vec::new(),
        })
    }

    /// The grid.
    pub fn grid(&self) -> &Grid {
        &self.setup.grid
    }

    /// Density injected per step (boundary inflow plus emission).
    pub fn injected_per_step(&self) -> f64 {
        self.setup.injected
    }

    /// Steps run so far.
    pub fn steps(&self) -> usize {
        self.steps
    }

    /// Totals of every step so far.
    pub fn history(&self) -> &[StepRecord] {
        &self.history
    }

    /// Bytes one step moves at least: 19 values read and 19 written per site (the σs, σa
    /// reads, 2 more values per site, are not counted; see the benchmark).
    pub fn bytes_per_step(&self) -> usize {
        2 * Q * self.setup.grid.len() * std::mem::size_of::<T>()
    }

    /// Runs one step and returns its totals.
    pub fn step(&mut self) -> StepRecord {
        let slab = self.setup.slab();
        let nx = self.setup.grid.n[0];
        let (setup, state) = (&self.setup, &self.state);
        let parts: Vec<[f64; 3]> = self
            .next
            .par_chunks_mut(slab)
            .enumerate()
            .map_init(
                || vec![T::zero(); 4 * nx],
                |scratch, (z, out)| setup.step_slab(state, z, out, scratch),
            )
            .collect();
        std::mem::swap(&mut self.state, &mut self.next);
        let sum = parts
            .iter()
            .fold([0.0; 3], |a, p| [a[0] + p[0], a[1] + p[1], a[2] + p[2]]);
        self.steps += 1;
        let rec = StepRecord {
            step: self.steps,
            total_density: sum[0],
            injected: self.setup.injected,
            outflow: sum[1],
            absorbed: sum[2],
        };
        self.history.push(rec);
        rec
    }

    /// Steps to the steady state or the cap.
    pub fn solve(self) -> LbmSolution<T> {
        self.solve_observed(|_, _| {})
    }

    /// As [`CpuLbm::solve`], calling `observer(step, total_density)` after every step.
    pub fn solve_observed(mut self, mut observer: impl FnMut(usize, f64)) -> LbmSolution<T> {
        let t0 = Instant::now();
        let tol = self.setup.tolerance;
        let mut status = Status::Cap;
        let mut prev = f64::NAN;
        while self.steps < self.setup.max_steps {
            let rec = self.step();
            observer(rec.step, rec.total_density);
            let t = rec.total_density;
            if !t.is_finite() {
                status = Status::NonFinite;
                break;
            }
            if steady(prev, t, 1, tol) {
                status = Status::Converged;
                break;
            }
            prev = t;
        }
        let seconds = t0.elapsed().as_secs_f64();
        let (phi, rho) = self.setup.fields(&self.state);
        let trace = LbmTrace {
            rho,
            history: self.history,
            clamped_sites: self.setup.clamped,
        };
        super::solution(
            self.setup.grid,
            phi,
            trace,
            self.steps,
            status,
            seconds,
            self.setup.setup_seconds,
            Timer::WallClock,
        )
    }

    /// φ (physical units) and ρ (lattice units) of the current state, natural layout.
    pub fn fields(&self) -> (Vec<T>, Vec<T>) {
        self.setup.fields(&self.state)
    }

    /// The raw state (post-collision densities, z-slab layout of the module docs).
    pub fn state(&self) -> &[T] {
        &self.state
    }
}

/// Whether totals `prev` → `now` over `steps` steps changed by less than `tol` relative per
/// step. An empty lattice that stays empty is steady.
pub(super) fn steady(prev: f64, now: f64, steps: usize, tol: f64) -> bool {
    if !prev.is_finite() {
        return false;
    }
    if now == 0.0 && prev == 0.0 {
        return true;
    }
    (now - prev).abs() < tol * now.abs() * steps as f64
}
