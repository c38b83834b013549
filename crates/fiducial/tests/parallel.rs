//! A search on rayon's threads (`Search::in_parallel`, #12) gives exactly the binary image,
//! quads (in order) and markers of the same search on the calling thread (threaded with
//! `--features parallel`, in turn without).

use fiducial::{Detector, DetectorConfig, Dictionary, GrayView, Region, Search};
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
        det.detect_with(&img, &Search::whole_frame().in_parallel(), &mut parallel);
        assert_eq!(parallel, serial, "{w}x{h}");
        assert_eq!(det.quads(), &quads[..], "{w}x{h}: quads differ");
        assert_eq!(det.binary(), &bin[..], "{w}x{h}: binary images differ");
        // A fresh detector, parallel first.
        let mut fresh = Detector::new(DetectorConfig::default());
        fresh.detect_with(&img, &Search::whole_frame().in_parallel(), &mut parallel);
        assert_eq!(parallel, serial, "{w}x{h}, fresh detector");
        // Every other way of searching, on the threads and on the calling thread: at a
        // coarser scale, in regions (one of them over a megapixel at the larger sizes), and
        // appending.
        let regions = [
            Region::new(0, 0, w, h * 3 / 4),
            Region::new(w / 2, h / 2, w / 2, h / 2),
        ];
        for search in [
            Search::whole_frame().at_scale(2),
            Search::in_regions(&regions),
            Search::in_regions(&regions).at_scale(2),
            Search::in_regions(&regions[1..]).appending(),
        ] {
            let mut one = serial.clone();
            let mut threads = serial.clone();
            det.detect_with(&img, &search, &mut one);
            det.detect_with(&img, &search.in_parallel(), &mut threads);
            assert_eq!(threads, one, "{w}x{h}: {search:?}");
        }
    }
}

/// Decoding on threads (#12) merges the threads' markers in quad order: on a large frame of
/// markers, clutter and motion blur (many quads, some read twice, some read as blurred)
/// the markers and the count of blurred readings are those of the single-threaded loop.
#[test]
fn parallel_decoding_equals_single_threaded_on_clutter() {
    let dict = Dictionary::paper();
    let (w, h) = (1920, 1080);
    let cfg = SceneConfig {
        width: w,
        height: h,
        noise: 3.0,
        markers: 24,
        min_side: 20.0,
        max_side: 70.0,
        ..SceneConfig::default()
    };
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let scene = marker_scene(&cfg, &common::entries(dict), &mut rng).expect("the scene fits");
    let clutter = marker_testkit::clutter_frame(w, h, 1.0, 3.0, common::not_markers(), &mut rng)
        .expect("valid clutter size");
    // The markers' scene over the clutter's left half, then a 7 px motion blur.
    let mut px = scene.pixels.clone();
    for y in 0..h {
        px[y * w..y * w + w / 2].copy_from_slice(&clutter[y * w..y * w + w / 2]);
    }
    let px = marker_testkit::motion_blur(&px, w, h, 7.0, 0.4).expect("valid frame");
    let img = GrayView::new(&px, w, h).expect("valid frame");
    let mut det = Detector::new(DetectorConfig::default());
    let (mut serial, mut parallel) = (Vec::new(), Vec::new());
    det.detect(&img, &mut serial);
    let quads = det.quads().to_vec();
    let blurred = det.stats().blurred;
    // (Over 20 with 8 markers until the re-cut stopped handing on components without
    // holes, which the clutter's solid squares are; 10 once quads as dark inside as their
    // border were dropped before the refinement. 24 markers give 18, several per thread.)
    assert!(quads.len() > 10, "only {} quads", quads.len());
    assert!(
        !serial.is_empty() && blurred > 0,
        "{} markers, {blurred} blurred",
        serial.len()
    );
    det.detect_with(&img, &Search::whole_frame().in_parallel(), &mut parallel);
    assert_eq!(parallel, serial);
    assert_eq!(det.stats().blurred, blurred);
    // Components are handed out largest first: their quads and re-cut boxes (whose quads
    // follow) are merged back in component order.
    assert_eq!(det.quads(), &quads[..], "quads differ");
}
