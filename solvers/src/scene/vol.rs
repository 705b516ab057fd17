//! Mitsuba 3's binary voxel-grid format (`.vol`, the `gridvolume` plugin's files).
//!
//! Layout (little-endian), as Mitsuba 3's `VolumeGrid` reads and writes it:
//!
//! | bytes | content |
//! |---|---|
//! | 0–2 | ASCII `VOL` |
//! | 3 | version, 3 |
//! | 4–7 | encoding (i32), 1 = float32 (the only one Mitsuba supports) |
//! | 8–19 | cells along x, y, z (3 × i32) |
//! | 20–23 | channels (i32) |
//! | 24–47 | bounding box xmin ymin zmin xmax ymax zmax (6 × f32) |
//! | 48– | data, f32, index `((z·ny + y)·nx + x)·channels + c` (x fastest, channel innermost) |
//!
//! The bounding box spans the outer faces of the cells (Mitsuba maps it to its texture's unit
//! cube, whose cell `i` covers `[i, i+1)/n`), so cell `(i, j, k)` is our voxel `(i, j, k)`
//! of a [`Grid`] with `origin = min` and `dl = (max − min)/n`; the cell order is ours too.
//!
//! Reading never panics: truncated, oversized or inconsistent input is a [`VolError`].

use crate::Grid;
use std::path::{Path, PathBuf};
use thiserror::Error;

/// Header length in bytes.
pub const HEADER_BYTES: usize = 48;

/// Errors reading or writing `.vol` files.
#[derive(Debug, Error)]
pub enum VolError {
    /// The file could not be read or written (the I/O error is the source).
    #[error("{}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The grid does not fit the memory budget.
    #[error(transparent)]
    TooLarge(#[from] crate::budget::TooLarge),
    /// Fewer bytes than the 48-byte header.
    #[error("truncated header: {got} bytes, a .vol header has {HEADER_BYTES}")]
    TruncatedHeader {
        /// Bytes present.
        got: usize,
    },
    /// The first three bytes are not `VOL`.
    #[error("not a .vol file: the first bytes are {0:?}, expected \"VOL\"")]
    BadMagic([u8; 3]),
    /// A version other than 3.
    #[error("unsupported .vol version {0} (only version 3 exists)")]
    UnsupportedVersion(u8),
    /// An encoding other than 1 (float32).
    #[error("unsupported .vol encoding {0} (only 1 = float32 is supported)")]
    UnsupportedEncoding(i32),
    /// A non-positive or too large cell count.
    #[error(
        "invalid .vol dimensions {0:?}: each must be at least 1 and the total must fit in memory"
    )]
    BadDimensions([i64; 3]),
    /// A channel count other than 1, 3 or 6 (the counts Mitsuba accepts).
    #[error("invalid .vol channel count {0} (Mitsuba accepts 1, 3 or 6)")]
    BadChannels(i64),
    /// The bounding box has a non-finite coordinate or max ≤ min on an axis.
    #[error(
        "invalid .vol bounding box min {min:?} max {max:?}: needs finite values with max > min"
    )]
    BadBoundingBox {
        /// Lower corner.
        min: [f32; 3],
        /// Upper corner.
        max: [f32; 3],
    },
    /// The data section is shorter or longer than the header says.
    #[error("data section has {got} bytes, the header (dims × channels × 4) needs {expected}")]
    DataLength {
        /// Bytes the header implies.
        expected: usize,
        /// Bytes present.
        got: usize,
    },
    /// `data.len()` does not match the dimensions (when building a grid in memory).
    #[error("{got} values given for a grid that needs {expected}")]
    ValueCount {
        /// Values needed.
        expected: usize,
        /// Values given.
        got: usize,
    },
    /// The voxels are not cubes, so the grid cannot become a [`Grid`].
    #[error(
        "voxels are not cubic: edge lengths {edges:?} along x, y, z (bounding box extent / cells must agree within 1e-4)"
    )]
    NonCubicVoxels {
        /// Voxel edge per axis.
        edges: [f64; 3],
    },
    /// The grid is not a valid solver grid (e.g. fewer than 3 cells on an axis); the solver
    /// error is the source.
    #[error("not a valid solver grid")]
    Grid(#[from] crate::SolverError),
}

/// A voxel grid as stored in a `.vol` file: dimensions, channels, box and `f32` data.
#[derive(Debug, Clone, PartialEq)]
pub struct VolGrid {
    /// Cells along x, y, z.
    pub dims: [usize; 3],
    /// Values per cell (1, 3 or 6).
    pub channels: usize,
    /// Lower corner of the box.
    pub min: [f32; 3],
    /// Upper corner of the box.
    pub max: [f32; 3],
    /// Values, x fastest and channel innermost: `((z·ny + y)·nx + x)·channels + c`.
    pub data: Vec<f32>,
}

impl VolGrid {
    /// A grid from parts, checking dimensions, channel count, box and data length.
    pub fn new(
        dims: [usize; 3],
        channels: usize,
        min: [f32; 3],
        max: [f32; 3],
        data: Vec<f32>,
    ) -> Result<Self, VolError> {
        let cells = cell_count(dims.map(|d| d as i64))?;
        check_channels(channels as i64)?;
        check_bbox(min, max)?;
        let expected = cells * channels;
        if data.len() != expected {
            return Err(VolError::ValueCount {
                expected,
                got: data.len(),
            });
        }
        Ok(Self {
            dims,
            channels,
            min,
            max,
            data,
        })
    }

    /// A one-channel grid holding `values` (one per voxel, our index order) on `grid`'s box.
    pub fn from_field(grid: &Grid, values: &[f64]) -> Result<Self, VolError> {
        let size = grid.size();
        let min = grid.origin.map(|v| v as f32);
        let max = [0, 1, 2].map(|a| (grid.origin[a] + size[a]) as f32);
        Self::new(
            grid.n,
            1,
            min,
            max,
            values.iter().map(|&v| v as f32).collect(),
        )
    }

    /// Parses the bytes of a `.vol` file.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, VolError> {
        let header = bytes
            .get(..HEADER_BYTES)
            .ok_or(VolError::TruncatedHeader { got: bytes.len() })?;
        let magic = [header[0], header[1], header[2]];
        if &magic != b"VOL" {
            return Err(VolError::BadMagic(magic));
        }
        if header[3] != 3 {
            return Err(VolError::UnsupportedVersion(header[3]));
        }
        let i32_at =
            |o: usize| i32::from_le_bytes([header[o], header[o + 1], header[o + 2], header[o + 3]]);
        let f32_at =
            |o: usize| f32::from_le_bytes([header[o], header[o + 1], header[o + 2], header[o + 3]]);
        let encoding = i32_at(4);
        if encoding != 1 {
            return Err(VolError::UnsupportedEncoding(encoding));
        }
        let dims_i = [i32_at(8), i32_at(12), i32_at(16)].map(i64::from);
        let cells = cell_count(dims_i)?;
        let channels = i64::from(i32_at(20));
        check_channels(channels)?;
        let channels = channels as usize;
        let min = [f32_at(24), f32_at(28), f32_at(32)];
        let max = [f32_at(36), f32_at(40), f32_at(44)];
        check_bbox(min, max)?;
        let body = &bytes[HEADER_BYTES..];
        let expected = cells
            .checked_mul(channels)
            .and_then(|v| v.checked_mul(4))
            .ok_or(VolError::BadDimensions(dims_i))?;
        if body.len() != expected {
            return Err(VolError::DataLength {
                expected,
                got: body.len(),
            });
        }
        let data = body
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        Ok(Self {
            dims: dims_i.map(|d| d as usize),
            channels,
            min,
            max,
            data,
        })
    }

    /// The bytes of the `.vol` file.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(HEADER_BYTES + 4 * self.data.len());
        out.extend_from_slice(b"VOL");
        out.push(3);
        out.extend_from_slice(&1i32.to_le_bytes());
        for d in self.dims {
            out.extend_from_slice(&(d as i32).to_le_bytes());
        }
        out.extend_from_slice(&(self.channels as i32).to_le_bytes());
        for v in self.min.iter().chain(&self.max) {
            out.extend_from_slice(&v.to_le_bytes());
        }
        for v in &self.data {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out
    }

    /// Reads a `.vol` file: only a regular file, whose length the header's dimensions
    /// account for, and whose grid fits the memory budget (checked before reading the data).
    pub fn read(path: &Path) -> Result<Self, VolError> {
        use std::io::Read as _;
        let io = |source| VolError::Io {
            path: path.to_path_buf(),
            source,
        };
        let (mut file, len) = crate::budget::open_regular(path, u64::MAX).map_err(io)?;
        let mut header = vec![0u8; HEADER_BYTES.min(len as usize)];
        file.read_exact(&mut header).map_err(io)?;
        // Validates the header alone (the data-length error tells the expected size).
        let expected = match Self::from_bytes(&header) {
            Err(VolError::DataLength { expected, .. }) => expected,
            Err(e) => return Err(e),
            Ok(v) => return Ok(v),
        };
        let body = len - HEADER_BYTES as u64;
        if body != expected as u64 {
            return Err(VolError::DataLength {
                expected,
                got: usize::try_from(body).unwrap_or(usize::MAX),
            });
        }
        // The file's bytes, their f32 values and the f64 medium built from them.
        crate::budget::check(
            format!("the .vol grid `{}`", path.display()),
            len.saturating_mul(4),
        )?;
        let mut bytes = header;
        bytes.reserve_exact(expected);
        file.take(body).read_to_end(&mut bytes).map_err(io)?;
        Self::from_bytes(&bytes)
    }

    /// Writes a `.vol` file.
    pub fn write(&self, path: &Path) -> Result<(), VolError> {
        std::fs::write(path, self.to_bytes()).map_err(|source| VolError::Io {
            path: path.to_path_buf(),
            source,
        })
    }

    /// Number of cells.
    pub fn cells(&self) -> usize {
        self.dims[0] * self.dims[1] * self.dims[2]
    }

    /// Channel `c` of every cell as `f64`, in our index order (`None` if `c` is out of range).
    pub fn channel(&self, c: usize) -> Option<Vec<f64>> {
        (c < self.channels).then(|| {
            self.data
                .iter()
                .skip(c)
                .step_by(self.channels)
                .map(|&v| f64::from(v))
                .collect()
        })
    }

    /// The solver [`Grid`] of this box: origin `min`, edge `(max − min)/n`. Voxels must be
    /// cubic: the three edge lengths must agree to a relative 10⁻⁴ (the box is stored in
    /// `f32`); the x edge is used.
    pub fn grid(&self) -> Result<Grid, VolError> {
        let edges = [0, 1, 2]
            .map(|a| (f64::from(self.max[a]) - f64::from(self.min[a])) / self.dims[a] as f64);
        let dl = edges[0];
        if edges.iter().any(|e| (e - dl).abs() > 1e-4 * dl) {
            return Err(VolError::NonCubicVoxels { edges });
        }
        Ok(Grid::with_origin(self.dims, dl, self.min.map(f64::from))?)
    }
}

fn cell_count(dims: [i64; 3]) -> Result<usize, VolError> {
    if dims.iter().any(|&d| d < 1 || d > i64::from(i32::MAX)) {
        return Err(VolError::BadDimensions(dims));
    }
    (dims[0] as usize)
        .checked_mul(dims[1] as usize)
        .and_then(|v| v.checked_mul(dims[2] as usize))
        .filter(|&v| v <= (isize::MAX as usize) / 64)
        .ok_or(VolError::BadDimensions(dims))
}

fn check_channels(c: i64) -> Result<(), VolError> {
    if matches!(c, 1 | 3 | 6) {
        Ok(())
    } else {
        Err(VolError::BadChannels(c))
    }
}

fn check_bbox(min: [f32; 3], max: [f32; 3]) -> Result<(), VolError> {
    let ok = (0..3).all(|a| min[a].is_finite() && max[a].is_finite() && max[a] > min[a]);
    if ok {
        Ok(())
    } else {
        Err(VolError::BadBoundingBox { min, max })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> VolGrid {
        let dims = [4, 3, 5];
        let data = (0..60 * 3).map(|i| i as f32 * 0.25 - 3.0).collect();
        VolGrid::new(dims, 3, [-1.0, 0.0, 2.0], [1.0, 1.5, 5.0], data).unwrap()
    }

    #[test]
    fn round_trip_through_bytes_and_file_is_exact() {
        let v = sample();
        let bytes = v.to_bytes();
        assert_eq!(bytes.len(), HEADER_BYTES + 4 * 180);
        assert_eq!(&bytes[..4], b"VOL\x03");
        assert_eq!(VolGrid::from_bytes(&bytes).unwrap(), v);
        let path =
            std::env::temp_dir().join(format!("scatterbench-vol-{}.vol", std::process::id()));
        v.write(&path).unwrap();
        let back = VolGrid::read(&path).unwrap();
        std::fs::remove_file(&path).ok();
        assert_eq!(back, v);
    }

    #[test]
    fn layout_is_x_fastest_channel_innermost() {
        // Mitsuba's index ((z·ny + y)·nx + x)·channels + c against an explicit byte offset.
        let v = sample();
        let bytes = v.to_bytes();
        let (x, y, z, c) = (3, 1, 4, 2);
        let idx = ((z * 3 + y) * 4 + x) * 3 + c;
        let o = HEADER_BYTES + 4 * idx;
        let got = f32::from_le_bytes([bytes[o], bytes[o + 1], bytes[o + 2], bytes[o + 3]]);
        assert_eq!(got, idx as f32 * 0.25 - 3.0);
        let ch = v.channel(2).unwrap();
        let g = Grid::new([4, 3, 5], 0.5).unwrap();
        assert_eq!(ch[g.index(x, y, z)], f64::from(got));
        assert!(v.channel(3).is_none());
    }

    #[test]
    fn solver_grid_matches_box_and_rejects_non_cubic_voxels() {
        let g = Grid::with_origin([8, 4, 6], 0.25, [1.0, -2.0, 0.5]).unwrap();
        let values: Vec<f64> = (0..g.len()).map(|i| i as f64).collect();
        let v = VolGrid::from_field(&g, &values).unwrap();
        assert_eq!(v.max, [3.0, -1.0, 2.0]);
        let back = v.grid().unwrap();
        assert_eq!(back.n, g.n);
        assert!((back.dl - g.dl).abs() < 1e-12);
        assert_eq!(back.origin, g.origin);
        assert_eq!(v.channel(0).unwrap(), values);
        let err = sample().grid().unwrap_err();
        assert!(matches!(err, VolError::NonCubicVoxels { .. }), "{err}");
        assert!(err.to_string().contains("not cubic"));
    }

    #[test]
    fn malformed_files_are_typed_errors_never_panics() {
        let good = sample().to_bytes();
        // Every truncation is an error (header or data length), never a panic.
        for len in 0..good.len() {
            let err = VolGrid::from_bytes(&good[..len]).unwrap_err();
            if len < HEADER_BYTES {
                assert!(matches!(err, VolError::TruncatedHeader { got } if got == len));
            } else {
                assert!(matches!(err, VolError::DataLength { .. }), "{err}");
            }
        }
        let mut extra = good.clone();
        extra.push(0);
        assert!(matches!(
            VolGrid::from_bytes(&extra),
            Err(VolError::DataLength { .. })
        ));
        let patch = |o: usize, b: &[u8]| {
            let mut v = good.clone();
            v[o..o + b.len()].copy_from_slice(b);
            VolGrid::from_bytes(&v).unwrap_err()
        };
        assert!(matches!(patch(0, b"VOX"), VolError::BadMagic(_)));
        assert!(matches!(patch(3, &[2]), VolError::UnsupportedVersion(2)));
        assert!(matches!(
            patch(4, &2i32.to_le_bytes()),
            VolError::UnsupportedEncoding(2)
        ));
        assert!(matches!(
            patch(12, &(-3i32).to_le_bytes()),
            VolError::BadDimensions(_)
        ));
        assert!(matches!(
            patch(8, &0i32.to_le_bytes()),
            VolError::BadDimensions(_)
        ));
        // Huge dimensions must not allocate or overflow: the data length check catches them.
        let err = patch(8, &i32::MAX.to_le_bytes());
        assert!(matches!(
            err,
            VolError::DataLength { .. } | VolError::BadDimensions(_)
        ));
        assert!(matches!(
            patch(20, &2i32.to_le_bytes()),
            VolError::BadChannels(2)
        ));
        assert!(matches!(
            patch(24, &f32::NAN.to_le_bytes()),
            VolError::BadBoundingBox { .. }
        ));
        assert!(matches!(
            patch(36, &(-5.0f32).to_le_bytes()),
            VolError::BadBoundingBox { .. }
        ));
        assert!(matches!(
            VolGrid::new([2, 2, 2], 1, [0.0; 3], [1.0; 3], vec![0.0; 7]),
            Err(VolError::ValueCount {
                expected: 8,
                got: 7
            })
        ));
    }
}
