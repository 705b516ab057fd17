//! Standard errors by batch means, the deterministic parallel driver every estimator runs on,
//! and the normal/χ² quantiles used to judge Monte Carlo results.
//!
//! **Batch means.** The N paths of an estimate are split into B ≥ [`MIN_BATCHES`] consecutive
//! batches of (nearly) equal size n_b. With batch means m_b and overall mean m = Σ n_b m_b / N,
//! the standard error of m is
//!
//! s² = Σ_b n_b (m_b − m)² / ((B − 1) N),
//!
//! which for equal batches is the textbook Σ (m_b − m)² / (B (B − 1)). Batches are far larger
//! than the correlation length of any estimator here (paths are independent), so the batch
//! means are independent and s is unbiased for the variance; with B = 16 the relative
//! uncertainty of s itself is about 1/√(2(B − 1)) ≈ 18 %, which is why judgements of the form
//! "within k standard errors" in the tests use B ≥ 32 or a margin.
//!
//! **Determinism.** Path `i` draws its random numbers from `Rng::new(seed, i)` only; paths
//! are summed chunk by chunk in a fixed order whose chunk size depends only on the path count,
//! never on the number of threads, so every result is bit-identical for any thread count.

use super::shard::{BatchSums, Shard};
use crate::ReferenceError;
use rayon::prelude::*;

/// The fewest batches any estimator accepts.
pub const MIN_BATCHES: u32 = 16;

/// A Monte Carlo estimate with its standard error.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    /// The mean.
    pub mean: f64,
    /// Its standard error (batch means).
    pub stderr: f64,
}

impl Estimate {
    /// (mean − `exact`) / stderr; ±∞ if the stderr is 0 and the mean differs, 0 if both agree.
    pub fn z(&self, exact: f64) -> f64 {
        let d = self.mean - exact;
        if d == 0.0 { 0.0 } else { d / self.stderr }
    }

    /// z-score of the difference of two independent estimates.
    pub fn z_diff(&self, other: &Estimate) -> f64 {
        let d = self.mean - other.mean;
        if d == 0.0 {
            0.0
        } else {
            d / (self.stderr.powi(2) + other.stderr.powi(2)).sqrt()
        }
    }

    /// stderr / |mean| (∞ for a zero mean with non-zero error, 0 for an exact zero).
    pub fn relative_stderr(&self) -> f64 {
        if self.stderr == 0.0 {
            0.0
        } else {
            self.stderr / self.mean.abs()
        }
    }
}

/// Checks `batches ≥ MIN_BATCHES` and `samples ≥ batches` (each batch needs one sample).
pub(crate) fn check_batches(
    batches: u32,
    samples: u64,
    what: &'static str,
) -> Result<(), ReferenceError> {
    if batches < MIN_BATCHES {
        return Err(ReferenceError::TooFewBatches {
            batches,
            min: MIN_BATCHES,
        });
    }
    if samples < batches as u64 {
        return Err(ReferenceError::BadParameter {
            name: what,
            value: samples as f64,
            reason: "must be at least the number of batches",
        });
    }
    Ok(())
}

/// Sizes of `batches` consecutive batches of `total` samples, differing by at most one.
pub(crate) fn batch_sizes(total: u64, batches: u32) -> Vec<u64> {
    let b = batches as u64;
    (0..b)
        .map(|i| total / b + u64::from(i < total % b))
        .collect()
}

/// The first sample index of each batch of `sizes` (a running sum).
pub(crate) fn batch_starts(sizes: &[u64]) -> Vec<u64> {
    sizes
        .iter()
        .scan(0u64, |s, &n| {
            let a = *s;
            *s += n;
            Some(a)
        })
        .collect()
}

/// Weighted batch-means accumulator over `bins` tallies (Welford's update on batch means).
#[derive(Debug, Clone)]
pub(crate) struct BatchMeans {
    n: u64,
    batches: u32,
    mean: Vec<f64>,
    m2: Vec<f64>,
}

impl BatchMeans {
    pub(crate) fn new(bins: usize) -> Self {
        Self {
            n: 0,
            batches: 0,
            mean: vec![0.0; bins],
            m2: vec![0.0; bins],
        }
    }

    /// Adds one batch of `n` samples whose per-bin sums are `sums`.
    pub(crate) fn add(&mut self, sums: &[f64], n: u64) {
        if n == 0 {
            return;
        }
        self.n += n;
        self.batches += 1;
        let w = n as f64 / self.n as f64;
        let inv = 1.0 / n as f64;
        for ((m, m2), &s) in self.mean.iter_mut().zip(&mut self.m2).zip(sums) {
            let x = s * inv;
            let d = x - *m;
            *m += d * w;
            *m2 += n as f64 * d * (x - *m);
        }
    }

    /// Means and standard errors per bin.
    pub(crate) fn finish(&self) -> Vec<Estimate> {
        let denom = (self.batches.max(2) - 1) as f64 * self.n.max(1) as f64;
        self.mean
            .iter()
            .zip(&self.m2)
            .map(|(&mean, &m2)| Estimate {
                mean,
                stderr: (m2.max(0.0) / denom).sqrt(),
            })
            .collect()
    }
}

/// Runs paths `0..paths` in `batches` batches: `path(i, tally)` adds path `i`'s scores to the
/// `bins` entries of `tally`. Within a batch, paths are summed in chunks processed in
/// parallel and combined in chunk order; the chunk size depends only on the batch size.
#[cfg(test)]
pub(crate) fn run_paths<F>(
    paths: u64,
    batches: u32,
    bins: usize,
    path: F,
) -> Result<Vec<Estimate>, ReferenceError>
where
    F: Fn(u64, &mut [f64]) + Sync,
{
    run_batches(paths, batches, bins, Shard::WHOLE, path)?.estimates()
}

/// [`run_paths`] for `shard`'s batches only: their per-batch sums, the same bits the
/// unsharded run computes for those batches (see [`shard`](super::shard)).
pub(crate) fn run_batches<F>(
    paths: u64,
    batches: u32,
    bins: usize,
    shard: Shard,
    path: F,
) -> Result<BatchSums, ReferenceError>
where
    F: Fn(u64, &mut [f64]) + Sync,
{
    let mut out = BatchSums::zeroed(paths, batches, bins, shard)?;
    for (k, range) in out.sample_ranges().into_iter().enumerate() {
        let (start, n) = (range.start, range.end - range.start);
        let chunk = n.div_ceil(256).max(64);
        let chunks: Vec<(u64, u64)> = (0..n.div_ceil(chunk))
            .map(|c| (start + c * chunk, (start + (c + 1) * chunk).min(start + n)))
            .collect();
        let partial: Vec<Vec<f64>> = chunks
            .par_iter()
            .map(|&(a, b)| {
                let mut t = vec![0.0; bins];
                for i in a..b {
                    path(i, &mut t);
                }
                t
            })
            .collect();
        let sums = &mut out.sums[k * bins..(k + 1) * bins];
        for t in &partial {
            for (s, v) in sums.iter_mut().zip(t) {
                *s += v;
            }
        }
    }
    Ok(out)
}

/// The complementary error function, with fractional error below 1.2·10⁻⁷ everywhere
/// (the Chebyshev-fitted exponential form of Press et al., *Numerical Recipes*, §6.2).
pub fn erfc(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let poly = -z * z - 1.265_512_23
        + t * (1.000_023_68
            + t * (0.374_091_96
                + t * (0.096_784_18
                    + t * (-0.186_288_06
                        + t * (0.278_868_07
                            + t * (-1.135_203_98
                                + t * (1.488_515_87 + t * (-0.822_152_23 + t * 0.170_872_77))))))));
    let r = t * poly.exp();
    if x >= 0.0 { r } else { 2.0 - r }
}

/// The standard normal upper-tail quantile: z with P(Z > z) = `p`, for p ∈ (0, ½], by
/// bisection on [`erfc`] (absolute accuracy about 10⁻⁹ in z plus erfc's own error).
pub fn normal_upper_quantile(p: f64) -> f64 {
    let (mut lo, mut hi) = (0.0f64, 40.0f64);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if 0.5 * erfc(mid / std::f64::consts::SQRT_2) > p {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// Šidák-corrected two-sided threshold: the |z| that `m` independent comparisons all stay
/// below with probability 1 − `family_alpha` under the null hypothesis.
/// E.g. `sidak_z(1, 0.0027)` ≈ 3.0 (the 3σ rule) and `sidak_z(40, 0.0027)` ≈ 4.0.
pub fn sidak_z(m: usize, family_alpha: f64) -> f64 {
    let per_test = 1.0 - (1.0 - family_alpha).powf(1.0 / m.max(1) as f64);
    normal_upper_quantile(per_test / 2.0)
}

/// The upper-`p` quantile of the χ² distribution with `k` degrees of freedom by the
/// Wilson–Hilferty cube-root normal approximation (relative error well below 1 % for k ≥ 10).
pub fn chi_square_upper_quantile(k: usize, p: f64) -> f64 {
    let k = k as f64;
    let z = normal_upper_quantile(p);
    let a = 2.0 / (9.0 * k);
    k * (1.0 - a + z * a.sqrt()).powi(3)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_match_tables() {
        assert!((normal_upper_quantile(0.025) - 1.959_964).abs() < 1e-5);
        assert!((normal_upper_quantile(0.00135) - 3.0).abs() < 2e-4);
        assert!((sidak_z(1, 0.0027) - 3.0).abs() < 1e-3);
        assert!((erfc(0.5) - 0.479_500_122).abs() < 1e-7);
        // χ²(30) upper 1 %: 50.892 (tables).
        assert!((chi_square_upper_quantile(30, 0.01) - 50.892).abs() < 0.1);
    }

    /// Batch means of i.i.d. exponential samples: the stderr matches σ/√N within its own
    /// sampling error, and unequal batches give the same mean as the plain average.
    #[test]
    fn batch_means_standard_error_is_calibrated() {
        let paths = 100_003u64;
        let est = run_paths(paths, 64, 1, |i, t| {
            let mut rng = super::super::rng::Rng::new(5, i);
            t[0] += rng.exponential();
        })
        .unwrap();
        let expected = 1.0 / (paths as f64).sqrt();
        // Relative sampling error of s with 63 dof is 1/√126 ≈ 9 %; allow 4 of them.
        assert!(
            (est[0].stderr / expected - 1.0).abs() < 0.36,
            "{} vs {expected}",
            est[0].stderr
        );
        assert!(est[0].z(1.0).abs() < 4.0, "{:?}", est[0]);
        let mut plain = 0.0;
        for i in 0..paths {
            plain += super::super::rng::Rng::new(5, i).exponential();
        }
        assert!((est[0].mean - plain / paths as f64).abs() < 1e-12);
        assert_eq!(batch_sizes(10, 4), vec![3, 3, 2, 2]);
    }
}
