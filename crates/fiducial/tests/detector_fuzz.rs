//! The fuzz target `fuzz/fuzz_targets/detect.rs` as a stable proptest: arbitrary bytes, the
//! first four giving width and height, through detection (both thresholds) and decoding of
//! every quad, never panicking and never producing a corner outside the frame. Also runs
//! inputs shaped to reach deep into the pipeline (large blocks of dark and light).
#![allow(clippy::unwrap_used)] // tests may unwrap (house rules)

use fiducial::{DecodeParams, Detector, DetectorConfig, Dictionary, GrayView, Threshold, decode};
use proptest::prelude::*;

/// The fuzz target's body (keep in step with `fuzz/fuzz_targets/detect.rs`).
fn run(data: &[u8]) {
    if data.len() < 5 {
        return;
    }
    let w = 1 + (usize::from(data[0]) | usize::from(data[1]) << 8) % 320;
    let h = 1 + (usize::from(data[2]) | usize::from(data[3]) << 8) % 320;
    let body = &data[4..];
    let pixels: Vec<u8> = body.iter().copied().cycle().take(w * h).collect();
    let img = GrayView::new(&pixels, w, h).expect("shape is valid by construction");
    for threshold in [Threshold::default(), Threshold::Otsu] {
        let mut det = Detector::new(DetectorConfig {
            threshold,
            ..DetectorConfig::default()
        });
        let mut out = Vec::new();
        det.detect(&img, &mut out);
        for q in det.quads() {
            for c in q.corners {
                assert!(c.x.is_finite() && c.y.is_finite());
                assert!(
                    c.x >= -0.5 && c.y >= -0.5 && c.x <= w as f64 - 0.5 && c.y <= h as f64 - 0.5
                );
            }
            let _ = decode(
                &img,
                &q.corners,
                Dictionary::paper(),
                &DecodeParams::default(),
            );
        }
        for d in &out {
            assert!(d.index < Dictionary::paper().len());
        }
    }
}

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
