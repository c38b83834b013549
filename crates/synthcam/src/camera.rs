//! Posed pinhole cameras: on a robot, or free.

use nalgebra::{
    Isometry3, Matrix3, Point2, Point3, Rotation3, Translation3, UnitQuaternion, Vector3,
};

use pose::Intrinsics;

use crate::error::{MAX_INTRINSIC, MAX_MAGNITUDE, SynthError, bounded, finite, finite_vec};
use unicycle::PlanarPose;

use crate::scene::{body_to_world, validate_pose};

/// Largest image the renderer accepts, in pixels (64 Mpx).
pub const MAX_PIXELS: usize = 1 << 26;

/// A posed camera: `pose`'s [`pose::Camera`] (intrinsics and image size; the renderer casts
/// ideal pinhole rays, so no lens distortion) and the extrinsics `world -> camera`.
///
/// Pixel `(u, v)` (u right, v down, integer values at pixel *centres*) sees the ray
/// `K^-1 [u, v, 1]^T` in the camera frame (x right, y down, z along the optical axis); the
/// image covers `[-0.5, w - 0.5] x [-0.5, h - 0.5]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PosedCamera {
    camera: pose::Camera,
    k: Matrix3<f64>,
    k_inv: Matrix3<f64>,
    width: usize,
    height: usize,
    world_to_camera: Isometry3<f64>,
}

impl PosedCamera {
    /// A camera from intrinsics, an image size (non-empty, at most [`MAX_PIXELS`]) and its
    /// extrinsics `world -> camera` (must be finite). Entries of `K` beyond
    /// [`MAX_INTRINSIC`] are refused.
    pub fn new(
        intrinsics: Intrinsics,
        width: usize,
        height: usize,
        world_to_camera: Isometry3<f64>,
    ) -> Result<Self, SynthError> {
        let k = intrinsics.matrix();
        for &c in k.iter() {
            bounded("intrinsic matrix entry", c, MAX_INTRINSIC)?;
        }
        let k_inv = k.try_inverse().ok_or(SynthError::InvalidIntrinsics {
            reason: "K is singular",
        })?;
        if k_inv.iter().any(|c| !c.is_finite()) {
            return Err(SynthError::InvalidIntrinsics {
                reason: "K is numerically singular",
            });
        }
        check_size(width, height)?;
        // World -> camera translation components of a camera whose centre lies within the
        // magnitude limit can reach sqrt(3) times it.
        for &c in world_to_camera.translation.vector.iter() {
            bounded("camera translation", c, 2.0 * MAX_MAGNITUDE)?;
        }
        for &c in world_to_camera.rotation.coords.iter() {
            finite("camera rotation", c)?;
        }
        Ok(Self {
            // Both sides are at most MAX_PIXELS (2^26), so they fit a u32.
            camera: pose::Camera::pinhole(intrinsics, width as u32, height as u32),
            k,
            k_inv,
            width,
            height,
            world_to_camera,
        })
    }

    /// A camera on a robot standing at `robot`, mounted with `camera_to_body` (the rigid
    /// transform camera frame -> robot body frame: body x forward, y left, z up, origin at
    /// the robot's reference point on the ground).
    pub fn on_robot(
        intrinsics: Intrinsics,
        width: usize,
        height: usize,
        camera_to_body: &Isometry3<f64>,
        robot: &PlanarPose,
    ) -> Result<Self, SynthError> {
        validate_pose(robot)?;
        for &c in camera_to_body
            .translation
            .vector
            .iter()
            .chain(camera_to_body.rotation.coords.iter())
        {
            finite("camera mount", c)?;
        }
        let camera_to_world = body_to_world(robot) * camera_to_body;
        Self::new(intrinsics, width, height, camera_to_world.inverse())
    }

    /// A free camera at `eye` looking at `target`, with image "up" (-y) as close to `up` as
    /// possible.
    pub fn look_at(
        intrinsics: Intrinsics,
        width: usize,
        height: usize,
        eye: Point3<f64>,
        target: Point3<f64>,
        up: Vector3<f64>,
    ) -> Result<Self, SynthError> {
        finite_vec("camera eye", &eye.coords)?;
        finite_vec("camera target", &target.coords)?;
        finite_vec("camera up", &up)?;
        let z = (target - eye)
            .try_normalize(1e-12)
            .ok_or(SynthError::DegenerateGeometry {
                what: "camera target coincides with the eye",
            })?;
        let x = z
            .cross(&up)
            .try_normalize(1e-12)
            .ok_or(SynthError::DegenerateGeometry {
                what: "camera up vector is zero or parallel to the view direction",
            })?;
        let y = z.cross(&x);
        let r = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, y, z]));
        let camera_to_world = Isometry3::from_parts(
            Translation3::from(eye.coords),
            UnitQuaternion::from_rotation_matrix(&r),
        );
        Self::new(intrinsics, width, height, camera_to_world.inverse())
    }

    /// The intrinsics.
    pub fn intrinsics(&self) -> &Intrinsics {
        &self.camera.intrinsics
    }
    /// The camera model (intrinsics and image size) it renders through.
    pub fn camera(&self) -> &pose::Camera {
        &self.camera
    }
    /// `K`.
    pub fn k(&self) -> &Matrix3<f64> {
        &self.k
    }
    /// `K^-1`.
    pub fn k_inv(&self) -> &Matrix3<f64> {
        &self.k_inv
    }
    /// Image width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }
    /// Image height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Exact pinhole projection of a camera-frame point ([`pose::Camera::project`]); `None`
    /// unless `z >` [`pose::MIN_DEPTH`] (which, with the crate's magnitude limits, keeps the
    /// result finite).
    pub fn project(&self, p: &Point3<f64>) -> Option<Point2<f64>> {
        self.camera.project(p).ok()
    }

    /// The (unnormalised, `z = 1`) camera-frame ray through pixel coordinates `(u, v)`.
    pub fn ray(&self, u: f64, v: f64) -> Vector3<f64> {
        self.k_inv * Vector3::new(u, v, 1.0)
    }

    /// True if `(u, v)` lies inside the image area `[-0.5, w - 0.5] x [-0.5, h - 0.5]`.
    pub fn contains(&self, p: &Point2<f64>) -> bool {
        self.camera.contains(p)
    }
    /// The rigid transform world -> camera.
    pub fn world_to_camera(&self) -> &Isometry3<f64> {
        &self.world_to_camera
    }
    /// The rigid transform camera -> world.
    pub fn camera_to_world(&self) -> Isometry3<f64> {
        self.world_to_camera.inverse()
    }
    /// Exact projection of a world point; `None` if it is not in front of the camera.
    pub fn project_world(&self, p: &Point3<f64>) -> Option<Point2<f64>> {
        self.project(&(self.world_to_camera * p))
    }
}

fn check_size(width: usize, height: usize) -> Result<(), SynthError> {
    if width == 0 || height == 0 {
        return Err(SynthError::ZeroImageSize { width, height });
    }
    match width.checked_mul(height) {
        Some(n) if n <= MAX_PIXELS => Ok(()),
        _ => Err(SynthError::ImageTooLarge {
            width,
            height,
            max: MAX_PIXELS,
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const W: usize = 640;
    const H: usize = 480;

    fn intr() -> Intrinsics {
        Intrinsics::from_hfov(60f64.to_radians(), W as u32, H as u32).unwrap()
    }

    /// PosedCamera -> body of a camera `d` ahead of the reference point at `height`, panned left
    /// by `pan` and tilted down by `tilt` (image x = body -y, image y = body -z when level).
    fn mount(d: f64, height: f64, pan: f64, tilt: f64) -> Isometry3<f64> {
        let r0 = Rotation3::from_matrix_unchecked(Matrix3::new(
            0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0,
        ));
        let r = Rotation3::from_axis_angle(&Vector3::z_axis(), pan)
            * Rotation3::from_axis_angle(&Vector3::y_axis(), tilt)
            * r0;
        Isometry3::from_parts(
            Translation3::new(d, 0.0, height),
            UnitQuaternion::from_rotation_matrix(&r),
        )
    }

    fn on_robot(m: &Isometry3<f64>, robot: PlanarPose) -> Result<PosedCamera, SynthError> {
        PosedCamera::on_robot(intr(), W, H, m, &robot)
    }

    #[test]
    fn level_mounted_camera_sees_a_point_ahead_at_the_principal_point() {
        let cam = on_robot(&mount(0.1, 0.3, 0.0, 0.0), PlanarPose::new(1.0, 2.0, 0.5)).unwrap();
        // A point 2 m ahead of the camera along the robot's heading, at camera height.
        let (s, c) = 0.5f64.sin_cos();
        let p = Point3::new(1.0 + 2.1 * c, 2.0 + 2.1 * s, 0.3);
        let q = cam.project_world(&p).unwrap();
        assert!(
            (q.x - 319.5).abs() < 1e-9 && (q.y - 239.5).abs() < 1e-9,
            "{q:?}"
        );
        // A point to the robot's left appears at smaller u; a point above at smaller v.
        let left = Point3::new(p.x - 0.2 * s, p.y + 0.2 * c, 0.3);
        assert!(cam.project_world(&left).unwrap().x < 319.0);
        let above = Point3::new(p.x, p.y, 0.5);
        assert!(cam.project_world(&above).unwrap().y < 239.0);
    }

    #[test]
    fn pan_left_and_tilt_down_move_the_view_as_documented() {
        let ahead = Point3::new(3.0, 0.0, 0.3);
        let origin = PlanarPose::default();
        let level = on_robot(&mount(0.0, 0.3, 0.0, 0.0), origin).unwrap();
        let panned = on_robot(&mount(0.0, 0.3, 0.2, 0.0), origin).unwrap();
        let tilted = on_robot(&mount(0.0, 0.3, 0.0, 0.2), origin).unwrap();
        let u0 = level.project_world(&ahead).unwrap();
        // Panning left moves a fixed point to the right of the image.
        assert!(panned.project_world(&ahead).unwrap().x > u0.x + 10.0);
        // Tilting down moves a fixed point up in the image.
        assert!(tilted.project_world(&ahead).unwrap().y < u0.y - 10.0);
    }

    #[test]
    fn look_at_matches_a_mounted_camera() {
        let a = on_robot(&mount(0.0, 0.3, 0.0, 0.0), PlanarPose::default()).unwrap();
        let b = PosedCamera::look_at(
            intr(),
            W,
            H,
            Point3::new(0.0, 0.0, 0.3),
            Point3::new(1.0, 0.0, 0.3),
            Vector3::z(),
        )
        .unwrap();
        let p = Point3::new(2.0, 0.4, -0.1);
        assert!((a.project_world(&p).unwrap() - b.project_world(&p).unwrap()).norm() < 1e-9);
    }

    #[test]
    fn bad_sizes_and_poses_are_errors() {
        let id = Isometry3::identity();
        let huge = Intrinsics::square_pixels(1e12, 1e12, 10.0, 10.0).unwrap();
        assert!(matches!(
            PosedCamera::new(huge, 20, 20, id),
            Err(SynthError::TooLarge { .. })
        ));
        assert!(matches!(
            PosedCamera::new(intr(), 0, 10, id),
            Err(SynthError::ZeroImageSize { .. })
        ));
        assert!(matches!(
            PosedCamera::new(intr(), 1 << 20, 1 << 20, id),
            Err(SynthError::ImageTooLarge { .. })
        ));
        assert!(matches!(
            on_robot(
                &mount(0.0, 0.0, 0.0, 0.0),
                PlanarPose::new(f64::INFINITY, 0.0, 0.0)
            ),
            Err(SynthError::NonFinite { .. })
        ));
        let mut bad_mount = mount(0.0, 0.3, 0.0, 0.0);
        bad_mount.translation.vector.x = f64::NAN;
        assert!(matches!(
            on_robot(&bad_mount, PlanarPose::default()),
            Err(SynthError::NonFinite { .. })
        ));
        assert!(
            PosedCamera::look_at(
                intr(),
                W,
                H,
                Point3::origin(),
                Point3::origin(),
                Vector3::z()
            )
            .is_err()
        );
        assert!(
            PosedCamera::look_at(
                intr(),
                W,
                H,
                Point3::origin(),
                Point3::new(0.0, 0.0, 1.0),
                Vector3::z()
            )
            .is_err()
        );
    }
}
