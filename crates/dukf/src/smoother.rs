//! The unscented Rauch-Tung-Striebel smoother (Särkkä 2008, "Unscented Rauch-Tung-Striebel
//! smoother", IEEE T-AC 53(3)): the fixed-interval smoother that runs backwards over the
//! estimates of a finished forward pass.
//!
//! # The backward step
//!
//! Given the filtered estimate `(m_k, P_k)` of every step `k = 0..n` of a forward pass (the
//! estimate after step `k`'s update, or after its prediction alone when step `k` had no
//! measurement) and the process `x_{k+1} = f_k(x_k) + q_k`, `q_k ~ N(0, Q_k)`, the smoothed
//! estimate of the last step is its filtered one, and for `k = n - 1, ..., 0`:
//!
//! ```text
//! X_i    = sigma points of (m_k, P_k)
//! m-     = mean_i f_k(X_i)                           (the forward prediction, recomputed)
//! P-     = sum_i Wc_i (f_k(X_i) (-) m-)(...)^T + Q_k
//! C      = sum_i Wc_i (X_i (-) m_k)(f_k(X_i) (-) m-)^T
//! G      = C P-^-1
//! ms_k   = m_k (+) G (ms_{k+1} (-) m-)
//! Ps_k   = P_k + G (Ps_{k+1} - P-) G^T
//! ```
//!
//! The prediction is recomputed from the filtered estimate rather than stored: the forward
//! [`Ukf::predict`](crate::Ukf::predict) computes exactly these moments from the same sigma
//! points, so with the same `f_k` and `Q_k` the two agree, and the history the caller keeps
//! is only one mean and one covariance per step. A step without a measurement needs nothing
//! special: its filtered estimate is its prediction, and the backward recursion is the same.
//!
//! For linear `f_k` in a Euclidean space the unscented transform is exact, so this is the
//! linear RTS smoother (a property test checks it to `1e-9`).
//!
//! # Spaces
//!
//! Residuals and sums go through the caller's [`Space`] (angles wrapped, circular means),
//! as in the filter. The cross-covariance uses the sigma-point offsets `+-gamma S_j`
//! themselves as the state deviations, as the filter does.
//!
//! # Parameters and dual filters
//!
//! The smoother smooths one vector. To smooth a [`DualUkf`](crate::DualUkf)'s state together
//! with its parameters `w`, smooth the augmented vector `z = [x; w]` with the process
//! `z_{k+1} = [f(x_k, w_k); w_k]` (a random walk for `w`) and noise `blockdiag(Q, Rr)`, from
//! the filtered estimates `[x_k; w_k]`, `blockdiag(P_k, Pw_k)` (the dual filter keeps no
//! cross-covariance between the two). The cross-covariance `C` then links `w_k` to
//! `x_{k+1}`, so that the positions measured after step `k` correct the velocity at `k`;
//! smoothing `x` alone with `w_k` as a fixed input would leave `w` at its causal estimate.
//!
//! # Definiteness
//!
//! Every covariance goes through [`factor_repaired`] with the smoother's [`JitterPolicy`]
//! (the filter's default unless replaced); one that cannot be repaired is a
//! [`UkfError::Smoothing`] naming the step, and nothing is returned. No NaN is ever
//! returned: a non-finite input, process value, noise or result is a typed error.

use nalgebra::{SMatrix, SVector};

use crate::error::{Covariance, Function, Input, UkfError};
use crate::jitter::{JitterPolicy, factor_repaired};
use crate::sigma::{UtParams, Weights};
use crate::space::{Space, residuals};
use crate::transform::{
    check_matrix, check_vector, cross_from_factor, map_points, sigma_points, weighted_covariance,
};

/// A Gaussian estimate: a mean and its covariance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gaussian<const N: usize> {
    /// The mean.
    pub mean: SVector<f64, N>,
    /// The covariance.
    pub covariance: SMatrix<f64, N, N>,
}

impl<const N: usize> Gaussian<N> {
    /// An estimate from its mean and covariance.
    pub const fn new(mean: SVector<f64, N>, covariance: SMatrix<f64, N, N>) -> Self {
        Self { mean, covariance }
    }
}

/// The result of a smoothing pass.
#[derive(Debug, Clone, PartialEq)]
pub struct Smoothed<const N: usize> {
    /// One smoothed estimate per filtered estimate, in the same order.
    pub estimates: Vec<Gaussian<N>>,
    /// The largest diagonal jitter any covariance of the pass needed (absolute; 0 if none).
    pub max_jitter: f64,
    /// The log-likelihood of the measurements under the forward pass: the sum over its
    /// updates of `log N(nu; 0, S)` (nats), how well the smoother's model predicted the
    /// recording. [`filter_and_smooth`] fills it in; `None` from [`RtsSmoother::smooth`], which
    /// sees no measurements. Comparable between models run on the same measurements.
    pub log_likelihood: Option<f64>,
}

/// The unscented Rauch-Tung-Striebel smoother over a vector of dimension `N` in the space
/// `S`. See the [module documentation](self) for the equations.
///
/// ```
/// use dukf::{Euclidean, Gaussian, RtsSmoother, Ukf, UtParams};
/// use nalgebra::{Matrix1, Matrix2, Vector1, Vector2};
///
/// // Constant velocity, position measured: the forward pass keeps every filtered estimate.
/// let f = |x: &Vector2<f64>| Vector2::new(x[0] + 0.1 * x[1], x[1]);
/// let q = Matrix2::identity() * 1e-4;
/// let mut ukf = Ukf::new(Vector2::new(0.0, 0.0), Matrix2::identity(), Euclidean, UtParams::default())?;
/// let mut history = vec![Gaussian::new(*ukf.state(), *ukf.covariance())];
/// for k in 1..=20 {
///     ukf.predict(f, &q)?;
///     let y = Vector1::new(0.1 * f64::from(k));
///     ukf.update(&y, |x| Vector1::new(x[0]), &Matrix1::new(0.01), &Euclidean)?;
///     history.push(Gaussian::new(*ukf.state(), *ukf.covariance()));
/// }
/// let smoother = RtsSmoother::new(Euclidean, UtParams::default())?;
/// let smoothed = smoother.smooth(&history, |_, x| f(x), |_| q)?;
/// // The velocity at the start is known much better once the whole track is seen.
/// assert!(smoothed.estimates[0].covariance[(1, 1)] < 0.1 * history[0].covariance[(1, 1)]);
/// # Ok::<(), dukf::UkfError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RtsSmoother<const N: usize, S: Space<N>> {
    space: S,
    weights: Weights,
    policy: JitterPolicy,
}

impl<const N: usize, S: Space<N>> RtsSmoother<N, S> {
    /// A smoother in `space` with the unscented-transform parameters `params` (use the
    /// forward filter's, so that the recomputed predictions equal the filter's) and the
    /// default [`JitterPolicy`].
    ///
    /// # Errors
    /// [`UkfError::InvalidParameters`].
    pub fn new(space: S, params: UtParams) -> Result<Self, UkfError> {
        Ok(Self {
            space,
            weights: Weights::new(params, N)?,
            policy: JitterPolicy::default(),
        })
    }

    /// Replaces the jitter policy.
    ///
    /// # Errors
    /// [`UkfError::InvalidJitterPolicy`] (and the smoother keeps its old policy).
    pub fn set_jitter_policy(&mut self, policy: JitterPolicy) -> Result<(), UkfError> {
        policy.validate()?;
        self.policy = policy;
        Ok(())
    }

    /// The space.
    pub fn space(&self) -> &S {
        &self.space
    }

    /// Smooths the filtered estimates `filtered[0..=n]` of a forward pass.
    ///
    /// `f(k, x)` is the process from step `k` to step `k + 1` (`k = 0..n`, with whatever
    /// inputs and parameters the forward pass used for that transition), `q(k)` its additive
    /// noise covariance. Allocates the returned vector once; nothing else.
    ///
    /// # Errors
    /// [`UkfError::EmptyHistory`] for an empty slice; otherwise a [`UkfError::Smoothing`]
    /// naming the step, wrapping a non-finite estimate, noise or process value, or a
    /// covariance that cannot be repaired. Nothing is returned on error.
    pub fn smooth<F, Q>(
        &self,
        filtered: &[Gaussian<N>],
        mut f: F,
        mut q: Q,
    ) -> Result<Smoothed<N>, UkfError>
    where
        F: FnMut(usize, &SVector<f64, N>) -> SVector<f64, N>,
        Q: FnMut(usize) -> SMatrix<f64, N, N>,
    {
        let Some(last) = filtered.last() else {
            return Err(UkfError::EmptyHistory);
        };
        let n = filtered.len() - 1;
        let at = |step: usize| {
            move |e: UkfError| UkfError::Smoothing {
                step,
                source: Box::new(e),
            }
        };
        check_estimate(last).map_err(at(n))?;
        let mut max_jitter = 0.0_f64;
        let mut out = Vec::with_capacity(filtered.len());
        out.extend_from_slice(filtered);
        for k in (0..n).rev() {
            let next = out[k + 1];
            let (smoothed, jitter) = self
                .backward(&filtered[k], &next, |x| f(k, x), &q(k))
                .map_err(at(k))?;
            max_jitter = max_jitter.max(jitter);
            out[k] = smoothed;
        }
        Ok(Smoothed {
            estimates: out,
            max_jitter,
            log_likelihood: None,
        })
    }

    /// One backward step: the smoothed estimate of step `k` from its filtered one and the
    /// smoothed estimate of step `k + 1`; returns it with the largest jitter used.
    fn backward<F>(
        &self,
        filtered: &Gaussian<N>,
        next: &Gaussian<N>,
        f: F,
        q: &SMatrix<f64, N, N>,
    ) -> Result<(Gaussian<N>, f64), UkfError>
    where
        F: FnMut(&SVector<f64, N>) -> SVector<f64, N>,
    {
        check_estimate(filtered)?;
        check_matrix(q, Input::ProcessNoise)?;
        let w = &self.weights;
        let pk = factor_repaired(&filtered.covariance, &self.policy, Covariance::Initial)?;
        let xs = sigma_points(&self.space, &filtered.mean, &pk.factor, w);
        let ys = map_points(&xs, f, Function::Process)?;
        let m_pred = self.space.weighted_mean(&ys, w);
        if m_pred.iter().any(|v| !v.is_finite()) {
            return Err(UkfError::NonFiniteEstimate {
                which: Covariance::Predicted,
            });
        }
        let r = residuals(&self.space, &ys, &m_pred);
        let p_pred = factor_repaired(
            &(weighted_covariance(&r, w) + q),
            &self.policy,
            Covariance::Predicted,
        )?;
        let c = cross_from_factor(&pk.factor, &r, w);
        // G^T = P-^-1 C^T by two triangular solves with P- = L L^T (the factor's diagonal is
        // positive: it came out of a successful Cholesky).
        let mut gt = c.transpose();
        let solved = p_pred.factor.solve_lower_triangular_mut(&mut gt)
            && p_pred.factor.tr_solve_lower_triangular_mut(&mut gt);
        if !solved {
            return Err(UkfError::NotPositiveDefinite {
                which: Covariance::Predicted,
                max_jitter: p_pred.jitter,
            });
        }
        let g = gt.transpose();
        let mean = self.space.add(
            &filtered.mean,
            &(g * self.space.residual(&next.mean, &m_pred)),
        );
        let p = pk.covariance + g * (next.covariance - p_pred.covariance) * gt;
        if mean.iter().chain(p.iter()).any(|v| !v.is_finite()) {
            return Err(UkfError::NonFiniteEstimate {
                which: Covariance::Smoothed,
            });
        }
        let p = factor_repaired(&p, &self.policy, Covariance::Smoothed)?;
        let jitter = pk.jitter.max(p_pred.jitter).max(p.jitter);
        Ok((Gaussian::new(mean, p.covariance), jitter))
    }
}

fn check_estimate<const N: usize>(e: &Gaussian<N>) -> Result<(), UkfError> {
    check_vector(&e.mean, Input::State)?;
    check_matrix(&e.covariance, Input::StateCovariance)
}

/// One measurement of a recorded step: the value and its noise covariance.
pub type Measured<const M: usize> = (SVector<f64, M>, SMatrix<f64, M, M>);

/// The smoother of a recorded run in one call: an unscented Kalman filter over `len` steps
/// from `start`, predicting step `k` from step `k - 1` with `f(k - 1, x)` and the noise
/// `noise(k - 1, m)` (`m` the filtered mean of step `k - 1`; each noise is computed once and
/// kept, so that the backward pass uses the same one), updating with `measurement(k)` through
/// `h` when there is one; then [`RtsSmoother::smooth`] backwards over that pass with the same
/// transitions. Use it when the filter that ran causally is not the smoother's model (a
/// multiple-model mixture, or two filters without their cross-covariance): the backward
/// recursion needs filtered estimates that are the Bayesian updates of its own predictions.
///
/// # Errors
/// Bad parameters, a bad start, any filter or smoother error ([`UkfError`]); nothing is
/// returned on error.
#[allow(clippy::too_many_arguments)] // one call: the model, the record and the spaces
pub fn filter_and_smooth<const N: usize, const M: usize, S, SM>(
    space: S,
    params: UtParams,
    start: &Gaussian<N>,
    len: usize,
    mut f: impl FnMut(usize, &SVector<f64, N>) -> SVector<f64, N>,
    mut noise: impl FnMut(usize, &SVector<f64, N>) -> SMatrix<f64, N, N>,
    mut measurement: impl FnMut(usize) -> Option<Measured<M>>,
    mut h: impl FnMut(&SVector<f64, N>) -> SVector<f64, M>,
    measurement_space: &SM,
) -> Result<Smoothed<N>, UkfError>
where
    S: Space<N> + Clone,
    SM: Space<M>,
{
    let smoother = RtsSmoother::new(space.clone(), params)?;
    let mut ukf = crate::Ukf::new(start.mean, start.covariance, space, params)?;
    let mut filtered = Vec::with_capacity(len);
    let mut noises: Vec<SMatrix<f64, N, N>> = Vec::with_capacity(len);
    filtered.push(Gaussian::new(*ukf.state(), *ukf.covariance()));
    let mut log_likelihood = 0.0;
    for k in 1..len {
        let q = noise(k - 1, ukf.state());
        noises.push(q);
        ukf.predict(|x| f(k - 1, x), &q)?;
        if let Some((y, r)) = measurement(k) {
            let report = ukf.update(&y, &mut h, &r, measurement_space)?;
            log_likelihood += gaussian_log_density(&report);
        }
        filtered.push(Gaussian::new(*ukf.state(), *ukf.covariance()));
    }
    let mut smoothed = smoother.smooth(&filtered, f, |k| noises[k])?;
    smoothed.log_likelihood = Some(log_likelihood);
    Ok(smoothed)
}

/// `log N(nu; 0, S)` of one update: `-(nis + ln det S + M ln 2 pi) / 2`, `ln det S` from the
/// Cholesky factor. `S` is positive definite after the update's repair; were it not, the
/// density is taken as zero (`-inf`), never NaN.
fn gaussian_log_density<const M: usize>(report: &crate::UpdateReport<M>) -> f64 {
    let Some(chol) = report.innovation_covariance.cholesky() else {
        return f64::NEG_INFINITY;
    };
    let log_det = 2.0
        * chol
            .l_dirty()
            .diagonal()
            .iter()
            .map(|d| d.ln())
            .sum::<f64>();
    -0.5 * (report.nis + log_det + M as f64 * (2.0 * std::f64::consts::PI).ln())
}
