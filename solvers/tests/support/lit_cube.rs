//! The lit albedo-1 cube of issue 12 as the pipeline builds its multiple-scattering problem
//! at downsample 1 (the baked q_ri of its one light as the source), and the relative L2
//! distance and the tight reference solve the default-stop tests measure with. Shared by
//! `default_stop.rs` and `rde_default_stop.rs` (declared once in `main.rs`).
#![allow(clippy::unwrap_used)]

use solvers::method::{Fluence, Method, Problem, Tolerance};
use solvers::pipeline::{bake, restrict};
use solvers::{Backend, Medium, Precision};

/// The 16³ cube at σt·Δl = `tau`: the solve medium and the scene (for its lights and phase).
pub fn lit_cube(tau: f64) -> (Medium<f64>, solvers::scene::Scene) {
    let scene = solvers::scenes::lit_albedo1_cube(16, tau).unwrap();
    let baked = vec![bake::bake(&scene.medium, 0, &scene.lights[0]).unwrap()];
    let q = bake::q_ri(&scene.medium, &baked);
    let m = restrict::restrict(&scene.medium, &q, 1, 1).unwrap();
    (m, scene)
}

/// ‖a − b‖₂ / ‖b‖₂.
pub fn rel_l2(a: &[f64], b: &[f64]) -> f64 {
    let d: f64 = a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum();
    (d / b.iter().map(|y| y * y).sum::<f64>()).sqrt()
}

/// `method` solved tightly (R̄/j̄ < 10⁻¹⁰ in f64, at most 10⁵ steps): the reference the
/// default stops are measured against.
pub fn tight_solve(method: &dyn Method, p: &Problem<'_>) -> Fluence {
    method
        .solve(
            &Backend::Cpu(Precision::F64),
            p,
            &Tolerance {
                rel: 1e-10,
                max_steps: 100_000,
            },
            &mut |_, _| {},
        )
        .unwrap()
}
