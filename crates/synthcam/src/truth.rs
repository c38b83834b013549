//! Exact ground truth: poses in the camera frame, face visibility, corners by exact projection.

use nalgebra::{Isometry3, Point2, Point3};

use unicycle::PlanarPose;

use crate::camera::PosedCamera;
use crate::error::SynthError;
use crate::raycast::Prepared;
use crate::scene::Scene;

/// How far a corner is pulled towards the face centre before the occlusion test, as a fraction
/// of the corner-to-centre distance (so faces that share an edge do not occlude each other).
pub const CORNER_INSET: f64 = 1e-3;

/// Ground truth of one face.
///
/// A face is **visible** when all of these hold:
/// - `front_facing`: the camera centre lies strictly on the outward side of the face's plane
///   (equivalently `off_axis_deg < 90`);
/// - `in_front`: all four corners have camera-frame `z >` [`pose::MIN_DEPTH`];
/// - `inside_image`: all four projected corners lie in the image area
///   `[-0.5, w - 0.5] x [-0.5, h - 0.5]`;
/// - `unoccluded`: for each corner, the segment from the camera centre to the corner (pulled
///   [`CORNER_INSET`] of the way towards the face centre) hits no other object or the ground.
///
/// Occlusion is only tested at the corners: an object that covers part of the face's interior
/// but none of its corners does not make it invisible.
#[derive(Clone, Debug, PartialEq)]
pub struct FaceTruth {
    /// The face's label (`Face::label`).
    pub label: u32,
    /// Index of the face in its robot's `faces`.
    pub index: usize,
    /// All four conditions below.
    pub visible: bool,
    /// The camera is on the face's outward side.
    pub front_facing: bool,
    /// All corners are in front of the camera.
    pub in_front: bool,
    /// All projected corners are inside the image area.
    pub inside_image: bool,
    /// Per corner (NW, NE, SE, SW): not occluded.
    pub unoccluded: [bool; 4],
    /// Angle between the outward normal and the direction from the face centre to the camera
    /// centre, in degrees, in `[0, 180]`.
    pub off_axis_deg: f64,
    /// Mean length of the projected top and bottom edges, in pixels (`None` unless `in_front`).
    pub width_px: Option<f64>,
    /// Projected corners NW, NE, SE, SW as seen from outside, pixel-centre convention
    /// (`None` unless `in_front`).
    pub corners_px: Option<[Point2<f64>; 4]>,
    /// Corners NW, NE, SE, SW in the camera frame (m).
    pub corners_camera: [Point3<f64>; 4],
    /// Face centre in the camera frame (m).
    pub centre_camera: Point3<f64>,
}

/// Ground truth of one robot.
#[derive(Clone, Debug, PartialEq)]
pub struct RobotTruth {
    /// Index of the robot in `Scene::robots`.
    pub index: usize,
    /// Its planar world pose.
    pub pose: PlanarPose,
    /// The rigid transform body frame -> camera frame (the robot's pose in the camera frame).
    pub body_to_camera: Isometry3<f64>,
    /// One entry per face, in the order of `Robot::faces`.
    pub faces: Vec<FaceTruth>,
}

/// Ground truth of a frame.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameTruth {
    /// The camera (intrinsics, image size, `world -> camera`).
    pub camera: PosedCamera,
    /// One entry per robot, in scene order.
    pub robots: Vec<RobotTruth>,
}

impl FrameTruth {
    /// The face labelled `label` of robot `robot`, if both exist.
    pub fn face(&self, robot: usize, label: u32) -> Option<&FaceTruth> {
        self.robots
            .get(robot)?
            .faces
            .iter()
            .find(|f| f.label == label)
    }
    /// All visible faces, as `(robot index, face)`.
    pub fn visible_faces(&self) -> impl Iterator<Item = (usize, &FaceTruth)> {
        self.robots.iter().flat_map(|r| {
            r.faces
                .iter()
                .filter(|f| f.visible)
                .map(move |f| (r.index, f))
        })
    }
}

/// Ground truth of `scene` seen by `camera`, without rendering.
pub fn ground_truth(scene: &Scene, camera: &PosedCamera) -> Result<FrameTruth, SynthError> {
    scene.validate()?;
    let prepared = Prepared::new(scene, camera, None)?;
    ground_truth_prepared(scene, camera, &prepared)
}

pub(crate) fn ground_truth_prepared(
    scene: &Scene,
    camera: &PosedCamera,
    prepared: &Prepared<'_>,
) -> Result<FrameTruth, SynthError> {
    let w2c = *camera.world_to_camera();
    let all: Vec<u32> = (0..prepared.prims.len() as u32).collect();
    let mut robots = Vec::with_capacity(scene.robots.len());
    for (ri, robot) in scene.robots.iter().enumerate() {
        let b2c = w2c * crate::scene::body_to_world(&robot.pose);
        let mut faces = Vec::with_capacity(robot.faces.len());
        for (fi, face) in robot.faces.iter().enumerate() {
            let frame = face.placement.frame()?;
            let corners_camera = face.placement.corners()?.map(|p| b2c * p);
            let centre_camera = b2c * face.placement.centre;
            let normal = b2c.rotation * frame.normal;
            let to_camera = -centre_camera.coords;
            let dist = to_camera.norm();
            let cos = if dist > 0.0 {
                (normal.dot(&to_camera) / dist).clamp(-1.0, 1.0)
            } else {
                0.0
            };
            let off_axis_deg = cos.acos().to_degrees();
            let front_facing = normal.dot(&to_camera) > 0.0;
            let projected: Vec<Point2<f64>> = corners_camera
                .iter()
                .filter_map(|p| camera.project(p))
                .collect();
            let in_front = projected.len() == 4;
            let corners_px = <[Point2<f64>; 4]>::try_from(projected).ok();
            let inside_image = corners_px.is_some_and(|c| c.iter().all(|p| camera.contains(p)));
            let width_px = corners_px.map(|c| ((c[1] - c[0]).norm() + (c[2] - c[3]).norm()) / 2.0);
            let skip = prepared
                .prims
                .iter()
                .position(|p| p.owner == (ri, Some(fi)));
            let unoccluded = corners_camera.map(|c| {
                let target = c + (centre_camera - c) * CORNER_INSET;
                // The ray d = target reaches the corner at t = 1.
                prepared
                    .nearest(&target.coords, None, &all, 1.0 - 1e-9, skip)
                    .is_none()
            });
            faces.push(FaceTruth {
                label: face.label,
                index: fi,
                visible: front_facing && in_front && inside_image && unoccluded.iter().all(|&x| x),
                front_facing,
                in_front,
                inside_image,
                unoccluded,
                off_axis_deg,
                width_px,
                corners_px,
                corners_camera,
                centre_camera,
            });
        }
        robots.push(RobotTruth {
            index: ri,
            pose: robot.pose,
            body_to_camera: b2c,
            faces,
        });
    }
    Ok(FrameTruth {
        camera: *camera,
        robots,
    })
}
