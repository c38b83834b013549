//! Robot poses from marker corners: exact corners give the true formation variables, noisy
//! corners stay within their propagated covariance, a face with a wrong code or a bad corner
//! is rejected, one face reports both candidates' ambiguity, and unknown codes are set
//! aside. Corners come from the scenes' exact ground truth (no rendering, no detector), so
//! these tests isolate `robots` from detection.

use fiducial::Dictionary;
use formation_sim::paper::{paper_scene, random_scene};
use formation_sim::scene::{SceneSpec, SceneTruth, build_scene, scene_truth};
use formation_tracker::rig::RigModel;
use formation_tracker::robots::{MarkerObservation, RobotConfig, measure_robots};
use nalgebra::{Matrix3, Point2};
use proptest::prelude::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use unicycle::wrap_angle;

fn truth_of(spec: &SceneSpec) -> SceneTruth {
    let rig = RigModel::reference();
    let built = build_scene(spec, &rig, Dictionary::paper()).expect("scene builds");
    scene_truth(spec, &built, &rig, Dictionary::paper()).expect("truth")
}

fn solver(truth: &SceneTruth) -> pose::PoseSolver {
    let k = Matrix3::from_row_slice(&truth.k.concat());
    pose::PoseSolver::new(pose::Intrinsics::from_matrix(&k).expect("valid K"))
}

/// Observations of the readable faces, corners perturbed by `noise` px (seeded).
fn observations(truth: &SceneTruth, noise: f64, seed: u64) -> Vec<MarkerObservation> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n = Normal::new(0.0, 1.0).expect("unit normal");
    let mut out = Vec::new();
    for r in &truth.robots {
        for f in r.faces.iter().filter(|f| f.readable) {
            let c = f.corners_px.expect("readable faces have corners");
            out.push(MarkerObservation {
                index: f.index,
                corners: c.map(|p| {
                    Point2::new(
                        p[0] + noise * n.sample(&mut rng),
                        p[1] + noise * n.sample(&mut rng),
                    )
                }),
            });
        }
    }
    out
}

fn errors(truth: &SceneTruth, config: &RobotConfig, obs: &[MarkerObservation]) -> Vec<[f64; 4]> {
    let found = measure_robots(
        obs,
        &RigModel::reference(),
        &solver(truth),
        &truth.mount,
        config,
    );
    assert!(found.failures.is_empty(), "{:?}", found.failures);
    found
        .robots
        .iter()
        .map(|m| {
            let t = truth
                .robot(m.robot)
                .expect("measured robots are in the scene");
            [
                (m.formation.l12 - t.formation.l12).abs() / t.formation.l12,
                wrap_angle(m.formation.alpha12 - t.formation.alpha12).abs(),
                wrap_angle(m.formation.beta12 - t.formation.beta12).abs(),
                wrap_angle(m.relative_heading() - t.relative_heading).abs(),
            ]
        })
        .collect()
}

#[test]
fn exact_corners_give_the_true_formation_variables() {
    for ground_plane in [false, true] {
        let config = RobotConfig {
            ground_plane,
            ..RobotConfig::default()
        };
        for fig in 7..=11 {
            let truth = truth_of(&paper_scene(fig).unwrap());
            let e = errors(&truth, &config, &observations(&truth, 0.0, 0));
            assert_eq!(e.len(), 2, "fig {fig}: both robots measured");
            for v in e {
                assert!(
                    v.iter().all(|x| *x < 1e-6),
                    "fig {fig} ground {ground_plane}: {v:?}"
                );
            }
        }
    }
}

#[test]
fn detect_fields_are_consistent() {
    let truth = truth_of(&paper_scene(7).unwrap());
    let found = measure_robots(
        &observations(&truth, 0.0, 0),
        &RigModel::reference(),
        &solver(&truth),
        &truth.mount,
        &RobotConfig::default(),
    );
    for m in &found.robots {
        let t = truth.robot(m.robot).unwrap();
        for i in 0..3 {
            assert!((m.translation[i] - t.translation[i]).abs() < 1e-6);
            assert!((m.rotation[i] - t.rotation[i]).abs() < 1e-6);
        }
        let want: Vec<u8> = t
            .faces
            .iter()
            .filter(|f| f.readable)
            .map(|f| f.face)
            .collect();
        assert_eq!(m.faces, want);
        assert!(m.rejected_faces.is_empty());
        assert!(m.reprojection_rms_px < 1e-6);
        assert!(!m.ambiguous, "several faces are never ambiguous");
        // The covariance is symmetric with a positive diagonal (the 0.1 px noise floor).
        for i in 0..3 {
            assert!(m.covariance[i][i] > 0.0 && m.covariance[i][i].is_finite());
            for j in 0..3 {
                assert!((m.covariance[i][j] - m.covariance[j][i]).abs() < 1e-12);
            }
        }
    }
}

#[test]
fn noisy_corners_stay_within_the_propagated_covariance() {
    // 0.3 px corner noise on the Fig. 10 scene, many seeds: the l12 errors' spread matches
    // the reported standard deviation to within a factor of two.
    let truth = truth_of(&paper_scene(10).unwrap());
    let rig = RigModel::reference();
    let solver = solver(&truth);
    let mut sq = 0.0;
    let mut var = 0.0;
    let n = 200;
    for seed in 0..n {
        let obs = observations(&truth, 0.3, seed);
        let found = measure_robots(&obs, &rig, &solver, &truth.mount, &RobotConfig::default());
        let m = found.robots.iter().find(|m| m.robot == 2).unwrap();
        let t = truth.robot(2).unwrap();
        sq += (m.formation.l12 - t.formation.l12).powi(2);
        var += m.covariance[0][0];
    }
    let ratio = (sq / var).sqrt();
    assert!(
        (0.5..2.0).contains(&ratio),
        "empirical / propagated sigma = {ratio}"
    );
}

#[test]
fn a_wrong_code_and_a_bad_corner_are_rejected() {
    let truth = truth_of(&paper_scene(7).unwrap());
    let rig = RigModel::reference();
    let mut obs = observations(&truth, 0.0, 0);
    // Robot 1's faces 2, 3, 4 are read. A stray quad elsewhere in the image carrying robot
    // 1's face 5 code (a misread).
    let stray = MarkerObservation {
        index: rig.index_of(1, 5).unwrap(),
        corners: [
            Point2::new(500.0, 100.0),
            Point2::new(530.0, 101.0),
            Point2::new(530.0, 130.0),
            Point2::new(500.0, 129.0),
        ],
    };
    obs.push(stray);
    let found = measure_robots(
        &obs,
        &rig,
        &solver(&truth),
        &truth.mount,
        &RobotConfig::default(),
    );
    let m = found.robots.iter().find(|m| m.robot == 1).unwrap();
    assert_eq!(m.rejected_faces, vec![5]);
    assert_eq!(m.faces, vec![2, 3, 4]);
    let t = truth.robot(1).unwrap();
    assert!((m.formation.l12 - t.formation.l12).abs() < 1e-6);

    // A corner of robot 2's face 3 caught 4 px off.
    let mut obs = observations(&truth, 0.0, 0);
    let i = obs
        .iter()
        .position(|o| o.index == rig.index_of(2, 3).unwrap())
        .unwrap();
    obs[i].corners[1].x += 4.0;
    let found = measure_robots(
        &obs,
        &rig,
        &solver(&truth),
        &truth.mount,
        &RobotConfig::default(),
    );
    let m = found.robots.iter().find(|m| m.robot == 2).unwrap();
    assert_eq!(m.rejected_faces, vec![3]);
    let t = truth.robot(2).unwrap();
    assert!((m.formation.l12 - t.formation.l12).abs() / t.formation.l12 < 1e-6);
}

#[test]
fn one_face_reports_its_ambiguity_and_unknown_codes_are_set_aside() {
    // A single face seen from 3 m: pose reports both planar candidates.
    let spec = SceneSpec::from_text(
        "robots: [{robot: 1, x: 3.2, y: 0.3, theta: 0.3}]",
        false,
        "s.yaml",
    )
    .unwrap();
    let truth = truth_of(&spec);
    let rig = RigModel::reference();
    let all = observations(&truth, 0.0, 0);
    let three = rig.index_of(1, 3).unwrap();
    let mut obs: Vec<MarkerObservation> = all.into_iter().filter(|o| o.index == three).collect();
    assert_eq!(obs.len(), 1);
    obs.push(MarkerObservation {
        index: 99,
        corners: obs[0]
            .corners
            .map(|p| p + nalgebra::Vector2::new(100.0, 0.0)),
    });
    let free = RobotConfig {
        ground_plane: false,
        ..RobotConfig::default()
    };
    let found = measure_robots(&obs, &rig, &solver(&truth), &truth.mount, &free);
    let m = found.robots.iter().find(|m| m.robot == 1).unwrap();
    assert_eq!(m.faces, vec![3]);
    let ratio = m.ambiguity_ratio.expect("one face has an alternative");
    assert!(ratio >= 1.0);
    assert_eq!(m.ambiguous, ratio < free.ambiguity_ratio);
    // Entry 99 is robot 20's face 5 in the reference table: measured as its own robot.
    assert!(found.robots.iter().any(|m| m.robot == 20));
    // A rig whose table lists only robot 1 puts entry 99 aside as unknown.
    let small = formation_io::rigfile::from_text(
        "markers: [{robot: 1, face: 3, index: 2}]",
        false,
        "<t>",
        Dictionary::paper(),
    )
    .unwrap();
    let found = measure_robots(&obs, &small, &solver(&truth), &truth.mount, &free);
    assert_eq!(found.unknown, vec![99]);
    assert_eq!(found.robots.len(), 1);
}

#[test]
fn ground_plane_refinement_is_not_worse_on_single_faces() {
    // One face at 2.5-3 m, 0.25 px corner noise: the heading from the ground-plane
    // refinement is at least as good (RMS over seeds) as the free 6-DOF pose.
    let rig = RigModel::reference();
    let (mut free_sq, mut ground_sq) = (0.0, 0.0);
    for seed in 0..60u64 {
        let x = 2.5 + 0.5 * (seed as f64 / 60.0);
        let spec = SceneSpec::from_text(
            &format!("robots: [{{robot: 1, x: {x}, y: 0.1, theta: 0.2}}]"),
            false,
            "s.yaml",
        )
        .unwrap();
        let truth = truth_of(&spec);
        let three = rig.index_of(1, 3).unwrap();
        let obs: Vec<MarkerObservation> = observations(&truth, 0.25, seed)
            .into_iter()
            .filter(|o| o.index == three)
            .collect();
        for (ground_plane, acc) in [(false, &mut free_sq), (true, &mut ground_sq)] {
            let config = RobotConfig {
                ground_plane,
                ..RobotConfig::default()
            };
            let e = errors(&truth, &config, &obs);
            *acc += e[0][3].powi(2);
        }
    }
    let (free, ground) = ((free_sq / 60.0).sqrt(), (ground_sq / 60.0).sqrt());
    assert!(
        ground <= free,
        "heading RMS: ground {ground} vs free {free} rad"
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]
    /// Random scenes, exact corners: every robot with a readable face is measured exactly.
    #[test]
    fn random_scenes_exact(seed in 0u64..1_000_000) {
        let truth = truth_of(&random_scene(seed, 0));
        let obs = observations(&truth, 0.0, 0);
        let measured = errors(&truth, &RobotConfig::default(), &obs);
        let expected = truth.robots.iter().filter(|r| r.faces.iter().any(|f| f.readable)).count();
        prop_assert_eq!(measured.len(), expected);
        for v in measured {
            prop_assert!(v.iter().all(|x| *x < 1e-6), "{:?}", v);
        }
    }
}

#[test]
fn non_finite_or_degenerate_corners_are_failures_not_panics() {
    let truth = truth_of(&paper_scene(7).unwrap());
    let rig = RigModel::reference();
    let mut obs = observations(&truth, 0.0, 0);
    let one = rig.index_of(2, 3).unwrap();
    obs.retain(|o| o.index == one);
    obs[0].corners[2].x = f64::NAN;
    let found = measure_robots(
        &obs,
        &rig,
        &solver(&truth),
        &truth.mount,
        &RobotConfig::default(),
    );
    assert!(found.robots.is_empty());
    assert_eq!(found.failures.len(), 1);
    assert!(
        found.failures[0].to_string().contains("robot 2"),
        "{}",
        found.failures[0]
    );
    // All four corners on one point.
    obs[0].corners = [Point2::new(100.0, 100.0); 4];
    let found = measure_robots(
        &obs,
        &rig,
        &solver(&truth),
        &truth.mount,
        &RobotConfig::default(),
    );
    assert!(found.robots.is_empty() && found.failures.len() == 1);
}
