//! The octagon rig built from AprilTag tag36h11 markers (`fixtures/rigs/octagon-tag36h11.yaml`,
//! faces named `(dictionary, id)`): rendered in the paper's scenes and a few random ones,
//! then detected, grouped, posed and turned into formation variables end to end with the
//! our own rig's criteria where they hold: no wrong id, every robot read is measured with
//! distance within 1 %; looser than our rig (see the asserts): heading within 2 degrees (not
//! 1), and at least 90 % (not all) of the faces in view and at least 14 px wide are read.

use std::path::PathBuf;

use fiducial::Dictionary;
use formation_sim::evaluate::{
    MAX_DISTANCE_ERROR_PCT, MAX_HEADING_ERROR_DEG, default_detector, evaluate_scene,
};
use formation_sim::paper::{PAPER_FIGURES, paper_scene, random_scene};
use formation_tracker::robots::RobotConfig;

#[test]
fn tag36h11_rig_is_read_and_measured_end_to_end() {
    let rig = formation_io::rigfile::load(
        &PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../../fixtures/rigs/octagon-tag36h11.yaml"),
        Dictionary::paper(),
    )
    .expect("the example rig loads");
    assert_eq!(rig.dictionary, "DICT_APRILTAG_36h11");
    assert_eq!(rig.robot_face_in("tag36h11", 22), Some((2, 3)));
    let dict = rig.marker_dictionary().expect("the rig's dictionary");
    assert_eq!(dict.family().rows(), 6);
    let mut detector = default_detector(dict);
    let mut scenes: Vec<_> = PAPER_FIGURES
        .iter()
        .map(|f| paper_scene(f.fig).expect("paper scene"))
        .collect();
    scenes.extend((0..4).map(|i| random_scene(2026, i)));
    let (mut measured, mut required, mut read) = (0, 0, 0);
    let (mut worst_d, mut worst_h) = (0.0f64, 0.0f64);
    for spec in &scenes {
        let report = evaluate_scene(
            spec,
            &rig,
            dict,
            &mut detector,
            &RobotConfig::default(),
            None,
        )
        .expect("scene evaluates")
        .report;
        assert_eq!(report.stray_codes, 0, "{}: stray ids", report.scene);
        for r in &report.robots {
            let ctx = format!("{} robot {}", report.scene, r.robot);
            assert_eq!(r.wrong_codes, 0, "{ctx}");
            required += r.faces_required.len();
            read += r
                .faces_required
                .iter()
                .filter(|f| r.faces_read.contains(f))
                .count();
            if let (Some(d), Some(h)) = (r.distance_error_pct, r.heading_error.map(f64::to_degrees))
            {
                measured += 1;
                worst_d = worst_d.max(d);
                worst_h = worst_h.max(h);
            } else {
                assert!(
                    r.faces_read.is_empty(),
                    "{ctx}: faces read but no pose: {r:?}"
                );
            }
        }
    }
    // The "required" faces are those at least 14 px wide, a bound set for our 7-cell-wide
    // markers: a tag36h11 marker is 8 cells wide, so at 14 px its cells are under 2 px and
    // a few such faces are missed (3 of 44 in these scenes when written).
    assert!(
        read * 100 >= required * 90,
        "read {read} of {required} required faces"
    );
    assert!(measured >= 10, "only {measured} robots measured");
    assert!(
        worst_d <= MAX_DISTANCE_ERROR_PCT,
        "distance error {worst_d:.3} %"
    );
    // Heading: our rig's bound is 1 degree. With tag36h11 (smaller cells, corners of
    // far faces less sharp) two far robots exceed it when written: fig9 robot 2 (faces 1,
    // 2) 1.42 deg and fig11 robot 2 (face 5 alone) 1.81 deg; the others are within 0.55 deg.
    // Held at twice the bound as a regression guard, not as the criterion met.
    assert!(
        worst_h <= 2.0 * MAX_HEADING_ERROR_DEG,
        "heading error {worst_h:.3} deg"
    );
}
