//! The body of the detector fuzz target, shared by `fuzz/fuzz_targets/detect.rs` (libFuzzer,
//! nightly) and `tests/detector_fuzz.rs` (the same inputs as a stable proptest), so the two
//! can never drift apart.

use fiducial::{DecodeParams, Detector, DetectorConfig, Dictionary, GrayView, Threshold, decode};

/// Arbitrary bytes through detection (both thresholds) and decoding of every quad found:
/// the first four bytes give the width and height (1..=320 each), the rest are the pixels
/// (cycled if short). Panics (the failure a fuzzer looks for) if a corner is non-finite or
/// outside the frame, or a decoded index is outside the dictionary.
pub fn run(data: &[u8]) {
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
