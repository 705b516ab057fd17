//! POP's measured weaknesses (spec pop.md §5) pinned as tests: each asserts the failure the
//! spec predicts, with bounds set from the measurement (`experiments::pop_weaknesses`'s docs)
//! and a margin, so a change that fixes or worsens one shows up here.
//! `cargo test --release -p experiments --test pop_weaknesses -- --nocapture`.
#![allow(clippy::unwrap_used)]

use experiments::pop_weaknesses::{blobs, skew, slab_row};

/// W3: slab τ = 4, albedo 1, g = 0.9, N = 8: POP reflects almost nothing (lobes keep
/// pointing along d), adding–doubling 0.122.
#[test]
fn w3_backscatter_is_lost_at_high_g() {
    let r = slab_row(4.0, 0.9, 8).unwrap();
    eprintln!("W3: R POP {:.5}, AD {:.5}", r.r_pop, r.r_ad);
    assert!((r.r_ad - 0.1221).abs() < 5e-4, "AD {}", r.r_ad);
    assert!(r.r_pop < 0.05 * r.r_ad, "POP R {}", r.r_pop);
}

/// W12: collided light crossing vacuum spreads like a lattice walk instead of streaming: the
/// gap between the blobs and the second blob are over-bright against the path tracer.
#[test]
fn w12_false_scattering_in_vacuum() {
    let rows = blobs(50_000, 3).unwrap();
    for r in &rows {
        eprintln!(
            "W12 {}: POP {:.4}, PT {:.4} ± {:.4}, ratio {:.3}",
            r.region, r.collided_pop, r.collided_pt, r.collided_pt_stderr, r.ratio
        );
        let hi = r.collided_pt + 3.0 * r.collided_pt_stderr;
        assert!(
            r.collided_pop > 1.5 * hi,
            "{}: {}",
            r.region,
            r.collided_pop
        );
    }
}

/// W13: behind a black wall the path tracer's light turns into the shadow (⟨ω_y⟩ < 0), which
/// one lobe along d cannot represent: POP's fluence deep in the shadow is far too low.
#[test]
fn w13_skew_into_the_shadow_is_missing() {
    let rows = skew(50_000, 4).unwrap();
    for r in &rows {
        eprintln!(
            "W13 y {}–{}: ⟨ω_y⟩ PT {:.3} ± {:.3}; φ PT {:.4} ± {:.4}, POP {:.4}",
            r.y0, r.y1, r.mu_y_pt, r.mu_y_pt_stderr, r.phi_pt, r.phi_pt_stderr, r.phi_pop
        );
    }
    let deep = &rows[0];
    let edge = &rows[1];
    assert!(
        edge.mu_y_pt + 5.0 * edge.mu_y_pt_stderr < -0.2,
        "⟨ω_y⟩ at the shadow's edge {}",
        edge.mu_y_pt
    );
    assert!(
        deep.phi_pop < 0.2 * (deep.phi_pt - 3.0 * deep.phi_pt_stderr),
        "deep shadow: POP {} vs PT {}",
        deep.phi_pop,
        deep.phi_pt
    );
}
