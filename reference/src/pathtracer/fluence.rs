//! Per-voxel fluence of a bounded scene by the track-length estimator.
//!
//! Particles leave the scene's sources — every light and the volume emission — chosen in
//! proportion to emitted power, each starting with the total power P as its weight:
//! * point light: at its position, isotropic;
//! * directional light: on the box faces it illuminates, with probability proportional to
//!   each face's projected area, along the beam (power E·Σ|d·n|A);
//! * environment: uniformly on the box surface, cosine-distributed inwards (power πL·A);
//! * sphere light: uniformly on the sphere, cosine-distributed outwards (power πL·4πR²);
//! * emission: in a voxel chosen ∝ j·Δl³, uniformly inside it, isotropic.
//!
//! External light blocked by a sphere before reaching the box is lost, as it would be.
//! Particles are tracked with delta tracking; at each real collision the weight is
//! multiplied by the albedo (implicit capture, Russian roulette below 0.1·P). Each flight
//! segment adds weight × (length inside voxel v) to voxel v; dividing by N·Δl³ gives the
//! voxel-averaged fluence φ_v = (1/V)∫_v φ dV in power per area — the quantity a grid solver
//! computes for the same sources (for a lone unit-power source, φ per unit power).
//! Segments before the first real scattering are *uncollided*, later ones *collided*.
//!
//! Batches run in parallel, each one sequentially into its own grid, and are merged in
//! batch order: results are bit-identical for any thread count.

use super::TraceOptions;
use super::estimators::{BatchMeans, batch_sizes, batch_starts, check_batches};
use super::math::{Vec3, at};
use super::phase::sample_dir;
use super::rng::Rng;
use super::world::{Event, Sources, World};
use crate::ReferenceError;
use rayon::prelude::*;
use solvers::Grid;
use solvers::scene::Scene;

/// Monte Carlo settings of the particle tallies (fluence, shells, slab).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PathSettings {
    /// Number of particle paths, ≥ `batches`.
    pub paths: u64,
    /// Seed of every random stream (path i uses stream (seed, i)).
    pub seed: u64,
    /// Batches for the standard errors, ≥ [`MIN_BATCHES`](super::estimators::MIN_BATCHES).
    pub batches: u32,
    /// Most scattering events per path (`None`: unlimited, unbiased).
    pub max_depth: Option<u32>,
}

impl PathSettings {
    /// `paths` paths in 16 batches, unlimited depth.
    pub fn new(paths: u64, seed: u64) -> Self {
        Self {
            paths,
            seed,
            batches: 16,
            max_depth: None,
        }
    }
}

/// A per-voxel field with standard errors.
#[derive(Debug, Clone, PartialEq)]
pub struct Field {
    /// Mean per voxel (x fastest, like every field of the project).
    pub mean: Vec<f64>,
    /// Standard error per voxel.
    pub stderr: Vec<f64>,
}

/// Voxel-averaged fluence φ of a scene.
#[derive(Debug, Clone, PartialEq)]
pub struct Fluence {
    /// The grid of the scene.
    pub grid: Grid,
    /// Total fluence.
    pub total: Field,
    /// Light that has not scattered.
    pub uncollided: Field,
    /// Light that has scattered at least once.
    pub collided: Field,
    /// Total emitted power of the sources (the weight of each particle).
    pub source_power: f64,
}

const ROULETTE: f64 = 0.1;

/// The track-length fluence of `scene` (the scene's interpolation, 8³ majorant blocks).
pub fn fluence(scene: &Scene, settings: &PathSettings) -> Result<Fluence, ReferenceError> {
    fluence_with(scene, settings, &TraceOptions::of(scene))
}

/// [`fluence`] with explicit tracing options. Volume emission as a source requires
/// [`Interpolation::Nearest`](super::Interpolation::Nearest).
pub fn fluence_with(
    scene: &Scene,
    settings: &PathSettings,
    options: &TraceOptions,
) -> Result<Fluence, ReferenceError> {
    check_batches(settings.batches, settings.paths, "paths")?;
    let world = World::new(scene, options)?;
    let sources = Sources::new(&world, scene)?;
    let grid = *world.volume().grid();
    let nv = grid.len();
    let sizes = batch_sizes(settings.paths, settings.batches);
    let starts = batch_starts(&sizes);
    let (mut unc, mut col, mut tot) = (
        BatchMeans::new(nv),
        BatchMeans::new(nv),
        BatchMeans::new(nv),
    );
    let group = rayon::current_num_threads().max(1);
    let norm = 1.0 / grid.dl.powi(3);
    for first in (0..sizes.len()).step_by(group) {
        let last = (first + group).min(sizes.len());
        let grids: Vec<(Vec<f64>, Vec<f64>)> = (first..last)
            .into_par_iter()
            .map(|b| {
                let mut g = (vec![0.0; nv], vec![0.0; nv]);
                for i in starts[b]..starts[b] + sizes[b] {
                    trace(&world, &sources, settings, i, &mut g.0, &mut g.1);
                }
                g
            })
            .collect();
        for (b, (mut u, mut c)) in (first..last).zip(grids) {
            u.iter_mut().for_each(|v| *v *= norm);
            c.iter_mut().for_each(|v| *v *= norm);
            unc.add(&u, sizes[b]);
            col.add(&c, sizes[b]);
            for (x, y) in u.iter_mut().zip(&c) {
                *x += y;
            }
            tot.add(&u, sizes[b]);
        }
    }
    let field = |bm: &BatchMeans| {
        let e = bm.finish();
        Field {
            mean: e.iter().map(|e| e.mean).collect(),
            stderr: e.iter().map(|e| e.stderr).collect(),
        }
    };
    Ok(Fluence {
        grid,
        total: field(&tot),
        uncollided: field(&unc),
        collided: field(&col),
        source_power: sources.total,
    })
}

/// One particle history, adding weighted track lengths to `unc`/`col`.
fn trace(
    world: &World,
    sources: &Sources,
    settings: &PathSettings,
    index: u64,
    unc: &mut [f64],
    col: &mut [f64],
) {
    let mut rng = Rng::new(settings.seed, index);
    let Some((mut o, mut d)) = sources.sample(world, &mut rng) else {
        return;
    };
    let p0 = sources.total;
    let mut weight = p0;
    let mut depth = 0u32;
    let volume = world.volume();
    loop {
        let event = world.flight(o, d, &mut rng);
        if let Some((c0, c1)) = volume.clip(o, d) {
            let (ta, tb) = (c0.max(0.0), c1.min(event.t_end()));
            let tally = if depth == 0 { &mut *unc } else { &mut *col };
            volume.voxels(o, d, ta, tb, |v, t0, t1| tally[v] += weight * (t1 - t0));
        }
        let Event::Collision(t) = event else {
            return;
        };
        let x = at(o, d, t);
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

/// A real collision at `x` of a particle history that started with weight `p0`: the depth
/// cap, the albedo, Russian roulette below `ROULETTE`·p0 and a phase-sampled new direction
/// `d` (the fluence and current tallies share it). Returns false when the history ends.
#[allow(clippy::too_many_arguments)]
#[inline]
pub(crate) fn scatter(
    world: &World,
    settings: &PathSettings,
    p0: f64,
    x: Vec3,
    weight: &mut f64,
    depth: &mut u32,
    d: &mut Vec3,
    rng: &mut Rng,
) -> bool {
    if settings.max_depth.is_some_and(|m| *depth >= m) {
        return false;
    }
    *weight *= world.volume().albedo(x);
    if *weight <= 0.0 {
        return false;
    }
    if *weight < ROULETTE * p0 {
        if rng.uniform() * ROULETTE * p0 >= *weight {
            return false;
        }
        *weight = ROULETTE * p0;
    }
    *depth += 1;
    *d = sample_dir(&world.phase, *d, rng.uniform(), rng.uniform());
    true
}
