//! The wgpu kernel of FLD Algorithm 1 (f32), the GPU twin of [`super::cpu`]: same packed
//! red-black layout, same per-voxel arithmetic (FLD Eqs 32–37 with the decisions of
//! [`super`]), same stopping rule. The shader is `fld.wgsl` beside this file; [`GpuParams`]
//! is mirrored there as `Params`.
//!
//! One iteration is three or four dispatches in one compute pass: the boundary-layer D
//! update (FLD only), the red and the black [`sweep`](GpuFld::record_iterations), and
//! `reduce`, which sums the per-workgroup squared residuals of both colours in a fixed
//! order, stores R̄/j̄ and raises a `done` flag below the tolerance. Every kernel returns at
//! once when `done` is set, so the host records [`GpuFld::check_every`] iterations per
//! submission and reads back only the small state buffer (iteration count, flag, residuals)
//! between them; φ is read back once at the end.

use super::cpu::CpuFld;
use super::{Boundary, FldConfig, FldSolution, FluxLimiter};
use crate::gpu::{
    GpuContext, GpuError, PassTimer, Timer, storage_buffer, storage_entry, uniform_entry,
};
use crate::method::Stop as Status;
use crate::{Grid, Medium, SolverError};
use bytemuck::{Pod, Zeroable};
use std::time::Instant;
use wgpu::util::DeviceExt;

/// The shader source, validated by naga in the crate's tests.
pub const SHADER: &str = include_str!("fld.wgsl");

/// Threads per workgroup of `sweep` along x (packed m) and y (j), as in `fld.wgsl`.
const WG_X: u32 = 32;
const WG_Y: u32 = 8;
/// Threads per workgroup of `boundary_d`.
const WG_BOUNDARY: u32 = 64;

/// Uniforms of `fld.wgsl` (`Params` there, same field order; 112 bytes, a multiple of 16).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct GpuParams {
    /// Grid size.
    pub nx: u32,
    /// Grid size.
    pub ny: u32,
    /// Grid size.
    pub nz: u32,
    /// Packed row length ⌈nx/2⌉.
    pub h: u32,
    /// Packed values per colour.
    pub plen: u32,
    /// Colour of the sweep (0 red, 1 black).
    pub color: u32,
    /// Lowest residual-counted coordinate.
    pub lo: u32,
    /// Highest residual-counted i.
    pub hi_x: u32,
    /// Highest residual-counted j.
    pub hi_y: u32,
    /// Highest residual-counted k.
    pub hi_z: u32,
    /// Boundary-layer voxels.
    pub boundary_count: u32,
    /// Threads per dispatch row of `boundary_d`.
    pub boundary_row: u32,
    /// Workgroups of one sweep.
    pub partials_per_color: u32,
    /// Residual slots in the state buffer.
    pub chunk: u32,
    /// Padding.
    pub _pad0: [u32; 2],
    /// SOR factor ω.
    pub omega: f32,
    /// 1 − ω.
    pub one_minus_omega: f32,
    /// 1/(2Δl).
    pub inv_2dl: f32,
    /// 1/Δl².
    pub inv_dl2: f32,
    /// ε j̄ floor of Eq 35.
    pub floor: f32,
    /// θ of the D under-relaxation.
    pub theta: f32,
    /// 1 − θ.
    pub one_minus_theta: f32,
    /// n of Larsen's limiter.
    pub larsen_n: f32,
    /// Tolerance on R̄/j̄.
    pub tolerance: f32,
    /// 1 / number of residual-counted voxels.
    pub inv_residual_count: f32,
    /// Padding.
    pub _pad1: [f32; 2],
}

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
    phi: wgpu::Buffer,
    state: wgpu::Buffer,
    pipelines: [wgpu::ComputePipeline; 3],
    /// Bind groups with the colour-0 and colour-1 uniforms.
    binds: [wgpu::BindGroup; 2],
    iterations: usize,
    residuals: Vec<f64>,
    status: Option<Status>,
    setup_seconds: f64,
    timer: PassTimer,
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
        medium.validate()?;
        config.validate()?;
        let grid = medium.grid;
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
        for name in ["phi", "D", "sigma", "absorption", "source"] {
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
        let partials_per_color = sweep_groups.iter().product::<u32>();
        // Limits are checked above, before any host memory is spent. The CPU kernel's setup
        // is the single source of the packed initial state.
        let host = CpuFld::<f32>::new(medium, boundary, config)?;
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
        let max_groups = ctx.limits().max_compute_workgroups_per_dimension;
        let bgroups = bcount.div_ceil(WG_BOUNDARY).max(1);
        let boundary_groups = if bgroups <= max_groups {
            [bgroups, 1]
        } else {
            [max_groups, bgroups.div_ceil(max_groups)]
        };
        let check_every = 32u32;
        let margin = host.residual_margin();
        let (lo, hi) = (
            1 + margin,
            [
                nx - 2 - margin.min(nx - 2),
                ny - 2 - margin.min(ny - 2),
                nz - 2 - margin.min(nz - 2),
            ],
        );
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
            _pad0: [0; 2],
            omega: p.omega,
            one_minus_omega: p.one_minus_omega,
            inv_2dl: p.inv_2dl,
            inv_dl2: p.inv_dl2,
            floor: p.floor,
            theta: p.theta,
            one_minus_theta: p.one_minus_theta,
            larsen_n: match config.limiter {
                FluxLimiter::Larsen(n) => n as f32,
                _ => 2.0,
            },
            tolerance: host.tolerance() as f32,
            inv_residual_count: 1.0 / host.residual_count() as f32,
            _pad1: [0.0; 2],
        };
        let needed = 5 * field_bytes + 8 * u64::from(partials_per_color) + 4 * u64::from(bcount);
        let fields = host.packed_fields();
        let (bufs, state, partials, blist, uniforms) = ctx.allocating(
            &format!("FLD buffers for a {nx}x{ny}x{nz} grid"),
            needed,
            |d| {
                let bufs: Vec<wgpu::Buffer> = fields
                    .iter()
                    .zip(["phi", "D", "sigma", "absorption", "source"])
                    .map(|(f, name)| {
                        let mut data = f[0].clone();
                        data.extend_from_slice(&f[1]);
                        storage_buffer(d, name, bytemuck::cast_slice(&data))
                    })
                    .collect();
                let st = vec![0u32; 4 + check_every as usize];
                let state = storage_buffer(d, "state", bytemuck::cast_slice(&st));
                let partials =
                    storage_buffer(d, "partials", &vec![0u8; 8 * partials_per_color as usize]);
                let blist = storage_buffer(d, "boundary", bytemuck::cast_slice(&boundary_list));
                let uniforms = [0u32, 1].map(|color| {
                    d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                        label: Some("fld params"),
                        contents: bytemuck::bytes_of(&GpuParams { color, ..base }),
                        usage: wgpu::BufferUsages::UNIFORM,
                    })
                });
                (bufs, state, partials, blist, uniforms)
            },
        )?;
        let (pipelines, binds) = ctx.allocating("FLD pipelines", 0, |device| {
            let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("fld.wgsl"),
                source: wgpu::ShaderSource::Wgsl(SHADER.into()),
            });
            let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("fld"),
                entries: &[
                    uniform_entry(0),
                    storage_entry(1, false),
                    storage_entry(2, false),
                    storage_entry(3, true),
                    storage_entry(4, true),
                    storage_entry(5, true),
                    storage_entry(6, false),
                    storage_entry(7, false),
                    storage_entry(8, true),
                ],
            });
            let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("fld"),
                bind_group_layouts: &[Some(&layout)],
                immediate_size: 0,
            });
            let limiter_id = f64::from(limiter_id(config.limiter));
            let constants = [("LIMITER", limiter_id)];
            let pipelines = crate::gpu::compute_pipelines(
                device,
                &pipeline_layout,
                &module,
                ["boundary_d", "sweep", "reduce"],
                &constants,
            );
            let binds = [0usize, 1].map(|c| {
                let entries: Vec<wgpu::BindGroupEntry> = std::iter::once(&uniforms[c])
                    .chain(bufs.iter())
                    .chain([&partials, &state, &blist])
                    .enumerate()
                    .map(|(b, buf)| wgpu::BindGroupEntry {
                        binding: b as u32,
                        resource: buf.as_entire_binding(),
                    })
                    .collect();
                device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("fld"),
                    layout: &layout,
                    entries: &entries,
                })
            });
            (pipelines, binds)
        })?;
        ctx.check_lost()?;
        let phi = bufs.into_iter().next().ok_or(GpuError::Internal {
            context: "FLD setup".into(),
            message: "no phi buffer".into(),
        })?;
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
            phi,
            state,
            pipelines,
            binds,
            iterations: 0,
            residuals: Vec::new(),
            status: None,
            setup_seconds: t0.elapsed().as_secs_f64(),
            timer: PassTimer::new(ctx),
        })
    }

    /// Iterations recorded per submission before the state is read back.
    pub fn check_every(&self) -> u32 {
        self.check_every
    }

    /// How the iteration time is measured on this device.
    pub fn timer(&self) -> Timer {
        self.timer.timer()
    }

    /// Records `n` red-black iterations (boundary D, red sweep, black sweep, reduce) into
    /// `pass`. Iterations past convergence are no-ops on the GPU.
    pub fn record_iterations(&self, pass: &mut wgpu::ComputePass<'_>, n: u32) {
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

    /// Runs up to `n` iterations (fewer if it converges or hits the cap) in one submission,
    /// reads back the state and returns the residuals of the iterations that ran.
    pub fn run(&mut self, n: u32) -> Result<&[f64], SolverError> {
        let start = self.residuals.len();
        if self.status.is_some() {
            return Ok(&self.residuals[start..]);
        }
        if self.trivial {
            self.status = Some(Status::Converged);
            return Ok(&self.residuals[start..]);
        }
        let n = n
            .min(self.check_every)
            .min((self.max_iterations - self.iterations).min(u32::MAX as usize) as u32);
        if n == 0 {
            self.status = Some(Status::Cap);
            return Ok(&self.residuals[start..]);
        }
        // Moved out for the call (a default timer allocates nothing) and put back.
        let mut timer = std::mem::take(&mut self.timer);
        let state = self.submit(n, &mut timer, true);
        self.timer = timer;
        let state = state?;
        let words: Vec<u32> = state
            .chunks_exact(4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        let (iter, done) = (words[0] as usize, words[1]);
        let chunk = self.check_every as usize;
        for it in self.iterations..iter {
            self.residuals
                .push(f64::from(f32::from_bits(words[4 + it % chunk])));
        }
        self.iterations = iter;
        self.status = match done {
            1 => Some(Status::Converged),
            2 => Some(Status::NonFinite),
            _ if self.iterations >= self.max_iterations => Some(Status::Cap),
            _ => None,
        };
        Ok(&self.residuals[start..])
    }

    /// Benchmarks: records `n` iterations in one compute pass, submits and waits, and returns
    /// their seconds (GPU timestamps when the device has them, else the wall clock around
    /// submit and wait). Convergence is not checked on the host: once the GPU's `done` flag
    /// is set the remaining iterations are no-ops, so run with tolerance 0 to time real work.
    pub fn time_iterations(&mut self, n: u32) -> Result<f64, SolverError> {
        let mut timer = PassTimer::new(self.ctx);
        self.submit(n, &mut timer, false)?;
        Ok(timer.seconds())
    }

    /// Records `n` iterations into one timed compute pass, submits, waits, adds the pass time
    /// to `timer` and returns the state buffer's bytes if `read_state` (else an empty vector).
    fn submit(
        &self,
        n: u32,
        timer: &mut PassTimer,
        read_state: bool,
    ) -> Result<Vec<u8>, SolverError> {
        let state_bytes = 16 + 4 * u64::from(self.check_every);
        Ok(timer.run_pass(
            self.ctx,
            "fld iterations",
            |pass| self.record_iterations(pass, n),
            read_state.then_some((&self.state, state_bytes)),
        )?)
    }

    /// Bytes one iteration must move at least (as [`CpuFld::bytes_per_iteration`] in f32:
    /// 9 values per voxel for FLD, 7 for CDA).
    pub fn bytes_per_iteration(&self) -> usize {
        (if self.fld { 9 } else { 7 }) * self.grid.len() * 4
    }

    /// Iterates to convergence, the iteration cap or a non-finite residual, calling
    /// `observer(iteration, residual)` for every iteration as its residual is read back.
    pub fn solve_observed(
        mut self,
        mut observer: impl FnMut(usize, f64),
    ) -> Result<FldSolution<f32>, SolverError> {
        let t0 = Instant::now();
        while self.status.is_none() {
            let before = self.iterations;
            let chunk = self.check_every;
            let fresh = self.run(chunk)?.to_vec();
            for (q, r) in fresh.into_iter().enumerate() {
                observer(before + q + 1, r);
            }
        }
        let wall = t0.elapsed().as_secs_f64();
        let phi = self.phi()?;
        let timer = self.timer.timer();
        let seconds = match timer {
            Timer::GpuTimestamps => self.timer.seconds(),
            Timer::WallClock => wall,
        };
        Ok(super::solution(
            self.grid,
            phi,
            self.residuals,
            self.iterations,
            self.status.unwrap_or(Status::Cap),
            seconds,
            self.setup_seconds,
            timer,
        ))
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
        let encoder = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("phi readback"),
            });
        let plen = g.n[2] * g.n[1] * self.h;
        let out = self
            .ctx
            .submit_and_read(encoder, &[(&self.phi, 2 * plen as u64 * 4)])?;
        let packed: &[f32] = bytemuck::cast_slice(&out[0]);
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

/// The `LIMITER` override constant of `fld.wgsl`.
fn limiter_id(l: FluxLimiter) -> u32 {
    match l {
        FluxLimiter::Cda => 0,
        FluxLimiter::Sum => 1,
        FluxLimiter::Max => 2,
        FluxLimiter::Kershaw => 3,
        FluxLimiter::Larsen(_) => 4,
        FluxLimiter::LevermorePomraning => 5,
    }
}
