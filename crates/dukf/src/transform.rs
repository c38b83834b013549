//! The unscented transform: sigma points through a function, and the moments that come out.

use nalgebra::{SMatrix, SVector};

use crate::error::{Covariance, Function, Input, UkfError};
use crate::jitter::{JitterPolicy, factor_repaired};
use crate::sigma::{SigmaPoints, UtParams, Weights};
use crate::space::{Space, residuals};

/// The moments of `y = f(x)` estimated by an unscented transform.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Transformed<const N: usize, const M: usize> {
    /// Mean of `y`.
    pub mean: SVector<f64, M>,
    /// Covariance of `y`.
    pub covariance: SMatrix<f64, M, M>,
    /// Cross-covariance of `x` and `y`.
    pub cross_covariance: SMatrix<f64, N, M>,
    /// Diagonal jitter that had to be added to the input covariance (0 if none).
    pub jitter: f64,
}

/// One unscented transform of the Gaussian `(x, p)` through `f`, standalone.
///
/// Computes the weights, factorises `p` (with the default [`JitterPolicy`]), draws the
/// `2N + 1` sigma points in `in_space`, maps them through `f` and returns the mean,
/// covariance and cross-covariance of the outputs in `out_space`. For a linear `f` in
/// Euclidean spaces the result is exact (`A x`, `A P A^T`, `P A^T`).
///
/// # Errors
/// [`UkfError::InvalidParameters`], [`UkfError::NonFiniteVector`] /
/// [`UkfError::NonFiniteMatrix`] for non-finite `x` or `p`, [`UkfError::NotPositiveDefinite`]
/// if `p` cannot be factorised, and [`UkfError::NonFiniteFunction`] if `f` returns a
/// non-finite value (reported as a measurement function).
pub fn unscented_transform<const N: usize, const M: usize, SI, SO, F>(
    x: &SVector<f64, N>,
    p: &SMatrix<f64, N, N>,
    f: F,
    in_space: &SI,
    out_space: &SO,
    params: UtParams,
) -> Result<Transformed<N, M>, UkfError>
where
    SI: Space<N>,
    SO: Space<M>,
    F: FnMut(&SVector<f64, N>) -> SVector<f64, M>,
{
    let weights = Weights::new(params, N)?;
    check_vector(x, Input::State)?;
    check_matrix(p, Input::StateCovariance)?;
    let fp = factor_repaired(p, &JitterPolicy::default(), Covariance::Initial)?;
    let xs = sigma_points(in_space, x, &fp.factor, &weights);
    let ys = map_points(&xs, f, Function::Measurement)?;
    let mean = out_space.weighted_mean(&ys, &weights);
    let r = residuals(out_space, &ys, &mean);
    let covariance = weighted_covariance(&r, &weights);
    let cross_covariance = cross_from_factor(&fp.factor, &r, &weights);
    Ok(Transformed {
        mean,
        covariance,
        cross_covariance,
        jitter: fp.jitter,
    })
}

/// The sigma points `x`, `x (+) gamma S_j`, `x (+) (-gamma S_j)` of a factorised covariance.
pub(crate) fn sigma_points<const N: usize, S: Space<N>>(
    space: &S,
    x: &SVector<f64, N>,
    factor: &SMatrix<f64, N, N>,
    weights: &Weights,
) -> SigmaPoints<N, N> {
    let mut plus = SMatrix::<f64, N, N>::zeros();
    let mut minus = SMatrix::<f64, N, N>::zeros();
    for j in 0..N {
        let d: SVector<f64, N> = factor.column(j) * weights.gamma;
        plus.set_column(j, &space.add(x, &d));
        minus.set_column(j, &space.add(x, &(-d)));
    }
    SigmaPoints {
        center: *x,
        plus,
        minus,
    }
}

/// Maps sigma points through `f`, turning a non-finite output into a typed error.
pub(crate) fn map_points<const D: usize, const E: usize, const L: usize, F>(
    points: &SigmaPoints<D, L>,
    f: F,
    function: Function,
) -> Result<SigmaPoints<E, L>, UkfError>
where
    F: FnMut(&SVector<f64, D>) -> SVector<f64, E>,
{
    points.try_map(f).map_err(
        |(sigma_point, component, value)| UkfError::NonFiniteFunction {
            function,
            sigma_point,
            component,
            value,
        },
    )
}

/// `sum_i Wc_i r_i r_i^T` over a residual set, computed on the lower triangle and mirrored
/// (the result is exactly symmetric, and half the work of two general products).
pub(crate) fn weighted_covariance<const D: usize, const L: usize>(
    r: &SigmaPoints<D, L>,
    weights: &Weights,
) -> SMatrix<f64, D, D> {
    let mut out = SMatrix::<f64, D, D>::zeros();
    for i in 0..D {
        for j in 0..=i {
            let mut sides = 0.0;
            for k in 0..L {
                sides += r.plus[(i, k)] * r.plus[(j, k)] + r.minus[(i, k)] * r.minus[(j, k)];
            }
            let v = weights.cov0 * r.center[i] * r.center[j] + weights.other * sides;
            out[(i, j)] = v;
            out[(j, i)] = v;
        }
    }
    out
}

/// Cross-covariance `sum_i Wc_i (X_i (-) x)(Y_i (-) y)^T` when the state deviations are the
/// sigma-point offsets themselves: `0` for the centre, `+-gamma S_j` on the sides, so the sum
/// is `Wi gamma S (R+ - R-)^T`.
pub(crate) fn cross_from_factor<const N: usize, const M: usize>(
    factor: &SMatrix<f64, N, N>,
    r: &SigmaPoints<M, N>,
    weights: &Weights,
) -> SMatrix<f64, N, M> {
    factor * (r.plus - r.minus).transpose() * (weights.other * weights.gamma)
}

/// Rejects a vector with a non-finite component.
pub(crate) fn check_vector<const D: usize>(
    v: &SVector<f64, D>,
    input: Input,
) -> Result<(), UkfError> {
    match v.iter().position(|c| !c.is_finite()) {
        Some(index) => Err(UkfError::NonFiniteVector {
            input,
            index,
            value: v[index],
        }),
        None => Ok(()),
    }
}

/// Rejects a matrix with a non-finite entry.
pub(crate) fn check_matrix<const R: usize, const C: usize>(
    m: &SMatrix<f64, R, C>,
    input: Input,
) -> Result<(), UkfError> {
    for col in 0..C {
        for row in 0..R {
            let value = m[(row, col)];
            if !value.is_finite() {
                return Err(UkfError::NonFiniteMatrix {
                    input,
                    row,
                    col,
                    value,
                });
            }
        }
    }
    Ok(())
}
