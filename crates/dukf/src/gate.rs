//! Innovation tests: how far a candidate measurement lies from a filter's prediction, before
//! it is applied, to gate outliers or choose between candidates.

use nalgebra::{SMatrix, SVector};

use crate::space::Space;

/// The squared Mahalanobis distance of the innovation `y (-) y_pred` (in `space`, so angles
/// wrap) under the covariance `predicted + r`: the NIS the update would have, chi-square with
/// `M` degrees of freedom when the filter is consistent. `None` when `predicted + r` is not
/// positive definite or the distance is not finite.
pub fn innovation_nis<const M: usize, S: Space<M>>(
    space: &S,
    y: &SVector<f64, M>,
    y_pred: &SVector<f64, M>,
    predicted: &SMatrix<f64, M, M>,
    r: &SMatrix<f64, M, M>,
) -> Option<f64> {
    let nu = space.residual(y, y_pred);
    let s = predicted + r;
    let d2 = s.cholesky()?.solve(&nu).dot(&nu);
    d2.is_finite().then_some(d2)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{AngleMask, Euclidean};
    use nalgebra::{Matrix2, Vector2};

    #[test]
    fn the_distance_is_the_innovation_under_both_covariances() {
        let p = Matrix2::new(1.0, 0.0, 0.0, 4.0);
        let r = Matrix2::identity();
        let d2 = innovation_nis(
            &Euclidean,
            &Vector2::new(2.0, 5.0),
            &Vector2::new(0.0, 0.0),
            &p,
            &r,
        );
        // nu = (2, 5), S = diag(2, 5): 4/2 + 25/5.
        assert!((d2.unwrap_or(f64::NAN) - 7.0).abs() < 1e-12);
        // An angle across +-pi is a small innovation, not 2 pi.
        let mask = AngleMask::new([false, true]);
        let y = Vector2::new(0.0, 3.1);
        let d2 = innovation_nis(&mask, &y, &Vector2::new(0.0, -3.1), &p, &r).unwrap_or(f64::NAN);
        assert!(d2 < 0.01, "{d2}");
        // Not positive definite: no distance.
        let bad = Matrix2::new(-3.0, 0.0, 0.0, 1.0);
        assert_eq!(innovation_nis(&Euclidean, &y, &y, &bad, &r), None);
    }
}
