//! The camera mount and the measurement transform of spec 2.5 (`unicycle::camera`, re-exported
//! here), and the propagation of a pose fit's covariance through that transform to the
//! formation variables `(l12, alpha12, beta12)`: the measurement covariance `R` the tracker
//! filters with.

use nalgebra::{Matrix3, Rotation3, SMatrix, SVector, Vector3};

use formation_filter::MEASUREMENT_SPACE;
pub use unicycle::camera::{CameraMount, MIN_L12, MeasurementError, formation_from_camera_pose};

/// `[l12, alpha12, beta12]` and their covariance for a leader pose given as the parameters
/// `[rotation vector; translation]` (rig frame into camera frame) with a 6x6 covariance:
/// [`formation_from_camera_pose`] and [`propagate_covariance`] together.
pub fn formation_of_pose(
    params: &SVector<f64, 6>,
    covariance: &SMatrix<f64, 6, 6>,
    mount: &CameraMount,
) -> Result<(SVector<f64, 3>, Matrix3<f64>), MeasurementError> {
    let to_formation = |p: &SVector<f64, 6>| {
        let rotation = Rotation3::new(Vector3::new(p[0], p[1], p[2]));
        formation_from_camera_pose(&rotation, &Vector3::new(p[3], p[4], p[5]), mount)
    };
    let y = to_formation(params)?;
    Ok((y, propagate_covariance(params, covariance, to_formation)?))
}

/// Propagates a 6x6 covariance of pose parameters `p` (whatever parameterisation the caller
/// uses, e.g. rotation vector and translation) through `p -> (l12, alpha12, beta12)` by
/// central differences: `S = J C J^T`. `to_formation` maps parameters to formation
/// variables; angle differences are wrapped so that a bearing near +-pi is handled.
pub fn propagate_covariance<F>(
    params: &SVector<f64, 6>,
    covariance: &SMatrix<f64, 6, 6>,
    to_formation: F,
) -> Result<SMatrix<f64, 3, 3>, MeasurementError>
where
    F: FnMut(&SVector<f64, 6>) -> Result<SVector<f64, 3>, MeasurementError>,
{
    if !covariance.iter().all(|v| v.is_finite()) {
        return Err(MeasurementError::NonFinite {
            what: "pose covariance",
        });
    }
    dukf::propagate_linearised(
        params,
        covariance,
        |p| 1e-6 * p.abs().max(1.0),
        &MEASUREMENT_SPACE,
        to_formation,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use dukf::Space as _;

    /// Covariance propagation agrees with the sample covariance of transformed samples.
    #[test]
    fn covariance_propagation_matches_linearisation() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let mount = CameraMount::default();
        // The leader seen from a follower at the origin (`unicycle::camera` tests this pose).
        let (r, t) = mount.leader_to_camera(1.5, 0.25, 0.1);
        let rv = r.scaled_axis();
        let params = SVector::<f64, 6>::new(rv.x, rv.y, rv.z, t.x, t.y, t.z);
        let sig = [0.01, 0.01, 0.01, 0.002, 0.002, 0.005];
        let cov =
            SMatrix::<f64, 6, 6>::from_diagonal(&SVector::from_iterator(sig.iter().map(|s| s * s)));
        let f = |p: &SVector<f64, 6>| {
            let rot = Rotation3::new(Vector3::new(p[0], p[1], p[2]));
            formation_from_camera_pose(&rot, &Vector3::new(p[3], p[4], p[5]), &mount)
        };
        let (y, s) = formation_of_pose(&params, &cov, &mount).unwrap();
        assert_eq!(y, f(&params).unwrap());
        assert_eq!(s, propagate_covariance(&params, &cov, f).unwrap());
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let n01 = Normal::new(0.0, 1.0).unwrap();
        let y0 = f(&params).unwrap();
        let n = 20_000;
        let mut acc = SMatrix::<f64, 3, 3>::zeros();
        for _ in 0..n {
            let mut p = params;
            for k in 0..6 {
                p[k] += sig[k] * n01.sample(&mut rng);
            }
            let dy = MEASUREMENT_SPACE.residual(&f(&p).unwrap(), &y0);
            acc += dy * dy.transpose();
        }
        acc /= n as f64;
        for i in 0..3 {
            let rel = (acc[(i, i)] - s[(i, i)]).abs() / s[(i, i)];
            assert!(
                rel < 0.05,
                "variance {i}: sampled {} vs propagated {}",
                acc[(i, i)],
                s[(i, i)]
            );
        }
    }
}
