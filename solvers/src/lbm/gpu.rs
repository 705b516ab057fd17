//! The wgpu kernel of the lattice-Boltzmann update (f32), the GPU twin of [`super::cpu`]:
//! same z-slab layout, same per-site arithmetic (LB Eqs 4–6 with the decisions of
//! [`super`]), same stopping rule evaluated at checkpoints. The shader is `lbm.wgsl` beside
//! this file; [`GpuParams`] is mirrored there as `Params`.
//!
//! Two state buffers ping-pong: a step reads one and writes the other, one dispatch per step
//! ([`GpuLbm::record_steps`]). Every [`LbmConfig::check_every`] steps the last step of a
//! submission is `step_reduce` (the same update plus per-workgroup sums), followed by
//! `reduce`, which adds the partials in a fixed order; only those three totals are read back.
//! The state is read back once at the end, and φ is formed on the host by the CPU code.

use super::cpu::{Setup, steady};
use super::{Injection, LbmConfig, LbmSolution, LbmTrace, Q, StepRecord};
use crate::gpu::{
    GpuContext, GpuError, PassTimer, Timer, storage_buffer, storage_entry, uniform_entry,
};
use crate::method::Stop as Status;
use crate::{Grid, Medium, SolverError};
use bytemuck::{Pod, Zeroable};
use std::time::Instant;
use wgpu::util::DeviceExt;

/// The shader source, validated by naga in the crate's tests.
pub const SHADER: &str = include_str!("lbm.wgsl");

/// Threads per workgroup of every kernel in `lbm.wgsl`.
const WG: u32 = 256;

/// Uniforms of `lbm.wgsl` (`Params` there, same field order; 32 bytes).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct GpuParams {
    /// Grid size.
    pub nx: u32,
    /// Grid size.
    pub ny: u32,
    /// Grid size.
    pub nz: u32,
    /// Sites nx·ny·nz.
    pub sites: u32,
    /// Threads per dispatch row (x workgroups × 256).
    pub row: u32,
    /// 1: re-emit the rest density (paper); 0: absorbed density is removed.
    pub reemit: u32,
    /// 1 if the emission buffer holds a source.
    pub has_src: u32,
    /// Workgroups of one step (partials of `step_reduce`).
    pub groups: u32,
}

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
    pipelines: [wgpu::ComputePipeline; 3],
    /// Bind group reading state 0 and writing state 1, and the reverse.
    binds: [wgpu::BindGroup; 2],
    parity: usize,
    check_every: u32,
    steps: usize,
    history: Vec<StepRecord>,
    timer: PassTimer,
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
        let groups =
            u32::try_from(sites.div_ceil(u64::from(WG))).map_err(|_| GpuError::TooLarge {
                what: "LBM workgroups".into(),
                needed: sites.div_ceil(u64::from(WG)),
                limit: u64::from(u32::MAX),
                limit_name: "u32 workgroup count",
                adapter: ctx.info().name.clone(),
            })?;
        let max = ctx.limits().max_compute_workgroups_per_dimension;
        let dispatch = if groups <= max {
            [groups, 1]
        } else {
            [max, groups.div_ceil(max)]
        };
        ctx.check_workgroups("the LBM step", dispatch[1])?;
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
        let (states, ss, sa, emission, table_buf, partials, totals, uniform) = ctx.allocating(
            &format!("LBM buffers for a {nx}x{ny}x{nz} lattice"),
            needed,
            |d| {
                let states = [
                    storage_buffer(d, "lbm state 0", &zeros),
                    storage_buffer(d, "lbm state 1", &zeros),
                ];
                let ss = storage_buffer(d, "sigma_s", bytemuck::cast_slice(&setup.ss));
                let sa = storage_buffer(d, "sigma_a", bytemuck::cast_slice(&setup.sa));
                let src: &[f32] = setup.src.as_deref().unwrap_or(&[]);
                let emission = storage_buffer(d, "emission", bytemuck::cast_slice(src));
                let table_buf = storage_buffer(d, "lbm table", bytemuck::cast_slice(&table));
                let partials = storage_buffer(d, "lbm partials", &vec![0u8; 12 * groups as usize]);
                let totals = storage_buffer(d, "lbm totals", &[0u8; 16]);
                let uniform = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("lbm params"),
                    contents: bytemuck::bytes_of(&params),
                    usage: wgpu::BufferUsages::UNIFORM,
                });
                (
                    states, ss, sa, emission, table_buf, partials, totals, uniform,
                )
            },
        )?;
        drop(zeros);
        let iso = setup.scatter.is_none();
        let (pipelines, binds) = ctx.allocating("LBM pipelines", 0, |device| {
            let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("lbm.wgsl"),
                source: wgpu::ShaderSource::Wgsl(SHADER.into()),
            });
            let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("lbm"),
                entries: &[
                    uniform_entry(0),
                    storage_entry(1, true),
                    storage_entry(2, false),
                    storage_entry(3, true),
                    storage_entry(4, true),
                    storage_entry(5, true),
                    storage_entry(6, true),
                    storage_entry(7, false),
                    storage_entry(8, false),
                ],
            });
            let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("lbm"),
                bind_group_layouts: &[Some(&layout)],
                immediate_size: 0,
            });
            let constants = [("ISO", if iso { 1.0 } else { 0.0 })];
            let pipelines = crate::gpu::compute_pipelines(
                device,
                &pipeline_layout,
                &module,
                ["step", "step_reduce", "reduce"],
                &constants,
            );
            let binds = [0usize, 1].map(|from| {
                let bufs = [
                    &uniform,
                    &states[from],
                    &states[1 - from],
                    &ss,
                    &sa,
                    &emission,
                    &table_buf,
                    &partials,
                    &totals,
                ];
                let entries: Vec<wgpu::BindGroupEntry> = bufs
                    .iter()
                    .enumerate()
                    .map(|(b, buf)| wgpu::BindGroupEntry {
                        binding: b as u32,
                        resource: buf.as_entire_binding(),
                    })
                    .collect();
                device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("lbm"),
                    layout: &layout,
                    entries: &entries,
                })
            });
            (pipelines, binds)
        })?;
        ctx.check_lost()?;
        let mut setup = setup;
        setup.setup_seconds = t0.elapsed().as_secs_f64();
        Ok(Self {
            ctx,
            setup,
            dispatch,
            states,
            totals,
            pipelines,
            binds,
            parity: 0,
            check_every: config.check_every,
            steps: 0,
            history: Vec::new(),
            timer: PassTimer::new(ctx),
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
    pub fn record_steps(&mut self, pass: &mut wgpu::ComputePass<'_>, n: u32) {
        pass.set_pipeline(&self.pipelines[0]);
        for _ in 0..n {
            pass.set_bind_group(0, &self.binds[self.parity], &[]);
            pass.dispatch_workgroups(self.dispatch[0], self.dispatch[1], 1);
            self.parity = 1 - self.parity;
            self.steps += 1;
        }
    }

    /// Records one step with the reduction of its totals (`step_reduce`, then `reduce`).
    pub fn record_checkpoint(&mut self, pass: &mut wgpu::ComputePass<'_>) {
        pass.set_pipeline(&self.pipelines[1]);
        pass.set_bind_group(0, &self.binds[self.parity], &[]);
        pass.dispatch_workgroups(self.dispatch[0], self.dispatch[1], 1);
        pass.set_pipeline(&self.pipelines[2]);
        pass.dispatch_workgroups(1, 1, 1);
        self.parity = 1 - self.parity;
        self.steps += 1;
    }

    /// Runs `n` ≥ 1 steps in one submission, the last one a checkpoint, and returns its totals.
    pub fn run(&mut self, n: u32) -> Result<StepRecord, SolverError> {
        let n = n.max(1);
        let mut timer = std::mem::take(&mut self.timer);
        let out = self.submit(n, &mut timer, true);
        self.timer = timer;
        let bytes = out?;
        let t: &[f32] = bytemuck::cast_slice(&bytes);
        let rec = StepRecord {
            step: self.steps,
            total_density: f64::from(t[0]),
            injected: self.setup.injected,
            outflow: f64::from(t[1]),
            absorbed: f64::from(t[2]),
        };
        self.history.push(rec);
        Ok(rec)
    }

    /// Benchmarks: records `n` plain steps in one timed compute pass, submits, waits and
    /// returns their seconds (GPU timestamps when available, else the wall clock).
    pub fn time_steps(&mut self, n: u32) -> Result<f64, SolverError> {
        let mut timer = PassTimer::new(self.ctx);
        self.submit(n, &mut timer, false)?;
        Ok(timer.seconds())
    }

    /// Records `n` steps (the last a checkpoint if `checkpoint`) into one timed pass, submits,
    /// waits and returns the 16 bytes of totals if `checkpoint` (else empty).
    fn submit(
        &mut self,
        n: u32,
        timer: &mut PassTimer,
        checkpoint: bool,
    ) -> Result<Vec<u8>, SolverError> {
        // wgpu handles are reference-counted: a clone lets the pass borrow `self` mutably.
        let (ctx, totals) = (self.ctx, self.totals.clone());
        Ok(timer.run_pass(
            ctx,
            "lbm steps",
            |pass| {
                if checkpoint {
                    self.record_steps(pass, n - 1);
                    self.record_checkpoint(pass);
                } else {
                    self.record_steps(pass, n);
                }
            },
            checkpoint.then_some((&totals, 16)),
        )?)
    }

    /// The current state (post-collision densities, z-slab layout), read back.
    pub fn state(&self) -> Result<Vec<f32>, SolverError> {
        let encoder = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("lbm readback"),
            });
        let bytes = (Q * self.setup.grid.len() * 4) as u64;
        let out = self
            .ctx
            .submit_and_read(encoder, &[(&self.states[self.parity], bytes)])?;
        Ok(bytemuck::cast_slice(&out[0]).to_vec())
    }

    /// Steps to the steady state (checked every `check_every` steps) or the cap, calling
    /// `observer(step, total_density)` at every checkpoint.
    pub fn solve_observed(
        mut self,
        mut observer: impl FnMut(usize, f64),
    ) -> Result<LbmSolution<f32>, SolverError> {
        let t0 = Instant::now();
        let tol = self.setup.tolerance;
        let max = self.setup.max_steps;
        let mut status = Status::Cap;
        let mut prev = f64::NAN;
        while self.steps < max {
            let k = (max - self.steps).min(self.check_every as usize) as u32;
            let rec = self.run(k)?;
            observer(rec.step, rec.total_density);
            let t = rec.total_density;
            if !t.is_finite() {
                status = Status::NonFinite;
                break;
            }
            if steady(prev, t, k as usize, tol) {
                status = Status::Converged;
                break;
            }
            prev = t;
        }
        let wall = t0.elapsed().as_secs_f64();
        let state = self.state()?;
        let (phi, rho) = self.setup.fields(&state);
        let timer = self.timer.timer();
        let seconds = match timer {
            Timer::GpuTimestamps => self.timer.seconds(),
            Timer::WallClock => wall,
        };
        let trace = LbmTrace {
            rho,
            history: self.history,
            clamped_sites: self.setup.clamped,
        };
        Ok(super::solution(
            self.setup.grid,
            phi,
            trace,
            self.steps,
            status,
            seconds,
            self.setup.setup_seconds,
            timer,
        ))
    }

    /// As [`GpuLbm::solve_observed`] without an observer.
    pub fn solve(self) -> Result<LbmSolution<f32>, SolverError> {
        self.solve_observed(|_, _| {})
    }
}
