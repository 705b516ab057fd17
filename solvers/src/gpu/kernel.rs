//! One small layer between a WGSL kernel and its host code: the bindings, entry points,
//! override constants and uniform structs of a shader are declared once, by name, in a
//! [`KernelSpec`] beside the host code; [`Kernel`] builds the shader module, the bind-group
//! layout and one pipeline per entry point from it, and [`Kernel::bind`] builds bind groups
//! checked by name. [`specs`] lists every kernel of the crate, so that the crate's tests
//! (`tests/kernel_contract.rs`, no GPU needed) check each spec against its WGSL with naga:
//! binding indices and access, entry points, override constants, and the size and member
//! offsets of every uniform struct against the Rust `#[repr(C)]` struct that fills it.
//!
//! The module also holds the submit path every solve loop shares: [`time_pass`] for
//! benchmarks, and (crate-internal) `run_checkpointed`, which records a few steps per
//! submission, reads a small state back after each and stops exactly where a `Checkpointed`
//! kernel says.

use super::{GpuContext, GpuError, PassTimer, Timer};
use std::time::Instant;

/// How a binding is accessed by the shader (`var<uniform>`, `var<storage, read>`,
/// `var<storage, read_write>`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Access {
    /// A uniform buffer.
    Uniform,
    /// A read-only storage buffer.
    Read,
    /// A read-write storage buffer.
    ReadWrite,
}

/// The byte layout of a Rust `#[repr(C)]` struct uploaded as a WGSL struct: its size and
/// each member's name and offset, in declaration order. Built with `struct_layout!`, which
/// fails to compile unless it lists every field.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StructLayout {
    /// The Rust type's name.
    pub rust: &'static str,
    /// `size_of` the Rust type.
    pub size: usize,
    /// (field name, `offset_of!`) for every field, in declaration order.
    pub members: &'static [(&'static str, usize)],
}

/// What the host code of one WGSL kernel assumes about it, declared once.
#[derive(Debug, Clone, Copy)]
pub struct KernelSpec {
    /// Label of the module, layout and pipelines (and the kernel's name in errors).
    pub label: &'static str,
    /// The WGSL source (`include_str!` of the `.wgsl` beside the host code).
    pub source: &'static str,
    /// The bindings of `@group(0)`: binding index = position, name = the WGSL global.
    pub bindings: &'static [(&'static str, Access)],
    /// The compute entry points, one pipeline each.
    pub entries: &'static [&'static str],
    /// The pipeline-overridable constants the host may set.
    pub constants: &'static [&'static str],
    /// For each uniform binding (by name), the layout of the Rust struct written to it.
    pub uniforms: &'static [(&'static str, StructLayout)],
}

/// Every kernel of the crate, for the host↔WGSL contract test (`tests/kernel_contract.rs`):
/// the kernels of every registered method ([`crate::Method::kernels`], so a new method's
/// kernel is checked without an edit here) and the crate's own (the copy probe), each once.
pub fn specs() -> Vec<&'static KernelSpec> {
    let mut all: Vec<&'static KernelSpec> = vec![&super::bandwidth::SPEC];
    for family in crate::method::METHODS {
        if let Ok(m) = (family.build)(None, &crate::method::Params::none()) {
            for k in m.kernels() {
                if !all.iter().any(|s| s.label == k.label) {
                    all.push(k);
                }
            }
        }
    }
    all
}

/// The layout of a `#[repr(C)]` struct: `struct_layout!(GpuParams; nx, ny, …)`. Every
/// field must be listed (an exhaustive pattern checks it at compile time); the contract test
/// compares the order and offsets with the WGSL struct.
macro_rules! struct_layout {
    ($ty:ident; $($field:ident),* $(,)?) => {{
        #[allow(dead_code)]
        fn every_field_is_listed(v: $ty) {
            let $ty { $($field: _),* } = v;
        }
        $crate::gpu::kernel::StructLayout {
            rust: stringify!($ty),
            size: ::std::mem::size_of::<$ty>(),
            members: &[$((stringify!($field), ::std::mem::offset_of!($ty, $field))),*],
        }
    }};
}
pub(crate) use struct_layout;

/// A shader module's bind-group layout and one compute pipeline per entry point, built from a
/// [`KernelSpec`].
#[derive(Debug)]
pub struct Kernel {
    spec: &'static KernelSpec,
    layout: wgpu::BindGroupLayout,
    pipelines: Vec<wgpu::ComputePipeline>,
}

impl Kernel {
    /// Compiles `spec.source` and creates its layout and pipelines, with the override
    /// `constants` (each must be declared in `spec.constants`). Workgroup memory is not
    /// zero-initialised: the kernels write before they read.
    pub fn new(
        ctx: &GpuContext,
        spec: &'static KernelSpec,
        constants: &[(&str, f64)],
    ) -> Result<Self, GpuError> {
        for (name, _) in constants {
            if !spec.constants.contains(name) {
                return Err(contract(
                    spec,
                    name,
                    Contract::UnknownConstant,
                    spec.constants,
                ));
            }
        }
        ctx.allocating(&format!("{} pipelines", spec.label), 0, |device| {
            let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(spec.label),
                source: wgpu::ShaderSource::Wgsl(spec.source.into()),
            });
            let entries: Vec<wgpu::BindGroupLayoutEntry> = spec
                .bindings
                .iter()
                .enumerate()
                .map(|(i, (_, access))| layout_entry(i as u32, *access))
                .collect();
            let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some(spec.label),
                entries: &entries,
            });
            let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some(spec.label),
                bind_group_layouts: &[Some(&layout)],
                immediate_size: 0,
            });
            let pipelines = spec
                .entries
                .iter()
                .map(|entry| {
                    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                        label: Some(entry),
                        layout: Some(&pipeline_layout),
                        module: &module,
                        entry_point: Some(entry),
                        compilation_options: wgpu::PipelineCompilationOptions {
                            constants,
                            zero_initialize_workgroup_memory: false,
                        },
                        cache: None,
                    })
                })
                .collect();
            Self {
                spec,
                layout,
                pipelines,
            }
        })
    }

    /// The spec this kernel was built from.
    pub fn spec(&self) -> &'static KernelSpec {
        self.spec
    }

    /// The pipeline of entry point `entry` (cloned: wgpu handles are reference-counted).
    pub fn pipeline(&self, entry: &str) -> Result<wgpu::ComputePipeline, GpuError> {
        let spec = self.spec;
        spec.entries
            .iter()
            .zip(&self.pipelines)
            .find(|(e, _)| **e == entry)
            .map(|(_, p)| p.clone())
            .ok_or_else(|| contract(spec, entry, Contract::UnknownEntry, spec.entries))
    }

    /// A bind group with `buffers` bound by binding name: every declared binding exactly once,
    /// nothing else ([`GpuError::Contract`] otherwise).
    pub fn bind(
        &self,
        ctx: &GpuContext,
        buffers: &[(&str, &wgpu::Buffer)],
    ) -> Result<wgpu::BindGroup, GpuError> {
        let spec = self.spec;
        let declared: Vec<&'static str> = spec.bindings.iter().map(|(n, _)| *n).collect();
        for (q, (name, _)) in buffers.iter().enumerate() {
            if !declared.contains(name) {
                return Err(contract(spec, name, Contract::UnknownBinding, &declared));
            }
            if buffers[..q].iter().any(|(n, _)| n == name) {
                return Err(contract(spec, name, Contract::DuplicateBinding, &declared));
            }
        }
        let mut entries = Vec::with_capacity(declared.len());
        for (i, name) in declared.iter().enumerate() {
            let buffer = buffers
                .iter()
                .find(|(n, _)| n == name)
                .map(|(_, b)| *b)
                .ok_or_else(|| contract(spec, name, Contract::MissingBinding, &declared))?;
            entries.push(wgpu::BindGroupEntry {
                binding: i as u32,
                resource: buffer.as_entire_binding(),
            });
        }
        ctx.allocating(&format!("{} bind group", spec.label), 0, |device| {
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some(spec.label),
                layout: &self.layout,
                entries: &entries,
            })
        })
    }
}

/// How a use of a kernel broke its [`KernelSpec`] (see [`GpuError::Contract`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum Contract {
    /// [`Kernel::bind`] got no buffer for a declared binding.
    #[error("no buffer given for binding")]
    MissingBinding,
    /// [`Kernel::bind`] got a buffer for a name that is not a declared binding.
    #[error("no binding declared named")]
    UnknownBinding,
    /// [`Kernel::bind`] got two buffers for one binding.
    #[error("two buffers given for binding")]
    DuplicateBinding,
    /// [`Kernel::pipeline`] was asked for an undeclared entry point.
    #[error("no entry point declared named")]
    UnknownEntry,
    /// [`Kernel::new`] got an undeclared override constant.
    #[error("no override constant declared named")]
    UnknownConstant,
}

fn contract(spec: &KernelSpec, name: &str, problem: Contract, declared: &[&str]) -> GpuError {
    GpuError::Contract {
        kernel: spec.label.to_string(),
        problem,
        name: name.to_string(),
        declared: declared.iter().map(|s| s.to_string()).collect(),
    }
}

fn layout_entry(binding: u32, access: Access) -> wgpu::BindGroupLayoutEntry {
    let ty = match access {
        Access::Uniform => wgpu::BufferBindingType::Uniform,
        Access::Read => wgpu::BufferBindingType::Storage { read_only: true },
        Access::ReadWrite => wgpu::BufferBindingType::Storage { read_only: false },
    };
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

/// Records one timed compute pass (`record` fills it) into a new encoder, submits it, waits,
/// adds the pass time to `timer`, and returns the first `read.1` bytes of `read.0` (empty
/// without `read`).
pub(crate) fn submit_pass(
    ctx: &GpuContext,
    timer: &mut PassTimer,
    label: &str,
    record: impl FnOnce(&mut wgpu::ComputePass<'_>),
    read: Option<(&wgpu::Buffer, u64)>,
) -> Result<Vec<u8>, GpuError> {
    let mut encoder = ctx
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(label) });
    {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some(label),
            timestamp_writes: timer.writes(),
        });
        record(&mut pass);
    }
    timer.resolve(&mut encoder);
    let mut reads: Vec<(&wgpu::Buffer, u64)> = read.into_iter().collect();
    if let Some(t) = timer.readback() {
        reads.push((t, 16));
    }
    let mut out = ctx.submit_and_read(encoder, &reads)?;
    let stamps = if timer.readback().is_some() {
        out.pop()
    } else {
        None
    };
    timer.record(stamps.as_deref());
    Ok(out.pop().unwrap_or_default())
}

/// Benchmarks: records one compute pass with `record`, submits, waits and returns its seconds
/// (GPU timestamps when the device has them, else the wall clock around submit and wait).
pub fn time_pass(
    ctx: &GpuContext,
    label: &str,
    record: impl FnOnce(&mut wgpu::ComputePass<'_>),
) -> Result<f64, GpuError> {
    let mut timer = PassTimer::new(ctx);
    submit_pass(ctx, &mut timer, label, record, None)?;
    Ok(timer.seconds())
}

/// An iterative GPU kernel driven by [`run_checkpointed`]: it records steps, and after every
/// submission reads a small state buffer and says whether to stop.
pub(crate) trait Checkpointed {
    /// Why a solve stopped.
    type Stop;
    /// Records `n` ≥ 1 steps into `pass`, the last of which leaves the state in
    /// [`Checkpointed::readback`].
    fn record(&mut self, pass: &mut wgpu::ComputePass<'_>, n: u32);
    /// The buffer read back after each submission, and how many bytes of it.
    fn readback(&self) -> (wgpu::Buffer, u64);
    /// Takes the read-back bytes after `n` more steps, reports progress to `observer`
    /// (step, value), and returns why to stop, or `None` to go on.
    fn checkpoint(
        &mut self,
        n: u32,
        bytes: &[u8],
        observer: &mut dyn FnMut(usize, f64),
    ) -> Option<Self::Stop>;
}

/// How a [`run_checkpointed`] loop ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Checkpoints<S> {
    /// Why it stopped.
    pub stop: S,
    /// Seconds of GPU work (timestamps), else of the whole loop on the wall clock.
    pub seconds: f64,
    /// Which of the two.
    pub timer: Timer,
}

/// Records up to `every` steps per submission, at most `max_steps` in all, calling
/// [`Checkpointed::checkpoint`] after each submission; stops where it returns a reason,
/// else with `cap` once `max_steps` steps are recorded.
pub(crate) fn run_checkpointed<K: Checkpointed>(
    ctx: &GpuContext,
    kernel: &mut K,
    label: &str,
    max_steps: usize,
    every: u32,
    cap: K::Stop,
    observer: &mut dyn FnMut(usize, f64),
) -> Result<Checkpoints<K::Stop>, GpuError> {
    let mut timer = PassTimer::new(ctx);
    let t0 = Instant::now();
    let mut steps = 0usize;
    let mut stop = None;
    while steps < max_steps {
        let n = (max_steps - steps).min(every.max(1) as usize) as u32;
        let (buffer, len) = kernel.readback();
        let bytes = submit_pass(
            ctx,
            &mut timer,
            label,
            |pass| kernel.record(pass, n),
            Some((&buffer, len)),
        )?;
        steps += n as usize;
        stop = kernel.checkpoint(n, &bytes, observer);
        if stop.is_some() {
            break;
        }
    }
    let wall = t0.elapsed().as_secs_f64();
    let kind = timer.timer();
    Ok(Checkpoints {
        stop: stop.unwrap_or(cap),
        seconds: match kind {
            Timer::GpuTimestamps => timer.seconds(),
            Timer::WallClock => wall,
        },
        timer: kind,
    })
}
