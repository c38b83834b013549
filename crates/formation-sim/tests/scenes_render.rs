//! Scenes: the paper configurations and scene files build and render deterministically,
//! the truth's formation variables agree with spec 2.3 computed from world poses, and every
//! readable face in a rendered frame decodes, at its true corners, to the marker the rig
//! puts there (so textures are the right codes, the right way up, at the right place).

use std::path::PathBuf;

use fiducial::{DecodeParams, Dictionary, GrayView, decode};
use formation_sim::paper::{PAPER_FIGURES, paper_scene, random_scene};
use formation_sim::scene::{SceneError, SceneSpec, SceneTruth, render_scene};
use formation_tracker::rig::RigModel;
use nalgebra::Point2;
use unicycle::wrap_angle;

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../fixtures/scenes")
        .join(name)
}

/// Spec 2.3 from the world poses, written out independently.
fn formation_2_3(spec: &SceneSpec, q1: (f64, f64, f64)) -> [f64; 3] {
    let q2 = &spec.camera_robot;
    let d = spec.mount.offset;
    let x2c = q2.x + d * q2.theta.cos();
    let y2c = q2.y + d * q2.theta.sin();
    let l12 = (q1.0 - x2c).hypot(q1.1 - y2c);
    let zeta = (q1.1 - y2c).atan2(q1.0 - x2c);
    [l12, wrap_angle(zeta - q1.2), wrap_angle(zeta - q2.theta)]
}

fn check_truth_formation(spec: &SceneSpec, truth: &SceneTruth) {
    for r in &truth.robots {
        let want = formation_2_3(spec, (r.pose.x, r.pose.y, r.pose.theta));
        assert!(
            (r.formation.l12 - want[0]).abs() < 1e-9,
            "{}: l12",
            spec.name
        );
        assert!(
            wrap_angle(r.formation.alpha12 - want[1]).abs() < 1e-9,
            "{}: alpha12",
            spec.name
        );
        assert!(
            wrap_angle(r.formation.beta12 - want[2]).abs() < 1e-9,
            "{}: beta12",
            spec.name
        );
    }
}

/// Every readable face decodes at its true corners to the rig's entry, upright.
fn check_faces_decode(spec: &SceneSpec, rig: &RigModel) -> usize {
    let dict = Dictionary::paper();
    let out = render_scene(spec, rig, dict).expect("scene renders");
    check_truth_formation(spec, &out.truth);
    let view = GrayView::new(out.image.as_raw(), out.truth.width, out.truth.height)
        .expect("image matches its size");
    let mut n = 0;
    for r in &out.truth.robots {
        for f in r.faces.iter().filter(|f| f.readable) {
            let c = f
                .corners_px
                .expect("readable faces have corners")
                .map(|p| Point2::new(p[0], p[1]));
            let d = decode(&view, &c, dict, &DecodeParams::default()).unwrap_or_else(|e| {
                panic!("{} robot {} face {}: {e:?}", spec.name, r.robot, f.face)
            });
            assert_eq!(
                d.index, f.index,
                "{} robot {} face {}",
                spec.name, r.robot, f.face
            );
            assert_eq!(Some(d.index), rig.index_of(r.robot, f.face));
            assert_eq!(d.rotation, 0, "marker upright");
            n += 1;
        }
    }
    n
}

#[test]
fn paper_scenes_show_the_right_markers() {
    let rig = RigModel::reference();
    let mut total = 0;
    for f in &PAPER_FIGURES {
        let spec = paper_scene(f.fig).unwrap();
        assert_eq!(spec.robots.len(), 2);
        assert_eq!((spec.camera.width, spec.camera.height), (640, 480));
        assert_eq!(
            (spec.render.noise_sigma, spec.render.blur_sigma),
            (3.0, 1.0)
        );
        let n = check_faces_decode(&spec, &rig);
        assert!(n >= 4, "fig {}: only {n} readable faces", f.fig);
        total += n;
    }
    assert!(total >= 25, "{total}");
    assert!(matches!(paper_scene(12), Err(SceneError::Field { .. })));
    assert!(matches!(paper_scene(6), Err(SceneError::Field { .. })));
}

#[test]
fn scene_files_match_and_custom_rigs_render() {
    let from_file = SceneSpec::load(&fixture("fig7.yaml")).unwrap();
    assert_eq!(from_file, paper_scene(7).unwrap());
    let panned = SceneSpec::load(&fixture("three-robots-panned.json")).unwrap();
    assert_eq!(panned.robots.len(), 3);
    assert!(check_faces_decode(&panned, &RigModel::reference()) >= 3);
    // A custom rig and marker table: robots 1 and 2 of the panned scene show entries 40-52.
    let rig = formation_io::rigfile::load(
        &PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../../fixtures/rigs/three-faces-custom-codes.yaml"),
        Dictionary::paper(),
    )
    .unwrap();
    let mut two = panned.clone();
    two.robots.truncate(2);
    assert!(check_faces_decode(&two, &rig) >= 2);
}

#[test]
fn random_scenes_are_seeded_and_in_range() {
    for i in 0..40 {
        let a = random_scene(5, i);
        assert_eq!(a, random_scene(5, i), "same seed, same scene");
        assert!((1..=3).contains(&a.robots.len()));
        for r in &a.robots {
            let range = (r.x - a.mount.offset).hypot(r.y);
            assert!((0.3..=3.0 + 1e-12).contains(&range), "{range}");
            assert!(r.theta.abs() <= std::f64::consts::FRAC_PI_2 + 1e-12);
        }
    }
    assert_ne!(random_scene(5, 1), random_scene(6, 1));
    let rig = RigModel::reference();
    for i in 0..4 {
        check_faces_decode(&random_scene(11, i), &rig);
    }
}

#[test]
fn rendering_is_deterministic_and_seeded() {
    let dict = Dictionary::paper();
    let rig = RigModel::reference();
    let spec = paper_scene(8).unwrap();
    let a = render_scene(&spec, &rig, dict).unwrap();
    let b = render_scene(&spec, &rig, dict).unwrap();
    assert_eq!(a.image, b.image);
    let mut other = spec.clone();
    other.render.seed += 1;
    let c = render_scene(&other, &rig, dict).unwrap();
    assert_ne!(a.image, c.image);
    assert_eq!(a.truth, c.truth);
}

fn bad(text: &str) -> String {
    match SceneSpec::from_text(text, false, "<test>") {
        Err(SceneError::Field { field, .. }) => field,
        other => panic!("expected a field error, got {other:?}"),
    }
}

#[test]
fn bad_scene_files_name_the_field() {
    let err = SceneSpec::from_text("robots: []\nnoise: 3\n", false, "s.yaml").unwrap_err();
    assert!(err.to_string().contains("noise"), "{err}");
    let err = SceneSpec::from_text("{}", true, "s.json").unwrap_err();
    assert!(err.to_string().contains("robots"), "{err}");
    assert_eq!(
        bad("robots: [{robot: 0, x: 1, y: 0, theta: 0}]"),
        "robots[0].robot"
    );
    assert_eq!(
        bad("robots: [{robot: 1, x: 1, y: 0, theta: 0}, {robot: 1, x: 2, y: 0, theta: 0}]"),
        "robots[1].robot"
    );
    assert_eq!(
        bad("robots: [{robot: 1, x: .nan, y: 0, theta: 0}]"),
        "robots[0].x"
    );
    assert_eq!(
        bad("camera: {hfov_deg: 190}\nrobots: []"),
        "camera.hfov_deg"
    );
    assert_eq!(bad("camera: {width: 0}\nrobots: []"), "camera.width/height");
    assert_eq!(
        bad("render: {supersampling: 0}\nrobots: []"),
        "render.supersampling"
    );
    assert_eq!(
        bad("render: {noise_sigma: -1}\nrobots: []"),
        "render.noise_sigma"
    );
    // A leader on top of the camera has no formation variables: refused when the file is
    // read, naming the robot (#32; it used to fail only when rendered).
    assert_eq!(
        bad("robots: [{robot: 1, x: 0, y: 0, theta: 0}]"),
        "robots[0]"
    );
    // A mount no robot has, and angles that look like degrees.
    assert_eq!(
        bad("mount: {offset: 0.5, height: -1, pan: 0, tilt: 0}\nrobots: []"),
        "mount.height"
    );
    assert_eq!(
        bad("mount: {offset: 0.5, height: 0.3, pan: 0, tilt: 2}\nrobots: []"),
        "mount.tilt"
    );
    assert_eq!(
        bad("robots: [{robot: 1, x: 1, y: 0, theta: 90}]"),
        "robots[0].theta"
    );
}

/// Equal up to the last bit of the floats (serde_json's default float parsing may round the
/// last bit differently).
fn same(a: &SceneSpec, b: &SceneSpec) -> bool {
    let close = |x: f64, y: f64| (x - y).abs() <= 1e-12 * x.abs().max(1.0);
    a.name == b.name
        && a.mount == b.mount
        && a.camera == b.camera
        && a.render == b.render
        && a.camera_robot == b.camera_robot
        && a.robots.len() == b.robots.len()
        && a.robots.iter().zip(&b.robots).all(|(p, q)| {
            p.robot == q.robot && close(p.x, q.x) && close(p.y, q.y) && close(p.theta, q.theta)
        })
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]
    /// Scene files round-trip through JSON and YAML, and building never panics: a valid
    /// spec builds or fails with a typed error (a leader on the camera point).
    #[test]
    fn scene_files_round_trip(seed in 0u64..1_000_000, index in 0u64..100) {
        let spec = random_scene(seed, index);
        let json = serde_json::to_string(&spec).unwrap();
        proptest::prop_assert!(same(&SceneSpec::from_text(&json, true, "p.json").unwrap(), &spec));
        let yaml = serde_saphyr::to_string(&spec).unwrap();
        proptest::prop_assert!(same(&SceneSpec::from_text(&yaml, false, "p.yaml").unwrap(), &spec));
        let rig = RigModel::reference();
        let built = formation_sim::scene::build_scene(&spec, &rig, Dictionary::paper()).unwrap();
        let truth = formation_sim::scene::scene_truth(&spec, &built, &rig, Dictionary::paper()).unwrap();
        proptest::prop_assert_eq!(truth.robots.len(), spec.robots.len());
        for r in &truth.robots {
            proptest::prop_assert!(r.formation.l12.is_finite() && r.formation.l12 >= 0.3 - 1e-9 && r.formation.l12 <= 3.0 + 1e-9);
        }
    }
}

/// A field error of a scene file names the file (#32: it named only the field).
#[test]
fn field_errors_of_a_scene_file_name_the_file() {
    let path = std::env::temp_dir().join(format!("ft-scene-{}.yaml", std::process::id()));
    std::fs::write(&path, "robots: [{robot: 1, x: 0, y: 0, theta: 0}]\n").unwrap();
    let err = SceneSpec::load(&path).unwrap_err();
    let _ = std::fs::remove_file(&path);
    assert!(matches!(&err, SceneError::InFile { .. }), "{err:?}");
    assert!(
        err.to_string()
            .starts_with(&format!("{}: scene: field `robots[0]`", path.display())),
        "{err}"
    );
}
