//! Free-flight sampling in a heterogeneous voxel medium: delta (Woodcock) tracking for
//! collisions and ratio tracking for transmittance, both against a coarse majorant grid.
//!
//! **Majorant grid.** The voxels are grouped into blocks of `block³`; each block stores the
//! largest σt its reconstruction can take inside it (for nearest, the max over its voxels;
//! for trilinear, over its voxels and the one-voxel ring the interpolation stencil reaches).
//! A ray walks the blocks with a 3D DDA and uses each block's own majorant μ̄, so sparse media
//! do not pay for their densest voxel everywhere, and blocks with μ̄ = 0 are skipped without
//! drawing a random number. A single block covering the grid is the textbook global-majorant
//! Woodcock tracker (`block ≥ max n`), which the tests compare against.
//!
//! **Delta tracking** (Woodcock et al. 1965; Raab, Seibert, Keller 2006, FLD's \[RSK06\]):
//! tentative collisions are drawn from the homogeneous majorant process; each is real with
//! probability σt(x)/μ̄. Across a block boundary the remaining exponential optical depth
//! carries over (memorylessness), so one exponential variate is used per tentative collision.
//!
//! **Ratio tracking** (Novák, Selle, Jarosz 2014): the same tentative collisions, but the
//! estimate is multiplied by (1 − σt(x)/μ̄) at each instead of stopping. Once the estimate
//! falls below 10⁻² it is continued with probability ½ and doubled (Russian roulette), which
//! keeps it unbiased and bounds the work in optically thick media.
//!
//! **Uniform blocks.** A block whose reconstruction is constant (every voxel its lookup can
//! reach has the same σt) is flagged. There every tentative collision is real, so delta
//! tracking skips the lookup and the acceptance draw, and the transmittance through it is
//! exactly e^{−μ̄·Δt}, so ratio tracking multiplies by that instead of tracking: same
//! distribution of collisions, a zero-variance shadow factor, and no random numbers spent.
//! Homogeneous media (and the homogeneous parts of heterogeneous ones) are cheaper that way
//! (measured on `scenes/emissive_sphere.toml` in `mitsuba_compare`).

use super::math::{Vec3, at};
use super::rng::Rng;
use super::volume::{Interpolation, Volume, traverse};

/// Default majorant block edge in voxels.
pub const DEFAULT_BLOCK: usize = 8;

const RATIO_ROULETTE: f64 = 1e-2;

/// Maximum σt per block of voxels.
#[derive(Debug, Clone)]
pub struct Majorant {
    block: usize,
    nb: [usize; 3],
    cell: f64,
    origin: Vec3,
    values: Vec<f64>,
    /// Whether σt is constant over the block's stencil (see the module docs).
    uniform: Vec<bool>,
}

impl Majorant {
    /// The majorant grid of `volume` with blocks of `block³` voxels (`block` ≥ 1; a block
    /// at least as large as the grid gives one global majorant).
    pub fn new(volume: &Volume, block: usize) -> Self {
        let g = volume.grid();
        let block = block.clamp(1, g.n.iter().copied().max().unwrap_or(1));
        let nb = g.n.map(|n| n.div_ceil(block));
        let ring = usize::from(volume.interpolation() == Interpolation::Trilinear);
        let sigma = volume.sigma_t_samples();
        let mut values = vec![0.0f64; nb[0] * nb[1] * nb[2]];
        let mut uniform = vec![false; values.len()];
        for bk in 0..nb[2] {
            for bj in 0..nb[1] {
                for bi in 0..nb[0] {
                    let range = |b: usize, n: usize| {
                        (b * block).saturating_sub(ring)..((b + 1) * block + ring).min(n)
                    };
                    let (mut m, mut lo) = (0.0f64, f64::INFINITY);
                    for k in range(bk, g.n[2]) {
                        for j in range(bj, g.n[1]) {
                            for i in range(bi, g.n[0]) {
                                let s = sigma[g.index(i, j, k)];
                                m = m.max(s);
                                lo = lo.min(s);
                            }
                        }
                    }
                    let b = bi + nb[0] * (bj + nb[1] * bk);
                    values[b] = m;
                    uniform[b] = lo == m;
                }
            }
        }
        Self {
            block,
            nb,
            cell: block as f64 * g.dl,
            origin: g.origin,
            values,
            uniform,
        }
    }

    /// Block edge in voxels.
    pub fn block(&self) -> usize {
        self.block
    }

    /// Number of blocks per axis.
    pub fn blocks(&self) -> [usize; 3] {
        self.nb
    }

    /// The largest majorant.
    pub fn max(&self) -> f64 {
        self.values.iter().copied().fold(0.0, f64::max)
    }

    /// Walks the blocks crossed over [ta, tb] with their majorants and uniformity flags.
    #[inline]
    fn walk(
        &self,
        o: Vec3,
        d: Vec3,
        ta: f64,
        tb: f64,
        mut f: impl FnMut(f64, bool, f64, f64) -> bool,
    ) {
        let nb = self.nb;
        traverse(self.origin, self.cell, nb, o, d, ta, tb, |c, t0, t1| {
            let b = c[0] + nb[0] * (c[1] + nb[1] * c[2]);
            f(self.values[b], self.uniform[b], t0, t1)
        });
    }
}

/// A volume with its majorant grid: the free-flight sampler.
#[derive(Debug, Clone)]
pub struct Tracker {
    /// The medium.
    pub volume: Volume,
    /// Its majorants.
    pub majorant: Majorant,
}

impl Tracker {
    /// A tracker with blocks of `block³` voxels.
    /// A medium that is one uniform value everywhere gets a single global block, so that
    /// its rays skip the block walk altogether.
    pub fn new(volume: Volume, block: usize) -> Self {
        let mut majorant = Majorant::new(&volume, block);
        let first = majorant.values.first().copied();
        if majorant.values.len() > 1
            && majorant.uniform.iter().all(|&u| u)
            && majorant.values.iter().all(|&v| Some(v) == first)
        {
            majorant = Majorant::new(&volume, usize::MAX);
        }
        Self { volume, majorant }
    }

    /// Delta tracking along `o + t·d` (unit `d`) over [ta, tb] clipped to the box: the
    /// parameter of the first real collision, or `None` if the ray passes.
    #[inline]
    pub fn sample_collision(
        &self,
        o: Vec3,
        d: Vec3,
        ta: f64,
        tb: f64,
        rng: &mut Rng,
    ) -> Option<f64> {
        let (c0, c1) = self.volume.clip(o, d)?;
        let (ta, tb) = (ta.max(c0), tb.min(c1));
        if ta >= tb {
            return None;
        }
        // Remaining exponential optical depth; drawn lazily so that vacuum costs nothing.
        let mut left = -1.0;
        let mut hit = None;
        self.majorant.walk(o, d, ta, tb, |mu, uniform, t0, t1| {
            if mu <= 0.0 {
                return true;
            }
            if left < 0.0 {
                left = rng.exponential();
            }
            let mut t = t0;
            loop {
                let span = mu * (t1 - t);
                if left >= span {
                    left -= span;
                    return true;
                }
                t += left / mu;
                if uniform || rng.uniform() * mu < self.volume.sigma_t(at(o, d, t)) {
                    hit = Some(t);
                    return false;
                }
                left = rng.exponential();
            }
        });
        hit
    }

    /// Ratio-tracking estimate of the transmittance exp(−∫σt) along `o + t·d` over
    /// [ta, tb] clipped to the box (1 outside it).
    #[inline]
    pub fn transmittance(&self, o: Vec3, d: Vec3, ta: f64, tb: f64, rng: &mut Rng) -> f64 {
        let Some((c0, c1)) = self.volume.clip(o, d) else {
            return 1.0;
        };
        let (ta, tb) = (ta.max(c0), tb.min(c1));
        if ta >= tb {
            return 1.0;
        }
        let mut tr = 1.0;
        self.majorant.walk(o, d, ta, tb, |mu, uniform, t0, t1| {
            if mu <= 0.0 {
                return true;
            }
            if uniform {
                tr *= (-mu * (t1 - t0)).exp();
                return roulette(&mut tr, rng);
            }
            let mut t = t0;
            loop {
                t += rng.exponential() / mu;
                if t >= t1 {
                    return true;
                }
                tr *= 1.0 - self.volume.sigma_t(at(o, d, t)) / mu;
                if !roulette(&mut tr, rng) {
                    return false;
                }
            }
        });
        tr
    }
}

/// Russian roulette on a small transmittance estimate: below 10⁻² it survives with
/// probability ½ and is doubled (unbiased). Returns whether tracking goes on.
#[inline]
fn roulette(tr: &mut f64, rng: &mut Rng) -> bool {
    if *tr < RATIO_ROULETTE {
        if *tr <= 0.0 || rng.uniform() < 0.5 {
            *tr = 0.0;
            return false;
        }
        *tr *= 2.0;
    }
    true
}

#[cfg(test)]
mod tests {
    use super::super::estimators::{Estimate, run_paths, sidak_z};
    use super::super::math::normalize;
    use super::*;
    use solvers::{Grid, Medium};

    /// A heterogeneous grid with a dense blob, a thin haze and a vacuum layer.
    fn medium() -> Medium<f64> {
        let grid = Grid::new([20, 16, 12], 0.05).unwrap();
        let sigma = grid.sample(|p| {
            let r2 = (p[0] - 0.5).powi(2) + (p[1] - 0.4).powi(2) + (p[2] - 0.3).powi(2);
            if p[2] > 0.4 {
                0.0
            } else {
                0.5 + 40.0 * (-r2 / 0.02).exp() + 2.0 * (7.0 * p[0]).sin().abs()
            }
        });
        let n = grid.len();
        Medium::new(grid, sigma, vec![0.8; n], vec![0.0; n]).unwrap()
    }

    /// Within `zmax` standard errors, or to rounding where the estimate has no variance
    /// (ratio tracking through uniform blocks only is exact).
    fn agrees(e: &Estimate, exact: f64, zmax: f64) -> bool {
        (e.mean - exact).abs() <= zmax * e.stderr + 1e-12 * exact
    }

    fn rays() -> Vec<(Vec3, Vec3)> {
        vec![
            ([-0.1, 0.55, 0.22], [1.0, 0.0, 0.0]),
            ([-0.2, -0.1, 0.05], normalize([1.0, 0.9, 0.5])),
            ([0.9, 0.7, 0.55], normalize([-1.0, -0.6, -0.7])),
            ([0.5, 0.4, 0.3], normalize([0.2, -0.3, 0.9])),
        ]
    }

    /// Ratio tracking and the escape probability of delta tracking both estimate
    /// exp(−∫σt) on a heterogeneous grid, for both reconstructions and for block sizes
    /// 1, 4 and global; every estimate is within a Šidák 3σ-family band of the exact value.
    #[test]
    fn transmittance_estimators_match_exact_optical_depth() {
        let m = medium();
        let cases = [Interpolation::Nearest, Interpolation::Trilinear]
            .into_iter()
            .flat_map(|i| [1usize, 4, 1000].map(move |b| (i, b)))
            .collect::<Vec<_>>();
        let comparisons = cases.len() * rays().len() * 2;
        let zmax = sidak_z(comparisons, 0.0027);
        for (interp, block) in cases {
            let tr = Tracker::new(Volume::new(&m, interp).unwrap(), block);
            for (k, (o, d)) in rays().into_iter().enumerate() {
                let exact = (-tr.volume.optical_depth(o, d, 0.0, f64::INFINITY)).exp();
                let est = run_paths(40_000, 32, 2, |i, t| {
                    let mut rng = Rng::new(k as u64, i);
                    t[0] += tr.transmittance(o, d, 0.0, f64::INFINITY, &mut rng);
                    let mut rng = Rng::new(100 + k as u64, i);
                    if tr
                        .sample_collision(o, d, 0.0, f64::INFINITY, &mut rng)
                        .is_none()
                    {
                        t[1] += 1.0;
                    }
                })
                .unwrap();
                for (name, e) in ["ratio", "delta"].iter().zip(&est) {
                    assert!(
                        agrees(e, exact, zmax),
                        "{interp:?} block {block} ray {k} {name}: {e:?} vs {exact} (z = {})",
                        e.z(exact)
                    );
                }
            }
        }
    }

    /// Uniform blocks: in a homogeneous grid ratio tracking is the exact e^{−σt·ℓ} (no
    /// variance, no random numbers while above the roulette threshold), and in a grid that
    /// is half homogeneous, half noisy both estimators still match the exact optical depth.
    #[test]
    fn uniform_blocks_are_exact_and_unbiased() {
        let grid = Grid::new([16, 8, 8], 0.0625).unwrap();
        let n = grid.len();
        let homogeneous = Medium::new(grid, vec![1.5; n], vec![0.8; n], vec![0.0; n]).unwrap();
        let tr = Tracker::new(
            Volume::new(&homogeneous, Interpolation::Nearest).unwrap(),
            4,
        );
        assert!(tr.majorant.uniform.iter().all(|&u| u));
        let (o, d) = ([-0.5, 0.2, 0.3], normalize([1.0, 0.3, 0.1]));
        let exact = (-tr.volume.optical_depth(o, d, 0.0, f64::INFINITY)).exp();
        assert!(exact > RATIO_ROULETTE && exact < 0.5);
        let mut rng = Rng::new(4, 0);
        let before = rng.clone().next_u64();
        let t = tr.transmittance(o, d, 0.0, f64::INFINITY, &mut rng);
        assert!((t - exact).abs() < 1e-12 * exact, "{t} vs {exact}");
        assert_eq!(rng.next_u64(), before);

        let sigma = grid.sample(|p| {
            if p[0] < 0.5 {
                2.0
            } else {
                0.5 + 3.0 * (9.0 * p[1] + 5.0 * p[2]).sin().abs()
            }
        });
        let half = Medium::new(grid, sigma, vec![0.8; n], vec![0.0; n]).unwrap();
        for interp in [Interpolation::Nearest, Interpolation::Trilinear] {
            let tr = Tracker::new(Volume::new(&half, interp).unwrap(), 4);
            assert!(tr.majorant.uniform.iter().any(|&u| u));
            assert!(!tr.majorant.uniform.iter().all(|&u| u));
            let exact = (-tr.volume.optical_depth(o, d, 0.0, f64::INFINITY)).exp();
            let est = run_paths(40_000, 32, 2, |i, t| {
                let mut rng = Rng::new(21, i);
                t[0] += tr.transmittance(o, d, 0.0, f64::INFINITY, &mut rng);
                let mut rng = Rng::new(22, i);
                if tr
                    .sample_collision(o, d, 0.0, f64::INFINITY, &mut rng)
                    .is_none()
                {
                    t[1] += 1.0;
                }
            })
            .unwrap();
            let zmax = sidak_z(4, 0.0027);
            for e in &est {
                assert!(agrees(e, exact, zmax), "{interp:?}: {e:?} vs {exact}");
            }
        }
    }

    /// The collision-distance distribution of delta tracking: P(t_c ≤ s) = 1 − T(0, s) at
    /// several s along a ray through the blob, with per-voxel block majorants.
    #[test]
    fn collision_distances_follow_the_exact_distribution() {
        let m = medium();
        let tr = Tracker::new(Volume::new(&m, Interpolation::Nearest).unwrap(), 2);
        let (o, d) = rays()[0];
        let marks = [0.2, 0.45, 0.5, 0.55, 0.8];
        let est = run_paths(40_000, 32, marks.len(), |i, t| {
            let mut rng = Rng::new(9, i);
            let c = tr.sample_collision(o, d, 0.0, f64::INFINITY, &mut rng);
            for (k, &s) in marks.iter().enumerate() {
                if c.is_some_and(|c| c <= s) {
                    t[k] += 1.0;
                }
            }
        })
        .unwrap();
        let zmax = sidak_z(marks.len(), 0.0027);
        for (k, &s) in marks.iter().enumerate() {
            let exact = 1.0 - (-tr.volume.optical_depth(o, d, 0.0, s)).exp();
            assert!(
                est[k].z(exact).abs() < zmax,
                "s={s}: {:?} vs {exact}",
                est[k]
            );
        }
    }

    #[test]
    fn majorants_bound_the_medium_and_vacuum_costs_nothing() {
        let m = medium();
        for interp in [Interpolation::Nearest, Interpolation::Trilinear] {
            let v = Volume::new(&m, interp).unwrap();
            let maj = Majorant::new(&v, 4);
            // Sample many points; σt never exceeds the majorant of the block they lie in.
            let mut rng = Rng::new(3, 0);
            for _ in 0..20_000 {
                let p = [rng.uniform(), rng.uniform() * 0.8, rng.uniform() * 0.6];
                let b = p.map(|x| (x / (4.0 * 0.05)) as usize);
                let mu = maj.values[b[0] + maj.nb[0] * (b[1] + maj.nb[1] * b[2])];
                assert!(v.sigma_t(p) <= mu * (1.0 + 1e-12));
            }
            // With nearest lookups the top block layer (voxels 8..11 in z) is pure vacuum:
            // a ray through it draws no random numbers. (Trilinear blocks see voxel 7.)
            if interp == Interpolation::Nearest {
                let tr = Tracker::new(v, 4);
                let mut rng = Rng::new(1, 1);
                let before = rng.clone().next_u64();
                let o = [-1.0, 0.3, 0.5];
                assert_eq!(
                    tr.transmittance(o, [1.0, 0.0, 0.0], 0.0, 9.0, &mut rng),
                    1.0
                );
                assert_eq!(
                    tr.sample_collision(o, [1.0, 0.0, 0.0], 0.0, 9.0, &mut rng),
                    None
                );
                assert_eq!(rng.next_u64(), before);
            }
        }
    }
}
