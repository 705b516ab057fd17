//! Light propagation maps (LPM): Fattal's maps with Gruson's propagate/collect split
//! (Gruson et al., *Light Propagation Maps on Parallel Graphics Architectures*, EGPGV 2012;
//! the spec is `../shared/specs/lpm.md`, cited as "spec §N", its decisions as Dk and its
//! tests as Tk).
//!
//! ## The paper's equations
//! * LPM Eq 1 (RTE): (ω·∇)L = Ka L_e − (Ka + Ks)L + (Ks/4π)∫_{S²} L(ω_i)ρ(ω, ω_i)dω_i.
//! * LPM Eq 2: I^d_xyz ≈ (V^d)⁻¹∫_C∫_{Ω^d}(Ks/4π)∫_{S²}Lρ dω′dω dp, V^d = Δ_V|Ω^d|.
//! * LPM Eq 3: L^{i,t} = L^{i,t−1}e^{−Δl(Ka+Ks)/ω_z} + U^{d,p}(1 − e^{−Δl(Ka+Ks)/ω_z})/(Ka + Ks).
//! * LPM Eq 4: R = (V^d)⁻¹A_{r,s}F^{i,d}L^{i,t}(1 − e^{−Δl Ks/ω_z}); I^d = R, U^d = R.
//! * LPM Eq 5: F^{i,d} = (1/4π)∫_{Ω^i}∫_{Ω^d}ρ(ω, ω′)dω dω′.
//! * LPM Eq 6: T^i_xyz += L^{i,t}(1 − e^{−Δl Ks/ω_z^i}).
//! * Alg 1 (Fattal) and Alg 2 (Gruson): orders p as Jacobi iterations over two U buffers;
//!   per LPM and direction the rays are marched through the grid (wrapping at the side
//!   faces, Fig 2), then the voxels collect T into U^{p_cur} and I.
//!
//! ## What this module computes (spec §1.6)
//! Per sub-segment of Euclidean length s in voxel v, with τ = σt s, E = e^{−τ},
//! φ1 = (1 − E)/τ, φ2 = (τ − 1 + E)/τ² ([`cpu::phis`]):
//! L_out = L_in E + U^{d(i)}_v s φ1 and T^i_v += s(L_in φ1 + U s φ2) (the exact ∫L ds), so
//! L_in − L_out + U s = σt·∫L ds to rounding (T5). The collect adds
//! σs_v A⊥_i F^{i,d′} T^i_v/(h³|Ω^{d′}|) to U^{d′,cur} and to I, with A⊥ = h²|ω_i·n_f|, and
//! Σ_i |Ω^i|A⊥T^i_v/h³ to the order's fluence φ^p (comparable with the path tracer's
//! track-length fluence). U⁰ = I⁰ = j/4π (emission coefficients, D9).
//!
//! * [`directions`]: the m×m gnomonic cells per face with exact solid angles (D10), the six
//!   storage cones (D7) and F of LPM Eq 5 by Gauss quadrature, Sinkhorn-renormalised (D8).
//! * [`geometry`]: per-(direction, slab) sub-segment tables in exact rational arithmetic.
//! * [`cpu::CpuLpm`]: rayon sweeps (one task per direction of the LPM, each owning its T of
//!   one slice and its ray state) and a per-voxel collect in a fixed order after each slice;
//!   generic over `f32`/`f64`.
//! * [`gpu::GpuLpm`]: the wgpu kernels (f32, `lpm.wgsl`): class-slotted T, no atomics,
//!   the same numbers as `CpuLpm<f32>` to 9.2·10⁻⁷ (section *GPU* below).
//! * [`method::LpmMethod`]: the registered method `lpm[:baked|:paper]` (CPU f32/f64; GPU
//!   except `lpm:paper`, whose deposit has no kernel).
//! * [`Formulas`]: the exact form (default) and the paper's literal formulas
//!   ([`Formulas::paper`]: deposit L(1 − e^{−Ks s}), face area, Δl/ω_z) for the furnace and
//!   balance tests that show their energy error.
//! * [`alg1::Alg1Lpm`]: Fattal's sequential form (LPM Alg 1: one thread, no T, deposits
//!   straight into U, I and φ), the T15 reference and the Fig 8 baseline (`lpm_speedup`).
//!
//! Experiments: `lpm_memory` (Fig 7, with and without streaming), `lpm_speedup` (Fig 8),
//! `lpm_cloud` (Figs 9/10 analogs against the path tracer), `lpm_accuracy` (T9–T12, the ray
//! effect, the collimated beam), and LPM's points in the `accuracy_cost` atlas at 1, 2, 3
//! orders and converged.
//!
//! Not here yet (a later session): streaming of the volume itself (σ, U, I stay resident:
//! only T is sliced, D19) and the paper's copy/compute overlap (Fig 5), Gauss–Seidel shooting
//! (D30; so T14 has nothing to test), sub-LPMs (D11), first-collision light baking inside LPM
//! (D13), the paper's deposit on the GPU, the fused pull kernel, and a float-atomic GPU
//! variant for Fig 8 (wgpu 30's WGSL has no f32 atomics on lavapipe, the only adapter here;
//! `lpm_speedup` reports it as not built), the GPU timings of acceptance 3 (no real GPU was
//! lent to this task).
//!
//! ## GPU (`gpu.rs`, `lpm.wgsl`; issue 16 build item 3, D17)
//! * **Kernels.** Per order and face: `sweep`, one thread per (direction k of the face, ray
//!   r), marches its ray through every slab with the CPU's tables (uploaded once; lengths
//!   pre-scaled by h and the path factor as the CPU scales them) and the CPU's f32 formulas
//!   ([`cpu::phis`], the same e^{−τ} polynomial with k = round(x log₂e); unfused, where the
//!   CPU fuses its multiply-adds, [`cpu::fmadd`]); then `collect`, one
//!   thread per voxel, sums the face's directions in the CPU's order into U^{cur}, I, φ^p and
//!   the voxel tallies; after the six faces `reduce` (one workgroup, fixed order) forms the
//!   order's tallies and evaluates the stopping rule (D1) on the GPU.
//! * **Race freedom (which thread writes which word).** Within slab z the sub-segment j of
//!   direction k maps the ray lattice onto the slab by a lateral shift, a bijection, so the
//!   word T[(k·slots + j)·n_v + v] (slots = the most sub-segments per slab, ≤ 3) has exactly
//!   one writer per sweep: the ray that sub-segment j of slab z puts into v. Ray tallies are
//!   one word per (direction, ray). `collect`'s thread v writes only voxel v's words of U,
//!   I, φ, φ^p and the tallies. Sweep, collect and reduce are separate dispatches. No word has
//!   two writers in one dispatch and nothing is atomic. The sum T_k(v) = Σ_j T[k, j, v] in j
//!   order from 0 is the CPU's `g += ∫L ds` in sub-segment order, so the GPU reproduces the
//!   CPU's summation order everywhere except the tallies (f32 tree on the GPU, f64 on the CPU).
//!   The paper's even/odd launches are not race-free (D17).
//! * **Orders and checkpoints.** Jacobi over two U buffers (two bind-group sets). The host
//!   records [`gpu::CHECK_EVERY`] = 8 orders per submission and reads back only the stats
//!   buffer then (order count, per-order tallies, and per-order φ when `keep_orders`). Once
//!   the stopping rule holds, every later kernel returns at once, so the state is exactly
//!   that after the stopping order. I, U and φ are read back once at the end. Every buffer is
//!   allocated once per [`GpuLpm`] (and reused by every solve), and each is checked against
//!   `max_storage_buffer_binding_size` and u32 indexing before allocation, with a typed error
//!   that names it (the unstreamed 128³, m = 5 T buffer, 25 · 3 · 128³ words, is refused on
//!   lavapipe's 128 MiB with `Streaming::Whole`, `t20_hard_inputs_on_gpu`).
//! * **Slice streaming on the GPU (D19).** tbuf holds the class-slotted T of one slice
//!   (m² · slots · S n_b n_c words); per (face, slice) one uniform and one bind-group pair,
//!   `sweep` runs the slice's slabs starting from the ray radiance and the raw ray tallies the
//!   previous slice left in `rayt` (the last sub-segment's offsets, needed for the wrap, are
//!   re-read from the table), and `collect` gathers the slice's voxels (one thread each).
//!   The arithmetic per ray and voxel is the unstreamed one in the same order, so streamed =
//!   unstreamed bitwise (T16 on the GPU, `t16_gpu_streamed_equals_unstreamed`: S = 1, 4, 16,
//!   20 on 20×13×18, open wrap and periodic + HG g = 0.6 + six I + stopping rule: max
//!   relative difference 0, every field and tally bitwise; streamed GPU vs CPU-f32 3.0·10⁻⁷).
//!   [`Streaming::Auto`] takes the largest S whose T fits one storage binding (and u32
//!   indexing, and the memory budget when one is set). The device bytes, measured as Σ
//!   `wgpu::Buffer::size()`, equal our device formula exactly at every S (same test); a
//!   budget halfway between the S = 1 (1.09 MB) and the unstreamed (2.37 MB) device bytes
//!   makes `Auto` pick S = 7 (1.73 MB ≤ the budget) with the unstreamed results, and a budget
//!   below S = 1 is a typed error.
//!   **128³, m = 5 on lavapipe** (measured 2026-12-03 by the test that is now the 64³ one
//!   below): Auto S = 27, T 132.7 MB ≤ the 134.2 MB binding (unstreamed 629 MB), 322 MB of
//!   device buffers, one order in 69 s wall (lavapipe on the shared 2 cores, under load),
//!   finite, positive, power imbalance 1.8·10⁻⁶. **64³, m = 5 under a 16 MiB binding**
//!   (`gpu_64_cubed_solves_with_streaming_under_a_16_mib_binding`, a device with the binding
//!   capped by `GpuContext::with_binding_limit`, so the streaming runs on any adapter; on
//!   lavapipe 2026-12-07): Auto S = 13, T 15.97 MB ≤ 16.78 MB (unstreamed 78.6 MB), 42.6 MB
//!   of device buffers, one order in 7.4 s, imbalance 7.8·10⁻⁶.
//! * **Measured on lavapipe** (llvmpipe, Mesa 22.3.6; `gpu_tests.rs`). T18: 12×10×14 white
//!   noise, environment + directional light, m = 5, 3 orders: GPU vs CPU-f32 max relative
//!   difference 3.2·10⁻⁷ over I, U, φ and φ^p where the CPU value is above 10⁻⁶ of its
//!   maximum, relative RMSE 5.8·10⁻⁸, tallies 5.2·10⁻⁷ of the input (bounds: the spec's 10⁻⁵
//!   and 10⁻⁶, 10⁻⁵ for the tallies). Five runs (four on reused buffers, one fresh) bitwise
//!   identical. T15 (GPU slotted ≡ CPU Alg 2, stop at rel 10⁻⁴): zero wrap m = 3 5.4·10⁻⁷
//!   (19 orders on both), periodic m = 4 5.8·10⁻⁷, the paper's area and Δl/ω_z 9.2·10⁻⁷ (60
//!   orders, cap), HG g = 0.7 with six I 3.5·10⁻⁷ (2.9, 2.3, 2.3·10⁻⁷ and bitwise equal
//!   before the CPU's f32 kernel fused its multiply-adds); the same order count and stop on
//!   both in every case. T7 on the GPU: furnace max |I/σsL − 1| = 6.7·10⁻⁷ (σt h = 0.01) and
//!   8.3·10⁻⁷ (0.1), g = 0 and 0.9 (bound 10⁻⁴). T20 on the GPU: vacuum, α ∈ {0, ½, 1},
//!   σt h up to 10³ on 7×5×9 finite and ≥ 0; α = 0 gives I = j/4π and U¹ = 0; vacuum
//!   fluence 4π to 1.2·10⁻⁷. The conformance suite (`tests/conformance.rs`) passes for
//!   `lpm` and `lpm:baked` on the GPU. The residual differences are the GPU compiler's
//!   rounding (division) and the CPU's fused multiply-adds (WGSL `fma()` at the places of
//!   [`cpu::fmadd`] would mirror them).
//!
//! ## Decisions where the paper is silent (each with its measurement and the test that
//! pins it, `tests.rs`)
//! * **D10 directions.** m×m cells per face, ray at the cell centre, exact solid angles: the
//!   150 cells of m = 5 sum to 4π within 1.8·10⁻¹⁵ and the set maps onto itself under the
//!   48 cube symmetries (directions and solid angles to 10⁻¹⁴; `t1_…`). m = 0 and m > 64 are
//!   typed errors naming `m` (`t20_…`).
//! * **D8 F normalisation.** Gauss–Legendre q×q per cell (default q = 6), then symmetric
//!   Sinkhorn scaling F ← c_iFc_j: rows and columns sum to |Ω^i| to 10⁻¹² and F stays
//!   symmetric (reciprocity) to 10⁻¹² (`t2_…`). See that test for the raw quadrature errors.
//! * **D5, D6 path and area.** s is the Euclidean sub-segment length and A⊥ = h²|ω·n_f|: per
//!   direction every voxel gets Σ A⊥ s = h³ exactly (T3, `t3_…`, every face, non-cubic
//!   grids); an oblique pure absorber leaves e^{−σt H/|ω_n|} per ray to 10⁻¹² (`t4_…`);
//!   the paper's Δl/ω_z fails it.
//! * **D4 deposit.** The exact ∫L ds deposit conserves each order to rounding: injected +
//!   emitted − exited − absorbed − scattered ≤ 2.0·10⁻¹⁵ (f64) and 2.1·10⁻⁸ (f32) of the
//!   input on a white-noise medium under an environment plus a directional light, for every
//!   wrap rule; the paper's deposit L_in(1 − e^{−Ks s}) loses 0.254 of it (`t6_…`, bounds
//!   10⁻¹⁰, 10⁻⁵). **Furnace** (acceptance 2, `t7_…`; 16³, α = 1, uniform L = 1, orders to
//!   ε = 10⁻⁹): the exact form gives I = σs L within 8.5·10⁻¹⁰ (f64) and 8.8·10⁻⁷ (f32) for
//!   σt h ∈ {0.01, 0.1} and g ∈ {0, 0.5, 0.9} (bounds 10⁻⁶, 10⁻⁴). Each paper formula alone
//!   fails it (max |I/σsL − 1| at σt h = 0.01 / 0.1): deposit 5.4·10⁻³ / 9.9·10⁻², face area
//!   0.25 / 0.70, Δl/ω_z 0.26 / 0.90, zero wrap 0.48 / 0.48, all four together 0.52 / 1.48.
//! * **T2 numbers.** Raw quadrature (q = 6) row sums off by 8.4·10⁻¹² (isotropic),
//!   1.1·10⁻¹⁰ (g = 0.5), 2.1·10⁻³ (g = 0.9), 1.3·10⁻¹¹ (g = −0.3); Sinkhorn needs 15–27
//!   sweeps. The spec's 10⁻¹⁴ for the raw isotropic sum is not reached at q = 6; the
//!   isotropic coarse F is set exactly to |Ω^i||Ω^{d′}|/4π (the renormalised limit).
//! * **Symmetry and precision.** A homogeneous cube with a centred emitter under uniform light
//!   is invariant under the 48 symmetries to 2.8·10⁻¹⁶ (`t8_…`); f32 vs f64 on a 32³ white
//!   noise medium, 3 orders: 2.2·10⁻⁷ (I) and 1.3·10⁻⁷ (φ) of the maximum (`t19_…`, spec
//!   64³; bound 10⁻⁴); 1 and 2 threads bit-identical (`t23_…`). A 12³ slab at α = 0.95 needs
//!   64 orders to ε = 10⁻⁶ (unshot ratio 0.808, settled to 4·10⁻¹⁰); ε and ε/10 differ by
//!   6.4·10⁻⁷ (`t13_…`).
//! * **Layout.** The x-faces sweep over copies of σt, σs and U in the layout
//!   y + n_y(z + n_z x), so every sweep's rows are contiguous. T is in the slice layout
//!   b + n_b(c + n_c(z − z0)) on every face (D19), so the x faces need no scratch T. Their
//!   collect writes U, I and φ^p in that layout too (I is transposed there before face 0;
//!   all go back after face 1, exactly), so T and the outputs run along memory together.
//! * **Speed** (bench `benches/lpm.rs`, 64³, RGB f32 as three channel solves, 3 orders,
//!   m = 5, 2 threads on a shared 2-core EPYC): 14.6 s (42.8 Mseg/s, 7.0·10⁷ sub-segments
//!   per order and channel = 265 n³) before the x-layout change and 21.1 s after it in a run
//!   whose triad probe read 16.7/57.0 GB/s against 110/40.8 GB/s for the first: the machine
//!   was loaded.
//! * **Vectorised sweep and collect** (issue 16 acceptance 3, first pass, SSE build; the
//!   kernel's numbers here are superseded by the next entry). `perf record` of the 32³
//!   bench: 54 % in the sweep's scalar loop (bounds checks on T reloaded after every libm
//!   call), 30 % in libm `expm1f`, 9 % in the collect. Now (a) a row of rays is four
//!   contiguous slices (ray, U, σt, T; the lateral stride is 1 in every layout) through
//!   `transport_row`, (b) [`cpu::phis`] is branch-free (series and direct form both
//!   evaluated, one selected) and in f32 uses [`cpu::exp_neg_f32`] (Cody–Waite reduction,
//!   degree-7 polynomial, 2^k from bits: 1.15 ulp measured, bound 2, test `exp_neg_f32_matches_f64`; E, φ1, φ2
//!   within 6.3·10⁻⁸, 1.6·10⁻⁷, 3.7·10⁻⁷ of f64, `phis_f32_matches_f64`), so the loop
//!   compiles to packed SIMD, (c) the collect runs
//!   direction-outer over each z-slice into six SoA accumulators, keeping the per-voxel
//!   summation order (bit-identical). f64 keeps libm `expm1` (its results are unchanged).
//!   Measured back to back (one 64³ RGB solve plus the shared setup, `perf stat`
//!   task-clock, i.e. CPU seconds, as wall time was useless at load 13–20 on 2 cores):
//!   old 9.09 / 9.86 CPU-s, new 4.39 / 4.48 CPU-s: 2.1× less work. All lpm tests (T1–T8,
//!   T13, T17, T19–T23) pass unchanged; T23 (1 vs 2 threads bit-identical) included. After
//!   the change the sweep is 70 % and the collect 14 % of the profile.
//! * **Fused kernel, full blocks, blocked collect** (issue 16 acceptance 3, second pass;
//!   the workspace now builds for x86-64-v3, 8 f32 lanes). Measured on the shared 2-vCPU
//!   Intel Xeon (AVX-512 capable, built for AVX2 + FMA; load average 4–8 from other
//!   sessions), one 64³ RGB f32 solve (m = 5, 3 orders, the bench's medium and light) plus
//!   its setup (0.15 CPU-s), `RAYON_NUM_THREADS=1`, `perf stat` task-clock, A/B back to back:
//!   **before 2.66 / 2.84 / 2.75 CPU-s, after 1.69 / 1.68 / 1.69 CPU-s** (solve alone ≈ 2.60
//!   → 1.54 CPU-s, 1.7× less work; 2.4 ns → 1.2 ns per sub-segment per core). Steps:
//!   (a) [`cpu::fmadd`]: the f32 kernel's multiply-adds fused (Horner chains half as long)
//!   and one series (φ2's; φ1 = 1 − τφ2, E = 1 − τφ1) instead of two: the kernel alone, on
//!   L1-resident 64-ray rows, 1.40 → 0.85 ns per sub-segment (one series without fusing:
//!   no change, the kernel was bound by its dependent chains, not by its op count; Estrin
//!   instead of Horner, a degree-6 exp, 7 series terms, no division: none faster by more
//!   than noise); whole solve 2.85 / 2.80 → 2.39 / 2.44 CPU-s. (b) `transport_row` in
//!   padded 8-ray blocks, no scalar epilogue: 2.87 → 2.51 CPU-s (A/B on top of (a); before
//!   (a) no measurable change). (c) The collect in 512-voxel blocks whose sums stay in L1:
//!   its profile share 0.51 → 0.42 CPU-s. (d) The x-faces' transpose back
//!   (`from_x_layout`) tiled: 12 % → 6 % of the profile. Results: f64 bit-identical
//!   (checked on the 32³ bench medium) and no slower (1.96 / 1.95 → 1.87 / 1.91 CPU-s for two
//!   32³ RGB solves); f32 moves by rounding only: 5.0·10⁻⁷ max relative (I and φ above
//!   10⁻⁶ of the maximum) against the unfused kernel; E, φ1, φ2 within 4.7·10⁻⁸, 1.6·10⁻⁷,
//!   3.4·10⁻⁷ of f64 (`phis_f32_matches_f64`), exp 0.86 ulp; T19 2.2·10⁻⁷, T7 f32 8.8·10⁻⁷,
//!   T6 f32 2.1·10⁻⁸, T18 GPU vs CPU 3.2·10⁻⁷, T15 ≤ 9.2·10⁻⁷; T23 bit-identical.
//!   **Profile after** (`perf record`, 1 thread, 64³ RGB incl. setup): sweep 46–50 %
//!   (about half of it the kernel's arithmetic, the rest stalls on the σt, U and T streams:
//!   3 MiB per direction, above the 2 MiB L2), collect 22 % (stalls reading the 25 T rows,
//!   25 MiB per face, from L3), memset 8 % (`g.fill` per direction in `solve` and the
//!   x-faces' zeroed scratch T in `sweep`), the transpose back 6 %, the bench's noise
//!   setup 4 %. What is left is memory traffic of the outer structure: sweeping several
//!   directions per pass over a slab (σt and U read once), collecting the x-faces from
//!   their own layout (no scratch T, no transpose, no fill) and skipping the fill of T
//!   buffers that are overwritten. **Roofline** (counted from the code; the VM exposes no
//!   cycle counters): ≈ 45 vector ops per 8 sub-segments after fusing, i.e. ≈ 2.8 cycles
//!   per sub-segment at 2 vector ops per cycle, ≈ 0.9 ns at 3 GHz: the measured 0.85 ns is
//!   at it, so of the 1.54 CPU-s of a 64³ RGB solve (6.3·10⁸ sub-segments) the kernel's
//!   arithmetic is ≈ 0.54 and the rest is memory traffic and the collect.
//! * **Third pass: rays by column, register-blocked collect, AVX-512 by detection, cache-sized
//!   slices** (issue 16 acceptance 3). Idle 2-vCPU Intel Xeon (2.6 GHz, 48 KiB L1d and
//!   2 MiB L2 per core, AVX-512 capable), 64³ and 128³ RGB f32, 3 orders, m = 5, the
//!   bench's medium and light, wall seconds of the three channel solves (best of 3–5 for
//!   64³, one for 128³), each step A/B on top of the previous one:
//!
//!   | step | 64³ | 128³ |
//!   |---|---|---|
//!   | after the streaming merge (`Whole`: the collect read the x faces' T with stride n_y n_z) | 1.49 (bench) | 23.4 (bench) |
//!   | (a) collect per z plane in runs contiguous in the slice layout | 1.08 | 13.6 |
//!   | (b) streaming S = 16 / 8 instead of `Whole` (T slice stays in cache) | 0.88 | 11.2 |
//!   | (c) sweep and collect compiled for AVX-512 too (16-lane blocks), runtime detection | 0.87 | – |
//!   | (d) rays stored by voxel column: a row is one slice, no split at the wrap | 0.70 | 9.26 |
//!   | (e) collect: the 7 sums of a block of 8/16 voxels in registers over the 25 directions, fused | 0.59 | 8.26 |
//!   | (f) x faces collect into outputs in their layout (contiguous writes) | 0.58 | 7.72 |
//!   | (g) x and z faces' collect in pieces of 4096 voxels, transposes and sums in parallel | 0.55 | 7.39 |
//!   | (h) isotropic F is rank one (w_{k,d′} = w_φ,k/4π): the collect sums once, not 7 times | 0.55 | 6.63 |
//!
//!   The bench after (h) (criterion means, same idle machine, two runs at triad 56/22 and
//!   50/43 GB/s at 64³, 24/24 and 26/23 GB/s at 128³): 64³ 0.651 and 0.597 s, 128³ 7.06
//!   and 6.89 s (before (h): 0.568 s and 7.71 s). Without AVX-512 (`wide` cleared, the
//!   8-lane code every x86-64-v3 CPU runs): 64³ 0.74 / 0.79 s, 128³ 10.75 / 9.18 s (before /
//!   after (h)): on an AVX2-only CPU of this class 128³ misses the 8 s target. (h) changes
//!   f32 results by rounding only (GPU vs CPU T15 ≤ 7.8·10⁻⁷, T18 4.4·10⁻⁷ max relative);
//!   the GPU collect takes the same shortcut (`Params.iso`), so the two stay together.
//!
//!   (c) alone gave 8 %: the 16-lane blocks were a quarter padding while a 64-ray row was
//!   split at the wrap in two runs; after (d) the wide kernel runs full blocks. The
//!   AVX-512 copies are `#[target_feature(enable = "avx512f")]` functions called after
//!   `is_x86_feature_detected!` (the workspace's one `unsafe`, allowed there only); each
//!   ray and voxel does the same IEEE operations in the same order in both widths, so
//!   results are bitwise equal (`wide_kernel_bitwise`, 23×13×18 with partial blocks,
//!   streamed, paper formulas, six I). Tried and dropped: one T allocation for the 25
//!   directions with a one-line skew between them (to put their streams on different L1
//!   sets): 0.55 → 0.65 s at 64³, slower; a skew of 0 in one allocation: 0.57 s, no gain.
//!   Streaming slices of S = 4 or fewer slabs: slower (0.97 s at 64³, S = 4, before (d)),
//!   the per-slice synchronisation. [`CPU_SLICE_BYTES`] sets `Auto` between.
//!   **Profile after (g)** (`perf record`, 128³, S = 5): sweep 41 %, collect 38 %, serial
//!   parts of `solve` 4 %, memset 4 % (T fills), the bench's noise setup 4 %. At 64³ the
//!   sweep runs 2.0·10⁹ sub-segments per second on 2 cores, at 128³ 1.35·10⁹: its rows of
//!   ray, U, σt and T (4 × 64 KiB at 128³) no longer fit L1 between a slab's sub-segments.
//! * **D12 wrap.** `Open` (default) re-enters rays through a side face with the boundary
//!   radiance at order 0 and 0 after; `Zero` is the paper's; `Periodic` carries the ray.
//! * **D1 stopping.** [`Orders::Converge`] continues while the unshot power
//!   Σ_vΣ_d U^d_v h³|Ω^d| exceeds `rel` × the power deposited at order 0 (capped);
//!   [`Orders::Fixed`] is Alg 2's fixed count (T13, `t13_…`).
//! * **D16 collect.** After each LPM (T holds the m² directions of one face).
//! * **D2 accumulate.** I and U^{cur} accumulate; I = U⁰ + Σ_p U^p (T22, `t22_…`).
//! * **Memory.** Every buffer is counted before allocation ([`memory_bytes_sliced`]); a grid
//!   beyond the budget is a typed [`SolverError::TooLarge`] naming the grid and the streaming
//!   (acceptance 5).
//! * **D19 slice streaming** (§4.2, Fig 5; [`Streaming`], issue 16 item 4). Per face the sweep
//!   axis is cut into slices of S slabs at full lateral extent; T (and the paper's deposit)
//!   holds one slice per direction of the LPM, each direction's rays (radiance, last
//!   sub-segment offsets, f64 tallies) are carried from slice to slice, and each slice is
//!   collected before the next is swept. The collect sums the directions k = 0, 1, … from
//!   zero per voxel as before, and the deposited and absorbed tallies are sums per (sweep
//!   step, chunk of the step's voxels), each over its voxels in slice order in 16 lanes
//!   fixed by position, folded in (step, chunk) order: the fields *and* the tallies do not
//!   depend on S, the thread count or the vector width. Only T is sliced; σ, U, I and φ stay
//!   resident (the paper also streams the volume to the device; not here). **T16**
//!   (`t16_streamed_equals_unstreamed`): 20×13×18 white noise, environment + directional
//!   light, S ∈ {1, 4, 16, 20} vs `Whole`, f32 and f64, open, zero and periodic wrap (the
//!   last with HG g = 0.6, six I and the stopping rule, 6 orders), the paper's formulas: I,
//!   U, φ, φ^p, orders and tallies bitwise equal. The existing tests print the numbers they
//!   printed before the change (T7, T15, T18), as the per-voxel order is unchanged. **T17**
//!   (`t17_streaming_memory_and_budget`): measured resident = formula exactly at S = 1, 3, 8,
//!   20 (f32, f64); a budget halfway between the S = 1 and the unstreamed totals (805 680 B
//!   f32 on 16×12×20) makes `Auto` pick S = 6 (total 789 680 B, S = 7 over it), bitwise equal
//!   to the unstreamed solve; a budget below S = 1 is refused naming "streaming = 1 slab(s)
//!   per slice", `Whole` beyond it naming "without streaming", `Slabs(0)` naming `streaming`.
//!   At 256³ (m = 5, f32, one channel, D_I = 1, 3 orders kept) our formula gives 3.30 GB
//!   unstreamed and 1.73 GB at S = 16, the paper's (U = I = 6, RGB) 8.878 GB, 3.845 GB
//!   without T and 0.573 GB streamed (spec §1.10).
//!   **Cost** (`lpm_memory`, one order, one channel, f32, m = 5, 2 threads, /proc CPU
//!   seconds at load 4.5–11 on the shared 2 cores): 64³ unstreamed 1.13, 1.11, 1.13, 1.12,
//!   1.16 vs S = 16 0.98, 0.98, 0.96, 0.99, 0.99 CPU-s (same processes, unstreamed first);
//!   128³ 8.57, 8.72 vs 6.86, 7.04. S = 1 was not timed. Streaming costs nothing here and is ~13 % cheaper: the slice's T (6.6 MB at 64³
//!   instead of 26 MB) stays in cache between the sweep and the collect, and the x faces
//!   lost their scratch T and transpose. The paper's streaming formula counts the volume
//!   per slice too; ours keeps it resident, so at S = 16 ours is 3.0× the paper's (1.59 GB
//!   vs 0.53 GB one channel at 256³, one order).
//!
//! **T9–T12 measured** (CPU f64, exact formulas, open wrap; tests in
//! `experiments/tests/lpm_accuracy.rs`, cases in `experiments::lpm_cases`, plots in the
//! `lpm_accuracy` experiment; `solvers` cannot depend on `reference`):
//! * **T9 order 1 under uniform light.** 16³ unit cube, σt h = 0.125, I = σs φ⁰/4π vs a
//!   face-by-face Gauss quadrature of σs/4π∫L e^{−σt ℓ}dω (4³ points per voxel, stable to
//!   4.4·10⁻⁵): relative L2 4.31·10⁻², 2.01·10⁻², 1.14·10⁻², 8.49·10⁻³ at m = 3, 5, 7, 9, fitted
//!   order 1.50 (1.18 between m = 7 and 9: one ray per cell and direction adds an
//!   m-independent spatial error). Asserted: falling, order ≥ 1.3, m = 9 ≤ 1.1·10⁻².
//! * **T10 slab vs adding–doubling.** τ = 1, normal beam. `WrapBc::Periodic` on a thin
//!   lateral grid does not model a laterally infinite slab: the x/y-face LPMs wrap through
//!   the z faces (light leaving the bottom re-enters the top) and start from zero at their
//!   own entry face; measured max(|ΔR|, |ΔT|) 1.54·10⁻² (α = 0.5) and 0.145 (α = 0.9) against
//!   8.4·10⁻⁴ and 2.3·10⁻³ with open side faces. So the grid is 8 mean free paths wide with
//!   open side faces (8 → 12 mfp changes R by 1.5·10⁻⁴), and R, T_d come from the central
//!   column's source I(z) through the exact exit integral 2π∫I E₂ dz (there is no per-face
//!   exit tally). α = 0.5, max(|ΔR|, |ΔT|): n_z = 8: 2.06·10⁻³, 6.1·10⁻⁴, 5.8·10⁻⁴, 4.5·10⁻⁴
//!   at m = 3, 5, 7, 9; m = 5: 8.4·10⁻⁴, 6.1·10⁻⁴, 5.0·10⁻⁴ at n_z = 4, 8, 16. At n_z = 4 the
//!   (negative) spatial error cancels part of the (positive) angular error and the m sweep is
//!   not monotone (2.15·10⁻³, 8.4·10⁻⁴, 1.24·10⁻³, 1.20·10⁻³). α = 0.9, m = 5: 2.3·10⁻³ (n_z
//!   = 4), 3.7·10⁻³ (n_z = 8; R 1.4 % high). Asserted (2×, α = 0.5): m = 3 ≤ 4·10⁻³, m ≥ 5
//!   ≤ 1.2·10⁻³, m = 9 ≤ 9·10⁻⁴, strictly falling in m at n_z = 8 and from n_z = 4 to 8; the
//!   periodic error > 3× the open one. The spec's n_z up to 128 is out of CI reach (the grid
//!   is 8 mfp wide in voxels of h).
//! * **T11 point source vs Case–Zweifel.** 33³, σt h = 0.6 (boundary 9.9 mfp away), m = 5,
//!   shells of voxel centres in [r, r + h), r = 3h … 9h, against the exact solution averaged
//!   over source and target voxels. Collided per shell −1.4 % … +7.5 % (α = 0.3) and
//!   −1.4 % … +7.0 % (α = 0.7), over [3h, 10h) +2.8 % / +2.5 %; uncollided per shell −17 % …
//!   +25 % (ray effect, CV 0.6–2.0 over a shell's voxels), over [3h, 10h) −3.5 %. The spec's
//!   2 % / 3 % are not met at this resolution. Asserted (≈ 1.3×): collided per shell ≤ 0.10,
//!   uncollided ≤ 0.35, range means ≤ 0.05 (uncollided) and 0.04 (collided).
//! * **T12 per order vs the path tracer.** 16³ `noise_cloud` (σt ≤ 20, α = 0.9), directional
//!   light along −z (the exact centre cell, no snapping), m = 5; the path tracer's order k =
//!   collided(max_depth k) − collided(max_depth k − 1) with common seeds, two seeds of 10⁶
//!   paths, noise from their difference. Debiased relative L2 / MC noise: order 0: 0 /
//!   1.2·10⁻² (exact exponential transport), order 1: 3.6·10⁻² / 2.5·10⁻², order 2:
//!   3.2·10⁻² / 3.3·10⁻², order 3: 3.2·10⁻² / 3.6·10⁻²; total fluence per order within
//!   −0.8 % … +1.3 %. Asserted: order 0 ≤ 5·10⁻³, orders 1–3 ≤ 6·10⁻², totals within 3 %.
//! * **Experiments** (`results/lpm_memory`, `results/lpm_accuracy`). Memory (m = 5, f32, one
//!   channel, one order): the resident bytes the solver reports equal [`memory_bytes_sliced`]'
//!   resident part exactly at 16³–128³, unstreamed and at S = 16 (128³: 379.0 MB unstreamed,
//!   total with the transient ray states 397.7 MB, process peak RSS 459 MB; S = 16 195.5 MB,
//!   total 214.2 MB; the paper's formula 329 MB, RGB 986 MB, streaming 42.5 MB). 256³ by the
//!   formula only: 3.16 GB unstreamed, 1.59 GB at S = 16 (T 105 MB). The full run took 34.7 s
//!   and 45.8 s wall (load 6 and 10), 17.8 and 18.1 CPU-s. Ray effect (spec §5 b, 33³, σt h = 0.01): on the shells r ∈ [13h, 16h) the
//!   fraction of voxels below 0.1× the exact uncollided fluence falls from 0.97 (m = 3) to
//!   0.85, 0.69–0.77, 0.58–0.68 (m = 5, 7, 9) and stays there at m = 11.

pub mod alg1;
pub mod cpu;
pub mod directions;
pub mod geometry;
pub mod gpu;
#[cfg(test)]
mod gpu_tests;
pub mod method;
#[cfg(test)]
mod tests;

pub use alg1::Alg1Lpm;
pub use cpu::CpuLpm;
pub use directions::{Directions, PhaseMatrix};
pub use gpu::GpuLpm;
pub use method::{LPM, LpmMethod};

use crate::method::Stop;
use crate::scene::Phase;
use crate::{Backend, Grid, Medium, Precision, Real, SolverError};

/// Which deposit of the scattered light (D3, D4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Deposit {
    /// σs∫L ds, exact along the sub-segment: conservative to rounding.
    #[default]
    TrackLength,
    /// LPM Eq 6 with the incoming radiance: L_in(1 − e^{−Ks s}).
    Paper,
}

/// The ray tube's cross-section in the collect (D6).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Area {
    /// A⊥ = h²|ω·n_f| (MOC's effective track spacing).
    #[default]
    Perpendicular,
    /// The paper's A_{r,s}, the face area h².
    Face,
}

/// The path length in LPM Eqs 3, 4, 6 (D5).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PathLength {
    /// The Euclidean sub-segment length.
    #[default]
    Euclidean,
    /// The paper's Δl/ω_z with Δl the Euclidean length (double-counts obliquity).
    Paper,
}

/// The formulas of the transport and the collect.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Formulas {
    /// The deposit.
    pub deposit: Deposit,
    /// The cross-section.
    pub area: Area,
    /// The path length.
    pub path: PathLength,
}

impl Formulas {
    /// The conservative form (default).
    pub fn exact() -> Self {
        Self::default()
    }

    /// The paper's literal formulas: deposit L(1 − e^{−Ks Δl/ω_z}), A = face area, Δl/ω_z.
    pub fn paper() -> Self {
        Self {
            deposit: Deposit::Paper,
            area: Area::Face,
            path: PathLength::Paper,
        }
    }

    /// The ray tube's cross-section A of a direction with |ω·n_f| = `cos_axis` on cells of
    /// edge `h`: A⊥ = h²|ω·n_f| (D6) or the paper's face area h².
    pub fn area(&self, h: f64, cos_axis: f64) -> f64 {
        match self.area {
            Area::Perpendicular => h * h * cos_axis,
            Area::Face => h * h,
        }
    }

    /// The factor on the Euclidean length of a direction with |ω·n_f| = `cos_axis`: 1 (D5)
    /// or the paper's 1/|ω_n|.
    pub fn path_factor(&self, cos_axis: f64) -> f64 {
        match self.path {
            PathLength::Euclidean => 1.0,
            PathLength::Paper => 1.0 / cos_axis,
        }
    }
}

/// The collect weights of direction `i` (LPM Eq 4): (A|Ω^i|/h³ for φ, A·F^{i,d′}/(h³|Ω^{d′}|)
/// per cone d′), with A of `formulas`; shared by Alg 2, Alg 1 and the GPU.
pub fn collect_weights(
    grid: &Grid,
    formulas: &Formulas,
    dirs: &Directions,
    phase: &PhaseMatrix,
    i: usize,
) -> (f64, [f64; directions::CONES]) {
    let d = &dirs.dirs[i];
    let area = formulas.area(grid.dl, d.cos_axis);
    let h3 = grid.dl.powi(3);
    let mut wu = [0.0; directions::CONES];
    for (q, w) in wu.iter_mut().enumerate() {
        *w = area * phase.coarse(i, q) / (h3 * directions::CONE_SOLID_ANGLE);
    }
    (area * d.solid_angle / h3, wu)
}

/// Sub-segments of one sweep of direction `dir` with geometry table `table` on `grid`: table
/// entries × rays of its face (Σ over the directions: the measured count of D20, 294 n³ for
/// m = 5).
pub fn sweep_segments(
    grid: &Grid,
    dir: &directions::Direction,
    table: &geometry::DirectionTable,
) -> u64 {
    let (b, c) = directions::lateral_axes(dir.face / 2);
    (table.segs.len() * grid.n[b] * grid.n[c]) as u64
}

/// What a ray that re-enters through a side face carries (D12).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum WrapBc {
    /// Zero radiance (the paper's text, Fig 2).
    Zero,
    /// The boundary radiance at order 0, zero after (default).
    #[default]
    Open,
    /// Its own radiance (an infinite periodic medium).
    Periodic,
}

/// How many I buffers (D15).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum StorageI {
    /// One isotropic I (the paper's choice for isotropic scattering).
    #[default]
    One,
    /// One per storage cone.
    Six,
}

/// How many scattering orders (D1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Orders {
    /// Exactly this many iterations (Alg 2's N_iterations), ≥ 1.
    Fixed(usize),
    /// Until the unshot power ≤ `rel` × that after order 0, at most `max_orders`.
    Converge {
        /// Relative level, > 0.
        rel: f64,
        /// Cap, ≥ 1.
        max_orders: usize,
    },
}

/// The T slice that [`Streaming::Auto`] aims at on the CPU, bytes: small enough that the
/// collect finds the slice the sweeps just wrote in cache (2 × 2 MiB of L2, and L3), large
/// enough that the per-slice synchronisation stays small. Measured, 64³ and 128³ RGB f32,
/// 3 orders, m = 5, idle 2-vCPU Xeon (2 MiB L2 per core): 64³ 0.649 s unstreamed, 0.581 s
/// at S = 16 (6.6 MB); 128³ 7.94 s at S = 16 (26 MB), 7.72 s at S = 8 (13 MB); S = 4 and
/// below slower again (synchronisation). 8 MiB gives S = 20 at 64³ and S = 5 at 128³.
pub const CPU_SLICE_BYTES: u64 = 8 << 20;

/// Slice streaming along the sweep axis (§4.2, Fig 5, D19): how many slabs of the sweep
/// axis one slice holds. T (∫L ds of the m² directions of one LPM) is allocated for one
/// slice only; every direction's ray state is carried from slice to slice, and each slice is
/// collected before the next is swept. The results do not depend on it (T16).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Streaming {
    /// No streaming: T spans the whole sweep axis.
    Whole,
    /// S slabs per slice (S ≥ 1; an axis shorter than S is one slice).
    Slabs(usize),
    /// On the CPU the largest S whose T slice fits [`CPU_SLICE_BYTES`] (so the collect
    /// reads T from cache) and whose total fits the memory budget; on the GPU the whole grid
    /// when it fits the budget and the storage-binding limit, else the largest S that does.
    /// Default.
    #[default]
    Auto,
}

/// The settings of an LPM solve.
#[derive(Debug, Clone, PartialEq)]
pub struct LpmConfig {
    /// Propagation cells per face edge (m = 5: 150 directions, the paper's 25 per face).
    pub m: usize,
    /// Phase function.
    pub phase: Phase,
    /// I buffers.
    pub storage_i: StorageI,
    /// Formulas.
    pub formulas: Formulas,
    /// Side-face re-entry.
    pub wrap: WrapBc,
    /// Orders.
    pub orders: Orders,
    /// Gauss points per cell axis for F (LPM Eq 5).
    pub quadrature: usize,
    /// Memory budget in bytes; `None`: [`crate::budget::available`].
    pub memory_budget: Option<u64>,
    /// Keep the fluence of every order ([`LpmSolution::phi_orders`]).
    pub keep_orders: bool,
    /// Slice streaming.
    pub streaming: Streaming,
}

impl Default for LpmConfig {
    /// m = 5, isotropic, one I, exact formulas, open wrap, 3 orders (the paper's benchmark).
    fn default() -> Self {
        Self {
            m: 5,
            phase: Phase::Isotropic,
            storage_i: StorageI::One,
            formulas: Formulas::exact(),
            wrap: WrapBc::Open,
            orders: Orders::Fixed(3),
            quadrature: 6,
            memory_budget: None,
            keep_orders: true,
            streaming: Streaming::Auto,
        }
    }
}

impl LpmConfig {
    /// Checks every field; errors name the parameter.
    pub fn validate(&self) -> Result<(), SolverError> {
        directions::Directions::new(self.m).map(|_| ())?;
        self.phase.validate()?;
        if self.streaming == Streaming::Slabs(0) {
            return Err(SolverError::BadParameter {
                name: "streaming",
                value: 0.0,
                reason: "a slice needs at least 1 slab",
            });
        }
        match self.orders {
            Orders::Fixed(0) => Err(SolverError::BadParameter {
                name: "orders",
                value: 0.0,
                reason: "0 orders with no stopping rule: give ≥ 1 or a relative stopping level",
            }),
            Orders::Converge { rel, max_orders } => {
                if !(rel.is_finite() && rel > 0.0) {
                    return Err(SolverError::BadParameter {
                        name: "rel",
                        value: rel,
                        reason: "the relative stopping level must be finite and > 0",
                    });
                }
                if max_orders == 0 {
                    return Err(SolverError::BadParameter {
                        name: "max_orders",
                        value: 0.0,
                        reason: "the order cap must be ≥ 1",
                    });
                }
                Ok(())
            }
            Orders::Fixed(_) => Ok(()),
        }
    }

    /// The most orders a solve may run.
    pub fn max_orders(&self) -> usize {
        match self.orders {
            Orders::Fixed(k) => k,
            Orders::Converge { max_orders, .. } => max_orders,
        }
    }

    /// Refuses `needed` bytes on `grid` above the budget (an unstreamed solve, for the
    /// message).
    pub fn check_budget(&self, grid: &Grid, needed: u64) -> Result<(), SolverError> {
        self.check_budget_sliced(grid, needed, usize::MAX)
    }

    /// [`Self::check_budget`] for a solve with `slabs` slabs per slice (≥ the longest axis:
    /// without streaming); the message names the grid and the streaming.
    pub fn check_budget_sliced(
        &self,
        grid: &Grid,
        needed: u64,
        slabs: usize,
    ) -> Result<(), SolverError> {
        let n_max = grid.n.iter().copied().max().unwrap_or(1);
        let how = if slabs >= n_max {
            "without streaming".to_string()
        } else {
            format!("streaming = {slabs} slab(s) per slice")
        };
        let what = format!(
            "LPM grid {}x{}x{} (m = {}, {how})",
            grid.n[0], grid.n[1], grid.n[2], self.m
        );
        let (available, origin) = self.budget();
        if needed > available {
            return Err(crate::budget::TooLarge {
                what,
                needed,
                available,
                origin,
            }
            .into());
        }
        Ok(())
    }

    /// The memory budget in bytes and where it comes from.
    pub fn budget(&self) -> (u64, &'static str) {
        match self.memory_budget {
            Some(b) => (b, "memory_budget of the LPM settings"),
            None => crate::budget::available(),
        }
    }

    /// The slabs per slice of a solve on `grid` with `word` bytes per value (CPU): the longest
    /// axis for [`Streaming::Whole`], S for [`Streaming::Slabs`], and for
    /// [`Streaming::Auto`] the largest S whose T slice fits [`CPU_SLICE_BYTES`] and whose
    /// [`memory_bytes_sliced`] total fits the budget; a typed error naming the grid and the
    /// streaming when nothing fits (S = 1 for `Auto`).
    pub fn slabs(&self, grid: &Grid, word: u64) -> Result<usize, SolverError> {
        let n_max = grid.n.iter().copied().max().unwrap_or(1);
        let need = |s: usize| memory_bytes_sliced(grid, self, word, s).total();
        let s = match self.streaming {
            Streaming::Whole => n_max,
            Streaming::Slabs(s) => s.clamp(1, n_max),
            Streaming::Auto => {
                let (available, _) = self.budget();
                let t = |s: usize| memory_bytes_sliced(grid, self, word, s).t;
                let cached = (1..=n_max)
                    .take_while(|&s| s == 1 || t(s) <= CPU_SLICE_BYTES)
                    .last()
                    .unwrap_or(1);
                if need(cached) <= available {
                    cached
                } else {
                    // The total grows with S: bisect for the largest S that fits.
                    let (mut lo, mut hi) = (1usize, n_max);
                    while lo < hi {
                        let mid = (lo + hi).div_ceil(2);
                        if need(mid) <= available {
                            lo = mid;
                        } else {
                            hi = mid - 1;
                        }
                    }
                    lo
                }
            }
        };
        self.check_budget_sliced(grid, need(s), s)?;
        Ok(s)
    }
}

/// Boundary radiance per propagation direction (direction of travel), cell averages (D13).
#[derive(Debug, Clone, PartialEq)]
pub struct BoundaryLight {
    /// L_bc(ω_i), one per direction.
    pub radiance: Vec<f64>,
}

impl BoundaryLight {
    /// No light from outside.
    pub fn none(dirs: &Directions) -> Self {
        Self {
            radiance: vec![0.0; dirs.len()],
        }
    }

    /// A uniform environment of radiance `l`.
    pub fn uniform(dirs: &Directions, l: f64) -> Self {
        Self {
            radiance: vec![l; dirs.len()],
        }
    }

    /// A directional light of `irradiance` travelling along `direction`, snapped to the
    /// cell that contains it: L = E/|Ω^i| there (D13, `Boundary` injection).
    pub fn directional(
        dirs: &Directions,
        direction: [f64; 3],
        irradiance: f64,
    ) -> Result<Self, SolverError> {
        let n = (direction[0].powi(2) + direction[1].powi(2) + direction[2].powi(2)).sqrt();
        if !(n.is_finite() && n > 0.0) {
            return Err(SolverError::BadParameter {
                name: "direction",
                value: n,
                reason: "a directional light needs a finite non-zero direction",
            });
        }
        if !(irradiance.is_finite() && irradiance >= 0.0) {
            return Err(SolverError::BadParameter {
                name: "irradiance",
                value: irradiance,
                reason: "must be finite and ≥ 0",
            });
        }
        let w = [direction[0] / n, direction[1] / n, direction[2] / n];
        let i = dirs.containing(w);
        let mut radiance = vec![0.0; dirs.len()];
        radiance[i] = irradiance / dirs.dirs[i].solid_angle;
        Ok(Self { radiance })
    }
}

impl BoundaryLight {
    /// A typed error unless there is one radiance per direction of `dirs`.
    pub fn check(&self, dirs: &Directions) -> Result<(), SolverError> {
        if self.radiance.len() != dirs.len() {
            return Err(SolverError::FieldSize {
                field: "boundary radiance",
                expected: dirs.len(),
                got: self.radiance.len(),
            });
        }
        Ok(())
    }
}

/// The order loop's bookkeeping (D1), one for every solver form (Alg 1, Alg 2): the tallies
/// so far, the unshot power after order 0 and the stopping rule of [`Orders`].
#[derive(Debug)]
pub(crate) struct OrderLoop {
    /// Most orders to run.
    pub(crate) max_orders: usize,
    rel: Option<f64>,
    first_unshot: f64,
    /// One tally per order run.
    pub(crate) tallies: Vec<OrderTally>,
    /// Why the loop stopped (`Cap` until a rule fires).
    pub(crate) stop: Stop,
}

impl OrderLoop {
    /// The loop of `orders`.
    pub(crate) fn new(orders: Orders) -> Self {
        let (max_orders, rel) = match orders {
            Orders::Fixed(k) => (k, None),
            Orders::Converge { rel, max_orders } => (max_orders, Some(rel)),
        };
        Self {
            max_orders,
            rel,
            first_unshot: f64::NAN,
            tallies: Vec::new(),
            stop: Stop::Cap,
        }
    }

    /// Records order `order`'s tally (its unshot power is what it scattered), shows the
    /// observer unshot / unshot after order 0, and returns whether to stop now: a non-finite
    /// tally, or the relative rule met.
    pub(crate) fn finish(
        &mut self,
        order: usize,
        mut tally: OrderTally,
        observer: &mut impl FnMut(usize, f64),
    ) -> bool {
        tally.unshot = tally.scattered;
        let finite = [tally.injected, tally.exited, tally.emitted, tally.scattered]
            .iter()
            .all(|x| x.is_finite());
        self.tallies.push(tally);
        if order == 0 {
            self.first_unshot = tally.unshot;
        }
        observer(order, tally.unshot / self.first_unshot);
        if !finite {
            self.stop = Stop::NonFinite;
            return true;
        }
        if let Some(rel) = self.rel {
            if tally.unshot <= rel * self.first_unshot || tally.unshot.is_nan() {
                self.stop = Stop::Converged;
                return true;
            }
        }
        false
    }
}

/// Bytes of the geometry tables as allocated (Σ capacities).
pub(crate) fn table_bytes(tables: &[geometry::DirectionTable]) -> u64 {
    tables
        .iter()
        .map(|t| {
            t.segs.capacity() * std::mem::size_of::<geometry::Seg>()
                + t.start.capacity() * std::mem::size_of::<usize>()
        })
        .sum::<usize>() as u64
}

/// Power balance of one order (spec T6), in power units (radiance × area × solid angle).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct OrderTally {
    /// Boundary light entering (entry faces and side re-entries).
    pub injected: f64,
    /// Emitted by the unshot U of this order (Σ U s A|Ω|).
    pub emitted: f64,
    /// Leaving through far and side faces.
    pub exited: f64,
    /// Absorbed, Σ σa φ h³.
    pub absorbed: f64,
    /// Deposited into U^{cur} (the next order's source power).
    pub scattered: f64,
    /// Unshot power after the order (= `scattered`).
    pub unshot: f64,
}

impl OrderTally {
    /// (injected + emitted − exited − absorbed − scattered)/(injected + emitted).
    pub fn imbalance(&self) -> f64 {
        (self.injected + self.emitted - self.exited - self.absorbed - self.scattered)
            / (self.injected + self.emitted)
    }
}

/// Bytes of a solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Memory {
    /// Our per-buffer formula ([`memory_bytes_sliced`] at the solve's slabs per slice).
    pub formula: MemoryBytes,
    /// Bytes of the resident buffers as allocated (Σ capacities; on the GPU Σ buffer sizes).
    pub resident_measured: u64,
    /// Slabs per slice of the solve (≥ the longest axis: not streamed).
    pub slabs: usize,
}

/// Our explicit per-buffer byte count (D18, D19).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MemoryBytes {
    /// σt, σs and the source j/4π, and σt, σs again in the x-faces' layout.
    pub medium: u64,
    /// Two U buffer sets of 6 cones.
    pub u: u64,
    /// I (1 or 6).
    pub i: u64,
    /// T (∫L ds) of the m² directions of one LPM over one slice (S slabs of the sweep axis at
    /// full lateral extent, the largest over the three axes), and the paper's deposit buffer
    /// if used.
    pub t: u64,
    /// Total φ and the kept per-order fluences (at the order cap).
    pub fluence: u64,
    /// Geometry tables (on the GPU also the direction table and the uniforms).
    pub tables: u64,
    /// GPU only (0 on the CPU): the voxel and ray tallies, the ray radiances carried between
    /// slices and the stats buffer (with the per-order fluence ring).
    pub tallies: u64,
    /// Transient: ray states (m² of the largest face, one per direction, carried from slice
    /// to slice), the x-faces' transposed U, the order's fluence when it is not kept, and
    /// the collect's per-row tallies (two f64 per row of x).
    pub rays: u64,
}

impl MemoryBytes {
    /// Everything.
    pub fn total(&self) -> u64 {
        self.medium
            + self.u
            + self.i
            + self.t
            + self.fluence
            + self.tables
            + self.tallies
            + self.rays
    }

    /// The resident part (without the transient ray states).
    pub fn resident(&self) -> u64 {
        self.total() - self.rays
    }
}

/// Our per-buffer formula for `grid`, `config` and `word` bytes per value at the slabs per
/// slice that `config.streaming` resolves to ([`LpmConfig::slabs`]; S = 1 where nothing fits).
pub fn memory_bytes(grid: &Grid, config: &LpmConfig, word: u64) -> MemoryBytes {
    let s = config.slabs(grid, word).unwrap_or(match config.streaming {
        Streaming::Slabs(s) => s.max(1),
        Streaming::Whole => usize::MAX,
        Streaming::Auto => 1,
    });
    memory_bytes_sliced(grid, config, word, s)
}

/// Voxels of the largest slice of `slabs` slabs along any sweep axis: max_a min(S, n_a)·n_b·n_c.
pub fn slice_voxels(grid: &Grid, slabs: usize) -> u64 {
    let n = grid.n;
    (0..3)
        .map(|a| {
            let (b, c) = directions::lateral_axes(a);
            (slabs.min(n[a]) * n[b] * n[c]) as u64
        })
        .max()
        .unwrap_or(0)
}

/// Our per-buffer formula with `slabs` slabs per slice (≥ the longest axis: unstreamed).
pub fn memory_bytes_sliced(
    grid: &Grid,
    config: &LpmConfig,
    word: u64,
    slabs: usize,
) -> MemoryBytes {
    let nv = grid.len() as u64;
    let m = config.m.min(directions::MAX_M) as u64;
    let per = m * m;
    let paper = config.formulas.deposit == Deposit::Paper;
    let kept = if config.keep_orders {
        config.max_orders() as u64
    } else {
        0
    };
    let n = grid.n;
    let table_slabs: u64 = (0..6).map(|f| n[f / 2] as u64).sum::<u64>() * per;
    let seg = std::mem::size_of::<geometry::Seg>() as u64;
    let usz = std::mem::size_of::<usize>() as u64;
    let lateral = (0..3)
        .map(|a| {
            let (b, c) = directions::lateral_axes(a);
            (n[b] * n[c]) as u64
        })
        .max()
        .unwrap_or(0);
    let sat = |x: u64, y: u64| x.saturating_mul(y);
    let slice = slice_voxels(grid, slabs.max(1));
    let rows = (n[1] * n[2]) as u64;
    MemoryBytes {
        medium: sat(5 * nv, word),
        u: sat(2 * 6 * nv, word),
        i: sat(config.storage_i.count() as u64 * nv, word),
        t: sat(sat(per * if paper { 2 } else { 1 }, slice), word),
        fluence: sat(sat(1 + kept, nv), word),
        // Table capacities: ≤ 3 sub-segments per slab, slabs + 1 starts per direction.
        tables: table_slabs * 3 * seg + (table_slabs + 6 * per) * usz,
        tallies: 0,
        rays: sat(sat(per, lateral) + 2 * nv, word) + 16 * rows,
    }
}

/// The paper's memory formula without streaming (§5), bytes:
/// 4·nbSpect·((1 + 2U + I)n³ + p n² + p n³).
pub fn paper_memory_bytes(n: u64, u: u64, i: u64, p: u64, spectra: u64) -> u64 {
    4 * spectra * ((1 + 2 * u + i) * n * n * n + p * n * n + p * n * n * n)
}

/// The paper's memory formula with streaming (§5), bytes, slice width `s` slabs:
/// 4·nbSpect·((1 + 2U + I)S n² + S p n² + p n²).
pub fn paper_streaming_memory_bytes(n: u64, u: u64, i: u64, p: u64, s: u64, spectra: u64) -> u64 {
    4 * spectra * ((1 + 2 * u + i) * s * n * n + s * p * n * n + p * n * n)
}

/// The result of an LPM solve.
#[derive(Debug, Clone)]
pub struct LpmSolution<T> {
    /// The grid.
    pub grid: Grid,
    /// I per storage direction (1 or 6 buffers), emission coefficients (W m⁻³ sr⁻¹).
    pub intensity: Vec<Vec<T>>,
    /// The unshot U^{d} after the last order (6 buffers).
    pub unshot: Vec<Vec<T>>,
    /// Total fluence Σ_p φ^p.
    pub phi: Vec<T>,
    /// Fluence of each order's rays (boundary light and U^p), if kept.
    pub phi_orders: Vec<Vec<T>>,
    /// Orders run.
    pub orders: usize,
    /// Power balance per order.
    pub tallies: Vec<OrderTally>,
    /// Why it stopped (`Cap` for a fixed count).
    pub stop: Stop,
    /// Wall-clock seconds of the orders.
    pub seconds: f64,
    /// Bytes.
    pub memory: Memory,
}

impl<T: Real> LpmSolution<T> {
    /// The isotropic average of I per voxel (I itself when D_I = 1).
    pub fn mean_intensity(&self) -> Vec<f64> {
        let k = self.intensity.len() as f64;
        (0..self.grid.len())
            .map(|v| self.intensity.iter().map(|b| b[v].f()).sum::<f64>() / k)
            .collect()
    }
}

/// Solves on the backend (CPU in its precision, or the GPU in f32); fields come back in f64.
pub fn solve(
    backend: &Backend<'_>,
    medium: &Medium<f64>,
    boundary: &BoundaryLight,
    config: &LpmConfig,
    observer: impl FnMut(usize, f64),
) -> Result<LpmSolution<f64>, SolverError> {
    match backend {
        Backend::Cpu(Precision::F64) => Ok(widen(
            CpuLpm::<f64>::new(&medium.cast(), config)?.solve(boundary, observer)?,
        )),
        Backend::Cpu(Precision::F32) => Ok(widen(
            CpuLpm::<f32>::new(&medium.cast(), config)?.solve(boundary, observer)?,
        )),
        Backend::Gpu(ctx) => Ok(widen(
            GpuLpm::new(ctx, medium, config)?.solve(boundary, observer)?,
        )),
    }
}

/// A solution with its fields in f64.
pub fn widen<T: Real>(s: LpmSolution<T>) -> LpmSolution<f64> {
    let w = |v: Vec<T>| v.into_iter().map(|x| x.f()).collect::<Vec<f64>>();
    LpmSolution {
        grid: s.grid,
        intensity: s.intensity.into_iter().map(w).collect(),
        unshot: s.unshot.into_iter().map(w).collect(),
        phi: w(s.phi),
        phi_orders: s.phi_orders.into_iter().map(w).collect(),
        orders: s.orders,
        tallies: s.tallies,
        stop: s.stop,
        seconds: s.seconds,
        memory: s.memory,
    }
}
