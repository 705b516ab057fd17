//! Counter-based seeding: every path owns a random stream determined by `(seed, path index)`
//! alone, so a result never depends on how paths are scheduled across threads.
//!
//! The pair is hashed with the SplitMix64 finaliser into the 128-bit state and the 128-bit
//! stream increment of a PCG-XSL-RR 128/64 generator (O'Neill 2014, "PCG: a family of simple
//! fast space-efficient statistically good algorithms for random number generation"): a
//! 128-bit linear congruential step with a xorshift-low / random-rotation output function.
//! Distinct increments select distinct LCG sequences, and hashed states put different paths
//! far apart within them.

use solvers::noise::mix64;

const GOLDEN: u64 = 0x9E37_79B9_7F4A_7C15;
const PCG_MULT: u128 = 0x2360_ED05_1FC6_5DA4_4385_DF64_9FCC_F645;

/// A PCG-XSL-RR 128/64 generator for one path.
#[derive(Debug, Clone)]
pub struct Rng {
    state: u128,
    inc: u128,
}

impl Rng {
    /// The generator of path `index` under `seed` ([`Streams::path`]).
    pub fn new(seed: u64, index: u64) -> Self {
        Streams::new(seed).path(index)
    }

    #[inline(always)]
    fn step(&mut self) {
        self.state = self.state.wrapping_mul(PCG_MULT).wrapping_add(self.inc);
    }

    /// Next 64 random bits.
    #[inline(always)]
    pub fn next_u64(&mut self) -> u64 {
        self.step();
        let s = self.state;
        ((s >> 64) as u64 ^ s as u64).rotate_right((s >> 122) as u32)
    }

    /// Uniform in [0, 1) with 53 random bits.
    #[inline(always)]
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// A standard exponential variate −ln(1 − u), finite because 1 − u ∈ (0, 1].
    #[inline(always)]
    pub fn exponential(&mut self) -> f64 {
        -(1.0 - self.uniform()).ln()
    }
}

/// The random streams of one seed: [`Streams::path`] is [`Rng::new`] with the hash of the
/// seed computed once per render instead of once per path.
#[derive(Debug, Clone, Copy)]
pub struct Streams {
    key: u64,
}

impl Streams {
    /// The streams of `seed`.
    pub fn new(seed: u64) -> Self {
        Self {
            key: mix64(seed.wrapping_add(GOLDEN)),
        }
    }

    /// The generator of path `index`.
    #[inline]
    pub fn path(&self, index: u64) -> Rng {
        // A SplitMix64 sequence started at a hash of (seed, index).
        let mut k = mix64(self.key ^ index.wrapping_mul(GOLDEN));
        let mut next = || {
            k = k.wrapping_add(GOLDEN);
            mix64(k)
        };
        let state = ((next() as u128) << 64) | next() as u128;
        let inc = (((next() as u128) << 64) | next() as u128) | 1;
        let mut rng = Rng { state, inc };
        rng.step();
        rng
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Mean and variance of U(0,1) draws, and the correlation of equal draws from
    /// neighbouring paths, are within 5 standard errors of 1/2, 1/12 and 0.
    #[test]
    fn uniform_moments_and_stream_independence() {
        let n = 200_000u64;
        let (mut s1, mut s2, mut cross) = (0.0, 0.0, 0.0);
        for i in 0..n {
            let mut a = Rng::new(42, i);
            let mut b = Rng::new(42, i + 1);
            let (x, y) = (a.uniform(), b.uniform());
            s1 += x;
            s2 += x * x;
            cross += (x - 0.5) * (y - 0.5);
        }
        let nf = n as f64;
        let mean = s1 / nf;
        let var = s2 / nf - mean * mean;
        assert!(
            (mean - 0.5).abs() < 5.0 * (1.0 / 12.0 / nf).sqrt(),
            "{mean}"
        );
        // Var of the sample variance of U(0,1): (1/80 - 1/144)/n.
        assert!(
            (var - 1.0 / 12.0).abs() < 5.0 * ((1.0 / 80.0 - 1.0 / 144.0) / nf).sqrt(),
            "{var}"
        );
        let corr = cross / nf * 12.0;
        assert!(corr.abs() < 5.0 / nf.sqrt(), "correlation {corr}");
        // Different seeds give different streams; equal (seed, index) the same one.
        assert_ne!(Rng::new(1, 0).next_u64(), Rng::new(2, 0).next_u64());
        assert_eq!(Rng::new(7, 9).next_u64(), Rng::new(7, 9).next_u64());
    }
}
