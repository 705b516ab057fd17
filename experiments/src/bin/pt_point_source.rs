//! Binary of [`experiments::pt_point_source`].
experiments::experiment_main!(experiments::pt_point_source::PtPointSource);
