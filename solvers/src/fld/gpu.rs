//! The wgpu kernel of FLD Algorithm 1 (f32), the GPU twin of [`super::cpu`]: same packed
//! red-black layout, same per-voxel arithmetic (FLD Eqs 32–37 with the decisions of
//! [`super`]), same stopping rule. The shader is `fld.wgsl` beside this file; `GpuParams` is
//! mirrored there as `Params`, and `SPEC` declares its bindings by name (both checked against
//! the WGSL by `tests/kernel_contract.rs`).
//!
//! One iteration is three or four dispatches in one compute pass: the boundary-layer D
//! update (FLD only), the red and the black `sweep`, and `reduce`, which sums the
//! per-workgroup squared residuals of both colours in a fixed order, stores R̄/j̄ and raises
//! a `done` flag below the tolerance. Every kernel returns at once when `done` is set, so the
//! host records [`GpuFld::check_every`] iterations per submission and reads back only the
//! small state buffer (iteration count, flag, residuals) between them (the shared loop of
//! [`crate::gpu::kernel`]); φ is read back once at the end.

use super::cpu::CpuFld;
use super::{Boundary, FldConfig, FldSolution, FluxLimiter};
use crate::gpu::kernel::{
    Access, Checkpointed, Checkpoints, Kernel, KernelSpec, run_checkpointed, struct_layout,
    time_pass,
};
use crate::gpu::{GpuContext, GpuError, Timer, storage_buffer, uniform_buffer};
use crate::method::Stop as Status;
use crate::{Grid, Medium, SolverError};
use bytemuck::{Pod, Zeroable};
use std::time::Instant;

/// Threads per workgroup of `sweep` along x (packed m) and y (j), as in `fld.wgsl`.
const WG_X: u32 = 32;
const WG_Y: u32 = 8;
/// Threads per workgroup of `boundary_d`.
const WG_BOUNDARY: u32 = 64;

/// Uniforms of `fld.wgsl` (`Params` there, same fields in the same order; 112 bytes, a
/// multiple of 16). Checked against the WGSL by `tests/kernel_contract.rs`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub(crate) struct GpuParams {
    nx: u32,
    ny: u32,
    nz: u32,
    /// Packed row length ⌈nx/2⌉.
    h: u32,
    /// Packed values per colour.
    plen: u32,
    /// Colour of the sweep (0 red, 1 black).
    color: u32,
    /// Residual-counted voxels: lo ≤ i ≤ hi_x, lo ≤ j ≤ hi_y, lo ≤ k ≤ hi_z.
    lo: u32,
    hi_x: u32,
    hi_y: u32,
    hi_z: u32,
    /// Boundary-layer voxels.
    boundary_count: u32,
    /// Threads per dispatch row of `boundary_d`.
    boundary_row: u32,
    /// Workgroups of one sweep.
    partials_per_color: u32,
    /// Residual slots in the state buffer.
    chunk: u32,
    _pad0: u32,
    _pad1: u32,
    /// SOR factor ω and 1 − ω.
    omega: f32,
    one_minus_omega: f32,
    /// 1/(2Δl) and 1/Δl².
    inv_2dl: f32,
    inv_dl2: f32,
    /// ε j̄ floor of Eq 35.
    floor: f32,
    /// θ of the D under-relaxation, and 1 − θ.
    theta: f32,
    one_minus_theta: f32,
    /// n of Larsen's limiter.
    larsen_n: f32,
    /// Tolerance on R̄/j̄.
    tolerance: f32,
    /// 1 / number of residual-counted voxels.
    inv_residual_count: f32,
    _pad2: f32,
    _pad3: f32,
}

/// What this host code assumes about `fld.wgsl`: bindings by name, entry points, the
/// `LIMITER` override and the layout of `Params`.
pub(crate) const SPEC: KernelSpec = KernelSpec {
    label: "fld.wgsl",
    source: concat!(include_str!("limiter.wgsl"), include_str!("fld.wgsl")),
    bindings: &[
        ("P", Access::Uniform),
        ("phi", Access::ReadWrite),
        ("dcoef", Access::ReadWrite),
        ("sig", Access::Read),
        ("absorb", Access::Read),
        ("src", Access::Read),
        ("partials", Access::ReadWrite),
        ("state", Access::ReadWrite),
        ("boundary", Access::Read),
    ],
    entries: &["boundary_d", "sweep", "reduce"],
    constants: &["LIMITER"],
    uniforms: &[(
        "P",
        struct_layout!(
            GpuParams;
            nx, ny, nz, h, plen, color, lo, hi_x, hi_y, hi_z, boundary_count, boundary_row,
            partials_per_color, chunk, _pad0, _pad1, omega, one_minus_omega, inv_2dl, inv_dl2,
            floor, theta, one_minus_theta, larsen_n, tolerance, inv_residual_count, _pad2,
            _pad3
        ),
    )],
};

/// The GPU state of one diffusion solve: buffers, pipelines and bind groups for one problem
/// size, built once and reused for every iteration.
#[derive(Debug)]
pub struct GpuFld<'a> {
    ctx: &'a GpuContext,
    grid: Grid,
    max_iterations: usize,
    j_ref: f64,
    trivial: bool,
    h: usize,
    check_every: u32,
    fld: bool,
    boundary_groups: [u32; 2],
    sweep_groups: [u32; 3],
    /// The packed fields φ, D, σ, absorption and source (as [`CpuFld::packed_fields`]).
    fields: [wgpu::Buffer; 5],
    state: wgpu::Buffer,
    /// The `boundary_d`, `sweep` and `reduce` pipelines.
    pipelines: [wgpu::ComputePipeline; 3],
    /// Bind groups with the colour-0 and colour-1 uniforms.
    binds: [wgpu::BindGroup; 2],
    /// Iterations completed on the GPU, as last read back.
    iterations: usize,
    residuals: Vec<f64>,
    setup_seconds: f64,
}

impl<'a> GpuFld<'a> {
    /// Validates the inputs exactly as [`CpuFld::new`] does, checks the device limits for
    /// this grid, uploads the packed fields and builds the pipelines.
    pub fn new(
        ctx: &'a GpuContext,
        medium: &Medium<f32>,
        boundary: &Boundary<f32>,
        config: &FldConfig,
    ) -> Result<Self, SolverError> {
        let t0 = Instant::now();
        if config.vacuum_face == super::VacuumFace::Marshak {
            return Err(SolverError::Unsupported(
                "the Marshak vacuum face runs on the CPU only (the GPU kernel has the paper's \
                 face)"
                    .into(),
            ));
        }
        medium.validate()?;
        config.validate()?;
        Self::check_limits(ctx, &medium.grid)?;
        // Limits are checked above, before any host memory is spent. The CPU kernel's setup
        // is the single source of the packed initial state.
        let host = CpuFld::<f32>::new(medium, boundary, config)?;
        let tolerance = host.tolerance();
        let kernel = Self::kernel(ctx, config.limiter)?;
        Self::upload(ctx, &kernel, &host, config, tolerance, t0)
    }

    /// `fld.wgsl` compiled for `limiter` (one per solve; the multigrid levels share one).
    pub(super) fn kernel(ctx: &GpuContext, limiter: FluxLimiter) -> Result<Kernel, GpuError> {
        Kernel::new(ctx, &SPEC, &[("LIMITER", f64::from(limiter_id(limiter)))])
    }

    /// Fails with a typed error unless a grid of this size fits the device's limits (buffer
    /// sizes, workgroup counts, u32 indexing); returns the sweep's workgroup counts.
    pub(super) fn check_limits(ctx: &GpuContext, grid: &Grid) -> Result<[u32; 3], SolverError> {
        let [nx, ny, nz] = grid.n;
        let h = nx.div_ceil(2);
        let plen = nz * ny * h;
        let adapter = ctx.info().name.clone();
        let too_large = |what: &str, needed: u64| GpuError::TooLarge {
            what: what.into(),
            needed,
            limit: u64::from(u32::MAX),
            limit_name: "u32 indexing in fld.wgsl",
            adapter: adapter.clone(),
        };
        if 2 * plen as u64 > u64::from(u32::MAX) {
            return Err(too_large("grid values", 2 * plen as u64).into());
        }
        let field_bytes = 2 * plen as u64 * 4;
        for name in FIELDS {
            ctx.check_storage_buffer(
                &format!("the {name} field of a {nx}x{ny}x{nz} grid"),
                field_bytes,
            )?;
        }
        let sweep_groups = [
            (h as u32).div_ceil(WG_X),
            (ny as u32).div_ceil(WG_Y),
            nz as u32,
        ];
        for g in sweep_groups {
            ctx.check_workgroups("the FLD sweep", g)?;
        }
        Ok(sweep_groups)
    }

    /// Uploads the packed state of `host` (built from `config`, limits already checked by
    /// [`GpuFld::check_limits`]) and binds it to `kernel` ([`GpuFld::kernel`]); the GPU raises
    /// its `done` flag below `tolerance` (0: never, as the multigrid smoother of every level
    /// runs).
    pub(super) fn upload(
        ctx: &'a GpuContext,
        kernel: &Kernel,
        host: &CpuFld<f32>,
        config: &FldConfig,
        tolerance: f64,
        t0: Instant,
    ) -> Result<Self, SolverError> {
        let grid = *host.grid();
        let [nx, ny, nz] = grid.n;
        let h = nx.div_ceil(2);
        let plen = nz * ny * h;
        let sweep_groups = Self::check_limits(ctx, &grid)?;
        let field_bytes = 2 * plen as u64 * 4;
        let partials_per_color = sweep_groups.iter().product::<u32>();
        let fld = !config.limiter.is_constant();
        let boundary_list: Vec<u32> = if fld {
            (0..grid.len())
                .filter(|&n| {
                    let [i, j, k] = grid.coords(n);
                    grid.is_boundary(i, j, k)
                })
                .map(|n| n as u32)
                .collect()
        } else {
            Vec::new()
        };
        let bcount = boundary_list.len() as u32;
        let bgroups = bcount.div_ceil(WG_BOUNDARY).max(1);
        let boundary_groups = ctx.split_workgroups("the FLD boundary-layer update", bgroups)?;
        let check_every = 32u32;
        let window = super::residual::ResidualWindow::new(&grid, host.residual_margin());
        let (lo, hi) = (window.lo, window.hi);
        let p = host.params();
        let base = GpuParams {
            nx: nx as u32,
            ny: ny as u32,
            nz: nz as u32,
            h: h as u32,
            plen: plen as u32,
            color: 0,
            lo: lo as u32,
            hi_x: hi[0] as u32,
            hi_y: hi[1] as u32,
            hi_z: hi[2] as u32,
            boundary_count: bcount,
            boundary_row: boundary_groups[0] * WG_BOUNDARY,
            partials_per_color,
            chunk: check_every,
            _pad0: 0,
            _pad1: 0,
            omega: p.omega,
            one_minus_omega: p.one_minus_omega,
            inv_2dl: p.inv_2dl,
            inv_dl2: p.inv_dl2,
            floor: p.floor,
            theta: p.theta,
            one_minus_theta: p.one_minus_theta,
            larsen_n: larsen_n(config.limiter),
            tolerance: tolerance as f32,
            inv_residual_count: 1.0 / host.residual_count() as f32,
            _pad2: 0.0,
            _pad3: 0.0,
        };
        let needed = 5 * field_bytes + 8 * u64::from(partials_per_color) + 4 * u64::from(bcount);
        let fields = host.packed_fields();
        let buffers = ctx.allocating(
            &format!("FLD buffers for a {nx}x{ny}x{nz} grid"),
            needed,
            |d| {
                let [phi, dcoef, sig, absorb, src] = [0, 1, 2, 3, 4].map(|f| {
                    let data = [&fields[f][0][..], &fields[f][1][..]].concat();
                    storage_buffer(d, FIELDS[f], bytemuck::cast_slice(&data))
                });
                let st = vec![0u32; 4 + check_every as usize];
                let partials = vec![0u8; 8 * partials_per_color as usize];
                let params = [0u32, 1]
                    .map(|color| uniform_buffer(d, "fld params", &GpuParams { color, ..base }));
                Buffers {
                    params,
                    phi,
                    dcoef,
                    sig,
                    absorb,
                    src,
                    partials: storage_buffer(d, "partials", &partials),
                    state: storage_buffer(d, "state", bytemuck::cast_slice(&st)),
                    boundary: storage_buffer(d, "boundary", bytemuck::cast_slice(&boundary_list)),
                }
            },
        )?;
        let pipelines = [
            kernel.pipeline("boundary_d")?,
            kernel.pipeline("sweep")?,
            kernel.pipeline("reduce")?,
        ];
        let b = &buffers;
        let bind = |params: &wgpu::Buffer| {
            kernel.bind(
                ctx,
                &[
                    ("P", params),
                    ("phi", &b.phi),
                    ("dcoef", &b.dcoef),
                    ("sig", &b.sig),
                    ("absorb", &b.absorb),
                    ("src", &b.src),
                    ("partials", &b.partials),
                    ("state", &b.state),
                    ("boundary", &b.boundary),
                ],
            )
        };
        let binds = [bind(&b.params[0])?, bind(&b.params[1])?];
        ctx.check_lost()?;
        Ok(Self {
            ctx,
            grid,
            max_iterations: config.max_iterations,
            j_ref: host.j_ref(),
            trivial: host.is_trivial(),
            h,
            check_every,
            fld,
            boundary_groups,
            sweep_groups,
            fields: [
                buffers.phi,
                buffers.dcoef,
                buffers.sig,
                buffers.absorb,
                buffers.src,
            ],
            state: buffers.state,
            pipelines,
            binds,
            iterations: 0,
            residuals: Vec::new(),
            setup_seconds: t0.elapsed().as_secs_f64(),
        })
    }

    /// The packed fields φ, D, σ, absorption and source on the device (the multigrid levels
    /// bind them to their transfer kernels).
    pub(super) fn fields(&self) -> &[wgpu::Buffer; 5] {
        &self.fields
    }

    /// Iterations recorded per submission before the state is read back.
    pub fn check_every(&self) -> u32 {
        self.check_every
    }

    /// How the iteration time is measured on this device.
    pub fn timer(&self) -> Timer {
        self.ctx.timer()
    }

    /// Records `n` red-black iterations (boundary D, red sweep, black sweep, reduce) into
    /// `pass`. Iterations past convergence are no-ops on the GPU.
    pub(crate) fn record_iterations(&self, pass: &mut wgpu::ComputePass<'_>, n: u32) {
        let [boundary, sweep, reduce] = &self.pipelines;
        for _ in 0..n {
            if self.fld {
                pass.set_pipeline(boundary);
                pass.set_bind_group(0, &self.binds[0], &[]);
                pass.dispatch_workgroups(self.boundary_groups[0], self.boundary_groups[1], 1);
            }
            pass.set_pipeline(sweep);
            for bind in &self.binds {
                pass.set_bind_group(0, bind, &[]);
                let [x, y, z] = self.sweep_groups;
                pass.dispatch_workgroups(x, y, z);
            }
            pass.set_pipeline(reduce);
            pass.set_bind_group(0, &self.binds[0], &[]);
            pass.dispatch_workgroups(1, 1, 1);
        }
    }

    /// Benchmarks: records `n` iterations in one compute pass, submits and waits, and returns
    /// their seconds (GPU timestamps when the device has them, else the wall clock around
    /// submit and wait). Convergence is not checked on the host: once the GPU's `done` flag
    /// is set the remaining iterations are no-ops, so run with tolerance 0 to time real work.
    pub fn time_iterations(&mut self, n: u32) -> Result<f64, SolverError> {
        Ok(time_pass(self.ctx, "fld iterations", |pass| {
            self.record_iterations(pass, n)
        })?)
    }

    /// Bytes one iteration must move at least (as [`CpuFld::bytes_per_iteration`] in f32:
    /// 9 values per voxel for FLD, 7 for CDA).
    pub fn bytes_per_iteration(&self) -> usize {
        (if self.fld { 9 } else { 7 }) * self.grid.len() * 4
    }

    /// Iterates to convergence, the iteration cap or a non-finite residual, calling
    /// `observer(iteration, residual)` for every iteration as its residual is read back
    /// (every [`GpuFld::check_every`] iterations).
    pub fn solve_observed(
        mut self,
        mut observer: impl FnMut(usize, f64),
    ) -> Result<FldSolution<f32>, SolverError> {
        let run = if self.trivial {
            Checkpoints {
                stop: Status::Converged,
                seconds: 0.0,
                timer: self.ctx.timer(),
            }
        } else {
            let (ctx, max, every) = (self.ctx, self.max_iterations, self.check_every);
            let cap = Status::Cap;
            run_checkpointed(
                ctx,
                &mut self,
                "fld iterations",
                max,
                every,
                cap,
                &mut observer,
            )?
        };
        let phi = self.phi()?;
        Ok(self.solution(phi, run))
    }

    /// The solution record of a finished solve.
    fn solution(self, phi: Vec<f32>, run: Checkpoints<Status>) -> FldSolution<f32> {
        super::solution(
            self.grid,
            phi,
            self.residuals,
            self.iterations,
            run.stop,
            run.seconds,
            self.setup_seconds,
            run.timer,
        )
    }

    /// As [`GpuFld::solve_observed`] without an observer.
    pub fn solve(self) -> Result<FldSolution<f32>, SolverError> {
        self.solve_observed(|_, _| {})
    }

    /// Reads φ back (natural layout, caller's units).
    pub fn phi(&self) -> Result<Vec<f32>, SolverError> {
        let g = self.grid;
        if self.trivial {
            return Ok(vec![0.0; g.len()]);
        }
        let plen = g.n[2] * g.n[1] * self.h;
        let bytes = self.ctx.read_buffer(&self.fields[0], 2 * plen as u64 * 4)?;
        let packed: Vec<f32> = bytemuck::pod_collect_to_vec(&bytes);
        let scale = self.j_ref;
        let mut phi = Vec::with_capacity(g.len());
        for k in 0..g.n[2] {
            for j in 0..g.n[1] {
                for i in 0..g.n[0] {
                    let c = (i + j + k) & 1;
                    let v = packed[c * plen + (k * g.n[1] + j) * self.h + i / 2];
                    phi.push((f64::from(v) * scale) as f32);
                }
            }
        }
        Ok(phi)
    }
}

/// The `larsen_n` uniform of `fld.wgsl` and `multigrid.wgsl` (unused but for Larsen).
pub(super) fn larsen_n(l: FluxLimiter) -> f32 {
    match l {
        FluxLimiter::Larsen(n) => n as f32,
        _ => 2.0,
    }
}

/// The `LIMITER` override constant of `fld.wgsl`.
pub(super) fn limiter_id(l: FluxLimiter) -> u32 {
    match l {
        FluxLimiter::Cda => 0,
        FluxLimiter::Sum => 1,
        FluxLimiter::Max => 2,
        FluxLimiter::Kershaw => 3,
        FluxLimiter::Larsen(_) => 4,
        FluxLimiter::LevermorePomraning => 5,
    }
}

/// The buffers of one solve, named as the bindings of `fld.wgsl`; `params` holds the colour-0
/// and colour-1 uniforms.
struct Buffers {
    params: [wgpu::Buffer; 2],
    phi: wgpu::Buffer,
    dcoef: wgpu::Buffer,
    sig: wgpu::Buffer,
    absorb: wgpu::Buffer,
    src: wgpu::Buffer,
    partials: wgpu::Buffer,
    state: wgpu::Buffer,
    boundary: wgpu::Buffer,
}

/// Labels of the five packed fields, in the order of [`CpuFld::packed_fields`].
const FIELDS: [&str; 5] = ["phi", "D", "sigma", "absorption", "source"];

impl Checkpointed for GpuFld<'_> {
    type Stop = Status;

    fn record(&mut self, pass: &mut wgpu::ComputePass<'_>, n: u32) {
        self.record_iterations(pass, n);
    }

    /// The state buffer: iteration count, `done` flag, two pads, the last `chunk` residuals.
    fn readback(&self) -> (wgpu::Buffer, u64) {
        (self.state.clone(), 16 + 4 * u64::from(self.check_every))
    }

    fn checkpoint(
        &mut self,
        _n: u32,
        bytes: &[u8],
        observer: &mut dyn FnMut(usize, f64),
    ) -> Option<Status> {
        let words: Vec<u32> = bytes
            .chunks_exact(4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        let (iter, done) = (words[0] as usize, words[1]);
        let chunk = self.check_every as usize;
        for it in self.iterations..iter {
            let r = f64::from(f32::from_bits(words[4 + it % chunk]));
            self.residuals.push(r);
            observer(it + 1, r);
        }
        self.iterations = iter;
        match done {
            1 => Some(Status::Converged),
            2 => Some(Status::NonFinite),
            _ => None,
        }
    }
}
