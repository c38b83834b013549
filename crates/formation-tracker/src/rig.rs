//! The leader's marker rig (spec 3.3): five faces of a regular octagon, each carrying one
//! marker, and the mapping between `(robot, face)` and dictionary entries.
//!
//! Faces are numbered 1..5 from the leader's left side, round its back, to its right side;
//! their outward normals point at yaw +90, +135, 180, -135 and -90 degrees in the leader's
//! body frame (x forward, y left, z up). The octagon is centred over the leader's reference
//! point, so a face's centre lies at the octagon's apothem `w / (2 tan 22.5 deg)` along its
//! normal, at the marker-centre height.
//!
//! Each face shows the marker of dictionary entry `(robot - 1) * 5 + (face - 1)`, robots
//! numbered from 1. The outer corners of a marker's black border are given in the body
//! frame in the marker's own order NW, NE, SE, SW *as seen from outside, facing the
//! marker*: clockwise to that viewer, so `(NE - NW) x (SW - NW)` points into the face.
//!
//! The types are plain data with serde derives, so a rig file (YAML/JSON) can override
//! the reference values.

use fiducial::{Dictionary, MarkerFamily};
use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Faces per leader.
pub const FACES_PER_ROBOT: u8 = 5;

/// Outward-normal yaw of faces 1..5 in the leader's body frame, degrees.
pub const FACE_YAWS_DEG: [f64; 5] = [90.0, 135.0, 180.0, -135.0, -90.0];

/// What is wrong with a rig or a `(robot, face)` request.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum RigError {
    /// Face numbers run 1..=5.
    #[error("face {face} does not exist; faces are numbered 1..=5")]
    NoSuchFace {
        /// The face asked for.
        face: u8,
    },
    /// Robots are numbered from 1.
    #[error("robot numbers start at 1 (got 0)")]
    RobotZero,
    /// The dictionary has too few entries for this robot.
    #[error(
        "robot {robot} needs dictionary entries up to #{needed}, but the dictionary has {len} \
         entries ({max_robots} robots of 5 faces)"
    )]
    TooManyRobots {
        /// The robot asked for.
        robot: u32,
        /// Highest entry index needed.
        needed: usize,
        /// Entries in the dictionary.
        len: usize,
        /// Robots the dictionary supports.
        max_robots: u32,
    },
    /// A length is not finite and positive.
    #[error("rig {what} must be finite and positive, got {value}")]
    BadLength {
        /// Which length.
        what: &'static str,
        /// Its value.
        value: f64,
    },
    /// The marker plus a one-cell quiet zone does not fit the face.
    #[error(
        "a marker {marker_m} m wide with a one-cell quiet zone ({cell_m} m) does not fit a \
         face {face_m} m wide"
    )]
    MarkerTooWide {
        /// Marker width (black border), metres.
        marker_m: f64,
        /// Cell size, metres.
        cell_m: f64,
        /// Face width, metres.
        face_m: f64,
    },
    /// A rig file's marker table has no entry for this `(robot, face)`.
    #[error("the rig's marker table gives no marker for robot {robot} face {face}")]
    NoMarker {
        /// The robot.
        robot: u32,
        /// The face.
        face: u8,
    },
    /// The marker family is invalid.
    #[error(transparent)]
    Family(#[from] fiducial::FiducialError),
}

/// A rig description: the octagon and the markers on it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Rig {
    /// Width of each octagon face, metres.
    pub face_width_m: f64,
    /// Height of the marker centres above the ground (the body frame's z = 0), metres.
    pub marker_centre_height_m: f64,
    /// Side of one marker cell, metres.
    pub cell_size_m: f64,
    /// Rows of data cells.
    pub data_rows: u32,
    /// Columns of data cells.
    pub data_cols: u32,
}

impl Default for Rig {
    fn default() -> Self {
        Self::reference()
    }
}

/// One face of the rig, in the leader's body frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Face {
    /// Face number, 1..=5.
    pub face: u8,
    /// Yaw of the outward normal, radians.
    pub yaw_rad: f64,
    /// Outward unit normal.
    pub normal: [f64; 3],
    /// Marker centre.
    pub centre: [f64; 3],
    /// Outer corners of the black border, NW, NE, SE, SW as seen facing the marker.
    pub corners: [[f64; 3]; 4],
}

impl Face {
    /// The outward normal as a vector.
    pub fn normal(&self) -> Vector3<f64> {
        Vector3::from(self.normal)
    }

    /// The corners as points.
    pub fn corner_points(&self) -> [Point3<f64>; 4] {
        self.corners.map(Point3::from)
    }
}

impl Rig {
    /// The reference rig of spec 3.3: faces 0.18 m wide, marker centres at 0.30 m, 4 x 5
    /// data cells of 20 mm with a one-cell border (marker 140 mm x 120 mm).
    pub fn reference() -> Self {
        Self {
            face_width_m: 0.18,
            marker_centre_height_m: 0.30,
            cell_size_m: 0.02,
            data_rows: 4,
            data_cols: 5,
        }
    }

    /// Checks lengths, family and that the marker with a one-cell quiet zone fits a face.
    pub fn validate(&self) -> Result<(), RigError> {
        for (what, value) in [
            ("face width", self.face_width_m),
            ("marker centre height", self.marker_centre_height_m),
            ("cell size", self.cell_size_m),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(RigError::BadLength { what, value });
            }
        }
        let family = self.family()?;
        let marker_m = f64::from(family.width_cells()) * self.cell_size_m;
        // A tolerance of a micrometre keeps 0.14 + 2 * 0.02 = 0.18 from failing on rounding.
        if marker_m + 2.0 * self.cell_size_m > self.face_width_m + 1e-6 {
            return Err(RigError::MarkerTooWide {
                marker_m,
                cell_m: self.cell_size_m,
                face_m: self.face_width_m,
            });
        }
        Ok(())
    }

    /// The marker family of the rig's markers.
    pub fn family(&self) -> Result<MarkerFamily, RigError> {
        Ok(MarkerFamily::new(self.data_rows, self.data_cols)?)
    }

    /// Width and height of a marker's black border, metres.
    pub fn marker_size_m(&self) -> Result<[f64; 2], RigError> {
        let f = self.family()?;
        Ok([
            f64::from(f.width_cells()) * self.cell_size_m,
            f64::from(f.height_cells()) * self.cell_size_m,
        ])
    }

    /// Distance from the octagon's centre to each face, metres: `w / (2 tan 22.5 deg)`.
    pub fn apothem_m(&self) -> f64 {
        self.face_width_m / (2.0 * (std::f64::consts::PI / 8.0).tan())
    }

    /// The geometry of face `face` (1..=5).
    pub fn face(&self, face: u8) -> Result<Face, RigError> {
        let yaw_deg = *FACE_YAWS_DEG
            .get(usize::from(face).wrapping_sub(1))
            .ok_or(RigError::NoSuchFace { face })?;
        self.face_at_yaw(face, yaw_deg.to_radians())
    }

    /// The geometry of a face whose outward normal is at `yaw` (radians, in the leader's
    /// body frame) on this rig's octagon: the reference faces use the spec's yaws, rig files
    /// may place faces elsewhere.
    pub fn face_at_yaw(&self, face: u8, yaw: f64) -> Result<Face, RigError> {
        self.validate()?;
        let normal = Vector3::new(yaw.cos(), yaw.sin(), 0.0);
        let up = Vector3::z();
        // A viewer outside looks along -normal; their right is z x normal.
        let right = up.cross(&normal);
        let centre = normal * self.apothem_m() + up * self.marker_centre_height_m;
        let [w, h] = self.marker_size_m()?;
        let (hw, hh) = (0.5 * w, 0.5 * h);
        let corner =
            |sx: f64, sy: f64| -> [f64; 3] { (centre + right * (sx * hw) + up * (sy * hh)).into() };
        Ok(Face {
            face,
            yaw_rad: yaw,
            normal: normal.into(),
            centre: centre.into(),
            corners: [
                corner(-1.0, 1.0),
                corner(1.0, 1.0),
                corner(1.0, -1.0),
                corner(-1.0, -1.0),
            ],
        })
    }

    /// All five faces, in face order.
    pub fn faces(&self) -> Result<[Face; 5], RigError> {
        Ok([
            self.face(1)?,
            self.face(2)?,
            self.face(3)?,
            self.face(4)?,
            self.face(5)?,
        ])
    }
}

/// The dictionary index shown on face `face` of robot `robot`:
/// `(robot - 1) * 5 + (face - 1)`.
pub fn marker_index(robot: u32, face: u8) -> Result<usize, RigError> {
    if robot == 0 {
        return Err(RigError::RobotZero);
    }
    if !(1..=FACES_PER_ROBOT).contains(&face) {
        return Err(RigError::NoSuchFace { face });
    }
    Ok((robot as usize - 1) * usize::from(FACES_PER_ROBOT) + usize::from(face - 1))
}

/// The `(robot, face)` showing dictionary entry `index`; the inverse of [`marker_index`].
pub fn robot_face(index: usize) -> (u32, u8) {
    let per = usize::from(FACES_PER_ROBOT);
    ((index / per) as u32 + 1, (index % per) as u8 + 1)
}

/// How many robots a dictionary supports (five entries each).
pub fn max_robots(dictionary: &Dictionary) -> u32 {
    (dictionary.len() / usize::from(FACES_PER_ROBOT)) as u32
}

/// The code on face `face` of robot `robot`, or why there is none.
pub fn marker_code(dictionary: &Dictionary, robot: u32, face: u8) -> Result<u64, RigError> {
    let index = marker_index(robot, face)?;
    dictionary.code(index).ok_or(RigError::TooManyRobots {
        robot,
        needed: index,
        len: dictionary.len(),
        max_robots: max_robots(dictionary),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rig_faces() -> [Face; 5] {
        Rig::reference().faces().unwrap()
    }

    #[test]
    fn reference_marker_is_140_by_120_mm() {
        let [w, h] = Rig::reference().marker_size_m().unwrap();
        assert!((w - 0.14).abs() < 1e-12 && (h - 0.12).abs() < 1e-12);
    }

    #[test]
    fn adjacent_faces_are_45_degrees_apart_round_the_back() {
        let f = rig_faces();
        for i in 0..4 {
            let cos = f[i].normal().dot(&f[i + 1].normal());
            assert!((cos - std::f64::consts::FRAC_1_SQRT_2).abs() < 1e-12);
            // Turning from the left side round the back: normals rotate positively.
            let turn = f[i].normal().cross(&f[i + 1].normal()).z;
            assert!(turn > 0.0, "face {} -> {}", i + 1, i + 2);
        }
        assert!(
            (f[0].normal() - Vector3::y()).norm() < 1e-12,
            "face 1 faces left"
        );
        assert!(
            (f[2].normal() + Vector3::x()).norm() < 1e-12,
            "face 3 faces back"
        );
        assert!(
            (f[4].normal() + Vector3::y()).norm() < 1e-12,
            "face 5 faces right"
        );
    }

    #[test]
    fn corners_lie_on_the_octagon_at_the_right_height() {
        let rig = Rig::reference();
        for face in rig_faces() {
            let n = face.normal();
            let c = face.corner_points();
            for p in &c {
                // In the face plane, at the apothem.
                assert!((p.coords.dot(&n) - rig.apothem_m()).abs() < 1e-12);
            }
            assert!((c[0].z - 0.36).abs() < 1e-12 && (c[1].z - 0.36).abs() < 1e-12);
            assert!((c[2].z - 0.24).abs() < 1e-12 && (c[3].z - 0.24).abs() < 1e-12);
            assert!(((c[1] - c[0]).norm() - 0.14).abs() < 1e-12);
            assert!(((c[3] - c[0]).norm() - 0.12).abs() < 1e-12);
            // The marker is centred on the face: its centre is at the octagon's apothem.
            let mid = (c[0].coords + c[2].coords) / 2.0;
            assert!((mid - Vector3::from(face.centre)).norm() < 1e-12);
            assert!((Vector3::new(mid.x, mid.y, 0.0).norm() - rig.apothem_m()).abs() < 1e-12);
        }
    }

    #[test]
    fn corners_wind_clockwise_seen_from_outside() {
        for face in rig_faces() {
            let c = face.corner_points();
            let n = face.normal();
            // Clockwise to a viewer on the +n side: the right-hand normal points away.
            for i in 0..4 {
                let e1 = c[(i + 1) % 4] - c[i];
                let e2 = c[(i + 2) % 4] - c[(i + 1) % 4];
                assert!(e1.cross(&e2).dot(&n) < 0.0, "face {} corner {i}", face.face);
            }
            // NW is up and to the viewer's left: the viewer's right is z x n.
            let right = Vector3::z().cross(&n);
            assert!((c[1] - c[0]).dot(&right) > 0.0);
        }
    }

    #[test]
    fn octagon_edge_is_the_face_width() {
        // Adjacent face planes meet at the octagon's vertices, half a face from each centre.
        let rig = Rig::reference();
        let f = rig_faces();
        let a = rig.apothem_m();
        let r = a / (std::f64::consts::PI / 8.0).cos();
        let vertex_yaw = (f[0].yaw_rad + f[1].yaw_rad) / 2.0;
        let vertex = Vector3::new(r * vertex_yaw.cos(), r * vertex_yaw.sin(), 0.0);
        for face in &f[..2] {
            let centre_ground = Vector3::new(face.centre[0], face.centre[1], 0.0);
            assert!(((vertex - centre_ground).norm() - 0.09).abs() < 1e-12);
        }
    }

    #[test]
    fn index_mapping_round_trips_and_rejects_bad_input() {
        for robot in 1..=20 {
            for face in 1..=5 {
                let i = marker_index(robot, face).unwrap();
                assert_eq!(robot_face(i), (robot, face));
            }
        }
        assert_eq!(marker_index(2, 3).unwrap(), 7);
        assert_eq!(marker_index(0, 1), Err(RigError::RobotZero));
        assert_eq!(marker_index(1, 6), Err(RigError::NoSuchFace { face: 6 }));
        assert!(matches!(
            Rig::reference().face(0),
            Err(RigError::NoSuchFace { face: 0 })
        ));
        let d = Dictionary::paper();
        let too_many = max_robots(d) + 1;
        assert!(matches!(
            marker_code(d, too_many, 1),
            Err(RigError::TooManyRobots { .. })
        ));
        assert_eq!(marker_code(d, 1, 1).unwrap(), d.codes()[0]);
    }

    #[test]
    fn bad_rigs_are_rejected() {
        let mut r = Rig::reference();
        r.face_width_m = 0.15;
        assert!(matches!(r.validate(), Err(RigError::MarkerTooWide { .. })));
        let mut r = Rig::reference();
        r.cell_size_m = f64::NAN;
        assert!(matches!(r.validate(), Err(RigError::BadLength { .. })));
        let mut r = Rig::reference();
        r.data_rows = 0;
        assert!(matches!(r.validate(), Err(RigError::Family(_))));
    }

    #[test]
    fn rig_round_trips_through_json() {
        let r = Rig::reference();
        let s = serde_json::to_string(&r).unwrap();
        assert_eq!(serde_json::from_str::<Rig>(&s).unwrap(), r);
        let f = r.face(2).unwrap();
        let s = serde_json::to_string(&f).unwrap();
        let back: Face = serde_json::from_str(&s).unwrap();
        assert_eq!(back.face, 2);
        // serde_json's default float parsing may differ in the last bit.
        for (a, b) in back
            .corners
            .iter()
            .flatten()
            .zip(f.corners.iter().flatten())
        {
            assert!((a - b).abs() <= 1e-15, "{a} vs {b}");
        }
    }
}
