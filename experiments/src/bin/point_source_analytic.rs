//! Binary of [`experiments::point_source_analytic`].
experiments::experiment_main!(experiments::point_source_analytic::PointSourceAnalytic);
