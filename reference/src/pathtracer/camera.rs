//! Camera images: radiance per pixel with batch-means error bars.
//!
//! **Camera model** (`solvers::scene::Camera`, rays from
//! `solvers::pipeline::geometry::CameraRays`, shared with the grid pipeline so that images
//! line up pixel for pixel): forward f = normalize(target − eye),
//! right r = normalize(f × up), image up u = r × f. Pixel (x, y) with x to the right and y
//! downwards, (0, 0) top-left, stored row by row. A sample at pixel position
//! (x + ξ₁, y + ξ₂) (box filter: uniform over the pixel's area) maps to image-plane
//! coordinates sx = 2(x + ξ₁)/W − 1 ∈ [−1, 1] (left to right) and
//! sy = 1 − 2(y + ξ₂)/H (top to bottom).
//! * Perspective: origin `eye`, direction ∝ f + sx·tan(fov_y/2)·(W/H)·r + sy·tan(fov_y/2)·u
//!   (`fov_y_degrees` is the full vertical field of view).
//! * Orthographic: direction f, origin `eye + sx·(w/2)·r + sy·(w/2)(H/W)·u` with `width` w.
//!
//! **Estimator.** Delta tracking from the camera; at every real collision the path weight is
//! multiplied by the albedo (implicit capture, with Russian roulette below 0.1 — survival
//! probability w/0.1) and a new direction is drawn from the phase function. Light enters as:
//! * point, directional and sphere lights: next-event estimation at every scattering vertex
//!   (shadow rays by ratio tracking; spheres sampled uniformly over their subtended cone);
//!   phase-sampled rays that reach a sphere end there without scoring, so nothing is counted
//!   twice; a sphere seen directly by the camera scores its radiance (times the path weight,
//!   which carries the transmittance through delta tracking);
//! * environment light: scored when the path escapes (including straight from the camera,
//!   unless `camera.hide_background`, which also hides sphere lights seen directly: both
//!   are Mitsuba's `hide_emitters`);
//! * volume emission j: ∫ j/4π dt along every flight segment up to its end (a track-length
//!   estimator, exact per segment for both reconstructions — see `Volume::integrate`).
//!
//! [`Contributions`] select scattering orders and emitters: `Contributions::up_to(k)` keeps
//! light that scattered at most k times (k = 0: emission, environment and spheres seen
//! directly through the medium only), which is Mitsuba's `max_depth` minus one;
//! `Contributions::all()` is unbiased (Russian roulette ends paths). A path stops as soon as
//! no later vertex can contribute.
//!
//! The pixel value is the radiance averaged over the pixel area; its standard error comes from
//! `batches` batch means of the pixel's `spp` samples. Sample s of pixel p (row-major index)
//! uses the random stream `(seed, p·spp + s)`.

use super::TraceOptions;
use super::contributions::Contributions;
use super::estimators::check_batches;
use super::math::{Vec3, at};
use super::phase::sample_dir;
use super::rng::{Rng, Streams};
use super::shard::{BatchSums, Shard};
use super::world::{Event, World};
use crate::ReferenceError;
use rayon::prelude::*;
use solvers::pipeline::geometry::CameraRays;
use solvers::scene::Scene;
use std::f64::consts::PI;

/// Settings of an image render.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RenderSettings {
    /// Samples (paths) per pixel, ≥ `batches`.
    pub spp: u32,
    /// Seed of every random stream.
    pub seed: u64,
    /// Batches for the standard error, ≥ [`MIN_BATCHES`](super::estimators::MIN_BATCHES).
    pub batches: u32,
    /// Which scattering orders and emitters are kept (default: all).
    pub contributions: Contributions,
}

/// A rendered image: radiance per pixel and its standard error.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    /// Pixels per row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Mean radiance per pixel, row-major, top-left first.
    pub mean: Vec<f64>,
    /// Standard error of each pixel's mean.
    pub stderr: Vec<f64>,
}

/// Renders `scene` through `scene.camera` with the scene's voxel interpolation
/// (`scene.interpolation`, nearest by default) and majorant blocks of 8³. Samples and seed come from `settings`
/// (`scene.sampler` is not consulted). Fails with [`ReferenceError::NoCamera`] without a
/// camera, [`ReferenceError::TooFewBatches`] below 16 batches, and
/// [`ReferenceError::Scene`] for an invalid scene.
pub fn render_image(scene: &Scene, settings: &RenderSettings) -> Result<Image, ReferenceError> {
    render_image_with(scene, settings, &TraceOptions::of(scene))
}

/// [`render_image`] with explicit tracing options (interpolation, majorant block size).
pub fn render_image_with(
    scene: &Scene,
    settings: &RenderSettings,
    options: &TraceOptions,
) -> Result<Image, ReferenceError> {
    let sums = render_image_part(scene, settings, options, Shard::WHOLE)?;
    let camera = scene.camera.ok_or(ReferenceError::NoCamera)?;
    let [width, height] = camera.resolution;
    Image::from_sums(width, height, &sums)
}

/// [`render_image_with`] for `shard`'s batches: per batch, each pixel's sum of radiance
/// samples (one bin per pixel, row-major), the bits the unsharded render sums.
pub fn render_image_part(
    scene: &Scene,
    settings: &RenderSettings,
    options: &TraceOptions,
    shard: Shard,
) -> Result<BatchSums, ReferenceError> {
    let camera = scene.camera.ok_or(ReferenceError::NoCamera)?;
    check_batches(settings.batches, settings.spp as u64, "spp")?;
    settings.contributions.validate()?;
    let world = World::new(scene, options)?;
    let rays = CameraRays::new(&camera);
    let [width, height] = camera.resolution;
    let pixels = width * height;
    let spp = settings.spp as u64;
    let mut out = BatchSums::zeroed(spp, settings.batches, pixels, shard)?;
    let ranges = out.sample_ranges();
    let nb = ranges.len();
    // Pixel-major while rendering (rows in parallel), batch-major in the result.
    let streams = Streams::new(settings.seed);
    let mut by_pixel = vec![0.0; pixels * nb];
    by_pixel
        .par_chunks_mut(width * nb)
        .enumerate()
        .for_each(|(y, row)| {
            for x in 0..width {
                let pixel = (y * width + x) as u64;
                for (k, r) in ranges.iter().enumerate() {
                    let mut sum = 0.0;
                    for s in r.clone() {
                        let mut rng = streams.path(pixel * spp + s);
                        let (o, d) = rays.ray(x as f64 + rng.uniform(), y as f64 + rng.uniform());
                        sum += radiance(&world, o, d, &settings.contributions, &mut rng);
                    }
                    row[x * nb + k] = sum;
                }
            }
        });
    for p in 0..pixels {
        for k in 0..nb {
            out.sums[k * pixels + p] = by_pixel[p * nb + k];
        }
    }
    Ok(out)
}

impl Image {
    /// A black `width`×`height` image with zero standard errors.
    pub fn zeros(width: usize, height: usize) -> Self {
        Image {
            width,
            height,
            mean: vec![0.0; width * height],
            stderr: vec![0.0; width * height],
        }
    }

    /// Adds an independent estimate of the same pixels: means add, standard errors add in
    /// quadrature.
    pub fn add_independent(&mut self, other: &Image) {
        for (p, (m, e)) in other.mean.iter().zip(&other.stderr).enumerate() {
            self.mean[p] += m;
            self.stderr[p] = self.stderr[p].hypot(*e);
        }
    }

    /// The image of a whole render from its joined per-batch sums ([`render_image_part`]).
    pub fn from_sums(
        width: usize,
        height: usize,
        sums: &BatchSums,
    ) -> Result<Self, ReferenceError> {
        if sums.bins != width * height {
            return Err(ReferenceError::ShardMismatch {
                what: format!(
                    "a {width}×{height} image has {} pixels, these sums {} bins",
                    width * height,
                    sums.bins
                ),
            });
        }
        let est = sums.estimates()?;
        Ok(Image {
            width,
            height,
            mean: est.iter().map(|e| e.mean).collect(),
            stderr: est.iter().map(|e| e.stderr).collect(),
        })
    }
}

const INV_4PI: f64 = 1.0 / (4.0 * PI);
const ROULETTE: f64 = 0.1;

/// Radiance arriving at `o` from direction −`d` (one path sample), restricted to `keep`.
pub(crate) fn radiance(
    world: &World,
    mut o: Vec3,
    mut d: Vec3,
    keep: &Contributions,
    rng: &mut Rng,
) -> f64 {
    let mut weight = 1.0;
    // Scattering events so far: the order of whatever this segment collects.
    let mut depth = 0u32;
    let mut l = 0.0;
    loop {
        let event = world.flight(o, d, rng);
        if world.has_emission && keep.emitted(depth) {
            l += weight * INV_4PI * world.volume().emission_integral(o, d, 0.0, event.t_end());
        }
        match event {
            Event::Escape => {
                if keep.light(depth) && !(depth == 0 && world.hide_background) {
                    l += weight * world.environment;
                }
                return l;
            }
            Event::Sphere { index, outside, .. } => {
                if depth == 0 && outside && keep.light(0) && !world.hide_background {
                    l += weight * world.spheres[index].radiance;
                }
                return l;
            }
            Event::Collision(t) => {
                if !keep.continues_after(depth) {
                    return l;
                }
                let x = at(o, d, t);
                weight *= world.volume().albedo(x);
                if weight <= 0.0 {
                    return l;
                }
                depth += 1;
                if keep.light(depth) {
                    l += weight * world.direct(x, d, rng);
                }
                if weight < ROULETTE {
                    if rng.uniform() * ROULETTE >= weight {
                        return l;
                    }
                    weight = ROULETTE;
                }
                d = sample_dir(&world.phase, d, rng.uniform(), rng.uniform());
                o = x;
            }
        }
    }
}

/// Used by tests: the direction of the centre ray of pixel (x, y).
#[cfg(test)]
pub(crate) fn centre_ray(camera: &solvers::scene::Camera, x: usize, y: usize) -> (Vec3, Vec3) {
    CameraRays::new(camera).ray(x as f64 + 0.5, y as f64 + 0.5)
}

#[cfg(test)]
mod tests {
    use super::super::math::{dot, norm};
    use super::*;
    use solvers::scene::{Camera, Projection};

    /// Pixel (0, 0) is top-left; the centre pixel of an odd perspective image looks at the
    /// target; horizontal and vertical field of view follow fov_y and the aspect ratio.
    #[test]
    fn camera_orientation_and_field_of_view() {
        let mut cam = Camera {
            hide_background: false,
            eye: [0.0, 0.0, 5.0],
            target: [0.0, 0.0, 0.0],
            up: [0.0, 1.0, 0.0],
            projection: Projection::Orthographic { width: 2.0 },
            resolution: [4, 2],
        };
        let (o, d) = centre_ray(&cam, 0, 0);
        assert_eq!(d, [0.0, 0.0, -1.0]);
        // Width 2 over 4 pixels: pixel centres at x = −0.75; height 1 over 2 rows: y = +0.25.
        assert!(
            (o[0] + 0.75).abs() < 1e-12 && (o[1] - 0.25).abs() < 1e-12,
            "{o:?}"
        );
        cam.projection = Projection::Perspective {
            fov_y_degrees: 60.0,
        };
        cam.resolution = [5, 3];
        let (_, d) = centre_ray(&cam, 2, 1);
        assert!((d[2] + 1.0).abs() < 1e-12);
        // The top edge of the image is fov_y/2 = 30° above the axis.
        let (_, top) = CameraRays::new(&cam).ray(2.5, 0.0);
        assert!((dot(top, [0.0, 0.0, -1.0]) - 30f64.to_radians().cos()).abs() < 1e-12);
        assert!(top[1] > 0.0);
        // The left edge is atan(tan 30° · 5/3) to the left.
        let (_, left) = CameraRays::new(&cam).ray(0.0, 1.5);
        let expected = (30f64.to_radians().tan() * 5.0 / 3.0).atan();
        assert!((left[0] / norm(left)).asin() + expected < 1e-12);
        assert!(left[0] < 0.0);
    }
}
