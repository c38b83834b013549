//! The parser fuzz targets of `fuzz/fuzz_targets/` for the files the tool reads through the
//! other crates (calibration YAML, scene files, scenario files) as stable proptests that CI
//! runs, through the same bodies (`tests/fuzz_body/`) as the fuzz targets: never a panic, and
//! what a parser accepts is usable. The readers of `formation-io` (rig files, inputs CSV,
//! y4m, images, bags) have theirs in that crate. The long campaigns
//! (`fuzz/run-campaigns.sh`) and what they found are recorded in docs/reliability.md.
#![allow(clippy::unwrap_used)] // tests may unwrap (house rules)

mod fuzz_body;

use marker_testkit::edits::{apply, edit, switched};
use proptest::prelude::*;

/// Text seeds: `(first byte for the YAML/JSON switch, file)`.
const CALIBRATIONS: [&str; 2] = [
    include_str!("../../../fixtures/calibration/opencv_640x480.yaml"),
    include_str!("../../../fixtures/calibration/ros_camera_info.yaml"),
];
const SCENES: [(u8, &str); 2] = [
    (0, include_str!("../../../fixtures/scenes/fig7.yaml")),
    (
        1,
        include_str!("../../../fixtures/scenes/three-robots-panned.json"),
    ),
];
const SCENARIOS: [(u8, &str); 3] = [
    (
        0,
        include_str!("../../../fixtures/scenarios/reference.yaml"),
    ),
    (0, include_str!("../../../fixtures/scenarios/l12-step.yaml")),
    (
        0,
        include_str!("../../../fixtures/scenarios/hard-turn.yaml"),
    ),
];

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    #[test]
    fn calibration_files(seed in 0usize..2, edits in prop::collection::vec(edit(), 0..6),
                         noise in prop::collection::vec(any::<u8>(), 0..512)) {
        fuzz_body::calibration::run(&apply(CALIBRATIONS[seed].as_bytes(), &edits));
        fuzz_body::calibration::run(&noise);
    }

    #[test]
    fn scene_files(seed in 0usize..2, edits in prop::collection::vec(edit(), 0..6),
                   noise in prop::collection::vec(any::<u8>(), 0..512)) {
        let (json, text) = SCENES[seed];
        fuzz_body::scene::run(&apply(&switched(json, text), &edits));
        fuzz_body::scene::run(&noise);
    }

    #[test]
    fn scenario_files(seed in 0usize..3, edits in prop::collection::vec(edit(), 0..6),
                      noise in prop::collection::vec(any::<u8>(), 0..512)) {
        let (json, text) = SCENARIOS[seed];
        fuzz_body::scenario::run(&apply(&switched(json, text), &edits));
        fuzz_body::scenario::run(&noise);
    }
}

#[test]
fn the_seeds_are_accepted() {
    // The edits start from inputs the parsers accept, so the proptests explore near them.
    for text in CALIBRATIONS {
        assert!(pose::Camera::from_yaml_str(text).is_ok());
    }
    for (json, text) in SCENES {
        formation_sim::scene::SceneSpec::from_text(text, json == 1, "seed").unwrap();
    }
    for (json, text) in SCENARIOS {
        formation_sim::scenario_file::ScenarioSpec::parse(
            text,
            json == 1,
            std::path::Path::new("seed"),
        )
        .unwrap();
    }
}
