//! Binary of [`experiments::lpm_accuracy`].
experiments::experiment_main!(experiments::lpm_accuracy::LpmAccuracy);
