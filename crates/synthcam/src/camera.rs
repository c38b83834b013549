//! Pinhole intrinsics, camera mounts on robots, and free camera poses.

use nalgebra::{
    Isometry3, Matrix3, Point2, Point3, Rotation3, Translation3, UnitQuaternion, Vector3,
};

use crate::error::{
    MAX_INTRINSIC, MAX_MAGNITUDE, SynthError, bounded, finite, finite_vec, in_range,
};
use crate::scene::Pose2;

/// Points closer to the camera's focal plane than this (m, camera-frame `z`) do not project.
pub const MIN_DEPTH: f64 = 1e-9;

/// Largest image the renderer accepts, in pixels (64 Mpx).
pub const MAX_PIXELS: usize = 1 << 26;

/// Pinhole intrinsics: an upper-triangular `K` (skew allowed) and an image size.
///
/// Pixel `(u, v)` (u right, v down, integer values at pixel *centres*) sees the ray
/// `K^-1 [u, v, 1]^T` in the camera frame (x right, y down, z along the optical axis); the
/// image covers `[-0.5, w - 0.5] x [-0.5, h - 0.5]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Intrinsics {
    k: Matrix3<f64>,
    k_inv: Matrix3<f64>,
    width: usize,
    height: usize,
}

impl Intrinsics {
    /// Intrinsics from `K` and an image size.
    ///
    /// `K` must be finite and upper triangular with `K[2][2] = 1` and positive focal lengths
    /// `K[0][0]`, `K[1][1]`; the image must be non-empty and at most [`MAX_PIXELS`].
    pub fn new(k: Matrix3<f64>, width: usize, height: usize) -> Result<Self, SynthError> {
        for &c in k.iter() {
            bounded("intrinsic matrix entry", c, MAX_INTRINSIC)?;
        }
        if k[(1, 0)] != 0.0 || k[(2, 0)] != 0.0 || k[(2, 1)] != 0.0 {
            return Err(SynthError::InvalidIntrinsics {
                reason: "K must be upper triangular",
            });
        }
        if k[(2, 2)] != 1.0 {
            return Err(SynthError::InvalidIntrinsics {
                reason: "K[2][2] must be 1",
            });
        }
        if !(k[(0, 0)] > 0.0 && k[(1, 1)] > 0.0) {
            return Err(SynthError::InvalidIntrinsics {
                reason: "focal lengths K[0][0] and K[1][1] must be > 0",
            });
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
        Ok(Self {
            k,
            k_inv,
            width,
            height,
        })
    }

    /// Square pixels, no skew, principal point at the image centre `((w-1)/2, (h-1)/2)`, and a
    /// horizontal field of view (degrees, in `(0, 180)`).
    pub fn from_hfov(width: usize, height: usize, hfov_deg: f64) -> Result<Self, SynthError> {
        check_size(width, height)?;
        in_range("horizontal field of view", hfov_deg, 1e-6, 179.999)?;
        let f = width as f64 / 2.0 / (hfov_deg.to_radians() / 2.0).tan();
        let k = Matrix3::new(
            f,
            0.0,
            (width as f64 - 1.0) / 2.0,
            0.0,
            f,
            (height as f64 - 1.0) / 2.0,
            0.0,
            0.0,
            1.0,
        );
        Self::new(k, width, height)
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

    /// Exact pinhole projection of a camera-frame point; `None` unless `z > MIN_DEPTH`
    /// (which, with the crate's magnitude limits, keeps the result finite).
    pub fn project(&self, p: &Point3<f64>) -> Option<Point2<f64>> {
        if p.z > MIN_DEPTH {
            let q = self.k * p.coords;
            Some(Point2::new(q.x / q.z, q.y / q.z))
        } else {
            None
        }
    }

    /// The (unnormalised, `z = 1`) ray through pixel coordinates `(u, v)`.
    pub fn ray(&self, u: f64, v: f64) -> Vector3<f64> {
        self.k_inv * Vector3::new(u, v, 1.0)
    }

    /// True if `(u, v)` lies inside the image area `[-0.5, w - 0.5] x [-0.5, h - 0.5]`.
    pub fn contains(&self, p: &Point2<f64>) -> bool {
        p.x >= -0.5
            && p.y >= -0.5
            && p.x <= self.width as f64 - 0.5
            && p.y <= self.height as f64 - 0.5
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

/// How a camera is mounted on a robot.
///
/// The optical centre sits at body `(d, 0, height)`: `d` ahead of the reference point, as in the
/// spec's `x_2c = x_2 + d cos(theta_2)`. With `pan = tilt = 0` the optical axis is body x, the
/// image x axis body -y and the image y axis body -z (a level camera looking forward). `pan`
/// rotates about the body z axis (left positive); `tilt` rotates about the panned camera's
/// horizontal axis, **down positive**. So `camera -> body` rotation is
/// `Rz(pan) * Ry(tilt) * R0` with `R0 = [[0, 0, 1], [-1, 0, 0], [0, -1, 0]]`.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct CameraMount {
    /// Offset ahead of the reference point (m).
    pub d: f64,
    /// Height of the optical centre above the ground (m).
    pub height: f64,
    /// Pan about body z (rad, left positive).
    pub pan: f64,
    /// Tilt (rad, down positive).
    pub tilt: f64,
}

impl CameraMount {
    /// The rigid transform camera frame -> robot body frame.
    pub fn camera_to_body(&self) -> Result<Isometry3<f64>, SynthError> {
        finite("mount d", self.d)?;
        finite("mount height", self.height)?;
        finite("mount pan", self.pan)?;
        finite("mount tilt", self.tilt)?;
        let r0 = Rotation3::from_matrix_unchecked(Matrix3::new(
            0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0,
        ));
        let r = Rotation3::from_axis_angle(&Vector3::z_axis(), self.pan)
            * Rotation3::from_axis_angle(&Vector3::y_axis(), self.tilt)
            * r0;
        Ok(Isometry3::from_parts(
            Translation3::new(self.d, 0.0, self.height),
            UnitQuaternion::from_rotation_matrix(&r),
        ))
    }
}

/// A posed pinhole camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    intrinsics: Intrinsics,
    world_to_camera: Isometry3<f64>,
}

impl Camera {
    /// A camera from intrinsics and its extrinsics `world -> camera` (must be finite).
    pub fn new(
        intrinsics: Intrinsics,
        world_to_camera: Isometry3<f64>,
    ) -> Result<Self, SynthError> {
        // World -> camera translation components of a camera whose centre lies within the
        // magnitude limit can reach sqrt(3) times it.
        for &c in world_to_camera.translation.vector.iter() {
            bounded("camera translation", c, 2.0 * MAX_MAGNITUDE)?;
        }
        for &c in world_to_camera.rotation.coords.iter() {
            finite("camera rotation", c)?;
        }
        Ok(Self {
            intrinsics,
            world_to_camera,
        })
    }

    /// A camera on a robot at `robot` with the given mount.
    pub fn on_robot(
        intrinsics: Intrinsics,
        mount: &CameraMount,
        robot: Pose2,
    ) -> Result<Self, SynthError> {
        robot.validate()?;
        let camera_to_world = robot.body_to_world() * mount.camera_to_body()?;
        Self::new(intrinsics, camera_to_world.inverse())
    }

    /// A free camera at `eye` looking at `target`, with image "up" (-y) as close to `up` as
    /// possible.
    pub fn look_at(
        intrinsics: Intrinsics,
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
        Self::new(intrinsics, camera_to_world.inverse())
    }

    /// The intrinsics.
    pub fn intrinsics(&self) -> &Intrinsics {
        &self.intrinsics
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
        self.intrinsics.project(&(self.world_to_camera * p))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn intr() -> Intrinsics {
        Intrinsics::from_hfov(640, 480, 60.0).unwrap()
    }

    #[test]
    fn level_mounted_camera_sees_a_point_ahead_at_the_principal_point() {
        let mount = CameraMount {
            d: 0.1,
            height: 0.3,
            pan: 0.0,
            tilt: 0.0,
        };
        let cam = Camera::on_robot(intr(), &mount, Pose2::new(1.0, 2.0, 0.5)).unwrap();
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
        let level = Camera::on_robot(
            intr(),
            &CameraMount {
                d: 0.0,
                height: 0.3,
                pan: 0.0,
                tilt: 0.0,
            },
            Pose2::default(),
        )
        .unwrap();
        let panned = Camera::on_robot(
            intr(),
            &CameraMount {
                d: 0.0,
                height: 0.3,
                pan: 0.2,
                tilt: 0.0,
            },
            Pose2::default(),
        )
        .unwrap();
        let tilted = Camera::on_robot(
            intr(),
            &CameraMount {
                d: 0.0,
                height: 0.3,
                pan: 0.0,
                tilt: 0.2,
            },
            Pose2::default(),
        )
        .unwrap();
        let u0 = level.project_world(&ahead).unwrap();
        // Panning left moves a fixed point to the right of the image.
        assert!(panned.project_world(&ahead).unwrap().x > u0.x + 10.0);
        // Tilting down moves a fixed point up in the image.
        assert!(tilted.project_world(&ahead).unwrap().y < u0.y - 10.0);
    }

    #[test]
    fn look_at_matches_a_mounted_camera() {
        let mount = CameraMount {
            d: 0.0,
            height: 0.3,
            pan: 0.0,
            tilt: 0.0,
        };
        let a = Camera::on_robot(intr(), &mount, Pose2::default()).unwrap();
        let b = Camera::look_at(
            intr(),
            Point3::new(0.0, 0.0, 0.3),
            Point3::new(1.0, 0.0, 0.3),
            Vector3::z(),
        )
        .unwrap();
        let p = Point3::new(2.0, 0.4, -0.1);
        assert!((a.project_world(&p).unwrap() - b.project_world(&p).unwrap()).norm() < 1e-9);
    }

    #[test]
    fn bad_intrinsics_and_poses_are_errors() {
        let mut k = *intr().k();
        k[(0, 0)] = 0.0;
        assert!(matches!(
            Intrinsics::new(k, 10, 10),
            Err(SynthError::InvalidIntrinsics { .. })
        ));
        let mut k = *intr().k();
        k[(2, 1)] = 0.3;
        assert!(matches!(
            Intrinsics::new(k, 10, 10),
            Err(SynthError::InvalidIntrinsics { .. })
        ));
        let mut k = *intr().k();
        k[(0, 2)] = f64::NAN;
        assert!(matches!(
            Intrinsics::new(k, 10, 10),
            Err(SynthError::NonFinite { .. })
        ));
        let mut k = *intr().k();
        k[(0, 0)] = 1e-320;
        assert!(Intrinsics::new(k, 10, 10).is_err());
        assert!(matches!(
            Intrinsics::from_hfov(0, 10, 60.0),
            Err(SynthError::ZeroImageSize { .. })
        ));
        assert!(matches!(
            Intrinsics::from_hfov(1 << 20, 1 << 20, 60.0),
            Err(SynthError::ImageTooLarge { .. })
        ));
        assert!(matches!(
            Camera::on_robot(
                intr(),
                &CameraMount::default(),
                Pose2::new(f64::INFINITY, 0.0, 0.0)
            ),
            Err(SynthError::NonFinite { .. })
        ));
        assert!(Camera::look_at(intr(), Point3::origin(), Point3::origin(), Vector3::z()).is_err());
        assert!(
            Camera::look_at(
                intr(),
                Point3::origin(),
                Point3::new(0.0, 0.0, 1.0),
                Vector3::z()
            )
            .is_err()
        );
    }
}
