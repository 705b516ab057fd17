//! Warnings for valid scenes that cannot show anything: the image of such a scene is black
//! for a reason the user can fix, so the binaries print one line per reason instead of
//! rendering black in silence (issue 13, item 7).

use super::{Effect, Effects, Light, Scene};
use crate::Grid;
use crate::pipeline::geometry::{CameraRays, ray_box};
use crate::vec3::{norm, sub};

/// Most camera rays tested for hitting the medium (pixel centres, on a regular subgrid of
/// the image when it has more pixels, always including its corners and edges).
const MAX_TESTED_RAYS: usize = 1 << 16;

/// The reasons a render of `scene` restricted to `effects` (`None`: every effect the scene
/// implies) shows nothing, one sentence each; empty for a scene that can show something.
pub fn degenerate(scene: &Scene, effects: Option<&Effects>) -> Vec<String> {
    let mut out = Vec::new();
    let m = &scene.medium;
    let emits = m.emission.iter().any(|&j| j > 0.0);
    let attenuates = m.sigma_t.iter().any(|&s| s > 0.0);
    if scene.lights.is_empty() && !emits {
        out.push(
            "the scene has no light and no volume emission: nothing emits, the image is black"
                .to_string(),
        );
    }
    if !attenuates && !emits {
        out.push(
            "the medium is empty (σt = 0 and no emission in every voxel): nothing scatters \
             or emits, the image is black (lights are not seen directly)"
                .to_string(),
        );
    }
    if let Some(e) = effects
        && !e.0.iter().any(|x| {
            matches!(
                x,
                Effect::SingleScattering { .. } | Effect::MultipleScattering | Effect::Emission
            )
        })
    {
        out.push(
            "the [effects] selection excludes every light-transport effect the scene has \
             (single and multiple scattering, emission): nothing is rendered, the image is black"
                .to_string(),
        );
    }
    if let Some(camera) = &scene.camera {
        for (k, light) in scene.lights.iter().enumerate() {
            if let Light::Sphere { center, radius, .. } = light
                && norm(sub(camera.eye, *center)) < *radius
            {
                out.push(format!(
                    "the camera is inside sphere light {k} (centre {center:?}, radius {radius}): \
                     the light's surface hides the scene"
                ));
            }
        }
        if attenuates || emits {
            if let Some(bounds) = occupied_box(scene) {
                if !sees(&CameraRays::new(camera), camera.resolution, &bounds) {
                    out.push(format!(
                        "no camera ray meets the medium (camera at {:?} looking at {:?}; the \
                         medium's occupied box is {:?} to {:?}): the image is black",
                        camera.eye,
                        camera.target,
                        bounds.origin,
                        corner(&bounds)
                    ));
                }
            }
        }
    }
    out
}

/// The far corner of `g`.
fn corner(g: &Grid) -> [f64; 3] {
    [0, 1, 2].map(|a| g.origin[a] + g.n[a] as f64 * g.dl)
}

/// The box of the voxels with σt > 0 or emission > 0, as a grid of the same spacing (its
/// `n` counts voxels along each axis of the box).
fn occupied_box(scene: &Scene) -> Option<Grid> {
    let m = &scene.medium;
    let g = &m.grid;
    let [nx, ny, nz] = g.n;
    let mut lo = [usize::MAX; 3];
    let mut hi = [0usize; 3];
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                let i = (z * ny + y) * nx + x;
                let busy = m.sigma_t.get(i).is_some_and(|&s| s > 0.0)
                    || m.emission.get(i).is_some_and(|&j| j > 0.0);
                if busy {
                    for (a, v) in [x, y, z].into_iter().enumerate() {
                        lo[a] = lo[a].min(v);
                        hi[a] = hi[a].max(v);
                    }
                }
            }
        }
    }
    if lo[0] == usize::MAX {
        return None;
    }
    Some(Grid {
        n: [0, 1, 2].map(|a| hi[a] - lo[a] + 1),
        dl: g.dl,
        origin: [0, 1, 2].map(|a| g.origin[a] + lo[a] as f64 * g.dl),
    })
}

/// Whether a camera ray through a pixel centre (all of them, or a regular subgrid with the
/// image's edges when there are more than [`MAX_TESTED_RAYS`]) meets `bounds`.
fn sees(rays: &CameraRays, resolution: [usize; 2], bounds: &Grid) -> bool {
    let [w, h] = resolution;
    let side = (MAX_TESTED_RAYS as f64).sqrt() as usize;
    let axis = |n: usize| -> Vec<f64> {
        if n <= side {
            (0..n).map(|i| i as f64 + 0.5).collect()
        } else {
            (0..side)
                .map(|i| 0.5 + (n - 1) as f64 * i as f64 / (side - 1) as f64)
                .collect()
        }
    };
    let (xs, ys) = (axis(w), axis(h));
    ys.iter().any(|&py| {
        xs.iter().any(|&px| {
            let (o, d) = rays.ray(px, py);
            ray_box(bounds, o, d, 0.0).is_some()
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Medium;
    use crate::scene::{Camera, Phase, Projection, Sampler};

    fn scene(sigma_t: f64, lights: Vec<Light>, eye: [f64; 3], target: [f64; 3]) -> Scene {
        let grid = Grid::cube(8, 1.0).unwrap();
        Scene {
            interpolation: Default::default(),
            medium: Medium::homogeneous(grid, sigma_t, 0.9).unwrap(),
            phase: Phase::Isotropic,
            lights,
            camera: Some(Camera {
                hide_background: false,
                eye,
                target,
                up: [0.0, 0.0, 1.0],
                projection: Projection::Perspective {
                    fov_y_degrees: 40.0,
                },
                resolution: [16, 16],
            }),
            sampler: Sampler { spp: 16, seed: 1 },
        }
    }

    fn sun() -> Vec<Light> {
        vec![Light::Directional {
            direction: [0.0, 0.0, -1.0],
            irradiance: 1.0,
        }]
    }

    #[test]
    fn a_good_scene_has_no_warning_and_each_degenerate_one_has_its_own() {
        let (eye, at) = ([0.5, -3.0, 0.5], [0.5, 0.5, 0.5]);
        assert!(degenerate(&scene(2.0, sun(), eye, at), None).is_empty());
        let w = degenerate(&scene(2.0, vec![], eye, at), None);
        assert!(w.len() == 1 && w[0].contains("no light"), "{w:?}");
        let w = degenerate(&scene(0.0, sun(), eye, at), None);
        assert!(w.len() == 1 && w[0].contains("empty"), "{w:?}");
        // Looking away from the cube.
        let w = degenerate(&scene(2.0, sun(), eye, [0.5, -6.0, 0.5]), None);
        assert!(w.len() == 1 && w[0].contains("no camera ray"), "{w:?}");
        let w = degenerate(&scene(2.0, sun(), eye, at), Some(&Effects::none()));
        assert!(w.len() == 1 && w[0].contains("[effects]"), "{w:?}");
        let sphere = vec![Light::Sphere {
            center: [0.5, -3.0, 0.5],
            radius: 1.0,
            radiance: 1.0,
        }];
        let w = degenerate(&scene(2.0, sphere, eye, at), None);
        assert!(
            w.len() == 1 && w[0].contains("inside sphere light 0"),
            "{w:?}"
        );
    }
}
