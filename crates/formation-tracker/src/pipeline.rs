//! The per-frame vision pipeline: a grey image in, the tracker's report out.
//!
//! One [`Pipeline`] per camera stream owns every buffer it needs (the detector's, the
//! decoded markers', the observations'), so a steady stream reuses them. Per frame:
//!
//! 1. **Detect** markers with `fiducial::Detector` (dictionary index and corners in the
//!    marker's own order).
//! 2. **Pose** every robot with [`crate::robots::measure_robots`]: markers grouped by robot
//!    through the rig's table, one joint pose per robot, an inconsistent face rejected, the
//!    pose refined on the ground plane and turned into `(l12, alpha12, beta12)` with its
//!    covariance. Those become [`PoseMeasurement::Formation`] observations. A robot seen
//!    through a single face that `measure_robots` marks `ambiguous` is instead given to the
//!    tracker as both planar candidates of `pose` that `measure_robots` computed for that
//!    face ([`PoseMeasurement::Candidates`]), so the tracker's prediction, not the
//!    reprojection RMS, chooses between them.
//! 3. **Track** with [`Tracker::update`].
//!
//! The time spent in each stage is measured with `std::time::Instant` and returned in
//! [`Timing`]; nothing is printed.

use std::time::Instant;

use fiducial::{Decoded, Detector, GrayView};
use nalgebra::{Matrix3, Vector3};
use pose::PoseSolver;
use serde::Serialize;
use unicycle::Inputs;

use crate::mount::CameraMount;
use crate::rig::RigModel;
use crate::robots::{MarkerObservation, RobotConfig, RobotMeasurement, measure_robots};
use crate::tracker::{
    FormationMeasurement, FrameInput, FrameReport, Observation, PoseMeasurement, Tracker,
    TrackerError,
};

/// Errors of one frame of the pipeline.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    /// The frame's size differs from the calibration's.
    #[error("frame is {width}x{height} but the camera calibration is for {cal_width}x{cal_height}")]
    SizeMismatch {
        /// Frame width.
        width: usize,
        /// Frame height.
        height: usize,
        /// Calibrated width.
        cal_width: u32,
        /// Calibrated height.
        cal_height: u32,
    },
    /// The image buffer cannot be viewed as a grey image.
    #[error(transparent)]
    Image(#[from] fiducial::ImageError),
    /// The tracker refused the frame.
    #[error(transparent)]
    Tracker(#[from] TrackerError),
}

/// Milliseconds spent in each stage of one frame.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Timing {
    /// Marker detection and decoding.
    pub detect_ms: f64,
    /// Robot poses and formation variables.
    pub pose_ms: f64,
    /// The tracker's update.
    pub track_ms: f64,
}

impl Timing {
    /// The three stages together.
    pub fn total_ms(&self) -> f64 {
        self.detect_ms + self.pose_ms + self.track_ms
    }
}

/// What one frame produced.
#[derive(Debug, Clone)]
pub struct PipelineFrame {
    /// The tracker's report.
    pub report: FrameReport,
    /// The robots measured in this frame (before tracking).
    pub robots: Vec<RobotMeasurement>,
    /// Markers read.
    pub markers: usize,
    /// Robots whose markers were read but whose pose failed, as messages.
    pub failures: Vec<String>,
    /// Stage times.
    pub timing: Timing,
}

/// Detector, pose solver, rig and tracker for one camera stream.
#[derive(Debug)]
pub struct Pipeline {
    detector: Detector,
    solver: PoseSolver,
    size: (u32, u32),
    rig: RigModel,
    robot_config: RobotConfig,
    tracker: Tracker,
    decoded: Vec<Decoded>,
    markers: Vec<MarkerObservation>,
}

impl Pipeline {
    /// A pipeline for frames of `size` (the calibration's) through `solver`.
    pub fn new(
        detector: Detector,
        solver: PoseSolver,
        size: (u32, u32),
        rig: RigModel,
        robot_config: RobotConfig,
        tracker: Tracker,
    ) -> Self {
        Self {
            detector,
            solver,
            size,
            rig,
            robot_config,
            tracker,
            decoded: Vec::new(),
            markers: Vec::new(),
        }
    }

    /// The markers read in the last frame.
    pub fn markers(&self) -> &[MarkerObservation] {
        &self.markers
    }

    /// The tracker (e.g. for its configuration).
    pub fn tracker(&self) -> &Tracker {
        &self.tracker
    }

    /// Processes one frame taken at `t` with the follower's inputs over the interval ending
    /// at it and the camera mount at that instant.
    ///
    /// # Errors
    /// A frame of the wrong size or a frame the tracker refuses (see [`TrackerError`]); the
    /// tracker is then unchanged.
    pub fn process(
        &mut self,
        data: &[u8],
        width: usize,
        height: usize,
        t: f64,
        follower: Inputs,
        mount: CameraMount,
    ) -> Result<PipelineFrame, PipelineError> {
        if (width, height) != (self.size.0 as usize, self.size.1 as usize) {
            return Err(PipelineError::SizeMismatch {
                width,
                height,
                cal_width: self.size.0,
                cal_height: self.size.1,
            });
        }
        let view = GrayView::new(data, width, height)?;
        let start = Instant::now();
        self.detector.detect(&view, &mut self.decoded);
        self.markers.clear();
        self.markers
            .extend(self.decoded.iter().map(|d| MarkerObservation {
                index: d.index,
                corners: d.corners,
            }));
        let detected = Instant::now();
        let found = measure_robots(
            &self.markers,
            &self.rig,
            &self.solver,
            &mount,
            &self.robot_config,
        );
        let observations: Vec<Observation> = found.robots.iter().map(observation).collect();
        let posed = Instant::now();
        let report = self.tracker.update(&FrameInput {
            t,
            follower,
            mount,
            observations,
        })?;
        let tracked = Instant::now();
        let ms = |a: Instant, b: Instant| (b - a).as_secs_f64() * 1e3;
        Ok(PipelineFrame {
            report,
            markers: self.markers.len(),
            failures: found.failures.iter().map(ToString::to_string).collect(),
            robots: found.robots,
            timing: Timing {
                detect_ms: ms(start, detected),
                pose_ms: ms(detected, posed),
                track_ms: ms(posed, tracked),
            },
        })
    }
}

/// The tracker's observation of one measured robot (see the module documentation).
fn observation(m: &RobotMeasurement) -> Observation {
    match m.candidates {
        Some(candidates) if m.ambiguous && m.faces.len() == 1 => Observation {
            robot: m.robot,
            points: 4,
            pose: PoseMeasurement::Candidates(candidates),
        },
        _ => Observation {
            robot: m.robot,
            points: 4 * m.faces.len(),
            pose: PoseMeasurement::Formation(FormationMeasurement {
                y: Vector3::new(m.l12, m.alpha12, m.beta12),
                r: Matrix3::from_fn(|i, j| m.covariance[i][j]),
            }),
        },
    }
}
