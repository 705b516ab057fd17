//! Classical (CDA) and flux-limited diffusion (FLD) for the multiply-scattered fluence φ.
//!
//! Solves the flux-limited diffusion equation (FLD Eq 20)
//! ∇·(D ∇φ) = σa φ − j,  D = F(R)/σt,  R = |∇φ|/(σt φ)
//! on a voxel grid with the red-black Gauss-Seidel SOR scheme of FLD Algorithm 1
//! (Eqs 30–37). CDA is the same solver with the constant limiter F = 1/3 (FLD Section 6.1).
//!
//! * [`FluxLimiter`]: F(R) for CDA and the five limiters of FLD Table 2.
//! * [`FldConfig`]: SOR factor, tolerance, floors σ_ε and ε, stopping rule.
//! * [`Boundary`]: zero Dirichlet (the paper's) or Dirichlet values from a function.
//! * [`cpu::CpuFld`]: the rayon kernel, generic over `f32`/`f64`.
//! * [`gpu::GpuFld`]: the wgpu kernel (f32, `fld.wgsl`), same layout and arithmetic.
//! * [`multigrid::CpuMultigrid`], [`multigrid::GpuMultigrid`]: nonlinear FAS multigrid with
//!   Algorithm 1's sweep as smoother, on the CPU and on the GPU (`multigrid.wgsl` for the
//!   transfers; method names `cda:mg`, `fld:<limiter>:mg`; see [`multigrid`]).
//! * [`Solver`]: which of the two runs; [`Solver::Auto`] (variant `:auto`) picks multigrid
//!   where it was measured faster and falls back to SOR where it does not converge.
//! * `limiter.wgsl`: the limiters in WGSL, prepended to `fld.wgsl` and `multigrid.wgsl`.
//!
//! ## Decisions where the paper is silent (each is tested in `cpu.rs`)
//! * **Boundary layer.** The outermost voxel layer holds the Dirichlet values and is never
//!   updated (FLD Section 5). Its diffusion coefficient is *updated* like the interior's
//!   (one-sided ∇φ at the faces) instead of staying at its initial εΔl: otherwise the face
//!   coefficient D_ps to the boundary would be half the interior value and a Dirichlet
//!   boundary would enter with the wrong weight. The analytic-boundary test (CDA vs FLD Eq 27
//!   within 1 %) depends on this.
//! * **Residual.** FLD Eq 37 is evaluated with the value of φ_p *before* its update, i.e. it
//!   is the residual of the iterate the sweep sees. Evaluated after the update it would be
//!   identically zero for ω = 1, so that cannot be the intended order. The RMS over
//!   interior voxels further than [`FldConfig::residual_margin`] voxels from the boundary
//!   layer, divided by j̄, is the stopping criterion.
//! * **Residual window: every interior voxel (margin 0; changed from 1, issue 12 item 4).**
//!   FLD Section 5 ignores "voxels close to the boundary"; with a margin of 1 the window left
//!   out the medium's surface layer of the pipeline's padded grids, which is where an
//!   optically thick medium lit from outside has all its source, so the first sweeps looked
//!   converged: at the default R̄/j̄ < 10⁻⁴ on issue 12's albedo-1 cubes (16³, directional
//!   light, downsample 1) CDA stopped 1.4 % (σt·Δl = 6, 16 iterations) and 84 % (60, 1
//!   iteration) and FLD-LP 100 % (60, 1 iteration) from a tight solve (R̄/j̄ < 10⁻¹⁰). With
//!   margin 0 every SOR method (CDA and the five limiters, f32 and f64) stops within
//!   6.5·10⁻⁵ of the tight solve on those cubes and, on the atlas's four datasets
//!   (downsample 4), within 2.5·10⁻⁵ in f64 and 5·10⁻⁴ in f32 (shell_core, where `fld:max`
//!   reaches the 20 000 cap; `experiments convergence_check`, `results/convergence_check`).
//!   Their tight solves are within 10⁻¹⁰ of a second solve at R̄/j̄ < 10⁻¹², i.e. converged.
//!   Pinned by
//!   `solvers/tests/default_stop.rs`, which fails with margin 1. Not fixed by this rule alone:
//!   multigrid (`cda:mg` stopped after 1–2 cycles 4.7–26 % from its own fixed point on those
//!   cubes) and the steady RDE (45–49 % on the cubes at σt·Δl = 6 and 60), whose residuals
//!   bound the error poorly when σa = 0. Both now also require a change-based error estimate,
//!   ‖Δφ‖/‖φ‖/(1 − ρ̂) < rel ([`multigrid`]; `rde::method`): multigrid is within 3.1·10⁻⁵ of
//!   its tight solve wherever it converges (cubes 3.7·10⁻⁶ … 2.6·10⁻⁵) and reports
//!   `stalled` elsewhere (`cda:mg` on nebula, emissive_cloud, shell_core; `fld:*:mg` on
//!   shell_core), the RDE within 4.9·10⁻⁵ except shell_core, where it reaches the step cap
//!   (`results/convergence_check`; the default_stop tests pin both).
//! * **Projection.** An over-relaxed update (ω > 1) that would make φ negative is set to 0
//!   (projected SOR). The exact solution is non-negative, so the fixed point is unchanged;
//!   NaN is *not* masked by this projection.
//! * **Under-relaxed D update.** Algorithm 1 replaces D_p by F(R)/σ every pass. With
//!   over-relaxation (ω > 1) that nonlinear iteration can oscillate forever: on our Fig 4
//!   cloud it converges for ω ≤ 1.8 but not at 1.9, and on white-noise media with 10⁴
//!   voxel-to-voxel contrast for no ω > 1 (measured; see `experiments convergence`). We
//!   therefore blend D_p ← θ·F(R)/σ + (1 − θ)·D_p with θ = [`FldConfig::d_relaxation`],
//!   default 0.5, which has the same fixed point and converges in those cases; θ = 1 is the
//!   paper's update verbatim. CDA is linear and unaffected.
//! * **Known limitation (measured, not fixed):** on white-noise media that are 95 % vacuum,
//!   FLD's iteration stalls at R̄/j̄ ≈ 0.1 for every limiter, in f64 as in f32, while staying
//!   finite and non-negative. In vacuum D → φ/|∇φ| and the equation turns hyperbolic;
//!   Gauss-Seidel then settles into a cycle. Media with connected vacuum (the Fig 4 cloud)
//!   converge.
//! * **Energy balance (measured, `solvers/tests/energy_balance.rs`).** An emissive albedo-1
//!   cube inside the vacuum Dirichlet layer (the pipeline's padding): the net discrete flux
//!   Σ D_pb (φ_p − φ_b) Δl through the faces to the boundary layer equals ∫ j dV to 10⁻⁸ in
//!   f64 (R̄/j̄ < 10⁻⁸) and to 2.6·10⁻⁵ in f32 (its default 10⁻⁴) for CDA and every limiter at
//!   σt·Δl ∈ {0.01, 1, 100}. The solver is conservative and not under-converged there.
//! * **The medium–vacuum face (the paper's method, documented, not changed).** The face
//!   coefficient to a vacuum voxel is the paper's (D_p + D_s)/2 with D_s from the floors of
//!   FLD Eqs 33/35: CDA's vacuum D = 1/(3σ_ε) = L/(3·10⁻³) pins the surface voxel to φ ≈ 0
//!   (4·10⁻⁶ of the Marshak vacuum value at σt·Δl = 100), FLD's vacuum D ≈ φ/|∇φ| → 0 leaves
//!   D_p/2 on the face and the surface voxel at ≈ 4× the Marshak value at σt·Δl = 100, growing
//!   like σt·Δl. The outflow is right either way, but the raymarch sees φ within a mean free
//!   path of the surface, which is why the pipeline's emissive albedo-1 images are far too dark
//!   (CDA) and too bright, growing with σt (FLD) (issue 12's table). Pinned by
//!   `the_vacuum_face_coefficient_sets_the_surface_fluence`.
//! * **The Marshak vacuum face (variant `:marshak`, [`VacuumFace::Marshak`]; CPU SOR only).**
//!   On a face between a medium voxel p and a vacuum voxel (σt ≤ σ_ε) no light enters from
//!   the vacuum, so the face's flux is half its fluence, F = φ_f/2 (Marshak), and with
//!   F = D_p(φ_p − φ_f)/(Δl/2) on the medium side the face coefficient is
//!   D_ps = 2D_pΔl/(Δl + 4D_p) (bounded by Δl/2 however thin the medium; → 2D_p, not the
//!   paper's D_p/2, when D_p ≪ Δl). Energy is conserved as with the paper's face
//!   (`solvers/tests/marshak.rs`: outflow = ∫ j dV to 10⁻⁸, every limiter). The raymarch
//!   then needs φ inside the surface voxel, which at σt·Δl ≫ 1 is far below φ_p: the
//!   pipeline interpolates φ with ghost values in the vacuum voxels that put the Marshak
//!   face value on the face ([`marshak_ghosts`]). Measured on issue 12's emissive albedo-1
//!   cube (8³, no lights, j = 1, downsample 1, image mean, `experiments emissive_cube`):
//!   CDA/FLD-LP with the Marshak face 0.0294 at σt = 100 and 0.0293 at σt = 1000 (the thick
//!   limit is independent of σt, as it must be), path tracer 0.0314 ± 0.0007 at σt = 100;
//!   the paper's faces give FLD-LP 0.262 / 2.33 and CDA 4.4·10⁻⁴ / 4.0·10⁻⁵. The default stays
//!   the paper's face: the GPU kernel and multigrid have only that one (a `:marshak` method
//!   reports itself CPU-only, and `:marshak:mg` is refused), and figures that reproduce the
//!   paper keep its boundary. At σt = 100 (16³, path tracer 1024 spp: 0.03051 ± 0.00034;
//!   σt = 1000: 0.0310 ± 0.0011) CDA/FLD-LP with the Marshak face are −0.4 % / −1.3 % off at
//!   downsample 1, −2 % / −4 % at 2 and −9 … −12 % at 3 and 4 (the coarse surface voxel);
//!   the paper's faces give FLD-LP 0.15 … 0.46 (σt = 100) and 1.2 … 4.3 (1000), CDA
//!   1.2·10⁻³ … 4·10⁻⁵ (`results/emissive_cube`). Convergence: `cda:marshak` needs more
//!   iterations where vacuum lies inside the grid (nebula 695 vs 57; `shell_core` reaches the
//!   20 000 cap 2.3 % from its tight solve), FLD-LP about as many as with the paper's face
//!   (`results/convergence_check`). Against the analytic CDA slab with the extrapolated
//!   boundary φ ∓ 2Dφ′ = 0 the Marshak face converges at second order (max relative error
//!   1.2·10⁻⁵ at 32 voxels across τ = 1, 1.1·10⁻³ at τ = 8 with σt·Δl = 1/4; observed orders
//!   1.9–2.9); the paper's face misses the surface fluence by 0.999.
//!   Pinned by `solvers/tests/marshak.rs`.
//! * **Anisotropy (issue 12, item 2).** The paper scatters isotropically with σs as given
//!   (variant `paper`, e.g. `cda`, `fld:lp`); `cda:similarity`, `fld:<limiter>:similarity`
//!   solve with σs' = (1 − g)σs, σt' = σa + σs' ([`crate::method::AnisotropyScaling`]) and,
//!   in the pipeline, the δ-scaled source σs'·L_ri' (lights baked through σt'). Keeping the
//!   source σs·L_ri instead (the first version) put 1/(1 − g) too much light into the
//!   diffusion near the lit surface: at g = 0.99 FLD-LP's multiple-scattering error was 12.5
//!   (noise_cloud 32³, 16×16) and is 0.98 with the δ-scaled source. The default stays
//!   `paper`: the measurement splits by g. In `results/accuracy_hg` (noise cloud and
//!   shell_core at 32³, 32×32 pixels, ds 4 and 2, tol 1e-3 f32, 2048-spp reference), the
//!   relative RMSE of the multiple-scattering image is lower with `similarity` in 8 of 16
//!   cases for FLD-LP (every case at g ≥ 0.9, e.g. g = 0.99 cloud ds 4: 8.26 → 0.978; none at
//!   g ≤ 0.7, e.g. g = 0.3 cloud ds 4: 0.333 paper vs 0.448) and in 2 of 16 for CDA (only
//!   the cloud at g = 0.99: 2.14 → 0.997; at g = 0.9 0.555 paper vs 0.946). The datasets of
//!   this repository that are anisotropic have g = 0.3, where `paper` is closer in every case.
//!   The plan warns when `paper` runs with |g| > 0.5. Pinned by
//!   `reference/tests/anisotropy_scaling.rs` (paper closer at g = 0.3, similarity at 0.99).
//! * **A limiter that vectorises (issue 15 item 3; [`limiter`]).** LP (and Kershaw,
//!   Larsen-2, sum, max) are evaluated branch-free with no libm call: LP was a Padé form of
//!   its continued fraction for R ≤ 2 and the closed form with an inline polynomial exp
//!   above (since 2026-12-06 a rational minimax form and (R − 1)/R², no exp: the last
//!   paragraphs of the bullet "Row length, boundary batch, split D loop" below), both
//!   computed and one selected, so the row loop of `cpu.rs` has no branch or
//!   call left in it (no runtime dispatch; the sweep's loop structure is unchanged; the
//!   code-generation target is the next decision). Accuracy (tests in `limiter.rs`, 20001 log-spaced R in
//!   [10⁻⁸, 10⁸] plus 0 and huge R): ≤ 4 ulp f32, ≤ 10⁻¹² f64 pinned. Bench
//!   (`benches/benches/diffusion.rs`, vacuum cloud, 2-core AMD EPYC, 32 MiB L3, shared
//!   machine: load 4 → 13.6 during the before run, 12.8 → 15.7 during the after run, so
//!   absolute times are several times the quiet ones and the before/after times are not
//!   like for like), ms per red-black
//!   iteration before → after, same-run ratio FLD-LP/CDA time in brackets:
//!   256³ f32 CDA 240.7 → 335.1, FLD-LP 1976 → 1059 (8.2 → 3.2); 256³ f64 CDA 397.7 →
//!   516.1, FLD-LP 4798 → 1627 (12.1 → 3.2); 128³ f32 FLD-LP 255.5 → 198.4 (10.6 → 3.0);
//!   128³ f64 FLD-LP 711 → 237 (22.1 → 4.1). Ratio to the STREAM-rule triad of the same
//!   run at 256³: FLD-LP f32 0.041 → 0.073, f64 0.073 → 0.102 (triad 5.7–7.8 GB/s under
//!   that load instead of ~45 quiet). Issue 15's ≥ 0.4 is not shown by these runs
//!   (`results/bench/diffusion_cpu.csv`, before: `diffusion_cpu_before_lim.csv`).
//! * **Code generation and the boundary layer (issue 15 item 4;
//!   `results/bench/diffusion_cpu.csv`, SSE2 run: `diffusion_cpu_sse2.csv`).** With the branch-free
//!   limiter the LP sweep is compute-bound, not bandwidth-bound: at 256³ f32 it moved 4.6
//!   GB/s of a 39 GB/s triad (`perf`: the row loop is vectorised, ~60 SSE instructions per
//!   voxel, register spills). Two changes, each bit-identical (hash of φ, D and the residual
//!   history after 30 iterations, every limiter, f32 and f64, 40×33×37 random medium; an
//!   ad-hoc example built under both targets, not kept):
//!   (1) the boundary-layer D update ran serially and cost 19 % of the CPU samples at 128³
//!   for 5 % of the voxels (still 12 % at 256³, 2 % of the voxels, once parallel: it reads
//!   scattered cache lines): it now runs in parallel over z-slabs
//!   (`results_are_bit_identical_for_one_and_two_threads` in `cpu/tests.rs`); (2) the
//!   workspace builds for x86-64-v3 (AVX2, `.cargo/config.toml`): 8 f32 lanes instead of 4.
//!   One red-black iteration at 256³ (vacuum cloud, `cargo bench -p benches --bench
//!   diffusion`, 2-vCPU AMD EPYC, 32 MiB L3, quiet), SSE2 → AVX2 build with (1) in both,
//!   ms (÷ triad of the same run): CDA f32 51.3 (0.20) → 31.0 (0.46), FLD-LP f32 132.1
//!   (0.12) → 87.3 (0.21), CDA f64 69.6 (0.42) → 47.4 (0.66), FLD-LP f64 259.3 (0.10) →
//!   139.4 (0.27); triad 29–48 GB/s across the probes of those runs. Issue 15's targets
//!   (FLD-LP ≥ 0.4, CDA ≥ 0.6 of triad) were then met for CDA f64 only (since the next
//!   decision, for CDA in both precisions): FLD-LP then did ~60 vector instructions per voxel (Padé + exp + 4 divisions + sqrt besides the stencil) on
//!   two vCPUs, which at 0.4 of a 33 GB/s triad would have to retire in ~40 ms.
//! * **Row length, boundary batch, split D loop (issue 15 item 4; 2026-12-06,
//!   `results/bench/diffusion_cpu.csv`).** Three changes to `cpu.rs`, each bit-identical (hash
//!   of φ, D and the residual history after 30 iterations for every limiter including
//!   Larsen-3, paper and Marshak faces, f32 and f64, 40×33×37 random medium with 20 % vacuum;
//!   an ad-hoc example, not kept):
//!   (1) packed rows are ⌈nx/2⌉ made odd (`packed_row_len`): at 256³ a row of 128 values put
//!   the z-neighbour rows a power of two apart, into the same cache sets; 256³ then ran slower
//!   than 258³ (f32 CDA 32.7 vs 21.7 ms), and with the odd row CDA f32 takes 21.8 ms;
//!   (2) the boundary layer's D is gathered per slab and computed in one vectorised loop
//!   (`perf`: 17.9 → 12.6 % of the FLD-LP f32 samples at 256³; what is left waits on the x
//!   faces' scattered loads); (3) the row loop computes D for the whole run before the φ update
//!   (fewer live vector registers; −3.8 % alone, p = 0.03).
//!   One red-black iteration at 256³ (2-vCPU AMD EPYC 7002-series, family 23 model 49, 16 MiB
//!   L3 reported; `cargo bench -p benches --bench diffusion` before and after, same machine), ms (÷ the triad of the
//!   same run): CDA f32 30.3 (0.43) → 20.0 (0.63), CDA f64 38.7 (0.71) → 28.3 (0.85),
//!   FLD-LP f32 95.4 (0.16) → 66.8 (0.25), FLD-LP f64 148.6 (0.21) → 113.1 (0.27); triad
//!   35–40 GB/s in those runs. Issue 15's CDA target (≥ 0.6 of triad) is met in both
//!   precisions; FLD-LP's (≥ 0.4) is not, and cannot be on this machine with FLD's arithmetic:
//!   the same sweep with the sum limiter (one division instead of LP's then Padé form,
//!   closed form and exp) takes 44.0 ms (0.34 of a 39.9 GB/s triad) and with the max limiter 46.1 ms
//!   (0.33), so the Knudsen number, D = F/σ and the θ-blend alone (a square root and two
//!   divisions per voxel on top of CDA's one) leave FLD below 0.4, and LP's own evaluation
//!   adds 23 ms. Tried and dropped on the way (same bench): fixed 8-voxel blocks (LLVM unrolled
//!   them into scalar code: CDA f32 205 ms), a row tail padded through a second, non-inlined
//!   call (its per-call alias checks cost more than the tail: CDA f32 45 ms), and writing each
//!   row to padded buffers (no gain once (1) was found).
//!   **Where the rest of FLD-LP's time goes (2026-12-06, same machine, an ad-hoc example timing
//!   `CpuFld::iterate` at 256³ on the vacuum cloud, median of 9, builds not kept).** Two
//!   divisions per voxel removed (LP's 1/R and F/σ replaced by products, wrong numbers, timing
//!   only): f32 65.7 → 66.3 ms, f64 112.0 → 111.7 ms, so the sweep is not bound by the divider.
//!   Skipping the boundary layer's two x-end voxels per row (2 % of the voxels): 66.4 → 58.7
//!   ms, so those scattered gathers (each reads seven cache lines in five rows) are 12 % of the
//!   iteration. (The four full faces are not free either: skipping them at 04d0d3a, three runs
//!   alternating, took 58.9–59.7 → 54.8–55.9 ms, about 7 %; they are still gathered by
//!   `update_boundary_d`, in rows.) The x-ends are now folded into
//!   the row passes (`CpuFld::x_ends_in_pass`, where it is argued exact: an end's only
//!   non-constant input is the interior voxel next to it in the same row): φ, D and the
//!   residual history are bit-identical (hashes after 30 iterations, every limiter including
//!   Larsen-3, paper and Marshak faces, θ = 0.7, f32 and f64, 40×33×37, 3×9×8 and 4×5×6
//!   random media with 20 % vacuum, and 12 multigrid cycles on the 48³ cloud), and the same
//!   example measures 256³ f32 66.0–68.3 → 62.1–62.2 ms, f64 113.7–115.4 → 110.3–112.0 ms,
//!   128³ f32 11.6 → 10.7 ms. `cargo bench -p benches --bench diffusion` afterwards (its CSV
//!   was committed with a38fa9f and replaced by the run of the next paragraph): FLD-LP 256³ f32 63.5 ms (0.24 of a 39.3 GB/s
//!   triad), f64 111.6 ms (0.27 of 40.8 GB/s); CDA f32 20.2 ms is 0.57 of that run's 40.8
//!   GB/s triad (0.63 of the 37.3 GB/s of the run before: the probe, not the sweep, moved;
//!   a 256³-only rerun gave 0.565 at 41.1 GB/s), CDA f64 0.78. A third full run ten minutes
//!   later (not committed) met a 29–30 GB/s triad with the same sweep times (CDA f32 256³
//!   20.2 ms, FLD-LP 61.6 ms f32 and 110.0 ms f64): 0.80, 0.33 and 0.38 of it. This shared
//!   machine's triad moves by a third within minutes while the sweeps do not move at all, so
//!   neither sweep is bound by DRAM bandwidth here, and a single run's ratio says more about
//!   the probe than about the sweep.
//!   **Row blocks across slabs (`SLAB_GROUP`, `ROW_BLOCK` in `cpu.rs`; 2026-12-06, the same
//!   2-vCPU AMD EPYC 7002, family 23 model 49).** A
//!   colour pass used to take one z-slab per task, row after row: by the time a slab needs
//!   its z-neighbours' rows (the slabs before and after, 4 arrays of 132 KB each at 256³
//!   f32), they have left the 512 KB L2. Each task now takes up to 8 consecutive slabs (at
//!   least 4 tasks per thread) and walks them 32 rows at a time, each slab's rows still in
//!   ascending order, so its residual sum, φ, D and the residual history are bit-identical
//!   (the hashes of the previous bullet, all 36 cases and the multigrid). Same ad-hoc
//!   example, ms per iteration before → after: CDA f32 256³ 19.7 → 17.4, 128³ 3.30 → 2.63,
//!   64³ 0.66 → 0.48; CDA f64 256³ 28.5 → 28.1, 128³ 4.32 → 3.82; FLD-LP f32 256³ 62.4 →
//!   59.5, 128³ 10.5 → 10.0; FLD-LP f64 256³ 110.8 → 107.4. The bench afterwards (its
//!   `results/bench/diffusion_cpu.csv`, committed with 04d0d3a and replaced by the run of the
//!   FMA paragraph below; its triad probes swung between 42 and 30 GB/s within the run): 256³ CDA f32 16.9 ms (0.66 of 42.3 GB/s), FLD-LP f32 58.4 ms (0.33
//!   of 31.4 GB/s), f64 105.8 ms (0.37 of 30.9 GB/s); its 64³ FLD-LP rows (1.9 and 4.0 ms)
//!   are noisy: a 64³-only rerun gave 2.2 and 2.6 ms. Padding each run to whole 8-voxel vectors (the padding lanes
//!   masked out of every store; before the x-end fold, against 65.5–67.3 ms f32 and
//!   113.4–115.8 ms f64 unpadded) did not pay: padding both loops took 68.6–74.2 ms f32 (LLVM's
//!   vectorised loop kept a scalar remainder of 1–8 iterations whatever the trip count, as it
//!   could not prove the cut slices as long as the run, so a run of 128 left 8 scalar voxels
//!   where 127 left 7; re-cutting the slices at the loop removed that but not the cost of the
//!   masks), padding the D loop alone 63.8–64.3 ms f32 but 117.1 ms f64, and F/σ into a
//!   scratch row over the padded run with the blend over the real one 70.9–71.3 ms f32.
//!   **Fused multiply-adds in the limiter polynomials (2026-12-06, same 2-vCPU AMD EPYC 7002;
//!   `fld::limiter`'s `mul_add`).** The Horner steps of LP's Padé form and of the exp behind
//!   its closed form (the LP of that time) became one FMA each where the target has FMA (x86-64-v3 does), instead of
//!   a rounded multiply and an add. One iteration at 256³ (the ad-hoc example above, median
//!   of 11, builds alternating): FLD-LP f32 58.8–59.3 → 55.1–56.4 ms, f64 106.3 → 97.3 ms;
//!   CDA and the other limiters are untouched. This is the one place the sweep is no longer
//!   bit-identical between targets with and without FMA (the limiter tests hold either way).
//!   `cargo bench -p benches --bench diffusion` afterwards (the committed
//!   `results/bench/diffusion_cpu.csv`; its triad probes stayed at 38–45 GB/s at 128³ and
//!   256³): 256³ FLD-LP f32 54.8 ms (0.27 of a 40.8 GB/s triad), f64 94.6 ms (0.31 of 41.2
//!   GB/s); CDA f32 17.3 ms (0.63 of 43.0 GB/s), f64 26.4 ms (0.90 of 39.5 GB/s).
//!   **What LP's evaluation costs (same example and machine, with the FMAs, median of 11, two
//!   runs each):** CDA 17.2–17.6 ms, sum 33.5–34.2 ms, max 33.7–33.8 ms, Kershaw 37.6–38.1
//!   ms, LP 55.3–55.6 ms per f32 iteration at 256³ (f64: CDA 27.2, LP 96.8 ms). The Knudsen
//!   number, D = F/σ and the θ-blend cost 16 ms over CDA with any limiter, and LP's then Padé form,
//!   closed form and exp another 21 ms. 0.4 of the bench run's 40.8 GB/s triad (below) at
//!   the 604 MB an f32 FLD iteration counts at 256³ would take ≈ 37 ms per iteration (≈ 49 ms
//!   at the 31 GB/s the probe read in the run before), so FLD-LP needs a cheaper LP, not less
//!   memory traffic.
//!   **Tried and dropped: no scalar tail (2026-12-06, builds not kept).** `perf annotate` of
//!   the f32 LP sweep at 256³ put about a fifth of the row loop's samples in LLVM's scalar
//!   remainder after the vectorised D loop (7 of each run's 127 voxels). (a) Chunks of 8
//!   voxels loaded into fixed arrays: LLVM unrolls the 8-lane loop and its SLP vectoriser
//!   leaves the limiter scalar (LP 198–253 ms, CDA 103–151 ms). (b) The D loop out of place
//!   into a scratch row over [0, 8⌊len/8⌋) and again over the last 8 voxels (overlapping, same
//!   inputs, same values; bit-identical): with the φ loop in a function of its own LP 54.3–55.7
//!   ms against 59.1–60.6 ms, but CDA 18.5–19.6 ms against 17.6–18.3 ms, and with the φ loop
//!   inline as before LP 58.9–59.8 ms (no gain): a gain that depends on where LLVM puts a
//!   loop, bought with a CDA loss, was not kept.
//!   **LP without exp, one division for D (2026-12-06, same 2-vCPU AMD EPYC 7002, same
//!   ad-hoc example, median of 11 (f32) / 7 (f64)).** (1) `limiter::levermore_pomraning` is
//!   now Q/(3Q + R²P) with P, Q a relative minimax rational of type (4, 4) in R² below R = 9
//!   (f32; (7, 7) below 16.5 in f64) and (R − 1)/R² above, where e^(−2R) is below the
//!   precision: no exp, no 1/R. Worst error 3.28 ulp over every positive f32 (measured
//!   exhaustively; the tests check every f32 in [2⁻¹⁰, 2²⁷]). (2) Every limiter is a
//!   fraction ([`limiter::FluxLimiter::fraction`]) and D = θ·num/(den·σ) takes one division
//!   instead of two. f32 LP 256³: 55.3–55.6 → 41.9–43.7 ms over eight runs (a plain P/Q of
//!   the same degree without (2), dropped for its accuracy: 41.4–42.1); f64 LP 96.4 →
//!   75.0–80.5 ms. The other limiters moved within the noise
//!   (f32 sum 33.1–34.0 → 32.1–33.5, Kershaw 35.7–36.5 after; CDA 17.3–17.8 after, untouched),
//!   so (2) is not measurably faster on its own; it is kept because it is one division fewer
//!   on any machine whose divider is busier. LP now costs ≈ 9 ms over the sum limiter in
//!   f32 (was 21) and ≈ 24 ms in f64 (was 42). Also measured and dropped: Estrin's scheme
//!   for the two polynomials (41.3–41.8 ms f32, 76.6–78.0 ms f64: within the noise, and 3.61
//!   ulp worst), and skipping the D loop's scalar remainder altogether (wrong numbers,
//!   timing only: LP 43.3–43.5 ms, so the tail no longer costs anything measurable).
//!   `cargo bench -p benches --bench diffusion` afterwards (the committed
//!   `results/bench/diffusion_cpu.csv`; triad probes 38–44 GB/s at 128³ and 256³): 256³
//!   FLD-LP f32 42.3 ms (0.34 of a 42.0 GB/s triad; was 54.8 ms, 0.27), f64 74.2 ms (0.38 of
//!   42.5 GB/s; was 94.6 ms, 0.31); CDA f32 16.6 ms (0.66 of 43.0 GB/s), f64 26.0 ms (0.87
//!   of 41.7 GB/s). Issue 15's FLD-LP target (≥ 0.4) is still not met: f32 would need ≈ 36 ms
//!   at this triad, about what the sum limiter's sweep takes (32–34 ms), and f64 ≈ 71 ms.
//!   Where f64 still goes (`perf record` of the ad-hoc example, f64 LP at 256³, cpu-clock
//!   samples, so attributed a few instructions late): 82 % of the samples in the inlined
//!   row passes, of which the D loop takes 57 % and the φ loop 29 %; about a third of the
//!   D loop's samples sit just behind its square root and its two divisions (the Knudsen
//!   number and D). A timing-only build without the Knudsen division (wrong numbers) took
//!   72.5–73.2 ms against 76.0 ms, so the divider is now a large part of f64 FLD-LP's
//!   remaining cost, and a cheaper limiter alone will not reach 0.4 in f64 either.
//!   **Fused colour passes (2026-12-06, 2-vCPU AMD EPYC Zen 5, family 26 model 2, 32 MiB L3;
//!   `CpuFld::fused_with`).** On grids of four slabs or more an iteration no longer runs the
//!   red pass over the whole grid and then the black pass: each task of consecutive slabs
//!   updates red slab k and then black slab k − 1 while the red slabs k − 2 … k that slab
//!   reads are still in cache, and the black slabs at the tasks' ends follow in a second
//!   parallel phase. A black voxel reads only red neighbours and a red one only black ones,
//!   so every voxel sees the same values as in the two passes: φ, D, the kept x-end D and
//!   the residual sums are bit-identical (`fused_passes_are_bit_identical_to_two_passes`,
//!   1, 2, 3 and 8 threads, both faces; and the hash of φ, D and the residual history after
//!   30 iterations for every limiter, both faces, f32 and f64, on six random media from
//!   40×33×37 to 3×9×8, one and two threads, against the build before). The other colour's
//!   φ and D then come from cache instead of memory: 5 values per voxel move for CDA
//!   instead of 7, and 7 for FLD instead of 9 (`bytes_per_iteration` keeps counting 7 and
//!   9, the work the bench's effective bandwidth is defined by). Measured with an ad-hoc
//!   example alternating fused and split iterations on one solver (256³ vacuum cloud,
//!   41 iterations each, three runs, minimum per run, ms): CDA f32 12.46–12.55 against
//!   14.42–14.58, CDA f64 21.88–22.37 against 24.08–25.43, FLD-LP f64 45.1–45.7 against
//!   48.5–49.2, FLD-LP f32 25.1–27.7 against 25.3–26.8 (no change: compute-bound, as its
//!   sweep at 96³ in L3 runs no faster per voxel); at 128³ (within reach of the L3) CDA
//!   f32 1.66 against 1.63, f64 2.95 against 3.26. Tasks of nz/(2 × threads) slabs; 1 or 4
//!   per thread measured the same within the noise of this shared host (its iteration times
//!   jump by up to 1.5× for minutes at a time, which is why minima are compared). Also
//!   measured here and dropped: skipping the row loops' scalar remainders (wrong numbers,
//!   timing only, alternating as above) changed nothing (FLD-LP f32 minima of two runs 23.5
//!   and 24.6 ms with the remainders, 23.3 and 25.0 ms without), although `perf` put a
//!   quarter of the cpu-clock samples of the LP pass in scalar code, so those samples most
//!   likely wait on loads (cpu-clock sampling cannot tell); and a build for this CPU's AVX-512
//!   (`-C target-cpu=native`, the whole bench) took FLD-LP f32 from 23.65 to 22.18 ms and
//!   CDA from 13.44 to 13.25 ms, too little for a second code path.
//!   `cargo bench -p benches --bench diffusion` before and after (same host, same session;
//!   the committed `results/bench/diffusion_cpu.csv` is the run after), 256³, ms (÷ the
//!   triad of the same run): CDA f32 13.44 (0.77 of 45.6 GB/s) → 12.27 (0.85 of 44.9),
//!   FLD-LP f32 23.65 (0.55 of 46.7) → 24.11 (0.53 of 47.3), CDA f64 25.51 (0.84 of 44.1)
//!   → 21.96 (0.56 of 76.0), FLD-LP f64 45.97 (0.58 of 45.3) → 46.07 (0.35 of 75.2). The
//!   host's triad rose from 45 to 75 GB/s between the f32 and the f64 half of the run
//!   after, and the f64 ratios fell with it while the sweep times did not rise: issue 15's
//!   ratios (FLD-LP ≥ 0.4, CDA ≥ 0.6) hold on this kind of host when its triad reads
//!   ≈ 45 GB/s (both precisions before, f32 after) and not when it reads 75 GB/s.
//!   **Row views inlined (2026-12-06, same host).** `perf` of a multigrid solve listed
//!   `Rows::new` (the other colour's five rows around a row, built three times per row) with
//!   self time of its own: LLVM had not inlined it, nor `Rows::cut`. Both are now
//!   `#[inline(always)]`; φ, D and residuals bit-identical (the hashes above). Minimum of 11
//!   iterations at 256³, three runs of each build alternating, ms: CDA f32 11.9–12.5 →
//!   11.2–11.5, CDA f64 21.6–22.4 → 21.1–21.5, FLD-LP f32 24.7–25.9 → 21.2–24.3, FLD-LP f64
//!   44.1–44.9 → 42.0–43.7.
//!   `cargo bench -p benches --bench diffusion` with both changes (the committed
//!   `results/bench/diffusion_cpu.csv`; this time the triad read 42–46 GB/s at 256³),
//!   256³: CDA f32 11.68 ms (0.90 of a 44.8 GB/s triad), FLD-LP f32 22.20 ms (0.64 of 42.5),
//!   CDA f64 21.51 ms (0.96 of 45.7), FLD-LP f64 43.35 ms (0.63 of 44.4). Their effective
//!   bandwidths (40.2, 27.2, 43.7, 27.9 GB/s) keep issue 15's ratios (CDA ≥ 0.6, FLD-LP ≥
//!   0.4) for any triad up to 67 GB/s (CDA f32), 68 (FLD-LP f32), 73 (CDA f64) and 70
//!   (FLD-LP f64); this kind of host has read 42–76 GB/s, so at the top of that range
//!   they do not hold.
//! * **Extent L** of σ_ε = 10⁻³/L is the grid's longest edge.
//! * **No emission.** If j̄ = 0 the floors and the normalisation use j_ref = max|φ_boundary|/Δl
//!   instead; with a zero boundary as well the solution is φ = 0 and no iteration runs.
//! * **ε in f32** is 10⁻¹⁰ instead of 10⁻²⁰ (see [`Real::DEFAULT_EPSILON`]).
//! * **Normalisation.** The solve runs on j/j̄ and boundary values/j̄, and φ is multiplied
//!   back by j̄ on output. CDA and FLD are degree-1 homogeneous in the source (R and F(R)
//!   are scale-free, the floors of Eq 35 scale with j̄), so this changes nothing
//!   mathematically; it keeps |∇φ|² and ε j̄ inside f32's range whatever the caller's units.
//!   Without it, f32 homogeneity held only for source scales 10⁻¹⁶ … 10¹⁴ (measured on the
//!   Fig 4 cloud; outside, |∇φ|² under- or overflowed and φ was wrong by O(1)). The
//!   homogeneity test covers 10⁻³⁰ … 10³⁰ in both precisions.

pub mod cpu;
pub mod gpu;
pub mod limiter;
pub mod method;
pub mod multigrid;
pub(crate) mod residual;

pub use cpu::CpuFld;
pub use gpu::GpuFld;
pub use limiter::FluxLimiter;
pub use method::{CDA, FLD, FldMethod};

/// The φ the raymarch interpolates after a solve with the Marshak vacuum face. With
/// κ_p = (4D_p − Δl)/(Δl + 4D_p), D_p = 1/(3σt_p), a vacuum voxel next to a medium voxel p
/// (vacuum: σt ≤ σ_ε = 10⁻³/L) across a face takes κ_p φ_p, so that φ, linear between the
/// voxel centres, equals the Marshak face value φ_f = (1 + κ_p)φ_p/2 = 4D_pφ_p/(Δl + 4D_p)
/// (twice the face's flux) on the face: inside the surface voxel φ then runs linearly from
/// φ_f to φ_p, the profile the face coefficient assumes. A vacuum voxel diagonal to p across
/// an edge takes φ_p and one across a corner κ_p φ_p: then the trilinear interpolant on
/// every face plane of p is φ_f up to the medium's edges and corners (with 0 there, as the
/// solve leaves the Dirichlet layer, the surface dips to negative values near every edge of
/// an optically thick medium). Each takes the mean over its neighbours of the lowest kind
/// (faces before edges before corners); other voxels are unchanged. The face and corner
/// values are negative for σt·Δl > 4/3 and only ever weight points in vacuum or inside a
/// surface voxel's outer half.
pub fn marshak_ghosts(medium: &Medium<f64>, phi: &[f64]) -> Vec<f64> {
    let g = medium.grid;
    let eps = 1e-3 / g.extent();
    let dl = g.dl;
    let mut out = phi.to_vec();
    if phi.len() != g.len() {
        return out;
    }
    for (idx, ghost) in out.iter_mut().enumerate() {
        if medium.sigma_t[idx] > eps {
            continue;
        }
        let [x, y, z] = g.coords(idx).map(|v| v as i64);
        // (sum, count) per kind: 1 = face, 2 = edge, 3 = corner neighbours.
        let mut acc = [(0.0, 0usize); 4];
        for dz in -1i64..=1 {
            for dy in -1i64..=1 {
                for dx in -1i64..=1 {
                    let m = (dx != 0) as usize + (dy != 0) as usize + (dz != 0) as usize;
                    let n = [x + dx, y + dy, z + dz];
                    if m == 0 || n.iter().zip(g.n).any(|(&v, k)| v < 0 || v >= k as i64) {
                        continue;
                    }
                    let p = g.index(n[0] as usize, n[1] as usize, n[2] as usize);
                    let st = medium.sigma_t[p];
                    if st > eps {
                        let d = 1.0 / (3.0 * st);
                        let kappa = (4.0 * d - dl) / (dl + 4.0 * d);
                        // Faces and corners κ φ_p, edges φ_p (see above).
                        acc[m].0 += phi[p] * if m == 2 { 1.0 } else { kappa };
                        acc[m].1 += 1;
                    }
                }
            }
        }
        if let Some((sum, count)) = acc[1..].iter().find(|(_, c)| *c > 0) {
            *ghost = sum / *count as f64;
        }
    }
    out
}

use crate::gpu::Timer;
use crate::method::{Solution, Stop};
use crate::{Backend, Grid, Medium, Precision, Real, SolverError};
use multigrid::CpuMultigrid;

/// Which extinction enters the Knudsen number R = |∇φ|/(σ φ) and D = F(R)/σ.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum KnudsenSigma {
    /// σt, as in FLD Eqs 15, 16, 33, 35.
    #[default]
    Extinction,
    /// α·σt = σs, Levermore & Pomraning's original effective-albedo form \[LP81\] with the
    /// effective albedo taken as the single-scattering albedo α (their ω also counts the local
    /// source, which we leave out): R = |∇φ|/(α σt φ), D = F(R)/(α σt). This keeps the flux
    /// bound |E| ≤ φ and has D → 1/(3σs) in the diffusive limit, which is closer to the
    /// Grosjean coefficient (2 − α)/(3σt) at low albedo. Both floored at σ_ε.
    EffectiveAlbedo,
}

/// The diffusion coefficient of a face between a medium voxel and a vacuum voxel (σt ≤ σ_ε).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum VacuumFace {
    /// The paper's D_ps = (D_p + D_s)/2 (FLD Eq 32), with the vacuum voxel's D from the floors
    /// of FLD Eqs 33/35.
    #[default]
    Paper,
    /// A Marshak (Robin) condition on the face: no light enters from the vacuum side, so the
    /// face's flux is half its fluence, F = φ_f/2, and with F = D(φ_p − φ_f)/(Δl/2) on the
    /// medium side D_ps = 2DΔl/(Δl + 4D) with D the medium voxel's (method spec `:marshak`).
    Marshak,
}

/// Solver parameters of FLD Algorithm 1.
#[derive(Debug, Clone, PartialEq)]
pub struct FldConfig {
    /// F(R); [`FluxLimiter::Cda`] gives classical diffusion.
    pub limiter: FluxLimiter,
    /// SOR factor ω ∈ (0, 2) (FLD Eq 36).
    pub omega: f64,
    /// Stop when R̄/j̄ falls below this; `None` uses [`Real::DEFAULT_TOLERANCE`]
    /// (10⁻⁶ in f64, 10⁻⁴ in f32). 0 runs exactly `max_iterations`.
    pub tolerance: Option<f64>,
    /// Upper bound on iterations (one iteration = red pass + black pass).
    pub max_iterations: usize,
    /// Extinction floor σ_ε (FLD Eq 33); `None` uses 10⁻³/L with L the grid extent. It
    /// bounds FLD's vacuum D by 1/(3σ_ε), which it approaches at critical points of φ, and so
    /// sets how slowly multigrid converges on vacuum scenes; it changes φ as well (measured
    /// in the `multigrid` module docs, "Why the cloud's FLD-LP cycles grow").
    pub sigma_eps: Option<f64>,
    /// ε of FLD Eq 35 and of the initial values; `None` uses [`Real::DEFAULT_EPSILON`]
    /// (the paper's 10⁻²⁰ in f64, 10⁻¹⁰ in f32 to stay clear of subnormals).
    pub epsilon: Option<f64>,
    /// Voxels next to the boundary layer left out of the RMS residual (FLD Section 5,
    /// "ignoring voxels close to the boundary"). 0 (the default) uses every interior voxel
    /// (see the module docs, "Residual window").
    pub residual_margin: usize,
    /// The σ in the Knudsen number and D.
    pub knudsen: KnudsenSigma,
    /// θ ∈ (0, 1]: under-relaxation of the D update (see the module docs). 1 is FLD
    /// Algorithm 1 verbatim; the default 0.5 keeps nonlinear SOR convergent up to ω = 1.9.
    pub d_relaxation: f64,
    /// The face coefficient between medium and vacuum (CPU SOR only for `Marshak`).
    pub vacuum_face: VacuumFace,
}

impl Default for FldConfig {
    fn default() -> Self {
        Self {
            limiter: FluxLimiter::LevermorePomraning,
            omega: 1.0,
            tolerance: None,
            max_iterations: 100_000,
            sigma_eps: None,
            epsilon: None,
            residual_margin: 0,
            knudsen: KnudsenSigma::Extinction,
            d_relaxation: 0.5,
            vacuum_face: VacuumFace::Paper,
        }
    }
}

impl FldConfig {
    /// CDA with otherwise default settings.
    pub fn cda() -> Self {
        Self {
            limiter: FluxLimiter::Cda,
            ..Self::default()
        }
    }

    /// FLD with the given limiter.
    pub fn fld(limiter: FluxLimiter) -> Self {
        Self {
            limiter,
            ..Self::default()
        }
    }

    /// Builder: SOR factor.
    pub fn with_omega(mut self, omega: f64) -> Self {
        self.omega = omega;
        self
    }

    /// Builder: tolerance on R̄/j̄.
    pub fn with_tolerance(mut self, tol: f64) -> Self {
        self.tolerance = Some(tol);
        self
    }

    /// Builder: iteration cap.
    pub fn with_max_iterations(mut self, n: usize) -> Self {
        self.max_iterations = n;
        self
    }

    /// The SOR factor that is optimal for the Poisson equation on an `n`-voxel-wide grid,
    /// 2/(1 + sin(π/n)). A good default for weakly absorbing media; absorption lowers the optimum.
    /// Too large for the max limiter (F = 1/max(3, R), a kink at R = 3) on fine grids: on the
    /// 127³ point source (τ = 4, albedo 0.1–0.7) SOR at this ω (1.952) stays at R̄/j̄
    /// 1.7–4.0·10⁻² for 20 000 sweeps, where ω = 1.9 converges in 914 (albedo 0.5; 31³ and 63³
    /// converge at this ω; `multigrid/HISTORY.md`, 2026-12-08). Such a solve ends at its cap,
    /// never as converged.
    pub fn poisson_optimal_omega(n: usize) -> f64 {
        2.0 / (1.0 + (std::f64::consts::PI / n.max(2) as f64).sin())
    }

    /// Checks every parameter.
    pub fn validate(&self) -> Result<(), SolverError> {
        self.limiter.validate()?;
        let bad = |name, value, reason| {
            Err(SolverError::BadParameter {
                name,
                value,
                reason,
            })
        };
        if !(self.omega > 0.0 && self.omega < 2.0) {
            return bad("omega", self.omega, "SOR needs 0 < ω < 2");
        }
        if let Some(t) = self.tolerance {
            if !(t.is_finite() && t >= 0.0) {
                return bad("tolerance", t, "must be finite and ≥ 0");
            }
        }
        if let Some(s) = self.sigma_eps {
            if !(s.is_finite() && s > 0.0) {
                return bad("sigma_eps", s, "must be finite and > 0");
            }
        }
        if !(self.d_relaxation > 0.0 && self.d_relaxation <= 1.0) {
            return bad("d_relaxation", self.d_relaxation, "θ must be in (0, 1]");
        }
        if let Some(e) = self.epsilon {
            if !(e.is_finite() && e > 0.0 && e < 1.0) {
                return bad("epsilon", e, "must be in (0, 1)");
            }
        }
        Ok(())
    }
}

/// Dirichlet boundary values on the outermost voxel layer.
#[derive(Debug, Clone, PartialEq)]
pub enum Boundary<T> {
    /// φ = ε j̄ Δl ≈ 0 on the boundary layer, as in FLD Section 5.
    Zero,
    /// Values per voxel (full grid, x fastest); only the boundary layer is read.
    Values(Vec<T>),
}

impl<T: Real> Boundary<T> {
    /// Dirichlet values from a function of the voxel centre, e.g. the analytic CDA solution
    /// for FLD Fig 5a. Only boundary voxels are evaluated.
    pub fn from_fn(grid: &Grid, f: impl Fn([f64; 3]) -> f64) -> Self {
        let mut v = vec![T::zero(); grid.len()];
        for k in 0..grid.n[2] {
            for j in 0..grid.n[1] {
                for i in 0..grid.n[0] {
                    if grid.is_boundary(i, j, k) {
                        v[grid.index(i, j, k)] = T::c(f(grid.center(i, j, k)));
                    }
                }
            }
        }
        Boundary::Values(v)
    }
}

impl Boundary<f64> {
    /// The same boundary in another precision.
    pub fn cast<U: Real>(&self) -> Boundary<U> {
        match self {
            Boundary::Zero => Boundary::Zero,
            Boundary::Values(v) => Boundary::Values(v.iter().map(|&x| U::c(x)).collect()),
        }
    }
}

/// Solves on any [`Backend`]: the medium and boundary are given in `f64` and converted to
/// the backend's precision; φ comes back in `f64`. `observer(iteration, residual)` sees every
/// iteration (on the GPU in batches of [`GpuFld::check_every`], as residuals are read back).
pub fn solve(
    backend: &Backend<'_>,
    medium: &Medium<f64>,
    boundary: &Boundary<f64>,
    config: &FldConfig,
    observer: impl FnMut(usize, f64),
) -> Result<FldSolution<f64>, SolverError> {
    fn widen<T: Real>(s: FldSolution<T>) -> FldSolution<f64> {
        s.widen_with(|t| t)
    }
    match backend {
        Backend::Cpu(Precision::F64) => {
            Ok(CpuFld::new(medium, boundary, config)?.solve_observed(observer))
        }
        Backend::Cpu(Precision::F32) => Ok(widen(
            CpuFld::<f32>::new(&medium.cast(), &boundary.cast(), config)?.solve_observed(observer),
        )),
        Backend::Gpu(ctx) => Ok(widen(
            GpuFld::new(ctx, &medium.cast(), &boundary.cast(), config)?.solve_observed(observer)?,
        )),
    }
}

/// How the FLD/CDA equation is solved: red-black SOR (FLD Algorithm 1, the reference),
/// FAS multigrid ([`multigrid`], CPU and GPU), or [`Solver::Auto`], which picks between them
/// by the measured rule of [`auto_multigrid_voxels`] and [`AUTO_SOR_SWEEPS`].
#[derive(Debug, Clone, PartialEq, Default)]
pub enum Solver {
    /// Red-black SOR, FLD Algorithm 1.
    #[default]
    Sor,
    /// FAS multigrid with these cycle settings.
    Multigrid(multigrid::MgConfig),
    /// Multigrid (with these settings) where it was measured faster, SOR where it was not,
    /// and SOR where multigrid does not converge:
    /// * grids of at least [`auto_multigrid_voxels`] voxels (CDA 100³, FLD 63³) start with
    ///   multigrid;
    /// * smaller grids start with SOR and hand the solve to multigrid (from scratch) if SOR
    ///   has not converged after [`AUTO_SOR_SWEEPS`] sweeps;
    /// * if multigrid stops without converging (`stalled`, the cap, non-finite) or cannot
    ///   run (`Unsupported` settings, its memory budget), SOR solves from scratch with the
    ///   full iteration cap;
    /// * with the Marshak face ([`VacuumFace::Marshak`], which multigrid does not have) SOR
    ///   alone.
    ///
    /// The result says which solvers ran in [`FldTrace::solver`] (e.g. `sor>multigrid`);
    /// its seconds, setup seconds and work units are the sums over them, its steps and
    /// residual history the last solver's.
    Auto(multigrid::MgConfig),
}

/// Grids with at least this many voxels (boundary layer included) start [`Solver::Auto`]
/// with multigrid: 10⁶ (100³) for CDA, 250 000 (63³) for FLD. *Why* (`multigrid_scaling`,
/// 2-vCPU AMD EPYC, CPU f64, R̄/j̄ < 10⁻⁶, SOR seconds over multigrid's, point source and
/// Fig 4 cloud): CDA 3.1× and 1.9× at 127³, 1.3× and 0.6× at 63³; FLD-LP 3.2× and 5.4× at
/// 127³, 1.2× and 3.4× at 63³, 0.6× and 1.5× at 31³.
pub fn auto_multigrid_voxels(limiter: FluxLimiter) -> usize {
    if limiter.is_constant() {
        1_000_000
    } else {
        250_000
    }
}

/// SOR sweeps [`Solver::Auto`] runs on a grid below [`auto_multigrid_voxels`] before it hands
/// the solve to multigrid. *Why*: a multigrid solve of the measured problems cost 26–60
/// work units of about 3 SOR sweeps each when this was set (2026-12-06, `multigrid/HISTORY.md`;
/// since the FMG start a CDA point-source solve is about 12), i.e. 80–180 sweeps
/// of wall time; a solve that SOR has not finished in 200 sweeps is one where multigrid
/// would have been about as fast or faster, and running SOR first bounds what the switch
/// can lose to 200 sweeps (the datasets of `convergence_check` at 18³: CDA 0.002–0.004 s
/// by SOR against 0.005 s by multigrid, but `shell_core` 0.74 s against 0.0096 s).
pub const AUTO_SOR_SWEEPS: usize = 200;

impl Solver {
    /// `sor`, `multigrid` or `auto`.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Sor => "sor",
            Self::Multigrid(_) => "multigrid",
            Self::Auto(_) => "auto",
        }
    }
}

/// As [`solve`] with the solver chosen by `solver`; multigrid on a GPU backend is
/// [`SolverError::Unsupported`].
pub fn solve_with(
    backend: &Backend<'_>,
    medium: &Medium<f64>,
    boundary: &Boundary<f64>,
    config: &FldConfig,
    solver: &Solver,
    observer: impl FnMut(usize, f64),
) -> Result<FldSolution<f64>, SolverError> {
    match solver {
        Solver::Sor => solve(backend, medium, boundary, config, observer),
        Solver::Multigrid(mg) => solve_multigrid(backend, medium, boundary, config, mg, observer),
        Solver::Auto(mg) => solve_auto(backend, medium, boundary, config, mg, observer),
    }
}

/// [`Solver::Multigrid`] on any backend.
fn solve_multigrid(
    backend: &Backend<'_>,
    medium: &Medium<f64>,
    boundary: &Boundary<f64>,
    config: &FldConfig,
    mg: &multigrid::MgConfig,
    observer: impl FnMut(usize, f64),
) -> Result<FldSolution<f64>, SolverError> {
    match backend {
        Backend::Cpu(Precision::F64) => {
            Ok(CpuMultigrid::new(medium, boundary, config, mg)?.solve_observed(observer))
        }
        Backend::Cpu(Precision::F32) => {
            Ok(
                CpuMultigrid::<f32>::new(&medium.cast(), &boundary.cast(), config, mg)?
                    .solve_observed(observer)
                    .widen_with(|t| t),
            )
        }
        Backend::Gpu(ctx) => {
            Ok(
                multigrid::GpuMultigrid::new(ctx, &medium.cast(), &boundary.cast(), config, mg)?
                    .solve_observed(observer)?
                    .widen_with(|t| t),
            )
        }
    }
}

/// [`Solver::Auto`]: SOR or multigrid by the grid's size, the other when the first does not
/// finish (see the variant's docs).
fn solve_auto(
    backend: &Backend<'_>,
    medium: &Medium<f64>,
    boundary: &Boundary<f64>,
    config: &FldConfig,
    mg: &multigrid::MgConfig,
    mut observer: impl FnMut(usize, f64),
) -> Result<FldSolution<f64>, SolverError> {
    if config.vacuum_face == VacuumFace::Marshak {
        // Multigrid has the paper's face only.
        return solve(backend, medium, boundary, config, observer);
    }
    let mut before = Spent::default();
    if medium.grid.len() < auto_multigrid_voxels(config.limiter) {
        let budget = FldConfig {
            max_iterations: config.max_iterations.min(AUTO_SOR_SWEEPS),
            ..config.clone()
        };
        let sor = solve(backend, medium, boundary, &budget, &mut observer)?;
        if sor.stop != Stop::Cap || budget.max_iterations == config.max_iterations {
            return Ok(sor);
        }
        before.add(&sor);
    }
    let last = match solve_multigrid(backend, medium, boundary, config, mg, &mut observer) {
        Ok(m) if m.converged() => m,
        Ok(m) => {
            before.add(&m);
            solve(backend, medium, boundary, config, &mut observer)?
        }
        // Multigrid cannot run here (`Unsupported` settings, its memory budget): SOR can.
        Err(SolverError::Unsupported(_) | SolverError::TooLarge(_)) => {
            solve(backend, medium, boundary, config, &mut observer)?
        }
        Err(e) => return Err(e),
    };
    Ok(before.onto(last))
}

/// What the solvers [`Solver::Auto`] ran before its last one cost (their φ is dropped).
#[derive(Default)]
struct Spent {
    solvers: Vec<String>,
    seconds: f64,
    setup_seconds: f64,
    work_units: f64,
}

impl Spent {
    fn add(&mut self, s: &FldSolution<f64>) {
        self.solvers.push(s.trace.solver.clone());
        self.seconds += s.seconds;
        self.setup_seconds += s.setup_seconds;
        self.work_units += s.trace.work_units;
    }

    /// `last` with these costs added and every solver named in [`FldTrace::solver`].
    fn onto(mut self, mut last: FldSolution<f64>) -> FldSolution<f64> {
        last.trace.seconds_to_tolerance = last.trace.seconds_to_tolerance.map(|t| t + self.seconds);
        last.seconds += self.seconds;
        last.setup_seconds += self.setup_seconds;
        last.trace.work_units += self.work_units;
        self.solvers.push(std::mem::take(&mut last.trace.solver));
        last.trace.solver = self.solvers.join(">");
        last
    }
}

/// FLD's part of a [`Solution`]: the residual history and the work it cost.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FldTrace {
    /// Normalised RMS residual R̄/j̄ after each iteration (index 0 = after iteration 1).
    pub residuals: Vec<f64>,
    /// Work in fine red-black sweeps: SOR's iterations; for multigrid every smoothing
    /// sweep on level ℓ counts 8^(−ℓ) ([`multigrid::CpuMultigrid::work_units`]; the
    /// transfers and residuals are not counted, the seconds are the full cost).
    pub work_units: f64,
    /// Wall-clock seconds from the start of the solve (setup excluded, as in
    /// [`Solution::seconds`]) until R̄/j̄ itself first fell below the tolerance; `None` if
    /// it never did or the solver does not time it (the GPU solvers). *Why*: SOR stops on
    /// R̄/j̄ alone, multigrid on R̄/j̄ and its error estimate (often one cycle more), so this
    /// is the like-for-like time to R̄/j̄ < tolerance that issue 15's acceptance 3 compares.
    pub seconds_to_tolerance: Option<f64>,
    /// The solver that produced φ: `sor` or `multigrid`; for [`Solver::Auto`] every solver
    /// that ran, in order, joined by `>` (e.g. `multigrid>sor`: multigrid did not converge
    /// and SOR solved from scratch).
    pub solver: String,
}

impl FldTrace {
    /// The last solver that ran (the part of [`FldTrace::solver`] after the last `>`).
    pub fn solver_name(&self) -> &'static str {
        match self.solver.rsplit('>').next() {
            Some("multigrid") => "multigrid",
            _ => "sor",
        }
    }
}

/// The result of a diffusion solve: φ, iterations ([`Solution::steps`]), why it stopped,
/// and the residual history in [`Solution::trace`].
pub type FldSolution<T> = Solution<T, FldTrace>;

impl<T> Solution<T, FldTrace> {
    /// The normalised residual after each iteration.
    pub fn residuals(&self) -> &[f64] {
        &self.trace.residuals
    }

    /// The last normalised residual (∞ if no iteration ran).
    pub fn final_residual(&self) -> f64 {
        self.trace
            .residuals
            .last()
            .copied()
            .unwrap_or(f64::INFINITY)
    }
}

/// The stopping rule every FLD solver loop shares: `step()` does one iteration (SOR) or
/// cycle (multigrid) and returns (iterations so far, R̄/j̄), starting from `start` done;
/// `observer` sees each. Stops at `max` iterations ([`Stop::Cap`]), a non-finite residual,
/// R̄/j̄ < `tolerance`, or, with
/// `stall = Some(k)`, after k steps in a row without cutting the best residual by 10 %.
pub(crate) fn iterate(
    start: usize,
    max: usize,
    tolerance: f64,
    stall: Option<usize>,
    mut step: impl FnMut() -> (usize, f64),
    mut observer: impl FnMut(usize, f64),
) -> Stop {
    let (mut best, mut since) = (f64::INFINITY, 0usize);
    let mut done = start;
    while done < max {
        let (k, r) = step();
        done = k;
        observer(k, r);
        if !r.is_finite() {
            return Stop::NonFinite;
        }
        if r < tolerance {
            return Stop::Converged;
        }
        if let Some(limit) = stall {
            if r < 0.9 * best {
                (best, since) = (r, 0);
            } else {
                since += 1;
                if since >= limit {
                    return Stop::Stalled;
                }
            }
        }
    }
    Stop::Cap
}

/// Assembles a solution (CPU and GPU kernels): `last_change` is the final residual.
#[allow(clippy::too_many_arguments)]
pub(crate) fn solution<T>(
    grid: Grid,
    phi: Vec<T>,
    residuals: Vec<f64>,
    iterations: usize,
    stop: Stop,
    seconds: f64,
    setup_seconds: f64,
    timer: Timer,
) -> FldSolution<T> {
    Solution {
        grid,
        phi,
        steps: iterations,
        last_change: residuals.last().copied().unwrap_or(f64::INFINITY),
        stop,
        seconds,
        setup_seconds,
        timer,
        balance: None,
        trace: FldTrace {
            residuals,
            work_units: iterations as f64,
            seconds_to_tolerance: None,
            solver: "sor".into(),
        },
    }
}
