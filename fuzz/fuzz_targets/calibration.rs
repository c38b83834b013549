//! Arbitrary bytes as calibration files (OpenCV or ROS YAML): never a panic, and what is accepted is usable. The body is
//! shared with the stable proptest `crates/formation-cli/tests/parsers_fuzz.rs`.
#![no_main]

use libfuzzer_sys::fuzz_target;

#[path = "../../crates/formation-cli/tests/fuzz_body/calibration.rs"]
mod body;

fuzz_target!(|data: &[u8]| body::run(data));
