//! Steady-state detection allocates nothing: a counting global allocator watches a stream of
//! frames of one size after a warm-up pass.
#![allow(unsafe_code)]
#![allow(clippy::unwrap_used)] // tests may unwrap (house rules)

use fiducial::{Detector, DetectorConfig, Dictionary, GrayView, Region, Search, Threshold};
use marker_testkit::{SceneConfig, clutter_frame, marker_scene};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
mod common;
mod counting;

use counting::allocs;

fn frames() -> Vec<Vec<u8>> {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let cfg = SceneConfig::default();
    let mut frames: Vec<Vec<u8>> = (0..3)
        .map(|_| {
            marker_scene(&cfg, &common::entries(Dictionary::paper()), &mut rng)
                .unwrap()
                .pixels
        })
        .collect();
    frames.push(clutter_frame(640, 480, 1.0, 3.0, common::not_markers(), &mut rng).unwrap());
    frames
}

fn allocations_in_second_pass(threshold: Threshold) -> (usize, usize) {
    let frames = frames();
    let mut det = Detector::new(DetectorConfig {
        threshold,
        ..DetectorConfig::default()
    });
    let mut out = Vec::new();
    // Warm-up: buffers grow to the stream's needs.
    for f in &frames {
        det.detect(&GrayView::new(f, 640, 480).unwrap(), &mut out);
    }
    let before = allocs();
    let mut read = 0;
    for _ in 0..2 {
        for f in &frames {
            det.detect(&GrayView::new(f, 640, 480).unwrap(), &mut out);
            read += out.len();
        }
    }
    (allocs() - before, read)
}

#[test]
fn steady_state_detection_allocates_nothing() {
    let (allocs, read) = allocations_in_second_pass(Threshold::default());
    assert_eq!(allocs, 0);
    // The frames really contained markers that were read (6 frames with 8 each, 2 passes).
    assert!(read >= 2 * 3 * 7, "only {read} markers read");
    let (allocs, _) = allocations_in_second_pass(Threshold::Otsu);
    assert_eq!(allocs, 0);
}

/// Guided mode: regions around each marker of the frame (as a tracker would predict them),
/// and a coarse full scan, over the same stream twice; the second pass allocates nothing.
#[test]
fn steady_state_guided_detection_allocates_nothing() {
    let frames = frames();
    let mut det = Detector::new(DetectorConfig::default());
    let mut out = Vec::new();
    // The regions of each frame: every marker's box with a 12 px margin, from a full scan.
    let regions: Vec<Vec<Region>> = frames
        .iter()
        .map(|f| {
            det.detect(&GrayView::new(f, 640, 480).unwrap(), &mut out);
            out.iter()
                .filter_map(|d| {
                    let xs = d.corners.map(|c| c.x);
                    let ys = d.corners.map(|c| c.y);
                    let lo = |v: [f64; 4]| v.iter().copied().fold(f64::INFINITY, f64::min);
                    let hi = |v: [f64; 4]| v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                    Region::from_bounds(
                        lo(xs) - 12.0,
                        lo(ys) - 12.0,
                        hi(xs) + 12.0,
                        hi(ys) + 12.0,
                        640,
                        480,
                    )
                })
                .collect()
        })
        .collect();
    let pass = |det: &mut Detector, out: &mut Vec<_>| {
        let mut read = 0;
        for (f, r) in frames.iter().zip(&regions) {
            let img = GrayView::new(f, 640, 480).unwrap();
            det.detect_with(&img, &Search::in_regions(r), out);
            read += out.len();
            det.detect_with(&img, &Search::in_regions(r).at_scale(2), out);
            read += out.len();
            det.detect_with(&img, &Search::whole_frame().at_scale(2), out);
            det.detect(&img, out);
        }
        read
    };
    pass(&mut det, &mut out);
    let before = allocs();
    let read = pass(&mut det, &mut out);
    assert_eq!(allocs() - before, 0);
    assert!(read >= 3 * 7, "only {read} markers read in the regions");
}

#[test]
fn the_counter_sees_a_fresh_detector_allocate() {
    // Guards the test above: a first frame must allocate, or the counter is not counting.
    let frames = frames();
    let before = allocs();
    let mut det = Detector::new(DetectorConfig::default());
    let mut out = Vec::new();
    det.detect(&GrayView::new(&frames[0], 640, 480).unwrap(), &mut out);
    assert!(allocs() > before);
}
