//! A device-memory copy-bandwidth probe, run beside GPU benchmarks so that their achieved
//! bytes/s can be reported as a fraction of what the same device copies in the same run.

use super::{GpuContext, GpuError, PassTimer, Timer, storage_entry, uniform_entry};
use bytemuck::{Pod, Zeroable};

/// Uniforms of `copy.wgsl` (mirrored there as `CopyParams`).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct CopyParams {
    len: u32,
    row: u32,
    _pad: [u32; 2],
}

/// The WGSL source of the probe.
pub const SHADER: &str = include_str!("copy.wgsl");

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
    let groups = len32.div_ceil(256);
    let max = ctx.limits().max_compute_workgroups_per_dimension;
    let (gx, gy) = if groups <= max {
        (groups, 1)
    } else {
        (max, groups.div_ceil(max))
    };
    ctx.check_workgroups("bandwidth probe", gy)?;
    let device = &ctx.device;
    let (src, dst, params) = ctx.allocating("bandwidth probe buffers", 2 * bytes, |d| {
        let src = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("probe src"),
            size: bytes,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        let dst = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("probe dst"),
            size: bytes,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        let p = CopyParams {
            len: len32,
            row: gx * 256,
            _pad: [0; 2],
        };
        let params = {
            use wgpu::util::DeviceExt;
            d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("probe params"),
                contents: bytemuck::bytes_of(&p),
                usage: wgpu::BufferUsages::UNIFORM,
            })
        };
        (src, dst, params)
    })?;
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("copy.wgsl"),
        source: wgpu::ShaderSource::Wgsl(SHADER.into()),
    });
    let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("probe"),
        entries: &[
            uniform_entry(0),
            storage_entry(1, true),
            storage_entry(2, false),
        ],
    });
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("probe"),
        bind_group_layouts: &[Some(&layout)],
        immediate_size: 0,
    });
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some("copy"),
        layout: Some(&pipeline_layout),
        module: &module,
        entry_point: Some("copy"),
        compilation_options: Default::default(),
        cache: None,
    });
    let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("probe"),
        layout: &layout,
        entries: &[
            wgpu::BindGroupEntry {
                binding: 0,
                resource: params.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: src.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 2,
                resource: dst.as_entire_binding(),
            },
        ],
    });
    let mut best = 0.0f64;
    let mut timer_kind = ctx.timer();
    for trial in 0..=trials {
        let mut timer = PassTimer::new(ctx);
        timer_kind = timer.timer();
        let mut encoder = device.create_command_encoder(&Default::default());
        let n = if trial == 0 { 1 } else { reps.max(1) };
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("copy"),
                timestamp_writes: timer.writes(),
            });
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &bind, &[]);
            for _ in 0..n {
                pass.dispatch_workgroups(gx, gy, 1);
            }
        }
        timer.resolve(&mut encoder);
        let reads: Vec<(&wgpu::Buffer, u64)> =
            timer.readback().map(|b| (b, 16)).into_iter().collect();
        let out = ctx.submit_and_read(encoder, &reads)?;
        timer.record(out.first().map(|v| v.as_slice()));
        if trial > 0 && timer.seconds() > 0.0 {
            best = best.max(2.0 * bytes as f64 * f64::from(n) / timer.seconds() / 1e9);
        }
    }
    Ok(CopyBandwidth {
        gbs: best,
        bytes,
        timer: timer_kind,
    })
}
