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
