//! Binary of [`experiments::convergence`].
experiments::experiment_main!(experiments::convergence::Convergence);
