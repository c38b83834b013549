//! Tracking-guided detection reads a leader's narrow faces (#12): a face seen at a grazing
//! angle is as tall as the others, so the region is searched at a coarse scale, where that
//! face's cells fall under a few pixels and its outline is lost; the pipeline searches such
//! faces' boxes at full resolution as well ([`LeaderRegion::fine_regions`]).
#![allow(clippy::unwrap_used)] // Tests may unwrap (house rules).

use fiducial::{Detector, DetectorConfig, GrayView, Region, Search};
use formation_tracker::guided::GuidedConfig;

#[path = "guided_support/mod.rs"]
mod guided_support;

#[test]
fn a_grazing_face_is_read_in_guided_mode() {
    // Robot 1 turned 0.5 rad, 1.5 m ahead: four faces turn towards the camera, one of them
    // about 40 px wide at 3840x2160; the faces are about 270 px tall, so the region is
    // searched at factor 4.
    let (pixels, r) = guided_support::leader_frame(3840, 2160, 1.5, 0.25, 0.5);
    let img = GrayView::new(&pixels, 3840, 2160).unwrap();
    let config = GuidedConfig::default();
    let factor = r.factor(&config);
    assert_eq!(factor, 4);
    // The narrow faces: at least 10 px wide, narrowest first, the grazing one among them.
    let widths: Vec<f64> = r.narrow.iter().flatten().map(|(_, w)| *w).collect();
    assert!(widths.windows(2).all(|w| w[0] <= w[1]), "{widths:?}");
    assert!(widths.iter().all(|&w| w >= 10.0), "{widths:?}");
    assert!(widths[0] < 50.0, "{widths:?}");
    assert_eq!(r.fine_regions(1).count(), 0);
    let fine: Vec<Region> = r.fine_regions(factor).collect();
    assert_eq!(
        fine.len(),
        1,
        "only the grazing face is searched at full resolution"
    );
    assert!(
        fine[0].area() * 20 < r.region.area(),
        "a face's box is small"
    );

    let mut det = Detector::new(DetectorConfig::default());
    let mut full = Vec::new();
    det.detect(&img, &mut full);
    assert_eq!(full.len(), 4);
    // The coarse region alone misses the grazing face ...
    let mut guided = Vec::new();
    det.detect_with(
        &img,
        &Search::in_regions(&[r.region]).at_scale(factor),
        &mut guided,
    );
    assert_eq!(guided.len(), 3);
    // ... its box at full resolution reads it, and nothing is read twice.
    det.detect_with(&img, &Search::in_regions(&fine).appending(), &mut guided);
    let ids = |v: &[fiducial::Decoded]| {
        let mut i: Vec<usize> = v.iter().map(|d| d.index).collect();
        i.sort_unstable();
        i
    };
    assert_eq!(ids(&guided), ids(&full));
}
