//! Binary of [`experiments::accuracy_cost`].
experiments::experiment_main!(experiments::accuracy_cost::AccuracyCost);
