//! The per-frame vision pipeline: a grey image in, the tracker's report out.
//!
//! One [`Pipeline`] per camera stream owns every buffer it needs (the detector's, the
//! decoded markers', the observations'), so a steady stream reuses them. Per frame:
//!
//! 1. **Detect** markers with `fiducial::Detector` (dictionary index and corners in the
//!    marker's own order): on the whole frame, or, in guided mode
//!    ([`Pipeline::set_guided`], [`crate::guided`]), only in the regions where the tracker
//!    predicts its leaders, with a full-frame scan every `full_scan_period` frames and
//!    whenever a track coasts. [`PipelineFrame::scan`] says which.
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

use fiducial::{Decoded, Detector, GrayView, Region, Search};
use nalgebra::Matrix3;
use pose::PoseSolver;
use serde::Serialize;
use unicycle::Inputs;

use crate::guided::{GuidedConfig, GuidedError, leader_region};
use crate::mount::CameraMount;
use crate::rig::{Face, RigModel};
use crate::robots::{MarkerObservation, RobotConfig, RobotMeasurement, measure_robots};
use crate::tracker::{
    FitResidual, FormationMeasurement, FrameInput, FrameReport, Observation, PoseMeasurement,
    Tracker, TrackerError,
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
    /// A guided-mode setting is out of range.
    #[error(transparent)]
    Guided(#[from] GuidedError),
    /// The rig's faces cannot be built (guided mode projects them).
    #[error(transparent)]
    Rig(#[from] crate::rig::RigError),
}

/// How a frame was searched for markers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(tag = "mode", rename_all = "snake_case")]
pub enum Scan {
    /// The whole frame, at `1 / factor` of the resolution for finding quads (corners are
    /// always refined at full resolution; factor 1 is a plain full scan). Above factor 1
    /// (guided mode's periodic scan), the tracked leaders' faces too narrow for that scale
    /// are searched at full resolution as well.
    Full {
        /// Decimation factor of the quad search (1 = full resolution).
        factor: usize,
    },
    /// Only the predicted regions of the tracked leaders (guided mode).
    Guided {
        /// Decimation factor of the quad search in the regions (1 = full resolution).
        factor: usize,
        /// Regions searched (before overlapping ones are merged), the leaders' and the boxes
        /// of narrow faces searched at full resolution besides them
        /// ([`crate::guided::LeaderRegion::fine_regions`]).
        regions: usize,
        /// Pixels in those regions, summed.
        pixels: usize,
    },
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
    /// How the frame was searched for markers.
    pub scan: Scan,
}

/// Guided mode's settings and state.
#[derive(Debug, Clone)]
struct Guided {
    config: GuidedConfig,
    faces: Vec<Face>,
    /// Frames since the last full scan.
    since_full: u32,
    regions: Vec<Region>,
    /// The leaders' predictions of the current frame (reused).
    leaders: Vec<crate::guided::LeaderRegion>,
    /// Narrow faces' boxes searched at full resolution besides coarse regions.
    fine: Vec<Region>,
}

impl Guided {
    /// Adds to `out` the markers of the tracked leaders' faces too narrow for a search at
    /// `factor` ([`crate::guided::LeaderRegion::fine_regions`]), searched in their boxes at
    /// full resolution; the boxes are kept in `fine`.
    fn search_narrow_faces(
        &mut self,
        factor: usize,
        detector: &mut Detector,
        view: &GrayView<'_>,
        out: &mut Vec<Decoded>,
    ) {
        for r in &self.leaders {
            self.fine.extend(r.fine_regions(factor));
        }
        if !self.fine.is_empty() {
            detector.detect_with(view, &Search::in_regions(&self.fine).appending(), out);
        }
    }
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
    guided: Option<Guided>,
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
            guided: None,
        }
    }

    /// Turns tracking-guided detection on (`Some`) or off (`None`, the default: every frame
    /// is scanned whole). See [`crate::guided`].
    ///
    /// # Errors
    /// A setting out of range, or a rig whose faces cannot be built; the pipeline is then
    /// unchanged.
    pub fn set_guided(&mut self, config: Option<GuidedConfig>) -> Result<(), PipelineError> {
        self.guided = match config {
            None => None,
            Some(config) => {
                config.validate()?;
                Some(Guided {
                    config,
                    faces: self.rig.face_geometries()?,
                    since_full: 0,
                    regions: Vec::new(),
                    leaders: Vec::new(),
                    fine: Vec::new(),
                })
            }
        };
        Ok(())
    }

    /// The guided-mode settings, if guided mode is on.
    pub fn guided(&self) -> Option<&GuidedConfig> {
        self.guided.as_ref().map(|g| &g.config)
    }

    /// Detects the markers of `view` into `self.decoded`, on the whole frame or in the
    /// predicted regions (see [`crate::guided`]).
    fn detect(
        &mut self,
        view: &GrayView<'_>,
        t: f64,
        follower: Inputs,
        mount: &CameraMount,
    ) -> Scan {
        let Some(g) = self.guided.as_mut() else {
            self.detector.detect(view, &mut self.decoded);
            return Scan::Full { factor: 1 };
        };
        let size = (view.width(), view.height());
        let predictions = self.tracker.predict(t, follower);
        let periodic = g.since_full + 1 >= g.config.full_scan_period;
        let mut lost_sight = predictions.is_empty() || predictions.iter().any(|p| p.coasting);
        g.regions.clear();
        g.leaders.clear();
        g.fine.clear();
        let mut region_factor = 4;
        if !lost_sight {
            let camera = self.solver.intrinsics();
            for p in &predictions {
                match leader_region(p, &g.faces, mount, camera, size, &g.config) {
                    Some(r) => {
                        region_factor = region_factor.min(r.factor(&g.config));
                        g.regions.push(r.region);
                        g.leaders.push(r);
                    }
                    None => {
                        lost_sight = true;
                        break;
                    }
                }
            }
        }
        if periodic || lost_sight {
            g.since_full = 0;
            // A leader not seen where predicted is looked for at full resolution.
            let factor = if lost_sight {
                1
            } else {
                g.config.coarse_factor_for(size.0)
            };
            if factor > 1 {
                self.detector.detect_with(
                    view,
                    &Search::whole_frame().at_scale(factor),
                    &mut self.decoded,
                );
                g.search_narrow_faces(factor, &mut self.detector, view, &mut self.decoded);
            } else {
                self.detector.detect(view, &mut self.decoded);
            }
            return Scan::Full { factor };
        }
        g.since_full += 1;
        self.detector.detect_with(
            view,
            &Search::in_regions(&g.regions).at_scale(region_factor),
            &mut self.decoded,
        );
        g.search_narrow_faces(region_factor, &mut self.detector, view, &mut self.decoded);
        Scan::Guided {
            factor: region_factor,
            regions: g.regions.len() + g.fine.len(),
            pixels: g.regions.iter().chain(&g.fine).map(Region::area).sum(),
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

    /// The tracker, to tell it what changes between frames (the follower's set-points).
    pub fn tracker_mut(&mut self) -> &mut Tracker {
        &mut self.tracker
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
        let scan = self.detect(&view, t, follower, &mount);
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
            scan,
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
                y: m.formation.to_vector(),
                r: Matrix3::from_fn(|i, j| m.covariance[i][j]),
                fit: Some(FitResidual {
                    rms_px: m.reprojection_rms_px,
                    parameters: if m.ground_plane { 3 } else { 6 },
                }),
            }),
        },
    }
}
