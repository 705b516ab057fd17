//! Nonlinear full-approximation-scheme (FAS) multigrid for FLD Eq 20 and CDA (FLD Eq 12), a
//! solver strategy next to red-black SOR (FLD Algorithm 1, which stays the reference).
//!
//! With L(φ) = −∇·(D(φ)∇φ) + σa φ discretised as in FLD Eq 32, the FAS coarse problem is
//! L_c(φ_c) = R(j − L(φ)) + L_c(R̂φ), and φ ← φ + P(φ_c − R̂φ) (Brandt's FAS).
//!
//! * **Smoother:** the red-black sweep of FLD Algorithm 1 itself ([`CpuFld`], same arithmetic,
//!   floors σ_ε and ε, θ-relaxed D update and projection φ ≥ 0), over-relaxed at ω = 1.2
//!   ([`MgConfig::smoother_omega`]; Gauss–Seidel, ω = 1, until 2026-12-07: next decisions).
//! * **Levels (per axis, see `Axis`).** The Dirichlet values sit at the layer voxels'
//!   centres, so the m interior unknowns of an axis are nodes 1..m between boundary nodes 0
//!   and m + 1. With m odd the axis is coarsened vertex-wise (coarse node c = fine node 2c,
//!   the coarse layer on the fine one, m → (m − 1)/2); with m even cell-wise (coarse voxel
//!   c covers fine 2c − 1, 2c, m → m/2, the coarse layer half a fine voxel outside). The
//!   coarse medium keeps ∫σa (full weighting ¼, ½, ¼ on vertex axes, the mean of the two
//!   children on cell axes); the σ of its diffusion coefficient is the harmonic mean of the
//!   children's (floored) σ with the same weights ([`CoarseSigma`], next decision), and it is
//!   rediscretised with the same floors (σ_ε of the finest grid). **Changed (2026-12-03):** every axis used to be coarsened cell-wise
//!   with coarse voxel I covering fine 2I − 1, 2I; for odd m (every point-source grid) the
//!   last coarse voxel then straddled the Dirichlet layer and the coarse boundary sat 2 fine
//!   voxels from its centre instead of ½, a coarse operator that does not approximate the
//!   fine one near the boundary. Measured (V(2,2), f64, cycles to R̄/j̄ < 10⁻⁶, point source
//!   τ = 10, albedo 0.9): CDA at n = 17, 33, 65 took 6, 8, 13 cycles before and takes 5, 5
//!   (n = 17, 33) with an asymptotic rate of 0.06–0.09 per cycle after; FLD-LP 6, 7, 8
//!   before, 6, 7 after (rate 0.05–0.10); albedo 1: CDA 5, 5, FLD-LP 7, 7
//!   (`tests/fld_multigrid.rs`). At n = 31 and 63 (cell-coarsened second level): CDA 6, 6
//!   (albedo 0.9 and 1; rate 0.11–0.14), FLD-LP 7, 9 (albedo 0.9) and 9, 9 (albedo 1; rate
//!   0.2–0.3): CDA is within the issue's 25 % over n = 17…63, FLD-LP is not (6 → 9). On
//!   the Fig 4 cloud FLD-LP takes 14, 22, 21 cycles at n = 17, 31, 33 and at 63 has not
//!   reached 10⁻⁶ after 40 (7.6·10⁻⁶, rate 0.77): not grid-independent where vacuum is.
//! * **Transfers:** linear prolongation of the correction in node positions (vertex axes
//!   ½, ½; cell axes ¾, ¼; zero correction on the coarse Dirichlet layer); residual
//!   restriction by its adjoint over 8 (full weighting); R̂φ as the medium's restriction.
//! * **D on every level:** before a residual is formed, D = F(R(φ))/σ is recomputed from that
//!   level's φ (FLD Eqs 33–35, one-sided ∇φ on the Dirichlet layer, as the SOR does).
//!
//! ## Decisions where the paper is silent (it names multigrid only as future work)
//! * **Stopping measure.** R̄/j̄ of FLD Eq 37 over the same window as SOR, but evaluated with
//!   D recomputed from the current φ (the residual of the nonlinear equation itself, not of
//!   the lagged D the sweep carries); at SOR's fixed point both coincide.
//! * **Stall.** If 8 consecutive cycles fail to reduce the best residual by 10 %, the solve
//!   stops with [`Stop::Stalled`], never [`Stop::Converged`]; the 95 %-vacuum white-noise
//!   medium that stalls SOR is the case this guards (tested in `tests/fld_multigrid.rs`).
//! * **Coarsest level:** coarsening stops when an axis has fewer than 4 interior voxels; there
//!   up to 200 sweeps run until the sweep residual drops by 10⁻³.
//! * **Cycles: F(2, 2) by default (V(2, 2) until 2026-12-06); V-cycles on request.** One
//!   work unit = one fine sweep; a sweep on level ℓ counts 8^(−ℓ). Measured with the Krylov
//!   acceleration of depth 3 (next decisions; 2-vCPU AMD EPYC 7002, quiet, one run each,
//!   cycles and seconds to R̄/j̄ < 10⁻⁶ incl. setup, V → F): point source CDA n = 127 7
//!   cycles 0.60 s → 5, 0.55 s; 255: 6, 4.6 s → 5, 4.9 s; FLD-LP 127: 16, 2.88 s → 11, 2.43
//!   s; 255: 20, 27.0 s → 13, 19.9 s; Fig 4 cloud CDA 127: 17, 1.21 s → 14, 1.28 s; 255: 22,
//!   11.7 s → 16, 10.6 s; FLD-LP 127: 108, 19.0 s → 54, 11.6 s. Cycles at n = 31, 63, 127
//!   (V → F): point source CDA 6, 6, 7 → 5, 5, 5, FLD-LP 9, 12, 16 → 9, 10, 11; cloud CDA 10,
//!   13, 17 → 10, 12, 14, FLD-LP 17, 34, 108 → 14, 21, 54. An F-cycle costs about 1.3 V-cycles
//!   of coarse work for the same 4 fine sweeps, so fewer, flatter cycles win.
//! * **The smoother's ω: 1.2, over-relaxed red-black ([`MgConfig::smoother_omega`];
//!   2026-12-07, 2-vCPU AMD EPYC Zen 5, 32 MiB L3).** Red-black SOR smooths better than
//!   Gauss–Seidel for some ω slightly above 1 (Yavneh's analysis of red-black relaxation as a
//!   smoother), and a smoother that also damps some smooth error helps where the coarse
//!   correction is weakest, in vacuum. Measured with `multigrid_scaling --smoother-omega ω`
//!   (defaults otherwise: F(2, 2), Krylov depth 3; f64, cycles to R̄/j̄ < 10⁻⁶ at n = 31, 63,
//!   127 for ω = 1, 1.2, 1.3, 1.4, 1.5):
//!   point source CDA 5,5,5 | 5,5,5 | 5,5,5 | 5,5,5 | 7,6,6; FLD-LP 9,10,11 | 8,9,10 |
//!   7,9,10 | 7,8,10 | 7,8,10; Fig 4 cloud CDA 10,12,14 | 8,10,12 | 7,9,11 | 7,9,10 | 7,8,9;
//!   FLD-LP 14,21,54 | 14,20,43 | 13,19,38 | 13,18,36 | 12,17,33; `ball_source` CDA 5,5,5 |
//!   5,4,4 | 4,4,4 | 5,5,5 | 6,6,5; FLD-LP 7,7,8 | 7,7,7 (the rest 7,7,7); `cloud_thin` CDA
//!   8,9,9 | 7,8,9 | 6,7,8 (1.4, 1.5 the same); FLD-LP 11,13,15 | 10,12,14 | 10,11,13 |
//!   9,11,12 | 9,10,12; `cloud_floor` CDA 7,8,8 | 6,7,8 | 6,7,7 | 6,6,7 | 6,7,7; FLD-LP
//!   9,10,12 | 9,9,11 | 8,9,10 (1.4, 1.5 the same). At n = 255 (ω = 1, 1.2, 1.3): point
//!   source CDA 5, 5, 4, FLD-LP 13, 12, 12; cloud CDA 16, 14, 12; `ball_source` CDA 4, 4, 4,
//!   FLD-LP 8, 8, 7; `cloud_thin` CDA 10, 9, 9, FLD-LP 19, 17, 16; `cloud_floor` CDA 9, 8, 8,
//!   FLD-LP 14, 12, 12; but the cloud with FLD-LP, whose count is set by the peak of D
//!   (below), 154, 125, 164 (ω = 1.25: 145, 1.4: 173). ω = 1.2 is the largest ω measured that
//!   needed no more cycles than Gauss–Seidel in any of these 40 runs; 1.3 and above save
//!   more on the vacuum problems but cost the 255³ cloud FLD-LP 164 cycles, and 1.5 costs
//!   the point source CDA one or two (7, 6, 6). The Krylov acceleration still pays with
//!   the over-relaxed smoother (ω = 1.3, depth 0 → 3, n = 31, 63, 127: point source FLD-LP
//!   10,12,13 → 7,9,10; cloud CDA 12,18,24 → 7,9,11; FLD-LP 15,26,100 → 13,19,38), so its
//!   depth stays 3. Nor does the cheaper F(1, 2) pay with it (ω = 1.2, n = 127, an ad-hoc
//!   driver, two alternating runs each): point source CDA 5 cycles either way (19.6 against
//!   26.1 work units) but 0.27–0.28 s to the tolerance against 0.20–0.23 s, FLD-LP 11
//!   against 10 cycles (1.53–1.59 s against 1.43–1.62 s), cloud CDA 13 against 12
//!   (0.59–0.67 s against 0.66–0.67 s), FLD-LP 51 against 43 (6.8–7.2 s against 6.5–7.6 s):
//!   F(2, 2) stays. Seconds (`point_source --n 127 --boundary zero --tolerance 1e-6 --solver
//!   sor,multigrid --limiter cda,lp`, every Fig 5 albedo, one run, a noisy host: SOR's CDA
//!   sweeps took 0.84–1.53 s for 274–284 of them): SOR / multigrid to the tolerance CDA
//!   4.5–5.4× (5 cycles, 4 to the tolerance; 4.1–4.8× with ω = 1 in the last session's run),
//!   FLD-LP 4.0–9.1× (10 cycles; 3.4–6.9× with ω = 1 and 11 cycles); at 255³ CDA 9.4–9.9×
//!   (543–566 sweeps in 13.9–16.2 s against 1.44–1.64 s; 8.1–11.3× with ω = 1), since the
//!   cycles to the tolerance stay 4 there. φ agrees with SOR's to 0.4–3.6·10⁻⁶ relative L2
//!   at both sizes. The GPU runs the same ω (`tests/fld_multigrid_gpu.rs` on lavapipe, ω =
//!   1.2: the 33³ point source and the 24 × 20 × 27 block in 4–6 cycles, the same count as
//!   the CPU-f32 multigrid in all 12 cases, 1.3–12·10⁻⁷ relative L2 apart; FLD-LP on 95 %
//!   vacuum now gets to f32's floor, ≈ 10⁻⁵, where it stalled at 6·10⁻³ with ω = 1).
//!   `over_relaxed_smoothing_cuts_cycles` (`tests/fld_multigrid.rs`) pins the cut: cloud
//!   13 → 10, 30 % vacuum noise 19 → 17, point source CDA 7 → 6, FLD-LP 9 → 8. The committed
//!   `multigrid_scaling` run with ω = 1.2 (quiet host, 211 s against 245 s with ω = 1) took
//!   the 255³ cloud FLD-LP solve to R̄/j̄ < 10⁻⁶ in 125 cycles and 72 s (154 cycles and 93 s
//!   before), and puts SOR / multigrid seconds at 127³ at 4.5× (point source CDA), 3.7×
//!   (FLD-LP), 2.1× (cloud CDA) and 7.8× (cloud FLD-LP), against 4.2×, 3.4×, 1.6× and 5.8×.
//! * **Coarse Dirichlet layer.** On vertex axes it coincides with the fine one (zero
//!   correction is exact); on cell axes it sits half a fine voxel further out and by default
//!   its correction is zero. Extrapolating it linearly to zero at the parent layer's
//!   position ([`MgConfig::extrapolated_layer`], cell axes only) is kept as an option; its
//!   earlier measurement (see there) was made with the old, straddling coarsening.
//! * **Cost per cycle (measured 2026-12-03, 2-core Intel Xeon with AVX-512, idle; f64, V(2,2),
//!   `point_source --n 127 --boundary zero --tolerance 1e-6 --solver sor,multigrid`).** CDA
//!   α = 0.5: SOR 277 iterations 2.17 s (1.87 s in a later run), multigrid 8 cycles (36.6
//!   work units) 1.63 s with the parallel residual, 1.49 s once D is fixed for constant
//!   limiters, 0.96 s with gather tables for the transfers instead of per-voxel allocations
//!   (φ bit-identical throughout: rel. L2 vs SOR 9.0e-7 every time). FLD-LP (measured at
//!   the 1.63 s stage): α = 0.5 SOR 497 it. 23.7 s vs 18 cycles 9.7 s; α = 0.99 SOR 974 it.
//!   47.8 s vs 18 cycles 11.3 s. A CDA cycle still costs ≈ 15–18 SOR sweeps of wall time
//!   (4.6 of them smoothing): the unpack/pack passes, residuals and transfers dominate, so
//!   issue 15's ≥ 10× is not met.
//! * **Cost per cycle, re-measured (2026-12-04, 2-vCPU AMD EPYC, quiet, AVX2 build,
//!   `point_source --n 127 --boundary zero --tolerance 1e-6 --solver sor,multigrid --limiter
//!   cda,lp`, every Fig 5 albedo, one run).** `perf` of the FLD-LP solve put 38 % of the
//!   samples in `fresh_d` (a per-voxel index loop calling `lim.eval`), 22 % in the smoother,
//!   10 % in the smoother's boundary-layer D and 8 % in `apply`; `fresh_d` and `apply` are
//!   now row-sliced with the limiter dispatched once, and the boundary update runs in
//!   parallel with no division: φ and every residual bit-identical (profiles and
//!   `runs.csv` compared byte for byte), FLD-LP multigrid 6.6 → 4.2 s at α = 0.5. SOR vs
//!   multigrid seconds (speed-up) at α = 0.1, 0.3, 0.5, 0.7, 0.9, 0.99: CDA 1.94/0.88
//!   (2.2×), 1.61/0.70 (2.3×), 1.86/0.65 (2.9×), 1.40/0.65 (2.1×), 1.45/0.77 (1.9×),
//!   1.33/0.73 (1.8×), always 8 cycles (36.6 work units vs 274–284 iterations); FLD-LP
//!   18.6/4.54 (4.1×), 10.9/4.44 (2.5×), 11.3/4.19 (2.7×), 13.2/4.47 (2.9×), 15.4/4.23
//!   (3.6×), 21.1/3.72 (5.7×), always 18 cycles (82.3 work units vs 472–974 iterations);
//!   multigrid vs SOR relative L2 1.0–9.6·10⁻⁶ at this tolerance. 255³, α = 0.5: CDA SOR
//!   551 it. 22.1 s vs 8 cycles 6.7 s (3.3×); FLD-LP SOR 2102 it. 312.8 s vs 25 cycles 48.0
//!   s (6.5×). Issue 15's ≥ 10× is **not met**: the work-unit ratio is 7.5–7.8× (CDA) and
//!   5.7–11.8× (FLD-LP) at 127³, 15× and 18× at 255³, so even a free cycle overhead would
//!   not reach 10× for CDA at 127³; a cycle still costs 2.2× (FLD-LP) to 2.6× (CDA) its
//!   smoothing (work units × SOR's seconds per iteration, α = 0.5).
//! * **Where a cycle's time goes (2026-12-06, same 2-vCPU AMD EPYC, quiet; an instrumented
//!   build timing each phase on the finest level, not kept; `point_source --n 127 --boundary
//!   zero --albedo 0.5 --tolerance 1e-6`).** CDA, 8 cycles, 0.59 s: smoothing 0.142 s,
//!   unpacking φ 0.028, in-cycle residual 0.047, R̂φ 0.039, residual restriction 0.033,
//!   prolongation 0.070, coarser levels 0.089, end-of-cycle residual 0.080, error estimate
//!   0.031. FLD-LP, 18 cycles, 3.59 s: smoothing 1.47, the three D-from-φ evaluations per
//!   cycle (in the in-cycle residual, after the prolongation, in the end-of-cycle residual)
//!   0.36 + 0.29 + 0.46 with their passes (one costs about a smoothing sweep: the limiter
//!   dominates both), coarser levels 0.51. The transfers are now separable (one axis at a time
//!   over contiguous rows, `restrict_separable`, `prolong_add`): R̂φ 0.039 → 0.019, residual
//!   restriction 0.033 → 0.021, prolongation 0.070 → 0.020 s (CDA; FLD-LP 0.077 → 0.044,
//!   0.072 → 0.036, 0.156 → 0.047), cycle counts and converged φ unchanged (not
//!   bit-identical: the sums run in another order). One run each, SOR in the same run:
//!   CDA multigrid 0.551 s vs SOR 1.113 s (2.0×), FLD-LP 3.59 s vs 10.22 s (2.8×). Smoothing
//!   alone (36.6 and 82.3 work units at SOR's seconds per iteration) would be 0.147 and 1.69 s,
//!   so even a free cycle overhead leaves CDA at 7.6× and FLD-LP at 6.0× here.
//! * **After the sweep's odd row length and boundary batch (2026-12-06, `fld` module docs;
//!   same 2-vCPU AMD EPYC, one run, `point_source --n 127 --boundary zero --tolerance 1e-6
//!   --solver sor,multigrid --limiter cda,lp --albedo 0.5,0.99`).** SOR vs multigrid seconds:
//!   CDA α = 0.5 1.22 vs 0.50 (2.4×), α = 0.99 1.13 vs 0.51 (2.2×); FLD-LP α = 0.5 8.81 vs
//!   3.31 (2.7×), α = 0.99 17.97 vs 3.19 (5.6×); cycles, work units and φ unchanged (8 and 18
//!   cycles; rel. L2 vs SOR 0.9–3.6·10⁻⁶). `perf` of the CDA solve then put 13–15 % of the
//!   samples in the kernel's page clearing, `memset` and page faults: every cycle allocated
//!   fresh fine-level vectors (φ unpacked, D, L(φ), the residual), 16 MB each at 127³. They
//!   now come from a per-level pool (`Level::pool`; `apply_into`, `fresh_d_into` and
//!   `CpuFld::mg_phi_into` overwrite every value) and the final φ is unpacked alone instead of
//!   with D, σ and the absorption. φ, the residual histories and `profiles.csv` are
//!   byte-identical; the same command, one run: CDA multigrid 0.434 s (α = 0.5) and 0.449 s
//!   (0.99) against SOR 1.27 and 1.20 s (2.9×, 2.7×), FLD-LP 2.89 and 2.95 s against 8.67
//!   and 17.70 s (3.0×, 6.0×). `memset` is gone from the profile; page clearing is down to
//!   8 % of the samples, most of it the setup's first touch of its fields. The coarse
//!   vectors of a visit (R̂φ, the restricted residual and right-hand side, the copy of R̂φ,
//!   the correction) and the restriction's scratch planes were still fresh allocations:
//!   pooled too (2026-12-06), the 255³ point source CDA solve took 437 000 instead of
//!   495 000 page faults (most of the rest is the Krylov history's first touch, 8 fine
//!   vectors) and 2.72–2.79 s instead of 2.82–2.85 s (three runs each, alternating); the
//!   residuals are bit-identical.
//! * **Full multigrid start: tried and rejected (2026-12-06, a build not kept).** Nested
//!   iteration (each level's own problem with f_l = R f_{l−1}, solved from the coarsest up, one
//!   V(2,2) per level, as the first cycle) cut the first cycle's R̄/j̄ only from 2.7–2.8·10⁻²
//!   to 1.7–1.8·10⁻² on the point source (τ = 4, albedo 0.5): cycles to 10⁻⁶ CDA 8 → 7 at n =
//!   31 and 63, FLD-LP 11 → 12 and 15 → 15; Fig 4 cloud FLD-LP 22 → 20 and 49 → 45 (CDA
//!   stalled either way with the arithmetic coarse σ of then), seconds within ±6 %. The interpolated coarse answer carries the fine
//!   grid's discretisation residual (largest at the source), so the start is not what limits;
//!   FLD-LP's rate per cycle (0.3–0.4 at n = 63) is.
//! * **Coarse σ: harmonic, not arithmetic ([`CoarseSigma`]; changed 2026-12-06).** The fine
//!   operator couples voxels through ½(D_p + D_q), an arithmetic mean of D = F/σ, so a vacuum
//!   voxel (D = 1/(3σ_ε), a near-perfect conductor) makes its faces conduct. A coarse voxel
//!   whose σ is the arithmetic mean of its children's (∫σt kept, the first version) loses
//!   that: one vacuum child among medium children gives an ordinary D. With the arithmetic
//!   σ, CDA on the Fig 4 cloud (n = 17, 33) cut the residual ×0.05–0.1 in the first cycle
//!   and then diverged (×2–6 per cycle, ended `Stalled`), and so did CDA on white noise with
//!   30 % or 95 % vacuum and with 10⁴ contrast and no vacuum. With the harmonic σ (the coarse
//!   D of a constant limiter is then the mean of the fine D) CDA converges on all of them to
//!   10⁻⁹ (`tests/fld_multigrid.rs`: cloud 24³ 21 cycles, 30 % vacuum 52, 95 % vacuum 11;
//!   the arithmetic σ on the cloud is pinned to stall there), on the datasets of
//!   `convergence_check` (18³, tolerance 10⁻⁴: nebula stalled at rel. error 0.81 → 6 cycles
//!   and 1.8·10⁻⁸ from SOR's tight solve; emissive_cloud stalled at 0.52 → 8 cycles, 1.3·10⁻⁷;
//!   plume 12 → 7 cycles; cubes unchanged; shell_core still stalls, at 0.89 instead of a
//!   residual of 10¹⁷) and on the `multigrid_scaling` cloud (n = 31, 63, 127: 20, 33, 48
//!   cycles to 10⁻⁶, where it stalled at every n). The homogeneous point source is unchanged
//!   (same cycles, 6–10). FLD is little affected (its D in vacuum is flux-limited, ≈ φ/|∇φ|,
//!   whatever σ): Fig 4 cloud 22 → 23 (n = 31) and 49 → 48 (n = 63) cycles, datasets ±1
//!   cycle, FLD-LP on shell_core stalls either way.
//! * **Krylov acceleration of the cycles, depth 3 by default ([`MgConfig::krylov`],
//!   `Krylov`; added 2026-12-06).** Oosterlee & Washio's nonlinear Krylov acceleration:
//!   before each cycle, φ becomes the combination of the last k + 1 cycle results whose
//!   linearised residual is least (for CDA, GMRES-like; for FLD a multisecant step), with a
//!   restart whenever a cycle ends with a larger R̄/j̄ than the one before. *Why*: the plain
//!   cycle's rate on vacuum clouds is set by a few slow modes the rediscretised coarse
//!   levels do not see (CDA on the Fig 4 cloud: 0.48, 0.63, 0.72 per cycle at n = 31, 63,
//!   127); a short Krylov history removes them. Measured (2026-12-06, 2-vCPU AMD EPYC 7002,
//!   `multigrid_scaling`, tolerance 10⁻⁶, CPU f64, cycles at n = 31, 63, 127, 255 plain →
//!   depth 3): CDA cloud 20, 33, 48, 67 → 10, 13, 17, 22 (255³: 30.7 → 11.1 s); CDA point
//!   source 8, 8, 8, 8 → 6, 6, 7, 6; FLD-LP point source 11, 15, 18, 25 → 9, 12, 16, 20;
//!   FLD-LP cloud 23, 48 → 17, 34 at n = 31, 63 and still `Stalled` at 127 and 255 (next
//!   bullet). Depth 1, 2, 3, 6 on the cloud at n = 63 and 127 (CDA): 19, 27; 13, 19; 13, 17;
//!   12, 16 cycles; FLD-LP at n = 63: 40, 40, 34, 30. A restart only when a cycle grows
//!   R̄/j̄ by 1.5× or more (`RESTART_GROWTH`): restarting on any growth left CDA on
//!   shell_core (18³) `Stalled` at 0.81, where it now converges in 16 cycles (plain cycles:
//!   R̄/j̄ 0.70 after 100). Depth 3 keeps 8 fine-grid vectors
//!   (1.1 GB at 255³, checked against the memory budget). Each cycle it reads k + 2
//!   residuals (the Gram update) and k + 1 iterates (the combination); once φ moved into the
//!   history instead of being copied and the error estimate's sums ran in parallel, the point
//!   source, where it saves one or two cycles, takes as long as without it (127³ CDA 0.56–0.58
//!   s either way over two runs each, 255³ 5.3 s against 5.6 s, one run each; seconds
//!   include setup). `krylov_acceleration_cuts_cycles_where_vacuum_slows_the_plain_cycle`
//!   (`tests/fld_multigrid.rs`) pins it. The GPU runs plain cycles ([`gpu`]).
//! * **Coarse D of FLD: FAS, and Picard coarse levels once the FAS stalls
//!   ([`CoarseD::Auto`], the default; 2026-12-06).** On the Fig 4 cloud at n = 127 FLD-LP
//!   falls to R̄/j̄ ≈ 0.01 in 17 cycles and then oscillates with period 2 and grows (0.011 →
//!   0.017 → 0.055 → 0.037 → 0.078, `Stalled`) while SOR converges (4347 iterations, 76 s).
//!   A diagnostic build (not kept) put 30–60 % of Σr² in 20 vacuum voxels (σ = σ_ε) of one
//!   pocket where φ is flat: there R = |∇φ|/(σφ) is O(1), so D = F(R)/σ swings between 0.5
//!   and 30 from one cycle to the next on a 10⁻⁴ change of φ, and the residual, D times the
//!   Laplacian, with it. Neither a damped coarse correction (0.7, 0.85) nor the θ-blend of D
//!   after the prolongation removed the oscillation. Freezing the coarse D at the mean of the
//!   fine D ([`CoarseD::Restricted`]: a Picard coarse problem, the coarse smoothers leave D
//!   alone) does, but its rate (0.85–0.95) is worse wherever the FAS converges (point source
//!   n = 31, 63, 127: 10, 15, 21 cycles against 9, 12, 16; cloud n = 31: 31 against 17), so
//!   the default runs the FAS and switches to Picard coarse levels for the rest of the solve
//!   when the stall rule fires (the Krylov history restarts, the stall rule starts afresh).
//!   Measured: Fig 4 cloud n = 127, FLD-LP: `Stalled` at 0.078 after 24 cycles → converged
//!   after 108 (24 FAS + 84 Picard); shell_core (18³, emission in the medium, tolerance 10⁻⁹):
//!   FAS `Stalled` at 2.7 after 14 cycles, Picard alone 42 cycles, the default 45, SOR 110042
//!   iterations (`the_picard_coarse_levels_take_over_where_the_fas_stalls`). The GPU runs the
//!   FAS only ([`gpu`]); `Restricted` is CPU only.
//! * **Where the defaults of 2026-12-06 stand (F(2, 2), Krylov depth 3, `CoarseD::Auto`;
//!   same 2-vCPU AMD EPYC, one run each).** `multigrid_scaling` (tolerance 10⁻⁶), cycles at
//!   n = 31, 63, 127, 255: point source CDA 5, 5, 5, 5 (was 8, 8, 8, 8), FLD-LP 9, 10, 11, 13
//!   (11, 15, 18, 25); Fig 4 cloud CDA 10, 12, 14, 16 (20, 33, 48, 67), FLD-LP 14, 21, 54,
//!   154 (23, 48, then `Stalled` at 127 and 255). 255³ seconds: point source CDA 4.2 (4.0),
//!   FLD-LP 19.7 (30.6); cloud CDA 9.4 (30.7), FLD-LP 192 (`Stalled` after 20 cycles, 23.9 s);
//!   rerun after the one-thread small levels (`SERIAL_VOXELS`, same cycles): 3.7, 19.1,
//!   8.8, 191 s. `point_source
//!   --n 127 --boundary zero --tolerance 1e-6 --solver sor,multigrid --limiter cda,lp`, SOR
//!   vs multigrid seconds at α = 0.1, 0.3, 0.5, 0.7, 0.9, 0.99: CDA 1.21/0.51 (2.4×),
//!   1.20/0.41 (2.9×), 1.09/0.40 (2.7×), 1.12/0.49 (2.3×), 1.12/0.44 (2.6×), 1.12/0.41
//!   (2.8×), 5 cycles (26.1 work units) each; FLD-LP 13.6/2.44 (5.6×), 8.23/2.89 (2.8×),
//!   8.65/2.38 (3.6×), 10.4/2.39 (4.4×), 11.8/2.35 (5.0×), 17.0/2.38 (7.2×), 11 cycles (57.5
//!   work units) each; relative L2 to SOR 0.4–3.6·10⁻⁶. After `SERIAL_VOXELS` (same
//!   command, α = 0.5 and 0.99, one run): CDA 1.22/0.366 (3.3×) and 1.13/0.353 (3.2×),
//!   FLD-LP 8.35/2.24 (3.7×) and 16.4/2.20 (7.5×). The datasets of `convergence_check`
//!   (18³, tolerance 10⁻⁴, f64, after the one-thread small levels of `SERIAL_VOXELS`):
//!   SOR vs multigrid seconds, CDA nebula 0.0039/0.0049, emissive_cloud 0.0038/0.0056,
//!   plume 0.0027/0.0048, cube (σt·Δl = 6) 0.0019/0.0052, shell_core 0.74/0.0096; FLD-LP
//!   0.028/0.025, 0.030/0.023, 0.022/0.021, 0.010/0.018, shell_core 2.89/0.078. Multigrid is
//!   therefore not faster everywhere it converges (small CDA grids), so no single solver
//!   is the faster default; the default is a rule between the two (next bullet).
//! * **The default solver: [`crate::fld::Solver::Auto`] (issue 15 item 4; 2026-12-06, 2-vCPU
//!   AMD EPYC Zen 5, 32 MiB L3, triad 67–70 GB/s).** Multigrid from 100³ voxels for CDA and
//!   63³ for FLD (the sizes where `multigrid_scaling` measured it faster on both of its
//!   problems, [`crate::fld::auto_multigrid_voxels`]); below, SOR for at most 200 sweeps
//!   ([`crate::fld::AUTO_SOR_SWEEPS`], about what a multigrid solve of those problems costs
//!   in wall time), then multigrid from scratch; SOR from scratch wherever multigrid ends
//!   without converging or cannot run (the Marshak face). `FldTrace::solver` and the
//!   `solved_by` column of `point_source` say which ran. It is `point_source`'s default
//!   (`--solver auto`; the `cda`/`fld` methods keep SOR, the paper's, and take it as the
//!   `:auto` variant or `render --solver auto`). Measured, `figures --only
//!   point_source,flux_limiters` before and after, one run each on the same idle host:
//!   `point_source` (Fig 5, 127³, 18 solves) 47.0 → 10.5 s wall (solves 45.5 → 8.6 s, all by
//!   multigrid), `flux_limiters` (63³, 66 solves) 19.8 → 10.0 s (solves 19.45 → 9.16 s: 60
//!   by multigrid, 6 CDA by SOR); the errors against Grosjean moved by at most 1.3·10⁻⁵
//!   relative (both solvers stop at R̄/j̄ < 10⁻⁶). With the first rule (10⁶ voxels for FLD
//!   too) `flux_limiters` took 17.9 s: 49 of its 66 solves ran 200 SOR sweeps before
//!   multigrid, which lost where SOR needed 201–300 (Kershaw α = 0.5: 0.17 → 0.29 s).
//!   The full `figures` run with this default took 3988 s on that host; the two experiments
//!   whose default changed were 66.8 s of the run before (1.7 %: the run's time is POP, the
//!   path tracer, Mitsuba, and experiments that run both solvers by design), so the run as a
//!   whole gained about 0.4 % (46.8 s saved, 29.2 s spent on the atlas's new `cda:mg` and
//!   `fld:lp:mg` points).
//!   Pinned by `auto_takes_each_branch_of_its_rule` (`tests/fld_multigrid.rs`) and
//!   `auto_hands_a_slow_sor_solve_to_multigrid_in_the_experiment`.
//! * **Issue 15's acceptance 3 at 255³, and what is left to try (2026-12-06, same 2-vCPU AMD
//!   EPYC 7002, quiet, one run: `point_source --n 255 --boundary zero --tolerance 1e-6
//!   --solver sor,multigrid --limiter cda,lp --albedo 0.5,0.99`, solve seconds without
//!   setup).** SOR vs multigrid: CDA α = 0.5 551 iterations 20.6 s vs 5 cycles 2.88 s (7.2×),
//!   α = 0.99 566 it. 21.0 s vs 5 cycles 2.75 s (7.6×); FLD-LP α = 0.5 2102 it. 271 s vs 13
//!   cycles 18.6 s (14.6×), α = 0.99 4049 it. 508 s vs 11 cycles 15.9 s (32×); relative L2 to
//!   SOR 0.8–4.3·10⁻⁶. FLD-LP is ≥ 10× at 255³, CDA is not at either size. At 127³ CDA cannot
//!   be: SOR's 277 sweeps against the multigrid's 26.1 work units cap the ratio at 10.6× for a
//!   cycle that cost nothing but its smoothing sweeps, and the cycle's own passes over the fine
//!   grid (the Krylov combination and history, packing φ into the smoother and out, two
//!   residuals, two restrictions, the prolongation, the error estimate) are not free: `perf`
//!   of the 255³ CDA `point_source` run (one solve; its setup and the analytic comparison
//!   are in the samples too) put 26 % of the samples in the smoothing sweeps, 10 % in the
//!   restrictions and 9 % in the residuals. Setup is not in these seconds; it now
//!   fills the fine level's packed fields in parallel over z-slabs and unpacks only σ and
//!   the absorption back (φ and D were unpacked and dropped): `CpuMultigrid::new` on the
//!   Fig 4 cloud, best of 3, 127³ CDA 0.109 → 0.085 s, FLD-LP 0.103 → 0.076 s; 255³ 1.15 →
//!   0.87 s and 0.97 → 0.81 s (`CpuFld::new` alone at 255³: 0.50 → 0.30 s CDA); the
//!   cycles' residuals are bit-identical. F(2, 1) instead of F(2, 2) (n = 31, 63, 127,
//!   Krylov depth 3): point source FLD-LP the same 9, 10, 11 cycles and 2.33 → 2.04 s at
//!   127³, but point source CDA 5 → 6 cycles (0.41 → 0.42 s), Fig 4 cloud CDA 10, 12, 14 →
//!   11, 14, 16 (1.01 → 1.09 s) and FLD-LP 14, 21, 54 → 16, 24, 80 (11.3 → 12.4 s); F(3, 3)
//!   and F(1, 1) on the FLD-LP point source: 8, 9, 10 cycles (2.64 s) and 10, 11, 15 (2.39 s).
//!   F(2, 2) stays.
//! * **First touch in parallel, one-pass packing, and the like-for-like time (2026-12-06,
//!   another machine: 2-vCPU AMD EPYC family 26 model 2 (Zen 5), 32 MiB L3, triad 68–70 GB/s
//!   in `cargo bench -p benches --bench diffusion` the same session).** `perf` of the 255³
//!   CDA point-source solve (cycles 2–5) put 12 % of the samples in first-touch page faults
//!   (and 8 % in the teardown's `munmap`, after the solve's clock stops): every new fine
//!   vector (the Krylov history alone takes 8 as it fills) was zeroed by one thread's
//!   `resize`. New vectors are now zeroed by every thread (`par_zeroed`) and the
//!   packed/natural copies (`CpuFld::mg_set`, `CpuFld::unpack_into`) split and interleave a
//!   row's two colours in one pass instead of a per-voxel index loop (per colour, for the
//!   packing): φ bit-identical (hashes of φ on the 255³ point source, the 127³ FLD-LP point
//!   source, the 95³ CDA and 63³ FLD-LP clouds against the build before), 255³ CDA solve
//!   (an ad-hoc driver, with the teardown) 2.56–2.81 s over 6 runs before, 2.25–2.27 s over
//!   3 with the parallel zeroing alone, 2.17–2.26 s over 2 with the packing too. SOR stops when R̄/j̄
//!   falls below the tolerance; multigrid's stop also waits for its error estimate (the 5th
//!   CDA cycle here: R̄/j̄ 4.0·10⁻⁷ after the 4th), so both now record the seconds until
//!   R̄/j̄ itself first fell below the tolerance (`FldTrace::seconds_to_tolerance`, the
//!   `seconds_to_tolerance` columns of `point_source` and `multigrid_scaling`), the
//!   comparison issue 15's acceptance 3 names. Measured (`point_source --boundary zero
//!   --tolerance 1e-6 --solver sor,multigrid`, one run each, every Fig 5 albedo 0.1, 0.3,
//!   0.5, 0.7, 0.9, 0.99), SOR seconds / multigrid seconds (to R̄/j̄ < tol; full stop):
//!   255³ CDA 16.46/1.488 (11.1×; 8.8×), 16.19/1.443 (11.2×; 9.0×), 17.11/1.447 (11.8×;
//!   9.4×), 17.28/1.511 (11.4×; 9.1×), 17.49/1.447 (12.1×; 9.6×), 17.70/1.430 (12.4×;
//!   9.8×), 543–566 SOR iterations against 5 cycles (4 to the tolerance);
//!   255³ FLD-LP 127.90/9.058 (14.1×; 12.3×), 129.33/9.130 (14.2×; 12.4×), 123.06/6.83
//!   (18.0×; 15.2×), 116.34/8.535 (13.6×; 11.9×), 176.81/8.665 (20.4×; 17.8×), 249.84/8.104
//!   (30.8×; 28.6×), 1961–4050 SOR iterations against 13 cycles (11 at α = 0.99);
//!   127³ CDA (5.0×; 4.0×), (3.6×; 3.0×), (4.4×; 3.5×), (4.6×; 3.6×), (4.7×; 3.7×), (4.5×;
//!   3.5×): SOR 0.78–0.87 s for 274–284 iterations, multigrid 0.17–0.22 s to the tolerance;
//!   127³ FLD-LP (6.6×; 6.0×), (3.3×; 3.0×), (3.5×; 3.2×), (3.9×; 3.5×), (4.6×; 4.2×), (6.2×;
//!   5.7×): SOR 2.80–5.77 s for 472–974 iterations, multigrid 0.85–0.93 s (11 cycles) to the
//!   tolerance (10 cycles, 52.3 work units); φ within 0.4–4.3·10⁻⁶ relative L2 of SOR's at
//!   both sizes (the largest: 255³ FLD-LP, α = 0.99). So at 255³ the ≥ 10× of
//!   acceptance 3 holds for CDA and FLD-LP at every albedo (to the tolerance; FLD-LP also by
//!   the full stop, CDA there 8.8–9.8×), and at 127³ it does not:
//!   there SOR's 274–284 sweeps against 4 cycles' 20.9 work units cap the ratio near 13× for
//!   CDA even for free transfers (FLD-LP: 472–974 sweeps against 52.3 work units, 9–19×),
//!   and a work unit of multigrid still costs 2.6–3.6 (CDA) and 2.6–3.0 (FLD-LP) SOR sweeps
//!   of wall time (residuals, transfers, packing, the Krylov history).
//! * **127³ after the fused sweeps, and where a CDA solve's time goes (2026-12-06, Zen 5
//!   host).** The sweeps now run both colours in one fused pass (`fld` module docs, "Fused
//!   colour passes"); SOR and the smoother gain alike. `point_source --n 127 --boundary zero
//!   --tolerance 1e-6 --solver sor,multigrid --limiter cda,lp`, every Fig 5 albedo, one run,
//!   SOR / multigrid seconds to the tolerance: CDA 4.1–4.8× (SOR 0.78–0.92 s for 274–284
//!   sweeps, multigrid 0.16–0.21 s), FLD-LP 3.4–6.9× (SOR 3.0–5.6 s for 472–974 sweeps,
//!   multigrid 0.80–0.89 s). An instrumented build (timers around each step of the finest
//!   level, not kept; CDA, α = 0.5, 5 cycles, a 0.264 s solve of which the timed steps were
//!   242 ms) put: fine smoothing 62 ms (23 % of the solve), the coarser levels 48 ms (18 %),
//!   the two fine residuals 44 ms (17 %; the in-cycle one costs twice the end-of-cycle one,
//!   its vectors still being first touched while the Krylov history fills), restrictions,
//!   prolongation and coarse packing 32 ms (12 %), the Krylov combination, Gram update and
//!   re-packing 28 ms (11 %), unpacking and packing φ 19 ms (7 %), error estimate and the
//!   residual's sum 9.5 ms (4 %). Four cycles reach the tolerance: their fine smoothing
//!   alone is ≈ 50 ms (15.8× against SOR's 0.78 s), and with the coarser levels as they are
//!   ≈ 88 ms (8.9×), so at 127³ even free transfers, residuals and Krylov steps would leave
//!   CDA below 10× unless the coarse levels got cheaper too.
//!   **255³ after the fused sweeps** (same command with `--n 255`, one run; CDA at every
//!   albedo, FLD-LP at α = 0.1 and 0.7, the two lowest ratios of the run before): CDA SOR
//!   12.2–15.4 s for 543–566 sweeps (16.2–17.7 s before) against multigrid 1.36–1.74 s to
//!   the tolerance (1.43–1.51 s before): **8.1–11.3×** (was 11.1–12.4×), 6.5–9.0× by the
//!   full stop; FLD-LP SOR 104.5 and 97.8 s (2019 and 1961 sweeps) against 6.76 and 6.82 s:
//!   15.4× and 14.3× (was 14.1× and 13.6×). The faster sweep is all of SOR's time but only
//!   a quarter of a CDA cycle's, so the CDA ratio fell below 10× at four of six albedos. A
//!   second CDA run right after (quieter: SOR 12.1–13.5 s, multigrid 1.25–1.35 s) read
//!   9.7–10.5×: CDA at 255³ now sits at the 10× line.
//!   Of what else a 255³ CDA solve spends, first touch is large: 437 000 page faults during
//!   the solve (1.8 GB; counted from `/proc/self/stat` in an ad-hoc driver), about what the
//!   fine vectors the solve allocates add up to (the Krylov history's 8 alone are 1.06 GB),
//!   and the whole process, setup and teardown included, spent 1.7 of its 4.8 CPU seconds
//!   in the kernel (`perf stat`). Touching them in the setup instead would only move
//!   that time out of the solve's clock, so it was not done.
//! * **Local relaxation around point-like sources ([`MgConfig::local_sweeps`] = 8 in a box of
//!   optical half-width [`MgConfig::local_radius`] = 0.5; `multigrid/local.rs`; 2026-12-07, 2-vCPU
//!   AMD EPYC Zen 5, 32 MiB L3).** *Why*: FLD-LP's cycles on the point source grew with n (8,
//!   9, 10, 12 at n = 31…255), and a build that printed where Σr² sits after each cycle (not
//!   kept) put 91–99.9 % of it within 8 voxels of the source at n = 255 for the first 8 cycles
//!   (the one-voxel source holds j = 1/Δl³; R ≈ 1/(σr) near it grows as Δl shrinks). Brandt's
//!   remedy for such singularities is extra relaxation in a neighbourhood of fixed physical
//!   size. Measured on an ad-hoc driver (`point_source` medium, τ = 4, albedo 0.5, cycles to
//!   R̄/j̄ < 10⁻⁶ at n = 31, 63, 127, 255), FLD-LP: none 8, 9, 10, 12; a box of 8 voxels and 8
//!   sweeps after the coarse-grid correction 6 (n = 63), 8 (127); also after the
//!   post-smoothing 5, 6, 7, 9 (a fixed box in voxels does not keep up with n: at n = 255 the
//!   residual then sat 17–32 voxels out, at the box's edge); a box of n/8 voxels (optical
//!   half-width 0.5) at both places 6, 6, 7, 7 and after the correction only 6, 6, 7, 9;
//!   before the pre-smoothing instead: no better (n = 63: 9, first residual 2.2; n = 127: 11); selecting the
//!   voxels with R > 4 instead of a box (the Dirichlet layer's neighbourhood, where φ → 0,
//!   is selected too) 6, 7, 7, 8. As built (the box ⌈τ₀/(σΔl)⌉ = 4, 8, 16, 32 voxels, at both
//!   places, D recomputed before each colour; before each sweep instead, the 255³ solve stopped
//!   after 8 cycles instead of 7, both below the tolerance after the 6th, for 5.9 instead of
//!   8.3 ms per box visit at 127³): FLD-LP **6, 6, 6, 7** (17 % spread; was 50 %),
//!   CDA 4, 4, 4, 4 cycles with R̄/j̄ below 10⁻⁶ after the 3rd at n = 31, 127, 255 (was 5, 5,
//!   5, 5 and the 4th). Seconds to the tolerance, alternating builds, two runs each, albedo
//!   0.99: 127³ CDA 0.192–0.194 → 0.176–0.178 s, FLD-LP 1.245–1.248 → 0.809–0.819 s (10 → 7
//!   cycles); 255³ CDA 1.40–1.47 → 1.26 s, FLD-LP 10.3–10.4 → 8.0–8.4 s (12 → 8 cycles). The
//!   boxes cost 8 sweeps × 2 × 1.6 % of the grid per cycle plus their D, which is why CDA
//!   gains less than its cycle: 4 sweeps and radius 0.5 took 8, 9 cycles at n = 127, 255
//!   (0.90, 7.6 s), 8 sweeps and radius 0.25 7, 8 (0.87, 7.3 s), 16 and 0.25 7, 8 (0.77,
//!   7.3 s): within the host's noise of the default. CDA alone would
//!   do with fewer (point source, albedo 0.5, two alternating runs each, seconds to the
//!   tolerance, 8 → 2 sweeps): 127³ 0.186 → 0.169–0.179 s, 63³ 0.026 → 0.023 s, the same 4
//!   cycles, but 5 instead of 4 at 31³; at 255³ and albedo 0.1, 4 and 2 sweeps took 1.27–1.32
//!   and 1.24–1.33 s against 1.41–1.42 s. One default for every limiter is kept: FLD-LP
//!   needs the 8, and CDA's gain (4–13 %) is smaller than the host's noise between runs. Media without a voxel holding 1 % of
//!   the emission (the Fig 4 clouds of `multigrid_scaling`) get no box and run exactly as
//!   before. A box that holds vacuum (a σ below 1 % of its largest, [`VACUUM_CONTRAST`]) is
//!   dropped: on white noise with 95 % vacuum (17³, tolerance 10⁻⁹) the boxes made FLD-LP
//!   stop `Stalled` after 38 cycles where it converges in 27 without them (30 % vacuum: 35
//!   against 34; found in review, 2026-12-07); blending the boxes' D with the smoother's θ
//!   instead converged there (18 and 28 cycles) but stopped the point source one cycle later
//!   (6, 6, 7, 8 at n = 31…255). The 18³ datasets of `convergence_check` do get boxes (tolerance 10⁻⁴, f64,
//!   cycles before → after): nebula CDA 5 → 4, every FLD limiter 9 → 8; emissive_cloud CDA
//!   6 → 5, every FLD limiter 8 → 7; plume CDA 6 → 5, FLD 8 → 7 (max: 8 either way); cube
//!   τ = 0.6 CDA, LP, Kershaw, Larsen 6 → 5 (sum 5, max 6 either way); the optically
//!   thicker cubes unchanged; shell_core CDA 12 → 11, FLD-LP 38 → 39, sum 32 → 32,
//!   max 64 → 48, Kershaw 36 → 37, Larsen 47 → 39; all converge. Issue 15's acceptance 3
//!   with it (`point_source --boundary zero --tolerance 1e-6 --solver sor,multigrid`, one
//!   run each, every Fig 5 albedo, SOR / multigrid seconds to the tolerance; full stop in
//!   brackets): 127³ CDA 3.9–6.5× (3.0–4.9×; SOR 0.76–1.27 s for 274–284 sweeps on a noisy
//!   host), FLD-LP 5.9–18.0× (5.0–13.2×; 6 or 7 cycles); 255³ CDA 8.4–11.8× (6.2–8.6×; 4
//!   cycles, 3 to the tolerance; 10.5–11.8× at five albedos, 8.4× at α = 0.1 where the
//!   multigrid solve took 1.56 s against 1.22–1.27 s at the others); φ 0.7–3.2·10⁻⁶ from
//!   SOR's (relative L2). Pinned by `local_relaxation_keeps_the_point_source_flat_in_n`
//!   (`tests/fld_multigrid.rs`: 8, 9, 10 → 6, 6, 6 at n = 31, 63, 127) and the box rule by
//!   `local::tests`.
//! * **Full-multigrid start ([`MgConfig::full_multigrid`], on by default; 2026-12-07, 2-vCPU
//!   AMD EPYC Zen 5, 32 MiB L3).** The first cycle used to start from φ = 0, so its residual
//!   still held the smooth error the coarse levels could have removed beforehand. Now the FAS
//!   problem at the starting φ is set up on every level, solved coarsest first, and each
//!   level's correction is prolongated to the next finer one and given one cycle there
//!   (nested iteration, Brandt's FMG). The solve's cycles then begin. This costs 0.7–1.1 work
//!   units, counted in the first cycle. Measured with `multigrid_scaling --full-multigrid
//!   false|true` (defaults otherwise, f64, tolerance 10⁻⁶, one run each, SOR off), cycles at
//!   n = 31, 63, 127, 255 from φ = 0 → FMG: point source CDA 4, 4, 4, 4 → 4, 4, 4, 3, FLD-LP
//!   6, 6, 6, 7 → 5, 5, 5, 7; Fig 4 cloud CDA 8, 10, 12, 14 → 8, 9, 11, 13, FLD-LP 14, 20,
//!   43, 125 → 12, 16, 38, 127; `ball_source` CDA 5, 4, 4, 4 → 4, 4, 3, 3, FLD-LP 7, 7, 7, 8 →
//!   6, 6, 7, 7; `cloud_thin` CDA 7, 8, 9, 9 → 6, 7, 8, 9, FLD-LP 10, 12, 14, 17 → 9, 10, 12,
//!   16; `cloud_floor` CDA 6, 7, 8, 8 → 6, 6, 7, 8, FLD-LP 9, 9, 11, 12 → 8, 8, 10, 11. That is
//!   fewer or as many cycles in 39 of the 40 runs (the exception, the 255³ cloud with FLD-LP,
//!   is set by the peak of D below). The residual after the first cycle falls about tenfold
//!   on the point source (127³ CDA 5.1·10⁻⁴ → 3.2·10⁻⁵, FLD-LP 1.3·10⁻² → 7.4·10⁻⁴). That
//!   is what acceptance 3 needed. Seconds to R̄/j̄ < 10⁻⁶ on the point source (same runs):
//!   CDA 127³ 0.147 → 0.127 s, 255³ 1.97 → 0.86 s (R̄/j̄ below 10⁻⁶ after 2 cycles instead
//!   of 3); FLD-LP 127³ 0.52 → 0.42 s, 255³ 5.11 → 4.54 s. Alternating runs of an ad-hoc
//!   driver (127³ CDA, albedo 0.5, six runs each) gave 0.166–0.195 s from φ = 0 and
//!   0.128–0.142 s with FMG. The FMG start and the local boxes work together: without the
//!   boxes (`local_sweeps` 0) the FMG start leaves the point source's residual at the source
//!   (127³ CDA: 4.8·10⁻³, 2.2·10⁻⁵, 3.4·10⁻⁷ after cycles 1–3 against 3.2·10⁻⁵, 3.2·10⁻⁷ with
//!   them; 0.17–0.22 s to the tolerance against 0.14–0.15 s, two alternating pairs; 255³ 3
//!   cycles to the tolerance against 2). Issue 15's acceptance 3 with it (`point_source --boundary zero
//!   --tolerance 1e-6 --solver sor,multigrid`, every Fig 5 albedo, one run per size, SOR /
//!   multigrid seconds to the tolerance, setup excluded on both sides): 127³ CDA 5.6–8.0×
//!   (SOR 0.87–1.21 s for 274–284 sweeps, multigrid 0.11–0.18 s, R̄/j̄ below 10⁻⁶ after 2
//!   cycles), FLD-LP 6.5–13.5× (SOR 4.3–7.8 s, multigrid 0.45–0.74 s, 5 or 6 cycles with
//!   the stop); 255³ CDA 9.1–15.6× (SOR 12.7–13.3 s for 543–566 sweeps, multigrid 0.85–1.41
//!   s, 2 cycles; the two lowest albedos 9.1× and 9.2×), FLD-LP at albedo 0.5 19.6× (SOR 2078
//!   sweeps in 111.1 s, multigrid 5.68 s, 7 cycles with the stop); φ 0.7–3.1·10⁻⁶ from SOR's
//!   (relative L2; FLD-LP at 255³ 1.8·10⁻⁶). A 127³ CDA
//!   solve to the tolerance is now the FMG start and two cycles, 30–50 SOR sweeps of wall
//!   time against SOR's 277, so 10× there needs a cycle that costs little more than its
//!   smoothing. Where a 127³ CDA cycle's time goes now (an instrumented build, not kept; four
//!   cycles from φ = 0, albedo 0.5, three runs, 0.22–0.23 s): the 16 fine sweeps 56–60 ms,
//!   the two fine residuals per cycle 35–37 ms (22–25 ms with Krylov depth 0: the rest is the
//!   first touch of the vectors the history keeps), the coarse levels 34–39 ms, the local
//!   boxes 21–25 ms, the transfers 17–21 ms, packing and unpacking φ 10–11 ms, the Krylov
//!   sums and combination 8–10 ms, the error estimate 5–6 ms. Starting the Krylov history only
//!   after a cycle that reduces R̄/j̄ by less than 20× (tried, not kept) left the 127³ CDA
//!   time to the tolerance within the noise (0.112–0.134 s against 0.115–0.135 s, three
//!   alternating pairs) and, measured without the FMG start, cost the 63³ `ball_source` CDA
//!   a cycle (4 → 5). Nor does F(1, 2) pay as a default with the FMG start (CDA, albedo 0.5,
//!   one run each, F(2, 2) → F(1, 2), cycles and seconds to the tolerance at n = 31, 63, 127,
//!   255): the point source keeps 4, 4, 4 cycles and 3 → 4 at 255 (1.62 → 1.00 s there,
//!   R̄/j̄ below 10⁻⁶ after 2 cycles either way; at 127³ 0.145–0.193 → 0.115–0.118 s over
//!   two alternating pairs), but the Fig 4 cloud takes 8, 9, 11, 13 → 9, 11, 13, 16 cycles
//!   (0.58 → 0.65 s at 127³, 6.5 → 6.7 s at 255³) and `ball_source` 4, 4, 3, 3 → 5, 4, 4, 4
//!   (1.72 → 2.22 s at 255³). The FMG start ends each level with one cycle of the solve's
//!   kind (F). The GPU starts from φ = 0 (`MgConfig::plain_fas`), and so does
//!   [`CoarseOp::Galerkin`], whose coarse levels solve for corrections only. Pinned by
//!   `the_full_multigrid_start_cuts_the_first_residual` (`tests/fld_multigrid.rs`).
//! * **Known limitations (measured, not fixed).** Cycles still grow with n on the vacuum
//!   cloud (CDA 10 → 16 over n = 31…255, FLD-LP 14 → 154; with ω = 1.2, 8 → 14 and 14 →
//!   125; at n = 127 with V cycles, 84 of 108 were Picard cycles after the FAS stalled). For
//!   FLD-LP on the point source they grew too (9 → 13; with ω = 1.2, 8 → 12) until the local
//!   relaxation (above: 6, 6, 6, 7): the ≤ 25 % of issue 15 then held on the point source
//!   for CDA and FLD-LP, not on the cloud. With the FMG start (above) R̄/j̄ falls below 10⁻⁶
//!   after 3, 3, 2, 2 cycles (CDA: the count falls with n, 50 % as a spread) and 4, 4, 4, 5
//!   (FLD-LP, 25 %) at n = 31…255 (`multigrid_scaling`'s `steps_to_tolerance`). Local relaxation does not fix the cloud (2026-12-07,
//!   ad-hoc builds, not kept; cycles to R̄/j̄ < 10⁻⁶): 8 extra sweeps twice per cycle on its
//!   surface shell (the voxels within 2 of a vacuum/medium face: 82 432, 4.0 % of the grid at
//!   127³; the voxels on either side of a face held 25–33 % of Σr² after each cycle, the
//!   vacuum 36–43 % and the cloud's inside 25–37 %) took
//!   CDA 8, 10, 12 → 8, 10, 11 cycles at n = 31, 63, 127. Boxes that follow the largest
//!   residual (after every cycle a box of half-width 8 around the voxel with the largest |r|,
//!   up to 8 boxes kept; the residual-threshold sets of the D-peak bullet below were the
//!   earlier form of this) took FLD-LP 14, 20, 43, 125 → 11, 19, 27, 106 cycles at n =
//!   31…255, but 107 s instead of 68–72 s at 255³: the D peak moves and multiplies as n grows.
//!   Nor does a Jacobi-smoothed prolongation of the correction ((I − ωD⁻¹A)P with the
//!   rediscretised coarse levels, ω = 0.67 or 1): CDA on the cloud 8, 10, 12 → 18, 41–42,
//!   80–81 cycles. Transparent huge pages (the host's THP switched from `madvise` to `always` for
//!   a test) made the 255³ CDA point source's time to the tolerance noisier, not reliably
//!   shorter: 1.27–2.42 s against 1.44–1.83 s over six runs each. On small vacuum clouds SOR is faster (CDA n =
//!   31: 0.009 s against 0.023 s, 0.076 s before `SERIAL_VOXELS`; `multigrid_scaling` with SOR up
//!   to n = 127: CDA on the cloud 0.4×, 0.7×, 1.6× at n = 31, 63, 127). A CDA work unit of multigrid costs about 3.9 SOR sweeps of
//!   wall time (127³, α = 0.5: 0.40 s / 26.1 work units against SOR's 1.09 s / 277 sweeps;
//!   transfers, residuals, packing), so the ≥ 10× of issue 15 is not met at 127³.
//!   FLD-LP on white noise with 95 % vacuum still stalls in f32 (the GPU test). shell_core
//!   (`convergence_check`) now converges (previous bullets). Operator-dependent
//!   (Galerkin-type) coarse coefficients and a Newton-type treatment of the limiter's
//!   nonlinearity remain the candidate fixes for the cloud's FLD-LP growth, whose cause is
//!   measured below (the peak of D at a critical point of φ in the vacuum).
//!   **W-cycles do not help (2026-12-06, same 2-vCPU AMD EPYC, a W(2, 2) variant built and
//!   measured, not kept; default Krylov depth 3, f64, R̄/j̄ < 10⁻⁶):** F → W cycles and
//!   seconds: cloud CDA n = 31, 63, 127: 10, 12, 14 → 10, 12, 14 (1.00 → 1.09 s at 127);
//!   cloud FLD-LP n = 63: 21 → 21; point source FLD-LP (α = 0.5) n = 63, 127: 10, 11 → 10,
//!   11 (1.81 → 1.87 s). Solving the coarse problems more exactly changes no cycle count,
//!   so the growth with n comes from the two-grid step itself (the rediscretised coarse
//!   operator against the fine one, or the smoother), not from the recursion. More
//!   smoothing (same runs, F-cycles, cycles at n = 31, 63, 127, 255) lowers the counts but
//!   not their growth: cloud CDA F(2, 2) 10, 12, 14, 16 (+60 %), F(4, 4) 7, 10, 10, 12
//!   (+71 %; 9.2 s at 255), F(8, 8) 6, 7, 8, 9 (+50 %; 10.5 s); point source FLD-LP F(2, 2)
//!   9, 10, 11, 13 (+44 %), F(4, 4) 7, 8, 9, 10 (+43 %; 16.2 s at 255 against 14.5 s). What
//!   grows with n is then the coarse-grid correction's error, which points at the
//!   rediscretised coarse operator (the Galerkin-type candidate above), not at the smoother.
//!   **Two controls say where FLD-LP's growth comes from (2026-12-06, Zen 5 host,
//!   `multigrid_scaling`'s `ball_source` and `cloud_thin`, cycles at n = 31, 63, 127, 255).**
//!   The point source's one emitting voxel (j = 1/Δl³) is a source that sharpens with n, so
//!   its discrete problems do not converge to one continuous problem: the same unit power
//!   over a ball of radius 0.1 ([`crate::scenes::ball_source`]) takes FLD-LP 7, 7, 8, 8
//!   cycles (+14 %; the one-voxel source 9, 10, 11, 13, +44 %) and CDA 5, 5, 5, 4 (+25 %):
//!   grid-independent within issue 15's 25 % for both
//!   (`cycles_do_not_grow_with_n_for_a_source_of_fixed_size` pins n = 33, 65). The cloud's
//!   growth is mostly its vacuum, where FLD's D → φ/|∇φ| and the equation becomes a
//!   first-order (free-streaming) one that a point smoother with isotropic coarsening does not
//!   resolve: with the vacuum filled by σt = 0.5 ([`crate::scenes::cloud_in_thin_medium`])
//!   FLD-LP takes 11, 13, 15, 19 (+73 %, against 14, 21, 54, 154 in vacuum) and CDA 8, 9, 9,
//!   10 (+25 %, against 10, 12, 14, 16). So acceptance 2 holds for resolved sources without
//!   vacuum, and not for FLD-LP where the medium is optically thin (+73 %) or vacuum.
//! * **Why the cloud's FLD-LP cycles grow: the peak of D at a critical point of φ in the
//!   vacuum (2026-12-07, 2-vCPU AMD EPYC Zen 5, 32 MiB L3; an ad-hoc driver over
//!   [`CpuMultigrid`] and a diagnostic build, not kept; defaults, f64, R̄/j̄ < 10⁻⁶).** At
//!   n = 127 the solve no longer stalls (54 cycles of the FAS alone; `Auto` does not switch),
//!   but it converges at about 0.8 per cycle. From cycle 7 on, 94–99 % of Σr² sat in vacuum
//!   voxels (56–86 % in those with no medium neighbour; sampled every sixth cycle), the
//!   largest residuals at (52–55, 46–49, 104–105), just
//!   outside the cloud's surface, where φ is flat (0.0688) and D is 5–8 against a median
//!   vacuum D of 0.25. That is a critical point of φ (∇φ ≈ 0): there R = |∇φ|/(σ_ε φ) falls
//!   and D = F(R)/σ_ε rises towards 1/(3σ_ε) = 333, and the nearer a voxel centre lies to the
//!   point, the higher its D. The largest interior D at the converged φ
//!   ([`diffusion_field`]) is 0.65, 1.76, 9.8 and 111 at n = 31, 63, 127, 255, always at the
//!   same place (its voxel's centre at (0.43–0.44, 0.37–0.38, 0.82–0.86) of the unit cube),
//!   and the cycles are 14, 21, 54, 154. The lagged D of the smoother (and of Picard coarse levels) leaves out D's
//!   dependence on φ, which near such a point is as large as the operator itself, and the
//!   coarse levels do not see the peak: the discrete problems carry a coefficient contrast
//!   that grows with n, as the point source's one-voxel j does.
//!   **Controls.** Capping the peak by a larger σ_ε (`FldConfig::sigma_eps`; n = 127): σ_ε =
//!   10⁻³ (default), 10⁻², 10⁻¹, 1 take 54, 46, 30, 12 cycles; with σ_ε = 1 (D ≤ 1/3,
//!   `multigrid_scaling`'s `cloud_floor`) the cycles at n = 31, 63, 127, 255 are 9, 10, 12,
//!   14 (+56 %), the growth that CDA on the cloud (+60 %) and FLD-LP on `cloud_thin` (+73 %)
//!   show, which Galerkin coarse operators halve for CDA (next bullet). σ_ε is physics, not a
//!   solver setting: against σ_ε = 10⁻³ at n = 127, φ changes in the cloud by 6.3·10⁻⁵
//!   (σ_ε = 10⁻², max 0.5 %), 6.9·10⁻⁴ (10⁻¹, max 4.4 %) and 8.7·10⁻³ (1, max 24 %)
//!   relative L2, and in the vacuum by 1.2·10⁻³, 1.3·10⁻² and 0.12; so the default stays.
//!   SOR slows with a smaller σ_ε too, as FLD Fig 4c shows (`convergence`'s `sigma_eps`
//!   case: 552, 745, 775 iterations at σ_ε·L = 10⁻¹, 10⁻², 10⁻³ on the 51³ cloud in f32 to
//!   10⁻⁴, then flat: 1.4× from 10⁻¹ to 10⁻³, where multigrid at n = 127 takes 1.8×).
//!   **Tried, not kept.** A deeper Krylov history (depth 0, 3, 6, 12: 110, 54, 39, 34 cycles
//!   at n = 127; at n = 255 depth 6 and 12 take 106 and 85 cycles, 62 and 54 s, against 154
//!   and 93 s at depth 3) helps but does not remove the growth, and it costs 2(k + 1) fine
//!   vectors (3.5 GB at 255³ for depth 12) and time where the cycles are few (CDA on the
//!   cloud at n = 127: 14 → 13 cycles, 0.59 → 0.74 s). So depth 3 stays the default, and
//!   [`MgConfig::krylov`] (`multigrid_scaling --krylov`) is the lever for FLD in vacuum.
//!   The θ of the D update is not ([`FldConfig::d_relaxation`] 0.3, 0.5, 0.7, 1: 92, 54, 55,
//!   98 cycles at n = 127; the default 0.5 stays). Local relaxation at the peak (Brandt's
//!   remedy for singularities: after each cycle, 2–50 nonlinear Gauss–Seidel sweeps with D
//!   recomputed, on the voxels whose r² exceeds 100× the mean and their neighbours, 665–3318
//!   voxels a cycle where printed): 54 → 47, 39, 32 cycles at n = 127 with 2, 10, 50 sweeps, 21 → 21 at n = 63,
//!   but 154 → 239 at n = 255; with a lower threshold (10× and 3× the mean, 65 000–541 000
//!   voxels) 59 and 63 at n = 127; the same sweeps with D held at its value after the cycle
//!   (linear Gauss–Seidel, 10 and 50 sweeps) 41 and 38 cycles at n = 127, and at n = 255
//!   `Stalled` after 31. What the peak needs is the limiter's Jacobian (a Newton
//!   step) where D is sensitive, or coarse operators built from the fine D; neither is built.
//!   `the_cloud_s_fld_cycles_follow_the_peak_of_d_in_its_vacuum` (`tests/fld_multigrid.rs`)
//!   pins the peak's sharpening and the capped cloud's flat cycles at n = 31 and 63.
//! * **Galerkin coarse operators ([`CoarseOp::Galerkin`], CDA only; 2026-12-06), first
//!   measured outside the crate (`scripts/mg-coarse-operators.py`, numpy/scipy/pyamg).** The
//!   script rebuilds the CDA operator of FLD Eq 32 on the vacuum cloud (σt = 20, albedo 0.9
//!   inside, vacuum floored at σ_ε = 10⁻³: a D contrast of 2·10⁴) on n = 2^k + 1 grids (every
//!   axis vertex-coarsened), smooths with symmetric Gauss–Seidel (two sweeps each side), and
//!   counts cycles to a relative residual of 10⁻⁶. Its rediscretised operator (the harmonic σ
//!   of this module) with F-cycles accelerated by conjugate gradients takes 10, 13, 15, 18
//!   cycles at n = 33, 65, 129, 257, close to this module's 10, 12, 14, 16 at n = 31…255 with
//!   its Krylov depth 3, so it models the growth; plain V-cycles 22, 36, 55, 76 (rate 0.51,
//!   0.67, 0.76, 0.82). Galerkin operators A_c = Pᵀ A P (27-point stencils) instead: trilinear P: V 15, 19,
//!   24 (rate 0.34, 0.43, 0.51), F+CG 8, 9, 10; an operator-dependent P (each axis's odd
//!   points weighted by their two face couplings, the fine faces coarsened in series
//!   alongside): V 12, 16, 19, 22 (0.26, 0.37, 0.43, 0.48), F+CG 7, 8, 9, 10; weights from
//!   the Galerkin stencils' collapsed couplings were no better than trilinear (V 16, 20, 25;
//!   F+CG 8, 8, 9). With σt = 0.2 outside instead of vacuum (contrast 100): rediscretised F+CG
//!   8, 10, 11, Galerkin with the operator-dependent P 5, 6, 7 (V 7, 9, 10).
//!   **In the crate** ([`CoarseOp::Galerkin`], module `galerkin`): R A P with this module's
//!   own transfers, by probing the finer operator; on cell-coarsened axes the linear P reaches
//!   one coarse voxel further, so the coarse stencil there has radius 2 (up to 125 points),
//!   smoothed by a multi-colour Gauss–Seidel (red-black is not a Gauss–Seidel for such
//!   stencils) and solved for the correction. Measured (same 2-vCPU AMD EPYC 7002, an ad-hoc
//!   driver over [`CpuMultigrid`], F(2, 2), f64, tolerance 10⁻⁶, one run each), cycles
//!   rediscretised → Galerkin at n = 31, 63, 127, 255 on the Fig 4 cloud, Krylov depth 3: 10,
//!   12, 14, 16 → 8, 9, 10, 11 (+60 % → +38 % over the range); plain cycles at n = 31, 63: 20,
//!   29 → 13, 17; the φ of the two agree to 1.4–12·10⁻⁸ relative L2; point source (n = 127):
//!   5 → 5 cycles. It is not faster: this first version's setup (one probe of the finer
//!   operator per stencil entry) took 1.84 s at 127³ and 14.7 s at 255³, and its scalar,
//!   bounds-checked rows make a cycle slower, so the cloud took 4.6 s against 1.0 s at 127³
//!   and 38 s against 9.4 s at 255³ (setup included); the point source 3.5 s against 0.50 s.
//!   With flat offsets for the rows away from the faces (review; φ and residuals
//!   bit-identical), one run: setup 1.72 and 13.4 s, the cloud 4.00 s against 1.02 s at 127³
//!   and 32.6 s against 8.85 s at 255³, the point source 3.15 s against 0.51 s.
//!   So the rediscretised levels stay the default. Galerkin operators roughly halve the
//!   cloud's growth but do not reach issue 15's ≤ 25 % at vacuum contrast either here or in
//!   the script; with the over-relaxed smoother of the finest level (ω = 1.2, 2026-12-07,
//!   Zen 5 host, same driver) they take 7, 8, 8, 10 cycles at n = 31…255 (+43 %; R̄/j̄
//!   1.2·10⁻⁶ after the 9th at 255, 85 s and a setup of 18 s there), against 8, 10, 12, 14
//!   rediscretised; for FLD they would need Pᵀ A(D) P once per cycle of the Picard linearisation
//!   (not built). `galerkin_coarse_levels_cut_cda_cycles_on_the_vacuum_cloud`
//!   (`tests/fld_multigrid.rs`) pins the agreement with SOR and the cycle cut.
//! * **GPU ([`gpu`], issue 15 item 2).** The same cycle in f32 on the device: the smoother of
//!   every level is `fld.wgsl`'s red-black sweep itself, the transfers (D from φ, residual,
//!   restriction of φ and of the residual, the FAS right-hand side, prolongation) are
//!   `multigrid.wgsl`, one compute pass per cycle, three sums read back per cycle. Measured
//!   on lavapipe (`tests/fld_multigrid_gpu.rs`, tolerance 10⁻⁵): on the 33³ point source and
//!   a 24 × 20 × 27 source block, for CDA and all five limiters, the GPU takes the same
//!   number of cycles as the CPU-f32 multigrid (6–7; once 6 vs 7) and agrees with it to
//!   0.09–1.3·10⁻⁶ relative L2 (max relative difference 0.8–10·10⁻⁶, the conformance bound
//!   is 10⁻³), and with the GPU's SOR to 1.4·10⁻⁶–2.5·10⁻⁵ relative L2. With the arithmetic
//!   coarse σ, where the CPU stalled (Fig 4 cloud CDA, 95 % vacuum, 10⁴-contrast noise for
//!   CDA) the GPU stalled after the same number of cycles at the same R̄/j̄ (3 digits); with
//!   the harmonic σ both converge there in the same number of cycles (7 and 14), and on the
//!   Fig 4 cloud CDA both stop `Stalled` at f32's floor (R̄/j̄ 1.0 and 1.1·10⁻⁴ after 20 and
//!   25 cycles, tolerance 10⁻⁵). Those were V cycles; with the F cycles of the default
//!   (2026-12-06) the GPU and the CPU-f32 multigrid (both plain FAS: [`gpu`]) take the same
//!   number of cycles in all 12 point-source and source-block cases (5–7).
//!
mod galerkin;
pub mod gpu;
mod local;

pub use gpu::GpuMultigrid;
pub use local::{MAX_BOXES, POINT_SHARE, VACUUM_CONTRAST};

use super::{Boundary, CpuFld, FldConfig, FldSolution, FluxLimiter};
use crate::fld::residual::ResidualWindow;
use crate::gpu::Timer;
use crate::method::Stop;
use crate::{Grid, Medium, Real, SolverError};
use rayon::prelude::*;
use std::time::Instant;

/// The largest [`MgConfig::krylov`] accepted (the history's least-squares system is solved
/// by dense elimination on the host, and every step of depth costs two fine-grid vectors).
pub const MAX_KRYLOV: usize = 16;

/// The largest [`MgConfig::local_sweeps`] accepted.
pub const MAX_LOCAL_SWEEPS: usize = 64;

/// V- or F-cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Cycle {
    /// One coarse-grid visit per level.
    V,
    /// F-cycle: an F-cycle on the coarse level followed by a V-cycle. The default (module
    /// docs: fewer cycles, flatter in n, and as fast or faster than V).
    #[default]
    F,
}

/// Multigrid settings.
#[derive(Debug, Clone, PartialEq)]
pub struct MgConfig {
    /// Cycle type.
    pub cycle: Cycle,
    /// Pre-smoothing sweeps.
    pub pre: usize,
    /// Post-smoothing sweeps.
    pub post: usize,
    /// Cycles without a 10 % gain on the best residual before [`Stop::Stalled`].
    pub stall_cycles: usize,
    /// Coarse levels: on cell-coarsened axes set the correction on the Dirichlet layer to
    /// −1/3 of its inward neighbour's after every sweep (linear extrapolation to zero at the
    /// parent layer's position, half a fine voxel inside the coarse layer); vertex axes keep
    /// zero. `false` keeps it zero everywhere. Default `false`. Measured with the earlier
    /// all-cell coarsening (not re-measured since): it lowered CDA's V-cycles to 1e-6 on the point source at
    /// n = 17, 33, 65 from 6, 8, 13 to 6, 7, 9 (FLD-LP: 6, 7, 8 either way), but makes
    /// FLD-LP at albedo 1 (17³) stall at R̄/j̄ ≈ 2·10⁻³ where it otherwise converges in 19
    /// cycles to 1e-9.
    pub extrapolated_layer: bool,
    /// How a coarse level's σ (the σ of D = F(R)/σ and of R) is formed from its parent's.
    pub coarse_sigma: CoarseSigma,
    /// Krylov acceleration of the cycles (Oosterlee & Washio's nonlinear Krylov subspace
    /// acceleration): before each cycle the fine φ is replaced by the combination of the last
    /// `krylov + 1` cycle results whose linearised residual is least (`Krylov`). 0 = plain
    /// cycles. Default measured in the module docs.
    pub krylov: usize,
    /// How a coarse level's D is formed (FLD limiters; CDA's D is fixed either way).
    pub coarse_d: CoarseD,
    /// How the coarse operators are formed: rediscretised (the default) or Galerkin
    /// (constant limiters on the CPU only).
    pub coarse_op: CoarseOp,
    /// The relaxation factor ω of the red-black smoother on every level (FLD Algorithm 1's
    /// SOR step; 1 = Gauss–Seidel), in (0, 2). Default 1.2: over-relaxed red-black smoothing
    /// took the same or fewer cycles than Gauss–Seidel in each of the 40 `multigrid_scaling`
    /// runs measured (every problem and limiter at n = 31…255), where larger ω did not
    /// (module docs, "The smoother's ω").
    pub smoother_omega: f64,
    /// Extra red-black sweeps, twice per cycle, on the finest level in a box around each
    /// point-like source (Brandt's local relaxation near singularities; [`POINT_SHARE`],
    /// [`MAX_BOXES`]); 0 = none. CPU only. Default 8 (module docs, "Local relaxation").
    pub local_sweeps: usize,
    /// The optical half-width τ₀ of those boxes (per axis ⌈τ₀ / (σΔl)⌉ voxels with the
    /// source voxel's σ, at most a quarter of the axis). Default 0.5.
    pub local_radius: f64,
    /// Start from a full-multigrid (FMG, nested-iteration) guess instead of φ = 0: the
    /// coarse problems at the starting φ are solved first, coarsest up, each level's solution
    /// prolongated to the next finer one and given one cycle there. Counted in the first
    /// cycle's work and time. Rediscretised coarse levels only (ignored with
    /// [`CoarseOp::Galerkin`]). Default measured in the module docs ("Full-multigrid start").
    pub full_multigrid: bool,
}

/// The operators of the coarse levels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum CoarseOp {
    /// The FLD operator rediscretised on each coarse level's restricted medium (with
    /// [`CoarseSigma`] and [`CoarseD`]): 7-point stencils, the red-black smoother of FLD
    /// Algorithm 1 on every level. The default.
    #[default]
    Rediscretised,
    /// A_c = R A P with the cycle's own transfers (27-point stencils, up to 125 along
    /// cell-coarsened axes), solved for the correction with a multi-colour Gauss–Seidel
    /// smoother. A constant limiter (CDA) on the CPU only: FLD's operator changes with φ.
    /// Measured in the module docs.
    Galerkin,
}

/// The D of the coarse levels of an FLD solve.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum CoarseD {
    /// Recomputed from the coarse φ on every coarse level and updated by its smoother: the
    /// FAS coarse problem is the nonlinear FLD equation itself.
    Recomputed,
    /// The mean of the finer level's D, fixed during the visit (coarse smoothers leave it
    /// alone): the coarse problem is the Picard linearisation at the fine φ. Slower per
    /// cycle in rate but free of the period-2 oscillation that stalls the FAS on the Fig 4
    /// cloud at n = 127 (module docs). CPU only.
    Restricted,
    /// [`CoarseD::Recomputed`] until the solve stalls, then [`CoarseD::Restricted`] for the
    /// rest of it (the stall rule starts afresh). On the GPU as `Recomputed`. The default.
    #[default]
    Auto,
}

/// The σ of a coarse level's diffusion coefficient (its absorption always keeps ∫σa).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum CoarseSigma {
    /// The harmonic mean of the children's σ (with the same weights as `Axis::mean`), so a
    /// constant limiter's coarse D is the mean of the fine D: a vacuum child (D = 1/(3σ_ε),
    /// a near-perfect conductor) keeps the coarse voxel conducting, as the fine faces'
    /// arithmetic mean of D does. The default; measured in the module docs.
    #[default]
    Harmonic,
    /// The arithmetic mean of σt (∫σt kept), the rediscretisation of the restricted medium
    /// (the first version): CDA diverges on the Fig 4 cloud with it.
    Arithmetic,
}

impl MgConfig {
    /// Typed errors for settings no solve can run with: no smoothing sweep at all, or a
    /// Krylov depth above [`MAX_KRYLOV`].
    pub fn validate(&self) -> Result<(), SolverError> {
        if self.pre + self.post == 0 {
            return Err(SolverError::BadParameter {
                name: "smoothing sweeps",
                value: 0.0,
                reason: "multigrid needs at least one pre- or post-smoothing sweep",
            });
        }
        if !(self.smoother_omega > 0.0 && self.smoother_omega < 2.0) {
            return Err(SolverError::BadParameter {
                name: "smoother_omega",
                value: self.smoother_omega,
                reason: "the smoother's relaxation factor must lie in (0, 2)",
            });
        }
        if !(self.local_radius.is_finite() && self.local_radius > 0.0) {
            return Err(SolverError::BadParameter {
                name: "local_radius",
                value: self.local_radius,
                reason: "the optical half-width of the local relaxation boxes must be finite and > 0",
            });
        }
        if self.local_sweeps > MAX_LOCAL_SWEEPS {
            return Err(SolverError::BadParameter {
                name: "local_sweeps",
                value: self.local_sweeps as f64,
                reason: "the local relaxation sweeps are an integer from 0 to 64",
            });
        }
        if self.krylov > MAX_KRYLOV {
            return Err(SolverError::BadParameter {
                name: "krylov",
                value: self.krylov as f64,
                reason: "the Krylov depth is an integer from 0 to 16",
            });
        }
        Ok(())
    }

    /// The settings the GPU multigrid runs ([`gpu`]): plain FAS cycles, without the CPU's
    /// Krylov acceleration and stall fallback.
    pub fn plain_fas(&self) -> Self {
        Self {
            krylov: 0,
            coarse_d: CoarseD::Recomputed,
            local_sweeps: 0,
            full_multigrid: false,
            ..self.clone()
        }
    }
}

impl Default for MgConfig {
    fn default() -> Self {
        Self {
            cycle: Cycle::F,
            pre: 2,
            post: 2,
            stall_cycles: 8,
            extrapolated_layer: false,
            coarse_sigma: CoarseSigma::Harmonic,
            krylov: 3,
            coarse_d: CoarseD::Auto,
            coarse_op: CoarseOp::Rediscretised,
            smoother_omega: 1.2,
            local_sweeps: 8,
            local_radius: 0.5,
            full_multigrid: true,
        }
    }
}

#[derive(Debug)]
struct Level<T> {
    fld: CpuFld<T>,
    grid: Grid,
    sig: Vec<f64>,
    absorb: Vec<f64>,
    /// R̂φ of the current visit (coarse levels), the base of the correction.
    base: Vec<f64>,
    /// Right-hand side of this level in natural layout: j/j̄ on the finest, the FAS
    /// right-hand side R(f − L(φ)) + L_c(R̂φ) of the current visit on coarse levels.
    rhs: Vec<f64>,
    /// D = 1/(3σ) when the limiter is constant (CDA): set once at setup, never recomputed
    /// (the smoother leaves D alone for CDA, so this is bit-identical to recomputing it).
    d_fixed: Option<Vec<f64>>,
    /// Per axis: this level was coarsened cell-wise from its parent (its layer lies half a
    /// parent voxel outside the parent's layer; see [`Axis`]).
    cell_axes: [bool; 3],
    /// Spare vectors of this level's length, reused from cycle to cycle (their values are
    /// stale: every user overwrites all of them). *Why*: allocating them afresh cost 13–15 %
    /// of a 127³ CDA solve in page clearing and `memset` (module docs).
    pool: Vec<Vec<f64>>,
}

/// The FAS multigrid solve of one medium (CPU, `f32` or `f64`).
#[derive(Debug)]
pub struct CpuMultigrid<T> {
    levels: Vec<Level<T>>,
    config: FldConfig,
    mg: MgConfig,
    floor: f64,
    tolerance: f64,
    trivial: bool,
    cycles: usize,
    work: f64,
    residuals: Vec<f64>,
    setup_seconds: f64,
    krylov: Krylov,
    estimate: ErrorEstimate,
    frozen: bool,
    /// A one-thread pool for the levels below `SERIAL_VOXELS` (`None` while in use, or if
    /// it could not be built: then everything runs on the global pool).
    serial: Option<rayon::ThreadPool>,
    /// [`CoarseOp::Galerkin`]: the operators of levels 1, 2, … (empty otherwise).
    galerkin: Vec<galerkin::BoxStencil>,
    /// [`MgConfig::local_sweeps`]: the boxes around the point-like sources of the finest
    /// level (empty if none or if the local relaxation is off).
    local: Vec<local::LocalBox>,
}

impl<T: Real> CpuMultigrid<T> {
    /// Validates the inputs (as [`CpuFld::new`]) and builds the level hierarchy.
    pub fn new(
        medium: &Medium<T>,
        boundary: &Boundary<T>,
        config: &FldConfig,
        mg: &MgConfig,
    ) -> Result<Self, SolverError> {
        let t0 = Instant::now();
        if config.vacuum_face == super::VacuumFace::Marshak {
            return Err(SolverError::Unsupported(
                "multigrid has the paper's vacuum face only (its residual operator does not \
                 know the Marshak face)"
                    .into(),
            ));
        }
        mg.validate()?;
        if mg.coarse_op == CoarseOp::Galerkin && !config.limiter.is_constant() {
            return Err(SolverError::Unsupported(
                "Galerkin coarse operators need a constant limiter (CDA): FLD's operator \
                 changes with phi"
                    .into(),
            ));
        }
        // The Krylov history: 2(k + 1) f64 vectors of the fine grid.
        crate::budget::check(
            format!("multigrid Krylov history (depth {})", mg.krylov),
            crate::budget::bytes(
                &[
                    medium.grid.len(),
                    2 * (mg.krylov + 1) * usize::from(mg.krylov > 0),
                ],
                8,
            ),
        )?;
        let (mut cfg, fine, floor) = fine_level(medium, boundary, config, mg.smoother_omega)?;
        let trivial = fine.is_trivial();
        cfg.residual_margin = fine.residual_margin();
        let tolerance = fine.tolerance();
        let mut levels = vec![Self::level(fine)];
        // Coarse media.
        let mut st: Vec<f64> = medium.sigma_t.iter().map(|x| x.f()).collect();
        let mut ss: Vec<f64> = medium
            .sigma_t
            .iter()
            .zip(&medium.albedo)
            .map(|(s, a)| s.f() * a.f())
            .collect();
        let mut g = medium.grid;
        let coarse_cfg = FldConfig {
            residual_margin: 0,
            ..cfg.clone()
        };
        while g.n.iter().all(|&n| n >= 6) && levels.len() < 16 {
            let (cg, cst, css) = restrict_medium(&g, &st, &ss)?;
            let albedo = cst
                .iter()
                .zip(&css)
                .map(|(&t, &s)| {
                    if t > 0.0 {
                        (s / t).clamp(0.0, 1.0)
                    } else {
                        0.0
                    }
                })
                .collect::<Vec<_>>();
            let cm = Medium::new(
                cg,
                cst.iter().map(|&x| T::c(x)).collect(),
                albedo.iter().map(|&x| T::c(x)).collect(),
                vec![T::zero(); cg.len()],
            )?;
            let mut lv = Self::level(CpuFld::mg_level(&cm, &coarse_cfg)?);
            lv.cell_axes = axes(&g).map(|a| !a.vertex);
            if mg.coarse_sigma == CoarseSigma::Harmonic {
                if let Some(parent) = levels.last() {
                    // D = F/σ averaged as the fine faces average it (arithmetically): σ by its
                    // harmonic mean; the absorption σaΔl² keeps ∫σa (the coarse Δl² is 4×).
                    let inv: Vec<f64> = parent.sig.iter().map(|s| 1.0 / s).collect();
                    let sig: Vec<f64> = restrict_mean(&g, &cg, &inv)
                        .iter()
                        .map(|x| 1.0 / x)
                        .collect();
                    let absorb: Vec<f64> = restrict_mean(&g, &cg, &parent.absorb)
                        .iter()
                        .map(|x| 4.0 * x)
                        .collect();
                    lv.fld.mg_set(3, &sig);
                    lv.fld.mg_set(4, &absorb);
                    lv.sig = sig;
                    lv.absorb = absorb;
                }
            }
            levels.push(lv);
            (g, st, ss) = (cg, cst, css);
        }
        if cfg.limiter.is_constant() {
            for lv in &mut levels {
                let d = fresh_d(&lv.grid, &[], &lv.sig, &cfg, floor);
                lv.fld.mg_set(1, &d);
                lv.d_fixed = Some(d);
            }
        }
        let mut solve = Self {
            levels,
            config: cfg,
            mg: mg.clone(),
            floor,
            tolerance,
            trivial,
            cycles: 0,
            work: 0.0,
            residuals: Vec::new(),
            setup_seconds: t0.elapsed().as_secs_f64(),
            krylov: Krylov::new(mg.krylov),
            estimate: ErrorEstimate::default(),
            frozen: false,
            serial: rayon::ThreadPoolBuilder::new().num_threads(1).build().ok(),
            galerkin: Vec::new(),
            local: Vec::new(),
        };
        if mg.local_sweeps > 0 && !trivial {
            let f = &solve.levels[0];
            solve.local = local::source_boxes(&f.grid, &f.rhs, &f.sig, mg.local_radius);
        }
        if mg.coarse_op == CoarseOp::Galerkin {
            solve.build_galerkin()?;
        }
        if mg.coarse_d == CoarseD::Restricted {
            solve.freeze_coarse_d();
        }
        // The local boxes and the Galerkin operators are setup too.
        solve.setup_seconds = t0.elapsed().as_secs_f64();
        Ok(solve)
    }

    /// Builds the Galerkin operators of every coarse level ([`CoarseOp::Galerkin`]; the
    /// limiter is constant, so the finest level's D is fixed).
    fn build_galerkin(&mut self) -> Result<(), SolverError> {
        // The stencils' memory first: a typed error instead of an allocation abort.
        let mut radius = [1usize; 3];
        let mut entries = 0u64;
        for l in 0..self.levels.len() - 1 {
            radius = galerkin::coarse_radius(&self.levels[l].grid, radius);
            let per_voxel = radius.iter().map(|r| 2 * r + 1).product::<usize>();
            entries = entries.saturating_add(crate::budget::bytes(
                &[self.levels[l + 1].grid.len(), per_voxel],
                1,
            ));
        }
        crate::budget::check(
            "multigrid Galerkin coarse stencils",
            entries.saturating_mul(8),
        )?;
        for l in 0..self.levels.len() - 1 {
            let (fg, cg) = (self.levels[l].grid, self.levels[l + 1].grid);
            let op = if l == 0 {
                let lv = &self.levels[0];
                let d = lv.d_fixed.as_deref().unwrap_or_default();
                galerkin::BoxStencil::galerkin(&fg, &cg, [1; 3], |x, out| {
                    apply_into(&fg, x, d, &lv.absorb, None, out)
                })
            } else {
                let finer = &self.galerkin[l - 1];
                galerkin::BoxStencil::galerkin(&fg, &cg, finer.radius(), |x, out| {
                    finer.residual_into(x, None, out)
                })
            };
            self.galerkin.push(op);
        }
        Ok(())
    }

    /// The linear cycle of the Galerkin levels ([`CoarseOp::Galerkin`]) on level `l` ≥ 1:
    /// improves the correction `e` of A_l e = f.
    fn galerkin_cycle(&mut self, l: usize, e: &mut [f64], f: &[f64], kind: Cycle) {
        let op_index = l - 1;
        let mut scratch = self.take(l);
        if l + 1 == self.levels.len() {
            let mut r = self.take(l);
            let norm = |r: &[f64]| r.iter().map(|x| x * x).sum::<f64>();
            self.galerkin[op_index].residual_into(e, Some(f), &mut r);
            let r0 = norm(&r);
            for _ in 0..200 {
                self.galerkin_sweep(l, e, f, &mut scratch);
                self.galerkin[op_index].residual_into(e, Some(f), &mut r);
                let rr = norm(&r);
                if rr.is_nan() || rr <= 1e-6 * r0 {
                    break;
                }
            }
            self.give(l, r);
            self.give(l, scratch);
            return;
        }
        for _ in 0..self.mg.pre {
            self.galerkin_sweep(l, e, f, &mut scratch);
        }
        let mut r = self.take(l);
        self.galerkin[op_index].residual_into(e, Some(f), &mut r);
        self.galerkin_correct(l, r, kind, e, false);
        for _ in 0..self.mg.post {
            self.galerkin_sweep(l, e, f, &mut scratch);
        }
        self.give(l, scratch);
    }

    /// One Gauss–Seidel sweep of level `l`'s Galerkin operator, counted as work.
    fn galerkin_sweep(&mut self, l: usize, e: &mut [f64], f: &[f64], scratch: &mut [f64]) {
        self.galerkin[l - 1].sweep(e, f, scratch);
        self.count_sweep(l);
    }

    /// The coarse-grid correction of the Galerkin levels: restricts level `l`'s residual `r`
    /// (returned to the pool), solves A_{l+1} e = R r from e = 0 with one cycle of `kind`
    /// (F: then one V), and adds P e to `x` (projected onto x ≥ 0 for the fine φ, not for a
    /// correction).
    fn galerkin_correct(
        &mut self,
        l: usize,
        r: Vec<f64>,
        kind: Cycle,
        x: &mut [f64],
        project: bool,
    ) {
        let (fg, cg) = (self.levels[l].grid, self.levels[l + 1].grid);
        let mut fc = self.take(l + 1);
        restrict_fw_into(&fg, &cg, &r, &mut fc);
        self.give(l, r);
        let mut e = self.take(l + 1);
        e.par_iter_mut().for_each(|v| *v = 0.0);
        self.galerkin_visit(l + 1, &mut e, &fc, kind);
        if kind == Cycle::F {
            self.galerkin_visit(l + 1, &mut e, &fc, Cycle::V);
        }
        prolong_add(&fg, &cg, &e, x, project);
        self.give(l + 1, e);
        self.give(l + 1, fc);
    }

    /// [`CpuMultigrid::galerkin_cycle`] on one thread if level `l` is small.
    fn galerkin_visit(&mut self, l: usize, e: &mut [f64], f: &[f64], kind: Cycle) {
        self.sized(l, |mg| mg.galerkin_cycle(l, e, f, kind));
    }

    /// Switches the coarse levels to [`CoarseD::Restricted`] (their smoothers stop updating
    /// D; each visit sets it from the finer level) and restarts the Krylov history. Returns
    /// `false`, changing nothing, if they are frozen already or the limiter is constant (CDA's
    /// D is fixed anyway).
    fn freeze_coarse_d(&mut self) -> bool {
        if self.frozen || self.config.limiter.is_constant() {
            return false;
        }
        self.frozen = true;
        for lv in self.levels.iter_mut().skip(1) {
            lv.fld.mg_freeze_d();
        }
        for v in self.krylov.clear() {
            self.give(0, v);
        }
        true
    }

    fn level(fld: CpuFld<T>) -> Level<T> {
        let [sig, absorb] = fld.mg_fields();
        Level {
            grid: *fld.grid(),
            rhs: fld.mg_rhs(),
            fld,
            sig,
            absorb,
            base: Vec::new(),
            d_fixed: None,
            pool: Vec::new(),
            cell_axes: [false; 3],
        }
    }

    /// Number of levels (1 = no coarse level; the grid is too small to coarsen).
    pub fn levels(&self) -> usize {
        self.levels.len()
    }

    /// Work units spent so far (one = one fine red-black sweep).
    pub fn work_units(&self) -> f64 {
        self.work
    }

    /// R̄/j̄ after each cycle.
    pub fn residuals(&self) -> &[f64] {
        &self.residuals
    }

    /// A spare vector of level `l`'s length (stale values) from its pool, or a new one
    /// zeroed by every thread ([`par_zeroed`]) when the pool is empty.
    fn take(&mut self, l: usize) -> Vec<f64> {
        let lv = &mut self.levels[l];
        let len = lv.grid.len();
        match lv.pool.pop() {
            Some(mut v) => {
                v.resize(len, 0.0);
                v
            }
            None => par_zeroed(len),
        }
    }

    /// Returns `v` (a vector, or the optional D of [`CpuMultigrid::fresh_d`]) to level `l`'s
    /// pool.
    fn give(&mut self, l: usize, v: impl Into<Option<Vec<f64>>>) {
        self.levels[l].pool.extend(v.into());
    }

    /// D of level `l` at φ in a pooled vector, or `None` for a constant limiter (whose D is
    /// the level's `d_fixed`).
    fn fresh_d(&mut self, l: usize, phi: &[f64]) -> Option<Vec<f64>> {
        if self.levels[l].d_fixed.is_some() {
            return None;
        }
        let mut d = self.take(l);
        let lv = &self.levels[l];
        fresh_d_into(&lv.grid, phi, &lv.sig, &self.config, self.floor, &mut d);
        Some(d)
    }

    /// The D to use on level `l`: `fresh` if recomputed, else the fixed D ([`CpuMultigrid::fresh_d`]
    /// returns `None` only when there is one).
    fn d_of<'s>(&'s self, l: usize, fresh: &'s Option<Vec<f64>>) -> &'s [f64] {
        fresh
            .as_deref()
            .or(self.levels[l].d_fixed.as_deref())
            .unwrap_or_default()
    }

    /// Adds one smoothing sweep on level `l` to the work: 8^(−l) fine sweeps.
    fn count_sweep(&mut self, l: usize) {
        self.work += 0.125f64.powi(l as i32);
    }

    fn sweep(&mut self, l: usize) -> f64 {
        let r = self.levels[l].fld.mg_sweep();
        self.count_sweep(l);
        if l > 0 && self.mg.extrapolated_layer {
            let lv = &mut self.levels[l];
            let mut phi = lv.fld.mg_phi();
            extrapolate_layer(&lv.grid, lv.cell_axes, &lv.base, &mut phi);
            lv.fld.mg_set(0, &phi);
        }
        r
    }

    /// Residual f − L(φ) with D recomputed from φ (0 on the Dirichlet layer), in one pass
    /// ([`apply_into`] with the right-hand side), in a pooled vector.
    fn residual(&mut self, l: usize, phi: &[f64], d: &Option<Vec<f64>>) -> Vec<f64> {
        let mut r = self.take(l);
        let lv = &self.levels[l];
        apply_into(
            &lv.grid,
            phi,
            self.d_of(l, d),
            &lv.absorb,
            Some(&lv.rhs),
            &mut r,
        );
        r
    }

    fn cycle_at(&mut self, l: usize, kind: Cycle) {
        if l + 1 == self.levels.len() {
            let mut first = None;
            for _ in 0..200 {
                let r = self.sweep(l);
                let r0 = *first.get_or_insert(r);
                if r.is_nan() || r <= 1e-3 * r0 {
                    break;
                }
            }
            return;
        }
        for _ in 0..self.mg.pre {
            self.sweep(l);
        }
        if self.galerkin.is_empty() {
            self.fas_correct(l, |mg| {
                mg.visit(l + 1, kind);
                if kind == Cycle::F {
                    mg.visit(l + 1, Cycle::V);
                }
            });
        } else {
            // [`CoarseOp::Galerkin`] (l = 0): the coarse levels solve for the correction.
            let (mut phi, d, r) = self.phi_and_residual(l);
            self.give(l, d);
            self.galerkin_correct(l, r, kind, &mut phi, true);
            self.hand_back(l, phi);
        }
        for _ in 0..self.mg.post {
            self.sweep(l);
        }
    }

    /// Level l's φ (natural layout), its D (`None` for a constant limiter) and its residual,
    /// in pooled vectors.
    fn phi_and_residual(&mut self, l: usize) -> (Vec<f64>, Option<Vec<f64>>, Vec<f64>) {
        let mut phi = self.take(l);
        self.levels[l].fld.mg_phi_into(&mut phi);
        let d = self.fresh_d(l, &phi);
        let r = self.residual(l, &phi, &d);
        (phi, d, r)
    }

    /// The FAS coarse-grid correction of level l: the coarse problem at the current φ is set
    /// up, `solve_coarse` solves it, and the correction goes back to level l's smoother.
    fn fas_correct(&mut self, l: usize, solve_coarse: impl FnOnce(&mut Self)) {
        let (mut phi, d, r) = self.phi_and_residual(l);
        let phi_c0 = self.coarse_problem(l, &phi, d, r);
        solve_coarse(self);
        self.correct(l, &mut phi, phi_c0);
        self.hand_back(l, phi);
    }

    /// Hands a corrected φ of level l back to its smoother, the finest level's local boxes
    /// relaxed first.
    fn hand_back(&mut self, l: usize, mut phi: Vec<f64>) {
        if l == 0 {
            self.relax_locally(&mut phi);
        }
        self.set_phi(l, phi);
    }

    /// Sets up level l + 1's FAS problem at level l's φ (natural layout) with its D (`None`
    /// for a constant limiter) and residual `r` (both returned to the pool); returns R̂φ.
    fn coarse_problem(
        &mut self,
        l: usize,
        phi: &[f64],
        d: Option<Vec<f64>>,
        r: Vec<f64>,
    ) -> Vec<f64> {
        let (fg, cg) = (self.levels[l].grid, self.levels[l + 1].grid);
        if self.frozen {
            // Picard coarse levels: D of the coarse level = the mean of the fine D (as the
            // harmonic σ makes it for a constant limiter), fixed for this visit.
            let dc = restrict_mean(&fg, &cg, self.d_of(l, &d));
            let c = &mut self.levels[l + 1];
            c.fld.mg_set(1, &dc);
            c.d_fixed = Some(dc);
        }
        self.give(l, d);
        let mut phi_c0 = self.take(l + 1);
        restrict_mean_into(&fg, &cg, phi, &mut phi_c0);
        // `None` for a constant limiter: the coarse D is fixed and already in place.
        let d_c = self.fresh_d(l + 1, &phi_c0);
        let mut lc = self.take(l + 1);
        apply_into(
            &cg,
            &phi_c0,
            self.d_of(l + 1, &d_c),
            &self.levels[l + 1].absorb,
            None,
            &mut lc,
        );
        let mut fc = self.take(l + 1);
        restrict_fw_into(&fg, &cg, &r, &mut fc);
        self.give(l, r);
        fc.par_iter_mut().zip(&lc).for_each(|(a, b)| *a += b);
        self.give(l + 1, lc);
        let old_rhs = {
            let c = &mut self.levels[l + 1];
            c.fld.mg_set(0, &phi_c0);
            if let Some(d_c) = &d_c {
                c.fld.mg_set(1, d_c);
            }
            c.fld.mg_set(2, &fc);
            c.base.clone_from(&phi_c0);
            std::mem::replace(&mut c.rhs, fc)
        };
        self.give(l + 1, old_rhs);
        self.give(l + 1, d_c);
        phi_c0
    }

    /// Adds the correction P(φ_c − R̂φ) of level l + 1 to level l's φ (natural layout);
    /// `phi_c0` is R̂φ ([`CpuMultigrid::coarse_problem`]).
    fn correct(&mut self, l: usize, phi: &mut [f64], phi_c0: Vec<f64>) {
        let (fg, cg) = (self.levels[l].grid, self.levels[l + 1].grid);
        // The correction e = φ_c − R̂φ, in the vector that held φ_c.
        let mut e = self.take(l + 1);
        self.levels[l + 1].fld.mg_phi_into(&mut e);
        e.par_iter_mut().zip(&phi_c0).for_each(|(a, b)| *a -= b);
        prolong_add(&fg, &cg, &e, phi, true);
        self.give(l + 1, e);
        self.give(l + 1, phi_c0);
    }

    /// The full-multigrid start ([`MgConfig::full_multigrid`]) from level l down: the
    /// coarse problem at the current φ solved by this recursively, its correction added, and
    /// one cycle on level l unless l = 0 (the solve's cycles follow).
    fn fmg_at(&mut self, l: usize) {
        if l + 1 == self.levels.len() {
            self.cycle_at(l, Cycle::V);
            return;
        }
        self.fas_correct(l, |mg| mg.sized(l + 1, |mg| mg.fmg_at(l + 1)));
        if l > 0 {
            self.cycle_at(l, self.mg.cycle);
        }
    }

    /// [`MgConfig::local_sweeps`] sweeps over every local box of the finest level, on φ in
    /// natural layout (the caller hands it to the smoother).
    fn relax_locally(&mut self, phi: &mut [f64]) {
        if self.local.is_empty() {
            return;
        }
        let lv = &self.levels[0];
        let f = local::Fields {
            grid: &lv.grid,
            rhs: &lv.rhs,
            sig: &lv.sig,
            absorb: &lv.absorb,
            d_fixed: lv.d_fixed.as_deref(),
            config: &self.config,
            floor: self.floor,
            omega: self.mg.smoother_omega,
        };
        let sweeps = self.mg.local_sweeps;
        for b in &self.local {
            local::relax(&f, b, phi, sweeps);
        }
        let voxels: usize = self.local.iter().map(local::LocalBox::len).sum();
        self.work += (sweeps * voxels) as f64 / lv.grid.len() as f64;
    }

    /// Hands φ (natural layout, a pooled vector) to level `l`'s smoother with D recomputed
    /// from it (FLD), and returns the vectors to the pool.
    fn set_phi(&mut self, l: usize, phi: Vec<f64>) {
        let d = self.fresh_d(l, &phi);
        let fl = &mut self.levels[l].fld;
        fl.mg_set(0, &phi);
        if let Some(d) = &d {
            fl.mg_set(1, d);
        }
        self.give(l, phi);
        self.give(l, d);
    }

    /// Runs one cycle and returns R̄/j̄ after it.
    pub fn cycle(&mut self) -> f64 {
        self.cycle_estimate().0
    }

    /// [`CpuMultigrid::cycle_at`] level `l`, on one thread if the level is small.
    fn visit(&mut self, l: usize, kind: Cycle) {
        self.sized(l, |mg| mg.cycle_at(l, kind));
    }

    /// Runs `f` inside the one-thread pool if level `l` has fewer than `SERIAL_VOXELS`
    /// voxels (inline when already inside that pool), else on the current pool.
    fn sized<R: Send>(&mut self, l: usize, f: impl FnOnce(&mut Self) -> R + Send) -> R {
        if self.levels[l].grid.len() >= SERIAL_VOXELS {
            return f(self);
        }
        match self.serial.take() {
            Some(pool) => {
                let r = pool.install(|| f(self));
                self.serial = Some(pool);
                r
            }
            None => f(self),
        }
    }

    /// One cycle: R̄/j̄ after it and the error estimate of [`ErrorEstimate`] (0 and 0 for the
    /// trivial problem).
    fn cycle_estimate(&mut self) -> (f64, f64) {
        self.sized(0, |mg| mg.cycle_estimate_on())
    }

    /// [`CpuMultigrid::cycle_estimate`] on the current pool.
    fn cycle_estimate_on(&mut self) -> (f64, f64) {
        if self.trivial {
            self.cycles += 1;
            self.residuals.push(0.0);
            return (0.0, 0.0);
        }
        if self.krylov.ready() {
            let mut acc = self.take(0);
            self.krylov.combine(&mut acc);
            self.set_phi(0, acc);
        }
        if self.cycles == 0 && self.mg.full_multigrid && self.galerkin.is_empty() {
            self.fmg_at(0);
        }
        self.cycle_at(0, self.mg.cycle);
        let mut phi = self.take(0);
        self.levels[0].fld.mg_phi_into(&mut phi);
        self.relax_locally(&mut phi);
        let d = self.fresh_d(0, &phi);
        // The smoother's state follows the relaxed boxes (φ, and D one voxel around them).
        for b in &self.local {
            let fl = &mut self.levels[0].fld;
            fl.mg_set_box(0, &phi, b.lo, b.hi);
            if let Some(d) = &d {
                let e = b.grown(1);
                fl.mg_set_box(1, d, e.lo, e.hi);
            }
        }
        let r = self.residual(0, &phi, &d);
        self.give(0, d);
        let w = ResidualWindow::new(&self.levels[0].grid, self.config.residual_margin);
        let [nx, ny, _] = self.levels[0].grid.n;
        // Per-slab partial sums added in slab order: the same sum for any thread count.
        let partial: Vec<f64> = r
            .par_chunks(nx * ny)
            .enumerate()
            .map(|(k, slab)| {
                let mut s = 0.0;
                for j in 0..ny {
                    if w.counts_row(j, k) {
                        for v in &slab[j * nx + w.lo..=j * nx + w.hi[0]] {
                            s += v * v;
                        }
                    }
                }
                s
            })
            .collect();
        let sumsq: f64 = partial.iter().sum();
        let res = w.rms(sumsq);
        let e = self.estimate.update(&phi);
        if self.krylov.depth > 0 {
            // φ and r move into the history (no copy); what it drops returns to the pool.
            for v in self.krylov.push(phi, r, res) {
                self.give(0, v);
            }
        } else {
            self.give(0, r);
            self.give(0, phi);
        }
        self.cycles += 1;
        self.residuals.push(res);
        (res, e)
    }

    /// As [`CpuMultigrid::solve_observed`] without an observer.
    pub fn solve(self) -> FldSolution<T> {
        self.solve_observed(|_, _| {})
    }

    /// Cycles until R̄/j̄ < tolerance, the cap (`max_iterations` cycles), a stall or a
    /// non-finite residual; `observer(cycle, residual)` after every cycle.
    pub fn solve_observed(mut self, mut observer: impl FnMut(usize, f64)) -> FldSolution<T> {
        let t0 = Instant::now();
        let mut reached = self.trivial.then_some(0.0);
        let status = if self.trivial {
            Stop::Converged
        } else {
            let (max, tol, stall) = (
                self.config.max_iterations,
                self.tolerance,
                self.mg.stall_cycles,
            );
            // The stop reads max(R̄/j̄, the error estimate of [`ErrorEstimate`]); the observer
            // and the residual history keep R̄/j̄ itself.
            let residual = std::cell::Cell::new(f64::NAN);
            loop {
                let stop = super::iterate(
                    self.cycles,
                    max,
                    tol,
                    Some(stall),
                    || {
                        let (r, e) = self.cycle_estimate();
                        if r < tol && reached.is_none() {
                            reached = Some(t0.elapsed().as_secs_f64());
                        }
                        residual.set(r);
                        (self.cycles, r.max(e))
                    },
                    |k, _| observer(k, residual.get()),
                );
                // [`CoarseD::Auto`]: a stalled FAS goes on with Picard coarse levels.
                if stop == Stop::Stalled
                    && self.mg.coarse_d == CoarseD::Auto
                    && self.freeze_coarse_d()
                {
                    continue;
                }
                break stop;
            }
        };
        let seconds = t0.elapsed().as_secs_f64();
        let fine = &self.levels[0];
        let grid = fine.grid;
        let scale = fine.fld.phi_unit();
        let phi = fine.fld.mg_phi().iter().map(|&x| T::c(x * scale)).collect();
        let mut sol = super::solution(
            grid,
            phi,
            std::mem::take(&mut self.residuals),
            self.cycles,
            status,
            seconds,
            self.setup_seconds,
            Timer::WallClock,
        );
        sol.trace.work_units = self.work;
        sol.trace.solver = "multigrid".into();
        sol.trace.seconds_to_tolerance = reached;
        sol
    }
}

/// The finest level's settings (the smoother's ω, [`MgConfig::smoother_omega`]; σ_ε made
/// explicit, so the coarse levels keep the finest grid's), its smoother and the floor of R's
/// numerator and denominator (ε of FLD Eq 35, at least the smallest positive `T`).
fn fine_level<T: Real>(
    medium: &Medium<T>,
    boundary: &Boundary<T>,
    config: &FldConfig,
    omega: f64,
) -> Result<(FldConfig, CpuFld<T>, f64), SolverError> {
    let mut cfg = config.clone();
    cfg.omega = omega;
    cfg.sigma_eps = Some(config.sigma_eps.unwrap_or(1e-3 / medium.grid.extent()));
    let fine = CpuFld::new(medium, boundary, &cfg)?;
    let floor = cfg
        .epsilon
        .unwrap_or(T::DEFAULT_EPSILON)
        .max(T::min_positive_value().f());
    Ok((cfg, fine, floor))
}

/// D = F(R)/σ (FLD Eqs 33–35) of `medium` under `boundary` at `phi` (physical units,
/// natural layout), as the CPU multigrid's residual evaluates it in f64: σ floored at σ_ε as
/// the solver floors it (`config.sigma_eps`), φ normalised by the solver's j̄, centred
/// differences inside and one-sided ones on the Dirichlet layer. A diagnostic of the
/// coefficient contrast a solve faces (module docs, "Why the cloud's FLD-LP cycles grow").
/// Errors: `phi` not as long as the grid, or a medium, boundary or configuration the solver
/// refuses.
pub fn diffusion_field<T: Real>(
    medium: &Medium<T>,
    boundary: &Boundary<T>,
    phi: &[f64],
    config: &FldConfig,
) -> Result<Vec<f64>, SolverError> {
    let g = medium.grid;
    if phi.len() != g.len() {
        return Err(SolverError::FieldSize {
            field: "phi",
            expected: g.len(),
            got: phi.len(),
        });
    }
    // ω plays no part in D.
    let (cfg, fine, floor) = fine_level(medium, boundary, config, 1.0)?;
    let scale = 1.0 / fine.phi_unit();
    let [sig, _] = fine.mg_fields();
    drop(fine);
    let normalised: Vec<f64> = phi.par_iter().map(|x| x * scale).collect();
    Ok(fresh_d(&g, &normalised, &sig, &cfg, floor))
}

/// A zeroed vector of `len` values written by every thread of the pool. *Why*: a fresh
/// fine-grid vector's pages are faulted in and cleared by the kernel on first touch, and a
/// serial `resize` did that on one thread: the Krylov history alone takes 8 fine vectors as
/// it fills (1.1 GB at 255³), so most of a 255³ solve's page faults fell in its first cycles.
fn par_zeroed(len: usize) -> Vec<f64> {
    (0..len).into_par_iter().map(|_| 0.0).collect()
}

/// Levels with fewer voxels than this (about 34³) run on one thread, inside a one-thread
/// pool so that every parallel loop of theirs runs inline. *Why*: a cycle issues dozens of
/// parallel loops per level visit, and on small levels waking the pool's workers costs more
/// than the loop (`perf` of a 19³ CDA solve: `sched_yield` and the scheduler took most of the
/// samples; 5 cycles took 17 ms where the arithmetic is well under 1 ms). Measured
/// (2026-12-06, 2-vCPU AMD EPYC, point source, seconds of the solve, threshold 0 → 40000 →
/// 110000): n = 31 CDA 0.024 → 0.012 → 0.011, FLD-LP 0.093 → 0.077 → 0.075; n = 47 CDA
/// 0.048 → 0.030 → 0.034, FLD-LP 0.194 → 0.158 → 0.209; n = 63 CDA 0.077 → 0.060 → 0.054,
/// FLD-LP 0.385 → 0.366 → 0.345; n = 127 CDA 0.397 → 0.379 → 0.375, FLD-LP 2.31 → 2.30 →
/// 2.27 (a 270000 threshold, which puts 63³ on one thread, made 63³ FLD-LP 0.52 s). The
/// arithmetic and the order of every sum are the same on any number of threads, so φ is
/// bit-identical.
const SERIAL_VOXELS: usize = 40_000;

/// A cycle whose R̄/j̄ grows by this factor or more restarts the Krylov history. *Why not
/// 1 (any growth)*: on shell_core (18³, CDA) the residual alternates up and down by a few
/// per cent for the first cycles, so a restart on any growth kept the history at one or
/// two entries and the solve stalled at R̄/j̄ 0.81 after 12 cycles; with 1.5 (or never) it
/// converges to 10⁻⁶ in 16. Elsewhere 1, 1.5 and ∞ gave the same cycles but for FLD-LP on
/// the Fig 4 cloud at n = 127 (108, 108, 115).
const RESTART_GROWTH: f64 = 1.5;

/// Nonlinear Krylov subspace acceleration of the cycles (Oosterlee & Washio, SIAM J. Sci.
/// Comput. 21, 2000): with the last m + 1 cycle results φ_0 … φ_m (φ_m the newest) and their
/// residuals r_i = f − L(φ_i) (D recomputed, the stop's residual), the next cycle starts from
/// φ_m + Σ α_i (φ_i − φ_m) with α minimising ‖r_m + Σ α_i (r_i − r_m)‖₂, the residual of
/// the combination were L linear (for CDA it is: this is GMRES-like acceleration of the
/// cycle; for FLD a multisecant step). The combination is projected to φ ≥ 0 as the smoother
/// projects. A cycle that ends with `RESTART_GROWTH` times the R̄/j̄ of the one before
/// drops the history but for its own result (a restart). The Gram matrix of the residuals is kept up to date
/// with one pass per cycle (sums per chunk added in chunk order: the same for any thread
/// count).
#[derive(Debug, Default)]
struct Krylov {
    depth: usize,
    /// (φ_i, r_i) oldest first, at most depth + 1.
    history: std::collections::VecDeque<(Vec<f64>, Vec<f64>)>,
    /// ⟨r_i, r_j⟩ in history order.
    gram: Vec<Vec<f64>>,
    /// R̄/j̄ of the newest result.
    last: f64,
}

impl Krylov {
    fn new(depth: usize) -> Self {
        Self {
            depth,
            last: f64::INFINITY,
            ..Self::default()
        }
    }

    /// The length of the chunks whose partial sums are added in chunk order (a function of
    /// the grid alone, so the sums are the same for any thread count).
    fn chunk(len: usize) -> usize {
        (len / 64).max(4096)
    }

    /// Whether there are at least two results to combine.
    fn ready(&self) -> bool {
        self.depth > 0 && self.history.len() >= 2
    }

    /// Empties the history; returns its vectors.
    fn clear(&mut self) -> Vec<Vec<f64>> {
        self.gram.clear();
        self.last = f64::INFINITY;
        self.history.drain(..).flat_map(|(p, q)| [p, q]).collect()
    }

    /// Records a cycle result; returns vectors no longer needed.
    fn push(&mut self, phi: Vec<f64>, r: Vec<f64>, res: f64) -> Vec<Vec<f64>> {
        let mut spare = Vec::new();
        if !res.is_finite() || res >= RESTART_GROWTH * self.last {
            // A restart: the last combination did not help (or the cycle diverged).
            spare = self.clear();
        }
        if self.history.len() > self.depth {
            if let Some((p, q)) = self.history.pop_front() {
                spare.push(p);
                spare.push(q);
            }
            self.gram.remove(0);
            for row in &mut self.gram {
                row.remove(0);
            }
        }
        self.last = res;
        let k = self.history.len();
        let slab = Self::chunk(r.len());
        let partial: Vec<Vec<f64>> = r
            .par_chunks(slab)
            .enumerate()
            .map(|(c, rc)| {
                let lo = c * slab;
                let mut s = vec![0.0; k + 1];
                for (i, (_, q)) in self.history.iter().enumerate() {
                    s[i] = rc
                        .iter()
                        .zip(&q[lo..lo + rc.len()])
                        .map(|(a, b)| a * b)
                        .sum();
                }
                s[k] = rc.iter().map(|a| a * a).sum();
                s
            })
            .collect();
        let mut dots = vec![0.0; k + 1];
        for p in &partial {
            for (d, x) in dots.iter_mut().zip(p) {
                *d += x;
            }
        }
        for (row, &d) in self.gram.iter_mut().zip(&dots) {
            row.push(d);
        }
        self.gram.push(dots);
        self.history.push_back((phi, r));
        spare
    }

    /// Writes the combination into `out` (the fine grid's length).
    fn combine(&self, out: &mut [f64]) {
        let m = self.history.len() - 1;
        let g = &self.gram;
        // Normal equations A α = −c of min ‖r_m + Σ α_i (r_i − r_m)‖.
        let mut a = vec![vec![0.0; m + 1]; m];
        for i in 0..m {
            for j in 0..m {
                a[i][j] = g[i][j] - g[i][m] - g[j][m] + g[m][m];
            }
            a[i][m] = -(g[i][m] - g[m][m]);
        }
        let alpha = solve_small(a).unwrap_or_else(|| vec![0.0; m]);
        let w0 = 1.0 - alpha.iter().sum::<f64>();
        let slab = Self::chunk(out.len());
        out.par_chunks_mut(slab).enumerate().for_each(|(c, oc)| {
            let (lo, len) = (c * slab, oc.len());
            let newest = &self.history[m].0[lo..lo + len];
            for (o, x) in oc.iter_mut().zip(newest) {
                *o = w0 * x;
            }
            for (al, (p, _)) in alpha.iter().zip(&self.history) {
                for (o, x) in oc.iter_mut().zip(&p[lo..lo + len]) {
                    *o += al * x;
                }
            }
            for o in oc.iter_mut() {
                *o = o.max(0.0);
            }
        });
    }
}

/// Gaussian elimination with partial pivoting of the m × (m + 1) augmented system `a`; a
/// diagonal shift of 10⁻¹² of the largest diagonal keeps a nearly dependent history solvable.
/// `None` if it is singular even so.
fn solve_small(mut a: Vec<Vec<f64>>) -> Option<Vec<f64>> {
    let m = a.len();
    let scale = (0..m).map(|i| a[i][i]).fold(0.0f64, f64::max);
    if scale.is_nan() || scale <= 0.0 || !scale.is_finite() {
        return None;
    }
    for (i, row) in a.iter_mut().enumerate() {
        row[i] += 1e-12 * scale;
    }
    for c in 0..m {
        let p = (c..m).max_by(|&x, &y| a[x][c].abs().total_cmp(&a[y][c].abs()))?;
        a.swap(c, p);
        if a[c][c] == 0.0 {
            return None;
        }
        let (top, rest) = a.split_at_mut(c + 1);
        let pivot = &top[c];
        for row in rest {
            let f = row[c] / pivot[c];
            for (x, p) in row[c..].iter_mut().zip(&pivot[c..]) {
                *x -= f * p;
            }
        }
    }
    let mut x = vec![0.0; m];
    for c in (0..m).rev() {
        let s: f64 = (c + 1..m).map(|k| a[c][k] * x[k]).sum();
        x[c] = (a[c][m] - s) / a[c][c];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// The error estimate of the multigrid stop: ‖φ_k − φ_{k−1}‖/‖φ_k‖ · 1/(1 − ρ̂), ρ̂ the ratio of
/// the last two update norms (the contraction per cycle), 1 ("not converged") until two
/// updates are known or while ρ̂ ≥ 1. *Why*: on the lit albedo-1 cubes `cda:mg` reached
/// R̄/j̄ = 5.8·10⁻⁷ after one cycle with φ 11 % from its own tight solve (σt·Δl = 60; 4.7 %
/// after 2 cycles at 6), because σa = 0 leaves the operator's smallest eigenvalue ~D(π/L)²
/// tiny, so a small residual bounds the error poorly (issue 12 item 4; `convergence_check`
/// and `solvers/tests/default_stop.rs`). The same rule stops the registered RDE.
#[derive(Debug, Default)]
struct ErrorEstimate {
    previous: Option<Vec<f64>>,
    contraction: Contraction,
}

impl ErrorEstimate {
    /// Feeds the φ of the next cycle; returns the estimate. The sums run in parallel over
    /// fixed chunks added in chunk order (the same for any thread count), and the copy of φ
    /// rides along in the same pass.
    fn update(&mut self, phi: &[f64]) -> f64 {
        const CHUNK: usize = 1 << 14;
        let (dd, pp) = match &mut self.previous {
            Some(prev) => prev
                .par_chunks_mut(CHUNK)
                .zip(phi.par_chunks(CHUNK))
                .map(|(p, a)| {
                    let (mut dd, mut pp) = (0.0f64, 0.0f64);
                    for (b, &a) in p.iter_mut().zip(a) {
                        dd += (a - *b) * (a - *b);
                        pp += a * a;
                        *b = a;
                    }
                    (dd, pp)
                })
                .collect::<Vec<_>>()
                .iter()
                .fold((0.0, 0.0), |s, x| (s.0 + x.0, s.1 + x.1)),
            None => {
                self.previous = Some(phi.par_iter().copied().collect());
                (0.0, 0.0)
            }
        };
        self.contraction.next(dd, pp)
    }
}

/// The arithmetic of [`ErrorEstimate`] from the two sums of a cycle, shared by the CPU (which
/// keeps the previous φ on the host) and the GPU (which sums on the device): `dd` =
/// ‖φ_k − φ_{k−1}‖², `pp` = ‖φ_k‖². The first call (no previous φ) returns 1.
#[derive(Debug, Default)]
struct Contraction {
    seen: bool,
    last_update: Option<f64>,
}

impl Contraction {
    fn next(&mut self, dd: f64, pp: f64) -> f64 {
        if !std::mem::replace(&mut self.seen, true) {
            return 1.0;
        }
        let delta = if pp > 0.0 { (dd / pp).sqrt() } else { 0.0 };
        let mut est = 1.0;
        if delta == 0.0 {
            est = 0.0;
        } else if let Some(last) = self.last_update {
            let rho = delta / last;
            if rho < 1.0 {
                est = (delta / (1.0 - rho)).min(1.0);
            }
        }
        self.last_update = Some(delta);
        est
    }
}

/// D = F(R)/σ from φ (FLD Eqs 33–35): centred ∇φ inside, one-sided on the Dirichlet layer.
///
/// The limiter is dispatched once here, so [`fresh_d_with`]'s interior row loop gets it
/// inlined and vectorises. *Why*: with `lim.eval` in a per-voxel index loop this was 38 % of
/// the CPU samples of a 127³ FLD-LP multigrid solve (the smoother 22 %); the values were
/// bit-identical to that loop (same operations per voxel) until D became num/(den·σ) with
/// one division (2026-12-06, `fld::limiter::FluxLimiter::fraction`).
fn fresh_d(g: &Grid, phi: &[f64], sig: &[f64], cfg: &FldConfig, floor: f64) -> Vec<f64> {
    let mut d = vec![0.0; g.len()];
    fresh_d_into(g, phi, sig, cfg, floor, &mut d);
    d
}

/// [`fresh_d`] into `d` (as long as the grid; every value is overwritten).
fn fresh_d_into(g: &Grid, phi: &[f64], sig: &[f64], cfg: &FldConfig, floor: f64, d: &mut [f64]) {
    if cfg.limiter.is_constant() {
        d.par_iter_mut()
            .zip(sig)
            .for_each(|(d, s)| *d = 1.0 / 3.0 / s);
        return;
    }
    super::limiter::with_limiter!(cfg.limiter, |lim| fresh_d_with(g, phi, sig, floor, lim, d))
}

/// [`fresh_d`] for one limiter `lim`: interior voxels of interior rows in a contiguous,
/// vectorisable loop; the Dirichlet layer with one-sided differences.
fn fresh_d_with<L: Fn(f64) -> (f64, f64) + Sync>(
    g: &Grid,
    phi: &[f64],
    sig: &[f64],
    floor: f64,
    lim: L,
    d: &mut [f64],
) {
    let [nx, ny, nz] = g.n;
    let plane = nx * ny;
    let inv_2dl = 0.5 / g.dl;
    // D = F(R)/σ with one division (`FluxLimiter::fraction`).
    let d_of = |r: f64, s: f64| {
        let (num, den) = lim(r);
        num / (den * s)
    };
    d.par_chunks_mut(plane).enumerate().for_each(|(k, slab)| {
        let one_sided = |i: usize, j: usize| {
            let axis = |x: usize, n: usize| (x.saturating_sub(1), (x + 1).min(n - 1));
            let (xl, xr) = axis(i, nx);
            let (yl, yr) = axis(j, ny);
            let (zl, zr) = axis(k, nz);
            let df = |a: usize, b: usize, steps: usize| {
                (phi[b] - phi[a]) * inv_2dl * (2.0 / steps as f64)
            };
            let gx = df(g.index(xl, j, k), g.index(xr, j, k), xr - xl);
            let gy = df(g.index(i, yl, k), g.index(i, yr, k), yr - yl);
            let gz = df(g.index(i, j, zl), g.index(i, j, zr), zr - zl);
            let n = g.index(i, j, k);
            let r = (gx * gx + gy * gy + gz * gz).sqrt().max(floor) / (sig[n] * phi[n]).max(floor);
            d_of(r, sig[n])
        };
        for j in 0..ny {
            let row = &mut slab[j * nx..(j + 1) * nx];
            if k == 0 || k + 1 == nz || j == 0 || j + 1 == ny || nx < 3 {
                for (i, x) in row.iter_mut().enumerate() {
                    *x = one_sided(i, j);
                }
                continue;
            }
            row[0] = one_sided(0, j);
            row[nx - 1] = one_sided(nx - 1, j);
            // Interior i = 1..nx − 1 of row (j, k): centred differences (the one-sided rule's
            // factor 2/steps is exactly 1 there).
            let c = g.index(1, j, k);
            let len = nx - 2;
            let cut = |start: usize| &phi[start..start + len];
            let (p, xm, xp) = (cut(c), cut(c - 1), cut(c + 1));
            let (ym, yp, zm, zp) = (cut(c - nx), cut(c + nx), cut(c - plane), cut(c + plane));
            let s = &sig[c..c + len];
            let out = &mut row[1..nx - 1];
            for q in 0..len {
                let gx = (xp[q] - xm[q]) * inv_2dl;
                let gy = (yp[q] - ym[q]) * inv_2dl;
                let gz = (zp[q] - zm[q]) * inv_2dl;
                let r = (gx * gx + gy * gy + gz * gz).sqrt().max(floor) / (s[q] * p[q]).max(floor);
                out[q] = d_of(r, s[q]);
            }
        }
    });
}

/// L(φ) of FLD Eq 32 (per unit volume, normalised units) into `out` (as long as the grid) at
/// interior voxels, 0 on the layer; with `rhs`, the residual rhs − L(φ) instead.
///
/// Row-sliced so the loop vectorises (the neighbour sums keep the order x−, x+, y−, y+, z−,
/// z+, so the values are bit-identical to the per-voxel index loop this replaced, which was
/// 8 % of a 127³ FLD-LP multigrid solve). The subtraction runs on the row just written, so
/// the residual is one pass over memory instead of two (bit-identical to the separate pass).
fn apply_into(
    g: &Grid,
    phi: &[f64],
    d: &[f64],
    absorb: &[f64],
    rhs: Option<&[f64]>,
    out: &mut [f64],
) {
    let [nx, ny, nz] = g.n;
    let inv_dl2 = 1.0 / (g.dl * g.dl);
    let plane = nx * ny;
    out.par_chunks_mut(plane).enumerate().for_each(|(k, slab)| {
        if k == 0 || k + 1 == nz || nx < 3 || ny < 3 {
            slab.fill(0.0);
            return;
        }
        slab[..nx].fill(0.0);
        slab[(ny - 1) * nx..].fill(0.0);
        for j in 1..ny - 1 {
            slab[j * nx] = 0.0;
            slab[(j + 1) * nx - 1] = 0.0;
            let c = g.index(1, j, k);
            let len = nx - 2;
            let offsets = [c - 1, c + 1, c - nx, c + nx, c - plane, c + plane];
            let np = offsets.map(|o| &phi[o..o + len]);
            let nd = offsets.map(|o| &d[o..o + len]);
            let (pp, dp, ap) = (&phi[c..c + len], &d[c..c + len], &absorb[c..c + len]);
            let row = &mut slab[j * nx + 1..j * nx + 1 + len];
            for q in 0..len {
                let (mut sphi, mut sdphi, mut sd) = (0.0, 0.0, 0.0);
                for n in 0..6 {
                    sphi += np[n][q];
                    sdphi += nd[n][q] * np[n][q];
                    sd += nd[n][q];
                }
                let den = ap[q] + 0.5 * (6.0 * dp[q] + sd);
                let num = 0.5 * (dp[q] * sphi + sdphi);
                row[q] = (pp[q] * den - num) * inv_dl2;
            }
            if let Some(f) = rhs {
                for (x, f) in row.iter_mut().zip(&f[c..c + len]) {
                    *x = f - *x;
                }
            }
        }
    });
}

/// How one axis coarsens. The Dirichlet values sit at the centres of the layer voxels, so
/// the interior unknowns 1..m are the nodes of a grid whose boundary nodes are 0 and m + 1.
/// * `m` odd (m + 1 even): **vertex** coarsening, coarse node c = fine node 2c; the coarse
///   layer lies exactly on the fine one.
/// * `m` even: **cell** coarsening, coarse voxel c covers fine 2c − 1, 2c (centre 2c − ½);
///   the coarse layer lies half a fine voxel outside the fine one (the true boundary is ¾ of
///   a coarse voxel from the first coarse centre).
#[derive(Debug, Clone, Copy)]
struct Axis {
    n: usize,
    nc: usize,
    vertex: bool,
}

impl Axis {
    fn new(n: usize) -> Self {
        let m = n - 2;
        if m % 2 == 1 {
            Self {
                n,
                nc: n.div_ceil(2),
                vertex: true,
            }
        } else {
            Self {
                n,
                nc: m / 2 + 2,
                vertex: false,
            }
        }
    }

    /// Prolongation weights of fine interior index i: (coarse index, weight), linear in
    /// the node positions.
    fn prolong(&self, i: usize) -> [(usize, f64); 2] {
        if self.vertex {
            if i % 2 == 0 {
                [(i / 2, 1.0), (i / 2, 0.0)]
            } else {
                [(i / 2, 0.5), (i / 2 + 1, 0.5)]
            }
        } else {
            let c = i.div_ceil(2);
            if i % 2 == 1 {
                [(c, 0.75), (c - 1, 0.25)]
            } else {
                [(c, 0.75), (c + 1, 0.25)]
            }
        }
    }

    /// Weights (fine index, weight) of coarse interior index c for the medium and R̂φ:
    /// the mean over the fine voxels it covers (cell) or the full weighting ¼, ½, ¼
    /// (vertex; keeps ∫σ). Injection for R̂φ on vertex axes was measured and rejected: with
    /// it FLD-LP stalls at R̄/j̄ ≈ 2–4·10⁻² (rate 1.00 per cycle) on the point source at
    /// n = 33 and at albedo 1 (n = 17, 33); with full weighting both converge in 6–7 cycles.
    fn mean(&self, c: usize) -> Vec<(usize, f64)> {
        match self.vertex {
            true => vec![(2 * c - 1, 0.25), (2 * c, 0.5), (2 * c + 1, 0.25)],
            false => vec![(2 * c - 1, 0.5), (2 * c, 0.5)],
        }
    }

    /// The transpose of [`Axis::prolong`] at coarse interior index c: every fine interior
    /// index whose prolongation reads c, with that weight (at most 4 of them).
    fn restrict(&self, c: usize) -> Vec<(usize, f64)> {
        let (lo, hi) = (
            (2 * c).saturating_sub(2).max(1),
            (2 * c + 1).min(self.n - 2),
        );
        (lo..=hi)
            .filter_map(|i| {
                let w: f64 = self
                    .prolong(i)
                    .iter()
                    .filter(|&&(ci, _)| ci == c)
                    .map(|&(_, w)| w)
                    .sum();
                (w != 0.0).then_some((i, w))
            })
            .collect()
    }

    /// Nearest fine layer index of a coarse layer index.
    fn layer(&self, c: usize) -> usize {
        if c == 0 { 0 } else { self.n - 1 }
    }
}

/// The three axis maps of a grid and its coarse grid.
fn axes(g: &Grid) -> [Axis; 3] {
    g.n.map(Axis::new)
}

/// Per-axis gather tables of the transfers: for axis d and index i < n[d], `weights(d, i)`,
/// built once per transfer (not per voxel).
fn axis_tables(
    n: [usize; 3],
    weights: impl Fn(usize, usize) -> Vec<(usize, f64)>,
) -> [Vec<Vec<(usize, f64)>>; 3] {
    [0, 1, 2].map(|d| (0..n[d]).map(|i| weights(d, i)).collect())
}

/// `w` at coarse interior indices, nothing on the coarse Dirichlet layer.
fn interior_only(
    cg: &Grid,
    d: usize,
    c: usize,
    w: impl FnOnce() -> Vec<(usize, f64)>,
) -> Vec<(usize, f64)> {
    if c == 0 || c + 1 == cg.n[d] {
        Vec::new()
    } else {
        w()
    }
}

/// The coarse grid of `g` (see [`Axis`]) and its medium.
fn restrict_medium(
    g: &Grid,
    st: &[f64],
    ss: &[f64],
) -> Result<(Grid, Vec<f64>, Vec<f64>), SolverError> {
    let ax = axes(g);
    let nc = ax.map(|a| a.nc);
    let origin = [0, 1, 2].map(|d| g.origin[d] - if ax[d].vertex { 0.5 } else { 1.0 } * g.dl);
    let cg = Grid::with_origin(nc, 2.0 * g.dl, origin)?;
    Ok((cg, restrict_mean(g, &cg, st), restrict_mean(g, &cg, ss)))
}

/// Coarse interior values as `Axis::mean` (tensor product); the coarse Dirichlet layer
/// copies the nearest fine layer voxel.
fn restrict_mean(g: &Grid, cg: &Grid, v: &[f64]) -> Vec<f64> {
    let mut out = Vec::new();
    restrict_mean_into(g, cg, v, &mut out);
    out
}

/// [`restrict_mean`] into `out` (resized to the coarse grid; every value is overwritten).
fn restrict_mean_into(g: &Grid, cg: &Grid, v: &[f64], out: &mut Vec<f64>) {
    let ax = axes(g);
    let tables = axis_tables(cg.n, |d, c| interior_only(cg, d, c, || ax[d].mean(c)));
    restrict_separable(g, cg, v, &tables, 1.0, out);
    let (cnx, cny) = (cg.n[0], cg.n[1]);
    out.par_chunks_mut(cnx * cny)
        .enumerate()
        .for_each(|(kc, slab)| {
            for jc in 0..cny {
                for ic in 0..cnx {
                    if !cg.is_boundary(ic, jc, kc) {
                        continue;
                    }
                    let c = [ic, jc, kc];
                    let f = [0, 1, 2].map(|d| {
                        if c[d] == 0 || c[d] + 1 == cg.n[d] {
                            ax[d].layer(c[d])
                        } else if ax[d].vertex {
                            2 * c[d]
                        } else {
                            2 * c[d] - 1
                        }
                    });
                    slab[jc * cnx + ic] = v[g.index(f[0], f[1], f[2])];
                }
            }
        });
}

/// Residual restriction: the adjoint of [`prolong_add`] over 8 (full weighting: ¼, ½, ¼ per
/// vertex axis, (1, 3, 3, 1)/8 per cell axis); the fine residual is 0 on the layer.
fn restrict_fw_into(g: &Grid, cg: &Grid, r: &[f64], out: &mut Vec<f64>) {
    let ax = axes(g);
    let tables = axis_tables(cg.n, |d, c| interior_only(cg, d, c, || ax[d].restrict(c)));
    restrict_separable(g, cg, r, &tables, 0.125, out);
}

/// `scale` × the tensor-product restriction of `v` with the per-axis gather `tables` (coarse
/// index → (fine index, weight)), 0 where a table is empty (the coarse layer). Applied one
/// axis at a time per coarse z-slab (z, then x, then y: about 2 multiply-adds per fine voxel,
/// in contiguous rows) instead of gathering up to 4³ fine values per coarse voxel. *Why*:
/// the gathered form took 0.039 s (R̂φ) + 0.033 s (residual) of a 0.59 s CDA solve at 127³
/// (8 cycles; FLD-LP 0.077 + 0.072 s of 3.59 s), measured with an instrumented build.
fn restrict_separable(
    g: &Grid,
    cg: &Grid,
    v: &[f64],
    tables: &[Vec<Vec<(usize, f64)>>; 3],
    scale: f64,
    out: &mut Vec<f64>,
) {
    let [nx, ny, _] = g.n;
    let [cnx, cny, _] = cg.n;
    let [tx, ty, tz] = tables;
    out.clear();
    out.resize(cg.len(), 0.0);
    // Scratch planes per rayon job, not per slab: fresh allocations of a plane per slab
    // faulted their pages in on every visit (see the module docs, "pooled").
    out.par_chunks_mut(cnx * cny).enumerate().for_each_init(
        || (Vec::new(), Vec::new()),
        |(zp, xp): &mut (Vec<f64>, Vec<f64>), (kc, slab)| {
            if tz[kc].is_empty() {
                return;
            }
            // z: the fine plane combined over this coarse slab's fine slabs.
            zp.clear();
            zp.resize(nx * ny, 0.0);
            for &(k, a) in &tz[kc] {
                let src = &v[g.index(0, 0, k)..g.index(0, 0, k) + nx * ny];
                for (o, &x) in zp.iter_mut().zip(src) {
                    *o += a * x;
                }
            }
            // x: per fine row, the coarse row.
            xp.clear();
            xp.resize(cnx * ny, 0.0);
            for j in 0..ny {
                let row = &zp[j * nx..(j + 1) * nx];
                for (ic, o) in xp[j * cnx..(j + 1) * cnx].iter_mut().enumerate() {
                    *o = tx[ic].iter().map(|&(i, w)| w * row[i]).sum();
                }
            }
            // y: the coarse rows.
            for (jc, out_row) in slab.chunks_mut(cnx).enumerate() {
                for &(j, b) in &ty[jc] {
                    for (o, &x) in out_row.iter_mut().zip(&xp[j * cnx..(j + 1) * cnx]) {
                        *o += b * x;
                    }
                }
                if !ty[jc].is_empty() {
                    for (ic, o) in out_row.iter_mut().enumerate() {
                        *o = if tx[ic].is_empty() { 0.0 } else { *o * scale };
                    }
                }
            }
        },
    );
}

/// φ += the interpolated coarse correction (zero on the coarse Dirichlet layer), with
/// `project` projected onto φ ≥ 0 as the smoother's update is (without, for a correction that
/// may be negative: the Galerkin levels). Per fine row, the coarse rows it reads
/// are first combined (z and y weights) into one coarse line, which is then interpolated
/// along x (2 terms per fine voxel). *Why*: the per-voxel 2³-term gather took 0.070 s of a
/// 0.59 s CDA solve at 127³ (FLD-LP 0.156 of 3.59 s; instrumented build).
fn prolong_add(g: &Grid, cg: &Grid, e: &[f64], phi: &mut [f64], project: bool) {
    let ax = axes(g);
    let (nx, ny, nz) = (g.n[0], g.n[1], g.n[2]);
    let cnx = cg.n[0];
    // Per axis and fine index: the coarse (index, weight) pairs of `Axis::prolong`, without
    // zero weights and coarse Dirichlet-layer indices (their correction is zero).
    let [tx, ty, tz] = &axis_tables(g.n, |d, i| {
        ax[d]
            .prolong(i)
            .into_iter()
            .filter(|&(c, w)| w != 0.0 && c > 0 && c + 1 < cg.n[d])
            .collect()
    });
    phi.par_chunks_mut(nx * ny)
        .enumerate()
        .for_each(|(k, slab)| {
            if k == 0 || k + 1 == nz {
                return;
            }
            let mut line = vec![0.0; cnx];
            for j in 1..ny - 1 {
                line.fill(0.0);
                for &(ck, wk) in &tz[k] {
                    for &(cj, wj) in &ty[j] {
                        let base = cg.index(0, cj, ck);
                        let w = wk * wj;
                        for (o, &x) in line.iter_mut().zip(&e[base..base + cnx]) {
                            *o += w * x;
                        }
                    }
                }
                let row = &mut slab[j * nx..(j + 1) * nx];
                for i in 1..nx - 1 {
                    let s: f64 = tx[i].iter().map(|&(ci, wi)| wi * line[ci]).sum();
                    let v = row[i] + s;
                    row[i] = if project && v < 0.0 { 0.0 } else { v };
                }
            }
        });
}

/// `out` = P e, the interpolated coarse vector alone (zero on the fine layer, not projected).
fn prolong_into(g: &Grid, cg: &Grid, e: &[f64], out: &mut [f64]) {
    out.par_iter_mut().for_each(|x| *x = 0.0);
    prolong_add(g, cg, e, out, false);
}

/// Coarse Dirichlet layer: φ = base + e, with e = −⅓ of the correction at the nearest
/// interior voxel per cell-coarsened axis the layer voxel lies outside of (linear
/// extrapolation to zero at the parent's layer, ¾ of a coarse voxel from the first centre),
/// and e = 0 if it lies outside a vertex-coarsened axis (the layers coincide); see
/// [`MgConfig::extrapolated_layer`].
fn extrapolate_layer(g: &Grid, cell: [bool; 3], base: &[f64], phi: &mut [f64]) {
    let [nx, ny, nz] = g.n;
    let cl = |x: usize, n: usize| x.clamp(1, n - 2);
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                if !g.is_boundary(i, j, k) {
                    continue;
                }
                let c = [i, j, k];
                let mut f = 1.0;
                for d in 0..3 {
                    if c[d] == 0 || c[d] + 1 == g.n[d] {
                        f *= if cell[d] { -1.0 / 3.0 } else { 0.0 };
                    }
                }
                let q = g.index(cl(i, nx), cl(j, ny), cl(k, nz));
                let p = g.index(i, j, k);
                phi[p] = base[p] + f * (phi[q] - base[q]);
            }
        }
    }
}
