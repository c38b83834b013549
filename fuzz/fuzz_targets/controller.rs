//! Arbitrary bytes as controller files (YAML or JSON): never a panic, and what is accepted is
//! usable. The body is shared with the stable proptest `crates/formation-io/tests/parsers_fuzz.rs`.
#![no_main]

use libfuzzer_sys::fuzz_target;

#[path = "../../crates/formation-io/tests/fuzz_body/controller.rs"]
mod body;

fuzz_target!(|data: &[u8]| body::run(data));
