//! Binary of [`experiments::lpm_cloud`].
experiments::experiment_main!(experiments::lpm_cloud::LpmCloud);
