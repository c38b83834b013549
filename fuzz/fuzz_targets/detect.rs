//! Arbitrary bytes through detection and decoding: the first four bytes give the width and
//! height (1..=320 each), the rest are the pixels (cycled if short). Both thresholds and
//! every decode of every quad found must return without panicking, with finite corners
//! inside the frame. The body is shared with the stable proptest
//! `crates/fiducial/tests/detector_fuzz.rs`.
#![no_main]

use libfuzzer_sys::fuzz_target;

#[path = "../../crates/fiducial/tests/fuzz_body/mod.rs"]
mod fuzz_body;

fuzz_target!(|data: &[u8]| fuzz_body::run(data));
