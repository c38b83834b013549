//! The formation filter: Wan and van der Merwe's dual unscented Kalman filter (spec 5, crate
//! `dukf`) over the unicycle polar model (spec 2.4, crate `unicycle`).
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
//! [`FilterTuning::propagate_parameter_uncertainty`] (on in the reference configuration) the
//! state filter's process noise at each step is `Q + J Pw- J^T`, with `J = df/dw` at the
//! current estimate (central differences) and `Pw- = Pw + Rr` the parameter filter's
//! predicted covariance: the velocity uncertainty enters the state covariance exactly as a
//! first-order propagation says it should. The measurement models are untouched.
//!
//! # Offline smoothing
//! [`FormationFilter::record`] copies the estimates after a step into a [`FilterStep`];
//! [`FormationFilter::smooth`] runs the unscented RTS smoother of `dukf` backwards over such a
//! history, over the state and the leader velocities together (see `smooth.rs` and
//! `docs/smoothing.md`), giving one [`SmoothedStep`] per recorded step.

mod smooth;

pub use smooth::{FilterStep, SmoothedStep};

use std::cell::Cell;

use dukf::{AngleMask, DualUkf, Euclidean, Ukf, UkfError, UtParams};
use nalgebra::{Matrix2, Matrix3, Matrix5, SMatrix, SVector, Vector2, Vector3};
use unicycle::{
    Formation, Inputs, MEASUREMENT_ANGLES, PolarModel, PolarState, STATE_ANGLES, UnicycleError,
    wrap_angle,
};

type Matrix6 = SMatrix<f64, 6, 6>;
type Vector6 = SVector<f64, 6>;
type Dual = DualUkf<6, 2, 3, AngleMask<6>, Euclidean, AngleMask<3>>;

/// Errors of the formation filter.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FilterError {
    /// The dual unscented Kalman filter failed (non-finite input, lost definiteness, ...).
    #[error(transparent)]
    Ukf(#[from] UkfError),
    /// The robot model refused a state or an input (e.g. `l12 <= 0` at a sigma point).
    #[error(transparent)]
    Model(#[from] UnicycleError),
    /// The time step is not finite and positive.
    #[error("filter time step dt = {dt} s must be finite and positive")]
    InvalidTimeStep {
        /// The step that was given.
        dt: f64,
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
    /// Scaled unscented transform parameters, used by both filters.
    pub ut: UtParams,
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
}

/// A dual UKF tracking one leader's formation variables and velocities.
#[derive(Debug, Clone)]
pub struct FormationFilter {
    model: PolarModel,
    dt: f64,
    q: Matrix6,
    propagate: bool,
    ut: UtParams,
    dual: Dual,
    last_nis: Option<f64>,
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
) -> Result<T, FilterError> {
    match (result, failure.get()) {
        (Ok(report), _) => Ok(report),
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
        let t = &config.tuning;
        let state = Ukf::new(config.x0, t.p0, state_space()?, t.ut)?;
        let params = Ukf::new(t.w0, t.pw0, Euclidean, t.ut)?;
        let dual = DualUkf::new(state, params, t.q, t.rr, measurement_space()?)?;
        Ok(Self {
            model,
            dt: config.dt,
            q: t.q,
            propagate: t.propagate_parameter_uncertainty,
            ut: t.ut,
            dual,
            last_nis: None,
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
        let report = outcome(result, &failure)?;
        self.last_nis = Some(report.state.nis);
        Ok(())
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
        outcome(result, &failure)?;
        self.last_nis = None;
        Ok(())
    }

    /// The normalised innovation squared `nu^T S^-1 nu` of the state filter's last update
    /// (chi-square with 3 degrees of freedom when the filter is consistent); `None` before
    /// the first update and after a frame without a measurement.
    pub fn last_nis(&self) -> Option<f64> {
        self.last_nis
    }

    /// The state covariance (order `[x1, y1, theta1, l12, alpha12, beta12]`).
    pub fn state_covariance(&self) -> &Matrix6 {
        self.dual.state_covariance()
    }

    /// The leader-velocity covariance (order `[v1, w1]`).
    pub fn leader_velocity_covariance(&self) -> &Matrix2<f64> {
        self.dual.parameter_covariance()
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

    /// The covariance of `[l12, alpha12, beta12, v1, w1]`: the state filter's block of the
    /// formation variables and the parameter filter's of the velocities. The dual filter
    /// keeps no cross-covariance between its two filters, so the formation-velocity terms
    /// are zero (the smoother's joint pass has them; `docs/smoothing.md`).
    pub fn estimate_covariance(&self) -> Matrix5<f64> {
        let mut c = Matrix5::zeros();
        c.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&self.dual.state_covariance().fixed_view::<3, 3>(3, 3));
        c.fixed_view_mut::<2, 2>(3, 3)
            .copy_from(self.dual.parameter_covariance());
        c
    }

    /// Standard deviations of `(v1, w1)`.
    pub fn leader_velocity_std(&self) -> Vector2<f64> {
        self.dual
            .parameter_covariance()
            .diagonal()
            .map(|v| v.max(0.0).sqrt())
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

    fn r() -> Matrix3<f64> {
        Matrix3::from_diagonal(&Vector3::new(
            0.07f64.powi(2),
            0.03f64.powi(2),
            0.03f64.powi(2),
        ))
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
            ..config()
        };
        assert!(matches!(
            FormationFilter::new(&config),
            Err(FilterError::InvalidTimeStep { .. })
        ));
    }
}
