//! What goes into the tracker per frame and what comes out.

use nalgebra::{Matrix3, Vector3};
use serde::Serialize;
use unicycle::{Formation, Inputs};

use crate::mount::CameraMount;

/// What the vision pipeline measured of one robot in one frame.
// Kept unboxed: one measurement per robot per frame, and boxing would allocate for each.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PoseMeasurement {
    /// One pose (e.g. a joint pose over several faces, which has no planar ambiguity).
    Chosen(pose::Estimate),
    /// A single face: both planar candidates, lowest reprojection RMS first.
    Candidates([pose::Estimate; 2]),
    /// A measurement already in formation variables: `y = [l12, alpha12, beta12]` and its
    /// covariance (e.g. a joint pose over several faces, or one refined on the ground
    /// plane). Used as given, unless it carries its fit's residual
    /// ([`FormationMeasurement::fit`]) and the tracker pools the corner noise: then
    /// rescaled to it; the floor is added.
    Formation(FormationMeasurement),
    /// Two candidates already in formation variables (a single face), best first.
    FormationCandidates([FormationMeasurement; 2]),
}

/// Formation variables `[l12, alpha12, beta12]` with their covariance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FormationMeasurement {
    /// `[l12, alpha12, beta12]` (m, rad, rad).
    pub y: Vector3<f64>,
    /// Their covariance.
    pub r: Matrix3<f64>,
    /// When `r` is a pose fit's covariance scaled by the pose solver's one-solve noise
    /// estimate, that fit's residual, so that the tracker can rescale `r` to the corner noise
    /// it pools from the residuals (when [`TrackerConfig::corner_sigma_px`](crate::tracker::TrackerConfig::corner_sigma_px)
    /// is `None`). `None`: `r` is used as given.
    pub fit: Option<FitResidual>,
}

/// The residual of the pose fit behind a [`FormationMeasurement`]'s covariance: `pose`
/// scales the fit's `(J^T J)^-1` by `max(N rms^2 / (2N - parameters), min_pixel_sigma^2)`
/// over `N` = [`Observation::points`] correspondences.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitResidual {
    /// Reprojection RMS of the fit, pixels.
    pub rms_px: f64,
    /// Parameters fitted: 6 for a free pose, 3 for a pose on the ground plane.
    pub parameters: usize,
}

/// One robot seen in one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observation {
    /// The robot's id (from its markers' codes, see [`crate::rig::RigModel::robot_face`]).
    pub robot: u32,
    /// Number of point correspondences of the pose solve (4 per marker face); used to
    /// rescale the covariance to [`TrackerConfig::corner_sigma_px`](crate::tracker::TrackerConfig::corner_sigma_px).
    pub points: usize,
    /// Its pose measurement: rig frame to camera frame, with covariance.
    pub pose: PoseMeasurement,
}

/// Everything the tracker needs about one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameInput {
    /// Frame time, seconds.
    pub t: f64,
    /// The follower's inputs `(v2, w2)` applied since the previous frame.
    pub follower: Inputs,
    /// The camera mount at this frame (its `pan` may change per frame; its `offset` must be
    /// the filter's `d`).
    pub mount: CameraMount,
    /// The robots seen (at most one entry per robot; later duplicates are ignored).
    pub observations: Vec<Observation>,
}

/// A track's status in one frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Status {
    /// A measurement was applied this frame.
    Tracking,
    /// No measurement applied this frame (not seen, gated or invalid); predicted only.
    Coasting,
    /// Dropped this frame (too long without a measurement, or the filter failed); the
    /// values are the last estimate.
    Lost,
}

/// Why a track was dropped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum LostReason {
    /// No accepted measurement for longer than `lost_after`.
    Timeout,
    /// The filter failed (e.g. a coasting prediction reached `l12 <= 0`).
    FilterFailed,
}

/// What happened to a leader's measurement in one frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum MeasurementUse {
    /// A new track was started from it.
    Initialised,
    /// Applied in a filter update.
    Updated,
    /// Rejected by the Mahalanobis gate.
    Gated,
    /// Unusable (non-finite, or the leader on the camera point); skipped.
    Invalid,
    /// The leader was not seen.
    Missing,
}

/// One leader in one frame's output.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LeaderReport {
    /// Robot id.
    pub robot: u32,
    /// Track status.
    pub status: Status,
    /// What happened to this frame's measurement.
    pub measurement: MeasurementUse,
    /// Why the track was dropped (only with status `lost`).
    pub lost: Option<LostReason>,
    /// Hypotheses alive: 2 while a single-face start is being confirmed, else 1.
    pub hypotheses: u8,
    /// Which planar candidate was used (0 = `best`, 1 = the alternative); `None` without
    /// candidates.
    pub candidate: Option<u8>,
    /// Mahalanobis distance squared of the used (or gated) measurement, if any.
    pub nis: Option<f64>,
    /// Estimated formation: separation `l12` (m), bearings `alpha12` in the leader's frame
    /// and `beta12` in the follower's (rad); flat in JSON (`l12`, `alpha12`, `beta12`).
    #[serde(flatten)]
    pub formation: Formation,
    /// Estimated leader speed, m/s.
    pub v1: f64,
    /// Estimated leader turn rate, rad/s.
    pub w1: f64,
    /// Standard deviation of `l12`, m.
    pub l12_std: f64,
    /// Standard deviation of `alpha12`, rad.
    pub alpha12_std: f64,
    /// Standard deviation of `beta12`, rad.
    pub beta12_std: f64,
    /// Standard deviation of `v1`, m/s.
    pub v1_std: f64,
    /// Standard deviation of `w1`, rad/s.
    pub w1_std: f64,
    /// Covariance of `[l12, alpha12, beta12, v1, w1]` (units: products of m, rad, m/s,
    /// rad/s), row by row; its diagonal is the squares of the `*_std` fields. With the IMM
    /// (the default) the formation-velocity terms are its own; with the dual UKF they are
    /// zero (it keeps no cross-covariance between its state and parameter filters).
    pub covariance: [[f64; 5]; 5],
    /// Seconds since the last accepted measurement.
    pub since_seen: f64,
}

/// One frame's output: every leader with a track, sorted by robot id.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FrameReport {
    /// Frame time, seconds.
    pub t: f64,
    /// The leaders.
    pub leaders: Vec<LeaderReport>,
}

/// One hypothesis of one leader, predicted to a coming frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PredictedLeader {
    /// Robot id.
    pub robot: u32,
    /// Predicted `[l12, alpha12, beta12]` (m, rad, rad).
    pub formation: Vector3<f64>,
    /// Their predicted standard deviations (m, rad, rad).
    pub std: Vector3<f64>,
    /// The track was not updated by the last frame (it is coasting).
    pub coasting: bool,
}
