//! Binary of [`experiments::emissive_cube`].
experiments::experiment_main!(experiments::emissive_cube::EmissiveCube);
