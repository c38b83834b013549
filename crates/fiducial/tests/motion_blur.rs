//! Issue #16: markers smeared by motion blur (the camera moving while the shutter is open)
//! are read through the blur-aware fallback (`DetectorConfig::motion_blur`), without wrong
//! codes. Seeds 90,000 on: not the
//! scenes of `cargo xtask detector-accuracy`'s motion-blur rows (70,000 on).
#![allow(clippy::unwrap_used)] // tests may unwrap (house rules)

use fiducial::{Detector, DetectorConfig, Dictionary, GrayView};
use marker_testkit::{
    CellPattern, MarkerScene, SceneConfig, clutter_frame, marker_scene, motion_blur,
};
mod common;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Scene `seed` of eight paper-dictionary markers with borders of `sides` px, blur sigma 1,
/// noise 3, then a box motion blur of `length` px in a random direction.
fn blurred_scene(seed: u64, sides: [f64; 2], length: f64) -> MarkerScene {
    let dict = Dictionary::paper();
    let f = dict.family();
    let all = CellPattern::from_codes(
        f.rows() as usize,
        f.cols() as usize,
        (0..dict.len()).map(|i| dict.code(i).unwrap_or(0)),
    );
    let base = SceneConfig {
        min_side: sides[0],
        max_side: sides[1],
        ..SceneConfig::default()
    };
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut scene = marker_scene(&base, &all, &mut rng).unwrap();
    let angle = rng.random_range(0.0..std::f64::consts::PI);
    scene.pixels = motion_blur(&scene.pixels, scene.width, scene.height, length, angle).unwrap();
    scene
}

/// Markers read and wrong codes over `scenes` scenes of eight markers (borders 20-70 px),
/// blur sigma 1, noise 3, then a box motion blur of `length` px in a random direction.
fn read(length: f64, scenes: u64) -> (usize, usize, usize) {
    let mut det = Detector::new(DetectorConfig {
        motion_blur: true,
        ..DetectorConfig::default()
    });
    let (mut total, mut found, mut wrong) = (0, 0, 0);
    let mut out = Vec::new();
    for seed in 0..scenes {
        let scene = blurred_scene(90_000 + seed, [20.0, 70.0], length);
        let img = GrayView::new(&scene.pixels, scene.width, scene.height).unwrap();
        det.detect(&img, &mut out);
        let (read, misread) = common::tally(&scene, &out);
        total += scene.markers.len();
        found += read;
        wrong += misread;
    }
    (total, found, wrong)
}

/// The 640 x 480 clutter frame of `seed` (blur 1, noise 3; no paper-dictionary entry), as
/// `cargo xtask detector-accuracy` renders its clutter set (seeds 7,000 on).
fn clutter(seed: u64) -> Vec<u8> {
    clutter_frame(
        640,
        480,
        1.0,
        3.0,
        common::not_markers(),
        &mut ChaCha8Rng::seed_from_u64(seed),
    )
    .unwrap()
}

#[test]
fn nine_pixel_motion_blur_is_read_without_wrong_codes() {
    let (total, found, wrong) = read(9.0, 4);
    assert_eq!(wrong, 0);
    // Before the blur-aware fallback: 43 of 80 at 9 px on the detector-accuracy rows.
    assert!(found * 100 >= total * 60, "{found} of {total} read at 9 px");
}

/// Regression: the blurred reading solved its systems for nearly every quad that was not a
/// marker (22 motions, both grid orientations, dense normal matrices), so the criterion
/// bench `fiducial/detect_clutter_640x480` took 515 ms a frame with it against 3 ms
/// without. Only quads that read as a marker's border, with a motion of at least 1.5
/// cells, are re-read now; the work is counted, not timed (house rules).
#[test]
fn clutter_rarely_takes_the_blurred_reading_and_sharp_markers_never() {
    let mut det = Detector::new(DetectorConfig::default());
    let mut out = Vec::new();
    let (mut quads, mut reads) = (0, 0);
    for seed in 43..53 {
        let px = clutter(seed);
        det.detect(&GrayView::new(&px, 640, 480).unwrap(), &mut out);
        assert!(out.is_empty());
        quads += det.quads().len();
        reads += det.stats().blurred;
    }
    eprintln!("clutter: {reads} blurred reads of {quads} quads");
    // At most two blurred readings a frame. (The bound was an eighth of the quads, but the
    // quads are the wrong measure: since the re-cut drops components without holes, which
    // no marker is, these frames give 70 quads instead of 261, and 10 blurred readings
    // instead of 15.)
    assert!(quads >= 20, "the clutter offers only {quads} quads");
    assert!(
        reads <= 2 * 10,
        "{reads} blurred reads of {quads} quads in 10 frames"
    );

    let dict = Dictionary::paper();
    let cfg = SceneConfig {
        width: 640,
        height: 480,
        noise: 3.0,
        ..SceneConfig::default()
    };
    for seed in 0..5 {
        let scene = marker_scene(
            &cfg,
            &common::entries(dict),
            &mut ChaCha8Rng::seed_from_u64(seed),
        )
        .unwrap();
        det.detect(
            &GrayView::new(&scene.pixels, scene.width, scene.height).unwrap(),
            &mut out,
        );
        assert_eq!(out.len(), scene.markers.len());
        assert_eq!(det.stats().blurred, 0, "sharp scene {seed}");
    }
}

/// Regression (issue #31): the second look's re-cut closes outlines that are dark below a
/// quarter of the local range all round, which a marker smeared by the 1.5 cells the blurred
/// reading models is not (next to a white cell its border averages to a third of the
/// contrast or more), so the re-cut's quads are not read as motion-blurred. The frame of the
/// criterion bench `fiducial/detect_clutter_640x480` (clutter seed 43) had one blurred
/// reading, of a re-cut quad, about a quarter of its time.
#[test]
fn the_re_cuts_quads_are_not_read_as_motion_blurred() {
    let mut det = Detector::new(DetectorConfig::default());
    let mut out = Vec::new();
    let px = clutter(43);
    det.detect(&GrayView::new(&px, 640, 480).unwrap(), &mut out);
    assert!(out.is_empty());
    let stats = det.stats();
    // The re-cut did add quads to this frame; none reached the solves.
    assert!(stats.second_quads > 0, "{stats:?}");
    assert_eq!(stats.blurred, 0, "{stats:?}");
}

/// Regression (issue #16): a marker smeared by two cells or more had no quad at all. At
/// the midpoint threshold its one-cell border, averaged with the white data cells next to
/// it, reads light, and its dark component opens into its inside. The light cut of the
/// boxes that gave no quad (`DetectorConfig::motion_blur`) closes the outline again. Seed
/// 90,009, marker 6 (index 49, 28-32 px), 9 px of motion blur: without the motion-blur
/// options no quad lies near it; with them it is read, with corners within 1.5 px.
#[test]
fn a_marker_whose_outline_the_blur_opened_is_found_by_the_light_cut() {
    let dict = Dictionary::paper();
    let base = SceneConfig {
        min_side: 20.0,
        max_side: 70.0,
        ..SceneConfig::default()
    };
    let mut rng = ChaCha8Rng::seed_from_u64(90_009);
    let mut scene = marker_scene(&base, &common::entries(dict), &mut rng).unwrap();
    let angle = rng.random_range(0.0..std::f64::consts::PI);
    scene.pixels = motion_blur(&scene.pixels, scene.width, scene.height, 9.0, angle).unwrap();
    let img = GrayView::new(&scene.pixels, scene.width, scene.height).unwrap();
    let m = &scene.markers[6];
    assert_eq!(m.index, Some(49), "the scene generator changed");
    let near = |q: &[nalgebra::Point2<f64>; 4], tol: f64| {
        m.corners
            .iter()
            .all(|p| q.iter().any(|r| (r - p).norm() < tol))
    };
    let mut out = Vec::new();
    let mut plain = Detector::new(DetectorConfig {
        motion_blur: false,
        ..DetectorConfig::default()
    });
    plain.detect(&img, &mut out);
    assert!(
        !plain.quads().iter().any(|q| near(&q.corners, 6.0)),
        "the midpoint cut already finds this marker's quad: the test no longer shows the light cut"
    );
    let mut det = Detector::new(DetectorConfig::default());
    det.detect(&img, &mut out);
    let d = out
        .iter()
        .find(|d| d.index == 49)
        .expect("marker 49 read through the light cut");
    assert!(
        near(&d.corners, 1.5),
        "corners {:?} against {:?}",
        d.corners,
        m.corners
    );
    assert!(
        out.iter()
            .all(|d| scene.markers.iter().any(|m| m.index == Some(d.index))),
        "a wrong code"
    );
}

/// Regression (issue #16): the least-cost reading of blurred cells read two sharp clutter
/// squares of `cargo xtask detector-accuracy`'s clutter set (frames 259 and 463, seeds
/// 7,259 and 7,463) as markers 1 and 58: the step widths across their sides, which also
/// cross the edges inside them, read motions of 10-20 px, and their random insides were
/// two cheap flips from an entry. It now runs only where the quad's outline itself is
/// smeared outwards.
#[test]
fn sharp_clutter_is_not_read_by_the_least_cost_reading() {
    let mut det = Detector::new(DetectorConfig::default());
    let mut out = Vec::new();
    for seed in [7_259, 7_463] {
        let px = clutter(seed);
        det.detect(&GrayView::new(&px, 640, 480).unwrap(), &mut out);
        assert!(
            out.is_empty(),
            "clutter seed {seed} read as {:?}",
            out.iter().map(|d| d.index).collect::<Vec<_>>()
        );
    }
}

/// Regression (issue #31): the photometric step, whose model blurs by a round Gaussian, was
/// fitted to markers read only by the motion-blurred reading, and at 3 px of motion it put
/// their corners further off (the detector-accuracy row went from 0.0422 to 0.0464 px RMS).
/// A marker the plain reading misses and the blurred reading reads keeps the corners it
/// would have without the step.
#[test]
fn markers_read_only_through_the_blur_skip_the_photometric_step() {
    let cols = Dictionary::paper().family().cols() as f64;
    let default = DetectorConfig::for_pose();
    assert!(default.motion_blur && default.refine.photometric_below_px > 0.0);
    let mut no_fit = default;
    no_fit.refine.photometric_below_px = 0.0;
    let mut plain = default;
    plain.motion_blur = false;
    let mut dets = [default, no_fit, plain].map(Detector::new);
    let (mut blurred, mut sharp_small) = (0, 0);
    let mut outs = [Vec::new(), Vec::new(), Vec::new()];
    for seed in 0..12 {
        let scene = blurred_scene(91_000 + seed, [16.0, 30.0], 4.0);
        let img = GrayView::new(&scene.pixels, scene.width, scene.height).unwrap();
        for (det, out) in dets.iter_mut().zip(outs.iter_mut()) {
            det.detect(&img, out);
        }
        let [with_fit, without_fit, plain_read] = &outs;
        for d in with_fit {
            let other = without_fit
                .iter()
                .find(|o| o.index == d.index)
                .expect("the photometric step does not change what is read");
            if plain_read.iter().any(|p| p.index == d.index) {
                // Read as sampled: small ones are fitted (their corners may move).
                let side = (d.corners[1] - d.corners[0]).norm();
                if side / (cols + 2.0) < 3.0 && d.corners != other.corners {
                    sharp_small += 1;
                }
            } else {
                blurred += 1;
                assert_eq!(d.corners, other.corners, "seed {seed}, marker {}", d.index);
            }
        }
    }
    // Both kinds were exercised.
    assert!(blurred >= 3, "{blurred} markers read only through the blur");
    assert!(sharp_small >= 3, "{sharp_small} small sharp markers fitted");
}

/// Regression (issue #31): the blurred reading's early stop (`MAX_UNEXPLAINED`) was set at
/// 0.08 from our own dictionary's markers, whose samples it explains to within 0.04 of
/// their variance; tag36h11's larger grid leaves up to 0.12 unexplained on markers it reads
/// (`cargo xtask motion-sets` lost 12 tag36h11 markers at 0.08). On these five scenes of
/// tag36h11 markers (40-70 px, 9 px of motion, seeds 95,000 on, where 0.08 and no early
/// stop at all differ) the bound of 0.08 read 33 of the 40 markers, no early stop 38.
#[test]
fn the_early_stop_keeps_the_tag36h11_markers_it_can_read() {
    let dict = fiducial::dictionary_by_name("tag36h11").unwrap();
    let mut det = Detector::with_dictionary(DetectorConfig::default(), dict.clone());
    let mut out = Vec::new();
    let (mut found, mut total) = (0, 0);
    for seed in [95_000u64, 95_023, 95_037, 95_039, 95_044] {
        let base = SceneConfig {
            min_side: 40.0,
            max_side: 70.0,
            ..SceneConfig::default()
        };
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut scene = marker_scene(&base, &common::entries(dict), &mut rng).unwrap();
        let angle = rng.random_range(0.0..std::f64::consts::PI);
        scene.pixels = motion_blur(&scene.pixels, scene.width, scene.height, 9.0, angle).unwrap();
        let img = GrayView::new(&scene.pixels, scene.width, scene.height).unwrap();
        det.detect(&img, &mut out);
        let (read, misread) = common::tally(&scene, &out);
        total += scene.markers.len();
        found += read;
        assert_eq!(misread, 0, "seed {seed}: a wrong code");
    }
    assert_eq!(total, 40);
    assert!(found >= 38, "{found} of {total} read");
}
