//! The interacting multiple-model (IMM) filter of Blom and Bar-Shalom (1988) over `K`
//! unscented Kalman filters that share one state vector.
//!
//! # The cycle
//!
//! Each model `j` has a filter (mean `x_j`, covariance `P_j`) and a probability `mu_j`; a
//! Markov matrix `Pi` (row `i`, column `j`: the probability of switching from model `i` to
//! model `j` over one step; rows sum to one) says how the models change. One step:
//!
//! 1. **Mixing.** `c_j = sum_i Pi_ij mu_i` (the predicted model probabilities) and
//!    `mu_{i|j} = Pi_ij mu_i / c_j`; each filter restarts from the mixture of all of them
//!    seen from model `j`: `x0_j = x_j (+) sum_i mu_{i|j} (x_i (-) x_j)`,
//!    `P0_j = sum_i mu_{i|j} (P_i + d_ij d_ij^T)` with `d_ij = x_i (-) x0_j`. The mean is taken
//!    through the [`Space`] (residuals from model `j`'s own mean), so angles mix on the circle.
//! 2. **Model-matched filtering.** Filter `j` predicts with its own process function and
//!    process noise (`f(j, x)`, `Q_j`) and, on a frame with a measurement, updates with the
//!    shared `y`, `h`, `R`.
//! 3. **Model probabilities.** The update's innovation `nu_j` and its covariance `S_j` give
//!    the likelihood `L_j = N(nu_j; 0, S_j)`; `mu_j = c_j L_j / sum_i c_i L_i`, computed
//!    from log-likelihoods (`-nis_j / 2 - ln det S_j / 2`) so that a model far from the data
//!    gets a probability near zero instead of an underflow. A frame without a measurement
//!    leaves `mu_j = c_j`.
//! 4. **Combination** (output only; the filters keep their own estimates):
//!    `x = x_0 (+) sum_j mu_j (x_j (-) x_0)`, `P = sum_j mu_j (P_j + d_j d_j^T)` with `d_j = x_j (-) x`.
//!
//! # Errors and no allocation
//!
//! A step works on copies of the `K` filters and commits them and the probabilities only
//! when every model succeeded: after an error the filter holds exactly what it held before
//! (the failing model is named in [`UkfError::Imm`]). After construction a step allocates
//! nothing (the error path boxes its source).

use nalgebra::{SMatrix, SVector};

use crate::error::{Input, UkfError};
use crate::space::Space;
use crate::transform::{check_matrix, check_vector};
use crate::ukf::Ukf;

/// What one IMM step did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImmReport<const K: usize> {
    /// Each model's normalised innovation squared (`None` on a frame without a measurement).
    pub nis: Option<[f64; K]>,
    /// The combined normalised innovation squared `nu^T S^-1 nu` of the probability-weighted
    /// innovation against the mixture's innovation covariance (chi-square with `M` degrees of
    /// freedom when the IMM is consistent); `None` on a frame without a measurement.
    pub combined_nis: Option<f64>,
    /// The model probabilities after the step.
    pub probabilities: [f64; K],
}

/// An interacting multiple-model filter over `K` unscented Kalman filters with a shared
/// state of dimension `N` in the space `S`. The models are supplied by the caller at every
/// step (`f(j, x)` and `Q_j`), so the filter knows nothing about what they mean; see the
/// module documentation for the cycle.
///
/// ```
/// use dukf::{Euclidean, Imm, Ukf, UtParams};
/// use nalgebra::{Matrix1, Matrix2, Vector1, Vector2};
///
/// // Position and velocity; model 0: constant velocity, model 1: standing still.
/// let ukf = Ukf::new(Vector2::new(0.0, 0.0), Matrix2::identity(), Euclidean, UtParams::default())?;
/// let pi = Matrix2::new(0.95, 0.05, 0.05, 0.95);
/// let mut imm = Imm::new([ukf, ukf], [0.5, 0.5], pi)?;
/// let q = [Matrix2::identity() * 1e-4, Matrix2::identity() * 1e-4];
/// for k in 1..=50 {
///     let y = Vector1::new(0.1 * f64::from(k)); // moving at 1 unit/s, dt = 0.1
///     imm.step(
///         |j, x: &Vector2<f64>| if j == 0 { Vector2::new(x[0] + 0.1 * x[1], x[1]) } else { Vector2::new(x[0], 0.0) },
///         &q,
///         &y,
///         |x: &Vector2<f64>| Vector1::new(x[0]),
///         &Matrix1::new(1e-3),
///         &Euclidean,
///     )?;
/// }
/// assert!(imm.probabilities()[0] > 0.9);
/// # Ok::<(), dukf::UkfError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Imm<const N: usize, const K: usize, S: Space<N>> {
    filters: [Ukf<N, S>; K],
    mu: [f64; K],
    transition: SMatrix<f64, K, K>,
}

impl<const N: usize, const K: usize, S: Space<N> + Copy> Imm<N, K, S> {
    /// An IMM from one filter per model (each with its initial estimate), the initial model
    /// probabilities `mu0` and the Markov switching matrix `transition` (row `i`, column `j`:
    /// the probability of switching from model `i` to model `j` in one step).
    ///
    /// # Errors
    /// [`UkfError::InvalidModelProbabilities`] if `K == 0`, any probability is negative or
    /// not finite, `mu0` or a row of `transition` does not sum to one (to `1e-9`).
    pub fn new(
        filters: [Ukf<N, S>; K],
        mu0: [f64; K],
        transition: SMatrix<f64, K, K>,
    ) -> Result<Self, UkfError> {
        if K == 0 {
            return Err(UkfError::InvalidModelProbabilities {
                reason: "an IMM needs at least one model",
            });
        }
        check_probabilities(&mu0)?;
        for i in 0..K {
            let row: [f64; K] = core::array::from_fn(|j| transition[(i, j)]);
            check_probabilities(&row)?;
        }
        Ok(Self {
            filters,
            mu: mu0,
            transition,
        })
    }

    /// The model probabilities.
    pub fn probabilities(&self) -> &[f64; K] {
        &self.mu
    }

    /// The model-matched filters (each with its own estimate).
    pub fn filters(&self) -> &[Ukf<N, S>; K] {
        &self.filters
    }

    /// The switching matrix.
    pub fn transition(&self) -> &SMatrix<f64, K, K> {
        &self.transition
    }

    /// Replaces the switching matrix and the model probabilities (e.g. when the set of
    /// models in force changes: a model given probability 0 and no transition into it drops
    /// out of the mixture). The model-matched filters keep their estimates.
    ///
    /// # Errors
    /// `mu` or a row of `transition` not a probability vector (finite, non-negative,
    /// summing to 1); nothing is changed then.
    pub fn set_structure(
        &mut self,
        transition: SMatrix<f64, K, K>,
        mu: [f64; K],
    ) -> Result<(), UkfError> {
        check_probabilities(&mu)?;
        for i in 0..K {
            let row: [f64; K] = core::array::from_fn(|j| transition[(i, j)]);
            check_probabilities(&row)?;
        }
        self.transition = transition;
        self.mu = mu;
        Ok(())
    }

    /// The combined (probability-weighted) estimate: mean and covariance, see the module
    /// documentation.
    pub fn estimate(&self) -> (SVector<f64, N>, SMatrix<f64, N, N>) {
        combine(&self.filters, &self.mu)
    }

    /// Re-initialises every model at `x`, `p` with probabilities `mu` (e.g. after a track
    /// was lost).
    ///
    /// # Errors
    /// As [`Ukf::reset`] and [`Imm::new`]; on error nothing changes.
    pub fn reset(
        &mut self,
        x: SVector<f64, N>,
        p: SMatrix<f64, N, N>,
        mu: [f64; K],
    ) -> Result<(), UkfError> {
        check_probabilities(&mu)?;
        let mut filters = self.filters;
        for f in &mut filters {
            f.reset(x, p)?;
        }
        self.filters = filters;
        self.mu = mu;
        Ok(())
    }

    /// The mixing stage: the predicted model probabilities `c` and the `K` filters restarted
    /// from their mixed estimates.
    fn mixed(&self) -> Result<([f64; K], [Ukf<N, S>; K]), UkfError> {
        let c: [f64; K] = core::array::from_fn(|j| {
            (0..K)
                .map(|i| self.transition[(i, j)] * self.mu[i])
                .sum::<f64>()
        });
        let mut filters = self.filters;
        for j in 0..K {
            if c[j] <= 0.0 {
                // Unreachable model: keep its own estimate (its weight is zero anyway).
                continue;
            }
            let w: [f64; K] = core::array::from_fn(|i| self.transition[(i, j)] * self.mu[i] / c[j]);
            let space = self.filters[j].space();
            let xj = self.filters[j].state();
            let mut dx = SVector::<f64, N>::zeros();
            for (fi, wi) in self.filters.iter().zip(w) {
                dx += space.residual(fi.state(), xj) * wi;
            }
            let x0 = space.add(xj, &dx);
            let mut p0 = SMatrix::<f64, N, N>::zeros();
            for (fi, wi) in self.filters.iter().zip(w) {
                let d = space.residual(fi.state(), &x0);
                p0 += (fi.covariance() + d * d.transpose()) * wi;
            }
            filters[j]
                .reset(x0, (p0 + p0.transpose()) * 0.5)
                .map_err(|e| e.in_imm(j))?;
        }
        Ok((c, filters))
    }

    /// One frame with a measurement `y`: mixing, model-matched prediction with `f(j, x)` and
    /// `q[j]`, update with `h` and `r`, model probabilities from the likelihoods.
    ///
    /// # Errors
    /// Non-finite `y`, `r` or `q`; any model's filter failing ([`UkfError::Imm`] names it).
    /// The filter is unchanged on error.
    pub fn step<const M: usize, SM, F, H>(
        &mut self,
        mut f: F,
        q: &[SMatrix<f64, N, N>; K],
        y: &SVector<f64, M>,
        mut h: H,
        r: &SMatrix<f64, M, M>,
        measurement_space: &SM,
    ) -> Result<ImmReport<K>, UkfError>
    where
        SM: Space<M>,
        F: FnMut(usize, &SVector<f64, N>) -> SVector<f64, N>,
        H: FnMut(&SVector<f64, N>) -> SVector<f64, M>,
    {
        check_vector(y, Input::Measurement)?;
        check_matrix(r, Input::MeasurementNoise)?;
        for qj in q {
            check_matrix(qj, Input::ProcessNoise)?;
        }
        let (c, mut filters) = self.mixed()?;
        let mut log_l = [0.0; K];
        let mut nis = [0.0; K];
        let mut innovations = [SVector::<f64, M>::zeros(); K];
        let mut covariances = [SMatrix::<f64, M, M>::zeros(); K];
        for (j, filter) in filters.iter_mut().enumerate() {
            filter
                .predict(|x| f(j, x), &q[j])
                .map_err(|e| e.in_imm(j))?;
            let report = filter
                .update(y, &mut h, r, measurement_space)
                .map_err(|e| e.in_imm(j))?;
            // ln det S from its Cholesky factor (S was factorised by the update).
            let ln_det = match report.innovation_covariance.cholesky() {
                Some(ch) => 2.0 * ch.l().diagonal().iter().map(|d| d.ln()).sum::<f64>(),
                None => {
                    return Err(UkfError::NotPositiveDefinite {
                        which: crate::error::Covariance::Innovation,
                        max_jitter: report.innovation_jitter,
                    }
                    .in_imm(j));
                }
            };
            log_l[j] = -0.5 * (report.nis + ln_det);
            nis[j] = report.nis;
            innovations[j] = report.innovation;
            covariances[j] = report.innovation_covariance;
        }
        let mu = posterior(&c, &log_l);
        // The combined innovation and its covariance (the mixture of the models' Gaussians).
        let mut nu = SVector::<f64, M>::zeros();
        for j in 0..K {
            nu += innovations[j] * c[j];
        }
        let mut s = SMatrix::<f64, M, M>::zeros();
        for j in 0..K {
            let d = innovations[j] - nu;
            s += (covariances[j] + d * d.transpose()) * c[j];
        }
        let combined_nis = s
            .cholesky()
            .map(|ch| nu.dot(&ch.solve(&nu)))
            .filter(|v| v.is_finite());
        self.filters = filters;
        self.mu = mu;
        Ok(ImmReport {
            nis: Some(nis),
            combined_nis,
            probabilities: mu,
        })
    }

    /// One frame without a measurement: mixing and model-matched prediction; the model
    /// probabilities become the predicted ones.
    ///
    /// # Errors
    /// Non-finite `q`; any model's prediction failing. The filter is unchanged on error.
    pub fn predict_only<F>(
        &mut self,
        mut f: F,
        q: &[SMatrix<f64, N, N>; K],
    ) -> Result<ImmReport<K>, UkfError>
    where
        F: FnMut(usize, &SVector<f64, N>) -> SVector<f64, N>,
    {
        for qj in q {
            check_matrix(qj, Input::ProcessNoise)?;
        }
        let (c, mut filters) = self.mixed()?;
        for (j, filter) in filters.iter_mut().enumerate() {
            filter
                .predict(|x| f(j, x), &q[j])
                .map_err(|e| e.in_imm(j))?;
        }
        self.filters = filters;
        self.mu = c;
        Ok(ImmReport {
            nis: None,
            combined_nis: None,
            probabilities: c,
        })
    }
}

/// `mu_j = c_j L_j / sum_i c_i L_i` from log-likelihoods, shifted by their maximum so that
/// the exponentials cannot all underflow.
fn posterior<const K: usize>(c: &[f64; K], log_l: &[f64; K]) -> [f64; K] {
    let top = (0..K)
        .filter(|&j| c[j] > 0.0)
        .map(|j| log_l[j])
        .fold(f64::NEG_INFINITY, f64::max);
    let mut mu: [f64; K] = core::array::from_fn(|j| {
        if c[j] > 0.0 {
            c[j] * (log_l[j] - top).exp()
        } else {
            0.0
        }
    });
    let total: f64 = mu.iter().sum();
    if total > 0.0 && total.is_finite() {
        for m in &mut mu {
            *m /= total;
        }
        mu
    } else {
        *c
    }
}

/// The probability-weighted mean and covariance of the models' estimates.
fn combine<const N: usize, const K: usize, S: Space<N>>(
    filters: &[Ukf<N, S>; K],
    mu: &[f64; K],
) -> (SVector<f64, N>, SMatrix<f64, N, N>) {
    let space = filters[0].space();
    let x0 = filters[0].state();
    let mut dx = SVector::<f64, N>::zeros();
    for (f, &m) in filters.iter().zip(mu) {
        dx += space.residual(f.state(), x0) * m;
    }
    let x = space.add(x0, &dx);
    let mut p = SMatrix::<f64, N, N>::zeros();
    for (f, &m) in filters.iter().zip(mu) {
        let d = space.residual(f.state(), &x);
        p += (f.covariance() + d * d.transpose()) * m;
    }
    (x, (p + p.transpose()) * 0.5)
}

/// Probabilities: finite, non-negative, summing to one within `1e-9`.
fn check_probabilities<const K: usize>(p: &[f64; K]) -> Result<(), UkfError> {
    if p.iter().any(|v| !v.is_finite() || *v < 0.0) {
        return Err(UkfError::InvalidModelProbabilities {
            reason: "probabilities must be finite and non-negative",
        });
    }
    if (p.iter().sum::<f64>() - 1.0).abs() > 1e-9 {
        return Err(UkfError::InvalidModelProbabilities {
            reason: "the model probabilities and each row of the switching matrix must sum to 1",
        });
    }
    Ok(())
}

/// The switching matrix of `K` models that stay in their model for a mean sojourn time
/// `sojourn` (seconds) and, when they leave, go to each other model with equal probability:
/// `Pi_jj = exp(-dt / sojourn)`, the rest of each row spread evenly.
///
/// # Errors
/// [`UkfError::InvalidModelProbabilities`] if `dt` or `sojourn` is not finite and positive.
pub fn sojourn_transition<const K: usize>(
    dt: f64,
    sojourn: f64,
) -> Result<SMatrix<f64, K, K>, UkfError> {
    if !(dt.is_finite() && dt > 0.0 && sojourn.is_finite() && sojourn > 0.0) {
        return Err(UkfError::InvalidModelProbabilities {
            reason: "the step dt and the mean sojourn time must be finite and positive",
        });
    }
    if K == 1 {
        return Ok(SMatrix::identity());
    }
    let stay = (-dt / sojourn).exp();
    let leave = (1.0 - stay) / (K - 1) as f64;
    Ok(SMatrix::from_fn(|i, j| if i == j { stay } else { leave }))
}
/// The moment-matched mean of `K` model predictions `outs` under the probabilities `p`:
/// `outs[0] (+) sum_j p_j (outs[j] (-) outs[0])` in `space` (angles averaged on the circle
/// near the first prediction). With [`mixture_noise`], it turns a model set into one
/// transition, e.g. for smoothing an IMM's recorded run with [`crate::filter_and_smooth`].
pub fn mixture_mean<const N: usize, const K: usize, S: Space<N>>(
    space: &S,
    outs: &[SVector<f64, N>; K],
    p: &[f64; K],
) -> SVector<f64, N> {
    let base = outs[0];
    let mut acc = SVector::<f64, N>::zeros();
    for (pj, out) in p.iter().zip(outs) {
        acc += space.residual(out, &base) * *pj;
    }
    space.add(&base, &acc)
}

/// The noise of the mixture transition of [`mixture_mean`]: `sum_j p_j (Q_j + d_j d_j^T)`
/// with `d_j = outs[j] (-) mean` (the models' own noises and the spread of their
/// predictions), symmetrised.
pub fn mixture_noise<const N: usize, const K: usize, S: Space<N>>(
    space: &S,
    outs: &[SVector<f64, N>; K],
    mean: &SVector<f64, N>,
    noises: impl Fn(usize) -> SMatrix<f64, N, N>,
    p: &[f64; K],
) -> SMatrix<f64, N, N> {
    let mut q = SMatrix::<f64, N, N>::zeros();
    for j in 0..K {
        let d = space.residual(&outs[j], mean);
        q += (noises(j) + d * d.transpose()) * p[j];
    }
    (q + q.transpose()) * 0.5
}
