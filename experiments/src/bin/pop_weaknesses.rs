//! Binary of [`experiments::pop_weaknesses`].
experiments::experiment_main!(experiments::pop_weaknesses::PopWeaknesses);
