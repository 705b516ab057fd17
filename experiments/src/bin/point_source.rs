//! Binary of [`experiments::point_source`].
experiments::experiment_main!(experiments::point_source::PointSource);
