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
//! **Refined blocks: bounded work in dense voxels.** One majorant per block makes a ray
//! through a block with one very dense voxel pay μ̄·ℓ tentative collisions over the whole
//! block (issue 14: an 8³ σt = 4 cube with one voxel of σt = 10⁶ took > 60 s for 16 spp at
//! 16×16, and σt = 3·10³⁸ never ended). A block is therefore *refined* when its majorant exceeds the
//! mean σt of its stencil by more than [`REFINE_OPTICAL_DEPTH`] per voxel edge,
//! (μ̄ − mean σt)·∆l > 1: a step of the inner DDA costs about one tentative collision, so
//! below that the coarse block is cheaper. A refined block is walked over the cells on
//! which the reconstruction is one polynomial piece, each with its exact maximum:
//! nearest, the voxels (σt constant, so delta tracking has no null collisions and ratio
//! tracking is the exact product of per-voxel transmittances); trilinear, the dual cells
//! between voxel centres, on which σt(t) along a ray is one cubic (a product of three
//! linear weights): its optical depth is integrated exactly by two-point Gauss–Legendre
//! (`cubic_depth`, lookups summing non-negative terms, so no cancellation at any
//! contrast), delta tracking becomes regular tracking (the collision is where the exact
//! optical depth reaches the exponential variate: safeguarded Newton on the monotone depth,
//! `invert_cubic_depth`) and ratio tracking the exact e^{−τ}. Nothing is stored per cell.
//! The tentative collisions of a path are then bounded by its real collisions plus the
//! cells it crosses, whatever the contrast, for both reconstructions
//! (`dense_voxels_cost_bounded_work`: at most one per call, and it is real, for a voxel of
//! 10³, 10⁶ and 3·10³⁸; coarse-only blocks need > 10³ per call at 10⁶). Before the exact
//! dual cells, trilinear refined blocks bounded each dual cell by its 8 corners and drew
//! null collisions where the interpolant was still small, ~(2μ̄∆l)^½ per call (measured 3.8
//! at 10³, 140 at 10⁶), and `render --method pt --spp 16` of the 3·10³⁸ cube at 16×16 did
//! not finish in 60 s. Smooth and sparse media keep their coarse blocks
//! ([`Majorant::refined_blocks`]).
//!
//! **Delta tracking** (Woodcock et al. 1965; Raab, Seibert, Keller 2006, FLD's \[RSK06\]):
//! tentative collisions are drawn from the homogeneous majorant process; each is real with
//! probability σt(x)/μ̄. Across a block boundary the remaining exponential optical depth
//! carries over (memorylessness), so one exponential variate is used per tentative collision.
//!
//! **Ratio tracking** (Novák, Selle, Jarosz 2014): the same tentative collisions, but the
//! estimate is multiplied by (1 − σt(x)/μ̄) at each instead of stopping; as in delta
//! tracking, the remaining exponential optical depth carries across block boundaries. Once the estimate
//! falls below 10⁻² it is continued with probability ½ and doubled (Russian roulette), which
//! keeps it unbiased and bounds the work in optically thick media.
//!
//! **Active box.** Rays are clipped to the smallest box outside which σt is 0 (the voxels
//! with σt > 0, one voxel wider for trilinear lookups), not to the grid: the vacuum around
//! a cloud or a sphere then costs no walk at all, and camera rays that miss the medium no
//! random number (`vacuum_around_the_medium_is_clipped_away`). On
//! `scenes/environment_sphere.toml` this cut the render time by 24 % (0.271 s → 0.206 s,
//! `reference/examples/pt_profile.rs`, 1024 spp).
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
use super::volume::{Interpolation, Volume, clip_box, traverse};

/// Default majorant block edge in voxels.
pub const DEFAULT_BLOCK: usize = 8;

const RATIO_ROULETTE: f64 = 1e-2;

/// Refine a block when (μ̄ − mean voxel σt)·∆l exceeds this optical depth (module docs).
pub const REFINE_OPTICAL_DEPTH: f64 = 1.0;

/// The majorant structure a tracker chose (automatically, module docs), as reported by
/// `render --method pt` (`plan.json`, `--explain`).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct MajorantReport {
    /// `global` (one majorant: a uniform medium or blocks ≥ the grid) or `blocks` (a grid
    /// of coarse blocks), with `+refined` when some blocks are walked cell by cell.
    pub structure: &'static str,
    /// Block edge in voxels.
    pub block: usize,
    /// Blocks per axis.
    pub blocks: [usize; 3],
    /// Blocks walked cell by cell ((μ̄ − mean σt)·∆l > `refine_optical_depth`).
    pub refined_blocks: usize,
    /// Blocks whose σt is constant over their stencil.
    pub uniform_blocks: usize,
    /// The largest majorant (inverse length).
    pub max: f64,
    /// The refinement threshold in optical depth per voxel edge ([`REFINE_OPTICAL_DEPTH`]).
    pub refine_optical_depth: f64,
}

/// Maximum σt per block of voxels; refined blocks are walked cell by cell.
#[derive(Debug, Clone)]
pub struct Majorant {
    block: usize,
    nb: [usize; 3],
    cell: f64,
    origin: Vec3,
    values: Vec<f64>,
    /// The box outside which σt is 0 (`None`: 0 everywhere): rays are clipped to it, so
    /// the vacuum around a medium costs no walk (module docs).
    active: Option<(Vec3, Vec3)>,
    /// Whether σt is constant over the block's stencil (see the module docs).
    uniform: Vec<bool>,
    /// Whether the block is walked cell by cell (module docs).
    refined: Vec<bool>,
}

impl Majorant {
    /// The majorant grid of `volume` with blocks of `block³` voxels (`block` ≥ 1; a block
    /// at least as large as the grid gives one global majorant), refined by the default
    /// rule ([`REFINE_OPTICAL_DEPTH`]).
    pub fn new(volume: &Volume, block: usize) -> Self {
        Self::with_refinement(volume, block, REFINE_OPTICAL_DEPTH)
    }

    /// As [`Majorant::new`] with refinement above `refine` optical depth per voxel edge
    /// (`f64::INFINITY`: coarse blocks only; 0: every non-uniform block).
    pub fn with_refinement(volume: &Volume, block: usize, refine: f64) -> Self {
        let g = volume.grid();
        let block = block.clamp(1, g.n.iter().copied().max().unwrap_or(1));
        let nb = g.n.map(|n| n.div_ceil(block));
        let ring = usize::from(volume.interpolation() == Interpolation::Trilinear);
        let sigma = volume.sigma_t_samples();
        let nblocks = nb[0] * nb[1] * nb[2];
        let mut values = vec![0.0f64; nblocks];
        let mut uniform = vec![false; nblocks];
        let mut refined = vec![false; nblocks];
        for bk in 0..nb[2] {
            for bj in 0..nb[1] {
                for bi in 0..nb[0] {
                    let lo = [bi * block, bj * block, bk * block];
                    let hi = [0, 1, 2].map(|a| (lo[a] + block).min(g.n[a]));
                    let range = |a: usize| lo[a].saturating_sub(ring)..(hi[a] + ring).min(g.n[a]);
                    let (mut m, mut l, mut sum, mut count) = (0.0f64, f64::INFINITY, 0.0, 0.0);
                    for k in range(2) {
                        for j in range(1) {
                            for i in range(0) {
                                let s = sigma[g.index(i, j, k)];
                                m = m.max(s);
                                l = l.min(s);
                                sum += s;
                                count += 1.0;
                            }
                        }
                    }
                    let b = bi + nb[0] * (bj + nb[1] * bk);
                    values[b] = m;
                    uniform[b] = l == m;
                    refined[b] = l < m && (m - sum / count) * g.dl > refine;
                }
            }
        }
        Self {
            block,
            nb,
            cell: block as f64 * g.dl,
            origin: g.origin,
            active: active_box(volume),
            values,
            uniform,
            refined,
        }
    }

    /// σt of a medium that is one uniform block (homogeneous): its flights and shadow rays
    /// skip the walk and its closure altogether.
    #[inline]
    fn homogeneous(&self) -> Option<f64> {
        (self.values.len() == 1 && self.uniform[0] && !self.refined[0]).then_some(self.values[0])
    }

    /// The part of the ray `o + t·d` inside the box where σt can be non-zero.
    #[inline]
    fn clip(&self, o: Vec3, d: Vec3) -> Option<(f64, f64)> {
        let (lo, hi) = self.active?;
        clip_box(lo, hi, o, d)
    }

    /// Block edge in voxels.
    pub fn block(&self) -> usize {
        self.block
    }

    /// Number of blocks per axis.
    pub fn blocks(&self) -> [usize; 3] {
        self.nb
    }

    /// Number of refined blocks (walked cell by cell; module docs).
    pub fn refined_blocks(&self) -> usize {
        self.refined.iter().filter(|&&r| r).count()
    }

    /// Number of uniform blocks (σt constant over the block's stencil: every tentative
    /// collision real, transmittance exact; module docs).
    pub fn uniform_blocks(&self) -> usize {
        self.uniform.iter().filter(|&&u| u).count()
    }

    /// What this majorant structure is, for reports (`render --explain`, `plan.json`).
    pub fn report(&self) -> MajorantReport {
        let total = self.values.len();
        let refined = self.refined_blocks();
        MajorantReport {
            structure: match (total == 1, refined > 0) {
                (true, false) => "global",
                (true, true) => "global+refined",
                (false, false) => "blocks",
                (false, true) => "blocks+refined",
            },
            block: self.block,
            blocks: self.nb,
            refined_blocks: refined,
            uniform_blocks: self.uniform_blocks(),
            max: self.max(),
            refine_optical_depth: REFINE_OPTICAL_DEPTH,
        }
    }

    /// The largest majorant.
    pub fn max(&self) -> f64 {
        self.values.iter().copied().fold(0.0, f64::max)
    }

    /// Walks the blocks crossed over [ta, tb] with their majorants and uniformity flags,
    /// and the cells of refined blocks with theirs ([`cells`]).
    #[inline]
    fn walk(
        &self,
        volume: &Volume,
        o: Vec3,
        d: Vec3,
        ta: f64,
        tb: f64,
        mut f: impl FnMut(Piece, f64, f64) -> bool,
    ) {
        let nb = self.nb;
        if self.values.len() == 1 {
            // One global block: no walk to set up (a homogeneous medium's every flight and
            // shadow ray; its 3D DDA setup was 9 divisions per ray).
            if self.refined[0] {
                cells(volume, o, d, ta, tb, &mut f);
            } else {
                f(
                    Piece::Bound {
                        mu: self.values[0],
                        uniform: self.uniform[0],
                    },
                    ta,
                    tb,
                );
            }
            return;
        }
        traverse(self.origin, self.cell, nb, o, d, ta, tb, |c, t0, t1| {
            let b = c[0] + nb[0] * (c[1] + nb[1] * c[2]);
            if self.refined[b] {
                cells(volume, o, d, t0, t1, &mut f)
            } else {
                f(
                    Piece::Bound {
                        mu: self.values[b],
                        uniform: self.uniform[b],
                    },
                    t0,
                    t1,
                )
            }
        });
    }
}

/// The smallest box outside which the reconstruction of σt is 0: the voxels with σt > 0,
/// widened by one voxel (within the grid) for trilinear lookups, whose stencil reaches that
/// far; `None` for a medium that is vacuum everywhere.
fn active_box(volume: &Volume) -> Option<(Vec3, Vec3)> {
    let g = volume.grid();
    let sigma = volume.sigma_t_samples();
    let (mut lo, mut hi) = ([usize::MAX; 3], [0usize; 3]);
    for k in 0..g.n[2] {
        for j in 0..g.n[1] {
            for i in 0..g.n[0] {
                if sigma[g.index(i, j, k)] > 0.0 {
                    for (a, c) in [i, j, k].into_iter().enumerate() {
                        lo[a] = lo[a].min(c);
                        hi[a] = hi[a].max(c);
                    }
                }
            }
        }
    }
    if lo[0] == usize::MAX {
        return None;
    }
    let ring = usize::from(volume.interpolation() == Interpolation::Trilinear);
    let (glo, ghi) = volume.bounds();
    let mut blo = [0.0; 3];
    let mut bhi = [0.0; 3];
    for a in 0..3 {
        let l = lo[a].saturating_sub(ring);
        let h = (hi[a] + 1 + ring).min(g.n[a]);
        // The grid's own faces where the box reaches them, so that clipping to it is
        // clipping to the grid there (no rounding of a recomputed face).
        blo[a] = if l == 0 {
            glo[a]
        } else {
            g.origin[a] + l as f64 * g.dl
        };
        bhi[a] = if h == g.n[a] {
            ghi[a]
        } else {
            g.origin[a] + h as f64 * g.dl
        };
    }
    Some((blo, bhi))
}

/// What the walk knows about σt on one segment of a ray.
#[derive(Debug, Clone, Copy)]
enum Piece {
    /// σt ≤ `mu` on the segment (a block's majorant); `uniform`: σt = `mu` there.
    Bound {
        /// The majorant.
        mu: f64,
        /// Whether σt equals the majorant everywhere on the segment.
        uniform: bool,
    },
    /// σt along the segment is one cubic polynomial of t (a trilinear dual cell of a
    /// refined block): its optical depth is integrated exactly ([`cubic_depth`]).
    Cubic,
}

/// 1/(2√3): the two Gauss–Legendre nodes on [0, 1] are ½ ∓ this.
const GAUSS_NODE: f64 = 0.288_675_134_594_812_9;

/// ∫σt over [t0, t0 + x] of a segment on which σt is one cubic in t (a trilinear dual cell):
/// two-point Gauss–Legendre, exact for cubics. Each lookup is a sum of non-negative terms,
/// so the result keeps its relative precision whatever the contrast (a monomial fit of the
/// cubic would not: with corners of 4 and 3·10³⁸ its coefficients cancel).
#[inline]
fn cubic_depth(volume: &Volume, o: Vec3, d: Vec3, t0: f64, x: f64) -> f64 {
    let m = t0 + 0.5 * x;
    0.5 * x
        * (volume.sigma_t(at(o, d, m - GAUSS_NODE * x))
            + volume.sigma_t(at(o, d, m + GAUSS_NODE * x)))
}

/// The x ∈ (0, h) where [`cubic_depth`] reaches `target` (0 ≤ target < cubic_depth(h) =
/// `total`): Newton steps on the increasing optical depth (its derivative is σt ≥ 0),
/// safeguarded by bisection, to 10⁻¹⁴ of the bracket or of the target.
fn invert_cubic_depth(
    volume: &Volume,
    o: Vec3,
    d: Vec3,
    t0: f64,
    h: f64,
    target: f64,
    total: f64,
) -> f64 {
    let (mut lo, mut hi) = (0.0, h);
    let mut x = (h * target / total).clamp(0.0, h);
    for _ in 0..128 {
        let g = cubic_depth(volume, o, d, t0, x) - target;
        if g.abs() <= 1e-14 * target {
            break;
        }
        if g > 0.0 {
            hi = x;
        } else {
            lo = x;
        }
        if hi - lo <= 1e-14 * hi {
            break;
        }
        let slope = volume.sigma_t(at(o, d, t0 + x));
        let newton = x - g / slope;
        x = if newton > lo && newton < hi {
            newton
        } else {
            0.5 * (lo + hi)
        };
    }
    x
}

/// Walks the cells on which the reconstruction is one polynomial piece, over [t0, t1];
/// returns whether `f` asked to go on. Nearest: the voxels, each with its constant σt
/// (always uniform). Trilinear: the dual cells between voxel centres (n + 1 per axis, the
/// outer ones half inside the box, where the reconstruction is clamped), on which σt(t) is
/// one cubic: vacuum and constant cells (all 8 corner samples equal) as bounds, the others
/// as [`Piece::Cubic`], integrated exactly.
#[inline]
fn cells(
    volume: &Volume,
    o: Vec3,
    d: Vec3,
    t0: f64,
    t1: f64,
    f: &mut impl FnMut(Piece, f64, f64) -> bool,
) -> bool {
    let g = volume.grid();
    let sigma = volume.sigma_t_samples();
    let mut go = true;
    match volume.interpolation() {
        Interpolation::Nearest => {
            traverse(g.origin, g.dl, g.n, o, d, t0, t1, |v, s0, s1| {
                let mu = sigma[g.index(v[0], v[1], v[2])];
                go = f(Piece::Bound { mu, uniform: true }, s0, s1);
                go
            });
        }
        Interpolation::Trilinear => {
            let origin = g.origin.map(|x| x - 0.5 * g.dl);
            let n = g.n.map(|n| n + 1);
            traverse(origin, g.dl, n, o, d, t0, t1, |c, s0, s1| {
                let lo = [0, 1, 2].map(|a| c[a].saturating_sub(1).min(g.n[a] - 1));
                let hi = [0, 1, 2].map(|a| c[a].min(g.n[a] - 1));
                let (mut m, mut l) = (0.0f64, f64::INFINITY);
                for k in [lo[2], hi[2]] {
                    for j in [lo[1], hi[1]] {
                        for i in [lo[0], hi[0]] {
                            let s = sigma[g.index(i, j, k)];
                            m = m.max(s);
                            l = l.min(s);
                        }
                    }
                }
                let piece = if l == m {
                    Piece::Bound {
                        mu: m,
                        uniform: true,
                    }
                } else {
                    Piece::Cubic
                };
                go = f(piece, s0, s1);
                go
            });
        }
    }
    go
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
        Self::with_refinement(volume, block, REFINE_OPTICAL_DEPTH)
    }

    /// As [`Tracker::new`] with the refinement threshold of
    /// [`Majorant::with_refinement`].
    pub fn with_refinement(volume: Volume, block: usize, refine: f64) -> Self {
        let mut majorant = Majorant::with_refinement(&volume, block, refine);
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
        self.sample_collision_counted(o, d, ta, tb, rng, &mut 0)
    }

    /// [`Tracker::sample_collision`], adding the number of tentative collisions drawn
    /// (real and null) to `tentative`.
    #[inline]
    pub fn sample_collision_counted(
        &self,
        o: Vec3,
        d: Vec3,
        ta: f64,
        tb: f64,
        rng: &mut Rng,
        tentative: &mut u64,
    ) -> Option<f64> {
        let (c0, c1) = self.majorant.clip(o, d)?;
        let (ta, tb) = (ta.max(c0), tb.min(c1));
        if ta >= tb {
            return None;
        }
        if let Some(mu) = self.majorant.homogeneous() {
            // The walk's one uniform piece, inlined (bit-identical to it).
            let left = rng.exponential();
            if left >= mu * (tb - ta) {
                return None;
            }
            *tentative += 1;
            return Some(ta + left * (1.0 / mu));
        }
        // Remaining exponential optical depth; drawn lazily so that vacuum costs nothing.
        let mut left = -1.0;
        let mut hit = None;
        let volume = &self.volume;
        self.majorant.walk(volume, o, d, ta, tb, |piece, t0, t1| {
            let (mu, uniform) = match piece {
                Piece::Bound { mu, uniform } => (mu, uniform),
                Piece::Cubic => {
                    // Regular tracking on the exact optical depth: no null collisions.
                    if left < 0.0 {
                        left = rng.exponential();
                    }
                    let h = t1 - t0;
                    let total = cubic_depth(volume, o, d, t0, h);
                    if left >= total {
                        left -= total;
                        return true;
                    }
                    *tentative += 1;
                    hit = Some(t0 + invert_cubic_depth(volume, o, d, t0, h, left, total));
                    return false;
                }
            };
            if mu <= 0.0 {
                return true;
            }
            if left < 0.0 {
                left = rng.exponential();
            }
            // One division per piece, not per tentative collision.
            let inv = 1.0 / mu;
            let mut t = t0;
            loop {
                let span = mu * (t1 - t);
                if left >= span {
                    left -= span;
                    return true;
                }
                t += left * inv;
                *tentative += 1;
                if uniform || rng.uniform() * mu < volume.sigma_t(at(o, d, t)) {
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
        self.transmittance_counted(o, d, ta, tb, rng, &mut 0)
    }

    /// [`Tracker::transmittance`], adding the number of tentative points drawn to
    /// `tentative` (uniform blocks and voxels draw none).
    #[inline]
    pub fn transmittance_counted(
        &self,
        o: Vec3,
        d: Vec3,
        ta: f64,
        tb: f64,
        rng: &mut Rng,
        tentative: &mut u64,
    ) -> f64 {
        let Some((c0, c1)) = self.majorant.clip(o, d) else {
            return 1.0;
        };
        let (ta, tb) = (ta.max(c0), tb.min(c1));
        if ta >= tb {
            return 1.0;
        }
        if let Some(mu) = self.majorant.homogeneous() {
            // The walk's one uniform piece, inlined (bit-identical to it).
            let mut tr = (-mu * (tb - ta)).exp();
            roulette(&mut tr, rng);
            return tr;
        }
        let mut tr = 1.0;
        // Remaining exponential optical depth to the next tentative point (drawn lazily).
        let mut left = -1.0;
        let volume = &self.volume;
        self.majorant.walk(volume, o, d, ta, tb, |piece, t0, t1| {
            let (mu, uniform) = match piece {
                Piece::Bound { mu, uniform } => (mu, uniform),
                Piece::Cubic => {
                    tr *= (-cubic_depth(volume, o, d, t0, t1 - t0)).exp();
                    return roulette(&mut tr, rng);
                }
            };
            if mu <= 0.0 {
                return true;
            }
            if uniform {
                tr *= (-mu * (t1 - t0)).exp();
                return roulette(&mut tr, rng);
            }
            // The remaining exponential optical depth carries over into the next piece
            // (memorylessness, as in delta tracking): one variate per tentative point, not
            // one more per piece crossed. One division per piece, not two per tentative
            // point (the ratio is clamped at 0: σt = μ̄ can round σt·(1/μ̄) above 1).
            if left < 0.0 {
                left = rng.exponential();
            }
            let inv = 1.0 / mu;
            let mut t = t0;
            loop {
                let span = mu * (t1 - t);
                if left >= span {
                    left -= span;
                    return true;
                }
                t += left * inv;
                *tentative += 1;
                tr *= (1.0 - volume.sigma_t(at(o, d, t)) * inv).max(0.0);
                if !roulette(&mut tr, rng) {
                    return false;
                }
                left = rng.exponential();
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

    /// Rays are clipped to the box outside which σt is 0: on the test medium (vacuum above
    /// z = 0.4) that box ends at z = 0.4 for nearest lookups and one voxel higher for
    /// trilinear ones, whose stencil reaches there. A ray through the vacuum layer draws no
    /// random number and sees transmittance exactly 1; at z = 0.41 it still sees the medium
    /// with trilinear lookups and not with nearest ones. An all-vacuum medium has no box.
    #[test]
    fn vacuum_around_the_medium_is_clipped_away() {
        let m = medium();
        let ray = |z: f64| ([-0.1, 0.3, z], [1.0, 0.0, 0.0]);
        for (interp, top, sees_041) in [
            (Interpolation::Nearest, 0.4, false),
            (Interpolation::Trilinear, 0.45, true),
        ] {
            let v = Volume::new(&m, interp).unwrap();
            let tr = Tracker::new(v.clone(), 4);
            let (lo, hi) = tr.majorant.active.unwrap();
            let (glo, ghi) = v.bounds();
            assert_eq!((lo, [hi[0], hi[1]]), (glo, [ghi[0], ghi[1]]), "{interp:?}");
            assert!((hi[2] - top).abs() < 1e-12, "{interp:?}: top {}", hi[2]);
            let (o, d) = ray(0.5);
            let mut rng = Rng::new(3, 0);
            let mut tentative = 0;
            assert_eq!(
                tr.sample_collision_counted(o, d, 0.0, f64::INFINITY, &mut rng, &mut tentative),
                None
            );
            assert_eq!(tr.transmittance(o, d, 0.0, f64::INFINITY, &mut rng), 1.0);
            assert_eq!(tentative, 0);
            assert_eq!(
                rng.next_u64(),
                Rng::new(3, 0).next_u64(),
                "{interp:?}: RNG used"
            );
            let (o, d) = ray(0.41);
            let exact = (-v.optical_depth(o, d, 0.0, f64::INFINITY)).exp();
            assert_eq!(exact < 1.0, sees_041, "{interp:?}: exact {exact}");
            let mut rng = Rng::new(4, 0);
            let t = tr.transmittance(o, d, 0.0, f64::INFINITY, &mut rng);
            assert_eq!(t < 1.0, sees_041, "{interp:?}: ratio tracking {t}");
        }
        let grid = Grid::new([4, 4, 4], 0.25).unwrap();
        let n = grid.len();
        let empty = Medium::new(grid, vec![0.0; n], vec![0.5; n], vec![0.0; n]).unwrap();
        let tr = Tracker::new(Volume::new(&empty, Interpolation::Nearest).unwrap(), 8);
        assert!(tr.majorant.active.is_none());
        let mut rng = Rng::new(5, 0);
        let (o, d) = ([0.5, 0.5, -1.0], [0.0, 0.0, 1.0]);
        assert_eq!(
            tr.sample_collision(o, d, 0.0, f64::INFINITY, &mut rng),
            None
        );
        assert_eq!(tr.transmittance(o, d, 0.0, f64::INFINITY, &mut rng), 1.0);
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

    /// Issue 14's dense-voxel cube: 8³ voxels of σt = 4 (∆l = 1/8), the voxel (4, 4, 4) of
    /// σt = `centre`.
    fn dense_cube(centre: f64) -> Medium<f64> {
        let grid = Grid::new([8, 8, 8], 0.125).unwrap();
        let mut sigma = vec![4.0; grid.len()];
        sigma[grid.index(4, 4, 4)] = centre;
        let n = grid.len();
        Medium::new(grid, sigma, vec![0.9; n], vec![0.0; n]).unwrap()
    }

    /// The structure `render --explain` and `plan.json` report is the one the tracker
    /// chose: a uniform medium collapses to one global block; a smooth one keeps coarse
    /// blocks; a dense voxel refines its block (one block of 8³ here, and one of the eight
    /// 4³ blocks).
    #[test]
    fn majorant_report_says_what_was_chosen() {
        let uniform = Medium::homogeneous(Grid::new([16, 8, 8], 0.1).unwrap(), 3.0, 0.5).unwrap();
        let r = Tracker::new(Volume::new(&uniform, Interpolation::Nearest).unwrap(), 4)
            .majorant
            .report();
        assert_eq!((r.structure, r.refined_blocks, r.max), ("global", 0, 3.0));
        let dense = dense_cube(1e6);
        for (block, structure, blocks) in [(8, "global+refined", 1), (4, "blocks+refined", 8)] {
            let r = Tracker::new(Volume::new(&dense, Interpolation::Nearest).unwrap(), block)
                .majorant
                .report();
            assert_eq!(r.structure, structure);
            assert_eq!(r.blocks.iter().product::<usize>(), blocks);
            assert_eq!((r.refined_blocks, r.max), (1, 1e6));
            assert_eq!(r.uniform_blocks, blocks - 1);
        }
        // A gentle ramp (σt·∆l rises by 0.05 per voxel): coarse blocks, none refined.
        let g = Grid::new([16, 16, 16], 0.0625).unwrap();
        let ramp = Medium::new(
            g,
            g.sample(|p| 1.0 + 12.8 * p[0]),
            vec![0.5; g.len()],
            vec![0.0; g.len()],
        )
        .unwrap();
        let r = Tracker::new(Volume::new(&ramp, Interpolation::Trilinear).unwrap(), 8)
            .majorant
            .report();
        assert_eq!((r.structure, r.refined_blocks), ("blocks", 0));
    }

    /// Rays from a sphere of radius 2 around the cube towards random points of the 3³
    /// voxels around the dense one.
    fn dense_rays(count: u64) -> Vec<(Vec3, Vec3)> {
        (0..count)
            .map(|i| {
                let mut rng = Rng::new(77, i);
                let z: f64 = 2.0 * rng.uniform() - 1.0;
                let phi = std::f64::consts::TAU * rng.uniform();
                let r = (1.0 - z * z).sqrt();
                let o = [
                    0.5 + 2.0 * r * phi.cos(),
                    0.5 + 2.0 * r * phi.sin(),
                    0.5 + 2.0 * z,
                ];
                let target = [0, 1, 2].map(|_| 0.4375 + 0.375 * rng.uniform());
                let d = normalize([0, 1, 2].map(|a| target[a] - o[a]));
                (o, d)
            })
            .collect()
    }

    /// Bounded work whatever the contrast (module docs, "Refined blocks"). In the refined
    /// block, nearest cells are uniform and trilinear dual cells are integrated exactly, so
    /// delta tracking draws at most one tentative collision per call (it is real) and ratio
    /// tracking none, for σt up to 3·10³⁸ in one voxel, with both reconstructions; the
    /// transmittance is then the exact e^{−τ}. The coarse-only majorant needs ≥ 10³
    /// tentative collisions per call at 10⁶ (what the refinement buys).
    #[test]
    fn dense_voxels_cost_bounded_work() {
        let rays = dense_rays(4000);
        for interp in [Interpolation::Nearest, Interpolation::Trilinear] {
            for centre in [1e3, 1e6, 3e38] {
                let m = dense_cube(centre);
                let v = Volume::new(&m, interp).unwrap();
                let tr = Tracker::new(v.clone(), DEFAULT_BLOCK);
                assert_eq!(tr.majorant.refined_blocks(), 1, "{interp:?} {centre}");
                let mut hits = 0;
                for (k, &(o, d)) in rays.iter().enumerate() {
                    let mut rng = Rng::new(5, k as u64);
                    let (mut td, mut tt) = (0u64, 0u64);
                    let hit =
                        tr.sample_collision_counted(o, d, 0.0, f64::INFINITY, &mut rng, &mut td);
                    assert!(
                        td <= 1 && (td == 1) == hit.is_some(),
                        "{interp:?} {centre}: {td} {hit:?}"
                    );
                    hits += usize::from(hit.is_some());
                    let t = tr.transmittance_counted(o, d, 0.0, f64::INFINITY, &mut rng, &mut tt);
                    assert_eq!(tt, 0, "{interp:?} {centre}");
                    // Exact pieces only: the exact e^{−τ}, unless the roulette (below 10⁻², on
                    // a decreasing product) took over.
                    let exact = (-tr.volume.optical_depth(o, d, 0.0, f64::INFINITY)).exp();
                    if exact > RATIO_ROULETTE {
                        assert!(
                            (t - exact).abs() <= 1e-12 * exact,
                            "{interp:?} {centre}: {t} vs {exact}"
                        );
                    } else {
                        assert!(
                            (0.0..=2.0 * RATIO_ROULETTE).contains(&t),
                            "{interp:?} {centre}: {t}"
                        );
                    }
                }
                // The rays aim at the dense voxel's neighbourhood: most of them collide.
                assert!(hits > rays.len() / 2, "{interp:?} {centre}: {hits} hits");
                if centre == 1e6 {
                    let coarse = Tracker {
                        volume: v.clone(),
                        majorant: Majorant::with_refinement(&v, DEFAULT_BLOCK, f64::INFINITY),
                    };
                    let mut coarse_sum = 0u64;
                    for (k, &(o, d)) in rays.iter().take(200).enumerate() {
                        let mut rng = Rng::new(6, k as u64);
                        coarse.sample_collision_counted(
                            o,
                            d,
                            0.0,
                            f64::INFINITY,
                            &mut rng,
                            &mut coarse_sum,
                        );
                    }
                    assert!(coarse_sum as f64 / 200.0 > 1e3, "coarse {coarse_sum}");
                }
            }
        }
    }

    /// Every non-uniform trilinear block refined (threshold 0) on the heterogeneous test
    /// medium: the exact dual-cell walk gives collision distances distributed as
    /// 1 − T(0, s) (within a Šidák 3σ-family band) and the exact transmittance (no variance).
    #[test]
    fn exact_trilinear_cells_follow_the_exact_distribution() {
        let m = medium();
        let v = Volume::new(&m, Interpolation::Trilinear).unwrap();
        let tr = Tracker {
            volume: v.clone(),
            majorant: Majorant::with_refinement(&v, 4, 0.0),
        };
        assert!(tr.majorant.refined_blocks() > 0);
        let marks = [0.2, 0.45, 0.5, 0.55, 0.8];
        let zmax = sidak_z(rays().len() * marks.len(), 0.0027);
        for (r, (o, d)) in rays().into_iter().enumerate() {
            let exact_t = (-tr.volume.optical_depth(o, d, 0.0, f64::INFINITY)).exp();
            let mut rng = Rng::new(40, r as u64);
            let t = tr.transmittance(o, d, 0.0, f64::INFINITY, &mut rng);
            if exact_t > RATIO_ROULETTE {
                assert!(
                    (t - exact_t).abs() <= 1e-12 * exact_t,
                    "ray {r}: {t} vs {exact_t}"
                );
            }
            let est = run_paths(40_000, 32, marks.len(), |i, t| {
                let mut rng = Rng::new(41 + r as u64, i);
                let c = tr.sample_collision(o, d, 0.0, f64::INFINITY, &mut rng);
                for (k, &s) in marks.iter().enumerate() {
                    if c.is_some_and(|c| c <= s) {
                        t[k] += 1.0;
                    }
                }
            })
            .unwrap();
            for (k, &s) in marks.iter().enumerate() {
                let exact = 1.0 - (-tr.volume.optical_depth(o, d, 0.0, s)).exp();
                assert!(
                    agrees(&est[k], exact, zmax),
                    "ray {r} s={s}: {:?} vs {exact}",
                    est[k]
                );
            }
        }
    }

    /// The refined walk stays exact: in the dense cube (σt = 10³ in one voxel) the
    /// collision-distance distribution of delta tracking and the ratio-tracking
    /// transmittance match 1 − T(0, s) and T from the exact optical depth, nearest and
    /// trilinear, within a Šidák 3σ-family band.
    #[test]
    fn refined_blocks_track_the_exact_optical_depth() {
        let m = dense_cube(1e3);
        let marks = [0.4, 0.6, 0.75, 0.9, 1.2];
        let zmax = sidak_z(2 * (marks.len() + 1), 0.0027);
        for interp in [Interpolation::Nearest, Interpolation::Trilinear] {
            let tr = Tracker::new(Volume::new(&m, interp).unwrap(), DEFAULT_BLOCK);
            assert_eq!(tr.majorant.refined_blocks(), 1);
            // Diagonal rays in a z plane that graze the dense voxel's corner (nearest) or its
            // trilinear support, so that it adds to τ and T is neither 0 nor 1.
            let (o, d) = match interp {
                Interpolation::Nearest => ([-0.2, -0.079, 0.56], normalize([1.0, 1.0, 0.0])),
                Interpolation::Trilinear => ([-0.2, 0.03, 0.5625], normalize([1.0, 1.0, 0.0])),
            };
            let through = tr.volume.optical_depth(o, d, 0.0, f64::INFINITY);
            let plain = Volume::new(&dense_cube(4.0), interp)
                .unwrap()
                .optical_depth(o, d, 0.0, f64::INFINITY);
            assert!(
                through - plain > 0.05 && through < 15.0,
                "{interp:?}: τ = {through}, {plain} without the dense voxel"
            );
            let est = run_paths(40_000, 32, marks.len() + 1, |i, t| {
                let mut rng = Rng::new(31, i);
                let c = tr.sample_collision(o, d, 0.0, f64::INFINITY, &mut rng);
                for (k, &s) in marks.iter().enumerate() {
                    if c.is_some_and(|c| c <= s) {
                        t[k] += 1.0;
                    }
                }
                t[marks.len()] += tr.transmittance(o, d, 0.0, f64::INFINITY, &mut rng);
            })
            .unwrap();
            for (k, &s) in marks.iter().enumerate() {
                let exact = 1.0 - (-tr.volume.optical_depth(o, d, 0.0, s)).exp();
                assert!(
                    agrees(&est[k], exact, zmax),
                    "{interp:?} s={s}: {:?} vs {exact}",
                    est[k]
                );
            }
            let exact = (-tr.volume.optical_depth(o, d, 0.0, f64::INFINITY)).exp();
            assert!(
                agrees(&est[marks.len()], exact, zmax),
                "{interp:?} T: {:?} vs {exact}",
                est[marks.len()]
            );
        }
    }
}
