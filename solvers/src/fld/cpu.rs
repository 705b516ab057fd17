//! The CPU kernel of FLD Algorithm 1: red-black Gauss-Seidel with SOR, parallel with rayon,
//! generic over `f32`/`f64`.
//!
//! ## Layout
//! Fields are stored as two packed checkerboards: colour `c` (0 = red, i + j + k even;
//! 1 = black) keeps, per row (j, k), the voxels i = 2m + s with s = (c + j + k) mod 2 at
//! position m, in rows of h values: ⌈nx/2⌉ made odd (see `packed_row_len`). A red pass then reads and writes contiguous
//! memory of its own colour and reads the other colour's φ and D, so one iteration moves
//! each value once instead of twice as a strided update on the natural layout would. The
//! x-neighbours of voxel m of a row are entries m + s − 1 and m + s of the other colour's
//! row; its y/z-neighbours are entry m of the adjacent rows of the other colour.
//!
//! ## Order
//! On grids of four slabs or more the two colour passes are fused slab by slab
//! (`CpuFld::fused_with`): red slab k, then black slab k − 1, whose red neighbours are
//! then final and still in cache. The result is bit-identical to the red pass followed by
//! the black pass, which smaller grids (and the tests) run.
//!
//! Per voxel and pass (FLD Algorithm 1): R by Eqs 34–35, D_p by Eq 33, D_ps = (D_p + D_s)/2,
//! φ'_p by Eq 32, SOR by Eq 36, residual by Eq 37 (before the update; see [`super`]).

use super::residual::ResidualWindow;
use super::{Boundary, FldConfig, FldSolution, FluxLimiter, KnudsenSigma};
use crate::gpu::Timer;
use crate::method::Stop;
use crate::{Grid, Medium, Real, SolverError};
use rayon::prelude::*;
use std::time::Instant;

/// Per-solve constants used inside the hot loop.
#[derive(Debug, Clone, Copy)]
pub(super) struct Params<T> {
    pub(super) omega: T,
    pub(super) one_minus_omega: T,
    pub(super) inv_2dl: T,
    pub(super) inv_dl2: T,
    /// ε j̄: floor of |∇φ| and σφ in the Knudsen number (FLD Eq 35).
    pub(super) floor: T,
    /// Under-relaxation θ of the D update and 1 − θ.
    pub(super) theta: T,
    pub(super) one_minus_theta: T,
    /// Δl (the Marshak face coefficient).
    pub(super) dl: T,
}

/// The packed red-black state of one diffusion solve.
///
/// Build with [`CpuFld::new`], then either [`CpuFld::solve`] to convergence or
/// [`CpuFld::iterate`] one red-black iteration at a time (benchmarks, progress display).
#[derive(Debug, Clone)]
pub struct CpuFld<T> {
    grid: Grid,
    config: FldConfig,
    /// Packed row length ⌈nx/2⌉.
    h: usize,
    /// σ of the Knudsen number and of D = F/σ, floored at σ_ε, per colour.
    sig: [Vec<T>; 2],
    /// (1 − α) max(σt, σ_ε) Δl², the absorption term of Eq 32's denominator.
    absorb: [Vec<T>; 2],
    /// j Δl², the source term of Eq 32's numerator.
    src: [Vec<T>; 2],
    phi: [Vec<T>; 2],
    d: [Vec<T>; 2],
    /// 1 where the voxel is vacuum (σt ≤ σ_ε), else 0; read only with
    /// [`super::VacuumFace::Marshak`].
    vac: [Vec<T>; 2],
    params: Params<T>,
    tolerance: f64,
    /// j̄ (or its substitute when there is no emission, see the module docs); the solve runs
    /// on fields divided by it.
    j_ref: f64,
    /// Interior voxels counted in the RMS residual.
    residual_count: usize,
    iterations: usize,
    residuals: Vec<f64>,
    setup_seconds: f64,
    /// No source and a zero boundary: φ = 0, nothing to iterate.
    trivial: bool,
    /// The black x-end voxels' D (see [`CpuFld::x_ends_in_pass`]) were set by the last black
    /// pass from the φ this iteration starts with; cleared by anything that sets φ, D or σ.
    black_x_ends_fresh: bool,
    /// The black x-end voxels' D of the iteration that set them ahead, two slots per row
    /// (k, j) (left, right), for [`CpuFld::diffusion_coefficient`].
    black_x_ends_prev: Vec<T>,
}

impl<T: Real> CpuFld<T> {
    /// Validates the inputs and builds the packed state with the initial values of
    /// Algorithm 1: φ = ε j̄ Δl, D = ε Δl (CDA: D = 1/(3σ) right away, it never changes),
    /// boundary layer from `boundary`.
    pub fn new(
        medium: &Medium<T>,
        boundary: &Boundary<T>,
        config: &FldConfig,
    ) -> Result<Self, SolverError> {
        let t0 = Instant::now();
        medium.validate()?;
        config.validate()?;
        let grid = medium.grid;
        let [nx, ny, nz] = grid.n;
        if let Boundary::Values(v) = boundary {
            if v.len() != grid.len() {
                return Err(SolverError::FieldSize {
                    field: "boundary",
                    expected: grid.len(),
                    got: v.len(),
                });
            }
            if let Some(index) = v.iter().position(|x| !(x.f().is_finite() && x.f() >= 0.0)) {
                return Err(SolverError::FieldValue {
                    field: "boundary",
                    index,
                    value: v[index].f(),
                    range: "[0, ∞)",
                });
            }
        }
        let dl = grid.dl;
        let sigma_eps = config.sigma_eps.unwrap_or(1e-3 / grid.extent());
        let jbar = medium.rms_emission();
        let boundary_max = match boundary {
            Boundary::Zero => 0.0,
            Boundary::Values(v) => (0..grid.len())
                .filter(|&idx| {
                    let [i, j, k] = grid.coords(idx);
                    grid.is_boundary(i, j, k)
                })
                .map(|idx| v[idx].f())
                .fold(0.0, f64::max),
        };
        let j_ref = if jbar > 0.0 { jbar } else { boundary_max / dl };
        let trivial = j_ref == 0.0;
        // The solve runs on j/j_ref (see the `fld` module docs, "Normalisation"), so inside
        // it j̄ = 1 and the floors of Eq 35 are ε itself.
        let scale = if trivial { 1.0 } else { j_ref };
        let eps = config.epsilon.unwrap_or(T::DEFAULT_EPSILON);
        let floor = T::c(eps).max(T::min_positive_value());
        // No source and a zero boundary: the exact answer φ = 0 is the initial value.
        let phi0 = if trivial {
            T::zero()
        } else {
            T::c(eps * dl).max(T::min_positive_value())
        };
        let d0 = T::c(eps * dl);

        let h = packed_row_len(nx);
        let slab = ny * h;
        let plen = nz * slab;
        // Zeroed (untouched pages) here, every value written below in parallel over z-slabs
        // (the serial fill it replaces: 0.50 → 0.30 s at 255³, `multigrid/HISTORY.md`).
        let zeros = || [vec![T::zero(); plen], vec![T::zero(); plen]];
        let (mut sig, mut absorb, mut src) = (zeros(), zeros(), zeros());
        let (mut phi, mut d, mut vac) = (zeros(), zeros(), zeros());
        let cda = config.limiter.is_constant();
        let third = T::one() / T::c(3.0);
        // Per slab k: [σ, absorption, source, φ, D, vacuum] × [red, black]; field F of
        // colour c at F + c.
        const SIG: usize = 0;
        const ABSORB: usize = 2;
        const SRC: usize = 4;
        const PHI: usize = 6;
        const D: usize = 8;
        const VAC: usize = 10;
        let mut slabs: Vec<Vec<&mut [T]>> = (0..nz).map(|_| Vec::with_capacity(12)).collect();
        for field in [&mut sig, &mut absorb, &mut src, &mut phi, &mut d, &mut vac] {
            for colour in field.iter_mut() {
                for (k, chunk) in colour.chunks_mut(slab).enumerate() {
                    slabs[k].push(chunk);
                }
            }
        }
        slabs.into_par_iter().enumerate().for_each(|(k, mut f)| {
            // Defaults, also of the slots past a row's last voxel (never a voxel's value).
            for c in 0..2 {
                f[SIG + c].fill(T::one());
                f[PHI + c].fill(phi0);
                f[D + c].fill(d0);
            }
            for j in 0..ny {
                for i in 0..nx {
                    let n = grid.index(i, j, k);
                    let (c, p) = packed_index(&grid, h, i, j, k);
                    let p = p - k * slab;
                    let st = medium.sigma_t[n].f().max(sigma_eps);
                    let a = medium.albedo[n].f();
                    let ks = match config.knudsen {
                        KnudsenSigma::Extinction => st,
                        KnudsenSigma::EffectiveAlbedo => (a * medium.sigma_t[n].f()).max(sigma_eps),
                    };
                    f[SIG + c][p] = T::c(ks);
                    if medium.sigma_t[n].f() <= sigma_eps {
                        f[VAC + c][p] = T::one();
                    }
                    f[ABSORB + c][p] = T::c((1.0 - a) * st * dl * dl);
                    f[SRC + c][p] = T::c(medium.emission[n].f() / scale * dl * dl);
                    if cda {
                        f[D + c][p] = third / T::c(ks);
                    }
                    if let (Boundary::Values(v), true) = (boundary, grid.is_boundary(i, j, k)) {
                        f[PHI + c][p] = T::c(v[n].f() / scale);
                    }
                }
            }
        });
        let window = ResidualWindow::new(&grid, config.residual_margin);
        let tolerance = config.tolerance.unwrap_or(T::DEFAULT_TOLERANCE);
        let omega = T::c(config.omega);
        let mut s = Self {
            grid,
            config: config.clone(),
            h,
            sig,
            absorb,
            src,
            phi,
            d,
            vac,
            params: Params {
                omega,
                one_minus_omega: T::one() - omega,
                inv_2dl: T::c(0.5 / dl),
                inv_dl2: T::c(1.0 / (dl * dl)),
                floor,
                theta: T::c(config.d_relaxation),
                one_minus_theta: T::c(1.0 - config.d_relaxation),
                dl: T::c(dl),
            },
            tolerance,
            j_ref,
            residual_count: window.count,
            iterations: 0,
            residuals: Vec::new(),
            setup_seconds: 0.0,
            trivial,
            black_x_ends_fresh: false,
            black_x_ends_prev: vec![T::zero(); 2 * ny * nz],
        };
        s.config.residual_margin = window.margin;
        s.setup_seconds = t0.elapsed().as_secs_f64();
        Ok(s)
    }

    /// The grid.
    pub fn grid(&self) -> &Grid {
        &self.grid
    }

    /// Iterations run so far.
    pub fn iterations(&self) -> usize {
        self.iterations
    }

    /// Normalised residual R̄/j̄ after each iteration so far.
    pub fn residuals(&self) -> &[f64] {
        &self.residuals
    }

    /// The tolerance this solve stops at.
    pub fn tolerance(&self) -> f64 {
        self.tolerance
    }

    /// j̄, the RMS emission the residual is normalised by.
    pub fn j_ref(&self) -> f64 {
        self.j_ref
    }

    /// The unit of the φ the solve runs on: j̄, or 1 for the trivial problem (no source and
    /// a zero boundary), so that φ in the caller's units is the solver's φ times this.
    pub(super) fn phi_unit(&self) -> f64 {
        if self.trivial { 1.0 } else { self.j_ref }
    }

    /// The per-solve constants (shared with the GPU kernel's uniforms).
    pub(super) fn params(&self) -> Params<T> {
        self.params
    }

    /// Voxels next to the boundary layer left out of the residual (after the small-grid fallback).
    pub(super) fn residual_margin(&self) -> usize {
        self.config.residual_margin
    }

    /// Number of voxels in the RMS residual.
    pub(super) fn residual_count(&self) -> usize {
        self.residual_count
    }

    /// No source and a zero boundary: φ = 0 without iterating.
    pub(super) fn is_trivial(&self) -> bool {
        self.trivial
    }

    /// The packed initial fields φ, D, σ, absorption and source, each as (red, black), in the
    /// compact layout of the GPU kernels: rows of exactly ⌈nx/2⌉ values (this solver's rows
    /// may carry one more, [`packed_row_len`]).
    pub(super) fn packed_fields(&self) -> [[Vec<T>; 2]; 5] {
        let [nx, ny, nz] = self.grid.n;
        let hc = nx.div_ceil(2);
        let h = self.h;
        let compact = |v: &Vec<T>| -> Vec<T> {
            (0..ny * nz)
                .flat_map(|r| v[r * h..r * h + hc].iter().copied())
                .collect()
        };
        [&self.phi, &self.d, &self.sig, &self.absorb, &self.src]
            .map(|f| [compact(&f[0]), compact(&f[1])])
    }

    /// Bytes one iteration moves when the two colour passes run one after the other, counting
    /// every packed field once per pass it is read or written (medium 3 fields + own φ, D
    /// read and written + other colour φ, D read), i.e. 9 values per voxel per iteration for
    /// FLD and 7 for CDA (D is constant): the work the benches' effective bandwidth is
    /// defined by. The fused passes (`CpuFld::fused_with`) read the other colour's φ and D
    /// from cache, so they move 7 and 5 values from memory.
    pub fn bytes_per_iteration(&self) -> usize {
        let per_voxel = if self.config.limiter.is_constant() {
            7
        } else {
            9
        };
        per_voxel * self.grid.len() * std::mem::size_of::<T>()
    }

    /// Multigrid level (see [`super::multigrid`]): the smoother state of one coarse level,
    /// with φ, D and the right-hand side set by the cycle, in normalised units (j̄ = 1).
    pub(super) fn mg_level(medium: &Medium<T>, config: &FldConfig) -> Result<Self, SolverError> {
        let mut s = Self::new(medium, &Boundary::Zero, config)?;
        s.trivial = false;
        s.j_ref = 1.0;
        Ok(s)
    }

    /// One red-black smoothing sweep of FLD Algorithm 1 (exactly [`CpuFld::iterate`] without
    /// the bookkeeping); returns the sweep's R̄/j̄.
    pub(super) fn mg_sweep(&mut self) -> f64 {
        if !self.config.limiter.is_constant() {
            self.update_boundary_d();
        }
        let sumsq = self.passes();
        ResidualWindow::new(&self.grid, self.config.residual_margin).rms(sumsq)
    }

    /// From now on the sweeps leave D alone (multigrid's Picard coarse levels: the caller
    /// sets D), as they do for CDA.
    pub(super) fn mg_freeze_d(&mut self) {
        self.config.limiter = FluxLimiter::Cda;
    }

    /// σ and the absorption (1 − α)σΔl² in natural layout and normalised units.
    pub(super) fn mg_fields(&self) -> [Vec<f64>; 2] {
        [&self.sig, &self.absorb].map(|f| self.unpack_f64(f, 1.0))
    }

    /// φ alone (natural layout, normalised units): the one field a cycle reads back per visit.
    pub(super) fn mg_phi(&self) -> Vec<f64> {
        self.unpack_f64(&self.phi, 1.0)
    }

    /// [`CpuFld::mg_phi`] into `out` (resized to the grid; every value is overwritten).
    pub(super) fn mg_phi_into(&self, out: &mut Vec<f64>) {
        out.resize(self.grid.len(), 0.0);
        self.unpack_into(&self.phi, out, |x| x.f());
    }

    /// The right-hand side j (normalised, natural layout) of FLD Eq 32.
    pub(super) fn mg_rhs(&self) -> Vec<f64> {
        let dl2 = self.grid.dl * self.grid.dl;
        self.unpack_f64(&self.src, 1.0 / dl2)
    }

    /// Sets φ (`which` = 0), D (1), the right-hand side j (2), the Knudsen σ (3) or the
    /// absorption (1 − α)σΔl² (4) from natural layout.
    pub(super) fn mg_set(&mut self, which: usize, v: &[f64]) {
        self.black_x_ends_fresh = false;
        let g = self.grid;
        let dl2 = g.dl * g.dl;
        let (f, scale) = match which {
            0 => (&mut self.phi, 1.0),
            1 => (&mut self.d, 1.0),
            2 => (&mut self.src, dl2),
            3 => (&mut self.sig, 1.0),
            _ => (&mut self.absorb, 1.0),
        };
        let [nx, ny, _] = g.n;
        let h = self.h;
        let [f0, f1] = f;
        // Packed slab k of colour c holds, per row j, the voxels i = 2m + s, s = (c + j + k) & 1:
        // each natural row is split into its even and odd voxels in one pass (both colours).
        f0.par_chunks_mut(ny * h)
            .zip(f1.par_chunks_mut(ny * h))
            .enumerate()
            .for_each(|(k, (s0, s1))| {
                for j in 0..ny {
                    let (r0, r1) = (&mut s0[j * h..(j + 1) * h], &mut s1[j * h..(j + 1) * h]);
                    let (even, odd) = if (j + k) & 1 == 0 { (r0, r1) } else { (r1, r0) };
                    let base = g.index(0, j, k);
                    let row = &v[base..base + nx];
                    let pairs = row.chunks_exact(2);
                    if let [last] = pairs.remainder() {
                        even[nx / 2] = T::c(last * scale);
                    }
                    for ((p, e), o) in pairs.zip(even.iter_mut()).zip(odd.iter_mut()) {
                        *e = T::c(p[0] * scale);
                        *o = T::c(p[1] * scale);
                    }
                }
            });
    }

    /// [`CpuFld::mg_set`] of φ (`which` = 0) or D (1) for the voxels of the box `lo..=hi`
    /// only (multigrid's local relaxation, [`super::multigrid`]).
    pub(super) fn mg_set_box(&mut self, which: usize, v: &[f64], lo: [usize; 3], hi: [usize; 3]) {
        self.black_x_ends_fresh = false;
        let (g, h) = (self.grid, self.h);
        let f = if which == 0 {
            &mut self.phi
        } else {
            &mut self.d
        };
        for k in lo[2]..=hi[2] {
            for j in lo[1]..=hi[1] {
                for i in lo[0]..=hi[0] {
                    let (c, q) = packed_index(&g, h, i, j, k);
                    f[c][q] = T::c(v[g.index(i, j, k)]);
                }
            }
        }
    }

    /// Runs one red-black iteration and returns the normalised residual R̄/j̄ measured during it.
    pub fn iterate(&mut self) -> f64 {
        if self.trivial {
            self.iterations += 1;
            self.residuals.push(0.0);
            return 0.0;
        }
        if !self.config.limiter.is_constant() {
            self.update_boundary_d();
        }
        let sumsq = self.passes();
        // Normalised units: j̄ = 1 inside the solve.
        let r = ResidualWindow::new(&self.grid, self.config.residual_margin).rms(sumsq);
        self.iterations += 1;
        self.residuals.push(r);
        r
    }

    /// Iterates until R̄/j̄ < tolerance, the iteration cap, or a non-finite residual.
    pub fn solve(self) -> FldSolution<T> {
        self.solve_observed(|_, _| {})
    }

    /// As [`CpuFld::solve`], calling `observer(iteration, residual)` after every iteration
    /// (for progress bars and residual plots).
    pub fn solve_observed(mut self, mut observer: impl FnMut(usize, f64)) -> FldSolution<T> {
        let t0 = Instant::now();
        let mut reached = self.trivial.then_some(0.0);
        let status = if self.trivial {
            Stop::Converged
        } else {
            let (max, tol) = (self.config.max_iterations, self.tolerance);
            super::iterate(
                self.iterations,
                max,
                tol,
                None,
                || {
                    let r = self.iterate();
                    if r < tol && reached.is_none() {
                        reached = Some(t0.elapsed().as_secs_f64());
                    }
                    (self.iterations, r)
                },
                &mut observer,
            )
        };
        let seconds = t0.elapsed().as_secs_f64();
        let mut sol = super::solution(
            self.grid,
            self.phi(),
            std::mem::take(&mut self.residuals),
            self.iterations,
            status,
            seconds,
            self.setup_seconds,
            Timer::WallClock,
        );
        sol.trace.seconds_to_tolerance = reached;
        sol
    }

    /// The current φ in natural layout (x fastest), in the caller's units.
    pub fn phi(&self) -> Vec<T> {
        let scale = self.phi_unit();
        self.unpack(&self.phi)
            .into_iter()
            .map(|x| T::c(x.f() * scale))
            .collect()
    }

    /// The current diffusion coefficient D in natural layout.
    pub fn diffusion_coefficient(&self) -> Vec<T> {
        let mut d = self.unpack(&self.d);
        if self.black_x_ends_fresh {
            // The black x-ends hold the next iteration's D (`x_ends_in_pass`): this one's.
            let g = self.grid;
            let [nx, ny, nz] = g.n;
            for k in 1..nz - 1 {
                for j in 1..ny - 1 {
                    for (side, i) in [0, nx - 1].into_iter().enumerate() {
                        if (i + j + k) & 1 == 1 {
                            d[g.index(i, j, k)] = self.black_x_ends_prev[(k * ny + j) * 2 + side];
                        }
                    }
                }
            }
        }
        d
    }

    fn unpack(&self, f: &[Vec<T>; 2]) -> Vec<T> {
        self.unpack_map(f, T::zero(), |x| x)
    }

    /// A packed field in natural layout as `f64`, times `scale`.
    fn unpack_f64(&self, f: &[Vec<T>; 2], scale: f64) -> Vec<f64> {
        self.unpack_map(f, 0.0, |x| x.f() * scale)
    }

    /// A packed field in natural layout (x fastest), each value mapped by `map`; parallel
    /// over z-slabs (every output value is written once, so the order does not matter).
    fn unpack_map<U: Copy + Send + Sync>(
        &self,
        f: &[Vec<T>; 2],
        zero: U,
        map: impl Fn(T) -> U + Sync,
    ) -> Vec<U> {
        let mut out = vec![zero; self.grid.len()];
        self.unpack_into(f, &mut out, map);
        out
    }

    /// A packed field into `out` in natural layout (x fastest, `out` as long as the grid),
    /// each value mapped by `map`; parallel over z-slabs (every output value is written once,
    /// so the order does not matter).
    fn unpack_into<U: Send>(&self, f: &[Vec<T>; 2], out: &mut [U], map: impl Fn(T) -> U + Sync) {
        let g = &self.grid;
        let [nx, ny, _] = g.n;
        let h = self.h;
        out.par_chunks_mut(nx * ny)
            .enumerate()
            .for_each(|(k, slab)| {
                for j in 0..ny {
                    // Voxel i of row (j, k) has colour (i + j + k) & 1 and packed slot i/2:
                    // the row interleaves the two colours' packed rows.
                    let start = (k * ny + j) * h;
                    let (r0, r1) = (&f[0][start..start + h], &f[1][start..start + h]);
                    let (even, odd) = if (j + k) & 1 == 0 { (r0, r1) } else { (r1, r0) };
                    let row = &mut slab[j * nx..(j + 1) * nx];
                    let mut pairs = row.chunks_exact_mut(2);
                    for ((p, &e), &o) in pairs.by_ref().zip(even).zip(odd) {
                        p[0] = map(e);
                        p[1] = map(o);
                    }
                    if let [last] = pairs.into_remainder() {
                        *last = map(even[nx / 2]);
                    }
                }
            });
    }

    /// The red pass then the black pass; returns Σ residual² of both.
    fn passes(&mut self) -> f64 {
        let sumsq = if self.fused() {
            self.fused_passes()
        } else {
            self.pass(0) + self.pass(1)
        };
        self.black_x_ends_fresh = self.x_ends_in_pass();
        sumsq
    }

    /// Whether the row passes compute the D of the boundary layer's x-end voxels (i = 0 and
    /// nx − 1 of the rows with 0 < j < ny − 1, 0 < k < nz − 1) instead of
    /// [`CpuFld::update_boundary_d`]: FLD with nx ≥ 3.
    ///
    /// *Why and why it is exact.* Gathered per voxel those ends cost 12 % of an FLD-LP
    /// iteration at 256³ (2 % of the voxels; each read seven scattered cache lines), while
    /// the pass has every row they read in cache. An end voxel X reads φ of X itself and of
    /// its y and z neighbours (all on the boundary layer: constant during an iteration) and
    /// of its one interior neighbour N in the same row, of the other colour; D_X is read only
    /// by N's update. So a red X's D is computed in the red pass (N, black, is not updated
    /// before the black pass) and a black X's D in the black pass for the next iteration (N,
    /// red, is final by then, and nothing reads D_X before the next red pass); the first
    /// iteration, and any after φ, D or σ were set from outside, take the black ends from
    /// [`CpuFld::update_boundary_d`] as before. Same operations in the same order, so φ, the
    /// residuals and every D the sweeps read are bit-identical; only a black end's stored D
    /// is one iteration ahead between iterations.
    fn x_ends_in_pass(&self) -> bool {
        !self.config.limiter.is_constant() && self.grid.n[0] >= 3
    }

    /// D on the boundary layer (FLD only): F(R)/σ with ∇φ by one-sided differences where a
    /// neighbour is outside the grid (a decision of this crate, see [`super`]).
    ///
    /// Each boundary voxel reads φ (not updated here) and writes only its own D, so the
    /// update runs in parallel over z-slabs and is bit-identical to any serial order. It was
    /// serial until issue 15's bench: at 128³ FLD-LP it took 19 % of the CPU samples (`perf`)
    /// for 5 % of the voxels.
    fn update_boundary_d(&mut self) {
        super::limiter::with_limiter!(self.config.limiter, |lim| self.update_boundary_d_with(lim))
    }

    /// [`CpuFld::update_boundary_d`] with the limiter resolved at compile time.
    ///
    /// Per z-slab in two phases: a scalar gather of each boundary voxel's |∇φ|², σφ, σ and
    /// old D (the scattered part: packed indices, one-sided differences), then the square
    /// root, the Knudsen number, the limiter and the θ-blend over contiguous buffers, a loop
    /// that vectorises (the same operations in the same order per voxel, so D is
    /// bit-identical to the one-voxel-at-a-time version it replaced; measured in the `fld`
    /// module docs).
    fn update_boundary_d_with<L: Fn(T) -> (T, T) + Sync>(&mut self, lim: L) {
        let g = self.grid;
        let [nx, ny, nz] = g.n;
        let h = self.h;
        let slab = ny * h;
        let p = self.params;
        let (phi, sig) = (&self.phi, &self.sig);
        // 2/steps for a centred (2) or one-sided (1) difference, without a division.
        let per_step = |steps: usize| match steps {
            2 => T::one(),
            1 => T::c(2.0),
            _ => T::c(2.0 / steps as f64),
        };
        let at = |i: usize, j: usize, k: usize| {
            let (c, q) = packed_index(&g, h, i, j, k);
            phi[c][q]
        };
        // x-ends of colour c left to the passes (see `x_ends_in_pass`).
        let folded = self.x_ends_in_pass();
        let skip = [folded, folded && self.black_x_ends_fresh];
        let [d0, d1] = &mut self.d;
        d0.par_chunks_mut(slab)
            .zip(d1.par_chunks_mut(slab))
            .enumerate()
            .for_each_init(BoundaryBatch::default, |b, (k, (s0, s1))| {
                b.clear();
                let mut gather = |i: usize, j: usize| {
                    let diff = |lo: [usize; 3], hi: [usize; 3], steps: usize| {
                        (at(hi[0], hi[1], hi[2]) - at(lo[0], lo[1], lo[2]))
                            * p.inv_2dl
                            * per_step(steps)
                    };
                    let axis = |x: usize, n: usize| (x.saturating_sub(1), (x + 1).min(n - 1));
                    let (xl, xr) = axis(i, nx);
                    let (yl, yr) = axis(j, ny);
                    let (zl, zr) = axis(k, nz);
                    let gx = diff([xl, j, k], [xr, j, k], xr - xl);
                    let gy = diff([i, yl, k], [i, yr, k], yr - yl);
                    let gz = diff([i, j, zl], [i, j, zr], zr - zl);
                    let (c, q) = packed_index(&g, h, i, j, k);
                    let s = sig[c][q];
                    let d = if c == 0 {
                        s0[q - k * slab]
                    } else {
                        s1[q - k * slab]
                    };
                    b.push(
                        c,
                        q - k * slab,
                        gx * gx + gy * gy + gz * gz,
                        s * phi[c][q],
                        s,
                        d,
                    );
                };
                for j in 0..ny {
                    if k == 0 || k + 1 == nz || j == 0 || j + 1 == ny {
                        (0..nx).for_each(|i| gather(i, j));
                    } else {
                        for i in [0, nx - 1] {
                            if !skip[(i + j + k) & 1] {
                                gather(i, j);
                            }
                        }
                    }
                }
                b.compute(&p, &lim);
                for (&(c, q), &d) in b.at.iter().zip(&b.d) {
                    if c == 0 {
                        s0[q] = d;
                    } else {
                        s1[q] = d;
                    }
                }
            });
    }

    /// One colour pass over all interior voxels of colour `c`; returns Σ residual² over the
    /// voxels counted in the RMS.
    fn pass(&mut self, c: usize) -> f64 {
        self.run(Passes::One(c))
    }

    /// `what` with the face treatment and the limiter resolved to one instance.
    fn run(&mut self, what: Passes) -> f64 {
        match self.config.vacuum_face {
            super::VacuumFace::Paper => self.run_face::<false>(what),
            super::VacuumFace::Marshak => self.run_face::<true>(what),
        }
    }

    fn run_face<const M: bool>(&mut self, what: Passes) -> f64 {
        match self.config.limiter {
            // CDA's D is fixed at setup: the pass skips the Knudsen number and the limiter.
            FluxLimiter::Cda => self.run_with::<false, M, _>(what, |_| (T::zero(), T::one())),
            // One instance per limiter (Larsen-2 its own, branch-free; other n call `powf`).
            lim => super::limiter::with_limiter!(lim, |f| self.run_with::<true, M, _>(what, f)),
        }
    }

    fn run_with<const FLD: bool, const M: bool, L: Fn(T) -> (T, T) + Sync>(
        &mut self,
        what: Passes,
        limiter: L,
    ) -> f64 {
        match what {
            Passes::One(c) => self.pass_with::<FLD, M, L>(c, limiter),
            Passes::Fused => self.fused_with::<FLD, M, L>(limiter),
        }
    }

    fn pass_with<const FLD: bool, const M: bool, L: Fn(T) -> (T, T) + Sync>(
        &mut self,
        c: usize,
        limiter: L,
    ) -> f64 {
        let sweep = self.sweep::<FLD, M, L>(&limiter);
        let ([_, ny, nz], h, slab) = (sweep.n, sweep.h, sweep.slab_len());
        let [phi0, phi1] = &mut self.phi;
        let [d0, d1] = &mut self.d;
        let (phi_c, phi_o, d_c, d_o) = if c == 0 {
            (phi0, &*phi1, d0, &*d1)
        } else {
            (phi1, &*phi0, d1, &*d0)
        };
        let own = ColourFields::of(&self.sig, &self.absorb, &self.src, &self.vac, c);
        let vac_o = &self.vac[1 - c];
        // At least four tasks per thread (load balance on many cores), at most SLAB_GROUP slabs.
        let group = (nz / (4 * rayon::current_num_threads())).clamp(1, SLAB_GROUP);
        let partial: Vec<f64> = phi_c
            .par_chunks_mut(slab * group)
            .zip(d_c.par_chunks_mut(slab * group))
            .zip(self.black_x_ends_prev.par_chunks_mut(2 * ny * group))
            .enumerate()
            .flat_map_iter(|(t, ((phi_group, d_group), prev_group))| {
                let slabs = phi_group.len() / slab;
                let mut sums = vec![T::zero(); slabs];
                let mut scratch = vec![T::zero(); h];
                // Blocks of rows across the group's slabs (see `SLAB_GROUP`); each slab's
                // rows are still visited in ascending j, so its sum is the same.
                for j0 in (1..ny - 1).step_by(ROW_BLOCK) {
                    for (kk, acc) in sums.iter_mut().enumerate() {
                        let k = t * group + kk;
                        if k == 0 || k + 1 == nz {
                            continue;
                        }
                        let other = [
                            around(phi_o, k, slab),
                            around(d_o, k, slab),
                            around(vac_o, k, slab),
                        ];
                        let mine = [&mut *phi_group, &mut *d_group, &mut *prev_group];
                        let mut io = SlabIo::cut(c, k, t * group, [slab, ny], mine, own, other);
                        sweep.rows(&mut io, j0..(j0 + ROW_BLOCK).min(ny - 1), acc, &mut scratch);
                    }
                }
                sums.into_iter().map(|a| a.f())
            })
            .collect();
        // Summed in slab order so the result does not depend on the thread count.
        partial.iter().sum()
    }

    /// Whether [`CpuFld::passes`] runs the two colour passes fused (`CpuFld::fused_with`):
    /// grids of at least [`FUSE_MIN_SLABS`] slabs.
    fn fused(&self) -> bool {
        self.grid.n[2] >= FUSE_MIN_SLABS
    }

    /// Both colour passes fused ([`CpuFld::fused_with`]).
    fn fused_passes(&mut self) -> f64 {
        self.run(Passes::Fused)
    }

    /// The red and the black pass of one iteration, fused slab by slab. φ, D, the black
    /// x-ends' kept D and the returned Σ residual² are bit-identical to `pass(0) + pass(1)`
    /// (test `fused_passes_are_bit_identical_to_two_passes`).
    ///
    /// The slabs are cut into tasks [a, b) of at least two slabs. A task updates red slab
    /// k and then black slab k − 1, for k = a … b − 1, while the rows black slab k − 1 reads
    /// (red slabs k − 2 … k) are still in cache: a black voxel reads only red neighbours, all
    /// updated by then, and a red voxel only black ones (slabs k − 1 … k + 1), none updated
    /// yet. The black slabs a and b − 1 of a task read red slabs of the tasks beside it, so
    /// they wait for a second parallel phase, when every red slab is done (in the first
    /// phase they are only read). Each voxel is updated from the same values by the same
    /// operations as in the two passes, each slab's residual sum runs over its rows in the
    /// same order, and the slab sums are added red slabs first, then black, in slab order,
    /// as the two passes add them.
    fn fused_with<const FLD: bool, const M: bool, L: Fn(T) -> (T, T) + Sync>(
        &mut self,
        limiter: L,
    ) -> f64 {
        let sweep = self.sweep::<FLD, M, L>(&limiter);
        let ([_, ny, nz], h, slab) = (sweep.n, sweep.h, sweep.slab_len());
        // Task starts a_0 = 0 < a_1 < … < a_T = nz, each task at least two slabs.
        let size = (nz / (FUSE_TASKS_PER_THREAD * rayon::current_num_threads())).max(2);
        let tasks = (nz / size).max(1);
        let starts: Vec<usize> = (0..tasks).map(|t| t * size).chain([nz]).collect();
        // The black fields are cut into joints J_t = [a_t − 1, a_t + 1) ∩ [0, nz) (J_0 = {0},
        // J_T = {nz − 1}) and task interiors I_t = [a_t + 1, a_{t+1} − 1) between them:
        // `cuts` = lo(J_0), hi(J_0), lo(J_1), …, hi(J_T), the pieces J_0, I_0, J_1, …, J_T.
        let joint = |t: usize| (starts[t].max(1) - 1, (starts[t] + 1).min(nz));
        let cuts: Vec<usize> = (0..=tasks)
            .flat_map(|t| {
                let (lo, hi) = joint(t);
                [lo, hi]
            })
            .collect();
        let [phi0, phi1] = &mut self.phi;
        let [d0, d1] = &mut self.d;
        let own =
            [0, 1].map(|c| ColourFields::of(&self.sig, &self.absorb, &self.src, &self.vac, c));
        let vac = [&self.vac[0][..], &self.vac[1][..]];
        let (mut joints_phi, mut inner_phi) = evens_odds(split_slabs(phi1, slab, &cuts));
        let (mut joints_d, mut inner_d) = evens_odds(split_slabs(d1, slab, &cuts));
        let (mut joints_prev, mut inner_prev) =
            evens_odds(split_slabs(&mut self.black_x_ends_prev, 2 * ny, &cuts));
        let mut red_sums = vec![0.0; nz];
        let mut black_sums = vec![0.0; nz];
        // Phase 1: every red slab, and the black slabs of the task interiors.
        {
            let (jp, jd) = (&joints_phi, &joints_d);
            let per_task: Vec<(Vec<f64>, Vec<f64>)> = split_slabs(phi0, slab, &starts)
                .into_par_iter()
                .zip(split_slabs(d0, slab, &starts))
                .zip(inner_phi.par_iter_mut().zip(inner_d.par_iter_mut()))
                .zip(inner_prev.par_iter_mut())
                .enumerate()
                .map(|(t, (((rphi, rd), (iphi, id)), iprev))| {
                    let (a, b) = (starts[t], starts[t + 1]);
                    let (j0, i0, j1) = (joint(t).0, joint(t).1, joint(t + 1).0);
                    let mut scratch = vec![T::zero(); h];
                    let (mut red, mut black) = (vec![0.0; b - a], vec![0.0; b - a]);
                    for k in a..b {
                        if k > 0 && k + 1 < nz {
                            let other = [
                                around_in([(&*jp[t], j0), (*iphi, i0), (&*jp[t + 1], j1)], k, slab),
                                around_in([(&*jd[t], j0), (*id, i0), (&*jd[t + 1], j1)], k, slab),
                                around(vac[1], k, slab),
                            ];
                            let mine = [&mut *rphi, &mut *rd, &mut []];
                            let io = SlabIo::cut(0, k, a, [slab, ny], mine, own[0], other);
                            red[k - a] = sweep.slab(io, &mut scratch);
                        }
                        // Black slab z = k − 1 if it is in I_t: its red neighbours are done.
                        if k > i0 {
                            let z = k - 1;
                            let other = [
                                around_in([(&*rphi, a); 3], z, slab),
                                around_in([(&*rd, a); 3], z, slab),
                                around(vac[0], z, slab),
                            ];
                            let mine = [&mut **iphi, &mut **id, &mut **iprev];
                            let io = SlabIo::cut(1, z, i0, [slab, ny], mine, own[1], other);
                            black[z - a] = sweep.slab(io, &mut scratch);
                        }
                    }
                    (red, black)
                })
                .collect();
            for (t, (red, black)) in per_task.into_iter().enumerate() {
                let a = starts[t];
                red_sums[a..a + red.len()].copy_from_slice(&red);
                // The joints' slabs are still zero here; phase 2 sets them.
                black_sums[a..a + black.len()].copy_from_slice(&black);
            }
        }
        // Phase 2: the black slabs of the joints between tasks (J_1 … J_{T−1}).
        let (rphi, rd) = (&phi0[..], &d0[..]);
        let joint_sums: Vec<Vec<(usize, f64)>> = joints_phi
            .par_iter_mut()
            .zip(joints_d.par_iter_mut())
            .zip(joints_prev.par_iter_mut())
            .enumerate()
            .map(|(t, ((jp, jdd), jprev))| {
                let mut scratch = vec![T::zero(); h];
                let lo = joint(t).0;
                let n = jp.len() / slab;
                (lo..lo + n)
                    .filter(|&z| z > 0 && z + 1 < nz)
                    .map(|z| {
                        let other = [
                            around(rphi, z, slab),
                            around(rd, z, slab),
                            around(vac[0], z, slab),
                        ];
                        let mine = [&mut **jp, &mut **jdd, &mut **jprev];
                        let io = SlabIo::cut(1, z, lo, [slab, ny], mine, own[1], other);
                        (z, sweep.slab(io, &mut scratch))
                    })
                    .collect()
            })
            .collect();
        for (z, v) in joint_sums.into_iter().flatten() {
            black_sums[z] = v;
        }
        red_sums.iter().sum::<f64>() + black_sums.iter().sum::<f64>()
    }

    /// The constants of one colour pass.
    fn sweep<'l, const FLD: bool, const M: bool, L: Fn(T) -> (T, T)>(
        &self,
        limiter: &'l L,
    ) -> Sweep<'l, T, L, FLD, M> {
        Sweep {
            n: self.grid.n,
            h: self.h,
            p: self.params,
            window: ResidualWindow::new(&self.grid, self.config.residual_margin),
            x_ends: FLD && self.x_ends_in_pass(),
            limiter,
        }
    }
}

/// What [`CpuFld::run`] sweeps: one colour pass, or both fused.
#[derive(Clone, Copy)]
enum Passes {
    /// The pass over colour c (0 red, 1 black).
    One(usize),
    /// Red then black, fused slab by slab ([`CpuFld::fused_with`]).
    Fused,
}

/// The constants of one colour pass (grid, packed row length, parameters, residual window,
/// whether the row passes do the x-ends, the limiter).
struct Sweep<'l, T, L, const FLD: bool, const M: bool> {
    n: [usize; 3],
    h: usize,
    p: Params<T>,
    window: ResidualWindow,
    x_ends: bool,
    limiter: &'l L,
}

impl<T: Real, L: Fn(T) -> (T, T), const FLD: bool, const M: bool> Sweep<'_, T, L, FLD, M> {
    /// Values per packed slab of one colour.
    fn slab_len(&self) -> usize {
        self.n[1] * self.h
    }

    /// Updates every interior row of one slab; returns its Σ residual² (summed in row order).
    #[inline(always)]
    fn slab(&self, mut io: SlabIo<'_, T>, scratch: &mut [T]) -> f64 {
        let mut acc = T::zero();
        self.rows(&mut io, 1..self.n[1] - 1, &mut acc, scratch);
        acc.f()
    }

    /// Updates the interior rows `rows` of one slab, in ascending j, adding each row's
    /// Σ residual² to `acc` in that order.
    #[inline(always)]
    fn rows(
        &self,
        io: &mut SlabIo<'_, T>,
        rows: std::ops::Range<usize>,
        acc: &mut T,
        scratch: &mut [T],
    ) {
        let [nx, _, _] = self.n;
        let (h, k, lo, hi) = (self.h, io.k, self.window.lo, self.window.hi);
        for j in rows {
            let s = (io.c + j + k) & 1;
            let row = j * h;
            let prow = Rows::new(&io.phi_o, j, h);
            let drows = Rows::new(&io.d_o, j, h);
            let vrows = Rows::new(&io.vac_o, j, h);
            let counted_row = self.window.counts_row(j, k);
            // Interior i = 2m + s ∈ [1, nx − 2].
            let m_lo = 1 - s;
            let m_hi = (nx - 2 - s) / 2;
            // Counted i ∈ [lo, hi_x] ⇒ m ∈ [⌈(lo − s)/2⌉, ⌊(hi_x − s)/2⌋].
            let (cm_lo, cm_hi) = if counted_row && hi[0] + 1 > lo {
                ((lo - s).div_ceil(2), (hi[0] - s) / 2 + 1)
            } else {
                (0, 0)
            };
            *acc = *acc
                + update_row::<T, FLD, M, L>(
                    &mut io.phi[row..row + h],
                    &mut io.d[row..row + h],
                    &io.own.sig[row..row + h],
                    &io.own.absorb[row..row + h],
                    &io.own.src[row..row + h],
                    &io.own.vac[row..row + h],
                    &prow,
                    &drows,
                    &vrows,
                    s,
                    m_lo..m_hi + 1,
                    cm_lo..cm_hi,
                    &self.p,
                    self.limiter,
                    scratch,
                );
            if self.x_ends {
                update_x_ends(
                    nx,
                    s,
                    &io.phi[row..row + h],
                    &mut io.d[row..row + h],
                    &io.own.sig[row..row + h],
                    &prow,
                    (io.c == 1).then(|| &mut io.prev[2 * j..2 * j + 2]),
                    &self.p,
                    self.limiter,
                );
            }
        }
    }
}

/// The read-only fields of one colour (σ, absorption, source, vacuum flag), whole.
#[derive(Clone, Copy)]
struct ColourFields<'a, T> {
    sig: &'a [T],
    absorb: &'a [T],
    src: &'a [T],
    vac: &'a [T],
}

impl<'a, T> ColourFields<'a, T> {
    fn of(
        sig: &'a [Vec<T>; 2],
        absorb: &'a [Vec<T>; 2],
        src: &'a [Vec<T>; 2],
        vac: &'a [Vec<T>; 2],
        c: usize,
    ) -> Self {
        Self {
            sig: &sig[c],
            absorb: &absorb[c],
            src: &src[c],
            vac: &vac[c],
        }
    }

    /// The same fields cut to slab k.
    fn slab(&self, k: usize, slab: usize) -> Self {
        let cut = |f: &'a [T]| &f[k * slab..(k + 1) * slab];
        Self {
            sig: cut(self.sig),
            absorb: cut(self.absorb),
            src: cut(self.src),
            vac: cut(self.vac),
        }
    }
}

/// What a colour pass reads and writes in slab k of colour c: its own φ, D and (black) kept
/// x-end D, its own read-only fields, and the other colour's φ, D and vacuum flags in
/// slabs k − 1, k, k + 1.
struct SlabIo<'a, T> {
    c: usize,
    k: usize,
    phi: &'a mut [T],
    d: &'a mut [T],
    prev: &'a mut [T],
    own: ColourFields<'a, T>,
    phi_o: [&'a [T]; 3],
    d_o: [&'a [T]; 3],
    vac_o: [&'a [T]; 3],
}

impl<'a, T> SlabIo<'a, T> {
    /// Slab z of colour c: its own φ, D and kept x-end D cut from pieces that start at slab
    /// `first` (`[slab, ny]`: values per slab, rows per slab; an empty x-end piece stays
    /// empty), its own read-only fields, and the other colour's φ, D and vacuum flags
    /// around it.
    fn cut(
        c: usize,
        z: usize,
        first: usize,
        [slab, ny]: [usize; 2],
        [phi, d, prev]: [&'a mut [T]; 3],
        own: ColourFields<'a, T>,
        [phi_o, d_o, vac_o]: [[&'a [T]; 3]; 3],
    ) -> Self {
        let at = z - first;
        let prev = if prev.is_empty() {
            prev
        } else {
            &mut prev[at * 2 * ny..(at + 1) * 2 * ny]
        };
        Self {
            c,
            k: z,
            phi: &mut phi[at * slab..(at + 1) * slab],
            d: &mut d[at * slab..(at + 1) * slab],
            prev,
            own: own.slab(z, slab),
            phi_o,
            d_o,
            vac_o,
        }
    }
}

/// Slabs k − 1, k, k + 1 of `f`.
fn around<T>(f: &[T], k: usize, slab: usize) -> [&[T]; 3] {
    around_in([(f, 0); 3], k, slab)
}

/// Slabs k − 1, k, k + 1 from pieces (values, index of their first slab) that together
/// hold them.
fn around_in<T>(parts: [(&[T], usize); 3], k: usize, slab: usize) -> [&[T]; 3] {
    [k - 1, k, k + 1].map(|z| {
        for (f, z0) in parts {
            if z >= z0 && (z - z0) * slab < f.len() {
                return &f[(z - z0) * slab..(z - z0 + 1) * slab];
            }
        }
        unreachable!("slab {z} is in none of the pieces a fused task reads")
    })
}

/// `f` cut at slabs `at` (ascending, from 0 to the last slab), `per` values a slab.
fn split_slabs<'a, T>(mut f: &'a mut [T], per: usize, at: &[usize]) -> Vec<&'a mut [T]> {
    let mut out = Vec::with_capacity(at.len().saturating_sub(1));
    for w in at.windows(2) {
        let (piece, rest) = f.split_at_mut((w[1] - w[0]) * per);
        out.push(piece);
        f = rest;
    }
    out
}

/// The pieces at even and at odd positions.
fn evens_odds<P>(pieces: Vec<P>) -> (Vec<P>, Vec<P>) {
    let (mut even, mut odd) = (Vec::new(), Vec::new());
    for (i, p) in pieces.into_iter().enumerate() {
        if i % 2 == 0 {
            even.push(p);
        } else {
            odd.push(p);
        }
    }
    (even, odd)
}

/// The boundary voxels of one z-slab gathered for [`CpuFld::update_boundary_d`]: where each
/// sits (colour, packed index within the slab) and its |∇φ|², σφ, σ and D.
#[derive(Default)]
struct BoundaryBatch<T> {
    at: Vec<(usize, usize)>,
    grad2: Vec<T>,
    sphi: Vec<T>,
    sig: Vec<T>,
    d: Vec<T>,
}

impl<T: Real> BoundaryBatch<T> {
    fn clear(&mut self) {
        self.at.clear();
        self.grad2.clear();
        self.sphi.clear();
        self.sig.clear();
        self.d.clear();
    }

    fn push(&mut self, c: usize, q: usize, grad2: T, sphi: T, sig: T, d: T) {
        self.at.push((c, q));
        self.grad2.push(grad2);
        self.sphi.push(sphi);
        self.sig.push(sig);
        self.d.push(d);
    }

    /// [`relaxed_d`] over equal-length slices, so the loop vectorises.
    fn compute<L: Fn(T) -> (T, T)>(&mut self, p: &Params<T>, lim: &L) {
        let n = self.d.len();
        let (grad2, sphi, sig, d) = (
            &self.grad2[..n],
            &self.sphi[..n],
            &self.sig[..n],
            &mut self.d[..n],
        );
        for q in 0..n {
            d[q] = relaxed_d(p, lim, grad2[q], sphi[q], sig[q], d[q]);
        }
    }
}

/// The other colour's five neighbour rows of a row: same row (x-neighbours), y ± 1, z ± 1.
struct Rows<'a, T> {
    x: &'a [T],
    ym: &'a [T],
    yp: &'a [T],
    zm: &'a [T],
    zp: &'a [T],
}

impl<'a, T> Rows<'a, T> {
    /// The rows around row j of the middle of three slabs (below, here, above; row length `h`).
    #[inline(always)]
    fn new(slabs: &[&'a [T]; 3], j: usize, h: usize) -> Self {
        let g = j * h;
        Self {
            x: &slabs[1][g..g + h],
            ym: &slabs[1][g - h..g],
            yp: &slabs[1][g + h..g + 2 * h],
            zm: &slabs[0][g..g + h],
            zp: &slabs[2][g..g + h],
        }
    }

    /// The six neighbour runs of the `len` voxels starting at m0: x−, x+ (starting at `xl`,
    /// `xr` in the same row), y−, y+, z−, z+, each exactly `len` long.
    #[inline(always)]
    fn cut(&self, xl: usize, xr: usize, m0: usize, len: usize) -> [&'a [T]; 6] {
        [
            &self.x[xl..xl + len],
            &self.x[xr..xr + len],
            &self.ym[m0..m0 + len],
            &self.yp[m0..m0 + len],
            &self.zm[m0..m0 + len],
            &self.zp[m0..m0 + len],
        ]
    }
}

/// Updates the voxels `ms` of one packed row; returns Σ residual² over `counted`.
///
/// Every input is first cut to exactly `ms.len()` elements so the compiler can drop bounds
/// checks and vectorise the loop.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn update_row<T: Real, const FLD: bool, const M: bool, L: Fn(T) -> (T, T)>(
    phi: &mut [T],
    d: &mut [T],
    sig: &[T],
    absorb: &[T],
    src: &[T],
    vac: &[T],
    po: &Rows<T>,
    dn: &Rows<T>,
    vn: &Rows<T>,
    s: usize,
    ms: std::ops::Range<usize>,
    counted: std::ops::Range<usize>,
    p: &Params<T>,
    limiter: &L,
    scratch: &mut [T],
) -> T {
    let half = T::c(0.5);
    let six = T::c(6.0);
    let (m0, len) = (ms.start, ms.len());
    let (xl, xr) = (m0 + s - 1, m0 + s);
    let [pxl, pxr, pym, pyp, pzm, pzp] = po.cut(xl, xr, m0, len);
    let [dxl, dxr, dym, dyp, dzm, dzp] = dn.cut(xl, xr, m0, len);
    let [vxl, vxr, vym, vyp, vzm, vzp] = vn.cut(xl, xr, m0, len);
    let vac = &vac[m0..m0 + len];
    let (two, four) = (T::c(2.0), T::c(4.0));
    let (sig, absorb, src) = (
        &sig[m0..m0 + len],
        &absorb[m0..m0 + len],
        &src[m0..m0 + len],
    );
    let phi = &mut phi[m0..m0 + len];
    let d = &mut d[m0..m0 + len];
    let (c_lo, c_hi) = (
        counted.start.saturating_sub(m0),
        counted.end.saturating_sub(m0),
    );
    let scratch = &mut scratch[..len];
    if FLD {
        // FLD Eqs 34, 35, 33 (D under-relaxed by θ, see the `fld` module docs), for the whole
        // run first: a voxel's D reads only the other colour's φ and its own φ, which this
        // run does not change before the voxel's own update, so the split is exact (measured
        // in the `fld` module docs).
        for q in 0..len {
            let gx = (pxr[q] - pxl[q]) * p.inv_2dl;
            let gy = (pyp[q] - pym[q]) * p.inv_2dl;
            let gz = (pzp[q] - pzm[q]) * p.inv_2dl;
            let grad2 = gx * gx + gy * gy + gz * gz;
            d[q] = relaxed_d(p, limiter, grad2, sig[q] * phi[q], sig[q], d[q]);
        }
    }
    for q in 0..len {
        let phi_p = phi[q];
        let ns = [pxl[q], pxr[q], pym[q], pyp[q], pzm[q], pzp[q]];
        let ds = [dxl[q], dxr[q], dym[q], dyp[q], dzm[q], dzp[q]];
        let d_p = d[q];
        let (num, den) = if M {
            // A face between medium and vacuum: the Marshak face coefficient of the medium
            // side's D (see the `fld` module docs), D_ps = 2 D Δl/(Δl + 4 D); elsewhere Eq 32.
            let vp = vac[q] > half;
            let vs = [vxl[q], vxr[q], vym[q], vyp[q], vzm[q], vzp[q]];
            let (mut num, mut den) = (src[q], absorb[q]);
            for k in 0..6 {
                let f = if vp != (vs[k] > half) {
                    let dm = if vp { ds[k] } else { d_p };
                    two * dm * p.dl / (p.dl + four * dm)
                } else {
                    half * (d_p + ds[k])
                };
                num = num + f * ns[k];
                den = den + f;
            }
            (num, den)
        } else {
            // FLD Eq 32 with D_ps = (D_p + D_s)/2.
            let sum_phi = ns[0] + ns[1] + ns[2] + ns[3] + ns[4] + ns[5];
            let sum_dphi = ds[0] * ns[0]
                + ds[1] * ns[1]
                + ds[2] * ns[2]
                + ds[3] * ns[3]
                + ds[4] * ns[4]
                + ds[5] * ns[5];
            let sum_d = ds[0] + ds[1] + ds[2] + ds[3] + ds[4] + ds[5];
            (
                src[q] + half * (d_p * sum_phi + sum_dphi),
                absorb[q] + half * (six * d_p + sum_d),
            )
        };
        // FLD Eq 37, before the update (see the module docs of `fld`).
        let res = (num - phi_p * den) * p.inv_dl2;
        let w = if q >= c_lo && q < c_hi {
            T::one()
        } else {
            T::zero()
        };
        scratch[q] = w * res * res;
        // FLD Eq 36, projected onto φ ≥ 0 (NaN passes through unchanged).
        let new = p.omega * (num / den) + p.one_minus_omega * phi_p;
        phi[q] = if new < T::zero() { T::zero() } else { new };
    }
    // Eight independent partial sums: a fixed order (deterministic) that still vectorises.
    let mut lanes = [T::zero(); 8];
    let chunks = scratch.chunks_exact(8);
    let tail = chunks.remainder();
    for c in chunks {
        for (l, &v) in lanes.iter_mut().zip(c) {
            *l = *l + v;
        }
    }
    lanes.iter().chain(tail).fold(T::zero(), |a, &b| a + b)
}

/// D ← θ F(R)/σ + (1 − θ) D with R = max(|∇φ|, floor)/max(σφ, floor) (FLD Eqs 33–35,
/// θ-relaxed, see the `fld` module docs), from |∇φ|² and σφ: the one formula of every D
/// update of the sweep (the row loop, the x-ends, the boundary batch).
#[inline(always)]
fn relaxed_d<T: Real, L: Fn(T) -> (T, T)>(
    p: &Params<T>,
    lim: &L,
    grad2: T,
    sphi: T,
    sig: T,
    d: T,
) -> T {
    let r = grad2.sqrt().max(p.floor) / sphi.max(p.floor);
    let (num, den) = lim(r);
    (p.theta * num) / (den * sig) + p.one_minus_theta * d
}

/// D of the x-end voxels (i = 0, nx − 1) of colour c in one interior row
/// ([`CpuFld::x_ends_in_pass`]), with the differences of [`CpuFld::update_boundary_d`]: one-sided
/// in x towards the interior neighbour (the other colour), central in y and z (their ×1
/// dropped: exact). `phi`, `d`, `sig`: the row of colour c (s = its parity); `rows`: the other
/// colour's rows around it; `prev`: where to keep the D being replaced (left, right), for a
/// black row.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn update_x_ends<T: Real, L: Fn(T) -> (T, T)>(
    nx: usize,
    s: usize,
    phi: &[T],
    d: &mut [T],
    sig: &[T],
    rows: &Rows<T>,
    mut prev: Option<&mut [T]>,
    p: &Params<T>,
    limiter: &L,
) {
    let two = T::c(2.0);
    // (m, whether it is the left end), where that end has this row's colour.
    let left = (s == 0).then_some((0, true));
    let right = ((nx - 1 - s) % 2 == 0).then_some(((nx - 1 - s) / 2, false));
    for (m, is_left) in [left, right].into_iter().flatten() {
        // The interior neighbour i = 1 or nx − 2.
        let n_phi = if is_left {
            rows.x[0]
        } else {
            rows.x[m + s - 1]
        };
        let gx = if is_left {
            n_phi - phi[m]
        } else {
            phi[m] - n_phi
        } * p.inv_2dl
            * two;
        let gy = (rows.yp[m] - rows.ym[m]) * p.inv_2dl;
        let gz = (rows.zp[m] - rows.zm[m]) * p.inv_2dl;
        if let Some(prev) = prev.as_deref_mut() {
            prev[usize::from(!is_left)] = d[m];
        }
        let grad2 = gx * gx + gy * gy + gz * gz;
        d[m] = relaxed_d(p, limiter, grad2, sig[m] * phi[m], sig[m], d[m]);
    }
}

/// Slabs per parallel task of a colour pass, and rows per block within it: the pass walks
/// a task's slabs block of rows by block of rows, so the z-neighbour rows a slab reads
/// (its neighbour slabs' rows of the same block) are still in the core's cache from the
/// slab before.
const SLAB_GROUP: usize = 8;
/// See [`SLAB_GROUP`].
const ROW_BLOCK: usize = 32;
/// Fused passes (`CpuFld::fused_with`): tasks per rayon thread (each at least two slabs),
/// and the fewest slabs a grid must have to be fused.
const FUSE_TASKS_PER_THREAD: usize = 2;
/// See [`FUSE_TASKS_PER_THREAD`].
const FUSE_MIN_SLABS: usize = 4;

/// The packed row length: ⌈nx/2⌉, plus one unused slot where that is even. With a row
/// length of a power of two the z-neighbour rows of a voxel (a slab apart: ny·h values) fall
/// into the same cache sets, and the sweep slows by half. Measured (2026-12-06, 2-vCPU AMD
/// EPYC 7002-series, `cargo bench -p benches --bench diffusion`, one red-black iteration on
/// the 256³ vacuum cloud, h = 128 → 129, f32): CDA 32.7 → 21.8 ms, FLD-LP 80.4 → 70.1 ms,
/// while 258³ (h = 129 either way) took 21.7 and 78.0 ms; φ, D and the residuals are
/// bit-identical (only where the values sit changes). The GPU kernels keep rows of exactly
/// ⌈nx/2⌉ ([`CpuFld::packed_fields`] hands them that layout).
fn packed_row_len(nx: usize) -> usize {
    nx.div_ceil(2) | 1
}

/// Colour and packed position of voxel (i, j, k).
#[inline(always)]
fn packed_index(g: &Grid, h: usize, i: usize, j: usize, k: usize) -> (usize, usize) {
    ((i + j + k) & 1, (k * g.n[1] + j) * h + i / 2)
}

#[cfg(test)]
mod tests;
