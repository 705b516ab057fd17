//! OpenVDB input for scene files (`[medium] vdb = "file.vdb"`, `grid = "density"`).
//!
//! Reading needs the `vdb` cargo feature (the `vdb-rs` crate); without it every read is a
//! [`VdbError::NotBuilt`].

use std::path::{Path, PathBuf};
use thiserror::Error;

/// Errors reading an OpenVDB file.
#[derive(Debug, Error)]
pub enum VdbError {
    /// This build has no OpenVDB reader.
    #[error(
        "cannot read `{0}`: this build has no OpenVDB reader (rebuild with `--features solvers/vdb`)"
    )]
    NotBuilt(PathBuf),
}

/// Reads the float grid `grid` of the OpenVDB file at `path` into a dense array over its
/// active bounding box: dimensions `[nx, ny, nz]` and values x fastest.
pub fn read_float_grid(path: &Path, grid: &str) -> Result<([usize; 3], Vec<f64>), VdbError> {
    let _ = grid;
    Err(VdbError::NotBuilt(path.to_path_buf()))
}
