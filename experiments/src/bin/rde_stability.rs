//! Binary of [`experiments::rde_stability`].
experiments::experiment_main!(experiments::rde_stability::RdeStability);
