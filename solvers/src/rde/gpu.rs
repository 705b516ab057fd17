//! The wgpu kernel of the RDE's FTCS step (f32), the GPU twin of [`super::cpu`]: same
//! natural layout, same per-voxel arithmetic, same stopping rule. The shader is `rde.wgsl`
//! beside this file; `GpuParams` is mirrored there as `Params`, and `SPEC` declares its
//! bindings by name (both checked against the WGSL by `tests/kernel_contract.rs`).
//!
//! The caller owns the device ([`GpuContext`]); buffers, pipelines and the two ping-pong bind
//! groups (read A write B, read B write A) are built once per problem and reused every step.
//! Steps are recorded into the caller's compute pass ([`GpuRde::record_steps`]) or, in
//! [`GpuRde::run`], into passes of [`RdeConfig::check_every`] steps submitted by the shared
//! checkpoint loop of [`crate::gpu::kernel`]: a `Steady` run reads back only the small state
//! buffer (step count, flag, residuals) between submissions, a `Frames` run nothing until a
//! snapshot; φ is read back once at the end.

use super::cpu::CpuRde;
use super::{BoundaryCondition, Coefficients, RdeConfig, RdeSolution, RdeTrace, Run};
use crate::gpu::kernel::{
    Access, Checkpointed, Checkpoints, Kernel, KernelSpec, run_checkpointed, struct_layout,
    time_pass,
};
use crate::gpu::{GpuContext, GpuError, Timer, storage_buffer, uniform_buffer};
use crate::method::Stop;
use crate::{Grid, SolverError};
use bytemuck::{Pod, Zeroable};
use std::time::Instant;

/// Threads per workgroup of `step` and `step_res` along x and y, as in `rde.wgsl`.
const WG_X: u32 = 32;
const WG_Y: u32 = 8;

/// Uniforms of `rde.wgsl` (`Params` there, same fields in the same order; 64 bytes).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub(crate) struct GpuParams {
    nx: u32,
    ny: u32,
    nz: u32,
    /// Residual-counted voxels: lo ≤ i ≤ hi_x, lo ≤ j ≤ hi_y, lo ≤ k ≤ hi_z.
    lo: u32,
    hi_x: u32,
    hi_y: u32,
    hi_z: u32,
    /// Workgroups of one step.
    groups: u32,
    /// Residual slots in the state buffer.
    chunk: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
    /// Global r.
    r: f32,
    /// Tolerance on R̄/j̄.
    tolerance: f32,
    /// 1/(counted voxels · ∆²).
    inv_count: f32,
    _pad3: f32,
}

/// What this host code assumes about `rde.wgsl`.
pub(crate) const SPEC: KernelSpec = KernelSpec {
    label: "rde.wgsl",
    source: include_str!("rde.wgsl"),
    bindings: &[
        ("P", Access::Uniform),
        ("phi_in", Access::Read),
        ("phi_out", Access::ReadWrite),
        ("beta", Access::Read),
        ("absorb", Access::Read),
        ("src", Access::Read),
        ("rloc", Access::Read),
        ("partials", Access::ReadWrite),
        ("state", Access::ReadWrite),
    ],
    entries: &["step", "step_res", "reduce"],
    constants: &["OP", "NEUMANN", "LOCAL"],
    uniforms: &[(
        "P",
        struct_layout!(
            GpuParams;
            nx, ny, nz, lo, hi_x, hi_y, hi_z, groups, chunk, _pad0, _pad1, _pad2, r,
            tolerance, inv_count, _pad3
        ),
    )],
};

/// The GPU state of one RDE run: built once per problem, reused every step.
#[derive(Debug)]
pub struct GpuRde<'a> {
    ctx: &'a GpuContext,
    grid: Grid,
    run: Run,
    check_every: u32,
    /// [`super::SteadyStop::ErrorBound`]: stopped by the host between blocks.
    by_error: bool,
    /// The `Steady` tolerance (of the error bound when `by_error`).
    tolerance: f64,
    j_ref: f64,
    trivial: bool,
    groups: [u32; 3],
    /// φ at even steps (A, the initial field) and odd steps (B).
    phi: [wgpu::Buffer; 2],
    state: wgpu::Buffer,
    /// `step`, `step_res`, `reduce`.
    pipelines: [wgpu::ComputePipeline; 3],
    /// Read A write B, and read B write A.
    binds: [wgpu::BindGroup; 2],
    /// Steps recorded so far (the field is in `phi[steps % 2]`).
    steps: usize,
    /// Steps completed on the GPU in a `Steady` run, as last read back.
    done_steps: usize,
    residuals: Vec<f64>,
    trace: RdeTrace<f32>,
    setup_seconds: f64,
}

impl<'a> GpuRde<'a> {
    /// Validates the inputs exactly as [`CpuRde::new`] does (whose setup is the single source
    /// of the initial state), checks the device limits, uploads and builds the pipelines.
    pub fn new(
        ctx: &'a GpuContext,
        coef: &Coefficients,
        config: &RdeConfig,
    ) -> Result<Self, SolverError> {
        let t0 = Instant::now();
        let grid = coef.grid;
        let [nx, ny, nz] = grid.n;
        let voxels = grid.len() as u64;
        if voxels > u64::from(u32::MAX) {
            return Err(GpuError::TooLarge {
                what: format!("the {nx}x{ny}x{nz} grid"),
                needed: voxels,
                limit: u64::from(u32::MAX),
                limit_name: "u32 indexing in rde.wgsl",
                adapter: ctx.info().name.clone(),
            }
            .into());
        }
        let field_bytes = voxels * 4;
        ctx.check_storage_buffer(&format!("a field of the {nx}x{ny}x{nz} grid"), field_bytes)?;
        let groups = [
            (nx as u32).div_ceil(WG_X),
            (ny as u32).div_ceil(WG_Y),
            nz as u32,
        ];
        for g in groups {
            ctx.check_workgroups("the RDE step", g)?;
        }
        let n_groups: u32 = groups.iter().product();
        let host = CpuRde::<f32>::new(coef, config)?;
        let w = host.window();
        let dl = grid.dl;
        let check_every = config.check_every;
        let params = GpuParams {
            nx: nx as u32,
            ny: ny as u32,
            nz: nz as u32,
            lo: w.lo as u32,
            hi_x: w.hi[0] as u32,
            hi_y: w.hi[1] as u32,
            hi_z: w.hi[2] as u32,
            groups: n_groups,
            chunk: check_every,
            _pad0: 0,
            _pad1: 0,
            _pad2: 0,
            r: host.r() as f32,
            // The error-bound stop is decided on the host between blocks: the device stops only
            // on a non-finite residual.
            tolerance: if config.stop == super::SteadyStop::ErrorBound {
                0.0
            } else {
                host.tolerance() as f32
            },
            inv_count: (1.0 / (w.count as f64 * dl * dl)) as f32,
            _pad3: 0.0,
        };
        let [phi0, beta, absorb, src, rloc] = host.fields();
        let local = !rloc.is_empty();
        let needed = (5 + u64::from(local)) * field_bytes + 4 * u64::from(n_groups);
        let b = ctx.allocating(
            &format!("RDE buffers for a {nx}x{ny}x{nz} grid"),
            needed,
            |d| {
                let st = vec![0u32; 4 + check_every as usize];
                Buffers {
                    params: uniform_buffer(d, "rde params", &params),
                    phi: [
                        storage_buffer(d, "phi A", bytemuck::cast_slice(phi0)),
                        storage_buffer(d, "phi B", bytemuck::cast_slice(phi0)),
                    ],
                    beta: storage_buffer(d, "beta", bytemuck::cast_slice(beta)),
                    absorb: storage_buffer(d, "absorb", bytemuck::cast_slice(absorb)),
                    src: storage_buffer(d, "src", bytemuck::cast_slice(src)),
                    rloc: storage_buffer(d, "rloc", bytemuck::cast_slice(rloc)),
                    partials: storage_buffer(d, "partials", &vec![0u8; 4 * n_groups as usize]),
                    state: storage_buffer(d, "state", bytemuck::cast_slice(&st)),
                }
            },
        )?;
        let kernel = Kernel::new(
            ctx,
            &SPEC,
            &[
                ("OP", f64::from(config.operator.id())),
                (
                    "NEUMANN",
                    f64::from(u8::from(config.boundary == BoundaryCondition::Neumann)),
                ),
                ("LOCAL", f64::from(u8::from(local))),
            ],
        )?;
        let pipelines = [
            kernel.pipeline("step")?,
            kernel.pipeline("step_res")?,
            kernel.pipeline("reduce")?,
        ];
        let bind = |from: usize| {
            kernel.bind(
                ctx,
                &[
                    ("P", &b.params),
                    ("phi_in", &b.phi[from]),
                    ("phi_out", &b.phi[1 - from]),
                    ("beta", &b.beta),
                    ("absorb", &b.absorb),
                    ("src", &b.src),
                    ("rloc", &b.rloc),
                    ("partials", &b.partials),
                    ("state", &b.state),
                ],
            )
        };
        let binds = [bind(0)?, bind(1)?];
        ctx.check_lost()?;
        Ok(Self {
            ctx,
            grid,
            run: config.run,
            check_every,
            by_error: config.stop == super::SteadyStop::ErrorBound,
            tolerance: host.tolerance(),
            j_ref: host.j_ref(),
            trivial: host.is_trivial(),
            groups,
            phi: b.phi,
            state: b.state,
            pipelines,
            binds,
            steps: 0,
            done_steps: 0,
            residuals: Vec::new(),
            trace: host.trace().clone(),
            setup_seconds: t0.elapsed().as_secs_f64(),
        })
    }

    /// Bytes one step moves at least (as [`CpuRde::bytes_per_step`] in f32).
    pub fn bytes_per_step(&self) -> usize {
        (if self.trace.local { 6 } else { 5 }) * self.grid.len() * 4
    }

    /// Records `n` plain steps into the caller's `pass` (one dispatch each, alternating the
    /// ping-pong bind groups); the caller submits.
    pub fn record_steps(&mut self, pass: &mut wgpu::ComputePass<'_>, n: u32) {
        pass.set_pipeline(&self.pipelines[0]);
        let [x, y, z] = self.groups;
        for _ in 0..n {
            pass.set_bind_group(0, &self.binds[self.steps % 2], &[]);
            pass.dispatch_workgroups(x, y, z);
            self.steps += 1;
        }
    }

    /// Records `n` steps with residuals (`step_res`, then `reduce`, each step).
    fn record_residual_steps(&mut self, pass: &mut wgpu::ComputePass<'_>, n: u32) {
        let [x, y, z] = self.groups;
        for _ in 0..n {
            pass.set_pipeline(&self.pipelines[1]);
            pass.set_bind_group(0, &self.binds[self.steps % 2], &[]);
            pass.dispatch_workgroups(x, y, z);
            pass.set_pipeline(&self.pipelines[2]);
            pass.dispatch_workgroups(1, 1, 1);
            self.steps += 1;
        }
    }

    /// Benchmarks: records `n` plain steps in one timed pass, submits, waits and returns their
    /// seconds (GPU timestamps when the device has them, else the wall clock).
    pub fn time_steps(&mut self, n: u32) -> Result<f64, SolverError> {
        let ctx = self.ctx;
        Ok(time_pass(ctx, "rde steps", |pass| {
            self.record_steps(pass, n)
        })?)
    }

    /// Reads the current φ back (natural layout, caller's units).
    pub fn phi(&self) -> Result<Vec<f32>, SolverError> {
        let g = self.grid;
        if self.trivial {
            return Ok(vec![0.0; g.len()]);
        }
        let bytes = self
            .ctx
            .read_buffer(&self.phi[self.current()], g.len() as u64 * 4)?;
        let v: Vec<f32> = bytemuck::pod_collect_to_vec(&bytes);
        Ok(v.iter()
            .map(|&x| (f64::from(x) * self.j_ref) as f32)
            .collect())
    }

    /// The buffer holding the current field.
    fn current(&self) -> usize {
        match self.run {
            Run::Steady { .. } => self.done_steps % 2,
            Run::Frames { .. } => self.steps % 2,
        }
    }

    /// Runs the configured mode.
    pub fn run(self) -> Result<RdeSolution<f32>, SolverError> {
        self.run_observed(|_, _| {})
    }

    /// As [`GpuRde::run`], calling `observer(step, R̄/j̄)` for every step of a `Steady` run as
    /// its residual is read back.
    pub fn run_observed(
        mut self,
        mut observer: impl FnMut(usize, f64),
    ) -> Result<RdeSolution<f32>, SolverError> {
        let ctx = self.ctx;
        let every = self.check_every;
        let (stop, seconds, timer) = if self.trivial {
            (Stop::Converged, 0.0, ctx.timer())
        } else {
            match self.run {
                Run::Steady { max_steps, .. } if self.by_error => {
                    // Blocks of `every` steps, φ read back after each (module docs of
                    // `super`, "Stopping rule"): the same blocks as the CPU.
                    let mut bound = super::ErrorBound::default();
                    bound.observe(&self.phi()?);
                    let (mut seconds, mut timer, mut stop) = (0.0, ctx.timer(), Stop::Cap);
                    while self.done_steps < max_steps {
                        let n = (every as usize).min(max_steps - self.done_steps);
                        let run = run_checkpointed(
                            ctx,
                            &mut self,
                            "rde steps",
                            n,
                            every,
                            Stop::Cap,
                            &mut observer,
                        )?;
                        seconds += run.seconds;
                        timer = run.timer;
                        if run.stop != Stop::Cap {
                            stop = run.stop;
                            break;
                        }
                        let e = bound.observe(&self.phi()?);
                        self.trace.error_estimates.push((self.done_steps, e));
                        if e < self.tolerance {
                            stop = Stop::Converged;
                            break;
                        }
                    }
                    (stop, seconds, timer)
                }
                Run::Steady { max_steps, .. } => {
                    let run = run_checkpointed(
                        ctx,
                        &mut self,
                        "rde steps",
                        max_steps,
                        every,
                        Stop::Cap,
                        &mut observer,
                    )?;
                    (run.stop, run.seconds, run.timer)
                }
                Run::Frames {
                    steps,
                    snapshot_every,
                } => {
                    let chunk = if snapshot_every > 0 {
                        snapshot_every
                    } else {
                        steps.max(1)
                    };
                    let mut seconds = 0.0;
                    let mut timer = ctx.timer();
                    while self.steps < steps {
                        let n = chunk.min(steps - self.steps);
                        let run: Checkpoints<Stop> = run_checkpointed(
                            ctx,
                            &mut self,
                            "rde frames",
                            n,
                            every,
                            Stop::Cap,
                            &mut observer,
                        )?;
                        seconds += run.seconds;
                        timer = run.timer;
                        if snapshot_every > 0 && self.steps % snapshot_every == 0 {
                            let snap = self.phi()?;
                            self.trace.snapshots.push((self.steps, snap));
                        }
                    }
                    let phi = self.phi()?;
                    let stop = if phi.iter().all(|x| x.is_finite()) {
                        Stop::Cap
                    } else {
                        Stop::NonFinite
                    };
                    (stop, seconds, timer)
                }
            }
        };
        let phi = self.phi()?;
        let steps = match self.run {
            Run::Steady { .. } => self.done_steps,
            Run::Frames { .. } => self.steps,
        };
        let mut trace = std::mem::take(&mut self.trace);
        trace.residuals = std::mem::take(&mut self.residuals);
        Ok(super::solution(
            self.grid,
            phi,
            steps,
            stop,
            seconds,
            self.setup_seconds,
            timer,
            trace,
            self.grid.dl,
        ))
    }

    /// How the step time is measured on this device.
    pub fn timer(&self) -> Timer {
        self.ctx.timer()
    }
}

/// The buffers of one run, named as the bindings of `rde.wgsl`.
struct Buffers {
    params: wgpu::Buffer,
    phi: [wgpu::Buffer; 2],
    beta: wgpu::Buffer,
    absorb: wgpu::Buffer,
    src: wgpu::Buffer,
    rloc: wgpu::Buffer,
    partials: wgpu::Buffer,
    state: wgpu::Buffer,
}

impl Checkpointed for GpuRde<'_> {
    type Stop = Stop;

    fn record(&mut self, pass: &mut wgpu::ComputePass<'_>, n: u32) {
        match self.run {
            Run::Steady { .. } => self.record_residual_steps(pass, n),
            Run::Frames { .. } => self.record_steps(pass, n),
        }
    }

    /// The state buffer: step count, `done` flag, two pads, the last `chunk` residuals.
    fn readback(&self) -> (wgpu::Buffer, u64) {
        (self.state.clone(), 16 + 4 * u64::from(self.check_every))
    }

    fn checkpoint(
        &mut self,
        _n: u32,
        bytes: &[u8],
        observer: &mut dyn FnMut(usize, f64),
    ) -> Option<Stop> {
        if let Run::Frames { .. } = self.run {
            return None;
        }
        let words: Vec<u32> = bytemuck::pod_collect_to_vec(bytes);
        let (iter, done) = (words[0] as usize, words[1]);
        let chunk = self.check_every as usize;
        for it in self.done_steps..iter {
            let r = f64::from(f32::from_bits(words[4 + it % chunk]));
            self.residuals.push(r);
            observer(it + 1, r);
        }
        self.done_steps = iter;
        match done {
            1 => Some(Stop::Converged),
            2 => Some(Stop::NonFinite),
            _ => None,
        }
    }
}
