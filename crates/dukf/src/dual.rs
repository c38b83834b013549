//! The dual unscented Kalman filter (Wan and van der Merwe's dual estimation, spec section 5).

use nalgebra::{SMatrix, SVector};

use crate::error::{DualFilter, Input, UkfError};
use crate::space::Space;
use crate::transform::{check_matrix, check_vector};
use crate::ukf::{PredictReport, Ukf, UpdateReport};

/// What one [`DualUkf::step`] did in each filter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DualReport<const M: usize> {
    /// The state filter's prediction.
    pub state_prediction: PredictReport,
    /// The state filter's update.
    pub state: UpdateReport<M>,
    /// The parameter filter's random-walk prediction.
    pub parameter_prediction: PredictReport,
    /// The parameter filter's update.
    pub parameter: UpdateReport<M>,
}

/// What one [`DualUkf::predict_only`] did in each filter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DualPredictReport {
    /// The state filter's prediction.
    pub state: PredictReport,
    /// The parameter filter's random-walk prediction.
    pub parameter: PredictReport,
}

/// Two unscented Kalman filters run side by side: one over the state `x` (dimension `N`),
/// one over the parameters `w` (dimension `P`) of the process `x_{k+1} = f(x_k, w_k) + v_k`,
/// both observing `y = h(x) + n` (dimension `M`).
///
/// At every [`step`](Self::step), from the previous estimates `x^_{k-1}` and `w^_{k-1}`:
///
/// - the **state filter** predicts with `f(., w^_{k-1})` (the parameters held at their
///   current estimate `w- = w^_{k-1}`) plus `Q`, then updates with `h` and `y_k`;
/// - the **parameter filter** predicts by a random walk (`w- = w^_{k-1}`,
///   `Pw- = Pw + Rr`), then updates with `y_k` observed through
///   `g(w) = h(f(x^_{k-1}, w))`.
///
/// Both filters see only the previous estimates, so their order does not matter; both are
/// computed first and committed together, so on error neither changes. Known inputs `u` of
/// the process go into the closure `f` (capture them), so this type never sees them.
///
/// A frame without a measurement is [`predict_only`](Self::predict_only): the state is
/// propagated, the parameters keep their mean and their covariance grows by `Rr`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DualUkf<const N: usize, const P: usize, const M: usize, SX, SW, SY>
where
    SX: Space<N>,
    SW: Space<P>,
    SY: Space<M>,
{
    state: Ukf<N, SX>,
    parameters: Ukf<P, SW>,
    measurement_space: SY,
    q: SMatrix<f64, N, N>,
    rr: SMatrix<f64, P, P>,
}

impl<const N: usize, const P: usize, const M: usize, SX, SW, SY> DualUkf<N, P, M, SX, SW, SY>
where
    SX: Space<N>,
    SW: Space<P>,
    SY: Space<M>,
{
    /// A dual filter from a state filter, a parameter filter, the process noise `q` of the
    /// state, the random-walk noise `rr` of the parameters, and the measurement space.
    ///
    /// # Errors
    /// [`UkfError::NonFiniteMatrix`] if `q` or `rr` has a non-finite entry.
    pub fn new(
        state: Ukf<N, SX>,
        parameters: Ukf<P, SW>,
        q: SMatrix<f64, N, N>,
        rr: SMatrix<f64, P, P>,
        measurement_space: SY,
    ) -> Result<Self, UkfError> {
        check_matrix(&q, Input::ProcessNoise)?;
        check_matrix(&rr, Input::ParameterNoise)?;
        Ok(Self {
            state,
            parameters,
            measurement_space,
            q,
            rr,
        })
    }

    /// One frame with a measurement `y` (noise covariance `r`, which may change every frame).
    ///
    /// `f(x, w)` is the process over one time step (with the known inputs captured), `h(x)`
    /// the measurement function.
    ///
    /// # Errors
    /// Non-finite `y` or `r` ([`UkfError::NonFiniteVector`] / [`UkfError::NonFiniteMatrix`]),
    /// or any failure of either filter wrapped in [`UkfError::Dual`]. Neither filter changes
    /// on error.
    pub fn step<F, H>(
        &mut self,
        mut f: F,
        mut h: H,
        y: &SVector<f64, M>,
        r: &SMatrix<f64, M, M>,
    ) -> Result<DualReport<M>, UkfError>
    where
        F: FnMut(&SVector<f64, N>, &SVector<f64, P>) -> SVector<f64, N>,
        H: FnMut(&SVector<f64, N>) -> SVector<f64, M>,
    {
        check_vector(y, Input::Measurement)?;
        check_matrix(r, Input::MeasurementNoise)?;
        let x_prev = self.state.estimate().x;
        let w_prev = self.parameters.estimate().x;
        let in_state = |e: UkfError| e.in_dual(DualFilter::State);
        let in_params = |e: UkfError| e.in_dual(DualFilter::Parameter);

        let xp = self
            .state
            .predicted(self.state.estimate(), |x| f(x, &w_prev), &self.q)
            .map_err(in_state)?;
        let (xu, state) = self
            .state
            .updated(&xp, y, &mut h, r, &self.measurement_space)
            .map_err(in_state)?;

        let wp = self
            .parameters
            .random_walk(self.parameters.estimate(), &self.rr)
            .map_err(in_params)?;
        let (wu, parameter) = self
            .parameters
            .updated(&wp, y, |w| h(&f(&x_prev, w)), r, &self.measurement_space)
            .map_err(in_params)?;

        let report = DualReport {
            state_prediction: PredictReport {
                jitter: xp.p.jitter,
            },
            state,
            parameter_prediction: PredictReport {
                jitter: wp.p.jitter,
            },
            parameter,
        };
        self.state.commit(xu);
        self.parameters.commit(wu);
        Ok(report)
    }

    /// One frame without a measurement: the state is predicted with `f(., w^)`, the
    /// parameters keep their mean and their covariance grows by `Rr`.
    ///
    /// # Errors
    /// Any failure of either prediction, wrapped in [`UkfError::Dual`]. Neither filter
    /// changes on error.
    pub fn predict_only<F>(&mut self, mut f: F) -> Result<DualPredictReport, UkfError>
    where
        F: FnMut(&SVector<f64, N>, &SVector<f64, P>) -> SVector<f64, N>,
    {
        let w_prev = self.parameters.estimate().x;
        let xp = self
            .state
            .predicted(self.state.estimate(), |x| f(x, &w_prev), &self.q)
            .map_err(|e| e.in_dual(DualFilter::State))?;
        let wp = self
            .parameters
            .random_walk(self.parameters.estimate(), &self.rr)
            .map_err(|e| e.in_dual(DualFilter::Parameter))?;
        let report = DualPredictReport {
            state: PredictReport {
                jitter: xp.p.jitter,
            },
            parameter: PredictReport {
                jitter: wp.p.jitter,
            },
        };
        self.state.commit(xp);
        self.parameters.commit(wp);
        Ok(report)
    }

    /// The state estimate `x^`.
    pub fn state(&self) -> &SVector<f64, N> {
        self.state.state()
    }

    /// The state covariance.
    pub fn state_covariance(&self) -> &SMatrix<f64, N, N> {
        self.state.covariance()
    }

    /// The parameter estimate `w^`.
    pub fn parameters(&self) -> &SVector<f64, P> {
        self.parameters.state()
    }

    /// The parameter covariance.
    pub fn parameter_covariance(&self) -> &SMatrix<f64, P, P> {
        self.parameters.covariance()
    }

    /// The state filter.
    pub fn state_filter(&self) -> &Ukf<N, SX> {
        &self.state
    }

    /// The state filter, mutably (e.g. to [`reset`](Ukf::reset) it after a lost track).
    pub fn state_filter_mut(&mut self) -> &mut Ukf<N, SX> {
        &mut self.state
    }

    /// The parameter filter.
    pub fn parameter_filter(&self) -> &Ukf<P, SW> {
        &self.parameters
    }

    /// The parameter filter, mutably.
    pub fn parameter_filter_mut(&mut self) -> &mut Ukf<P, SW> {
        &mut self.parameters
    }

    /// The measurement space.
    pub fn measurement_space(&self) -> &SY {
        &self.measurement_space
    }

    /// The state process noise `Q`.
    pub fn process_noise(&self) -> &SMatrix<f64, N, N> {
        &self.q
    }

    /// The parameter random-walk noise `Rr`.
    pub fn parameter_noise(&self) -> &SMatrix<f64, P, P> {
        &self.rr
    }

    /// Replaces `Q`.
    ///
    /// # Errors
    /// [`UkfError::NonFiniteMatrix`] (and `Q` is unchanged).
    pub fn set_process_noise(&mut self, q: SMatrix<f64, N, N>) -> Result<(), UkfError> {
        check_matrix(&q, Input::ProcessNoise)?;
        self.q = q;
        Ok(())
    }

    /// Replaces `Rr`.
    ///
    /// # Errors
    /// [`UkfError::NonFiniteMatrix`] (and `Rr` is unchanged).
    pub fn set_parameter_noise(&mut self, rr: SMatrix<f64, P, P>) -> Result<(), UkfError> {
        check_matrix(&rr, Input::ParameterNoise)?;
        self.rr = rr;
        Ok(())
    }
}
