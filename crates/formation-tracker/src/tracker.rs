//! Tracking leaders over time: one formation filter (the IMM by default) per leader robot,
//! fed per-frame pose measurements, with coasting, loss, re-acquisition, planar-ambiguity resolution and gating.
//!
//! The tracker does not look at images. Its input per frame ([`FrameInput`]) is what the
//! vision pipeline makes of one camera frame: for every robot seen, either one chosen pose
//! (several faces seen, a joint pose) or, for a single marker face, both planar candidates
//! of `pose::PoseSolver::planar_candidates`; plus the follower's own inputs `(v2, w2)`, the
//! camera mount (whose pan may change per frame) and the frame time. Its output per frame
//! ([`FrameReport`]) is, per leader, the formation variables `(l12, alpha12, beta12)`, the
//! leader's velocities `(v1, w1)`, their standard deviations and the track's status.
//!
//! # One frame, per leader
//! 1. **Measurement.** Each pose candidate (rig frame to camera frame) goes through the
//!    measurement transform of spec 2.5 ([`crate::mount::formation_of_pose`]), which also
//!    propagates its 6x6 pose covariance (a joint or ground-plane fit comes with its formation
//!    covariance). That covariance, which `pose` scales by one fit's residual, is rescaled to
//!    the corner noise **pooled** over the robot's recent fits, `sum SSE / sum (2N - p)`
//!    ([`TrackerConfig::corner_noise_memory_dof`], or a fixed
//!    [`TrackerConfig::corner_sigma_px`]); the floor [`TrackerConfig::measurement_floor_std`]
//!    and [`TrackerConfig::relative_distance_std`] are added, and the whole is multiplied by
//!    the factor learned from the robot's innovations ([`TrackerConfig::innovation_memory`],
//!    [`dukf::NoiseScale`]). `docs/tracking.md` has the measurements behind these defaults.
//! 2. **Prediction.** The track's filter is predicted over the frame gap (see *Time*) on a
//!    copy, giving the predicted measurement `y-` and its variances `diag(P-)`.
//! 3. **Candidate choice.** With two planar candidates, the one with the smaller
//!    `d^2 = nu^T (diag(P-) + R_i)^-1 nu` (innovation `nu = y_i - y-`, angles wrapped) is
//!    used: the track's prediction decides, not the reprojection RMS. Only the diagonal of
//!    `P-` is used; its off-diagonal terms are small next to `R` for these three variables.
//! 4. **Gating.** The chosen measurement is applied only if `d^2 <=`
//!    [`TrackerConfig::gate`] (16.27, the 99.9 % point of a chi-square with 3 degrees of
//!    freedom); a gated one leaves the track coasting for this frame. The next is taken if
//!    it lies within the gate of one IMM model's own prediction. A follower that changes its
//!    set-point says so ([`Tracker::follower_setpoint_changed`]) to have it expected. When
//!    [`TrackerConfig::restart_after_gated`] measurements (default 2) in a row lie beyond
//!    four times the gate of every model, or five times as many beyond the gate at all, the
//!    track restarts from the latest one (`initialised`, keeping its velocity estimate with
//!    the prior's spread): a leader faster than any model allows (a robot at rest reaching
//!    0.8 m/s within one frame) is taken up again one frame later.
//! 5. **Update or coast.** Accepted: a filter step with `R`; status `tracking`. Not seen,
//!    gated or invalid: a predict-only step (the covariance grows); status `coasting`.
//!    When the time since the last accepted measurement exceeds `lost_after` (default 2 s)
//!    the leader is reported once as `lost` (its last estimate) and its track is dropped.
//!    A robot seen again after that gets a new track under its own id, initialised from the
//!    measurement.
//!
//! # Initialisation
//! A new track's formation variables are the first measurement, with its `R` as their
//! covariance. The leader's world pose `(x1, y1, theta1)`, which the measurements do not
//! observe and the model does not need, is placed as if the follower stood at the origin,
//! with a loose [`TrackerConfig::world_pose_prior_std`] (0.1). The leader's velocity prior is
//! the filter template's `w0`, `Pw0`: by default the paper's `[0, 0]` and `I`.
//!
//! With two candidates and no track yet, nothing in one frame can decide: the `best`
//! candidate (lower RMS) starts the main hypothesis and the other a **rival**. For
//! [`TrackerConfig::confirm_time`] (default 1 s) both are run on every frame, each choosing
//! its own nearest candidate and accumulating a score, the sum of its chosen `d^2` (each
//! capped at the gate). The main hypothesis is reported unless the rival's score is lower by
//! more than 8 (hysteresis), in which case they swap (the report's
//! `hypotheses` is 2 meanwhile); at the end of the window the other is dropped. The flipped
//! pose is not consistent with the unicycle kinematics and the follower's known motion over
//! time, so its score grows faster. A wrong hypothesis that survives shows up as gated
//! measurements and is replaced after `lost_after`.
//!
//! # Time
//! The filter's step `dt` is fixed ([`TrackerConfig::filter`]`.dt`, the camera's frame
//! period). The gap between two frames is rounded to a whole number `n >= 1` of steps; the
//! track is predicted `n - 1` times with the frame's follower inputs, then stepped (or
//! predicted) once. So a dropped camera frame costs one more prediction, not a wrong `dt`.
//! Frame times must increase ([`TrackerError::TimeNotIncreasing`]).
//!
//! # Bad input
//! A bad frame (non-finite time, inputs or mount, time not increasing, a mount offset other
//! than the filter's `d`) is a [`TrackerError`] and leaves the tracker unchanged. A bad
//! measurement of one robot (non-finite pose or covariance, a leader on the camera point) is
//! a documented skip: that leader's entry reports [`MeasurementUse::Invalid`] and coasts;
//! the other leaders are unaffected. If a track's filter fails (e.g. a coasting prediction
//! reaches `l12 <= 0`), the track is reported `lost` and dropped. No NaN is ever reported.

mod config;
mod io;
mod predict;
mod smooth;

pub use config::{CHI2_3_999, TrackerConfig, TrackerError};
pub use io::{
    FitResidual, FormationMeasurement, FrameInput, FrameReport, LeaderReport, LostReason,
    MeasurementUse, Observation, PoseMeasurement, PredictedLeader, Status,
};
pub use smooth::SmoothedLeader;

use std::collections::BTreeMap;

use nalgebra::{Matrix3, Vector2, Vector3};
use unicycle::{ControllerConfig, Inputs};

use crate::filter::{FilterError, FormationFilter, MEASUREMENT_SPACE};
use crate::mount::{CameraMount, MIN_L12, MeasurementError, formation_of_pose};
use smooth::{NO_INPUTS, Recorded, Segment};

/// How much lower (in summed `d^2`) the rival's score must be before it replaces the main
/// hypothesis: hysteresis, so that the reported estimate does not alternate between the two
/// while the evidence is still even.
const SWITCH_MARGIN: f64 = 8.0;

/// The factor on a robot's `R` before its innovations have been seen (a new track does not
/// yet know the errors its fit residuals miss, and its first frames are where the IMM is
/// most confident), and the measurements it weighs: a running mean forgets it within a few
/// frames ([`dukf::NoiseScale::with_prior`]; weighing `innovation_memory`, it kept `far`'s
/// NIS under its band for 2 s). `docs/tracking.md` has the measurements.
const INITIAL_INNOVATION_SCALE: (f64, f64) = (2.0, 5.0);

/// The range of the factor the innovations may put on `R`
/// ([`TrackerConfig::innovation_memory`]): at `far` it settles near 0.3.
const INNOVATION_SCALE_RANGE: [f64; 2] = [0.1, 100.0];

/// One filter and how well it has explained the measurements so far.
#[derive(Debug, Clone)]
struct Hypothesis {
    filter: FormationFilter,
    /// Sum of the chosen candidates' `d^2`, each capped at the gate.
    score: f64,
    /// Every filter step since the start, when the tracker records (see
    /// [`Tracker::record_history`]); empty otherwise.
    history: Vec<Recorded>,
    /// The gate's count of refusals in a row ([`Tracker::gate`]).
    runs: dukf::GateRuns,
}

impl Hypothesis {
    fn new(filter: FormationFilter, t: f64, recording: bool) -> Self {
        let history = if recording {
            vec![Recorded {
                frame: Some(t),
                step: filter.record(NO_INPUTS, None),
            }]
        } else {
            Vec::new()
        };
        Self {
            filter,
            score: 0.0,
            history,
            runs: dukf::GateRuns::default(),
        }
    }
}

/// One leader's track: the main hypothesis (reported) and, while a single-face start is
/// unconfirmed, the rival started from the other planar candidate.
#[derive(Debug, Clone)]
struct Track {
    main: Hypothesis,
    rival: Option<Hypothesis>,
    confirm_until: f64,
    last_seen: f64,
}

/// What one hypothesis did with one frame's measurement.
#[derive(Debug, Clone, Copy)]
struct Outcome {
    usage: MeasurementUse,
    chosen: Option<(Formed, f64)>,
}

/// A measurement converted to formation variables.
#[derive(Debug, Clone, Copy)]
struct Formed {
    y: Vector3<f64>,
    r: Matrix3<f64>,
    candidate: Option<u8>,
}

/// The multi-leader tracker. See the module documentation.
#[derive(Debug, Clone)]
pub struct Tracker {
    config: TrackerConfig,
    tracks: BTreeMap<u32, Track>,
    last_t: Option<f64>,
    recording: bool,
    /// The recorded steps of the tracks already dropped, in the order they ended.
    finished: Vec<Segment>,
    /// Per robot, the pooled corner noise of its recent pose solves (see
    /// [`TrackerConfig::corner_noise_memory_dof`]).
    corner_noise: BTreeMap<u32, pose::ResidualPool>,
    /// Per robot, the factor on `R` that the innovations call for (see
    /// [`TrackerConfig::innovation_memory`]); absent until a measurement was tested.
    innovation_scale: BTreeMap<u32, dukf::NoiseScale>,
    /// Per leader, the follower's own controller towards it, if told
    /// ([`set_follower_controller`](Self::set_follower_controller)).
    controllers: BTreeMap<u32, ControllerConfig>,
}

impl Tracker {
    /// A tracker with no tracks.
    ///
    /// # Errors
    /// [`TrackerError::InvalidConfig`] or a filter template error.
    pub fn new(config: TrackerConfig) -> Result<Self, TrackerError> {
        config.validate()?;
        Ok(Self {
            config,
            tracks: BTreeMap::new(),
            last_t: None,
            recording: false,
            finished: Vec::new(),
            corner_noise: BTreeMap::new(),
            controllers: BTreeMap::new(),
            innovation_scale: BTreeMap::new(),
        })
    }

    /// Tells the tracker the follower's own separation-bearing controller towards the leader
    /// `robot` (gains and current set-points; `None`: not known, the default). From the next
    /// [`update`](Self::update) on, that leader's track filters with the IMM's controlled
    /// model set ([`FormationFilter::set_follower_controller`]; `docs/dukf-reproduction.md`,
    /// measurements 11-13); call it again when a set-point changes. The dual UKF ignores it.
    /// Frames do not carry the controller, so a track is only told what is set here.
    pub fn set_follower_controller(&mut self, robot: u32, controller: Option<ControllerConfig>) {
        match controller {
            Some(c) => {
                self.controllers.insert(robot, c);
            }
            None => {
                self.controllers.remove(&robot);
            }
        }
    }

    /// The follower changed its set-point towards `robot` (its own plan): the formation is
    /// not held until it settles ([`FormationFilter::follower_setpoint_changed`]).
    ///
    /// # Errors
    /// As [`FormationFilter::follower_setpoint_changed`].
    pub fn follower_setpoint_changed(&mut self, robot: u32) -> Result<(), TrackerError> {
        if let Some(track) = self.tracks.get_mut(&robot) {
            for h in std::iter::once(&mut track.main).chain(&mut track.rival) {
                h.filter.follower_setpoint_changed()?;
            }
        }
        Ok(())
    }

    /// Turns recording for [`smooth`](Self::smooth) on or off (off by default). While on,
    /// every filter step of every track is copied into the track's history, which grows by
    /// one [`FilterStep`](crate::filter::FilterStep) (about 500 bytes) per step and leader
    /// until the tracker is dropped. Tracks started while it was off are not recorded.
    pub fn record_history(&mut self, on: bool) {
        self.recording = on;
    }

    /// The fixed-interval smoothed estimates of every recorded track (the dropped ones and
    /// the live ones), one [`SmoothedLeader`] per frame of each, segments in the order they
    /// ended (live tracks last, by robot id). See [`FormationFilter::smooth`] and
    /// `docs/smoothing.md`. Does not change the tracker: call it again after more frames.
    ///
    /// # Errors
    /// [`TrackerError::Filter`] if a segment cannot be smoothed (a recorded covariance that
    /// cannot be repaired, the model refusing a sigma point); nothing is returned then.
    pub fn smooth(&self) -> Result<Vec<SmoothedLeader>, TrackerError> {
        let template = FormationFilter::new(&self.config.filter)?;
        let live = self.tracks.iter().map(|(&robot, track)| Segment {
            robot,
            steps: track.main.history.clone(),
        });
        let mut out = Vec::new();
        for (index, segment) in self.finished.iter().cloned().chain(live).enumerate() {
            if segment.steps.is_empty() {
                continue;
            }
            out.extend(segment.smooth(index, &template)?);
        }
        Ok(out)
    }

    /// Keeps a dropped track's recorded steps for [`smooth`](Self::smooth).
    fn finish(&mut self, robot: u32, track: Track) {
        if !track.main.history.is_empty() {
            self.finished.push(Segment {
                robot,
                steps: track.main.history,
            });
        }
    }

    /// The configuration.
    pub fn config(&self) -> &TrackerConfig {
        &self.config
    }

    /// Robot ids with a live track, ascending.
    pub fn robots(&self) -> impl Iterator<Item = u32> + '_ {
        self.tracks.keys().copied()
    }

    /// Processes one frame.
    ///
    /// # Errors
    /// A bad frame (see the module documentation); the tracker is then unchanged.
    pub fn update(&mut self, frame: &FrameInput) -> Result<FrameReport, TrackerError> {
        let t = frame.t;
        self.check_frame(frame)?;
        // Each track's filters take the follower's controller towards its leader, as told.
        for (robot, track) in &mut self.tracks {
            let controller = self.controllers.get(robot).copied();
            for h in std::iter::once(&mut track.main).chain(&mut track.rival) {
                h.filter.set_follower_controller(controller)?;
            }
        }
        let dt = self.config.filter.dt;
        let steps = match self.last_t {
            Some(prev) => (((t - prev) / dt).round() as u64).max(1),
            None => 1,
        };
        self.last_t = Some(t);
        let u = frame.follower;

        let mut seen: BTreeMap<u32, &Observation> = BTreeMap::new();
        for obs in &frame.observations {
            seen.entry(obs.robot).or_insert(obs);
        }
        let mut robots: Vec<u32> = self.tracks.keys().copied().collect();
        robots.extend(
            seen.keys()
                .copied()
                .filter(|r| !self.tracks.contains_key(r)),
        );
        robots.sort_unstable();

        if self.config.corner_sigma_px.is_none() {
            for (&robot, obs) in &seen {
                let fit = match &obs.pose {
                    PoseMeasurement::Chosen(e) | PoseMeasurement::Candidates([e, _]) => {
                        FitResidual {
                            rms_px: e.rms,
                            parameters: 6,
                        }
                    }
                    PoseMeasurement::Formation(f)
                    | PoseMeasurement::FormationCandidates([f, _]) => match f.fit {
                        Some(fit) => fit,
                        None => continue,
                    },
                };
                let c = &self.config;
                let prior =
                    pose::ResidualPool::new(c.corner_noise_prior_px, c.corner_noise_prior_dof);
                self.corner_noise.entry(robot).or_insert(prior).add(
                    fit.rms_px,
                    obs.points,
                    fit.parameters,
                    self.config.corner_noise_memory_dof,
                );
            }
        }
        let mut leaders = Vec::with_capacity(robots.len());
        for robot in robots {
            let formed = seen.get(&robot).map(|m| self.measurements(m, &frame.mount));
            let report = match self.tracks.remove(&robot) {
                None => match formed {
                    Some(Ok(list)) => self.start(robot, t, &list, None),
                    Some(Err(_)) | None => None,
                },
                Some(track) => Some(self.advance(robot, track, t, steps, u, formed)),
            };
            if let Some(r) = report {
                leaders.push(r);
            }
        }
        Ok(FrameReport { t, leaders })
    }

    fn check_frame(&self, frame: &FrameInput) -> Result<(), TrackerError> {
        let t = frame.t;
        let non_finite = |what, value: f64| TrackerError::NonFinite { what, value, t };
        if !t.is_finite() {
            return Err(non_finite("t", t));
        }
        if !frame.follower.v.is_finite() {
            return Err(non_finite("v2", frame.follower.v));
        }
        if !frame.follower.w.is_finite() {
            return Err(non_finite("w2", frame.follower.w));
        }
        if !frame.mount.is_finite() {
            return Err(non_finite("camera mount", f64::NAN));
        }
        if (frame.mount.offset - self.config.filter.d).abs() > 1e-9 {
            return Err(TrackerError::MountOffsetMismatch {
                mount: frame.mount.offset,
                filter: self.config.filter.d,
            });
        }
        if let Some(previous) = self.last_t
            && t <= previous
        {
            return Err(TrackerError::TimeNotIncreasing { previous, t });
        }
        Ok(())
    }

    /// The measurement's candidates as formation variables with covariance (floor added).
    fn measurements(
        &self,
        obs: &Observation,
        mount: &CameraMount,
    ) -> Result<Vec<Formed>, MeasurementError> {
        let m = &obs.pose;
        let points = obs.points;
        let floor = self.config.measurement_floor_std;
        let floor = Matrix3::from_diagonal(&Vector3::new(
            floor[0] * floor[0],
            floor[1] * floor[1],
            floor[2] * floor[2],
        ));
        let form = |e: &pose::Estimate, candidate| -> Result<Formed, MeasurementError> {
            let fit = FitResidual {
                rms_px: e.rms,
                parameters: 6,
            };
            let covariance = e.covariance * self.noise_scale(&fit, points, obs.robot);
            let (y, r) = formation_of_pose(&e.pose.to_params(), &covariance, mount)?;
            let r = (r + floor + self.distance_floor(y[0])) * self.innovation_scale(obs.robot);

            if !r.iter().all(|v| v.is_finite()) {
                return Err(MeasurementError::NonFinite {
                    what: "measurement covariance",
                });
            }
            Ok(Formed { y, r, candidate })
        };
        let given = |f: &FormationMeasurement, candidate| -> Result<Formed, MeasurementError> {
            if !f.y.iter().chain(f.r.iter()).all(|v| v.is_finite()) {
                return Err(MeasurementError::NonFinite {
                    what: "formation measurement",
                });
            }
            if f.y[0] < MIN_L12 {
                return Err(MeasurementError::Coincident { l12: f.y[0] });
            }
            let y = MEASUREMENT_SPACE.normalize(&f.y);
            // A joint or ground-plane fit is rescaled only to the pooled corner noise (a fixed
            // `corner_sigma_px` stands for single faces' 2-dof estimates).
            let scale = match (self.config.corner_sigma_px, f.fit) {
                (None, Some(fit)) => self.noise_scale(&fit, points, obs.robot),
                _ => 1.0,
            };
            let r = ((f.r + f.r.transpose()) * (0.5 * scale) + floor + self.distance_floor(y[0]))
                * self.innovation_scale(obs.robot);
            Ok(Formed { y, r, candidate })
        };
        let pair = |first: Result<Formed, MeasurementError>,
                    second: Result<Formed, MeasurementError>| {
            // An unusable alternative does not spoil a usable best candidate.
            match (first, second) {
                (Ok(x), Ok(y)) => Ok(vec![x, y]),
                (Ok(x), Err(_)) => Ok(vec![x]),
                (Err(_), Ok(y)) => Ok(vec![y]),
                (Err(e), Err(_)) => Err(e),
            }
        };
        match m {
            PoseMeasurement::Chosen(e) => Ok(vec![form(e, None)?]),
            PoseMeasurement::Candidates([a, b]) => pair(form(a, Some(0)), form(b, Some(1))),
            PoseMeasurement::Formation(f) => Ok(vec![given(f, None)?]),
            PoseMeasurement::FormationCandidates([a, b]) => {
                pair(given(a, Some(0)), given(b, Some(1)))
            }
        }
    }

    /// The variance added to `l12`'s for errors the residuals cannot see
    /// ([`TrackerConfig::relative_distance_std`]).
    fn distance_floor(&self, l12: f64) -> Matrix3<f64> {
        let mut m = Matrix3::zeros();
        m[(0, 0)] = (self.config.relative_distance_std * l12).powi(2);
        m
    }

    /// The factor on `robot`'s `R` from its recent innovations ([`INITIAL_INNOVATION_SCALE`]
    /// before any).
    fn innovation_scale(&self, robot: u32) -> f64 {
        if self.config.innovation_memory <= 0.0 {
            return 1.0;
        }
        self.innovation_scale
            .get(&robot)
            .map_or(INITIAL_INNOVATION_SCALE.0, dukf::NoiseScale::factor)
    }

    /// Moves `robot`'s factor on `R` towards what the latest tested measurement's `d^2`
    /// (capped at the gate, 3 degrees of freedom) calls for ([`dukf::NoiseScale`]): up when
    /// the innovations are larger than the prediction and `R` together say (errors the fit
    /// residuals cannot see, such as corner errors shared by a face's corners), down when
    /// they are not.
    fn learn_innovation_scale(&mut self, robot: u32, d2: f64) {
        let memory = self.config.innovation_memory;
        if memory <= 0.0 {
            return;
        }
        let ([min, max], (initial, prior)) = (INNOVATION_SCALE_RANGE, INITIAL_INNOVATION_SCALE);
        self.innovation_scale
            .entry(robot)
            .or_insert_with(|| dukf::NoiseScale::new(initial, memory, min, max).with_prior(prior))
            .learn(d2, self.config.gate, 3.0);
    }

    /// The gate of [`TrackerConfig::gate`] and [`TrackerConfig::restart_after_gated`]: a
    /// refusal counts towards a restart when it lies beyond four times the gate of every
    /// model (one just outside is more likely an unlucky measurement than a leader every
    /// model has lost), and five times as many refusals in a row restart the track however
    /// near the gate they lay.
    fn gate(&self) -> dukf::Gate {
        dukf::Gate {
            threshold: self.config.gate,
            restart_after: self.config.restart_after_gated,
            far_factor: 4.0,
            persistent_factor: 5,
        }
    }

    /// The factor that takes a covariance scaled by `pose`'s one-solve noise estimate (from
    /// `fit` over `points` correspondences) to the corner noise of
    /// [`TrackerConfig::corner_sigma_px`], or when that is `None` to the pooled corner noise
    /// of `robot`'s recent solves; 1 when `points` leaves no residual degree of freedom (the
    /// solver's scaling cannot be undone) or nothing is known.
    fn noise_scale(&self, fit: &FitResidual, points: usize, robot: u32) -> f64 {
        let variance = match self.config.corner_sigma_px {
            Some(sigma) => sigma * sigma,
            None => match self.corner_noise.get(&robot) {
                Some(pool) => pool.variance(),
                None => return 1.0,
            },
        };
        let floor = self.config.solver_min_pixel_sigma;
        pose::rescale_factor(variance, fit.rms_px, points, fit.parameters, floor)
    }

    /// A new track from the measurement: the first candidate (`best`) as the main
    /// hypothesis and, for a single face, the other candidate as a rival until
    /// `confirm_time` has passed (see the module documentation).
    fn start(
        &mut self,
        robot: u32,
        t: f64,
        list: &[Formed],
        velocity: Option<Inputs>,
    ) -> Option<LeaderReport> {
        let m = list.first()?;
        let recording = self.recording;
        let main = Hypothesis::new(self.filter_from(m, velocity)?, t, recording);
        let rival = list
            .get(1)
            .filter(|_| self.config.confirm_time > 0.0)
            .and_then(|r| self.filter_from(r, velocity))
            .map(|f| Hypothesis::new(f, t, recording));
        let track = Track {
            main,
            rival,
            confirm_until: t + self.config.confirm_time,
            last_seen: t,
        };
        let report = report(
            robot,
            &track,
            t,
            Status::Tracking,
            MeasurementUse::Initialised,
        )
        .with(m.candidate, None);
        self.tracks.insert(robot, track);
        Some(report)
    }

    /// A filter initialised from one measurement, with the leader-velocity prior's mean
    /// `velocity` (a restarted track keeps its last estimate, with the prior's spread) or
    /// the template's `w0`.
    fn filter_from(&self, m: &Formed, velocity: Option<Inputs>) -> Option<FormationFilter> {
        let s = self.config.world_pose_prior_std;
        let mut config = self.config.filter.started_at(&m.y, &m.r, s).ok()?;
        if let Some(w) = velocity {
            config.tuning.w0 = w.into();
        }
        FormationFilter::new(&config).ok()
    }

    /// Advances an existing track over `steps` filter steps to time `t`.
    fn advance(
        &mut self,
        robot: u32,
        mut track: Track,
        t: f64,
        steps: u64,
        u: Inputs,
        formed: Option<Result<Vec<Formed>, MeasurementError>>,
    ) -> LeaderReport {
        let waited = t - track.last_seen;
        if waited > self.config.lost_after {
            // Too long unseen: dropped. A measurement in this very frame starts a new track.
            let lost = report(robot, &track, t, Status::Lost, MeasurementUse::Missing)
                .lost(LostReason::Timeout);
            self.finish(robot, track);
            if let Some(Ok(list)) = &formed
                && let Some(r) = self.start(robot, t, list, None)
            {
                return r;
            }
            return lost;
        }
        let formed = formed.as_ref();
        let main = self.run(&mut track.main, t, steps, u, formed);
        let rival = match track.rival.take() {
            Some(mut h) => self.run(&mut h, t, steps, u, formed).ok().map(|o| (h, o)),
            None => None,
        };
        let mut outcome = match (main, rival) {
            (Ok(o), None) => o,
            (Ok(o), Some((h, ro))) => {
                if h.score + SWITCH_MARGIN < track.main.score {
                    // The rival explains the measurements better: it becomes the main.
                    track.rival = Some(std::mem::replace(&mut track.main, h));
                    ro
                } else {
                    track.rival = Some(h);
                    o
                }
            }
            (Err(_), Some((h, ro))) => {
                track.main = h;
                ro
            }
            (Err(_), None) => {
                let lost = report(robot, &track, t, Status::Lost, MeasurementUse::Missing)
                    .lost(LostReason::FilterFailed);
                self.finish(robot, track);
                return lost;
            }
        };
        // A measurement refused once is most likely an outlier and does not teach `R`; one
        // refused again right after it does (capped at the gate).
        if let Some((_, d2)) = outcome.chosen
            && (outcome.usage == MeasurementUse::Updated
                || (outcome.usage == MeasurementUse::Gated && track.main.runs.refused > 1))
        {
            self.learn_innovation_scale(robot, d2);
        }
        if outcome.usage == MeasurementUse::Gated
            && self.gate().restart_due(&track.main.runs)
            && let Some(Ok(list)) = formed
            && let Some(restarted) =
                self.start(robot, t, list, Some(track.main.filter.leader_velocity()))
        {
            // Refused again and again: no model of the filter follows what the leader did.
            // The track restarts from this measurement; the old one's steps are kept as a
            // finished segment.
            self.finish(robot, track);
            return restarted;
        }
        if t >= track.confirm_until {
            track.rival = None;
        }
        let status = if outcome.usage == MeasurementUse::Updated {
            track.last_seen = t;
            Status::Tracking
        } else {
            Status::Coasting
        };
        if outcome.usage == MeasurementUse::Missing {
            outcome.chosen = None;
        }
        let out = report(robot, &track, t, status, outcome.usage).with(
            outcome.chosen.and_then(|(m, _)| m.candidate),
            outcome.chosen.map(|(_, n)| n),
        );
        self.tracks.insert(robot, track);
        out
    }

    /// One hypothesis over the frame: predict over the gap, choose, gate, update or coast,
    /// and add the (capped) `d^2` of the chosen candidate to its score.
    fn run(
        &self,
        h: &mut Hypothesis,
        t: f64,
        steps: u64,
        u: Inputs,
        formed: Option<&Result<Vec<Formed>, MeasurementError>>,
    ) -> Result<Outcome, FilterError> {
        for _ in 1..steps {
            h.filter.predict_only(u)?;
            if self.recording {
                h.history.push(Recorded {
                    frame: None,
                    step: h.filter.record(u, None),
                });
            }
        }
        let (chosen, usage) = match formed {
            None => (None, MeasurementUse::Missing),
            Some(Err(_)) => (None, MeasurementUse::Invalid),
            Some(Ok(list)) => match self.choose(&h.filter, u, list) {
                Some((m, nis, model_d2)) => {
                    if self.gate().judge(&mut h.runs, nis, model_d2) {
                        (Some((m, nis)), MeasurementUse::Updated)
                    } else {
                        (Some((m, nis)), MeasurementUse::Gated)
                    }
                }
                None => (None, MeasurementUse::Invalid),
            },
        };
        let applied = match (usage, chosen) {
            (MeasurementUse::Updated, Some((m, _))) => {
                h.filter.step(&m.y, &m.r, u)?;
                Some((m.y, m.r))
            }
            _ => {
                h.filter.predict_only(u)?;
                None
            }
        };
        if self.recording {
            h.history.push(Recorded {
                frame: Some(t),
                step: h.filter.record(u, applied),
            });
        }
        if let Some((_, nis)) = chosen {
            h.score += nis.min(self.config.gate);
        }
        Ok(Outcome { usage, chosen })
    }

    /// The candidate nearest the filter's one-step prediction, with its `d^2` against that
    /// prediction and the smallest `d^2` against one IMM model's own prediction
    /// ([`crate::filter::Predicted`]), which the gate takes after a refusal.
    fn choose(
        &self,
        filter: &FormationFilter,
        u: Inputs,
        list: &[Formed],
    ) -> Option<(Formed, f64, f64)> {
        let predicted = filter.predicted(u).ok()?;
        let (m, d2) = list
            .iter()
            .take(2)
            .filter_map(|m| predicted.nis(&m.y, &m.r).map(|d2| (*m, d2)))
            .min_by(|a, b| a.1.total_cmp(&b.1))?;
        Some((m, d2, predicted.best_model_nis(&m.y, &m.r, d2)))
    }
}

fn report(
    robot: u32,
    track: &Track,
    t: f64,
    status: Status,
    measurement: MeasurementUse,
) -> LeaderReport {
    let filter = &track.main.filter;
    let f = filter.formation();
    let fs = filter.formation_std();
    let w = filter.leader_velocity();
    let ws: Vector2<f64> = filter.leader_velocity_std();
    LeaderReport {
        robot,
        status,
        measurement,
        lost: None,
        hypotheses: if track.rival.is_some() { 2 } else { 1 },
        candidate: None,
        nis: None,
        formation: f,
        v1: w.v,
        w1: w.w,
        l12_std: fs[0],
        alpha12_std: fs[1],
        beta12_std: fs[2],
        v1_std: ws[0],
        w1_std: ws[1],
        covariance: filter.estimate_covariance().transpose().into(),
        since_seen: t - track.last_seen,
    }
}

impl LeaderReport {
    fn lost(mut self, reason: LostReason) -> Self {
        self.lost = Some(reason);
        self
    }

    fn with(mut self, candidate: Option<u8>, nis: Option<f64>) -> Self {
        self.candidate = candidate;
        self.nis = nis;
        self
    }
}
