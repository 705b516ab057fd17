//! Binary of [`experiments::lbm_convergence`].
experiments::experiment_main!(experiments::lbm_convergence::LbmConvergence);
