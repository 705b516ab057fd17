//! Per-voxel track-length current J = Σ ℓ·ω next to the fluence φ = Σ ℓ, and the exit
//! fractions through the six faces of the box: the direction tally POP's mean cosine
//! ⟨μ⟩ = J·d/φ is measured against (spec pop.md Fig 12, issue 17).
//!
//! The sources, delta tracking, implicit capture and roulette are those of
//! [`fluence`](super::fluence()) (a separate history loop, so the fluence tally stays as it
//! is). Each flight segment of length ℓ in voxel v along ω adds w·ℓ to φ_v and w·ℓ·ω to J_v
//! (both ÷ N·Δl³: voxel averages in power per area). A particle that escapes adds its weight
//! to the face its last segment leaves the box through (÷ N·P: fractions of the emitted
//! power). A flight ending on a sphere light is not counted as an exit.
//!
//! **Errors.** Batch means per bin ([`Field`]); for ⟨μ⟩ over a set of voxels the ratio
//! Σ J·d / Σ φ has the linearised batch-means error of a ratio estimator
//! ([`CurrentTally::mean_cosine`]): with batch means a_b, b_b and r = ā/b̄,
//! s²(r) = Σ_b n_b (a_b − r b_b)² / ((B − 1) N b̄²).
//!
//! **Determinism.** Batches run in parallel, each sequentially; batch sums are kept and
//! combined in batch order, so every result is bit-identical for any thread count.

use super::TraceOptions;
use super::estimators::{Estimate, batch_sizes, batch_starts, check_batches};
use super::fluence::{Field, PathSettings, scatter};
use super::math::at;
use super::rng::Rng;
use super::world::{Event, Sources, World};
use crate::ReferenceError;
use rayon::prelude::*;
use solvers::Grid;
use solvers::scene::Scene;

/// The faces of the box, in the order of [`CurrentTally::exits`].
pub const FACES: [&str; 6] = ["-x", "+x", "-y", "+y", "-z", "+z"];

/// Fluence, current and exits of a bounded scene.
#[derive(Debug, Clone, PartialEq)]
pub struct CurrentTally {
    /// The scene's grid.
    pub grid: Grid,
    /// Voxel-averaged fluence φ (total: uncollided and collided).
    pub fluence: Field,
    /// Voxel-averaged current J_x, J_y, J_z.
    pub current: [Field; 3],
    /// Fraction of the emitted power leaving through each face ([`FACES`]).
    pub exits: [Estimate; 6],
    /// Total emitted power of the sources.
    pub source_power: f64,
    /// Paths per batch and each batch's sums per path (φ, J_x, J_y, J_z per voxel).
    batches: Vec<(u64, Vec<f64>)>,
}

impl CurrentTally {
    /// ⟨μ⟩ = Σ_v J_v·`axis` / Σ_v φ_v over `voxels` (unit `axis`), with the ratio
    /// estimator's batch-means standard error. NaN mean where φ sums to 0.
    pub fn mean_cosine(&self, voxels: &[usize], axis: [f64; 3]) -> Estimate {
        let nv = self.grid.len();
        let per_batch: Vec<(f64, f64, f64)> = self
            .batches
            .iter()
            .map(|(n, s)| {
                let (mut a, mut b) = (0.0, 0.0);
                for &v in voxels {
                    b += s[v];
                    a += (0..3).map(|c| s[(c + 1) * nv + v] * axis[c]).sum::<f64>();
                }
                (*n as f64, a / *n as f64, b / *n as f64)
            })
            .collect();
        let total: f64 = per_batch.iter().map(|p| p.0).sum();
        let a = per_batch.iter().map(|p| p.0 * p.1).sum::<f64>() / total;
        let b = per_batch.iter().map(|p| p.0 * p.2).sum::<f64>() / total;
        let r = a / b;
        let nb = per_batch.len().max(2) as f64;
        let s2 = per_batch
            .iter()
            .map(|&(n, ab, bb)| n * (ab - r * bb).powi(2))
            .sum::<f64>()
            / ((nb - 1.0) * total * b * b);
        Estimate {
            mean: r,
            stderr: s2.max(0.0).sqrt(),
        }
    }

    /// The volume mean of φ over all voxels, with its batch-means error.
    pub fn mean_fluence(&self) -> Estimate {
        let nv = self.grid.len();
        let all: Vec<usize> = (0..nv).collect();
        self.sum_estimate(&all, 1.0 / nv as f64)
    }

    /// `scale`·Σ_{v ∈ voxels} φ_v with its batch-means error.
    pub fn sum_estimate(&self, voxels: &[usize], scale: f64) -> Estimate {
        let per: Vec<(f64, f64)> = self
            .batches
            .iter()
            .map(|(n, s)| {
                let x: f64 = voxels.iter().map(|&v| s[v]).sum();
                (*n as f64, scale * x / *n as f64)
            })
            .collect();
        let total: f64 = per.iter().map(|p| p.0).sum();
        let mean = per.iter().map(|p| p.0 * p.1).sum::<f64>() / total;
        let nb = per.len().max(2) as f64;
        let s2 = per
            .iter()
            .map(|&(n, x)| n * (x - mean).powi(2))
            .sum::<f64>()
            / ((nb - 1.0) * total);
        Estimate {
            mean,
            stderr: s2.max(0.0).sqrt(),
        }
    }
}

/// The tally of `scene` with its own interpolation and default majorant blocks.
pub fn current(scene: &Scene, settings: &PathSettings) -> Result<CurrentTally, ReferenceError> {
    current_with(scene, settings, &TraceOptions::of(scene))
}

/// [`current`] with explicit tracing options.
pub fn current_with(
    scene: &Scene,
    settings: &PathSettings,
    options: &TraceOptions,
) -> Result<CurrentTally, ReferenceError> {
    check_batches(settings.batches, settings.paths, "paths")?;
    let world = World::new(scene, options)?;
    let sources = Sources::new(&world, scene)?;
    let grid = *world.volume().grid();
    let nv = grid.len();
    let bins = 4 * nv + 6;
    let sizes = batch_sizes(settings.paths, settings.batches);
    let starts = batch_starts(&sizes);
    let norm = 1.0 / grid.dl.powi(3);
    let p0 = sources.total;
    let batches: Vec<(u64, Vec<f64>)> = (0..sizes.len())
        .into_par_iter()
        .map(|b| {
            let mut t = vec![0.0; bins];
            for i in starts[b]..starts[b] + sizes[b] {
                trace(&world, &sources, settings, i, nv, &mut t);
            }
            for v in &mut t[..4 * nv] {
                *v *= norm;
            }
            if p0 > 0.0 {
                for v in &mut t[4 * nv..] {
                    *v /= p0;
                }
            }
            (sizes[b], t)
        })
        .collect();
    let total: u64 = sizes.iter().sum();
    let nb = batches.len().max(2) as f64;
    let estimate = |bin: usize| {
        let mean = batches.iter().map(|(_, s)| s[bin]).sum::<f64>() / total as f64;
        let s2 = batches
            .iter()
            .map(|(n, s)| *n as f64 * (s[bin] / *n as f64 - mean).powi(2))
            .sum::<f64>()
            / ((nb - 1.0) * total as f64);
        Estimate {
            mean,
            stderr: s2.max(0.0).sqrt(),
        }
    };
    let field = |slot: usize| {
        let e: Vec<Estimate> = (0..nv).map(|v| estimate(slot * nv + v)).collect();
        Field {
            mean: e.iter().map(|e| e.mean).collect(),
            stderr: e.iter().map(|e| e.stderr).collect(),
        }
    };
    Ok(CurrentTally {
        grid,
        fluence: field(0),
        current: [field(1), field(2), field(3)],
        exits: std::array::from_fn(|f| estimate(4 * nv + f)),
        source_power: p0,
        batches,
    })
}

/// The face (index into [`FACES`]) a ray from inside the box leaves through.
fn exit_face(o: [f64; 3], d: [f64; 3], lo: [f64; 3], hi: [f64; 3]) -> usize {
    let mut best = (f64::INFINITY, 0);
    for a in 0..3 {
        if d[a] != 0.0 {
            let (bound, face) = if d[a] > 0.0 {
                (hi[a], 2 * a + 1)
            } else {
                (lo[a], 2 * a)
            };
            let t = (bound - o[a]) / d[a];
            if t < best.0 {
                best = (t, face);
            }
        }
    }
    best.1
}

/// One history: φ and J per voxel into `t[..4nv]`, the exit face into `t[4nv..]`.
fn trace(
    world: &World,
    sources: &Sources,
    settings: &PathSettings,
    index: u64,
    nv: usize,
    t: &mut [f64],
) {
    history(
        world,
        sources,
        settings,
        index,
        |tally, event| match event {
            Track::Segment { voxel, length, d } => {
                tally_segment(tally, nv, voxel, length, d);
            }
            Track::Exit { face, weight } => tally[4 * nv + face] += weight,
        },
        t,
    );
}

fn tally_segment(t: &mut [f64], nv: usize, v: usize, l: f64, d: [f64; 3]) {
    t[v] += l;
    t[nv + v] += l * d[0];
    t[2 * nv + v] += l * d[1];
    t[3 * nv + v] += l * d[2];
}

/// What a history reports to its tally.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Track {
    /// A flight segment inside `voxel`: weight × length, along `d`.
    Segment {
        /// The voxel.
        voxel: usize,
        /// Weight times the segment's length.
        length: f64,
        /// Direction of flight.
        d: [f64; 3],
    },
    /// The particle left the box through `face` ([`FACES`]) with `weight`.
    Exit {
        /// Face index.
        face: usize,
        /// Weight.
        weight: f64,
    },
}

/// One particle history (the sources, delta tracking, implicit capture and roulette of
/// [`fluence`](super::fluence())), reporting every segment and the exit to `sink`.
pub(crate) fn history<S: ?Sized>(
    world: &World,
    sources: &Sources,
    settings: &PathSettings,
    index: u64,
    mut sink: impl FnMut(&mut S, Track),
    state: &mut S,
) {
    let mut rng = Rng::new(settings.seed, index);
    let Some((mut o, mut d)) = sources.sample(world, &mut rng) else {
        return;
    };
    let p0 = sources.total;
    let mut weight = p0;
    let mut depth = 0u32;
    let volume = world.volume();
    let (lo, hi) = volume.bounds();
    loop {
        let event = world.flight(o, d, &mut rng);
        let clip = volume.clip(o, d);
        if let Some((c0, c1)) = clip {
            let (ta, tb) = (c0.max(0.0), c1.min(event.t_end()));
            volume.voxels(o, d, ta, tb, |v, t0, t1| {
                sink(
                    state,
                    Track::Segment {
                        voxel: v,
                        length: weight * (t1 - t0),
                        d,
                    },
                );
            });
        }
        let Event::Collision(tc) = event else {
            if event == Event::Escape && clip.is_some_and(|(_, c1)| c1 > 0.0) {
                // Last seen inside the box (or entering it): it leaves through a face.
                let start = clip.map_or(o, |(c0, _)| if c0 > 0.0 { at(o, d, c0) } else { o });
                sink(
                    state,
                    Track::Exit {
                        face: exit_face(start, d, lo, hi),
                        weight,
                    },
                );
            }
            return;
        };
        let x = at(o, d, tc);
        if !scatter(
            world,
            settings,
            p0,
            x,
            &mut weight,
            &mut depth,
            &mut d,
            &mut rng,
        ) {
            return;
        }
        o = x;
    }
}
