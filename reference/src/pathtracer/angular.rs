//! Direction-binned track-length tally over probe regions: the angular radiance that POP's
//! Fig 12 polar plots show (spec pop.md §3, Fig 12 (a); issue 17 item 7).
//!
//! **Estimator.** The histories of [`current`](super::current::current) (same sources,
//! tracking, capture and roulette, same random streams). Each flight segment of weighted
//! length w·ℓ inside a voxel of probe p along ω adds w·ℓ to bin k of p, where
//! μ = ω·`axis` ∈ [μ_k, μ_{k+1}) with K equal bins of [−1, 1]. Divided by N·V_p·2πΔμ (V_p the
//! probe's volume) a bin is the probe-averaged radiance averaged over the band's solid angle
//! 2πΔμ (azimuth included): L̄_k = ∫_band L dω / (2πΔμ). Summed over the bins with their
//! solid angles it is the probe-averaged fluence, to rounding (`angular_sums_to_fluence`).
//!
//! **Errors.** Batch means per bin, as every tally of the path tracer; batches are combined
//! in batch order, so results are bit-identical for any thread count.

use super::TraceOptions;
use super::current::{Track, history};
use super::estimators::{BatchMeans, Estimate, batch_sizes, batch_starts, check_batches};
use super::fluence::PathSettings;
use super::world::{Sources, World};
use crate::ReferenceError;
use rayon::prelude::*;
use solvers::scene::Scene;
use std::f64::consts::PI;

/// Angular radiance per probe and μ bin.
#[derive(Debug, Clone, PartialEq)]
pub struct AngularTally {
    /// The bin edges μ_0 = −1 < … < μ_K = 1.
    pub edges: Vec<f64>,
    /// `[probe][bin]`: the probe- and band-averaged radiance L̄_k.
    pub radiance: Vec<Vec<Estimate>>,
}

/// Tallies the angular radiance about unit `axis` in `bins` equal μ bins over each probe
/// (a set of voxel indices of `scene`'s grid; probes must not share voxels). Typed errors:
/// no probe, an empty probe, a voxel index outside the grid or in two probes, `bins` = 0,
/// an axis that is not a unit vector, too few paths per batch.
pub fn angular(
    scene: &Scene,
    settings: &PathSettings,
    probes: &[Vec<usize>],
    axis: [f64; 3],
    bins: usize,
) -> Result<AngularTally, ReferenceError> {
    check_batches(settings.batches, settings.paths, "paths")?;
    let bad = |name: &'static str, value: f64, reason: &'static str| {
        Err(ReferenceError::BadParameter {
            name,
            value,
            reason,
        })
    };
    if bins == 0 {
        return bad("bins", 0.0, "at least one μ bin");
    }
    let len = axis.iter().map(|a| a * a).sum::<f64>().sqrt();
    if (len - 1.0).abs() > 1e-9 || len.is_nan() {
        return bad("axis", len, "must be a unit vector");
    }
    if probes.is_empty() {
        return bad("probes", 0.0, "at least one probe");
    }
    let options = TraceOptions::of(scene);
    let world = World::new(scene, &options)?;
    let sources = Sources::new(&world, scene)?;
    let grid = *world.volume().grid();
    let nv = grid.len();
    let mut owner = vec![usize::MAX; nv];
    for (p, voxels) in probes.iter().enumerate() {
        if voxels.is_empty() {
            return bad("probes", p as f64, "a probe needs at least one voxel");
        }
        for &v in voxels {
            if v >= nv {
                return bad("probes", v as f64, "voxel index outside the grid");
            }
            if owner[v] != usize::MAX {
                return bad("probes", v as f64, "a voxel belongs to two probes");
            }
            owner[v] = p;
        }
    }
    let np = probes.len();
    let sizes = batch_sizes(settings.paths, settings.batches);
    let starts = batch_starts(&sizes);
    let batches: Vec<(u64, Vec<f64>)> = (0..sizes.len())
        .into_par_iter()
        .map(|b| {
            let mut t = vec![0.0; np * bins];
            for i in starts[b]..starts[b] + sizes[b] {
                history(
                    &world,
                    &sources,
                    settings,
                    i,
                    |t: &mut Vec<f64>, event| {
                        if let Track::Segment { voxel, length, d } = event {
                            let p = owner[voxel];
                            if p != usize::MAX {
                                let mu = d[0] * axis[0] + d[1] * axis[1] + d[2] * axis[2];
                                let k = (((mu + 1.0) * 0.5 * bins as f64) as usize).min(bins - 1);
                                t[p * bins + k] += length;
                            }
                        }
                    },
                    &mut t,
                );
            }
            (sizes[b], t)
        })
        .collect();
    let mut means = BatchMeans::new(np * bins);
    for (n, t) in &batches {
        means.add(t, *n);
    }
    let est = means.finish();
    let dmu = 2.0 / bins as f64;
    let cell = grid.dl.powi(3);
    let radiance = (0..np)
        .map(|p| {
            let scale = 1.0 / (probes[p].len() as f64 * cell * 2.0 * PI * dmu);
            est[p * bins..(p + 1) * bins]
                .iter()
                .map(|e| Estimate {
                    mean: e.mean * scale,
                    stderr: e.stderr * scale,
                })
                .collect()
        })
        .collect();
    Ok(AngularTally {
        edges: (0..=bins).map(|k| -1.0 + k as f64 * dmu).collect(),
        radiance,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pathtracer::current::current;
    use solvers::scene::{Light, Phase, Sampler};
    use solvers::{Grid, Medium};

    fn cube(albedo: f64, g: f64) -> Scene {
        let grid = Grid::cube(8, 1.0).unwrap();
        Scene {
            medium: Medium::homogeneous(grid, 2.0, albedo).unwrap(),
            phase: Phase::HenyeyGreenstein { g },
            lights: vec![Light::directional([1.0, 0.0, 0.0], 1.0).unwrap()],
            camera: None,
            sampler: Sampler { spp: 1, seed: 1 },
            interpolation: Default::default(),
        }
    }

    fn probes(grid: &Grid) -> Vec<Vec<usize>> {
        [[1, 2], [5, 6]]
            .iter()
            .map(|xs| {
                let mut v = Vec::new();
                for &i in xs {
                    for j in 3..5 {
                        for k in 3..5 {
                            v.push(grid.index(i, j, k));
                        }
                    }
                }
                v
            })
            .collect()
    }

    /// Σ_k L̄_k 2πΔμ is the probe-mean fluence of the current tally on the same histories
    /// (same seed, same streams): to rounding, bin by bin of the sums.
    #[test]
    fn angular_sums_to_fluence() {
        let scene = cube(0.9, 0.7);
        let settings = PathSettings::new(20_000, 5);
        let grid = scene.medium.grid;
        let pr = probes(&grid);
        let a = angular(&scene, &settings, &pr, [1.0, 0.0, 0.0], 12).unwrap();
        let c = current(&scene, &settings).unwrap();
        for (p, voxels) in pr.iter().enumerate() {
            let dmu = 2.0 / 12.0;
            let sum: f64 = a.radiance[p].iter().map(|e| e.mean * 2.0 * PI * dmu).sum();
            let phi = c.sum_estimate(voxels, 1.0 / voxels.len() as f64).mean;
            assert!((sum / phi - 1.0).abs() < 1e-12, "probe {p}: {sum} vs {phi}");
        }
    }

    /// Albedo 0: only the uncollided beam, all of it in the μ = 1 bin, equal to the exact
    /// probe-mean e^{−σt x} over that bin's solid angle within 4 standard errors (the
    /// tracking is analog: each history flies to an exponential collision), and no other
    /// bin sees anything.
    #[test]
    fn uncollided_beam_lands_in_the_forward_bin() {
        let scene = cube(0.0, 0.0);
        let grid = scene.medium.grid;
        let pr = probes(&grid);
        let a = angular(
            &scene,
            &PathSettings::new(40_000, 2),
            &pr,
            [1.0, 0.0, 0.0],
            8,
        )
        .unwrap();
        for (p, xs) in [[1usize, 2], [5, 6]].iter().enumerate() {
            // Voxel average of e^{−2x} over x ∈ [i/8, (i+1)/8], averaged over the two columns.
            let avg = |i: usize| {
                let (x0, x1) = (i as f64 / 8.0, (i + 1) as f64 / 8.0);
                ((-2.0 * x0).exp() - (-2.0 * x1).exp()) / (2.0 * (x1 - x0))
            };
            let exact = (avg(xs[0]) + avg(xs[1])) / 2.0 / (2.0 * PI * 0.25);
            let last = a.radiance[p][7];
            let z = (last.mean - exact) / last.stderr;
            assert!(
                z.abs() < 4.0,
                "probe {p}: {} ± {} vs {exact}",
                last.mean,
                last.stderr
            );
            assert!(a.radiance[p][..7].iter().all(|e| e.mean == 0.0));
        }
    }

    /// Typed errors, no panic, on bad probes, bins and axes.
    #[test]
    fn bad_input_is_typed() {
        let scene = cube(0.5, 0.0);
        let s = PathSettings::new(1_000, 1);
        let x = [1.0, 0.0, 0.0];
        assert!(angular(&scene, &s, &[], x, 4).is_err());
        assert!(angular(&scene, &s, &[vec![]], x, 4).is_err());
        assert!(angular(&scene, &s, &[vec![1 << 20]], x, 4).is_err());
        assert!(angular(&scene, &s, &[vec![3], vec![3]], x, 4).is_err());
        assert!(angular(&scene, &s, &[vec![3]], x, 0).is_err());
        assert!(angular(&scene, &s, &[vec![3]], [1.0, 1.0, 0.0], 4).is_err());
    }
}
