//! Binary of [`experiments::pt_slab`].
experiments::experiment_main!(experiments::pt_slab::PtSlab);
