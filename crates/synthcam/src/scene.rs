//! The scene: robots on a ground plane, their bodies and their rigs of textured faces.
//!
//! Everything is plain data with public fields, so a caller (the composition layer) can build
//! scenes from its own types directly; [`Scene::validate`] (called by the renderer) checks the
//! whole scene and returns a typed error for anything non-finite or degenerate.

use std::sync::Arc;

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};

use unicycle::PlanarPose;

use crate::error::{SynthError, finite, finite_vec, in_range, positive};
use crate::texture::Texture;

/// Checks that a robot's planar pose is finite (and within [`crate::MAX_MAGNITUDE`]).
pub(crate) fn validate_pose(pose: &PlanarPose) -> Result<(), SynthError> {
    finite("pose x", pose.x)?;
    finite("pose y", pose.y)?;
    finite("pose theta", pose.theta)?;
    Ok(())
}

/// The rigid transform body frame -> world frame of a robot at `pose` (the body frame's
/// origin is the reference point on the ground, x forward, y left, z up).
pub(crate) fn body_to_world(pose: &PlanarPose) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(pose.x, pose.y, 0.0),
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), pose.theta),
    )
}

/// A robot's opaque body, standing on the ground and centred on its reference point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Body {
    /// No body: only the faces are drawn (useful for tests).
    None,
    /// An axis-aligned box in the body frame: `x` in `[-length/2, length/2]`,
    /// `y` in `[-width/2, width/2]`, `z` in `[0, height]`.
    Box {
        /// Extent along body x (m).
        length: f64,
        /// Extent along body y (m).
        width: f64,
        /// Extent along body z (m).
        height: f64,
        /// Grey albedo in `[0, 1]`.
        albedo: f64,
    },
    /// A vertical cylinder about the body z axis, `z` in `[0, height]`.
    Cylinder {
        /// Radius (m).
        radius: f64,
        /// Height (m).
        height: f64,
        /// Grey albedo in `[0, 1]`.
        albedo: f64,
    },
}

impl Body {
    fn validate(&self) -> Result<(), SynthError> {
        match *self {
            Body::None => Ok(()),
            Body::Box {
                length,
                width,
                height,
                albedo,
            } => {
                positive("box length", length)?;
                positive("box width", width)?;
                positive("box height", height)?;
                in_range("box albedo", albedo, 0.0, 1.0)?;
                Ok(())
            }
            Body::Cylinder {
                radius,
                height,
                albedo,
            } => {
                positive("cylinder radius", radius)?;
                positive("cylinder height", height)?;
                in_range("cylinder albedo", albedo, 0.0, 1.0)?;
                Ok(())
            }
        }
    }
}

/// Where a planar rectangular face sits in its robot's body frame.
///
/// The face is seen from the side its outward `normal` points to. `up` need not be exactly
/// perpendicular to `normal`: its component along the normal is removed. Looking at the face
/// from outside, `right = up x normal`; texture coordinate `s` runs along `right` and `t` along
/// `-up`, so corner NW is `centre - right w/2 + up h/2`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FacePlacement {
    /// Centre of the rectangle (m, body frame).
    pub centre: Point3<f64>,
    /// Outward normal (any non-zero length).
    pub normal: Vector3<f64>,
    /// Up direction on the face (any length, not parallel to `normal`).
    pub up: Vector3<f64>,
    /// Width along `right` (m).
    pub width: f64,
    /// Height along `up` (m).
    pub height: f64,
}

/// The orthonormal frame of a face: unit `right`, `up`, outward `normal`, all in the frame the
/// placement was given in.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FaceFrame {
    /// Unit vector along increasing texture `s`.
    pub right: Vector3<f64>,
    /// Unit vector along decreasing texture `t`.
    pub up: Vector3<f64>,
    /// Unit outward normal.
    pub normal: Vector3<f64>,
}

impl FacePlacement {
    /// Check finiteness, positive size and a usable normal/up pair, and return the frame.
    pub fn frame(&self) -> Result<FaceFrame, SynthError> {
        finite_vec("face centre", &self.centre.coords)?;
        finite_vec("face normal", &self.normal)?;
        finite_vec("face up", &self.up)?;
        positive("face width", self.width)?;
        positive("face height", self.height)?;
        let normal = self
            .normal
            .try_normalize(1e-12)
            .ok_or(SynthError::DegenerateGeometry {
                what: "face normal is zero",
            })?;
        let up = (self.up - normal * self.up.dot(&normal))
            .try_normalize(1e-9 * self.up.norm().max(1e-300))
            .ok_or(SynthError::DegenerateGeometry {
                what: "face up vector is zero or parallel to the normal",
            })?;
        let right = up.cross(&normal);
        Ok(FaceFrame { right, up, normal })
    }

    /// The four corners NW, NE, SE, SW (as seen from outside), in the placement's frame.
    pub fn corners(&self) -> Result<[Point3<f64>; 4], SynthError> {
        let f = self.frame()?;
        let r = f.right * (self.width / 2.0);
        let u = f.up * (self.height / 2.0);
        let c = self.centre;
        Ok([c - r + u, c + r + u, c + r - u, c - r - u])
    }
}

/// A textured face of a robot's rig.
#[derive(Clone, Debug)]
pub struct Face {
    /// A label reported in the ground truth (e.g. a rig's face number).
    pub label: u32,
    /// Where the face is, in the body frame.
    pub placement: FacePlacement,
    /// What is drawn on its outer side.
    pub texture: Arc<dyn Texture>,
    /// Grey albedo of its back side, in `[0, 1]`.
    pub back_albedo: f64,
}

impl Face {
    /// A face with the default back albedo (0.25).
    pub fn new(label: u32, placement: FacePlacement, texture: Arc<dyn Texture>) -> Self {
        Self {
            label,
            placement,
            texture,
            back_albedo: 0.25,
        }
    }
}

/// A robot: a planar pose, a body and a rig of faces given in the body frame.
#[derive(Clone, Debug)]
pub struct Robot {
    /// PlanarPose on the ground (`unicycle`'s planar pose: metres, metres, radians CCW).
    pub pose: PlanarPose,
    /// The opaque body.
    pub body: Body,
    /// The rig's faces (body frame).
    pub faces: Vec<Face>,
}

impl Robot {
    /// A robot with a body and no faces yet.
    pub fn new(pose: PlanarPose, body: Body) -> Self {
        Self {
            pose,
            body,
            faces: Vec::new(),
        }
    }
    /// Add a face (builder style).
    pub fn with_face(mut self, face: Face) -> Self {
        self.faces.push(face);
        self
    }
    /// Add several faces (builder style).
    pub fn with_faces(mut self, faces: impl IntoIterator<Item = Face>) -> Self {
        self.faces.extend(faces);
        self
    }
}

/// A flat textured parallelogram fixed in the world: a poster, a test chart, or a marker held
/// up in front of the camera (any image quadrilateral is the view of some parallelogram).
///
/// Texture `s` runs from corner NW to NE and `t` from NW to SW; SE is `NE + SW - NW`. The
/// front is the side from which NW, NE, SE, SW run clockwise (as a face seen from outside).
#[derive(Clone, Debug)]
pub struct Panel {
    /// Corners NW, NE and SW (m, world frame).
    pub corners: [Point3<f64>; 3],
    /// What is drawn on its front.
    pub texture: Arc<dyn Texture>,
    /// Grey albedo of its back side, in `[0, 1]`.
    pub back_albedo: f64,
}

impl Panel {
    /// A panel with the default back albedo (0.25).
    pub fn new(corners: [Point3<f64>; 3], texture: Arc<dyn Texture>) -> Self {
        Self {
            corners,
            texture,
            back_albedo: 0.25,
        }
    }

    fn validate(&self) -> Result<(), SynthError> {
        for c in &self.corners {
            finite_vec("panel corner", &c.coords)?;
        }
        let [nw, ne, sw] = self.corners;
        let n = (sw - nw).cross(&(ne - nw));
        let scale = (ne - nw).norm() * (sw - nw).norm();
        if !(n.norm() > 1e-12 * scale && scale > 0.0) {
            return Err(SynthError::DegenerateGeometry {
                what: "panel corners are collinear or coincide",
            });
        }
        in_range("panel back albedo", self.back_albedo, 0.0, 1.0)?;
        Ok(())
    }
}

/// The ground plane `z = 0`, textured by tiling a texture: one texture period covers
/// `tile x tile` metres, with `s` along world x and `t` along world -y.
#[derive(Clone, Debug)]
pub struct Ground {
    /// The tiled texture.
    pub texture: Arc<dyn Texture>,
    /// Size of one tile (m).
    pub tile: f64,
}

/// A whole scene.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The robots (their index is their id in the ground truth).
    pub robots: Vec<Robot>,
    /// Panels fixed in the world.
    pub panels: Vec<Panel>,
    /// The ground plane, if any (without one, rays that miss everything see the background).
    pub ground: Option<Ground>,
    /// Grey albedo in `[0, 1]` of everything the rays do not hit (sky or far wall).
    pub background: f64,
}

impl Scene {
    /// An empty scene with no ground and the given background albedo.
    pub fn new(background: f64) -> Self {
        Self {
            robots: Vec::new(),
            panels: Vec::new(),
            ground: None,
            background,
        }
    }

    /// Check every number in the scene (finite poses, positive sizes, albedos in `[0, 1]`,
    /// usable face frames).
    pub fn validate(&self) -> Result<(), SynthError> {
        in_range("background albedo", self.background, 0.0, 1.0)?;
        if let Some(g) = &self.ground {
            positive("ground tile", g.tile)?;
        }
        for p in &self.panels {
            p.validate()?;
        }
        for r in &self.robots {
            validate_pose(&r.pose)?;
            r.body.validate()?;
            for f in &r.faces {
                f.placement.frame()?;
                in_range("face back albedo", f.back_albedo, 0.0, 1.0)?;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn degenerate_faces_are_errors() {
        let mut p = FacePlacement {
            centre: Point3::new(0.0, 0.2, 0.3),
            normal: Vector3::y(),
            up: Vector3::z(),
            width: 0.18,
            height: 0.16,
        };
        assert!(p.frame().is_ok());
        p.up = p.normal * 2.0;
        assert!(matches!(
            p.frame(),
            Err(SynthError::DegenerateGeometry { .. })
        ));
        p.up = Vector3::z();
        p.normal = Vector3::zeros();
        assert!(matches!(
            p.frame(),
            Err(SynthError::DegenerateGeometry { .. })
        ));
        p.normal = Vector3::x();
        p.width = 0.0;
        assert!(matches!(p.frame(), Err(SynthError::NotPositive { .. })));
        p.width = f64::NAN;
        assert!(matches!(p.frame(), Err(SynthError::NonFinite { .. })));
    }
}
