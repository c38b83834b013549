//! The formation filter: Wan and van der Merwe's dual unscented Kalman filter (spec 5, crate
//! `dukf`) over the unicycle polar model (spec 2.4, crate `unicycle`), and the dual-UKF
//! reproduction of the paper's Figs. 12-13 on the reference scenario.
//!
//! [`FormationFilter`] is the piece the tracker reuses per leader: a state filter over
//! `x = [x1, y1, theta1, l12, alpha12, beta12]` and a parameter filter over the leader's
//! velocities `w = [v1, w1]` (a random walk), both fed the measurement
//! `y = [l12, alpha12, beta12]` and the follower's own inputs `u = [v2, w2]`.
//!
//! # Parameter uncertainty in the state prediction
//! In the plain dual filter the state filter treats `w^` as exact, so while `w^` is still
//! wrong (at the start `w0 = [0, 0]` against a leader at 0.8 m/s) the state filter's
//! covariance is far too small and its estimate drifts with the wrong velocity. With
//! [`FilterConfig::propagate_parameter_uncertainty`] (on in the reference configuration) the
//! state filter's process noise at each step is `Q + J Pw- J^T`, with `J = df/dw` at the
//! current estimate (central differences) and `Pw- = Pw + Rr` the parameter filter's
//! predicted covariance: the velocity uncertainty enters the state covariance exactly as a
//! first-order propagation says it should. The measurement models are untouched.

use std::cell::Cell;

use dukf::{AngleMask, DualUkf, Euclidean, Ukf, UkfError, UtParams};
use nalgebra::{Matrix2, Matrix3, SMatrix, SVector, Vector2, Vector3};
use serde::Serialize;
use unicycle::{
    Formation, Inputs, MEASUREMENT_ANGLES, PolarModel, PolarState, STATE_ANGLES, UnicycleError,
    wrap_angle,
};

use crate::scenario::{PAPER_X0, Scenario, ScenarioConfig, ScenarioError, simulate};

type Matrix6 = SMatrix<f64, 6, 6>;
type Vector6 = SVector<f64, 6>;
type Dual = DualUkf<6, 2, 3, AngleMask<6>, Euclidean, AngleMask<3>>;

/// Errors of the formation filter and the reproduction.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FilterError {
    /// The dual unscented Kalman filter failed (non-finite input, lost definiteness, ...).
    #[error(transparent)]
    Ukf(#[from] UkfError),
    /// The robot model refused a state or an input (e.g. `l12 <= 0` at a sigma point).
    #[error(transparent)]
    Model(#[from] UnicycleError),
    /// The scenario could not be simulated.
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    /// The time step is not finite and positive.
    #[error("filter time step dt = {dt} s must be finite and positive")]
    InvalidTimeStep {
        /// The step that was given.
        dt: f64,
    },
}

/// Everything that defines a [`FormationFilter`].
#[derive(Debug, Clone, PartialEq)]
pub struct FilterConfig {
    /// Camera offset `d` of the follower, metres.
    pub d: f64,
    /// Time between frames, seconds.
    pub dt: f64,
    /// Initial state estimate.
    pub x0: PolarState,
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
    /// Scaled unscented transform parameters, used by both filters.
    pub ut: UtParams,
}

impl FilterConfig {
    /// The configuration of the dual-UKF reproduction (see `docs/reference-scenario.md` for
    /// the rationale of each number): the paper's `x0`, `w0 = [0, 0]`, `Pw0 = I`;
    /// `P0 = diag(0.1^2, 0.1^2, 0.1^2, 0.07^2, 0.03^2, 0.03^2)` (the measurement noise on the
    /// measured components); `Q = diag(1e-6, 1e-6, 1e-6, 1e-7, 1e-5, 1e-5)`;
    /// `Rr = diag(1e-4, 1e-4)`; parameter uncertainty propagated; `alpha = 1, beta = 2,
    /// kappa = 0`.
    pub fn reference(d: f64, dt: f64) -> Self {
        Self {
            d,
            dt,
            x0: PolarState::from_row_slice(&PAPER_X0),
            p0: Matrix6::from_diagonal(&Vector6::new(0.01, 0.01, 0.01, 0.0049, 0.0009, 0.0009)),
            w0: Vector2::zeros(),
            pw0: Matrix2::identity(),
            q: Matrix6::from_diagonal(&Vector6::new(1e-6, 1e-6, 1e-6, 1e-7, 1e-5, 1e-5)),
            rr: Matrix2::from_diagonal(&Vector2::new(1e-4, 1e-4)),
            propagate_parameter_uncertainty: true,
            ut: UtParams::new(1.0, 2.0, 0.0),
        }
    }
}

/// A dual UKF tracking one leader's formation variables and velocities.
#[derive(Debug, Clone)]
pub struct FormationFilter {
    model: PolarModel,
    dt: f64,
    q: Matrix6,
    propagate: bool,
    dual: Dual,
}

fn state_space() -> Result<AngleMask<6>, UkfError> {
    AngleMask::from_indices(&STATE_ANGLES)
}

fn measurement_space() -> Result<AngleMask<3>, UkfError> {
    AngleMask::from_indices(&MEASUREMENT_ANGLES)
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
        Err(e) => {
            if failure.get().is_none() {
                failure.set(Some(e));
            }
            PolarState::repeat(f64::NAN)
        }
    }
}

/// The filter's result, preferring the model's own error when a sigma point was refused.
fn outcome<T>(
    result: Result<T, UkfError>,
    failure: &Cell<Option<UnicycleError>>,
) -> Result<(), FilterError> {
    match (result, failure.get()) {
        (Ok(_), _) => Ok(()),
        (Err(_), Some(model_error)) => Err(model_error.into()),
        (Err(e), None) => Err(e.into()),
    }
}

impl FormationFilter {
    /// A filter from its configuration.
    ///
    /// # Errors
    /// A bad offset or time step, non-finite or non-positive-definite initial covariances, or
    /// bad unscented-transform parameters.
    pub fn new(config: &FilterConfig) -> Result<Self, FilterError> {
        if !(config.dt.is_finite() && config.dt > 0.0) {
            return Err(FilterError::InvalidTimeStep { dt: config.dt });
        }
        let model = PolarModel::new(config.d)?;
        let state = Ukf::new(config.x0, config.p0, state_space()?, config.ut)?;
        let params = Ukf::new(config.w0, config.pw0, Euclidean, config.ut)?;
        let dual = DualUkf::new(state, params, config.q, config.rr, measurement_space()?)?;
        Ok(Self {
            model,
            dt: config.dt,
            q: config.q,
            propagate: config.propagate_parameter_uncertainty,
            dual,
        })
    }

    /// Sets the state process noise for this step: `Q`, plus `F_w Pw- F_w^T` when
    /// configured, with `F_w = df/dw` by central differences at the current estimates.
    fn prepare_process_noise(&mut self, u: &Vector2<f64>) -> Result<(), FilterError> {
        if !self.propagate {
            return Ok(());
        }
        let x = *self.dual.state();
        let w = *self.dual.parameters();
        let mut fw = SMatrix::<f64, 6, 2>::zeros();
        for j in 0..2 {
            let h = 1e-6 * (1.0 + w[j].abs());
            let (mut wp, mut wm) = (w, w);
            wp[j] += h;
            wm[j] -= h;
            let mut d = self.model.f(&x, u, &wp, self.dt)? - self.model.f(&x, u, &wm, self.dt)?;
            for i in STATE_ANGLES {
                d[i] = wrap_angle(d[i]);
            }
            fw.set_column(j, &(d / (2.0 * h)));
        }
        let pw = self.dual.parameter_covariance() + self.dual.parameter_noise();
        let q = self.q + fw * pw * fw.transpose();
        self.dual.set_process_noise((q + q.transpose()) * 0.5)?;
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
        self.prepare_process_noise(&u)?;
        let failure = Cell::new(None);
        let result = self.dual.step(
            process(&self.model, &u, self.dt, &failure),
            PolarModel::h,
            y,
            r,
        );
        outcome(result, &failure)
    }

    /// One frame without a measurement (e.g. the leader was not detected): the state coasts
    /// on the model with the current velocity estimate and the covariances grow.
    ///
    /// # Errors
    /// As [`FormationFilter::step`].
    pub fn predict_only(&mut self, u: Inputs) -> Result<(), FilterError> {
        let u: Vector2<f64> = u.into();
        self.prepare_process_noise(&u)?;
        let failure = Cell::new(None);
        let result = self
            .dual
            .predict_only(process(&self.model, &u, self.dt, &failure));
        outcome(result, &failure)
    }

    /// The state estimate `[x1, y1, theta1, l12, alpha12, beta12]`.
    pub fn state(&self) -> &PolarState {
        self.dual.state()
    }

    /// Standard deviations of the state estimate.
    pub fn state_std(&self) -> PolarState {
        self.dual
            .state_covariance()
            .diagonal()
            .map(|v| v.max(0.0).sqrt())
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
        (*self.dual.parameters()).into()
    }

    /// Standard deviations of `(v1, w1)`.
    pub fn leader_velocity_std(&self) -> Vector2<f64> {
        self.dual
            .parameter_covariance()
            .diagonal()
            .map(|v| v.max(0.0).sqrt())
    }
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

/// Figures of one run (the fields of `summary.json`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Summary {
    /// Mean square error of the estimated `l12` over all filtered steps, m^2.
    pub mse_l12: f64,
    /// Mean square error of the estimated `alpha12`, rad^2.
    pub mse_alpha12: f64,
    /// Mean square error of the estimated `beta12`, rad^2.
    pub mse_beta12: f64,
    /// Mean square error of the estimated `v1`, (m/s)^2.
    pub mse_v1: f64,
    /// Mean square error of the estimated `w1`, (rad/s)^2.
    pub mse_w1: f64,
    /// Mean square error of the raw measured `l12`, m^2.
    pub mse_meas_l12: f64,
    /// Mean square error of the raw measured `alpha12`, rad^2.
    pub mse_meas_alpha12: f64,
    /// Mean square error of the raw measured `beta12`, rad^2.
    pub mse_meas_beta12: f64,
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
}

/// Computes the [`Summary`] of a run's records.
pub fn summarize(records: &[StepRecord], seed: u64, bias: bool) -> Summary {
    let n = records.len().max(1) as f64;
    let mut est = Vector3::zeros();
    let mut meas = Vector3::zeros();
    let (mut v, mut w) = (0.0, 0.0);
    let (mut v2, mut w2, mut late) = (0.0, 0.0, 0usize);
    for r in records {
        est += r.estimation_error().component_mul(&r.estimation_error());
        meas += r.measurement_error().component_mul(&r.measurement_error());
        let (ev, ew) = (r.v1_estimated - r.v1_true, r.w1_estimated - r.w1_true);
        v += ev * ev;
        w += ew * ew;
        if r.t > 2.0 {
            v2 += ev * ev;
            w2 += ew * ew;
            late += 1;
        }
    }
    let late = late.max(1) as f64;
    Summary {
        mse_l12: est[0] / n,
        mse_alpha12: est[1] / n,
        mse_beta12: est[2] / n,
        mse_v1: v / n,
        mse_w1: w / n,
        mse_meas_l12: meas[0] / n,
        mse_meas_alpha12: meas[1] / n,
        mse_meas_beta12: meas[2] / n,
        rms_v1_after_2s: (v2 / late).sqrt(),
        rms_w1_after_2s: (w2 / late).sqrt(),
        steps: records.len(),
        mse_from_t: records.first().map_or(0.0, |r| r.t),
        seed,
        bias,
    }
}

/// A filtered run of a scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct Reproduction {
    /// The scenario's configuration.
    pub scenario: ScenarioConfig,
    /// One record per filtered frame, `t = dt, 2 dt, ..., duration`.
    pub records: Vec<StepRecord>,
    /// Its figures.
    pub summary: Summary,
}

/// Runs the formation filter over a simulated scenario: the filter starts at `t = 0` from
/// its configured prior, and at every later frame `k` takes the follower's inputs applied
/// over `(t_{k-1}, t_k]` and the measurement at `t_k`.
///
/// # Errors
/// Any [`FilterError`].
pub fn run_filter(scenario: &Scenario, config: &FilterConfig) -> Result<Reproduction, FilterError> {
    let mut filter = FormationFilter::new(config)?;
    let r = scenario.config.noise_covariance();
    let mut records = Vec::with_capacity(scenario.samples.len());
    for pair in scenario.samples.windows(2) {
        let (prev, now) = (&pair[0], &pair[1]);
        filter.step(&now.measurement, &r, prev.follower_inputs)?;
        let w = filter.leader_velocity();
        let w_std = filter.leader_velocity_std();
        records.push(StepRecord {
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
        });
    }
    let summary = summarize(
        &records,
        scenario.config.seed,
        scenario.config.bias.is_some(),
    );
    Ok(Reproduction {
        scenario: scenario.config.clone(),
        records,
        summary,
    })
}

/// The dual-UKF reproduction of the paper's Figs. 12-13: the reference scenario with `seed`
/// (and the paper's bias if `bias`), filtered with [`FilterConfig::reference`].
///
/// # Errors
/// Any [`FilterError`].
pub fn reproduce(seed: u64, bias: bool) -> Result<Reproduction, FilterError> {
    let mut config = ScenarioConfig::reference(seed);
    if bias {
        config = config.with_paper_bias();
    }
    let scenario = simulate(&config)?;
    run_filter(&scenario, &FilterConfig::reference(config.d, config.dt))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn filter() -> FormationFilter {
        FormationFilter::new(&FilterConfig::reference(0.5, 1.0 / 30.0)).unwrap()
    }

    fn r() -> Matrix3<f64> {
        ScenarioConfig::reference(1).noise_covariance()
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
        let mut config = FilterConfig::reference(0.5, 1.0 / 30.0);
        config.x0[3] = 0.0;
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
    fn bad_time_step_is_an_error() {
        let config = FilterConfig {
            dt: 0.0,
            ..FilterConfig::reference(0.5, 1.0 / 30.0)
        };
        assert!(matches!(
            FormationFilter::new(&config),
            Err(FilterError::InvalidTimeStep { .. })
        ));
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
        assert!((mse - s.mse_l12).abs() < 1e-15);
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
