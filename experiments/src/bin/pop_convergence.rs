//! Binary of [`experiments::pop_convergence`].
experiments::experiment_main!(experiments::pop_convergence::PopConvergence);
