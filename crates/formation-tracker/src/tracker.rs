//! Tracking leaders over time: one dual UKF per leader robot, fed per-frame pose
//! measurements, with coasting, loss, re-acquisition, planar-ambiguity resolution and gating.
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
//!    measurement transform of spec 2.5 ([`crate::mount::formation_from_camera_pose`]); its
//!    6x6 pose covariance is propagated to `(l12, alpha12, beta12)` by
//!    [`crate::mount::propagate_covariance`], and a floor variance
//!    ([`TrackerConfig::measurement_floor_std`]) is **added** to the diagonal. The pose
//!    covariance only knows pixel noise (at least `pose`'s 0.1 px floor); corner bias,
//!    calibration and mount errors are not in it, and a near-zero `R` would make the filter
//!    trust one frame completely. Adding (rather than clamping) keeps `R` positive definite
//!    even when the Jacobian is rank-deficient.
//! 2. **Prediction.** The track's filter is predicted over the frame gap (see *Time*) on a
//!    copy, giving the predicted measurement `y-` and its variances `diag(P-)`.
//! 3. **Candidate choice.** With two planar candidates, the one with the smaller
//!    Mahalanobis distance `d^2 = nu^T (diag(P-) + R_i)^-1 nu` (innovation `nu = y_i - y-`,
//!    angles wrapped) is used: the track's prediction, not the reprojection RMS, decides, so
//!    a frame where the flipped pose happens to reproject better does not flip the estimate.
//!    Only the diagonal of `P-` is used (the filter exposes standard deviations); the
//!    off-diagonal terms are small next to `R` for these three variables.
//! 4. **Gating.** The chosen measurement is applied only if `d^2 <=`
//!    [`TrackerConfig::gate`] (default 16.27, the 99.9 % point of a chi-square with 3
//!    degrees of freedom). A gated measurement leaves the track coasting for this frame.
//!    Consistent rejection therefore ends in loss and re-initialisation after
//!    [`TrackerConfig::lost_after`], which is how a diverged track recovers.
//! 5. **Update or coast.** Accepted: a dual-UKF step with `R`; status `tracking`. Not seen,
//!    gated or invalid: a predict-only step (the covariance grows); status `coasting`.
//!    When the time since the last accepted measurement exceeds `lost_after` (default 2 s)
//!    the leader is reported once as `lost` (its last estimate) and its track is dropped.
//!    A robot seen again after that gets a new track under its own id, initialised from the
//!    measurement.
//!
//! # Initialisation
//! A new track's formation variables are the first measurement; their covariance is that
//! measurement's `R` (floor included). The leader's world pose `(x1, y1, theta1)` is not
//! observable from `(l12, alpha12, beta12)` and the model does not need it; it is placed as
//! if the follower stood at the origin at that instant, with a loose
//! [`TrackerConfig::world_pose_prior_std`] (0.1). The leader's velocity prior is the
//! filter template's `w0`, `Pw0`: by default the paper's `[0, 0]` and `I` (nothing is known
//! about how the leader moves; 1 m/s and 1 rad/s standard deviations). With two candidates
//! and no track yet, the one with the lower RMS (`best`) is taken: nothing else can decide.
//! A wrong start then shows up as a track whose innovations keep being gated and is replaced
//! after `lost_after` (a known limitation: a wrong start that stays self-consistent is kept).
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

use std::collections::BTreeMap;

use nalgebra::{Matrix3, Rotation3, SMatrix, SVector, Vector2, Vector3};
use serde::Serialize;
use unicycle::{Formation, Inputs, PolarState, wrap_angle};

use crate::filter::{FilterConfig, FilterError, FormationFilter};
use crate::mount::{
    CameraMount, MeasurementError, formation_from_camera_pose, propagate_covariance,
};

/// The 99.9 % point of a chi-square distribution with 3 degrees of freedom.
pub const CHI2_3_999: f64 = 16.266;

/// Errors of the tracker: bad frames and bad configurations. A failed call leaves the tracker
/// unchanged.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TrackerError {
    /// A frame-level number is NaN or infinite.
    #[error("non-finite {what} = {value} in frame at t = {t} s")]
    NonFinite {
        /// Which input: `"t"`, `"v2"`, `"w2"`, `"camera mount"`.
        what: &'static str,
        /// The offending value.
        value: f64,
        /// The frame time.
        t: f64,
    },
    /// Frame times must increase.
    #[error("frame time t = {t} s does not follow the previous frame's {previous} s")]
    TimeNotIncreasing {
        /// The previous frame's time.
        previous: f64,
        /// This frame's time.
        t: f64,
    },
    /// The frame's camera offset differs from the filter's `d`.
    #[error("camera mount offset {mount} m differs from the filter's d = {filter} m")]
    MountOffsetMismatch {
        /// The mount's offset.
        mount: f64,
        /// The filter template's `d`.
        filter: f64,
    },
    /// A configuration value is out of range.
    #[error("tracker configuration: {what} = {value} must be {expected}")]
    InvalidConfig {
        /// Which setting.
        what: &'static str,
        /// Its value.
        value: f64,
        /// What it must be.
        expected: &'static str,
    },
    /// The filter template is unusable (checked at construction).
    #[error(transparent)]
    Filter(#[from] FilterError),
}

/// Tracker settings. [`TrackerConfig::reference`] gives the documented defaults.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackerConfig {
    /// Template of every track's filter: `d`, `dt`, `Q`, `Rr`, `w0`, `Pw0`, unscented
    /// parameters. Its `x0` and `p0` are replaced at each track's initialisation.
    pub filter: FilterConfig,
    /// Seconds without an accepted measurement after which a track is `lost`. Default 2 s.
    pub lost_after: f64,
    /// Mahalanobis gate `d^2` on `(l12, alpha12, beta12)`. Default [`CHI2_3_999`];
    /// `f64::INFINITY` disables gating.
    pub gate: f64,
    /// Standard deviations `[m, rad, rad]` whose squares are added to the propagated
    /// measurement covariance. Default `[0.005, 0.005, 0.005]`.
    pub measurement_floor_std: [f64; 3],
    /// Standard deviation of the leader's world pose `(x1, y1, theta1)` at initialisation
    /// (unobservable, carried along). Default 0.1.
    pub world_pose_prior_std: f64,
}

impl TrackerConfig {
    /// The defaults: the filter of the reference scenario (`FilterConfig::reference(d, dt)`:
    /// its `Q`, `Rr`, velocity prior `w0 = [0, 0]`, `Pw0 = I`), `lost_after = 2 s`, gate
    /// 16.27, measurement floor 5 mm / 5 mrad, world-pose prior 0.1.
    pub fn reference(d: f64, dt: f64) -> Self {
        Self {
            filter: FilterConfig::reference(d, dt),
            lost_after: 2.0,
            gate: CHI2_3_999,
            measurement_floor_std: [0.005, 0.005, 0.005],
            world_pose_prior_std: 0.1,
        }
    }

    fn validate(&self) -> Result<(), TrackerError> {
        let positive = |what, value: f64| {
            if value.is_finite() && value > 0.0 {
                Ok(())
            } else {
                Err(TrackerError::InvalidConfig {
                    what,
                    value,
                    expected: "finite and positive",
                })
            }
        };
        positive("lost_after", self.lost_after)?;
        positive("world_pose_prior_std", self.world_pose_prior_std)?;
        for s in self.measurement_floor_std {
            positive("measurement_floor_std", s)?;
        }
        if self.gate.is_nan() || self.gate <= 0.0 {
            return Err(TrackerError::InvalidConfig {
                what: "gate",
                value: self.gate,
                expected: "positive (infinity disables gating)",
            });
        }
        // Builds one filter to check the template (dt, d, covariances).
        FormationFilter::new(&self.filter)?;
        Ok(())
    }
}

/// What the vision pipeline measured of one robot in one frame.
// Kept unboxed: one measurement per robot per frame, and boxing would allocate for each.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PoseMeasurement {
    /// One pose (e.g. a joint pose over several faces, which has no planar ambiguity).
    Chosen(pose::Estimate),
    /// A single face: both planar candidates, lowest reprojection RMS first.
    Candidates([pose::Estimate; 2]),
}

/// One robot seen in one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observation {
    /// The robot's id (from its markers' codes, see [`crate::rig::robot_face`]).
    pub robot: u32,
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
    /// Which planar candidate was used (0 = `best`, 1 = the alternative); `None` without
    /// candidates.
    pub candidate: Option<u8>,
    /// Mahalanobis distance squared of the used (or gated) measurement, if any.
    pub nis: Option<f64>,
    /// Estimated separation, m.
    pub l12: f64,
    /// Estimated bearing in the leader's frame, rad.
    pub alpha12: f64,
    /// Estimated bearing in the follower's frame, rad.
    pub beta12: f64,
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

#[derive(Debug, Clone)]
struct Track {
    filter: FormationFilter,
    last_seen: f64,
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
        })
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
        let dt = self.config.filter.dt;
        let steps = match self.last_t {
            Some(prev) => (((t - prev) / dt).round() as u64).max(1),
            None => 1,
        };
        self.last_t = Some(t);
        let u = frame.follower;

        let mut seen: BTreeMap<u32, &PoseMeasurement> = BTreeMap::new();
        for obs in &frame.observations {
            seen.entry(obs.robot).or_insert(&obs.pose);
        }
        let mut robots: Vec<u32> = self.tracks.keys().copied().collect();
        robots.extend(
            seen.keys()
                .copied()
                .filter(|r| !self.tracks.contains_key(r)),
        );
        robots.sort_unstable();

        let mut leaders = Vec::with_capacity(robots.len());
        for robot in robots {
            let formed = seen.get(&robot).map(|m| self.measurements(m, &frame.mount));
            let report = match self.tracks.remove(&robot) {
                None => match formed {
                    Some(Ok(list)) => self.start(robot, t, &list),
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
        m: &PoseMeasurement,
        mount: &CameraMount,
    ) -> Result<Vec<Formed>, MeasurementError> {
        let floor = self.config.measurement_floor_std;
        let floor = Matrix3::from_diagonal(&Vector3::new(
            floor[0] * floor[0],
            floor[1] * floor[1],
            floor[2] * floor[2],
        ));
        let form = |e: &pose::Estimate, candidate| -> Result<Formed, MeasurementError> {
            let params = e.pose.to_params();
            let to_formation = |p: &SVector<f64, 6>| {
                let rot = Rotation3::new(Vector3::new(p[0], p[1], p[2]));
                formation_from_camera_pose(&rot, &Vector3::new(p[3], p[4], p[5]), mount)
            };
            let y = to_formation(&params)?;
            let r = propagate_covariance(&params, &e.covariance, to_formation)? + floor;
            if !r.iter().all(|v| v.is_finite()) {
                return Err(MeasurementError::NonFinite {
                    what: "measurement covariance",
                });
            }
            Ok(Formed { y, r, candidate })
        };
        match m {
            PoseMeasurement::Chosen(e) => Ok(vec![form(e, None)?]),
            PoseMeasurement::Candidates([a, b]) => {
                // An unusable alternative does not spoil a usable best candidate.
                let first = form(a, Some(0));
                let second = form(b, Some(1));
                match (first, second) {
                    (Ok(x), Ok(y)) => Ok(vec![x, y]),
                    (Ok(x), Err(_)) => Ok(vec![x]),
                    (Err(_), Ok(y)) => Ok(vec![y]),
                    (Err(e), Err(_)) => Err(e),
                }
            }
        }
    }

    /// A new track from the first usable candidate (the best one; see the module docs).
    fn start(&mut self, robot: u32, t: f64, list: &[Formed]) -> Option<LeaderReport> {
        let m = list.first()?;
        let d = self.config.filter.d;
        let formation = Formation::from_vector(&m.y);
        let world = formation
            .leader_pose(&unicycle::Pose::new(0.0, 0.0, 0.0), d)
            .ok()?;
        let mut cfg = self.config.filter.clone();
        cfg.x0 = PolarState::new(world.x, world.y, world.theta, m.y[0], m.y[1], m.y[2]);
        let s = self.config.world_pose_prior_std;
        let mut p0 = SMatrix::<f64, 6, 6>::zeros();
        p0.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&Matrix3::from_diagonal_element(s * s));
        p0.fixed_view_mut::<3, 3>(3, 3).copy_from(&m.r);
        cfg.p0 = p0;
        let filter = FormationFilter::new(&cfg).ok()?;
        let track = Track {
            filter,
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
        let lost = |track: &Track| report(robot, track, t, Status::Lost, MeasurementUse::Missing);
        let waited = t - track.last_seen;
        if waited > self.config.lost_after {
            // Too long unseen: dropped. A measurement in this very frame starts a new track.
            if let Some(Ok(list)) = &formed
                && let Some(r) = self.start(robot, t, list)
            {
                return r;
            }
            return lost(&track);
        }
        for _ in 1..steps {
            if track.filter.predict_only(u).is_err() {
                return lost(&track);
            }
        }
        let (chosen, usage) = match formed {
            None => (None, MeasurementUse::Missing),
            Some(Err(_)) => (None, MeasurementUse::Invalid),
            Some(Ok(list)) => match self.choose(&track, u, &list) {
                Some((m, nis)) if nis <= self.config.gate => {
                    (Some((m, nis)), MeasurementUse::Updated)
                }
                Some((m, nis)) => (Some((m, nis)), MeasurementUse::Gated),
                None => (None, MeasurementUse::Invalid),
            },
        };
        let result = match (usage, chosen) {
            (MeasurementUse::Updated, Some((m, _))) => track.filter.step(&m.y, &m.r, u),
            _ => track.filter.predict_only(u),
        };
        if result.is_err() {
            return lost(&track);
        }
        let status = if usage == MeasurementUse::Updated {
            track.last_seen = t;
            Status::Tracking
        } else {
            Status::Coasting
        };
        let out = report(robot, &track, t, status, usage).with(
            chosen.and_then(|(m, _)| m.candidate),
            chosen.map(|(_, n)| n),
        );
        self.tracks.insert(robot, track);
        out
    }

    /// The candidate nearest the track's one-step prediction, with its `d^2`.
    fn choose(&self, track: &Track, u: Inputs, list: &[Formed]) -> Option<(Formed, f64)> {
        let mut predicted = track.filter.clone();
        predicted.predict_only(u).ok()?;
        let y_pred = predicted.formation().to_vector();
        let var = predicted.formation_std().map(|s| s * s);
        list.iter()
            .filter_map(|m| {
                let nu = Vector3::new(
                    m.y[0] - y_pred[0],
                    wrap_angle(m.y[1] - y_pred[1]),
                    wrap_angle(m.y[2] - y_pred[2]),
                );
                let s = Matrix3::from_diagonal(&var) + m.r;
                let d2 = s.cholesky()?.solve(&nu).dot(&nu);
                d2.is_finite().then_some((*m, d2))
            })
            .min_by(|a, b| a.1.total_cmp(&b.1))
    }
}

fn report(
    robot: u32,
    track: &Track,
    t: f64,
    status: Status,
    measurement: MeasurementUse,
) -> LeaderReport {
    let f = track.filter.formation();
    let fs = track.filter.formation_std();
    let w = track.filter.leader_velocity();
    let ws: Vector2<f64> = track.filter.leader_velocity_std();
    LeaderReport {
        robot,
        status,
        measurement,
        candidate: None,
        nis: None,
        l12: f.l12,
        alpha12: f.alpha12,
        beta12: f.beta12,
        v1: w.v,
        w1: w.w,
        l12_std: fs[0],
        alpha12_std: fs[1],
        beta12_std: fs[2],
        v1_std: ws[0],
        w1_std: ws[1],
        since_seen: t - track.last_seen,
    }
}

impl LeaderReport {
    fn with(mut self, candidate: Option<u8>, nis: Option<f64>) -> Self {
        self.candidate = candidate;
        self.nis = nis;
        self
    }
}
