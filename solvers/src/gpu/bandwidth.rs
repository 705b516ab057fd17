//! A device-memory copy-bandwidth probe, run beside GPU benchmarks so that their achieved
//! bytes/s can be reported as a fraction of what the same device copies in the same run.

use super::kernel::{Access, Kernel, KernelSpec, struct_layout, time_pass};
use super::{GpuContext, GpuError, Timer, uniform_buffer};
use bytemuck::{Pod, Zeroable};

/// Uniforms of `copy.wgsl` (mirrored there as `CopyParams`).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct CopyParams {
    len: u32,
    row: u32,
    _pad0: u32,
    _pad1: u32,
}

/// What the probe's host code assumes about `copy.wgsl`.
pub(crate) const SPEC: KernelSpec = KernelSpec {
    label: "copy.wgsl",
    source: include_str!("copy.wgsl"),
    bindings: &[
        ("P", Access::Uniform),
        ("src", Access::Read),
        ("dst", Access::ReadWrite),
    ],
    entries: &["copy"],
    constants: &[],
    uniforms: &[("P", struct_layout!(CopyParams; len, row, _pad0, _pad1))],
};

/// Result of [`copy_gbs`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CopyBandwidth {
    /// Bytes read plus bytes written per second, in GB/s (10⁹ bytes).
    pub gbs: f64,
    /// Buffer size copied, in bytes.
    pub bytes: u64,
    /// How the time was measured.
    pub timer: Timer,
}

/// Copies a `bytes`-sized buffer `reps` times with a compute kernel (after one warm-up) and
/// returns (read + written bytes)/s of the best of `trials` passes.
pub fn copy_gbs(
    ctx: &GpuContext,
    bytes: u64,
    reps: u32,
    trials: u32,
) -> Result<CopyBandwidth, GpuError> {
    let len = (bytes / 16).max(1);
    let bytes = len * 16;
    ctx.check_storage_buffer("bandwidth probe buffer", bytes)?;
    let len32 = u32::try_from(len).map_err(|_| GpuError::TooLarge {
        what: "bandwidth probe elements".into(),
        needed: len,
        limit: u64::from(u32::MAX),
        limit_name: "u32 element index",
        adapter: ctx.info().name.clone(),
    })?;
    let [gx, gy] = ctx.split_workgroups("bandwidth probe", len32.div_ceil(256))?;
    let (src, dst, params) = ctx.allocating("bandwidth probe buffers", 2 * bytes, |d| {
        let buffer = |label| {
            d.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes,
                usage: wgpu::BufferUsages::STORAGE,
                mapped_at_creation: false,
            })
        };
        let p = CopyParams {
            len: len32,
            row: gx * 256,
            _pad0: 0,
            _pad1: 0,
        };
        (
            buffer("probe src"),
            buffer("probe dst"),
            uniform_buffer(d, "probe params", &p),
        )
    })?;
    let kernel = Kernel::new(ctx, &SPEC, &[])?;
    let pipeline = kernel.pipeline("copy")?;
    let bind = kernel.bind(ctx, &[("P", &params), ("src", &src), ("dst", &dst)])?;
    let mut best = 0.0f64;
    for trial in 0..=trials {
        let n = if trial == 0 { 1 } else { reps.max(1) };
        let seconds = time_pass(ctx, "copy", |pass| {
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &bind, &[]);
            for _ in 0..n {
                pass.dispatch_workgroups(gx, gy, 1);
            }
        })?;
        if trial > 0 && seconds > 0.0 {
            best = best.max(2.0 * bytes as f64 * f64::from(n) / seconds / 1e9);
        }
    }
    Ok(CopyBandwidth {
        gbs: best,
        bytes,
        timer: ctx.timer(),
    })
}
