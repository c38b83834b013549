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

use std::time::Instant;

use fiducial::{Detector, DetectorConfig, Dictionary};
use nalgebra::Vector3;
use serde::Serialize;
use unicycle::{
    ControllerConfig, Formation, Inputs, Pose, SeparationBearingController, UnicycleError,
};

use crate::annotate::{AnnotateError, MarkerLabel, RigOverlay, annotate};
use crate::reproduce::StepRecord;
use crate::scenario::reference_leader_inputs;
use crate::scene::{self, CameraSpec, RenderSpec, RobotSpec, SceneError, SceneSpec};
use formation_tracker::mount::CameraMount;
use formation_tracker::pipeline::{Pipeline, PipelineError, Timing};
use formation_tracker::rigfile::RigModel;
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
    /// Desired separation of the follower's controller, m.
    pub l12_desired: f64,
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

/// Figures of merit of robot 2's track of robot 1 (`summary.json`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DemoSummary {
    /// Mean square error of `l12` over the frames with an estimate, m^2.
    pub mse_l12: f64,
    /// Mean square error of `alpha12`, rad^2.
    pub mse_alpha12: f64,
    /// Mean square error of `beta12`, rad^2.
    pub mse_beta12: f64,
    /// Mean square error of `v1`, (m/s)^2.
    pub mse_v1: f64,
    /// Mean square error of `w1`, (rad/s)^2.
    pub mse_w1: f64,
    /// Mean square error of the vision measurement of `l12` (frames with one), m^2.
    pub mse_meas_l12: f64,
    /// Mean square error of the vision measurement of `alpha12`, rad^2.
    pub mse_meas_alpha12: f64,
    /// Frames processed by robot 2's pipeline (including `t = 0`).
    pub frames: usize,
    /// Frames in which robot 1 was measured.
    pub frames_detected: usize,
    /// Frames inside the occlusion.
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
    /// Noise seed.
    pub seed: u64,
}

/// Everything a demo run produced.
#[derive(Debug, Clone)]
pub struct DemoRun {
    /// One trace per follower, robot 2 first.
    pub traces: Vec<FollowerTrace>,
    /// Robot 2's annotated frames (step, image) for the strip.
    pub strip: Vec<(usize, image::RgbImage)>,
    /// The figures of merit.
    pub summary: DemoSummary,
}

struct Follower {
    pipeline: Pipeline,
    controller: SeparationBearingController,
    inputs: Inputs,
    trace: FollowerTrace,
}

fn nan3() -> Vector3<f64> {
    Vector3::repeat(f64::NAN)
}

/// Runs the demo.
///
/// # Errors
/// A bad configuration, or any stage failing (see [`DemoError`]).
pub fn run_demo(config: &DemoConfig) -> Result<DemoRun, DemoError> {
    run_demo_with_progress(config, |_, _| {})
}

/// [`run_demo`], calling `progress(step, steps)` after every step (for a progress bar).
///
/// # Errors
/// As [`run_demo`].
pub fn run_demo_with_progress(
    config: &DemoConfig,
    mut progress: impl FnMut(usize, usize),
) -> Result<DemoRun, DemoError> {
    if !(2..=6).contains(&config.robots) {
        return Err(DemoError::Config {
            what: "robots",
            value: config.robots as f64,
            expected: "2 to 6",
        });
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
    let mount = CameraMount::default();
    let d = mount.offset;
    let rig = RigModel::reference();
    let dict = Dictionary::paper();
    let camera = CameraSpec::default();
    let k = pose::Intrinsics::from_hfov(
        camera.hfov_deg.to_radians(),
        camera.width as u32,
        camera.height as u32,
    )?;
    let n = config.robots;
    let mut poses: Vec<Pose> = (1..=n)
        .map(|i| {
            let back = (n - i) as f64;
            Pose::new(1.5 * back, 0.25 * back, 0.0)
        })
        .collect();
    let mut followers = Vec::new();
    for j in 1..n {
        let start = Formation::from_poses(&poses[j - 1], &poses[j], d)?;
        followers.push(Follower {
            pipeline: Pipeline::new(
                Detector::with_dictionary(DetectorConfig::default(), dict.clone()),
                pose::PoseSolver::new(k),
                (camera.width as u32, camera.height as u32),
                rig.clone(),
                RobotConfig::default(),
                Tracker::new(TrackerConfig::reference(d, config.dt))?,
            ),
            controller: SeparationBearingController::new(d, ControllerConfig::hold(&start))?,
            inputs: Inputs::new(0.0, 0.0),
            trace: FollowerTrace {
                follower: (j + 1) as u32,
                leader: j as u32,
                records: Vec::new(),
            },
        });
    }
    let steps = (config.duration / config.dt).round() as usize;
    let mut leader_inputs_prev = Inputs::new(0.0, 0.0);
    let mut strip = Vec::new();
    let mut render_s = 0.0;
    for step in 0..=steps {
        let t = step as f64 * config.dt;
        let occluded = config
            .occlusion
            .is_some_and(|(a, b)| t >= a - 1e-9 && t < b - 1e-9);
        // Inputs over (t_{k-1}, t_k] of every robot: index 0 the leader's.
        let mut applied = vec![leader_inputs_prev];
        applied.extend(followers.iter().map(|f| f.inputs));
        let mut new_inputs = vec![reference_leader_inputs(t)];
        for (idx, f) in followers.iter_mut().enumerate() {
            let (me, ahead) = (idx + 1, idx);
            let robots: Vec<RobotSpec> = poses
                .iter()
                .enumerate()
                .filter(|&(i, _)| i != me && !(occluded && me == 1 && i == 0))
                .map(|(i, p)| RobotSpec {
                    robot: (i + 1) as u32,
                    x: p.x,
                    y: p.y,
                    theta: p.theta,
                })
                .collect();
            let spec = SceneSpec {
                name: String::new(),
                camera_robot: Pose {
                    x: poses[me].x,
                    y: poses[me].y,
                    theta: poses[me].theta,
                },
                mount,
                camera,
                render: RenderSpec {
                    seed: config.render.seed.wrapping_add((step * n + me) as u64),
                    ..config.render
                },
                robots,
            };
            let started = Instant::now();
            let frame = scene::render_scene(&spec, &rig, dict)?.image;
            render_s += started.elapsed().as_secs_f64();
            let done = f.pipeline.process(
                frame.as_raw(),
                camera.width,
                camera.height,
                t,
                applied[me],
                mount,
            )?;
            let truth = Formation::from_poses(&poses[ahead], &poses[me], d)?;
            let leader_id = (ahead + 1) as u32;
            let measured = done
                .robots
                .iter()
                .find(|m| m.robot == leader_id)
                .map_or_else(nan3, |m| Vector3::new(m.l12, m.alpha12, m.beta12));
            let track = done.report.leaders.iter().find(|l| l.robot == leader_id);
            if me == 1 && config.strip_every > 0 && step % config.strip_every == 0 {
                let markers: Vec<MarkerLabel> = f
                    .pipeline
                    .markers()
                    .iter()
                    .filter_map(|m| {
                        let (robot, face) = rig.robot_face(m.index)?;
                        Some(MarkerLabel {
                            robot,
                            face,
                            corners: m.corners,
                        })
                    })
                    .collect();
                let rigs: Vec<RigOverlay> = done.robots.iter().map(RigOverlay::from).collect();
                strip.push((step, annotate(&frame, &k.matrix(), &rig, &markers, &rigs)?));
            }
            // Controller inputs for the next interval.
            let leader_now = new_inputs[ahead];
            let estimate = track.map(|l| {
                (
                    Formation {
                        l12: l.l12,
                        alpha12: l.alpha12,
                        beta12: l.beta12,
                    },
                    Inputs::new(l.v1, l.w1),
                )
            });
            f.inputs = if config.closed_loop {
                estimate
                    .and_then(|(form, v)| f.controller.inputs(&form, v).ok())
                    .unwrap_or(f.inputs)
            } else {
                f.controller.inputs(&truth, leader_now)?
            };
            new_inputs.push(f.inputs);
            if step == 0 {
                continue;
            }
            let est = track.map_or_else(nan3, |l| Vector3::new(l.l12, l.alpha12, l.beta12));
            let est_std = track.map_or_else(nan3, |l| {
                Vector3::new(l.l12_std, l.alpha12_std, l.beta12_std)
            });
            let nan = f64::NAN;
            f.trace.records.push(DemoRecord {
                step: StepRecord {
                    t,
                    truth: truth.to_vector(),
                    measured,
                    estimated: est,
                    estimated_std: est_std,
                    v1_true: applied[ahead].v,
                    w1_true: applied[ahead].w,
                    v1_estimated: track.map_or(nan, |l| l.v1),
                    w1_estimated: track.map_or(nan, |l| l.w1),
                    v1_std: track.map_or(nan, |l| l.v1_std),
                    w1_std: track.map_or(nan, |l| l.w1_std),
                },
                status: track.map(|l| l.status),
                measurement: track.map(|l| l.measurement),
                markers: done.markers,
                leaders: done.report.leaders.len(),
                occluded: occluded && me == 1,
                timing: done.timing,
                l12_desired: f.controller.config().l12_desired,
            });
        }
        progress(step, steps);
        leader_inputs_prev = new_inputs[0];
        if step < steps {
            for (p, u) in poses.iter_mut().zip(&new_inputs) {
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

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn summarize(traces: &[FollowerTrace], config: &DemoConfig, render_s: f64) -> DemoSummary {
    let records = &traces[0].records;
    let (mut sq, mut n) = ([0.0; 5], 0usize);
    let (mut meas, mut n_meas) = ([0.0; 2], 0usize);
    let mut max_coast: f64 = 0.0;
    let (mut coasting, mut detected, mut occluded) = (0, 0, 0);
    for r in records {
        let s = &r.step;
        let e = s.estimation_error();
        if e.iter().all(|v| v.is_finite()) {
            let ev = [
                e[0],
                e[1],
                e[2],
                s.v1_estimated - s.v1_true,
                s.w1_estimated - s.w1_true,
            ];
            for (acc, x) in sq.iter_mut().zip(ev) {
                *acc += x * x;
            }
            n += 1;
        }
        let m = s.measurement_error();
        if m.iter().all(|v| v.is_finite()) {
            meas[0] += m[0] * m[0];
            meas[1] += m[1] * m[1];
            n_meas += 1;
            detected += 1;
        }
        if r.status == Some(Status::Coasting) {
            coasting += 1;
            if e[0].is_finite() {
                max_coast = max_coast.max(e[0].abs());
            }
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
    let nf = n.max(1) as f64;
    let nm = n_meas.max(1) as f64;
    DemoSummary {
        mse_l12: sq[0] / nf,
        mse_alpha12: sq[1] / nf,
        mse_beta12: sq[2] / nf,
        mse_v1: sq[3] / nf,
        mse_w1: sq[4] / nf,
        mse_meas_l12: meas[0] / nm,
        mse_meas_alpha12: meas[1] / nm,
        frames,
        frames_detected: detected,
        frames_occluded: occluded,
        frames_coasting: coasting,
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
        seed: config.render.seed,
    }
}
