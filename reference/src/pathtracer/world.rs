//! A bounded scene prepared for tracing: the tracker, the phase function, the lights by kind,
//! free flights that stop at real collisions and at opaque spheres, shadow rays, next-event
//! estimation, and emitted-particle sampling for the fluence tallies.
//!
//! Sphere lights are opaque and black: a ray reaching one ends there. Points inside a sphere
//! are outside the scene (nothing is emitted into or seen from the interior).

use super::TraceOptions;
use super::math::{Vec3, add, around, dot, norm, scale, sub};
use super::phase::{eval, uniform_sphere};
use super::rng::Rng;
use super::tracking::{self, Tracker};
use super::volume::Volume;
use crate::ReferenceError;
use solvers::scene::{Light, Phase, Scene};
use std::f64::consts::PI;

/// An opaque black sphere emitting `radiance` outward.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Sphere {
    pub center: Vec3,
    pub radius: f64,
    pub radiance: f64,
}

impl Sphere {
    /// The nearest intersection with t > ε along `o + t·d` (unit `d`): `(t, from_outside)`.
    #[inline]
    pub fn intersect(&self, o: Vec3, d: Vec3) -> Option<(f64, bool)> {
        let oc = sub(o, self.center);
        let b = dot(oc, d);
        let c = dot(oc, oc) - self.radius * self.radius;
        let disc = b * b - c;
        if disc < 0.0 {
            return None;
        }
        let s = disc.sqrt();
        let eps = 1e-9 * (self.radius + norm(oc));
        let (t0, t1) = (-b - s, -b + s);
        if t0 > eps {
            Some((t0, true))
        } else if t1 > eps {
            // Origin inside (or on the surface heading in): the far wall, seen from inside.
            Some((t1, false))
        } else {
            None
        }
    }

    fn contains(&self, p: Vec3) -> bool {
        let v = sub(p, self.center);
        dot(v, v) < self.radius * self.radius
    }
}

/// What ended a free flight.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Event {
    /// A real collision at this parameter.
    Collision(f64),
    /// Sphere `index` reached at this parameter; `outside` if hit on its emitting side.
    Sphere { t: f64, index: usize, outside: bool },
    /// The ray left for infinity.
    Escape,
}

impl Event {
    /// The parameter where the flight ends (∞ for an escape).
    pub fn t_end(&self) -> f64 {
        match *self {
            Event::Collision(t) | Event::Sphere { t, .. } => t,
            Event::Escape => f64::INFINITY,
        }
    }
}

/// The traceable form of a [`Scene`].
#[derive(Debug, Clone)]
pub(crate) struct World {
    pub tracker: Tracker,
    pub phase: Phase,
    /// Point lights: position and intensity power/4π.
    pub points: Vec<(Vec3, f64)>,
    /// Directional lights: unit direction towards the light and irradiance.
    pub directionals: Vec<(Vec3, f64)>,
    pub spheres: Vec<Sphere>,
    /// Summed radiance of the environment lights.
    pub environment: f64,
    pub has_emission: bool,
    /// The camera leaves out order-0 light from the lights (`Camera::hide_background`).
    pub hide_background: bool,
}

impl World {
    pub fn new(scene: &Scene, options: &TraceOptions) -> Result<Self, ReferenceError> {
        scene.validate()?;
        let volume = Volume::new(&scene.medium, options.interpolation)?;
        let has_emission = volume.has_emission();
        let refine = if options.refine {
            tracking::REFINE_OPTICAL_DEPTH
        } else {
            f64::INFINITY
        };
        let tracker = Tracker::with_refinement(volume, options.majorant_block, refine);
        let mut w = Self {
            tracker,
            phase: scene.phase,
            points: Vec::new(),
            directionals: Vec::new(),
            spheres: Vec::new(),
            environment: 0.0,
            has_emission,
            hide_background: scene.camera.is_some_and(|c| c.hide_background),
        };
        for light in &scene.lights {
            match *light {
                Light::Point { position, power } => w.points.push((position, power / (4.0 * PI))),
                Light::Directional {
                    direction,
                    irradiance,
                } => w.directionals.push((scale(direction, -1.0), irradiance)),
                Light::Sphere {
                    center,
                    radius,
                    radiance,
                } => w.spheres.push(Sphere {
                    center,
                    radius,
                    radiance,
                }),
                Light::Environment { radiance } => w.environment += radiance,
            }
        }
        Ok(w)
    }

    pub fn volume(&self) -> &Volume {
        &self.tracker.volume
    }

    /// The nearest sphere hit along the ray.
    #[inline]
    fn sphere_hit(&self, o: Vec3, d: Vec3) -> Option<(f64, usize, bool)> {
        let mut best: Option<(f64, usize, bool)> = None;
        for (i, s) in self.spheres.iter().enumerate() {
            if let Some((t, outside)) = s.intersect(o, d)
                && best.is_none_or(|b| t < b.0)
            {
                best = Some((t, i, outside));
            }
        }
        best
    }

    /// Samples a free flight from `o` along unit `d`.
    #[inline]
    pub fn flight(&self, o: Vec3, d: Vec3, rng: &mut Rng) -> Event {
        let hit = self.sphere_hit(o, d);
        let t_max = hit.map_or(f64::INFINITY, |h| h.0);
        match self.tracker.sample_collision(o, d, 0.0, t_max, rng) {
            Some(t) => Event::Collision(t),
            None => match hit {
                Some((t, index, outside)) => Event::Sphere { t, index, outside },
                None => Event::Escape,
            },
        }
    }

    /// Transmittance from `x` along unit `d` up to `t_max`: 0 if a sphere other than
    /// `target` (the sphere light sampled, whose near surface is at `t_max`: it cannot
    /// occlude itself, and skipping it saves an intersection per sample) intervenes,
    /// otherwise ratio tracking through the medium.
    #[inline]
    pub fn shadow(
        &self,
        x: Vec3,
        d: Vec3,
        t_max: f64,
        target: Option<usize>,
        rng: &mut Rng,
    ) -> f64 {
        let limit = t_max * (1.0 - 1e-9);
        if self
            .spheres
            .iter()
            .enumerate()
            .any(|(i, s)| Some(i) != target && s.intersect(x, d).is_some_and(|(t, _)| t < limit))
        {
            return 0.0;
        }
        self.tracker.transmittance(x, d, 0.0, t_max, rng)
    }

    /// Next-event estimate at a scattering point `x` of the radiance scattered towards the
    /// camera by point, directional and sphere lights (environment light and emission are
    /// collected by the path itself). `d` is the propagation direction of the camera path
    /// arriving at `x`; the phase function is evaluated at cos θ = ω_light · d (the light
    /// propagates along −ω_light and leaves along −d).
    pub fn direct(&self, x: Vec3, d: Vec3, rng: &mut Rng) -> f64 {
        let mut sum = 0.0;
        for &(p, intensity) in &self.points {
            let v = sub(p, x);
            let dist = norm(v);
            if dist > 0.0 {
                let wl = scale(v, 1.0 / dist);
                let f = eval(&self.phase, dot(wl, d));
                sum += intensity * f / (dist * dist) * self.shadow(x, wl, dist, None, rng);
            }
        }
        for &(wl, irradiance) in &self.directionals {
            let f = eval(&self.phase, dot(wl, d));
            sum += irradiance * f * self.shadow(x, wl, f64::INFINITY, None, rng);
        }
        for (i, s) in self.spheres.iter().enumerate() {
            let v = sub(s.center, x);
            let dist2 = dot(v, v);
            let r2 = s.radius * s.radius;
            if dist2 <= r2 {
                continue;
            }
            let dist = dist2.sqrt();
            let axis = scale(v, 1.0 / dist);
            // Uniform over the cone of directions subtended by the sphere;
            // 1 − cos θmax = sin²θmax / (1 + cos θmax) without cancellation (sin² from
            // dist², not from 1/dist: a shorter chain of dependent square roots and
            // divisions, which is what this loop waits on).
            let sin2 = r2 / dist2;
            let cos_max = (1.0 - sin2).sqrt();
            let one_minus = sin2 / (1.0 + cos_max);
            let cos = 1.0 - rng.uniform() * one_minus;
            let wl = around(axis, cos, rng.uniform());
            // Distance to the near surface; clamp the discriminant at the cone's rim.
            let b = dist * cos;
            let t = b - (b * b - (dist2 - r2)).max(0.0).sqrt();
            // 1/pdf: the cone's solid angle.
            let solid_angle = 2.0 * PI * one_minus;
            let f = eval(&self.phase, dot(wl, d));
            sum += s.radiance * f * solid_angle * self.shadow(x, wl, t, Some(i), rng);
        }
        sum
    }
}

/// Where emitted particles come from, for the fluence tallies: each light and the volume
/// emission with its total power, chosen in proportion to power.
#[derive(Debug, Clone)]
pub(crate) struct Sources {
    kinds: Vec<SourceKind>,
    cdf: Vec<f64>,
    /// Total emitted power (the weight every particle starts with).
    pub total: f64,
    /// Emitting voxels and their cumulative power.
    voxel: Vec<usize>,
    voxel_cdf: Vec<f64>,
    /// Box faces (axis, upper side) and their cumulative areas, for the environment.
    faces: [(f64, f64); 6],
}

#[derive(Debug, Clone, Copy)]
enum SourceKind {
    Point(Vec3),
    Directional(Vec3),
    Sphere(Sphere),
    Environment,
    Emission,
}

/// Index of the first entry of an increasing `cdf` above `u` (clamped to the last).
fn pick(cdf: &[f64], u: f64) -> usize {
    cdf.partition_point(|&c| c <= u)
        .min(cdf.len().saturating_sub(1))
}

impl Sources {
    pub fn new(world: &World, scene: &Scene) -> Result<Self, ReferenceError> {
        let v = world.volume();
        let (lo, hi) = v.bounds();
        let size = sub(hi, lo);
        let face_area = [size[1] * size[2], size[0] * size[2], size[0] * size[1]];
        let total_area = 2.0 * (face_area[0] + face_area[1] + face_area[2]);
        let mut faces = [(0.0, 0.0); 6];
        let mut acc = 0.0;
        for (f, face) in faces.iter_mut().enumerate() {
            acc += face_area[f / 2];
            *face = (face_area[f / 2], acc);
        }
        let mut kinds = Vec::new();
        let mut power = Vec::new();
        for light in &scene.lights {
            match *light {
                Light::Point { position, power: p } => {
                    kinds.push(SourceKind::Point(position));
                    power.push(p);
                }
                Light::Directional {
                    direction,
                    irradiance,
                } => {
                    let proj: f64 = (0..3).map(|a| direction[a].abs() * face_area[a]).sum();
                    kinds.push(SourceKind::Directional(direction));
                    power.push(irradiance * proj);
                }
                Light::Sphere {
                    center,
                    radius,
                    radiance,
                } => {
                    kinds.push(SourceKind::Sphere(Sphere {
                        center,
                        radius,
                        radiance,
                    }));
                    power.push(radiance * PI * 4.0 * PI * radius * radius);
                }
                Light::Environment { radiance } => {
                    kinds.push(SourceKind::Environment);
                    power.push(PI * radiance * total_area);
                }
            }
        }
        let (mut voxel, mut voxel_cdf) = (Vec::new(), Vec::new());
        if world.has_emission {
            if v.interpolation() != super::volume::Interpolation::Nearest {
                return Err(ReferenceError::Unsupported {
                    what: "volume emission as a fluence source needs Interpolation::Nearest \
                           (particles are emitted per voxel)",
                });
            }
            let dv = v.grid().dl.powi(3);
            let mut acc = 0.0;
            for (i, &j) in v.emission_samples().iter().enumerate() {
                if j > 0.0 {
                    acc += j * dv;
                    voxel.push(i);
                    voxel_cdf.push(acc);
                }
            }
            kinds.push(SourceKind::Emission);
            power.push(acc);
        }
        let mut cdf = Vec::with_capacity(power.len());
        let mut acc = 0.0;
        for p in power {
            acc += p;
            cdf.push(acc);
        }
        if !(acc > 0.0 && acc.is_finite()) {
            return Err(ReferenceError::BadParameter {
                name: "scene.lights",
                value: acc,
                reason: "the scene emits no power (add a light or emission)",
            });
        }
        Ok(Self {
            kinds,
            cdf,
            total: acc,
            voxel,
            voxel_cdf,
            faces,
        })
    }

    /// Samples an emitted particle: origin and unit direction (weight [`Sources::total`]),
    /// or `None` if a sphere blocks an external light before it reaches the box.
    pub fn sample(&self, world: &World, rng: &mut Rng) -> Option<(Vec3, Vec3)> {
        let k = pick(&self.cdf, rng.uniform() * self.total);
        let (lo, hi) = world.volume().bounds();
        let size = sub(hi, lo);
        let on_face = |axis: usize, upper: bool, rng: &mut Rng| {
            let mut p = [0.0; 3];
            for a in 0..3 {
                p[a] = if a == axis {
                    if upper { hi[a] } else { lo[a] }
                } else {
                    lo[a] + rng.uniform() * size[a]
                };
            }
            p
        };
        let blocked =
            |p: Vec3, back: Vec3| world.spheres.iter().any(|s| s.intersect(p, back).is_some());
        match self.kinds[k] {
            SourceKind::Point(p) => Some((p, uniform_sphere(rng.uniform(), rng.uniform()))),
            SourceKind::Sphere(s) => {
                let n = uniform_sphere(rng.uniform(), rng.uniform());
                let o = add(s.center, scale(n, s.radius));
                let d = cosine_around(n, rng);
                Some((o, d))
            }
            SourceKind::Directional(d) => {
                let w: Vec<f64> = (0..3)
                    .map(|a| d[a].abs() * self.faces[2 * a].0)
                    .scan(0.0, |acc, x| {
                        *acc += x;
                        Some(*acc)
                    })
                    .collect();
                let axis = pick(&w, rng.uniform() * w[2]);
                // A beam travelling towards +axis enters through the lower face.
                let p = on_face(axis, d[axis] < 0.0, rng);
                (!blocked(p, scale(d, -1.0))).then_some((p, d))
            }
            SourceKind::Environment => {
                let f = pick(&self.faces.map(|x| x.1), rng.uniform() * self.faces[5].1);
                let (axis, upper) = (f / 2, f % 2 == 1);
                let p = on_face(axis, upper, rng);
                let mut n = [0.0; 3];
                n[axis] = if upper { -1.0 } else { 1.0 };
                let d = cosine_around(n, rng);
                (!blocked(p, scale(d, -1.0))).then_some((p, d))
            }
            SourceKind::Emission => {
                let total = self.voxel_cdf.last().copied().unwrap_or(0.0);
                let idx = self.voxel[pick(&self.voxel_cdf, rng.uniform() * total)];
                let g = world.volume().grid();
                let [i, j, kk] = g.coords(idx);
                let c = [i as f64, j as f64, kk as f64];
                let p = [0, 1, 2].map(|a| g.origin[a] + (c[a] + rng.uniform()) * g.dl);
                let inside_sphere = world.spheres.iter().any(|s| s.contains(p));
                (!inside_sphere).then(|| (p, uniform_sphere(rng.uniform(), rng.uniform())))
            }
        }
    }
}

/// A cosine-distributed unit vector about the unit normal `n`.
#[inline]
fn cosine_around(n: Vec3, rng: &mut Rng) -> Vec3 {
    let cos = rng.uniform().sqrt();
    let d = around(n, cos, rng.uniform());
    // Guard against a grazing direction rounding to the wrong side.
    if dot(d, n) > 0.0 { d } else { n }
}

#[cfg(test)]
mod tests {
    use super::super::rng::Rng;
    use super::*;
    use crate::quadrature::simpson;
    use solvers::scene::{Camera, Sampler};
    use solvers::{Grid, Medium};

    fn vacuum_world(phase: Phase, lights: Vec<Light>) -> World {
        let grid = Grid::cube(4, 1.0).unwrap();
        let n = grid.len();
        let scene = Scene {
            interpolation: Default::default(),
            medium: Medium::new(grid, vec![0.0; n], vec![1.0; n], vec![0.0; n]).unwrap(),
            phase,
            lights,
            camera: None::<Camera>,
            sampler: Sampler { spp: 1, seed: 0 },
        };
        World::new(&scene, &TraceOptions::default()).unwrap()
    }

    /// Next-event estimation in vacuum: a point light gives I·p/d² exactly; a sphere light
    /// with isotropic phase gives L·Ω/(4π) exactly (uniform cone sampling has zero variance
    /// then), with HG the cone average matches L∫_cone p dω by quadrature; an opaque sphere
    /// between a point and a point light casts an exact shadow.
    #[test]
    fn next_event_estimation_in_vacuum() {
        let x = [0.5, 0.5, 0.5];
        let d = [0.0, 0.0, -1.0];
        let (c, r, l) = ([0.5, 0.5, 3.5], 1.0, 2.0);
        let sphere = Light::Sphere {
            center: c,
            radius: r,
            radiance: l,
        };
        let w = vacuum_world(Phase::Isotropic, vec![sphere]);
        let dist: f64 = 3.0;
        let omega = 2.0 * PI * (1.0 - (1.0 - r * r / (dist * dist)).sqrt());
        let mut rng = Rng::new(0, 0);
        for _ in 0..10 {
            let v = w.direct(x, d, &mut rng);
            assert!((v - l * omega / (4.0 * PI)).abs() < 1e-12 * v, "{v}");
        }
        let g = 0.7;
        let w = vacuum_world(Phase::HenyeyGreenstein { g }, vec![sphere]);
        // cos θ = ω_l · d; over the cone about +z, ω_l·d = −cos(angle to the axis).
        let cos_max = (1.0 - r * r / (dist * dist)).sqrt();
        let exact = l * 2.0 * PI * simpson(|m| eval(&w.phase, -m), cos_max, 1.0, 20_000);
        let n = 200_000;
        let (mut s1, mut s2) = (0.0, 0.0);
        for i in 0..n {
            let v = w.direct(x, d, &mut Rng::new(1, i));
            s1 += v;
            s2 += v * v;
        }
        let mean = s1 / n as f64;
        let se = ((s2 / n as f64 - mean * mean) / n as f64).sqrt();
        assert!((mean - exact).abs() < 3.0 * se, "{mean} ± {se} vs {exact}");

        let point = Light::Point {
            position: [0.5, 0.5, 2.0],
            power: 4.0 * PI * 3.0,
        };
        let w = vacuum_world(Phase::HenyeyGreenstein { g: 0.3 }, vec![point]);
        let v = w.direct(x, d, &mut rng);
        let exact = 3.0 * eval(&w.phase, -1.0) / (1.5 * 1.5);
        assert!((v - exact).abs() < 1e-12 * exact);
        let blocker = Light::Sphere {
            center: [0.5, 0.5, 1.2],
            radius: 0.1,
            radiance: 1.0,
        };
        let w = vacuum_world(Phase::Isotropic, vec![point, blocker]);
        // The blocker hides the point light; its own cone still contributes.
        let v = w.direct(x, d, &mut rng);
        let own = (2.0 * PI * (1.0 - (1.0f64 - 0.01 / (0.7 * 0.7)).sqrt())) / (4.0 * PI);
        assert!((v - own).abs() < 1e-12, "{v} vs {own}");
    }
}
