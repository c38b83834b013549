//! The bodies of the parser fuzz targets in `fuzz/fuzz_targets/` for the files the tool reads
//! through `pose` and `formation-sim`, shared with the stable proptest twin
//! `tests/parsers_fuzz.rs`. Each takes arbitrary bytes as one kind of user file, parses it the
//! way the tool does, and asserts that nothing panics and that what the parser accepts is
//! usable (finite numbers, sizes within their limits). One file per parser, so that each fuzz
//! target includes only its own body with `#[path]`. `formation-io` has the bodies of its own
//! readers.

pub mod calibration;
pub mod scenario;
pub mod scene;
