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
//! Per row (y, z) the 19 source rows are copied into a padded scratch (inflow values at both
//! ends, or a whole row of inflow where the upstream row lies outside), so the collision loop
//! runs branch-free over chunks of [`CHUNK`] sites held in fixed-size arrays, which the
//! compiler vectorises. Totals are summed per slab and then in slab order: results are
//! bit-identical for any thread count.

use super::{
    Absorption, C, Injection, LbmConfig, LbmSolution, Q, Scattering, Status, StepRecord, W, speed,
};
use crate::gpu::Timer;
use crate::{Grid, Medium, Real, SolverError};
use rayon::prelude::*;
use std::time::Instant;

/// Sites per inner chunk (fixed-size arrays the compiler keeps in vector registers).
const CHUNK: usize = 16;

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

impl<T: Real> Setup<T> {
    pub(super) fn new(
        medium: &Medium<f64>,
        injection: &Injection,
        config: &LbmConfig,
    ) -> Result<Self, SolverError> {
        let t0 = Instant::now();
        medium.validate()?;
        config.validate()?;
        injection.validate()?;
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

    /// Copies the 19 upstream rows of row (y, z) into `pad` (rows of nx + 2, inflow at both
    /// ends or throughout where the upstream row is outside the grid).
    fn pull_rows(&self, state: &[T], y: usize, z: usize, pad: &mut [T]) {
        let [nx, ny, nz] = self.grid.n;
        let w = nx + 2;
        for (i, c) in C.iter().enumerate() {
            let row = &mut pad[i * w..(i + 1) * w];
            let ys = y as isize - c[1] as isize;
            let zs = z as isize - c[2] as isize;
            if ys < 0 || zs < 0 || ys >= ny as isize || zs >= nz as isize {
                row.fill(self.inflow[i]);
            } else {
                let start = ((zs as usize * Q + i) * ny + ys as usize) * nx;
                row[1..nx + 1].copy_from_slice(&state[start..start + nx]);
                row[0] = self.inflow[i];
                row[nx + 1] = self.inflow[i];
            }
        }
    }

    /// Collides one row: `pad` from [`Setup::pull_rows`], results into `outs` (19 rows).
    /// Returns (total density arriving, density absorbed and removed).
    fn collide_row(&self, pad: &[T], y: usize, z: usize, outs: &mut [&mut [T]]) -> (f64, f64) {
        let nx = self.grid.n[0];
        let w = nx + 2;
        let base = (z * self.grid.n[1] + y) * nx;
        let ins: Vec<&[T]> = (0..Q)
            .map(|i| {
                let s = (i * w) as isize + 1 - C[i][0] as isize;
                &pad[s as usize..s as usize + nx]
            })
            .collect();
        let ss = &self.ss[base..base + nx];
        let sa = &self.sa[base..base + nx];
        let src = self.src.as_ref().map(|s| &s[base..base + nx]);
        match &self.scatter {
            None => collide::<T, true>(&ins, ss, sa, src, self.reemit, None, outs),
            Some(s) => collide::<T, false>(&ins, ss, sa, src, self.reemit, Some(s), outs),
        }
    }

    /// One step of z-slab `z`: reads `state`, writes the slab `out`; returns (total, outflow,
    /// absorbed) of the slab.
    fn step_slab(&self, state: &[T], z: usize, out: &mut [T], pad: &mut [T]) -> [f64; 3] {
        let [nx, ny, nz] = self.grid.n;
        let mut planes: Vec<&mut [T]> = out.chunks_mut(nx * ny).collect();
        let (mut total, mut outflow, mut absorbed) = (0.0, 0.0, 0.0);
        for y in 0..ny {
            self.pull_rows(state, y, z, pad);
            let mut outs: Vec<&mut [T]> = planes
                .iter_mut()
                .map(|p| &mut p[y * nx..(y + 1) * nx])
                .collect();
            let (t, a) = self.collide_row(pad, y, z, &mut outs);
            total += t;
            absorbed += a;
            // Sink: post-collision density whose downstream site is outside the grid.
            for (i, c) in C.iter().enumerate().skip(1) {
                let yd = y as isize + c[1] as isize;
                let zd = z as isize + c[2] as isize;
                let row = &outs[i];
                if yd < 0 || zd < 0 || yd >= ny as isize || zd >= nz as isize {
                    outflow += row.iter().fold(T::zero(), |a, &b| a + b).f();
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
                let mut pad = vec![T::zero(); Q * (nx + 2)];
                let mut tmp = vec![T::zero(); Q * nx];
                for y in 0..ny {
                    self.pull_rows(state, y, z, &mut pad);
                    let mut outs: Vec<&mut [T]> = tmp.chunks_mut(nx).collect();
                    self.collide_row(&pad, y, z, &mut outs);
                    for x in 0..nx {
                        let (mut p, mut r) = (T::zero(), T::zero());
                        for i in 0..Q {
                            let inv =
                                pad[i * (nx + 2) + (x as isize + 1 - C[i][0] as isize) as usize];
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

/// The collision of LB Eqs 4–6 over one row, in chunks of [`CHUNK`] sites.
/// `ISO`: Sᵢⱼ = wᵢ (no matrix product). Returns (Σ arriving density, Σ removed absorption).
#[allow(clippy::too_many_arguments)]
fn collide<T: Real, const ISO: bool>(
    ins: &[&[T]],
    ss: &[T],
    sa: &[T],
    src: Option<&[T]>,
    reemit: bool,
    scatter: Option<&[[T; Q]; Q]>,
    outs: &mut [&mut [T]],
) -> (f64, f64) {
    let n = ss.len();
    let w: [T; Q] = std::array::from_fn(|i| T::c(W[i]));
    let (w_ax, w_dg) = (w[1], w[7]);
    let rest_on = if reemit { T::one() } else { T::zero() };
    let (mut total, mut absorbed) = (0.0, 0.0);
    let mut x0 = 0;
    while x0 < n {
        let len = (n - x0).min(CHUNK);
        let mut f = [[T::zero(); CHUNK]; Q];
        for (fi, inp) in f.iter_mut().zip(ins) {
            fi[..len].copy_from_slice(&inp[x0..x0 + len]);
        }
        let (mut s_s, mut s_a, mut e) =
            ([T::zero(); CHUNK], [T::zero(); CHUNK], [T::zero(); CHUNK]);
        s_s[..len].copy_from_slice(&ss[x0..x0 + len]);
        s_a[..len].copy_from_slice(&sa[x0..x0 + len]);
        if let Some(src) = src {
            e[..len].copy_from_slice(&src[x0..x0 + len]);
        }
        let mut m = [T::zero(); CHUNK];
        for fi in &f[1..] {
            for q in 0..CHUNK {
                m[q] = m[q] + fi[q];
            }
        }
        let mut o = [[T::zero(); CHUNK]; Q];
        let mut keep = [T::zero(); CHUNK];
        let mut iso = [T::zero(); CHUNK];
        let mut tot = [T::zero(); CHUNK];
        for q in 0..CHUNK {
            keep[q] = T::one() - s_s[q] - s_a[q];
            o[0][q] = s_a[q] * m[q];
            let rest = rest_on * f[0][q];
            tot[q] = m[q] + rest;
            // Re-emission (column 0) and emission share the isotropic weights.
            iso[q] = if ISO {
                s_s[q] * m[q] + rest + e[q]
            } else {
                rest + e[q]
            };
        }
        if ISO {
            for i in 1..Q {
                let wi = if i <= 6 { w_ax } else { w_dg };
                let (fi, oi) = (&f[i], &mut o[i]);
                for q in 0..CHUNK {
                    oi[q] = keep[q] * fi[q] + wi * iso[q];
                }
            }
        } else if let Some(s) = scatter {
            for i in 1..Q {
                let mut acc = [T::zero(); CHUNK];
                for j in 1..Q {
                    let sij = s[i][j];
                    let fj = &f[j];
                    for q in 0..CHUNK {
                        acc[q] = acc[q] + sij * fj[q];
                    }
                }
                let wi = w[i];
                let (fi, oi) = (&f[i], &mut o[i]);
                for q in 0..CHUNK {
                    oi[q] = keep[q] * fi[q] + s_s[q] * acc[q] + wi * iso[q];
                }
            }
        }
        for (oi, out) in o.iter().zip(outs.iter_mut()) {
            out[x0..x0 + len].copy_from_slice(&oi[..len]);
        }
        total += tot[..len].iter().fold(T::zero(), |a, &b| a + b).f();
        if !reemit {
            absorbed += o[0][..len].iter().fold(T::zero(), |a, &b| a + b).f();
        }
        x0 += len;
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
                || vec![T::zero(); Q * (nx + 2)],
                |pad, (z, out)| setup.step_slab(state, z, out, pad),
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
        let mut status = Status::MaxSteps;
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
                status = Status::Steady;
                break;
            }
            prev = t;
        }
        let seconds = t0.elapsed().as_secs_f64();
        let (phi, rho) = self.setup.fields(&self.state);
        LbmSolution {
            grid: self.setup.grid,
            phi,
            rho,
            steps: self.steps,
            history: self.history,
            status,
            clamped_sites: self.setup.clamped,
            seconds,
            setup_seconds: self.setup.setup_seconds,
            timer: Timer::WallClock,
        }
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
