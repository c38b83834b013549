//! Pinhole intrinsics with skew (spec 4.1) and the OpenGL frustum they come from in the
//! synthetic camera (spec 4.2).
//!
//! Pixel convention (spec 2.1): u right, v down, integer coordinates are pixel centres, so a
//! `w x h` image covers `[-0.5, w - 0.5] x [-0.5, h - 0.5]`.

use crate::{Distortion, Pose, PoseError, so3};
use nalgebra::{Matrix2x3, Matrix3, Point2, Point3, SMatrix, Vector3};

/// The one behind-the-camera rule of the workspace: a camera-frame point projects only if its
/// depth `z` is above this (metres); one at or below it (on or behind the camera plane, or
/// NaN) is refused, never projected to a flipped or infinite pixel.
pub const MIN_DEPTH: f64 = 1e-9;

/// A camera: pinhole intrinsics, lens distortion and the image size. It is what a
/// calibration file describes ([`crate::calib`]), what the synthetic camera renders through
/// and what annotations are drawn with; [`Camera::project`] is the one projection.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Pinhole intrinsics.
    pub intrinsics: Intrinsics,
    /// Lens distortion (none: [`Distortion::NONE`]).
    pub distortion: Distortion,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
}

impl Camera {
    /// A camera without lens distortion.
    pub fn pinhole(intrinsics: Intrinsics, width: u32, height: u32) -> Self {
        Self {
            intrinsics,
            distortion: Distortion::NONE,
            width,
            height,
        }
    }

    /// Projects a camera-frame point to a pixel: the pinhole projection
    /// ([`Intrinsics::project`]), then the lens distortion. A point with `z <=` [`MIN_DEPTH`]
    /// is an error ([`PoseError::PointBehindCamera`]).
    #[inline]
    pub fn project(&self, p: &Point3<f64>) -> Result<Point2<f64>, PoseError> {
        let ideal = self.intrinsics.project(p)?;
        if self.distortion.is_identity() {
            Ok(ideal)
        } else {
            Ok(self.distortion.distort_pixel(&self.intrinsics, &ideal))
        }
    }

    /// True if the pixel `m` lies inside the image, `[-0.5, w - 0.5] x [-0.5, h - 0.5]`
    /// (spec 2.1).
    pub fn contains(&self, m: &Point2<f64>) -> bool {
        m.x >= -0.5
            && m.y >= -0.5
            && m.x <= f64::from(self.width) - 0.5
            && m.y <= f64::from(self.height) - 0.5
    }
}

/// Pinhole intrinsics `K = [[alpha, -alpha cot(theta), u0], [0, beta / sin(theta), v0], [0, 0, 1]]`
/// (spec 4.1, paper eq. 20).
///
/// Fields are private so every value is a valid, invertible camera: build it with
/// [`Intrinsics::new`], [`Intrinsics::square_pixels`], [`Intrinsics::from_hfov`] or
/// [`Frustum::intrinsics`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Intrinsics {
    alpha: f64,
    beta: f64,
    theta: f64,
    u0: f64,
    v0: f64,
    // Cached entries of K: k01 = -alpha cot(theta), k11 = beta / sin(theta).
    k01: f64,
    k11: f64,
}

impl Intrinsics {
    /// Intrinsics from the spec's five parameters. `alpha`, `beta` > 0 (pixels), skew angle
    /// `theta` in (0, pi) radians (pi/2 for rectangular pixels), finite principal point.
    pub fn new(alpha: f64, beta: f64, theta: f64, u0: f64, v0: f64) -> Result<Self, PoseError> {
        let bad = |reason| {
            Err(PoseError::InvalidIntrinsics {
                alpha,
                beta,
                theta,
                u0,
                v0,
                reason,
            })
        };
        if ![alpha, beta, theta, u0, v0].iter().all(|v| v.is_finite()) {
            return bad("a parameter is not finite");
        }
        if alpha <= 0.0 || beta <= 0.0 {
            return bad("focal scales alpha and beta must be positive");
        }
        // Keep sin(theta) well away from 0 so K stays invertible.
        if !(1e-3..=std::f64::consts::PI - 1e-3).contains(&theta) {
            return bad("skew angle theta must lie in (0, pi)");
        }
        let (s, c) = theta.sin_cos();
        Ok(Self {
            alpha,
            beta,
            theta,
            u0,
            v0,
            k01: -alpha * c / s,
            k11: beta / s,
        })
    }

    /// Rectangular pixels (theta = pi/2): `K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`.
    pub fn square_pixels(fx: f64, fy: f64, cx: f64, cy: f64) -> Result<Self, PoseError> {
        let mut k = Self::new(fx, fy, std::f64::consts::FRAC_PI_2, cx, cy)?;
        k.k01 = 0.0; // exactly, not -fx * cot(pi/2) ~ 1e-16 fx
        k.k11 = fy;
        Ok(k)
    }

    /// Square pixels from a horizontal field of view (radians) and an image size, with the
    /// principal point at the image centre `((w - 1)/2, (h - 1)/2)` (pixel-centre convention).
    /// The focal length is `f = (w/2) / tan(hfov/2)`: the field of view spans the full image
    /// width, from the left edge of the first pixel to the right edge of the last.
    pub fn from_hfov(hfov: f64, width: u32, height: u32) -> Result<Self, PoseError> {
        if !(hfov.is_finite() && hfov > 0.0 && hfov < std::f64::consts::PI)
            || width == 0
            || height == 0
        {
            return Err(PoseError::InvalidFieldOfView {
                hfov,
                width,
                height,
            });
        }
        let f = 0.5 * f64::from(width) / (0.5 * hfov).tan();
        Self::square_pixels(
            f,
            f,
            0.5 * (f64::from(width) - 1.0),
            0.5 * (f64::from(height) - 1.0),
        )
    }

    /// Intrinsics from a 3x3 camera matrix (as stored by OpenCV or ROS): `alpha = K00`,
    /// `u0 = K02`, `v0 = K12`, the skew angle from `K01 = -alpha cot(theta)` and
    /// `beta = K11 sin(theta)`. `K` must be upper triangular with `K22 = 1`.
    pub fn from_matrix(k: &Matrix3<f64>) -> Result<Self, PoseError> {
        let alpha = k[(0, 0)];
        let (u0, v0) = (k[(0, 2)], k[(1, 2)]);
        let lower = [k[(1, 0)], k[(2, 0)], k[(2, 1)]];
        if lower.iter().any(|v| *v != 0.0) || k[(2, 2)] != 1.0 {
            return Err(PoseError::InvalidIntrinsics {
                alpha,
                beta: k[(1, 1)],
                theta: f64::NAN,
                u0,
                v0,
                reason: "camera matrix must be upper triangular with K[2][2] = 1",
            });
        }
        if k[(0, 1)] == 0.0 {
            return Self::square_pixels(alpha, k[(1, 1)], u0, v0);
        }
        // cot(theta) = -K01 / alpha; beta = K11 sin(theta).
        let theta = (alpha).atan2(-k[(0, 1)]);
        let beta = k[(1, 1)] * theta.sin();
        Self::new(alpha, beta, theta, u0, v0)
    }

    /// Focal scale in u (pixels).
    pub fn alpha(&self) -> f64 {
        self.alpha
    }
    /// Focal scale in v (pixels), before the skew correction.
    pub fn beta(&self) -> f64 {
        self.beta
    }
    /// Skew angle in radians (pi/2 for rectangular pixels).
    pub fn theta(&self) -> f64 {
        self.theta
    }
    /// Principal point u (pixels).
    pub fn u0(&self) -> f64 {
        self.u0
    }
    /// Principal point v (pixels).
    pub fn v0(&self) -> f64 {
        self.v0
    }

    /// The camera matrix `K`.
    pub fn matrix(&self) -> Matrix3<f64> {
        Matrix3::new(
            self.alpha, self.k01, self.u0, 0.0, self.k11, self.v0, 0.0, 0.0, 1.0,
        )
    }

    /// Pixel of a normalised image point `(x/z, y/z)`.
    #[inline]
    pub fn normalized_to_pixel(&self, n: &Point2<f64>) -> Point2<f64> {
        Point2::new(
            self.alpha * n.x + self.k01 * n.y + self.u0,
            self.k11 * n.y + self.v0,
        )
    }

    /// Normalised image point `(x/z, y/z)` of a pixel (the inverse of `K`).
    #[inline]
    pub fn pixel_to_normalized(&self, m: &Point2<f64>) -> Point2<f64> {
        let y = (m.y - self.v0) / self.k11;
        Point2::new((m.x - self.u0 - self.k01 * y) / self.alpha, y)
    }

    /// Projects a camera-frame point to a pixel, `m = (1/z) K p`, without lens distortion
    /// ([`Camera::project`] adds it). A point with `z <=` [`MIN_DEPTH`] (on or behind the
    /// camera plane) is an error, never a flipped pixel.
    #[inline]
    pub fn project(&self, p: &Point3<f64>) -> Result<Point2<f64>, PoseError> {
        if p.z.is_nan() || p.z <= MIN_DEPTH {
            return Err(PoseError::PointBehindCamera { index: 0, z: p.z });
        }
        Ok(self.normalized_to_pixel(&Point2::new(p.x / p.z, p.y / p.z)))
    }

    /// The ray through a pixel, as the camera-frame point at depth `z = 1`.
    #[inline]
    pub fn back_project(&self, m: &Point2<f64>) -> Vector3<f64> {
        let n = self.pixel_to_normalized(m);
        Vector3::new(n.x, n.y, 1.0)
    }

    /// The camera-frame point at depth `depth` along the ray through pixel `m`.
    #[inline]
    pub fn back_project_at_depth(&self, m: &Point2<f64>, depth: f64) -> Point3<f64> {
        Point3::from(self.back_project(m) * depth)
    }

    /// The 2x3 Jacobian of [`Intrinsics::project`] with respect to the camera-frame point.
    /// Meaningless (but finite) for `z <= 0`; callers check depth first.
    #[inline]
    pub fn projection_jacobian(&self, p: &Point3<f64>) -> Matrix2x3<f64> {
        let iz = 1.0 / p.z;
        let (x, y) = (p.x * iz, p.y * iz);
        // d(x/z, y/z)/dp = (1/z) [[1, 0, -x], [0, 1, -y]], then the 2x2 upper part of K.
        Matrix2x3::new(
            self.alpha * iz,
            self.k01 * iz,
            -(self.alpha * x + self.k01 * y) * iz,
            0.0,
            self.k11 * iz,
            -self.k11 * y * iz,
        )
    }

    /// Projects a model point through a pose and returns the pixel with its 2x6 Jacobian with
    /// respect to the pose parameters `[wx, wy, wz, tx, ty, tz]`.
    pub fn project_with_pose_jacobian(
        &self,
        pose: &Pose,
        model: &Point3<f64>,
    ) -> Result<(Point2<f64>, SMatrix<f64, 2, 6>), PoseError> {
        let (r, jl) = so3::exp_and_left_jacobian(&pose.rotation);
        let rp = r * model.coords;
        let pc = Point3::from(rp + pose.translation);
        let m = self.project(&pc)?;
        let jp = self.projection_jacobian(&pc);
        let dw = -so3::hat(&rp) * jl;
        let mut j = SMatrix::<f64, 2, 6>::zeros();
        j.fixed_view_mut::<2, 3>(0, 0).copy_from(&(jp * dw));
        j.fixed_view_mut::<2, 3>(0, 3).copy_from(&jp);
        Ok((m, j))
    }
}

/// An OpenGL-style viewing frustum (`glFrustum(left, right, bottom, top, near, far)`) with a
/// `width x height` viewport: the synthetic camera of spec 4.2 (paper eq. 25).
///
/// OpenGL's eye frame has y up and looks down -z; ours (OpenCV's) has y down and z forward, so a
/// camera-frame point `(x, y, z)` is the eye-frame point `(x, -y, -z)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frustum {
    /// Near plane distance (> 0).
    pub near: f64,
    /// Far plane distance (> near).
    pub far: f64,
    /// Left edge of the near-plane window.
    pub left: f64,
    /// Right edge of the near-plane window.
    pub right: f64,
    /// Top edge of the near-plane window.
    pub top: f64,
    /// Bottom edge of the near-plane window.
    pub bottom: f64,
    /// Viewport width in pixels.
    pub width: u32,
    /// Viewport height in pixels.
    pub height: u32,
}

impl Frustum {
    fn check(&self) -> Result<(), PoseError> {
        let bad = |reason| {
            Err(PoseError::InvalidFrustum {
                near: self.near,
                far: self.far,
                left: self.left,
                right: self.right,
                top: self.top,
                bottom: self.bottom,
                width: self.width,
                height: self.height,
                reason,
            })
        };
        if ![
            self.near,
            self.far,
            self.left,
            self.right,
            self.top,
            self.bottom,
        ]
        .iter()
        .all(|v| v.is_finite())
        {
            return bad("a parameter is not finite");
        }
        if !(self.near > 0.0 && self.far > self.near) {
            return bad("need 0 < near < far");
        }
        if !(self.right > self.left && self.top > self.bottom) {
            return bad("need right > left and top > bottom");
        }
        if self.width == 0 || self.height == 0 {
            return bad("empty viewport");
        }
        Ok(())
    }

    /// The equivalent pinhole intrinsics (spec 4.2): `theta = pi/2`,
    /// `alpha = n w / (r - l)`, `beta = n h / (t - b)`, `u0 = -l w / (r - l) - 0.5`,
    /// `v0 = t h / (t - b) - 0.5`.
    pub fn intrinsics(&self) -> Result<Intrinsics, PoseError> {
        self.check()?;
        let (w, h) = (f64::from(self.width), f64::from(self.height));
        let rl = self.right - self.left;
        let tb = self.top - self.bottom;
        Intrinsics::square_pixels(
            self.near * w / rl,
            self.near * h / tb,
            -self.left * w / rl - 0.5,
            self.top * h / tb - 0.5,
        )
    }

    /// The OpenGL projection matrix (as `glFrustum` builds it), acting on eye coordinates.
    pub fn projection_matrix(&self) -> nalgebra::Matrix4<f64> {
        let (n, f, l, r, t, b) = (
            self.near,
            self.far,
            self.left,
            self.right,
            self.top,
            self.bottom,
        );
        nalgebra::Matrix4::new(
            2.0 * n / (r - l),
            0.0,
            (r + l) / (r - l),
            0.0,
            0.0,
            2.0 * n / (t - b),
            (t + b) / (t - b),
            0.0,
            0.0,
            0.0,
            -(f + n) / (f - n),
            -2.0 * f * n / (f - n),
            0.0,
            0.0,
            -1.0,
            0.0,
        )
    }

    /// Projects a camera-frame point (OpenCV axes) the way the OpenGL pipeline does: eye
    /// coordinates, projection matrix, clip, perspective divide to NDC, viewport transform to
    /// window coordinates (origin bottom-left, pixel centres at +0.5), then flipped to our
    /// pixel convention (v down, centres at integers). Returns `None` outside the clip volume.
    pub fn project_gl(&self, p: &Point3<f64>) -> Option<Point2<f64>> {
        let eye = nalgebra::Vector4::new(p.x, -p.y, -p.z, 1.0);
        let clip = self.projection_matrix() * eye;
        if clip.w.is_nan() || clip.w <= 0.0 {
            return None;
        }
        let ndc = clip.xyz() / clip.w;
        if ndc.iter().any(|c| c.abs() > 1.0) {
            return None;
        }
        let (w, h) = (f64::from(self.width), f64::from(self.height));
        let xw = (ndc.x + 1.0) * 0.5 * w;
        let yw = (ndc.y + 1.0) * 0.5 * h;
        Some(Point2::new(xw - 0.5, h - yw - 0.5))
    }
}
