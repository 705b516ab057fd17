//! Seeded, deterministic gradient (Perlin) noise and a small PRNG, so procedural scenes are
//! reproducible bit for bit from a seed on every platform.

/// The SplitMix64 finaliser (Steele, Lea, Flood 2014): a bijective 64-bit mixer, also used to
/// hash (seed, path index) into the path tracer's per-path streams.
#[inline(always)]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// SplitMix64: a tiny, fast, well-mixed 64-bit generator (Steele, Lea, Flood 2014), used for
/// procedural media and permutation tables. Not for Monte Carlo estimators.
#[derive(Debug, Clone)]
pub struct SplitMix64(u64);

impl SplitMix64 {
    /// A generator started from `seed`.
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    /// Next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        mix64(self.0)
    }

    /// Uniform in [0, 1) with 53 random bits.
    pub fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

/// Three-dimensional gradient noise with a seeded permutation table (Perlin's construction:
/// pseudo-random gradients at lattice points, quintic fade). Values lie in about [−1, 1],
/// are 0 at lattice points and repeat with period 256.
#[derive(Debug, Clone)]
pub struct Perlin {
    perm: [u8; 512],
}

impl Perlin {
    /// A noise function determined by `seed`.
    pub fn new(seed: u64) -> Self {
        let mut rng = SplitMix64::new(seed);
        let mut p: [u8; 256] = std::array::from_fn(|i| i as u8);
        for i in (1..256).rev() {
            let j = (rng.next_u64() % (i as u64 + 1)) as usize;
            p.swap(i, j);
        }
        Self {
            perm: std::array::from_fn(|i| p[i & 255]),
        }
    }

    fn grad(hash: u8, x: f64, y: f64, z: f64) -> f64 {
        // The 12 edge directions of a cube (4 repeated), as in Perlin's improved noise.
        match hash & 15 {
            0 | 12 => x + y,
            1 | 13 => -x + y,
            2 => x - y,
            3 => -x - y,
            4 => x + z,
            5 => -x + z,
            6 => x - z,
            7 => -x - z,
            8 => y + z,
            9 | 14 => -y + z,
            10 => y - z,
            _ => -y - z,
        }
    }

    /// Noise at `p`.
    pub fn at(&self, p: [f64; 3]) -> f64 {
        let fl = p.map(f64::floor);
        let c = [0, 1, 2].map(|a| (fl[a] as i64).rem_euclid(256) as usize);
        let [x, y, z] = [p[0] - fl[0], p[1] - fl[1], p[2] - fl[2]];
        let fade = |t: f64| t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
        let (u, v, w) = (fade(x), fade(y), fade(z));
        let pm = &self.perm;
        let h = |i: usize, j: usize, k: usize| {
            pm[pm[pm[c[0] + i] as usize + c[1] + j] as usize + c[2] + k]
        };
        let lerp = |t: f64, a: f64, b: f64| a + t * (b - a);
        let g = |i: usize, j: usize, k: usize| {
            Self::grad(h(i, j, k), x - i as f64, y - j as f64, z - k as f64)
        };
        lerp(
            w,
            lerp(
                v,
                lerp(u, g(0, 0, 0), g(1, 0, 0)),
                lerp(u, g(0, 1, 0), g(1, 1, 0)),
            ),
            lerp(
                v,
                lerp(u, g(0, 0, 1), g(1, 0, 1)),
                lerp(u, g(0, 1, 1), g(1, 1, 1)),
            ),
        )
    }

    /// Fractal sum of `octaves` octaves, each at twice the frequency and half the amplitude.
    pub fn fbm(&self, p: [f64; 3], octaves: u32) -> f64 {
        let (mut sum, mut amp, mut freq) = (0.0, 1.0, 1.0);
        for _ in 0..octaves {
            sum += amp * self.at(p.map(|x| x * freq));
            amp *= 0.5;
            freq *= 2.0;
        }
        sum
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn perlin_is_deterministic_bounded_and_zero_on_lattice() {
        let (a, b) = (Perlin::new(7), Perlin::new(7));
        let mut rng = SplitMix64::new(1);
        let mut sumsq = 0.0;
        for _ in 0..2000 {
            let p = [
                rng.next_f64() * 10.0,
                rng.next_f64() * 10.0,
                rng.next_f64() * 10.0,
            ];
            let v = a.at(p);
            assert_eq!(v, b.at(p));
            assert!(v.abs() <= 1.5, "{v}");
            sumsq += v * v;
        }
        assert!(sumsq / 2000.0 > 0.01, "noise is nearly constant");
        assert_eq!(a.at([3.0, 4.0, 5.0]), 0.0);
        assert_ne!(Perlin::new(8).at([0.5, 0.5, 0.5]), a.at([0.5, 0.5, 0.5]));
    }
}
