//! Shared by the backend-conformance test files: run one test body per backend (CPU-f32,
//! CPU-f64, GPU) with one GPU context per test binary.
//!
//! GPU tests share one device and run one at a time. Without an adapter each prints
//! "<test>: skipped: no GPU adapter" and passes, unless `SCATTERBENCH_REQUIRE_GPU=1` (CI),
//! which makes them fail.

#[macro_use]
pub mod methods;

use solvers::gpu::GpuContext;
use solvers::{Backend, Precision};
use std::sync::{Mutex, OnceLock};

static GPU: OnceLock<Option<Mutex<GpuContext>>> = OnceLock::new();

/// Runs `body` on the named backend; the GPU one is skipped (with one line) when no adapter
/// exists and the environment does not require one.
pub fn on_backend(kind: &str, test: &str, body: impl FnOnce(&Backend<'_>)) {
    match kind {
        "cpu-f32" => body(&Backend::Cpu(Precision::F32)),
        "cpu-f64" => body(&Backend::Cpu(Precision::F64)),
        _ => {
            let gpu = GPU.get_or_init(|| {
                GpuContext::for_tests()
                    .unwrap_or_else(|e| panic!("SCATTERBENCH_REQUIRE_GPU is set: {e}"))
                    .map(Mutex::new)
            });
            match gpu {
                None => solvers::gpu::log_uncaptured(&format!("{test}: skipped: no GPU adapter")),
                Some(m) => {
                    let ctx = m.lock().unwrap_or_else(|e| e.into_inner());
                    solvers::gpu::log_uncaptured(&format!("{test}: ran on {}", ctx.describe()));
                    body(&Backend::Gpu(&ctx));
                }
            }
        }
    }
}

/// One test per backend for each case function `fn(&Backend)`.
#[macro_export]
macro_rules! conformance {
    ($($case:ident),* $(,)?) => {$(
        mod $case {
            #[test]
            fn cpu_f32() {
                $crate::common::on_backend("cpu-f32", concat!(stringify!($case), "::cpu_f32"), super::$case);
            }
            #[test]
            fn cpu_f64() {
                $crate::common::on_backend("cpu-f64", concat!(stringify!($case), "::cpu_f64"), super::$case);
            }
            #[test]
            fn gpu() {
                $crate::common::on_backend("gpu", concat!(stringify!($case), "::gpu"), super::$case);
            }
        }
    )*};
}
