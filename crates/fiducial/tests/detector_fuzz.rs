//! The fuzz target `fuzz/fuzz_targets/detect.rs` as a stable proptest: arbitrary bytes, the
//! first four giving width and height, through detection (both thresholds) and decoding of
//! every quad, never panicking and never producing a corner outside the frame. Also runs
//! inputs shaped to reach deep into the pipeline (large blocks of dark and light).
#![allow(clippy::unwrap_used)] // tests may unwrap (house rules)

mod fuzz_body;

use fuzz_body::run;
use proptest::prelude::*;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn arbitrary_bytes(data in prop::collection::vec(any::<u8>(), 0..4096)) {
        run(&data);
    }

    #[test]
    fn blocky_bytes(
        w in 0u8..=255,
        h in 0u8..=255,
        blocks in prop::collection::vec(prop_oneof![Just(0u8), Just(255u8), any::<u8>()], 1..64),
        run_len in 1usize..40,
    ) {
        // Long runs of one value make rectangles that reach contour tracing and refinement.
        let mut data = vec![w % 160, 0, h % 160, 0];
        for b in blocks {
            data.extend(std::iter::repeat_n(b, run_len));
        }
        run(&data);
    }
}

#[test]
fn tiny_and_degenerate_inputs() {
    for data in [
        &[][..],
        &[0, 0, 0, 0][..],
        &[0, 0, 0, 0, 7][..],
        &[255, 255, 255, 255, 0, 255][..],
        &[9, 0, 9, 0, 0, 0, 0, 255, 255, 255][..],
    ] {
        run(data);
    }
}
