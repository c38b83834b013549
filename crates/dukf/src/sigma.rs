//! Scaled sigma points and their weights (spec section 5).
//!
//! For a vector of dimension `L` the scaled unscented transform uses `2L + 1` points
//!
//! ```text
//! X_0 = x,   X_j = x (+) gamma S_j,   X_{L+j} = x (+) (-gamma S_j),   j = 1..L
//! ```
//!
//! where `S_j` is column `j` of the lower Cholesky factor of `P`, `gamma = sqrt(L + lambda)`
//! and `(+)` is the space's [`add`](crate::Space::add). The weights are
//!
//! ```text
//! lambda = a^2 (L + kappa) - L
//! W0_m = lambda / (L + lambda)
//! W0_c = W0_m + (1 - a^2 + b)
//! Wi_m = Wi_c = 1 / (2 (L + lambda))
//! ```
//!
//! Because `2L + 1` cannot be written as a const generic on stable Rust, a set of points is
//! stored as a centre plus two `D x L` matrices (the plus side and the minus side), so
//! nothing is heap-allocated.

use nalgebra::{SMatrix, SVector};

use crate::error::UkfError;

/// Parameters of the scaled unscented transform.
///
/// The defaults are `alpha = 0.1`, `beta = 2`, `kappa = 0`. `beta = 2` is optimal for a
/// Gaussian prior. `alpha = 0.1` puts the sigma points `0.1 sqrt(L)` standard deviations
/// from the mean (a quarter sigma for `L = 6`): local enough that a model is not evaluated
/// far outside its domain (a distance pushed through zero, an angle past a half turn), but
/// not as close as the often quoted `1e-3`, where the weights (about `1 / (2 alpha^2 L)`)
/// amplify the rounding in `f` a million times (see the `linear` tests: `1e-9` agreement with
/// the Kalman filter at `alpha >= 1e-2`, only `1e-7` at `1e-3`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UtParams {
    /// Spread of the points around the mean (`a`, `0 < a <= 1` in practice).
    pub alpha: f64,
    /// Prior knowledge of the distribution (`b`, 2 is optimal for a Gaussian).
    pub beta: f64,
    /// Secondary scaling (`kappa`, usually 0 or `3 - L`).
    pub kappa: f64,
}

impl Default for UtParams {
    fn default() -> Self {
        Self {
            alpha: 0.1,
            beta: 2.0,
            kappa: 0.0,
        }
    }
}

impl UtParams {
    /// Parameters with the given `alpha`, `beta` and `kappa`.
    pub const fn new(alpha: f64, beta: f64, kappa: f64) -> Self {
        Self { alpha, beta, kappa }
    }
}

/// Precomputed weights for one dimension `L` (computed once, at construction).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Weights {
    /// Mean weight of the centre point, `W0_m = lambda / (L + lambda)`.
    pub mean0: f64,
    /// Covariance weight of the centre point, `W0_c = W0_m + (1 - a^2 + b)`.
    pub cov0: f64,
    /// Weight of every other point (mean and covariance), `1 / (2 (L + lambda))`.
    pub other: f64,
    /// Scale of the Cholesky columns, `gamma = sqrt(L + lambda)`.
    pub gamma: f64,
    /// `lambda = a^2 (L + kappa) - L`.
    pub lambda: f64,
}

impl Weights {
    /// Weights of the scaled unscented transform for a vector of dimension `dimension`.
    ///
    /// # Errors
    /// [`UkfError::InvalidParameters`] if a parameter is not finite, `alpha <= 0`,
    /// `dimension == 0`, or `L + lambda <= 0` (no real sigma points).
    pub fn new(params: UtParams, dimension: usize) -> Result<Self, UkfError> {
        let UtParams { alpha, beta, kappa } = params;
        let invalid = |reason| UkfError::InvalidParameters {
            alpha,
            beta,
            kappa,
            dimension,
            reason,
        };
        if !(alpha.is_finite() && beta.is_finite() && kappa.is_finite()) {
            return Err(invalid("all parameters must be finite"));
        }
        if alpha <= 0.0 {
            return Err(invalid("alpha must be positive"));
        }
        if dimension == 0 {
            return Err(invalid("the dimension must be at least 1"));
        }
        #[allow(clippy::cast_precision_loss)]
        let l = dimension as f64;
        let lambda = alpha * alpha * (l + kappa) - l;
        let l_plus_lambda = l + lambda;
        if !l_plus_lambda.is_finite() || l_plus_lambda <= 0.0 {
            return Err(invalid("L + lambda = alpha^2 (L + kappa) must be positive"));
        }
        let mean0 = lambda / l_plus_lambda;
        let cov0 = mean0 + (1.0 - alpha * alpha + beta);
        let other = 1.0 / (2.0 * l_plus_lambda);
        Ok(Self {
            mean0,
            cov0,
            other,
            gamma: l_plus_lambda.sqrt(),
            lambda,
        })
    }

    /// Mean weight of point `i` (0 is the centre).
    pub fn mean(&self, i: usize) -> f64 {
        if i == 0 { self.mean0 } else { self.other }
    }

    /// Covariance weight of point `i` (0 is the centre).
    pub fn cov(&self, i: usize) -> f64 {
        if i == 0 { self.cov0 } else { self.other }
    }
}

/// A set of `2L + 1` points in a space of dimension `D`: a centre, `L` plus-side points and
/// `L` minus-side points.
///
/// Point `0` is the centre, points `1..=L` are the columns of [`plus`](Self::plus), points
/// `L+1..=2L` the columns of [`minus`](Self::minus). The set is generated in the state space
/// (`D = L`) and then mapped through a function into another space (`D = M`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SigmaPoints<const D: usize, const L: usize> {
    /// The centre point (weight `W0`).
    pub center: SVector<f64, D>,
    /// The plus-side points, one per column.
    pub plus: SMatrix<f64, D, L>,
    /// The minus-side points, one per column.
    pub minus: SMatrix<f64, D, L>,
}

impl<const D: usize, const L: usize> SigmaPoints<D, L> {
    /// Number of points, `2L + 1`.
    pub const COUNT: usize = 2 * L + 1;

    /// Point `i` (0 is the centre, `1..=L` plus side, `L+1..=2L` minus side), or `None`
    /// past the end.
    pub fn point(&self, i: usize) -> Option<SVector<f64, D>> {
        if i == 0 {
            Some(self.center)
        } else if i <= L {
            Some(self.plus.column(i - 1).into_owned())
        } else if i <= 2 * L {
            Some(self.minus.column(i - 1 - L).into_owned())
        } else {
            None
        }
    }

    /// All `2L + 1` points in order, centre first.
    pub fn iter(&self) -> impl Iterator<Item = SVector<f64, D>> + '_ {
        (0..Self::COUNT).filter_map(|i| self.point(i))
    }

    /// All points with their mean weights, centre first.
    pub fn weighted(&self, weights: &Weights) -> impl Iterator<Item = (f64, SVector<f64, D>)> + '_ {
        let weights = *weights;
        (0..Self::COUNT).filter_map(move |i| self.point(i).map(|p| (weights.mean(i), p)))
    }

    /// Maps every point through `f`, checking that every output is finite.
    ///
    /// On a non-finite output returns `(sigma_point, component, value)` of the first one.
    pub(crate) fn try_map<const E: usize, F>(
        &self,
        mut f: F,
    ) -> Result<SigmaPoints<E, L>, (usize, usize, f64)>
    where
        F: FnMut(&SVector<f64, D>) -> SVector<f64, E>,
    {
        let check = |i: usize, v: &SVector<f64, E>| match v.iter().position(|c| !c.is_finite()) {
            Some(k) => Err((i, k, v[k])),
            None => Ok(()),
        };
        let center = f(&self.center);
        check(0, &center)?;
        let mut plus = SMatrix::<f64, E, L>::zeros();
        let mut minus = SMatrix::<f64, E, L>::zeros();
        for j in 0..L {
            let p: SVector<f64, D> = self.plus.column(j).into_owned();
            let y = f(&p);
            check(1 + j, &y)?;
            plus.set_column(j, &y);
        }
        for j in 0..L {
            let m: SVector<f64, D> = self.minus.column(j).into_owned();
            let y = f(&m);
            check(1 + L + j, &y)?;
            minus.set_column(j, &y);
        }
        Ok(SigmaPoints {
            center,
            plus,
            minus,
        })
    }
}
