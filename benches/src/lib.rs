//! Benchmark support for the solver benchmarks.
//!
//! * [`bandwidth`]: a STREAM-like memory-bandwidth probe (triad and copy over `f32` buffers,
//!   parallel with rayon), run in the same process as a benchmark so the solver's achieved
//!   effective bandwidth can be put in relation to what the memory system delivers for a
//!   simple streaming kernel on the same machine, at the same moment.
//! * [`median_seconds`]: the median wall-clock time of a closure over a few runs.
//! * [`cli`]: what every bench binary shares: benchmark vs test mode, the size list from the
//!   environment, fatal errors, and writing its summary CSV under `results/bench/`.
#![deny(missing_docs)]

use std::hint::black_box;
use std::time::Instant;

pub mod bandwidth {
    //! STREAM-like bandwidth probes.
    //!
    //! Both kernels run over `f32` buffers split into chunks of [`CHUNK`] elements that rayon
    //! distributes over its thread pool (`par_chunks_mut`). The buffers are allocated and
    //! first touched in parallel with the same chunking before any timing, so page faults are
    //! not measured. Each call runs the kernel `reps` times (at least once) and returns the
    //! best, i.e. the highest, bandwidth, as STREAM does.
    //!
    //! **Byte counting** follows STREAM: only the bytes the kernel's source code reads and
    //! writes are counted, i.e. triad `a[i] = b[i] + s·c[i]` counts 3 arrays × 4 bytes per
    //! element (2 reads + 1 write) and copy `a[i] = b[i]` counts 2 arrays × 4 bytes. The
    //! write-allocate traffic (the cache line of `a` that a normal store reads from memory
    //! before overwriting it) is **not** counted, so on a write-allocate cache the hardware
    //! moves about 4/3 (triad) and 3/2 (copy) of the reported bytes. GB are 10⁹ bytes.
    //!
    //! The solver's "effective bytes" (`CpuFld::bytes_per_iteration`) are counted the same way
    //! (each value once per read or write), so the ratio of the two is like for like.

    use rayon::prelude::*;
    use std::hint::black_box;
    use std::time::Instant;

    /// Elements per rayon work item (64 Ki `f32` = 256 KiB per array).
    pub const CHUNK: usize = 64 * 1024;

    /// Bytes per `f32` element.
    const F32_BYTES: usize = std::mem::size_of::<f32>();

    /// A buffer of `len` copies of `value`, first touched in parallel with the kernels' chunking.
    fn filled(len: usize, value: f32) -> Vec<f32> {
        let mut v = vec![0.0f32; len];
        v.par_chunks_mut(CHUNK).for_each(|c| c.fill(value));
        v
    }

    /// Runs `kernel` `reps` times (at least once) and returns the best bandwidth in GB/s for
    /// a kernel that moves `bytes` bytes per run.
    fn best_gbs(bytes: usize, reps: usize, mut kernel: impl FnMut()) -> f64 {
        let mut best = 0.0f64;
        for _ in 0..reps.max(1) {
            let t0 = Instant::now();
            kernel();
            let seconds = t0.elapsed().as_secs_f64();
            if seconds > 0.0 {
                best = best.max(bytes as f64 / seconds / 1e9);
            }
        }
        best
    }

    /// STREAM triad `a[i] = b[i] + s·c[i]` over three `f32` arrays of `len_f32` elements each
    /// (at least 1). Returns the best GB/s over `reps` runs (at least 1), counting
    /// 3 × 4 bytes per element (no write-allocate traffic, see the module docs).
    pub fn triad_gbs(len_f32: usize, reps: usize) -> f64 {
        let len = len_f32.max(1);
        let mut a = filled(len, 0.0);
        let b = filled(len, 1.0);
        let c = filled(len, 2.0);
        let s = black_box(3.0f32);
        let gbs = best_gbs(3 * F32_BYTES * len, reps, || {
            let (b, c) = (black_box(b.as_slice()), black_box(c.as_slice()));
            a.par_chunks_mut(CHUNK)
                .zip(b.par_chunks(CHUNK))
                .zip(c.par_chunks(CHUNK))
                .for_each(|((a, b), c)| {
                    for ((x, &y), &z) in a.iter_mut().zip(b).zip(c) {
                        *x = y + s * z;
                    }
                });
            black_box(a.as_mut_slice());
        });
        black_box(&a);
        gbs
    }

    /// STREAM copy `a[i] = b[i]` over two `f32` arrays of `len_f32` elements each
    /// (at least 1). Returns the best GB/s over `reps` runs (at least 1), counting
    /// 2 × 4 bytes per element (no write-allocate traffic, see the module docs).
    pub fn copy_gbs(len_f32: usize, reps: usize) -> f64 {
        let len = len_f32.max(1);
        let mut a = filled(len, 0.0);
        let b = filled(len, 1.0);
        let gbs = best_gbs(2 * F32_BYTES * len, reps, || {
            let b = black_box(b.as_slice());
            a.par_chunks_mut(CHUNK)
                .zip(b.par_chunks(CHUNK))
                .for_each(|(a, b)| a.copy_from_slice(b));
            black_box(a.as_mut_slice());
        });
        black_box(&a);
        gbs
    }

    /// The size of the largest CPU cache in bytes, read from Linux's
    /// `/sys/devices/system/cpu/cpu0/cache/index*/size` (`None` where it cannot be read).
    pub fn last_level_cache_bytes() -> Option<usize> {
        let dir = std::fs::read_dir("/sys/devices/system/cpu/cpu0/cache").ok()?;
        dir.filter_map(|e| e.ok())
            .filter(|e| e.file_name().to_string_lossy().starts_with("index"))
            .filter_map(|e| std::fs::read_to_string(e.path().join("size")).ok())
            .filter_map(|t| parse_cache_size(t.trim()))
            .max()
    }

    /// Parses a sysfs cache size such as `32768K` or `32M` (plain digits: bytes).
    pub fn parse_cache_size(text: &str) -> Option<usize> {
        let (digits, scale) = match text.chars().last()? {
            'K' | 'k' => (&text[..text.len() - 1], 1 << 10),
            'M' | 'm' => (&text[..text.len() - 1], 1 << 20),
            'G' | 'g' => (&text[..text.len() - 1], 1 << 30),
            _ => (text, 1),
        };
        digits.parse::<usize>().ok().map(|d| d * scale)
    }

    /// Fallback for [`stream_rule_len`] where the cache size cannot be read: 128 MiB, four
    /// times the largest L3 this machine kind has come with (32 and 105 MiB seen).
    pub const FALLBACK_CACHE_BYTES: usize = 128 << 20;

    /// Elements per array by STREAM's sizing rule: each array at least four times the
    /// largest cache ([`last_level_cache_bytes`], else [`FALLBACK_CACHE_BYTES`]), so the
    /// probe measures main memory and not the cache. A probe over a solver's own footprint
    /// ([`len_for_total_bytes`]) is partly served by the cache when that footprint is near
    /// the cache size (a 128³ `f32` step: 42 MB against a 32 MiB L3), and then overstates
    /// what the memory system delivers.
    pub fn stream_rule_len() -> usize {
        4 * last_level_cache_bytes().unwrap_or(FALLBACK_CACHE_BYTES) / F32_BYTES
    }

    /// Elements per array such that `arrays` `f32` arrays together hold about `total_bytes`
    /// bytes (at least 1 element), e.g. to run [`triad_gbs`] (3 arrays) or [`copy_gbs`]
    /// (2 arrays) over the same footprint as a solver's state.
    pub fn len_for_total_bytes(total_bytes: usize, arrays: usize) -> usize {
        (total_bytes / (arrays.max(1) * F32_BYTES)).max(1)
    }
}

pub mod cli {
    //! Shared by the bench binaries.

    use std::path::PathBuf;

    /// The CPU model from `/proc/cpuinfo` (`unknown` where there is none), commas replaced
    /// by spaces so it fits a CSV cell: every summary CSV names the machine it came from.
    pub fn cpu_model() -> String {
        std::fs::read_to_string("/proc/cpuinfo")
            .ok()
            .and_then(|s| {
                s.lines()
                    .find(|l| l.starts_with("model name"))
                    .and_then(|l| l.split(':').nth(1))
                    .map(|m| m.trim().replace(',', " "))
            })
            .unwrap_or_else(|| "unknown".into())
    }

    /// Prints `bench: message` and exits with status 2 (a bench has no caller to return to).
    pub fn fail(bench: &str, message: &str) -> ! {
        eprintln!("{bench} bench: {message}");
        std::process::exit(2)
    }

    /// Whether criterion runs in benchmark mode (`--bench` given, no `--test`, `--list` or
    /// `--profile-time`): only then are summaries measured and written.
    pub fn benchmark_mode() -> bool {
        let args: Vec<String> = std::env::args().skip(1).collect();
        is_benchmark_mode(&args)
    }

    /// [`benchmark_mode`] for an explicit argument list.
    pub fn is_benchmark_mode(args: &[String]) -> bool {
        args.iter().any(|a| a == "--bench")
            && !args
                .iter()
                .any(|a| a == "--test" || a == "--list" || a.starts_with("--profile-time"))
    }

    /// Grid sizes from the environment variable `var` (comma-separated, each ≥ 3), else
    /// `default` in benchmark mode and `test` otherwise.
    pub fn sizes(
        var: &str,
        bench: bool,
        default: &[usize],
        test: &[usize],
    ) -> Result<Vec<usize>, String> {
        match std::env::var(var) {
            Ok(text) => parse_sizes(var, &text),
            Err(_) if bench => Ok(default.to_vec()),
            Err(_) => Ok(test.to_vec()),
        }
    }

    /// Parses a comma-separated size list such as `64,128`: each a grid size n ≥ 3 whose n³
    /// fits a `usize`, duplicates dropped; an empty list is an error.
    pub fn parse_sizes(var: &str, text: &str) -> Result<Vec<usize>, String> {
        let mut sizes = Vec::new();
        for item in text.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            let n: usize = item.parse().map_err(|e| {
                format!("{var}: `{item}` is not a grid size ({e}); expected e.g. {var}=64,128")
            })?;
            if n < 3 {
                return Err(format!(
                    "{var}: grid size {n} is too small; the solvers need n ≥ 3"
                ));
            }
            if n.checked_pow(3).is_none() {
                return Err(format!("{var}: grid size {n} is too large; n³ overflows"));
            }
            if !sizes.contains(&n) {
                sizes.push(n);
            }
        }
        if sizes.is_empty() {
            return Err(format!(
                "{var}=`{text}` names no grid size; expected e.g. {var}=64,128"
            ));
        }
        Ok(sizes)
    }

    /// `relative` under the workspace root (the parent of this crate's manifest directory).
    pub fn workspace_path(relative: &str) -> PathBuf {
        let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
        root.parent()
            .map(|p| p.join(relative))
            .unwrap_or_else(|| root.join(relative))
    }

    /// Prints a bench's summary table (`header`, then one CSV line per row, then `note`) and
    /// writes it to `relative` under the workspace root ([`write_result`]); a write error is
    /// printed, not fatal (the table is on stdout).
    pub fn emit_table(relative: &str, header: &str, lines: &[String], note: &str) {
        let mut text = format!("{header}\n");
        println!("\n{header}");
        for line in lines {
            println!("{line}");
            text.push_str(line);
            text.push('\n');
        }
        println!("{note}");
        match write_result(relative, &text) {
            Ok(path) => println!("wrote {}", path.display()),
            Err(e) => eprintln!("error: cannot write {relative}: {e}"),
        }
    }

    /// Writes `contents` to `relative` under the workspace root, creating its folder, through
    /// a temporary file renamed into place (a reader never sees half a table).
    pub fn write_result(relative: &str, contents: &str) -> std::io::Result<PathBuf> {
        let path = workspace_path(relative);
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir)?;
        }
        let tmp = path.with_extension("csv.tmp");
        std::fs::write(&tmp, contents)?;
        std::fs::rename(&tmp, &path)?;
        Ok(path)
    }
}

/// Median wall-clock seconds of `k` runs (at least 1) of `f`; the result of each run goes
/// through [`black_box`] so it is not optimised away. With an even count the median is the
/// mean of the two middle runs.
pub fn median_seconds<R>(k: usize, mut f: impl FnMut() -> R) -> f64 {
    let mut times: Vec<f64> = (0..k.max(1))
        .map(|_| {
            let t0 = Instant::now();
            black_box(f());
            t0.elapsed().as_secs_f64()
        })
        .collect();
    times.sort_by(f64::total_cmp);
    let mid = times.len() / 2;
    if times.len() % 2 == 1 {
        times[mid]
    } else {
        0.5 * (times[mid - 1] + times[mid])
    }
}

#[cfg(test)]
mod tests {
    use super::bandwidth::{copy_gbs, len_for_total_bytes, triad_gbs};
    use super::median_seconds;

    #[test]
    fn probes_return_positive_finite_bandwidth() {
        for gbs in [
            triad_gbs(1 << 18, 2),
            copy_gbs(1 << 18, 2),
            triad_gbs(0, 0),
            copy_gbs(3, 1),
        ] {
            assert!(gbs.is_finite() && gbs >= 0.0, "{gbs}");
        }
        assert!(triad_gbs(1 << 20, 3) > 0.0);
    }

    #[test]
    fn len_for_total_bytes_splits_the_footprint() {
        assert_eq!(len_for_total_bytes(1200, 3), 100);
        assert_eq!(len_for_total_bytes(800, 2), 100);
        assert_eq!(len_for_total_bytes(0, 3), 1);
        assert_eq!(len_for_total_bytes(8, 0), 2);
    }

    #[test]
    fn size_lists_parse_or_fail_with_the_variable_name() {
        use super::cli::{is_benchmark_mode, parse_sizes};
        assert_eq!(parse_sizes("V", "16, 32,16").unwrap(), vec![16, 32]);
        assert!(
            parse_sizes("V", "99999999999")
                .unwrap_err()
                .contains("overflows")
        );
        assert!(parse_sizes("V", "2").unwrap_err().contains("V"));
        assert!(parse_sizes("V", "x").is_err());
        assert!(parse_sizes("V", " , ").is_err());
        let a = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        assert!(is_benchmark_mode(&a(&["--bench"])));
        assert!(!is_benchmark_mode(&a(&["--bench", "--test"])));
        assert!(!is_benchmark_mode(&a(&[])));
    }

    #[test]
    fn median_of_odd_and_even_counts() {
        let mut calls = 0;
        let m = median_seconds(5, || calls += 1);
        assert_eq!(calls, 5);
        assert!(m >= 0.0);
        let mut calls = 0;
        median_seconds(0, || calls += 1);
        assert_eq!(calls, 1);
        let sleep = |ms| move || std::thread::sleep(std::time::Duration::from_millis(ms));
        assert!(median_seconds(2, sleep(2)) >= 0.002);
    }

    #[test]
    fn sysfs_cache_sizes_parse() {
        use super::bandwidth::parse_cache_size;
        assert_eq!(parse_cache_size("32768K"), Some(32 << 20));
        assert_eq!(parse_cache_size("105M"), Some(105 << 20));
        assert_eq!(parse_cache_size("512"), Some(512));
        assert_eq!(parse_cache_size("K"), None);
        assert_eq!(parse_cache_size("x1K"), None);
    }
}
