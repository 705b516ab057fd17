//! Principal-ordinates propagation (Elek, Ritschel, Dachsbacher, Seidel, *Principal-Ordinates
//! Propagation*, Computers & Graphics 45, 2014; "POP Eq N"), CPU core. The OCR copy garbles
//! Eqs 2–4 and 6; they are used as rebuilt in `specs/pop.md` (§1.6), whose decisions D1… and
//! tests T1… are cited below.
//!
//! * [`PopMedium`]: σs, σa per channel per voxel, g per channel (g ∈ [0, 1]).
//! * [`Ordinate`]: a collimated beam (d, E, a). [`Ordinate::directional`] for a directional
//!   light; [`environment_ordinates`] for an environment (Sec 5.1).
//! * [`PropagationGrid`] ([`grid`]): the grid aligned with one ordinate, and the medium
//!   resampled into it.
//! * [`CpuPop`] ([`cpu`]): the propagation state of one ordinate (rayon, `f32`/`f64`).
//! * [`solve`]: every ordinate, [`PopSolution::fluence_on`] gathers φ onto a world grid.
//! * [`GpuPop`] ([`gpu`]): the same propagation on the GPU (f32); [`gpu::solve`].
//! * [`method::PopMethod`]: the registered method `pop[:per-cell|:heuristic]`, which takes
//!   the lights itself (`LightInput::Direct`; what its φ holds is in [`method`]).
//!
//! ## The equations (POP Sec 4, as rebuilt)
//! Per cell i and channel: magnitude L_i and anisotropy a_i; the radiance is
//! L(x_i, ω) = L_i·f_hg(ω·d, a_i) with f_hg(μ, g) = (1 − g²)/(4π(1 + g² − 2gμ)^{3/2}).
//!
//! * **Eq 1**: F_hg(μ, g) = ∫_{−1}^{μ} f_hg dμ′; with the azimuth, G = 2πF_hg has the closed
//!   form G(μ, a) = (1 − a)(1 + μ)/(s(1 + a + s)), s = √(1 + a² − 2aμ) ([`cumulative`]).
//! * **Eqs 2–3**: ΔL_{src→dst} = L_src·T_{src→dst}·|φ₁ − φ₂|(F(cos θ₁) − F(cos θ₂)) over the
//!   patches (θ₁, θ₂, |φ₁ − φ₂|) = (0, π/4, 2π) front, (π/4, 3π/4, π/2) each lateral
//!   neighbour, (3π/4, π, 2π) back: the fractions 1 − G(1/√2, a), (G(1/√2, a) − G(−1/√2, a))/4
//!   and G(−1/√2, a) ([`fractions`]); T = exp(−σ̄a z), absorption only.
//! * **Eq 4**: Δa_{src→dst} = a_src·ḡ^{σ̄s z} ([`decay`]).
//! * **Eq 5**: L_dst = Σ_src ΔL; **Eq 6**: a_dst = Σ ΔL·Δa / Σ ΔL.
//! * **Eq 7**: L_acc^{m+1} = L_acc^m + L^{m+1}(x_i, c − x_i); **Eq 8**: … + L^{m+1}_i·f_hg(u, a^{m+1}_i),
//!   u = d·(view direction).
//! * Ping-pong L^m → L^{m+1} over all cells; stop when every L^m is below ε_L (Sec 5.4) or at
//!   a fixed M (the paper: 10–20).
//!
//! **Cost** (`benches/benches/pop.rs`, the Fig 14 setting: 64 ordinates × 20³ × 10
//! iterations, RGB, `results/bench/pop.csv`), on the 2 cores shared with other jobs (load
//! average 11 during the run): propagation 492 ms f32 (1.04·10⁷ RGB cell-updates/s, the
//! issue's target of ≤ 0.5 s met by a hair on a loaded machine) and 620 ms f64
//! (8.3·10⁶/s); the whole solve with grid builds and resampling 653 / 1215 ms. Effective
//! 2.9 / 4.6 GB/s = 0.11 / 0.27 of the same run's STREAM-rule triad: compute-bound (two
//! square roots and divisions per cell and channel for the fractions, the six-term ledger).
//! Cells without light skip the fraction pass (a wavefront fills one slice per iteration).
//!
//! The isotropic residuum (Eqs 9–10) is in [`residuum`] (CPU, f64, behind
//! `PopConfig::residuum`; registered as the variants `pop:residuum` and, ours, `pop:residuum-fld`,
//! see [`method`]). Back to world space (Secs 4.4, 5.3) is [`upsample`]: the merge
//! into one medium-aligned grid at 2× the ordinate grids' resolution (D13), joint bilateral
//! upsampling guided by σs (D19; trilinear as the control; T14 and the W10 energy
//! measurement there), and POP's own image ([`upsample::view_image`]: the camera as Eq 8's
//! observer, σs·L_acc raymarched through the pipeline's view-dependent source hook
//! `pipeline::raymarch::Term::ViewSource`). Point lights propagate on radial octahedral grids (Sec 6, spec D16–D18) in [`radial`]:
//! [`solve_point`] and [`RadialSolution::fluence_on`]; its own docs hold the equations, the
//! decisions with their measurements and T15; [`method::PopMethod`] runs one per point
//! light, on the CPU or on the GPU ([`radial::gpu`], `radial.wgsl`: the same step, bitwise
//! equal to CPU-f32 at a fixed step count on lavapipe, `tests/pop_gpu.rs`). Importance
//! propagation (Sec 5.2) is not built; the GPU kernels propagate directional, environment
//! and emission ordinates and point lights' radial grids (what the CPU code does), and the
//! grids, resampling and links are still built on the host.
//!
//! ## GPU ([`gpu`], `pop.wgsl`, f32)
//! Per ordinate the host builds the [`CpuPop`] (resampling, links T and γ, Eq 8's u,
//! injection) and [`GpuPop::load`] uploads it into buffers allocated once per grid size and
//! reused by every ordinate of a solve; a step is two dispatches (fractions with each cell's
//! own loss accumulator, then the gather with φ, J, L_acc); the ledger is reduced per slice
//! and channel on the GPU and added in slice order on the host in f64, read back every
//! K = [`gpu::DEFAULT_CHECK_EVERY`] = 8 steps under ε_L, and only at the end (≤ 1024 steps
//! per submission) at a fixed M. No pow in the shader (γ is the host's [`decay`] with the
//! V16 branches); a is clamped to [0, 1] before the fractions (a = 1 gives 1, 0, 0 without
//! 0/0), and Eq 8 uses [`kernel::hg_view`]'s clamped cancellation-free f_hg. Measured on lavapipe
//! (llvmpipe, Mesa 22.3.6; `solvers/tests/pop_gpu.rs`):
//! * **T17** (12³ random medium with vacuum and 10⁴ contrast, two channels g = 0.7 / 0.95, skew
//!   d, point observer, M = 64, open and periodic faces; and the paper's per-cell init with the
//!   literal Eq 8 and an orthographic observer): φ, J, L_acc, L and a are **bitwise
//!   equal** to CPU-f32 (max difference 0: the shader repeats cpu.rs's operation order, and
//!   lavapipe's f32 arithmetic matched the CPU's bit for bit; a GPU that fuses multiply-adds
//!   need not, hence the bounds); the exit fractions differ by ≤ 5.0·10⁻⁸ (2.0·10⁻⁷ with
//!   the per-cell init; f32 per-cell loss sums vs the CPU's f64 per-slice sums; bound
//!   10⁻⁴). The ε_L = 10⁻³ stop on
//!   the Fig 12 cube at g = 0.7, 16³: CPU 397 steps, GPU 400 (the next multiple of K: 0.8 %,
//!   bound 2 %; φ differs by 1.0·10⁻⁴ relative, the light of the 3 extra steps). The
//!   conformance suite's `pop::gpu_matches_cpu_f32` (15³, 64 steps) measures 0 too, and so
//!   does the method under a constant environment (8 ordinates) plus a sun, 40 iterations.
//! * **T10**: three channels × two ordinates in one GPU solve = the single-channel
//!   single-ordinate GPU solves to 0 (bound 10⁻⁵): the reused buffers keep nothing of the
//!   previous ordinate.
//! * **T3**: |injected − absorbed − exits − in flight|/injected ≤ 2.9·10⁻⁷ after 150 steps on
//!   the four random media of `t3_…` and ≤ 1.6·10⁻⁷ at each of 120 single steps (bound
//!   10⁻⁵); R never rises by more than 10⁻⁶ relative between checkpoints.
//! * **T4** (g ∈ {0, 1}, vacuum cells, σΔx ∈ [10⁻⁶, 10³], observer): L finite ≥ 0, a ∈ [0, 1],
//!   accumulators finite ≥ 0. Two GPU solves are bitwise identical (accumulators, ledgers,
//!   histories).
//!
//! * **Emission** (ours; "Volume emission" below): the host injects it into the [`CpuPop`]
//!   that [`GpuPop::load`] uploads, so the kernel needs nothing more
//!   (`method_on_the_gpu_takes_emission`: 10³ random medium, 10²-contrast j, a constant
//!   environment sharing its 8 grids with the emission plus a sun, 40 fixed iterations: φ
//!   equal to CPU-f32, max difference 0; emission alone at rel = 10⁻⁴: the GPU stops after 32
//!   steps at its checkpoints vs the CPU's 25, φ within 6.8·10⁻⁵, and its books close to
//!   2.8·10⁻⁵, the power still in flight). The conformance suite's `pop::gpu_matches_cpu_f32`
//!   now runs POP on its emission source (15³, 64 ordinates, 64 steps): difference 0.
//!
//! The GPU's speed is not measured here (lavapipe runs on the same loaded CPU cores; the
//! bench has a GPU row for a real device).
//!
//! ## Decisions where the paper is silent
//! Each with what pins it (tests in `pop/tests.rs`; all pass in f64 and, where named, f32).
//!
//! * **Initialisation (D1).** Sec 4.1 fills every cell with L_in·T_i and a = 1. Under Eqs 5
//!   and 7 that counts the beam (j+1) times in cell j ([`Init::PaperPerCell`], kept as a
//!   variant: `t6_…` measures φ_j/exact = j+1 to 10⁻⁹ in a pure absorber). The default
//!   [`Init::EntrySlice`] injects a wavefront into slice k = 0 only: L = E·e^{−σa Δx/2},
//!   a = a_n·g^{σs Δx/2}. A pure absorber then gives φ = E·e^{−σa x} at every cell centre to
//!   10⁻¹² (f64; 10⁻⁵ f32) and the run converges in exactly N_d iterations (`t5_…`).
//! * **Frame and size (D2, D3).** The frame across d is Duff et al.'s branch-free basis
//!   ([`frame`]; orthonormal and right-handed for 200 random d and ±z; d = +x gives
//!   t₁ = −z, t₂ = +y so an axis ordinate's cells are the medium's voxels,
//!   `frames_are_…`). N³ cubic cells, Δx = the largest extent of the medium's box along
//!   the three frame axes / N, centred on the box: a diagonal ordinate's cells are up to √3
//!   larger. T12 (`t12_rotation_invariance`: homogeneous ball, σs = 4, σa = 0.4, g = 0.9, 20³,
//!   converged to 10⁻⁶) measures what that costs: relative L2 of the world fluence vs the
//!   d = x̂ run of 0.023 (x̂ with its frame turned 45°, cells √2 larger), 0.026 and 0.024
//!   ((1,1,0)/√2, plain and turned), 0.026 and 0.026 ((1,1,1)/√3); bound 0.035 (spec's 5 %).
//! * **Resampling (D4).** MIP level ℓ = ⌈log₂(Δx/Δx_medium)⌉ (capped at the coarsest
//!   level with one voxel), box filter of σs and σa separately (∫σs dV, ∫σa dV conserved
//!   to 10⁻¹², levels 0–2), then clamped trilinear at the rotated cell centres, vacuum
//!   outside the medium's box (`resampling_…`). g is one per channel (the project's scenes
//!   have one phase function), so the σs-weighted g of D4/D6 is moot.
//! * **Pair coefficients (D6, V9).** σ̄a and σ̄s are the arithmetic means of src and dst,
//!   z = Δx; T and γ = ḡ^{σ̄s z} are precomputed per cell link once per grid (the medium
//!   does not change between iterations). γ takes the branches of V16 (σ̄s z = 0 → 1 even
//!   at g = 0; g = 0 → 0): `t4_…` runs g ∈ {0, 1}, vacuum cells and σΔx ∈ [10⁻⁶, 10³] and
//!   finds L ≥ 0, a ∈ [0, 1] and finite accumulators in f32 and f64.
//! * **Boundaries (ours).** Nothing enters except by injection. Light leaving the grid goes
//!   through a vacuum ghost cell: the link's σ̄a is half the cell's, so the exit carries
//!   e^{−σa Δx/2} and the rest is absorbed. With the D1 half cell at entry, a pure-absorber
//!   slab transmits exactly e^{−τ} (`t5_…`). [`Lateral::Periodic`] makes a laterally infinite
//!   slab for the adding–doubling comparisons (T7).
//! * **Eq 6 without light.** A cell that receives nothing gets a = 0; a is clamped to
//!   [0, 1] against rounding.
//! * **Bookkeeping (D5).** Per channel a [`Ledger`]: injected, absorbed (1 − T of every
//!   transfer), exits through the entry face (R), far face (T) and lateral faces, in flight
//!   (Σ L Δx²), each summed in f64 per slice and then in slice order. Accumulators per cell:
//!   φ = Σ_m L^m (the initial L⁰ included), J = Σ_m L^m a^m (flux along d; ⟨μ⟩ = J/φ) and
//!   L_acc. `t3_…`: injected = absorbed + exits + in flight at every one of 300 iterations
//!   on random media (vacuum, 10⁴ contrast, albedo 0–1, g ∈ {0, 0.5, 0.9, 0.99}, skew d) to
//!   10⁻¹² (f64) and 10⁻⁵ (f32), and the power in flight never rises.
//! * **Eq 8 (D7, D8).** u = d·(c − x_i)/|c − x_i| ([`Observer::Point`]) or d·w
//!   ([`Observer::Direction`]). Default [`Eq8::PhaseConvolved`] accumulates
//!   L^m f_hg(u, a^m g), the in-scattered lobe; [`Eq8::Literal`] uses a^m as printed. Both
//!   clamp the lobe to ≤ 1 − 10⁻⁴ and evaluate f_hg as (1 − g)(1 + g)/((1 − g)² + 2g(1 − μ))^{3/2}/4π,
//!   which is finite in f32 where the expanded denominator cancels to ≤ 0 (`t2_…`). The
//!   convolution is exact, not an approximation: HG lobes have Legendre moments g^l, and the
//!   moments of a convolution multiply, so HG(a) ⊛ HG(g) = HG(a·g). **T23, the orbit test**
//!   (`reference/tests/pop_orbit.rs`: Fig 12 cube, an orthographic camera on a circle in the
//!   plane of d, POP's own image by [`upsample::view_image`] vs the path tracer, mean
//!   silhouette radiance): the phase-convolved reading is closer, mean |ln(POP/PT)| over
//!   θ = 0…180° of 0.33 vs 0.58 (literal) at g = 0.96 and 0.85 vs 1.02 at g = 0.7. At
//!   g = 0.96 POP/PT is 0.49 / 1.21 / 1.30 / 1.25 / 0.88 / 0.82 / 0.54 at θ = 0 / 10 / 20 / 45 /
//!   90 / 135 / 180° (literal 3.30 / 1.21 / 1.07 / 0.93 / 0.59 / 0.49 / 0.27). T23 as written
//!   (one reading within 2× at every angle) fails at θ = 0 only, straight into the beam: the
//!   light there is a mixture of scattering orders (order k ≈ HG(g^k)) and one HG lobe with
//!   the same first moment has a lower forward peak (HG(1, x) is convex in x: 0.46–0.65 of the
//!   mixture for σs z = 0.5…4), a limit of the unimodal lobe (W1), which the test pins as the
//!   band [0.4, 0.7]. At g = 0.7 POP is 2.5–4.3× too bright from θ = 45° on (W2).
//! * **Stopping (D9).** R^m/P_inj < ε_L in every channel, where R^m is the power in flight
//!   (default ε_L = the precision's `DEFAULT_TOLERANCE`, 10⁻⁶ f64, 10⁻⁴ f32); ε_L = 0 runs
//!   the paper's fixed M ([`PopConfig::fixed`]); a run also stops when nothing is left.
//! * **Environment (D10, D11).** Spherical Fibonacci directions; a latitude–longitude map
//!   rasterised with exact texel solid angles and first moments, each texel assigned to the
//!   nearest ordinate (its Voronoi cell): E_n = Σ L Ω. [`Prefilter::Voronoi`] (default)
//!   takes d_n = −(radiance-weighted centroid) and a_n = |∫Lω|/∫L over the cell, so Σ E_n = ∫L dω
//!   and Σ E_n a_n d_n = −∫Lω dω. `t11_…`: both to 10⁻¹² for a constant environment
//!   (N = 8…216), the gradient 1 + ω_z/2 to 10⁻⁴, and a_n within 2 % of the cap value
//!   1 − 1/N for N ≥ 27. The paper's heuristic ([`Prefilter::Heuristic`], β) and no
//!   prefilter ([`Prefilter::None`]) are variants.
//! * **Determinism.** Every cell is a pure gather; sums are per slice then in slice order:
//!   results are bitwise equal on 1 and 3 threads (`results_do_not_depend_…`).
//!
//! ## Volume emission (ours, not the paper's)
//! The paper has lights only. POP here also takes the medium's isotropic volume emission j
//! ([`PopMedium::emission`]; power per volume spread over 4π, the source of the fluence
//! equation as in [`crate::fld`], so an infinite medium has φ = j/σa). Each decision with its
//! measurement and the test in `pop/emission_tests.rs` that pins it (f64 unless named):
//! * **E1, the ordinates.** Isotropic emission is apportioned exactly as D10–D11 apportion a
//!   constant environment: [`env::emission_ordinates`] takes the N ordinates of a constant
//!   unit environment (same Fibonacci set, Voronoi cells and prefilter) and gives ordinate n
//!   the share w_n = E_n/ΣE = Ω_n/4π ([`Ordinate::emission`]) and the anisotropy a_n that D11
//!   gives it, the mean cosine of its cap about d_n: Σ w_n = 1 and Σ w_n a_n d_n = 0 to
//!   10⁻¹² for N = 1…216 (`emission_ordinates_share_…`). In [`method::PopMethod`] the emission
//!   takes `ordinates` (default 64) with the method's prefilter: with no light at all (an
//!   emissive cloud alone) these are the only ordinates; with a constant environment light
//!   the first environment's grids carry the emission too ([`env::share_emission`]: the twins
//!   agree to rounding), so it costs no extra grid; with only directional lights the
//!   emission needs its own N grids, i.e. N ordinate propagations on top of one per sun.
//!   Measured once each (CPU f32, 16³ unit cube, σt = 4, albedo 0.9, g = 0.4, rel = 10⁻⁴,
//!   N = 64; AMD EPYC, 2 cores shared, load average 1.8): solve 0.031 s for a sun alone,
//!   1.67 s for the emission alone, 1.70 s for both, 1.64 s for a constant environment and
//!   1.64 s for the environment with the emission (sharing costs nothing measurable).
//! * **E2, injection.** At step 0 every cell of grid n receives the power j·Δx_n³·w_n, i.e.
//!   L = j w_n Δx_n with anisotropy a_n, through the same path as any packet
//!   ([`CpuPop::emit`]): counted as injected and in flight, merged by Eq 6 with what the cell
//!   holds. The propagation then sums the Neumann series Σ_m P^m S of this step-0 source S,
//!   which is the steady state of the constant source (the m-th term is the light emitted
//!   m cells upstream), so the uncollided emission (m = 0 along each ordinate's straight
//!   run) and every scattering order are in φ, as the contract of
//!   [`crate::method::LightInput`] asks.
//! * **E3, the half visit.** The step-0 packet enters its own cell's accumulators with weight
//!   ½ ([`cpu::EMISSION_VISIT`]): φ is a point value at the cell centre, where half of the
//!   cell's own emission has arrived (D1's half cell for a beam, the same reading). In an
//!   infinite medium this makes φσa/j = h(σaΔx) = (σaΔx/2)·coth(σaΔx/2) = 1 + O((σaΔx)²)
//!   per grid, where a full visit gives σaΔx/(1 − e^{−σaΔx}) = 1 + σaΔx/2 + …. Measured
//!   (`emission_pure_absorber_…`): a full visit would put the centre of the test-1 cube
//!   13.7 % high for every N.
//! * **E4, resampling.** j goes onto each rotated grid the way σ does (D4: box filter to the
//!   MIP level, clamped trilinear at the cell centres, 0 at centres outside the medium's
//!   box), then per channel scaled so that Σ j_cell Δx³ = ∫ j dV ([`grid::resample_emission`]);
//!   a source no cell centre sees goes whole into the cell holding each MIP voxel's centre.
//!   ∫ j dV kept to 10⁻¹² on axis, diagonal and random grids of 3³–20³ over a 9×6×5 medium,
//!   two channels, and by the fallback on a slab thinner than the cells
//!   (`emission_resampling_conserves`). The global scaling moves the interior j of a rotated
//!   grid by the boundary cells' imbalance: at 24³ the interior φ is 7.4·10⁻⁴ above the
//!   prediction with the unscaled j (test 3 below uses each grid's own j_n).
//!
//! Measured (`emission_tests.rs`, CPU; the numbers do not depend on the machine):
//! * **Pure absorber (test 1, `emission_pure_absorber_…`):** unit cube 16³, σa = 2, σs = 0,
//!   j = 3, against the exact uncollided fluence (j/4πσa)∫(1 − e^{−σa ℓ(ω)})dω by quadrature
//!   over directions: φ/exact − 1 at the centre voxel +5.2 %, +0.76 %, +0.15 % for
//!   N = 8, 64, 216 (ray effects: 6.8× smaller from N = 8 to 64, 5× from 64 to 216), 3 voxels from a face +7.4 %,
//!   +0.90 %, +0.12 %; next to an edge ((1, 1, 8)) +9.0 %, −1.5 %, −2.4 % and in the corner
//!   voxel −3.4 %, −9.5 %, −12.4 %: there the rotated grids' cells straddle the box (D3), a
//!   boundary resolution error that more ordinates do not remove. Bounds 8 / 1.2 / 0.3 %
//!   inside, 10 % and 15 % at the edge and corner.
//! * **Books (test 2, `emission_balance_f64/f32`):** the four random media of T3 with
//!   10³-contrast emission in two thirds of the voxels, 8 emission ordinates and a skew beam
//!   sharing a grid with emission: injected = the beam + w_n ∫ j dV to 10⁻¹², and
//!   injected = absorbed + exits + in flight at each of 300 steps to 7.2·10⁻¹⁵ (f64, bound
//!   10⁻¹²) and 3.2·10⁻⁸ (f32, bound 10⁻⁵); the power in flight never rises.
//! * **Infinite medium (test 3, `emission_deep_inside_…`):** σs = σa = 16, g = 0.5, 64
//!   ordinates, the centre 8 absorption lengths from the faces: φσa/j = 1.3323 (12³) and
//!   1.0868 (24³) against the continuum 1, second order (ratio 3.8 of the excesses), and
//!   equal to E3's (1/σa)Σ w_n j_n h(σaΔx_n) to 1.2·10⁻⁵ (12³) and 2·10⁻⁸ (24³).
//! * **Method (test 4):** `pop`, `pop:residuum` and `pop:residuum-fld` with emission and no
//!   light report the source ∫ j dV to 10⁻¹², and their books close to 9.1·10⁻¹⁰ (`pop` at
//!   rel = 10⁻⁹: what is still in flight), 1.0·10⁻¹⁶ and 8.8·10⁻¹⁷ (across the switch: the
//!   emitted power is merged and handed over like a beam's); a sun adds exactly (3.5·10⁻¹⁶
//!   of max φ where its φ_s is not clamped), a constant environment sharing the grids adds
//!   up to 8.8·10⁻⁵ of max φ (Eq 6 merges the two lobes of a cell into one, and the Eq 3
//!   fractions are not linear in a) (`emission_adds_…`, `emission_runs_…`).
//! * **f32 (test 5, `emission_f32_…`):** φ within 2.9·10⁻⁷ of f64 (bound 10⁻⁵).
//!
//! ## What the scheme does (measured; the spec's prototype reproduced)
//! Once a lobe has isotropised (a → 0, fractions 0.146/0.177/0.146) POP is a lattice random
//! walk that moves one cell per iteration: variance (1 − 1/√2)·m Δx² along d and
//! (1/√2)/2·m Δx² across, to 10⁻¹⁰ (`t8_…`, 64³ vacuum). Its mean free path is set by the
//! grid, not by σs or g:
//! * laterally periodic slab, albedo 1, g = 0: T = 1/(N+1), R = N/(N+1) to 10⁻⁹ for
//!   N ∈ {4, 8, 16} and σs ∈ {0.5, 4, 32} alike (`t7_…`); slab τ = 4, albedo 1: R = 0.00162
//!   (N = 8) and 0.00058 (N = 16) at g = 0.9 (the spec's adding–doubling value: 0.122), 0.642 at g = 0.5,
//!   N = 16 (spec AD: 0.51) (`t19_slab_…`);
//! * the Fig 12 cube (unit cube, σs = 4, albedo 1, 16³, d = +x), converged: exits R/T/side
//!   0.6706/0.0033/0.3261 (g = 0; independent of σs ∈ {0.5, 4, 32}), 0.0354/0.1382/0.8264
//!   (g = 0.7), 0.00021/0.9350/0.0648 (g = 0.96); volume-mean φ 1.030, 3.516, 1.058 (path
//!   tracer in the spec: 0.86, 0.89, 0.95); at the paper's M = 16: 0.471, 0.942, 1.021; centre
//!   ⟨μ⟩ 0.318 (M = 16) and 0.081 (converged) at g = 0.7 vs the path tracer's 0.62, and 0.913
//!   at g = 0.96 vs 0.91 (`t19_cube_…`; every figure within 1 % or the rounding of the
//!   spec's prototype value);
//! * convergence (g = 0.7): R^M/P_inj = 0.890, 0.753, 0.556, 0.308, 0.101, 1.13·10⁻²,
//!   1.39·10⁻⁴ at M = 8…512; 10⁻³ at 397 and 10⁻⁶ at 800 iterations (16³); 3008 at 32³
//!   (ratio 3.760, ∝ N²), where the volume-mean φ grows to 6.07 (`t21_…`): the scheme does
//!   not converge to transport under grid refinement (spec W2).
//! * constant environment on a ball (σs = 4, albedo 0.9, g = 0.9, 12³, M = 36):
//!   ‖φ_N − φ_216‖/‖φ_216‖ = 0.139, 0.033, 0.011, 0.0033 for N = 8, 27, 64, 125 (`t22_…`).
//!
//! ## The isotropic residuum and the comparison with the path tracer (measured)
//! * **Eq 10 (T16, `residuum::tests::t16_…`).** The Fig 8 inputs (σs = 0.91/1.07/1.25 m⁻¹,
//!   g = 0.95, ε_a = 0.1, Δx = 0.25 m) give m′ = 197.3 / 167.8 / 143.6 at ā = 1 and
//!   196 / 166 / 142 at ā = 0.98 (spec V4), not the paper's 20; the switch is ⌈m′⌉ clamped to
//!   [N_d, M_max], the clamp returned in [`residuum::SwitchIteration`].
//! * **Merge (T13, `t13_…`).** The adjoint-of-trilinear splat conserves Σ Q to 10⁻¹² (2000
//!   random points, some outside the box) and the gather maps a constant to itself to 10⁻¹²;
//!   the books balance across the switch to 10⁻¹² (`residuum_conserves_…`).
//! * **Fig 8 / T24 (`tests/pop_residuum.rs`, 64 ordinates, 16³, f64).** Full run: 42–50
//!   iterations per ordinate (not the paper's ≈ 100). Paper m′ = 20 + 20 isotropic steps on
//!   32³: max a at the switch 0.755 (> ε_a; spec 0.75), 5.2 % of the power in flight at the
//!   switch, 1.4 % dropped, volume-mean φ +2.6 %, relative L2 of φ 0.035 and of an
//!   orthographic image 0.035 (the spec's 2 % flag is exceeded), 2.06× fewer cell updates
//!   (paper: 4×). Eq 10 with the D11 ā = 0.984 and the mean Δx_n gives m′ = 108.9, after every
//!   ordinate has converged: no residuum, the full result.
//! * **Fig 12 cube vs the path tracer** (`reference/tests/pop_cube.rs`, 2·10⁵ paths, the
//!   path tracer's current tally): volume-mean φ POP/PT = 1.196 (g = 0), 3.95 (0.7), 1.111
//!   (0.96; T20's 15 % holds). ⟨μ⟩ on the axis at g = 0.96: POP 0.979 → 0.857 from entry to
//!   far face, PT 0.934 → 0.910: differences +0.045, +0.032, +0.007, −0.020, −0.053 (PT error
//!   ≤ 0.005), so T20's "⟨μ⟩ within 0.03" holds only at the middle probes. g = 0: POP ⟨μ⟩ = 0
//!   everywhere vs PT 0.24–0.38; g = 0.7: POP 0.39 → 0.02 vs PT 0.55–0.63. Exits R/T/side:
//!   PT 0.326/0.073/0.601 (g = 0), 0.096/0.243/0.661 (0.7), 0.0097/0.736/0.254 (0.96)
//!   (the spec's prototype MC: 0.327/0.073/0.600, 0.095/0.243/0.662, 0.010/0.735/0.256).
//! * **Fig 12's angular radiance** ([`probe::angular`] vs the path tracer's direction-binned
//!   tally, centre probe, 20 bands of μ, `reference/tests/pop_cube.rs`): relative L2 over the
//!   bands 0.052 at g = 0.96 (forward band 1.46 vs 1.40 ± 0.01, the rest within 30 %), 4.6 at
//!   g = 0.7 (POP nearly isotropic, 0.64 vs 0.02 in the backward band).
//! * **Convergence (`pop_convergence`, g = 0.7):** 263 / 397 / 800 iterations to 10⁻² / 10⁻³ /
//!   10⁻⁶ at 16³, 978 / 1486 / 3008 at 32³; converged volume-mean φ 3.516 and 6.069.

pub mod cpu;
#[cfg(test)]
mod emission_tests;
pub mod env;
pub mod gpu;
pub mod grid;
pub mod kernel;
pub mod method;
pub mod probe;
pub mod radial;
pub mod residuum;
#[cfg(test)]
mod tests;
pub mod upsample;

pub use cpu::{CpuPop, Ledger};
pub use env::{Prefilter, environment_ordinates, fibonacci};
pub use gpu::GpuPop;
pub use grid::{PropagationGrid, frame};
pub use kernel::{Fractions, cumulative, decay, fractions, hg};
pub use method::{POP, PopMethod};
pub use radial::{RadialConfig, RadialSolution, solve_point};
pub use upsample::{Slot, Upsample};

use crate::method::Stop;
use crate::{Grid, Medium, Real, SolverError};
use rayon::prelude::*;

/// Initialisation of a propagation grid (spec §1.5, V1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Init {
    /// Decision D1: a wavefront injected into the entry slice k = 0 only, L = E·e^{−σa Δx/2},
    /// a = a_n·g^{σs Δx/2}. Energy-exact.
    #[default]
    EntrySlice,
    /// POP Sec 4.1 as printed: every cell L_i = E·T_i (T_i with σt to the cell centre along
    /// d), a = a_n. Counts the beam (j+1) times in cell j (test T6).
    PaperPerCell,
}

/// Which lobe Eq 8 accumulates towards the observer (spec D8).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Eq8 {
    /// In-scattered radiance: Σ_m L^m f_hg(u, a^m·g) (HG self-convolution).
    #[default]
    PhaseConvolved,
    /// POP Eq 8 as printed: Σ_m L^m f_hg(u, a^m), a clamped to ≤ 1 − 10⁻⁴.
    Literal,
}

/// The lateral faces of a propagation grid (the faces parallel to d).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Lateral {
    /// Light leaving through a lateral face is lost (the paper).
    #[default]
    Open,
    /// Laterally periodic: a slab of infinite extent (tests T7, T19 vs adding–doubling).
    Periodic,
}

/// The observer of Eq 8 (spec D7: u = d·(direction from the cell to the observer)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Observer {
    /// A camera at this world position (perspective).
    Point([f64; 3]),
    /// A camera infinitely far along this unit direction (orthographic).
    Direction([f64; 3]),
}

/// One principal ordinate: a collimated beam along `direction` with `irradiance` measured
/// perpendicular to it and initial lobe anisotropy `anisotropy` (1: a directional light;
/// lower after prefiltering, Sec 5.1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ordinate {
    /// Unit direction of travel d_n.
    pub direction: [f64; 3],
    /// E_n, irradiance on a plane perpendicular to d_n (every channel).
    pub irradiance: f64,
    /// a_n ∈ [0, 1].
    pub anisotropy: f64,
    /// w_n ∈ [0, 1]: the share of the medium's isotropic volume emission this ordinate
    /// carries (ours, not the paper's: Ω_n/4π of the cap it stands for, see
    /// [`env::emission_ordinates`]); 0 for a directional light. Injected at step 0 into
    /// every cell as the power j·V·w_n with anisotropy a_n ([`CpuPop::emit`]).
    pub emission: f64,
}

impl Ordinate {
    /// A directional light: one ordinate with a = 1 (Sec 5, spec §1.2). Fails on a zero or
    /// non-finite direction or an irradiance that is not finite and ≥ 0.
    pub fn directional(direction: [f64; 3], irradiance: f64) -> Result<Self, SolverError> {
        let o = Self {
            direction: grid::normalise("ordinate.direction", direction)?,
            irradiance,
            anisotropy: 1.0,
            emission: 0.0,
        };
        o.validate()?;
        Ok(o)
    }

    /// Checks the fields (unit direction, E ≥ 0 finite, a ∈ [0, 1], w ∈ [0, 1]).
    pub fn validate(&self) -> Result<(), SolverError> {
        let len = grid::dot(self.direction, self.direction).sqrt();
        if (len - 1.0).abs().is_nan() || (len - 1.0).abs() > 1e-9 {
            return Err(SolverError::BadParameter {
                name: "ordinate.direction",
                value: len,
                reason: "must be a unit vector (use Ordinate::directional to normalise)",
            });
        }
        if !(self.irradiance.is_finite() && self.irradiance >= 0.0) {
            return Err(SolverError::BadParameter {
                name: "ordinate.irradiance",
                value: self.irradiance,
                reason: "must be finite and ≥ 0",
            });
        }
        if !(0.0..=1.0).contains(&self.anisotropy) {
            return Err(SolverError::BadParameter {
                name: "ordinate.anisotropy",
                value: self.anisotropy,
                reason: "POP lobes have a ∈ [0, 1]",
            });
        }
        if !(0.0..=1.0).contains(&self.emission) {
            return Err(SolverError::BadParameter {
                name: "ordinate.emission",
                value: self.emission,
                reason: "an ordinate's share of the volume emission is in [0, 1]",
            });
        }
        Ok(())
    }
}

/// The medium as POP reads it: σs and σa per channel per voxel of one grid, and the
/// Henyey–Greenstein g of each channel (the project's phase is one per scene; POP's per-cell
/// g, Sec 4, is not needed by any scene here).
#[derive(Debug, Clone, PartialEq)]
pub struct PopMedium {
    /// The medium's voxel grid.
    pub grid: Grid,
    /// σs per channel per voxel.
    pub sigma_s: Vec<Vec<f64>>,
    /// σa per channel per voxel.
    pub sigma_a: Vec<Vec<f64>>,
    /// g per channel, in [0, 1] (negative g is excluded, POP Sec 4).
    pub g: Vec<f64>,
    /// The isotropic volume emission j per channel per voxel (power per volume, spread over
    /// 4π: the source of the fluence equation, as in [`crate::fld`]); empty: none. Ours, not
    /// the paper's (see the module docs, "Volume emission").
    pub emission: Vec<Vec<f64>>,
}

impl PopMedium {
    /// One channel per medium (all on the same grid), with phase parameter `g[c]` each.
    pub fn new(media: &[Medium<f64>], g: &[f64]) -> Result<Self, SolverError> {
        let first = media.first().ok_or(SolverError::BadParameter {
            name: "channels",
            value: 0.0,
            reason: "at least one channel medium is needed",
        })?;
        if g.len() != media.len() {
            return Err(SolverError::FieldSize {
                field: "g (one per channel)",
                expected: media.len(),
                got: g.len(),
            });
        }
        let mut sigma_s = Vec::with_capacity(media.len());
        let mut sigma_a = Vec::with_capacity(media.len());
        let emits = media.iter().any(|m| m.emission.iter().any(|&j| j != 0.0));
        let mut emission = Vec::new();
        for m in media {
            m.validate()?;
            if m.grid != first.grid {
                return Err(SolverError::Unsupported(
                    "POP channel media must share one grid".into(),
                ));
            }
            sigma_s.push(
                m.sigma_t
                    .iter()
                    .zip(&m.albedo)
                    .map(|(t, a)| t * a)
                    .collect(),
            );
            sigma_a.push(
                m.sigma_t
                    .iter()
                    .zip(&m.albedo)
                    .map(|(t, a)| t * (1.0 - a))
                    .collect(),
            );
            if emits {
                emission.push(m.emission.clone());
            }
        }
        let out = Self {
            grid: first.grid,
            sigma_s,
            sigma_a,
            g: g.to_vec(),
            emission,
        };
        out.validate()?;
        Ok(out)
    }

    /// A homogeneous single-channel medium on `grid`.
    pub fn homogeneous(
        grid: Grid,
        sigma_s: f64,
        sigma_a: f64,
        g: f64,
    ) -> Result<Self, SolverError> {
        let out = Self {
            grid,
            sigma_s: vec![vec![sigma_s; grid.len()]],
            sigma_a: vec![vec![sigma_a; grid.len()]],
            g: vec![g],
            emission: Vec::new(),
        };
        out.validate()?;
        Ok(out)
    }

    /// Number of channels.
    pub fn channels(&self) -> usize {
        self.g.len()
    }

    /// Whether any voxel of any channel emits (j > 0).
    pub fn emits(&self) -> bool {
        self.emission.iter().flatten().any(|&j| j != 0.0)
    }

    /// The same medium with the uniform emission `j` in every voxel of every channel.
    pub fn with_uniform_emission(mut self, j: f64) -> Result<Self, SolverError> {
        self.emission = vec![vec![j; self.grid.len()]; self.channels()];
        self.validate()?;
        Ok(self)
    }

    /// Checks sizes and ranges: σs, σa finite ≥ 0; g ∈ [0, 1] (typed error for g < 0,
    /// which POP does not support: Eq 4 would alternate the sign of a).
    pub fn validate(&self) -> Result<(), SolverError> {
        if self.g.is_empty() {
            return Err(SolverError::BadParameter {
                name: "channels",
                value: 0.0,
                reason: "at least one channel is needed",
            });
        }
        for &g in &self.g {
            if !(0.0..=1.0).contains(&g) {
                return Err(SolverError::BadParameter {
                    name: "phase.g",
                    value: g,
                    reason: "POP supports g ∈ [0, 1] only (Sec 4: negative g is excluded; Eq 4 needs g ≥ 0)",
                });
            }
        }
        // No emission is an empty list; otherwise one field per channel.
        let emission = (!self.emission.is_empty()).then_some(("emission", &self.emission));
        for (field, set) in [("sigma_s", &self.sigma_s), ("sigma_a", &self.sigma_a)]
            .into_iter()
            .chain(emission)
        {
            if set.len() != self.g.len() {
                return Err(SolverError::FieldSize {
                    field,
                    expected: self.g.len(),
                    got: set.len(),
                });
            }
            for f in set {
                if f.len() != self.grid.len() {
                    return Err(SolverError::FieldSize {
                        field,
                        expected: self.grid.len(),
                        got: f.len(),
                    });
                }
                if let Some((index, &value)) = f
                    .iter()
                    .enumerate()
                    .find(|(_, v)| !(v.is_finite() && **v >= 0.0))
                {
                    return Err(SolverError::FieldValue {
                        field,
                        index,
                        value,
                        range: "[0, ∞) and finite",
                    });
                }
            }
        }
        Ok(())
    }
}

/// Settings of a POP solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PopConfig {
    /// Cells per axis of every propagation grid (N³, spec D3). Paper: 8–20.
    pub n: usize,
    /// Initialisation (D1).
    pub init: Init,
    /// Eq 8 lobe (D8); only used with an observer.
    pub eq8: Eq8,
    /// Lateral faces.
    pub lateral: Lateral,
    /// Observer of Eq 8; `None` accumulates no view-dependent radiance.
    pub observer: Option<Observer>,
    /// Stop when R^m/P_inj < tolerance in every channel (D9); 0 runs exactly
    /// `max_iterations` (the paper's fixed M) unless all light has left.
    pub tolerance: f64,
    /// Iteration cap M.
    pub max_iterations: usize,
    /// The isotropic residuum (Sec 5.4), default off; only [`residuum::solve`] honours it
    /// ([`solve`] refuses a config that asks for it).
    pub residuum: residuum::Residuum,
}

impl PopConfig {
    /// D1 init, phase-convolved Eq 8, open faces, no observer, the precision's default
    /// tolerance (10⁻⁶ f64, 10⁻⁴ f32, spec D9), at most 100 000 iterations.
    pub fn new<T: Real>(n: usize) -> Self {
        Self {
            n,
            init: Init::EntrySlice,
            eq8: Eq8::PhaseConvolved,
            lateral: Lateral::Open,
            observer: None,
            tolerance: T::DEFAULT_TOLERANCE,
            max_iterations: 100_000,
            residuum: residuum::Residuum::Off,
        }
    }

    /// The paper's fixed iteration count M (no convergence test).
    pub fn fixed<T: Real>(n: usize, m: usize) -> Self {
        Self {
            tolerance: 0.0,
            max_iterations: m,
            ..Self::new::<T>(n)
        }
    }

    /// Checks `n`, the tolerance and, for `ordinates` grids in precision `T` on `channels`
    /// channels, the memory budget ([`crate::budget`]).
    pub fn validate<T: Real>(&self, ordinates: usize, channels: usize) -> Result<(), SolverError> {
        if self.n < 2 {
            return Err(SolverError::BadParameter {
                name: "pop.n",
                value: self.n as f64,
                reason: "a propagation grid needs at least 2 cells per axis",
            });
        }
        if !(self.tolerance.is_finite() && self.tolerance >= 0.0) {
            return Err(SolverError::BadParameter {
                name: "pop.tolerance",
                value: self.tolerance,
                reason: "must be finite and ≥ 0",
            });
        }
        if let Some(Observer::Direction(w)) = self.observer {
            grid::normalise("pop.observer", w)?;
        }
        crate::budget::check(
            format!("POP: {ordinates} ordinate grids of n = {}", self.n),
            Self::bytes::<T>(self.n, ordinates, channels),
        )?;
        Ok(())
    }

    /// Upper bound of the bytes a solve holds: the working state of one grid per rayon
    /// thread and the accumulators of every ordinate.
    pub fn bytes<T: Real>(n: usize, ordinates: usize, channels: usize) -> u64 {
        let size = std::mem::size_of::<T>() as u64;
        let cells = crate::budget::bytes(&[n, n, n, channels], 1);
        let working = cells.saturating_mul(size * 15 + 16 + 8);
        let threads = (rayon::current_num_threads().min(ordinates.max(1))) as u64;
        let kept = cells.saturating_mul(size * cpu::ACC as u64);
        working
            .saturating_mul(threads)
            .saturating_add(kept.saturating_mul(ordinates as u64))
    }
}

/// What one ordinate's propagation produced.
#[derive(Debug, Clone)]
pub struct OrdinateRun<T> {
    /// The ordinate.
    pub ordinate: Ordinate,
    /// Its grid.
    pub grid: PropagationGrid,
    /// Channels.
    pub channels: usize,
    /// `[cell][channel][φ, J, L_acc]`: fluence Σ L^m, flux along d Σ L^m a^m, and the
    /// Eq 8 radiance (0 without observer).
    pub acc: Vec<T>,
    /// Where the power went, per channel.
    pub ledger: Vec<Ledger>,
    /// R^m/P_inj (max over channels) after the steps in `history_steps`: every step on
    /// the CPU, every checkpoint on the GPU ([`gpu`]).
    pub history: Vec<f64>,
    /// The step after which each `history` entry was taken (CPU: 1, 2, …; GPU: K, 2K, …
    /// and the last step).
    pub history_steps: Vec<usize>,
    /// Steps run.
    pub steps: usize,
    /// Why it stopped.
    pub stop: Stop,
}

impl<T: Real> OrdinateRun<T> {
    /// φ of channel `ch` at world point `p`: clamped trilinear in the rotated grid, 0
    /// outside it (spec D13's gather, on any target grid).
    pub fn fluence_at(&self, ch: usize, p: [f64; 3]) -> f64 {
        self.slot_at(ch, upsample::Slot::Fluence, p)
    }
}

/// All ordinates of a solve.
#[derive(Debug, Clone)]
pub struct PopSolution<T> {
    /// One run per ordinate, in the order given.
    pub runs: Vec<OrdinateRun<T>>,
}

impl<T: Real> PopSolution<T> {
    /// Fluence per channel on `target` (x fastest): Σ over ordinates of the trilinear gather
    /// of each φ at the voxel centres (spec D13 without the 2× merge and the JBU).
    pub fn fluence_on(&self, target: &Grid) -> Vec<Vec<f64>> {
        self.on_grid(target, upsample::Slot::Fluence)
    }
}

/// Propagates every ordinate through `medium` (rayon over ordinates and over the slices of
/// each grid; the result does not depend on the thread count). The GPU twin is
/// [`gpu::solve`]; [`method::PopMethod`] dispatches on the backend.
pub fn solve<T: Real>(
    medium: &PopMedium,
    ordinates: &[Ordinate],
    config: &PopConfig,
) -> Result<PopSolution<T>, SolverError> {
    validate_solve::<T>(medium, ordinates, config)?;
    let runs = ordinates
        .par_iter()
        .map(|o| run_ordinate::<T>(medium, o, config))
        .collect();
    Ok(PopSolution { runs })
}

/// The input checks of a solve (CPU and GPU alike).
pub(crate) fn validate_solve<T: Real>(
    medium: &PopMedium,
    ordinates: &[Ordinate],
    config: &PopConfig,
) -> Result<(), SolverError> {
    validate_inputs::<T>(medium, ordinates, config)?;
    // The residuum runs through `residuum::solve` only (CPU), never here or on the GPU.
    residuum::refuse(config)
}

/// The medium, the ordinates and the config (every POP solve, the residuum's included).
pub(crate) fn validate_inputs<T: Real>(
    medium: &PopMedium,
    ordinates: &[Ordinate],
    config: &PopConfig,
) -> Result<(), SolverError> {
    medium.validate()?;
    if ordinates.is_empty() {
        return Err(SolverError::BadParameter {
            name: "ordinates",
            value: 0.0,
            reason: "POP needs at least one ordinate (a light, or volume emission)",
        });
    }
    for o in ordinates {
        o.validate()?;
    }
    config.validate::<T>(ordinates.len(), medium.channels())
}

/// One ordinate's grid (D2–D3) and its state with the medium at the MIP level of D4,
/// injected (D1), not yet stepped.
pub(crate) fn prepare<T: Real>(
    medium: &PopMedium,
    ordinate: &Ordinate,
    config: &PopConfig,
) -> (PropagationGrid, CpuPop<T>) {
    let grid = PropagationGrid::over(&medium.grid, ordinate.direction, config.n);
    let mip = grid::box_filter(medium, grid::mip_level(&medium.grid, grid.dx));
    let mut pop = CpuPop::<T>::new(grid, &mip, &medium.g, config);
    pop.inject(ordinate, config.init);
    if ordinate.emission > 0.0 && medium.emits() {
        let j = grid::resample_emission(medium, &grid);
        pop.emit(&j, ordinate.emission, ordinate.anisotropy);
    }
    (grid, pop)
}

/// One ordinate: its grid (D2–D3), the medium at the MIP level of D4, init, iterations.
pub fn run_ordinate<T: Real>(
    medium: &PopMedium,
    ordinate: &Ordinate,
    config: &PopConfig,
) -> OrdinateRun<T> {
    let (grid, mut pop) = prepare::<T>(medium, ordinate, config);
    let stop = pop.run(config.tolerance, config.max_iterations);
    OrdinateRun {
        ordinate: *ordinate,
        grid,
        channels: medium.channels(),
        ledger: pop.ledger().to_vec(),
        history: pop.history().to_vec(),
        history_steps: (1..=pop.history().len()).collect(),
        steps: pop.steps(),
        stop,
        acc: pop.accumulators().to_vec(),
    }
}
