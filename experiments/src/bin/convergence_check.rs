//! Binary of [`experiments::convergence_check`].
experiments::experiment_main!(experiments::convergence_check::ConvergenceCheck);
