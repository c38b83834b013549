//! Accuracy scenes (`cargo xtask detector-accuracy`, seeds of `ChaCha8Rng`, rendered by
//! `synthcam` through `marker_testkit`) in which hard decisions alone lose a marker. The
//! losses are ~20 px markers (cells of ~3 px under blur 1, noise 3) whose quad is found with
//! good corners and the right aspect, but one data cell reads on the wrong side of the
//! threshold by a small margin; the soft-decision correction recovers them. (With the
//! earlier in-crate renderer the seeds were 17, 143, 146, 151, 155 and 174; marker
//! placements are drawn from the RNG exactly as before, and scene 17 now loses one marker
//! even with soft decisions: the one marker in 1600 that `detector-accuracy` misses.)
#![allow(clippy::unwrap_used)] // tests may unwrap (house rules)

use fiducial::{Detector, DetectorConfig, Dictionary, GrayView};
use marker_testkit::{SceneConfig, marker_scene};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
mod common;

/// Scenes of the accuracy run (seeds 0..200) that lose one marker each to hard decisions
/// alone (found by scanning all 200).
const SEEDS: [u64; 4] = [113, 151, 155, 174];

/// All of them still exercise the weak-cell case.
const WEAK_CELL_SEEDS: [u64; 4] = SEEDS;

/// Markers of the scene `seed` read with their own index, and reads of other indices.
fn found(seed: u64, cfg: DetectorConfig) -> (usize, usize, usize) {
    let dict = Dictionary::paper();
    let scene = marker_scene(
        &SceneConfig::default(),
        &common::entries(dict),
        &mut ChaCha8Rng::seed_from_u64(seed),
    )
    .unwrap();
    let img = GrayView::new(&scene.pixels, scene.width, scene.height).unwrap();
    let mut det = Detector::new(cfg);
    let mut out = Vec::new();
    det.detect(&img, &mut out);
    let (right, wrong) = common::tally(&scene, &out);
    (right, wrong, scene.markers.len())
}

#[test]
fn once_lost_small_markers_are_all_found() {
    for seed in SEEDS {
        let (right, wrong, total) = found(seed, DetectorConfig::default());
        assert_eq!((right, wrong), (total, 0), "scene {seed}");
    }
}

#[test]
fn without_soft_decisions_those_scenes_lose_a_marker() {
    // The scenes still exercise the weak-cell case: hard decisions alone miss one marker
    // in each (if this fails, the scenes no longer test the soft decision). The
    // motion-blurred reading, a second reader of quads whose cells are not an entry, is
    // off here: it recovers those markers too.
    let mut cfg = DetectorConfig::default();
    cfg.decode.soft_errors = 0;
    cfg.motion_blur = false;
    for seed in WEAK_CELL_SEEDS {
        let (right, wrong, total) = found(seed, cfg);
        assert_eq!((right, wrong), (total - 1, 0), "scene {seed}");
    }
}
