//! Where a solver runs, as a value: the CPU kernels in `f32` or `f64`, or the GPU (wgpu, `f32`)
//! on a caller-owned [`GpuContext`].

use crate::gpu::GpuContext;
use crate::{Real, SolverError};
use std::fmt;

/// Floating-point precision of a CPU kernel.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Precision {
    /// `f32`, the GPU precision.
    F32,
    /// `f64`.
    F64,
}

impl Precision {
    /// Bytes per value: 4 or 8.
    pub fn bytes(&self) -> usize {
        match self {
            Precision::F32 => 4,
            Precision::F64 => 8,
        }
    }

    /// `"f32"` or `"f64"`.
    pub fn name(&self) -> &'static str {
        match self {
            Precision::F32 => f32::NAME,
            Precision::F64 => f64::NAME,
        }
    }
}

impl std::str::FromStr for Precision {
    type Err = SolverError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "f32" => Ok(Precision::F32),
            "f64" => Ok(Precision::F64),
            other => Err(SolverError::UnknownName {
                what: "precision",
                got: other.to_string(),
                known: "f32, f64".into(),
            }),
        }
    }
}

/// A compute backend. GPU kernels are `f32` only.
#[derive(Debug, Clone, Copy)]
pub enum Backend<'a> {
    /// The rayon kernels in the given precision.
    Cpu(Precision),
    /// The wgpu kernels on this device.
    Gpu(&'a GpuContext),
}

impl Backend<'_> {
    /// `cpu` or `gpu`.
    pub fn kind(&self) -> &'static str {
        match self {
            Backend::Cpu(_) => "cpu",
            Backend::Gpu(_) => "gpu",
        }
    }

    /// The precision the backend computes in.
    pub fn precision(&self) -> Precision {
        match self {
            Backend::Cpu(p) => *p,
            Backend::Gpu(_) => Precision::F32,
        }
    }

    /// The adapter (GPU) or `None` (CPU).
    pub fn gpu(&self) -> Option<&GpuContext> {
        match self {
            Backend::Cpu(_) => None,
            Backend::Gpu(ctx) => Some(ctx),
        }
    }
}

impl fmt::Display for Backend<'_> {
    /// `cpu-f32`, `cpu-f64` or `gpu-f32`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}-{}", self.kind(), self.precision().name())
    }
}
