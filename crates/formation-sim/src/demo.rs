//! The end-to-end demo: the reference scenario (`docs/reference-scenario.md`) with the
//! synthetic camera in the loop.
//!
//! Every step, each follower's camera frame is rendered by `synthcam` (640x480, 60 degrees,
//! sensor noise and blur on), then goes through the same [`Pipeline`] as `track` (detect,
//! pose, track). The leader (robot 1) drives the reference inputs
//! `v1 = 0.8 + 0.2 sin(0.5 t)`, `w1 = 0.2 sin(0.4 t)`; robot `j + 1` follows robot `j` with
//! the separation-bearing controller of the reference scenario, holding its initial
//! `l12` and `alpha12`. Robots start on a line: robot `i` of `N` at
//! `((N - i) 1.5, (N - i) 0.25, 0)`, so with two robots this is exactly the reference
//! scenario. Both robots are integrated exactly.
//!
//! - **Occlusion**: during [`DemoConfig::occlusion`] (default 3.5 s to 4.5 s) robot 1 is
//!   left out of robot 2's camera frame (the frame is still rendered and processed), so
//!   robot 2's track of it coasts and must be re-acquired under the same id.
//! - **Open loop** (default): each follower's controller uses the *true* formation
//!   variables and the true leader inputs, as in the reference scenario, so the run is
//!   comparable with the dual-UKF reproduction. **Closed loop**: it uses its tracker's
//!   estimate of its leader (formation variables and leader velocities), holding its last
//!   inputs when it has no estimate.
//!
//! Figures of merit are computed for robot 2's track of robot 1 (the reference pair); every
//! follower's trace is returned.
//!
//! **Scenario files** ([`DemoConfig::from_scenario`], `demo --scenario FILE`): the file of
//! `reproduce dukf --scenario` (see [`crate::scenario_file`]) gives the two robots' start,
//! the leader's inputs, the follower's set-point changes, the frame rate and duration, and
//! in its `vision` section the camera (size, field of view, mount), the rendering (noise,
//! blur, motion blur, lighting gradient) and the occlusion. **Motion blur**: a frame at time
//! `t` with exposure `e` averages the radiance of `n` (odd) sub-frames at
//! `t + e ((i + 1/2) / n - 1/2)`, the robots placed by integrating their inputs exactly
//! (before `t` the inputs of the interval ending at `t`; after it, the same inputs held), then
//! blurs and adds noise once; the truth is at `t` (the middle sub-frame).

use std::time::Instant;

use fiducial::{Detector, DetectorConfig, Dictionary};
use nalgebra::Vector3;
use serde::Serialize;
use unicycle::{
    Actuation, ControllerConfig, Formation, Inputs, PlanarPose, SeparationBearingController,
    UnicycleError,
};

use crate::annotate::{AnnotateError, MarkerLabel, RigOverlay, annotate};
use crate::reproduce::{MeanSquareErrors, MseSummary, StepRecord};
use crate::scenario::{actuation_rng, follower_motion, reference_leader_inputs};
use crate::scenario_file::{GradientSpec, MotionBlurSpec, ScenarioSpec};
use crate::scene::{self, CameraSpec, RenderSpec, RobotSpec, SceneError, SceneSpec};
use formation_tracker::guided::GuidedConfig;
use formation_tracker::mount::CameraMount;
use formation_tracker::pipeline::{Pipeline, PipelineError, Scan, Timing};
use formation_tracker::rig::RigModel;
use formation_tracker::robots::RobotConfig;
use formation_tracker::tracker::{MeasurementUse, Status, Tracker, TrackerConfig, TrackerError};

/// Errors of the demo.
#[derive(Debug, thiserror::Error)]
pub enum DemoError {
    /// A setting is out of range.
    #[error("demo: {what} = {value} is out of range ({expected})")]
    Config {
        /// Which setting.
        what: &'static str,
        /// Its value.
        value: f64,
        /// The range.
        expected: &'static str,
    },
    /// The robot model or the controller failed.
    #[error(transparent)]
    Model(#[from] UnicycleError),
    /// A scene could not be built or rendered.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// A frame could not be processed.
    #[error(transparent)]
    Pipeline(#[from] PipelineError),
    /// The tracker configuration was refused.
    #[error(transparent)]
    Tracker(#[from] TrackerError),
    /// A frame could not be annotated.
    #[error(transparent)]
    Annotate(#[from] AnnotateError),
    /// The camera model could not be built.
    #[error(transparent)]
    Pose(#[from] pose::PoseError),
    /// The scenario's vision settings are out of range.
    #[error(transparent)]
    Scenario(crate::scenario_file::ScenarioFileError),
    /// The caller asked the run to stop ([`run_demo_until`]) before step `step`.
    #[error("demo: stopped before step {step} of {steps}")]
    Stopped {
        /// The first step not run.
        step: usize,
        /// The run's last step.
        steps: usize,
    },
}

/// Settings of the demo. [`DemoConfig::default`] is the documented demo.
#[derive(Debug, Clone, PartialEq)]
pub struct DemoConfig {
    /// Number of robots in the chain (>= 2; robot 1 leads).
    pub robots: usize,
    /// Followers steer on their trackers' estimates instead of the truth.
    pub closed_loop: bool,
    /// Duration, seconds (8).
    pub duration: f64,
    /// Time step = frame period, seconds (1/30).
    pub dt: f64,
    /// Interval during which robot 1 is hidden from robot 2's camera, seconds.
    pub occlusion: Option<(f64, f64)>,
    /// Rendering: 4 x 4 samples per pixel, noise sigma 3 grey levels, blur sigma 1 px;
    /// `seed` seeds the noise (frame `k` uses `seed + k`).
    pub render: RenderSpec,
    /// Annotated frames kept for the strip: every this many steps (30: one a second).
    pub strip_every: usize,
    /// Image size and field of view (640 x 480, 60 degrees).
    pub camera: CameraSpec,
    /// The camera mount of every follower (0.5 m ahead, 0.30 m high, level); its offset is
    /// the filter's `d`.
    pub mount: CameraMount,
    /// Motion blur (none).
    pub motion_blur: Option<MotionBlurSpec>,
    /// Lighting gradient across the image (none).
    pub gradient: Option<GradientSpec>,
    /// The scenario the robots drive (start, leader inputs, set-point changes); `None`: the
    /// reference inputs from the starting line (see the module documentation). Only with two
    /// robots.
    pub scenario: Option<ScenarioSpec>,
    /// Tracking-guided detection in every follower's pipeline (default `None`: every frame
    /// is scanned whole); see `formation_tracker::guided`.
    pub guided: Option<GuidedConfig>,
}

impl DemoConfig {
    /// The demo of a scenario file: two robots, open loop, the file's start, leader inputs,
    /// set-points, frame rate, duration, camera offset and `vision` section, a strip frame a
    /// second and noise seed 1. The reference scenario's file gives exactly
    /// [`DemoConfig::default`]'s run.
    pub fn from_scenario(spec: &ScenarioSpec) -> Self {
        let v = &spec.vision;
        Self {
            robots: 2,
            closed_loop: false,
            duration: spec.duration,
            dt: 1.0 / spec.frame_rate,
            occlusion: v.occlusions.first().map(|o| (o.from, o.to)),
            render: RenderSpec {
                supersampling: v.render.supersampling,
                noise_sigma: v.render.noise_sigma,
                blur_sigma: v.render.blur_sigma,
                seed: 1,
            },
            strip_every: (spec.frame_rate.round() as usize).max(1),
            camera: v.camera,
            mount: CameraMount {
                offset: spec.camera_offset,
                height: v.mount.height,
                pan: v.mount.pan,
                tilt: v.mount.tilt,
            },
            motion_blur: v.render.motion_blur,
            gradient: v.render.gradient,
            scenario: Some(spec.clone()),
            guided: None,
        }
    }
}

impl DemoConfig {
    /// Whether robot 1 is hidden from robot 2's camera at `t` (the occlusion interval,
    /// closed at its start, open at its end).
    pub(crate) fn occluded_at(&self, t: f64) -> bool {
        self.occlusion
            .is_some_and(|(a, b)| t >= a - 1e-9 && t < b - 1e-9)
    }
}

impl Default for DemoConfig {
    fn default() -> Self {
        Self {
            robots: 2,
            closed_loop: false,
            duration: 8.0,
            dt: 1.0 / 30.0,
            occlusion: Some((3.5, 4.5)),
            render: RenderSpec {
                supersampling: 4,
                noise_sigma: 3.0,
                blur_sigma: 1.0,
                seed: 1,
            },
            strip_every: 30,
            camera: CameraSpec::default(),
            mount: CameraMount::default(),
            motion_blur: None,
            gradient: None,
            scenario: None,
            guided: None,
        }
    }
}

/// One follower's frame of the demo.
#[derive(Debug, Clone, PartialEq)]
pub struct DemoRecord {
    /// Truth, vision measurement (NaN when the leader was not measured) and the tracker's
    /// estimate (NaN when it has no track of the leader) of the follower's leader.
    pub step: StepRecord,
    /// The leader track's status, if there is a track.
    pub status: Option<Status>,
    /// What the tracker did with the leader's measurement.
    pub measurement: Option<MeasurementUse>,
    /// Markers read in the frame.
    pub markers: usize,
    /// Leaders tracked in the frame (all robots in view).
    pub leaders: usize,
    /// Whether the frame was inside the occlusion.
    pub occluded: bool,
    /// Stage times of the pipeline.
    pub timing: Timing,
    /// How the frame was searched (whole, or the predicted regions in guided mode).
    pub scan: Scan,
    /// Desired separation of the follower's controller, m.
    pub l12_desired: f64,
    /// Normalised innovation squared of the leader's measurement when the tracker used it
    /// (or gated it): `nu^T S^-1 nu` over `(l12, alpha12, beta12)`, see
    /// [`formation_tracker::tracker::LeaderReport::nis`].
    pub nis: Option<f64>,
}

/// One follower's whole run.
#[derive(Debug, Clone, PartialEq)]
pub struct FollowerTrace {
    /// The follower's robot number.
    pub follower: u32,
    /// Its leader's robot number.
    pub leader: u32,
    /// One record per step from `t = dt` (the frame at `t = 0` only starts the track).
    pub records: Vec<DemoRecord>,
}

/// How one follower tracked the robot ahead of it (every pair of a chain).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PairSummary {
    /// The follower (whose camera and tracker these are).
    pub follower: u32,
    /// The robot it tracks.
    pub leader: u32,
    /// Mean square errors of the tracked `[l12, alpha12, beta12, v1, w1]` over the scored
    /// frames (m^2, rad^2, rad^2, (m/s)^2, (rad/s)^2).
    pub mse: [f64; 5],
    /// Mean square errors of the vision measurement of `[l12, alpha12, beta12]` over the
    /// frames with one.
    pub mse_meas: [f64; 3],
    /// Scored frames (after `t = 0`).
    pub frames_scored: usize,
    /// Scored frames in which the leader was measured.
    pub frames_detected: usize,
    /// Scored frames in which the track was coasting.
    pub frames_coasting: usize,
    /// Mean square errors of the tracked `[l12, alpha12, beta12, v1, w1]` over the scored
    /// frames in which the leader was measured (the frames of `mse_meas`), same units.
    pub mse_detected: [f64; 5],
    /// Mean square errors of the tracked `[l12, alpha12, beta12, v1, w1]` over the coasting
    /// frames (NaN when none).
    pub mse_coasting: [f64; 5],
    /// RMS error of the tracked `[v1, w1]` after `t = 2 s` (m/s, rad/s).
    pub rms_velocity_after_2s: [f64; 2],
    /// Consistency of the measurements with the track (NIS, 3 degrees of freedom).
    pub nis: NisSummary,
}

/// The normalised innovation squared (NIS) of the measurements a track used, against its
/// chi-square distribution with 3 degrees of freedom (`l12`, `alpha12`, `beta12`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct NisSummary {
    /// Frames whose measurement was used (updated).
    pub frames: usize,
    /// Mean NIS over those frames (3 for a consistent filter).
    pub mean: f64,
    /// The two-sided 95 % interval of the mean of `frames` independent chi-square(3) values:
    /// `[chi2(0.025, 3 n) / n, chi2(0.975, 3 n) / n]`; a consistent filter's `mean` lies in it.
    pub mean_bounds_95: [f64; 2],
    /// Fraction of the frames whose NIS lies in the per-frame two-sided 95 % interval of a
    /// chi-square(3), [0.216, 9.348] (0.95 for a consistent filter).
    pub inside_95: f64,
}

/// The `p` quantile of a chi-square distribution with `k` degrees of freedom, by the
/// Wilson-Hilferty approximation (within 0.5 % for `k >= 3` at these tails); `z` is the
/// standard normal quantile of `p`.
fn chi2_quantile(k: f64, z: f64) -> f64 {
    let a = 2.0 / (9.0 * k);
    k * (1.0 - a + z * a.sqrt()).powi(3)
}

/// The 2.5 % and 97.5 % points of a chi-square with 3 degrees of freedom.
pub const CHI2_3_95: (f64, f64) = (0.2158, 9.3484);

/// The standard normal's 97.5 % point.
const Z_975: f64 = 1.959_964;

impl NisSummary {
    /// The NIS values `nis` (3 degrees of freedom each).
    pub fn of(nis: &[f64]) -> Self {
        let n = nis.len();
        if n == 0 {
            return Self {
                frames: 0,
                mean: f64::NAN,
                mean_bounds_95: [f64::NAN; 2],
                inside_95: f64::NAN,
            };
        }
        let k = 3.0 * n as f64;
        // The exact per-frame quantiles (the approximation is poor at 3 degrees of freedom).
        let (lo, hi) = CHI2_3_95;
        Self {
            frames: n,
            mean: nis.iter().sum::<f64>() / n as f64,
            mean_bounds_95: [
                chi2_quantile(k, -Z_975) / n as f64,
                chi2_quantile(k, Z_975) / n as f64,
            ],
            inside_95: nis.iter().filter(|&&x| x >= lo && x <= hi).count() as f64 / n as f64,
        }
    }
}

impl PairSummary {
    fn of(trace: &FollowerTrace) -> Self {
        let mse = MeanSquareErrors::of(trace.records.iter().map(|r| &r.step));
        let detected = MeanSquareErrors::of(
            trace
                .records
                .iter()
                .filter(|r| r.step.measured.iter().all(|v| v.is_finite()))
                .map(|r| &r.step),
        );
        let coasting = MeanSquareErrors::of(
            trace
                .records
                .iter()
                .filter(|r| r.status == Some(Status::Coasting))
                .map(|r| &r.step),
        );
        let nis: Vec<f64> = trace
            .records
            .iter()
            .filter(|r| r.measurement == Some(MeasurementUse::Updated))
            .filter_map(|r| r.nis)
            .collect();
        Self {
            follower: trace.follower,
            leader: trace.leader,
            mse: mse.estimate,
            mse_meas: mse.measurement,
            frames_scored: trace.records.len(),
            frames_detected: mse.measured,
            frames_coasting: trace
                .records
                .iter()
                .filter(|r| r.status == Some(Status::Coasting))
                .count(),
            mse_detected: detected.estimate,
            mse_coasting: if coasting.estimated > 0 {
                coasting.estimate
            } else {
                [f64::NAN; 5]
            },
            rms_velocity_after_2s: mse.rms_velocity_after_2s,
            nis: NisSummary::of(&nis),
        }
    }
}

/// Figures of merit of the demo (`summary.json`). The top-level fields are robot 2's track
/// of robot 1 (the reference pair); `pairs` has every follower-leader pair of the chain,
/// that one first.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DemoSummary {
    /// The mean square errors of the estimate over the frames with an estimate and of the
    /// vision measurement over the frames with one (flat in `summary.json`: `mse_l12` ...
    /// `mse_meas_beta12`).
    #[serde(flatten)]
    pub mse: MseSummary,
    /// Mean square errors of the tracked `l12`, `alpha12`, `beta12` over the frames in which
    /// the leader was measured (the frames of the vision MSEs): m^2, rad^2, rad^2.
    pub mse_detected: [f64; 3],
    /// Mean square errors of the tracked `l12`, `alpha12`, `beta12` over the coasting frames
    /// (NaN when none): m^2, rad^2, rad^2.
    pub mse_coasting: [f64; 3],
    /// RMS error of the tracked `v1` (m/s) and `w1` (rad/s) after `t = 2 s`.
    pub rms_velocity_after_2s: [f64; 2],
    /// NIS of the measurements robot 2's track used, against its 95 % chi-square bounds.
    pub nis: NisSummary,
    /// Frames processed by robot 2's pipeline (including `t = 0`).
    pub frames: usize,
    /// Frames scored (every frame after `t = 0`, whose measurement only initialises the
    /// tracker): the rows of `series.csv` and the frames the MSEs are over. Equal to
    /// `frames_detected + frames_occluded` when the leader is seen whenever it is visible.
    pub frames_scored: usize,
    /// Scored frames in which robot 1 was measured.
    pub frames_detected: usize,
    /// Scored frames inside the occlusion.
    pub frames_occluded: usize,
    /// Frames in which robot 2's track of robot 1 was coasting.
    pub frames_coasting: usize,
    /// Largest `|l12|` error while coasting, m.
    pub max_coasting_error_l12: f64,
    /// Whether robot 1 was tracked again after the occlusion by the same track (updated, not
    /// re-initialised) under its own id.
    pub reacquired_same_id: bool,
    /// Seconds from the end of the occlusion to the first update.
    pub reacquired_after_s: Option<f64>,
    /// Median detection time per frame, ms.
    pub detect_ms_median: f64,
    /// Median detect + pose + track time per frame, ms.
    pub pipeline_ms_median: f64,
    /// Frames per second of the pipeline on one core (rendering excluded): frames over the
    /// summed pipeline time.
    pub frames_per_second: f64,
    /// Largest relative error of the true `l12` from the controller's set-point after
    /// `t = 3 s`, over all followers.
    pub max_formation_error_after_3s: f64,
    /// Seconds spent rendering.
    pub render_s: f64,
    /// Robots in the chain.
    pub robots: usize,
    /// Whether the controllers used the estimates.
    pub closed_loop: bool,
    /// Every follower-leader pair (robot `k + 1` tracking robot `k`), robot 2's first.
    pub pairs: Vec<PairSummary>,
    /// Noise seed.
    pub seed: u64,
}

/// One annotated frame of the strip (robot 2's camera).
#[derive(Debug, Clone)]
pub struct StripFrame {
    /// The step (frame number from 0).
    pub step: usize,
    /// The frame with the markers read and the measured rigs drawn over it.
    pub image: image::RgbImage,
    /// The markers read, as `robot/face` labels, in the order drawn.
    pub labels: Vec<String>,
}

/// Everything a demo run produced.
#[derive(Debug, Clone)]
pub struct DemoRun {
    /// One trace per follower, robot 2 first.
    pub traces: Vec<FollowerTrace>,
    /// Robot 2's annotated frames for the strip.
    pub strip: Vec<StripFrame>,
    /// The figures of merit.
    pub summary: DemoSummary,
}

struct Follower {
    pipeline: Pipeline,
    controller: SeparationBearingController,
    /// Set-point changes of the scenario applied so far.
    setpoints_applied: usize,
    inputs: Inputs,
    trace: FollowerTrace,
}

fn nan3() -> Vector3<f64> {
    Vector3::repeat(f64::NAN)
}

/// Everything the followers share: the world they are rendered in.
pub(crate) struct World<'a> {
    pub(crate) config: &'a DemoConfig,
    pub(crate) mount: CameraMount,
    pub(crate) camera: CameraSpec,
    k: pose::Intrinsics,
    pub(crate) rig: RigModel,
    pub(crate) dict: &'a Dictionary,
}

/// One step's state of the chain as seen by a follower.
pub(crate) struct StepContext<'a> {
    pub(crate) step: usize,
    pub(crate) t: f64,
    pub(crate) occluded: bool,
    pub(crate) poses: &'a [PlanarPose],
    /// The poses one step earlier (at step 0, the start).
    pub(crate) previous: &'a [PlanarPose],
    /// Inputs over `(t_{k-1}, t_k]` of every robot (index 0 the leader's), as executed:
    /// what moved it.
    pub(crate) applied: &'a [Inputs],
    /// The same inputs as each robot's odometry reported them: what its tracker is given.
    pub(crate) odometry: &'a [Inputs],
}

/// Runs the demo.
///
/// # Errors
/// A bad configuration, or any stage failing (see [`DemoError`]).
pub fn run_demo(config: &DemoConfig) -> Result<DemoRun, DemoError> {
    run_demo_with_progress(config, |_, _| {})
}

/// One camera frame of a demo run, as [`run_demo_observed`] hands it out.
#[derive(Debug, Clone, Copy)]
pub struct DemoFrame<'a> {
    /// Step from 0; the frame is at `t = step * dt`.
    pub step: usize,
    /// The robot whose camera took it (2 for the first follower).
    pub robot: usize,
    /// The follower's own inputs over the interval ending at this frame (what a real robot
    /// logs from its odometry), as the tracker is given them.
    pub inputs: Inputs,
    /// The raw rendered frame (grey, before any annotation).
    pub image: &'a image::GrayImage,
}

/// [`run_demo_with_progress`], also handing every follower's raw frame to `on_frame` (to save
/// a test sequence for `track`).
///
/// # Errors
/// As [`run_demo`].
pub fn run_demo_observed(
    config: &DemoConfig,
    progress: impl FnMut(usize, usize),
    on_frame: impl FnMut(&DemoFrame<'_>),
) -> Result<DemoRun, DemoError> {
    run_demo_inner(config, progress, on_frame, || false)
}

/// [`run_demo_observed`] that asks `stop()` before every step and ends with
/// [`DemoError::Stopped`] when it says so (a command interrupted by a signal).
///
/// # Errors
/// As [`run_demo`], and [`DemoError::Stopped`].
pub fn run_demo_until(
    config: &DemoConfig,
    progress: impl FnMut(usize, usize),
    on_frame: impl FnMut(&DemoFrame<'_>),
    stop: impl Fn() -> bool,
) -> Result<DemoRun, DemoError> {
    run_demo_inner(config, progress, on_frame, stop)
}

/// [`run_demo`], calling `progress(step, steps)` after every step (for a progress bar).
///
/// # Errors
/// As [`run_demo`].
pub fn run_demo_with_progress(
    config: &DemoConfig,
    progress: impl FnMut(usize, usize),
) -> Result<DemoRun, DemoError> {
    run_demo_inner(config, progress, |_| {}, || false)
}

fn run_demo_inner(
    config: &DemoConfig,
    mut progress: impl FnMut(usize, usize),
    mut on_frame: impl FnMut(&DemoFrame<'_>),
    stop: impl Fn() -> bool,
) -> Result<DemoRun, DemoError> {
    validate(config)?;
    let world = World::new(config)?;
    let mut poses = start_poses(config);
    let mut previous = poses.clone();
    let mut followers = start_followers(&world, &poses)?;
    let steps = (config.duration / config.dt).round() as usize;
    let mut leader_inputs_prev = Inputs::new(0.0, 0.0);
    // The followers' actuation and odometry (exact unless the scenario says otherwise).
    let (actuation, odometry_noise_std) = config
        .scenario
        .as_ref()
        .map_or((Actuation::PERFECT, [0.0; 2]), |s| {
            (s.actuation, s.odometry_noise_std)
        });
    let mut motion_rng = actuation_rng(config.render.seed);
    let mut executed: Vec<Inputs> = followers.iter().map(|f| f.inputs).collect();
    let mut odometry = executed.clone();
    let mut strip = Vec::new();
    let mut render_s = 0.0;
    for step in 0..=steps {
        if stop() {
            return Err(DemoError::Stopped { step, steps });
        }
        let t = step as f64 * config.dt;
        let mut applied = vec![leader_inputs_prev];
        applied.extend(&executed);
        let mut measured = vec![leader_inputs_prev];
        measured.extend(&odometry);
        let ctx = StepContext {
            step,
            t,
            occluded: config.occluded_at(t),
            poses: &poses,
            previous: &previous,
            applied: &applied,
            odometry: &measured,
        };
        let leader_now = match &config.scenario {
            Some(spec) => spec.leader_inputs(t),
            None => reference_leader_inputs(t),
        };
        let mut new_inputs = vec![leader_now];
        for (idx, f) in followers.iter_mut().enumerate() {
            let me = idx + 1;
            let (render, annotated, image) = f.frame(&world, &ctx, me, new_inputs[me - 1])?;
            on_frame(&DemoFrame {
                step,
                robot: me + 1,
                inputs: ctx.odometry[me],
                image: &image,
            });
            render_s += render;
            strip.extend(annotated.map(|(image, labels)| StripFrame {
                step,
                image,
                labels,
            }));
            new_inputs.push(f.inputs);
        }
        progress(step, steps);
        leader_inputs_prev = new_inputs[0];
        for (k, commanded) in new_inputs[1..].iter().enumerate() {
            let (e, o) =
                follower_motion(&actuation, odometry_noise_std, *commanded, &mut motion_rng);
            (executed[k], odometry[k]) = (e, o);
        }
        if step < steps {
            previous.clone_from(&poses);
            let moved = std::iter::once(&leader_inputs_prev).chain(&executed);
            for (p, u) in poses.iter_mut().zip(moved) {
                *p = p.integrate_exact(*u, config.dt)?;
            }
        }
    }
    let traces: Vec<FollowerTrace> = followers.into_iter().map(|f| f.trace).collect();
    let summary = summarize(&traces, config, render_s);
    Ok(DemoRun {
        traces,
        strip,
        summary,
    })
}

impl<'a> World<'a> {
    pub(crate) fn new(config: &'a DemoConfig) -> Result<Self, DemoError> {
        let camera = config.camera;
        Ok(Self {
            config,
            mount: config.mount,
            camera,
            k: pose::Intrinsics::from_hfov(
                camera.hfov_deg.to_radians(),
                camera.width as u32,
                camera.height as u32,
            )?,
            rig: RigModel::reference(),
            dict: Dictionary::paper(),
        })
    }
}

/// The robots' poses at `t = 0`: the scenario file's, else the starting line.
pub(crate) fn start_poses(config: &DemoConfig) -> Vec<PlanarPose> {
    match &config.scenario {
        Some(spec) => {
            let [fx, fy, ft] = spec.follower;
            let [lx, ly, lt] = spec.leader;
            vec![PlanarPose::new(lx, ly, lt), PlanarPose::new(fx, fy, ft)]
        }
        None => starting_line(config.robots),
    }
}

/// The rays the demo's rendering casts: per frame, every pixel times the supersampling's
/// square times the motion blur's sub-frames, for every follower at every step.
pub fn render_rays(config: &DemoConfig) -> f64 {
    let steps = (config.duration / config.dt).round() + 1.0;
    let subframes = config.motion_blur.map_or(1, |mb| mb.subframes.max(1));
    let ss = config.render.supersampling.max(1) as f64;
    steps
        * (config.robots.saturating_sub(1)) as f64
        * (config.camera.width * config.camera.height) as f64
        * ss
        * ss
        * subframes as f64
}

/// How many rays the probe of [`estimate_render_seconds`] casts: about 20 ms of rendering
/// on the reference machine.
const PROBE_RAYS: f64 = 2e6;

/// An estimate of the seconds the demo will spend rendering, made before it starts so that
/// a run of hours says so at once (issue #32): the first frame is rendered as a *probe* with
/// the same scene, supersampling and sub-frames (no lighting gradient), its camera scaled down so that it
/// casts about two million rays, and its time is scaled by [`render_rays`]. Good to a factor
/// of about two (a smaller frame's fixed costs weigh a little more); it measures this machine
/// in this build, so a debug build's estimate is a debug build's time.
///
/// # Errors
/// A configuration [`run_demo`] would refuse, or a probe that cannot be rendered.
pub fn estimate_render_seconds(config: &DemoConfig) -> Result<f64, DemoError> {
    validate(config)?;
    let rays = render_rays(config);
    let per_frame = rays / ((config.duration / config.dt).round() + 1.0);
    let scale = (PROBE_RAYS / per_frame.max(1.0)).sqrt().min(1.0);
    let mut probe = config.clone();
    probe.camera.width = ((config.camera.width as f64 * scale).round() as usize).max(8);
    probe.camera.height = ((config.camera.height as f64 * scale).round() as usize).max(8);
    let world = World::new(&probe)?;
    let poses = start_poses(&probe);
    let applied = vec![Inputs::new(0.0, 0.0); poses.len()];
    let ctx = StepContext {
        step: 0,
        t: 0.0,
        occluded: false,
        poses: &poses,
        previous: &poses,
        applied: &applied,
        odometry: &applied,
    };
    let specs = exposure_poses(&probe, &ctx)?
        .iter()
        .map(|p| follower_scene(&world, &ctx, p, 1))
        .collect::<Vec<_>>();
    let started = Instant::now();
    scene::render_scene_exposure(&specs, None, &world.rig, world.dict)?;
    let probe_s = started.elapsed().as_secs_f64();
    let probe_rays = render_rays(&DemoConfig {
        duration: 0.0,
        robots: 2,
        ..probe
    });
    Ok(probe_s * rays / probe_rays.max(1.0))
}

pub(crate) fn validate(config: &DemoConfig) -> Result<(), DemoError> {
    if !(2..=6).contains(&config.robots) {
        return Err(DemoError::Config {
            what: "robots",
            value: config.robots as f64,
            expected: "2 to 6",
        });
    }
    if config.scenario.is_some() && config.robots != 2 {
        return Err(DemoError::Config {
            what: "robots",
            value: config.robots as f64,
            expected: "2 with a scenario file (it describes a leader and one follower)",
        });
    }
    if let Some(spec) = &config.scenario {
        spec.vision.check(config.dt).map_err(DemoError::Scenario)?;
    }
    for (what, value) in [("duration", config.duration), ("dt", config.dt)] {
        if !(value.is_finite() && value > 0.0) {
            return Err(DemoError::Config {
                what,
                value,
                expected: "finite and positive",
            });
        }
    }
    Ok(())
}

/// The followers' tracker settings: the defaults, told the noise of the follower's own
/// odometry (a property of the robot, from the scenario file; exact without one).
fn tracker_config(world: &World<'_>) -> TrackerConfig {
    let mut c = TrackerConfig::reference(world.mount.offset, world.config.dt);
    if let Some(s) = &world.config.scenario {
        c.filter.tuning.input_noise_std = nalgebra::Vector2::from(s.odometry_noise_std);
    }
    c
}

/// Robot `i` of `n` at `((n - i) 1.5, (n - i) 0.25, 0)`.
fn starting_line(n: usize) -> Vec<PlanarPose> {
    (1..=n)
        .map(|i| {
            let back = (n - i) as f64;
            PlanarPose::new(1.5 * back, 0.25 * back, 0.0)
        })
        .collect()
}

/// One follower per robot behind the leader, each holding its starting formation.
fn start_followers(world: &World<'_>, poses: &[PlanarPose]) -> Result<Vec<Follower>, DemoError> {
    let d = world.mount.offset;
    let (w, h) = (world.camera.width as u32, world.camera.height as u32);
    (1..poses.len())
        .map(|j| {
            let start = Formation::from_poses(&poses[j - 1], &poses[j], d)?;
            let mut pipeline = Pipeline::new(
                Detector::with_dictionary(DetectorConfig::for_pose(), world.dict.clone()),
                pose::PoseSolver::new(world.k),
                (w, h),
                world.rig.clone(),
                RobotConfig::default(),
                Tracker::new(tracker_config(world))?,
            );
            pipeline.set_guided(world.config.guided)?;
            Ok(Follower {
                pipeline,
                controller: SeparationBearingController::new(d, ControllerConfig::hold(&start))?,
                setpoints_applied: 0,
                inputs: Inputs::new(0.0, 0.0),
                trace: FollowerTrace {
                    follower: (j + 1) as u32,
                    leader: j as u32,
                    records: Vec::new(),
                },
            })
        })
        .collect()
}

/// The scene follower `me` sees: every other robot, less robot 1 from robot 2 during the
/// occlusion; frame `k` of follower `me` uses noise seed `seed + k n + me`.
pub(crate) fn follower_scene(
    world: &World<'_>,
    ctx: &StepContext<'_>,
    poses: &[PlanarPose],
    me: usize,
) -> SceneSpec {
    let n = poses.len();
    let robots: Vec<RobotSpec> = poses
        .iter()
        .enumerate()
        .filter(|&(i, _)| i != me && !(ctx.occluded && me == 1 && i == 0))
        .map(|(i, p)| RobotSpec {
            robot: (i + 1) as u32,
            x: p.x,
            y: p.y,
            theta: p.theta,
        })
        .collect();
    SceneSpec {
        name: String::new(),
        camera_robot: PlanarPose {
            x: poses[me].x,
            y: poses[me].y,
            theta: poses[me].theta,
        },
        mount: world.mount,
        camera: world.camera,
        render: RenderSpec {
            seed: world
                .config
                .render
                .seed
                .wrapping_add((ctx.step * n + me) as u64),
            ..world.config.render
        },
        robots,
    }
}

/// The robots' poses at the sub-frame times of the exposure of step `ctx.step` (see the
/// module documentation); without motion blur, only the poses at the frame time.
pub(crate) fn exposure_poses(
    config: &DemoConfig,
    ctx: &StepContext<'_>,
) -> Result<Vec<Vec<PlanarPose>>, DemoError> {
    let Some(mb) = config.motion_blur else {
        return Ok(vec![ctx.poses.to_vec()]);
    };
    let n = mb.subframes.max(1);
    (0..n)
        .map(|i| {
            let s = mb.exposure_s * ((i as f64 + 0.5) / n as f64 - 0.5);
            ctx.poses
                .iter()
                .zip(ctx.previous)
                .zip(ctx.applied)
                .map(|((now, before), u)| {
                    if s < 0.0 {
                        before.integrate_exact(*u, config.dt + s)
                    } else if s > 0.0 {
                        now.integrate_exact(*u, s)
                    } else {
                        Ok(*now)
                    }
                })
                .collect::<Result<Vec<PlanarPose>, _>>()
                .map_err(DemoError::from)
        })
        .collect()
}

/// An annotated strip frame and the `robot/face` labels of the markers read in it.
type Annotated = (image::RgbImage, Vec<String>);

impl Follower {
    /// Renders and processes follower `me`'s frame, records it (after `t = 0`) and sets the
    /// inputs for the next interval. `leader_now` is the leader's input for that interval.
    /// Returns the seconds spent rendering, on robot 2's strip steps the annotated frame, and
    /// the raw frame.
    fn frame(
        &mut self,
        world: &World<'_>,
        ctx: &StepContext<'_>,
        me: usize,
        leader_now: Inputs,
    ) -> Result<(f64, Option<Annotated>, image::GrayImage), DemoError> {
        let ahead = me - 1;
        let d = world.mount.offset;
        let (width, height) = (world.camera.width, world.camera.height);
        let specs = exposure_poses(world.config, ctx)?
            .iter()
            .map(|poses| follower_scene(world, ctx, poses, me))
            .collect::<Vec<_>>();
        let gradient = world.config.gradient.map(|g| synthcam::Gradient {
            from: g.from,
            to: g.to,
            angle: g.angle_deg.to_radians(),
        });
        let started = Instant::now();
        let frame = scene::render_scene_exposure(&specs, gradient, &world.rig, world.dict)?.image;
        let render_s = started.elapsed().as_secs_f64();
        let done = self.pipeline.process(
            frame.as_raw(),
            width,
            height,
            ctx.t,
            ctx.odometry[me],
            world.mount,
        )?;
        let truth = Formation::from_poses(&ctx.poses[ahead], &ctx.poses[me], d)?;
        let leader_id = (ahead + 1) as u32;
        let measured = done
            .robots
            .iter()
            .find(|m| m.robot == leader_id)
            .map_or_else(nan3, |m| m.formation.to_vector());
        let track = done.report.leaders.iter().find(|l| l.robot == leader_id);
        let strip_step =
            world.config.strip_every > 0 && ctx.step.is_multiple_of(world.config.strip_every);
        let annotated = if me == 1 && strip_step {
            Some(self.annotate(world, &frame, &done.robots)?)
        } else {
            None
        };
        if me == 1 {
            self.apply_setpoints(world, ctx.t, leader_id)?;
        }
        self.inputs = if world.config.closed_loop {
            track
                .and_then(|l| {
                    let leader = Inputs::new(l.v1, l.w1);
                    self.controller.inputs(&l.formation, leader).ok()
                })
                .unwrap_or(self.inputs)
        } else {
            self.controller.inputs(&truth, leader_now)?
        };
        if ctx.step > 0 {
            let nan = f64::NAN;
            self.trace.records.push(DemoRecord {
                step: StepRecord {
                    t: ctx.t,
                    truth: truth.to_vector(),
                    measured,
                    estimated: track.map_or_else(nan3, |l| l.formation.to_vector()),
                    estimated_std: track.map_or_else(nan3, |l| {
                        Vector3::new(l.l12_std, l.alpha12_std, l.beta12_std)
                    }),
                    v1_true: ctx.applied[ahead].v,
                    w1_true: ctx.applied[ahead].w,
                    v1_estimated: track.map_or(nan, |l| l.v1),
                    w1_estimated: track.map_or(nan, |l| l.w1),
                    v1_std: track.map_or(nan, |l| l.v1_std),
                    w1_std: track.map_or(nan, |l| l.w1_std),
                },
                status: track.map(|l| l.status),
                measurement: track.map(|l| l.measurement),
                markers: done.markers,
                leaders: done.report.leaders.len(),
                occluded: ctx.occluded && me == 1,
                timing: done.timing,
                scan: done.scan,
                l12_desired: self.controller.config().l12_desired,
                nis: track.and_then(|l| l.nis),
            });
        }
        Ok((render_s, annotated, frame))
    }

    /// Applies the scenario's set-point changes due by `t` (in time order, each once), as
    /// `reproduce dukf` does, and tells the tracker of its leader `leader` that they changed
    /// (the follower knows its own plan; `Tracker::follower_setpoint_changed`).
    fn apply_setpoints(&mut self, world: &World<'_>, t: f64, leader: u32) -> Result<(), DemoError> {
        let Some(spec) = &world.config.scenario else {
            return Ok(());
        };
        let mut due: Vec<_> = spec.setpoints.iter().filter(|s| t >= s.at).collect();
        due.sort_by(|a, b| a.at.total_cmp(&b.at));
        for change in due.iter().skip(self.setpoints_applied) {
            let goal = self
                .controller
                .config()
                .with_setpoints(change.l12, change.alpha12);
            self.controller = SeparationBearingController::new(world.mount.offset, goal)?;
            self.pipeline
                .tracker_mut()
                .follower_setpoint_changed(leader)?;
        }
        self.setpoints_applied = self.setpoints_applied.max(due.len());
        Ok(())
    }

    /// The frame with the markers read and each measured robot's rig drawn over it, and the
    /// markers' `robot/face` labels.
    fn annotate(
        &self,
        world: &World<'_>,
        frame: &image::GrayImage,
        robots: &[formation_tracker::robots::RobotMeasurement],
    ) -> Result<Annotated, DemoError> {
        let markers: Vec<MarkerLabel> = self
            .pipeline
            .markers()
            .iter()
            .filter_map(|m| {
                let (robot, face) = world.rig.robot_face(m.index)?;
                Some(MarkerLabel {
                    robot,
                    face,
                    corners: m.corners,
                })
            })
            .collect();
        let rigs: Vec<RigOverlay> = robots.iter().map(RigOverlay::from).collect();
        let labels = markers
            .iter()
            .map(|m| format!("{}/{}", m.robot, m.face))
            .collect();
        let camera = pose::Camera::pinhole(world.k, frame.width(), frame.height());
        let image = annotate(frame, &camera, &world.rig, &markers, &rigs)?;
        Ok((image, labels))
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn summarize(traces: &[FollowerTrace], config: &DemoConfig, render_s: f64) -> DemoSummary {
    let records = &traces[0].records;
    // The top-level figures are the first pair's.
    let pairs: Vec<PairSummary> = traces.iter().map(PairSummary::of).collect();
    let first = &pairs[0];
    let mut max_coast: f64 = 0.0;
    let mut occluded = 0;
    for r in records {
        let e = r.step.estimation_error();
        if r.status == Some(Status::Coasting) && e[0].is_finite() {
            max_coast = max_coast.max(e[0].abs());
        }
        if r.occluded {
            occluded += 1;
        }
    }
    let occlusion_end = config.occlusion.map(|(_, b)| b);
    let after: Vec<&DemoRecord> = records
        .iter()
        .filter(|r| occlusion_end.is_some_and(|b| r.step.t >= b - 1e-9))
        .collect();
    let first_update = after
        .iter()
        .find(|r| {
            matches!(
                r.measurement,
                Some(MeasurementUse::Updated | MeasurementUse::Initialised)
            )
        })
        .copied();
    let reacquired_same_id = first_update
        .is_some_and(|r| r.measurement == Some(MeasurementUse::Updated))
        && !records
            .iter()
            .any(|r| r.measurement == Some(MeasurementUse::Initialised));
    let max_formation = traces
        .iter()
        .flat_map(|tr| tr.records.iter())
        .filter(|r| r.step.t > 3.0)
        .map(|r| (r.step.truth[0] - r.l12_desired).abs() / r.l12_desired)
        .fold(0.0, f64::max);
    let pipeline_ms: Vec<f64> = records.iter().map(|r| r.timing.total_ms()).collect();
    let total_s: f64 = pipeline_ms.iter().sum::<f64>() / 1e3;
    let frames = records.len() + 1;
    DemoSummary {
        mse: MseSummary::new(first.mse, first.mse_meas),
        mse_detected: [
            first.mse_detected[0],
            first.mse_detected[1],
            first.mse_detected[2],
        ],
        mse_coasting: [
            first.mse_coasting[0],
            first.mse_coasting[1],
            first.mse_coasting[2],
        ],
        rms_velocity_after_2s: first.rms_velocity_after_2s,
        nis: first.nis,
        frames,
        frames_scored: first.frames_scored,
        frames_detected: first.frames_detected,
        frames_occluded: occluded,
        frames_coasting: first.frames_coasting,
        max_coasting_error_l12: max_coast,
        reacquired_same_id,
        reacquired_after_s: first_update.zip(occlusion_end).map(|(r, b)| r.step.t - b),
        detect_ms_median: median(records.iter().map(|r| r.timing.detect_ms).collect()),
        pipeline_ms_median: median(pipeline_ms),
        frames_per_second: if total_s > 0.0 {
            records.len() as f64 / total_s
        } else {
            f64::NAN
        },
        max_formation_error_after_3s: max_formation,
        render_s,
        robots: config.robots,
        closed_loop: config.closed_loop,
        pairs,
        seed: config.render.seed,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn render_rays_count_every_pixel_sample_subframe_follower_and_step() {
        let mut config = DemoConfig::default();
        let frames = (config.duration / config.dt).round() + 1.0;
        let ss = config.render.supersampling as f64;
        let per_frame = 640.0 * 480.0 * ss * ss;
        assert_eq!(render_rays(&config), frames * per_frame);
        config.robots = 4;
        config.motion_blur = Some(MotionBlurSpec {
            exposure_s: 0.02,
            subframes: 5,
        });
        assert_eq!(render_rays(&config), frames * 3.0 * 5.0 * per_frame);
    }

    #[test]
    fn the_render_estimate_is_made_from_a_small_probe_and_refuses_bad_configurations() {
        // A 4096 x 4096 camera with supersampling 8 and 5 sub-frames: 5.4e9 rays a frame.
        // The probe casts about 2e6 of them, so the estimate comes at once.
        let mut config = DemoConfig::default();
        config.camera.width = 4096;
        config.camera.height = 4096;
        config.render.supersampling = 8;
        config.motion_blur = Some(MotionBlurSpec {
            exposure_s: 0.02,
            subframes: 5,
        });
        let estimate = estimate_render_seconds(&config).unwrap();
        assert!(estimate.is_finite() && estimate > 0.0, "{estimate}");
        config.duration = f64::NAN;
        assert!(estimate_render_seconds(&config).is_err());
    }
}
