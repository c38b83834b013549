//! `Detector::detect_parallel` (#12) gives exactly the binary image, quads (in order) and
//! markers of `Detector::detect` (threaded with `--features parallel`, in turn without).

use fiducial::{Detector, DetectorConfig, Dictionary, GrayView};
use marker_testkit::{SceneConfig, marker_scene};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
mod common;

#[test]
fn parallel_detection_equals_single_threaded() {
    let dict = Dictionary::paper();
    // Above the one-megapixel cut (bands run on threads) and below it (calling thread).
    for (w, h, seed) in [(1920, 1080, 7u64), (1280, 1024, 8), (640, 480, 9)] {
        let cfg = SceneConfig {
            width: w,
            height: h,
            noise: 3.0,
            ..SceneConfig::default()
        };
        let px = marker_scene(
            &cfg,
            &common::entries(dict),
            &mut ChaCha8Rng::seed_from_u64(seed),
        )
        .expect("the scene fits its frame")
        .pixels;
        let img = GrayView::new(&px, w, h).expect("valid frame");
        let mut det = Detector::new(DetectorConfig::default());
        let (mut serial, mut parallel) = (Vec::new(), Vec::new());
        det.detect(&img, &mut serial);
        assert!(!serial.is_empty(), "{w}x{h}: no marker read");
        let bin = det.binary().to_vec();
        let quads = det.quads().to_vec();
        det.detect_parallel(&img, &mut parallel);
        assert_eq!(parallel, serial, "{w}x{h}");
        assert_eq!(det.quads(), &quads[..], "{w}x{h}: quads differ");
        assert_eq!(det.binary(), &bin[..], "{w}x{h}: binary images differ");
        // A fresh detector, parallel first.
        let mut fresh = Detector::new(DetectorConfig::default());
        fresh.detect_parallel(&img, &mut parallel);
        assert_eq!(parallel, serial, "{w}x{h}, fresh detector");
    }
}
