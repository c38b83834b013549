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
//! [`RigModel`] is the single source of all of this: its [`RigGeometry`] (lengths and
//! marker family), its faces (number and yaw; the reference rig has the five above) and its
//! `(robot, face)` <-> dictionary-entry table, in the dictionary it names (our own by
//! default, or a predefined ArUco/AprilTag one, so a rig can be built from markers users
//! already print). A rig file (`rigfile`, YAML/JSON) overrides any of it.

use fiducial::{Dictionary, MarkerFamily};
use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Outward-normal yaw of the reference rig's faces 1..5 in the leader's body frame, degrees.
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

/// The rig's physical dimensions: the octagon's face width, the marker height, the cell size
/// and the marker family. Where the faces are and which marker each carries is
/// [`RigModel`]'s.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RigGeometry {
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

impl Default for RigGeometry {
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

impl RigGeometry {
    /// The reference dimensions of spec 3.3: faces 0.18 m wide, marker centres at 0.30 m, 4 x 5
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
}

/// One face of a rig: its number and the yaw of its outward normal.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FaceSpec {
    /// Face number (1..=255), as printed on the robot.
    pub face: u8,
    /// Yaw of the outward normal in the robot's body frame, degrees (left positive).
    pub yaw_deg: f64,
}

/// A checked rig: geometry, faces and the `(robot, face)` <-> dictionary-entry table.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RigModel {
    /// Face and marker geometry.
    pub geometry: RigGeometry,
    /// Faces in the order given.
    pub faces: Vec<FaceSpec>,
    /// Explicit marker table (`None`: the default formula).
    pub markers: Option<Vec<(u32, u8, usize)>>,
    /// The dictionary the markers' ids are entries of, by its standard name
    /// ([`fiducial::PAPER_NAME`] for our own, or an OpenCV/AprilTag name such as
    /// `DICT_APRILTAG_36h11`; see [`fiducial::dictionary_by_name`]).
    pub dictionary: &'static str,
}

impl Default for RigModel {
    fn default() -> Self {
        Self::reference()
    }
}

impl RigModel {
    /// The reference rig of spec 3.3 with the default marker table.
    pub fn reference() -> Self {
        Self {
            geometry: RigGeometry::reference(),
            faces: reference_faces(),
            markers: None,
            dictionary: fiducial::PAPER_NAME,
        }
    }

    /// The dictionary the rig's markers come from (see [`RigModel::dictionary`]).
    pub fn marker_dictionary(&self) -> Result<&'static Dictionary, RigError> {
        Ok(fiducial::dictionary_by_name(self.dictionary)?)
    }

    /// The `(robot, face)` carrying entry `index` of the dictionary called `dictionary`
    /// (any accepted spelling), if that is the rig's dictionary and the entry is on a face.
    pub fn robot_face_in(&self, dictionary: &str, index: usize) -> Option<(u32, u8)> {
        let name = fiducial::canonical_name(dictionary).ok()?;
        (name == self.dictionary)
            .then(|| self.robot_face(index))
            .flatten()
    }

    /// The geometry of face number `face`.
    pub fn face(&self, face: u8) -> Result<Face, RigError> {
        let spec = self
            .faces
            .iter()
            .find(|f| f.face == face)
            .ok_or(RigError::NoSuchFace { face })?;
        self.geometry.face_at_yaw(face, spec.yaw_deg.to_radians())
    }

    /// Every face's geometry, in the rig's order.
    pub fn face_geometries(&self) -> Result<Vec<Face>, RigError> {
        self.faces.iter().map(|f| self.face(f.face)).collect()
    }

    /// The dictionary entry on `(robot, face)`, if that face carries one.
    pub fn index_of(&self, robot: u32, face: u8) -> Option<usize> {
        match &self.markers {
            Some(list) => list
                .iter()
                .find(|&&(r, f, _)| r == robot && f == face)
                .map(|&(_, _, i)| i),
            None => {
                let pos = self.faces.iter().position(|f| f.face == face)?;
                let robot = usize::try_from(robot.checked_sub(1)?).ok()?;
                robot.checked_mul(self.faces.len())?.checked_add(pos)
            }
        }
    }

    /// The `(robot, face)` carrying dictionary entry `index`, if any.
    pub fn robot_face(&self, index: usize) -> Option<(u32, u8)> {
        match &self.markers {
            Some(list) => list
                .iter()
                .find(|&&(_, _, i)| i == index)
                .map(|&(r, f, _)| (r, f)),
            None => {
                let n = self.faces.len();
                let robot = u32::try_from(index / n).ok()?.checked_add(1)?;
                Some((robot, self.faces.get(index % n)?.face))
            }
        }
    }

    /// The code on `(robot, face)`, or why there is none.
    pub fn code(&self, dictionary: &Dictionary, robot: u32, face: u8) -> Result<u64, RigError> {
        if robot == 0 {
            return Err(RigError::RobotZero);
        }
        if !self.faces.iter().any(|f| f.face == face) {
            return Err(RigError::NoSuchFace { face });
        }
        let needed = self
            .index_of(robot, face)
            .ok_or(RigError::NoMarker { robot, face })?;
        dictionary.code(needed).ok_or(RigError::TooManyRobots {
            robot,
            needed,
            len: dictionary.len(),
            max_robots: self.max_robots(dictionary),
        })
    }

    /// How many robots `dictionary` supports with this rig's default marker table (one
    /// entry per face and robot).
    pub fn max_robots(&self, dictionary: &Dictionary) -> u32 {
        u32::try_from(dictionary.len() / self.faces.len().max(1)).unwrap_or(u32::MAX)
    }
}

fn reference_faces() -> Vec<FaceSpec> {
    FACE_YAWS_DEG
        .iter()
        .enumerate()
        .map(|(i, &yaw_deg)| FaceSpec {
            face: i as u8 + 1,
            yaw_deg,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rig_faces() -> Vec<Face> {
        RigModel::reference().face_geometries().unwrap()
    }

    #[test]
    fn reference_marker_is_140_by_120_mm() {
        let [w, h] = RigGeometry::reference().marker_size_m().unwrap();
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
        let rig = RigGeometry::reference();
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
        let rig = RigGeometry::reference();
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
        let rig = RigModel::reference();
        for robot in 1..=20 {
            for face in 1..=5 {
                let i = rig.index_of(robot, face).unwrap();
                assert_eq!(rig.robot_face(i), Some((robot, face)));
            }
        }
        assert_eq!(rig.index_of(2, 3), Some(7));
        assert_eq!(rig.index_of(0, 1), None);
        assert_eq!(rig.index_of(1, 6), None);
        let d = Dictionary::paper();
        assert_eq!(rig.code(d, 0, 1), Err(RigError::RobotZero));
        assert_eq!(rig.code(d, 1, 6), Err(RigError::NoSuchFace { face: 6 }));
        assert!(matches!(rig.face(0), Err(RigError::NoSuchFace { face: 0 })));
        let too_many = rig.max_robots(d) + 1;
        assert!(matches!(
            rig.code(d, too_many, 1),
            Err(RigError::TooManyRobots { .. })
        ));
        assert_eq!(rig.code(d, 1, 1).unwrap(), d.codes()[0]);
    }

    #[test]
    fn bad_rigs_are_rejected() {
        let mut r = RigGeometry::reference();
        r.face_width_m = 0.15;
        assert!(matches!(r.validate(), Err(RigError::MarkerTooWide { .. })));
        let mut r = RigGeometry::reference();
        r.cell_size_m = f64::NAN;
        assert!(matches!(r.validate(), Err(RigError::BadLength { .. })));
        let mut r = RigGeometry::reference();
        r.data_rows = 0;
        assert!(matches!(r.validate(), Err(RigError::Family(_))));
    }

    #[test]
    fn rig_round_trips_through_json() {
        let r = RigGeometry::reference();
        let s = serde_json::to_string(&r).unwrap();
        assert_eq!(serde_json::from_str::<RigGeometry>(&s).unwrap(), r);
        let f = RigModel::reference().face(2).unwrap();
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
