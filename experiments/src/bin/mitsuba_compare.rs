//! Binary of [`experiments::mitsuba_compare`].
experiments::experiment_main!(experiments::mitsuba_compare::MitsubaCompare);
