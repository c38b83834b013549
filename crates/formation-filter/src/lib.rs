//! The formation filter over the unicycle polar model (spec 2.4, crate `unicycle`): the
//! paper's dual UKF (spec 5, the default of [`FilterTuning::reference`]) or, selected with
//! [`FilterTuning::design`], an interacting multiple-model (IMM) filter of three unscented
//! filters (crate `dukf`).
//!
//! The IMM is better on every reference figure (`docs/dukf-reproduction.md`) and is what
//! `reproduce dukf` (told the follower's controller) and the tracker (`TrackerConfig::reference`;
//! told the controller only through `Tracker::set_follower_controller`) run; the offline smoother
//! ([`FormationFilter::smooth`]) follows the design that recorded the history.
//!
//! [`FormationFilter`] is the piece the tracker reuses per leader. It is fed the measurement
//! `y = [l12, alpha12, beta12]` and the follower's own inputs `u = [v2, w2]`, and estimates
//! the state `x = [x1, y1, theta1, l12, alpha12, beta12]` and the leader's velocities
//! `[v1, w1]`.
//!
//! # The IMM design
//! The three models share the joint state `z = [x, v1, w1, a_v, a_w]` (the leader's
//! accelerations included), so they mix exactly (Blom and Bar-Shalom; `dukf::Imm`):
//! - **A, the leader accelerates**: `[v1, w1]` move with `[a_v, a_w]`, which are a random walk
//!   of per-step standard deviation `jerk * dt` ([`LeaderMotionTuning::jerk`], the leader's largest
//!   jerk: a property of the robot, not of a scenario).
//! - **B, the follower holds the formation**: the leader velocity is the one that keeps
//!   `l12` and `alpha12` constant given the follower's known inputs
//!   ([`unicycle::formation_holding_velocity`]); the held variables drift by a small random walk
//!   ([`LeaderMotionTuning::held_rate_std`]). `beta12` is still predicted through the model.
//! - **C, the follower holds the bearing**: model A's speed, and the turn rate that keeps
//!   `alpha12` constant ([`unicycle::bearing_holding_turn_rate`]): the follower changes its separation
//!   (a set-point step) while holding the bearing. A follower that changes its own
//!   set-point says so ([`FormationFilter::follower_setpoint_changed`]): B's probability
//!   goes to C, since the formation is not held until it settles.
//!
//! The switching matrix has one constant, the mean time a model stays in force
//! ([`LeaderMotionTuning::sojourn`], `Pi_jj = exp(-dt / sojourn)`).
//!
//! **A manoeuvre hypothesis J** ([`LeaderMotionTuning::jump`], off in the reference tuning)
//! takes C's place: A's motion with velocity jumps of [`unicycle::LeaderJump::velocity_std`]
//! per step, for a leader whose `v1` steps or `w1` flips, which A with a jerk sized for smooth
//! motion follows only slowly and overconfidently. A hands over to J once per
//! [`unicycle::LeaderJump::onset`] seconds on average and J back to A after
//! [`unicycle::LeaderJump::sojourn`]; B switches as before. `docs/dukf-held-out.md` reports
//! it beside the default (issue #30).
//!
//! **With the follower's controller known** ([`FormationFilter::set_follower_controller`], as
//! `reproduce dukf` runs it) the model set changes: B takes the leader velocity under which the
//! formation moves as the controller commands ([`unicycle::controlled_formation_velocity`]), with no held
//! random walk (only the integrator's error, [`LeaderMotionTuning::controlled_formation_q`]); C, which
//! covered set-point changes that B now models, is dropped; and B does not switch out, while A
//! hands over to B at the sojourn rate. Each of these rules removes one cause of the
//! under-confidence measured before (`docs/dukf-reproduction.md`, measurement 12): a held random
//! walk sized for the mismatch the controller now models, a formation noise far above the
//! integrator's error, and wide improbable models dominating the mixture's covariance.

//! # The dual UKF and the parameter uncertainty in its state prediction
//! A state filter over `x` and a parameter filter over `w = [v1, w1]` (a random walk with
//! [`FilterTuning::rr`]). In the plain dual filter the state filter treats `w^` as exact, so
//! while `w^` is still wrong (at the start `w0 = [0, 0]` against a leader at 0.8 m/s) the
//! state filter's covariance is far too small and its estimate drifts with the wrong
//! velocity. With [`FilterTuning::propagate_parameter_uncertainty`] (on in the reference
//! configuration) the state filter's process noise at each step is `Q + J Pw- J^T`, with
//! `J = df/dw` at the current estimate (central differences) and `Pw- = Pw + Rr` the
//! parameter filter's predicted covariance.
//!
//! # The follower's odometry noise
//! The follower's inputs `u` reach the filter as its odometry measured them.
//! [`FilterTuning::input_noise_std`] is that odometry's white-noise standard deviation;
//! each step then adds `G diag(s^2) G^T` to the state's process noise (every IMM model's,
//! and the dual state filter's), with `G = df/du` by central differences at the current
//! estimate and the leader's velocity held. It matters when the camera is precise: at 30 Hz,
//! 0.01 m/s and 0.01 rad/s of odometry noise move the formation by 0.33 mm and 0.33 mrad per
//! step, three times a near vision measurement's error, and a filter that takes the odometry
//! as exact gates good measurements (`tests/odometry_noise.rs`).
//!
//! # Offline smoothing
//! [`FormationFilter::record`] copies the estimates after a step into a [`FilterStep`];
//! [`FormationFilter::smooth`] runs the unscented RTS smoother of `dukf` backwards over such a
//! history, over the state and the leader velocities together (see `smooth.rs` and
//! `docs/smoothing.md`), giving one [`SmoothedStep`] per recorded step. The smoother reruns its
//! own joint forward pass from the first recorded estimate: for the dual UKF over `[x; w]`
//! (leader velocity a random walk with `Q` and `Rr`), for the IMM over its joint state with
//! its models mixed with each step's probabilities.

#![deny(missing_docs)]

mod smooth;

/// This crate's version (`CARGO_PKG_VERSION`), for tools that report what they were built from.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");

use std::cell::Cell;

use dukf::{AngleMask, DualUkf, Euclidean, Imm, Ukf, UkfError, UtParams, sojourn_transition};
use nalgebra::{Matrix2, Matrix3, Matrix5, SMatrix, SVector, Vector2, Vector3};
use unicycle::{
    ControllerConfig, Formation, Inputs, LeaderMotion, LeaderMotionTuning, MEASUREMENT_ANGLES,
    MIN_PREDICTED_SEPARATION, PolarModel, PolarState, STATE_ANGLES, UnicycleError, predict_leader,
};

type Matrix6 = SMatrix<f64, 6, 6>;
type Vector6 = SVector<f64, 6>;
type Dual = DualUkf<6, 2, 3, AngleMask<6>, Euclidean, AngleMask<3>>;
/// The IMM's joint state `[x1, y1, theta1, l12, alpha12, beta12, v1, w1, a_v, a_w]`.
type Joint = SVector<f64, 10>;
type Matrix10 = SMatrix<f64, 10, 10>;
type ImmFilter = Imm<10, 3, AngleMask<10>>;

/// The formation variables `[l12, alpha12, beta12]` as a `dukf` space: the bearings
/// ([`unicycle::MEASUREMENT_ANGLES`]) are angles. The one place their wrapping is defined:
/// the filters, the tracker's gate and the measurement transform all use it.
pub const MEASUREMENT_SPACE: AngleMask<3> = AngleMask::at(&MEASUREMENT_ANGLES);

/// One step of a [`FormationFilter`]'s forward pass, as the smoother needs it: the filtered
/// estimates after the step and the follower inputs applied over it. Recorded with
/// [`FormationFilter::record`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FilterStep {
    /// The follower's inputs `(v2, w2)` applied over the step that ended here (ignored for
    /// the first step of a history).
    pub inputs: Inputs,
    /// The measurement `y = [l12, alpha12, beta12]` applied at this step, with its noise
    /// covariance `R` (`None` for a predict-only step and for the initial estimate).
    pub measurement: Option<(Vector3<f64>, Matrix3<f64>)>,
    /// State estimate `[x1, y1, theta1, l12, alpha12, beta12]`.
    pub state: PolarState,
    /// Its covariance.
    pub state_covariance: Matrix6,
    /// Leader-velocity estimate `[v1, w1]`.
    pub velocity: Vector2<f64>,
    /// Its covariance.
    pub velocity_covariance: Matrix2<f64>,
    /// The IMM's whole mixed estimate over `[x, v1, w1, a_v, a_w]` after the step (`None`
    /// for the dual UKF); the IMM smoother starts from the first step's.
    pub joint: Option<dukf::Gaussian<10>>,
    /// The IMM's model probabilities after the step (`None` for the dual UKF); the IMM
    /// smoother's forward pass mixes the models' transitions with them.
    pub model_probabilities: Option<[f64; 3]>,
    /// The follower's controller the filter was told for the step that ended here
    /// ([`FormationFilter::set_follower_controller`]; `None` if not told): the IMM
    /// smoother's forward pass predicts that step with it, set-point changes included.
    pub controller: Option<ControllerConfig>,
}

/// One smoothed step: the estimate of the state and the leader velocities given the whole
/// recording.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SmoothedStep {
    /// State estimate `[x1, y1, theta1, l12, alpha12, beta12]`.
    pub state: PolarState,
    /// Its covariance.
    pub state_covariance: Matrix6,
    /// Leader velocities `(v1, w1)` over the step that ended here (see the module
    /// documentation).
    pub velocity: Inputs,
    /// Their covariance.
    pub velocity_covariance: Matrix2<f64>,
}

impl SmoothedStep {
    /// The smoothed formation variables.
    pub fn formation(&self) -> Formation {
        Formation::from_vector(&PolarModel::h(&self.state))
    }

    /// Standard deviations of `[l12, alpha12, beta12]`.
    pub fn formation_std(&self) -> Vector3<f64> {
        PolarModel::h(&std_of(&self.state_covariance))
    }

    /// Standard deviations of `(v1, w1)`.
    pub fn velocity_std(&self) -> Vector2<f64> {
        std_of(&self.velocity_covariance)
    }
}

/// Errors of the formation filter.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FilterError {
    /// The dual unscented Kalman filter failed (non-finite input, lost definiteness, ...).
    #[error(transparent)]
    Ukf(#[from] UkfError),
    /// The robot model refused a state or an input (e.g. `l12 <= 0` at a sigma point).
    #[error(transparent)]
    Model(#[from] UnicycleError),
    /// A recorded history was made by a filter of another design than the one asked to
    /// smooth it.
    #[error(
        "the recorded history was made by the {recorded:?} filter but the {smoother:?} filter \
         was asked to smooth it; smooth it with a filter of the design that recorded it"
    )]
    HistoryDesign {
        /// The design that recorded the history.
        recorded: FilterDesign,
        /// The design asked to smooth it.
        smoother: FilterDesign,
    },
    /// The time step is not finite and positive.
    #[error("filter time step dt = {dt} s must be finite and positive")]
    InvalidTimeStep {
        /// The step that was given.
        dt: f64,
    },
    /// A component of [`FilterTuning::input_noise_std`] is negative or not finite.
    #[error("odometry noise input_noise_std[{index}] = {value} must be finite and non-negative")]
    InvalidInputNoise {
        /// 0 for `v2` (m/s), 1 for `w2` (rad/s).
        index: usize,
        /// The value that was given.
        value: f64,
    },
}

/// How a [`FormationFilter`] weighs the model against the measurements: the prior
/// covariances, the leader-velocity prior, the process and random-walk noises and the
/// unscented-transform parameters. It holds no scenario: the initial state is
/// [`FilterConfig::x0`].
#[derive(Debug, Clone, PartialEq)]
pub struct FilterTuning {
    /// Initial state covariance.
    pub p0: Matrix6,
    /// Initial leader-velocity estimate `[v1, w1]`.
    pub w0: Vector2<f64>,
    /// Initial leader-velocity covariance.
    pub pw0: Matrix2<f64>,
    /// State process noise `Q` per step.
    pub q: Matrix6,
    /// Random-walk noise `Rr` of `[v1, w1]` per step.
    pub rr: Matrix2<f64>,
    /// Whether the state prediction adds `J Pw- J^T` (see the module documentation).
    pub propagate_parameter_uncertainty: bool,
    /// Scaled unscented transform parameters, used by every filter.
    pub ut: UtParams,
    /// Which causal filter runs: the paper's dual UKF (the default) or the IMM.
    pub design: FilterDesign,
    /// The IMM's settings (unused by the dual UKF).
    pub imm: LeaderMotionTuning,
    /// Standard deviation `[m/s, rad/s]` of the follower's odometry: the inputs `u` given to
    /// each step are what the wheels executed plus white noise of this size. Each step's
    /// process noise then adds `G diag(s^2) G^T`, with `G = df/du` (central differences at
    /// the current estimate, the leader's velocity held): the formation moves by what the
    /// wheels did, not by what the odometry says. A property of the robot's odometry, like
    /// the camera's corner noise. Default `[0, 0]` (exact odometry, the paper's assumption).
    pub input_noise_std: Vector2<f64>,
}

/// Which causal filter a [`FormationFilter`] runs (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FilterDesign {
    /// The interacting multiple-model filter over the joint state `[x, v1, w1, a_v, a_w]`:
    /// a constant-acceleration leader and a follower holding the formation.
    Imm,
    /// The paper's dual UKF: a state filter over `x` and a parameter filter over `[v1, w1]`
    /// (a random walk with [`FilterTuning::rr`]).
    Dual,
}

impl FilterTuning {
    /// The reference tuning (see `docs/reference-scenario.md` for the rationale of each
    /// number): `w0 = [0, 0]`, `Pw0 = I`;
    /// `P0 = diag(0.1^2, 0.1^2, 0.1^2, 0.07^2, 0.03^2, 0.03^2)` (the measurement noise on the
    /// measured components); `Q = diag(1e-6, 1e-6, 1e-6, 1e-7, 1e-5, 1e-5)`;
    /// `Rr = diag(1e-4, 1e-4)`; parameter uncertainty propagated; `alpha = 1, beta = 2,
    /// kappa = 0`.
    pub fn reference() -> Self {
        Self {
            p0: Matrix6::from_diagonal(&Vector6::new(0.01, 0.01, 0.01, 0.0049, 0.0009, 0.0009)),
            w0: Vector2::zeros(),
            pw0: Matrix2::identity(),
            q: Matrix6::from_diagonal(&Vector6::new(1e-6, 1e-6, 1e-6, 1e-7, 1e-5, 1e-5)),
            rr: Matrix2::from_diagonal(&Vector2::new(1e-4, 1e-4)),
            propagate_parameter_uncertainty: true,
            ut: UtParams::new(1.0, 2.0, 0.0),
            design: FilterDesign::Dual,
            imm: LeaderMotionTuning::reference(),
            input_noise_std: Vector2::zeros(),
        }
    }
}

impl Default for FilterTuning {
    fn default() -> Self {
        Self::reference()
    }
}

/// Everything that defines a [`FormationFilter`]: the follower's camera offset, the frame
/// period, the initial state and the tuning.
#[derive(Debug, Clone, PartialEq)]
pub struct FilterConfig {
    /// Camera offset `d` of the follower, metres.
    pub d: f64,
    /// Time between frames, seconds.
    pub dt: f64,
    /// Initial state estimate `[x1, y1, theta1, l12, alpha12, beta12]`.
    pub x0: PolarState,
    /// Noises, priors and unscented-transform parameters.
    pub tuning: FilterTuning,
}

impl FilterConfig {
    /// A configuration with the [reference tuning](FilterTuning::reference).
    pub fn new(d: f64, dt: f64, x0: PolarState) -> Self {
        Self {
            d,
            dt,
            x0,
            tuning: FilterTuning::reference(),
        }
    }

    /// This configuration started at one measurement `y = [l12, alpha12, beta12]` of
    /// covariance `r`: the formation variables are `y` with covariance `r`, and the leader's
    /// world pose `[x1, y1, theta1]`, which no measurement sees and the model does not need,
    /// is placed as if the follower stood at the origin, with standard deviation
    /// `world_pose_std` on each component and no correlation.
    ///
    /// # Errors
    /// A measurement the model refuses (non-finite, `l12` within
    /// [`unicycle::MIN_SEPARATION`]) or a bad offset.
    pub fn started_at(
        &self,
        y: &Vector3<f64>,
        r: &Matrix3<f64>,
        world_pose_std: f64,
    ) -> Result<Self, FilterError> {
        let origin = unicycle::PlanarPose::new(0.0, 0.0, 0.0);
        let world = Formation::from_vector(y).leader_pose(&origin, self.d)?;
        let mut p0 = Matrix6::zeros();
        let s2 = world_pose_std * world_pose_std;
        p0.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&Matrix3::from_diagonal_element(s2));
        p0.fixed_view_mut::<3, 3>(3, 3).copy_from(r);
        let mut config = self.clone();
        config.x0 = PolarState::new(world.x, world.y, world.theta, y[0], y[1], y[2]);
        config.tuning.p0 = p0;
        Ok(config)
    }
}

/// The causal filter inside a [`FormationFilter`].
#[derive(Debug, Clone)]
enum Engine {
    Dual(Box<Dual>),
    Imm(Box<ImmEngine>),
}

/// The IMM and its models' process noises and switching matrices, for the two model sets:
/// the follower's controller unknown (B and C hold the formation up to a random walk) or
/// known (B follows the controller; C, which B then covers, is dropped; B does not switch).
#[derive(Debug, Clone)]
struct ImmEngine {
    imm: ImmFilter,
    /// The hypotheses in the filter's order ([`LeaderMotionTuning::motions`]).
    motions: [LeaderMotion; 3],
    q: [Matrix10; 3],
    q_controlled: [Matrix10; 3],
    transition: Matrix3<f64>,
    transition_controlled: Matrix3<f64>,
}

/// The estimates the accessors return, refreshed after every successful step.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Snapshot {
    state: PolarState,
    state_covariance: Matrix6,
    velocity: Vector2<f64>,
    velocity_covariance: Matrix2<f64>,
    /// Covariance of `[l12, alpha12, beta12]` with `[v1, w1]` (zero for the dual UKF).
    cross: SMatrix<f64, 3, 2>,
    /// The IMM's whole mixed estimate over `[x, v1, w1, a_v, a_w]` (for the smoother).
    joint: Option<dukf::Gaussian<10>>,
}

/// What the dual filter's per-step process noise is made of (copied from the filter, whose
/// engine is then borrowed mutably).
struct DualNoise {
    model: PolarModel,
    dt: f64,
    q: Matrix6,
    propagate: bool,
    input_variance: Vector2<f64>,
}

/// A filter tracking one leader's formation variables and velocities: by default the IMM,
/// or the paper's dual UKF ([`FilterTuning::design`]).
#[derive(Debug, Clone)]
pub struct FormationFilter {
    model: PolarModel,
    dt: f64,
    q: Matrix6,
    rr: Matrix2<f64>,
    propagate: bool,
    /// Squares of [`FilterTuning::input_noise_std`].
    input_variance: Vector2<f64>,
    ut: UtParams,
    engine: Engine,
    snapshot: Snapshot,
    last_nis: Option<f64>,
    model_probabilities: Option<[f64; 3]>,
    follower: Option<ControllerConfig>,
}

fn state_space() -> Result<AngleMask<6>, UkfError> {
    AngleMask::from_indices(&STATE_ANGLES)
}

/// Runs `model.f`, remembering the first model error (the UKF closures cannot fail, so a
/// refused sigma point becomes NaN, which `dukf` reports; we then return the model's own,
/// clearer error).
fn process<'a>(
    model: &'a PolarModel,
    u: &'a Vector2<f64>,
    dt: f64,
    failure: &'a Cell<Option<UnicycleError>>,
) -> impl FnMut(&PolarState, &Vector2<f64>) -> PolarState + 'a {
    move |x, w| match model.f(x, u, w, dt) {
        Ok(next) => next,
        Err(e) => PolarState::repeat(remember(failure, e)),
    }
}

/// Keeps the first model error of a step in `failure` and returns the NaN that stands for the
/// refused sigma point (`dukf` reports it; [`outcome`] then returns the model's error).
fn remember(failure: &Cell<Option<UnicycleError>>, e: UnicycleError) -> f64 {
    if failure.get().is_none() {
        failure.set(Some(e));
    }
    f64::NAN
}

/// The IMM's three process functions over `z = [x, v1, w1, a_v, a_w]`: model `j` is
/// [`LeaderMotion::ALL`]`[j]` ([`unicycle::predict_leader`], which recovers states outside the
/// model's domain). A refused step is remembered in `failure` and becomes NaN, which `dukf`
/// reports; the mean is checked at construction: a non-positive initial `l12` is an error.
fn imm_process<'a>(
    model: &'a PolarModel,
    motions: [LeaderMotion; 3],
    u: &'a Vector2<f64>,
    dt: f64,
    controller: Option<ControllerConfig>,
    failure: &'a Cell<Option<UnicycleError>>,
) -> impl FnMut(usize, &Joint) -> Joint + 'a {
    move |j, z| match predict_leader(model, motions[j], z, u, dt, controller) {
        Ok(next) => next,
        Err(e) => Joint::repeat(remember(failure, e)),
    }
}

/// The filter's result, preferring the model's own error when a sigma point was refused.
fn outcome<T>(
    result: Result<T, UkfError>,
    failure: &Cell<Option<UnicycleError>>,
) -> Result<T, FilterError> {
    match (result, failure.get()) {
        (Ok(report), _) => Ok(report),
        (Err(_), Some(model_error)) => Err(model_error.into()),
        (Err(e), None) => Err(e.into()),
    }
}

impl ImmEngine {
    fn new(config: &FilterConfig) -> Result<Self, FilterError> {
        let t = &config.tuning;
        let i = &t.imm;
        let dt = config.dt;
        i.validate()?;
        if config.x0[3].is_nan() || config.x0[3] <= MIN_PREDICTED_SEPARATION {
            return Err(UnicycleError::SeparationTooSmall {
                l12: config.x0[3],
                min: MIN_PREDICTED_SEPARATION,
            }
            .into());
        }
        let mut z0 = Joint::zeros();
        z0.fixed_rows_mut::<6>(0).copy_from(&config.x0);
        z0[6] = t.w0[0];
        z0[7] = t.w0[1];
        let mut p0 = Matrix10::zeros();
        p0.fixed_view_mut::<6, 6>(0, 0).copy_from(&t.p0);
        p0.fixed_view_mut::<2, 2>(6, 6).copy_from(&t.pw0);
        p0[(8, 8)] = i.acceleration_std[0].powi(2);
        p0[(9, 9)] = i.acceleration_std[1].powi(2);
        let space = AngleMask::<10>::from_indices(&STATE_ANGLES)?;
        let ukf = Ukf::new(z0, p0, space, t.ut)?;
        let pose_q = Vector3::new(t.q[(0, 0)], t.q[(1, 1)], t.q[(2, 2)]);
        let [q, q_controlled] = i.process_noises(&pose_q, dt);
        let transition = match &i.jump {
            None => sojourn_transition::<3>(dt, i.sojourn)?,
            // A hands over to B at the sojourn rate and to J at the manoeuvre rate; B back to
            // A at the sojourn rate; J back to A at its own.
            Some(j) => {
                let (pa, pj) = ((-dt / i.sojourn).exp(), (-dt / j.sojourn).exp());
                let aj = (dt / j.onset).min(0.5 * pa);
                #[rustfmt::skip]
                let m = Matrix3::new(
                    pa - aj, 1.0 - pa, aj,
                    1.0 - pa, pa, 0.0,
                    1.0 - pj, 0.0, pj,
                );
                m
            }
        };
        // With the controller known, A hands over to B alone: at the sojourn rate (with J,
        // A's rate to J goes to B too, C's slot being dropped).
        let stay = match &i.jump {
            None => transition[(0, 0)],
            Some(_) => transition[(0, 0)] + transition[(0, 2)],
        };
        #[rustfmt::skip]
        let transition_controlled = Matrix3::new(
            stay, 1.0 - stay, 0.0,
            0.0, 1.0, 0.0,
            0.0, 1.0, 0.0,
        );
        let rest = 0.5 * (1.0 - i.mu0_a);
        let imm = Imm::new([ukf, ukf, ukf], [i.mu0_a, rest, rest], transition)?;
        Ok(Self {
            imm,
            motions: i.motions(),
            q,
            q_controlled,
            transition,
            transition_controlled,
        })
    }

    /// The models' process noises with the follower's controller known or not.
    fn noise(&self, controlled: bool) -> &[Matrix10; 3] {
        if controlled {
            &self.q_controlled
        } else {
            &self.q
        }
    }

    /// The IMM and [`ImmEngine::noise`], borrowed apart, so that a step needs no copy of the
    /// noises.
    fn filter_and_noise(&mut self, controlled: bool) -> (&mut ImmFilter, &[Matrix10; 3]) {
        let q = if controlled {
            &self.q_controlled
        } else {
            &self.q
        };
        (&mut self.imm, q)
    }

    /// Switches between the two model sets. To the controlled set: C's probability goes to B
    /// (B covers what C was for) and B no longer switches; back: the switching matrix of the
    /// sojourn time, with C re-entering through it.
    fn set_controlled(&mut self, controlled: bool) -> Result<(), UkfError> {
        let mu = *self.imm.probabilities();
        if controlled {
            self.imm
                .set_structure(self.transition_controlled, [mu[0], mu[1] + mu[2], 0.0])
        } else {
            self.imm.set_structure(self.transition, mu)
        }
    }

    /// Model B's probability handed to the model that covers a set-point change (C, or A
    /// when J stands in C's place): see [`FormationFilter::follower_setpoint_changed`].
    fn release_formation(&mut self) -> Result<(), UkfError> {
        let find = |m: LeaderMotion| self.motions.iter().position(|&k| k == m);
        let (Some(held), Some(to)) = (
            find(LeaderMotion::HoldsFormation),
            find(LeaderMotion::HoldsBearing).or_else(|| find(LeaderMotion::Accelerates)),
        ) else {
            return Ok(());
        };
        let mut mu = *self.imm.probabilities();
        mu[to] += mu[held];
        mu[held] = 0.0;
        self.imm.set_structure(*self.imm.transition(), mu)
    }

    /// The odometry noise's process noise ([`input_noise`]) at the mixed estimate.
    fn input_noise(
        &self,
        model: &PolarModel,
        dt: f64,
        variance: &Vector2<f64>,
        u: &Vector2<f64>,
    ) -> Result<Option<Matrix6>, FilterError> {
        if *variance == Vector2::zeros() {
            return Ok(None);
        }
        let (z, _) = self.imm.estimate();
        let x: PolarState = z.fixed_rows::<6>(0).into_owned();
        input_noise(model, dt, variance, &x, &Vector2::new(z[6], z[7]), u)
    }

    fn snapshot(&self) -> Snapshot {
        let (z, p) = self.imm.estimate();
        Snapshot {
            state: z.fixed_rows::<6>(0).into_owned(),
            state_covariance: p.fixed_view::<6, 6>(0, 0).into_owned(),
            velocity: Vector2::new(z[6], z[7]),
            velocity_covariance: p.fixed_view::<2, 2>(6, 6).into_owned(),
            cross: p.fixed_view::<3, 2>(3, 6).into_owned(),
            joint: Some(dukf::Gaussian::new(z, p)),
        }
    }
}

/// `G diag(variance) G^T`, `G = df/du` by central differences at `(x, w)`: what the
/// follower's odometry noise adds to one step's state process noise ([`FilterTuning::input_noise_std`]).
/// `None` when the odometry is exact.
fn input_noise(
    model: &PolarModel,
    dt: f64,
    variance: &Vector2<f64>,
    x: &PolarState,
    w: &Vector2<f64>,
    u: &Vector2<f64>,
) -> Result<Option<Matrix6>, FilterError> {
    if *variance == Vector2::zeros() {
        return Ok(None);
    }
    let step = |v: f64| 1e-6 * (1.0 + v.abs());
    let g = dukf::central_jacobian(u, step, &state_space()?, |u| model.f(x, u, w, dt))?;
    let q = g * Matrix2::from_diagonal(variance) * g.transpose();
    Ok(Some((q + q.transpose()) * 0.5))
}

/// The IMM's per-model process noises with the odometry's term added to each model's state
/// block.
fn with_input_noise(q: &[Matrix10; 3], extra: Option<&Matrix6>) -> [Matrix10; 3] {
    let mut out = *q;
    if let Some(e) = extra {
        for m in &mut out {
            let mut block = m.fixed_view_mut::<6, 6>(0, 0);
            block += e;
        }
    }
    out
}

fn dual_snapshot(dual: &Dual) -> Snapshot {
    Snapshot {
        state: *dual.state(),
        state_covariance: *dual.state_covariance(),
        velocity: *dual.parameters(),
        velocity_covariance: *dual.parameter_covariance(),
        cross: SMatrix::zeros(),
        joint: None,
    }
}

impl FormationFilter {
    /// A filter from its configuration.
    ///
    /// # Errors
    /// A bad offset or time step, non-finite or non-positive-definite initial covariances, or
    /// bad unscented-transform parameters or IMM settings.
    pub fn new(config: &FilterConfig) -> Result<Self, FilterError> {
        if !(config.dt.is_finite() && config.dt > 0.0) {
            return Err(FilterError::InvalidTimeStep { dt: config.dt });
        }
        let model = PolarModel::new(config.d)?;
        let t = &config.tuning;
        if let Some(index) = t
            .input_noise_std
            .iter()
            .position(|s| !(s.is_finite() && *s >= 0.0))
        {
            return Err(FilterError::InvalidInputNoise {
                index,
                value: t.input_noise_std[index],
            });
        }
        let (engine, snapshot) = match t.design {
            FilterDesign::Dual => {
                let state = Ukf::new(config.x0, t.p0, state_space()?, t.ut)?;
                let params = Ukf::new(t.w0, t.pw0, Euclidean, t.ut)?;
                let dual = DualUkf::new(state, params, t.q, t.rr, MEASUREMENT_SPACE)?;
                let snapshot = dual_snapshot(&dual);
                (Engine::Dual(Box::new(dual)), snapshot)
            }
            FilterDesign::Imm => {
                let engine = ImmEngine::new(config)?;
                let snapshot = engine.snapshot();
                (Engine::Imm(Box::new(engine)), snapshot)
            }
        };
        Ok(Self {
            model,
            dt: config.dt,
            q: t.q,
            rr: t.rr,
            propagate: t.propagate_parameter_uncertainty,
            input_variance: t.input_noise_std.map(|s| s * s),
            ut: t.ut,
            engine,
            snapshot,
            last_nis: None,
            model_probabilities: match t.design {
                FilterDesign::Imm => {
                    let rest = 0.5 * (1.0 - t.imm.mu0_a);
                    Some([t.imm.mu0_a, rest, rest])
                }
                FilterDesign::Dual => None,
            },
            follower: None,
        })
    }

    /// A copy of the dual filter to step, with this step's state process noise: `Q`, plus
    /// `F_w Pw- F_w^T` when configured, with `F_w = df/dw` by central differences at the
    /// current estimates, plus the odometry noise's term ([`input_noise`]).
    fn prepared(noise: &DualNoise, dual: &Dual, u: &Vector2<f64>) -> Result<Dual, FilterError> {
        let mut next = *dual;
        let (model, dt) = (&noise.model, noise.dt);
        let odometry = input_noise(
            model,
            dt,
            &noise.input_variance,
            dual.state(),
            dual.parameters(),
            u,
        )?;
        if !noise.propagate && odometry.is_none() {
            return Ok(next);
        }
        let mut q = noise.q + odometry.unwrap_or_else(Matrix6::zeros);
        if noise.propagate {
            let x = *dual.state();
            let step = |w: f64| 1e-6 * (1.0 + w.abs());
            let fw = dukf::central_jacobian(dual.parameters(), step, &state_space()?, |w| {
                model.f(&x, u, w, dt)
            })?;
            let pw = dual.parameter_covariance() + dual.parameter_noise();
            q += fw * pw * fw.transpose();
        }
        next.set_process_noise((q + q.transpose()) * 0.5)?;
        Ok(next)
    }

    /// The pieces of the dual filter's per-step process noise ([`Self::prepared`]).
    fn dual_noise(&self) -> DualNoise {
        DualNoise {
            model: self.model,
            dt: self.dt,
            q: self.q,
            propagate: self.propagate,
            input_variance: self.input_variance,
        }
    }

    /// Tells the IMM the follower's own separation-bearing controller (gains and current
    /// set-points) that computes the inputs passed to the next steps; `reproduce dukf` does,
    /// from the scenario. Model B then takes the leader velocity under which the formation
    /// moves as that controller commands ([`unicycle::controlled_formation_velocity`]) instead of one
    /// that holds it exactly, with no held random walk (only
    /// [`LeaderMotionTuning::controlled_formation_q`]); model C, which covered set-point changes that
    /// B now models, is dropped (its probability goes to B); and B does not switch out (the
    /// follower's controller is its own knowledge, not a behaviour that ends): model A
    /// competes from its initial probability and hands over to B at the sojourn rate.
    /// `None` (the default) assumes an exactly held formation and restores the three-model
    /// switching. Call it again when a set-point changes. The dual UKF ignores it. Gains and
    /// set-points are used as given (no validation beyond what the model's own checks catch).
    ///
    /// # Errors
    /// Only if the model probabilities were not a probability vector (they always are); the
    /// filter is then unchanged.
    pub fn set_follower_controller(
        &mut self,
        controller: Option<ControllerConfig>,
    ) -> Result<(), FilterError> {
        if let Engine::Imm(engine) = &mut self.engine
            && controller.is_some() != self.follower.is_some()
        {
            engine.set_controlled(controller.is_some())?;
            self.model_probabilities = Some(*engine.imm.probabilities());
            self.snapshot = engine.snapshot();
        }
        self.follower = controller;
        Ok(())
    }

    /// The follower changed its own set-point (its plan: a robot knows it at run time, as it
    /// knows the commands it sends). Until the formation settles at the new set-point it is
    /// not held, so model B, the formation held, is wrong from the first frame on: its
    /// probability goes to model C, which covers a separation or bearing that changes (to A
    /// when J stands in C's place), and returns through the switching matrix and the
    /// likelihoods once the formation is held again. Without this, B holds nearly all of the
    /// probability when the follower brakes, the mixture predicts the leader braking with it,
    /// and the first measurement of the change lies far outside the gate (`far.yaml`: 16 mm
    /// in one frame, NIS 123). Nothing changes for the dual UKF, or when the follower's
    /// controller is known ([`set_follower_controller`](Self::set_follower_controller)): B
    /// then models the change itself.
    ///
    /// # Errors
    /// Only if the model probabilities were not a probability vector (they always are); the
    /// filter is then unchanged.
    pub fn follower_setpoint_changed(&mut self) -> Result<(), FilterError> {
        if let Engine::Imm(engine) = &mut self.engine
            && self.follower.is_none()
        {
            engine.release_formation()?;
            self.model_probabilities = Some(*engine.imm.probabilities());
            self.snapshot = engine.snapshot();
        }
        Ok(())
    }

    /// One frame with a measurement `y = [l12, alpha12, beta12]` of noise covariance `r`;
    /// `u` are the follower's inputs applied since the previous frame.
    ///
    /// # Errors
    /// Non-finite `y`, `r` or `u`; the model or the filter failing. On error the estimates
    /// are unchanged.
    pub fn step(
        &mut self,
        y: &Vector3<f64>,
        r: &Matrix3<f64>,
        u: Inputs,
    ) -> Result<(), FilterError> {
        let u: Vector2<f64> = u.into();
        let failure = Cell::new(None);
        let noise = self.dual_noise();
        match &mut self.engine {
            Engine::Dual(dual) => {
                let mut next = Self::prepared(&noise, dual, &u)?;
                let result = next.step(
                    process(&self.model, &u, self.dt, &failure),
                    PolarModel::h,
                    y,
                    r,
                );
                let report = outcome(result, &failure)?;
                **dual = next;
                self.snapshot = dual_snapshot(dual);
                self.last_nis = Some(report.state.nis);
            }
            Engine::Imm(engine) => {
                check_inputs(&u)?;
                let motions = engine.motions;
                let extra = engine.input_noise(&self.model, self.dt, &self.input_variance, &u)?;
                let (imm, q) = engine.filter_and_noise(self.follower.is_some());
                let q = with_input_noise(q, extra.as_ref());
                let result = imm.step(
                    imm_process(&self.model, motions, &u, self.dt, self.follower, &failure),
                    &q,
                    y,
                    |z| Vector3::new(z[3], z[4], z[5]),
                    r,
                    &MEASUREMENT_SPACE,
                );
                let report = outcome(result, &failure)?;
                self.snapshot = engine.snapshot();
                self.last_nis = report.combined_nis;
                self.model_probabilities = Some(report.probabilities);
            }
        }
        Ok(())
    }

    /// **An oracle, for comparisons only**: sets the leader-velocity estimate to `w` (the
    /// truth a simulation knows) with a negligible variance, and no correlation with the
    /// rest of the state, before the next step. The IMM is restarted from its mixed estimate
    /// so pinned, with the accelerations zero and model A (the leader moves as its state says)
    /// certain: its models B and C, which infer the velocity, only re-enter through the
    /// switching. `cargo xtask dukf-table --held-out` calls it before every step for its
    /// oracle column (issue #30): what the filter would reach if it knew the leader's inputs.
    /// No robot has them.
    ///
    /// # Errors
    /// A non-finite `w`; a covariance the filter refuses. On error the filter is unchanged.
    pub fn pin_leader_velocity(&mut self, w: Inputs) -> Result<(), FilterError> {
        const PINNED_VARIANCE: f64 = 1e-12;
        let w: Vector2<f64> = w.into();
        check_inputs(&w)?;
        match &mut self.engine {
            Engine::Dual(dual) => {
                dual.parameter_filter_mut()
                    .reset(w, Matrix2::identity() * PINNED_VARIANCE)?;
                self.snapshot = dual_snapshot(dual);
            }
            Engine::Imm(engine) => {
                let (mut z, mut p) = engine.imm.estimate();
                z[6] = w[0];
                z[7] = w[1];
                z[8] = 0.0;
                z[9] = 0.0;
                for i in 6..10 {
                    for j in 0..10 {
                        p[(i, j)] = 0.0;
                        p[(j, i)] = 0.0;
                    }
                    p[(i, i)] = PINNED_VARIANCE;
                }
                engine.imm.reset(z, p, [1.0, 0.0, 0.0])?;
                self.model_probabilities = Some([1.0, 0.0, 0.0]);
                self.snapshot = engine.snapshot();
            }
        }
        Ok(())
    }

    /// One frame without a measurement (e.g. the leader was not detected): the state coasts
    /// on the model with the current velocity estimate and the covariances grow.
    ///
    /// # Errors
    /// As [`FormationFilter::step`].
    pub fn predict_only(&mut self, u: Inputs) -> Result<(), FilterError> {
        let u: Vector2<f64> = u.into();
        let failure = Cell::new(None);
        let noise = self.dual_noise();
        match &mut self.engine {
            Engine::Dual(dual) => {
                let mut next = Self::prepared(&noise, dual, &u)?;
                let result = next.predict_only(process(&self.model, &u, self.dt, &failure));
                outcome(result, &failure)?;
                **dual = next;
                self.snapshot = dual_snapshot(dual);
            }
            Engine::Imm(engine) => {
                check_inputs(&u)?;
                let motions = engine.motions;
                let extra = engine.input_noise(&self.model, self.dt, &self.input_variance, &u)?;
                let (imm, q) = engine.filter_and_noise(self.follower.is_some());
                let q = with_input_noise(q, extra.as_ref());
                let result = imm.predict_only(
                    imm_process(&self.model, motions, &u, self.dt, self.follower, &failure),
                    &q,
                );
                let report = outcome(result, &failure)?;
                self.snapshot = engine.snapshot();
                self.model_probabilities = Some(report.probabilities);
            }
        }
        self.last_nis = None;
        Ok(())
    }

    /// The normalised innovation squared `nu^T S^-1 nu` of the last update (chi-square with 3
    /// degrees of freedom when the filter is consistent; for the IMM, the probability-weighted
    /// innovation against the mixture's innovation covariance); `None` before the first
    /// update and after a frame without a measurement.
    pub fn last_nis(&self) -> Option<f64> {
        self.last_nis
    }

    /// The IMM's model probabilities `[constant-acceleration leader, formation held, bearing
    /// held]` after the last step (`None` for the dual UKF).
    ///
    /// They are the filter's own test of model mismatch, run on its innovations: told the
    /// follower's controller, a formation that does not move as the controller commands (a
    /// slow wheel, a slipping track) makes model B's innovations lose to model A's, and B's
    /// probability falls (with the follower's wheels at 0.9 of the commanded speed, from 0.32
    /// and 0.43 with exact wheels to 0.06 and 0.05 after 2 s; `formation-sim`'s
    /// `tests/model_mismatch.rs`).
    pub fn model_probabilities(&self) -> Option<[f64; 3]> {
        self.model_probabilities
    }

    /// The IMM's per-model estimates of the leader velocities `[v1, w1]` and their
    /// covariances, in the order of [`model_probabilities`](Self::model_probabilities)
    /// (`None` for the dual UKF). The combined estimate
    /// ([`leader_velocity`](Self::leader_velocity)) is their probability-weighted mixture.
    pub fn model_velocities(&self) -> Option<[(Vector2<f64>, Matrix2<f64>); 3]> {
        match &self.engine {
            Engine::Dual(_) => None,
            Engine::Imm(engine) => Some(engine.imm.filters().each_ref().map(|f| {
                (
                    f.state().fixed_rows::<2>(6).into_owned(),
                    f.covariance().fixed_view::<2, 2>(6, 6).into_owned(),
                )
            })),
        }
    }

    /// The IMM's per-model estimates of the joint state `[x1, y1, theta1, l12, alpha12,
    /// beta12, v1, w1, a_v, a_w]` and their covariances, in the order of
    /// [`model_probabilities`](Self::model_probabilities) (`None` for the dual UKF): what the
    /// combined estimate mixes, for diagnosing its consistency model by model.
    pub fn model_estimates(&self) -> Option<[(SVector<f64, 10>, SMatrix<f64, 10, 10>); 3]> {
        match &self.engine {
            Engine::Dual(_) => None,
            Engine::Imm(engine) => Some(
                engine
                    .imm
                    .filters()
                    .each_ref()
                    .map(|f| (*f.state(), *f.covariance())),
            ),
        }
    }

    /// The measurement this filter predicts for its next step with the follower's inputs
    /// `u`, for testing candidate measurements before one is applied (gating, choosing
    /// between planar candidates). The filter is predicted on a copy; `self` is unchanged.
    ///
    /// # Errors
    /// As [`FormationFilter::predict_only`].
    pub fn predicted(&self, u: Inputs) -> Result<Predicted, FilterError> {
        let mut next = self.clone();
        next.predict_only(u)?;
        let per_model = |(z, p): (SVector<f64, 10>, SMatrix<f64, 10, 10>)| {
            let var = Matrix3::from_diagonal(&p.fixed_view::<3, 3>(3, 3).diagonal());
            (z.fixed_rows::<3>(3).into_owned(), var)
        };
        Ok(Predicted {
            y: next.formation().to_vector(),
            var: Matrix3::from_diagonal(&next.formation_std().map(|s| s * s)),
            models: next.model_estimates().map(|m| m.map(per_model)),
        })
    }

    /// Which design this filter runs.
    pub fn design(&self) -> FilterDesign {
        match self.engine {
            Engine::Dual(_) => FilterDesign::Dual,
            Engine::Imm(_) => FilterDesign::Imm,
        }
    }

    /// The state covariance (order `[x1, y1, theta1, l12, alpha12, beta12]`).
    pub fn state_covariance(&self) -> &Matrix6 {
        &self.snapshot.state_covariance
    }

    /// The leader-velocity covariance (order `[v1, w1]`).
    pub fn leader_velocity_covariance(&self) -> &Matrix2<f64> {
        &self.snapshot.velocity_covariance
    }

    /// The state estimate `[x1, y1, theta1, l12, alpha12, beta12]`.
    pub fn state(&self) -> &PolarState {
        &self.snapshot.state
    }

    /// Standard deviations of the state estimate.
    pub fn state_std(&self) -> PolarState {
        std_of(&self.snapshot.state_covariance)
    }

    /// The estimated formation variables.
    pub fn formation(&self) -> Formation {
        Formation::from_vector(&PolarModel::h(self.state()))
    }

    /// Standard deviations of `[l12, alpha12, beta12]`.
    pub fn formation_std(&self) -> Vector3<f64> {
        PolarModel::h(&self.state_std())
    }

    /// The estimated leader velocities `(v1, w1)`.
    pub fn leader_velocity(&self) -> Inputs {
        self.snapshot.velocity.into()
    }

    /// The covariance of `[l12, alpha12, beta12, v1, w1]`. The IMM estimates them jointly, so
    /// the formation-velocity terms are its own; the dual filter keeps no cross-covariance
    /// between its two filters, so there they are zero (the smoother's joint pass has them;
    /// `docs/smoothing.md`).
    pub fn estimate_covariance(&self) -> Matrix5<f64> {
        let s = &self.snapshot;
        let mut c = Matrix5::zeros();
        c.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&s.state_covariance.fixed_view::<3, 3>(3, 3));
        c.fixed_view_mut::<2, 2>(3, 3)
            .copy_from(&s.velocity_covariance);
        c.fixed_view_mut::<3, 2>(0, 3).copy_from(&s.cross);
        c.fixed_view_mut::<2, 3>(3, 0)
            .copy_from(&s.cross.transpose());
        c
    }

    /// Standard deviations of `(v1, w1)`.
    pub fn leader_velocity_std(&self) -> Vector2<f64> {
        std_of(&self.snapshot.velocity_covariance)
    }
}

/// The standard deviations on the diagonal of a covariance (a negative rounding error reads
/// as 0).
fn std_of<const N: usize>(covariance: &SMatrix<f64, N, N>) -> SVector<f64, N> {
    covariance.diagonal().map(|v| v.max(0.0).sqrt())
}

/// The follower inputs must be finite (the IMM's model B divides by them only through the
/// model, which reports a non-finite input as its own error).
fn check_inputs(u: &Vector2<f64>) -> Result<(), FilterError> {
    match u.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(index) => Err(UnicycleError::NonFinite {
            what: "follower inputs",
            index,
            value: u[index],
        }
        .into()),
    }
}

/// A filter's predicted measurement `(l12, alpha12, beta12)` for its next step
/// ([`FormationFilter::predicted`]), against which candidate measurements are tested.
/// Only the diagonal of the predicted covariance is used: the filter reports standard
/// deviations, and the off-diagonal terms are small next to `R` for these three variables.
#[derive(Debug, Clone, Copy)]
pub struct Predicted {
    y: Vector3<f64>,
    var: Matrix3<f64>,
    models: Option<[(Vector3<f64>, Matrix3<f64>); 3]>,
}

impl Predicted {
    /// The predicted measurement.
    pub fn y(&self) -> Vector3<f64> {
        self.y
    }

    /// The normalised innovation squared of measurement `y` with covariance `r` against the
    /// prediction (angles wrapped; [`dukf::innovation_nis`]); `None` if not finite.
    pub fn nis(&self, y: &Vector3<f64>, r: &Matrix3<f64>) -> Option<f64> {
        dukf::innovation_nis(&MEASUREMENT_SPACE, y, &self.y, &self.var, r)
    }

    /// The smallest normalised innovation squared of `y` against one IMM model's own
    /// prediction, or `nis` (the combined prediction's) if that is smaller or there are no
    /// models (the dual UKF): a change one model predicts while another holds the
    /// probability shows here first.
    pub fn best_model_nis(&self, y: &Vector3<f64>, r: &Matrix3<f64>, nis: f64) -> f64 {
        self.models
            .iter()
            .flatten()
            .filter_map(|(m, var)| dukf::innovation_nis(&MEASUREMENT_SPACE, y, m, var, r))
            .fold(nis, f64::min)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn config() -> FilterConfig {
        let x0 = PolarState::from_row_slice(&[1.5, 0.25, 0.0, 1.047, 0.233, 0.232]);
        FilterConfig::new(0.5, 1.0 / 30.0, x0)
    }

    fn filter() -> FormationFilter {
        FormationFilter::new(&config()).unwrap()
    }

    /// Regression (#30): with the controller known A hands over to B at the sojourn rate,
    /// with or without J (adding J once changed the reference model set's switching).
    #[test]
    fn the_controlled_switching_keeps_a_at_its_sojourn_rate() {
        let dt = 1.0 / 30.0;
        let plain = ImmEngine::new(&config()).unwrap();
        let pa = (-dt / config().tuning.imm.sojourn).exp();
        let t = plain.transition_controlled;
        assert_eq!(t[(0, 0)], plain.transition[(0, 0)]);
        assert!((t[(0, 0)] - pa).abs() < 1e-12, "{} vs {pa}", t[(0, 0)]);
        assert_eq!((t[(0, 1)], t[(0, 2)]), (1.0 - t[(0, 0)], 0.0));
        let mut jump = config();
        jump.tuning.imm.jump = Some(unicycle::LeaderJump {
            velocity_std: Vector2::new(0.05, 0.1),
            sojourn: 0.2,
            onset: 10.0,
        });
        let with = ImmEngine::new(&jump).unwrap();
        let t = with.transition_controlled;
        assert!((t[(0, 0)] - pa).abs() < 1e-12, "{} vs {pa}", t[(0, 0)]);
        assert_eq!(t[(0, 2)], 0.0);
        // Uncontrolled: every row sums to one, and A reaches J at dt / onset.
        let u = with.transition;
        for r in 0..3 {
            assert!((u.row(r).sum() - 1.0).abs() < 1e-12);
        }
        assert!((u[(0, 2)] - dt / 10.0).abs() < 1e-12);
        assert_eq!(with.motions[2], unicycle::LeaderMotion::Jumps);
    }

    fn r() -> Matrix3<f64> {
        Matrix3::from_diagonal(&Vector3::new(
            0.07f64.powi(2),
            0.03f64.powi(2),
            0.03f64.powi(2),
        ))
    }

    #[test]
    fn a_filter_started_at_a_measurement_holds_it_and_places_the_leader_from_the_origin() {
        let y = Vector3::new(1.2, -0.3, 0.4);
        let started = config().started_at(&y, &r(), 0.1).unwrap();
        assert_eq!(PolarModel::h(&started.x0), y);
        assert_eq!(started.tuning.p0.fixed_view::<3, 3>(3, 3), r());
        assert_eq!(started.tuning.p0.fixed_view::<3, 3>(0, 3), Matrix3::zeros());
        assert!((started.tuning.p0[(1, 1)] - 0.01).abs() < 1e-15);
        // The leader's world pose is where `y` puts it seen from a follower at the origin.
        let origin = unicycle::PlanarPose::new(0.0, 0.0, 0.0);
        let leader = PolarModel::leader_pose(&started.x0);
        let back = Formation::from_poses(&leader, &origin, 0.5).unwrap();
        assert!((back.to_vector() - y).norm() < 1e-12, "{back:?}");
        // Everything else is the template's.
        assert_eq!(started.tuning.q, config().tuning.q);
        for bad in [0.0, f64::NAN] {
            let y = Vector3::new(bad, 0.0, 0.0);
            assert!(matches!(
                config().started_at(&y, &r(), 0.1),
                Err(FilterError::Model(_))
            ));
        }
    }

    #[test]
    fn non_finite_measurement_is_an_error_and_changes_nothing() {
        let mut f = filter();
        let before = (*f.state(), f.state_std(), f.leader_velocity());
        let y = Vector3::new(1.0, f64::NAN, 0.2);
        let err = f.step(&y, &r(), Inputs::new(0.5, 0.0)).unwrap_err();
        assert!(matches!(err, FilterError::Ukf(_)), "{err:?}");
        assert_eq!(before, (*f.state(), f.state_std(), f.leader_velocity()));
        let err = f
            .step(
                &Vector3::new(1.0, 0.2, 0.2),
                &r(),
                Inputs::new(f64::INFINITY, 0.0),
            )
            .unwrap_err();
        assert!(
            matches!(err, FilterError::Model(UnicycleError::NonFinite { .. })),
            "{err:?}"
        );
        assert_eq!(before.0, *f.state());
    }

    #[test]
    fn separation_at_zero_is_the_models_error() {
        let mut config = config();
        config.x0[3] = 0.0;
        config.tuning.design = FilterDesign::Imm;
        // The IMM refuses it at construction; the dual UKF at its first step.
        assert!(matches!(
            FormationFilter::new(&config),
            Err(FilterError::Model(UnicycleError::SeparationTooSmall { .. }))
        ));
        config.tuning.design = FilterDesign::Dual;
        let mut f = FormationFilter::new(&config).unwrap();
        let err = f.predict_only(Inputs::new(0.5, 0.0)).unwrap_err();
        assert!(
            matches!(
                err,
                FilterError::Model(UnicycleError::SeparationTooSmall { .. })
            ),
            "{err:?}"
        );
    }

    #[test]
    fn coasting_grows_the_uncertainty_and_a_measurement_shrinks_it() {
        // Also the regression test of the IMM's sigma-point clamp: coasting on the initial
        // velocity prior (1 m/s) drew sigma points with l12 < 0, which failed the step.
        let mut f = filter();
        let s0 = f.formation_std()[0];
        for _ in 0..10 {
            f.predict_only(Inputs::new(0.8, 0.0)).unwrap();
        }
        let s1 = f.formation_std()[0];
        assert!(s1 > s0, "{s1} <= {s0}");
        f.step(
            &Vector3::new(1.03, 0.245, 0.245),
            &r(),
            Inputs::new(0.8, 0.0),
        )
        .unwrap();
        assert!(f.formation_std()[0] < s1);
        assert!(f.leader_velocity_std()[0] < 1.0);
    }

    #[test]
    fn the_dual_ukf_is_the_default_and_the_imm_is_selectable() {
        let mut dual = filter();
        assert_eq!(dual.design(), FilterDesign::Dual);
        let mut cfg = config();
        cfg.tuning.design = FilterDesign::Imm;
        let mut imm = FormationFilter::new(&cfg).unwrap();
        assert_eq!(imm.design(), FilterDesign::Imm);
        assert_eq!(dual.design(), FilterDesign::Dual);
        assert_eq!(dual.model_probabilities(), None);
        let y = Vector3::new(1.03, 0.245, 0.245);
        for _ in 0..30 {
            imm.step(&y, &r(), Inputs::new(0.8, 0.0)).unwrap();
            dual.step(&y, &r(), Inputs::new(0.8, 0.0)).unwrap();
        }
        let mu = imm.model_probabilities().unwrap();
        // The combined velocity is the probability-weighted mean of the models' velocities.
        let per_model = imm.model_velocities().unwrap();
        let mixed: Vector2<f64> = (0..3).map(|j| per_model[j].0 * mu[j]).sum();
        let w = imm.leader_velocity();
        assert!((mixed - Vector2::new(w.v, w.w)).amax() < 1e-9, "{mixed:?}");
        assert!(dual.model_velocities().is_none());
        assert!((mu.iter().sum::<f64>() - 1.0).abs() < 1e-12, "{mu:?}");
        // The IMM estimates formation and velocity jointly: cross terms; the dual UKF none.
        let c = imm.estimate_covariance();
        assert!(c.fixed_view::<3, 2>(0, 3).amax() > 0.0);
        assert!((c - c.transpose()).amax() < 1e-15);
        assert_eq!(
            dual.estimate_covariance().fixed_view::<3, 2>(0, 3).amax(),
            0.0
        );
        assert!(imm.last_nis().is_some_and(|n| n.is_finite() && n >= 0.0));
    }

    #[test]
    fn a_known_controller_drops_model_c_and_stops_the_switching_out_of_b() {
        let mut cfg = config();
        cfg.tuning.design = FilterDesign::Imm;
        let mut f = FormationFilter::new(&cfg).unwrap();
        let goal = ControllerConfig {
            l12_desired: 1.03,
            alpha12_desired: 0.245,
            k_l: 1.0,
            k_alpha: 1.0,
            max_v: None,
            max_w: None,
        };
        assert_eq!(f.model_probabilities(), Some([0.5, 0.25, 0.25]));
        f.set_follower_controller(Some(goal)).unwrap();
        // C's probability went to B; the estimate is unchanged (all models start alike).
        assert_eq!(f.model_probabilities(), Some([0.5, 0.5, 0.0]));
        let y = Vector3::new(1.03, 0.245, 0.245);
        for _ in 0..30 {
            f.set_follower_controller(Some(goal)).unwrap();
            f.step(&y, &r(), Inputs::new(0.8, 0.0)).unwrap();
            let mu = f.model_probabilities().unwrap();
            assert_eq!(mu[2], 0.0, "{mu:?}");
            assert!((mu.iter().sum::<f64>() - 1.0).abs() < 1e-12, "{mu:?}");
        }
        // Back to the three-model switching: C re-enters through the switching matrix.
        f.set_follower_controller(None).unwrap();
        f.step(&y, &r(), Inputs::new(0.8, 0.0)).unwrap();
        assert!(f.model_probabilities().unwrap()[2] > 0.0);
        // The dual UKF ignores the controller.
        let mut dual = filter();
        dual.set_follower_controller(Some(goal)).unwrap();
        assert_eq!(dual.model_probabilities(), None);
        dual.step(&y, &r(), Inputs::new(0.8, 0.0)).unwrap();
    }

    #[test]
    fn bad_imm_settings_are_errors() {
        let imm = || {
            let mut cfg = config();
            cfg.tuning.design = FilterDesign::Imm;
            cfg
        };
        let mut cfg = imm();
        cfg.tuning.imm.mu0_a = 1.5;
        assert!(FormationFilter::new(&cfg).is_err());
        let mut cfg = imm();
        cfg.tuning.imm.sojourn = 0.0;
        assert!(FormationFilter::new(&cfg).is_err());
        let mut cfg = imm();
        cfg.tuning.imm.jerk[0] = f64::NAN;
        assert!(FormationFilter::new(&cfg).is_err());
        let mut cfg = imm();
        cfg.tuning.imm.controlled_formation_q[1] = f64::INFINITY;
        assert!(FormationFilter::new(&cfg).is_err());
    }

    #[test]
    fn bad_time_step_is_an_error() {
        let config = FilterConfig {
            dt: 0.0,
            ..config()
        };
        assert!(matches!(
            FormationFilter::new(&config),
            Err(FilterError::InvalidTimeStep { .. })
        ));
    }
}
