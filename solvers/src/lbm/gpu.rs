//! The wgpu kernel of the lattice-Boltzmann update (f32), the GPU twin of [`super::cpu`]:
//! same z-slab layout, same per-site arithmetic (LB Eqs 4–6 with the decisions of
//! [`super`]), same stopping rule evaluated at checkpoints. The shader is `lbm.wgsl` beside
//! this file; `GpuParams` is mirrored there as `Params`, and `SPEC` declares its bindings by
//! name (both checked against the WGSL by `tests/kernel_contract.rs`).
//!
//! Two state buffers ping-pong: a step reads one and writes the other, one dispatch per
//! step. Every [`LbmConfig::check_every`] steps the last step of a submission is `step_reduce` (the same update plus per-workgroup sums), followed by
//! `reduce`, which adds the partials in a fixed order; only those three totals are read back.
//! The state is read back once at the end, and φ is formed on the host by the CPU code.

use super::cpu::{Setup, steady};
use super::{Injection, LbmConfig, LbmSolution, LbmTrace, Q, StepRecord};
use crate::gpu::kernel::{
    Access, Checkpointed, Checkpoints, Kernel, KernelSpec, run_checkpointed, struct_layout,
    time_pass,
};
use crate::gpu::{GpuContext, GpuError, storage_buffer, uniform_buffer};
use crate::method::Stop as Status;
use crate::{Grid, Medium, SolverError};
use bytemuck::{Pod, Zeroable};
use std::time::Instant;

/// Threads per workgroup of every kernel in `lbm.wgsl`.
const WG: u32 = 256;

/// Uniforms of `lbm.wgsl` (`Params` there, same fields in the same order; 32 bytes).
/// Checked against the WGSL by `tests/kernel_contract.rs`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub(crate) struct GpuParams {
    nx: u32,
    ny: u32,
    nz: u32,
    /// Sites nx·ny·nz.
    sites: u32,
    /// Threads per dispatch row (x workgroups × 256).
    row: u32,
    /// 1: re-emit the rest density (paper); 0: absorbed density is removed.
    reemit: u32,
    /// 1 if the emission buffer holds a source.
    has_src: u32,
    /// Workgroups of one step (partials of `step_reduce`).
    groups: u32,
}

/// What this host code assumes about `lbm.wgsl`: bindings by name, entry points, the `ISO`
/// override and the layout of `Params`.
pub(crate) const SPEC: KernelSpec = KernelSpec {
    label: "lbm.wgsl",
    source: include_str!("lbm.wgsl"),
    bindings: &[
        ("P", Access::Uniform),
        ("fin", Access::Read),
        ("fout", Access::ReadWrite),
        ("ss", Access::Read),
        ("sa", Access::Read),
        ("emission", Access::Read),
        ("table", Access::Read),
        ("partials", Access::ReadWrite),
        ("totals", Access::ReadWrite),
    ],
    entries: &["step", "step_reduce", "reduce"],
    constants: &["ISO"],
    uniforms: &[(
        "P",
        struct_layout!(GpuParams; nx, ny, nz, sites, row, reemit, has_src, groups),
    )],
};

/// The GPU state of one lattice-Boltzmann solve: buffers, pipelines and bind groups built
/// once for one problem size.
#[derive(Debug)]
pub struct GpuLbm<'a> {
    ctx: &'a GpuContext,
    setup: Setup<f32>,
    dispatch: [u32; 2],
    /// The two state buffers; `parity` says which holds the current state.
    states: [wgpu::Buffer; 2],
    totals: wgpu::Buffer,
    /// The `step`, `step_reduce` and `reduce` pipelines.
    pipelines: [wgpu::ComputePipeline; 3],
    /// Bind group reading state 0 and writing state 1, and the reverse.
    binds: [wgpu::BindGroup; 2],
    parity: usize,
    check_every: u32,
    steps: usize,
    history: Vec<StepRecord>,
    /// Total density at the previous checkpoint (NaN before the first).
    previous: f64,
}

impl<'a> GpuLbm<'a> {
    /// Validates the inputs exactly as [`super::CpuLbm::new`] does, checks the device limits
    /// for this grid, uploads the medium and builds the pipelines.
    pub fn new(
        ctx: &'a GpuContext,
        medium: &Medium<f64>,
        injection: &Injection,
        config: &LbmConfig,
    ) -> Result<Self, SolverError> {
        let t0 = Instant::now();
        super::cpu::validate(medium, injection, config)?;
        let grid = medium.grid;
        let [nx, ny, nz] = grid.n;
        let sites = grid.len() as u64;
        let adapter = ctx.info().name.clone();
        if Q as u64 * sites > u64::from(u32::MAX) {
            return Err(GpuError::TooLarge {
                what: format!("the {nx}x{ny}x{nz} lattice's 19 directions"),
                needed: Q as u64 * sites,
                limit: u64::from(u32::MAX),
                limit_name: "u32 indexing in lbm.wgsl",
                adapter,
            }
            .into());
        }
        let state_bytes = Q as u64 * sites * 4;
        ctx.check_storage_buffer(
            &format!("a state buffer of the {nx}x{ny}x{nz} lattice"),
            state_bytes,
        )?;
        let groups = ctx.workgroup_count("LBM workgroups", sites.div_ceil(u64::from(WG)))?;
        let dispatch = ctx.split_workgroups("the LBM step", groups)?;
        let groups = dispatch[0] * dispatch[1];
        let setup = Setup::<f32>::new(medium, injection, config)?;
        let params = GpuParams {
            nx: nx as u32,
            ny: ny as u32,
            nz: nz as u32,
            sites: sites as u32,
            row: dispatch[0] * WG,
            reemit: u32::from(setup.reemit),
            has_src: u32::from(setup.src.is_some()),
            groups,
        };
        let mut table = vec![0.0f32; Q + Q * Q];
        table[..Q].copy_from_slice(&setup.inflow);
        for i in 0..Q {
            for j in 0..Q {
                table[Q + Q * i + j] = setup.scatter64.s[i][j] as f32;
            }
        }
        let needed = 2 * state_bytes + 2 * sites * 4 + 12 * u64::from(groups);
        let zeros = vec![0u8; state_bytes as usize];
        let b = ctx.allocating(
            &format!("LBM buffers for a {nx}x{ny}x{nz} lattice"),
            needed,
            |d| {
                let src: &[f32] = setup.src.as_deref().unwrap_or(&[]);
                Buffers {
                    params: uniform_buffer(d, "lbm params", &params),
                    states: [
                        storage_buffer(d, "lbm state 0", &zeros),
                        storage_buffer(d, "lbm state 1", &zeros),
                    ],
                    ss: storage_buffer(d, "sigma_s", bytemuck::cast_slice(&setup.ss)),
                    sa: storage_buffer(d, "sigma_a", bytemuck::cast_slice(&setup.sa)),
                    emission: storage_buffer(d, "emission", bytemuck::cast_slice(src)),
                    table: storage_buffer(d, "lbm table", bytemuck::cast_slice(&table)),
                    partials: storage_buffer(d, "lbm partials", &vec![0u8; 12 * groups as usize]),
                    totals: storage_buffer(d, "lbm totals", &[0u8; 16]),
                }
            },
        )?;
        drop(zeros);
        let iso = setup.scatter.is_none();
        let kernel = Kernel::new(ctx, &SPEC, &[("ISO", if iso { 1.0 } else { 0.0 })])?;
        let pipelines = [
            kernel.pipeline("step")?,
            kernel.pipeline("step_reduce")?,
            kernel.pipeline("reduce")?,
        ];
        let bind = |from: usize| {
            kernel.bind(
                ctx,
                &[
                    ("P", &b.params),
                    ("fin", &b.states[from]),
                    ("fout", &b.states[1 - from]),
                    ("ss", &b.ss),
                    ("sa", &b.sa),
                    ("emission", &b.emission),
                    ("table", &b.table),
                    ("partials", &b.partials),
                    ("totals", &b.totals),
                ],
            )
        };
        let binds = [bind(0)?, bind(1)?];
        ctx.check_lost()?;
        let mut setup = setup;
        setup.setup_seconds = t0.elapsed().as_secs_f64();
        Ok(Self {
            ctx,
            setup,
            dispatch,
            states: b.states,
            totals: b.totals,
            pipelines,
            binds,
            parity: 0,
            check_every: config.check_every,
            steps: 0,
            history: Vec::new(),
            previous: f64::NAN,
        })
    }

    /// The grid.
    pub fn grid(&self) -> &Grid {
        &self.setup.grid
    }

    /// Steps recorded so far.
    pub fn steps(&self) -> usize {
        self.steps
    }

    /// Bytes one step moves at least (19 f32 read and 19 written per site), as
    /// [`super::CpuLbm::bytes_per_step`].
    pub fn bytes_per_step(&self) -> usize {
        2 * Q * self.setup.grid.len() * 4
    }

    /// Records `n` steps into `pass` (one dispatch each, alternating the ping-pong bind
    /// groups) and advances the step count; the caller submits.
    pub(crate) fn record_steps(&mut self, pass: &mut wgpu::ComputePass<'_>, n: u32) {
        pass.set_pipeline(&self.pipelines[0]);
        for _ in 0..n {
            pass.set_bind_group(0, &self.binds[self.parity], &[]);
            pass.dispatch_workgroups(self.dispatch[0], self.dispatch[1], 1);
            self.parity = 1 - self.parity;
            self.steps += 1;
        }
    }

    /// Records one step with the reduction of its totals (`step_reduce`, then `reduce`).
    pub(crate) fn record_checkpoint(&mut self, pass: &mut wgpu::ComputePass<'_>) {
        pass.set_pipeline(&self.pipelines[1]);
        pass.set_bind_group(0, &self.binds[self.parity], &[]);
        pass.dispatch_workgroups(self.dispatch[0], self.dispatch[1], 1);
        pass.set_pipeline(&self.pipelines[2]);
        pass.dispatch_workgroups(1, 1, 1);
        self.parity = 1 - self.parity;
        self.steps += 1;
    }

    /// Benchmarks: records `n` plain steps in one timed compute pass, submits, waits and
    /// returns their seconds (GPU timestamps when available, else the wall clock).
    pub fn time_steps(&mut self, n: u32) -> Result<f64, SolverError> {
        let ctx = self.ctx;
        Ok(time_pass(ctx, "lbm steps", |pass| {
            self.record_steps(pass, n)
        })?)
    }

    /// The current state (post-collision densities, z-slab layout), read back.
    pub fn state(&self) -> Result<Vec<f32>, SolverError> {
        let bytes = (Q * self.setup.grid.len() * 4) as u64;
        let out = self.ctx.read_buffer(&self.states[self.parity], bytes)?;
        Ok(bytemuck::pod_collect_to_vec(&out))
    }

    /// Steps to the steady state (checked every `check_every` steps) or the cap, calling
    /// `observer(step, total_density)` at every checkpoint.
    pub fn solve_observed(
        mut self,
        mut observer: impl FnMut(usize, f64),
    ) -> Result<LbmSolution<f32>, SolverError> {
        let (ctx, max, every) = (self.ctx, self.setup.max_steps, self.check_every);
        let cap = Status::Cap;
        let run = run_checkpointed(ctx, &mut self, "lbm steps", max, every, cap, &mut observer)?;
        let state = self.state()?;
        Ok(self.solution(&state, run))
    }

    /// The solution record of a finished solve, from the final state.
    fn solution(self, state: &[f32], run: Checkpoints<Status>) -> LbmSolution<f32> {
        let (phi, rho) = self.setup.fields(state);
        let trace = LbmTrace {
            rho,
            history: self.history,
            clamped_sites: self.setup.clamped,
        };
        super::solution(
            self.setup.grid,
            phi,
            trace,
            self.steps,
            run.stop,
            run.seconds,
            self.setup.setup_seconds,
            run.timer,
        )
    }

    /// As [`GpuLbm::solve_observed`] without an observer.
    pub fn solve(self) -> Result<LbmSolution<f32>, SolverError> {
        self.solve_observed(|_, _| {})
    }
}

/// The buffers of one solve, named as the bindings of `lbm.wgsl` (`states` are `fin` and
/// `fout`, swapped every step).
struct Buffers {
    params: wgpu::Buffer,
    states: [wgpu::Buffer; 2],
    ss: wgpu::Buffer,
    sa: wgpu::Buffer,
    emission: wgpu::Buffer,
    table: wgpu::Buffer,
    partials: wgpu::Buffer,
    totals: wgpu::Buffer,
}

impl Checkpointed for GpuLbm<'_> {
    type Stop = Status;

    /// `n` − 1 plain steps, then one with the reduction of its totals.
    fn record(&mut self, pass: &mut wgpu::ComputePass<'_>, n: u32) {
        self.record_steps(pass, n.saturating_sub(1));
        self.record_checkpoint(pass);
    }

    /// The three totals (density, outflow, absorbed) and a pad.
    fn readback(&self) -> (wgpu::Buffer, u64) {
        (self.totals.clone(), 16)
    }

    fn checkpoint(
        &mut self,
        n: u32,
        bytes: &[u8],
        observer: &mut dyn FnMut(usize, f64),
    ) -> Option<Status> {
        let t: Vec<f32> = bytemuck::pod_collect_to_vec(bytes);
        let rec = StepRecord {
            step: self.steps,
            total_density: f64::from(t[0]),
            injected: self.setup.injected,
            outflow: f64::from(t[1]),
            absorbed: f64::from(t[2]),
        };
        self.history.push(rec);
        observer(rec.step, rec.total_density);
        let total = rec.total_density;
        if !total.is_finite() {
            return Some(Status::NonFinite);
        }
        if steady(self.previous, total, n as usize, self.setup.tolerance) {
            return Some(Status::Converged);
        }
        self.previous = total;
        None
    }
}
