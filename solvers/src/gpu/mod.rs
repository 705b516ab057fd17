//! The GPU context every wgpu kernel is built from, and the small pieces they share:
//! buffer readback, GPU timing, the [`kernel`] layer (bindings declared once by name, the
//! checkpointed solve loop) and a copy-bandwidth probe.
//!
//! The caller owns the device: binaries and tests build one [`GpuContext`] (usually with
//! [`GpuContext::from_env`]) and hand `&GpuContext` to each kernel. Kernels create their
//! pipelines and buffers once per problem size, record into command encoders and read back
//! only at checkpoints.
//!
//! ## Environment
//! * `WGPU_BACKEND` (e.g. `vulkan`, `metal`, `dx12`, `gl`) restricts the backends searched.
//! * `WGPU_ADAPTER_NAME` picks the first adapter whose name contains it (case-insensitive);
//!   with no match [`GpuContext::from_env`] fails with [`GpuError::NoMatchingAdapter`] and
//!   lists the adapters it saw.
//! * `WGPU_POWER_PREF` (`low`/`high`) when no name is given.
//! * `SCATTERBENCH_REQUIRE_GPU=1` makes [`GpuContext::for_tests`] fail instead of skip
//!   when there is no adapter (CI sets it; see `.ci/run`).
//!
//! ## `XDG_RUNTIME_DIR is invalid or not set`
//! With Mesa's Vulkan drivers (lavapipe included) and `XDG_RUNTIME_DIR` unset, opening a
//! context prints `error: XDG_RUNTIME_DIR is invalid or not set in the environment.` to
//! stderr. It is not ours and not an error: Mesa's implicit `VK_LAYER_MESA_device_select`
//! layer looks for a Wayland compositor (to put its GPU first) on every
//! `vkEnumeratePhysicalDevices` call, because wgpu enables `VK_KHR_wayland_surface`
//! whenever the driver offers it, and libwayland prints the line when it cannot find the
//! socket directory. A context enumerates adapters once (two Vulkan calls: count, then
//! list), so the line appears twice per context — it was four before the name lookup and
//! wgpu's choice stopped enumerating separately. wgpu has no safe way to leave the Wayland
//! extension out, and the backends are already only those compiled in (Vulkan on Linux;
//! no GL), so the remaining lines go away only from the environment: set
//! `XDG_RUNTIME_DIR`, or disable the layer with `NODEVICE_SELECT=1`.

pub mod bandwidth;
pub mod kernel;

/// The wgpu version this crate is built against, re-exported for callers' types.
pub use wgpu;

use std::sync::{Arc, Mutex};
use std::time::Instant;
use thiserror::Error;

/// Why a GPU operation failed. Every variant carries enough to act on.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum GpuError {
    /// No adapter at all: no Vulkan/Metal/DX12 driver, or none that wgpu can use.
    #[error(
        "no GPU adapter found (backends searched: {backends}); install a Vulkan driver, e.g. Mesa's lavapipe (`apt-get install mesa-vulkan-drivers`), or run on the CPU backend"
    )]
    NoAdapter {
        /// The backends that were searched.
        backends: String,
    },
    /// `WGPU_ADAPTER_NAME` matched none of the adapters.
    #[error("WGPU_ADAPTER_NAME={wanted:?} matches none of the adapters found: {found:?}")]
    NoMatchingAdapter {
        /// The requested name fragment.
        wanted: String,
        /// Names of the adapters that exist.
        found: Vec<String>,
    },
    /// The adapter refused to create a device.
    #[error("the GPU adapter {adapter:?} could not create a device: {reason}")]
    RequestDevice {
        /// Adapter name.
        adapter: String,
        /// wgpu's reason.
        reason: String,
    },
    /// The problem does not fit the device's limits; checked before anything is allocated.
    #[error(
        "{what} needs {needed} bytes but the GPU device on {adapter:?} allows at most {limit} ({limit_name}); use a smaller grid or the CPU backend"
    )]
    TooLarge {
        /// What was being allocated.
        what: String,
        /// Bytes (or counts) needed.
        needed: u64,
        /// The device's limit.
        limit: u64,
        /// The name of the wgpu limit.
        limit_name: &'static str,
        /// Adapter name.
        adapter: String,
    },
    /// The device ran out of memory while allocating.
    #[error(
        "the GPU ran out of memory allocating {what} ({needed} bytes in all); use a smaller grid or the CPU backend"
    )]
    OutOfMemory {
        /// What was being allocated.
        what: String,
        /// Total bytes requested.
        needed: u64,
    },
    /// The device was lost (driver reset, GPU removed, timeout).
    #[error("the GPU device was lost: {0}")]
    DeviceLost(String),
    /// Host code used a kernel against its declared [`kernel::KernelSpec`] (a binding missing,
    /// unknown or given twice; an unknown entry point or override constant): a bug in this
    /// crate, reported rather than panicking.
    #[error("GPU kernel {kernel:?}: {problem} {name:?} (declared: {declared:?})")]
    Contract {
        /// The kernel's label.
        kernel: String,
        /// What is wrong.
        problem: kernel::Contract,
        /// The offending name.
        name: String,
        /// The names the spec declares.
        declared: Vec<String>,
    },
    /// wgpu reported a validation or internal error: a bug in this crate, reported rather than
    /// panicking.
    #[error("GPU error in {context}: {message}")]
    Internal {
        /// What was being done.
        context: String,
        /// wgpu's message.
        message: String,
    },
}

/// Writes one line to the process's stderr directly, bypassing the test harness's output
/// capture (which only intercepts `eprintln!`), so that CI logs show which adapter the GPU
/// tests ran on, or that they were skipped.
pub fn log_uncaptured(line: &str) {
    use std::io::Write as _;
    let mut err = std::io::stderr().lock();
    let _ = writeln!(err, "{line}");
}

/// How GPU time was measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Timer {
    /// Host wall clock (CPU kernels, or GPU work timed around a blocking poll).
    WallClock,
    /// GPU timestamp queries at the beginning and end of each compute pass.
    GpuTimestamps,
}

impl std::fmt::Display for Timer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Timer::WallClock => "wall-clock",
            Timer::GpuTimestamps => "gpu-timestamps",
        })
    }
}

/// Which adapter [`GpuContext::select`] opens.
#[derive(Debug, Clone, PartialEq)]
pub struct AdapterSelection {
    /// Backends searched.
    pub backends: wgpu::Backends,
    /// The first adapter whose name contains this (case-insensitive); `None`: wgpu's choice.
    pub name: Option<String>,
    /// Preference when no name is given.
    pub power_preference: wgpu::PowerPreference,
}

impl AdapterSelection {
    /// From `WGPU_BACKEND`, `WGPU_ADAPTER_NAME` and `WGPU_POWER_PREF`.
    pub fn from_env() -> Self {
        Self {
            backends: wgpu::Backends::from_env().unwrap_or(wgpu::Backends::PRIMARY),
            name: std::env::var("WGPU_ADAPTER_NAME").ok(),
            power_preference: wgpu::PowerPreference::from_env().unwrap_or_default(),
        }
    }
}

/// Instance, adapter, device and queue of one GPU, plus what it reports about itself.
#[derive(Debug)]
pub struct GpuContext {
    /// The wgpu instance.
    pub instance: wgpu::Instance,
    /// The adapter the device was created on.
    pub adapter: wgpu::Adapter,
    /// The device kernels are built from.
    pub device: wgpu::Device,
    /// The queue work is submitted to.
    pub queue: wgpu::Queue,
    info: wgpu::AdapterInfo,
    timestamps: bool,
    lost: Arc<Mutex<Option<String>>>,
}

impl GpuContext {
    /// Opens the adapter selected by the environment (see the module docs) and creates a
    /// device with the adapter's full limits, and timestamp queries when it has them.
    pub fn from_env() -> Result<Self, GpuError> {
        Self::select(&AdapterSelection::from_env())
    }

    /// Opens the adapter described by `sel` (see [`AdapterSelection`]).
    pub fn select(sel: &AdapterSelection) -> Result<Self, GpuError> {
        let backends = sel.backends;
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
        desc.backends = backends;
        let instance = wgpu::Instance::new(desc);
        // One adapter enumeration per context: by name when one is given, else wgpu's own
        // choice. (Enumerating first and then asking wgpu enumerated twice; see the module
        // docs for why each enumeration can print to stderr.)
        let adapter = match sel.name.clone() {
            Some(wanted) if !wanted.is_empty() => {
                let adapters = pollster::block_on(instance.enumerate_adapters(backends));
                let found: Vec<String> = adapters.iter().map(|a| a.get_info().name).collect();
                adapters
                    .into_iter()
                    .find(|a| {
                        a.get_info()
                            .name
                            .to_lowercase()
                            .contains(&wanted.to_lowercase())
                    })
                    .ok_or(GpuError::NoMatchingAdapter { wanted, found })?
            }
            _ => pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
                power_preference: sel.power_preference,
                compatible_surface: None,
                force_fallback_adapter: false,
                ..Default::default()
            }))
            .map_err(|_| GpuError::NoAdapter {
                backends: format!("{backends:?}"),
            })?,
        };
        Self::from_adapter(instance, adapter)
    }

    /// Creates the device on a chosen adapter, with the adapter's full limits.
    pub fn from_adapter(
        instance: wgpu::Instance,
        adapter: wgpu::Adapter,
    ) -> Result<Self, GpuError> {
        let limits = adapter.limits();
        Self::with_limits(instance, adapter, limits)
    }

    /// A second device on this context's adapter whose storage-binding limit is at most
    /// `bytes` (every other limit the adapter's), so that the paths a smaller device takes
    /// (LPM's slice streaming once its T exceeds one binding) run, and are tested, on any
    /// adapter at a size that is cheap on lavapipe.
    pub fn with_binding_limit(&self, bytes: u64) -> Result<Self, GpuError> {
        let mut limits = self.adapter.limits();
        limits.max_storage_buffer_binding_size = limits.max_storage_buffer_binding_size.min(bytes);
        Self::with_limits(self.instance.clone(), self.adapter.clone(), limits)
    }

    fn with_limits(
        instance: wgpu::Instance,
        adapter: wgpu::Adapter,
        required_limits: wgpu::Limits,
    ) -> Result<Self, GpuError> {
        let info = adapter.get_info();
        let timestamps = adapter.features().contains(wgpu::Features::TIMESTAMP_QUERY);
        let required_features = if timestamps {
            wgpu::Features::TIMESTAMP_QUERY
        } else {
            wgpu::Features::empty()
        };
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("scatterbench"),
            required_features,
            required_limits,
            experimental_features: wgpu::ExperimentalFeatures::disabled(),
            memory_hints: wgpu::MemoryHints::Performance,
            trace: wgpu::Trace::Off,
        }))
        .map_err(|e| GpuError::RequestDevice {
            adapter: info.name.clone(),
            reason: e.to_string(),
        })?;
        let lost = Arc::new(Mutex::new(None));
        let sink = Arc::clone(&lost);
        device.set_device_lost_callback(move |reason, message| {
            if let Ok(mut slot) = sink.lock() {
                slot.get_or_insert(format!("{reason:?}: {message}"));
            }
        });
        // wgpu's default handler panics on any error outside an error scope; record it
        // instead, so that the next `check_lost` returns it as a typed error.
        let uncaptured = Arc::clone(&lost);
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            if let Ok(mut slot) = uncaptured.lock() {
                slot.get_or_insert(format!("uncaptured GPU error: {e}"));
            }
        }));
        Ok(Self {
            instance,
            adapter,
            device,
            queue,
            info,
            timestamps,
            lost,
        })
    }

    /// For tests: `Ok(None)` when there is no adapter (the caller prints its one "skipped: no
    /// GPU adapter" line), unless `SCATTERBENCH_REQUIRE_GPU` is set to a non-empty value other
    /// than `0`, in which case the error is returned.
    pub fn for_tests() -> Result<Option<Self>, GpuError> {
        let required = std::env::var("SCATTERBENCH_REQUIRE_GPU")
            .map(|v| !v.is_empty() && v != "0")
            .unwrap_or(false);
        match Self::from_env() {
            Ok(ctx) => Ok(Some(ctx)),
            Err(GpuError::NoAdapter { .. }) if !required => Ok(None),
            Err(e) => Err(e),
        }
    }

    /// What the adapter reports about itself.
    pub fn info(&self) -> &wgpu::AdapterInfo {
        &self.info
    }

    /// One line: adapter name, backend, device type, driver and driver info.
    pub fn describe(&self) -> String {
        let i = &self.info;
        format!(
            "{} ({:?}, {:?}, driver {} {})",
            i.name, i.backend, i.device_type, i.driver, i.driver_info
        )
    }

    /// Whether kernels time themselves with GPU timestamp queries.
    pub fn timer(&self) -> Timer {
        if self.timestamps {
            Timer::GpuTimestamps
        } else {
            Timer::WallClock
        }
    }

    /// The device's limits: the adapter's full limits, or those of
    /// [`GpuContext::with_binding_limit`].
    pub fn limits(&self) -> wgpu::Limits {
        self.device.limits()
    }

    /// Fails if a buffer of `bytes` bytes bound as storage would exceed the device's limits.
    pub fn check_storage_buffer(&self, what: &str, bytes: u64) -> Result<(), GpuError> {
        let l = self.limits();
        let checks = [
            (
                l.max_storage_buffer_binding_size,
                "max_storage_buffer_binding_size",
            ),
            (l.max_buffer_size, "max_buffer_size"),
        ];
        for (limit, limit_name) in checks {
            if bytes > limit {
                return Err(GpuError::TooLarge {
                    what: what.to_string(),
                    needed: bytes,
                    limit,
                    limit_name,
                    adapter: self.info.name.clone(),
                });
            }
        }
        Ok(())
    }

    /// `groups` as the u32 a dispatch takes, or a typed error naming `what` where it does not
    /// fit (the per-dimension limit is checked by [`GpuContext::check_workgroups`] and
    /// [`GpuContext::split_workgroups`]).
    pub fn workgroup_count(&self, what: &str, groups: u64) -> Result<u32, GpuError> {
        u32::try_from(groups).map_err(|_| GpuError::TooLarge {
            what: what.to_string(),
            needed: groups,
            limit: u64::from(u32::MAX),
            limit_name: "u32 workgroup count",
            adapter: self.info.name.clone(),
        })
    }

    /// Fails with a typed error if a dispatch of `groups` workgroups along one dimension exceeds
    /// the device's limit.
    pub fn check_workgroups(&self, what: &str, groups: u32) -> Result<(), GpuError> {
        let limit = self.limits().max_compute_workgroups_per_dimension;
        if groups > limit {
            return Err(GpuError::TooLarge {
                what: what.to_string(),
                needed: u64::from(groups),
                limit: u64::from(limit),
                limit_name: "max_compute_workgroups_per_dimension",
                adapter: self.info.name.clone(),
            });
        }
        Ok(())
    }

    /// Spreads `groups` workgroups over x and y of a dispatch: `[groups, 1]` when it fits the
    /// per-dimension limit, else `[limit, ⌈groups/limit⌉]` (the kernel folds y back into its
    /// index), failing with a typed error if even y exceeds the limit.
    pub fn split_workgroups(&self, what: &str, groups: u32) -> Result<[u32; 2], GpuError> {
        let max = self.limits().max_compute_workgroups_per_dimension;
        let split = if groups <= max {
            [groups, 1]
        } else {
            [max, groups.div_ceil(max)]
        };
        self.check_workgroups(what, split[1])?;
        Ok(split)
    }

    /// Runs `create` inside out-of-memory and validation error scopes, turning a captured
    /// error into [`GpuError::OutOfMemory`] (with `needed` bytes) or [`GpuError::Internal`].
    pub fn allocating<R>(
        &self,
        what: &str,
        needed: u64,
        create: impl FnOnce(&wgpu::Device) -> R,
    ) -> Result<R, GpuError> {
        let validation = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let oom = self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let r = create(&self.device);
        let oom_err = pollster::block_on(oom.pop());
        let val_err = pollster::block_on(validation.pop());
        if oom_err.is_some() {
            return Err(GpuError::OutOfMemory {
                what: what.to_string(),
                needed,
            });
        }
        if let Some(e) = val_err {
            return Err(GpuError::Internal {
                context: what.to_string(),
                message: e.to_string(),
            });
        }
        self.check_lost()?;
        Ok(r)
    }

    /// [`GpuError::DeviceLost`] if the device-lost callback fired or wgpu reported an error
    /// outside an error scope (after which the device's state cannot be trusted).
    pub fn check_lost(&self) -> Result<(), GpuError> {
        match self.lost.lock() {
            Ok(slot) => match slot.as_ref() {
                Some(reason) => Err(GpuError::DeviceLost(reason.clone())),
                None => Ok(()),
            },
            Err(_) => Err(GpuError::DeviceLost("device-lost state poisoned".into())),
        }
    }

    /// Blocks until all submitted work has finished.
    pub fn wait(&self) -> Result<(), GpuError> {
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| GpuError::DeviceLost(e.to_string()))?;
        self.check_lost()
    }

    /// Reads the first `bytes` bytes of `buffer` back (after all submitted work).
    pub fn read_buffer(&self, buffer: &wgpu::Buffer, bytes: u64) -> Result<Vec<u8>, GpuError> {
        let encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("readback"),
            });
        let mut out = self.submit_and_read(encoder, &[(buffer, bytes)])?;
        Ok(out.pop().unwrap_or_default())
    }

    /// Submits `encoder`, then copies `sources` (buffer, byte length) into one mappable
    /// staging buffer, waits and returns their bytes. The copies are recorded into `encoder`
    /// after whatever it already holds.
    pub fn submit_and_read(
        &self,
        mut encoder: wgpu::CommandEncoder,
        sources: &[(&wgpu::Buffer, u64)],
    ) -> Result<Vec<Vec<u8>>, GpuError> {
        let total: u64 = sources.iter().map(|(_, n)| n.next_multiple_of(8)).sum();
        let staging = self.allocating("readback staging buffer", total, |d| {
            d.create_buffer(&wgpu::BufferDescriptor {
                label: Some("readback"),
                size: total.max(8),
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        })?;
        let mut offset = 0;
        for (buf, n) in sources {
            encoder.copy_buffer_to_buffer(buf, 0, &staging, offset, *n);
            offset += n.next_multiple_of(8);
        }
        self.queue.submit([encoder.finish()]);
        let slice = staging.slice(..);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        self.wait()?;
        match rx.recv() {
            Ok(Ok(())) => {}
            Ok(Err(e)) => {
                return Err(GpuError::Internal {
                    context: "mapping the readback buffer".into(),
                    message: e.to_string(),
                });
            }
            Err(_) => return Err(GpuError::DeviceLost("readback never completed".into())),
        }
        let data = slice.get_mapped_range().map_err(|e| GpuError::Internal {
            context: "reading the readback buffer".into(),
            message: e.to_string(),
        })?;
        let mut out = Vec::with_capacity(sources.len());
        let mut offset = 0usize;
        for (_, n) in sources {
            let n = *n as usize;
            out.push(data[offset..offset + n].to_vec());
            offset += n.next_multiple_of(8);
        }
        drop(data);
        staging.unmap();
        Ok(out)
    }
}

/// Times compute passes: GPU timestamps when the device has them, else the wall clock
/// around submit-and-wait (which includes submission and synchronisation overhead).
/// `PassTimer::default()` is a wall-clock timer that holds no GPU resources.
#[derive(Debug, Default)]
pub struct PassTimer {
    queries: Option<(wgpu::QuerySet, wgpu::Buffer)>,
    period_ns: f64,
    seconds: f64,
    wall_start: Option<Instant>,
}

impl PassTimer {
    /// A timer for `ctx`.
    pub fn new(ctx: &GpuContext) -> Self {
        let queries = (ctx.timer() == Timer::GpuTimestamps).then(|| {
            let set = ctx.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("pass timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: 2,
            });
            let resolve = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timestamp resolve"),
                size: 16,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            (set, resolve)
        });
        Self {
            queries,
            period_ns: f64::from(ctx.queue.get_timestamp_period()),
            seconds: 0.0,
            wall_start: None,
        }
    }

    /// Which clock this timer uses.
    pub fn timer(&self) -> Timer {
        if self.queries.is_some() {
            Timer::GpuTimestamps
        } else {
            Timer::WallClock
        }
    }

    /// The timestamp writes to put on the timed compute pass (None for the wall clock).
    pub fn writes(&self) -> Option<wgpu::ComputePassTimestampWrites<'_>> {
        self.queries
            .as_ref()
            .map(|(set, _)| wgpu::ComputePassTimestampWrites {
                query_set: set,
                beginning_of_pass_write_index: Some(0),
                end_of_pass_write_index: Some(1),
            })
    }

    /// Call after the timed pass is recorded and before submission: resolves the queries
    /// into `encoder`, and starts the wall clock.
    pub fn resolve(&mut self, encoder: &mut wgpu::CommandEncoder) {
        if let Some((set, buf)) = &self.queries {
            encoder.resolve_query_set(set, 0..2, buf, 0);
        }
        self.wall_start = Some(Instant::now());
    }

    /// The buffer to read back with the pass results (16 bytes), if timestamps are used.
    pub fn readback(&self) -> Option<&wgpu::Buffer> {
        self.queries.as_ref().map(|(_, b)| b)
    }

    /// Adds the elapsed time of the pass: from the read-back timestamps (the bytes of
    /// [`PassTimer::readback`]) or from the wall clock started in [`PassTimer::resolve`].
    pub fn record(&mut self, timestamps: Option<&[u8]>) {
        match timestamps {
            Some(b) if b.len() >= 16 => {
                let t0 = u64::from_le_bytes(b[0..8].try_into().unwrap_or([0; 8]));
                let t1 = u64::from_le_bytes(b[8..16].try_into().unwrap_or([0; 8]));
                self.seconds += t1.saturating_sub(t0) as f64 * self.period_ns * 1e-9;
            }
            _ => {
                if let Some(t) = self.wall_start.take() {
                    self.seconds += t.elapsed().as_secs_f64();
                }
            }
        }
    }

    /// Total seconds recorded.
    pub fn seconds(&self) -> f64 {
        self.seconds
    }
}

/// Creates a storage buffer initialised with `data` (at least 4 bytes, for empty data).
pub(crate) fn storage_buffer(device: &wgpu::Device, label: &str, data: &[u8]) -> wgpu::Buffer {
    use wgpu::util::DeviceExt;
    let contents: &[u8] = if data.is_empty() { &[0; 4] } else { data };
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents,
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_SRC
            | wgpu::BufferUsages::COPY_DST,
    })
}

/// Creates a uniform buffer holding `value`.
pub(crate) fn uniform_buffer<T: bytemuck::Pod>(
    device: &wgpu::Device,
    label: &str,
    value: &T,
) -> wgpu::Buffer {
    use wgpu::util::DeviceExt;
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: bytemuck::bytes_of(value),
        usage: wgpu::BufferUsages::UNIFORM,
    })
}
