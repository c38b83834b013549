//! Rig files (YAML or JSON, `formation_io::rigfile`): never a panic, and an
//! accepted rig has valid geometry, a geometry for each of its faces, and a marker table
//! whose entries map back to the same robot and face.

use fiducial::Dictionary;

/// Parses `data` as a rig file (YAML when the first byte is even, else JSON).
pub fn run(data: &[u8]) {
    let json = data.first().is_some_and(|b| b % 2 == 1);
    let text = String::from_utf8_lossy(data.get(1..).unwrap_or_default());
    let Ok(rig) = formation_io::rigfile::from_text(&text, json, "fuzz.rig", Dictionary::paper())
    else {
        return;
    };
    assert!(rig.geometry.validate().is_ok(), "accepted invalid geometry");
    let faces = rig
        .face_geometries()
        .expect("every face of an accepted rig has a geometry");
    assert_eq!(faces.len(), rig.faces.len());
    for robot in 1..=3 {
        for spec in &rig.faces {
            if let Some(index) = rig.index_of(robot, spec.face) {
                assert_eq!(rig.robot_face(index), Some((robot, spec.face)));
            }
        }
    }
}
