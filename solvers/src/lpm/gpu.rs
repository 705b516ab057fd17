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
use super::directions::{CONES, lateral_axes};
use super::{
    BoundaryLight, Deposit, LpmConfig, LpmSolution, Memory, MemoryBytes, OrderTally, Orders,
    Streaming, WrapBc,
};
use crate::gpu::kernel::{
    Access, Checkpointed, Kernel, KernelSpec, run_checkpointed, struct_layout,
};
use crate::gpu::{GpuContext, GpuError, storage_buffer, uniform_buffer};
use crate::method::Stop;
use crate::scene::Phase;
use crate::{Grid, Medium, SolverError};
use bytemuck::{Pod, Zeroable};

/// Threads per workgroup of `sweep` and `collect`.
const WG: u32 = 64;

/// Orders recorded per submission (and read back at once): the checkpoint interval K.
pub const CHECK_EVERY: usize = 8;

/// Uniforms of `lpm.wgsl` (`Params` there, same fields in the same order; 100 bytes), one per
/// (face, slice).
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
    z0: u32,
    z1: u32,
    tstride: u32,
    first: u32,
    last: u32,
    iso: f32,
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
            converge, ring, phi_ring, row, crow, rel, h3, ts, z0, z1, tstride, first, last,
            iso),
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
    /// `binds[parity][pass]`: parity p reads U[p] and writes U[1 − p]; one pass per (face,
    /// slice) in face order, slices in sweep order.
    binds: [Vec<wgpu::BindGroup>; 2],
    /// Per pass: the sweep's and the collect's workgroups.
    groups: Vec<([u32; 2], [u32; 2])>,
    slabs: usize,
    formula: super::MemoryBytes,
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

/// The device buffers of a solve with `slabs` slabs per slice, in words (`T`: the
/// class-slotted T of one slice), and our per-buffer formula (D18, D19) from them: every
/// buffer is resident, so the formula's transient part is 0.
struct DeviceLayout {
    buffers: Vec<(&'static str, u64)>,
    formula: MemoryBytes,
}

fn device_layout(
    setup: &CpuLpm<f32>,
    slots: usize,
    ring: usize,
    phi_ring: usize,
    slabs: usize,
) -> DeviceLayout {
    let grid = &setup.grid;
    let n = grid.n;
    let nv = grid.len() as u64;
    let per = setup.dirs.per_face() as u64;
    let d_i = setup.config.storage_i.count() as u64;
    let max_rays = (0..3)
        .map(|a| {
            let (b, c) = lateral_axes(a);
            (n[b] * n[c]) as u64
        })
        .max()
        .unwrap_or(1);
    let nsegs: u64 = setup.tables.iter().map(|t| t.segs.len() as u64).sum();
    let nstarts: u64 = setup.tables.iter().map(|t| t.start.len() as u64).sum();
    let passes: u64 = (0..6)
        .map(|f| {
            let na = n[f / 2];
            na.div_ceil(slabs.clamp(1, na)) as u64
        })
        .sum();
    let t = (per * slots as u64).saturating_mul(super::slice_voxels(grid, slabs.max(1)));
    let buffers = vec![
        ("sub-segment table", 4 * nsegs),
        ("slab starts", nstarts),
        ("direction table", 11 * setup.dirs.len() as u64),
        ("sigma_t", nv),
        ("sigma_s", nv),
        ("source", nv),
        ("U buffer (6 cones)", CONES as u64 * nv),
        ("U buffer (6 cones)", CONES as u64 * nv),
        ("T", t),
        ("I buffer", d_i * nv),
        ("fluence", nv),
        ("voxel tallies", 2 * nv),
        // Two tally words per (direction, ray) of all six faces, then the ray radiances of
        // one face carried between its slices.
        ("ray tallies and states", 13 * per * max_rays),
        ("stats", 4 + 8 * ring as u64 + phi_ring as u64 * nv),
    ];
    let w = |name: &str| -> u64 {
        4 * buffers
            .iter()
            .filter(|b| b.0 == name)
            .map(|b| b.1)
            .sum::<u64>()
    };
    let formula = MemoryBytes {
        medium: w("sigma_t") + w("sigma_s") + w("source"),
        u: w("U buffer (6 cones)"),
        i: w("I buffer"),
        t: w("T"),
        fluence: w("fluence"),
        tables: w("sub-segment table")
            + w("slab starts")
            + w("direction table")
            + passes * std::mem::size_of::<GpuParams>() as u64,
        tallies: w("voxel tallies") + w("ray tallies and states") + w("stats"),
        rays: 0,
    };
    DeviceLayout { buffers, formula }
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
        // The host setup (tables, the f32 medium) holds no T: check it as the smallest
        // streamed CPU solve against the host's memory; the device's own budget is below.
        let host = LpmConfig {
            streaming: Streaming::Slabs(1),
            memory_budget: None,
            ..config.clone()
        };
        let mut setup = CpuLpm::<f32>::new(&medium.cast(), &host)?;
        setup.config = config.clone();
        let grid = setup.grid;
        let n = grid.n;
        let nv = grid.len();
        let per = setup.dirs.per_face();
        let [nx, ny, nz] = n;
        let n_max = nx.max(ny).max(nz);
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
        let layout = |slabs: usize| device_layout(&setup, slots, ring, phi_ring, slabs);
        // Slabs per slice: the class-slotted T of one slice must fit one storage binding (and
        // u32 indexing), and with a memory budget every buffer together must fit it.
        let limits = ctx.limits();
        let bind_max = limits
            .max_storage_buffer_binding_size
            .min(limits.max_buffer_size);
        let fits = |s: usize| {
            let t = (per * slots) as u64 * super::slice_voxels(&grid, s);
            t <= u64::from(u32::MAX)
                && 4 * t <= bind_max
                && config
                    .memory_budget
                    .is_none_or(|b| layout(s).formula.total() <= b)
        };
        let slabs = match config.streaming {
            Streaming::Whole => n_max,
            Streaming::Slabs(s) => s.clamp(1, n_max),
            Streaming::Auto if fits(n_max) => n_max,
            Streaming::Auto => {
                let (mut lo, mut hi) = (1usize, n_max);
                while lo < hi {
                    let mid = (lo + hi).div_ceil(2);
                    if fits(mid) {
                        lo = mid;
                    } else {
                        hi = mid - 1;
                    }
                }
                lo
            }
        };
        let plan = layout(slabs);
        if config.memory_budget.is_some() {
            config.check_budget_sliced(&grid, plan.formula.total(), slabs)?;
        }
        // Every buffer checked against the limits before anything is allocated.
        for &(what, words) in &plan.buffers {
            let what = if what == "T" {
                format!(
                    "the LPM class-slotted T buffer ({per} directions x {slots} slots x {} slab(s)) of a {nx}x{ny}x{nz} grid",
                    slabs.min(n_max)
                )
            } else {
                format!("the LPM {what} of a {nx}x{ny}x{nz} grid")
            };
            if words > u64::from(u32::MAX) {
                return Err(too_large(ctx, what, words, "u32 indexing in lpm.wgsl").into());
            }
            ctx.check_storage_buffer(&what, 4 * words)?;
        }
        let words = |name: &str| {
            plan.buffers
                .iter()
                .find(|b| b.0 == name)
                .map_or(0, |b| b.1 as usize)
        };
        let tstride = super::slice_voxels(&grid, slabs) as usize;
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
        let (rel, converge) = match config.orders {
            Orders::Converge { rel, .. } => (rel as f32, 1),
            Orders::Fixed(_) => (0.0, 0),
        };
        let h3 = grid.dl.powi(3);
        let d_i = config.storage_i.count();
        let mut params = Vec::new();
        let mut groups = Vec::new();
        for (f, &face_rays) in rays.iter().enumerate() {
            let na = n[f / 2];
            let step = slabs.min(na);
            let sweep = threads("sweep", per * face_rays)?;
            for z0 in (0..na).step_by(step) {
                let z1 = (z0 + step).min(na);
                let collect = threads("collect", (z1 - z0) * face_rays)?;
                groups.push((sweep, collect));
                params.push(GpuParams {
                    nx: nx as u32,
                    ny: ny as u32,
                    nz: nz as u32,
                    nv: nv as u32,
                    face: f as u32,
                    per: per as u32,
                    slots: slots as u32,
                    rays: face_rays as u32,
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
                    row: sweep[0] * WG,
                    crow: collect[0] * WG,
                    rel,
                    h3: h3 as f32,
                    ts: series_threshold::<f32>(),
                    z0: z0 as u32,
                    z1: z1 as u32,
                    tstride: tstride as u32,
                    first: u32::from(z0 == 0),
                    last: u32::from(z1 == na),
                    // As the CPU collect: the isotropic F is rank one, w_{k,d′} = w_φ,k/4π.
                    iso: if config.phase == Phase::Isotropic {
                        (1.0 / (4.0 * std::f64::consts::PI)) as f32
                    } else {
                        0.0
                    },
                });
            }
        }
        // The tables: sub-segment lengths scaled by h and the path factor exactly as the CPU
        // sweep scales them (f64 product, rounded once to f32).
        let mut segs = Vec::with_capacity(words("sub-segment table") / 4);
        let mut starts = Vec::with_capacity(words("slab starts"));
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
            let (wphi, wu) =
                super::collect_weights(&grid, &config.formulas, &setup.dirs, &setup.phase, i);
            let wu = wu.map(|w| w as f32);
            dirs.push(GpuDir {
                start_base,
                l_bc: 0.0,
                w: (area * d.solid_angle) as f32,
                wphi: wphi as f32,
                emit: (area * d.solid_angle * grid.dl * setup.path_factor(i) / d.cos_axis) as f32,
                wu,
            });
        }
        let zeros = |name: &str| vec![0u8; 4 * words(name)];
        let b = ctx.allocating(
            &format!("LPM buffers for a {nx}x{ny}x{nz} grid"),
            plan.formula.total(),
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
                    storage_buffer(dev, "lpm U 0", &zeros("U buffer (6 cones)")),
                    storage_buffer(dev, "lpm U 1", &zeros("U buffer (6 cones)")),
                ],
                tbuf: storage_buffer(dev, "lpm T", &zeros("T")),
                intensity: storage_buffer(dev, "lpm I", &zeros("I buffer")),
                phi: storage_buffer(dev, "lpm phi", &zeros("fluence")),
                vox: storage_buffer(dev, "lpm voxel tallies", &zeros("voxel tallies")),
                rayt: storage_buffer(dev, "lpm ray tallies", &zeros("ray tallies and states")),
                stats: storage_buffer(dev, "lpm stats", &zeros("stats")),
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
        // Measured: the sizes of the buffers as wgpu reports them.
        let resident = b.params.iter().map(|p| p.size()).sum::<u64>()
            + [
                &b.segs,
                &b.starts,
                &b.dirs,
                &b.sigma_t,
                &b.sigma_s,
                &b.source,
                &b.u[0],
                &b.u[1],
                &b.tbuf,
                &b.intensity,
                &b.phi,
                &b.vox,
                &b.rayt,
                &b.stats,
            ]
            .iter()
            .map(|x| x.size())
            .sum::<u64>();
        Ok(Self {
            ctx,
            setup,
            dirs,
            b,
            pipelines,
            binds,
            groups,
            slabs,
            formula: plan.formula,
            ring,
            phi_ring,
            resident,
            parity: 0,
            orders: 0,
            tallies: Vec::new(),
            phi_orders: Vec::new(),
        })
    }

    /// Slabs per slice of this solver's sweeps (≥ the longest axis: not streamed).
    pub fn slabs(&self) -> usize {
        self.slabs
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
        boundary.check(&self.setup.dirs)?;
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
            formula: self.formula,
            resident_measured: self.resident,
            slabs: self.slabs,
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
            for (bind, (sweep, collect)) in set.iter().zip(&self.groups) {
                pass.set_bind_group(0, bind, &[]);
                pass.set_pipeline(&self.pipelines[0]);
                pass.dispatch_workgroups(sweep[0], sweep[1], 1);
                pass.set_pipeline(&self.pipelines[1]);
                pass.dispatch_workgroups(collect[0], collect[1], 1);
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
