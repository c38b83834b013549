//! Linearisation by central differences, for what an unscented transform does not cover: a
//! Jacobian to propagate a parameter covariance through a function once (`J C J^T`), or to
//! add a parameter's uncertainty to a process noise.

use nalgebra::{SMatrix, SVector};

use crate::space::Space;

/// The Jacobian of `f` at `x` by central differences: column `k` is
/// `(f(x + h_k e_k) (-) f(x - h_k e_k)) / (2 h_k)` with `h_k = step(x[k])`, the difference
/// taken in `space` (so that an angle output near `+-pi` is not a jump of `2 pi`).
///
/// # Errors
/// The first error of `f`.
pub fn central_jacobian<const N: usize, const M: usize, S: Space<M>, E>(
    x: &SVector<f64, N>,
    step: impl Fn(f64) -> f64,
    space: &S,
    mut f: impl FnMut(&SVector<f64, N>) -> Result<SVector<f64, M>, E>,
) -> Result<SMatrix<f64, M, N>, E> {
    let mut jacobian = SMatrix::<f64, M, N>::zeros();
    for k in 0..N {
        let h = step(x[k]);
        let (mut plus, mut minus) = (*x, *x);
        plus[k] += h;
        minus[k] -= h;
        let d = space.residual(&f(&plus)?, &f(&minus)?);
        jacobian.set_column(k, &(d / (2.0 * h)));
    }
    Ok(jacobian)
}

/// The covariance of `f(x)` for `x` of covariance `covariance`, linearised at `x`:
/// `J C J^T` with `J` from [`central_jacobian`], symmetrised.
///
/// # Errors
/// The first error of `f`.
pub fn propagate_linearised<const N: usize, const M: usize, S: Space<M>, E>(
    x: &SVector<f64, N>,
    covariance: &SMatrix<f64, N, N>,
    step: impl Fn(f64) -> f64,
    space: &S,
    f: impl FnMut(&SVector<f64, N>) -> Result<SVector<f64, M>, E>,
) -> Result<SMatrix<f64, M, M>, E> {
    let j = central_jacobian(x, step, space, f)?;
    let s = j * covariance * j.transpose();
    Ok((s + s.transpose()) * 0.5)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use super::*;
    use crate::{AngleMask, Euclidean};
    use nalgebra::{Matrix2, Vector2};

    #[test]
    fn a_linear_map_gives_its_matrix_and_a_c_at() {
        let a = Matrix2::new(2.0, -1.0, 0.5, 3.0);
        let x = Vector2::new(0.3, -7.0);
        let j = central_jacobian(
            &x,
            |v| 1e-6 * v.abs().max(1.0),
            &Euclidean,
            |v| Ok::<_, ()>(a * v),
        )
        .unwrap();
        assert!((j - a).norm() < 1e-8, "{j}");
        let c = Matrix2::new(0.04, 0.01, 0.01, 0.09);
        let s = propagate_linearised(&x, &c, |_| 1e-6, &Euclidean, |v| Ok::<_, ()>(a * v)).unwrap();
        assert!((s - a * c * a.transpose()).norm() < 1e-9, "{s}");
    }

    #[test]
    fn an_angle_output_at_pi_does_not_jump() {
        // atan2 of a point just across the negative x axis: the raw difference is 2 pi.
        let x = Vector2::new(-1.0, 0.0);
        let mask = AngleMask::new([true]);
        let j = central_jacobian(
            &x,
            |_| 1e-6,
            &mask,
            |v| Ok::<_, ()>(nalgebra::Vector1::new(v[1].atan2(v[0]))),
        )
        .unwrap();
        assert!(
            (j[(0, 1)] + 1.0).abs() < 1e-6,
            "d atan2 / dy at (-1, 0) is -1: {j}"
        );
        let err = central_jacobian(&x, |_| 1e-6, &Euclidean, |_| Err::<Vector2<f64>, _>("no"));
        assert_eq!(err.unwrap_err(), "no");
    }
}
