//! The camera path tracer in optically thick voxels against an exact transport solution
//! (issue 12, item 6): a 16³ cube of σt = 1000 (σt·Δl = 62.5, 1000 mean free paths across)
//! is a half-space for light entering the centre of its top face. Under normally incident
//! collimated irradiance E, the radiance reflected at cosine μ by a half-space of isotropic
//! scatterers with albedo c is Chandrasekhar's
//!
//! ```text
//! I(μ) = E μ0 c H(μ) H(μ0) / (4π (μ + μ0)),   μ0 = 1,
//! ```
//!
//! with H from `reference::transport::hfunction`. An orthographic camera sees a 0.1 × 0.1
//! patch of the top face at μ = cos 60° (the lateral edges are 450 mean free paths away, 78
//! diffusion lengths at c = 0.99). Every pixel must agree within its Šidák-corrected z-test
//! and the image mean within 3 standard errors.
//!
//! *Measured* (8×8 pixels, 65536 spp): ours 0.137419 ± 3.8·10⁻⁵ against the exact 0.137453
//! at c = 0.9 (z = −0.9) and 0.240118 ± 9.4·10⁻⁵ against 0.240085 at c = 0.99 (z = 0.4).
//! Mitsuba 3.9.1 `scalar_rgb` (volpath, 32 renders) on the same export: 0.135748 ± 5.4·10⁻⁵
//! (−1.2 %, z = −32) and 0.249798 ± 3.8·10⁻⁴ (+4.0 %, z = 26). Mitsuba's error depends on where
//! the cube sits: the same c = 0.99 scene translated by 100 units renders 0.083 in Mitsuba
//! (the exact answer does not move), and at σt = 100 and 10⁴ it is +0.5 % and −1.4 %, so it
//! scales with σt times the scene's coordinates — single-precision ray offsets comparable to
//! the mean free path, not a transport error of ours. That Mitsuba case stays in
//! `results/` (`mitsuba_compare` on such scenes reports `passed = false`).

#![allow(clippy::unwrap_used, clippy::expect_used)]

use reference::compare::{ImageEstimate, compare};
use reference::pathtracer::{Contributions, RenderSettings, render_image};
use reference::transport::hfunction::h_function;
use solvers::scene::SceneFile;
use std::f64::consts::PI;
use std::path::Path;

fn scene(albedo: f64) -> String {
    format!(
        r#"
format = 1
[medium]
generator = "homogeneous"
params = {{ n = 16, extent = 1.0, sigma_t = 1000.0, albedo = {albedo} }}
[[light]]
type = "directional"
direction = [0.0, 0.0, -1.0]
irradiance = 1.0
[camera]
eye = [1.3660254037844386, 0.5, 1.5]
target = [0.5, 0.5, 1.0]
up = [0.0, 0.0, 1.0]
projection = "orthographic"
width = 0.1
resolution = [8, 8]
"#
    )
}

#[test]
fn reflection_of_a_dense_half_space_matches_chandrasekhar() {
    let mu: f64 = 0.5;
    for c in [0.9, 0.99] {
        let file = SceneFile::parse(&scene(c), Path::new("."), Path::new("semi.toml")).unwrap();
        let img = render_image(
            &file.scene,
            &RenderSettings {
                spp: 8192,
                seed: 21,
                batches: 16,
                contributions: Contributions::all(),
            },
        )
        .unwrap();
        let exact =
            c * h_function(c, mu).unwrap() * h_function(c, 1.0).unwrap() / (4.0 * PI * (mu + 1.0));
        let n = img.width * img.height;
        let ours = ImageEstimate::batched(img.width, img.height, img.mean.clone(), img.stderr, 16);
        let truth = ImageEstimate::exact(img.width, img.height, vec![exact; n]);
        let cmp = compare(&ours, &truth, 0.01).unwrap();
        eprintln!(
            "c = {c}: mean {:.6} ± {:.1e} vs exact {exact:.6}, z {:+.2}, pixels passing {:.3}",
            cmp.mean_ours.0, cmp.mean_ours.1, cmp.mean_z, cmp.fraction_passing
        );
        assert!(
            cmp.passed(),
            "c = {c}: z {} passing {}",
            cmp.mean_z,
            cmp.fraction_passing
        );
        assert_eq!(cmp.fraction_passing, 1.0, "c = {c}");
    }
}
