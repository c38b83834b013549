//! Camera models and 6-DOF pose from 2D-3D correspondences: pinhole intrinsics with skew, the
//! OpenGL frustum of the synthetic camera, lens distortion (OpenCV's and ROS's `plumb_bob`,
//! `rational_polynomial` and fisheye `equidistant` models), rotations by the
//! exponential map, POSIT, IPPE and Levenberg-Marquardt (spec sections 2.1 and 4).
//!
//! # Design
//!
//! **One parameterisation everywhere.** A pose is the rotation vector and translation
//! `[wx, wy, wz, tx, ty, tz]` of the paper (eqs. 23-24), mapping model (rig) points into the
//! camera frame (OpenCV axes: x right, y down, z forward). The solver optimises exactly these
//! six numbers, so the covariance it reports is the covariance of the parameters a filter
//! downstream consumes, not of some internal increment. The exponential map is made safe at
//! angle 0 (Taylor series) and near pi (axis from the symmetric part), see [`so3`].
//!
//! **Two initialisers, one refiner.** Four or more non-coplanar points (two or more octagon
//! faces) start from POSIT, as the paper does. One face is planar, and a plane has two
//! reprojection minima that trade places under noise (the "pose flip"); so coplanar points go
//! through IPPE, which yields *both* candidates in closed form, and both are refined. The
//! result keeps the better one and reports the other with its reprojection error
//! ([`PoseSolution::alternative`], [`PoseSolution::ambiguity_ratio`]), and
//! [`PoseSolver::planar_candidates`] hands both to a tracker that can choose by consistency
//! with its prediction. [`PoseSolver::refine`] starts from a caller's pose instead.
//!
//! **A body on a known plane** has three free parameters, not six:
//! [`PoseSolver::refine_on_plane`] fits `(x, y, yaw)` in the plane's frame given the plane's
//! pose in the camera frame ([`plane`]), with the same Levenberg-Marquardt loop and an
//! analytic Jacobian.
//!
//! **Fast and allocation-free.** The solver never forms the 2N x 6 Jacobian: each point adds its
//! block to `J^T J` and `J^T e` directly, POSIT keeps no per-point state, the homography's
//! normal equations are 8x8 and static, and undistorted points live in a stack buffer for up to
//! 32 points. A 4-point solve with both candidates refined takes a few microseconds (criterion
//! benchmarks `pose/one_face_4pts`, `pose/three_faces_12pts_lm`).
//!
//! **Bad input is typed.** Too few points, mismatched lengths, coincident or collinear model
//! points, points behind the camera, non-finite numbers, singular intrinsics, undistortion that
//! does not converge and an LM solve that runs out of iterations each have a [`PoseError`]
//! variant; the last carries the estimate reached (`NotConverged { iterations, estimate }`).
//!
//! **One marker** ([`marker`]): [`PoseSolver::solve_square_marker`] gives what OpenCV's
//! `solvePnP(..., SOLVEPNP_IPPE_SQUARE)` gives, in OpenCV's marker frame and corner order,
//! with both candidates and the covariance.
//!
//! **Camera files** (feature `calib`, on by default; pure Rust via `serde-saphyr`): OpenCV
//! `FileStorage` YAML and ROS `camera_info` YAML, see [`calib`].
//!
//! # Example
//!
//! ```
//! use nalgebra::{Point3, Vector3};
//! use pose::{Intrinsics, Pose, PoseSolver};
//!
//! let k = Intrinsics::from_hfov(60f64.to_radians(), 640, 480)?;
//! // One 140 mm x 120 mm marker face, corners in the face frame (metres).
//! let model = [
//!     Point3::new(-0.07, -0.06, 0.0),
//!     Point3::new(0.07, -0.06, 0.0),
//!     Point3::new(0.07, 0.06, 0.0),
//!     Point3::new(-0.07, 0.06, 0.0),
//! ];
//! let truth = Pose::new(Vector3::new(0.1, 0.5, 0.05), Vector3::new(0.1, -0.05, 1.0));
//! let image: Vec<_> = model.iter().map(|p| k.project(&truth.transform_point(p))).collect::<Result<_, _>>()?;
//! let solution = PoseSolver::new(k).solve(&model, &image)?;
//! assert!(solution.pose().rotation_angle_to(&truth) < 1e-6);
//! # Ok::<(), pose::PoseError>(())
//! ```
#![deny(missing_docs)]

/// This crate's version (`CARGO_PKG_VERSION`), for tools that report what they were built from.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");

#[cfg(feature = "calib")]
pub mod calib;
mod camera;
mod distortion;
mod error;
pub mod faces;
mod ippe;
mod ldl;
mod lm;
pub mod marker;
mod noise;
pub mod plane;
mod posit;
pub mod so3;
mod solve;

pub use camera::{Camera, Frustum, Intrinsics, MIN_DEPTH};
pub use distortion::{Distortion, DistortionModel, UNDISTORT_MAX_ITERATIONS, UNDISTORT_TOLERANCE};
pub use error::PoseError;
pub use lm::LmConfig;
pub use marker::{MarkerPose, marker_corners};
pub use noise::{ResidualPool, rescale_factor};
pub use plane::{PlanarEstimate, PlaneFrame};
pub use posit::{POSIT_MAX_ITERATIONS, POSIT_TOLERANCE, posit};
pub use so3::Pose;
pub use solve::{Estimate, PoseSolution, PoseSolver, SolverOptions};

/// The types most callers need.
pub mod prelude {
    pub use crate::{
        Distortion, DistortionModel, Estimate, Frustum, Intrinsics, MarkerPose, Pose, PoseError,
        PoseSolution, PoseSolver, SolverOptions,
    };
}
