//! Memory budget checks made before a run allocates anything.
//!
//! Every entry point (experiment flags, scene and volume files) estimates the bytes its big
//! allocations need — an upper bound is fine — and calls [`check`], which refuses with a
//! [`TooLarge`] naming the flag or field, the bytes needed and the bytes available. The
//! budget is `SCATTERBENCH_MEMORY_BUDGET` (bytes) when set, otherwise `MemAvailable` from
//! `/proc/meminfo`; where neither can be read it is unlimited.

use thiserror::Error;

/// The environment variable that overrides the budget (a byte count).
pub const ENV: &str = "SCATTERBENCH_MEMORY_BUDGET";

/// Bytes per voxel of a grid solver's state, an upper bound over the registered methods
/// (the lattice-Boltzmann solvers keep two sets of lattice directions; the diffusion solvers
/// a dozen `f64` fields).
pub const SOLVER_BYTES_PER_VOXEL: u64 = 512;

/// Bytes per voxel of a medium (σt, albedo, emission, colour channels, majorants), an upper
/// bound.
pub const MEDIUM_BYTES_PER_VOXEL: u64 = 128;

/// Bytes per pixel of a rendered image set (a handful of RGB `f64` images and their
/// accumulators), an upper bound.
pub const IMAGE_BYTES_PER_PIXEL: u64 = 512;

/// Largest scene (TOML) file read, in bytes.
pub const MAX_TOML_BYTES: u64 = 16 << 20;

/// A run or file needs more memory than the budget allows.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error(
    "{what} needs about {} ({needed} bytes), more than the {} ({available} bytes) {origin}",
    human(*.needed),
    human(*.available)
)]
pub struct TooLarge {
    /// The flag or field responsible, with its value (e.g. `--n 99999`).
    pub what: String,
    /// Estimated bytes needed (saturated at `u64::MAX`).
    pub needed: u64,
    /// Bytes available.
    pub available: u64,
    /// Where the budget came from.
    pub origin: &'static str,
}

/// The budget in bytes and where it came from.
pub fn available() -> (u64, &'static str) {
    if let Some(b) = std::env::var(ENV)
        .ok()
        .and_then(|v| v.trim().parse::<u64>().ok())
    {
        return (b, "budget set by SCATTERBENCH_MEMORY_BUDGET");
    }
    std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("MemAvailable:"))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|kb| kb.parse::<u64>().ok())
        })
        .map(|kb| (kb.saturating_mul(1024), "available memory (MemAvailable)"))
        .unwrap_or((u64::MAX, "unlimited budget"))
}

/// Refuses `needed` bytes for `what` when they exceed the budget.
pub fn check(what: impl Into<String>, needed: u64) -> Result<(), TooLarge> {
    let (available, origin) = available();
    if needed > available {
        return Err(TooLarge {
            what: what.into(),
            needed,
            available,
            origin,
        });
    }
    Ok(())
}

/// The product of `dims` times `bytes_each`, saturating at `u64::MAX`.
pub fn bytes(dims: &[usize], bytes_each: u64) -> u64 {
    dims.iter()
        .fold(bytes_each, |acc, &d| acc.saturating_mul(d as u64))
}

/// Bytes of a grid solver on an `n³` grid (solver state plus medium).
pub fn cube_solver_bytes(n: usize) -> u64 {
    bytes(&[n, n, n], SOLVER_BYTES_PER_VOXEL + MEDIUM_BYTES_PER_VOXEL)
}

/// Bytes of images of `w × h` pixels.
pub fn image_bytes(w: usize, h: usize) -> u64 {
    bytes(&[w, h], IMAGE_BYTES_PER_PIXEL)
}

/// Opens `path` for reading if it is a regular file (not a device such as `/dev/zero`, a
/// FIFO or a directory) of at most `max_bytes`; returns it with its length.
pub fn open_regular(
    path: &std::path::Path,
    max_bytes: u64,
) -> std::io::Result<(std::fs::File, u64)> {
    let file = std::fs::File::open(path)?;
    let meta = file.metadata()?;
    if !meta.is_file() {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "not a regular file (a device, FIFO or directory cannot be read as input)",
        ));
    }
    if meta.len() > max_bytes {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            format!(
                "{} bytes, more than the {} ({max_bytes} bytes) this input may have",
                meta.len(),
                human(max_bytes)
            ),
        ));
    }
    Ok((file, meta.len()))
}

/// Reads at most `max_bytes` of the regular file `path` (see [`open_regular`]).
pub fn read_regular(path: &std::path::Path, max_bytes: u64) -> std::io::Result<Vec<u8>> {
    use std::io::Read as _;
    let (file, len) = open_regular(path, max_bytes)?;
    let mut out = Vec::with_capacity(len as usize);
    file.take(max_bytes).read_to_end(&mut out)?;
    Ok(out)
}

/// `bytes` in KiB/MiB/GiB/TiB/PiB/EiB, one decimal.
pub fn human(bytes: u64) -> String {
    const UNITS: [&str; 7] = ["B", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"];
    let mut v = bytes as f64;
    let mut u = 0;
    while v >= 1024.0 && u + 1 < UNITS.len() {
        v /= 1024.0;
        u += 1;
    }
    if u == 0 {
        format!("{bytes} B")
    } else {
        format!("{v:.1} {}", UNITS[u])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_saturate_and_absurd_grids_are_refused() {
        assert_eq!(bytes(&[2, 3, 4], 8), 192);
        assert_eq!(bytes(&[usize::MAX, usize::MAX], 8), u64::MAX);
        let e = check("--n 99999", cube_solver_bytes(99_999)).unwrap_err();
        assert!(e.to_string().contains("--n 99999"), "{e}");
        assert!(e.to_string().contains("bytes"), "{e}");
        assert!(check("tiny", 1).is_ok());
    }

    #[test]
    fn devices_and_directories_are_not_inputs() {
        assert!(open_regular(std::path::Path::new("/dev/zero"), 1 << 20).is_err());
        assert!(open_regular(std::path::Path::new("."), 1 << 20).is_err());
        let cargo = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("Cargo.toml");
        assert!(read_regular(&cargo, 1 << 20).is_ok());
        assert!(open_regular(&cargo, 1).is_err());
    }

    #[test]
    fn human_units() {
        assert_eq!(human(512), "512 B");
        assert_eq!(human(1536), "1.5 KiB");
        assert_eq!(human(3 << 30), "3.0 GiB");
    }
}
