//! Binary of [`experiments::pop_residuum`].
experiments::experiment_main!(experiments::pop_residuum::PopResiduum);
