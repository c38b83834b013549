//! The crate's one error type.

use crate::Pose;

/// Everything that can go wrong in this crate. Struct variants carry the offending values so a
/// caller can report them or recover.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum PoseError {
    /// The intrinsics do not describe an invertible camera.
    #[error(
        "singular or invalid intrinsics: {reason} (alpha {alpha}, beta {beta}, skew angle {theta} rad, u0 {u0}, v0 {v0})"
    )]
    InvalidIntrinsics {
        /// Focal scale in u (pixels).
        alpha: f64,
        /// Focal scale in v (pixels).
        beta: f64,
        /// Skew angle in radians (pi/2 for square pixels).
        theta: f64,
        /// Principal point u.
        u0: f64,
        /// Principal point v.
        v0: f64,
        /// Which condition failed.
        reason: &'static str,
    },
    /// An OpenGL frustum that cannot be converted (zero width/height, non-positive near plane).
    #[error(
        "invalid frustum: {reason} (near {near}, far {far}, left {left}, right {right}, top {top}, bottom {bottom}, viewport {width}x{height})"
    )]
    InvalidFrustum {
        /// Near plane distance.
        near: f64,
        /// Far plane distance.
        far: f64,
        /// Left edge at the near plane.
        left: f64,
        /// Right edge at the near plane.
        right: f64,
        /// Top edge at the near plane.
        top: f64,
        /// Bottom edge at the near plane.
        bottom: f64,
        /// Viewport width in pixels.
        width: u32,
        /// Viewport height in pixels.
        height: u32,
        /// Which condition failed.
        reason: &'static str,
    },
    /// A horizontal field of view outside (0, pi) or an empty image.
    #[error(
        "invalid field of view {hfov} rad for a {width}x{height} image (need 0 < hfov < pi and a non-empty image)"
    )]
    InvalidFieldOfView {
        /// Horizontal field of view in radians.
        hfov: f64,
        /// Image width.
        width: u32,
        /// Image height.
        height: u32,
    },
    /// A distortion coefficient vector has a length its model does not take.
    #[error("{model} distortion needs {accepted} coefficients; got {count}")]
    DistortionCount {
        /// The model (`plumb_bob`, `rational_polynomial`, `equidistant`, or `OpenCV` for an
        /// OpenCV vector whose model follows from its length).
        model: &'static str,
        /// Values given.
        count: usize,
        /// What the model accepts.
        accepted: &'static str,
    },
    /// One of OpenCV's thin-prism (`s1..s4`, coefficients 8-11) or tilt (`tauX, tauY`,
    /// 12-13) terms is not zero: those models are not supported.
    #[error(
        "distortion coefficient {index} is {value}: the thin-prism (s1..s4) and tilted-sensor (tauX, tauY) terms are not supported, coefficients 8 and beyond must be zero (plumb_bob takes k1, k2, p1, p2[, k3], rational_polynomial k1, k2, p1, p2, k3, k4, k5, k6)"
    )]
    UnsupportedDistortion {
        /// Position in the coefficient vector (0-based).
        index: usize,
        /// Its value.
        value: f64,
    },
    /// A distortion model name that is not one of ours.
    #[error(
        "unknown distortion model `{name}`: use plumb_bob, rational_polynomial or equidistant (fisheye)"
    )]
    UnknownDistortionModel {
        /// The name given.
        name: String,
    },
    /// A fisheye point whose ray is 90 degrees or more off the optical axis: it has no
    /// pinhole (normalised) image, so no pose can use it.
    #[error(
        "distorted normalised point ({x}, {y}) is a ray {angle} rad off the optical axis (90 degrees or more): it has no pinhole image"
    )]
    BeyondPinholeView {
        /// Distorted normalised x.
        x: f64,
        /// Distorted normalised y.
        y: f64,
        /// The ray's angle from the optical axis, radians.
        angle: f64,
    },
    /// A distortion coefficient is NaN or infinite.
    #[error("distortion coefficient {name} is not finite ({value})")]
    InvalidDistortion {
        /// Coefficient name (k1..k6, p1, p2).
        name: &'static str,
        /// Its value.
        value: f64,
    },
    /// Iterative undistortion of a point did not converge (the point is probably outside the
    /// region where the distortion model is invertible).
    #[error(
        "undistortion of normalised point ({x}, {y}) did not converge after {iterations} iterations (residual {residual:e})"
    )]
    UndistortionNotConverged {
        /// Distorted normalised x.
        x: f64,
        /// Distorted normalised y.
        y: f64,
        /// Iterations run.
        iterations: usize,
        /// Final residual in normalised units.
        residual: f64,
    },
    /// A marker size that is not positive and finite.
    #[error(
        "invalid marker size {width} x {height} m (need positive, finite side lengths in metres)"
    )]
    InvalidMarkerSize {
        /// Width, metres.
        width: f64,
        /// Height, metres.
        height: f64,
    },
    /// A point lies on or behind the camera plane (z <= 0 in the camera frame).
    #[error("point {index} is behind the camera (camera-frame z = {z})")]
    PointBehindCamera {
        /// Index of the point in the input slice (0 when a single point was given).
        index: usize,
        /// Its camera-frame depth.
        z: f64,
    },
    /// Fewer correspondences than the solver needs.
    #[error("need at least {needed} point correspondences, got {got}")]
    TooFewPoints {
        /// Minimum number of points.
        needed: usize,
        /// Number given.
        got: usize,
    },
    /// Model and image point slices differ in length.
    #[error("{model} model points but {image} image points")]
    LengthMismatch {
        /// Model point count.
        model: usize,
        /// Image point count.
        image: usize,
    },
    /// A NaN or infinite coordinate in the input.
    #[error("non-finite {which} point at index {index}")]
    NonFinite {
        /// "model", "image" or "initial pose".
        which: &'static str,
        /// Index of the offending point (0 for a pose).
        index: usize,
    },
    /// Two model points coincide, so they carry no independent information.
    #[error("model points {first} and {second} coincide")]
    CoincidentPoints {
        /// First index.
        first: usize,
        /// Second index.
        second: usize,
    },
    /// All model points lie on one line: the pose is not determined.
    #[error(
        "model points are collinear (spread across the line {ratio:e} of the spread along it): the pose is not determined"
    )]
    CollinearPoints {
        /// Ratio of the second to the first principal extent.
        ratio: f64,
    },
    /// The normal equations became singular: the geometry does not determine the pose.
    #[error("degenerate geometry: {reason}")]
    Degenerate {
        /// What was singular.
        reason: &'static str,
    },
    /// An iterative solver ran out of iterations. The last estimate is kept so the caller can
    /// still use (or reject) it.
    #[error("solver did not converge after {iterations} iterations")]
    NotConverged {
        /// Iterations run.
        iterations: usize,
        /// The last estimate.
        estimate: Pose,
    },
    /// A solver setting is negative, NaN or infinite.
    #[error("invalid solver option {name} = {value} (must be finite and non-negative)")]
    InvalidOptions {
        /// The option.
        name: &'static str,
        /// Its value.
        value: f64,
    },
    /// A calibration file could not be read or parsed.
    #[cfg(feature = "calib")]
    #[error(transparent)]
    Camera(#[from] crate::calib::CalibrationError),
}
