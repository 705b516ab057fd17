//! The wgpu kernel of one ordinate's propagation (f32), the GPU twin of [`super::cpu`]: same
//! cell layout, same per-cell arithmetic in the same order (POP Eqs 2–8 with the decisions of
//! [`super`]), the same stopping rule (D9) evaluated at checkpoints. The shader is `pop.wgsl`
//! beside this file; `GpuParams` is mirrored there as `Params`, and `SPEC` declares its
//! bindings by name (both checked against the WGSL by `tests/kernel_contract.rs`).
//!
//! **What runs where.** The host builds the ordinate's [`CpuPop`] as the CPU solve does: the
//! medium resampled at the cell centres, the per-link T, γ and ghost transmittance, the
//! per-cell u of Eq 8 and the injection (D1), with its ledger. [`GpuPop::load`] uploads the
//! state, links, accumulators and u once into buffers that [`GpuPop::new`] allocated once per
//! grid size and that every ordinate of a solve reuses. One step is two dispatches:
//! `fractions_step` (the Eq 3 fractions of every lit cell and where its light goes: absorbed
//! by the link, or out through a face; each cell adds its own share to a per-cell loss
//! accumulator, so no step needs a reduction) and `gather` (the 6-neighbour gather, Eqs 5–6,
//! and φ, J, L_acc of Eqs 7–8), ping-ponging the (L, a) buffers. Every K steps a
//! checkpoint adds `reduce`: one workgroup per slice and channel sums the loss accumulators
//! and the power in flight of its slice in a fixed order; only those n·nc·5 floats are read
//! back, and the host adds them in slice order in f64 (no float atomics: bitwise-repeatable).
//! With ε_L = 0 (the paper's fixed M) the host reads nothing until the end (at most
//! [`MAX_BATCH`] steps per submission). The accumulators are read back once per ordinate.
//!
//! **The stop at checkpoints.** The CPU tests R^m/P_inj < ε_L after every step; the GPU
//! after every K-th (and after the last), so it stops at the first checkpoint at or after the
//! CPU's step: up to K − 1 steps later (R^m never rises, T3). Those extra steps add to φ the
//! little light still in flight (< ε_L of the injected power per step).

use super::cpu::{CpuPop, K, Ledger, S, worse_residual};
use super::{Lateral, OrdinateRun, PopConfig, PopMedium, PopSolution};
use crate::SolverError;
use crate::gpu::kernel::{
    Access, Checkpointed, Kernel, KernelSpec, run_checkpointed, struct_layout, time_pass,
};
use crate::gpu::{GpuContext, GpuError, storage_buffer, uniform_buffer};
use crate::method::Stop;
use bytemuck::{Pod, Zeroable};

/// Threads per workgroup of every kernel in `pop.wgsl`.
const WG: u32 = 64;

/// Steps between two read-backs of the ledger under a relative stop (ε_L > 0).
pub const DEFAULT_CHECK_EVERY: u32 = 8;

/// The most steps recorded into one submission (fixed-M runs submit ⌈M/`MAX_BATCH`⌉ times).
pub const MAX_BATCH: u32 = 1024;

/// Floats per slice and channel in the `partials` buffer: absorbed, exit back, exit front,
/// exit side, in flight.
const PARTIAL: usize = 5;

/// Uniforms of `pop.wgsl` (`Params` there, same fields in the same order; 32 bytes).
/// Checked against the WGSL by `tests/kernel_contract.rs`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub(crate) struct GpuParams {
    /// Cells per axis.
    n: u32,
    /// Channels.
    nc: u32,
    /// n³.
    cells: u32,
    /// n².
    plane: u32,
    /// Threads per dispatch row (x workgroups × 64).
    row: u32,
    /// 1: laterally periodic faces.
    periodic: u32,
    /// 1: accumulate the Eq 8 radiance.
    has_view: u32,
    /// Workgroups of `reduce` (n·nc).
    groups: u32,
}

/// What this host code assumes about `pop.wgsl`: bindings by name, entry points and the
/// layout of `Params`.
pub(crate) const SPEC: KernelSpec = KernelSpec {
    label: "pop.wgsl",
    source: include_str!("pop.wgsl"),
    bindings: &[
        ("P", Access::Uniform),
        ("lin", Access::Read),
        ("lout", Access::ReadWrite),
        ("links", Access::Read),
        ("frac", Access::ReadWrite),
        ("acc", Access::ReadWrite),
        ("loss", Access::ReadWrite),
        ("view", Access::Read),
        ("partials", Access::ReadWrite),
    ],
    entries: &["fractions_step", "gather", "reduce"],
    constants: &[],
    uniforms: &[(
        "P",
        struct_layout!(GpuParams; n, nc, cells, plane, row, periodic, has_view, groups),
    )],
};

/// The buffers of one grid size, named as the bindings of `pop.wgsl` (`states` are `lin`
/// and `lout`, swapped every step).
#[derive(Debug)]
struct Buffers {
    params: wgpu::Buffer,
    states: [wgpu::Buffer; 2],
    links: wgpu::Buffer,
    frac: wgpu::Buffer,
    acc: wgpu::Buffer,
    loss: wgpu::Buffer,
    view: wgpu::Buffer,
    partials: wgpu::Buffer,
}

/// The GPU propagation state of one grid size (n³ cells, nc channels, one lateral boundary,
/// with or without an observer): buffers, pipelines and bind groups built once; ordinates
/// are loaded into it one after the other ([`GpuPop::load`]).
#[derive(Debug)]
pub struct GpuPop<'a> {
    ctx: &'a GpuContext,
    n: usize,
    nc: usize,
    lateral: Lateral,
    has_view: bool,
    dispatch: [u32; 2],
    groups: u32,
    b: Buffers,
    /// `fractions_step`, `gather`, `reduce`.
    pipelines: [wgpu::ComputePipeline; 3],
    /// Bind group reading state 0 and writing state 1, and the reverse.
    binds: [wgpu::BindGroup; 2],
    parity: usize,
    check_every: u32,
    /// Cell edge of the loaded grid (for the ledger's Δx²).
    dx: f64,
    /// The ledger at load (injection, and whatever the CPU had run), per channel.
    base: Vec<Ledger>,
    ledger: Vec<Ledger>,
    /// (step, max over channels of R/P_inj) at each checkpoint.
    history: Vec<(usize, f64)>,
    steps: usize,
    tolerance: f64,
}

impl<'a> GpuPop<'a> {
    /// Checks the device limits for `n`³ cells of `channels` channels and allocates every
    /// buffer and pipeline once (typed errors before any allocation).
    pub fn new(
        ctx: &'a GpuContext,
        n: usize,
        channels: usize,
        lateral: Lateral,
        has_view: bool,
    ) -> Result<Self, SolverError> {
        let adapter = ctx.info().name.clone();
        if n < 2 || channels == 0 {
            return Err(SolverError::BadParameter {
                name: "pop.n",
                value: n as f64,
                reason: "a GPU propagation grid needs n ≥ 2 and at least one channel",
            });
        }
        let cells = (n as u64).saturating_pow(3);
        let slots = cells.saturating_mul(channels as u64);
        // The largest index the shader forms: links at slot·7 + 6, and link cells packed as
        // cell·8 + axis.
        let largest = slots.saturating_mul(K as u64).max(cells.saturating_mul(8));
        if largest > u64::from(u32::MAX) {
            return Err(GpuError::TooLarge {
                what: format!("a POP grid of {n}³ cells × {channels} channels"),
                needed: largest,
                limit: u64::from(u32::MAX),
                limit_name: "u32 indexing in pop.wgsl",
                adapter,
            }
            .into());
        }
        let what = |b: &str| format!("the {b} buffer of a {n}³ × {channels} POP grid");
        let state_bytes = slots * S as u64 * 4;
        let links_bytes = slots * K as u64 * 4;
        let frac_bytes = slots * 3 * 4;
        let acc_bytes = slots * super::cpu::ACC as u64 * 4;
        let loss_bytes = slots * 4 * 4;
        let view_bytes = (channels as u64 + if has_view { cells } else { 0 }) * 4;
        let groups64 = (n as u64) * channels as u64;
        let partial_bytes = groups64 * PARTIAL as u64 * 4;
        for (name, bytes) in [
            ("state", state_bytes),
            ("links", links_bytes),
            ("fractions", frac_bytes),
            ("accumulator", acc_bytes),
            ("loss", loss_bytes),
            ("view", view_bytes),
            ("partials", partial_bytes),
        ] {
            ctx.check_storage_buffer(&what(name), bytes)?;
        }
        let groups = ctx.workgroup_count("POP reduce workgroups", groups64)?;
        ctx.check_workgroups(
            "the POP reduction (one workgroup per slice and channel)",
            groups,
        )?;
        let cell_groups = ctx.workgroup_count("POP workgroups", cells.div_ceil(u64::from(WG)))?;
        let dispatch = ctx.split_workgroups("the POP step", cell_groups)?;
        let params = GpuParams {
            n: n as u32,
            nc: channels as u32,
            cells: cells as u32,
            plane: (n * n) as u32,
            row: dispatch[0] * WG,
            periodic: u32::from(lateral == Lateral::Periodic),
            has_view: u32::from(has_view),
            groups,
        };
        let needed = 2 * state_bytes
            + links_bytes
            + frac_bytes
            + acc_bytes
            + loss_bytes
            + view_bytes
            + partial_bytes;
        let b = ctx.allocating(&what("every"), needed, |d| {
            let zeros = |bytes: u64| vec![0u8; bytes as usize];
            Buffers {
                params: uniform_buffer(d, "pop params", &params),
                states: [
                    storage_buffer(d, "pop state 0", &zeros(state_bytes)),
                    storage_buffer(d, "pop state 1", &zeros(state_bytes)),
                ],
                links: storage_buffer(d, "pop links", &zeros(links_bytes)),
                frac: storage_buffer(d, "pop fractions", &zeros(frac_bytes)),
                acc: storage_buffer(d, "pop accumulators", &zeros(acc_bytes)),
                loss: storage_buffer(d, "pop losses", &zeros(loss_bytes)),
                view: storage_buffer(d, "pop view", &zeros(view_bytes)),
                partials: storage_buffer(d, "pop partials", &zeros(partial_bytes)),
            }
        })?;
        let kernel = Kernel::new(ctx, &SPEC, &[])?;
        let pipelines = [
            kernel.pipeline("fractions_step")?,
            kernel.pipeline("gather")?,
            kernel.pipeline("reduce")?,
        ];
        let bind = |from: usize| {
            kernel.bind(
                ctx,
                &[
                    ("P", &b.params),
                    ("lin", &b.states[from]),
                    ("lout", &b.states[1 - from]),
                    ("links", &b.links),
                    ("frac", &b.frac),
                    ("acc", &b.acc),
                    ("loss", &b.loss),
                    ("view", &b.view),
                    ("partials", &b.partials),
                ],
            )
        };
        let binds = [bind(0)?, bind(1)?];
        ctx.check_lost()?;
        Ok(Self {
            ctx,
            n,
            nc: channels,
            lateral,
            has_view,
            dispatch,
            groups,
            b,
            pipelines,
            binds,
            parity: 0,
            check_every: DEFAULT_CHECK_EVERY,
            dx: 0.0,
            base: Vec::new(),
            ledger: Vec::new(),
            history: Vec::new(),
            steps: 0,
            tolerance: 0.0,
        })
    }

    /// Sets the steps between read-backs under a relative stop (at least 1).
    pub fn with_check_every(mut self, k: u32) -> Self {
        self.check_every = k.max(1);
        self
    }

    /// Steps between read-backs under a relative stop.
    pub fn check_every(&self) -> u32 {
        self.check_every
    }

    /// Uploads the state, links, accumulators and Eq 8 directions of `cpu` (the ordinate's
    /// grid after injection, or after any number of CPU steps) and resets the loss
    /// accumulators; the ledger continues from `cpu`'s. Fails if `cpu`'s grid size, channels,
    /// lateral faces or observer differ from this state's.
    pub fn load(&mut self, cpu: &CpuPop<f32>) -> Result<(), SolverError> {
        let parts = cpu.parts();
        let grid = cpu.grid();
        if grid.n != self.n
            || cpu.channels() != self.nc
            || parts.lateral != self.lateral
            || parts.view_u.is_some() != self.has_view
        {
            return Err(SolverError::Unsupported(format!(
                "GpuPop::load: a {}³ × {} grid (lateral {:?}, observer {}) into a GPU state \
                 built for {}³ × {} (lateral {:?}, observer {})",
                grid.n,
                cpu.channels(),
                parts.lateral,
                parts.view_u.is_some(),
                self.n,
                self.nc,
                self.lateral,
                self.has_view
            )));
        }
        let q = &self.ctx.queue;
        self.parity = 0;
        q.write_buffer(&self.b.states[0], 0, bytemuck::cast_slice(parts.state));
        q.write_buffer(&self.b.links, 0, bytemuck::cast_slice(parts.links));
        q.write_buffer(&self.b.acc, 0, bytemuck::cast_slice(parts.acc));
        let slots = grid.len() * self.nc;
        q.write_buffer(&self.b.loss, 0, &vec![0u8; slots * 4 * 4]);
        q.write_buffer(&self.b.frac, 0, &vec![0u8; slots * 3 * 4]);
        let mut view: Vec<f32> = parts.lobe.iter().map(|&v| v as f32).collect();
        if let Some(u) = parts.view_u {
            view.extend_from_slice(u);
        }
        q.write_buffer(&self.b.view, 0, bytemuck::cast_slice(&view));
        self.dx = grid.dx;
        self.base = parts.ledger.to_vec();
        self.ledger = parts.ledger.to_vec();
        self.history.clear();
        self.steps = parts.steps;
        self.ctx.check_lost()?;
        Ok(())
    }

    /// Steps until R/P_inj < `tolerance` in every channel at a checkpoint (0: never; a run
    /// also stops when nothing is in flight), or until `max_iterations` steps in total.
    pub fn run(&mut self, tolerance: f64, max_iterations: usize) -> Result<Stop, SolverError> {
        self.tolerance = tolerance;
        let every = if tolerance > 0.0 {
            self.check_every
        } else {
            MAX_BATCH
        };
        let remaining = max_iterations.saturating_sub(self.steps);
        let ctx = self.ctx;
        let run = run_checkpointed(
            ctx,
            self,
            "pop steps",
            remaining,
            every,
            Stop::Cap,
            &mut |_, _| {},
        )?;
        Ok(run.stop)
    }

    /// Steps run (including any the CPU ran before [`GpuPop::load`]).
    pub fn steps(&self) -> usize {
        self.steps
    }

    /// Per channel, where the power has gone (as of the last checkpoint).
    pub fn ledger(&self) -> &[Ledger] {
        &self.ledger
    }

    /// (step, max over channels of R/P_inj) at every checkpoint.
    pub fn history(&self) -> &[(usize, f64)] {
        &self.history
    }

    /// The accumulators `[cell][channel][φ, J, L_acc]`, read back.
    pub fn accumulators(&self) -> Result<Vec<f32>, SolverError> {
        let bytes = (self.n.pow(3) * self.nc * super::cpu::ACC * 4) as u64;
        let out = self.ctx.read_buffer(&self.b.acc, bytes)?;
        Ok(bytemuck::pod_collect_to_vec(&out))
    }

    /// The current state `[cell][channel][L, a]`, read back.
    pub fn state(&self) -> Result<Vec<f32>, SolverError> {
        let bytes = (self.n.pow(3) * self.nc * S * 4) as u64;
        let out = self.ctx.read_buffer(&self.b.states[self.parity], bytes)?;
        Ok(bytemuck::pod_collect_to_vec(&out))
    }

    /// Benchmarks: records `steps` plain steps in one timed compute pass, submits, waits and
    /// returns their seconds (GPU timestamps when available, else the wall clock).
    pub fn time_steps(&mut self, steps: u32) -> Result<f64, SolverError> {
        let ctx = self.ctx;
        Ok(time_pass(ctx, "pop steps", |pass| {
            self.record_steps(pass, steps)
        })?)
    }

    fn record_steps(&mut self, pass: &mut wgpu::ComputePass<'_>, steps: u32) {
        for _ in 0..steps {
            pass.set_bind_group(0, &self.binds[self.parity], &[]);
            pass.set_pipeline(&self.pipelines[0]);
            pass.dispatch_workgroups(self.dispatch[0], self.dispatch[1], 1);
            pass.set_pipeline(&self.pipelines[1]);
            pass.dispatch_workgroups(self.dispatch[0], self.dispatch[1], 1);
            self.parity = 1 - self.parity;
            self.steps += 1;
        }
    }
}

impl Checkpointed for GpuPop<'_> {
    type Stop = Stop;

    /// `n` steps, then `reduce` over the state they leave (the `lin` of the next bind group).
    fn record(&mut self, pass: &mut wgpu::ComputePass<'_>, n: u32) {
        self.record_steps(pass, n);
        pass.set_bind_group(0, &self.binds[self.parity], &[]);
        pass.set_pipeline(&self.pipelines[2]);
        pass.dispatch_workgroups(self.groups, 1, 1);
    }

    fn readback(&self) -> (wgpu::Buffer, u64) {
        let bytes = (self.n * self.nc * PARTIAL * 4) as u64;
        (self.b.partials.clone(), bytes)
    }

    /// The ledger from the per-slice partials, added in slice order in f64; D9's test.
    fn checkpoint(
        &mut self,
        _n: u32,
        bytes: &[u8],
        observer: &mut dyn FnMut(usize, f64),
    ) -> Option<Stop> {
        let p: Vec<f32> = bytemuck::pod_collect_to_vec(bytes);
        let area = self.dx * self.dx;
        let mut worst = 0f64;
        for ch in 0..self.nc {
            let mut sum = [0f64; PARTIAL];
            for k in 0..self.n {
                let o = (k * self.nc + ch) * PARTIAL;
                for (s, v) in sum.iter_mut().zip(&p[o..o + PARTIAL]) {
                    *s += f64::from(*v);
                }
            }
            let base = self.base[ch];
            let led = &mut self.ledger[ch];
            led.absorbed = base.absorbed + sum[0] * area;
            led.exit_back = base.exit_back + sum[1] * area;
            led.exit_front = base.exit_front + sum[2] * area;
            led.exit_side = base.exit_side + sum[3] * area;
            led.in_flight = sum[4] * area;
            worst = worse_residual(worst, led.in_flight, led.injected);
        }
        self.history.push((self.steps, worst));
        observer(self.steps, worst);
        if !worst.is_finite() {
            return Some(Stop::NonFinite);
        }
        if worst < self.tolerance || worst == 0.0 {
            return Some(Stop::Converged);
        }
        None
    }
}

/// [`super::solve`] on the GPU (f32): every ordinate in turn on one [`GpuPop`] allocated for
/// the first and reused by the others (the grids of one solve share n and the channels).
/// Each [`OrdinateRun::history`] holds R/P_inj at the checkpoints, at the steps in
/// [`OrdinateRun::history_steps`].
pub fn solve(
    ctx: &GpuContext,
    medium: &PopMedium,
    ordinates: &[super::Ordinate],
    config: &PopConfig,
) -> Result<PopSolution<f32>, SolverError> {
    super::validate_solve::<f32>(medium, ordinates, config)?;
    let mut gpu: Option<GpuPop<'_>> = None;
    let mut runs = Vec::with_capacity(ordinates.len());
    for o in ordinates {
        let (grid, cpu) = super::prepare::<f32>(medium, o, config);
        let state = match gpu.as_mut() {
            Some(s) => s,
            None => gpu.insert(GpuPop::new(
                ctx,
                config.n,
                medium.channels(),
                config.lateral,
                config.observer.is_some(),
            )?),
        };
        state.load(&cpu)?;
        let stop = state.run(config.tolerance, config.max_iterations)?;
        runs.push(OrdinateRun {
            ordinate: *o,
            grid,
            channels: medium.channels(),
            acc: state.accumulators()?,
            ledger: state.ledger().to_vec(),
            history: state.history().iter().map(|h| h.1).collect(),
            history_steps: state.history().iter().map(|h| h.0).collect(),
            steps: state.steps(),
            stop,
        });
    }
    Ok(PopSolution { runs })
}
