//! Binary of [`experiments::pop_cube`].
experiments::experiment_main!(experiments::pop_cube::PopCube);
