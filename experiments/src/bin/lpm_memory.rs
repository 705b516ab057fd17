//! Binary of [`experiments::lpm_memory`].
experiments::experiment_main!(experiments::lpm_memory::LpmMemory);
