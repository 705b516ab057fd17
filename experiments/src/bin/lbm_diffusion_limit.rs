//! Binary of [`experiments::lbm_diffusion_limit`].
experiments::experiment_main!(experiments::lbm_diffusion_limit::LbmDiffusionLimit);
