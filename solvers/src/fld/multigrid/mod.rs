//! Nonlinear full-approximation-scheme (FAS) multigrid for FLD Eq 20 and CDA (FLD Eq 12), a
//! solver strategy next to red-black SOR (FLD Algorithm 1, which stays the reference).
//!
//! With L(φ) = −∇·(D(φ)∇φ) + σa φ discretised as in FLD Eq 32, the FAS coarse problem is
//! L_c(φ_c) = R(j − L(φ)) + L_c(R̂φ), and φ ← φ + P(φ_c − R̂φ) (Brandt's FAS).
//!
//! This page states the algorithm as it runs, each decision with the measurement that settled
//! it and the test that pins it, what a solve costs against SOR, and what is known not to
//! work. The dated measurements behind every decision, stage by stage and with the variants
//! that were built and dropped, are in `HISTORY.md` next to this file.
//!
//! ## The cycle
//! * **Smoother:** the red-black sweep of FLD Algorithm 1 itself ([`CpuFld`], same arithmetic,
//!   floors σ_ε and ε, θ-relaxed D update and projection φ ≥ 0), over-relaxed at ω = 1.2
//!   ([`MgConfig::smoother_omega`]).
//! * **Levels (per axis, see `Axis`).** The Dirichlet values sit at the layer voxels'
//!   centres, so the m interior unknowns of an axis are nodes 1..m between boundary nodes 0
//!   and m + 1. With m odd the axis is coarsened vertex-wise (coarse node c = fine node 2c,
//!   the coarse layer on the fine one, m → (m − 1)/2); with m even cell-wise (coarse voxel
//!   c covers fine 2c − 1, 2c, m → m/2, the coarse layer half a fine voxel outside). So odd
//!   and non-power-of-two grids coarsen without padding (127 → 64 → 33 → 17 → … voxels per
//!   axis, layers included). The coarse medium keeps ∫σa (full weighting ¼, ½, ¼ on vertex
//!   axes, the mean of the two children on cell axes); the σ of its diffusion coefficient is
//!   the harmonic mean of the children's floored σ with the same weights ([`CoarseSigma`]),
//!   rediscretised with the floors of the finest grid.
//! * **Transfers:** linear prolongation of the correction in node positions (vertex axes
//!   ½, ½; cell axes ¾, ¼; zero correction on the coarse Dirichlet layer, projected onto
//!   φ ≥ 0 like the smoother's update); residual restriction by its adjoint over 8 (full
//!   weighting); R̂φ as the medium's restriction. All are separable, one axis at a time over
//!   contiguous rows (`restrict_separable`, `prolong_add`).
//! * **D on every level:** before a residual is formed, D = F(R(φ))/σ is recomputed from that
//!   level's φ (FLD Eqs 33–35, one-sided ∇φ on the Dirichlet layer, as the SOR does). A
//!   constant limiter's D is computed once per level.
//! * **Coarsest level:** coarsening stops when an axis has fewer than 4 interior voxels; there
//!   up to 200 sweeps run until the sweep residual drops by 10⁻³.
//! * **A solve:** a full-multigrid start (the FAS problem at φ = 0 solved coarsest first, each
//!   level's correction prolongated and given one cycle), then F(2, 2) cycles. Before each
//!   cycle the fine φ becomes the best combination of the last 4 cycle results (Krylov depth
//!   3); after each coarse-grid correction and after each cycle, 8 extra sweeps run in a box
//!   of optical half-width 0.5 around each point-like source. One work unit is one fine sweep;
//!   a sweep on level ℓ counts 8^(−ℓ), a box sweep its share of the grid.
//! * **Stop:** R̄/j̄ < tolerance (FLD Eq 37, next section) *and* the change-based error estimate
//!   ‖Δφ‖/‖φ‖/(1 − ρ̂) below it (`ErrorEstimate`; the `fld` module docs, "Residual window",
//!   say why the residual alone is not enough), or a stall, the cap, or a non-finite residual.
//!   `FldTrace::seconds_to_tolerance` records when R̄/j̄ itself first fell below the tolerance,
//!   the like-for-like time against SOR, whose stop is the residual alone.
//!
//! ## Decisions where the paper is silent (it names multigrid only as future work)
//! Measured on 2-vCPU AMD EPYC hosts (a 7002 and a Zen 5 with 32 MiB L3; the first numbers of
//! 2026-12-03 on a 2-core Intel Xeon; `HISTORY.md` names each), f64,
//! `multigrid_scaling`'s problems unless stated: the point source (τ = 4, albedo 0.5), the Fig 4
//! cloud, and three controls: `ball_source` (the point source's power over a ball of radius
//! 0.1), `cloud_thin` (the cloud's vacuum filled by σt = 0.5) and `cloud_floor` (σ_ε = 1).
//! Cycle counts do not depend on the host or the thread count; seconds are one run each.
//! * **Stopping measure.** R̄/j̄ of FLD Eq 37 over the same window as SOR, but evaluated with
//!   D recomputed from the current φ (the residual of the nonlinear equation itself, not of
//!   the lagged D the sweep carries); at SOR's fixed point both coincide.
//! * **Stall.** If 8 consecutive cycles fail to reduce the best residual by 10 %, the solve
//!   stops with [`Stop::Stalled`], never [`Stop::Converged`]; the 95 %-vacuum white-noise
//!   medium that stalls SOR is the case this guards (tested in `tests/fld_multigrid.rs`).
//! * **Coarsening by the parity of each axis.** Coarsening every axis cell-wise (the first
//!   version) left the last coarse voxel of an odd axis straddling the Dirichlet layer, a coarse
//!   operator that does not approximate the fine one near the boundary: V(2, 2) cycles to
//!   10⁻⁶ on the point source (τ = 10, albedo 0.9) at n = 17, 33, 65 were CDA 6, 8, 13 with
//!   it and 5, 5 (n = 17, 33; 2026-12-03, before the error-estimate stop, which now makes
//!   them 6, 7) with vertex coarsening of odd axes (`tests/fld_multigrid.rs`).
//!   Injection for R̂φ on vertex axes stalls FLD-LP at R̄/j̄ ≈ 2–4·10⁻² on the point source
//!   (n = 33) and at albedo 1; full weighting converges in 6–7 cycles.
//! * **Coarse σ: harmonic ([`CoarseSigma`]).** The fine operator couples voxels through
//!   ½(D_p + D_q), so a vacuum voxel (D = 1/(3σ_ε), a near-perfect conductor) makes its faces
//!   conduct; a coarse σ that is the arithmetic mean of its children's loses that. With it CDA
//!   on the Fig 4 cloud, on white noise with 30 % or 95 % vacuum and on 10⁴-contrast noise cut
//!   the residual in the first cycle and then diverged (`Stalled`); with the harmonic σ (a
//!   constant limiter's coarse D is then the mean of the fine D) all converge to 10⁻⁹. FLD
//!   changes by ±1 cycle (its D in vacuum is flux-limited, ≈ φ/|∇φ|, whatever σ). Pinned by
//!   `tests/fld_multigrid.rs` (the arithmetic σ is pinned to stall on the cloud).
//! * **F(2, 2) cycles ([`Cycle`]).** An F-cycle costs about 1.3 V-cycles of coarse work for
//!   the same 4 fine sweeps and needs fewer, flatter cycles: with Krylov depth 3, V → F cycles
//!   at n = 31, 63, 127: point source CDA 6, 6, 7 → 5, 5, 5, FLD-LP 9, 12, 16 → 9, 10, 11;
//!   cloud CDA 10, 13, 17 → 10, 12, 14, FLD-LP 17, 34, 108 → 14, 21, 54 (ω = 1, no FMG start;
//!   seconds at 127³ with setup: point source CDA 0.60 → 0.55, FLD-LP 2.88 → 2.43, cloud CDA
//!   1.21 → 1.28, FLD-LP 19.0 → 11.6). F(2, 1) and F(1, 2) took more cycles on the cloud or
//!   `ball_source`, W-cycles the same cycles in more seconds, and on the FLD-LP point source
//!   F(3, 3) one cycle fewer in more seconds (2.64 against 2.33 s) and F(1, 1) more cycles
//!   (`HISTORY.md`).
//! * **The smoother's ω: 1.2 ([`MgConfig::smoother_omega`]).** Over-relaxed red-black
//!   relaxation smooths better than Gauss–Seidel for ω slightly above 1 (Yavneh), and damps
//!   some smooth error where the coarse correction is weakest, in vacuum. Over the 40 runs of
//!   `multigrid_scaling --smoother-omega` (5 problems × CDA and FLD-LP × n = 31…255), 1.2 was
//!   the largest ω that needed no more cycles than Gauss–Seidel in any of them (255³ cloud
//!   FLD-LP: 154 cycles at ω = 1, 125 at 1.2, 164 at 1.3; 1.5 costs the point source CDA one
//!   or two). Pinned by `over_relaxed_smoothing_cuts_cycles` (with the FMG start: cloud 14 →
//!   11, 30 % vacuum noise 19 → 17, point source CDA 6 → 5, FLD-LP 7 → 6).
//! * **Krylov acceleration, depth 3 ([`MgConfig::krylov`], `Krylov`).** Oosterlee & Washio's
//!   nonlinear Krylov acceleration: φ becomes the combination of the last k + 1 cycle results
//!   whose linearised residual is least (GMRES-like for CDA, a multisecant step for FLD),
//!   restarted when a cycle grows R̄/j̄ by 1.5× or more (on any growth, CDA on shell_core
//!   stalled). The plain cycle's rate on vacuum clouds is set by a few slow modes the
//!   rediscretised coarse levels miss (CDA on the cloud: 0.48, 0.63, 0.72 per cycle at n = 31,
//!   63, 127); plain → depth 3 cycles at n = 31…255: CDA cloud 20, 33, 48, 67 → 10, 13, 17, 22,
//!   FLD-LP point source 11, 15, 18, 25 → 9, 12, 16, 20 (V cycles, ω = 1). Deeper histories
//!   help FLD-LP on the cloud (depth 6, 12: 106, 85 cycles at 255³ against 154, ω = 1) but
//!   cost time where cycles are few. The history keeps 2(k + 1) fine vectors (depth 3: 8,
//!   1.1 GB at 255³, checked against the memory budget; the largest depth is [`MAX_KRYLOV`]);
//!   φ and r move into it without copies. Pinned by
//!   `krylov_acceleration_cuts_cycles_where_vacuum_slows_the_plain_cycle` (measured from φ = 0:
//!   cloud 14 → 10, noise 37 → 17, point source CDA 7 → 6, FLD-LP 8 → 7).
//! * **Coarse D of FLD: FAS, then Picard once the FAS stalls ([`CoarseD::Auto`]).** With
//!   V-cycles the FAS on the cloud at n = 127 oscillated with period 2 and stalled (R̄/j̄ ≈
//!   0.01–0.08) where D = F(R)/σ swings by 60× on a 10⁻⁴ change of φ in a flat vacuum
//!   pocket; freezing the coarse D at the mean of the fine D ([`CoarseD::Restricted`], the
//!   Picard linearisation) converges there but is slower wherever the FAS converges (V-cycles,
//!   point source n = 31, 63, 127: 10, 15, 21 cycles against 9, 12, 16). So the FAS runs until
//!   the stall rule fires, then Picard coarse levels. With the F-cycles of the default the
//!   cloud no longer stalls (`Auto` does not switch there), but shell_core does (18³,
//!   emission in the medium, tolerance 10⁻⁹: the FAS alone `Stalled` at R̄/j̄ 3.9 after 9
//!   cycles, Picard alone 40 cycles, the default 31, SOR 110 042 iterations). Pinned by
//!   `the_picard_coarse_levels_take_over_where_the_fas_stalls`.
//! * **Local relaxation around point-like sources ([`MgConfig::local_sweeps`] 8,
//!   [`MgConfig::local_radius`] 0.5; `multigrid/local.rs`).** A one-voxel source holds
//!   j = 1/Δl³ and sharpens with n; after each of the first 8 cycles 91–99.9 % of Σr² sat within
//!   8 voxels of it at n = 255, and FLD-LP's cycles grew (8, 9, 10, 12 at n = 31…255).
//!   Brandt's remedy is extra relaxation in a neighbourhood of fixed physical size: a box of
//!   half-width ⌈τ₀/(σΔl)⌉ voxels per axis with the source voxel's σ (4, 8, 16, 32 at n =
//!   31…255; at most a quarter of the axis, clipped two voxels inside the layer), on the
//!   finest level only, relaxed after the coarse-grid correction and after the
//!   post-smoothing, with D recomputed before each colour. FLD-LP then took 6, 6, 6, 7 cycles
//!   (was 8, 9, 10, 12; before the FMG start); a box fixed in voxels, one place only, or a set
//!   of voxels with R > 4 instead were worse. At most [`MAX_BOXES`] boxes, around voxels
//!   holding at least [`POINT_SHARE`] of the emission (none on the Fig 4 clouds); a box
//!   holding vacuum (σ below [`VACUUM_CONTRAST`] of its largest) is dropped: on 95 %-vacuum
//!   noise the boxes made FLD-LP stall. The box sweeps compute whole rows (both colours; a
//!   colour writes back its own) and D row by row with one limiter per loop, so both loops
//!   vectorise: φ bit-identical to the per-voxel loops they replaced. The 127³ point
//!   source's seconds to the tolerance, albedo 0.3, fastest/median, old and new builds
//!   interleaved in one run (2026-12-07, 2-vCPU AMD EPYC Zen 5, triad 43.7–47.7 GB/s by the
//!   benches' bandwidth probe before and after): FLD-LP 0.455/0.513 → 0.406/0.429 s (five
//!   solves each); CDA, whose boxes evaluate no limiter, 0.109/0.115 → 0.106/0.118 s (twelve
//!   each), no difference beyond the host's noise. CPU only.
//!   Pinned by `local_relaxation_keeps_the_point_source_flat_in_n` (without → with the boxes, FMG start
//!   on both sides: 8, 9, 10 → 5, 5, 5 cycles at n = 31, 63, 127) and `local::tests`.
//! * **Full-multigrid start ([`MgConfig::full_multigrid`], on).** Starting the first cycle
//!   from φ = 0 left in its residual the smooth error the coarse levels could have removed
//!   first. The FMG start costs 0.7–1.1 work units, counted in the first cycle; it is skipped
//!   with [`CoarseOp::Galerkin`] and on the GPU. `multigrid_scaling --full-multigrid
//!   false|true`, cycles to the full stop (its `steps`) at n = 31…255: point source CDA 4, 4,
//!   4, 4 → 4, 4, 4, 3, FLD-LP 6, 6, 6, 7 → 5, 5, 5, 7; cloud CDA 8, 10, 12, 14 → 8, 9, 11, 13, FLD-LP 14,
//!   20, 43, 125 → 12, 16, 38, 127; `ball_source` CDA 5, 4, 4, 4 → 4, 4, 3, 3, FLD-LP 7, 7, 7,
//!   8 → 6, 6, 7, 7; `cloud_thin` and `cloud_floor` one cycle fewer at most sizes: fewer or as
//!   many in 39 of 40 runs. The residual after the first cycle falls about tenfold on the
//!   point source (127³ CDA 5.1·10⁻⁴ → 3.2·10⁻⁵). It needs the local boxes: without them it
//!   leaves the residual at the source (127³ CDA 4.8·10⁻³ after the first cycle). Cubic
//!   instead of linear interpolation of the FMG corrections on vertex axes (2026-12-07, a
//!   build not kept) lowered that first residual only from 3.1 to 2.3·10⁻⁵ (albedo 0.1; 0.99:
//!   3.4 → 2.5·10⁻⁵) and saved no cycle: what remains after the first cycle sits at the
//!   source (16 and 32 box sweeps, albedo 0.5: 1.3 and 1.1·10⁻⁵ against 3.2·10⁻⁵ with 8),
//!   not in the interpolation. Pinned by
//!   `the_full_multigrid_start_cuts_the_first_residual` (33³, τ = 10, albedo 0.9: CDA 3.9·10⁻³
//!   → 3.5·10⁻⁴, FLD-LP 8.2·10⁻³ → 7.6·10⁻⁴).
//! * **Coarse Dirichlet layer.** On vertex axes it coincides with the fine one (zero
//!   correction is exact); on cell axes it sits half a fine voxel further out and its
//!   correction is zero. Extrapolating it linearly to zero at the parent layer's position
//!   ([`MgConfig::extrapolated_layer`], cell axes only) is kept as an option; its only
//!   measurement was made with the old all-cell coarsening.
//! * **Pooled vectors and first touch.** Every fine and coarse vector of a visit comes from a
//!   per-level pool, and new vectors are zeroed by every thread (`par_zeroed`): fresh 16 MB
//!   vectors per cycle put 13–15 % of a 127³ CDA solve's samples in page clearing and faults.
//!   The 255³ CDA point-source solve still takes about 437 000 page faults, mostly the Krylov
//!   history's first touch; allocating the pool during the setup moves that time out of the
//!   solve's clock without removing it, so it is not done.
//! * **Setup.** `CpuMultigrid::new` restricts the medium level by level, fills the finest
//!   level's packed smoother fields in parallel over z-slabs (127³ 0.085 s CDA, 0.076 s
//!   FLD-LP; 255³ 0.87 and 0.81 s, the Fig 4 cloud), finds the local boxes and, with
//!   [`CoarseOp::Galerkin`], builds the coarse operators; setup is not in the solve's
//!   seconds, nor is SOR's in its.
//! * **The default solver: [`crate::fld::Solver::Auto`].** Multigrid is slower than SOR on
//!   small grids (18³ datasets of `convergence_check`: CDA 0.0049 against 0.0039 s on nebula;
//!   the 31³ cloud with CDA 0.0086 against 0.0042 s in `multigrid_scaling`), so the default
//!   is a rule: multigrid from 100³ voxels for CDA
//!   and 63³ for FLD ([`crate::fld::auto_multigrid_voxels`], where `multigrid_scaling` measured
//!   it faster on both its problems); below, SOR for at most 200 sweeps
//!   ([`crate::fld::AUTO_SOR_SWEEPS`]) and then multigrid from scratch; SOR from scratch where
//!   multigrid ends without converging or cannot run (the Marshak face). `FldTrace::solver` and
//!   `point_source`'s `solved_by` column say which ran. `figures --only point_source,flux_limiters`:
//!   47.0 → 10.5 s and 19.8 → 10.0 s wall; the full `figures` run gained about 0.4 % (3988 s;
//!   its time is POP, the path tracer, Mitsuba and the experiments that run both solvers by
//!   design). Pinned by `auto_takes_each_branch_of_its_rule` and
//!   `auto_hands_a_slow_sor_solve_to_multigrid_in_the_experiment`.
//! * **GPU ([`gpu`], issue 15 item 2).** The same cycle in f32 on the device, as plain FAS
//!   ([`MgConfig::plain_fas`]: no Krylov history, Picard fallback, local boxes or FMG start):
//!   the smoother of every level is `fld.wgsl`'s red-black sweep itself, the transfers (D from
//!   φ, residual, restriction of φ and of the residual, the FAS right-hand side, prolongation)
//!   are `multigrid.wgsl`, one compute pass per cycle, three sums read back per cycle; its
//!   coarsest level runs a fixed 16 sweeps, and [`CoarseD::Restricted`] and
//!   [`CoarseOp::Galerkin`] are refused there with a typed error. On
//!   lavapipe (`tests/fld_multigrid_gpu.rs`, tolerance 10⁻⁵) on the 33³ point source and a
//!   24 × 20 × 27 source block, for CDA and all five limiters, the GPU takes the same number
//!   of cycles as the CPU-f32 plain FAS in all 12 cases (4–6; the test allows two more) and
//!   agrees with it to 1.3–12·10⁻⁷ relative L2 (conformance bound 10⁻³); on the Fig 4 cloud CDA both stop
//!   `Stalled` at f32's floor (R̄/j̄ ≈ 10⁻⁴).
//!
//! ## What a solve costs against SOR (issue 15, acceptance 3)
//! Seconds until R̄/j̄ first fell below 10⁻⁶, setup excluded on both sides, SOR / multigrid,
//! `point_source --boundary zero --tolerance 1e-6 --solver sor,multigrid`, every Fig 5 albedo,
//! one run per size with the vectorised box sweeps (2026-12-07, sixteenth session, Zen 5
//! host, whose bandwidth probe gave triad 43.7–47.7 GB/s in the same session, not the same
//! run; ratios within a run need no probe; the runs before them, `HISTORY.md`: 127³ CDA
//! 5.6–8.0× and 6.4–8.4×, FLD-LP 6.5–13.5× and 6.4–12.9×; 255³ CDA 9.1–15.6×, FLD-LP 19.6×
//! with 5.68 s):
//!
//! | size | limiter | speed-up | SOR | multigrid |
//! |---|---|---|---|---|
//! | 127³ | CDA | 6.2–8.5× | 0.74–0.89 s, 274–284 sweeps | 0.102–0.121 s, FMG + 2 cycles |
//! | 127³ | FLD-LP | 6.7–15.6× | 2.74–6.54 s, 472–974 sweeps | 0.408–0.433 s, 4 cycles (5–6 with the stop) |
//! | 255³ | CDA | 14.6–16.5× | 13.1–16.8 s, 543–566 sweeps | 0.85–1.11 s, FMG + 2 cycles |
//! | 255³ | FLD-LP (α = 0.5) | 27.9× | 106.0 s, 2078 sweeps | 3.80 s, 7 cycles with the stop |
//!
//! On a Zen 3 host with about half that bandwidth (triad 21–28 GB/s; seventeenth session,
//! `HISTORY.md`) every second was 2–2.6× longer and the ratios about the same: 127³ CDA
//! 5.5–7.0×, FLD-LP 6.5–12.9×; 255³ CDA 14.7–18.9×, FLD-LP (α = 0.5) 24.1× (SOR 241.5 s).
//! SOR's own seconds vary by up to 25 % between runs on the Zen 5 host, so only ratios within one
//! run compare. φ agrees with SOR's to 0.4–3.6·10⁻⁶ relative L2. At 127³ the ≥ 10× of
//! acceptance 3 is not met for CDA at any albedo, nor for FLD-LP at 0.3–0.7. For CDA a solve to
//! the tolerance is 11.5–11.9 work units (the FMG start and two cycles with their boxes), so a
//! cycle that cost only its sweeps would allow about 24× against SOR's 277 sweeps, but a work
//! unit still costs about 3 SOR sweeps of wall time (9–15 ms against 3.1–4.4 ms). Where the
//! time of four 127³ CDA cycles from φ = 0 goes (albedo 0.5, an instrumented build not kept,
//! three runs, 0.22–0.23 s): the 16 fine sweeps 56–60 ms, the two fine residuals per cycle
//! 35–37 ms (22–25 ms with Krylov depth 0, the rest the first touch of the vectors the history
//! keeps), the coarse levels 34–39 ms, the local boxes 21–25 ms (before their sweeps were
//! vectorised), the transfers 17–21 ms, packing and unpacking φ between the smoother's
//! red-black layout and the natural one 10–11 ms, the Krylov sums and combination 8–10 ms, the
//! error estimate 5–6 ms. F(1, 1) cycles show the same (2026-12-07, an ad-hoc driver, FMG start
//! and four cycles, two runs each): 12.1 work units in 0.23–0.24 s against 22.9 in 0.25–0.28 s
//! with F(2, 2), so most of a cycle's time is its passes over the fine grid other than
//! smoothing. `multigrid_scaling` reports multigrid's speed-up over SOR up to n = 127
//! (`--sor-max-n`), in its report's `seconds` and `seconds_to_tolerance` tables.
//!
//! ## Known limitations (measured, not fixed)
//! * **Cycles grow with n on the vacuum cloud** (acceptance 2, `results/multigrid_scaling`):
//!   cycles to R̄/j̄ < 10⁻⁶ at n = 31…255, CDA 7, 9, 11, 13, FLD-LP 12, 16, 38, 125; against
//!   the point source (CDA 3, 3, 2, 2; FLD-LP 4, 4, 4, 5) and `ball_source` (CDA 4, 3, 3, 3;
//!   FLD-LP 5, 6, 7, 7). On the cloud with CDA the first cycles barely gain: R̄/j̄ after the
//!   first two is 0.77, 0.25 at n = 31 and 2.3, 1.3 at n = 127 (1 at φ = 0), and the reduction
//!   per cycle after them is 0.03–0.14 at n = 31 and 0.04–0.43 at n = 127 (2026-12-07, ad-hoc
//!   driver). The evidence points at the rediscretised coarse operator at 2·10⁴ contrast for
//!   CDA: W-cycles (solving the coarse problem more exactly) change no count, more smoothing lowers the
//!   counts but not their growth (F(8, 8): 6, 7, 8, 9), deeper Krylov histories (8, 16) save one
//!   cycle at 127³, and Galerkin coarse operators halve the growth (below). Without Krylov
//!   one mode sets the rate, 0.33, 0.48, 0.57, 0.61 per cycle at n = 31, 63, 127, 255: an
//!   error smooth inside the cloud that peaks a few fine voxels under its surface, closer to
//!   it as n grows, and is there with only two levels (8, 9, 10 cycles at n = 31, 63, 127):
//!   the first coarsening misplaces the interface, whose surface voxels the fine faces tie to
//!   the vacuum (face D ≈ 167 against 0.017 inside). No mean of a cell's children fixes that
//!   (power means of D with p = 0.5, 2, 4: 8, 9, 11; 8, 10, 12; 8, 10, 11; the geometric
//!   mean of σ 9, 12, 14), since one cell D cannot conduct towards the vacuum and insulate
//!   towards the cloud; the Galerkin operators' directional couplings partly do (below).
//!   Directional coarse face coefficients for the rediscretised levels (two fine faces in
//!   series, full weighting across; `scripts/mg-coarse-operators.py`'s `series` and
//!   `series-op`, not built in the crate) do not: F-cycles with conjugate gradients took 30,
//!   44, 54 and 15, 22, 25 cycles at n = 33, 65, 129 against the rediscretised 10, 13, 15,
//!   and plain V-cycles diverged (seventeenth session, `HISTORY.md`). Classical algebraic
//!   multigrid (pyamg's Ruge–Stüben on the same operator, the script's `ruge-stuben`), whose
//!   coarse grids follow the interface, grows too: V + CG 5, 5, 7 cycles at n = 33, 65, 129
//!   (+40 %). That agrees with the theory of multigrid-preconditioned CG for jump
//!   coefficients (finite elements; Xu and Zhu, M3AS 2008, and for diffusion with absorption
//!   Kolev, Xu and Zhu, arXiv:1411.7092): apart from a few small eigenvalues the effective
//!   condition number is bounded uniformly in the jump but only up to a factor logarithmic in
//!   the mesh size, so such bounds allow a slow growth with n and none promises a flat count.
//!   Also tried and
//!   dropped (`HISTORY.md`): relaxing the cloud's surface shell (8, 10, 12 → 8, 10, 11 cycles
//!   at n = 31, 63, 127), boxes that follow the largest residual (FLD-LP 14, 20, 43, 125 → 11,
//!   19, 27, 106 cycles but 107 s against 68–72 s at 255³), and a Jacobi-smoothed
//!   prolongation (CDA 8, 10, 12 → 18, 41–42, 80–81).
//! * **Why the cloud's FLD-LP cycles grow: the peak of D at a critical point of φ in the
//!   vacuum.** At n = 127 (ω = 1), from cycle 7 on 94–99 % of Σr² sat in vacuum voxels, the
//!   largest residuals just outside the cloud where φ is flat: there R = |∇φ|/(σ_ε φ) falls and D = F(R)/σ_ε rises towards
//!   1/(3σ_ε) = 333. The largest interior D at the converged φ ([`diffusion_field`]) is 0.65,
//!   1.76, 9.8 and 111 at n = 31, 63, 127, 255, always at the same place, so the discrete
//!   problems carry a coefficient contrast that grows with n, as the point source's one-voxel j
//!   does. Capping it by a larger σ_ε (`cloud_floor`, σ_ε = 1, D ≤ 1/3) brings FLD-LP to
//!   the growth CDA shows (8, 8, 10, 11 cycles at n = 31…255, against CDA's 8, 9, 11, 13 on
//!   the cloud); σ_ε is physics, not a solver
//!   setting (σ_ε = 1 moves φ in the cloud by 8.7·10⁻³ relative L2), so the default stays.
//!   The lagged D of the smoother leaves out D's dependence on φ, which near such a point is as
//!   large as the operator itself; what it needs is the limiter's Jacobian (a Newton step) where
//!   D is sensitive, or coarse operators built from the fine D; neither is built. Local
//!   relaxation at the peak (2–50 sweeps on the voxels with the largest residuals), a deeper
//!   Krylov history and the θ of the D update did not remove the growth (`HISTORY.md`).
//!   Pinned by `the_cloud_s_fld_cycles_follow_the_peak_of_d_in_its_vacuum`.
//! * **Galerkin coarse operators ([`CoarseOp::Galerkin`], CDA, CPU only)**: A_c = R A P with
//!   the cycle's own transfers by probing the finer operator (27-point stencils, up to 125 on
//!   cell-coarsened axes; module `galerkin`), multi-colour Gauss–Seidel, solved for the
//!   correction. On the cloud at n = 31…255: 7, 8, 8, 10 cycles (+43 %) against 8, 10, 12, 14
//!   rediscretised (ω = 1.2, from φ = 0), φ within 1.4–12·10⁻⁸ of the rediscretised solve; but
//!   its setup (1.7 s at 127³, 13–18 s at 255³) and scalar rows make it 4× slower (the cloud at
//!   127³ 4.0 s against 1.0 s), so the rediscretised levels stay the default. An
//!   operator-dependent P (outside the crate, `scripts/mg-coarse-operators.py`) reached 7, 8, 9,
//!   10 (F + CG): still +43 %. For FLD it would need Pᵀ A(D) P once per Picard step (not built).
//!   Pinned by `galerkin_coarse_levels_cut_cda_cycles_on_the_vacuum_cloud`.
//! * **FLD-LP on 95 %-vacuum white noise in f32** ends at f32's floor: on the GPU `Stalled`
//!   after 52 cycles at R̄/j̄ 1.14·10⁻⁵, the CPU-f32 multigrid `Converged` after 48 at
//!   8.2·10⁻⁶ (tolerance 10⁻⁵; `tests/fld_multigrid_gpu.rs`).
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
    /// docs: fewer cycles, flatter in n, in 3 of 4 cases faster than V at 127³).
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
            d_row(
                g,
                phi,
                sig,
                g.index(1, j, k),
                floor,
                &lim,
                &mut row[1..nx - 1],
            );
        }
    });
}

/// D = F(R)/σ (`lim` gives F as [`FluxLimiter::fraction`]'s numerator and denominator) at
/// the `out.len()` voxels of one x-row from voxel `c` on, with centred differences: in one
/// contiguous loop that vectorises. Shared by [`fresh_d_with`] and the local boxes.
#[inline(always)]
pub(super) fn d_row<L: Fn(f64) -> (f64, f64)>(
    g: &Grid,
    phi: &[f64],
    sig: &[f64],
    c: usize,
    floor: f64,
    lim: &L,
    out: &mut [f64],
) {
    let (nx, plane, len) = (g.n[0], g.n[0] * g.n[1], out.len());
    let inv_2dl = 0.5 / g.dl;
    let cut = |start: usize| &phi[start..start + len];
    let (p, xm, xp) = (cut(c), cut(c - 1), cut(c + 1));
    let (ym, yp, zm, zp) = (cut(c - nx), cut(c + nx), cut(c - plane), cut(c + plane));
    let s = &sig[c..c + len];
    for q in 0..len {
        let gx = (xp[q] - xm[q]) * inv_2dl;
        let gy = (yp[q] - ym[q]) * inv_2dl;
        let gz = (zp[q] - zm[q]) * inv_2dl;
        let r = (gx * gx + gy * gy + gz * gz).sqrt().max(floor) / (s[q] * p[q]).max(floor);
        let (num, den) = lim(r);
        out[q] = num / (den * s[q]);
    }
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
