//! Shared proptest strategies for the workspace's fuzz targets. Every fuzz target is a test whose
//! name starts with `fuzz_`, so that `cargo test fuzz_` selects them all; the number of inputs is
//! proptest's default (256) unless `PROPTEST_CASES` says otherwise (see `tools/fuzz-long`).

pub mod jpeg;
pub mod messages;
pub mod mutation;
