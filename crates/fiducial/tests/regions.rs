//! Region-of-interest and coarse-scale detection (#12) read the same markers, with the same
//! corners, as a full-resolution scan of the whole frame.
#![allow(clippy::unwrap_used)] // tests may unwrap (house rules)

use fiducial::{Decoded, Detector, DetectorConfig, Dictionary, GrayView, Region, Search};
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
        det.detect_with(&img, &Search::in_regions(&regions), &mut roi);
        let mut a: Vec<usize> = full.iter().map(|d| d.index).collect();
        let mut b: Vec<usize> = roi.iter().map(|d| d.index).collect();
        a.sort_unstable();
        b.sort_unstable();
        assert_eq!(a, b, "seed {seed}");
        // Regions are put on the binarization's tile grid, so a marker well inside one has
        // the full scan's outline and the same corners: all but one to 2e-13 px, the worst
        // 3.4e-6 px. Before the alignment the worst moved 8.0e-4 px (seed 17, id 72).
        for d in &roi {
            let e = corner_error(&full, d);
            assert!(
                e < 2e-5,
                "seed {seed} id {}: corners moved {e:.3e} px",
                d.index
            );
        }
        // A region without any marker reads nothing; a region list of the whole frame
        // reads what the full scan reads.
        det.detect_with(
            &img,
            &Search::in_regions(&[Region::new(0, 0, 8, 8)]),
            &mut roi,
        );
        assert!(roi.is_empty());
        det.detect_with(
            &img,
            &Search::in_regions(&[Region::full(640, 480)]),
            &mut roi,
        );
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
        det.detect_with(&img, &Search::whole_frame().at_scale(2), &mut coarse);
        check_coarse(seed, &full, &coarse, 40.0);
        // Regions at a coarser scale: every marker of 80 px or more at 3 and at 4.
        let everything = [Region::full(1280, 960)];
        for factor in [3, 4] {
            det.detect_with(
                &img,
                &Search::in_regions(&everything).at_scale(factor),
                &mut coarse,
            );
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

mod aligned {
    use super::Region;
    use proptest::prelude::*;

    proptest! {
        /// An aligned region holds the original, stays in the frame, and its edges lie on
        /// the grid or on the frame's edge.
        #[test]
        fn holds_the_region_on_the_grid_inside_the_frame(
            w in 1usize..2000, h in 1usize..2000,
            fx in 0.0f64..1.0, fy in 0.0f64..1.0, fw in 0.0f64..1.0, fh in 0.0f64..1.0,
            step in 0usize..70,
        ) {
            let x = ((w - 1) as f64 * fx) as usize;
            let y = ((h - 1) as f64 * fy) as usize;
            let r = Region::new(x, y, 1 + ((w - x - 1) as f64 * fw) as usize,
                1 + ((h - y - 1) as f64 * fh) as usize);
            let a = r.aligned(step, w, h);
            prop_assert!(a.x <= r.x && a.y <= r.y);
            prop_assert!(a.x + a.width >= r.x + r.width && a.y + a.height >= r.y + r.height);
            prop_assert!(a.x + a.width <= w && a.y + a.height <= h);
            if step > 1 {
                prop_assert!(a.x.is_multiple_of(step));
                prop_assert!(a.y.is_multiple_of(step));
                prop_assert!((a.x + a.width).is_multiple_of(step) || a.x + a.width == w);
                prop_assert!((a.y + a.height).is_multiple_of(step) || a.y + a.height == h);
            } else {
                prop_assert_eq!(a, r);
            }
        }
    }
}
