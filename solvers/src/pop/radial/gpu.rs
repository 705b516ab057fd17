//! A point light's radial octahedral grid on the GPU (f32), the twin of [`RadialPop::step`]:
//! same cell layout, the same per-cell arithmetic in the same order, the same stop and the
//! same geometric tail, both evaluated at checkpoints. The shader is `radial.wgsl` beside
//! this file; `RadialParams` is mirrored there as `Params` and `SPEC` declares its
//! bindings by name (both checked against the WGSL by `tests/kernel_contract.rs`).
//!
//! **What runs where.** The host builds the light's [`RadialPop`] as the CPU solve does (the
//! medium resampled per cell with its MIP levels, the per-link T and γ, Δr/V per cell, the
//! octahedral neighbour tables, the injection with its ledger); [`GpuRadial::new`] uploads it
//! once. One step is two dispatches, `fractions_step` (the Eq 3 fractions and what each
//! cell's links absorb or let escape through r_max, added to that cell's own loss
//! accumulator: no reduction per step) and `gather` (Eqs 2, 4–6 and φ, J). A checkpoint
//! records its steps with a reduction before the last step and one after it (`reduce_a`,
//! `reduce_b`: one workgroup per shell and channel, fixed order, no atomics) and reads back
//! only those 2·N_r·channels·4 floats; the host adds the shells in shell order in f64. The
//! accumulators are read back once, at the end.
//!
//! **Checkpoints.** Under a relative stop the GPU checks R^m/P_inj < ε every
//! [`CHECK_EVERY`] steps (the CPU after every step), so it stops at the first checkpoint at
//! or after the CPU's step. The geometric tail ([`super::RadialConfig::tail`]) is tried at
//! the same checkpoints: the ratio ρ = R^m/R^{m−1} and the last step's losses come from the
//! two reductions, the visits Σ_m R^m from Σ φ/(Δr/V), and the prediction is compared with
//! the one [`super::TAIL_WINDOW`] steps earlier (a multiple of [`CHECK_EVERY`], so that one is
//! a checkpoint too). Adding the tail reads the state and the accumulators back once,
//! applies it on the host as the CPU does and writes them back. The last step's losses are
//! differences of two f32 running sums: they only split the tail's power between absorbed
//! and escaped, the balance holds whatever they are. With ε = 0 and no tail (a fixed step
//! count) nothing is read until the end.

use super::{
    ACC, LINKS, Octahedral, RadialGrid, RadialLedger, RadialPop, RadialSolution, S, TAIL_WINDOW,
    add_tail, predicted_total, tail_due,
};
use crate::SolverError;
use crate::gpu::kernel::{
    Access, Checkpointed, Kernel, KernelSpec, run_checkpointed, struct_layout,
};
use crate::gpu::{GpuContext, GpuError, storage_buffer, uniform_buffer};
use crate::method::Stop;
use bytemuck::{Pod, Zeroable};

/// Threads per workgroup of every kernel in `radial.wgsl`.
const WG: u32 = 64;

/// Steps between two read-backs under a relative stop or a tail (divides
/// [`super::TAIL_WINDOW`]).
pub const CHECK_EVERY: u32 = 10;

/// The most steps recorded into one submission of a fixed-count run.
const MAX_BATCH: u32 = 1024;

/// Floats per shell and channel in each half of `partials`: absorbed, escaped, in flight,
/// visits.
const PARTIAL: usize = 4;

/// Texel table entries: 4 neighbours, the slot of each neighbour's list pointing back, the
/// antipode.
const TOPO: usize = 9;

/// Uniforms of `radial.wgsl` (`Params` there, same fields in the same order; 32 bytes).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub(crate) struct RadialParams {
    /// Texels per shell (N_a²).
    na2: u32,
    /// Shells.
    nr: u32,
    /// Channels.
    nc: u32,
    /// N_a²·N_r·channels.
    slots: u32,
    /// Threads per dispatch row (x workgroups × 64).
    row: u32,
    /// Workgroups of the reductions (N_r·channels).
    groups: u32,
    pad0: u32,
    pad1: u32,
}

/// What this host code assumes about `radial.wgsl`.
pub(crate) const SPEC: KernelSpec = KernelSpec {
    label: "radial.wgsl",
    source: include_str!("radial.wgsl"),
    bindings: &[
        ("P", Access::Uniform),
        ("lin", Access::Read),
        ("lout", Access::ReadWrite),
        ("links", Access::Read),
        ("frac", Access::ReadWrite),
        ("acc", Access::ReadWrite),
        ("loss", Access::ReadWrite),
        ("topo", Access::Read),
        ("weight", Access::Read),
        ("partials", Access::ReadWrite),
    ],
    entries: &["fractions_step", "gather", "reduce_a", "reduce_b"],
    constants: &[],
    uniforms: &[(
        "P",
        struct_layout!(RadialParams; na2, nr, nc, slots, row, groups, pad0, pad1),
    )],
};

/// The buffers, named as the bindings of `radial.wgsl` (`states` are `lin` and `lout`).
#[derive(Debug)]
struct Buffers {
    states: [wgpu::Buffer; 2],
    acc: wgpu::Buffer,
    partials: wgpu::Buffer,
}

/// The host's view of one channel's tail (the CPU's `TailTrack` at checkpoints).
#[derive(Debug, Clone, Default)]
struct Tail {
    /// (step, Σ_m R^m + R^m ρ/(1 − ρ)) at each checkpoint.
    predicted: Vec<(usize, f64)>,
    /// Power booked as absorbed and as escaped when the tail was added.
    booked: [f64; 2],
    done: Option<(usize, f64)>,
}

/// One point light's radial propagation on the GPU: buffers, pipelines and bind groups built
/// once from a [`RadialPop`] after injection.
#[derive(Debug)]
pub struct GpuRadial<'a> {
    ctx: &'a GpuContext,
    /// The uploaded grid's geometry, channels and Δr/V per cell (for the result and the
    /// tail; the rest of the host state lives on the device only).
    grid: RadialGrid,
    oct: Octahedral,
    nc: usize,
    weight: Vec<f32>,
    dispatch: [u32; 2],
    groups: u32,
    b: Buffers,
    /// `fractions_step`, `gather`, `reduce_a`, `reduce_b`.
    pipelines: [wgpu::ComputePipeline; 4],
    binds: [wgpu::BindGroup; 2],
    parity: usize,
    /// The ledger at upload (injection), per channel.
    base: Vec<RadialLedger>,
    ledger: Vec<RadialLedger>,
    tails: Vec<Tail>,
    /// (step, max over channels of R/P_inj) at each checkpoint.
    history: Vec<(usize, f64)>,
    steps: usize,
    tolerance: f64,
    tail: Option<f64>,
    /// A read-back or upload that failed inside a checkpoint.
    failed: Option<GpuError>,
}

impl<'a> GpuRadial<'a> {
    /// Checks the device limits and uploads `pop` (a grid after injection, no steps run).
    pub fn new(ctx: &'a GpuContext, pop: RadialPop<f32>) -> Result<Self, SolverError> {
        let adapter = ctx.info().name.clone();
        if pop.steps != 0 {
            return Err(SolverError::Unsupported(
                "GpuRadial::new: the radial grid must be uploaded before any CPU step".into(),
            ));
        }
        let na2 = pop.oct.len();
        let nr = pop.grid.n_r;
        let nc = pop.nc;
        let cells = (na2 as u64).saturating_mul(nr as u64);
        let slots = cells.saturating_mul(nc as u64);
        let largest = slots.saturating_mul(2 * LINKS as u64);
        if largest > u64::from(u32::MAX) || nc == 0 {
            return Err(GpuError::TooLarge {
                what: format!("a radial grid of {na2} texels × {nr} shells × {nc} channels"),
                needed: largest,
                limit: u64::from(u32::MAX),
                limit_name: "u32 indexing in radial.wgsl",
                adapter,
            }
            .into());
        }
        let what = |b: &str| format!("the {b} buffer of a {na2} × {nr} × {nc} radial grid");
        let groups64 = nr as u64 * nc as u64;
        let sizes = [
            ("state", slots * S as u64 * 4),
            ("links", slots * 2 * LINKS as u64 * 4),
            ("fractions", slots * 3 * 4),
            ("accumulator", slots * ACC as u64 * 4),
            ("loss", slots * 2 * 4),
            ("topology", na2 as u64 * TOPO as u64 * 4),
            ("weight", cells * 4),
            ("partials", 2 * groups64 * PARTIAL as u64 * 4),
        ];
        for (name, bytes) in sizes {
            ctx.check_storage_buffer(&what(name), bytes)?;
        }
        let groups = ctx.workgroup_count("radial reduce workgroups", groups64)?;
        ctx.check_workgroups(
            "the radial reduction (one workgroup per shell and channel)",
            groups,
        )?;
        let slot_groups =
            ctx.workgroup_count("radial workgroups", slots.div_ceil(u64::from(WG)))?;
        let dispatch = ctx.split_workgroups("the radial step", slot_groups)?;
        let params = RadialParams {
            na2: na2 as u32,
            nr: nr as u32,
            nc: nc as u32,
            slots: slots as u32,
            row: dispatch[0] * WG,
            groups,
            pad0: 0,
            pad1: 0,
        };
        let topo: Vec<u32> = (0..na2)
            .flat_map(|t| {
                let mut e = [0u32; TOPO];
                for s in 0..4 {
                    e[s] = pop.nb[t][s] as u32;
                    e[4 + s] = pop.rev[t][s] as u32;
                }
                e[8] = pop.anti[t] as u32;
                e
            })
            .collect();
        let needed: u64 = sizes.iter().map(|s| s.1).sum::<u64>() + sizes[0].1;
        let (buffers, params_buf, fixed) = ctx.allocating(&what("every"), needed, |d| {
            let zeros = |bytes: u64| vec![0u8; bytes as usize];
            let fixed = [
                storage_buffer(d, "radial links", bytemuck::cast_slice(&pop.links)),
                storage_buffer(d, "radial fractions", bytemuck::cast_slice(&pop.frac)),
                storage_buffer(d, "radial losses", &zeros(sizes[4].1)),
                storage_buffer(d, "radial topology", bytemuck::cast_slice(&topo)),
                storage_buffer(d, "radial weight", bytemuck::cast_slice(&pop.weight)),
            ];
            (
                Buffers {
                    states: [
                        storage_buffer(d, "radial state 0", bytemuck::cast_slice(&pop.state)),
                        storage_buffer(d, "radial state 1", &zeros(sizes[0].1)),
                    ],
                    acc: storage_buffer(d, "radial accumulators", bytemuck::cast_slice(&pop.acc)),
                    partials: storage_buffer(d, "radial partials", &zeros(sizes[7].1)),
                },
                uniform_buffer(d, "radial params", &params),
                fixed,
            )
        })?;
        let kernel = Kernel::new(ctx, &SPEC, &[])?;
        let pipelines = [
            kernel.pipeline("fractions_step")?,
            kernel.pipeline("gather")?,
            kernel.pipeline("reduce_a")?,
            kernel.pipeline("reduce_b")?,
        ];
        let [links, frac, loss, topo_buf, weight] = &fixed;
        let bind = |from: usize| {
            kernel.bind(
                ctx,
                &[
                    ("P", &params_buf),
                    ("lin", &buffers.states[from]),
                    ("lout", &buffers.states[1 - from]),
                    ("links", links),
                    ("frac", frac),
                    ("acc", &buffers.acc),
                    ("loss", loss),
                    ("topo", topo_buf),
                    ("weight", weight),
                    ("partials", &buffers.partials),
                ],
            )
        };
        let binds = [bind(0)?, bind(1)?];
        ctx.check_lost()?;
        let base = pop.ledger.clone();
        Ok(Self {
            ctx,
            dispatch,
            groups,
            b: buffers,
            pipelines,
            binds,
            parity: 0,
            ledger: base.clone(),
            base,
            tails: vec![Tail::default(); nc],
            history: Vec::new(),
            steps: 0,
            tolerance: 0.0,
            tail: None,
            failed: None,
            grid: pop.grid,
            oct: pop.oct,
            nc,
            weight: pop.weight,
        })
    }

    /// Steps until R/P_inj < `tolerance` in every channel at a checkpoint (0: never; a run
    /// also stops when nothing is in flight) or `max_iterations` steps, with the geometric
    /// tail at `tail` (see the module docs).
    pub fn run(
        &mut self,
        tolerance: f64,
        max_iterations: usize,
        tail: Option<f64>,
    ) -> Result<Stop, SolverError> {
        self.tolerance = tolerance;
        self.tail = tail;
        let every = if tolerance > 0.0 || tail.is_some() {
            CHECK_EVERY
        } else {
            MAX_BATCH
        };
        let remaining = max_iterations.saturating_sub(self.steps);
        let ctx = self.ctx;
        let run = run_checkpointed(
            ctx,
            self,
            "radial steps",
            remaining,
            every,
            Stop::Cap,
            &mut |_, _| {},
        )?;
        if let Some(e) = self.failed.take() {
            return Err(e.into());
        }
        Ok(run.stop)
    }

    /// The result so far, with the accumulators read back; `history` holds R/P_inj at the
    /// checkpoints, at the steps in [`RadialSolution::history_steps`].
    pub fn solution(&self, stop: Stop) -> Result<RadialSolution<f32>, SolverError> {
        let acc = self.ctx.read_buffer(&self.b.acc, self.slot_bytes(ACC))?;
        Ok(RadialSolution {
            grid: self.grid.clone(),
            oct: self.oct.clone(),
            channels: self.nc,
            acc: bytemuck::pod_collect_to_vec(&acc),
            ledger: self.ledger.clone(),
            history: self.history.iter().map(|h| h.1).collect(),
            history_steps: self.history.iter().map(|h| h.0).collect(),
            steps: self.steps,
            stop,
            tail: self.tails.iter().map(|t| t.done).collect(),
        })
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

    fn reduce(&self, pass: &mut wgpu::ComputePass<'_>, half: usize) {
        pass.set_bind_group(0, &self.binds[self.parity], &[]);
        pass.set_pipeline(&self.pipelines[2 + half]);
        pass.dispatch_workgroups(self.groups, 1, 1);
    }

    /// Bytes of a per-slot buffer with `per` floats per cell and channel.
    fn slot_bytes(&self, per: usize) -> u64 {
        (self.weight.len() * self.nc * per * 4) as u64
    }

    /// Adds the geometric tail to channels `chs` (rest factors f): one read-back of the state
    /// and the accumulators, [`add_tail`] as on the CPU, one write-back.
    fn add_tails(&mut self, chs: &[(usize, f64)]) -> Result<(), GpuError> {
        let state_buf = &self.b.states[self.parity];
        let mut state: Vec<f32> =
            bytemuck::pod_collect_to_vec(&self.ctx.read_buffer(state_buf, self.slot_bytes(S))?);
        let mut acc: Vec<f32> =
            bytemuck::pod_collect_to_vec(&self.ctx.read_buffer(&self.b.acc, self.slot_bytes(ACC))?);
        for &(ch, f) in chs {
            add_tail(&mut state, &mut acc, &self.weight, self.nc, ch, f);
        }
        let q = &self.ctx.queue;
        q.write_buffer(state_buf, 0, bytemuck::cast_slice(&state));
        q.write_buffer(&self.b.acc, 0, bytemuck::cast_slice(&acc));
        self.ctx.check_lost()
    }
}

impl Checkpointed for GpuRadial<'_> {
    type Stop = Stop;

    /// `n − 1` steps, `reduce_a`, the last step, `reduce_b`.
    fn record(&mut self, pass: &mut wgpu::ComputePass<'_>, n: u32) {
        self.record_steps(pass, n - 1);
        self.reduce(pass, 0);
        self.record_steps(pass, 1);
        self.reduce(pass, 1);
    }

    fn readback(&self) -> (wgpu::Buffer, u64) {
        let bytes = (2 * self.groups as usize * PARTIAL * 4) as u64;
        (self.b.partials.clone(), bytes)
    }

    /// The ledger and each channel's tail track from the per-shell partials (added in shell
    /// order in f64), the tail where it is due, then the stop.
    fn checkpoint(
        &mut self,
        _n: u32,
        bytes: &[u8],
        observer: &mut dyn FnMut(usize, f64),
    ) -> Option<Stop> {
        let p: Vec<f32> = bytemuck::pod_collect_to_vec(bytes);
        let nc = self.nc;
        let nr = self.grid.n_r;
        let sum = |half: usize, ch: usize| {
            let mut s = [0f64; PARTIAL];
            for k in 0..nr {
                let o = ((half * nr + k) * nc + ch) * PARTIAL;
                for (acc, v) in s.iter_mut().zip(&p[o..o + PARTIAL]) {
                    *acc += f64::from(*v);
                }
            }
            s
        };
        let mut due = Vec::new();
        let mut last_loss = Vec::with_capacity(nc);
        for ch in 0..nc {
            let (a, b) = (sum(0, ch), sum(1, ch));
            let base = self.base[ch];
            let tail = &mut self.tails[ch];
            let led = &mut self.ledger[ch];
            led.absorbed = base.absorbed + b[0] + tail.booked[0];
            led.escaped = base.escaped + b[1] + tail.booked[1];
            led.in_flight = b[2];
            let rho = if a[2] > 0.0 { b[2] / a[2] } else { 0.0 };
            let now = predicted_total(b[3], b[2], rho);
            tail.predicted.push((self.steps, now));
            last_loss.push([b[0] - a[0], b[1] - a[1]]);
            let Some(eps) = self.tail else { continue };
            if tail.done.is_some() || self.steps <= TAIL_WINDOW {
                continue;
            }
            let then = tail
                .predicted
                .iter()
                .rev()
                .find(|(s, _)| *s + TAIL_WINDOW == self.steps)
                .map(|x| x.1);
            if let Some(then) = then
                && tail_due(led, rho, now, then, eps)
            {
                due.push((ch, rho / (1.0 - rho)));
            }
        }
        if !due.is_empty() {
            if let Err(e) = self.add_tails(&due) {
                self.failed = Some(e);
                return Some(Stop::NonFinite);
            }
            for &(ch, _) in &due {
                let (booked, frac) = self.ledger[ch].book_tail(last_loss[ch]);
                let tail = &mut self.tails[ch];
                tail.booked = booked;
                tail.done = Some((self.steps, frac));
            }
        }
        let worst = self.ledger.iter().fold(0f64, |w, l| {
            super::super::cpu::worse_residual(w, l.in_flight, l.injected)
        });
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

/// [`super::solve_point_split`] on the GPU (f32): the total and the uncollided run, each on
/// its own [`GpuRadial`].
pub fn solve_point_split(
    ctx: &GpuContext,
    medium: &super::PopMedium,
    position: [f64; 3],
    intensity: &[f64],
    config: &super::RadialConfig,
) -> Result<(RadialSolution<f32>, RadialSolution<f32>), SolverError> {
    let (pop, bare) = super::prepare_split::<f32>(medium, position, intensity, config)?;
    let n_r = pop.grid.n_r;
    let mut gpu = GpuRadial::new(ctx, pop)?;
    let stop = gpu.run(config.tolerance, config.max_iterations, config.tail)?;
    let total = gpu.solution(stop)?;
    drop(gpu);
    let mut gpu = GpuRadial::new(ctx, bare)?;
    let stop = gpu.run(0.0, n_r + 1, None)?;
    Ok((total, gpu.solution(stop)?))
}
