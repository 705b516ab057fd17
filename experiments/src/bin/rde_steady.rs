//! Binary of [`experiments::rde_steady`].
experiments::experiment_main!(experiments::rde_steady::RdeSteady);
