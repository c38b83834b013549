//! Arbitrary bytes through detection and decoding: the first four bytes give the width and
//! height (1..=320 each), the rest are the pixels (cycled if short). Both thresholds and
//! every decode of every quad found must return without panicking, with finite corners
//! inside the frame. Keep in step with `crates/fiducial/tests/detector_fuzz.rs`.
#![no_main]

use fiducial::{DecodeParams, Detector, DetectorConfig, Dictionary, GrayView, Threshold, decode};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
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
                assert!(c.x >= -0.5 && c.y >= -0.5 && c.x <= w as f64 - 0.5 && c.y <= h as f64 - 0.5);
            }
            let _ = decode(&img, &q.corners, Dictionary::paper(), &DecodeParams::default());
        }
        for d in &out {
            assert!(d.index < Dictionary::paper().len());
        }
    }
});
