//! Binary of [`experiments::rde_controls`].
experiments::experiment_main!(experiments::rde_controls::RdeControls);
