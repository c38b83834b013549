//! The decoded-pattern refinement (`RefineConfig::with_pattern`, issue #13): on small
//! markers it must beat the plain refinement clearly, for our family and for tag36h11, on
//! scenes it was not tuned on (the accuracy scenes and the documented figures use seeds
//! 0-199 and 50,000 on; these use 7,000 on), under uniform light and under a 3:1 gradient.

use fiducial::{Detector, DetectorConfig, Dictionary, GrayView, dictionary_by_name};
use marker_testkit::{SceneConfig, marker_scene};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

mod common;

/// Corner RMS (px) of the markers of 20-40 px found with and without the pattern step, and
/// how many such markers each found.
fn rms_small(dict: &Dictionary, lighting: f64, seeds: std::ops::Range<u64>) -> [(f64, usize); 2] {
    let entries = common::entries(dict);
    let cfg = SceneConfig {
        max_side: 60.0,
        lighting,
        ..SceneConfig::default()
    };
    let mut out = [(0.0, 0); 2];
    for (k, with) in [false, true].into_iter().enumerate() {
        let mut dc = DetectorConfig::default();
        dc.refine.with_pattern = with;
        let mut det = Detector::with_dictionary(dc, dict.clone());
        let (mut se, mut n) = (0.0, 0usize);
        let mut found = Vec::new();
        for seed in seeds.clone() {
            let scene = marker_scene(&cfg, &entries, &mut ChaCha8Rng::seed_from_u64(seed))
                .expect("the scene fits its frame");
            let img = GrayView::new(&scene.pixels, scene.width, scene.height).expect("frame");
            det.detect(&img, &mut found);
            for m in &scene.markers {
                let side = (0..4)
                    .map(|i| (m.corners[(i + 1) % 4] - m.corners[i]).norm())
                    .fold(0.0, f64::max);
                if side >= 40.0 {
                    continue;
                }
                let Some(d) = found.iter().find(|d| Some(d.index) == m.index) else {
                    continue;
                };
                se += (0..4)
                    .map(|i| (d.corners[i] - m.corners[i]).norm_squared())
                    .sum::<f64>();
                n += 1;
            }
        }
        out[k] = ((se / (4 * n.max(1)) as f64).sqrt(), n);
    }
    out
}

fn check(name: &str, dict: &Dictionary, lighting: f64, bound: f64) {
    let [(plain, n_plain), (pattern, n_pattern)] = rms_small(dict, lighting, 7_000..7_030);
    assert!(n_plain >= 60, "{name}: only {n_plain} small markers found");
    assert_eq!(
        n_plain, n_pattern,
        "{name}: the pattern step changed what is found"
    );
    assert!(
        pattern < bound * plain,
        "{name}, light {lighting}:1: corner RMS {pattern:.4} px with the pattern step against \
         {plain:.4} without"
    );
}

#[test]
fn the_pattern_step_shrinks_small_markers_corner_error_for_our_family() {
    check("own", Dictionary::paper(), 1.0, 0.7);
}

#[test]
fn the_pattern_step_shrinks_small_markers_corner_error_for_tag36h11() {
    let tag = dictionary_by_name("tag36h11").expect("a standard family");
    check("tag36h11", tag, 1.0, 0.7);
}

/// Under a 3:1 light gradient most small markers' profiles reach beyond their one-cell quiet
/// zone, where the gradient read from opposite sides is confirmed by the level along the
/// sides between. Before, such markers kept their plain corners and the step did little
/// (0.96 of the plain RMS for our family on these seeds); now 0.77, and 0.73 for tag36h11.
#[test]
fn under_a_light_gradient_the_pattern_step_shrinks_small_markers_corner_error() {
    check("own", Dictionary::paper(), 3.0, 0.85);
    let tag = dictionary_by_name("tag36h11").expect("a standard family");
    check("tag36h11", tag, 3.0, 0.85);
}
