//! Typed errors for everything a user can get wrong when setting up a solve.

use thiserror::Error;

/// Errors returned by the solvers. Every variant says which input is wrong and why.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum SolverError {
    /// A grid needs at least 3 voxels per axis: one interior voxel between two boundary layers.
    #[error(
        "grid dimension {axis} = {n} is too small: at least 3 voxels are needed (one interior voxel between the two Dirichlet boundary layers)"
    )]
    GridTooSmall {
        /// Axis name, `x`, `y` or `z`.
        axis: char,
        /// The offending size.
        n: usize,
    },
    /// The voxel size must be finite and positive.
    #[error("voxel size must be finite and > 0, got {0}")]
    BadVoxelSize(f64),
    /// The grid has more voxels than fit in memory addressing.
    #[error("grid {nx}x{ny}x{nz} has too many voxels")]
    GridTooLarge {
        /// Voxels along x.
        nx: usize,
        /// Voxels along y.
        ny: usize,
        /// Voxels along z.
        nz: usize,
    },
    /// A field has the wrong number of values for its grid.
    #[error("field `{field}` has {got} values but the grid has {expected} voxels")]
    FieldSize {
        /// Field name.
        field: &'static str,
        /// Expected number of values (voxels).
        expected: usize,
        /// Actual number of values.
        got: usize,
    },
    /// A field value is outside its physical range (negative extinction, albedo above 1, NaN …).
    #[error("field `{field}` at voxel {index} is {value}, which is outside {range}")]
    FieldValue {
        /// Field name.
        field: &'static str,
        /// Linear voxel index (x fastest).
        index: usize,
        /// The offending value.
        value: f64,
        /// The allowed range, in words.
        range: &'static str,
    },
    /// A solver parameter is out of range.
    #[error("parameter `{name}` = {value} is invalid: {reason}")]
    BadParameter {
        /// Parameter name.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What is allowed.
        reason: &'static str,
    },
    /// An explicit time step above the stability bound it is checked against (the RDE's
    /// fixed r above the Gershgorin bound, or above thesis Eq 4.9 in the strict mode).
    #[error("parameter `{name}` = {value} exceeds {criterion} = {bound}")]
    StepAboveBound {
        /// Parameter name.
        name: &'static str,
        /// Its value.
        value: f64,
        /// The bound it exceeds.
        bound: f64,
        /// Which bound, in words.
        criterion: &'static str,
    },
    /// The flux limiter name could not be parsed.
    #[error(
        "unknown flux limiter `{0}`; expected one of cda, sum, max, kershaw, larsen<n> (e.g. larsen2), lp"
    )]
    UnknownLimiter(String),
    /// A name (method, method parameter, precision …) that is not one of those that exist.
    #[error("unknown {what} `{got}`; known: {known}")]
    UnknownName {
        /// What kind of name.
        what: &'static str,
        /// The name given.
        got: String,
        /// The names that exist.
        known: String,
    },
    /// A GPU backend failure (no adapter, grid too large for the device, device lost …).
    #[error(transparent)]
    Gpu(#[from] crate::gpu::GpuError),
    /// The requested combination of backend and precision does not exist.
    #[error("{0}")]
    Unsupported(String),
}
