//! Shards: a run's batches split across processes, and the per-batch sums that merge exactly.
//!
//! Every estimator runs its samples in `B` batches (see [`estimators`](super::estimators)):
//! batch b holds a fixed, contiguous range of sample indices and each sample's random stream
//! depends only on (seed, sample index). So the per-batch sums of a run do not depend on which
//! process computed them. A [`Shard`] `i/N` computes the contiguous batch range
//! `[⌊iB/N⌋, ⌊(i+1)B/N⌋)`; its [`BatchSums`] hold one sum per batch and bin, bit for bit the
//! sums the unsharded run computes for those batches. [`BatchSums::join`] puts the shards'
//! ranges back together (refusing gaps, overlaps and mismatched layouts), and
//! [`BatchSums::estimates`] folds the batches in batch order through the one batch-means
//! accumulator every estimator uses — so a merged result is bit-identical to the unsharded
//! one for the same seed and batch count.

use super::estimators::{BatchMeans, Estimate, batch_sizes};
use crate::ReferenceError;
use std::ops::Range;

/// Shard `index` of `count` (0-based): which contiguous part of a run's batches a process
/// computes. [`Shard::WHOLE`] is the unsharded run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Shard {
    index: u32,
    count: u32,
}

impl Shard {
    /// The whole run (shard 0 of 1).
    pub const WHOLE: Shard = Shard { index: 0, count: 1 };

    /// Shard `index` of `count`; fails unless `count ≥ 1` and `index < count`.
    pub fn new(index: u32, count: u32) -> Result<Self, ReferenceError> {
        if count == 0 {
            return Err(ReferenceError::BadShard {
                shard: format!("{index}/{count}"),
                reason: "the number of shards must be at least 1",
            });
        }
        if index >= count {
            return Err(ReferenceError::BadShard {
                shard: format!("{index}/{count}"),
                reason: "the shard index is 0-based and must be below the number of shards",
            });
        }
        Ok(Self { index, count })
    }

    /// 0-based index.
    pub fn index(&self) -> u32 {
        self.index
    }

    /// Number of shards.
    pub fn count(&self) -> u32 {
        self.count
    }

    /// Whether this is the whole run.
    pub fn is_whole(&self) -> bool {
        self.count == 1
    }

    /// The batches of a run of `total` batches that this shard computes. Fails when a shard
    /// would get no batch (more shards than batches).
    pub fn batches(&self, total: u32) -> Result<Range<u32>, ReferenceError> {
        if self.count > total {
            return Err(ReferenceError::BadShard {
                shard: self.to_string(),
                reason: "more shards than batches: raise the batch count or use fewer shards",
            });
        }
        let at = |i: u32| (u64::from(i) * u64::from(total) / u64::from(self.count)) as u32;
        Ok(at(self.index)..at(self.index + 1))
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl std::str::FromStr for Shard {
    type Err = ReferenceError;

    /// Parses `i/N` (0-based i).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let bad = |reason| ReferenceError::BadShard {
            shard: s.to_string(),
            reason,
        };
        let (i, n) = s
            .split_once('/')
            .ok_or_else(|| bad("expected `i/N`, e.g. `0/4` for the first of four shards"))?;
        let i = i
            .trim()
            .parse::<u32>()
            .map_err(|_| bad("the shard index `i` of `i/N` is not a whole number"))?;
        let n = n
            .trim()
            .parse::<u32>()
            .map_err(|_| bad("the shard count `N` of `i/N` is not a whole number"))?;
        Shard::new(i, n)
    }
}

/// One sum per bin for each batch of a contiguous range of a run's batches.
#[derive(Debug, Clone, PartialEq)]
pub struct BatchSums {
    /// Tallies per batch.
    pub bins: usize,
    /// Batches of the whole run.
    pub total_batches: u32,
    /// Samples of the whole run.
    pub total_samples: u64,
    /// First batch held.
    pub first: u32,
    /// Samples in each held batch.
    pub sizes: Vec<u64>,
    /// The sums, batch-major: `sums[k · bins + bin]` for the k-th held batch.
    pub sums: Vec<f64>,
}

impl BatchSums {
    /// Zeroed sums for `shard`'s batches of a run of `samples` samples in `batches` batches.
    pub(crate) fn zeroed(
        samples: u64,
        batches: u32,
        bins: usize,
        shard: Shard,
    ) -> Result<Self, ReferenceError> {
        let range = shard.batches(batches)?;
        let sizes =
            batch_sizes(samples, batches)[range.start as usize..range.end as usize].to_vec();
        Ok(Self {
            bins,
            total_batches: batches,
            total_samples: samples,
            first: range.start,
            sums: vec![0.0; sizes.len() * bins],
            sizes,
        })
    }

    /// Index of the first sample of each held batch, and its size.
    pub(crate) fn sample_ranges(&self) -> Vec<Range<u64>> {
        let all = batch_sizes(self.total_samples, self.total_batches);
        let mut start: u64 = all[..self.first as usize].iter().sum();
        self.sizes
            .iter()
            .map(|&n| {
                let r = start..start + n;
                start += n;
                r
            })
            .collect()
    }

    /// The batches held.
    pub fn batches(&self) -> Range<u32> {
        self.first..self.first + self.sizes.len() as u32
    }

    /// Whether every batch of the run is held.
    pub fn is_complete(&self) -> bool {
        self.first == 0 && self.sizes.len() == self.total_batches as usize
    }

    /// Sums of the k-th held batch.
    pub fn batch(&self, k: usize) -> &[f64] {
        &self.sums[k * self.bins..(k + 1) * self.bins]
    }

    /// Joins the parts of one run into one: they must share bins, batch and sample counts
    /// and, sorted by first batch, hold consecutive ranges from batch 0 without gaps or
    /// overlaps. The result need not be complete (check [`BatchSums::is_complete`]).
    pub fn join(mut parts: Vec<BatchSums>) -> Result<BatchSums, ReferenceError> {
        parts.sort_by_key(|p| p.first);
        let Some(first) = parts.first() else {
            return Err(ReferenceError::ShardMismatch {
                what: "no parts to join".into(),
            });
        };
        let (bins, total_batches, total_samples) =
            (first.bins, first.total_batches, first.total_samples);
        let mut out = BatchSums {
            bins,
            total_batches,
            total_samples,
            first: 0,
            sizes: Vec::with_capacity(total_batches as usize),
            sums: Vec::new(),
        };
        let mut next = 0u32;
        for p in parts {
            if (p.bins, p.total_batches, p.total_samples) != (bins, total_batches, total_samples) {
                return Err(ReferenceError::ShardMismatch {
                    what: format!(
                        "parts of different runs: {bins} bins, {total_batches} batches of \
                         {total_samples} samples vs {} bins, {} batches of {} samples",
                        p.bins, p.total_batches, p.total_samples
                    ),
                });
            }
            if p.sums.len() != p.sizes.len() * bins {
                return Err(ReferenceError::ShardMismatch {
                    what: format!(
                        "a part holds {} sums for {} batches of {bins} bins",
                        p.sums.len(),
                        p.sizes.len()
                    ),
                });
            }
            let r = p.batches();
            if r.start < next {
                return Err(ReferenceError::ShardMismatch {
                    what: format!("batches {}..{} are held twice", r.start, next.min(r.end)),
                });
            }
            if r.start > next {
                return Err(ReferenceError::ShardMismatch {
                    what: format!("batches {next}..{} are missing", r.start),
                });
            }
            next = r.end;
            out.sizes.extend_from_slice(&p.sizes);
            out.sums.extend_from_slice(&p.sums);
        }
        if next < total_batches {
            return Err(ReferenceError::ShardMismatch {
                what: format!("batches {next}..{total_batches} are missing"),
            });
        }
        Ok(out)
    }

    /// The per-bin means and batch-means standard errors of a complete run.
    pub fn estimates(&self) -> Result<Vec<Estimate>, ReferenceError> {
        Ok(self.fold()?.finish())
    }

    /// The accumulator after every batch, in batch order.
    pub(crate) fn fold(&self) -> Result<BatchMeans, ReferenceError> {
        if !self.is_complete() {
            return Err(ReferenceError::ShardMismatch {
                what: format!(
                    "batches {}..{} of {} held: estimates need the whole run (merge the \
                     other shards first)",
                    self.first,
                    self.first + self.sizes.len() as u32,
                    self.total_batches
                ),
            });
        }
        let mut acc = BatchMeans::new(self.bins);
        for (k, &n) in self.sizes.iter().enumerate() {
            acc.add(self.batch(k), n);
        }
        Ok(acc)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_cover_the_batches_once() {
        for total in [16u32, 17, 31, 64] {
            for count in 1..=total.min(20) {
                let mut next = 0;
                for i in 0..count {
                    let r = Shard::new(i, count).unwrap().batches(total).unwrap();
                    assert_eq!(r.start, next);
                    assert!(r.end > r.start, "shard {i}/{count} of {total} is empty");
                    next = r.end;
                }
                assert_eq!(next, total);
            }
        }
        assert!(Shard::new(0, 17).unwrap().batches(16).is_err());
    }

    #[test]
    fn parse_and_refuse() {
        assert_eq!("3/4".parse::<Shard>().unwrap(), Shard::new(3, 4).unwrap());
        for bad in ["4/4", "1/0", "a/2", "2", "-1/3"] {
            assert!(bad.parse::<Shard>().is_err(), "{bad}");
        }
    }

    fn part(first: u32, n: usize) -> BatchSums {
        BatchSums {
            bins: 1,
            total_batches: 4,
            total_samples: 40,
            first,
            sizes: vec![10; n],
            sums: (0..n).map(|k| (first as usize + k) as f64).collect(),
        }
    }

    #[test]
    fn join_refuses_gaps_overlaps_and_strangers() {
        let whole = BatchSums::join(vec![part(2, 2), part(0, 2)]).unwrap();
        assert!(whole.is_complete());
        assert_eq!(whole.sums, vec![0.0, 1.0, 2.0, 3.0]);
        assert!(BatchSums::join(vec![part(0, 2)]).is_err());
        assert!(BatchSums::join(vec![part(0, 2), part(3, 1)]).is_err());
        assert!(BatchSums::join(vec![part(0, 3), part(2, 2)]).is_err());
        let mut other = part(2, 2);
        other.total_samples = 44;
        assert!(BatchSums::join(vec![part(0, 2), other]).is_err());
        assert!(part(0, 2).estimates().is_err());
    }
}
