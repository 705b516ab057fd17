//! Tests of the RDE kernels.
