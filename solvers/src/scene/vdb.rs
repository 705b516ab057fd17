//! OpenVDB input for scene files (`[medium] vdb = "file.vdb"`, `grid = "density"`), for
//! users' own data.
//!
//! Reading uses the `vdb-rs` crate (cargo feature `vdb`, on by default). Only `float`
//! grids in full precision are read; the active voxels and tiles are scattered into a
//! dense array over their bounding box (index space; the grid's world transform is not
//! used: the scene file's `min`/`max` place the box, default the unit cube's scaling
//! `Δl = 1/longest axis`), inactive voxels are 0. Dense grids beyond [`MAX_VOXELS`] are
//! refused rather than allocated.
//!
//! Caveat: `vdb-rs` is a young reader; a malformed file may make it fail in ways this
//! module cannot turn into an error (we map every error it returns).

use std::path::{Path, PathBuf};
use thiserror::Error;

/// The largest dense grid read from a VDB file (512³).
pub const MAX_VOXELS: usize = 512 * 512 * 512;

/// Errors reading an OpenVDB file.
#[derive(Debug, Error)]
pub enum VdbError {
    /// This build has no OpenVDB reader.
    #[error(
        "cannot read `{0}`: this build has no OpenVDB reader (rebuild with the `vdb` feature of solvers)"
    )]
    NotBuilt(PathBuf),
    /// The file cannot be opened (the I/O error is the source).
    #[error("cannot read `{}`", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The file is not a VDB file the reader understands.
    #[error("`{path}` is not a readable OpenVDB file: {reason}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// The reader's message.
        reason: String,
    },
    /// No grid of that name.
    #[error("`{path}` has no grid `{grid}`; it has: {available}")]
    NoSuchGrid {
        /// The file.
        path: PathBuf,
        /// The requested grid.
        grid: String,
        /// The grids in the file.
        available: String,
    },
    /// The grid is not a full-precision float grid, is empty or too large.
    #[error("grid `{grid}` of `{path}`: {reason}")]
    Unsupported {
        /// The file.
        path: PathBuf,
        /// The grid.
        grid: String,
        /// Why.
        reason: String,
    },
}

/// Reads the float grid `grid` of the OpenVDB file at `path` into a dense array over the
/// bounding box of its active values: dimensions `[nx, ny, nz]` and values (x fastest).
#[cfg(feature = "vdb")]
pub fn read_float_grid(path: &Path, grid: &str) -> Result<([usize; 3], Vec<f64>), VdbError> {
    use vdb_rs::{VdbLevel, VdbReader};
    let (file, _) = crate::budget::open_regular(path, u64::MAX).map_err(|source| VdbError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let parse = |e: vdb_rs::ParseError| VdbError::Parse {
        path: path.to_path_buf(),
        reason: e.to_string(),
    };
    let mut reader = VdbReader::new(std::io::BufReader::new(file)).map_err(parse)?;
    let mut names = reader.available_grids();
    names.sort();
    if !names.iter().any(|n| n == grid) {
        return Err(VdbError::NoSuchGrid {
            path: path.to_path_buf(),
            grid: grid.to_string(),
            available: names.join(", "),
        });
    }
    let unsupported = |reason: String| VdbError::Unsupported {
        path: path.to_path_buf(),
        grid: grid.to_string(),
        reason,
    };
    let g = reader.read_grid::<f32>(grid).map_err(parse)?;
    let ty = &g.descriptor.grid_type;
    if !ty.contains("float") || g.descriptor.meta_data.is_half_float() {
        return Err(unsupported(format!(
            "type `{ty}`{} is not a full-precision float grid",
            if g.descriptor.meta_data.is_half_float() {
                " (half)"
            } else {
                ""
            }
        )));
    }
    // Active values: (lower corner in index space, value, edge in voxels).
    let cells: Vec<([i64; 3], f32, i64)> = g
        .iter()
        .map(|(c, v, level)| {
            let edge = match level {
                VdbLevel::Voxel => 1,
                other => other.scale() as i64,
            };
            (
                [c.x.round() as i64, c.y.round() as i64, c.z.round() as i64],
                v,
                edge,
            )
        })
        .collect();
    if cells.is_empty() {
        return Err(unsupported("has no active values".into()));
    }
    let mut lo = [i64::MAX; 3];
    let mut hi = [i64::MIN; 3];
    for (c, _, e) in &cells {
        for a in 0..3 {
            lo[a] = lo[a].min(c[a]);
            hi[a] = hi[a].max(c[a] + e);
        }
    }
    let dims = [0, 1, 2].map(|a| (hi[a] - lo[a]).max(1) as usize);
    let total = dims[0]
        .checked_mul(dims[1])
        .and_then(|v| v.checked_mul(dims[2]))
        .filter(|&v| v <= MAX_VOXELS)
        .ok_or_else(|| unsupported(format!("dense box {dims:?} exceeds {MAX_VOXELS} voxels")))?;
    crate::budget::check(
        format!("the dense box {dims:?} of grid `{grid}`"),
        crate::budget::bytes(&dims, crate::budget::MEDIUM_BYTES_PER_VOXEL),
    )
    .map_err(|e| unsupported(e.to_string()))?;
    let mut out = vec![0.0; total];
    for (c, v, e) in cells {
        for dz in 0..e {
            for dy in 0..e {
                for dx in 0..e {
                    let i = (c[0] + dx - lo[0]) as usize;
                    let j = (c[1] + dy - lo[1]) as usize;
                    let k = (c[2] + dz - lo[2]) as usize;
                    out[i + dims[0] * (j + dims[1] * k)] = f64::from(v);
                }
            }
        }
    }
    Ok((dims, out))
}

/// Without the `vdb` feature: always [`VdbError::NotBuilt`].
#[cfg(not(feature = "vdb"))]
pub fn read_float_grid(path: &Path, grid: &str) -> Result<([usize; 3], Vec<f64>), VdbError> {
    let _ = grid;
    Err(VdbError::NotBuilt(path.to_path_buf()))
}

#[cfg(all(test, feature = "vdb"))]
mod tests {
    use super::*;

    #[test]
    fn unreadable_files_are_typed_errors() {
        let dir = std::env::temp_dir().join(format!("scatterbench-vdb-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let missing = read_float_grid(&dir.join("missing.vdb"), "density").unwrap_err();
        assert!(matches!(missing, VdbError::Io { .. }), "{missing}");
        std::fs::write(dir.join("junk.vdb"), b"this is not an OpenVDB file at all").unwrap();
        let junk = read_float_grid(&dir.join("junk.vdb"), "density").unwrap_err();
        assert!(matches!(junk, VdbError::Parse { .. }), "{junk}");
        assert!(junk.to_string().contains("junk.vdb"));
        std::fs::remove_dir_all(&dir).ok();
    }
}
