//! The reference scenario of the dual-UKF experiment (paper Figs. 12-13): a leader weaving
//! ahead of a follower that holds formation, and noisy measurements of the formation
//! variables. Documented in `docs/reference-scenario.md`.
//!
//! The truth is simulated in Cartesian form (both unicycles integrated exactly, spec 2.2,
//! then spec 2.3), not with the polar model the filter uses, so the filter is not tested
//! against its own equations. Inputs are held constant over each step (zero-order hold).

use formation_filter::MEASUREMENT_SPACE;
use nalgebra::Vector3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal, StandardNormal};
use unicycle::{
    Actuation, ControllerConfig, Formation, FormationMeasurement, Inputs, PlanarPose, PolarModel,
    PolarState, SeparationBearingController, UnicycleError,
};

/// The paper's measurement bias `[l12, alpha12, beta12]` (Figs. 12-13).
pub const PAPER_BIAS: [f64; 3] = [-0.0702, 0.0248, 0.0236];

/// The paper's filter initial state `[x1, y1, theta1, l12, alpha12, beta12]`.
pub const PAPER_X0: [f64; 6] = [1.5, 0.25, 0.0, 1.047, 0.233, 0.232];

/// Errors of the scenario simulation.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ScenarioError {
    /// The robot model refused a pose, an input or a step.
    #[error(transparent)]
    Model(#[from] UnicycleError),
    /// A noise standard deviation is negative or not finite.
    #[error("measurement noise standard deviation {index} = {value} must be finite and >= 0")]
    InvalidNoise {
        /// Component (0: l12, 1: alpha12, 2: beta12).
        index: usize,
        /// The value that was given.
        value: f64,
    },
    /// An odometry noise standard deviation is negative or not finite.
    #[error("odometry noise standard deviation {index} = {value} must be finite and >= 0")]
    InvalidOdometryNoise {
        /// Component (0: v, 1: w).
        index: usize,
        /// The value that was given.
        value: f64,
    },
    /// The follower's controller acts on its estimate ([`Control::Estimate`]) but no
    /// estimate was given: such a run needs its estimator in the loop
    /// ([`Simulation::step`], `formation_sim::reproduce::ClosedLoop`), not the plain iterator.
    #[error(
        "control: estimate needs the follower's estimate at t = {t} s: run the scenario with its filter in the loop (formation_sim::reproduce::ClosedLoop), or set control: truth or open"
    )]
    NoEstimate {
        /// Time of the step that had none, seconds.
        t: f64,
    },
    /// The duration or step gives no step at all, or is not finite.
    #[error("duration {duration} s with dt = {dt} s gives no simulation step")]
    NoSteps {
        /// Duration, seconds.
        duration: f64,
        /// Step, seconds.
        dt: f64,
    },
}

/// What the follower's separation-bearing controller acts on (`control` in scenario files).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Control {
    /// On the follower's own estimate of the formation and of the leader's velocity, as on a
    /// robot: the estimate after the filter took the measurement at `t_k` commands the step
    /// from `t_k` to `t_{k+1}` (the default of scenario files).
    #[default]
    Estimate,
    /// On the true formation and the true leader inputs: the paper's setting (Figs. 12-13),
    /// which hands the follower's motion a quantity no robot has.
    Truth,
    /// Without feedback: the follower replays the commands its controller gives along the
    /// planned run (true leader, follower moved exactly by its commands), so its actuation
    /// errors accumulate.
    Open,
}

impl Control {
    /// Every mode, in the order of the documentation.
    pub const ALL: [Self; 3] = [Self::Estimate, Self::Truth, Self::Open];

    /// The name used in scenario files and tables (`estimate`, `truth`, `open`).
    pub fn name(self) -> &'static str {
        match self {
            Self::Estimate => "estimate",
            Self::Truth => "truth",
            Self::Open => "open",
        }
    }

    /// The mode called `name` ([`Self::name`]).
    ///
    /// # Errors
    /// Any other name, with the names accepted.
    pub fn from_name(name: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|c| c.name() == name)
            .ok_or_else(|| format!("control `{name}`: one of estimate, truth, open"))
    }
}

impl<'de> serde::Deserialize<'de> for Control {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let name = String::deserialize(d)?;
        Self::from_name(&name).map_err(serde::de::Error::custom)
    }
}

/// Everything that defines one run of the reference scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct ScenarioConfig {
    /// Camera offset `d`, metres.
    pub d: f64,
    /// Time step, seconds.
    pub dt: f64,
    /// Duration, seconds.
    pub duration: f64,
    /// Follower's initial pose.
    pub follower0: PlanarPose,
    /// Leader's initial pose.
    pub leader0: PlanarPose,
    /// Standard deviations of the measurement noise `[l12, alpha12, beta12]`.
    pub noise_std: [f64; 3],
    /// Constant bias added to every measurement, if any.
    pub bias: Option<[f64; 3]>,
    /// Seed of the measurement noise (`ChaCha8Rng::seed_from_u64`); the actuation and
    /// odometry noises draw from stream 1 of the same seed, so that they never change the
    /// measurement noise.
    pub seed: u64,
    /// How the follower executes its commands ([`Actuation::PERFECT`] in the paper's
    /// setting): its pose moves with the executed inputs.
    pub actuation: Actuation,
    /// Standard deviations of the follower's odometry noise `[v, w]` (m/s, rad/s): what its
    /// wheel encoders report is the executed inputs plus this white noise (0: exact).
    pub odometry_noise_std: [f64; 2],
    /// What the follower's controller acts on ([`Control::Truth`] in the paper's setting).
    pub control: Control,
}

impl ScenarioConfig {
    /// The reference scenario (see `docs/reference-scenario.md`) with the given seed, without
    /// bias: follower at (0, 0, 0), leader at (1.5, 0.25, 0), d = 0.5 m, dt = 1/30 s, 8 s,
    /// noise standard deviations (0.07 m, 0.03 rad, 0.03 rad), in the paper's setting: the
    /// follower's controller on the truth, exact actuation and odometry
    /// ([`Self::with_control`] puts it on the follower's estimate).
    pub fn reference(seed: u64) -> Self {
        Self {
            d: 0.5,
            dt: 1.0 / 30.0,
            duration: 8.0,
            follower0: PlanarPose::new(0.0, 0.0, 0.0),
            leader0: PlanarPose::new(1.5, 0.25, 0.0),
            noise_std: [0.07, 0.03, 0.03],
            bias: None,
            seed,
            actuation: Actuation::PERFECT,
            odometry_noise_std: [0.0; 2],
            control: Control::Truth,
        }
    }

    /// The same scenario with the follower's controller acting on `control`.
    pub fn with_control(mut self, control: Control) -> Self {
        self.control = control;
        self
    }

    /// The same scenario with the paper's measurement bias [`PAPER_BIAS`] added.
    pub fn with_paper_bias(mut self) -> Self {
        self.bias = Some(PAPER_BIAS);
        self
    }

    /// Measurement noise covariance `diag(std^2)`.
    pub fn noise_covariance(&self) -> nalgebra::Matrix3<f64> {
        let [a, b, c] = self.noise_std;
        nalgebra::Matrix3::from_diagonal(&Vector3::new(a * a, b * b, c * c))
    }

    /// Number of steps after the initial instant: `round(duration / dt)`.
    pub fn steps(&self) -> usize {
        let n = (self.duration / self.dt).round();
        if n.is_finite() && n >= 1.0 {
            n as usize
        } else {
            0
        }
    }
}

/// The leader's inputs of the reference scenario at time `t`:
/// `v1 = 0.8 + 0.2 sin(0.5 t)` m/s, `w1 = 0.2 sin(0.4 t)` rad/s.
pub fn reference_leader_inputs(t: f64) -> Inputs {
    Inputs::new(0.8 + 0.2 * (0.5 * t).sin(), 0.2 * (0.4 * t).sin())
}

/// One instant `t_k = k dt` of a simulated run.
#[derive(Debug, Clone, PartialEq)]
pub struct Sample {
    /// Time, seconds.
    pub t: f64,
    /// True polar state `[x1, y1, theta1, l12, alpha12, beta12]`.
    pub truth: PolarState,
    /// True follower pose.
    pub follower: PlanarPose,
    /// Leader inputs applied from `t_k` to `t_{k+1}`.
    pub leader_inputs: Inputs,
    /// Follower inputs commanded (by the formation controller) from `t_k` to `t_{k+1}`.
    pub follower_inputs: Inputs,
    /// Follower inputs its wheels executed over the same interval
    /// ([`ScenarioConfig::actuation`]): what moved it. Truth, never given to an estimator.
    pub executed_inputs: Inputs,
    /// The follower's odometry over the same interval: the executed inputs as its encoders
    /// measured them ([`ScenarioConfig::odometry_noise_std`]). What an estimator is given.
    pub odometry: Inputs,
    /// Measurement `h(x_k) + n_k` (+ bias), angles wrapped.
    pub measurement: FormationMeasurement,
    /// The follower's controller (gains and set-points) that computed
    /// [`follower_inputs`](Self::follower_inputs).
    pub controller: ControllerConfig,
}

/// A simulated run: `steps() + 1` samples from `t = 0` to `t = duration`.
#[derive(Debug, Clone, PartialEq)]
pub struct Scenario {
    /// The configuration that produced it.
    pub config: ScenarioConfig,
    /// The samples, `samples[k]` at `t = k dt`.
    pub samples: Vec<Sample>,
}

/// Simulates the scenario: both unicycles integrated exactly, the follower driven by the
/// separation-bearing controller (holding the initial `l12` and `alpha12`) on what
/// [`ScenarioConfig::control`] says, measurements drawn from the seeded noise.
///
/// # Errors
/// A bad configuration ([`ScenarioError`]), a model error (e.g. a collision), or
/// [`ScenarioError::NoEstimate`] for [`Control::Estimate`], which needs the follower's
/// estimator in the loop (`formation_sim::reproduce::ClosedLoop`).
pub fn simulate(config: &ScenarioConfig) -> Result<Scenario, ScenarioError> {
    simulate_with(config, reference_leader_inputs)
}

/// As [`simulate`] with other leader inputs.
///
/// # Errors
/// As [`simulate`].
pub fn simulate_with(
    config: &ScenarioConfig,
    leader_inputs: impl Fn(f64) -> Inputs,
) -> Result<Scenario, ScenarioError> {
    simulate_scheduled(config, leader_inputs, &[])
}

/// A change of the follower's set-points at time `at`: from the first sample with
/// `t >= at` on, the controller holds the given `l12` and/or `alpha12` (a missing one keeps
/// its previous value).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SetpointChange {
    /// Time of the change, seconds.
    pub at: f64,
    /// New desired `l12`, metres.
    pub l12: Option<f64>,
    /// New desired `alpha12`, radians.
    pub alpha12: Option<f64>,
}

/// As [`simulate_with`], with the follower's set-points changed at the given times (in any
/// order; at equal times the later entry wins).
///
/// # Errors
/// As [`simulate`]; a set-point the controller refuses (e.g. `l12 <= 0`) is a model error.
pub fn simulate_scheduled(
    config: &ScenarioConfig,
    leader_inputs: impl Fn(f64) -> Inputs,
    setpoints: &[SetpointChange],
) -> Result<Scenario, ScenarioError> {
    let simulation = Simulation::new(config, leader_inputs, setpoints)?;
    let mut samples = Vec::with_capacity(config.steps() + 1);
    for sample in simulation {
        samples.push(sample?);
    }
    Ok(Scenario {
        config: config.clone(),
        samples,
    })
}

/// A scenario simulated one sample at a time: the same samples as [`simulate_scheduled`]
/// (which collects them), in the same order, from the same random stream, but in constant
/// memory whatever the duration. `reproduce dukf` filters a scenario of hours through it.
///
/// Yields `config.steps() + 1` samples (`t = 0, dt, ..., duration`); after an error it
/// yields nothing more. As an iterator it has no estimator, so a run with
/// [`Control::Estimate`] fails at its first sample ([`ScenarioError::NoEstimate`]): drive it
/// with [`Simulation::step`] (as `formation_sim::reproduce::ClosedLoop` does).
pub struct Simulation<F> {
    config: ScenarioConfig,
    leader_inputs: F,
    noise: [Normal<f64>; 3],
    bias: [f64; 3],
    model: PolarModel,
    goal: ControllerConfig,
    controller: SeparationBearingController,
    schedule: Vec<SetpointChange>,
    next_change: usize,
    rng: ChaCha8Rng,
    /// Stream 1 of the seed: actuation and odometry noise.
    actuation_rng: ChaCha8Rng,
    leader: PlanarPose,
    follower: PlanarPose,
    /// Where the follower would be had it executed its commands exactly ([`Control::Open`]).
    planned_follower: PlanarPose,
    /// The next sample's index `k`; `None` once finished or failed.
    k: Option<usize>,
    n: usize,
}

impl<F: Fn(f64) -> Inputs> Simulation<F> {
    /// Checks `config` and sets up the run; nothing is simulated yet.
    ///
    /// # Errors
    /// As [`simulate_scheduled`] for the configuration itself (no step, a bad noise
    /// deviation, a degenerate start, a set-point the controller refuses at the start).
    pub fn new(
        config: &ScenarioConfig,
        leader_inputs: F,
        setpoints: &[SetpointChange],
    ) -> Result<Self, ScenarioError> {
        let n = config.steps();
        if n == 0 || !config.dt.is_finite() {
            return Err(ScenarioError::NoSteps {
                duration: config.duration,
                dt: config.dt,
            });
        }
        let normal = |index: usize| {
            let s = config.noise_std[index];
            // Normal::new refuses only non-finite deviations; a negative one is refused here.
            let invalid = ScenarioError::InvalidNoise { index, value: s };
            if s < 0.0 {
                return Err(invalid);
            }
            Normal::new(0.0, s).map_err(|_| invalid)
        };
        let noise = [normal(0)?, normal(1)?, normal(2)?];
        config.actuation.validate()?;
        for (index, &s) in config.odometry_noise_std.iter().enumerate() {
            if !(s.is_finite() && s >= 0.0) {
                return Err(ScenarioError::InvalidOdometryNoise { index, value: s });
            }
        }
        let model = PolarModel::new(config.d)?;
        let start = Formation::from_poses(&config.leader0, &config.follower0, config.d)?;
        let goal = ControllerConfig::hold(&start);
        let controller = SeparationBearingController::new(config.d, goal)?;
        let mut schedule = setpoints.to_vec();
        schedule.sort_by(|a, b| a.at.total_cmp(&b.at));
        Ok(Self {
            config: config.clone(),
            leader_inputs,
            noise,
            bias: config.bias.unwrap_or([0.0; 3]),
            model,
            goal,
            controller,
            schedule,
            next_change: 0,
            rng: ChaCha8Rng::seed_from_u64(config.seed),
            actuation_rng: actuation_rng(config.seed),
            leader: config.leader0,
            follower: config.follower0,
            planned_follower: config.follower0,
            k: Some(0),
            n,
        })
    }

    /// The scenario's configuration.
    pub fn config(&self) -> &ScenarioConfig {
        &self.config
    }

    /// The instant `t_k` as the follower sees it before it acts: the truth, the measurement
    /// and the controller in force (set-point changes due at `t_k` applied).
    fn observe(&mut self, k: usize) -> Result<Observation, ScenarioError> {
        let t = k as f64 * self.config.dt;
        let truth = self.model.state_from_poses(&self.leader, &self.follower)?;
        let mut changed = false;
        while let Some(change) = self.schedule.get(self.next_change).filter(|c| t >= c.at) {
            self.goal = self.goal.with_setpoints(change.l12, change.alpha12);
            self.next_change += 1;
            changed = true;
        }
        if changed {
            self.controller = SeparationBearingController::new(self.config.d, self.goal)?;
        }
        let mut y = PolarModel::h(&truth);
        for i in 0..3 {
            y[i] += self.bias[i] + self.noise[i].sample(&mut self.rng);
        }
        Ok(Observation {
            t,
            truth,
            follower: self.follower,
            leader_inputs: (self.leader_inputs)(t),
            measurement: MEASUREMENT_SPACE.normalize(&y),
            controller: self.goal,
        })
    }

    /// The follower's command at the observed instant ([`ScenarioConfig::control`]), what its
    /// wheels execute and its odometry, and both robots moved on to step `k + 1`.
    fn act(
        &mut self,
        k: usize,
        seen: Observation,
        estimate: Option<(Formation, Inputs)>,
    ) -> Result<Sample, ScenarioError> {
        let dt = self.config.dt;
        let u1 = seen.leader_inputs;
        let u2 = match self.config.control {
            Control::Truth => {
                let formation = Formation::from_vector(&PolarModel::h(&seen.truth));
                self.controller.inputs(&formation, u1)?
            }
            Control::Estimate => {
                let (formation, leader) =
                    estimate.ok_or(ScenarioError::NoEstimate { t: seen.t })?;
                self.controller.inputs(&formation, leader)?
            }
            Control::Open => {
                let planned =
                    Formation::from_poses(&self.leader, &self.planned_follower, self.config.d)?;
                self.controller.inputs(&planned, u1)?
            }
        };
        let (executed, odometry) = follower_motion(
            &self.config.actuation,
            self.config.odometry_noise_std,
            u2,
            &mut self.actuation_rng,
        );
        if k < self.n {
            self.leader = self.leader.integrate_exact(u1, dt)?;
            self.follower = self.follower.integrate_exact(executed, dt)?;
            if self.config.control == Control::Open {
                self.planned_follower = self.planned_follower.integrate_exact(u2, dt)?;
            }
        }
        Ok(Sample {
            t: seen.t,
            truth: seen.truth,
            follower: seen.follower,
            leader_inputs: u1,
            follower_inputs: u2,
            executed_inputs: executed,
            odometry,
            measurement: seen.measurement,
            controller: seen.controller,
        })
    }

    /// The next sample, with the follower's estimate taken between the measurement and its
    /// command: `estimator` is given what the follower observes at `t_k` (it must use only
    /// [`Observation::measurement`] and what it kept of earlier samples' odometry and
    /// controller) and returns the follower's estimate of the formation and of the leader's
    /// inputs, or `None` when it has none. [`Control::Estimate`] commands from that estimate
    /// (and fails with [`ScenarioError::NoEstimate`] without one); the other modes call the
    /// estimator too, and ignore its answer. `None` once the run is over or failed.
    pub fn step<E: From<ScenarioError>>(
        &mut self,
        estimator: impl FnOnce(&Observation) -> Result<Option<(Formation, Inputs)>, E>,
    ) -> Option<Result<Sample, E>> {
        let k = self.k?;
        let run = || -> Result<Sample, E> {
            let seen = self.observe(k)?;
            let estimate = estimator(&seen)?;
            Ok(self.act(k, seen, estimate)?)
        };
        let sample = run();
        self.k = (sample.is_ok() && k < self.n).then_some(k + 1);
        Some(sample)
    }
}

/// What the follower has at `t_k` before it commands the next step, with the truth beside it
/// for scoring (an estimator takes only the measurement).
#[derive(Debug, Clone, PartialEq)]
pub struct Observation {
    /// Time, seconds.
    pub t: f64,
    /// True polar state, for scoring only.
    pub truth: PolarState,
    /// True follower pose, for scoring only.
    pub follower: PlanarPose,
    /// True leader inputs from `t_k` to `t_{k+1}`, for scoring only.
    pub leader_inputs: Inputs,
    /// Measurement `h(x_k) + n_k` (+ bias), angles wrapped.
    pub measurement: FormationMeasurement,
    /// The follower's controller in force from `t_k`.
    pub controller: ControllerConfig,
}

impl Sample {
    /// What the follower had at this sample's instant before it acted.
    pub fn observation(&self) -> Observation {
        Observation {
            t: self.t,
            truth: self.truth,
            follower: self.follower,
            leader_inputs: self.leader_inputs,
            measurement: self.measurement,
            controller: self.controller,
        }
    }
}

/// What a follower commanded with `commanded` does: the inputs its wheels execute
/// ([`Actuation::execute`]) and what its odometry reports of them (plus white noise of
/// `odometry_noise_std`). Four standard normal draws from `rng` every call, used or not, so
/// that one setting never shifts the noise of another; exact when the actuation is perfect
/// and the odometry noiseless.
pub(crate) fn follower_motion(
    actuation: &Actuation,
    odometry_noise_std: [f64; 2],
    commanded: Inputs,
    rng: &mut ChaCha8Rng,
) -> (Inputs, Inputs) {
    let mut n01 = || StandardNormal.sample(&mut *rng);
    let draws: [f64; 4] = [n01(), n01(), n01(), n01()];
    let executed = actuation.execute(commanded, [draws[0], draws[1]]);
    // The encoders add white noise and no scale error: an actuation of scale one.
    let encoders = Actuation {
        scale: [1.0; 2],
        noise_std: odometry_noise_std,
    };
    (executed, encoders.execute(executed, [draws[2], draws[3]]))
}

/// The generator of the actuation and odometry noise for `seed`: stream 1, apart from the
/// measurement noise (stream 0).
pub(crate) fn actuation_rng(seed: u64) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(1);
    rng
}

impl<F: Fn(f64) -> Inputs> Iterator for Simulation<F> {
    type Item = Result<Sample, ScenarioError>;

    fn next(&mut self) -> Option<Self::Item> {
        self.step(|_| Ok::<_, ScenarioError>(None))
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        let left = self.k.map_or(0, |k| self.n + 1 - k);
        (left, Some(left))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// #30: the follower moves by what its wheels executed and reports its odometry; the
    /// measurement noise is the same stream whatever the actuation.
    #[test]
    fn the_follower_moves_by_the_executed_inputs_and_reports_its_odometry() {
        let perfect = simulate(&ScenarioConfig::reference(5)).unwrap();
        for s in &perfect.samples {
            assert_eq!(s.executed_inputs, s.follower_inputs);
            assert_eq!(s.odometry, s.follower_inputs);
        }
        let mut config = ScenarioConfig::reference(5);
        config.actuation = Actuation {
            scale: [0.95, 1.0],
            noise_std: [0.0, 0.0],
        };
        let scaled = simulate(&config).unwrap();
        for s in &scaled.samples {
            assert_eq!(s.executed_inputs.v, 0.95 * s.follower_inputs.v);
            assert_eq!(s.executed_inputs.w, s.follower_inputs.w);
            assert_eq!(s.odometry, s.executed_inputs);
        }
        config.actuation.noise_std = [0.03, 0.03];
        config.odometry_noise_std = [0.01, 0.02];
        let noisy = simulate(&config).unwrap();
        let (mut act, mut odo) = (Vector3::zeros(), Vector3::zeros());
        for pair in noisy.samples.windows(2) {
            let (s, next) = (&pair[0], &pair[1]);
            // The pose moves by the executed inputs.
            let moved = s
                .follower
                .integrate_exact(s.executed_inputs, config.dt)
                .unwrap();
            assert_eq!(moved, next.follower);
            let e = s.executed_inputs.v - 0.95 * s.follower_inputs.v;
            let o = s.odometry.w - s.executed_inputs.w;
            act += Vector3::new(1.0, e, e * e);
            odo += Vector3::new(1.0, o, o * o);
        }
        // Sample standard deviations near the settings (240 draws: within 20 %).
        for (sum, std) in [(act, 0.03), (odo, 0.02)] {
            let n = sum[0];
            let sd = (sum[2] / n - (sum[1] / n).powi(2)).sqrt();
            assert!((sd / std - 1.0).abs() < 0.2, "{sd} vs {std}");
        }
        // The measurement noise draws are those of the perfect run.
        for (a, b) in perfect.samples.iter().zip(&noisy.samples) {
            let na = MEASUREMENT_SPACE.normalize(&(a.measurement - PolarModel::h(&a.truth)));
            let nb = MEASUREMENT_SPACE.normalize(&(b.measurement - PolarModel::h(&b.truth)));
            assert!((na - nb).norm() < 1e-12, "{na} vs {nb}");
        }
        // Bad settings are errors.
        config.odometry_noise_std = [f64::NAN, 0.0];
        assert!(matches!(
            simulate(&config),
            Err(ScenarioError::InvalidOdometryNoise { index: 0, .. })
        ));
        config.odometry_noise_std = [0.0; 2];
        config.actuation.scale = [0.0, 1.0];
        assert!(matches!(simulate(&config), Err(ScenarioError::Model(_))));
    }

    /// #30: `control` decides what the follower's command is computed from.
    #[test]
    fn the_follower_commands_from_its_estimate_the_truth_or_its_plan() {
        let truth = simulate(&ScenarioConfig::reference(4)).unwrap();
        // As an iterator, control on the estimate has none: a typed error at t = 0.
        let estimate = ScenarioConfig::reference(4).with_control(Control::Estimate);
        assert!(matches!(
            simulate(&estimate),
            Err(ScenarioError::NoEstimate { t }) if t == 0.0
        ));
        // Given the truth as its "estimate", the estimate-driven run is the paper's run.
        let mut sim = Simulation::new(&estimate, reference_leader_inputs, &[]).unwrap();
        let mut calls = 0;
        let mut fed = Vec::new();
        while let Some(s) = sim.step(|seen| {
            calls += 1;
            Ok::<_, ScenarioError>(Some((
                Formation::from_vector(&PolarModel::h(&seen.truth)),
                seen.leader_inputs,
            )))
        }) {
            fed.push(s.unwrap());
        }
        assert_eq!(calls, 241);
        assert_eq!(fed, truth.samples);
        // A biased estimate moves the follower: the command is the controller's on it.
        let goal = truth.samples[0].controller;
        let controller = SeparationBearingController::new(0.5, goal).unwrap();
        let mut sim = Simulation::new(&estimate, reference_leader_inputs, &[]).unwrap();
        let mut biased = Vec::new();
        while let Some(s) = sim.step(|seen| {
            let mut f = Formation::from_vector(&PolarModel::h(&seen.truth));
            f.l12 += 0.1;
            Ok::<_, ScenarioError>(Some((f, Inputs::new(0.8, 0.0))))
        }) {
            biased.push(s.unwrap());
        }
        for s in &biased {
            let mut f = Formation::from_vector(&PolarModel::h(&s.truth));
            f.l12 += 0.1;
            let u = controller.inputs(&f, Inputs::new(0.8, 0.0)).unwrap();
            assert_eq!(s.follower_inputs, u);
        }
        // The follower closes in on a leader it believes 10 cm further away.
        let last = biased.last().unwrap();
        assert!(last.truth[3] < truth.samples.last().unwrap().truth[3] - 0.05);
        // Open loop with exact actuation is the paper's run; with a scale error it drifts
        // where the truth-driven follower corrects it.
        let open = simulate(&ScenarioConfig::reference(4).with_control(Control::Open)).unwrap();
        for (a, b) in open.samples.iter().zip(&truth.samples) {
            assert!(
                (a.truth - b.truth).norm() < 1e-9,
                "{} vs {}",
                a.truth,
                b.truth
            );
        }
        let slow = Actuation {
            scale: [0.9, 1.0],
            noise_std: [0.0; 2],
        };
        let mut config = ScenarioConfig::reference(4).with_control(Control::Open);
        config.actuation = slow;
        let drift = simulate(&config).unwrap();
        config.control = Control::Truth;
        let held = simulate(&config).unwrap();
        let l0 = truth.samples[0].truth[3];
        let error = |s: &Scenario| (s.samples.last().unwrap().truth[3] - l0).abs();
        assert!(error(&drift) > 0.3, "open loop drifts: {}", error(&drift));
        // (Feedback leaves the controller's steady-state error of a 10 % slow wheel, about
        // 0.1 v1 / k_l = 8 cm.)
        assert!(error(&held) < 0.1, "feedback holds: {}", error(&held));
        assert!(error(&drift) > 3.0 * error(&held));
    }

    #[test]
    fn same_seed_same_run_other_seed_other_noise() {
        let a = simulate(&ScenarioConfig::reference(7)).unwrap();
        let b = simulate(&ScenarioConfig::reference(7)).unwrap();
        let c = simulate(&ScenarioConfig::reference(8)).unwrap();
        assert_eq!(a, b);
        assert_eq!(a.samples.len(), 241);
        // The truth does not depend on the seed, the measurements do.
        assert_eq!(a.samples[100].truth, c.samples[100].truth);
        assert_ne!(a.samples[100].measurement, c.samples[100].measurement);
    }

    #[test]
    fn truth_starts_at_the_poses_and_the_controller_holds_the_formation() {
        let s = simulate(&ScenarioConfig::reference(1)).unwrap();
        let x0 = s.samples[0].truth;
        // Follower (0, 0, 0) with d = 0.5: camera at (0.5, 0), leader at (1.5, 0.25).
        assert!((x0[3] - (1.0f64 + 0.0625).sqrt()).abs() < 1e-12);
        assert!((x0[4] - 0.25f64.atan2(1.0)).abs() < 1e-12);
        for sample in &s.samples {
            assert!(
                (sample.truth[3] - x0[3]).abs() < 5e-3,
                "l12 {}",
                sample.truth[3]
            );
            assert!(
                (sample.truth[4] - x0[4]).abs() < 5e-3,
                "alpha12 {}",
                sample.truth[4]
            );
        }
        let last = s.samples.last().unwrap();
        assert!((last.t - 8.0).abs() < 1e-12);
        // The leader really moved: about 6.4 m along its path.
        assert!(last.truth[0] > 6.0);
    }

    #[test]
    fn measurement_noise_has_the_configured_spread_and_bias() {
        let noise = |bias: bool| {
            let mut cfg = ScenarioConfig::reference(3);
            cfg.duration = 200.0;
            if bias {
                cfg = cfg.with_paper_bias();
            }
            let s = simulate(&cfg).unwrap();
            let n = s.samples.len() as f64;
            let mut mean = Vector3::zeros();
            let mut sq = Vector3::zeros();
            for x in &s.samples {
                let e = MEASUREMENT_SPACE.normalize(&(x.measurement - PolarModel::h(&x.truth)));
                mean += e / n;
                sq += e.component_mul(&e) / n;
            }
            (mean, sq - mean.component_mul(&mean))
        };
        let (mean, var) = noise(false);
        for (i, s) in [0.07f64, 0.03, 0.03].iter().enumerate() {
            assert!(mean[i].abs() < 3.0 * s / 77.0, "mean {i} = {}", mean[i]);
            assert!(
                (var[i].sqrt() / s - 1.0).abs() < 0.05,
                "std {i} = {}",
                var[i].sqrt()
            );
        }
        let (mean, _) = noise(true);
        for i in 0..3 {
            assert!(
                (mean[i] - PAPER_BIAS[i]).abs() < 0.005,
                "bias {i} = {}",
                mean[i]
            );
        }
    }

    #[test]
    fn bad_configurations_are_errors() {
        let mut cfg = ScenarioConfig::reference(1);
        cfg.noise_std[1] = -0.1;
        assert!(matches!(
            simulate(&cfg),
            Err(ScenarioError::InvalidNoise { index: 1, .. })
        ));
        let mut cfg = ScenarioConfig::reference(1);
        cfg.duration = 0.0;
        assert!(matches!(simulate(&cfg), Err(ScenarioError::NoSteps { .. })));
        let mut cfg = ScenarioConfig::reference(1);
        cfg.leader0 = PlanarPose::new(0.5, 0.0, 0.0);
        assert!(matches!(
            simulate(&cfg),
            Err(ScenarioError::Model(
                UnicycleError::SeparationTooSmall { .. }
            ))
        ));
    }
}
