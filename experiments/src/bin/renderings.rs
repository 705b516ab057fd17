//! Binary of [`experiments::renderings`].
experiments::experiment_main!(experiments::renderings::Renderings);
