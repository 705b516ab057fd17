//! Binary of [`experiments::pop_ordinates`].
experiments::experiment_main!(experiments::pop_ordinates::PopOrdinates);
