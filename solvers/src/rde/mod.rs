//! Unsteady radiance diffusion (RDE) by FTCS finite differences (Murray, *Legible
//! Visualization of Semi-Transparent Objects using Light Transport*, thesis Ch. 4; the
//! verification spec is `../shared/specs/rde.md`).
//!
//! ## The thesis's equations
//! The P1 moments of the unsteady RTE (thesis Eqs 3.23–3.24) with a quasi-steady flux give
//! Fick's law E = −D∇φ, D = 1/(3K′t), K′t = Ka + (1 − g)Ks (thesis Eqs 4.1–4.2), and
//!
//! (1/c) ∂φ/∂t = ∇·(D∇φ) − Ka φ + φe   (the unnumbered equation before thesis Eq 4.3).
//!
//! Thesis Eq 4.3 expands it as D∆φ **−** ∇D·∇φ − Kaφ + φe; the correct sign is **+**
//! (∇·(D∇φ) = D∆φ + ∇D·∇φ), and the − is carried into the FTCS of thesis Eq 4.4 and its
//! reparametrisation thesis Eq 4.8 with α = Ks/Kt (thesis Eq 4.5), Ka = (1 − α)/(3(1 − αg)D)
//! (thesis Eq 4.6) and β = D/∆ (thesis Eq 4.7):
//!
//! φᵗ = φe + [1 − r(1 − α)/(3(1 − αg)β) − 6βr] φᵗ⁻¹ + βr Σ₆ φᵗ⁻¹ − (r/4) Σ_axes (β₊ − β₋)(φ₊ − φ₋)ᵗ⁻¹,
//!
//! with r = c∆t/∆. The thesis's stability condition (thesis Eq 4.9, Fig 4.1) asks the explicit
//! update matrix to be diagonally dominant with the worst case |∆β| = 1 per axis:
//! r ≤ 6β/(72β² + 9β + 2(1 − α)) ([`eq_4_9_printed`]; [`eq_4_9`] is the same inequality with
//! the voxel's own a = Ka∆, 1/(a + 12β + 3/2)).
//!
//! ## What this module computes
//! In grid units (a = Ka∆, the voxel's absorption optical depth; s = ∆q for a volume source q
//! in power per volume) one step is φ ← φ + r B(φ) with
//! B_p = s_p − a_p φ_p + L(φ)_p and, by [`Operator`]:
//! * `Conservative` (default): L = Σ_s β_ps (φ_s − φ_p), β_ps = (β_p + β_s)/2, exactly FLD
//!   Eq 31's D_ps = (D_p + D_s)/2, i.e. the divergence form. Its steady state solves CDA's
//!   linear system (FLD Eq 32 with F = 1/3).
//! * `ThesisExpanded`: L = β_p Σ_s (φ_s − φ_p) **+** ¼ Σ_axes (β₊ − β₋)(φ₊ − φ₋) (thesis
//!   Eq 4.8, sign fixed).
//! * `ThesisVerbatim`: the same with **−** (thesis Eq 4.8 as printed; reproduction only).
//!
//! The three are the same discrete operator in a homogeneous medium. Physical inputs
//! ([`Coefficients::from_medium`]): β = 1/(3σt(1 − αg)∆), a = (1 − α)σt∆; the thesis's maps
//! ([`Coefficients::from_maps`]): β ∈ [0, 1] and a ≥ 0 per voxel directly.
//!
//! * [`RdeConfig`]: operator, [`BoundaryCondition`], [`TimeStep`], [`StepCheck`], [`Run`].
//! * [`cpu::CpuRde`]: the rayon kernel, generic over `f32`/`f64`, deterministic for any
//!   thread count (ping-pong buffers; residual partials summed in slab order).
//! * [`gpu::GpuRde`]: the wgpu kernel (f32, `rde.wgsl`), same layout and arithmetic.
//! * [`solve`]: backend dispatch; [`RdeSolution`] carries steps, r, the physical time
//!   ([`RdeTrace::light_path`] = n·c∆t), the bounds and counts of the medium.
//! * [`method::RdeMethod`]: the steady RDE as a registered method (`rde[:expanded|verbatim]`).
//! * [`pm`]: Perona–Malik selective diffusion (thesis Eqs 3.1–3.5) and the containment
//!   phantoms; [`p1`], [`fe`]: the thesis's P1 and FE schemes as negative controls;
//!   [`dvr`]: thesis-style images (thesis Eqs 1.12–1.14; illustration only).
//! * Experiments `rde_stability` (thesis Fig 4.1 with the measured critical r) and
//!   `rde_steady` (steady state vs CDA, time to tolerance vs CDA-SOR, phantom containment);
//!   bench `benches/benches/rde.rs` (one FTCS step against the triad probe).
//!
//! ## Time step
//! r_G = 2/max_p(a_p + 2Σ_s β_ps) (Gershgorin, sufficient for the symmetric conservative
//! operator; tight in uniform media), r_pos = 1/max_p(a_p + Σ_s β_ps) (every weight ≥ 0),
//! and min_p thesis Eq 4.9 are computed per medium ([`StepBounds`], in every solution's trace).
//! [`TimeStep::Gershgorin`] (default, safety 0.9), [`TimeStep::Fixed`] (rejected above r_G
//! with [`SolverError::StepAboveBound`] naming `r`; [`StepCheck::Eq49Strict`] also rejects it
//! above Eq 4.9), [`TimeStep::Local`] (r_p = safety/(a_p + Σβ_ps): damped Jacobi, same steady
//! state, non-physical transient; [`RdeTrace::light_path`] is NaN).
//!
//! ## Stopping rule
//! Two rules ([`SteadyStop`], [`RdeConfig::stop`]); [`crate::method::Tolerance::rel`] maps
//! to tol one to one (see [`method`]).
//! * [`SteadyStop::Residual`] (the low-level default, `rde` with `stop=0`): R̄/j̄ < tol with
//!   R_p = (φⁿ⁺¹_p − φⁿ_p)/(c∆t) = B_p/∆ evaluated before the update: FLD Eq 37's residual of
//!   the same equation, with FLD's RMS window (interior minus `residual_margin` voxels) and j̄
//!   normalisation, through the code FLD uses (`fld::residual`); the window is every interior
//!   voxel (margin 0, changed with FLD's, see the `fld` module docs).
//! * [`SteadyStop::ErrorBound`] (the registered `rde`'s default, `stop=1`): every m =
//!   [`RdeConfig::check_every`] (32) steps, the estimated relative error of φ,
//!   ‖φ_k − φ_{k−1}‖/‖φ_k‖ · 1/(1 − ρ̂) with ρ̂ the larger of the last two block contractions
//!   ‖φ_k − φ_{k−1}‖/‖φ_{k−1} − φ_{k−2}‖ ([`ErrorBound`]), < tol. Same blocks on the CPU and
//!   the GPU (φ read back after each block there); the residual is still recorded every step.
//!
//! *Why the default changed* (issue 12 items 3–4, a decision where the thesis is silent: it
//! steps a fixed number of frames). Measured with the residual stop at rel = 10⁻⁴
//! (`experiments convergence_check`, before this change): the steady RDE stopped within
//! 2·10⁻⁷ of its tight solve on nebula, emissive_cloud and plume, but 45 % (σt·Δl = 6, 17
//! steps) and 49 % (60, 6 steps) from it on issue 12's albedo-1 16³ cubes, and ran to the cap
//! 34 % off on shell_core. With the local step the lit surface voxels (large r_p = safety/(a +
//! Σβ), β small in thick voxels) relax in a few steps and the residual drops by 10⁴, while the
//! slow diffusion mode of the interior contracts by only 0.67–0.88 per step (8³ cube at
//! σt·Δl = 6): the residual of the stiff Jacobi iteration is small while the error is large
//! (at rel = 10⁻⁸ still 2.6 % at σt·Δl = 60). With the error bound at rel = 10⁻⁴ (test
//! `solvers/tests/rde_default_stop.rs`, 16³ cubes vs CDA's SOR at 10⁻¹⁰, f64 and f32): 2.8·10⁻⁵
//! (σt·Δl = 0.6, 512 steps; residual stop 7.4·10⁻⁴ in 348), 3.6·10⁻⁵ (6, 480 steps; residual
//! stop 0.45 in 17), 4.9·10⁻⁵ (60, 448 steps; 0.49 in 6). The `rde` rows of
//! `results/convergence_check` are re-measured with it. `Frames(n)` runs n steps (the thesis's one step per frame) with snapshots.
//!
//! ## Decisions where the paper is silent (each with its measurement and test, `tests.rs`)
//! * **Conservative operator by default.** In homogeneous media all three operators give
//!   CDA's steady state: max|∆φ|/max φ = 3.6·10⁻¹² (α = 0.9, 878 steps) and 1.2·10⁻¹¹
//!   (α = 0.99, 3367 steps) in f64 at R̄/j̄ < 10⁻¹¹, 33³ (test `a1_…`). In a smooth β bump
//!   (0.5 → 0.9 over ≈ 8 voxels) `Conservative` equals CDA to 4.7·10⁻¹², `ThesisExpanded`
//!   differs by 1.6·10⁻³ (relative L2), and that difference falls 3.86× when ∆ halves at fixed
//!   physical D (5.87·10⁻³ → 1.52·10⁻³, second order; `a2_…`). Across a one-voxel step
//!   β 0.1 | 0.9 the expanded form has negative neighbour weights on the whole plane
//!   (|β₊ − β₋| > 4β_p, counted in [`RdeTrace::expanded_violations`]; `a3_…`), the
//!   conservative one equals CDA (3.3·10⁻¹²) and stays ≥ 0. With random voxel-scale
//!   β ∈ U[0.01, 1] at α = 1 and r = 0.02 (inside Eq 4.9's 0.074) `ThesisExpanded` grew
//!   1.3·10¹²× (3D 10³) and 8.1·10²⁰× (2D 22², Neumann) in 20 000 steps while
//!   `Conservative` decayed (0.72, 0.093; `b8_…`); over seeds 0–7 of a similar generator it
//!   grew > 10³× in 4/8 (3D) and 7/8 (2D) media, `ThesisVerbatim` in 6/8 (3D), the
//!   conservative form in none. It is also the only one that conserves per step (imbalance
//!   1.1·10⁻¹⁵ vs 2.3·10⁻² expanded; `d14_…`) and is reciprocal (asymmetry 3.6·10⁻¹³ vs 0.11;
//!   `d17_…`).
//! * **Boundary.** The thesis states none. Dirichlet (default): the outermost layer holds its
//!   initial values (0 without an initial field, as CDA's `Boundary::Zero`) and is never
//!   updated; its β enters the face coefficient as CDA's D does. With the Dirichlet values of
//!   FLD Eq 27 a point source matches FLD Eq 27's shells beyond 3 voxels within 5.4·10⁻³
//!   (f64) and 7.9·10⁻³ (f32) (`a5_…`, bound 2 %). Neumann: clamp-to-edge, every voxel
//!   updated, no flux through the walls (tested against the plain update).
//! * **Time step.** Default 0.9 r_G. In uniform 16³ Dirichlet media over a 10 × 10 (β, α)
//!   grid the top Dirichlet mode decays by exactly 1 − r(a + 12β cos²(π/(2(N+1)))) per step
//!   (10⁻¹²), grows at 1.02 r_crit and decays at 0.98 r_crit; r_crit/r_G ≥ 1.0009 and
//!   Eq 4.9 < r_crit everywhere (`b6_…`). At r = r_G the conservative update never increased
//!   ‖φ‖₂ in 5000 steps on a β step, random β, a voxel checkerboard and the thesis's gradient
//!   mapping of a tube (`b7_…`). The thesis's r = 0.1 on β = 1, α = 0 exceeds Eq 4.9 (0.072)
//!   but not r_G (0.162): accepted by default, rejected by `Eq49Strict`; 0.2 rejected by both
//!   (`b9_…`). Positivity holds only up to r_pos, which the default exceeds where a > 1.5β;
//!   [`RdeTrace::min_phi`] records the final minimum; at r = r_pos φ stayed ≥ 0 at every step
//!   on media with 10⁴ β contrast and a up to 10 (`d16_…`).
//! * **Sources.** q is a volume source (power per volume) added as r∆q per step, so the steady
//!   state does not depend on ∆t: r and r/2 agree to 3.9·10⁻¹³ (741 and 1493 steps; `a4_…`).
//!   A [`PointSource`] of power P is q = P/∆³ in its voxel; negative power is the thesis's
//!   negative source (Fig 4.7) and makes the source signed ([`Coefficients::signed_source`],
//!   φ < 0 allowed): mirrored about the midplane of a mirrored medium it gives φ = 0 there
//!   exactly (0.0 in f32 and f64; `f22_…`). Painting (thesis Fig 4.8) makes every visited
//!   voxel a source once: the union of the path (`f23_…`). The thesis's limit of 8 sources is
//!   a UI limit and not enforced. Forcing ([`Coefficients::force`]) turns the voxels that
//!   reached a fraction of max φ into an extended source (our reading of §4.2.5, which gives
//!   no rule); it changes the converged field, as the thesis says (`f24_…`).
//! * **Transient.** A unit pulse (β = 0.5, a = 0.01, 65³) keeps Σφ = (1 − ra)ⁿ to 4·10⁻⁹ and
//!   matches (4πβτ)^{−3/2}e^{−R²/(4βτ)}(1 − ra)ⁿ, τ = nr, to 3.7·10⁻³ (r = 0.1) and 6.7·10⁻³
//!   (r = 0.3) relative L2 beyond 2 voxels (`d15_…`); the discrete decay (1 − ra)ⁿ is used,
//!   not e^{−aτ}.
//! * **β cap.** The physical API caps β at [`BETA_MAX`] = 1 (σ′t∆ ≥ 1/3, the thesis's range;
//!   vacuum otherwise forces r → 0) and counts the capped voxels
//!   ([`Coefficients::beta_capped`]). **Overturned for the registered method**: on
//!   `scenes/cloud_directional.toml --quick` (18³ solve grid) the cap makes the
//!   multiple-scattering image 5.26× CDA's (relative L2 3.7), because vacuum and thin voxels
//!   diffuse with D = ∆ instead of streaming; β ≤ 10 gives 1.60×, β ≤ 100 1.05× but needs
//!   15 891 global steps. The method therefore uses CDA's cap 1/(3σ_ε∆) (σ_ε = 10⁻³/L) and the
//!   local step: its steady state is CDA's system, reached in 493 steps, and the image is
//!   within 2.0·10⁻⁵ (relative L2) of CDA's (CDA's SOR: 59 iterations). `local=0 beta_max=1`
//!   gives the thesis's FTCS (448 steps, the 5.26× image).
//! * **Normalisation.** The run is on q/j̄ (or, without a source, on φ₀/max|φ₀|·∆), as FLD:
//!   φ(λq)/λ = φ(q) to rounding for λ = 10⁻³⁰ … 10³⁰ in f32 and f64 (`d18_…`).
//! * **GPU.** Same layout and arithmetic as the CPU; ping-pong buffers, one dispatch per
//!   step, residual reduced on the GPU in a fixed order. On lavapipe the GPU equals CPU f32
//!   bitwise after 200 steps for every operator, boundary and step mode; at steady state both
//!   f32 backends lie 1.0·10⁻⁷ from f64 (bound 10ε₃₂/(rλ₁) = 9.1·10⁻⁵); step counts to
//!   R̄/j̄ < 10⁻⁴ agree (463, 463); 10 GPU steps equal the double-buffered CPU result to
//!   1.1·10⁻⁷ where an in-place update differs by 9.8·10⁻² (`e19_e21_…`).
//! * **P1 control** ([`p1`], thesis Eqs 3.23–3.26): Ka in the φ row and K′t in the E row
//!   (`verbatim` switch for the printed Kt). A one-voxel source leaves φ and E exactly 0.0 off
//!   their sublattices after 1, 10 and 4000 steps (f32 and f64), and the steady φ on the
//!   source sublattice equals CDA on the coarse grid H = 2∆ to 1.3·10⁻¹⁴ (f64; `c10_…`). The
//!   detector ([`p1::Checkerboard`]) reads off-sublattice fraction 0 and Nyquist-plane energy
//!   0.300 for P1, 0.831 and 0.0355 for the RDE (19³; `c11_…`). The exact von Neumann bound
//!   ([`p1::p1_critical_r`]) is 0.3626 at β = 1, α = 0.9 and 1.0 at β = 1/3; the run the
//!   thesis's criterion admits there (r = 1.0) grows 1.9·10³× from step 30 to 60 with the row
//!   through the source reading + 0 − 0 + …, as in thesis Fig 3.6(a) (`c12_…`). The
//!   Fig 3.6(b) control ([`p1::P1Stencil::Sobel`], weights (1, 2, 1)/4 across each
//!   difference, our choice: the thesis gives none) couples the sublattices (off-sublattice
//!   0.707) but keeps Nyquist-plane energy 0.244 and negative lobes (min/max φ = −0.133), so
//!   the detector still flags it (`c11_…`).
//! * **FE control** ([`fe`], thesis Eqs 3.16–3.22): on a uniform field the Jacobi iteration
//!   multiplies by exactly −5/4 (2D) and −19/8 (3D) for Kt∆ ∈ {1, 10, 100}; from a random
//!   start on a periodic 6³ grid it grows 2.475× (Kt∆ = 1) and 21.7× (Kt∆ = 0.1) per
//!   iteration (`c13_…`), the sign alternation of thesis Fig 3.5.
//! * **Perona–Malik** ([`pm`], thesis Eqs 3.1–3.5): energy diffused with conductances from
//!   the data volume, clamped source, Neumann walls, capped iterations, and the synthetic
//!   containment phantoms of spec §3 (gap in an edge, tube, step edge) with leak and fill
//!   fractions. With Neumann walls the steady E equals E_src on the connected region to
//!   2.1·10⁻¹¹ (f64), and the flood time across an edge scales as 1/C(edge) within 1.07 over
//!   σ ∈ {0.05, 0.1, 0.2} (`f25_…`; measurements in [`pm`]).
//! * **Typos and units** (thesis): the printed δy, δz definitions, "does vary in time" for
//!   Qe, N/S swapped between Ch. 3 and Ch. 4 (Ch. 4's N = (i + 1, j, k) is used), and φe
//!   "incorporating c∆t" (here q, with the c∆t = r∆ factor applied by the step).
pub mod cpu;
pub mod dvr;
pub mod fe;
pub mod gpu;
pub mod method;
pub mod p1;
pub mod pm;

pub use cpu::CpuRde;
pub use gpu::GpuRde;
pub use method::{RDE, RdeMethod};

use crate::fld::residual::ResidualWindow;
use crate::gpu::Timer;
use crate::method::{Solution, Stop};
use crate::{Backend, Grid, Medium, Precision, Real, SolverError};

/// The spatial operator of the FTCS update (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Operator {
    /// Divergence form Σ_s β_ps (φ_s − φ_p) with face coefficients β_ps = (β_p + β_s)/2, as
    /// FLD Eq 31's D_ps: conservative, symmetric, positive for r ≤ r_pos.
    #[default]
    Conservative,
    /// Thesis Eq 4.8 with the sign of the ∇β·∇φ term fixed to +.
    ThesisExpanded,
    /// Thesis Eq 4.8 exactly as printed (− sign): reproduction only.
    ThesisVerbatim,
}

impl Operator {
    /// All three, in declaration order.
    pub const ALL: [Operator; 3] = [
        Operator::Conservative,
        Operator::ThesisExpanded,
        Operator::ThesisVerbatim,
    ];

    /// `conservative`, `expanded` or `verbatim`.
    pub fn name(self) -> &'static str {
        match self {
            Operator::Conservative => "conservative",
            Operator::ThesisExpanded => "expanded",
            Operator::ThesisVerbatim => "verbatim",
        }
    }

    /// The id of the `OP` override constant of `rde.wgsl` (and the CPU kernel's const
    /// parameter).
    pub(crate) fn id(self) -> u8 {
        match self {
            Operator::Conservative => 0,
            Operator::ThesisExpanded => 1,
            Operator::ThesisVerbatim => 2,
        }
    }
}

/// What holds at the grid's outer faces.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BoundaryCondition {
    /// φ = 0 on the outermost voxel layer, which is never updated; its β enters the face
    /// coefficients (the CDA layout of `fld::Boundary::Zero`).
    #[default]
    Dirichlet,
    /// Zero flux (clamp-to-edge): every voxel is updated, and a neighbour outside the grid is
    /// the voxel itself.
    Neumann,
}

/// How r = c∆t/∆ is chosen.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TimeStep {
    /// r = safety · r_G, r_G = 2/max_p(a_p + 2Σ_s β_ps) (Gershgorin bound of the conservative
    /// operator). The default, safety 0.9.
    Gershgorin {
        /// Factor in (0, 1].
        safety: f64,
    },
    /// A given r (the thesis's 0.1), rejected with [`SolverError::StepAboveBound`] above r_G.
    Fixed(f64),
    /// Local time step r_p = safety/(a_p + Σ_s β_ps): damped Jacobi. The steady state is the
    /// same; the transient is not physical.
    Local {
        /// Factor in (0, 1].
        safety: f64,
    },
}

impl Default for TimeStep {
    fn default() -> Self {
        TimeStep::Gershgorin { safety: 0.9 }
    }
}

/// Which bound a time step is checked against.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum StepCheck {
    /// The Gershgorin bound r_G of the conservative operator (sufficient for it).
    #[default]
    Gershgorin,
    /// Also thesis Eq 4.9 at every updated voxel (with the thesis's worst case |∆β| = 1):
    /// `Fixed` above it is an error, `Gershgorin` and `Local` are capped by it.
    Eq49Strict,
    /// No check: `Fixed` may exceed every bound (stability experiments and tests only).
    Unchecked,
}

/// How long to run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Run {
    /// Until R̄/j̄ (FLD Eq 37's normalised residual) < `tolerance` or `max_steps`.
    Steady {
        /// `None`: [`Real::DEFAULT_TOLERANCE`] (10⁻⁶ f64, 10⁻⁴ f32). 0 runs `max_steps`.
        tolerance: Option<f64>,
        /// Step cap.
        max_steps: usize,
    },
    /// Exactly `steps` steps (the thesis's one step per frame), φ kept every
    /// `snapshot_every` steps (0: none).
    Frames {
        /// Steps to run.
        steps: usize,
        /// Snapshot interval (0: no snapshots).
        snapshot_every: usize,
    },
}

impl Default for Run {
    fn default() -> Self {
        Run::Steady {
            tolerance: None,
            max_steps: 100_000,
        }
    }
}

/// Solver settings.
#[derive(Debug, Clone, PartialEq)]
pub struct RdeConfig {
    /// The spatial operator.
    pub operator: Operator,
    /// Outer boundary.
    pub boundary: BoundaryCondition,
    /// How r is chosen.
    pub time_step: TimeStep,
    /// What r is checked against.
    pub check: StepCheck,
    /// Run mode.
    pub run: Run,
    /// Voxels next to the boundary layer left out of the RMS residual, as
    /// `FldConfig::residual_margin` (default 0, as there).
    pub residual_margin: usize,
    /// GPU: steps recorded per submission before the state is read back; with
    /// [`SteadyStop::ErrorBound`] also the block length of the error estimate (both backends).
    pub check_every: u32,
    /// What ends a `Steady` run.
    pub stop: SteadyStop,
}

/// What ends a [`Run::Steady`] run (module docs, "Stopping rule").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SteadyStop {
    /// R̄/j̄ (FLD Eq 37's normalised residual) < tolerance: the low-level default, as FLD.
    #[default]
    Residual,
    /// The estimated relative error of φ, ‖φⁿ − φⁿ⁻ᵐ‖/‖φⁿ‖ · 1/(1 − ρ̂) with m =
    /// [`RdeConfig::check_every`] and ρ̂ the larger of the last two measured block
    /// contractions ([`ErrorBound`]), < tolerance; the registered `rde`'s default.
    ErrorBound,
}

/// The error estimate of [`SteadyStop::ErrorBound`], fed the field every m steps: with
/// d_k = ‖φ_k − φ_{k−1}‖ (L2 over every voxel) and ρ_k = d_k/d_{k−1} the measured contraction
/// of one block, ρ̂ = max(ρ_k, ρ_{k−1}); while ρ̂ < 1 the remaining error of a linear
/// iteration contracting by ρ̂ per block is at most d_k ρ̂/(1 − ρ̂) ≤ d_k/(1 − ρ̂), and the
/// estimate is that bound over ‖φ_k‖ (∞ until two contractions are known or while ρ̂ ≥ 1).
/// Sums in f64 in voxel order: deterministic for any thread count.
#[derive(Debug, Clone, Default)]
pub struct ErrorBound {
    prev: Vec<f64>,
    d: Option<f64>,
    rho: Option<f64>,
}

impl ErrorBound {
    /// Feeds φ after the next block; returns the estimated relative error.
    pub fn observe<T: Real>(&mut self, phi: &[T]) -> f64 {
        if self.prev.len() != phi.len() {
            self.prev = phi.iter().map(|x| x.f()).collect();
            return f64::INFINITY;
        }
        let (mut dd, mut pp) = (0.0, 0.0);
        for (x, p) in phi.iter().zip(self.prev.iter_mut()) {
            let x = x.f();
            dd += (x - *p) * (x - *p);
            pp += x * x;
            *p = x;
        }
        let d = dd.sqrt();
        let rho = self.d.map(|d0| if d0 > 0.0 { d / d0 } else { 0.0 });
        let est = match (rho, self.rho) {
            _ if d == 0.0 => 0.0,
            (Some(r1), Some(r0)) => {
                let r = r1.max(r0);
                if r < 1.0 && pp > 0.0 {
                    d / pp.sqrt() / (1.0 - r)
                } else {
                    f64::INFINITY
                }
            }
            _ => f64::INFINITY,
        };
        self.d = Some(d);
        self.rho = rho;
        est
    }
}

impl Default for RdeConfig {
    fn default() -> Self {
        Self {
            operator: Operator::Conservative,
            boundary: BoundaryCondition::Dirichlet,
            time_step: TimeStep::default(),
            check: StepCheck::Gershgorin,
            run: Run::default(),
            residual_margin: 0,
            check_every: 32,
            stop: SteadyStop::Residual,
        }
    }
}

impl RdeConfig {
    /// Builder: operator.
    pub fn with_operator(mut self, op: Operator) -> Self {
        self.operator = op;
        self
    }

    /// Builder: boundary condition.
    pub fn with_boundary(mut self, b: BoundaryCondition) -> Self {
        self.boundary = b;
        self
    }

    /// Builder: time step.
    pub fn with_time_step(mut self, t: TimeStep) -> Self {
        self.time_step = t;
        self
    }

    /// Builder: step check.
    pub fn with_check(mut self, c: StepCheck) -> Self {
        self.check = c;
        self
    }

    /// Builder: run to R̄/j̄ < `tol` or `max_steps`.
    pub fn steady(mut self, tol: f64, max_steps: usize) -> Self {
        self.run = Run::Steady {
            tolerance: Some(tol),
            max_steps,
        };
        self
    }

    /// Builder: what ends a `Steady` run.
    pub fn with_stop(mut self, stop: SteadyStop) -> Self {
        self.stop = stop;
        self
    }

    /// Builder: exactly `steps` steps, snapshots every `snapshot_every` (0: none).
    pub fn frames(mut self, steps: usize, snapshot_every: usize) -> Self {
        self.run = Run::Frames {
            steps,
            snapshot_every,
        };
        self
    }

    /// Checks every parameter.
    pub fn validate(&self) -> Result<(), SolverError> {
        let bad = |name, value, reason| {
            Err(SolverError::BadParameter {
                name,
                value,
                reason,
            })
        };
        match self.time_step {
            TimeStep::Gershgorin { safety } | TimeStep::Local { safety } => {
                if !(safety > 0.0 && safety <= 1.0) {
                    return bad(
                        "safety",
                        safety,
                        "the time-step safety factor must be in (0, 1]",
                    );
                }
            }
            TimeStep::Fixed(r) => {
                if !(r.is_finite() && r > 0.0) {
                    return bad("r", r, "r = c∆t/∆ must be finite and > 0");
                }
            }
        }
        if let Run::Steady {
            tolerance: Some(t), ..
        } = self.run
        {
            if !(t.is_finite() && t >= 0.0) {
                return bad("tolerance", t, "must be finite and ≥ 0");
            }
        }
        if self.check_every == 0 {
            return bad("check_every", 0.0, "must be at least 1");
        }
        Ok(())
    }

    /// The step cap of the run mode.
    pub fn max_steps(&self) -> usize {
        match self.run {
            Run::Steady { max_steps, .. } => max_steps,
            Run::Frames { steps, .. } => steps,
        }
    }
}

/// The largest β = D/∆ the physical API produces (σ′t∆ ≥ 1/3); larger values are capped
/// and counted (see the module docs).
pub const BETA_MAX: f64 = 1.0;

/// The per-voxel inputs of the FTCS update in the thesis's parametrisation, in `f64`, every
/// field x fastest and including the boundary layer.
#[derive(Debug, Clone, PartialEq)]
pub struct Coefficients {
    /// The grid.
    pub grid: Grid,
    /// β = D/∆ (thesis Eq 4.7), ≥ 0 ([0, 1] from the thesis maps, at most the cap from a
    /// medium).
    pub beta: Vec<f64>,
    /// a = Ka∆, the absorption optical depth of one voxel, ≥ 0.
    pub ka_dl: Vec<f64>,
    /// Volume source q (power per volume), ≥ 0 unless `signed_source`; enters each step as
    /// r∆q.
    pub source: Vec<f64>,
    /// φ at t = 0 (power per area); `None`: 0. With a Dirichlet boundary its values on the
    /// boundary layer are the Dirichlet values, held for the whole run (0 without it, as
    /// CDA's `Boundary::Zero`).
    pub initial: Option<Vec<f64>>,
    /// Voxels whose β was capped at [`BETA_MAX`] ([`Coefficients::from_medium`]).
    pub beta_capped: usize,
    /// Whether `source` may be negative (the thesis's negative sources, Fig 4.7; set by
    /// [`Coefficients::with_point_sources`] and [`Coefficients::paint`] for negative power).
    pub signed_source: bool,
}

/// An isotropic point source (thesis §4.2.5; the thesis's UI places up to 8): power `power`
/// (power units; negative for the thesis's negative sources, Fig 4.7) in one voxel, i.e.
/// q = P/∆³ there, injected as r∆q per step so the steady state does not depend on ∆t.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointSource {
    /// The voxel (i, j, k).
    pub voxel: [usize; 3],
    /// Its power P.
    pub power: f64,
}

impl Coefficients {
    /// From physical parameters: D = 1/(3σt(1 − αg)) (thesis Eq 4.2 with K′t = σt(1 − αg)),
    /// β = D/∆ capped at [`BETA_MAX`] (vacuum gets the cap), a = (1 − α)σt∆, q = the
    /// medium's emission.
    pub fn from_medium(medium: &Medium<f64>, g: f64) -> Result<Self, SolverError> {
        Self::from_medium_capped(medium, g, BETA_MAX)
    }

    /// As [`Coefficients::from_medium`] with the cap `beta_max` (≥ 1) instead of
    /// [`BETA_MAX`] (steady solves of media with vacuum, see the module docs).
    pub fn from_medium_capped(
        medium: &Medium<f64>,
        g: f64,
        beta_max: f64,
    ) -> Result<Self, SolverError> {
        medium.validate()?;
        if !(beta_max.is_finite() && beta_max >= BETA_MAX) {
            return Err(SolverError::BadParameter {
                name: "beta_max",
                value: beta_max,
                reason: "the β cap must be finite and ≥ 1",
            });
        }
        if !(g.is_finite() && g > -1.0 && g < 1.0) {
            return Err(SolverError::BadParameter {
                name: "g",
                value: g,
                reason: "the HG mean cosine must be in (−1, 1)",
            });
        }
        let dl = medium.grid.dl;
        let mut capped = 0;
        let beta = medium
            .sigma_t
            .iter()
            .zip(&medium.albedo)
            .map(|(&st, &al)| {
                let b = 1.0 / (3.0 * st * (1.0 - al * g) * dl);
                if b > beta_max || b.is_nan() {
                    capped += 1;
                    beta_max
                } else {
                    b
                }
            })
            .collect();
        let ka_dl = medium
            .sigma_t
            .iter()
            .zip(&medium.albedo)
            .map(|(&st, &al)| (1.0 - al) * st * dl)
            .collect();
        Ok(Self {
            grid: medium.grid,
            beta,
            ka_dl,
            source: medium.emission.clone(),
            initial: None,
            beta_capped: capped,
            signed_source: false,
        })
    }

    /// The thesis's user-facing maps directly: β ∈ [0, 1] and a = Ka∆ ≥ 0 per voxel, with
    /// source q ≥ 0. Validated (see [`Coefficients::validate`]).
    pub fn from_maps(
        grid: Grid,
        beta: Vec<f64>,
        ka_dl: Vec<f64>,
        source: Vec<f64>,
    ) -> Result<Self, SolverError> {
        let c = Self {
            grid,
            beta,
            ka_dl,
            source,
            initial: None,
            beta_capped: 0,
            signed_source: false,
        };
        c.validate()?;
        if let Some(index) = c.beta.iter().position(|&b| b > BETA_MAX) {
            return Err(SolverError::FieldValue {
                field: "beta",
                index,
                value: c.beta[index],
                range: "[0, 1] (thesis Eq 4.7's β = D/∆)",
            });
        }
        Ok(c)
    }

    /// A uniform medium (β, a) on `grid` without a source.
    pub fn uniform(grid: Grid, beta: f64, ka_dl: f64) -> Result<Self, SolverError> {
        let n = grid.len();
        Self::from_maps(grid, vec![beta; n], vec![ka_dl; n], vec![0.0; n])
    }

    /// Adds point sources to the volume source (q += P/∆³ in each source's voxel). A
    /// negative power makes the source signed (φ < 0 is then allowed, as the thesis intends).
    pub fn with_point_sources(mut self, sources: &[PointSource]) -> Result<Self, SolverError> {
        let g = self.grid;
        for s in sources {
            let idx = self.voxel_index(s.voxel)?;
            if !s.power.is_finite() {
                return Err(SolverError::BadParameter {
                    name: "point_source.power",
                    value: s.power,
                    reason: "must be finite",
                });
            }
            self.signed_source |= s.power < 0.0;
            self.source[idx] += s.power / g.dl.powi(3);
        }
        Ok(self)
    }

    /// Painting (thesis Fig 4.8): the source persists along a brush path; every voxel the
    /// path visits becomes a source of density `q` (power per volume), once however often it
    /// is visited, so the effective source is the union of the visited voxels.
    pub fn paint(mut self, path: &[[usize; 3]], q: f64) -> Result<Self, SolverError> {
        if !q.is_finite() {
            return Err(SolverError::BadParameter {
                name: "paint.q",
                value: q,
                reason: "must be finite",
            });
        }
        let mut visited = vec![false; self.grid.len()];
        for &v in path {
            let idx = self.voxel_index(v)?;
            if !visited[idx] {
                visited[idx] = true;
                self.source[idx] += q;
            }
        }
        self.signed_source |= q < 0.0;
        Ok(self)
    }

    /// Forcing (thesis §4.2.5, "Forcing the Diffusion"): every voxel where the current field
    /// `phi` has reached `fraction` of its maximum becomes an extended source of density `q`
    /// (added once), to speed the spread up; the converged result changes, as the thesis
    /// notes. Returns the number of voxels converted. Continue from `phi` with
    /// [`Coefficients::with_initial`].
    pub fn force(&mut self, phi: &[f64], fraction: f64, q: f64) -> Result<usize, SolverError> {
        if phi.len() != self.grid.len() {
            return Err(SolverError::FieldSize {
                field: "phi",
                expected: self.grid.len(),
                got: phi.len(),
            });
        }
        if !(fraction > 0.0 && fraction <= 1.0) {
            return Err(SolverError::BadParameter {
                name: "force.fraction",
                value: fraction,
                reason: "must be in (0, 1]",
            });
        }
        if !(q.is_finite() && q >= 0.0) {
            return Err(SolverError::BadParameter {
                name: "force.q",
                value: q,
                reason: "must be finite and ≥ 0",
            });
        }
        let max = phi.iter().fold(0.0f64, |m, x| m.max(*x));
        let mut n = 0;
        if max > 0.0 {
            for (s, &v) in self.source.iter_mut().zip(phi) {
                if v >= fraction * max {
                    *s += q;
                    n += 1;
                }
            }
        }
        Ok(n)
    }

    fn voxel_index(&self, v: [usize; 3]) -> Result<usize, SolverError> {
        let g = self.grid;
        match (0..3).find(|&a| v[a] >= g.n[a]) {
            Some(a) => Err(SolverError::BadParameter {
                name: "point_source.voxel",
                value: v[a] as f64,
                reason: "the voxel index is outside the grid",
            }),
            None => Ok(g.index(v[0], v[1], v[2])),
        }
    }

    /// Builder: the initial field.
    pub fn with_initial(mut self, phi0: Vec<f64>) -> Self {
        self.initial = Some(phi0);
        self
    }

    /// Checks sizes and ranges: β ≥ 0, a ≥ 0, q ≥ 0, initial φ finite, all
    /// finite; errors name the field and the voxel.
    pub fn validate(&self) -> Result<(), SolverError> {
        let n = self.grid.len();
        let mut fields: Vec<(&'static str, &Vec<f64>)> = vec![
            ("beta", &self.beta),
            ("ka_dl", &self.ka_dl),
            ("source", &self.source),
        ];
        if let Some(v) = &self.initial {
            fields.push(("initial", v));
        }
        for (field, v) in &fields {
            if v.len() != n {
                return Err(SolverError::FieldSize {
                    field,
                    expected: n,
                    got: v.len(),
                });
            }
        }
        let check = |field: &'static str, v: &[f64], ok: fn(f64) -> bool, range| match v
            .iter()
            .position(|&x| !ok(x))
        {
            Some(index) => Err(SolverError::FieldValue {
                field,
                index,
                value: v[index],
                range,
            }),
            None => Ok(()),
        };
        check(
            "beta",
            &self.beta,
            |x| x.is_finite() && x >= 0.0,
            "[0, ∞) (thesis Eq 4.7's β = D/∆)",
        )?;
        check(
            "ka_dl",
            &self.ka_dl,
            |x| x.is_finite() && x >= 0.0,
            "[0, ∞) (absorption Ka∆)",
        )?;
        if self.signed_source {
            check("source", &self.source, |x| x.is_finite(), "finite values")?;
        } else {
            check(
                "source",
                &self.source,
                |x| x.is_finite() && x >= 0.0,
                "[0, ∞)",
            )?;
        }
        if let Some(v) = &self.initial {
            check("initial", v, |x| x.is_finite(), "finite values")?;
        }
        Ok(())
    }

    /// Whether voxel `idx` is updated under `bc` (Dirichlet: interior only).
    pub fn is_updated(&self, bc: BoundaryCondition, idx: usize) -> bool {
        let [i, j, k] = self.grid.coords(idx);
        bc == BoundaryCondition::Neumann || !self.grid.is_boundary(i, j, k)
    }

    /// Σ_s β_ps over the faces of voxel `idx` that carry flux under `bc` (β_ps = (β_p + β_s)/2;
    /// Neumann: faces to outside the grid carry none).
    pub fn face_sum(&self, bc: BoundaryCondition, idx: usize) -> f64 {
        let g = &self.grid;
        let [i, j, k] = g.coords(idx);
        let p = [i, j, k];
        let mut sum = 0.0;
        for axis in 0..3 {
            for dir in [-1i64, 1] {
                let x = p[axis] as i64 + dir;
                if x < 0 || x >= g.n[axis] as i64 {
                    debug_assert_eq!(bc, BoundaryCondition::Neumann);
                    continue;
                }
                let mut q = p;
                q[axis] = x as usize;
                sum += 0.5 * (self.beta[idx] + self.beta[g.index(q[0], q[1], q[2])]);
            }
        }
        sum
    }

    /// The stability bounds of this medium under `bc` (module docs, "Time step").
    pub fn bounds(&self, bc: BoundaryCondition) -> StepBounds {
        let mut g_max: f64 = 0.0;
        let mut pos_max: f64 = 0.0;
        let mut eq49 = f64::INFINITY;
        for idx in 0..self.grid.len() {
            if !self.is_updated(bc, idx) {
                continue;
            }
            let (a, s) = (self.ka_dl[idx], self.face_sum(bc, idx));
            g_max = g_max.max(a + 2.0 * s);
            pos_max = pos_max.max(a + s);
            eq49 = eq49.min(eq_4_9(self.beta[idx], a));
        }
        StepBounds {
            gershgorin: 2.0 / g_max,
            positivity: 1.0 / pos_max,
            eq49,
        }
    }

    /// Voxels where an expanded operator (thesis Eq 4.8) has a negative neighbour weight,
    /// |β₊ − β₋| > 4β_p on some axis (spec §4 item 3): positivity fails there at every r.
    pub fn expanded_violations(&self, bc: BoundaryCondition) -> usize {
        let g = &self.grid;
        (0..g.len())
            .filter(|&idx| self.is_updated(bc, idx))
            .filter(|&idx| {
                let p = g.coords(idx);
                (0..3).any(|axis| {
                    let nb = |dir: i64| {
                        let mut q = p;
                        q[axis] = (p[axis] as i64 + dir).clamp(0, g.n[axis] as i64 - 1) as usize;
                        self.beta[g.index(q[0], q[1], q[2])]
                    };
                    (nb(1) - nb(-1)).abs() > 4.0 * self.beta[idx]
                })
            })
            .count()
    }
}

/// Thesis Eq 4.9 generalised to the voxel's own a = Ka∆ (and so to g ≠ 0): diagonal
/// dominance of the explicit update with the worst case |∆β| = 1 on every axis,
/// 1 − r a − 6βr ≥ 6βr + (3/2)r, i.e. r ≤ 1/(a + 12β + 3/2). With a = (1 − α)/(3β) this is
/// the printed 6β/(72β² + 9β + 2(1 − α)).
pub fn eq_4_9(beta: f64, ka_dl: f64) -> f64 {
    1.0 / (ka_dl + 12.0 * beta + 1.5)
}

/// The printed form of thesis Eq 4.9 (g = 0): r ≤ 6β/(72β² + 9β + 2(1 − α)).
pub fn eq_4_9_printed(beta: f64, albedo: f64) -> f64 {
    6.0 * beta / (72.0 * beta * beta + 9.0 * beta + 2.0 * (1.0 - albedo))
}

/// Stability bounds on r = c∆t/∆ of one medium.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepBounds {
    /// r_G = 2/max_p(a_p + 2Σ_s β_ps): Gershgorin, sufficient for the conservative operator.
    pub gershgorin: f64,
    /// r_pos = 1/max_p(a_p + Σ_s β_ps): every weight of the conservative update ≥ 0.
    pub positivity: f64,
    /// min_p thesis Eq 4.9 ([`eq_4_9`]).
    pub eq49: f64,
}

/// The time step a configuration resolves to on a medium: global r, or per-voxel r_p.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum ResolvedStep {
    Global(f64),
    Local(Vec<f64>),
}

/// Resolves and checks the time step of `cfg` on `coef`.
pub(crate) fn resolve_step(
    coef: &Coefficients,
    cfg: &RdeConfig,
    bounds: &StepBounds,
) -> Result<ResolvedStep, SolverError> {
    if !bounds.gershgorin.is_finite() {
        return Err(SolverError::BadParameter {
            name: "beta",
            value: 0.0,
            reason: "β and Ka∆ are 0 at every updated voxel: nothing diffuses or absorbs, so no time step is defined",
        });
    }
    let strict = cfg.check == StepCheck::Eq49Strict;
    match cfg.time_step {
        TimeStep::Gershgorin { safety } => {
            let r = safety * bounds.gershgorin;
            Ok(ResolvedStep::Global(if strict {
                r.min(bounds.eq49)
            } else {
                r
            }))
        }
        TimeStep::Fixed(r) => {
            if cfg.check == StepCheck::Unchecked {
                return Ok(ResolvedStep::Global(r));
            }
            if r > bounds.gershgorin {
                return Err(SolverError::StepAboveBound {
                    name: "r",
                    value: r,
                    bound: bounds.gershgorin,
                    criterion: "the Gershgorin bound 2/max(Ka∆ + 2Σβ_ps) of the conservative operator",
                });
            }
            if strict && r > bounds.eq49 {
                return Err(SolverError::StepAboveBound {
                    name: "r",
                    value: r,
                    bound: bounds.eq49,
                    criterion: "thesis Eq 4.9 (min over voxels, worst case |∆β| = 1)",
                });
            }
            Ok(ResolvedStep::Global(r))
        }
        TimeStep::Local { safety } => {
            let bc = cfg.boundary;
            Ok(ResolvedStep::Local(
                (0..coef.grid.len())
                    .map(|idx| {
                        if !coef.is_updated(bc, idx) {
                            return 0.0;
                        }
                        let d = coef.ka_dl[idx] + coef.face_sum(bc, idx);
                        let r = if d > 0.0 { safety / d } else { 0.0 };
                        if strict {
                            r.min(eq_4_9(coef.beta[idx], coef.ka_dl[idx]))
                        } else {
                            r
                        }
                    })
                    .collect(),
            ))
        }
    }
}

/// RDE's part of a [`Solution`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RdeTrace<T> {
    /// `Steady`: R̄/j̄ after each step (index 0 = step 1); `Frames`: empty.
    pub residuals: Vec<f64>,
    /// r = c∆t/∆ (`Local`: the largest r_p).
    pub r: f64,
    /// Whether r is per voxel (`Local`: the transient is not physical).
    pub local: bool,
    /// c·t = n·r·∆ after the run, the light path length travelled (a length in the grid's
    /// units; divide by c for seconds); NaN for `Local`.
    pub light_path: f64,
    /// The medium's stability bounds.
    pub bounds: StepBounds,
    /// Voxels whose β was capped at [`BETA_MAX`].
    pub beta_capped: usize,
    /// Expanded operators: voxels with a negative neighbour weight (|β₊ − β₋| > 4β_p); 0 for
    /// the conservative operator.
    pub expanded_violations: usize,
    /// The smallest φ of the final field (≥ 0 is guaranteed only for the conservative operator
    /// at r ≤ r_pos).
    pub min_phi: f64,
    /// `Frames`: (step, φ) every `snapshot_every` steps.
    pub snapshots: Vec<(usize, Vec<T>)>,
    /// [`SteadyStop::ErrorBound`]: (step, estimated relative error) every block.
    pub error_estimates: Vec<(usize, f64)>,
}

impl<T> RdeTrace<T> {
    /// The physical time t = n∆t for light speed `c` (in the grid's length units per second).
    pub fn time(&self, c: f64) -> f64 {
        self.light_path / c
    }
}

impl Default for StepBounds {
    fn default() -> Self {
        Self {
            gershgorin: f64::NAN,
            positivity: f64::NAN,
            eq49: f64::NAN,
        }
    }
}

/// The result of an RDE run: φ, steps ([`Solution::steps`]), why it stopped, and the
/// time step, bounds and residuals in [`Solution::trace`].
pub type RdeSolution<T> = Solution<T, RdeTrace<T>>;

impl<T> Solution<T, RdeTrace<T>> {
    /// The normalised residual after each step (`Steady`).
    pub fn residuals(&self) -> &[f64] {
        &self.trace.residuals
    }
}

/// Solves on any [`Backend`]; φ comes back in `f64`. `observer(step, R̄/j̄)` sees every step
/// (CPU) or every checkpoint's steps (GPU) of a `Steady` run.
pub fn solve(
    backend: &Backend<'_>,
    coef: &Coefficients,
    config: &RdeConfig,
    observer: impl FnMut(usize, f64),
) -> Result<RdeSolution<f64>, SolverError> {
    fn widen<T: Real>(s: RdeSolution<T>) -> RdeSolution<f64> {
        s.widen_with(|t| RdeTrace {
            residuals: t.residuals,
            r: t.r,
            local: t.local,
            light_path: t.light_path,
            bounds: t.bounds,
            beta_capped: t.beta_capped,
            expanded_violations: t.expanded_violations,
            min_phi: t.min_phi,
            snapshots: t
                .snapshots
                .into_iter()
                .map(|(n, v)| (n, v.iter().map(|x| x.f()).collect()))
                .collect(),
            error_estimates: t.error_estimates,
        })
    }
    match backend {
        Backend::Cpu(Precision::F64) => {
            Ok(CpuRde::<f64>::new(coef, config)?.run_observed(observer))
        }
        Backend::Cpu(Precision::F32) => Ok(widen(
            CpuRde::<f32>::new(coef, config)?.run_observed(observer),
        )),
        Backend::Gpu(ctx) => Ok(widen(
            GpuRde::new(ctx, coef, config)?.run_observed(observer)?,
        )),
    }
}

/// Assembles a solution (CPU and GPU kernels).
#[allow(clippy::too_many_arguments)]
pub(crate) fn solution<T: Real>(
    grid: Grid,
    phi: Vec<T>,
    steps: usize,
    stop: Stop,
    seconds: f64,
    setup_seconds: f64,
    timer: Timer,
    mut trace: RdeTrace<T>,
    dl: f64,
) -> RdeSolution<T> {
    trace.min_phi = phi.iter().map(|x| x.f()).fold(f64::INFINITY, f64::min);
    trace.light_path = if trace.local {
        f64::NAN
    } else {
        steps as f64 * trace.r * dl
    };
    Solution {
        grid,
        phi,
        steps,
        last_change: trace.residuals.last().copied().unwrap_or(f64::NAN),
        stop,
        seconds,
        setup_seconds,
        timer,
        balance: None,
        trace,
    }
}

/// The residual window of an RDE run (FLD's, shared).
pub(crate) fn window(grid: &Grid, margin: usize) -> ResidualWindow {
    ResidualWindow::new(grid, margin)
}

#[cfg(test)]
mod tests;
