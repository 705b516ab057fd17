//! The CPU solver: Gruson's propagate/collect split (LPM Alg 2, Eq 6) with rayon, one task
//! per direction of the current LPM (each owns its T buffer of one slice and its ray state,
//! D19), then after each slice a per-voxel collect that sums the directions in a fixed order.
//! Bit-identical for any thread count (test T23) and any slicing (T16).

use super::directions::{CONE_SOLID_ANGLE, CONES, Directions, PhaseMatrix, lateral_axes};
use super::geometry::DirectionTable;
use super::{BoundaryLight, Deposit, LpmConfig, LpmSolution, Memory, OrderTally, StorageI, WrapBc};
use crate::scene::Phase;
use crate::{Grid, Medium, Real, SolverError};
use rayon::prelude::*;
use std::f64::consts::PI;

/// A prepared LPM solve on one medium: directions, phase matrix, geometry tables and the
/// medium in the working precision.
#[derive(Debug, Clone)]
pub struct CpuLpm<T> {
    /// The grid.
    pub grid: Grid,
    /// The settings.
    pub config: LpmConfig,
    /// The propagation directions.
    pub dirs: Directions,
    /// F of LPM Eq 5 (fine and coarse).
    pub phase: PhaseMatrix,
    /// One sub-segment table per direction (its face's sweep length).
    pub tables: Vec<DirectionTable>,
    pub(super) sigma_t: Vec<T>,
    pub(super) sigma_s: Vec<T>,
    /// σt and σs in the x-faces' layout ([`to_x_layout`]), so their sweeps run along memory.
    sigma_t_x: Vec<T>,
    sigma_s_x: Vec<T>,
    /// U⁰ = I⁰ = j/4π per voxel (D9).
    pub(super) source: Vec<T>,
    /// Slabs per slice (D19; ≥ the longest axis: not streamed).
    slabs: usize,
    /// Whether an f32 sweep may use the AVX-512 kernel where the CPU has it (set by
    /// [`CpuLpm::new`]; clear it to force the 8-lane kernel, e.g. to compare the two).
    pub wide: bool,
}

/// (E, φ1, φ2) of optical depth τ: E = e^{−τ}, φ1 = (1 − E)/τ, φ2 = (τ − 1 + E)/τ² (spec
/// §1.6); below `ts` the series (truncation < 10⁻¹⁶ at the thresholds used) with
/// E = 1 − τφ1, so vacuum is exact (D29).
///
/// In f32 the form is branch-free, so a row of sub-segments vectorises: the series and the
/// direct form are both evaluated and one is selected. The series is φ2's alone (8 terms,
/// Horner in [`fmadd`]), with φ1 = 1 − τφ2 and E = 1 − τφ1 (exact identities; below
/// τ = 0.5 neither step cancels: τφ2 ≤ 0.22, τφ1 ≤ 0.40). The direct form takes E from
/// [`exp_neg_f32`] (no libm call). In f64 the two series and libm's `expm1` as before.
#[inline(always)]
pub fn phis<T: Real>(tau: T, ts: T) -> (T, T, T) {
    let c = |x: f64| T::c(x);
    if is_f32::<T>() {
        let m = -tau;
        let mut f2s = c(1.0 / 362880.0);
        for k in [40320.0, 5040.0, 720.0, 120.0, 24.0, 6.0, 2.0] {
            f2s = fmadd(m, f2s, c(1.0 / k));
        }
        let f1s = fmadd(m, f2s, T::one());
        let es = fmadd(m, f1s, T::one());
        // Direct form for τ ≥ ts = 0.5: 1 − E ≥ 0.39, so E itself (not expm1) loses nothing.
        let e = T::c(exp_neg_f32(tau.f() as f32) as f64);
        let inv = T::one() / tau;
        let f1d = (T::one() - e) * inv;
        let f2d = (tau - T::one() + e) * inv * inv;
        let small = tau < ts;
        let f1 = if small { f1s } else { f1d };
        let f2 = if small { f2s } else { f2d };
        let e = if small { es } else { e };
        return (e, f1, f2);
    }
    let f1s = T::one()
        - tau
            * (c(1.0 / 2.0)
                - tau
                    * (c(1.0 / 6.0)
                        - tau
                            * (c(1.0 / 24.0)
                                - tau
                                    * (c(1.0 / 120.0)
                                        - tau
                                            * (c(1.0 / 720.0)
                                                - tau
                                                    * (c(1.0 / 5040.0)
                                                        - tau * c(1.0 / 40320.0)))))));
    let f2s = c(1.0 / 2.0)
        - tau
            * (c(1.0 / 6.0)
                - tau
                    * (c(1.0 / 24.0)
                        - tau
                            * (c(1.0 / 120.0)
                                - tau
                                    * (c(1.0 / 720.0)
                                        - tau
                                            * (c(1.0 / 5040.0)
                                                - tau
                                                    * (c(1.0 / 40320.0)
                                                        - tau * c(1.0 / 362880.0)))))));
    if tau < ts {
        (T::one() - tau * f1s, f1s, f2s)
    } else {
        let em1 = (-tau).exp_m1();
        (T::one() + em1, -em1 / tau, (tau + em1) / (tau * tau))
    }
}

/// Whether `T` is single precision (a constant after monomorphisation).
#[inline(always)]
fn is_f32<T: Real>() -> bool {
    T::epsilon().f() > 1e-10
}

/// Whether [`fmadd`] fuses: where the target has a fused multiply-add instruction (x86-64
/// with FMA, e.g. this workspace's x86-64-v3 build; every aarch64). Elsewhere `mul_add`
/// would be a scalar libm call per operation, so it is not used there.
pub const FUSED: bool = cfg!(any(target_feature = "fma", target_arch = "aarch64"));

/// a·b + c of the f32 kernel ([`phis`], [`exp_neg_f32`], [`segment`]): one rounding (fused,
/// `mul_add`) where [`FUSED`], else a·b then + c. The fused form halves the kernel's
/// dependent chains (the Horner polynomials); a build without FMA (e.g.
/// `RUSTFLAGS="-C target-cpu=x86-64"`) gives results that differ by rounding.
#[inline(always)]
pub fn fmadd<T: Real>(a: T, b: T, c: T) -> T {
    if FUSED { a.mul_add(b, c) } else { a * b + c }
}

/// e^{−τ} in f32 for τ ≥ 0 without a libm call, so that LLVM vectorises it: τ is clamped to
/// 80 (e^{−80} = 1.8·10⁻³⁵, still normal), x = −τ = k ln 2 + r with k by the 1.5·2²³
/// rounding trick and a two-constant Cody–Waite ln 2, e^r (|r| ≤ ln2/2) by its Taylor
/// polynomial to r⁷ (truncation 0.347⁸/8! = 5·10⁻⁹ relative, Horner in [`fmadd`]), times
/// 2^k built from its bits. Within 0.86 ulp of the exact value with FMA (1.15 ulp unfused;
/// measured against f64 over τ ∈ [0, 80], bound 2, in `exp_neg_f32_matches_f64`).
#[inline(always)]
pub fn exp_neg_f32(tau: f32) -> f32 {
    const MAGIC: f32 = 12_582_912.0; // 1.5·2²³
    let x = -tau.min(80.0);
    let t = fmadd(x, std::f32::consts::LOG2_E, MAGIC);
    let k = t - MAGIC;
    let ki = (t.to_bits() as i32).wrapping_sub(MAGIC.to_bits() as i32);
    let r = fmadd(k, 2.121_944_4e-4, fmadd(k, -0.693_359_4, x));
    let mut p = 1.0 / 5040.0;
    for a in [720.0, 120.0, 24.0, 6.0, 2.0, 1.0, 1.0] {
        p = fmadd(p, r, 1.0 / a);
    }
    p * f32::from_bits(((ki + 127) as u32) << 23)
}

/// The series threshold of [`phis`] for precision `T`: 0.05 in f64, 0.5 in f32 (where the
/// direct φ2 loses 2ε/τ to cancellation).
pub fn series_threshold<T: Real>() -> T {
    T::c(if T::epsilon().f() > 1e-10 { 0.5 } else { 0.05 })
}

/// One sub-segment of LPM Eq 3 in the conservative form (spec §1.6): returns
/// (L_out, ∫L ds) for incoming radiance `l_in`, unshot source `u`, extinction `st` and
/// length `s`.
#[inline(always)]
pub fn segment<T: Real>(l_in: T, u: T, st: T, s: T, ts: T) -> (T, T) {
    let (e, f1, f2) = phis(st * s, ts);
    let us = u * s;
    if is_f32::<T>() {
        (fmadd(l_in, e, us * f1), s * fmadd(l_in, f1, us * f2))
    } else {
        (l_in * e + us * f1, s * (l_in * f1 + us * f2))
    }
}

/// [`segment`] over one row of rays: `rays` (in and out), their voxels' unshot source `u`
/// and extinction `st`, and their T, all with one sub-segment length `s`.
///
/// In f32 the row runs in blocks of `L` ([`LANES`], or [`WIDE_LANES`] in the AVX-512 copy)
/// and the last partial block is padded (σt = 0, so τ = 0) and run as a full one, so every
/// sub-segment goes through the vector code: a plain loop left up to 7 rays of each run (a
/// row was then split in two runs at the wrap) to a scalar epilogue, 34 % of the sweep's
/// samples at 64³. With the fused kernel the blocks saved 12 % of a 64³ RGB solve
/// (2.87 → 2.51 CPU-s, 1 thread, A/B). Each ray's arithmetic is unchanged (bit-identical). f64 keeps the plain
/// loop (its libm `expm1` does not vectorise).
// The padding copies are element loops on purpose (see the comment there).
#[allow(clippy::manual_memcpy)]
#[inline(always)]
fn transport_row<T: Real, const L: usize>(
    rays: &mut [T],
    u: &[T],
    st: &[T],
    g: &mut [T],
    s: T,
    ts: T,
) {
    let n = rays.len();
    let (u, st, g) = (&u[..n], &st[..n], &mut g[..n]);
    if !is_f32::<T>() {
        for (((l, &u), &st), g) in rays.iter_mut().zip(u).zip(st).zip(g) {
            let (l_out, int) = segment(*l, u, st, s, ts);
            *g = *g + int;
            *l = l_out;
        }
        return;
    }
    let full = n - n % L;
    let (rays_b, rays_r) = rays.split_at_mut(full);
    let (u_b, u_r) = u.split_at(full);
    let (st_b, st_r) = st.split_at(full);
    let (g_b, g_r) = g.split_at_mut(full);
    for (((l, u), st), g) in rays_b
        .chunks_exact_mut(L)
        .zip(u_b.chunks_exact(L))
        .zip(st_b.chunks_exact(L))
        .zip(g_b.chunks_exact_mut(L))
    {
        transport_block::<T, L>(l, u, st, g, s, ts);
    }
    let r = rays_r.len();
    if r > 0 {
        let mut l = [T::zero(); L];
        let mut uu = [T::zero(); L];
        let mut ss = [T::zero(); L];
        let mut gg = [T::zero(); L];
        // Element loops, not `copy_from_slice`: a memcpy call per ≤ 7 words cost 4 % of
        // the solve.
        for j in 0..r {
            l[j] = rays_r[j];
            uu[j] = u_r[j];
            ss[j] = st_r[j];
            gg[j] = g_r[j];
        }
        transport_block::<T, L>(&mut l, &uu, &ss, &mut gg, s, ts);
        for j in 0..r {
            rays_r[j] = l[j];
            g_r[j] = gg[j];
        }
    }
}

/// Rays per block of [`transport_row`]: one AVX2 register of f32.
const LANES: usize = 8;

/// Rays per block of the AVX-512 sweep: one 512-bit register of f32.
pub const WIDE_LANES: usize = 16;

/// [`segment`] over exactly `L` rays (a fixed trip count, so LLVM emits one straight vector
/// body with no epilogue).
#[inline(always)]
fn transport_block<T: Real, const L: usize>(
    rays: &mut [T],
    u: &[T],
    st: &[T],
    g: &mut [T],
    s: T,
    ts: T,
) {
    let (rays, u, st, g) = (&mut rays[..L], &u[..L], &st[..L], &mut g[..L]);
    for j in 0..L {
        let (l_out, int) = segment(rays[j], u[j], st[j], s, ts);
        g[j] = g[j] + int;
        rays[j] = l_out;
    }
}

/// Ray-sum tallies of one direction's sweep (radiance summed over rays; the caller weights
/// them by A|Ω^i|).
#[derive(Debug, Clone, Copy, Default)]
struct SweepTally {
    injected: f64,
    exited: f64,
}

/// One direction's rays between slices: radiance per ray, the last sub-segment's lateral
/// offsets (for the wrap events), the re-entry radiance and the tally.
///
/// A row's rays (fixed c) are stored by the voxel column b they are in, not by their lattice
/// index (lattice ray r is in column (r + o_b) mod n_b): a row of rays then lines up with a
/// row of voxels, so the sweep runs it as one slice, not two split at the wrap (with
/// blocks of 8 rays the split left 2 padded blocks per row; the rows rotate by one when
/// o_b changes, at most once per slab). The rows themselves stay in lattice order.
#[derive(Debug, Clone)]
struct RayState<T> {
    ray: Vec<T>,
    prev: [i64; 2],
    l0: f64,
    tally: SweepTally,
}

/// One direction's buffers of a face: its slice of T (and of the paper's deposit) and its
/// rays.
#[derive(Debug)]
struct Lane<T> {
    g: Vec<T>,
    p: Vec<T>,
    rays: Option<RayState<T>>,
}

impl<T: Real> CpuLpm<T> {
    /// Prepares a solve; validates the medium and the settings, and refuses a grid whose
    /// buffers exceed the memory budget (before allocating them).
    pub fn new(medium: &Medium<T>, config: &LpmConfig) -> Result<Self, SolverError> {
        config.validate()?;
        medium.validate()?;
        let grid = medium.grid;
        let dirs = Directions::new(config.m)?;
        let slabs = config.slabs(&grid, std::mem::size_of::<T>() as u64)?;
        let phase = PhaseMatrix::new(&dirs, config.phase, config.quadrature)?;
        let tables = dirs
            .dirs
            .iter()
            .map(|d| DirectionTable::new(d, config.m, grid.n[d.face / 2]))
            .collect();
        let sigma_s: Vec<T> = medium
            .sigma_t
            .iter()
            .zip(&medium.albedo)
            .map(|(&s, &a)| s * a)
            .collect();
        let four_pi = T::c(4.0 * PI);
        let sigma_s: Vec<T> = sigma_s;
        Ok(Self {
            sigma_t_x: to_x_layout(&grid, &medium.sigma_t),
            sigma_s_x: to_x_layout(&grid, &sigma_s),
            grid,
            config: config.clone(),
            dirs,
            phase,
            tables,
            sigma_t: medium.sigma_t.clone(),
            sigma_s,
            source: medium.emission.iter().map(|&j| j / four_pi).collect(),
            slabs,
            wide: true,
        })
    }

    /// Sub-segments one order processes: Σ_i (table entries of i) × (rays of i's face), the
    /// measured count of D20 (294 n³ for m = 5).
    pub fn sub_segments_per_order(&self) -> u64 {
        self.dirs
            .dirs
            .iter()
            .zip(&self.tables)
            .map(|(d, t)| super::sweep_segments(&self.grid, d, t))
            .sum()
    }

    /// Bytes of a solve by our per-buffer formula ([`super::memory_bytes`]).
    pub fn memory_estimate(&self) -> u64 {
        self.memory_formula().total()
    }

    /// Our per-buffer formula at this solve's slabs per slice.
    pub fn memory_formula(&self) -> super::MemoryBytes {
        super::memory_bytes_sliced(
            &self.grid,
            &self.config,
            std::mem::size_of::<T>() as u64,
            self.slabs,
        )
    }

    /// The ray tube's cross-section A of direction i: A⊥ = h²|ω·n_f| (D6) or the paper's face
    /// area h².
    pub fn area(&self, i: usize) -> f64 {
        let cos = self.dirs.dirs[i].cos_axis;
        self.config.formulas.area(self.grid.dl, cos)
    }

    /// The factor on the Euclidean length: 1 (D5) or the paper's 1/|ω_n|.
    pub fn path_factor(&self, i: usize) -> f64 {
        self.config.formulas.path_factor(self.dirs.dirs[i].cos_axis)
    }

    /// The medium (σt, σs), in the layout the sweeps of sweep axis `a` read, and the strides
    /// of the x, y, z voxel indices in it: the x faces read the copies in the layout of
    /// [`to_x_layout`], so every sweep's rows run along memory.
    fn sweep_media(&self, a: usize) -> ((&[T], &[T]), [usize; 3]) {
        let n = self.grid.n;
        if a == 0 {
            ((&self.sigma_t_x, &self.sigma_s_x), [n[1] * n[2], 1, n[1]])
        } else {
            ((&self.sigma_t, &self.sigma_s), [1, n[0], n[0] * n[1]])
        }
    }

    /// Slabs per slice of the solve (the longest axis: not streamed).
    pub fn slabs(&self) -> usize {
        self.slabs
    }

    /// The rays of direction `i` entering its face at `order` (boundary radiance `l_bc`),
    /// before the first slab.
    fn start_rays(&self, i: usize, l_bc: f64, order: usize) -> RayState<T> {
        let (b, c) = lateral_axes(self.dirs.dirs[i].face / 2);
        let rays = self.grid.n[b] * self.grid.n[c];
        let l0 = if order == 0 { l_bc } else { 0.0 };
        RayState {
            ray: vec![T::c(l0); rays],
            prev: [0, 0],
            l0,
            tally: SweepTally {
                injected: l0 * rays as f64,
                exited: 0.0,
            },
        }
    }

    /// Sweeps the rays `st` of direction `i` through the slabs `z0..z1` (sweep order) of
    /// its face: reads `u_src` (the unshot U of its cone, in the x layout for the x faces),
    /// re-enters rays per the wrap rule, accumulates ∫L ds into the slice's T `g` (and the
    /// paper's deposit into `paper`), both in the slice layout b + n_b(c + n_c(z − z0)).
    /// The ray state is left for the next slice; the summation order per voxel does not
    /// depend on the slicing.
    ///
    /// In f32 on an x86-64 CPU with AVX-512F (and [`CpuLpm::wide`] set) the sweep runs a
    /// copy compiled for AVX-512 with blocks of 16 rays ([`WIDE_LANES`]); elsewhere the
    /// build's own code with blocks of 8. Each ray does the same IEEE operations in the same
    /// order in both, so the results are bitwise equal (test `wide_kernel_bitwise`).
    fn sweep_slabs(
        &self,
        i: usize,
        u_src: &[T],
        slice: (usize, usize),
        st: &mut RayState<T>,
        g: &mut [T],
        paper: Option<&mut [T]>,
    ) {
        #[cfg(target_arch = "x86_64")]
        if self.wide && is_f32::<T>() && std::arch::is_x86_feature_detected!("avx512f") {
            // SAFETY: the CPU has AVX-512F, checked just above.
            #[allow(unsafe_code)]
            unsafe {
                self.sweep_slabs_avx512(i, u_src, slice, st, g, paper)
            };
            return;
        }
        self.sweep_slabs_with::<LANES>(i, u_src, slice, st, g, paper);
    }

    /// [`Self::sweep_slabs`] compiled for AVX-512F, blocks of [`WIDE_LANES`].
    ///
    /// # Safety
    /// The CPU must have AVX-512F.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    #[allow(unsafe_code)]
    unsafe fn sweep_slabs_avx512(
        &self,
        i: usize,
        u_src: &[T],
        slice: (usize, usize),
        st: &mut RayState<T>,
        g: &mut [T],
        paper: Option<&mut [T]>,
    ) {
        self.sweep_slabs_with::<WIDE_LANES>(i, u_src, slice, st, g, paper);
    }

    /// [`Self::sweep_slabs`] with f32 blocks of `L` rays.
    #[inline(always)]
    fn sweep_slabs_with<const L: usize>(
        &self,
        i: usize,
        u_src: &[T],
        (z0, z1): (usize, usize),
        st: &mut RayState<T>,
        g: &mut [T],
        mut paper: Option<&mut [T]>,
    ) {
        let dir = &self.dirs.dirs[i];
        let (a, sign) = dir.axis();
        let (b, c) = lateral_axes(a);
        let n = self.grid.n;
        let (na, nb, nc) = (n[a], n[b], n[c]);
        let ((sigma_t, sigma_s), strides) = self.sweep_media(a);
        let (sa, sb, sc) = (strides[a], strides[b], strides[c]);
        debug_assert_eq!(sb, 1, "rows run along memory");
        let scale = self.grid.dl * self.path_factor(i);
        let reentry = match self.config.wrap {
            WrapBc::Zero => Some(T::zero()),
            WrapBc::Open => Some(T::c(st.l0)),
            WrapBc::Periodic => None,
        };
        let ts = series_threshold::<T>();
        let ray = &mut st.ray;
        let tally = &mut st.tally;
        let table = &self.tables[i];
        let mut prev = st.prev;
        let paper_deposit = self.config.formulas.deposit == Deposit::Paper;
        for z in z0..z1 {
            let slab = if sign > 0 { z } else { na - 1 - z };
            let tz = (z - z0) * nb * nc;
            for seg in table.slab(z) {
                let oc = seg.offset[1].rem_euclid(nc as i64) as usize;
                let db = seg.offset[0] - prev[0];
                let wc = seg.offset[1] != prev[1];
                // The rays are stored by the voxel column they are in (see `RayState`): when
                // the lattice moves along b, every row rotates with it.
                if db != 0 {
                    let k = db.rem_euclid(nb as i64) as usize;
                    for row in ray.chunks_exact_mut(nb) {
                        row.rotate_right(k);
                    }
                }
                if let Some(re) = reentry {
                    // Rays that just crossed a side face leave (A) and re-enter (B), Fig 2.
                    let mut xb = usize::MAX;
                    if db != 0 {
                        xb = if db > 0 { 0 } else { nb - 1 };
                        for s in 0..nc {
                            let l = &mut ray[xb + nb * s];
                            tally.exited += l.f();
                            *l = re;
                            tally.injected += re.f();
                        }
                    }
                    if wc {
                        let yc = if seg.offset[1] > prev[1] { 0 } else { nc - 1 };
                        let s = (yc + nc - oc) % nc;
                        for x in (0..nb).filter(|&x| x != xb) {
                            let l = &mut ray[x + nb * s];
                            tally.exited += l.f();
                            *l = re;
                            tally.injected += re.f();
                        }
                    }
                }
                prev = seg.offset;
                let len = T::c(seg.len * scale);
                for yc in 0..nc {
                    let s = (yc + nc - oc) % nc;
                    let run = &mut ray[nb * s..nb * (s + 1)];
                    let v0 = slab * sa + yc * sc;
                    let t0 = tz + yc * nb;
                    let w = nb;
                    if let (true, Some(p)) = (paper_deposit, paper.as_deref_mut()) {
                        let ss = &sigma_s[v0..v0 + w];
                        for ((l, p), &ss) in run.iter().zip(&mut p[t0..t0 + w]).zip(ss) {
                            *p = *p - *l * (-(ss * len)).exp_m1();
                        }
                    }
                    // The lateral stride is 1 in every layout (asserted above) and the rays
                    // are stored by column, so a row is four whole contiguous slices: no
                    // bounds checks, no split at the wrap, vectorisable.
                    transport_row::<T, L>(
                        run,
                        &u_src[v0..v0 + w],
                        &sigma_t[v0..v0 + w],
                        &mut g[t0..t0 + w],
                        len,
                        ts,
                    );
                }
            }
        }
        st.prev = prev;
    }

    /// The grid voxel of slice-layout index `l` of a slice starting at sweep step `z0` of
    /// face `face` (the inverse of the layout of [`Self::sweep_slabs`]).
    fn slice_voxel(&self, face: usize, z0: usize, l: usize) -> usize {
        let n = self.grid.n;
        let a = face / 2;
        let (b, c) = lateral_axes(a);
        let (nb, nc) = (n[b], n[c]);
        let z = z0 + l / (nb * nc);
        let mut xyz = [0usize; 3];
        xyz[a] = if face % 2 == 0 { z } else { n[a] - 1 - z };
        xyz[b] = l % nb;
        xyz[c] = (l / nb) % nc;
        self.grid.index(xyz[0], xyz[1], xyz[2])
    }

    /// One unstreamed order-0 sweep of direction `i` with boundary radiance `l_bc` and no
    /// source: (final ray state, T per grid voxel).
    fn sweep_whole(&self, i: usize, l_bc: f64) -> (RayState<T>, Vec<T>) {
        let face = self.dirs.dirs[i].face;
        let na = self.grid.n[face / 2];
        let nv = self.grid.len();
        let zero = vec![T::zero(); nv];
        let mut g = vec![T::zero(); nv];
        let mut st = self.start_rays(i, l_bc, 0);
        self.sweep_slabs(i, &zero, (0, na), &mut st, &mut g, None);
        let mut out = vec![T::zero(); nv];
        for (l, &x) in g.iter().enumerate() {
            out[self.slice_voxel(face, 0, l)] = x;
        }
        (st, out)
    }

    /// The radiances leaving the far face of direction `i` in a single order-0 sweep with
    /// boundary radiance `l_bc` and no source (test T4), in lattice order.
    pub fn exit_radiance(&self, i: usize, l_bc: f64) -> Vec<T> {
        let st = self.sweep_whole(i, l_bc).0;
        let (b, _) = lateral_axes(self.dirs.dirs[i].face / 2);
        let nb = self.grid.n[b];
        // Stored by column: lattice ray r of a row is in column (r + o_b) mod n_b.
        let ob = st.prev[0].rem_euclid(nb as i64) as usize;
        let mut ray = st.ray;
        for row in ray.chunks_exact_mut(nb) {
            row.rotate_left(ob);
        }
        ray
    }

    /// Σ A·∫L ds per voxel for direction `i` divided by h³, in one order-0 sweep of a unit
    /// boundary radiance: the track volume / h³ of T3 when σt = 0.
    pub fn track_volume(&self, i: usize) -> Vec<f64> {
        let g = self.sweep_whole(i, 1.0).1;
        let w = self.area(i) / self.grid.dl.powi(3);
        g.iter().map(|x| x.f() * w).collect()
    }

    /// Runs the scattering orders (Jacobi by order, LPM Alg 2 with D1, D2, D16) with the
    /// boundary radiance `boundary`. `observer(order, unshot / unshot after order 0)` sees
    /// every order.
    pub fn solve(
        &self,
        boundary: &BoundaryLight,
        mut observer: impl FnMut(usize, f64),
    ) -> Result<LpmSolution<T>, SolverError> {
        boundary.check(&self.dirs)?;
        let start = std::time::Instant::now();
        let nv = self.grid.len();
        let per = self.dirs.per_face();
        let d_i = self.config.storage_i.count();
        let mut orders = super::OrderLoop::new(self.config.orders);
        let paper = self.config.formulas.deposit == Deposit::Paper;
        let mut u_prev: Vec<Vec<T>> = (0..CONES).map(|_| self.source.clone()).collect();
        let mut u_cur: Vec<Vec<T>> = (0..CONES).map(|_| vec![T::zero(); nv]).collect();
        let mut intensity: Vec<Vec<T>> = (0..d_i).map(|_| self.source.clone()).collect();
        // T (and the paper's deposit) of one slice per direction of the LPM (D16, D19).
        let slice = super::slice_voxels(&self.grid, self.slabs) as usize;
        let mut lanes: Vec<Lane<T>> = (0..per)
            .map(|_| Lane {
                g: vec![T::zero(); slice],
                p: if paper {
                    vec![T::zero(); slice]
                } else {
                    Vec::new()
                },
                rays: None,
            })
            .collect();
        let mut phi = vec![T::zero(); nv];
        let mut phi_orders: Vec<Vec<T>> = Vec::new();
        // The x faces' unshot U in their layout, then the scratch of the transposes back
        // (transient: the formula's `rays` counts it).
        let mut xbuf = vec![T::zero(); nv];
        let h3 = self.grid.dl.powi(3);
        let n = self.grid.n;
        for order in 0..orders.max_orders {
            for u in &mut u_cur {
                u.par_iter_mut().for_each(|x| *x = T::zero());
            }
            let mut phi_p = vec![T::zero(); nv];
            let mut tally = OrderTally::default();
            // The x faces (0 and 1, the first two) collect into the outputs in their layout
            // (see `collect`): I holds earlier orders, so it goes there first; everything
            // goes back after face 1. Transposes are exact, so per voxel the arithmetic is
            // that of collecting in the grid layout.
            for b in &mut intensity {
                to_x_layout_into(&self.grid, b, &mut xbuf);
                std::mem::swap(b, &mut xbuf);
            }
            for face in 0..6 {
                let u_global = &u_prev[face];
                let sum_u = ordered_sum(u_global);
                if face / 2 == 0 {
                    to_x_layout_into(&self.grid, u_global, &mut xbuf);
                }
                let u_src: &[T] = if face / 2 == 0 { &xbuf } else { u_global };
                let dirs0 = face * per;
                let na = n[face / 2];
                let step = self.slabs.min(na);
                for (k, lane) in lanes.iter_mut().enumerate() {
                    let i = dirs0 + k;
                    lane.rays = Some(self.start_rays(i, boundary.radiance[i], order));
                }
                // The collect's (deposited, absorbed) per (sweep step, chunk), folded in that
                // order after the face: the tallies do not depend on the slicing either.
                let mut parts = vec![(0.0f64, 0.0f64); na * collect_chunks(face, &self.grid)];
                for z0 in (0..na).step_by(step) {
                    let z1 = (z0 + step).min(na);
                    let len = (z1 - z0) * self.grid.len() / na;
                    lanes.par_iter_mut().enumerate().for_each(|(k, lane)| {
                        let Lane { g, p, rays } = lane;
                        g[..len].fill(T::zero());
                        let p = if paper {
                            p[..len].fill(T::zero());
                            Some(&mut p[..len])
                        } else {
                            None
                        };
                        if let Some(st) = rays.as_mut() {
                            self.sweep_slabs(dirs0 + k, u_src, (z0, z1), st, &mut g[..len], p);
                        }
                    });
                    self.collect(
                        face,
                        (z0, z1),
                        &lanes,
                        (&mut u_cur, &mut intensity, &mut phi_p),
                        &mut parts,
                    );
                }
                for (k, lane) in lanes.iter_mut().enumerate() {
                    let Some(st) = lane.rays.take() else { continue };
                    let exited = st.tally.exited + st.ray.iter().map(|l| l.f()).sum::<f64>();
                    let i = dirs0 + k;
                    let w = self.area(i) * self.dirs.dirs[i].solid_angle;
                    tally.injected += w * st.tally.injected;
                    tally.exited += w * exited;
                    tally.emitted +=
                        w * self.grid.dl * self.path_factor(i) / self.dirs.dirs[i].cos_axis * sum_u;
                }
                let (dep, abs) = parts
                    .iter()
                    .fold((0.0, 0.0), |acc, p| (acc.0 + p.0, acc.1 + p.1));
                tally.scattered += dep * h3;
                tally.absorbed += abs * h3;
                if face == 1 {
                    let outputs = u_cur.iter_mut().chain(&mut intensity);
                    for b in outputs.chain(std::iter::once(&mut phi_p)) {
                        from_x_layout(&self.grid, b, &mut xbuf);
                        std::mem::swap(b, &mut xbuf);
                    }
                }
            }
            std::mem::swap(&mut u_prev, &mut u_cur);
            phi.par_iter_mut()
                .zip(&phi_p)
                .for_each(|(t, p)| *t = *t + *p);
            if self.config.keep_orders {
                phi_orders.push(phi_p);
            }
            if orders.finish(order, tally, &mut observer) {
                break;
            }
        }
        let capacity = |v: &[Vec<T>]| v.iter().map(|b| b.capacity()).sum::<usize>();
        let allocated = capacity(&u_prev)
            + capacity(&u_cur)
            + capacity(&intensity)
            + lanes
                .iter()
                .map(|l| l.g.capacity() + l.p.capacity())
                .sum::<usize>()
            + phi.capacity()
            + capacity(&phi_orders)
            + self.sigma_t.capacity()
            + self.sigma_s.capacity()
            + self.sigma_t_x.capacity()
            + self.sigma_s_x.capacity()
            + self.source.capacity();
        let memory = Memory {
            formula: self.memory_formula(),
            resident_measured: (allocated * std::mem::size_of::<T>()) as u64
                + super::table_bytes(&self.tables),
            slabs: self.slabs,
        };
        Ok(LpmSolution {
            grid: self.grid,
            intensity,
            unshot: u_prev,
            phi,
            phi_orders,
            orders: orders.tallies.len(),
            tallies: orders.tallies,
            stop: orders.stop,
            seconds: start.elapsed().as_secs_f64(),
            memory,
        })
    }

    /// The collect step of LPM Eq 4 for the m² directions of `face` over the slice of sweep
    /// steps `z0..z1` (T in `lanes`, slice layout): U^{d′} and I get A·F^{i,d′}·T^i/(h³|Ω^{d′}|),
    /// the order's fluence Σ_i |Ω^i|A∫L ds/h³. The deposited Σ_d′ ΔU^{d′}|Ω^{d′}| and the
    /// absorbed σa Δφ (both per h³) go to `parts`, one sum per (sweep step, chunk) of
    /// [`collect_chunks`], over the step's voxels in slice order.
    ///
    /// The outputs are in the x faces' layout ([`to_x_layout`]) for the x faces, in the
    /// grid layout otherwise, so that T and the outputs run along memory together: tasks own
    /// an x plane (x faces), a chunk of [`COLLECT_PLANES`] z planes (y faces: T is contiguous
    /// over the chunk's rows within a slab) or a z plane (z faces), and take their slabs'
    /// runs in sweep order. Reading the x faces' T along x instead (stride n_y·n_z) made the
    /// collect 33 % of a 64³ RGB solve; writing their outputs with stride n_x cost the x
    /// faces' collect 1.7× the z faces' (A/B at 128³).
    ///
    /// Per voxel the sum over the directions runs k = 0, 1, … from zero whatever the slicing,
    /// so the fields are bitwise those of the unstreamed solve (T16); the tallies too, since
    /// the parts are fixed by the grid and folded in a fixed order.
    fn collect(
        &self,
        face: usize,
        (z0, z1): (usize, usize),
        lanes: &[Lane<T>],
        (u_cur, intensity, phi_p): (&mut [Vec<T>], &mut [Vec<T>], &mut [T]),
        parts: &mut [(f64, f64)],
    ) {
        let per = self.dirs.per_face();
        let paper = self.config.formulas.deposit == Deposit::Paper;
        let (wphi, wu): (Vec<T>, Vec<[T; CONES]>) = (0..per)
            .map(|k| {
                let w = super::collect_weights(
                    &self.grid,
                    &self.config.formulas,
                    &self.dirs,
                    &self.phase,
                    face * per + k,
                );
                (T::c(w.0), w.1.map(T::c))
            })
            .unzip();
        let d_i = intensity.len();
        let [nx, ny, nz] = self.grid.n;
        let a = face / 2;
        let forward = face % 2 == 0;
        let na = self.grid.n[a];
        // The slice's slabs [lo, hi) in grid coordinates of axis a; grid slab g is the
        // slice's sweep step `local(g)`.
        let (lo, hi) = if forward {
            (z0, z1)
        } else {
            (na - z1, na - z0)
        };
        let local = |g: usize| if forward { g - z0 } else { na - 1 - g - z0 };
        // Each task's output slices (6 U, D_I of I, φ^p), as chunks of `chunk` voxels of the
        // output layout: x planes (x faces), COLLECT_PLANES z planes (y), z planes (z).
        let chunk = match a {
            0 => ny * nz,
            1 => nx * ny * COLLECT_PLANES,
            _ => nx * ny,
        };
        let mut iters: Vec<std::slice::ChunksMut<'_, T>> = u_cur
            .iter_mut()
            .chain(intensity.iter_mut())
            .map(|b| b.chunks_mut(chunk))
            .collect();
        iters.push(phi_p.chunks_mut(chunk));
        // The x and z faces' planes go out in pieces of ≤ COLLECT_PIECE voxels (a slice of
        // S slabs is S planes: S tasks alone would leave a core idle at odd S).
        let piece = if a == 1 {
            chunk
        } else {
            COLLECT_PIECE.min(chunk)
        };
        let mut tasks = Vec::new();
        for ci in 0.. {
            let sl: Vec<&mut [T]> = iters.iter_mut().filter_map(|it| it.next()).collect();
            if sl.is_empty() {
                break;
            }
            if a == 1 || (lo..hi).contains(&ci) {
                let mut parts: Vec<std::slice::ChunksMut<'_, T>> =
                    sl.into_iter().map(|b| b.chunks_mut(piece)).collect();
                for pi in 0.. {
                    let sub: Vec<&mut [T]> = parts.iter_mut().filter_map(|it| it.next()).collect();
                    if sub.is_empty() {
                        break;
                    }
                    tasks.push((ci, pi, sub));
                }
            }
        }
        let (sigma_t_x, sigma_s_x) = (&self.sigma_t_x[..], &self.sigma_s_x[..]);
        let ctx = CollectCtx {
            lanes,
            wu: &wu,
            wphi: &wphi,
            paper,
            d_i,
            wide: self.wide,
            // The isotropic coarse F is |Ω^i||Ω^{d′}|/4π exactly and every cone has
            // |Ω^{d′}| = 4π/6 (`PhaseMatrix::new`), so w_{k,d′} = w_φ,k/4π.
            iso: (self.config.phase == Phase::Isotropic).then(|| T::c(1.0 / (4.0 * PI))),
        };
        let nchunks = collect_chunks(face, &self.grid);
        let done: Vec<Vec<(usize, (f64, f64))>> = tasks
            .into_par_iter()
            .map(|(ci, pi, mut sl)| {
                let len = sl[0].len();
                let m0 = chunk * ci + piece * pi;
                let media = if a == 0 {
                    (&sigma_t_x[m0..m0 + len], &sigma_s_x[m0..m0 + len])
                } else {
                    (&self.sigma_t[m0..m0 + len], &self.sigma_s[m0..m0 + len])
                };
                // (part index, run) per slab of the slice the task meets, in sweep order.
                let runs: Vec<(usize, Run)> = match a {
                    0 => vec![(
                        (z0 + local(ci)) * nchunks + pi,
                        Run {
                            t0: ny * nz * local(ci) + piece * pi,
                            len,
                            nb: len,
                            o: [1, 0, 0],
                        },
                    )],
                    1 => {
                        let planes = len / (nx * ny);
                        (0..hi - lo)
                            .map(|s| {
                                let g = if forward { lo + s } else { hi - 1 - s };
                                let run = Run {
                                    t0: nx * (COLLECT_PLANES * ci + nz * s),
                                    len: nx * planes,
                                    nb: nx,
                                    o: [1, nx * ny, nx * g],
                                };
                                ((z0 + s) * nchunks + ci, run)
                            })
                            .collect()
                    }
                    _ => vec![(
                        (z0 + local(ci)) * nchunks + pi,
                        Run {
                            t0: nx * ny * local(ci) + piece * pi,
                            len,
                            nb: len,
                            o: [1, 0, 0],
                        },
                    )],
                };
                runs.into_iter()
                    .map(|(key, run)| (key, ctx.run(&run, &mut sl, media)))
                    .collect()
            })
            .collect();
        for (key, part) in done.into_iter().flatten() {
            parts[key] = part;
        }
    }
}

/// Chunks per sweep step of [`CpuLpm::collect`]'s parts on `face`: the y faces' tasks each
/// take COLLECT_PLANES z planes of a slab, the others a piece of ≤ [`COLLECT_PIECE`] voxels
/// of a slab.
fn collect_chunks(face: usize, grid: &Grid) -> usize {
    let [nx, ny, nz] = grid.n;
    match face / 2 {
        0 => (ny * nz).div_ceil(COLLECT_PIECE),
        1 => nz.div_ceil(COLLECT_PLANES),
        _ => (nx * ny).div_ceil(COLLECT_PIECE),
    }
}

/// Voxels per task of the x and z faces' collect (a plane is cut into pieces of this size).
const COLLECT_PIECE: usize = 4096;

/// z planes per task of the y faces' collect: their T is contiguous over the chunk's rows
/// within a slab, so the m² T streams run COLLECT_PLANES rows before they jump (a task per
/// plane, a jump per row, made the collect latency-bound).
const COLLECT_PLANES: usize = 4;

/// One slab's range of the collect: `len` T entries contiguous from `t0`; entry j is the
/// lateral (b, c) = (j mod `nb`, j div `nb`), at output index o₀b + o₁c + o₂ of the task's
/// chunk (and its medium).
struct Run {
    t0: usize,
    len: usize,
    nb: usize,
    o: [usize; 3],
}

/// Lanes of the collect's tally partial sums (voxel j of a run goes to lane j mod 16,
/// whatever the vector width, so the tallies do not depend on it).
const TALLY_LANES: usize = 16;

/// What [`CollectCtx::run`] reads besides the run: a face's T (and the paper's deposit)
/// per direction, the weights A·F/(h³|Ω^{d′}|) per direction and cone and A|Ω^i|/h³ per
/// direction, D_I and whether the AVX-512 kernel may run.
struct CollectCtx<'a, T> {
    lanes: &'a [Lane<T>],
    wu: &'a [[T; CONES]],
    wphi: &'a [T],
    paper: bool,
    d_i: usize,
    wide: bool,
    /// c with w_{k,d′} = c·w_φ,k for every k and d′ (the isotropic phase: c = 1/4π), if so.
    iso: Option<T>,
}

impl<T: Real> CollectCtx<'_, T> {
    /// The collect of one run into a task's outputs `sl` (six U cones, the D_I buffers of
    /// I, φ^p) with its medium (σt, σs): the run's (deposited, absorbed) sums. In f32 on a
    /// CPU with AVX-512F (and [`CpuLpm::wide`]) compiled for it, with blocks of
    /// [`WIDE_LANES`] voxels; elsewhere blocks of [`LANES`]. Per voxel the same operations
    /// in the same order either way, and the same sums.
    fn run(&self, run: &Run, sl: &mut [&mut [T]], media: (&[T], &[T])) -> (f64, f64) {
        #[cfg(target_arch = "x86_64")]
        if self.wide && is_f32::<T>() && std::arch::is_x86_feature_detected!("avx512f") {
            // SAFETY: the CPU has AVX-512F, checked just above.
            #[allow(unsafe_code)]
            return unsafe { self.run_avx512(run, sl, media) };
        }
        self.run_with::<LANES>(run, sl, media)
    }

    /// [`Self::run`] compiled for AVX-512F.
    ///
    /// # Safety
    /// The CPU must have AVX-512F.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    #[allow(unsafe_code)]
    unsafe fn run_avx512(&self, run: &Run, sl: &mut [&mut [T]], media: (&[T], &[T])) -> (f64, f64) {
        self.run_with::<WIDE_LANES>(run, sl, media)
    }

    /// [`Self::run`] in blocks of `L` voxels.
    #[inline(always)]
    fn run_with<const L: usize>(
        &self,
        run: &Run,
        sl: &mut [&mut [T]],
        media: (&[T], &[T]),
    ) -> (f64, f64) {
        let mut sums = ([0.0f64; TALLY_LANES], [0.0f64; TALLY_LANES]);
        for j0 in (0..run.len).step_by(L) {
            self.block::<L>(run, j0, sl, media, &mut sums);
        }
        let fold = |v: &[f64]| v.iter().fold(0.0, |a, &x| a + x);
        (fold(&sums.0), fold(&sums.1))
    }

    /// The collect of the ≤ `L` entries of `run` from `j0`: the seven sums (six cones and
    /// φ) of the block are `L`-lane registers while the m² directions' T stream past
    /// (direction-inner: per voxel k = 0, 1, … in order, each a fused a + w·T); then each
    /// voxel's outputs, and its deposited and absorbed power added to the tally lane of its
    /// run position. A block on one contiguous stretch of outputs writes them as vectors,
    /// others voxel by voxel (same operations); a last partial block is padded with zeros.
    // One index addresses the sums and every output slice at once.
    #[allow(clippy::needless_range_loop)]
    #[inline(always)]
    fn block<const L: usize>(
        &self,
        run: &Run,
        j0: usize,
        sl: &mut [&mut [T]],
        (st, ss): (&[T], &[T]),
        (deps, abss): &mut ([f64; TALLY_LANES], [f64; TALLY_LANES]),
    ) {
        let w = L.min(run.len - j0);
        let t = run.t0 + j0;
        let mut acc = [[T::zero(); L]; CONES];
        let mut fls = [T::zero(); L];
        if let Some(c) = self.iso {
            // Isotropic: w_{k,d′} = c·w_φ,k, so every cone gets c·Σ_k w_φ,k X_k (one sum,
            // and the φ sum is it when X = T).
            let mut xs = [T::zero(); L];
            for (k, lane) in self.lanes.iter().enumerate() {
                let wk = self.wphi[k];
                let (mut gk, mut xk) = ([T::zero(); L], [T::zero(); L]);
                gk[..w].copy_from_slice(&lane.g[t..t + w]);
                for j in 0..L {
                    fls[j] = fmadd(wk, gk[j], fls[j]);
                }
                if self.paper {
                    xk[..w].copy_from_slice(&lane.p[t..t + w]);
                    for j in 0..L {
                        xs[j] = fmadd(wk, xk[j], xs[j]);
                    }
                }
            }
            let x = if self.paper { xs } else { fls };
            for a in &mut acc {
                for j in 0..L {
                    a[j] = c * x[j];
                }
            }
        } else {
            for (k, lane) in self.lanes.iter().enumerate() {
                let src = if self.paper { &lane.p } else { &lane.g };
                if w == L {
                    accumulate::<T, L>(
                        &lane.g[t..t + L],
                        &src[t..t + L],
                        (self.wphi[k], &self.wu[k]),
                        &mut fls,
                        &mut acc,
                    );
                } else {
                    let (mut gk, mut xk) = ([T::zero(); L], [T::zero(); L]);
                    gk[..w].copy_from_slice(&lane.g[t..t + w]);
                    xk[..w].copy_from_slice(&src[t..t + w]);
                    let wk = (self.wphi[k], &self.wu[k]);
                    accumulate::<T, L>(&gk, &xk, wk, &mut fls, &mut acc);
                }
            }
        }
        let sixth = T::c(1.0 / 6.0);
        let d_i = self.d_i;
        let (b0, c0) = (j0 % run.nb, j0 / run.nb);
        let lane0 = j0 % TALLY_LANES;
        let o0 = run.o[0] * b0 + run.o[1] * c0 + run.o[2];
        if w == L && run.o[0] == 1 && b0 + L <= run.nb {
            // One contiguous stretch: vector loads and stores.
            let s = &ss[o0..o0 + L];
            let mut total = [T::zero(); L];
            for d in 0..CONES {
                let mut du = acc[d];
                if !self.paper {
                    for j in 0..L {
                        du[j] = s[j] * du[j];
                    }
                }
                add_to(&mut sl[d][o0..o0 + L], &du);
                if d_i == CONES {
                    add_to(&mut sl[CONES + d][o0..o0 + L], &du);
                }
                for j in 0..L {
                    total[j] = total[j] + du[j];
                }
            }
            if d_i == 1 {
                let mut t6 = total;
                for t in &mut t6 {
                    *t = *t * sixth;
                }
                add_to(&mut sl[CONES][o0..o0 + L], &t6);
            }
            add_to(&mut sl[CONES + d_i][o0..o0 + L], &fls);
            for j in 0..L {
                let q = (lane0 + j) % TALLY_LANES;
                deps[q] += total[j].f() * CONE_SOLID_ANGLE;
                abss[q] += (st[o0 + j] - s[j]).f() * fls[j].f();
            }
            return;
        }
        let (mut b, mut c) = (b0, c0);
        for j in 0..w {
            let o = run.o[0] * b + run.o[1] * c + run.o[2];
            let fl = fls[j];
            let s = ss[o];
            let mut total = T::zero();
            for d in 0..CONES {
                let du = if self.paper { acc[d][j] } else { s * acc[d][j] };
                sl[d][o] = sl[d][o] + du;
                if d_i == CONES {
                    sl[CONES + d][o] = sl[CONES + d][o] + du;
                }
                total = total + du;
            }
            if d_i == 1 {
                sl[CONES][o] = sl[CONES][o] + total * sixth;
            }
            sl[CONES + d_i][o] = sl[CONES + d_i][o] + fl;
            let q = (lane0 + j) % TALLY_LANES;
            deps[q] += total.f() * CONE_SOLID_ANGLE;
            abss[q] += (st[o] - s).f() * fl.f();
            b += 1;
            if b == run.nb {
                b = 0;
                c += 1;
            }
        }
    }
}

/// `out[j] += x[j]` over `L` values.
#[inline(always)]
fn add_to<T: Real, const L: usize>(out: &mut [T], x: &[T; L]) {
    for (o, &x) in out[..L].iter_mut().zip(x) {
        *o = *o + x;
    }
}

/// One direction's share of a collect block: φ += w_φ·T and, per cone d, U_d += w_d·X (X = T,
/// or the paper's deposit), over `L` voxels, fused ([`fmadd`]).
#[inline(always)]
fn accumulate<T: Real, const L: usize>(
    g: &[T],
    src: &[T],
    (wphi, wu): (T, &[T; CONES]),
    fls: &mut [T; L],
    acc: &mut [[T; L]; CONES],
) {
    let (g, src) = (&g[..L], &src[..L]);
    for j in 0..L {
        fls[j] = fmadd(wphi, g[j], fls[j]);
    }
    for (a, &w) in acc.iter_mut().zip(wu) {
        for j in 0..L {
            a[j] = fmadd(w, src[j], a[j]);
        }
    }
}

/// `field` (x fastest) in the x-faces' layout y + n_y(z + n_z x), where the sweep axis x is
/// slowest and the first lateral axis y contiguous.
pub fn to_x_layout<T: Copy + Default + Send + Sync>(grid: &Grid, field: &[T]) -> Vec<T> {
    let mut out = vec![T::default(); field.len()];
    to_x_layout_into(grid, field, &mut out);
    out
}

/// [`to_x_layout`] into `out`: tiled transposes of the n_x × n_y planes (the mirror of
/// [`from_x_layout`]), in parallel over groups of `TILE` x planes of `out`.
pub fn to_x_layout_into<T: Copy + Send + Sync>(grid: &Grid, field: &[T], out: &mut [T]) {
    let [nx, ny, nz] = grid.n;
    let sx = ny * nz; // out's stride of x
    out[..nx * sx]
        .par_chunks_mut(TILE * sx)
        .enumerate()
        .for_each(|(xt, out)| {
            let x0 = xt * TILE;
            let x1 = (x0 + TILE).min(nx);
            for z in 0..nz {
                for y0 in (0..ny).step_by(TILE) {
                    let by = TILE.min(ny - y0);
                    for x in x0..x1 {
                        let dst = &mut out[y0 + ny * z + sx * (x - x0)..][..by];
                        let src = field[x + nx * (y0 + ny * z)..].iter().step_by(nx);
                        for (o, &v) in dst.iter_mut().zip(src) {
                            *o = v;
                        }
                    }
                }
            }
        });
}

/// The inverse of [`to_x_layout`], into `out`: per z a transpose of the n_x × n_y plane in
/// tiles of `TILE`², contiguous reads and writes of stride n_x (the plain triple loop,
/// with a bounds check per word, was 12 % of a 64³ solve's profile, the tiles 6 %), in
/// parallel over the z planes.
pub fn from_x_layout<T: Copy + Send + Sync>(grid: &Grid, local: &[T], out: &mut [T]) {
    let [nx, ny, nz] = grid.n;
    let sx = ny * nz; // local stride of x
    out[..nx * ny * nz]
        .par_chunks_mut(nx * ny)
        .enumerate()
        .for_each(|(z, out)| {
            for x0 in (0..nx).step_by(TILE) {
                for y0 in (0..ny).step_by(TILE) {
                    let by = TILE.min(ny - y0);
                    for x in x0..(x0 + TILE).min(nx) {
                        let src = &local[y0 + ny * z + sx * x..][..by];
                        let dst = out[x + nx * y0..].iter_mut().step_by(nx);
                        for (o, &v) in dst.zip(src) {
                            *o = v;
                        }
                    }
                }
            }
        });
}

/// Σ x in f64, in parallel: sums of fixed chunks of 2¹⁴ values folded in order, so the
/// result does not depend on the thread count.
fn ordered_sum<T: Real>(v: &[T]) -> f64 {
    let parts: Vec<f64> = v
        .par_chunks(1 << 14)
        .map(|c| c.iter().map(|x| x.f()).sum::<f64>())
        .collect();
    parts.iter().sum()
}

/// Edge of the tiles of [`from_x_layout`].
const TILE: usize = 16;

impl StorageI {
    /// The number of I buffers: 1 or 6.
    pub fn count(self) -> usize {
        match self {
            StorageI::One => 1,
            StorageI::Six => CONES,
        }
    }
}

#[cfg(test)]
mod fast_exp_tests {
    use super::{exp_neg_f32, from_x_layout, phis, series_threshold, to_x_layout};
    use crate::Grid;

    /// The tiled transpose back from the x-faces' layout inverts [`to_x_layout`] exactly on
    /// grids whose sides are below, at and above multiples of the tile edge (16).
    #[test]
    fn x_layout_round_trip() {
        for n in [
            [3, 3, 3],
            [3, 17, 5],
            [16, 16, 16],
            [33, 7, 18],
            [20, 40, 3],
        ] {
            let grid = Grid::new(n, 0.1).expect("grid");
            let field: Vec<u32> = (0..grid.len() as u32).collect();
            let local = to_x_layout(&grid, &field);
            let [nx, ny, nz] = n;
            for (x, y, z) in [
                (0, 0, 0),
                (nx - 1, ny - 1, nz - 1),
                (nx / 2, ny - 1, nz / 3),
            ] {
                assert_eq!(local[y + ny * (z + nz * x)], field[x + nx * (y + ny * z)]);
            }
            let mut back = vec![u32::MAX; grid.len()];
            from_x_layout(&grid, &local, &mut back);
            assert_eq!(back, field, "{n:?}");
        }
    }

    /// Units in the last place of `want` (f32) between `got` and the f64 value `want`.
    fn ulps(got: f32, want: f64) -> f64 {
        let w = want as f32;
        let ulp = (f32::from_bits(w.to_bits() + 1) - w) as f64;
        (got as f64 - want).abs() / ulp
    }

    /// The f32 e^{−τ} of the vectorised sweep is within 2 ulp of the exact value on τ ∈
    /// [0, 80] (dense: 2·10⁵ points, linear and logarithmic), and tiny and finite beyond.
    /// Measured 0.86 ulp fused, 1.15 unfused.
    #[test]
    fn exp_neg_f32_matches_f64() {
        let mut worst: f64 = 0.0;
        for k in 0..100_000 {
            let lin = 80.0 * k as f64 / 100_000.0;
            let log = 10f64.powf(-8.0 + 9.9 * k as f64 / 100_000.0);
            for tau in [lin, log.min(80.0)] {
                let t = tau as f32;
                worst = worst.max(ulps(exp_neg_f32(t), (-(t as f64)).exp()));
            }
        }
        eprintln!("exp_neg_f32: worst {worst:.2} ulp on [0, 80]");
        assert!(worst <= 2.0, "worst {worst} ulp");
        for tau in [80.0f32, 100.0, 1e3, 1e30, f32::INFINITY] {
            let e = exp_neg_f32(tau);
            assert!(e.is_finite() && (0.0..2e-35).contains(&e), "τ = {tau}: {e}");
        }
    }

    /// The branch-free f32 (E, φ1, φ2) agrees with the f64 libm form for τ from 10⁻⁸ to 10³,
    /// across the series/direct switch at 0.5. Measured (fused kernel): E 4.7·10⁻⁸
    /// absolute, φ1 1.6·10⁻⁷ and φ2 3.4·10⁻⁷ relative (unfused: 6.3·10⁻⁸, 1.6·10⁻⁷,
    /// 3.7·10⁻⁷; φ2's direct form cancels just above the switch: τ − 1 + E = 0.107 at
    /// τ = 0.5); bounds 3·10⁻⁷, 3·10⁻⁷, 10⁻⁶.
    #[test]
    fn phis_f32_matches_f64() {
        let (mut we, mut w1, mut w2) = (0.0f64, 0.0f64, 0.0f64);
        for k in 0..=200_000 {
            let t = 10f64.powf(-8.0 + 11.0 * k as f64 / 200_000.0) as f32;
            let (e, f1, f2) = phis(t, series_threshold::<f32>());
            let (e6, f16, f26) = phis(t as f64, series_threshold::<f64>());
            we = we.max((e as f64 - e6).abs());
            w1 = w1.max((f1 as f64 / f16 - 1.0).abs());
            w2 = w2.max((f2 as f64 / f26 - 1.0).abs());
        }
        eprintln!("phis f32 vs f64: E {we:.2e} abs, φ1 {w1:.2e}, φ2 {w2:.2e} rel");
        assert!(we < 3e-7 && w1 < 3e-7 && w2 < 1e-6, "{we:e} {w1:e} {w2:e}");
    }
}
