//! Issue #16: scenes of `cargo xtask random-scenes` that failed on seeds the table was never
//! run with, each rendered, detected and scored as the xtask does, and a property: a face
//! cut by an occluder (one or two corners moved along a side, as when the side runs along
//! the occluder's edge) is never used in the pose.
#![allow(clippy::unwrap_used)] // tests may unwrap (house rules)

use fiducial::Dictionary;
use formation_sim::evaluate::{default_detector, evaluate_scene};
use formation_sim::paper::random_scene;
use formation_sim::scene::{SceneSpec, SceneTruth, build_scene, scene_truth};
use formation_tracker::rig::RigModel;
use formation_tracker::robots::{MarkerObservation, RobotConfig, measure_robots};
use nalgebra::{Matrix3, Point2};
use proptest::prelude::*;

/// Scores scene `index` of series `seed` (noise seed = scene number) and returns the report
/// of robot `robot` with its measurement's rejections.
fn scored(seed: u64, index: u64) -> formation_sim::evaluate::Evaluation {
    let dict = Dictionary::paper();
    let spec = random_scene(seed, index);
    let mut detector = default_detector(dict);
    evaluate_scene(
        &spec,
        &RigModel::reference(),
        dict,
        &mut detector,
        &RobotConfig::default(),
        None,
    )
    .unwrap()
}

#[test]
fn a_face_cut_by_the_other_robot_is_dropped_not_the_good_one() {
    // Seed 777, random-84: robot 1's face 2 is cut on its right by robot 2's rig (its quad
    // 3 px narrow), face 1 is whole. Dropping the smaller quad kept face 2 and put the
    // heading 15 deg off.
    let e = scored(777, 84);
    let m = e.robots.robots.iter().find(|m| m.robot == 1).unwrap();
    assert_eq!(m.faces, vec![1]);
    assert_eq!(m.rejected_faces, vec![2]);
    assert!(
        m.rejections[0].reason.contains("face 1"),
        "{:?}",
        m.rejections
    );
    assert!(e.report.pass, "{:#?}", e.report);
}

#[test]
fn a_face_cut_on_one_side_is_left_out_of_three() {
    // Seed 777, random-89: robot 1's face 3 is cut on its left (2.4 px), and under the joint
    // pose of faces 3, 4, 5 it was below the old 1 px outlier limit.
    let e = scored(777, 89);
    let m = e.robots.robots.iter().find(|m| m.robot == 1).unwrap();
    assert_eq!(m.rejected_faces, vec![3]);
    assert!(e.report.pass, "{:#?}", e.report);
}

#[test]
fn steeply_foreshortened_faces_are_read() {
    // Faces 66-73 deg off-axis, 14.6-17 px wide: their border columns are about two pixels
    // wide, and the 3x3 smoothing before the threshold lifted them to the threshold, so the
    // outline broke and no quad was found (seed 777 random-21, random-50; seed 4242
    // random-2).
    for (seed, index, robot, face) in [(777, 21, 1, 1), (777, 50, 1, 1), (4242, 2, 1, 3)] {
        let e = scored(seed, index);
        let r = e.report.robots.iter().find(|r| r.robot == robot).unwrap();
        assert!(
            r.faces_read.contains(&face),
            "seed {seed} random-{index}: robot {robot} face {face} not read: {r:?}"
        );
        assert!(e.report.pass, "seed {seed} random-{index}: {:#?}", e.report);
    }
}

fn truth_of(spec: &SceneSpec) -> SceneTruth {
    let rig = RigModel::reference();
    let built = build_scene(spec, &rig, Dictionary::paper()).unwrap();
    scene_truth(spec, &built, &rig, Dictionary::paper()).unwrap()
}

/// A leader 1.4-2.6 m ahead showing two or three readable faces.
fn two_faced() -> impl Strategy<Value = SceneSpec> {
    (1.4f64..2.6, -0.3f64..0.3, -1.2f64..1.2).prop_map(|(x, y, theta)| {
        SceneSpec::from_text(
            &format!("robots: [{{robot: 1, x: {x}, y: {y}, theta: {theta}}}]"),
            false,
            "occluded",
        )
        .unwrap()
    })
}

/// Cases of the occluder property: 128, or `PROPTEST_CASES` (e.g. 2000 when changing the
/// fusion).
fn cases() -> u32 {
    std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(128)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(cases()))]

    /// An occluder covers one side of one face: the two corners of that side move inwards
    /// along the face's top and bottom edges by 6-40 % of its width (the quad the detector
    /// finds when the side runs along the occluder's edge), or one corner alone is cut. The
    /// cut face is never used for the pose, and the pose of the rest is right. With the
    /// ground-plane face check on (`RobotConfig::plane_face_check`, off by default because it
    /// also drops good steep faces).
    #[test]
    fn a_face_cut_by_an_occluder_is_never_used(
        spec in two_faced(),
        which in 0usize..3,
        right in any::<bool>(),
        one_corner in any::<bool>(),
        cut in 0.06f64..0.4,
    ) {
        let truth = truth_of(&spec);
        let t = &truth.robots[0];
        let readable: Vec<_> = t.faces.iter().filter(|f| f.readable).collect();
        prop_assume!(readable.len() >= 2);
        let cut_face = readable[which % readable.len()];
        let mut obs: Vec<MarkerObservation> = readable
            .iter()
            .map(|f| MarkerObservation {
                index: f.index,
                corners: f.corners_px.unwrap().map(|p| Point2::new(p[0], p[1])),
            })
            .collect();
        let o = obs.iter_mut().find(|o| o.index == cut_face.index).unwrap();
        // NW, NE, SE, SW: the right side is NE-SE, the left SW-NW; corners move towards
        // the opposite side along the top and bottom edges.
        let moved: &[(usize, usize)] = match (right, one_corner) {
            (true, false) => &[(1, 0), (2, 3)],
            (false, false) => &[(0, 1), (3, 2)],
            (true, true) => &[(1, 0)],
            (false, true) => &[(3, 2)],
        };
        let before = o.corners;
        for &(c, to) in moved {
            o.corners[c] = before[c] + (before[to] - before[c]) * cut;
        }
        let k = Matrix3::from_row_slice(&truth.k.concat());
        let solver = pose::PoseSolver::new(pose::Intrinsics::from_matrix(&k).unwrap());
        let found = measure_robots(
            &obs,
            &RigModel::reference(),
            &solver,
            &truth.mount,
            &RobotConfig {
                plane_face_check: true,
                ..RobotConfig::default()
            },
        );
        let m = found.robots.iter().find(|m| m.robot == 1);
        prop_assert!(m.is_some(), "no pose: {:?}", found.failures);
        let m = m.unwrap();
        prop_assert!(
            !m.faces.contains(&cut_face.face),
            "cut face {} used: faces {:?}, rejections {:?}",
            cut_face.face, m.faces, m.rejections
        );
        prop_assert!((m.l12 - t.l12).abs() / t.l12 < 0.01, "l12 {} vs {}", m.l12, t.l12);
    }
}
