//! Region-of-interest and coarse-scale detection (#12) read the same markers, with the same
//! corners, as a full-resolution scan of the whole frame.
#![allow(clippy::unwrap_used)] // tests may unwrap (house rules)

use fiducial::{Decoded, Detector, DetectorConfig, Dictionary, GrayView, Region};
use marker_testkit::{SceneConfig, marker_scene};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
mod common;

fn scene(seed: u64, width: usize, height: usize) -> Vec<u8> {
    let cfg = SceneConfig {
        width,
        height,
        ..SceneConfig::default()
    };
    marker_scene(
        &cfg,
        &common::entries(Dictionary::paper()),
        &mut ChaCha8Rng::seed_from_u64(seed),
    )
    .unwrap()
    .pixels
}

fn side(d: &Decoded) -> f64 {
    (0..4)
        .map(|i| (d.corners[(i + 1) % 4] - d.corners[i]).norm())
        .fold(f64::INFINITY, f64::min)
}

fn box_of(d: &Decoded, margin: f64, w: usize, h: usize) -> Region {
    let lo = |f: fn(&nalgebra::Point2<f64>) -> f64| {
        d.corners.iter().map(f).fold(f64::INFINITY, f64::min)
    };
    let hi = |f: fn(&nalgebra::Point2<f64>) -> f64| {
        d.corners.iter().map(f).fold(f64::NEG_INFINITY, f64::max)
    };
    Region::from_bounds(
        lo(|p| p.x) - margin,
        lo(|p| p.y) - margin,
        hi(|p| p.x) + margin,
        hi(|p| p.y) + margin,
        w,
        h,
    )
    .unwrap()
}

/// The largest corner distance between a reading and the full scan's reading of that id.
fn corner_error(full: &[Decoded], d: &Decoded) -> f64 {
    let f = full.iter().find(|f| f.index == d.index).unwrap();
    (0..4)
        .map(|i| (f.corners[i] - d.corners[i]).norm())
        .fold(0.0, f64::max)
}

#[test]
fn regions_read_what_the_full_frame_reads() {
    for seed in [3u64, 17, 29] {
        let pixels = scene(seed, 640, 480);
        let img = GrayView::new(&pixels, 640, 480).unwrap();
        let mut det = Detector::new(DetectorConfig::default());
        let (mut full, mut roi) = (Vec::new(), Vec::new());
        det.detect(&img, &mut full);
        assert!(full.len() >= 6, "seed {seed}: only {} markers", full.len());
        let regions: Vec<Region> = full.iter().map(|d| box_of(d, 10.0, 640, 480)).collect();
        det.detect_in_regions(&img, &regions, 1, &mut roi);
        let mut a: Vec<usize> = full.iter().map(|d| d.index).collect();
        let mut b: Vec<usize> = roi.iter().map(|d| d.index).collect();
        a.sort_unstable();
        b.sort_unstable();
        assert_eq!(a, b, "seed {seed}");
        for d in &roi {
            let e = corner_error(&full, d);
            assert!(
                e < 0.05,
                "seed {seed} id {}: corners moved {e:.3} px",
                d.index
            );
        }
        // A region without any marker reads nothing; a region list of the whole frame
        // reads what the full scan reads.
        det.detect_in_regions(&img, &[Region::new(0, 0, 8, 8)], 1, &mut roi);
        assert!(roi.is_empty());
        det.detect_in_regions(&img, &[Region::full(640, 480)], 1, &mut roi);
        assert_eq!(roi.len(), full.len());
    }
}

#[test]
fn coarse_scan_finds_big_markers_with_full_resolution_corners() {
    for seed in [5u64, 41] {
        let pixels = scene(seed, 1280, 960);
        let img = GrayView::new(&pixels, 1280, 960).unwrap();
        let mut det = Detector::new(DetectorConfig::default());
        let (mut full, mut coarse) = (Vec::new(), Vec::new());
        det.detect(&img, &mut full);
        det.detect_coarse(&img, 2, &mut coarse);
        check_coarse(seed, &full, &coarse, 40.0);
        // Regions at a coarser scale: every marker of 80 px or more at 3 and at 4.
        let everything = [Region::full(1280, 960)];
        for factor in [3, 4] {
            det.detect_in_regions(&img, &everything, factor, &mut coarse);
            check_coarse(seed, &full, &coarse, 20.0 * factor as f64);
        }
    }
}

/// Every marker of `full` at least `min_side` px is in `coarse`, with the same corners.
fn check_coarse(seed: u64, full: &[Decoded], coarse: &[Decoded], min_side: f64) {
    {
        for f in full.iter().filter(|f| side(f) >= min_side) {
            assert!(
                coarse.iter().any(|c| c.index == f.index),
                "seed {seed}: marker {} of side {:.0} px missed by the coarse scan",
                f.index,
                side(f)
            );
        }
        for c in coarse {
            let e = corner_error(full, c);
            assert!(
                e < 0.05,
                "seed {seed} id {}: corners moved {e:.3} px",
                c.index
            );
        }
    }
}
