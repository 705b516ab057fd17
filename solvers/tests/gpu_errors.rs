//! GPU failure modes are typed errors with actionable messages, never panics.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use solvers::fld::{Boundary, FldConfig, FluxLimiter, GpuFld};
use solvers::gpu::{AdapterSelection, GpuContext, GpuError};
use solvers::{SolverError, scenes};

fn gpu(test: &str) -> Option<GpuContext> {
    let ctx =
        GpuContext::for_tests().unwrap_or_else(|e| panic!("SCATTERBENCH_REQUIRE_GPU is set: {e}"));
    if let Some(c) = &ctx {
        solvers::gpu::log_uncaptured(&format!("{test}: ran on {}", c.describe()));
    }
    if ctx.is_none() {
        solvers::gpu::log_uncaptured(&format!("{test}: skipped: no GPU adapter"));
    }
    ctx
}

#[test]
fn an_adapter_name_that_matches_nothing_lists_the_adapters() {
    let sel = AdapterSelection {
        name: Some("no-such-adapter-xyz".into()),
        ..AdapterSelection::from_env()
    };
    match GpuContext::select(&sel) {
        Err(e @ GpuError::NoMatchingAdapter { .. }) => {
            let msg = e.to_string();
            assert!(msg.contains("no-such-adapter-xyz"), "{msg}");
        }
        Err(GpuError::NoAdapter { .. }) => {}
        other => panic!("expected NoMatchingAdapter, got {other:?}"),
    }
}

#[test]
fn a_buffer_beyond_the_device_limits_says_how_much_is_needed() {
    let Some(ctx) = gpu("a_buffer_beyond_the_device_limits_says_how_much_is_needed") else {
        return;
    };
    let limit = ctx.limits().max_storage_buffer_binding_size;
    let err = ctx
        .check_storage_buffer("the phi field", limit + 1)
        .unwrap_err();
    let msg = err.to_string();
    assert!(
        msg.contains(&(limit + 1).to_string()) && msg.contains("max_storage_buffer_binding_size"),
        "{msg}"
    );
    assert!(ctx.check_storage_buffer("the phi field", limit).is_ok());
}

#[test]
fn a_destroyed_device_is_reported_as_lost() {
    let Some(ctx) = gpu("a_destroyed_device_is_reported_as_lost") else {
        return;
    };
    let medium = scenes::vacuum_cloud::<f32>(9, 1).unwrap();
    let solver = GpuFld::new(
        &ctx,
        &medium,
        &Boundary::Zero,
        &FldConfig::fld(FluxLimiter::Sum),
    )
    .unwrap();
    ctx.device.destroy();
    match solver.solve() {
        Err(SolverError::Gpu(GpuError::DeviceLost(reason))) => eprintln!("device lost: {reason}"),
        other => panic!("expected DeviceLost, got {other:?}"),
    }
}

#[test]
fn a_kernel_bound_against_its_spec_gives_a_typed_error_naming_the_binding() {
    use solvers::gpu::kernel::{Contract, Kernel, specs};
    let Some(ctx) = gpu("a_kernel_bound_against_its_spec_gives_a_typed_error_naming_the_binding")
    else {
        return;
    };
    let spec = specs()
        .into_iter()
        .find(|s| s.label == "copy.wgsl")
        .unwrap();
    let problem = |r: Result<_, GpuError>| match r {
        Err(GpuError::Contract { problem, name, .. }) => (problem, name),
        other => panic!("expected a contract error, got {other:?}"),
    };
    assert_eq!(
        problem(Kernel::new(&ctx, spec, &[("NO_SUCH", 1.0)]).map(|_| ())),
        (Contract::UnknownConstant, "NO_SUCH".to_string())
    );
    let kernel = Kernel::new(&ctx, spec, &[]).unwrap();
    assert_eq!(
        problem(kernel.pipeline("nope").map(|_| ())),
        (Contract::UnknownEntry, "nope".to_string())
    );
    let buffer = |usage| {
        ctx.device
            .create_buffer(&solvers::gpu::wgpu::BufferDescriptor {
                label: None,
                size: 64,
                usage,
                mapped_at_creation: false,
            })
    };
    let uniform = buffer(solvers::gpu::wgpu::BufferUsages::UNIFORM);
    let storage = buffer(solvers::gpu::wgpu::BufferUsages::STORAGE);
    let missing = kernel.bind(&ctx, &[("P", &uniform), ("src", &storage)]);
    assert_eq!(
        problem(missing.map(|_| ())),
        (Contract::MissingBinding, "dst".to_string())
    );
    let unknown = kernel.bind(
        &ctx,
        &[("P", &uniform), ("src", &storage), ("out", &storage)],
    );
    let err = unknown.as_ref().map(|_| ()).unwrap_err().to_string();
    assert!(
        err.contains("\"out\"") && err.contains("copy.wgsl"),
        "{err}"
    );
    assert_eq!(
        problem(unknown.map(|_| ())),
        (Contract::UnknownBinding, "out".to_string())
    );
    let twice = kernel.bind(
        &ctx,
        &[("P", &uniform), ("src", &storage), ("src", &storage)],
    );
    assert_eq!(
        problem(twice.map(|_| ())),
        (Contract::DuplicateBinding, "src".to_string())
    );
    let ok = kernel.bind(
        &ctx,
        &[("dst", &storage), ("P", &uniform), ("src", &storage)],
    );
    assert!(ok.is_ok(), "{ok:?}");
    ctx.check_lost().unwrap();
}
