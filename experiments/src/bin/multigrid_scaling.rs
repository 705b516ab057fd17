//! Binary of [`experiments::multigrid_scaling`].
experiments::experiment_main!(experiments::multigrid_scaling::MultigridScaling);
