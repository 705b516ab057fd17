//! The scene data model shared by every grid method and by the reference path tracer:
//! a voxel [`Medium`] with its phase function, the lights that illuminate it, an optional
//! camera and the sampler settings of Monte Carlo references.
//!
//! Units follow the crate conventions: lengths in the grid's units, σt in inverse length,
//! volume emission `j` in power per unit volume (an isotropic source of radiance `j/4π` per
//! unit length, so that the diffusion equation reads −∇·D∇φ + σa φ = j), light powers in
//! watts, irradiance in power per unit area, radiance in power per area per steradian.
//!
//! The medium occupies exactly its grid's box `[origin, origin + n·Δl]`; outside is vacuum.
//! Field values are constant over each voxel (cell-centred samples, piecewise constant); a
//! consumer that interpolates instead must say so.

use crate::vec3::{cross, norm, sub};
use crate::{Medium, SolverError};

pub mod datasets;
pub mod effects;
pub mod file;
pub mod generators;
pub mod vdb;
pub mod vol;
pub mod warnings;

pub use effects::{Effect, EffectPattern, EffectSelection, Effects, EffectsError};
pub use file::{OutputKind, SceneFile, SceneFileError, load_scene};
pub use vol::{VolError, VolGrid};

/// A phase function.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Phase {
    /// p(θ) = 1/4π.
    Isotropic,
    /// Henyey–Greenstein with mean cosine `g` ∈ (−1, 1); positive `g` scatters forward.
    HenyeyGreenstein {
        /// Mean cosine of the scattering angle.
        g: f64,
    },
}

impl Phase {
    /// The mean cosine of the scattering angle (0 for isotropic).
    #[inline]
    pub fn mean_cosine(&self) -> f64 {
        match *self {
            Phase::Isotropic => 0.0,
            Phase::HenyeyGreenstein { g } => g,
        }
    }

    /// Checks that `g` lies in (−1, 1).
    pub fn validate(&self) -> Result<(), SolverError> {
        let g = self.mean_cosine();
        if g.is_finite() && g.abs() < 1.0 {
            Ok(())
        } else {
            Err(SolverError::BadParameter {
                name: "phase.g",
                value: g,
                reason: "the Henyey-Greenstein mean cosine must lie in (-1, 1)",
            })
        }
    }
}

/// A light source outside or inside the medium.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Light {
    /// An isotropic point light of total `power` (intensity `power/4π` in every direction).
    Point {
        /// Position.
        position: [f64; 3],
        /// Total emitted power, > 0.
        power: f64,
    },
    /// A directional light (collimated beam) travelling along `direction`, with `irradiance`
    /// measured on a plane perpendicular to the beam.
    Directional {
        /// Unit direction of propagation.
        direction: [f64; 3],
        /// Irradiance on a plane perpendicular to `direction`, > 0.
        irradiance: f64,
    },
    /// An opaque, black sphere whose surface emits constant `radiance` outward (a diffuse
    /// area light; Mitsuba's `sphere` shape with an `area` emitter and a black BSDF).
    Sphere {
        /// Centre.
        center: [f64; 3],
        /// Radius, > 0.
        radius: f64,
        /// Emitted radiance, > 0.
        radiance: f64,
    },
    /// Constant radiance arriving from every direction at infinity.
    Environment {
        /// Radiance, > 0.
        radiance: f64,
    },
}

/// The largest magnitude of a position coordinate (light, camera) and of a sphere light's
/// radius, in world units. Beyond about 1e154 squared distances overflow to ∞ and the
/// renderers' inverse-square and intersection terms become NaN (found by the fuzz test
/// `reference/tests/fuzz_render.rs`: a point light at x = 1e308 rendered NaN pixels); 1e15
/// leaves every product of two coordinates far from overflow and is far beyond any scene.
pub const MAX_COORDINATE: f64 = 1e15;

/// The largest light strength (point power, irradiance, radiance). Found by the fuzz test
/// `reference/tests/fuzz_render.rs`: an irradiance of 1e308 gave the path tracer an infinite
/// standard error (squared samples overflow); 1e15 keeps squares, and sums of squares over a
/// grid in f32, finite.
pub const MAX_STRENGTH: f64 = 1e15;

/// `Err` naming `name` unless every coordinate of `p` is finite and within ±[`MAX_COORDINATE`].
fn check_coordinates(name: &'static str, p: [f64; 3]) -> Result<(), SolverError> {
    match p
        .iter()
        .find(|v| !(v.is_finite() && v.abs() <= MAX_COORDINATE))
    {
        Some(&v) => Err(SolverError::BadParameter {
            name,
            value: v,
            reason: "coordinates must be finite and within ±1e15",
        }),
        None => Ok(()),
    }
}

impl Light {
    /// Checks that every parameter is finite and in range (unit direction, positive power,
    /// positions and radius within [`MAX_COORDINATE`], strengths at most [`MAX_STRENGTH`]).
    pub fn validate(&self) -> Result<(), SolverError> {
        let positive = |name: &'static str, v: f64| {
            if v.is_finite() && v > 0.0 && v <= MAX_STRENGTH {
                Ok(())
            } else {
                Err(SolverError::BadParameter {
                    name,
                    value: v,
                    reason: "must be finite, > 0 and at most 1e15",
                })
            }
        };
        let finite3 = check_coordinates;
        match *self {
            Light::Point { position, power } => {
                finite3("light.position", position)?;
                positive("light.power", power)
            }
            Light::Directional {
                direction,
                irradiance,
            } => {
                finite3("light.direction", direction)?;
                let len = norm(direction);
                if (len - 1.0).abs() > 1e-9 {
                    return Err(SolverError::BadParameter {
                        name: "light.direction",
                        value: len,
                        reason: "must be a unit vector (use Light::directional to normalise)",
                    });
                }
                positive("light.irradiance", irradiance)
            }
            Light::Sphere {
                center,
                radius,
                radiance,
            } => {
                finite3("light.center", center)?;
                positive("light.radius", radius)?;
                positive("light.radiance", radiance)
            }
            Light::Environment { radiance } => positive("light.radiance", radiance),
        }
    }

    /// A directional light along `direction` (normalised here; fails on a zero vector).
    pub fn directional(direction: [f64; 3], irradiance: f64) -> Result<Self, SolverError> {
        let len = norm(direction);
        if !(len.is_finite() && len > 0.0) {
            return Err(SolverError::BadParameter {
                name: "light.direction",
                value: len,
                reason: "must be a non-zero finite vector",
            });
        }
        let light = Light::Directional {
            direction: direction.map(|v| v / len),
            irradiance,
        };
        light.validate()?;
        Ok(light)
    }
}

/// How a camera projects rays.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Projection {
    /// Parallel rays; the image spans `width` world units horizontally.
    Orthographic {
        /// Horizontal extent of the image plane in world units.
        width: f64,
    },
    /// A pinhole camera with the given vertical field of view in degrees, in (0, 180).
    Perspective {
        /// Vertical field of view in degrees.
        fov_y_degrees: f64,
    },
}

/// A camera looking from `eye` towards `target`, `up` fixing the roll. Pixels are square;
/// pixel (0, 0) is the top-left one and images are stored row by row.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Eye position (orthographic: the centre of the image plane).
    pub eye: [f64; 3],
    /// The point the camera looks at.
    pub target: [f64; 3],
    /// Approximate up direction (need not be orthogonal to the view direction).
    pub up: [f64; 3],
    /// Orthographic or perspective projection.
    pub projection: Projection,
    /// Image width and height in pixels.
    pub resolution: [usize; 2],
    /// Leave out light seen directly (order 0 from the lights: the environment and sphere
    /// lights seen through the medium), as Mitsuba's `hide_emitters`; scene files:
    /// `[camera] hide_background = true`. Default false: the environment is visible.
    pub hide_background: bool,
}

impl Camera {
    /// Checks that the frame is well defined and the resolution non-zero.
    pub fn validate(&self) -> Result<(), SolverError> {
        check_coordinates("camera.eye", self.eye)?;
        check_coordinates("camera.target", self.target)?;
        let forward = sub(self.target, self.eye);
        if norm(forward).partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return Err(SolverError::BadParameter {
                name: "camera.target",
                value: norm(forward),
                reason: "must differ from camera.eye",
            });
        }
        let sine = norm(cross(forward, self.up)) / (norm(forward) * norm(self.up));
        if sine.partial_cmp(&1e-12) != Some(std::cmp::Ordering::Greater) {
            return Err(SolverError::BadParameter {
                name: "camera.up",
                value: norm(self.up),
                reason: "must be non-zero and not parallel to the view direction",
            });
        }
        if self.resolution[0] == 0 || self.resolution[1] == 0 {
            return Err(SolverError::BadParameter {
                name: "camera.resolution",
                value: 0.0,
                reason: "width and height must be at least 1 pixel",
            });
        }
        match self.projection {
            Projection::Orthographic { width } if !(width.is_finite() && width > 0.0) => {
                Err(SolverError::BadParameter {
                    name: "camera.width",
                    value: width,
                    reason: "must be finite and > 0",
                })
            }
            Projection::Perspective { fov_y_degrees }
                if !(fov_y_degrees > 0.0 && fov_y_degrees < 180.0) =>
            {
                Err(SolverError::BadParameter {
                    name: "camera.fov_y_degrees",
                    value: fov_y_degrees,
                    reason: "must lie in (0, 180)",
                })
            }
            _ => Ok(()),
        }
    }
}

/// Monte Carlo settings of a reference render.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Sampler {
    /// Samples (paths) per pixel.
    pub spp: u32,
    /// Seed; with the path index it determines every random number of a path.
    pub seed: u64,
}

/// How renderers that sample the medium between voxel centres reconstruct it (the path
/// tracer, the Mitsuba export, the grid methods' restriction). Scene files:
/// `[medium] interpolation = "nearest" | "trilinear"`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Interpolation {
    /// Constant over each voxel: the project convention (default), which every grid method
    /// discretises directly.
    #[default]
    Nearest,
    /// Trilinear between voxel centres, clamped to the outermost centres (the outer half
    /// voxel is constant along the normal); Mitsuba's and pbrt's default grid filter.
    Trilinear,
}

impl Interpolation {
    /// The scene-file name (also Mitsuba's `filter_type`).
    pub fn name(&self) -> &'static str {
        match self {
            Interpolation::Nearest => "nearest",
            Interpolation::Trilinear => "trilinear",
        }
    }
}

/// A complete scene: medium, phase function, lights, optional camera and sampler.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// σt, albedo and emission j on a voxel grid; the grid's box bounds the medium.
    pub medium: Medium<f64>,
    /// The phase function of every voxel.
    pub phase: Phase,
    /// External and embedded lights (volume emission lives in `medium.emission`).
    pub lights: Vec<Light>,
    /// The camera of image renders, if any.
    pub camera: Option<Camera>,
    /// Monte Carlo settings.
    pub sampler: Sampler,
    /// Reconstruction of the voxel fields between centres (default nearest).
    pub interpolation: Interpolation,
}

impl Scene {
    /// Validates every part.
    pub fn validate(&self) -> Result<(), SolverError> {
        self.medium.validate()?;
        self.phase.validate()?;
        for light in &self.lights {
            light.validate()?;
        }
        if let Some(camera) = &self.camera {
            camera.validate()?;
        }
        if self.sampler.spp == 0 {
            return Err(SolverError::BadParameter {
                name: "sampler.spp",
                value: 0.0,
                reason: "must be at least 1",
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn invalid_parts_are_rejected_with_the_field_named() {
        let err = Light::directional([0.0; 3], 1.0).unwrap_err();
        assert!(err.to_string().contains("light.direction"), "{err}");
        let err = Phase::HenyeyGreenstein { g: 1.0 }.validate().unwrap_err();
        assert!(err.to_string().contains("phase.g"), "{err}");
        let cam = Camera {
            hide_background: false,
            eye: [0.0, 0.0, -1.0],
            target: [0.0; 3],
            up: [0.0, 0.0, 1.0],
            projection: Projection::Perspective {
                fov_y_degrees: 40.0,
            },
            resolution: [8, 8],
        };
        let err = cam.validate().unwrap_err();
        assert!(err.to_string().contains("camera.up"), "{err}");
        let d = Light::directional([0.0, 0.0, -2.0], 1.0).unwrap();
        assert_eq!(
            d,
            Light::Directional {
                direction: [0.0, 0.0, -1.0],
                irradiance: 1.0
            }
        );
    }
}
