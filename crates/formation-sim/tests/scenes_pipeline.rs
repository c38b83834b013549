//! The done-when criteria of the scenes issue, end to end (render, detect, group, pose,
//! formation variables), on the paper's five scenes and a seeded subset of the random
//! scenes of `docs/random-scenes.md`: every face visible at most 75 deg off-axis and at least
//! 14 px wide is read, no code is wrong, and every robot with such a face has a distance
//! error of at most 1 % and a heading error of at most 1 degree.

use fiducial::Dictionary;
use formation_sim::evaluate::{
    MAX_DISTANCE_ERROR_PCT, MAX_HEADING_ERROR_DEG, SceneReport, default_detector, evaluate_scene,
};
use formation_sim::paper::{PAPER_FIGURES, paper_scene, random_scene};
use formation_sim::scene::SceneSpec;
use formation_tracker::rig::RigModel;
use formation_tracker::robots::RobotConfig;

fn score(spec: &SceneSpec, paper: Option<(&[u8], &[u8])>) -> SceneReport {
    let dict = Dictionary::paper();
    let mut detector = default_detector(dict);
    evaluate_scene(
        spec,
        &RigModel::reference(),
        dict,
        &mut detector,
        &RobotConfig::default(),
        paper,
    )
    .expect("scene evaluates")
    .report
}

fn check(report: &SceneReport) {
    assert_eq!(report.stray_codes, 0, "{}: stray codes", report.scene);
    for r in &report.robots {
        let ctx = format!("{} robot {}", report.scene, r.robot);
        assert_eq!(r.wrong_codes, 0, "{ctx}: wrong codes");
        for f in &r.faces_required {
            assert!(r.faces_read.contains(f), "{ctx}: face {f} not read ({r:?})");
        }
        if !r.faces_required.is_empty() {
            let d = r
                .distance_error_pct
                .expect("a robot with a readable face is measured");
            let h = r.heading_error.expect("and has a heading").to_degrees();
            assert!(
                d <= MAX_DISTANCE_ERROR_PCT,
                "{ctx}: distance error {d:.3} %"
            );
            assert!(
                h <= MAX_HEADING_ERROR_DEG,
                "{ctx}: heading error {h:.3} deg"
            );
        }
        assert!(r.pass, "{ctx}");
    }
    assert!(report.pass, "{}", report.scene);
}

#[test]
fn paper_scenes_meet_the_criteria() {
    for f in &PAPER_FIGURES {
        let report = score(&paper_scene(f.fig).unwrap(), f.paper_faces);
        // The scenes show what the paper's figures show: two leaders, both measured.
        assert_eq!(report.robots.len(), 2);
        check(&report);
    }
}

#[test]
fn random_scenes_meet_the_criteria() {
    // The first twelve scenes of the series documented in docs/random-scenes.md (seed 2026),
    // for speed; the document scores all 100 (`cargo xtask random-scenes`) and lists the
    // scenes that fail.
    for i in 0..12 {
        check(&score(&random_scene(2026, i), None));
    }
}

#[test]
fn scenes_that_once_failed_meet_the_criteria() {
    // Regressions, each with what was wrong:
    // - random-44: robot 2 through one near-frontal face at 2 m read a heading 1.18 deg off.
    //   Not noise (1.02 deg mean over 30 noise seeds, sd 0.19): the renderer sampled each
    //   pixel on an 8 x 8 grid of cell centres, which places the level camera's vertical
    //   marker edges up to 1/16 px off; now every sample has its own column (synthcam).
    // - random-85 (and random-89 under another noise seed): a face 14-15 px wide at 68 deg
    //   off-axis, whose two-pixel border the threshold broke where a white data cell touches
    //   it, gave no quad; notched sides are now accepted (fiducial::quad).
    let mut renoised = random_scene(2026, 89);
    renoised.render.seed = 101_089;
    for spec in [random_scene(2026, 44), random_scene(2026, 85), renoised] {
        check(&score(&spec, None));
    }
}
