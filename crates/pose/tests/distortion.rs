//! Radial-tangential lens distortion.

use nalgebra::Point2;
use pose::{Distortion, Intrinsics, PoseError};
use proptest::prelude::*;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn undistort_inverts_distort(k1 in -0.3f64..0.3, k2 in -0.1f64..0.1, p1 in -0.005f64..0.005, p2 in -0.005f64..0.005, k3 in -0.02f64..0.02,
                                 x in -0.6f64..0.6, y in -0.45f64..0.45) {
        let d = Distortion::new(k1, k2, p1, p2, k3).unwrap();
        let n = Point2::new(x, y);
        let back = d.undistort(&d.distort(&n)).unwrap();
        prop_assert!((back - n).norm() < 1e-10, "{n:?} -> {back:?}");
    }

    #[test]
    fn pixel_round_trip(x in 0.0f64..640.0, y in 0.0f64..480.0) {
        let k = Intrinsics::from_hfov(60f64.to_radians(), 640, 480).unwrap();
        let d = Distortion::new(-0.12, 0.035, 0.001, -0.0005, 0.0).unwrap();
        let m = Point2::new(x, y);
        let back = d.distort_pixel(&k, &d.undistort_pixel(&k, &m).unwrap());
        prop_assert!((back - m).norm() < 1e-8);
    }
}

#[test]
fn distort_matches_the_opencv_formula() {
    let d = Distortion::new(0.1, 0.01, 0.002, 0.003, 0.001).unwrap();
    let (x, y) = (0.3, -0.2);
    let r2: f64 = x * x + y * y;
    let radial = 1.0 + 0.1 * r2 + 0.01 * r2 * r2 + 0.001 * r2 * r2 * r2;
    let xd = x * radial + 2.0 * 0.002 * x * y + 0.003 * (r2 + 2.0 * x * x);
    let yd = y * radial + 0.002 * (r2 + 2.0 * y * y) + 2.0 * 0.003 * x * y;
    let got = d.distort(&Point2::new(x, y));
    assert!((got.x - xd).abs() < 1e-15 && (got.y - yd).abs() < 1e-15);
}

#[test]
fn non_invertible_region_reports_non_convergence() {
    // Strong barrel distortion folds over at r ~ 0.58: radii beyond the fold's image have no
    // preimage.
    let d = Distortion::new(-1.0, 0.0, 0.0, 0.0, 0.0).unwrap();
    let e = d.undistort(&Point2::new(0.9, 0.0)).unwrap_err();
    assert!(
        matches!(e, PoseError::UndistortionNotConverged { iterations, .. } if iterations == pose::UNDISTORT_MAX_ITERATIONS),
        "{e:?}"
    );
}

#[test]
fn bad_coefficients_are_rejected() {
    assert!(matches!(
        Distortion::new(f64::NAN, 0.0, 0.0, 0.0, 0.0),
        Err(PoseError::InvalidDistortion { name: "k1", .. })
    ));
    assert!(matches!(
        Distortion::new(0.0, 0.0, f64::INFINITY, 0.0, 0.0),
        Err(PoseError::InvalidDistortion { name: "p1", .. })
    ));
    // Regression (#11): the count error read "coefficient count (need 4 or 5) is not
    // finite (3)".
    let e = Distortion::from_slice(&[0.1, 0.2, 0.0]).unwrap_err();
    assert!(matches!(e, PoseError::DistortionCount { count: 3 }), "{e}");
    assert!(e.to_string().contains("4 or 5 coefficients") && e.to_string().contains("got 3"));
    let e = Distortion::from_slice(&[0.1, 0.2, 0.0, 0.0, 0.0, 0.5, 0.0, 0.0]).unwrap_err();
    assert!(
        matches!(e, PoseError::UnsupportedDistortion { index: 5, .. }),
        "{e}"
    );
    let d = Distortion::from_slice(&[0.1, 0.2, 0.01, 0.02]).unwrap();
    assert_eq!(d.k3, 0.0);
    assert!(matches!(
        Distortion::default().undistort(&Point2::new(f64::NAN, 0.0)),
        Err(PoseError::NonFinite { .. })
    ));
}
