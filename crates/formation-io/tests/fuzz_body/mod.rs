//! The bodies of the fuzz targets in `fuzz/fuzz_targets/` for this crate's readers, shared
//! with the stable proptest twin `tests/parsers_fuzz.rs`. Each takes arbitrary bytes as one
//! kind of user file, parses it the way the tool does, and asserts that nothing panics and
//! that what the parser accepts is usable (finite numbers, sizes within their limits). One
//! file per parser, so that each fuzz target includes only its own body with `#[path]`.

pub mod bag;
pub mod controller;
pub mod image;
pub mod inputs;
pub mod rig;
pub mod y4m;
