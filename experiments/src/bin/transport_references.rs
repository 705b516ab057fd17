//! Binary of [`experiments::transport_references`].
experiments::experiment_main!(experiments::transport_references::TransportReferences);
