//! Rig files: the fixtures describe the reference rig, omitted fields keep reference
//! values, explicit marker tables are honoured, and every bad field is named in the error.

use std::path::PathBuf;

use fiducial::Dictionary;
use formation_io::rigfile::RigFileError;
use formation_tracker::rig::{FACE_YAWS_DEG, RigError, RigGeometry, RigModel};
use proptest::prelude::*;

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../fixtures/rigs")
        .join(name)
}

fn yaml(text: &str) -> Result<RigModel, RigFileError> {
    formation_io::rigfile::from_text(text, false, "<test>", Dictionary::paper())
}

/// The field a `Field` error names, or a panic with the error.
fn bad_field(r: Result<RigModel, RigFileError>) -> String {
    match r {
        Err(RigFileError::Field { field, .. }) => field,
        other => panic!("expected a field error, got {other:?}"),
    }
}

#[test]
fn fixtures_and_empty_file_are_the_reference_rig() {
    let d = Dictionary::paper();
    let reference = RigModel::reference();
    for name in ["reference.yaml", "reference.json"] {
        let m = formation_io::rigfile::load(&fixture(name), d).unwrap();
        assert_eq!(m, reference, "{name}");
    }
    assert_eq!(yaml("").unwrap(), reference);
    assert_eq!(yaml("{}").unwrap(), reference);
    // Face geometry is the spec's: face f at yaw FACE_YAWS_DEG[f - 1] on the reference octagon.
    let r = RigGeometry::reference();
    for f in 1..=5u8 {
        let a = reference.face(f).unwrap();
        let yaw = FACE_YAWS_DEG[usize::from(f) - 1].to_radians();
        let b = r.face_at_yaw(f, yaw).unwrap();
        for (p, q) in a.corners.iter().flatten().zip(b.corners.iter().flatten()) {
            assert!((p - q).abs() < 1e-12, "face {f}");
        }
    }
    // And the default table is the spec's mapping: entry (robot - 1) * 5 + (face - 1).
    for robot in 1..=20u32 {
        for face in 1..=5u8 {
            let index = (robot as usize - 1) * 5 + usize::from(face) - 1;
            assert_eq!(reference.index_of(robot, face), Some(index));
            assert_eq!(reference.code(d, robot, face).unwrap(), d.codes()[index]);
        }
    }
}

#[test]
fn explicit_marker_table_is_the_whole_table() {
    let d = Dictionary::paper();
    let m = formation_io::rigfile::load(&fixture("three-faces-custom-codes.yaml"), d).unwrap();
    assert_eq!(m.faces.len(), 3);
    assert_eq!(m.index_of(1, 3), Some(41));
    assert_eq!(m.index_of(2, 4), Some(52));
    assert_eq!(m.robot_face(50), Some((2, 2)));
    assert_eq!(m.robot_face(0), None, "entry 0 is not on any face");
    assert_eq!(m.index_of(3, 3), None);
    assert!(matches!(
        m.code(d, 3, 3),
        Err(RigError::NoMarker { robot: 3, face: 3 })
    ));
    assert!(matches!(
        m.code(d, 1, 1),
        Err(RigError::NoSuchFace { face: 1 })
    ));
    // A code is accepted in place of an index.
    let code = d.code(77).unwrap();
    let m = yaml(&format!(
        "markers:\n  - {{ robot: 4, face: 5, code: {code} }}\n"
    ))
    .unwrap();
    assert_eq!(m.index_of(4, 5), Some(77));
}

#[test]
fn changed_geometry_moves_the_corners() {
    let m = yaml("face_width_m: 0.24\nmarker_centre_height_m: 0.5\ncell_size_m: 0.025\n").unwrap();
    let f = m.face(3).unwrap();
    // Marker 7 x 6 cells of 25 mm, centred at 0.5 m height.
    assert!((f.corners[0][2] - (0.5 + 0.075)).abs() < 1e-12);
    assert!(((f.corners[1][1] - f.corners[0][1]).abs() - 0.175).abs() < 1e-12);
}

#[test]
fn unknown_and_mistyped_fields_are_named() {
    let err = yaml("cell_size_mm: 20\n").unwrap_err().to_string();
    assert!(err.contains("cell_size_mm"), "{err}");
    let err = formation_io::rigfile::from_text(
        r#"{"faces": [{"face": 1, "yaw": 90}]}"#,
        true,
        "x.json",
        Dictionary::paper(),
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("yaw") && err.contains("x.json"), "{err}");
    let err = yaml("face_width_m: wide\n").unwrap_err();
    assert!(matches!(err, RigFileError::Parse { .. }), "{err:?}");
    let err = formation_io::rigfile::load(&fixture("no-such-file.yaml"), Dictionary::paper())
        .unwrap_err();
    assert!(matches!(err, RigFileError::Io { .. }));
}

#[test]
fn bad_values_name_their_field() {
    assert_eq!(
        bad_field(yaml(
            "faces: [{face: 1, yaw_deg: 90}, {face: 1, yaw_deg: 180}]"
        )),
        "faces[1].face"
    );
    assert_eq!(
        bad_field(yaml(
            "faces: [{face: 1, yaw_deg: 90}, {face: 2, yaw_deg: 120}]"
        )),
        "faces[1].yaw_deg"
    );
    assert_eq!(
        bad_field(yaml("faces: [{face: 0, yaw_deg: 90}]")),
        "faces[0].face"
    );
    assert_eq!(bad_field(yaml("faces: []")), "faces");
    assert_eq!(
        bad_field(yaml("markers: [{robot: 1, face: 1, index: 100}]")),
        "markers[0].index"
    );
    assert_eq!(
        bad_field(yaml("markers: [{robot: 1, face: 1, code: 1}]")),
        "markers[0].code"
    );
    assert_eq!(
        bad_field(yaml("markers: [{robot: 1, face: 1, index: 3, code: 5}]")),
        "markers[0]"
    );
    assert_eq!(
        bad_field(yaml("markers: [{robot: 1, face: 9, index: 3}]")),
        "markers[0].face"
    );
    assert_eq!(
        bad_field(yaml("markers: [{robot: 0, face: 1, index: 3}]")),
        "markers[0].robot"
    );
    assert_eq!(
        bad_field(yaml(
            "markers: [{robot: 1, face: 1, index: 3}, {robot: 2, face: 1, index: 3}]"
        )),
        "markers[1]"
    );
    assert_eq!(bad_field(yaml("data_rows: 5")), "data_rows/data_cols");
    assert!(matches!(
        yaml("face_width_m: 0.1"),
        Err(RigFileError::Rig(RigError::MarkerTooWide { .. }))
    ));
    assert!(matches!(
        yaml("cell_size_m: -0.02"),
        Err(RigFileError::Rig(RigError::BadLength { .. }))
    ));
}

proptest! {
    /// The default table is a bijection between `(robot, face)` and dictionary entries for
    /// any set of faces.
    #[test]
    fn default_table_round_trips(
        n_faces in 1usize..=8, robot in 1u32..1000, pick in 0usize..8,
    ) {
        let faces: String = (0..n_faces)
            .map(|i| format!("{{face: {}, yaw_deg: {}}}", i + 3, i as f64 * 45.0))
            .collect::<Vec<_>>()
            .join(", ");
        let m = yaml(&format!("faces: [{faces}]")).unwrap();
        let face = (pick % n_faces) as u8 + 3;
        let index = m.index_of(robot, face).unwrap();
        prop_assert_eq!(m.robot_face(index), Some((robot, face)));
        prop_assert_eq!(index, (robot as usize - 1) * n_faces + (pick % n_faces));
    }
}

#[test]
fn rigs_name_their_dictionary_and_faces_by_dictionary_and_id() {
    let m = formation_io::rigfile::load(&fixture("octagon-tag36h11.yaml"), Dictionary::paper())
        .unwrap();
    assert_eq!(m.dictionary, "DICT_APRILTAG_36h11");
    assert_eq!((m.geometry.data_rows, m.geometry.data_cols), (6, 6));
    assert_eq!(m.index_of(2, 3), Some(22));
    assert_eq!(m.robot_face_in("TAG36H11", 22), Some((2, 3)));
    assert_eq!(m.robot_face_in("FORMATION_4X5", 22), None);
    let dict = m.marker_dictionary().unwrap();
    assert_eq!(m.code(dict, 1, 1).unwrap(), dict.codes()[10]);
    // Our own dictionary by default, and by name.
    assert_eq!(RigModel::reference().dictionary, fiducial::PAPER_NAME);
    assert_eq!(yaml("dictionary: own").unwrap(), RigModel::reference());
    // Errors name the field.
    assert_eq!(bad_field(yaml("dictionary: tag99h1")), "dictionary");
    assert_eq!(
        bad_field(yaml(
            "dictionary: tag36h11\ncell_size_m: 0.0175\nmarkers:\n  - { robot: 1, face: 1, dictionary: DICT_4X4_50, id: 3 }"
        )),
        "markers[0].dictionary"
    );
    assert_eq!(
        bad_field(yaml(
            "dictionary: tag36h11\ncell_size_m: 0.0175\nmarkers:\n  - { robot: 1, face: 1, id: 3, index: 3 }"
        )),
        "markers[0]"
    );
    assert_eq!(
        bad_field(yaml(
            "dictionary: tag36h11\ncell_size_m: 0.0175\nmarkers:\n  - { robot: 1, face: 1, id: 587 }"
        )),
        "markers[0].index"
    );
    // A tag36h11 marker of 20 mm cells (160 mm) does not fit a 180 mm face with its margin.
    assert!(matches!(
        yaml("dictionary: tag36h11"),
        Err(RigFileError::Rig(RigError::MarkerTooWide { .. }))
    ));
}
