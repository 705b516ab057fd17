//! Energy balance of LBM on emissive albedo-1 media (issue 12, items 3 and acceptance 2; the
//! LBM side of `energy_balance.rs`): an n³ cube with emission j = 1, albedo 1, inside one
//! layer of vacuum, no lights. With the paper's absorption (a delay, no loss) and σa = 0,
//! every unit of emitted power streams out of the grid, so the outflow per step equals
//! ∫ j dV per step (the lattice's source) at steady state; a lattice that lost or created
//! density (collision columns not summing to 1, a wrong sink) fails it.
//!
//! It also prints, as the diagnostic of the emissive-cube gap (`lbm/mod.rs`, "Emissive
//! albedo-1 media"), the centre fluence and the mean fluence of the surface layer against
//! CDA with the Marshak face, which matches the path tracer on the emissive cube.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use solvers::method::{self, Problem, Tolerance};
use solvers::scene::Phase;
use solvers::{Backend, Grid, Medium, Precision};

fn cube(n: usize, tau: f64) -> Medium<f64> {
    let grid = Grid::new([n + 2; 3], 1.0).unwrap();
    let len = grid.len();
    let (mut st, mut a, mut j) = (vec![0.0; len], vec![0.0; len], vec![0.0; len]);
    for idx in 0..len {
        let [x, y, z] = grid.coords(idx);
        if !grid.is_boundary(x, y, z) {
            st[idx] = tau;
            a[idx] = 1.0;
            j[idx] = 1.0;
        }
    }
    Medium::new(grid, st, a, j).unwrap()
}

#[test]
fn lbm_outflow_equals_the_emitted_power_at_albedo_1() {
    let n = 8;
    let mut failures = Vec::new();
    for tau in [0.01, 1.0, 100.0] {
        let m = cube(n, tau);
        let p = Problem {
            medium: &m,
            lights: &[],
            phase: Phase::Isotropic,
        };
        let tight = Tolerance {
            rel: 1e-9,
            max_steps: 200_000,
        };
        let s = method::parse("lbm")
            .unwrap()
            .solve(&Backend::Cpu(Precision::F64), &p, &tight, &mut |_, _| {})
            .unwrap();
        let b = s.balance.expect("LBM reports its balance");
        let ratio = b.outflow / b.source;
        let c = method::parse("cda:marshak")
            .unwrap()
            .solve(&Backend::Cpu(Precision::F64), &p, &tight, &mut |_, _| {})
            .unwrap();
        let g = m.grid;
        let centre = g.index(n / 2, n / 2, n / 2);
        let surface = |phi: &[f64]| {
            let (mut sum, mut cnt) = (0.0, 0);
            for (idx, &v) in phi.iter().enumerate() {
                let [x, y, z] = g.coords(idx);
                let edge = [x, y, z].iter().any(|&c| c == 1 || c == n);
                if !g.is_boundary(x, y, z) && edge {
                    sum += v;
                    cnt += 1;
                }
            }
            sum / cnt as f64
        };
        println!(
            "lbm σt·Δl {tau}: {} steps ({}), outflow/source {ratio:.6}; φ centre lbm {:.4e} \
             cda:marshak {:.4e} (ratio {:.3}); surface-layer mean lbm {:.4e} cda:marshak {:.4e} \
             (ratio {:.3})",
            s.steps,
            s.stop,
            s.phi[centre],
            c.phi[centre],
            s.phi[centre] / c.phi[centre],
            surface(&s.phi),
            surface(&c.phi),
            surface(&s.phi) / surface(&c.phi),
        );
        if !(s.converged() && (ratio - 1.0).abs() < 1e-3) {
            failures.push(format!(
                "σt·Δl {tau}: outflow/source {ratio:.6} ({})",
                s.stop
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
