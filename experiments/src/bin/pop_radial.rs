//! Binary of [`experiments::pop_radial`].
experiments::experiment_main!(experiments::pop_radial::PopRadial);
