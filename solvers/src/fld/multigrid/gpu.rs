//! FAS multigrid on the GPU (f32): the cycle of [`super::CpuMultigrid`] recorded into one
//! compute pass per cycle, with the per-level smoother being `fld.wgsl` itself ([`GpuFld`],
//! one instance per level at [`super::MgConfig::smoother_omega`], never stopping on its
//! own) and the transfers in `multigrid.wgsl` beside this file (`MgParams` mirrors its
//! `Params`, `SPEC` its bindings; both checked by `tests/kernel_contract.rs`).
//!
//! The level hierarchy (grids, coarse media, packed initial state) is built once on the host
//! by [`super::CpuMultigrid::new`] and uploaded; after that nothing but three sums per cycle
//! (Σ residual² over the stopping window, ‖φ_k − φ_{k−1}‖², ‖φ_k‖²) comes back until φ is
//! read once at the end. The stopping rule, the stall rule and the error estimate are the
//! CPU's (`fld::iterate`, `Contraction`), evaluated on those sums.
//!
//! ## Decisions where the CPU version is not followed
//! * **Coarsest level: a fixed number of sweeps** ([`coarsest_sweeps`]: 4 per interior voxel
//!   of its longest axis, at least 16 and at most the CPU's cap of 200), where the CPU runs up
//!   to 200 until its sweep residual has dropped by 10⁻³: deciding that on the GPU would need
//!   a read-back per coarsest visit. Measured on the CPU (f64, V(2,2), tolerance 10⁻⁶; an
//!   instrumented build, not kept): on the point source (τ = 10, albedo 0.9, n = 33, 63, 127,
//!   CDA and FLD-LP) and the Fig 4 cloud (n = 33, 64, FLD-LP) the coarsest level is 5³ (3³
//!   unknowns) and its solve took 5–12 sweeps, so the GPU's 16 there cover every case
//!   measured. A coarsest level that stays long along some axis (a thin slab stops coarsening
//!   early) gets up to 200 sweeps, as the CPU's cap.
//! * **Everything in f32**, where the CPU-f32 multigrid forms its residuals and transfers in
//!   f64 around an f32 smoother. R̄/j̄ then floors where f32 rounding dominates: it reached
//!   9·10⁻⁸ on the 33³ point source, but on the Fig 4 cloud CDA stops `Stalled` near 10⁻⁴ (as
//!   the CPU-f32 multigrid does; the f32 default tolerance is 10⁻⁴). GPU vs CPU-f32 is compared at convergence (`tests/fld_multigrid_gpu.rs`).
//! * **Plain FAS cycles: [`MgConfig::krylov`], the stall fallback of [`super::CoarseD::Auto`]
//!   and the local relaxation of [`MgConfig::local_sweeps`] are CPU settings, ignored here** ([`super::CoarseD::Restricted`] is refused with a typed
//!   error). The CPU's Krylov acceleration keeps 2(k + 1) fine-grid vectors and needs k + 1
//!   dot products and a combination pass per cycle; on the device that is k + 1 more sums
//!   per read-back and 2(k + 1) more bindings than the transfer kernel's, and the Picard
//!   coarse levels need a smoother that leaves D alone on coarse levels only; neither is
//!   built yet (nor are the local boxes' sweeps). The GPU therefore runs the cycles the CPU
//!   runs with `krylov: 0`, `CoarseD::Recomputed` and `local_sweeps: 0`
//!   ([`MgConfig::plain_fas`]), and is compared with those (`tests/fld_multigrid_gpu.rs`).

use super::{Contraction, CpuMultigrid, Cycle, MgConfig, axes};
use crate::fld::gpu::{GpuFld, larsen_n, limiter_id};
use crate::fld::residual::ResidualWindow;
use crate::fld::{Boundary, FldConfig, FldSolution};
use crate::gpu::kernel::{Access, Kernel, KernelSpec, struct_layout, submit_pass};
use crate::gpu::{GpuContext, GpuError, PassTimer, Timer, storage_buffer, uniform_buffer};
use crate::method::Stop;
use crate::{Grid, Medium, SolverError};
use bytemuck::{Pod, Zeroable};
use std::time::Instant;

/// Red-black sweeps on the coarsest level `g` per visit (see the module docs).
pub fn coarsest_sweeps(g: &Grid) -> u32 {
    let longest = g.n.iter().map(|&n| n.saturating_sub(2)).max().unwrap_or(0);
    (4 * longest as u32).clamp(16, 200)
}

/// Workgroup size of every per-voxel kernel of `multigrid.wgsl`.
const WG: [u32; 3] = [8, 8, 4];

/// Storage bindings of `multigrid.wgsl` (every one but `P`).
const STORAGE_BINDINGS: u32 = 13;

/// Uniforms of `multigrid.wgsl` (`Params` there; 112 bytes).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub(crate) struct MgParams {
    nx: u32,
    ny: u32,
    nz: u32,
    h: u32,
    plen: u32,
    cnx: u32,
    cny: u32,
    cnz: u32,
    ch: u32,
    cplen: u32,
    vertex_x: u32,
    vertex_y: u32,
    vertex_z: u32,
    lo: u32,
    hi_x: u32,
    hi_y: u32,
    hi_z: u32,
    norm_groups: u32,
    fld: u32,
    _pad0: u32,
    inv_2dl: f32,
    inv_dl2: f32,
    dl2: f32,
    floor: f32,
    larsen_n: f32,
    _pad1: f32,
    _pad2: f32,
    _pad3: f32,
}

/// What the host code assumes about `multigrid.wgsl` (the flux limiter of `limiter.wgsl`
/// prepended, as for `fld.wgsl`).
pub(crate) const SPEC: KernelSpec = KernelSpec {
    label: "multigrid.wgsl",
    source: concat!(
        include_str!("../limiter.wgsl"),
        include_str!("multigrid.wgsl")
    ),
    bindings: &[
        ("P", Access::Uniform),
        ("phi", Access::ReadWrite),
        ("dcoef", Access::ReadWrite),
        ("sig", Access::Read),
        ("absorb", Access::Read),
        ("src", Access::ReadWrite),
        ("tmp", Access::ReadWrite),
        ("res", Access::ReadWrite),
        ("base", Access::ReadWrite),
        ("cphi", Access::ReadWrite),
        ("cres", Access::ReadWrite),
        ("cbase", Access::ReadWrite),
        ("partials", Access::ReadWrite),
        ("sums", Access::ReadWrite),
    ],
    entries: &[
        "fresh_d",
        "residual",
        "coarse_rhs",
        "take_d",
        "restrict_down",
        "prolong",
        "norm",
        "finish",
    ],
    constants: &["LIMITER"],
    uniforms: &[(
        "P",
        struct_layout!(
            MgParams;
            nx, ny, nz, h, plen, cnx, cny, cnz, ch, cplen, vertex_x, vertex_y, vertex_z, lo,
            hi_x, hi_y, hi_z, norm_groups, fld, _pad0, inv_2dl, inv_dl2, dl2, floor, larsen_n,
            _pad1, _pad2, _pad3
        ),
    )],
};

/// The pipelines of `multigrid.wgsl`, in the order of `SPEC.entries`.
#[derive(Debug)]
struct Pipelines {
    fresh_d: wgpu::ComputePipeline,
    residual: wgpu::ComputePipeline,
    coarse_rhs: wgpu::ComputePipeline,
    take_d: wgpu::ComputePipeline,
    restrict: wgpu::ComputePipeline,
    prolong: wgpu::ComputePipeline,
    norm: wgpu::ComputePipeline,
    finish: wgpu::ComputePipeline,
}

/// One level on the device: its smoother, the transfer bind group (its own fields and the
/// next coarser level's φ, residual and R̂φ) and its scratch buffers (kept alive here).
#[derive(Debug)]
struct GpuLevel<'a> {
    smoother: GpuFld<'a>,
    /// Workgroups of a per-voxel kernel over this level.
    groups: [u32; 3],
    bind: wgpu::BindGroup,
    /// D from the current φ, the residual, and R̂φ (coarse) or the previous cycle's φ
    /// (finest): bound in `bind`, held here.
    _scratch: [wgpu::Buffer; 3],
}

/// The FAS multigrid solve of one medium on the GPU (f32).
#[derive(Debug)]
pub struct GpuMultigrid<'a> {
    ctx: &'a GpuContext,
    levels: Vec<GpuLevel<'a>>,
    pipelines: Pipelines,
    sums: wgpu::Buffer,
    fld: bool,
    mg: MgConfig,
    grid: Grid,
    coarsest_sweeps: u32,
    inv_count: f64,
    tolerance: f64,
    max_cycles: usize,
    trivial: bool,
    cycles: usize,
    work: f64,
    residuals: Vec<f64>,
    setup_seconds: f64,
}

fn groups(g: &Grid) -> [u32; 3] {
    [0, 1, 2].map(|d| (g.n[d] as u32).div_ceil(WG[d]))
}

impl<'a> GpuMultigrid<'a> {
    /// Validates the inputs (as [`super::CpuMultigrid::new`]), checks the device limits of
    /// every level, builds the hierarchy on the host and uploads it.
    pub fn new(
        ctx: &'a GpuContext,
        medium: &Medium<f32>,
        boundary: &Boundary<f32>,
        config: &FldConfig,
        mg: &MgConfig,
    ) -> Result<Self, SolverError> {
        let t0 = Instant::now();
        let have = ctx.limits().max_storage_buffers_per_shader_stage;
        if have < STORAGE_BINDINGS {
            return Err(GpuError::TooLarge {
                what: "storage buffers per shader stage of the multigrid transfers".into(),
                needed: u64::from(STORAGE_BINDINGS),
                limit: u64::from(have),
                limit_name: "max_storage_buffers_per_shader_stage",
                adapter: ctx.info().name.clone(),
            }
            .into());
        }
        GpuFld::check_limits(ctx, &medium.grid)?;
        for g in groups(&medium.grid) {
            ctx.check_workgroups("the multigrid transfers", g)?;
        }
        if mg.coarse_op == super::CoarseOp::Galerkin {
            return Err(SolverError::Unsupported(
                "the GPU multigrid rediscretises its coarse levels (CoarseOp::Galerkin is CPU \
                 only)"
                    .into(),
            ));
        }
        if mg.coarse_d == super::CoarseD::Restricted {
            return Err(SolverError::Unsupported(
                "the GPU multigrid recomputes the coarse D (CoarseD::Restricted is CPU only)"
                    .into(),
            ));
        }
        let host = CpuMultigrid::<f32>::new(medium, boundary, config, &mg.plain_fas())?;
        let cfg = &host.config;
        let fld = !cfg.limiter.is_constant();
        let fine = host.levels[0].grid;
        let window = ResidualWindow::new(&fine, cfg.residual_margin);
        let norm_groups: u32 = groups(&fine).iter().product();
        let kernel = Kernel::new(
            ctx,
            &SPEC,
            &[("LIMITER", f64::from(limiter_id(cfg.limiter)))],
        )?;
        let p = |e: &str| kernel.pipeline(e);
        let pipelines = Pipelines {
            fresh_d: p("fresh_d")?,
            residual: p("residual")?,
            coarse_rhs: p("coarse_rhs")?,
            take_d: p("take_d")?,
            restrict: p("restrict_down")?,
            prolong: p("prolong")?,
            norm: p("norm")?,
            finish: p("finish")?,
        };
        let (partials, sums, dummy) = ctx.allocating(
            "multigrid reduction buffers",
            12 * u64::from(norm_groups) + 16,
            |d| {
                (
                    storage_buffer(d, "mg partials", &vec![0u8; 12 * norm_groups as usize]),
                    storage_buffer(d, "mg sums", &[0u8; 16]),
                    [0, 1, 2].map(|_| storage_buffer(d, "mg dummy", &[0u8; 16])),
                )
            },
        )?;
        let smoother_kernel = GpuFld::kernel(ctx, cfg.limiter)?;
        let mut smoothers = Vec::with_capacity(host.levels.len());
        let mut scratch = Vec::with_capacity(host.levels.len());
        for lv in &host.levels {
            let smoother = GpuFld::upload(ctx, &smoother_kernel, &lv.fld, cfg, 0.0, t0)?;
            let plen = 2 * lv.grid.n[2] * lv.grid.n[1] * lv.grid.n[0].div_ceil(2);
            let [_, d0, ..] = lv.fld.packed_fields();
            let tmp: Vec<f32> = [&d0[0][..], &d0[1][..]].concat();
            let bufs = ctx.allocating(
                &format!("multigrid scratch of a {:?} level", lv.grid.n),
                3 * 4 * plen as u64,
                |d| {
                    [
                        storage_buffer(d, "mg tmp", bytemuck::cast_slice(&tmp)),
                        storage_buffer(d, "mg res", &vec![0u8; 4 * plen]),
                        storage_buffer(d, "mg base", &vec![0u8; 4 * plen]),
                    ]
                },
            )?;
            smoothers.push(smoother);
            scratch.push(bufs);
        }
        let mut binds = Vec::with_capacity(smoothers.len());
        for (l, smoother) in smoothers.iter().enumerate() {
            let g = host.levels[l].grid;
            let cn = host.levels.get(l + 1).map_or([0; 3], |c| c.grid.n);
            let vertex = axes(&g).map(|a| u32::from(a.vertex));
            let h = |n: [usize; 3]| n[0].div_ceil(2);
            let params = MgParams {
                nx: g.n[0] as u32,
                ny: g.n[1] as u32,
                nz: g.n[2] as u32,
                h: h(g.n) as u32,
                plen: (g.n[2] * g.n[1] * h(g.n)) as u32,
                cnx: cn[0] as u32,
                cny: cn[1] as u32,
                cnz: cn[2] as u32,
                ch: h(cn) as u32,
                cplen: (cn[2] * cn[1] * h(cn)) as u32,
                vertex_x: vertex[0],
                vertex_y: vertex[1],
                vertex_z: vertex[2],
                lo: window.lo as u32,
                hi_x: window.hi[0] as u32,
                hi_y: window.hi[1] as u32,
                hi_z: window.hi[2] as u32,
                norm_groups,
                fld: u32::from(fld),
                _pad0: 0,
                inv_2dl: (0.5 / g.dl) as f32,
                inv_dl2: (1.0 / (g.dl * g.dl)) as f32,
                dl2: (g.dl * g.dl) as f32,
                floor: host.floor as f32,
                larsen_n: larsen_n(cfg.limiter),
                _pad1: 0.0,
                _pad2: 0.0,
                _pad3: 0.0,
            };
            let uniform = ctx.allocating("multigrid params", 112, |d| {
                uniform_buffer(d, "mg params", &params)
            })?;
            let [phi, dcoef, sig, absorb, src] = smoother.fields();
            let [tmp, res, base] = &scratch[l];
            // The coarsest level binds dummies for the next level's fields (never read).
            let (cphi, cres, cbase) = match (smoothers.get(l + 1), scratch.get(l + 1)) {
                (Some(c), Some([_, cres, cbase])) => (&c.fields()[0], cres, cbase),
                _ => (&dummy[0], &dummy[1], &dummy[2]),
            };
            binds.push(kernel.bind(
                ctx,
                &[
                    ("P", &uniform),
                    ("phi", phi),
                    ("dcoef", dcoef),
                    ("sig", sig),
                    ("absorb", absorb),
                    ("src", src),
                    ("tmp", tmp),
                    ("res", res),
                    ("base", base),
                    ("cphi", cphi),
                    ("cres", cres),
                    ("cbase", cbase),
                    ("partials", &partials),
                    ("sums", &sums),
                ],
            )?);
        }
        let levels = smoothers
            .into_iter()
            .zip(binds)
            .zip(scratch)
            .zip(&host.levels)
            .map(|(((smoother, bind), scratch), lv)| GpuLevel {
                smoother,
                groups: groups(&lv.grid),
                bind,
                _scratch: scratch,
            })
            .collect();
        ctx.check_lost()?;
        Ok(Self {
            ctx,
            levels,
            pipelines,
            sums,
            fld,
            mg: host.mg.clone(),
            grid: fine,
            coarsest_sweeps: host.levels.last().map_or(16, |c| coarsest_sweeps(&c.grid)),
            inv_count: 1.0 / window.count as f64,
            tolerance: host.tolerance,
            max_cycles: cfg.max_iterations,
            trivial: host.trivial,
            cycles: 0,
            work: 0.0,
            residuals: Vec::new(),
            setup_seconds: t0.elapsed().as_secs_f64(),
        })
    }

    /// Number of levels.
    pub fn levels(&self) -> usize {
        self.levels.len()
    }

    /// Records one dispatch of `pipeline` on level `l` over `groups` workgroups.
    fn dispatch(
        &self,
        pass: &mut wgpu::ComputePass<'_>,
        pipeline: &wgpu::ComputePipeline,
        l: usize,
        groups: [u32; 3],
    ) {
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &self.levels[l].bind, &[]);
        pass.dispatch_workgroups(groups[0], groups[1], groups[2]);
    }

    /// Smoothing sweeps on level `l` (each counts 8^(−l) work units).
    fn smooth(&self, pass: &mut wgpu::ComputePass<'_>, l: usize, n: u32, work: &mut f64) {
        self.levels[l].smoother.record_iterations(pass, n);
        *work += f64::from(n) * 0.125f64.powi(l as i32);
    }

    /// `res` of level `l` = j − L(φ) with D recomputed from φ (FLD) or fixed (CDA).
    fn residual(&self, pass: &mut wgpu::ComputePass<'_>, l: usize) {
        let g = self.levels[l].groups;
        if self.fld {
            self.dispatch(pass, &self.pipelines.fresh_d, l, g);
        }
        self.dispatch(pass, &self.pipelines.residual, l, g);
    }

    /// The cycle from level `l` down (as `CpuMultigrid::cycle_at`).
    fn cycle_at(&self, pass: &mut wgpu::ComputePass<'_>, l: usize, kind: Cycle, work: &mut f64) {
        if l + 1 == self.levels.len() {
            self.smooth(pass, l, self.coarsest_sweeps, work);
            return;
        }
        let pl = &self.pipelines;
        self.smooth(pass, l, self.mg.pre as u32, work);
        self.residual(pass, l);
        let cg = self.levels[l + 1].groups;
        self.dispatch(pass, &pl.restrict, l, cg);
        if self.fld {
            self.dispatch(pass, &pl.fresh_d, l + 1, cg);
        }
        self.dispatch(pass, &pl.coarse_rhs, l + 1, cg);
        self.cycle_at(pass, l + 1, kind, work);
        if kind == Cycle::F {
            self.cycle_at(pass, l + 1, Cycle::V, work);
        }
        let g = self.levels[l].groups;
        self.dispatch(pass, &pl.prolong, l, g);
        if self.fld {
            self.dispatch(pass, &pl.fresh_d, l, g);
            self.dispatch(pass, &pl.take_d, l, g);
        }
        self.smooth(pass, l, self.mg.post as u32, work);
    }

    /// One cycle and its stopping sums (residual, update and φ norms) into `sums`.
    fn record_cycle(&self, pass: &mut wgpu::ComputePass<'_>, work: &mut f64) {
        self.cycle_at(pass, 0, self.mg.cycle, work);
        self.residual(pass, 0);
        self.dispatch(pass, &self.pipelines.norm, 0, self.levels[0].groups);
        self.dispatch(pass, &self.pipelines.finish, 0, [1, 1, 1]);
    }

    /// As [`GpuMultigrid::solve_observed`] without an observer.
    pub fn solve(self) -> Result<FldSolution<f32>, SolverError> {
        self.solve_observed(|_, _| {})
    }

    /// Cycles until R̄/j̄ < tolerance (with the error estimate of the CPU multigrid), the cap
    /// (`max_iterations` cycles), a stall or a non-finite residual, reading three sums back
    /// after every cycle; `observer(cycle, R̄/j̄)` after each. φ is read back once at the end.
    pub fn solve_observed(
        mut self,
        mut observer: impl FnMut(usize, f64),
    ) -> Result<FldSolution<f32>, SolverError> {
        let t0 = Instant::now();
        let mut timer = PassTimer::new(self.ctx);
        let mut failure: Option<GpuError> = None;
        let status = if self.trivial {
            Stop::Converged
        } else {
            let residual = std::cell::Cell::new(f64::NAN);
            let mut estimate = Contraction::default();
            let (max, tol, stall) = (self.max_cycles, self.tolerance, self.mg.stall_cycles);
            super::super::iterate(
                0,
                max,
                tol,
                Some(stall),
                || {
                    let mut work = 0.0;
                    let read = submit_pass(
                        self.ctx,
                        &mut timer,
                        "multigrid cycle",
                        |pass| self.record_cycle(pass, &mut work),
                        Some((&self.sums, 12)),
                    );
                    self.work += work;
                    self.cycles += 1;
                    let sums = match read {
                        Ok(bytes) => bytemuck::pod_collect_to_vec::<u8, f32>(&bytes),
                        Err(e) => {
                            failure = Some(e);
                            vec![f32::NAN; 3]
                        }
                    };
                    let [r2, dd, pp] = [0, 1, 2].map(|i| f64::from(sums[i]));
                    let r = (r2 * self.inv_count).sqrt();
                    residual.set(r);
                    self.residuals.push(r);
                    let e = estimate.next(dd, pp);
                    (self.cycles, r.max(e))
                },
                |k, _| observer(k, residual.get()),
            )
        };
        if let Some(e) = failure {
            return Err(e.into());
        }
        let phi = self.levels[0].smoother.phi()?;
        let kind = timer.timer();
        let seconds = match kind {
            Timer::GpuTimestamps => timer.seconds(),
            Timer::WallClock => t0.elapsed().as_secs_f64(),
        };
        let mut sol = crate::fld::solution(
            self.grid,
            phi,
            std::mem::take(&mut self.residuals),
            self.cycles,
            status,
            seconds,
            self.setup_seconds,
            kind,
        );
        sol.trace.work_units = self.work;
        sol.trace.solver = "multigrid".into();
        Ok(sol)
    }
}
