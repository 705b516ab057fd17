//! `transport_references` flag errors. Its CSV interface is checked by `tests/registry.rs`,
//! and its claims (energy balance, Grosjean's few-percent band) on the same quick run there.

// Test helpers unwrap: a failed setup should fail the test loudly.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use clap::Parser;
use experiments::transport_references;

#[test]
fn transport_references_rejects_bad_flags() {
    for bad in [
        ["--albedo", "1.0"],
        ["--h-albedo", "1.5"],
        ["--g", "1"],
        ["--mu0", "0"],
    ] {
        let mut argv = vec!["transport_references", "--quick", "--no-progress"];
        argv.extend(bad);
        let a = transport_references::Args::parse_from(argv);
        assert!(transport_references::run(&a).is_err(), "{bad:?}");
    }
}
