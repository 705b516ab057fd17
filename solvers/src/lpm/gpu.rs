//! The wgpu kernels of LPM (f32), the GPU twin of [`super::cpu`]: the same geometry tables,
//! the same per-sub-segment arithmetic ([`super::cpu::phis`] with the same f32 e^{−τ}), the
//! same collect order, the same stopping rule. The shader is `lpm.wgsl` beside this file;
//! `GpuParams` is mirrored there as `Params` and `SPEC` declares its bindings (both
//! checked against the WGSL by `tests/kernel_contract.rs`).
//!
//! **Race freedom without atomics (D17, class-slotted T).** An order is, per face: `sweep`
//! (one thread per (direction k of the face, ray r); each marches its ray through all slabs),
//! then `collect` (one thread per voxel); then `reduce` (one workgroup). Within slab z, the
//! sub-segment j of direction k maps the m_b × m_c ray lattice onto the slab by a lateral
//! shift, a bijection, so the word T[(k·slots + j)·n_v + v] is written by exactly one thread
//! per sweep (the ray that sub-segment j of slab z puts into v), and every voxel of slab z
//! gets exactly one write per j. `collect` reads T_k(v) = Σ_{j < segs(k, z)} T[k, j, v] from
//! zero in j order (the CPU's `g += ∫L ds` in sub-segment order), then the directions
//! k = 0, 1, … (the CPU's order), and writes only voxel v's words of U^{cur}, I, φ and the
//! tallies. `reduce` sums in a fixed order (a per-thread stride, then a tree). The ray tallies
//! are one word per (direction, ray). No word is written by two threads of one dispatch,
//! nothing is atomic, and the results are bitwise reproducible (test
//! `t18_gpu_runs_are_bitwise_identical`).
//!
//! **Orders** run as Jacobi over two U buffers (two bind-group sets). The stopping test of D1
//! is evaluated by `reduce` on the GPU after every order; once it holds, every later kernel
//! returns at once, so the state is exactly that after the stopping order although the host
//! records [`CHECK_EVERY`] orders per submission and reads back only then (the order count,
//! the per-order tallies and, with `keep_orders`, the per-order fluence). I, U and φ are read
//! back once at the end.
//!
//! Not on the GPU: the paper's deposit L(1 − e^{−Ks s}) ([`Deposit::Paper`], a typed
//! [`SolverError::Unsupported`]); the face area and Δl/ω_z are table factors and are
//! supported. No float-atomic variant: wgpu 30's WGSL has no f32 atomics on lavapipe.

use super::cpu::{CpuLpm, series_threshold};
use super::directions::{CONE_SOLID_ANGLE, CONES, lateral_axes};
use super::{BoundaryLight, Deposit, LpmConfig, LpmSolution, Memory, OrderTally, Orders, WrapBc};
use crate::gpu::kernel::{
    Access, Checkpointed, Kernel, KernelSpec, run_checkpointed, struct_layout,
};
use crate::gpu::{GpuContext, GpuError, storage_buffer, uniform_buffer};
use crate::method::Stop;
use crate::{Grid, Medium, SolverError};
use bytemuck::{Pod, Zeroable};

/// Threads per workgroup of `sweep` and `collect`.
const WG: u32 = 64;

/// Orders recorded per submission (and read back at once): the checkpoint interval K.
pub const CHECK_EVERY: usize = 8;

/// Uniforms of `lpm.wgsl` (`Params` there, same fields in the same order; 80 bytes), one per
/// face.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub(crate) struct GpuParams {
    nx: u32,
    ny: u32,
    nz: u32,
    nv: u32,
    face: u32,
    per: u32,
    slots: u32,
    rays: u32,
    max_rays: u32,
    wrap: u32,
    d_i: u32,
    converge: u32,
    ring: u32,
    phi_ring: u32,
    row: u32,
    crow: u32,
    rel: f32,
    h3: f32,
    ts: f32,
    pad: u32,
}

/// One sub-segment (`Seg` in `lpm.wgsl`): absolute lateral offsets and the length in world
/// units (times the path factor).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct GpuSeg {
    ob: i32,
    oc: i32,
    len: f32,
    pad: f32,
}

/// Per-direction constants (`Dir` in `lpm.wgsl`, 44 bytes).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct GpuDir {
    start_base: u32,
    l_bc: f32,
    w: f32,
    wphi: f32,
    emit: f32,
    wu: [f32; CONES],
}

/// What this host code assumes about `lpm.wgsl`: bindings by name, entry points and the layout
/// of `Params`.
pub(crate) const SPEC: KernelSpec = KernelSpec {
    label: "lpm.wgsl",
    source: include_str!("lpm.wgsl"),
    bindings: &[
        ("P", Access::Uniform),
        ("segs", Access::Read),
        ("starts", Access::Read),
        ("dirs", Access::Read),
        ("sigma_t", Access::Read),
        ("sigma_s", Access::Read),
        ("uprev", Access::Read),
        ("ucur", Access::ReadWrite),
        ("tbuf", Access::ReadWrite),
        ("intensity", Access::ReadWrite),
        ("phi", Access::ReadWrite),
        ("vox", Access::ReadWrite),
        ("rayt", Access::ReadWrite),
        ("stats", Access::ReadWrite),
    ],
    entries: &["sweep", "collect", "reduce"],
    constants: &[],
    uniforms: &[(
        "P",
        struct_layout!(GpuParams; nx, ny, nz, nv, face, per, slots, rays, max_rays, wrap, d_i,
            converge, ring, phi_ring, row, crow, rel, h3, ts, pad),
    )],
};

/// The device buffers of one prepared solve.
#[derive(Debug)]
struct Buffers {
    params: Vec<wgpu::Buffer>,
    segs: wgpu::Buffer,
    starts: wgpu::Buffer,
    dirs: wgpu::Buffer,
    sigma_t: wgpu::Buffer,
    sigma_s: wgpu::Buffer,
    source: wgpu::Buffer,
    u: [wgpu::Buffer; 2],
    tbuf: wgpu::Buffer,
    intensity: wgpu::Buffer,
    phi: wgpu::Buffer,
    vox: wgpu::Buffer,
    rayt: wgpu::Buffer,
    stats: wgpu::Buffer,
}

/// A prepared GPU LPM solve on one medium: the CPU setup (directions, F, tables, the medium in
/// f32), the buffers (allocated once, reused by every [`GpuLpm::solve`]), pipelines and bind
/// groups.
#[derive(Debug)]
pub struct GpuLpm<'a> {
    ctx: &'a GpuContext,
    /// The CPU setup whose tables and f32 medium are uploaded.
    pub setup: CpuLpm<f32>,
    dirs: Vec<GpuDir>,
    b: Buffers,
    pipelines: [wgpu::ComputePipeline; 3],
    /// `binds[parity][face]`: parity p reads U[p] and writes U[1 − p].
    binds: [Vec<wgpu::BindGroup>; 2],
    sweep_groups: [[u32; 2]; 6],
    collect_groups: [u32; 2],
    ring: usize,
    phi_ring: usize,
    resident: u64,
    parity: usize,
    orders: usize,
    tallies: Vec<OrderTally>,
    phi_orders: Vec<Vec<f32>>,
}

fn too_large(ctx: &GpuContext, what: String, needed: u64, limit_name: &'static str) -> GpuError {
    GpuError::TooLarge {
        what,
        needed,
        limit: u64::from(u32::MAX),
        limit_name,
        adapter: ctx.info().name.clone(),
    }
}

impl<'a> GpuLpm<'a> {
    /// Validates as [`CpuLpm::new`] does, checks every buffer and dispatch against the device
    /// limits (typed errors naming the buffer), then uploads the tables and the medium and
    /// builds the pipelines.
    pub fn new(
        ctx: &'a GpuContext,
        medium: &Medium<f64>,
        config: &LpmConfig,
    ) -> Result<Self, SolverError> {
        if config.formulas.deposit == Deposit::Paper {
            return Err(SolverError::Unsupported(
                "lpm on the GPU: the paper's deposit L(1 − e^{−Ks s}) (formulas.deposit = Paper) runs on the CPU only".into(),
            ));
        }
        let setup = CpuLpm::<f32>::new(&medium.cast(), config)?;
        let grid = setup.grid;
        let n = grid.n;
        let nv = grid.len();
        let per = setup.dirs.per_face();
        let d_i = config.storage_i.count();
        let [nx, ny, nz] = n;
        let rays: Vec<usize> = (0..6)
            .map(|f| {
                let (b, c) = lateral_axes(f / 2);
                n[b] * n[c]
            })
            .collect();
        let max_rays = rays.iter().copied().max().unwrap_or(1);
        let slots = setup
            .tables
            .iter()
            .flat_map(|t| t.start.windows(2).map(|w| w[1] - w[0]))
            .max()
            .unwrap_or(1)
            .max(1);
        let max_orders = config.max_orders();
        let ring = CHECK_EVERY.min(max_orders).max(1);
        let phi_ring = if config.keep_orders { ring } else { 1 };
        // Words of every buffer, checked before anything is allocated.
        let words = |what: &str, count: usize| -> Result<u64, GpuError> {
            let c = count as u64;
            if c > u64::from(u32::MAX) {
                return Err(too_large(
                    ctx,
                    format!("the LPM {what} of a {nx}x{ny}x{nz} grid"),
                    c,
                    "u32 indexing in lpm.wgsl",
                ));
            }
            ctx.check_storage_buffer(&format!("the LPM {what} of a {nx}x{ny}x{nz} grid"), 4 * c)?;
            Ok(4 * c)
        };
        let nsegs: usize = setup.tables.iter().map(|t| t.segs.len()).sum();
        let nstarts: usize = setup.tables.iter().map(|t| t.start.len()).sum();
        let sizes = [
            words("sub-segment table", 4 * nsegs)?,
            words("slab starts", nstarts)?,
            words("direction table", 11 * setup.dirs.len())?,
            words("sigma_t", nv)?,
            words("sigma_s", nv)?,
            words("source", nv)?,
            words("U buffer (6 cones)", CONES * nv)?,
            words("U buffer (6 cones)", CONES * nv)?,
            words(
                &format!("class-slotted T buffer ({per} directions x {slots} slots)"),
                per * slots * nv,
            )?,
            words("I buffer", d_i * nv)?,
            words("fluence", nv)?,
            words("voxel tallies", 2 * nv)?,
            words("ray tallies", 2 * 6 * per * max_rays)?,
            words(
                "stats (tallies and per-order fluence)",
                4 + 8 * ring + phi_ring * nv,
            )?,
        ];
        let resident: u64 = sizes.iter().sum::<u64>() + 6 * std::mem::size_of::<GpuParams>() as u64;
        let mut sweep_groups = [[1u32; 2]; 6];
        let mut params = Vec::with_capacity(6);
        let threads = |what: &str, count: usize| -> Result<[u32; 2], GpuError> {
            let groups = (count as u64).div_ceil(u64::from(WG));
            let g = u32::try_from(groups).map_err(|_| {
                too_large(
                    ctx,
                    format!("LPM {what} workgroups"),
                    groups,
                    "u32 workgroup count",
                )
            })?;
            ctx.split_workgroups(&format!("the LPM {what}"), g)
        };
        let collect_groups = threads("collect", nv)?;
        let (rel, converge) = match config.orders {
            Orders::Converge { rel, .. } => (rel as f32, 1),
            Orders::Fixed(_) => (0.0, 0),
        };
        let h3 = grid.dl.powi(3);
        for (f, groups) in sweep_groups.iter_mut().enumerate() {
            *groups = threads("sweep", per * rays[f])?;
            params.push(GpuParams {
                nx: nx as u32,
                ny: ny as u32,
                nz: nz as u32,
                nv: nv as u32,
                face: f as u32,
                per: per as u32,
                slots: slots as u32,
                rays: rays[f] as u32,
                max_rays: max_rays as u32,
                wrap: match config.wrap {
                    WrapBc::Zero => 0,
                    WrapBc::Open => 1,
                    WrapBc::Periodic => 2,
                },
                d_i: d_i as u32,
                converge,
                ring: ring as u32,
                phi_ring: phi_ring as u32,
                row: groups[0] * WG,
                crow: collect_groups[0] * WG,
                rel,
                h3: h3 as f32,
                ts: series_threshold::<f32>(),
                pad: 0,
            });
        }
        // The tables: sub-segment lengths scaled by h and the path factor exactly as the CPU
        // sweep scales them (f64 product, rounded once to f32).
        let mut segs = Vec::with_capacity(nsegs);
        let mut starts = Vec::with_capacity(nstarts);
        let mut dirs = Vec::with_capacity(setup.dirs.len());
        for (i, (d, t)) in setup.dirs.dirs.iter().zip(&setup.tables).enumerate() {
            let scale = grid.dl * setup.path_factor(i);
            let base = segs.len() as u32;
            let start_base = starts.len() as u32;
            starts.extend(t.start.iter().map(|&s| base + s as u32));
            segs.extend(t.segs.iter().map(|s| GpuSeg {
                ob: s.offset[0] as i32,
                oc: s.offset[1] as i32,
                len: (s.len * scale) as f32,
                pad: 0.0,
            }));
            let area = setup.area(i);
            let mut wu = [0.0f32; CONES];
            for (q, w) in wu.iter_mut().enumerate() {
                *w = (area * setup.phase.coarse(i, q) / (h3 * CONE_SOLID_ANGLE)) as f32;
            }
            dirs.push(GpuDir {
                start_base,
                l_bc: 0.0,
                w: (area * d.solid_angle) as f32,
                wphi: (area * d.solid_angle / h3) as f32,
                emit: (area * d.solid_angle * grid.dl * setup.path_factor(i) / d.cos_axis) as f32,
                wu,
            });
        }
        let zeros = |words: usize| vec![0u8; 4 * words];
        let b = ctx.allocating(
            &format!("LPM buffers for a {nx}x{ny}x{nz} grid"),
            resident,
            |dev| Buffers {
                params: params
                    .iter()
                    .map(|p| uniform_buffer(dev, "lpm params", p))
                    .collect(),
                segs: storage_buffer(dev, "lpm segs", bytemuck::cast_slice(&segs)),
                starts: storage_buffer(dev, "lpm starts", bytemuck::cast_slice(&starts)),
                dirs: storage_buffer(dev, "lpm dirs", bytemuck::cast_slice(&dirs)),
                sigma_t: storage_buffer(dev, "lpm sigma_t", bytemuck::cast_slice(&setup.sigma_t)),
                sigma_s: storage_buffer(dev, "lpm sigma_s", bytemuck::cast_slice(&setup.sigma_s)),
                source: storage_buffer(dev, "lpm source", bytemuck::cast_slice(&setup.source)),
                u: [
                    storage_buffer(dev, "lpm U 0", &zeros(CONES * nv)),
                    storage_buffer(dev, "lpm U 1", &zeros(CONES * nv)),
                ],
                tbuf: storage_buffer(dev, "lpm T", &zeros(per * slots * nv)),
                intensity: storage_buffer(dev, "lpm I", &zeros(d_i * nv)),
                phi: storage_buffer(dev, "lpm phi", &zeros(nv)),
                vox: storage_buffer(dev, "lpm voxel tallies", &zeros(2 * nv)),
                rayt: storage_buffer(dev, "lpm ray tallies", &zeros(12 * per * max_rays)),
                stats: storage_buffer(dev, "lpm stats", &zeros(4 + 8 * ring + phi_ring * nv)),
            },
        )?;
        let kernel = Kernel::new(ctx, &SPEC, &[])?;
        let pipelines = [
            kernel.pipeline("sweep")?,
            kernel.pipeline("collect")?,
            kernel.pipeline("reduce")?,
        ];
        let mut binds: [Vec<wgpu::BindGroup>; 2] = [Vec::new(), Vec::new()];
        for (parity, set) in binds.iter_mut().enumerate() {
            for p in &b.params {
                set.push(kernel.bind(
                    ctx,
                    &[
                        ("P", p),
                        ("segs", &b.segs),
                        ("starts", &b.starts),
                        ("dirs", &b.dirs),
                        ("sigma_t", &b.sigma_t),
                        ("sigma_s", &b.sigma_s),
                        ("uprev", &b.u[parity]),
                        ("ucur", &b.u[1 - parity]),
                        ("tbuf", &b.tbuf),
                        ("intensity", &b.intensity),
                        ("phi", &b.phi),
                        ("vox", &b.vox),
                        ("rayt", &b.rayt),
                        ("stats", &b.stats),
                    ],
                )?);
            }
        }
        ctx.check_lost()?;
        Ok(Self {
            ctx,
            setup,
            dirs,
            b,
            pipelines,
            binds,
            sweep_groups,
            collect_groups,
            ring,
            phi_ring,
            resident,
            parity: 0,
            orders: 0,
            tallies: Vec::new(),
            phi_orders: Vec::new(),
        })
    }

    /// The grid.
    pub fn grid(&self) -> &Grid {
        &self.setup.grid
    }

    /// Bytes of the device buffers (Σ sizes as allocated).
    pub fn device_bytes(&self) -> u64 {
        self.resident
    }

    /// Runs the scattering orders with the boundary radiance `boundary` (as
    /// [`CpuLpm::solve`]); `observer(order, unshot / unshot after order 0)` sees every order,
    /// at the checkpoints. Reuses the buffers: a second call starts afresh.
    pub fn solve(
        &mut self,
        boundary: &BoundaryLight,
        mut observer: impl FnMut(usize, f64),
    ) -> Result<LpmSolution<f32>, SolverError> {
        let ndirs = self.setup.dirs.len();
        if boundary.radiance.len() != ndirs {
            return Err(SolverError::FieldSize {
                field: "boundary radiance",
                expected: ndirs,
                got: boundary.radiance.len(),
            });
        }
        let ctx = self.ctx;
        let grid = self.setup.grid;
        let nv = grid.len() as u64;
        let d_i = self.setup.config.storage_i.count() as u64;
        for (d, &l) in self.dirs.iter_mut().zip(&boundary.radiance) {
            d.l_bc = l as f32;
        }
        ctx.queue
            .write_buffer(&self.b.dirs, 0, bytemuck::cast_slice(&self.dirs));
        // U⁰ = I⁰ = j/4π (D9); φ, the stats and the ray tallies start at zero.
        let mut enc = ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("lpm init"),
            });
        for q in 0..CONES as u64 {
            enc.copy_buffer_to_buffer(&self.b.source, 0, &self.b.u[0], 4 * q * nv, 4 * nv);
        }
        for q in 0..d_i {
            enc.copy_buffer_to_buffer(&self.b.source, 0, &self.b.intensity, 4 * q * nv, 4 * nv);
        }
        enc.clear_buffer(&self.b.phi, 0, None);
        enc.clear_buffer(&self.b.stats, 0, None);
        enc.clear_buffer(&self.b.rayt, 0, None);
        ctx.submit_and_read(enc, &[])?;
        self.parity = 0;
        self.orders = 0;
        self.tallies.clear();
        self.phi_orders.clear();
        let max = self.setup.config.max_orders();
        let every = self.ring as u32;
        let run = run_checkpointed(
            ctx,
            self,
            "lpm orders",
            max,
            every,
            Stop::Cap,
            &mut observer,
        )?;
        let unshot_buf = &self.b.u[self.orders % 2];
        let out = ctx.submit_and_read(
            ctx.device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("lpm readback"),
                }),
            &[
                (unshot_buf, 4 * CONES as u64 * nv),
                (&self.b.intensity, 4 * d_i * nv),
                (&self.b.phi, 4 * nv),
            ],
        )?;
        let floats = |bytes: &[u8]| -> Vec<f32> { bytemuck::pod_collect_to_vec(bytes) };
        let split =
            |v: Vec<f32>| -> Vec<Vec<f32>> { v.chunks(nv as usize).map(|c| c.to_vec()).collect() };
        let memory = Memory {
            formula: super::memory_bytes(&grid, &self.setup.config, 4),
            resident_measured: self.resident,
        };
        Ok(LpmSolution {
            grid,
            intensity: split(floats(&out[1])),
            unshot: split(floats(&out[0])),
            phi: floats(&out[2]),
            phi_orders: std::mem::take(&mut self.phi_orders),
            orders: self.orders,
            tallies: self.tallies.clone(),
            stop: run.stop,
            seconds: run.seconds,
            memory,
        })
    }

    /// Words of the stats buffer read back at a checkpoint.
    fn stats_words(&self) -> usize {
        let head = 4 + 8 * self.ring;
        if self.setup.config.keep_orders {
            head + self.phi_ring * self.setup.grid.len()
        } else {
            head
        }
    }
}

impl Checkpointed for GpuLpm<'_> {
    type Stop = Stop;

    /// `n` orders: per face a sweep and a collect, then the reduction.
    fn record(&mut self, pass: &mut wgpu::ComputePass<'_>, n: u32) {
        for _ in 0..n {
            let set = &self.binds[self.parity];
            for (f, bind) in set.iter().enumerate() {
                pass.set_bind_group(0, bind, &[]);
                pass.set_pipeline(&self.pipelines[0]);
                pass.dispatch_workgroups(self.sweep_groups[f][0], self.sweep_groups[f][1], 1);
                pass.set_pipeline(&self.pipelines[1]);
                pass.dispatch_workgroups(self.collect_groups[0], self.collect_groups[1], 1);
            }
            pass.set_pipeline(&self.pipelines[2]);
            pass.dispatch_workgroups(1, 1, 1);
            self.parity = 1 - self.parity;
        }
    }

    fn readback(&self) -> (wgpu::Buffer, u64) {
        (self.b.stats.clone(), 4 * self.stats_words() as u64)
    }

    fn checkpoint(
        &mut self,
        _n: u32,
        bytes: &[u8],
        observer: &mut dyn FnMut(usize, f64),
    ) -> Option<Stop> {
        let w: Vec<u32> = bytemuck::pod_collect_to_vec(bytes);
        let word = |k: usize| w.get(k).copied().unwrap_or(0);
        let f = |k: usize| f64::from(f32::from_bits(word(k)));
        let (done_orders, done) = (word(0) as usize, word(1));
        let nv = self.setup.grid.len();
        let head = 4 + 8 * self.ring;
        for order in self.orders..done_orders {
            let s = 4 + 8 * (order % self.ring);
            let scattered = f(s + 4);
            let tally = OrderTally {
                injected: f(s),
                emitted: f(s + 1),
                exited: f(s + 2),
                absorbed: f(s + 3),
                scattered,
                unshot: scattered,
            };
            self.tallies.push(tally);
            let first = self.tallies[0].unshot;
            observer(order, tally.unshot / first);
            if self.setup.config.keep_orders {
                let p = head + (order % self.phi_ring) * nv;
                self.phi_orders
                    .push((p..p + nv).map(|k| f32::from_bits(word(k))).collect());
            }
        }
        self.orders = done_orders;
        match done {
            1 => Some(Stop::Converged),
            2 => Some(Stop::NonFinite),
            _ => None,
        }
    }
}
