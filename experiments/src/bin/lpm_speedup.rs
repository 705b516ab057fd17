//! Binary of [`experiments::lpm_speedup`].
experiments::experiment_main!(experiments::lpm_speedup::LpmSpeedup);
