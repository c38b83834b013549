//! Steady-state detection with the motion-blurred reading (`DetectorConfig::motion_blur`,
//! issue #16) allocates nothing: its least-squares systems live in scratch the detector owns.
//! A counting global allocator watches a stream of motion-blurred frames after a warm-up.
#![allow(unsafe_code)]
#![allow(clippy::unwrap_used)] // tests may unwrap (house rules)

use fiducial::{Detector, DetectorConfig, Dictionary, GrayView};
use marker_testkit::{SceneConfig, marker_scene, motion_blur};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
mod common;
mod counting;

use counting::allocs;

/// Scenes of eight markers (borders 20-70 px) smeared by 5-9 px of motion blur.
fn frames() -> Vec<(Vec<u8>, usize, usize)> {
    let mut rng = ChaCha8Rng::seed_from_u64(16);
    let cfg = SceneConfig {
        min_side: 20.0,
        max_side: 70.0,
        ..SceneConfig::default()
    };
    (0..3)
        .map(|i| {
            let s = marker_scene(&cfg, &common::entries(Dictionary::paper()), &mut rng).unwrap();
            let angle = rng.random_range(0.0..std::f64::consts::PI);
            let length = [5.0, 7.0, 9.0][i];
            let pixels = motion_blur(&s.pixels, s.width, s.height, length, angle).unwrap();
            (pixels, s.width, s.height)
        })
        .collect()
}

#[test]
fn steady_state_blurred_reading_allocates_nothing() {
    let frames = frames();
    let mut det = Detector::new(DetectorConfig {
        motion_blur: true,
        ..DetectorConfig::default()
    });
    let mut plain = Detector::new(DetectorConfig {
        motion_blur: false,
        ..DetectorConfig::default()
    });
    let mut out = Vec::new();
    let mut read_plain = 0;
    for (f, w, h) in &frames {
        let img = GrayView::new(f, *w, *h).unwrap();
        det.detect(&img, &mut out);
        plain.detect(&img, &mut out);
        read_plain += out.len();
    }
    let before = allocs();
    let mut read = 0;
    for _ in 0..2 {
        for (f, w, h) in &frames {
            det.detect(&GrayView::new(f, *w, *h).unwrap(), &mut out);
            read += out.len();
        }
    }
    assert_eq!(allocs() - before, 0);
    // The blurred reading really ran and read markers the plain one could not.
    assert!(
        read > 2 * read_plain,
        "{read} read over two passes, {read_plain} without it"
    );
}
