//! The unscented Kalman filter with additive noise.

use nalgebra::{SMatrix, SVector};

use crate::error::{Covariance, Function, Input, UkfError};
use crate::jitter::{Factored, JitterPolicy, factor_repaired};
use crate::sigma::{UtParams, Weights};
use crate::space::{Euclidean, Space, residuals};
use crate::transform::{
    check_matrix, check_vector, cross_from_factor, map_points, sigma_points, weighted_covariance,
};

/// What a prediction did besides predicting.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PredictReport {
    /// Diagonal jitter added to the predicted covariance to keep it positive definite
    /// (absolute; 0 if none was needed).
    pub jitter: f64,
}

/// What a measurement update saw and did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UpdateReport<const M: usize> {
    /// The innovation `y (-) y^`.
    pub innovation: SVector<f64, M>,
    /// The innovation covariance `S` (after repair, if any).
    pub innovation_covariance: SMatrix<f64, M, M>,
    /// Normalised innovation squared `nu^T S^-1 nu` (chi-square with `M` degrees of freedom
    /// when the filter is consistent; useful for gating outliers).
    pub nis: f64,
    /// Diagonal jitter added to the innovation covariance (0 if none).
    pub innovation_jitter: f64,
    /// Diagonal jitter added to the updated state covariance (0 if none).
    pub jitter: f64,
}

/// A mean with its factorised covariance: the filter's invariant is that the covariance it
/// holds always comes with a valid Cholesky factor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Estimate<const N: usize> {
    pub(crate) x: SVector<f64, N>,
    pub(crate) p: Factored<N>,
}

/// An unscented Kalman filter over a state of dimension `N` in the space `S`, with additive
/// process and measurement noise.
///
/// The filter keeps its covariance together with that covariance's Cholesky factor: every
/// operation factorises the covariance it produces (repairing it by the documented
/// [`JitterPolicy`] if needed) before committing it, so the next operation can draw sigma
/// points without refactorising, and a covariance that cannot be factorised is reported
/// while the filter still holds its last good estimate.
///
/// ```
/// use dukf::{Euclidean, Ukf, UtParams};
/// use nalgebra::{Matrix1, Matrix2, Vector1, Vector2};
///
/// // Constant velocity, position measured.
/// let mut ukf = Ukf::new(Vector2::new(0.0, 1.0), Matrix2::identity(), Euclidean, UtParams::default())?;
/// let q = Matrix2::identity() * 1e-3;
/// ukf.predict(|x| Vector2::new(x[0] + 0.1 * x[1], x[1]), &q)?;
/// let report = ukf.update(&Vector1::new(0.12), |x| Vector1::new(x[0]), &Matrix1::new(0.01), &Euclidean)?;
/// assert!(report.nis >= 0.0);
/// assert!((ukf.state()[0] - 0.1).abs() < 0.05);
/// # Ok::<(), dukf::UkfError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ukf<const N: usize, S: Space<N> = Euclidean> {
    est: Estimate<N>,
    space: S,
    weights: Weights,
    policy: JitterPolicy,
    initial_jitter: f64,
}

impl<const N: usize, S: Space<N>> Ukf<N, S> {
    /// A filter starting at mean `x0` with covariance `p0`.
    ///
    /// `x0` is normalised through the space (`x0 (+) 0`, which wraps angles). If `p0` fails
    /// Cholesky it is repaired by the default [`JitterPolicy`]; the jitter used is
    /// [`initial_jitter`](Self::initial_jitter).
    ///
    /// # Errors
    /// [`UkfError::InvalidParameters`], non-finite `x0`/`p0`, or
    /// [`UkfError::NotPositiveDefinite`] if `p0` cannot be repaired.
    pub fn new(
        x0: SVector<f64, N>,
        p0: SMatrix<f64, N, N>,
        space: S,
        params: UtParams,
    ) -> Result<Self, UkfError> {
        let weights = Weights::new(params, N)?;
        let policy = JitterPolicy::default();
        let est = initial_estimate(&space, &x0, &p0, &policy)?;
        let initial_jitter = est.p.jitter;
        Ok(Self {
            est,
            space,
            weights,
            policy,
            initial_jitter,
        })
    }

    /// Replaces the jitter policy used from now on.
    ///
    /// # Errors
    /// [`UkfError::InvalidJitterPolicy`] (and the filter keeps its old policy).
    pub fn set_jitter_policy(&mut self, policy: JitterPolicy) -> Result<(), UkfError> {
        policy.validate()?;
        self.policy = policy;
        Ok(())
    }

    /// Re-initialises the estimate (e.g. after a track was lost), returning the jitter that
    /// `p` needed.
    ///
    /// # Errors
    /// As [`new`](Self::new); on error the filter is unchanged.
    pub fn reset(&mut self, x: SVector<f64, N>, p: SMatrix<f64, N, N>) -> Result<f64, UkfError> {
        self.est = initial_estimate(&self.space, &x, &p, &self.policy)?;
        Ok(self.est.p.jitter)
    }

    /// The current state mean.
    pub fn state(&self) -> &SVector<f64, N> {
        &self.est.x
    }

    /// The current state covariance.
    pub fn covariance(&self) -> &SMatrix<f64, N, N> {
        &self.est.p.covariance
    }

    /// The lower Cholesky factor of [`covariance`](Self::covariance).
    pub fn covariance_factor(&self) -> &SMatrix<f64, N, N> {
        &self.est.p.factor
    }

    /// The state space.
    pub fn space(&self) -> &S {
        &self.space
    }

    /// The precomputed sigma-point weights.
    pub fn weights(&self) -> &Weights {
        &self.weights
    }

    /// The jitter policy in force.
    pub fn jitter_policy(&self) -> &JitterPolicy {
        &self.policy
    }

    /// The diagonal jitter the initial covariance needed (0 if none).
    pub fn initial_jitter(&self) -> f64 {
        self.initial_jitter
    }

    /// Time update: propagates the sigma points through `f` and adds `q`.
    ///
    /// `x- = mean_i f(X_i)`, `P- = sum_i Wc_i r_i r_i^T + Q` with `r_i = f(X_i) (-) x-`.
    /// Without a following [`update`](Self::update) this is the predict-only step for a frame
    /// with no measurement: the covariance grows by `Q` plus the spread of `f`.
    ///
    /// # Errors
    /// Non-finite `q`, `f` returning a non-finite value, an overflow, or a predicted
    /// covariance that cannot be repaired. The filter is unchanged on error.
    pub fn predict<F>(&mut self, f: F, q: &SMatrix<f64, N, N>) -> Result<PredictReport, UkfError>
    where
        F: FnMut(&SVector<f64, N>) -> SVector<f64, N>,
    {
        check_matrix(q, Input::ProcessNoise)?;
        let est = self.predicted(&self.est, f, q)?;
        let report = PredictReport {
            jitter: est.p.jitter,
        };
        self.est = est;
        Ok(report)
    }

    /// Measurement update with measurement `y`, measurement function `h` and noise `r`
    /// (which may differ at every call), `y` living in `measurement_space`.
    ///
    /// Redraws sigma points from the current (predicted) estimate, so the additive `Q` of
    /// the prediction is seen by `h`; then `S = sum Wc r r^T + R`, `Pxy`, `K = Pxy S^-1`,
    /// `x+ = x- (+) K (y (-) y^)`, `P+ = P- - K S K^T`.
    ///
    /// # Errors
    /// Non-finite `y` or `r`, `h` returning a non-finite value, an overflow, or an innovation
    /// or updated covariance that cannot be repaired. The filter is unchanged on error.
    pub fn update<const M: usize, SM, H>(
        &mut self,
        y: &SVector<f64, M>,
        h: H,
        r: &SMatrix<f64, M, M>,
        measurement_space: &SM,
    ) -> Result<UpdateReport<M>, UkfError>
    where
        SM: Space<M>,
        H: FnMut(&SVector<f64, N>) -> SVector<f64, M>,
    {
        check_vector(y, Input::Measurement)?;
        check_matrix(r, Input::MeasurementNoise)?;
        let (est, report) = self.updated(&self.est, y, h, r, measurement_space)?;
        self.est = est;
        Ok(report)
    }

    pub(crate) fn estimate(&self) -> &Estimate<N> {
        &self.est
    }

    pub(crate) fn commit(&mut self, est: Estimate<N>) {
        self.est = est;
    }

    /// The prediction of `prior` (inputs already checked), not committed.
    pub(crate) fn predicted<F>(
        &self,
        prior: &Estimate<N>,
        f: F,
        q: &SMatrix<f64, N, N>,
    ) -> Result<Estimate<N>, UkfError>
    where
        F: FnMut(&SVector<f64, N>) -> SVector<f64, N>,
    {
        let xs = sigma_points(&self.space, &prior.x, &prior.p.factor, &self.weights);
        let ys = map_points(&xs, f, Function::Process)?;
        let x = self.space.weighted_mean(&ys, &self.weights);
        if x.iter().any(|v| !v.is_finite()) {
            return Err(UkfError::NonFiniteEstimate {
                which: Covariance::Predicted,
            });
        }
        let r = residuals(&self.space, &ys, &x);
        let p = weighted_covariance(&r, &self.weights) + q;
        let p = factor_repaired(&p, &self.policy, Covariance::Predicted)?;
        Ok(Estimate { x, p })
    }

    /// The random-walk prediction `x- = x`, `P- = P + Q` (exact, no sigma points), not
    /// committed.
    pub(crate) fn random_walk(
        &self,
        prior: &Estimate<N>,
        q: &SMatrix<f64, N, N>,
    ) -> Result<Estimate<N>, UkfError> {
        let p = factor_repaired(
            &(prior.p.covariance + q),
            &self.policy,
            Covariance::Predicted,
        )?;
        Ok(Estimate { x: prior.x, p })
    }

    /// The update of `prior` (inputs already checked), not committed.
    pub(crate) fn updated<const M: usize, SM, H>(
        &self,
        prior: &Estimate<N>,
        y: &SVector<f64, M>,
        h: H,
        r: &SMatrix<f64, M, M>,
        measurement_space: &SM,
    ) -> Result<(Estimate<N>, UpdateReport<M>), UkfError>
    where
        SM: Space<M>,
        H: FnMut(&SVector<f64, N>) -> SVector<f64, M>,
    {
        let w = &self.weights;
        let xs = sigma_points(&self.space, &prior.x, &prior.p.factor, w);
        let ys = map_points(&xs, h, Function::Measurement)?;
        let y_hat = measurement_space.weighted_mean(&ys, w);
        if y_hat.iter().any(|v| !v.is_finite()) {
            return Err(UkfError::NonFiniteEstimate {
                which: Covariance::Innovation,
            });
        }
        let ry = residuals(measurement_space, &ys, &y_hat);
        let s = factor_repaired(
            &(weighted_covariance(&ry, w) + r),
            &self.policy,
            Covariance::Innovation,
        )?;
        let pxy = cross_from_factor(&prior.p.factor, &ry, w);

        // K^T = S^-1 Pxy^T by two triangular solves with S = L L^T. The factor's diagonal is
        // positive (it came out of a successful Cholesky), so the solves cannot fail.
        let mut kt = pxy.transpose();
        let solved = s.factor.solve_lower_triangular_mut(&mut kt)
            && s.factor.tr_solve_lower_triangular_mut(&mut kt);
        let innovation = measurement_space.residual(y, &y_hat);
        let mut z = innovation;
        let solved = solved && s.factor.solve_lower_triangular_mut(&mut z);
        if !solved {
            return Err(UkfError::NotPositiveDefinite {
                which: Covariance::Innovation,
                max_jitter: s.jitter,
            });
        }
        let nis = z.norm_squared();
        if !nis.is_finite() {
            // A finite but absurd measurement (e.g. 1e308) overflows the innovation.
            return Err(UkfError::NonFiniteEstimate {
                which: Covariance::Innovation,
            });
        }
        let k = kt.transpose();
        let x = self.space.add(&prior.x, &(k * innovation));
        if x.iter().any(|v| !v.is_finite()) {
            return Err(UkfError::NonFiniteEstimate {
                which: Covariance::Updated,
            });
        }
        // P+ = P- - K S K^T = P- - K Pxy^T (K S = Pxy).
        let p = prior.p.covariance - k * pxy.transpose();
        let p = factor_repaired(&p, &self.policy, Covariance::Updated)?;
        let report = UpdateReport {
            innovation,
            innovation_covariance: s.covariance,
            nis,
            innovation_jitter: s.jitter,
            jitter: p.jitter,
        };
        Ok((Estimate { x, p }, report))
    }
}

/// Checks and factorises a caller-supplied estimate.
fn initial_estimate<const N: usize, S: Space<N>>(
    space: &S,
    x: &SVector<f64, N>,
    p: &SMatrix<f64, N, N>,
    policy: &JitterPolicy,
) -> Result<Estimate<N>, UkfError> {
    check_vector(x, Input::State)?;
    check_matrix(p, Input::StateCovariance)?;
    let x = space.add(x, &SVector::zeros());
    let p = factor_repaired(p, policy, Covariance::Initial)?;
    Ok(Estimate { x, p })
}
