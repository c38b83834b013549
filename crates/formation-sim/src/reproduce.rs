//! The reproduction of the paper's Figs. 12-13: the formation filter (the IMM by default,
//! the paper's dual UKF on request) run over a simulated [`Scenario`], step records, and the
//! figures of merit.

use formation_filter::{FilterConfig, FilterDesign, FilterError, FilterStep, FormationFilter};
use nalgebra::{Matrix3, Vector2, Vector3};
use serde::Serialize;
use unicycle::{Formation, Inputs, PolarModel, PolarState, wrap_angle};

use crate::scenario::{
    Control, Observation, PAPER_X0, Sample, Scenario, ScenarioConfig, ScenarioError, Simulation,
    simulate,
};

/// Errors of a reproduction run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReproduceError {
    /// The scenario could not be simulated.
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    /// The formation filter failed.
    #[error(transparent)]
    Filter(#[from] FilterError),
    /// Smoothing was asked of a [`FilterRun`] that kept no history of these records.
    #[error(
        "no filter history to smooth: the run was made without keeping one (FilterRun::new with keep_history = false), or the records are not the run's"
    )]
    NoHistory,
}

/// The filter configuration of the reproduction: the paper's initial state `x0` with the
/// reference tuning (the IMM design).
pub fn paper_filter_config(d: f64, dt: f64) -> FilterConfig {
    let mut config = FilterConfig::new(d, dt, PolarState::from_row_slice(&PAPER_X0));
    config.tuning.design = FilterDesign::Imm;
    config
}

/// [`paper_filter_config`] with the given filter design.
pub fn paper_filter_config_with(d: f64, dt: f64, design: FilterDesign) -> FilterConfig {
    let mut config = paper_filter_config(d, dt);
    config.tuning.design = design;
    config
}

/// One filtered frame of a reproduction run.
#[derive(Debug, Clone, PartialEq)]
pub struct StepRecord {
    /// Time, seconds.
    pub t: f64,
    /// True `[l12, alpha12, beta12]`.
    pub truth: Vector3<f64>,
    /// Measured `[l12, alpha12, beta12]`.
    pub measured: Vector3<f64>,
    /// Estimated `[l12, alpha12, beta12]`.
    pub estimated: Vector3<f64>,
    /// Standard deviations of the estimate.
    pub estimated_std: Vector3<f64>,
    /// True `v1` over the step that ended at `t`, m/s.
    pub v1_true: f64,
    /// True `w1` over the step that ended at `t`, rad/s.
    pub w1_true: f64,
    /// Estimated `v1`, m/s.
    pub v1_estimated: f64,
    /// Estimated `w1`, rad/s.
    pub w1_estimated: f64,
    /// Standard deviation of `v1`, m/s.
    pub v1_std: f64,
    /// Standard deviation of `w1`, rad/s.
    pub w1_std: f64,
}

fn wrapped_error(a: &Vector3<f64>, b: &Vector3<f64>) -> Vector3<f64> {
    Vector3::new(
        a[0] - b[0],
        wrap_angle(a[1] - b[1]),
        wrap_angle(a[2] - b[2]),
    )
}

impl StepRecord {
    /// Measured minus true (angles wrapped).
    pub fn measurement_error(&self) -> Vector3<f64> {
        wrapped_error(&self.measured, &self.truth)
    }

    /// Estimated minus true (angles wrapped).
    pub fn estimation_error(&self) -> Vector3<f64> {
        wrapped_error(&self.estimated, &self.truth)
    }
}

/// The mean square errors every run reports, of the estimate and of the raw vision
/// measurement, written flat into `summary.json` as `mse_l12`, `mse_alpha12`, `mse_beta12`,
/// `mse_v1`, `mse_w1`, `mse_meas_l12`, `mse_meas_alpha12`, `mse_meas_beta12`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MseSummary {
    /// Of the estimated `l12`, m^2.
    #[serde(rename = "mse_l12")]
    pub l12: f64,
    /// Of the estimated `alpha12`, rad^2.
    #[serde(rename = "mse_alpha12")]
    pub alpha12: f64,
    /// Of the estimated `beta12`, rad^2.
    #[serde(rename = "mse_beta12")]
    pub beta12: f64,
    /// Of the estimated `v1`, (m/s)^2.
    #[serde(rename = "mse_v1")]
    pub v1: f64,
    /// Of the estimated `w1`, (rad/s)^2.
    #[serde(rename = "mse_w1")]
    pub w1: f64,
    /// Of the raw measured `l12`, m^2.
    #[serde(rename = "mse_meas_l12")]
    pub meas_l12: f64,
    /// Of the raw measured `alpha12`, rad^2.
    #[serde(rename = "mse_meas_alpha12")]
    pub meas_alpha12: f64,
    /// Of the raw measured `beta12`, rad^2.
    #[serde(rename = "mse_meas_beta12")]
    pub meas_beta12: f64,
}

impl MseSummary {
    /// From the estimate's `[l12, alpha12, beta12, v1, w1]` and the measurement's
    /// `[l12, alpha12, beta12]` mean square errors.
    pub fn new(estimate: [f64; 5], measurement: [f64; 3]) -> Self {
        let [l12, alpha12, beta12, v1, w1] = estimate;
        let [meas_l12, meas_alpha12, meas_beta12] = measurement;
        Self {
            l12,
            alpha12,
            beta12,
            v1,
            w1,
            meas_l12,
            meas_alpha12,
            meas_beta12,
        }
    }
}

/// Figures of one run (the fields of `summary.json`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Summary {
    /// The mean square errors of the estimate and of the raw measurement over all filtered
    /// steps (in `summary.json` as the top-level fields `mse_l12` ... `mse_meas_beta12`).
    #[serde(flatten)]
    pub mse: MseSummary,
    /// RMS error of `v1` over the steps with `t > 2 s`, m/s.
    pub rms_v1_after_2s: f64,
    /// RMS error of `w1` over the steps with `t > 2 s`, rad/s.
    pub rms_w1_after_2s: f64,
    /// Number of filtered steps the MSEs average over.
    pub steps: usize,
    /// Time of the first step counted, seconds (no initial transient is skipped).
    pub mse_from_t: f64,
    /// Seed of the measurement noise.
    pub seed: u64,
    /// Whether the paper's measurement bias was added.
    pub bias: bool,
    /// What the follower's controller acted on: `estimate` (the filter's, as on a robot),
    /// `truth` (the paper's setting) or `open`.
    pub control: Control,
}

/// Mean square errors of a run's records, the estimate and the raw measurement each over
/// the records where it is finite (a frame without an estimate or without a measurement,
/// NaN in its [`StepRecord`], is left out of that mean, not counted as zero).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeanSquareErrors {
    /// `[l12, alpha12, beta12, v1, w1]` estimate minus truth, squared and averaged (m^2,
    /// rad^2, rad^2, (m/s)^2, (rad/s)^2).
    pub estimate: [f64; 5],
    /// `[l12, alpha12, beta12]` measurement minus truth, squared and averaged.
    pub measurement: [f64; 3],
    /// Records with a finite estimate.
    pub estimated: usize,
    /// Records with a finite measurement.
    pub measured: usize,
    /// RMS of the `v1` and `w1` errors over the records with an estimate and `t > 2 s`.
    pub rms_velocity_after_2s: [f64; 2],
}

impl MeanSquareErrors {
    /// Accumulates `records` (angles wrapped, see [`StepRecord::estimation_error`]).
    pub fn of<'a>(records: impl IntoIterator<Item = &'a StepRecord>) -> Self {
        let mut tally = ErrorTally::default();
        for r in records {
            tally.push(r);
        }
        tally.finish()
    }
}

/// [`MeanSquareErrors`] accumulated one record at a time, in constant memory (the same sums
/// in the same order as [`MeanSquareErrors::of`], so the same figures to the bit).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ErrorTally {
    est: [f64; 5],
    meas: [f64; 3],
    late: [f64; 2],
    n_late: usize,
    estimated: usize,
    measured: usize,
}

impl ErrorTally {
    /// Adds one record.
    pub fn push(&mut self, r: &StepRecord) {
        let e = r.estimation_error();
        let errors = [
            e[0],
            e[1],
            e[2],
            r.v1_estimated - r.v1_true,
            r.w1_estimated - r.w1_true,
        ];
        if errors.iter().all(|v| v.is_finite()) {
            for (acc, x) in self.est.iter_mut().zip(errors) {
                *acc += x * x;
            }
            self.estimated += 1;
            if r.t > 2.0 {
                self.late[0] += errors[3] * errors[3];
                self.late[1] += errors[4] * errors[4];
                self.n_late += 1;
            }
        }
        let m = r.measurement_error();
        if m.iter().all(|v| v.is_finite()) {
            for (acc, x) in self.meas.iter_mut().zip(m.iter()) {
                *acc += x * x;
            }
            self.measured += 1;
        }
    }

    /// The means of what was pushed (zeros for nothing).
    pub fn finish(&self) -> MeanSquareErrors {
        let (ne, nm, nl) = (
            self.estimated.max(1) as f64,
            self.measured.max(1) as f64,
            self.n_late.max(1) as f64,
        );
        MeanSquareErrors {
            estimate: self.est.map(|v| v / ne),
            measurement: self.meas.map(|v| v / nm),
            estimated: self.estimated,
            measured: self.measured,
            rms_velocity_after_2s: self.late.map(|v| (v / nl).sqrt()),
        }
    }
}

/// The figures of a run ([`Summary`]) of the scenario `scenario` from its step records.
pub fn summarize(records: &[StepRecord], scenario: &ScenarioConfig) -> Summary {
    let mut tally = SummaryTally::default();
    for r in records {
        tally.push(r);
    }
    tally.finish(scenario)
}

/// [`summarize`] one record at a time, in constant memory (the same figures to the bit).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SummaryTally {
    errors: ErrorTally,
    steps: usize,
    first_t: Option<f64>,
}

impl SummaryTally {
    /// Adds one record.
    pub fn push(&mut self, r: &StepRecord) {
        self.errors.push(r);
        self.steps += 1;
        self.first_t.get_or_insert(r.t);
    }

    /// The summary of what was pushed, from a run of `scenario`.
    pub fn finish(&self, scenario: &ScenarioConfig) -> Summary {
        let m = self.errors.finish();
        Summary {
            mse: MseSummary::new(m.estimate, m.measurement),
            rms_v1_after_2s: m.rms_velocity_after_2s[0],
            rms_w1_after_2s: m.rms_velocity_after_2s[1],
            steps: self.steps,
            mse_from_t: self.first_t.unwrap_or(0.0),
            seed: scenario.seed,
            bias: scenario.bias.is_some(),
            control: scenario.control,
        }
    }
}

/// The consistency statistics of one filtered frame (Bar-Shalom's tests): each is
/// chi-square distributed with the given degrees of freedom when the filter is consistent.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepConsistency {
    /// Normalised innovation squared of the state update (3 degrees of freedom).
    pub nis: f64,
    /// Normalised estimation error squared of the measured state components
    /// `[l12, alpha12, beta12]` against their 3 x 3 covariance block (3 degrees of freedom).
    pub nees_formation: f64,
    /// Normalised estimation error squared of the leader velocities `[v1, w1]` against the
    /// parameter covariance (2 degrees of freedom).
    pub nees_velocity: f64,
}

/// A filtered run of a scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct Reproduction {
    /// The scenario's configuration.
    pub scenario: ScenarioConfig,
    /// One record per filtered frame, `t = dt, 2 dt, ..., duration`.
    pub records: Vec<StepRecord>,
    /// The consistency statistics of the same frames.
    pub consistency: Vec<StepConsistency>,
    /// Its figures.
    pub summary: Summary,
    /// The same frames after the offline unscented RTS smoother
    /// ([`FormationFilter::smooth`]) ran backwards over the whole run: `estimated`, the
    /// velocities and their standard deviations are the smoothed ones, everything else as in
    /// [`records`](Self::records).
    pub smoothed_records: Vec<StepRecord>,
    /// The figures of [`smoothed_records`](Self::smoothed_records).
    pub smoothed_summary: Summary,
}

/// Runs the formation filter over a simulated scenario: the filter starts at `t = 0` from
/// its configured prior, and at every later frame `k` takes the follower's inputs applied
/// over `(t_{k-1}, t_k]`, the follower's controller in force over that step (the follower
/// knows its own controller: [`FormationFilter::set_follower_controller`],
/// [`Sample::controller`](crate::scenario::Sample::controller); the IMM's model B uses it,
/// the dual UKF ignores it) and the measurement at `t_k`. Then the offline smoother runs over
/// the recorded pass (see [`Reproduction::smoothed_records`]).
///
/// # Errors
/// Any [`ReproduceError`].
pub fn run_filter(
    scenario: &Scenario,
    config: &FilterConfig,
) -> Result<Reproduction, ReproduceError> {
    run_filter_with(scenario, config, true)
}

/// As [`run_filter`]; with `follower_controller = false` the filter is *not* told the
/// follower's controller, so the IMM's models B and C assume an exactly held formation (the
/// model set before the controller was wired; `docs/dukf-reproduction.md`, measurements
/// 10-12). It is told when the follower changes its set-point
/// ([`FormationFilter::follower_setpoint_changed`]), as the demo's tracker is.
///
/// # Errors
/// Any [`ReproduceError`].
pub fn run_filter_with(
    scenario: &Scenario,
    config: &FilterConfig,
    follower_controller: bool,
) -> Result<Reproduction, ReproduceError> {
    let mut run = FilterRun::new(config, &scenario.config, follower_controller, true)?;
    let mut records = Vec::with_capacity(scenario.samples.len());
    let mut consistency = Vec::with_capacity(scenario.samples.len());
    for sample in &scenario.samples {
        if let Some((record, stats)) = run.push(sample)? {
            records.push(record);
            consistency.push(stats);
        }
    }
    reproduction(&run, &scenario.config, records, consistency)
}

/// A run's [`Reproduction`] from its records and consistency statistics: the summaries, and
/// the smoother over `run`'s history.
fn reproduction(
    run: &FilterRun,
    scenario: &ScenarioConfig,
    records: Vec<StepRecord>,
    consistency: Vec<StepConsistency>,
) -> Result<Reproduction, ReproduceError> {
    let summary = summarize(&records, scenario);
    let smoothed_records = run.smoothed_records(&records)?;
    let smoothed_summary = summarize(&smoothed_records, scenario);
    Ok(Reproduction {
        scenario: scenario.clone(),
        records,
        consistency,
        summary,
        smoothed_records,
        smoothed_summary,
    })
}

/// The formation filter run over a scenario one sample at a time, as [`run_filter_with`]
/// does (the same records to the bit), for runs too long to hold: it keeps only the filter
/// and, if asked, the history the offline smoother needs (one [`FilterStep`] per step, about
/// 1.4 kB), so without the smoother its memory does not grow with the duration.
pub struct FilterRun {
    filter: FormationFilter,
    r: Matrix3<f64>,
    follower_controller: bool,
    previous: Option<Sample>,
    /// The set-point `[l12, alpha12]` the follower held before `previous`.
    before: Option<[f64; 2]>,
    history: Option<Vec<FilterStep>>,
    /// Restart from the first measurement with this configuration (see [`Self::new`]).
    restart: Option<FilterConfig>,
    /// Whether the filter is handed the leader's true inputs before each step
    /// ([`Self::oracle`]).
    oracle: bool,
}

/// Standard deviation of the leader's world pose `[x1, y1, theta1]` when a filter starts at
/// its first measurement (m, m, rad): no measurement sees it and the formation does not
/// depend on it ([`FilterConfig::started_at`]).
pub const START_WORLD_POSE_STD: f64 = 1.0;

impl FilterRun {
    /// A run of the filter `config` over samples of a scenario with configuration
    /// `scenario` (its measurement noise is the filter's `R`); with `follower_controller` the
    /// filter is told the follower's controller at each step (see [`run_filter_with`]); with
    /// `keep_history` every step is recorded for [`Self::smoothed_records`].
    ///
    /// In the paper's setting ([`Control::Truth`]) the filter starts at `config`'s prior (the
    /// paper's `x0`). Otherwise it starts, as a robot's does, at the first measurement it is
    /// given (`t = 0`; [`FilterConfig::started_at`] with the measurement covariance and
    /// [`START_WORLD_POSE_STD`]); the leader velocities keep their configured prior.
    ///
    /// # Errors
    /// A filter configuration [`FormationFilter::new`] refuses.
    pub fn new(
        config: &FilterConfig,
        scenario: &ScenarioConfig,
        follower_controller: bool,
        keep_history: bool,
    ) -> Result<Self, ReproduceError> {
        let filter = FormationFilter::new(config)?;
        let history =
            keep_history.then(|| vec![filter.record(unicycle::Inputs::new(0.0, 0.0), None)]);
        Ok(Self {
            filter,
            r: scenario.noise_covariance(),
            follower_controller,
            previous: None,
            before: None,
            history,
            // Off the paper's setting the filter starts as a robot's does.
            restart: (scenario.control != Control::Truth).then(|| config.clone()),
            oracle: false,
        })
    }

    /// **An oracle, for comparisons only**: before every step the filter is handed the
    /// leader's true inputs over it ([`FormationFilter::pin_leader_velocity`]). The
    /// held-out table's oracle column (issue #30): what the same filter reaches when the
    /// leader's velocities are known. No robot has them.
    pub fn oracle(mut self) -> Self {
        self.oracle = true;
        self
    }

    /// Feeds the next sample. The first sample (`t = 0`) only starts the run and gives
    /// `None`; every later one is filtered (the follower's inputs and controller of the
    /// previous sample over the step, this sample's measurement) and gives its record and
    /// consistency statistics.
    ///
    /// # Errors
    /// A [`ReproduceError::Filter`] from the filter's step.
    pub fn push(
        &mut self,
        now: &Sample,
    ) -> Result<Option<(StepRecord, StepConsistency)>, ReproduceError> {
        let out = self.observe(&now.observation())?;
        self.acted(now.clone());
        Ok(out)
    }

    /// The filter as it stands (e.g. its model probabilities, [`FormationFilter::model_probabilities`]).
    pub fn filter(&self) -> &FormationFilter {
        &self.filter
    }

    /// The follower's estimate of the formation and of the leader's inputs now: what its
    /// controller acts on under [`Control::Estimate`].
    pub fn control_estimate(&self) -> (Formation, Inputs) {
        (self.filter.formation(), self.filter.leader_velocity())
    }

    /// Records the sample the follower acted on, whose odometry and controller the next
    /// [`Self::observe`] filters over.
    pub fn acted(&mut self, sample: Sample) {
        self.before = self
            .previous
            .as_ref()
            .map(|p| [p.controller.l12_desired, p.controller.alpha12_desired]);
        self.previous = Some(sample);
    }

    /// Filters the measurement of `now` over the step from the last sample
    /// [`acted`](Self::acted) on (its odometry and controller); `None` before any.
    ///
    /// # Errors
    /// A [`ReproduceError::Filter`] from the filter's step.
    pub fn observe(
        &mut self,
        now: &Observation,
    ) -> Result<Option<(StepRecord, StepConsistency)>, ReproduceError> {
        let Some(prev) = &self.previous else {
            if let Some(config) = self.restart.take() {
                let started = config.started_at(&now.measurement, &self.r, START_WORLD_POSE_STD)?;
                self.filter = FormationFilter::new(&started)?;
                if let Some(history) = &mut self.history {
                    *history = vec![self.filter.record(Inputs::new(0.0, 0.0), None)];
                }
            }
            return Ok(None);
        };
        let filter = &mut self.filter;
        if self.follower_controller {
            // The follower knows its own controller: the IMM's models B and C use it.
            filter.set_follower_controller(Some(prev.controller))?;
        }
        // Not told its controller, the filter is still told when the follower changes its
        // own set-point, as the demo's tracker is (its plan; a no-op when it knows the
        // controller).
        let setpoint = [prev.controller.l12_desired, prev.controller.alpha12_desired];
        if self.before.is_some_and(|b| b != setpoint) {
            filter.follower_setpoint_changed()?;
        }
        if self.oracle {
            filter.pin_leader_velocity(prev.leader_inputs)?;
        }
        // The follower's odometry, as a robot has it (not what its wheels executed).
        filter.step(&now.measurement, &self.r, prev.odometry)?;
        if let Some(history) = &mut self.history {
            history.push(filter.record(prev.odometry, Some((now.measurement, self.r))));
        }
        let w = filter.leader_velocity();
        let w_std = filter.leader_velocity_std();
        let ex = wrapped_error(&PolarModel::h(filter.state()), &PolarModel::h(&now.truth));
        let px = filter
            .state_covariance()
            .fixed_view::<3, 3>(3, 3)
            .into_owned();
        let ew = Vector2::new(w.v - prev.leader_inputs.v, w.w - prev.leader_inputs.w);
        let pw = *filter.leader_velocity_covariance();
        let stats = StepConsistency {
            nis: filter.last_nis().unwrap_or(f64::NAN),
            nees_formation: px.try_inverse().map_or(f64::NAN, |inv| ex.dot(&(inv * ex))),
            nees_velocity: pw.try_inverse().map_or(f64::NAN, |inv| ew.dot(&(inv * ew))),
        };
        let record = StepRecord {
            t: now.t,
            truth: PolarModel::h(&now.truth),
            measured: now.measurement,
            estimated: PolarModel::h(filter.state()),
            estimated_std: filter.formation_std(),
            v1_true: prev.leader_inputs.v,
            w1_true: prev.leader_inputs.w,
            v1_estimated: w.v,
            w1_estimated: w.w,
            v1_std: w_std[0],
            w1_std: w_std[1],
        };
        Ok(Some((record, stats)))
    }

    /// The `records` this run gave (all of them, in order), with the estimates of the
    /// offline smoother ([`FormationFilter::smooth`], run backwards over the recorded pass)
    /// in place of the causal ones; everything else as recorded.
    ///
    /// # Errors
    /// [`ReproduceError::NoHistory`] for a run made without `keep_history` or records that
    /// are not this run's; a [`ReproduceError::Filter`] from the smoother.
    pub fn smoothed_records(
        &self,
        records: &[StepRecord],
    ) -> Result<Vec<StepRecord>, ReproduceError> {
        let Some(history) = &self.history else {
            return Err(ReproduceError::NoHistory);
        };
        // history[0] is the prior at t = 0, which has no record.
        if history.len() != records.len() + 1 {
            return Err(ReproduceError::NoHistory);
        }
        let smoothed = self.filter.smooth(history)?;
        Ok(records
            .iter()
            .zip(&smoothed[1..])
            .map(|(r, s)| StepRecord {
                estimated: PolarModel::h(&s.state),
                estimated_std: s.formation_std(),
                v1_estimated: s.velocity.v,
                w1_estimated: s.velocity.w,
                v1_std: s.velocity_std()[0],
                w1_std: s.velocity_std()[1],
                ..r.clone()
            })
            .collect())
    }
}

/// A scenario run with its formation filter in the loop, one sample at a time: at each
/// `t_k` the simulation draws the measurement, the filter takes it (over the step from
/// `t_{k-1}`, with the follower's odometry and controller of that step), and the follower
/// commands the next step from the filter's estimate ([`Control::Estimate`], as on a robot)
/// or, as its scenario says, from the truth or its plan. Yields each sample with the
/// filter's record of it (`None` at `t = 0`), the same records as [`FilterRun::push`] over
/// the same samples; constant memory without the smoother's history.
pub struct ClosedLoop<F> {
    simulation: Simulation<F>,
    run: FilterRun,
}

impl<F: Fn(f64) -> Inputs> ClosedLoop<F> {
    /// The scenario of `simulation` filtered by `config`. The filter is told the follower's
    /// controller when `follower_controller` is set and the follower runs it (not under
    /// [`Control::Open`], where it replays a plan); with `keep_history` the run keeps what
    /// [`Self::smoothed_records`] needs.
    ///
    /// # Errors
    /// A filter configuration [`FormationFilter::new`] refuses.
    pub fn new(
        simulation: Simulation<F>,
        config: &FilterConfig,
        follower_controller: bool,
        keep_history: bool,
    ) -> Result<Self, ReproduceError> {
        let scenario = simulation.config();
        let told = follower_controller && scenario.control != Control::Open;
        let run = FilterRun::new(config, scenario, told, keep_history)?;
        Ok(Self { simulation, run })
    }

    /// The scenario's configuration.
    pub fn config(&self) -> &ScenarioConfig {
        self.simulation.config()
    }

    /// The filter run as it stands after the last sample.
    pub fn run(&self) -> &FilterRun {
        &self.run
    }

    /// The same loop with an oracle filter ([`FilterRun::oracle`]): comparisons only.
    pub fn oracle(mut self) -> Self {
        self.run = self.run.oracle();
        self
    }

    /// Runs the loop to its end and collects it, as [`run_closed_loop`] does.
    ///
    /// # Errors
    /// Any [`ReproduceError`].
    pub fn collect_run(mut self) -> Result<(Scenario, Reproduction), ReproduceError> {
        let scenario_config = self.config().clone();
        let mut samples = Vec::with_capacity(scenario_config.steps() + 1);
        let mut records = Vec::with_capacity(scenario_config.steps());
        let mut consistency = Vec::with_capacity(scenario_config.steps());
        for step in self.by_ref() {
            let (sample, filtered) = step?;
            samples.push(sample);
            if let Some((record, stats)) = filtered {
                records.push(record);
                consistency.push(stats);
            }
        }
        let reproduction = reproduction(&self.run, &scenario_config, records, consistency)?;
        let scenario = Scenario {
            config: scenario_config,
            samples,
        };
        Ok((scenario, reproduction))
    }

    /// As [`FilterRun::smoothed_records`].
    ///
    /// # Errors
    /// As [`FilterRun::smoothed_records`].
    pub fn smoothed_records(
        &self,
        records: &[StepRecord],
    ) -> Result<Vec<StepRecord>, ReproduceError> {
        self.run.smoothed_records(records)
    }
}

/// One sample of a [`ClosedLoop`] run and the filter's record of it.
pub type LoopStep = (Sample, Option<(StepRecord, StepConsistency)>);

impl<F: Fn(f64) -> Inputs> Iterator for ClosedLoop<F> {
    type Item = Result<LoopStep, ReproduceError>;

    fn next(&mut self) -> Option<Self::Item> {
        let Self { simulation, run } = self;
        let mut out = None;
        let sample = simulation.step(|seen| -> Result<_, ReproduceError> {
            out = run.observe(seen)?;
            Ok(Some(run.control_estimate()))
        })?;
        Some(sample.map(|sample| {
            run.acted(sample.clone());
            (sample, out)
        }))
    }
}

/// Runs a [`ClosedLoop`] to its end and collects it: the scenario's samples (what the
/// follower did under its estimates) and their filtered [`Reproduction`], smoother included.
///
/// # Errors
/// Any [`ReproduceError`].
pub fn run_closed_loop<F: Fn(f64) -> Inputs>(
    simulation: Simulation<F>,
    config: &FilterConfig,
    follower_controller: bool,
) -> Result<(Scenario, Reproduction), ReproduceError> {
    ClosedLoop::new(simulation, config, follower_controller, true)?.collect_run()
}

/// The reproduction of the paper's Figs. 12-13: the reference scenario with `seed` (and the
/// paper's bias if `bias`), filtered with [`paper_filter_config`] (the default design, the
/// IMM).
///
/// # Errors
/// Any [`ReproduceError`].
pub fn reproduce(seed: u64, bias: bool) -> Result<Reproduction, ReproduceError> {
    reproduce_with(seed, bias, FilterDesign::Imm)
}

/// As [`reproduce`] with the given filter design ([`FilterDesign::Dual`]: the paper's dual
/// UKF, for comparison).
///
/// # Errors
/// Any [`ReproduceError`].
pub fn reproduce_with(
    seed: u64,
    bias: bool,
    design: FilterDesign,
) -> Result<Reproduction, ReproduceError> {
    let mut config = ScenarioConfig::reference(seed);
    if bias {
        config = config.with_paper_bias();
    }
    let scenario = simulate(&config)?;
    run_filter(
        &scenario,
        &paper_filter_config_with(config.d, config.dt, design),
    )
}

/// Which single-measurement Kalman filter a [`baseline`] runs on each of `l12`, `alpha12`,
/// `beta12` (the comparisons of issue #15).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Baseline {
    /// A scalar random walk: `x_k = x_{k-1} + n`, `n ~ N(0, q)` per step.
    RandomWalk {
        /// Process noise per step.
        q: f64,
    },
    /// A constant-velocity model `[x, x']` driven by continuous white acceleration of
    /// spectral density `q` (discretised exactly: `Q = q [dt^3/3, dt^2/2; dt^2/2, dt]`).
    ConstantVelocity {
        /// Spectral density of the white acceleration.
        q: f64,
    },
}

impl Baseline {
    /// The random-walk baseline of issue #15: `q = 1e-6` per step.
    pub const RANDOM_WALK: Self = Self::RandomWalk { q: 1e-6 };
    /// The constant-velocity baseline of issue #15: white acceleration `q = 1e-5`.
    pub const CONSTANT_VELOCITY: Self = Self::ConstantVelocity { q: 1e-5 };
}

/// The MSEs of a [`Baseline`] over one scenario: each measured variable filtered alone from
/// the paper's initial value ([`PAPER_X0`]) with variance 1 (and, for the constant-velocity
/// model, velocity 0 with variance 1), with the scenario's measurement variance, over the same
/// steps `k = 1..` as [`run_filter`]. Returns `[l12, alpha12, beta12]`.
pub fn baseline(scenario: &Scenario, x0: &[f64; 3], which: Baseline) -> [f64; 3] {
    let dt = scenario.config.dt;
    let mut out = [0.0; 3];
    for (i, mse) in out.iter_mut().enumerate() {
        let r = scenario.config.noise_std[i].powi(2);
        let angle = i > 0;
        // State [x, v], covariance [[p00, p01], [p01, p11]].
        let (mut x, mut v) = (x0[i], 0.0);
        let (mut p00, mut p01, mut p11) = (1.0, 0.0, 1.0);
        let mut sum = 0.0;
        for s in &scenario.samples[1..] {
            match which {
                Baseline::RandomWalk { q } => {
                    p00 += q;
                }
                Baseline::ConstantVelocity { q } => {
                    x += v * dt;
                    let n00 = p00 + 2.0 * dt * p01 + dt * dt * p11 + q * dt.powi(3) / 3.0;
                    let n01 = p01 + dt * p11 + q * dt * dt / 2.0;
                    let n11 = p11 + q * dt;
                    (p00, p01, p11) = (n00, n01, n11);
                }
            }
            let mut nu = s.measurement[i] - x;
            if angle {
                nu = wrap_angle(nu);
            }
            let sk = p00 + r;
            let (k0, k1) = (p00 / sk, p01 / sk);
            x += k0 * nu;
            if angle {
                x = wrap_angle(x);
            }
            if matches!(which, Baseline::ConstantVelocity { .. }) {
                v += k1 * nu;
                p11 -= k1 * p01;
            }
            p01 -= k0 * p01;
            p00 -= k0 * p00;
            let truth = PolarModel::h(&s.truth)[i];
            let e = if angle {
                wrap_angle(x - truth)
            } else {
                x - truth
            };
            sum += e * e;
        }
        *mse = sum / (scenario.samples.len() - 1).max(1) as f64;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// #30: with the filter in the loop, control on the truth gives the records of the
    /// filter run after the fact; on the estimate, the follower moves by what the filter says.
    #[test]
    fn the_closed_loop_runs_the_filter_between_measurement_and_command() {
        let config = ScenarioConfig::reference(6);
        let filter = paper_filter_config(config.d, config.dt);
        let after = run_filter(&simulate(&config).unwrap(), &filter).unwrap();
        let sim = Simulation::new(&config, crate::scenario::reference_leader_inputs, &[]).unwrap();
        let (scenario, looped) = run_closed_loop(sim, &filter, true).unwrap();
        assert_eq!(scenario, simulate(&config).unwrap());
        assert_eq!(looped.records, after.records);
        assert_eq!(looped.smoothed_records, after.smoothed_records);
        assert_eq!(looped.summary.control, Control::Truth);

        let config = config.with_control(Control::Estimate);
        let sim = Simulation::new(&config, crate::scenario::reference_leader_inputs, &[]).unwrap();
        let (scenario, looped) = run_closed_loop(sim, &filter, true).unwrap();
        assert_eq!(looped.summary.control, Control::Estimate);
        assert_eq!(scenario.samples.len(), 241);
        // The filter starts at the first measurement, and the follower's first command is its
        // controller on that start.
        let started = filter
            .started_at(
                &scenario.samples[0].measurement,
                &config.noise_covariance(),
                START_WORLD_POSE_STD,
            )
            .unwrap();
        let prior = FormationFilter::new(&started).unwrap();
        assert_eq!(
            prior.formation().to_vector(),
            scenario.samples[0].measurement
        );
        let controller =
            unicycle::SeparationBearingController::new(config.d, scenario.samples[0].controller)
                .unwrap();
        let first = controller
            .inputs(&prior.formation(), prior.leader_velocity())
            .unwrap();
        assert_eq!(scenario.samples[0].follower_inputs, first);
        // The trajectory differs from the truth-driven one, and the filter still tracks it.
        assert_ne!(
            PolarModel::h(&scenario.samples[100].truth),
            after.records[99].truth
        );
        assert!(looped.summary.mse.l12 < 0.5 * looped.summary.mse.meas_l12);
        // Filtering the same samples after the fact gives the same records.
        let replay = run_filter(&scenario, &filter).unwrap();
        assert_eq!(replay.records, looped.records);
    }

    #[test]
    fn summary_counts_every_step_and_the_late_window() {
        let run = reproduce(2, false).unwrap();
        let s = &run.summary;
        assert_eq!(s.steps, run.records.len());
        // Recompute one figure by hand.
        let mse: f64 = run
            .records
            .iter()
            .map(|r| (r.estimated[0] - r.truth[0]).powi(2))
            .sum::<f64>()
            / run.records.len() as f64;
        assert!((mse - s.mse.l12).abs() < 1e-15);
        let late: Vec<f64> = run
            .records
            .iter()
            .filter(|r| r.t > 2.0)
            .map(|r| (r.v1_estimated - r.v1_true).powi(2))
            .collect();
        let rms = (late.iter().sum::<f64>() / late.len() as f64).sqrt();
        assert!((rms - s.rms_v1_after_2s).abs() < 1e-15);
    }
}
