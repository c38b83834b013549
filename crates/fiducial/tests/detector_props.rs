//! Property tests of the detector on synthetic views: a real marker warped by a random
//! homography is found with the right code and sub-pixel corners in its own NW, NE, SE, SW
//! order, and arbitrary images never make it panic.
#![allow(clippy::unwrap_used)] // tests may unwrap (house rules)

use fiducial::synth::{Canvas, CellPattern};
use fiducial::{Detector, DetectorConfig, Dictionary, GrayView, Threshold};
use proptest::prelude::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// (RMS, largest) corner error of the best cyclic matching of `found` to `truth`.
fn errors(found: &fiducial::Corners, truth: &[[f64; 2]; 4]) -> (f64, f64) {
    (0..4)
        .map(|r| {
            let e: [f64; 4] = std::array::from_fn(|i| {
                let p = found[(i + r) % 4];
                (p.x - truth[i][0]).hypot(p.y - truth[i][1])
            });
            let rms = (e.iter().map(|v| v * v).sum::<f64>() / 4.0).sqrt();
            (rms, e.iter().copied().fold(0.0, f64::max))
        })
        .fold((f64::MAX, f64::MAX), |a, b| if b.0 < a.0 { b } else { a })
}

/// Largest corner error of the best cyclic matching.
fn corner_error(found: &fiducial::Corners, truth: &[[f64; 2]; 4]) -> f64 {
    errors(found, truth).1
}

/// A view of dictionary entry `index` (a 7 x 6 cell marker, square cells) warped to a random
/// pose, and its true corners NW, NE, SE, SW.
fn marker_view(
    index: usize,
    side: f64,
    angle: f64,
    jitter: [f64; 8],
    blur: f64,
    noise: f64,
    seed: u64,
) -> (Vec<u8>, [[f64; 2]; 4]) {
    let dict = Dictionary::paper();
    let code = dict.code(index % dict.len()).unwrap();
    let pattern = CellPattern::from_code(dict.family(), code);
    let (pixels, q) = warp(&pattern, side, angle, jitter, blur, noise, seed);
    (pixels, q)
}

fn view(
    side: f64,
    angle: f64,
    jitter: [f64; 8],
    blur: f64,
    noise: f64,
    seed: u64,
) -> (Vec<u8>, [[f64; 2]; 4]) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let pattern = CellPattern::random_marker(4, 5, &mut rng);
    warp(&pattern, side, angle, jitter, blur, noise, seed)
}

fn warp(
    pattern: &CellPattern,
    side: f64,
    angle: f64,
    jitter: [f64; 8],
    blur: f64,
    noise: f64,
    seed: u64,
) -> (Vec<u8>, [[f64; 2]; 4]) {
    let (w, h) = (220usize, 200usize);
    let (c, s) = (angle.cos(), angle.sin());
    let aspect = pattern.aspect();
    let q: [[f64; 2]; 4] = std::array::from_fn(|i| {
        let u = [[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]][i];
        let (x, y) = (u[0] * side, u[1] * side / aspect);
        [
            110.0 + c * x - s * y + jitter[2 * i] * side,
            100.0 + s * x + c * y + jitter[2 * i + 1] * side,
        ]
    });
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut canvas = Canvas::new(w, h, 215.0).unwrap();
    canvas.draw_pattern(pattern, &q, 25.0, 215.0);
    canvas.blur(blur);
    canvas.noise(noise, &mut rng);
    (canvas.to_gray(), q)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn warped_marker_corners_within_a_tenth_of_a_pixel(
        side in 30.0f64..120.0,
        angle in 0.0f64..std::f64::consts::TAU,
        jitter in prop::array::uniform8(-0.08f64..0.08),
        blur in 0.0f64..1.5,
        noise in 0.0f64..3.0,
        seed in any::<u64>(),
    ) {
        let (pixels, truth) = view(side, angle, jitter, blur, noise, seed);
        let img = GrayView::new(&pixels, 220, 200).unwrap();
        let mut det = Detector::new(DetectorConfig::default());
        let quads = det.find_quads(&img);
        let (rms, max) = quads
            .iter()
            .map(|q| errors(&q.corners, &truth))
            .fold((f64::MAX, f64::MAX), |a, b| if b.0 < a.0 { b } else { a });
        // RMS over the four corners within 0.1 px; single corners (noise on unblurred edges
        // has a tail) within 0.15 px.
        prop_assert!(rms <= 0.1 && max <= 0.15, "corner errors rms {rms} max {max} px over {} quads", quads.len());
    }

    #[test]
    fn warped_real_marker_is_read_with_its_code_and_corner_order(
        index in 0usize..100,
        side in 30.0f64..120.0,
        angle in 0.0f64..std::f64::consts::TAU,
        jitter in prop::array::uniform8(-0.08f64..0.08),
        blur in 0.0f64..1.5,
        noise in 0.0f64..3.0,
        seed in any::<u64>(),
    ) {
        let (pixels, truth) = marker_view(index, side, angle, jitter, blur, noise, seed);
        let img = GrayView::new(&pixels, 220, 200).unwrap();
        let mut det = Detector::new(DetectorConfig::default());
        let mut found = Vec::new();
        det.detect(&img, &mut found);
        prop_assert_eq!(found.len(), 1, "markers read: {:?}", found);
        let d = found[0];
        let dict = Dictionary::paper();
        prop_assert_eq!(d.index, index % dict.len());
        prop_assert_eq!(Some(d.code), dict.code(d.index));
        // Corners in the marker's own order: no cyclic matching here.
        let e: Vec<f64> = (0..4)
            .map(|i| (d.corners[i].x - truth[i][0]).hypot(d.corners[i].y - truth[i][1]))
            .collect();
        let rms = (e.iter().map(|v| v * v).sum::<f64>() / 4.0).sqrt();
        prop_assert!(rms <= 0.1 && e.iter().all(|&v| v <= 0.15), "corner errors {:?}", e);
    }

    #[test]
    fn arbitrary_images_never_panic(
        w in 1usize..48,
        h in 1usize..48,
        bytes in prop::collection::vec(any::<u8>(), 48 * 48),
        otsu in any::<bool>(),
    ) {
        let img = GrayView::new(&bytes[..w * h], w, h).unwrap();
        let mut cfg = DetectorConfig::default();
        if otsu {
            cfg.threshold = Threshold::Otsu;
        }
        let mut det = Detector::new(cfg);
        for q in det.find_quads(&img) {
            for p in q.corners {
                prop_assert!(p.x.is_finite() && p.y.is_finite());
                prop_assert!(p.x >= -0.5 && p.y >= -0.5 && p.x <= w as f64 - 0.5 && p.y <= h as f64 - 0.5);
            }
        }
    }

    #[test]
    fn blocky_images_never_panic(
        w in 1usize..120,
        h in 1usize..120,
        cells in prop::collection::vec(any::<bool>(), 64),
        scale in 1usize..20,
    ) {
        // Large blocks of black and white make many quad candidates, unlike random bytes.
        let pixels: Vec<u8> = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w / scale, i / w / scale);
                if cells[(y * 8 + x) % 64] { 20 } else { 230 }
            })
            .collect();
        let img = GrayView::new(&pixels, w, h).unwrap();
        let mut det = Detector::new(DetectorConfig::default());
        let n = det.find_quads(&img).len();
        prop_assert!(n <= w * h);
    }
}

#[test]
fn a_marker_touching_the_frame_border_is_rejected() {
    // The same marker, shifted until its border touches the frame edge.
    let mut canvas = Canvas::new(120, 100, 215.0).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let p = CellPattern::random_marker(4, 5, &mut rng);
    let q = [[0.2, 20.0], [60.0, 20.0], [60.0, 80.0], [0.2, 80.0]];
    canvas.draw_pattern(&p, &q, 25.0, 215.0);
    let px = canvas.to_gray();
    let img = GrayView::new(&px, 120, 100).unwrap();
    let mut det = Detector::new(DetectorConfig::default());
    let touching = det
        .find_quads(&img)
        .iter()
        .filter(|q| q.corners.iter().any(|c| c.x < 2.0))
        .count();
    assert_eq!(touching, 0);

    // Moved inside, it is found.
    let mut canvas = Canvas::new(120, 100, 215.0).unwrap();
    let q = [[20.0, 20.0], [80.0, 20.0], [80.0, 80.0], [20.0, 80.0]];
    canvas.draw_pattern(&p, &q, 25.0, 215.0);
    let px = canvas.to_gray();
    let img = GrayView::new(&px, 120, 100).unwrap();
    let best = det
        .find_quads(&img)
        .iter()
        .map(|f| corner_error(&f.corners, &q))
        .fold(f64::MAX, f64::min);
    assert!(best < 0.05, "{best}");
}

#[test]
fn otsu_finds_the_marker_under_even_light() {
    let (pixels, truth) = view(80.0, 0.3, [0.0; 8], 1.0, 2.0, 9);
    let img = GrayView::new(&pixels, 220, 200).unwrap();
    let mut det = Detector::new(DetectorConfig {
        threshold: Threshold::Otsu,
        ..DetectorConfig::default()
    });
    let best = det
        .find_quads(&img)
        .iter()
        .map(|q| corner_error(&q.corners, &truth))
        .fold(f64::MAX, f64::min);
    assert!(best < 0.1, "{best}");
}
